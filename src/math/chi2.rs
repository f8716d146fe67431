//! Pearson chi-square goodness-of-fit tests for direction samplers on the unit sphere, and for samplers of an
//! interval (test-only).
//!
//! The sphere is cut into `N_COS × N_PHI` bins that are equal in (cos θ, φ) ∈ \[−1, 1\] × \[0, 2π), which
//! makes them equal in solid angle. The expected count of a bin is the number of samples times the
//! integral of the claimed density over the bin, computed with nested adaptive Simpson quadrature
//! (Kuncir 1962) started from a fine grid so that narrow lobes are found. Samples the sampler rejects
//! (`None`) fall in one extra bin whose expected count is the density's missing mass. Bins expecting
//! fewer than 5 samples are pooled. The p-value is the upper tail of the chi-square distribution,
//! `Q(k/2, χ²/2)` with the regularised incomplete gamma function of Abramowitz & Stegun §6.5.

use crate::math::{Rng, Vec3};
use std::f64::consts::PI;

/// Bins in cos θ.
const N_COS: usize = 10;
/// Bins in φ.
const N_PHI: usize = 20;
/// Initial Simpson panels per bin and dimension, fine enough that no lobe wider than ~1/200 of the
/// sphere's cos θ range slips between the quadrature nodes.
const PANELS: usize = 8;
/// Smallest expected count a bin may have before it is pooled (Cochran's rule).
const MIN_EXPECTED: f64 = 5.0;
/// Family-wise significance of all chi-square tests of the crate.
const ALPHA: f64 = 0.01;
/// An upper bound on the number of chi-square tests in the crate; each test rejects at the Šidák-corrected
/// level `1 − (1 − ALPHA)^(1/FAMILY_SIZE)`.
const FAMILY_SIZE: usize = 150;

/// ln Γ(x) for x > 0: the recurrence Γ(x+1) = xΓ(x) lifts x above 8, then Stirling's series
/// (Abramowitz & Stegun 6.1.41) truncated after the x⁻⁷ term (error below 1e-12 there).
fn ln_gamma(x: f64) -> f64 {
    let mut x = x;
    let mut shift = 0.0;
    while x < 8.0 {
        shift += x.ln();
        x += 1.0;
    }
    let inv = 1.0 / x;
    let inv2 = inv * inv;
    let series = inv * (1.0 / 12.0 - inv2 * (1.0 / 360.0 - inv2 * (1.0 / 1260.0 - inv2 / 1680.0)));
    (x - 0.5) * x.ln() - x + 0.5 * (2.0 * PI).ln() + series - shift
}

/// Regularised upper incomplete gamma function Q(a, x) = Γ(a, x) / Γ(a). For x < a + 1 it is 1 − P(a, x)
/// with P from its power series (Abramowitz & Stegun 6.5.29); otherwise the continued fraction of
/// A&S 6.5.31 evaluated with the modified Lentz method (Thompson & Barnett 1986).
pub(crate) fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let prefactor = (-x + a * x.ln() - ln_gamma(a)).exp();
    if x < a + 1.0 {
        let mut term = 1.0 / a;
        let mut sum = term;
        for n in 1..10_000 {
            term *= x / (a + n as f64);
            sum += term;
            if term < sum * 1e-16 {
                break;
            }
        }
        (1.0 - prefactor * sum).max(0.0)
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        prefactor * h
    }
}

/// Adaptive Simpson quadrature of `f` over \[a, b\] (Kuncir 1962 with Richardson's correction), started from
/// `PANELS` panels.
fn integrate(f: &dyn Fn(f64) -> f64, a: f64, b: f64, eps: f64) -> f64 {
    /// One Simpson step on \[a, b\] with the values `fs` at a, the midpoint and b.
    fn refine(
        f: &dyn Fn(f64) -> f64,
        (a, b): (f64, f64),
        fs: [f64; 3],
        whole: f64,
        eps: f64,
        depth: u32,
    ) -> f64 {
        let [fa, fm, fb] = fs;
        let m = 0.5 * (a + b);
        let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
        let (flm, frm) = (f(lm), f(rm));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let diff = left + right - whole;
        if depth == 0 || diff.abs() <= 15.0 * eps {
            return left + right + diff / 15.0;
        }
        refine(f, (a, m), [fa, flm, fm], left, 0.5 * eps, depth - 1)
            + refine(f, (m, b), [fm, frm, fb], right, 0.5 * eps, depth - 1)
    }
    let h = (b - a) / PANELS as f64;
    (0..PANELS)
        .map(|i| {
            let (x0, x1) = (a + i as f64 * h, a + (i + 1) as f64 * h);
            let (f0, fm, f1) = (f(x0), f(0.5 * (x0 + x1)), f(x1));
            let whole = h / 6.0 * (f0 + 4.0 * fm + f1);
            refine(f, (x0, x1), [f0, fm, f1], whole, eps / PANELS as f64, 14)
        })
        .sum()
}

