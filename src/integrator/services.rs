//! Renderer services (Fong et al. 2017, "Production Volume Rendering", §5): what the renderer offers to
//! whoever integrates light at a point — a surface BSDF or a medium's scattering event — without them knowing
//! the scene: choosing and sampling a light, and the transmittance of a shadow ray through everything in
//! between (index-matched boundaries, nested interiors, overlapping position-filled volumes).

use super::{MediumStack, PathCounters};
use crate::geometry::ShadowSegment;
use crate::guiding::GuidingField;
use crate::light::{Light, LightBvh, LightContext, LightSample};
use crate::math::{Ray, Rgb, Rng, Vec2, Vec3};
use crate::scene::Scene;
use crate::volume::Medium;

/// Light sampling and shadow-ray transmittance over a scene.
#[derive(Clone, Copy)]
pub struct RendererServices<'a> {
    scene: &'a Scene,
    /// The light BVH when the render chose it ([`crate::light::LightSamplerChoice`]); `None`: lights are
    /// chosen by power.
    light_bvh: Option<&'a LightBvh>,
    /// The guiding cache paths sample directions from at medium scattering events, when the render is guided.
    guide: Option<&'a GuidingField>,
    /// The training's value of the pixel whose samples are traced, which guided Russian roulette and splitting
    /// compare paths with ([`crate::guiding::adjoint`]); `None`: classic Russian roulette.
    pixel_estimate: Option<f32>,
}

/// A light sample chosen from all the scene's lights.
#[derive(Clone, Copy, Debug)]
pub struct ChosenLight {
    /// The sample from the chosen light.
    pub sample: LightSample,
    /// Probability of having chosen that light.
    pub pmf: f32,
    /// Index of the light in the scene.
    pub index: usize,
}

/// In scenes with at most this many lights, none of them emissive triangles, next-event estimation at
/// *surfaces* samples every light (one shadow ray each) instead of choosing one: choosing by power ignores where a light is shadowed (a
/// floor under smoke, in the sun's shadow, lit by the sky), and at a surface the extra shadow rays cost less
/// than the selection noise they remove. Inside media one light is still chosen by power: there every shadow
/// ray is tracked through the medium, and measured on the peer benchmark's cloud and plume, sampling every
/// light cost more than it saved there (see docs/performance.md).
pub const EVERY_LIGHT_MAX: usize = 4;

/// Surfaces a shadow ray may pass through (index-matched boundaries) before it is considered blocked.
const MAX_SHADOW_CROSSINGS: u32 = 64;
/// Most media a segment can be inside at once (one interior plus overlapping volumes).
pub const MAX_SEGMENT_MEDIA: usize = 8;

/// The media a ray segment runs through: the current interior and every position-filled volume whose bounds
/// it crosses.
#[derive(Clone, Copy, Debug, Default)]
pub struct SegmentMedia {
    ids: [u32; MAX_SEGMENT_MEDIA],
    len: usize,
}

impl SegmentMedia {
    /// The medium indices.
    pub fn ids(&self) -> &[u32] {
        &self.ids[..self.len]
    }

    /// The same media in the order the integrator asks them for their free flights: media that collide and
    /// do not emit, then those that collide and emit, then those that never collide (absorption only), each
    /// group in its order here. An absorber's weight is its transmittance to the segment's event, so it must be
    /// asked once the event is known; an emitting medium's samples are weighted by the transmittance of the
    /// media asked after it, fewest when it comes late.
    pub fn in_flight_order(&self, media: &[std::sync::Arc<dyn Medium>]) -> Self {
        let rank = |&m: &u32| {
            let medium = &media[m as usize];
            match (medium.is_absorbing_only(), medium.is_emissive()) {
                (true, _) => 2,
                (false, true) => 1,
                (false, false) => 0,
            }
        };
        let mut ordered = *self;
        ordered.ids[..self.len].sort_by_key(rank);
        ordered
    }

    fn push(&mut self, id: u32) {
        if self.len < MAX_SEGMENT_MEDIA && !self.ids().contains(&id) {
            self.ids[self.len] = id;
            self.len += 1;
        }
    }
}

