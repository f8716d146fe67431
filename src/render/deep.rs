//! Deep samples (OpenEXR 2.0 deep data): per pixel, a list of samples at depths, each with its own alpha and
//! premultiplied colour, so that a compositor can merge the render with other deep images and hold it out by
//! them (OpenEXR's "Interpreting OpenEXR Deep Pixels"). Surfaces are point samples (`Z == ZBack`); media are
//! depth intervals (`Z < ZBack`), whose alpha a compositor spreads over the interval as a uniform density.
//!
//! **Depth.** `Z` and `ZBack` are distances along the camera's view axis (the camera-space depth, OpenEXR's
//! convention for deep `Z`), not along the ray: a camera ray's distance `t` becomes `t · cos θ`, θ the angle
//! between the ray and the view axis (for a moving camera, the axis at the sample's time). For an orthographic
//! camera `Z` is `t`.
//!
//! **What a sample is made of.** Each camera path is put in one *bin* of its pixel by the event along the
//! camera ray that decided its coverage (the path's alpha):
//! - an opaque surface at depth `z`: a surface bin, one per depth bucket, a point sample at the mean `z` of
//!   its paths;
//! - a real collision in a medium at depth `z`: a medium bin, one per depth bucket, an interval over the
//!   bucket clipped to where the camera rays crossed media;
//! - the end of the camera ray without either (it escaped, or a holdout cut it): the light of the environment
//!   seen directly goes to a background point sample (at the holdout, or at [`FAR`]), and the rest of the
//!   path's light and its alpha (a medium whose tracking weights, not collisions, took a part of the sample)
//!   to a *passed* bin over the span of media the camera ray crossed, which is shared out over the buckets it
//!   covers by length.
//!
//! Depth buckets are [`BUCKETS_PER_OCTAVE`] per doubling of depth: bucket `k` is `[2^(k/16), 2^((k+1)/16))`, 4.4%
//! of its depth deep. Every bin sums its paths' radiance and alpha exactly (`ValueSum`, like the film's
//! beauty), so bins of one pixel add up, over all of them, to the beauty and alpha sums bit for bit, in any
//! order of the samples.
//!
//! **From additive bins to samples that composite.** Divided by the pixel's sample count `n`, bin `i` holds an
//! additive colour `s_i` and coverage `c_i`, and `Σ s_i` is the flat beauty, `Σ c_i` the flat alpha. Sorted
//! front to back, deep samples `(C_i, A_i)` flatten by "over" to `Σ C_i T_i` with `T_i = Π_{j<i} (1 − A_j)`
//! and alpha `1 − Π (1 − A_i)`. Taking
//!
//! ```text
//!     T_i = 1 − Σ_{j<i} c_j,   A_i = c_i / T_i,   C_i = s_i / T_i
//! ```
//!
//! gives `1 − A_i = T_{i+1} / T_i`, so the product telescopes to `1 − Σ c_i` (the flat alpha) and
//! `C_i T_i = s_i` (the flat beauty). `A_i ≤ 1` holds because the paths of bin `i` are not those in front of it
//! and each path's alpha is at most 1: `T_i ≥` (the share of paths in bins `i` and behind) `≥ c_i`. A bin whose
//! `T_i` rounding took to zero is guarded (alpha 1, colour divided by [`MIN_TRANSMITTANCE`]).
//!
//! **Tidy.** Before the conversion, an interval that a point sample lies inside is split at the point, the
//! additive colour and coverage shared by length, so that samples never overlap; the partition of the paths'
//! light stays a partition, so the flattened result is unchanged.
//!
//! **At most N samples.** While a pixel has more than `--deep-samples N` samples, the adjacent pair whose merge
//! changes the pixel's holdout curve least (`merge_cost`: the transmittance a holdout at each depth would see,
//! sampled through both samples, times the transmittance in front; the front-most pair on a tie) becomes one
//! sample from the front one's `Z` to the back one's `ZBack`, with alpha `1 − (1 − A_1)(1 − A_2)` and colour
//! `C_1 + (1 − A_1) C_2`: that is "over", so the flattened pixel stays the same (up to float rounding). Two
//! touching intervals of one density cost nothing, so a homogeneous medium merges first and holdouts inside it
//! stay exact; a surface point, an opaque sample or the background far behind merge last.
//!
//! **Bounded bins.** A pixel keeps at most [`max_bins`] surface and medium bins (twice `N`): beyond, its buckets
//! double in depth and the bins in one bucket are added up (exactly, and whatever the order of the samples).
//!
//! The emission of emitter-edge supersampling (scenes without media) goes to the bin of the sample's path.

