//! Rendering: the film that accumulates samples and their AOVs in exact sums, the progressive pass loop with
//! its time budget, progress and cancellation, the statistics of a render, and deep samples.

pub mod aovs;
mod cancel;
mod channels;
pub mod cryptomatte;
pub mod deep;
mod emitter_edges;
mod exact;
mod film;
mod image;
mod recording;
mod renderer;
pub mod resume;

pub use crate::integrator::{EquiangularTargets, PathSample};
pub use aovs::{AovSelection, LayerPlan, LightGroupMode, LightGroups};
pub use cancel::CancelToken;
pub use channels::{channel_names, Channel, ChannelKind, Layer, LayerData, LAYERS};
pub use deep::{DeepImage, DeepSample};
pub use emitter_edges::{
    EdgeDecision, EmitterEdgeSampling, EmitterEdges, EDGE_RAYS, MAX_EMISSIVE_TRIANGLES,
    MAX_MARKED_SHARE,
};
pub use exact::{ValueSum, MAX_SAMPLE_VALUE};
pub use film::{Film, FilmMergeError, FilmPixel, FilmRow, PixelSums, PixelWindow};
pub use image::{AovLayer, ImageMetadata, RenderImage};
pub use recording::LayerRecorder;
pub use renderer::{
    peak_memory_bytes, MediumStats, Progress, RegionError, RenderError, RenderRegion,
    RenderSettings, RenderStats, Renderer, Sampler, DEFAULT_MAX_DEPTH, DEFAULT_WIDTH,
};