impl<'a> RendererServices<'a> {
    /// Services over `scene`, choosing lights through its light BVH when `light_bvh` is set, by power
    /// otherwise.
    pub fn new(scene: &'a Scene, light_bvh: bool) -> Self {
        Self {
            scene,
            light_bvh: light_bvh.then(|| scene.light_bvh()),
            guide: None,
            pixel_estimate: None,
        }
    }

    /// The same services with paths guided by `guide` (none: unguided).
    pub fn with_guide(self, guide: Option<&'a GuidingField>) -> Self {
        Self { guide, ..self }
    }

    /// The same services for the samples of a pixel whose training value is `pixel_estimate`.
    pub fn with_pixel_estimate(self, pixel_estimate: Option<f32>) -> Self {
        Self {
            pixel_estimate,
            ..self
        }
    }

    /// The training's value of the pixel being traced, when guided roulette has one.
    pub fn pixel_estimate(&self) -> Option<f32> {
        self.pixel_estimate
    }

    /// The guiding cache, when the render is guided.
    pub fn guide(&self) -> Option<&'a GuidingField> {
        self.guide
    }

    /// The scene.
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The media the segment `(0, t_max)` of `ray` runs through, given the interior stack.
    pub fn segment_media(&self, ray: &Ray, t_max: f32, stack: &MediumStack) -> SegmentMedia {
        let mut out = SegmentMedia::default();
        if let Some(m) = stack.current() {
            out.push(m);
        }
        for &m in &self.scene.filled_media {
            let bounds = self.scene.media[m as usize].fill_bounds();
            if bounds.is_some_and(|b| b.intersect(ray, 0.0, t_max).is_some()) {
                out.push(m);
            }
        }
        out
    }

    /// True when next-event estimates at surfaces sample every light (see [`EVERY_LIGHT_MAX`]): there are at
    /// most that many, and none is an emissive triangle (an emitting mesh is many triangle lights, which would
    /// each get a shadow ray; they are chosen by power).
    pub fn surfaces_sample_every_light(&self) -> bool {
        let lights = &self.scene.lights;
        lights.len() <= EVERY_LIGHT_MAX && !lights.iter().any(|l| matches!(l, Light::Area(_)))
    }

    /// True when a next-event estimate at `ctx` samples every light: at a surface (`ctx.n` is set) of a scene
    /// where [`Self::surfaces_sample_every_light`].
    fn samples_every_light(&self, ctx: &LightContext) -> bool {
        ctx.n.is_some() && self.surfaces_sample_every_light()
    }

    /// The light samples of one next-event estimate at `ctx` (its normal set at surfaces, `None` in media):
    /// every light with probability 1 where [`Self::samples_every_light`]; otherwise one light, chosen by the
    /// light BVH or by power. Each sample is handed to `each` with the generator (lights that give none, being
    /// dark or facing away, are skipped): a closure rather than a returned list, which measured 1% of a
    /// surfaces-only render's instructions in copying.
    pub fn sample_lights(
        &self,
        ctx: &LightContext,
        rng: &mut Rng,
        mut each: impl FnMut(ChosenLight, &mut Rng),
    ) {
        let p = ctx.p;
        if self.samples_every_light(ctx) {
            // Every light's pair is drawn before any shadow ray runs (the order of the stratified values).
            let count = self.scene.lights.len().min(EVERY_LIGHT_MAX);
            let mut u = [Vec2::ZERO; EVERY_LIGHT_MAX];
            for slot in &mut u[..count] {
                *slot = rng.sample_2d();
            }
            for (index, &u) in u[..count].iter().enumerate() {
                if let Some(chosen) = self.sample_chosen_light(index, 1.0, p, u) {
                    each(chosen, rng);
                }
            }
        } else {
            // For emissive triangles, one stratified pair both chooses the triangle (its first value, rescaled
            // within the triangle's share) and places the sample on it, so that the samples of a pixel stay
            // stratified over a light made of many triangles (the light BVH rescales it within the chosen
            // child's share at every level). Other lights take a pair of their own: sharing it raised the MSE
            // of the peer benchmark's plume (sun and sky, chosen inside the medium) by 21%.
            let u = rng.sample_2d();
            let chosen = match self.light_bvh {
                Some(bvh) => bvh.sample(ctx, u.x),
                None => self.scene.light_sampler.sample_remapped(u.x),
            };
            if let Some((index, pmf, rest)) = chosen {
                let on_light = match self.scene.lights[index] {
                    Light::Area(_) => Vec2::new(rest, u.y),
                    _ => rng.sample_2d(),
                };
                if let Some(chosen) = self.sample_chosen_light(index, pmf, p, on_light) {
                    each(chosen, rng);
                }
            }
        }
    }

    /// Probability that a next-event estimate at `ctx` ([`Self::sample_lights`]) samples light `index`: 1 when
    /// every light is sampled, else its probability of being chosen there (the same product of child
    /// probabilities the light BVH returned when it chose it, or its share of the power).
    fn light_pmf(&self, index: usize, ctx: &LightContext) -> f32 {
        if self.samples_every_light(ctx) {
            1.0
        } else if let Some(bvh) = self.light_bvh {
            bvh.pmf(index, ctx)
        } else {
            self.scene.light_sampler.pmf(index)
        }
    }

    /// Chooses a light by power from `u` ∈ [0, 1), whatever the render's light sampler (for equiangular
    /// sampling along a segment, which has no one shading point): its index and the probability of choosing
    /// it.
    pub fn choose_light(&self, u: f32) -> Option<(usize, f32)> {
        self.scene.light_sampler.sample(u)
    }

    /// Samples light `index` (chosen with probability `pmf`) as seen from `p`, with `u` for where on it.
    pub fn sample_chosen_light(
        &self,
        index: usize,
        pmf: f32,
        p: Vec3,
        u: Vec2,
    ) -> Option<ChosenLight> {
        let sample = self.scene.lights[index].sample_li(p, u, &self.scene.textures)?;
        (sample.pdf > 0.0 && sample.radiance.max_element() > 0.0).then_some(ChosenLight {
            sample,
            pmf,
            index,
        })
    }

    /// Density, in solid angle at `ctx.p`, with which [`Self::sample_lights`] at `ctx` would have chosen the
    /// point `q` on the area light `light`.
    pub fn area_light_pdf(&self, light: usize, ctx: &LightContext, q: Vec3) -> f32 {
        match &self.scene.lights[light] {
            Light::Area(a) => {
                self.light_pmf(light, ctx) * a.pdf_from_point(ctx.p, q).unwrap_or(0.0)
            }
            _ => 0.0,
        }
    }

    /// Density with which [`Self::sample_lights`] at `ctx` would have chosen direction `dir` toward the
    /// environment.
    pub fn environment_pdf(&self, dir: Vec3, ctx: &LightContext) -> f32 {
        match (self.scene.environment, self.scene.environment_light()) {
            (Some(i), Some(env)) => self.light_pmf(i, ctx) * env.pdf(dir),
            _ => 0.0,
        }
    }

    /// Transmittance along the shadow segment (see [`ShadowSegment`]), starting inside the interiors of
    /// `stack`, at the path's `time` (frames relative to the frame, for motion blur). Index-matched boundaries
    /// let it through (updating the interiors); any other surface blocks it. Media contribute their
    /// transmittance estimates.
    pub fn transmittance(
        &self,
        segment: &ShadowSegment,
        time: f32,
        stack: &MediumStack,
        rng: &mut Rng,
        counters: &mut PathCounters,
    ) -> Rgb {
        self.weighted_transmittance(1.0, segment, time, stack, rng, counters)
    }

    /// `weight` times [`Self::transmittance`], for a shadow ray that Russian roulette kept with probability
    /// 1/`weight` (`crate::guiding::shadow`): the first medium the segment crosses starts its estimate from the
    /// weight ([`crate::volume::Medium::weighted_transmittance`]).
    pub fn weighted_transmittance(
        &self,
        weight: f32,
        segment: &ShadowSegment,
        time: f32,
        stack: &MediumStack,
        rng: &mut Rng,
        counters: &mut PathCounters,
    ) -> Rgb {
        counters.rays.shadow += 1;
        let scene = self.scene;
        let mut stack = *stack;
        let dir = segment.dir;
        let end = segment.end();
        let mut ray = Ray::new(segment.origin, dir).at_time(time);
        let mut remaining = segment.t_max;
        if !scene.has_invisible_boundaries() {
            // Every surface blocks: one any-hit query decides visibility, and the media are tracked over the
            // whole segment (the interiors cannot change without a boundary to cross).
            if scene.occluded(&ray, 0.0, remaining) {
                return Rgb::ZERO;
            }
            return self.through_media((Rgb::ONE, weight), &ray, remaining, &stack, rng, counters);
        }
        let mut tr = Rgb::ONE;
        // Given to the first part of the segment only.
        let mut weight = weight;
        for _ in 0..MAX_SHADOW_CROSSINGS {
            let hit = scene.intersect(&ray, 0.0, remaining);
            let t_seg = hit.as_ref().map_or(remaining, |h| h.t);
            tr = self.through_media((tr, weight), &ray, t_seg, &stack, rng, counters);
            weight = 1.0;
            if tr.max_element() <= 0.0 {
                return Rgb::ZERO;
            }
            let Some(hit) = hit else { return tr };
            if !scene
                .shading(hit.material, &hit.point_shading())
                .bsdf
                .is_index_matched()
            {
                return Rgb::ZERO;
            }
            let material = &scene.materials[hit.material as usize];
            if let Some(interior) = material.interior {
                stack.cross(interior, dir.dot(hit.geometric_normal) < 0.0);
            }
            let next = hit.spawn_origin(dir);
            if remaining.is_finite() {
                // Measured to the segment's fixed end, never by subtracting offsets.
                remaining = (end - next).dot(dir);
                if remaining <= 0.0 {
                    return tr;
                }
            }
            ray = Ray::new(next, dir).at_time(time);
        }
        Rgb::ZERO
    }

    /// `tr` times `weight` times the transmittance estimate of every medium over `(0, t_max)` of `ray`, inside
    /// the interiors of `stack` (no surface in between); the first medium starts its estimate from `weight`.
    fn through_media(
        &self,
        (mut tr, mut weight): (Rgb, f32),
        ray: &Ray,
        t_max: f32,
        stack: &MediumStack,
        rng: &mut Rng,
        counters: &mut PathCounters,
    ) -> Rgb {
        if stack.current().is_none() && self.scene.filled_media.is_empty() {
            // No interior and no volume anywhere: nothing on the segment attenuates.
            return tr * weight;
        }
        for &m in self.segment_media(ray, t_max, stack).ids() {
            let medium = &self.scene.media[m as usize];
            let counters = &mut counters.media[m as usize];
            tr *= medium.weighted_transmittance(weight, ray, t_max, rng, counters);
            weight = 1.0;
        }
        tr * weight
    }
}

