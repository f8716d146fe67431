//! Our subdivision against an independent implementation of the same rules: `opensubdiv-rs`, a port of Pixar's
//! OpenSubdiv (the library USD's renderers subdivide with), used only as a test dependency. Each test refines the
//! same cage with both and compares every child face: its corner positions and its face-varying values.
//!
//! The two number child vertices differently (OpenSubdiv puts face points first), so faces are matched by their
//! centroid and corners by their position.

use super::*;
use opensubdiv_rs::far::{
    FVarChannelDescriptor, PrimvarRefiner, TopologyDescriptor, TopologyRefinerFactory,
    UniformOptions,
};
use opensubdiv_rs::sdc;

/// A refined face: its corners' positions and face-varying values (u, v, 0).
type Face = Vec<(Vec3, Vec3)>;

/// OpenSubdiv's options for our rules.
fn options(rules: &SubdivisionRules) -> sdc::Options {
    sdc::Options::default()
        .with_vtx_boundary_interpolation(match rules.boundary {
            BoundaryRule::EdgeAndCorner => sdc::VtxBoundaryInterpolation::EdgeAndCorner,
            BoundaryRule::EdgeOnly => sdc::VtxBoundaryInterpolation::EdgeOnly,
        })
        .with_fvar_linear_interpolation(match rules.face_varying {
            FaceVaryingRule::None => sdc::FVarLinearInterpolation::None,
            FaceVaryingRule::CornersOnly => sdc::FVarLinearInterpolation::CornersOnly,
            FaceVaryingRule::CornersPlus1 => sdc::FVarLinearInterpolation::CornersPlus1,
            FaceVaryingRule::CornersPlus2 => sdc::FVarLinearInterpolation::CornersPlus2,
            FaceVaryingRule::Boundaries => sdc::FVarLinearInterpolation::Boundaries,
            FaceVaryingRule::All => sdc::FVarLinearInterpolation::All,
        })
        .with_creasing_method(match rules.crease_method {
            CreaseMethod::Uniform => sdc::CreasingMethod::Uniform,
            CreaseMethod::Chaikin => sdc::CreasingMethod::Chaikin,
        })
}

/// The faces OpenSubdiv makes from `cage` (whose UVs, if any, are welded into a face-varying channel by equal
/// value at a vertex) after `levels` of `scheme`.
fn reference(cage: &PolygonMesh, scheme: Scheme, levels: usize) -> Vec<Face> {
    let counts: Vec<usize> = cage.counts.iter().map(|&c| c as usize).collect();
    let (mut pairs, mut weights) = (Vec::new(), Vec::new());
    for (&(a, b), &s) in &cage.creases {
        pairs.push([a, b]);
        weights.push(s);
    }
    let (mut corner_vertices, mut corner_weights) = (Vec::new(), Vec::new());
    for (&v, &s) in &cage.corners {
        corner_vertices.push(v);
        corner_weights.push(s);
    }
    // The face-varying channel: one value per distinct (vertex, uv).
    let uvs: Vec<Vec3> = match &cage.uvs {
        Some(uvs) => uvs.iter().map(|uv| uv.extend(0.0)).collect(),
        None => vec![Vec3::ZERO; cage.indices.len()],
    };
    let mut values: Vec<[f32; 3]> = Vec::new();
    let mut value_of: HashMap<(u32, [u32; 3]), u32> = HashMap::new();
    let value_indices: Vec<u32> = cage
        .indices
        .iter()
        .zip(&uvs)
        .map(|(&v, uv)| {
            let key = (v, uv.to_array().map(f32::to_bits));
            *value_of.entry(key).or_insert_with(|| {
                values.push(uv.to_array());
                values.len() as u32 - 1
            })
        })
        .collect();
    let channels = [FVarChannelDescriptor::new(values.len(), &value_indices)];
    let descriptor = TopologyDescriptor::new(cage.points.len(), &counts, &cage.indices)
        .with_creases(&pairs, &weights)
        .with_corners(&corner_vertices, &corner_weights)
        .with_fvar_channels(&channels);
    let scheme = match scheme {
        Scheme::CatmullClark => sdc::SchemeType::Catmark,
        Scheme::Loop => sdc::SchemeType::Loop,
    };
    let mut refiner =
        TopologyRefinerFactory::create(descriptor, scheme, options(&cage.rules)).unwrap();
    refiner.refine_uniform(UniformOptions::new(levels));
    let primvar = PrimvarRefiner::new(&refiner);
    let mut points: Vec<[f32; 3]> = cage.points.iter().map(|p| p.to_array()).collect();
    for level in 1..=levels {
        let mut next = vec![[0.0; 3]; refiner.level(level).num_vertices()];
        primvar.interpolate(level, &points, &mut next);
        points = next;
        let mut next = vec![[0.0; 3]; refiner.level(level).num_fvar_values(0)];
        primvar.interpolate_face_varying(level, 0, &values, &mut next);
        values = next;
    }
    let last = refiner.level(levels);
    (0..last.num_faces())
        .map(|f| {
            let corners = last.face_vertices(f);
            let fvar = last.face_fvar_values(f, 0);
            corners
                .iter()
                .zip(fvar)
                .map(|(&v, &u)| {
                    (
                        Vec3::from(points[v as usize]),
                        Vec3::from(values[u as usize]),
                    )
                })
                .collect()
        })
        .collect()
}

