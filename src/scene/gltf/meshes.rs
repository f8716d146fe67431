//! Mesh primitives copied to world space: `mode` (triangles, strips and fans; other modes skipped with a
//! warning), `indices` and the attributes `POSITION`, `NORMAL`, `TANGENT`, `TEXCOORD_0`, `TEXCOORD_1`,
//! `COLOR_0` (each checked finite and of POSITION's count; any other attribute's bytes checked), morphed by
//! `targets` with the pose's or `weights`, skinned by the node's `skin` (see `deform`), and sampled at the
//! motion steps under a shutter.

use super::accessors::{check_bytes, read_floats, read_indices, Usage};
use super::nodes::NodeContext;
use super::{animation, deform, Loader, QUOTE};
use crate::geometry::{Mesh, MeshMotion};
use crate::limits::one_line;
use crate::math::{Mat4, Vec2, Vec3, Vec4};
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

impl Loader<'_> {
    /// The description of `primitive` (`MESH, primitive N`) when it holds triangles (a list, strip or fan);
    /// any other mode is warned about and skipped (`None`).
    pub(super) fn triangle_primitive(
        &mut self,
        mesh_name: &str,
        primitive: &gltf::Primitive,
    ) -> Option<String> {
        let what = format!("{mesh_name}, primitive {}", primitive.index());
        let mode = primitive.mode();
        if matches!(
            mode,
            gltf::mesh::Mode::Triangles
                | gltf::mesh::Mode::TriangleStrip
                | gltf::mesh::Mode::TriangleFan
        ) {
            return Some(what);
        }
        self.builder.warnings.push(format!(
            "{what}: {mode:?} primitives are not triangles; skipped"
        ));
        None
    }

    /// Loads a node's mesh: each triangle primitive's attributes, morphed by the pose's weights, then posed
    /// by the node's skin or placed by the node's world matrix (times `instance`, an `EXT_mesh_gpu_instancing`
    /// instance's own, else the identity). Under a shutter, the same is done at each motion step, and a mesh
    /// whose vertices differ at some step from the frame's gets those steps as its motion (transform, morph
    /// and skin blur alike).
    pub(super) fn load_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: gltf::Mesh,
        node_world: &Mat4,
        instance: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let world = &(*node_world * *instance);
        let mesh_name = mesh_name(&mesh);
        if node.skin().is_some() && !std::mem::replace(&mut self.skin_warned, true) {
            self.builder.warnings.push(
                "skinned meshes are posed at their rest pose (the joints' own node transforms); animations are not played".into(),
            );
        }
        if node.skin().is_some() && self.node_worlds.is_empty() {
            self.node_worlds = deform::node_worlds(self.document, &self.pose.locals);
        }
        let frame_deform =
            self.deformation(node, &mesh, &self.pose, 0, &self.node_worlds, world)?;
        let step_deforms = self.step_deformations(node, &mesh, instance)?;
        for primitive in mesh.primitives() {
            let Some(what) = self.triangle_primitive(&mesh_name, &primitive) else {
                continue;
            };
            let (triangles, vertices) = primitive_size(&primitive);
            let copies = 1 + step_deforms.as_ref().map_or(0, Vec::len) as u64;
            self.builder
                .check_mesh(
                    format_args!("{what} on node {}", node.index()),
                    triangles,
                    vertices.saturating_mul(copies),
                )
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
            let base = self.read_primitive(&primitive, &what)?;
            let mut m = self.deformed(&base, &primitive, &frame_deform, &what)?;
            if let Some(deforms) = &step_deforms {
                m.motion = self.step_motion(&base, &primitive, deforms, &m, &what)?;
            }
            m.name = node.name().map_or_else(|| mesh_name.clone(), str::to_owned);
            m.asset = context.asset.clone();
            m.tags = context.tags.clone();
            m.material = self.primitive_material(&primitive, &what)?;
            self.builder.add_mesh(m);
        }
        Ok(())
    }

    /// The material of a primitive: the one `KHR_materials_variants` maps the chosen variant to, else its own.
    pub(super) fn primitive_material(
        &mut self,
        primitive: &gltf::Primitive,
        what: &str,
    ) -> Result<u32, SceneError> {
        match self.variant_material(primitive, what)? {
            Some(i) => {
                let material = self.document.materials().nth(i).expect("index checked");
                self.material(material)
            }
            None => self.material(primitive.material()),
        }
    }

    /// What poses `node`'s `mesh` (placed by `instance` in the node's frame) at each motion step of the
    /// shutter; `None` without one.
    fn step_deformations(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        instance: &Mat4,
    ) -> Result<Option<Vec<Deformation>>, SceneError> {
        let Some(m) = &self.motion else {
            return Ok(None);
        };
        m.poses
            .iter()
            .zip(&m.worlds)
            .enumerate()
            .map(|(k, (pose, worlds))| {
                let world = worlds[node.index()] * *instance;
                self.deformation(node, mesh, pose, k + 1, worlds, &world)
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    /// The motion of primitive `base`, posed as `m` at the frame, across the shutter: its vertices posed by
    /// each step's deformation in `deforms`; `None` when no step moves a vertex, or when the winding flips
    /// at some step (a warning says so).
    fn step_motion(
        &mut self,
        base: &Mesh,
        primitive: &gltf::Primitive,
        deforms: &[Deformation],
        m: &Mesh,
        what: &str,
    ) -> Result<Option<MeshMotion>, SceneError> {
        let Some(motion) = &self.motion else {
            return Ok(None);
        };
        let steps = motion.steps;
        let mut positions = Vec::with_capacity(deforms.len());
        let mut normals = Vec::with_capacity(deforms.len());
        for d in deforms {
            let step = self.deformed(base, primitive, d, what)?;
            if step.indices != m.indices {
                // A mirroring transform at some steps only (a scale through zero) flips the winding.
                self.builder.warnings.push(format!(
                    "{what}: its winding flips across the shutter; not motion-blurred"
                ));
                positions.clear();
                break;
            }
            positions.push(step.positions);
            normals.push(step.normals);
        }
        let moves = positions.iter().any(|p| *p != m.positions);
        Ok(moves.then_some(MeshMotion {
            steps,
            positions,
            normals,
        }))
    }

    /// What poses a node's mesh in `pose` (number `pose_index`: 0 the frame's, k + 1 motion step k): its morph
    /// weights, and its skin's joint matrices (from the node `worlds` of that pose) or else its world matrix
    /// `world`.
    fn deformation(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        pose: &animation::Pose,
        pose_index: usize,
        worlds: &[Mat4],
        world: &Mat4,
    ) -> Result<Deformation, SceneError> {
        let weights: Vec<f32> = match &pose.weights[node.index()] {
            Some(animated) => animated.clone(),
            None => deform::morph_weights(node, mesh).to_vec(),
        };
        let joints = match node.skin() {
            Some(skin) => Some(self.joint_matrices(&skin, pose_index, worlds)?),
            None => None,
        };
        Ok(Deformation {
            weights,
            joints,
            world: *world,
        })
    }

    /// The joint matrices of `skin` in pose `pose_index` (see [`Self::deformation`]), computed on first use
    /// and counted against the work budget, one step a joint.
    fn joint_matrices(
        &self,
        skin: &gltf::Skin,
        pose_index: usize,
        worlds: &[Mat4],
    ) -> Result<Rc<[Mat4]>, SceneError> {
        let key = (pose_index, skin.index());
        if let Some(joints) = self.joints.borrow().get(&key) {
            return Ok(joints.clone());
        }
        let count = skin.joints().len() as u64;
        self.work
            .spend(
                format_args!("skin {}: {count} joint matrices", skin.index()),
                count,
            )
            .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        let joints: Rc<[Mat4]> =
            deform::joint_matrices(skin, worlds, self.buffers, &self.options.limits)
                .map_err(|e| {
                    self.error(SceneErrorKind::malformed(
                        MalformedPart::Animation,
                        e.to_string(),
                    ))
                })?
                .into();
        self.joints.borrow_mut().insert(key, joints.clone());
        Ok(joints)
    }

    /// The object-space primitive `base` morphed and posed by `d`, with flat normals where it has none. The
    /// morph targets read (one step a vertex each) and the skinned vertices count against the work budget.
    fn deformed(
        &self,
        base: &Mesh,
        primitive: &gltf::Primitive,
        d: &Deformation,
        what: &str,
    ) -> Result<Mesh, SceneError> {
        let vertices = base.positions.len() as u64;
        let targets = d.weights.iter().filter(|&&w| w != 0.0).count() as u64;
        let (skinned, how) = match d.joints {
            Some(_) => (vertices, ", skinned"),
            None => (0, ""),
        };
        self.work
            .spend(
                format_args!("{what}: posing {vertices} vertices ({targets} morph targets{how})"),
                targets.saturating_mul(vertices).saturating_add(skinned),
            )
            .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        let mut m = base.clone();
        let limits = &self.options.limits;
        deform::apply_morph_targets(&mut m, primitive, &d.weights, self.buffers, limits)
            .and_then(|()| match &d.joints {
                Some(j) => deform::apply_skin(&mut m, primitive, j, self.buffers, limits),
                None => {
                    m.transform(&d.world);
                    Ok(())
                }
            })
            .map_err(|e| {
                self.error(SceneErrorKind::malformed(
                    MalformedPart::Animation,
                    format!("{what}: {e}"),
                ))
            })?;
        if m.normals.is_empty() {
            m.generate_normals();
        }
        Ok(m)
    }

    /// A primitive's vertices in object space: POSITION, NORMAL, TANGENT and TEXCOORD_0 (sparse or quantized
    /// accessors decoded), its index list triangulated, every other attribute's bytes checked.
    pub(super) fn read_primitive(
        &self,
        primitive: &gltf::Primitive,
        what: &str,
    ) -> Result<Mesh, SceneError> {
        let (buffers, limits) = (self.buffers, &self.options.limits);
        let bad = |m: String| self.error(SceneErrorKind::InvalidReference(format!("{what}: {m}")));
        let mut mesh = self.read_vertices(primitive, what)?;
        let count = mesh.positions.len();
        let flat: Vec<u32> = match primitive.indices() {
            Some(a) => read_indices(&a, buffers, limits).map_err(|e| bad(e.to_string()))?,
            None => (0..count as u32).collect(),
        };
        if let Some(i) = flat.iter().find(|&&i| i as usize >= count) {
            return Err(bad(format!(
                "index {i} is out of range for {count} vertices"
            )));
        }
        self.check_vertices(&mesh, what)?;
        mesh.indices = triangulate(&flat, primitive.mode());
        Ok(mesh)
    }

    /// A primitive's vertex attributes (POSITION, NORMAL, TEXCOORD_0, TANGENT, TEXCOORD_1, COLOR_0), without
    /// indices; every other attribute's bytes are checked.
    fn read_vertices(&self, primitive: &gltf::Primitive, what: &str) -> Result<Mesh, SceneError> {
        use gltf::Semantic as S;
        let (buffers, limits) = (self.buffers, &self.options.limits);
        let bad = |m: String| self.error(SceneErrorKind::InvalidReference(format!("{what}: {m}")));
        let floats = |semantic: &S, usage| match primitive.get(semantic) {
            Some(a) => read_floats(&a, usage, buffers, limits)
                .map(Some)
                .map_err(|e| bad(e.to_string())),
            None => Ok(None),
        };
        let positions: Vec<Vec3> = floats(&S::Positions, Usage::Position)?
            .ok_or_else(|| {
                self.error(SceneErrorKind::malformed(
                    MalformedPart::Mesh,
                    format!("{what} has no POSITION"),
                ))
            })?
            .chunks_exact(3)
            .map(Vec3::from_slice)
            .collect();
        let normals: Vec<Vec3> = floats(&S::Normals, Usage::Normal)?
            .map(|f| f.chunks_exact(3).map(Vec3::from_slice).collect())
            .unwrap_or_default();
        let uvs: Option<Vec<Vec2>> = floats(&S::TexCoords(0), Usage::TexCoord)?
            .map(|f| f.chunks_exact(2).map(Vec2::from_slice).collect());
        let tangents: Option<Vec<Vec4>> = floats(&S::Tangents, Usage::Tangent)?
            .map(|f| f.chunks_exact(4).map(Vec4::from_slice).collect());
        let uvs1: Option<Vec<Vec2>> = floats(&S::TexCoords(1), Usage::TexCoord)?
            .map(|f| f.chunks_exact(2).map(Vec2::from_slice).collect());
        let colors: Option<Vec<Vec4>> = match primitive.get(&S::Colors(0)) {
            Some(a) if a.dimensions() == gltf::accessor::Dimensions::Vec3 => {
                floats(&S::Colors(0), Usage::ColorRgb)?.map(|f| {
                    f.chunks_exact(3)
                        .map(|c| Vec3::from_slice(c).extend(1.0))
                        .collect()
                })
            }
            Some(_) => floats(&S::Colors(0), Usage::ColorRgba)?
                .map(|f| f.chunks_exact(4).map(Vec4::from_slice).collect()),
            None => None,
        };
        for (semantic, accessor) in primitive.attributes() {
            if !matches!(
                semantic,
                S::Positions
                    | S::Normals
                    | S::Tangents
                    | S::TexCoords(0)
                    | S::TexCoords(1)
                    | S::Colors(0)
            ) {
                check_bytes(&accessor, buffers, limits)
                    .map_err(|e| bad(format!("{semantic:?}: {e}")))?;
            }
        }
        Ok(Mesh {
            positions,
            normals,
            uvs,
            uvs1,
            colors,
            tangents,
            ..Default::default()
        })
    }

    /// Refuses a primitive whose attributes are not one per position, or hold a number that is not finite.
    fn check_vertices(&self, mesh: &Mesh, what: &str) -> Result<(), SceneError> {
        let Mesh {
            positions,
            normals,
            uvs,
            uvs1,
            colors,
            tangents,
            ..
        } = mesh;
        let count = positions.len();
        let same_len = |n: usize| n == count;
        if (!normals.is_empty() && !same_len(normals.len()))
            || uvs.as_ref().is_some_and(|u| !same_len(u.len()))
            || uvs1.as_ref().is_some_and(|u| !same_len(u.len()))
            || colors.as_ref().is_some_and(|c| !same_len(c.len()))
            || tangents.as_ref().is_some_and(|t| !same_len(t.len()))
        {
            return Err(self.error(SceneErrorKind::malformed(
                MalformedPart::Mesh,
                format!("{what}: attribute counts differ from POSITION's {count}"),
            )));
        }
        let bad = [
            ("POSITION", positions.iter().position(|v| !v.is_finite())),
            ("NORMAL", normals.iter().position(|v| !v.is_finite())),
            (
                "TEXCOORD_0",
                uvs.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "TEXCOORD_1",
                uvs1.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "COLOR_0",
                colors.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "TANGENT",
                tangents.iter().flatten().position(|v| !v.is_finite()),
            ),
        ];
        if let Some((name, Some(i))) = bad.into_iter().find(|(_, i)| i.is_some()) {
            return Err(self.error(SceneErrorKind::malformed(
                MalformedPart::Mesh,
                format!("{what}: {name}[{i}] is not finite"),
            )));
        }
        Ok(())
    }
}

/// A mesh's name for messages and as its Cryptomatte object name: its own, else `mesh N`.
pub(super) fn mesh_name(mesh: &gltf::Mesh) -> String {
    mesh.name()
        .map_or_else(|| format!("mesh {}", mesh.index()), |n| one_line(n, QUOTE))
}

/// How many nodes of the document draw each mesh, by mesh index.
pub(super) fn mesh_users(document: &gltf::Document) -> Vec<u32> {
    let mut users = vec![0u32; document.meshes().len()];
    for node in document.nodes() {
        if let Some(n) = node.mesh().and_then(|m| users.get_mut(m.index())) {
            *n = n.saturating_add(1);
        }
    }
    users
}

/// Skins' joint matrices by pose (0: the frame's, k + 1: motion step k) and skin index.
pub(super) type JointCache = RefCell<HashMap<(usize, usize), Rc<[Mat4]>>>;

/// How a node's mesh is posed at one instant: morph weights, then skin joint matrices or the world matrix.
struct Deformation {
    weights: Vec<f32>,
    joints: Option<Rc<[Mat4]>>,
    world: Mat4,
}

/// Converts strip and fan index lists to triangle lists (glTF 2.0 §3.7.2.1); degenerate triangles are dropped.
fn triangulate(indices: &[u32], mode: gltf::mesh::Mode) -> Vec<[u32; 3]> {
    let tris: Vec<[u32; 3]> = match mode {
        gltf::mesh::Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i - 2], indices[i - 1], indices[i]]
                } else {
                    [indices[i - 1], indices[i - 2], indices[i]]
                }
            })
            .collect(),
        gltf::mesh::Mode::TriangleFan => (2..indices.len())
            .map(|i| [indices[0], indices[i - 1], indices[i]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    };
    tris.into_iter()
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

/// The triangles and vertices of a primitive, from its index and POSITION counts, before anything is read:
/// a third of the corners for a triangle list, all but two for a strip or fan.
pub(super) fn primitive_size(primitive: &gltf::Primitive) -> (u64, u64) {
    let vertices = primitive
        .get(&gltf::Semantic::Positions)
        .map_or(0, |a| a.count() as u64);
    let corners = primitive.indices().map_or(vertices, |a| a.count() as u64);
    let triangles = match primitive.mode() {
        gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => {
            corners.saturating_sub(2)
        }
        _ => corners / 3,
    };
    (triangles, vertices)
}
