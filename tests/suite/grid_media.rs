//! VDB grid media rendered end to end: delta tracking on a constant grid against the closed form, a white
//! furnace with a heterogeneous grid, every majorant structure converging to the same image, an
//! under-estimated majorant reported, and the glTF `nimbus_volume` path.

use crate::common;

use glam::{DMat4, DVec3, IVec3};
use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Rng, Vec3};
use nimbus::render::{RenderImage, RenderStats};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::vdb::{GridTree, Tree};
use nimbus::volume::density::{DensityField, GridDensity};
use nimbus::volume::grid::GridMedium;
use nimbus::volume::homogeneous::HomogeneousMedium;
use nimbus::volume::majorant::{MajorantKind, Majorants};
use nimbus::volume::majorant_choice::pilot_rays;
use nimbus::volume::tracking::{sample_collision, TrackingCounters};
use std::sync::Arc;

const VOXEL: f64 = 0.0625;

/// A 16³ block of density 1 with voxel centres at world [−0.5, 0.4375]³ (voxel size 1/16 m).
fn block(scale: f32) -> GridDensity {
    let voxels = (0..16).flat_map(|x| {
        (0..16).flat_map(move |y| (0..16).map(move |z| (IVec3::new(x, y, z), 1.0f32)))
    });
    let tree = Tree::from_voxels(0.0, voxels);
    let m = DMat4::from_translation(DVec3::splat(-0.5)) * DMat4::from_scale(DVec3::splat(VOXEL));
    GridDensity::from_tree(Arc::new(GridTree::Float(tree)), m, scale).unwrap()
}

/// A smooth ball of radius 12 voxels (density 1 in the middle, 0 at the rim), voxel size 1/16 m.
fn ball(scale: f32) -> GridDensity {
    let mut voxels = Vec::new();
    for x in -12..=12 {
        for y in -12..=12 {
            for z in -12..=12 {
                let r = ((x * x + y * y + z * z) as f32).sqrt() / 12.0;
                if r < 1.0 {
                    voxels.push((IVec3::new(x, y, z), (1.0 - r * r).powi(2)));
                }
            }
        }
    }
    let tree = Tree::from_voxels(0.0, voxels);
    GridDensity::from_tree(
        Arc::new(GridTree::Float(tree)),
        DMat4::from_scale(DVec3::splat(VOXEL)),
        scale,
    )
    .unwrap()
}

fn render(b: SceneBuilder, size: usize, spp: u32, max_depth: u32) -> (RenderImage, RenderStats) {
    common::render_square(b, size, spp, max_depth, 5)
}

fn scene_with(medium: Arc<dyn nimbus::volume::Medium>, fov: f32, distance: f32) -> SceneBuilder {
    let mut b = SceneBuilder::default();
    b.add_medium(medium);
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, distance),
        Vec3::ZERO,
        fov.to_radians(),
    ));
    b
}

#[test]
fn delta_tracking_on_a_constant_grid_matches_the_closed_form() {
    // Seen along z through the block's middle, the trilinear density is 1 over the 15 voxel spacings between
    // the first and last centres and ramps to 0 over one spacing at each end: optical depth σ · 16 · voxel.
    // With max_depth 0 a collision ends the path, so the pixel value is the transmittance.
    let scale = 1.5f32;
    let truth = (-(scale as f64) * 16.0 * VOXEL).exp();
    let medium = GridMedium::new(
        "block",
        block(scale),
        MajorantKind::Adaptive,
        Rgb::splat(0.8),
        0.0,
    );
    let (img, stats) = render(scene_with(Arc::new(medium), 0.3, 60.0), 8, 256, 0);
    let (mean, se) = common::mean_and_se(&img, 1);
    assert!(
        (mean - truth).abs() < 4.0 * se,
        "delta tracking {mean} vs closed form {truth} (se {se})"
    );
    assert!(
        stats.media[0].counters.real_collisions > 0
            && stats.media[0].counters.majorant_violations == 0
    );

    // The equivalent homogeneous slab (closed-form tracking) gives the same value.
    let mut b = SceneBuilder::default();
    let h = b.add_medium(Arc::new(HomogeneousMedium::new(
        "slab",
        Rgb::ZERO,
        Rgb::splat(scale),
        0.0,
    )));
    common::fill_box(&mut b, h, Vec3::splat(-0.5), Vec3::splat(0.5));
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 60.0),
        Vec3::ZERO,
        0.3f32.to_radians(),
    ));
    let (closed, _) = render(b, 8, 256, 0);
    let (m2, se2) = common::mean_and_se(&closed, 1);
    assert!(
        (m2 - truth).abs() < 4.0 * se2 + 1e-4,
        "closed form {m2} vs {truth}"
    );
}

#[test]
fn white_furnace_with_a_heterogeneous_grid() {
    for scale in [2.0f32, 60.0] {
        let medium = GridMedium::new("ball", ball(scale), MajorantKind::Adaptive, Rgb::ONE, 0.4);
        let (img, stats) = render(scene_with(Arc::new(medium), 20.0, 3.0), 12, 16, 100_000);
        for c in 0..3 {
            let (mean, se) = common::mean_and_se(&img, c);
            assert!(
                (mean - 1.0).abs() < 4.0 * se + 1e-5,
                "scale {scale}: {mean} vs 1 (se {se})"
            );
        }
        assert_eq!(stats.nan_samples, 0);
        assert!(stats.media[0].counters.real_collisions > 0);
    }
}

