//! Adjoint-driven Russian roulette and splitting (Vorba & Křivánek 2016, "Adjoint-Driven Russian Roulette and
//! Splitting in Light Transport Simulation", TOG 35(4); in volumes as Herholz et al. 2019, "Volume Path Guiding
//! Based on Zero-Variance Random Walk Theory", TOG 38(3), §5).
//!
//! At a medium scattering event the path's expected contribution to its pixel is its throughput times the
//! radiance the cache expects to be scattered there (the cell's mean incident radiance,
//! [`super::GuidingField::mean_radiance_at`]); a zero-variance walk would keep that equal to the pixel's value
//! ([`PixelEstimates`], from the training pre-pass: like the continuation it is compared with, the light its
//! samples found after their first event's next-event estimate). Their ratio r is held in a weight window around 1
//! (Vorba & Křivánek 2016, §4.2, eq. 7: bounds 2/(1+s) and 2s/(1+s) with s = [`WINDOW_SPREAD`]): below it the
//! path survives with probability q = max(r, [`MIN_SURVIVAL`]) and its throughput is divided by q; above it the
//! path splits into n = ⌊r⌋ + (1 with probability r − ⌊r⌋) paths (at most [`MAX_SPLIT`], and within the
//! sample's budget of [`MAX_BRANCHES`] extra paths), each with throughput / n. Both keep every estimate
//! unbiased, whatever the estimates are: E\[1{u < q}/q\] = 1, and n independent continuations weighted 1/n each
//! have the expectation of one. Good estimates only lower the variance.

/// The window's spread s: its upper bound over its lower bound (Vorba & Křivánek 2016 use s = 5).
pub const WINDOW_SPREAD: f32 = 5.0;
/// The most paths one event splits into.
pub const MAX_SPLIT: u32 = 8;
/// The most extra paths splitting may add to one camera sample (bounds the work of a sample).
pub const MAX_BRANCHES: u32 = 64;
/// The lowest survival probability Russian roulette plays with (the ratio can be 0 where the cache saw no
/// light; a floor keeps such paths possible, so the estimate stays unbiased where the cache is wrong).
pub const MIN_SURVIVAL: f32 = 0.05;
/// Pixels a side of the tiles over which the training's pixel values are averaged ([`PixelEstimates`]): a
/// few training samples per pixel are too noisy alone.
pub const PIXEL_TILE: usize = 4;

/// The lower and upper bounds of the weight window, as ratios of the expected contribution to the pixel's
/// value (Vorba & Křivánek 2016, eq. 7, with the window's centre at ratio 1).
pub fn weight_window() -> (f32, f32) {
    let lower = 2.0 / (1.0 + WINDOW_SPREAD);
    (lower, lower * WINDOW_SPREAD)
}

/// What the weight window decides for a path at one event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Roulette {
    /// The path ends here.
    Ends,
    /// The path goes on as `copies` independent paths, each with its throughput times `weight`.
    GoesOn {
        /// How many paths continue from the event (1: no splitting).
        copies: u32,
        /// The factor on each copy's throughput: 1/q after roulette, 1/n after splitting, 1 inside the window.
        weight: f32,
    },
}

/// The weight window's decision for a path whose expected contribution is `ratio` times its pixel's value,
/// with `u` uniform in \[0, 1) and `budget` extra paths left to the sample (see the module documentation).
pub fn play(ratio: f32, u: f32, budget: u32) -> Roulette {
    let (lower, upper) = weight_window();
    if !ratio.is_finite() || ratio < lower {
        let survival = if ratio.is_finite() {
            ratio.clamp(MIN_SURVIVAL, 1.0)
        } else {
            MIN_SURVIVAL
        };
        return if u < survival {
            Roulette::GoesOn {
                copies: 1,
                weight: 1.0 / survival,
            }
        } else {
            Roulette::Ends
        };
    }
    if ratio <= upper {
        return Roulette::GoesOn {
            copies: 1,
            weight: 1.0,
        };
    }
    let whole = ratio.floor();
    let extra = u32::from(u < ratio - whole);
    let copies = (whole as u32 + extra).clamp(1, MAX_SPLIT.min(budget + 1));
    Roulette::GoesOn {
        copies,
        weight: 1.0 / copies as f32,
    }
}

/// The value each pixel's paths are compared with: the mean of the training samples' continuations (channel
/// means; [`super::GuidePath::continuation`], the light found after a sample's first event's next-event
/// estimate, as a path's continuation after an event's) over the [`PIXEL_TILE`]² tile the pixel lies in.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelEstimates {
    /// Tiles a row.
    tiles_x: usize,
    /// Per tile, the sum of the sample values and the number of samples.
    sums: Vec<(f64, u64)>,
}

impl PixelEstimates {
    /// No samples yet for a frame `width` × `height` pixels.
    pub fn new(width: usize, height: usize) -> Self {
        let tiles_x = width.div_ceil(PIXEL_TILE).max(1);
        let tiles_y = height.div_ceil(PIXEL_TILE).max(1);
        Self {
            tiles_x,
            sums: vec![(0.0, 0); tiles_x * tiles_y],
        }
    }

    /// The tile of pixel `(x, y)`, if inside the frame.
    fn tile(&self, (x, y): (usize, usize)) -> Option<usize> {
        let (tx, ty) = (x / PIXEL_TILE, y / PIXEL_TILE);
        (tx < self.tiles_x)
            .then_some(ty * self.tiles_x + tx)
            .filter(|&t| t < self.sums.len())
    }

