//! Error of an image against a reference, over the beauty RGB (every channel of every pixel counts once).
//!
//! A reference rendered by Monte Carlo has noise of its own, which adds its variance to every squared error:
//! E[(x − r)²] = (x − r_true)² + se_r² for a reference pixel r with standard error se_r, independent of x. When the
//! reference's standard errors are known, [`error_metrics_against_noisy`] subtracts them, so that the RMSE and
//! relative MSE estimate the error against the noise-free image instead of flattening at the reference's noise.

use crate::math::Rgb;

/// Errors of one image against the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ErrorMetrics {
    /// Root mean squared error.
    pub rmse: f64,
    /// Relative MSE: mean of (x − r)² / (r² + 0.01).
    pub relmse: f64,
    /// Mean signed error: mean of x − r.
    pub bias: f64,
}

impl ErrorMetrics {
    /// The mean squared error.
    pub fn mse(&self) -> f64 {
        self.rmse * self.rmse
    }
}

/// An image and its reference (or the reference's standard errors) hold different numbers of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the image has {image} pixels and the reference {reference}")]
pub struct SizeMismatch {
    /// Pixels in the image.
    pub image: usize,
    /// Pixels in the reference (or in its standard errors).
    pub reference: usize,
}

/// The errors of `image` against `reference`, pixel by pixel (both the same length and order).
#[cfg(test)]
pub fn error_metrics(image: &[Rgb], reference: &[Rgb]) -> Result<ErrorMetrics, SizeMismatch> {
    error_metrics_against_noisy(image, reference, None)
}

/// The errors of `image` against a `reference` whose pixels have the standard errors `reference_se` (same
/// length and order), with the reference's variance subtracted from each squared error (see the module docs).
/// The sums are clamped at 0, so an image closer to the truth than the reference can resolve reads 0.
pub fn error_metrics_against_noisy(
    image: &[Rgb],
    reference: &[Rgb],
    reference_se: Option<&[Rgb]>,
) -> Result<ErrorMetrics, SizeMismatch> {
    for reference in std::iter::once(reference).chain(reference_se) {
        if reference.len() != image.len() {
            return Err(SizeMismatch {
                image: image.len(),
                reference: reference.len(),
            });
        }
    }
    let (mut se, mut rel, mut sum) = (0.0f64, 0.0f64, 0.0f64);
    for (i, (x, r)) in image.iter().zip(reference).enumerate() {
        let noise = reference_se.map_or([0.0; 3], |s| s[i].to_array());
        for ((x, r), s) in x.to_array().into_iter().zip(r.to_array()).zip(noise) {
            let (x, r, s) = (x as f64, r as f64, s as f64);
            let d = x - r;
            se += d * d - s * s;
            rel += (d * d - s * s) / (r * r + 0.01);
            sum += d;
        }
    }
    let n = (image.len() * 3).max(1) as f64;
    Ok(ErrorMetrics {
        rmse: (se.max(0.0) / n).sqrt(),
        relmse: rel.max(0.0) / n,
        bias: sum / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_that_differ_are_an_error() {
        let two = [Rgb::ZERO; 2];
        let err = error_metrics(&two, &two[..1]).unwrap_err();
        assert_eq!((err.image, err.reference), (2, 1));
        assert!(error_metrics_against_noisy(&two, &two, Some(&two[..1])).is_err());
    }

    #[test]
    fn hand_computed_metrics() {
        // Differences 0.1, 0.2, 0.3 (pixel 1) and 0, 0, -0.6 (pixel 2) against 0, 1, 0 and 1, 0, 0.
        let reference = [Rgb::new(0.0, 1.0, 0.0), Rgb::new(1.0, 0.0, 0.0)];
        let image = [Rgb::new(0.1, 1.2, 0.3), Rgb::new(1.0, 0.0, -0.6)];
        let m = error_metrics(&image, &reference).unwrap();
        // Squares: 0.01, 0.04, 0.09, 0, 0, 0.36 → sum 0.5, mean 1/12.
        assert!((m.rmse - (0.5f64 / 6.0).sqrt()).abs() < 1e-6, "{m:?}");
        assert!((m.mse() - 0.5 / 6.0).abs() < 1e-6);
        // Relative: 0.01/0.01 + 0.04/1.01 + 0.09/0.01 + 0 + 0 + 0.36/0.01 = 1 + 0.0396 + 9 + 36.
        let rel = (1.0 + 0.04 / 1.01 + 9.0 + 36.0) / 6.0;
        assert!((m.relmse - rel).abs() < 1e-5, "{m:?}");
        // Bias: (0.1 + 0.2 + 0.3 - 0.6) / 6 = 0.
        assert!(m.bias.abs() < 1e-7, "{m:?}");
        let same = error_metrics(&reference, &reference).unwrap();
        assert_eq!((same.rmse, same.relmse, same.bias), (0.0, 0.0, 0.0));
        let offset = error_metrics(&[Rgb::splat(0.5)], &[Rgb::splat(0.25)]).unwrap();
        assert!((offset.bias - 0.25).abs() < 1e-7 && (offset.rmse - 0.25).abs() < 1e-7);
    }

    /// Against a noisy reference the expected squared error grows by the reference's variance; subtracting
    /// the known standard errors recovers the error against the noise-free image.
    #[test]
    fn reference_noise_is_subtracted() {
        let mut rng = crate::math::Rng::new(5, 0);
        let n = 20_000;
        let truth = vec![Rgb::splat(1.0); n];
        // An image 0.02 off the truth, and a reference with Gaussian-like noise of standard error 0.05.
        let image: Vec<Rgb> = truth.iter().map(|t| *t + Rgb::splat(0.02)).collect();
        let se = 0.05f32;
        let reference: Vec<Rgb> = truth
            .iter()
            .map(|t| {
                // Sum of 12 uniforms minus 6 has unit variance.
                let g = (0..12).map(|_| rng.next_f32()).sum::<f32>() - 6.0;
                *t + Rgb::new(g, -g, g) * se
            })
            .collect();
        let naive = error_metrics(&image, &reference).unwrap();
        let corrected =
            error_metrics_against_noisy(&image, &reference, Some(&vec![Rgb::splat(se); n]))
                .unwrap();
        assert!(
            (naive.rmse - (0.02f64.powi(2) + 0.05f64.powi(2)).sqrt()).abs() < 2e-3,
            "{naive:?}"
        );
        assert!((corrected.rmse - 0.02).abs() < 2e-3, "{corrected:?}");
        // Nothing left to subtract from an exact match but noise: clamped at 0.
        let exact =
            error_metrics_against_noisy(&truth, &truth, Some(&vec![Rgb::splat(se); n])).unwrap();
        assert_eq!(exact.rmse, 0.0);
    }
}
