//! Materials: the surface description a primitive carries ([`Material`]), the BSDFs it creates for surface
//! hits, and textures.
//!
//! Directions are in the local shading frame (z = shading normal) and point away from the surface. See
//! `Bsdf` for the contract with the integrator and `PbrParams` for the glTF parameters read.

mod bsdf;
mod clearcoat;
mod dielectric;
mod dielectric_albedo;
mod fresnel;
mod gltf_pbr;
mod lambert;
mod layered;
mod lobes;
mod microfacet;
mod sample;
mod sheen;
#[cfg(feature = "testing")]
pub mod spec_gloss;
#[cfg(not(feature = "testing"))]
pub(crate) mod spec_gloss;
mod surface;
mod texture;
mod thin_film;

pub use crate::geometry::CompositingTags;
pub use lobes::LobeClass;
pub use spec_gloss::SpecularGlossiness;
pub(crate) use surface::MaterialShading;
pub use surface::{
    AlphaMode, Anisotropy, ClearcoatLayer, DiffuseTransmission, Iridescence, Material, SheenLayer,
    TextureId,
};
internal! {
    pub use bsdf::Bsdf;
    pub use gltf_pbr::PbrParams;
    pub use lobes::LobeSplit;
    pub use texture::{
        ColorSpace, Filter, MipImage, Sampler, ShadingPoint, TexCoord, Texture, UvTransform, Wrap,
        UV_SETS,
    };
}
internal! {
    pub use bsdf::BsdfSample;
}
#[cfg(feature = "testing")]
pub use clearcoat::Clearcoat;
#[cfg(feature = "testing")]
pub use dielectric::Dielectric;
#[cfg(feature = "testing")]
pub use gltf_pbr::GltfPbr;
#[cfg(feature = "testing")]
pub use lambert::Lambert;
#[cfg(feature = "testing")]
pub use layered::Layered;
#[cfg(feature = "testing")]
pub use microfacet::{Ggx, DELTA_ALPHA};
#[cfg(feature = "testing")]
pub use sheen::Sheen;
#[cfg(feature = "testing")]
pub use spec_gloss::{to_metallic_roughness, MetallicRoughness};
#[cfg(feature = "testing")]
pub use thin_film::{airy_reflectance, substrate_ior, ThinFilm};
