//! The film: per-pixel running sums of the samples, from which the mean (beauty), the AOVs and the variance of
//! the mean are taken.

use super::RenderImage;
use crate::integrator::PathSample;
use crate::math::{Rgb, Vec3};

/// Running sums for one pixel. Samples are added in sample-index order, so the result does not depend on how
/// pixels are split between threads.
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelSums {
    count: u32,
    sum: [f64; 3],
    sum_sq: [f64; 3],
    albedo: [f64; 3],
    normal: [f64; 3],
    depth: f64,
}

impl PixelSums {
    /// Adds one finite sample.
    pub fn add(&mut self, s: &PathSample) {
        self.count += 1;
        for c in 0..3 {
            let v = s.radiance[c] as f64;
            self.sum[c] += v;
            self.sum_sq[c] += v * v;
            self.albedo[c] += s.albedo[c] as f64;
            self.normal[c] += s.normal[c] as f64;
        }
        self.depth += s.depth as f64;
    }
}

/// The accumulation buffer of a whole image.
#[derive(Clone, Debug)]
pub struct Film {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    pixels: Vec<PixelSums>,
}

impl Film {
    /// An empty film.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            pixels: vec![PixelSums::default(); width * height],
        }
    }

    /// The pixel sums, row-major, for parallel accumulation.
    pub fn pixels_mut(&mut self) -> &mut [PixelSums] {
        &mut self.pixels
    }

    /// The image: sample means for beauty and AOVs, and the variance of the mean,
    /// `(Σx² − (Σx)²/n) / (n − 1) / n`, per channel.
    pub fn image(&self) -> RenderImage {
        let mut img = RenderImage::new(self.width, self.height);
        for (i, p) in self.pixels.iter().enumerate() {
            if p.count == 0 {
                continue;
            }
            let n = p.count as f64;
            let mean =
                |a: [f64; 3]| Vec3::new((a[0] / n) as f32, (a[1] / n) as f32, (a[2] / n) as f32);
            img.beauty[i] = mean(p.sum);
            img.albedo[i] = mean(p.albedo);
            img.normal[i] = mean(p.normal).normalize_or_zero();
            img.depth[i] = (p.depth / n) as f32;
            if p.count > 1 {
                let var = |c: usize| {
                    ((p.sum_sq[c] - p.sum[c] * p.sum[c] / n).max(0.0) / (n - 1.0) / n) as f32
                };
                img.variance[i] = Rgb::new(var(0), var(1), var(2));
            }
        }
        img
    }
}
