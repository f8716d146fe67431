//! glTF materials: `pbrMetallicRoughness` (`baseColorFactor`, `metallicFactor`, `roughnessFactor` and their
//! textures), `normalTexture` (`scale`), `occlusionTexture` (`strength`), `emissiveFactor`,
//! `emissiveTexture`, `alphaMode`, `alphaCutoff`, `doubleSided`, and the extensions `KHR_materials_emissive_strength`,
//! `KHR_materials_ior`, `KHR_materials_specular`, `KHR_materials_transmission`, `KHR_materials_unlit` and
//! `KHR_materials_volume` (`thicknessFactor`, `attenuationColor`, `attenuationDistance`: an absorbing
//! interior); the others are in `material_extensions`. Material `extras`: [`MATERIAL_EXTRAS`]
//! (`nimbus_medium` with `crate::volume::MEDIUM_KEYS`, and the compositing tags).

use super::extras::node_tags;
use super::{Loader, QUOTE};
use crate::geometry::CompositingTags;
use crate::limits::one_line;
use crate::material::{AlphaMode, ColorSpace, Material};
use crate::math::{Rgb, Vec4};
use crate::params::{unknown_json_keys, unknown_json_names};
use crate::scene::MalformedPart;
use crate::scene::{MediumTag, SceneError, SceneErrorKind};

/// A material's core textures (scene texture indices), read by [`Loader::core_textures`].
struct CoreTextures {
    /// `pbrMetallicRoughness.baseColorTexture`.
    base_color: Option<u32>,
    /// `pbrMetallicRoughness.metallicRoughnessTexture`.
    metallic_roughness: Option<u32>,
    /// `normalTexture` and its `scale`.
    normal: Option<(u32, f32)>,
    /// `occlusionTexture` and its `strength`.
    occlusion: Option<(u32, f32)>,
    /// `emissiveTexture`.
    emission: Option<u32>,
}

/// A material's `KHR_materials_specular`, read by [`Loader::specular`].
struct Specular {
    /// `specularFactor` (default 1).
    factor: f32,
    /// `specularColorFactor` (default white).
    color: Rgb,
    /// `specularTexture`.
    texture: Option<u32>,
    /// `specularColorTexture`.
    color_texture: Option<u32>,
}

