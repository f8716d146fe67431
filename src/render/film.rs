//! The film: per-pixel exact sums of the samples (see [`super::exact`]), from which the mean (beauty), the AOVs
//! and the variance of the mean are taken. A film covers a window of the frame (the whole frame, or the crop of
//! a tile render), and films of the same frame add up exactly, whatever samples and pixels each one holds.

use super::exact::{clamp_sample, SquareSum, ValueSum};
use super::RenderImage;
use crate::integrator::PathSample;
use crate::math::{Rgb, Vec3};

/// A rectangle of pixels `[x0, x1) × [y0, y1)` in a frame, `y = 0` the top row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PixelWindow {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// One past the last column.
    pub x1: usize,
    /// One past the last row.
    pub y1: usize,
}

impl PixelWindow {
    /// The whole of a `width` × `height` frame.
    pub fn full(width: usize, height: usize) -> Self {
        Self {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    /// Columns in the window.
    pub fn width(&self) -> usize {
        self.x1.saturating_sub(self.x0)
    }

    /// Rows in the window.
    pub fn height(&self) -> usize {
        self.y1.saturating_sub(self.y0)
    }

    /// Pixels in the window.
    pub fn pixel_count(&self) -> usize {
        self.width() * self.height()
    }

    /// True when the window holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.pixel_count() == 0
    }

    /// True when the window lies inside a `width` × `height` frame.
    pub fn fits(&self, width: usize, height: usize) -> bool {
        self.x1 <= width && self.y1 <= height
    }

    /// True when `other` lies inside this window.
    pub fn contains(&self, other: &PixelWindow) -> bool {
        other.x0 >= self.x0 && other.y0 >= self.y0 && other.x1 <= self.x1 && other.y1 <= self.y1
    }

    /// True when the two windows share a pixel.
    pub fn overlaps(&self, other: &PixelWindow) -> bool {
        self.x0.max(other.x0) < self.x1.min(other.x1)
            && self.y0.max(other.y0) < self.y1.min(other.y1)
    }
}

impl std::fmt::Display for PixelWindow {
    /// `x0,y0,x1,y1`, the syntax of `--crop`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.y0, self.x1, self.y1)
    }
}

/// Exact sums of one pixel's samples. Any two sets of samples of a pixel add up to the same bits in any order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PixelSums {
    count: u32,
    sum: [ValueSum; 3],
    sum_sq: [SquareSum; 3],
    albedo: [ValueSum; 3],
    normal: [ValueSum; 3],
    depth: ValueSum,
}

impl PixelSums {
    /// Number of 32-bit words in [`to_words`](Self::to_words): the count, then the sums of radiance,
    /// squared radiance, albedo, normal and depth (see [`WORD_NAMES`](Self::WORD_NAMES)).
    pub const WORDS: usize = 1 + 10 * ValueSum::WORDS + 3 * SquareSum::WORDS;

    /// The name of each word of [`to_words`](Self::to_words): `count`, then `sum.R.0` … `sum.R.3` (radiance,
    /// little-endian words of a two's-complement integer), `sumsq.R.0` … `sumsq.R.5`, `albedo.R.0`,
    /// `normal.X.0`, `depth.Z.0` and so on.
    #[rustfmt::skip]
    pub const WORD_NAMES: [&'static str; Self::WORDS] = [
        "count",
        "sum.R.0", "sum.R.1", "sum.R.2", "sum.R.3",
        "sum.G.0", "sum.G.1", "sum.G.2", "sum.G.3",
        "sum.B.0", "sum.B.1", "sum.B.2", "sum.B.3",
        "sumsq.R.0", "sumsq.R.1", "sumsq.R.2", "sumsq.R.3", "sumsq.R.4", "sumsq.R.5",
        "sumsq.G.0", "sumsq.G.1", "sumsq.G.2", "sumsq.G.3", "sumsq.G.4", "sumsq.G.5",
        "sumsq.B.0", "sumsq.B.1", "sumsq.B.2", "sumsq.B.3", "sumsq.B.4", "sumsq.B.5",
        "albedo.R.0", "albedo.R.1", "albedo.R.2", "albedo.R.3",
        "albedo.G.0", "albedo.G.1", "albedo.G.2", "albedo.G.3",
        "albedo.B.0", "albedo.B.1", "albedo.B.2", "albedo.B.3",
        "normal.X.0", "normal.X.1", "normal.X.2", "normal.X.3",
        "normal.Y.0", "normal.Y.1", "normal.Y.2", "normal.Y.3",
        "normal.Z.0", "normal.Z.1", "normal.Z.2", "normal.Z.3",
        "depth.Z.0", "depth.Z.1", "depth.Z.2", "depth.Z.3",
    ];

