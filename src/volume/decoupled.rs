//! Distances for the decoupled direct light on a ray segment through a heterogeneous medium (Novák et al. 2018,
//! "Monte Carlo Methods for Volumetric Light Transport Simulation", §5: the direct light of every segment is
//! estimated at a point of its own, not only at the free-flight collision of the segments that collide).
//!
//! The transmittance of a grid has no closed form, so the distance cannot follow it exactly as it does in a
//! constant medium. It follows a bound σ̄ of the density instead, piecewise constant along the segment, which is
//! known exactly and is positive wherever the medium can scatter: over each voxel cell the segment crosses, the
//! largest of its eight voxels (which bound its trilinear density exactly), where the majorant structure is not
//! zero. The structure's own cells are far too coarse for it: a cloud's 16³ majorant grid bounds its thin edges
//! by its dense core's maximum, so distances drawn from it landed mostly where the density is near zero
//! (measured: 1.6× the backlit cloud's MSE of collisions alone, docs/performance.md, "Decoupled direct light in
//! grid media"). With τ̄(t) the
//! majorant optical depth from the segment's start and τ̄(L) that of the whole segment, the density is the
//! one-sample mixture (Veach 1997, §9.2.4)
//!
//! p(t) = σ̄(t) · [a / τ̄(L) + (1 − a) e^{−τ̄(t)} / (1 − e^{−τ̄(L)})],
//!
//! of "uniform in majorant optical depth" (weight a = [`UNIFORM_SHARE`]) and the majorant's truncated exponential.
//! The first bounds the estimate's weight σ_s T / p by albedo · τ̄(L) / a wherever the density is near its
//! majorant, whatever the light; the second puts the points near the entry of a dense core, where the
//! transmittance from the segment's start is. Both are sampled by inverting the majorant optical depth along the
//! segment's majorant segments.

use super::density::{DensityField, DensityLookup};
use super::majorant::{Majorants, VoxelCells};
use super::tracking::{roulette, TrackingCounters};
use crate::math::{Ray, Rng, Vec2};

/// The probability with which [`MajorantDistance`] draws a distance uniform in the bound's optical depth (else
/// from the bound's truncated exponential).
pub const UNIFORM_SHARE: f32 = 0.5;

/// The bound's optical depth after which the decoupled sample's part of a segment ends ([`MajorantDistance::end`]):
/// beyond it the transmittance from the segment's start is at most about e^{−8} where the bound is tight, the
/// free-flight collisions, which reach nearly every path there, estimate the rest, and the walk of a dense core's
/// voxel cells stops after a few voxels.
pub const MAX_DEPTH: f32 = 8.0;

/// An interval `[a, b)` of the ray parameter on which the bound is the constant `sigma_bar` (per world metre).
#[derive(Clone, Copy, Debug)]
struct Interval {
    a: f32,
    b: f32,
    sigma_bar: f32,
}

/// The distance density of the decoupled sample on a segment of a ray through a medium (see the module
/// documentation): the bound's intervals along the segment, walked once, and their total optical depth.
pub(crate) struct MajorantDistance<'a, F: ?Sized> {
    field: &'a F,
    /// The ray in the field's local space, with the world ray's parameter.
    ray: Ray,
    /// Length of the world ray's direction: world metres per unit of the parameter (σ̄ is per world metre).
    len: f32,
    /// The intervals of positive bound, in increasing t.
    intervals: Vec<Interval>,
    /// τ̄(L): the bound's optical depth over the whole part.
    depth: f32,
    /// Where the part ends.
    end: f32,
}

