//! MikkTSpace tangents (Mikkelsen 2008, the `mikktspace` crate) for meshes that have texture coordinates but
//! no tangents, as glTF 2.0 §3.7.2.1 requires for normal-mapped meshes without TANGENT.
//!
//! Texture coordinates in Nimbus follow glTF (v runs down the image), while MikkTSpace, like the bakers that
//! make normal maps, expects v up; the generator is given `(u, 1 - v)`, so that the bitangent sign it stores
//! in `w` gives the normal map's +y (up in the image) as `w · cross(n, t)`, the frame glTF defines.
//! MikkTSpace gives each triangle corner its own tangent; a vertex whose corners disagree (a uv seam, a
//! mirrored half) is split, the copies appended after the original vertices.

use super::Mesh;
use crate::math::Vec4;
use std::collections::HashMap;

/// The mesh as MikkTSpace reads it, and the tangent it writes at each triangle corner.
struct Corners<'a> {
    mesh: &'a Mesh,
    uvs: &'a [crate::math::Vec2],
    tangents: Vec<[f32; 4]>,
}

impl mikktspace::Geometry for Corners<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.indices.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.positions[self.mesh.indices[face][vert] as usize].to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.normals[self.mesh.indices[face][vert] as usize].to_array()
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let uv = self.uvs[self.mesh.indices[face][vert] as usize];
        [uv.x, 1.0 - uv.y]
    }

    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        self.tangents[3 * face + vert] = tangent;
    }
}

impl Mesh {
    /// Generates MikkTSpace tangents with the bitangent sign in `w` (see the module docs), splitting vertices
    /// whose triangle corners get different tangents. Needs texture coordinates and one normal per position;
    /// without them, or if the generator fails, the mesh is left as it was and `false` returned.
    pub fn generate_tangents(&mut self) -> bool {
        let n = self.positions.len();
        let Some(uvs) = self.uvs.as_deref() else {
            return false;
        };
        let valid = uvs.len() == n
            && self.normals.len() == n
            && self.indices.iter().flatten().all(|&i| (i as usize) < n);
        if !valid || self.indices.is_empty() {
            return false;
        }
        let mut corners = Corners {
            mesh: self,
            uvs,
            tangents: vec![[0.0; 4]; 3 * self.indices.len()],
        };
        // The generator indexes its own arrays; a panic in it must not take the load down.
        let generated =
            crate::limits::catch_quietly(|| mikktspace::generate_tangents(&mut corners));
        if generated != Ok(true) {
            return false;
        }
        let per_corner = corners.tangents;
        let mut tangents: Vec<Option<Vec4>> = vec![None; n];
        let mut copies: HashMap<(u32, [u32; 4]), u32> = HashMap::new();
        for (c, t) in per_corner.into_iter().enumerate() {
            let (face, vert) = (c / 3, c % 3);
            let v = self.indices[face][vert];
            let t = Vec4::from_array(t);
            let t = if t.is_finite() { t } else { Vec4::ZERO };
            match tangents[v as usize] {
                None => tangents[v as usize] = Some(t),
                Some(existing) if existing == t => {}
                Some(_) => {
                    let key = (v, t.to_array().map(f32::to_bits));
                    let copy = *copies.entry(key).or_insert_with(|| {
                        tangents.push(Some(t));
                        self.duplicate_vertex(v)
                    });
                    self.indices[face][vert] = copy;
                }
            }
        }
        self.tangents = Some(
            tangents
                .into_iter()
                .map(Option::unwrap_or_default)
                .collect(),
        );
        true
    }
}

impl Mesh {
    /// Appends a copy of vertex `v` with every per-vertex attribute (position, normal, both UV sets, colour,
    /// tangent and each motion step) and returns its index. Skins and morph targets are applied before a mesh
    /// reaches the scene, so these are all the attributes a vertex has here.
    fn duplicate_vertex(&mut self, v: u32) -> u32 {
        fn copy<T: Copy>(values: &mut Vec<T>, i: usize) {
            values.push(values[i]);
        }
        let i = v as usize;
        copy(&mut self.positions, i);
        copy(&mut self.normals, i);
        for set in [&mut self.uvs, &mut self.uvs1].into_iter().flatten() {
            copy(set, i);
        }
        if let Some(colors) = &mut self.colors {
            copy(colors, i);
        }
        if let Some(tangents) = &mut self.tangents {
            copy(tangents, i);
        }
        if let Some(motion) = &mut self.motion {
            for step in motion.positions.iter_mut().chain(&mut motion.normals) {
                copy(step, i);
            }
        }
        (self.positions.len() - 1) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Vec2, Vec3};

