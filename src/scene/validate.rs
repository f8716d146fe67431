//! The last guard before a scene is built: every reference between a builder's parts and the numbers every
//! loader must have checked already, so that a scene built in code gets an error, never a panic.

use super::{SceneBuilder, SceneError, SceneErrorKind, BUILDER_PATH};
use crate::light::Light;
use crate::scene::MalformedPart;

/// A dangling reference in a built scene, named by `what`.
fn invalid(what: String) -> SceneError {
    SceneError::new(BUILDER_PATH, SceneErrorKind::InvalidReference(what))
}

/// A number no loader should have let through, named by `what`.
fn malformed(part: MalformedPart, what: String) -> SceneError {
    SceneError::new(BUILDER_PATH, SceneErrorKind::malformed(part, what))
}

impl SceneBuilder {
    /// Checks every reference between the parts (a mesh's material and vertex indices and attribute lengths, a
    /// material's textures and interior medium) and the numbers every loader must have checked already, as a
    /// last guard for scenes built in code: a camera that [`Camera::is_valid`](super::Camera::is_valid), finite lights, positions and
    /// emission.
    pub(super) fn validate(&self) -> Result<(), SceneError> {
        self.check_mesh_references()?;
        self.check_motion_steps()?;
        self.check_attribute_lengths()?;
        self.check_camera()?;
        self.check_lights()?;
        self.check_positions()?;
        self.check_instance_placements()?;
        self.check_materials()
    }

    /// Each mesh's material and vertex indices in range.
    fn check_mesh_references(&self) -> Result<(), SceneError> {
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            if mesh.material as usize >= self.materials.len() {
                return Err(invalid(format!(
                    "mesh '{}' uses material {}, but there are {} materials",
                    mesh.name,
                    mesh.material,
                    self.materials.len()
                )));
            }
            let n = mesh.positions.len();
            if let Some(i) = mesh.indices.iter().flatten().find(|&&i| i as usize >= n) {
                return Err(invalid(format!(
                    "mesh '{}' has vertex index {i}, but {n} positions",
                    mesh.name
                )));
            }
        }
        Ok(())
    }

    /// Each moving mesh's motion steps: at least two finite, ordered instants with one finite position and one normal per vertex each.
    fn check_motion_steps(&self) -> Result<(), SceneError> {
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            let Some(m) = &mesh.motion else { continue };
            let count = m.steps.count as usize;
            let consistent = count >= 2
                && m.steps.open.is_finite()
                && m.steps.close.is_finite()
                && m.steps.open <= m.steps.close
                && m.positions.len() == count
                && m.normals.len() == count
                && m.positions.iter().all(|p| p.len() == mesh.positions.len())
                && m.normals.iter().all(|n| n.len() == mesh.positions.len());
            if !consistent {
                return Err(invalid(format!(
                "mesh '{}' has motion steps that are not at least 2 finite, ordered instants with one position and normal per vertex each",
                mesh.name
            )));
            }
            if !m.positions.iter().flatten().all(|p| p.is_finite()) {
                return Err(malformed(
                    MalformedPart::Mesh,
                    format!(
                        "mesh '{}' has a non-finite position in a motion step",
                        mesh.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Each mesh's normals, texture coordinates, colours and tangents one per position (checked after the motion steps, so that a short step is named as such rather than as the normals that could not be generated for it).
    fn check_attribute_lengths(&self) -> Result<(), SceneError> {
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            let n = mesh.positions.len();
            let lengths_match = mesh.normals.len() == n
                && mesh.uvs.as_ref().is_none_or(|u| u.len() == n)
                && mesh.uvs1.as_ref().is_none_or(|u| u.len() == n)
                && mesh.colors.as_ref().is_none_or(|c| c.len() == n)
                && mesh.tangents.as_ref().is_none_or(|t| t.len() == n);
            if !lengths_match {
                return Err(invalid(format!(
                "mesh '{}' has normals, texture coordinates, colours or tangents not one per position",
                mesh.name
            )));
            }
        }
        Ok(())
    }

    /// The camera, if one is set, valid ([`Camera::is_valid`](super::Camera::is_valid)) and its motion too.
    fn check_camera(&self) -> Result<(), SceneError> {
        if let Some(c) = &self.camera {
            if !c.is_valid() {
                return Err(malformed(MalformedPart::Camera, format!(
                "the camera needs a finite placement, 0 < yfov < pi (perspective) or a positive half height (orthographic), a positive aspect ratio and a lens with a positive radius and focus distance (yfov {}, {:?}, aspect ratio {:?}, lens {:?})",
                c.yfov, c.projection, c.aspect_ratio, c.lens
            )));
            }
            if c.motion.as_ref().is_some_and(|m| !m.is_valid()) {
                return Err(malformed(MalformedPart::Camera,
                "the camera's motion needs one finite pose per step, at least two, at ordered instants"
                    .into(),
            ));
            }
        }
        Ok(())
    }

    /// Every punctual light's position, direction and intensity finite.
    fn check_lights(&self) -> Result<(), SceneError> {
        for (i, light) in self.lights.iter().enumerate() {
            let finite = match light {
                Light::Point(l) => l.position.is_finite() && l.intensity.is_finite(),
                Light::Spot(l) => {
                    l.position.is_finite() && l.direction.is_finite() && l.intensity.is_finite()
                }
                Light::Directional(l) => l.direction.is_finite() && l.irradiance.is_finite(),
                Light::Area(_) | Light::Environment(_) => true,
            };
            if !finite {
                return Err(malformed(
                    MalformedPart::Light,
                    format!("light {i} has a non-finite position, direction or intensity"),
                ));
            }
        }
        Ok(())
    }

    /// Every mesh position finite.
    fn check_positions(&self) -> Result<(), SceneError> {
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            if !mesh.positions.iter().all(|p| p.is_finite()) {
                return Err(malformed(
                    MalformedPart::Mesh,
                    format!("mesh '{}' has a non-finite position", mesh.name),
                ));
            }
        }
        Ok(())
    }

    /// Each instance's prototype in range and its transform finite.
    fn check_instance_placements(&self) -> Result<(), SceneError> {
        for (i, instance) in self.instances.iter().enumerate() {
            if instance.prototype as usize >= self.prototypes.len() {
                return Err(invalid(format!(
                    "instance {i} '{}' places prototype {}, but there are {} prototypes",
                    instance.name,
                    instance.prototype,
                    self.prototypes.len()
                )));
            }
            if !instance.object_to_world.is_finite() {
                return Err(malformed(
                    MalformedPart::Instancing,
                    format!(
                        "instance {i} '{}' has a non-finite transform",
                        instance.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Each material's textures and interior medium in range and its emission finite and non-negative.
    fn check_materials(&self) -> Result<(), SceneError> {
        for m in &self.materials {
            if let Some(t) = m.texture_ids().find(|&t| t as usize >= self.textures.len()) {
                return Err(invalid(format!(
                    "material '{}' uses texture {t}, but there are {} textures",
                    m.name,
                    self.textures.len()
                )));
            }
            if !(m.emission.is_finite() && m.emission.min_element() >= 0.0) {
                return Err(malformed(
                    MalformedPart::Material,
                    format!(
                        "material '{}' has emission {:?}, not finite and non-negative",
                        m.name, m.emission
                    ),
                ));
            }
            if let Some(i) = m.interior.filter(|&i| i as usize >= self.media.len()) {
                return Err(invalid(format!(
                    "material '{}' fills its interior with medium {i}, but there are {} media",
                    m.name,
                    self.media.len()
                )));
            }
        }
        Ok(())
    }
}