/// Our faces of `mesh`, in the same form.
fn ours(mesh: &PolygonMesh) -> Vec<Face> {
    let uvs = mesh.uvs.clone().unwrap_or_default();
    mesh.faces()
        .map(|(_, corners)| {
            let start = corners.as_ptr() as usize - mesh.indices.as_ptr() as usize;
            let start = start / std::mem::size_of::<u32>();
            corners
                .iter()
                .enumerate()
                .map(|(k, &v)| {
                    let uv = uvs.get(start + k).map_or(Vec3::ZERO, |uv| uv.extend(0.0));
                    (mesh.points[v as usize], uv)
                })
                .collect()
        })
        .collect()
}

/// The largest differences (position, face-varying value) between our `levels` of `scheme` on `cage` and
/// OpenSubdiv's, over corresponding corners.
fn differences(cage: &PolygonMesh, scheme: Scheme, levels: u32) -> (f32, f32) {
    let mine = ours(&cage.subdivide_with(scheme, levels).unwrap());
    let theirs = reference(cage, scheme, levels as usize);
    assert_eq!(mine.len(), theirs.len(), "face counts");
    let centroid = |f: &Face| f.iter().fold(Vec3::ZERO, |a, c| a + c.0) / f.len() as f32;
    let mut worst = (0.0f32, 0.0f32);
    for face in &mine {
        let c = centroid(face);
        let other = theirs
            .iter()
            .min_by(|a, b| centroid(a).distance(c).total_cmp(&centroid(b).distance(c)))
            .unwrap();
        assert_eq!(face.len(), other.len());
        for &(p, uv) in face {
            let &(q, their_uv) = other
                .iter()
                .min_by(|a, b| a.0.distance(p).total_cmp(&b.0.distance(p)))
                .unwrap();
            worst.0 = worst.0.max(p.distance(q));
            worst.1 = worst.1.max(uv.distance(their_uv));
        }
    }
    worst
}

