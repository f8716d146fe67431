//! Free-flight sampling and transmittance estimators over a [`DensityField`] and its [`Majorants`].
//!
//! All estimators map the world ray to the field's local space (same parameter `t`), walk the majorant
//! segments, and sample tentative collisions with rate σ̄·|d| per unit of `t` (|d| the world direction's length).
//! Every density lookup above the segment's majorant (beyond a relative [`VIOLATION_EPS`]) is counted in
//! [`TrackingCounters::majorant_violations`]; it is never clamped, so the estimator keeps its usual formula and
//! the caller reports the bias.
//!
//! References: Woodcock, Murphy, Hemmings, Longworth 1965 ("Techniques used in the GEM code for Monte Carlo
//! neutronics calculations"); Cramer 1978 ("Application of the fictitious scattering radiation transport model
//! for deep-penetration Monte Carlo calculations"); Novák, Selle, Jarosz 2014 ("Residual Ratio Tracking for
//! Estimating Attenuation in Participating Media"); Novák, Georgiev, Hanika, Jarosz 2018 ("Monte Carlo Methods
//! for Volumetric Light Transport Simulation", STAR).

use super::density::{local_ray, DensityField};
use super::majorant::{Majorants, Segment};
use crate::math::{Ray, Rng};
use std::ops::ControlFlow;

/// Relative tolerance above a majorant before a lookup counts as a violation.
pub const VIOLATION_EPS: f32 = 1e-4;
/// Russian roulette starts when the running transmittance weight falls below this value.
pub const ROULETTE_THRESHOLD: f32 = 0.1;

/// Work and correctness counters of the tracking estimators, accumulated through `&mut`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct TrackingCounters {
    /// Density lookups.
    pub density_lookups: u64,
    /// Accepted (real) collisions in delta tracking.
    pub real_collisions: u64,
    /// Rejected (null) collisions in delta tracking, and tentative collisions in ratio tracking.
    pub null_collisions: u64,
    /// Majorant segments visited.
    pub majorant_segments: u64,
    /// Lookups where σ_t exceeded the segment's majorant.
    pub majorant_violations: u64,
}

impl TrackingCounters {
    /// Adds `other` into `self`.
    pub fn add(&mut self, other: &TrackingCounters) {
        self.density_lookups += other.density_lookups;
        self.real_collisions += other.real_collisions;
        self.null_collisions += other.null_collisions;
        self.majorant_segments += other.majorant_segments;
        self.majorant_violations += other.majorant_violations;
    }
}

/// Samples the next tentative collision after `t` with rate `rate` per unit of `t`: t − ln(1 − ξ)/rate
/// (the exponential free-flight distribution of a homogeneous medium of extinction `rate`). Always advances `t`.
#[inline]
fn next_collision(t: f32, rate: f32, rng: &mut Rng) -> f32 {
    let tn = t - (1.0 - rng.next_f32()).ln() / rate;
    if tn > t {
        tn
    } else {
        t.next_up()
    }
}

/// One density lookup at local parameter `t`, counted and checked against the segment's majorant.
#[inline]
fn lookup<F: DensityField + ?Sized>(
    field: &F,
    ray: &Ray,
    t: f32,
    s: &Segment,
    c: &mut TrackingCounters,
) -> f32 {
    let sigma = field.density_local(ray.at(t));
    c.density_lookups += 1;
    if sigma > s.sigma_max * (1.0 + VIOLATION_EPS) {
        c.majorant_violations += 1;
    }
    sigma
}

/// Unbiased Russian roulette on a transmittance weight: below [`ROULETTE_THRESHOLD`] the path survives with
/// probability q = |T|/threshold and is divided by q (so E[T] is unchanged). Returns true when terminated.
#[inline]
fn roulette(tr: &mut f32, rng: &mut Rng) -> bool {
    let a = tr.abs();
    if a < ROULETTE_THRESHOLD {
        let q = a / ROULETTE_THRESHOLD;
        if rng.next_f32() >= q {
            *tr = 0.0;
            return true;
        }
        *tr /= q;
    }
    false
}

