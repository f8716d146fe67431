//! The sheen lobe of `KHR_materials_sheen`: the "Charlie" microfiber distribution and its visibility term
//! (Conty Estevez & Kulla 2017, "Production Friendly Microfacet Sheen BRDF", SIGGRAPH course notes), as the
//! extension's implementation notes give them, and the albedo scaling with which it is layered over the base.
//!
//! `f_sheen = sheenColor · D(h) · V(wo, wi)` with
//! - `D(h) = (2 + 1/α) sin(θh)^(1/α) / (2π)`, α = `sheenRoughness` (the extension's text uses the roughness
//!   itself, not its square), kept at or above [`MIN_ALPHA`];
//! - `V = 1 / ((1 + Λ(wo) + Λ(wi)) · 4 cos θo cos θi)`, Λ the fitted `lambdaSheen` of the notes.
//!
//! Layering (the extension's "albedo-scaling technique"): the base is scaled by
//! `min(1 − max(sheenColor)·E(cos θo), 1 − max(sheenColor)·E(cos θi))`, where `E(μ)` is the directional albedo
//! of the white lobe. Nimbus computes `E` once, by quadrature of this very lobe on a grid of (μ, α), and
//! interpolates it bilinearly in (√μ, α) (the table the notes and the Enterprise PBR specification §6.2.3 tabulate), so
//! the layered albedo never exceeds the base's.
//!
//! Sampling: the cosine-weighted hemisphere (the lobe is broad; MIS with light sampling handles the rest).

use crate::math::{Rgb, Vec3};
use std::f32::consts::PI;
use std::sync::OnceLock;

/// Smallest α used: below it the lobe is a sliver at grazing angles that no sampler finds (glTF viewers such
/// as three.js clamp the sheen roughness the same way).
pub const MIN_ALPHA: f32 = 0.07;

/// Table size in √μ, μ = cos θ (from 0 to 1: the albedo changes fastest at grazing angles), and in α (from
/// [`MIN_ALPHA`] to 1).
const TABLE_MU: usize = 32;
const TABLE_ALPHA: usize = 32;
/// Quadrature nodes per dimension (cos θi, φ) for each table entry.
const QUAD: usize = 64;

/// The sheen lobe at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheen {
    /// `sheenColorFactor` × texture, linear RGB, in \[0, 1\].
    pub color: Rgb,
    /// Distribution width α, in \[0.07, 1\] (see `MIN_ALPHA`).
    pub alpha: f32,
}

/// `l(x, α)` of the visibility fit.
fn fit_l(x: f32, alpha: f32) -> f32 {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let mix = |a: f32, b: f32| a + (b - a) * t;
    let a = mix(21.5473, 25.3245);
    let b = mix(3.82987, 3.32435);
    let c = mix(0.19823, 0.16801);
    let d = mix(-1.97760, -1.27393);
    let e = mix(-4.32054, -4.85967);
    a / (1.0 + b * x.powf(c)) + d * x + e
}

/// The fitted `lambdaSheen(cos θ, α)`.
fn lambda(cos: f32, alpha: f32) -> f32 {
    if cos < 0.5 {
        fit_l(cos, alpha).exp()
    } else {
        (2.0 * fit_l(0.5, alpha) - fit_l(1.0 - cos, alpha)).exp()
    }
}

/// The white lobe `D · V` for directions above the surface.
fn white(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize_or_zero();
    let sin2 = (1.0 - h.z * h.z).max(0.0);
    let inv = 1.0 / alpha;
    let d = (2.0 + inv) * sin2.powf(0.5 * inv) / (2.0 * PI);
    let v = 1.0 / ((1.0 + lambda(wo.z, alpha) + lambda(wi.z, alpha)) * 4.0 * wo.z * wi.z);
    let f = d * v;
    if f.is_finite() {
        f
    } else {
        0.0
    }
}

/// The directional albedo `∫ D V cos θi dωi` of the white lobe for `wo` at cos θ = `mu`, by the midpoint rule
/// in (cos θi, φ) (φ over half the circle: the lobe is symmetric about the plane of incidence).
fn albedo_by_quadrature(mu: f32, alpha: f32) -> f32 {
    let mu = mu.clamp(1e-3, 1.0);
    let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
    let mut sum = 0.0f64;
    for i in 0..QUAD {
        let c = (i as f32 + 0.5) / QUAD as f32;
        let s = (1.0 - c * c).sqrt();
        for j in 0..QUAD {
            let phi = PI * (j as f32 + 0.5) / QUAD as f32;
            let wi = Vec3::new(s * phi.cos(), s * phi.sin(), c);
            sum += (white(wo, wi, alpha) * c) as f64;
        }
    }
    // dω = d(cos θ) dφ over cos θ ∈ [0, 1], φ ∈ [0, 2π): twice the half circle.
    (sum * 2.0 * PI as f64 / (QUAD * QUAD) as f64) as f32
}

