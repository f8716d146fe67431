//! `UsdGeomPointInstancer`: each prototype's static meshes are read once, in the prototype's frame, and every
//! instance places them as instances of shared object-space meshes (`crate::scene::MeshInstance`, traced
//! through the two-level hierarchy); a prototype's moving (motion-blurred) meshes are copied to world space
//! per instance, as any other mesh. Native instances (`instanceable` prims, which `openusd` composes as instance
//! proxies of a shared prototype) are placed the same way when their prototype holds only static meshes
//! (`Loader::native_instance`).
//!
//! Read: `prototypes` (relationship, in order), `protoIndices` (int[]), `positions` (point3f[]),
//! `orientations` (quath[]) or `orientationsf` (quatf[]), `scales` (float3[]), `ids` (int64[]) and
//! `invisibleIds` (int64[], matched against `ids`, else against the instance index). An instance's matrix is
//! the prototype root's own transform, then scale, then orientation, then translation by its position
//! (UsdGeomPointInstancer::ComputeInstanceTransformsAtTime), then the instancer's world matrix. Velocities,
//! accelerations and angular velocities (motion) are not read.

use super::values::vec3_array;
use super::Loader;
use crate::geometry::{CompositingTags, Mesh};
use crate::math::{Mat4, Quat, Vec3};
use crate::scene::MalformedPart;
use crate::scene::{MeshInstance, SceneError, SceneErrorKind};
use openusd::{sdf, usd};
use std::collections::HashSet;

/// What a native instance's prototype became the first time an instance of it was read.
pub(super) enum NativePrototype {
    /// Static meshes only: prototypes, each with its mesh's path and asset below the instance prim (the part
    /// after the instance's own path, or the whole path when it lies elsewhere) and its own compositing tags.
    Shared(Vec<SharedMesh>),
    /// Lights, cameras, volumes or moving meshes inside: each instance's subtree is read and copied as before.
    Copied,
}

/// One static mesh of a native instance prototype.
#[derive(Clone)]
pub(super) struct SharedMesh {
    /// The prototype's index in the builder.
    prototype: u32,
    /// The mesh's path after the instance prim's (`/Tri` of `/A/Tri`).
    name_suffix: String,
    /// Its asset's path after the instance prim's, when the asset lies inside the instance; `None`: each
    /// instance's own asset.
    asset_suffix: Option<String>,
    /// The compositing tags set inside the prototype (each instance's own apply where these are unset).
    tags: CompositingTags,
}

/// The per-instance arrays of a `PointInstancer`, all as long as `indices` (or empty where optional).
struct InstancerArrays {
    /// `protoIndices`: each instance's prototype.
    indices: Vec<i32>,
    /// `positions`.
    positions: Vec<Vec3>,
    /// `orientations` or `orientationsf` (empty: none).
    orientations: Vec<Quat>,
    /// `scales` (empty: none).
    scales: Vec<Vec3>,
    /// `ids` (empty: the instance indices).
    ids: Vec<i64>,
    /// `invisibleIds`.
    invisible: HashSet<i64>,
}

impl InstancerArrays {
    /// Instance `i`'s matrix in the instancer's frame: scale, then orientation, then translation by its
    /// position.
    fn instance_matrix(&self, i: usize) -> Mat4 {
        Mat4::from_scale_rotation_translation(
            self.scales.get(i).copied().unwrap_or(Vec3::ONE),
            self.orientations.get(i).copied().unwrap_or(Quat::IDENTITY),
            self.positions[i],
        )
    }
}

/// Most instances one instancer may place.
pub(super) const MAX_INSTANCES: usize = 1 << 20;

/// One prototype of a `PointInstancer`, read once: its static meshes made shared prototypes, and its moving
/// meshes, which each instance copies.
struct PrototypeMeshes {
    /// The static meshes, as prototypes of the builder.
    shared: Vec<StaticMesh>,
    /// The meshes with motion, copied (and transformed) per instance.
    moving: Vec<Mesh>,
}

/// A static mesh of a `PointInstancer` prototype: its index among the builder's prototypes, and its name,
/// which each instance's name extends with the instance's number.
struct StaticMesh {
    prototype: u32,
    name: String,
}