impl<'a, F: DensityField + ?Sized> MajorantDistance<'a, F> {
    /// The density on `[t0, t1]` of the local-space `ray` (world direction length `len`) through `field` and its
    /// `majorants`: walks the bound along the segment once, in increasing t (counted in `counters`): the voxel
    /// cells of the majorant structure's segments, each bounded by its eight voxels, or the structure's segment
    /// itself where the field has no voxel cells (an analytic or a displaced one). The walk stops where the
    /// bound's optical depth reaches `max_depth`, which ends the part of the segment the density covers
    /// ([`Self::end`]). `None` where the bound is zero along the whole segment (nothing can scatter there).
    pub(crate) fn new(
        field: &'a F,
        majorants: &Majorants,
        ray: Ray,
        len: f32,
        (t0, t1): (f32, f32),
        max_depth: f32,
        counters: &mut TrackingCounters,
    ) -> Option<Self> {
        let mut lookup = field.lookup();
        let mut intervals = Vec::new();
        let mut depth = 0.0;
        let mut end = t1;
        // Adds `[a, b)` at `sigma_bar`; true once the depth reaches `max_depth` (the interval cut there).
        let mut push = |a: f32, b: f32, sigma_bar: f32| {
            let rate = sigma_bar * len;
            let room = rate * (b - a);
            if depth + room < max_depth {
                depth += room;
                intervals.push(Interval { a, b, sigma_bar });
                return false;
            }
            let b = (a + (max_depth - depth) / rate).clamp(a, b);
            depth = max_depth;
            end = b;
            intervals.push(Interval { a, b, sigma_bar });
            true
        };
        let mut segments = majorants.segments(&ray, t0, t1);
        'segments: for s in segments.by_ref() {
            counters.majorant_segments += 1;
            let mut cells = VoxelCells::new(&ray, s.t0, s.t1);
            while let Some((cell, a, b)) = cells.next(&mut counters.voxel_cells) {
                let Some((_, sigma_bar)) = lookup.cell_bounds(cell) else {
                    if push(a, s.t1, s.sigma_max) {
                        break 'segments;
                    }
                    continue 'segments;
                };
                if sigma_bar > 0.0 && push(a, b, sigma_bar) {
                    break 'segments;
                }
            }
        }
        counters.majorant_cells += segments.cells();
        (depth > 0.0 && depth.is_finite()).then_some(Self {
            field,
            ray,
            len,
            intervals,
            depth,
            end,
        })
    }

    /// Where the part of the segment the density covers ends: the segment's end, or where the bound's optical
    /// depth reached the walk's `max_depth`. Free-flight collisions beyond it estimate the direct light there.
    pub(crate) fn end(&self) -> f32 {
        self.end
    }

    /// The mixture's density per unit of the parameter where the bound is `sigma_bar` and its optical depth from
    /// the start `tau`.
    fn density(&self, sigma_bar: f32, tau: f32) -> f32 {
        let rate = sigma_bar * self.len;
        let uniform = UNIFORM_SHARE / self.depth;
        let exponential = (1.0 - UNIFORM_SHARE) * (-tau).exp() / -(-self.depth).exp_m1();
        rate * (uniform + exponential)
    }

    /// A distance drawn from the density with the 2-D sample `u` (`u.x` picks the strategy and, rescaled, the
    /// optical depth; `u.y` is unused and kept for a stratified pair), and its density there: the bound's
    /// optical depth τ* is drawn (uniform on [0, τ̄(L)] or from the truncated exponential) and located in the
    /// intervals.
    pub(crate) fn sample(&self, u: Vec2) -> (f32, f32) {
        let target = if u.x < UNIFORM_SHARE {
            u.x / UNIFORM_SHARE * self.depth
        } else {
            let v = ((u.x - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE)).min(1.0);
            // Inverse of the truncated exponential's CDF (1 − e^{−τ}) / (1 − e^{−τ̄(L)}).
            -(v * (-self.depth).exp_m1()).ln_1p()
        };
        let target = target.clamp(0.0, self.depth);
        let mut tau = 0.0;
        for i in &self.intervals {
            let rate = i.sigma_bar * self.len;
            let room = rate * (i.b - i.a);
            if tau + room >= target {
                let t = (i.a + (target - tau) / rate).clamp(i.a, i.b.next_down().max(i.a));
                return (t, self.density(i.sigma_bar, target));
            }
            tau += room;
        }
        // Round-off may leave the target just beyond the last interval: its end.
        let last = self.intervals[self.intervals.len() - 1];
        (
            last.b.next_down().max(last.a),
            self.density(last.sigma_bar, self.depth),
        )
    }

    /// An unbiased estimate of the transmittance from the segment's start to `t`: ratio tracking (Novák et al.
    /// 2014, eq. 6) over the walked intervals, whose bounds are majorants and, on voxel cells, tight ones, so
    /// that it looks up the density far less often than over the majorant structure's cells; Russian roulette
    /// as the medium's other ratio tracking plays it ([`roulette`]).
    pub(crate) fn transmittance(
        &self,
        t: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> f32 {
        let mut lookup = self.field.lookup();
        let mut tr = 1.0;
        for i in self.intervals.iter().take_while(|i| i.a < t) {
            let rate = i.sigma_bar * self.len;
            let end = i.b.min(t);
            let mut x = i.a;
            loop {
                x -= (1.0 - rng.next_f32()).ln() / rate;
                if x >= end {
                    break;
                }
                let sigma = lookup.density_local(self.ray.at(x));
                counters.density_lookups += 1;
                counters.null_collisions += 1;
                tr *= 1.0 - sigma / i.sigma_bar;
                if roulette(&mut tr, rng) {
                    return 0.0;
                }
            }
        }
        tr
    }

    /// The density at `t` (0 outside the segment and where the bound is 0).
    #[cfg(test)]
    pub(crate) fn pdf(&self, t: f32) -> f32 {
        let mut tau = 0.0;
        for i in &self.intervals {
            if t < i.a {
                return 0.0;
            }
            let rate = i.sigma_bar * self.len;
            if t < i.b {
                return self.density(i.sigma_bar, tau + rate * (t - i.a));
            }
            tau += rate * (i.b - i.a);
        }
        0.0
    }

    /// τ̄(L), the bound's optical depth over the segment.
    #[cfg(test)]
    pub(crate) fn depth(&self) -> f32 {
        self.depth
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::chi2::assert_interval_sampler_fits;
    use crate::math::{Rng, Vec3};
    use crate::volume::density::test_fields::sphere_grid;
    use crate::volume::density::{local_ray, DensityField};
    use crate::volume::majorant::MajorantKind;

    /// Through the sphere grid (whose gap leaves a stretch of zero majorant), at a thin and a thick density
    /// scale and for every majorant structure, the distances follow the density the sampler returns with them
    /// (chi-square), that density integrates to 1 over the segment, and it is the one `pdf` evaluates.
    #[test]
    fn majorant_distances_follow_their_density() {
        for (scale, max_depth) in [
            (0.5f32, f32::INFINITY),
            (200.0, f32::INFINITY),
            (200.0, 8.0),
        ] {
            let field = sphere_grid(scale);
            for kind in [
                MajorantKind::Global,
                MajorantKind::Grid16,
                MajorantKind::Adaptive,
            ] {
                let majorants = Majorants::build(kind, &field);
                let b = field.bounds();
                let origin = b.min - Vec3::new(0.3, 0.1, 0.2);
                let ray = Ray::new(origin, (b.max - origin).normalize());
                let t1 = (b.max - origin).length() + 0.5;
                let mut c = TrackingCounters::default();
                let lr = local_ray(&field, &ray);
                let d = MajorantDistance::new(
                    &field,
                    &majorants,
                    lr,
                    1.0,
                    (0.0, t1),
                    max_depth,
                    &mut c,
                )
                .expect("the ray crosses the sphere");
                let name =
                    format!("majorant distance, scale {scale} to depth {max_depth}, {kind:?}");
                assert!(d.depth() <= max_depth && d.end() <= t1);
                if max_depth.is_finite() {
                    assert!(
                        d.end() < t1 && (d.depth() - max_depth).abs() < 1e-3,
                        "{name}: cut"
                    );
                }
                let n = 64;
                let integral: f64 = (0..n * 64)
                    .map(|i| {
                        let t = (i as f64 + 0.5) / (n * 64) as f64 * t1 as f64;
                        d.pdf(t as f32) as f64 * t1 as f64 / (n * 64) as f64
                    })
                    .sum();
                assert!(
                    (integral - 1.0).abs() < 0.02,
                    "{name}: ∫p = {integral} (τ̄ = {})",
                    d.depth()
                );
                let mut rng = Rng::new(3, 11);
                let mut draw = || {
                    let (t, pdf) = d.sample(rng.sample_2d());
                    let want = d.pdf(t);
                    assert!(
                        (pdf - want).abs() <= 1e-3 * want.max(1e-6),
                        "{name}: sampled density {pdf} vs {want} at {t}"
                    );
                    t
                };
                assert_interval_sampler_fits(&name, 50_000, (0.0, t1 as f64), &mut draw, |t| {
                    d.pdf(t as f32) as f64
                });
            }
        }
    }
}
