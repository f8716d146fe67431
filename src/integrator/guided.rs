//! Path guiding inside the path tracer: when the render trained a guiding cache
//! ([`RendererServices::guide`]), a medium scattering event samples its direction from the product of the
//! cache's vMF mixture at that point with the phase function ([`VmfMixture::product`], Herholz et al. 2019,
//! "Volume Path Guiding Based on Zero-Variance Random Walk Theory", §4) with probability α and from the phase
//! function otherwise, and weights it by ρ(ω)/(α q(ω) + (1 − α) ρ(ω)): one-sample MIS (Müller et al. 2017,
//! "Practical Path Guiding for Efficient Light-Transport Simulation", with the phase function in the BSDF's
//! place), α the cell's learned selection probability ([`Guide`]; [`GUIDE_PROBABILITY`] on training paths; a
//! cell that learned 0 makes no product). A Lambertian surface samples the product of the
//! cache's distribution with the cosine to its shading normal in the mixture with its BSDF, weighting by
//! f cos θ/(α q + (1 − α) p_bsdf). Next-event estimation at a medium event is weighed by the power heuristic
//! against the mixture's density ([`mixture_pdf`]); at a guided surface against the BSDF's density alone, and
//! the emission its sampled direction reaches (guided or not) is weighed with the same density, so that the
//! two weights still sum to 1 and the estimate stays unbiased (Veach 1997, §9.2: any weights that sum to 1 over
//! the strategies that can produce a path). Weighed against the mixture, a guide that points at a light takes
//! its direct light from next-event estimation and gives it to the noisier guided direction (measured on the
//! baffle box: docs/performance.md, "Next-event estimation against the BSDF at guided surfaces").
//!
//! A path whose throughput exceeds [`GUIDE_MAX_THROUGHPUT`] samples the phase function or BSDF alone
//! (no guide is looked up) until it falls back: a guided event's weight is at most
//! 1/(1 − [`GUIDE_PROBABILITY`]), and over the hundreds of events of a walk in a dense medium their product
//! otherwise grew without bound with guiding by the radiance alone (measured: 13x the MSE of unguided paths on
//! the backlit cloud). Choosing the strategy from the path's past keeps the estimate unbiased: each event's
//! weight uses the density it sampled with.

use super::services::RendererServices;
use crate::guiding::lit::DistanceGuide;
use crate::guiding::vmf::lobe_kappa;
use crate::guiding::{
    VmfMixture, GUIDED_DISTANCE_PROBABILITY, GUIDE_MAX_THROUGHPUT, GUIDE_PROBABILITY,
};
use crate::material::{Bsdf, BsdfSample, LobeClass};
use crate::math::sampling::ONE_BELOW;
use crate::math::Ray;
use crate::math::{Frame, Rgb, Rng, Vec2, Vec3};
use crate::volume::{ConstantScattering, PhaseFunction};

/// A guided event's guide: the product of the cache's distribution with the phase function or the cosine, and
/// the probability `alpha` with which the event samples it (the cell's learned selection probability,
/// [`crate::guiding::GuidingField::guide_at`]; [`GUIDE_PROBABILITY`] on training paths, whose records it is
/// learned from).
#[derive(Clone, Copy, Debug)]
pub(super) struct Guide {
    /// The product.
    pub product: VmfMixture,
    /// The probability of sampling it.
    pub alpha: f32,
}

/// The cache's distribution at `p` and its selection probability, when the render is guided, the cache learned
/// one there, the path's throughput `beta` is at most [`GUIDE_MAX_THROUGHPUT`] and the probability is positive
/// (a cell where it is 0 makes no product); a `training` path uses [`GUIDE_PROBABILITY`].
fn cell_guide<'a>(
    services: &RendererServices<'a>,
    beta: Rgb,
    p: Vec3,
    training: bool,
) -> Option<(&'a VmfMixture, f32)> {
    let field = services
        .guide()
        .filter(|_| beta.max_element() <= GUIDE_MAX_THROUGHPUT)?;
    let (mixture, alpha) = field.guide_at(p)?;
    let alpha = if training { GUIDE_PROBABILITY } else { alpha };
    (alpha > 0.0).then_some((mixture, alpha))
}

