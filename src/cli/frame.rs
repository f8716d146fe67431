//! One frame of `nimbus render`, in its phases: load the scene, settle the render settings, plan the region
//! (a whole frame or a farm part), render (resumable, with previews and checkpoints), and write the outputs and
//! the statistics.

use crate::{
    check_image_size, create_parent, explain_volume_sampling, finish_render, frame_path,
    image_metadata, load_builder, part_region, part_scene_hash, remove_checkpoint, resume_from,
    signal_name, write_image, write_progress_preview, LoadingPhase, ProgressReporter, RenderArgs,
    VolumeSampling, STOP_SIGNAL,
};
use nimbus::farm::checkpoint::write_checkpoint;
use nimbus::farm::PartInfo;
use nimbus::light::EnvironmentLight;
use nimbus::limits::{one_line, MAX_MESSAGE_CHARS};
use nimbus::render::resume::RegionProgress;
use nimbus::render::{
    CancelToken, Film, GuidingMode, PixelWindow, Progress, RenderRegion, RenderSettings,
    RenderStats, Renderer,
};
use nimbus::scene::{Scene, SceneBuilder, DEFAULT_ENVIRONMENT_RADIANCE};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Loads, renders and writes one frame (`None`: a still).
pub(crate) fn render_frame(
    args: &RenderArgs,
    frame: Option<i64>,
    reporter: &mut ProgressReporter,
    cancel: &CancelToken,
) -> Result<(), String> {
    let output = frame_path(&args.output, frame);
    let stats_path = args.stats.as_deref().map(|s| frame_path(s, frame));
    let scene = load_scene(args, frame)?;
    if args.explain {
        explain_scene(args, &scene);
    }
    let settings = frame_settings(args, &scene)?;
    announce(args, &scene, &settings);
    let renderer = Renderer::new(settings);
    let job = FrameJob::plan(args, frame, &scene, &renderer, output, stats_path)?;
    let (film, stats, progress) = job.render(reporter, cancel)?;
    if args.explain && args.guiding == GuidingMode::Auto {
        // Before rendering `--explain` could only say how `auto` would decide; its pilot has decided now.
        eprintln!("nimbus: path guiding decided: {}", stats.guiding.reason);
    }
    let stop = STOP_SIGNAL.load(Ordering::SeqCst);
    // A signal that came after the last pass stops nothing: the render is written as finished.
    let finished = progress.complete == job.region.samples.end;
    if stats.cancelled && stop != 0 && !finished {
        return Err(job.write_stopped(&film, stats, &progress, signal_name(stop)));
    }
    job.write_finished(&film, &stats)
}

/// Loads the frame's scene, applies `--camera` and `--env-color`, says how it is lit, builds it and prints its
/// warnings; a signal meanwhile ends the process at once ([`LoadingPhase`]).
fn load_scene(args: &RenderArgs, frame: Option<i64>) -> Result<Scene, String> {
    let loading = LoadingPhase::start();
    let mut builder = load_builder(args, frame, args.shutter)?;
    if let Some(name) = &args.camera {
        builder.select_camera(name).map_err(|e| {
            let file = args
                .scene
                .as_deref()
                .unwrap_or(Path::new("assets/cloud.gltf"));
            format!("{}: --camera: {e}", file.display())
        })?;
    }
    if let Some(c) = args.env_color {
        builder.set_environment(EnvironmentLight::Constant(c));
    }
    report_lighting(&mut builder);
    let scene: Scene = builder.build().map_err(|e| e.to_string())?;
    drop(loading);
    for w in scene.warnings() {
        eprintln!("nimbus: warning: {}", one_line(w, MAX_MESSAGE_CHARS));
    }
    Ok(scene)
}

/// Says whether the scene gets the default white environment (it has no light of its own) or none (it
/// lights itself).
fn report_lighting(builder: &mut SceneBuilder) {
    let lighting = builder.own_lighting();
    if builder.light_by_default() {
        let textured = match lighting.textured_emissive_meshes {
            0 => String::new(),
            n => format!(
                " ({n} mesh(es) with textured emission glow but do not count: such emission is detail, which \
                 glTF viewers show under their own environment)"
            ),
        };
        eprintln!(
            "nimbus: the scene has no light of its own{textured}, so a uniform white environment of radiance \
             {DEFAULT_ENVIRONMENT_RADIANCE} lights it (a nimbus_environment or --env-color 0,0,0 keeps it dark)"
        );
    } else if !lighting.environment {
        eprintln!(
            "nimbus: the scene lights itself ({}), so it gets no default environment (--env-color 1,1,1 adds the \
             white one)",
            lighting.describe()
        );
    }
}

