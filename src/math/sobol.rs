//! Low-discrepancy sample values: the first two dimensions of the Sobol sequence, Owen-scrambled and shuffled
//! per pixel and per dimension pair, and padded across pairs (Burley 2020, "Practical Hash-based Owen
//! Scrambling", JCGT 9(4): the Laine–Karras hash as a nested uniform scramble, §3–4, and shuffling by
//! scrambling the sample index, §5). pbrt-v4's padded Sobol sampler follows the same plan.
//!
//! Sample `i` of a pixel gets, for its `d`-th pair of dimensions, the 2-D Sobol point of index
//! `scramble(i, seed_d)`, each coordinate scrambled with its own seed; the seeds hash the render seed, the pixel
//! and `d`. So:
//! - within a pixel, the first 2^k samples of every pair form a (0, k, 2)-net, since a Sobol point's leading k
//!   bits depend only on its index's low k bits, which the index scramble permutes;
//! - different pairs of one sample are independent (independent scrambles), which keeps every estimate
//!   unbiased;
//! - every value is a pure function of (seed, pixel, sample, pair): the same for any thread count and any split
//!   of the samples into farm parts.

use glam::Vec2;

/// Direction numbers of the Sobol sequence's second dimension (primitive polynomial x + 1, m_k = 1):
/// v_1 = 2^31 and v_{k+1} = v_k ⊕ (v_k >> 1).
const SECOND_DIMENSION: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// Per byte of a *bit-reversed* index, both halves of what one set of four lookups gives: entry `[b][v]` has in
/// its low word the XOR of reverse(v_k) (the second dimension's bit-reversed direction numbers) over the bits
/// set in `v`, where bit j of byte b of the reversed index is bit k = 31 − (8b + j) of the index; and in its
/// high word those bits of the index itself, reverse(v << 8b). The index and its second dimension come out of
/// the same four lookups, in place of a loop over 32 bits and a bit reversal (measured: 0.7 % of the render
/// instructions of the peer benchmark's mirrors scene).
const INDEX_AND_SECOND_DIMENSION_BY_BYTE: [[u64; 256]; 4] = {
    let mut table = [[0u64; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut v = 1;
        while v < 256 {
            let mut acc = 0u32;
            let mut j = 0;
            while j < 8 {
                if v & (1 << j) != 0 {
                    acc ^= SECOND_DIMENSION[31 - (8 * b + j)].reverse_bits();
                }
                j += 1;
            }
            let index_bits = ((v as u32) << (8 * b)).reverse_bits();
            table[b][v] = ((index_bits as u64) << 32) | acc as u64;
            v += 1;
        }
        b += 1;
    }
    table
};

/// The Laine–Karras permutation (Burley 2020, listing 3): bijective on 32-bit words, where each output bit
/// depends only on the same and lower input bits, so that on bit-reversed values it is a nested uniform
/// (Owen) scramble.
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Owen scrambling of a 32-bit fixed-point value in base 2 (Burley 2020, listing 4).
#[cfg(test)]
pub fn owen_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

/// The index whose bit reversal is `reversed_index`, and the second dimension of its Sobol point, itself
/// bit-reversed.
fn index_and_second_dimension_reversed(reversed_index: u32) -> (u32, u32) {
    let t = &INDEX_AND_SECOND_DIMENSION_BY_BYTE;
    let r = reversed_index as usize;
    let both = t[0][r & 0xff] ^ t[1][(r >> 8) & 0xff] ^ t[2][(r >> 16) & 0xff] ^ t[3][r >> 24];
    ((both >> 32) as u32, both as u32)
}

/// The unscrambled 2-D Sobol point of `index`, as 32-bit fixed-point fractions (the reference the fast path
/// of [`SobolStream::next_2d`] is tested against).
#[cfg(test)]
fn sobol_2d(index: u32) -> (u32, u32) {
    let mut y = 0u32;
    let mut bits = index;
    let mut k = 0;
    while bits != 0 {
        if bits & 1 != 0 {
            y ^= SECOND_DIMENSION[k];
        }
        bits >>= 1;
        k += 1;
    }
    (index.reverse_bits(), y)
}

/// A 32-bit hash of a 64-bit key (the SplitMix64 finaliser, folded).
fn hash32(mut z: u64) -> u32 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z ^ (z >> 32)) as u32
}

