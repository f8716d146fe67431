//! The clear-coat lobe of `KHR_materials_clearcoat`: a GGX dielectric layer of index 1.5 with its own
//! roughness and normal.
//!
//! The extension's specification ("Clearcoat", with glTF 2.0 Appendix B's `specular_brdf` and
//! `fresnel_coat`) layers it as
//! `f = (1 − c·F(wo·nc)) · f_base + c·F(wo·nc) · D G2 / (4 |wo·nc| |wi·nc|)`, where `c` is `clearcoatFactor` ×
//! texture, `nc` the coat normal, `F` Schlick's Fresnel with `f0 = ((1.5 − 1)/(1.5 + 1))² = 0.04`, and the
//! microfacet term is GGX with α = `clearcoatRoughness`², the height-correlated Smith G2. Since the GGX term
//! reflects at most all light and `c·F ≤ 1`, the coated albedo never exceeds 1 when the base's does not.
//!
//! Directions are in the base's shading frame; the coat's own frame (around `nc`, which the coat's normal map
//! may tilt) is held here. The lobe is zero unless both directions are above both the base and the coat. With
//! a tilted coat normal the lobe's cosine is the coat's own (see [`Clearcoat::eval`]).

use super::fresnel::reflect;
use super::microfacet::{Ggx, DELTA_ALPHA};
use crate::math::{Frame, Vec2, Vec3};

/// Normal-incidence reflectance of the coat, `((1.5 − 1)/(1.5 + 1))²`.
pub const COAT_F0: f32 = 0.04;

/// The coat at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clearcoat {
    /// `clearcoatFactor` × texture, in \[0, 1\].
    pub weight: f32,
    /// GGX α = `clearcoatRoughness`².
    pub alpha: f32,
    /// The unit coat normal in the base's shading frame (+z unless the coat has its own normal map).
    pub normal: Vec3,
}

impl Clearcoat {
    /// A coat of `weight` and perceptual `roughness` (both clamped to \[0, 1\]) whose normal is the base's.
    pub fn new(weight: f32, roughness: f32) -> Self {
        let r = roughness.clamp(0.0, 1.0);
        Self {
            weight: weight.clamp(0.0, 1.0),
            alpha: r * r,
            normal: Vec3::Z,
        }
    }

    /// The coat's frame within the base's (z = the coat normal).
    fn frame(&self) -> Frame {
        Frame::from_normal(self.normal)
    }

    /// Tilts the coat normal to `n` (a unit vector in the base's frame, above it); others are ignored.
    pub fn set_normal(&mut self, n: Vec3) {
        if n.is_finite() && n.z > 0.0 {
            self.normal = n.normalize();
        }
    }

    /// True when the coat is a perfect mirror (α below [`DELTA_ALPHA`]).
    pub fn is_delta(&self) -> bool {
        self.alpha < DELTA_ALPHA
    }

    /// The blend weight `c · F(wo·nc)` (0 below the coat).
    pub fn blend(&self, wo: Vec3) -> f32 {
        let cos = self.normal.dot(wo);
        if cos <= 0.0 {
            return 0.0;
        }
        let m = 1.0 - cos.min(1.0);
        let m2 = m * m;
        self.weight * (COAT_F0 + (1.0 - COAT_F0) * m2 * m2 * m)
    }

    /// Both directions in the coat's frame, when both are above the base and the coat.
    fn local(&self, wo: Vec3, wi: Vec3) -> Option<(Vec3, Vec3)> {
        let frame = self.frame();
        let (o, i) = (frame.to_local(wo), frame.to_local(wi));
        (wo.z > 0.0 && wi.z > 0.0 && o.z > 0.0 && i.z > 0.0).then_some((o, i))
    }

    /// The microfacet term `D G2 / (4 |wo·nc| |wi·nc|)` (without the blend weight; 0 for a mirror coat),
    /// times `(wi·nc)/(wi·n)`: the integrator weighs every lobe by the cosine to the shading normal `n`, and
    /// this makes the coat's contribution the one its own cosine gives (as Cycles evaluates each closure with
    /// its own normal), so a tilted coat normal never adds energy.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_delta() {
            return 0.0;
        }
        let Some((o, i)) = self.local(wo, wi) else {
            return 0.0;
        };
        let h = (o + i).normalize();
        let ggx = Ggx::isotropic(self.alpha);
        ggx.d(h) * ggx.g2(o, i) / (4.0 * o.z * wi.z)
    }

    /// Density of [`Clearcoat::sample`]: visible normals reflected, `D_wo(h) / (4 wo·h)` in the coat's frame
    /// (Heitz 2018; Walter et al. 2007, eq. 14). Directions below the base or the coat have density 0.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_delta() {
            return 0.0;
        }
        let Some((o, i)) = self.local(wo, wi) else {
            return 0.0;
        };
        let h = (o + i).normalize();
        Ggx::isotropic(self.alpha).pdf_visible(o, h) / (4.0 * o.dot(h))
    }

    /// Samples a reflected direction: a visible GGX normal, or the coat normal itself for a mirror coat.
    /// `None` when the direction falls below the base or the coat.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<Vec3> {
        let frame = self.frame();
        let o = frame.to_local(wo);
        if o.z <= 0.0 {
            return None;
        }
        let h = if self.is_delta() {
            Vec3::Z
        } else {
            Ggx::isotropic(self.alpha).sample_visible(o, u)
        };
        let i = reflect(o, h);
        let wi = frame.to_world(i);
        (wi.z > 0.0 && i.z > 0.0).then_some(wi)
    }
}
