//! The surface material of a primitive: glTF 2.0 metallic-roughness parameters and textures, which create a
//! [`Bsdf`] at each hit and may own the medium of the primitive's interior (Fong et al. 2017, §4).
//!
//! glTF keys read: `pbrMetallicRoughness.{baseColorFactor, baseColorTexture, metallicFactor, roughnessFactor,
//! metallicRoughnessTexture}`, `normalTexture` (+ `scale`), `occlusionTexture` (+ `strength`),
//! `emissiveFactor`, `emissiveTexture`, `doubleSided`, and the extensions
//! `KHR_materials_emissive_strength.emissiveStrength` (it multiplies `emissiveFactor`, and so the emissive
//! texture too), `KHR_materials_specular.{specularFactor, specularColorFactor}`,
//! `KHR_materials_transmission.transmissionFactor`, `KHR_materials_ior.ior` (default 1.5), `KHR_materials_unlit`,
//! `KHR_materials_clearcoat.{clearcoatFactor, clearcoatTexture, clearcoatRoughnessFactor,
//! clearcoatRoughnessTexture, clearcoatNormalTexture}` and `KHR_materials_sheen.{sheenColorFactor,
//! sheenColorTexture, sheenRoughnessFactor, sheenRoughnessTexture}`,
//! `KHR_materials_anisotropy.{anisotropyStrength, anisotropyRotation, anisotropyTexture}`,
//! `KHR_materials_diffuse_transmission.{diffuseTransmissionFactor, diffuseTransmissionTexture (A),
//! diffuseTransmissionColorFactor, diffuseTransmissionColorTexture (sRGB RGB)}` (see [`super::GltfPbr`]),
//! `KHR_materials_dispersion.dispersion` (read beside `KHR_materials_volume` only; see
//! [`Material::dispersed_ior`]), `KHR_materials_iridescence.{iridescenceFactor, iridescenceTexture (R),
//! iridescenceIor, iridescenceThicknessMinimum, iridescenceThicknessMaximum, iridescenceThicknessTexture (G)}`
//! (see [`super::ThinFilm`]), and the archived
//! `KHR_materials_pbrSpecularGlossiness.{diffuseFactor, diffuseTexture, specularFactor, glossinessFactor,
//! specularGlossinessTexture}`, converted where the material is shaded to the base colour, metalness and
//! roughness it replaces (see [`super::spec_gloss`]). Every texture reference may carry
//! `texCoord` and `KHR_texture_transform` (held by the [`Texture`] it names). The mesh's vertex colour
//! (`COLOR_0`) multiplies the base colour and its alpha. OBJ/MTL materials are mapped onto the same fields by
//! the OBJ loader.
//!
//! Choices where a path tracer differs from a rasteriser:
//! - Unlit (`KHR_materials_unlit`): the surface emits its base colour (× texture × vertex colour) toward the
//!   viewer and scatters nothing, like an emission shader in Cycles or three.js's `MeshBasicMaterial`. It is
//!   not a light: nothing samples it, so it lights other surfaces only through paths that hit it. One-sided
//!   unlit surfaces are black from behind.
//! - Occlusion (`occlusionTexture`): read (kept in [`Material::occlusion_texture`]), but never applied to the
//!   rendered image; a path tracer computes occlusion itself, and darkening by the baked map would count it
//!   twice.
//! - Clear coat: emission is not darkened by the coat's Fresnel (the extension darkens it), so that light
//!   sampling and BSDF sampling see the same emitter.
//! - Diffuse transmission without `KHR_materials_volume` is a thin wall: both faces scatter alike (the
//!   integrator turns the shading frame toward the arriving light, as for a double-sided material), and a
//!   single-sided one is not culled. Beside a volume the transmitted light enters the mesh's interior medium.
//! - Dispersion: the path carries one colour channel from a dispersive surface on, chosen with probability
//!   proportional to its throughput (hero-wavelength sampling with RGB channels as the wavelengths), and the
//!   surface refracts with that channel's index.

use super::spec_gloss::{to_metallic_roughness, MetallicRoughness, SpecularGlossiness};
use super::texture::{ShadingPoint, TexCoord, Texture};
use super::{Bsdf, PbrParams};
use crate::geometry::CompositingTags;
use crate::math::{Frame, Rgb, Vec2, Vec3, Vec4};
use std::borrow::Cow;

/// A material's parameters at a point and the BSDF made from them ([`Material::pbr_params`],
/// [`Material::bsdf`]): what shading a surface hit needs, computed once per hit, or once per scene for a
/// material without textures ([`Material::constant_shading`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MaterialShading {
    /// The parameters (the first hit's albedo AOV is their base colour).
    pub params: PbrParams,
    /// The BSDF made from them.
    pub bsdf: Bsdf,
}

impl MaterialShading {
    /// `material`'s shading at `at`.
    pub(crate) fn of(material: &Material, at: &ShadingPoint, textures: &[Texture]) -> Self {
        let params = material.pbr_params(at, textures);
        Self {
            params,
            bsdf: Bsdf::from_gltf(&params),
        }
    }

