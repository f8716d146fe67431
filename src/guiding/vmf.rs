//! A parametric directional distribution for the guiding cache: a mixture of von Mises–Fisher lobes fitted to a
//! cell's training records by weighted, maximum-a-posteriori EM, as Herholz et al. 2016 ("Product Importance
//! Sampling for Light Transport Path Guiding", CGF 35(4), §4) and 2019 ("Volume Path Guiding Based on
//! Zero-Variance Random Walk Theory", TOG 38(3), §4) fit their mixtures.
//!
//! - A lobe is v(ω) = κ / (2π (1 − e^(−2κ))) · e^(κ (μ·ω − 1)) (the vMF density on the sphere, written so that
//!   it stays finite for large κ), sampled by Jakob 2012 ("Numerically stable sampling of the von Mises Fisher
//!   distribution on S² (and other tricks)": the cosine to μ by inversion, w = 1 + ln(ξ + (1 − ξ) e^(−2κ))/κ,
//!   evaluated with ln_1p and exp_m1).
//! - The fit ([`VmfMixture::fit`]): batch EM over the records' directions weighted by radiance/pdf (each
//!   record an importance-weighted sample of the incident radiance). The M-step's mean direction is the
//!   weighted resultant; its concentration comes from the mean resultant length r̄ by Banerjee et al. 2005
//!   ("Clustering on the Unit Hypersphere using von Mises-Fisher Distributions", JMLR 6; their approximation
//!   κ ≈ r̄(d − r̄²)/(1 − r̄²) with d = 3). The MAP priors: r̄ is computed with [`KAPPA_PRIOR`] · N/[`LOBES`]
//!   pseudo-records of mean cosine 0 added to each lobe's N records (a lobe that holds a few records stays
//!   broad instead of collapsing onto one), and the weights with a Dirichlet prior of [`WEIGHT_PRIOR`] ·
//!   N/[`LOBES`] pseudo-records per lobe. No record counts for more than [`MAX_RECORD_WEIGHT`] average records (the spikes of single high-value records the
//!   histograms showed, docs/performance.md "Diagnosis with an oracle").
//! - The product with a lobe (the phase function or a cosine approximated by one, [`lobe_kappa`]) has a closed
//!   form: v₁ v₂ = c · v(κ₁μ₁ + κ₂μ₂) (Herholz et al. 2019 §4), so the product of the mixture with a lobe is a
//!   mixture ([`VmfMixture::product`]).

use crate::math::sampling::ONE_BELOW;
use crate::math::{Frame, Vec2, Vec3};
use std::f32::consts::PI;

/// Lobes of a mixture.
pub const LOBES: usize = 8;
/// EM iterations of a fit.
const EM_ITERATIONS: usize = 16;
/// Records a cell keeps for its fit (a uniform reservoir sample of those it receives).
pub const FIT_RECORDS: usize = 2048;
/// Pseudo-records of mean cosine 0 added to each lobe's resultant, as a fraction of the records per lobe
/// (N / [`LOBES`]): 0.5 of 0, 0.05 and 0.5, measured equal within the noise (docs/performance.md, "vMF mixtures
/// in place of the histograms"), as the most conservative. A lobe holding all N records has r̄ ≤ 16/17, so
/// κ ≤ 17.4 (an angular spread 1/√κ of about 14°).
const KAPPA_PRIOR: f32 = 0.5;
/// Dirichlet pseudo-records per lobe for the weights, as a fraction of the records per lobe.
const WEIGHT_PRIOR: f32 = 0.01;
/// The most average records one record counts as in a fit.
const MAX_RECORD_WEIGHT: f32 = 20.0;
/// The largest concentration a fitted lobe may have (an angular spread 1/√κ of about 1.8°).
const MAX_KAPPA: f32 = 1000.0;
/// The smallest concentration a lobe may have (below it the lobe is uniform to f32 precision).
const MIN_KAPPA: f32 = 1e-4;

/// ln of the vMF normalisation in the form v(ω) = exp(ln_norm(κ) + κ (μ·ω − 1)): ln(κ / (2π (1 − e^(−2κ)))).
fn ln_norm(kappa: f32) -> f32 {
    // Above κ = 9, 1 − e^(−2κ) rounds to 1 in f32.
    let denominator = if kappa > 9.0 {
        1.0
    } else {
        -(-2.0 * kappa).exp_m1()
    };
    (kappa / denominator).ln() - (2.0 * PI).ln()
}

