//! Product guiding: directions sampled in proportion to the learned incident radiance times the phase function
//! (or another factor of the direction), q(ω) ∝ L_i(x, ω) ρ(ω_o, ω), as Herholz et al. 2019, "Volume Path
//! Guiding Based on Zero-Variance Random Walk Theory" (TOG 38(3)), §4, do with their mixtures. Their guided
//! weight ρ/q is then (∫ ρ L_i dω)/L_i(ω): it varies with the radiance alone, not with the phase function too.
//!
//! Our distributions are quadtrees, whose product with a phase function has no closed form, so the product is
//! tabulated per scattering event on a coarse grid of the cylindrical (equal-area) map:
//!
//! - A cell's distribution is first turned into its bin probabilities on the histogram's grid
//!   ([`RadianceGrid`], once per cell at the end of training): m_f for each fine bin f, and their sums M_c over
//!   the [`PRODUCT_SIDE`]² coarse bins, each `FINE`² fine bins.
//! - Per event ([`ProductGuide`]), each coarse bin c gets the weight w_c = M_c · r(a · ω_c), with r the
//!   factor (the phase function of the scattering cosine) at the bin's centre direction ω_c and a its axis
//!   (−ω_o); W = Σ w_c.
//! - Sampling picks a coarse bin by w_c/W (its u index by the marginal, then its v index: the 2-D sample keeps
//!   its stratification), a fine bin in it by m_f/M_c (the same way), and a point uniformly in that fine bin.
//!   Its solid-angle density is exactly q(ω) = (w_c/W) (m_f/M_c) · N_f/4π (N_f fine bins of area 1/N_f on
//!   the square; the map preserves area up to 4π), which [`ProductGuide::pdf`] evaluates for MIS.
//!
//! The factor is only read at coarse-bin centres, so q is the product of the learned radiance with a piecewise
//! constant approximation of the phase function: any approximation leaves the estimator unbiased, since q is
//! the density it samples; only the variance depends on it.

use super::quadtree::{from_square, to_square, DirectionalQuadtree, HISTOGRAM_SIDE};
use crate::math::{Vec2, Vec3};
use std::f32::consts::PI;
use std::sync::LazyLock;

/// Bins a side of the coarse grid on which the product is tabulated per event (16 × 16 = 256 factor
/// evaluations per event).
pub const PRODUCT_SIDE: usize = 16;
/// Fine (histogram) bins a side of a coarse bin.
const FINE: usize = HISTOGRAM_SIDE / PRODUCT_SIDE;
/// Coarse bins.
const PRODUCT_BINS: usize = PRODUCT_SIDE * PRODUCT_SIDE;
/// The largest f32 below 1.
const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// The centre direction of every coarse bin (`j · PRODUCT_SIDE + i`: u index i, v index j).
static BIN_CENTRES: LazyLock<[Vec3; PRODUCT_BINS]> = LazyLock::new(|| {
    std::array::from_fn(|k| {
        let (i, j) = (k % PRODUCT_SIDE, k / PRODUCT_SIDE);
        from_square(Vec2::new(i as f32 + 0.5, j as f32 + 0.5) / PRODUCT_SIDE as f32)
    })
});

/// A cell's learned distribution of incident radiance, tabulated for the product (see the module
/// documentation): the probability of each histogram bin and their sums over each coarse bin.
#[derive(Clone, Debug)]
pub struct RadianceGrid {
    /// m_f: the probability of each histogram bin (`j · HISTOGRAM_SIDE + i`).
    fine: Vec<f32>,
    /// M_c: their sums over each coarse bin (`j · PRODUCT_SIDE + i`).
    coarse: Vec<f32>,
}

impl RadianceGrid {
    /// The grid of the distribution `tree` ([`DirectionalQuadtree::bin_probabilities`]).
    pub fn new(tree: &DirectionalQuadtree) -> Self {
        let fine = tree.bin_probabilities();
        let mut coarse = vec![0.0; PRODUCT_BINS];
        for (k, &m) in fine.iter().enumerate() {
            let (i, j) = (k % HISTOGRAM_SIDE, k / HISTOGRAM_SIDE);
            coarse[(j / FINE) * PRODUCT_SIDE + i / FINE] += m;
        }
        Self { fine, coarse }
    }
}