    /// `material`'s shading at `at`, borrowed from `constant` (its [`Material::constant_shading`]) where that
    /// holds there, i.e. where the vertex colour is white (the same bits as [`Self::of`]: a factor of 1 is
    /// exact), else computed. Borrowed, not copied: a copy of the parameters and the BSDF per hit measured
    /// 1.2 % of the peer benchmark's mirrors render.
    pub(crate) fn at<'a>(
        constant: Option<&'a Self>,
        material: &Material,
        at: &ShadingPoint,
        textures: &[Texture],
    ) -> Cow<'a, Self> {
        match constant {
            Some(shading) if at.color == Vec4::ONE => Cow::Borrowed(shading),
            _ => Cow::Owned(Self::of(material, at, textures)),
        }
    }
}

/// A texture reference: an index into the scene's texture list.
pub type TextureId = u32;

/// A surface material in the glTF metallic-roughness model.
#[derive(Clone, Debug)]
pub struct Material {
    /// Name from the scene file, for messages and statistics.
    pub name: String,
    /// Linear base colour (RGB) and alpha.
    pub base_color: Vec4,
    /// Optional sRGB base-colour texture, multiplied with `base_color`.
    pub base_color_texture: Option<TextureId>,
    /// Metalness in \[0, 1\].
    pub metallic: f32,
    /// Perceptual roughness in \[0, 1\] (GGX alpha = roughness²).
    pub roughness: f32,
    /// Optional linear texture: roughness in G, metalness in B (glTF layout).
    pub metallic_roughness_texture: Option<TextureId>,
    /// Optional tangent-space normal map and its scale.
    pub normal_texture: Option<(TextureId, f32)>,
    /// Optional ambient-occlusion map (red channel) and its strength; read, never applied to the render.
    pub occlusion_texture: Option<(TextureId, f32)>,
    /// Emitted radiance (emissive factor × emissive strength), linear RGB, front faces only.
    pub emission: Rgb,
    /// Optional sRGB emissive texture, multiplied with `emission`.
    pub emission_texture: Option<TextureId>,
    /// Index of refraction of the dielectric layer and of transmission.
    pub ior: f32,
    /// KHR_materials_specular strength; 0 removes the specular layer (an exactly Lambertian surface).
    pub specular_factor: f32,
    /// KHR_materials_specular colour of the dielectric F0.
    pub specular_color: Rgb,
    /// KHR_materials_transmission factor: the fraction of the dielectric base that refracts.
    pub transmission: f32,
    /// `KHR_materials_transmission.transmissionTexture` (linear): its red channel multiplies `transmission`.
    pub transmission_texture: Option<TextureId>,
    /// `KHR_materials_specular.specularTexture` (linear): its alpha channel multiplies `specular_factor`.
    pub specular_texture: Option<TextureId>,
    /// `KHR_materials_specular.specularColorTexture` (sRGB): its RGB multiplies `specular_color`.
    pub specular_color_texture: Option<TextureId>,
    /// When false, the back face of an opaque surface reflects nothing, and camera rays do not see it
    /// (`Self::culls_back_faces`).
    pub double_sided: bool,
    /// The medium filling the interior of a closed mesh with this material (index into `Scene::media`).
    pub interior: Option<u32>,
    /// How the coverage (alpha) is used: opaque, a cut-out, or partial coverage (glTF `alphaMode`).
    pub alpha_mode: AlphaMode,
    /// Optional coverage texture whose first channel multiplies alpha (OBJ `map_d`); glTF takes alpha from the
    /// base-colour texture instead.
    pub alpha_texture: Option<TextureId>,
    /// `KHR_materials_unlit`: the surface shows its base colour as emitted radiance and scatters nothing.
    pub unlit: bool,
    /// `KHR_materials_clearcoat`, when present.
    pub clearcoat: Option<ClearcoatLayer>,
    /// `KHR_materials_sheen`, when present.
    pub sheen: Option<SheenLayer>,
    /// `KHR_materials_pbrSpecularGlossiness`, when present: it replaces `base_color`, `base_color_texture`,
    /// `metallic`, `roughness` and `metallic_roughness_texture` (converted at each shading point).
    pub specular_glossiness: Option<SpecularGlossiness>,
    /// `KHR_materials_anisotropy`, when present.
    pub anisotropy: Option<Anisotropy>,
    /// `KHR_materials_diffuse_transmission`, when present.
    pub diffuse_transmission: Option<DiffuseTransmission>,
    /// `KHR_materials_iridescence`, when present.
    pub iridescence: Option<Iridescence>,
    /// `KHR_materials_dispersion.dispersion`, `20/V` for the Abbe number V (0: no dispersion). Only a
    /// transmissive material disperses (`Self::is_dispersive`); the glTF loader reads it beside
    /// `KHR_materials_volume` only, as the extension requires.
    pub dispersion: f32,
    /// Light group, holdout and shadow-catcher tags of every surface with this material (`extras`
    /// `nimbus_light_group`, `nimbus_holdout`, `nimbus_shadow_catcher`; see [`CompositingTags`]).
    pub tags: CompositingTags,
}

