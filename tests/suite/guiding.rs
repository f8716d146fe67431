//! Path guiding end to end (issue 34): guided renders keep the mean (a white furnace, closed form), are the same
//! on any number of threads and in any farm split, refuse to merge with unguided parts (parts hash by what
//! `--guiding` decided), and `--guiding auto` guides where a pilot of unguided paths finds that guided shadow
//! roulette would save most of the shadow rays, saying what its pilot measured.

use crate::common;

use glam::{DMat4, DVec3, IVec3};
use nimbus::farm;
use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::resume::ResumeFrom;
use nimbus::render::{
    CancelToken, GuidingMode, PixelWindow, RenderImage, RenderRegion, RenderSettings, RenderStats,
    Renderer,
};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::vdb::{GridTree, Tree};
use nimbus::volume::density::GridDensity;
use nimbus::volume::grid::GridMedium;
use nimbus::volume::homogeneous::HomogeneousMedium;
use nimbus::volume::majorant::MajorantKind;
use nimbus::{channel_names, Scene};
use std::path::Path;
use std::sync::Arc;

/// A smooth ball of radius 12 voxels of 1/16 m (density 1 in the middle, 0 at the rim) times `scale`.
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
        DMat4::from_scale(DVec3::splat(0.0625)),
        scale,
    )
    .unwrap()
}

/// The ball (density `scale`, albedo `albedo`, g 0.4) in a constant environment of radiance 1, seen whole.
fn ball_scene(scale: f32, albedo: f32, sun: bool) -> Scene {
    let mut b = SceneBuilder::default();
    let medium = GridMedium::new(
        "ball",
        ball(scale),
        MajorantKind::Adaptive,
        Rgb::splat(albedo),
        0.4,
    );
    b.add_medium(Arc::new(medium));
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    if sun {
        b.add_directional_light(Vec3::new(0.3, -0.2, -1.0), Rgb::splat(20.0));
    }
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        20f32.to_radians(),
    ));
    b.build().unwrap()
}

fn settings(size: usize, spp: u32, threads: usize, guiding: GuidingMode) -> RenderSettings {
    RenderSettings {
        width: size,
        height: size,
        spp,
        seed: 9,
        threads,
        max_depth: 100_000,
        guiding,
        ..Default::default()
    }
}

/// Asserts that two images hold the same bits in every channel.
fn assert_bit_identical(got: &RenderImage, want: &RenderImage, what: &str) {
    for name in channel_names() {
        let (g, w) = (got.channel(&name).unwrap(), want.channel(&name).unwrap());
        let same = g.iter().zip(w).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(same, "{what}: channel {name} differs");
    }
}

/// A white furnace: an albedo-1 medium in a uniform environment of radiance 1 looks exactly like the
/// environment, whatever its density; guided directions must not change that mean (within 4 standard errors),
/// in a thin and in a dense ball, with the training's 7 samples per pixel in the image (of 16) and as the
/// whole image (of 7).
#[test]
fn a_guided_white_furnace_shows_the_environment() {
    for (scale, spp) in [(4.0f32, 16), (60.0, 16), (4.0, 7), (60.0, 7)] {
        let scene = ball_scene(scale, 1.0, false);
        let (img, stats) = Renderer::new(settings(16, spp, 2, GuidingMode::On))
            .render(&scene, &mut |_| true)
            .unwrap();
        assert_eq!(stats.guiding.training_samples_in_image, 7);
        assert_eq!(stats.guiding.mode, "on");
        assert!(
            stats.guiding.guided_cells > 0 && stats.guiding.training_records > 1000,
            "scale {scale}: the cache learned something: {:?}",
            stats.guiding
        );
        assert_eq!(stats.nan_samples, 0);
        for c in 0..3 {
            let (mean, se) = common::mean_and_se(&img, c);
            assert!(se > 0.0 && se < 0.03, "scale {scale}: standard error {se}");
            assert!(
                (mean - 1.0).abs() < 4.0 * se,
                "scale {scale}: guided furnace {mean} vs 1 (se {se})"
            );
        }
    }
}

/// Adds a Lambertian floor of albedo 0.5 at y = 0, 2 km on a side, centred on the origin.
fn add_grey_floor(b: &mut SceneBuilder) {
    let grey = b.add_material(nimbus::Material::lambertian("floor", Rgb::splat(0.5)));
    let f = 1000.0;
    let floor = vec![
        Vec3::new(-f, 0.0, -f),
        Vec3::new(-f, 0.0, f),
        Vec3::new(f, 0.0, f),
        Vec3::new(f, 0.0, -f),
    ];
    b.add_triangle_mesh(floor, vec![[0, 1, 2], [0, 2, 3]], grey)
        .unwrap();
}

