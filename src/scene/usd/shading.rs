//! USD shading: `material:binding`, `Material` → `UsdPreviewSurface` and `UsdUVTexture` inputs.

use super::values::{number, token, vec2, vec3, vec3_array, vec4};
use super::Loader;
use crate::material::{ColorSpace, Material, Texture, UvTransform};
use crate::math::{Rgb, Vec2, Vec4};
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use openusd::{sdf, usd};
use std::path::PathBuf;

/// What a texture feeds, which decides how its `scale` and `bias` are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum TextureRole {
    /// A colour input: the texture holds `tex × scale + bias`.
    Color,
    /// The `normal` input: `tex × scale + bias` is the tangent-space normal in [−1, 1]³, stored as
    /// `(n + 1) / 2`, the encoding [`Material::normal_map`] decodes.
    Normal,
}

/// A loaded texture's identity: the file, its colour space, its role and the `scale` and `bias` baked in.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub(super) struct TextureKey {
    file: PathBuf,
    srgb: bool,
    role: TextureRole,
    /// The bits of `scale` then `bias`.
    affine: [u32; 8],
}

/// The `info:id` of MaterialX's Autodesk Standard Surface shader node.
const STANDARD_SURFACE: &str = "ND_standard_surface_surfaceshader";

/// A base colour read per vertex from a mesh primvar: `primvars:NAME` times the material's base colour, or
/// `fallback` on a mesh without it (UsdPrimvarReader's `fallback`).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct PrimvarColor {
    /// The attribute: `primvars:` and the reader's `varname`.
    pub(super) attribute: String,
    /// The colour of a mesh that does not author the primvar.
    pub(super) fallback: Rgb,
}

/// One channel of a texture feeding a scalar input, with the transform of its coordinates.
struct ScalarMap {
    width: usize,
    height: usize,
    /// Row-major values, top row first.
    values: Vec<f32>,
    transform: UvTransform,
}

/// Texels of a packed texture.
struct Packed {
    width: usize,
    height: usize,
    texels: Vec<Vec4>,
}

impl ScalarMap {
    /// The nearest value at (x + ½, y + ½) of a `width` × `height` raster over the same [0, 1]² image.
    fn at(&self, x: usize, y: usize, width: usize, height: usize) -> f32 {
        let sx = ((x * self.width) / width).min(self.width - 1);
        let sy = ((y * self.height) / height).min(self.height - 1);
        self.values[sy * self.width + sx]
    }

    /// glTF's metallic-roughness layout from two maps (either may be absent, read as 1): roughness in G and
    /// metalness in B, at the larger map's resolution (the other resampled by nearest texel).
    fn pack(roughness: Option<&ScalarMap>, metallic: Option<&ScalarMap>) -> Packed {
        let (width, height) = [roughness, metallic]
            .into_iter()
            .flatten()
            .map(|m| (m.width, m.height))
            .max_by_key(|&(w, h)| w * h)
            .unwrap_or((1, 1));
        let read = |map: Option<&ScalarMap>, x, y| map.map_or(1.0, |m| m.at(x, y, width, height));
        let texels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| Vec4::new(0.0, read(roughness, x, y), read(metallic, x, y), 1.0))
            .collect();
        Packed {
            width,
            height,
            texels,
        }
    }
}

/// A `UsdTransform2d` (`st' = translation + R(rotation) · (scale ⊙ st)`, rotation in degrees counter-clockwise
/// in st space, v up; UsdPreviewSurface specification) as a transform of Nimbus's texture coordinates, which
/// the loader flips to v down (`uv = (s, 1 − t)`). Conjugating by that flip F gives
/// `uv' = R(−θ)·S·uv + (tx − sy·sin θ, 1 − ty − sy·cos θ)`: [`UvTransform`]'s matrix with rotation θ, its scale,
/// and that offset.
pub(super) fn usd_transform_2d(
    rotation_degrees: f32,
    scale: Vec2,
    translation: Vec2,
) -> UvTransform {
    let theta = rotation_degrees.to_radians();
    let (sin, cos) = theta.sin_cos();
    UvTransform {
        offset: Vec2::new(
            translation.x - scale.y * sin,
            1.0 - translation.y - scale.y * cos,
        ),
        rotation: theta,
        scale,
    }
}