/// The clear coat of a material (`KHR_materials_clearcoat`): a GGX dielectric layer of index 1.5.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClearcoatLayer {
    /// `clearcoatFactor` (default 0: no coat).
    pub factor: f32,
    /// `clearcoatTexture`: its red channel multiplies `factor`.
    pub texture: Option<TextureId>,
    /// `clearcoatRoughnessFactor` (perceptual, default 0).
    pub roughness: f32,
    /// `clearcoatRoughnessTexture`: its green channel multiplies `roughness`.
    pub roughness_texture: Option<TextureId>,
    /// `clearcoatNormalTexture` and its `scale`: the coat's own normal map. Without it the coat follows the
    /// interpolated normal, not the base's normal map (as the extension specifies).
    pub normal_texture: Option<(TextureId, f32)>,
}

/// The sheen of a material (`KHR_materials_sheen`): the "Charlie" microfiber lobe over the base.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SheenLayer {
    /// `sheenColorFactor` (linear RGB, default 0: no sheen).
    pub color: Rgb,
    /// `sheenColorTexture` (sRGB): its RGB multiplies `color`.
    pub color_texture: Option<TextureId>,
    /// `sheenRoughnessFactor` (default 0).
    pub roughness: f32,
    /// `sheenRoughnessTexture`: its alpha channel multiplies `roughness`.
    pub roughness_texture: Option<TextureId>,
}

/// The anisotropy of a material's specular reflection (`KHR_materials_anisotropy`): the strength and the
/// direction, in the tangent frame, along which the GGX width grows (see `super::GltfPbr`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Anisotropy {
    /// `anisotropyStrength`, in \[0, 1\] (default 0: isotropic).
    pub strength: f32,
    /// `anisotropyRotation`: radians counter-clockwise from the tangent toward the bitangent (default 0).
    pub rotation: f32,
    /// `anisotropyTexture` (linear): RG the direction in tangent space, encoded `[0, 1] → [−1, 1]`, before the
    /// rotation; B multiplies `strength`.
    pub texture: Option<TextureId>,
}

/// The diffuse transmission of a material (`KHR_materials_diffuse_transmission`): the share of the diffuse base
/// that a Lambertian lobe transmits to the other side, and its colour (see `super::GltfPbr`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseTransmission {
    /// `diffuseTransmissionFactor`, in \[0, 1\] (default 0: none).
    pub factor: f32,
    /// `diffuseTransmissionTexture` (linear): its alpha channel multiplies `factor`.
    pub texture: Option<TextureId>,
    /// `diffuseTransmissionColorFactor` (linear RGB, default 1).
    pub color: Rgb,
    /// `diffuseTransmissionColorTexture` (sRGB): its RGB multiplies `color`.
    pub color_texture: Option<TextureId>,
}

impl Default for DiffuseTransmission {
    /// The extension's defaults: factor 0, white.
    fn default() -> Self {
        Self {
            factor: 0.0,
            texture: None,
            color: Rgb::ONE,
            color_texture: None,
        }
    }
}

/// The thin film over a material's specular layer (`KHR_materials_iridescence`; see `super::ThinFilm`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iridescence {
    /// `iridescenceFactor`, in \[0, 1\] (default 0: no film).
    pub factor: f32,
    /// `iridescenceTexture` (linear): its red channel multiplies `factor`.
    pub texture: Option<TextureId>,
    /// `iridescenceIor`: the film's index (default 1.3).
    pub ior: f32,
    /// `iridescenceThicknessMinimum` in nanometres (default 100).
    pub thickness_min: f32,
    /// `iridescenceThicknessMaximum` in nanometres (default 400): the thickness without a texture.
    pub thickness_max: f32,
    /// `iridescenceThicknessTexture` (linear): its green channel blends from the minimum to the maximum.
    pub thickness_texture: Option<TextureId>,
}

impl Default for Iridescence {
    /// The extension's defaults.
    fn default() -> Self {
        Self {
            factor: 0.0,
            texture: None,
            ior: 1.3,
            thickness_min: 100.0,
            thickness_max: 400.0,
            thickness_texture: None,
        }
    }
}

/// How a material's alpha (`base_color.w` × the base-colour texture's alpha × `alpha_texture`) covers the surface
/// (glTF 2.0 §3.9.4 `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is fully opaque.
    #[default]
    Opaque,
    /// A cut-out: the surface exists where alpha ≥ `cutoff` and is absent elsewhere, for every ray.
    Mask {
        /// The glTF `alphaCutoff` (default 0.5).
        cutoff: f32,
    },
    /// Partial coverage: a ray passes through with probability 1 − alpha (stochastic, unbiased transparency).
    Blend,
}

