//! The directional half of the guiding cache: a quadtree over the cylindrical (Lambert equal-area) map of the
//! sphere, built from a histogram of incident radiance, as in Müller et al. 2017, "Practical Path Guiding for
//! Efficient Light-Transport Simulation" (EGSR 2017; CGF 36(4)).
//!
//! A direction ω = (sin θ cos φ, sin θ sin φ, cos θ) maps to the unit square by u = (cos θ + 1)/2, v = φ/2π. The
//! map preserves area up to the constant 4π (the sphere's solid angle over the square's area 1), so a density q
//! over the square is the solid-angle density q/4π on the sphere (the cylindrical coordinates Müller et al.
//! 2017 use). Each node of the quadtree holds the energy (the histogram's sum) of its square; a node is
//! split while its energy exceeds [`SPLIT_FRACTION`] of the root's (their ρ = 0.01) and it is coarser than
//! the histogram. Sampling descends from the root choosing a child by its share of the parent's energy and is
//! uniform within the leaf reached, so the density of a direction is the product of 4 · (child share) over the
//! levels it descends (their Eq. 4 with the tree's own energies), exactly the sampled one.
//!
//! Paths do not sample the tree itself: its bin probabilities ([`DirectionalQuadtree::bin_probabilities`]) feed
//! the product with the phase function or the cosine ([`super::product`]). The tree's own sampler and density
//! are test-only; its tests check the tree the product reads.

use crate::math::{Vec2, Vec3};
use std::f32::consts::PI;

/// Levels of the finest subdivision: the histogram has `2^HISTOGRAM_LEVELS` bins a side.
pub const HISTOGRAM_LEVELS: u32 = 5;
/// Bins a side of the histogram.
pub const HISTOGRAM_SIDE: usize = 1 << HISTOGRAM_LEVELS;
/// A node is split while its energy exceeds this fraction of the whole (Müller et al. 2017 use ρ = 0.01).
const SPLIT_FRACTION: f64 = 0.01;

