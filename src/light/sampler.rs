//! Light selection: the power sampler, which chooses lights with probability proportional to their power
//! (PBRT4 §12.6.2), and the choice between it and the spatial [`LightBvh`](super::LightBvh) per scene
//! ([`LightSamplerChoice`], `--light-sampler`).

use super::Light;
use crate::math::Distribution1D;

/// Scenes with at least this many bounded lights (emissive triangles, point and spot lights) get the light BVH
/// under [`LightSamplerChoice::Auto`]; fewer keep the power sampler. Measured (256², 64 spp, 2 threads): on
/// the DamagedHelmet benchmark (15,452 textured emissive triangles under a dim sky) the BVH has 1.14× less
/// variance for 1.02× the time; on the Cornell box (2 triangles) the same variance for 1.07× the time. The
/// threshold between those counts is a round guess: no scene between 2 and 15,452 lights was measured.
pub const BVH_MIN_BOUNDED_LIGHTS: usize = 16;

/// Which light-selection distribution next-event estimation uses (`--light-sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LightSamplerChoice {
    /// The BVH where a scene has at least [`BVH_MIN_BOUNDED_LIGHTS`] bounded lights, the power sampler
    /// otherwise.
    #[default]
    Auto,
    /// Every light by its power alone ([`LightSampler`]).
    Power,
    /// The light BVH ([`LightBvh`](super::LightBvh)): bounded lights by their importance at the shading point.
    Bvh,
}

impl LightSamplerChoice {
    /// Whether a scene with `lights` uses the light BVH under this choice.
    pub fn uses_bvh(self, lights: &[Light]) -> bool {
        match self {
            LightSamplerChoice::Auto => bounded_lights(lights) >= BVH_MIN_BOUNDED_LIGHTS,
            LightSamplerChoice::Power => false,
            LightSamplerChoice::Bvh => true,
        }
    }

    /// The sampler this choice gives a scene with `lights`, and why, in words (for `--explain`).
    pub fn explain(self, lights: &[Light]) -> String {
        let bounded = bounded_lights(lights);
        match (self, self.uses_bvh(lights)) {
            (LightSamplerChoice::Power, _) => "power (--light-sampler power)".to_string(),
            (LightSamplerChoice::Bvh, _) => format!(
                "light BVH over {bounded} bounded light(s) (--light-sampler bvh)"
            ),
            (LightSamplerChoice::Auto, true) => format!(
                "light BVH: {bounded} bounded lights (at least {BVH_MIN_BOUNDED_LIGHTS}), chosen by their \
                 importance at each shading point (distance, orientation, the surface's normal)"
            ),
            (LightSamplerChoice::Auto, false) => format!(
                "power: {bounded} bounded light(s), fewer than the {BVH_MIN_BOUNDED_LIGHTS} at which the light \
                 BVH pays"
            ),
        }
    }
}

/// Lights with a position (everything but directional and environment lights).
fn bounded_lights(lights: &[Light]) -> usize {
    lights.iter().filter(|l| !l.is_at_infinity()).count()
}

/// Chooses a light with probability proportional to its emitted power.
#[derive(Clone, Debug)]
pub struct LightSampler {
    distribution: Option<Distribution1D>,
}

impl LightSampler {
    /// Builds the distribution over `lights`; `scene_radius` sizes lights at infinity.
    pub fn new(lights: &[Light], scene_radius: f32) -> Self {
        if lights.is_empty() {
            return Self { distribution: None };
        }
        let powers: Vec<f32> = lights.iter().map(|l| l.power(scene_radius)).collect();
        Self {
            distribution: Some(Distribution1D::new(&powers)),
        }
    }

    /// Picks a light: (index, probability), or `None` without lights.
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        let d = self.distribution.as_ref()?;
        let (i, p) = d.sample_discrete(u);
        (p > 0.0).then_some((i, p))
    }

    /// Picks a light as [`Self::sample`] does, and also returns `u` rescaled to \[0, 1) within the light's share
    /// (see [`Distribution1D::sample_discrete_remapped`]).
    pub fn sample_remapped(&self, u: f32) -> Option<(usize, f32, f32)> {
        let d = self.distribution.as_ref()?;
        let (i, p, rest) = d.sample_discrete_remapped(u);
        (p > 0.0).then_some((i, p, rest))
    }

    /// Probability of picking light `index`.
    pub fn pmf(&self, index: usize) -> f32 {
        self.distribution
            .as_ref()
            .map_or(0.0, |d| d.discrete_pdf(index))
    }
}
