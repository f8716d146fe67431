//! What `--guiding auto` decides for a scene, and why (as `--explain` prints it).
//!
//! Guiding could pay only where paths wander: in media of high albedo that are optically thick, where light
//! reaches a point after many scattering events. It costs its training (7 samples per pixel of the frame) and a
//! lookup per scattering event. Measured on the eleven benchmark scenes with a scattering medium (docs/performance.md,
//! "Where guiding pays: the benchmark set against a rule for auto"; 128², 128 spp, 2 threads, CPU time, two pairs
//! of seeds each), guided paths had 1.05-1.37x unguided paths' efficiency on three (the backlit cloud; the
//! door-gap room and the validation's point in a medium) and 0.89-1.08x on the other eight, none of them above 1
//! in both pairs by more than the noise. What the pilot below measures of the media cannot tell them apart: the
//! same cloud (albedo 0.99, depth 22 or 76) gained 1.15x and 1.27x lit from behind but lost (0.97x, 0.92x) lit
//! from the front. The backlit clouds' win is the CPU their guided shadow roulette saves (0.28-0.54x the shadow
//! rays; the front-lit ones 1.00x), which depends on the light's way through the medium. So `auto` decides in
//! two steps: before rendering, off where the scene has no scattering medium (the pilot reports the likeliest
//! medium of those it has, the one with the largest albedo × optical depth); otherwise from a pilot of unguided
//! paths (sample 0 of at least 16,384 pixels spread over the frame, every pixel of a smaller one: `decide`
//! in `crate::render::guiding`), from what their shadow rays found ([`decide_from_shadow_pilot`]): guided where
//! guided shadow roulette would trace at most [`AUTO_MAX_SHADOW_TRACED`] of them and the render has at least
//! [`AUTO_MIN_SPP`] samples per pixel. Of the benchmark scenes that guides the backlit clouds and, from 128² on,
//! the door-gap room (its pilot 0.44 there, against 0.77 and 0.80 on the glass scene and `cloud_mitsuba_check`,
//! where guiding neither wins nor loses: docs/performance.md, "Auto decides by a shadow-ray pilot" and "A pilot of
//! the same size at every image size"); the point light's win is left to `--guiding on`.
//!
//! The pilot measures with the media's own estimators, through the `Medium` trait only: [`PILOT_CHORDS`]
//! chords through the centre of the medium's bounds (a position-filled volume's box, or the box of the meshes
//! whose interior it fills) along fixed, evenly spread directions. Along each, free flights are sampled one
//! after the other without turning: the number of real collisions on the chord estimates its optical depth
//! (they form a Poisson process of rate σ_t), and the albedo is read at the first. Fixed seeds: the same
//! scene always decides the same way.

use super::GuidingMode;
use crate::math::{luminance, Aabb, Ray, Rng, Vec3};
use crate::scene::Scene;
use crate::volume::{Medium, TentativeEmission, TrackingCounters};

/// Chords the pilot measures per medium.
pub const PILOT_CHORDS: usize = 32;
/// Real collisions the pilot counts along one chord at most (an optical depth beyond it counts as this).
const MAX_PILOT_COLLISIONS: u32 = 1000;

/// Whether a render is guided, and why in words.
#[derive(Clone, Debug, PartialEq)]
pub struct GuidingDecision {
    /// True when paths are guided (for a provisional decision: when the training starts).
    pub on: bool,
    /// True when a pilot of unguided paths decides, before the training, whether the render is guided
    /// ([`decide_from_shadow_pilot`]; `--guiding auto` in a scene with a scattering medium).
    pub provisional: bool,
    /// Why, as `--explain` says it.
    pub reason: String,
}

/// The fewest samples per pixel a render must have for `auto` to guide it: the training's 7 are the image's
/// first, but a render of few more has too few guided samples to pay back its iterations (at 16 spp the
/// benchmark's wins were 1.02-1.04x, within the noise).
pub const AUTO_MIN_SPP: u32 = 16;

