//! Grid media: VDB density (and optional temperature) grids placed in the scene by a glTF node's
//! `extras.nimbus_volume` or a USD `Volume` prim (keys in [`super::spec`]).
//!
//! - σ_t(x) = density_scale · ρ(x) per world metre (ρ: OpenVDB BoxSampler trilinear lookup), grey; σ_s = albedo ·
//!   σ_t; Henyey–Greenstein phase function.
//! - Free flights: decomposition tracking (Kutz et al. 2017, §4: delta tracking, Woodcock et al. 1965, whose
//!   tentative collisions under the segment's minorant are real without a lookup) over a majorant structure
//!   (`"majorant": "auto" | "adaptive" | "grid16" | "global"`); `auto`, the default, picks the cheapest for this
//!   grid at this density scale by a fixed-seed pilot ([`super::majorant_choice`]). Segments whose majorant
//!   optical depth per voxel exceeds [`super::tracking::REFINE_TAU`] are walked voxel cell by voxel cell, each
//!   bounded by its eight voxels, so the work per free flight stays flat as the density grows. Segments of
//!   constant density are tracked in closed form.
//! - RGB extinction (a vec3 density grid): majorants of the channels' maximum; free flights by spectral tracking
//!   (Kutz et al. 2017, §5, history-aware collision probabilities: the path keeps all three channels), or with
//!   `"chromatic_tracking": "one_channel"` by delta tracking of the one channel the path is made to carry. `auto`
//!   (the default) is spectral tracking, measured 2.8× to 8.5× as efficient (docs/reference.md), alone on a segment
//!   or beside other media (each medium flies over the part before the collisions of those before it).
//! - Shadow rays: ratio tracking (Novák et al. 2014, eq. 6), or residual ratio tracking (Novák et al. 2014, §4)
//!   with `"shadow_estimator": "residual_ratio"`.
//! - Emission: σ_a · L_e with L_e = emission_scale · blackbody(temperature_scale · T(x) + temperature_offset),
//!   gathered at the tentative collisions of a free flight's walk: an unbiased blend, per collision, of Miller
//!   et al. 2019's track-length estimator (σ_t/σ̄ · (σ_a/σ_t) · L_e at every tentative collision) and the
//!   collision estimator ((σ_a/σ_t) · L_e at the real one) with the blend α = exp(−σ̄·d) (σ̄ the majorant at the
//!   collision, d the distance left to the medium's exit; 0 below 1/64), weighted toward the first where the
//!   flight is likely to get through (thin regions, where it has less variance) and toward the second where it
//!   is sure to end soon (thick regions, where it has less) ([`super::tracking::TentativeCollision::emission_weight`],
//!   `Gather`). Taken from the majorant, α is known before a collision is decided: where it is 0, control
//!   collisions need no density lookup and null collisions no emission lookup.
//! - Motion blur: with a shutter and a velocity grid, every lookup at time τ reads the frame at x − v(x)·τ
//!   ([`super::velocity`]), over majorants dilated for the shutter.

use super::channels::{AlbedoGrids, ChannelGrid, Flame};
use super::density::{DensityField, GridDensity};
use super::emission::BlackbodyTable;
use super::error::VolumeError;
use super::majorant::{MajorantKind, Majorants};
use super::majorant_choice::{self, MajorantEstimate};
use super::tracking::{
    decomposition_tracking, decomposition_tracking_reporting, ratio_tracking,
    residual_ratio_tracking, spectral_tracking, NoHook, RgbDensity, TentativeCollision,
    TentativeHook,
};
use super::velocity::{Displaced, VelocityField};
use super::{
    Chromatic, ChromaticTracking, Collision, Flight, FreeFlight, Medium, MediumMethod,
    MethodReason, PhaseFunction, TentativeEmission, TrackingCounters, TransmittanceMethod,
    VolumeSpec,
};
#[cfg(any(test, feature = "testing"))]
use crate::limits::Limits;
use crate::math::{Aabb, Ray, Rgb, Rng, Vec3};
use std::sync::Arc;

/// The estimator used for shadow-ray transmittance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowEstimator {
    /// Ratio tracking.
    Ratio,
    /// Residual ratio tracking with the majorant segments' minorants as control.
    ResidualRatio,
}

impl ShadowEstimator {
    /// Every estimator, in the order of [`ShadowEstimator::NAMES`].
    pub const ALL: [ShadowEstimator; 2] = [Self::Ratio, Self::ResidualRatio];

    /// The scene-file names (`"shadow_estimator"` key), in the order of [`ShadowEstimator::ALL`].
    pub const NAMES: &'static [&'static str] = &["ratio", "residual_ratio"];

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The estimator of a scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }
}