impl Default for Material {
    /// The glTF default material: white, fully metallic, fully rough.
    fn default() -> Self {
        Self {
            name: String::from("default"),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            occlusion_texture: None,
            emission: Rgb::ZERO,
            emission_texture: None,
            ior: 1.5,
            specular_factor: 1.0,
            specular_color: Rgb::ONE,
            transmission: 0.0,
            transmission_texture: None,
            specular_texture: None,
            specular_color_texture: None,
            double_sided: false,
            interior: None,
            alpha_mode: AlphaMode::Opaque,
            alpha_texture: None,
            unlit: false,
            clearcoat: None,
            sheen: None,
            specular_glossiness: None,
            anisotropy: None,
            diffuse_transmission: None,
            iridescence: None,
            dispersion: 0.0,
            tags: CompositingTags::default(),
        }
    }
}

/// The value of texture `id` at `at` (through the texture's own UV set and transform).
fn lookup(textures: &[Texture], id: Option<TextureId>, at: &ShadingPoint) -> Option<Vec4> {
    id.and_then(|i| textures.get(i as usize))
        .map(|t| t.lookup_at(at))
}

/// The metallic-roughness reading of `KHR_materials_pbrSpecularGlossiness` at a point, and its alpha: the
/// diffuse colour (`diffuseFactor` × the vertex colour × `diffuseTexture`), the specular colour and the
/// glossiness (factors × `specularGlossinessTexture`), converted by [`to_metallic_roughness`].
fn spec_gloss_at(
    sg: &SpecularGlossiness,
    at: &ShadingPoint,
    textures: &[Texture],
) -> (MetallicRoughness, f32) {
    let mut diffuse = sg.diffuse * at.color;
    if let Some(t) = lookup(textures, sg.diffuse_texture, at) {
        diffuse *= t;
    }
    let (mut specular, mut glossiness) = (sg.specular, sg.glossiness);
    if let Some(t) = lookup(textures, sg.specular_glossiness_texture, at) {
        specular *= t.truncate();
        glossiness *= t.w;
    }
    (
        to_metallic_roughness(diffuse.truncate(), specular, glossiness),
        diffuse.w,
    )
}

/// Decodes a tangent-space normal-map texel: glTF stores `n · 0.5 + 0.5`, and `scale` multiplies x and y
/// (glTF 2.0 §5.19.3, `normalTextureInfo.scale`). `None` when the result is not above the surface.
fn decode_normal(t: Vec4, scale: f32) -> Option<Vec3> {
    let n = Vec3::new(
        (t.x * 2.0 - 1.0) * scale,
        (t.y * 2.0 - 1.0) * scale,
        t.z * 2.0 - 1.0,
    )
    .normalize_or_zero();
    (n.z > 0.0).then_some(n)
}

impl Anisotropy {
    internal! {
        /// The strength and the direction in tangent space at a point whose anisotropy texel is `texel`
        /// (`KHR_materials_anisotropy`'s specification and its property descriptions): the direction is the
        /// texel's RG mapped to \[−1, 1\] (`(1, 0)` without a texture, or where the texel's direction is zero) and
        /// normalised, then rotated counter-clockwise by `rotation`; the strength is `strength` × the texel's B, in
        /// \[0, 1\].
        pub fn at(&self, texel: Option<Vec4>) -> (f32, Vec2) {
            let (direction, scale) = texel.map_or((Vec2::X, 1.0), |t| {
                let d = Vec2::new(2.0 * t.x - 1.0, 2.0 * t.y - 1.0);
                (d.try_normalize().unwrap_or(Vec2::X), t.z)
            });
            let (sin, cos) = self.rotation.sin_cos();
            let rotated = Vec2::new(
                cos * direction.x - sin * direction.y,
                sin * direction.x + cos * direction.y,
            );
            let strength = (self.strength * scale).clamp(0.0, 1.0);
            (if strength.is_nan() { 0.0 } else { strength }, rotated)
        }
    }
}

impl Material {
    /// A plain Lambertian material (no specular layer), as glTF writes it with `specularFactor` 0.
    pub fn lambertian(name: &str, albedo: Rgb) -> Self {
        Self {
            name: name.to_owned(),
            base_color: albedo.extend(1.0),
            metallic: 0.0,
            specular_factor: 0.0,
            ..Self::default()
        }
    }

    /// Whether camera rays pass through this material's back faces: a single-sided surface that neither
    /// transmits (specularly or diffusely), bounds a medium nor emits (glTF's back-face culling, Arnold's `sidedness` for USD's
    /// `doubleSided = false`). A boundary or a refracting surface is seen from either side; so is an emitter,
    /// whose back shows black as a one-sided area light does in Mitsuba 3 and Cycles (the shared validation
    /// scene `area-light-floor` sees its light from behind).
    pub(crate) fn culls_back_faces(&self) -> bool {
        !self.double_sided
            && !self.is_transmissive()
            && !self.transmits_diffusely()
            && self.interior.is_none()
            && !self.is_emissive()
    }

