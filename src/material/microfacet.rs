//! The GGX (Trowbridge–Reitz) microfacet distribution, isotropic or anisotropic: normal distribution D, Smith
//! masking Λ, G1 and the height-correlated G2, and exact sampling of the distribution of visible normals.
//!
//! Directions are in the local frame of the distribution: z = macro normal, x the direction of width `alpha_x`,
//! y that of width `alpha_y`. Microfacet normals always lie in the upper hemisphere; callers that look from
//! below mirror their directions first. With `alpha_x == alpha_y` every formula is the isotropic one.

use crate::math::{Vec2, Vec3};
use std::f32::consts::PI;

/// Below this GGX α a lobe is treated as perfectly smooth, i.e. a delta distribution.
pub const DELTA_ALPHA: f32 = 1e-4;

/// GGX distribution with widths `alpha_x` and `alpha_y` along the frame's x and y axes (α = perceptual
/// roughness², glTF 2.0 Appendix B; the anisotropic widths of `KHR_materials_anisotropy`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// GGX width along x (not below [`DELTA_ALPHA`] for a meaningful distribution).
    pub alpha_x: f32,
    /// GGX width along y (not below [`DELTA_ALPHA`] for a meaningful distribution).
    pub alpha_y: f32,
}

impl Ggx {
    /// The isotropic distribution of width `alpha` along both axes.
    pub fn isotropic(alpha: f32) -> Self {
        Self {
            alpha_x: alpha,
            alpha_y: alpha,
        }
    }

