//! The film: per-pixel exact sums of the samples (see [`super::exact`]), from which the mean (beauty), the
//! alpha, the AOVs and the variance of the mean are taken. A film covers a window of the frame (the whole frame,
//! or the crop of a tile render), and films of the same frame add up exactly, whatever samples and pixels each
//! one holds. Beyond its core sums a film keeps what its [`LayerPlan`] asks for: RGB slots of exact sums
//! (light-path layers, colours, light groups, the shadow catcher) and Cryptomatte coverage maps; and, when deep
//! output is on, each pixel's deep bins ([`super::deep`]).

use super::aovs::{color_layer_name, LayerPlan, LightPath, CATCHER_LIT, CATCHER_OPEN};
use super::cryptomatte::IdCoverage;
use super::deep::{DeepImage, DeepPixel};
use super::exact::{clamp_sample, SquareSum, ValueSum};
use super::image::AovLayer;
use super::RenderImage;
use crate::integrator::PathSample;
use crate::math::{Rgb, Vec3};
use std::sync::Arc;

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

    /// Pixels in the window (saturating: a window that large fits no frame, and budgets refuse it).
    pub fn pixel_count(&self) -> usize {
        self.width().saturating_mul(self.height())
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

/// Why [`Film::merge`] refused a film.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilmMergeError {
    /// The films are of different frames or plans, or the window does not lie inside this film's.
    DoesNotFit,
    /// A count or sum of pixel (x, y) (in the frame) would overflow: more samples than a film can hold, or
    /// sums no samples could give.
    Overflow {
        /// Column of the pixel.
        x: usize,
        /// Row of the pixel.
        y: usize,
    },
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
    alpha: ValueSum,
}

impl PixelSums {
    /// Number of 32-bit words in [`to_words`](Self::to_words): the count, then the sums of radiance,
    /// squared radiance, albedo, normal, depth and alpha (see [`WORD_NAMES`](Self::WORD_NAMES)).
    pub const WORDS: usize = 1 + 11 * ValueSum::WORDS + 3 * SquareSum::WORDS;

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
        "alpha.A.0", "alpha.A.1", "alpha.A.2", "alpha.A.3",
    ];

    internal! {
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
            // Arrays, not the vectors' `Index`, whose match on the channel the loop kept.
            let (radiance, albedo, normal) = (
                s.radiance.to_array(),
                s.albedo.to_array(),
                s.normal.to_array(),
            );
            for c in 0..3 {
                let v = take(radiance[c]);
                self.sum[c].add_value(v);
                self.sum_sq[c].add_square(v);
                self.albedo[c].add_value(take(albedo[c]));
                self.normal[c].add_value(take(normal[c]));
            }
            self.depth.add_value(take(s.depth));
            self.alpha.add_value(take(s.alpha));
            clamped
        }
    }

    /// Adds the samples of `other` (another set of samples of the same pixel), or returns false (leaving these
    /// sums as they were) where a count or a sum would not fit: sums read from files are not bounded by the
    /// samples behind them.
    #[must_use]
    pub(crate) fn checked_merge(&mut self, other: &PixelSums) -> bool {
        let mut total = *self;
        let Some(count) = total.count.checked_add(other.count) else {
            return false;
        };
        total.count = count;
        let mut fits = true;
        for c in 0..3 {
            fits &= total.sum[c].checked_add(other.sum[c]);
            fits &= total.sum_sq[c].checked_add(other.sum_sq[c]);
            fits &= total.albedo[c].checked_add(other.albedo[c]);
            fits &= total.normal[c].checked_add(other.normal[c]);
        }
        fits &= total.depth.checked_add(other.depth);
        fits &= total.alpha.checked_add(other.alpha);
        if fits {
            *self = total;
        }
        fits
    }

    internal! {
        /// Number of samples added.
        pub fn count(&self) -> u32 {
            self.count
        }
    }

    /// The sums as 32-bit words, in the order of [`WORD_NAMES`](Self::WORD_NAMES), for files that carry the
    /// exact state of a partial render.
    pub(crate) fn to_words(self) -> [u32; Self::WORDS] {
        let values = |v: &[ValueSum]| v.iter().flat_map(|s| s.to_words()).collect::<Vec<_>>();
        let words = std::iter::once(self.count)
            .chain(values(&self.sum))
            .chain(self.sum_sq.iter().flat_map(|s| s.to_words()))
            .chain(values(&self.albedo))
            .chain(values(&self.normal))
            .chain(self.depth.to_words())
            .chain(self.alpha.to_words());
        let mut out = [0; Self::WORDS];
        for (o, w) in out.iter_mut().zip(words) {
            *o = w;
        }
        out
    }

    /// The inverse of [`to_words`](Self::to_words).
    pub(crate) fn from_words(words: &[u32; Self::WORDS]) -> Self {
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
            alpha: value(),
        }
    }
}

