//! The volumetric path tracer: next-event estimation at every non-delta scattering event (surface or medium),
//! BSDF or phase-function sampling to continue the path, and multiple importance sampling of both strategies
//! with the power heuristic (Veach 1997, §9.2, eq. 9.13). Russian roulette (Arvo & Kirk 1990) ends
//! low-throughput paths after a few bounces, judging the throughput with the radiance factors 1/η² of the
//! refractions so far undone (pbrt-v4's `etaScale`).
//!
//! Media: along each segment every medium answers one question, [`Medium::free_flight`]: its next real
//! collision and the path throughput its walk's weights leave (spectral MIS, spectral tracking of an RGB
//! density, or 1 for analog tracking). Where media overlap, each flies over the part of the segment before the
//! nearest collision of those asked before it, which combines them exactly (`combined_flight`), so a chromatic
//! medium keeps all colour channels beside any other. An emitting medium gathers its emission along its free
//! flight, at the tentative collisions of its walk ([`TentativeEmission`]); the integrator weights it by the
//! transmittance of the media asked after it. Nothing here depends on which tracking method a medium uses.
//!
//! Direct light in constant media: on a segment inside one medium of constant coefficients
//! ([`Medium::constant_scattering`]), the direct light of directional, area and environment lights is estimated
//! apart from the path's free flight (decoupled: the path still scatters at its free-flight collision, but
//! estimates no direct light of those lights there). Every segment, whether its flight collides or not,
//! estimates it at a distance drawn from the free-flight density truncated to the segment (Novák et al. 2018,
//! "Monte Carlo Methods for Volumetric Light Transport Simulation", §5; [`PathTracer::decoupled`]), where a thin
//! medium's collisions reach only the fraction 1 − T(d) of segments that collide. The direct light of a point
//! or spot light is also estimated at a distance sampled equiangularly toward it (Kulla & Fajardo 2012,
//! "Importance Sampling Techniques for Path Tracing in Participating Media", §4.1), and both that estimate and
//! next-event estimation at the free-flight collision are weighted by the power heuristic over the two distance
//! densities ([`ConstantScattering::free_flight_pdf`] and the equiangular one). Distance sampling alone scatters
//! where the medium is dense, not where the light is bright, and leaves fireflies around every small light in a
//! thin medium.
//!
//! Texture filtering: each path carries a ray cone (Akenine-Möller et al. 2021, "Improved Shader and Texture
//! Level of Detail Using Ray Cones", JCGT 10(1)) that starts at the camera with the spread of one pixel. Its
//! width at a hit, projected onto the surface, is the footprint over which textures are filtered
//! ([`SurfaceHit::tex_coord`]). The width keeps growing with the distance travelled, through every bounce
//! (surface curvature is not modelled). Emission is always read at full resolution, so that light sampling and
//! BSDF sampling see the same emitter.
//!
//! Path guiding: when the render trained a guiding cache, medium scattering events sample their direction from
//! the one-sample MIS mixture of the phase function and the product of the cache's distribution with it, and
//! Lambertian surfaces from the mixture of the cache's distribution and the BSDF; next-event estimation is
//! weighed against the mixture's density in media and against the BSDF's alone at surfaces (all in
//! [`super::guided`]). A
//! training path remembers its events ([`GuidePath`]) so that the cache learns the radiance found after each.
//! With [`PathTracer::guided_roulette`], a medium scattering event also plays the weight window of guided Russian
//! roulette and splitting ([`crate::guiding::adjoint`]) in place of classic Russian roulette: the path may end,
//! or split into paths of their own ([`Branch`]) after the event's next-event estimate, each of which samples its
//! direction from a generator derived from the path's, so a sample stays a pure function of its seed.
//!
//! `max_depth` counts scattering events (surface bounces and medium scattering), as pbrt's `maxdepth`: 0 shows
//! emitters seen directly, 1 adds direct lighting, and so on. Crossing an index-matched boundary (transmission
//! 1, ior 1, smooth) is not a scattering event and does not count.
//!
//! [`Medium::free_flight`]: crate::volume::Medium::free_flight
//! [`Medium::constant_scattering`]: crate::volume::Medium::constant_scattering
//! [`SurfaceHit::tex_coord`]: crate::scene::SurfaceHit::tex_coord

use super::guided;
use super::record::{CameraEvent, FirstEvent, Origin, SampleRecord};
use super::services::RendererServices;
use super::{MediumStack, PathCounters};
use crate::geometry::SurfacePoint;
use crate::guiding::adjoint::{self, Roulette};
use crate::guiding::shadow::{SHADOW_MIN_SURVIVAL, VISIBILITY_MIN_SURVIVAL};
use crate::guiding::{GuidePath, StrategyDensities};
use crate::light::{LightContext, LightSample};
use crate::material::{Bsdf, BsdfSample, LobeSplit, ShadingPoint};
use crate::math::sampling::{carry_one_channel, power_heuristic, Equiangular};
use crate::math::{luminance, Frame, Ray, Rgb, Rng, Vec3};
use crate::scene::{Scene, SurfaceHit};
use crate::volume::{ConstantScattering, PhaseFunction, TentativeEmission};
use std::borrow::Cow;

/// Bounces after which Russian roulette may end a path.
const ROULETTE_START: u32 = 3;
/// Invisible-boundary crossings allowed per path, a guard against degenerate geometry.
const MAX_BOUNDARY_CROSSINGS: u32 = 256;

/// What one camera path returns: its radiance and the first hit's AOVs.
#[derive(Clone, Copy, Debug, Default)]
pub struct PathSample {
    /// Radiance carried to the camera.
    pub radiance: Rgb,
    /// Albedo of the first visible surface, or the scattering albedo σ_s/σ_t at the camera ray's first real
    /// collision in a medium (zero when the ray escapes).
    pub albedo: Rgb,
    /// World-space shading normal of the first visible surface, facing the camera; at a first collision in a
    /// medium, the direction back to the camera.
    pub normal: Vec3,
    /// Distance from the camera to the first visible surface or first real collision in a medium (0 when the
    /// ray escapes).
    pub depth: f32,
    /// Coverage: 1 − the camera ray's transmittance to the environment (or to a holdout), in \[0, 1\].
    pub alpha: f32,
}

/// The path tracer and its settings.
#[derive(Clone, Copy, Debug)]
pub struct PathTracer {
    /// Maximum number of scattering events per path.
    pub max_depth: u32,
    /// Multiple importance sampling at medium scattering events (default true). When false, emitters are
    /// reached from inside media by light sampling only: next-event estimation gets weight 1 and phase-sampled
    /// hits on emitters add nothing (still unbiased, usually noisier).
    pub media_mis: bool,
    /// Spread angle of a camera ray's cone, in radians: the angle one pixel subtends
    /// ([`crate::scene::Camera::pixel_spread_angle`]). 0 reads every texture at full resolution.
    pub pixel_spread: f32,
    /// Width of a camera ray's cone where it starts, in scene units ([`crate::scene::Camera::pixel_width`]): 0
    /// for a perspective camera, one pixel for an orthographic one.
    pub pixel_width: f32,
    /// Equiangular sampling toward point and spot lights on segments through constant media, MIS'd with
    /// distance sampling (see the module documentation); [`PathTracer::uses_equiangular`] says whether a scene
    /// gets it.
    pub equiangular: bool,
    /// Decoupled direct light on segments through constant media: each such segment estimates the direct light
    /// of the lights equiangular sampling does not serve at a distance drawn from the free-flight density
    /// truncated to the segment, in place of next-event estimation at its free-flight collision (see the module
    /// documentation); [`PathTracer::uses_decoupled`] says whether a scene gets it.
    pub decoupled: bool,
    /// A transparent film: the environment seen directly is left out of the radiance (recorded apart).
    pub transparent: bool,
    /// Whether the scene has holdouts or shadow catchers ([`crate::scene::SceneNames::has_mattes`]), which
    /// camera rays must look for.
    pub mattes: bool,
    /// Guided Russian roulette and splitting at medium scattering events, where the render is guided and the
    /// cache and the training have estimates there ([`crate::guiding::adjoint`]); classic Russian roulette
    /// otherwise.
    pub guided_roulette: bool,
    /// The interior media around the camera, which camera paths start in ([`MediumStack::enclosing`]).
    pub camera_media: MediumStack,
}

/// Mixed into the streams of split-off paths' generators.
const BRANCH_STREAM: u64 = 0x8979_0a0b_4e5d_1c3f;

/// A medium scattering event, as a path goes on from it after its next-event estimate.
#[derive(Clone, Copy)]
struct MediumEvent {
    /// The ray that reached the event, and the event's distance along it.
    ray: Ray,
    t: f32,
    /// The phase function there.
    phase: PhaseFunction,
    /// The product of the guiding cache's distribution with the phase function, which its direction is sampled
    /// from in the mixture with the phase function, when the event is guided ([`guided::medium_guide_at`],
    /// decided once, before next-event estimation, which is weighed against that density).
    guide: Option<guided::Guide>,
}

impl MediumEvent {
    /// Where it happened.
    fn point(&self) -> Vec3 {
        self.ray.at(self.t)
    }
}

