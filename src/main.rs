//! The `nimbus` command line: `render` a scene (or a part of it) to EXR + PNG, `merge` parts, `info` about a VDB
//! file, `converge` charts.

mod cli;

use clap::{Args, Parser, Subcommand};
use cli::frame::render_frame;
use nimbus::farm::checkpoint::read_checkpoint;
use nimbus::farm::{FarmError, PartInfo};
use nimbus::frames::{has_frame_token, with_frame, FrameRange, Shutter};
use nimbus::limits::{one_line, Limits, MAX_MESSAGE_CHARS};
use nimbus::math::Rgb;
use nimbus::output::Exposure;
use nimbus::params::Choice;
use nimbus::render::resume::ResumeFrom;
use nimbus::render::{
    CancelToken, PixelWindow, Progress, RenderImage, RenderRegion, RenderSettings, RenderStats,
};
use nimbus::scene::{LoadOptions, Scene, SceneBuilder};
use std::io::IsTerminal;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
#[cfg(feature = "denoise")]
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "nimbus",
    version,
    about = "A volumetric path tracer for glTF/OBJ/USD scenes with OpenVDB volumes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene (.gltf, .glb, .obj, .usd, .usda, .usdc, .usdz) to an EXR with AOV layers and a PNG preview.
    #[command(allow_negative_numbers = true)]
    Render(Box<RenderArgs>),
    /// Describe the grids of an OpenVDB file: counts, statistics, bounds and transform.
    #[command(allow_negative_numbers = true)]
    Info(InfoArgs),
    /// Compare methods' error against a reference over render time: CSV, log-log chart, summary.
    #[command(allow_negative_numbers = true)]
    Converge(ConvergeArgs),
    /// Merge parts rendered with --samples, --crop or --chunk-from-env into the image of the whole render, bit
    /// for bit; refuses parts of different renders, overlapping parts and gaps.
    #[command(allow_negative_numbers = true)]
    Merge(MergeArgs),
    /// Denoise a merged frame with Intel Open Image Denoise (beauty guided by its albedo and normal layers):
    /// writes the EXR with a `denoised` layer added and its PNG preview. Needs a build with the `denoise`
    /// feature.
    #[command(allow_negative_numbers = true)]
    Denoise(DenoiseArgs),
}

#[derive(Args)]
struct DenoiseArgs {
    /// The frame's EXR, as `nimbus render` or `nimbus merge` wrote it (beauty, albedo and normal layers).
    input: PathBuf,
    /// Output EXR (may be the input, which is then replaced atomically); the PNG preview of the denoised
    /// image goes beside it with the same stem.
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// Exposure of the PNG preview: `auto` (metered from the image, printed) or a number of stops (0: the
    /// linear values as they are). The EXR is never exposed.
    #[arg(long, default_value = "auto", allow_negative_numbers = true, value_parser = exposure_value)]
    exposure: Exposure,
}

/// The value parser of a library option chosen by name ([`nimbus::params::Choice`]): its names are the
/// possible values that help and errors list.
fn choice<T: Choice + Clone + Send + Sync>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::TypedValueParser;
    clap::builder::PossibleValuesParser::new(T::CHOICES.iter().map(|(name, _)| *name))
        .try_map(|name| T::from_name(&name).ok_or_else(|| format!("unknown value '{name}'")))
}

/// `--volume-sampling`: the distance-sampling strategies of media (Cycles' "volume sampling" names).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum VolumeSampling {
    /// Distance sampling and, where they apply, equiangular sampling (combined by MIS) and decoupled
    /// direct-light sampling.
    Mis,
    /// Distance sampling alone.
    Distance,
}

#[derive(Args)]
struct MergeArgs {
    /// Part files, in any order (e.g. parts/shot.chunk*.exr).
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output EXR; the PNG preview goes beside it with the same stem.
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
    /// Exposure of the PNG preview: `auto` (metered from the image, printed) or a number of stops (0: the
    /// linear values as they are). The EXR is never exposed.
    #[arg(long, default_value = "auto", allow_negative_numbers = true, value_parser = exposure_value)]
    exposure: Exposure,
    /// How the EXR is stored.
    #[command(flatten)]
    storage: StorageArgs,
}

/// How EXR files are stored: `render` and `merge` share these.
#[derive(Args)]
struct StorageArgs {
    /// Store the colour AOV layers as 16-bit half floats (`--half`), or the beauty and alpha too
    /// (`--half=all`); depth, variance and Cryptomatte stay 32-bit.
    #[arg(long, value_parser = choice::<nimbus::output::HalfFloats>(), num_args = 0..=1, require_equals = true,
          default_missing_value = "aovs", default_value = "off")]
    half: nimbus::output::HalfFloats,
    /// EXR compression: zip (lossless, the default), piz (lossless wavelet), pxr24 (32-bit floats rounded to
    /// 24 bits), b44 (lossy, half channels), rle, none.
    #[arg(long, value_parser = choice::<nimbus::output::ExrCompression>(), default_value = "zip")]
    compression: nimbus::output::ExrCompression,
}

impl StorageArgs {
    fn options(&self) -> nimbus::output::ExrOptions {
        nimbus::output::ExrOptions {
            compression: self.compression,
            half: self.half,
        }
    }
}

#[derive(Args)]
struct ConvergeArgs {
    /// Scene file (.gltf, .glb, .obj).
    scene: PathBuf,
    /// Reference EXR; without it one is rendered with the default method (4x the budget) to DIR/reference.exr.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Comma-separated methods: default, global-majorant, grid16-majorant, adaptive-majorant, ratio-shadow,
    /// residual-ratio-shadow, no-media-mis.
    #[arg(
        long,
        default_value = "default,global-majorant,grid16-majorant,adaptive-majorant,ratio-shadow,residual-ratio-shadow,no-media-mis"
    )]
    methods: String,
    /// Render seconds over all methods, shared equally.
    #[arg(long, default_value_t = 60.0, value_parser = positive_seconds)]
    budget: f64,
    /// Image size, seed and threads (converge's default width: the reference's, else 96).
    #[command(flatten)]
    image: ImageArgs,
    /// Output folder.
    #[arg(short = 'o', long = "output")]
    output: PathBuf,
}

/// The image and sampling arguments that `render` and `converge` share.
#[derive(Args)]
struct ImageArgs {
    /// Image width in pixels.
    #[arg(long, value_parser = at_least_one)]
    width: Option<usize>,
    /// Image height in pixels (default: from the camera's aspect ratio, else 3/4 of the width).
    #[arg(long, value_parser = at_least_one)]
    height: Option<usize>,
    /// Seed of the random streams.
    #[arg(long, default_value_t = 0, value_parser = whole_number::<u64>)]
    seed: u64,
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 0, value_parser = whole_number::<usize>)]
    threads: usize,
}