/// Adds a (possibly out-of-range) value to an exact sum; returns true when it had to be clamped.
pub(crate) fn add_clamped(sum: &mut ValueSum, v: f32) -> bool {
    let (v, clamped) = clamp_sample(v);
    sum.add_value(v);
    clamped
}

/// The sums of one pixel a render adds a sample to: its core sums, its slots (three values each, in the plan's
/// order), its Cryptomatte coverage maps (one per kind of the plan) and its deep bins (with deep output).
pub struct FilmPixel<'a> {
    /// The core sums.
    pub sums: &'a mut PixelSums,
    /// The slots' sums.
    pub slots: &'a mut [ValueSum],
    /// The Cryptomatte maps.
    pub crypto: &'a mut [IdCoverage],
    /// The deep bins, when the film keeps them.
    pub deep: Option<&'a mut DeepPixel>,
}

/// One row of a film's window, for parallel accumulation: the pixels' core sums, slots and Cryptomatte maps.
pub struct FilmRow<'a> {
    sums: &'a mut [PixelSums],
    slots: &'a mut [ValueSum],
    crypto: &'a mut [IdCoverage],
    /// The row's deep bins (empty without deep output).
    deep: &'a mut [DeepPixel],
    slot_values: usize,
    kinds: usize,
}

impl<'a> FilmRow<'a> {
    internal! {
        /// The pixels of the row, left to right.
        pub fn pixels(self) -> impl Iterator<Item = FilmPixel<'a>> {
            let (slot_values, kinds) = (self.slot_values, self.kinds);
            let n = self.sums.len();
            let mut slots = self.slots;
            let mut crypto = self.crypto;
            let mut deep = self.deep;
            self.sums.iter_mut().take(n).map(move |sums| {
                let (s, rest) = std::mem::take(&mut slots).split_at_mut(slot_values);
                slots = rest;
                let (c, rest) = std::mem::take(&mut crypto).split_at_mut(kinds);
                crypto = rest;
                let d = match std::mem::take(&mut deep).split_first_mut() {
                    Some((d, rest)) => {
                        deep = rest;
                        Some(d)
                    }
                    None => None,
                };
                FilmPixel {
                    sums,
                    slots: s,
                    crypto: c,
                    deep: d,
                }
            })
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
    plan: Arc<LayerPlan>,
    /// `plan.values_per_pixel()` sums per pixel, row-major.
    slots: Vec<ValueSum>,
    /// `plan.cryptomatte.len()` coverage maps per pixel, row-major.
    crypto: Vec<IdCoverage>,
    /// Each pixel's deep bins, row-major; empty without deep output.
    deep: Vec<DeepPixel>,
    /// The most deep samples per pixel of the image (0 without deep output).
    deep_samples: usize,
}

impl Film {
    /// An empty film of the whole `width` × `height` frame, with no layers beyond the core.
    pub fn new(width: usize, height: usize) -> Self {
        Self::with_window(width, height, PixelWindow::full(width, height))
    }

