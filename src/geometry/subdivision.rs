//! Catmull-Clark subdivision of polygon meshes (Catmull & Clark 1978, "Recursively generated B-spline surfaces
//! on arbitrary topological meshes"), with the sharp and semi-sharp creases and corners of DeRose, Kass & Truong
//! 1998 ("Subdivision Surfaces in Character Animation", §3) in the "uniform" crease method that USD's
//! `creaseMethod` defaults to: a sharpness s > 0 is an infinitely sharp rule while s ≥ 1, blends the smooth and
//! sharp rules by s below 1, and decreases by one at each level.
//!
//! The rules USD's `UsdGeomMesh` names, with its defaults ([`SubdivisionRules`]):
//! - `interpolateBoundary`: boundary edges are infinitely sharp; with `edgeAndCorner` (the default) a boundary
//!   vertex of a single face is also a corner, with `edgeOnly` it follows the crease rule. Edges shared by more
//!   than two faces (non-manifold) are sharp too.
//! - `creaseMethod`: `uniform` (the default) decreases a sharpness by one a level; `chaikin` first blends each
//!   half edge's sharpness with the other sharp edges at its end (3/4 its own, 1/4 their mean), so that a crease
//!   of varying sharpness decays smoothly along its length.
//! - `faceVaryingLinearInterpolation`: face-varying data (texture coordinates, colours) is subdivided as a mesh of
//!   its own, whose vertices are the distinct values at each vertex: a UV seam is a boundary of that mesh. From
//!   `none` (smooth everywhere, seams as smooth boundary curves) through `cornersOnly`, `cornersPlus1` (the
//!   default: also pins every value where three or more UV islands meet), `cornersPlus2` (also pins seam ends
//!   inside the mesh and concave island corners) and `boundaries` (every seam value pinned) to `all` (linear in
//!   each face). The mesh's creases and corners hold for its face-varying data too.
//!
//! Where a sharpness decays to zero between two levels, the vertex point blends the parent level's rule with the
//! child level's by the decaying sharpnesses (at most 1 each, averaged), as OpenSubdiv, which USD renderers
//! subdivide with, does. `subdivision_reference.rs` checks every rule against `opensubdiv-rs`, a port of it. One
//! level turns an n-gon into n quads.
//!
//! The rules (DeRose et al. 1998, §3, and Catmull & Clark 1978):
//! - face point: the average of the face's vertices;
//! - edge point: smooth, (v₀ + v₁ + f₀ + f₁) / 4; sharp, the midpoint (v₀ + v₁) / 2;
//! - vertex point with n incident edges, Q the average of the adjacent face points, R the average of the incident
//!   edges' midpoints and S the vertex: smooth (fewer than two sharp edges), (Q + 2R + (n − 3)S) / n; crease (two
//!   sharp edges to a and b), (a + 6S + b) / 8; corner (three or more sharp edges, or a corner sharpness), S.

use crate::math::{Vec2, Vec3};
use std::collections::HashMap;

/// Sharpness that never decreases (USD's `SHARPNESS_INFINITE` is 10; anything from it up is infinite).
pub const INFINITELY_SHARP: f32 = 10.0;

/// A polygon mesh to subdivide: faces of any size, with optional per-face-corner data and per-face tags.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolygonMesh {
    /// Vertex positions.
    pub points: Vec<Vec3>,
    /// The number of vertices of each face (at least 3).
    pub counts: Vec<u32>,
    /// The faces' vertex indices, face after face, counter-clockwise seen from the front.
    pub indices: Vec<u32>,
    /// Texture coordinates per face corner (as `indices`), if any.
    pub uvs: Option<Vec<Vec2>>,
    /// Colours per face corner, if any.
    pub colors: Option<Vec<Vec3>>,
    /// A tag per face (its material), kept by the faces it subdivides into.
    pub face_tags: Vec<u32>,
    /// Edge sharpness by the edge's vertex pair (smaller index first); absent edges are smooth.
    pub creases: HashMap<(u32, u32), f32>,
    /// Corner sharpness by vertex; absent vertices are not corners.
    pub corners: HashMap<u32, f32>,
    /// How boundaries, creases and face-varying data subdivide.
    pub rules: SubdivisionRules,
}

/// How a mesh's boundaries subdivide (USD's `interpolateBoundary`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BoundaryRule {
    /// Boundary edges are sharp and a boundary vertex of a single face is a corner (`edgeAndCorner`, USD's
    /// default).
    #[default]
    EdgeAndCorner,
    /// Boundary edges are sharp; boundary vertices follow the crease rule (`edgeOnly`).
    EdgeOnly,
}

/// How semi-sharp creases decay from level to level (USD's `creaseMethod`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CreaseMethod {
    /// Each level subtracts one (`uniform`, USD's default).
    #[default]
    Uniform,
    /// Each half edge blends 3/4 of its sharpness with 1/4 of the mean of the other sharp edges at its end, then
    /// subtracts one (`chaikin`).
    Chaikin,
}

/// How face-varying data subdivides (USD's `faceVaryingLinearInterpolation`); each rule pins more values than
/// the one before it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FaceVaryingRule {
    /// Smooth everywhere; seams subdivide as smooth boundary curves (`none`).
    None,
    /// Values of a single face at a vertex (island corners) are pinned (`cornersOnly`).
    CornersOnly,
    /// Also every value at a vertex where three or more values meet (`cornersPlus1`, USD's default).
    #[default]
    CornersPlus1,
    /// Also a seam's end inside the mesh, and both values of a vertex where one of two is an island corner
    /// (`cornersPlus2`).
    CornersPlus2,
    /// Every value on a seam or boundary is pinned (`boundaries`).
    Boundaries,
    /// Linear within each face (`all`).
    All,
}

/// The subdivision rules of one mesh; the default is USD's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SubdivisionRules {
    /// `interpolateBoundary`.
    pub boundary: BoundaryRule,
    /// `creaseMethod`.
    pub crease_method: CreaseMethod,
    /// `faceVaryingLinearInterpolation`.
    pub face_varying: FaceVaryingRule,
}

/// A subdivision scheme (USD's `subdivisionScheme`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// Catmull-Clark (any polygons; quads from the first level on).
    CatmullClark,
    /// Loop (Loop 1987, "Smooth Subdivision Surfaces Based on Triangles"): triangles only, each becoming four.
    Loop,
}

