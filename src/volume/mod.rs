//! Participating media: phase functions (and, later, the Volume interface and its implementations).

pub mod density;
pub mod majorant;
pub mod phase;
pub mod tracking;
