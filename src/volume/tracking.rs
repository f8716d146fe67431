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
//! On grids, a segment whose majorant optical depth per voxel exceeds [`REFINE_TAU`] is walked voxel cell by
//! voxel cell, each cell bounded exactly by its eight voxels (which also count as violations where they exceed
//! the structure's bound): the resolution of the majorants follows their optical depth, so that the work of a
//! free flight stays flat as the density scale grows. Free flights are sampled by delta tracking or by
//! decomposition tracking ([`decomposition_tracking`], Kutz et al. 2017), which takes the collisions that fall
//! under the segment's minorant without a lookup. Free flights through an RGB extinction are sampled for all
//! three channels at once by spectral tracking ([`spectral_tracking`], Kutz et al. 2017), over the majorants of
//! the channels' maximum.
//!
//! References: Woodcock, Murphy, Hemmings, Longworth 1965 ("Techniques used in the GEM code for Monte Carlo
//! neutronics calculations"); Cramer 1978 ("Application of the fictitious scattering radiation transport model
//! for deep-penetration Monte Carlo calculations"); Novák, Selle, Jarosz 2014 ("Residual Ratio Tracking for
//! Estimating Attenuation in Participating Media"); Novák, Georgiev, Hanika, Jarosz 2018 ("Monte Carlo Methods
//! for Volumetric Light Transport Simulation", STAR); Kutz, Habel, Li, Novák 2017 ("Spectral and Decomposition
//! Tracking for Rendering Heterogeneous Volumes").

use super::density::{local_ray, DensityField, DensityLookup};
use super::majorant::{Majorants, Segment, VoxelCells};
use super::Flight;
use crate::math::{Ray, Rgb, Rng};
use std::ops::ControlFlow;

/// Relative tolerance above a majorant before a lookup counts as a violation.
pub const VIOLATION_EPS: f32 = 1e-4;
/// Russian roulette starts when the running transmittance weight falls below this value.
pub const ROULETTE_THRESHOLD: f32 = 0.1;
/// Majorant optical depth per voxel above which a grid's majorant segment is walked voxel by voxel, each voxel
/// cell bounded by its eight voxels ([`DensityLookup::cell_bounds`]).
///
/// A piecewise-constant majorant over a cell of many voxels wastes σ̄/σ_t − 1 null collisions per real one
/// wherever the density is below the cell's maximum, and in a thick medium the real collisions happen right
/// where it is: at the rim, where the density ramps up from zero across the cell. That waste grows with the
/// density scale (about as its square root on a linear ramp). Refining to voxel cells, whose trilinear density
/// is bounded exactly by their corners, costs one read of eight voxels per cell crossed but keeps σ̄/σ_t near 1
/// on a smooth field and gives each cell a minorant (the control of [`decomposition_tracking`]), so the work per
/// free flight stays flat as the density grows. A ray crosses up to √3 cells per voxel of length and a cell
/// read costs about a lookup, so refinement pays only well above one tentative collision per voxel: at 1, the
/// stability suite's g = ±0.99 balls read 60 % more (lookups plus cells) than unrefined, while the bundled
/// cloud and plume at 10× and 100× density did about as well as at 4 (`benches/free_flight.rs`). The
/// resolution of the majorants thus follows their optical depth per cell.
pub const REFINE_TAU: f32 = 4.0;

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
    /// Lookups where σ_t exceeded the segment's majorant, and voxel cells of a refined segment whose voxels
    /// exceeded it.
    pub majorant_violations: u64,
    /// Voxel cells walked where a segment was refined to voxel bounds (`REFINE_TAU`): each reads the eight
    /// voxels of its cell, about the work of one density lookup.
    pub voxel_cells: u64,
    /// Free flights sampled by spectral tracking (`spectral_tracking`: all three channels of an RGB
    /// extinction at once).
    pub spectral_flights: u64,
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
        self.voxel_cells += other.voxel_cells;
        self.spectral_flights += other.spectral_flights;
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

/// One tracking walk's state: the local ray, its lookups, the free path and the estimator.
struct Walker<'a, L, E> {
    lr: Ray,
    /// Length of the world direction.
    len: f32,
    lookup: L,
    path: FreePath,
    estimator: &'a mut E,
}

impl<L: DensityLookup, E: Estimator> Walker<'_, L, E> {
    /// Tracks through segment `s` at the rate the estimator asks for; `Break` when the estimator stops.
    #[inline]
    fn segment(
        &mut self,
        s: &Segment,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let rate = match self.estimator.segment(s, self.len, rng) {
            OnSegment::Track(rate) => rate,
            OnSegment::Pass => return ControlFlow::Continue(()),
            OnSegment::Stop => return ControlFlow::Break(()),
        };
        let mut t = s.t0;
        while self.path.next_collision(&mut t, s.t1, rate, rng) {
            let mut x = Tentative {
                lookup: &mut self.lookup,
                ray: &self.lr,
                t,
                segment: s,
            };
            self.estimator.collision(&mut x, rng, counters)?;
        }
        ControlFlow::Continue(())
    }

    /// Tracks through segment `s` voxel cell by voxel cell, each a segment bounded by its eight voxels
    /// ([`REFINE_TAU`]); cells of zero density are passed.
    fn voxel_cells(
        &mut self,
        s: &Segment,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let mut cells = VoxelCells::new(&self.lr, s.t0, s.t1);
        while let Some((cell, t0, t1)) = cells.next(&mut counters.voxel_cells) {
            let Some((sigma_min, sigma_max)) = self.lookup.cell_bounds(cell) else {
                // Not a voxel field (an analytic one): the rest of the segment as it is.
                return self.segment(&Segment { t0, ..*s }, rng, counters);
            };
            // Every lookup in the cell reads its eight voxels, which the structure's segment must bound: a cell
            // above it is the structure's violation, counted even though the cell's own bound is exact.
            if sigma_max > s.sigma_max * (1.0 + VIOLATION_EPS) {
                counters.majorant_violations += 1;
            }
            if sigma_max > 0.0 {
                let cell = Segment {
                    t0,
                    t1,
                    sigma_max,
                    sigma_min,
                };
                self.segment(&cell, rng, counters)?;
            }
        }
        ControlFlow::Continue(())
    }
}