/// A path split off at a medium scattering event by guided splitting: the state of the path there (its albedo,
/// next-event estimate and the split's 1/n done), and a generator of its own. It goes on from there as the path
/// that split does, sampling its own direction.
struct Branch {
    event: MediumEvent,
    rng: Rng,
    onward: OnwardState,
}

impl Branch {
    /// A copy of the path in `s` at `event`, its generator seeded from `rng`'s next numbers.
    fn split_off(s: &PathState, event: &MediumEvent, rng: &mut Rng) -> Self {
        let seed = (u64::from(rng.next_u32()) << 32) | u64::from(rng.next_u32());
        let stream = u64::from(rng.next_u32()) ^ BRANCH_STREAM;
        Self {
            event: *event,
            rng: Rng::new(seed, stream),
            onward: s.onward,
        }
    }

    /// Puts the branch's state into `s` (the radiance, coverage and records stay the sample's) and returns
    /// the event and the branch's generator.
    fn resume(self, s: &mut PathState) -> (MediumEvent, Rng) {
        s.onward = self.onward;
        (self.event, self.rng)
    }
}

/// What every step of one path draws on besides the path's state: the renderer's services, the path's random
/// numbers and its work counters. Steps pass it on whole, so each takes the three as one argument.
pub struct PathContext<'a, 's> {
    /// Light sampling and shadow-ray transmittance over the scene.
    pub services: &'a RendererServices<'s>,
    /// The path's random numbers.
    pub rng: &'a mut Rng,
    /// The work counters the path adds to.
    pub counters: &'a mut PathCounters,
}

/// A point inside media that scatters light toward the ray's origin: where the three in-medium direct-light
/// estimates (next-event estimation at a collision, the equiangular and the decoupled samples) evaluate a light
/// sample.
struct ScatterPoint<'a> {
    /// The point, on the ray.
    p: Vec3,
    /// The direction back along the ray.
    wo: Vec3,
    /// The ray's time, for moving media and geometry.
    time: f32,
    /// The media the point lies in, where shadow rays start.
    stack: &'a MediumStack,
}

impl<'a> ScatterPoint<'a> {
    /// The point `p` on `ray`, inside the media of `stack`.
    fn on(ray: &Ray, p: Vec3, stack: &'a MediumStack) -> Self {
        Self {
            p,
            wo: -ray.dir,
            time: ray.time,
            stack,
        }
    }

    /// One light sample's unweighted in-scattering here: the phase function's value ρ(ωo, ωi) toward the sample
    /// and the transmittance of its shadow segment (the radiative transfer equation's in-scattering integrand
    /// without σ_s, L_i and the sample's pdf, which each estimate weighs its own way), the latter times
    /// `weight` (1, or 1/q for a shadow ray kept with probability q: [`crate::guiding::shadow`]). None where
    /// either is zero; no shadow ray is traced where the phase function is zero.
    fn lit_by(
        &self,
        services: &RendererServices,
        phase: &PhaseFunction,
        sample: &LightSample,
        weight: f32,
        rng: &mut Rng,
        counters: &mut PathCounters,
    ) -> Option<(f32, Rgb)> {
        let value = phase.eval(self.wo, sample.wi);
        let shadow = sample.shadow_segment(&SurfacePoint::free(self.p))?;
        if value <= 0.0 {
            return None;
        }
        let tr =
            services.weighted_transmittance(weight, &shadow, self.time, self.stack, rng, counters);
        (tr.max_element() > 0.0).then_some((value, tr))
    }
}

/// A segment inside exactly one medium of constant coefficients, whose direct light is estimated at up to three
/// distances: the free-flight collision, a decoupled sample (the lights equiangular sampling does not serve) and
/// an equiangular one (point and spot lights).
#[derive(Clone, Copy, Debug)]
struct ConstantSegment {
    /// Where the segment starts and its direction (the ray's).
    origin: Vec3,
    dir: Vec3,
    /// Its length: the distance to the surface that ends it.
    length: f32,
    /// The path throughput when the segment starts, as the medium's free-flight sampling saw it.
    throughput: Rgb,
    /// The medium's coefficients.
    coefficients: ConstantScattering,
}

/// The part of a path's state that it carries from one event to the next and that a path split off at a medium
/// scattering event copies whole ([`Branch`]): the sample's radiance, coverage and records stay with the
/// sample, and what the last event was (`prev*`) the split-off path's own direction sampling sets.
#[derive(Clone, Copy)]
struct OnwardState {
    /// The path throughput.
    beta: Rgb,
    /// The product of η² over the refractions so far (pbrt-v4's `etaScale`): `beta` times it undoes their
    /// radiance factors 1/η², which Russian roulette looks at instead of `beta` alone.
    eta_scale: f32,
    /// Scattering events so far.
    depth: u32,
    /// The media the path is inside.
    stack: MediumStack,
    /// Width of the ray cone where the current ray starts, in world units.
    cone_width: f32,
    /// Invisible (index-matched) boundaries crossed so far.
    crossings: u32,
    /// Whether the next surface hit is the first (whose emission `first_emission` decides).
    first_hit: bool,
    /// The constant-medium segment that ended in the current real collision, for the MIS weight of its
    /// next-event estimate against equiangular sampling, and to leave out of it the lights whose direct light
    /// the segment's decoupled sample estimated.
    collided_segment: Option<ConstantSegment>,
    /// The path's first scattering event, by which its later light is classed.
    first_event: FirstEvent,
}

/// The state of a path between events; `'r` borrows the sample's records.
struct PathState<'r> {
    radiance: Rgb,
    /// What the path carries from event to event, and all a path split off from it copies.
    onward: OnwardState,
    /// Whether the last scattering event was a delta lobe (no MIS for emitters hit next).
    prev_delta: bool,
    /// Solid-angle density the last sampled direction is weighed with by MIS on emitters hit next: the one it
    /// was sampled with, except at a guided surface (the BSDF's alone; see the guided module).
    prev_pdf: f32,
    /// Where the last scattering event happened, with its shading normal at a surface (the normal also
    /// tells whether its next-event estimate may have sampled every light, see
    /// [`RendererServices::surfaces_sample_every_light`]).
    prev: LightContext,
    /// Whether emitters hit next were already counted by light sampling alone (a medium event without MIS).
    prev_light_only: bool,
    /// Whether the first-hit AOVs (albedo, normal, depth) are still to be recorded: at the first surface hit
    /// or, before it, the camera ray's first real collision in a medium.
    aovs_pending: bool,
    /// Whether the first surface hit's emission is counted.
    first_emission: FirstEmission,
    /// The sample's coverage, once known.
    coverage: Option<f32>,
    /// The first medium the camera ray crossed: what covers the part of a sample that media weights, not
    /// collisions, take away (spectral tracking).
    crossed_medium: Option<u32>,
    /// Where the contributions are recorded for the compositing layers, if they are.
    record: Option<&'r mut SampleRecord>,
    /// The distance along the camera ray where the current ray starts, while the path is still on it (it
    /// passes through culled back faces, shadow catchers and index-matched boundaries): what deep output
    /// measures depths by.
    camera_t: f32,
    /// The emission media gathered along the current segment's free flights.
    emitted: TentativeEmission,
    /// Where a training path remembers its guided vertices, when it trains the guiding cache.
    guide_path: Option<&'r mut GuidePath>,
    /// Paths split off and not yet traced.
    branches: Vec<Branch>,
    /// Extra paths splitting may still add to the sample.
    branch_budget: u32,
}

impl PathState<'_> {
    /// 1 − the mean of the throughput's channels: how much of the camera ray something in front has taken,
    /// where the path meets the environment or a holdout.
    fn coverage_so_far(&self) -> f32 {
        (1.0 - self.onward.beta.element_sum() / 3.0).clamp(0.0, 1.0)
    }

    /// Decides the sample's coverage (once): `coverage` of it, decided by `event` at distance `t` along the
    /// current ray (for deep output), covered by Cryptomatte item `item()` (asked only when the path records).
    fn cover(
        &mut self,
        coverage: f32,
        event: fn(f32) -> CameraEvent,
        t: f32,
        item: impl FnOnce() -> Option<u32>,
    ) {
        if self.coverage.is_none() {
            self.coverage = Some(coverage);
            let camera_t = self.camera_t;
            if let Some(r) = self.record.as_deref_mut() {
                if r.deep {
                    r.camera_event = Some(event(camera_t + t));
                }
                if coverage > 0.0 {
                    r.covered_by = item();
                }
            }
        }
    }

    /// Adds light the path reached at an emitter (not sampled toward it): emission seen directly before any
    /// scattering event, direct light after one, indirect after more. `emitter()` names the emitter; it is
    /// asked only when the path records (so are the emitters of the other `add_*`).
    fn add_reached(&mut self, value: Rgb, emitter: impl FnOnce() -> Option<u32>) {
        self.radiance += value;
        if let Some(r) = self.record.as_deref_mut() {
            r.add(
                value,
                self.onward.first_event,
                self.onward.depth == 1,
                emitter(),
            );
        }
    }

    /// Adds `value`, light estimated by next-event estimation at a surface, where `split` gives the same light
    /// by lobe class when this is the path's first scattering event (direct light of those classes).
    fn add_surface_sample(
        &mut self,
        value: Rgb,
        split: impl FnOnce() -> LobeSplit,
        emitter: impl FnOnce() -> Option<u32>,
    ) {
        self.radiance += value;
        if let Some(r) = self.record.as_deref_mut() {
            if self.onward.depth == 0 {
                r.add_split(split(), true, emitter());
            } else {
                r.add(value, self.onward.first_event, false, emitter());
            }
        }
    }

    /// Adds light estimated by next-event (or equiangular) estimation at a point in a medium.
    fn add_volume_sample(&mut self, value: Rgb, emitter: impl FnOnce() -> Option<u32>) {
        self.radiance += value;
        if let Some(r) = self.record.as_deref_mut() {
            match self.onward.depth {
                0 => r.add(value, FirstEvent::Volume, true, emitter()),
                _ => r.add(value, self.onward.first_event, false, emitter()),
            }
        }
    }
}

