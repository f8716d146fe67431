//! Picks the majorant structure for a grid medium: the one with the least estimated tracking cost on this grid
//! at this density scale (`"majorant": "auto"`, the default).
//!
//! Which structure is cheapest depends on the data and on how optically thick the medium is:
//! - a small or thin medium is cheapest under one global bound, which costs no traversal at all;
//! - a large sparse one, or a thick one, pays for a finer structure, because every unit of majorant optical
//!   depth above the density is a wasted lookup. Where a segment holds more than
//!   [`REFINE_TAU`](super::tracking::REFINE_TAU) of majorant optical depth per voxel, tracking refines it to
//!   voxel cells under any structure, so at high density scales the structures differ mostly in how they skip
//!   empty space and in the voxel cells they make tracking read (counted with the lookups).
//!
//! The choice is made by a pilot: [`PILOT_RAYS`] fixed-seed rays from the grid's bounding sphere towards points
//! inside its bounds are tracked through each structure, once by delta tracking (a free flight) and once by
//! ratio tracking (a shadow ray), counting density lookups and majorant cells walked. The estimated cost is
//! [`NS_PER_LOOKUP`] per lookup plus [`NS_PER_CELL`] per cell, constants fitted by `benches/fit_majorant_costs.py`
//! to `cargo bench --bench majorants -- --csv` timings of five corpus grids at mean optical depths 0.1 to 100
//! (see `docs/method_choices.md`). The pilot counts work, never time, so the choice is the same on every machine
//! and run. Structures are tried finest first, and a structure's pilot stops once its work passes
//! [`PILOT_WORK_CAP`] times the whole pilot of the cheapest so far (it cannot win), so a density that makes one
//! structure very slow (a single extreme voxel under the global bound) does not make the pilot slow.

use super::density::{DensityField, GridDensity};
use super::majorant::{MajorantKind, Majorants};
use super::tracking::{decomposition_tracking, ratio_tracking, TrackingCounters};
use crate::limits::Limits;
use crate::math::{Ray, Rng, Vec3};

/// Rays in the pilot.
pub const PILOT_RAYS: usize = 256;
/// Fitted cost of one density lookup (trilinear, eight voxel reads), in nanoseconds of one core.
pub const NS_PER_LOOKUP: f64 = 65.0;
/// Fitted cost of one majorant cell walked (a DDA step and its segment), in nanoseconds of one core.
pub const NS_PER_CELL: f64 = 27.0;
/// A structure's pilot stops when its estimated work passes this multiple of the cheapest complete pilot.
pub const PILOT_WORK_CAP: f64 = 4.0;
/// The order structures are piloted in: the finest (usually cheapest) first, so the work cap bites early.
const PILOT_ORDER: [MajorantKind; 3] = [
    MajorantKind::Grid16,
    MajorantKind::Adaptive,
    MajorantKind::Global,
];

/// The pilot's figures for one majorant structure.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MajorantEstimate {
    /// The structure.
    pub kind: MajorantKind,
    /// Density lookups per pilot ray (a free flight plus a shadow ray), with the voxel cells whose bounds were
    /// read (`TrackingCounters::voxel_cells`: eight voxels each, the work of a lookup).
    pub lookups_per_ray: f64,
    /// Majorant cells walked per pilot ray.
    pub cells_per_ray: f64,
    /// Estimated nanoseconds per pilot ray.
    pub cost_ns: f64,
    /// Pilot rays traced: fewer than [`PILOT_RAYS`] when the pilot stopped at the work cap (the figures are then
    /// means over the rays traced, and the structure was not chosen).
    pub rays_traced: usize,
}

/// Fixed-seed rays from the bounding sphere of `bounds` towards uniform points inside them, with unit
/// directions, and the parameter length that crosses the whole sphere.
pub fn pilot_rays(field: &GridDensity, n: usize, seed: u64) -> (Vec<Ray>, f32) {
    let b = field.bounds();
    let r = 0.5 * b.extent().length();
    let mut rng = Rng::new(seed, 11);
    let mut u3 = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    let rays = (0..n)
        .map(|_| {
            let target = b.min + u3() * b.extent();
            let mut d = u3() - 0.5;
            if d.length() < 1e-3 {
                d = Vec3::X;
            }
            let from = b.center() + d.normalize() * r;
            Ray::new(from, (target - from).normalize())
        })
        .collect();
    (rays, 4.0 * r)
}

/// Estimated nanoseconds of the work `c` counts.
fn work_ns(c: &TrackingCounters) -> f64 {
    NS_PER_LOOKUP * (c.density_lookups + c.voxel_cells) as f64
        + NS_PER_CELL * c.majorant_cells as f64
}