/// `--explain`'s lines on the scene: its media, volume sampling, the light sampler and motion blur.
fn explain_scene(args: &RenderArgs, scene: &Scene) {
    for line in scene.explain_media() {
        eprintln!("nimbus: {line}");
    }
    explain_volume_sampling(scene, args.volume_sampling);
    eprintln!(
        "nimbus: light sampler: {}",
        args.light_sampler.explain(scene)
    );
    if let Some(shutter) = scene.shutter() {
        eprintln!(
            "nimbus: motion blur: shutter {} frames (box), {} moving triangles, the camera {}",
            shutter,
            scene.moving_triangle_count(),
            if scene.camera().is_moving() {
                "moves"
            } else {
                "stands still"
            }
        );
    }
}

/// The render settings of the frame from the flags: its size (checked), the time limit and the samples per
/// pixel (unlimited under a time limit without `--spp`, else 64 by default).
fn frame_settings(args: &RenderArgs, scene: &Scene) -> Result<RenderSettings, String> {
    let (width, height) = RenderSettings::frame_size(scene, args.image.width, args.image.height);
    check_image_size(width, height)?;
    let time_limit = match args.time_limit {
        Some(t) => Some(Duration::try_from_secs_f64(t).map_err(|_| {
            format!("--time-limit {t} is not a non-negative number of seconds that fits a duration")
        })?),
        None => None,
    };
    let spp = args
        .spp
        .unwrap_or(if time_limit.is_some() { u32::MAX } else { 64 });
    Ok(RenderSettings {
        width,
        height,
        spp,
        seed: args.image.seed,
        threads: args.image.threads,
        max_depth: RenderSettings::max_depth_for(scene, args.max_depth),
        time_limit,
        media_mis: true,
        equiangular: args.volume_sampling == VolumeSampling::Mis,
        decoupled: args.volume_sampling == VolumeSampling::Mis,
        sampler: args.sampler,
        light_sampler: args.light_sampler,
        emitter_edges: args.emitter_edges,
        limits: args.limits(),
        aovs: args.aovs.clone(),
        transparent: args.transparent,
        light_groups: args.light_groups,
        cryptomatte_depth: args.cryptomatte_depth,
        deep_samples: args.deep.then_some(args.deep_samples as usize),
        guiding: args.guiding,
        guided_roulette: args.guided_roulette,
    })
}

/// `--explain`'s lines on emitter edges and path guiding, then the render's one-line summary (triangles, lights,
/// size, samples, time limit).
fn announce(args: &RenderArgs, scene: &Scene, settings: &RenderSettings) {
    let (width, height) = (settings.width, settings.height);
    if args.explain {
        eprintln!(
            "nimbus: emitter edges: {}",
            args.emitter_edges.explain(scene, width, height)
        );
        eprintln!("nimbus: path guiding: {}", args.guiding.explain(scene));
    }
    eprintln!(
        "nimbus: {} triangles, {}, {width}x{height}, {} spp{}",
        scene.triangle_count(),
        scene.describe_lights(),
        if settings.spp == u32::MAX {
            "unlimited".to_string()
        } else {
            settings.spp.to_string()
        },
        settings.time_limit.map_or(String::new(), |t| format!(
            ", time limit {:.1} s",
            t.as_secs_f64()
        ))
    );
}

/// One frame's render once planned: its scene and renderer, the region it covers and where it writes.
struct FrameJob<'a> {
    args: &'a RenderArgs,
    frame: Option<i64>,
    scene: &'a Scene,
    renderer: &'a Renderer,
    /// The scene hash that parts and checkpoints carry ([`part_scene_hash`]).
    hash: u64,
    /// The pixels and samples rendered: the whole frame, or a farm part's.
    region: RenderRegion,
    /// The EXR written (a chunk's own file for `--chunk-from-env`).
    output: PathBuf,
    /// Whether this is a farm part (`--samples`, `--crop`, `--chunk-from-env`).
    is_part: bool,
    /// The checkpoint file beside the output.
    checkpoint: PathBuf,
    /// Where `--stats` writes the statistics of this frame.
    stats_path: Option<PathBuf>,
}