fn to_unit(x: u32) -> f32 {
    // 24 high bits give every representable multiple of 2^-24 below 1.
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Dimension pairs a sample draws from the sequence; later pairs come from the sample's PCG stream, where
/// stratification no longer pays (deep bounces).
pub const SOBOL_PAIRS: u32 = 48;

/// The low-discrepancy values of one pixel sample: one 2-D point per dimension pair, in order.
#[derive(Clone, Debug)]
pub struct SobolStream {
    pixel_key: u64,
    /// The sample index, bit-reversed (the unscrambled first coordinate of its Sobol point).
    reversed_sample: u32,
    pair: u32,
}

impl SobolStream {
    /// The stream of sample `sample_index` of pixel `pixel_index` for the render seed `seed`.
    pub fn new(seed: u64, pixel_index: u64, sample_index: u64) -> Self {
        Self {
            pixel_key: hash32(seed ^ 0x5851_f42d_4c95_7f2d) as u64
                ^ (pixel_index << 32)
                ^ pixel_index,
            reversed_sample: (sample_index as u32).reverse_bits(),
            pair: 0,
        }
    }

    /// The key of the next dimension pair, or `None` after [`SOBOL_PAIRS`] pairs.
    fn next_pair_key(&mut self) -> Option<u64> {
        if self.pair >= SOBOL_PAIRS {
            return None;
        }
        let key = self
            .pixel_key
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .wrapping_add(self.pair as u64);
        self.pair += 1;
        Some(key)
    }

    /// The first coordinate of the next dimension pair's point (the pair is used up): a 1-D decision costs
    /// half a 2-D one.
    pub fn next_1d(&mut self) -> Option<f32> {
        let key = self.next_pair_key()?;
        let index = laine_karras(self.reversed_sample, hash32(key)).reverse_bits();
        Some(to_unit(
            laine_karras(index, hash32(key ^ 0xa076_1d64_78bd_642f)).reverse_bits(),
        ))
    }

    /// Uses up the next dimension pair without computing its point, as [`Self::next_1d`] would: false (nothing
    /// used up) after [`SOBOL_PAIRS`] pairs. For a decision that does not need its value, so that the later
    /// pairs keep theirs.
    pub fn skip_pair(&mut self) -> bool {
        self.next_pair_key().is_some()
    }

    /// The next dimension pair's point in \[0, 1)², or `None` after [`SOBOL_PAIRS`] pairs.
    pub fn next_2d(&mut self) -> Option<Vec2> {
        let key = self.next_pair_key()?;
        // With idx = scramble(sample): x = reverse(idx), so owen(x) = reverse(LK(idx)); and
        // owen(y) = reverse(LK(reverse(y))), where idx and reverse(y) come from the byte tables of reverse(idx).
        let reversed_index = laine_karras(self.reversed_sample, hash32(key));
        let (index, y_reversed) = index_and_second_dimension_reversed(reversed_index);
        let x = laine_karras(index, hash32(key ^ 0xa076_1d64_78bd_642f)).reverse_bits();
        let y = laine_karras(y_reversed, hash32(key ^ 0xe703_7ed1_a0b4_28db)).reverse_bits();
        Some(Vec2::new(to_unit(x), to_unit(y)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether `points` (2^k of them) put exactly one point in every elementary interval of area 2^-k.
    fn is_net(points: &[Vec2]) -> bool {
        let n = points.len();
        let k = n.trailing_zeros();
        (0..=k).all(|a| {
            let (nx, ny) = (1usize << a, 1usize << (k - a));
            let mut seen = vec![false; n];
            points.iter().all(|p| {
                let cell = (p.x * nx as f32) as usize * ny + (p.y * ny as f32) as usize;
                !std::mem::replace(&mut seen[cell], true)
            })
        })
    }

    #[test]
    fn unscrambled_points_are_the_sobol_sequence() {
        // The first points of Sobol's first two dimensions, from the sequence's definition.
        let expected = [
            (0.0, 0.0),
            (0.5, 0.5),
            (0.25, 0.75),
            (0.75, 0.25),
            (0.125, 0.625),
        ];
        for (i, &(x, y)) in expected.iter().enumerate() {
            let (a, b) = sobol_2d(i as u32);
            assert_eq!(
                (a as f64 / 2f64.powi(32), b as f64 / 2f64.powi(32)),
                (x, y),
                "{i}"
            );
        }
    }

    #[test]
    fn the_fast_path_equals_the_definition() {
        for (i, sample) in [0u32, 1, 2, 77, 1 << 20, u32::MAX].into_iter().enumerate() {
            let mut stream = SobolStream::new(4, 99, sample as u64);
            for pair in 0..3u64 {
                let key = stream
                    .pixel_key
                    .wrapping_mul(0x9e37_79b9_7f4a_7c15)
                    .wrapping_add(pair);
                let (x, y) = sobol_2d(owen_scramble(sample, hash32(key)));
                let expected = Vec2::new(
                    to_unit(owen_scramble(x, hash32(key ^ 0xa076_1d64_78bd_642f))),
                    to_unit(owen_scramble(y, hash32(key ^ 0xe703_7ed1_a0b4_28db))),
                );
                assert_eq!(stream.next_2d(), Some(expected), "case {i} pair {pair}");
            }
            // A 1-D draw is the x of the pair it uses up.
            let mut one = SobolStream::new(4, 99, sample as u64);
            let mut two = one.clone();
            assert_eq!(one.next_1d(), two.next_2d().map(|u| u.x));
            assert_eq!(one.next_2d(), two.next_2d());
        }
    }

    #[test]
    fn the_byte_tables_give_the_index_and_its_second_dimension() {
        for r in [0u32, 1, 0x8000_0000, 0xdead_beef, u32::MAX, 12_345] {
            let (index, y_reversed) = index_and_second_dimension_reversed(r);
            assert_eq!(index, r.reverse_bits(), "{r:#x}");
            assert_eq!(y_reversed, sobol_2d(index).1.reverse_bits(), "{r:#x}");
        }
    }

    #[test]
    fn owen_scrambling_is_a_nested_bijection() {
        // Values that share their leading bits keep sharing them (nested), and distinct values stay distinct.
        for seed in [0u32, 1, 0xdead_beef] {
            let mut out: Vec<u32> = (0..4096u32).map(|i| owen_scramble(i << 20, seed)).collect();
            for i in (0..4096).step_by(2) {
                assert_eq!(out[i] >> 21, out[i + 1] >> 21, "seed {seed}");
            }
            out.sort_unstable();
            out.dedup();
            assert_eq!(out.len(), 4096);
        }
    }

    #[test]
    fn every_pair_of_a_pixel_is_a_net_at_every_power_of_two() {
        for pixel in [0u64, 17, 123_456] {
            let mut streams: Vec<SobolStream> =
                (0..256).map(|s| SobolStream::new(9, pixel, s)).collect();
            for pair in 0..SOBOL_PAIRS {
                let points: Vec<Vec2> = streams.iter_mut().map(|s| s.next_2d().unwrap()).collect();
                for k in [1, 4, 16, 64, 256] {
                    assert!(is_net(&points[..k]), "pixel {pixel} pair {pair}: first {k}");
                }
            }
            assert!(streams[0].next_2d().is_none());
        }
    }

    #[test]
    fn pairs_of_one_sample_are_independent_and_uniform() {
        // One sample index over many pixels: the 4-D point of pairs 0 and 5 in 4 bins per axis (256 cells),
        // chi-square with 255 degrees of freedom; the 0.1% critical value is 330.5.
        let n = 256_000;
        let mut bins = vec![0u32; 256];
        for pixel in 0..n as u64 {
            let mut s = SobolStream::new(3, pixel, 5);
            let a = s.next_2d().unwrap();
            for _ in 0..4 {
                s.next_2d();
            }
            let b = s.next_2d().unwrap();
            let cell = [a.x, a.y, b.x, b.y]
                .iter()
                .fold(0usize, |c, &v| c * 4 + (v * 4.0) as usize);
            bins[cell] += 1;
        }
        let expected = n as f64 / 256.0;
        let chi2: f64 = bins
            .iter()
            .map(|&b| (b as f64 - expected).powi(2) / expected)
            .sum();
        assert!(chi2 < 330.5, "chi2 {chi2}");
    }
}