#[cfg(test)]
mod tests {
    use crate::light::{Light, LightSamplerChoice};
    use crate::material::Material;
    use crate::math::{Rgb, Vec3};
    use crate::render::{RenderSettings, Renderer};
    use crate::scene::{Camera, Scene, SceneBuilder};
    use glam::DVec3;

    /// A grey Lambertian floor under a checkerboard of 128 emissive squares (256 triangles of different
    /// radiances) at height 2, facing down, with 32 squares facing up (away from the floor) above them; the
    /// camera looks down at a 5 mm patch around the origin. Returns the scene and the reflected radiance at
    /// the origin in closed form, ρ/π · Σ E_square.
    fn checkerboard() -> (Scene, f64) {
        let albedo = 0.5;
        let mut b = SceneBuilder::new();
        let floor = b.add_material(Material::lambertian("floor", Rgb::splat(albedo)));
        let f = 20.0;
        let quad = vec![
            Vec3::new(-f, 0.0, -f),
            Vec3::new(-f, 0.0, f),
            Vec3::new(f, 0.0, f),
            Vec3::new(f, 0.0, -f),
        ];
        b.add_triangle_mesh(quad, vec![[0, 1, 2], [0, 2, 3]], floor)
            .unwrap();
        let mut irradiance = 0.0;
        let cell = 0.5;
        for i in 0..16 {
            for j in 0..16 {
                let up = (i + j) % 2 == 1;
                if up && (i % 4 != 1) {
                    continue;
                }
                let radiance = 0.5 + ((i * 7 + j * 3) % 11) as f32;
                let mut emitter = Material::lambertian("emitter", Rgb::ZERO);
                emitter.emission = Rgb::splat(radiance);
                let m = b.add_material(emitter);
                let (x0, z0) = (-4.0 + i as f32 * cell, -4.0 + j as f32 * cell);
                let y = if up { 2.5 } else { 2.0 };
                let corners = vec![
                    Vec3::new(x0, y, z0),
                    Vec3::new(x0 + cell, y, z0),
                    Vec3::new(x0 + cell, y, z0 + cell),
                    Vec3::new(x0, y, z0 + cell),
                ];
                // Counter-clockwise seen from below (normal −Y) for the lower squares, from above for the
                // upper ones.
                let indices = if up {
                    vec![[0, 2, 1], [0, 3, 2]]
                } else {
                    vec![[0, 1, 2], [0, 2, 3]]
                };
                if !up {
                    let polygon: Vec<DVec3> = corners.iter().map(|c| c.as_dvec3()).collect();
                    irradiance += crate::testing::polygon_irradiance(
                        DVec3::ZERO,
                        DVec3::Y,
                        &polygon,
                        radiance as f64,
                    );
                }
                b.add_triangle_mesh(corners, indices, m).unwrap();
            }
        }
        b.set_camera(Camera::look_at(Vec3::new(0.0, 0.5, 0.05), Vec3::ZERO, 0.01));
        let scene = b.build().unwrap();
        (scene, albedo as f64 / std::f64::consts::PI * irradiance)
    }

