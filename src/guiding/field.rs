//! The spatial half of the guiding cache and the cache itself: a binary tree over a cube around the scene and
//! its media, each leaf (a cell) with the directional distribution learned there (the spatial tree of Müller et
//! al. 2017, "Practical Path Guiding for Efficient Light-Transport Simulation", with a vMF mixture per cell in
//! place of their quadtree, [`super::vmf`]).
//!
//! Cells split at their midpoint along x, y, z in turn. After each training iteration k, a cell that received
//! more than `c · √(2^k)` radiance records is split until each part would (at an even spread) hold fewer
//! (their rule, with c = [`SPLIT_RECORDS`] records instead of their 12000 path vertices, for our smaller
//! training budgets), and the parts start from the parent's distribution. Each cell keeps a uniform sample of at
//! most [`FIT_RECORDS`] of the iteration's records that carry energy (reservoir sampling, Vitter 1985's algorithm
//! R), to which a vMF mixture is fitted at the iteration's end ([`VmfMixture::fit`]): the cell's distribution
//! for the next iteration; a cell that received no energy has none (paths there sample the phase function alone).
//!
//! Each cell also keeps the mean incident radiance its records estimate (Σ radiance/pdf over the records, / 4π
//! and their count), and the cache keeps the training's pixel values ([`PixelEstimates`]): the two adjoint
//! estimates of guided Russian roulette and splitting ([`super::adjoint`]).
//!
//! Each cell also learns the probability with which the image's paths sample its guide
//! ([`GuidingField::guide_at`]): of [`SELECTION_CHOICES`], the one under which the iteration's records (each
//! with its strategies' densities) estimate the least second moment, guiding counted [`SELECTION_COST`] dearer.
//!
//! The cache also holds the grid of the direct light the training's decoupled samples received
//! ([`LitGrid`]), from which those samples draw guided distances.
//!
//! Determinism: records are added in the order [`GuidingField::add_records`] gets them, one thread (the
//! reservoirs draw from one seeded generator), so a caller that hands them over in a fixed order (the training's
//! rows, in row order) builds the same field on any number of threads; each cell's fit is its own.

use super::adjoint::PixelEstimates;
use super::lit::{DistanceGuide, LitGrid, LitRecord};
use super::vmf::{VmfMixture, FIT_RECORDS};
use super::GUIDE_PROBABILITY;
use crate::math::{Aabb, Rng, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// The `c` of the split rule (see the module documentation).
pub const SPLIT_RECORDS: f64 = 4000.0;
/// The most cells the tree may have; a cell is not split beyond it.
pub const MAX_CELLS: usize = 4096;
/// The deepest a cell may be.
const MAX_DEPTH: u32 = 30;
/// The guide's selection probabilities a cell chooses among ([`GuidingField::guide_at`]): 0 (the cell's
/// events are not guided, and no product is made there), or up to [`GUIDE_PROBABILITY`], which bounds a guided
/// event's weight.
pub const SELECTION_CHOICES: [f32; 3] = [0.0, 0.25, GUIDE_PROBABILITY];
/// The fewest guided records of an iteration from which a cell chooses its selection probability.
pub const MIN_SELECTION_RECORDS: u64 = 64;
/// What a guided event costs beyond an unguided one, as a fraction of the second moment: a cell guides only
/// where a positive selection probability's estimated second moment is below 1/(1 + this) of the unguided
/// one's (the product, its density and the lookup, about 2,000 instructions per event against about 7,700 for
/// an unguided event's share of the door-gap room's paths; 0, 0.05, 0.1 and 1 (no cell guided) measured on it,
/// docs/performance.md "Cutting guiding's cost on the door-gap room").
pub const SELECTION_COST: f64 = 0.1;

/// The selection probability of a cell whose records estimate the second moments `moments` under
/// [`SELECTION_CHOICES`] (the first, 0, unguided): the least of them, a guided one counted [`SELECTION_COST`]
/// higher; ties go to the smaller probability.
fn choose_selection(moments: &[f64; SELECTION_CHOICES.len()]) -> f32 {
    let cost = |k: usize| moments[k] * if k > 0 { 1.0 + SELECTION_COST } else { 1.0 };
    let mut best = 0;
    for k in 1..moments.len() {
        if cost(k) < cost(best) {
            best = k;
        }
    }
    SELECTION_CHOICES[best]
}

/// What one path vertex teaches the cache: at point `p`, light arrived from the unit direction `dir`, which had
/// been sampled with solid-angle density `pdf`, with an incident-radiance estimate `radiance` (a luminance):
/// its weight in the fit is `radiance / pdf`, a Monte Carlo estimate of the incident radiance's integral.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadianceRecord {
    /// Where the path scattered.
    pub p: Vec3,
    /// The direction it left in (toward where the light came from).
    pub dir: Vec3,
    /// The incident radiance along `dir` the path found (luminance, ≥ 0).
    pub radiance: f32,
    /// The density `dir` was sampled with.
    pub pdf: f32,
    /// The density of the unguided strategy (the phase function or the BSDF) at `dir`.
    pub unguided_pdf: f32,
    /// The density of the guide (the cell's distribution times the phase function or the cosine) at `dir`,
    /// where the event looked one up.
    pub guide_pdf: Option<f32>,
}

