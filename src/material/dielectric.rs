//! A dielectric interface that reflects and refracts: smooth (delta lobes picked by exact Fresnel) or rough
//! (Walter et al. 2007, "Microfacet Models for Refraction through Rough Surfaces", with GGX and visible-normal
//! sampling).
//!
//! glTF: `KHR_materials_transmission.transmissionFactor` selects it, `KHR_materials_ior.ior` is the index
//! (default 1.5), `roughnessFactor`² is the GGX α and `baseColorFactor` tints the transmitted light.
//! Reflection uses the exact Fresnel term and is untinted; `KHR_materials_specular` does not apply here.
//! `KHR_materials_iridescence` puts a thin film on the outside of the interface: for light arriving from
//! outside, the Fresnel term F becomes `mix(F, R_film, weight)` per channel ([`ThinFilm::fresnel`], substrate
//! `F0 = ((ior − 1)/(ior + 1))²`), the reflection weighted by it and the refraction by `1 − F` (the extension
//! replaces the F of `fresnel_mix`, whose base holds the transmission's `specular_btdf`). The lobe is then
//! picked with the channels' mean of F. From inside, the interface is bare (the film's model assumes air
//! above it).
//!
//! Multiple scattering: the single-scattering model of Walter et al. loses the light that scatters more than
//! once between microfacets (at roughness 1 and index 1.5, about 30% of it from outside and up to 56% from
//! inside, by the tables' `E`). A rough interface compensates in
//! the spirit of Turquin 2019, "Practical multiple scattering compensation for microfacet models" (the BSDF
//! scaled by the inverse of its single-scattering directional albedo `E(μ) = ∫ (f_r + η² f_t) |cos θi| dωi`,
//! tabulated over cos θ, α and η separately for the two sides: `material/dielectric_albedo`), so that the
//! lossless interface passes the white furnace, `∫ (f_r + η² f_t) |cos θi| dωi = 1`, from both sides. From
//! outside (the thinner side), the reflection is scaled by `1/√(E(μo) E(μi))`, which keeps it reciprocal,
//! and the refraction by the tabulated `t(μo)` that closes the energy balance (about `1/E(μo)`). From inside,
//! both are scaled by `1/E(μo)` as in Turquin's paper: there `E` changes so steeply across the critical
//! angle that the symmetric scaling overshoots (the scaled reflection alone carried more than all the energy
//! at some angles), so the reflection inside is not exactly reciprocal. Sampling is unchanged (the
//! single-scattering visible-normal sampler); only the values, and so the sample weights, grow. The tables
//! leave out the thin film (an iridescent rough interface is compensated as if bare) and clamp indices above
//! 3 to 3. A smooth interface is untouched.
//!
//! Conventions: the surface is a solid interface with index `ior` below (z < 0) and 1 above. `wo` and `wi`
//! point away from the surface; `wo.z < 0` means the ray arrives from inside. Refraction carries radiance, so
//! it includes the factor 1/η² with η = η(wi side)/η(wo side) (Veach 1997, §5.2): camera paths only.

use super::dielectric_albedo;
use super::fresnel;
use super::lobes::{LobeClass, LobeSplit};
use super::microfacet::{Ggx, DELTA_ALPHA};
use super::thin_film::ThinFilm;
use crate::math::{Rgb, Vec2, Vec3};

/// A direction chosen by [`Dielectric::sample`]: the direction, its lobe's class (reflection glossy,
/// refraction transmission), the relative index it crossed, whether it is a delta lobe and, for delta lobes
/// only, the BSDF value and the discrete lobe probability.
#[derive(Clone, Copy, Debug)]
pub(super) struct DielectricSample {
    pub wi: Vec3,
    pub class: LobeClass,
    /// η = η(wi side)/η(wo side) for a refraction (whose value carries 1/η²), 1 for a reflection.
    pub eta: f32,
    /// Delta lobes: (f, probability). Non-delta: `None`, evaluate with `eval`/`pdf`.
    pub delta: Option<(Rgb, f32)>,
}

/// Dielectric interface between the outside (index 1, above) and a solid of index `ior` (below).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Index of refraction of the solid below the surface.
    pub ior: f32,
    /// GGX α of the interface; below [`DELTA_ALPHA`] it is smooth.
    pub alpha: f32,
    /// Colour multiplying the transmitted light (glTF base colour).
    pub tint: Rgb,
    /// The thin film on the outside of the interface (`KHR_materials_iridescence`), if any.
    pub film: Option<ThinFilm>,
}

/// Mean of the channels of a colour: the probability of picking a lobe weighted by a coloured Fresnel term.
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// Mirrors a direction pair so that `wo` is above the surface, and returns the relative index
/// η = η(far side)/η(wo's side).
fn orient(ior: f32, wo: Vec3, wi: Vec3) -> (Vec3, Vec3, f32) {
    if wo.z < 0.0 {
        (-wo, -wi, 1.0 / ior)
    } else {
        (wo, wi, ior)
    }
}

