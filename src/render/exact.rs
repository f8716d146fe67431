//! Exact, order-independent sums of sample values, so that any split of a render (threads, sample ranges,
//! tiles, machines) adds up to the same bits as one render.
//!
//! A float sum depends on the order of its terms: `(a + b) + c` and `a + (b + c)` can differ in the last bit,
//! so a merge of two partial float sums can never promise the bits of one running sum. An integer sum does
//! not depend on the order. Every sample value is therefore rounded once, on its own, to a fixed-point
//! integer, and the integers are summed exactly:
//!
//! - [`ValueSum`]: value × 2^56, rounded to the nearest integer (halves away from zero), summed in an `i128`.
//!   One unit is 2^-56 ≈ 1.4e-17: a value of 2^-32 ≈ 2.3e-10 or more keeps all 24 bits of its `f32`
//!   significand, and a smaller one keeps an absolute precision of 6.9e-18.
//! - [`SquareSum`]: value² (exact in `f64`, the product of two 24-bit significands) × 2^80, rounded the same
//!   way, summed in 192 bits. One unit is 2^-80 ≈ 8.3e-25.
//!
//! One sample's value is clamped to ±[`MAX_SAMPLE_VALUE`] = ±2^38 ≈ ±2.7e11 before rounding (the film counts
//! such samples). With at most `u32::MAX` samples in a pixel a value sum stays below 2^126 and a square
//! sum below 2^188, so neither can overflow. Sums read from files (farm parts) are not bounded by any samples,
//! so they are added with `checked_add`, which refuses a total that would not fit. Turning a sum back into `f64`
//! is one deterministic rounding.
//!
//! The price: 240 bytes of film per pixel instead of 112 for `f64` sums, and values below 2.3e-10 keep an
//! absolute rather than a relative precision. Plain `f64` running sums would give the same `f32` image for
//! almost every pixel, but not for all: a split moves the roundings of the sum, and where the sum lies near
//! the midpoint between two `f32` values the mean comes out one unit apart (see the film's tests).

/// Fractional bits of a [`ValueSum`]: one unit is 2^-56.
pub const VALUE_FRACTION_BITS: i32 = 56;
/// Fractional bits of a [`SquareSum`]: one unit is 2^-80.
pub const SQUARE_FRACTION_BITS: i32 = 80;
/// The largest magnitude of one sample value that the sums take as it is: 2^38 ≈ 2.7e11. See
/// `clamp_sample`.
pub const MAX_SAMPLE_VALUE: f32 = 274_877_906_944.0;

/// Brings one sample value into the range the sums take: NaN becomes 0 and a magnitude above
/// [`MAX_SAMPLE_VALUE`] (infinities included) becomes ±[`MAX_SAMPLE_VALUE`]. Returns the value and whether
/// it changed.
pub fn clamp_sample(v: f32) -> (f32, bool) {
    if v.is_nan() {
        (0.0, true)
    } else if v.abs() > MAX_SAMPLE_VALUE {
        (MAX_SAMPLE_VALUE.copysign(v), true)
    } else {
        (v, false)
    }
}

/// 2^63, below which an `f64` converts to `i64` in one instruction.
const TWO_POW_63: f64 = (1u64 << 63) as f64;

/// `x` rounded to the nearest integer, halves away from zero, for a finite `|x| < 2^127`.
fn round_to_i128(x: f64) -> i128 {
    if x.abs() < TWO_POW_63 {
        // |x| < 2^63: truncate (exact), then look at the fraction, which `x - t` gives exactly.
        let t = x as i64;
        let fraction = x - t as f64;
        let t = t as i128;
        if fraction >= 0.5 {
            t + 1
        } else if fraction <= -0.5 {
            t - 1
        } else {
            t
        }
    } else {
        // |x| ≥ 2^63 > 2^52: x is already an integer.
        x as i128
    }
}

/// An exact sum of sample values in fixed point (units of 2^-56); see the module docs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ValueSum(i128);

impl ValueSum {
    /// Number of 32-bit words in [`to_words`](Self::to_words).
    pub const WORDS: usize = 4;

    /// Adds one sample value, which must already be in range (see [`clamp_sample`]).
    pub fn add_value(&mut self, v: f32) {
        debug_assert!(
            v.is_finite() && v.abs() <= MAX_SAMPLE_VALUE,
            "unclamped {v}"
        );
        self.0 += round_to_i128(v as f64 * 2f64.powi(VALUE_FRACTION_BITS));
    }

    /// Adds another sum (the result does not depend on the order of additions), or returns false (leaving this one as it was) where the total would not fit: sums read
    /// from files are not bounded by the samples behind them.
    #[must_use]
    pub fn checked_add(&mut self, other: ValueSum) -> bool {
        match self.0.checked_add(other.0) {
            Some(total) => {
                self.0 = total;
                true
            }
            None => false,
        }
    }

    /// The sum as `f64` (one rounding of the exact value).
    pub fn to_f64(self) -> f64 {
        self.0 as f64 * 2f64.powi(-VALUE_FRACTION_BITS)
    }