/// UsdUVTexture's default `scale` and `bias` (UsdPreviewSurface spec, UsdUVTexture inputs).
const IDENTITY_AFFINE: (Vec4, Vec4) = (Vec4::ONE, Vec4::ZERO);

/// The `scale` and `bias` assumed for an 8-bit normal map that authors neither: the UsdPreviewSurface spec's
/// recommended values for such maps.
const NORMAL_MAP_AFFINE: (Vec4, Vec4) = (
    Vec4::new(2.0, 2.0, 2.0, 1.0),
    Vec4::new(-1.0, -1.0, -1.0, 0.0),
);

impl Loader<'_> {
    /// The material bound directly to `prim` (`material:binding`), if any.
    pub(super) fn binding(&self, prim: &usd::Prim) -> Result<Option<String>, SceneError> {
        let targets = prim
            .relationship("material:binding")
            .targets()
            .map_err(|e| {
                self.error(
                    MalformedPart::Material,
                    prim.path().as_str(),
                    format!("{e:#}"),
                )
            })?;
        Ok(targets.first().map(|p| p.prim_path().as_str().to_owned()))
    }

    /// The material index for a gprim: the bound `UsdPreviewSurface`, else one from `primvars:displayColor`.
    /// With `per_vertex` (a mesh, which reads colour primvars per face corner), a `displayColor` of more than
    /// one value makes a white material whose colour the mesh gives per vertex ([`Self::primvar_color`]);
    /// other gprims take its first value.
    pub(super) fn material(
        &mut self,
        prim: &usd::Prim,
        binding: Option<&str>,
        double_sided: bool,
        per_vertex: bool,
    ) -> Result<u32, SceneError> {
        let key = match binding {
            Some(b) => b.to_owned(),
            None => {
                let display = self.value(prim, "primvars:displayColor")?;
                let colors = display
                    .as_ref()
                    .and_then(|v| vec3(v).map(|c| vec![c]).or_else(|| vec3_array(v)))
                    .unwrap_or_default();
                let mut m = preview_defaults(prim.path().as_str());
                m.double_sided = double_sided;
                let varying = per_vertex && colors.len() > 1;
                let color = if varying {
                    Rgb::ONE
                } else {
                    colors.first().copied().unwrap_or(Rgb::splat(0.18))
                };
                m.base_color = color.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
                let id = self.builder.add_material(m);
                if varying {
                    let color = PrimvarColor {
                        attribute: "primvars:displayColor".into(),
                        fallback: Rgb::splat(0.18),
                    };
                    self.primvar_colors.insert(id, color);
                }
                return Ok(id);
            }
        };
        if let Some(&id) = self.materials.get(&(key.clone(), double_sided)) {
            return Ok(id);
        }
        let (mut m, primvar_color) = self.preview_surface(&key)?;
        m.double_sided = double_sided;
        let id = self.builder.add_material(m);
        self.materials.insert((key, double_sided), id);
        if let Some(color) = primvar_color {
            self.primvar_colors.insert(id, color);
        }
        Ok(id)
    }

    /// The per-vertex base colour that material `material` asks of its meshes, if any.
    pub(super) fn primvar_color(&self, material: u32) -> Option<&PrimvarColor> {
        self.primvar_colors.get(&material)
    }

    /// The primvar reader a shader input connects to: a `UsdPrimvarReader_float3` (or `_float4`, whose first
    /// three components are read) gives the primvar `primvars:<varname>` and its `fallback`. Readers of other
    /// types are reported and the input keeps its value.
    fn primvar_reader(
        &mut self,
        shader: &usd::Prim,
        name: &str,
    ) -> Result<Option<PrimvarColor>, SceneError> {
        let Some(reader) = self.connection(shader, name)? else {
            return Ok(None);
        };
        let id = self.shader_id(&reader)?;
        if !id.starts_with("UsdPrimvarReader_") {
            return Ok(None);
        }
        let at = reader.path().as_str().to_owned();
        if id != "UsdPrimvarReader_float3" && id != "UsdPrimvarReader_float4" {
            self.warn(format!(
                "{}.{name}: {id} ({at}) is not read; the input's value is used",
                shader.path().as_str()
            ));
            return Ok(None);
        }
        let Some(varname) = self
            .value(&reader, "inputs:varname")?
            .and_then(|v| token(&v))
        else {
            self.warn(format!(
                "{at}: a primvar reader without inputs:varname; {}.{name}'s value is used",
                shader.path().as_str()
            ));
            return Ok(None);
        };
        let fallback = match self.value(&reader, "inputs:fallback")? {
            Some(v) => vec3(&v)
                .or_else(|| vec4(&v).map(|c| c.truncate()))
                .unwrap_or(Rgb::ZERO),
            None => Rgb::ZERO,
        };
        Ok(Some(PrimvarColor {
            attribute: format!("primvars:{varname}"),
            fallback,
        }))
    }

    /// Maps the `UsdPreviewSurface` behind material prim `path` onto a [`Material`]:
    /// diffuseColor → base colour (default 0.18), metallic (0), roughness (0.5), emissiveColor → emission,
    /// ior (1.5), opacity (1) → transmission 1 − opacity; glTF's default specular layer is kept
    /// (UsdPreviewSurface has no specular factor: a diffuse material with metallic 0 still has a dielectric
    /// coat of the given ior); `useSpecularWorkflow` 1 is read as metallic 0 with a warning.
    pub(super) fn preview_surface(
        &mut self,
        path: &str,
    ) -> Result<(Material, Option<PrimvarColor>), SceneError> {
        let material = self.stage.prim(path);
        let mut m = preview_defaults(path);
        let surface = material
            .attribute("outputs:surface")
            .connections()
            .map_err(|e| self.error(MalformedPart::Material, path, format!("{e:#}")))?;
        let Some(shader_path) = surface.first().map(|p| p.prim_path()) else {
            let mtlx = material
                .attribute("outputs:mtlx:surface")
                .connections()
                .map_err(|e| self.error(MalformedPart::Material, path, format!("{e:#}")))?;
            if let Some(shader) = mtlx
                .first()
                .map(|p| self.stage.prim(p.prim_path().as_str()))
            {
                return self.standard_surface(path, &shader).map(|m| (m, None));
            }
            self.warn(format!(
                "material {path} has no outputs:surface; default surface used"
            ));
            return Ok((m, None));
        };
        let shader = self.stage.prim(shader_path.as_str());
        let id = self.shader_id(&shader)?;
        if id == STANDARD_SURFACE {
            return self.standard_surface(path, &shader).map(|m| (m, None));
        }
        if id != "UsdPreviewSurface" {
            self.warn(format!(
                "material {path}: shader '{id}' is not UsdPreviewSurface; default surface used"
            ));
            return Ok((m, None));
        }
        let primvar_color = self.primvar_reader(&shader, "inputs:diffuseColor")?;
        if primvar_color.is_some() {
            // White, times the primvar each mesh gives per vertex.
            m.base_color = Vec4::ONE;
        } else {
            let (diffuse, diffuse_tex) =
                self.color_input(&shader, "inputs:diffuseColor", Rgb::splat(0.18), true)?;
            m.base_color = diffuse.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
            m.base_color_texture = diffuse_tex;
        }
        let (emission, emission_tex) =
            self.color_input(&shader, "inputs:emissiveColor", Rgb::ZERO, true)?;
        m.emission = emission.max(Rgb::ZERO);
        m.emission_texture = emission_tex;
        self.metallic_roughness(path, &shader, &mut m)?;
        m.ior = self.scalar_input(&shader, "inputs:ior", 1.5)?;
        m.transmission = (1.0 - self.scalar_input(&shader, "inputs:opacity", 1.0)?).clamp(0.0, 1.0);
        m.normal_texture = self
            .texture_of(&shader, "inputs:normal", false, TextureRole::Normal)?
            .map(|t| (t, 1.0));
        let specular_workflow = match self.value(&shader, "inputs:useSpecularWorkflow")? {
            Some(v) => number(&v).unwrap_or(0.0) != 0.0,
            None => false,
        };
        if specular_workflow {
            m.metallic = 0.0;
            self.warn(format!(
                "material {path}: useSpecularWorkflow is not supported; read as metallic 0"
            ));
        }
        Ok((m, primvar_color))
    }

    /// Sets `m`'s metallic and roughness from the UsdPreviewSurface `shader` of material `path`: their values
    /// (0 and 0.5 by default), and their textures packed into one in glTF's layout.
    fn metallic_roughness(
        &mut self,
        path: &str,
        shader: &usd::Prim,
        m: &mut Material,
    ) -> Result<(), SceneError> {
        m.metallic = self.float(shader, "inputs:metallic", 0.0)?;
        m.roughness = self.float(shader, "inputs:roughness", 0.5)?;
        let roughness_map = self.scalar_texture(shader, "inputs:roughness")?;
        let metallic_map = self.scalar_texture(shader, "inputs:metallic")?;
        if roughness_map.is_some() || metallic_map.is_some() {
            // glTF's layout: roughness in G, metalness in B, each times its factor (1 where textured).
            let transform = roughness_map
                .as_ref()
                .or(metallic_map.as_ref())
                .map_or(UvTransform::default(), |map| map.transform);
            if roughness_map.is_some() {
                m.roughness = 1.0;
            }
            if metallic_map.is_some() {
                m.metallic = 1.0;
            }
            let packed = ScalarMap::pack(roughness_map.as_ref(), metallic_map.as_ref());
            let texture = Texture::from_linear(packed.width, packed.height, packed.texels)
                .ok_or_else(|| {
                    self.error(
                        MalformedPart::Material,
                        path,
                        "empty metallic-roughness texture",
                    )
                })?;
            self.builder.textures.push(texture);
            let id = (self.builder.textures.len() - 1) as u32;
            m.metallic_roughness_texture = Some(self.transformed(id, transform));
        }
        Ok(())
    }

    /// Maps a MaterialX `standard_surface` shader (Autodesk Standard Surface 1.0.1, as MaterialX 1.38 defines
    /// it) read as a UsdPreviewSurface would be: `base` × `base_color` → base colour, `metalness` → metallic,
    /// `specular_roughness` → roughness, `specular_IOR` → ior, `transmission` → transmission, `emission` ×
    /// `emission_color` → emission. `base_color` and `emission_color` may come from an image node
    /// (`ND_image_*`, `ND_tiledimage_*`: its `file`); any other node feeding an input, and a non-zero `coat`,
    /// `subsurface`, `sheen` or `thin_film_thickness`, is reported in a warning naming it, and the input keeps its
    /// value.
    fn standard_surface(&mut self, path: &str, shader: &usd::Prim) -> Result<Material, SceneError> {
        let id = self.shader_id(shader)?;
        let mut m = preview_defaults(path);
        if id != STANDARD_SURFACE {
            self.warn(format!(
                "material {path}: MaterialX shader '{id}' is not {STANDARD_SURFACE}; default surface used"
            ));
            return Ok(m);
        }
        // The node definition's defaults: base 0.8, base_color white.
        let base = self.mtlx_float(shader, "inputs:base", 0.8)?;
        let (base_color, base_texture) = self.mtlx_color(shader, "inputs:base_color", Rgb::ONE)?;
        m.base_color = (base_color * base).clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
        m.base_color_texture = base_texture;
        // (A texture's texels are scaled by `base` through the base colour factor.)
        m.metallic = self
            .mtlx_float(shader, "inputs:metalness", 0.0)?
            .clamp(0.0, 1.0);
        m.roughness = self
            .mtlx_float(shader, "inputs:specular_roughness", 0.2)?
            .clamp(0.0, 1.0);
        m.ior = self.mtlx_float(shader, "inputs:specular_IOR", 1.5)?;
        m.transmission = self
            .mtlx_float(shader, "inputs:transmission", 0.0)?
            .clamp(0.0, 1.0);
        let emission = self.mtlx_float(shader, "inputs:emission", 0.0)?;
        let (emission_color, emission_texture) =
            self.mtlx_color(shader, "inputs:emission_color", Rgb::ONE)?;
        m.emission = (emission_color * emission).max(Rgb::ZERO);
        m.emission_texture = emission_texture.filter(|_| emission > 0.0);
        for unread in [
            "inputs:coat",
            "inputs:subsurface",
            "inputs:sheen",
            "inputs:thin_film_thickness",
        ] {
            if self.mtlx_float(shader, unread, 0.0)? > 0.0 {
                self.warn(format!(
                    "{}.{unread}: not read by Nimbus's standard_surface mapping; left out",
                    shader.path().as_str()
                ));
            }
        }
        Ok(m)
    }

    /// A MaterialX colour input: an image node's texture (white), else the authored value (a warning names any
    /// other node connected to it).
    fn mtlx_color(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: Rgb,
    ) -> Result<(Rgb, Option<u32>), SceneError> {
        if let Some(node) = self.connection(shader, name)? {
            let id = self.shader_id(&node)?;
            if id.starts_with("ND_image_") || id.starts_with("ND_tiledimage_") {
                if let Some(t) = self.texture_of(shader, name, true, TextureRole::Color)? {
                    return Ok((Rgb::ONE, Some(t)));
                }
            } else {
                self.warn_unread_node(shader, name, &node, &id);
            }
        }
        Ok((self.color(shader, name, default)?, None))
    }

    /// A MaterialX float input's authored value (a warning names any node connected to it).
    fn mtlx_float(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: f32,
    ) -> Result<f32, SceneError> {
        if let Some(node) = self.connection(shader, name)? {
            let id = self.shader_id(&node)?;
            self.warn_unread_node(shader, name, &node, &id);
        }
        self.float(shader, name, default)
    }

    /// The warning for a MaterialX node graph Nimbus does not evaluate.
    fn warn_unread_node(&mut self, shader: &usd::Prim, name: &str, node: &usd::Prim, id: &str) {
        self.warn(format!(
            "{}.{name}: MaterialX node {} ('{id}') is not evaluated; the input's own value is used",
            shader.path().as_str(),
            node.path().as_str()
        ));
    }

    /// A scalar shader input; a texture connection is reported and its fallback value used.
    pub(super) fn scalar_input(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: f32,
    ) -> Result<f32, SceneError> {
        if self.connection(shader, name)?.is_some() {
            self.warn(format!(
                "{}.{name}: textured scalar inputs are not supported; value used",
                shader.path().as_str()
            ));
        }
        self.float(shader, name, default)
    }

    /// A colour shader input: its value, or white and a texture when it connects to a `UsdUVTexture`.
    pub(super) fn color_input(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        default: Rgb,
        srgb: bool,
    ) -> Result<(Rgb, Option<u32>), SceneError> {
        match self.texture_of(shader, name, srgb, TextureRole::Color)? {
            Some(t) => Ok((Rgb::ONE, Some(t))),
            None => Ok((self.color(shader, name, default)?, None)),
        }
    }

    /// A shader prim's `info:id` (empty when it has none).
    fn shader_id(&self, shader: &usd::Prim) -> Result<String, SceneError> {
        Ok(self
            .value(shader, "info:id")?
            .and_then(|v| token(&v))
            .unwrap_or_default())
    }

    /// The prim an input connects to, if any.
    pub(super) fn connection(
        &self,
        shader: &usd::Prim,
        name: &str,
    ) -> Result<Option<usd::Prim>, SceneError> {
        let targets = shader.attribute(name).connections().map_err(|e| {
            self.error(
                MalformedPart::Material,
                shader.path().as_str(),
                format!("{e:#}"),
            )
        })?;
        Ok(targets
            .first()
            .map(|p| self.stage.prim(p.prim_path().as_str())))
    }

    /// The texture a shader input reads through a `UsdUVTexture` (`inputs:file`, `inputs:sourceColorSpace`,
    /// `inputs:scale`, `inputs:bias`: the value is `tex × scale + bias`, UsdPreviewSurface spec), loaded once
    /// per file, colour space, role and scale/bias. A file that cannot be read (missing, or outside its
    /// package) or a MaterialX document is a warning naming the texture prim and the file, and the input keeps
    /// its untextured value.
    pub(super) fn texture_of(
        &mut self,
        shader: &usd::Prim,
        name: &str,
        srgb_default: bool,
        role: TextureRole,
    ) -> Result<Option<u32>, SceneError> {
        let Some(tex) = self.connection(shader, name)? else {
            return Ok(None);
        };
        let Some(file) = self.asset(&tex, "inputs:file")? else {
            return Ok(None);
        };
        let at = tex.path().as_str().to_owned();
        if file
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("mtlx"))
        {
            self.warn(format!(
                "{at}: texture file {} is a MaterialX document, not an image; untextured value used",
                file.display()
            ));
            return Ok(None);
        }
        let srgb = match self
            .value(&tex, "inputs:sourceColorSpace")?
            .and_then(|v| token(&v))
            .as_deref()
        {
            Some("raw") => false,
            Some("sRGB") => true,
            _ => srgb_default,
        };
        let (scale, bias) = self.scale_bias(&tex, role)?;
        let key = TextureKey {
            file: file.clone(),
            srgb,
            role,
            affine: [scale.to_array(), bias.to_array()]
                .concat()
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
                .try_into()
                .unwrap_or_default(),
        };
        let transform = self.st_transform(&tex)?;
        if let Some(&id) = self.textures.get(&key) {
            return Ok(Some(self.transformed(id, transform)));
        }
        let bytes = match self.read_asset(&file) {
            Ok(bytes) => bytes,
            Err(e) => {
                self.warn(format!(
                    "{at}: texture file {} cannot be read ({e}); untextured value used",
                    file.display()
                ));
                return Ok(None);
            }
        };
        // The RGBA8 copy and the float mip pyramid (16 bytes a texel, 4/3 for the levels).
        let image = crate::limits::decode_image_named(&bytes, Some(&file), &self.limits, 4 + 22)
            .map_err(|e| {
                SceneError::new(
                    &file,
                    SceneErrorKind::malformed(MalformedPart::Texture, e.to_string()),
                )
            })?
            .to_rgba8();
        let t = texture_from_image(&image, srgb, (scale, bias), role).ok_or_else(|| {
            SceneError::new(
                &file,
                SceneErrorKind::malformed(MalformedPart::Texture, "empty image"),
            )
        })?;
        self.builder.textures.push(t);
        let id = (self.builder.textures.len() - 1) as u32;
        self.textures.insert(key, id);
        Ok(Some(self.transformed(id, transform)))
    }

    /// Texture `id` read through `transform`: the same pixels under a second mapping (made once per texture
    /// and transform), or `id` itself for the identity.
    fn transformed(&mut self, id: u32, transform: UvTransform) -> u32 {
        if transform.is_identity() {
            return id;
        }
        let key = (
            id,
            [
                transform.offset.x,
                transform.offset.y,
                transform.rotation,
                transform.scale.x,
                transform.scale.y,
            ]
            .map(f32::to_bits),
        );
        if let Some(&mapped) = self.transformed_textures.get(&key) {
            return mapped;
        }
        let texture = self.builder.textures[id as usize]
            .clone()
            .with_mapping(0, transform);
        self.builder.textures.push(texture);
        let mapped = (self.builder.textures.len() - 1) as u32;
        self.transformed_textures.insert(key, mapped);
        mapped
    }

    /// A scalar shader input read from one channel of a `UsdUVTexture` (`outputs:r`, `g`, `b` or `a`, after
    /// the texture's `scale` and `bias`; `sourceColorSpace` `sRGB` decodes r, g and b, anything else reads them
    /// raw, as single channels usually are). `None` for an input without a texture; a texture that cannot be
    /// read, or a connection to anything else, is a warning and the input keeps its value.
    fn scalar_texture(
        &mut self,
        shader: &usd::Prim,
        name: &str,
    ) -> Result<Option<ScalarMap>, SceneError> {
        let at = format!("{}.{name}", shader.path().as_str());
        let targets = shader
            .attribute(name)
            .connections()
            .map_err(|e| self.error(MalformedPart::Material, &at, format!("{e:#}")))?;
        let Some(target) = targets.first() else {
            return Ok(None);
        };
        let tex = self.stage.prim(target.prim_path().as_str());
        let output = target.as_str().rsplit('.').next().unwrap_or_default();
        let channel = match output {
            "outputs:r" => 0,
            "outputs:g" => 1,
            "outputs:b" => 2,
            "outputs:a" => 3,
            other => {
                self.warn(format!(
                    "{at}: connects to '{other}' of {}, not a texture channel (r, g, b, a); value used",
                    tex.path().as_str()
                ));
                return Ok(None);
            }
        };
        let Some(file) = self.asset(&tex, "inputs:file")? else {
            return Ok(None);
        };
        let bytes = match self.read_asset(&file) {
            Ok(bytes) => bytes,
            Err(e) => {
                self.warn(format!(
                    "{at}: texture file {} cannot be read ({e}); value used",
                    file.display()
                ));
                return Ok(None);
            }
        };
        let srgb = self
            .value(&tex, "inputs:sourceColorSpace")?
            .and_then(|v| token(&v))
            .is_some_and(|s| s == "sRGB");
        let (scale, bias) = self.scale_bias(&tex, TextureRole::Color)?;
        // The RGBA8 copy, the values and the packed texture's float mip pyramid.
        let image =
            crate::limits::decode_image_named(&bytes, Some(&file), &self.limits, 4 + 4 + 22)
                .map_err(|e| {
                    SceneError::new(
                        &file,
                        SceneErrorKind::malformed(MalformedPart::Texture, e.to_string()),
                    )
                })?
                .to_rgba8();
        let values = image
            .as_raw()
            .chunks_exact(4)
            .map(|p| {
                let v = p[channel] as f32 / 255.0;
                let v = if srgb && channel < 3 {
                    crate::math::srgb_to_linear(v)
                } else {
                    v
                };
                (v * scale[channel] + bias[channel]).clamp(0.0, 1.0)
            })
            .collect();
        Ok(Some(ScalarMap {
            width: image.width() as usize,
            height: image.height() as usize,
            values,
            transform: self.st_transform(&tex)?,
        }))
    }

    /// The `UsdTransform2d` a `UsdUVTexture`'s `inputs:st` goes through, as a transform of Nimbus's texture
    /// coordinates ([`usd_transform_2d`]); the identity when `st` connects straight to a primvar reader.
    fn st_transform(&mut self, texture: &usd::Prim) -> Result<UvTransform, SceneError> {
        let Some(node) = self.connection(texture, "inputs:st")? else {
            return Ok(UvTransform::default());
        };
        let id = self.shader_id(&node)?;
        if id != "UsdTransform2d" {
            return Ok(UvTransform::default());
        }
        let pair =
            |v: Option<sdf::Value>, default: Vec2| v.as_ref().and_then(vec2).unwrap_or(default);
        let rotation = self.float(&node, "inputs:rotation", 0.0)?;
        let scale = pair(self.value(&node, "inputs:scale")?, Vec2::ONE);
        let translation = pair(self.value(&node, "inputs:translation")?, Vec2::ZERO);
        let at = node.path().as_str();
        if !(rotation.is_finite() && scale.is_finite() && translation.is_finite()) {
            return Err(self.error(
                MalformedPart::Material,
                at,
                "UsdTransform2d inputs must be finite",
            ));
        }
        Ok(usd_transform_2d(rotation, scale, translation))
    }

    /// A `UsdUVTexture`'s `inputs:scale` and `inputs:bias` (float4; defaults 1 and 0). A normal map that
    /// authors neither is read with the 8-bit convention (scale 2, bias −1), as the UsdPreviewSurface spec
    /// recommends for such maps.
    fn scale_bias(&self, tex: &usd::Prim, role: TextureRole) -> Result<(Vec4, Vec4), SceneError> {
        let read = |name: &str| -> Result<Option<Vec4>, SceneError> {
            match self.value(tex, name)? {
                None => Ok(None),
                Some(v) => vec4(&v).filter(|v| v.is_finite()).map(Some).ok_or_else(|| {
                    self.error(
                        MalformedPart::Material,
                        &format!("{}.{name}", tex.path().as_str()),
                        "expected a float4",
                    )
                }),
            }
        };
        let (scale, bias) = (read("inputs:scale")?, read("inputs:bias")?);
        let (default_scale, default_bias) = match (role, scale, bias) {
            (TextureRole::Normal, None, None) => NORMAL_MAP_AFFINE,
            _ => IDENTITY_AFFINE,
        };
        Ok((scale.unwrap_or(default_scale), bias.unwrap_or(default_bias)))
    }
}