    /// An empty film of `window` (which should fit the frame) in a `width` × `height` frame, with no layers
    /// beyond the core.
    pub fn with_window(width: usize, height: usize, window: PixelWindow) -> Self {
        Self::with_plan(width, height, window, Arc::new(LayerPlan::default()))
    }

    internal! {
        /// An empty film of `window` in a `width` × `height` frame that keeps what `plan` asks for.
        pub fn with_plan(
            width: usize,
            height: usize,
            window: PixelWindow,
            plan: Arc<LayerPlan>,
        ) -> Self {
            let n = window.pixel_count();
            Self {
                width,
                height,
                window,
                pixels: vec![PixelSums::default(); n],
                slots: vec![ValueSum::default(); n * plan.values_per_pixel()],
                crypto: vec![IdCoverage::default(); n * plan.cryptomatte.len()],
                plan,
                deep: Vec::new(),
                deep_samples: 0,
            }
        }
    }

    /// Makes the film keep deep bins (empty so far), for an image with at most `max_samples` (at least 1) deep
    /// samples per pixel ([`super::deep`]). A film keeps them only from the samples added after this.
    pub(crate) fn enable_deep(&mut self, max_samples: usize) {
        self.deep = vec![DeepPixel::default(); self.pixels.len()];
        self.deep_samples = max_samples.max(1);
    }

    /// The most deep samples per pixel, when the film keeps deep bins.
    pub fn deep_samples(&self) -> Option<usize> {
        (self.deep_samples > 0).then_some(self.deep_samples)
    }

    internal! {
        /// What the film keeps beyond its core sums.
        pub fn plan(&self) -> &LayerPlan {
            &self.plan
        }
    }

    /// The slots' sums of the window: `plan().values_per_pixel()` per pixel, row-major.
    pub(crate) fn slots(&self) -> &[ValueSum] {
        &self.slots
    }

    /// The Cryptomatte maps of the window: `plan().cryptomatte.len()` per pixel, row-major.
    pub(crate) fn crypto(&self) -> &[IdCoverage] {
        &self.crypto
    }

    /// The rows of the window, top first, for parallel accumulation.
    pub(crate) fn rows_mut(&mut self) -> Vec<FilmRow<'_>> {
        let w = self.window.width();
        let (v, k) = (self.plan.values_per_pixel(), self.plan.cryptomatte.len());
        let mut slots = self.slots.as_mut_slice();
        let mut crypto = self.crypto.as_mut_slice();
        let mut deep = self.deep.as_mut_slice();
        let deep_width = if deep.is_empty() { 0 } else { w };
        self.pixels
            .chunks_mut(w.max(1))
            .map(|sums| {
                let (s, rest) = std::mem::take(&mut slots).split_at_mut(w * v);
                slots = rest;
                let (c, rest) = std::mem::take(&mut crypto).split_at_mut(w * k);
                crypto = rest;
                let (d, rest) = std::mem::take(&mut deep).split_at_mut(deep_width);
                deep = rest;
                FilmRow {
                    sums,
                    slots: s,
                    crypto: c,
                    deep: d,
                    slot_values: v,
                    kinds: k,
                }
            })
            .collect()
    }

    /// The pixels of the frame this film holds.
    pub fn window(&self) -> PixelWindow {
        self.window
    }

    internal! {
        /// The pixel sums of the window, row-major.
        pub fn pixels(&self) -> &[PixelSums] {
            &self.pixels
        }
    }

    internal! {
        /// The pixel sums of the window, row-major, for parallel accumulation.
        #[cfg(any(test, feature = "testing"))]
        pub fn pixels_mut(&mut self) -> &mut [PixelSums] {
            &mut self.pixels
        }
    }