/// A node of the spatial tree: a leaf holds a cell, an inner node its two children.
#[derive(Clone, Copy, Debug)]
enum SpatialNode {
    /// Index into the cells.
    Leaf(u32),
    /// Index of the first child (the second follows) and the axis split at the midpoint.
    Inner { first_child: u32, axis: u8 },
}

/// One cell: its records of the iteration under way and the distribution learned before.
#[derive(Clone, Debug)]
struct Cell {
    /// Records added this iteration.
    records: u64,
    /// Σ radiance / pdf over this iteration's records.
    energy: f64,
    /// The mean incident radiance over the sphere the previous iteration's records estimate (Σ radiance/pdf
    /// over the records, / 4π), when it had records.
    mean_radiance: Option<f32>,
    /// Depth in the spatial tree.
    depth: u32,
    /// A uniform sample (reservoir) of this iteration's records with energy: direction and radiance / pdf.
    sample: Vec<(Vec3, f32)>,
    /// Records with energy this iteration (the reservoir's count).
    energetic: u64,
    /// What paths sample from: the vMF mixture fitted to the previous iteration's sample.
    vmf: Option<VmfMixture>,
    /// The estimated second moments of this iteration's guided records under each of [`SELECTION_CHOICES`]
    /// (see [`GuidingField::selection_at`]).
    moments: [f64; SELECTION_CHOICES.len()],
    /// Records of this iteration that count in `moments`.
    moment_records: u64,
    /// The probability with which the image's paths sample the guide here (learned, else
    /// [`GUIDE_PROBABILITY`]).
    selection: f32,
}

impl Cell {
    fn new(
        depth: u32,
        vmf: Option<VmfMixture>,
        mean_radiance: Option<f32>,
        selection: f32,
    ) -> Self {
        Self {
            records: 0,
            energy: 0.0,
            mean_radiance,
            depth,
            sample: Vec::new(),
            energetic: 0,
            vmf,
            moments: [0.0; SELECTION_CHOICES.len()],
            moment_records: 0,
            selection,
        }
    }
}

/// The guiding cache (a spatial tree of vMF mixtures): where paths look up a distribution of incident light to
/// sample from.
#[derive(Clone, Debug)]
pub struct GuidingField {
    bounds: Aabb,
    nodes: Vec<SpatialNode>,
    cells: Vec<Cell>,
    /// Training iterations finished.
    iterations: u32,
    /// The training's pixel values, once given ([`GuidingField::set_pixel_estimates`]).
    pixels: Option<PixelEstimates>,
    /// The reservoirs' random numbers (records arrive in a fixed order, so the samples are deterministic).
    rng: Rng,
    /// The direct light of the decoupled samples.
    lit: LitGrid,
    /// The transmittance the training's shadow rays found ([`super::shadow`]).
    shadow: LitGrid,
}

