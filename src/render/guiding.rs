//! The guiding cache's training: a fixed pre-pass before the image's samples (Müller et al. 2017, "Practical
//! Path Guiding for Efficient Light-Transport Simulation": iterations of doubling sample counts, each guided by
//! the cache of the one before, the last cache guiding the image), whose samples are the image's first.
//!
//! Iteration k takes `2^k` samples of every pixel of the whole frame, whatever the region a part renders: the
//! samples `2^k − 1 .. 2^(k+1) − 1` of each pixel's sequence, drawn, traced and filtered as every image sample
//! is (`Pass::train_row` in `super::renderer`), so that the [`TRAINING_SAMPLES`] (7) samples of the training
//! are samples `0..7` of the image (Cycles keeps its training's samples too: each is an unbiased estimate of
//! its pixel, iteration 0 unguided, the later ones guided by the cache before). Those of them in the render's
//! sample range and of the pixels of its window are added to its film, exactly as image samples; the rest only
//! teach the cache. A render of `--spp N` thus traces `N − 7` samples per pixel after the training (none when
//! N ≤ 7).
//!
//! `auto`'s pilot ([`decide`]) traces sample 0 of a lattice of pixels unguided, as iteration 0 traces it. Where
//! iteration 0 traces those paths anyway (a whole frame from sample 0, or a frame whose lattice is every pixel),
//! iteration 0 is the pilot: it decides after that iteration, whose sample 0 stays in the film either way, so
//! `auto` that does not guide traces no path an `off` render does not. Elsewhere the lattice is traced first, alone
//! ([`lattice_pilot`]).
//!
//! Determinism: rows are traced in parallel a block at a time and their records added to the cache in row
//! order, one thread. The cache is the same for any thread count and in every farm part of a render, and the
//! film's sums are exact, so the training's samples merge bit for bit whichever part holds them.
//!
//! With guided Russian roulette on ([`PathTracer::guided_roulette`]), the training's samples also give the pixel
//! values it compares paths with ([`PixelEstimates`], every iteration's samples: each sample's continuation
//! after its first remembered event's next-event estimate, [`GuidePath::continuation`], an unbiased estimate of
//! that part of its pixel), summed in the same row order; without it they are not kept.
//!
//! [`PathTracer::guided_roulette`]: crate::integrator::PathTracer::guided_roulette
//! [`GuidePath::continuation`]: crate::guiding::GuidePath::continuation

use super::film::{Film, FilmRow, PixelWindow};
use super::renderer::{GuidingStats, Pass};
use crate::guiding::adjoint::PixelEstimates;
use crate::guiding::lit::LitGrid;
use crate::guiding::pilot::AUTO_PILOT_PATHS;
use crate::guiding::shadow::{survival, SHADOW_MIN_SURVIVAL, VISIBILITY_MIN_SURVIVAL};
use crate::guiding::{
    decide_from_shadow_pilot, GuidingDecision, GuidingField, LitRecord, RadianceRecord,
    TRAINING_ITERATIONS,
};
use crate::integrator::PathCounters;
use rayon::prelude::*;
use std::ops::Range;
use std::time::Instant;

/// Samples per pixel of the training, all its iterations' (1 + 2 + 4): the first samples of every pixel.
pub(crate) const TRAINING_SAMPLES: u32 = (1 << TRAINING_ITERATIONS) - 1;
/// The sparsest the pilot gets: every 4th pixel along each axis, a sixteenth of a sample per pixel.
const AUTO_PILOT_MAX_STRIDE: usize = 4;
/// Rows traced in parallel before their records are added (bounds the records held at once).
const ROWS_PER_BLOCK: usize = 16;