    /// Adds the samples of `other`, a film of the same frame and plan (and deep output, or none) whose window
    /// lies inside this one's.
    /// Refuses (adding nothing) a film that does not fit, and stops at the first pixel whose counts or sums
    /// would overflow (possible only for sums read from files), leaving the pixels before it merged.
    pub fn merge(&mut self, other: &Film) -> Result<(), FilmMergeError> {
        if (other.width, other.height) != (self.width, self.height)
            || !self.window.contains(&other.window)
            || other.plan != self.plan
            || other.deep_samples != self.deep_samples
        {
            return Err(FilmMergeError::DoesNotFit);
        }
        let (w, ow) = (self.window.width(), other.window.width());
        let (v, k) = (self.plan.values_per_pixel(), self.plan.cryptomatte.len());
        for row in 0..other.window.height() {
            let y = other.window.y0 + row - self.window.y0;
            for x in 0..ow {
                let dst = y * w + other.window.x0 - self.window.x0 + x;
                let src = row * ow + x;
                let mut fits = self.pixels[dst].checked_merge(&other.pixels[src]);
                for j in 0..v {
                    fits &= self.slots[dst * v + j].checked_add(other.slots[src * v + j]);
                }
                for j in 0..k {
                    fits &= self.crypto[dst * k + j].checked_merge(&other.crypto[src * k + j]);
                }
                if let (Some(d), Some(o)) = (self.deep.get_mut(dst), other.deep.get(src)) {
                    fits &= d.checked_merge(o, super::deep::max_bins(self.deep_samples));
                }
                if !fits {
                    return Err(FilmMergeError::Overflow {
                        x: other.window.x0 + x,
                        y: other.window.y0 + row,
                    });
                }
            }
        }
        Ok(())
    }

    /// Sets the sums of pixel `i` (row-major in the window) from a part file: the core sums, the slots'
    /// sums and the Cryptomatte maps (`None` keeps what is there). Lengths must be the plan's.
    pub(crate) fn set_pixel(
        &mut self,
        i: usize,
        sums: PixelSums,
        slots: &[ValueSum],
        crypto: Option<Vec<IdCoverage>>,
    ) {
        let (v, k) = (self.plan.values_per_pixel(), self.plan.cryptomatte.len());
        self.pixels[i] = sums;
        self.slots[i * v..(i + 1) * v].copy_from_slice(slots);
        if let Some(c) = crypto {
            for (dst, src) in self.crypto[i * k..(i + 1) * k].iter_mut().zip(c) {
                *dst = src;
            }
        }
    }