    /// The two's-complement integer as little-endian 32-bit words.
    pub fn to_words(self) -> [u32; 4] {
        let u = self.0 as u128;
        std::array::from_fn(|i| (u >> (32 * i)) as u32)
    }

    /// The inverse of [`to_words`](Self::to_words).
    pub fn from_words(words: [u32; 4]) -> Self {
        Self(
            words
                .iter()
                .rev()
                .fold(0u128, |acc, &w| (acc << 32) | w as u128) as i128,
        )
    }
}

/// An exact sum of squared sample values in fixed point (units of 2^-80), 192 bits wide; see the module
/// docs. Squares are never negative, so the sum is unsigned.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SquareSum([u64; 3]);

impl SquareSum {
    /// Number of 32-bit words in [`to_words`](Self::to_words).
    pub const WORDS: usize = 6;

    /// Adds the square of one sample value, which must already be in range (see [`clamp_sample`]).
    pub fn add_square(&mut self, v: f32) {
        debug_assert!(
            v.is_finite() && v.abs() <= MAX_SAMPLE_VALUE,
            "unclamped {v}"
        );
        let v = v as f64;
        // Exact: v * v has a 48-bit significand, and scaling by a power of two is exact.
        let x = v * v * 2f64.powi(SQUARE_FRACTION_BITS);
        if x < TWO_POW_63 {
            self.add_parts(round_to_i128(x) as u128, 0);
            return;
        }
        // x ≥ 2^63 (< 2^157) is an integer: its 53-bit significand shifted left by 11 to 104 bits, split into
        // the low 128 bits and the bits above them.
        let bits = x.to_bits();
        let shift = ((bits >> 52) & 0x7ff) as u32 - 1075;
        let significand = (bits & ((1u64 << 52) - 1)) | (1u64 << 52);
        let high = if shift > 75 {
            significand >> (128 - shift)
        } else {
            0
        };
        self.add_parts((significand as u128) << shift, high);
    }

    /// Adds `low + high · 2^128`.
    fn add_parts(&mut self, low: u128, high: u64) {
        let sum = self.0[0] as u128 | (self.0[1] as u128) << 64;
        let (sum, carry) = sum.overflowing_add(low);
        self.0 = [
            sum as u64,
            (sum >> 64) as u64,
            self.0[2] + high + carry as u64,
        ];
    }

    /// Adds another sum (the result does not depend on the order of additions), or returns false (leaving this
    /// one as it was) where the total would not fit in 192 bits: sums read from files are not bounded by the samples behind them.
    #[must_use]
    pub fn checked_add(&mut self, other: SquareSum) -> bool {
        let low = |s: &SquareSum| s.0[0] as u128 | (s.0[1] as u128) << 64;
        let (sum, carry) = low(self).overflowing_add(low(&other));
        let Some(high) = self.0[2]
            .checked_add(other.0[2])
            .and_then(|h| h.checked_add(carry as u64))
        else {
            return false;
        };
        self.0 = [sum as u64, (sum >> 64) as u64, high];
        true
    }

    /// The sum as `f64` (deterministic; within one unit in the last place of the exact value).
    pub fn to_f64(self) -> f64 {
        let [lo, mid, hi] = self.0;
        (hi as f64 * 2f64.powi(128) + mid as f64 * 2f64.powi(64) + lo as f64)
            * 2f64.powi(-SQUARE_FRACTION_BITS)
    }

    /// The integer as little-endian 32-bit words.
    pub fn to_words(self) -> [u32; 6] {
        std::array::from_fn(|i| (self.0[i / 2] >> (32 * (i % 2))) as u32)
    }

