//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution: normal distribution D, Smith masking Λ,
//! G1 and the height-correlated G2, and exact sampling of the distribution of visible normals.
//!
//! Directions are in the local shading frame (z = macro normal). Microfacet normals always lie in the upper
//! hemisphere; callers that look from below mirror their directions first.

use crate::math::{Vec2, Vec3};
use std::f32::consts::PI;

/// Below this GGX α a lobe is treated as perfectly smooth, i.e. a delta distribution.
pub const DELTA_ALPHA: f32 = 1e-4;

/// Isotropic GGX distribution with width `alpha` (α = perceptual roughness², glTF 2.0 Appendix B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// GGX width α (not below [`DELTA_ALPHA`] for a meaningful distribution).
    pub alpha: f32,
}

impl Ggx {
    /// Normal distribution `D(m) = α² / (π cos⁴θm (α² + tan²θm)²)` (Walter et al. 2007, "Microfacet Models for
    /// Refraction through Rough Surfaces", eq. 33), evaluated as `1 / (π α² (cos²θm + sin²θm/α²)²)` to keep
    /// precision for small α. Zero for `m.z <= 0`.
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = (m.x * m.x + m.y * m.y) / a2 + m.z * m.z;
        1.0 / (PI * a2 * t * t)
    }

    /// Smith's auxiliary function for GGX, `Λ(ω) = (−1 + √(1 + α² tan²θ)) / 2` (Heitz 2014, "Understanding the
    /// Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2), its closed form for GGX). Depends
    /// only on |tan θ|.
    pub fn lambda(&self, w: Vec3) -> f32 {
        let s2 = w.x * w.x + w.y * w.y;
        if s2 <= 0.0 {
            return 0.0;
        }
        let a2_tan2 = self.alpha * self.alpha * s2 / (w.z * w.z);
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
    /// the method of Heitz 2018 (JCGT 7(4)): stretch `wo` to the α = 1 configuration, sample the projected
    /// hemisphere as a disk warped toward its visible half, lift to the hemisphere and unstretch.
    pub fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
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
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize_or(Vec3::Z)
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
            let ggx = Ggx { alpha };
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
        let (sampled, claimed) = (Ggx { alpha: 0.5 }, Ggx { alpha: 0.55 });
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
            let ggx = Ggx { alpha };
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
}