use super::exact::{clamp_sample, ValueSum};
use crate::integrator::{CameraEvent, Origin, SampleRecord};
use crate::math::Rgb;

/// Depth buckets per doubling of depth (see the module docs).
pub const BUCKETS_PER_OCTAVE: f32 = 16.0;
/// The depth of the background sample of a ray that escaped: the largest finite `f32`, which compositors
/// order behind everything (an infinite depth would make `ZBack − Z` undefined).
pub const FAR: f32 = f32::MAX;
/// The smallest transmittance in front of a bin that the conversion divides by.
pub const MIN_TRANSMITTANCE: f64 = 1e-12;
/// The default most samples per pixel (`--deep-samples`).
pub const DEFAULT_MAX_SAMPLES: usize = 32;
/// The smallest depth a bucket is taken of (depths below map to this one's bucket).
const MIN_DEPTH: f32 = 1e-6;

/// The kind of a bin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum BinKind {
    /// Paths covered by an opaque surface: a point sample.
    Surface,
    /// Paths covered by a real collision in a medium: an interval.
    Medium,
    /// Paths that ended behind media without a collision: an interval over the media they crossed.
    Passed,
    /// The environment seen directly, or nothing in front of a holdout: a point sample.
    Background,
}

/// One bin of a pixel: exact sums of its paths' radiance and alpha, and where it lies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Bin {
    kind: BinKind,
    /// The depth bucket at the pixel's level (0 for the passed and background bins, of which a pixel has one
    /// each).
    bucket: i32,
    /// Paths in the bin (for the mean depth of a surface bin).
    count: u32,
    color: [ValueSum; 3],
    alpha: ValueSum,
    /// Sum of the depths of a surface bin's paths.
    depth: ValueSum,
    /// Nearest and farthest depth, as `f32` bits (non-negative floats order as their bits): of the media
    /// crossed for a medium bin, else of the bin's events.
    near: u32,
    far: u32,
    /// Nearest and farthest depth of a medium bin's collisions, as `f32` bits.
    first: u32,
    last: u32,
}

/// The deep bins of one pixel, sorted by kind and bucket.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeepPixel {
    bins: Vec<Bin>,
    /// How many times the depth buckets were doubled to keep the bins within [`max_bins`].
    level: u8,
}

/// One deep sample: its depth interval along the view axis and its alpha and premultiplied colour.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeepSample {
    /// Front depth.
    pub z: f32,
    /// Back depth (`== z` for a point sample).
    pub z_back: f32,
    /// Alpha.
    pub a: f32,
    /// Premultiplied colour.
    pub rgb: [f32; 3],
}

/// The most bins (surface and medium) a pixel keeps for images of at most `max_samples` deep samples a pixel:
/// twice that, and at least 4. Beyond it, the pixel's depth buckets are doubled (its level goes up by one) and
/// the bins that fall in one bucket are added up, until they fit. The sums stay exact and the result does not
/// depend on the order of the samples: the level is the least one at which all the pixel's paths fit.
pub fn max_bins(max_samples: usize) -> usize {
    (2 * max_samples).max(4)
}

/// The most times a pixel's buckets are doubled (then one bucket spans every depth).
const MAX_LEVEL: u8 = 24;

/// The bucket of depth `z` at `level`.
fn bucket(z: f32, level: u8) -> i32 {
    ((z.max(MIN_DEPTH).log2() * BUCKETS_PER_OCTAVE).floor() as i32) >> level
}

/// The depth where bucket `k` of `level` starts.
fn bucket_start(k: i32, level: u8) -> f32 {
    ((k as f64 * (1u64 << level) as f64) / BUCKETS_PER_OCTAVE as f64).exp2() as f32
}

impl Bin {
    /// Adds `other`'s paths (of the same kind and bucket) to this bin; false where a sum would overflow.
    #[must_use]
    fn absorb(&mut self, other: &Bin) -> bool {
        let mut fits = match self.count.checked_add(other.count) {
            Some(count) => {
                self.count = count;
                true
            }
            None => false,
        };
        for c in 0..3 {
            fits &= self.color[c].checked_add(other.color[c]);
        }
        fits &= self.alpha.checked_add(other.alpha);
        fits &= self.depth.checked_add(other.depth);
        self.near = self.near.min(other.near);
        self.far = self.far.max(other.far);
        self.first = self.first.min(other.first);
        self.last = self.last.max(other.last);
        fits
    }
}

