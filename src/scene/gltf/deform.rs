//! glTF mesh deformations applied at load, as glTF viewers show a file with no animation playing:
//! morph targets with their default weights (glTF 2.0 §3.7.2.2: `node.weights`, else `mesh.weights`, else
//! zero; POSITION, NORMAL and TANGENT displacements) and skins at their rest pose (§3.7.3: each vertex moved by
//! `Σ weight × jointWorld × inverseBindMatrix` over its JOINTS_n / WEIGHTS_n sets, with the joints' own node
//! transforms; the skinned mesh node's transform is ignored, §3.7.3.3). Morphing comes before skinning.

use super::accessors::{read_floats, read_joints, AccessorError, Usage};
use crate::geometry::Mesh;
use crate::limits::Limits;
use crate::math::{Mat4, Vec3};

/// Why a mesh cannot be morphed or skinned.
#[derive(Debug, thiserror::Error)]
pub(super) enum DeformError {
    /// An accessor of a skin or morph target (named by `at`) that cannot be read.
    #[error("{at}: {source}")]
    Accessor {
        /// Where the accessor is used (`skin 0: inverseBindMatrices`, `targets[1].POSITION`, `JOINTS_0`).
        at: String,
        /// Why it cannot be read.
        source: AccessorError,
    },
    /// A skin's inverse bind matrices are fewer than its joints.
    #[error("skin {skin}: inverseBindMatrices holds {matrices} matrices for {joints} joints")]
    TooFewInverseBinds {
        /// The skin's index.
        skin: usize,
        /// The inverse bind matrices.
        matrices: usize,
        /// The joints.
        joints: usize,
    },
    /// A joint's matrix is not finite.
    #[error("skin {skin}: joint {joint} has a non-finite matrix (its node transforms or inverse bind matrix)")]
    JointNotFinite {
        /// The skin's index.
        skin: usize,
        /// The joint's position in the skin.
        joint: usize,
    },
    /// More morph weights than morph targets.
    #[error("{weights} morph weights for {targets} morph targets")]
    TooManyWeights {
        /// The weights.
        weights: usize,
        /// The primitive's morph targets.
        targets: usize,
    },
    /// A morph target's attribute is not one per vertex.
    #[error("targets[{target}].{name} has {found} elements, not one per vertex ({count})")]
    TargetCount {
        /// The target's index.
        target: usize,
        /// The attribute (POSITION, NORMAL or TANGENT).
        name: &'static str,
        /// Its elements.
        found: usize,
        /// The primitive's vertices.
        count: usize,
    },
    /// A morph target's attribute holds a number that is not finite.
    #[error("targets[{target}].{name} holds a non-finite value")]
    TargetNotFinite {
        /// The target's index.
        target: usize,
        /// The attribute (POSITION, NORMAL or TANGENT).
        name: &'static str,
    },
    /// A skinned primitive without both JOINTS_0 and WEIGHTS_0.
    #[error(
        "a skinned primitive needs JOINTS_0 and WEIGHTS_0 together (glTF 2.0 section 3.7.3.1)"
    )]
    FirstSkinSetIncomplete,
    /// A later JOINTS_n or WEIGHTS_n set without the other.
    #[error("a skinned primitive needs JOINTS_{set} and WEIGHTS_{set} together")]
    SkinSetIncomplete {
        /// The set's number.
        set: u32,
    },
    /// A JOINTS_n or WEIGHTS_n set not one per vertex.
    #[error("JOINTS_{set} or WEIGHTS_{set} is not one per vertex ({count})")]
    SkinSetCount {
        /// The set's number.
        set: u32,
        /// The primitive's vertices.
        count: usize,
    },
    /// A skin weight that is negative or not finite.
    #[error("WEIGHTS_{set}[{vertex}] holds {weight}")]
    BadWeight {
        /// The set's number.
        set: u32,
        /// The vertex.
        vertex: usize,
        /// The weight.
        weight: f32,
    },
    /// A weighted joint the skin does not have.
    #[error("JOINTS_{set}[{vertex}] names joint {joint}, but the skin has {joints} joints")]
    NoSuchJoint {
        /// The set's number.
        set: u32,
        /// The vertex.
        vertex: usize,
        /// The joint named.
        joint: u32,
        /// The skin's joints.
        joints: usize,
    },
    /// A skinned vertex that is not finite.
    #[error("skinned vertex {0} is not finite")]
    SkinnedNotFinite(usize),
}

