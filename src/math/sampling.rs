//! Sampling warps from the unit square to common domains, with their densities, and MIS weights.
//! Each warp follows Pharr, Jakob, Humphreys, "Physically Based Rendering" 4th ed. (PBRT4) §A.5.

use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

/// Concentric (Shirley–Chiu) map from the unit square to the unit disk, PBRT4 §A.5.1.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, FRAC_PI_4 * (o.y / o.x))
    } else {
        (o.y, FRAC_PI_2 - FRAC_PI_4 * (o.x / o.y))
    };
    r * Vec2::new(theta.cos(), theta.sin())
}

/// Cosine-weighted hemisphere around +z (Malley's method), PBRT4 §A.5.3. Density `cos θ / π`.
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Density of [`cosine_hemisphere`] for a direction with `cos θ = cos_theta`.
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction on the unit sphere. Density `1 / 4π`.
pub fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// The largest f32 below 1: where a sample value rescaled to \[0, 1) is clamped, so that rounding in the
/// rescaling cannot reach 1.
pub const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// Density of [`uniform_sphere`].
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// Uniform direction in the cone of half-angle `acos(cos_max)` around +z. Density `1 / (2π (1 − cos_max))`.
#[cfg(test)]
pub fn uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_theta = 1.0 - u.x * (1.0 - cos_max);
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// Density of [`uniform_cone`].
#[cfg(test)]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Uniform barycentrics (b0, b1) on a triangle, PBRT4 §6.5.4 (Heitz 2019's low-distortion map).
pub fn uniform_triangle(u: Vec2) -> (f32, f32) {
    let (b0, b1);
    if u.x < u.y {
        b0 = u.x / 2.0;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2.0;
        b0 = u.x - b1;
    }
    (b0, b1)
}

/// Equiangular sampling of a distance along a ray segment, with density ∝ 1/r(t)², the inverse squared
/// distance from the point at t to a fixed point (a light): Kulla & Fajardo 2012, "Importance Sampling
/// Techniques for Path Tracing in Participating Media", §4.1 (eqs. 6–8). The samples are uniform in the angle
/// they subtend at the light, which cancels a point light's 1/r² falloff, the cause of fireflies around lights
/// inside media.
#[derive(Clone, Copy, Debug)]
pub struct Equiangular {
    /// Distance along the ray to the foot of the perpendicular from the light.
    foot: f32,
    /// Distance from the light to the ray's line.
    height: f32,
    /// Angle at the light between the perpendicular and the segment's start.
    theta_start: f32,
    /// Angle at the light between the perpendicular and the segment's end.
    theta_end: f32,
    /// Length of the segment.
    length: f32,
}

impl Equiangular {
    /// Equiangular sampling of `[0, length]` along the ray from `origin` in the unit direction `dir`, toward
    /// `light`. `None` when the segment is empty or unbounded, or the light lies on the ray's line (where the
    /// density would be a delta).
    pub fn new(origin: Vec3, dir: Vec3, length: f32, light: Vec3) -> Option<Self> {
        let foot = (light - origin).dot(dir);
        let height = (origin + dir * foot - light).length();
        let usable = length > 0.0 && length.is_finite() && height > 1e-7 * (1.0 + foot.abs());
        if !usable {
            return None;
        }
        let theta_start = (-foot / height).atan();
        let theta_end = ((length - foot) / height).atan();
        (theta_end > theta_start).then_some(Self {
            foot,
            height,
            theta_start,
            theta_end,
            length,
        })
    }

    /// A distance in `[0, length]` from `u` ∈ [0, 1), and its density (eq. 7: t = Δ + D tan θ, θ uniform).
    pub fn sample(&self, u: f32) -> (f32, f32) {
        let theta = self.theta_start + u * (self.theta_end - self.theta_start);
        let t = (self.foot + self.height * theta.tan()).clamp(0.0, self.length);
        (t, self.pdf(t))
    }

    /// Density of [`Self::sample`] at distance `t`, per unit length (eq. 8): D / ((θ_b − θ_a)(D² + (t − Δ)²)).
    pub fn pdf(&self, t: f32) -> f32 {
        if !(0.0..=self.length).contains(&t) {
            return 0.0;
        }
        let x = t - self.foot;
        self.height / ((self.theta_end - self.theta_start) * (self.height * self.height + x * x))
    }
}