/// A Lambertian floor of albedo 0.5 under a uniform sky of radiance 1 (nothing else in the scene) reflects
/// exactly 0.5 everywhere; guided directions at the floor (the cache learns the sky from the floor's own paths)
/// must keep that mean within 4 standard errors.
#[test]
fn a_guided_lambert_floor_under_a_uniform_sky_reflects_its_albedo() {
    let mut b = SceneBuilder::default();
    add_grey_floor(&mut b);
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 1.0, 0.5),
        Vec3::ZERO,
        30f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let (img, stats) = Renderer::new(settings(16, 16, 2, GuidingMode::On))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert!(stats.guiding.guided_cells > 0, "{:?}", stats.guiding);
    for c in 0..3 {
        let (mean, se) = common::mean_and_se(&img, c);
        assert!(se > 0.0 && se < 0.02, "standard error {se}");
        assert!(
            (mean - 0.5).abs() < 4.0 * se,
            "guided floor {mean} vs 0.5 (se {se})"
        );
    }
}

/// A Lambertian floor of albedo 0.5 lit by a black square emitter of radiance 5 (0.5 m wide, 1 m above it,
/// nothing else) reflects (0.5/π)·E at the point the camera sees (a field of 0.01°: one point, E from Lambert's
/// formula). Guided directions at the floor find the square, so where the guide and the BSDF differ, next-event
/// estimation's MIS weight and the weight of the emission a sampled direction hits must be computed from the
/// same density, or they no longer sum to 1: with next-event estimation weighed against the BSDF and the
/// emission hit against the guided mixture (or the reverse) the mean moves by more than 4 standard errors.
#[test]
fn a_guided_floor_under_a_square_light_reflects_its_irradiance() {
    let mut b = SceneBuilder::default();
    add_grey_floor(&mut b);
    let mut lamp = nimbus::Material::lambertian("lamp", Rgb::ZERO);
    lamp.emission = Rgb::splat(5.0);
    let lamp = b.add_material(lamp);
    // Counter-clockwise seen from below: it shines down.
    let (h, height) = (0.25, 1.0);
    let corners = [
        Vec3::new(-h, height, -h),
        Vec3::new(h, height, -h),
        Vec3::new(h, height, h),
        Vec3::new(-h, height, h),
    ];
    b.add_mesh(common::quad(corners, lamp));
    let seen = Vec3::new(0.2, 0.0, 0.1);
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.5, 1.5),
        seen,
        0.01f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let corners = corners.map(|c| c.as_dvec3());
    let want = 0.5 / std::f64::consts::PI
        * nimbus::testing::polygon_irradiance(seen.as_dvec3(), DVec3::Y, &corners, 5.0);
    let (img, stats) = Renderer::new(settings(32, 64, 2, GuidingMode::On))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert!(stats.guiding.guided_cells > 0, "{:?}", stats.guiding);
    assert_eq!(stats.nan_samples, 0);
    for c in 0..3 {
        let (mean, se) = common::mean_and_se(&img, c);
        assert!(
            se > 0.0 && se < 0.01 * want,
            "standard error {se} of {want}"
        );
        assert!(
            (mean - want).abs() < 4.0 * se,
            "guided floor {mean} vs {want} (se {se})"
        );
    }
}