/// Adds `v` to an exact sum, clamped as the film clamps sample values.
fn add(sum: &mut ValueSum, v: f32) {
    sum.add_value(clamp_sample(v).0);
}

impl DeepPixel {
    /// The bin of `kind` and `bucket`, created empty (over `[near, far]`) when new.
    fn bin(&mut self, kind: BinKind, bucket: i32, near: f32, far: f32) -> &mut Bin {
        let at = match self
            .bins
            .binary_search_by_key(&(kind, bucket), |b| (b.kind, b.bucket))
        {
            Ok(i) => i,
            Err(i) => {
                self.bins.insert(
                    i,
                    Bin {
                        kind,
                        bucket,
                        count: 0,
                        color: [ValueSum::default(); 3],
                        alpha: ValueSum::default(),
                        depth: ValueSum::default(),
                        near: near.to_bits(),
                        far: far.to_bits(),
                        first: f32::MAX.to_bits(),
                        last: 0,
                    },
                );
                i
            }
        };
        let b = &mut self.bins[at];
        b.near = b.near.min(near.to_bits());
        b.far = b.far.max(far.to_bits());
        b
    }

    internal! {
        /// Adds one camera path: its record (the event that decided its coverage, the span of media its camera ray
        /// crossed and its contributions), its finite `radiance` and `alpha` as the film took them, and `cos`, the
        /// cosine between its camera ray and the view axis (distances times `cos` are depths); keeps at most
        /// `max_bins` surface and medium bins ([`max_bins`]).
        pub fn add(
            &mut self,
            record: &SampleRecord,
            radiance: Rgb,
            alpha: f32,
            cos: f32,
            max_bins: usize,
        ) {
            self.add_path(record, radiance, alpha, cos);
            self.coarsen(max_bins);
        }
    }

    /// [`Self::add`] before the bins are kept within their number.
    fn add_path(&mut self, record: &SampleRecord, radiance: Rgb, alpha: f32, cos: f32) {
        let depth = |t: f32| (t * cos).clamp(0.0, FAR);
        let span = record.media_span.map(|(a, b)| (depth(a), depth(b)));
        let put = |bin: &mut Bin, color: Rgb, alpha: f32| {
            bin.count += 1;
            for c in 0..3 {
                add(&mut bin.color[c], color[c]);
            }
            add(&mut bin.alpha, alpha);
        };
        match record.camera_event {
            Some(CameraEvent::Surface(t)) => {
                let z = depth(t);
                let bin = self.bin(BinKind::Surface, bucket(z, self.level), z, z);
                add(&mut bin.depth, z);
                put(bin, radiance, alpha);
            }
            Some(CameraEvent::Collision(t)) => {
                let z = depth(t);
                let (near, far) = span.unwrap_or((0.0, FAR));
                let bin = self.bin(BinKind::Medium, bucket(z, self.level), near, far);
                bin.first = bin.first.min(z.to_bits());
                bin.last = bin.last.max(z.to_bits());
                put(bin, radiance, alpha);
            }
            ended => {
                let end = match ended {
                    Some(CameraEvent::Ended(t)) => depth(t),
                    _ => FAR,
                };
                // The environment seen directly is the background's; the rest is the media's in front.
                let environment = record
                    .contributions
                    .iter()
                    .filter(|c| c.in_beauty && c.origin == Origin::Environment)
                    .fold(Rgb::ZERO, |sum, c| sum + c.value);
                let rest = radiance - environment;
                match span.filter(|(a, _)| *a < end) {
                    Some((a, b)) => {
                        put(self.bin(BinKind::Passed, 0, a, b.min(end)), rest, alpha);
                        if environment != Rgb::ZERO {
                            put(self.bin(BinKind::Background, 0, end, end), environment, 0.0);
                        }
                    }
                    None => put(self.bin(BinKind::Background, 0, end, end), radiance, alpha),
                }
            }
        }
    }

    /// Doubles the depth buckets until at most `max_bins` surface and medium bins remain (see [`max_bins`]).
    fn coarsen(&mut self, max_bins: usize) {
        let binned = |p: &Self| {
            p.bins
                .iter()
                .filter(|b| matches!(b.kind, BinKind::Surface | BinKind::Medium))
                .count()
        };
        while binned(self) > max_bins && self.level < MAX_LEVEL {
            self.raise_to(self.level + 1);
        }
    }