impl Dielectric {
    /// The Fresnel reflectance per channel at `cos = wo·h` (with `wo` mirrored above), η = η(far side)/η(wo's
    /// side): the exact term, under the film when there is one and `wo` arrives from outside (η = ior).
    fn reflectance(&self, cos: f32, eta: f32, outside: bool) -> Rgb {
        let f = Rgb::splat(fresnel::dielectric(cos, eta));
        match self.film {
            Some(film) if outside => {
                let r = (self.ior - 1.0) / (self.ior + 1.0);
                film.fresnel(f, cos, Rgb::splat(r * r))
                    .clamp(Rgb::ZERO, Rgb::ONE)
            }
            _ => f,
        }
    }

    /// True when the interface is a delta BSDF: α below [`DELTA_ALPHA`], or the indices match (then the
    /// microfacets refract nothing and every roughness is invisible).
    pub fn is_smooth(&self) -> bool {
        self.alpha < DELTA_ALPHA || (self.ior - 1.0).abs() < 1e-6
    }

    /// Rough-interface BSDF value (0 for a smooth one): the single-scattering value
    /// (`Dielectric::eval_single_scattering`) with the multiple-scattering compensation of the module
    /// documentation (reflection and refraction scaled by `dielectric_albedo::reflection_scale` and
    /// `dielectric_albedo::refraction_scale`).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let single = self.eval_single_scattering(wo, wi);
        if single == Rgb::ZERO {
            return single;
        }
        let (wo_up, wi_up, eta) = orient(self.ior, wo, wi);
        let scale = if wi_up.z > 0.0 {
            dielectric_albedo::reflection_scale(wo_up.z, wi_up.z, self.alpha, eta)
        } else {
            dielectric_albedo::refraction_scale(wo_up.z, self.alpha, eta)
        };
        single * scale
    }

    /// Single-scattering rough-interface BSDF value (0 for a smooth one). With the pair mirrored so that `wo`
    /// is above, η the index of `wi`'s side over `wo`'s, and
    /// `h` the (generalised) half vector: reflection `F D G2 / (4 |wo.z| |wi.z|)` (Walter et al. 2007, eqs. 13
    /// and 20); transmission `|wi·h| |wo·h| (1 − F) D G2 / (|wi.z| |wo.z| (η wi·h + wo·h)²)` (eqs. 16 and 21
    /// with η_o = 1, η_i = η), times the tint. F is the exact Fresnel term at `wo·h`.
    pub(super) fn eval_single_scattering(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if self.is_smooth() || wo.z == 0.0 || wi.z == 0.0 {
            return Rgb::ZERO;
        }
        let outside = wo.z > 0.0;
        let (wo, wi, eta) = orient(self.ior, wo, wi);
        let ggx = Ggx::isotropic(self.alpha);
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            let f = self.reflectance(wo.dot(h), eta, outside);
            return f * (ggx.d(h) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z));
        }
        let Some(h) = transmission_half_vector(wo, wi, eta) else {
            return Rgb::ZERO;
        };
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        let f = self.reflectance(oh, eta, outside);
        let denom = eta * ih + oh;
        let value =
            (ih * oh).abs() * ggx.d(h) * ggx.g2(wo, wi) / ((wi.z * wo.z).abs() * denom * denom);
        self.tint * (Rgb::ONE - f) * value
    }

    /// [`Dielectric::eval`] split by class: reflection (`wi` on `wo`'s side) is glossy, refraction
    /// transmission, from either side.
    pub fn eval_split(&self, wo: Vec3, wi: Vec3) -> LobeSplit {
        let class = if (wo.z > 0.0) == (wi.z > 0.0) {
            LobeClass::Glossy
        } else {
            LobeClass::Transmission
        };
        LobeSplit::only(class, self.eval(wo, wi))
    }

    /// The class colours seen from `wo` (zero when `wo` is tangent): glossy `R`, transmission
    /// `tint (1 − R) / η²` with η = η(far side)/η(wo's side). These are the directional albedos of the
    /// reflection and of the refraction (whose weight carries the radiance factor 1/η², see the module
    /// documentation) when `R` is the interface's reflectance. Smooth: `R = F(|cos θo|)`, exact (under the film
    /// from outside: [`Dielectric::eval`]'s term). Rough: an
    /// estimate, `R = (1 − α) F(|cos θo|) + α F̄` with F̄ the hemispherical average reflectance
    /// (`fresnel::dielectric_average`): the rougher the interface, the more microfacet angles it averages
    /// over. `F̄ < 1` keeps the refraction's colour positive past the critical angle, where tilted microfacets
    /// still refract. `R` plus the refraction's `(1 − R)` is 1, as the compensated interface's albedo is.
    pub fn colors(&self, wo: Vec3) -> LobeSplit {
        if wo.z == 0.0 {
            return LobeSplit::ZERO;
        }
        let (wo_up, _, eta) = orient(self.ior, wo, Vec3::Z);
        let mut r = self.reflectance(wo_up.z, eta, wo.z > 0.0);
        if !self.is_smooth() {
            r += (Rgb::splat(fresnel::dielectric_average(eta)) - r) * self.alpha;
        }
        LobeSplit {
            glossy: r,
            transmission: self.tint * (Rgb::ONE - r) / (eta * eta),
            ..LobeSplit::ZERO
        }
    }

    /// Solid-angle density of the non-delta directions of its sampler (0 for a smooth interface):
    /// the visible-normal density times the lobe probability (the channels' mean of F, or 1 − it) times the
    /// half-vector Jacobian,
    /// `1/(4 |wo·h|)` for reflection (Walter et al. 2007, eq. 14) and `η² |wi·h| / (η wi·h + wo·h)²` for
    /// transmission (eq. 17).
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.is_smooth() || wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let outside = wo.z > 0.0;
        let (wo, wi, eta) = orient(self.ior, wo, wi);
        let ggx = Ggx::isotropic(self.alpha);
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            let oh = wo.dot(h);
            let p_reflect = mean(self.reflectance(oh, eta, outside));
            return p_reflect * ggx.pdf_visible(wo, h) / (4.0 * oh);
        }
        let Some(h) = transmission_half_vector(wo, wi, eta) else {
            return 0.0;
        };
        let (oh, ih) = (wo.dot(h), wi.dot(h));
        let denom = eta * ih + oh;
        let p_refract = 1.0 - mean(self.reflectance(oh, eta, outside));
        p_refract * ggx.pdf_visible(wo, h) * eta * eta * ih.abs() / (denom * denom)
    }

    /// Samples the interface. Smooth: reflection with probability P = mean(F(|wo.z|)) (exact Fresnel, under
    /// the film from outside), else refraction by Snell's law; f is `F/|cos|` or `tint (1 − F) / (η² |cos|)`,
    /// so the weight `f |cos| / pdf` is `F/P` or `tint (1 − F) / (η² (1 − P))` (1 and `tint / η²` without a
    /// film). Rough: a visible normal `h` (Heitz 2018), then reflection about `h` with probability
    /// mean(F(wo·h)), else refraction through `h`; `None` when the direction ends on the wrong side.
    pub(super) fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<DielectricSample> {
        if wo.z == 0.0 {
            return None;
        }
        let (sign, outside) = (wo.z.signum(), wo.z > 0.0);
        let (wo_up, _, eta) = orient(self.ior, wo, Vec3::Z);
        if self.is_smooth() {
            let f = self.reflectance(wo_up.z, eta, outside);
            let p_reflect = mean(f);
            if u_lobe < p_reflect {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                return Some(DielectricSample {
                    wi,
                    class: LobeClass::Glossy,
                    eta: 1.0,
                    delta: Some((f / wi.z.abs(), p_reflect)),
                });
            }
            let wi = fresnel::refract(wo_up, Vec3::Z, eta)? * sign;
            let value = self.tint * (Rgb::ONE - f) / (eta * eta * wi.z.abs());
            return Some(DielectricSample {
                wi,
                class: LobeClass::Transmission,
                eta,
                delta: Some((value, 1.0 - p_reflect)),
            });
        }
        let h = Ggx::isotropic(self.alpha).sample_visible(wo_up, u);
        let oh = wo_up.dot(h);
        if oh <= 0.0 {
            return None;
        }
        let (wi_up, class, crossed) = if u_lobe < mean(self.reflectance(oh, eta, outside)) {
            let wi = Some(fresnel::reflect(wo_up, h)).filter(|w| w.z > 0.0);
            (wi, LobeClass::Glossy, 1.0)
        } else {
            let wi = fresnel::refract(wo_up, h, eta).filter(|w| w.z < 0.0);
            (wi, LobeClass::Transmission, eta)
        };
        Some(DielectricSample {
            wi: wi_up? * sign,
            class,
            eta: crossed,
            delta: None,
        })
    }
}

/// The generalised half vector of a refraction pair (Walter et al. 2007, eq. 16) oriented to +z, with `wo`
/// above and index ratio η; `None` when the pair cannot come from one microfacet (the side conditions
/// `wo·h > 0 > wi·h`).
fn transmission_half_vector(wo: Vec3, wi: Vec3, eta: f32) -> Option<Vec3> {
    let h = (wo + eta * wi).try_normalize()?;
    let h = if h.z < 0.0 { -h } else { h };
    (wo.dot(h) > 0.0 && wi.dot(h) < 0.0).then_some(h)
}