/// Temperature lookup and the blackbody table for an emitting grid.
struct Emission {
    temperature: GridDensity,
    table: &'static BlackbodyTable,
    scale: f32,
    temperature_scale: f32,
    temperature_offset: f32,
}

/// Runs `$call` with `$f` bound to `$channel` (a `&GridDensity`) as a ray at `$time` sees it: displaced along
/// the velocity when the medium moves, else as it is (static dispatch in both cases: the hot path of tracking).
macro_rules! with_field {
    ($medium:expr, $channel:expr, $time:expr, |$f:ident| $call:expr) => {
        match $medium.moved($channel, $time) {
            Some(displaced) => {
                let $f = &displaced;
                $call
            }
            None => {
                let $f: &GridDensity = $channel;
                $call
            }
        }
    };
}

/// The world box a grid medium fills: its majorants' box (which holds the field over the whole shutter, grown
/// by the velocity reach), else the density's bounds. Computed once: every ray segment asks for it.
fn world_bounds(density: &GridDensity, majorants: &Majorants) -> Aabb {
    let b = majorants.local_bounds();
    if b.is_empty() {
        return density.bounds();
    }
    b.transformed(&density.index_to_world())
}

/// The error for a grid `name` that the volume's file lacks, naming the grids it has.
fn missing_grid(file: &crate::vdb::VdbFile, spec: &VolumeSpec, name: &str) -> VolumeError {
    VolumeError::GridMissing {
        file: spec.file.clone(),
        grid: name.to_owned(),
        available: file.grids.iter().map(|g| g.name.clone()).collect(),
    }
}

/// The grid `name` of the volume's file, or [`missing_grid`]'s error; a level set is refused as one.
fn named_grid<'f>(
    file: &'f crate::vdb::VdbFile,
    spec: &VolumeSpec,
    name: &str,
) -> Result<&'f crate::vdb::Grid, VolumeError> {
    let grid = file
        .grid(name)
        .ok_or_else(|| missing_grid(file, spec, name))?;
    if grid.class == crate::vdb::GridClass::LevelSet {
        return Err(grid_error(spec, name)(super::DensityError::LevelSet));
    }
    Ok(grid)
}

/// Turns a problem with grid `name` of the volume's file into an error naming both.
fn grid_error(spec: &VolumeSpec, name: &str) -> impl FnOnce(super::DensityError) -> VolumeError {
    let (file, grid) = (spec.file.clone(), name.to_owned());
    move |source| VolumeError::Density { file, grid, source }
}

/// A velocity field and the factor turning a ray's time (frames) into its scaled seconds.
struct Motion {
    velocity: VelocityField,
    /// `velocity_scale / fps`.
    seconds_per_frame: f32,
    /// The majorants' dilation per axis of the density's index space: the largest displacement over the
    /// shutter.
    reach: Vec3,
}

/// A heterogeneous medium backed by a sparse VDB grid.
pub struct GridMedium {
    name: String,
    /// World bounds of what the medium fills ([`Medium::fill_bounds`]).
    world_bounds: Aabb,
    density: GridDensity,
    majorants: Majorants,
    /// The pilot's estimates when the structure was chosen automatically.
    majorant_estimates: Vec<MajorantEstimate>,
    albedo: Rgb,
    phase: PhaseFunction,
    shadow: ShadowEstimator,
    emission: Option<Emission>,
    flame: Option<Flame>,
    albedo_grids: AlbedoGrids,
    motion: Option<Motion>,
    /// For an RGB (vec3) density grid, σ_t per channel; `density` is then their maximum, which the majorants
    /// bound.
    channels: Option<Box<[GridDensity; 3]>>,
    /// How free flights handle the channels of an RGB density.
    chromatic: Chromatic,
}

impl GridMedium {
    /// Builds a medium from a placed density field and its parameters.
    #[cfg(any(test, feature = "testing"))]
    pub fn new(name: &str, density: GridDensity, kind: MajorantKind, albedo: Rgb, g: f32) -> Self {
        let majorants = Majorants::build(kind, &density);
        Self::with_parts(name, density, majorants, Vec::new(), albedo, g)
    }

    /// Builds a medium whose majorant structure is the cheapest by the pilot of [`majorant_choice::choose`],
    /// among those that fit the default memory budget.
    #[cfg(any(test, feature = "testing"))]
    pub fn with_chosen_majorants(name: &str, density: GridDensity, albedo: Rgb, g: f32) -> Self {
        Self::chosen_within(name, density, albedo, g, &Limits::default())
    }

    /// [`with_chosen_majorants`](Self::with_chosen_majorants) under the budget `limits`.
    #[cfg(any(test, feature = "testing"))]
    fn chosen_within(
        name: &str,
        density: GridDensity,
        albedo: Rgb,
        g: f32,
        limits: &Limits,
    ) -> Self {
        let (majorants, estimates) = majorant_choice::choose(&density, limits);
        Self::with_parts(name, density, majorants, estimates, albedo, g)
    }

