//! Lambertian (ideal diffuse) reflection, `f = albedo / π`, sampled with the cosine-weighted hemisphere.
//!
//! glTF: a material with `metallicFactor` 0, `KHR_materials_specular.specularFactor` 0 and no transmission
//! maps here; `baseColorFactor` (times its texture) is the albedo.

use super::lobes::{LobeClass, LobeSplit};
use crate::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::math::{Rgb, Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Ideal diffuse reflector (Lambert 1760): `f(wo, wi) = albedo / π` for directions above the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Directional-hemispherical reflectance.
    pub albedo: Rgb,
}

impl Lambert {
    /// `albedo / π` when both directions are above the surface (one-sided), else 0.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::ZERO;
        }
        self.albedo * FRAC_1_PI
    }

    /// [`Lambert::eval`], all of it diffuse.
    pub fn eval_split(&self, wo: Vec3, wi: Vec3) -> LobeSplit {
        LobeSplit::only(LobeClass::Diffuse, self.eval(wo, wi))
    }

    /// The class colours: the albedo as the diffuse colour for `wo` above the surface (its exact directional
    /// albedo, `∫ albedo/π cos θi dωi = albedo`), zero from below, where the surface reflects nothing.
    pub fn colors(&self, wo: Vec3) -> LobeSplit {
        if wo.z <= 0.0 {
            return LobeSplit::ZERO;
        }
        LobeSplit::only(LobeClass::Diffuse, self.albedo)
    }

    /// Cosine-weighted density `cos θi / π` when both directions are above the surface, else 0.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        cosine_hemisphere_pdf(wi.z)
    }

    /// A cosine-weighted direction about +z; `None` when `wo` is below the surface or the sample is grazing.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = cosine_hemisphere(u);
        (wi.z > 0.0).then_some(wi)
    }
}
