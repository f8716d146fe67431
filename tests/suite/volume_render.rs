//! Media rendered end to end against closed forms: Beer's-law slabs seen against a constant environment,
//! and white furnaces with albedo-1 scattering media, thin and thick, grey and chromatic.

use crate::common;

use glam::DVec3;
use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::{RenderImage, RenderStats};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::volume::homogeneous::HomogeneousMedium;
use std::f64::consts::PI;
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
    common::fill_box(&mut b, medium, Vec3::splat(-1.0), Vec3::splat(1.0));
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
    assert_eq!(
        stats.media[0].method_details.why,
        nimbus::volume::MethodReason::AbsorptionOnly,
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

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's iteration on the Legendre recurrence).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            loop {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                let dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-14 {
                    return (x, 2.0 / ((1.0 - x * x) * dp * dp));
                }
            }
        })
        .collect()
}

/// Radiance along one camera ray (from `origin` along unit `d`, entering the box [−1, 1]³ through its z = 1
/// face) for a medium of grey σ_t = σ_s (no absorption) with Henyey–Greenstein `g`, under a constant
/// environment of radiance 1, counting paths with at most one scattering event:
///
/// L = T(ℓ) + ∫₀^ℓ σ_s e^{−σ_s s} ∫_{S²} p(u · d) e^{−σ_s b(x_s, u)} du ds,
///
/// with ℓ the chord, x_s = entry + s·d, b(x, u) the distance from x to the box's surface along u (the light
/// arrives from the environment in direction u), and p(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}),
/// θ the angle between the light's propagation (−u) and the scattered light's (−d): forward scattering sees
/// the environment behind x. Evaluated by Gauss–Legendre quadrature in s and in cos θ about d, and the
/// (periodic) trapezoid rule in azimuth: a reference independent of the renderer's sampling.
fn single_scattering_radiance(origin: DVec3, d: DVec3, sigma_s: f64, g: f64) -> f64 {
    let entry = origin + d * ((1.0 - origin.z) / d.z);
    let chord = distance_out_of_box(entry, d);
    let e1 = d.any_orthonormal_vector();
    let e2 = d.cross(e1);
    let (along, cosines, azimuths) = (gauss_legendre(24), gauss_legendre(48), 96);
    let mut scattered = 0.0;
    for &(xs, ws) in &along {
        let s = 0.5 * chord * (xs + 1.0);
        let x = entry + d * s;
        let mut inscattered = 0.0;
        for &(c, wc) in &cosines {
            let r = (1.0 - c * c).sqrt();
            let ring: f64 = (0..azimuths)
                .map(|k| {
                    let phi = 2.0 * PI * k as f64 / azimuths as f64;
                    let u = d * c + (e1 * phi.cos() + e2 * phi.sin()) * r;
                    (-sigma_s * distance_out_of_box(x, u)).exp()
                })
                .sum::<f64>()
                * (2.0 * PI / azimuths as f64);
            inscattered += wc * henyey_greenstein(g, c) * ring;
        }
        scattered += 0.5 * chord * ws * sigma_s * (-sigma_s * s).exp() * inscattered;
    }
    (-sigma_s * chord).exp() + scattered
}

