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
//! of its depth deep. Every bin sums its paths' radiance and alpha exactly ([`ValueSum`], like the film's
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
//! **At most N samples.** While a pixel has more than `--deep-samples N` samples, the adjacent pair whose merged
//! alpha `1 − (1 − A_1)(1 − A_2)` is least (the least visible; the front-most pair on a tie) becomes one sample
//! from the front one's `Z` to the back one's `ZBack`, with that alpha and colour `C_1 + (1 − A_1) C_2`: that is
//! "over", so the flattened pixel stays the same (up to float rounding). Two adjacent intervals of one
//! homogeneous medium merge into an interval of the same density, so holdouts inside it stay exact.
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
    /// The depth bucket (0 for the passed and background bins, of which a pixel has one each).
    bucket: i32,
    /// Paths in the bin (for the mean depth of a surface bin).
    count: u32,
    color: [ValueSum; 3],
    alpha: ValueSum,
    /// Sum of the depths of a surface bin's paths.
    depth: ValueSum,
    /// Nearest and farthest depth, as `f32` bits (non-negative floats order as their bits).
    near: u32,
    far: u32,
}

/// The deep bins of one pixel, sorted by kind and bucket.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeepPixel {
    bins: Vec<Bin>,
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

/// The bucket of depth `z` and its bounds.
fn bucket(z: f32) -> (i32, f32, f32) {
    let k = (z.max(MIN_DEPTH).log2() * BUCKETS_PER_OCTAVE).floor() as i32;
    (k, bucket_start(k), bucket_start(k + 1))
}