/// The guide at a surface point `p` of shading normal `n` (the product with the cosine, a Lambertian BSDF's
/// shape), under the conditions of [`cell_guide`].
pub(super) fn surface_guide_at(
    services: &RendererServices,
    beta: Rgb,
    p: Vec3,
    n: Vec3,
    training: bool,
) -> Option<Guide> {
    let (mixture, alpha) = cell_guide(services, beta, p, training)?;
    // The clamped cosine max(cos θ, 0)/π as the vMF lobe of the same mean cosine (2/3) about the normal.
    let product = mixture.product(n, lobe_kappa(2.0 / 3.0))?;
    Some(Guide { product, alpha })
}

/// The guide at a medium point `p` (the product with the phase function `phase` for light leaving toward
/// `wo`), under the conditions of [`cell_guide`].
pub(super) fn medium_guide_at(
    services: &RendererServices,
    beta: Rgb,
    p: Vec3,
    phase: &PhaseFunction,
    wo: Vec3,
    training: bool,
) -> Option<Guide> {
    let (mixture, alpha) = cell_guide(services, beta, p, training)?;
    let product = match *phase {
        // A constant factor: the product is the learned distribution itself.
        PhaseFunction::Isotropic => *mixture,
        // Henyey & Greenstein 1941 as the vMF lobe of the same mean cosine g about the forward direction −ω_o
        // (of −g about ω_o for back scattering; Herholz et al. 2019 §4 match the mean cosine too).
        PhaseFunction::HenyeyGreenstein { g } => {
            let axis = if g >= 0.0 { -wo } else { wo };
            mixture.product(axis, lobe_kappa(g.abs()))?
        }
    };
    Some(Guide { product, alpha })
}

/// The density of the direction `wi_world` under the one-sample MIS mixture α q + (1 − α) p of the guide's
/// distribution q (α its selection probability) and the phase function's or BSDF's density `pdf` = p(wi);
/// `pdf` alone unguided.
pub(super) fn mixture_pdf(guide: Option<&Guide>, wi_world: Vec3, pdf: f32) -> f32 {
    match guide {
        Some(g) => g.alpha * g.product.pdf(wi_world) + (1.0 - g.alpha) * pdf,
        None => pdf,
    }
}

/// The one-sample MIS choice of a guided event from its 2-D sample `u`: the guide when `u.x` < `a` (its
/// probability), else the other strategy, with `u.x` rescaled to \[0, 1) within the part chosen, so that each
/// strategy keeps the stratification of the sampler's points (a separate random number for the choice measured
/// worse on the Sobol sampler's early bounces).
fn choose_strategy(u: Vec2, a: f32) -> (bool, Vec2) {
    if u.x < a {
        (true, Vec2::new((u.x / a).min(ONE_BELOW), u.y))
    } else {
        (
            false,
            Vec2::new(((u.x - a) / (1.0 - a)).min(ONE_BELOW), u.y),
        )
    }
}

/// The direction to continue from a medium scattering event at which light leaves toward `wo`: the phase
/// function's sample, or, guided, the mixture's with the product `guide`. Returns the direction, its density and
/// the throughput factor ρ/pdf (1 for the phase function sampled exactly), or `None` where the mixture's
/// density is not positive.
pub(super) fn sample_phase(
    phase: &PhaseFunction,
    guide: Option<&Guide>,
    wo: Vec3,
    rng: &mut Rng,
) -> Option<(Vec3, f32, f32)> {
    let Some(g) = guide else {
        let (wi, pdf) = phase.sample(wo, rng.sample_2d());
        return Some((wi, pdf, 1.0));
    };
    let (guided, u) = choose_strategy(rng.sample_2d(), g.alpha);
    let wi = if guided {
        g.product.sample(u)
    } else {
        phase.sample(wo, u).0
    };
    let pdf = mixture_pdf(guide, wi, phase.eval(wo, wi));
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    Some((wi, pdf, phase.eval(wo, wi) / pdf))
}

