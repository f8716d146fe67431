//! The layered-material extensions, each an object on a material checked before use:
//! `KHR_materials_clearcoat`, `KHR_materials_sheen`, `KHR_materials_pbrSpecularGlossiness`,
//! `KHR_materials_anisotropy`, `KHR_materials_diffuse_transmission`, `KHR_materials_iridescence` and
//! `KHR_materials_dispersion` (their keys in each function's documentation).

use super::Loader;
use crate::material::{
    Anisotropy, ClearcoatLayer, ColorSpace, DiffuseTransmission, Iridescence, SheenLayer,
    SpecularGlossiness,
};
use crate::math::{Rgb, Vec4};
use crate::scene::MalformedPart;
use crate::scene::SceneError;

impl Loader<'_> {
    /// `KHR_materials_clearcoat` of a material, when present: factors checked (finite, in \[0, 1\]) and
    /// textures read.
    pub(super) fn clearcoat(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<ClearcoatLayer>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_clearcoat");
        let Some(ext) = self.extension_object(material, "KHR_materials_clearcoat", &at)? else {
            return Ok(None);
        };
        let factor = self.unit_number(&ext, "clearcoatFactor", 0.0, &at)?;
        let roughness = self.unit_number(&ext, "clearcoatRoughnessFactor", 0.0, &at)?;
        let texture = self.ext_texture(&ext, "clearcoatTexture", ColorSpace::Linear, &at)?;
        let roughness_texture =
            self.ext_texture(&ext, "clearcoatRoughnessTexture", ColorSpace::Linear, &at)?;
        let normal_texture = match ext.get("clearcoatNormalTexture") {
            Some(v) => {
                let field = format!("{at}.clearcoatNormalTexture");
                let scale = match v.get("scale") {
                    Some(s) => s.as_f64().filter(|s| s.is_finite()).ok_or_else(|| {
                        self.malformed(
                            MalformedPart::Material,
                            format!("{field}.scale must be a finite number"),
                        )
                    })? as f32,
                    None => 1.0,
                };
                let r = self.json_ref(v, &field)?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, scale))
            }
            None => None,
        };
        Ok(Some(ClearcoatLayer {
            factor,
            texture,
            roughness,
            roughness_texture,
            normal_texture,
        }))
    }

    /// `KHR_materials_sheen` of a material, when present: factors checked and textures read.
    pub(super) fn sheen(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<SheenLayer>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_sheen");
        let Some(ext) = self.extension_object(material, "KHR_materials_sheen", &at)? else {
            return Ok(None);
        };
        let color = match ext.get("sheenColorFactor") {
            Some(v) => crate::params::parse_rgb(v)
                .filter(|c| c.max_element() <= 1.0)
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.sheenColorFactor must be three numbers in [0, 1]"),
                    )
                })?,
            None => Rgb::ZERO,
        };
        let roughness = self.unit_number(&ext, "sheenRoughnessFactor", 0.0, &at)?;
        let color_texture = self.ext_texture(&ext, "sheenColorTexture", ColorSpace::Srgb, &at)?;
        let roughness_texture =
            self.ext_texture(&ext, "sheenRoughnessTexture", ColorSpace::Linear, &at)?;
        Ok(Some(SheenLayer {
            color,
            color_texture,
            roughness,
            roughness_texture,
        }))
    }

    /// `KHR_materials_pbrSpecularGlossiness` of a material, when present: factors checked (finite, in
    /// \[0, 1\]) and textures read (both sRGB colour with linear alpha, as the extension specifies).
    pub(super) fn specular_glossiness(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<SpecularGlossiness>, SceneError> {
        let name = "KHR_materials_pbrSpecularGlossiness";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let mut sg = SpecularGlossiness::default();
        if let Some(v) = ext.get("diffuseFactor") {
            let d = unit_numbers::<4>(v).ok_or_else(|| {
                self.malformed(
                    MalformedPart::Material,
                    format!("{at}.diffuseFactor must be four numbers in [0, 1]"),
                )
            })?;
            sg.diffuse = Vec4::from(d);
        }
        if let Some(v) = ext.get("specularFactor") {
            let s = unit_numbers::<3>(v).ok_or_else(|| {
                self.malformed(
                    MalformedPart::Material,
                    format!("{at}.specularFactor must be three numbers in [0, 1]"),
                )
            })?;
            sg.specular = Rgb::from(s);
        }
        sg.glossiness = self.unit_number(&ext, "glossinessFactor", 1.0, &at)?;
        sg.diffuse_texture = self.ext_texture(&ext, "diffuseTexture", ColorSpace::Srgb, &at)?;
        sg.specular_glossiness_texture =
            self.ext_texture(&ext, "specularGlossinessTexture", ColorSpace::Srgb, &at)?;
        Ok(Some(sg))
    }

    /// `KHR_materials_anisotropy` of a material, when present: `anisotropyStrength` in \[0, 1\] (default 0),
    /// `anisotropyRotation` a finite number of radians (default 0), `anisotropyTexture` read as linear data.
    pub(super) fn anisotropy(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<Anisotropy>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_anisotropy");
        let Some(ext) = self.extension_object(material, "KHR_materials_anisotropy", &at)? else {
            return Ok(None);
        };
        let strength = self.unit_number(&ext, "anisotropyStrength", 0.0, &at)?;
        let rotation = match ext.get("anisotropyRotation") {
            None => 0.0,
            Some(v) => v
                .as_f64()
                .map(|r| r as f32)
                .filter(|r| r.is_finite())
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.anisotropyRotation must be a finite number (radians)"),
                    )
                })?,
        };
        let texture = self.ext_texture(&ext, "anisotropyTexture", ColorSpace::Linear, &at)?;
        Ok(Some(Anisotropy {
            strength,
            rotation,
            texture,
        }))
    }

    /// `KHR_materials_diffuse_transmission` of a material, when present: `diffuseTransmissionFactor` in
    /// \[0, 1\] (default 0), `diffuseTransmissionColorFactor` three numbers in \[0, 1\] (default white),
    /// `diffuseTransmissionTexture` read as linear data (its alpha is used), `diffuseTransmissionColorTexture`
    /// as sRGB colour.
    pub(super) fn diffuse_transmission(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<DiffuseTransmission>, SceneError> {
        let name = "KHR_materials_diffuse_transmission";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let factor = self.unit_number(&ext, "diffuseTransmissionFactor", 0.0, &at)?;
        let color = match ext.get("diffuseTransmissionColorFactor") {
            Some(v) => Rgb::from(unit_numbers::<3>(v).ok_or_else(|| {
                self.malformed(
                    MalformedPart::Material,
                    format!("{at}.diffuseTransmissionColorFactor must be three numbers in [0, 1]"),
                )
            })?),
            None => Rgb::ONE,
        };
        let texture =
            self.ext_texture(&ext, "diffuseTransmissionTexture", ColorSpace::Linear, &at)?;
        let color_texture = self.ext_texture(
            &ext,
            "diffuseTransmissionColorTexture",
            ColorSpace::Srgb,
            &at,
        )?;
        Ok(Some(DiffuseTransmission {
            factor,
            texture,
            color,
            color_texture,
        }))
    }

    /// `KHR_materials_iridescence` of a material, when present: `iridescenceFactor` in \[0, 1\] (default 0),
    /// `iridescenceIor` a finite number ≥ 1 (default 1.3), `iridescenceThicknessMinimum` and
    /// `iridescenceThicknessMaximum` finite numbers ≥ 0 of nanometres (defaults 100 and 400), the textures read
    /// as linear data.
    pub(super) fn iridescence(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<Iridescence>, SceneError> {
        let name = "KHR_materials_iridescence";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let defaults = Iridescence::default();
        let number = |key: &str, default: f32, min: f32| match ext.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .map(|v| v as f32)
                .filter(|v| v.is_finite() && *v >= min)
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.{key} must be a finite number >= {min}"),
                    )
                }),
        };
        let ior = number("iridescenceIor", defaults.ior, 1.0)?;
        let thickness_min = number("iridescenceThicknessMinimum", defaults.thickness_min, 0.0)?;
        let thickness_max = number("iridescenceThicknessMaximum", defaults.thickness_max, 0.0)?;
        let factor = self.unit_number(&ext, "iridescenceFactor", 0.0, &at)?;
        let texture = self.ext_texture(&ext, "iridescenceTexture", ColorSpace::Linear, &at)?;
        let thickness_texture =
            self.ext_texture(&ext, "iridescenceThicknessTexture", ColorSpace::Linear, &at)?;
        Ok(Some(Iridescence {
            factor,
            texture,
            ior,
            thickness_min,
            thickness_max,
            thickness_texture,
        }))
    }

    /// `KHR_materials_dispersion.dispersion` of a material (a finite number ≥ 0, default 0). It applies to the
    /// volume of a `KHR_materials_volume` material only (the extension's rule): without one, or with a thin
    /// wall (`thicknessFactor` 0), a warning says it is ignored and the result is 0.
    pub(super) fn dispersion(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<f32, SceneError> {
        let name = "KHR_materials_dispersion";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(0.0);
        };
        let dispersion = match ext.get("dispersion") {
            None => 0.0,
            Some(v) => v
                .as_f64()
                .map(|v| v as f32)
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.dispersion must be a finite number >= 0"),
                    )
                })?,
        };
        let volume = material
            .volume()
            .is_some_and(|v| v.thickness_factor() > 0.0);
        if dispersion > 0.0 && !volume {
            self.builder.warnings.push(format!(
                "{at}: dispersion needs KHR_materials_volume with thicknessFactor > 0 and is ignored"
            ));
            return Ok(0.0);
        }
        Ok(dispersion)
    }

    /// The JSON object of extension `name` on a material, if present (an error if it is not an object).
    fn extension_object(
        &self,
        material: &gltf::Material,
        name: &str,
        at: &str,
    ) -> Result<Option<serde_json::Map<String, serde_json::Value>>, SceneError> {
        match material.extensions().and_then(|e| e.get(name)) {
            None => Ok(None),
            Some(serde_json::Value::Object(o)) => Ok(Some(o.clone())),
            Some(_) => {
                Err(self.malformed(MalformedPart::Material, format!("{at} must be an object")))
            }
        }
    }

    /// A number in \[0, 1\] of an extension object, or `default` when absent.
    fn unit_number(
        &self,
        ext: &serde_json::Map<String, serde_json::Value>,
        key: &str,
        default: f32,
        at: &str,
    ) -> Result<f32, SceneError> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .filter(|v| (0.0..=1.0).contains(v))
                .map(|v| v as f32)
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Material,
                        format!("{at}.{key} must be a number in [0, 1]"),
                    )
                }),
        }
    }
}

/// An array of exactly `N` numbers, each in \[0, 1\]; `None` otherwise.
fn unit_numbers<const N: usize>(value: &serde_json::Value) -> Option<[f32; N]> {
    let a = value.as_array().filter(|a| a.len() == N)?;
    let mut out = [0.0; N];
    for (o, v) in out.iter_mut().zip(a) {
        *o = v.as_f64().filter(|v| (0.0..=1.0).contains(v))? as f32;
    }
    Some(out)
}