impl Scheme {
    /// The scheme's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::CatmullClark => "Catmull-Clark",
            Scheme::Loop => "Loop",
        }
    }
}

/// Why a mesh cannot be subdivided.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SubdivisionError {
    /// A face has fewer than 3 vertices, an index is out of range, or the attribute lengths disagree.
    #[error("{0}")]
    Topology(String),
}

impl PolygonMesh {
    /// The number of faces `levels` of subdivision make: each n-gon becomes n quads, each quad then 4 per level.
    pub fn faces_after(&self, levels: u32) -> u64 {
        if levels == 0 {
            return self.counts.len() as u64;
        }
        let corners: u64 = self.counts.iter().map(|&c| u64::from(c)).sum();
        corners.saturating_mul(4u64.saturating_pow(levels - 1))
    }

    /// Checks the topology and the lengths of the per-corner and per-face data.
    pub fn validate(&self) -> Result<(), SubdivisionError> {
        let bad = |m: String| Err(SubdivisionError::Topology(m));
        if let Some(c) = self.counts.iter().find(|&&c| c < 3) {
            return bad(format!("a face has {c} vertices (at least 3 are needed)"));
        }
        let corners: usize = self.counts.iter().map(|&c| c as usize).sum();
        if corners != self.indices.len() {
            return bad(format!(
                "the faces have {corners} corners but there are {} indices",
                self.indices.len()
            ));
        }
        if let Some(i) = self
            .indices
            .iter()
            .find(|&&i| i as usize >= self.points.len())
        {
            return bad(format!(
                "vertex index {i} is out of range ({} points)",
                self.points.len()
            ));
        }
        let corner_data = [
            self.uvs.as_ref().map(Vec::len),
            self.colors.as_ref().map(Vec::len),
        ];
        if corner_data.into_iter().flatten().any(|n| n != corners) {
            return bad("face-varying data must have one value per face corner".into());
        }
        if self.face_tags.len() != self.counts.len() {
            return bad("there must be one tag per face".into());
        }
        Ok(())
    }

    /// The mesh after `levels` of Catmull-Clark subdivision (all quads from the first level on).
    #[cfg(test)]
    pub fn subdivide(&self, levels: u32) -> Result<PolygonMesh, SubdivisionError> {
        self.subdivide_with(Scheme::CatmullClark, levels)
    }

    /// The mesh after `levels` of subdivision by `scheme`. Loop subdivision needs a mesh of triangles.
    pub fn subdivide_with(
        &self,
        scheme: Scheme,
        levels: u32,
    ) -> Result<PolygonMesh, SubdivisionError> {
        self.validate()?;
        if scheme == Scheme::Loop {
            if let Some((f, &c)) = self.counts.iter().enumerate().find(|&(_, &c)| c != 3) {
                return Err(SubdivisionError::Topology(format!(
                    "Loop subdivision needs triangles, but face {f} has {c} vertices"
                )));
            }
        }
        let mut mesh = self.clone();
        for _ in 0..levels {
            mesh = match scheme {
                Scheme::CatmullClark => mesh.subdivide_once(None),
                Scheme::Loop => mesh.loop_once(None),
            };
        }
        Ok(mesh)
    }

    /// The number of faces `levels` of subdivision by `scheme` make.
    pub fn faces_after_with(&self, scheme: Scheme, levels: u32) -> u64 {
        match scheme {
            Scheme::CatmullClark => self.faces_after(levels),
            Scheme::Loop => (self.counts.len() as u64).saturating_mul(4u64.saturating_pow(levels)),
        }
    }

    /// Area-weighted vertex normals (the sum of each adjacent face's vector area, normalised), per face corner:
    /// the smooth shading normals of the subdivided surface. A vertex whose faces cancel gets zero.
    pub fn corner_normals(&self) -> Vec<Vec3> {
        let mut sums = vec![Vec3::ZERO; self.points.len()];
        for (_, corners) in self.faces() {
            let p = |k: usize| self.points[corners[k % corners.len()] as usize];
            // Newell's vector area of the polygon.
            let area = (0..corners.len()).fold(Vec3::ZERO, |a, k| a + p(k).cross(p(k + 1)));
            for &v in corners {
                sums[v as usize] += area;
            }
        }
        self.indices
            .iter()
            .map(|&v| sums[v as usize].normalize_or_zero())
            .collect()
    }

    /// (face index, its vertex indices) for every face.
    fn faces(&self) -> impl Iterator<Item = (usize, &[u32])> {
        let mut start = 0usize;
        self.counts.iter().enumerate().map(move |(f, &c)| {
            let corners = &self.indices[start..start + c as usize];
            start += c as usize;
            (f, corners)
        })
    }

    /// One level of subdivision.
    ///
    /// `around`, given for a face-varying value mesh, holds for each value the sharpness of the edges at its
    /// vertex in the mesh the values belong to: Chaikin's rule averages over those, not over the value mesh's
    /// seams.
    fn subdivide_once(&self, around: Option<&[Vec<f32>]>) -> PolygonMesh {
        let n_points = self.points.len();
        let face_points: Vec<Vec3> = self
            .faces()
            .map(|(_, corners)| {
                corners
                    .iter()
                    .fold(Vec3::ZERO, |a, &v| a + self.points[v as usize])
                    / corners.len() as f32
            })
            .collect();
        let (edge_index, edges) = self.edge_table();
        let edge_points = self.catmull_clark_edge_points(&edges, &face_points);
        let (vertex_edges, vertex_faces) = self.incidence(&edges);
        let incidence = Topology {
            edges: &edges,
            vertex_edges: &vertex_edges,
            vertex_faces: &vertex_faces,
        };
        let vertex_points = self.catmull_clark_vertex_points(&incidence, &face_points, around);
        // New points: vertices, then edges, then faces.
        let edge_base = n_points as u32;
        let face_base = edge_base + edges.len() as u32;
        let mut points = vertex_points;
        points.extend(edge_points);
        points.extend(face_points);
        let mut out = PolygonMesh {
            points,
            rules: self.rules,
            ..Default::default()
        };
        for (f, corners) in self.faces() {
            let c = corners.len();
            let edge_of = |k: usize| {
                let (a, b) = (corners[k % c], corners[(k + 1) % c]);
                edge_base + edge_index[&(a.min(b), a.max(b))] as u32
            };
            for (k, &vertex) in corners.iter().enumerate() {
                out.counts.push(4);
                out.indices
                    .extend([vertex, edge_of(k), face_base + f as u32, edge_of(k + c - 1)]);
                out.face_tags.push(self.face_tags[f]);
            }
        }
        self.child_face_varying_into(Scheme::CatmullClark, &incidence, &mut out);
        self.child_creases(&edges, &vertex_edges, edge_base, &mut out);
        out
    }

