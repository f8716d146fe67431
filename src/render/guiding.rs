//! The guiding cache's training: a fixed pre-pass of samples of its own before the image's (Müller et al. 2017,
//! "Practical Path Guiding for Efficient Light-Transport Simulation": iterations of doubling sample
//! counts, each guided by the cache of the one before, the last cache guiding the image).
//!
//! Determinism: iteration k takes `2^k` samples of every pixel of the whole frame, whatever the region a part
//! renders, from streams of their own (`seed` mixed with [`TRAINING_STREAM`] and k, the independent sampler);
//! rows are traced in parallel a block at a time and their records added to the cache in row order, one thread.
//! The cache, and so the image, is the same for any thread count and in every farm part of a render.
//!
//! With guided Russian roulette on ([`PathTracer::guided_roulette`]), the training's samples also give the pixel
//! values it compares paths with ([`PixelEstimates`], every iteration's samples: each sample's continuation
//! after its first remembered event's next-event estimate, [`GuidePath::continuation`], an unbiased estimate of
//! that part of its pixel), summed in the same row order; without it they are not kept.

use super::renderer::GuidingStats;
use super::CancelToken;
use crate::guiding::adjoint::PixelEstimates;
use crate::guiding::{
    GuidePath, GuidingDecision, GuidingField, LitRecord, RadianceRecord, TRAINING_ITERATIONS,
};
use crate::integrator::{FirstEmission, PathContext, PathCounters, PathTracer, RendererServices};
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
    let mut pixels = tracer
        .guided_roulette
        .then(|| PixelEstimates::new(frame.width, frame.height));
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
                field.add_lit_records(&row.lit);
                field.add_shadow_records(&row.shadow);
                if let Some(pixels) = pixels.as_mut() {
                    for &(pixel, value) in &row.values {
                        pixels.add(pixel, value);
                    }
                }
            }
        }
        field.finish_iteration();
        stats.training_paths += (frame.width * frame.height) as u64 * spp as u64;
        stats.training_samples_per_pixel += spp;
    }
    if let Some(pixels) = pixels {
        field.set_pixel_estimates(pixels);
    }
    stats.cells = field.cell_count();
    stats.guided_cells = field.guided_cell_count();
    stats.training_seconds = start.elapsed().as_secs_f64();
    (Some(field), stats)
}

/// What the training paths of one row found: their records, their decoupled samples' and medium shadow rays'
/// records and, for guided Russian roulette, each sample's continuation (channel mean), pixel by pixel in order.
struct TrainingRow {
    records: Vec<RadianceRecord>,
    lit: Vec<LitRecord>,
    shadow: Vec<LitRecord>,
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
    let mut lit = Vec::new();
    let mut shadow = Vec::new();
    // Only guided Russian roulette reads the samples' values (as its pixel estimates).
    let keeps_values = tracer.guided_roulette;
    let mut values = Vec::with_capacity(keeps_values as usize * frame.width * spp as usize);
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
            let mut cx = PathContext {
                services,
                rng: &mut rng,
                counters: &mut counters,
            };
            let result = tracer.trace(&mut cx, ray, FirstEmission::Count, None, Some(&mut path));
            lit.extend_from_slice(path.lit());
            shadow.extend_from_slice(path.shadow());
            if result.radiance.is_finite() {
                path.finish(result.radiance, &mut records);
                if keeps_values {
                    let continued = path.continuation(result.radiance);
                    values.push(((x, y), continued.element_sum() / 3.0));
                }
            }
        }
    }
    TrainingRow {
        records,
        lit,
        shadow,
        values,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::{MediumStack, PathSample};
    use crate::light::EnvironmentLight;
    use crate::math::{Rgb, Vec3};
    use crate::scene::{Camera, SceneBuilder};
    use crate::vdb::{GridTree, Tree};
    use crate::volume::density::GridDensity;
    use crate::volume::grid::GridMedium;
    use crate::volume::majorant::MajorantKind;
    use glam::{DMat4, DVec3, IVec3};
    use std::sync::Arc;

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

    /// The training keeps its samples' values as pixel estimates only for guided Russian roulette, their only
    /// reader: a render without it does no such work.
    #[test]
    fn pixel_estimates_are_kept_only_for_guided_roulette() {
        let scene = furnace();
        let services = RendererServices::new(&scene, false);
        let frame = TrainingFrame {
            width: 4,
            height: 4,
            seed: 3,
        };
        for guided_roulette in [false, true] {
            let tracer = furnace_tracer(64, guided_roulette);
            let decision = GuidingDecision {
                on: true,
                reason: String::new(),
            };
            let (field, _) = train(
                &scene,
                &tracer,
                &services,
                &frame,
                decision,
                &CancelToken::new(),
            );
            let estimate = field.unwrap().pixel_estimate((2, 2));
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
        let frame = TrainingFrame {
            width: 16,
            height: 16,
            seed: 3,
        };
        let decision = GuidingDecision {
            on: true,
            reason: String::new(),
        };
        let cancel = CancelToken::new();
        let (field, _) = train(&scene, &tracer, &services, &frame, decision, &cancel);
        let field = field.unwrap();
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
