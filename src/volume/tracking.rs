//! Free-flight sampling and transmittance estimators over a [`DensityField`] and its [`Majorants`].
//!
//! All estimators share one skeleton (`track`): map the world ray to the field's local space (same parameter
//! `t`), pull the majorant segments from a [`MajorantIterator`](super::majorant::MajorantIterator), and sample
//! tentative collisions with rate σ̄·|d| per unit of `t` (|d| the world direction's length); each estimator only
//! says what to do on entering a segment and at a tentative collision.
//! Every density lookup above the segment's majorant (beyond a relative [`VIOLATION_EPS`]) is counted in
//! [`TrackingCounters::majorant_violations`]; it is never clamped, so the estimator keeps its usual formula and
//! the caller reports the bias.
//!
//! References: Woodcock, Murphy, Hemmings, Longworth 1965 ("Techniques used in the GEM code for Monte Carlo
//! neutronics calculations"); Cramer 1978 ("Application of the fictitious scattering radiation transport model
//! for deep-penetration Monte Carlo calculations"); Novák, Selle, Jarosz 2014 ("Residual Ratio Tracking for
//! Estimating Attenuation in Participating Media"); Novák, Georgiev, Hanika, Jarosz 2018 ("Monte Carlo Methods
//! for Volumetric Light Transport Simulation", STAR).

use super::density::{local_ray, DensityField, DensityLookup};
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
    /// Majorant cells walked (DDA steps at every level of the structure, empty cells included): the traversal
    /// work, which segments merged by the adaptive structure hide.
    pub majorant_cells: u64,
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
        self.majorant_cells += other.majorant_cells;
        self.majorant_violations += other.majorant_violations;
    }
}

/// The optical depth left before the next tentative collision, carried across majorant segments.
///
/// Tentative collisions of a piecewise-constant majorant rate form a Poisson process: with an Exp(1) sample τ,
/// the next one lies where the majorant optical depth ∫σ̄ reaches τ. Each segment consumes rate × length of τ;
/// the segment where τ runs out holds the collision, at t + τ/rate (inversion of the exponential CDF). Carrying
/// τ over boundaries is the same distribution as restarting the exponential at each one (memorylessness) but
/// costs one logarithm per collision instead of one per segment, which matters on fine majorant grids.
struct FreePath {
    tau: f32,
}

impl FreePath {
    /// A fresh Exp(1) optical depth, −ln(1 − ξ).
    #[inline]
    fn new(rng: &mut Rng) -> Self {
        Self {
            tau: -(1.0 - rng.next_f32()).ln(),
        }
    }

    /// Moves `t` towards `t1` at majorant `rate` per unit of `t`. Returns true at a tentative collision (`t` is
    /// its parameter, strictly advanced, and a fresh τ is drawn for the next one), or false when the segment
    /// ends first (its optical depth is consumed).
    #[inline]
    fn next_collision(&mut self, t: &mut f32, t1: f32, rate: f32, rng: &mut Rng) -> bool {
        let room = rate * (t1 - *t);
        if self.tau >= room {
            self.tau -= room;
            return false;
        }
        let tn = (*t + self.tau / rate).max(t.next_up());
        if tn >= t1 {
            // Round-off at the boundary: the collision falls into the next segment at its start.
            self.tau = 0.0;
            return false;
        }
        *t = tn;
        *self = Self::new(rng);
        true
    }
}

/// A tentative collision: the point at parameter `t` of the local-space ray, in majorant segment `segment`,
/// with the walk's lookup state.
struct Tentative<'a, L> {
    lookup: &'a mut L,
    ray: &'a Ray,
    t: f32,
    segment: &'a Segment,
}

impl<L: DensityLookup> Tentative<'_, L> {
    /// The density lookup at the collision, counted and checked against the segment's majorant.
    #[inline]
    fn density(&mut self, c: &mut TrackingCounters) -> f32 {
        let sigma = self.lookup.density_local(self.ray.at(self.t));
        c.density_lookups += 1;
        if sigma > self.segment.sigma_max * (1.0 + VIOLATION_EPS) {
            c.majorant_violations += 1;
        }
        sigma
    }
}

