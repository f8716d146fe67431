//! The render output image: the beauty pass and its arbitrary output variables (AOVs).

use crate::math::{Rgb, Vec3};

/// A rendered image with its AOVs, one value per pixel in every buffer.
///
/// All buffers are row-major with `width * height` entries; row 0 is the top of the image and column 0
/// its left edge, so pixel `(x, y)` lives at [`RenderImage::pixel_index`]`(x, y) = y * width + x`.
///
/// The AOVs:
/// - `beauty`: linear Rec.709 RGB radiance, the mean of all samples taken in the pixel.
/// - `albedo`: linear RGB albedo of the first surface hit by the camera ray (zero where nothing was hit).
/// - `normal`: world-space unit shading normal at the first surface hit (zero where nothing was hit).
/// - `depth`: distance along the camera ray from the camera to the first hit, in scene units; `0` where
///   nothing was hit (never infinity, which EXR viewers and compositors handle badly).
/// - `variance`: per-channel estimated variance of the beauty mean, i.e. the sample variance of the
///   pixel's samples divided by the sample count `N`; its square root is the standard error of `beauty`.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear RGB radiance, the per-pixel mean of the samples.
    pub beauty: Vec<Rgb>,
    /// Linear RGB albedo of the first surface hit; zero for no hit.
    pub albedo: Vec<Rgb>,
    /// World-space normal at the first surface hit; zero for no hit.
    pub normal: Vec<Vec3>,
    /// Camera distance to the first hit; `0` for no hit.
    pub depth: Vec<f32>,
    /// Per-channel variance of the beauty mean (sample variance / sample count).
    pub variance: Vec<Rgb>,
}

impl RenderImage {
    /// A `width` × `height` image with every buffer zero-filled.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            beauty: vec![Rgb::ZERO; n],
            albedo: vec![Rgb::ZERO; n],
            normal: vec![Vec3::ZERO; n],
            depth: vec![0.0; n],
            variance: vec![Rgb::ZERO; n],
        }
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Index into every buffer of pixel `(x, y)`, with `y = 0` the top row.
    pub fn pixel_index(&self, x: usize, y: usize) -> usize {
        debug_assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        y * self.width + x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_is_zero_filled_and_sized() {
        let img = RenderImage::new(4, 3);
        assert_eq!(img.pixel_count(), 12);
        for len in [
            img.beauty.len(),
            img.albedo.len(),
            img.normal.len(),
            img.depth.len(),
            img.variance.len(),
        ] {
            assert_eq!(len, 12);
        }
        assert!(img
            .beauty
            .iter()
            .chain(&img.variance)
            .all(|c| *c == Rgb::ZERO));
        assert!(img.depth.iter().all(|d| *d == 0.0));
    }

    #[test]
    fn pixel_index_is_row_major_from_the_top() {
        let img = RenderImage::new(4, 3);
        assert_eq!(img.pixel_index(0, 0), 0);
        assert_eq!(img.pixel_index(3, 0), 3);
        assert_eq!(img.pixel_index(0, 1), 4);
        assert_eq!(img.pixel_index(3, 2), 11);
    }
}