    fn with_parts(
        name: &str,
        density: GridDensity,
        majorants: Majorants,
        majorant_estimates: Vec<MajorantEstimate>,
        albedo: Rgb,
        g: f32,
    ) -> Self {
        Self {
            name: name.to_owned(),
            world_bounds: world_bounds(&density, &majorants),
            density,
            majorants,
            majorant_estimates,
            albedo,
            phase: PhaseFunction::henyey_greenstein(g),
            shadow: ShadowEstimator::Ratio,
            emission: None,
            flame: None,
            albedo_grids: AlbedoGrids::default(),
            motion: None,
            channels: None,
            chromatic: Chromatic {
                tracking: ChromaticTracking::AUTO,
                requested: false,
            },
        }
    }

    /// Uses `shadow` for shadow-ray transmittance.
    pub fn with_shadow_estimator(mut self, shadow: ShadowEstimator) -> Self {
        self.shadow = shadow;
        self
    }

    /// Replaces the majorant structure (for benchmarks and tests of under-estimated majorants).
    #[cfg(any(test, feature = "testing"))]
    pub fn with_majorants(mut self, majorants: Majorants) -> Self {
        self.world_bounds = world_bounds(&self.density, &majorants);
        self.majorants = majorants;
        self.majorant_estimates.clear();
        self
    }

    /// Where `ray` leaves the medium's box before `t_max` (`t_max` when it does not).
    fn exit(&self, ray: &Ray, t_max: f32) -> f32 {
        self.world_bounds
            .intersect(ray, 0.0, t_max)
            .map_or(t_max, |(_, far)| far)
    }

    /// Spectral tracking of `interval` of `ray` through the RGB density, reporting its tentative collisions to
    /// `hook`; `None` for a scalar density.
    fn spectral_walk<H: TentativeHook>(
        &self,
        ray: &Ray,
        interval: (f32, f32),
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        hook: H,
    ) -> Option<Flight> {
        let channels = self.channels.as_deref()?;
        Some(match self.moved(&self.density, ray.time) {
            Some(max) => {
                let [r, g, b] = channels
                    .each_ref()
                    .map(|density| Displaced { density, ..max });
                spectral_tracking(
                    RgbDensity {
                        max: &max,
                        channels: [&r, &g, &b],
                        majorants: &self.majorants,
                    },
                    ray,
                    interval,
                    throughput,
                    rng,
                    counters,
                    hook,
                )
            }
            None => spectral_tracking(
                RgbDensity {
                    max: &self.density,
                    channels: channels.each_ref(),
                    majorants: &self.majorants,
                },
                ray,
                interval,
                throughput,
                rng,
                counters,
                hook,
            ),
        })
    }