/// Checks every combination of `rules` on each of `cages`, to `levels`, and fails naming every one that differs
/// from OpenSubdiv by more than `TOLERANCE`.
fn assert_all_match(
    cages: &[(&str, PolygonMesh)],
    scheme: Scheme,
    rules: &[SubdivisionRules],
    levels: u32,
) {
    const TOLERANCE: f32 = 2e-5;
    let mut failures = Vec::new();
    for (name, base) in cages {
        for &rule in rules {
            let mut cage = base.clone();
            cage.rules = rule;
            for level in 1..=levels {
                let (position, value) = differences(&cage, scheme, level);
                if position > TOLERANCE || value > TOLERANCE {
                    failures.push(format!(
                        "{name} {rule:?} level {level}: position {position:.2e}, face-varying {value:.2e}"
                    ));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases differ from OpenSubdiv:\n{}",
        failures.len(),
        cages.len() * rules.len() * levels as usize,
        failures.join("\n")
    );
}

/// Every combination of the three rules.
fn every_rule() -> Vec<SubdivisionRules> {
    let mut rules = Vec::new();
    for boundary in [BoundaryRule::EdgeAndCorner, BoundaryRule::EdgeOnly] {
        for crease_method in [CreaseMethod::Uniform, CreaseMethod::Chaikin] {
            for face_varying in ALL_FACE_VARYING {
                rules.push(SubdivisionRules {
                    boundary,
                    crease_method,
                    face_varying,
                });
            }
        }
    }
    rules
}

/// A 3×2 grid of unit quads in the xz plane (an open mesh with boundary corners), with UVs in two islands split
/// along x = 1 (a seam), so that the seam's ends are face-varying corners and junctions.
fn seamed_grid() -> PolygonMesh {
    let (nx, nz) = (3u32, 2u32);
    let points = (0..=nz)
        .flat_map(|z| (0..=nx).map(move |x| Vec3::new(x as f32, 0.1 * (x * z) as f32, z as f32)))
        .collect();
    let mut mesh = PolygonMesh {
        points,
        ..Default::default()
    };
    let mut uvs = Vec::new();
    for z in 0..nz {
        for x in 0..nx {
            let v = |x: u32, z: u32| z * (nx + 1) + x;
            let corners = [v(x, z), v(x + 1, z), v(x + 1, z + 1), v(x, z + 1)];
            mesh.counts.push(4);
            mesh.indices.extend(corners);
            mesh.face_tags.push(0);
            let island = if x == 0 { 0.0 } else { 0.5 };
            for c in corners {
                let (cx, cz) = ((c % (nx + 1)) as f32, (c / (nx + 1)) as f32);
                uvs.push(Vec2::new(0.25 * cx + island, 0.3 * cz + 0.05 * cx * cx));
            }
        }
    }
    mesh.uvs = Some(uvs);
    mesh
}

/// The cube with UVs in six islands (one per face), a semi-sharp crease chain of varying sharpness along
/// three edges, and a semi-sharp corner.
fn creased_cube() -> PolygonMesh {
    let mut cube = tests::cube();
    let uvs = (0..24)
        .map(|k| {
            let face = (k / 4) as f32;
            let corner = k % 4;
            Vec2::new(
                face * 0.17
                    + if corner == 1 || corner == 2 {
                        0.15
                    } else {
                        0.0
                    },
                if corner >= 2 { 0.15 } else { 0.0 } + 0.01 * face,
            )
        })
        .collect();
    cube.uvs = Some(uvs);
    for (edge, s) in [((0, 1), 2.5), ((1, 3), 0.7), ((3, 7), 1.6)] {
        cube.creases.insert(edge, s);
    }
    cube.corners.insert(6, 1.3);
    cube
}

const ALL_FACE_VARYING: [FaceVaryingRule; 6] = [
    FaceVaryingRule::None,
    FaceVaryingRule::CornersOnly,
    FaceVaryingRule::CornersPlus1,
    FaceVaryingRule::CornersPlus2,
    FaceVaryingRule::Boundaries,
    FaceVaryingRule::All,
];

#[test]
fn catmull_clark_matches_opensubdiv_under_every_rule() {
    let cages = [
        ("seamed grid", seamed_grid()),
        ("creased cube", creased_cube()),
    ];
    assert_all_match(&cages, Scheme::CatmullClark, &every_rule(), 3);
}

/// The seamed grid with each quad split into two triangles (a UV seam, a boundary), and the octahedron with a
/// crease chain of varying sharpness, a semi-sharp corner and UVs in two islands.
fn triangle_cages() -> Vec<(&'static str, PolygonMesh)> {
    let mut grid = seamed_grid();
    let (mut indices, mut uvs) = (Vec::new(), Vec::new());
    let quad_uvs = grid.uvs.take().unwrap();
    for (f, quad) in grid.indices.chunks(4).enumerate() {
        for k in [0, 1, 2, 0, 2, 3] {
            indices.push(quad[k]);
            uvs.push(quad_uvs[4 * f + k]);
        }
    }
    grid.counts = vec![3; indices.len() / 3];
    grid.face_tags = vec![0; grid.counts.len()];
    grid.indices = indices;
    grid.uvs = Some(uvs);

    let mut octahedron = tests::octahedron();
    let uvs = octahedron
        .indices
        .iter()
        .enumerate()
        .map(|(k, &v)| {
            let p = octahedron.points[v as usize];
            let island = if k < 12 { 0.0 } else { 0.6 };
            Vec2::new(0.25 * (p.x + 1.0) + island, 0.25 * (p.y + 1.0) + 0.1 * p.z)
        })
        .collect();
    octahedron.uvs = Some(uvs);
    for (edge, s) in [((0, 2), 2.5), ((2, 4), 0.7), ((1, 4), 1.6)] {
        octahedron.creases.insert(edge, s);
    }
    octahedron.corners.insert(3, 1.3);
    vec![
        ("triangulated seamed grid", grid),
        ("creased octahedron", octahedron),
    ]
}

#[test]
fn loop_matches_opensubdiv_under_every_rule() {
    let cages = triangle_cages();
    assert_all_match(&cages[..1], Scheme::Loop, &every_rule(), 3);
    // The octahedron's Chaikin crease beside a seam is the one known difference (the next test).
    let uniform: Vec<SubdivisionRules> = every_rule()
        .into_iter()
        .filter(|r| r.crease_method == CreaseMethod::Uniform)
        .collect();
    assert_all_match(&cages[1..], Scheme::Loop, &uniform, 3);
}

/// Where a Chaikin crease meets a UV seam, the two differ, by design: `opensubdiv-rs` refines the value mesh's
/// own sharpness, so the seam's (infinitely sharp) edges enter Chaikin's average at the crease's end, while we
/// take the face-varying data's sharpness from the mesh at every level, as OpenSubdiv's face-varying levels
/// take theirs from the vertex topology. `triangle_cages` has such a crease (0.7 from +y up to +z, beside the
/// equator's seam); this test pins the difference so that a change to either side shows.
#[test]
fn chaikin_creases_beside_a_seam_take_the_mesh_sharpness() {
    let (_, mut octahedron) = triangle_cages().remove(1);
    octahedron.rules.crease_method = CreaseMethod::Chaikin;
    let (position, value) = differences(&octahedron, Scheme::Loop, 2);
    assert!(position < 2e-5, "positions agree: {position}");
    assert!(
        value > 1e-3,
        "face-varying values differ as described: {value}"
    );
    // With the same crease and no seam, the two agree at every level: the difference is that average alone.
    let mut no_seam = octahedron.clone();
    let uvs: Vec<Vec2> = no_seam
        .indices
        .iter()
        .map(|&v| no_seam.points[v as usize].truncate() * 0.25)
        .collect();
    no_seam.uvs = Some(uvs);
    assert!(differences(&no_seam, Scheme::Loop, 3).1 < 2e-5);
}
