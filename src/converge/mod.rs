//! `nimbus converge`: renders one scene with several method configurations progressively, measures the error
//! against a reference at doubling sample counts, and writes `convergence.csv`, a log-log chart
//! (`convergence.png`, `convergence.svg`, with the `charts` feature) and `summary.md`.

#[cfg(feature = "charts")]
mod chart;
mod error;
mod methods;
mod metrics;
mod summary;

#[cfg(feature = "charts")]
pub use chart::ChartError;
#[cfg(feature = "charts")]
internal! {
    pub use chart::draw_chart;
}
#[cfg(all(feature = "charts", feature = "testing"))]
pub use chart::{draw_loglog_chart, LegendCorner, LogLogChart, Series};
pub use error::ConvergeError;
pub use methods::{Method, MethodError};
pub use metrics::{ErrorMetrics, SizeMismatch};
pub use summary::{Checkpoint, Curve};
internal! {
    pub use metrics::error_metrics_against_noisy;
    pub use summary::{csv, summary_markdown};
}
#[cfg(feature = "testing")]
pub use summary::{efficiency, rmse_at, summarize, MethodSummary, CSV_HEADER};

use crate::math::Rgb;
use crate::render::{RenderSettings, Renderer};
use crate::scene::{LoadOptions, Scene};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Fewest checkpoints per method, whatever the budget.
pub(crate) const MIN_CHECKPOINTS: usize = 6;
/// The reference rendered when none is given gets this many times the whole budget.
pub(crate) const REFERENCE_BUDGET_FACTOR: f64 = 4.0;
/// Image width when neither `--width` nor a reference gives one.
pub const DEFAULT_WIDTH: usize = 96;

/// What to compare, and where to write.
#[derive(Clone, Debug)]
pub struct ConvergeOptions {
    /// The scene file.
    pub scene: PathBuf,
    /// Reference EXR (beauty = the default layer); rendered with the default method when `None`. When
    /// `STEM_se.exr` lies beside it (as `gltf2mitsuba.py --write-se` writes), its per-pixel standard errors are
    /// subtracted from the squared errors.
    pub reference: Option<PathBuf>,
    /// Methods to compare, in order.
    pub methods: Vec<Method>,
    /// Render seconds over all methods (each gets an equal share).
    pub budget_seconds: f64,
    /// Image width; default the reference's, else [`DEFAULT_WIDTH`].
    pub width: Option<usize>,
    /// Image height; default the reference's, else from the camera's aspect ratio (4:3 without one).
    pub height: Option<usize>,
    /// Output folder.
    pub output_dir: PathBuf,
    /// Seed of the methods' renders (the reference uses another).
    pub seed: u64,
    /// Worker threads, 0 = all cores.
    pub threads: usize,
}

/// Runs the comparison and writes every output; `log` receives progress lines. Returns the curves.
pub fn run(
    options: &ConvergeOptions,
    log: &mut dyn FnMut(&str),
) -> Result<Vec<Curve>, ConvergeError> {
    if !(options.budget_seconds.is_finite() && options.budget_seconds > 0.0) {
        return Err(ConvergeError::InvalidBudget(options.budget_seconds));
    }
    if options.methods.is_empty() {
        return Err(ConvergeError::NoMethods);
    }
    std::fs::create_dir_all(&options.output_dir).map_err(|source| ConvergeError::Write {
        path: options.output_dir.clone(),
        source,
    })?;
    // Every method loads the scene once; this fails early, before any rendering, where one cannot apply.
    for &method in &options.methods {
        load(&options.scene, method)?;
    }
    let Reference {
        width,
        height,
        beauty: reference,
        standard_errors: reference_se,
    } = match &options.reference {
        Some(path) => read_reference(path, options, log)?,
        None => render_reference(options, log)?,
    };
    let noise_floor = reference_se.as_ref().map(|se| {
        let sum: f64 = se.iter().map(|s| s.length_squared() as f64).sum();
        (sum / (3 * se.len().max(1)) as f64).sqrt()
    });
    let share = options.budget_seconds / options.methods.len() as f64;
    let mut curves = Vec::new();
    for &method in &options.methods {
        let scene = load(&options.scene, method)?;
        let curve = measure(
            options,
            &scene,
            (width, height),
            method,
            share,
            (&reference, reference_se.as_deref()),
        )?;
        if let Some(last) = curve.points.last() {
            log(&format!(
                "{method}: {} checkpoints, {} spp in {:.2} s, RMSE {:.4e}",
                curve.points.len(),
                last.spp,
                last.seconds,
                last.metrics.rmse
            ));
        }
        curves.push(curve);
    }
    let dir = &options.output_dir;
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        crate::output::write_atomically(&path, text.as_bytes())
            .map_err(|source| ConvergeError::Write { path, source })
    };
    write("convergence.csv", csv(&curves))?;
    let scene_name = options.scene.display().to_string();
    write(
        "summary.md",
        summary_markdown(&scene_name, width, height, &curves, noise_floor),
    )?;
    #[cfg(feature = "charts")]
    draw_chart(
        &curves,
        &dir.join("convergence.png"),
        &dir.join("convergence.svg"),
    )?;
    Ok(curves)
}

