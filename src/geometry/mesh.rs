//! Triangle meshes: world-space ones (each node's mesh transformed to world space once, so the BVH and the
//! integrator see one list of triangles), and the object-space prototypes that instances place (see
//! `crate::scene::MeshInstance`), which keep their own coordinates and are traced through an `InstanceBvh`.

use super::motion::{lerp, MotionSteps, MovingTriangle};
use super::CompositingTags;
#[cfg(any(test, feature = "testing"))]
use crate::math::Aabb;
use crate::math::{Mat4, Vec2, Vec3, Vec4};

/// A triangle mesh with per-vertex attributes: in world space, or in object space as an instance prototype.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Name from the scene file (node or mesh name), for messages and as its Cryptomatte object name.
    pub name: String,
    /// The asset the mesh belongs to, as Cryptomatte's `CryptoAsset` names it: the top-level node of its glTF
    /// hierarchy, or its USD model root; empty: the mesh's own name.
    pub asset: String,
    /// Its light group, holdout and shadow-catcher tags (see [`CompositingTags`]); the material's apply where
    /// these are unset.
    pub tags: CompositingTags,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, one per position (generated from faces when the file has none).
    pub normals: Vec<Vec3>,
    /// Optional texture coordinates (glTF TEXCOORD_0), one per position.
    pub uvs: Option<Vec<Vec2>>,
    /// Optional second texture-coordinate set (glTF TEXCOORD_1), one per position.
    pub uvs1: Option<Vec<Vec2>>,
    /// Optional linear RGBA vertex colours (glTF COLOR_0), one per position; they multiply the base colour.
    pub colors: Option<Vec<Vec4>>,
    /// Optional tangents (xyz) with bitangent sign (w), one per position.
    pub tangents: Option<Vec<Vec4>>,
    /// Triangles as vertex indices, counter-clockwise when seen from the front.
    pub indices: Vec<[u32; 3]>,
    /// Index of the material in the scene.
    pub material: u32,
    /// The mesh's world positions and normals across the shutter when it moves (transform motion blur);
    /// `None` for a static mesh. `positions` and `normals` above stay the pose at the frame's time, which
    /// area lights, tangents and the scene bounds use.
    pub motion: Option<MeshMotion>,
}

/// Vertex motion steps of a moving mesh (see [`crate::geometry::MotionBvh`]): its world positions and normals
/// at `steps.count` instants evenly spaced over the shutter, one entry per vertex of the mesh at each step
/// (the triangles are the mesh's). Rays at time `t` see the vertices interpolated between the two steps
/// around `t`.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshMotion {
    /// When the steps are.
    pub steps: MotionSteps,
    /// World positions at each step, each as long as the mesh's `positions`.
    pub positions: Vec<Vec<Vec3>>,
    /// Unit world normals at each step, each as long as the mesh's `normals`.
    pub normals: Vec<Vec<Vec3>>,
}

impl MeshMotion {
    /// Triangle `idx` at every step, for [`crate::geometry::MotionBvh::build`].
    pub fn triangle(&self, idx: [u32; 3]) -> MovingTriangle {
        MovingTriangle {
            steps: self.steps,
            vertices: self
                .positions
                .iter()
                .map(|p| idx.map(|i| p[i as usize]))
                .collect(),
        }
    }

    /// The positions and (unnormalised) normals of the vertices `idx` at `time`: bit for bit the triangle
    /// [`MovingTriangle::at`] gives the hierarchy.
    pub fn at(&self, idx: [usize; 3], time: f32) -> ([Vec3; 3], [Vec3; 3]) {
        let (i, f) = self.steps.segment(time);
        let mix = |values: &[Vec<Vec3>]| idx.map(|v| lerp(values[i][v], values[i + 1][v], f));
        (mix(&self.positions), mix(&self.normals))
    }
}

