//! Whether a scene lights itself ([`OwnLighting`]), and the neutral environment the CLI and the Python module
//! add when it does not ([`DEFAULT_ENVIRONMENT_RADIANCE`]).

use super::SceneBuilder;
use crate::geometry::Mesh;
use crate::light::{EnvironmentLight, Light};
use crate::math::Rgb;

/// Radiance of the neutral environment that lights a scene without lighting of its own (see
/// [`SceneBuilder::has_own_lighting`]), as glTF viewers light such files: the CLI adds it.
pub const DEFAULT_ENVIRONMENT_RADIANCE: f32 = 1.0;

/// A scene's own light sources by kind ([`SceneBuilder::own_lighting`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OwnLighting {
    /// Point, spot and directional lights.
    pub punctual: usize,
    /// Whether the scene has an environment light.
    pub environment: bool,
    /// Meshes whose material has untextured emission (light fixtures).
    pub emissive_meshes: usize,
    /// Meshes whose emission an `emissiveTexture` modulates: detail, not lighting (they are still sampled as
    /// lights).
    pub textured_emissive_meshes: usize,
    /// Media that emit (fire, glowing gas).
    pub emitting_media: usize,
}

impl OwnLighting {
    /// Whether these sources light the scene (everything but textured emission counts).
    pub fn lights_the_scene(&self) -> bool {
        self.punctual > 0 || self.environment || self.emissive_meshes > 0 || self.emitting_media > 0
    }

    /// The sources that count, in words ("2 punctual lights, 1 emissive mesh"); empty when there is none.
    pub fn describe(&self) -> String {
        let count = crate::light::counted;
        let mut parts = Vec::new();
        if self.punctual > 0 {
            parts.push(count(self.punctual, "punctual light", "punctual lights"));
        }
        if self.environment {
            parts.push("an environment light".to_owned());
        }
        if self.emissive_meshes > 0 {
            parts.push(count(
                self.emissive_meshes,
                "mesh with untextured emission",
                "meshes with untextured emission",
            ));
        }
        if self.emitting_media > 0 {
            parts.push(count(
                self.emitting_media,
                "emitting medium",
                "emitting media",
            ));
        }
        parts.join(", ")
    }
}

impl SceneBuilder {
    /// Whether the scene lights itself: a punctual or environment light, an emitting medium, or a mesh whose
    /// material has untextured emission (a light fixture, such as a Cornell box's ceiling light). Emission that an
    /// `emissiveTexture` modulates (the screens and lamps on an asset such as DamagedHelmet) does not count:
    /// it is detail, which glTF viewers show under their own default environment. The CLI lights a scene for
    /// which this is false with a neutral environment.
    pub fn has_own_lighting(&self) -> bool {
        self.own_lighting().lights_the_scene()
    }

    /// Lights a scene without lighting of its own ([`Self::has_own_lighting`] false) as the CLI and the Python
    /// module do: with a uniform environment of radiance [`DEFAULT_ENVIRONMENT_RADIANCE`]. Returns whether it
    /// was added (a scene that lights itself is left as it is).
    pub fn light_by_default(&mut self) -> bool {
        if self.has_own_lighting() {
            return false;
        }
        self.set_environment(EnvironmentLight::Constant(Rgb::splat(
            DEFAULT_ENVIRONMENT_RADIANCE,
        )));
        true
    }

    /// The scene's own light sources by kind, as [`Self::has_own_lighting`] counts them.
    pub fn own_lighting(&self) -> OwnLighting {
        let emitting_meshes = |textured: bool| {
            let emits = |mesh: &Mesh| {
                self.materials
                    .get(mesh.material as usize)
                    .is_some_and(|m| m.is_emissive() && m.emission_texture.is_some() == textured)
            };
            // An emissive prototype's instances become meshes of their own when the scene is built.
            let instances = self
                .instances
                .iter()
                .filter(|i| self.prototypes.get(i.prototype as usize).is_some_and(emits));
            self.meshes.iter().filter(|m| emits(m)).count() + instances.count()
        };
        OwnLighting {
            punctual: self
                .lights
                .iter()
                .filter(|l| !matches!(l, Light::Environment(_) | Light::Area(_)))
                .count(),
            environment: self
                .lights
                .iter()
                .any(|l| matches!(l, Light::Environment(_))),
            emissive_meshes: emitting_meshes(false),
            textured_emissive_meshes: emitting_meshes(true),
            emitting_media: self.media.iter().filter(|m| m.is_emissive()).count(),
        }
    }
}
