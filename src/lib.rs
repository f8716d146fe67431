//! Nimbus: a production volumetric path tracer for glTF, OBJ and USD scenes with OpenVDB volumes.
//!
//! See `ARCHITECTURE.md` for the module map.

pub mod geometry;
pub mod integrator;
pub mod light;
pub mod material;
pub mod math;
pub mod output;
pub mod render;
pub mod scene;
pub mod vdb;
pub mod volume;