/// Estimates the tracking cost of `majorants` over `field` with the pilot rays, stopping after the ray whose
/// work takes the total past `max_total_ns`.
pub fn estimate(
    field: &GridDensity,
    majorants: &Majorants,
    rays: &[Ray],
    t_max: f32,
    max_total_ns: f64,
) -> MajorantEstimate {
    let mut rng = Rng::new(0x9e37, majorants.kind() as u64);
    let mut counters = TrackingCounters::default();
    let mut traced = 0;
    for ray in rays {
        decomposition_tracking(field, majorants, ray, 0.0, t_max, &mut rng, &mut counters);
        ratio_tracking(
            field,
            majorants,
            ray,
            (0.0, t_max),
            1.0,
            &mut rng,
            &mut counters,
        );
        traced += 1;
        if work_ns(&counters) > max_total_ns {
            break;
        }
    }
    let n = traced.max(1) as f64;
    let lookups_per_ray = (counters.density_lookups + counters.voxel_cells) as f64 / n;
    let cells_per_ray = counters.majorant_cells as f64 / n;
    MajorantEstimate {
        kind: majorants.kind(),
        lookups_per_ray,
        cells_per_ray,
        cost_ns: NS_PER_LOOKUP * lookups_per_ray + NS_PER_CELL * cells_per_ray,
        rays_traced: traced,
    }
}

/// Builds every structure over `field` that fits the memory budget (the global bound always does), runs the
/// pilot, and returns the cheapest with the estimates of those built (in [`MajorantKind::ALL`] order). Ties go
/// to the simpler structure (earlier in [`MajorantKind::ALL`]).
pub fn choose(field: &GridDensity, limits: &Limits) -> (Majorants, Vec<MajorantEstimate>) {
    let (rays, t_max) = pilot_rays(field, PILOT_RAYS, 0x51ed);
    let rank = |kind: MajorantKind| MajorantKind::ALL.iter().position(|k| *k == kind);
    let mut best: Option<(Majorants, f64)> = None;
    let mut estimates = Vec::with_capacity(MajorantKind::ALL.len());
    for kind in PILOT_ORDER {
        let Ok(majorants) = Majorants::try_build(kind, field, limits) else {
            continue;
        };
        let cap = best.as_ref().map_or(f64::INFINITY, |(_, cost)| {
            PILOT_WORK_CAP * cost * rays.len() as f64
        });
        let e = estimate(field, &majorants, &rays, t_max, cap);
        estimates.push(e);
        let wins = best.as_ref().is_none_or(|(m, cost)| {
            e.rays_traced == rays.len()
                && (e.cost_ns < *cost || (e.cost_ns == *cost && rank(kind) < rank(m.kind())))
        });
        if wins {
            best = Some((majorants, e.cost_ns));
        }
    }
    estimates.sort_by_key(|e| rank(e.kind));
    let (majorants, _) = best.expect("the global bound always fits the budget");
    (majorants, estimates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::density::test_fields::sphere_grid;

    #[test]
    fn thin_media_pick_the_global_bound_and_thick_ones_the_cheapest_estimate() {
        // The same ball at two density scales: thin, tracking is dominated by traversal; thick, by lookups.
        let limits = Limits::default();
        let (thin, thin_est) = choose(&sphere_grid(0.01), &limits);
        assert_eq!(thin.kind(), MajorantKind::Global, "{thin_est:?}");
        // Thick: the pick is the cheapest estimate.
        let (thick, thick_est) = choose(&sphere_grid(50.0), &limits);
        let cost = |es: &[MajorantEstimate], k| es.iter().find(|e| e.kind == k).unwrap().cost_ns;
        assert!(
            thick_est
                .iter()
                .all(|e| cost(&thick_est, thick.kind()) <= e.cost_ns),
            "{thick_est:?}"
        );
        // Very thick (100 per voxel at the centre): every structure's thick segments are refined to voxel
        // cells, so even the global bound stays cheap (without refinement it would take thousands of lookups
        // per ray), and the estimates count the voxel cells with the lookups.
        let (_, very_thick) = choose(&sphere_grid(2000.0), &limits);
        assert!(
            very_thick.iter().all(|e| e.lookups_per_ray < 100.0),
            "{very_thick:?}"
        );
        // Deterministic: the pilot counts work only.
        assert_eq!(choose(&sphere_grid(50.0), &limits).1, thick_est);
        // A budget too small for the adaptive structure's dense part leaves it out of the pilot.
        let adaptive = Majorants::dense_bytes(MajorantKind::Adaptive, &sphere_grid(1.0));
        let small = Limits::with_memory(adaptive - 1);
        let (_, estimates) = choose(&sphere_grid(50.0), &small);
        assert!(
            estimates.iter().all(|e| e.kind != MajorantKind::Adaptive),
            "{estimates:?}"
        );
    }
}