    /// Catmull-Clark edge points: the average of the edge's ends and its two faces' points when smooth, the
    /// midpoint when sharp (sharpness ≥ 1), and the blend of the two for a semi-sharp edge (DeRose et al. 1998).
    fn catmull_clark_edge_points(&self, edges: &[Edge], face_points: &[Vec3]) -> Vec<Vec3> {
        let point = |v: u32| self.points[v as usize];
        edges
            .iter()
            .map(|e| {
                let mid = (point(e.ends.0) + point(e.ends.1)) * 0.5;
                if e.sharpness >= 1.0 {
                    return mid;
                }
                let smooth = (point(e.ends.0)
                    + point(e.ends.1)
                    + face_points[e.faces[0]]
                    + face_points[e.faces[1]])
                    * 0.25;
                smooth.lerp(mid, e.sharpness)
            })
            .collect()
    }

    /// Catmull-Clark vertex points, (Q + 2R + (n − 3)S) / n for a smooth vertex of valence n (Q the average of
    /// its faces' points, R of its edges' midpoints), then the crease and corner rules of
    /// [`PolygonMesh::sharpened_vertex`]; a vertex with no edge or face stays where it is.
    fn catmull_clark_vertex_points(
        &self,
        topology: &Topology,
        face_points: &[Vec3],
        around: Option<&[Vec<f32>]>,
    ) -> Vec<Vec3> {
        let point = |v: u32| self.points[v as usize];
        let edges = topology.edges;
        (0..self.points.len())
            .map(|v| {
                let s = self.points[v];
                let incident = &topology.vertex_edges[v];
                let faces = &topology.vertex_faces[v];
                if incident.is_empty() || faces.is_empty() {
                    return s;
                }
                let n = incident.len() as f32;
                let q =
                    faces.iter().fold(Vec3::ZERO, |a, &f| a + face_points[f]) / faces.len() as f32;
                let r = incident.iter().fold(Vec3::ZERO, |a, &e| {
                    a + (point(edges[e].ends.0) + point(edges[e].ends.1)) * 0.5
                }) / n;
                let smooth = (q + 2.0 * r + (n - 3.0) * s) / n;
                self.sharpened_vertex(v, smooth, incident, faces.len(), edges, around)
            })
            .collect()
    }

