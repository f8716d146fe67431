//! Materials: the surface description a primitive carries ([`Material`]), the BSDFs it creates for surface
//! hits, and textures.
//!
//! Directions are in the local shading frame (z = shading normal) and point away from the surface. See
//! [`Bsdf`] for the contract with the integrator and [`PbrParams`] for the glTF parameters read.

mod bsdf;
mod clearcoat;
mod dielectric;
mod fresnel;
mod gltf_pbr;
mod lambert;
mod layered;
mod lobes;
mod microfacet;
mod sample;
mod sheen;
pub mod spec_gloss;
mod surface;
mod texture;
mod thin_film;

pub use bsdf::{Bsdf, BsdfSample};
pub use clearcoat::Clearcoat;
pub use dielectric::Dielectric;
pub use gltf_pbr::{GltfPbr, PbrParams};
pub use lambert::Lambert;
pub use layered::Layered;
pub use lobes::{LobeClass, LobeSplit};
pub use microfacet::{Ggx, DELTA_ALPHA};
pub use sheen::Sheen;
pub use spec_gloss::{to_metallic_roughness, MetallicRoughness, SpecularGlossiness};
pub use surface::{
    AlphaMode, Anisotropy, ClearcoatLayer, DiffuseTransmission, Iridescence, Material, SheenLayer,
    TextureId,
};
pub use texture::{
    ColorSpace, Filter, MipImage, Sampler, ShadingPoint, TexCoord, Texture, UvTransform, Wrap,
    UV_SETS,
};
pub use thin_film::{airy_reflectance, substrate_ior, ThinFilm};
