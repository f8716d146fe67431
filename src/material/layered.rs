//! The glTF metallic-roughness BSDF with the layers of `KHR_materials_sheen` and `KHR_materials_clearcoat`
//! on top, in the order the extensions define: sheen over the base, the coat over both
//! (`KHR_materials_sheen`, "the clearcoat is layered on top of sheen").
//!
//! For `wo` above the surface:
//! `f = (1 − b(wo)) · (f_sheen + s(wo, wi) · f_base) + b(wo) · f_coat`, with `b = c·F(wo·nc)` the coat's blend
//! weight ([`Clearcoat`]) and `s` the sheen's albedo scaling ([`Sheen`]). From below (inside a transmissive
//! base) only the base scatters. Emission is not darkened by the coat (see [`crate::material::Material`]).
//!
//! Sampling picks the coat, the sheen or the base with probabilities from their albedos seen from `wo`, each
//! kept within \[0.05, 0.95\] so that no lobe is starved; non-delta samples carry the full mixture's value and
//! density, so that MIS with light sampling sees one BSDF.

use super::clearcoat::Clearcoat;
use super::gltf_pbr::GltfPbr;
use super::lobes::{LobeClass, LobeSplit};
use super::sample::BsdfSample;
use super::sheen::Sheen;
use crate::math::sampling::{cosine_hemisphere, cosine_hemisphere_pdf};
use crate::math::{Rgb, Vec2, Vec3};

/// A base glTF BSDF with an optional sheen and an optional clear coat.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layered {
    /// The metallic-roughness base (with its transmission, if any).
    pub base: GltfPbr,
    /// The sheen layer, if `sheenColorFactor` × texture is non-zero.
    pub sheen: Option<Sheen>,
    /// The clear coat, if `clearcoatFactor` × texture is non-zero.
    pub coat: Option<Clearcoat>,
}

/// Lobe-selection probabilities for one `wo`.
struct Choice {
    coat: f32,
    sheen: f32,
    base: f32,
}

impl Layered {
    /// The coat's blend weight `b(wo)` (0 without a coat or from below).
    fn blend(&self, wo: Vec3) -> f32 {
        match self.coat {
            Some(c) if wo.z > 0.0 => c.blend(wo),
            _ => 0.0,
        }
    }

    /// The sheen's scaling of the base for (wo, wi) (1 without a sheen).
    fn scaling(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.sheen.map_or(1.0, |s| s.albedo_scaling(wo.z, wi.z))
    }

    /// Lobe probabilities from the albedos seen from `wo`: `b` for the coat against the base's largest
    /// reflectance weighted by `1 − b`, then the sheen's albedo against the base's.
    fn choice(&self, wo: Vec3) -> Choice {
        if wo.z <= 0.0 {
            return Choice {
                coat: 0.0,
                sheen: 0.0,
                base: 1.0,
            };
        }
        let base_weight = self.base.base_color.max_element().max(0.05);
        let split = |layer: f32| {
            if layer + base_weight > 0.0 {
                (layer / (layer + (1.0 - layer) * base_weight)).clamp(0.05, 0.95)
            } else {
                0.5
            }
        };
        let coat = self.coat.map_or(0.0, |_| split(self.blend(wo)));
        let sheen = self.sheen.map_or(0.0, |s| split(s.albedo(wo)));
        Choice {
            coat,
            sheen: (1.0 - coat) * sheen,
            base: (1.0 - coat) * (1.0 - sheen),
        }
    }

    /// True when every lobe is a delta distribution.
    pub fn is_delta(&self) -> bool {
        self.base.is_delta() && self.sheen.is_none() && self.coat.is_none_or(|c| c.is_delta())
    }

