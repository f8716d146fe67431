use super::sobol::SobolStream;

/// PCG32 random number generator (O'Neill 2014, "PCG: A Family of Simple Fast Space-Efficient Statistically
/// Good Algorithms for Random Number Generation", the XSH-RR output on a 64-bit LCG).
///
/// The renderer seeds one generator per (seed, pixel, sample) with [`Rng::for_sample`], so an image does not
/// depend on how pixels are split between threads.
///
/// A generator made by [`Rng::for_sample_sobol`] also carries the sample's low-discrepancy values
/// ([`SobolStream`]), which [`Rng::sample_1d`] and [`Rng::sample_2d`] hand out to the path's key decisions
/// (pixel position, light choice and position, BSDF and phase sampling); everything else draws from PCG32.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
    sobol: Option<SobolStream>,
}

const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// SplitMix64 finaliser, used to decorrelate the seeds of neighbouring streams.
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A uniform float in \[0, 1) that is a pure function of `words` (each word through the SplitMix64 finaliser):
/// the random number of a decision that must not consume the path's generator, such as the stochastic
/// alpha test of a hit, keyed by the ray and the triangle (as pbrt-v4 hashes the ray for its alpha test).
pub fn hash_to_unit(words: &[u32]) -> f32 {
    let h = words
        .iter()
        .fold(0x2545_f491_4f6c_dd1d_u64, |h, &w| mix64(h ^ u64::from(w)));
    (h >> 40) as f32 * (1.0 / 16_777_216.0)
}

impl Rng {
    /// A generator on stream `stream` starting from `seed`.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: 0,
            inc: (stream << 1) | 1,
            sobol: None,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The generator for one pixel sample: a pure function of the render seed, the pixel and the sample index.
    pub fn for_sample(seed: u64, pixel_index: u64, sample_index: u64) -> Self {
        let a = mix64(seed ^ mix64(pixel_index.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        let b = mix64(a ^ sample_index.wrapping_mul(0xd1b5_4a32_d192_ed03));
        Rng::new(b, mix64(b ^ pixel_index))
    }

    /// [`Rng::for_sample`] with the sample's low-discrepancy values ([`SobolStream`]) for
    /// [`Rng::sample_1d`] and [`Rng::sample_2d`].
    pub fn for_sample_sobol(seed: u64, pixel_index: u64, sample_index: u64) -> Self {
        let mut rng = Rng::for_sample(seed, pixel_index, sample_index);
        rng.sobol = Some(SobolStream::new(seed, pixel_index, sample_index));
        rng
    }

    /// Two uniform values for one of the path's key decisions: the next low-discrepancy pair when the
    /// generator has them, else [`Rng::next_2d`].
    pub fn sample_2d(&mut self) -> glam::Vec2 {
        match self.sobol.as_mut().and_then(SobolStream::next_2d) {
            Some(u) => u,
            None => self.next_2d(),
        }
    }

    /// One uniform value for one of the path's key decisions (the first of a [`Rng::sample_2d`] pair).
    pub fn sample_1d(&mut self) -> f32 {
        match self.sobol.as_mut().and_then(SobolStream::next_1d) {
            Some(u) => u,
            None => self.next_f32(),
        }
    }

    /// Uses up the value [`Rng::sample_1d`] would return without computing it (its Sobol pair, else one PCG32
    /// output), so that every later value is the one it would have been: for a key decision that turns out not
    /// to need its value (the lobe choice of a single-lobe BSDF).
    pub fn skip_1d(&mut self) {
        if !self.sobol.as_mut().is_some_and(SobolStream::skip_pair) {
            self.next_u32();
        }
    }

    /// The next 32 uniformly distributed bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform float in \[0, 1).
    pub fn next_f32(&mut self) -> f32 {
        // 24 high bits give every representable multiple of 2^-24 below 1.
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two uniform floats in \[0, 1).
    pub fn next_2d(&mut self) -> glam::Vec2 {
        glam::Vec2::new(self.next_f32(), self.next_f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skip_1d_leaves_later_values_as_sample_1d_does() {
        // Past the Sobol pairs too: 60 decisions run beyond the 48 pairs into PCG32.
        for skipped in [0, 5, 47, 48, 55] {
            let mut drawn = Rng::for_sample_sobol(3, 17, 9);
            let mut skipping = drawn.clone();
            let values = |rng: &mut Rng, skip: bool| -> Vec<f32> {
                (0..60)
                    .map(|i| match (i == skipped, skip) {
                        (true, true) => {
                            rng.skip_1d();
                            -1.0
                        }
                        (true, false) => {
                            rng.sample_1d();
                            -1.0
                        }
                        _ if i % 2 == 0 => rng.sample_2d().y,
                        _ => rng.sample_1d(),
                    })
                    .collect()
            };
            assert_eq!(values(&mut drawn, false), values(&mut skipping, true));
            assert_eq!(drawn.next_u32(), skipping.next_u32());
        }
    }

    #[test]
    fn hash_to_unit_is_uniform() {
        // Chi-square over 16 bins of 64,000 keys that differ in one word, as neighbouring rays do.
        let mut bins = [0u32; 16];
        for i in 0..64_000u32 {
            let u = hash_to_unit(&[0x3f80_0000, i, 7]);
            assert!((0.0..1.0).contains(&u));
            bins[(u * 16.0) as usize] += 1;
        }
        let expected = 4000.0;
        let chi2: f64 = bins
            .iter()
            .map(|&b| (b as f64 - expected).powi(2) / expected)
            .sum();
        // 15 degrees of freedom: the 0.1% critical value is 37.7.
        assert!(chi2 < 37.7, "chi2 {chi2}, bins {bins:?}");
    }

    #[test]
    fn uniform_mean_and_range() {
        let mut rng = Rng::new(7, 3);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        let mean = sum / n as f64;
        // Standard error of the mean of U(0,1) is sqrt(1/12/n).
        let se = (1.0 / 12.0 / n as f64).sqrt();
        assert!((mean - 0.5).abs() < 4.0 * se, "mean {mean}");
    }

    #[test]
    fn sample_streams_are_reproducible_and_distinct() {
        let a = Rng::for_sample(1, 10, 0).next_u32();
        assert_eq!(a, Rng::for_sample(1, 10, 0).next_u32());
        assert_ne!(a, Rng::for_sample(1, 10, 1).next_u32());
        assert_ne!(a, Rng::for_sample(1, 11, 0).next_u32());
        assert_ne!(a, Rng::for_sample(2, 10, 0).next_u32());
    }
}
