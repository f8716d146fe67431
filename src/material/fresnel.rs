//! Fresnel reflectance: the exact unpolarised formula for dielectric interfaces, Schlick's approximation for
//! the glTF metallic-roughness model, their hemispherical averages (for the light-path AOVs' colour
//! estimates), and the reflection and refraction (Snell's law) of directions.

use crate::math::{Rgb, Vec3};

/// Schlick's approximation of Fresnel reflectance, `F = f0 + (1 − f0)(1 − cos θ)⁵` (Schlick 1994, "An
/// Inexpensive BRDF Model for Physically-based Rendering", eq. 24), as glTF 2.0 Appendix B uses it. `cos_theta`
/// is clamped to \[0, 1\].
pub fn schlick(f0: Rgb, cos_theta: f32) -> Rgb {
    let m = (1.0 - cos_theta).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (Rgb::ONE - f0) * (m2 * m2 * m)
}

/// The cosine-weighted hemispherical average of Schlick's approximation,
/// `F̄ = 2∫₀¹ F(μ) μ dμ = f0 + (1 − f0)/21`, since `2∫₀¹ (1 − μ)⁵ μ dμ = 2 B(2, 6) = 1/21`.
pub fn schlick_average(f0: Rgb) -> Rgb {
    f0 + (Rgb::ONE - f0) / 21.0
}

/// An estimate of the cosine-weighted hemispherical average `F̄ = 2∫₀¹ F(μ) μ dμ` of [`dielectric`]'s
/// reflectance, for `eta` = η_t/η_i: from the optically thinner side (η ≥ 1) Schlick's average with
/// `f0 = F(1) = ((η − 1)/(η + 1))²` (within 0.01 of the exact value for indices from 1.33 to 3, up to 0.05 too
/// high as the index nears 1, where Schlick's form is poorest), from the denser side by
/// reciprocity, `1 − η²(1 − F̄(1/η))` (the hemispherical transmittance scales by η², Veach 1997, §5.2).
/// Always strictly between 0 and 1.
pub fn dielectric_average(eta: f32) -> f32 {
    let outside = |eta: f32| {
        let r = (eta - 1.0) / (eta + 1.0);
        schlick_average(Rgb::splat(r * r)).x
    };
    if eta >= 1.0 {
        outside(eta)
    } else {
        1.0 - eta * eta * (1.0 - outside(1.0 / eta))
    }
}

/// Exact unpolarised Fresnel reflectance of a dielectric interface (the Fresnel equations, Born & Wolf,
/// "Principles of Optics" §1.5.2): `R = (r_s² + r_p²)/2` with `r_s = (cos θi − η cos θt)/(cos θi + η cos θt)`
/// and `r_p = (η cos θi − cos θt)/(η cos θi + cos θt)`. `cos_i` is the cosine on the incident side (its sign
/// is ignored), `eta = η_t/η_i` the relative index of the far side. Total internal reflection gives 1.
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.abs().min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (r_s * r_s + r_p * r_p)
}

/// Mirror reflection of `wo` about the unit normal `n`: `2(wo·n)n − wo` (both point away from the surface).
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    2.0 * wo.dot(n) * n - wo
}