    /// Spectral tracking over `(0, t_max)` of `ray` for a path of `throughput`, gathering emission at its
    /// tentative collisions when the medium emits; `None` for a scalar density.
    fn spectral_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        emission: &mut TentativeEmission,
    ) -> Option<Flight> {
        let interval = (0.0, t_max);
        if !self.is_emissive() {
            return self.spectral_walk(ray, interval, throughput, rng, counters, NoHook);
        }
        // The walk's weights already hold the path's throughput.
        let gather = Gather::new(self, ray, t_max, Rgb::ONE, emission);
        self.spectral_walk(ray, interval, throughput, rng, counters, gather)
    }

    /// Delta (decomposition) tracking over `(0, t_max)` of `ray` for a path of `throughput`: the next real
    /// collision, analog. An RGB density tracked one channel at a time makes the path carry one channel, chosen
    /// ∝ its throughput; delta tracking in it is analog (weight 1), over the majorants of the channels'
    /// maximum. An emitting medium gathers its emission at the walk's tentative collisions, times the carried
    /// throughput (the walk's weights are 1).
    fn delta_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        emission: &mut TentativeEmission,
    ) -> Flight {
        let mut carried = throughput;
        let channel = match &self.channels {
            Some(ch) => {
                crate::math::sampling::carry_one_channel(&mut carried, rng);
                &ch[carried.max_position()]
            }
            None => &self.density,
        };
        let collision = if self.is_emissive() {
            let gather = Gather::new(self, ray, t_max, carried, emission);
            with_field!(self, channel, ray.time, |field| {
                decomposition_tracking_reporting(
                    field,
                    &self.majorants,
                    ray,
                    (0.0, t_max),
                    rng,
                    counters,
                    gather,
                )
            })
        } else {
            with_field!(self, channel, ray.time, |field| decomposition_tracking(
                field,
                &self.majorants,
                ray,
                0.0,
                t_max,
                rng,
                counters
            ))
        };
        Flight {
            collision,
            throughput: carried,
        }
    }

    /// True for an RGB density whose free flights use spectral tracking.
    fn tracks_spectrally(&self) -> bool {
        self.channels.is_some() && self.chromatic.tracking == ChromaticTracking::Spectral
    }

    /// The density field.
    #[cfg(any(test, feature = "testing"))]
    pub fn density(&self) -> &GridDensity {
        &self.density
    }

    /// Loads the grids `spec` names and builds the medium. Errors name the VDB file and the grid.
    pub fn load(spec: &VolumeSpec) -> Result<Self, VolumeError> {
        let file = match spec.embedded {
            Some(bytes) => crate::vdb::read_bytes(bytes, &spec.file),
            None => crate::vdb::read_file_with(
                &spec.file,
                &crate::vdb::ReadOptions {
                    limits: spec.limits,
                    ..Default::default()
                },
            ),
        }?;
        let density_grid = named_grid(&file, spec, &spec.density_grid)?;
        let (density, channels) = if density_grid.tree.as_vec3().is_some() {
            let (max, channels) =
                rgb_density(density_grid, spec).map_err(grid_error(spec, &spec.density_grid))?;
            (max, Some(Box::new(channels)))
        } else {
            let density = GridDensity::new(
                density_grid,
                spec.node_to_world.as_dmat4(),
                spec.density_scale,
            )
            .map_err(grid_error(spec, &spec.density_grid))?;
            (density, None)
        };
        let motion = match spec.shutter {
            Some(shutter) => Self::load_motion(spec, &file, density_grid, shutter)?,
            None => None,
        };
        let reach = motion.as_ref().map_or(Vec3::ZERO, |m| m.reach);
        let (majorants, estimates) = match spec.majorant {
            // Moving or chromatic: majorants without minorants (no constant-density shortcuts, which would hold
            // for the channels' maximum only), dilated over the shutter when the medium moves.
            kind if motion.is_some() || channels.is_some() => {
                let kind = match kind {
                    Some(MajorantKind::Global) => MajorantKind::Global,
                    _ => MajorantKind::Grid16,
                };
                (Majorants::build_reaching(kind, &density, reach), Vec::new())
            }
            Some(kind) => {
                let majorants =
                    Majorants::try_build(kind, &density, &spec.limits).map_err(|source| {
                        VolumeError::OverBudget {
                            file: spec.file.clone(),
                            source,
                        }
                    })?;
                (majorants, Vec::new())
            }
            None => majorant_choice::choose(&density, &spec.limits),
        };
        let mut medium = Self::with_parts(
            &spec.name,
            density,
            majorants,
            estimates,
            spec.albedo,
            spec.anisotropy,
        )
        .with_shadow_estimator(spec.shadow_estimator);
        medium.motion = motion;
        medium.load_channels(spec, &file)?;
        medium.channels = channels;
        if let Some(tracking) = spec.chromatic_tracking {
            medium.chromatic = Chromatic {
                tracking,
                requested: true,
            };
        }
        Ok(medium)
    }

    /// Loads the channels beside density that `spec` names: temperature (blackbody emission), flame, and the
    /// albedo and colour grids.
    fn load_channels(
        &mut self,
        spec: &VolumeSpec,
        file: &crate::vdb::VdbFile,
    ) -> Result<(), VolumeError> {
        let node_to_world = spec.node_to_world.as_dmat4();
        if let Some(t) = &spec.temperature_grid {
            // A temperature, not an extinction: never clamped as too dense.
            let temperature = GridDensity::scalar(named_grid(file, spec, t)?, node_to_world)
                .map_err(grid_error(spec, t))?;
            self.emission = Some(Emission {
                temperature,
                table: BlackbodyTable::shared(),
                scale: spec.emission_scale,
                temperature_scale: spec.temperature_scale,
                temperature_offset: spec.temperature_offset,
            });
        }
        let channel = |name: &str| -> Result<ChannelGrid, VolumeError> {
            ChannelGrid::new(named_grid(file, spec, name)?, node_to_world)
                .map_err(grid_error(spec, name))
        };
        if let Some(name) = &spec.flame_grid {
            let colour = spec
                .flame_color
                .unwrap_or_else(|| BlackbodyTable::shared().lookup(spec.flame_temperature));
            self.flame = Some(Flame {
                grid: channel(name)?,
                radiance: colour * spec.flame_scale,
            });
        }
        for name in [&spec.albedo_grid, &spec.color_grid].into_iter().flatten() {
            self.albedo_grids.factors.push(channel(name)?);
        }
        Ok(())
    }

    /// The motion of a blurred volume: the velocity field of `velocity_grid` (one vec3 grid, else its `.x`,
    /// `.y`, `.z` scalar grids) placed with the `density` grid, its seconds per shutter frame
    /// (`velocity_scale / fps`) and its reach over the shutter, which may not exceed [`MAX_REACH_VOXELS`].
    /// `None` when the file has neither grid and the key was left at its default (the volume does not move),
    /// or the scale or the shutter is 0.
    fn load_motion(
        spec: &VolumeSpec,
        file: &crate::vdb::VdbFile,
        density: &crate::vdb::Grid,
        shutter: crate::frames::Shutter,
    ) -> Result<Option<Motion>, VolumeError> {
        let name = spec
            .velocity_grid
            .as_deref()
            .unwrap_or(DEFAULT_VELOCITY_GRID);
        let parts = [".x", ".y", ".z"].map(|axis| file.grid(&format!("{name}{axis}")));
        let grids: Vec<&crate::vdb::Grid> = match (file.grid(name), parts) {
            (Some(g), _) => vec![g],
            (None, [Some(x), Some(y), Some(z)]) => vec![x, y, z],
            _ if spec.velocity_grid.is_none() => return Ok(None),
            _ => return Err(missing_grid(file, spec, name)),
        };
        let velocity = VelocityField::new(&grids, density).map_err(grid_error(spec, name))?;
        let seconds_per_frame = (spec.velocity_scale as f64 / spec.fps) as f32;
        if seconds_per_frame == 0.0 || shutter.open == shutter.close && shutter.open == 0.0 {
            return Ok(None);
        }
        let longest = shutter.open.abs().max(shutter.close.abs());
        let reach = velocity.reach(longest * seconds_per_frame);
        if !reach.is_finite() || reach.max_element() > MAX_REACH_VOXELS {
            return Err(grid_error(spec, name)(super::DensityError::Placement(format!(
                "over the shutter the velocities move the density up to {:.3e} voxels, beyond the limit of {MAX_REACH_VOXELS} (check velocity_scale and the velocity grid's units)",
                reach.max_element()
            ))));
        }
        Ok(Some(Motion {
            velocity,
            seconds_per_frame,
            reach,
        }))
    }

    /// The density as seen by a ray at `time` frames: displaced along the velocity when the medium moves.
    fn moved<'a>(&'a self, channel: &'a GridDensity, time: f32) -> Option<Displaced<'a>> {
        let m = self.motion.as_ref()?;
        (time != 0.0).then_some(Displaced {
            density: channel,
            velocity: &m.velocity,
            seconds: time * m.seconds_per_frame,
        })
    }

    /// The world point whose frame-time values reach world point `p` at `time` frames.
    fn source_point(&self, p: Vec3, time: f32) -> Vec3 {
        match self.moved(&self.density, time) {
            Some(d) => {
                let index = self.density.world_to_index().transform_point3(p);
                self.density
                    .index_to_world()
                    .transform_point3(d.source(index))
            }
            None => p,
        }
    }
}