    /// Adds one sample whose radiance is finite. Returns true when a value had to be clamped into the range
    /// of the exact sums (see the module docs on clamping).
    pub fn add(&mut self, s: &PathSample) -> bool {
        let mut clamped = false;
        let mut take = |v: f32| {
            let (v, c) = clamp_sample(v);
            clamped |= c;
            v
        };
        self.count += 1;
        for c in 0..3 {
            let v = take(s.radiance[c]);
            self.sum[c].add_value(v);
            self.sum_sq[c].add_square(v);
            self.albedo[c].add_value(take(s.albedo[c]));
            self.normal[c].add_value(take(s.normal[c]));
        }
        self.depth.add_value(take(s.depth));
        clamped
    }

    /// Adds the samples of `other` (another set of samples of the same pixel).
    pub fn merge(&mut self, other: &PixelSums) {
        self.count += other.count;
        for c in 0..3 {
            self.sum[c].add(other.sum[c]);
            self.sum_sq[c].add(other.sum_sq[c]);
            self.albedo[c].add(other.albedo[c]);
            self.normal[c].add(other.normal[c]);
        }
        self.depth.add(other.depth);
    }

    /// Number of samples added.
    pub fn count(&self) -> u32 {
        self.count
    }

    /// The sums as 32-bit words, in the order of [`WORD_NAMES`](Self::WORD_NAMES), for files that carry the
    /// exact state of a partial render.
    pub fn to_words(&self) -> [u32; Self::WORDS] {
        let values = |v: &[ValueSum]| v.iter().flat_map(|s| s.to_words()).collect::<Vec<_>>();
        let words = std::iter::once(self.count)
            .chain(values(&self.sum))
            .chain(self.sum_sq.iter().flat_map(|s| s.to_words()))
            .chain(values(&self.albedo))
            .chain(values(&self.normal))
            .chain(self.depth.to_words());
        let mut out = [0; Self::WORDS];
        for (o, w) in out.iter_mut().zip(words) {
            *o = w;
        }
        out
    }

    /// The inverse of [`to_words`](Self::to_words).
    pub fn from_words(words: &[u32; Self::WORDS]) -> Self {
        let mut it = words[1..].iter().copied();
        let mut value = || ValueSum::from_words(std::array::from_fn(|_| it.next().unwrap_or(0)));
        let sum = [value(), value(), value()];
        let mut square = || SquareSum::from_words(std::array::from_fn(|_| it.next().unwrap_or(0)));
        let sum_sq = [square(), square(), square()];
        let mut value = || ValueSum::from_words(std::array::from_fn(|_| it.next().unwrap_or(0)));
        Self {
            count: words[0],
            sum,
            sum_sq,
            albedo: [value(), value(), value()],
            normal: [value(), value(), value()],
            depth: value(),
        }
    }
}

/// The accumulation buffer of a frame or of a window of it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Film {
    /// Width of the frame in pixels.
    pub width: usize,
    /// Height of the frame in pixels.
    pub height: usize,
    window: PixelWindow,
    pixels: Vec<PixelSums>,
}

impl Film {
    /// An empty film of the whole `width` × `height` frame.
    pub fn new(width: usize, height: usize) -> Self {
        Self::with_window(width, height, PixelWindow::full(width, height))
    }

    /// An empty film of `window` (which should fit the frame) in a `width` × `height` frame.
    pub fn with_window(width: usize, height: usize, window: PixelWindow) -> Self {
        Self {
            width,
            height,
            window,
            pixels: vec![PixelSums::default(); window.pixel_count()],
        }
    }

    /// The pixels of the frame this film holds.
    pub fn window(&self) -> PixelWindow {
        self.window
    }

