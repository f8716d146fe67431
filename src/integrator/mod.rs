//! The light integrator: a unidirectional volumetric path tracer with next-event estimation and multiple
//! importance sampling at surfaces and in media, and the renderer services it hands to whoever needs light
//! samples or shadow-ray transmittance.

mod guided;
mod medium_stack;
mod path;
mod record;
mod services;
mod stats;

pub use medium_stack::MediumStack;
pub use path::{EquiangularTargets, FirstEmission, PathContext, PathSample, PathTracer};
pub use record::{CameraEvent, EventClass, Origin, SampleRecord};
pub use services::RendererServices;
pub use stats::{PathCounters, RayCounters};
