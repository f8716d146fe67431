//! No NaN from glass (issue 33): a dielectric whose `KHR_materials_volume` interior has a colour channel that
//! does not attenuate (`attenuationColor` 1 there, σ_a = 0) is common in glTF files (the Khronos glass models
//! use `[0.8, 0.95, 1.0]`). When a refracted path leaves the scene while that interior is still on its medium
//! stack (a glass sheet modelled as one open surface, or any mesh that is not closed) its last segment is
//! infinite, and Beer's law over it must give 0 where σ_a > 0 and exactly 1 where σ_a = 0, not `exp(−0·∞)`,
//! a NaN that the film then drops as a sample.
//!
//! Closed form: a smooth glass sheet (index η) seen at normal incidence under a constant environment of
//! radiance 1, its interior absorbing red and green only. A sample reflects with probability F = ((η − 1)/(η +
//! 1))² and sees the environment (value 1 in every channel), or refracts (weight 1/η², the radiance scaling of
//! refraction on camera paths) and leaves through the interior forever: 0 in red and green, 1/η² in blue. The
//! mean is F in red and green and F + (1 − F)/η² in blue.

use crate::common;

use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Vec3};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::volume::homogeneous::HomogeneousMedium;
use nimbus::Material;
use std::sync::Arc;

/// A smooth glass sheet of index `ior` in the plane z = 0 (front face toward +z), with an absorbing interior
/// that leaves blue alone, under a constant white environment, seen head-on from +z through a narrow lens.
fn open_glass_sheet(ior: f32) -> SceneBuilder {
    let mut b = SceneBuilder::default();
    // attenuationColor [0.5, 0.8, 1.0] at attenuationDistance 0.1 m, as the glTF loader reads it.
    let sigma_a = Rgb::new(-(0.5f32.ln()), -(0.8f32.ln()), 0.0) / 0.1;
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "glass interior",
        sigma_a,
        Rgb::ZERO,
        0.0,
    )));
    let mut glass = Material::lambertian("glass", Rgb::ONE);
    glass.metallic = 0.0;
    glass.roughness = 0.0;
    glass.transmission = 1.0;
    glass.ior = ior;
    glass.interior = Some(medium);
    let m = b.add_material(glass);
    let s = 10.0;
    b.add_mesh(common::quad(
        [
            Vec3::new(-s, -s, 0.0),
            Vec3::new(s, -s, 0.0),
            Vec3::new(s, s, 0.0),
            Vec3::new(-s, s, 0.0),
        ],
        m,
    ));
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 3.0),
        Vec3::ZERO,
        1f32.to_radians(),
    ));
    b
}

#[test]
fn glass_with_a_clear_channel_leaving_the_scene_is_finite_and_exact() {
    for (k, ior) in [1.5f32, 1.33].into_iter().enumerate() {
        let (img, stats) = common::render_square(open_glass_sheet(ior), 8, 256, 4, 40 + k as u64);
        assert_eq!(stats.nan_samples, 0, "ior {ior}: NaN samples");
        assert!(img.beauty.iter().all(|p| p.is_finite()));
        let f = ((ior - 1.0) / (ior + 1.0)).powi(2) as f64;
        let transmitted = (1.0 - f) / (ior as f64 * ior as f64);
        for (c, expected) in [(0, f), (1, f), (2, f + transmitted)] {
            let (mean, se) = common::mean_and_se(&img, c);
            println!("ior {ior}, channel {c}: {mean:.5} ± {se:.5}, closed form {expected:.5}");
            assert!(
                (mean - expected).abs() <= 4.0 * se + 1e-5,
                "ior {ior}, channel {c}: {mean} ± {se} against {expected}"
            );
        }
    }
}
