//! Renderer services (Fong et al. 2017, "Production Volume Rendering", §5): what the renderer offers to
//! whoever integrates light at a point — a surface BSDF today, a volume later — without them knowing the scene:
//! choosing and sampling a light, and the transmittance of a shadow ray.

use super::RayCounters;
use crate::light::{Light, LightSample};
use crate::math::{Ray, Rgb, Rng, Vec3};
use crate::scene::Scene;

/// Light sampling and shadow-ray transmittance over a scene.
pub struct RendererServices<'a> {
    scene: &'a Scene,
}

/// A light sample chosen from all the scene's lights.
#[derive(Clone, Copy, Debug)]
pub struct ChosenLight {
    /// The sample from the chosen light.
    pub sample: LightSample,
    /// Probability of having chosen that light.
    pub pmf: f32,
}

/// Offset for ray origins leaving a surface, relative to the magnitude of the coordinates.
const RAY_EPSILON: f32 = 1e-4;

/// Moves `p` off the surface with geometric normal `n` toward the side that `dir` points to.
pub fn offset_origin(p: Vec3, n: Vec3, dir: Vec3) -> Vec3 {
    let scale = RAY_EPSILON * p.abs().max_element().max(1.0);
    if n.dot(dir) >= 0.0 {
        p + n * scale
    } else {
        p - n * scale
    }
}

impl<'a> RendererServices<'a> {
    /// Services over `scene`.
    pub fn new(scene: &'a Scene) -> Self {
        Self { scene }
    }

    /// The scene.
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// Chooses a light by power and samples it as seen from `p`.
    pub fn sample_light(&self, p: Vec3, rng: &mut Rng) -> Option<ChosenLight> {
        let (index, pmf) = self.scene.light_sampler.sample(rng.next_f32())?;
        let u = rng.next_2d();
        let sample = self.scene.lights[index].sample_li(p, u, &self.scene.textures)?;
        (sample.pdf > 0.0 && sample.radiance.max_element() > 0.0)
            .then_some(ChosenLight { sample, pmf })
    }

    /// Density, in solid angle at `p`, with which [`Self::sample_light`] would have chosen the point `q` on
    /// the area light `light`.
    pub fn area_light_pdf(&self, light: usize, p: Vec3, q: Vec3) -> f32 {
        match &self.scene.lights[light] {
            Light::Area(a) => {
                self.scene.light_sampler.pmf(light) * a.pdf_from_point(p, q).unwrap_or(0.0)
            }
            _ => 0.0,
        }
    }

    /// Density with which [`Self::sample_light`] would have chosen direction `dir` toward the environment.
    pub fn environment_pdf(&self, dir: Vec3) -> f32 {
        match (self.scene.environment, self.scene.environment_light()) {
            (Some(i), Some(env)) => self.scene.light_sampler.pmf(i) * env.pdf(dir),
            _ => 0.0,
        }
    }

    /// Transmittance of the shadow ray from `origin` along unit `dir` over `distance` (infinite for lights at
    /// infinity): 1 when nothing blocks it, 0 otherwise.
    pub fn transmittance(
        &self,
        origin: Vec3,
        dir: Vec3,
        distance: f32,
        counters: &mut RayCounters,
    ) -> Rgb {
        counters.shadow += 1;
        let ray = Ray::new(origin, dir);
        // Stop short of the light's own surface.
        let t_max = if distance.is_finite() {
            distance * (1.0 - 1e-4)
        } else {
            f32::INFINITY
        };
        if self.scene.occluded(&ray, 0.0, t_max) {
            Rgb::ZERO
        } else {
            Rgb::ONE
        }
    }
}
