//! The BSDF handed to the integrator: an enum over the scattering models, built from glTF parameters.
//!
//! Contract: every direction is in the local shading frame (z = shading normal), unit length, and both `wo`
//! and `wi` point away from the surface. Opaque lobes are one-sided (zero unless `wo.z > 0`, and
//! `wi.z > 0` but for a diffuse transmission); the integrator flips the frame for double-sided materials and
//! diffusely transmitting thin walls hit from behind. The sample weight is `f |wi.z| / pdf`.

use super::clearcoat::Clearcoat;
use super::dielectric::Dielectric;
use super::gltf_pbr::{GltfPbr, PbrParams};
use super::lambert::Lambert;
use super::layered::Layered;
use super::lobes::{LobeClass, LobeSplit};
pub use super::sample::BsdfSample;
use super::sheen::Sheen;
use crate::math::{Rgb, Vec2, Vec3};

/// Directions whose cosine to the shading normal is below this in magnitude (within 1e-9 radians of the tangent
/// plane) are taken as exactly tangent: no value, no density and no sample. The models divide by products and
/// squares of cosines, which underflow `f32` below about 1e-19 and gave infinite or NaN values (issue 33, found by
/// `tests/suite/bsdf_finite.rs`); the directions dropped carry no measurable light.
const TANGENT_COS: f32 = 1e-9;

/// True when `w` lies in the tangent plane to within [`TANGENT_COS`].
fn is_tangent(w: Vec3) -> bool {
    w.z.abs() < TANGENT_COS
}

/// A surface scattering model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Ideal diffuse reflection.
    Lambert(Lambert),
    /// A pure dielectric interface (full transmission, no metal): smooth or rough.
    Dielectric(Dielectric),
    /// The general glTF metallic-roughness model, with optional partial transmission.
    Pbr(GltfPbr),
    /// The metallic-roughness model under a sheen and/or a clear coat.
    Layered(Layered),
}

impl Bsdf {
    /// Maps glTF 2.0 material parameters (spec Appendix B and the extensions of [`PbrParams`]) to a BSDF:
    /// metallic 0, specular 0 and no transmission (specular or diffuse) give exactly [`Lambert`]; transmission 1 with metallic 0
    /// gives a pure [`Dielectric`] tinted by the base colour; everything else (mirrors included: metallic 1 and
    /// roughness 0) the [`GltfPbr`] mixture; a non-zero clear coat or sheen puts it under those layers
    /// ([`Layered`]).
    pub fn from_gltf(p: &PbrParams) -> Bsdf {
        let coat = p.clearcoat.is_finite() && p.clearcoat > 0.0;
        let sheen = p.sheen_color.max_element() > 0.0;
        if coat || sheen {
            return Bsdf::Layered(Layered {
                base: GltfPbr::new(p),
                sheen: sheen.then(|| Sheen::new(p.sheen_color, p.sheen_roughness)),
                coat: coat.then(|| Clearcoat::new(p.clearcoat, p.clearcoat_roughness)),
            });
        }
        let diffuse_transmission = p.diffuse_transmission > 0.0;
        if p.metallic <= 0.0
            && p.specular_factor <= 0.0
            && p.transmission <= 0.0
            && !diffuse_transmission
        {
            return Bsdf::Lambert(Lambert {
                albedo: p.base_color.max(Rgb::ZERO),
            });
        }
        let pbr = GltfPbr::new(p);
        if pbr.transmission >= 1.0 {
            Bsdf::Dielectric(pbr.dielectric)
        } else {
            Bsdf::Pbr(pbr)
        }
    }

