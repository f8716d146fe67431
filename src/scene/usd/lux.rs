//! UsdLux lights: rect, disk, sphere, distant and dome lights (see the module docs of [`super`] for the units).

use super::Loader;
use crate::geometry::Mesh;
use crate::light::{DirectionalLight, EnvironmentLight, EnvironmentMap, Light, PointLight};
use crate::material::Material;
use crate::math::{Mat3, Mat4, Quat, Rgb, Vec2, Vec3};
use crate::scene::MalformedPart;
use crate::scene::{LightTag, SceneError, SceneErrorKind};
use openusd::{sdf, usd};

impl Loader<'_> {
    /// Reads the UsdLux light `prim` of type `kind` at `world`: its radiance from intensity, exposure and
    /// colour, and the emissive mesh, point, directional or dome light it becomes.
    pub(super) fn light(
        &mut self,
        prim: &usd::Prim,
        kind: &str,
        world: &Mat4,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let intensity = self.float(prim, "inputs:intensity", 1.0)?;
        let exposure = self.float(prim, "inputs:exposure", 0.0)?;
        let color = self.color(prim, "inputs:color", Rgb::ONE)?;
        let normalize = matches!(
            self.value(prim, "inputs:normalize")?,
            Some(sdf::Value::Bool(true))
        );
        let radiance = (color * intensity * exposure.exp2()).max(Rgb::ZERO);
        if !radiance.is_finite() {
            return Err(self.error(MalformedPart::Light, &at, "light intensity is not finite"));
        }
        let mesh = match kind {
            "RectLight" => rect(
                self.float(prim, "inputs:width", 1.0)?,
                self.float(prim, "inputs:height", 1.0)?,
            ),
            "DiskLight" => disk(self.float(prim, "inputs:radius", 0.5)?, 48),
            "SphereLight" => {
                let r = self.float(prim, "inputs:radius", 0.5)?;
                if matches!(
                    self.value(prim, "treatAsPoint")?,
                    Some(sdf::Value::Bool(true))
                ) {
                    let scale = if normalize {
                        0.25
                    } else {
                        std::f32::consts::PI * r * r
                    };
                    let light = Light::Point(PointLight {
                        position: world.transform_point3(Vec3::ZERO),
                        intensity: radiance * scale,
                    });
                    self.add_delta_light(&at, light);
                    return Ok(());
                }
                Mesh::uv_sphere(Vec3::ZERO, r, 16, 32, 0)
            }
            "DistantLight" => {
                // Only an authored angle is worth a word: UsdLux's default (0.53 degrees) is in every file.
                if self.float(prim, "inputs:angle", 0.0)? > 0.0 {
                    self.warn(format!(
                        "{at}: DistantLight inputs:angle is ignored (a delta directional light)"
                    ));
                }
                let light = Light::Directional(DirectionalLight {
                    direction: world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Y),
                    irradiance: radiance,
                });
                self.add_delta_light(&at, light);
                return Ok(());
            }
            _ => return self.dome(prim, radiance, world),
        };
        self.add_area_light(&at, mesh, radiance, normalize, world)
    }

    /// Adds the emissive `mesh` of area light `at`, placed at `world`, emitting `radiance` (divided by its
    /// area when `normalize`d).
    fn add_area_light(
        &mut self,
        at: &str,
        mut mesh: Mesh,
        radiance: Rgb,
        normalize: bool,
        world: &Mat4,
    ) -> Result<(), SceneError> {
        mesh.name = at.to_owned();
        mesh.transform(world);
        let area: f32 = (0..mesh.indices.len())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let emission = if normalize {
            if area <= 0.0 {
                return Err(self.error(
                    MalformedPart::Light,
                    at,
                    "a normalized light must have a positive area",
                ));
            }
            radiance / area
        } else {
            radiance
        };
        let mut material = Material::lambertian(at, Rgb::ZERO);
        material.emission = emission;
        mesh.material = self.builder.add_material(material);
        self.add_mesh(mesh)?;
        Ok(())
    }

    /// Adds a point or directional light named `at`, in the light group of the prims around it.
    fn add_delta_light(&mut self, at: &str, light: Light) {
        let tag = LightTag {
            name: at.to_owned(),
            light_group: self.tags.light_group.clone(),
        };
        self.builder.add_tagged_light(light, tag);
    }

    pub(super) fn dome(
        &mut self,
        prim: &usd::Prim,
        radiance: Rgb,
        world: &Mat4,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let rotation = Mat4::from_mat3(Mat3::from_mat4(self.root.inverse() * *world))
            .to_scale_rotation_translation()
            .1;
        if rotation.angle_between(Quat::IDENTITY) > 1e-3 {
            self.warn(format!(
                "{at}: the DomeLight's rotation is ignored (Nimbus's lat-long orientation)"
            ));
        }
        let env = match self.asset(prim, "inputs:texture:file")? {
            Some(file) => {
                if (radiance.x - radiance.y).abs() > 1e-6 || (radiance.y - radiance.z).abs() > 1e-6
                {
                    self.warn(format!(
                        "{at}: a textured DomeLight's colour is ignored (only its luminous scale)"
                    ));
                }
                let scale = radiance.max_element();
                let map = EnvironmentMap::load(&file, scale, &self.limits)
                    .map_err(|e| SceneError::new(self.path, SceneErrorKind::Environment(e)))?;
                EnvironmentLight::Map(Box::new(map))
            }
            None => EnvironmentLight::Constant(radiance),
        };
        self.builder.set_environment(env);
        self.builder
            .set_environment_group(self.tags.light_group.clone());
        Ok(())
    }
}

/// A RectLight's quad of `width` by `height` in the XY plane, counter-clockwise seen from −Z (its front face
/// emits along −Z), with texture coordinates over it.
fn rect(width: f32, height: f32) -> Mesh {
    let (w, h) = (0.5 * width, 0.5 * height);
    Mesh {
        positions: vec![
            Vec3::new(-w, -h, 0.0),
            Vec3::new(-w, h, 0.0),
            Vec3::new(w, h, 0.0),
            Vec3::new(w, -h, 0.0),
        ],
        uvs: Some(vec![
            Vec2::new(0.0, 1.0),
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
        ]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
        ..Default::default()
    }
}

/// A disk of radius `r` in the XY plane, its front face toward −Z.
pub(super) fn disk(r: f32, segments: u32) -> Mesh {
    let mut positions = vec![Vec3::ZERO];
    for s in 0..segments {
        let phi = -2.0 * std::f32::consts::PI * s as f32 / segments as f32;
        positions.push(Vec3::new(r * phi.cos(), r * phi.sin(), 0.0));
    }
    let indices = (0..segments)
        .map(|s| [0, 1 + s, 1 + (s + 1) % segments])
        .collect();
    Mesh {
        positions,
        indices,
        ..Default::default()
    }
}