    /// Takes the bins to the coarser `level`, adding up those that fall in one bucket.
    fn raise_to(&mut self, level: u8) {
        let shift = level.saturating_sub(self.level);
        if shift == 0 {
            return;
        }
        self.level = level;
        let mut bins: Vec<Bin> = Vec::with_capacity(self.bins.len());
        for mut b in self.bins.drain(..) {
            if matches!(b.kind, BinKind::Surface | BinKind::Medium) {
                b.bucket >>= shift;
            }
            match bins.last_mut() {
                // Shifting keeps the order, so bins of one new bucket are neighbours; no samples can overflow
                // the sums of one pixel.
                Some(last) if (last.kind, last.bucket) == (b.kind, b.bucket) => {
                    let _ = last.absorb(&b);
                }
                _ => bins.push(b),
            }
        }
        self.bins = bins;
    }

    /// Adds the bins of `other`, another set of samples of the same pixel (exact, in any order: the result is
    /// the bins of all the samples), keeping at most `max_bins`. Returns false (with the pixel's bins partly
    /// merged) where a count or sum would overflow, which no samples can make.
    #[must_use]
    pub fn checked_merge(&mut self, other: &DeepPixel, max_bins: usize) -> bool {
        self.raise_to(other.level);
        let mut other = other.clone();
        other.raise_to(self.level);
        let mut fits = true;
        for o in &other.bins {
            let (near, far) = (f32::from_bits(o.near), f32::from_bits(o.far));
            fits &= self.bin(o.kind, o.bucket, near, far).absorb(o);
        }
        self.coarsen(max_bins);
        fits
    }

    /// The pixel's deep samples, for `n` samples taken in it: tidy (sorted front to back, none overlapping),
    /// at most `max_samples` (at least 1) of them, flattening to the pixel's beauty and alpha (see the module
    /// docs).
    pub fn samples(&self, n: u32, max_samples: usize) -> Vec<DeepSample> {
        if n == 0 {
            return Vec::new();
        }
        let n = n as f64;
        let mut entries = self.additive_entries(n);
        split_at_points(&mut entries);
        entries.sort_by(|a, b| a.near.total_cmp(&b.near).then(a.far.total_cmp(&b.far)));
        let mut samples = to_over(&entries);
        merge_down(&mut samples, max_samples.max(1));
        samples
            .into_iter()
            .map(|s| DeepSample {
                z: s.near as f32,
                z_back: s.far as f32,
                a: s.alpha as f32,
                rgb: s.color.map(|c| c as f32),
            })
            .collect()
    }

    /// The bins as additive entries (colour and coverage divided by `n`), with the passed bin shared out over
    /// the depth buckets it covers (into the medium entries of the same buckets).
    fn additive_entries(&self, n: f64) -> Vec<Entry> {
        let mut points = Vec::new();
        // Medium entries by bucket: (bucket, entry), sorted by bucket.
        let mut intervals: Vec<(i32, Entry)> = Vec::new();
        let mut passed = None;
        for b in &self.bins {
            let mut e = Entry {
                near: f32::from_bits(b.near) as f64,
                far: f32::from_bits(b.far) as f64,
                color: b.color.map(|c| c.to_f64() / n),
                alpha: b.alpha.to_f64() / n,
            };
            match b.kind {
                BinKind::Surface => {
                    let z = b.depth.to_f64() / b.count.max(1) as f64;
                    (e.near, e.far) = (z, z);
                    points.push(e);
                }
                BinKind::Background => points.push(e),
                BinKind::Medium => {
                    // The bucket, clipped to the media crossed, and covering every collision.
                    let (first, last) = (
                        f32::from_bits(b.first) as f64,
                        f32::from_bits(b.last) as f64,
                    );
                    let start = bucket_start(b.bucket, self.level) as f64;
                    let end = bucket_start(b.bucket + 1, self.level) as f64;
                    e.near = start.max(e.near).min(first);
                    e.far = end.min(e.far).max(last);
                    intervals.push((b.bucket, e));
                }
                BinKind::Passed => passed = Some(e),
            }
        }
        if let Some(p) = passed {
            let length = p.far - p.near;
            if length <= 0.0 {
                points.push(p);
            } else {
                let mut k = bucket(p.near as f32, self.level);
                let mut start = p.near;
                while start < p.far {
                    let end = (bucket_start(k + 1, self.level) as f64)
                        .min(p.far)
                        .max(start);
                    let share = (end - start) / length;
                    let piece = Entry {
                        near: start,
                        far: end,
                        color: p.color.map(|c| c * share),
                        alpha: p.alpha * share,
                    };
                    match intervals.binary_search_by_key(&k, |(b, _)| *b) {
                        Ok(i) => intervals[i].1.absorb(&piece),
                        Err(i) => intervals.insert(i, (k, piece)),
                    }
                    if end >= p.far || k == i32::MAX {
                        break;
                    }
                    start = end;
                    k += 1;
                }
            }
        }
        points.extend(intervals.into_iter().map(|(_, e)| e));
        points.retain(|e| e.alpha != 0.0 || e.color.iter().any(|&c| c != 0.0));
        points
    }
}

