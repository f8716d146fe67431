//! The progressive renderer: passes of samples over the whole image in parallel (rayon), until the sample
//! count is reached, the time budget is spent, or the caller cancels.
//!
//! Determinism: sample `s` of pixel `i` draws its random numbers from `Rng::for_sample(seed, i, s)` and the
//! film sums samples exactly (in fixed point, see [`super::exact`]), so the same seed gives the same image, bit
//! for bit, for any thread count, and any split of the render into sample ranges and windows
//! ([`Renderer::render_region`]) adds up to the bits of the whole.

use super::aovs::{AovSelection, LayerPlan, LightGroupMode, LightGroups, PlanError};
use super::emitter_edges::{EmitterEdgeSampling, EmitterEdges, EDGE_RAYS};
use super::film::{Film, FilmPixel, FilmRow, PixelSums, PixelWindow};
use super::guiding::{PilotRow, TrainingRow};
use super::recording::LayerRecorder;
use super::resume::{RegionProgress, ResumeFrom, StoppedPass};
use super::{CancelToken, RenderImage};
use crate::guiding::{GuidePath, GuidingDecision, GuidingField, GuidingMode};
use crate::integrator::{
    FirstEmission, MediumStack, Origin, PathContext, PathCounters, PathSample, PathTracer,
    RayCounters, RendererServices, SampleRecord,
};
use crate::light::LightSamplerChoice;
use crate::math::{is_finite_rgb, Ray, Rgb, Rng, Vec2};
use crate::scene::Scene;
use crate::volume::{MediumMethod, TrackingCounters};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// Mixed into the seed of the stream that draws each camera ray's shutter time, so that it is independent of
/// the path's own stream (the first 64 bits of π's fraction).
const SHUTTER_STREAM: u64 = 0x243f_6a88_85a3_08d3;
/// Mixed into the seed of the stream that places the camera rays of emitter-edge supersampling (the next 64
/// bits of π's fraction).
const EDGE_STREAM: u64 = 0x1319_8a2e_0370_7344;

/// Where a path's key random decisions come from: the pixel position, the light choice and light sample, and
/// BSDF and phase sampling. Tracking, Russian roulette and the rest always use the sample's PCG32 stream.
/// It is the `--sampler` value, by its [`Choice`](crate::params::Choice) name.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Sampler {
    /// Owen-scrambled, shuffled 2-D Sobol points per dimension pair (`nimbus::math::sobol`): stratified within
    /// each pixel, so the error falls faster than 1/√N where the integrand allows.
    #[default]
    Sobol,
    /// Independent uniform values from PCG32.
    Independent,
}

impl crate::params::Choice for Sampler {
    const CHOICES: &'static [(&'static str, Self)] =
        &[("sobol", Self::Sobol), ("independent", Self::Independent)];
}

/// How to render.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Samples per pixel to reach (the render may stop earlier under a time limit).
    pub spp: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Worker threads; 0 uses every core. More than [`crate::limits::max_threads`] are capped there.
    pub threads: usize,
    /// Maximum scattering events per path.
    pub max_depth: u32,
    /// Wall-clock budget; rendering stops after the pass during which it runs out.
    pub time_limit: Option<Duration>,
    /// Multiple importance sampling at medium scattering events (off: emitters are reached from inside media by light sampling alone).
    pub media_mis: bool,
    /// Equiangular sampling toward point and spot lights on segments through constant media, MIS'd with
    /// distance sampling (Kulla & Fajardo 2012); off: distance sampling alone.
    pub equiangular: bool,
    /// Decoupled direct light on segments through constant (homogeneous) scattering media: each segment
    /// estimates the direct light of the lights equiangular sampling does not serve (all but point and spot
    /// lights when it is on) at a distance drawn from the free-flight density truncated to it, in place of the
    /// estimate at the free-flight collision (Novák et al. 2018, §5); off: only at collisions.
    pub decoupled: bool,
    /// Where the path's key random decisions come from.
    pub sampler: Sampler,
    /// How next-event estimation chooses a light: by power, through the light BVH, or per scene (auto).
    pub light_sampler: LightSamplerChoice,
    /// Whether pixels that an emitter's outline crosses estimate the directly visible emission from more
    /// camera rays (`super::EmitterEdges`).
    pub emitter_edges: EmitterEdgeSampling,
    /// The memory budget: a film larger than it is refused before it is allocated.
    pub limits: crate::limits::Limits,
    /// The layers written beyond the beauty and alpha; `None`: the scene's defaults
    /// ([`AovSelection::for_scene`]).
    pub aovs: Option<AovSelection>,
    /// A transparent film: the environment seen directly is left out of the beauty (the `environment` layer
    /// holds it). A scene can also ask for one ([`Scene::transparent`]).
    pub transparent: bool,
    /// How emitters are put in light groups.
    pub light_groups: LightGroupMode,
    /// Cryptomatte ranks per pixel (1 to [`super::cryptomatte::MAX_DEPTH`], rounded up to even).
    pub cryptomatte_depth: usize,
    /// Deep output ([`super::deep`]): the most deep samples per pixel (`--deep-samples`), or `None` for none.
    /// It changes no estimate: the flat image is the same with it or without.
    pub deep_samples: Option<usize>,
    /// Path guiding in media (`--guiding`): a cache of incident light trained before the image's samples, from
    /// which paths sample directions at medium scattering events. It changes the noise, never the mean.
    pub guiding: GuidingMode,
    /// Where paths are guided, guided Russian roulette and splitting at medium scattering events (default off:
    /// measured to lose against classic roulette so far; `--guided-roulette`; `crate::guiding::adjoint`). It
    /// changes the noise, never the mean.
    pub guided_roulette: bool,
}

/// The image width of a render when none is given (`nimbus render` and the Python module).
pub const DEFAULT_WIDTH: usize = 640;

/// The most scattering events per path when neither the caller nor the scene sets them.
pub const DEFAULT_MAX_DEPTH: u32 = 64;

impl RenderSettings {
    /// The image size of a render of `scene`, as `nimbus render` and the Python module choose it: `width`, else
    /// [`DEFAULT_WIDTH`]; `height`, else the width over the camera's aspect ratio (4:3 for a camera without
    /// one), rounded, at least 1.
    pub fn frame_size(
        scene: &Scene,
        width: Option<usize>,
        height: Option<usize>,
    ) -> (usize, usize) {
        let width = width.unwrap_or(DEFAULT_WIDTH);
        let aspect = scene.camera().aspect_ratio.unwrap_or(4.0 / 3.0);
        let height = height
            .unwrap_or(((width as f32 / aspect).round() as usize).max(1))
            .max(1);
        (width, height)
    }