impl Loader<'_> {
    /// The scene material for a glTF material (made once per glTF material): its factors checked, its
    /// textures read, its extensions, compositing tags and interior medium.
    pub(super) fn material(&mut self, material: gltf::Material) -> Result<u32, SceneError> {
        if let Some(&id) = self.material_map.get(&material.index()) {
            return Ok(id);
        }
        let pbr = material.pbr_metallic_roughness();
        let emissive_strength = material.emissive_strength().unwrap_or(1.0);
        self.check_material_numbers(&material, emissive_strength)?;
        let at = material_path(&material);
        // With the specular-glossiness extension, the core metallic-roughness is only its fallback: unread.
        let specular_glossiness = self.specular_glossiness(&material, &at)?;
        let textures = self.core_textures(&material, specular_glossiness.is_none(), &at)?;
        // The specular-glossiness model fixes the dielectric F0 at 0.04 (ior 1.5, full specular): the ior and
        // specular extensions, which its specification excludes beside it, are not read.
        let fixed_f0 = specular_glossiness.is_some();
        let specular = self.specular(&material, fixed_f0, &at)?;
        let transmission_texture = self.info_texture(
            material
                .transmission()
                .and_then(|t| t.transmission_texture()),
            ColorSpace::Linear,
            &format!("{at}.extensions.KHR_materials_transmission.transmissionTexture"),
        )?;
        let clearcoat = self.clearcoat(&material, &at)?;
        let sheen = self.sheen(&material, &at)?;
        let anisotropy = self.anisotropy(&material, &at)?;
        let diffuse_transmission = self.diffuse_transmission(&material, &at)?;
        let iridescence = self.iridescence(&material, &at)?;
        let dispersion = self.dispersion(&material, &at)?;
        let m = Material {
            name: material.name().map_or_else(
                || format!("material {}", material.index().map_or(-1, |i| i as i64)),
                str::to_owned,
            ),
            base_color: Vec4::from(pbr.base_color_factor()),
            base_color_texture: textures.base_color,
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            metallic_roughness_texture: textures.metallic_roughness,
            normal_texture: textures.normal,
            occlusion_texture: textures.occlusion,
            emission: Rgb::from(material.emissive_factor()) * emissive_strength,
            emission_texture: textures.emission,
            ior: material.ior().filter(|_| !fixed_f0).unwrap_or(1.5),
            specular_factor: specular.factor,
            specular_color: specular.color,
            transmission: material
                .transmission()
                .map_or(0.0, |t| t.transmission_factor()),
            transmission_texture,
            specular_texture: specular.texture,
            specular_color_texture: specular.color_texture,
            double_sided: material.double_sided(),
            interior: None,
            alpha_mode: alpha_mode(&material),
            alpha_texture: None,
            unlit: material.unlit(),
            clearcoat,
            sheen,
            specular_glossiness,
            anisotropy,
            diffuse_transmission,
            iridescence,
            dispersion,
            tags: CompositingTags::default(),
        };
        self.finish_material(&material, m)
    }

    /// Adds `m`, made from `material`, with the compositing tags and interior medium of `material`; returns
    /// its index.
    fn finish_material(
        &mut self,
        material: &gltf::Material,
        mut m: Material,
    ) -> Result<u32, SceneError> {
        m.tags = self.material_tags(material, &m.name)?;
        m.interior = self.interior_medium(material, &m)?;
        if let Some(interior) = m.interior {
            let tag = MediumTag {
                asset: String::new(),
                tags: m.tags.clone(),
            };
            self.builder.set_medium_tag(interior, tag);
        }
        let id = self.builder.add_material(m);
        self.material_map.insert(material.index(), id);
        Ok(id)
    }

    /// The core textures of a material: base colour and metallic-roughness (when `metallic_roughness`: not
    /// beside `KHR_materials_pbrSpecularGlossiness`), normal (with its scale), occlusion (with its strength)
    /// and emissive.
    fn core_textures(
        &mut self,
        material: &gltf::Material,
        metallic_roughness: bool,
        at: &str,
    ) -> Result<CoreTextures, SceneError> {
        let pbr = material.pbr_metallic_roughness();
        let base_color = self.info_texture(
            pbr.base_color_texture().filter(|_| metallic_roughness),
            ColorSpace::Srgb,
            &format!("{at}.pbrMetallicRoughness.baseColorTexture"),
        )?;
        let metallic_roughness = self.info_texture(
            pbr.metallic_roughness_texture()
                .filter(|_| metallic_roughness),
            ColorSpace::Linear,
            &format!("{at}.pbrMetallicRoughness.metallicRoughnessTexture"),
        )?;
        let normal = match material.normal_texture() {
            Some(t) => {
                let r = self.raw_ref(
                    t.texture().index(),
                    t.tex_coord(),
                    t.extensions(),
                    &format!("{at}.normalTexture"),
                )?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, t.scale()))
            }
            None => None,
        };
        let occlusion = match material.occlusion_texture() {
            Some(t) => {
                let r = self.raw_ref(
                    t.texture().index(),
                    t.tex_coord(),
                    t.extensions(),
                    &format!("{at}.occlusionTexture"),
                )?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, t.strength()))
            }
            None => None,
        };
        let emission = self.info_texture(
            material.emissive_texture(),
            ColorSpace::Srgb,
            &format!("{at}.emissiveTexture"),
        )?;
        Ok(CoreTextures {
            base_color,
            metallic_roughness,
            normal,
            occlusion,
            emission,
        })
    }

    /// `KHR_materials_specular` of a material: its factors and textures (defaults without it, and when
    /// `fixed_f0`, beside `KHR_materials_pbrSpecularGlossiness`, where it is not read and a warning says so if
    /// it or `KHR_materials_ior` is there).
    fn specular(
        &mut self,
        material: &gltf::Material,
        fixed_f0: bool,
        at: &str,
    ) -> Result<Specular, SceneError> {
        if fixed_f0 && (material.ior().is_some() || material.specular().is_some()) {
            self.builder.warnings.push(format!(
                "{at}: KHR_materials_ior and KHR_materials_specular are not read beside \
                 KHR_materials_pbrSpecularGlossiness (its dielectric F0 is 0.04)"
            ));
        }
        let specular = material.specular().filter(|_| !fixed_f0);
        let (factor, color) = specular.as_ref().map_or((1.0, Rgb::ONE), |s| {
            (s.specular_factor(), Rgb::from(s.specular_color_factor()))
        });
        let texture = self.info_texture(
            specular.as_ref().and_then(|s| s.specular_texture()),
            ColorSpace::Linear,
            &format!("{at}.extensions.KHR_materials_specular.specularTexture"),
        )?;
        let color_texture = self.info_texture(
            specular.as_ref().and_then(|s| s.specular_color_texture()),
            ColorSpace::Srgb,
            &format!("{at}.extensions.KHR_materials_specular.specularColorTexture"),
        )?;
        Ok(Specular {
            factor,
            color,
            texture,
            color_texture,
        })
    }

    /// Refuses a non-finite factor, or a negative emission, with an error naming the material and field.
    fn check_material_numbers(
        &self,
        material: &gltf::Material,
        emissive_strength: f32,
    ) -> Result<(), SceneError> {
        let fields = material_number_fields(material, emissive_strength);
        let at = material.index().map_or_else(
            || "the default material".to_owned(),
            |i| format!("materials[{i}]"),
        );
        for (field, values, non_negative) in fields {
            if let Some(v) = values
                .iter()
                .find(|v| !v.is_finite() || (non_negative && **v < 0.0))
            {
                let rule = if non_negative {
                    "finite and >= 0"
                } else {
                    "finite"
                };
                return Err(self.error(SceneErrorKind::malformed(
                    MalformedPart::Material,
                    format!("{at}.{field} holds {v}; it must be {rule}"),
                )));
            }
        }
        Ok(())
    }

    /// The compositing tags in a material's `extras` (see [`node_tags`]).
    fn material_tags(
        &self,
        material: &gltf::Material,
        name: &str,
    ) -> Result<CompositingTags, SceneError> {
        let bad = |msg: String| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Material,
                format!("material '{}': extras: {msg}", one_line(name, QUOTE)),
            ))
        };
        let Some(raw) = material.extras() else {
            return Ok(CompositingTags::default());
        };
        let extras: serde_json::Value =
            serde_json::from_str(raw.get()).map_err(|e| bad(e.to_string()))?;
        node_tags(Some(&extras)).map_err(|e| bad(e.to_string()))
    }

    /// The medium filling meshes with this material: `extras.nimbus_medium`, else `KHR_materials_volume` with
    /// `thicknessFactor` > 0 on a material that transmits, specularly or diffusely (absorption only).
    fn interior_medium(
        &mut self,
        material: &gltf::Material,
        m: &Material,
    ) -> Result<Option<u32>, SceneError> {
        let path = self.path;
        let bad = |msg: String| {
            SceneError::new(
                path,
                SceneErrorKind::malformed(
                    MalformedPart::Material,
                    format!("material '{}': {msg}", one_line(&m.name, QUOTE)),
                ),
            )
        };
        if let Some(raw) = material.extras() {
            let extras: serde_json::Value =
                serde_json::from_str(raw.get()).map_err(|e| bad(format!("extras: {e}")))?;
            let at = format!("material '{}'", one_line(&m.name, QUOTE));
            let unknown = unknown_json_names(&extras, MATERIAL_EXTRAS, "nimbus_");
            self.unknown_keys(&format!("{at}: extras"), &unknown)?;
            if let Some(spec) = extras.get("nimbus_medium") {
                let unknown = unknown_json_keys(spec, crate::volume::MEDIUM_KEYS);
                self.unknown_keys(&format!("{at}: nimbus_medium"), &unknown)?;
                let medium =
                    crate::volume::parse_nimbus_medium(spec, &m.name).map_err(|source| {
                        self.error(SceneErrorKind::Volume {
                            at: format!("material '{}': nimbus_medium", one_line(&m.name, QUOTE))
                                .into(),
                            source,
                        })
                    })?;
                return Ok(Some(self.builder.add_medium(medium)));
            }
        }
        if let Some(volume) = material.volume() {
            if volume.thickness_factor() > 0.0 && (m.transmission > 0.0 || m.transmits_diffusely())
            {
                let distance = volume.attenuation_distance();
                let color = Rgb::from(volume.attenuation_color());
                if distance.is_nan() || distance <= 0.0 || color.min_element() <= 0.0 {
                    return Err(bad(
                        "KHR_materials_volume needs attenuationDistance > 0 and a positive attenuationColor".into(),
                    ));
                }
                // Beer's law: attenuationColor is the transmittance after attenuationDistance (infinite: none).
                let sigma_a = if distance.is_finite() {
                    Rgb::new(-color.x.ln(), -color.y.ln(), -color.z.ln()).max(Rgb::ZERO) / distance
                } else {
                    Rgb::ZERO
                };
                let medium = crate::volume::homogeneous::HomogeneousMedium::new(
                    &m.name,
                    sigma_a,
                    Rgb::ZERO,
                    0.0,
                );
                return Ok(Some(self.builder.add_medium(std::sync::Arc::new(medium))));
            }
        }
        Ok(None)
    }
}