/// The image every method's error is measured against, with its per-pixel standard errors when known.
struct Reference {
    width: usize,
    height: usize,
    beauty: Vec<Rgb>,
    standard_errors: Option<Vec<Rgb>>,
}

/// Reads the `--reference` EXR at `path` (it must have the size asked for and finite values), and its standard
/// errors from the `.se.exr` beside it when that exists.
fn read_reference(
    path: &Path,
    options: &ConvergeOptions,
    log: &mut dyn FnMut(&str),
) -> Result<Reference, ConvergeError> {
    let reference_error = |reason: String| ConvergeError::Reference {
        path: path.to_path_buf(),
        reason,
    };
    let layers = crate::output::read_exr_layers(path)?;
    let beauty = layers
        .rgb("")
        .ok_or_else(|| reference_error("no R, G, B channels".into()))?;
    let (w, h) = (options.width, options.height);
    if w.is_some_and(|w| w != layers.width) || h.is_some_and(|h| h != layers.height) {
        return Err(reference_error(format!(
            "{}x{}, not the size asked for",
            layers.width, layers.height
        )));
    }
    check_finite(&beauty, layers.width).map_err(|e| reference_error(e.to_string()))?;
    let se_path = standard_error_path(path);
    let se = if se_path.is_file() {
        let se_layers = crate::output::read_exr_layers(&se_path)?;
        let se = se_layers
            .rgb("")
            .filter(|s| s.len() == beauty.len())
            .ok_or_else(|| ConvergeError::Reference {
                path: se_path.clone(),
                reason: "no R, G, B channels of the reference's size".into(),
            })?;
        check_finite(&se, layers.width).map_err(|e| ConvergeError::Reference {
            path: se_path.clone(),
            reason: e.to_string(),
        })?;
        log(&format!(
            "{}: the reference's standard errors are subtracted from the squared errors",
            se_path.display()
        ));
        Some(se)
    } else {
        None
    };
    Ok(Reference {
        width: layers.width,
        height: layers.height,
        beauty,
        standard_errors: se,
    })
}

/// Renders a reference with the default method for [`REFERENCE_BUDGET_FACTOR`] times the budget, under another seed
/// than the methods', writes it as `reference.exr`, and takes its standard errors from its own variance.
fn render_reference(
    options: &ConvergeOptions,
    log: &mut dyn FnMut(&str),
) -> Result<Reference, ConvergeError> {
    let scene = load(&options.scene, Method::Default)?;
    let width = options.width.unwrap_or(DEFAULT_WIDTH).max(1);
    let aspect = scene.camera.aspect_ratio.unwrap_or(4.0 / 3.0);
    let height = options
        .height
        .unwrap_or(((width as f32 / aspect).round() as usize).max(1))
        .max(1);
    let seconds = REFERENCE_BUDGET_FACTOR * options.budget_seconds;
    log(&format!(
        "no --reference: rendering one with the default method for {seconds:.1} s \
         ({REFERENCE_BUDGET_FACTOR}x the budget)"
    ));
    let settings = RenderSettings {
        time_limit: Some(Duration::from_secs_f64(seconds)),
        spp: u32::MAX,
        // Another seed than the methods', so that the reference's noise is independent of theirs.
        seed: options.seed ^ 0x5EED_F00D,
        ..settings(options, &scene, width, height, Method::Default)
    };
    let (image, stats) = Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .map_err(ConvergeError::Render)?;
    let path = options.output_dir.join("reference.exr");
    crate::output::write_exr(&image, &path)?;
    log(&format!(
        "wrote {} ({} spp)",
        path.display(),
        stats.samples_per_pixel
    ));
    // Its own variance of the mean gives its standard errors.
    let se = image
        .variance
        .iter()
        .map(|v| v.max(Rgb::ZERO).map(f32::sqrt))
        .collect();
    Ok(Reference {
        width,
        height,
        beauty: image.beauty,
        standard_errors: Some(se),
    })
}