#[derive(Args)]
struct InfoArgs {
    /// The .vdb file.
    file: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file; without it, the bundled demo scene is rendered.
    scene: Option<PathBuf>,
    /// Output EXR; the PNG preview goes beside it with the same stem. With frames, a frame pattern
    /// (`shot.####.exr`, `shot.$F4.exr`, `shot.%04d.exr`) names each frame's file.
    #[arg(short = 'o', long = "output", default_value = "render.exr")]
    output: PathBuf,
    /// Render this frame of the shot: VDB sequences read its file, and frame patterns in -o and --stats take
    /// its number.
    #[arg(long, allow_negative_numbers = true, conflicts_with = "frames")]
    frame: Option<i64>,
    /// Render frames A..B (both included), every STEP-th, one after the other, each to its own files.
    #[arg(long, value_parser = FrameRange::parse, allow_hyphen_values = true,
          conflicts_with_all = ["samples", "crop", "chunk_from_env"])]
    frames: Option<FrameRange>,
    /// Frames per second of the shot, for glTF animation and USD time codes (default: a USD stage's
    /// framesPerSecond, else 24).
    #[arg(long, value_parser = parse_fps)]
    fps: Option<f64>,
    /// Motion blur: the shutter opens and closes at these times, in frames relative to each frame
    /// (`-0.25,0.25` is a 180° shutter). Animated cameras and objects are blurred between their poses, and
    /// volumes with a velocity grid move along it. Default: off (an instant).
    #[arg(long, value_parser = Shutter::parse, allow_hyphen_values = true)]
    shutter: Option<Shutter>,
    /// glTF material variant (KHR_materials_variants) to render, by name: each primitive takes the material
    /// the file maps to it. Default: every primitive's own material (a warning lists the file's variants).
    #[arg(long, value_name = "NAME")]
    variant: Option<String>,
    /// Catmull-Clark levels of every USD mesh whose subdivisionScheme is catmullClark (USD's default), 0 for
    /// the control cage (default: the mesh's refineLevel, else 2; at most 8).
    #[arg(long = "subdivision-level", value_name = "N",
          value_parser = clap::value_parser!(u32).range(0..=8))]
    subdivision_level: Option<u32>,
    /// Refuse scene-file keys Nimbus does not know (a misspelt nimbus_volume key, an unknown nimbus_* extras key
    /// or USD nimbus: attribute) instead of warning and ignoring them.
    #[arg(long)]
    strict: bool,
    /// Samples per pixel (with --time-limit and no --spp: as many as the budget allows); with guiding on, the
    /// training's 7 are among them.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    spp: Option<u32>,
    /// Image size, seed and threads.
    #[command(flatten)]
    image: ImageArgs,
    /// Maximum scattering events (bounces) per path, as pbrt's maxdepth.
    #[arg(long = "max-depth")]
    max_depth: Option<u32>,
    /// Render progressively for this many seconds, then write what there is.
    #[arg(long = "time-limit")]
    time_limit: Option<f64>,
    /// Write the film's exact sums as a checkpoint (OUT.checkpoint.exr beside the output) every SECONDS, at
    /// the end of the first pass after each interval, and when SIGTERM or SIGINT stops the render; --resume
    /// continues from it.
    #[arg(long, value_parser = positive_seconds, conflicts_with = "time_limit")]
    checkpoint: Option<f64>,
    /// Continue from the checkpoint beside the output when there is one, taking only the samples it lacks
    /// (the image is the uninterrupted render's, bit for bit); without one, render from the first sample.
    #[arg(long, conflicts_with = "time_limit")]
    resume: bool,
    /// Write render statistics as JSON to this file.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Distance sampling in media: `mis` also samples segments through constant media equiangularly toward
    /// point and spot lights, MIS'd with distance sampling, and estimates the other lights' direct light at a
    /// distance decoupled from the path's (truncated to each segment); `distance` uses distance sampling alone.
    #[arg(long = "volume-sampling", value_enum, default_value = "mis")]
    volume_sampling: VolumeSampling,
    /// Where the paths' key random decisions come from: `sobol` (Owen-scrambled Sobol points, stratified per
    /// pixel) or `independent` (uniform random numbers).
    #[arg(long, value_parser = choice::<nimbus::render::Sampler>(), default_value = "sobol")]
    sampler: nimbus::render::Sampler,
    /// How next-event estimation chooses a light: `power` (by emitted power), `bvh` (a light BVH, by each
    /// light's importance at the shading point) or `auto` (the BVH for scenes with many bounded lights, such
    /// as emissive meshes; power otherwise).
    #[arg(long = "light-sampler", value_parser = choice::<nimbus::light::LightSamplerChoice>(),
          default_value = "auto")]
    light_sampler: nimbus::light::LightSamplerChoice,
    /// Pixels that an emitter's outline crosses: `auto` estimates their directly visible emission from 16
    /// camera rays per sample where the scene allows it (no media, no motion, outlines on at most 2% of the
    /// image); `off` takes one camera ray per sample everywhere.
    #[arg(long = "emitter-edges", value_parser = choice::<nimbus::render::EmitterEdgeSampling>(),
          default_value = "auto")]
    emitter_edges: nimbus::render::EmitterEdgeSampling,
    /// Path guiding: `on` trains a cache of incident light (7 samples per pixel of the frame, which are the
    /// image's first 7 and count in --spp) and uses it for directions at medium scattering events and Lambertian
    /// surfaces, for the distances of the decoupled direct-light sample in homogeneous media and for Russian
    /// roulette on shadow rays (of medium collisions, decoupled samples and surfaces); `auto` guides where that
    /// roulette saves most of the shadow rays: in a scene with a scattering medium a pilot of unguided paths
    /// decides (guided when roulette would trace at most half its shadow rays and --spp is at least 16,
    /// otherwise unguided, as `off`);
    /// --explain and --stats say why; `off` never guides.
    #[arg(long, value_parser = choice::<nimbus::render::GuidingMode>(), default_value = "auto")]
    guiding: nimbus::render::GuidingMode,
    /// Where paths are guided, guided Russian roulette and splitting at medium scattering events instead of
    /// classic Russian roulette: each path's expected contribution, from the guiding cache, is compared with its
    /// pixel's value from the training, and paths are ended or split to keep it near that value (off by
    /// default: measured to lose so far).
    #[arg(long = "guided-roulette")]
    guided_roulette: bool,
    /// Constant environment radiance r,g,b (overrides the scene's nimbus_environment).
    #[arg(long = "env-color", value_parser = parse_rgb)]
    env_color: Option<Rgb>,
    /// Memory budget for any one allocation sized by a file or a flag (a file read whole, a majorant
    /// structure, a decoded texture, the film), as bytes or with a K, M, G or T suffix (default: half of the
    /// physical memory).
    #[arg(long = "memory-limit", value_parser = nimbus::limits::parse_size)]
    memory_limit: Option<u64>,
    /// Most prims a USD stage may compose: counted from its layers before composing (each prim once per arc
    /// that brings it in) and again as the stage is read (default 1000000).
    #[arg(long = "max-prims", value_parser = clap::value_parser!(u64).range(1..))]
    max_prims: Option<u64>,
    /// Most layers one USD layer stack may expand to: a layer and its sublayers, nested ones included, a layer
    /// named twice counting twice (default 1000).
    #[arg(long = "max-sublayers", value_parser = clap::value_parser!(u64).range(1..))]
    max_sublayers: Option<u64>,
    /// Exposure of the PNG preview: `auto` (metered from the image, printed) or a number of stops (0: the
    /// linear values as they are). The EXR is never exposed.
    #[arg(long, default_value = "auto", allow_negative_numbers = true, value_parser = exposure_value)]
    exposure: Exposure,
    /// Print the estimator chosen for each medium, the light sampler and emitter-edge supersampling, and why,
    /// before rendering.
    #[arg(long)]
    explain: bool,
    /// Render only samples START..END (END exclusive) of each pixel's --spp samples, as a part for `merge`.
    #[arg(long, value_parser = nimbus::farm::parse_samples,
          conflicts_with_all = ["chunk_from_env", "time_limit"])]
    samples: Option<Range<u32>>,
    /// Render only the pixels x0 <= x < x1, y0 <= y < y1 of the frame (0,0 = top left), as a part for `merge`.
    #[arg(long, value_parser = nimbus::farm::parse_crop, conflicts_with = "time_limit")]
    crop: Option<PixelWindow>,
    /// Render chunk i of --chunks N of the samples, i read from NIMBUS_TASK_INDEX, SLURM_ARRAY_TASK_ID or
    /// JOB_COMPLETION_INDEX (first set wins; 0 to N-1), as a part for `merge` written to OUT.chunk<i>.exr.
    #[arg(
        long = "chunk-from-env",
        requires = "chunks",
        conflicts_with = "time_limit"
    )]
    chunk_from_env: bool,
    /// Number of sample chunks of --chunk-from-env.
    #[arg(long, requires = "chunk_from_env")]
    chunks: Option<u32>,
    /// Leave the environment seen directly out of the beauty (written to the `environment` layer): alpha is
    /// then the coverage of everything else, to put the render over a plate.
    #[arg(long)]
    transparent: bool,
    /// The layers to write beyond the beauty and alpha, comma-separated: layer names (`diffuse_direct`,
    /// `lg_key`, `CryptoObject`...) and sets (`default`, `lightpaths`, `colors`, `lightgroups`, `cryptomatte`,
    /// `all`, `none`). Default: `default`, plus `environment` on a transparent film, the light groups when
    /// there are any, and `shadow_catcher` when the scene has a catcher.
    #[arg(long, value_parser = parse_aovs)]
    aovs: Option<nimbus::render::AovSelection>,
    /// Print every layer `--aovs` takes (with the scene's light groups when a scene is given), then exit.
    #[arg(long = "list-aovs")]
    list_aovs: bool,
    /// Render from the scene's camera of this name: a glTF node name (or camera name for a node without one),
    /// a USD prim name or prim path. Default: the first camera in the file. An unknown name is an error that
    /// lists the scene's cameras.
    #[arg(long)]
    camera: Option<String>,
    /// Print the scene's cameras (name, projection, field of view or film height, aspect ratio, lens), one per
    /// line, then exit without rendering.
    #[arg(long = "list-cameras")]
    list_cameras: bool,
    /// Light groups: `scene` (the groups the scene declares; emitters in none go to `default`), `per-light`
    /// (one group per emitter) or `off`.
    #[arg(long = "light-groups", value_parser = choice::<nimbus::render::LightGroupMode>(),
          default_value = "scene")]
    light_groups: nimbus::render::LightGroupMode,
    /// Cryptomatte ranks per pixel (1 to 16, rounded up to even: two per layer).
    #[arg(long = "cryptomatte-depth", default_value_t = nimbus::render::cryptomatte::DEFAULT_DEPTH)]
    cryptomatte_depth: usize,
    /// Also write deep samples (OpenEXR 2.0 deep scanline) to OUT.deep.exr beside the EXR: per pixel, surfaces
    /// as point samples and media as depth intervals, each with Z and ZBack (depth along the view axis), A and
    /// premultiplied R, G, B, all 32-bit floats; they flatten to the EXR's beauty and alpha. Stored ZIPS, or
    /// uncompressed with --compression none. Whole frames only (not with farm parts or checkpoints).
    #[arg(long)]
    deep: bool,
    /// The most deep samples per pixel (1 to 65536): more are merged by "over", the pair whose merge changes
    /// the holdout curve least first, which keeps the flattened pixel.
    #[arg(long = "deep-samples", value_name = "N", requires = "deep",
          default_value_t = nimbus::render::deep::DEFAULT_MAX_SAMPLES as u32,
          value_parser = clap::value_parser!(u32).range(1..=65536))]
    deep_samples: u32,
    /// Denoise the finished frame with Intel Open Image Denoise, guided by the albedo and normal layers: the
    /// EXR gains a `denoised` layer beside the raw beauty, and the PNG preview shows the denoised image. Needs a
    /// build with the `denoise` feature; refused for a farm part (denoise the merged frame with `nimbus
    /// denoise`).
    #[arg(long)]
    denoise: bool,
    /// Rewrite the PNG preview every SECONDS while the render runs (at the end of the first pass after each
    /// interval), atomically; denoised in a build with the `denoise` feature. Not for a farm part.
    #[arg(long = "preview-every", value_name = "SECONDS", value_parser = positive_seconds,
          conflicts_with_all = ["samples", "crop", "chunk_from_env"])]
    preview_every: Option<f64>,
    /// How the EXR is stored.
    #[command(flatten)]
    storage: StorageArgs,
}

