//! The glTF metallic-roughness metal lobe in a white furnace, against a table of its directional albedo
//! computed here by quadrature.
//!
//! A metal plane (glTF: `metallic` 1, `baseColor` c, perceptual roughness r) seen from the angle θo under a
//! constant environment of radiance 1, with one bounce, reflects exactly its directional albedo
//! E(θo) = ∫ f(ωo, ωi) cos θi dωi. The table is a quadrature of the glTF 2.0 specification's formulas (Appendix B:
//! the GGX distribution D with α = r², the height-correlated Smith visibility, Schlick's Fresnel with F0 = c),
//! written here independently of the renderer's BSDF code. The render exercises everything the quadrature does
//! not: BSDF sampling, its pdf, light sampling of the environment and their multiple importance sampling.

use crate::common;

use nimbus::light::EnvironmentLight;
use nimbus::math::{Rgb, Vec3};
use nimbus::{Camera, Material, SceneBuilder};
use std::f64::consts::PI;

/// Smith's Λ for GGX (Heitz 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs").
fn smith_lambda(cos: f64, alpha: f64) -> f64 {
    let tan2 = (1.0 - cos * cos).max(0.0) / (cos * cos);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// ∫∫ `integrand(ωo·h, cos θi)` / (μo cos θh) over half vectors h drawn from D(h) cos θh, for ωo at cos θo = `mu_o`,
/// restricted to ωo·h > 0 and, with `above_horizon`, to reflected directions above the surface (cos θi > 0).
///
/// With h drawn from D(h)·cos θh (u ∈ [0, 1): tan²θh = α²·u/(1 − u); φ uniform), dωi = 4 (ωo·h) dωh turns
/// f cos θi dωi = F·D·G2/(4 μo μi) · μi dωi into F·G2·(ωo·h)/(μo cos θh) · D cos θh dωh. The substitution
/// u = 1 − s² removes the integrable 1/cos θh singularity at u → 1, and on each ring of θh the allowed φ form one
/// interval |φ| < φmax found in closed form, so the midpoint rule integrates smooth functions only.
fn half_vector_quadrature(
    mu_o: f64,
    alpha: f64,
    above_horizon: bool,
    integrand: impl Fn(f64, f64) -> f64,
) -> f64 {
    let sin_o = (1.0 - mu_o * mu_o).max(0.0).sqrt();
    let (ns, nphi) = (2000, 200);
    let mut sum = 0.0;
    for i in 0..ns {
        let s = (i as f64 + 0.5) / ns as f64;
        let u = 1.0 - s * s;
        let tan2 = alpha * alpha * u / (1.0 - u);
        let cos_h = 1.0 / (1.0 + tan2).sqrt();
        let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
        // ωo·h = sin_o sin_h cos φ + μo cos_h > 0, and cos θi = 2 (ωo·h) cos_h − μo > 0.
        let phi_max = if sin_o * sin_h == 0.0 {
            let valid = mu_o * cos_h > 0.0 && (!above_horizon || 2.0 * cos_h * cos_h > 1.0);
            if valid {
                PI
            } else {
                continue;
            }
        } else {
            let mut c = -mu_o * cos_h / (sin_o * sin_h);
            if above_horizon {
                c = c.max(mu_o * (1.0 - 2.0 * cos_h * cos_h) / (2.0 * sin_o * sin_h * cos_h));
            }
            if c >= 1.0 {
                continue;
            }
            c.max(-1.0).acos()
        };
        let mut ring = 0.0;
        for j in 0..nphi {
            let phi = -phi_max + 2.0 * phi_max * (j as f64 + 0.5) / nphi as f64;
            let o_dot_h = sin_o * sin_h * phi.cos() + mu_o * cos_h;
            let mu_i = 2.0 * o_dot_h * cos_h - mu_o;
            ring += integrand(o_dot_h, mu_i) / (mu_o * cos_h);
        }
        // du = 2s ds; the φ interval is 2 φmax of the full 2π.
        sum += 2.0 * s * ring * (2.0 * phi_max) / (2.0 * PI * nphi as f64);
    }
    sum / ns as f64
}

/// Directional albedo of the glTF metal lobe at cos θo = `mu_o`: ∫ F·G2·(ωo·h)/(μo cos θh) over D(h) cos θh.
fn directional_albedo(mu_o: f64, alpha: f64, f0: f64) -> f64 {
    let lambda_o = smith_lambda(mu_o, alpha);
    half_vector_quadrature(mu_o, alpha, true, |o_dot_h, mu_i| {
        let g2 = 1.0 / (1.0 + lambda_o + smith_lambda(mu_i.max(1e-12), alpha));
        let fresnel = f0 + (1.0 - f0) * (1.0 - o_dot_h).powi(5);
        fresnel * g2 * o_dot_h
    })
}

#[test]
fn metal_lobe_in_a_furnace_reflects_its_directional_albedo() {
    let mut failures = Vec::new();
    let mut seed = 0;
    println!("| roughness | base colour | θo | render | ± s.e. | quadrature |");
    for &roughness in &[0.25f32, 0.5, 1.0] {
        for &base in &[1.0f32, 0.4] {
            for &theta_deg in &[0.0f32, 40.0, 70.0, 85.0] {
                let mut b = SceneBuilder::default();
                let mut metal = Material::lambertian("metal", Rgb::splat(base));
                metal.metallic = 1.0;
                metal.roughness = roughness;
                metal.specular_factor = 1.0;
                let m = b.add_material(metal);
                let s = 100.0;
                b.add_mesh(common::quad(
                    [
                        Vec3::new(-s, 0.0, -s),
                        Vec3::new(-s, 0.0, s),
                        Vec3::new(s, 0.0, s),
                        Vec3::new(s, 0.0, -s),
                    ],
                    m,
                ));
                b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
                let theta = theta_deg.to_radians();
                let eye = Vec3::new(theta.sin(), theta.cos(), 0.0);
                // A narrow view of the plane's centre: every pixel sees it from θo to within 0.05°.
                b.set_camera(Camera::look_at(eye, Vec3::ZERO, 0.1f32.to_radians()));
                // Each case its own seed, so that the cases' errors are independent.
                seed += 1;
                let (img, stats) = common::render_square(b, 8, 1024, 1, seed);
                assert_eq!(stats.nan_samples, 0);
                let (mean, se) = common::mean_and_se(&img, 0);
                let expected = directional_albedo(
                    theta.cos() as f64,
                    (roughness * roughness) as f64,
                    base as f64,
                );
                let ok = (mean - expected).abs() <= 4.0 * se + 1e-4 * expected;
                println!(
                    "| {roughness} | {base} | {theta_deg}° | {mean:.5} | {se:.5} | {expected:.5} |{}",
                    if ok { "" } else { " FAIL" }
                );
                if !ok {
                    failures.push(format!(
                        "roughness {roughness}, base {base}, θo {theta_deg}°: {mean} ± {se}, quadrature {expected}"
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn quadrature_integrates_the_visible_normals_to_one() {
    // The distribution of visible normals is normalised: ∫ G1(ωo) max(0, ωo·h) D(h) / μo dωh = 1 (Heitz 2014),
    // at every angle and roughness; this checks the quadrature itself, to 1e-4.
    for &alpha in &[0.01f64, 0.0625, 0.25, 1.0] {
        for &mu_o in &[1.0f64, 0.7, 0.3, 0.087] {
            let g1 = 1.0 / (1.0 + smith_lambda(mu_o, alpha));
            let total = half_vector_quadrature(mu_o, alpha, false, |o_dot_h, _| g1 * o_dot_h);
            assert!(
                (total - 1.0).abs() < 1e-4,
                "alpha {alpha} mu {mu_o}: {total}"
            );
        }
    }
    // A nearly smooth white metal reflects everything.
    assert!((directional_albedo(0.8, 1e-3, 1.0) - 1.0).abs() < 1e-3);
}
