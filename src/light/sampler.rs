//! Light selection: the power sampler, which chooses lights with probability proportional to their power
//! (PBRT4 §12.6.2), and the choice between it and the spatial [`LightBvh`](super::LightBvh) per scene
//! ([`LightSamplerChoice`], `--light-sampler`).

use super::Light;
use crate::math::Distribution1D;

/// Scenes with at least this many bounded lights (emissive triangles, point and spot lights) get the light BVH
/// under [`LightSamplerChoice::Auto`], however they are grouped. Measured (256², 64 spp, 2 threads): on the
/// DamagedHelmet benchmark (15,452 textured emissive triangles of one mesh under a dim sky) the BVH has 1.14×
/// less variance for 1.02× the time; on the Cornell box (2 triangles) the same variance for 1.07× the time.
pub const BVH_MIN_BOUNDED_LIGHTS: usize = 16;

/// Scenes with at least this many separate emitters (meshes with emissive triangles, point and spot lights)
/// get the light BVH under [`LightSamplerChoice::Auto`], even with fewer than [`BVH_MIN_BOUNDED_LIGHTS`]
/// bounded lights. Measured with `benches/light_sampler_threshold.py` (128², 64 spp, 4 seeds): emitters
/// scattered over a 20 m floor at radiances over two decades give the BVH 2.7× the power sampler's efficiency
/// at 3 emitters, 2.9× at 4, 11-21× at 6-16 and 6-9× at 64-256, and 1.01× at 2; one flat panel cut into 2-64
/// triangles, where a spatial choice cannot gain, gives it 0.5-1.05× (its traversal costs 5-44% more time),
/// so the triangles of one mesh count as one emitter.
pub const BVH_MIN_EMITTERS: usize = 3;

/// Which light-selection distribution next-event estimation uses (`--light-sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightSamplerChoice {
    /// The BVH where a scene has at least `BVH_MIN_BOUNDED_LIGHTS` bounded lights or at least
    /// `BVH_MIN_EMITTERS` separate emitters, the power sampler otherwise.
    #[default]
    Auto,
    /// Every light by its power alone (`LightSampler`).
    Power,
    /// The light BVH (`LightBvh`): bounded lights by their importance at the shading point.
    Bvh,
}

impl crate::params::Choice for LightSamplerChoice {
    const CHOICES: &'static [(&'static str, Self)] = &[
        ("auto", Self::Auto),
        ("power", Self::Power),
        ("bvh", Self::Bvh),
    ];
}

impl LightSamplerChoice {
    /// Whether a scene with `lights` uses the light BVH under this choice.
    pub(crate) fn uses_bvh(self, lights: &[Light]) -> bool {
        match self {
            LightSamplerChoice::Auto => {
                bounded_lights(lights) >= BVH_MIN_BOUNDED_LIGHTS
                    || emitters(lights) >= BVH_MIN_EMITTERS
            }
            LightSamplerChoice::Power => false,
            LightSamplerChoice::Bvh => true,
        }
    }

    /// The sampler this choice gives `scene`, and why, in words (for `--explain`).
    pub fn explain(self, scene: &crate::scene::Scene) -> String {
        self.explain_lights(scene.lights())
    }

    /// The sampler this choice gives a scene with `lights`, and why, in words.
    pub(crate) fn explain_lights(self, lights: &[Light]) -> String {
        let bounded = bounded_lights(lights);
        let emitters = emitters(lights);
        match (self, self.uses_bvh(lights)) {
            (LightSamplerChoice::Power, _) => "power (--light-sampler power)".to_string(),
            (LightSamplerChoice::Bvh, _) => format!(
                "light BVH over {bounded} bounded light(s) (--light-sampler bvh)"
            ),
            (LightSamplerChoice::Auto, true) => format!(
                "light BVH: {bounded} bounded light(s) in {emitters} emitter(s) (at least \
                 {BVH_MIN_BOUNDED_LIGHTS} lights or {BVH_MIN_EMITTERS} emitters), chosen by their importance at \
                 each shading point (distance, orientation, the surface's normal)"
            ),
            (LightSamplerChoice::Auto, false) => format!(
                "power: {bounded} bounded light(s) in {emitters} emitter(s), fewer than the \
                 {BVH_MIN_BOUNDED_LIGHTS} lights or {BVH_MIN_EMITTERS} emitters at which the light BVH pays"
            ),
        }
    }
}

/// Lights with a position (everything but directional and environment lights).
fn bounded_lights(lights: &[Light]) -> usize {
    lights.iter().filter(|l| !l.is_at_infinity()).count()
}

/// Separate bounded emitters: each point or spot light, and each mesh with emissive triangles (counted once).
fn emitters(lights: &[Light]) -> usize {
    let mut meshes: Vec<u32> = lights
        .iter()
        .filter_map(|l| match l {
            Light::Area(a) => Some(a.mesh),
            _ => None,
        })
        .collect();
    meshes.sort_unstable();
    meshes.dedup();
    let punctual = lights
        .iter()
        .filter(|l| !l.is_at_infinity() && !matches!(l, Light::Area(_)))
        .count();
    meshes.len() + punctual
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{AreaLight, DirectionalLight, PointLight};
    use crate::math::{Rgb, Vec2, Vec3};

    /// Triangle `i` of mesh `mesh`: small, apart from the others, emitting.
    fn triangle(i: u32, mesh: u32) -> Light {
        let c = Vec3::new(i as f32, 2.0, 0.0);
        let v = [c, c + Vec3::X * 0.1, c + Vec3::Z * 0.1];
        Light::Area(AreaLight::new(v, [Vec2::ZERO; 3], Rgb::ONE, None, [i, mesh]).unwrap())
    }

    fn point() -> Light {
        Light::Point(PointLight {
            position: Vec3::ONE,
            intensity: Rgb::ONE,
        })
    }

    #[test]
    fn auto_counts_the_triangles_of_one_mesh_as_one_emitter() {
        let auto = LightSamplerChoice::Auto;
        // The Cornell box: one quad light of two triangles.
        assert!(!auto.uses_bvh(&[triangle(0, 0), triangle(1, 0)]));
        // Two emitters, and lights at infinity do not count.
        let sun = Light::Directional(DirectionalLight {
            direction: Vec3::Y,
            irradiance: Rgb::ONE,
        });
        assert!(!auto.uses_bvh(&[triangle(0, 0), point(), sun.clone(), sun]));
        // Three emitters: two meshes and a point light; three single-triangle meshes.
        assert!(auto.uses_bvh(&[triangle(0, 0), triangle(1, 1), triangle(2, 1), point()]));
        assert!(auto.uses_bvh(&[triangle(0, 0), triangle(1, 1), triangle(2, 2)]));
        // One mesh: power below BVH_MIN_BOUNDED_LIGHTS triangles, the BVH from there.
        let panel = |n: u32| (0..n).map(|i| triangle(i, 7)).collect::<Vec<_>>();
        assert!(!auto.uses_bvh(&panel(BVH_MIN_BOUNDED_LIGHTS as u32 - 1)));
        assert!(auto.uses_bvh(&panel(BVH_MIN_BOUNDED_LIGHTS as u32)));
        assert!(auto
            .explain_lights(&panel(2))
            .contains("power: 2 bounded light(s) in 1 emitter(s)"));
        assert!(LightSamplerChoice::Bvh.uses_bvh(&panel(1)));
        assert!(!LightSamplerChoice::Power.uses_bvh(&panel(100)));
    }
}