    /// BSDF value of the non-delta lobes.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let base = self.base.eval(wo, wi);
        if wo.z <= 0.0 {
            return base;
        }
        let mut f = base * self.scaling(wo, wi);
        if let Some(s) = self.sheen {
            f += s.eval(wo, wi);
        }
        if let Some(c) = self.coat {
            let b = c.blend(wo);
            f = f * (1.0 - b) + Rgb::splat(b * c.eval(wo, wi));
        }
        f
    }

    /// [`Layered::eval`] split by class: the base's classes ([`GltfPbr::eval_split`]) scaled as in `eval`; the
    /// sheen and the coat are glossy.
    pub fn eval_split(&self, wo: Vec3, wi: Vec3) -> LobeSplit {
        let base = self.base.eval_split(wo, wi);
        if wo.z <= 0.0 {
            return base;
        }
        let mut split = base * self.scaling(wo, wi);
        if let Some(s) = self.sheen {
            split.glossy += s.eval(wo, wi);
        }
        if let Some(c) = self.coat {
            let b = c.blend(wo);
            split = split * (1.0 - b);
            split.glossy += Rgb::splat(b * c.eval(wo, wi));
        }
        split
    }

    /// The class colours seen from `wo` above the surface, `(1 − b)(s · base + sheen) + b · coat` as in
    /// `eval`, with `b` = `b(wo)` the coat's blend weight:
    /// - the base's colours ([`GltfPbr::colors`]) times `s = 1 − max(sheenColor) E(cos θo)`, the sheen's
    ///   scaling `1 − max(sheenColor) max(E(cos θo), E(cos θi))` at its largest, reached where
    ///   `E(cos θi) ≤ E(cos θo)` (the mirror direction among others): exact for a mirror base, an upper
    ///   bound otherwise;
    /// - glossy: the sheen's albedo `sheenColor · E(cos θo)` (tabulated, [`Sheen::directional_albedo`]) and
    ///   the coat's `b`, the exact albedo of a mirror coat; a rough coat's masking loss is left out.
    ///
    /// From below only the base scatters: its colours.
    pub fn colors(&self, wo: Vec3) -> LobeSplit {
        let base = self.base.colors(wo);
        if wo.z <= 0.0 {
            return base;
        }
        let mut colors = base;
        if let Some(s) = self.sheen {
            let e = s.directional_albedo(wo.z);
            colors = colors * (1.0 - s.color.max_element() * e).max(0.0);
            colors.glossy += s.color * e;
        }
        if let Some(c) = self.coat {
            let b = c.blend(wo);
            colors = colors * (1.0 - b);
            colors.glossy += Rgb::splat(b);
        }
        colors
    }

    /// Solid-angle density of the non-delta directions of [`Layered::sample`].
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p = self.choice(wo);
        let mut pdf = p.base * self.base.pdf(wo, wi);
        if let Some(c) = self.coat {
            pdf += p.coat * c.pdf(wo, wi);
        }
        if self.sheen.is_some() && wo.z > 0.0 && wi.z > 0.0 {
            pdf += p.sheen * cosine_hemisphere_pdf(wi.z);
        }
        pdf
    }

    /// Picks the coat, the sheen or the base with `u_lobe` and samples it with `u`. Delta samples (a mirror
    /// coat, a smooth base) carry their lobe's weighted value and discrete probability.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return self.base.sample(wo, u_lobe, u);
        }
        let p = self.choice(wo);
        let (wi, class, eta) = if u_lobe < p.coat {
            let c = self.coat?;
            let wi = c.sample(wo, u)?;
            if c.is_delta() {
                return Some(BsdfSample {
                    wi,
                    f: Rgb::splat(c.blend(wo) / wi.z),
                    pdf: p.coat,
                    is_delta: true,
                    class: LobeClass::Glossy,
                    eta: 1.0,
                });
            }
            (wi, LobeClass::Glossy, 1.0)
        } else if u_lobe < p.coat + p.sheen {
            let wi = cosine_hemisphere(u);
            if wi.z <= 0.0 {
                return None;
            }
            (wi, LobeClass::Glossy, 1.0)
        } else {
            let u_base = ((u_lobe - p.coat - p.sheen) / p.base).clamp(0.0, 1.0 - f32::EPSILON);
            let s = self.base.sample(wo, u_base, u)?;
            if s.is_delta {
                let layers = (1.0 - self.blend(wo)) * self.scaling(wo, s.wi);
                return Some(BsdfSample {
                    f: s.f * layers,
                    pdf: s.pdf * p.base,
                    ..s
                });
            }
            (s.wi, s.class, s.eta)
        };
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.eval(wo, wi),
            pdf,
            is_delta: false,
            class,
            eta,
        })
    }
}