/// 1 − e^(−2κ) for κ > 0, for the product's weights: 1 above κ = 9 (as in [`ln_norm`]), exp_m1 below 2κ = 0.7
/// (where 1 − e^(−2κ) would lose digits), else one exponential (the difference then is at least 1/2, exact to the
/// rounding of e^(−2κ)).
fn one_minus_exp_neg_2k(kappa: f32) -> f32 {
    if kappa > 9.0 {
        1.0
    } else if kappa < 0.35 {
        -(-2.0 * kappa).exp_m1()
    } else {
        1.0 - (-2.0 * kappa).exp()
    }
}

/// The concentration of a vMF lobe with mean cosine `mean_cosine` ∈ \[0, 1) (Banerjee et al. 2005's approximation).
pub fn lobe_kappa(mean_cosine: f32) -> f32 {
    let r = mean_cosine.clamp(0.0, 0.999);
    (r * (3.0 - r * r) / (1.0 - r * r)).clamp(MIN_KAPPA, MAX_KAPPA)
}

/// One von Mises–Fisher lobe with its mixture weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VmfLobe {
    /// Mean direction (unit).
    pub mu: Vec3,
    /// Concentration κ > 0.
    pub kappa: f32,
    /// Weight in the mixture (the weights sum to 1).
    pub weight: f32,
}

impl VmfLobe {
    /// The lobe's density at the unit direction `w`.
    #[cfg(test)]
    pub fn pdf(&self, w: Vec3) -> f32 {
        (ln_norm(self.kappa) + self.kappa * (self.mu.dot(w) - 1.0)).exp()
    }

    /// A direction sampled from the lobe by `u` ∈ \[0, 1)² (Jakob 2012).
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let k = self.kappa;
        let w = (1.0 + (-(1.0 - u.x) * -(-2.0 * k).exp_m1()).ln_1p() / k).clamp(-1.0, 1.0);
        let r = (1.0 - w * w).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        Frame::from_normal(self.mu).to_world(Vec3::new(r * phi.cos(), r * phi.sin(), w))
    }
}

/// A mixture of up to [`LOBES`] vMF lobes (unused lobes have weight 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VmfMixture {
    lobes: [VmfLobe; LOBES],
    /// ln(weight) + ln_norm(κ) − κ per lobe (−∞ for unused lobes): the density is Σ exp(this + κ μ·ω).
    ln_scale: [f32; LOBES],
}

impl VmfMixture {
    /// The mixture of `lobes` (at most [`LOBES`]) with their weights normalised; `None` without weight.
    pub fn new(lobes: &[VmfLobe]) -> Option<Self> {
        let mut out = [VmfLobe {
            mu: Vec3::Z,
            kappa: 1.0,
            weight: 0.0,
        }; LOBES];
        out[..lobes.len()].copy_from_slice(lobes);
        let total: f32 = out.iter().map(|l| l.weight).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        out.iter_mut().for_each(|l| l.weight /= total);
        let ln_scale = std::array::from_fn(|k| {
            let l = out[k];
            if l.weight > 0.0 {
                l.weight.ln() + ln_norm(l.kappa) - l.kappa
            } else {
                f32::NEG_INFINITY
            }
        });
        Some(Self {
            lobes: out,
            ln_scale,
        })
    }

    /// The lobes.
    #[cfg(test)]
    pub fn lobes(&self) -> &[VmfLobe; LOBES] {
        &self.lobes
    }

