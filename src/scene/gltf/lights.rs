//! `KHR_lights_punctual` lights (`type` point, spot with `spot.innerConeAngle`/`outerConeAngle`, or
//! directional; `color`, `intensity`; `range` is warned about and ignored) placed by their node, and the scene
//! extras key `nimbus_light_units` (`"photometric"`, the default, divides intensities by
//! [`LUMENS_PER_WATT`]; `"radiometric"` takes them as W/sr and W/m²).

use super::Loader;
use crate::light::{DirectionalLight, Light, PointLight, SpotLight, LUMENS_PER_WATT};
use crate::math::{Mat4, Rgb, Vec3};
use crate::scene::MalformedPart;
use crate::scene::{LightTag, SceneError, SceneErrorKind};

impl Loader<'_> {
    /// Adds a `KHR_lights_punctual` light placed by its node's `world` matrix, its intensity in the scene's
    /// light units; `range` is warned about and ignored.
    pub(super) fn load_light(
        &mut self,
        light: gltf::khr_lights_punctual::Light,
        world: &Mat4,
        tag: LightTag,
    ) {
        let color = Rgb::from(light.color()) * (light.intensity() * self.light_unit_scale);
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(-Vec3::Z).normalize_or_zero();
        let l = match light.kind() {
            gltf::khr_lights_punctual::Kind::Point => Light::Point(PointLight {
                position,
                intensity: color,
            }),
            gltf::khr_lights_punctual::Kind::Directional => Light::Directional(DirectionalLight {
                direction,
                irradiance: color,
            }),
            gltf::khr_lights_punctual::Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => Light::Spot(SpotLight {
                position,
                direction,
                intensity: color,
                cos_inner: inner_cone_angle.cos(),
                cos_outer: outer_cone_angle.cos(),
            }),
        };
        if light.range().is_some() {
            self.builder.warnings.push(format!(
                "light {}: 'range' is ignored (physical inverse-square falloff)",
                light.index()
            ));
        }
        self.builder.add_tagged_light(l, tag);
    }

    /// Reads `nimbus_light_units` from the scene extras, before any light is loaded.
    pub(super) fn read_light_units(
        &mut self,
        extras: &gltf::json::Extras,
    ) -> Result<(), SceneError> {
        let Some(raw) = extras else { return Ok(()) };
        let value: serde_json::Value = serde_json::from_str(raw.get()).map_err(|e| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Settings,
                format!("scene extras: {e}"),
            ))
        })?;
        self.light_unit_scale = match value.get("nimbus_light_units") {
            None => 1.0 / LUMENS_PER_WATT,
            Some(v) => match v.as_str() {
                Some("photometric") => 1.0 / LUMENS_PER_WATT,
                Some("radiometric") => 1.0,
                _ => {
                    return Err(self.error(SceneErrorKind::malformed(MalformedPart::Settings, format!(
                        "scene extras: nimbus_light_units must be \"photometric\" or \"radiometric\", not {v}"
                    ))))
                }
            },
        };
        Ok(())
    }
}