/// The unit direction with the given cos θ and φ.
fn direction(cos_theta: f64, phi: f64) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    Vec3::new(
        (sin_theta * phi.cos()) as f32,
        (sin_theta * phi.sin()) as f32,
        cos_theta as f32,
    )
}

/// Index of the (cos θ, φ) bin holding `w`.
fn bin_of(w: Vec3) -> usize {
    let c = ((w.z as f64 + 1.0) * 0.5 * N_COS as f64)
        .floor()
        .clamp(0.0, N_COS as f64 - 1.0) as usize;
    let mut phi = (w.y as f64).atan2(w.x as f64);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let p = (phi / (2.0 * PI) * N_PHI as f64)
        .floor()
        .clamp(0.0, N_PHI as f64 - 1.0) as usize;
    c * N_PHI + p
}

/// The p-value of Pearson's chi-square statistic for `observed` against `expected` counts, after pooling
/// every bin expecting fewer than `MIN_EXPECTED` samples into one (merged with the smallest remaining bin if
/// the pool itself is still too small). Degrees of freedom: the number of cells − 1.
pub(crate) fn p_value(observed: &[f64], expected: &[f64]) -> f64 {
    let mut cells: Vec<(f64, f64)> = Vec::new();
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        if e < MIN_EXPECTED {
            pool_o += o;
            pool_e += e;
        } else {
            cells.push((o, e));
        }
    }
    if pool_o > 0.0 || pool_e > 0.0 {
        if pool_e < MIN_EXPECTED && !cells.is_empty() {
            let smallest = (0..cells.len())
                .min_by(|&i, &j| cells[i].1.total_cmp(&cells[j].1))
                .unwrap_or(0);
            cells[smallest].0 += pool_o;
            cells[smallest].1 += pool_e;
        } else {
            cells.push((pool_o, pool_e));
        }
    }
    if cells.len() < 2 {
        return 1.0;
    }
    let mut chi2 = 0.0;
    for &(o, e) in &cells {
        if e <= 0.0 {
            return if o > 0.0 { 0.0 } else { 1.0 };
        }
        chi2 += (o - e) * (o - e) / e;
    }
    let dof = (cells.len() - 1) as f64;
    gamma_q(0.5 * dof, 0.5 * chi2)
}

/// Draws `samples` directions from `sample` (seeded with `seed`), bins them and tests them against the
/// solid-angle density `pdf`; panics, naming `name`, when the fit is rejected at the Šidák-corrected level.
/// Returns the p-value.
pub(crate) fn assert_sampler_fits(
    name: &str,
    samples: usize,
    seed: u64,
    mut sample: impl FnMut(&mut Rng) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
) -> f64 {
    let n_bins = N_COS * N_PHI;
    let mut observed = vec![0.0; n_bins + 1];
    let mut rng = Rng::new(seed, 0x0c41_2a11);
    for _ in 0..samples {
        match sample(&mut rng) {
            Some(w) => observed[bin_of(w)] += 1.0,
            None => observed[n_bins] += 1.0,
        }
    }
    let (dc, dp) = (2.0 / N_COS as f64, 2.0 * PI / N_PHI as f64);
    // Absolute tolerance per bin: a count error far below one sample.
    let eps = 0.02 / samples as f64;
    let mut expected = vec![0.0; n_bins + 1];
    for (i, e) in expected.iter_mut().take(n_bins).enumerate() {
        let (c0, p0) = (-1.0 + (i / N_PHI) as f64 * dc, (i % N_PHI) as f64 * dp);
        let inner = |phi: f64| integrate(&|c: f64| pdf(direction(c, phi)), c0, c0 + dc, eps);
        *e = integrate(&inner, p0, p0 + dp, eps) * samples as f64;
    }
    let total: f64 = expected.iter().sum();
    expected[n_bins] = (samples as f64 - total).max(0.0);
    assert_fits(name, &observed, &expected)
}

/// The p-value of `observed` against `expected` counts; panics, naming `name`, when the fit is rejected at the
/// Šidák-corrected level.
fn assert_fits(name: &str, observed: &[f64], expected: &[f64]) -> f64 {
    let p = p_value(observed, expected);
    let threshold = 1.0 - (1.0 - ALPHA).powf(1.0 / FAMILY_SIZE as f64);
    eprintln!("chi2 {name}: p = {p:.4}");
    assert!(
        p >= threshold,
        "{name}: chi-square rejects the sampler (p = {p:.3e} < {threshold:.3e})"
    );
    p
}

/// Bins of the one-dimensional test.
const N_INTERVAL_BINS: usize = 64;

