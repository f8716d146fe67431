//! The surface material of a primitive: glTF 2.0 metallic-roughness parameters and textures, which create a
//! [`Bsdf`] at each hit and may own the medium of the primitive's interior (Fong et al. 2017, §4).
//!
//! glTF keys read: `pbrMetallicRoughness.{baseColorFactor, baseColorTexture, metallicFactor, roughnessFactor,
//! metallicRoughnessTexture}`, `normalTexture` (+ `scale`), `emissiveFactor`, `emissiveTexture`,
//! `doubleSided`, and the extensions `KHR_materials_emissive_strength.emissiveStrength`,
//! `KHR_materials_specular.{specularFactor, specularColorFactor}`, `KHR_materials_transmission.transmissionFactor`,
//! `KHR_materials_ior.ior` (default 1.5). OBJ/MTL materials are mapped onto the same fields by the OBJ loader.

use super::texture::{TexCoord, Texture};
use super::{Bsdf, PbrParams};
use crate::math::{Rgb, Vec3, Vec4};

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
    /// When false the back face of an opaque surface reflects nothing.
    pub double_sided: bool,
    /// The medium filling the interior of a closed mesh with this material (index into `Scene::media`).
    pub interior: Option<u32>,
    /// How the coverage (alpha) is used: opaque, a cut-out, or partial coverage (glTF `alphaMode`).
    pub alpha_mode: AlphaMode,
    /// Optional coverage texture whose first channel multiplies alpha (OBJ `map_d`); glTF takes alpha from the
    /// base-colour texture instead.
    pub alpha_texture: Option<TextureId>,
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
            emission: Rgb::ZERO,
            emission_texture: None,
            ior: 1.5,
            specular_factor: 1.0,
            specular_color: Rgb::ONE,
            transmission: 0.0,
            double_sided: false,
            interior: None,
            alpha_mode: AlphaMode::Opaque,
            alpha_texture: None,
        }
    }
}

fn lookup(textures: &[Texture], id: Option<TextureId>, tc: TexCoord) -> Option<Vec4> {
    id.and_then(|i| textures.get(i as usize))
        .map(|t| t.lookup(tc))
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

    /// True when the material emits light from its front faces.
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// True when light can pass through the surface (the BSDF has a transmission lobe).
    pub fn is_transmissive(&self) -> bool {
        self.transmission > 0.0
    }

    /// Emitted radiance at texture coordinates `tc` of a front face.
    pub fn emission_at(&self, tc: TexCoord, textures: &[Texture]) -> Rgb {
        match lookup(textures, self.emission_texture, tc) {
            Some(t) => self.emission * t.truncate(),
            None => self.emission,
        }
    }

    /// The BSDF parameters at texture coordinates `tc`.
    pub fn pbr_params(&self, tc: TexCoord, textures: &[Texture]) -> PbrParams {
        let mut base = self.base_color.truncate();
        if let Some(t) = lookup(textures, self.base_color_texture, tc) {
            base *= t.truncate();
        }
        let (mut metallic, mut roughness) = (self.metallic, self.roughness);
        if let Some(t) = lookup(textures, self.metallic_roughness_texture, tc) {
            roughness *= t.y;
            metallic *= t.z;
        }
        PbrParams {
            base_color: base.clamp(Vec3::ZERO, Vec3::ONE),
            metallic: metallic.clamp(0.0, 1.0),
            roughness: roughness.clamp(0.0, 1.0),
            ior: self.ior,
            specular_factor: self.specular_factor.clamp(0.0, 1.0),
            specular_color: self.specular_color.max(Vec3::ZERO),
            transmission: self.transmission.clamp(0.0, 1.0),
        }
    }

    /// Creates the BSDF for a hit at texture coordinates `tc`.
    pub fn bsdf(&self, tc: TexCoord, textures: &[Texture]) -> Bsdf {
        Bsdf::from_gltf(&self.pbr_params(tc, textures))
    }

    /// The coverage at texture coordinates `tc`: `base_color.w` × the base-colour texture's alpha × the first
    /// channel of `alpha_texture`, in \[0, 1\]. Only [`AlphaMode::Mask`] and [`AlphaMode::Blend`] use it.
    pub fn alpha_at(&self, tc: TexCoord, textures: &[Texture]) -> f32 {
        let mut alpha = self.base_color.w;
        if let Some(t) = lookup(textures, self.base_color_texture, tc) {
            alpha *= t.w;
        }
        if let Some(t) = lookup(textures, self.alpha_texture, tc) {
            alpha *= t.x;
        }
        alpha.clamp(0.0, 1.0)
    }

    /// True when the material has a normal map.
    pub fn has_normal_map(&self) -> bool {
        self.normal_texture.is_some()
    }

    /// The tangent-space normal from the normal map at `tc` (z up), or `None` without a normal map.
    /// glTF stores `(n * 0.5 + 0.5)`; `scale` multiplies the x and y components.
    pub fn normal_map(&self, tc: TexCoord, textures: &[Texture]) -> Option<Vec3> {
        let (id, scale) = self.normal_texture?;
        let t = textures.get(id as usize)?.lookup(tc);
        let n = Vec3::new(
            (t.x * 2.0 - 1.0) * scale,
            (t.y * 2.0 - 1.0) * scale,
            t.z * 2.0 - 1.0,
        );
        let n = n.normalize_or_zero();
        (n.z > 0.0).then_some(n)
    }
}
