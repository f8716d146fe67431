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
mod guiding;
mod image;
mod recording;
mod renderer;
pub mod resume;

pub use crate::integrator::{EquiangularTargets, RayCounters};
pub use crate::volume::TrackingCounters;
pub use aovs::{AovSelection, LayerPlan, LightGroupMode, LightGroups};
pub use cancel::CancelToken;
pub use channels::{channel_names, Channel, ChannelKind, Layer, LayerData, LAYERS};
pub use deep::{DeepImage, DeepSample};
#[cfg(feature = "testing")]
pub use emitter_edges::EdgeDecision;
pub use emitter_edges::EmitterEdgeSampling;
pub use film::{Film, FilmMergeError, PixelWindow};
internal! {
    pub use film::PixelSums;
}
pub use image::{AovLayer, ImageMetadata, RenderImage};
internal! {
    pub use exact::ValueSum;
}
pub use crate::guiding::GuidingMode;
#[cfg(feature = "testing")]
pub use crate::integrator::PathSample;
#[cfg(feature = "testing")]
pub use emitter_edges::{EmitterEdges, EDGE_RAYS, MAX_EMISSIVE_TRIANGLES, MAX_MARKED_SHARE};
#[cfg(feature = "testing")]
pub use exact::MAX_SAMPLE_VALUE;
#[cfg(feature = "testing")]
pub use film::{FilmPixel, FilmRow};
#[cfg(feature = "testing")]
pub use recording::LayerRecorder;
#[cfg(feature = "testing")]
pub use renderer::peak_memory_bytes;
pub use renderer::{
    GuidingStats, MediumStats, Progress, RegionError, RenderError, RenderRegion, RenderSettings,
    RenderStats, Renderer, Sampler, DEFAULT_MAX_DEPTH, DEFAULT_WIDTH,
};