    internal! {
        /// True when the material emits light from its front faces.
        pub fn is_emissive(&self) -> bool {
            self.emission.max_element() > 0.0
        }
    }

    /// True when light can pass through the surface by refraction (the BSDF has a dielectric interface).
    pub(crate) fn is_transmissive(&self) -> bool {
        self.transmission > 0.0
    }

    /// True when the BSDF can have a diffuse transmission lobe (`KHR_materials_diffuse_transmission` with a
    /// positive factor; a texture only scales it down).
    pub(crate) fn transmits_diffusely(&self) -> bool {
        self.diffuse_transmission.is_some_and(|d| d.factor > 0.0)
    }

    internal! {
        /// True when the index of refraction depends on the colour channel: a positive dispersion on a refracting
        /// material.
        pub fn is_dispersive(&self) -> bool {
            self.dispersion > 0.0 && self.is_transmissive()
        }
    }

    /// The index of refraction in colour channel `channel` (0, 1, 2 for R, G, B) at its wavelength λ
    /// ([`crate::math::RGB_WAVELENGTHS_NM`]): Cauchy's equation fitted to the Abbe number, as
    /// `KHR_materials_dispersion` specifies, `n(λ) = max(n_d + (n_d − 1)/V · (523655/λ² − 1.5168), 1)` with λ in
    /// nm, `n_d = ior` the index at the Fraunhofer d line (587.56 nm) and `V = 20/dispersion`. Without
    /// dispersion, `ior` unchanged.
    pub(crate) fn dispersed_ior(&self, channel: usize) -> f32 {
        if !self.is_dispersive() {
            return self.ior;
        }
        let lambda = crate::math::RGB_WAVELENGTHS_NM[channel.min(2)];
        let n_d = self.ior;
        let cauchy = 523655.0 / (lambda * lambda) - 1.5168;
        (n_d + (n_d - 1.0) * self.dispersion / 20.0 * cauchy).max(1.0)
    }

    internal! {
        /// Emitted radiance at a point of a front face: `emissiveFactor` × `emissiveStrength` × the emissive
        /// texture.
        pub fn emission_at(&self, at: &ShadingPoint, textures: &[Texture]) -> Rgb {
            match lookup(textures, self.emission_texture, at) {
                Some(t) => self.emission * t.truncate(),
                None => self.emission,
            }
        }
    }

    internal! {
        /// The base colour and alpha at a point: `baseColorFactor` × the base-colour texture × the vertex colour
        /// (glTF 2.0 §3.9.2: `COLOR_0` multiplies the base colour, alpha included). With
        /// `KHR_materials_pbrSpecularGlossiness`, the converted base colour, and the diffuse alpha (× the vertex
        /// colour's).
        pub fn base_color_at(&self, at: &ShadingPoint, textures: &[Texture]) -> Vec4 {
            if let Some(sg) = &self.specular_glossiness {
                let (mr, alpha) = spec_gloss_at(sg, at, textures);
                return mr.base_color.extend(alpha);
            }
            let mut base = self.base_color * at.color;
            if let Some(t) = lookup(textures, self.base_color_texture, at) {
                base *= t;
            }
            base
        }
    }

    /// The radiance an unlit material shows at a point: its base colour (see the module documentation).
    pub(crate) fn unlit_radiance(&self, at: &ShadingPoint, textures: &[Texture]) -> Rgb {
        self.base_color_at(at, textures).truncate().max(Rgb::ZERO)
    }

    /// True when the BSDF may be an invisible boundary ([`Bsdf::is_index_matched`] at some point): full
    /// transmission (a constant of the material) and ior 1. Conservative: the tint and roughness, which may
    /// come from textures, are not checked.
    pub(crate) fn may_be_index_matched(&self) -> bool {
        self.transmission >= 1.0 && self.ior == 1.0
    }