/// The skeleton of every tracker: maps the world `ray` to the field's local space, walks the majorant segments
/// over `[t_min, t_max]` and samples tentative collisions on each at the rate the estimator asks for, carrying
/// the free path across segments ([`FreePath`]), until the estimator stops or the segments end. A segment whose
/// majorant optical depth per voxel passes [`REFINE_TAU`] is walked voxel cell by voxel cell on fields that
/// bound their voxel cells ([`DensityLookup::cell_bounds`]). Counts the segments and cells walked.
fn track<F: DensityField + ?Sized, E: Estimator>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    (t_min, t_max): (f32, f32),
    rng: &mut Rng,
    counters: &mut TrackingCounters,
    estimator: &mut E,
) {
    let lr = local_ray(field, ray);
    let len = ray.dir.length();
    // Local units (voxels) per unit of the parameter: σ̄·len / voxels_per_t is the optical depth per voxel.
    let voxels_per_t = lr.dir.length();
    let mut w = Walker {
        lr,
        len,
        lookup: field.lookup(),
        path: FreePath::new(rng),
        estimator,
    };
    let mut segments = majorants.segments(&lr, t_min, t_max);
    for s in segments.by_ref() {
        counters.majorant_segments += 1;
        let refine = majorants.voxel_refinement()
            && !s.is_uniform()
            && s.sigma_max * len > REFINE_TAU * voxels_per_t;
        let flow = if refine {
            w.voxel_cells(&s, rng, counters)
        } else {
            w.segment(&s, rng, counters)
        };
        if flow.is_break() {
            break;
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

/// What a free-flight walk knows at one of its tentative collisions, once it has decided it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TentativeCollision {
    /// The ray parameter of the collision.
    pub t: f32,
    /// The walk's throughput arriving there (1 for an analog walk such as delta tracking).
    pub throughput: Rgb,
    /// σ_t(x)/σ̄ per channel: the probability that the collision is real, for a grey walk. `None` where the
    /// walk decided the collision without reading the density (a control collision of decomposition tracking)
    /// because the hook's [`TentativeHook::blend`] there is 0, so that the track-length term needs no ratio.
    pub ratio: Option<Rgb>,
    /// The majorant σ̄ there, per unit of world length.
    pub sigma_bar: f32,
    /// For a real collision, the walk's throughput after its weight (1 for an analog walk); `None` for a null one.
    pub real: Option<Rgb>,
}

impl TentativeCollision {
    /// The weight of the emission (σ_a/σ_t)·L_e at x in an estimator of ∫T σ_a L_e along the flight: the blend
    /// α·β·σ_t/σ̄ + (1 − α)·β_real·[real] of the track-length estimator, which gathers σ_a L_e/σ̄ at every
    /// tentative collision (Miller, Georgiev, Jarosz 2019, "A null-scattering path integral formulation of light
    /// transport", eq. 9; pbrt-v4's volumetric path tracer), and of the collision estimator, which gathers
    /// (σ_a/σ_t) L_e at the real collision only. Both terms have the expectation β·σ_t/σ̄ given the walk so far
    /// and x, so any `alpha` in [0, 1] chosen from those, not from this collision's decision, keeps the sum
    /// unbiased. Neither estimator wins everywhere: where the flight is likely to leave the interval the
    /// track-length one avoids the all-or-nothing of rare real collisions, while where it is sure to end soon
    /// the collision estimator is nearly deterministic and the track-length one adds the variance of how many
    /// null collisions came first. A collision reported without its ratio has a track-length term of 0: `alpha`
    /// there is the hook's blend, which was 0.
    pub fn emission_weight(&self, alpha: f32) -> Rgb {
        let track_length = self
            .ratio
            .map_or(Rgb::ZERO, |ratio| self.throughput * ratio * alpha);
        match self.real {
            Some(after) => track_length + after * (1.0 - alpha),
            None => track_length,
        }
    }
}

/// What a free-flight walk reports at each of its tentative collisions, besides deciding them: the hook of the
/// emission estimator ([`TentativeCollision::emission_weight`]).
pub trait TentativeHook {
    /// False for [`NoHook`]: the walk then reads no density it would not read anyway (compiled out).
    const WANTS: bool;
    /// The blend α of [`TentativeCollision::emission_weight`] the hook will use at a tentative collision at ray
    /// parameter `t` under the majorant `sigma_bar` (per unit of world length), asked before the walk decides
    /// the collision (so it cannot depend on that decision, which keeps the blend unbiased). Where it is 0 the
    /// track-length term is 0, and a walk that can decide the collision without a lookup (a control collision
    /// of decomposition tracking) does not read the density to report its ratio.
    fn blend(&mut self, t: f32, sigma_bar: f32) -> f32;
    /// A tentative collision, decided.
    fn tentative(&mut self, collision: &TentativeCollision);
}

/// The hook of a walk that reports nothing.
pub struct NoHook;

impl TentativeHook for NoHook {
    const WANTS: bool = false;
    #[inline]
    fn blend(&mut self, _: f32, _: f32) -> f32 {
        0.0
    }
    #[inline]
    fn tentative(&mut self, _: &TentativeCollision) {}
}

/// A closure hook reads every collision's ratio (its blend is 1: it may weigh the terms as it likes).
impl<F: FnMut(&TentativeCollision)> TentativeHook for F {
    const WANTS: bool = true;
    #[inline]
    fn blend(&mut self, _: f32, _: f32) -> f32 {
        1.0
    }
    #[inline]
    fn tentative(&mut self, collision: &TentativeCollision) {
        self(collision)
    }
}

/// Delta tracking's decisions: the first accepted tentative collision.
struct Delta<H> {
    hit: Option<f32>,
    /// Decomposition tracking: a tentative collision that falls to the segment's minorant (the control) is real
    /// without a lookup.
    decompose: bool,
    hook: H,
}

impl<H> Delta<H> {
    /// A walk yet to collide: delta tracking (`decompose` false) or decomposition tracking (true), reporting
    /// its tentative collisions to `hook`.
    fn new(decompose: bool, hook: H) -> Self {
        Self {
            hit: None,
            decompose,
            hook,
        }
    }
}

impl<H: TentativeHook> Estimator for Delta<H> {
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
        // The hook's blend, asked before the collision is decided (0 without a hook).
        let blend = if H::WANTS {
            self.hook.blend(x.t, s.sigma_max)
        } else {
            0.0
        };
        // σ_t = σ̄ on a uniform segment: every tentative collision is real, no lookup needed.
        let (real, ratio) = if s.is_uniform() {
            (true, Some(1.0))
        } else {
            let u = rng.next_f32() * s.sigma_max;
            let control = self.decompose && u < s.sigma_min;
            // A control collision needs no lookup to be decided, only to be reported with a track-length term.
            if control && blend == 0.0 {
                (true, None)
            } else {
                let sigma = x.density(c);
                (control || u < sigma, Some(sigma / s.sigma_max))
            }
        };
        // A null collision under a blend of 0 has no emission weight: nothing to report.
        if H::WANTS && (real || blend > 0.0) {
            self.hook.tentative(&TentativeCollision {
                t: x.t,
                throughput: Rgb::ONE,
                ratio: ratio.map(Rgb::splat),
                sigma_bar: s.sigma_max,
                real: real.then_some(Rgb::ONE),
            });
        }
        if real {
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
#[cfg(any(test, feature = "testing"))]
pub fn sample_collision<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> Option<f32> {
    first_real_collision(
        field,
        majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        Delta::new(false, NoHook),
    )
}

/// Decomposition tracking (Kutz, Habel, Li, Novák 2017, "Spectral and Decomposition Tracking for Rendering
/// Heterogeneous Volumes", §4): samples the parameter of a real collision along the world `ray` in
/// `[t_min, t_max]`, or `None` when the path leaves the interval, with the distribution of
/// [`sample_collision`].
///
/// The extinction is split per majorant segment into a control and a residual, σ_t = σ_c + σ_r with σ_c the
/// segment's minorant, so the transmittance factors as T(t) = exp(−∫σ_c) · exp(−∫σ_r) (their §4), and the free
/// flight is the first of two independent collision processes: the control one, homogeneous at rate σ_c,
/// whose collisions are always real and need no lookup, and the residual one, delta-tracked against the residual
/// majorant σ̄ − σ_c. Both are sampled here as one process at rate σ̄ (the superposition of two
/// Poisson processes): a tentative collision belongs to the control with probability σ_c/σ̄, and is then real
/// without a lookup; otherwise it is a residual tentative collision, real with probability (σ_t − σ_c)/(σ̄ − σ_c).
/// A single uniform u decides both (control when u·σ̄ < σ_c, real when u·σ̄ < σ_t), so a collision is real with
/// probability σ_t/σ̄ exactly as in delta tracking: the estimator, the path's weights (analog, 1) and even the
/// random numbers are those of [`sample_collision`], but the dense interior of a medium, where σ_c is close to
/// σ̄, costs few lookups. With σ_c = 0 (structures without minorants) it is delta tracking.
pub fn decomposition_tracking<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    t_min: f32,
    t_max: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> Option<f32> {
    first_real_collision(
        field,
        majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        Delta::new(true, NoHook),
    )
}

/// [`decomposition_tracking`] over `interval` (`t_min`, `t_max`) that also reports every tentative collision
/// to `hook` (the tentative-collision estimator of emission): the same walk, decisions and random numbers.
pub fn decomposition_tracking_reporting<F: DensityField + ?Sized, H: TentativeHook>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    interval: (f32, f32),
    rng: &mut Rng,
    counters: &mut TrackingCounters,
    hook: H,
) -> Option<f32> {
    first_real_collision(
        field,
        majorants,
        ray,
        interval,
        rng,
        counters,
        Delta::new(true, hook),
    )
}

/// The walk of [`sample_collision`] and [`decomposition_tracking`] (as `delta` was made, see [`Delta::new`]):
/// the first real collision in `interval`, if any, with every tentative collision reported to its hook.
fn first_real_collision<F: DensityField + ?Sized, H: TentativeHook>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    interval: (f32, f32),
    rng: &mut Rng,
    counters: &mut TrackingCounters,
    mut delta: Delta<H>,
) -> Option<f32> {
    track(field, majorants, ray, interval, rng, counters, &mut delta);
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
///
/// The walk starts from the weight `start` (1 for the transmittance itself) and returns an estimate of
/// `start` · T: the roulette sees the weighted estimate, so a caller that kept the ray with probability
/// q = 1/`start` (Russian roulette before the walk) is not played roulette on a second time until the weighted
/// estimate falls below the threshold.
pub fn ratio_tracking<F: DensityField + ?Sized>(
    field: &F,
    majorants: &Majorants,
    ray: &Ray,
    (t_min, t_max): (f32, f32),
    start: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> f32 {
    let mut ratio = Ratio { tr: start };
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
    (t_min, t_max): (f32, f32),
    start: f32,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
) -> f32 {
    let mut residual = ResidualRatio {
        tr: start,
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

/// Spectral tracking's state: the path throughput as the walk has weighted it so far, and the lookups of the
/// three channels' extinction.
struct Spectral<L, H> {
    channels: [L; 3],
    throughput: Rgb,
    hit: Option<f32>,
    hook: H,
}

impl<C: DensityLookup, H: TentativeHook> Estimator for Spectral<C, H> {
    fn segment(&mut self, s: &Segment, len: f32, _: &mut Rng) -> OnSegment {
        // The segment bounds the channels' maximum; a constant maximum says nothing of each channel, so even
        // uniform segments are tracked with lookups.
        OnSegment::Track(s.sigma_max * len)
    }

    fn collision<L: DensityLookup>(
        &mut self,
        x: &mut Tentative<'_, L>,
        rng: &mut Rng,
        c: &mut TrackingCounters,
    ) -> ControlFlow<()> {
        let p = x.ray.at(x.t);
        let [r, g, b] = &mut self.channels;
        let sigma = Rgb::new(r.density_local(p), g.density_local(p), b.density_local(p));
        c.density_lookups += 3;
        let sigma_bar = x.segment.sigma_max;
        if sigma.max_element() > sigma_bar * (1.0 + VIOLATION_EPS) {
            c.majorant_violations += 1;
        }
        // σ_n = σ̄ − σ_t per channel (negative only under a violated majorant, where |σ_n| keeps the
        // probabilities valid and the weight's sign keeps the estimate unbiased).
        let sigma_n = Rgb::splat(sigma_bar) - sigma;
        // History-aware probabilities: throughput-weighted sums, normalised by their total.
        let real = self.throughput.dot(sigma);
        let null = self.throughput.dot(sigma_n.abs());
        let total = real + null;
        if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            // Nothing carried (or nothing finite): the path ends here with zero weight.
            self.throughput = Rgb::ZERO;
            return ControlFlow::Break(());
        }
        let arriving = self.throughput;
        let is_real = rng.next_f32() * total < real;
        if is_real {
            c.real_collisions += 1;
            // σ_t / (σ̄ P_real), P_real = real / total.
            self.throughput *= sigma * (total / (sigma_bar * real));
            self.hit = Some(x.t);
        } else {
            c.null_collisions += 1;
            // σ_n / (σ̄ P_null), P_null = null / total.
            self.throughput *= sigma_n * (total / (sigma_bar * null));
        }
        if H::WANTS {
            self.hook.tentative(&TentativeCollision {
                t: x.t,
                throughput: arriving,
                ratio: Some(sigma / sigma_bar),
                sigma_bar,
                real: is_real.then_some(self.throughput),
            });
        }
        if is_real {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// An RGB density as [`spectral_tracking`] walks it: its three channels, the field of their per-voxel maximum,
/// and that field's majorants, which bound every channel.
pub struct RgbDensity<'a, F: ?Sized> {
    /// The field of the channels' per-voxel maximum.
    pub max: &'a F,
    /// The red, green and blue densities.
    pub channels: [&'a F; 3],
    /// The majorants of `max`.
    pub majorants: &'a Majorants,
}

/// Spectral tracking (Kutz, Habel, Li, Novák 2017, "Spectral and Decomposition Tracking for Rendering
/// Heterogeneous Volumes", §5, with the history-aware collision probabilities of §5.1): samples a free flight
/// along the world `ray` in `[t_min, t_max]` through a medium whose extinction differs per channel (`density`),
/// for all three channels at once, and returns the collision with the path's new throughput.
///
/// Tentative collisions are sampled at the rate σ̄ of the majorants of `density.max` (which bound every channel). At
/// each, with σ_n = σ̄ − σ_t per channel and β the path throughput so far (walk weights included), the collision
/// is real with probability P_r = ⟨β, σ_t⟩ / c and null with P_n = ⟨β, |σ_n|⟩ / c, c = ⟨β, σ_t⟩ + ⟨β, |σ_n|⟩
/// (the throughput-weighted average of the paper's collision-type probabilities, absorption and scattering
/// merged into one real event whose albedo the caller applies). The throughput is multiplied by the vector
/// weight σ_t / (σ̄ P_r) at the real collision and σ_n / (σ̄ P_n) at each null one (their eq. for the weights
/// of a general collision-type sampler), so the estimator is unbiased in every channel for any valid
/// probabilities. The expectation at a tentative collision is σ_t/σ̄ · (real) + σ_n/σ̄ · (null), the
/// null-collision integral of every channel.
///
/// Without violations c = σ̄ Σβ, so each weight keeps Σβ: the throughput's sum is unchanged by the walk and
/// no channel's weight can grow without bound, whatever the chromaticity. A path carrying one channel is
/// delta-tracked in that channel exactly as [`sample_collision`] would (weights 1). Each tentative collision
/// reads the three channels (counted as three lookups); segments thicker than [`REFINE_TAU`] per voxel are
/// refined to voxel cells bounded by `density.max`'s eight voxels. Every tentative collision is reported to `hook`
/// ([`NoHook`] for none) with the throughput arriving there and, when real, the throughput it leaves.
pub fn spectral_tracking<F: DensityField + ?Sized, H: TentativeHook>(
    density: RgbDensity<'_, F>,
    ray: &Ray,
    (t_min, t_max): (f32, f32),
    throughput: Rgb,
    rng: &mut Rng,
    counters: &mut TrackingCounters,
    hook: H,
) -> Flight {
    let mut spectral = Spectral {
        channels: density.channels.map(|f| f.lookup()),
        throughput,
        hit: None,
        hook,
    };
    counters.spectral_flights += 1;
    track(
        density.max,
        density.majorants,
        ray,
        (t_min, t_max),
        rng,
        counters,
        &mut spectral,
    );
    Flight {
        collision: spectral.hit,
        throughput: spectral.throughput,
    }
}

/// Deterministic reference optical depth ∫σ_t(o + t d)|d| dt over `[t0, t1]` of the world `ray`, by the
/// composite midpoint rule with `steps` intervals (f64 accumulation). For tests and references.
#[cfg(any(test, feature = "testing"))]
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
        let dt = estimate(n, || {
            decomposition_tracking(f, maj, ray, t0, t1, &mut rng, &mut c).map_or(1.0, |_| 0.0)
        });
        check(&format!("{label} decomposition"), dt, truth);
        let r = estimate(n, || {
            ratio_tracking(f, maj, ray, (t0, t1), 1.0, &mut rng, &mut c) as f64
        });
        check(&format!("{label} ratio"), r, truth);
        let rr = estimate(n, || {
            residual_ratio_tracking(f, maj, ray, (t0, t1), 1.0, &mut rng, &mut c) as f64
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
        let t =
            residual_ratio_tracking(&f, &maj, &ray, (0.0, 5.0), 1.0, &mut Rng::new(1, 2), &mut c);
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

    /// The emission estimators over what [`TentativeHook`] reports: along rays through the smooth sphere, a
    /// medium of albedo 0 and L_e = 1 seen through its whole depth gives ∫σ_t T dt = 1 − e^−τ, against the
    /// quadrature; with every majorant structure and for every blend α of
    /// [`TentativeCollision::emission_weight`]: 1 (the track-length estimator, σ_t/σ̄ at every tentative
    /// collision), 0 (the collision estimator, 1 at the real one) and one between. The track-length estimator has
    /// less variance than the collision estimator (a Bernoulli variable of variance T(1 − T)) here. The walk's
    /// decisions and random numbers are those of [`decomposition_tracking`] without the hook.
    #[test]
    fn tentative_collisions_estimate_emission_with_less_variance_than_real_ones() {
        const N: usize = 4_000;
        const ALPHAS: [f32; 3] = [1.0, 0.3, 0.0];
        let g = sphere_grid(8.0);
        let rays = random_rays(&g, 8, 5);
        let (mut var_tentative, mut var_collision) = (0.0f64, 0.0f64);
        for kind in MajorantKind::ALL {
            let m = Majorants::build(kind, &g);
            for (i, ray) in rays.iter().enumerate() {
                let opacity = 1.0 - (-optical_depth_quadrature(&g, ray, 0.0, 20.0, 20_000)).exp();
                let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
                for k in 0..N {
                    let mut gathered = [0.0f64; 3];
                    let hook = |x: &TentativeCollision| {
                        for (g, alpha) in gathered.iter_mut().zip(ALPHAS) {
                            *g += x.emission_weight(alpha).x as f64;
                        }
                    };
                    let (mut rng, mut c) = (Rng::new(9, k as u64), TrackingCounters::default());
                    let t = decomposition_tracking_reporting(
                        &g,
                        &m,
                        ray,
                        (0.0, 20.0),
                        &mut rng,
                        &mut c,
                        hook,
                    );
                    let (mut rng, mut c) = (Rng::new(9, k as u64), TrackingCounters::default());
                    let plain = decomposition_tracking(&g, &m, ray, 0.0, 20.0, &mut rng, &mut c);
                    assert_eq!(t, plain, "the hook changes nothing of the walk");
                    for a in 0..3 {
                        sum[a] += gathered[a];
                        sum2[a] += gathered[a] * gathered[a];
                    }
                }
                for (a, alpha) in ALPHAS.iter().enumerate() {
                    let mean = sum[a] / N as f64;
                    let var = (sum2[a] / N as f64 - mean * mean).max(0.0);
                    let se = (var / N as f64).sqrt();
                    assert!(
                        (mean - opacity).abs() <= 4.0 * se + 1e-4,
                        "ray {i} {kind:?} α {alpha}: {mean} ± {se} vs 1 − T = {opacity}"
                    );
                    if a == 0 {
                        var_tentative += var;
                        var_collision += opacity * (1.0 - opacity);
                    }
                }
            }
        }
        // Measured 2026-12-04: 0.75 of the collision estimator's variance over these rays (majorants tight on the
        // smooth sphere leave few null collisions, where the gain is).
        assert!(
            var_tentative < 0.85 * var_collision,
            "tentative {var_tentative} vs collision {var_collision}"
        );
    }

    /// Spectral tracking's tentative collisions report the throughput arriving and, at the real one, leaving:
    /// the blended emission weights summed over a walk are β_c (1 − e^−τ_c) in expectation for each channel of
    /// a chromatic slab (closed form).
    #[test]
    fn spectral_tracking_reports_tentative_emission_per_channel() {
        const N: usize = 20_000;
        let slab = ChromaticSlab::new(16, 0.1, [0.5, 1.5, 4.0]);
        let maj = Majorants::build(MajorantKind::Grid16, &slab.max);
        let beta = Rgb::new(0.2, 1.0, 3.0);
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        for k in 0..N {
            let mut gathered = Rgb::ZERO;
            let hook = |x: &TentativeCollision| gathered += x.emission_weight(0.5);
            spectral_tracking(
                RgbDensity {
                    max: &slab.max,
                    channels: slab.channels.each_ref(),
                    majorants: &maj,
                },
                &slab.ray,
                (0.0, 10.0),
                beta,
                &mut Rng::new(12, k as u64),
                &mut TrackingCounters::default(),
                hook,
            );
            for ch in 0..3 {
                sum[ch] += gathered[ch] as f64;
                sum2[ch] += (gathered[ch] as f64).powi(2);
            }
        }
        for ch in 0..3 {
            let truth = beta[ch] as f64 * (1.0 - (-slab.tau(ch, slab.t_end())).exp());
            let mean = sum[ch] / N as f64;
            let se = ((sum2[ch] / N as f64 - mean * mean).max(0.0) / N as f64).sqrt();
            assert!(
                (mean - truth).abs() <= 4.0 * se + 1e-4,
                "channel {ch}: {mean} ± {se} vs {truth}"
            );
        }
    }

    /// The exact free-flight pdf σ_t(t)|d| exp(−τ(0, t)) of an analytic field along `ray`.
    fn free_flight_pdf(f: &AnalyticDensity, ray: &Ray, t: f64) -> f64 {
        let sigma = f.density(ray.at(t as f32)) as f64 * ray.dir.as_dvec3().length();
        sigma * (-f.optical_depth(ray, 0.0, t as f32)).exp()
    }

    #[test]
    fn decomposition_tracking_samples_the_exact_free_flight_pdf() {
        // Fields whose minorant is a large part of their majorant, so most collisions come from the control, and
        // one without (σ_c = 0, plain delta tracking); oblique, non-unit directions.
        let bounds = Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        let ray = Ray::new(Vec3::new(-2.0, 0.1, -0.3), Vec3::new(1.5, 0.05, 0.2));
        let t_max = 3.0;
        for (i, f) in [
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 0.6,
                sigma1: 1.4,
            },
            AnalyticDensity::Exponential {
                bounds,
                axis: 0,
                sigma0: 2.0,
                falloff: 0.7,
            },
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 0.0,
                sigma1: 2.0,
            },
        ]
        .iter()
        .enumerate()
        {
            let maj = Majorants::analytic(f);
            let mut rng = Rng::new(29, i as u64);
            let mut c = TrackingCounters::default();
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("decomposition tracking {f:?}"),
                100_000,
                (0.0, t_max as f64),
                || {
                    decomposition_tracking(f, &maj, &ray, 0.0, t_max, &mut rng, &mut c)
                        .unwrap_or(f32::INFINITY)
                },
                |t| free_flight_pdf(f, &ray, t),
            );
            assert_eq!(c.majorant_violations, 0);
        }
    }

    #[test]
    fn decomposition_tracking_is_delta_tracking_with_fewer_lookups() {
        // The same random numbers give the same collisions as delta tracking; collisions under the minorant
        // take no lookup. Analytic: σ_c/σ̄ = 2/3, so about a third of the tentative collisions look up.
        let bounds = Aabb::new(Vec3::ZERO, Vec3::new(4.0, 1.0, 1.0));
        let ramp = AnalyticDensity::Ramp {
            bounds,
            axis: 0,
            sigma0: 2.0,
            sigma1: 3.0,
        };
        let ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X);
        let compare = |f: &dyn Fn(&mut Rng, &mut TrackingCounters, bool) -> Option<f32>| {
            let (mut delta, mut decomposed) = (TrackingCounters::default(), Default::default());
            for i in 0..20_000 {
                let a = f(&mut Rng::new(3, i), &mut delta, false);
                let b = f(&mut Rng::new(3, i), &mut decomposed, true);
                assert_eq!(a, b, "ray {i}");
            }
            assert_eq!(
                (delta.real_collisions, delta.null_collisions),
                (decomposed.real_collisions, decomposed.null_collisions)
            );
            (delta, decomposed)
        };
        let maj = Majorants::analytic(&ramp);
        let (delta, decomposed) = compare(&|rng, c, decompose| {
            let track = if decompose {
                decomposition_tracking
            } else {
                sample_collision
            };
            track(&ramp, &maj, &ray, 0.0, 10.0, rng, c)
        });
        let ratio = decomposed.density_lookups as f64 / delta.density_lookups as f64;
        assert!(
            (0.28..0.39).contains(&ratio),
            "{ratio} {delta:?} {decomposed:?}"
        );
        // A thick ball on the adaptive structure (the one that stores minorants): the dense interior's fine
        // cells have minorants close to their majorants.
        let g = sphere_grid(400.0);
        let maj = Majorants::build(MajorantKind::Adaptive, &g);
        let rays = random_rays(&g, 64, 21);
        let (delta, decomposed) = compare(&|rng, c, decompose| {
            let ray = &rays[rng.next_u32() as usize % rays.len()];
            let track = if decompose {
                decomposition_tracking
            } else {
                sample_collision
            };
            track(&g, &maj, ray, 0.0, 20.0, rng, c)
        });
        assert!(
            decomposed.density_lookups < delta.density_lookups,
            "{delta:?} {decomposed:?}"
        );
    }

    #[test]
    fn voxel_refinement_samples_the_exact_free_flight_pdf_in_a_thick_grid() {
        // Up to 8 per voxel of optical depth at the ball's centre: segments of every structure pass REFINE_TAU
        // there and are walked voxel by voxel. The pdf σ_t(t)|d| exp(−τ(0, t)) with τ from a fine quadrature.
        let g = sphere_grid(160.0);
        let b = g.bounds();
        let from = b.center() - Vec3::new(2.0, 0.3, 0.4);
        let ray = Ray::new(
            from,
            (b.center() + Vec3::new(0.0, 0.05, -0.02) - from) * 0.7,
        );
        let t_max = 8.0f32;
        let steps = 200_000;
        let dt = t_max as f64 / steps as f64;
        let mut tau = vec![0.0f64; steps + 1];
        for i in 0..steps {
            let t = (i as f64 + 0.5) * dt;
            tau[i + 1] = tau[i] + g.density(ray.at(t as f32)) as f64 * dt;
        }
        let speed = ray.dir.as_dvec3().length();
        let pdf = |t: f64| {
            let x = (t / dt).clamp(0.0, steps as f64 - 1e-9);
            let i = x as usize;
            let tau_t = tau[i] + (tau[i + 1] - tau[i]) * (x - i as f64);
            g.density(ray.at(t as f32)) as f64 * speed * (-tau_t * speed).exp()
        };
        assert!(tau[steps] * speed > 10.0, "{}", tau[steps] * speed);
        // Where the collisions are: from the entry into the ball to where its optical depth reaches 8.
        let (enter, _) = b.intersect(&ray, 0.0, t_max).unwrap();
        let deep = (0..steps).find(|&i| tau[i] * speed > 8.0).unwrap() as f64 * dt;
        for kind in MajorantKind::ALL {
            let maj = Majorants::build(kind, &g);
            let mut rng = Rng::new(31, kind as u64);
            let mut c = TrackingCounters::default();
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("voxel-refined decomposition tracking, {kind:?}"),
                100_000,
                (enter as f64, deep),
                || {
                    decomposition_tracking(&g, &maj, &ray, 0.0, t_max, &mut rng, &mut c)
                        .unwrap_or(f32::INFINITY)
                },
                pdf,
            );
            // The global bound (8 per voxel) is refined from the rim on; the finer structures where they are thick.
            assert!(
                c.voxel_cells > 0 || kind != MajorantKind::Global,
                "{kind:?}: {c:?}"
            );
            assert_eq!(c.majorant_violations, 0, "{kind:?}");
        }
    }

    #[test]
    fn voxel_refinement_keeps_thick_grids_exact_and_flattens_the_work() {
        // Transmittance of every estimator through a thick ball (20 per voxel at its centre) against quadrature,
        // with refinement; and the work of a free flight under the global bound with and without it.
        // Each ray ends inside the ball where its optical depth reaches 2, so the transmittance is not ~0.
        let g = sphere_grid(400.0);
        let rays = random_rays(&g, 12, 8);
        let mut checked = 0;
        for (i, ray) in rays.iter().enumerate() {
            let steps = 40_000;
            let dt = 20.0 / steps as f32;
            let (mut tau, mut t1) = (0.0f64, 20.0f32);
            for k in 0..steps {
                tau += optical_depth_quadrature(&g, ray, k as f32 * dt, (k + 1) as f32 * dt, 1);
                if tau > 2.0 {
                    t1 = (k + 1) as f32 * dt;
                    break;
                }
            }
            let tau = optical_depth_quadrature(&g, ray, 0.0, t1, 40_000);
            checked += usize::from(tau > 1.0);
            for kind in MajorantKind::ALL {
                check_all(
                    &format!("thick ball ray {i} {kind:?}"),
                    &g,
                    &Majorants::build(kind, &g),
                    ray,
                    (0.0, t1),
                    (-tau).exp(),
                    2_000,
                );
            }
        }
        assert!(checked >= 4, "{checked}");
        let work = |g: &GridDensity, refine: bool| {
            let maj = Majorants::build(MajorantKind::Global, g).with_voxel_refinement(refine);
            let mut c = TrackingCounters::default();
            for (i, ray) in rays.iter().enumerate() {
                for j in 0..500 {
                    let mut rng = Rng::new(i as u64, j);
                    decomposition_tracking(g, &maj, ray, 0.0, 20.0, &mut rng, &mut c);
                }
            }
            (c.density_lookups + c.voxel_cells) as f64 / c.real_collisions.max(1) as f64
        };
        let (plain, refined) = (work(&g, false), work(&g, true));
        assert!(
            refined < 0.25 * plain,
            "{refined} vs {plain} per real collision"
        );
        // 10× the density: the refined work per collision stays about the same; the plain work grows.
        let thick = sphere_grid(4000.0);
        let (plain10, refined10) = (work(&thick, false), work(&thick, true));
        assert!(refined10 < 1.5 * refined, "{refined10} vs {refined}");
        assert!(plain10 > 2.0 * plain, "{plain10} vs {plain}");
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
            ratio_tracking(&g, &bad, &ray, (0.0, 20.0), 1.0, &mut rng, &mut c);
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

    /// A chromatic constant slab as grids: `block_grid(n, vs, ·)` at densities `s` (one field per channel, sharing
    /// the tree and placement) and their maximum. Along +x at interior y and z a trilinear lookup reads the
    /// trapezoid of the block: rising over the voxel before it, 1 over n − 1 voxels, falling over the last.
    struct ChromaticSlab {
        n: i32,
        vs: f64,
        s: [f64; 3],
        max: GridDensity,
        channels: [GridDensity; 3],
        ray: Ray,
        /// The ray parameter where the rising ramp starts.
        t_a: f64,
    }

    impl ChromaticSlab {
        fn new(n: i32, vs: f64, s: [f64; 3]) -> Self {
            let half = vs * n as f64 / 2.0;
            // Voxel index o sits at world (−1, 0, 2); the ramp starts one voxel before it on x.
            let ray = Ray::new(
                Vec3::new(
                    -3.0,
                    (half + 0.3 * vs) as f32,
                    (2.0 + half + 0.17 * vs) as f32,
                ),
                Vec3::X,
            );
            Self {
                n,
                vs,
                s,
                max: block_grid(n, vs, s.iter().cloned().fold(0.0, f64::max) as f32),
                channels: s.map(|c| block_grid(n, vs, c as f32)),
                ray,
                t_a: 2.0 - vs,
            }
        }

        /// Closed-form optical depth of channel `c` from the ray origin to `t`: s_c · vs · F(u), u the voxels
        /// past the ramp's start, F the integral of the trapezoid.
        fn tau(&self, c: usize, t: f64) -> f64 {
            let n = self.n as f64;
            let u = ((t - self.t_a) / self.vs).clamp(0.0, n + 1.0);
            let f = if u < 1.0 {
                0.5 * u * u
            } else if u < n {
                u - 0.5
            } else {
                let v = u - n;
                n - 0.5 + v - 0.5 * v * v
            };
            self.s[c] * self.vs * f
        }

        fn t_end(&self) -> f64 {
            self.t_a + (self.n as f64 + 1.0) * self.vs
        }
    }

    /// Spectral tracking through a chromatic slab against its closed forms, for every channel a path carries:
    /// the throughput-weighted escapes (E = e^−τ_c) and the throughput-weighted collisions in each of `bins`
    /// intervals (E = e^−τ_c(a) − e^−τ_c(b): the integral of the collision density σ_c e^−τ_c), each within 4
    /// standard errors. Channels the path does not carry must stay exactly 0. Returns the counters.
    fn check_spectral(
        label: &str,
        slab: &ChromaticSlab,
        maj: &Majorants,
        beta: Rgb,
    ) -> TrackingCounters {
        const N: usize = 40_000;
        const BINS: usize = 8;
        let (t0, t1) = (slab.t_a, slab.t_end());
        let mut rng = Rng::new(41, 3);
        let mut c = TrackingCounters::default();
        // Per channel: sums and squared sums of the escape weight and of each bin's weight.
        let mut sum = [[0.0f64; BINS + 1]; 3];
        let mut sum2 = [[0.0f64; BINS + 1]; 3];
        let channels = slab.channels.each_ref();
        for _ in 0..N {
            let f = spectral_tracking(
                RgbDensity {
                    max: &slab.max,
                    channels,
                    majorants: maj,
                },
                &slab.ray,
                (0.0, 10.0),
                beta,
                &mut rng,
                &mut c,
                NoHook,
            );
            assert!(f.throughput.is_finite(), "{label}: {f:?}");
            let slot = match f.collision {
                None => BINS,
                Some(t) => (((t as f64 - t0) / (t1 - t0) * BINS as f64) as usize).min(BINS - 1),
            };
            for ch in 0..3 {
                if beta[ch] == 0.0 {
                    assert_eq!(f.throughput[ch], 0.0, "{label}: uncarried channel {ch}");
                    continue;
                }
                let w = (f.throughput[ch] / beta[ch]) as f64;
                sum[ch][slot] += w;
                sum2[ch][slot] += w * w;
            }
        }
        for ch in (0..3).filter(|&ch| beta[ch] != 0.0) {
            for slot in 0..=BINS {
                let truth = if slot == BINS {
                    (-slab.tau(ch, t1)).exp()
                } else {
                    let a = t0 + (t1 - t0) * slot as f64 / BINS as f64;
                    let b = t0 + (t1 - t0) * (slot + 1) as f64 / BINS as f64;
                    (-slab.tau(ch, a)).exp() - (-slab.tau(ch, b)).exp()
                };
                let m = sum[ch][slot] / N as f64;
                let se = ((sum2[ch][slot] / N as f64 - m * m).max(0.0) / N as f64).sqrt();
                assert!(
                    (m - truth).abs() <= 4.0 * se + 1e-4 * truth.max(1e-3),
                    "{label}: channel {ch}, {} {m} ± {se} vs closed form {truth}",
                    if slot == BINS {
                        "escape".to_string()
                    } else {
                        format!("bin {slot}")
                    },
                );
            }
        }
        assert_eq!(c.majorant_violations, 0, "{label}");
        c
    }

    #[test]
    fn spectral_tracking_matches_the_closed_forms_of_a_chromatic_slab() {
        // Mildly (1:1.5:2) and strongly (1:10:100) chromatic, thin and thick (50 per metre is 5 per 0.1 m voxel:
        // refined to voxel cells); paths carrying all channels equally, unequally, and one only.
        for s in [[1.0, 1.5, 2.0], [0.5, 5.0, 50.0]] {
            let slab = ChromaticSlab::new(16, 0.1, s);
            for kind in MajorantKind::ALL {
                let maj = Majorants::build(kind, &slab.max);
                for beta in [Rgb::ONE, Rgb::new(0.2, 1.0, 3.0), Rgb::new(0.0, 1.0, 0.0)] {
                    let c = check_spectral(&format!("{s:?} {kind:?} {beta}"), &slab, &maj, beta);
                    assert_eq!(c.spectral_flights, 40_000);
                    if s[2] > 40.0 && kind == MajorantKind::Global {
                        assert!(c.voxel_cells > 0, "{c:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn spectral_tracking_keeps_the_throughput_sum_and_tracks_one_channel_as_delta_tracking() {
        // History-aware probabilities: every weight keeps Σβ, so no channel's weight grows without bound.
        let slab = ChromaticSlab::new(16, 0.1, [0.5, 5.0, 50.0]);
        let maj = Majorants::build(MajorantKind::Grid16, &slab.max);
        let beta = Rgb::new(0.2, 1.0, 3.0);
        for i in 0..2000 {
            let f = spectral_tracking(
                RgbDensity {
                    max: &slab.max,
                    channels: slab.channels.each_ref(),
                    majorants: &maj,
                },
                &slab.ray,
                (0.0, 10.0),
                beta,
                &mut Rng::new(5, i),
                &mut TrackingCounters::default(),
                NoHook,
            );
            let sum = f.throughput.element_sum();
            assert!(
                (sum - beta.element_sum()).abs() < 1e-4 * beta.element_sum(),
                "{f:?}"
            );
        }
        // A path carrying one channel collides where delta tracking of that channel does, with weight 1 (on a
        // slab thin enough not to be refined to voxel cells, whose constant interior delta tracking takes
        // without a random number).
        let slab = ChromaticSlab::new(16, 0.1, [0.5, 5.0, 20.0]);
        let maj = Majorants::build(MajorantKind::Grid16, &slab.max);
        let one = Rgb::new(0.0, 2.0, 0.0);
        for i in 0..2000 {
            let mut c = TrackingCounters::default();
            let f = spectral_tracking(
                RgbDensity {
                    max: &slab.max,
                    channels: slab.channels.each_ref(),
                    majorants: &maj,
                },
                &slab.ray,
                (0.0, 10.0),
                one,
                &mut Rng::new(6, i),
                &mut c,
                NoHook,
            );
            assert!((f.throughput - one).abs().max_element() < 1e-5, "{f:?}");
            let delta = sample_collision(
                &slab.channels[1],
                &maj,
                &slab.ray,
                0.0,
                10.0,
                &mut Rng::new(6, i),
                &mut c,
            );
            assert_eq!(f.collision, delta, "ray {i}");
        }
    }
}