    /// The maximum scattering events of a render of `scene`: `max_depth`, else the scene's own
    /// ([`Scene::max_bounces`]), else [`DEFAULT_MAX_DEPTH`].
    pub fn max_depth_for(scene: &Scene, max_depth: Option<u32>) -> u32 {
        max_depth
            .or(scene.max_bounces())
            .unwrap_or(DEFAULT_MAX_DEPTH)
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: DEFAULT_WIDTH,
            height: 480,
            spp: 64,
            seed: 0,
            threads: 0,
            max_depth: DEFAULT_MAX_DEPTH,
            time_limit: None,
            media_mis: true,
            equiangular: true,
            decoupled: true,
            sampler: Sampler::Sobol,
            light_sampler: LightSamplerChoice::Auto,
            emitter_edges: EmitterEdgeSampling::Auto,
            limits: crate::limits::Limits::default(),
            aovs: None,
            transparent: false,
            light_groups: LightGroupMode::Scene,
            cryptomatte_depth: super::cryptomatte::DEFAULT_DEPTH,
            deep_samples: None,
            guiding: GuidingMode::Auto,
            guided_roulette: false,
        }
    }
}

/// Progress reported after every pass.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Samples per pixel completed so far.
    pub samples_done: u32,
    /// Samples per pixel aimed for.
    pub samples_target: u32,
    /// Seconds since the render started.
    pub elapsed_seconds: f64,
    /// Fraction of the work or of the time budget done, in \[0, 1\].
    pub fraction: f64,
    /// Samples dropped as NaN or infinite so far (with those of the checkpoint a render resumed from).
    pub nan_samples: u64,
    /// Samples clamped so far (with those of the checkpoint a render resumed from).
    pub clamped_samples: u64,
}

/// What a render did, as written by `--stats`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    /// Samples per pixel actually taken.
    pub samples_per_pixel: u32,
    /// Wall-clock seconds spent rendering (scene loading excluded).
    pub render_seconds: f64,
    /// Seconds from the start of the render (as `render_seconds`: the scene loaded, guiding training included)
    /// until the first pixel held the samples of the first pass, the first pixel of the first progressive
    /// image; `None` when no pixel was rendered (cancelled before).
    pub first_pixel_seconds: Option<f64>,
    /// Rays traced, by kind.
    pub rays: RayCounters,
    /// Samples dropped because their radiance was NaN or infinite (never written to the film).
    pub nan_samples: u64,
    /// Samples with a value (radiance or AOV) beyond ±2^38 ≈ ±2.7e11, or a NaN or infinite AOV, clamped into
    /// the range of the film's exact sums (see `MAX_SAMPLE_VALUE`).
    pub clamped_samples: u64,
    /// Peak resident memory of the process, when the platform reports it.
    pub peak_memory_bytes: Option<u64>,
    /// Image width.
    pub width: usize,
    /// Image height.
    pub height: usize,
    /// Worker threads used.
    pub threads: usize,
    /// The seed.
    pub seed: u64,
    /// Maximum scattering events per path.
    pub max_depth: u32,
    /// Samples per second over the whole image.
    pub samples_per_second: f64,
    /// True when the caller cancelled the render.
    pub cancelled: bool,
    /// True when the image written is of a render stopped before its samples were taken (the CLI, stopped by
    /// SIGTERM or SIGINT without `--checkpoint`); pixels then hold `samples_per_pixel` samples or one pass more.
    pub partial: bool,
    /// The signal that stopped the render (`SIGTERM`, `SIGINT`), if one did.
    pub interrupted_by: Option<String>,
    /// Samples per pixel a resumed render found in its checkpoint (counted in `samples_per_pixel`); 0 when it
    /// did not resume.
    pub resumed_samples: u32,
    /// The motion-blur shutter (open, close), in frames relative to the frame; `None` for an instant.
    pub shutter: Option<[f32; 2]>,
    /// Triangles that move over the shutter (kept at every motion step).
    pub moving_triangles: usize,
    /// Whether the camera moves over the shutter.
    pub camera_moves: bool,
    /// Per-medium tracking work and the method chosen.
    pub media: Vec<MediumStats>,
    /// Pixels whose directly visible emission was supersampled because an emitter's outline crosses them (0
    /// when emitter-edge supersampling is off).
    pub emitter_edge_pixels: usize,
    /// Whether the film was transparent (the environment seen directly left out of the beauty).
    pub transparent: bool,
    /// The layers written after the beauty and alpha (first-hit layers, light paths, colours, light groups,
    /// `shadow_catcher`, Cryptomatte kinds), as named by `--aovs`.
    pub layers: Vec<String>,
    /// The light groups' layer names (`lg_<group>`), whether written or not.
    pub light_groups: Vec<String>,
    /// Path guiding: whether it was on, why, and what its training did.
    pub guiding: GuidingStats,
}

/// What path guiding did, as written by `--stats` under `guiding`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GuidingStats {
    /// `on` or `off`: whether paths were guided.
    pub mode: String,
    /// Why (what `--explain` prints).
    pub reason: String,
    /// Samples per pixel of the whole frame the training took (0 when off).
    pub training_samples_per_pixel: u32,
    /// Samples per pixel of the image that are the training's (counted in `samples_per_pixel`): its samples in
    /// the render's sample range, 7 of a whole render of 7 samples or more, none in a part whose range starts at
    /// 7 or later (see `--spp` in docs/reference.md).
    pub training_samples_in_image: u32,
    /// Samples per pixel of the image that are `auto`'s pilot's (counted in `samples_per_pixel`, and in
    /// `training_samples_in_image` when it guides): 1 where the pilot is the training's first iteration (a whole
    /// frame, or any frame below about 256²) and the render's sample range starts at 0, else 0.
    pub pilot_samples_in_image: u32,
    /// Training paths traced, each once: `auto`'s pilot's included (where the pilot is the training's first
    /// iteration, its paths are that iteration's).
    pub training_paths: u64,
    /// Radiance records the cache learned from (one per medium scattering event of a training path).
    pub training_records: u64,
    /// Cells of the cache's spatial tree.
    pub cells: usize,
    /// Cells with a learned distribution (the others sample the phase function alone).
    pub guided_cells: usize,
    /// Wall-clock seconds of the training (counted in `render_seconds`).
    pub training_seconds: f64,
}

/// Statistics of one medium, as written by `--stats` under `media`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MediumStats {
    /// The glTF node or material that declared it.
    pub name: String,
    /// The estimator chosen for it, in words (`MediumMethod`'s `Display`).
    pub method: String,
    /// The same, as data: its `--stats` keys (`free_flight`, `channel_choice`, `closed_form_segments`,
    /// `majorant`, `shadow_estimator`, `method_reason`, `majorant_pilot`) sit flat beside `method`.
    #[cfg(feature = "testing")]
    #[serde(flatten)]
    pub method_details: MediumMethod,
    /// The same, as data (internal without the `testing` feature: `method` says it in words).
    #[cfg(not(feature = "testing"))]
    #[serde(flatten)]
    pub(crate) method_details: MediumMethod,
    /// Bytes held by the medium (grids, majorants).
    pub memory_bytes: usize,
    /// Tracking counters (`density_lookups`, `real_collisions`, `null_collisions`, `majorant_segments`,
    /// `majorant_violations`).
    #[serde(flatten)]
    pub counters: TrackingCounters,
}

