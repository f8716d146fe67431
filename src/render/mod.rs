//! Rendering: the film that accumulates samples and their AOVs in exact sums, the progressive pass loop with
//! its time budget, progress and cancellation, and the statistics of a render.

mod cancel;
mod channels;
pub mod exact;
mod film;
pub mod image;
mod renderer;

pub use cancel::CancelToken;
pub use channels::{channel_names, Layer, LayerData, LAYERS};
pub use film::{Film, PixelSums, PixelWindow};
pub use image::RenderImage;
pub use renderer::{
    peak_memory_bytes, MediumStats, Progress, RegionError, RenderRegion, RenderSettings,
    RenderStats, Renderer,
};