/// The guided image is the same on 1 and 3 threads, and sample-range parts written to files merge into it bit
/// for bit, with guided Russian roulette and splitting at work (split paths draw from generators derived from
/// their sample's); a part rendered unguided refuses to merge with a guided one, and so does a guided part with
/// classic roulette.
#[test]
fn guided_renders_are_deterministic_and_merge_bit_for_bit() {
    // Density 5, 12 samples: in the balls of density 1, 3, 10, 20 and 30 the window splits no path of these
    // samples (vMF caches with learned selection probabilities; density 10 and 6 samples did before them).
    let scene = ball_scene(5.0, 0.98, true);
    let (size, spp) = (20, 12);
    let render = |threads| {
        Renderer::new(RenderSettings {
            guided_roulette: true,
            ..settings(size, spp, threads, GuidingMode::On)
        })
        .render(&scene, &mut |_| true)
        .unwrap()
    };
    let (one, stats) = render(1);
    assert!(stats.guiding.guided_cells > 0, "{:?}", stats.guiding);
    assert!(stats.rays.split > 0, "paths were split: {:?}", stats.rays);
    let (three, _) = render(3);
    assert_bit_identical(&three, &one, "3 threads against 1");
    let (unguided, _) = Renderer::new(settings(size, spp, 1, GuidingMode::Off))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert!(
        unguided.beauty != one.beauty,
        "guiding changes the samples (else this test tests nothing)"
    );

    let dir = std::env::temp_dir().join(format!("nimbus-guiding-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let part = |samples: std::ops::Range<u32>, threads: usize, mode: GuidingMode, name: &str| {
        let settings = RenderSettings {
            guided_roulette: name != "classic.exr",
            ..settings(size, spp, threads, mode)
        };
        let path = dir.join(name);
        common::render_part(
            &scene,
            b"ball",
            settings,
            PixelWindow::full(size, size),
            samples,
            &path,
        );
        path
    };
    let a = part(0..4, 2, GuidingMode::On, "a.exr");
    let b = part(4..12, 3, GuidingMode::On, "b.exr");
    let merged = farm::merge_parts(&[a.clone(), b]).unwrap();
    assert_bit_identical(
        &merged.image,
        &one,
        "parts 0..4 and 4..12 against the whole",
    );
    let off = part(4..12, 1, GuidingMode::Off, "off.exr");
    let Err(refused) = farm::merge_parts(&[a.clone(), off]) else {
        panic!("guided and unguided parts merged");
    };
    assert!(refused.to_string().contains("scene hash"), "{refused}");
    let classic = part(4..12, 1, GuidingMode::On, "classic.exr");
    let Err(refused) = farm::merge_parts(&[a, classic]) else {
        panic!("parts with guided and classic roulette merged");
    };
    assert!(refused.to_string().contains("scene hash"), "{refused}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Parts hash by what `--guiding` decided for the scene before rendering, not by the mode's name: `off`, and
/// `auto` in a scene without a scattering medium, add nothing (so they hash as renders from before guiding
/// existed); `auto` in a scene with one, which a pilot of unguided paths decides, has a tag of its
/// own. So two auto parts of the ball merge, bit for bit the whole auto render, and an auto part refuses to merge
/// with an off part and with an on part.
#[test]
fn parts_hash_by_what_guiding_decided() {
    let scene = ball_scene(5.0, 0.98, true);
    let (size, spp) = (12, 9);
    assert!(GuidingMode::Auto.decide(&scene).provisional);
    let dir = std::env::temp_dir().join(format!("nimbus-guiding-hash-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let part = |samples: std::ops::Range<u32>, mode: GuidingMode, name: &str| {
        let path = dir.join(name);
        let settings = settings(size, spp, 1, mode);
        common::render_part(
            &scene,
            b"ball",
            settings,
            PixelWindow::full(size, size),
            samples,
            &path,
        );
        path
    };
    let auto = part(0..2, GuidingMode::Auto, "auto.exr");
    let rest = part(2..9, GuidingMode::Auto, "auto-rest.exr");
    let merged = farm::merge_parts(&[auto.clone(), rest]).unwrap();
    let (whole, _) = Renderer::new(settings(size, spp, 1, GuidingMode::Auto))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert_bit_identical(
        &merged.image,
        &whole,
        "auto 0..2 and auto 2..9 against the whole",
    );
    for (mode, name) in [(GuidingMode::Off, "off.exr"), (GuidingMode::On, "on.exr")] {
        let other = part(2..9, mode, name);
        let Err(refused) = farm::merge_parts(&[auto.clone(), other]) else {
            panic!("an auto part merged with a {mode:?} part");
        };
        assert!(refused.to_string().contains("scene hash"), "{refused}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The training's samples are the image's first: a guided render's sample 0 is the training's first iteration,
/// traced before there is a cache and drawn, traced and filtered as an unguided image sample, so a guided render
/// of 1 sample per pixel is the unguided one, bit for bit in every layer (light paths, light groups,
/// Cryptomatte, alpha); 16 samples per pixel trace 16 camera rays per pixel in all, 7 of them the training's.
#[test]
fn the_training_samples_are_the_images_first() {
    let scene = ball_scene(5.0, 0.8, true);
    let with_layers = |spp, guiding| RenderSettings {
        aovs: Some(nimbus::render::AovSelection::parse("all").unwrap()),
        light_groups: nimbus::render::LightGroupMode::PerLight,
        ..settings(12, spp, 2, guiding)
    };
    let (guided, stats) = Renderer::new(with_layers(1, GuidingMode::On))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert_eq!(stats.guiding.training_samples_in_image, 1);
    assert_eq!(stats.guiding.training_samples_per_pixel, 7);
    let (unguided, _) = Renderer::new(with_layers(1, GuidingMode::Off))
        .render(&scene, &mut |_| true)
        .unwrap();
    let names = unguided.channel_names();
    assert_eq!(guided.channel_names(), names);
    assert!(names.iter().any(|n| n.starts_with("lg_")), "{names:?}");
    for name in &names {
        let (g, u) = (
            guided.channel(name).unwrap(),
            unguided.channel(name).unwrap(),
        );
        let same = g.iter().zip(u).all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same,
            "channel {name}: sample 0 of the guided render is not the training's"
        );
    }
    let (_, stats) = Renderer::new(with_layers(16, GuidingMode::On))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert_eq!(stats.samples_per_pixel, 16);
    assert_eq!(stats.guiding.training_samples_in_image, 7);
    assert_eq!(stats.rays.camera, 16 * 12 * 12, "{:?}", stats.rays);
}

/// A guided render stopped after a pass, or cancelled before its training ends, resumes to the film of the
/// uninterrupted render bit for bit (the training's samples are in the film once, whole); a film stopped inside
/// the training's samples (a region ending before sample 7) is refused as a start.
#[test]
fn guided_renders_resume_bit_for_bit() {
    let scene = ball_scene(5.0, 0.98, true);
    let renderer = Renderer::new(settings(12, 24, 2, GuidingMode::On));
    let region = RenderRegion {
        window: PixelWindow::full(12, 12),
        samples: 0..24,
    };
    let resume = |from| {
        renderer
            .render_resumable(&scene, &region, from, &mut |_, _| true, &CancelToken::new())
            .unwrap()
    };
    let (whole, _, _) = resume(None);
    // Stopped by the progress callback after the first pass (samples 7..9), and cancelled before training.
    let (film, stats, progress) = renderer
        .render_resumable(
            &scene,
            &region,
            None,
            &mut |_, _| false,
            &CancelToken::new(),
        )
        .unwrap();
    assert!(stats.cancelled && progress.complete == 9, "{progress:?}");
    let cancel = CancelToken::new();
    cancel.cancel();
    let (empty, stats, at_start) = renderer
        .render_resumable(&scene, &region, None, &mut |_, _| true, &cancel)
        .unwrap();
    assert_eq!((stats.samples_per_pixel, at_start.complete), (0, 0));
    for (film, progress) in [(film, progress), (empty, at_start)] {
        let from = ResumeFrom {
            film,
            progress,
            nan_samples: 0,
            clamped_samples: 0,
        };
        let (resumed, stats, _) = resume(Some(from));
        assert!(
            resumed == whole,
            "resumed from {} samples",
            stats.resumed_samples
        );
    }
    let short = RenderRegion {
        samples: 0..3,
        ..region.clone()
    };
    let (film, _, progress) = renderer
        .render_resumable(&scene, &short, None, &mut |_, _| true, &CancelToken::new())
        .unwrap();
    let from = ResumeFrom {
        film,
        progress,
        nan_samples: 0,
        clamped_samples: 0,
    };
    let refused = renderer.render_resumable(
        &scene,
        &region,
        Some(from),
        &mut |_, _| true,
        &CancelToken::new(),
    );
    let Err(refused) = refused else {
        panic!("a film inside the training was resumed");
    };
    assert!(
        refused.to_string().contains("guiding training"),
        "{refused}"
    );
}

/// `--guiding auto` decides before rendering only where there is no scattering medium (off: the surfaces-only
/// Cornell boxes, the Lambertian one and the glossy baffle box of the guiding benchmark); in a scene with one (the
/// bundled demo, the backlit-cloud benchmark) a pilot of unguided paths decides, and the reason says what
/// the pilot measured of the likeliest medium (the demo's albedo 0.95, the backlit cloud's 0.99).
#[test]
fn auto_decides_by_a_pilot_where_there_is_a_scattering_medium() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let decide = |file: &str| {
        let scene = Scene::load(&root.join(file)).unwrap();
        GuidingMode::Auto.decide(&scene)
    };
    let demo = decide("assets/cloud.gltf");
    assert!(
        demo.on && demo.provisional && demo.reason.contains("albedo 0.950"),
        "{demo:?}"
    );
    for surfaces_only in [
        "benches/peers/scenes/cornell.gltf",
        "benches/peers/scenes/baffle.gltf",
    ] {
        let d = decide(surfaces_only);
        assert!(
            !d.on && !d.provisional && d.reason.contains("no scattering medium"),
            "{d:?}"
        );
    }
    let backlit = decide("benches/peers/scenes/backlit.gltf");
    assert!(
        backlit.provisional && backlit.reason.contains("albedo 0.990"),
        "{backlit:?}"
    );
    let scene = Scene::load(&root.join("assets/cloud.gltf")).unwrap();
    let (off, on) = (
        GuidingMode::Off.decide(&scene),
        GuidingMode::On.decide(&scene),
    );
    assert!(!off.on && on.on && !off.provisional && !on.provisional);
}

/// `--guiding auto` guides where guided shadow roulette would save most of the shadow rays, as its pilot
/// (unguided paths of sample 0 at every pixel of this 16² frame: at least 16,384 pixels where a frame has
/// them, every pixel of a smaller one) finds: in the slab of grid medium lit from behind, most scattering events
/// the camera's paths reach are on its dark side, so the render is guided, the same bits as `--guiding on`'s; lit
/// from the front, their shadow rays find the light and auto does not guide, the same bits as `--guiding off`'s
/// in every layer. Either way the pilot's paths are the image's first sample, so auto traces the same rays as
/// the render it equals.
#[test]
fn auto_guides_where_shadow_roulette_saves_most_shadow_rays() {
    for (light, guided) in [(Vec3::Z, true), (-Vec3::Z, false)] {
        let scene = slab_scene(8.0, 0.8, 100.0, light);
        let render = |mode| {
            Renderer::new(settings(16, 16, 2, mode))
                .render(&scene, &mut |_| true)
                .unwrap()
        };
        let (auto, stats) = render(GuidingMode::Auto);
        let (same, same_stats) = render(if guided {
            GuidingMode::On
        } else {
            GuidingMode::Off
        });
        assert_eq!(
            stats.guiding.mode,
            if guided { "on" } else { "off" },
            "{:?}",
            stats.guiding
        );
        assert!(stats
            .guiding
            .reason
            .contains("on a pilot of unguided paths"));
        assert_bit_identical(&auto, &same, &format!("auto, light along {light}"));
        assert_eq!(stats.samples_per_pixel, 16);
        // The pilot traced sample 0 of every pixel of the small frame, which is the image's first sample and
        // the training's first iteration: traced once, so auto traced the rays of the render it equals.
        assert_eq!(stats.guiding.pilot_samples_in_image, 1);
        assert_eq!(
            stats.rays, same_stats.rays,
            "auto against {}",
            stats.guiding.mode
        );
        assert_eq!(stats.rays.camera, 16 * 16 * 16);
        let training_samples = if guided { 7 } else { 1 };
        assert_eq!(stats.guiding.training_paths, 16 * 16 * training_samples);
    }
    // With fewer samples per pixel than the training pays back in, auto does not guide the backlit slab.
    let scene = slab_scene(8.0, 0.8, 100.0, Vec3::Z);
    let (_, stats) = Renderer::new(settings(16, 15, 2, GuidingMode::Auto))
        .render(&scene, &mut |_| true)
        .unwrap();
    assert_eq!(stats.guiding.mode, "off", "{:?}", stats.guiding);
    assert!(stats.guiding.reason.contains("fewer than 16"));
}

/// In a 256² frame, whose pilot lattice is every 2nd pixel along each axis, a whole render whose samples start at
/// 0 takes the training's first iteration (sample 0 of every pixel) as `auto`'s pilot: that sample goes into the
/// film and no path is traced twice (the rays of the `off` render it equals). A crop, or a part whose samples
/// start later, traces the lattice alone and decides alike: the parts merge into the whole render bit for bit.
#[test]
fn autos_pilot_is_the_first_sample_of_a_whole_large_frame() {
    let scene = slab_scene(8.0, 0.8, 100.0, -Vec3::Z);
    let (size, spp) = (256, 2);
    let render = |mode| {
        Renderer::new(settings(size, spp, 2, mode))
            .render(&scene, &mut |_| true)
            .unwrap()
    };
    let (auto, stats) = render(GuidingMode::Auto);
    let (off, off_stats) = render(GuidingMode::Off);
    assert_eq!(stats.guiding.mode, "off", "{:?}", stats.guiding);
    assert_bit_identical(&auto, &off, "auto against off");
    assert_eq!(stats.rays, off_stats.rays);
    assert_eq!(stats.guiding.pilot_samples_in_image, 1);
    assert_eq!(stats.guiding.training_paths, (size * size) as u64);
    assert_eq!(stats.guiding.training_records, 0, "no cache was kept");

    let top = PixelWindow {
        x0: 0,
        y0: 0,
        x1: size,
        y1: size / 2,
    };
    let region = RenderRegion {
        window: top,
        samples: 0..spp,
    };
    let (_, crop) = Renderer::new(settings(size, spp, 2, GuidingMode::Auto))
        .render_region(&scene, &region, &mut |_| true, &CancelToken::new())
        .unwrap();
    assert_eq!(crop.guiding.reason, stats.guiding.reason);
    assert_eq!(crop.guiding.pilot_samples_in_image, 0);
    assert_eq!(crop.guiding.training_paths, (size * size / 4) as u64);

    let dir = std::env::temp_dir().join(format!("nimbus-guiding-pilot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let part = |window: PixelWindow, samples: std::ops::Range<u32>, name: &str| {
        let path = dir.join(name);
        let settings = settings(size, spp, 2, GuidingMode::Auto);
        common::render_part(&scene, b"slab", settings, window, samples, &path);
        path
    };
    let whole = PixelWindow::full(size, size);
    let bottom = PixelWindow {
        y0: size / 2,
        y1: size,
        ..top
    };
    for (parts, what) in [
        ([(whole, 0..1), (whole, 1..spp)], "samples 0..1 and 1..2"),
        (
            [(top, 0..spp), (bottom, 0..spp)],
            "the top and bottom halves",
        ),
    ] {
        let files: Vec<_> = parts
            .into_iter()
            .enumerate()
            .map(|(i, (window, samples))| part(window, samples, &format!("{i}.exr")))
            .collect();
        let merged = farm::merge_parts(&files).unwrap();
        assert_bit_identical(&merged.image, &auto, what);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An `auto` render that decides not to guide resumes as an unguided one: a film stopped after 3 samples (inside
/// the training's 7, which a guided render refuses) goes on to the uninterrupted render's bits.
#[test]
fn an_unguided_auto_render_resumes_inside_the_training() {
    let scene = slab_scene(8.0, 0.8, 100.0, -Vec3::Z);
    let renderer = Renderer::new(settings(12, 10, 2, GuidingMode::Auto));
    let region = RenderRegion {
        window: PixelWindow::full(12, 12),
        samples: 0..10,
    };
    let resume = |region: &RenderRegion, from| {
        renderer
            .render_resumable(&scene, region, from, &mut |_, _| true, &CancelToken::new())
            .unwrap()
    };
    let (whole, stats, _) = resume(&region, None);
    assert_eq!(stats.guiding.mode, "off");
    let short = RenderRegion {
        samples: 0..3,
        ..region.clone()
    };
    let (film, _, progress) = resume(&short, None);
    assert_eq!(progress.complete, 3);
    let from = ResumeFrom {
        film,
        progress,
        nan_samples: 0,
        clamped_samples: 0,
    };
    let (resumed, _, _) = resume(&region, Some(from));
    assert!(resumed == whole, "resumed from 3 samples");
}

/// A render cancelled before it starts does not train either: guiding's pre-pass stops between blocks of rows at
/// the cancel token (it trained all 7 samples per pixel before, so Ctrl-C waited for the whole pre-pass).
#[test]
fn a_cancelled_render_stops_training() {
    let scene = ball_scene(4.0, 1.0, false);
    let cancel = CancelToken::new();
    cancel.cancel();
    let (_, stats) = Renderer::new(settings(24, 4, 2, GuidingMode::On))
        .render_with_cancel(&scene, &mut |_| true, &cancel)
        .unwrap();
    assert_eq!(stats.guiding.mode, "on");
    assert_eq!(stats.guiding.training_paths, 0, "{:?}", stats.guiding);
    assert_eq!(stats.guiding.cells, 0, "no cache is kept");
}

/// A slab of grid medium of optical depth `tau` along z and albedo `albedo` (g = 0), its density varying along z
/// only, lit by a sun of irradiance `irradiance` travelling along `light`, seen along −z through a field of
/// 0.01° from z = 3.
fn slab_scene(tau: f64, albedo: f32, irradiance: f32, light: Vec3) -> Scene {
    let spacing = 0.0625f64;
    let profile = |z: i32| 0.5 + 0.4 * (z as f64).sin();
    let depth: f64 = (-6..=6).map(profile).sum::<f64>() * spacing;
    let mut voxels = Vec::new();
    for x in -20..=20 {
        for y in -20..=20 {
            for z in -6..=6 {
                voxels.push((IVec3::new(x, y, z), profile(z) as f32));
            }
        }
    }
    let density = GridDensity::from_tree(
        Arc::new(GridTree::Float(Tree::from_voxels(0.0, voxels))),
        DMat4::from_scale(DVec3::splat(spacing)),
        (tau / depth) as f32,
    )
    .unwrap();
    let mut b = SceneBuilder::default();
    let medium = GridMedium::new(
        "slab",
        density,
        MajorantKind::Adaptive,
        Rgb::splat(albedo),
        0.0,
    );
    b.add_medium(Arc::new(medium));
    b.add_directional_light(light, Rgb::splat(irradiance));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        0.01f32.to_radians(),
    ));
    b.build().unwrap()
}

/// Renders `scene` (32², `spp`, `max_depth` 1) unguided and then guided, checks every channel's mean against
/// `truth` within 4 standard errors (the standard error below 5% of it), and returns the two renders' statistics.
fn single_scattering_unguided_and_guided(
    scene: &Scene,
    truth: f64,
    spp: u32,
    label: &str,
) -> [RenderStats; 2] {
    [GuidingMode::Off, GuidingMode::On].map(|guiding| {
        let settings = RenderSettings {
            max_depth: 1,
            ..settings(32, spp, 2, guiding)
        };
        let (img, stats) = Renderer::new(settings)
            .render(scene, &mut |_| true)
            .unwrap();
        for c in 0..3 {
            let (mean, se) = common::mean_and_se(&img, c);
            eprintln!(
                "{label}, guiding {guiding:?}, channel {c}: {mean:.6} ± {se:.6} vs {truth:.6}"
            );
            assert!(
                se > 0.0 && se < 0.05 * truth,
                "{label}, {guiding:?}: standard error {se}"
            );
            assert!(
                (mean - truth).abs() < 4.0 * se,
                "{label}, {guiding:?}: single scattering {mean} vs {truth} (se {se})"
            );
        }
        stats
    })
}

/// Guided shadow roulette (`nimbus::guiding::shadow`) keeps single scattering's mean. A slab of grid medium,
/// its density varying along z only (so that ratio tracking walks it with tentative collisions and plays its
/// own roulette), lit by the sun from behind along the camera's axis: a point's transmittance toward the camera
/// and toward the sun multiply to e^{−τ} for the slab's whole optical depth τ, wherever the point is, so single
/// scattering (`max_depth` 1, g = 0) is L = E α τ e^{−τ} / (4π) in closed form. Most collisions are on the
/// camera's side, where the training's shadow rays found a transmittance of e^{−5} or less, so most shadow rays
/// of the guided render are cut; the survivors' weight 1/q must keep the mean (within 4 standard errors).
#[test]
fn guided_shadow_roulette_keeps_single_scattering_through_a_backlit_slab() {
    let (tau, albedo, irradiance) = (8.0f64, 0.8f32, 100.0f32);
    // Travelling along +z, toward the camera.
    let scene = slab_scene(tau, albedo, irradiance, Vec3::Z);
    let truth = (irradiance * albedo) as f64 * tau * (-tau).exp() / (4.0 * std::f64::consts::PI);
    let stats = single_scattering_unguided_and_guided(&scene, truth, 192, "backlit slab");
    let shadow_rays = stats.map(|s| s.rays.shadow);
    // The guided render cut most of its shadow rays.
    assert!(
        shadow_rays[1] * 2 < shadow_rays[0],
        "shadow rays unguided, guided: {shadow_rays:?}"
    );
}

/// Guided shadow roulette at the decoupled direct-light samples of a constant medium keeps single scattering's
/// mean. The homogeneous twin of the slab above: a box 0.5 m thick along z (2 m across, so the shadow grid's
/// voxels are 1/16 m) of optical depth τ = 8, lit by the sun from behind along the camera's axis, so single
/// scattering (`max_depth` 1, g = 0) is again L = E α τ e^{−τ} / (4π). The camera segment's decoupled sample
/// (not a collision's next-event estimate) takes the sun; most of its distances lie on the camera's side, where
/// the training's decoupled shadow rays found e^{−4} or less, so the guided render plays roulette on most of
/// them, and the survivors' weight 1/q must keep the mean (within 4 standard errors).
#[test]
fn guided_shadow_roulette_keeps_decoupled_single_scattering_through_a_backlit_homogeneous_slab() {
    let (tau, albedo, irradiance) = (8.0f32, 0.8f32, 100.0f32);
    let thickness = 0.5f32;
    let sigma_t = tau / thickness;
    let mut b = SceneBuilder::default();
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "slab",
        Rgb::splat(sigma_t * (1.0 - albedo)),
        Rgb::splat(sigma_t * albedo),
        0.0,
    )));
    common::fill_box(
        &mut b,
        medium,
        Vec3::new(-1.0, -1.0, -0.5 * thickness),
        Vec3::new(1.0, 1.0, 0.5 * thickness),
    );
    // Travelling along +z, toward the camera.
    b.add_directional_light(Vec3::Z, Rgb::splat(irradiance));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        0.01f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let tau = tau as f64;
    let truth = (irradiance * albedo) as f64 * tau * (-tau).exp() / (4.0 * std::f64::consts::PI);
    let stats =
        single_scattering_unguided_and_guided(&scene, truth, 128, "backlit homogeneous slab");
    assert!(
        stats.iter().all(|s| s.rays.decoupled > 0),
        "no decoupled samples"
    );
    let shadow_rays = stats.map(|s| s.rays.shadow);
    // The guided render played roulette on most of its shadow rays (at least a quarter of them survive).
    assert!(
        shadow_rays[1] * 3 < shadow_rays[0] * 2,
        "shadow rays unguided, guided: {shadow_rays:?}"
    );
}

/// Guided shadow roulette at surfaces keeps direct light's mean. A Lambertian floor (albedo 0.5) under a slab
/// of absorbing medium (τ = 6 along the vertical), lit by the sun from straight above, seen from below the slab:
/// its radiance is ρ E e^{−τ} / π in closed form, and next-event estimation finds it exactly in every unguided
/// sample. The training's floor shadow rays found e^{−6} ≈ 0.0025, below the cut, so the guided render traces
/// them with probability 0.25 (`VISIBILITY_MIN_SURVIVAL`) and weighs the survivors by 4: within 4 standard
/// errors of the closed form, with fewer than half the shadow rays.
#[test]
fn guided_shadow_roulette_keeps_a_floors_direct_light_under_an_absorbing_slab() {
    let (tau, albedo, irradiance) = (6.0f32, 0.5f32, 100.0f32);
    let mut b = SceneBuilder::default();
    let floor = b.add_material(nimbus::material::Material::lambertian(
        "floor",
        Vec3::splat(albedo),
    ));
    b.add_mesh(common::quad(
        [
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, -2.0),
        ],
        floor,
    ));
    let thickness = 0.5f32;
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "absorber",
        Rgb::splat(tau / thickness),
        Rgb::ZERO,
        0.0,
    )));
    common::fill_box(
        &mut b,
        medium,
        Vec3::new(-3.0, 1.0, -3.0),
        Vec3::new(3.0, 1.0 + thickness, 3.0),
    );
    // Travelling down.
    b.add_directional_light(Vec3::NEG_Y, Rgb::splat(irradiance));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.5, 0.3),
        Vec3::ZERO,
        1.0f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let truth = (albedo * irradiance) as f64 * (-(tau as f64)).exp() / std::f64::consts::PI;
    let mut shadow_rays = Vec::new();
    for guiding in [GuidingMode::Off, GuidingMode::On] {
        let settings = RenderSettings {
            max_depth: 1,
            ..settings(16, 64, 2, guiding)
        };
        let (img, stats) = Renderer::new(settings)
            .render(&scene, &mut |_| true)
            .unwrap();
        for c in 0..3 {
            let (mean, se) = common::mean_and_se(&img, c);
            eprintln!("floor under a slab, guiding {guiding:?}, channel {c}: {mean:.6} ± {se:.6} vs {truth:.6}");
            if guiding == GuidingMode::Off {
                // Every sample finds the closed form.
                assert!(
                    (mean - truth).abs() < 1e-4 * truth,
                    "unguided: {mean} vs {truth}"
                );
            } else {
                assert!(se > 0.0 && se < 0.05 * truth, "guided: standard error {se}");
                assert!(
                    (mean - truth).abs() < 4.0 * se,
                    "guided: direct light {mean} vs {truth} (se {se})"
                );
            }
        }
        shadow_rays.push(stats.rays.shadow);
    }
    assert!(
        shadow_rays[1] * 2 < shadow_rays[0],
        "shadow rays unguided, guided: {shadow_rays:?}"
    );
}