impl<'a> FrameJob<'a> {
    /// Checks the layers against `--compression`, hashes the scene and settles the region (a part's, or the
    /// whole frame's).
    fn plan(
        args: &'a RenderArgs,
        frame: Option<i64>,
        scene: &'a Scene,
        renderer: &'a Renderer,
        output: PathBuf,
        stats_path: Option<PathBuf>,
    ) -> Result<Self, String> {
        let plan = renderer.layer_plan(scene).map_err(|e| e.to_string())?;
        if args.storage.compression == nimbus::output::ExrCompression::Pxr24
            && !plan.cryptomatte.is_empty()
        {
            return Err("--compression pxr24 rounds 32-bit floats to 24 bits, which destroys Cryptomatte IDs; use zip, piz, rle or none".into());
        }
        let settings = renderer.settings();
        let hash = part_scene_hash(args, frame, settings, scene)?;
        let part = part_region(args, &output, settings)?;
        let is_part = part.is_some();
        let (region, output) = part.unwrap_or_else(|| {
            let whole = RenderRegion {
                window: PixelWindow::full(settings.width, settings.height),
                samples: 0..settings.spp.max(1),
            };
            (whole, output)
        });
        if is_part {
            eprintln!(
                "nimbus: part: samples {}..{} of the pixels in {}",
                region.samples.start, region.samples.end, region.window
            );
        }
        let checkpoint = nimbus::farm::checkpoint::checkpoint_path(&output);
        Ok(Self {
            args,
            frame,
            scene,
            renderer,
            hash,
            region,
            output,
            is_part,
            checkpoint,
            stats_path,
        })
    }

    /// What a checkpoint of this render says of it (its sample counters filled in when one is written).
    fn checkpoint_info(&self) -> PartInfo {
        PartInfo {
            estimators: PartInfo::estimators_of(self.scene),
            ..PartInfo::new(
                self.renderer.settings(),
                self.hash,
                &self.region,
                &RenderStats::default(),
            )
        }
    }

    /// Renders the region (from the checkpoint with `--resume`), reporting progress, writing previews and
    /// checkpoints as it goes.
    fn render(
        &self,
        reporter: &mut ProgressReporter,
        cancel: &CancelToken,
    ) -> Result<(Film, RenderStats, RegionProgress), String> {
        let from = resume_from(
            self.args,
            &self.checkpoint,
            self.scene,
            self.renderer.settings(),
            self.hash,
            &self.region,
        )?;
        let mut on_pass = self.on_pass(reporter);
        let rendered = self
            .renderer
            .render_resumable(self.scene, &self.region, from, &mut on_pass, cancel)
            .map_err(|e| e.to_string())?;
        drop(on_pass);
        reporter.finish();
        Ok(rendered)
    }

