//! The result of sampling any BSDF lobe, shared by every lobe and by the [`super::Bsdf`] dispatch (its own
//! module so that lobes need not import the dispatcher).

use super::lobes::LobeClass;
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
    /// The class of the lobe that produced the sample. For a delta sample the whole weight belongs to it.
    /// For a non-delta one it is informational: `f` is the whole mixture's value, which the light-path AOVs
    /// share by [`super::Bsdf::eval_split`] (other lobes hold the same `wi`). The sampled lobe always holds
    /// `wi`: a glTF material's GGX reflection that falls below the horizon is rejected, not kept where only
    /// a transmissive lobe has a value.
    pub class: LobeClass,
    /// The relative index of refraction η = η(wi side)/η(wo side) when `wi` refracts through a dielectric
    /// interface, whose value `f` then carries the radiance factor 1/η² (Veach 1997, §5.2); 1 for every other
    /// lobe. Russian roulette undoes that factor with it (pbrt-v4's `etaScale`).
    pub eta: f32,
}
