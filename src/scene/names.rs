//! The names the compositing outputs use: which emitter each light, emissive mesh and emitting medium is (light
//! groups count emitters), and the Cryptomatte names (object, material, asset) of every mesh and medium. Built
//! once with the scene from what the loaders tagged (see [`crate::geometry::CompositingTags`]).

use crate::geometry::{CompositingTags, Mesh};
use crate::light::Light;
use crate::material::Material;
use crate::volume::Medium;
use std::sync::Arc;

/// The name of the environment light, as an emitter and as its light group under `--light-groups per-light`.
pub const ENVIRONMENT_NAME: &str = "environment";

/// What a loader knows of a light (punctual or environment) beyond its emission.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LightTag {
    /// Its name: the glTF light's (else its node's), the USD prim's path, `environment` for the environment.
    pub name: String,
    /// Its declared light group.
    pub light_group: Option<String>,
}

/// What a loader knows of a medium beyond its own name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MediumTag {
    /// The asset it belongs to (the top-level node of a VDB volume's glTF hierarchy, its USD model root);
    /// empty: the medium's own name.
    pub asset: String,
    /// Light group of its emission, holdout (shadow catching does not apply to media).
    pub tags: CompositingTags,
}

/// One source of light, as light groups count them: an emissive (or unlit) mesh with all its triangles, a
/// punctual light, the environment, or an emitting medium.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Emitter {
    /// Its name (the mesh's, the light's, `environment`, the medium's).
    pub name: String,
    /// Its declared light group, if any.
    pub light_group: Option<String>,
}

/// The Cryptomatte names of a mesh or a medium.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CryptoNames {
    /// `CryptoObject`: the glTF node (or mesh) name, the USD prim path, the medium's name.
    pub object: String,
    /// `CryptoMaterial`: the material's name (a medium's own name).
    pub material: String,
    /// `CryptoAsset`: the top-level node or USD model root (the object's own name without one).
    pub asset: String,
}

/// A surface object as names see it: a mesh, or an instance of a prototype with its own name, asset and tags.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SurfaceObject<'a> {
    /// Its name (Cryptomatte object, emitter).
    pub name: &'a str,
    /// Its asset (empty: its name).
    pub asset: &'a str,
    /// Its own compositing tags (its material's apply where these are unset).
    pub tags: &'a CompositingTags,
    /// Its material's index.
    pub material: u32,
}

impl<'a> SurfaceObject<'a> {
    /// The names of `mesh`.
    pub fn of_mesh(mesh: &'a Mesh) -> Self {
        Self {
            name: &mesh.name,
            asset: &mesh.asset,
            tags: &mesh.tags,
            material: mesh.material,
        }
    }
}

/// No entry (a mesh that emits nothing, a medium that does not glow).
const NONE: u32 = u32::MAX;

/// The emitters and Cryptomatte names of a scene, and the holdout and shadow-catcher flags of its surfaces and
/// media. Surface objects are the meshes, then the instances; Cryptomatte items are the surface objects
/// followed by the media.
#[derive(Clone, Debug, Default)]
pub struct SceneNames {
    /// Every emitter.
    pub emitters: Vec<Emitter>,
    /// The emitter of each scene light.
    emitter_of_light: Vec<u32>,
    /// The emitter of each mesh ([`NONE`] when it neither emits nor is unlit).
    emitter_of_mesh: Vec<u32>,
    /// The emitter of each medium ([`NONE`] when it does not emit).
    emitter_of_medium: Vec<u32>,
    /// The Cryptomatte names of the meshes, then of the media.
    pub items: Vec<CryptoNames>,
    /// Whether each mesh is a holdout.
    mesh_holdout: Vec<bool>,
    /// Whether each mesh is a shadow catcher.
    mesh_catcher: Vec<bool>,
    /// Whether each medium is a holdout.
    medium_holdout: Vec<bool>,
}