/// Every node's world matrix from its local matrix (`locals`, by node index: its own TRS or matrix, or its
/// animated pose) and its ancestors' (the node graph is a checked forest); nodes outside the default scene get
/// theirs from their own ancestors too.
pub(super) fn node_worlds(document: &gltf::Document, locals: &[Mat4]) -> Vec<Mat4> {
    let n = document.nodes().len();
    let mut parent = vec![None; n];
    for node in document.nodes() {
        for child in node.children() {
            parent[child.index()] = Some(node.index());
        }
    }
    let mut world: Vec<Option<Mat4>> = vec![None; n];
    for start in 0..n {
        // Walk up to the first node whose world is known (or a root), then back down.
        let mut chain = vec![start];
        while let Some(p) = parent[*chain.last().unwrap_or(&start)] {
            if world[p].is_some() {
                break;
            }
            chain.push(p);
        }
        for &i in chain.iter().rev() {
            if world[i].is_none() {
                let above = parent[i].and_then(|p| world[p]).unwrap_or(Mat4::IDENTITY);
                world[i] = Some(above * locals[i]);
            }
        }
    }
    world
        .into_iter()
        .map(|w| w.unwrap_or(Mat4::IDENTITY))
        .collect()
}

/// The joint matrices of a skin (at least one joint, checked by `check`): each joint's world matrix times
/// its inverse bind matrix (identity when the skin has none).
pub(super) fn joint_matrices(
    skin: &gltf::Skin,
    worlds: &[Mat4],
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<Mat4>, DeformError> {
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    let inverse_binds: Vec<Mat4> = match skin.inverse_bind_matrices() {
        Some(a) => {
            let floats =
                read_floats(&a, Usage::InverseBindMatrices, buffers, limits).map_err(|source| {
                    DeformError::Accessor {
                        at: format!("skin {}: inverseBindMatrices", skin.index()),
                        source,
                    }
                })?;
            if floats.len() / 16 < joints.len() {
                return Err(DeformError::TooFewInverseBinds {
                    skin: skin.index(),
                    matrices: floats.len() / 16,
                    joints: joints.len(),
                });
            }
            floats.chunks_exact(16).map(Mat4::from_cols_slice).collect()
        }
        None => vec![Mat4::IDENTITY; joints.len()],
    };
    let matrices: Vec<Mat4> = joints
        .iter()
        .zip(&inverse_binds)
        .map(|(&j, ibm)| worlds.get(j).copied().unwrap_or(Mat4::IDENTITY) * *ibm)
        .collect();
    if let Some(k) = matrices.iter().position(|m| !m.is_finite()) {
        return Err(DeformError::JointNotFinite {
            skin: skin.index(),
            joint: k,
        });
    }
    Ok(matrices)
}

/// The morph weights a mesh node is drawn with: the node's, else the mesh's, else none.
pub(super) fn morph_weights<'a>(node: &gltf::Node<'a>, mesh: &gltf::Mesh<'a>) -> &'a [f32] {
    node.weights().or_else(|| mesh.weights()).unwrap_or(&[])
}

/// Adds `Σ weight × displacement` (the weights checked finite by `check`) of the primitive's morph targets to the mesh's object-space positions,
/// normals (renormalized) and tangents (xyz; w kept). Targets with weight 0 are not read.
pub(super) fn apply_morph_targets(
    mesh: &mut Mesh,
    primitive: &gltf::Primitive,
    weights: &[f32],
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<(), DeformError> {
    let targets = primitive.morph_targets().len();
    if weights.len() > targets {
        return Err(DeformError::TooManyWeights {
            weights: weights.len(),
            targets,
        });
    }
    let count = mesh.positions.len();
    let mut normals_moved = false;
    for (k, (target, &w)) in primitive.morph_targets().zip(weights).enumerate() {
        if w == 0.0 {
            continue;
        }
        let read = |a: Option<gltf::Accessor>, usage: Usage, name: &'static str| {
            let Some(a) = a else {
                return Ok(None);
            };
            let floats = read_floats(&a, usage, buffers, limits).map_err(|source| {
                DeformError::Accessor {
                    at: format!("targets[{k}].{name}"),
                    source,
                }
            })?;
            if floats.len() != 3 * count {
                return Err(DeformError::TargetCount {
                    target: k,
                    name,
                    found: floats.len() / 3,
                    count,
                });
            }
            if floats.iter().any(|v| !v.is_finite()) {
                return Err(DeformError::TargetNotFinite { target: k, name });
            }
            Ok(Some(
                floats
                    .chunks_exact(3)
                    .map(|c| w * Vec3::new(c[0], c[1], c[2]))
                    .collect::<Vec<Vec3>>(),
            ))
        };
        if let Some(d) = read(target.positions(), Usage::PositionDelta, "POSITION")? {
            mesh.positions.iter_mut().zip(d).for_each(|(p, d)| *p += d);
        }
        if let Some(d) = read(target.normals(), Usage::DirectionDelta, "NORMAL")? {
            if !mesh.normals.is_empty() {
                mesh.normals.iter_mut().zip(d).for_each(|(n, d)| *n += d);
                normals_moved = true;
            }
        }
        if let Some(d) = read(target.tangents(), Usage::DirectionDelta, "TANGENT")? {
            if let Some(tangents) = &mut mesh.tangents {
                tangents
                    .iter_mut()
                    .zip(d)
                    .for_each(|(t, d)| *t += d.extend(0.0));
            }
        }
    }
    if normals_moved {
        for n in &mut mesh.normals {
            *n = n.normalize_or_zero();
        }
    }
    Ok(())
}

/// Poses the mesh's object-space vertices by the skin (`joints` from [`joint_matrices`]): positions by the
/// blended joint matrix, normals by its inverse transpose, tangents by it. Weights are divided by their sum
/// (as quantized weights rarely add to exactly 1); a vertex whose weights are all zero keeps its bind position.
/// A triangle whose first vertex's blended matrix mirrors has its winding reversed, as `Mesh::transform` does.
pub(super) fn apply_skin(
    mesh: &mut Mesh,
    primitive: &gltf::Primitive,
    joints: &[Mat4],
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<(), DeformError> {
    let blend = blended_joints(primitive, joints, mesh.positions.len(), buffers, limits)?;
    for (p, m) in mesh.positions.iter_mut().zip(&blend) {
        *p = m.transform_point3(*p);
    }
    for (n, m) in mesh.normals.iter_mut().zip(&blend) {
        *n = m
            .inverse()
            .transpose()
            .transform_vector3(*n)
            .normalize_or_zero();
    }
    if let Some(tangents) = &mut mesh.tangents {
        for (t, m) in tangents.iter_mut().zip(&blend) {
            *t = m
                .transform_vector3(t.truncate())
                .normalize_or_zero()
                .extend(t.w);
        }
    }
    for tri in &mut mesh.indices {
        if blend[tri[0] as usize].determinant() < 0.0 {
            tri.swap(1, 2);
        }
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(DeformError::SkinnedNotFinite(i));
    }
    Ok(())
}

/// Each of the `count` vertices' blended joint matrix: the weighted sum of its joints' matrices over every
/// JOINTS_n / WEIGHTS_n set, divided by the sum of its weights (the identity where they are all zero).
fn blended_joints(
    primitive: &gltf::Primitive,
    joints: &[Mat4],
    count: usize,
    buffers: &[gltf::buffer::Data],
    limits: &Limits,
) -> Result<Vec<Mat4>, DeformError> {
    let mut blend = vec![Mat4::ZERO; count];
    let mut total = vec![0.0f32; count];
    let mut set = 0;
    loop {
        let j = primitive.get(&gltf::Semantic::Joints(set));
        let w = primitive.get(&gltf::Semantic::Weights(set));
        let (j, w) = match (j, w) {
            (Some(j), Some(w)) => (j, w),
            (None, None) if set > 0 => break,
            _ if set == 0 => return Err(DeformError::FirstSkinSetIncomplete),
            _ => return Err(DeformError::SkinSetIncomplete { set }),
        };
        let ids = read_joints(&j, buffers, limits).map_err(|source| DeformError::Accessor {
            at: format!("JOINTS_{set}"),
            source,
        })?;
        let weights = read_floats(&w, Usage::Weights, buffers, limits).map_err(|source| {
            DeformError::Accessor {
                at: format!("WEIGHTS_{set}"),
                source,
            }
        })?;
        if ids.len() != count || weights.len() != 4 * count {
            return Err(DeformError::SkinSetCount { set, count });
        }
        add_joint_set(set, &ids, &weights, joints, &mut blend, &mut total)?;
        set += 1;
    }
    for (m, &t) in blend.iter_mut().zip(&total) {
        *m = if t > 0.0 {
            *m * (1.0 / t)
        } else {
            Mat4::IDENTITY
        };
    }
    Ok(blend)
}

/// Adds set `set` (each vertex's four joint `ids` and `weights`) to the vertices' weighted sums of joint
/// matrices (`blend`) and of weights (`total`); a weight must be finite and non-negative, and a joint with a
/// weight must exist.
fn add_joint_set(
    set: u32,
    ids: &[[u32; 4]],
    weights: &[f32],
    joints: &[Mat4],
    blend: &mut [Mat4],
    total: &mut [f32],
) -> Result<(), DeformError> {
    for (v, (ids, ws)) in ids.iter().zip(weights.chunks_exact(4)).enumerate() {
        for (&id, &weight) in ids.iter().zip(ws) {
            if !(weight.is_finite() && weight >= 0.0) {
                return Err(DeformError::BadWeight {
                    set,
                    vertex: v,
                    weight,
                });
            }
            if weight == 0.0 {
                continue;
            }
            let m = joints.get(id as usize).ok_or(DeformError::NoSuchJoint {
                set,
                vertex: v,
                joint: id,
                joints: joints.len(),
            })?;
            blend[v] += *m * weight;
            total[v] += weight;
        }
    }
    Ok(())
}
