//! Nimbus: a production volumetric path tracer for glTF, OBJ and USD scenes with OpenVDB volumes.
//!
//! See `ARCHITECTURE.md` for the module map.

pub mod geometry;
pub mod math;