/// What an estimator does on a majorant segment.
enum OnSegment {
    /// Sample tentative collisions at this rate per unit of the ray parameter.
    Track(f32),
    /// Pass the segment without tentative collisions.
    Pass,
    /// Stop tracking.
    Stop,
}

/// The part of a tracking estimator that differs between estimators; [`track`] is the skeleton they share.
trait Estimator {
    /// Entering segment `s` of a ray whose world direction has length `len`.
    fn segment(&mut self, s: &Segment, len: f32, rng: &mut Rng) -> OnSegment;
    /// A tentative collision on the segment last entered; `Break` stops tracking.
    fn collision<L: DensityLookup>(
        &mut self,
        x: &mut Tentative<'_, L>,
        rng: &mut Rng,
        c: &mut TrackingCounters,
    ) -> ControlFlow<()>;
}

/// The skeleton of every tracker: maps the world `ray` to the field's local space, walks the majorant segments
/// over `[t_min, t_max]` and samples tentative collisions on each at the rate the estimator asks for, carrying
/// the free path across segments ([`FreePath`]), until the estimator stops or the segments end. Counts the
/// segments and cells walked.
fn track<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    (t_min, t_max): (f32, f32),
    rng: &mut Rng,
    counters: &mut TrackingCounters,
    estimator: &mut impl Estimator,
) {
    let lr = local_ray(field, ray);
    let mut lookup = field.lookup();
    let len = ray.dir.length();
    let mut path = FreePath::new(rng);
    let mut segments = majorants.segments(&lr, t_min, t_max);
    'walk: for s in segments.by_ref() {
        counters.majorant_segments += 1;
        let rate = match estimator.segment(&s, len, rng) {
            OnSegment::Track(rate) => rate,
            OnSegment::Pass => continue,
            OnSegment::Stop => break,
        };
        let mut t = s.t0;
        while path.next_collision(&mut t, s.t1, rate, rng) {
            let mut x = Tentative {
                lookup: &mut lookup,
                ray: &lr,
                t,
                segment: &s,
            };
            if estimator.collision(&mut x, rng, counters).is_break() {
                break 'walk;
            }
        }
    }
    counters.majorant_cells += segments.cells();
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

/// Delta tracking's decisions: the first accepted tentative collision.
struct Delta {
    hit: Option<f32>,
}

impl Estimator for Delta {
    fn segment(&mut self, s: &Segment, len: f32, _: &mut Rng) -> OnSegment {
        OnSegment::Track(s.sigma_max * len)
    }

    fn collision<L: DensityLookup>(
        &mut self,
        x: &mut Tentative<'_, L>,
        rng: &mut Rng,
        c: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let s = x.segment;
        // σ_t = σ̄ on a uniform segment: every tentative collision is real, no lookup needed.
        if s.is_uniform() || rng.next_f32() * s.sigma_max < x.density(c) {
            c.real_collisions += 1;
            self.hit = Some(x.t);
            return ControlFlow::Break(());
        }
        c.null_collisions += 1;
        ControlFlow::Continue(())
    }
}

/// Delta (Woodcock) tracking: samples the parameter of a real collision along the world `ray` in
/// `[t_min, t_max]`, or `None` when the path leaves the interval.
///
/// Within each majorant segment tentative collisions follow the homogeneous free-flight pdf
/// σ̄ exp(−σ̄ t), and a tentative collision at x is accepted as real with probability σ_t(x)/σ̄ (Woodcock et al.
/// 1965; Novák et al. 2018 STAR §5.1, eq. 19 and Alg. 1). Restarting the exponential at each segment boundary is
/// exact by memorylessness. The escape probability is the transmittance exp(−∫σ_t). Terminates at the first
/// real collision, so optically thick media stay cheap. On a segment of constant density
/// ([`Segment::is_uniform`]) the first tentative collision is real with probability 1, so it is taken without
/// a lookup: closed-form free-flight sampling.
pub fn sample_collision<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> Option<f32> {
    let mut delta = Delta { hit: None };
    track(
        field,
        majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        &mut delta,
    );
    delta.hit
}