/// Refuses an image with a NaN or infinite value: every error against it would be NaN, or skipped and read as 0.
/// Names the first such pixel (x, y) and channel.
fn check_finite(image: &[Rgb], width: usize) -> Result<(), NonFinitePixel> {
    for (index, pixel) in image.iter().enumerate() {
        for (channel, value) in ["R", "G", "B"].into_iter().zip(pixel.to_array()) {
            if !value.is_finite() {
                return Err(NonFinitePixel {
                    x: index % width.max(1),
                    y: index / width.max(1),
                    channel,
                    value,
                });
            }
        }
    }
    Ok(())
}

/// A reference pixel's channel that is NaN or infinite ([`check_finite`]).
#[derive(Debug, thiserror::Error)]
#[error("pixel ({x}, {y}) channel {channel} is {value}; a reference must be finite everywhere")]
struct NonFinitePixel {
    x: usize,
    y: usize,
    channel: &'static str,
    value: f32,
}

/// `DIR/STEM_se.exr` for a reference `DIR/STEM.exr`: the per-pixel standard errors of its mean.
pub(crate) fn standard_error_path(reference: &Path) -> PathBuf {
    let stem = reference
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    reference.with_file_name(format!("{stem}_se.exr"))
}

/// Loads and builds the scene with `method`'s overrides; a method that changes VDB volumes is refused on a
/// scene that has none (it would render the same image as `default`).
fn load(path: &Path, method: Method) -> Result<Scene, ConvergeError> {
    let volumes = std::cell::Cell::new(0usize);
    let apply = |spec: &mut crate::volume::VolumeSpec| {
        volumes.set(volumes.get() + 1);
        method.apply_to_volume(spec);
    };
    let options = LoadOptions {
        volume_override: Some(crate::scene::VolumeOverride::new(&apply)),
        ..LoadOptions::default()
    };
    let scene = crate::scene::load_builder(path, &options)?.build()?;
    if method.changes_volumes() && volumes.get() == 0 {
        return Err(ConvergeError::NoVolumeToChange {
            scene: path.to_path_buf(),
            method: method.name(),
        });
    }
    Ok(scene)
}

fn settings(
    options: &ConvergeOptions,
    scene: &Scene,
    width: usize,
    height: usize,
    method: Method,
) -> RenderSettings {
    RenderSettings {
        width,
        height,
        spp: u32::MAX,
        seed: options.seed,
        threads: options.threads,
        max_depth: scene.max_bounces.unwrap_or(64),
        time_limit: None,
        media_mis: method.media_mis(),
        ..RenderSettings::default()
    }
}

/// Renders `scene` with doubling passes, measuring after each, until `share` seconds would be exceeded by
/// the next pass (but at least [`MIN_CHECKPOINTS`] checkpoints).
fn measure(
    options: &ConvergeOptions,
    scene: &Scene,
    (width, height): (usize, usize),
    method: Method,
    share: f64,
    (reference, reference_se): (&[Rgb], Option<&[Rgb]>),
) -> Result<Curve, ConvergeError> {
    let mut points = Vec::new();
    let mut measuring = 0.0f64;
    let mut mismatch = None;
    Renderer::new(settings(options, scene, width, height, method))
        .render_with_snapshots(scene, &mut |p, film| {
            let start = Instant::now();
            let seconds = p.elapsed_seconds - measuring;
            let image = film.image();
            match error_metrics_against_noisy(&image.beauty, reference, reference_se) {
                Ok(metrics) => points.push(Checkpoint {
                    spp: p.samples_done,
                    seconds,
                    metrics,
                }),
                Err(e) => {
                    mismatch = Some(e);
                    return false;
                }
            }
            measuring += start.elapsed().as_secs_f64();
            // The next pass doubles the samples, so it takes about as long as everything so far.
            points.len() < MIN_CHECKPOINTS || 2.0 * seconds <= share
        })
        .map_err(ConvergeError::Render)?;
    match mismatch {
        Some(e) => Err(ConvergeError::SizeMismatch(e)),
        None => Ok(Curve { method, points }),
    }
}