    /// One level of Loop subdivision (Loop 1987) of a mesh of triangles, with the same sharp and semi-sharp
    /// rules as Catmull-Clark's (DeRose et al. 1998): each triangle becomes four, its corners' vertex points and
    /// its edges' edge points.
    /// - edge point: smooth, 3/8 (v₀ + v₁) + 1/8 (o₀ + o₁) with o the vertices opposite the edge; sharp, the
    ///   midpoint;
    /// - vertex point with n neighbours: smooth, (1 − nβ) S + β Σ neighbours with
    ///   β = (5/8 − (3/8 + cos(2π/n)/4)²) / n (Loop 1987, §3.2); crease and corner as Catmull-Clark's.
    ///
    /// `around` as in [`Self::subdivide_once`].
    fn loop_once(&self, around: Option<&[Vec<f32>]>) -> PolygonMesh {
        let n_points = self.points.len();
        let (edge_index, edges) = self.edge_table();
        let point = |v: u32| self.points[v as usize];
        let triangles: Vec<&[u32]> = self.faces().map(|(_, corners)| corners).collect();
        let opposite = |f: usize, e: &Edge| {
            triangles[f]
                .iter()
                .copied()
                .find(|&v| v != e.ends.0 && v != e.ends.1)
                .map_or(Vec3::ZERO, point)
        };
        let edge_points: Vec<Vec3> = edges
            .iter()
            .map(|e| {
                let mid = (point(e.ends.0) + point(e.ends.1)) * 0.5;
                if e.sharpness >= 1.0 {
                    return mid;
                }
                let smooth = (point(e.ends.0) + point(e.ends.1)) * 0.375
                    + (opposite(e.faces[0], e) + opposite(e.faces[1], e)) * 0.125;
                smooth.lerp(mid, e.sharpness)
            })
            .collect();
        let (vertex_edges, vertex_faces) = self.incidence(&edges);
        let vertex_points: Vec<Vec3> = (0..n_points)
            .map(|v| {
                let s = self.points[v];
                let incident = &vertex_edges[v];
                if incident.is_empty() || vertex_faces[v].is_empty() {
                    return s;
                }
                let n = incident.len() as f32;
                let neighbours = incident.iter().fold(Vec3::ZERO, |a, &e| {
                    let (x, y) = edges[e].ends;
                    a + point(if x as usize == v { y } else { x })
                });
                let c = 0.375 + 0.25 * (std::f32::consts::TAU / n).cos();
                let beta = (0.625 - c * c) / n;
                let smooth = s * (1.0 - n * beta) + neighbours * beta;
                self.sharpened_vertex(v, smooth, incident, vertex_faces[v].len(), &edges, around)
            })
            .collect();
        let edge_base = n_points as u32;
        let mut points = vertex_points;
        points.extend(edge_points);
        let mut out = PolygonMesh {
            points,
            rules: self.rules,
            ..Default::default()
        };
        for (f, corners) in triangles.iter().enumerate() {
            let mid = |k: usize| {
                let (a, b) = (corners[k], corners[(k + 1) % 3]);
                edge_base + edge_index[&(a.min(b), a.max(b))] as u32
            };
            let [a, b, c] = [corners[0], corners[1], corners[2]];
            let [ab, bc, ca] = [mid(0), mid(1), mid(2)];
            for child in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]] {
                out.counts.push(3);
                out.indices.extend(child);
                out.face_tags.push(self.face_tags[f]);
            }
        }
        let topology = Topology {
            edges: &edges,
            vertex_edges: &vertex_edges,
            vertex_faces: &vertex_faces,
        };
        self.child_face_varying_into(Scheme::Loop, &topology, &mut out);
        self.child_creases(&edges, &vertex_edges, edge_base, &mut out);
        out
    }

    /// The mesh's edges, each with the faces that use it and its sharpness this level (infinite on boundaries and
    /// non-manifold edges), and the index of each by its vertex pair (smaller index first).
    fn edge_table(&self) -> (HashMap<(u32, u32), usize>, Vec<Edge>) {
        let mut edge_index: HashMap<(u32, u32), usize> = HashMap::new();
        let mut edges: Vec<Edge> = Vec::new();
        for (f, corners) in self.faces() {
            for k in 0..corners.len() {
                let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
                let key = (a.min(b), a.max(b));
                let e = *edge_index.entry(key).or_insert_with(|| {
                    edges.push(Edge {
                        ends: key,
                        faces: Vec::new(),
                        sharpness: self.creases.get(&key).copied().unwrap_or(0.0).max(0.0),
                    });
                    edges.len() - 1
                });
                edges[e].faces.push(f);
            }
        }
        for e in &mut edges {
            if e.faces.len() != 2 {
                e.sharpness = INFINITELY_SHARP;
            }
        }
        (edge_index, edges)
    }

    /// Each vertex's incident edges and faces.
    fn incidence(&self, edges: &[Edge]) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
        let mut vertex_edges: Vec<Vec<usize>> = vec![Vec::new(); self.points.len()];
        for (i, e) in edges.iter().enumerate() {
            vertex_edges[e.ends.0 as usize].push(i);
            vertex_edges[e.ends.1 as usize].push(i);
        }
        let mut vertex_faces: Vec<Vec<usize>> = vec![Vec::new(); self.points.len()];
        for (f, corners) in self.faces() {
            for &v in corners {
                vertex_faces[v as usize].push(f);
            }
        }
        (vertex_edges, vertex_faces)
    }

    /// The vertex point of `v` from its scheme's `smooth` point and the sharp rules (DeRose et al. 1998, §3): a
    /// corner (a corner sharpness, three or more sharp edges, or with `edgeAndCorner` a boundary vertex of one
    /// face) stays put; two sharp edges to a and b make the crease point (a + 6S + b)/8; otherwise the smooth
    /// point. Where the rule this level differs from the next level's (a sharpness decays to zero), the two are
    /// blended by [`transition_weight`].
    fn sharpened_vertex(
        &self,
        v: usize,
        smooth: Vec3,
        incident: &[usize],
        face_count: usize,
        edges: &[Edge],
        around: Option<&[Vec<f32>]>,
    ) -> Vec3 {
        let s = self.points[v];
        let mut corner = self
            .corners
            .get(&(v as u32))
            .copied()
            .unwrap_or(0.0)
            .max(0.0);
        if self.rules.boundary == BoundaryRule::EdgeAndCorner && face_count == 1 {
            corner = INFINITELY_SHARP;
        }
        let parent: Vec<f32> = incident.iter().map(|&e| edges[e].sharpness).collect();
        let around = around.map_or(&parent[..], |around| &around[v]);
        let child: Vec<f32> = parent
            .iter()
            .map(|&sharpness| self.rules.crease_method.child_sharpness(sharpness, around))
            .collect();
        let child_corner = decremented(corner);
        let point = |sharpnesses: &[f32], corner: f32| match VertexRule::of(corner, sharpnesses) {
            VertexRule::Smooth => smooth,
            VertexRule::Corner => s,
            VertexRule::Crease(i, j) => {
                let other = |k: usize| {
                    let (a, b) = edges[incident[k]].ends;
                    self.points[if a as usize == v { b } else { a } as usize]
                };
                (other(i) + 6.0 * s + other(j)) / 8.0
            }
        };
        let (this_level, next_level) = (point(&parent, corner), point(&child, child_corner));
        if VertexRule::of(corner, &parent) == VertexRule::of(child_corner, &child) {
            return this_level;
        }
        let weight = transition_weight(corner, child_corner, &parent, &child);
        next_level.lerp(this_level, weight)
    }

    /// The next level's creases and corners (`out`'s): each parent edge's two halves (to its edge point, numbered
    /// `edge_base + edge`) take the sharpness the crease method gives them at their own end; corner sharpness
    /// decreases by one a level. Infinitely sharp stays so.
    fn child_creases(
        &self,
        edges: &[Edge],
        vertex_edges: &[Vec<usize>],
        edge_base: u32,
        out: &mut PolygonMesh,
    ) {
        for (e, edge) in edges.iter().enumerate() {
            let sharpness = self.creases.get(&edge.ends).copied().unwrap_or(0.0);
            if sharpness <= 0.0 {
                continue;
            }
            let mid = edge_base + e as u32;
            for end in [edge.ends.0, edge.ends.1] {
                let around: Vec<f32> = vertex_edges[end as usize]
                    .iter()
                    .map(|&i| edges[i].sharpness)
                    .collect();
                let s = self.rules.crease_method.child_sharpness(sharpness, &around);
                if s > 0.0 {
                    out.creases.insert((end.min(mid), end.max(mid)), s);
                }
            }
        }
        for (&v, &s) in &self.corners {
            let s = decremented(s);
            if s > 0.0 {
                out.corners.insert(v, s);
            }
        }
    }

    /// Sets `out`'s UVs and colours (its faces made by one level of `scheme` on this mesh, of `topology`) from
    /// this mesh's.
    fn child_face_varying_into(&self, scheme: Scheme, topology: &Topology, out: &mut PolygonMesh) {
        let around: Vec<Vec<f32>> = topology
            .vertex_edges
            .iter()
            .map(|incident| {
                incident
                    .iter()
                    .map(|&e| topology.edges[e].sharpness)
                    .collect()
            })
            .collect();
        out.uvs = self.uvs.as_ref().map(|uvs| {
            let values: Vec<Vec3> = uvs.iter().map(|uv| uv.extend(0.0)).collect();
            let child = self.child_face_varying(&values, scheme, &around, topology);
            child.into_iter().map(Vec3::truncate).collect()
        });
        out.colors = self
            .colors
            .as_ref()
            .map(|colors| self.child_face_varying(colors, scheme, &around, topology));
    }

    /// The child corners' face-varying `values` (one per face corner of this mesh, in `scheme`'s child order):
    /// linear within each face under [`FaceVaryingRule::All`], else one level of `scheme` on
    /// [`Self::value_mesh`], with Chaikin's rule averaging over this mesh's edge sharpness `around` each vertex.
    fn child_face_varying(
        &self,
        values: &[Vec3],
        scheme: Scheme,
        around: &[Vec<f32>],
        topology: &Topology,
    ) -> Vec<Vec3> {
        if self.rules.face_varying == FaceVaryingRule::All {
            let mut start = 0usize;
            let mut out = Vec::with_capacity(values.len() * 4);
            for &c in &self.counts {
                let face = &values[start..start + c as usize];
                out.extend(match scheme {
                    Scheme::CatmullClark => linear_face_varying(face),
                    Scheme::Loop => linear_face_varying_triangle(face),
                });
                start += c as usize;
            }
            return out;
        }
        let (mesh, vertex_of) = self.value_mesh(values, topology);
        let around: Vec<Vec<f32>> = vertex_of
            .iter()
            .map(|&v| around[v as usize].clone())
            .collect();
        let child = match scheme {
            Scheme::CatmullClark => mesh.subdivide_once(Some(&around)),
            Scheme::Loop => mesh.loop_once(Some(&around)),
        };
        child
            .indices
            .iter()
            .map(|&i| child.points[i as usize])
            .collect()
    }

    /// Face-varying `values` (one per face corner) as a mesh of their own: a vertex per distinct value at each
    /// vertex, so that a seam is a boundary. It keeps the faces, the creases and corners of this mesh, and its
    /// face-varying rule becomes sharpness: a boundary rule (corners pinned unless the rule is `none`) and
    /// infinitely sharp values where the rule pins them.
    ///
    /// Returns the mesh and the vertex of each of its values.
    fn value_mesh(&self, values: &[Vec3], topology: &Topology) -> (PolygonMesh, Vec<u32>) {
        let mut id_of: HashMap<(u32, [u32; 3]), u32> = HashMap::new();
        let (mut points, mut vertex_of) = (Vec::new(), Vec::new());
        let indices: Vec<u32> = self
            .indices
            .iter()
            .zip(values)
            .map(|(&v, value)| {
                *id_of
                    .entry((v, value.to_array().map(f32::to_bits)))
                    .or_insert_with(|| {
                        points.push(*value);
                        vertex_of.push(v);
                        points.len() as u32 - 1
                    })
            })
            .collect();
        let rule = self.rules.face_varying;
        let mut mesh = PolygonMesh {
            points,
            counts: self.counts.clone(),
            indices,
            face_tags: vec![0; self.counts.len()],
            rules: SubdivisionRules {
                boundary: match rule {
                    FaceVaryingRule::None | FaceVaryingRule::All => BoundaryRule::EdgeOnly,
                    _ => BoundaryRule::EdgeAndCorner,
                },
                crease_method: self.rules.crease_method,
                face_varying: FaceVaryingRule::All,
            },
            ..Default::default()
        };
        let (_, value_edges) = mesh.edge_table();
        for edge in &value_edges {
            let (a, b) = (
                vertex_of[edge.ends.0 as usize],
                vertex_of[edge.ends.1 as usize],
            );
            if let Some(&s) = self.creases.get(&(a.min(b), a.max(b))) {
                mesh.creases.insert(edge.ends, s);
            }
        }
        // The mesh's corners hold for its values, and so does `edgeAndCorner`'s corner at a vertex of one face
        // (which matters under `none`, whose own boundary rule leaves island corners smooth).
        for (value, &v) in vertex_of.iter().enumerate() {
            let boundary_corner = self.rules.boundary == BoundaryRule::EdgeAndCorner
                && topology.vertex_faces[v as usize].len() == 1;
            let sharpness = if boundary_corner {
                Some(INFINITELY_SHARP)
            } else {
                self.corners.get(&v).copied()
            };
            if let Some(s) = sharpness {
                mesh.corners.insert(value as u32, s);
            }
        }
        for value in self.pinned_values(rule, &mesh, &value_edges, &vertex_of, topology) {
            mesh.corners.insert(value, INFINITELY_SHARP);
        }
        (mesh, vertex_of)
    }

    /// The values of `value_mesh` (whose edges are `value_edges`, and whose value i lies at vertex
    /// `vertex_of[i]`) that face-varying `rule` pins beyond its boundary rule: where three or more values meet
    /// (`cornersPlus1` and `cornersPlus2`); a seam's end inside the mesh and both values of a vertex where one of
    /// two spans a single face (`cornersPlus2`); every value on a seam or boundary (`boundaries`).
    fn pinned_values(
        &self,
        rule: FaceVaryingRule,
        value_mesh: &PolygonMesh,
        value_edges: &[Edge],
        vertex_of: &[u32],
        topology: &Topology,
    ) -> Vec<u32> {
        let on_boundary = |edges: &[Edge], n: usize| {
            let mut boundary = vec![false; n];
            for edge in edges.iter().filter(|e| e.faces.len() != 2) {
                boundary[edge.ends.0 as usize] = true;
                boundary[edge.ends.1 as usize] = true;
            }
            boundary
        };
        let value_on_boundary = on_boundary(value_edges, value_mesh.points.len());
        match rule {
            FaceVaryingRule::Boundaries => {
                return (0..value_mesh.points.len() as u32)
                    .filter(|&i| value_on_boundary[i as usize])
                    .collect()
            }
            FaceVaryingRule::CornersPlus1 | FaceVaryingRule::CornersPlus2 => {}
            _ => return Vec::new(),
        }
        // Each vertex's values, with the number of faces each spans there.
        let mut at_vertex: Vec<Vec<(u32, usize)>> = vec![Vec::new(); self.points.len()];
        for &value in &value_mesh.indices {
            let values = &mut at_vertex[vertex_of[value as usize] as usize];
            match values.iter_mut().find(|(v, _)| *v == value) {
                Some((_, span)) => *span += 1,
                None => values.push((value, 1)),
            }
        }
        let vertex_on_boundary = on_boundary(topology.edges, self.points.len());
        let plus2 = rule == FaceVaryingRule::CornersPlus2;
        let mut pinned = Vec::new();
        for (v, values) in at_vertex.iter().enumerate() {
            let junction = values.len() > 2;
            let seam_end = plus2
                && values.len() == 1
                && !vertex_on_boundary[v]
                && value_on_boundary[values[0].0 as usize];
            let concave = plus2 && values.len() == 2 && values.iter().any(|&(_, span)| span == 1);
            if junction || seam_end || concave {
                pinned.extend(values.iter().map(|&(value, _)| value));
            }
        }
        pinned
    }
}

