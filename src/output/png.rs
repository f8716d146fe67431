//! The 8-bit sRGB PNG preview of the beauty pass.

use super::{validate, OutputError};
use crate::math::linear_to_srgb;
use crate::render::RenderImage;
use std::path::{Path, PathBuf};

/// The preview's path for an EXR at `exr_path`: same folder and stem, extension `.png`
/// (`out/frame.exr` → `out/frame.png`; a path without extension gains `.png`).
pub fn preview_path(exr_path: &Path) -> PathBuf {
    exr_path.with_extension("png")
}

/// Writes the beauty pass of `image` to `path` as an 8-bit RGB PNG: each linear channel is scaled by
/// `2^exposure`, clamped to \[0, 1\], sRGB encoded and rounded. Non-finite samples (NaN, ±inf) become 0. The file
/// is written atomically ([`super::write_atomically`]).
pub fn write_png_preview(
    image: &RenderImage,
    path: &Path,
    exposure: f32,
) -> Result<(), OutputError> {
    validate(image, path)?;
    let invalid = |reason: String| OutputError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let width = u32::try_from(image.width)
        .map_err(|_| invalid(format!("width {} too large for PNG", image.width)))?;
    let height = u32::try_from(image.height)
        .map_err(|_| invalid(format!("height {} too large for PNG", image.height)))?;
    let scale = exposure.exp2();
    let bytes: Vec<u8> = image
        .beauty
        .iter()
        .flat_map(|c| c.to_array())
        .map(|v| encode(v, scale))
        .collect();
    let png_error = |source| OutputError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut encoded = Vec::new();
    ::image::ImageEncoder::write_image(
        ::image::codecs::png::PngEncoder::new(&mut encoded),
        &bytes,
        width,
        height,
        ::image::ExtendedColorType::Rgb8,
    )
    .map_err(png_error)?;
    super::write_atomically(path, &encoded).map_err(|e| png_error(::image::ImageError::IoError(e)))
}

/// One linear channel scaled by `scale`, clamped, sRGB encoded and quantised to 8 bits; non-finite → 0.
fn encode(v: f32, scale: f32) -> u8 {
    let v = if v.is_finite() { v * scale } else { 0.0 };
    if v.is_nan() {
        return 0;
    }
    (linear_to_srgb(v) * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn preview_path_swaps_the_extension() {
        assert_eq!(
            preview_path(Path::new("out/frame.exr")),
            PathBuf::from("out/frame.png")
        );
        assert_eq!(
            preview_path(Path::new("frame.0001.exr")),
            PathBuf::from("frame.0001.png")
        );
        assert_eq!(
            preview_path(Path::new("render")),
            PathBuf::from("render.png")
        );
    }

    #[test]
    fn encode_clamps_and_maps_non_finite_to_zero() {
        assert_eq!(encode(0.0, 1.0), 0);
        assert_eq!(encode(1.0, 1.0), 255);
        assert_eq!(encode(7.5, 1.0), 255);
        assert_eq!(encode(-3.0, 1.0), 0);
        assert_eq!(encode(f32::NAN, 1.0), 0);
        assert_eq!(encode(f32::INFINITY, 1.0), 0);
        assert_eq!(encode(f32::NEG_INFINITY, 1.0), 0);
        assert_eq!(encode(0.5, f32::NAN), 0);
        // 18% grey encodes to sRGB 0.4613 → 117.6 → 118.
        assert_eq!(encode(0.18, 1.0), 118);
        // Exposure +1 doubles: 0.25 * 2 = 0.5 linear → sRGB 0.7354 → 188.
        assert_eq!(encode(0.25, 2.0), 188);
    }

    #[test]
    fn writes_an_exposed_clamped_8_bit_rgb_png_top_row_first() {
        let dir = std::env::temp_dir().join(format!("nimbus-output-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("preview.png");
        let mut img = RenderImage::new(2, 2);
        img.beauty[0] = Vec3::new(0.25, 0.0, 100.0);
        img.beauty[1] = Vec3::new(f32::NAN, f32::INFINITY, -1.0);
        img.beauty[2] = Vec3::splat(0.5);
        write_png_preview(&img, &path, 1.0).unwrap();
        let read = ::image::open(&path).unwrap();
        assert_eq!(read.color(), ::image::ColorType::Rgb8);
        let read = read.to_rgb8();
        assert_eq!(read.dimensions(), (2, 2));
        assert_eq!(read.get_pixel(0, 0).0, [188, 0, 255]);
        assert_eq!(read.get_pixel(1, 0).0, [0, 0, 0]);
        assert_eq!(read.get_pixel(0, 1).0, [255, 255, 255]);
        assert_eq!(read.get_pixel(1, 1).0, [0, 0, 0]);
        std::fs::remove_file(&path).unwrap();
    }
}