impl RenderArgs {
    /// Whether this render is a farm part (`--samples`, `--crop`, `--chunk-from-env`) rather than a whole image.
    fn is_part(&self) -> bool {
        self.samples.is_some() || self.crop.is_some() || self.chunk_from_env
    }

    /// The limits `--memory-limit`, `--max-prims` and `--max-sublayers` set, the defaults where they are not
    /// given.
    fn limits(&self) -> Limits {
        let mut limits = self
            .memory_limit
            .map_or_else(Limits::default, Limits::with_memory);
        if let Some(prims) = self.max_prims {
            limits.usd_prims = prims;
        }
        if let Some(entries) = self.max_sublayers {
            limits.usd_layer_stack = entries;
        }
        limits
    }
}

// The value parsers of the flags below (`value_parser = ...`) return `Result<T, String>`: clap's convention,
// whose message it prints after the flag and value. The command functions return `String` too: the CLI's one
// error line (`nimbus: error: ...`); the library's typed errors become that text at this boundary.

/// Parses `--aovs`.
fn parse_aovs(list: &str) -> Result<nimbus::render::AovSelection, String> {
    nimbus::render::AovSelection::parse(list).map_err(|e| e.to_string())
}

fn parse_rgb(s: &str) -> Result<Rgb, String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>().map_err(|e| format!("'{c}': {e}")))
        .collect::<Result<_, _>>()?;
    match v.as_slice() {
        [r, g, b] if v.iter().all(|c| c.is_finite() && *c >= 0.0) => Ok(Rgb::new(*r, *g, *b)),
        _ => Err("expected three non-negative numbers r,g,b".into()),
    }
}