/// A sharpness one level down: infinitely sharp stays so, others lose one, down to zero.
fn decremented(sharpness: f32) -> f32 {
    if sharpness >= INFINITELY_SHARP {
        sharpness
    } else {
        (sharpness - 1.0).max(0.0)
    }
}

impl CreaseMethod {
    /// The sharpness of an edge's half at one of its ends, from the edge's `sharpness` and the sharpness of
    /// every edge at that end (`around`, the edge itself included).
    fn child_sharpness(self, sharpness: f32, around: &[f32]) -> f32 {
        if self == CreaseMethod::Uniform || around.len() < 2 || sharpness <= 0.0 {
            return decremented(sharpness);
        }
        if sharpness >= INFINITELY_SHARP {
            return sharpness;
        }
        // The other sharp edges' mean (the edge itself taken out once).
        let (sum, count) = around
            .iter()
            .filter(|&&s| s > 0.0)
            .fold((-sharpness, -1i32), |(sum, n), &s| (sum + s, n + 1));
        let blended = if count > 0 {
            0.75 * sharpness + 0.25 * sum / count as f32
        } else {
            sharpness
        };
        (blended - 1.0).max(0.0)
    }
}

/// Which rule places a vertex point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum VertexRule {
    /// The scheme's smooth rule (also a dart: one sharp edge).
    Smooth,
    /// The crease rule along the two sharp edges at these positions in the vertex's edge list.
    Crease(usize, usize),
    /// The vertex stays put.
    Corner,
}