/// Delta (Woodcock) tracking: samples the parameter of a real collision along the world `ray` in
/// `[t_min, t_max]`, or `None` when the path leaves the interval.
///
/// Within each majorant segment tentative collisions follow the homogeneous free-flight pdf
/// σ̄ exp(−σ̄ t), and a tentative collision at x is accepted as real with probability σ_t(x)/σ̄ (Woodcock et al.
/// 1965; Novák et al. 2018 STAR §5.1, eq. 19 and Alg. 1). Restarting the exponential at each segment boundary is
/// exact by memorylessness. The escape probability is the transmittance exp(−∫σ_t). Terminates at the first
/// real collision, so optically thick media stay cheap.
pub fn sample_collision<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> Option<f32> {
    let lr = local_ray(field, ray);
    let len = ray.dir.length();
    let mut hit = None;
    let _ = majorants.for_each_segment(&lr, t_min, t_max, |s| {
        counters.majorant_segments += 1;
        let rate = s.sigma_max * len;
        let mut t = s.t0;
        loop {
            t = next_collision(t, rate, rng);
            if t >= s.t1 {
                return ControlFlow::Continue(());
            }
            let sigma = lookup(field, &lr, t, &s, counters);
            if rng.next_f32() * s.sigma_max < sigma {
                counters.real_collisions += 1;
                hit = Some(t);
                return ControlFlow::Break(());
            }
            counters.null_collisions += 1;
        }
    });
    hit
}

/// Ratio tracking estimate of the transmittance exp(−∫σ_t) along the world `ray` over `[t_min, t_max]`.
///
/// Tentative collisions x_i are sampled with the majorant rate σ̄ and the estimate is
/// T = ∏ᵢ (1 − σ_t(x_i)/σ̄) (Cramer 1978; Novák et al. 2014, eq. 6; Novák et al. 2018 STAR §5.2). Russian
/// roulette below [`ROULETTE_THRESHOLD`] keeps it unbiased and bounds the work in thick media.
pub fn ratio_tracking<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> f32 {
    let lr = local_ray(field, ray);
    let len = ray.dir.length();
    let mut tr = 1.0f32;
    let _ = majorants.for_each_segment(&lr, t_min, t_max, |s| {
        counters.majorant_segments += 1;
        let rate = s.sigma_max * len;
        let mut t = s.t0;
        loop {
            t = next_collision(t, rate, rng);
            if t >= s.t1 {
                return ControlFlow::Continue(());
            }
            let sigma = lookup(field, &lr, t, &s, counters);
            counters.null_collisions += 1;
            tr *= 1.0 - sigma / s.sigma_max;
            if roulette(&mut tr, rng) {
                return ControlFlow::Break(());
            }
        }
    });
    tr
}

/// Residual ratio tracking estimate of the transmittance along the world `ray` over `[t_min, t_max]`.
///
/// Per segment the control extinction σ_c is the segment's minorant; the control part is integrated in closed
/// form and only the residual σ_r = σ_t − σ_c is tracked with the residual majorant σ̄_r = σ̄ − σ_c:
/// T = exp(−σ_c ℓ) · ∏ᵢ (1 − (σ_t(x_i) − σ_c)/σ̄_r) (Novák et al. 2014, §4, eq. 12–13). Where the segment is
/// homogeneous (σ̄_r = 0) it costs no lookup. With σ_c = 0 it reduces to [`ratio_tracking`]. Russian roulette as
/// in ratio tracking.
pub fn residual_ratio_tracking<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> f32 {
    let lr = local_ray(field, ray);
    let len = ray.dir.length();
    let mut tr = 1.0f32;
    let _ = majorants.for_each_segment(&lr, t_min, t_max, |s| {
        counters.majorant_segments += 1;
        let control = s.sigma_min.clamp(0.0, s.sigma_max);
        tr *= (-control * len * (s.t1 - s.t0)).exp();
        if roulette(&mut tr, rng) {
            return ControlFlow::Break(());
        }
        let residual_max = s.sigma_max - control;
        if residual_max <= 0.0 {
            return ControlFlow::Continue(());
        }
        let rate = residual_max * len;
        let mut t = s.t0;
        loop {
            t = next_collision(t, rate, rng);
            if t >= s.t1 {
                return ControlFlow::Continue(());
            }
            let sigma = lookup(field, &lr, t, &s, counters);
            counters.null_collisions += 1;
            tr *= 1.0 - (sigma - control) / residual_max;
            if roulette(&mut tr, rng) {
                return ControlFlow::Break(());
            }
        }
    });
    tr
}

/// Deterministic reference optical depth ∫σ_t(o + t d)|d| dt over `[t0, t1]` of the world `ray`, by the
/// composite midpoint rule with `steps` intervals (f64 accumulation). For tests and references.
pub fn optical_depth_quadrature<F: DensityField + ?Sized>(
    field: &F,
    ray: &Ray,
    t0: f32,
    t1: f32,
    steps: usize,
) -> f64 {
    let steps = steps.max(1);
    let dt = (t1 as f64 - t0 as f64) / steps as f64;
    let mut sum = 0.0f64;
    for i in 0..steps {
        let t = t0 as f64 + (i as f64 + 0.5) * dt;
        sum += field.density(ray.at(t as f32)) as f64;
    }
    sum * dt * ray.dir.as_dvec3().length()
}