/// An additive entry (colour and coverage as shares of the pixel) or, after [`to_over`], a deep sample in
/// `f64` (alpha and premultiplied colour).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    near: f64,
    far: f64,
    color: [f64; 3],
    alpha: f64,
}

impl Entry {
    /// Adds another additive entry's colour and coverage, and widens the depth range to cover it.
    fn absorb(&mut self, other: &Entry) {
        for c in 0..3 {
            self.color[c] += other.color[c];
        }
        self.alpha += other.alpha;
        self.near = self.near.min(other.near);
        self.far = self.far.max(other.far);
    }

    /// The part of this additive interval from `near` to `far`, its colour and coverage shared by length.
    fn part(&self, near: f64, far: f64) -> Entry {
        let share = (far - near) / (self.far - self.near);
        Entry {
            near,
            far,
            color: self.color.map(|c| c * share),
            alpha: self.alpha * share,
        }
    }
}

/// Splits every additive interval that a point entry lies strictly inside at that point.
fn split_at_points(entries: &mut Vec<Entry>) {
    let mut cuts: Vec<f64> = entries
        .iter()
        .filter(|e| e.near == e.far)
        .map(|e| e.near)
        .collect();
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let mut out = Vec::with_capacity(entries.len());
    for e in entries.drain(..) {
        let inside: Vec<f64> = cuts
            .iter()
            .copied()
            .filter(|&z| e.near < z && z < e.far)
            .collect();
        if inside.is_empty() {
            out.push(e);
            continue;
        }
        let mut start = e.near;
        for z in inside.into_iter().chain(std::iter::once(e.far)) {
            out.push(e.part(start, z));
            start = z;
        }
    }
    *entries = out;
}

/// The additive entries, sorted front to back, as deep samples that composite by "over" to their sum (see the
/// module docs).
fn to_over(entries: &[Entry]) -> Vec<Entry> {
    let mut transmittance = 1.0f64;
    entries
        .iter()
        .map(|e| {
            let t = transmittance.max(MIN_TRANSMITTANCE);
            transmittance -= e.alpha;
            Entry {
                alpha: (e.alpha / t).clamp(0.0, 1.0),
                color: e.color.map(|c| c / t),
                ..*e
            }
        })
        .collect()
}

/// Two adjacent deep samples as one, by "over": from the front one's depth to the back one's.
fn over(front: &Entry, back: &Entry) -> Entry {
    Entry {
        near: front.near,
        far: back.far.max(front.far),
        color: std::array::from_fn(|c| front.color[c] + (1.0 - front.alpha) * back.color[c]),
        alpha: merged_alpha(front, back),
    }
}

/// The alpha of two samples merged by "over".
fn merged_alpha(front: &Entry, back: &Entry) -> f64 {
    1.0 - (1.0 - front.alpha) * (1.0 - back.alpha)
}

/// How much merging the adjacent samples `front` and `back`, behind `transmittance`, changes the pixel's
/// holdout curve: the transmittance that a holdout at each depth would see, with an interval's alpha spread
/// uniformly over it (OpenEXR's rule) and a point's taken at its depth. The largest change, at nine depths
/// through each of the two samples, times `transmittance`. Two touching intervals of one density cost
/// nothing; a point spread into an interval, an opaque sample spread over a transparent one, or a sample
/// stretched over a gap (to the background at [`FAR`]) cost up to their alpha.
fn merge_cost(front: &Entry, back: &Entry, transmittance: f64) -> f64 {
    let merged = over(front, back);
    // The transmittance through `s` to depth `z`, relative to what is in front of it.
    let through = |s: &Entry, z: f64| {
        if s.near == s.far {
            if z >= s.near {
                1.0 - s.alpha
            } else {
                1.0
            }
        } else {
            (1.0 - s.alpha).powf(((z - s.near) / (s.far - s.near)).clamp(0.0, 1.0))
        }
    };
    let mut change = 0.0f64;
    for s in [front, back] {
        for k in 0..=8 {
            let z = s.near + (s.far - s.near) * k as f64 / 8.0;
            let original = through(front, z) * through(back, z);
            change = change.max((original - through(&merged, z)).abs());
        }
    }
    transmittance * change
}

