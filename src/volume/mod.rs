//! Participating media: phase functions (and, later, the Volume interface and its implementations).

pub mod phase;