    /// Normal distribution `D(m) = 1 / (π αx αy (mx²/αx² + my²/αy² + mz²)²)` (the anisotropic GGX of Heitz
    /// 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2); for αx = αy it
    /// is Walter et al. 2007, "Microfacet Models for Refraction through Rough Surfaces", eq. 33), in this form to
    /// keep precision for small α. Zero for `m.z <= 0`.
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let t = m.x * m.x / (ax * ax) + m.y * m.y / (ay * ay) + m.z * m.z;
        1.0 / (PI * ax * ay * t * t)
    }

    /// Smith's auxiliary function for GGX, `Λ(ω) = (−1 + √(1 + α(φ)² tan²θ)) / 2` with
    /// `α(φ)² tan²θ = (αx² ωx² + αy² ωy²) / ωz²` (Heitz 2014: the GGX Λ of an anisotropic distribution is
    /// the isotropic one with the roughness projected on ω's azimuth, `α(φ)² = cos²φ αx² + sin²φ αy²`).
    pub fn lambda(&self, w: Vec3) -> f32 {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let s2 = ax * ax * w.x * w.x + ay * ay * w.y * w.y;
        if s2 <= 0.0 {
            return 0.0;
        }
        let a2_tan2 = s2 / (w.z * w.z);
        0.5 * ((1.0 + a2_tan2).sqrt() - 1.0)
    }

    /// Smith masking `G1(ω) = 1 / (1 + Λ(ω))` (Smith 1967; Heitz 2014, the Smith masking function).
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated Smith masking-shadowing `G2(ωo, ωi) = 1 / (1 + Λ(ωo) + Λ(ωi))` (Heitz 2014, the height-correlated
    /// masking-shadowing function).
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normals seen from `wo` (`wo.z > 0`), `D_wo(m) = G1(wo) max(0, wo·m) D(m) / wo.z`
    /// (Heitz 2014, the distribution of visible normals; Heitz 2018, "Sampling the GGX Distribution of Visible
    /// Normals", JCGT 7(4), §2): the
    /// solid-angle density of [`Ggx::sample_visible`].
    pub fn pdf_visible(&self, wo: Vec3, m: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(m).max(0.0) * self.d(m) / wo.z
    }

    /// Samples a microfacet normal from the distribution of visible normals for `wo` (`wo.z > 0`), exactly, by
    /// the method of Heitz 2018 (JCGT 7(4), its sampling routine): stretch `wo` by (αx, αy) to the α = 1
    /// configuration, sample the projected hemisphere as a disk warped toward its visible half, lift to the
    /// hemisphere and unstretch the normal (scale by (αx, αy, 1), normalise).
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let (ax, ay) = (self.alpha_x, self.alpha_y);
        let vh = Vec3::new(ax * wo.x, ay * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 {
            Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
        } else {
            Vec3::X
        };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        Vec3::new(ax * nh.x, ay * nh.y, nh.z.max(0.0)).normalize_or(Vec3::Z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{chi2, sampling, Rng};

    #[test]
    fn projected_area_of_the_microsurface_is_one() {
        // ∫ D(m) cos θm dm = 1 and ∫ D_wo(m) dm = 1, by uniform-sphere Monte Carlo within 4 standard errors.
        for alpha in [0.2f32, 0.5, 1.0] {
            let ggx = Ggx::isotropic(alpha);
            let wo = Vec3::new(0.6, 0.0, 0.8);
            let mut rng = Rng::new(11, alpha.to_bits() as u64);
            let n = 400_000;
            for f in [&(|m: Vec3| ggx.d(m) * m.z) as &dyn Fn(Vec3) -> f32, &|m| {
                ggx.pdf_visible(wo, m)
            }] {
                let (mut s, mut s2) = (0.0f64, 0.0f64);
                for _ in 0..n {
                    let v = (f(sampling::uniform_sphere(rng.next_2d()))
                        / sampling::UNIFORM_SPHERE_PDF) as f64;
                    s += v;
                    s2 += v * v;
                }
                let mean = s / n as f64;
                let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
                assert!(
                    (mean - 1.0).abs() < 4.0 * se,
                    "alpha {alpha}: {mean} ± {se}"
                );
            }
        }
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn chi2_detects_a_slightly_wrong_density() {
        // Power check: samples for α = 0.5 against the density of α = 0.55 must be rejected.
        let wo = Vec3::new(0.8, 0.0, 0.6);
        let (sampled, claimed) = (Ggx::isotropic(0.5), Ggx::isotropic(0.55));
        chi2::assert_sampler_fits(
            "GGX visible normals with a wrong alpha",
            100_000,
            77,
            |rng| Some(sampled.sample_visible(wo, rng.next_2d())),
            |m| claimed.pdf_visible(wo, m) as f64,
        );
    }

    #[test]
    fn visible_normal_sampling_chi2() {
        for (k, alpha) in [0.1f32, 0.5, 1.0].into_iter().enumerate() {
            let ggx = Ggx::isotropic(alpha);
            let wo = Vec3::new(0.8, 0.0, 0.6);
            chi2::assert_sampler_fits(
                &format!("GGX visible normals alpha {alpha}"),
                100_000,
                k as u64,
                |rng| Some(ggx.sample_visible(wo, rng.next_2d())),
                |m| ggx.pdf_visible(wo, m) as f64,
            );
        }
    }

    /// Strongly and mildly anisotropic widths and view directions (off both axes, near an axis, grazing) of
    /// the anisotropic tests.
    fn anisotropic_cases() -> Vec<(Ggx, Vec3)> {
        let dir = |theta: f32, phi: f32| {
            Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
        };
        vec![
            (
                Ggx {
                    alpha_x: 0.05,
                    alpha_y: 0.5,
                },
                dir(0.9, 0.5),
            ),
            (
                Ggx {
                    alpha_x: 0.5,
                    alpha_y: 0.05,
                },
                dir(0.9, 0.5),
            ),
            (
                Ggx {
                    alpha_x: 1.0,
                    alpha_y: 0.1,
                },
                dir(1.4, 2.0),
            ),
            (
                Ggx {
                    alpha_x: 0.1,
                    alpha_y: 1.0,
                },
                dir(0.3, -1.0),
            ),
            (
                Ggx {
                    alpha_x: 0.3,
                    alpha_y: 0.6,
                },
                dir(1.2, 0.0),
            ),
            (
                Ggx {
                    alpha_x: 0.02,
                    alpha_y: 0.4,
                },
                dir(0.6, 1.5),
            ),
        ]
    }

    /// `∫ f(m) dm` over the upper hemisphere by the midpoint rule in `(t, φ)` with `tan θ = k t / (1 − t)`,
    /// `k = √(αx αy)`: the substitution spreads the lobe and its slowly falling tail over the unit interval.
    fn hemisphere_integral(ggx: &Ggx, nt: usize, nphi: usize, f: impl Fn(Vec3) -> f64) -> f64 {
        let k = ((ggx.alpha_x * ggx.alpha_y) as f64).sqrt();
        let mut sum = 0.0;
        for i in 0..nt {
            let t = (i as f64 + 0.5) / nt as f64;
            let rho = k * t / (1.0 - t);
            let drho_dt = k / ((1.0 - t) * (1.0 - t));
            let theta = rho.atan();
            // dω = sin θ dθ dφ, dθ = dρ / (1 + ρ²).
            let jac = theta.sin() / (1.0 + rho * rho) * drho_dt;
            let mut ring = 0.0;
            for j in 0..nphi {
                let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / nphi as f64;
                let m = Vec3::new(
                    (theta.sin() * phi.cos()) as f32,
                    (theta.sin() * phi.sin()) as f32,
                    theta.cos() as f32,
                );
                ring += f(m);
            }
            sum += ring * jac;
        }
        sum * (1.0 / nt as f64) * (2.0 * std::f64::consts::PI / nphi as f64)
    }

    #[test]
    fn anisotropic_distribution_is_normalised_and_its_projected_area_is_cos_theta_o() {
        // ∫ D(m) cos θm dm = 1 and ∫ G1(wo) max(0, wo·m) D(m) dm = cos θo (Heitz 2014: the projected areas of
        // the microsurface and of its visible part are those of the macrosurface), by deterministic quadrature.
        for (ggx, wo) in anisotropic_cases() {
            let norm = hemisphere_integral(&ggx, 4096, 512, |m| (ggx.d(m) * m.z) as f64);
            let g1 = ggx.g1(wo) as f64;
            let projected = g1
                * hemisphere_integral(&ggx, 4096, 512, |m| (wo.dot(m).max(0.0) * ggx.d(m)) as f64);
            eprintln!(
                "alpha ({}, {}), wo {wo}: ∫D cos = {norm:.7}, ∫G1 (wo·m)+ D = {projected:.7} vs cos θo {:.7}",
                ggx.alpha_x, ggx.alpha_y, wo.z
            );
            assert!((norm - 1.0).abs() < 1e-4, "{ggx:?}: ∫ D cos θm = {norm}");
            assert!(
                (projected - wo.z as f64).abs() < 1e-4,
                "{ggx:?}, wo {wo}: projected area {projected}, cos θo {}",
                wo.z
            );
        }
    }

    #[test]
    fn isotropic_widths_give_the_isotropic_formulas() {
        // With αx = αy the anisotropic D and Λ are the isotropic closed forms (Walter et al. 2007, eq. 33;
        // Heitz 2014's GGX Λ) at every azimuth.
        let a = 0.3f32;
        let ggx = Ggx::isotropic(a);
        for (theta, phi) in [(0.2f32, 0.0f32), (0.7, 1.0), (1.3, -2.5)] {
            let w = Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let tan2 = theta.tan() * theta.tan();
            let d = a * a / (PI * theta.cos().powi(4) * (a * a + tan2).powi(2));
            let lambda = 0.5 * ((1.0 + a * a * tan2).sqrt() - 1.0);
            assert!((ggx.d(w) - d).abs() <= 1e-5 * d, "D {} vs {d}", ggx.d(w));
            assert!((ggx.lambda(w) - lambda).abs() <= 1e-5 * lambda.max(1e-3));
        }
    }

    #[test]
    fn anisotropic_visible_normal_sampling_chi2() {
        for (k, (ggx, wo)) in anisotropic_cases().into_iter().enumerate() {
            chi2::assert_sampler_fits(
                &format!("anisotropic GGX visible normals {ggx:?} wo {wo}"),
                200_000,
                100 + k as u64,
                |rng| Some(ggx.sample_visible(wo, rng.next_2d())),
                |m| ggx.pdf_visible(wo, m) as f64,
            );
        }
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn chi2_detects_swapped_anisotropic_axes() {
        // Power check: samples of (0.2, 0.6) against the density of (0.6, 0.2) must be rejected.
        let wo = Vec3::new(0.5, 0.3, 0.81).normalize();
        let sampled = Ggx {
            alpha_x: 0.2,
            alpha_y: 0.6,
        };
        let claimed = Ggx {
            alpha_x: 0.6,
            alpha_y: 0.2,
        };
        chi2::assert_sampler_fits(
            "GGX visible normals with swapped axes",
            100_000,
            78,
            |rng| Some(sampled.sample_visible(wo, rng.next_2d())),
            |m| claimed.pdf_visible(wo, m) as f64,
        );
    }
}