    /// A unit quad in the z = 0 plane facing +z, u along +x and (glTF) v down the image, i.e. along −y.
    fn quad(u_sign: f32) -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            normals: vec![Vec3::Z; 4],
            uvs: Some(vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(u_sign, 1.0),
                Vec2::new(u_sign, 0.0),
                Vec2::new(0.0, 0.0),
            ]),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn bitangent_is_image_up_for_a_plain_and_a_mirrored_mapping() {
        for u_sign in [1.0, -1.0] {
            let mut m = quad(u_sign);
            assert!(m.generate_tangents());
            for t in m.tangents.as_ref().unwrap() {
                // The tangent follows +u; w·cross(n, t) is image up: +y in world here.
                assert!(t.truncate().distance(Vec3::X * u_sign) < 1e-5, "{t}");
                let bitangent = t.w * Vec3::Z.cross(t.truncate());
                assert!(bitangent.distance(Vec3::Y) < 1e-5, "{bitangent}");
            }
            assert_eq!(m.positions.len(), 4, "no seam, no split");
        }
    }

    /// Two quads sharing the edge x = 1, the second mapped mirrored in u: the shared vertices 1 and 2 split.
    fn seam() -> Mesh {
        Mesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::Y,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(2.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 6],
            uvs: Some(vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 0.0),
                Vec2::new(0.0, 1.0),
                Vec2::new(0.0, 0.0),
            ]),
            indices: vec![[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]],
            ..Default::default()
        }
    }

    #[test]
    fn a_uv_seam_splits_its_vertices() {
        let mut m = seam();
        assert!(m.generate_tangents());
        assert_eq!(m.positions.len(), 8);
        let t = m.tangents.as_ref().unwrap();
        for (face, tri) in m.indices.iter().enumerate() {
            let want = if face >= 2 { -Vec3::X } else { Vec3::X };
            for &i in tri {
                assert!(t[i as usize].truncate().distance(want) < 1e-5);
            }
        }
    }

    #[test]
    fn a_split_copies_every_vertex_attribute() {
        // Issue 37: the split extended positions, normals and the first UV set only, so COLOR_0, TEXCOORD_1
        // and the motion steps of a split vertex were read past their ends.
        let mut m = seam();
        let n = m.positions.len();
        let marker = |i: usize| i as f32 + 0.5;
        m.uvs1 = Some((0..n).map(|i| Vec2::splat(marker(i))).collect());
        m.colors = Some((0..n).map(|i| Vec4::splat(marker(i))).collect());
        let steps = crate::geometry::MotionSteps {
            count: 2,
            open: 0.0,
            close: 1.0,
        };
        let moved = |dz: f32| {
            m.positions
                .iter()
                .map(|p| *p + Vec3::Z * dz)
                .collect::<Vec<_>>()
        };
        m.motion = Some(crate::geometry::MeshMotion {
            steps,
            positions: vec![moved(0.0), moved(1.0)],
            normals: vec![m.normals.clone(), m.normals.clone()],
        });
        let before = m.clone();
        assert!(m.generate_tangents());
        let count = m.positions.len();
        assert_eq!(count, 8);
        assert_eq!(m.uvs1.as_ref().unwrap().len(), count);
        assert_eq!(m.colors.as_ref().unwrap().len(), count);
        let motion = m.motion.as_ref().unwrap();
        assert!(motion.positions.iter().all(|p| p.len() == count));
        assert!(motion.normals.iter().all(|p| p.len() == count));
        // Each corner still reads the attributes of the vertex it named before the split.
        for (tri, was) in m.indices.iter().zip(&before.indices) {
            for (&i, &j) in tri.iter().zip(was) {
                let (i, j) = (i as usize, j as usize);
                assert_eq!(m.positions[i], before.positions[j]);
                assert_eq!(
                    m.uvs1.as_ref().unwrap()[i],
                    before.uvs1.as_ref().unwrap()[j]
                );
                assert_eq!(
                    m.colors.as_ref().unwrap()[i],
                    before.colors.as_ref().unwrap()[j]
                );
                assert_eq!(
                    motion.positions[1][i],
                    before.motion.as_ref().unwrap().positions[1][j]
                );
            }
        }
    }
}