/// The bundled demo scene (a VDB cloud over a ground plane), embedded with its VDB so that `nimbus render`
/// works from any folder.
const DEMO_SCENE: &[u8] = include_bytes!("../assets/cloud.gltf");
/// The demo's cloud.
const DEMO_CLOUD: &[u8] = include_bytes!("../assets/cloud.vdb");

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    let result = match cli.command {
        Command::Render(args) => render(*args),
        Command::Info(args) => info(args),
        Command::Converge(args) => converge(args),
        Command::Merge(args) => merge(args),
        Command::Denoise(args) => denoise(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("nimbus: error: {}", one_line(&message, MAX_MESSAGE_CHARS));
            // A render stopped by a signal ends as the signal would have ended it (130 for SIGINT, 143 for
            // SIGTERM), after writing what it had.
            match STOP_SIGNAL.load(Ordering::SeqCst) {
                0 => ExitCode::FAILURE,
                signal => ExitCode::from(128 + signal as u8),
            }
        }
    }
}

fn info(args: InfoArgs) -> Result<(), String> {
    let info = nimbus::vdb::file_info(&args.file).map_err(|e| e.to_string())?;
    if args.json {
        let json = serde_json::to_string_pretty(&info).map_err(|e| e.to_string())?;
        print_stdout(&format!("{json}\n"))
    } else {
        print_stdout(&info.to_string())
    }
}

/// Prints a command-line parsing error as one line, as every other error is printed, with clap's tips
/// (a similar flag's name) folded into it; help and version requests print as clap prints them.
fn usage_error(error: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        error.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        let _ = error.print();
        return if error.use_stderr() {
            ExitCode::from(2)
        } else {
            ExitCode::SUCCESS
        };
    }
    let rendered = error.render().to_string();
    let mut message = String::new();
    for line in rendered.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if !message.is_empty() {
            message.push_str(if line.starts_with("tip: ") { "; " } else { " " });
        }
        message.push_str(line.trim_start_matches("error: "));
    }
    message.push_str(" (--help lists the flags)");
    eprintln!("nimbus: error: {}", one_line(&message, MAX_MESSAGE_CHARS));
    ExitCode::from(2)
}

/// Writes `text` to standard output. A reader that stopped reading (`nimbus info FILE | head -1`: a broken
/// pipe) ends the output quietly, as it does for other command-line tools; any other write error is an error.
fn print_stdout(text: &str) -> Result<(), String> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(format!("cannot write to standard output: {e}"))
        }
        _ => Ok(()),
    }
}

/// The largest image side `render` and `converge` accept.
const MAX_IMAGE_SIDE: usize = 65_536;
/// The most pixels in one frame: 8192 × 8192, whose film takes 16 GB (240 bytes a pixel).
const MAX_IMAGE_PIXELS: usize = 1 << 26;

/// Refuses image sizes whose film could not be allocated, before anything is allocated.
fn check_image_size(width: usize, height: usize) -> Result<(), String> {
    let pixels = width.saturating_mul(height);
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE || pixels > MAX_IMAGE_PIXELS {
        return Err(format!(
            "image {width}x{height} is too large: at most {MAX_IMAGE_SIDE} pixels a side and \
             {MAX_IMAGE_PIXELS} pixels in all"
        ));
    }
    Ok(())
}

fn converge(args: ConvergeArgs) -> Result<(), String> {
    check_image_size(
        args.image.width.unwrap_or(1),
        args.image.height.unwrap_or(1),
    )?;
    let options = nimbus::converge::ConvergeOptions {
        scene: args.scene,
        reference: args.reference,
        methods: nimbus::converge::Method::parse_list(&args.methods).map_err(|e| e.to_string())?,
        budget_seconds: args.budget,
        width: args.image.width,
        height: args.image.height,
        output_dir: args.output,
        seed: args.image.seed,
        threads: args.image.threads,
    };
    nimbus::converge::run(&options, &mut |line| eprintln!("nimbus: {line}"))
        .map_err(|e| e.to_string())?;
    eprintln!(
        "nimbus: wrote convergence.csv, convergence.png, convergence.svg and summary.md to {}",
        options.output_dir.display()
    );
    Ok(())
}

/// Loads the scene of `args` (the bundled demo without one) at `frame` under `shutter`, with the file options
/// the flags give (memory limit, frames per second, material variant, subdivision level).
fn load_builder(
    args: &RenderArgs,
    frame: Option<i64>,
    shutter: Option<Shutter>,
) -> Result<SceneBuilder, String> {
    let options = LoadOptions {
        limits: args.limits(),
        frame,
        fps: args.fps,
        shutter,
        variant: args.variant.as_deref(),
        subdivision_level: args.subdivision_level,
        strict: args.strict,
        ..LoadOptions::default()
    };
    let mut builder = match &args.scene {
        Some(path) => nimbus::scene::load_builder(path, &options),
        None => nimbus::scene::load_gltf_slice(
            DEMO_SCENE,
            Path::new("assets/cloud.gltf"),
            &LoadOptions {
                embedded: &[("cloud.vdb", DEMO_CLOUD)],
                ..options
            },
        ),
    }
    .map_err(|e| e.to_string())?;
    builder.set_shutter(shutter);
    Ok(builder)
}

/// Parses frames per second: a finite number above 0.
fn parse_fps(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 => Ok(f),
        Ok(f) => Err(format!(
            "{f} must be a positive number of frames per second"
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// Parses a count that must be at least 1 (an image side).
fn at_least_one(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(_) => Err("expected a whole number of at least 1".into()),
    }
}

/// Parses a whole number of 0 or more (a seed, a thread count).
fn whole_number<T: std::str::FromStr>(text: &str) -> Result<T, String> {
    text.parse()
        .map_err(|_| "expected a whole number of 0 or more".to_owned())
}

/// Parses `--exposure`: `auto` or a finite number of stops.
fn exposure_value(text: &str) -> Result<Exposure, String> {
    Exposure::parse(text).ok_or_else(|| "expected auto or a finite number of stops".into())
}

/// The preview's exposure in stops for `image`: the fixed one, or the metered one (printed). Either way, an
/// image that is almost black before exposure gets one warning line saying so.
fn preview_stops(exposure: Exposure, image: &RenderImage) -> f32 {
    let metering = nimbus::output::meter(image);
    let stops = match exposure {
        Exposure::Stops(stops) => stops,
        Exposure::Auto => metering.auto_stops,
    };
    if metering.almost_black {
        let advice = match exposure {
            Exposure::Auto => format!("the PNG preview is exposed by {stops:+.2} stops"),
            Exposure::Stops(_) => format!(
                "--exposure auto would expose the PNG preview by {:+.2} stops",
                metering.auto_stops
            ),
        };
        eprintln!(
            "nimbus: warning: the image is almost black before exposure (fewer than {}% of its pixels reach \
             luminance {}; log-average {:.3e}); {advice}, and the EXR keeps the linear values",
            nimbus::output::BLACK_SHARE * 100.0,
            nimbus::output::BLACK_LUMINANCE,
            metering.key
        );
    } else if exposure == Exposure::Auto {
        eprintln!(
            "nimbus: preview exposure {stops:+.2} stops (auto: log-average luminance {:.3e} to middle grey; \
             --exposure 0 shows the linear values)",
            metering.key
        );
    }
    stops
}

/// Parses a positive, finite number of seconds (a time budget).
fn positive_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("expected a positive number of seconds".into()),
    }
}