/// The value that chooses `bsdf`'s lobe in [`Bsdf::sample`]: drawn where it has several, its dimension used up
/// without computing it for a Lambertian BSDF, which has one (a Sobol value measured 1.6 % of the peer
/// benchmark's mirrors render there), so that every later value is the same either way.
fn lobe_choice(bsdf: &Bsdf, rng: &mut Rng) -> f32 {
    if let Bsdf::Lambert(_) = bsdf {
        rng.skip_1d();
        0.0
    } else {
        rng.sample_1d()
    }
}

/// The direction to continue from a surface (`frame` its shading frame, `wo` local): the BSDF's sample, or,
/// guided, the mixture's, with the mixture's density (`direction_pdf`, local directions) and the BSDF's value.
pub(super) fn sample_bsdf(
    bsdf: &Bsdf,
    guide: Option<&Guide>,
    frame: &Frame,
    wo: Vec3,
    rng: &mut Rng,
    direction_pdf: impl Fn(Vec3) -> f32,
) -> Option<BsdfSample> {
    let Some(g) = guide else {
        return bsdf.sample(wo, lobe_choice(bsdf, rng), rng.sample_2d());
    };
    let u_lobe = lobe_choice(bsdf, rng);
    let (guided, u) = choose_strategy(rng.sample_2d(), g.alpha);
    let wi = if guided {
        Some(frame.to_local(g.product.sample(u)))
    } else {
        bsdf.sample(wo, u_lobe, u).map(|b| b.wi)
    };
    wi.map(|wi| BsdfSample {
        wi,
        f: bsdf.eval(wo, wi),
        pdf: direction_pdf(wi),
        is_delta: false,
        class: LobeClass::Diffuse,
        // Guided surfaces are Lambertian: nothing refracts.
        eta: 1.0,
    })
}

/// The distance of the decoupled direct-light sample on the segment [0, `length`] of `ray` through the
/// homogeneous medium `c`, for a path of `throughput`, from the 2-D sample `u`, and its density: unguided, or
/// where the cache's lit grid knows no light on the segment, the free-flight density truncated to the segment
/// ([`ConstantScattering::sample_in_segment`]); else the one-sample mixture of the grid's distance density
/// ([`DistanceGuide`], with probability [`GUIDED_DISTANCE_PROBABILITY`]) and that density
/// ([`distance_from_mixture`]).
pub(super) fn decoupled_distance(
    services: &RendererServices,
    c: &ConstantScattering,
    ray: &Ray,
    length: f32,
    throughput: Rgb,
    u: Vec2,
) -> Option<(f32, f32)> {
    let guide = services.guide().and_then(|field| {
        field.distance_guide(ray.origin, ray.dir, length, c.sigma_t.element_sum() / 3.0)
    });
    distance_from_mixture(guide.as_ref(), c, length, throughput, u)
}