impl SceneNames {
    /// The names of a scene's parts. `objects` are its surface objects (the meshes, then the instances);
    /// `lights` are the scene's lights: the first `light_tags.len()` as the loader added them (punctual and
    /// environment), then the area lights that `build` made from emissive triangles.
    pub(crate) fn new<'a>(
        objects: impl IntoIterator<Item = SurfaceObject<'a>>,
        materials: &[Material],
        lights: &[Light],
        light_tags: &[LightTag],
        media: &[Arc<dyn Medium>],
        media_tags: &[MediumTag],
    ) -> Self {
        let mut names = SceneNames::default();
        for mesh in objects {
            let material = materials.get(mesh.material as usize);
            let tags = mesh
                .tags
                .or(material.map_or(&CompositingTags::default(), |m| &m.tags));
            let emits = material.is_some_and(|m| m.is_emissive() || m.unlit);
            let emitter = if emits {
                names.push_emitter(mesh.name, tags.light_group.clone())
            } else {
                NONE
            };
            names.emitter_of_mesh.push(emitter);
            names.mesh_holdout.push(tags.holdout);
            names.mesh_catcher.push(tags.shadow_catcher);
            names.items.push(CryptoNames {
                object: mesh.name.to_owned(),
                material: material.map_or_else(String::new, |m| m.name.clone()),
                asset: non_empty_or(mesh.asset, mesh.name),
            });
        }
        for (i, light) in lights.iter().enumerate() {
            let emitter = match (light, light_tags.get(i)) {
                (Light::Area(area), _) => names
                    .emitter_of_mesh
                    .get(area.mesh as usize)
                    .copied()
                    .unwrap_or(NONE),
                (_, Some(tag)) => names.push_emitter(&tag.name, tag.light_group.clone()),
                (Light::Environment(_), None) => names.push_emitter(ENVIRONMENT_NAME, None),
                (_, None) => names.push_emitter(&format!("light{i}"), None),
            };
            names.emitter_of_light.push(emitter);
        }
        for (m, medium) in media.iter().enumerate() {
            let tag = media_tags.get(m).cloned().unwrap_or_default();
            let emitter = if medium.is_emissive() {
                names.push_emitter(medium.name(), tag.tags.light_group.clone())
            } else {
                NONE
            };
            names.emitter_of_medium.push(emitter);
            names.medium_holdout.push(tag.tags.holdout);
            names.items.push(CryptoNames {
                object: medium.name().to_owned(),
                material: medium.name().to_owned(),
                asset: non_empty_or(&tag.asset, medium.name()),
            });
        }
        names
    }

    fn push_emitter(&mut self, name: &str, light_group: Option<String>) -> u32 {
        self.emitters.push(Emitter {
            name: name.to_owned(),
            light_group,
        });
        (self.emitters.len() - 1) as u32
    }

    /// The emitter of scene light `light`.
    pub fn emitter_of_light(&self, light: usize) -> Option<u32> {
        some(self.emitter_of_light.get(light))
    }

    /// The emitter of mesh `mesh`, when it is emissive or unlit.
    pub fn emitter_of_mesh(&self, mesh: usize) -> Option<u32> {
        some(self.emitter_of_mesh.get(mesh))
    }

    /// The emitter of medium `medium`, when it emits.
    pub fn emitter_of_medium(&self, medium: usize) -> Option<u32> {
        some(self.emitter_of_medium.get(medium))
    }

    /// The Cryptomatte item of mesh `mesh`.
    pub fn item_of_mesh(&self, mesh: usize) -> u32 {
        mesh as u32
    }

    /// The Cryptomatte item of medium `medium`.
    pub fn item_of_medium(&self, medium: usize) -> u32 {
        (self.mesh_holdout.len() + medium) as u32
    }

    /// True when mesh `mesh` is a holdout.
    pub fn mesh_is_holdout(&self, mesh: usize) -> bool {
        self.mesh_holdout.get(mesh).copied().unwrap_or(false)
    }

    /// True when mesh `mesh` is a shadow catcher.
    pub fn mesh_is_shadow_catcher(&self, mesh: usize) -> bool {
        self.mesh_catcher.get(mesh).copied().unwrap_or(false)
    }

    /// True when medium `medium` is a holdout.
    pub fn medium_is_holdout(&self, medium: usize) -> bool {
        self.medium_holdout.get(medium).copied().unwrap_or(false)
    }

    /// True when some surface is a holdout or a shadow catcher, or some medium a holdout: camera paths must
    /// then look at what they hit first.
    pub fn has_mattes(&self) -> bool {
        self.mesh_holdout
            .iter()
            .chain(&self.mesh_catcher)
            .chain(&self.medium_holdout)
            .any(|&b| b)
    }

    /// True when some surface is a shadow catcher.
    pub fn has_shadow_catcher(&self) -> bool {
        self.mesh_catcher.iter().any(|&b| b)
    }

    /// True when some emitter declares a light group.
    pub fn declares_light_groups(&self) -> bool {
        self.emitters.iter().any(|e| e.light_group.is_some())
    }
}

