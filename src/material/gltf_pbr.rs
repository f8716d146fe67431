//! The glTF 2.0 metallic-roughness BRDF (glTF 2.0 specification, Appendix B) with `KHR_materials_specular`,
//! `KHR_materials_ior` and `KHR_materials_transmission` (the sheen and clear-coat layers over it are in
//! [`super::Layered`]).
//!
//! glTF keys read (through [`PbrParams`]): `baseColorFactor`, `metallicFactor`, `roughnessFactor`
//! (α = roughness²), `KHR_materials_ior.ior` (default 1.5), `KHR_materials_specular.specularFactor` (default 1)
//! and `specularColorFactor` (default \[1, 1, 1\]), `KHR_materials_transmission.transmissionFactor` (default 0).
//!
//! The opaque part is `mix(dielectric_brdf, metal_brdf, metallic)` where
//! - `dielectric_brdf = (1 − s·max(F_d)) · base/π + s·F_d · specular`, with `F_d` Schlick's Fresnel at `wo·h` with
//!   `f0 = min(((ior − 1)/(ior + 1))² · specularColor, 1)` and `s = specularFactor` (KHR_materials_specular);
//! - `metal_brdf = F_m · specular`, `F_m` Schlick's Fresnel with `f0 = baseColor`;
//! - `specular = D G2 / (4 |wo.z| |wi.z|)`, GGX with the height-correlated Smith G2, or a delta mirror when α is
//!   below [`DELTA_ALPHA`].
//!
//! `KHR_materials_anisotropy` makes the specular reflection (dielectric specular and metal) an anisotropic GGX:
//! with `s` the strength and α = roughness², the width along the anisotropy direction is
//! `α_t = mix(α, 1, s²)` and across it `α_b = α` (the formulas of the extension's specification), the anisotropy
//! direction being [`PbrParams::anisotropy_direction`] in the shading frame's tangent plane. The transmissive
//! interface, the clear coat and the colour estimates keep the isotropic α.
//!
//! The transmissive part is a [`Dielectric`] interface tinted by the base colour. Metals do not transmit, so the
//! BSDF is `(1 − t)·opaque + t·dielectric` with `t = transmission · (1 − metallic)`. The specification's
//! material is `mix(dielectric_brdf, metal_brdf, metallic)` with the transmission inside the dielectric's base
//! (`mix(diffuse_brdf, specular_btdf, transmission)`, KHR_materials_transmission): the metal keeps its weight
//! `metallic` and the opaque dielectric gets `(1 − metallic)(1 − transmission)`. The opaque part therefore
//! mixes its dielectric and its metal by the share `m = metallic / (1 − t)` ([`GltfPbr::metallic`]), not by
//! `metallic` itself.
//!
//! `KHR_materials_diffuse_transmission` (`diffuseTransmissionFactor` × `diffuseTransmissionTexture` (A) = `dt`,
//! `diffuseTransmissionColorFactor` × `diffuseTransmissionColorTexture` (RGB) = `c_dt`) replaces the diffuse
//! base of `dielectric_brdf` by `mix(diffuse_brdf(baseColor), diffuse_btdf(c_dt), dt)` (the extension's
//! normative `dielectric_brdf`): `(1 − dt)·baseColor/π` toward `wo`'s hemisphere and a Lambertian
//! transmission `dt·c_dt/π` into the opposite one, both under the same Fresnel weight `kd`. For the
//! transmitted pair `kd` is taken at the half vector of `wo` and `wi` mirrored through the surface
//! (`(wi.x, wi.y, −wi.z)`), which keeps the lobe reciprocal; the specular layer is unchanged, and
//! `KHR_materials_transmission` overrides it as the extension says (its weight `t` scales the whole opaque
//! part). Like the rest of the opaque part the lobe scatters only light arriving from above (`wo.z > 0`):
//! the integrator turns the frame of a thin-walled surface toward the arriving light.
//!
//! `KHR_materials_iridescence` replaces both Schlick terms (dielectric `F_d`, metal `F_m`) by
//! `mix(F, R_film, weight)`, the reflectance of a thin film over the specular layer ([`ThinFilm`]); `kd`
//! follows, since it is computed from `F_d`. The transmissive part's exact Fresnel term is mixed the same way
//! (see [`Dielectric`]).