/// The majorant optical depth left to the medium's exit beyond which [`Gather`]'s blend is 0, the collision
/// estimator alone: ln 64, so the smallest blend used is 1/64.
const MAX_BLEND_DEPTH: f32 = 4.158_883;

/// The emission hook of a grid medium's free flight: gathers (σ_a/σ_t) L_e at the walk's tentative collisions
/// with the weight [`TentativeCollision::emission_weight`] of the blend α = exp(−σ̄·d), σ̄ the majorant at the
/// collision and d the distance left to the medium's exit (0 when σ̄·d exceeds [`MAX_BLEND_DEPTH`]).
///
/// The blend leans on the track-length estimator (Miller, Georgiev, Jarosz 2019, eq. 9) where even a medium as
/// dense as the majorant all the way would likely let the flight through (thin media, where it has less
/// variance), and on the collision estimator where the flight is sure to end soon (thick media, where that one
/// is nearly deterministic). It is taken from the majorant, not from σ_t(x): it is then known before the walk
/// decides the collision, so decomposition tracking keeps its lookup-free control collisions where it is 0,
/// and null collisions there gather nothing and read no emission.
struct Gather<'a> {
    medium: &'a GridMedium,
    ray: &'a Ray,
    /// The length of the ray's direction: world length per unit of its parameter.
    len: f32,
    /// Where the ray leaves the medium (or the flight's interval ends).
    t_end: f32,
    /// The path throughput that the walk's own weights do not hold.
    start: Rgb,
    emission: &'a mut TentativeEmission,
}

impl<'a> Gather<'a> {
    /// The hook of a flight over `(0, t_max)` of `ray` through `medium` for a path of throughput `start` (before
    /// the walk's weights), gathering into `emission`.
    fn new(
        medium: &'a GridMedium,
        ray: &'a Ray,
        t_max: f32,
        start: Rgb,
        emission: &'a mut TentativeEmission,
    ) -> Self {
        Self {
            medium,
            ray,
            len: ray.dir.length(),
            t_end: medium.exit(ray, t_max),
            start,
            emission,
        }
    }
}

