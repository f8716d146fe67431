//! Guided distances for the decoupled direct-light sample in homogeneous media: a grid of the direct light that
//! the training's decoupled samples received, and the piecewise-constant distance density along a segment that
//! it gives (Herholz et al. 2019, "Volume Path Guiding Based on Zero-Variance Random Walk Theory", TOG 38(3),
//! §5: distances drawn in proportion to the cache's estimate of the in-scattered radiance along the ray).
//!
//! [`LitGrid`] is a uniform grid over the scene's box ([`LIT_RESOLUTION`] voxels along its longest side). Each
//! decoupled sample of a training path records, at its point, the direct light it received per unit of
//! σ_s T / p (its lights' radiance times the shadow rays' transmittance, the phase function and the MIS weight, a
//! luminance, [`LitRecord`]); a voxel's estimate is the mean of every record that fell in it over all training
//! iterations so far (each is an unbiased sample of the light there, however its distance was drawn), published
//! at the end of each iteration.
//!
//! [`DistanceGuide`] cuts a segment where it crosses the voxels (the volume module's 3D DDA,
//! `crate::volume::dda`) and gives piece i the weight max(L_i, [`LIT_FLOOR`] · L̄) ∫_piece e^{−σ t} dt, with
//! L_i the voxel's estimate (L̄, the length-weighted mean over the segment's pieces that have one, where a voxel
//! has none) and σ the mean of the medium's σ_t channels. The integral of the transmittance is taken by the
//! trapezoid rule with a rational stand-in for the exponential: any positive weights make a density, and the
//! estimator divides by the one it sampled. Within a piece the density is uniform. The traversal walks only the
//! box of the voxels with light: the parts of the segment outside it are one piece each, of estimate 0, and a
//! segment that misses it gets no guide. The floor keeps every part of the segment at a density of at least that
//! fraction of the mean, so a lit interval the grid missed is not left to the free-flight density alone.

use crate::math::{Aabb, Ray, Vec3};
use crate::volume::dda::{Dda, UniformGrid};
use glam::IVec3;

/// Voxels of [`LitGrid`] along the longest side of the scene's box.
pub const LIT_RESOLUTION: usize = 32;
/// The fraction of a segment's mean estimate below which no piece's estimate falls in [`DistanceGuide`].
pub const LIT_FLOOR: f32 = 0.05;
/// The most pieces a segment is cut into: one per voxel crossed (at most the sum of the grid's three
/// resolutions, plus the start voxel) and the parts before and after the box of the lit voxels.
const MAX_PIECES: usize = 3 * LIT_RESOLUTION + 4;

/// What a training path's decoupled direct-light sample received at `p`: its lights' radiance times the
/// transmittance of the shadow rays, the phase function and the MIS weight, over the lights' densities (a
/// luminance; the sample's value per unit of σ_s T(t) / p(t)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LitRecord {
    /// Where the decoupled sample was.
    pub p: Vec3,
    /// The direct light it received (≥ 0).
    pub value: f32,
}

/// The grid of the direct light decoupled samples receive (see the module documentation).
#[derive(Clone, Debug)]
pub struct LitGrid {
    /// The grid's box.
    bounds: Aabb,
    /// Voxels per axis.
    resolution: [usize; 3],
    /// The edge of a voxel (the same along every axis).
    voxel: f32,
    /// Σ value over the records of every iteration, per voxel.
    sums: Vec<f64>,
    /// Records per voxel, every iteration.
    counts: Vec<u32>,
    /// Each voxel's mean at the end of the last finished iteration; NaN where it had no record.
    means: Vec<f32>,
    /// The box of the voxels whose mean is positive (none: no light learned).
    lit_bounds: Option<Aabb>,
}