/// Whether a camera path counts the light emitted by the first surface it hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FirstEmission {
    /// The path counts it, like every other emitter it reaches.
    Count,
    /// The path leaves it out: the caller estimates it separately (emitter-edge supersampling,
    /// [`PathTracer::first_surface_emission`]), so that the two add up to the whole.
    Omit,
}

/// What shading a surface hit decided.
enum SurfaceOutcome {
    /// The path goes on along this ray.
    Continue(Ray),
    /// The path ends here.
    End,
}

/// A surface hit a path scatters at.
struct Surface<'a> {
    /// The hit, with its normal map applied.
    hit: &'a SurfaceHit,
    /// Where its textures are read.
    at: &'a ShadingPoint,
    /// The shading frame before the normal map (the clear coat's default normal).
    unmapped: Frame,
    /// The shading frame, oriented by [`shading_frame`].
    frame: Frame,
}

/// The first-hit AOVs (albedo, normal, depth) of a visible surface hit by `ray`, recorded once. An invisible,
/// index-matched boundary records none: the camera ray goes on to what lies behind it, a medium's first
/// collision or another surface.
struct SurfaceAovs<'a> {
    hit: &'a SurfaceHit,
    ray: &'a Ray,
    at: &'a ShadingPoint,
    scene: &'a Scene,
}

impl SurfaceAovs<'_> {
    /// Records the AOVs into `out` when they are still pending, the albedo from the material's parameters
    /// at the hit.
    fn record(&self, s: &mut PathState, out: &mut PathSample) {
        let (hit, scene) = (self.hit, self.scene);
        self.record_with_albedo(s, out, || {
            scene.materials[hit.material as usize]
                .pbr_params(self.at, &scene.textures)
                .base_color
        });
    }

    /// Records the AOVs into `out` when they are still pending, with `albedo()` the base colour at the hit
    /// (asked only then).
    fn record_with_albedo(
        &self,
        s: &mut PathState,
        out: &mut PathSample,
        albedo: impl FnOnce() -> Rgb,
    ) {
        if std::mem::take(&mut s.aovs_pending) {
            let hit = self.hit;
            out.depth = (hit.p - self.ray.origin).length();
            out.albedo = albedo();
            out.normal = if hit.shading.n.dot(-self.ray.dir) < 0.0 {
                -hit.shading.n
            } else {
                hit.shading.n
            };
        }
    }
}

/// The first-hit AOVs at the camera ray's first real collision, at `t` in medium `m`: what a denoiser's auxiliary
/// images see of a medium (as Cycles writes it): its scattering albedo there, and the way back to the camera.
fn record_collision_aovs(out: &mut PathSample, scene: &Scene, ray: &Ray, t: f32, m: u32) {
    out.albedo = scene.media[m as usize]
        .collision(ray.at(t), ray.time)
        .albedo;
    out.normal = -ray.dir;
    out.depth = t;
}

/// An unlit surface `hit` ends the path showing its base colour, on its front face (or both faces when
/// double-sided); it scatters nothing and is not a light (weight 1).
fn show_unlit(
    s: &mut PathState,
    scene: &Scene,
    hit: &SurfaceHit,
    at: &ShadingPoint,
    item: impl FnOnce() -> Option<u32>,
    emitter: impl FnOnce() -> Option<u32>,
) {
    let material = &scene.materials[hit.material as usize];
    if s.onward.depth == 0 {
        s.cover(1.0, CameraEvent::Surface, hit.t, item);
    }
    if hit.front_face || material.double_sided {
        let value = s.onward.beta * material.unlit_radiance(at, &scene.textures);
        s.add_reached(value, emitter);
    }
}

/// Passes the path through the surface `hit` along `ray` without scattering (a culled back face, an
/// index-matched boundary), entering or leaving `interior` when the surface bounds one; the path ends after
/// [`MAX_BOUNDARY_CROSSINGS`] crossings.
fn cross_boundary(
    s: &mut PathState,
    ray: &Ray,
    hit: &SurfaceHit,
    interior: Option<u32>,
    counters: &mut PathCounters,
) -> SurfaceOutcome {
    s.onward.crossings += 1;
    if s.onward.crossings > MAX_BOUNDARY_CROSSINGS {
        return SurfaceOutcome::End;
    }
    if let Some(interior) = interior {
        s.onward
            .stack
            .cross(interior, ray.dir.dot(hit.geometric_normal) < 0.0);
    }
    counters.rays.bounce += 1;
    SurfaceOutcome::Continue(Ray::new(hit.spawn_origin(ray.dir), ray.dir).at_time(ray.time))
}

/// The shading frame a path scatters in at `hit`: one-sided surfaces reflect nothing from behind (`None`); a
/// refracting interface keeps its orientation (its inside is below); a diffusely transmitting thin wall scatters
/// alike on both faces.
fn shading_frame(hit: &SurfaceHit, material: &crate::material::Material) -> Option<Frame> {
    if hit.front_face || material.is_transmissive() {
        Some(hit.shading)
    } else if material.double_sided || material.transmits_diffusely() {
        Some(Frame {
            s: hit.shading.s,
            t: -hit.shading.t,
            n: -hit.shading.n,
        })
    } else {
        None
    }
}

/// What equiangular sampling can aim at in a scene: the media of constant scattering coefficients it samples
/// distances in, and the point and spot lights it samples toward (it runs only where both exist); and the
/// other lights, which the decoupled sample serves in those media.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EquiangularTargets {
    /// Media whose scattering coefficients are constant.
    pub constant_media: usize,
    /// Point and spot lights.
    pub point_lights: usize,
    /// The other lights that emit (directional, area, environment): those whose direct light in constant media
    /// the decoupled sample estimates when equiangular sampling serves the point and spot lights.
    pub decoupled_lights: usize,
    /// Media of constant scattering coefficients that light sampling can see out of: the interior of at least
    /// one material that may be an invisible (index-matched) boundary. Shadow rays from inside a medium sealed
    /// by refracting surfaces (a glass object's interior) never reach a light outside it, so the decoupled
    /// sample's extra shadow rays there are wasted (measured: 0.79× the efficiency on the peer benchmark's
    /// glass), and it runs only where one of these exists.
    pub open_constant_media: usize,
}

impl EquiangularTargets {
    /// Counts the targets in `scene`.
    pub fn of(scene: &Scene) -> Self {
        let open = |m: usize| {
            scene
                .materials
                .iter()
                .any(|mat| mat.interior == Some(m as u32) && mat.may_be_index_matched())
        };
        Self {
            open_constant_media: scene
                .media
                .iter()
                .enumerate()
                .filter(|(i, m)| m.constant_scattering().is_some() && open(*i))
                .count(),
            constant_media: scene
                .media
                .iter()
                .filter(|m| m.constant_scattering().is_some())
                .count(),
            point_lights: scene
                .lights()
                .iter()
                .filter(|l| l.point_position().is_some())
                .count(),
            // A black environment (a scene's explicit `[0, 0, 0]`) gives no light to estimate.
            decoupled_lights: scene
                .lights()
                .iter()
                .filter(|l| l.point_position().is_none() && l.power(1.0) > 0.0)
                .count(),
        }
    }

    /// True when there is both a medium to sample in and a light to sample toward.
    pub fn any(&self) -> bool {
        self.constant_media > 0 && self.point_lights > 0
    }
}

impl PathTracer {
    /// True when `scene` gets equiangular sampling: it is on, and the scene has a point or spot light and a
    /// scattering medium of constant coefficients ([`EquiangularTargets::any`]).
    pub fn uses_equiangular(equiangular: bool, scene: &Scene) -> bool {
        equiangular && EquiangularTargets::of(scene).any()
    }

    /// True when `scene` gets decoupled direct-light sampling: it is on, and the scene has a scattering medium
    /// of constant coefficients that light sampling can see out of ([`EquiangularTargets::open_constant_media`])
    /// and a light that it serves: any light but a point or spot light when `equiangular` sampling is on, which
    /// serves those ([`EquiangularTargets::decoupled_lights`]).
    pub fn uses_decoupled(decoupled: bool, equiangular: bool, scene: &Scene) -> bool {
        let targets = EquiangularTargets::of(scene);
        let lights = if equiangular {
            targets.decoupled_lights
        } else {
            targets.decoupled_lights + targets.point_lights
        };
        decoupled && targets.open_constant_media > 0 && lights > 0
    }