impl GuidingField {
    /// An empty cache over `bounds` (made a cube around their centre, so that cells split in turn along x, y,
    /// z stay near cubes), with one cell and no distribution.
    pub fn new(bounds: Aabb) -> Self {
        let lit = LitGrid::new(bounds);
        let (centre, half) = if bounds.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            (
                bounds.center(),
                (bounds.extent().max_element() * 0.5).max(1e-3),
            )
        };
        // A little margin so that points on the boundary are inside.
        let half = Vec3::splat(half * 1.001);
        Self {
            bounds: Aabb::new(centre - half, centre + half),
            nodes: vec![SpatialNode::Leaf(0)],
            cells: vec![Cell::new(0, None, None, GUIDE_PROBABILITY)],
            iterations: 0,
            pixels: None,
            rng: Rng::new(0x0076_6d66, 0),
            lit,
            shadow: LitGrid::new(bounds),
        }
    }

    /// Number of cells (leaves of the spatial tree).
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Cells with a distribution to sample.
    pub fn guided_cell_count(&self) -> usize {
        self.cells.iter().filter(|c| c.vmf.is_some()).count()
    }

    /// Training iterations finished.
    #[cfg(test)]
    pub fn iterations(&self) -> u32 {
        self.iterations
    }

    /// The index of the cell holding `p` (points outside the bounds are clamped into them).
    fn cell_index(&self, p: Vec3) -> usize {
        let (mut lo, mut hi) = (self.bounds.min, self.bounds.max);
        let p = p.clamp(lo, hi);
        let mut node = 0usize;
        loop {
            match self.nodes[node] {
                SpatialNode::Leaf(cell) => return cell as usize,
                SpatialNode::Inner { first_child, axis } => {
                    let a = axis as usize;
                    let mid = 0.5 * (lo[a] + hi[a]);
                    if p[a] < mid {
                        hi[a] = mid;
                        node = first_child as usize;
                    } else {
                        lo[a] = mid;
                        node = first_child as usize + 1;
                    }
                }
            }
        }
    }

    /// The distribution paths at `p` sample from (its product with the phase function or the cosine), if the
    /// cell there learned one.
    #[cfg(test)]
    pub fn vmf_at(&self, p: Vec3) -> Option<&VmfMixture> {
        self.cells[self.cell_index(p)].vmf.as_ref()
    }

    /// The distribution the cell at `p` learned, if any, and the probability with which the image's paths
    /// sample it (its product) there rather than the phase function or the BSDF: of [`SELECTION_CHOICES`], the
    /// one under which the last iteration's guided records estimate the least second moment of the direction's
    /// estimate (ρ L / (α q + (1 − α) ρ): the unguided density ρ, the guide's q, L the incident radiance),
    /// each record's term (ρ L)² / ((α q + (1 − α) ρ) p), p the density it was sampled with (an importance-
    /// sampled estimate of ∫ (ρ L)² / (α q + (1 − α) ρ), the second moment at α; the idea of Müller et al.
    /// 2019, "Practical Path Guiding in Production", learning the selection probability per cell, with a
    /// choice among a few values in place of their gradient descent), a positive one counted [`SELECTION_COST`]
    /// higher. [`GUIDE_PROBABILITY`] where the cell had fewer than [`MIN_SELECTION_RECORDS`] such records.
    pub fn guide_at(&self, p: Vec3) -> Option<(&VmfMixture, f32)> {
        let cell = &self.cells[self.cell_index(p)];
        cell.vmf.as_ref().map(|v| (v, cell.selection))
    }

    /// The mean incident radiance over the sphere at `p` (a luminance), as the cell there estimated it in the
    /// last training iteration; `None` where it had no records.
    pub fn mean_radiance_at(&self, p: Vec3) -> Option<f32> {
        self.cells[self.cell_index(p)].mean_radiance
    }

    /// Keeps the training's pixel values, which guided Russian roulette compares paths with.
    pub fn set_pixel_estimates(&mut self, pixels: PixelEstimates) {
        self.pixels = Some(pixels);
    }

    /// The training's value of pixel `(x, y)` ([`PixelEstimates::at`]), once given.
    pub fn pixel_estimate(&self, pixel: (usize, usize)) -> Option<f32> {
        self.pixels.as_ref().and_then(|p| p.at(pixel))
    }

    /// Adds records to the iteration under way, in order (non-finite or non-positive densities are skipped;
    /// every other record counts toward its cell's split, a dark one included).
    pub fn add_records(&mut self, records: &[RadianceRecord]) {
        for r in records {
            if !(r.pdf > 0.0 && r.pdf.is_finite() && r.radiance.is_finite() && r.radiance >= 0.0) {
                continue;
            }
            let index = self.cell_index(r.p);
            let cell = &mut self.cells[index];
            cell.records += 1;
            let energy = r.radiance / r.pdf;
            cell.energy += r.radiance as f64 / r.pdf as f64;
            if let Some(q) = r.guide_pdf {
                let (p, rho) = (r.pdf as f64, r.unguided_pdf as f64);
                if q >= 0.0 && q.is_finite() && rho > 0.0 && rho.is_finite() {
                    let f = rho * r.radiance as f64;
                    for (m, a) in cell.moments.iter_mut().zip(SELECTION_CHOICES) {
                        let a = a as f64;
                        *m += f * f / ((a * q as f64 + (1.0 - a) * rho) * p);
                    }
                    cell.moment_records += 1;
                }
            }
            if energy > 0.0 && energy.is_finite() {
                cell.energetic += 1;
                if cell.sample.len() < FIT_RECORDS {
                    cell.sample.push((r.dir, energy));
                } else {
                    // Reservoir sampling (Vitter's algorithm R): keep it with probability FIT_RECORDS / seen.
                    let k = (self.rng.next_f32() as f64 * cell.energetic as f64) as usize;
                    if k < FIT_RECORDS {
                        cell.sample[k] = (r.dir, energy);
                    }
                }
            }
        }
    }

    /// Adds the records of decoupled direct-light samples to the lit grid, in order ([`LitGrid::add`]).
    pub fn add_lit_records(&mut self, records: &[LitRecord]) {
        self.lit.add(records);
    }

    /// Adds the records of shadow rays to the shadow grid, in order ([`LitGrid::add`]).
    pub fn add_shadow_records(&mut self, records: &[LitRecord]) {
        self.shadow.add(records);
    }

    /// The probability with which an image path traces a shadow ray from `p`, at least `min_survival`
    /// ([`super::shadow`]).
    pub fn shadow_survival(&self, p: Vec3, min_survival: f32) -> f32 {
        super::shadow::survival(self.shadow.mean_at(p), min_survival)
    }

    /// The guided distance density of a decoupled sample on the segment `origin + t dir`, t ∈ [0, `length`],
    /// in a medium of mean extinction `sigma` ([`LitGrid::distance_guide`]).
    pub fn distance_guide(
        &self,
        origin: Vec3,
        dir: Vec3,
        length: f32,
        sigma: f32,
    ) -> Option<DistanceGuide> {
        self.lit.distance_guide(origin, dir, length, sigma)
    }

    /// Ends training iteration `self.iterations()`: every cell's sample is fitted (no distribution without
    /// energy), the lit grid's means are published, cells over the split rule are split (their parts start
    /// from the new distribution), and every cell's records start again from none.
    pub fn finish_iteration(&mut self) {
        let threshold = SPLIT_RECORDS * 2f64.powf(self.iterations as f64 * 0.5);
        self.cells.par_iter_mut().for_each(|cell| {
            cell.vmf = VmfMixture::fit(&cell.sample);
        });
        self.lit.finish_iteration();
        self.shadow.publish_means();
        for cell in &mut self.cells {
            let total = cell.energy;
            cell.mean_radiance = (cell.records > 0 && total.is_finite())
                .then(|| (total / (cell.records as f64 * 4.0 * PI)) as f32);
            if cell.moment_records >= MIN_SELECTION_RECORDS {
                cell.selection = choose_selection(&cell.moments);
            }
        }
        // Walk the leaves in node order (deterministic) and split those over the threshold.
        let leaves: Vec<(usize, usize)> = self
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(n, node)| match node {
                SpatialNode::Leaf(c) => Some((n, *c as usize)),
                SpatialNode::Inner { .. } => None,
            })
            .collect();
        for (node, cell) in leaves {
            let records = self.cells[cell].records as f64;
            if records > threshold {
                // Parts at an even spread: split until records / 2^levels ≤ threshold.
                let levels = (records / threshold).log2().ceil() as u32;
                self.split(node, cell, levels);
            }
        }
        for cell in &mut self.cells {
            cell.records = 0;
            cell.moments = [0.0; SELECTION_CHOICES.len()];
            cell.moment_records = 0;
            cell.energetic = 0;
            cell.sample.clear();
            cell.energy = 0.0;
        }
        self.iterations += 1;
    }

    /// Splits the leaf `node` (holding `cell`) `levels` times, each part starting from the cell's
    /// distribution.
    fn split(&mut self, node: usize, cell: usize, levels: u32) {
        let depth = self.cells[cell].depth;
        if levels == 0 || depth >= MAX_DEPTH || self.cells.len() >= MAX_CELLS {
            return;
        }
        let first_child = self.nodes.len();
        let mean_radiance = self.cells[cell].mean_radiance;
        let vmf = self.cells[cell].vmf;
        let selection = self.cells[cell].selection;
        let other = self.cells.len();
        self.cells[cell].depth = depth + 1;
        self.cells
            .push(Cell::new(depth + 1, vmf, mean_radiance, selection));
        self.nodes.push(SpatialNode::Leaf(cell as u32));
        self.nodes.push(SpatialNode::Leaf(other as u32));
        self.nodes[node] = SpatialNode::Inner {
            first_child: first_child as u32,
            axis: (depth % 3) as u8,
        };
        self.split(first_child, cell, levels - 1);
        self.split(first_child + 1, other, levels - 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> Aabb {
        Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    #[test]
    fn cells_split_where_the_records_are_and_learn_their_light() {
        let mut field = GuidingField::new(unit_box());
        assert!(field.vmf_at(Vec3::ZERO).is_none());
        // Many records near one corner, light from +z; fewer elsewhere, light from -x.
        let mut records = Vec::new();
        for k in 0..20_000 {
            let t = k as f32 / 20_000.0;
            records.push(RadianceRecord {
                p: Vec3::new(0.5 + 0.4 * t, 0.6, 0.7 - 0.2 * t),
                dir: Vec3::Z,
                radiance: 1.0,
                pdf: 0.25,
                unguided_pdf: 0.25,
                guide_pdf: None,
            });
        }
        // (Enough of them to be in the reservoirs' samples and to outweigh the fit's priors: a single record
        // does not make a lobe.)
        for _ in 0..2000 {
            records.push(RadianceRecord {
                p: Vec3::new(-0.8, -0.8, -0.8),
                dir: -Vec3::X,
                radiance: 2.0,
                pdf: 0.1,
                unguided_pdf: 0.1,
                guide_pdf: None,
            });
        }
        field.add_records(&records);
        field.finish_iteration();
        assert!(field.cell_count() >= 8, "{}", field.cell_count());
        let near = field.vmf_at(Vec3::new(0.7, 0.6, 0.6)).unwrap();
        assert!(near.pdf(Vec3::Z) > 10.0 * near.pdf(-Vec3::Z));
        let far = field.vmf_at(Vec3::new(-0.8, -0.8, -0.8)).unwrap();
        assert!(far.pdf(-Vec3::X) > far.pdf(Vec3::X));
        // The same records in the same order give the same field.
        let mut again = GuidingField::new(unit_box());
        again.add_records(&records);
        again.finish_iteration();
        assert_eq!(again.cell_count(), field.cell_count());
        let w = Vec3::new(0.3, 0.4, 0.866).normalize();
        let p = Vec3::new(0.7, 0.6, 0.6);
        assert_eq!(
            again.vmf_at(p).unwrap().pdf(w).to_bits(),
            field.vmf_at(p).unwrap().pdf(w).to_bits()
        );
    }

    /// Records of a uniform incident radiance L sampled uniformly over the sphere (pdf 1/4π) give a mean
    /// radiance of L; a cell without records has none.
    #[test]
    fn cells_estimate_their_mean_incident_radiance() {
        let mut field = GuidingField::new(unit_box());
        let pdf = 0.25 / std::f32::consts::PI;
        let records: Vec<RadianceRecord> = (0..100)
            .map(|k| RadianceRecord {
                p: Vec3::splat(0.5),
                dir: crate::math::sampling::uniform_sphere(crate::math::Vec2::new(
                    (k % 10) as f32 / 10.0 + 0.05,
                    (k / 10) as f32 / 10.0 + 0.05,
                )),
                radiance: 2.0,
                pdf,
                unguided_pdf: pdf,
                guide_pdf: None,
            })
            .collect();
        field.add_records(&records);
        field.finish_iteration();
        let mean = field.mean_radiance_at(Vec3::splat(0.5)).unwrap();
        assert!((mean - 2.0).abs() < 1e-5, "{mean}");
        assert!(field.pixel_estimate((0, 0)).is_none());
        let mut empty = GuidingField::new(unit_box());
        empty.finish_iteration();
        assert!(empty.mean_radiance_at(Vec3::ZERO).is_none());
    }

    /// Records of light from a cap about +z (L = 1 where z > 0.8), their directions uniform over the sphere
    /// (as the phase function of an isotropic medium samples them), each with the density at its direction of a
    /// guide lobe of κ 10 about `guide_axis`.
    fn cap_records(count: usize, guide_axis: Vec3) -> Vec<RadianceRecord> {
        let guide = crate::guiding::vmf::VmfLobe {
            mu: guide_axis,
            kappa: 10.0,
            weight: 1.0,
        };
        let uniform = 0.25 / std::f32::consts::PI;
        let mut rng = Rng::new(11, 12);
        (0..count)
            .map(|_| {
                let dir = crate::math::sampling::uniform_sphere(rng.next_2d());
                RadianceRecord {
                    p: Vec3::splat(0.5),
                    dir,
                    radiance: if dir.z > 0.8 { 1.0 } else { 0.0 },
                    pdf: uniform,
                    unguided_pdf: uniform,
                    guide_pdf: Some(guide.pdf(dir)),
                }
            })
            .collect()
    }

    /// A cell learns its selection probability from its records' estimated second moments: a guide toward the
    /// light is sampled with the largest probability, a guide away from it (where guiding only adds variance)
    /// not at all, and too few records leave [`GUIDE_PROBABILITY`].
    #[test]
    fn cells_learn_their_selection_probability() {
        let selection = |records: &[RadianceRecord]| {
            let mut field = GuidingField::new(unit_box());
            field.add_records(records);
            field.finish_iteration();
            field.guide_at(Vec3::splat(0.5)).unwrap().1
        };
        assert_eq!(selection(&cap_records(3000, Vec3::Z)), GUIDE_PROBABILITY);
        assert_eq!(selection(&cap_records(3000, -Vec3::Z)), 0.0);
        let few = MIN_SELECTION_RECORDS as usize - 1;
        let mut records = cap_records(3000, -Vec3::Z);
        records
            .iter_mut()
            .skip(few)
            .for_each(|r| r.guide_pdf = None);
        assert_eq!(selection(&records), GUIDE_PROBABILITY);
        // The choice weighs the cost of guiding: an estimated second moment below the unguided one's by less
        // than the cost is not guided.
        assert_eq!(choose_selection(&[1.0, 0.96, 0.95]), 0.0);
        assert_eq!(choose_selection(&[1.0, 0.85, 0.88]), SELECTION_CHOICES[1]);
    }

    #[test]
    fn bad_records_are_skipped_and_points_outside_are_clamped() {
        let mut field = GuidingField::new(unit_box());
        let bad = RadianceRecord {
            p: Vec3::ZERO,
            dir: Vec3::Z,
            radiance: f32::NAN,
            pdf: 1.0,
            unguided_pdf: 1.0,
            guide_pdf: None,
        };
        field.add_records(&[
            bad,
            RadianceRecord {
                pdf: 0.0,
                radiance: 1.0,
                ..bad
            },
        ]);
        field.finish_iteration();
        assert!(field.vmf_at(Vec3::ZERO).is_none());
        field.add_records(&[RadianceRecord {
            radiance: 1.0,
            ..bad
        }]);
        field.finish_iteration();
        assert!(field.vmf_at(Vec3::splat(100.0)).is_some());
        assert_eq!(field.iterations(), 2);
    }
}