/// Ratio tracking's running transmittance estimate.
struct Ratio {
    tr: f32,
}

impl Estimator for Ratio {
    fn segment(&mut self, s: &Segment, len: f32, _: &mut Rng) -> OnSegment {
        if s.is_uniform() {
            // Constant density: the segment's transmittance in closed form, exactly and without lookups.
            self.tr *= (-s.sigma_max * len * (s.t1 - s.t0)).exp();
            return OnSegment::Pass;
        }
        OnSegment::Track(s.sigma_max * len)
    }

    fn collision<L: DensityLookup>(
        &mut self,
        x: &mut Tentative<'_, L>,
        rng: &mut Rng,
        c: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let sigma = x.density(c);
        c.null_collisions += 1;
        self.tr *= 1.0 - sigma / x.segment.sigma_max;
        if roulette(&mut self.tr, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}

/// Ratio tracking estimate of the transmittance exp(−∫σ_t) along the world `ray` over `[t_min, t_max]`.
///
/// Tentative collisions x_i are sampled with the majorant rate σ̄ and the estimate is
/// T = ∏ᵢ (1 − σ_t(x_i)/σ̄) (Cramer 1978; Novák et al. 2014, eq. 6; Novák et al. 2018 STAR §5.2). Russian
/// roulette below [`ROULETTE_THRESHOLD`] keeps it unbiased and bounds the work in thick media. On a segment of
/// constant density ([`Segment::is_uniform`]) the factor is exp(−σ ℓ) in closed form: residual ratio tracking
/// with the exact control, so the estimate there has zero variance and costs no lookup.
pub fn ratio_tracking<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> f32 {
    let mut ratio = Ratio { tr: 1.0 };
    track(
        field,
        majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        &mut ratio,
    );
    ratio.tr
}

/// Residual ratio tracking's running estimate, and the control of the segment last entered.
struct ResidualRatio {
    tr: f32,
    /// Control extinction σ_c.
    control: f32,
    /// Residual majorant σ̄ − σ_c.
    residual_max: f32,
}

impl Estimator for ResidualRatio {
    fn segment(&mut self, s: &Segment, len: f32, rng: &mut Rng) -> OnSegment {
        self.control = s.sigma_min.clamp(0.0, s.sigma_max);
        self.tr *= (-self.control * len * (s.t1 - s.t0)).exp();
        self.residual_max = s.sigma_max - self.control;
        if self.tr == 0.0 {
            return OnSegment::Stop;
        }
        if self.residual_max <= 0.0 {
            return OnSegment::Pass;
        }
        // Roulette only before lookups, so a homogeneous segment stays exact.
        if roulette(&mut self.tr, rng) {
            return OnSegment::Stop;
        }
        OnSegment::Track(self.residual_max * len)
    }

    fn collision<L: DensityLookup>(
        &mut self,
        x: &mut Tentative<'_, L>,
        rng: &mut Rng,
        c: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let sigma = x.density(c);
        c.null_collisions += 1;
        self.tr *= 1.0 - (sigma - self.control) / self.residual_max;
        if roulette(&mut self.tr, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
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
    let mut residual = ResidualRatio {
        tr: 1.0,
        control: 0.0,
        residual_max: 0.0,
    };
    track(
        field,
        majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        &mut residual,
    );
    residual.tr
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Aabb, Vec3};
    use crate::volume::density::test_fields::{block_grid, sphere_grid};
    use crate::volume::density::{AnalyticDensity, GridDensity};
    use crate::volume::majorant::MajorantKind;

    /// Mean and standard error of `n` samples of `f`.
    fn estimate(n: usize, mut f: impl FnMut() -> f64) -> (f64, f64) {
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let x = f();
            assert!(x.is_finite());
            s += x;
            s2 += x * x;
        }
        let m = s / n as f64;
        let var = (s2 / n as f64 - m * m).max(0.0);
        (m, (var / n as f64).sqrt())
    }

    fn check(label: &str, (m, se): (f64, f64), truth: f64) {
        // 4 standard errors, plus a floor for estimators with (near) zero variance.
        assert!(
            (m - truth).abs() <= 4.0 * se + 1e-6 * truth.max(1e-3),
            "{label}: {m} ± {se} vs {truth}"
        );
    }

    /// Checks delta, ratio and residual ratio tracking against `truth` = exp(−τ) on `ray` over `[t0, t1]`.
    fn check_all<F: DensityField + ?Sized>(
        label: &str,
        f: &F,
        maj: &Majorants,
        ray: &Ray,
        (t0, t1): (f32, f32),
        truth: f64,
        n: usize,
    ) -> TrackingCounters {
        let mut rng = Rng::new(17, 5);
        let mut c = TrackingCounters::default();
        let d = estimate(n, || {
            sample_collision(f, maj, ray, t0, t1, &mut rng, &mut c).map_or(1.0, |_| 0.0)
        });
        check(&format!("{label} delta"), d, truth);
        let r = estimate(n, || {
            ratio_tracking(f, maj, ray, t0, t1, &mut rng, &mut c) as f64
        });
        check(&format!("{label} ratio"), r, truth);
        let rr = estimate(n, || {
            residual_ratio_tracking(f, maj, ray, t0, t1, &mut rng, &mut c) as f64
        });
        check(&format!("{label} residual"), rr, truth);
        assert_eq!(c.majorant_violations, 0, "{label}");
        c
    }

    #[test]
    fn homogeneous_box_every_majorant_kind() {
        // 24 voxels of 0.1 m along x, σ_t = 5/m: τ = 5 · 2.4 = 12 on an interior axis-aligned ray.
        let g = block_grid(24, 0.1, 0.5);
        let ray = Ray::new(Vec3::new(-3.0, 1.03, 3.17), Vec3::X);
        let truth = (-0.5f64 * 2.4).exp();
        let q = optical_depth_quadrature(&g, &ray, 0.0, 10.0, 100_000);
        assert!((q - 1.2).abs() < 1e-3, "{q}");
        for kind in MajorantKind::ALL {
            let maj = Majorants::build(kind, &g);
            check_all(
                &format!("{kind:?}"),
                &g,
                &maj,
                &ray,
                (0.0, 10.0),
                truth,
                40_000,
            );
        }
        // And an analytic box with an oblique, non-unit direction.
        let bounds = Aabb::new(Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0));
        let f = AnalyticDensity::Constant { bounds, sigma: 1.5 };
        let ray = Ray::new(Vec3::new(-1.0, 0.2, 0.3), Vec3::new(2.0, 0.2, 0.1));
        let truth = (-f.optical_depth(&ray, 0.0, 5.0)).exp();
        let maj = Majorants::analytic(&f);
        check_all("const", &f, &maj, &ray, (0.0, 5.0), truth, 40_000);
        // Homogeneous: residual ratio tracking integrates the control exactly and needs no lookup.
        let mut c = TrackingCounters::default();
        let t = residual_ratio_tracking(&f, &maj, &ray, 0.0, 5.0, &mut Rng::new(1, 2), &mut c);
        assert!(
            (t as f64 - truth).abs() < 1e-6 && c.density_lookups == 0,
            "{t} {c:?}"
        );
    }

    #[test]
    fn ramp_and_exponential_agree_with_closed_form() {
        let bounds = Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        let ray = Ray::new(
            Vec3::new(-2.0, 0.1, -0.3),
            Vec3::new(1.0, 0.05, 0.1).normalize(),
        );
        for f in [
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 0.2,
                sigma1: 3.0,
            },
            AnalyticDensity::Exponential {
                bounds,
                axis: 0,
                sigma0: 4.0,
                falloff: 2.0,
            },
        ] {
            let tau = f.optical_depth(&ray, 0.0, 6.0);
            let q = optical_depth_quadrature(&f, &ray, 0.0, 6.0, 100_000);
            assert!((tau - q).abs() < 1e-4 * tau);
            check_all(
                &format!("{f:?}"),
                &f,
                &Majorants::analytic(&f),
                &ray,
                (0.0, 6.0),
                (-tau).exp(),
                40_000,
            );
        }
    }