impl TentativeHook for Gather<'_> {
    const WANTS: bool = true;

    #[inline]
    fn blend(&mut self, t: f32, sigma_bar: f32) -> f32 {
        let depth_left = sigma_bar * self.len * (self.t_end - t);
        if depth_left > MAX_BLEND_DEPTH {
            0.0
        } else {
            (-depth_left).exp()
        }
    }

    fn tentative(&mut self, x: &TentativeCollision) {
        let weight = x.emission_weight(self.blend(x.t, x.sigma_bar));
        // A null collision where the blend is 0 or the medium is empty gathers nothing: no lookup.
        if weight == Rgb::ZERO {
            return;
        }
        let collision = self.medium.collision(self.ray.at(x.t), self.ray.time);
        if x.real.is_some() {
            self.emission.keep_real(x.t, collision);
        }
        let emitted = collision.emission;
        if emitted.max_element() > 0.0 {
            self.emission.push(x.t, self.start * weight * emitted);
        }
    }
}

/// The σ_t fields of an RGB density grid: their per-voxel maximum (which the majorants and the pilot use) and
/// each channel, each `density_scale` times the grid's component, placed like a scalar density grid.
fn rgb_density(
    grid: &crate::vdb::Grid,
    spec: &VolumeSpec,
) -> Result<(GridDensity, [GridDensity; 3]), super::DensityError> {
    let Some(tree) = grid.tree.as_vec3() else {
        return Err(super::DensityError::NotScalar);
    };
    let index_to_world = spec.node_to_world.as_dmat4() * grid.index_to_world;
    let field = |values: crate::vdb::FloatTree| {
        GridDensity::from_tree(
            Arc::new(crate::vdb::GridTree::Float(values)),
            index_to_world,
            spec.density_scale,
        )
    };
    let max = field(tree.map(|v| v.max_element()))?;
    let channels = [
        field(tree.map(|v| v.x))?,
        field(tree.map(|v| v.y))?,
        field(tree.map(|v| v.z))?,
    ];
    Ok((max, channels))
}

/// The largest displacement velocity blur may bring over the shutter, in voxels: far beyond any real simulation
/// (a fluid crosses a few voxels a frame), while a corrupt or mis-scaled velocity would dilate the majorants over
/// so much space that tracking took practically endless steps.
pub const MAX_REACH_VOXELS: f32 = 65536.0;

/// The velocity grid read when `velocity_grid` is not given (Houdini's and Blender's name).
pub const DEFAULT_VELOCITY_GRID: &str = "vel";

impl Medium for GridMedium {
    fn name(&self) -> &str {
        &self.name
    }

    fn method(&self) -> MediumMethod {
        MediumMethod {
            free_flight: FreeFlight::DeltaTracking {
                closed_form_segments: self.majorants.stores_minorants(),
                // Spectral tracking reads every channel at each tentative collision: no control to decompose.
                decomposition: !self.tracks_spectrally(),
                // A moving medium's displaced density has no voxel cells to bound.
                voxel_refinement: self.majorants.voxel_refinement() && self.motion.is_none(),
                chromatic: self.channels.as_ref().map(|_| self.chromatic),
            },
            majorant: Some(self.majorants.kind()),
            shadow: match self.shadow {
                ShadowEstimator::Ratio => TransmittanceMethod::RatioTracking,
                ShadowEstimator::ResidualRatio => TransmittanceMethod::ResidualRatioTracking,
            },
            why: if let Some(m) = &self.motion {
                MethodReason::VelocityBlur {
                    reach_voxels: m.reach.max_element(),
                }
            } else if self.channels.is_some() {
                MethodReason::ChromaticExtinction
            } else if self.majorant_estimates.is_empty() {
                MethodReason::Requested
            } else {
                MethodReason::Pilot(self.majorant_estimates.clone())
            },
        }
    }

    fn memory_bytes(&self) -> usize {
        self.density.memory_bytes()
            + self.majorants.memory_bytes()
            + self
                .emission
                .as_ref()
                .map_or(0, |e| e.temperature.memory_bytes())
            + self.flame.as_ref().map_or(0, |f| f.grid.memory_bytes())
            + self.albedo_grids.memory_bytes()
            + self
                .motion
                .as_ref()
                .map_or(0, |m| m.velocity.memory_bytes())
    }

    fn fill_bounds(&self) -> Option<Aabb> {
        Some(self.world_bounds)
    }