/// What the training did: the cache (none when guiding is off or the render was cancelled), its statistics, the
/// work of all its paths, and the samples it added to the film that were dropped or clamped.
pub(super) struct Training {
    /// The trained cache.
    pub field: Option<GuidingField>,
    /// What `--stats` says of it.
    pub stats: GuidingStats,
    /// The work of every training path (those only the cache learned from included).
    pub counters: PathCounters,
    /// True when `auto`'s pilot decided not to guide ([`GuidingDecision::provisional`]): the film holds no
    /// sample but those in `in_film`.
    pub decided_off: bool,
    /// The samples (of every pixel of the window) added to the film: the training's, or `auto`'s pilot's
    /// sample 0 where it decided not to guide; none when cancelled.
    pub in_film: Range<u32>,
    /// Samples meant for the film dropped as NaN or infinite.
    pub nan_samples: u64,
    /// Samples added to the film with a value clamped.
    pub clamped_samples: u64,
}

/// Trains a guiding cache for `image`'s scene, adding the training's samples in `image.samples` (a part of
/// `0..TRAINING_SAMPLES`, empty for none) to the pixels of `film` (empty so far; `image` is the pass over its
/// window), on the caller's thread pool; `decision` is what the guiding mode decided (no cache when off). A
/// cancelled render stops training between blocks of rows and gets no cache (it renders no samples after it,
/// and the caller empties the film again); the time budget is not looked at here, the passes after it are (the
/// training's seconds count in the budget). A provisional decision (`auto`) is made by the pilot first
/// (see the module documentation); when it does not guide, the film holds at most its sample 0.
pub(super) fn train(image: &Pass<'_>, film: &mut Film, decision: GuidingDecision) -> Training {
    let mut training = Training {
        field: None,
        stats: GuidingStats {
            mode: if decision.on { "on" } else { "off" }.to_owned(),
            reason: decision.reason,
            ..GuidingStats::default()
        },
        counters: PathCounters::new(image.scene.media.len()),
        decided_off: false,
        in_film: 0..0,
        nan_samples: 0,
        clamped_samples: 0,
    };
    if !decision.on {
        return training;
    }
    let start = Instant::now();
    let keep = image.samples.clone();
    let (width, height) = (image.width, image.height);
    let stride = pilot_stride(width, height);
    // `auto`'s pilot is the first iteration where none of that iteration's paths is traced for the pilot alone.
    let first_is_pilot = decision.provisional
        && (stride == 1 || (keep.contains(&0) && image.window == PixelWindow::full(width, height)));
    if decision.provisional && !first_is_pilot {
        let (lattice, counters) = lattice_pilot(image, stride);
        training.counters.add(&counters);
        training.stats.training_paths += pilot_pixels(width, height, stride) as u64;
        let decided = decide(image, &lattice);
        if !note_decision(&mut training.stats, decided) {
            training.stats.training_seconds = start.elapsed().as_secs_f64();
            training.decided_off = true;
            return training;
        }
    }
    let stats = &mut training.stats;
    let mut field = GuidingField::new(image.scene.bounds);
    let keeps_values = image.tracer.guided_roulette;
    let mut pixels = keeps_values.then(|| PixelEstimates::new(width, height));
    let mut lattice = Vec::new();
    for k in 0..TRAINING_ITERATIONS {
        let samples = (1u32 << k) - 1..(2u32 << k) - 1;
        let pilot = (k == 0 && first_is_pilot).then_some(stride);
        // The window's rows, taken in order as the blocks reach them (none when no sample is kept).
        let mut film_rows = if keep.is_empty() {
            Vec::new()
        } else {
            film.rows_mut()
        }
        .into_iter();
        for block in (0..height).step_by(ROWS_PER_BLOCK) {
            if image.cancel.is_cancelled() {
                stats.training_seconds = start.elapsed().as_secs_f64();
                return training;
            }
            let pass = image.retargeted(image.services.with_guide(Some(&field)), samples.clone());
            let rows: Vec<(usize, Option<FilmRow<'_>>)> = (block
                ..(block + ROWS_PER_BLOCK).min(height))
                .map(|y| {
                    let in_window = (image.window.y0..image.window.y1).contains(&y);
                    (y, in_window.then(|| film_rows.next()).flatten())
                })
                .collect();
            let traced: Vec<TrainingRow> = rows
                .into_par_iter()
                .map(|(y, film_row)| pass.train_row(y, 1, film_row, &keep, keeps_values, pilot))
                .collect();
            for row in traced {
                stats.training_records += learn(&mut field, pixels.as_mut(), &row);
                training.counters.add(&row.counters);
                training.nan_samples += row.nan_samples;
                training.clamped_samples += row.clamped_samples;
                lattice.extend(row.pilot);
            }
        }
        stats.training_paths += (width * height) as u64 * samples.len() as u64;
        if pilot.is_some() {
            // Sample 0 of the window's pixels, where the film takes it, is there whatever the pilot decides.
            let in_film = if keep.contains(&0) { 0..1 } else { 0..0 };
            stats.pilot_samples_in_image = in_film.len() as u32;
            if !note_decision(stats, decide(image, &std::mem::take(&mut lattice))) {
                // The cache that learned from this iteration is dropped: no render learns from its records.
                stats.training_records = 0;
                stats.training_seconds = start.elapsed().as_secs_f64();
                training.decided_off = true;
                training.in_film = in_film;
                return training;
            }
        }
        field.finish_iteration();
        stats.training_samples_per_pixel += samples.len() as u32;
    }
    if let Some(pixels) = pixels {
        field.set_pixel_estimates(pixels);
    }
    stats.cells = field.cell_count();
    stats.guided_cells = field.guided_cell_count();
    stats.training_seconds = start.elapsed().as_secs_f64();
    stats.training_samples_in_image = keep.len() as u32;
    training.field = Some(field);
    training.in_film = keep;
    training
}