    fn random_rays(g: &GridDensity, n: usize, seed: u64) -> Vec<Ray> {
        let b = g.bounds();
        let mut rng = Rng::new(seed, 1);
        let u3 = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        (0..n)
            .map(|_| {
                let target = b.min + u3(&mut rng) * b.extent();
                let from = b.center() + (u3(&mut rng) - 0.5).normalize() * b.extent().length();
                Ray::new(from, (target - from).normalize())
            })
            .collect()
    }

    #[test]
    fn sphere_grid_kinds_agree_with_quadrature() {
        let g = sphere_grid(8.0);
        let rays = random_rays(&g, 24, 3);
        let kinds = MajorantKind::ALL.map(|k| Majorants::build(k, &g));
        let mut tau_max = 0.0f64;
        for (i, ray) in rays.iter().enumerate() {
            let tau = optical_depth_quadrature(&g, ray, 0.0, 20.0, 20_000);
            tau_max = tau_max.max(tau);
            for m in &kinds {
                check_all(
                    &format!("ray {i} {:?}", m.kind()),
                    &g,
                    m,
                    ray,
                    (0.0, 20.0),
                    (-tau).exp(),
                    4_000,
                );
            }
        }
        assert!(
            tau_max > 2.0,
            "the test medium should be optically thick somewhere: {tau_max}"
        );
    }