    /// Adds a sample of value `value` (a channel mean) taken in pixel `(x, y)`; non-finite values are skipped.
    pub fn add(&mut self, pixel: (usize, usize), value: f32) {
        if let (Some(t), true) = (self.tile(pixel), value.is_finite()) {
            self.sums[t].0 += value as f64;
            self.sums[t].1 += 1;
        }
    }

    /// The estimate of pixel `(x, y)`: `None` outside the frame, where the tile took no samples, or where
    /// they saw no light (there is nothing to compare with).
    pub fn at(&self, pixel: (usize, usize)) -> Option<f32> {
        let (sum, count) = self.sums[self.tile(pixel)?];
        let mean = (sum / count.max(1) as f64) as f32;
        (count > 0 && mean > 0.0 && mean.is_finite()).then_some(mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    /// A random walk with a closed form: each step scores 1 and goes on with probability `albedo` (analog), so
    /// the expected score is 1/(1 − albedo). The weight window is played at every step against a deliberately
    /// poor adjoint estimate (a constant `adjoint` times the throughput), so it both kills and splits. Returns
    /// the mean score and its standard error over `paths` walks.
    fn walk_mean(
        paths: u32,
        albedo: f32,
        adjoint: f32,
        play: fn(f32, f32, u32) -> Roulette,
    ) -> (f64, f64) {
        let mut rng = Rng::new(7, 11);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..paths {
            let mut score = 0.0f64;
            let mut budget = MAX_BRANCHES;
            let mut pending = vec![1.0f32];
            while let Some(mut beta) = pending.pop() {
                loop {
                    score += beta as f64;
                    if rng.next_f32() >= albedo {
                        break;
                    }
                    match play(beta * adjoint, rng.next_f32(), budget) {
                        Roulette::Ends => break,
                        Roulette::GoesOn { copies, weight } => {
                            beta *= weight;
                            budget -= copies - 1;
                            pending.extend(std::iter::repeat_n(beta, copies as usize - 1));
                        }
                    }
                }
            }
            sum += score;
            sum2 += score * score;
        }
        let n = paths as f64;
        let mean = sum / n;
        (mean, ((sum2 / n - mean * mean) / n).sqrt())
    }

    /// The same window without the survivors' 1/q: what forgetting it does (biased low).
    fn play_forgetting_survival(ratio: f32, u: f32, budget: u32) -> Roulette {
        match play(ratio, u, budget) {
            Roulette::GoesOn { copies: 1, .. } if ratio < weight_window().0 => Roulette::GoesOn {
                copies: 1,
                weight: 1.0,
            },
            other => other,
        }
    }

    #[test]
    fn roulette_and_splitting_keep_the_closed_form_and_a_biased_window_fails() {
        let albedo = 0.9;
        let want = 1.0 / (1.0 - albedo as f64);
        // An adjoint estimate 10x too low kills, one 10x too high splits.
        for adjoint in [0.1f32, 10.0] {
            let (mean, se) = walk_mean(100_000, albedo, adjoint, play);
            assert!(
                (mean - want).abs() < 4.0 * se,
                "adjoint {adjoint}: {mean} vs {want} (se {se})"
            );
            let (biased, se) = walk_mean(100_000, albedo, adjoint, play_forgetting_survival);
            if adjoint < 1.0 {
                assert!(
                    (biased - want).abs() > 4.0 * se,
                    "the biased window passed: {biased} (se {se})"
                );
            }
        }
    }

    #[test]
    fn the_window_splits_within_its_bounds_and_leaves_the_middle_alone() {
        assert_eq!(
            play(1.0, 0.3, MAX_BRANCHES),
            Roulette::GoesOn {
                copies: 1,
                weight: 1.0
            }
        );
        assert_eq!(
            play(3.5, 0.2, MAX_BRANCHES),
            Roulette::GoesOn {
                copies: 4,
                weight: 0.25
            }
        );
        assert_eq!(
            play(3.5, 0.7, MAX_BRANCHES),
            Roulette::GoesOn {
                copies: 3,
                weight: 1.0 / 3.0
            }
        );
        assert_eq!(
            play(1e9, 0.5, MAX_BRANCHES),
            Roulette::GoesOn {
                copies: MAX_SPLIT,
                weight: 0.125
            }
        );
        assert_eq!(
            play(1e9, 0.5, 2),
            Roulette::GoesOn {
                copies: 3,
                weight: 1.0 / 3.0
            }
        );
        assert_eq!(
            play(1e9, 0.5, 0),
            Roulette::GoesOn {
                copies: 1,
                weight: 1.0
            }
        );
        assert_eq!(
            play(0.0, 0.04, MAX_BRANCHES),
            Roulette::GoesOn {
                copies: 1,
                weight: 20.0
            }
        );
        assert_eq!(play(0.0, 0.06, MAX_BRANCHES), Roulette::Ends);
        assert_eq!(play(f32::NAN, 0.06, MAX_BRANCHES), Roulette::Ends);
    }

    #[test]
    fn pixel_estimates_average_their_tile() {
        let mut e = PixelEstimates::new(6, 5);
        e.add((0, 0), 1.0);
        e.add((3, 3), 3.0);
        e.add((5, 4), 2.0);
        e.add((2, 1), f32::NAN);
        assert_eq!(e.at((1, 2)), Some(2.0));
        assert_eq!(e.at((4, 4)), Some(2.0));
        assert_eq!(e.at((4, 0)), None);
        assert_eq!(e.at((8, 0)), None);
        assert_eq!(e.at((0, 40)), None);
        let empty = PixelEstimates::new(4, 4);
        assert_eq!(empty.at((0, 0)), None);
    }
}