impl VertexRule {
    /// The rule of a vertex of `corner` sharpness whose edges have `sharpnesses`.
    fn of(corner: f32, sharpnesses: &[f32]) -> VertexRule {
        let mut sharp = sharpnesses.iter().enumerate().filter(|(_, &s)| s > 0.0);
        match (corner > 0.0, sharp.next(), sharp.next(), sharp.next()) {
            (true, ..) | (_, Some(_), Some(_), Some(_)) => VertexRule::Corner,
            (_, Some((i, _)), Some((j, _)), None) => VertexRule::Crease(i, j),
            _ => VertexRule::Smooth,
        }
    }
}

/// The weight of this level's rule against the next level's where they differ: the mean of the sharpnesses
/// (each at most 1) of the corner and edges that decay to zero between the two levels (DeRose et al. 1998, §3's
/// fractional sharpness, as OpenSubdiv averages it over several at once).
fn transition_weight(corner: f32, child_corner: f32, parent: &[f32], child: &[f32]) -> f32 {
    let decaying = std::iter::once((corner, child_corner))
        .chain(parent.iter().copied().zip(child.iter().copied()))
        .filter(|&(s, c)| s > 0.0 && c <= 0.0)
        .map(|(s, _)| s.min(1.0));
    let (sum, n) = decaying.fold((0.0, 0), |(sum, n), s| (sum + s, n + 1));
    if n == 0 {
        1.0
    } else {
        sum / n as f32
    }
}

/// The edges of the mesh being subdivided and what meets at each vertex, as one level computes them once
/// ([`PolygonMesh::edge_table`], [`PolygonMesh::incidence`]) for its points and its face-varying data alike.
struct Topology<'a> {
    /// The edges.
    edges: &'a [Edge],
    /// Each vertex's incident edges.
    vertex_edges: &'a [Vec<usize>],
    /// Each vertex's incident faces.
    vertex_faces: &'a [Vec<usize>],
}

/// An edge of the mesh being subdivided.
struct Edge {
    /// Its vertices, smaller index first.
    ends: (u32, u32),
    /// The faces that use it.
    faces: Vec<usize>,
    /// Its sharpness this level (infinite on boundaries and non-manifold edges).
    sharpness: f32,
}

/// The four corners of each child quad of a face, from the face's corner values: for corner k, the value at the
/// corner, at the next edge's midpoint, at the face centre and at the previous edge's midpoint.
fn linear_face_varying<T>(values: &[T]) -> Vec<T>
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<f32, Output = T>,
{
    let c = values.len();
    let centre = values.iter().skip(1).fold(values[0], |a, &v| a + v) * (1.0 / c as f32);
    (0..c)
        .flat_map(|k| {
            let (prev, here, next) = (values[(k + c - 1) % c], values[k], values[(k + 1) % c]);
            [here, (here + next) * 0.5, centre, (prev + here) * 0.5]
        })
        .collect()
}