/// The product distribution at one event: the coarse bins' weights w_c and their sums (see the module
/// documentation).
#[derive(Clone, Copy, Debug)]
pub struct ProductGuide<'a> {
    grid: &'a RadianceGrid,
    /// w_c = M_c · r(a · ω_c).
    weights: [f32; PRODUCT_BINS],
    /// Σ_j w_(j, i) for each u index i: the marginal the u index is picked from.
    marginal: [f32; PRODUCT_SIDE],
    /// W = Σ w_c.
    total: f32,
}

impl<'a> ProductGuide<'a> {
    /// The product of `grid`'s radiance with `factor(a · ω)` (a function of the cosine between the direction
    /// and `axis`, non-negative); `None` where the product is zero everywhere (or not finite).
    pub fn new(grid: &'a RadianceGrid, axis: Vec3, factor: impl Fn(f32) -> f32) -> Option<Self> {
        let mut weights = [0.0; PRODUCT_BINS];
        let mut marginal = [0.0; PRODUCT_SIDE];
        for (k, (w, centre)) in weights.iter_mut().zip(BIN_CENTRES.iter()).enumerate() {
            let m = grid.coarse[k];
            if m > 0.0 {
                *w = m * factor(axis.dot(*centre)).max(0.0);
                marginal[k % PRODUCT_SIDE] += *w;
            }
        }
        let total: f32 = marginal.iter().sum();
        (total > 0.0 && total.is_finite()).then_some(Self {
            grid,
            weights,
            marginal,
            total,
        })
    }

    /// A direction sampled from the product by `u` ∈ \[0, 1)²: its density is [`Self::pdf`] of it.
    pub fn sample(&self, u: Vec2) -> Vec3 {
        let s = PRODUCT_SIDE;
        let (i, ux) = pick(self.marginal.iter().copied(), self.total, u.x);
        let row = (0..s).map(|j| self.weights[j * s + i]);
        let (j, uy) = pick(row, self.marginal[i], u.y);
        // The fine bin inside coarse bin (i, j): its u half by the fine columns' sums, then its v half.
        let fine = |a: usize, b: usize| self.grid.fine[(j * FINE + b) * HISTOGRAM_SIDE + i * FINE + a];
        let columns = (0..FINE).map(|a| (0..FINE).map(|b| fine(a, b)).sum::<f32>());
        let column_total: f32 = columns.clone().sum();
        let (a, ux) = pick(columns, column_total, ux);
        let cells = (0..FINE).map(|b| fine(a, b));
        let cells_total: f32 = cells.clone().sum();
        let (b, uy) = pick(cells, cells_total, uy);
        let corner = Vec2::new((i * FINE + a) as f32, (j * FINE + b) as f32);
        let p = (corner + Vec2::new(ux, uy)) / HISTOGRAM_SIDE as f32;
        from_square(p.min(Vec2::splat(ONE_BELOW)))
    }

    /// Solid-angle density with which [`Self::sample`] returns the unit direction `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        let p = to_square(w) * HISTOGRAM_SIDE as f32;
        let (fi, fj) = (
            (p.x as usize).min(HISTOGRAM_SIDE - 1),
            (p.y as usize).min(HISTOGRAM_SIDE - 1),
        );
        let c = (fj / FINE) * PRODUCT_SIDE + fi / FINE;
        let m_c = self.grid.coarse[c];
        if m_c <= 0.0 {
            return 0.0;
        }
        let m_f = self.grid.fine[fj * HISTOGRAM_SIDE + fi];
        let fine_bins = (HISTOGRAM_SIDE * HISTOGRAM_SIDE) as f32;
        self.weights[c] / self.total * (m_f / m_c) * fine_bins / (4.0 * PI)
    }
}