/// A candidate merge in [`merge_down`]'s heap: the [`merge_cost`] of the pair that starts at sample `front`,
/// valid while both samples keep the versions it saw. Ordered so that the heap's top is the least cost, the
/// front-most pair on a tie.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Candidate {
    cost: f64,
    front: usize,
    versions: (u32, u32),
}

impl Eq for Candidate {}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other
            .cost
            .total_cmp(&self.cost)
            .then(other.front.cmp(&self.front))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Merges adjacent deep samples by "over" until at most `max` remain, least [`merge_cost`] first, the
/// front-most pair on a tie (see the module docs): a heap of candidate pairs over a linked list, O(n log n).
/// The transmittance in front of a sample does not change as samples merge ("over" keeps the product).
fn merge_down(samples: &mut Vec<Entry>, max: usize) {
    let n = samples.len();
    if n <= max {
        return;
    }
    let in_front: Vec<f64> = samples
        .iter()
        .scan(1.0, |t, s| {
            let before = *t;
            *t *= 1.0 - s.alpha;
            Some(before)
        })
        .collect();
    let mut next: Vec<usize> = (1..=n).collect();
    let mut prev: Vec<Option<usize>> = (0..n).map(|i| i.checked_sub(1)).collect();
    let mut alive = vec![true; n];
    let mut version = vec![0u32; n];
    let mut heap = std::collections::BinaryHeap::new();
    let candidate = |samples: &[Entry], version: &[u32], front: usize, back: usize| Candidate {
        cost: merge_cost(&samples[front], &samples[back], in_front[front]),
        front,
        versions: (version[front], version[back]),
    };
    for i in 0..n - 1 {
        heap.push(candidate(samples, &version, i, i + 1));
    }
    let mut count = n;
    while count > max {
        let Some(c) = heap.pop() else { break };
        let (i, j) = (c.front, next[c.front]);
        if !alive[i] || j >= n || c.versions != (version[i], version[j]) {
            continue;
        }
        samples[i] = over(&samples[i], &samples[j]);
        alive[j] = false;
        version[i] += 1;
        next[i] = next[j];
        if next[i] < n {
            prev[next[i]] = Some(i);
            heap.push(candidate(samples, &version, i, next[i]));
        }
        if let Some(p) = prev[i] {
            heap.push(candidate(samples, &version, p, i));
        }
        count -= 1;
    }
    let mut kept = alive.iter();
    samples.retain(|_| *kept.next().unwrap_or(&false));
}

/// Flattens one pixel's deep samples (sorted front to back) by "over": its colour and alpha.
pub fn flatten(samples: &[DeepSample]) -> (Rgb, f32) {
    let mut color = [0.0f64; 3];
    let mut transmittance = 1.0f64;
    for s in samples {
        for (c, &v) in color.iter_mut().zip(&s.rgb) {
            *c += transmittance * v as f64;
        }
        transmittance *= 1.0 - s.a as f64;
    }
    (
        Rgb::new(color[0] as f32, color[1] as f32, color[2] as f32),
        (1.0 - transmittance) as f32,
    )
}

/// A deep image: every pixel's deep samples, row-major from the top row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeepImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// The most samples a pixel may hold (`--deep-samples`).
    pub max_samples: usize,
    /// Where each pixel's samples start in [`samples`](Self::samples), and one past the last pixel's end.
    pub offsets: Vec<usize>,
    /// The samples of every pixel, one pixel after the other.
    pub samples: Vec<DeepSample>,
}

impl DeepImage {
    /// The samples of pixel `i` (row-major).
    pub fn pixel(&self, i: usize) -> &[DeepSample] {
        &self.samples[self.offsets[i]..self.offsets[i + 1]]
    }

