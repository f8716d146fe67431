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
//! The cache also holds the grid of the direct light the training's decoupled samples received
//! ([`LitGrid`]), from which those samples draw guided distances.
//!
//! Determinism: records are added in the order [`GuidingField::add_records`] gets them, one thread (the
//! reservoirs draw from one seeded generator), so a caller that hands them over in a fixed order (the training's
//! rows, in row order) builds the same field on any number of threads; each cell's fit is its own.

use super::adjoint::PixelEstimates;
use super::lit::{DistanceGuide, LitGrid, LitRecord};
use super::vmf::{VmfMixture, FIT_RECORDS};
use crate::math::{Aabb, Rng, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// The `c` of the split rule (see the module documentation).
pub const SPLIT_RECORDS: f64 = 4000.0;
/// The most cells the tree may have; a cell is not split beyond it.
pub const MAX_CELLS: usize = 4096;
/// The deepest a cell may be.
const MAX_DEPTH: u32 = 30;

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
}

impl Cell {
    fn new(depth: u32, vmf: Option<VmfMixture>, mean_radiance: Option<f32>) -> Self {
        Self {
            records: 0,
            energy: 0.0,
            mean_radiance,
            depth,
            sample: Vec::new(),
            energetic: 0,
            vmf,
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
}

impl GuidingField {
    /// An empty cache over `bounds` (made a cube around their centre, so that cells split in turn along x, y,
    /// z stay near cubes), with one cell and no distribution.
    pub fn new(bounds: Aabb) -> Self {
        let lit = LitGrid::new(bounds);
        let (centre, half) = if bounds.is_empty() {
            (Vec3::ZERO, 1.0)
        } else {
            (bounds.center(), (bounds.extent().max_element() * 0.5).max(1e-3))
        };
        // A little margin so that points on the boundary are inside.
        let half = Vec3::splat(half * 1.001);
        Self {
            bounds: Aabb::new(centre - half, centre + half),
            nodes: vec![SpatialNode::Leaf(0)],
            cells: vec![Cell::new(0, None, None)],
            iterations: 0,
            pixels: None,
            rng: Rng::new(0x0076_6d66, 0),
            lit,
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
    pub fn vmf_at(&self, p: Vec3) -> Option<&VmfMixture> {
        self.cells[self.cell_index(p)].vmf.as_ref()
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
        for cell in &mut self.cells {
            let total = cell.energy;
            cell.mean_radiance = (cell.records > 0 && total.is_finite())
                .then(|| (total / (cell.records as f64 * 4.0 * PI)) as f32);
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
        let other = self.cells.len();
        self.cells[cell].depth = depth + 1;
        self.cells.push(Cell::new(depth + 1, vmf, mean_radiance));
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

    #[test]
    fn bad_records_are_skipped_and_points_outside_are_clamped() {
        let mut field = GuidingField::new(unit_box());
        let bad = RadianceRecord {
            p: Vec3::ZERO,
            dir: Vec3::Z,
            radiance: f32::NAN,
            pdf: 1.0,
        };
        field.add_records(&[bad, RadianceRecord { pdf: 0.0, radiance: 1.0, ..bad }]);
        field.finish_iteration();
        assert!(field.vmf_at(Vec3::ZERO).is_none());
        field.add_records(&[RadianceRecord { radiance: 1.0, ..bad }]);
        field.finish_iteration();
        assert!(field.vmf_at(Vec3::splat(100.0)).is_some());
        assert_eq!(field.iterations(), 2);
    }
}