    #[test]
    fn underestimated_majorant_is_detected() {
        let g = sphere_grid(8.0);
        let good = Majorants::build(MajorantKind::Global, &g);
        let bad = Majorants::global(g.index_bounds(), 0.0, 0.5 * good.global_max());
        let mut rng = Rng::new(1, 1);
        let mut c = TrackingCounters::default();
        for ray in random_rays(&g, 64, 9) {
            sample_collision(&g, &bad, &ray, 0.0, 20.0, &mut rng, &mut c);
            ratio_tracking(&g, &bad, &ray, 0.0, 20.0, &mut rng, &mut c);
        }
        assert!(c.majorant_violations > 0, "{c:?}");
    }

    #[test]
    fn thick_and_thin_media_are_fast_and_correct() {
        let bounds = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        for f in [
            AnalyticDensity::Constant {
                bounds,
                sigma: 5000.0,
            },
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 2500.0,
                sigma1: 7500.0,
            },
        ] {
            let c = check_all(
                "thick",
                &f,
                &Majorants::analytic(&f),
                &ray,
                (0.0, 3.0),
                0.0,
                20_000,
            );
            // Delta tracking stops at the first real collision; ratio tracking is cut by roulette.
            assert!(c.density_lookups < 20 * 20_000, "{c:?}");
        }
        let thick = block_grid(16, 0.1, 3125.0); // σ_t·d = 3125 · 1.6 = 5000
        let gray = Ray::new(Vec3::new(-3.0, 0.73, 3.11), Vec3::X);
        for kind in MajorantKind::ALL {
            check_all(
                "thick grid",
                &thick,
                &Majorants::build(kind, &thick),
                &gray,
                (0.0, 10.0),
                0.0,
                2_000,
            );
        }
        for f in [
            AnalyticDensity::Constant {
                bounds,
                sigma: 1e-3,
            },
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 0.0,
                sigma1: 2e-3,
            },
        ] {
            let truth = (-f.optical_depth(&ray, 0.0, 3.0)).exp();
            assert!((truth - (-1e-3f64).exp()).abs() < 1e-6);
            check_all(
                "thin",
                &f,
                &Majorants::analytic(&f),
                &ray,
                (0.0, 3.0),
                truth,
                40_000,
            );
        }
    }
}