/// Distance sampling truncated to a segment: density p(t) = σ e^{−σt} / (1 − e^{−σd}) on `[0, d]`, the
/// transmittance-proportional density of a homogeneous medium conditioned on a collision before `d` (the
/// "forced" or decoupled distance sampling of Novák et al. 2018, "Monte Carlo Methods for Volumetric Light
/// Transport Simulation", §5, where every segment yields a point). σ = 0 is the uniform density 1/d.
#[derive(Clone, Copy, Debug)]
pub struct TruncatedExponential {
    /// The extinction coefficient σ ≥ 0.
    sigma: f32,
    /// The segment's length d.
    length: f32,
    /// 1 − e^{−σd}, the probability of an untruncated collision before d (0 when σ = 0).
    mass: f32,
}

impl TruncatedExponential {
    /// The density on `[0, length]` for extinction `sigma`; `None` for an empty, unbounded or non-finite
    /// segment or a negative or non-finite σ.
    pub fn new(sigma: f32, length: f32) -> Option<Self> {
        let usable = length > 0.0 && length.is_finite() && sigma >= 0.0 && sigma.is_finite();
        usable.then(|| Self {
            sigma,
            length,
            mass: -(-sigma * length).exp_m1(),
        })
    }

    /// True when σd is so small that the density is uniform to f32 precision.
    fn is_uniform(&self) -> bool {
        self.sigma * self.length < 1e-6
    }

    /// A distance in `[0, length]` from `u` ∈ [0, 1), and its density: t = −ln(1 − u(1 − e^{−σd}))/σ.
    pub fn sample(&self, u: f32) -> (f32, f32) {
        let t = if self.is_uniform() {
            u * self.length
        } else {
            -(-u * self.mass).ln_1p() / self.sigma
        };
        let t = t.clamp(0.0, self.length);
        (t, self.pdf(t))
    }

    /// Density of [`Self::sample`] at distance `t`, per unit length.
    pub fn pdf(&self, t: f32) -> f32 {
        if !(0.0..=self.length).contains(&t) {
            return 0.0;
        }
        if self.is_uniform() {
            return 1.0 / self.length;
        }
        self.sigma * (-self.sigma * t).exp() / self.mass
    }
}

/// Makes a path carry a single colour channel, chosen with probability proportional to its throughput β_c and
/// weighted by 1/p_c, so the new throughput Σβ · e_c has the old one as its expectation (unbiased); returns the
/// channel. Spectral renderers sample one wavelength per path the same way (hero wavelength); the cost is colour
/// noise. Used where one channel is all an event can follow: a dispersive surface
/// (`KHR_materials_dispersion`) refracts with the index of the channel returned, and an RGB grid medium with
/// `chromatic_tracking: one_channel` delta-tracks that channel alone. A path already carrying one channel is
/// unchanged and that channel returned (the green one for a path that carries nothing).
pub fn carry_one_channel(beta: &mut super::Rgb, rng: &mut super::Rng) -> usize {
    let carried = beta.to_array().iter().filter(|&&b| b > 0.0).count();
    if carried <= 1 {
        return beta.to_array().iter().position(|&b| b > 0.0).unwrap_or(1);
    }
    let sum = beta.element_sum();
    let u = rng.next_f32() * sum;
    let channel = if u < beta.x {
        0
    } else if u < beta.x + beta.y {
        1
    } else {
        2
    };
    let mut one = super::Rgb::ZERO;
    one[channel] = sum;
    *beta = one;
    channel
}

/// Balance heuristic for one sample from each of two strategies (Veach 1997, eq. 9.10).
#[cfg(test)]
pub fn balance_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    if pdf_a <= 0.0 {
        return 0.0;
    }
    if pdf_a.is_infinite() {
        return 1.0;
    }
    pdf_a / (pdf_a + pdf_b)
}

