//! World-space triangle meshes. Loaders flatten instances: each node's mesh is transformed to world space once,
//! so the BVH and the integrator see one list of triangles.

use crate::math::{Aabb, Mat4, Vec2, Vec3, Vec4};

/// A triangle mesh in world space with per-vertex attributes.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Name from the scene file (node or mesh name), for messages.
    pub name: String,
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
        if m.determinant() < 0.0 {
            for tri in &mut self.indices {
                tri.swap(1, 2);
            }
        }
    }

    /// Replaces the normals with area-weighted face normals (for meshes without normals).
    pub fn generate_normals(&mut self) {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for tri in 0..self.indices.len() {
            let [a, b, c] = self.triangle(tri);
            let face = (b - a).cross(c - a); // length is twice the area: area weighting
            for &i in &self.indices[tri] {
                normals[i as usize] += face;
            }
        }
        self.normals = normals
            .into_iter()
            .map(|n| n.try_normalize().unwrap_or(Vec3::Y))
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
    fn mirroring_keeps_front_faces() {
        let mut m = quad();
        m.transform(&Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        m.generate_normals();
        // Mirrored in x, the face still points toward +z.
        assert!(m.normals.iter().all(|n| n.distance(Vec3::Z) < 1e-6));
    }
}