    /// The image of the window: sample means for beauty, alpha and AOVs, the variance of the mean,
    /// `(Σx² − (Σx)²/n) / (n − 1) / n`, per channel, and the plan's layers (see [`super::aovs`]).
    pub fn image(&self) -> RenderImage {
        let mut img = RenderImage::new(self.window.width(), self.window.height());
        img.first_hit.retain(|f| self.plan.writes(f.name()));
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
            img.alpha[i] = (p.alpha.to_f64() / n) as f32;
            if p.count > 1 {
                let var = |c: usize| {
                    let (s, sq) = (p.sum[c].to_f64(), p.sum_sq[c].to_f64());
                    ((sq - s * s / n).max(0.0) / (n - 1.0) / n) as f32
                };
                img.variance[i] = Rgb::new(var(0), var(1), var(2));
            }
        }
        img.aovs = self.layer_images();
        img.cryptomatte = self.plan.cryptomatte.clone();
        img.deep = self.deep_image();
        img
    }

    /// The deep image of the window, when the film keeps deep bins.
    fn deep_image(&self) -> Option<DeepImage> {
        let max_samples = self.deep_samples()?;
        let mut image = DeepImage {
            width: self.window.width(),
            height: self.window.height(),
            max_samples,
            offsets: vec![0],
            samples: Vec::new(),
        };
        for (p, d) in self.pixels.iter().zip(&self.deep) {
            image.samples.extend(d.samples(p.count, max_samples));
            image.offsets.push(image.samples.len());
        }
        Some(image)
    }

    /// The mean of slot `slot` in pixel `i` (zero without samples), per channel, in `f64`.
    fn slot_mean(&self, i: usize, slot: usize) -> [f64; 3] {
        let n = self.pixels[i].count;
        if n == 0 {
            return [0.0; 3];
        }
        let base = i * self.plan.values_per_pixel() + 3 * slot;
        std::array::from_fn(|c| self.slots[base + c].to_f64() / n as f64)
    }

    /// The plan's written layers other than the first-hit ones, in the plan's order.
    fn layer_images(&self) -> Vec<AovLayer> {
        let n = self.pixels.len();
        let mut out = Vec::new();
        let rgb = |name: &str, value: &dyn Fn(usize) -> [f64; 3]| {
            let mut layer = AovLayer::rgb(name, n);
            for i in 0..n {
                for (channel, v) in layer.data.iter_mut().zip(value(i)) {
                    channel[i] = v as f32;
                }
            }
            layer
        };
        for name in &self.plan.written {
            if let Some(path) = LightPath::ALL.into_iter().find(|p| p.name() == name) {
                let slot = self.plan.slot(name).unwrap_or(0);
                let color = path
                    .color()
                    .and_then(|c| self.plan.slot(&color_layer_name(c)));
                out.push(rgb(name, &|i| {
                    let light = self.slot_mean(i, slot);
                    match color {
                        // Cycles' convention: light / colour, so that (direct + indirect) × colour is the
                        // light; nothing where the colour is nothing.
                        Some(c) => {
                            let color = self.slot_mean(i, c);
                            std::array::from_fn(|k| {
                                if color[k] > 0.0 {
                                    light[k] / color[k]
                                } else {
                                    0.0
                                }
                            })
                        }
                        None => light,
                    }
                }));
            } else if name == "shadow_catcher" {
                let (lit, open) = (
                    self.plan.slot(CATCHER_LIT).unwrap_or(0),
                    self.plan.slot(CATCHER_OPEN).unwrap_or(0),
                );
                out.push(rgb(name, &|i| {
                    let (l, o) = (self.slot_mean(i, lit), self.slot_mean(i, open));
                    std::array::from_fn(|k| if o[k] > 0.0 { l[k] / o[k] } else { 1.0 })
                }));
            } else if let Some(k) = self
                .plan
                .cryptomatte
                .iter()
                .position(|(kind, _)| kind.layer_name() == name)
            {
                out.extend(self.cryptomatte_layers(name, k));
            } else if let Some(slot) = self.plan.slot(name) {
                out.push(rgb(name, &|i| self.slot_mean(i, slot)));
            }
        }
        out
    }

    /// The rank layers `<Kind>00`, `<Kind>01`, … of Cryptomatte kind `k` of the plan.
    fn cryptomatte_layers(&self, name: &str, k: usize) -> Vec<AovLayer> {
        let depth = self.plan.cryptomatte_depth;
        let kinds = self.plan.cryptomatte.len();
        let n = self.pixels.len();
        let mut layers: Vec<AovLayer> = (0..depth / 2)
            .map(|l| AovLayer::cryptomatte(&format!("{name}{l:02}"), n))
            .collect();
        for i in 0..n {
            let ranks = self.crypto[i * kinds + k].ranks(self.pixels[i].count, depth);
            for (r, (id, coverage)) in ranks.into_iter().enumerate() {
                let layer = &mut layers[r / 2];
                layer.data[2 * (r % 2)][i] = id;
                layer.data[2 * (r % 2) + 1][i] = coverage;
            }
        }
        layers
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
            alpha: 0.25 * (k % 5) as f32,
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
        assert!(merged.checked_merge(&parts[0]));
        assert!(merged.checked_merge(&parts[1]));
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
        assert_eq!(first.merge(&second), Ok(()));
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
                alpha: 0.5,
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
        assert_eq!(whole.merge(&tile), Ok(()));
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
        assert_eq!(
            tile.merge(&whole),
            Err(FilmMergeError::DoesNotFit),
            "a larger window does not fit"
        );
        assert_eq!(
            whole.merge(&Film::new(5, 3)),
            Err(FilmMergeError::DoesNotFit),
            "another frame size does not fit"
        );
    }
}