    /// BSDF value of the non-delta lobes, without the cosine.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        if is_tangent(wo) || is_tangent(wi) {
            return Rgb::ZERO;
        }
        match self {
            Bsdf::Lambert(b) => b.eval(wo, wi),
            Bsdf::Dielectric(b) => b.eval(wo, wi),
            Bsdf::Pbr(b) => b.eval(wo, wi),
            Bsdf::Layered(b) => b.eval(wo, wi),
        }
    }

    /// [`Bsdf::eval`] split by lobe class, for the light-path AOVs; `eval_split(wo, wi).total()` equals
    /// `eval(wo, wi)` up to rounding. The rule: Lambert and the glTF diffuse base are diffuse; the specular
    /// reflection of the metallic-roughness model (dielectric specular and metal, GGX or mirror), the clear
    /// coat, the sheen and a dielectric interface's reflection (rough or smooth, from either side) are glossy;
    /// a dielectric interface's refraction (rough or smooth, from either side) and the diffuse transmission of
    /// `KHR_materials_diffuse_transmission` are transmission. Glossy light
    /// therefore stays on `wo`'s side and transmitted light crosses the surface.
    pub fn eval_split(&self, wo: Vec3, wi: Vec3) -> LobeSplit {
        if is_tangent(wo) || is_tangent(wi) {
            return LobeSplit::ZERO;
        }
        match self {
            Bsdf::Lambert(b) => b.eval_split(wo, wi),
            Bsdf::Dielectric(b) => b.eval_split(wo, wi),
            Bsdf::Pbr(b) => b.eval_split(wo, wi),
            Bsdf::Layered(b) => b.eval_split(wo, wi),
        }
    }

    /// Each class's colour seen from `wo`, for the colour passes by which the light passes are divided: a
    /// deterministic, non-negative estimate of the class's directional albedo `∫ f_k |cos θi| dωi` (plus its
    /// delta lobes' weights), as Cycles takes a closure's weight times an albedo estimate. Exact for a Lambert
    /// (its albedo above the surface), a mirror reflection, a mirror coat and a smooth dielectric interface;
    /// for the glTF diffuse base and rough lobes an estimate, not the
    /// exact albedo (see [`GltfPbr::colors`], [`Dielectric::colors`], [`Layered::colors`]). A channel is
    /// positive wherever its class can carry energy for this `wo`, and zero where the class is absent.
    pub fn colors(&self, wo: Vec3) -> LobeSplit {
        match self {
            Bsdf::Lambert(b) => b.colors(wo),
            Bsdf::Dielectric(b) => b.colors(wo),
            Bsdf::Pbr(b) => b.colors(wo),
            Bsdf::Layered(b) => b.colors(wo),
        }
    }

    /// Solid-angle density with which [`Bsdf::sample`] picks `wi` through its non-delta lobes.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if is_tangent(wo) || is_tangent(wi) {
            return 0.0;
        }
        match self {
            Bsdf::Lambert(b) => b.pdf(wo, wi),
            Bsdf::Dielectric(b) => b.pdf(wo, wi),
            Bsdf::Pbr(b) => b.pdf(wo, wi),
            Bsdf::Layered(b) => b.pdf(wo, wi),
        }
    }

    /// Samples a direction with `u_lobe` choosing the lobe and `u` the direction within it; `None` when no
    /// direction carries energy (e.g. `wo` below an opaque surface) or when `wo` or the direction is tangent
    /// (see [`TANGENT_COS`]).
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if is_tangent(wo) {
            return None;
        }
        let sample = self.sample_any(wo, u_lobe, u)?;
        (!is_tangent(sample.wi)).then_some(sample)
    }

    /// [`Bsdf::sample`] before tangent directions are dropped.
    fn sample_any(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        match self {
            Bsdf::Lambert(b) => {
                let wi = b.sample(wo, u)?;
                Some(BsdfSample {
                    wi,
                    f: b.eval(wo, wi),
                    pdf: b.pdf(wo, wi),
                    is_delta: false,
                    class: LobeClass::Diffuse,
                    eta: 1.0,
                })
            }
            Bsdf::Dielectric(b) => {
                let s = b.sample(wo, u_lobe, u)?;
                match s.delta {
                    Some((f, pdf)) => Some(BsdfSample {
                        wi: s.wi,
                        f,
                        pdf,
                        is_delta: true,
                        class: s.class,
                        eta: s.eta,
                    }),
                    None => {
                        let pdf = b.pdf(wo, s.wi);
                        (pdf > 0.0).then(|| BsdfSample {
                            wi: s.wi,
                            f: b.eval(wo, s.wi),
                            pdf,
                            is_delta: false,
                            class: s.class,
                            eta: s.eta,
                        })
                    }
                }
            }
            Bsdf::Pbr(b) => b.sample(wo, u_lobe, u),
            Bsdf::Layered(b) => b.sample(wo, u_lobe, u),
        }
    }

    /// True when every lobe is a delta distribution (next-event estimation is then pointless).
    pub fn is_delta(&self) -> bool {
        match self {
            Bsdf::Lambert(_) => false,
            Bsdf::Dielectric(b) => b.is_smooth(),
            Bsdf::Pbr(b) => b.is_delta(),
            Bsdf::Layered(b) => b.is_delta(),
        }
    }

    /// A representative colour for the albedo AOV: the base colour (the tint for a dielectric).
    #[cfg(any(test, feature = "testing"))]
    pub fn albedo(&self) -> Rgb {
        match self {
            Bsdf::Lambert(b) => b.albedo,
            Bsdf::Dielectric(b) => b.tint,
            Bsdf::Pbr(b) => b.base_color,
            Bsdf::Layered(b) => b.base.base_color,
        }
    }

    /// Tilts the clear coat's normal to `n` (unit, in the shading frame, above it), for a coat with its own
    /// normal map or a base whose normal map the coat does not follow; other BSDFs are unchanged.
    pub fn set_coat_normal(&mut self, n: Vec3) {
        if let Bsdf::Layered(Layered {
            coat: Some(coat), ..
        }) = self
        {
            coat.set_normal(n);
        }
    }

    /// True for an invisible boundary: a smooth pure dielectric with ior 1 and a white tint, whose
    /// [`Bsdf::sample`] always returns `-wo` with weight 1.
    pub fn is_index_matched(&self) -> bool {
        matches!(self, Bsdf::Dielectric(d) if d.ior == 1.0 && d.is_smooth() && d.tint == Rgb::ONE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::fresnel;
    use crate::math::{chi2, sampling, Rng};
    use std::f32::consts::FRAC_1_PI;

    const SAMPLES: usize = 100_000;

    /// A unit direction with the given cos θ (negative: below the surface) and φ = 0.7.
    fn dir(cos_theta: f32) -> Vec3 {
        let s = (1.0 - cos_theta * cos_theta).sqrt();
        Vec3::new(s * 0.7f32.cos(), s * 0.7f32.sin(), cos_theta)
    }

    fn params(metallic: f32, roughness: f32) -> PbrParams {
        PbrParams {
            base_color: Rgb::new(0.9, 0.6, 0.3),
            metallic,
            roughness,
            ..Default::default()
        }
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-3 * a.abs().max(b.abs()) + 1e-6
    }

    /// Chi-square test of the non-delta directions of `bsdf.sample` against `bsdf.pdf` (delta samples count as
    /// rejected, so their probability must be the mass `pdf` lacks); also checks that each sample's `pdf` and
    /// `f` equal `pdf()` and `eval()`.
    fn chi2_bsdf(name: &str, bsdf: &Bsdf, wo: Vec3, seed: u64) -> f64 {
        chi2::assert_sampler_fits(
            name,
            SAMPLES,
            seed,
            |rng| {
                let s = bsdf.sample(wo, rng.next_f32(), rng.next_2d())?;
                assert!(
                    s.pdf > 0.0 && s.pdf.is_finite() && crate::math::is_finite_rgb(s.f),
                    "{name}: {s:?}"
                );
                assert!((s.wi.length() - 1.0).abs() < 1e-4, "{name}: unit wi");
                if s.is_delta {
                    return None;
                }
                let (pdf, f) = (bsdf.pdf(wo, s.wi), bsdf.eval(wo, s.wi));
                assert!(
                    close(s.pdf, pdf),
                    "{name}: sampled pdf {} vs pdf() {pdf}",
                    s.pdf
                );
                for c in 0..3 {
                    assert!(
                        close(s.f[c], f[c]),
                        "{name}: sampled f {} vs eval() {f}",
                        s.f
                    );
                }
                Some(s.wi)
            },
            |wi| bsdf.pdf(wo, wi) as f64,
        )
    }

    #[test]
    fn lambert_chi2() {
        let bsdf = Bsdf::from_gltf(&PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..params(0.0, 0.5)
        });
        for (k, c) in [0.95, 0.5, 0.15].into_iter().enumerate() {
            chi2_bsdf(&format!("Lambert cos {c}"), &bsdf, dir(c), k as u64);
        }
    }

    #[test]
    fn gltf_metallic_roughness_chi2() {
        let mut seed = 1000;
        for metallic in [0.0, 0.5, 1.0] {
            for roughness in [0.1, 0.3, 0.7, 1.0] {
                let bsdf = Bsdf::from_gltf(&params(metallic, roughness));
                assert!(matches!(bsdf, Bsdf::Pbr(_)));
                for c in [0.95, 0.5, 0.15] {
                    seed += 1;
                    chi2_bsdf(
                        &format!("glTF metallic {metallic} roughness {roughness} cos {c}"),
                        &bsdf,
                        dir(c),
                        seed,
                    );
                }
            }
        }
    }

    /// `params(metallic, roughness)` with `KHR_materials_anisotropy` strength `strength` along the direction at
    /// `angle` radians from the tangent.
    fn anisotropic(metallic: f32, roughness: f32, strength: f32, angle: f32) -> PbrParams {
        PbrParams {
            anisotropy_strength: strength,
            anisotropy_direction: Vec2::new(angle.cos(), angle.sin()),
            ..params(metallic, roughness)
        }
    }

    #[test]
    fn anisotropic_gltf_chi2() {
        let cases = [
            (1.0, 0.3, 0.8, 0.6, 0.5),
            (1.0, 0.0, 0.9, -1.2, 0.8),
            (0.5, 0.5, 1.0, 2.0, 0.3),
            (0.0, 0.2, 0.7, 0.0, 0.95),
        ];
        for (k, (metallic, roughness, strength, angle, c)) in cases.into_iter().enumerate() {
            let bsdf = Bsdf::from_gltf(&anisotropic(metallic, roughness, strength, angle));
            assert!(matches!(bsdf, Bsdf::Pbr(_)));
            chi2_bsdf(
                &format!("anisotropic glTF metallic {metallic} roughness {roughness} strength {strength} angle {angle} cos {c}"),
                &bsdf,
                dir(c),
                3000 + k as u64,
            );
        }
    }

    #[test]
    fn anisotropy_follows_the_extension_formula_and_its_direction() {
        // KHR_materials_anisotropy: α_t = mix(α, 1, s²), α_b = α, α = roughness².
        let Bsdf::Pbr(pbr) = Bsdf::from_gltf(&anisotropic(1.0, 0.5, 0.6, 0.4)) else {
            panic!("expected the metallic-roughness BSDF");
        };
        let alpha = 0.25f32;
        assert!((pbr.specular.alpha_x - (alpha + (1.0 - alpha) * 0.36)).abs() < 1e-6);
        assert_eq!(pbr.specular.alpha_y, alpha);
        // Strength 0 is the isotropic BSDF, whatever the direction.
        assert_eq!(
            Bsdf::from_gltf(&anisotropic(1.0, 0.5, 0.0, 1.0)),
            Bsdf::from_gltf(&params(1.0, 0.5))
        );
        // The direction rotates the lobe: the BSDF along angle φ at (wo, wi) is the one along the tangent at
        // (wo, wi) rotated by −φ about the normal; and it is reciprocal.
        let phi = 0.9f32;
        let along = Bsdf::from_gltf(&anisotropic(1.0, 0.4, 0.8, phi));
        let tangent = Bsdf::from_gltf(&anisotropic(1.0, 0.4, 0.8, 0.0));
        let rot = |v: Vec3| {
            let (s, c) = (-phi).sin_cos();
            Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
        };
        let mut rng = Rng::new(5, 5);
        for _ in 0..200 {
            let wo = sampling::cosine_hemisphere(rng.next_2d());
            let wi = sampling::cosine_hemisphere(rng.next_2d());
            let (a, b) = (along.eval(wo, wi), tangent.eval(rot(wo), rot(wi)));
            let r = along.eval(wi, wo);
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-3 * a[c].max(b[c]) + 1e-6,
                    "{a} vs {b}"
                );
                assert!(
                    (a[c] - r[c]).abs() <= 1e-3 * a[c].max(r[c]) + 1e-6,
                    "{a} vs {r}"
                );
            }
            assert!(
                (along.pdf(wo, wi) - tangent.pdf(rot(wo), rot(wi))).abs()
                    <= 1e-3 * along.pdf(wo, wi) + 1e-6
            );
        }
        // The lobe is wider along the anisotropy direction: at the same grazing angle, the mirror of wo
        // tilted along the direction reflects more than tilted across it.
        let wo = Vec3::Z;
        let tilt = 0.6f32;
        let wi_along = Vec3::new(tilt.sin() * phi.cos(), tilt.sin() * phi.sin(), tilt.cos());
        let wi_across = Vec3::new(-tilt.sin() * phi.sin(), tilt.sin() * phi.cos(), tilt.cos());
        assert!(along.eval(wo, wi_along).x > 2.0 * along.eval(wo, wi_across).x);
    }

    #[test]
    fn rough_dielectric_chi2_outside_and_inside() {
        let mut seed = 2000;
        for roughness in [0.1, 0.3, 0.7, 1.0] {
            let bsdf = Bsdf::from_gltf(&PbrParams {
                transmission: 1.0,
                metallic: 0.0,
                ..params(0.0, roughness)
            });
            assert!(matches!(bsdf, Bsdf::Dielectric(_)) && !bsdf.is_delta());
            for c in [0.95, 0.5, 0.15, -0.95, -0.5, -0.15] {
                seed += 1;
                chi2_bsdf(
                    &format!("rough dielectric roughness {roughness} cos {c}"),
                    &bsdf,
                    dir(c),
                    seed,
                );
            }
        }
    }

    #[test]
    fn transmission_takes_the_whole_dielectric_base_of_a_part_metal() {
        // glTF 2.0 Appendix B with KHR_materials_transmission: `mix(dielectric_brdf, metal_brdf, metallic)`, the
        // dielectric's base `mix(diffuse_brdf, specular_btdf, transmission)`. Transmission 1 leaves no diffuse
        // at any metallic, and the metal keeps its weight `metallic`: a smooth white part-metal reflects
        // `metallic · 1 + (1 − metallic) · F` (F the exact Fresnel term of the glass) and refracts the rest.
        for (metallic, roughness) in [(0.5f32, 0.0f32), (0.3, 0.4), (0.8, 0.0)] {
            let bsdf = Bsdf::from_gltf(&PbrParams {
                base_color: Rgb::ONE,
                transmission: 1.0,
                metallic,
                roughness,
                ..Default::default()
            });
            let colors = bsdf.colors(dir(0.8));
            assert_eq!(
                colors.diffuse,
                Rgb::ZERO,
                "metallic {metallic} roughness {roughness}"
            );
            if roughness > 0.0 {
                continue;
            }
            let (mut reflected, mut refracted) = (0.0, 0.0);
            let n = 1000;
            for k in 0..n {
                let u_lobe = (k as f32 + 0.5) / n as f32;
                let s = bsdf.sample(Vec3::Z, u_lobe, Vec2::splat(0.5)).unwrap();
                assert!(s.is_delta);
                let w = (s.f * s.wi.z.abs() / s.pdf).x / n as f32;
                if s.wi.z > 0.0 {
                    reflected += w;
                } else {
                    refracted += w * 1.5 * 1.5;
                }
            }
            let f = 0.04;
            let expected = metallic + (1.0 - metallic) * f;
            assert!(
                (reflected - expected).abs() < 1e-3,
                "{reflected} vs {expected}"
            );
            let expected_t = (1.0 - metallic) * (1.0 - f);
            assert!(
                (refracted - expected_t).abs() < 1e-3,
                "{refracted} vs {expected_t}"
            );
        }
    }

    #[test]
    fn iridescent_rough_dielectric_chi2_outside_and_inside() {
        // The film colours the Fresnel term; the lobe is picked by the channels' mean, which `pdf` must follow.
        let mut seed = 2100;
        for roughness in [0.3, 0.7] {
            let bsdf = Bsdf::from_gltf(&PbrParams {
                transmission: 1.0,
                iridescence: 1.0,
                iridescence_ior: 1.8,
                iridescence_thickness: 350.0,
                ..params(0.0, roughness)
            });
            for c in [0.95, 0.3, -0.6] {
                seed += 1;
                chi2_bsdf(
                    &format!("iridescent rough dielectric roughness {roughness} cos {c}"),
                    &bsdf,
                    dir(c),
                    seed,
                );
            }
        }
    }

    #[test]
    fn partial_transmission_chi2() {
        // Rough everywhere, from both sides; and smooth, where delta lobes take the mass pdf() lacks.
        let rough = Bsdf::from_gltf(&PbrParams {
            transmission: 0.5,
            ..params(0.2, 0.5)
        });
        chi2_bsdf("transmission 0.5 rough outside", &rough, dir(0.6), 3001);
        chi2_bsdf("transmission 0.5 rough inside", &rough, dir(-0.6), 3002);
        let smooth = Bsdf::from_gltf(&PbrParams {
            transmission: 0.5,
            ..params(0.0, 0.0)
        });
        assert!(!smooth.is_delta());
        chi2_bsdf("transmission 0.5 smooth outside", &smooth, dir(0.6), 3003);
    }

    #[test]
    fn lambert_mapping_is_exact_and_conserves_energy() {
        let base = Rgb::new(0.2, 0.5, 0.8);
        let bsdf = Bsdf::from_gltf(&PbrParams {
            base_color: base,
            metallic: 0.0,
            specular_factor: 0.0,
            ..Default::default()
        });
        assert!(matches!(bsdf, Bsdf::Lambert(_)));
        let (wo, wi) = (dir(0.3), dir(0.8));
        assert_eq!(bsdf.eval(wo, wi), base * FRAC_1_PI);
        assert_eq!(bsdf.pdf(wo, wi), wi.z * FRAC_1_PI);
        assert_eq!(bsdf.eval(wo, -wi), Rgb::ZERO);
        assert_eq!(bsdf.albedo(), base);
        // White furnace: ∫ f cos dω = 1 for albedo 1, by uniform-sphere Monte Carlo within 4 standard errors.
        let white = Bsdf::from_gltf(&PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..Default::default()
        });
        let mut rng = Rng::new(5, 5);
        let n = 200_000;
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let wi = sampling::uniform_sphere(rng.next_2d());
            let v = (white.eval(wo, wi).x * wi.z.abs() / sampling::UNIFORM_SPHERE_PDF) as f64;
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!((mean - 1.0).abs() < 4.0 * se, "albedo {mean} ± {se}");
    }

    #[test]
    fn reflection_is_reciprocal_and_one_sided() {
        let mut rng = Rng::new(8, 8);
        for (metallic, roughness) in [(0.0, 0.3), (0.5, 0.6), (1.0, 0.2), (0.3, 1.0)] {
            for bsdf in [
                Bsdf::from_gltf(&params(metallic, roughness)),
                Bsdf::from_gltf(&PbrParams {
                    transmission: 1.0,
                    ..params(0.0, roughness)
                }),
            ] {
                for _ in 0..1000 {
                    let wo = sampling::cosine_hemisphere(rng.next_2d());
                    let wi = sampling::cosine_hemisphere(rng.next_2d());
                    let (a, b) = (bsdf.eval(wo, wi), bsdf.eval(wi, wo));
                    for c in 0..3 {
                        assert!(
                            (a[c] - b[c]).abs() <= 1e-3 * a[c].max(b[c]) + 1e-6,
                            "{bsdf:?}: {a} vs {b}"
                        );
                    }
                    if matches!(bsdf, Bsdf::Pbr(_)) {
                        assert_eq!(bsdf.eval(-wo, wi), Rgb::ZERO);
                        assert_eq!(bsdf.eval(wo, -wi), Rgb::ZERO);
                        assert!(bsdf.sample(-wo, 0.5, rng.next_2d()).is_none());
                    }
                }
            }
        }
    }

    #[test]
    fn smooth_metal_is_a_schlick_mirror() {
        let base = Rgb::new(0.95, 0.64, 0.54);
        let bsdf = Bsdf::from_gltf(&PbrParams {
            base_color: base,
            metallic: 1.0,
            roughness: 0.0,
            ..Default::default()
        });
        assert!(bsdf.is_delta());
        for c in [1.0, 0.7, 0.2, 0.01] {
            let wo = dir(c);
            let s = bsdf
                .sample(wo, 0.3, Vec2::new(0.2, 0.9))
                .expect("a mirror reflects");
            assert!(s.is_delta);
            assert!(
                (s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6,
                "reflection law"
            );
            let weight = s.f * s.wi.z / s.pdf;
            assert!((weight - fresnel::schlick(base, c)).abs().max_element() < 1e-5);
            assert_eq!(bsdf.eval(wo, s.wi), Rgb::ZERO);
            assert_eq!(bsdf.pdf(wo, s.wi), 0.0);
        }
    }

    /// Every sample reports the relative index it refracted through (`BsdfSample::eta`, what Russian roulette
    /// undoes the 1/η² radiance factor with): η = ior entering, 1/ior leaving, 1 for a reflection, with a
    /// smooth or rough interface, alone, mixed with an opaque base or under a clear coat.
    #[test]
    fn samples_report_the_index_they_refract_through() {
        let ior = 1.4;
        let glass = |roughness: f32, transmission: f32| PbrParams {
            transmission,
            ior,
            ..params(0.0, roughness)
        };
        let bsdfs = [
            Bsdf::from_gltf(&glass(0.0, 1.0)),
            Bsdf::from_gltf(&glass(0.4, 1.0)),
            Bsdf::from_gltf(&glass(0.0, 0.5)),
            Bsdf::from_gltf(&glass(0.3, 0.5)),
            coated(1.0, 0.0, glass(0.0, 1.0)),
            coated(1.0, 0.2, glass(0.3, 1.0)),
            Bsdf::from_gltf(&params(0.0, 0.5)),
        ];
        let mut rng = Rng::new(5, 5);
        for (i, bsdf) in bsdfs.iter().enumerate() {
            let mut refracted = 0;
            for c in [0.9f32, 0.4, -0.3, -0.95] {
                let wo = dir(c);
                let expected = if c > 0.0 { ior } else { 1.0 / ior };
                for _ in 0..2000 {
                    let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_2d()) else {
                        continue;
                    };
                    if s.wi.z * wo.z < 0.0 {
                        refracted += 1;
                        assert_eq!(s.eta, expected, "bsdf {i}: {s:?}");
                    } else {
                        assert_eq!(s.eta, 1.0, "bsdf {i}: {s:?}");
                    }
                }
            }
            assert_eq!(refracted > 0, i < 6, "bsdf {i}: {refracted} refractions");
        }
    }

    #[test]
    fn smooth_dielectric_follows_snell_fresnel_and_conserves_energy() {
        let ior = 1.5;
        let bsdf = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            roughness: 0.0,
            ior,
            ..params(0.0, 0.0)
        });
        let white = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            roughness: 0.0,
            ior,
            metallic: 0.0,
            ..Default::default()
        });
        assert!(bsdf.is_delta() && !bsdf.is_index_matched());
        let mut rng = Rng::new(13, 13);
        for c in [0.9f32, 0.5, 0.2, -0.9, -0.8, -0.5] {
            let wo = dir(c);
            let eta = if c > 0.0 { ior } else { 1.0 / ior };
            let fresnel = fresnel::dielectric(c, eta);
            let n = 100_000;
            let (mut reflected, mut energy, mut energy2) = (0usize, 0.0f64, 0.0f64);
            for _ in 0..n {
                let s = white
                    .sample(wo, rng.next_f32(), rng.next_2d())
                    .expect("a dielectric always scatters");
                assert!(s.is_delta);
                let weight = s.f.x * s.wi.z.abs() / s.pdf;
                if s.wi.z * wo.z > 0.0 {
                    reflected += 1;
                    assert!(
                        (s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6,
                        "reflection law"
                    );
                    energy += weight as f64;
                    energy2 += (weight * weight) as f64;
                } else {
                    let (sin_i, sin_t) = (wo.truncate().length(), s.wi.truncate().length());
                    assert!((sin_i - eta * sin_t).abs() < 1e-5, "Snell's law");
                    assert!(
                        wo.truncate().dot(s.wi.truncate()) <= 0.0,
                        "plane of incidence"
                    );
                    // Undo the radiance scaling 1/η²: the rest must be exactly the transmitted energy.
                    let w = weight * eta * eta;
                    energy += w as f64;
                    energy2 += (w * w) as f64;
                    let tinted = bsdf.sample(wo, 0.999_999, Vec2::ZERO).expect("refracts");
                    assert!(
                        (tinted.f * tinted.wi.z.abs() / tinted.pdf * eta * eta - bsdf.albedo())
                            .abs()
                            .max_element()
                            < 1e-4
                    );
                }
            }
            // The fraction reflected is Fresnel's R within 4 binomial standard errors; R + T = 1.
            let frac = reflected as f64 / n as f64;
            let se = (fresnel as f64 * (1.0 - fresnel as f64) / n as f64)
                .sqrt()
                .max(1e-9);
            assert!(
                (frac - fresnel as f64).abs() < 4.0 * se,
                "cos {c}: reflected {frac} vs Fresnel {fresnel}"
            );
            let mean = energy / n as f64;
            assert!(
                (mean - 1.0).abs() < 1e-5 && (energy2 / n as f64 - mean * mean).abs() < 1e-5,
                "R + T = {mean}"
            );
        }
        // Past the critical angle from inside every sample reflects.
        let wo = dir(-0.3);
        for _ in 0..100 {
            let s = white.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
            assert!(
                s.wi.z < 0.0 && (s.f.x * s.wi.z.abs() / s.pdf - 1.0).abs() < 1e-5,
                "total internal reflection"
            );
        }
    }

    #[test]
    fn tinted_rough_dielectric_keeps_its_tint_and_a_white_one_conserves_energy() {
        // E[f |cos| / pdf], with refraction's 1/η² undone, is ∫(f_r + η² f_t)|cos|: 1 with the
        // multiple-scattering compensation (the single-scattering model alone gave E[G2/G1] < 1).
        let ior = 1.5;
        let bsdf = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ior,
            ..params(0.0, 0.3)
        });
        let white = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ior,
            roughness: 0.3,
            metallic: 0.0,
            ..Default::default()
        });
        assert_eq!(bsdf.albedo(), params(0.0, 0.3).base_color);
        let mut rng = Rng::new(17, 17);
        for c in [0.8f32, 0.4, -0.8, -0.4] {
            let (mean, se) = white_furnace(&white, ior, dir(c), 100_000, &mut rng);
            assert!(
                (mean - 1.0).abs() <= 4.0 * se,
                "cos {c}: albedo {mean} ± {se}"
            );
        }
    }

    /// Mean and standard error of the white furnace weight `(f_r + η² f_t) |cos θi| / pdf` (red channel) of
    /// `bsdf`, an interface of index `ior`, seen from `wo` (refraction's radiance factor 1/η² undone), by its
    /// own sampler from `n` samples.
    fn white_furnace(bsdf: &Bsdf, ior: f32, wo: Vec3, n: usize, rng: &mut Rng) -> (f64, f64) {
        let eta = if wo.z > 0.0 { ior } else { 1.0 / ior };
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            if let Some(smp) = bsdf.sample(wo, rng.next_f32(), rng.next_2d()) {
                let scale = if smp.wi.z * wo.z < 0.0 {
                    eta * eta
                } else {
                    1.0
                };
                let w = (smp.f.x * smp.wi.z.abs() / smp.pdf * scale) as f64;
                s += w;
                s2 += w * w;
            }
        }
        let mean = s / n as f64;
        (
            mean,
            ((s2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt(),
        )
    }

    #[test]
    fn rough_dielectric_passes_the_white_furnace_from_both_sides() {
        // A lossless interface sends every photon somewhere: with the multiple-scattering compensation the
        // directional albedo (f_r + η² f_t) is 1 at every roughness, index and angle, from either side.
        let mut rng = Rng::new(37, 37);
        for alpha in [0.1f32, 0.5, 1.0] {
            for ior in [1.33f32, 1.5, 2.0] {
                for c in [0.95f32, 0.6, 0.3, 0.1, -0.95, -0.6, -0.3, -0.1] {
                    let glass = Bsdf::Dielectric(Dielectric {
                        ior,
                        alpha,
                        tint: Rgb::ONE,
                        film: None,
                    });
                    let (mean, se) = white_furnace(&glass, ior, dir(c), 50_000, &mut rng);
                    assert!(
                        (mean - 1.0).abs() <= 4.0 * se,
                        "α {alpha} ior {ior} cos {c}: albedo {mean} ± {se}"
                    );
                }
            }
        }
    }

    #[test]
    fn index_matched_boundary_is_invisible() {
        let bsdf = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ior: 1.0,
            roughness: 0.0,
            metallic: 0.0,
            ..Default::default()
        });
        assert!(bsdf.is_index_matched() && bsdf.is_delta());
        for c in [0.9, 0.1, -0.4] {
            let wo = dir(c);
            let s = bsdf.sample(wo, 0.7, Vec2::new(0.3, 0.3)).unwrap();
            assert!(s.is_delta && (s.wi + wo).length() < 1e-6);
            assert!((s.f * s.wi.z.abs() / s.pdf - Rgb::ONE).abs().max_element() < 1e-5);
        }
        assert!(!Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            metallic: 0.0,
            ..Default::default()
        })
        .is_index_matched());
    }

    #[test]
    fn random_materials_and_directions_stay_finite() {
        let mut rng = Rng::new(99, 1);
        for _ in 0..2000 {
            let p = PbrParams {
                base_color: Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
                metallic: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                roughness: [0.0, 0.011, 1.0, rng.next_f32()][(rng.next_u32() % 4) as usize],
                ior: [1.0, 1.5, 1.0 + 2.0 * rng.next_f32()][(rng.next_u32() % 3) as usize],
                specular_factor: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                specular_color: Rgb::new(rng.next_f32(), 1.0, 2.0),
                transmission: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                clearcoat: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                clearcoat_roughness: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                sheen_color: [Rgb::ZERO, Rgb::ONE, Rgb::splat(rng.next_f32())]
                    [(rng.next_u32() % 3) as usize],
                sheen_roughness: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                anisotropy_strength: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                anisotropy_direction: [
                    Vec2::X,
                    Vec2::ZERO,
                    Vec2::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5),
                ][(rng.next_u32() % 3) as usize],
                diffuse_transmission: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                diffuse_transmission_color: Rgb::new(rng.next_f32(), 1.0, 0.0),
                iridescence: [0.0, 1.0, rng.next_f32()][(rng.next_u32() % 3) as usize],
                iridescence_ior: [1.0, 1.3, 1.0 + 2.0 * rng.next_f32()]
                    [(rng.next_u32() % 3) as usize],
                iridescence_thickness: [0.0, 400.0, 2000.0 * rng.next_f32()]
                    [(rng.next_u32() % 3) as usize],
            };
            let mut bsdf = Bsdf::from_gltf(&p);
            if rng.next_f32() < 0.3 {
                bsdf.set_coat_normal(sampling::cosine_hemisphere(rng.next_2d()));
            }
            for _ in 0..20 {
                // Include grazing and exactly tangent directions.
                let mut wo = sampling::uniform_sphere(rng.next_2d());
                if rng.next_f32() < 0.1 {
                    wo = Vec3::new(wo.x, wo.y, 0.0).normalize();
                }
                let wi = sampling::uniform_sphere(rng.next_2d());
                assert!(
                    crate::math::is_finite_rgb(bsdf.eval(wo, wi))
                        && bsdf.eval(wo, wi).min_element() >= 0.0
                );
                assert!(
                    bsdf.pdf(wo, wi).is_finite() && bsdf.pdf(wo, wi) >= 0.0,
                    "{p:?}"
                );
                if let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_2d()) {
                    let weight = s.f * s.wi.z.abs() / s.pdf;
                    assert!(
                        crate::math::is_finite_rgb(weight) && s.pdf > 0.0,
                        "{p:?} {wo} {s:?}"
                    );
                }
            }
        }
    }

    /// Directional albedo `∫ f |cos θi| dωi` for `wo`, by uniform-sphere Monte Carlo (non-delta lobes) plus
    /// the delta lobes' weights by sampling, with its standard error.
    fn albedo(bsdf: &Bsdf, wo: Vec3, n: usize, seed: u64) -> (f64, f64) {
        let mut rng = Rng::new(seed, seed);
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let wi = sampling::uniform_sphere(rng.next_2d());
            let mut v = (bsdf.eval(wo, wi).max_element() * wi.z.abs()
                / sampling::UNIFORM_SPHERE_PDF) as f64;
            if let Some(d) = bsdf
                .sample(wo, rng.next_f32(), rng.next_2d())
                .filter(|d| d.is_delta)
            {
                v += (d.f.max_element() * d.wi.z.abs() / d.pdf) as f64;
            }
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        (mean, ((s2 / n as f64 - mean * mean) / n as f64).sqrt())
    }

    fn coated(clearcoat: f32, clearcoat_roughness: f32, base: PbrParams) -> Bsdf {
        Bsdf::from_gltf(&PbrParams {
            clearcoat,
            clearcoat_roughness,
            ..base
        })
    }

    fn sheened(sheen_roughness: f32, base: PbrParams) -> Bsdf {
        Bsdf::from_gltf(&PbrParams {
            sheen_color: Rgb::ONE,
            sheen_roughness,
            ..base
        })
    }

    /// A white base that reflects everything: Lambertian albedo 1, no specular layer.
    fn white_lambert() -> PbrParams {
        PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..Default::default()
        }
    }

    #[test]
    fn clearcoat_and_sheen_never_add_energy() {
        // White furnace: over a base of albedo 1, the layered albedo stays at or below 1 (within 4 standard
        // errors) for every view; and the coat takes from the base exactly what its Fresnel blend reflects.
        let mut seed = 40;
        for c in [0.95f32, 0.6, 0.3, 0.08] {
            let wo = dir(c);
            let mut layered = vec![
                ("coat 1 rough 0.3", coated(1.0, 0.3, white_lambert())),
                ("coat 0.5 rough 0.8", coated(0.5, 0.8, white_lambert())),
                ("coat 1 smooth", coated(1.0, 0.0, white_lambert())),
                ("sheen rough 0.3", sheened(0.3, white_lambert())),
                ("sheen rough 1", sheened(1.0, white_lambert())),
                (
                    "sheen and coat",
                    coated(
                        1.0,
                        0.2,
                        PbrParams {
                            sheen_color: Rgb::ONE,
                            sheen_roughness: 0.5,
                            ..white_lambert()
                        },
                    ),
                ),
            ];
            let mut tilted = coated(1.0, 0.3, white_lambert());
            tilted.set_coat_normal(Vec3::new(0.3, 0.0, 1.0).normalize());
            layered.push(("coat with a tilted normal", tilted));
            for (name, bsdf) in &layered {
                seed += 1;
                let (a, se) = albedo(bsdf, wo, 200_000, seed);
                assert!(a <= 1.0 + 4.0 * se, "{name} cos {c}: albedo {a} ± {se}");
                assert!(a > 0.5, "{name} cos {c}: albedo {a} ± {se} lost energy");
            }
            // A smooth coat over white Lambert: F(wo) goes to the mirror, 1 − F(wo) to the base (albedo 1).
            let (a, se) = albedo(&coated(1.0, 0.0, white_lambert()), wo, 100_000, seed + 100);
            assert!(
                (a - 1.0).abs() < 4.0 * se + 1e-4,
                "smooth coat cos {c}: {a} ± {se}"
            );
        }
    }

    /// The layered configurations of the chi-square tests, over a rough half-metallic base.
    fn layered_cases() -> Vec<(&'static str, Bsdf)> {
        let base = params(0.3, 0.5);
        let mut cases = vec![
            ("coat rough 0.3", coated(1.0, 0.3, base)),
            ("coat 0.5 rough 0.7", coated(0.5, 0.7, base)),
            (
                "coat smooth (delta) over rough base",
                coated(1.0, 0.0, base),
            ),
            (
                "coat over a transmissive base",
                coated(
                    1.0,
                    0.4,
                    PbrParams {
                        transmission: 0.6,
                        ..base
                    },
                ),
            ),
            ("sheen rough 0.3", sheened(0.3, base)),
            ("sheen rough 1", sheened(1.0, base)),
            (
                "sheen and coat",
                coated(
                    0.8,
                    0.2,
                    PbrParams {
                        sheen_color: Rgb::new(1.0, 0.5, 0.2),
                        sheen_roughness: 0.6,
                        ..base
                    },
                ),
            ),
        ];
        let mut tilted = coated(1.0, 0.3, base);
        tilted.set_coat_normal(Vec3::new(0.3, 0.2, 1.0).normalize());
        cases.push(("coat with a tilted normal", tilted));
        cases
    }

    #[test]
    fn clearcoat_and_sheen_sampling_chi2() {
        let mut seed = 5000;
        for (name, bsdf) in &layered_cases() {
            assert!(matches!(bsdf, Bsdf::Layered(_)), "{name}");
            for c in [0.9, 0.4, 0.1] {
                seed += 1;
                chi2_bsdf(&format!("{name} cos {c}"), bsdf, dir(c), seed);
            }
        }
    }

    #[test]
    fn clearcoat_follows_the_extension_formula() {
        // f = (1 − c F(wo·n)) f_base + c F(wo·n) D G2 / (4 cos cos), Schlick F with f0 = 0.04; checked against
        // the GGX terms composed here.
        let base = params(0.0, 0.6);
        let (c, r) = (0.7f32, 0.4f32);
        let bsdf = coated(c, r, base);
        let plain = Bsdf::from_gltf(&base);
        let ggx = crate::material::Ggx::isotropic(r * r);
        for (o, i) in [(0.9f32, 0.5f32), (0.3, 0.8), (0.6, 0.6)] {
            let (wo, wi) = (
                dir(o),
                Vec3::new(-dir(i).x, dir(i).y * 0.5, dir(i).z).normalize(),
            );
            let h = (wo + wi).normalize();
            let f = c * fresnel::schlick(Rgb::splat(0.04), wo.z).x;
            let spec = ggx.d(h) * ggx.g2(wo, wi) / (4.0 * wo.z * wi.z);
            let expected = plain.eval(wo, wi) * (1.0 - f) + Rgb::splat(f * spec);
            let got = bsdf.eval(wo, wi);
            for k in 0..3 {
                assert!(close(got[k], expected[k]), "{got} vs {expected}");
            }
        }
    }

    /// Every configuration of the chi-square tests, with the classes of its non-delta lobes by the
    /// classification rule, as flags in the order of [`LobeClass::ALL`].
    fn lobe_cases() -> Vec<(String, Bsdf, [bool; 3])> {
        let lambert = PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..params(0.0, 0.5)
        };
        let mut cases = vec![(
            "Lambert".to_string(),
            Bsdf::from_gltf(&lambert),
            [true, false, false],
        )];
        for metallic in [0.0, 0.5, 1.0] {
            for roughness in [0.1, 0.3, 0.7, 1.0] {
                cases.push((
                    format!("metallic {metallic} roughness {roughness}"),
                    Bsdf::from_gltf(&params(metallic, roughness)),
                    [metallic < 1.0, true, false],
                ));
            }
        }
        for roughness in [0.1, 0.3, 0.7, 1.0] {
            let p = PbrParams {
                transmission: 1.0,
                ..params(0.0, roughness)
            };
            let name = format!("rough dielectric roughness {roughness}");
            cases.push((name, Bsdf::from_gltf(&p), [false, true, true]));
        }
        let rough = PbrParams {
            transmission: 0.5,
            ..params(0.2, 0.5)
        };
        cases.push((
            "transmission 0.5 rough".into(),
            Bsdf::from_gltf(&rough),
            [true; 3],
        ));
        // Smooth: the specular layer and the interface are delta lobes, only the diffuse base is left to eval.
        let smooth = PbrParams {
            transmission: 0.5,
            ..params(0.0, 0.0)
        };
        let smooth_classes = [true, false, false];
        cases.push((
            "transmission 0.5 smooth".into(),
            Bsdf::from_gltf(&smooth),
            smooth_classes,
        ));
        for (name, bsdf) in layered_cases() {
            let transmissive = matches!(bsdf, Bsdf::Layered(l) if l.base.transmission > 0.0);
            cases.push((name.to_string(), bsdf, [true, true, transmissive]));
        }
        // KHR_materials_diffuse_transmission: a Lambertian lobe through the surface, in the transmission
        // class; with dt = 1 no diffuse reflection is left.
        for (dt, roughness, classes) in [
            (0.6, 0.5, [true; 3]),
            (1.0, 0.3, [false, true, true]),
            (0.4, 0.0, [true, false, true]),
        ] {
            let p = diffuse_transmitter(dt, Rgb::new(0.9, 0.5, 0.2), params(0.0, roughness));
            let name = format!("diffuse transmission {dt} roughness {roughness}");
            cases.push((name, Bsdf::from_gltf(&p), classes));
        }
        let sheen = PbrParams {
            sheen_color: Rgb::splat(0.5),
            clearcoat: 0.5,
            clearcoat_roughness: 0.3,
            ..diffuse_transmitter(0.5, Rgb::ONE, params(0.0, 0.5))
        };
        cases.push((
            "diffuse transmission under sheen and coat".into(),
            Bsdf::from_gltf(&sheen),
            [true; 3],
        ));
        cases
    }

    /// `base` with `KHR_materials_diffuse_transmission` factor `dt` and colour `color`.
    fn diffuse_transmitter(dt: f32, color: Rgb, base: PbrParams) -> PbrParams {
        PbrParams {
            diffuse_transmission: dt,
            diffuse_transmission_color: color,
            ..base
        }
    }

    /// Mean and standard error of `n` Monte Carlo estimates of `∫ f |cos θi| dωi` (channel `c`) from `wo`,
    /// by uniform sphere directions (independent of the BSDF's sampler).
    fn albedo_uniform(bsdf: &Bsdf, wo: Vec3, c: usize, n: usize, rng: &mut Rng) -> (f64, f64) {
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let wi = sampling::uniform_sphere(rng.next_2d());
            let v = (bsdf.eval(wo, wi)[c] * wi.z.abs() / sampling::UNIFORM_SPHERE_PDF) as f64;
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        (mean, ((s2 / n as f64 - mean * mean) / n as f64).sqrt())
    }

    #[test]
    fn diffuse_transmission_white_furnace() {
        let mut rng = Rng::new(70, 70);
        let white = PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..params(0.0, 0.5)
        };
        for dt in [1.0, 0.4] {
            let bsdf = Bsdf::from_gltf(&diffuse_transmitter(
                dt,
                Rgb::ONE,
                PbrParams {
                    base_color: Rgb::ONE,
                    ..white
                },
            ));
            assert!(matches!(bsdf, Bsdf::Pbr(_)), "{bsdf:?}");
            for c in [0.95, 0.5, 0.1] {
                let wo = dir(c);
                // Reflected and transmitted halves, and their sum: (1 − dt) + dt = 1 in the furnace.
                let (total, se) = albedo_uniform(&bsdf, wo, 0, 400_000, &mut rng);
                println!("diffuse transmission {dt} cos {c}: furnace {total:.5} ± {se:.5}");
                assert!(
                    (total - 1.0).abs() < 4.0 * se,
                    "dt {dt} cos {c}: {total} ± {se}"
                );
                let split = bsdf.colors(wo);
                assert_eq!(split.transmission, Rgb::splat(dt), "cos {c}");
                assert_eq!(split.diffuse, Rgb::splat(1.0 - dt), "cos {c}");
                // The sampler's weights f |cos| / pdf are exactly 1 (a perfect importance sampler).
                for _ in 0..100 {
                    let s = bsdf.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
                    let w = s.f.x * s.wi.z.abs() / s.pdf;
                    assert!((w - 1.0).abs() < 1e-5, "weight {w}");
                }
            }
        }
        // With the specular layer on, diffuse transmission of a white colour only moves light from one side
        // to the other: the total albedo is the one without it (within the two estimates' errors), which the
        // glTF mixture itself does not keep at 1 (its diffuse weight uses Fresnel at wo·h, not an albedo).
        let specular = PbrParams {
            base_color: Rgb::ONE,
            ..params(0.0, 0.4)
        };
        let plain = Bsdf::from_gltf(&specular);
        let translucent = Bsdf::from_gltf(&diffuse_transmitter(0.7, Rgb::ONE, specular));
        for c in [0.9, 0.3] {
            let (a, sa) = albedo_uniform(&plain, dir(c), 0, 400_000, &mut Rng::new(71, 71));
            let (b, sb) = albedo_uniform(&translucent, dir(c), 0, 400_000, &mut Rng::new(72, 72));
            println!("specular white cos {c}: {a:.5} ± {sa:.5} without, {b:.5} ± {sb:.5} with");
            assert!(
                (a - b).abs() < 4.0 * (sa * sa + sb * sb).sqrt(),
                "{a} vs {b}"
            );
        }
    }

    #[test]
    fn diffuse_transmission_chi2() {
        let cases = [
            (0.6, 0.5, 0.0, 0.95),
            (0.6, 0.5, 0.0, 0.3),
            (1.0, 0.2, 0.0, 0.6),
            (0.3, 0.7, 0.4, 0.5),
            (0.8, 0.0, 0.0, 0.7),
        ];
        for (k, (dt, roughness, metallic, c)) in cases.into_iter().enumerate() {
            let p = diffuse_transmitter(dt, Rgb::new(0.3, 0.9, 0.6), params(metallic, roughness));
            let bsdf = Bsdf::from_gltf(&p);
            let name = format!(
                "diffuse transmission {dt} roughness {roughness} metallic {metallic} cos {c}"
            );
            chi2_bsdf(&name, &bsdf, dir(c), 4000 + k as u64);
        }
    }

    #[test]
    fn diffuse_transmission_is_reciprocal_through_the_wall() {
        // Seen from the other face the integrator turns the frame over (s kept, t and n negated): the value
        // for light crossing one way equals the value for light crossing back.
        let over = |v: Vec3| Vec3::new(v.x, -v.y, -v.z);
        let mut rng = Rng::new(73, 73);
        let p = diffuse_transmitter(0.6, Rgb::new(0.9, 0.4, 0.1), params(0.2, 0.4));
        let bsdf = Bsdf::from_gltf(&p);
        for _ in 0..2000 {
            let wo = sampling::cosine_hemisphere(rng.next_2d());
            let wi = sampling::cosine_hemisphere(rng.next_2d());
            for (a, b) in [
                (bsdf.eval(wo, wi), bsdf.eval(wi, wo)),
                (bsdf.eval(wo, -wi), bsdf.eval(over(-wi), over(wo))),
            ] {
                assert!(a.max_element() > 0.0);
                for c in 0..3 {
                    assert!(
                        (a[c] - b[c]).abs() <= 1e-4 * a[c].max(b[c]) + 1e-7,
                        "{a} vs {b}"
                    );
                }
            }
        }
        // The transmitted value is dt · c_dt/π times the Fresnel weight at the mirrored half vector.
        let Bsdf::Pbr(pbr) = bsdf else { panic!() };
        let (wo, wi) = (dir(0.8), -dir(0.5));
        let h = (wo + Vec3::new(wi.x, wi.y, -wi.z)).normalize();
        let kd = (1.0 - 0.2) * (1.0 - fresnel::schlick(pbr.f0, wo.dot(h)).max_element());
        let expected = kd * 0.6 * Rgb::new(0.9, 0.4, 0.1) * FRAC_1_PI * (1.0 - pbr.transmission);
        assert!((bsdf.eval(wo, wi) - expected).abs().max_element() < 1e-6);
    }

    #[test]
    fn zero_diffuse_transmission_and_iridescence_change_nothing() {
        for p in [
            params(0.0, 0.5),
            params(0.5, 0.2),
            params(1.0, 0.0),
            PbrParams {
                transmission: 0.5,
                ..params(0.0, 0.3)
            },
        ] {
            let plain = Bsdf::from_gltf(&p);
            let zero = Bsdf::from_gltf(&PbrParams {
                diffuse_transmission: 0.0,
                diffuse_transmission_color: Rgb::new(0.1, 0.2, 0.3),
                iridescence: 0.0,
                iridescence_ior: 1.8,
                iridescence_thickness: 250.0,
                ..p
            });
            let thin = Bsdf::from_gltf(&PbrParams {
                iridescence: 1.0,
                iridescence_thickness: 0.0,
                ..p
            });
            assert_eq!(plain, zero);
            assert_eq!(plain, thin);
        }
        let lambert = PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..params(0.0, 0.5)
        };
        assert!(matches!(Bsdf::from_gltf(&lambert), Bsdf::Lambert(_)));
        let translucent = diffuse_transmitter(0.5, Rgb::ONE, lambert);
        assert!(matches!(Bsdf::from_gltf(&translucent), Bsdf::Pbr(_)));
    }

    #[test]
    fn an_iridescent_mirror_reflects_the_thin_film_reflectance() {
        // A smooth metal under a film of weight 1: its delta sample's weight f |cos| / pdf is the film's
        // Airy reflectance over the substrate whose F0 is the base colour, per channel at its wavelength.
        let base = Rgb::new(0.9, 0.6, 0.3);
        for (ior, d) in [(1.3f32, 400.0f32), (1.8, 250.0), (2.0, 120.0)] {
            let bsdf = Bsdf::from_gltf(&PbrParams {
                iridescence: 1.0,
                iridescence_ior: ior,
                iridescence_thickness: d,
                ..params(1.0, 0.0)
            });
            for c in [1.0f32, 0.6, 0.2] {
                let s = bsdf.sample(dir(c), 0.5, Vec2::splat(0.5)).unwrap();
                assert!(s.is_delta);
                let w = s.f * s.wi.z / s.pdf;
                for k in 0..3 {
                    let expected = crate::material::airy_reflectance(
                        c,
                        ior,
                        crate::material::substrate_ior(base[k]),
                        d,
                        crate::math::RGB_WAVELENGTHS_NM[k],
                    );
                    assert!((w[k] - expected).abs() < 1e-5, "{w} vs {expected}");
                }
            }
        }
        // Half weight: halfway between Schlick's term and the film's.
        let half = Bsdf::from_gltf(&PbrParams {
            iridescence: 0.5,
            ..params(1.0, 0.0)
        });
        let s = half.sample(dir(0.7), 0.5, Vec2::splat(0.5)).unwrap();
        let w = s.f * s.wi.z / s.pdf;
        let film = crate::material::ThinFilm::new(1.0, 1.3, 400.0).unwrap();
        let schlick = fresnel::schlick(base, 0.7);
        let expected = 0.5 * (schlick + film.reflectance(0.7, base));
        assert!(
            (w - expected).abs().max_element() < 1e-5,
            "{w} vs {expected}"
        );
    }

    /// Reflectance of a film of index `n2` and thickness `d` (nm) between air and a substrate of index `n3` at
    /// normal incidence and wavelength `lambda` (nm): `|(r12 + r23 e^{iδ}) / (1 + r12 r23 e^{iδ})|²` with
    /// `r_ij = (n_i − n_j)/(n_i + n_j)` and `δ = 4π n2 d / λ` (Born & Wolf, "Principles of Optics", §1.6).
    fn film_at_normal_incidence(n2: f64, n3: f64, d: f64, lambda: f64) -> f64 {
        let (r12, r23) = ((1.0 - n2) / (1.0 + n2), (n2 - n3) / (n2 + n3));
        let delta = 4.0 * std::f64::consts::PI * n2 * d / lambda;
        let (num_re, num_im) = (r12 + r23 * delta.cos(), r23 * delta.sin());
        let (den_re, den_im) = (1.0 + r12 * r23 * delta.cos(), r12 * r23 * delta.sin());
        (num_re * num_re + num_im * num_im) / (den_re * den_re + den_im * den_im)
    }

    #[test]
    fn iridescent_glass_reflects_the_film_and_transmits_the_rest() {
        // KHR_materials_iridescence replaces the Fresnel term F of `fresnel_mix`, whose base holds the
        // transmission's `specular_btdf`: a smooth glass (transmission 1) under a film of weight 1 reflects the
        // film's reflectance R and refracts `tint (1 − R) / η²` (the radiance factor), channel by channel.
        let (ior, film_ior, d) = (1.5f32, 1.3f32, 400.0f32);
        let bsdf = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ior,
            iridescence: 1.0,
            iridescence_ior: film_ior,
            iridescence_thickness: d,
            ..params(0.0, 0.0)
        });
        let expected = Rgb::from_array(std::array::from_fn(|k| {
            film_at_normal_incidence(
                film_ior.into(),
                ior.into(),
                d.into(),
                crate::math::RGB_WAVELENGTHS_NM[k].into(),
            ) as f32
        }));
        let wo = Vec3::Z;
        let reflected = bsdf.sample(wo, 0.0, Vec2::splat(0.5)).unwrap();
        assert!(reflected.is_delta && reflected.wi.z > 0.0);
        let r = reflected.f * reflected.wi.z;
        assert!(
            (r - expected).abs().max_element() < 1e-4,
            "{r} vs {expected}"
        );
        let refracted = bsdf.sample(wo, 1.0 - 1e-6, Vec2::splat(0.5)).unwrap();
        assert!(refracted.is_delta && refracted.wi.z < 0.0);
        let t = refracted.f * refracted.wi.z.abs() * ior * ior;
        let tint = Rgb::new(0.9, 0.6, 0.3);
        let expected_t = tint * (Rgb::ONE - expected);
        assert!(
            (t - expected_t).abs().max_element() < 1e-4,
            "{t} vs {expected_t}"
        );
        // The probabilities of the two lobes add up to 1.
        assert!((reflected.pdf + refracted.pdf - 1.0).abs() < 1e-5);
    }

    fn flags(split: &LobeSplit) -> [bool; 3] {
        LobeClass::ALL.map(|class| split.get(class).max_element() > 0.0)
    }

    #[test]
    fn eval_split_adds_up_to_eval_and_follows_the_rule() {
        let mut rng = Rng::new(61, 61);
        for (name, bsdf, classes) in lobe_cases() {
            let mut seen = [false; 3];
            for _ in 0..300 {
                let wo = sampling::uniform_sphere(rng.next_2d());
                // A uniform direction, and a sampled one to reach the narrow lobes.
                let mut wis = vec![sampling::uniform_sphere(rng.next_2d())];
                wis.extend(bsdf.sample(wo, rng.next_f32(), rng.next_2d()).map(|s| s.wi));
                for wi in wis {
                    let (split, f) = (bsdf.eval_split(wo, wi), bsdf.eval(wo, wi));
                    let total = split.total();
                    for c in 0..3 {
                        assert!(
                            (total[c] - f[c]).abs() <= 1e-5 * f[c] + 1e-7,
                            "{name}: {split:?} adds up to {total}, eval {f}"
                        );
                    }
                    let crosses = (wo.z > 0.0) != (wi.z > 0.0);
                    for (k, class) in LobeClass::ALL.into_iter().enumerate() {
                        let v = split.get(class);
                        assert!(
                            crate::math::is_finite_rgb(v) && v.min_element() >= 0.0,
                            "{name}: {split:?}"
                        );
                        if v.max_element() == 0.0 {
                            continue;
                        }
                        seen[k] = true;
                        assert!(classes[k], "{name}: {class:?} {v} for {wo} {wi}");
                        assert_eq!(
                            crosses,
                            class == LobeClass::Transmission,
                            "{name}: {class:?} {v} for {wo} {wi}"
                        );
                        if !classes[2] {
                            assert!(wo.z > 0.0 && wi.z > 0.0, "{name}: opaque from below");
                        }
                    }
                }
            }
            assert_eq!(seen, classes, "{name}: classes found");
        }
    }

    #[test]
    fn split_parts_carry_their_lobes_colours() {
        // With metallic 0 the specular layer (f0 = 0.04, white specular colour) and the interface's reflection
        // are grey, while the diffuse base and the refraction carry the base colour: a part in the wrong
        // class shows.
        let base = params(0.0, 0.4).base_color;
        let cases = [
            params(0.0, 0.4),
            PbrParams {
                transmission: 0.5,
                ..params(0.0, 0.4)
            },
            PbrParams {
                transmission: 1.0,
                ..params(0.0, 0.4)
            },
        ];
        let mut rng = Rng::new(62, 62);
        for p in cases {
            let bsdf = Bsdf::from_gltf(&p);
            let mut found = [false; 3];
            for _ in 0..2000 {
                let wo = sampling::uniform_sphere(rng.next_2d());
                let wi = sampling::uniform_sphere(rng.next_2d());
                let split = bsdf.eval_split(wo, wi);
                let g = split.glossy;
                assert!(
                    g.max_element() - g.min_element() <= 1e-6 * g.max_element(),
                    "{split:?}"
                );
                for v in [split.diffuse, split.transmission] {
                    let ratio = v / base;
                    assert!(
                        ratio.max_element() - ratio.min_element() <= 1e-5 * ratio.max_element()
                    );
                }
                for (k, f) in flags(&split).into_iter().enumerate() {
                    found[k] |= f;
                }
            }
            let expected = [p.transmission < 1.0, true, p.transmission > 0.0];
            assert_eq!(found, expected, "{p:?}");
        }
    }

    #[test]
    fn non_delta_samples_name_a_lobe_holding_their_direction() {
        let mut rng = Rng::new(63, 63);
        for (name, bsdf, classes) in lobe_cases() {
            let mut sampled = [false; 3];
            for c in [0.8, 0.3, -0.6] {
                let wo = dir(c);
                for _ in 0..500 {
                    let Some(s) = bsdf.sample(wo, rng.next_f32(), rng.next_2d()) else {
                        continue;
                    };
                    if s.is_delta {
                        continue;
                    }
                    // The sampled lobe holds wi, on the side it reaches (a GGX reflection below the horizon
                    // is rejected, not handed to the transmissive lobes).
                    let crosses = (s.wi.z > 0.0) != (wo.z > 0.0);
                    assert_eq!(
                        crosses,
                        s.class == LobeClass::Transmission,
                        "{name}: {s:?} on the wrong side"
                    );
                    let v = bsdf.eval_split(wo, s.wi).get(s.class);
                    assert!(
                        v.max_element() > 0.0,
                        "{name}: {s:?} has no value in its class"
                    );
                    sampled[LobeClass::ALL.iter().position(|&k| k == s.class).unwrap()] = true;
                }
            }
            assert_eq!(sampled, classes, "{name}: classes sampled");
        }
    }

    #[test]
    fn delta_samples_belong_to_their_lobes_class() {
        let mut rng = Rng::new(64, 64);
        let mirror = Bsdf::from_gltf(&params(1.0, 0.0));
        for c in [0.9, 0.3, 0.05] {
            for _ in 0..100 {
                let s = mirror
                    .sample(dir(c), rng.next_f32(), rng.next_2d())
                    .unwrap();
                assert!(s.is_delta && s.class == LobeClass::Glossy, "{s:?}");
            }
        }
        // Smooth glass: reflection glossy, refraction transmission, in Fresnel's proportions.
        let ior = 1.5;
        let glass = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ..params(0.0, 0.0)
        });
        for c in [0.9f32, 0.5, 0.2, -0.9, -0.8, -0.5] {
            let wo = dir(c);
            let eta = if c > 0.0 { ior } else { 1.0 / ior };
            let refracted_p = 1.0 - fresnel::dielectric(c, eta) as f64;
            let n = 100_000;
            let mut refracted = 0;
            for _ in 0..n {
                let s = glass.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
                let crosses = (s.wi.z > 0.0) != (wo.z > 0.0);
                let expected = if crosses {
                    refracted += 1;
                    LobeClass::Transmission
                } else {
                    LobeClass::Glossy
                };
                assert!(s.is_delta && s.class == expected, "cos {c}: {s:?}");
            }
            let frac = refracted as f64 / n as f64;
            let se = (refracted_p * (1.0 - refracted_p) / n as f64)
                .sqrt()
                .max(1e-9);
            assert!(
                (frac - refracted_p).abs() < 4.0 * se,
                "cos {c}: refracted {frac} vs 1 − F = {refracted_p}"
            );
        }
        // Inside mixtures: diffuse + mirror + glass (delta lobes of both classes), and a mirror coat.
        let mixed = Bsdf::from_gltf(&PbrParams {
            transmission: 0.5,
            ..params(0.0, 0.0)
        });
        let mut kinds = std::collections::HashSet::new();
        for _ in 0..2000 {
            let wo = dir(0.6);
            let s = mixed.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
            let expected = match (s.is_delta, s.wi.z < 0.0) {
                (false, _) => LobeClass::Diffuse,
                (true, false) => LobeClass::Glossy,
                (true, true) => LobeClass::Transmission,
            };
            assert_eq!(s.class, expected, "{s:?}");
            kinds.insert((s.is_delta, s.class));
        }
        assert_eq!(kinds.len(), 3);
        let coat = coated(1.0, 0.0, params(0.3, 0.5));
        let mut coat_deltas = 0;
        for _ in 0..2000 {
            let s = coat.sample(dir(0.4), rng.next_f32(), rng.next_2d());
            if let Some(s) = s.filter(|s| s.is_delta) {
                coat_deltas += 1;
                assert_eq!(s.class, LobeClass::Glossy);
            }
        }
        assert!(coat_deltas > 100);
    }

    /// The energy each class's channels carry from `wo`, as seen by `n` uniform directions and `n` samples:
    /// per class and channel the largest `eval_split` part, or a delta sample's `f` in its class.
    fn energy_seen(bsdf: &Bsdf, wo: Vec3, n: usize, rng: &mut Rng) -> LobeSplit {
        let mut seen = LobeSplit::ZERO;
        let mut record = |split: LobeSplit| {
            for class in LobeClass::ALL {
                let part = seen.get_mut(class);
                *part = part.max(split.get(class));
            }
        };
        for _ in 0..n {
            record(bsdf.eval_split(wo, sampling::uniform_sphere(rng.next_2d())));
            match bsdf.sample(wo, rng.next_f32(), rng.next_2d()) {
                Some(s) if s.is_delta => record(LobeSplit::only(s.class, s.f)),
                Some(s) => record(bsdf.eval_split(wo, s.wi)),
                None => {}
            }
        }
        seen
    }

    #[test]
    fn colors_are_positive_exactly_where_a_class_carries_energy() {
        let mut cases = lobe_cases();
        cases.push((
            "mirror".into(),
            Bsdf::from_gltf(&params(1.0, 0.0)),
            [false; 3],
        ));
        let glass = PbrParams {
            transmission: 1.0,
            ..params(0.0, 0.0)
        };
        cases.push(("smooth glass".into(), Bsdf::from_gltf(&glass), [false; 3]));
        // A metal with a black channel: seen at normal incidence, its f0 = 0 channel reflects only from
        // tilted microfacets.
        let black_channel = PbrParams {
            base_color: Rgb::new(1.0, 0.5, 0.0),
            ..params(1.0, 0.5)
        };
        cases.push((
            "metal, black blue".into(),
            Bsdf::from_gltf(&black_channel),
            [false; 3],
        ));
        let mut rng = Rng::new(65, 65);
        for (name, bsdf, _) in cases {
            for c in [1.0, 0.9, 0.5, 0.15, -0.9, -0.5, -0.15] {
                let wo = dir(c);
                let colors = bsdf.colors(wo);
                let seen = energy_seen(&bsdf, wo, 20_000, &mut rng);
                for class in LobeClass::ALL {
                    let (color, energy) = (colors.get(class), seen.get(class));
                    let at = format!("{name} cos {c} {class:?}: colour {color}, energy {energy}");
                    assert!(
                        crate::math::is_finite_rgb(color) && color.min_element() >= 0.0,
                        "{at}"
                    );
                    for k in 0..3 {
                        assert!(energy[k] == 0.0 || color[k] > 0.0, "{at}");
                    }
                    if energy == Rgb::ZERO {
                        assert_eq!(color, Rgb::ZERO, "{at}");
                    }
                }
            }
        }
    }

    /// Per class, the mean and standard error of one estimator's per-sample values.
    #[derive(Default)]
    struct ClassMeans {
        sum: LobeSplit,
        sum2: LobeSplit,
        n: usize,
    }

    impl ClassMeans {
        fn add(&mut self, v: LobeSplit) {
            self.sum += v;
            self.sum2 += LobeSplit {
                diffuse: v.diffuse * v.diffuse,
                glossy: v.glossy * v.glossy,
                transmission: v.transmission * v.transmission,
            };
            self.n += 1;
        }

        /// Asserts that every class's mean is `expected` within 4 standard errors (and 1e-5 for exact sums).
        fn assert_mean(&self, expected: LobeSplit, what: &str) {
            let n = self.n as f32;
            for class in LobeClass::ALL {
                let mean = self.sum.get(class) / n;
                let var = (self.sum2.get(class) / n - mean * mean).max(Rgb::ZERO);
                let se = (var / n).powf(0.5);
                let err = (mean - expected.get(class)).abs();
                assert!(
                    err.cmple(4.0 * se + 1e-5 * (1.0 + mean)).all(),
                    "{what} {class:?}: {mean} ± {se}, colour {}",
                    expected.get(class)
                );
            }
        }
    }

    #[test]
    fn colors_are_the_directional_albedos_where_those_are_known() {
        let base = params(0.0, 0.0).base_color;
        let mut rng = Rng::new(66, 66);
        let n = 100_000;
        // Lambert: the albedo above (∫ f_d |cos| dω by uniform-sphere Monte Carlo), nothing below.
        let lambert = Bsdf::from_gltf(&PbrParams {
            metallic: 0.0,
            specular_factor: 0.0,
            ..params(0.0, 0.5)
        });
        assert_eq!(lambert.colors(dir(-0.5)), LobeSplit::ZERO);
        for c in [0.9, 0.2] {
            let wo = dir(c);
            assert_eq!(
                lambert.colors(wo),
                LobeSplit::only(LobeClass::Diffuse, base)
            );
            let mut means = ClassMeans::default();
            for _ in 0..n {
                let wi = sampling::uniform_sphere(rng.next_2d());
                means.add(lambert.eval_split(wo, wi) * (wi.z.abs() / sampling::UNIFORM_SPHERE_PDF));
            }
            means.assert_mean(lambert.colors(wo), &format!("Lambert cos {c}"));
        }
        // Smooth glass: F glossy and tint (1 − F)/η² transmission, the mean weights of the classes' samples.
        let glass = Bsdf::from_gltf(&PbrParams {
            transmission: 1.0,
            ..params(0.0, 0.0)
        });
        for c in [0.9f32, 0.5, 0.2, -0.9, -0.8, -0.5] {
            let wo = dir(c);
            let eta = if c > 0.0 { 1.5f32 } else { 1.0 / 1.5 };
            let f = fresnel::dielectric(c, eta);
            let colors = glass.colors(wo);
            assert_eq!(colors.glossy, Rgb::splat(f));
            assert!(
                (colors.transmission - base * (1.0 - f) / (eta * eta))
                    .abs()
                    .max_element()
                    < 1e-6
            );
            let mut means = ClassMeans::default();
            for _ in 0..n {
                let s = glass.sample(wo, rng.next_f32(), rng.next_2d()).unwrap();
                means.add(LobeSplit::only(s.class, s.f * (s.wi.z.abs() / s.pdf)));
            }
            means.assert_mean(colors, &format!("smooth glass cos {c}"));
        }
        // A mirror coat over a Lambertian base: b(wo) glossy (the delta samples' weights), (1 − b) base diffuse
        // (uniform-sphere Monte Carlo of the diffuse part).
        let coat = coated(
            0.7,
            0.0,
            PbrParams {
                metallic: 0.0,
                specular_factor: 0.0,
                ..params(0.0, 0.5)
            },
        );
        for c in [0.9, 0.3] {
            let wo = dir(c);
            let colors = coat.colors(wo);
            let b = 0.7 * fresnel::schlick(Rgb::splat(0.04), c).x;
            assert!((colors.glossy - Rgb::splat(b)).abs().max_element() < 1e-6);
            let mut means = ClassMeans::default();
            for _ in 0..n {
                let wi = sampling::uniform_sphere(rng.next_2d());
                let mut v = coat.eval_split(wo, wi) * (wi.z.abs() / sampling::UNIFORM_SPHERE_PDF);
                if let Some(s) = coat
                    .sample(wo, rng.next_f32(), rng.next_2d())
                    .filter(|s| s.is_delta)
                {
                    v += LobeSplit::only(s.class, s.f * (s.wi.z / s.pdf));
                }
                means.add(v);
            }
            means.assert_mean(colors, &format!("mirror coat cos {c}"));
        }
    }
}