    /// Traces one camera path: alternates [`Self::sample_segment_media`] along each segment with either
    /// [`Self::scatter_in_medium`] at a real collision or [`Self::shade_surface`] at the surface that ends it.
    /// With [`FirstEmission::Omit`] the light emitted by the first surface hit is left out. A training path
    /// (`guide_path` given) remembers its medium scattering events there, for the guiding cache to learn from.
    pub fn trace(
        &self,
        cx: &mut PathContext,
        ray: Ray,
        first_emission: FirstEmission,
        record: Option<&mut SampleRecord>,
        guide_path: Option<&mut GuidePath>,
    ) -> PathSample {
        let mut out = PathSample::default();
        let mut s = PathState {
            radiance: Rgb::ZERO,
            onward: OnwardState {
                beta: Rgb::ONE,
                eta_scale: 1.0,
                depth: 0,
                stack: self.camera_media,
                cone_width: self.pixel_width,
                crossings: 0,
                first_hit: true,
                collided_segment: None,
                first_event: FirstEvent::None,
            },
            prev_delta: true,
            prev_pdf: 0.0,
            prev: LightContext {
                p: ray.origin,
                n: None,
            },
            prev_light_only: false,
            aovs_pending: true,
            first_emission,
            coverage: None,
            crossed_medium: None,
            record,
            camera_t: 0.0,
            emitted: TentativeEmission::default(),
            guide_path,
            branches: Vec::new(),
            branch_budget: adjoint::MAX_BRANCHES,
        };
        cx.counters.rays.camera += 1;
        self.walk(cx, &mut s, ray, &mut out);
        while let Some(branch) = s.branches.pop() {
            let (event, mut rng) = branch.resume(&mut s);
            let mut branch_cx = PathContext {
                services: cx.services,
                rng: &mut rng,
                counters: &mut *cx.counters,
            };
            if let Some(ray) = self.scatter_onward(&mut branch_cx, &mut s, &event, true) {
                self.walk(&mut branch_cx, &mut s, ray, &mut out);
            }
        }
        out.radiance = s.radiance;
        out.alpha = s.coverage.unwrap_or(1.0);
        out
    }

    /// Follows the path in `s` from `ray` until it ends, filling `out`'s first-hit AOVs when they are pending.
    fn walk(
        &self,
        cx: &mut PathContext<'_, '_>,
        s: &mut PathState<'_>,
        mut ray: Ray,
        out: &mut PathSample,
    ) {
        let scene = cx.services.scene();
        loop {
            let hit = scene.intersect(&ray, 0.0, f32::INFINITY);
            let t_surface = hit.as_ref().map_or(f32::INFINITY, |h| h.t);
            if let Some((t, m)) = self.sample_segment_media(cx, s, &ray, t_surface) {
                if s.aovs_pending && s.onward.depth == 0 {
                    s.aovs_pending = false;
                    record_collision_aovs(out, scene, &ray, t, m);
                }
                if !self.scatter_in_medium(cx, s, &mut ray, t, m) {
                    break;
                }
                continue;
            }
            let Some(hit) = hit else {
                self.escape(cx.services, s, ray.dir);
                break;
            };
            if s.onward.beta.max_element() <= 0.0 {
                break;
            }
            let t_hit = hit.t;
            match self.shade_surface(cx, s, &ray, hit, out) {
                SurfaceOutcome::Continue(next) => {
                    if s.onward.depth == 0 {
                        s.camera_t += t_hit;
                    }
                    ray = next;
                }
                SurfaceOutcome::End => break,
            }
        }
    }

    /// The light emitted toward the camera by the first surface `ray` (a camera ray) hits: the term a path
    /// traced with [`FirstEmission::Omit`] leaves out, as [`Self::shade_surface`] counts it (front faces of
    /// emissive, lit materials; weight 1, no scattering event before it). Only for scenes without media, where
    /// nothing lies between the camera and that surface.
    /// Returns the emission and its emitter.
    pub fn first_surface_emission(
        &self,
        services: &RendererServices,
        ray: &Ray,
        counters: &mut PathCounters,
    ) -> (Rgb, Option<u32>) {
        let scene = services.scene();
        counters.rays.emitter_edge += 1;
        let mut ray = *ray;
        // Culled back faces are passed through as the path does, up to its limit of crossings.
        for _ in 0..=MAX_BOUNDARY_CROSSINGS {
            let Some(hit) = scene.intersect(&ray, 0.0, f32::INFINITY) else {
                return (Rgb::ZERO, None);
            };
            let material = &scene.materials[hit.material as usize];
            if !hit.front_face && material.culls_back_faces() {
                ray = Ray::new(hit.spawn_origin(ray.dir), ray.dir).at_time(ray.time);
                continue;
            }
            if material.unlit || !hit.front_face || !material.is_emissive() {
                return (Rgb::ZERO, None);
            }
            let emitter = scene.names().emitter_of_mesh(scene.mesh_of_prim(hit.prim));
            return (
                material.emission_at(&hit.point_shading(), &scene.textures),
                emitter,
            );
        }
        (Rgb::ZERO, None)
    }

    /// Runs the media overlapping the segment `[0, t_surface)` of `ray`: each answers one question,
    /// [`Medium::free_flight`](crate::volume::Medium::free_flight), for the part of the segment before the
    /// nearest collision of those asked before it ([`Self::combined_flight`]), and the emission their walks
    /// gathered is added ([`Self::add_media_emission`]). Returns the nearest collision's distance and medium,
    /// or `None` when the path reaches the surface (or escapes).
    fn sample_segment_media(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        t_surface: f32,
    ) -> Option<(f32, u32)> {
        let services = cx.services;
        let scene = services.scene();
        if s.onward.stack.current().is_none() && scene.filled_media.is_empty() {
            // No interior and no volume anywhere: the segment crosses no medium (what the steps below come
            // to, without their work).
            s.emitted.clear();
            s.onward.collided_segment = None;
            return None;
        }
        let crossed = services.segment_media(ray, t_surface, &s.onward.stack);
        if s.onward.depth == 0 {
            s.crossed_medium = s.crossed_medium.or(crossed.ids().first().copied());
            self.record_deep_media(services, s, ray, t_surface, crossed.ids());
        }
        let media = crossed.in_flight_order(&scene.media);
        s.emitted.clear();
        let constant = self.constant_segment(services, s, ray, t_surface, media.ids());
        if let Some(segment) = &constant {
            if self.equiangular {
                self.sample_equiangular(cx, s, ray, segment);
            }
            if self.decoupled {
                self.sample_decoupled(cx, s, ray, segment);
            }
        }
        let nearest = self.combined_flight(cx, s, ray, t_surface, media.ids());
        self.add_media_emission(cx, s, ray, media.ids());
        s.onward.collided_segment = constant.filter(|_| nearest.is_some());
        nearest
    }

    /// Deep output: where the camera ray crosses `media` before `t_surface`, when the path records deep data.
    fn record_deep_media(
        &self,
        services: &RendererServices,
        s: &mut PathState,
        ray: &Ray,
        t_surface: f32,
        media: &[u32],
    ) {
        let camera_t = s.camera_t;
        let Some(r) = s.record.as_deref_mut().filter(|r| r.deep) else {
            return;
        };
        for &m in media {
            let (near, far) = match services.scene().media[m as usize].fill_bounds() {
                Some(bounds) => match bounds.intersect(ray, 0.0, t_surface) {
                    Some(range) => range,
                    None => continue,
                },
                None => (0.0, t_surface),
            };
            r.cross_media(camera_t + near, camera_t + far.min(t_surface));
        }
    }

    /// The free flight through the overlapping `media` (in the order of
    /// [`SegmentMedia::in_flight_order`](super::services::SegmentMedia::in_flight_order)) of the segment
    /// `[0, t_surface)`: each medium in turn flies over `(0, t_cut)`, `t_cut` the nearest collision of the
    /// media before it (the surface at first), starting with the throughput their walks left; its collision,
    /// if any, becomes the nearest. Returns the nearest collision and its medium.
    ///
    /// This combines the media exactly, whatever each one's estimator. A medium's walk over `(0, t_cut)` with
    /// `t_cut` independent of it is unbiased (Kutz et al. 2017, §5): its weight w times any function h of where
    /// it ends has the expectation ∫₀^t_cut σ T h + T(t_cut) h(t_cut). Taking h as what the later media make of
    /// the interval up to that end, the expectation over both walks is the collision integral of the summed
    /// extinction, ∫ (σ₁ + σ₂) T₁ T₂ h + T₁ T₂ h(surface), with each collision in the medium that made it. So a
    /// chromatic medium keeps its spectral tracking or spectral MIS beside any other medium and the path keeps
    /// its colour; nothing is cut down to one channel. Media that never collide (absorption only) come last and
    /// carry their transmittance to the event. For analog media it is the nearest of independent collisions,
    /// the event of the sum of their extinctions. (Letting every colliding medium fly over the whole segment and
    /// keeping the nearest collision, with each walk's whole weight, is unbiased as well, since E[w 1{end > t}]
    /// = T(t) for each walk; the cut stops the later walks at the nearest collision so far and hands them the
    /// throughput the earlier ones left. Measured on the overlapping-media tests, the uncut variant looked up the
    /// densities 1.72×, 1.16× and 1.05× as often for the same error: docs/performance.md.)
    fn combined_flight(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        t_surface: f32,
        media: &[u32],
    ) -> Option<(f32, u32)> {
        let scene = cx.services.scene();
        let mut nearest: Option<(f32, u32)> = None;
        for &m in media {
            let t_cut = nearest.map_or(t_surface, |(t, _)| t);
            s.emitted.begin(m);
            let counter = &mut cx.counters.media[m as usize];
            let flight = scene.media[m as usize].free_flight(
                ray,
                t_cut,
                s.onward.beta,
                cx.rng,
                counter,
                &mut s.emitted,
            );
            s.onward.beta = flight.throughput;
            if let Some(t) = flight.collision {
                nearest = Some((t, m));
            }
        }
        nearest
    }