/// Draws `samples` values from `sample`, bins them over `interval` and tests them against the density `pdf`
/// (per unit length) with Pearson's chi-square; samples outside the interval count against its missing mass.
/// Panics, naming `name`, when the fit is rejected at the Šidák-corrected level. Returns the p-value.
pub(crate) fn assert_interval_sampler_fits(
    name: &str,
    samples: usize,
    interval: (f64, f64),
    mut sample: impl FnMut() -> f32,
    pdf: impl Fn(f64) -> f64,
) -> f64 {
    let (lo, hi) = interval;
    let width = (hi - lo) / N_INTERVAL_BINS as f64;
    let mut observed = vec![0.0; N_INTERVAL_BINS + 1];
    for _ in 0..samples {
        let x = sample() as f64;
        let bin = ((x - lo) / width).floor();
        if (0.0..N_INTERVAL_BINS as f64).contains(&bin) {
            observed[bin as usize] += 1.0;
        } else if x == hi {
            observed[N_INTERVAL_BINS - 1] += 1.0;
        } else {
            observed[N_INTERVAL_BINS] += 1.0;
        }
    }
    let eps = 0.02 / samples as f64;
    let mut expected: Vec<f64> = (0..N_INTERVAL_BINS)
        .map(|i| {
            let a = lo + i as f64 * width;
            integrate(&pdf, a, a + width, eps) * samples as f64
        })
        .collect();
    let total: f64 = expected.iter().sum();
    expected.push((samples as f64 - total).max(0.0));
    assert_fits(name, &observed, &expected)
}

/// Draws `samples` indices in `0..n` from `sample` (`None`: the sampler chose nothing) and tests them against
/// the probabilities `pmf` with Pearson's chi-square; a shortfall of the probabilities below 1 is the
/// expected share of `None`. Panics, naming `name`, when the fit is rejected at the Šidák-corrected level.
/// Returns the p-value.
pub(crate) fn assert_discrete_sampler_fits(
    name: &str,
    samples: usize,
    n: usize,
    mut sample: impl FnMut() -> Option<usize>,
    pmf: impl Fn(usize) -> f64,
) -> f64 {
    let mut observed = vec![0.0; n + 1];
    for _ in 0..samples {
        match sample() {
            Some(i) if i < n => observed[i] += 1.0,
            _ => observed[n] += 1.0,
        }
    }
    let mut expected: Vec<f64> = (0..n).map(|i| pmf(i) * samples as f64).collect();
    let total: f64 = expected.iter().sum();
    expected.push((samples as f64 - total).max(0.0));
    assert_fits(name, &observed, &expected)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_gamma_matches_closed_forms_and_tables() {
        // Q(1, x) = e^{−x}.
        for x in [0.1, 1.0, 3.0, 20.0] {
            let q = gamma_q(1.0, x);
            assert!((q - (-x).exp()).abs() < 1e-10, "Q(1, {x}) = {q}");
        }
        // Upper 1% points of chi-square: 6.635 (1 dof), 23.209 (10 dof), 135.807 (100 dof).
        for (dof, x) in [(1.0, 6.634_897), (10.0, 23.209_251), (100.0, 135.806_723)] {
            let p = gamma_q(0.5 * dof, 0.5 * x);
            assert!((p - 0.01).abs() < 1e-5, "dof {dof}: {p}");
        }
        assert!((ln_gamma(0.5) - 0.5 * PI.ln()).abs() < 1e-10);
    }

    #[test]
    fn uniform_sphere_passes_and_a_biased_sampler_fails() {
        let uniform = |rng: &mut Rng| Some(crate::math::sampling::uniform_sphere(rng.next_2d()));
        let p = assert_sampler_fits("uniform sphere", 100_000, 3, uniform, |_| 0.25 / PI);
        assert!(p > 0.0);
        // A cosine-weighted hemisphere is not uniform on the sphere: the test must reject it.
        let mut rng = Rng::new(9, 9);
        let mut observed = vec![0.0; N_COS * N_PHI + 1];
        for _ in 0..100_000 {
            observed[bin_of(crate::math::sampling::cosine_hemisphere(rng.next_2d()))] += 1.0;
        }
        let mut expected = vec![100_000.0 / (N_COS * N_PHI) as f64; N_COS * N_PHI];
        expected.push(0.0);
        assert!(p_value(&observed, &expected) < 1e-10);
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn the_discrete_test_rejects_a_wrong_pmf() {
        let mut rng = Rng::new(4, 4);
        let claimed = [0.4, 0.3, 0.2, 0.1];
        assert_discrete_sampler_fits(
            "uniform as if skewed",
            20_000,
            4,
            || Some((rng.next_f32() * 4.0) as usize),
            |i| claimed[i],
        );
    }
}