    /// Renders the direct light on the floor with `choice` and returns the mean over the pixels and its
    /// standard error (from the film's per-pixel variance of the mean).
    fn render_floor(scene: &Scene, choice: LightSamplerChoice) -> (f64, f64) {
        let settings = RenderSettings {
            width: 4,
            height: 4,
            spp: 2048,
            seed: 17,
            max_depth: 1,
            light_sampler: choice,
            ..RenderSettings::default()
        };
        let (image, _) = Renderer::new(settings)
            .render(scene, &mut |_| true)
            .unwrap();
        let n = image.beauty.len() as f64;
        let mean = image.beauty.iter().map(|c| c.x as f64).sum::<f64>() / n;
        let variance = image.variance.iter().map(|v| v.x as f64).sum::<f64>() / (n * n);
        (mean, variance.sqrt())
    }

    #[test]
    fn both_light_samplers_match_the_closed_form_irradiance_of_many_emitters() {
        let (scene, expected) = checkerboard();
        assert!(
            scene
                .lights()
                .iter()
                .filter(|l| matches!(l, Light::Area(_)))
                .count()
                > 256,
            "many triangle lights"
        );
        let (power, power_error) = render_floor(&scene, LightSamplerChoice::Power);
        let (bvh, bvh_error) = render_floor(&scene, LightSamplerChoice::Bvh);
        eprintln!(
            "closed form {expected:.5}; power {power:.5} ± {power_error:.5}; bvh {bvh:.5} ± {bvh_error:.5}"
        );
        for (name, value, error) in [("power", power, power_error), ("bvh", bvh, bvh_error)] {
            assert!(
                error > 0.0 && error < 0.02 * expected,
                "{name}: standard error {error} too large to test anything"
            );
            assert!(
                (value - expected).abs() < 4.0 * error,
                "{name}: {value} vs the closed form {expected} (standard error {error})"
            );
        }
        assert!(
            bvh_error < power_error,
            "the light BVH should sample the near squares more: {bvh_error} vs {power_error}"
        );
    }
}
