//! Writing and reading rendered images: the multi-layer OpenEXR file, the deep scanline OpenEXR file and the
//! 8-bit sRGB PNG preview.

mod atomic;
mod deep;
mod exposure;
mod exr;
mod png;

pub use self::atomic::write_atomically;
pub use self::deep::{deep_path, write_deep_exr, DeepCompression};
pub use self::exposure::{meter, Exposure, Metering, BLACK_LUMINANCE, BLACK_SHARE};
pub use self::exr::{write_exr, write_exr_with, ExrCompression, ExrOptions, HalfFloats};
internal! {
    pub use self::exr::read_exr_layers;
}
#[cfg(feature = "testing")]
pub use self::atomic::temporary_path;
#[cfg(feature = "testing")]
pub use self::deep::{encode_deep_exr, DEEP_CHANNELS};
#[cfg(feature = "testing")]
pub use self::exposure::{KEY_RANGE, MAX_AUTO_STOPS, MIDDLE_GREY};
#[cfg(feature = "testing")]
pub use self::exr::ExrLayers;
pub(crate) use self::exr::{read_flat_image, write_sorted};
pub use self::png::{preview_path, write_png_preview};

use std::path::PathBuf;

/// Why writing or reading an output image failed; every variant names the file involved.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The OpenEXR encoder or decoder failed (I/O, malformed file, unsupported feature).
    #[error("EXR file {path}: {source}")]
    Exr {
        /// The file being written or read.
        path: PathBuf,
        /// The underlying `exr` crate error.
        #[source]
        source: ::exr::error::Error,
    },
    /// The PNG encoder failed (I/O or encoding).
    #[error("PNG file {path}: {source}")]
    Png {
        /// The file being written.
        path: PathBuf,
        /// The underlying `image` crate error.
        #[source]
        source: ::image::ImageError,
    },
    /// The image cannot be written or the file's contents are unusable (empty image, buffer
    /// lengths that disagree with the size, layers of different sizes...).
    #[error("image for {path}: {reason}")]
    Invalid {
        /// The file being written or read.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
}

/// Checks that `image` is non-empty and that every buffer holds `width * height` pixels.
fn validate(image: &crate::render::RenderImage, path: &std::path::Path) -> Result<(), OutputError> {
    let invalid = |reason: String| OutputError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    if image.width == 0 || image.height == 0 {
        return Err(invalid(format!(
            "empty image {}x{}",
            image.width, image.height
        )));
    }
    let n = image
        .width
        .checked_mul(image.height)
        .ok_or_else(|| invalid(format!("size {}x{} overflows", image.width, image.height)))?;
    for layer in &crate::render::LAYERS {
        let len = layer.buffer_len(image);
        if len != n {
            let name = match layer.name {
                "" => "beauty",
                name => name,
            };
            return Err(invalid(format!(
                "{name} buffer holds {len} pixels, expected {n} for {}x{}",
                image.width, image.height
            )));
        }
    }
    for layer in &image.aovs {
        if let Some(len) = layer.data.iter().map(Vec::len).find(|&len| len != n) {
            return Err(invalid(format!(
                "layer {} holds {len} pixels, expected {n} for {}x{}",
                layer.name, image.width, image.height
            )));
        }
    }
    Ok(())
}