fn some(entry: Option<&u32>) -> Option<u32> {
    entry.copied().filter(|&e| e != NONE)
}

fn non_empty_or(name: &str, fallback: &str) -> String {
    if name.is_empty() { fallback } else { name }.to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{EnvironmentLight, PointLight};
    use crate::math::{Rgb, Vec3};
    use crate::scene::SceneBuilder;

    fn quad(name: &str, material: u32, y: f32) -> Mesh {
        Mesh {
            name: name.into(),
            positions: vec![
                Vec3::new(0.0, y, 0.0),
                Vec3::new(1.0, y, 0.0),
                Vec3::new(1.0, y, 1.0),
            ],
            indices: vec![[0, 2, 1]],
            material,
            ..Default::default()
        }
    }

    #[test]
    fn emitters_count_meshes_lights_and_environment_once() {
        let mut b = SceneBuilder::new();
        let grey = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let mut lamp = Material::lambertian("lamp", Rgb::ONE);
        lamp.emission = Rgb::ONE;
        lamp.tags.light_group = Some("practicals".into());
        let lamp = b.add_material(lamp);
        let mut panel = quad("panel", lamp, 1.0);
        panel.indices.push([0, 1, 2]);
        panel.tags.light_group = Some("key".into());
        panel.asset = "rig".into();
        b.add_mesh(panel);
        b.add_mesh(quad("bulb mesh", lamp, 2.0));
        let mut floor = quad("floor", grey, 0.0);
        floor.tags.shadow_catcher = true;
        b.add_mesh(floor);
        b.add_tagged_light(
            Light::Point(PointLight {
                position: Vec3::Y,
                intensity: Rgb::ONE,
            }),
            LightTag {
                name: "fill".into(),
                light_group: None,
            },
        );
        b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
        b.set_environment_group(Some("sky".into()));
        // Replacing the environment keeps its group.
        b.set_environment(EnvironmentLight::Constant(Rgb::splat(2.0)));
        let scene = b.build().unwrap();
        let n = scene.names();
        let names: Vec<(&str, Option<&str>)> = n
            .emitters
            .iter()
            .map(|e| (e.name.as_str(), e.light_group.as_deref()))
            .collect();
        assert_eq!(
            names,
            [
                ("panel", Some("key")),
                ("bulb mesh", Some("practicals")),
                ("fill", None),
                ("environment", Some("sky")),
            ]
        );
        // The panel's two area lights are one emitter; the floor emits nothing.
        let area_emitters: Vec<u32> = (0..scene.lights().len())
            .filter(|&i| matches!(scene.lights()[i], Light::Area(_)))
            .map(|i| n.emitter_of_light(i).unwrap())
            .collect();
        assert_eq!(area_emitters, [0, 0, 1]);
        assert_eq!(n.emitter_of_mesh(2), None);
        assert!(n.mesh_is_shadow_catcher(2) && !n.mesh_is_holdout(2));
        assert!(n.has_mattes() && n.has_shadow_catcher() && n.declares_light_groups());
        assert_eq!(n.items[0].asset, "rig");
        assert_eq!(n.items[1].asset, "bulb mesh");
        assert_eq!(n.items[1].material, "lamp");
    }
}