#[test]
fn every_majorant_structure_gives_the_same_image() {
    // Each structure on its own segments, then with thick segments refined to voxel cells (the default): up to
    // 5 of optical depth per voxel, above REFINE_TAU.
    let mut means = Vec::new();
    for refine in [false, true] {
        for kind in [
            MajorantKind::Global,
            MajorantKind::Grid16,
            MajorantKind::Adaptive,
        ] {
            let density = ball(80.0);
            let majorants = Majorants::build(kind, &density).with_voxel_refinement(refine);
            let medium = GridMedium::new("ball", density, kind, Rgb::splat(0.9), 0.0)
                .with_majorants(majorants);
            let mut b = scene_with(Arc::new(medium), 20.0, 3.0);
            b.set_environment(EnvironmentLight::Constant(Rgb::new(1.0, 0.5, 0.25)));
            let (img, stats) = render(b, 12, 16, 64);
            let c = stats.media[0].counters;
            assert_eq!(c.majorant_violations, 0, "{kind:?}");
            assert_eq!(c.voxel_cells > 0, refine, "{kind:?}: {c:?}");
            means.push(((kind, refine), common::mean_and_se(&img, 0), c));
        }
    }
    let (_, (m0, s0), c0) = means[0];
    for (kind, (m, s), c) in &means[1..] {
        assert!(
            (m - m0).abs() < 4.0 * (s * s + s0 * s0).sqrt(),
            "{kind:?}: {m} vs global {m0}"
        );
        // Tighter majorants waste fewer lookups on null collisions.
        assert!(
            c.null_collisions < c0.null_collisions,
            "{kind:?}: {} vs {}",
            c.null_collisions,
            c0.null_collisions
        );
    }
}

#[test]
fn an_underestimated_majorant_is_counted() {
    let density = ball(10.0);
    let bounds = density.local_bounds();
    let low = Majorants::global(bounds, 0.0, 10.0 * 0.5);
    let medium = GridMedium::new("ball", density, MajorantKind::Global, Rgb::splat(0.9), 0.0)
        .with_majorants(low);
    let (_, stats) = render(scene_with(Arc::new(medium), 20.0, 3.0), 8, 4, 8);
    assert!(
        stats.media[0].counters.majorant_violations > 0,
        "violations must be reported"
    );
}

#[test]
fn refined_tracking_through_the_bundled_cloud_finds_every_majorant_sound() {
    // The bundled cloud at 100× its scene density: segments past REFINE_TAU are walked voxel cell by voxel
    // cell, and a cell reported outside the segment by round-off read bounds the majorant never promised
    // (one false violation in these 4000 flights on the adaptive structure before the fix). Every structure
    // must bound every cell.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cloud.vdb");
    let file = nimbus::vdb::read_file(&path).expect("the bundled cloud");
    let grid = file.grid("density").expect("a density grid");
    let field = GridDensity::new(grid, DMat4::IDENTITY, 3000.0).expect("a scalar grid");
    let (rays, t_max) = pilot_rays(&field, 4000, 7);
    for kind in MajorantKind::ALL {
        let majorants = Majorants::build(kind, &field);
        assert!(majorants.voxel_refinement());
        let mut c = TrackingCounters::default();
        for (i, ray) in rays.iter().enumerate() {
            let mut rng = Rng::new(i as u64, 3);
            sample_collision(&field, &majorants, ray, 0.0, t_max, &mut rng, &mut c);
        }
        assert!(
            c.voxel_cells > 10_000,
            "{kind:?}: refinement must be exercised: {c:?}"
        );
        assert_eq!(c.majorant_violations, 0, "{kind:?}: {c:?}");
    }
}

#[test]
fn gltf_nimbus_volume_loads_the_grid() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes");
    let scene = nimbus::scene::Scene::load(&dir.join("constant_grid.gltf")).expect("loads");
    assert_eq!(scene.media().len(), 1);
    assert!(
        scene.media()[0].fill_bounds().is_some(),
        "a VDB volume fills its region by position"
    );
    assert!(matches!(
        scene.media()[0].method().free_flight,
        nimbus::volume::FreeFlight::DeltaTracking { .. }
    ));
    let bad = std::env::temp_dir().join(format!("nimbus-badvol-{}.gltf", std::process::id()));
    std::fs::write(
        &bad,
        r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
           "nodes":[{"name":"smoke","extras":{"nimbus_volume":{"file":"missing.vdb"}}}]}"#,
    )
    .unwrap();
    let err = nimbus::scene::Scene::load(&bad)
        .err()
        .expect("a missing VDB is an error")
        .to_string();
    assert!(
        err.contains("smoke") && err.contains("missing.vdb"),
        "{err}"
    );
    std::fs::write(
        &bad,
        r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
           "nodes":[{"name":"smoke","extras":{"nimbus_volume":{"file":"x.vdb","albedo":[2,0,0]}}}]}"#,
    )
    .unwrap();
    let err = nimbus::scene::Scene::load(&bad)
        .err()
        .expect("albedo > 1 is an error")
        .to_string();
    assert!(err.contains("smoke") && err.contains("albedo"), "{err}");
}

