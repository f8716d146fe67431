//! The spatial half of the guiding cache and the cache itself: a binary tree over a cube around the scene and
//! its media, each leaf (a cell) with the directional quadtree learned there (Müller et al. 2017, "Practical
//! Path Guiding for Efficient Light-Transport Simulation": the SD-tree).
//!
//! Cells split at their midpoint along x, y, z in turn. After each training iteration k, a cell that received
//! more than `c · √(2^k)` radiance records is split until each part would (at an even spread) hold fewer
//! (their rule, with c = [`SPLIT_RECORDS`] records instead of their 12000 path vertices, for our smaller
//! training budgets), and the parts start from the parent's distribution. Each cell's histogram of the
//! iteration's records, averaged over blocks of 8 × 8 bins ([`smooth`]: the records are too few for more
//! directional resolution), becomes its quadtree for the next iteration; a cell that received no energy has none
//! (paths there sample the phase function alone).
//!
//! Each cell also keeps the mean incident radiance its records estimate (the histogram's total over the records
//! and 4π), and the cache keeps the training's pixel values ([`PixelEstimates`]): the two adjoint estimates of
//! guided Russian roulette and splitting ([`super::adjoint`]).
//!
//! Determinism: records are added in the order [`GuidingField::add_records`] gets them, one thread, so a
//! caller that hands them over in a fixed order (the training's rows, in row order) builds the same field on
//! any number of threads.

use super::adjoint::PixelEstimates;
use super::product::RadianceGrid;
use super::quadtree::{bin_of, to_square, DirectionalQuadtree, HISTOGRAM_SIDE};
use crate::math::{Aabb, Vec3};
use std::f64::consts::PI;

/// The `c` of the split rule (see the module documentation).
pub const SPLIT_RECORDS: f64 = 4000.0;
/// Histogram bins a side of the blocks each cell's histogram is averaged over before its quadtree is built
/// ([`smooth`]): 8 leaves 4 × 4 directions over the sphere.
const SMOOTHING_BLOCK: usize = 8;
/// The most cells the tree may have; a cell is not split beyond it.
pub const MAX_CELLS: usize = 4096;
/// The deepest a cell may be.
const MAX_DEPTH: u32 = 30;

/// What one path vertex teaches the cache: at point `p`, light arrived from the unit direction `dir`, which had
/// been sampled with solid-angle density `pdf`, with an incident-radiance estimate `radiance` (a luminance):
/// its histogram bin gets `radiance / pdf`, a Monte Carlo estimate of the bin's integral of incident radiance.
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
    /// Σ radiance / pdf per histogram bin this iteration.
    histogram: Vec<f64>,
    /// What paths sample from, learned in the previous iteration.
    distribution: Option<DirectionalQuadtree>,
    /// The same distribution tabulated for the product with the phase function at medium events.
    radiance_grid: Option<RadianceGrid>,
    /// The mean incident radiance over the sphere the previous iteration's records estimate (Σ radiance/pdf
    /// over the records, / 4π), when it had records.
    mean_radiance: Option<f32>,
    /// Depth in the spatial tree.
    depth: u32,
}

impl Cell {
    fn new(
        depth: u32,
        distribution: Option<DirectionalQuadtree>,
        mean_radiance: Option<f32>,
    ) -> Self {
        Self {
            records: 0,
            histogram: vec![0.0; HISTOGRAM_SIDE * HISTOGRAM_SIDE],
            radiance_grid: distribution.as_ref().map(RadianceGrid::new),
            distribution,
            mean_radiance,
            depth,
        }
    }
}

/// The guiding cache (an SD-tree): where paths look up a distribution of incident light to sample from.
#[derive(Clone, Debug)]
pub struct GuidingField {
    bounds: Aabb,
    nodes: Vec<SpatialNode>,
    cells: Vec<Cell>,
    /// Training iterations finished.
    iterations: u32,
    /// The training's pixel values, once given ([`GuidingField::set_pixel_estimates`]).
    pixels: Option<PixelEstimates>,
}