/// Refraction of `wo` through the interface with unit normal `n` on `wo`'s side (`wo·n > 0`), by Snell's law
/// `sin θt = sin θi / η` with `eta = η_t/η_i`. Returns the transmitted direction pointing away from the
/// surface on the far side, or `None` under total internal reflection.
pub fn refract(wo: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = wo.dot(n);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wo / eta + (cos_i / eta - cos_t) * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Transmittance from the Fresnel transmission amplitudes, weighted by the ratio of energy fluxes
    /// (η_t cos θt)/(η_i cos θi): an independent route to `1 − R`.
    fn transmittance(cos_i: f32, eta: f32) -> f32 {
        let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
        if sin2_t >= 1.0 {
            return 0.0;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        let t_s = 2.0 * cos_i / (cos_i + eta * cos_t);
        let t_p = 2.0 * cos_i / (eta * cos_i + cos_t);
        eta * cos_t / cos_i * 0.5 * (t_s * t_s + t_p * t_p)
    }

    /// Walter et al. 2007, eq. 22: the same reflectance in another algebraic form.
    fn walter_fresnel(c: f32, eta: f32) -> f32 {
        let g2 = eta * eta - 1.0 + c * c;
        if g2 < 0.0 {
            return 1.0;
        }
        let g = g2.sqrt();
        let a = (g - c) / (g + c);
        let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
        0.5 * a * a * (1.0 + b * b)
    }

    #[test]
    fn reflectance_plus_transmittance_is_one() {
        for eta in [1.0, 1.33, 1.5, 2.4, 1.0 / 1.5, 1.0 / 2.4] {
            for i in 1..=50 {
                let c = i as f32 / 50.0;
                let r = dielectric(c, eta);
                assert!((0.0..=1.0).contains(&r));
                assert!(
                    (r + transmittance(c, eta) - 1.0).abs() < 1e-4,
                    "eta {eta} cos {c}"
                );
                assert!(
                    (r - walter_fresnel(c, eta)).abs() < 1e-4,
                    "eta {eta} cos {c}"
                );
            }
        }
        // Normal incidence: ((η − 1)/(η + 1))².
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(dielectric(1.0, 1.0), 0.0);
    }

    #[test]
    fn snell_and_reflection_laws() {
        let n = Vec3::Z;
        for eta in [1.5f32, 1.0 / 1.5] {
            for i in 1..20 {
                let theta = i as f32 * 0.075;
                let wo = Vec3::new(theta.sin() * 0.6, theta.sin() * 0.8, theta.cos());
                let r = reflect(wo, n);
                assert!((r - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6);
                match refract(wo, n, eta) {
                    Some(t) => {
                        assert!((t.length() - 1.0).abs() < 1e-5 && t.z < 0.0);
                        let (sin_i, sin_t) = (wo.truncate().length(), t.truncate().length());
                        assert!((sin_i - eta * sin_t).abs() < 1e-5, "Snell");
                        assert!(t.truncate().dot(wo.truncate()) <= 0.0, "plane of incidence");
                    }
                    None => assert!(
                        eta < 1.0 && theta.sin() > eta,
                        "TIR only past the critical angle"
                    ),
                }
            }
        }
        assert_eq!(schlick(Rgb::splat(0.04), 1.0), Rgb::splat(0.04));
        assert_eq!(schlick(Rgb::splat(0.04), 0.0), Rgb::ONE);
    }

    #[test]
    fn schlick_average_matches_quadrature() {
        // Midpoint rule for 2∫F(μ) μ dμ.
        for f0 in [0.0f32, 0.04, 0.5, 1.0] {
            let n = 10_000;
            let sum: f64 = (0..n)
                .map(|i| {
                    let mu = (i as f32 + 0.5) / n as f32;
                    (2.0 * schlick(Rgb::splat(f0), mu).x * mu) as f64
                })
                .sum();
            let quadrature = sum / n as f64;
            let average = schlick_average(Rgb::splat(f0)).x as f64;
            assert!(
                (average - quadrature).abs() < 1e-5,
                "f0 {f0}: {average} vs {quadrature}"
            );
        }
        // The dielectric estimate against the quadrature of the exact reflectance, from both sides.
        for ior in [1.1f32, 1.33, 1.5, 2.0, 2.4] {
            for eta in [ior, 1.0 / ior] {
                let n = 10_000;
                let sum: f64 = (0..n)
                    .map(|i| {
                        let mu = (i as f32 + 0.5) / n as f32;
                        (2.0 * dielectric(mu, eta) * mu) as f64
                    })
                    .sum();
                let quadrature = sum / n as f64;
                let average = dielectric_average(eta) as f64;
                let tolerance = if ior < 1.3 { 0.03 } else { 0.01 };
                assert!(average > 0.0 && average < 1.0);
                assert!(
                    (average - quadrature).abs() < tolerance,
                    "eta {eta}: {average} vs {quadrature}"
                );
            }
        }
    }
}
