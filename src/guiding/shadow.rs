//! Guided Russian roulette on the shadow rays of next-event estimation (at medium collisions, at the decoupled
//! samples of constant media, and at surfaces): a shadow ray whose transmittance the training expects to be
//! nearly zero is traced only with probability q, and weighed by 1/q when it is.
//!
//! In a dense cloud lit from behind (the backlit cloud of issue 34: optical depth 60–76, albedo 0.99) most
//! scattering events are deep on the dark side, where the transmittance toward the sun is e^{−20} or less; their
//! shadow rays carry nothing, but ratio tracking still walks them until its own roulette (below a running
//! estimate of [`crate::volume::tracking::ROULETTE_THRESHOLD`]) ends them, about 2.3 optical depths of lookups
//! each. The training's shadow rays record their transmittance estimates on a grid
//! ([`super::lit::LitGrid`], the same voxels as the lit grid), and an image path's shadow ray at a point whose
//! voxel learned a mean transmittance T̄ survives with
//!
//! q = clamp(T̄ / [`SHADOW_CUT`], q_min, 1)
//!
//! (q = 1 where the voxel has no record), with q_min = [`SHADOW_MIN_SURVIVAL`] at a medium collision and
//! [`VISIBILITY_MIN_SURVIVAL`] at a decoupled direct-light sample of a constant medium and at a surface.
//! Survivors start their ratio-tracking walk from the weight 1/q
//! ([`crate::volume::Medium::weighted_transmittance`]), so that walk's roulette, which acts on the weighted
//! estimate, does not compound with this one: where the point's transmittance T is below 10 T̄, the weighted
//! estimate T/q falls below that roulette's threshold (0.1) before the walk ends (T/q ≤ [`SHADOW_CUT`] · T/T̄
//! above the floor), and the surviving walk is ended by the same roulette as before, so the estimate's second
//! moment is what it was, for a fraction q of the walks. Any q > 0 keeps the estimate unbiased (E[X/q · 1_{u<q}] = E[X]); the learned mean only decides how
//! much work is saved, and how much variance a voxel whose points see far more light than its mean adds.
//! This is the zero-variance idea applied to the shadow ray's continuation (Herholz et al. 2019 §5; Vorba &
//! Křivánek 2016 decide survival from the expected contribution the same way).
//!
//! The shadow rays of decoupled samples and of surfaces (the door-gap room of issue 34: a hazy room lit by the
//! sun through a 0.2 m gap, where most samples and most of the floor and walls lie in the dark and their shadow
//! rays end on the wall) see a visibility that is 0 or 1, not a transmittance that falls smoothly into the dark:
//! a voxel that the shaft of light only grazes can learn a mean of 0 and still hold lit points, whose survivors
//! carry the weight 1/q_min. So their floor is higher (measured on the door-gap room's decoupled samples, 128²,
//! 128 spp, seeds 1 and 2, against a floor of 0.1: MSE −9% for +4% CPU; on the backlit cloud's collisions a floor
//! of 0.25 gave the same MSE over 8 seeds for +6% CPU: docs/performance.md, "Guided shadow roulette at decoupled
//! samples and surfaces").

/// The learned transmittance below which shadow rays are played roulette on (see the module documentation).
pub const SHADOW_CUT: f32 = 0.01;
/// The smallest survival probability of a shadow ray from a medium collision, where a voxel learned a mean
/// transmittance of (almost) zero: it bounds the weight 1/q of the rare survivor.
pub const SHADOW_MIN_SURVIVAL: f32 = 0.1;
/// The smallest survival probability of a shadow ray whose answer is mostly a visibility, 0 or 1: from a
/// decoupled direct-light sample of a constant medium, or from a surface (see the module documentation).
pub const VISIBILITY_MIN_SURVIVAL: f32 = 0.25;

/// The probability with which a shadow ray from a point whose voxel learned the mean transmittance
/// `mean` (`None`: no record) is traced, at least `min_survival` ([`SHADOW_MIN_SURVIVAL`] or
/// [`VISIBILITY_MIN_SURVIVAL`]).
pub fn survival(mean: Option<f32>, min_survival: f32) -> f32 {
    match mean {
        Some(m) if m.is_finite() => (m / SHADOW_CUT).clamp(min_survival, 1.0),
        _ => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survival_follows_the_learned_transmittance_within_its_bounds() {
        let floor = SHADOW_MIN_SURVIVAL;
        assert_eq!(survival(None, floor), 1.0);
        assert_eq!(survival(Some(f32::NAN), floor), 1.0);
        assert_eq!(survival(Some(0.5), floor), 1.0);
        assert_eq!(survival(Some(SHADOW_CUT), floor), 1.0);
        assert!((survival(Some(SHADOW_CUT * 0.25), floor) - 0.25).abs() < 1e-6);
        assert_eq!(survival(Some(0.0), floor), SHADOW_MIN_SURVIVAL);
        assert_eq!(survival(Some(-1.0), floor), SHADOW_MIN_SURVIVAL);
        let visibility = VISIBILITY_MIN_SURVIVAL;
        assert_eq!(survival(Some(0.0), visibility), VISIBILITY_MIN_SURVIVAL);
        assert!((survival(Some(SHADOW_CUT * 0.5), visibility) - 0.5).abs() < 1e-6);
    }
}
