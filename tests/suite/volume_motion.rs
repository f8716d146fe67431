//! Velocity motion blur and pyro channels of grid media against closed forms.
//!
//! The fixture `tests/scenes/pyro_box.vdb` (made by `assets/make_shot.py`) holds a box of density 1 on voxels
//! [0, 15]³ of 0.0625 m, so a trilinear lookup reads the trapezoid f(i) = clamp(min(i + 1, 16 − i), 0, 1) along
//! each index axis, and a ray along z through the interior of x and y sees an optical depth of exactly
//! density_scale × 1 m (15 voxels at 1 plus two ramps of half a voxel each). Its velocity is 2 m/s along +x
//! everywhere (`vel`, and `v.x/v.y/v.z`), its flame 1 wherever density can be read, its `albedo` grid 0 and its
//! `Cd` grid ((i + 2) / 19, 0.5, 0.25) at index (i, j, k): a red ramp along x.

use nimbus::frames::Shutter;
use nimbus::math::{Ray, Rng, Vec3};
use nimbus::scene::{LoadOptions, Scene};
use nimbus::volume::TrackingCounters;
use std::path::PathBuf;

use crate::common;

const VOXEL: f64 = 0.0625;
const SPEED: f64 = 2.0;
const FPS: f64 = 24.0;
const SIGMA: f64 = 2.0;

/// The trapezoid a trilinear lookup of the box reads along x at world coordinate `x` (metres).
fn box_profile(x: f64) -> f64 {
    let i = x / VOXEL;
    (i + 1.0).min(16.0 - i).clamp(0.0, 1.0)
}