impl LitGrid {
    /// An empty grid over `bounds` (a voxel edge of the longest side / [`LIT_RESOLUTION`]), with no estimate.
    pub fn new(bounds: Aabb) -> Self {
        let (min, extent) = if bounds.is_empty() {
            (Vec3::splat(-1.0), Vec3::splat(2.0))
        } else {
            (bounds.min, bounds.extent())
        };
        let voxel = (extent.max_element() / LIT_RESOLUTION as f32).max(1e-4);
        let resolution =
            [0, 1, 2].map(|a| ((extent[a] / voxel).ceil() as usize).clamp(1, LIT_RESOLUTION));
        let max = min
            + Vec3::new(
                resolution[0] as f32,
                resolution[1] as f32,
                resolution[2] as f32,
            ) * voxel;
        let n = resolution.iter().product();
        Self {
            bounds: Aabb::new(min, max),
            resolution,
            voxel,
            sums: vec![0.0; n],
            counts: vec![0; n],
            means: vec![f32::NAN; n],
            lit_bounds: None,
        }
    }

    /// The voxel holding `p` (clamped into the grid).
    fn voxel_of(&self, p: Vec3) -> [usize; 3] {
        let q = (p - self.bounds.min) / self.voxel;
        [0, 1, 2].map(|a| (q[a].max(0.0) as usize).min(self.resolution[a] - 1))
    }

    fn index(&self, v: [usize; 3]) -> usize {
        (v[2] * self.resolution[1] + v[1]) * self.resolution[0] + v[0]
    }

    /// Adds records, in order (non-finite or negative values are skipped).
    pub fn add(&mut self, records: &[LitRecord]) {
        for r in records {
            if !(r.value.is_finite() && r.value >= 0.0 && r.p.is_finite()) {
                continue;
            }
            let i = self.index(self.voxel_of(r.p));
            self.sums[i] += r.value as f64;
            self.counts[i] = self.counts[i].saturating_add(1);
        }
    }

    /// The mean of the records in the voxel holding `p` (clamped into the grid) at the end of the last finished
    /// iteration, or `None` where it had none.
    pub fn mean_at(&self, p: Vec3) -> Option<f32> {
        let mean = self.means[self.index(self.voxel_of(p))];
        (!mean.is_nan()).then_some(mean)
    }

    /// The mean of the records so far in the voxel of `record`, `record` itself left out (one that
    /// [`LitGrid::add`] added): `None` where it is the voxel's only one, or was skipped. A leave-one-out mean,
    /// for judging what a mean learned from other rays predicts of this one (`auto`'s shadow-ray pilot).
    pub fn mean_without(&self, record: &LitRecord) -> Option<f32> {
        if !(record.value.is_finite() && record.value >= 0.0 && record.p.is_finite()) {
            return None;
        }
        let i = self.index(self.voxel_of(record.p));
        let others = self.counts[i].checked_sub(1).filter(|&n| n > 0)?;
        Some(((self.sums[i] - record.value as f64) / others as f64).max(0.0) as f32)
    }

    /// Publishes every voxel's mean over the records so far ([`LitGrid::mean_at`]), without the box of those
    /// with light that [`LitGrid::finish_iteration`] also finds (a grid asked only for means: the shadow grid).
    pub fn publish_means(&mut self) {
        for ((mean, &sum), &count) in self.means.iter_mut().zip(&self.sums).zip(&self.counts) {
            *mean = if count > 0 {
                (sum / count as f64) as f32
            } else {
                f32::NAN
            };
        }
    }