/// Checks, before anything is rendered, that `output` names an EXR in a folder that exists (or can be made)
/// and can be written: the PNG preview goes beside it, so `-o out.png` would write the PNG over the EXR.
fn check_output(output: &Path) -> Result<(), String> {
    let is_exr = output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !is_exr {
        return Err(format!(
            "-o {} must name an .exr file (the PNG preview is written beside it with the same stem)",
            output.display()
        ));
    }
    check_folder_writable(output)
}

/// Makes `path`'s folder if it is missing and checks that a file can be written in it.
fn check_folder_writable(path: &Path) -> Result<(), String> {
    create_parent(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let probe = dir.join(format!(".nimbus-write-test-{}", std::process::id()));
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| format!("cannot write to {}: {e}", dir.display()))
}

/// Checks, before anything is rendered, that `--stats` names a file that is neither the EXR nor its PNG preview
/// (the JSON would replace the image) nor a folder, in a folder that exists (or can be made) and can be written.
fn check_stats_path(stats: &Path, output: &Path) -> Result<(), String> {
    let preview = output.with_extension("png");
    if same_file_name(stats, output) || same_file_name(stats, &preview) {
        return Err(format!(
            "--stats {} names an image this render writes; give the statistics their own file",
            stats.display()
        ));
    }
    if stats.is_dir() {
        return Err(format!(
            "--stats {} is a folder; name a file in it (e.g. {})",
            stats.display(),
            stats.join("stats.json").display()
        ));
    }
    check_folder_writable(stats)
}

/// Whether two paths name the same file: equal once made absolute and their folders resolved (the files
/// themselves need not exist yet).
fn same_file_name(a: &Path, b: &Path) -> bool {
    let resolve = |p: &Path| {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_owned());
        dir.join(p.file_name().unwrap_or_default())
    };
    resolve(a) == resolve(b)
}

/// `path` with `.####` before its extension when it holds no frame pattern (`shot.exr` → `shot.####.exr`), so
/// that the frames of a range do not overwrite one another.
fn with_frame_pattern(path: &Path, flag: &str) -> PathBuf {
    if path.to_str().is_some_and(has_frame_token) {
        return path.to_owned();
    }
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.####.{}", ext.to_string_lossy()),
        None => format!("{stem}.####"),
    };
    let patterned = path.with_file_name(name);
    eprintln!(
        "nimbus: {flag} {} has no frame pattern; the frames go to {}",
        path.display(),
        patterned.display()
    );
    patterned
}

/// `path` with its frame pattern replaced by `frame` (unchanged without a frame or a pattern).
fn frame_path(path: &Path, frame: Option<i64>) -> PathBuf {
    match (frame, path.to_str()) {
        (Some(f), Some(p)) => with_frame(p, f).map_or_else(|| path.to_owned(), PathBuf::from),
        _ => path.to_owned(),
    }
}

/// `nimbus render`: a still, one frame (`--frame`) or a range of frames (`--frames`), each loaded, rendered and
/// written in turn (a frame's scene and grids are dropped before the next is loaded).
fn render(mut args: RenderArgs) -> Result<(), String> {
    if args.list_aovs {
        return list_aovs(&args);
    }
    if args.list_cameras {
        return list_cameras(&args);
    }
    if args.denoise && args.is_part() {
        return Err("--denoise is refused for a farm part (--samples, --crop, --chunk-from-env): denoising runs \
                    after the merge, on the whole frame (the filter reads each pixel's neighbours); run `nimbus \
                    denoise` on the merged EXR"
            .into());
    }
    #[cfg(not(feature = "denoise"))]
    if args.denoise {
        return Err(DENOISE_BUILD.into());
    }
    if args.deep && (args.is_part() || args.checkpoint.is_some() || args.resume) {
        return Err("--deep renders whole frames only: deep samples are merged per pixel down to --deep-samples, \
                    which farm parts and checkpoints (exact sums) do not carry; drop --samples, --crop, \
                    --chunk-from-env, --checkpoint and --resume"
            .into());
    }
    let range = args.frames.or(args.frame.map(FrameRange::single));
    if range.is_some_and(|r| r.len() > 1) {
        args.output = with_frame_pattern(&args.output, "-o");
        args.stats = args.stats.map(|s| with_frame_pattern(&s, "--stats"));
    }
    let first = range.map(|r| r.first);
    check_output(&frame_path(&args.output, first))?;
    if let Some(stats) = &args.stats {
        check_stats_path(&frame_path(stats, first), &frame_path(&args.output, first))?;
    }
    if args.image.threads > nimbus::limits::max_threads() {
        eprintln!(
            "nimbus: warning: --threads {} is capped at {} ({} per core)",
            args.image.threads,
            nimbus::limits::max_threads(),
            nimbus::limits::THREADS_PER_CORE
        );
    }
    let mut reporter = ProgressReporter::new();
    let cancel = CancelToken::new();
    stop_on_signals(cancel.clone())?;
    let Some(range) = range else {
        return render_frame(&args, None, &mut reporter, &cancel);
    };
    let count = range.len();
    for (i, frame) in range.frames().enumerate() {
        reporter.start_frame(frame, i as u64, count);
        render_frame(&args, Some(frame), &mut reporter, &cancel)?;
    }
    if count > 1 {
        eprintln!(
            "nimbus: rendered frames {range} ({count} frames) to {}",
            args.output.display()
        );
    }
    Ok(())
}

/// `--list-aovs`: every layer `--aovs` takes, with its meaning, and the scene's light groups when a scene is
/// given.
fn list_aovs(args: &RenderArgs) -> Result<(), String> {
    use std::fmt::Write;
    let mut text = String::from("layers (--aovs takes these names, comma-separated):\n");
    for (name, meaning) in nimbus::render::aovs::layer_catalog() {
        let _ = writeln!(text, "  {name:<22} {meaning}");
    }
    text.push_str("sets:\n");
    for (name, meaning) in nimbus::render::aovs::AOV_SETS {
        let _ = writeln!(text, "  {name:<22} {meaning}");
    }
    if args.scene.is_some() {
        let builder = load_builder(args, args.frame, None)?;
        let scene = builder.build().map_err(|e| e.to_string())?;
        let groups = nimbus::render::LightGroups::new(&scene, args.light_groups)
            .map_err(|e| e.to_string())?;
        let names = if groups.names.is_empty() {
            "none".to_owned()
        } else {
            groups.names.join(", ")
        };
        let _ = writeln!(
            text,
            "light groups of this scene (--light-groups {}): {names}",
            light_group_mode_name(args.light_groups)
        );
    }
    print_stdout(&text)
}