/// The largest fraction of the pilot's shadow rays that guided shadow roulette may still have to trace
/// for `auto` to guide (see [`decide_from_shadow_pilot`]).
pub const AUTO_MAX_SHADOW_TRACED: f64 = 0.5;

/// The pixels the shadow-ray pilot traces at the least, where the frame has that many (every pixel of a smaller
/// frame; `pilot_stride` in `crate::render::guiding`): its prediction rests on the records per voxel of the
/// shadow grid, whatever the image's size (measured on the door-gap room: 0.58 of the shadow rays traced from
/// 4,096 pixels, 0.44 from 16,384 and from 65,536). Part of an `auto` render's farm hash, as it decides.
pub const AUTO_PILOT_PATHS: usize = 16_384;

/// Whether `auto` guides, from the shadow rays of its pilot (unguided paths of sample 0 over a lattice of the
/// frame's pixels): `shadow_rays` of them in all, `medium_shadow_rays` from medium scattering events, of which guided shadow
/// roulette, from the transmittance they found, would trace `medium_traced` (the sum of their survival
/// probabilities, [`super::shadow`]). On the benchmark scenes guiding won where that roulette saves most of the
/// shadow rays (the backlit clouds: 1.15-1.27x the efficiency, guided renders tracing 0.28-0.54x the shadow rays)
/// and not elsewhere, where the pilot's albedo and depth are the same (docs/performance.md, "Where guiding
/// pays"), so `auto` guides a render of `spp` samples per pixel when the predicted fraction of the shadow rays
/// traced, 1 − (medium_shadow_rays − medium_traced) / shadow_rays, is at most [`AUTO_MAX_SHADOW_TRACED`] and
/// `spp` is at least [`AUTO_MIN_SPP`].
pub fn decide_from_shadow_pilot(
    spp: u32,
    shadow_rays: u64,
    medium_shadow_rays: u64,
    medium_traced: f64,
) -> GuidingDecision {
    let saved = (medium_shadow_rays as f64 - medium_traced).max(0.0);
    let traced = if shadow_rays == 0 {
        1.0
    } else {
        (1.0 - saved / shadow_rays as f64).clamp(0.0, 1.0)
    };
    let on = traced <= AUTO_MAX_SHADOW_TRACED && spp >= AUTO_MIN_SPP;
    let few_samples = if spp < AUTO_MIN_SPP {
        format!("; {spp} samples per pixel, fewer than {AUTO_MIN_SPP}")
    } else {
        String::new()
    };
    GuidingDecision {
        on,
        provisional: false,
        reason: format!(
            "{} (auto): on a pilot of unguided paths guided shadow roulette would trace {:.2} of the \
             shadow rays ({} of {} from medium scattering events; guided at most {AUTO_MAX_SHADOW_TRACED}){}",
            if on { "on" } else { "off" },
            traced,
            medium_shadow_rays,
            shadow_rays,
            few_samples,
        ),
    }
}

/// What the pilot measured of one medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumPilot {
    /// Mean single-scattering albedo (luminance) at the chords' real collisions (0 without any).
    pub albedo: f32,
    /// Median optical depth along the chords.
    pub depth: f32,
}

impl GuidingMode {
    /// What this mode decides for `scene`, and why, in words (for `--explain`).
    pub fn explain(self, scene: &Scene) -> String {
        self.decide(scene).reason
    }

    internal! {
        /// What this mode decides for `scene`.
        pub fn decide(self, scene: &Scene) -> GuidingDecision {
            match self {
                GuidingMode::Off => GuidingDecision {
                    on: false,
                    provisional: false,
                    reason: "off (--guiding off)".into(),
                },
                GuidingMode::On => GuidingDecision {
                    on: true,
                    provisional: false,
                    reason: "on (--guiding on)".into(),
                },
                GuidingMode::Auto => auto_decision(scene),
            }
        }
    }
}