/// The UsdPreviewSurface defaults on Nimbus's material model (see `Loader::preview_surface`).
pub(super) fn preview_defaults(name: &str) -> Material {
    Material {
        name: name.to_owned(),
        base_color: Rgb::splat(0.18).extend(1.0),
        metallic: 0.0,
        roughness: 0.5,
        ..Material::default()
    }
}

/// A decoded UsdUVTexture image as a texture: each texel `tex × scale + bias` (`tex` decoded from sRGB when
/// `srgb`; alpha always linear), and a normal map's XYZ then stored in [0, 1] as glTF stores normal maps; `None`
/// for an empty image. The plain colour case keeps the 8-bit texels.
fn texture_from_image(
    image: &image::RgbaImage,
    srgb: bool,
    (scale, bias): (Vec4, Vec4),
    role: TextureRole,
) -> Option<Texture> {
    let space = if srgb {
        ColorSpace::Srgb
    } else {
        ColorSpace::Linear
    };
    let (w, h) = (image.width() as usize, image.height() as usize);
    if (scale, bias) == IDENTITY_AFFINE && role == TextureRole::Color {
        return Texture::from_rgba8(w, h, image.as_raw(), space);
    }
    let decode = |v: u8| {
        let f = v as f32 / 255.0;
        if srgb {
            crate::math::srgb_to_linear(f)
        } else {
            f
        }
    };
    let texels = image
        .as_raw()
        .chunks_exact(4)
        .map(|p| {
            let t = Vec4::new(
                decode(p[0]),
                decode(p[1]),
                decode(p[2]),
                p[3] as f32 / 255.0,
            );
            let v = t * scale + bias;
            match role {
                TextureRole::Color => v,
                TextureRole::Normal => ((v.truncate() + 1.0) * 0.5).extend(v.w),
            }
        })
        .collect();
    Texture::from_linear(w, h, texels)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transform of flipped coordinates equals UsdTransform2d applied in st space, then flipped: checked
    /// at points and parameters drawn from a fixed sequence.
    #[test]
    fn usd_transform_2d_is_the_st_transform_in_flipped_coordinates() {
        let mut rng = crate::math::Rng::new(5, 7);
        let mut draw = |lo: f32, hi: f32| lo + (hi - lo) * rng.next_f32();
        for _ in 0..200 {
            let (degrees, scale, translation) = (
                draw(-360.0, 360.0),
                Vec2::new(draw(-3.0, 3.0), draw(-3.0, 3.0)),
                Vec2::new(draw(-2.0, 2.0), draw(-2.0, 2.0)),
            );
            let st = Vec2::new(draw(-1.0, 2.0), draw(-1.0, 2.0));
            // UsdTransform2d in st space: scale, rotate counter-clockwise, translate.
            let (sin, cos) = degrees.to_radians().sin_cos();
            let scaled = st * scale;
            let usd = translation
                + Vec2::new(
                    cos * scaled.x - sin * scaled.y,
                    sin * scaled.x + cos * scaled.y,
                );
            let ours =
                usd_transform_2d(degrees, scale, translation).apply(Vec2::new(st.x, 1.0 - st.y));
            let want = Vec2::new(usd.x, 1.0 - usd.y);
            assert!(
                ours.distance(want) < 1e-4,
                "{degrees} {scale} {translation} {st}: {ours} vs {want}"
            );
        }
        assert!(usd_transform_2d(0.0, Vec2::ONE, Vec2::ZERO).is_identity());
    }
}