#[test]
fn single_scattering_slab_matches_closed_form_in_depth_one() {
    // max_depth 1 through a grey scattering box (σ_s = 0.5, g = 0.3) under a constant environment: what
    // reaches the camera is the unscattered environment plus single scattering, whose expectation over the
    // film is the quadrature of `single_scattering_radiance` at every pixel's centre (the radiance varies
    // smoothly over a pixel: the midpoint rule's error is far below the tolerance).
    let (sigma_s, g, size) = (0.5f32, 0.3, 8);
    let b = box_scene(Rgb::ZERO, Rgb::splat(sigma_s), Rgb::ONE, 10.0);
    let camera = b.camera().cloned().unwrap();
    let (img, _) = render(b, size, 256, 1);
    let mut truth = 0.0;
    for y in 0..size {
        for x in 0..size {
            let film = nimbus::math::Vec2::new(
                (x as f32 + 0.5) / size as f32,
                (y as f32 + 0.5) / size as f32,
            );
            let ray = camera.generate_ray(film, 1.0);
            truth += single_scattering_radiance(
                ray.origin.as_dvec3(),
                ray.dir.as_dvec3().normalize(),
                sigma_s as f64,
                g,
            );
        }
    }
    truth /= (size * size) as f64;
    let transmitted = (-2.0 * sigma_s as f64).exp();
    assert!(
        truth > transmitted + 0.1,
        "single scattering is a large part: {truth}"
    );
    for c in 0..3 {
        let (mean, se) = common::mean_and_se(&img, c);
        assert!(
            (mean - truth).abs() < 4.0 * se + 1e-4,
            "channel {c}: {mean} vs {truth} (se {se})"
        );
    }
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

/// The distance from `x` inside the box [−1, 1]³ to its boundary along the unit direction `u`, slab by slab.
fn distance_out_of_box(x: DVec3, u: DVec3) -> f64 {
    (0..3)
        .filter(|&i| u[i] != 0.0)
        .map(|i| ((u[i].signum() - x[i]) / u[i]).max(0.0))
        .fold(f64::INFINITY, f64::min)
}

/// The Henyey–Greenstein phase function at deflection cosine `mu`.
fn henyey_greenstein(g: f64, mu: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// Midpoint quadrature of the single scattering seen along the ray from z = 1 to z = −1 through the box
/// [−1, 1]³ (toward a camera on +z): L_c = ∫₀² σ_s,c e^{−σ_t,c (s + r(x))} w(x) E_c ds at x = (0, 0, 1 − s), where
/// `light_at(x)` gives r(x), the distance the light travels inside the medium to x, and w(x), the phase function
/// toward the camera times the light's falloff (1/r² for a point light, 1 for the sun), and E is `emitted`.
fn single_scattering_quadrature(
    sigma_a: Rgb,
    sigma_s: Rgb,
    emitted: Rgb,
    light_at: impl Fn(DVec3) -> (f64, f64),
) -> [f64; 3] {
    let sigma_t = sigma_a + sigma_s;
    let steps = 400_000;
    let mut truth = [0.0f64; 3];
    for i in 0..steps {
        let s = (i as f64 + 0.5) / steps as f64 * 2.0;
        let (r, w) = light_at(DVec3::new(0.0, 0.0, 1.0 - s));
        for c in 0..3 {
            truth[c] += sigma_s[c] as f64
                * (-(sigma_t[c] as f64) * (s + r)).exp()
                * w
                * emitted[c] as f64
                * (2.0 / steps as f64);
        }
    }
    truth
}

/// Renders the one pixel of [`single_scattering_quadrature`]'s ray (a camera on +z with a tiny field of view,
/// 40,000 spp, max depth 1) through the homogeneous box lit by `light` alone, with the in-medium sampling of
/// `settings`, and checks each channel's mean within 4 standard errors of `truth`. Returns the statistics and
/// the image's variance (the sum of the channels' squared standard errors).
fn render_single_scattering(
    label: &str,
    medium: HomogeneousMedium,
    light: nimbus::light::Light,
    settings: nimbus::render::RenderSettings,
    truth: [f64; 3],
) -> (RenderStats, f64) {
    let mut b = SceneBuilder::default();
    let medium = b.add_medium(Arc::new(medium));
    common::fill_box(&mut b, medium, Vec3::splat(-1.0), Vec3::splat(1.0));
    b.add_light(light);
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::ZERO,
        0.001f32.to_radians(),
    ));
    let settings = nimbus::render::RenderSettings {
        width: 1,
        height: 1,
        spp: 40_000,
        threads: 2,
        max_depth: 1,
        ..settings
    };
    let (img, stats) = nimbus::render::Renderer::new(settings)
        .render(&b.build().unwrap(), &mut |_| true)
        .unwrap();
    let mut variance = 0.0;
    for (c, &expected) in truth.iter().enumerate() {
        let (mean, se) = common::mean_and_se(&img, c);
        eprintln!("{label} channel {c}: {mean:.6} ± {se:.6} vs {expected:.6}");
        assert!(
            (mean - expected).abs() < 4.0 * se,
            "{label} channel {c}: {mean} vs {expected} (se {se})"
        );
        variance += se * se;
    }
    (stats, variance)
}

