/// A piecewise-constant 1D distribution on \[0, 1), sampled by inverting its CDF (PBRT4 §A.4.2).
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// Builds from non-negative function values over `n` equal bins. A function that is zero everywhere
    /// becomes uniform, so sampling stays defined. Negative and non-finite values count as zero.
    pub fn new(values: &[f32]) -> Self {
        let n = values.len().max(1);
        let func: Vec<f32> = (0..n)
            .map(|i| {
                values
                    .get(i)
                    .copied()
                    .filter(|v| v.is_finite() && *v > 0.0)
                    .unwrap_or(0.0)
            })
            .collect();
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += func[i] as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Self {
            func,
            cdf,
            integral,
        }
    }

    /// Number of bins.
    #[cfg(any(test, feature = "testing"))]
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True when there are no bins (never, since `new` makes at least one).
    #[cfg(any(test, feature = "testing"))]
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Integral of the function over \[0, 1).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Samples a bin with probability proportional to its value: returns (bin, probability of the bin).
    pub fn sample_discrete(&self, u: f32) -> (usize, f32) {
        let i = self.find_interval(u);
        (i, self.discrete_pdf(i))
    }

    /// [`Self::sample_discrete`] that also returns `u` rescaled within the chosen bin's share of \[0, 1), which is
    /// again uniform in \[0, 1) and independent of the choice: one stratified value then both picks a bin and
    /// places a sample inside what it picked.
    pub fn sample_discrete_remapped(&self, u: f32) -> (usize, f32, f32) {
        let i = self.find_interval(u);
        let pmf = self.discrete_pdf(i);
        let rest = if pmf > 0.0 {
            ((u - self.cdf[i]) / pmf).clamp(0.0, 1.0 - f32::EPSILON)
        } else {
            0.5
        };
        (i, pmf, rest)
    }

    /// Probability of choosing bin `i` in [`Self::sample_discrete`].
    pub fn discrete_pdf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Samples a continuous position in \[0, 1): returns (x, density at x, bin).
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let i = self.find_interval(u);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 {
            (u - self.cdf[i]) / width
        } else {
            0.5
        };
        let n = self.func.len() as f32;
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / n).min(1.0 - f32::EPSILON);
        (x, self.pdf_bin(i), i)
    }

    /// Density of [`Self::sample_continuous`] at `x` in \[0, 1).
    pub fn pdf(&self, x: f32) -> f32 {
        let n = self.func.len();
        let i = ((x * n as f32) as usize).min(n - 1);
        self.pdf_bin(i)
    }

    fn pdf_bin(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }

    fn find_interval(&self, u: f32) -> usize {
        // Largest i with cdf[i] <= u, restricted to bins 0..n-1.
        let n = self.func.len();
        let idx = self.cdf.partition_point(|&c| c <= u);
        idx.saturating_sub(1).min(n - 1)
    }
}

/// A piecewise-constant 2D distribution on \[0, 1)² built from a row-major image: a marginal over rows (v) and
/// one conditional per row (u), PBRT4 §A.5.6.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    conditionals: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds from `width × height` non-negative values, row-major with row 0 at v = 0.
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        let conditionals: Vec<Distribution1D> = (0..height)
            .map(|y| Distribution1D::new(&values[y * width..(y + 1) * width]))
            .collect();
        let row_integrals: Vec<f32> = conditionals.iter().map(|c| c.integral()).collect();
        Self {
            marginal: Distribution1D::new(&row_integrals),
            conditionals,
        }
    }

    /// Samples (u, v) with density proportional to the values; returns the point and its density.
    pub fn sample(&self, u: glam::Vec2) -> (glam::Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_u, _) = self.conditionals[row].sample_continuous(u.x);
        (glam::Vec2::new(x, v), pdf_v * pdf_u)
    }

    /// Density of [`Self::sample`] at `p`.
    pub fn pdf(&self, p: glam::Vec2) -> f32 {
        let h = self.conditionals.len();
        let row = ((p.y * h as f32) as usize).min(h - 1);
        self.marginal.pdf(p.y) * self.conditionals[row].pdf(p.x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn discrete_probabilities_follow_the_values() {
        let d = Distribution1D::new(&[1.0, 0.0, 3.0]);
        assert!((d.discrete_pdf(0) - 0.25).abs() < 1e-6);
        assert_eq!(d.discrete_pdf(1), 0.0);
        assert_eq!(d.sample_discrete(0.1).0, 0);
        assert_eq!(d.sample_discrete(0.3).0, 2);
        assert_eq!(d.sample_discrete(0.999_999).0, 2);
    }

    #[test]
    fn continuous_density_integrates_to_one_and_matches_samples() {
        let d = Distribution2D::new(&[1.0, 2.0, 0.0, 5.0, 0.5, 0.5], 3, 2);
        let mut rng = crate::math::Rng::new(3, 4);
        for _ in 0..1000 {
            let (p, pdf) = d.sample(rng.next_2d());
            assert!(pdf > 0.0);
            assert!(
                (d.pdf(p) - pdf).abs() < 1e-4 * pdf.max(1.0),
                "{} vs {pdf}",
                d.pdf(p)
            );
        }
        // Riemann sum of the density over a fine grid is 1.
        let n = 300;
        let mut total = 0.0;
        for j in 0..n {
            for i in 0..n {
                total += d.pdf(glam::Vec2::new(
                    (i as f32 + 0.5) / n as f32,
                    (j as f32 + 0.5) / n as f32,
                ));
            }
        }
        assert!((total / (n * n) as f32 - 1.0).abs() < 1e-3);
    }

    #[test]
    fn all_zero_is_uniform() {
        let d = Distribution1D::new(&[0.0, 0.0]);
        assert_eq!(d.pdf(0.3), 1.0);
        assert!((d.discrete_pdf(1) - 0.5).abs() < 1e-6);
    }
}