use super::dielectric::Dielectric;
use super::fresnel;
use super::lobes::{LobeClass, LobeSplit};
use super::microfacet::{Ggx, DELTA_ALPHA};
use super::sample::BsdfSample;
use super::thin_film::ThinFilm;
use crate::math::sampling::cosine_hemisphere;
use crate::math::{Rgb, Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

/// Material parameters of the glTF 2.0 metallic-roughness model and the extensions Nimbus reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PbrParams {
    /// `baseColorFactor` × texture, linear RGB. Default 1.
    pub base_color: Rgb,
    /// `metallicFactor` × texture, in \[0, 1\]. Default 1.
    pub metallic: f32,
    /// Perceptual `roughnessFactor` × texture; the GGX α is its square. Default 1.
    pub roughness: f32,
    /// `KHR_materials_ior.ior`. Default 1.5.
    pub ior: f32,
    /// `KHR_materials_specular.specularFactor`. Default 1.
    pub specular_factor: f32,
    /// `KHR_materials_specular.specularColorFactor`. Default 1.
    pub specular_color: Rgb,
    /// `KHR_materials_transmission.transmissionFactor`. Default 0.
    pub transmission: f32,
    /// `KHR_materials_clearcoat.clearcoatFactor` × texture. Default 0 (no coat).
    pub clearcoat: f32,
    /// `KHR_materials_clearcoat.clearcoatRoughnessFactor` × texture. Default 0.
    pub clearcoat_roughness: f32,
    /// `KHR_materials_sheen.sheenColorFactor` × texture. Default 0 (no sheen).
    pub sheen_color: Rgb,
    /// `KHR_materials_sheen.sheenRoughnessFactor` × texture. Default 0.
    pub sheen_roughness: f32,
    /// `KHR_materials_anisotropy.anisotropyStrength` × the anisotropy texture's blue channel, in \[0, 1\].
    /// Default 0 (isotropic).
    pub anisotropy_strength: f32,
    /// The anisotropy direction in the shading frame's tangent plane, `(cos, sin)` of its angle from the
    /// tangent toward the bitangent: the texture's RG direction (or `(1, 0)`) rotated counter-clockwise by
    /// `anisotropyRotation`. Need not be unit length; a zero or non-finite direction means the tangent.
    /// Default `(1, 0)`.
    pub anisotropy_direction: Vec2,
    /// `KHR_materials_diffuse_transmission.diffuseTransmissionFactor` × the texture's alpha, in \[0, 1\]: the
    /// share of the diffuse base that is transmitted. Default 0.
    pub diffuse_transmission: f32,
    /// `diffuseTransmissionColorFactor` × `diffuseTransmissionColorTexture`, linear RGB. Default 1.
    pub diffuse_transmission_color: Rgb,
    /// `KHR_materials_iridescence.iridescenceFactor` × the texture's red channel, in \[0, 1\]. Default 0 (no
    /// film).
    pub iridescence: f32,
    /// `iridescenceIor`: the film's index. Default 1.3.
    pub iridescence_ior: f32,
    /// The film's thickness in nanometres: `mix(iridescenceThicknessMinimum, iridescenceThicknessMaximum,
    /// texture G)`, the maximum without the texture. Default 400.
    pub iridescence_thickness: f32,
}

impl Default for PbrParams {
    /// The glTF 2.0 defaults: white, fully metallic, fully rough, ior 1.5, specular 1, no transmission.
    fn default() -> Self {
        Self {
            base_color: Rgb::ONE,
            metallic: 1.0,
            roughness: 1.0,
            ior: 1.5,
            specular_factor: 1.0,
            specular_color: Rgb::ONE,
            transmission: 0.0,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Rgb::ZERO,
            sheen_roughness: 0.0,
            anisotropy_strength: 0.0,
            anisotropy_direction: Vec2::X,
            diffuse_transmission: 0.0,
            diffuse_transmission_color: Rgb::ONE,
            iridescence: 0.0,
            iridescence_ior: 1.3,
            iridescence_thickness: 400.0,
        }
    }
}