impl Loader<'_> {
    /// Places a `PointInstancer`'s prototypes: instances of their static meshes, copies of their moving ones.
    pub(super) fn point_instancer(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: Option<String>,
        depth: usize,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let prototypes = prim.relationship("prototypes").targets().map_err(|e| {
            self.error(MalformedPart::Instancing, &at, format!("prototypes: {e:#}"))
        })?;
        let arrays = self.instancer_arrays(prim, &at)?;
        let parts = self.instancer_prototypes(&prototypes, &at, binding, depth)?;
        self.check_instancer_budget(&at, &arrays.indices, &parts)?;
        for i in 0..arrays.indices.len() {
            let id = arrays.ids.get(i).copied().unwrap_or(i as i64);
            if arrays.invisible.contains(&id) {
                continue;
            }
            let p = usize::try_from(arrays.indices[i])
                .ok()
                .filter(|&p| p < parts.len())
                .ok_or_else(|| {
                    self.error(
                        MalformedPart::Instancing,
                        &at,
                        format!(
                            "protoIndices[{i}] = {} but there are {} prototypes",
                            arrays.indices[i],
                            prototypes.len()
                        ),
                    )
                })?;
            let m = *world * arrays.instance_matrix(i);
            if !m.is_finite() {
                return Err(self.error(
                    MalformedPart::Instancing,
                    &at,
                    format!("instance {i} has a non-finite transform"),
                ));
            }
            self.place_instance(i, &m, &parts[p])?;
        }
        Ok(())
    }

    /// The per-instance arrays of the instancer `prim` (at `at`), checked to match `protoIndices` in length,
    /// which is at most [`MAX_INSTANCES`].
    fn instancer_arrays(&self, prim: &usd::Prim, at: &str) -> Result<InstancerArrays, SceneError> {
        let indices = self.int_array(prim, "protoIndices")?;
        let positions = match self.value(prim, "positions")? {
            Some(v) => vec3_array(&v).ok_or_else(|| {
                self.error(
                    MalformedPart::Instancing,
                    at,
                    "positions must be a point3f[]",
                )
            })?,
            None => Vec::new(),
        };
        let n = indices.len();
        if n > MAX_INSTANCES {
            return Err(self.error(
                MalformedPart::Instancing,
                at,
                format!("{n} instances; at most {MAX_INSTANCES} are expanded"),
            ));
        }
        if positions.len() != n {
            return Err(self.error(
                MalformedPart::Instancing,
                at,
                format!(
                    "positions has {} entries for {n} protoIndices",
                    positions.len()
                ),
            ));
        }
        let orientations = self.orientations(prim)?;
        let scales = match self.value(prim, "scales")? {
            Some(v) => vec3_array(&v).ok_or_else(|| {
                self.error(MalformedPart::Instancing, at, "scales must be a float3[]")
            })?,
            None => Vec::new(),
        };
        for (name, len) in [
            ("orientations", orientations.len()),
            ("scales", scales.len()),
        ] {
            if len != 0 && len != n {
                return Err(self.error(
                    MalformedPart::Instancing,
                    at,
                    format!("{name} has {len} entries for {n} protoIndices"),
                ));
            }
        }
        let ids = self.int64_array(prim, "ids")?;
        if !ids.is_empty() && ids.len() != n {
            return Err(self.error(
                MalformedPart::Instancing,
                at,
                format!("ids has {} entries for {n} protoIndices", ids.len()),
            ));
        }
        let invisible = self
            .int64_array(prim, "invisibleIds")?
            .into_iter()
            .collect();
        Ok(InstancerArrays {
            indices,
            positions,
            orientations,
            scales,
            ids,
            invisible,
        })
    }

    /// Each prototype's meshes, read once in the prototype's own frame (its root transform included): the
    /// static ones become shared prototypes, the moving ones stay meshes to copy. Lights inside a prototype are
    /// dropped with a warning.
    fn instancer_prototypes(
        &mut self,
        prototypes: &[sdf::Path],
        at: &str,
        binding: Option<String>,
        depth: usize,
    ) -> Result<Vec<PrototypeMeshes>, SceneError> {
        let mut parts = Vec::with_capacity(prototypes.len());
        for proto in prototypes {
            let proto = self.stage.prim(proto.prim_path().as_str());
            let (meshes, lights) = (self.builder.meshes.len(), self.builder.lights.len());
            self.visit(&proto, Mat4::IDENTITY, binding.clone(), depth + 1)?;
            if self.builder.lights.len() != lights {
                self.builder.truncate_lights(lights);
                self.warn(format!(
                    "{at}: lights inside the prototype {} are not instanced; skipped",
                    proto.path().as_str()
                ));
            }
            let (moving, still): (Vec<Mesh>, Vec<Mesh>) = self
                .builder
                .split_meshes_off(meshes)
                .into_iter()
                .partition(|m| m.motion.is_some());
            let shared = still
                .into_iter()
                .map(|m| {
                    let name = m.name.clone();
                    StaticMesh {
                        prototype: self.builder.add_prototype(m),
                        name,
                    }
                })
                .collect();
            parts.push(PrototypeMeshes { shared, moving });
        }
        Ok(parts)
    }

    /// Checks that the instance records and the copied meshes of the instances of `indices` (into `parts`) fit
    /// the memory budget with the rest of the scene's, before any is made (each is checked again as it is added).
    fn check_instancer_budget(
        &self,
        at: &str,
        indices: &[i32],
        parts: &[PrototypeMeshes],
    ) -> Result<(), SceneError> {
        let n = indices.len();
        let of_instance = |p: &i32| usize::try_from(*p).ok().and_then(|p| parts.get(p));
        let records = indices
            .iter()
            .filter_map(of_instance)
            .map(|part| part.shared.len() as u64)
            .sum::<u64>();
        self.builder
            .check_instances(format!("{at}: {n} instances"), records)
            .map_err(|e| SceneError::new(self.path, SceneErrorKind::OverLimit(e.to_string())))?;
        let (triangles, vertices) = indices
            .iter()
            .filter_map(of_instance)
            .flat_map(|part| &part.moving)
            .fold((0u64, 0u64), |(t, v), m| {
                (
                    t.saturating_add(m.indices.len() as u64),
                    v.saturating_add(m.positions.len() as u64),
                )
            });
        self.check_mesh(&format!("{at}: {n} instances"), triangles, vertices)
    }

    /// Places instance `i` at `m`: an instance of each of its prototype's shared meshes, a copy of each of its
    /// moving ones.
    fn place_instance(
        &mut self,
        i: usize,
        m: &Mat4,
        part: &PrototypeMeshes,
    ) -> Result<(), SceneError> {
        for shared in &part.shared {
            let instance = MeshInstance {
                prototype: shared.prototype,
                object_to_world: *m,
                name: format!("{}[{i}]", shared.name),
                asset: self.asset.clone(),
                tags: self.tags.clone(),
            };
            self.builder.add_instance(instance).map_err(|e| {
                SceneError::new(self.path, SceneErrorKind::OverLimit(e.to_string()))
            })?;
        }
        for mesh in &part.moving {
            let mut mesh = mesh.clone();
            mesh.name = format!("{}[{i}]", mesh.name);
            mesh.transform(m);
            self.add_mesh(mesh)?;
        }
        Ok(())
    }

    /// Places the native instance `prim` (at `world`, under the inherited material `binding`) as instances of
    /// its prototype's static meshes, read once per prototype and binding; returns whether it did. `false`
    /// (the caller reads the subtree as any other) for a prim that is not an instance, and for a prototype that
    /// holds lights, cameras, volumes or moving meshes: those are copied per instance, as before.
    pub(super) fn native_instance(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: &Option<String>,
        depth: usize,
    ) -> Result<bool, SceneError> {
        let at = prim.path().as_str().to_owned();
        if !prim
            .is_instance()
            .map_err(|e| self.error(MalformedPart::Instancing, &at, format!("{e:#}")))?
        {
            return Ok(false);
        }
        let Some(proto) = prim
            .prototype()
            .map_err(|e| self.error(MalformedPart::Instancing, &at, format!("{e:#}")))?
        else {
            return Ok(false);
        };
        let key = (proto.as_str().to_owned(), binding.clone());
        if !self.native.contains_key(&key) {
            let read = self.read_native_prototype(prim, binding, depth)?;
            self.native.insert(key.clone(), read);
        }
        let NativePrototype::Shared(meshes) = &self.native[&key] else {
            return Ok(false);
        };
        for mesh in meshes.clone() {
            let instance = MeshInstance {
                prototype: mesh.prototype,
                object_to_world: *world,
                name: format!("{at}{}", mesh.name_suffix),
                asset: match &mesh.asset_suffix {
                    Some(suffix) => format!("{at}{suffix}"),
                    None => self.asset.clone(),
                },
                tags: mesh.tags.or(&self.tags),
            };
            self.builder.add_instance(instance).map_err(|e| {
                SceneError::new(self.path, SceneErrorKind::OverLimit(e.to_string()))
            })?;
        }
        Ok(true)
    }

    /// Reads the subtree of the first instance `prim` of a prototype in the instance's own frame: its static
    /// meshes become prototypes ([`NativePrototype::Shared`]); if anything else was added (a light, a camera,
    /// a medium, a moving mesh), it is all taken back and the prototype is [`NativePrototype::Copied`].
    fn read_native_prototype(
        &mut self,
        prim: &usd::Prim,
        binding: &Option<String>,
        depth: usize,
    ) -> Result<NativePrototype, SceneError> {
        let at = prim.path().as_str().to_owned();
        let b = &self.builder;
        let before = (
            b.meshes.len(),
            b.lights.len(),
            b.cameras.len(),
            b.media.len(),
            b.camera.is_some(),
        );
        let outer = (self.tags.clone(), self.asset.clone());
        // The meshes keep only the tags set inside the prototype; each instance adds its own.
        self.tags = CompositingTags::default();
        let mut visited = Ok(());
        for child in self.children(prim)? {
            visited = self.visit(&child, Mat4::IDENTITY, binding.clone(), depth + 1);
            if visited.is_err() {
                break;
            }
        }
        (self.tags, self.asset) = outer;
        visited?;
        let meshes = self.builder.split_meshes_off(before.0);
        let b = &mut self.builder;
        let others =
            b.lights.len() != before.1 || b.cameras.len() != before.2 || b.media.len() != before.3;
        if others || meshes.iter().any(|m| m.motion.is_some()) {
            b.truncate_lights(before.1);
            b.cameras.truncate(before.2);
            b.media.truncate(before.3);
            b.media_tags.truncate(before.3);
            if !before.4 {
                b.camera = None;
            }
            return Ok(NativePrototype::Copied);
        }
        let shared = meshes
            .into_iter()
            .map(|mesh| {
                let suffix = |path: &str| path.strip_prefix(at.as_str()).map(str::to_owned);
                let name_suffix = suffix(&mesh.name).unwrap_or_else(|| mesh.name.clone());
                let asset_suffix = suffix(&mesh.asset);
                let tags = mesh.tags.clone();
                SharedMesh {
                    prototype: self.builder.add_prototype(mesh),
                    name_suffix,
                    asset_suffix,
                    tags,
                }
            })
            .collect();
        Ok(NativePrototype::Shared(shared))
    }

    /// `orientations` (quath[]) or `orientationsf` (quatf[]), normalised; empty when neither is authored.
    fn orientations(&self, prim: &usd::Prim) -> Result<Vec<Quat>, SceneError> {
        let at = prim.path().as_str();
        let value = match self.value(prim, "orientations")? {
            Some(v) => v,
            None => match self.value(prim, "orientationsf")? {
                Some(v) => v,
                None => return Ok(Vec::new()),
            },
        };
        let quats: Vec<Quat> = match value {
            sdf::Value::QuathVec(q) => q
                .iter()
                .map(|q| Quat::from_xyzw(q.x.to_f32(), q.y.to_f32(), q.z.to_f32(), q.w.to_f32()))
                .collect(),
            sdf::Value::QuatfVec(q) => q
                .iter()
                .map(|q| Quat::from_xyzw(q.x, q.y, q.z, q.w))
                .collect(),
            sdf::Value::QuatdVec(q) => q
                .iter()
                .map(|q| Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32))
                .collect(),
            _ => {
                return Err(self.error(
                    MalformedPart::Instancing,
                    at,
                    "orientations must be a quath[]",
                ))
            }
        };
        quats
            .into_iter()
            .map(|q| {
                let len = q.length();
                (len.is_finite() && len > 0.0)
                    .then(|| q / len)
                    .ok_or_else(|| {
                        self.error(
                            MalformedPart::Instancing,
                            at,
                            "an orientation is zero or not finite",
                        )
                    })
            })
            .collect()
    }

    /// An `int64[]` (or `int[]`) attribute; empty when not authored.
    fn int64_array(&self, prim: &usd::Prim, name: &str) -> Result<Vec<i64>, SceneError> {
        match self.value(prim, name)? {
            None => Ok(Vec::new()),
            Some(sdf::Value::Int64Vec(v)) => Ok(v),
            Some(sdf::Value::IntVec(v)) => Ok(v.into_iter().map(i64::from).collect()),
            Some(_) => Err(self.error(
                MalformedPart::Instancing,
                &format!("{}.{name}", prim.path().as_str()),
                "expected an int64[]",
            )),
        }
    }
}