/// Writes what `auto`'s pilot decided into `stats` (`mode`, `reason`); returns whether it guides.
fn note_decision(stats: &mut GuidingStats, decided: GuidingDecision) -> bool {
    stats.mode = if decided.on { "on" } else { "off" }.to_owned();
    stats.reason = decided.reason;
    decided.on
}

/// Adds what one row's training paths found to the iteration under way of `field` (and their continuations to
/// `pixels`, for guided Russian roulette); returns the radiance records added.
fn learn(field: &mut GuidingField, pixels: Option<&mut PixelEstimates>, row: &TrainingRow) -> u64 {
    field.add_records(&row.records);
    field.add_lit_records(&row.lit);
    field.add_shadow_records(&row.shadow);
    field.add_shadow_records(&row.decoupled_shadow);
    field.add_shadow_records(&row.surface_shadow);
    if let Some(pixels) = pixels {
        for &(pixel, value) in &row.values {
            pixels.add(pixel, value);
        }
    }
    row.records.len() as u64
}

/// The pilot's stride along each axis for a frame of `width` × `height` pixels: the largest that still traces
/// [`AUTO_PILOT_PATHS`] pixels (1 for a smaller frame: every pixel), at most [`AUTO_PILOT_MAX_STRIDE`].
fn pilot_stride(width: usize, height: usize) -> usize {
    let mut stride = 1;
    while stride < AUTO_PILOT_MAX_STRIDE
        && pilot_pixels(width, height, stride + 1) >= AUTO_PILOT_PATHS
    {
        stride += 1;
    }
    stride
}

/// The pixels a pilot of `stride` traces in a frame of `width` × `height`: every `stride`-th along each axis,
/// from the first.
fn pilot_pixels(width: usize, height: usize, stride: usize) -> usize {
    width.div_ceil(stride) * height.div_ceil(stride)
}

/// What one row of `auto`'s pilot found at the pixels of its lattice (every [`pilot_stride`]-th pixel along
/// both axes): their paths' shadow rays, and the records of those that left medium scattering events and
/// decoupled samples.
#[derive(Default)]
pub(super) struct PilotRow {
    /// Shadow rays traced (of every kind).
    pub shadow_rays: u64,
    /// The records of the shadow rays of medium scattering events.
    pub shadow: Vec<LitRecord>,
    /// The records of the shadow rays of decoupled samples.
    pub decoupled_shadow: Vec<LitRecord>,
}