/// Single scattering of a point light inside a homogeneous box, seen along one ray, against the quadrature of
/// its closed-form integrand L = ∫ σ_s e^{−σ_t s} ρ_HG(μ(s)) I e^{−σ_t r(s)} / r(s)² ds (max depth 1, no other
/// light). Distance sampling alone, equiangular sampling MIS'd with it, and each with the decoupled sample on
/// (which serves the point light in place of next-event estimation at the collision when equiangular sampling
/// is off, and leaves it to equiangular sampling when on) must match; equiangular sampling must also cut the
/// variance, as it exists to, and so must the decoupled sample against distance sampling alone. Grey and
/// chromatic media (the chromatic one exercises the spectral-MIS free-flight densities in the MIS weights and
/// the decoupled sample's channel mixture).
#[test]
fn single_scattering_of_a_point_light_matches_quadrature() {
    use nimbus::light::{Light, PointLight};
    let light = Vec3::new(0.25, 0.1, -0.3);
    let intensity = Rgb::new(2.0, 1.5, 1.0);
    let g = 0.4;
    for (label, sigma_a, sigma_s) in [
        ("grey", Rgb::splat(0.2), Rgb::splat(0.6)),
        (
            "chromatic",
            Rgb::new(0.1, 0.3, 0.6),
            Rgb::new(0.5, 0.4, 0.3),
        ),
    ] {
        let truth = single_scattering_quadrature(sigma_a, sigma_s, intensity, |x| {
            let to_light = light.as_dvec3() - x;
            let r = to_light.length();
            // Deflection cosine between the light's travel (from the light to x) and the camera's direction (+z).
            let mu = -to_light.z / r;
            (r, henyey_greenstein(g, mu) / (r * r))
        });
        let mut variances = Vec::new();
        for (equiangular, decoupled) in [(false, false), (true, false), (false, true), (true, true)]
        {
            let name = format!("{label} equiangular={equiangular} decoupled={decoupled}");
            let (stats, variance) = render_single_scattering(
                &name,
                HomogeneousMedium::new("box", sigma_a, sigma_s, g as f32),
                Light::Point(PointLight {
                    position: light,
                    intensity,
                }),
                nimbus::render::RenderSettings {
                    seed: 5,
                    equiangular,
                    decoupled,
                    ..Default::default()
                },
                truth,
            );
            assert_eq!(stats.rays.equiangular > 0, equiangular, "{name}");
            // With equiangular sampling on, the point light is its to serve, not the decoupled sample's.
            assert_eq!(
                stats.rays.decoupled > 0,
                decoupled && !equiangular,
                "{name}"
            );
            variances.push(variance);
        }
        eprintln!("{label}: variances distance, MIS, decoupled, decoupled with MIS {variances:?}");
        assert!(variances[1] * 2.0 < variances[0], "{label}: {variances:?}");
        assert!(variances[2] * 1.3 < variances[0], "{label}: {variances:?}");
    }
}

/// Single scattering of the sun (a directional light) in a homogeneous box, seen along one ray, against the
/// quadrature of L = ∫ σ_s e^{−σ_t s} ρ_HG(μ) E e^{−σ_t r(s)} ds, r(s) the distance from the ray's point at s to
/// the box's boundary toward the sun (max depth 1, no other light). With and without the decoupled direct-light
/// sample (a distance from the free-flight density truncated to the segment, in place of next-event estimation
/// at the collision); in this thin box (optical depth 0.8 along the ray) the decoupled sample must also cut the
/// variance, since every path estimates the direct light where only the 1 − e^{−0.8} = 55% that collide did.
/// Grey and chromatic media.
#[test]
fn single_scattering_of_the_sun_matches_quadrature() {
    use nimbus::light::{DirectionalLight, Light};
    // The direction the light travels in: toward −x, down, and toward the camera.
    let travel = Vec3::new(-1.0, -0.5, 0.3).normalize();
    let irradiance = Rgb::new(2.0, 1.5, 1.0);
    let g = 0.3;
    for (label, sigma_a, sigma_s) in [
        ("grey", Rgb::splat(0.1), Rgb::splat(0.3)),
        (
            "chromatic",
            Rgb::new(0.05, 0.2, 0.4),
            Rgb::new(0.4, 0.3, 0.2),
        ),
    ] {
        let to_sun = -travel.as_dvec3();
        // Deflection cosine between the light's travel and the camera's direction (+z): the same everywhere.
        let phase = henyey_greenstein(g, travel.as_dvec3().z);
        let truth = single_scattering_quadrature(sigma_a, sigma_s, irradiance, |x| {
            (distance_out_of_box(x, to_sun), phase)
        });
        let mut variances = Vec::new();
        for decoupled in [false, true] {
            let name = format!("{label} decoupled={decoupled}");
            let (stats, variance) = render_single_scattering(
                &name,
                HomogeneousMedium::new("box", sigma_a, sigma_s, g as f32),
                Light::Directional(DirectionalLight {
                    direction: travel,
                    irradiance,
                }),
                nimbus::render::RenderSettings {
                    seed: 9,
                    decoupled,
                    ..Default::default()
                },
                truth,
            );
            assert_eq!(stats.rays.decoupled > 0, decoupled, "{name}");
            variances.push(variance);
        }
        eprintln!("{label}: variances without, with the decoupled sample {variances:?}");
        assert!(variances[1] * 1.5 < variances[0], "{label}: {variances:?}");
    }
}