/// `--list-cameras`: the scene's cameras, one per line (tab-separated: name, projection, field of view or
/// film height, aspect ratio, lens), the one that renders by default first; a line saying so when there are
/// none (the default framing renders).
fn list_cameras(args: &RenderArgs) -> Result<(), String> {
    let builder = load_builder(args, args.frame, None)?;
    let mut text = String::new();
    for camera in builder.cameras() {
        text.push_str(&camera.describe());
        text.push('\n');
    }
    if text.is_empty() {
        text.push_str("the scene has no cameras: the default camera frames it\n");
    }
    print_stdout(&text)
}

/// The `--light-groups` value's name.
fn light_group_mode_name(mode: nimbus::render::LightGroupMode) -> &'static str {
    match mode {
        nimbus::render::LightGroupMode::Scene => "scene",
        nimbus::render::LightGroupMode::PerLight => "per-light",
        nimbus::render::LightGroupMode::Off => "off",
    }
}

/// Writes the EXR `output` of `image`, its PNG preview and, with `--deep`, its deep EXR.
fn write_image(args: &RenderArgs, image: &RenderImage, output: &Path) -> Result<(), String> {
    create_parent(output)?;
    write_flat_image(args, image, output)?;
    if let Some(deep) = &image.deep {
        let path = nimbus::output::deep_path(output);
        let compression = match args.storage.compression {
            nimbus::output::ExrCompression::None => nimbus::output::DeepCompression::None,
            _ => nimbus::output::DeepCompression::Zips,
        };
        nimbus::output::write_deep_exr(deep, &path, compression, &image.metadata)
            .map_err(|e| e.to_string())?;
        eprintln!(
            "nimbus: wrote {} ({} deep samples, at most {} in a pixel)",
            path.display(),
            deep.samples.len(),
            deep.most_samples()
        );
    }
    Ok(())
}

/// Writes the EXR `output` of `image` and its PNG preview; with `--denoise`, the EXR gains the `denoised`
/// layer and the preview shows it.
fn write_flat_image(args: &RenderArgs, image: &RenderImage, output: &Path) -> Result<(), String> {
    let png = nimbus::output::preview_path(output);
    #[cfg(feature = "denoise")]
    if args.denoise {
        let start = Instant::now();
        let pixels = nimbus::denoise::denoise_image(image).map_err(|e| e.to_string())?;
        eprintln!(
            "nimbus: denoised {}x{} in {:.2} s (Open Image Denoise, guided by albedo and normal)",
            image.width,
            image.height,
            start.elapsed().as_secs_f64()
        );
        let mut with_layer = image.clone();
        with_layer
            .aovs
            .push(nimbus::denoise::denoised_layer(&pixels));
        nimbus::output::write_exr_with(&with_layer, output, &args.storage.options())
            .map_err(|e| e.to_string())?;
        let preview =
            nimbus::denoise::preview_image(image.width, image.height, pixels, &image.alpha);
        return nimbus::output::write_png_preview(
            &preview,
            &png,
            preview_stops(args.exposure, &preview),
        )
        .map_err(|e| e.to_string());
    }
    nimbus::output::write_exr_with(image, output, &args.storage.options())
        .map_err(|e| e.to_string())?;
    nimbus::output::write_png_preview(image, &png, preview_stops(args.exposure, image))
        .map_err(|e| e.to_string())
}

/// `--preview-every`: the PNG preview of the render so far at `png`, denoised in a build with the `denoise`
/// feature, exposed quietly (the fixed stops, or auto's metering without a line each time).
fn write_progress_preview(
    args: &RenderArgs,
    image: &RenderImage,
    png: &Path,
) -> Result<(), String> {
    #[cfg(feature = "denoise")]
    let image = &nimbus::denoise::preview_image(
        image.width,
        image.height,
        nimbus::denoise::denoise_image(image).map_err(|e| e.to_string())?,
        &image.alpha,
    );
    let stops = match args.exposure {
        Exposure::Stops(stops) => stops,
        Exposure::Auto => nimbus::output::meter(image).auto_stops,
    };
    nimbus::output::write_png_preview(image, png, stops).map_err(|e| e.to_string())
}

/// How to get a build that denoises: the refusal of `--denoise` and `nimbus denoise` without the feature.
#[cfg(not(feature = "denoise"))]
const DENOISE_BUILD: &str = "this nimbus was built without the `denoise` feature: build it with `cargo build \
     --release --features denoise` and OIDN_DIR pointing at Open Image Denoise 2.x (see docs/denoising.md)";

/// `nimbus denoise IN.exr -o OUT.exr`: the merged frame with its `denoised` layer added, and the denoised PNG
/// preview.
#[cfg(feature = "denoise")]
fn denoise(args: DenoiseArgs) -> Result<(), String> {
    check_output(&args.output)?;
    create_parent(&args.output)?;
    let start = Instant::now();
    let frame =
        nimbus::denoise::denoise_exr(&args.input, &args.output).map_err(|e| e.to_string())?;
    let png = nimbus::output::preview_path(&args.output);
    nimbus::output::write_png_preview(&frame, &png, preview_stops(args.exposure, &frame))
        .map_err(|e| e.to_string())?;
    eprintln!(
        "nimbus: denoised {} ({}x{}) in {:.2} s into {} and {}",
        args.input.display(),
        frame.width,
        frame.height,
        start.elapsed().as_secs_f64(),
        args.output.display(),
        png.display()
    );
    Ok(())
}

/// `nimbus denoise` in a build without the `denoise` feature: refused, saying how to build one with it.
#[cfg(not(feature = "denoise"))]
fn denoise(_args: DenoiseArgs) -> Result<(), String> {
    Err(DENOISE_BUILD.into())
}

