//! Materials: the surface description a primitive carries, the BSDFs it creates at each hit, and textures.

pub mod bsdf;
pub mod surface;
pub mod texture;

pub use bsdf::{Bsdf, BsdfSample, PbrParams};
pub use surface::{Material, TextureId};
pub use texture::{ColorSpace, Texture, Wrap};
