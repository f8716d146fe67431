//! Robust ray spawning, checked against a closed form: a Lambertian floor point straight under a rectangular
//! emitter must receive exactly the irradiance the point-to-rectangle form factor gives, whatever the height of
//! the emitter and the scale (and distance from the origin) of the scene.
//!
//! This is the configuration where a shadow ray's origin offset and its end-point epsilon can cancel, so that
//! the shadow ray hits the emitter's own triangle: every light sample is then "blocked" and the floor is dark.

use crate::common;

use nimbus::math::{Rgb, Vec3};
use nimbus::{Camera, Material, SceneBuilder};

/// Form factor from a differential area to a parallel rectangle `x` × `y` whose corner lies straight above it at
/// height `h` (the classic corner configuration of radiative transfer; e.g. Howell's catalog of configuration
/// factors): F = 1/(2π) · [X/√(1+X²) · atan(Y/√(1+X²)) + Y/√(1+Y²) · atan(X/√(1+Y²))], X = x/h, Y = y/h.
fn corner_form_factor(x: f64, y: f64, h: f64) -> f64 {
    let (a, b) = (x / h, y / h);
    let (sa, sb) = ((1.0 + a * a).sqrt(), (1.0 + b * b).sqrt());
    ((a / sa) * (b / sa).atan() + (b / sb) * (a / sb).atan()) / (2.0 * std::f64::consts::PI)
}

#[test]
fn floor_under_a_rectangular_emitter_receives_the_form_factor_at_every_height_and_scale() {
    // Half-sizes of the emitter, in metres before scaling.
    let (half_x, half_z) = (0.5f32, 0.3f32);
    let mut failures = Vec::new();
    for &scale in &[1e-3f32, 1.0, 1e4] {
        for &height in &[1e-3f32, 1e-2, 1.0, 100.0] {
            let h = height * scale;
            let (a, b) = (half_x * scale, half_z * scale);
            // Away from the origin, so that coordinates are large compared with the height.
            let p = Vec3::new(3.0, 0.5, -2.0) * scale;
            let mut builder = SceneBuilder::default();
            let floor = builder.add_material(Material::lambertian("floor", Rgb::ONE));
            let mut emitter = Material::lambertian("emitter", Rgb::ZERO);
            emitter.emission = Rgb::ONE;
            let light = builder.add_material(emitter);
            let s = (a.max(b) + h) * 2.0;
            builder.add_mesh(common::quad(
                [
                    p + Vec3::new(-s, 0.0, -s),
                    p + Vec3::new(-s, 0.0, s),
                    p + Vec3::new(s, 0.0, s),
                    p + Vec3::new(s, 0.0, -s),
                ],
                floor,
            ));
            // Counter-clockwise seen from below: it emits downward.
            builder.add_mesh(common::quad(
                [
                    p + Vec3::new(-a, h, -b),
                    p + Vec3::new(a, h, -b),
                    p + Vec3::new(a, h, b),
                    p + Vec3::new(-a, h, b),
                ],
                light,
            ));
            // Looking straight down at p from half the height, seeing a disc of radius 1e-4 h: the irradiance
            // varies over it by about (1e-4)², far below the noise.
            let yfov = 2.0 * (2e-4f32).atan();
            builder.set_camera(Camera::look_at(p + Vec3::Y * (0.5 * h), p, yfov));
            // One bounce: direct light only, with light sampling and BSDF sampling combined by MIS.
            let (img, stats) = common::render_square(builder, 8, 256, 1, 11);
            assert_eq!(stats.nan_samples, 0);
            let (mean, se) = common::mean_and_se(&img, 1);
            // Albedo 1 and emitted radiance 1: outgoing radiance = E / π = F.
            let expected = 4.0 * corner_form_factor(a as f64, b as f64, h as f64);
            let ok = (mean - expected).abs() <= 4.0 * se + 1e-6 * expected;
            println!(
                "scale {scale:e} height {height:e}: {mean:.6} ± {se:.6}, form factor {expected:.6} ({})",
                if ok { "ok" } else { "FAIL" }
            );
            if !ok {
                failures.push(format!(
                    "scale {scale}, height {height}: radiance {mean} ± {se}, form factor {expected}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