/// The depth where bucket `k` starts.
fn bucket_start(k: i32) -> f32 {
    (k as f32 / BUCKETS_PER_OCTAVE).exp2()
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

    /// Adds one camera path: its record (the event that decided its coverage, the span of media its camera ray
    /// crossed and its contributions), its finite `radiance` and `alpha` as the film took them, and `cos`, the
    /// cosine between its camera ray and the view axis (distances times `cos` are depths).
    pub fn add(&mut self, record: &SampleRecord, radiance: Rgb, alpha: f32, cos: f32) {
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
                let bin = self.bin(BinKind::Surface, bucket(z).0, z, z);
                add(&mut bin.depth, z);
                put(bin, radiance, alpha);
            }
            Some(CameraEvent::Collision(t)) => {
                let z = depth(t);
                let (k, mut near, mut far) = bucket(z);
                if let Some((a, b)) = span {
                    near = near.max(a).min(z);
                    far = far.min(b).max(z);
                }
                put(self.bin(BinKind::Medium, k, near, far), radiance, alpha);
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

    /// Adds the bins of `other`, another set of samples of the same pixel (exact, in any order). Returns false
    /// (with the pixel's bins partly merged) where a count or sum would overflow, which no samples can make.
    #[must_use]
    pub fn checked_merge(&mut self, other: &DeepPixel) -> bool {
        let mut fits = true;
        for o in &other.bins {
            let (near, far) = (f32::from_bits(o.near), f32::from_bits(o.far));
            let b = self.bin(o.kind, o.bucket, near, far);
            match b.count.checked_add(o.count) {
                Some(count) => b.count = count,
                None => fits = false,
            }
            for c in 0..3 {
                fits &= b.color[c].checked_add(o.color[c]);
            }
            fits &= b.alpha.checked_add(o.alpha);
            fits &= b.depth.checked_add(o.depth);
        }
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
                BinKind::Medium => intervals.push((b.bucket, e)),
                BinKind::Passed => passed = Some(e),
            }
        }
        if let Some(p) = passed {
            let length = p.far - p.near;
            if length <= 0.0 {
                points.push(p);
            } else {
                let (mut k, ..) = bucket(p.near as f32);
                let mut start = p.near;
                while start < p.far {
                    let end = (bucket_start(k + 1) as f64).min(p.far).max(start);
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

/// A candidate merge in [`merge_down`]'s heap: the merged alpha of the pair that starts at sample `front`,
/// valid while both samples keep the versions it saw. Ordered so that the heap's top is the least alpha, the
/// front-most pair on a tie.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Candidate {
    alpha: f64,
    front: usize,
    versions: (u32, u32),
}

impl Eq for Candidate {}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other
            .alpha
            .total_cmp(&self.alpha)
            .then(other.front.cmp(&self.front))
    }
}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Merges adjacent deep samples by "over" until at most `max` remain, least merged alpha first, the front-most
/// pair on a tie (see the module docs): a heap of candidate pairs over a linked list, O(n log n).
fn merge_down(samples: &mut Vec<Entry>, max: usize) {
    let n = samples.len();
    if n <= max {
        return;
    }
    let mut next: Vec<usize> = (1..=n).collect();
    let mut prev: Vec<Option<usize>> = (0..n).map(|i| i.checked_sub(1)).collect();
    let mut alive = vec![true; n];
    let mut version = vec![0u32; n];
    let mut heap = std::collections::BinaryHeap::new();
    let candidate = |samples: &[Entry], version: &[u32], front: usize, back: usize| Candidate {
        alpha: merged_alpha(&samples[front], &samples[back]),
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
            pixel.add(r, *c, *a, 1.0);
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
        // Collisions at the quantiles of an exponential with sigma_t = 0.5 over a slab [1, 9]: the alpha in
        // front of depth 5 must be 1 - exp(-0.5 * 4) after merging down to 4 samples.
        let (sigma, n) = (0.5f64, 20000);
        let mut pixel = DeepPixel::default();
        for k in 0..n {
            let u = (k as f64 + 0.5) / n as f64;
            let t = 1.0 - (1.0 - u).ln() / sigma;
            let r = if t < 9.0 {
                record(CameraEvent::Collision(t as f32), Some((1.0, 9.0)))
            } else {
                record(CameraEvent::Ended(f32::INFINITY), Some((1.0, 9.0)))
            };
            pixel.add(&r, Rgb::ZERO, (t < 9.0) as u32 as f32, 1.0);
        }
        for max in [4, 32] {
            let samples = pixel.samples(n, max);
            check_tidy(&samples);
            let mut transmittance = 1.0f64;
            for s in &samples {
                let f =
                    ((5.0 - s.z as f64) / (s.z_back as f64 - s.z as f64).max(1e-9)).clamp(0.0, 1.0);
                transmittance *= (1.0 - s.a as f64).powf(f);
            }
            let want = 1.0 - (-sigma * 4.0).exp();
            assert!(
                ((1.0 - transmittance) - want).abs() < 2e-3,
                "{max}: {} {want}",
                1.0 - transmittance
            );
        }
    }

    #[test]
    fn bins_merge_exactly_in_any_grouping() {
        let paths = mixed_paths();
        let mut whole = DeepPixel::default();
        let (mut a, mut b) = (DeepPixel::default(), DeepPixel::default());
        for (k, (r, c, al)) in paths.iter().enumerate() {
            whole.add(r, *c, *al, 0.9);
            if k % 3 == 0 { &mut a } else { &mut b }.add(r, *c, *al, 0.9);
        }
        assert!(b.checked_merge(&a));
        assert_eq!(b.samples(200, 8), whole.samples(200, 8));
    }

    #[test]
    fn the_heap_merges_as_the_plain_rule_does() {
        // The rule spelt out: merge the least-alpha adjacent pair (front-most on a tie) until `max` remain.
        fn plain(mut s: Vec<Entry>, max: usize) -> Vec<Entry> {
            while s.len() > max {
                let best = (0..s.len() - 1)
                    .min_by(|&a, &b| {
                        merged_alpha(&s[a], &s[a + 1]).total_cmp(&merged_alpha(&s[b], &s[b + 1]))
                    })
                    .unwrap();
                s[best] = over(&s[best], &s[best + 1]);
                s.remove(best + 1);
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
        );
        assert_eq!(pixel.samples(1, 4)[0].z, 5.0);
    }
}
