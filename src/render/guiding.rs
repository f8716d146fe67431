//! The guiding cache's training: a fixed pre-pass of samples of its own before the image's (Müller et al. 2017,
//! "Practical Path Guiding for Efficient Light-Transport Simulation": iterations of doubling sample
//! counts, each guided by the cache of the one before, the last cache guiding the image).
//!
//! Determinism: iteration k takes `2^k` samples of every pixel of the whole frame, whatever the region a part
//! renders, from streams of their own (`seed` mixed with [`TRAINING_STREAM`] and k, the independent sampler);
//! rows are traced in parallel a block at a time and their records added to the cache in row order, one thread.
//! The cache, and so the image, is the same for any thread count and in every farm part of a render.
//!
//! The training's samples are also the pixel values guided Russian roulette compares paths with
//! ([`PixelEstimates`], every iteration's samples: each is an unbiased estimate of its pixel), summed in the
//! same row order.

use super::renderer::GuidingStats;
use super::CancelToken;
use crate::guiding::adjoint::PixelEstimates;
use crate::guiding::{
    GuidePath, GuidingDecision, GuidingField, RadianceRecord, TRAINING_ITERATIONS,
};
use crate::integrator::{FirstEmission, PathCounters, PathTracer, RendererServices};
use crate::math::{Rng, Vec2};
use crate::scene::Scene;
use rayon::prelude::*;
use std::time::Instant;

/// Mixed into the seed of the training streams (the next 64 bits of π's fraction after the renderer's).
const TRAINING_STREAM: u64 = 0xa409_3822_299f_31d0;
/// Rows traced in parallel before their records are added (bounds the records held at once).
const ROWS_PER_BLOCK: usize = 16;

/// The frame training paths are shot through, and the seed their streams are mixed from.
pub(super) struct TrainingFrame {
    /// Frame width in pixels.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// The render's seed.
    pub seed: u64,
}

/// Trains a guiding cache for `scene` with `tracer` (on the caller's thread pool) and says what it did;
/// `decision` is what the guiding mode decided (no cache when off). A cancelled render stops training between
/// blocks of rows and gets no cache (it renders no samples after it); the time budget is not looked at here, the
/// passes after it are (the training's seconds count in the budget).
pub(super) fn train(
    scene: &Scene,
    tracer: &PathTracer,
    services: &RendererServices,
    frame: &TrainingFrame,
    decision: GuidingDecision,
    cancel: &CancelToken,
) -> (Option<GuidingField>, GuidingStats) {
    let mut stats = GuidingStats {
        mode: if decision.on { "on" } else { "off" }.to_owned(),
        reason: decision.reason,
        ..GuidingStats::default()
    };
    if !decision.on {
        return (None, stats);
    }
    let start = Instant::now();
    let mut field = GuidingField::new(scene.bounds);
    let mut pixels = PixelEstimates::new(frame.width, frame.height);
    for k in 0..TRAINING_ITERATIONS {
        let spp = 1u32 << k;
        let seed = frame.seed ^ TRAINING_STREAM ^ k as u64;
        for block in (0..frame.height).step_by(ROWS_PER_BLOCK) {
            if cancel.is_cancelled() {
                stats.training_seconds = start.elapsed().as_secs_f64();
                return (None, stats);
            }
            let rows = block..(block + ROWS_PER_BLOCK).min(frame.height);
            let guided = services.with_guide(Some(&field));
            let traced: Vec<TrainingRow> = rows
                .into_par_iter()
                .map(|y| trace_row(tracer, &guided, frame, y, spp, seed))
                .collect();
            for row in &traced {
                stats.training_records += row.records.len() as u64;
                field.add_records(&row.records);
                for &(pixel, value) in &row.values {
                    pixels.add(pixel, value);
                }
            }
        }
        field.finish_iteration();
        stats.training_paths += (frame.width * frame.height) as u64 * spp as u64;
        stats.training_samples_per_pixel += spp;
    }
    field.set_pixel_estimates(pixels);
    stats.cells = field.cell_count();
    stats.guided_cells = field.guided_cell_count();
    stats.training_seconds = start.elapsed().as_secs_f64();
    (Some(field), stats)
}

/// What the training paths of one row found: their records and each sample's value (channel mean), pixel by
/// pixel in order.
struct TrainingRow {
    records: Vec<RadianceRecord>,
    values: Vec<((usize, usize), f32)>,
}

/// Traces `spp` training paths through every pixel of row `y` (samples from `seed`'s streams).
fn trace_row(
    tracer: &PathTracer,
    services: &RendererServices,
    frame: &TrainingFrame,
    y: usize,
    spp: u32,
    seed: u64,
) -> TrainingRow {
    let scene = services.scene();
    let aspect = frame.width as f32 / frame.height as f32;
    let mut counters = PathCounters::new(scene.media.len());
    let mut path = GuidePath::default();
    let mut records = Vec::new();
    let mut values = Vec::with_capacity(frame.width * spp as usize);
    for x in 0..frame.width {
        let pixel_index = (y * frame.width + x) as u64;
        for sample in 0..spp {
            let mut rng = Rng::for_sample(seed, pixel_index, sample as u64);
            let time = scene.shutter.map(|shutter| shutter.time_at(rng.next_f32()));
            let jitter = rng.sample_2d();
            let lens = scene.camera.lens.is_some().then(|| rng.sample_2d());
            let film = Vec2::new(
                (x as f32 + jitter.x) / frame.width as f32,
                (y as f32 + jitter.y) / frame.height as f32,
            );
            let ray = scene.camera.sample_ray(film, lens, aspect, time);
            path.clear();
            let result = tracer.trace(
                services,
                ray,
                FirstEmission::Count,
                &mut rng,
                &mut counters,
                None,
                Some(&mut path),
            );
            if result.radiance.is_finite() {
                path.finish(result.radiance, &mut records);
                values.push(((x, y), result.radiance.element_sum() / 3.0));
            }
        }
    }
    TrainingRow { records, values }
}