/// What a host sees of a VDB volume that does not load: walking `source()` down from the public
/// `nimbus::Error` reaches the `VolumeError`, which tells a grid missing from a readable file from a corrupt
/// (truncated) or absent file, and the `VdbError` below it for the latter.
#[test]
fn volume_errors_tell_a_missing_grid_from_a_corrupt_file() {
    use nimbus::volume::VolumeError;
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes");
    let dir = std::env::temp_dir().join(format!("nimbus-volerr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(scenes.join("constant_grid.vdb"), dir.join("good.vdb")).unwrap();
    let mut corrupt = std::fs::read(scenes.join("constant_grid.vdb")).unwrap();
    corrupt.truncate(corrupt.len() / 2);
    std::fs::write(dir.join("corrupt.vdb"), corrupt).unwrap();
    let load = |file: &str, grid: &str| {
        let gltf = dir.join(format!("{grid}_{file}.gltf"));
        std::fs::write(
            &gltf,
            format!(
                r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
                   "nodes":[{{"name":"smoke","extras":{{"nimbus_volume":{{"file":"{file}","density_grid":"{grid}"}}}}}}]}}"#
            ),
        )
        .unwrap();
        let err = nimbus::Error::from(nimbus::scene::Scene::load(&gltf).err().expect("fails"));
        // Walk the chain: nimbus::Error -> SceneError -> SceneErrorKind::Volume -> VolumeError -> ...
        let mut chain = Vec::new();
        let mut next: Option<&(dyn std::error::Error + 'static)> = Some(&err);
        while let Some(e) = next {
            chain.push(e);
            next = e.source();
        }
        let volume = chain
            .iter()
            .find_map(|e| e.downcast_ref::<VolumeError>())
            .unwrap_or_else(|| panic!("no VolumeError in the chain of {err}"));
        let kind = match volume {
            VolumeError::GridMissing {
                grid, available, ..
            } => {
                assert_eq!(
                    (grid.as_str(), available.as_slice()),
                    ("smoke", &["density".to_owned()][..])
                );
                "grid missing"
            }
            VolumeError::Vdb(_) => {
                assert!(chain
                    .iter()
                    .any(|e| e.downcast_ref::<nimbus::VdbError>().is_some()));
                "file unreadable"
            }
            other => panic!("unexpected {other}"),
        };
        let message = err.to_string();
        assert!(
            message.contains(&format!("{grid}_{file}.gltf")),
            "{message}"
        );
        assert!(
            message.contains("node 'smoke'") && message.contains(file),
            "{message}"
        );
        assert!(!message.contains('\n'), "one line: {message}");
        kind
    };
    assert_eq!(load("good.vdb", "smoke"), "grid missing");
    assert_eq!(load("corrupt.vdb", "density"), "file unreadable");
    assert_eq!(load("absent.vdb", "density"), "file unreadable");
    std::fs::remove_dir_all(&dir).ok();
}

/// The `--stats` JSON of a medium keeps the keys docs/reference.md lists (`method` still the sentence) and adds the
/// structured method keys.
#[test]
fn stats_json_has_the_method_sentence_and_its_fields() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes");
    let scene = nimbus::scene::Scene::load(&dir.join("constant_grid.gltf")).expect("loads");
    let settings = nimbus::render::RenderSettings {
        width: 4,
        height: 4,
        spp: 1,
        threads: 1,
        ..Default::default()
    };
    let (_, stats) = nimbus::render::Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap();
    let json = serde_json::to_value(&stats).unwrap();
    let medium = &json["media"][0];
    for key in [
        "name",
        "method",
        "memory_bytes",
        "density_lookups",
        "real_collisions",
        "null_collisions",
        "majorant_segments",
        "majorant_cells",
        "majorant_violations",
        "free_flight",
        "channel_choice",
        "closed_form_segments",
        "decomposition_tracking",
        "voxel_refinement",
        "voxel_cells",
        "majorant",
        "shadow_estimator",
        "method_reason",
        "majorant_pilot",
        "chromatic_tracking",
        "spectral_flights",
    ] {
        assert!(medium.get(key).is_some(), "no '{key}' in {medium}");
    }
    assert_eq!(medium["method"], scene.media()[0].method().to_string());
    assert_eq!(medium["free_flight"], "delta_tracking");
    assert_eq!(medium["shadow_estimator"], "ratio");
    // The scene does not name a structure, so auto's pilot chose it, and says what each would cost.
    assert_eq!(medium["method_reason"], "pilot");
    let pilot = medium["majorant_pilot"].as_array().unwrap();
    assert_eq!(pilot.len(), 3);
    assert!(pilot.iter().any(|p| p["majorant"] == medium["majorant"]));
}
