//! Instancing (issue 37's `EXT_mesh_gpu_instancing`, issue 36's instanced forest): instances are traced through
//! the two-level hierarchy, not copied. Checked against independent references: the analytic ellipsoid that a
//! non-uniformly scaled, rotated (and mirrored) sphere instance is (hit distance, normals, any-hit), spawned
//! rays that never re-hit the surface they leave, and the same scene written with one mesh per node (which the
//! loader copies to world space), rendered with the same estimator and seed.

use crate::common;

use nimbus::geometry::Mesh;
use nimbus::material::Material;
use nimbus::math::{Mat4, Quat, Ray, Rgb, Rng, Vec3};
use nimbus::render::{RenderImage, RenderSettings, Renderer};
use nimbus::scene::{gltf, MeshInstance, SceneBuilder};
use nimbus::{Camera, Scene};
use serde_json::{json, Value};
use std::path::Path;

/// A glTF document holding `mesh` (positions, normals, u32 indices) as accessors 0, 1 and 2, with `nodes` and
/// `meshes` as given and extra float accessors appended from `extra` (each: the values and the type).
fn document(mesh: &Mesh, meshes: Value, nodes: Vec<Value>, extra: &[(Vec<f32>, &str)]) -> Vec<u8> {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |bytes: Vec<u8>, accessor: Value, bin: &mut Vec<u8>| {
        let offset = bin.len();
        bin.extend_from_slice(&bytes);
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        let mut a = accessor;
        a["bufferView"] = json!(views.len() - 1);
        accessors.push(a);
    };
    let floats = |v: &[f32]| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
    let b = mesh.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let p: Vec<f32> = mesh.positions.iter().flat_map(|v| v.to_array()).collect();
    push(
        floats(&p),
        json!({"componentType": 5126, "count": mesh.positions.len(), "type": "VEC3",
               "min": b.0.to_array(), "max": b.1.to_array()}),
        &mut bin,
    );
    let n: Vec<f32> = mesh.normals.iter().flat_map(|v| v.to_array()).collect();
    push(
        floats(&n),
        json!({"componentType": 5126, "count": mesh.normals.len(), "type": "VEC3"}),
        &mut bin,
    );
    let i: Vec<u8> = mesh
        .indices
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    push(
        i,
        json!({"componentType": 5125, "count": 3 * mesh.indices.len(), "type": "SCALAR"}),
        &mut bin,
    );
    for (values, ty) in extra {
        let per = if *ty == "VEC4" { 4 } else { 3 };
        push(
            floats(values),
            json!({"componentType": 5126, "count": values.len() / per, "type": ty}),
            &mut bin,
        );
    }
    let root = json!({
        "asset": {"version": "2.0"}, "extensionsUsed": ["EXT_mesh_gpu_instancing"],
        "scene": 0, "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes, "meshes": meshes, "accessors": accessors, "bufferViews": views,
        "buffers": [{"byteLength": bin.len(),
                     "uri": format!("data:application/octet-stream;base64,{}", common::base64(&bin))}]
    });
    serde_json::to_vec(&root).unwrap()
}

