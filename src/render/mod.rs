//! Rendering: the output image with its arbitrary output variables (AOVs).

pub mod image;

pub use image::RenderImage;
