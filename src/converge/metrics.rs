//! Error of an image against a reference, over the beauty RGB (every channel of every pixel counts once).

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

/// The errors of `image` against `reference`, pixel by pixel (both the same length and order).
pub fn error_metrics(image: &[Rgb], reference: &[Rgb]) -> ErrorMetrics {
    assert_eq!(
        image.len(),
        reference.len(),
        "image and reference sizes differ"
    );
    let (mut se, mut rel, mut sum) = (0.0f64, 0.0f64, 0.0f64);
    for (x, r) in image.iter().zip(reference) {
        for (x, r) in x.to_array().into_iter().zip(r.to_array()) {
            let (x, r) = (x as f64, r as f64);
            let d = x - r;
            se += d * d;
            rel += d * d / (r * r + 0.01);
            sum += d;
        }
    }
    let n = (image.len() * 3).max(1) as f64;
    ErrorMetrics {
        rmse: (se / n).sqrt(),
        relmse: rel / n,
        bias: sum / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_metrics() {
        // Differences 0.1, 0.2, 0.3 (pixel 1) and 0, 0, -0.6 (pixel 2) against 0, 1, 0 and 1, 0, 0.
        let reference = [Rgb::new(0.0, 1.0, 0.0), Rgb::new(1.0, 0.0, 0.0)];
        let image = [Rgb::new(0.1, 1.2, 0.3), Rgb::new(1.0, 0.0, -0.6)];
        let m = error_metrics(&image, &reference);
        // Squares: 0.01, 0.04, 0.09, 0, 0, 0.36 → sum 0.5, mean 1/12.
        assert!((m.rmse - (0.5f64 / 6.0).sqrt()).abs() < 1e-6, "{m:?}");
        assert!((m.mse() - 0.5 / 6.0).abs() < 1e-6);
        // Relative: 0.01/0.01 + 0.04/1.01 + 0.09/0.01 + 0 + 0 + 0.36/0.01 = 1 + 0.0396 + 9 + 36.
        let rel = (1.0 + 0.04 / 1.01 + 9.0 + 36.0) / 6.0;
        assert!((m.relmse - rel).abs() < 1e-5, "{m:?}");
        // Bias: (0.1 + 0.2 + 0.3 - 0.6) / 6 = 0.
        assert!(m.bias.abs() < 1e-7, "{m:?}");
        let same = error_metrics(&reference, &reference);
        assert_eq!((same.rmse, same.relmse, same.bias), (0.0, 0.0, 0.0));
        let offset = error_metrics(&[Rgb::splat(0.5)], &[Rgb::splat(0.25)]);
        assert!((offset.bias - 0.25).abs() < 1e-7 && (offset.rmse - 0.25).abs() < 1e-7);
    }
}