    /// The callback after each pass: reports progress and, while samples remain, writes the `--preview-every`
    /// preview and the `--checkpoint` checkpoint when they are due (a failed write is a warning).
    fn on_pass<'r>(
        &'r self,
        reporter: &'r mut ProgressReporter,
    ) -> impl FnMut(&Progress, &Film) -> bool + 'r {
        let checkpoint_info = self.checkpoint_info();
        let interval = self.args.checkpoint.map(Duration::from_secs_f64);
        let mut last_checkpoint = Instant::now();
        let preview_every = self.args.preview_every.map(Duration::from_secs_f64);
        let mut last_preview = Instant::now();
        let preview = nimbus::output::preview_path(&self.output);
        move |p: &Progress, film: &Film| {
            let go_on = reporter.report(p);
            let complete = self.region.samples.start + p.samples_done;
            let remaining = complete < self.region.samples.end;
            if let Some(every) = preview_every.filter(|_| remaining) {
                if last_preview.elapsed() >= every {
                    if let Err(e) = write_progress_preview(self.args, &film.image(), &preview) {
                        eprintln!(
                            "nimbus: warning: preview not written: {}",
                            one_line(&e, MAX_MESSAGE_CHARS)
                        );
                    }
                    last_preview = Instant::now();
                }
            }
            if let Some(interval) = interval.filter(|_| remaining) {
                if last_checkpoint.elapsed() >= interval {
                    let info = PartInfo {
                        nan_samples: p.nan_samples,
                        clamped_samples: p.clamped_samples,
                        ..checkpoint_info.clone()
                    };
                    let progress = RegionProgress::start(complete);
                    if let Err(e) = write_checkpoint(&self.checkpoint, film, &info, &progress) {
                        eprintln!(
                            "nimbus: warning: checkpoint not written: {}",
                            one_line(&e.to_string(), MAX_MESSAGE_CHARS)
                        );
                    }
                    last_checkpoint = Instant::now();
                }
            }
            go_on
        }
    }

    /// A render stopped by `signal` before its last sample: writes a checkpoint (with `--checkpoint` or for a
    /// part) or the partial image and its statistics, and returns the error that says what was written.
    fn write_stopped(
        &self,
        film: &Film,
        mut stats: RenderStats,
        progress: &RegionProgress,
        signal: &str,
    ) -> String {
        let samples = &self.region.samples;
        if progress.is_empty(samples.start) {
            return format!("stopped by {signal} before any sample was taken; nothing written");
        }
        let complete = progress.complete - samples.start;
        if self.args.checkpoint.is_some() || self.is_part {
            let info = PartInfo {
                nan_samples: stats.nan_samples,
                clamped_samples: stats.clamped_samples,
                ..self.checkpoint_info()
            };
            if let Err(e) = write_checkpoint(&self.checkpoint, film, &info, progress) {
                return e.to_string();
            }
            return format!(
                "stopped by {signal}: wrote checkpoint {} ({complete} of {} samples in every pixel); continue with --resume",
                self.checkpoint.display(),
                samples.len()
            );
        }
        stats.partial = true;
        stats.interrupted_by = Some(signal.to_owned());
        let mut image = film.image();
        image.metadata = self.metadata(&stats);
        let nimbus_attributes = &mut image.metadata.nimbus;
        nimbus_attributes.insert("spp".into(), complete.to_string());
        nimbus_attributes.insert("partial".into(), "true".into());
        nimbus_attributes.insert("interrupted_by".into(), signal.to_owned());
        let written = write_image(self.args, &image, &self.output)
            .and_then(|()| finish_render(&stats, self.stats_path.as_deref()));
        match written {
            Err(e) => e,
            Ok(()) => format!(
                "stopped by {signal}: wrote the partial image {} ({complete} of {} samples in every pixel; nimbus/partial in its header)",
                self.output.display(),
                samples.len()
            ),
        }
    }

    /// A finished render: writes the part file or the image (EXR and PNG), removes the checkpoint and writes the
    /// statistics.
    fn write_finished(&self, film: &Film, stats: &RenderStats) -> Result<(), String> {
        let metadata = self.metadata(stats);
        let output = &self.output;
        if self.is_part {
            let info = PartInfo::new(self.renderer.settings(), self.hash, &self.region, stats)
                .with_metadata(metadata);
            create_parent(output)?;
            nimbus::farm::write_part(output, film, &info).map_err(|e| e.to_string())?;
            eprintln!(
                "nimbus: wrote part {} ({} spp in {:.2} s, {:.0} samples/s)",
                output.display(),
                stats.samples_per_pixel,
                stats.render_seconds,
                stats.samples_per_second
            );
        } else {
            let mut image = film.image();
            image.metadata = metadata;
            image
                .metadata
                .nimbus
                .insert("spp".into(), stats.samples_per_pixel.to_string());
            write_image(self.args, &image, output)?;
            eprintln!(
                "nimbus: wrote {} and {} ({} spp in {:.2} s, {:.0} samples/s)",
                output.display(),
                nimbus::output::preview_path(output).display(),
                stats.samples_per_pixel,
                stats.render_seconds,
                stats.samples_per_second
            );
        }
        remove_checkpoint(&self.checkpoint)?;
        finish_render(stats, self.stats_path.as_deref())
    }

    /// The EXR header attributes of this render with `stats`.
    fn metadata(&self, stats: &RenderStats) -> nimbus::render::ImageMetadata {
        image_metadata(
            self.args,
            self.scene,
            self.renderer.settings(),
            self.frame,
            self.hash,
            stats,
        )
    }
}
