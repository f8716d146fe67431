//! Picks the majorant structure for a grid medium: the one with the least estimated tracking cost on this grid
//! at this density scale (`"majorant": "auto"`, the default).
//!
//! Which structure is cheapest depends on the data and on how optically thick the medium is:
//! - a small or thin medium is cheapest under one global bound, which costs no traversal at all;
//! - a large sparse one, or a thick one, pays for a finer structure, because every unit of majorant optical
//!   depth above the density is a wasted lookup.
//!
//! The choice is made by a pilot: [`PILOT_RAYS`] fixed-seed rays from the grid's bounding sphere towards points
//! inside its bounds are tracked through each structure, once by delta tracking (a free flight) and once by
//! ratio tracking (a shadow ray), counting density lookups and majorant cells walked. The estimated cost is
//! [`NS_PER_LOOKUP`] per lookup plus [`NS_PER_CELL`] per cell, constants fitted by `benches/fit_majorant_costs.py`
//! to `cargo bench --bench majorants -- --csv` timings of five corpus grids at mean optical depths 0.1 to 100
//! (see `docs/method_choices.md`). The pilot counts work, never time, so the choice is the same on every machine
//! and run.

use super::density::{DensityField, GridDensity};
use super::majorant::{MajorantKind, Majorants};
use super::tracking::{ratio_tracking, sample_collision, TrackingCounters};
use crate::math::{Ray, Rng, Vec3};

/// Rays in the pilot.
pub const PILOT_RAYS: usize = 256;
/// Fitted cost of one density lookup (trilinear, eight voxel reads), in nanoseconds of one core.
pub const NS_PER_LOOKUP: f64 = 65.0;
/// Fitted cost of one majorant cell walked (a DDA step and its segment), in nanoseconds of one core.
pub const NS_PER_CELL: f64 = 27.0;

/// The pilot's figures for one majorant structure.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MajorantEstimate {
    /// The structure.
    pub kind: MajorantKind,
    /// Density lookups per pilot ray (a free flight plus a shadow ray).
    pub lookups_per_ray: f64,
    /// Majorant cells walked per pilot ray.
    pub cells_per_ray: f64,
    /// Estimated nanoseconds per pilot ray.
    pub cost_ns: f64,
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

/// Estimates the tracking cost of `majorants` over `field` with the pilot rays.
pub fn estimate(
    field: &GridDensity,
    majorants: &Majorants,
    rays: &[Ray],
    t_max: f32,
) -> MajorantEstimate {
    let mut rng = Rng::new(0x9e37, majorants.kind() as u64);
    let mut counters = TrackingCounters::default();
    for ray in rays {
        sample_collision(field, majorants, ray, 0.0, t_max, &mut rng, &mut counters);
        ratio_tracking(field, majorants, ray, 0.0, t_max, &mut rng, &mut counters);
    }
    let n = rays.len().max(1) as f64;
    let lookups_per_ray = counters.density_lookups as f64 / n;
    let cells_per_ray = counters.majorant_cells as f64 / n;
    MajorantEstimate {
        kind: majorants.kind(),
        lookups_per_ray,
        cells_per_ray,
        cost_ns: NS_PER_LOOKUP * lookups_per_ray + NS_PER_CELL * cells_per_ray,
    }
}

/// Builds every structure over `field`, runs the pilot, and returns the cheapest with the estimates of all (in
/// [`MajorantKind::ALL`] order). Ties go to the simpler structure.
pub fn choose(field: &GridDensity) -> (Majorants, Vec<MajorantEstimate>) {
    let (rays, t_max) = pilot_rays(field, PILOT_RAYS, 0x51ed);
    let mut best: Option<(Majorants, f64)> = None;
    let mut estimates = Vec::with_capacity(MajorantKind::ALL.len());
    for kind in MajorantKind::ALL {
        let majorants = Majorants::build(kind, field);
        let e = estimate(field, &majorants, &rays, t_max);
        estimates.push(e);
        if best.as_ref().is_none_or(|(_, c)| e.cost_ns < *c) {
            best = Some((majorants, e.cost_ns));
        }
    }
    let (majorants, _) = best.expect("MajorantKind::ALL is not empty");
    (majorants, estimates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::density::test_fields::sphere_grid;

    #[test]
    fn thin_media_pick_the_global_bound_and_thick_ones_a_finer_structure() {
        // The same ball at two density scales: thin, tracking is dominated by traversal; thick, by lookups.
        let (thin, thin_est) = choose(&sphere_grid(0.01));
        assert_eq!(thin.kind(), MajorantKind::Global, "{thin_est:?}");
        let (thick, thick_est) = choose(&sphere_grid(50.0));
        assert_ne!(thick.kind(), MajorantKind::Global, "{thick_est:?}");
        let cost = |es: &[MajorantEstimate], k| es.iter().find(|e| e.kind == k).unwrap().cost_ns;
        assert!(cost(&thick_est, thick.kind()) < cost(&thick_est, MajorantKind::Global));
        // Deterministic: the pilot counts work only.
        assert_eq!(choose(&sphere_grid(50.0)).1, thick_est);
    }
}