    /// The mixture's density at the unit direction `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        let mut sum = 0.0;
        for (l, &c) in self.lobes.iter().zip(self.ln_scale.iter()) {
            sum += (c + l.kappa * l.mu.dot(w)).exp();
        }
        sum
    }

    /// A direction sampled by `u` ∈ \[0, 1)²: a lobe picked by its weight with `u.x` (rescaled within the
    /// lobe, keeping the sample's stratification), then sampled; its density is [`Self::pdf`].
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let mut below = 0.0;
        let mut chosen = (0, ONE_BELOW);
        for (k, l) in self.lobes.iter().enumerate() {
            if l.weight > 0.0 {
                chosen = (k, ONE_BELOW);
                if u.x < below + l.weight {
                    chosen = (k, ((u.x - below) / l.weight).clamp(0.0, ONE_BELOW));
                    break;
                }
                below += l.weight;
            }
        }
        self.lobes[chosen.0].sample(Vec2::new(chosen.1, u.y))
    }

    /// The mixture times the lobe e^(κ a·ω) (unnormalised; `kappa` 0 is a constant), normalised: each lobe's
    /// product is the lobe of κᵢμᵢ + κa with weight wᵢ · exp(ln_norm(κᵢ) − κᵢ − ln_norm(κ') + κ') (the
    /// normalisations' ratio). `None` where no weight is left (or it is not finite).
    ///
    /// The weights are taken as exp(cᵢ + κ' − top) · (1 − e^(−2κ'))/κ' (cᵢ = ln wᵢ + ln_norm(κᵢ) − κᵢ, top the
    /// largest cᵢ + κ'; ln_norm(κ') = ln((κ'/(1 − e^(−2κ'))) / 2π)): one exponential and, below κ' = 9, one
    /// more for the normalisation, in place of a logarithm and an exp_m1 per lobe.
    pub fn product(&self, axis: Vec3, kappa: f32) -> Option<Self> {
        let mut lobes = self.lobes;
        let mut exponents = [f32::NEG_INFINITY; LOBES];
        let mut norms = [0.0f32; LOBES];
        for (((l, e), n), &c) in lobes
            .iter_mut()
            .zip(exponents.iter_mut())
            .zip(norms.iter_mut())
            .zip(self.ln_scale.iter())
        {
            if l.weight <= 0.0 {
                continue;
            }
            let v = l.mu * l.kappa + axis * kappa;
            let k = v.length();
            let (mu, k) = if k > MIN_KAPPA {
                (v / k, k)
            } else {
                (axis, MIN_KAPPA)
            };
            *e = c + k;
            *n = one_minus_exp_neg_2k(k) / k;
            l.mu = mu;
            l.kappa = k;
        }
        let top = exponents.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        if !top.is_finite() {
            return None;
        }
        for ((l, e), n) in lobes.iter_mut().zip(exponents).zip(norms) {
            l.weight = (e - top).exp() * n;
        }
        let total: f32 = lobes.iter().map(|l| l.weight).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        lobes.iter_mut().for_each(|l| l.weight /= total);
        // The product lobe's ln(weight) + ln_norm(κ') − κ' is c − ln(Σ), Σ the sum of the weights before they
        // are normalised, exp(c + κ' − ln_norm(κ')) = 2π · exp(c + κ') (1 − e^(−2κ'))/κ' each: no
        // normalisation to evaluate again.
        let ln_total = top + total.ln() + (2.0 * PI).ln();
        let ln_scale = std::array::from_fn(|k| {
            if lobes[k].weight > 0.0 {
                self.ln_scale[k] - ln_total
            } else {
                f32::NEG_INFINITY
            }
        });
        Some(Self { lobes, ln_scale })
    }

    /// The MAP-EM fit to `records` (unit direction, weight ≥ 0; see the module documentation), started from
    /// [`LOBES`] lobes about the cube's diagonals; `None` without positive weight.
    pub fn fit(records: &[(Vec3, f32)]) -> Option<Self> {
        let total: f64 = records.iter().map(|r| r.1 as f64).sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let n = records.len() as f32;
        let scale = (n as f64 / total) as f32;
        let weight = |r: &(Vec3, f32)| (r.1 * scale).min(MAX_RECORD_WEIGHT);
        let per_lobe = n / LOBES as f32;
        let mut lobes: [VmfLobe; LOBES] = std::array::from_fn(|k| VmfLobe {
            mu: Vec3::new(
                if k & 1 == 0 { 1.0 } else { -1.0 },
                if k & 2 == 0 { 1.0 } else { -1.0 },
                if k & 4 == 0 { 1.0 } else { -1.0 },
            )
            .normalize(),
            kappa: 3.0,
            weight: 1.0 / LOBES as f32,
        });
        for _ in 0..EM_ITERATIONS {
            let mut mass = [0.0f64; LOBES];
            let mut resultant = [[0.0f64; 3]; LOBES];
            let ln_parts: [(f32, f32); LOBES] = std::array::from_fn(|k| {
                let l = lobes[k];
                (l.weight.max(1e-30).ln() + ln_norm(l.kappa), l.kappa)
            });
            for r in records {
                let w = weight(r);
                if w <= 0.0 {
                    continue;
                }
                let mut p = [0.0f32; LOBES];
                for (k, l) in lobes.iter().enumerate() {
                    p[k] = (ln_parts[k].0 + ln_parts[k].1 * (l.mu.dot(r.0) - 1.0)).exp();
                }
                let sum: f32 = p.iter().sum();
                if sum.is_nan() || sum <= 0.0 {
                    continue;
                }
                for k in 0..LOBES {
                    let g = (w * p[k] / sum) as f64;
                    mass[k] += g;
                    resultant[k][0] += g * r.0.x as f64;
                    resultant[k][1] += g * r.0.y as f64;
                    resultant[k][2] += g * r.0.z as f64;
                }
            }
            let all: f64 = mass.iter().sum();
            if all.is_nan() || all <= 0.0 {
                return None;
            }
            let prior_w = (WEIGHT_PRIOR * per_lobe) as f64;
            let prior_k = (KAPPA_PRIOR * per_lobe) as f64;
            for (k, l) in lobes.iter_mut().enumerate() {
                let r = resultant[k];
                let length = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
                if length > 0.0 {
                    l.mu = Vec3::new(r[0] as f32, r[1] as f32, r[2] as f32) / length as f32;
                }
                l.kappa = lobe_kappa((length / (mass[k] + prior_k)) as f32);
                l.weight = ((mass[k] + prior_w) / (all + prior_w * LOBES as f64)) as f32;
            }
        }
        Self::new(&lobes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{chi2, Rng};

    fn two_lobes() -> VmfMixture {
        VmfMixture::new(&[
            VmfLobe {
                mu: Vec3::new(0.3, -0.4, 0.866).normalize(),
                kappa: 40.0,
                weight: 0.3,
            },
            VmfLobe {
                mu: Vec3::new(-0.8, 0.1, -0.2).normalize(),
                kappa: 2.5,
                weight: 0.7,
            },
        ])
        .unwrap()
    }

    /// Midpoint rule over the equal-area map of `uniform_sphere` (4π / n² per cell).
    fn integral(f: impl Fn(Vec3) -> f32) -> f64 {
        let n = 512;
        let mut sum = 0.0f64;
        for a in 0..n {
            for b in 0..n {
                let u = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
                sum += f(crate::math::sampling::uniform_sphere(u)) as f64;
            }
        }
        sum * 4.0 * std::f64::consts::PI / (n * n) as f64
    }

    #[test]
    fn lobes_and_mixtures_integrate_to_one() {
        for kappa in [MIN_KAPPA, 0.01, 1.0, 30.0, 300.0] {
            let lobe = VmfLobe {
                mu: Vec3::new(0.2, 0.9, -0.3).normalize(),
                kappa,
                weight: 1.0,
            };
            let i = integral(|w| lobe.pdf(w));
            assert!((i - 1.0).abs() < 2e-3, "κ {kappa}: {i}");
        }
        let i = integral(|w| two_lobes().pdf(w));
        assert!((i - 1.0).abs() < 1e-3, "{i}");
    }

    #[test]
    fn sampling_fits_the_pdf_chi2() {
        let mix = two_lobes();
        chi2::assert_sampler_fits(
            "vMF mixture",
            200_000,
            31,
            |rng| Some(mix.sample(rng.next_2d())),
            |w| mix.pdf(w) as f64,
        );
        let product = mix.product(Vec3::new(0.0, 0.6, 0.8), 1.8).unwrap();
        chi2::assert_sampler_fits(
            "vMF mixture times a lobe",
            200_000,
            32,
            |rng| Some(product.sample(rng.next_2d())),
            |w| product.pdf(w) as f64,
        );
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn chi2_detects_a_wrong_concentration() {
        // Power check: a lobe sampled with κ 40 against the density of κ 44.
        let mix = two_lobes();
        let mut lobes = *mix.lobes();
        lobes[0].kappa = 44.0;
        let claimed = VmfMixture::new(&lobes).unwrap();
        chi2::assert_sampler_fits(
            "vMF against another κ",
            200_000,
            33,
            |rng| Some(mix.sample(rng.next_2d())),
            |w| claimed.pdf(w) as f64,
        );
    }

    /// The product's density is the normalised pointwise product (checked against quadrature of the two
    /// factors), and its lobes' weights are the shares of that product's mass near their axes: the second axis
    /// (κ 2.4 against the broad lobe's κ 2.5) leaves that lobe a product of κ' ≈ 0.15, the normalisation's
    /// exp_m1 branch, the first κ' from 0.5 to 43 (its exponential and above-9 branches).
    #[test]
    fn the_product_is_the_normalised_product() {
        let mix = two_lobes();
        let broad = mix.lobes()[1];
        for (axis, kappa) in [
            (Vec3::new(-0.5, 0.5, 0.5).normalize(), 3.0),
            (-broad.mu, 2.4),
        ] {
            let factor = |w: Vec3| (kappa * (axis.dot(w) - 1.0)).exp();
            let norm = integral(|w| mix.pdf(w) * factor(w));
            let product = mix.product(axis, kappa).unwrap();
            let mut rng = Rng::new(8, 9);
            for _ in 0..200 {
                let w = crate::math::sampling::uniform_sphere(rng.next_2d());
                let expected = (mix.pdf(w) * factor(w)) as f64 / norm;
                let got = product.pdf(w) as f64;
                assert!(
                    (got - expected).abs() <= 1e-3 * expected.max(1e-4),
                    "{got} vs {expected} at {w}"
                );
            }
            // Each product lobe's weight is its share of the product's mass: the integral of its own density
            // times its weight (the product lobe's term of the density) over the sphere, by quadrature.
            for (k, l) in product.lobes().iter().enumerate() {
                let share = integral(|w| (product.ln_scale[k] + l.kappa * l.mu.dot(w)).exp());
                assert!(
                    (share - l.weight as f64).abs() < 1e-3,
                    "lobe {k}: {share} vs {}",
                    l.weight
                );
            }
        }
        // A constant factor leaves the mixture as it is.
        let same = mix.product(Vec3::Y, 0.0).unwrap();
        let w = Vec3::new(0.1, 0.2, 0.97).normalize();
        assert!((same.pdf(w) - mix.pdf(w)).abs() < 1e-4 * mix.pdf(w));
    }

    /// The fit finds two well-separated lobes from samples of them (unit weights), broadened by the prior on κ
    /// but no narrower than the truth; weights matter: the same directions with one lobe's records weighted 3×
    /// shift the mixture's mass toward it.
    #[test]
    fn em_recovers_two_lobes() {
        let truth = VmfMixture::new(&[
            VmfLobe {
                mu: Vec3::Z,
                kappa: 30.0,
                weight: 0.5,
            },
            VmfLobe {
                mu: -Vec3::X,
                kappa: 10.0,
                weight: 0.5,
            },
        ])
        .unwrap();
        let mut rng = Rng::new(1, 2);
        let records: Vec<(Vec3, f32)> = (0..FIT_RECORDS)
            .map(|_| (truth.sample(rng.next_2d()), 1.0))
            .collect();
        let fit = VmfMixture::fit(&records).unwrap();
        let mass_near = |m: &VmfMixture, d: Vec3| -> f32 {
            m.lobes()
                .iter()
                .filter(|l| l.mu.dot(d) > 0.9)
                .map(|l| l.weight)
                .sum()
        };
        let (z, x) = (mass_near(&fit, Vec3::Z), mass_near(&fit, -Vec3::X));
        assert!(
            (z - 0.5).abs() < 0.1 && (x - 0.5).abs() < 0.1,
            "{z} {x}: {fit:?}"
        );
        for d in [Vec3::Z, -Vec3::X] {
            let (a, b) = (fit.pdf(d), truth.pdf(d));
            assert!(a > 0.15 * b && a < b, "{d}: {a} vs {b}: {fit:?}");
        }
        assert!(fit.pdf(Vec3::Z) > fit.pdf(-Vec3::X), "{fit:?}");
        assert!(
            fit.pdf(Vec3::X) < 0.1 * fit.pdf(-Vec3::X),
            "{}",
            fit.pdf(Vec3::X)
        );
        let weighted: Vec<(Vec3, f32)> = records
            .iter()
            .map(|&(d, _)| (d, if d.z > 0.5 { 3.0 } else { 1.0 }))
            .collect();
        let fit = VmfMixture::fit(&weighted).unwrap();
        assert!(mass_near(&fit, Vec3::Z) > 0.65, "{fit:?}");
    }

    /// One record of a large weight among uniformly spread ones (the histograms' spikes) does not get a lobe of
    /// its own: the fitted density toward it stays within 2× of uniform.
    #[test]
    fn a_single_heavy_record_does_not_make_a_lobe() {
        let mut rng = Rng::new(3, 4);
        let spike = Vec3::new(0.48, -0.6, 0.64).normalize();
        let mut records: Vec<(Vec3, f32)> = (0..FIT_RECORDS - 1)
            .map(|_| (crate::math::sampling::uniform_sphere(rng.next_2d()), 1.0))
            .collect();
        records.push((spike, 1000.0));
        let fit = VmfMixture::fit(&records).unwrap();
        let uniform = 0.25 / PI;
        assert!(
            fit.pdf(spike) < 2.0 * uniform,
            "{} against {uniform}: {fit:?}",
            fit.pdf(spike)
        );
    }

    #[test]
    fn a_fit_without_weight_is_none() {
        assert!(VmfMixture::fit(&[]).is_none());
        assert!(VmfMixture::fit(&[(Vec3::Z, 0.0)]).is_none());
        assert!(VmfMixture::new(&[]).is_none());
    }
}