/// `auto`'s pilot where it is not the training's first iteration (a crop, or a part whose sample range does not
/// start at 0, in a frame of about 256² or more): sample 0 of the lattice's pixels alone, for no film. Returns their
/// rows' findings and their paths' work.
fn lattice_pilot(image: &Pass<'_>, stride: usize) -> (Vec<PilotRow>, PathCounters) {
    let empty = GuidingField::new(image.scene.bounds);
    let pass = image.retargeted(image.services.with_guide(Some(&empty)), 0..1);
    let rows: Vec<TrainingRow> = (0..image.height)
        .step_by(stride)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|y| pass.train_row(y, stride, None, &(0..0), false, Some(stride)))
        .collect();
    let mut counters = PathCounters::new(image.scene.media.len());
    let mut lattice = Vec::new();
    for row in rows {
        counters.add(&row.counters);
        lattice.extend(row.pilot);
    }
    (lattice, counters)
}

/// Whether `auto` guides `image`'s render ([`GuidingDecision::provisional`]), from its pilot: sample 0 of
/// every [`pilot_stride`]-th pixel along both axes of the whole frame, traced unguided, whose medium shadow
/// rays' records go on a shadow grid as the training's do ([`decide_from_shadow_pilot`]). `lattice` holds
/// the rows' findings in row order, so the decision is the same for any thread count and in every farm part.
///
/// The pilot's paths are traced exactly as the training's first iteration and the unguided image's sample 0
/// trace them. So where that iteration traces them anyway (a frame whose lattice is every pixel, or a whole
/// frame whose sample range starts at 0), it is the pilot: its sample 0 goes into the film whatever the pilot
/// decides, and its records into the cache when it guides. Elsewhere [`lattice_pilot`] traces the lattice alone.
fn decide(image: &Pass<'_>, lattice: &[PilotRow]) -> GuidingDecision {
    let mut grid = LitGrid::new(image.scene.bounds);
    for row in lattice {
        grid.add(&row.shadow);
        grid.add(&row.decoupled_shadow);
    }
    // Each ray is judged by the mean of the others in its voxel, as the image's rays are by the training's: a
    // mean that held the ray itself would predict too much of it where voxels hold few records.
    let traced_of = |records: &[LitRecord], min_survival: f32| -> f64 {
        records
            .iter()
            .map(|r| survival(grid.mean_without(r), min_survival) as f64)
            .sum()
    };
    let (mut traced, mut medium_shadow_rays, mut shadow_rays) = (0.0, 0, 0);
    for row in lattice {
        traced += traced_of(&row.shadow, SHADOW_MIN_SURVIVAL);
        traced += traced_of(&row.decoupled_shadow, VISIBILITY_MIN_SURVIVAL);
        medium_shadow_rays += (row.shadow.len() + row.decoupled_shadow.len()) as u64;
        shadow_rays += row.shadow_rays;
    }
    decide_from_shadow_pilot(image.settings.spp, shadow_rays, medium_shadow_rays, traced)
}

/// The training samples of a region of `samples` to add to its film, which holds its samples up to `complete`:
/// those of `0..TRAINING_SAMPLES` in the range from `complete` on.
pub(super) fn kept_samples(samples: &Range<u32>, complete: u32) -> Range<u32> {
    complete.max(samples.start)..samples.end.min(TRAINING_SAMPLES)
}

/// What the training paths of one row found: their records, their decoupled samples' records and their shadow
/// rays' (of medium collisions, decoupled samples and surfaces) and, for guided Russian roulette, each sample's
/// continuation (channel mean), pixel by pixel in order; the work of its paths, and its samples for the film
/// that were dropped or clamped.
pub(super) struct TrainingRow {
    /// The radiance records of the row's paths.
    pub records: Vec<RadianceRecord>,
    /// Their decoupled direct-light samples' records.
    pub lit: Vec<LitRecord>,
    /// Their medium collisions' shadow rays' records.
    pub shadow: Vec<LitRecord>,
    /// Their decoupled samples' shadow rays' records.
    pub decoupled_shadow: Vec<LitRecord>,
    /// Their surfaces' shadow rays' records.
    pub surface_shadow: Vec<LitRecord>,
    /// Each sample's continuation, by pixel (guided Russian roulette only).
    pub values: Vec<((usize, usize), f32)>,
    /// What the row's paths at the pixels of `auto`'s pilot lattice found, where the row is the pilot's.
    pub pilot: Option<PilotRow>,
    /// The work of the row's paths.
    pub counters: PathCounters,
    /// Samples for the film dropped as NaN or infinite.
    pub nan_samples: u64,
    /// Samples added to the film with a value clamped.
    pub clamped_samples: u64,
}

