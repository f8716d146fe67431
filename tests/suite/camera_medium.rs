//! A camera inside closed medium boundaries starts its paths in the media around it, as Cycles and Arnold
//! find them and as pbrt-v4 and Mitsuba 3 are told (a camera medium, a sensor medium). Checked against Beer's
//! law: the camera sits at the origin inside absorbing cubes and looks down −z at a uniform environment of
//! radiance 1 through a narrow field of view (rays within 0.6° of −z), so each pixel is
//! `exp(−Σ σ_a·d)` over the lengths `d` of the ray in each medium, innermost medium counting where media nest.

use crate::common;

use nimbus::light::{EnvironmentLight, Light};
use nimbus::math::{Rgb, Vec3};
use nimbus::scene::SceneBuilder;
use nimbus::volume::homogeneous::HomogeneousMedium;
use nimbus::Camera;
use std::sync::Arc;

/// A scene of absorbing cubes, each `(half side, sigma_a)` centred on the origin, the camera at the origin
/// looking down −z, and a uniform environment of radiance 1.
fn cubes_around_the_camera(cubes: &[(f32, f32)]) -> SceneBuilder {
    let mut b = SceneBuilder::new();
    for (i, &(half, sigma_a)) in cubes.iter().enumerate() {
        let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
            &format!("cube{i}"),
            Rgb::splat(sigma_a),
            Rgb::ZERO,
            0.0,
        )));
        common::fill_box(&mut b, medium, Vec3::splat(-half), Vec3::splat(half));
    }
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(Camera::look_at(
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -1.0),
        1.2f32.to_radians(),
    ));
    b
}

/// Renders `builder` and checks every channel's mean against `expected` within 4 standard errors (plus 0.2%
/// for the rays' slant, at most 1/cos 0.6° − 1 = 5.5e-5 of the path length).
fn check(label: &str, builder: SceneBuilder, expected: f64) {
    let (img, stats) = common::render_square(builder, 8, 16, 4, 7);
    assert_eq!(stats.nan_samples, 0);
    for c in 0..3 {
        let (mean, se) = common::mean_and_se(&img, c);
        println!("{label} channel {c}: {mean:.5} ± {se:.5}, Beer's law {expected:.5}");
        assert!(
            (mean - expected).abs() <= 4.0 * se + 2e-3 * expected,
            "{label} channel {c}: {mean} ± {se} vs {expected}"
        );
    }
}

#[test]
fn a_camera_inside_an_absorbing_cube_sees_through_it() {
    // 1 m of sigma_a 0.7 between the camera and the cube's face at z = −1.
    check(
        "one cube",
        cubes_around_the_camera(&[(1.0, 0.7)]),
        (-0.7f64).exp(),
    );
}

#[test]
fn a_camera_inside_nested_cubes_starts_in_the_innermost() {
    // 0.5 m in the inner cube (sigma_a 0.4), then 0.5 m in the outer one only (sigma_a 0.3). Starting in the
    // outer medium would give exp(−0.3), in none exp(0) = 1.
    check(
        "nested cubes",
        cubes_around_the_camera(&[(1.0, 0.3), (0.5, 0.4)]),
        (-0.35f64).exp(),
    );
}