/// With `--resume`, the checkpoint at `path` to continue from, once checked to be of this render (`None`
/// when there is none: the render starts from its first sample).
fn resume_from(
    args: &RenderArgs,
    path: &Path,
    scene: &Scene,
    settings: &RenderSettings,
    hash: u64,
    region: &RenderRegion,
) -> Result<Option<ResumeFrom>, String> {
    if !args.resume {
        return Ok(None);
    }
    if !path.exists() {
        eprintln!(
            "nimbus: --resume: no checkpoint {}; rendering from the first sample",
            path.display()
        );
        return Ok(None);
    }
    let (info, from) = read_checkpoint(path).map_err(|e| e.to_string())?;
    let differences = [
        (
            "Nimbus version",
            info.version.clone(),
            env!("CARGO_PKG_VERSION").to_owned(),
        ),
        (
            "scene hash (scene file, settings and overrides)",
            format!("{:016x}", info.scene_hash),
            format!("{hash:016x}"),
        ),
        (
            "size",
            format!("{}x{}", info.width, info.height),
            format!("{}x{}", settings.width, settings.height),
        ),
        ("seed", info.seed.to_string(), settings.seed.to_string()),
        (
            "max depth",
            info.max_depth.to_string(),
            settings.max_depth.to_string(),
        ),
        ("spp", info.spp.to_string(), settings.spp.to_string()),
        ("crop", info.window.to_string(), region.window.to_string()),
        (
            "first sample",
            info.samples.start.to_string(),
            region.samples.start.to_string(),
        ),
        (
            "media estimators",
            info.estimators.clone(),
            PartInfo::estimators_of(scene),
        ),
    ];
    if let Some((what, theirs, ours)) = differences.iter().find(|(_, a, b)| a != b) {
        return Err(format!(
            "checkpoint {}: its {what} '{theirs}' is not this render's '{ours}'; delete it or render without --resume",
            path.display()
        ));
    }
    eprintln!(
        "nimbus: resuming from {}: {} of {} samples in every pixel{}",
        path.display(),
        from.progress.complete - region.samples.start,
        region.samples.len(),
        if from.progress.stopped_pass.is_some() {
            ", and a pass stopped part way"
        } else {
            ""
        }
    );
    Ok(Some(from))
}

/// Removes the checkpoint of a render that finished (none is no error).
fn remove_checkpoint(path: &Path) -> Result<(), String> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(format!(
            "{}: the render finished, but its checkpoint could not be removed: {e}",
            path.display()
        )),
        _ => Ok(()),
    }
}

/// The signal that is stopping the render (`SIGTERM` or `SIGINT`), 0 while none has arrived.
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

/// True while a frame's scene is being loaded and built: no sample has been taken for it and nothing is being
/// written, so a signal then ends the process at once instead of after the load (which a large USD stage can
/// make longer than a scheduler's grace period, Slurm's `KillWait` of 30 s).
static LOADING: AtomicBool = AtomicBool::new(false);

/// Marks the loading of a frame's scene (see [`LOADING`]) until dropped.
struct LoadingPhase;

impl LoadingPhase {
    fn start() -> Self {
        LOADING.store(true, Ordering::SeqCst);
        LoadingPhase
    }
}

impl Drop for LoadingPhase {
    fn drop(&mut self) {
        LOADING.store(false, Ordering::SeqCst);
    }
}

/// Cancels `token` on the first SIGTERM or SIGINT (kept in [`STOP_SIGNAL`]), so that the render stops after
/// the pixels in flight and writes what it has; a second one ends the process at once, with status 128 + the
/// signal (outputs are written atomically, so none is left torn).
fn stop_on_signals(token: CancelToken) -> Result<(), String> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGINT])
        .map_err(|e| format!("cannot watch SIGTERM and SIGINT: {e}"))?;
    std::thread::spawn(move || {
        for signal in signals.forever() {
            if STOP_SIGNAL.swap(signal, Ordering::SeqCst) != 0 {
                eprintln!("nimbus: {} again: stopping now", signal_name(signal));
                std::process::exit(128 + signal);
            }
            if LOADING.load(Ordering::SeqCst) {
                eprintln!(
                    "nimbus: {} received while loading the scene: stopping now; nothing of this frame was written",
                    signal_name(signal)
                );
                std::process::exit(128 + signal);
            }
            eprintln!(
                "nimbus: {} received: stopping after the pixels in flight (send it again to stop at once)",
                signal_name(signal)
            );
            token.cancel();
        }
    });
    Ok(())
}

/// The name of a signal [`stop_on_signals`] watches.
fn signal_name(signal: i32) -> &'static str {
    if signal == signal_hook::consts::SIGINT {
        "SIGINT"
    } else {
        "SIGTERM"
    }
}

/// The EXR header attributes of a render ([`nimbus::render::ImageMetadata::for_render`]), the scene named by
/// its file or as the bundled demo.
fn image_metadata(
    args: &RenderArgs,
    scene: &Scene,
    settings: &RenderSettings,
    frame: Option<i64>,
    hash: u64,
    stats: &RenderStats,
) -> nimbus::render::ImageMetadata {
    let label = args.scene.as_ref().map_or_else(
        || "bundled demo (assets/cloud.gltf)".into(),
        |p| p.display().to_string(),
    );
    nimbus::render::ImageMetadata::for_render(scene, settings, &label, frame, hash, stats)
}

/// Creates the folder an output file goes in (every task of an array job may race to create it).
fn create_parent(path: &Path) -> Result<(), String> {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))
        }
        _ => Ok(()),
    }
}

/// `--explain`'s line on distance sampling in media: whether segments through constant media are also
/// sampled equiangularly toward point and spot lights, whether the other lights' direct light is estimated at a
/// decoupled distance on every segment, and why (not).
fn explain_volume_sampling(scene: &Scene, sampling: VolumeSampling) {
    let nimbus::render::EquiangularTargets {
        constant_media: constant,
        point_lights: points,
        decoupled_lights: others,
        open_constant_media: open,
    } = nimbus::render::EquiangularTargets::of(scene);
    if constant == 0 {
        return;
    }
    let mut choices = Vec::new();
    if sampling == VolumeSampling::Distance {
        choices.push("distance sampling alone (--volume-sampling distance)".to_string());
    } else {
        if points > 0 {
            choices.push(format!(
                "equiangular sampling toward {points} point/spot light(s), MIS'd with distance sampling \
                 (power heuristic): distance sampling alone scatters where the medium is dense, not where a \
                 small light is bright"
            ));
        }
        if others > 0 && open == 0 {
            choices.push(format!(
                "the direct light of {others} directional/area/environment light(s) estimated at collisions: \
                 every constant medium is sealed by refracting surfaces, which shadow rays do not pass"
            ));
        } else if others > 0 {
            choices.push(format!(
                "the direct light of {others} directional/area/environment light(s) estimated on every \
                 segment at a distance from the transmittance truncated to it (decoupled from the path's \
                 collision, which estimates none): collisions alone reach only the 1 - T of segments that \
                 collide"
            ));
        }
        if choices.is_empty() {
            choices.push("distance sampling alone: no light to sample toward".to_string());
        }
    }
    eprintln!(
        "nimbus: volume sampling in {constant} constant medium/media: {}",
        choices.join("; ")
    );
}

