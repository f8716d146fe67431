//! Meshes drawn more than once, by several nodes or by `EXT_mesh_gpu_instancing` (`attributes`:
//! `TRANSLATION`, `ROTATION`, `SCALE`): a static one is read once as object-space prototypes and placed as
//! instances; skinned, morphed and moving ones are copied per placement (`meshes`).

use super::accessors::{read_floats, Usage};
use super::meshes::{mesh_name, primitive_size};
use super::nodes::{node_name, NodeContext};
use super::{Loader, QUOTE};
use crate::limits::one_line;
use crate::math::{Mat4, Quat, Vec3};
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use std::rc::Rc;

impl Loader<'_> {
    /// `EXT_mesh_gpu_instancing` on `node`: one matrix per instance, T·R·S from its `TRANSLATION`, `ROTATION`
    /// (a unit quaternion) and `SCALE` accessors (each optional, all of one count; the extension's
    /// specification), placed in the node's frame; `None` without the extension. A static mesh's instances
    /// share its prototypes ([`Self::place_mesh`]); a skinned, morphed or moving one is copied per instance.
    pub(super) fn instances(&self, node: &gltf::Node) -> Result<Option<Vec<Mat4>>, SceneError> {
        let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
            return Ok(None);
        };
        let at = format!(
            "node '{}': extensions.EXT_mesh_gpu_instancing",
            one_line(&node_name(node), QUOTE)
        );
        let attributes = ext
            .get("attributes")
            .and_then(|a| a.as_object())
            .ok_or_else(|| {
                self.malformed(
                    MalformedPart::Instancing,
                    format!("{at}: attributes must be an object"),
                )
            })?;
        let read =
            |key: &str, usage: Usage, components: usize| -> Result<Option<Vec<f32>>, SceneError> {
                let Some(value) = attributes.get(key) else {
                    return Ok(None);
                };
                let accessor = value
                    .as_u64()
                    .and_then(|i| usize::try_from(i).ok())
                    .and_then(|i| self.document.accessors().nth(i))
                    .ok_or_else(|| {
                        self.malformed(
                            MalformedPart::Instancing,
                            format!("{at}.{key}: no such accessor"),
                        )
                    })?;
                let floats = read_floats(&accessor, usage, self.buffers, &self.options.limits)
                    .map_err(|m| {
                        self.malformed(MalformedPart::Instancing, format!("{at}.{key}: {m}"))
                    })?;
                if floats.len() % components != 0 || floats.iter().any(|v| !v.is_finite()) {
                    return Err(self.malformed(
                        MalformedPart::Instancing,
                        format!("{at}.{key}: values must be finite"),
                    ));
                }
                Ok(Some(floats))
            };
        let translation = read("TRANSLATION", Usage::KeyVec3, 3)?;
        let rotation = read("ROTATION", Usage::KeyRotation, 4)?;
        let scale = read("SCALE", Usage::KeyVec3, 3)?;
        let counts = [
            translation.as_ref().map(|t| t.len() / 3),
            rotation.as_ref().map(|r| r.len() / 4),
            scale.as_ref().map(|s| s.len() / 3),
        ];
        let mut known = counts.iter().flatten();
        let Some(&count) = known.next() else {
            return Err(self.malformed(
                MalformedPart::Instancing,
                format!("{at}: needs TRANSLATION, ROTATION or SCALE"),
            ));
        };
        if known.any(|&c| c != count) {
            return Err(self.malformed(
                MalformedPart::Instancing,
                format!("{at}: the attributes have different counts {counts:?}"),
            ));
        }
        let vec3 = |v: &Option<Vec<f32>>, i: usize, default: Vec3| {
            v.as_ref()
                .map_or(default, |v| Vec3::from_slice(&v[3 * i..3 * i + 3]))
        };
        Ok(Some(
            (0..count)
                .map(|i| {
                    let q = rotation.as_ref().map_or(Quat::IDENTITY, |r| {
                        Quat::from_slice(&r[4 * i..4 * i + 4]).normalize()
                    });
                    Mat4::from_scale_rotation_translation(
                        vec3(&scale, i, Vec3::ONE),
                        if q.is_finite() { q } else { Quat::IDENTITY },
                        vec3(&translation, i, Vec3::ZERO),
                    )
                })
                .collect(),
        ))
    }

    /// Whether `node`'s `mesh` at `world` becomes instances of shared prototypes rather than world-space
    /// copies: when the mesh is drawn more than once (by several nodes, or by `EXT_mesh_gpu_instancing`) and
    /// is static: no skin, no morph targets, and (under a shutter) the same world matrix at every motion step.
    pub(super) fn instanceable(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world: &Mat4,
        gpu_instanced: bool,
    ) -> bool {
        let reused = gpu_instanced || self.mesh_users.get(mesh.index()).is_some_and(|&n| n > 1);
        let deformed = node.skin().is_some()
            || mesh
                .primitives()
                .any(|p| p.morph_targets().next().is_some());
        let moving = self
            .motion
            .as_ref()
            .is_some_and(|m| m.worlds.iter().any(|w| w[node.index()] != *world));
        reused && !deformed && !moving
    }

    /// Places `mesh` at `world` as instances of its prototypes (one per triangle primitive, read the first
    /// time the mesh is placed and counted once against the memory budget), each instance named as a
    /// flattened copy would be (the node's name, else the mesh's) with the node's asset and tags.
    pub(super) fn place_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let prototypes = match self.prototypes.get(&mesh.index()) {
            Some(p) => p.clone(),
            None => {
                let p = self.read_prototypes(node, mesh)?;
                self.prototypes.insert(mesh.index(), p.clone());
                p
            }
        };
        let name = node.name().map_or_else(|| mesh_name(mesh), str::to_owned);
        for &prototype in prototypes.iter() {
            let instance = crate::scene::MeshInstance {
                prototype,
                object_to_world: *world,
                name: name.clone(),
                asset: context.asset.clone(),
                tags: context.tags.clone(),
            };
            self.builder
                .add_instance(instance)
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        }
        Ok(())
    }

    /// Reads the triangle primitives of `mesh` (first placed by `node`) as object-space prototypes with
    /// their materials, each checked against the memory budget first; returns their indices.
    fn read_prototypes(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
    ) -> Result<Rc<[u32]>, SceneError> {
        let mesh_name = mesh_name(mesh);
        let mut ids = Vec::new();
        for primitive in mesh.primitives() {
            let Some(what) = self.triangle_primitive(&mesh_name, &primitive) else {
                continue;
            };
            let (triangles, vertices) = primitive_size(&primitive);
            self.builder
                .check_mesh(
                    format_args!("{what} on node {}", node.index()),
                    triangles,
                    vertices,
                )
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
            let mut m = self.read_primitive(&primitive, &what)?;
            if m.normals.is_empty() {
                m.generate_normals();
            }
            m.name.clone_from(&mesh_name);
            m.material = self.primitive_material(&primitive, &what)?;
            ids.push(self.builder.add_prototype(m));
        }
        Ok(ids.into())
    }
}