/// Power heuristic with β = 2 (Veach 1997, eq. 9.13).
pub fn power_heuristic(pdf_a: f32, pdf_b: f32) -> f32 {
    if pdf_a <= 0.0 {
        return 0.0;
    }
    if pdf_a.is_infinite() {
        return 1.0;
    }
    let a = pdf_a * pdf_a;
    a / (a + pdf_b * pdf_b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    #[test]
    fn warps_land_in_their_domains() {
        let mut rng = Rng::new(1, 1);
        for _ in 0..10_000 {
            let u = rng.next_2d();
            assert!(concentric_disk(u).length() <= 1.0 + 1e-6);
            let c = cosine_hemisphere(u);
            assert!(c.z >= 0.0 && (c.length() - 1.0).abs() < 1e-4);
            assert!((uniform_sphere(u).length() - 1.0).abs() < 1e-4);
            assert!(uniform_cone(u, 0.9).z >= 0.9 - 1e-6);
            let (b0, b1) = uniform_triangle(u);
            assert!(b0 >= 0.0 && b1 >= 0.0 && b0 + b1 <= 1.0 + 1e-6);
        }
    }

    #[test]
    fn equiangular_samples_follow_their_density() {
        // Lights beside, before, behind and near the segment, and far from it (nearly uniform).
        let dir = Vec3::new(1.0, 2.0, -0.5).normalize();
        let origin = Vec3::new(0.3, -0.2, 1.0);
        for (i, (light, length)) in [
            (Vec3::new(1.0, 1.0, 1.0), 3.0),
            (origin + dir * 5.0 + Vec3::new(0.0, 0.0, 0.4), 2.0),
            (origin - dir * 1.0 + Vec3::new(0.2, 0.0, 0.0), 4.0),
            (origin + dir * 1.5 + Vec3::new(0.0, 0.01, 0.0), 3.0),
            (Vec3::new(100.0, -40.0, 3.0), 1.0),
        ]
        .into_iter()
        .enumerate()
        {
            let eq = Equiangular::new(origin, dir, length, light).unwrap();
            let mut rng = Rng::new(3, i as u64);
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("equiangular {i}"),
                200_000,
                (0.0, length as f64),
                || {
                    let (t, pdf) = eq.sample(rng.next_f32());
                    let r2 = (origin + dir * t - light).length_squared();
                    // The returned density is the one claimed, and ∝ 1/r².
                    assert!((pdf - eq.pdf(t)).abs() <= 1e-5 * pdf);
                    assert!(pdf > 0.0 && (pdf * r2).is_finite());
                    t
                },
                |t| eq.pdf(t as f32) as f64,
            );
            // ∝ 1/r²: pdf · r² is the same constant everywhere on the segment.
            let k = |t: f32| eq.pdf(t) * (origin + dir * t - light).length_squared();
            assert!((k(0.0) - k(length)).abs() <= 1e-3 * k(0.0), "{i}");
        }
        // A light on the ray's line, and unbounded or empty segments, are refused.
        assert!(Equiangular::new(origin, dir, 2.0, origin + dir * 3.0).is_none());
        assert!(Equiangular::new(origin, dir, f32::INFINITY, Vec3::ONE).is_none());
        assert!(Equiangular::new(origin, dir, 0.0, Vec3::ONE).is_none());
    }

    #[test]
    fn truncated_exponential_samples_follow_their_density() {
        // Thin (nearly uniform), moderate and thick segments, and σ = 0 (uniform).
        for (i, (sigma, length)) in [
            (1e-3, 2.0),
            (0.31, 4.0),
            (2.0, 1.5),
            (30.0, 3.0),
            (0.0, 2.5),
        ]
        .into_iter()
        .enumerate()
        {
            let d = TruncatedExponential::new(sigma, length).unwrap();
            let mut rng = Rng::new(11, i as u64);
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("truncated exponential {i}"),
                200_000,
                (0.0, length as f64),
                || {
                    let (t, pdf) = d.sample(rng.next_f32());
                    assert!((pdf - d.pdf(t)).abs() <= 1e-5 * pdf, "{i}: {pdf} at {t}");
                    t
                },
                // The closed form in f64, independent of the sampler's arithmetic.
                |t| {
                    let (s, l) = (sigma as f64, length as f64);
                    if s == 0.0 {
                        1.0 / l
                    } else {
                        s * (-s * t).exp() / (1.0 - (-s * l).exp())
                    }
                },
            );
        }
        // Unbounded, empty or negative-coefficient segments are refused; outside the segment the density is 0.
        assert!(TruncatedExponential::new(1.0, f32::INFINITY).is_none());
        assert!(TruncatedExponential::new(1.0, 0.0).is_none());
        assert!(TruncatedExponential::new(-1.0, 1.0).is_none());
        assert_eq!(TruncatedExponential::new(1.0, 1.0).unwrap().pdf(1.5), 0.0);
    }

    #[test]
    fn cosine_hemisphere_mean_cosine_is_two_thirds() {
        // E[cos θ] under cos θ/π is 2/3; its variance is 1/2 − 4/9 = 1/18.
        let mut rng = Rng::new(5, 9);
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|_| cosine_hemisphere(rng.next_2d()).z as f64)
            .sum::<f64>()
            / n as f64;
        let se = (1.0 / 18.0 / n as f64).sqrt();
        assert!((mean - 2.0 / 3.0).abs() < 4.0 * se, "mean {mean}");
    }
}