/// The three corners of each of a triangle's four Loop children, from its corner values (in the order
/// [`PolygonMesh::loop_once`] makes the children: the three at the corners, then the middle one).
fn linear_face_varying_triangle<T>(values: &[T]) -> Vec<T>
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<f32, Output = T>,
{
    let [a, b, c] = [values[0], values[1], values[2]];
    let [ab, bc, ca] = [(a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5];
    vec![a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca]
}

#[cfg(test)]
#[path = "subdivision_reference.rs"]
mod opensubdiv_reference;

#[cfg(test)]
mod tests {
    use super::*;

    /// The cube [−1, 1]³ as 6 quads, counter-clockwise from outside.
    pub(super) fn cube() -> PolygonMesh {
        let points = (0..8)
            .map(|i| {
                Vec3::new(
                    if i & 1 == 0 { -1.0 } else { 1.0 },
                    if i & 2 == 0 { -1.0 } else { 1.0 },
                    if i & 4 == 0 { -1.0 } else { 1.0 },
                )
            })
            .collect();
        PolygonMesh {
            points,
            counts: vec![4; 6],
            indices: vec![
                0, 2, 3, 1, // −z
                4, 5, 7, 6, // +z
                0, 1, 5, 4, // −y
                2, 6, 7, 3, // +y
                0, 4, 6, 2, // −x
                1, 3, 7, 5, // +x
            ],
            face_tags: vec![0; 6],
            ..Default::default()
        }
    }

    /// One level on the cube, by hand (Catmull & Clark's rules): a corner (±1)³ moves to (±5/9)³, an edge
    /// point lies at (±3/4, ±3/4, 0) and the like, a face point at the face centre.
    #[test]
    fn one_level_on_a_cube_gives_the_closed_form_points() {
        let c = cube();
        let s = c.subdivide(1).unwrap();
        assert_eq!((s.points.len(), s.counts.len()), (8 + 12 + 6, 24));
        for (i, &p) in s.points[..8].iter().enumerate() {
            assert!(
                p.distance(c.points[i] * (5.0 / 9.0)) < 1e-6,
                "vertex {i}: {p}"
            );
        }
        for &p in &s.points[8..20] {
            let sorted = {
                let mut a = p.abs().to_array();
                a.sort_by(f32::total_cmp);
                a
            };
            assert!(
                (sorted[0]).abs() < 1e-6
                    && (sorted[1] - 0.75).abs() < 1e-6
                    && (sorted[2] - 0.75).abs() < 1e-6,
                "edge point {p}"
            );
        }
        for &p in &s.points[20..] {
            assert!(
                (p.length() - 1.0).abs() < 1e-6 && p.abs().max_element() == 1.0,
                "face point {p}"
            );
        }
        // Two levels: 96 quads, and every vertex strictly inside the cube, on the convex side.
        let s2 = c.subdivide(2).unwrap();
        assert_eq!(s2.faces_after(0), 96);
        assert_eq!(c.faces_after(2), 96);
        assert!(s2.points.iter().all(|p| p.abs().max_element() < 1.0));
    }

    /// Every edge infinitely sharp: the cube keeps its shape (each face subdivides as a bilinear patch).
    #[test]
    fn infinitely_sharp_edges_keep_a_cube_a_cube() {
        let mut c = cube();
        for (_, corners) in c.clone().faces() {
            for k in 0..4 {
                let (a, b) = (corners[k], corners[(k + 1) % 4]);
                c.creases.insert((a.min(b), a.max(b)), INFINITELY_SHARP);
            }
        }
        let s = c.subdivide(3).unwrap();
        for p in &s.points {
            // On the cube's surface: one coordinate is ±1, the others within.
            assert!((p.abs().max_element() - 1.0).abs() < 1e-6, "{p}");
        }
        for (i, p) in c.points.iter().enumerate() {
            assert!(
                s.points[i].distance(*p) < 1e-6,
                "corner {i} moved to {}",
                s.points[i]
            );
        }
    }

    /// A semi-sharp crease of sharpness 0.5 on one cube edge puts its edge point halfway between the smooth
    /// rule and the midpoint; sharpness 1.5 is sharp at the first level and half sharp at the second.
    #[test]
    fn semi_sharp_edges_blend_the_rules_and_decrease_per_level() {
        let edge = (3, 7); // (1, 1, −1)–(1, 1, 1)
        for (sharpness, want) in [(0.5, 0.875), (1.5, 1.0), (0.0, 0.75)] {
            let mut c = cube();
            c.creases.insert(edge, sharpness);
            let s = c.subdivide(1).unwrap();
            let p = s.points[8..20]
                .iter()
                .find(|p| p.z.abs() < 1e-6 && p.x > 0.0 && p.y > 0.0)
                .unwrap();
            assert!(
                (p.x - want).abs() < 1e-6 && (p.y - want).abs() < 1e-6,
                "s {sharpness}: {p}"
            );
            let remaining = s.creases.values().copied().collect::<Vec<_>>();
            let expected = if sharpness > 1.0 {
                vec![0.5, 0.5]
            } else {
                vec![]
            };
            assert_eq!(remaining, expected, "s {sharpness}");
        }
    }

    /// A flat 3×3 grid of quads stays flat, keeps its boundary on the square (boundary edges are sharp) and
    /// its four corners fixed (edgeAndCorner); the centre vertex of a regular flat grid does not move.
    #[test]
    fn a_flat_grid_stays_flat_with_fixed_corners_and_boundary() {
        let points = (0..16)
            .map(|i| Vec3::new((i % 4) as f32, (i / 4) as f32, 0.0))
            .collect();
        let mut indices = Vec::new();
        for y in 0..3 {
            for x in 0..3 {
                let i = y * 4 + x;
                indices.extend([i, i + 1, i + 5, i + 4]);
            }
        }
        let uvs: Vec<Vec2> = indices
            .iter()
            .map(|&i| Vec2::new((i % 4) as f32, (i / 4) as f32))
            .collect();
        let grid = PolygonMesh {
            points,
            counts: vec![4; 9],
            indices,
            uvs: Some(uvs),
            face_tags: (0..9).collect(),
            ..Default::default()
        };
        let s = grid.subdivide(2).unwrap();
        assert!(s.points.iter().all(|p| p.z == 0.0));
        assert!(s
            .points
            .iter()
            .all(|p| (-1e-6..=3.0 + 1e-6).contains(&p.x) && (-1e-6..=3.0 + 1e-6).contains(&p.y)));
        for corner in [0, 3, 12, 15] {
            assert!(s.points[corner].distance(grid.points[corner]) < 1e-6);
        }
        for inner in [5, 6, 9, 10] {
            assert!(
                s.points[inner].distance(grid.points[inner]) < 1e-5,
                "{}",
                s.points[inner]
            );
        }
        // Cubic B-splines reproduce linear functions, so on a uniform flat grid every subdivided point is where
        // bilinear interpolation of the cage puts it: the linearly interpolated uv (the cage's xy) equals it.
        let uvs = s.uvs.as_ref().unwrap();
        for (k, &v) in s.indices.iter().enumerate() {
            let p = s.points[v as usize];
            assert!(
                uvs[k].distance(p.truncate()) < 1e-5,
                "corner {k}: uv {} at {p}",
                uvs[k]
            );
        }
        assert_eq!(s.face_tags.len(), 144);
        assert!(s.face_tags.iter().all(|&t| t < 9));
        // Normals of a flat grid all face +z.
        assert!(s
            .corner_normals()
            .iter()
            .all(|n| n.distance(Vec3::Z) < 1e-6));
    }

    #[test]
    fn bad_topology_is_an_error() {
        let mut c = cube();
        c.counts[0] = 2;
        assert!(c.subdivide(1).is_err());
        let mut c = cube();
        c.indices[0] = 99;
        assert!(c.subdivide(1).is_err());
        let mut c = cube();
        c.face_tags.pop();
        assert!(c.subdivide(1).is_err());
    }

    /// The regular octahedron (vertices ±x, ±y, ±z), counter-clockwise from outside.
    pub(super) fn octahedron() -> PolygonMesh {
        let points = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let (px, nx, py, ny, pz, nz) = (0, 1, 2, 3, 4, 5);
        let indices = vec![
            px, py, pz, py, nx, pz, nx, ny, pz, ny, px, pz, //
            py, px, nz, nx, py, nz, ny, nx, nz, px, ny, nz,
        ];
        PolygonMesh {
            points,
            counts: vec![3; 8],
            indices,
            face_tags: vec![0; 8],
            ..Default::default()
        }
    }

    /// One Loop level on the octahedron, by hand (Loop 1987): every vertex has n = 4 neighbours summing to zero,
    /// so it moves to (1 − 4β) with β = (5/8 − (3/8)²)/4 = 31/256, that is to 132/256 of itself; an edge point
    /// is 3/8 of the edge's end sum (its two opposite vertices cancel).
    #[test]
    fn one_loop_level_on_an_octahedron_gives_the_closed_form_points() {
        let o = octahedron();
        let s = o.subdivide_with(Scheme::Loop, 1).unwrap();
        assert_eq!((s.points.len(), s.counts.len()), (6 + 12, 32));
        assert_eq!(o.faces_after_with(Scheme::Loop, 3), 8 * 64);
        for (i, &p) in s.points[..6].iter().enumerate() {
            assert!(
                p.distance(o.points[i] * (132.0 / 256.0)) < 1e-6,
                "vertex {i}: {p}"
            );
        }
        for &p in &s.points[6..] {
            let mut a = p.abs().to_array();
            a.sort_by(f32::total_cmp);
            assert!(
                a[0].abs() < 1e-6 && (a[1] - 0.375).abs() < 1e-6 && (a[2] - 0.375).abs() < 1e-6,
                "edge point {p}"
            );
        }
        // Faces keep facing outwards, and two more levels shrink every point inside the octahedron's hull.
        let s3 = o.subdivide_with(Scheme::Loop, 3).unwrap();
        assert_eq!(s3.counts.len(), 8 * 64);
        assert!(s3.points.iter().all(|p| p.abs().element_sum() < 1.0));
        let normals = s3.corner_normals();
        for (k, &v) in s3.indices.iter().enumerate() {
            assert!(normals[k].dot(s3.points[v as usize]) > 0.0, "corner {k}");
        }
    }

    /// A flat triangulated square stays flat under Loop's rules; its boundary is sharp, so points on it stay on
    /// it, and corners marked infinitely sharp stay put; face-varying values interpolate linearly.
    #[test]
    fn a_flat_triangle_grid_stays_flat_with_a_sharp_boundary() {
        let uv = |x: f32, y: f32| Vec2::new(x, y);
        let mut square = PolygonMesh {
            points: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::Y,
                Vec3::new(0.5, 0.5, 0.0),
            ],
            counts: vec![3; 4],
            indices: vec![0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4],
            uvs: Some(vec![
                uv(0.0, 0.0),
                uv(1.0, 0.0),
                uv(0.5, 0.5),
                uv(1.0, 0.0),
                uv(1.0, 1.0),
                uv(0.5, 0.5),
                uv(1.0, 1.0),
                uv(0.0, 1.0),
                uv(0.5, 0.5),
                uv(0.0, 1.0),
                uv(0.0, 0.0),
                uv(0.5, 0.5),
            ]),
            face_tags: vec![0, 1, 2, 3],
            ..Default::default()
        };
        for v in 0..4 {
            square.corners.insert(v, INFINITELY_SHARP);
        }
        let s = square.subdivide_with(Scheme::Loop, 2).unwrap();
        assert!(s.points.iter().all(|p| p.z.abs() < 1e-6));
        for i in 0..4 {
            assert!(s.points[i].distance(square.points[i]) < 1e-6, "corner {i}");
        }
        assert!(s
            .points
            .iter()
            .all(|p| p.x > -1e-6 && p.y > -1e-6 && p.x < 1.0 + 1e-6 && p.y < 1.0 + 1e-6));
        // The UVs are the points' x and y with no seam, so under USD's default face-varying rule they are
        // subdivided as the points are.
        let uvs = s.uvs.as_ref().unwrap();
        for (k, &v) in s.indices.iter().enumerate() {
            assert!(
                uvs[k].distance(s.points[v as usize].truncate()) < 1e-6,
                "corner {k}"
            );
        }
        // Linear face-varying interpolation: face 0's first child is (corner 0, the midpoint toward 1, the
        // midpoint toward the centre).
        square.rules.face_varying = FaceVaryingRule::All;
        let one = square.subdivide_with(Scheme::Loop, 1).unwrap();
        let uvs = one.uvs.unwrap();
        assert_eq!(&uvs[..3], &[uv(0.0, 0.0), uv(0.5, 0.0), uv(0.25, 0.25)]);
        assert_eq!(&uvs[9..12], &[uv(0.5, 0.0), uv(0.75, 0.25), uv(0.25, 0.25)]);
        assert_eq!(s.face_tags.iter().filter(|&&t| t == 2).count(), 16);
    }

    #[test]
    fn loop_subdivision_refuses_polygons_other_than_triangles() {
        let err = cube().subdivide_with(Scheme::Loop, 1).unwrap_err();
        assert!(err.to_string().contains("face 0 has 4 vertices"), "{err}");
    }
}