/// The primitive every mesh of [`document`] draws.
fn primitive() -> Value {
    json!({"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2})
}

/// Five placements (translation, rotation, scale), one of them mirroring and two non-uniform.
fn placements() -> Vec<(Vec3, Quat, Vec3)> {
    vec![
        (Vec3::new(-2.0, 0.0, 0.0), Quat::IDENTITY, Vec3::ONE),
        (
            Vec3::new(-1.0, 0.5, -0.5),
            Quat::from_rotation_z(0.6),
            Vec3::new(1.5, 0.5, 1.0),
        ),
        (
            Vec3::new(0.0, -0.4, 0.3),
            Quat::from_rotation_y(1.1),
            Vec3::new(-1.0, 1.0, 1.0),
        ),
        (
            Vec3::new(1.1, 0.2, 0.0),
            Quat::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 0.8),
            Vec3::new(0.7, 1.3, 0.9),
        ),
        (Vec3::new(2.1, -0.3, -1.0), Quat::IDENTITY, Vec3::splat(0.6)),
    ]
}

fn load(bytes: &[u8], name: &str) -> SceneBuilder {
    gltf::load_slice(bytes, Path::new(name), &Default::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn render(mut b: SceneBuilder, seed: u64) -> RenderImage {
    b.add_directional_light(Vec3::new(-0.3, -1.0, -0.5), Rgb::new(2.0, 1.8, 1.5));
    b.set_environment(nimbus::light::EnvironmentLight::Constant(Rgb::splat(0.3)));
    b.set_camera(Camera::look_at(
        Vec3::new(0.3, 1.2, 6.0),
        Vec3::ZERO,
        45f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let settings = RenderSettings {
        width: 40,
        height: 40,
        spp: 8,
        seed,
        threads: 2,
        max_depth: 4,
        transparent: true,
        ..Default::default()
    };
    Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap()
        .0
}

/// `EXT_mesh_gpu_instancing` places one sphere five times (rotated, non-uniformly scaled, one mirrored) as
/// five instances of one prototype, and renders what the same scene written as five nodes with a mesh each
/// (copied to world space by the loader) renders with the same seed: the same coverage and, pixel by pixel, the
/// same radiance but for the few paths that rounding sends another way. Before, the instances were copies: no
/// prototype, five meshes.
#[test]
fn gpu_instancing_renders_what_separate_copies_render() {
    let sphere = common::uv_sphere(Vec3::ZERO, 0.45, 24, 48, 0);
    let places = placements();
    let t: Vec<f32> = places.iter().flat_map(|p| p.0.to_array()).collect();
    let r: Vec<f32> = places.iter().flat_map(|p| p.1.to_array()).collect();
    let s: Vec<f32> = places.iter().flat_map(|p| p.2.to_array()).collect();
    let instanced = document(
        &sphere,
        json!([{"primitives": [primitive()]}]),
        vec![json!({"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing":
            {"attributes": {"TRANSLATION": 3, "ROTATION": 4, "SCALE": 5}}}})],
        &[(t, "VEC3"), (r, "VEC4"), (s, "VEC3")],
    );
    let nodes = places
        .iter()
        .enumerate()
        .map(|(i, (t, r, s))| {
            json!({"mesh": i, "translation": t.to_array(), "rotation": r.to_array(),
                   "scale": s.to_array()})
        })
        .collect();
    let separate = document(
        &sphere,
        json!(vec![json!({"primitives": [primitive()]}); 5]),
        nodes,
        &[],
    );
    let a = load(&instanced, "instanced.gltf");
    let b = load(&separate, "separate.gltf");
    assert_eq!(
        (a.prototypes().len(), a.instances().len(), a.meshes().len()),
        (1, 5, 0)
    );
    assert_eq!((b.prototypes().len(), b.meshes().len()), (0, 5));
    let (ia, ib) = (render(a, 11), render(b, 11));
    let n = ia.pixel_count();
    let coverage_differs = (0..n).filter(|&i| ia.alpha[i] != ib.alpha[i]).count();
    let radiance_differs = (0..n)
        .filter(|&i| {
            (0..3).any(|c| {
                let (x, y) = (ia.beauty[i][c], ib.beauty[i][c]);
                (x - y).abs() > 1e-3 * x.max(y) + 1e-5
            })
        })
        .count();
    let covered = (0..n).filter(|&i| ia.alpha[i] > 0.0).count();
    eprintln!(
        "{covered} of {n} pixels covered; coverage differs in {coverage_differs}, radiance in {radiance_differs}"
    );
    assert!(covered > n / 10, "{covered}");
    assert!(coverage_differs <= n / 200, "{coverage_differs}");
    assert!(radiance_differs <= n / 50, "{radiance_differs}");
    for c in 0..3 {
        let ((ma, sa), (mb, sb)) = (common::mean_and_se(&ia, c), common::mean_and_se(&ib, c));
        assert!(
            (ma - mb).abs() <= 4.0 * (sa * sa + sb * sb).sqrt() + 1e-6,
            "channel {c}: {ma} vs {mb}"
        );
    }
}

/// One unit-sphere prototype (128 rings) placed twice: as an ellipsoid scaled (2, 0.5, 1), rotated and moved
/// 1000 units away, and mirrored with scale (−1, 1.5, 0.75).
fn ellipsoids() -> (Scene, [(Mat4, &'static str); 2]) {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
    let proto = b.add_prototype(Mesh::uv_sphere(Vec3::ZERO, 1.0, 128, 256, m));
    let placed = [
        (
            Mat4::from_scale_rotation_translation(
                Vec3::new(2.0, 0.5, 1.0),
                Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3),
                Vec3::new(1000.0, -3.0, 2.0),
            ),
            "far",
        ),
        (
            Mat4::from_scale_rotation_translation(
                Vec3::new(-1.0, 1.5, 0.75),
                Quat::from_rotation_z(0.4),
                Vec3::new(-2.0, 1.0, 0.5),
            ),
            "mirrored",
        ),
    ];
    for (m, name) in placed {
        b.add_instance(MeshInstance {
            prototype: proto,
            object_to_world: m,
            name: name.into(),
            ..Default::default()
        })
        .unwrap();
    }
    (b.build().unwrap(), placed)
}

/// The analytic ellipsoid `|A⁻¹(x − c)| = 1` of placement `m` (A its linear part), in f64: the first hit
/// distance of `o + t·d` (if any) and the outward unit normal `A⁻ᵀA⁻¹(x − c)` there.
fn ellipsoid_hit(m: &Mat4, o: Vec3, d: Vec3) -> Option<(f64, Vec3)> {
    let inv = m.as_dmat4().inverse();
    let (lo, ld) = (
        inv.transform_point3(o.as_dvec3()),
        inv.transform_vector3(d.as_dvec3()),
    );
    let (a, b, c) = (ld.dot(ld), 2.0 * lo.dot(ld), lo.dot(lo) - 1.0);
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / (2.0 * a);
    let local = lo + ld * t;
    let normal = inv.transpose().transform_vector3(local).normalize();
    Some((t, normal.as_vec3()))
}

/// Rays from all around each ellipsoid toward points inside it hit at the analytic distance (within the
/// tessellation's chord error), with geometric and shading normals along the analytic normal, on the front
/// face (the mirrored one too: its winding follows the mirror), named by their instance; any-hit queries see
/// the surface just past the hit and not just before it.
#[test]
fn transformed_instances_hit_the_analytic_ellipsoids() {
    let (scene, placed) = ellipsoids();
    let mut rng = Rng::new(17, 3);
    let mut worst = (0.0f64, 1.0f32, 1.0f32);
    for (m, name) in placed {
        let centre = m.transform_point3(Vec3::ZERO);
        for _ in 0..400 {
            let o = centre + 9.0 * nimbus::math::sampling::uniform_sphere(rng.next_2d());
            let target = m.transform_point3(
                0.6 * nimbus::math::sampling::uniform_sphere(rng.next_2d()) * rng.next_f32(),
            );
            let d = (target - o).normalize();
            let (t, normal) = ellipsoid_hit(&m, o, d).expect("toward the inside");
            let ray = Ray::new(o, d);
            let hit = scene
                .intersect(&ray, 0.0, f32::INFINITY)
                .expect("a ray toward the inside hits");
            // A 128-ring sphere's chord error is below 1 − cos(π/256) ≈ 7.5e-5 of the radius, at most 2 here;
            // f32 positions 1000 units out round by 6e-5.
            let dt = (hit.t as f64 - t).abs();
            assert!(dt < 4e-4, "{name}: t {} vs {t}", hit.t);
            assert!(hit.front_face, "{name}");
            let (g, s) = (hit.geometric_normal.dot(normal), hit.shading.n.dot(normal));
            assert!(g > 0.99 && s > 0.9995, "{name}: normals {g} {s}");
            worst = (worst.0.max(dt), worst.1.min(g), worst.2.min(s));
            let object = &scene.names().items[scene.mesh_of_prim(hit.prim)].object;
            assert_eq!(object, name);
            assert!(!scene.occluded(&ray, 0.0, hit.t * (1.0 - 1e-4)), "{name}");
            assert!(scene.occluded(&ray, 0.0, hit.t * (1.0 + 1e-4)), "{name}");
            assert!(
                hit.p.distance(ray.at(hit.t)) <= 1e-3,
                "{name}: {} vs {}",
                hit.p,
                ray.at(hit.t)
            );
        }
    }
    eprintln!(
        "worst: |t - t_exact| {:.2e}, geometric normal cos {:.6}, shading normal cos {:.6}",
        worst.0, worst.1, worst.2
    );
}

/// Rays spawned off an instance's surface (offset by the hit point's error bound carried through the
/// transform) never re-hit it: outward rays leave the convex ellipsoid for good, inward rays cross to its
/// far side. The far ellipsoid sits 1000 units out, where the rounding of the transforms is largest.
#[test]
fn rays_spawned_off_instances_never_rehit_them() {
    let (scene, placed) = ellipsoids();
    let mut rng = Rng::new(23, 5);
    for (m, name) in placed {
        let centre = m.transform_point3(Vec3::ZERO);
        let mut inward = 0;
        for _ in 0..2000 {
            let o = centre + 9.0 * nimbus::math::sampling::uniform_sphere(rng.next_2d());
            let d = (centre - o + 0.5 * nimbus::math::sampling::uniform_sphere(rng.next_2d()))
                .normalize();
            let Some(hit) = scene.intersect(&Ray::new(o, d), 0.0, f32::INFINITY) else {
                continue;
            };
            let w = nimbus::math::sampling::uniform_sphere(rng.next_2d());
            let next = scene.intersect(&Ray::new(hit.spawn_origin(w), w), 0.0, f32::INFINITY);
            let same =
                next.is_some_and(|h| scene.mesh_of_prim(h.prim) == scene.mesh_of_prim(hit.prim));
            let cos = w.dot(hit.geometric_normal);
            if cos > 0.0 {
                assert!(
                    !same,
                    "{name}: an outward ray re-hit the ellipsoid: {next:?}"
                );
            } else if cos < -0.1 {
                // Not grazing, so the chord to the far side is long.
                inward += 1;
                let far = next.expect("an inward ray crosses the ellipsoid");
                assert!(same && far.t > 1e-3, "{name}: {far:?}");
            }
        }
        assert!(inward > 500, "{inward}");
    }
}

/// A sphere with texture coordinates, vertex colours and tangents (w = −1: a mirrored uv mapping) placed by
/// three transforms (one mirroring, one shearing), as instances and as copies (`SceneBuilder::world_meshes`,
/// the path every mesh took before instancing): every ray hits the same surface with the same shading frame
/// (tangents carried to world space), texture coordinates, footprint scale, colour and facing.
#[test]
fn instance_hits_shade_like_world_copies() {
    let mut sphere = Mesh::uv_sphere(Vec3::ZERO, 1.0, 32, 64, 0);
    let n = sphere.positions.len();
    sphere.uvs = Some(
        sphere
            .positions
            .iter()
            .map(|p| nimbus::math::Vec2::new(p.x.atan2(p.z), p.y) * 0.5 + 0.5)
            .collect(),
    );
    sphere.colors = Some(
        sphere
            .positions
            .iter()
            .map(|p| (p.abs() * 0.8 + 0.1).extend(1.0))
            .collect(),
    );
    sphere.tangents = Some(
        sphere
            .normals
            .iter()
            .map(|nrm| {
                Vec3::Y
                    .cross(*nrm)
                    .try_normalize()
                    .unwrap_or(Vec3::X)
                    .extend(-1.0)
            })
            .collect(),
    );
    assert_eq!(sphere.tangents.as_ref().unwrap().len(), n);
    let transforms = [
        Mat4::from_scale_rotation_translation(
            Vec3::new(1.5, 0.6, 1.0),
            Quat::from_rotation_x(0.5),
            Vec3::new(-2.5, 0.0, 0.0),
        ),
        Mat4::from_scale_rotation_translation(
            Vec3::new(-0.8, 1.0, 1.2),
            Quat::from_rotation_y(-0.9),
            Vec3::new(0.0, 0.5, 0.5),
        ),
        Mat4::from_translation(Vec3::new(2.5, -0.5, 0.0))
            * Mat4::from_cols_array(&[
                1.0, 0.0, 0.0, 0.0, 0.4, 1.0, 0.0, 0.0, 0.0, 0.3, 0.9, 0.0, 0.0, 0.0, 0.0, 1.0,
            ]),
    ];
    let scene_with = |instanced: bool| {
        let mut b = SceneBuilder::new();
        b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let proto = b.add_prototype(sphere.clone());
        for (i, m) in transforms.iter().enumerate() {
            b.add_instance(MeshInstance {
                prototype: proto,
                object_to_world: *m,
                name: format!("ball{i}"),
                ..Default::default()
            })
            .unwrap();
        }
        if instanced {
            return b.build().unwrap();
        }
        let mut copies = SceneBuilder::new();
        copies.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        for mesh in b.world_meshes() {
            copies.add_mesh(mesh);
        }
        copies.build().unwrap()
    };
    let (a, b) = (scene_with(true), scene_with(false));
    assert_eq!((a.instance_count(), b.instance_count()), (3, 0));
    let mut rng = Rng::new(31, 7);
    let mut hits = 0;
    for _ in 0..3000 {
        let o =
            Vec3::new(0.0, 0.0, 0.0) + 8.0 * nimbus::math::sampling::uniform_sphere(rng.next_2d());
        let target = Vec3::new(6.0 * rng.next_f32() - 3.0, 2.0 * rng.next_f32() - 1.0, 0.0);
        let ray = Ray::new(o, (target - o).normalize());
        let (ha, hb) = (
            a.intersect(&ray, 0.0, f32::INFINITY),
            b.intersect(&ray, 0.0, f32::INFINITY),
        );
        let (Some(ha), Some(hb)) = (ha, hb) else {
            assert_eq!(ha.is_some(), hb.is_some(), "{ray:?}");
            continue;
        };
        hits += 1;
        let close = |x: Vec3, y: Vec3, tol: f32| x.distance(y) <= tol;
        assert!((ha.t - hb.t).abs() <= 1e-4 * hb.t, "{} vs {}", ha.t, hb.t);
        assert_eq!(ha.front_face, hb.front_face);
        assert!(close(ha.geometric_normal, hb.geometric_normal, 1e-4));
        for (x, y) in [
            (ha.shading.n, hb.shading.n),
            (ha.shading.s, hb.shading.s),
            (ha.shading.t, hb.shading.t),
        ] {
            assert!(close(x, y, 1e-3), "{:?} vs {:?}", ha.shading, hb.shading);
        }
        // Barycentrics differ by rounding; a triangle across the atan2 seam stretches uv a lot.
        assert!(ha.uv.distance(hb.uv) <= 2e-3, "{} vs {}", ha.uv, hb.uv);
        assert!((ha.uv_per_world - hb.uv_per_world).abs() <= 1e-3 * hb.uv_per_world);
        assert!(ha.color.distance(hb.color) <= 1e-4);
        let names = |s: &Scene, prim: u32| s.names().items[s.mesh_of_prim(prim)].object.clone();
        assert_eq!(names(&a, ha.prim), names(&b, hb.prim));
    }
    assert!(hits > 1000, "{hits}");
}

/// Instances of an emissive prototype are copied to world space when the scene is built (area lights are world
/// triangles): each copy is a light of its own, under its instance's name, and counts as the scene's own
/// lighting before the build.
#[test]
fn emissive_instances_become_area_lights_of_their_own() {
    let mut b = SceneBuilder::new();
    let mut glow = Material::lambertian("glow", Rgb::ZERO);
    glow.emission = Rgb::splat(2.0);
    let m = b.add_material(glow);
    let unit = common::quad(
        [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        m,
    );
    let proto = b.add_prototype(unit);
    for (i, x) in [-2.0f32, 2.0].into_iter().enumerate() {
        b.add_instance(MeshInstance {
            prototype: proto,
            object_to_world: Mat4::from_translation(Vec3::new(x, 0.0, 0.0))
                * Mat4::from_scale(Vec3::new(0.5, 2.0, 1.0)),
            name: format!("panel{i}"),
            ..Default::default()
        })
        .unwrap();
    }
    assert_eq!(b.own_lighting().emissive_meshes, 2);
    let scene = b.build().unwrap();
    assert_eq!(
        scene.instance_count(),
        0,
        "emitters are copied, not instanced"
    );
    let areas: Vec<_> = scene
        .lights()
        .iter()
        .filter_map(|l| match l {
            nimbus::light::Light::Area(a) => Some(a),
            _ => None,
        })
        .collect();
    assert_eq!(areas.len(), 4, "two triangles per panel");
    // Each panel's triangles lie where its instance placed them, with its scaled area (0.5 × 2 = 1).
    let area: f32 = areas.iter().map(|a| a.area).sum();
    assert!((area - 2.0).abs() < 1e-5, "{area}");
    let emitters: Vec<&str> = scene
        .names()
        .emitters
        .iter()
        .map(|e| e.name.as_str())
        .collect();
    assert_eq!(emitters, ["panel0", "panel1"]);
}