/// A part of a render: a window of the frame and a range of every pixel's sample sequence. Parts that cover
/// the frame and the samples `0..spp` once each merge into the render of the whole, bit for bit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderRegion {
    /// The pixels to render.
    pub window: PixelWindow,
    /// The samples of each pixel to take: sample `s` of pixel `i` is the same in every region.
    pub samples: Range<u32>,
}

/// Why [`Renderer::render_region`] cannot render a region.
#[derive(Debug, thiserror::Error)]
pub enum RegionError {
    /// The window is empty or does not fit the frame.
    #[error("crop {window} is empty or does not fit the {width}x{height} frame")]
    Window {
        /// The window asked for.
        window: PixelWindow,
        /// Frame width.
        width: usize,
        /// Frame height.
        height: usize,
    },
    /// The sample range is empty.
    #[error("sample range {start}..{end} is empty")]
    Samples {
        /// First sample.
        start: u32,
        /// One past the last sample.
        end: u32,
    },
    /// The render could not start.
    #[error(transparent)]
    Render(#[from] RenderError),
}

impl From<PlanError> for RegionError {
    fn from(e: PlanError) -> Self {
        RegionError::Render(RenderError::Layers(e))
    }
}

/// Why a render could not start.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The worker thread pool could not be started.
    #[error("cannot start render worker threads: {0}")]
    ThreadPool(#[from] rayon::ThreadPoolBuildError),
    /// The film (and the image made from it) would exceed the memory budget.
    #[error(transparent)]
    OverBudget(#[from] crate::limits::OverBudget),
    /// The layers asked for cannot be made (an unknown light group, too many groups).
    #[error(transparent)]
    Layers(#[from] PlanError),
    /// The film to resume from is not one of this render's region (another window, other layers, or a progress
    /// that does not fit it).
    #[error("cannot resume: {0}")]
    Resume(String),
}

/// Renders scenes with fixed settings.
pub struct Renderer {
    settings: RenderSettings,
}

impl Renderer {
    /// A renderer with `settings`.
    pub fn new(settings: RenderSettings) -> Self {
        Self { settings }
    }

    /// The settings.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Whether a render of `scene` has a transparent film: the settings or the scene ask for one.
    pub fn transparent(&self, scene: &Scene) -> bool {
        self.settings.transparent || scene.transparent()
    }

    /// The light groups of a render of `scene`.
    pub fn light_groups(&self, scene: &Scene) -> Result<LightGroups, PlanError> {
        Ok(LightGroups::new(scene, self.settings.light_groups)?)
    }

    /// What a render of `scene` accumulates and writes beyond the beauty, alpha and first-hit sums.
    pub fn layer_plan(&self, scene: &Scene) -> Result<LayerPlan, PlanError> {
        let groups = self.light_groups(scene)?;
        let selection = match &self.settings.aovs {
            Some(s) => s.clone(),
            None => AovSelection::for_scene(scene, self.transparent(scene), &groups),
        };
        LayerPlan::new(scene, &selection, &groups, self.settings.cryptomatte_depth)
    }

    /// Renders `scene`. `progress` is called after every pass; returning `false` cancels the render, which
    /// then returns what it has.
    pub fn render(
        &self,
        scene: &Scene,
        progress: &mut dyn FnMut(&Progress) -> bool,
    ) -> Result<(RenderImage, RenderStats), RenderError> {
        self.render_with_cancel(scene, progress, &CancelToken::new())
    }

    /// Renders `scene` like [`render`](Self::render), and also stops when `cancel` is cancelled: the token is
    /// checked between passes and before every pixel. A cancelled render returns what it has, with
    /// `stats.cancelled` set and `stats.samples_per_pixel` counting the passes that completed.
    pub fn render_with_cancel(
        &self,
        scene: &Scene,
        progress: &mut dyn FnMut(&Progress) -> bool,
        cancel: &CancelToken,
    ) -> Result<(RenderImage, RenderStats), RenderError> {
        let (film, stats, _) = self.run(
            scene,
            &self.whole(),
            None,
            &mut |p, _| progress(p),
            cancel,
            false,
        )?;
        Ok((film.image(), stats))
    }

    /// Renders one region of the frame (a crop and a sample range; `settings.spp` is not used) and returns its
    /// film, whose exact sums [`Film::merge`] adds to the films of other regions. Under a time limit the
    /// samples taken are `samples.start..samples.start + stats.samples_per_pixel`. A cancelled render returns
    /// what it has, like [`render_with_cancel`](Self::render_with_cancel): pixels may then hold different
    /// sample counts, so its film is no part of a whole.
    pub fn render_region(
        &self,
        scene: &Scene,
        region: &RenderRegion,
        progress: &mut dyn FnMut(&Progress) -> bool,
        cancel: &CancelToken,
    ) -> Result<(Film, RenderStats), RegionError> {
        let (film, stats, _) =
            self.render_resumable(scene, region, None, &mut |p, _| progress(p), cancel)?;
        Ok((film, stats))
    }

    /// Renders `region` like [`render_region`](Self::render_region), continuing from `from` (the film and
    /// progress of a checkpoint of the same render) when given, and returns how far the film got besides:
    /// a render stopped by `cancel` or by `progress` (which also sees the film after every pass, where every
    /// pixel holds the samples up to `Progress::samples_done`) can be continued from that film and progress,
    /// and the continued render's film is the uninterrupted one, bit for bit (see [`super::resume`]). The
    /// stats count the samples of `from` in `samples_per_pixel`, `nan_samples` and `clamped_samples`.
    pub fn render_resumable(
        &self,
        scene: &Scene,
        region: &RenderRegion,
        from: Option<ResumeFrom>,
        progress: &mut dyn FnMut(&Progress, &Film) -> bool,
        cancel: &CancelToken,
    ) -> Result<(Film, RenderStats, RegionProgress), RegionError> {
        let (width, height) = (self.settings.width, self.settings.height);
        if region.window.is_empty() || !region.window.fits(width, height) {
            return Err(RegionError::Window {
                window: region.window,
                width,
                height,
            });
        }
        if region.samples.is_empty() {
            return Err(RegionError::Samples {
                start: region.samples.start,
                end: region.samples.end,
            });
        }
        Ok(self.run(scene, region, from, progress, cancel, false)?)
    }

    /// The whole frame and the samples `0..spp` (at least one).
    fn whole(&self) -> RenderRegion {
        RenderRegion {
            window: PixelWindow::full(self.settings.width, self.settings.height),
            samples: 0..self.settings.spp.max(1),
        }
    }

    /// Renders `scene` in passes that double the sample count (1, 2, 4, 8, … spp, capped by `spp` and any time
    /// limit) and shows `snapshot` the film after each, for convergence measurements. Time spent in `snapshot`
    /// counts in later `elapsed_seconds`. Returning `false` stops the render.
    pub fn render_with_snapshots(
        &self,
        scene: &Scene,
        snapshot: &mut dyn FnMut(&Progress, &Film) -> bool,
    ) -> Result<(RenderImage, RenderStats), RenderError> {
        let (film, stats, _) = self.run(
            scene,
            &self.whole(),
            None,
            snapshot,
            &CancelToken::new(),
            true,
        )?;
        Ok((film.image(), stats))
    }

    /// The pass loop over `region` (valid), from `from` when given; `doubling` makes every pass as large as
    /// all the previous ones together.
    fn run(
        &self,
        scene: &Scene,
        region: &RenderRegion,
        from: Option<ResumeFrom>,
        progress: &mut dyn FnMut(&Progress, &Film) -> bool,
        cancel: &CancelToken,
        doubling: bool,
    ) -> Result<(Film, RenderStats, RegionProgress), RenderError> {
        let s = &self.settings;
        let groups = self.light_groups(scene)?;
        let plan = Arc::new(self.layer_plan(scene)?);
        let recorder = LayerRecorder::new(scene, &plan, &groups);
        self.check_film_memory(&plan, region)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(s.threads.min(crate::limits::max_threads()))
            .build()?;
        let threads = pool.current_num_threads();
        let start = Instant::now();
        let (mut film, at, nan_samples, clamped_samples) = self.first_film(from, region, &plan)?;
        let edges = s.emitter_edges.decide(scene, s.width, s.height);
        let tracer = self.path_tracer(scene);
        let resumed_samples = at.complete - region.samples.start;
        let mut totals = PassTotals {
            counters: PathCounters::new(scene.media.len()),
            nan_samples,
            clamped_samples,
            done: resumed_samples,
            cancelled: false,
        };
        let clock = FirstPixelClock {
            start,
            seconds: OnceLock::new(),
        };
        let passes = Passes {
            clock: &clock,
            renderer: self,
            scene,
            tracer,
            region,
            recorder: &recorder,
            edges: edges.edges(),
            guide: None,
            pool: &pool,
            cancel,
            doubling,
            start,
        };
        // The guiding cache, trained over the whole frame whatever the region; its samples in the region are the
        // film's first (see `super::guiding`).
        let decision = s.guiding.decide(scene);
        let keep = if decision.on {
            super::guiding::kept_samples(&region.samples, at.complete)
        } else {
            0..0
        };
        // A film stopped inside the training cannot go on guided (its cache would guide the training's samples
        // still to come differently); `auto` knows whether it guides only after its pilot.
        let inside_training = !keep.is_empty() && at.complete != region.samples.start;
        let refusal = || {
            RenderError::Resume(format!(
                "the film holds samples {}..{}, inside the guiding training's first {}",
                region.samples.start,
                at.complete,
                super::guiding::TRAINING_SAMPLES
            ))
        };
        if inside_training && !decision.provisional {
            return Err(refusal());
        }
        let training = pool.install(|| passes.train(&mut film, keep.clone(), decision));
        if inside_training && training.field.is_some() {
            return Err(refusal());
        }
        totals.counters.add(&training.counters);
        let mut at = at;
        // The training's samples in the film, or those of `auto`'s pilot that decided not to guide (then the
        // render goes on unguided after them).
        if !training.in_film.is_empty() {
            at = RegionProgress::start(training.in_film.end);
            totals.done = at.complete - region.samples.start;
            totals.nan_samples += training.nan_samples;
            totals.clamped_samples += training.clamped_samples;
            clock.pixel_done();
            if training.decided_off {
                // The pilot's sample 0 is reported as a pass is, so that progressive consumers see the film
                // after it (`converge`'s rows at 1, 2, 4, ... samples: an `off` render's first pass of one).
                let report = passes.report(&totals, region.samples.len() as u32, start.elapsed());
                totals.cancelled = !progress(&report, &film);
            }
        } else if !keep.is_empty() && !training.decided_off && training.field.is_none() {
            // Cancelled part way: the film, empty before, holds no whole sample of any pixel.
            film = self.first_film(None, region, &plan)?.0;
        }
        let guiding = training.stats;
        let passes = Passes {
            guide: training.field.as_ref(),
            ..passes
        };
        let at = if totals.cancelled {
            at
        } else {
            passes.run(&mut film, at, &mut totals, progress)
        };
        totals.cancelled |= cancel.is_cancelled();
        let seconds = start.elapsed().as_secs_f64();
        let stats = RenderStats {
            threads,
            resumed_samples,
            emitter_edge_pixels: edges.edges().map_or(0, EmitterEdges::count),
            transparent: self.transparent(scene),
            layers: plan.written.clone(),
            light_groups: groups.names,
            guiding,
            first_pixel_seconds: clock.seconds.get().copied(),
            ..self.pass_stats(scene, region, totals, seconds)
        };
        Ok((film, stats, at))
    }

    /// Refuses a film of `region`'s window whose memory, at what `plan` keeps per pixel, would pass the limits.
    fn check_film_memory(
        &self,
        plan: &LayerPlan,
        region: &RenderRegion,
    ) -> Result<(), RenderError> {
        // Per pixel: the film's exact sums, then the f32 channels of the image made from them.
        let pixel_bytes = std::mem::size_of::<PixelSums>()
            + 4 * super::channels::channel_names().len()
            + plan.film_bytes_per_pixel()
            + 4 * (plan.values_per_pixel() + 2 * plan.cryptomatte_depth * plan.cryptomatte.len())
            // Deep bins grow with the depths a pixel's paths reach; counted here at one per pixel.
            + self.settings.deep_samples.map_or(0, |_| 128);
        let (w, h) = (region.window.width() as u64, region.window.height() as u64);
        self.settings.limits.check_items(
            format_args!("the film of {w}x{h} pixels"),
            w.saturating_mul(h),
            pixel_bytes as u64,
        )?;
        Ok(())
    }

    /// The film a render starts from, with its progress and its dropped and clamped sample counts: `from`'s
    /// (checked to fit the region and the plan), or an empty one.
    fn first_film(
        &self,
        from: Option<ResumeFrom>,
        region: &RenderRegion,
        plan: &Arc<LayerPlan>,
    ) -> Result<(Film, RegionProgress, u64, u64), RenderError> {
        let s = &self.settings;
        match from {
            Some(from) => {
                check_resume(&from, region, plan)?;
                if from.film.deep_samples() != s.deep_samples {
                    return Err(RenderError::Resume(
                        "the film to resume from has other deep output settings".into(),
                    ));
                }
                Ok((
                    from.film,
                    from.progress,
                    from.nan_samples,
                    from.clamped_samples,
                ))
            }
            None => {
                let mut film = Film::with_plan(s.width, s.height, region.window, plan.clone());
                if let Some(max) = s.deep_samples {
                    film.enable_deep(max);
                }
                Ok((film, RegionProgress::start(region.samples.start), 0, 0))
            }
        }
    }

    /// The statistics that the passes' `totals` over `region` and the scene give, after `seconds` of rendering
    /// (the rest of the fields at their defaults).
    fn pass_stats(
        &self,
        scene: &Scene,
        region: &RenderRegion,
        totals: PassTotals,
        seconds: f64,
    ) -> RenderStats {
        let s = &self.settings;
        let done = totals.done;
        RenderStats {
            samples_per_pixel: done,
            render_seconds: seconds,
            rays: totals.counters.rays,
            nan_samples: totals.nan_samples,
            clamped_samples: totals.clamped_samples,
            peak_memory_bytes: peak_memory_bytes(),
            width: s.width,
            height: s.height,
            seed: s.seed,
            max_depth: s.max_depth,
            samples_per_second: (done as f64 * region.window.pixel_count() as f64)
                / seconds.max(1e-9),
            cancelled: totals.cancelled,
            partial: false,
            interrupted_by: None,
            shutter: scene.shutter.map(|s| [s.open, s.close]),
            moving_triangles: scene.moving_triangle_count(),
            camera_moves: scene.camera.motion.is_some(),
            media: scene
                .media
                .iter()
                .zip(&totals.counters.media)
                .map(|(m, c)| {
                    let method = m.method();
                    MediumStats {
                        name: m.name().to_owned(),
                        method: method.to_string(),
                        method_details: method,
                        memory_bytes: m.memory_bytes(),
                        counters: *c,
                    }
                })
                .collect(),
            ..RenderStats::default()
        }
    }
}

/// What every pixel of one pass shares: the scene and how it is traced, where the samples go, and which samples
/// they are.
#[derive(Clone)]
pub(super) struct Pass<'a> {
    pub(super) scene: &'a Scene,
    pub(super) settings: &'a RenderSettings,
    pub(super) tracer: PathTracer,
    pub(super) services: RendererServices<'a>,
    recorder: &'a LayerRecorder,
    /// The pixels that supersample their directly visible emission.
    edges: Option<&'a EmitterEdges>,
    /// The whole frame's size (the window is a part of it).
    pub(super) width: usize,
    pub(super) height: usize,
    /// The film's window.
    pub(super) window: PixelWindow,
    /// Whether samples are recorded for layers (AOVs or deep output).
    records: bool,
    /// Whether the records carry the shadow catcher's lit estimate.
    shadow_catcher: bool,
    /// Whether the records carry deep bins.
    deep: bool,
    /// The most deep bins a pixel keeps.
    max_bins: usize,
    /// The sample indices the pass adds to every pixel.
    pub(super) samples: Range<u32>,
    pub(super) cancel: &'a CancelToken,
    /// Notes when the first pixel is done.
    clock: &'a FirstPixelClock,
}

/// When the first pixel of a render held its first pass's samples.
struct FirstPixelClock {
    /// When the render started.
    start: Instant,
    /// Seconds from `start` to the first pixel done, once one is.
    seconds: OnceLock<f64>,
}

impl FirstPixelClock {
    /// Notes that a pixel is done (only the first note counts).
    fn pixel_done(&self) {
        if self.seconds.get().is_none() {
            let _ = self.seconds.set(self.start.elapsed().as_secs_f64());
        }
    }
}

impl<'a> Pass<'a> {
    /// Adds the pass's samples to the pixels of window row `row_index` from column `first_column` on, stopping
    /// before the next pixel once cancelled. Returns the counters, the dropped NaN samples, the clamped samples,
    /// and how many pixels of the row, from the left, hold the samples.
    fn render_row(
        &self,
        row_index: usize,
        row: FilmRow<'_>,
        first_column: usize,
    ) -> (PathCounters, u64, u64, u32) {
        let y = self.window.y0 + row_index;
        let mut counters = PathCounters::new(self.scene.media.len());
        let (mut nans, mut clamped) = (0u64, 0u64);
        let mut record = self.records.then(|| SampleRecord {
            shadow_catcher: self.shadow_catcher,
            deep: self.deep,
            ..SampleRecord::default()
        });
        let mut columns_done = first_column;
        for (column, mut pixel) in row.pixels().enumerate().skip(first_column) {
            let x = self.window.x0 + column;
            if self.cancel.is_cancelled() {
                break;
            }
            columns_done = column + 1;
            let pixel_index = (y * self.width + x) as u64;
            let on_edge = self.edges.is_some_and(|e| e.is_marked(x, y));
            for sample in self.samples.clone() {
                let (ray, time, result, _) = self.trace_sample(
                    (x, y),
                    pixel_index,
                    sample,
                    on_edge,
                    record.as_mut(),
                    &mut counters,
                    None,
                );
                if !is_finite_rgb(result.radiance) {
                    nans += 1;
                    continue;
                }
                clamped += self.splat(&mut pixel, (ray, time), &result, record.as_ref()) as u64;
            }
            self.clock.pixel_done();
        }
        (counters, nans, clamped, columns_done as u32)
    }

    /// The same pass, its paths traced with `services` and adding the samples `samples`.
    pub(super) fn retargeted<'b>(
        &self,
        services: RendererServices<'b>,
        samples: Range<u32>,
    ) -> Pass<'b>
    where
        'a: 'b,
    {
        Pass {
            services,
            samples,
            ..self.clone()
        }
    }

    /// Adds a sample, traced along the camera ray `ray` at shutter time `time`, whose `result` is finite and
    /// whose layers `record` holds (when the film keeps layers) to `pixel`: its sums, its layers and its deep
    /// bins. Returns whether a value had to be clamped.
    fn splat(
        &self,
        pixel: &mut FilmPixel<'_>,
        (ray, time): (Ray, Option<f32>),
        result: &PathSample,
        record: Option<&SampleRecord>,
    ) -> bool {
        let mut clamped = pixel.sums.add(result);
        if let Some(r) = record {
            clamped |= self.recorder.commit(r, result.alpha, pixel);
            if let Some(d) = pixel.deep.as_deref_mut() {
                let cos = ray.dir.normalize_or_zero().dot(self.view_axis(time));
                d.add(r, result.radiance, result.alpha, cos, self.max_bins);
            }
        }
        clamped
    }

    /// Traces the pass's samples (those of a training iteration, guided by the cache of the iteration before)
    /// through every pixel of frame row `y`, the whole frame's width, and returns what the guiding cache learns
    /// from them; those in `keep` of the pixels of the window are added to `film_row` (the window's row
    /// `y`, `None` outside it) as image samples, exactly as [`render_row`](Self::render_row) adds them. With
    /// `keeps_values` (guided Russian roulette), each sample's continuation is kept as its pixel's estimate.
    /// With `pilot_stride`, the row is `auto`'s pilot's: its paths at the pixels of the pilot's lattice (every
    /// `pilot_stride`-th along both axes) also go into the row's [`PilotRow`].
    pub(super) fn train_row(
        &self,
        y: usize,
        x_stride: usize,
        film_row: Option<FilmRow<'_>>,
        keep: &Range<u32>,
        keeps_values: bool,
        pilot_stride: Option<usize>,
    ) -> TrainingRow {
        let mut pixels: Vec<FilmPixel<'_>> =
            film_row.map_or_else(Vec::new, |r| r.pixels().collect());
        let mut row = TrainingRow::new(self.scene.media.len());
        let mut record = self.records.then(|| SampleRecord {
            shadow_catcher: self.shadow_catcher,
            deep: self.deep,
            ..SampleRecord::default()
        });
        let mut path = GuidePath::default();
        let lattice = pilot_stride.filter(|s| y.is_multiple_of(*s));
        row.pilot = lattice.map(|_| PilotRow::default());
        for x in (0..self.width).step_by(x_stride) {
            let pixel_index = (y * self.width + x) as u64;
            let on_edge = self.edges.is_some_and(|e| e.is_marked(x, y));
            let mut pixel = (self.window.x0..self.window.x1)
                .contains(&x)
                .then(|| pixels.get_mut(x - self.window.x0))
                .flatten();
            let on_lattice = lattice.is_some_and(|s| x.is_multiple_of(s));
            for sample in self.samples.clone() {
                let kept = pixel.is_some() && keep.contains(&sample);
                path.clear();
                let shadow_rays = row.counters.rays.shadow;
                let (ray, time, result, gathered) = self.trace_sample(
                    (x, y),
                    pixel_index,
                    sample,
                    on_edge,
                    record.as_mut().filter(|_| kept),
                    &mut row.counters,
                    Some(&mut path),
                );
                row.lit.extend_from_slice(path.lit());
                row.shadow.extend_from_slice(path.shadow());
                row.decoupled_shadow
                    .extend_from_slice(path.decoupled_shadow());
                row.surface_shadow.extend_from_slice(path.surface_shadow());
                if let Some(pilot) = row.pilot.as_mut().filter(|_| on_lattice) {
                    pilot.shadow_rays += row.counters.rays.shadow - shadow_rays;
                    pilot.shadow.extend_from_slice(path.shadow());
                    pilot
                        .decoupled_shadow
                        .extend_from_slice(path.decoupled_shadow());
                }
                if !is_finite_rgb(result.radiance) {
                    row.nan_samples += kept as u64;
                    continue;
                }
                path.finish(gathered, &mut row.records);
                if keeps_values {
                    let continued = path.continuation(gathered);
                    row.values.push(((x, y), continued.element_sum() / 3.0));
                }
                if let (true, Some(pixel)) = (kept, pixel.as_deref_mut()) {
                    let r = record.as_ref();
                    row.clamped_samples += self.splat(pixel, (ray, time), &result, r) as u64;
                }
            }
        }
        row
    }

    /// Traces sample `sample` of the pixel at `(x, y)` (index `pixel_index` in the frame), clearing and filling
    /// `record`, and remembering on `guide_path` (a training sample's) what the guiding cache learns from.
    /// Returns the camera ray, its shutter time, the path's sample, and the radiance the path gathered itself
    /// (the sample's but an emitter-edge pixel's supersampled directly visible emission, which no event of the
    /// path saw).
    #[allow(clippy::too_many_arguments)]
    fn trace_sample(
        &self,
        (x, y): (usize, usize),
        pixel_index: u64,
        sample: u32,
        on_edge: bool,
        mut record: Option<&mut SampleRecord>,
        counters: &mut PathCounters,
        guide_path: Option<&mut GuidePath>,
    ) -> (Ray, Option<f32>, PathSample, Rgb) {
        let s = self.settings;
        // Only guided Russian roulette reads the pixel's training value.
        let services = if self.tracer.guided_roulette {
            let estimate = self.services.guide().and_then(|g| g.pixel_estimate((x, y)));
            self.services.with_pixel_estimate(estimate)
        } else {
            self.services
        };
        let mut rng = self.sample_rng(s.seed, pixel_index, sample as u64);
        // A box shutter: the time is uniform over the interval, drawn from a stream of its own so that the
        // path's numbers are those of a render without a shutter (a still scene renders bit for bit the same
        // with one).
        let time = self.scene.shutter.map(|shutter| {
            let u = Rng::for_sample(s.seed ^ SHUTTER_STREAM, pixel_index, sample as u64).next_f32();
            shutter.time_at(u)
        });
        // A camera with a thin lens takes the sample's next 2-D value for the point on its lens; a pinhole draws
        // none, so its paths keep the numbers they had before lenses existed.
        let has_lens = self.scene.camera.lens.is_some();
        let jitter = rng.sample_2d();
        let lens = has_lens.then(|| rng.sample_2d());
        let ray = self.camera_ray((x, y), jitter, lens, time);
        if let Some(r) = record.as_deref_mut() {
            r.clear();
        }
        let result = if on_edge {
            // The directly visible emission from EDGE_RAYS positions of their own, the rest of the light from
            // the path (see `super::emitter_edges`).
            let emission = self.edge_emission(
                (x, y),
                pixel_index,
                sample,
                time,
                record.as_deref_mut(),
                counters,
            );
            let mut cx = PathContext {
                services: &services,
                rng: &mut rng,
                counters,
            };
            let mut result =
                self.tracer
                    .trace(&mut cx, ray, FirstEmission::Omit, record, guide_path);
            let gathered = result.radiance;
            result.radiance += emission / EDGE_RAYS as f32;
            (result, gathered)
        } else {
            let mut cx = PathContext {
                services: &services,
                rng: &mut rng,
                counters,
            };
            let result = self
                .tracer
                .trace(&mut cx, ray, FirstEmission::Count, record, guide_path);
            (result, result.radiance)
        };
        (ray, time, result.0, result.1)
    }

    /// The directly visible emission summed over the EDGE_RAYS camera rays of an edge pixel's sample, each
    /// emitter's share pushed onto `record`.
    fn edge_emission(
        &self,
        (x, y): (usize, usize),
        pixel_index: u64,
        sample: u32,
        time: Option<f32>,
        mut record: Option<&mut SampleRecord>,
        counters: &mut PathCounters,
    ) -> Rgb {
        let has_lens = self.scene.camera.lens.is_some();
        let mut emission = Rgb::ZERO;
        for k in 0..EDGE_RAYS {
            let index = sample as u64 * EDGE_RAYS as u64 + k as u64;
            // `EmitterEdgeSampling::decide` keeps edges off for a thin lens; were they on, each edge ray would
            // take its own lens point, as camera rays do.
            let mut edge_rng =
                self.sample_rng(self.settings.seed ^ EDGE_STREAM, pixel_index, index);
            let jitter = edge_rng.sample_2d();
            let r = self.camera_ray((x, y), jitter, has_lens.then(|| edge_rng.sample_2d()), time);
            let (e, emitter) = self
                .tracer
                .first_surface_emission(&self.services, &r, counters);
            emission += e;
            if let (Some(rec), true) = (record.as_deref_mut(), e.max_element() > 0.0) {
                rec.push(e / EDGE_RAYS as f32, Origin::Emitted, emitter, true);
            }
        }
        emission
    }

    /// The random stream of sample `index` of pixel `pixel_index` under `seed`, from the chosen sampler.
    fn sample_rng(&self, seed: u64, pixel_index: u64, index: u64) -> Rng {
        match self.settings.sampler {
            Sampler::Sobol => Rng::for_sample_sobol(seed, pixel_index, index),
            Sampler::Independent => Rng::for_sample(seed, pixel_index, index),
        }
    }

    /// The camera ray through the pixel at `(x, y)`, offset by `jitter` in it (a box filter: uniform jitter,
    /// unweighted mean), through `lens` on a thin lens, at shutter time `time`.
    fn camera_ray(
        &self,
        (x, y): (usize, usize),
        jitter: Vec2,
        lens: Option<Vec2>,
        time: Option<f32>,
    ) -> Ray {
        let film_pos = Vec2::new(
            (x as f32 + jitter.x) / self.width as f32,
            (y as f32 + jitter.y) / self.height as f32,
        );
        let aspect = self.width as f32 / self.height as f32;
        self.scene.camera.sample_ray(film_pos, lens, aspect, time)
    }

    /// The camera's view axis at `time` (a moving camera's at the sample's time): deep depths are a camera
    /// ray's distance times its cosine to it.
    fn view_axis(&self, time: Option<f32>) -> crate::math::Vec3 {
        let camera = &self.scene.camera;
        let to_world = match (&camera.motion, time) {
            (Some(m), Some(t)) => m.camera_to_world_at(t),
            _ => camera.camera_to_world,
        };
        -to_world.z_axis.truncate().normalize_or_zero()
    }
}

/// The running totals of a render's passes.
struct PassTotals {
    counters: PathCounters,
    /// Samples dropped as NaN/Inf.
    nan_samples: u64,
    /// Samples clamped into the film's range.
    clamped_samples: u64,
    /// Samples per pixel done in the region, those resumed from included.
    done: u32,
    /// Whether the progress callback stopped the render.
    cancelled: bool,
}

/// The pass loop of one render: what every pass needs besides the film.
struct Passes<'a> {
    /// Notes when the first pixel is done.
    clock: &'a FirstPixelClock,
    renderer: &'a Renderer,
    scene: &'a Scene,
    /// The render's path tracer, made once ([`Renderer::path_tracer`] walks a ray to find the camera's media).
    tracer: PathTracer,
    region: &'a RenderRegion,
    recorder: &'a LayerRecorder,
    edges: Option<&'a EmitterEdges>,
    guide: Option<&'a GuidingField>,
    pool: &'a rayon::ThreadPool,
    cancel: &'a CancelToken,
    /// Whether every pass is as large as all the previous ones together.
    doubling: bool,
    /// When the render started.
    start: Instant,
}