    /// The inverse of [`to_words`](Self::to_words).
    pub fn from_words(words: [u32; 6]) -> Self {
        Self(std::array::from_fn(|limb| {
            words[2 * limb] as u64 | (words[2 * limb + 1] as u64) << 32
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;

    /// Sample-like values over a wide range of magnitudes, signs and special cases.
    fn values(n: usize) -> Vec<f32> {
        let mut rng = Rng::for_sample(7, 0, 0);
        let mut v: Vec<f32> = (0..n)
            .map(|_| {
                let u = rng.next_f32();
                let e = (rng.next_f32() * 80.0) as i32 - 50;
                (u - 0.3) * 2f32.powi(e)
            })
            .collect();
        v.extend([
            0.0,
            -0.0,
            1.0,
            0.5,
            -0.5,
            f32::MIN_POSITIVE,
            1e-45,
            MAX_SAMPLE_VALUE,
        ]);
        v.extend([
            -MAX_SAMPLE_VALUE,
            2.0e11,
            1.5 * 2f32.powi(-56),
            2.5 * 2f32.powi(-56),
        ]);
        v
    }

    #[test]
    fn sums_do_not_depend_on_order_or_grouping() {
        let v = values(2000);
        let sequential = |v: &[f32]| {
            let (mut s, mut q) = (ValueSum::default(), SquareSum::default());
            for &x in v {
                s.add_value(x);
                q.add_square(x);
            }
            (s, q)
        };
        let (s, q) = sequential(&v);
        let mut reversed = v.clone();
        reversed.reverse();
        assert_eq!(sequential(&reversed), (s, q));
        // Uneven groups summed separately, then the group sums added in reverse order.
        let mut groups: Vec<(ValueSum, SquareSum)> = v.chunks(37).map(sequential).collect();
        groups.reverse();
        let (mut gs, mut gq) = (ValueSum::default(), SquareSum::default());
        for (a, b) in groups {
            assert!(gs.checked_add(a) && gq.checked_add(b));
        }
        assert_eq!((gs, gq), (s, q));
        // While float sums in different orders disagree on these values.
        let f = |v: &[f32]| v.iter().fold(0.0f64, |a, &x| a + x as f64);
        assert_ne!(f(&v).to_bits(), f(&reversed).to_bits());
    }

    #[test]
    fn sums_are_close_to_the_float_sums() {
        let v: Vec<f32> = values(500).into_iter().filter(|x| x.abs() < 1e6).collect();
        let (mut s, mut q) = (ValueSum::default(), SquareSum::default());
        for &x in &v {
            s.add_value(x);
            q.add_square(x);
        }
        let exact_sum: f64 = v.iter().map(|&x| x as f64).sum();
        let exact_sq: f64 = v.iter().map(|&x| x as f64 * x as f64).sum();
        let scale: f64 = v.iter().map(|&x| (x as f64).abs()).sum();
        assert!((s.to_f64() - exact_sum).abs() <= 1e-12 * scale + 1e-13);
        assert!((q.to_f64() - exact_sq).abs() <= 1e-12 * exact_sq);
    }

    #[test]
    fn rounding_is_to_nearest_with_halves_away_from_zero() {
        let unit = 2f32.powi(-VALUE_FRACTION_BITS);
        let raw = |v: f32| {
            let mut s = ValueSum::default();
            s.add_value(v);
            s.0
        };
        assert_eq!(raw(0.5 * unit), 1);
        assert_eq!(raw(-0.5 * unit), -1);
        assert_eq!(raw(0.25 * unit), 0);
        assert_eq!(raw(1.5 * unit), 2);
        assert_eq!(raw(2.5 * unit), 3);
        assert_eq!(raw(1.0), 1 << 56);
        assert_eq!(raw(-3.0), -3 << 56);
        assert_eq!(raw(MAX_SAMPLE_VALUE), 1 << 94);
        let mut q = SquareSum::default();
        q.add_square(MAX_SAMPLE_VALUE);
        assert_eq!(q.0, [0, 0, 1 << (156 - 128)]);
        let mut q = SquareSum::default();
        q.add_square(3.0);
        assert_eq!(q.0, [0, 9 << 16, 0]);
    }

    #[test]
    fn the_largest_sums_do_not_overflow() {
        let mut s = ValueSum::default();
        let mut q = SquareSum::default();
        let (mut one_s, mut one_q) = (ValueSum::default(), SquareSum::default());
        one_s.add_value(MAX_SAMPLE_VALUE);
        one_q.add_square(MAX_SAMPLE_VALUE);
        // Doubling 32 times: the sums of 2^32 samples of the largest value.
        assert!(s.checked_add(one_s) && q.checked_add(one_q));
        for _ in 0..32 {
            assert!(s.checked_add(s) && q.checked_add(q));
        }
        assert_eq!(s.0, 1 << 126);
        assert_eq!(q.0, [0, 0, 1 << 60]);
        // Sums no samples could give, as a forged file holds, are refused rather than wrapped, and left as
        // they were.
        let before = s;
        assert!(!s.checked_add(s), "2^127 does not fit an i128");
        assert_eq!(s, before);
        for _ in 0..3 {
            assert!(q.checked_add(q), "up to 2^191");
        }
        let before = q;
        assert!(!q.checked_add(q), "2^192 does not fit");
        assert_eq!(q, before);
        assert_eq!(s.to_f64(), 2f64.powi(38 + 32));
        assert_eq!(q.to_f64(), 2f64.powi(76 + 32 + 3));
    }

    #[test]
    fn words_round_trip() {
        for v in values(200) {
            let (mut s, mut q) = (ValueSum::default(), SquareSum::default());
            s.add_value(v);
            s.add_value(v * 0.75);
            q.add_square(v);
            assert_eq!(ValueSum::from_words(s.to_words()), s);
            assert_eq!(SquareSum::from_words(q.to_words()), q);
        }
        assert_eq!(ValueSum(-1).to_words(), [u32::MAX; 4]);
        assert_eq!(SquareSum([1, 2, 3]).to_words(), [1, 0, 2, 0, 3, 0]);
    }

    #[test]
    fn clamping_catches_nan_infinity_and_huge_values() {
        assert_eq!(clamp_sample(1.5), (1.5, false));
        assert_eq!(clamp_sample(-MAX_SAMPLE_VALUE), (-MAX_SAMPLE_VALUE, false));
        assert_eq!(clamp_sample(f32::NAN), (0.0, true));
        assert_eq!(clamp_sample(f32::INFINITY), (MAX_SAMPLE_VALUE, true));
        assert_eq!(clamp_sample(-1e20), (-MAX_SAMPLE_VALUE, true));
    }
}