/// The table of `E(μ, α)`, row per α.
fn table() -> &'static [[f32; TABLE_MU]; TABLE_ALPHA] {
    static TABLE: OnceLock<[[f32; TABLE_MU]; TABLE_ALPHA]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [[0.0; TABLE_MU]; TABLE_ALPHA];
        for (a, row) in t.iter_mut().enumerate() {
            let alpha = MIN_ALPHA + (1.0 - MIN_ALPHA) * a as f32 / (TABLE_ALPHA - 1) as f32;
            for (m, e) in row.iter_mut().enumerate() {
                let root = m as f32 / (TABLE_MU - 1) as f32;
                *e = albedo_by_quadrature(root * root, alpha).min(1.0);
            }
        }
        t
    })
}

impl Sheen {
    /// The lobe for `sheenColor` and `sheenRoughness` (clamped to their ranges).
    pub fn new(color: Rgb, roughness: f32) -> Self {
        Self {
            color: color.clamp(Rgb::ZERO, Rgb::ONE),
            alpha: roughness.clamp(MIN_ALPHA, 1.0),
        }
    }

    /// BSDF value `sheenColor · D · V` (one-sided).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.color * white(wo, wi, self.alpha)
    }

    /// Directional albedo `E(cos θ)` of the white lobe, interpolated bilinearly in the table (in √cos θ and α).
    pub fn directional_albedo(&self, cos: f32) -> f32 {
        let t = table();
        let x = cos.clamp(0.0, 1.0).sqrt() * (TABLE_MU - 1) as f32;
        let y = ((self.alpha - MIN_ALPHA) / (1.0 - MIN_ALPHA)).clamp(0.0, 1.0)
            * (TABLE_ALPHA - 1) as f32;
        let (x0, y0) = (
            (x as usize).min(TABLE_MU - 2),
            (y as usize).min(TABLE_ALPHA - 2),
        );
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let row = |r: &[f32; TABLE_MU]| r[x0] + (r[x0 + 1] - r[x0]) * fx;
        let (a, b) = (row(&t[y0]), row(&t[y0 + 1]));
        a + (b - a) * fy
    }

    /// The factor on the base layer, `min(1 − max(sheenColor)·E(|cos θo|), 1 − max(sheenColor)·E(|cos θi|))`.
    pub fn albedo_scaling(&self, cos_o: f32, cos_i: f32) -> f32 {
        let c = self.color.max_element();
        let e = self
            .directional_albedo(cos_o.abs())
            .max(self.directional_albedo(cos_i.abs()));
        (1.0 - c * e).max(0.0)
    }

    /// The lobe's own albedo seen from `wo`, `max(sheenColor) · E(cos θo)`, for lobe selection.
    pub fn albedo(&self, wo: Vec3) -> f32 {
        self.color.max_element() * self.directional_albedo(wo.z.max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{sampling, Rng};

    #[test]
    fn tabulated_albedo_matches_monte_carlo() {
        // Independent of the table's quadrature: uniform-sphere Monte Carlo of the white lobe.
        let mut rng = Rng::new(21, 21);
        for (mu, roughness) in [(0.9f32, 0.3f32), (0.5, 1.0), (0.2, 0.5), (0.05, 0.1)] {
            let sheen = Sheen::new(Rgb::ONE, roughness);
            let wo = Vec3::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let n = 400_000;
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let wi = sampling::uniform_sphere(rng.next_2d());
                let v =
                    (sheen.eval(wo, wi).x * wi.z.max(0.0) / sampling::UNIFORM_SPHERE_PDF) as f64;
                s += v;
                s2 += v * v;
            }
            let mean = s / n as f64;
            let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
            let e = sheen.directional_albedo(mu) as f64;
            assert!(
                (e - mean).abs() < 4.0 * se + 0.01 * mean,
                "mu {mu} roughness {roughness}: table {e}, Monte Carlo {mean} ± {se}"
            );
            assert!(e > 0.0 && e < 1.0);
        }
    }
}
