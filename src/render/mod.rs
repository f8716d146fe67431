//! Rendering: the film that accumulates samples and their AOVs in exact sums, the progressive pass loop with
//! its time budget, progress and cancellation, and the statistics of a render.

mod cancel;
mod channels;
mod emitter_edges;
mod exact;
mod film;
mod image;
mod renderer;

pub use crate::integrator::{EquiangularTargets, PathSample};
pub use cancel::CancelToken;
pub use channels::{channel_names, Layer, LayerData, LAYERS};
pub use emitter_edges::{
    EdgeDecision, EmitterEdgeSampling, EmitterEdges, EDGE_RAYS, MAX_EMISSIVE_TRIANGLES,
    MAX_MARKED_SHARE,
};
pub use exact::MAX_SAMPLE_VALUE;
pub use film::{Film, PixelSums, PixelWindow};
pub use image::RenderImage;
pub use renderer::{
    peak_memory_bytes, MediumStats, Progress, RegionError, RenderError, RenderRegion,
    RenderSettings, RenderStats, Renderer, Sampler,
};