    fn warnings(&self) -> Vec<String> {
        // An RGB grid's values are its components, each channel counting its own: the channels' maximum, which
        // the majorants use, hides a negative component beside a positive one.
        let (mut bad, values) = match &self.channels {
            Some(channels) => (
                channels
                    .iter()
                    .fold(super::density::BadValues::default(), |mut all, c| {
                        all.add(&c.bad_values());
                        all
                    }),
                "vec3 grid components",
            ),
            None => (self.density.bad_values(), "grid values"),
        };
        if let Some(e) = &self.emission {
            bad.add(&e.temperature.bad_values());
        }
        let mut warnings = Vec::new();
        if bad.nan + bad.infinite + bad.negative > 0 {
            warnings.push(format!(
                "medium '{}': {} NaN, {} infinite and {} negative {values} were replaced by zero",
                self.name, bad.nan, bad.infinite, bad.negative
            ));
        }
        if bad.too_dense > 0 {
            warnings.push(format!(
                "medium '{}': {} grid values denser than an optical depth of {} per voxel were clamped to it",
                self.name,
                bad.too_dense,
                super::density::MAX_VOXEL_OPTICAL_DEPTH
            ));
        }
        warnings
    }

    fn is_absorbing_only(&self) -> bool {
        false
    }

    fn is_emissive(&self) -> bool {
        self.emission.as_ref().is_some_and(|e| e.scale > 0.0)
            || self
                .flame
                .as_ref()
                .is_some_and(|f| f.radiance.max_element() > 0.0)
    }

    fn free_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        emission: &mut TentativeEmission,
    ) -> Flight {
        if self.tracks_spectrally() {
            if let Some(flight) =
                self.spectral_flight(ray, t_max, throughput, rng, counters, emission)
            {
                return flight;
            }
        }
        self.delta_flight(ray, t_max, throughput, rng, counters, emission)
    }

    fn collision(&self, p: Vec3, time: f32) -> Collision {
        let p = self.source_point(p, time);
        let albedo = self.albedo_grids.albedo_at(self.albedo, p);
        let mut radiance = match &self.emission {
            Some(e) => {
                let kelvin = e.temperature_scale * e.temperature.density(p) + e.temperature_offset;
                e.scale * e.table.lookup(kelvin)
            }
            None => Rgb::ZERO,
        };
        if let Some(f) = &self.flame {
            radiance += f.radiance_at(p);
        }
        Collision {
            albedo,
            // σ_a L_e / σ_t, the collision estimator's weight of emission.
            emission: (Rgb::ONE - albedo) * radiance,
            phase: self.phase,
        }
    }

    /// The ratio-tracking walks start from `weight`, so their roulette sees the weighted estimate.
    fn weighted_transmittance(
        &self,
        weight: f32,
        ray: &Ray,
        t_max: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb {
        let mut estimate = |channel: &GridDensity, rng: &mut Rng| match self.shadow {
            ShadowEstimator::Ratio => with_field!(self, channel, ray.time, |f| ratio_tracking(
                f,
                &self.majorants,
                ray,
                (0.0, t_max),
                weight,
                rng,
                counters
            )),
            ShadowEstimator::ResidualRatio => {
                with_field!(self, channel, ray.time, |f| residual_ratio_tracking(
                    f,
                    &self.majorants,
                    ray,
                    (0.0, t_max),
                    weight,
                    rng,
                    counters
                ))
            }
        };
        match &self.channels {
            // Each channel's own estimate (each unbiased), over the shared majorants.
            Some(ch) => Rgb::new(
                estimate(&ch[0], rng),
                estimate(&ch[1], rng),
                estimate(&ch[2], rng),
            ),
            None => Rgb::splat(estimate(&self.density, rng)),
        }
    }
}

