//! Rendering: the film that accumulates samples and their AOVs, the progressive pass loop with its time budget,
//! progress and cancellation, and the statistics of a render.

mod cancel;
mod channels;
mod film;
pub mod image;
mod renderer;

pub use cancel::CancelToken;
pub use channels::CHANNEL_NAMES;
pub use film::Film;
pub use image::RenderImage;
pub use renderer::{
    peak_memory_bytes, MediumStats, Progress, RenderSettings, RenderStats, Renderer,
};