impl TrainingRow {
    /// An empty row's findings, in a scene of `media` media.
    pub fn new(media: usize) -> Self {
        Self {
            records: Vec::new(),
            lit: Vec::new(),
            shadow: Vec::new(),
            decoupled_shadow: Vec::new(),
            surface_shadow: Vec::new(),
            values: Vec::new(),
            pilot: None,
            counters: PathCounters::new(media),
            nan_samples: 0,
            clamped_samples: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::guiding::GuidingMode;
    use crate::integrator::{
        FirstEmission, MediumStack, PathContext, PathCounters, PathSample, PathTracer,
        RendererServices,
    };
    use crate::light::EnvironmentLight;
    use crate::math::{Rgb, Vec3};
    use crate::math::{Rng, Vec2};
    use crate::render::{RenderSettings, Renderer};
    use crate::scene::Scene;
    use crate::scene::{Camera, SceneBuilder};
    use crate::vdb::{GridTree, Tree};
    use crate::volume::density::GridDensity;
    use crate::volume::grid::GridMedium;
    use crate::volume::majorant::MajorantKind;
    use glam::{DMat4, DVec3, IVec3};
    use std::sync::Arc;

    /// The pilot traces at least [`AUTO_PILOT_PATHS`] pixels where the frame has them (every pixel of a
    /// smaller frame) and never fewer than a sixteenth of them.
    #[test]
    fn the_pilot_traces_enough_paths_at_every_image_size() {
        use super::{pilot_pixels, pilot_stride, AUTO_PILOT_MAX_STRIDE};
        use crate::guiding::pilot::AUTO_PILOT_PATHS;
        let traced = |w: usize, h: usize| pilot_pixels(w, h, pilot_stride(w, h));
        assert_eq!(pilot_stride(64, 64), 1);
        assert_eq!(pilot_stride(128, 128), 1);
        assert_eq!(pilot_stride(256, 256), 2);
        assert_eq!(pilot_stride(384, 384), 3);
        assert_eq!(pilot_stride(512, 512), 4);
        assert_eq!(pilot_stride(1920, 1080), AUTO_PILOT_MAX_STRIDE);
        for (w, h) in [
            (1, 1),
            (100, 30),
            (200, 90),
            (255, 257),
            (640, 360),
            (4096, 2160),
        ] {
            let n = traced(w, h);
            assert!(n >= AUTO_PILOT_PATHS.min(w * h), "{w}x{h}: {n}");
            assert!(n * 16 >= w * h, "{w}x{h}: {n}");
        }
    }

    /// A white furnace: a smooth ball (radius 0.75, density 10 at its middle, albedo 1, g 0.4) in a uniform
    /// environment of radiance 1, seen through its middle. Every path sees exactly 1 on average.
    fn furnace() -> Scene {
        let voxels = (-12..=12).flat_map(|x| {
            (-12..=12).flat_map(move |y| {
                (-12..=12).filter_map(move |z| {
                    let r = ((x * x + y * y + z * z) as f32).sqrt() / 12.0;
                    (r < 1.0).then(|| (IVec3::new(x, y, z), (1.0 - r * r).powi(2)))
                })
            })
        });
        let density = GridDensity::from_tree(
            Arc::new(GridTree::Float(Tree::from_voxels(0.0, voxels))),
            DMat4::from_scale(DVec3::splat(0.0625)),
            10.0,
        )
        .unwrap();
        let mut b = SceneBuilder::default();
        let medium = GridMedium::new("ball", density, MajorantKind::Adaptive, Rgb::ONE, 0.4);
        b.add_medium(Arc::new(medium));
        b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
        b.set_camera(Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 0.3));
        b.build().unwrap()
    }

    /// Traces `n` paths through the middle of the image; returns the mean of the red channel, its standard
    /// error and the counters.
    fn trace_middle(
        scene: &Scene,
        tracer: &PathTracer,
        services: &RendererServices,
        n: u64,
    ) -> (f64, f64, PathCounters) {
        let mut counters = PathCounters::new(scene.media.len());
        let ray = scene.camera.sample_ray(Vec2::splat(0.5), None, 1.0, None);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for i in 0..n {
            let mut rng = Rng::for_sample(5, 0, i);
            let mut cx = PathContext {
                services,
                rng: &mut rng,
                counters: &mut counters,
            };
            let PathSample { radiance, .. } =
                tracer.trace(&mut cx, ray, FirstEmission::Count, None, None);
            sum += radiance.x as f64;
            sum2 += (radiance.x as f64).powi(2);
        }
        let mean = sum / n as f64;
        (
            mean,
            ((sum2 / n as f64 - mean * mean) / n as f64).sqrt(),
            counters,
        )
    }

    /// A plain path tracer (no pixel footprint, no equiangular sampling, opaque, no mattes) of `max_depth`
    /// bounces, with or without guided Russian roulette, its camera outside every medium.
    fn furnace_tracer(max_depth: u32, guided_roulette: bool) -> PathTracer {
        PathTracer {
            max_depth,
            media_mis: true,
            pixel_spread: 0.0,
            pixel_width: 0.0,
            equiangular: false,
            decoupled: false,
            transparent: false,
            mattes: false,
            guided_roulette,
            camera_media: MediumStack::default(),
        }
    }

    /// A renderer of a `size`² frame of seed 3 whose paths are those of [`furnace_tracer`] (`max_depth`
    /// bounces, with or without guided Russian roulette), guiding on.
    fn furnace_renderer(size: usize, max_depth: u32, guided_roulette: bool) -> Renderer {
        Renderer::new(RenderSettings {
            width: size,
            height: size,
            seed: 3,
            max_depth,
            equiangular: false,
            decoupled: false,
            guiding: GuidingMode::On,
            guided_roulette,
            ..RenderSettings::default()
        })
    }

    /// The training keeps its samples' values as pixel estimates only for guided Russian roulette, their only
    /// reader: a render without it does no such work.
    #[test]
    fn pixel_estimates_are_kept_only_for_guided_roulette() {
        let scene = furnace();
        for guided_roulette in [false, true] {
            let field = furnace_renderer(4, 64, guided_roulette).trained_guide(&scene);
            let estimate = field.pixel_estimate((2, 2));
            assert_eq!(estimate.is_some(), guided_roulette, "{estimate:?}");
        }
    }

    /// Guided Russian roulette and splitting keep the white furnace's mean, 1, within 4 standard errors where
    /// the pixel value they compare with is far too low (every event splits, up to the sample's budget) and far
    /// too high (roulette ends most paths): the weights 1/n and 1/q are what keeps it (forgetting 1/q fails
    /// this test).
    #[test]
    fn guided_roulette_and_splitting_keep_the_white_furnace() {
        let scene = furnace();
        let tracer = furnace_tracer(100_000, true);
        let services = RendererServices::new(&scene, false);
        let field = furnace_renderer(16, 100_000, true).trained_guide(&scene);
        let guided = services.with_guide(Some(&field));
        let (_, _, plain) = trace_middle(&scene, &tracer, &guided, 1000);
        for pixel in [0.02f32, 50.0] {
            let services = guided.with_pixel_estimate(Some(pixel));
            let (mean, se, counters) = trace_middle(&scene, &tracer, &services, 3000);
            assert!(se > 0.0 && se < 0.25, "pixel {pixel}: standard error {se}");
            assert!(
                (mean - 1.0).abs() < 4.0 * se,
                "pixel {pixel}: {mean} vs 1 (se {se})"
            );
            if pixel < 1.0 {
                assert!(counters.rays.split > 3000, "{:?}", counters.rays);
            } else {
                assert_eq!(counters.rays.split, 0);
                assert!(
                    counters.rays.bounce < plain.rays.bounce / 2,
                    "{:?}",
                    counters.rays
                );
            }
        }
    }
}