    internal! {
        /// The BSDF parameters at a point.
        pub fn pbr_params(&self, at: &ShadingPoint, textures: &[Texture]) -> PbrParams {
            let (base, metallic, roughness) = match &self.specular_glossiness {
                Some(sg) => {
                    let (mr, _) = spec_gloss_at(sg, at, textures);
                    (mr.base_color, mr.metallic, mr.roughness)
                }
                None => {
                    let base = self.base_color_at(at, textures).truncate();
                    let (mut metallic, mut roughness) = (self.metallic, self.roughness);
                    if let Some(t) = lookup(textures, self.metallic_roughness_texture, at) {
                        roughness *= t.y;
                        metallic *= t.z;
                    }
                    (base, metallic, roughness)
                }
            };
            let (mut clearcoat, mut clearcoat_roughness) = (0.0, 0.0);
            if let Some(c) = &self.clearcoat {
                clearcoat = c.factor * lookup(textures, c.texture, at).map_or(1.0, |t| t.x);
                clearcoat_roughness =
                    c.roughness * lookup(textures, c.roughness_texture, at).map_or(1.0, |t| t.y);
            }
            let (mut sheen_color, mut sheen_roughness) = (Rgb::ZERO, 0.0);
            if let Some(s) = &self.sheen {
                sheen_color = s.color
                    * lookup(textures, s.color_texture, at).map_or(Rgb::ONE, |t| t.truncate());
                sheen_roughness =
                    s.roughness * lookup(textures, s.roughness_texture, at).map_or(1.0, |t| t.w);
            }
            let (mut diffuse_transmission, mut diffuse_transmission_color) = (0.0, Rgb::ONE);
            if let Some(d) = &self.diffuse_transmission {
                diffuse_transmission =
                    d.factor * lookup(textures, d.texture, at).map_or(1.0, |t| t.w);
                diffuse_transmission_color = d.color
                    * lookup(textures, d.color_texture, at).map_or(Rgb::ONE, |t| t.truncate());
            }
            let transmission = self.transmission
                * lookup(textures, self.transmission_texture, at).map_or(1.0, |t| t.x);
            let specular_factor = self.specular_factor
                * lookup(textures, self.specular_texture, at).map_or(1.0, |t| t.w);
            let specular_color = self.specular_color
                * lookup(textures, self.specular_color_texture, at)
                    .map_or(Rgb::ONE, |t| t.truncate());
            let film = self.iridescence.unwrap_or_default();
            let iridescence = film.factor * lookup(textures, film.texture, at).map_or(1.0, |t| t.x);
            let iridescence_thickness = match lookup(textures, film.thickness_texture, at) {
                Some(t) => film.thickness_min + (film.thickness_max - film.thickness_min) * t.y,
                None => film.thickness_max,
            };
            let (anisotropy_strength, anisotropy_direction) = self
                .anisotropy
                .as_ref()
                .map_or((0.0, Vec2::X), |a| a.at(lookup(textures, a.texture, at)));
            PbrParams {
                base_color: base.clamp(Vec3::ZERO, Vec3::ONE),
                metallic: metallic.clamp(0.0, 1.0),
                roughness: roughness.clamp(0.0, 1.0),
                ior: self.ior,
                specular_factor: specular_factor.clamp(0.0, 1.0),
                specular_color: specular_color.max(Vec3::ZERO),
                transmission: transmission.clamp(0.0, 1.0),
                clearcoat: clearcoat.clamp(0.0, 1.0),
                clearcoat_roughness: clearcoat_roughness.clamp(0.0, 1.0),
                sheen_color: sheen_color.clamp(Rgb::ZERO, Rgb::ONE),
                sheen_roughness: sheen_roughness.clamp(0.0, 1.0),
                anisotropy_strength,
                anisotropy_direction,
                diffuse_transmission: diffuse_transmission.clamp(0.0, 1.0),
                diffuse_transmission_color: diffuse_transmission_color.max(Rgb::ZERO),
                iridescence: iridescence.clamp(0.0, 1.0),
                iridescence_ior: film.ior,
                iridescence_thickness: iridescence_thickness.max(0.0),
            }
        }
    }

    /// Creates the BSDF for a hit at a point (a clear coat's normal is the shading normal until
    /// [`Bsdf::set_coat_normal`] tilts it; see [`Material::coat_normal`]). The renderer takes it together with
    /// the parameters it is made from ([`MaterialShading`]); this is the tests' way to ask for it alone.
    #[cfg(any(test, feature = "testing"))]
    pub fn bsdf(&self, at: &ShadingPoint, textures: &[Texture]) -> Bsdf {
        MaterialShading::of(self, at, textures).bsdf
    }

    /// The material's parameters and BSDF where they are the same at every point: it refers to no texture
    /// ([`Self::texture_ids`]), so they depend on the point only through its vertex colour, and this is their
    /// value where that is white ([`MaterialShading::at`] checks it). `None` for a textured material.
    pub(crate) fn constant_shading(&self) -> Option<MaterialShading> {
        if self.texture_ids().next().is_some() {
            return None;
        }
        Some(MaterialShading::of(
            self,
            &ShadingPoint::from(TexCoord::default()),
            &[],
        ))
    }

    /// [`Material::bsdf`] for a path that carries colour channel `channel` alone: the refraction index is
    /// that channel's ([`Material::dispersed_ior`]). The same BSDF as [`Material::bsdf`] without dispersion.
    pub(crate) fn bsdf_in_channel(
        &self,
        at: &ShadingPoint,
        textures: &[Texture],
        channel: usize,
    ) -> Bsdf {
        Bsdf::from_gltf(&PbrParams {
            ior: self.dispersed_ior(channel),
            ..self.pbr_params(at, textures)
        })
    }

