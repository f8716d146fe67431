//! The light integrator: a unidirectional path tracer with next-event estimation and multiple importance
//! sampling, and the renderer services it hands to whoever needs light samples or shadow-ray transmittance.

mod path;
mod services;
mod stats;

pub use path::{PathSample, PathTracer};
pub use services::RendererServices;
pub use stats::RayCounters;