/// The auto rule of the module documentation.
fn auto_decision(scene: &Scene) -> GuidingDecision {
    let mut best: Option<(String, MediumPilot)> = None;
    for (index, medium) in scene.media.iter().enumerate() {
        if medium.is_absorbing_only() {
            continue;
        }
        let Some(bounds) = medium_bounds(scene, index) else {
            continue;
        };
        let pilot = measure(medium.as_ref(), &bounds);
        if best
            .as_ref()
            .is_none_or(|(_, b)| pilot.depth * pilot.albedo > b.depth * b.albedo)
        {
            best = Some((medium.name().to_owned(), pilot));
        }
    }
    let Some((name, pilot)) = best else {
        return GuidingDecision {
            on: false,
            provisional: false,
            reason: "off (auto): no scattering medium to guide in".to_owned(),
        };
    };
    GuidingDecision {
        on: true,
        provisional: true,
        reason: format!(
            "decided by a pilot of unguided paths before the training (auto): guided if guided shadow roulette would trace \
             at most {AUTO_MAX_SHADOW_TRACED} of its shadow rays and the render has at least {AUTO_MIN_SPP} \
             samples per pixel; the likeliest medium to pay, '{name}', has \
             albedo {:.3} and median optical depth {:.1}",
            pilot.albedo, pilot.depth
        ),
    }
}

/// The box a medium fills: its own for a position-filled volume, else that of the meshes whose material has it
/// as interior.
fn medium_bounds(scene: &Scene, index: usize) -> Option<Aabb> {
    if let Some(b) = scene.media[index].fill_bounds() {
        return Some(b);
    }
    let mut bounds: Option<Aabb> = None;
    for mesh in &scene.meshes {
        if scene.materials[mesh.material as usize].interior != Some(index as u32) {
            continue;
        }
        for &p in &mesh.positions {
            bounds = Some(bounds.map_or(Aabb::new(p, p), |b| b.extend(p)));
        }
    }
    bounds.filter(|b| !b.is_empty())
}

/// Measures `medium` along [`PILOT_CHORDS`] chords through the centre of `bounds` (Fibonacci-sphere
/// directions), from fixed seeds.
pub fn measure(medium: &dyn Medium, bounds: &Aabb) -> MediumPilot {
    let centre = bounds.center();
    let reach = bounds.extent().length() * 0.5 + 1e-3;
    let mut rng = Rng::new(0x6775_6964_696e_6700, 7);
    let mut counters = TrackingCounters::default();
    let mut emission = TentativeEmission::default();
    let mut depths = Vec::with_capacity(PILOT_CHORDS);
    let (mut albedo_sum, mut collisions) = (0.0f32, 0u32);
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    for k in 0..PILOT_CHORDS {
        let z = 1.0 - (2.0 * k as f32 + 1.0) / PILOT_CHORDS as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = golden * k as f32;
        let dir = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        let start = centre - dir * reach;
        // Real collisions along a straight chord form a Poisson process of rate σ_t: their expected count,
        // restarting the free flight at each one without turning, is the chord's optical depth.
        let (mut travelled, mut count) = (0.0f32, 0u32);
        while count < MAX_PILOT_COLLISIONS {
            let ray = Ray::new(start + dir * travelled, dir);
            emission.clear();
            let flight = medium.free_flight(
                &ray,
                2.0 * reach - travelled,
                Vec3::ONE,
                &mut rng,
                &mut counters,
                &mut emission,
            );
            let Some(t) = flight.collision else { break };
            if count == 0 {
                albedo_sum += luminance(medium.collision(ray.at(t), 0.0).albedo);
                collisions += 1;
            }
            count += 1;
            travelled += t.max(1e-6);
        }
        depths.push(count as f32);
    }
    depths.sort_by(f32::total_cmp);
    MediumPilot {
        albedo: if collisions > 0 {
            albedo_sum / collisions as f32
        } else {
            0.0
        },
        depth: depths[PILOT_CHORDS / 2],
    }
}