/// The index k picked with probability w_k / `total` by `u` ∈ \[0, 1) (the first whose running sum passes
/// u · total; zero weights are never picked), and `u` rescaled to \[0, 1) within it, for the next choice.
fn pick(weights: impl Iterator<Item = f32>, total: f32, u: f32) -> (usize, f32) {
    let target = u * total;
    let mut below = 0.0;
    let mut last = (0, ONE_BELOW);
    for (k, w) in weights.enumerate() {
        if w > 0.0 {
            if target < below + w {
                return (k, ((target - below) / w).clamp(0.0, ONE_BELOW));
            }
            below += w;
            last = (k, ONE_BELOW);
        }
    }
    // Rounding put the target past the running sum: the last bin with weight, at its far end.
    last
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::chi2;

    /// A histogram with a bright spot (a sun-like lobe), a dimmer band and empty bins, as the quadtree's tests.
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

    /// A Henyey–Greenstein lobe (g = 0.7, unnormalised) about `axis`.
    fn hg(cos: f32) -> f32 {
        let g = 0.7f32;
        let d = 1.0 + g * g - 2.0 * g * cos;
        1.0 / (d * d.sqrt())
    }

    #[test]
    fn the_density_integrates_to_one() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let grid = RadianceGrid::new(&tree);
        let guide = ProductGuide::new(&grid, Vec3::new(0.3, -0.5, 0.8).normalize(), hg).unwrap();
        // Midpoint rule over a grid finer than the histogram (the density is constant on each fine bin).
        let n = 256;
        let mut integral = 0.0f64;
        for a in 0..n {
            for b in 0..n {
                let p = Vec2::new((a as f32 + 0.5) / n as f32, (b as f32 + 0.5) / n as f32);
                integral += guide.pdf(from_square(p)) as f64 * 4.0 * std::f64::consts::PI / (n * n) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 1e-4, "{integral}");
    }

    #[test]
    fn sampling_fits_the_pdf_chi2() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let grid = RadianceGrid::new(&tree);
        for (k, axis) in [Vec3::Z, Vec3::new(-0.6, 0.2, -0.77).normalize()].into_iter().enumerate() {
            let guide = ProductGuide::new(&grid, axis, hg).unwrap();
            chi2::assert_sampler_fits(
                &format!("guiding product about {axis}"),
                200_000,
                21 + k as u64,
                |rng| Some(guide.sample(rng.next_2d())),
                |w| guide.pdf(w) as f64,
            );
        }
    }

    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn chi2_detects_a_product_with_another_axis() {
        // Power check: the product about one axis sampled, the density of the product about a nearby one claimed.
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let grid = RadianceGrid::new(&tree);
        let guide = ProductGuide::new(&grid, Vec3::Z, hg).unwrap();
        let claimed = ProductGuide::new(&grid, Vec3::new(0.0, 0.3, 0.95).normalize(), hg).unwrap();
        chi2::assert_sampler_fits(
            "guiding product against another axis's pdf",
            200_000,
            23,
            |rng| Some(guide.sample(rng.next_2d())),
            |w| claimed.pdf(w) as f64,
        );
    }

    #[test]
    fn a_constant_factor_gives_the_radiance_distribution() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let grid = RadianceGrid::new(&tree);
        let guide = ProductGuide::new(&grid, Vec3::Z, |_| 2.0).unwrap();
        let mut rng = crate::math::Rng::new(5, 6);
        for _ in 0..500 {
            let w = from_square(rng.next_2d());
            let (a, b) = (guide.pdf(w), tree.pdf(w));
            assert!((a - b).abs() <= 1e-4 * b.max(1e-3), "{a} vs {b} at {w}");
        }
    }

    #[test]
    fn a_product_that_is_zero_everywhere_is_none() {
        let tree = DirectionalQuadtree::from_histogram(&lumpy_histogram()).unwrap();
        let grid = RadianceGrid::new(&tree);
        assert!(ProductGuide::new(&grid, Vec3::Z, |_| 0.0).is_none());
        assert!(ProductGuide::new(&grid, Vec3::Z, |_| f32::NAN).is_none());
    }
}