/// A glTF with the box's volume (extra `nimbus_volume` keys in `extra`) at the origin, in a fresh folder.
fn scene_file(test: &str, extra: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-motion-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"name":"box","extras":{{"nimbus_volume":{{"file":{:?},"density_scale":{SIGMA}{extra}}}}}}}]}}"#,
        vdb.to_str().unwrap()
    );
    let path = dir.join("box.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

fn load(path: &std::path::Path, shutter: Option<Shutter>) -> Scene {
    nimbus::scene::load_builder(
        path,
        &LoadOptions {
            shutter,
            fps: Some(FPS),
            ..LoadOptions::default()
        },
    )
    .unwrap()
    .build()
    .unwrap()
}

/// The time-averaged transmittance along z at world x = `x0` (y inside the box) over `shutter`: the mean over
/// the shutter of exp(−σ · 1 m · f(x0 − scale·v·τ)), τ in seconds, by the midpoint rule with 200,000 steps.
fn averaged_transmittance(x0: f64, shutter: Shutter, velocity_scale: f64) -> f64 {
    let n = 200_000;
    let (open, close) = (shutter.open as f64 / FPS, shutter.close as f64 / FPS);
    (0..n)
        .map(|k| {
            let tau = open + (close - open) * (k as f64 + 0.5) / n as f64;
            (-SIGMA * box_profile(x0 - velocity_scale * SPEED * tau)).exp()
        })
        .sum::<f64>()
        / n as f64
}

/// Ratio-tracking and delta-tracking (escape) estimates of the transmittance along z at x = `x0`, with ray times
/// uniform over the shutter: (ratio mean, its s.e., escape fraction, its s.e., majorant violations).
fn estimates(scene: &Scene, x0: f32, shutter: Shutter, n: usize) -> (f64, f64, f64, f64, u64) {
    let medium = &scene.media()[0];
    let mut counters = TrackingCounters::default();
    let (mut sum, mut sum2, mut escaped) = (0.0f64, 0.0f64, 0usize);
    for i in 0..n {
        let mut rng = Rng::for_sample(7, 0, i as u64);
        let time = shutter.time_at(rng.next_f32());
        let ray = Ray::new(Vec3::new(x0, 0.5, -1.0), Vec3::Z).at_time(time);
        let t = medium.transmittance(&ray, 3.0, &mut rng, &mut counters).x as f64;
        sum += t;
        sum2 += t * t;
        if medium
            .free_flight(
                &ray,
                3.0,
                Vec3::ONE,
                &mut rng,
                &mut counters,
                &mut nimbus::volume::TentativeEmission::default(),
            )
            .collision
            .is_none()
        {
            escaped += 1;
        }
    }
    let nf = n as f64;
    let mean = sum / nf;
    let se = ((sum2 / nf - mean * mean).max(0.0) / nf).sqrt();
    let p = escaped as f64 / nf;
    let p_se = (p * (1.0 - p) / nf).sqrt();
    (mean, se, p, p_se, counters.majorant_violations)
}

fn assert_blur(scene: &Scene, x0: f64, shutter: Shutter, velocity_scale: f64) {
    let expected = averaged_transmittance(x0, shutter, velocity_scale);
    let (mean, se, escape, escape_se, violations) = estimates(scene, x0 as f32, shutter, 20_000);
    println!(
        "x0 {x0} shutter {shutter}: closed form {expected:.5}, ratio tracking {mean:.5} ± {se:.5}, \
         escape {escape:.5} ± {escape_se:.5}, violations {violations}"
    );
    assert!(
        (mean - expected).abs() <= 4.0 * se + 1e-4,
        "ratio tracking {mean} ± {se} vs {expected}"
    );
    assert!(
        (escape - expected).abs() <= 4.0 * escape_se + 1e-4,
        "delta tracking escape {escape} ± {escape_se} vs {expected}"
    );
    assert_eq!(violations, 0, "majorants must bound the displaced density");
}

#[test]
fn a_box_moving_at_constant_velocity_blurs_to_the_time_averaged_transmittance() {
    let path = scene_file("vec3", "");
    let centred = Shutter::parse("-6,6").unwrap();
    let scene = load(&path, Some(centred));
    // Beyond the box's frame-time edge (x = 1 m): covered part of the shutter only.
    assert_blur(&scene, 1.2, centred, 1.0);
    // Inside: covered all the shutter, partly by the ramp.
    assert_blur(&scene, 0.5, centred, 1.0);
    // Before its left edge.
    assert_blur(&scene, -0.4, centred, 1.0);
    // A shutter after the frame only: the box has moved along +x, never back (the sign of the velocity).
    let after = Shutter::parse("0,6").unwrap();
    let scene = load(&path, Some(after));
    assert_blur(&scene, 1.2, after, 1.0);
    let expected = averaged_transmittance(1.2, after, 1.0);
    let backwards = averaged_transmittance(1.2, after, -1.0);
    assert!(
        (expected - backwards).abs() > 0.3,
        "the fixture must tell +v from -v"
    );
}

#[test]
fn velocity_components_and_scale_blur_alike() {
    let shutter = Shutter::parse("-6,6").unwrap();
    let scene = load(
        &scene_file("components", r#","velocity_grid":"v""#),
        Some(shutter),
    );
    assert_blur(&scene, 1.2, shutter, 1.0);
    let scene = load(
        &scene_file("scale", r#","velocity_scale":0.5"#),
        Some(shutter),
    );
    assert_blur(&scene, 1.1, shutter, 0.5);
}

#[test]
fn without_a_shutter_the_box_stays_at_its_frame() {
    let path = scene_file("still", "");
    let scene = load(&path, None);
    let medium = &scene.media()[0];
    let mut c = TrackingCounters::default();
    let mut rng = Rng::for_sample(1, 0, 0);
    for x0 in [1.2f32, -0.4] {
        let ray = Ray::new(Vec3::new(x0, 0.5, -1.0), Vec3::Z);
        assert_eq!(medium.transmittance(&ray, 3.0, &mut rng, &mut c).x, 1.0);
    }
    assert!(!medium.method().to_string().contains("velocity"));
    // A named velocity grid the file lacks is an error, naming it.
    let err = nimbus::scene::load_builder(
        &scene_file("missing", r#","velocity_grid":"wind""#),
        &LoadOptions {
            shutter: Some(Shutter::parse("-0.5,0.5").unwrap()),
            ..LoadOptions::default()
        },
    )
    .err()
    .expect("fails")
    .to_string();
    assert!(err.contains("'wind'"), "{err}");
    // A velocity scaled far beyond any simulation is refused, not tracked over endless majorants: 2 m/s × 1e6
    // over 0.25 s is 8e6 voxels.
    let err = nimbus::scene::load_builder(
        &scene_file("fast", r#","velocity_scale":1e6"#),
        &LoadOptions {
            shutter: Some(Shutter::parse("-6,6").unwrap()),
            ..LoadOptions::default()
        },
    )
    .err()
    .expect("fails")
    .to_string();
    assert!(
        err.contains("velocity_scale") && err.contains("pyro_box.vdb"),
        "{err}"
    );
}

#[test]
fn explain_names_the_dilated_majorants() {
    let scene = load(
        &scene_file("explain", ""),
        Some(Shutter::parse("-6,6").unwrap()),
    );
    let method = scene.media()[0].method().to_string();
    // 2 m/s × 0.25 s = 0.5 m = 8 voxels.
    assert!(method.contains("dilated by up to 8.0 voxels"), "{method}");
}

/// Renders the box (centred on the origin, density scale [`SIGMA`], no light) seen along −z through a 0.05 rad
/// field of view, so every ray crosses the interior: mean and s.e. per channel of the 16 pixels.
fn render_box(extra: &str, max_depth: u32) -> [(f64, f64); 3] {
    render_box_lit(extra, max_depth, SIGMA, "", 256)
}

/// [`render_box`] with density scale `sigma`, scene `extras` (an environment) and `spp` samples per pixel.
fn render_box_lit(
    extra: &str,
    max_depth: u32,
    sigma: f64,
    scene_extras: &str,
    spp: u32,
) -> [(f64, f64); 3] {
    let path = box_scene(&format!("render{max_depth}"), extra, sigma, scene_extras);
    let builder = nimbus::scene::load_builder(&path, &LoadOptions::default()).unwrap();
    let (img, stats) = common::render_square(builder, 4, spp, max_depth, 3);
    assert_eq!(stats.nan_samples, 0);
    [0, 1, 2].map(|c| common::mean_and_se(&img, c))
}

/// The glTF of [`render_box_lit`]'s scene, in a fresh folder named after `test`.
fn box_scene(test: &str, extra: &str, sigma: f64, scene_extras: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "nimbus-motion-{test}-{}-{}-{}",
        extra.len(),
        scene_extras.len(),
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("box.gltf");
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]{scene_extras}}}],
        "nodes":[{{"name":"box","translation":[-0.5,-0.5,-0.5],"extras":{{"nimbus_volume":{{"file":{:?},"density_scale":{sigma}{extra}}}}}}},
        {{"name":"camera","camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.05,"znear":0.01}}}}]}}"#,
        vdb.to_str().unwrap()
    );
    std::fs::write(&path, gltf).unwrap();
    path
}

#[test]
fn flame_emission_through_an_absorbing_box_matches_the_closed_form() {
    // albedo_grid 0: a pure absorber, L = flame_scale · colour · (1 − e^−σ).
    let colour = [1.0, 0.5, 0.25];
    let got = render_box(
        r#","albedo_grid":"albedo","flame_grid":"flame","flame_scale":3.0,"flame_color":[1.0,0.5,0.25]"#,
        8,
    );
    let opacity = 1.0 - (-SIGMA).exp();
    for c in 0..3 {
        let expected = 3.0 * colour[c] * opacity;
        let (mean, se) = got[c];
        println!("flame channel {c}: {mean:.4} ± {se:.4}, closed form {expected:.4}");
        assert!(
            (mean - expected).abs() <= 4.0 * se + 2e-3 * expected,
            "channel {c}"
        );
    }
}

/// The flame box (albedo 0, so it only absorbs and emits) inside a chromatic absorbing homogeneous medium filling
/// a 2 m cube around it: two overlapping media on every camera segment. Each sample of the box's emission,
/// gathered at its tentative collisions, is weighted by the absorber's transmittance to it, so the pixel is
/// L_c = ∫ 3 · colour_c · σ f(z) · exp(−τ_box(z) − σ_a,c · (1 − z)) dz along the ray from the cube's face at
/// z = 1 (the integral of the non-scattering transfer equation, by the midpoint rule in f64).
#[test]
fn flame_emission_through_an_overlapping_chromatic_absorber_matches_the_integral() {
    let colour = [1.0, 0.5, 0.25];
    let sigma_a: [f32; 3] = [0.3, 0.9, 1.5];
    let path = box_scene(
        "overlap",
        r#","albedo_grid":"albedo","flame_grid":"flame","flame_scale":3.0,"flame_color":[1.0,0.5,0.25]"#,
        SIGMA,
        "",
    );
    let mut builder = nimbus::scene::load_builder(&path, &LoadOptions::default()).unwrap();
    let absorber = builder.add_medium(std::sync::Arc::new(
        nimbus::volume::homogeneous::HomogeneousMedium::new(
            "absorber",
            nimbus::math::Rgb::from_array(sigma_a),
            nimbus::math::Rgb::ZERO,
            0.0,
        ),
    ));
    common::fill_box(&mut builder, absorber, Vec3::splat(-1.0), Vec3::splat(1.0));
    let (img, stats) = common::render_square(builder, 4, 256, 8, 3);
    assert_eq!(stats.nan_samples, 0);
    // The box's density at world z is σ f(z + 0.5) (the node moves it by −0.5 m).
    let n = 200_000;
    let dz = 2.0 / n as f64;
    for c in 0..3 {
        let (mut tau_box, mut expected) = (0.0f64, 0.0f64);
        for k in 0..n {
            let z = 1.0 - (k as f64 + 0.5) * dz;
            let sigma = SIGMA * box_profile(z + 0.5);
            let transmittance =
                (-(tau_box + 0.5 * sigma * dz) - sigma_a[c] as f64 * (1.0 - z)).exp();
            expected += 3.0 * colour[c] * sigma * transmittance * dz;
            tau_box += sigma * dz;
        }
        let (mean, se) = common::mean_and_se(&img, c);
        println!("overlap channel {c}: {mean:.4} ± {se:.4}, integral {expected:.4}");
        assert!(
            (mean - expected).abs() <= 4.0 * se + 2e-3 * expected,
            "channel {c}: {mean} ± {se} vs {expected}"
        );
    }
}

/// The box's `rgb_density` grid ((1, 2, 4) times σ per metre: a chromatic absorber, albedo 0) inside a grey
/// absorbing homogeneous medium filling a 2 m cube, under a white sky: two overlapping media, one chromatic. A
/// camera ray's value is the transmittance, exp(−σ (1, 2, 4) · 1 m − 0.4 · 2 m) per channel. Spectral tracking
/// over the part of the segment before the grey medium's collision keeps every channel; carrying one channel
/// (`chromatic_tracking: one_channel`, what every path through overlapping media did before) is as unbiased,
/// with colour noise: with albedo 0.8 (no closed form; the two agree) its standard errors are larger.
#[test]
fn a_chromatic_grid_overlapping_a_grey_medium_keeps_its_colours() {
    let sky = r#","extras":{"nimbus_environment":{"color":[1.0,1.0,1.0]}}"#;
    let render = |tracking: &str, albedo: f32| {
        let extra = format!(
            r#","density_grid":"rgb_density","albedo":{albedo:?},"chromatic_tracking":"{tracking}""#
        );
        let path = box_scene(&format!("chroma-{tracking}-{albedo}"), &extra, SIGMA, sky);
        let mut builder = nimbus::scene::load_builder(&path, &LoadOptions::default()).unwrap();
        let grey = builder.add_medium(std::sync::Arc::new(
            nimbus::volume::homogeneous::HomogeneousMedium::new(
                "grey",
                nimbus::math::Rgb::splat(0.4),
                nimbus::math::Rgb::ZERO,
                0.0,
            ),
        ));
        common::fill_box(&mut builder, grey, Vec3::splat(-1.0), Vec3::splat(1.0));
        let (img, stats) = common::render_square(builder, 4, 256, 8, 3);
        assert_eq!(stats.nan_samples, 0);
        [0, 1, 2].map(|c| common::mean_and_se(&img, c))
    };
    let expected = [1.0, 2.0, 4.0].map(|k| (-SIGMA * k - 0.4 * 2.0).exp());
    let spectral = render("spectral", 0.0);
    let one = render("one_channel", 0.0);
    for c in 0..3 {
        for (name, (mean, se)) in [("spectral", spectral[c]), ("one channel", one[c])] {
            println!(
                "{name} channel {c}: {mean:.5} ± {se:.5}, closed form {:.5}",
                expected[c]
            );
            assert!(
                (mean - expected[c]).abs() <= 4.0 * se + 2e-3 * expected[c],
                "{name} channel {c}: {mean} ± {se} vs {}",
                expected[c]
            );
        }
    }
    let spectral = render("spectral", 0.8);
    let one = render("one_channel", 0.8);
    // Scattering (albedo 0.8): measured 2026-12-04, spectral s.e. 0.66, 0.50 and 0.75 of one channel's.
    for c in 0..3 {
        println!(
            "albedo 0.8 channel {c}: spectral {:.5} ± {:.5}, one channel {:.5} ± {:.5}",
            spectral[c].0, spectral[c].1, one[c].0, one[c].1
        );
        assert!((spectral[c].0 - one[c].0).abs() <= 4.0 * (spectral[c].1 + one[c].1));
        assert!(spectral[c].1 < 0.9 * one[c].1, "channel {c}");
    }
}

#[test]
fn a_colour_grid_sets_the_albedo_that_emission_leaves() {
    // Cd's green and blue, 0.5 and 0.25, are the albedo there; with no scattering counted (max depth 0) the first
    // collision's emission (1 − albedo) · L_e is all: L = (1 − Cd) · flame_scale · (1 − e^−σ).
    let got = render_box(
        r#","color_grid":"Cd","flame_grid":"flame","flame_scale":2.0,"flame_color":1.0"#,
        0,
    );
    let opacity = 1.0 - (-SIGMA).exp();
    for (c, cd) in [(1, 0.5), (2, 0.25)] {
        let expected = (1.0 - cd) * 2.0 * opacity;
        let (mean, se) = got[c];
        println!("Cd channel {c}: {mean:.4} ± {se:.4}, closed form {expected:.4}");
        assert!((mean - expected).abs() <= 4.0 * se + 2e-3, "channel {c}");
    }
}

#[test]
fn albedo_follows_the_colour_and_albedo_grids_where_the_node_places_them() {
    // The node moves the grids by (0.3, 0, 0) and the constant albedo is 0.8: at world x the red albedo is
    // 0.8 · ((x − 0.3)/0.0625 + 2)/19 (trilinear reads of a linear ramp are exact); green 0.8 · 0.5.
    let dir = std::env::temp_dir().join(format!("nimbus-motion-albedo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"name":"box","translation":[0.3,0,0],"extras":{{"nimbus_volume":{{"file":{:?},
        "albedo":0.8,"color_grid":"Cd"}}}}}}]}}"#,
        vdb.to_str().unwrap()
    );
    let path = dir.join("albedo.gltf");
    std::fs::write(&path, gltf).unwrap();
    let scene = load(&path, None);
    let medium = &scene.media()[0];
    let mut rng = Rng::for_sample(5, 0, 0);
    for _ in 0..200 {
        let p = Vec3::new(
            0.3 - 0.1 + 1.15 * rng.next_f32(),
            1.0 * rng.next_f32(),
            1.0 * rng.next_f32(),
        );
        let a = medium.collision(p, 0.0).albedo;
        let red = 0.8 * ((p.x as f64 - 0.3) / VOXEL + 2.0) / 19.0;
        assert!((a.x as f64 - red).abs() < 1e-4, "at {p}: {} vs {red}", a.x);
        assert!((a.y - 0.4).abs() < 1e-5 && (a.z - 0.2).abs() < 1e-5, "{a}");
    }
    // Blurred, the colour moves with the velocity: at 6 frames (0.25 s at 2 m/s) x reads x − 0.5 m.
    let scene = load(&path, Some(Shutter::parse("-6,6").unwrap()));
    let medium = &scene.media()[0];
    for x in [0.75f32, 1.0, 1.3] {
        let p = Vec3::new(x, 0.5, 0.5);
        let a = medium.collision(p, 6.0).albedo;
        let red = 0.8 * ((x as f64 - 0.5 - 0.3) / VOXEL + 2.0) / 19.0;
        assert!(
            (a.x as f64 - red).abs() < 1e-4,
            "at {p}, 6 frames: {} vs {red}",
            a.x
        );
    }
}