/// The `nimbus_*` keys a material's `extras` may hold.
const MATERIAL_EXTRAS: &[&str] = &[
    "nimbus_medium",
    "nimbus_light_group",
    "nimbus_holdout",
    "nimbus_shadow_catcher",
];

/// The numbers of a material that must be finite, by field name (relative to the material), each with whether
/// it must also be non-negative.
fn material_number_fields(
    material: &gltf::Material,
    emissive_strength: f32,
) -> Vec<(&'static str, Vec<f32>, bool)> {
    let pbr = material.pbr_metallic_roughness();
    let mut fields: Vec<(&'static str, Vec<f32>, bool)> = vec![
        (
            "pbrMetallicRoughness.baseColorFactor",
            pbr.base_color_factor().to_vec(),
            false,
        ),
        (
            "pbrMetallicRoughness.metallicFactor",
            vec![pbr.metallic_factor()],
            false,
        ),
        (
            "pbrMetallicRoughness.roughnessFactor",
            vec![pbr.roughness_factor()],
            false,
        ),
        ("emissiveFactor", material.emissive_factor().to_vec(), true),
        (
            "KHR_materials_emissive_strength.emissiveStrength",
            vec![emissive_strength],
            true,
        ),
    ];
    if let Some(t) = material.normal_texture() {
        fields.push(("normalTexture.scale", vec![t.scale()], false));
    }
    if let Some(cutoff) = material.alpha_cutoff() {
        fields.push(("alphaCutoff", vec![cutoff], true));
    }
    if let Some(ior) = material.ior() {
        fields.push(("KHR_materials_ior.ior", vec![ior], false));
    }
    if let Some(t) = material.transmission() {
        let f = t.transmission_factor();
        fields.push((
            "KHR_materials_transmission.transmissionFactor",
            vec![f],
            false,
        ));
    }
    if let Some(s) = material.specular() {
        fields.push((
            "KHR_materials_specular.specularFactor",
            vec![s.specular_factor()],
            false,
        ));
        let c = s.specular_color_factor().to_vec();
        fields.push(("KHR_materials_specular.specularColorFactor", c, false));
    }
    if let Some(v) = material.volume() {
        let t = v.thickness_factor();
        fields.push(("KHR_materials_volume.thicknessFactor", vec![t], false));
        let c = v.attenuation_color().to_vec();
        fields.push(("KHR_materials_volume.attenuationColor", c, false));
    }
    fields
}

/// The material's `alphaMode` and `alphaCutoff` (default 0.5), glTF 2.0 §3.9.4.
fn alpha_mode(material: &gltf::Material) -> AlphaMode {
    match material.alpha_mode() {
        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        gltf::material::AlphaMode::Mask => AlphaMode::Mask {
            cutoff: material.alpha_cutoff().unwrap_or(0.5),
        },
        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
    }
}

/// `materials[i]` or "the default material", for messages.
fn material_path(material: &gltf::Material) -> String {
    material.index().map_or_else(
        || "the default material".to_owned(),
        |i| format!("materials[{i}]"),
    )
}