/// The glTF metallic-roughness BSDF: the opaque BRDF of the module documentation, mixed with a dielectric
/// interface by the effective transmission weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfPbr {
    /// Base colour (diffuse albedo, metal f0 and transmission tint).
    pub base_color: Rgb,
    /// The metal's share of the opaque part, in \[0, 1\]: `metallic / (1 − t)` with `t` the effective
    /// transmission weight (`metallic` itself without transmission), so that the metal's weight in the whole
    /// BSDF is `metallic`.
    pub metallic: f32,
    /// `specularFactor`.
    pub specular_factor: f32,
    /// Dielectric f0: `min(((ior − 1)/(ior + 1))² · specularColor, 1)`.
    pub f0: Rgb,
    /// Isotropic GGX α = roughness²: the transmissive interface's, and the colour estimates'.
    pub alpha: f32,
    /// The GGX of the specular reflection lobes in the anisotropy frame (x along the anisotropy direction):
    /// `(α_t, α_b)` of `KHR_materials_anisotropy`, `(α, α)` without anisotropy.
    pub specular: Ggx,
    /// Unit anisotropy direction `(cos φ, sin φ)` in the shading frame's tangent plane; `(1, 0)` without
    /// anisotropy.
    pub anisotropy_direction: Vec2,
    /// Effective transmission weight `transmission · (1 − metallic)`, in \[0, 1).
    pub transmission: f32,
    /// The transmissive interface (ior, α, tint = base colour).
    pub dielectric: Dielectric,
    /// The share `dt` of the diffuse base transmitted (`KHR_materials_diffuse_transmission`), in \[0, 1\].
    pub diffuse_transmission: f32,
    /// The colour `c_dt` of the diffuse transmission.
    pub diffuse_transmission_color: Rgb,
    /// The thin film over the specular layer (`KHR_materials_iridescence`), if any.
    pub film: Option<ThinFilm>,
}

/// Largest channel of a colour.
fn max_component(c: Rgb) -> f32 {
    c.x.max(c.y).max(c.z)
}