/// The point of the unit square (u, v) ∈ \[0, 1)² where the cylindrical map puts the unit direction `w`.
pub fn to_square(w: Vec3) -> Vec2 {
    let u = ((w.z.clamp(-1.0, 1.0) + 1.0) * 0.5).clamp(0.0, 1.0 - f32::EPSILON);
    let mut phi = w.y.atan2(w.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let v = (phi / (2.0 * PI)).clamp(0.0, 1.0 - f32::EPSILON);
    Vec2::new(u, v)
}

/// The unit direction at the point `p` of the unit square (the inverse of [`to_square`]).
pub fn from_square(p: Vec2) -> Vec3 {
    let cos_theta = 2.0 * p.x - 1.0;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * p.y;
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// The histogram bin of a point of the unit square.
pub fn bin_of(p: Vec2) -> usize {
    let side = HISTOGRAM_SIDE as f32;
    let i = ((p.x * side) as usize).min(HISTOGRAM_SIDE - 1);
    let j = ((p.y * side) as usize).min(HISTOGRAM_SIDE - 1);
    j * HISTOGRAM_SIDE + i
}

/// One node: its energy and, when split, the index of its first child (the four children are consecutive:
/// child `ix + 2 iy` covers the quarter `ix` along u and `iy` along v).
#[derive(Clone, Copy, Debug)]
struct Node {
    energy: f64,
    first_child: u32,
}

/// A sampling distribution over directions (see the module documentation).
#[derive(Clone, Debug)]
pub struct DirectionalQuadtree {
    nodes: Vec<Node>,
}

impl DirectionalQuadtree {
    /// The quadtree of a histogram of `HISTOGRAM_SIDE²` non-negative energies (bin `j · side + i` covers
    /// u ∈ \[i, i+1)/side, v ∈ \[j, j+1)/side); `None` when they hold no energy (or are not finite).
    pub fn from_histogram(bins: &[f64]) -> Option<Self> {
        debug_assert_eq!(bins.len(), HISTOGRAM_SIDE * HISTOGRAM_SIDE);
        let total: f64 = bins.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return None;
        }
        let mut tree = Self {
            nodes: vec![Node {
                energy: total,
                first_child: 0,
            }],
        };
        tree.split(0, 0, 0, HISTOGRAM_SIDE, bins, total * SPLIT_FRACTION);
        Some(tree)
    }

    /// Splits node `index`, covering the bins `[i0, i0 + size) × [j0, j0 + size)`, while its energy exceeds
    /// `threshold` and it spans more than one bin.
    fn split(&mut self, index: usize, i0: usize, j0: usize, size: usize, bins: &[f64], threshold: f64) {
        if size == 1 || self.nodes[index].energy <= threshold {
            return;
        }
        let half = size / 2;
        let first = self.nodes.len();
        self.nodes[index].first_child = first as u32;
        for child in 0..4 {
            let (ci, cj) = (i0 + (child & 1) * half, j0 + (child >> 1) * half);
            let energy = (cj..cj + half)
                .map(|j| bins[j * HISTOGRAM_SIDE + ci..j * HISTOGRAM_SIDE + ci + half].iter().sum::<f64>())
                .sum();
            self.nodes.push(Node {
                energy,
                first_child: 0,
            });
        }
        for child in 0..4 {
            let (ci, cj) = (i0 + (child & 1) * half, j0 + (child >> 1) * half);
            self.split(first + child, ci, cj, half, bins, threshold);
        }
    }

    /// Number of nodes.
    #[cfg(test)]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Samples a unit direction from `u` ∈ \[0, 1)²; returns it with its solid-angle density ([`Self::pdf`]).
    /// At each split node the u half is chosen by the halves' energies with `u.x`, then the v half within it
    /// with `u.y`, each value rescaled to \[0, 1) for the next level (as Müller et al. 2017 descend their quadtrees).
    #[cfg(test)]
    pub fn sample(&self, u: Vec2) -> (Vec3, f32) {
        let (mut ux, mut uy) = (u.x as f64, u.y as f64);
        let (mut origin, mut size) = (Vec2::ZERO, 1.0f32);
        let mut node = self.nodes[0];
        let mut density = 1.0f64;
        while node.first_child != 0 {
            let c = node.first_child as usize;
            let e = |k: usize| self.nodes[c + k].energy;
            let low_u = e(0) + e(2);
            let p_low_u = low_u / node.energy;
            let ix = if ux < p_low_u {
                ux /= p_low_u;
                0
            } else {
                ux = (ux - p_low_u) / (1.0 - p_low_u);
                1
            };
            let column = e(ix) + e(ix + 2);
            let p_low_v = e(ix) / column;
            let iy = if uy < p_low_v {
                uy /= p_low_v;
                0
            } else {
                uy = (uy - p_low_v) / (1.0 - p_low_v);
                1
            };
            let child = self.nodes[c + ix + 2 * iy];
            density *= 4.0 * child.energy / node.energy;
            size *= 0.5;
            origin += Vec2::new(ix as f32, iy as f32) * size;
            node = child;
        }
        let (ux, uy) = (ux.clamp(0.0, 1.0) as f32, uy.clamp(0.0, 1.0) as f32);
        let p = (origin + Vec2::new(ux, uy) * size).min(Vec2::splat(1.0 - f32::EPSILON));
        (from_square(p), (density / (4.0 * std::f64::consts::PI)) as f32)
    }

    /// The probability of each histogram bin under this distribution (bin `j · side + i` as in
    /// [`Self::from_histogram`]): every leaf's share of the root's energy, spread evenly over the bins it covers.
    /// The density is constant on each bin (a leaf covers whole bins), so these give it exactly.
    pub fn bin_probabilities(&self) -> Vec<f32> {
        let mut out = vec![0.0; HISTOGRAM_SIDE * HISTOGRAM_SIDE];
        self.spread(0, (0, 0), HISTOGRAM_SIDE, 1.0, &mut out);
        out
    }

    /// Spreads `share`, the probability of node `index` covering the bins from `corner` over `size` a side,
    /// over those bins (down its children where it is split).
    fn spread(&self, index: usize, corner: (usize, usize), size: usize, share: f64, out: &mut [f32]) {
        let node = self.nodes[index];
        if node.first_child == 0 {
            let per_bin = (share / (size * size) as f64) as f32;
            for j in corner.1..corner.1 + size {
                out[j * HISTOGRAM_SIDE + corner.0..j * HISTOGRAM_SIDE + corner.0 + size].fill(per_bin);
            }
            return;
        }
        let half = size / 2;
        for child in 0..4 {
            let c = node.first_child as usize + child;
            let child_corner = (corner.0 + (child & 1) * half, corner.1 + (child >> 1) * half);
            let child_share = share * self.nodes[c].energy / node.energy;
            self.spread(c, child_corner, half, child_share, out);
        }
    }

    /// Solid-angle density with which [`Self::sample`] returns the unit direction `w`.
    #[cfg(test)]
    pub fn pdf(&self, w: Vec3) -> f32 {
        let mut p = to_square(w);
        let mut node = self.nodes[0];
        let mut density = 1.0f64;
        while node.first_child != 0 {
            let ix = (p.x >= 0.5) as usize;
            let iy = (p.y >= 0.5) as usize;
            p = Vec2::new(p.x * 2.0 - ix as f32, p.y * 2.0 - iy as f32);
            let child = self.nodes[node.first_child as usize + ix + 2 * iy];
            density *= 4.0 * child.energy / node.energy;
            node = child;
        }
        (density / (4.0 * std::f64::consts::PI)) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::chi2;

    /// A histogram with a bright spot (a sun-like lobe), a dimmer band and empty bins.
    fn lumpy_histogram() -> Vec<f64> {
        let mut bins = vec![0.0; HISTOGRAM_SIDE * HISTOGRAM_SIDE];
        for (k, b) in bins.iter_mut().enumerate() {
            let (i, j) = (k % HISTOGRAM_SIDE, k / HISTOGRAM_SIDE);
            if i > 20 {
                *b = 0.3 + (j % 5) as f64;
            }
            if (3..6).contains(&i) && (10..12).contains(&j) {
                *b = 400.0;
            }
        }
        bins[0] = 1e4;
        bins
    }

    #[test]
    fn the_map_is_inverted() {
        for k in 0..200 {
            let u = Vec2::new((k as f32 * 0.618_034).fract(), (k as f32 * 0.414_213_5).fract());
            let back = to_square(from_square(u));
            assert!((back - u).abs().max_element() < 1e-4, "{u} -> {back}");
        }
    }

    #[test]
    fn the_density_integrates_to_one() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        assert!(tree.node_count() > 20, "{}", tree.node_count());
        // Midpoint rule over a grid finer than the histogram (the density is constant on each bin).
        let n = 256;
        let mut integral = 0.0f64;
        for a in 0..n {
            for b in 0..n {
                let p = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
                integral += tree.pdf(from_square(p)) as f64 * 4.0 * std::f64::consts::PI / (n * n) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 1e-4, "{integral}");
    }

    #[test]
    fn sampled_densities_are_the_pdf() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let mut rng = crate::math::Rng::new(3, 4);
        for _ in 0..1000 {
            let (w, pdf) = tree.sample(rng.next_2d());
            assert!((w.length() - 1.0).abs() < 1e-4);
            let again = tree.pdf(w);
            assert!((pdf - again).abs() <= 1e-3 * pdf, "{pdf} vs {again} at {w}");
        }
    }

    #[test]
    fn sampling_fits_the_pdf_chi2() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        chi2::assert_sampler_fits(
            "guiding quadtree",
            200_000,
            11,
            |rng| Some(tree.sample(rng.next_2d()).0),
            |w| tree.pdf(w) as f64,
        );
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn chi2_detects_a_wrong_pdf() {
        // Power check: the sampler of one histogram against the density of a slightly different one.
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let mut other = lumpy_histogram();
        other[0] *= 1.3;
        let claimed = DirectionalQuadtree::from_histogram(&other).unwrap();
        chi2::assert_sampler_fits(
            "guiding quadtree against another histogram's pdf",
            200_000,
            12,
            |rng| Some(tree.sample(rng.next_2d()).0),
            |w| claimed.pdf(w) as f64,
        );
    }

    #[test]
    fn bin_probabilities_are_the_density_on_each_bin() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let probabilities = tree.bin_probabilities();
        let total: f64 = probabilities.iter().map(|&p| p as f64).sum();
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        let bin_area = 1.0 / (HISTOGRAM_SIDE * HISTOGRAM_SIDE) as f32;
        for (k, &p) in probabilities.iter().enumerate() {
            let (i, j) = (k % HISTOGRAM_SIDE, k / HISTOGRAM_SIDE);
            let centre = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) / HISTOGRAM_SIDE as f32;
            let density = tree.pdf(from_square(centre)) * 4.0 * PI;
            assert!((p - density * bin_area).abs() <= 1e-4 * p.max(1e-6), "bin {k}: {p} vs {density}");
        }
    }

    #[test]
    fn an_empty_histogram_has_no_distribution() {
        assert!(DirectionalQuadtree::from_histogram(&vec![0.0; HISTOGRAM_SIDE * HISTOGRAM_SIDE]).is_none());
    }
}