    internal! {
        /// The world-space normal of the clear coat, for a hit whose frame before any normal mapping is
        /// `unmapped`: that frame's normal bent by `clearcoatNormalTexture` if there is one, else the frame's
        /// normal itself (the coat does not follow the base's normal map). `None` without a clear coat.
        pub fn coat_normal(
            &self,
            unmapped: &Frame,
            at: &ShadingPoint,
            textures: &[Texture],
        ) -> Option<Vec3> {
            let coat = self.clearcoat.as_ref()?;
            let mapped = coat
                .normal_texture
                .and_then(|(id, scale)| decode_normal(lookup(textures, Some(id), at)?, scale));
            Some(mapped.map_or(unmapped.n, |n| {
                unmapped.to_world(n).normalize_or(unmapped.n)
            }))
        }
    }

    /// Every texture the material refers to.
    pub(crate) fn texture_ids(&self) -> impl Iterator<Item = TextureId> + '_ {
        let coat = self.clearcoat.iter().flat_map(|c| {
            [
                c.texture,
                c.roughness_texture,
                c.normal_texture.map(|t| t.0),
            ]
        });
        let sheen = self
            .sheen
            .iter()
            .flat_map(|s| [s.color_texture, s.roughness_texture]);
        let spec_gloss = self
            .specular_glossiness
            .iter()
            .flat_map(|s| [s.diffuse_texture, s.specular_glossiness_texture]);
        let anisotropy = self.anisotropy.iter().map(|a| a.texture);
        let diffuse_transmission = self
            .diffuse_transmission
            .iter()
            .flat_map(|d| [d.texture, d.color_texture]);
        let iridescence = self
            .iridescence
            .iter()
            .flat_map(|i| [i.texture, i.thickness_texture]);
        [
            self.base_color_texture,
            self.metallic_roughness_texture,
            self.normal_texture.map(|t| t.0),
            self.occlusion_texture.map(|t| t.0),
            self.emission_texture,
            self.alpha_texture,
            self.transmission_texture,
            self.specular_texture,
            self.specular_color_texture,
        ]
        .into_iter()
        .chain(coat)
        .chain(sheen)
        .chain(spec_gloss)
        .chain(anisotropy)
        .chain(diffuse_transmission)
        .chain(iridescence)
        .flatten()
    }

    /// The coverage at a point: the alpha of [`Self::base_color_at`] (`base_color.w` × the vertex colour's ×
    /// the base-colour texture's) × the first channel of `alpha_texture`, in \[0, 1\]. Only
    /// [`AlphaMode::Mask`] and [`AlphaMode::Blend`] use it.
    pub(crate) fn alpha_at(&self, at: &ShadingPoint, textures: &[Texture]) -> f32 {
        let mut alpha = self.base_color_at(at, textures).w;
        if let Some(t) = lookup(textures, self.alpha_texture, at) {
            alpha *= t.x;
        }
        alpha.clamp(0.0, 1.0)
    }

    /// True when the material has a normal map.
    pub fn has_normal_map(&self) -> bool {
        self.normal_texture.is_some()
    }

    /// True when the material's specular reflection can be anisotropic (`KHR_materials_anisotropy` with a
    /// positive strength; a texture only scales it down).
    pub fn is_anisotropic(&self) -> bool {
        self.anisotropy.is_some_and(|a| a.strength > 0.0)
    }

    /// True when the material's shading needs a tangent frame: a normal map, or anisotropy (its directions are
    /// given in tangent space).
    pub fn needs_tangents(&self) -> bool {
        self.has_normal_map() || self.is_anisotropic()
    }

    internal! {
        /// The tangent-space normal from the normal map at a point (z up), or `None` without a normal map.
        /// glTF stores `(n * 0.5 + 0.5)`; `scale` multiplies the x and y components.
        pub fn normal_map(&self, at: &ShadingPoint, textures: &[Texture]) -> Option<Vec3> {
            let (id, scale) = self.normal_texture?;
            decode_normal(lookup(textures, Some(id), at)?, scale)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::TexCoord;
    use crate::math::RGB_WAVELENGTHS_NM;

    fn glass(dispersion: f32) -> Material {
        Material {
            base_color: Vec4::ONE,
            metallic: 0.0,
            roughness: 0.0,
            transmission: 1.0,
            ior: 1.5,
            dispersion,
            ..Material::default()
        }
    }

    /// The shading a scene keeps for an untextured material is what the material gives at any point where
    /// the vertex colour is white, bit for bit; a coloured vertex and a textured material are computed anew.
    #[test]
    fn constant_shading_is_the_materials_own_wherever_it_is_used() {
        let mut coated = glass(0.0);
        coated.clearcoat = Some(ClearcoatLayer {
            factor: 0.5,
            ..ClearcoatLayer::default()
        });
        let materials = [
            Material::lambertian("wall", Rgb::new(0.73, 0.5, 0.2)),
            Material {
                metallic: 1.0,
                roughness: 0.0,
                ..Material::default()
            },
            glass(0.0),
            coated,
        ];
        let white = ShadingPoint::from(TexCoord {
            uv: Vec2::new(0.3, 0.7),
            footprint: 0.01,
        });
        let coloured = ShadingPoint {
            color: Vec4::new(0.5, 0.25, 1.0, 1.0),
            ..white
        };
        for m in &materials {
            let constant = m.constant_shading().expect("no textures");
            for at in [&white, &coloured] {
                let shading = MaterialShading::at(Some(&constant), m, at, &[]);
                assert_eq!(*shading, MaterialShading::of(m, at, &[]));
                assert_eq!(shading.params, m.pbr_params(at, &[]));
                assert_eq!(shading.bsdf, Bsdf::from_gltf(&m.pbr_params(at, &[])));
            }
        }
        assert_ne!(
            MaterialShading::of(&materials[0], &coloured, &[])
                .params
                .base_color,
            materials[0].constant_shading().unwrap().params.base_color,
            "a coloured vertex changes the base colour"
        );
        let textured = Material {
            base_color_texture: Some(0),
            ..materials[0].clone()
        };
        assert!(textured.constant_shading().is_none());
    }

    #[test]
    fn dispersion_refracts_each_channel_by_snell_with_the_cauchy_index() {
        let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
        // Abbe number V = 20 / dispersion; Cauchy's fit through n_d at the d line (587.56 nm).
        let mut worst = 0.0f64;
        for (dispersion, n_d) in [(1.0f32, 1.5f32), (0.4, 1.7), (2.5, 1.33)] {
            let m = Material {
                ior: n_d,
                ..glass(dispersion)
            };
            let abbe = 20.0 / dispersion as f64;
            let mut previous = 0.0;
            for (c, &lambda) in RGB_WAVELENGTHS_NM.iter().enumerate() {
                let lambda = lambda as f64;
                let n_d = n_d as f64;
                let n =
                    (n_d + (n_d - 1.0) / abbe * (523655.0 / (lambda * lambda) - 1.5168)).max(1.0);
                assert!((m.dispersed_ior(c) as f64 - n).abs() < 1e-6);
                assert!(n > previous, "shorter wavelengths bend more");
                previous = n;
                let Bsdf::Dielectric(d) = m.bsdf_in_channel(&at, &[], c) else {
                    panic!("smooth glass");
                };
                for theta_deg in [10.0f64, 35.0, 60.0, 80.0] {
                    let theta = theta_deg.to_radians();
                    let wo = Vec3::new(theta.sin() as f32, 0.0, theta.cos() as f32);
                    // u_lobe near 1: the refracted branch.
                    let s = d.sample(wo, 0.999_999, Vec2::splat(0.5)).unwrap();
                    assert!(s.wi.z < 0.0);
                    let refracted = (s.wi.x.hypot(s.wi.y) as f64).asin();
                    let snell = (theta.sin() / n).asin();
                    worst = worst.max((refracted - snell).abs());
                    assert!((refracted - snell).abs() < 2e-6, "{refracted} vs {snell}");
                    assert!(s.wi.x <= 0.0, "the far side of the normal");
                }
            }
        }
        println!("dispersion: worst |refraction − Snell| = {worst:.2e} rad");
        // At the d line the index is n_d itself.
        let n_at_d = 1.5 + 0.5 / 20.0 * (523655.0 / (587.56f64 * 587.56) - 1.5168);
        assert!((n_at_d - 1.5).abs() < 1e-4);
    }

    #[test]
    fn no_dispersion_is_the_same_bsdf_in_every_channel() {
        let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
        let m = glass(0.0);
        assert!(!m.is_dispersive());
        for c in 0..3 {
            assert_eq!(m.dispersed_ior(c).to_bits(), m.ior.to_bits());
            assert_eq!(m.bsdf_in_channel(&at, &[], c), m.bsdf(&at, &[]));
        }
        // An opaque material does not disperse, whatever its dispersion.
        let opaque = Material {
            transmission: 0.0,
            ..glass(1.0)
        };
        assert!(!opaque.is_dispersive());
        assert_eq!(opaque.dispersed_ior(2), opaque.ior);
    }

    #[test]
    fn diffuse_transmission_keeps_back_faces_and_reads_its_textures() {
        let mut m = Material::lambertian("leaf", Rgb::ONE);
        assert!(m.culls_back_faces());
        m.diffuse_transmission = Some(DiffuseTransmission {
            factor: 0.5,
            color: Rgb::new(1.0, 0.5, 0.25),
            ..Default::default()
        });
        assert!(m.transmits_diffusely() && !m.culls_back_faces() && !m.is_transmissive());
        let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
        let p = m.pbr_params(&at, &[]);
        assert_eq!(p.diffuse_transmission, 0.5);
        assert_eq!(p.diffuse_transmission_color, Rgb::new(1.0, 0.5, 0.25));
        m.iridescence = Some(Iridescence {
            factor: 0.7,
            ..Default::default()
        });
        let p = m.pbr_params(&at, &[]);
        assert_eq!(
            (p.iridescence, p.iridescence_ior, p.iridescence_thickness),
            (0.7, 1.3, 400.0)
        );
    }
}
