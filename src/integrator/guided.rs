//! Path guiding inside the path tracer: when the render trained a guiding cache
//! ([`RendererServices::guide`]), a medium scattering event samples its direction from the product of the
//! cache's vMF mixture at that point with the phase function ([`VmfMixture::product`], Herholz et al. 2019,
//! "Volume Path Guiding Based on Zero-Variance Random Walk Theory", §4) with probability [`GUIDE_PROBABILITY`]
//! and from the phase function otherwise, and weights it by ρ(ω)/(α q(ω) + (1 − α) ρ(ω)): one-sample MIS with a fixed
//! selection probability (Müller et al. 2017, "Practical Path Guiding for Efficient Light-Transport
//! Simulation", with the phase function in the BSDF's place). A Lambertian surface samples the product of the
//! cache's distribution with the cosine to its shading normal in the mixture with its BSDF, weighting by
//! f cos θ/(α q + (1 − α) p_bsdf). Next-event estimation there is weighed by the power heuristic against that
//! mixture's density ([`mixture_pdf`]), so the estimate stays unbiased.
//!
//! A path whose throughput exceeds [`GUIDE_MAX_THROUGHPUT`] samples the phase function or BSDF alone
//! (no guide is looked up) until it falls back: a guided event's weight is at most
//! 1/(1 − [`GUIDE_PROBABILITY`]), and over the hundreds of events of a walk in a dense medium their product
//! otherwise grew without bound with guiding by the radiance alone (measured: 13x the MSE of unguided paths on
//! the backlit cloud). Choosing the strategy from the path's past keeps the estimate unbiased: each event's
//! weight uses the density it sampled with.

use super::services::RendererServices;
use crate::guiding::vmf::lobe_kappa;
use crate::guiding::{VmfMixture, GUIDE_MAX_THROUGHPUT, GUIDE_PROBABILITY};
use crate::material::{Bsdf, BsdfSample, LobeClass};
use crate::math::sampling::ONE_BELOW;
use crate::math::{Frame, Rgb, Rng, Vec2, Vec3};
use crate::volume::PhaseFunction;

/// The product of the guiding cache's distribution at a surface point `p` with the cosine to the shading
/// normal `n` (a Lambertian BSDF's shape), when the render is guided, the cache learned one there, and the path's
/// throughput `beta` is at most [`GUIDE_MAX_THROUGHPUT`].
pub(super) fn surface_guide_at(
    services: &RendererServices,
    beta: Rgb,
    p: Vec3,
    n: Vec3,
) -> Option<VmfMixture> {
    let field = services
        .guide()
        .filter(|_| beta.max_element() <= GUIDE_MAX_THROUGHPUT)?;
    // The clamped cosine max(cos θ, 0)/π as the vMF lobe of the same mean cosine (2/3) about the normal.
    field.vmf_at(p)?.product(n, lobe_kappa(2.0 / 3.0))
}

/// The product of the guiding cache's distribution at a medium point `p` with the phase function `phase` for
/// light leaving toward `wo`, under the same conditions as [`surface_guide_at`].
pub(super) fn medium_guide_at(
    services: &RendererServices,
    beta: Rgb,
    p: Vec3,
    phase: &PhaseFunction,
    wo: Vec3,
) -> Option<VmfMixture> {
    let field = services
        .guide()
        .filter(|_| beta.max_element() <= GUIDE_MAX_THROUGHPUT)?;
    let mixture = field.vmf_at(p)?;
    match *phase {
        // A constant factor: the product is the learned distribution itself.
        PhaseFunction::Isotropic => Some(*mixture),
        // Henyey & Greenstein 1941 as the vMF lobe of the same mean cosine g about the forward direction −ω_o
        // (of −g about ω_o for back scattering; Herholz et al. 2019 §4 match the mean cosine too).
        PhaseFunction::HenyeyGreenstein { g } => {
            let axis = if g >= 0.0 { -wo } else { wo };
            mixture.product(axis, lobe_kappa(g.abs()))
        }
    }
}

/// The density of the direction `wi_world` under the one-sample MIS mixture α q + (1 − α) p of the guide's
/// distribution q and the phase function's or BSDF's density `pdf` = p(wi); `pdf` alone unguided.
pub(super) fn mixture_pdf(guide: Option<&VmfMixture>, wi_world: Vec3, pdf: f32) -> f32 {
    match guide {
        Some(d) => GUIDE_PROBABILITY * d.pdf(wi_world) + (1.0 - GUIDE_PROBABILITY) * pdf,
        None => pdf,
    }
}

/// The one-sample MIS choice of a guided event from its 2-D sample `u`: the guide when `u.x` <
/// [`GUIDE_PROBABILITY`], else the phase function or BSDF, with `u.x` rescaled to \[0, 1) within the part chosen,
/// so that each strategy keeps the stratification of the sampler's points (a separate random number for the
/// choice measured worse on the Sobol sampler's early bounces).
fn choose_strategy(u: Vec2) -> (bool, Vec2) {
    let a = GUIDE_PROBABILITY;
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
    guide: Option<&VmfMixture>,
    wo: Vec3,
    rng: &mut Rng,
) -> Option<(Vec3, f32, f32)> {
    let Some(distribution) = guide else {
        let (wi, pdf) = phase.sample(wo, rng.sample_2d());
        return Some((wi, pdf, 1.0));
    };
    let (guided, u) = choose_strategy(rng.sample_2d());
    let wi = if guided {
        distribution.sample(u)
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
    guide: Option<&VmfMixture>,
    frame: &Frame,
    wo: Vec3,
    rng: &mut Rng,
    direction_pdf: impl Fn(Vec3) -> f32,
) -> Option<BsdfSample> {
    let Some(distribution) = guide else {
        return bsdf.sample(wo, lobe_choice(bsdf, rng), rng.sample_2d());
    };
    let u_lobe = lobe_choice(bsdf, rng);
    let (guided, u) = choose_strategy(rng.sample_2d());
    let wi = if guided {
        Some(frame.to_local(distribution.sample(u)))
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
