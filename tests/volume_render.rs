//! Media rendered end to end against closed forms: Beer's-law slabs seen against a constant environment,
//! and white furnaces with albedo-1 scattering media, thin and thick, grey and chromatic.

mod common;

use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::{RenderImage, RenderStats};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::volume::homogeneous::HomogeneousMedium;
use std::sync::Arc;

fn render(b: SceneBuilder, size: usize, spp: u32, max_depth: u32) -> (RenderImage, RenderStats) {
    common::render_square(b, size, spp, max_depth, 3)
}

/// A box medium [-1,1]³ with an index-matched boundary, a constant environment and a camera on +z.
fn box_scene(sigma_a: Rgb, sigma_s: Rgb, env: Rgb, fov: f32) -> SceneBuilder {
    let mut b = SceneBuilder::default();
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "box", sigma_a, sigma_s, 0.3,
    )));
    let mat = b.add_material(common::boundary(medium));
    b.add_mesh(common::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), mat));
    b.set_environment(EnvironmentLight::Constant(env));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::ZERO,
        fov.to_radians(),
    ));
    b
}

#[test]
fn beers_law_slab_transmittance_is_exact() {
    // Absorption only, seen head-on through 2 m: L = env · exp(−σ_a · 2), no randomness but pixel jitter
    // (the narrow field of view keeps every ray inside the box's front face).
    let sigma_a = Rgb::new(0.4, 0.8, 1.6);
    let b = box_scene(sigma_a, Rgb::ZERO, Rgb::ONE, 10.0);
    let camera = b.camera().cloned().unwrap();
    let (img, stats) = render(b, 8, 64, 0);
    // Each ray crosses the slab z ∈ [−1, 1] over 2/|d_z|; the box filter averages that over the pixel, so the
    // expectation is a quadrature over the pixel and the tolerance 4 standard errors of the jitter.
    for (i, p) in img.beauty.iter().enumerate() {
        let (x, y) = (i % 8, i / 8);
        for c in 0..3 {
            let mut truth = 0.0;
            for j in 0..8 {
                for k in 0..8 {
                    let film = nimbus::math::Vec2::new(
                        (x as f32 + (k as f32 + 0.5) / 8.0) / 8.0,
                        (y as f32 + (j as f32 + 0.5) / 8.0) / 8.0,
                    );
                    let d = camera.generate_ray(film, 1.0).dir;
                    truth += (-sigma_a[c] * 2.0 / d.z.abs()).exp() / 64.0;
                }
            }
            let se = img.variance[i][c].sqrt();
            assert!(
                (p[c] - truth).abs() < 4.0 * se + 1e-5,
                "channel {c}: {} vs {truth} (se {se})",
                p[c]
            );
        }
    }
    assert_eq!(stats.media.len(), 1);
    assert!(
        stats.media[0].method.contains("absorption only"),
        "{}",
        stats.media[0].method
    );
    assert_eq!(
        stats.media[0].counters.real_collisions, 0,
        "absorption-only media sample no collisions"
    );
}

#[test]
fn white_furnace_scattering_media_thin_thick_and_chromatic() {
    for (sigma_s, label) in [
        (Rgb::splat(0.05), "thin"),
        (Rgb::splat(8.0), "thick"),
        (Rgb::new(0.5, 5.0, 50.0), "chromatic 1:10:100"),
    ] {
        let env = Rgb::splat(0.7);
        let (img, stats) = render(box_scene(Rgb::ZERO, sigma_s, env, 30.0), 12, 16, 10_000);
        assert_eq!(stats.nan_samples, 0);
        for c in 0..3 {
            let (mean, se) = common::mean_and_se(&img, c);
            assert!(
                (mean - 0.7).abs() < 4.0 * se + 1e-5,
                "{label}, channel {c}: {mean} vs 0.7 (se {se})"
            );
        }
        assert!(
            stats.media[0].counters.real_collisions > 0,
            "{label}: the medium scatters"
        );
    }
}

#[test]
fn single_scattering_slab_matches_closed_form_in_depth_one() {
    // max_depth 1 through a grey scattering slab under a constant environment: what reaches the camera is
    // the unscattered environment plus single scattering. The pixel mean is checked against the exact
    // zero-scattering term plus a bound: 0 ≤ single scattering ≤ env·(1 − T).
    let sigma_s = Rgb::splat(0.5);
    let (img, _) = render(box_scene(Rgb::ZERO, sigma_s, Rgb::ONE, 10.0), 8, 64, 1);
    let t = (-1.0f64).exp();
    let (mean, se) = common::mean_and_se(&img, 0);
    assert!(
        mean > t - 4.0 * se && mean < 1.0 + 4.0 * se,
        "{mean} outside [{t}, 1]"
    );
}

#[test]
fn homogeneous_sphere_transmittance_for_every_method() {
    // Through the centre of a sphere of radius 1 the chord is 2: absorption only (closed-form transmittance)
    // and scattering with max_depth 0 (closed-form free flights: escaping paths carry T) both give
    // exp(−2σ_t). A narrow field of view keeps every ray within 0.2% of the central chord.
    for (sigma_a, sigma_s, label) in [
        (1.0f32, 0.0f32, "absorbing"),
        (0.0, 1.0, "scattering"),
        (0.3, 0.7, "mixed"),
    ] {
        let mut b = SceneBuilder::default();
        let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
            "sphere",
            Rgb::splat(sigma_a),
            Rgb::splat(sigma_s),
            0.0,
        )));
        let mat = b.add_material(common::boundary(medium));
        b.add_mesh(common::uv_sphere(Vec3::ZERO, 1.0, 128, 256, mat));
        b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
        b.set_camera(Camera::look_at(
            Vec3::new(0.0, 0.0, 50.0),
            Vec3::ZERO,
            0.05f32.to_radians(),
        ));
        let (img, _) = render(b, 4, 256, 0);
        let truth = (-2.0f64 * (sigma_a + sigma_s) as f64).exp();
        let (mean, se) = common::mean_and_se(&img, 0);
        assert!(
            (mean - truth).abs() < 4.0 * se + 2e-3 * truth,
            "{label}: {mean} vs {truth} (se {se})"
        );
    }
}