    /// Adds the emission the free flights of `media` (in the order they flew) gathered at their tentative
    /// collisions (`s.emitted`, already times the path throughput their walks carried there, which holds the
    /// weights of the media that flew before). A sample at t of one medium lies before that medium's end, and
    /// before the nearest collision of the media before it; the media that flew after it are accounted for by
    /// their transmittance estimates to t ([`Medium::transmittance`](crate::volume::Medium::transmittance)), so
    /// the expectation is ∫ T(t) σ_a L_e dt with T the transmittance of all the media. Holdout media emit nothing
    /// toward the camera (their collisions end camera paths).
    fn add_media_emission(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        media: &[u32],
    ) {
        if s.emitted.samples().is_empty() {
            return;
        }
        let scene = cx.services.scene();
        let emitted = std::mem::take(&mut s.emitted);
        for (i, &m) in media.iter().enumerate() {
            if self.mattes && s.onward.depth == 0 && scene.names().medium_is_holdout(m as usize) {
                continue;
            }
            let mut sum = Rgb::ZERO;
            for &(t, radiance, _) in emitted.samples().iter().filter(|e| e.2 == m) {
                let mut weight = Rgb::ONE;
                for &later in &media[i + 1..] {
                    let counter = &mut cx.counters.media[later as usize];
                    weight *= scene.media[later as usize].transmittance(ray, t, cx.rng, counter);
                }
                sum += radiance * weight;
            }
            if sum.max_element() > 0.0 {
                s.add_reached(sum, || scene.names().emitter_of_medium(m as usize));
            }
        }
        s.emitted = emitted;
    }

    /// The segment `[0, t_surface)` of `ray` when equiangular or decoupled sampling applies to it: one is on,
    /// the path may still scatter, the segment is bounded and inside exactly one medium, and that medium
    /// scatters with constant coefficients.
    fn constant_segment(
        &self,
        services: &RendererServices,
        s: &PathState,
        ray: &Ray,
        t_surface: f32,
        media: &[u32],
    ) -> Option<ConstantSegment> {
        let &[medium] = media else { return None };
        let on = self.equiangular || self.decoupled;
        if !on || s.onward.depth >= self.max_depth || !t_surface.is_finite() {
            return None;
        }
        let coefficients = services.scene().media[medium as usize].constant_scattering()?;
        Some(ConstantSegment {
            origin: ray.origin,
            dir: ray.dir,
            length: t_surface,
            throughput: s.onward.beta,
            coefficients,
        })
    }