/// Warns about biased media, dropped and clamped samples, and writes the statistics if asked.
fn finish_render(stats: &RenderStats, stats_path: Option<&Path>) -> Result<(), String> {
    for m in stats
        .media
        .iter()
        .filter(|m| m.counters.majorant_violations > 0)
    {
        eprintln!(
            "nimbus: warning: medium '{}': {} density lookups exceeded their majorant; the estimate is biased there",
            m.name, m.counters.majorant_violations
        );
    }
    warn_samples(stats.nan_samples, stats.clamped_samples);
    if let Some(path) = stats_path {
        let json = serde_json::to_string_pretty(stats).map_err(|e| e.to_string())?;
        nimbus::output::write_atomically(path, (json + "\n").as_bytes())
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// Warns about samples dropped as NaN/Inf and samples clamped into the film's range.
fn warn_samples(nan_samples: u64, clamped_samples: u64) {
    if nan_samples > 0 {
        eprintln!("nimbus: warning: {nan_samples} NaN/Inf samples were dropped");
    }
    if clamped_samples > 0 {
        eprintln!(
            "nimbus: warning: {clamped_samples} samples had values beyond +/-2^38 (2.7e11) or NaN/Inf AOVs, and were clamped"
        );
    }
}

/// The region and output file of a part render (`--samples`, `--crop`, `--chunk-from-env`), or `None` for a
/// whole render.
fn part_region(
    args: &RenderArgs,
    frame_output: &Path,
    settings: &RenderSettings,
) -> Result<Option<(RenderRegion, PathBuf)>, String> {
    if !args.is_part() {
        return Ok(None);
    }
    let window = args
        .crop
        .unwrap_or(PixelWindow::full(settings.width, settings.height));
    if !window.fits(settings.width, settings.height) {
        return Err(format!(
            "--crop {window} does not fit the {}x{} frame",
            settings.width, settings.height
        ));
    }
    let mut output = frame_output.to_owned();
    let samples = match (&args.samples, args.chunks) {
        (Some(samples), _) => {
            if samples.end > settings.spp {
                return Err(format!(
                    "--samples {}..{} goes past --spp {}",
                    samples.start, samples.end, settings.spp
                ));
            }
            samples.clone()
        }
        (None, Some(chunks)) => {
            let task = nimbus::farm::task_index(|k| std::env::var(k).ok(), chunks)
                .map_err(|e| e.to_string())?;
            eprintln!(
                "nimbus: chunk {} of {chunks} (from {})",
                task.index, task.variable
            );
            output = nimbus::farm::chunk_output_path(frame_output, task.index, chunks);
            nimbus::farm::sample_chunk(task.index, chunks, settings.spp)
                .map_err(|e| e.to_string())?
        }
        (None, None) => 0..settings.spp,
    };
    Ok(Some((RenderRegion { window, samples }, output)))
}

/// The scene hash of a part render: the scene file's bytes (the embedded demo's without one), the settings,
/// the `--env-color` override, the frame, the shutter, the material variant, the `--camera` choice and the
/// camera's lens, if it has one (parts of different frames, shutters, variants, cameras or apertures must not
/// merge), and whether `--guiding` guides `scene`.
fn part_scene_hash(
    args: &RenderArgs,
    frame: Option<i64>,
    settings: &RenderSettings,
    scene: &nimbus::Scene,
) -> Result<u64, String> {
    let file;
    let files: Vec<&[u8]> = match &args.scene {
        Some(path) => {
            file = nimbus::limits::read_file(path, &args.limits())
                .map_err(|e| format!("{}: {e}", path.display()))?;
            vec![&file]
        }
        None => vec![DEMO_SCENE, DEMO_CLOUD],
    };
    let overrides = nimbus::farm::SceneOverrides {
        env_color: args.env_color,
        frame,
        fps: args.fps,
        shutter: args.shutter,
        camera: args.camera.as_deref(),
        lens: scene.camera().lens,
        variant: args.variant.as_deref(),
        subdivision_level: args.subdivision_level,
    };
    Ok(overrides.scene_hash(&files, settings, scene))
}

fn merge(args: MergeArgs) -> Result<(), String> {
    if let Ok(out) = args.output.canonicalize() {
        if let Some(p) = args
            .parts
            .iter()
            .find(|p| p.canonicalize().is_ok_and(|p| p == out))
        {
            return Err(FarmError::OutputIsInput { path: p.clone() }.to_string());
        }
    }
    let merged = nimbus::farm::merge_parts(&args.parts).map_err(|e| e.to_string())?;
    create_parent(&args.output)?;
    nimbus::output::write_exr_with(&merged.image, &args.output, &args.storage.options())
        .map_err(|e| e.to_string())?;
    let png = nimbus::output::preview_path(&args.output);
    nimbus::output::write_png_preview(
        &merged.image,
        &png,
        preview_stops(args.exposure, &merged.image),
    )
    .map_err(|e| e.to_string())?;
    eprintln!(
        "nimbus: merged {} parts ({}x{}, {} spp) into {} and {}",
        merged.parts,
        merged.image.width,
        merged.image.height,
        merged.spp,
        args.output.display(),
        png.display()
    );
    warn_samples(merged.nan_samples, merged.clamped_samples);
    Ok(())
}

/// A progress bar on a terminal, plain log lines otherwise (CI).
struct ProgressReporter {
    bar: Option<indicatif::ProgressBar>,
    last_logged: f64,
    /// The frame being rendered, its position in the shot and the shot's length (a still: `None`).
    frame: Option<(i64, u64, u64)>,
}

impl ProgressReporter {
    fn new() -> Self {
        let interactive = std::io::stderr().is_terminal() && std::env::var_os("CI").is_none();
        let bar = interactive.then(|| {
            let bar = indicatif::ProgressBar::new(1000);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:40} {percent:>3}% {msg} [{elapsed_precise} < {eta}]",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar
        });
        Self {
            bar,
            last_logged: -1.0,
            frame: None,
        }
    }

    /// Starts frame `frame`, the `index`-th of `count`: the bar then spans the whole shot, so its ETA is the
    /// shot's.
    fn start_frame(&mut self, frame: i64, index: u64, count: u64) {
        self.frame = Some((frame, index, count));
        self.last_logged = -1.0;
        if let Some(bar) = &self.bar {
            bar.set_length(1000 * count);
            bar.set_position(1000 * index);
        }
    }

    fn report(&mut self, p: &Progress) -> bool {
        let (done_frames, frame_label) = match self.frame {
            Some((frame, index, count)) => {
                (index, format!("frame {frame} ({}/{count}) ", index + 1))
            }
            None => (0, String::new()),
        };
        match &self.bar {
            Some(bar) => {
                bar.set_position(1000 * done_frames + (p.fraction * 1000.0) as u64);
                bar.set_message(format!("{frame_label}{} spp", p.samples_done));
            }
            None => {
                if p.fraction - self.last_logged >= 0.1 || p.fraction >= 1.0 {
                    self.last_logged = p.fraction;
                    eprintln!(
                        "nimbus: {frame_label}{:>3.0}% {} spp {:.1} s",
                        p.fraction * 100.0,
                        p.samples_done,
                        p.elapsed_seconds
                    );
                }
            }
        }
        true
    }

    /// Ends one render: the bar is cleared after a still or the shot's last frame.
    fn finish(&self) {
        let last = self
            .frame
            .is_none_or(|(_, index, count)| index + 1 == count);
        if let (Some(bar), true) = (&self.bar, last) {
            bar.finish_and_clear();
        }
    }
}