impl<'a> Passes<'a> {
    /// The pass that adds `samples` to the pixels of `film`'s window, its paths traced with `services`.
    fn pass(&self, film: &Film, samples: Range<u32>, services: RendererServices<'a>) -> Pass<'a> {
        Pass {
            scene: self.scene,
            settings: &self.renderer.settings,
            tracer: self.tracer,
            services,
            recorder: self.recorder,
            edges: self.edges,
            width: film.width,
            height: film.height,
            window: film.window(),
            records: film.plan().records() || film.deep_samples().is_some(),
            shadow_catcher: film.plan().slot(super::aovs::CATCHER_LIT).is_some(),
            deep: film.deep_samples().is_some(),
            max_bins: film.deep_samples().map_or(0, super::deep::max_bins),
            samples,
            cancel: self.cancel,
            clock: self.clock,
        }
    }

    /// Trains the guiding cache that `decision` asks for, adding the training's samples in `keep` to `film`
    /// (empty so far) as image samples (see `super::guiding`).
    fn train(
        &self,
        film: &mut Film,
        keep: Range<u32>,
        decision: GuidingDecision,
    ) -> super::guiding::Training {
        let pass = self.pass(film, keep, self.renderer.services(self.scene));
        super::guiding::train(&pass, film, decision)
    }

    /// Adds `samples` to every pixel of the film's window, but the first `skip[r]` pixels of each window row
    /// `r` (which took them already), stopping each row before its next pixel once the render is cancelled;
    /// pixels that the emitter edges mark supersample their directly visible emission. Returns the counters, the
    /// dropped NaN samples, the clamped samples, and how many pixels of each row, from the left, hold the
    /// samples (the skipped ones included). Paths are guided by the render's cache when it has one.
    fn render_pass(
        &self,
        film: &mut Film,
        samples: Range<u32>,
        skip: Option<&[u32]>,
    ) -> (PathCounters, u64, u64, Vec<u32>) {
        let scene = self.scene;
        debug_assert!(film.width > 0 && film.height > 0 && !film.window().is_empty());
        let services = self.renderer.services(scene).with_guide(self.guide);
        let pass = self.pass(film, samples, services);
        film.rows_mut()
            .into_par_iter()
            // One row per task: rayon's adaptive splitting otherwise hands a thread a run of rows it cannot
            // give up once started, and the other thread idled for ~10 ms at the end of each pass (cloud, 2
            // threads).
            .with_max_len(1)
            .enumerate()
            .map(|(row_index, row)| {
                pass.render_row(row_index, row, skip.map_or(0, |s| s[row_index] as usize))
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold(
                (PathCounters::new(scene.media.len()), 0, 0, Vec::new()),
                |(mut counters, nans, clamped, mut rows), row| {
                    counters.add(&row.0);
                    rows.push(row.3);
                    (counters, nans + row.1, clamped + row.2, rows)
                },
            )
    }

    /// Renders passes into `film` from `at` until the region's samples are done, the time limit is spent, a
    /// pass stops part way, `cancel` is cancelled or `progress` (called after each pass) says stop; returns
    /// where the region stands.
    fn run(
        &self,
        film: &mut Film,
        mut at: RegionProgress,
        totals: &mut PassTotals,
        progress: &mut dyn FnMut(&Progress, &Film) -> bool,
    ) -> RegionProgress {
        let s = &self.renderer.settings;
        let target = self.region.samples.len() as u32;
        // Pass size: about 16 passes for progress reports, 1 spp at first under a time budget.
        let mut pass = if s.time_limit.is_some() || self.doubling {
            1
        } else {
            target.div_ceil(16)
        };
        while totals.done < target && !self.cancel.is_cancelled() {
            let pass_start = Instant::now();
            let first = at.complete;
            // A pass a checkpoint stopped in is finished first, on the pixels that did not take it.
            let stopped = at.stopped_pass.take();
            let (end, skip) = match &stopped {
                Some(p) => (p.end, Some(p.row_pixels.as_slice())),
                None => (first + pass.min(target - totals.done), None),
            };
            let count = end - first;
            let (c, nans, clamped, rows) = self
                .pool
                .install(|| self.render_pass(film, first..end, skip));
            totals.counters.add(&c);
            totals.nan_samples += nans;
            totals.clamped_samples += clamped;
            at = after_pass(first, end, rows, self.region.window.width());
            totals.done = at.complete - self.region.samples.start;
            if at.stopped_pass.is_some() {
                break;
            }
            let elapsed = self.start.elapsed();
            if !progress(&self.report(totals, target, elapsed), film) {
                totals.cancelled = true;
                break;
            }
            if let Some(limit) = s.time_limit {
                if elapsed >= limit {
                    break;
                }
                // Size the next pass to use about half of the remaining budget.
                let per_spp = pass_start.elapsed().as_secs_f64() / count as f64;
                let remaining = (limit - elapsed).as_secs_f64();
                pass = ((remaining * 0.5 / per_spp.max(1e-9)) as u32).clamp(1, 64);
            }
            if self.doubling {
                pass = totals.done;
            }
        }
        at
    }

    /// The progress report after a pass: samples done of `target`, and the fraction done (of the time limit,
    /// when that is further along).
    fn report(&self, totals: &PassTotals, target: u32, elapsed: Duration) -> Progress {
        let done = totals.done;
        let fraction = match self.renderer.settings.time_limit {
            Some(limit) => (elapsed.as_secs_f64() / limit.as_secs_f64().max(1e-9))
                .max(done as f64 / target as f64),
            None => done as f64 / target as f64,
        };
        Progress {
            samples_done: done,
            samples_target: target,
            elapsed_seconds: elapsed.as_secs_f64(),
            fraction: fraction.min(1.0),
            nan_samples: totals.nan_samples,
            clamped_samples: totals.clamped_samples,
        }
    }
}

impl Renderer {
    /// The path tracer of a render of `scene` with these settings.
    fn path_tracer(&self, scene: &Scene) -> PathTracer {
        let s = &self.settings;
        PathTracer {
            max_depth: s.max_depth,
            media_mis: s.media_mis,
            equiangular: PathTracer::uses_equiangular(s.equiangular, scene),
            decoupled: PathTracer::uses_decoupled(s.decoupled, s.equiangular, scene),
            pixel_spread: scene.camera.pixel_spread_angle(s.height),
            pixel_width: scene.camera.pixel_width(s.height),
            transparent: self.transparent(scene),
            mattes: scene.names().has_mattes(),
            guided_roulette: s.guided_roulette,
            camera_media: MediumStack::enclosing(scene, scene.camera.position()),
        }
    }

    /// The renderer services of a render of `scene` with these settings (unguided).
    fn services<'a>(&self, scene: &'a Scene) -> RendererServices<'a> {
        RendererServices::new(scene, self.settings.light_sampler.uses_bvh(scene.lights()))
    }
}

#[cfg(test)]
impl Renderer {
    /// The guiding cache that a render of `scene` trains (guiding on, whatever the settings say), none of its
    /// samples kept, for tests of what it guides.
    pub(super) fn trained_guide(&self, scene: &Scene) -> GuidingField {
        let plan = Arc::new(LayerPlan::default());
        let recorder = LayerRecorder::new(scene, &plan, &self.light_groups(scene).unwrap());
        let region = self.whole();
        let pool = rayon::ThreadPoolBuilder::new().build().unwrap();
        let start = Instant::now();
        let clock = FirstPixelClock {
            start,
            seconds: OnceLock::new(),
        };
        let passes = Passes {
            clock: &clock,
            renderer: self,
            scene,
            tracer: self.path_tracer(scene),
            region: &region,
            recorder: &recorder,
            edges: None,
            guide: None,
            pool: &pool,
            cancel: &CancelToken::new(),
            doubling: false,
            start,
        };
        let mut film = Film::with_plan(
            self.settings.width,
            self.settings.height,
            region.window,
            plan,
        );
        let decision = GuidingDecision {
            on: true,
            provisional: false,
            reason: String::new(),
        };
        pool.install(|| passes.train(&mut film, 0..0, decision))
            .field
            .unwrap()
    }
}

/// Where a film stands after a pass of the samples `first..end` over a window `width` pixels wide, in which
/// each row took the pass in `rows[r]` of its pixels: the pass is complete when every row took it in full,
/// else it is a stopped pass (and nothing changed when no pixel took it).
fn after_pass(first: u32, end: u32, rows: Vec<u32>, width: usize) -> RegionProgress {
    if rows.iter().all(|&n| n as usize == width) {
        RegionProgress::start(end)
    } else if rows.iter().all(|&n| n == 0) {
        RegionProgress::start(first)
    } else {
        RegionProgress {
            complete: first,
            stopped_pass: Some(StoppedPass {
                end,
                row_pixels: rows,
            }),
        }
    }
}

/// Checks that `from` is a film of `region` with the layers of `plan`, and that its progress fits the region.
fn check_resume(
    from: &ResumeFrom,
    region: &RenderRegion,
    plan: &LayerPlan,
) -> Result<(), RenderError> {
    if from.film.window() != region.window {
        return Err(RenderError::Resume(format!(
            "the film holds the pixels {}, the render is of {}",
            from.film.window(),
            region.window
        )));
    }
    if from.film.plan().describe() != plan.describe() {
        return Err(RenderError::Resume(format!(
            "the film holds the layers '{}', the render makes '{}'",
            from.film.plan().describe(),
            plan.describe()
        )));
    }
    from.progress
        .fits(&from.film, &region.samples)
        .map_err(|e| RenderError::Resume(e.to_string()))
}

/// Peak resident set size of this process (Linux `VmHWM`), or `None` where unknown.
pub fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