    /// The equiangular half of the direct light on a constant-medium segment: chooses a light as next-event
    /// estimation does and, when it is a point or spot light, samples a distance t on the segment with density
    /// ∝ 1/r² toward it (Kulla & Fajardo 2012, eq. 8) and adds σ_s T(t) ρ(θ) L_i T_shadow / (P(light) p_e(t)),
    /// weighted by the power heuristic against the medium's free-flight density at t. The path does not
    /// continue from t; scattering there is the free-flight sample's job.
    fn sample_equiangular(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        segment: &ConstantSegment,
    ) {
        let services = cx.services;
        let scene = services.scene();
        let u = cx.rng.sample_2d();
        let Some((index, pmf)) = services.choose_light(u.x) else {
            return;
        };
        let Some(light) = scene.lights[index].point_position() else {
            return;
        };
        let Some(equiangular) =
            Equiangular::new(segment.origin, segment.dir, segment.length, light)
        else {
            return;
        };
        let (t, pdf) = equiangular.sample(u.y);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return;
        }
        cx.counters.rays.equiangular += 1;
        let p = ray.at(t);
        let Some(chosen) = services.sample_chosen_light(index, pmf, p, cx.rng.next_2d()) else {
            return;
        };
        let ls = chosen.sample;
        let coefficients = &segment.coefficients;
        let Some((phase, tr)) = ScatterPoint::on(ray, p, &s.onward.stack).lit_by(
            services,
            &coefficients.phase,
            &ls,
            1.0,
            cx.rng,
            cx.counters,
        ) else {
            return;
        };
        let weight = power_heuristic(pdf, coefficients.free_flight_pdf(t, segment.throughput));
        let transmittance = coefficients.transmittance(t);
        let value = segment.throughput
            * coefficients.sigma_s
            * transmittance
            * tr
            * ls.radiance
            * (phase * weight / (pmf * pdf));
        s.add_volume_sample(value, || scene.names().emitter_of_light(index));
    }

    /// The decoupled direct light of a constant-medium segment: a distance t drawn from the free-flight density
    /// truncated to the segment ([`ConstantScattering::sample_in_segment`]; Novák et al. 2018, "Monte Carlo
    /// Methods for Volumetric Light Transport Simulation", §5), so that every segment through the medium
    /// estimates its in-scattered light, not only the fraction 1 − T(d) of them that collide, and a next-event
    /// estimate there: σ_s T(t) ρ L_i T_shadow / (p_d(t) P(light) p(ω)), for the lights it serves
    /// ([`Self::decoupled_serves`]: all but the point and spot lights of equiangular sampling). For those lights
    /// it replaces next-event estimation at the segment's free-flight collision (the distance weights are 1
    /// here and 0 there, which sum to 1 wherever p_d > 0, and p_d > 0 on the whole segment). Its weight is the
    /// direction MIS a collision at t would use: the power heuristic (Veach 1997, eq. 9.13) against the density
    /// the path would sample its next direction with there, guided or not, so the phase-sampled hits on
    /// emitters keep their weight and the estimate stays unbiased. The path does not continue from t.
    ///
    /// Guided, t comes from the one-sample mixture of the free-flight density with the distances of the cache's
    /// lit grid ([`guided::decoupled_distance`]; Herholz et al. 2019 §5), and a training path records what the
    /// sample received ([`GuidePath::push_lit`]) and what its shadow rays found
    /// ([`GuidePath::push_decoupled_shadow`]), from which an image path's shadow rays play guided shadow roulette
    /// as at a collision (`crate::guiding::shadow`): in the door-gap room most decoupled samples lie in the dark,
    /// and their shadow rays toward the sun end on the wall.
    fn sample_decoupled(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        segment: &ConstantSegment,
    ) {
        let services = cx.services;
        let scene = services.scene();
        let c = &segment.coefficients;
        let Some((t, pdf)) = guided::decoupled_distance(
            services,
            c,
            ray,
            segment.length,
            segment.throughput,
            cx.rng.sample_2d(),
        ) else {
            return;
        };
        if !(pdf > 0.0 && pdf.is_finite()) {
            return;
        }
        cx.counters.rays.decoupled += 1;
        let p = ray.at(t);
        let wo = -ray.dir;
        let transmittance = c.transmittance(t);
        // The direction density of a path that collided here, for the direction MIS.
        let at_collision = c.throughput_at_collision(t, segment.throughput);
        // Looked up and multiplied with the phase function only when a light sample is weighed against it (none
        // for a delta light, as the door-gap room's sun: the product is most of guiding's cost per event).
        let mut guide: Option<Option<guided::Guide>> = None;
        let training = s.guide_path.is_some();
        let scale = segment.throughput * c.sigma_s * transmittance / pdf;
        let ctx = LightContext { p, n: None };
        // What the lights gave, per unit of `scale`, for the guiding cache's lit grid (training paths only).
        let mut received = Rgb::ZERO;
        let survival = match services.guide() {
            Some(guide) if !training => guide.shadow_survival(p, VISIBILITY_MIN_SURVIVAL),
            _ => 1.0,
        };
        services.sample_lights(&ctx, cx.rng, |chosen, rng| {
            if !self.decoupled_serves(services, chosen.index) {
                return;
            }
            if survival < 1.0 && rng.next_f32() >= survival {
                return;
            }
            let ls = chosen.sample;
            let lit = ScatterPoint::on(ray, p, &s.onward.stack).lit_by(
                services,
                &c.phase,
                &ls,
                1.0 / survival,
                rng,
                cx.counters,
            );
            if let Some(path) = s.guide_path.as_deref_mut() {
                path.push_decoupled_shadow(p, lit.map_or(0.0, |(_, tr)| tr.max_element()));
            }
            let Some((phase, tr)) = lit else {
                return;
            };
            let light_pdf = chosen.pmf * ls.pdf;
            let weight = if ls.is_delta || !self.media_mis {
                1.0
            } else {
                let guide = guide.get_or_insert_with(|| {
                    guided::medium_guide_at(services, at_collision, p, &c.phase, wo, training)
                });
                power_heuristic(light_pdf, guided::mixture_pdf(guide.as_ref(), ls.wi, phase))
            };
            if training {
                received += tr * ls.radiance * (phase * weight / light_pdf);
            }
            let value = scale * tr * ls.radiance * (phase * weight / light_pdf);
            s.add_volume_sample(value, || scene.names().emitter_of_light(chosen.index));
        });
        if let Some(path) = s.guide_path.as_deref_mut() {
            path.push_lit(p, luminance(received));
        }
    }

    /// True when the decoupled sample, not next-event estimation at the collision, estimates the direct light
    /// of light `index` on constant-medium segments: it is on, and the light is not one that equiangular
    /// sampling serves (a point or spot light, when equiangular sampling is on; MIS'd with the collision's
    /// estimate, it already places distances where such a light is bright).
    fn decoupled_serves(&self, services: &RendererServices, index: usize) -> bool {
        self.decoupled
            && !(self.equiangular && services.scene().lights[index].point_position().is_some())
    }

    /// The MIS weight of next-event estimation at a free-flight collision `t` along the current segment for a
    /// light sample from light `index`: the power heuristic against equiangular sampling toward that light
    /// when the segment had it, else 1.
    fn equiangular_weight(
        &self,
        services: &RendererServices,
        s: &PathState,
        t: f32,
        index: usize,
    ) -> f32 {
        let Some(segment) = &s.onward.collided_segment else {
            return 1.0;
        };
        let Some(light) = services.scene().lights[index].point_position() else {
            return 1.0;
        };
        if !self.equiangular {
            return 1.0;
        }
        let pdf_equiangular = Equiangular::new(segment.origin, segment.dir, segment.length, light)
            .map_or(0.0, |e| e.pdf(t));
        power_heuristic(
            segment.coefficients.free_flight_pdf(t, segment.throughput),
            pdf_equiangular,
        )
    }

    /// A path that escapes along `dir`: a camera ray decides its coverage (what the media it crossed took),
    /// and the environment's light is added.
    fn escape(&self, services: &RendererServices, s: &mut PathState, dir: Vec3) {
        if s.onward.depth == 0 {
            let scene = services.scene();
            let medium = s.crossed_medium;
            let item = || medium.map(|m| scene.names().item_of_medium(m as usize));
            s.cover(s.coverage_so_far(), CameraEvent::Ended, f32::INFINITY, item);
        }
        self.add_environment(services, s, dir);
    }

    /// Adds the environment's radiance for a path that escapes along `dir`, MIS-weighted against the
    /// environment's light sampling. Seen directly (no scattering event before), it is recorded as the
    /// environment and, on a transparent film, left out of the radiance.
    fn add_environment(&self, services: &RendererServices, s: &mut PathState, dir: Vec3) {
        let scene = services.scene();
        let Some(env) = scene.environment_light() else {
            return;
        };
        let weight = if s.prev_light_only {
            0.0
        } else if s.prev_delta {
            1.0
        } else {
            power_heuristic(s.prev_pdf, services.environment_pdf(dir, &s.prev))
        };
        let value = s.onward.beta * env.radiance(dir) * weight;
        let emitter = || {
            scene
                .environment
                .and_then(|i| scene.names().emitter_of_light(i))
        };
        if s.onward.depth > 0 {
            s.add_reached(value, emitter);
            return;
        }
        if !self.transparent {
            s.radiance += value;
        }
        if let Some(r) = s.record.as_deref_mut() {
            r.push(value, Origin::Environment, emitter(), !self.transparent);
        }
    }

    /// Shades a surface hit: records the first hit's AOVs, adds the surface's emission (MIS-weighted against
    /// light sampling), passes through index-matched boundaries and culled back faces, and scatters
    /// ([`Self::scatter_at_surface`]).
    fn shade_surface(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        mut hit: SurfaceHit,
        out: &mut PathSample,
    ) -> SurfaceOutcome {
        let services = cx.services;
        let scene = services.scene();
        let material = &scene.materials[hit.material as usize];
        // A single-sided material's back faces are culled (glTF 2.0 §3.9.3 `doubleSided`; UsdGeomGprim
        // `doubleSided`): camera rays, before any scattering event, pass through them as if they were not there.
        if s.onward.depth == 0 && !hit.front_face && material.culls_back_faces() {
            return cross_boundary(s, ray, &hit, None, cx.counters);
        }
        s.onward.cone_width += self.pixel_spread * hit.t;
        let at = hit.shading_point(s.onward.cone_width, ray.dir);
        let unmapped = hit.shading;
        if material.has_normal_map() {
            scene.apply_normal_map(&mut hit, &at);
        }
        let mesh = || scene.mesh_of_prim(hit.prim);
        // Camera rays (no scattering event yet) pass through shadow catchers and are cut by holdouts.
        let matte = self.mattes && s.onward.depth == 0;
        if matte && scene.names().mesh_is_shadow_catcher(mesh()) {
            return self.pass_shadow_catcher(cx, s, ray, &hit, &at);
        }
        let count_emission = !s.onward.first_hit || s.first_emission == FirstEmission::Count;
        s.onward.first_hit = false;
        let aovs = SurfaceAovs {
            hit: &hit,
            ray,
            at: &at,
            scene,
        };
        if matte && scene.names().mesh_is_holdout(mesh()) {
            aovs.record(s, out);
            s.cover(s.coverage_so_far(), CameraEvent::Ended, hit.t, || None);
            return SurfaceOutcome::End;
        }
        let item = || Some(scene.names().item_of_mesh(mesh()));
        let emitter = || scene.names().emitter_of_mesh(mesh());
        if material.unlit {
            aovs.record(s, out);
            show_unlit(s, scene, &hit, &at, item, emitter);
            return SurfaceOutcome::End;
        }
        if count_emission && hit.front_face && material.is_emissive() {
            self.add_surface_emission(services, s, &hit, emitter);
        }
        let shading = scene.shading(hit.material, &at);
        if shading.bsdf.is_index_matched() {
            return cross_boundary(s, ray, &hit, material.interior, cx.counters);
        }
        aovs.record_with_albedo(s, out, || shading.params.base_color);
        if s.onward.depth == 0 {
            s.cover(1.0, CameraEvent::Surface, hit.t, item);
        }
        if s.onward.depth >= self.max_depth {
            return SurfaceOutcome::End;
        }
        let Some(frame) = shading_frame(&hit, material) else {
            return SurfaceOutcome::End;
        };
        let surface = Surface {
            hit: &hit,
            at: &at,
            unmapped,
            frame,
        };
        self.scatter_at_surface(cx, s, ray, &surface, &shading.bsdf)
    }

    /// Adds the light the emissive surface `hit` emits toward the path (where an emissive texture is black there
    /// is nothing to weight: the light sampler's density is not asked for), weighted by the power heuristic
    /// against light sampling when the last event sampled its direction.
    fn add_surface_emission(
        &self,
        services: &RendererServices,
        s: &mut PathState,
        hit: &SurfaceHit,
        emitter: impl FnOnce() -> Option<u32>,
    ) {
        let scene = services.scene();
        let material = &scene.materials[hit.material as usize];
        let le = material.emission_at(&hit.point_shading(), &scene.textures);
        if le.max_element() > 0.0 {
            let weight = match scene.area_light_of(hit.prim) {
                Some(_) if s.prev_light_only => 0.0,
                Some(light) if !s.prev_delta => {
                    power_heuristic(s.prev_pdf, services.area_light_pdf(light, &s.prev, hit.p))
                }
                _ => 1.0,
            };
            s.add_reached(s.onward.beta * le * weight, emitter);
        }
    }

    /// Scatters at a surface: a dispersive surface first makes the path carry one channel; next-event
    /// estimation, then the BSDF (or, guided at a Lambertian surface, the mixture of the guide and the BSDF,
    /// see the guided module) samples the direction to continue in.
    fn scatter_at_surface(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        surface: &Surface,
        bsdf: &Bsdf,
    ) -> SurfaceOutcome {
        let services = cx.services;
        let scene = services.scene();
        let (hit, frame) = (surface.hit, surface.frame);
        let material = &scene.materials[hit.material as usize];
        // The material's BSDF, copied only where this hit changes it.
        let mut bsdf = Cow::Borrowed(bsdf);
        // A dispersive surface: the path goes on in one colour channel, refracted with that channel's index (the
        // first hit's colours are seen with the throughput before the choice).
        let seen_beta = s.onward.beta;
        if material.is_dispersive() {
            let channel = carry_one_channel(&mut s.onward.beta, cx.rng);
            bsdf = Cow::Owned(material.bsdf_in_channel(surface.at, &scene.textures, channel));
        }
        // The clear coat's normal: its own normal map, else the normal before the base's normal map.
        if let Some(n) = material.coat_normal(&surface.unmapped, surface.at, &scene.textures) {
            let n = if frame.n.dot(hit.shading.n) < 0.0 {
                -n
            } else {
                n
            };
            bsdf.to_mut().set_coat_normal(frame.to_local(n));
        }
        let bsdf = &*bsdf;
        let wo = frame.to_local(-ray.dir);
        if s.onward.depth == 0 {
            if let Some(r) = s.record.as_deref_mut() {
                r.colors = bsdf.colors(wo) * seen_beta;
            }
        }
        let guide = match bsdf {
            Bsdf::Lambert(_) => guided::surface_guide_at(
                services,
                s.onward.beta,
                hit.p,
                frame.n,
                s.guide_path.is_some(),
            ),
            _ => None,
        };
        // Next-event estimation is weighed against the BSDF's density alone, guided or not (see the guided
        // module): so is the emission the sampled direction reaches (`mis_pdf` below).
        if !bsdf.is_delta() {
            self.surface_next_event(cx, s, ray, surface, bsdf, |wi| bsdf.pdf(wo, wi));
        }
        let direction_pdf =
            |wi: Vec3| guided::mixture_pdf(guide.as_ref(), frame.to_world(wi), bsdf.pdf(wo, wi));
        let sampled = guided::sample_bsdf(bsdf, guide.as_ref(), &frame, wo, cx.rng, direction_pdf);
        let Some(bs) = sampled else {
            return SurfaceOutcome::End;
        };
        if bs.pdf.is_nan() || bs.pdf <= 0.0 || bs.f.max_element() <= 0.0 {
            return SurfaceOutcome::End;
        }
        let mis_pdf = if guide.is_some() {
            bsdf.pdf(wo, bs.wi)
        } else {
            bs.pdf
        };
        if s.onward.depth == 0 && s.record.is_some() {
            // The first event's classes share the path's later light as they share this direction's value.
            s.onward.first_event = FirstEvent::Surface(if bs.is_delta {
                LobeSplit::only(bs.class, Rgb::ONE)
            } else {
                bsdf.eval_split(wo, bs.wi).shares()
            });
        }
        // What a training path's record needs for the cell's selection probability.
        let densities = s.guide_path.is_some().then(|| StrategyDensities {
            unguided: bsdf.pdf(wo, bs.wi),
            guide: guide.as_ref().map(|g| g.product.pdf(frame.to_world(bs.wi))),
        });
        self.continue_from_surface(
            cx,
            s,
            ray,
            surface,
            material.interior,
            (&bs, mis_pdf, densities),
        )
    }

    /// Next-event estimation at a surface, seen along `ray`: each light sample weighted by the power heuristic
    /// against `direction_pdf` (the BSDF's density, local directions, also where the path's next direction is
    /// guided: the emission that direction reaches is weighed with the same density).
    fn surface_next_event(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        surface: &Surface,
        bsdf: &Bsdf,
        direction_pdf: impl Fn(Vec3) -> f32,
    ) {
        let services = cx.services;
        let scene = services.scene();
        let (hit, frame) = (surface.hit, surface.frame);
        let wo = frame.to_local(-ray.dir);
        let material = &scene.materials[hit.material as usize];
        let ctx = LightContext {
            p: hit.p,
            n: Some(frame.n),
        };
        // Guided shadow roulette (`crate::guiding::shadow`) for the image's paths; a training path traces every
        // shadow ray and records what it found.
        let survival = match services.guide() {
            Some(guide) if s.guide_path.is_none() => {
                guide.shadow_survival(hit.p, VISIBILITY_MIN_SURVIVAL)
            }
            _ => 1.0,
        };
        services.sample_lights(&ctx, cx.rng, |chosen, rng| {
            let ls = chosen.sample;
            let wi = frame.to_local(ls.wi);
            let f = bsdf.eval(wo, wi) * wi.z.abs();
            let segment = ls.shadow_segment(&hit.surface_point());
            if let (true, Some(segment)) = (f.max_element() > 0.0, segment) {
                if survival < 1.0 && rng.next_f32() >= survival {
                    return;
                }
                let mut stack = s.onward.stack;
                if let Some(interior) = material.interior {
                    stack.cross(interior, ls.wi.dot(hit.geometric_normal) < 0.0);
                }
                let tr = services.weighted_transmittance(
                    1.0 / survival,
                    &segment,
                    ray.time,
                    &stack,
                    rng,
                    cx.counters,
                );
                if let Some(path) = s.guide_path.as_deref_mut() {
                    path.push_surface_shadow(hit.p, tr.max_element());
                }
                if tr.max_element() > 0.0 {
                    let light_pdf = chosen.pmf * ls.pdf;
                    let weight = if ls.is_delta {
                        1.0
                    } else {
                        power_heuristic(light_pdf, direction_pdf(wi))
                    };
                    let value = s.onward.beta * f * tr * ls.radiance * (weight / light_pdf);
                    let beta = s.onward.beta;
                    let split = || {
                        let factor = beta * tr * ls.radiance * (wi.z.abs() * weight / light_pdf);
                        bsdf.eval_split(wo, wi) * factor
                    };
                    let emitter = || scene.names().emitter_of_light(chosen.index);
                    s.add_surface_sample(value, split, emitter);
                }
            }
        });
    }

    /// Continues the path from `surface` along the sampled direction `bs`: weights the throughput, keeps
    /// `mis_pdf` (the density an emitter hit next is weighed with: the BSDF's, also where `bs` was guided),
    /// crosses into or out of the surface's `interior` when the direction refracts, counts the bounce (Russian
    /// roulette) and remembers the event for the guiding cache (with the strategies' `densities`, given on
    /// training paths). Returns the next ray, or the end of the path.
    fn continue_from_surface(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        surface: &Surface,
        interior: Option<u32>,
        (bs, mis_pdf, densities): (&BsdfSample, f32, Option<StrategyDensities>),
    ) -> SurfaceOutcome {
        let (hit, frame) = (surface.hit, surface.frame);
        let wi_world = frame.to_world(bs.wi);
        s.onward.beta *= bs.f * (bs.wi.z.abs() / bs.pdf);
        s.onward.eta_scale *= bs.eta * bs.eta;
        s.prev_delta = bs.is_delta;
        s.prev_pdf = mis_pdf;
        s.prev = LightContext {
            p: hit.p,
            n: Some(frame.n),
        };
        s.prev_light_only = false;
        let radiance_before = s.radiance;
        if let Some(interior) = interior {
            // Crossing the surface (refraction) enters or leaves its interior.
            let wo_world = -ray.dir;
            let crossing = wi_world.dot(hit.geometric_normal).signum()
                != wo_world.dot(hit.geometric_normal).signum();
            if crossing {
                s.onward
                    .stack
                    .cross(interior, wi_world.dot(hit.geometric_normal) < 0.0);
            }
        }
        if !self.next_bounce(s, cx.rng, true) {
            return SurfaceOutcome::End;
        }
        if let (Some(path), false, Some(densities)) =
            (s.guide_path.as_deref_mut(), bs.is_delta, densities)
        {
            path.push(
                hit.p,
                (wi_world, bs.pdf),
                densities,
                s.onward.beta,
                radiance_before,
            );
        }
        cx.counters.rays.bounce += 1;
        SurfaceOutcome::Continue(Ray::new(hit.spawn_origin(wi_world), wi_world).at_time(ray.time))
    }

    /// A camera ray (no scattering event yet) at a shadow catcher: the first catcher it meets records its
    /// direct light with and without the scene's occlusion (next-event estimation alone, weight 1, both
    /// times the throughput), when the shadow-catcher layer is written; the ray passes through, as through an
    /// invisible boundary.
    fn pass_shadow_catcher(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        hit: &SurfaceHit,
        at: &crate::material::ShadingPoint,
    ) -> SurfaceOutcome {
        let services = cx.services;
        let scene = services.scene();
        let wanted = s
            .record
            .as_deref()
            .is_some_and(|r| r.shadow_catcher && r.catcher.is_none());
        if wanted {
            let bsdf = scene.shading(hit.material, at).bsdf;
            let frame = if hit.front_face {
                hit.shading
            } else {
                Frame {
                    s: hit.shading.s,
                    t: -hit.shading.t,
                    n: -hit.shading.n,
                }
            };
            let wo = frame.to_local(-ray.dir);
            let ctx = LightContext {
                p: hit.p,
                n: Some(frame.n),
            };
            let (mut lit, mut open) = (Rgb::ZERO, Rgb::ZERO);
            let beta = s.onward.beta;
            services.sample_lights(&ctx, cx.rng, |chosen, rng| {
                let ls = chosen.sample;
                let wi = frame.to_local(ls.wi);
                let f = bsdf.eval(wo, wi) * wi.z.abs();
                if f.max_element() <= 0.0 {
                    return;
                }
                let unshadowed = beta * f * ls.radiance / (chosen.pmf * ls.pdf);
                open += unshadowed;
                if let Some(segment) = ls.shadow_segment(&hit.surface_point()) {
                    let tr = services.transmittance(
                        &segment,
                        ray.time,
                        &s.onward.stack,
                        rng,
                        cx.counters,
                    );
                    lit += unshadowed * tr;
                }
            });
            if let Some(r) = s.record.as_deref_mut() {
                r.catcher = Some((lit, open));
            }
        }
        s.onward.crossings += 1;
        if s.onward.crossings > MAX_BOUNDARY_CROSSINGS {
            return SurfaceOutcome::End;
        }
        cx.counters.rays.bounce += 1;
        SurfaceOutcome::Continue(Ray::new(hit.spawn_origin(ray.dir), ray.dir).at_time(ray.time))
    }

    /// Handles a real collision at distance `t` in medium `m`: the medium's albedo, next-event estimation with
    /// MIS against the direction sampling to come, guided Russian roulette and splitting where it applies
    /// ([`Self::guided_roulette`]), then [`Self::scatter_onward`]. Returns false when the path ends.
    fn scatter_in_medium(
        &self,
        cx: &mut PathContext<'_, '_>,
        s: &mut PathState<'_>,
        ray: &mut Ray,
        t: f32,
        m: u32,
    ) -> bool {
        let services = cx.services;
        let scene = services.scene();
        s.onward.cone_width += self.pixel_spread * t;
        let p = ray.at(t);
        if s.onward.depth == 0 {
            if self.mattes && scene.names().medium_is_holdout(m as usize) {
                s.cover(s.coverage_so_far(), CameraEvent::Ended, t, || None);
                return false;
            }
            s.cover(1.0, CameraEvent::Collision, t, || {
                Some(scene.names().item_of_medium(m as usize))
            });
        }
        // The medium's emission here was gathered with its free flight (at every tentative collision), which
        // may have kept the collision it looked up here.
        let collision = s
            .emitted
            .real_collision(m, t)
            .unwrap_or_else(|| scene.media[m as usize].collision(p, ray.time));
        s.onward.beta *= collision.albedo;
        if s.onward.beta.max_element() <= 0.0 || s.onward.depth >= self.max_depth {
            return false;
        }
        let wo = -ray.dir;
        // Guided directions (see the guided module): the mixture's density is what light sampling is weighed
        // against, so the estimate stays unbiased; the choice is made once, before roulette changes the
        // throughput, and holds for every path split off here.
        let guide = guided::medium_guide_at(
            services,
            s.onward.beta,
            p,
            &collision.phase,
            wo,
            s.guide_path.is_some(),
        );
        let direction_pdf =
            |wi: Vec3| guided::mixture_pdf(guide.as_ref(), wi, collision.phase.eval(wo, wi));
        self.medium_next_event(cx, s, ray, t, &collision.phase, direction_pdf);
        let event = MediumEvent {
            ray: *ray,
            t,
            phase: collision.phase,
            guide,
        };
        let played = match self.guided_roulette(cx, s, &event) {
            Some(false) => return false,
            Some(true) => true,
            None => false,
        };
        self.scatter_onward(cx, s, &event, played)
            .map(|next| *ray = next)
            .is_some()
    }

    /// Guided Russian roulette and splitting at the medium scattering `event`, after its albedo and its
    /// next-event estimate ([`crate::guiding::adjoint`]): the expected contribution of the path's continuation
    /// is its throughput (channel mean) times the cache's mean incident radiance there (which, like the
    /// continuation, leaves out the event's own next-event estimate), compared with its pixel's training value.
    /// Returns `None` where it does not apply (not on, a training path, or no estimate: classic Russian roulette
    /// then), else whether the path goes on; paths split off wait in `s.branches`.
    fn guided_roulette(
        &self,
        cx: &mut PathContext,
        s: &mut PathState<'_>,
        event: &MediumEvent,
    ) -> Option<bool> {
        if !self.guided_roulette || s.guide_path.is_some() {
            return None;
        }
        let pixel = cx.services.pixel_estimate()?;
        let radiance = cx.services.guide()?.mean_radiance_at(event.point())?;
        let ratio = s.onward.beta.element_sum() / 3.0 * radiance / pixel;
        match adjoint::play(ratio, cx.rng.next_f32(), s.branch_budget) {
            Roulette::Ends => Some(false),
            Roulette::GoesOn { copies, weight } => {
                s.onward.beta *= weight;
                for _ in 1..copies {
                    let branch = Branch::split_off(s, event, cx.rng);
                    s.branches.push(branch);
                }
                s.branch_budget -= copies - 1;
                cx.counters.rays.split += u64::from(copies - 1);
                Some(true)
            }
        }
    }

    /// Samples the direction to go on from the medium scattering `event` (its albedo and next-event estimate
    /// done): the phase function, or the mixture with the cache's distribution when the event is guided.
    /// Classic Russian roulette is played unless `roulette_played` (guided roulette decided this event).
    /// Returns the next ray, or `None` when the path ends.
    fn scatter_onward(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        event: &MediumEvent,
        roulette_played: bool,
    ) -> Option<Ray> {
        let p = event.point();
        let (wi, pdf, weight) =
            guided::sample_phase(&event.phase, event.guide.as_ref(), -event.ray.dir, cx.rng)?;
        s.onward.beta *= weight;
        if s.onward.depth == 0 {
            s.onward.first_event = FirstEvent::Volume;
        }
        s.prev_delta = false;
        s.prev_pdf = pdf;
        s.prev = LightContext { p, n: None };
        s.prev_light_only = !self.media_mis;
        let radiance_before = s.radiance;
        if !self.next_bounce(s, cx.rng, !roulette_played) {
            return None;
        }
        if let Some(path) = s.guide_path.as_deref_mut() {
            let densities = StrategyDensities {
                unguided: event.phase.eval(-event.ray.dir, wi),
                guide: event.guide.as_ref().map(|g| g.product.pdf(wi)),
            };
            path.push(p, (wi, pdf), densities, s.onward.beta, radiance_before);
        }
        cx.counters.rays.bounce += 1;
        Some(Ray::new(p, wi).at_time(event.ray.time))
    }

    /// Next-event estimation at a real collision `t` along `ray` (the point, with its phase function `phase`):
    /// one light sample, weighted by the power heuristic against `direction_pdf` (the density with which the
    /// path samples its next direction), or against equiangular sampling for a point or spot light. Nothing for
    /// a light whose direct light the segment's decoupled sample estimated ([`Self::decoupled_serves`]).
    fn medium_next_event(
        &self,
        cx: &mut PathContext,
        s: &mut PathState,
        ray: &Ray,
        t: f32,
        phase: &PhaseFunction,
        direction_pdf: impl Fn(Vec3) -> f32,
    ) {
        let services = cx.services;
        let scene = services.scene();
        let ctx = LightContext {
            p: ray.at(t),
            n: None,
        };
        let decoupled = self.decoupled && s.onward.collided_segment.is_some();
        if decoupled && !self.equiangular {
            // The segment's decoupled sample estimated every light's direct light.
            return;
        }
        // Guided shadow roulette (`crate::guiding::shadow`) for the image's paths; a training path traces every
        // shadow ray and records what it found.
        let survival = match services.guide() {
            Some(guide) if s.guide_path.is_none() => {
                guide.shadow_survival(ctx.p, SHADOW_MIN_SURVIVAL)
            }
            _ => 1.0,
        };
        let shadow_weight = 1.0 / survival;
        services.sample_lights(&ctx, cx.rng, |chosen, rng| {
            if decoupled && self.decoupled_serves(services, chosen.index) {
                // The segment's decoupled sample estimated this light's direct light (weight 0 here).
                return;
            }
            if survival < 1.0 && rng.next_f32() >= survival {
                return;
            }
            let ls = chosen.sample;
            let lit = ScatterPoint::on(ray, ctx.p, &s.onward.stack).lit_by(
                services,
                phase,
                &ls,
                shadow_weight,
                rng,
                cx.counters,
            );
            if let Some(path) = s.guide_path.as_deref_mut() {
                path.push_shadow(ctx.p, lit.map_or(0.0, |(_, tr)| tr.max_element()));
            }
            let Some((phase, tr)) = lit else {
                return;
            };
            let light_pdf = chosen.pmf * ls.pdf;
            let weight = if ls.is_delta {
                self.equiangular_weight(services, s, t, chosen.index)
            } else if !self.media_mis {
                1.0
            } else {
                power_heuristic(light_pdf, direction_pdf(ls.wi))
            };
            let value = s.onward.beta * tr * ls.radiance * (phase * weight / light_pdf);
            s.add_volume_sample(value, || scene.names().emitter_of_light(chosen.index));
        });
    }

    /// Counts a scattering event and, with `roulette`, plays classic Russian roulette; returns false when the
    /// path ends. The survival probability is the throughput's largest channel with the refractions' 1/η²
    /// undone (the `etaScale` of pbrt-v4's path integrator; Mitsuba 3's path tracers do the same): a path inside a dense dielectric
    /// carries 1/η² less radiance until it leaves, not less importance, and is not ended more often for it.
    fn next_bounce(&self, s: &mut PathState, rng: &mut Rng, roulette: bool) -> bool {
        s.onward.depth += 1;
        if roulette && s.onward.depth > ROULETTE_START {
            let survive = (s.onward.beta.max_element() * s.onward.eta_scale).clamp(0.05, 1.0);
            if rng.next_f32() >= survive {
                return false;
            }
            s.onward.beta /= survive;
        }
        true
    }
}
