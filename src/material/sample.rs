//! The result of sampling any BSDF lobe, shared by every lobe and by the [`super::Bsdf`] dispatch (its own
//! module so that lobes need not import the dispatcher).

use crate::math::{Rgb, Vec3};

/// One sampled direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// The sampled direction, pointing away from the surface.
    pub wi: Vec3,
    /// BSDF value for (wo, wi), without the cosine. For delta lobes, the lobe's value such that
    /// `f |wi.z| / pdf` is the sample weight.
    pub f: Rgb,
    /// Solid-angle density of `wi`; for delta lobes the discrete probability of the chosen lobe.
    pub pdf: f32,
    /// True when `wi` comes from a delta lobe (no MIS, no `eval`).
    pub is_delta: bool,
}