    /// Publishes every voxel's mean over the records so far, and the box of those with light (for
    /// [`LitGrid::distance_guide`]).
    pub fn finish_iteration(&mut self) {
        self.publish_means();
        let [nx, ny, _] = self.resolution;
        let (mut lo, mut hi) = ([usize::MAX; 3], [0usize; 3]);
        for (i, _) in self.means.iter().enumerate().filter(|(_, &m)| m > 0.0) {
            let v = [i % nx, (i / nx) % ny, i / (nx * ny)];
            for a in 0..3 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a] + 1);
            }
        }
        self.lit_bounds = (lo[0] != usize::MAX).then(|| {
            let corner = |v: [usize; 3]| {
                self.bounds.min + Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32) * self.voxel
            };
            Aabb::new(corner(lo), corner(hi))
        });
    }

    /// The distance density along the segment `origin + t dir`, t ∈ [0, `length`], in a medium of mean
    /// extinction `sigma` (per unit of t), or `None` when no voxel it crosses has a positive estimate (or the
    /// segment is empty or unbounded).
    pub fn distance_guide(
        &self,
        origin: Vec3,
        dir: Vec3,
        length: f32,
        sigma: f32,
    ) -> Option<DistanceGuide> {
        if !(length > 0.0 && length.is_finite() && sigma >= 0.0 && sigma.is_finite()) {
            return None;
        }
        // A segment that misses the lit voxels' box crosses no light (tested before the pieces' arrays are made).
        let span = self.lit_span(origin, dir, length)?;
        let mut guide = DistanceGuide {
            ends: [0.0; MAX_PIECES],
            cdf: [0.0; MAX_PIECES],
            len: 0,
            total: 0.0,
        };
        // First the pieces' estimates (NaN: none) in `cdf`; then their weights, summed.
        self.cut(origin, dir, length, span, &mut guide);
        let (mut known_length, mut known_sum) = (0.0f32, 0.0f32);
        let mut start = 0.0;
        for i in 0..guide.len {
            let value = guide.cdf[i];
            if !value.is_nan() {
                known_length += guide.ends[i] - start;
                known_sum += value * (guide.ends[i] - start);
            }
            start = guide.ends[i];
        }
        let mean = known_sum / known_length;
        if !(mean > 0.0 && mean.is_finite()) {
            return None;
        }
        let floor = LIT_FLOOR * mean;
        // The transmittance from the segment's start, at the piece's start, and over each piece e^{−x}
        // approximated by 1/(1 + x + x²/2) (positive and decreasing: any positive weights make a density, and
        // these need no exponential).
        let (mut start, mut total, mut decay) = (0.0f32, 0.0f32, 1.0f32);
        for i in 0..guide.len {
            let value = guide.cdf[i];
            let value = if value.is_nan() {
                mean
            } else {
                value.max(floor)
            };
            let end = guide.ends[i];
            let x = sigma * (end - start);
            let decay_end = decay / (1.0 + x * (1.0 + 0.5 * x));
            // The trapezoid rule for ∫ T over the piece.
            total += value * (end - start) * 0.5 * (decay + decay_end);
            guide.cdf[i] = total;
            start = end;
            decay = decay_end;
        }
        guide.total = total;
        (total > 0.0 && total.is_finite()).then_some(guide)
    }

    /// The part [t_in, t_out] of the segment `origin + t dir`, t ∈ [0, `length`], inside the box of the lit
    /// voxels; `None` when it misses the box (or no voxel has light).
    fn lit_span(&self, origin: Vec3, dir: Vec3, length: f32) -> Option<(f32, f32)> {
        let lit = self.lit_bounds?;
        let (mut t_in, mut t_out) = (0.0f32, length);
        for a in 0..3 {
            if dir[a] == 0.0 {
                if origin[a] < lit.min[a] || origin[a] > lit.max[a] {
                    return None;
                }
                continue;
            }
            let t0 = (lit.min[a] - origin[a]) / dir[a];
            let t1 = (lit.max[a] - origin[a]) / dir[a];
            t_in = t_in.max(t0.min(t1));
            t_out = t_out.min(t0.max(t1));
        }
        (t_in < t_out).then_some((t_in, t_out))
    }

    /// Cuts the segment into pieces where it crosses voxel faces inside the box of the lit voxels (`span`, from
    /// [`Self::lit_span`]): `guide.ends` the pieces' ends (increasing, the last `length`), `guide.cdf` their
    /// voxels' estimates (NaN for none), and one piece of estimate 0 for each part outside that box (no voxel
    /// there has light).
    fn cut(
        &self,
        origin: Vec3,
        dir: Vec3,
        length: f32,
        span: (f32, f32),
        guide: &mut DistanceGuide,
    ) {
        let push = |guide: &mut DistanceGuide, end: f32, value: f32| {
            let end = end.min(length);
            if guide.len == MAX_PIECES {
                // Never reached by the traversal's count; kept as a bound. The last piece takes the rest.
                guide.ends[MAX_PIECES - 1] = end;
                return;
            }
            guide.ends[guide.len] = end;
            guide.cdf[guide.len] = value;
            guide.len += 1;
        };
        let (t_in, t_out) = span;
        if t_in > 0.0 {
            push(guide, t_in, 0.0);
        }
        // The voxels the segment crosses inside that box, in order (the volume module's 3D DDA).
        let grid = UniformGrid {
            origin: self.bounds.min,
            cell: Vec3::splat(self.voxel),
            res: IVec3::from_array(self.resolution.map(|r| r as i32)),
        };
        let mut walk = Dda::inside(&grid, &Ray::new(origin, dir), dir.recip(), t_in, t_out);
        let mut cells = 0;
        while let Some((voxel, _, end)) = walk.next(&mut cells) {
            push(
                guide,
                end,
                self.means[self.index(voxel.to_array().map(|c| c as usize))],
            );
        }
        let last = if guide.len > 0 {
            guide.ends[guide.len - 1]
        } else {
            0.0
        };
        if last < length {
            push(guide, length, 0.0);
        }
    }
}