/// Mean of the channels of a colour.
fn mean(c: Rgb) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl GltfPbr {
    /// Builds the BSDF from glTF parameters (clamped to their valid ranges).
    pub fn new(p: &PbrParams) -> Self {
        let ior = p.ior.max(1.0);
        let metallic = p.metallic.clamp(0.0, 1.0);
        let roughness = p.roughness.clamp(0.0, 1.0);
        let alpha = roughness * roughness;
        let r = (ior - 1.0) / (ior + 1.0);
        let base_color = p.base_color.max(Rgb::ZERO);
        let (specular, anisotropy_direction) = anisotropic_specular(alpha, p);
        let transmission = p.transmission.clamp(0.0, 1.0) * (1.0 - metallic);
        let film = ThinFilm::new(p.iridescence, p.iridescence_ior, p.iridescence_thickness);
        Self {
            base_color,
            metallic: opaque_metal_share(metallic, transmission),
            specular_factor: p.specular_factor.clamp(0.0, 1.0),
            f0: (r * r * p.specular_color.max(Rgb::ZERO)).min(Rgb::ONE),
            alpha,
            specular,
            anisotropy_direction,
            transmission,
            dielectric: Dielectric {
                ior,
                alpha,
                tint: base_color,
                film,
            },
            diffuse_transmission: if p.diffuse_transmission.is_nan() {
                0.0
            } else {
                p.diffuse_transmission.clamp(0.0, 1.0)
            },
            diffuse_transmission_color: if p.diffuse_transmission > 0.0 {
                p.diffuse_transmission_color.max(Rgb::ZERO)
            } else {
                Rgb::ONE
            },
            film,
        }
    }

    /// The diffuse reflection albedo `(1 − dt)·baseColor` and transmission albedo `dt·c_dt` of the diffuse base
    /// (before the Fresnel weight `kd`).
    fn diffuse_albedos(&self) -> (Rgb, Rgb) {
        let dt = self.diffuse_transmission;
        (
            (1.0 - dt) * self.base_color,
            dt * self.diffuse_transmission_color,
        )
    }

    /// Probability that a sample of the diffuse base is transmitted: the transmission's share of the two
    /// albedos' means (0 without diffuse transmission).
    fn diffuse_transmission_probability(&self) -> f32 {
        if self.diffuse_transmission <= 0.0 {
            return 0.0;
        }
        let (reflected, transmitted) = self.diffuse_albedos();
        let (r, t) = (mean(reflected), mean(transmitted));
        if r + t > 0.0 {
            t / (r + t)
        } else {
            0.0
        }
    }

    /// True when the specular lobes are delta mirrors (`α_t ≥ α_b`, so the wider width decides).
    fn specular_is_delta(&self) -> bool {
        self.specular.alpha_x < DELTA_ALPHA
    }

    /// A shading-frame direction in the anisotropy frame: rotated by −φ about the normal so that the
    /// anisotropy direction becomes x. The identity, exactly, for the direction `(1, 0)`.
    fn anisotropy_local(&self, v: Vec3) -> Vec3 {
        let (c, s) = (self.anisotropy_direction.x, self.anisotropy_direction.y);
        Vec3::new(c * v.x + s * v.y, c * v.y - s * v.x, v.z)
    }

    /// The inverse of [`GltfPbr::anisotropy_local`].
    fn shading_local(&self, v: Vec3) -> Vec3 {
        let (c, s) = (self.anisotropy_direction.x, self.anisotropy_direction.y);
        Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
    }

    /// True when the diffuse base (reflection or transmission) can be non-zero.
    fn has_diffuse(&self) -> bool {
        let (reflected, transmitted) = self.diffuse_albedos();
        let albedo = if self.diffuse_transmission > 0.0 {
            max_component(reflected).max(max_component(transmitted))
        } else {
            max_component(self.base_color)
        };
        self.metallic < 1.0 && self.transmission < 1.0 && albedo > 0.0
    }

    /// True when the specular reflection lobe can be non-zero.
    fn has_specular(&self) -> bool {
        self.metallic > 0.0 || self.specular_factor > 0.0
    }

    /// True when every lobe is a delta distribution.
    pub fn is_delta(&self) -> bool {
        let opaque_delta = !self.has_diffuse() && self.specular_is_delta();
        opaque_delta && (self.transmission == 0.0 || self.dielectric.is_smooth())
    }

    /// The Fresnel weights of the opaque part at `cos = wo·h`: the scalar weight of the diffuse base,
    /// `(1 − metallic)(1 − s·max(F_d))`, and the colour of the specular layer, `(1 − metallic) s F_d + metallic F_m`
    /// (glTF 2.0 Appendix B `fresnel_mix` and `conductor_fresnel`, with KHR_materials_specular).
    fn fresnel_weights(&self, cos: f32) -> (f32, Rgb) {
        let mut f_d = fresnel::schlick(self.f0, cos);
        let mut f_m = fresnel::schlick(self.base_color, cos);
        if let Some(film) = self.film {
            f_d = film.fresnel(f_d, cos, self.f0);
            f_m = film.fresnel(f_m, cos, self.base_color);
        }
        let dielectric = 1.0 - self.metallic;
        let kd = dielectric * (1.0 - self.specular_factor * max_component(f_d));
        let ks = dielectric * self.specular_factor * f_d + self.metallic * f_m;
        (kd, ks)
    }

    /// Probability of sampling the diffuse lobe of the opaque part for `wo`, from the lobe weights at
    /// `cos = wo.z`, kept within \[0.05, 0.95\] when both lobes exist so that neither is ever starved.
    fn diffuse_probability(&self, wo: Vec3) -> f32 {
        match (self.has_diffuse(), self.has_specular()) {
            (true, false) => 1.0,
            (false, _) => 0.0,
            (true, true) => {
                let (kd, ks) = self.fresnel_weights(wo.z);
                let wd = if self.diffuse_transmission > 0.0 {
                    let (reflected, transmitted) = self.diffuse_albedos();
                    kd * (mean(reflected) + mean(transmitted))
                } else {
                    kd * mean(self.base_color)
                };
                let ws = mean(ks);
                if wd + ws > 0.0 {
                    (wd / (wd + ws)).clamp(0.05, 0.95)
                } else {
                    0.5
                }
            }
        }
    }

    /// Opaque BSDF value (non-delta part), one-sided, as its (diffuse reflection, specular, diffuse
    /// transmission) lobes; `None` unless `wo` is above the surface and `wi` above it, or below it with
    /// diffuse transmission.
    fn opaque_lobes(&self, wo: Vec3, wi: Vec3) -> Option<(Rgb, Rgb, Rgb)> {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return None;
        }
        let (reflected, transmitted) = self.diffuse_albedos();
        if wi.z < 0.0 {
            if self.diffuse_transmission <= 0.0 {
                return None;
            }
            let h = (wo + Vec3::new(wi.x, wi.y, -wi.z)).normalize();
            let (kd, _) = self.fresnel_weights(wo.dot(h));
            return Some((Rgb::ZERO, Rgb::ZERO, kd * FRAC_1_PI * transmitted));
        }
        let h = (wo + wi).normalize();
        let (kd, ks) = self.fresnel_weights(wo.dot(h));
        let diffuse = kd * FRAC_1_PI * reflected;
        if self.specular_is_delta() {
            return Some((diffuse, Rgb::ZERO, Rgb::ZERO));
        }
        let ggx = self.specular;
        let (o, i) = (self.anisotropy_local(wo), self.anisotropy_local(wi));
        let m = self.anisotropy_local(h);
        Some((
            diffuse,
            ks * (ggx.d(m) * ggx.g2(o, i) / (4.0 * wo.z * wi.z)),
            Rgb::ZERO,
        ))
    }

    /// Opaque BSDF value (non-delta part), one-sided.
    fn eval_opaque(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.opaque_lobes(wo, wi)
            .map_or(Rgb::ZERO, |(diffuse, specular, transmitted)| {
                diffuse + specular + transmitted
            })
    }

    /// Density of the non-delta directions of the opaque sampler: `p_d (1 − q) cos θi/π + (1 − p_d)
    /// D_wo(h)/(4 wo·h)` above the surface (visible normals, Heitz 2018, with the reflection Jacobian of Walter
    /// et al. 2007, eq. 14) and `p_d q |cos θi|/π` below it, `q` the diffuse transmission's share of the diffuse
    /// samples.
    fn pdf_opaque(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let pd = self.diffuse_probability(wo);
        let q = self.diffuse_transmission_probability();
        if wi.z < 0.0 {
            return pd * q * -wi.z * FRAC_1_PI;
        }
        let mut pdf = pd * (1.0 - q) * wi.z * FRAC_1_PI;
        if !self.specular_is_delta() && pd < 1.0 {
            let h = (wo + wi).normalize();
            let (o, m) = (self.anisotropy_local(wo), self.anisotropy_local(h));
            pdf += (1.0 - pd) * self.specular.pdf_visible(o, m) / (4.0 * wo.dot(h));
        }
        pdf
    }

    /// Probability of sampling the dielectric interface rather than the opaque part: the transmission weight
    /// from outside, 1 from inside (where the one-sided opaque part is black).
    fn dielectric_probability(&self, wo: Vec3) -> f32 {
        if self.transmission == 0.0 {
            0.0
        } else if wo.z < 0.0 {
            1.0
        } else {
            self.transmission
        }
    }

    /// BSDF value, non-delta part: `(1 − t) opaque + t dielectric`.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let t = self.transmission;
        let mut f = (1.0 - t) * self.eval_opaque(wo, wi);
        if t > 0.0 {
            f += t * self.dielectric.eval(wo, wi);
        }
        f
    }

    /// [`GltfPbr::eval`] split by class: the opaque part's diffuse reflection is diffuse, its diffuse
    /// transmission transmission and its specular layer glossy; the dielectric interface's reflection is glossy and its refraction transmission
    /// ([`Dielectric::eval_split`]).
    pub fn eval_split(&self, wo: Vec3, wi: Vec3) -> LobeSplit {
        let t = self.transmission;
        let mut split = match self.opaque_lobes(wo, wi) {
            Some((diffuse, specular, transmitted)) => LobeSplit {
                diffuse: (1.0 - t) * diffuse,
                glossy: (1.0 - t) * specular,
                transmission: (1.0 - t) * transmitted,
            },
            None => LobeSplit::ZERO,
        };
        if t > 0.0 {
            split += self.dielectric.eval_split(wo, wi) * t;
        }
        split
    }

    /// The class colours seen from `wo`: `(1 − t)` times the opaque part's plus `t` times the dielectric
    /// interface's ([`Dielectric::colors`]). The opaque part, above the surface only, with the Fresnel
    /// weights `kd`, `ks` of [`GltfPbr::eval`]:
    /// - diffuse `kd(cos(θo/2)) · (1 − dt) · baseColor` and transmission `kd(cos(θo/2)) · dt · c_dt` (the diffuse
    ///   reflection and transmission of `KHR_materials_diffuse_transmission`), with `cos(θo/2) = √((1 + cos θo)/2)`: the weight at the half
    ///   vector of `wo` and the normal, where the cosine-weighted diffuse directions peak (an estimate: `kd`
    ///   varies with the half vector, and is 0 at grazing `wo·h` when `specularFactor` is 1);
    /// - glossy, for a mirror, `ks(cos θo)`, its exact albedo; for a rough specular layer the estimate
    ///   `ks` with each Schlick term `F(cos θo)` replaced by `(1 − α) F(cos θo) + α F̄`, where
    ///   `F̄ = f0 + (1 − f0)/21` is Schlick's hemispherical average (`fresnel::schlick_average`): the
    ///   rougher the lobe, the more microfacet angles it averages over. The energy lost to masking is left
    ///   out.
    pub fn colors(&self, wo: Vec3) -> LobeSplit {
        let t = self.transmission;
        let mut colors = LobeSplit::ZERO;
        if wo.z > 0.0 && t < 1.0 {
            colors = self.opaque_colors(wo) * (1.0 - t);
        }
        if t > 0.0 {
            colors += self.dielectric.colors(wo) * t;
        }
        colors
    }

    /// The opaque part's colours for `wo` above the surface (see [`GltfPbr::colors`]).
    fn opaque_colors(&self, wo: Vec3) -> LobeSplit {
        let half_cos = (0.5 * (1.0 + wo.z)).sqrt();
        let (kd, _) = self.fresnel_weights(half_cos);
        let (_, mirror_ks) = self.fresnel_weights(wo.z);
        let glossy = if self.specular_is_delta() {
            mirror_ks
        } else {
            let rough = |f0: Rgb| {
                let f = fresnel::schlick(f0, wo.z);
                f + self.alpha * (fresnel::schlick_average(f0) - f)
            };
            let dielectric = 1.0 - self.metallic;
            dielectric * self.specular_factor * rough(self.f0)
                + self.metallic * rough(self.base_color)
        };
        let (reflected, transmitted) = self.diffuse_albedos();
        LobeSplit {
            diffuse: kd * reflected,
            glossy,
            transmission: kd * transmitted,
        }
    }

    /// Solid-angle density of the non-delta directions of [`GltfPbr::sample`], the mixture of the lobe
    /// densities with the lobe-selection probabilities.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p = self.dielectric_probability(wo);
        let mut pdf = 0.0;
        if p < 1.0 {
            pdf += (1.0 - p) * self.pdf_opaque(wo, wi);
        }
        if p > 0.0 {
            pdf += p * self.dielectric.pdf(wo, wi);
        }
        pdf
    }

    /// Picks the dielectric or the opaque part with `u_lobe`, then, in the opaque part, the diffuse or the
    /// specular lobe; samples it (cosine hemisphere, or GGX visible normals reflected about `h`). Non-delta
    /// samples carry the full mixture `eval` and `pdf`; delta samples their lobe's weighted value and discrete
    /// probability.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        let p = self.dielectric_probability(wo);
        let (wi, class, eta) = if u_lobe < p {
            let s = self.dielectric.sample(wo, u_lobe / p, u)?;
            if let Some((f, prob)) = s.delta {
                return Some(BsdfSample {
                    wi: s.wi,
                    f: self.transmission * f,
                    pdf: p * prob,
                    is_delta: true,
                    class: s.class,
                    eta: s.eta,
                });
            }
            (s.wi, s.class, s.eta)
        } else {
            if wo.z <= 0.0 {
                return None;
            }
            let u_lobe = ((u_lobe - p) / (1.0 - p)).min(1.0 - f32::EPSILON);
            let pd = self.diffuse_probability(wo);
            if u_lobe < pd {
                let wi = cosine_hemisphere(u);
                if u_lobe < pd * self.diffuse_transmission_probability() {
                    (Vec3::new(wi.x, wi.y, -wi.z), LobeClass::Transmission, 1.0)
                } else {
                    (wi, LobeClass::Diffuse, 1.0)
                }
            } else if self.specular_is_delta() {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                let (_, ks) = self.fresnel_weights(wo.z);
                let f = (1.0 - self.transmission) * ks / wi.z;
                return Some(BsdfSample {
                    wi,
                    f,
                    pdf: (1.0 - p) * (1.0 - pd),
                    is_delta: true,
                    class: LobeClass::Glossy,
                    eta: 1.0,
                });
            } else {
                let o = self.anisotropy_local(wo);
                let h = self.shading_local(self.specular.sample_visible(o, u));
                let wi = fresnel::reflect(wo, h);
                // A reflection below the horizon is no sample of the reflection lobe: `pdf` does not count
                // it, so keeping it where another lobe has a value there (the diffuse transmission, the
                // dielectric's refraction) would weight it by the wrong density.
                if wi.z <= 0.0 {
                    return None;
                }
                (wi, LobeClass::Glossy, 1.0)
            }
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

/// The metal's share of the opaque part of a material whose metallic is `metallic` and whose effective
/// transmission weight is `transmission` (`t`): `metallic / (1 − t)`, so that `(1 − t)` times it is
/// `metallic` (see the module documentation); `metallic` where nothing is opaque (`t = 1`).
fn opaque_metal_share(metallic: f32, transmission: f32) -> f32 {
    let opaque = 1.0 - transmission;
    if opaque > 0.0 {
        (metallic / opaque).min(1.0)
    } else {
        metallic
    }
}

/// The specular GGX and the unit anisotropy direction for isotropic width `alpha` and the anisotropy of `p`
/// (`KHR_materials_anisotropy`'s specification: `α_t = mix(α, 1, s²)`, `α_b = α`). Without anisotropy, or
/// when even `α_t` is below [`DELTA_ALPHA`] (a mirror), `(α, α)` along `(1, 0)`; otherwise `α_b` is kept at
/// least [`DELTA_ALPHA`] so that the distribution stays a function (roughness 0 with anisotropy is a
/// one-dimensional streak).
fn anisotropic_specular(alpha: f32, p: &PbrParams) -> (Ggx, Vec2) {
    let strength = if p.anisotropy_strength.is_nan() {
        0.0
    } else {
        p.anisotropy_strength.clamp(0.0, 1.0)
    };
    let alpha_t = alpha + (1.0 - alpha) * strength * strength;
    let direction = p.anisotropy_direction;
    let length = direction.length();
    if strength <= 0.0 || alpha_t < DELTA_ALPHA {
        return (Ggx::isotropic(alpha), Vec2::X);
    }
    let direction = if length.is_finite() && length > 0.0 {
        direction / length
    } else {
        Vec2::X
    };
    (
        Ggx {
            alpha_x: alpha_t,
            alpha_y: alpha.max(DELTA_ALPHA),
        },
        direction,
    )
}