/// Loads the VDB file of `spec` (for a sequence, the file of its frame) and builds its grid medium; `None`
/// when a sequence has no file for the frame and `missing_frame` is `empty`.
pub fn load_grid_medium(spec: &VolumeSpec) -> Result<Option<Arc<dyn Medium>>, VolumeError> {
    let Some(file) = spec.frame_file()? else {
        return Ok(None);
    };
    let spec = VolumeSpec {
        file,
        ..spec.clone()
    };
    Ok(Some(Arc::new(GridMedium::load(&spec)?)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vdb::{GridTree, Tree};
    use glam::{DMat4, DVec3, IVec3};

    /// Voxels along the ray of [`emitting_ramp`].
    const N: i32 = 32;
    /// Voxel size in metres.
    const VOXEL: f64 = 0.05;
    /// The density of the ramp's first voxel, in units of its step per voxel.
    const RAMP_START: f32 = 8.0;
    /// The temperature everywhere the ramp has density, in kelvin.
    const KELVIN: f32 = 2000.0;

    /// An `N`³ block whose density rises along x, `scale` · ([`RAMP_START`] + i) at voxel i, placed at voxel size
    /// [`VOXEL`], with a constant temperature ([`KELVIN`]) on a block two voxels wider on every side, albedo 0
    /// (σ_a = σ_t) and emission scale 1, under majorants `kind`. Along a ray on x through the block's middle the
    /// trilinear density is piecewise linear between voxel centres and falls to 0 one voxel beyond the end
    /// ones, so the optical depth across it is exactly `scale` · [`VOXEL`] · Σ ([`RAMP_START`] + i). The
    /// interior leaves (8³ voxels) have minorants above 0: decomposition tracking's control collisions.
    fn emitting_ramp(scale: f32, kind: MajorantKind) -> GridMedium {
        let index_to_world = DMat4::from_scale(DVec3::splat(VOXEL));
        let block = |lo: i32, hi: i32, value: &dyn Fn(i32) -> f32| {
            let voxels = (lo..hi).flat_map(|x| {
                (lo..hi).flat_map(move |y| (lo..hi).map(move |z| (IVec3::new(x, y, z), x)))
            });
            let tree = Tree::from_voxels(0.0, voxels.map(|(p, x)| (p, value(x))));
            Arc::new(GridTree::Float(tree))
        };
        let density = GridDensity::from_tree(
            block(0, N, &|x| RAMP_START + x as f32),
            index_to_world,
            scale,
        )
        .unwrap();
        let temperature =
            GridDensity::from_tree(block(-2, N + 2, &|_| 1.0), index_to_world, 1.0).unwrap();
        let mut medium = GridMedium::new("ramp", density, kind, Rgb::ZERO, 0.0);
        medium.emission = Some(Emission {
            temperature,
            table: BlackbodyTable::shared(),
            scale: 1.0,
            temperature_scale: KELVIN,
            temperature_offset: 0.0,
        });
        medium
    }

    /// The mean and standard error of the emission gathered by `n` free flights along `ray` (path throughput 1)
    /// and the flights' tracking counters.
    fn gathered_emission(
        medium: &GridMedium,
        ray: &Ray,
        n: u64,
    ) -> (DVec3, DVec3, TrackingCounters) {
        let (mut sum, mut sum2) = (DVec3::ZERO, DVec3::ZERO);
        let mut counters = TrackingCounters::default();
        let mut emission = TentativeEmission::default();
        for k in 0..n {
            emission.clear();
            let mut rng = Rng::new(21, k);
            medium.free_flight(ray, 10.0, Rgb::ONE, &mut rng, &mut counters, &mut emission);
            let total = emission
                .samples()
                .iter()
                .fold(DVec3::ZERO, |total, sample| total + sample.1.as_dvec3());
            sum += total;
            sum2 += total * total;
        }
        let mean = sum / n as f64;
        let variance = (sum2 / n as f64 - mean * mean).max(DVec3::ZERO);
        (mean, (variance / n as f64).powf(0.5), counters)
    }

    /// The blended estimator of emission ([`Gather`]) is unbiased: along a ray through an emitting ramp of
    /// albedo 0 and constant temperature, the emission gathered at the tentative collisions has the expectation
    /// L_e (1 − e^−τ) (∫ σ_t T L_e dt in closed form), within 4 standard errors, with every majorant
    /// structure; in a thin ramp (τ = 1, where the blend is above 0 everywhere) and a thick one (τ = 30, where it
    /// is 0 until the last few collisions before the exit, and decomposition tracking decides its control
    /// collisions without a density lookup).
    #[test]
    fn blended_emission_matches_the_closed_form_in_thin_and_thick_media() {
        let middle = (N as f32 / 2.0 - 0.3) * VOXEL as f32;
        let ray = Ray::new(Vec3::new(-1.0, middle, middle + 0.01), Vec3::X);
        let ramp_sum = (N * (N - 1) / 2) as f64 + (N as f64) * RAMP_START as f64;
        for tau in [1.0f64, 30.0] {
            let scale = (tau / (VOXEL * ramp_sum)) as f32;
            for kind in MajorantKind::ALL {
                let medium = emitting_ramp(scale, kind);
                let le = medium
                    .collision(Vec3::new(0.4, middle, middle), 0.0)
                    .emission;
                assert!(le.min_element() > 0.0, "the ramp emits: {le:?}");
                let (mean, se, counters) = gathered_emission(&medium, &ray, 20_000);
                let expected = le.as_dvec3() * (1.0 - (-tau).exp());
                for c in 0..3 {
                    assert!(
                        (mean[c] - expected[c]).abs() <= 4.0 * se[c] + 1e-5 * expected[c],
                        "τ {tau} {kind:?} channel {c}: {} ± {} vs L_e (1 − e^−τ) = {}",
                        mean[c],
                        se[c],
                        expected[c]
                    );
                }
                if tau > 10.0 && kind == MajorantKind::Adaptive {
                    let tentative = counters.real_collisions + counters.null_collisions;
                    assert!(
                        counters.density_lookups < tentative,
                        "control collisions need no lookup: {counters:?}"
                    );
                }
            }
        }
    }
}