    /// The most samples any pixel holds.
    pub fn most_samples(&self) -> usize {
        self.offsets
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::Origin;

    fn record(event: CameraEvent, span: Option<(f32, f32)>) -> SampleRecord {
        SampleRecord {
            deep: true,
            camera_event: Some(event),
            media_span: span,
            ..SampleRecord::default()
        }
    }

    /// Sums of radiance and alpha the way the film takes the beauty's mean.
    fn flat(paths: &[(SampleRecord, Rgb, f32)]) -> (Rgb, f32) {
        let n = paths.len() as f32;
        let (c, a) = paths
            .iter()
            .fold((Rgb::ZERO, 0.0), |(c, a), p| (c + p.1, a + p.2));
        (c / n, a / n)
    }

    fn check_tidy(samples: &[DeepSample]) {
        for s in samples {
            assert!(s.z <= s.z_back && (0.0..=1.0).contains(&s.a), "{s:?}");
        }
        for w in samples.windows(2) {
            assert!(w[0].z_back <= w[1].z, "overlap or unsorted: {w:?}");
        }
    }

    /// A pixel of many paths: a medium slab from 2 to 6 in front of a surface at 5, the environment around.
    fn mixed_paths() -> Vec<(SampleRecord, Rgb, f32)> {
        let mut paths = Vec::new();
        let mut env = record(CameraEvent::Ended(f32::INFINITY), Some((2.0, 6.0)));
        env.push(Rgb::new(0.2, 0.3, 0.4), Origin::Environment, None, true);
        for k in 0..200 {
            let t = 2.0 + 4.0 * (k as f32 + 0.5) / 200.0;
            let c = Rgb::new(0.01 * (k % 7) as f32, 0.5, 1.0 / (1.0 + k as f32));
            paths.push(match k % 5 {
                0 | 1 => (record(CameraEvent::Collision(t), Some((2.0, 6.0))), c, 1.0),
                2 => (record(CameraEvent::Surface(5.0), Some((2.0, 5.0))), c, 1.0),
                3 => (env.clone(), Rgb::new(0.2, 0.3, 0.4) + c * 0.1, 0.25),
                _ => (record(CameraEvent::Ended(f32::INFINITY), None), c, 0.0),
            });
        }
        paths
    }

    #[test]
    fn samples_are_tidy_and_flatten_to_the_flat_pixel() {
        let paths = mixed_paths();
        let mut pixel = DeepPixel::default();
        for (r, c, a) in &paths {
            pixel.add(r, *c, *a, 1.0, 1000);
        }
        let (want, want_alpha) = flat(&paths);
        for max in [1, 2, 5, 32, 1000] {
            let samples = pixel.samples(paths.len() as u32, max);
            assert!(samples.len() <= max && !samples.is_empty());
            check_tidy(&samples);
            let (got, alpha) = flatten(&samples);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c]).abs() <= 1e-5 * want[c].abs(),
                    "{max}: {got} {want}"
                );
            }
            assert!(
                (alpha - want_alpha).abs() <= 1e-6,
                "{max}: {alpha} {want_alpha}"
            );
        }
        let all = pixel.samples(paths.len() as u32, 1000);
        assert!(all.len() > 20, "{}", all.len());
        assert!(
            all.iter().any(|s| s.z == 5.0 && s.z_back == 5.0),
            "the surface point"
        );
        assert!(all.last().unwrap().z == FAR, "the background is last");
    }

    #[test]
    fn a_homogeneous_slab_keeps_its_exponential_profile() {
        // Collisions at the quantiles of an exponential with sigma_t = 0.5 over a slab [1, 9], the rest seeing
        // the environment behind: held out at depths 3, 5 and 7, the alpha in front must be 1 - exp(-0.5 (d - 1))
        // however few samples the pixel is merged down to (the background is never stretched over the slab),
        // and with bins coarsened (a cap of 4).
        let (sigma, n) = (0.5f64, 20000);
        let (mut pixel, mut coarse) = (DeepPixel::default(), DeepPixel::default());
        for k in 0..n {
            let u = (k as f64 + 0.5) / n as f64;
            let t = 1.0 - (1.0 - u).ln() / sigma;
            let mut r = if t < 9.0 {
                record(CameraEvent::Collision(t as f32), Some((1.0, 9.0)))
            } else {
                record(CameraEvent::Ended(f32::INFINITY), Some((1.0, 9.0)))
            };
            r.push(Rgb::splat(0.5), Origin::Environment, None, true);
            let radiance = if t < 9.0 {
                Rgb::splat(0.1)
            } else {
                Rgb::splat(0.5)
            };
            pixel.add(&r, radiance, (t < 9.0) as u32 as f32, 1.0, 1000);
            coarse.add(&r, radiance, (t < 9.0) as u32 as f32, 1.0, 4);
        }
        for (pixel, max) in [
            (&pixel, 2),
            (&pixel, 4),
            (&pixel, 32),
            (&coarse, 2),
            (&coarse, 32),
        ] {
            let samples = pixel.samples(n, max);
            check_tidy(&samples);
            for depth in [3.0, 5.0, 7.0] {
                let mut transmittance = 1.0f64;
                for s in &samples {
                    let length = (s.z_back as f64 - s.z as f64).max(1e-9);
                    let f = ((depth - s.z as f64) / length).clamp(0.0, 1.0);
                    transmittance *= (1.0 - s.a as f64).powf(f);
                }
                let want = 1.0 - (-sigma * (depth - 1.0)).exp();
                assert!(
                    ((1.0 - transmittance) - want).abs() < 2e-3,
                    "{max} samples, level {}, depth {depth}: {} {want}",
                    pixel.level,
                    1.0 - transmittance
                );
            }
        }
        assert!(coarse.level > 0);
    }

    #[test]
    fn bins_merge_exactly_in_any_grouping() {
        let paths = mixed_paths();
        let mut whole = DeepPixel::default();
        let (mut a, mut b) = (DeepPixel::default(), DeepPixel::default());
        for (k, (r, c, al)) in paths.iter().enumerate() {
            whole.add(r, *c, *al, 0.9, 1000);
            if k % 3 == 0 { &mut a } else { &mut b }.add(r, *c, *al, 0.9, 1000);
        }
        assert!(b.checked_merge(&a, 1000));
        assert_eq!(b.samples(200, 8), whole.samples(200, 8));
    }

    #[test]
    fn the_heap_merges_as_the_plain_rule_does() {
        // The rule spelt out: merge the least-cost adjacent pair (front-most on a tie) until `max` remain.
        fn plain(mut s: Vec<Entry>, max: usize) -> Vec<Entry> {
            // The transmittance in front of each sample, as the samples first were.
            let mut in_front: Vec<f64> = (0..s.len())
                .map(|i| s[..i].iter().fold(1.0, |t, e| t * (1.0 - e.alpha)))
                .collect();
            while s.len() > max {
                let cost = |i: usize| merge_cost(&s[i], &s[i + 1], in_front[i]);
                let best = (0..s.len() - 1)
                    .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
                    .unwrap();
                s[best] = over(&s[best], &s[best + 1]);
                s.remove(best + 1);
                in_front.remove(best + 1);
            }
            s
        }
        let mut state = 12345u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f64 / (1u64 << 24) as f64
        };
        for n in [1, 2, 7, 40, 200] {
            let entries: Vec<Entry> = (0..n)
                .map(|k| Entry {
                    near: k as f64,
                    far: k as f64 + 0.5,
                    color: [random(), random(), random()],
                    // Some ties: alphas on a coarse grid.
                    alpha: (random() * 8.0).floor() / 8.0,
                })
                .collect();
            for max in [1, 3, 32] {
                let mut heap = entries.clone();
                merge_down(&mut heap, max);
                assert_eq!(
                    heap,
                    plain(entries.clone(), max),
                    "{n} samples down to {max}"
                );
            }
        }
    }

    #[test]
    fn depth_is_along_the_view_axis() {
        let mut pixel = DeepPixel::default();
        pixel.add(
            &record(CameraEvent::Surface(10.0), None),
            Rgb::ONE,
            1.0,
            0.5,
            4,
        );
        assert_eq!(pixel.samples(1, 4)[0].z, 5.0);
    }

    #[test]
    fn bins_beyond_the_cap_coarsen_exactly_and_in_any_order() {
        let paths = mixed_paths();
        let (want, want_alpha) = flat(&paths);
        let bins = |p: &DeepPixel| {
            p.bins
                .iter()
                .filter(|b| matches!(b.kind, BinKind::Surface | BinKind::Medium))
                .count()
        };
        let mut forward = DeepPixel::default();
        let mut backward = DeepPixel::default();
        let (mut front, mut back) = (DeepPixel::default(), DeepPixel::default());
        for (k, (r, c, a)) in paths.iter().enumerate() {
            forward.add(r, *c, *a, 1.0, 4);
            if k < 50 { &mut front } else { &mut back }.add(r, *c, *a, 1.0, 4);
        }
        for (r, c, a) in paths.iter().rev() {
            backward.add(r, *c, *a, 1.0, 4);
        }
        assert!(
            forward.level > 0 && bins(&forward) <= 4,
            "{}",
            forward.level
        );
        assert_eq!(
            forward, backward,
            "the order of the samples does not matter"
        );
        assert!(back.checked_merge(&front, 4));
        assert_eq!(back, forward, "nor a split into parts");
        let samples = forward.samples(paths.len() as u32, 32);
        check_tidy(&samples);
        let (got, alpha) = flatten(&samples);
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() <= 1e-5 * want[c].abs(),
                "{got} {want}"
            );
        }
        assert!((alpha - want_alpha).abs() <= 1e-6);
    }
}