/// A piecewise-constant distance density over a segment [0, length] (see the module documentation), made by
/// [`LitGrid::distance_guide`].
#[derive(Clone, Debug)]
pub struct DistanceGuide {
    /// The pieces' ends, increasing; the last is the segment's length.
    ends: [f32; MAX_PIECES],
    /// The pieces' cumulative weights.
    cdf: [f32; MAX_PIECES],
    /// Pieces in use.
    len: usize,
    /// The sum of the weights (the last of `cdf`).
    total: f32,
}

impl DistanceGuide {
    /// The piece `i`'s start and end.
    fn piece(&self, i: usize) -> (f32, f32) {
        let start = if i == 0 { 0.0 } else { self.ends[i - 1] };
        (start, self.ends[i])
    }

    /// A distance from `u` ∈ [0, 1): a piece in proportion to its weight, then uniformly within it.
    pub fn sample(&self, u: f32) -> f32 {
        let target = u * self.total;
        let i = self.cdf[..self.len]
            .partition_point(|&c| c <= target)
            .min(self.len - 1);
        let before = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let weight = self.cdf[i] - before;
        let v = if weight > 0.0 {
            ((target - before) / weight).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let (start, end) = self.piece(i);
        (start + v * (end - start)).clamp(start, end)
    }

    /// The density of [`Self::sample`] at `t`, per unit of t (0 outside the segment).
    pub fn pdf(&self, t: f32) -> f32 {
        let length = self.ends[self.len - 1];
        if !(0.0..=length).contains(&t) {
            return 0.0;
        }
        let i = self.ends[..self.len]
            .partition_point(|&e| e <= t)
            .min(self.len - 1);
        let (start, end) = self.piece(i);
        let before = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        if end > start {
            (self.cdf[i] - before) / (self.total * (end - start))
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    #[test]
    fn the_mean_without_a_record_is_that_of_the_others_in_its_voxel() {
        let mut grid = LitGrid::new(Aabb::new(Vec3::ZERO, Vec3::splat(4.0)));
        let at = |x: f32, value: f32| LitRecord {
            p: Vec3::new(x, 0.1, 0.1),
            value,
        };
        let (a, b, c, alone) = (at(0.01, 0.2), at(0.02, 0.4), at(0.03, 0.9), at(3.9, 0.5));
        grid.add(&[a, b, c, alone]);
        assert!((grid.mean_without(&a).unwrap() - 0.65).abs() < 1e-6);
        assert!((grid.mean_without(&c).unwrap() - 0.3).abs() < 1e-6);
        assert_eq!(grid.mean_without(&alone), None, "alone in its voxel");
        assert_eq!(grid.mean_without(&at(0.01, f32::NAN)), None, "never added");
    }

    /// A grid over [0, 4]³ whose voxels in the slab 1.5 ≤ x < 2 are lit (value 2), all others dark (0) except
    /// those with z ≥ 3, which have no record.
    fn shaft() -> LitGrid {
        let mut grid = LitGrid::new(Aabb::new(Vec3::ZERO, Vec3::splat(4.0)));
        let h = 4.0 / LIT_RESOLUTION as f32;
        let mut records = Vec::new();
        for i in 0..LIT_RESOLUTION {
            for j in 0..LIT_RESOLUTION {
                for k in 0..LIT_RESOLUTION {
                    let p = Vec3::new(i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5) * h;
                    if p.z < 3.0 {
                        let lit = (1.5..2.0).contains(&p.x);
                        records.push(LitRecord {
                            p,
                            value: if lit { 2.0 } else { 0.0 },
                        });
                    }
                }
            }
        }
        grid.add(&records);
        grid.finish_iteration();
        grid
    }

    /// The sampler fits its density (chi-square), on segments that cross the lit slab, start and end outside
    /// the grid, run along an axis, and reach voxels without records.
    #[test]
    fn the_piecewise_distance_sampler_fits_its_density() {
        let grid = shaft();
        for (i, (origin, dir, length, sigma)) in [
            (Vec3::new(0.1, 1.0, 1.0), Vec3::new(1.0, 0.1, 0.2), 3.5, 0.5),
            (
                Vec3::new(-1.0, 2.0, 2.0),
                Vec3::new(1.0, 0.0, 0.0),
                6.0,
                0.0,
            ),
            (
                Vec3::new(3.9, 0.3, 1.0),
                Vec3::new(-0.7, 0.3, 0.6),
                4.0,
                2.0,
            ),
            (
                Vec3::new(1.7, 3.0, 3.5),
                Vec3::new(0.0, -0.6, -0.8),
                3.0,
                1.0,
            ),
        ]
        .into_iter()
        .enumerate()
        {
            let dir = dir.normalize();
            let guide = grid.distance_guide(origin, dir, length, sigma).unwrap();
            let mut rng = Rng::new(11, i as u64);
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("lit distance {i}"),
                200_000,
                (0.0, length as f64),
                || {
                    let t = guide.sample(rng.next_f32());
                    assert!(guide.pdf(t) > 0.0, "{i}: {t}");
                    t
                },
                |t| guide.pdf(t as f32) as f64,
            );
        }
    }

    /// Every piece keeps at least the floor's share of the density, the lit slab gets most of it, and a
    /// segment that crosses only dark voxels, or none with a record, has no guide.
    #[test]
    fn the_density_favours_the_lit_voxels_and_keeps_a_floor() {
        let grid = shaft();
        let (origin, dir, length) = (Vec3::new(0.1, 1.0, 1.0), Vec3::X, 3.8);
        let guide = grid.distance_guide(origin, dir, length, 0.0).unwrap();
        // Lit over [1.4, 1.9] of the segment (x from 1.5 to 2.0).
        let lit: f32 = (0..1000)
            .map(|k| guide.pdf(1.4 + 0.5 * (k as f32 + 0.5) / 1000.0))
            .sum::<f32>()
            * 0.5
            / 1000.0;
        assert!(lit > 0.7, "{lit}");
        let mean = 1.0 / length;
        let dark = guide.pdf(0.5);
        assert!(dark > 0.0 && dark < 0.2 * mean, "{dark}");
        assert!(grid
            .distance_guide(Vec3::new(0.1, 1.0, 1.0), Vec3::Y, 2.0, 0.0)
            .is_none());
        assert!(grid
            .distance_guide(Vec3::new(1.7, 1.0, 3.5), Vec3::Y, 2.0, 0.0)
            .is_none());
        assert!(grid
            .distance_guide(origin, dir, f32::INFINITY, 0.0)
            .is_none());
    }
}
