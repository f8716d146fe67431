//! Phase functions: isotropic and Henyey–Greenstein.
//!
//! Parameters (volume extras): `g`, the Henyey–Greenstein anisotropy in (−1, 1); 0 is isotropic, g > 0 forward
//! scattering. Values are clamped to \[−0.999, 0.999\].
//!
//! Convention: `wo` points away from the scattering point toward where the light goes (toward the camera,
//! `-ray.dir`), `wi` points away toward the light. Light travels along `-wi` and leaves along `wo`, so the
//! scattering angle θ has `cos θ = -wo·wi`, and forward scattering peaks at `wi = -wo`.

use crate::math::{Frame, Vec2, Vec3};
use std::f32::consts::PI;

/// Anisotropies below this magnitude are sampled as isotropic (the inversion formula divides by g); there
/// HG differs from isotropic by under 3·10⁻⁶ relative, below f32 resolution.
const ISOTROPIC_G: f64 = 1e-6;

/// A phase function; every variant is normalised over the sphere and sampled exactly (value == pdf).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PhaseFunction {
    /// `p = 1/(4π)`.
    Isotropic,
    /// Henyey & Greenstein 1941, "Diffuse radiation in the Galaxy" (ApJ 93, 70–83), their phase function:
    /// `p(θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2})`.
    HenyeyGreenstein {
        /// Mean cosine of the scattering angle, in (−1, 1).
        g: f32,
    },
}

/// The Henyey–Greenstein density of a scattering angle with cosine `cos_theta`.
fn hg(g: f32, cos_theta: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

impl PhaseFunction {
    /// A Henyey–Greenstein phase function with `g` clamped to \[−0.999, 0.999\] (0, or a NaN, gives isotropic).
    pub fn henyey_greenstein(g: f32) -> Self {
        if g == 0.0 || g.is_nan() {
            PhaseFunction::Isotropic
        } else {
            PhaseFunction::HenyeyGreenstein {
                g: g.clamp(-0.999, 0.999),
            }
        }
    }

    /// Phase function value for the pair (`wo`, `wi`), per steradian.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        match *self {
            PhaseFunction::Isotropic => 0.25 / PI,
            PhaseFunction::HenyeyGreenstein { g } => hg(g, (-wo.dot(wi)).clamp(-1.0, 1.0)),
        }
    }

    /// Solid-angle density of [`PhaseFunction::sample`]; equal to [`PhaseFunction::eval`].
    #[cfg(any(test, feature = "testing"))]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval(wo, wi)
    }

    /// Samples `wi` exactly in proportion to the phase function; returns it with its density. The scattering
    /// cosine inverts the Henyey–Greenstein CDF: `cos θ = (1 + g² − ((1 − g²)/(1 − g + 2gξ))²) / (2g)` (the
    /// closed-form inverse, e.g. Pharr et al., "Physically Based Rendering", 4th ed., §11.3.1), with
    /// `cos θ = 1 − 2ξ` when |g| < 1e-6. It is evaluated in f64: the numerator cancels to O(g). φ is uniform
    /// about the axis `-wo`.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> (Vec3, f32) {
        let g = match *self {
            PhaseFunction::Isotropic => 0.0,
            PhaseFunction::HenyeyGreenstein { g } => g,
        };
        let (g, xi) = (g as f64, u.x as f64);
        let cos_theta = if g.abs() < ISOTROPIC_G {
            1.0 - 2.0 * xi
        } else {
            let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
            ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
        } as f32;
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let local = Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
        let wi = Frame::from_normal(-wo).to_world(local);
        (wi, self.eval(wo, wi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{chi2, sampling, Rng};

    #[test]
    fn henyey_greenstein_sampling_chi2() {
        let wo = Vec3::new(0.3, -0.4, 0.5).normalize();
        for (k, g) in [-0.9f32, -0.3, 0.0, 0.3, 0.9].into_iter().enumerate() {
            let phase = PhaseFunction::henyey_greenstein(g);
            chi2::assert_sampler_fits(
                &format!("HG g {g}"),
                200_000,
                100 + k as u64,
                |rng| {
                    let (wi, pdf) = phase.sample(wo, rng.next_2d());
                    assert!(
                        (pdf - phase.pdf(wo, wi)).abs() <= 1e-4 * pdf,
                        "sampled pdf matches pdf()"
                    );
                    Some(wi)
                },
                |wi| phase.eval(wo, wi) as f64,
            );
        }
    }

    #[test]
    fn normalised_with_mean_cosine_g_and_stable_at_extremes() {
        let wo = Vec3::new(0.0, 0.6, -0.8);
        for g in [-0.99f32, -0.9, -0.3, 0.0, 1e-4, 0.3, 0.9, 0.99] {
            let phase = PhaseFunction::henyey_greenstein(g);
            let mut rng = Rng::new(21, g.to_bits() as u64);
            let n = 200_000;
            // ∫ p dω = 1 by uniform-sphere Monte Carlo (only for moderate g: the peak of g = ±0.99 makes this
            // estimator's variance huge), and E[cos θ] = g under the sampler.
            let (mut s, mut s2, mut c, mut c2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for _ in 0..n {
                let v = (phase.eval(wo, sampling::uniform_sphere(rng.next_2d()))
                    / sampling::UNIFORM_SPHERE_PDF) as f64;
                s += v;
                s2 += v * v;
                let (wi, pdf) = phase.sample(wo, rng.next_2d());
                assert!(wi.is_finite() && pdf.is_finite() && pdf > 0.0, "g {g}");
                assert!((wi.length() - 1.0).abs() < 1e-4);
                let cos = -(wo.dot(wi)) as f64;
                c += cos;
                c2 += cos * cos;
            }
            let se = |sum: f64, sum2: f64| {
                let m = sum / n as f64;
                (m, ((sum2 / n as f64 - m * m) / n as f64).sqrt().max(1e-6))
            };
            let (cos_mean, cos_se) = se(c, c2);
            assert!(
                (cos_mean - g as f64).abs() < 4.0 * cos_se,
                "g {g}: mean cosine {cos_mean} ± {cos_se}"
            );
            if g.abs() < 0.95 {
                let (norm, norm_se) = se(s, s2);
                assert!(
                    (norm - 1.0).abs() < 4.0 * norm_se,
                    "g {g}: ∫p = {norm} ± {norm_se}"
                );
            }
        }
        // Forward scattering peaks at wi = -wo.
        let hg = PhaseFunction::henyey_greenstein(0.7);
        assert!(hg.eval(wo, -wo) > hg.eval(wo, wo));
        assert_eq!(
            PhaseFunction::henyey_greenstein(0.0),
            PhaseFunction::Isotropic
        );
    }
}