/// The `chromatic_tracking` methods of an RGB density grid.
const CHROMATIC_METHODS: [&str; 2] = ["one_channel", "spectral"];

/// The white environment, as scene extras.
const WHITE_SKY: &str = r#","extras":{"nimbus_environment":{"color":[1,1,1]}}"#;

#[test]
fn an_rgb_density_grid_attenuates_each_channel_by_its_own_extinction() {
    // σ_t = (1, 2, 4) per metre through 1 m of a pure absorber (albedo 0) in front of a white sky: each channel
    // is e^−σ_c, whether each path tracks one channel only or spectral tracking keeps all three.
    for method in CHROMATIC_METHODS {
        let got = render_box_lit(
            &format!(
                r#","density_grid":"rgb_density","albedo":0.0,"chromatic_tracking":"{method}""#
            ),
            8,
            1.0,
            WHITE_SKY,
            4096,
        );
        for (c, sigma) in [1.0f64, 2.0, 4.0].into_iter().enumerate() {
            let expected = (-sigma).exp();
            let (mean, se) = got[c];
            println!("{method} rgb transmittance channel {c}: {mean:.4} ± {se:.4}, closed form {expected:.4}");
            assert!(
                (mean - expected).abs() <= 4.0 * se + 1e-3,
                "{method} channel {c}"
            );
        }
    }
    // Shadow-ray estimates: per channel ratio tracking.
    let scene = load(&scene_file("rgb", r#","density_grid":"rgb_density""#), None);
    let medium = &scene.media()[0];
    assert!(matches!(
        medium.method().free_flight,
        nimbus::volume::FreeFlight::DeltaTracking {
            chromatic: Some(_),
            ..
        }
    ));
    assert!(medium.method().to_string().contains("RGB density"));
    // `auto` is spectral tracking; either method can be forced, and `--explain` and `--stats` say which.
    let stats = |m: &dyn nimbus::volume::Medium| serde_json::to_value(m.method()).unwrap();
    assert_eq!(stats(medium.as_ref())["chromatic_tracking"], "spectral");
    assert!(medium.method().to_string().contains("spectral tracking"));
    assert!(medium.method().to_string().contains("auto: "));
    for method in CHROMATIC_METHODS {
        let forced = load(
            &scene_file(
                &format!("rgb-{method}"),
                &format!(r#","density_grid":"rgb_density","chromatic_tracking":"{method}""#),
            ),
            None,
        );
        let m = &forced.media()[0];
        assert_eq!(stats(m.as_ref())["chromatic_tracking"], method);
        assert!(
            m.method().to_string().contains("as requested"),
            "{}",
            m.method()
        );
    }
    let mut c = TrackingCounters::default();
    let n = 4000;
    let mut sum = Vec3::ZERO;
    for i in 0..n {
        let mut rng = Rng::for_sample(9, 0, i);
        let ray = Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        sum += medium.transmittance(&ray, 3.0, &mut rng, &mut c);
    }
    let mean = sum / n as f32;
    // σ = 2 · (1, 2, 4) here (the fixture's density scale); ratio tracking's spread stays below 0.5 per sample.
    for (ch, sigma) in [2.0f32, 4.0, 8.0].into_iter().enumerate() {
        let expected = (-sigma).exp();
        assert!(
            (mean[ch] - expected).abs() < 4.0 * 0.5 / (n as f32).sqrt(),
            "channel {ch}: {} vs {expected}",
            mean[ch]
        );
    }
    assert_eq!(c.majorant_violations, 0);
}

#[test]
fn an_rgb_density_grid_passes_the_white_furnace() {
    // Albedo 1 under a white sky: every channel of every pixel is exactly 1, whatever σ_t per channel, with
    // either chromatic method; mildly (1:2:4) and strongly (1:10:100: up to 100 per metre)
    // chromatic.
    for (grid, sigma, spp) in [("rgb_density", 1.0, 2048), ("rgb_strong", 1.0, 512)] {
        for method in CHROMATIC_METHODS {
            let got = render_box_lit(
                &format!(
                    r#","density_grid":"{grid}","albedo":1.0,"chromatic_tracking":"{method}""#
                ),
                100_000,
                sigma,
                WHITE_SKY,
                spp,
            );
            for (c, (mean, se)) in got.into_iter().enumerate() {
                println!("{grid} {method} furnace channel {c}: {mean:.4} ± {se:.4}");
                assert!(
                    (mean - 1.0).abs() <= 4.0 * se + 1e-3,
                    "{grid} {method} channel {c}: {mean} ± {se}"
                );
            }
        }
    }
}

/// Mitsuba 3's render (scalar_rgb, `volpath`, unbounded depth) of the RGB box (σ_t = (1, 2, 4) per metre,
/// albedo 0.8) under the white sky, framed as [`render_box_lit`] frames it: the mean of the 16 pixels per channel
/// and its standard error over 32 passes of 16384 spp (`tests/scenes/rgb_box_mitsuba.py 1,2,4 0.8 524288`).
const MITSUBA_RGB_BOX: [(f64, f64); 3] =
    [(0.81362, 0.00086), (0.66620, 0.00013), (0.47311, 0.00033)];

#[test]
fn an_rgb_density_box_matches_mitsuba() {
    // Multiple scattering in a chromatic grid, against an independent renderer, with either chromatic method.
    for method in CHROMATIC_METHODS {
        let got = render_box_lit(
            &format!(
                r#","density_grid":"rgb_density","albedo":0.8,"chromatic_tracking":"{method}""#
            ),
            100_000,
            1.0,
            WHITE_SKY,
            16384,
        );
        for (c, ((mean, se), (reference, reference_se))) in
            got.into_iter().zip(MITSUBA_RGB_BOX).enumerate()
        {
            let z = (mean - reference) / (se * se + reference_se * reference_se).sqrt();
            println!("{method} channel {c}: {mean:.5} ± {se:.5}, Mitsuba {reference:.5} ± {reference_se:.5}, z {z:.2}");
            assert!(z.abs() <= 4.0, "{method} channel {c}: z = {z}");
        }
    }
}

#[test]
fn spectral_tracking_follows_a_moving_rgb_density() {
    // The RGB box (σ_t = 2 · (1, 2, 4) per metre) blurred over the shutter -6..6 frames, rays along z at world
    // x = 0.22 and 3 frames (0.125 s at 2 m/s: the box has moved 0.25 m), where the lookups read the box's
    // frame-time profile at x = −0.03: each channel's spectral-tracking escape weight averages
    // e^−σ_c·f(−0.03), f the trapezoid a trilinear lookup reads.
    let scene = load(
        &scene_file("rgb-moving", r#","density_grid":"rgb_density""#),
        Some(Shutter::parse("-6,6").unwrap()),
    );
    let medium = &scene.media()[0];
    let mut counters = TrackingCounters::default();
    let n = 20_000;
    let (mut sum, mut sum2) = (Vec3::ZERO.as_dvec3(), Vec3::ZERO.as_dvec3());
    for i in 0..n {
        let mut rng = Rng::for_sample(13, 0, i);
        let ray = Ray::new(Vec3::new(0.22, 0.5, -1.0), Vec3::Z).at_time(3.0);
        // An RGB density tracks spectrally by default.
        let flight = medium.free_flight(
            &ray,
            3.0,
            Vec3::ONE,
            &mut rng,
            &mut counters,
            &mut nimbus::volume::TentativeEmission::default(),
        );
        let w = if flight.collision.is_none() {
            flight.throughput.as_dvec3()
        } else {
            Vec3::ZERO.as_dvec3()
        };
        sum += w;
        sum2 += w * w;
    }
    let mean = sum / n as f64;
    let se = ((sum2 / n as f64 - mean * mean).max(glam::DVec3::ZERO) / n as f64).map(f64::sqrt);
    for (c, sigma) in [1.0f64, 2.0, 4.0].into_iter().enumerate() {
        let expected = (-SIGMA * sigma * box_profile(-0.03)).exp();
        println!(
            "moving rgb channel {c}: {:.4} ± {:.4}, closed form {expected:.4}",
            mean[c], se[c]
        );
        assert!(
            (mean[c] - expected).abs() <= 4.0 * se[c] + 1e-4,
            "channel {c}"
        );
    }
    assert_eq!(counters.spectral_flights, n);
    assert_eq!(counters.majorant_violations, 0);
}

#[test]
fn spectral_tracking_renders_the_same_image_on_any_thread_count() {
    // The strongly chromatic box (1:10:100) with albedo 0.8 under a white sky, 1 and 3 threads, same seed.
    let path = box_scene(
        "spectral-threads",
        r#","density_grid":"rgb_strong","albedo":0.8,"chromatic_tracking":"spectral""#,
        1.0,
        WHITE_SKY,
    );
    let render = |threads| {
        let scene = nimbus::scene::load_builder(&path, &LoadOptions::default())
            .unwrap()
            .build()
            .unwrap();
        let settings = nimbus::render::RenderSettings {
            width: 6,
            height: 6,
            spp: 32,
            seed: 11,
            threads,
            max_depth: 64,
            ..Default::default()
        };
        nimbus::render::Renderer::new(settings)
            .render(&scene, &mut |_| true)
            .unwrap()
    };
    let (one, stats) = render(1);
    let (three, _) = render(3);
    assert_eq!(stats.nan_samples, 0);
    assert!(stats.media[0].counters.spectral_flights > 0);
    assert!(one.beauty.iter().all(|p| p.is_finite()));
    assert_eq!(one.beauty, three.beauty);
}

#[test]
fn a_usd_stage_s_frame_rate_converts_the_shutter_to_seconds() {
    // At 12 frames per second a shutter of ±6 frames is ±0.5 s: 2 m/s moves the box 1 m, 16 voxels (8 at 24).
    let dir = std::env::temp_dir().join(format!("nimbus-motion-usdfps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let stage = dir.join("box.usda");
    std::fs::write(
        &stage,
        format!(
            "#usda 1.0\n(\n    framesPerSecond = 12\n    timeCodesPerSecond = 12\n)\ndef Volume \"Box\"\n{{\n\
             custom rel field:density = </Box/density>\ndef OpenVDBAsset \"density\"\n{{\n\
             token fieldName = \"density\"\nasset filePath = @{}@\n}}\n}}\n",
            vdb.display()
        ),
    )
    .unwrap();
    let shutter = Some(Shutter::parse("-6,6").unwrap());
    let at = |fps: Option<f64>| {
        let builder = nimbus::scene::load_builder(
            &stage,
            &LoadOptions {
                shutter,
                fps,
                ..LoadOptions::default()
            },
        )
        .unwrap();
        builder.media()[0].method().to_string()
    };
    assert!(
        at(None).contains("dilated by up to 16.0 voxels"),
        "{}",
        at(None)
    );
    // --fps overrides the stage's rate.
    assert!(
        at(Some(24.0)).contains("dilated by up to 8.0 voxels"),
        "{}",
        at(Some(24.0))
    );
    std::fs::remove_dir_all(dir).ok();
}