impl GuidingField {
    /// An empty cache over `bounds` (made a cube around their centre, so that cells split in turn along x, y,
    /// z stay near cubes), with one cell and no distribution.
    pub fn new(bounds: Aabb) -> Self {
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
        }
    }

    /// Number of cells (leaves of the spatial tree).
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Cells with a distribution to sample.
    pub fn guided_cell_count(&self) -> usize {
        self.cells.iter().filter(|c| c.distribution.is_some()).count()
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

    /// The distribution paths at `p` sample from, if the cell there learned one.
    #[cfg(test)]
    pub fn distribution_at(&self, p: Vec3) -> Option<&DirectionalQuadtree> {
        self.cells[self.cell_index(p)].distribution.as_ref()
    }

    /// The learned distribution at `p` tabulated for product guiding, if the cell there learned one.
    pub fn radiance_grid_at(&self, p: Vec3) -> Option<&RadianceGrid> {
        self.cells[self.cell_index(p)].radiance_grid.as_ref()
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
            cell.histogram[bin_of(to_square(r.dir))] += r.radiance as f64 / r.pdf as f64;
        }
    }

    /// Ends training iteration `self.iterations()`: every cell's histogram becomes its distribution (none
    /// without energy), cells over the split rule are split (their parts start from the new distribution),
    /// and every histogram starts again from zero.
    pub fn finish_iteration(&mut self) {
        let threshold = SPLIT_RECORDS * 2f64.powf(self.iterations as f64 * 0.5);
        for cell in &mut self.cells {
            smooth(&mut cell.histogram);
            cell.distribution = DirectionalQuadtree::from_histogram(&cell.histogram);
            cell.radiance_grid = cell.distribution.as_ref().map(RadianceGrid::new);
            let total: f64 = cell.histogram.iter().sum();
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
            cell.histogram.iter_mut().for_each(|b| *b = 0.0);
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
        let distribution = self.cells[cell].distribution.clone();
        let mean_radiance = self.cells[cell].mean_radiance;
        let other = self.cells.len();
        self.cells[cell].depth = depth + 1;
        self.cells
            .push(Cell::new(depth + 1, distribution, mean_radiance));
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

/// Replaces each [`SMOOTHING_BLOCK`]² block of the histogram `bins` by its mean (the total is kept). A bin's
/// sum is a few records of one path's radiance each, too noisy for the histogram's resolution: at full
/// resolution the learned distributions sampled the backlit cloud's incident radiance worse than uniform
/// sampling at 8 of 10 points checked against brute force, and averaging 8 × 8 blocks lowered guided MSE by
/// 6% (backlit cloud) and 22% (door-gap room; docs/performance.md, "Diagnosis with an oracle").
fn smooth(bins: &mut [f64]) {
    let (side, block) = (HISTOGRAM_SIDE, SMOOTHING_BLOCK);
    for j0 in (0..side).step_by(block) {
        for i0 in (0..side).step_by(block) {
            let rows = || (j0..j0 + block).map(|j| j * side + i0..j * side + i0 + block);
            let sum: f64 = rows().flat_map(|r| bins[r].iter().copied()).sum();
            let mean = sum / (block * block) as f64;
            rows().for_each(|r| bins[r].fill(mean));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smoothing spreads a bin's energy evenly over its block and keeps the total; other blocks stay empty.
    #[test]
    fn smoothing_spreads_each_block_evenly() {
        let mut bins = vec![0.0; HISTOGRAM_SIDE * HISTOGRAM_SIDE];
        bins[3 * HISTOGRAM_SIDE + 5] = 64.0;
        bins[20 * HISTOGRAM_SIDE + 30] = 6.4;
        smooth(&mut bins);
        let total: f64 = bins.iter().sum();
        assert!((total - 70.4).abs() < 1e-9, "{total}");
        for j in 0..HISTOGRAM_SIDE {
            for i in 0..HISTOGRAM_SIDE {
                let expected = match (j / SMOOTHING_BLOCK, i / SMOOTHING_BLOCK) {
                    (0, 0) => 1.0,
                    (2, 3) => 0.1,
                    _ => 0.0,
                };
                assert!((bins[j * HISTOGRAM_SIDE + i] - expected).abs() < 1e-12, "bin ({i}, {j})");
            }
        }
    }

    fn unit_box() -> Aabb {
        Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0))
    }

    #[test]
    fn cells_split_where_the_records_are_and_learn_their_light() {
        let mut field = GuidingField::new(unit_box());
        assert!(field.distribution_at(Vec3::ZERO).is_none());
        // Many records near one corner, light from +z; a few elsewhere, light from -x.
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
        records.push(RadianceRecord {
            p: Vec3::new(-0.8, -0.8, -0.8),
            dir: -Vec3::X,
            radiance: 2.0,
            pdf: 0.1,
        });
        field.add_records(&records);
        field.finish_iteration();
        assert!(field.cell_count() >= 8, "{}", field.cell_count());
        let near = field.distribution_at(Vec3::new(0.7, 0.6, 0.6)).unwrap();
        assert!(near.pdf(Vec3::Z) > 10.0 * near.pdf(-Vec3::Z));
        let far = field.distribution_at(Vec3::new(-0.8, -0.8, -0.8)).unwrap();
        assert!(far.pdf(-Vec3::X) > far.pdf(Vec3::X));
        // The same records in the same order give the same field.
        let mut again = GuidingField::new(unit_box());
        again.add_records(&records);
        again.finish_iteration();
        assert_eq!(again.cell_count(), field.cell_count());
        let w = Vec3::new(0.3, 0.4, 0.866).normalize();
        let p = Vec3::new(0.7, 0.6, 0.6);
        assert_eq!(
            again.distribution_at(p).unwrap().pdf(w).to_bits(),
            field.distribution_at(p).unwrap().pdf(w).to_bits()
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
                dir: super::super::quadtree::from_square(crate::math::Vec2::new(
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
        assert!(field.distribution_at(Vec3::ZERO).is_none());
        field.add_records(&[RadianceRecord { radiance: 1.0, ..bad }]);
        field.finish_iteration();
        assert!(field.distribution_at(Vec3::splat(100.0)).is_some());
        assert_eq!(field.iterations(), 2);
    }
}