/// A distance on [0, `length`] from `u` and its density: with `guide`, the one-sample mixture a p_g + (1 − a)
/// p_ff of the guide's density and the truncated free-flight density (a = [`GUIDED_DISTANCE_PROBABILITY`],
/// chosen by `u.x` as [`choose_strategy`] does), its density evaluated at the distance drawn whichever drew
/// it, so that the estimate stays unbiased whatever the guide; without, the free-flight density's sample.
fn distance_from_mixture(
    guide: Option<&DistanceGuide>,
    c: &ConstantScattering,
    length: f32,
    throughput: Rgb,
    u: Vec2,
) -> Option<(f32, f32)> {
    let Some(guide) = guide else {
        return c.sample_in_segment(u, length, throughput);
    };
    let a = GUIDED_DISTANCE_PROBABILITY;
    let t = match choose_strategy(u, a) {
        (true, u) => guide.sample(u.x),
        (false, u) => c.sample_in_segment(u, length, throughput)?.0,
    };
    let pdf = a * guide.pdf(t) + (1.0 - a) * c.segment_pdf(t, length, throughput);
    Some((t, pdf))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::guiding::lit::{LitGrid, LitRecord};
    use crate::math::Aabb;
    use crate::volume::ChannelSampling;

    /// A learned mixture for the guided-sampling tests: a sharp lobe (κ 20, weight 0.7) about `sharp_axis`
    /// (normalised) and a broad one (κ 2, weight 0.3) about −x.
    fn two_lobes(sharp_axis: Vec3) -> VmfMixture {
        VmfMixture::new(&[
            crate::guiding::vmf::VmfLobe {
                mu: sharp_axis.normalize(),
                kappa: 20.0,
                weight: 0.7,
            },
            crate::guiding::vmf::VmfLobe {
                mu: -Vec3::X,
                kappa: 2.0,
                weight: 0.3,
            },
        ])
        .unwrap()
    }

    /// Guided phase sampling at a selection probability below and at [`GUIDE_PROBABILITY`] draws directions
    /// with the mixture density it claims (chi-square), which is what its weight and the MIS weights divide by.
    #[test]
    fn guided_phase_sampling_fits_its_mixture_density() {
        let product = two_lobes(Vec3::new(0.3, -0.5, 0.81));
        let phase = PhaseFunction::HenyeyGreenstein { g: 0.3 };
        let wo = Vec3::new(0.0, 0.6, 0.8);
        for (i, alpha) in [0.25, GUIDE_PROBABILITY].into_iter().enumerate() {
            let guide = Guide { product, alpha };
            crate::math::chi2::assert_sampler_fits(
                &format!("guided phase sampling, α {alpha}"),
                200_000,
                40 + i as u64,
                |rng| {
                    let (wi, pdf, weight) = sample_phase(&phase, Some(&guide), wo, rng)?;
                    assert!((weight * pdf - phase.eval(wo, wi)).abs() < 1e-5 * phase.eval(wo, wi));
                    Some(wi)
                },
                |w| mixture_pdf(Some(&guide), w, phase.eval(wo, w)) as f64,
            );
        }
    }

    /// A guide at a Lambertian surface of shading normal `n`: a two-lobe learned mixture's product with the
    /// cosine, as [`surface_guide_at`] makes it, sampled with probability `alpha`.
    fn lambert_guide(n: Vec3, alpha: f32) -> Guide {
        let mixture = two_lobes(Vec3::new(0.3, 0.5, 0.81));
        let product = mixture.product(n, lobe_kappa(2.0 / 3.0)).unwrap();
        Guide { product, alpha }
    }

    /// Draws guided directions at a Lambertian surface (`sample_bsdf` with a guide sampled with probability
    /// `sampled`) and checks them by chi-square against the mixture density of a guide of probability `claimed`,
    /// the density the path divides by where the two are equal; each sample is the BSDF's value there.
    fn check_guided_lambert(sampled: f32, claimed: f32, seed: u64) {
        let n = Vec3::new(0.2, 0.9, -0.1).normalize();
        let frame = Frame::from_normal(n);
        let bsdf = Bsdf::Lambert(crate::material::Lambert {
            albedo: Rgb::splat(0.7),
        });
        let wo = frame.to_local(Vec3::new(0.1, 0.8, 0.6).normalize());
        let (guide, claimed) = (lambert_guide(n, sampled), lambert_guide(n, claimed));
        let density =
            |g: &Guide, wi: Vec3| mixture_pdf(Some(g), frame.to_world(wi), bsdf.pdf(wo, wi));
        crate::math::chi2::assert_sampler_fits(
            &format!(
                "guided Lambertian sampling, α {sampled} against {}",
                claimed.alpha
            ),
            200_000,
            seed,
            |rng| {
                let s = sample_bsdf(&bsdf, Some(&guide), &frame, wo, rng, |wi| {
                    density(&guide, wi)
                })?;
                assert_eq!(s.f, bsdf.eval(wo, s.wi));
                Some(frame.to_world(s.wi))
            },
            |w| density(&claimed, frame.to_local(w)) as f64,
        );
    }

    /// Guided sampling at a Lambertian surface (the learned mixture's product with the cosine, in one-sample MIS
    /// with the BSDF's cosine-weighted sample) draws directions with the mixture density the path divides by, at
    /// a selection probability below and at [`GUIDE_PROBABILITY`] (chi-square).
    #[test]
    fn guided_lambert_sampling_fits_its_mixture_density() {
        check_guided_lambert(0.25, 0.25, 50);
        check_guided_lambert(GUIDE_PROBABILITY, GUIDE_PROBABILITY, 51);
    }

    /// The check above can fail: directions drawn with the guide chosen a quarter of the time do not fit the
    /// density of a guide chosen half of the time.
    #[test]
    #[should_panic(expected = "chi-square rejects")]
    fn guided_lambert_sampling_against_another_selection_probability_is_rejected() {
        check_guided_lambert(0.25, 0.5, 52);
    }

    /// A lit grid over [0, 2]³ that knows light in the slab 0.8 ≤ x < 1 only.
    fn slab() -> LitGrid {
        let mut grid = LitGrid::new(Aabb::new(Vec3::ZERO, Vec3::splat(2.0)));
        let records: Vec<LitRecord> = (0..200)
            .map(|k| {
                let x = (k as f32 + 0.5) / 100.0;
                LitRecord {
                    p: Vec3::new(x, 1.0, 1.0),
                    value: if (0.8..1.0).contains(&x) { 3.0 } else { 0.0 },
                }
            })
            .collect();
        grid.add(&records);
        grid.finish_iteration();
        grid
    }

    /// The mixture's density integrates to 1 over the segment, for grey and chromatic media (the latter with
    /// its channel mixture), and its samples keep the density they claim (chi-square).
    #[test]
    fn the_guided_distance_mixture_is_a_density_on_the_segment() {
        let grid = slab();
        let grey = ConstantScattering {
            sigma_s: Rgb::splat(0.6),
            sigma_t: Rgb::splat(0.8),
            phase: PhaseFunction::Isotropic,
            spectral_mis: None,
        };
        let chromatic = ConstantScattering {
            sigma_s: Rgb::new(0.3, 0.5, 1.0),
            sigma_t: Rgb::new(0.5, 1.0, 2.0),
            spectral_mis: Some(ChannelSampling::Throughput),
            ..grey
        };
        let throughput = Rgb::new(1.0, 0.5, 0.25);
        let length = 1.9;
        let origin = Vec3::new(0.05, 1.0, 1.0);
        for (i, c) in [grey, chromatic].iter().enumerate() {
            let guide = grid
                .distance_guide(origin, Vec3::X, length, c.sigma_t.element_sum() / 3.0)
                .unwrap();
            let n = 200_000;
            let mut rng = Rng::new(7, i as u64);
            let mut density_at = Vec::new();
            let integral: f64 = (0..n)
                .map(|k| {
                    let t = (k as f32 + 0.5) / n as f32 * length;
                    let pdf = GUIDED_DISTANCE_PROBABILITY * guide.pdf(t)
                        + (1.0 - GUIDED_DISTANCE_PROBABILITY)
                            * c.segment_pdf(t, length, throughput);
                    pdf as f64 * (length / n as f32) as f64
                })
                .sum();
            assert!((integral - 1.0).abs() < 1e-3, "{i}: {integral}");
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("guided distance mixture {i}"),
                200_000,
                (0.0, length as f64),
                || {
                    let (t, pdf) =
                        distance_from_mixture(Some(&guide), c, length, throughput, rng.next_2d())
                            .unwrap();
                    density_at.push((t, pdf));
                    t
                },
                |t| {
                    let t = t as f32;
                    (GUIDED_DISTANCE_PROBABILITY * guide.pdf(t)
                        + (1.0 - GUIDED_DISTANCE_PROBABILITY)
                            * c.segment_pdf(t, length, throughput)) as f64
                },
            );
            // Over a third of the samples land in the lit slab, [0.75, 0.95] of the segment (a tenth of it).
            let lit = density_at
                .iter()
                .filter(|(t, _)| (0.75..0.95).contains(t))
                .count();
            assert!(lit * 3 > density_at.len(), "{i}: {lit}");
        }
    }
}
