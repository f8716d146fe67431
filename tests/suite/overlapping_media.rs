//! Overlapping media, one or more of them chromatic, against closed forms (issue 35, "one medium contract").
//!
//! The fixture `tests/scenes/pyro_box.vdb` (see `volume_motion.rs`) holds a box of density 1 whose trilinear
//! profile integrates to exactly 1 m along z through its interior; its `rgb_density` grid is (1, 2, 4) times
//! that per channel and its `flame` grid is 1 wherever density can be read. Every scene here places two copies
//! of the box at the same place (two overlapping grid media), inside a homogeneous cube of side 2 m, and looks
//! down −z through the boxes' interior with a narrow camera, so every camera ray crosses all three media.
//!
//! Each test prints the render's mean per channel with its standard error, the closed form, and the render's
//! seconds and per-pixel mean squared error against the closed form (the efficiency figures of the report).

use nimbus::math::{Rgb, Vec3};
use nimbus::scene::LoadOptions;
use std::path::PathBuf;
use std::time::Instant;

use crate::common;

/// A glTF with two copies of the box (their `nimbus_volume` keys after `file` in `first` and `second`) at the
/// world cube [−0.5, 0.5]³, a camera on +z looking down through them, and `scene_extras` on the scene.
fn two_boxes(test: &str, first: &str, second: &str, scene_extras: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-overlap-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("boxes.gltf");
    let vdb = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let file = format!("{:?}", vdb.to_str().unwrap());
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1,2]{scene_extras}}}],
        "nodes":[{{"name":"a","translation":[-0.5,-0.5,-0.5],"extras":{{"nimbus_volume":{{"file":{file}{first}}}}}}},
        {{"name":"b","translation":[-0.5,-0.5,-0.5],"extras":{{"nimbus_volume":{{"file":{file}{second}}}}}}},
        {{"name":"camera","camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.05,"znear":0.01}}}}]}}"#
    );
    std::fs::write(&path, gltf).unwrap();
    path
}

/// Loads `path` and adds a homogeneous medium of `sigma_a` and `sigma_s` filling the cube [−1, 1]³.
fn with_cube(path: &std::path::Path, sigma_a: Rgb, sigma_s: Rgb) -> nimbus::scene::SceneBuilder {
    let mut builder = nimbus::scene::load_builder(path, &LoadOptions::default()).unwrap();
    let cube = builder.add_medium(std::sync::Arc::new(
        nimbus::volume::homogeneous::HomogeneousMedium::new("cube", sigma_a, sigma_s, 0.0),
    ));
    common::fill_box(&mut builder, cube, Vec3::splat(-1.0), Vec3::splat(1.0));
    builder
}

/// Renders `builder` (8×8, `spp`, `max_depth`) and checks every channel's mean against `expected` within 4
/// standard errors (plus 0.2% of the value for the closed form's own rounding). Prints the figures.
fn check(
    label: &str,
    builder: nimbus::scene::SceneBuilder,
    spp: u32,
    depth: u32,
    expected: [f64; 3],
) {
    let start = Instant::now();
    let (img, stats) = common::render_square(builder, 8, spp, depth, 5);
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(stats.nan_samples, 0);
    for (c, &truth) in expected.iter().enumerate() {
        let (mean, se) = common::mean_and_se(&img, c);
        let mse = img
            .beauty
            .iter()
            .map(|p| (p[c] as f64 - truth).powi(2))
            .sum::<f64>()
            / img.pixel_count() as f64;
        println!(
            "{label} channel {c}: {mean:.5} ± {se:.5}, closed form {truth:.5}; pixel MSE {mse:.3e}, {seconds:.2} s"
        );
        assert!(
            (mean - truth).abs() <= 4.0 * se + 2e-3 * truth,
            "{label} channel {c}: {mean} ± {se} vs {truth}"
        );
    }
}

/// Two overlapping chromatic boxes (RGB density, σ = 1 and 0.5 per metre times (1, 2, 4), albedo 0.7) inside a
/// chromatic scattering cube (σ_a (0.1, 0.2, 0.3), σ_s (0.4, 0.1, 0.05)), under a white sky, with no scattering
/// counted (max depth 0: a collision ends the path): a camera ray's value is the transmittance of the sum,
/// exp(−(1 + 0.5) · (1, 2, 4) − 2 σ_t,cube) per channel.
#[test]
fn two_chromatic_boxes_in_a_chromatic_cube_transmit_the_sum_of_their_extinctions() {
    let sky = r#","extras":{"nimbus_environment":{"color":[1.0,1.0,1.0]}}"#;
    let rgb = |sigma: f64| {
        format!(r#","density_scale":{sigma},"density_grid":"rgb_density","albedo":0.7"#)
    };
    let path = two_boxes("transmittance", &rgb(1.0), &rgb(0.5), sky);
    let (sigma_a, sigma_s) = (Rgb::new(0.1, 0.2, 0.3), Rgb::new(0.4, 0.1, 0.05));
    let sigma_t = (sigma_a + sigma_s).to_array();
    let expected = [0, 1, 2].map(|c| (-1.5 * [1.0, 2.0, 4.0][c] - 2.0 * sigma_t[c] as f64).exp());
    check(
        "two chromatic boxes, transmittance",
        with_cube(&path, sigma_a, sigma_s),
        2048,
        0,
        expected,
    );
}

/// The same media, conservative (albedo 1 in the boxes, σ_a 0 in the cube), under a white sky, with every
/// bounce counted: the white furnace, 1 in every channel whatever the chromaticity and overlap.
#[test]
fn two_chromatic_boxes_in_a_chromatic_cube_hold_the_furnace() {
    let sky = r#","extras":{"nimbus_environment":{"color":[1.0,1.0,1.0]}}"#;
    let rgb = |sigma: f64| {
        format!(r#","density_scale":{sigma},"density_grid":"rgb_density","albedo":1.0"#)
    };
    let path = two_boxes("furnace", &rgb(1.0), &rgb(0.5), sky);
    check(
        "two chromatic boxes, furnace",
        with_cube(&path, Rgb::ZERO, Rgb::new(0.6, 0.2, 0.05)),
        512,
        10_000,
        [1.0; 3],
    );
}

/// The trapezoid a trilinear lookup of the box reads along z at world coordinate `z` (metres): the box's voxels
/// of 0.0625 m, moved by −0.5 m.
fn box_profile(z: f64) -> f64 {
    let i = (z + 0.5) / 0.0625;
    (i + 1.0).min(16.0 - i).clamp(0.0, 1.0)
}

/// A chromatic box (RGB density, σ 0.5 · (1, 2, 4), albedo 0: an absorber) overlapping an emitting box (flame
/// 3 · (1, 0.5, 0.25), σ_f 1, albedo 0), inside a chromatic absorbing cube (σ_a (0.3, 0.9, 1.5)), no sky: a
/// chromatic medium beside an emitting one, inside a third. The pixel is the integral of the non-scattering
/// transfer equation along the ray from the cube's face at z = 1,
/// L_c = ∫ 3 colour_c σ_f f(z) exp(−(σ_f + 0.5 k_c) F(z) − σ_a,c (1 − z)) dz, F(z) = ∫_z^1 f,
/// by the midpoint rule in f64 (without the cube it is 3 colour_c σ_f / (σ_f + σ_c) · (1 − e^−(σ_f + σ_c))).
#[test]
fn flame_through_an_overlapping_chromatic_box_matches_the_integral() {
    let flame = r#","density_scale":1.0,"albedo_grid":"albedo","flame_grid":"flame","flame_scale":3.0,"flame_color":[1.0,0.5,0.25]"#;
    let absorber = r#","density_scale":0.5,"density_grid":"rgb_density","albedo":0.0"#;
    let path = two_boxes("flame", absorber, flame, "");
    let sigma_a = [0.3, 0.9, 1.5];
    let colour = [1.0, 0.5, 0.25];
    let n = 200_000;
    let dz = 2.0 / n as f64;
    let expected = [0, 1, 2].map(|c| {
        let sigma = 1.0 + 0.5 * [1.0, 2.0, 4.0][c];
        let (mut depth, mut sum) = (0.0f64, 0.0f64);
        for k in 0..n {
            let z = 1.0 - (k as f64 + 0.5) * dz;
            let f = box_profile(z);
            let transmittance = (-sigma * (depth + 0.5 * f * dz) - sigma_a[c] * (1.0 - z)).exp();
            sum += 3.0 * colour[c] * f * transmittance * dz;
            depth += f * dz;
        }
        sum
    });
    check(
        "chromatic box over a flame",
        with_cube(&path, Rgb::from_array(sigma_a.map(|s| s as f32)), Rgb::ZERO),
        2048,
        4,
        expected,
    );
}
