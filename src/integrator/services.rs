//! Renderer services (Fong et al. 2017, "Production Volume Rendering", §5): what the renderer offers to
//! whoever integrates light at a point — a surface BSDF or a medium's scattering event — without them knowing
//! the scene: choosing and sampling a light, and the transmittance of a shadow ray through everything in
//! between (index-matched boundaries, nested interiors, overlapping position-filled volumes).

use super::{MediumStack, PathCounters};
use crate::geometry::ShadowSegment;
use crate::light::{Light, LightSample};
use crate::math::{Ray, Rgb, Rng, Vec2, Vec3};
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
    /// Index of the light in the scene.
    pub index: usize,
}

/// In scenes with at most this many lights, none of them emissive triangles, next-event estimation at
/// *surfaces* samples every light (one shadow ray each) instead of choosing one by power: choosing by power ignores where a light is shadowed (a
/// floor under smoke, in the sun's shadow, lit by the sky), and at a surface the extra shadow rays cost less
/// than the selection noise they remove. Inside media one light is still chosen by power: there every shadow
/// ray is tracked through the medium, and measured on the peer benchmark's cloud and plume, sampling every
/// light cost more than it saved there (see docs/performance.md).
pub const EVERY_LIGHT_MAX: usize = 4;

/// The light samples of one next-event estimate: one from every light, or one light chosen by power.
#[derive(Clone, Copy, Debug, Default)]
pub struct LightSamples {
    samples: [Option<ChosenLight>; EVERY_LIGHT_MAX],
}

impl LightSamples {
    /// The samples (lights that gave none, being dark or facing away, are skipped).
    pub fn iter(&self) -> impl Iterator<Item = ChosenLight> + '_ {
        self.samples.iter().flatten().copied()
    }
}

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

    fn push(&mut self, id: u32) {
        if self.len < MAX_SEGMENT_MEDIA && !self.ids().contains(&id) {
            self.ids[self.len] = id;
            self.len += 1;
        }
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

    /// The light samples of one next-event estimate at `p`: with `every` (only when
    /// [`Self::surfaces_sample_every_light`]), every light with probability 1; otherwise one light chosen by
    /// power.
    pub fn sample_lights(&self, p: Vec3, every: bool, rng: &mut Rng) -> LightSamples {
        let mut out = LightSamples::default();
        if every && self.surfaces_sample_every_light() {
            for (index, slot) in out
                .samples
                .iter_mut()
                .enumerate()
                .take(self.scene.lights.len())
            {
                *slot = self.sample_chosen_light(index, 1.0, p, rng.sample_2d());
            }
        } else {
            // For emissive triangles, one stratified pair both chooses the triangle (its first value, rescaled
            // within the triangle's share) and places the sample on it, so that the samples of a pixel stay
            // stratified over a light made of many triangles. Other lights take a pair of their own: sharing
            // it raised the MSE of the peer benchmark's plume (sun and sky, chosen inside the medium) by 21%.
            let u = rng.sample_2d();
            if let Some((index, pmf, rest)) = self.scene.light_sampler.sample_remapped(u.x) {
                let on_light = match self.scene.lights[index] {
                    Light::Area(_) => Vec2::new(rest, u.y),
                    _ => rng.sample_2d(),
                };
                out.samples[0] = self.sample_chosen_light(index, pmf, p, on_light);
            }
        }
        out
    }

    /// Probability that a next-event estimate (with `every` as given to [`Self::sample_lights`]) samples light
    /// `index`: 1 when every light is sampled, else its probability of being chosen by power.
    fn light_pmf(&self, index: usize, every: bool) -> f32 {
        if every && self.surfaces_sample_every_light() {
            1.0
        } else {
            self.scene.light_sampler.pmf(index)
        }
    }

    /// Chooses a light by power from `u` ∈ [0, 1): its index and the probability of choosing it.
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

    /// Density, in solid angle at `p`, with which [`Self::sample_lights`] would have chosen the point `q` on
    /// the area light `light`.
    pub fn area_light_pdf(&self, light: usize, p: Vec3, q: Vec3, every: bool) -> f32 {
        match &self.scene.lights[light] {
            Light::Area(a) => self.light_pmf(light, every) * a.pdf_from_point(p, q).unwrap_or(0.0),
            _ => 0.0,
        }
    }

    /// Density with which [`Self::sample_lights`] would have chosen direction `dir` toward the environment.
    pub fn environment_pdf(&self, dir: Vec3, every: bool) -> f32 {
        match (self.scene.environment, self.scene.environment_light()) {
            (Some(i), Some(env)) => self.light_pmf(i, every) * env.pdf(dir),
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
            return self.through_media(Rgb::ONE, &ray, remaining, &stack, rng, counters);
        }
        let mut tr = Rgb::ONE;
        for _ in 0..MAX_SHADOW_CROSSINGS {
            let hit = scene.intersect(&ray, 0.0, remaining);
            let t_seg = hit.as_ref().map_or(remaining, |h| h.t);
            tr = self.through_media(tr, &ray, t_seg, &stack, rng, counters);
            if tr.max_element() <= 0.0 {
                return Rgb::ZERO;
            }
            let Some(hit) = hit else { return tr };
            let material = &scene.materials[hit.material as usize];
            if !material
                .bsdf(&hit.point_shading(), &scene.textures)
                .is_index_matched()
            {
                return Rgb::ZERO;
            }
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

    /// `tr` times the transmittance estimate of every medium over `(0, t_max)` of `ray`, inside the interiors
    /// of `stack` (no surface in between).
    fn through_media(
        &self,
        mut tr: Rgb,
        ray: &Ray,
        t_max: f32,
        stack: &MediumStack,
        rng: &mut Rng,
        counters: &mut PathCounters,
    ) -> Rgb {
        for &m in self.segment_media(ray, t_max, stack).ids() {
            let medium = &self.scene.media[m as usize];
            tr *= medium.transmittance(ray, t_max, rng, &mut counters.media[m as usize]);
        }
        tr
    }
}