/// Single scattering of the sun through a slit: the homogeneous box of
/// [`single_scattering_of_the_sun_matches_quadrature`] behind a black wall at x = 1.5 with a 0.2 m gap, so the
/// sun lights the camera's ray only over 0.35 < z < 0.55 (a tenth of it), against the quadrature of the same
/// integral with that visibility. Unguided and guided (`--guiding on`: the decoupled samples' distances from the
/// mixture with the training's lit grid) must both match within 4 standard errors, and the guided distances must
/// cut the variance (most unguided decoupled samples land in the wall's shadow). 16² pixels of the same ray
/// (a field of view of 0.001°), so that the training has 1,792 paths to learn the lit interval from.
#[test]
fn single_scattering_of_the_sun_through_a_slit_matches_quadrature_guided() {
    use nimbus::light::{DirectionalLight, Light};
    use nimbus::render::GuidingMode;
    let travel = Vec3::new(-1.0, -0.5, 0.3).normalize();
    let irradiance = Rgb::new(2.0, 1.5, 1.0);
    let (g, sigma_a, sigma_s) = (0.3, Rgb::splat(0.1), Rgb::splat(0.3));
    let to_sun = -travel.as_dvec3();
    let phase = henyey_greenstein(g, travel.as_dvec3().z);
    // Where the ray from x toward the sun crosses the wall's plane x = 1.5: lit through the gap |z| < 0.1.
    let lit = |x: DVec3| {
        let at_wall = x + to_sun * ((1.5 - x.x) / to_sun.x);
        at_wall.z.abs() < 0.1
    };
    let truth = single_scattering_quadrature(sigma_a, sigma_s, irradiance, |x| {
        (
            distance_out_of_box(x, to_sun),
            if lit(x) { phase } else { 0.0 },
        )
    });
    let mut variances = Vec::new();
    for guiding in [GuidingMode::Off, GuidingMode::On] {
        let mut b = SceneBuilder::default();
        let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
            "box", sigma_a, sigma_s, g as f32,
        )));
        common::fill_box(&mut b, medium, Vec3::splat(-1.0), Vec3::splat(1.0));
        let black = b.add_material(nimbus::material::Material::lambertian("wall", Vec3::ZERO));
        for (z0, z1) in [(-3.0, -0.1), (0.1, 3.0)] {
            let corner = |y: f32, z: f32| Vec3::new(1.5, y, z);
            b.add_mesh(common::quad(
                [
                    corner(-3.0, z0),
                    corner(3.0, z0),
                    corner(3.0, z1),
                    corner(-3.0, z1),
                ],
                black,
            ));
        }
        b.add_light(Light::Directional(DirectionalLight {
            direction: travel,
            irradiance,
        }));
        b.set_camera(Camera::look_at(
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            0.001f32.to_radians(),
        ));
        let settings = nimbus::render::RenderSettings {
            width: 16,
            height: 16,
            spp: 160,
            threads: 2,
            max_depth: 1,
            seed: 13,
            guiding,
            ..Default::default()
        };
        let (img, stats) = nimbus::render::Renderer::new(settings)
            .render(&b.build().unwrap(), &mut |_| true)
            .unwrap();
        assert!(stats.rays.decoupled > 0, "{guiding:?}");
        let mut variance = 0.0;
        for (c, &expected) in truth.iter().enumerate() {
            let (mean, se) = common::mean_and_se(&img, c);
            eprintln!(
                "slit, guiding {guiding:?}, channel {c}: {mean:.6} ± {se:.6} vs {expected:.6}"
            );
            assert!(
                (mean - expected).abs() < 4.0 * se,
                "guiding {guiding:?} channel {c}: {mean} vs {expected} (se {se})"
            );
            variance += se * se;
        }
        variances.push(variance);
    }
    eprintln!("slit: variances unguided, guided {variances:?}");
    assert!(variances[1] * 2.0 < variances[0], "{variances:?}");
}