    /// The pixel sums of the window, row-major.
    pub fn pixels(&self) -> &[PixelSums] {
        &self.pixels
    }

    /// The pixel sums of the window, row-major, for parallel accumulation.
    pub fn pixels_mut(&mut self) -> &mut [PixelSums] {
        &mut self.pixels
    }

    /// Adds the samples of `other`, a film of the same frame whose window lies inside this one's; returns
    /// false (and adds nothing) when it does not fit.
    pub fn merge(&mut self, other: &Film) -> bool {
        if (other.width, other.height) != (self.width, self.height)
            || !self.window.contains(&other.window)
        {
            return false;
        }
        let (w, ow) = (self.window.width(), other.window.width());
        for (row, src) in other.pixels.chunks_exact(ow.max(1)).enumerate() {
            let y = other.window.y0 + row - self.window.y0;
            let start = y * w + other.window.x0 - self.window.x0;
            for (dst, src) in self.pixels[start..start + ow].iter_mut().zip(src) {
                dst.merge(src);
            }
        }
        true
    }

    /// The image of the window: sample means for beauty and AOVs, and the variance of the mean,
    /// `(Σx² − (Σx)²/n) / (n − 1) / n`, per channel.
    pub fn image(&self) -> RenderImage {
        let mut img = RenderImage::new(self.window.width(), self.window.height());
        for (i, p) in self.pixels.iter().enumerate() {
            if p.count == 0 {
                continue;
            }
            let n = p.count as f64;
            let mean = |a: &[ValueSum; 3]| {
                Vec3::new(
                    (a[0].to_f64() / n) as f32,
                    (a[1].to_f64() / n) as f32,
                    (a[2].to_f64() / n) as f32,
                )
            };
            img.beauty[i] = mean(&p.sum);
            img.albedo[i] = mean(&p.albedo);
            img.normal[i] = mean(&p.normal).normalize_or_zero();
            img.depth[i] = (p.depth.to_f64() / n) as f32;
            if p.count > 1 {
                let var = |c: usize| {
                    let (s, sq) = (p.sum[c].to_f64(), p.sum_sq[c].to_f64());
                    ((sq - s * s / n).max(0.0) / (n - 1.0) / n) as f32
                };
                img.variance[i] = Rgb::new(var(0), var(1), var(2));
            }
        }
        img
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(k: u32) -> PathSample {
        let f = k as f32;
        PathSample {
            radiance: Rgb::new(0.1 * f, 1.0 / (1.0 + f), 3.0e-9 * f * f),
            albedo: Rgb::new(0.5, 0.25 * (k % 3) as f32, 1.0),
            normal: Vec3::new(0.6, -0.8, 0.0) * if k.is_multiple_of(2) { 1.0 } else { -1.0 },
            depth: 2.5 + f,
        }
    }

    #[test]
    fn window_geometry() {
        let w = PixelWindow {
            x0: 3,
            y0: 1,
            x1: 7,
            y1: 2,
        };
        assert_eq!((w.width(), w.height(), w.pixel_count()), (4, 1, 4));
        assert!(w.fits(7, 2) && !w.fits(6, 2) && !w.fits(7, 1));
        assert!(PixelWindow::full(8, 2).contains(&w));
        assert!(!w.contains(&PixelWindow::full(8, 2)));
        assert!(w.overlaps(&PixelWindow {
            x0: 6,
            y0: 0,
            x1: 9,
            y1: 9
        }));
        assert!(!w.overlaps(&PixelWindow {
            x0: 7,
            y0: 0,
            x1: 9,
            y1: 9
        }));
        assert!(!w.overlaps(&PixelWindow {
            x0: 0,
            y0: 2,
            x1: 9,
            y1: 9
        }));
        assert!(PixelWindow {
            x0: 2,
            y0: 0,
            x1: 2,
            y1: 5
        }
        .is_empty());
        assert_eq!(w.to_string(), "3,1,7,2");
    }

    #[test]
    fn pixel_sums_merge_in_any_grouping_and_round_trip_as_words() {
        let mut all = PixelSums::default();
        for k in 0..40 {
            assert!(!all.add(&sample(k)));
        }
        let mut parts = [PixelSums::default(); 3];
        for k in 0..40 {
            parts[[0, 2, 1, 2, 0][k as usize % 5]].add(&sample(k));
        }
        let mut merged = parts[2];
        merged.merge(&parts[0]);
        merged.merge(&parts[1]);
        assert_eq!(merged, all);
        assert_eq!(merged.count(), 40);
        assert_eq!(PixelSums::from_words(&all.to_words()), all);
        let mut names = PixelSums::WORD_NAMES.to_vec();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), PixelSums::WORDS);
    }

    #[test]
    fn float_sums_would_give_a_split_other_bits_but_exact_sums_do_not() {
        // Four samples of one pixel, rendered as the parts [0, 2) and [2, 4).
        let values = [1.0f32, 2f32.powi(-24), 2f32.powi(-54), 3.0 * 2f32.powi(-55)];
        // With f64 running sums, a single render adds in order, a merge adds the two parts' sums: the sums
        // round differently and the f32 means land on either side of a rounding midpoint.
        let v: Vec<f64> = values.iter().map(|&v| v as f64).collect();
        let single = ((v[0] + v[1]) + v[2]) + v[3];
        let merged = (v[0] + v[1]) + (v[2] + v[3]);
        assert_ne!((single / 4.0) as f32, (merged / 4.0) as f32);
        // The film's exact sums give the same bits both ways.
        let add = |film: &mut Film, v: f32| {
            film.pixels_mut()[0].add(&PathSample {
                radiance: Rgb::splat(v),
                ..Default::default()
            });
        };
        let mut whole = Film::new(1, 1);
        values.iter().for_each(|&v| add(&mut whole, v));
        let (mut first, mut second) = (Film::new(1, 1), Film::new(1, 1));
        values[..2].iter().for_each(|&v| add(&mut first, v));
        values[2..].iter().for_each(|&v| add(&mut second, v));
        assert!(first.merge(&second));
        assert_eq!(first, whole);
        assert_eq!(first.image(), whole.image());
    }

    #[test]
    fn clamped_values_are_reported() {
        let mut p = PixelSums::default();
        let mut s = sample(1);
        s.depth = f32::INFINITY;
        assert!(p.add(&s));
        s.depth = 1.0;
        s.albedo.x = f32::NAN;
        assert!(p.add(&s));
        assert_eq!(p.count(), 2);
    }

    #[test]
    fn image_is_mean_and_variance_of_the_mean() {
        let mut film = Film::new(2, 1);
        let values = [1.0f32, 2.0, 4.0];
        for v in values {
            film.pixels_mut()[1].add(&PathSample {
                radiance: Rgb::splat(v),
                albedo: Rgb::splat(0.5),
                normal: Vec3::new(0.0, 0.0, 2.0),
                depth: v,
            });
        }
        let img = film.image();
        assert_eq!(img.beauty[0], Rgb::ZERO);
        assert_eq!(img.beauty[1], Rgb::splat(7.0 / 3.0));
        assert_eq!(img.albedo[1], Rgb::splat(0.5));
        assert_eq!(img.normal[1], Vec3::Z);
        assert_eq!(img.depth[1], 7.0 / 3.0);
        // Sample variance 7/3, over n = 3.
        assert!((img.variance[1].x - 7.0 / 9.0).abs() < 1e-6);
    }

    #[test]
    fn windows_merge_into_their_place() {
        let mut whole = Film::new(5, 4);
        let window = PixelWindow {
            x0: 1,
            y0: 2,
            x1: 4,
            y1: 4,
        };
        let mut tile = Film::with_window(5, 4, window);
        for (i, p) in tile.pixels_mut().iter_mut().enumerate() {
            p.add(&sample(i as u32));
        }
        assert!(whole.merge(&tile));
        for y in 0..4 {
            for x in 0..5 {
                let inside = (1..4).contains(&x) && (2..4).contains(&y);
                let p = &whole.pixels()[y * 5 + x];
                assert_eq!(p.count(), inside as u32, "({x}, {y})");
                if inside {
                    assert_eq!(*p, tile.pixels()[(y - 2) * 3 + x - 1]);
                }
            }
        }
        assert!(!tile.merge(&whole), "a larger window does not fit");
        assert!(
            !whole.merge(&Film::new(5, 3)),
            "another frame size does not fit"
        );
    }
}
