//! Materials: the surface description a primitive carries ([`Material`]), the BSDFs it creates for surface
//! hits, and textures.
//!
//! Directions are in the local shading frame (z = shading normal) and point away from the surface. See
//! [`Bsdf`] for the contract with the integrator and [`PbrParams`] for the glTF parameters read.

pub mod bsdf;
pub mod dielectric;
pub mod fresnel;
pub mod gltf_pbr;
pub mod lambert;
pub mod microfacet;
pub mod sample;
pub mod surface;
pub mod texture;

pub use bsdf::{Bsdf, BsdfSample};
pub use gltf_pbr::PbrParams;
pub use surface::{Material, TextureId};
pub use texture::{ColorSpace, Filter, MipImage, Sampler, TexCoord, Texture, Wrap};
