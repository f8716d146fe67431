//! The light-selection distribution: lights are chosen with probability proportional to their power
//! (PBRT4 §12.6.2, the power light sampler).

use super::Light;
use crate::math::Distribution1D;

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