impl Mesh {
    /// The three positions of triangle `tri`.
    pub fn triangle(&self, tri: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[tri];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Texture-coordinate set `set` (0: `uvs`, 1: `uvs1`), if the mesh has it.
    pub fn uv_set(&self, set: usize) -> Option<&[Vec2]> {
        match set {
            0 => self.uvs.as_deref(),
            1 => self.uvs1.as_deref(),
            _ => None,
        }
    }

    /// Bounds of all vertices.
    #[cfg(any(test, feature = "testing"))]
    pub fn bounds(&self) -> Aabb {
        self.positions.iter().fold(Aabb::EMPTY, |b, p| b.extend(*p))
    }

    /// Applies an object-to-world matrix: positions by `m`, normals by its inverse transpose, tangents by `m`.
    /// A mirroring matrix (negative determinant) reverses the winding, so front faces stay front faces
    /// (glTF 2.0 §3.7.4).
    pub fn transform(&mut self, m: &Mat4) {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        let normal_matrix = m.inverse().transpose();
        for n in &mut self.normals {
            *n = normal_matrix.transform_vector3(*n).normalize_or_zero();
        }
        if let Some(tangents) = &mut self.tangents {
            for t in tangents {
                let xyz = m.transform_vector3(t.truncate()).normalize_or_zero();
                *t = xyz.extend(t.w);
            }
        }
        if let Some(motion) = &mut self.motion {
            for p in motion.positions.iter_mut().flatten() {
                *p = m.transform_point3(*p);
            }
            for n in motion.normals.iter_mut().flatten() {
                *n = normal_matrix.transform_vector3(*n).normalize_or_zero();
            }
        }
        if m.determinant() < 0.0 {
            for tri in &mut self.indices {
                tri.swap(1, 2);
            }
        }
    }

    /// Whether every index refers to a position, and every vertex attribute (texture coordinates, colours,
    /// tangents) and motion step has one value per position: what [`Mesh::generate_normals`] needs to run.
    pub fn indices_fit_attributes(&self) -> bool {
        let n = self.positions.len();
        let fits = |len: Option<usize>| len.is_none_or(|len| len == n);
        self.indices.iter().flatten().all(|&i| (i as usize) < n)
            && fits(self.uvs.as_ref().map(Vec::len))
            && fits(self.uvs1.as_ref().map(Vec::len))
            && fits(self.colors.as_ref().map(Vec::len))
            && fits(self.tangents.as_ref().map(Vec::len))
            && self
                .motion
                .as_ref()
                .is_none_or(|m| m.positions.iter().all(|p| p.len() == n))
    }

    /// Gives a mesh without normals flat ones: every triangle gets its own three vertices (their other
    /// attributes copied) with the face normal. glTF 2.0 §3.7.2.1 requires flat normals where NORMAL is absent,
    /// and an OBJ without `vn` is faceted; smoothing over shared corners would bend a box's normals by up to
    /// 55° at its edges and shade them dark. A moving mesh's steps get their own flat normals the same way.
    pub fn generate_normals(&mut self) {
        fn unweld<T: Copy>(values: &mut Option<Vec<T>>, indices: &[[u32; 3]]) {
            if let Some(v) = values {
                *v = indices.iter().flatten().map(|&i| v[i as usize]).collect();
            }
        }
        fn flat(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec3> {
            indices
                .iter()
                .flat_map(|t| {
                    let [a, b, c] = t.map(|i| positions[i as usize]);
                    [(b - a).cross(c - a).try_normalize().unwrap_or(Vec3::Y); 3]
                })
                .collect()
        }
        let indices = std::mem::take(&mut self.indices);
        self.normals = flat(&self.positions, &indices);
        if let Some(motion) = &mut self.motion {
            motion.normals = motion.positions.iter().map(|p| flat(p, &indices)).collect();
            for p in &mut motion.positions {
                *p = indices.iter().flatten().map(|&i| p[i as usize]).collect();
            }
        }
        let mut positions = Some(std::mem::take(&mut self.positions));
        unweld(&mut positions, &indices);
        self.positions = positions.unwrap_or_default();
        unweld(&mut self.uvs, &indices);
        unweld(&mut self.uvs1, &indices);
        unweld(&mut self.colors, &indices);
        unweld(&mut self.tangents, &indices);
        self.indices = (0..indices.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect();
    }

    /// A closed UV sphere with outward normals and counter-clockwise front faces: `rings` latitude bands from
    /// +Y to −Y and `segments` longitude slices. The pole rows hold zero-area triangles, which never render.
    pub fn uv_sphere(center: Vec3, radius: f32, rings: u32, segments: u32, material: u32) -> Mesh {
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        for r in 0..=rings {
            let theta = std::f32::consts::PI * r as f32 / rings as f32;
            for s in 0..=segments {
                let phi = 2.0 * std::f32::consts::PI * s as f32 / segments as f32;
                let n = Vec3::new(
                    theta.sin() * phi.sin(),
                    theta.cos(),
                    theta.sin() * phi.cos(),
                );
                normals.push(n);
                positions.push(center + radius * n);
            }
        }
        let mut indices = Vec::new();
        for r in 0..rings {
            for s in 0..segments {
                let a = r * (segments + 1) + s;
                let b = a + segments + 1;
                indices.push([a, b, a + 1]);
                indices.push([a + 1, b, b + 1]);
            }
        }
        Mesh {
            name: "sphere".into(),
            positions,
            normals,
            indices,
            material,
            ..Default::default()
        }
    }

    /// Drops triangles whose indices fall outside the vertex list; returns how many were dropped.
    pub fn remove_invalid_triangles(&mut self) -> usize {
        let n = self.positions.len() as u32;
        let before = self.indices.len();
        self.indices.retain(|t| t.iter().all(|&i| i < n));
        before - self.indices.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn generated_normals_follow_ccw_winding() {
        let mut m = quad();
        m.generate_normals();
        assert!(m.normals.iter().all(|n| n.distance(Vec3::Z) < 1e-6));
    }

    #[test]
    fn generated_normals_are_flat_with_attributes_kept() {
        // Two faces of a box sharing an edge: each keeps its own face normal along the shared edge.
        let mut m = Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 0.0, -1.0),
            ],
            uvs: Some(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]),
            indices: vec![[0, 1, 2], [1, 0, 3]],
            ..Default::default()
        };
        m.generate_normals();
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.indices, [[0, 1, 2], [3, 4, 5]]);
        assert!(m.normals[..3].iter().all(|n| n.distance(Vec3::Z) < 1e-6));
        assert!(m.normals[3..]
            .iter()
            .all(|n| n.distance(Vec3::NEG_Y) < 1e-6));
        assert_eq!(m.positions[3], Vec3::X);
        assert_eq!(m.uvs.as_ref().unwrap()[5], Vec2::Y);
    }

    #[test]
    fn mirroring_keeps_front_faces() {
        let mut m = quad();
        m.transform(&Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        m.generate_normals();
        // Mirrored in x, the face still points toward +z.
        assert!(m.normals.iter().all(|n| n.distance(Vec3::Z) < 1e-6));
    }
}
