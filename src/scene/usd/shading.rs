//! USD shading: `material:binding`, `Material` → `UsdPreviewSurface` and `UsdUVTexture` inputs.

use super::values::{number, token, vec3, vec3_array, vec4};
use super::Loader;
use crate::material::{ColorSpace, Material, Texture};
use crate::math::{Rgb, Vec4};
use crate::scene::{SceneError, SceneErrorKind};
use openusd::usd;
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
            .map_err(|e| self.error(prim.path().as_str(), format!("{e:#}")))?;
        Ok(targets.first().map(|p| p.prim_path().as_str().to_owned()))
    }

    /// The material index for a mesh: the bound `UsdPreviewSurface`, else one from `primvars:displayColor`.
    pub(super) fn material(
        &mut self,
        prim: &usd::Prim,
        binding: Option<&str>,
        double_sided: bool,
    ) -> Result<u32, SceneError> {
        let key = match binding {
            Some(b) => b.to_owned(),
            None => {
                let color = match self.value(prim, "primvars:displayColor")? {
                    Some(v) => vec3(&v).or_else(|| vec3_array(&v).and_then(|c| c.first().copied())),
                    None => None,
                }
                .unwrap_or(Rgb::splat(0.18));
                let mut m = preview_defaults(prim.path().as_str());
                m.base_color = color.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
                m.double_sided = double_sided;
                return Ok(self.builder.add_material(m));
            }
        };
        if let Some(&id) = self.materials.get(&(key.clone(), double_sided)) {
            return Ok(id);
        }
        let mut m = self.preview_surface(&key)?;
        m.double_sided = double_sided;
        let id = self.builder.add_material(m);
        self.materials.insert((key, double_sided), id);
        Ok(id)
    }

    /// Maps the `UsdPreviewSurface` behind material prim `path` onto a [`Material`]:
    /// diffuseColor → base colour (default 0.18), metallic (0), roughness (0.5), emissiveColor → emission,
    /// ior (1.5), opacity (1) → transmission 1 − opacity; glTF's default specular layer is kept
    /// (UsdPreviewSurface has no specular factor: a diffuse material with metallic 0 still has a dielectric
    /// coat of the given ior); `useSpecularWorkflow` 1 is read as metallic 0 with a warning.
    pub(super) fn preview_surface(&mut self, path: &str) -> Result<Material, SceneError> {
        let material = self.stage.prim(path);
        let mut m = preview_defaults(path);
        let surface = material
            .attribute("outputs:surface")
            .connections()
            .map_err(|e| self.error(path, format!("{e:#}")))?;
        let Some(shader_path) = surface.first().map(|p| p.prim_path()) else {
            self.warn(format!(
                "material {path} has no outputs:surface; default surface used"
            ));
            return Ok(m);
        };
        let shader = self.stage.prim(shader_path.as_str());
        let id = self
            .value(&shader, "info:id")?
            .and_then(|v| token(&v))
            .unwrap_or_default();
        if id != "UsdPreviewSurface" {
            self.warn(format!(
                "material {path}: shader '{id}' is not UsdPreviewSurface; default surface used"
            ));
            return Ok(m);
        }
        let (diffuse, diffuse_tex) =
            self.color_input(&shader, "inputs:diffuseColor", Rgb::splat(0.18), true)?;
        m.base_color = diffuse.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0);
        m.base_color_texture = diffuse_tex;
        let (emission, emission_tex) =
            self.color_input(&shader, "inputs:emissiveColor", Rgb::ZERO, true)?;
        m.emission = emission.max(Rgb::ZERO);
        m.emission_texture = emission_tex;
        m.metallic = self.scalar_input(&shader, "inputs:metallic", 0.0)?;
        m.roughness = self.scalar_input(&shader, "inputs:roughness", 0.5)?;
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
        Ok(m)
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

    /// The prim an input connects to, if any.
    pub(super) fn connection(
        &self,
        shader: &usd::Prim,
        name: &str,
    ) -> Result<Option<usd::Prim>, SceneError> {
        let targets = shader
            .attribute(name)
            .connections()
            .map_err(|e| self.error(shader.path().as_str(), format!("{e:#}")))?;
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
        if let Some(&id) = self.textures.get(&key) {
            return Ok(Some(id));
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
        let image = crate::limits::decode_image(&bytes, &self.limits, 4 + 22)
            .map_err(|e| SceneError::new(&file, SceneErrorKind::Malformed(e)))?
            .to_rgba8();
        let space = if srgb {
            ColorSpace::Srgb
        } else {
            ColorSpace::Linear
        };
        let (w, h) = (image.width() as usize, image.height() as usize);
        let t = if (scale, bias) == IDENTITY_AFFINE && role == TextureRole::Color {
            Texture::from_rgba8(w, h, image.as_raw(), space)
        } else {
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
        .ok_or_else(|| SceneError::new(&file, SceneErrorKind::Malformed("empty image".into())))?;
        self.builder.textures.push(t);
        let id = (self.builder.textures.len() - 1) as u32;
        self.textures.insert(key, id);
        Ok(Some(id))
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
