//! `nimbus._nimbus`: the Rust half of the Python module. It wraps the public API of the `nimbus` crate (scene
//! loading, [`nimbus::Renderer`], [`nimbus::output`], [`nimbus::farm`], [`nimbus::vdb`]) in a few functions and
//! two classes; python/nimbus/__init__.py builds the Python API on them (NumPy arrays, warnings, USD stages).
//!
//! Renders run on a thread of their own while the calling thread waits with the GIL released, waking every
//! [`POLL`] to run Python's signal handlers (Ctrl-C cancels the render through its [`CancelToken`]) and to hand
//! the progress callback the latest pass.

use nimbus::farm::{PartInfo, SceneOverrides};
use nimbus::limits::{one_line, Limits, MAX_MESSAGE_CHARS};
use nimbus::params::Choice;
use nimbus::render::{AovSelection, Film, GuidingMode, ImageMetadata, PixelWindow, RenderRegion};
use nimbus::scene::LoadOptions;
use nimbus::{CancelToken, RenderImage, RenderSettings, RenderStats, Renderer};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyBytes};
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

create_exception!(
    nimbus,
    Error,
    PyException,
    "Any error of Nimbus; each Rust error type is one subclass, with the same one-line message."
);
create_exception!(
    nimbus,
    SceneError,
    Error,
    "A scene file could not be loaded (names the file and the problem)."
);
create_exception!(
    nimbus,
    OutputError,
    Error,
    "An image could not be written or read."
);
create_exception!(nimbus, VdbError, Error, "A VDB file could not be read.");
create_exception!(
    nimbus,
    RegionError,
    Error,
    "A render's crop window or sample range does not fit the frame."
);
create_exception!(
    nimbus,
    FarmError,
    Error,
    "Farm parts could not be written or merged (parts of different renders, overlaps, gaps)."
);
create_exception!(
    nimbus,
    RenderError,
    Error,
    "A render could not start: its worker threads, a film over the memory budget, layers that cannot be made."
);

/// How often a waiting render wakes to run Python's signal handlers and the progress callback.
const POLL: Duration = Duration::from_millis(20);
/// The least time between two calls of the progress callback (at most ten a second).
const PROGRESS_INTERVAL: Duration = Duration::from_millis(100);

/// The Python exception of `error`: the subclass of `nimbus.Error` for its Rust type, with the CLI's one-line
/// message.
fn py_error(error: impl Into<nimbus::Error>) -> PyErr {
    let error = error.into();
    let message = one_line(&error.to_string(), MAX_MESSAGE_CHARS);
    match error {
        nimbus::Error::Scene(_) => SceneError::new_err(message),
        nimbus::Error::Output(_) => OutputError::new_err(message),
        nimbus::Error::Vdb(_) => VdbError::new_err(message),
        nimbus::Error::Region(nimbus::render::RegionError::Render(_))
        | nimbus::Error::Render(_) => RenderError::new_err(message),
        nimbus::Error::Region(_) => RegionError::new_err(message),
        nimbus::Error::Farm(_) => FarmError::new_err(message),
        other => Error::new_err(one_line(&other.to_string(), MAX_MESSAGE_CHARS)),
    }
}

/// Where a scene came from: its file, and the text of a flattened USD stage when it came from one.
#[derive(Clone)]
enum Source {
    File(PathBuf),
    Text { label: String, text: Vec<u8> },
}

/// A loaded scene, ready to render any number of times (from any thread).
#[pyclass(module = "nimbus", frozen)]
struct Scene {
    scene: Arc<nimbus::Scene>,
    source: Source,
    frame: Option<i64>,
    fps: Option<f64>,
    camera: Option<String>,
    variant: Option<String>,
    subdivision_level: Option<u32>,
    media_mis: bool,
    limits: Limits,
}

#[pymethods]
impl Scene {
    /// The loader's warnings (unknown keys, unsupported features), one line each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scene
            .warnings()
            .iter()
            .map(|w| one_line(w, MAX_MESSAGE_CHARS))
            .collect()
    }

    /// Number of triangles after instancing.
    #[getter]
    fn triangle_count(&self) -> usize {
        self.scene.triangle_count()
    }

    /// The file the scene was loaded from (a flattened USD stage: what it was composed from).
    #[getter]
    fn source(&self) -> String {
        self.label()
    }

    /// The camera's width / height, if the scene gives one.
    #[getter]
    fn aspect_ratio(&self) -> Option<f32> {
        self.scene.camera().aspect_ratio
    }

    fn __repr__(&self) -> String {
        format!(
            "<nimbus.Scene {} ({} triangles)>",
            self.label(),
            self.scene.triangle_count()
        )
    }
}

impl Scene {
    fn label(&self) -> String {
        match &self.source {
            Source::File(path) => path.display().to_string(),
            Source::Text { label, .. } => label.clone(),
        }
    }

    /// The scene hash of a part rendered with `settings`, as `nimbus render` computes it for the same file and
    /// options (so parts from either merge together).
    fn scene_hash(&self, settings: &RenderSettings) -> PyResult<u64> {
        let overrides = SceneOverrides {
            frame: self.frame,
            fps: self.fps,
            camera: self.camera.as_deref(),
            lens: self.scene.camera().lens,
            variant: self.variant.as_deref(),
            subdivision_level: self.subdivision_level,
            ..SceneOverrides::default()
        };
        let file;
        let bytes: &[u8] = match &self.source {
            Source::File(path) => {
                file = nimbus::limits::read_file(path, &self.limits)
                    .map_err(|e| OutputError::new_err(format!("{}: {e}", path.display())))?;
                &file
            }
            Source::Text { text, .. } => text,
        };
        Ok(overrides.scene_hash(&[bytes], settings, &self.scene))
    }
}

/// Why [`load`] gave no scene.
enum LoadFailure {
    /// The file could not be loaded, or the scene built.
    Scene(nimbus::SceneError),
    /// The scene (at the path) has no camera of the name asked for.
    Camera(PathBuf, nimbus::scene::UnknownCamera),
}

impl From<nimbus::SceneError> for LoadFailure {
    fn from(error: nimbus::SceneError) -> Self {
        Self::Scene(error)
    }
}

impl std::fmt::Display for LoadFailure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Scene(error) => error.fmt(f),
            Self::Camera(path, error) => write!(f, "{}: camera: {error}", path.display()),
        }
    }
}

/// Loads a scene file with the options of `nimbus render` (`source_text`: the bytes a part's scene hash takes
/// instead of the file's, for a flattened USD stage written to `path`).
#[pyfunction]
#[pyo3(signature = (path, frame=None, fps=None, volume_method=None, variant=None, subdivision_level=None,
                    strict=false, camera=None, memory_limit=None, source_text=None, source_label=None))]
#[allow(clippy::too_many_arguments)]
fn load(
    py: Python<'_>,
    path: PathBuf,
    frame: Option<i64>,
    fps: Option<f64>,
    volume_method: Option<&str>,
    variant: Option<String>,
    subdivision_level: Option<u32>,
    strict: bool,
    camera: Option<String>,
    memory_limit: Option<u64>,
    source_text: Option<Vec<u8>>,
    source_label: Option<String>,
) -> PyResult<Scene> {
    if let Some(f) = fps.filter(|f| !(f.is_finite() && *f > 0.0)) {
        return Err(PyValueError::new_err(format!(
            "fps {f} must be a positive number of frames per second"
        )));
    }
    let method = volume_method
        .map(|m| m.parse::<nimbus::converge::Method>())
        .transpose()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let limits = memory_limit.map_or_else(Limits::default, Limits::with_memory);
    let loaded = py.detach(|| -> Result<nimbus::Scene, LoadFailure> {
        let options = LoadOptions {
            limits,
            frame,
            fps,
            variant: variant.as_deref(),
            subdivision_level,
            strict,
            volume_override: method.map(nimbus::scene::VolumeOverride::method),
            ..LoadOptions::default()
        };
        let mut builder = nimbus::scene::load_builder(&path, &options)?;
        if let Some(name) = &camera {
            builder
                .select_camera(name)
                .map_err(|e| LoadFailure::Camera(path.clone(), e))?;
        }
        builder.light_by_default();
        Ok(builder.build()?)
    });
    let scene =
        loaded.map_err(|e| SceneError::new_err(one_line(&e.to_string(), MAX_MESSAGE_CHARS)))?;
    let source = match source_text {
        Some(text) => Source::Text {
            label: source_label.unwrap_or_else(|| path.display().to_string()),
            text,
        },
        None => Source::File(path),
    };
    Ok(Scene {
        scene: Arc::new(scene),
        source,
        frame,
        fps,
        camera,
        variant,
        subdivision_level,
        media_mis: method.is_none_or(|m| m.media_mis()),
        limits,
    })
}

/// A rendered image: a whole frame, or a farm part (a sample range or crop window of one) with the film sums
/// `merge` adds.
#[pyclass(module = "nimbus", frozen)]
struct RawImage {
    image: RenderImage,
    stats_json: String,
    part: Option<(Film, PartInfo)>,
}

#[pymethods]
impl RawImage {
    /// Width in pixels.
    #[getter]
    fn width(&self) -> usize {
        self.image.width
    }

    /// Height in pixels.
    #[getter]
    fn height(&self) -> usize {
        self.image.height
    }

    /// Whether this is a farm part (rendered with `samples` or `crop`).
    #[getter]
    fn is_part(&self) -> bool {
        self.part.is_some()
    }

    /// The render statistics as the JSON text `nimbus render --stats` writes.
    #[getter]
    fn stats_json(&self) -> &str {
        &self.stats_json
    }

    /// The EXR header's `nimbus/` keys.
    #[getter]
    fn metadata(&self) -> std::collections::BTreeMap<String, String> {
        self.image.metadata.nimbus.clone()
    }

    /// Every layer of the EXR as (name, component names, float32 samples interleaved row by row from the top,
    /// as a bytearray): the beauty (`R`, `G`, `B`, `A`) first, then the first-hit layers, then the rest.
    fn layers<'py>(&self, py: Python<'py>) -> Vec<(String, Vec<String>, Bound<'py, PyByteArray>)> {
        let image = &self.image;
        let mut groups: Vec<(String, Vec<String>, Vec<Vec<f32>>)> = Vec::new();
        for layer in nimbus::render::LAYERS
            .iter()
            .filter(|l| l.is_written(image))
        {
            let name = match layer.name {
                "" => "beauty",
                name => name,
            };
            let channels = (0..layer.components.len()).map(|c| layer.samples(image, c));
            let components = layer.components.iter().map(|c| c.to_string());
            match groups.iter_mut().find(|g| g.0 == name) {
                Some(group) => {
                    group.1.extend(components);
                    group.2.extend(channels);
                }
                None => groups.push((name.to_owned(), components.collect(), channels.collect())),
            }
        }
        for layer in &image.aovs {
            groups.push((
                layer.name.clone(),
                layer.components.iter().map(|c| c.to_string()).collect(),
                layer.data.clone(),
            ));
        }
        groups
            .into_iter()
            .map(|(name, components, channels)| {
                let pixels = image.width * image.height;
                let mut bytes = Vec::with_capacity(pixels * channels.len() * 4);
                for i in 0..pixels {
                    for channel in &channels {
                        bytes.extend_from_slice(&channel[i].to_ne_bytes());
                    }
                }
                (name, components, PyByteArray::new(py, &bytes))
            })
            .collect()
    }

    /// Writes the image as `nimbus render` writes its EXR (ZIP, 32-bit floats); a part as the part file
    /// `nimbus merge` reads.
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| match &self.part {
            Some((film, info)) => nimbus::farm::write_part(&path, film, info).map_err(py_error),
            None => nimbus::write_exr(&self.image, &path).map_err(py_error),
        })
    }

    /// Writes the 8-bit sRGB PNG preview, exposed by `exposure` stops (`None`: metered as `--exposure auto`).
    #[pyo3(signature = (path, exposure=0.0))]
    fn write_png(&self, py: Python<'_>, path: PathBuf, exposure: Option<f32>) -> PyResult<()> {
        py.detach(|| {
            let stops = exposure.unwrap_or_else(|| nimbus::output::meter(&self.image).auto_stops);
            nimbus::write_png_preview(&self.image, &path, stops).map_err(py_error)
        })
    }
}

/// What a render reports between passes: (samples done, samples aimed for), and whether it has ended.
#[derive(Default)]
struct Shared {
    progress: Option<(u32, u32)>,
    done: bool,
}

/// Renders `scene` as `nimbus render` does with the same options, on a thread of its own while this one waits
/// with the GIL released; Ctrl-C (a pending KeyboardInterrupt) or an exception from `progress` cancels it.
#[pyfunction]
#[pyo3(signature = (scene, spp=None, width=None, height=None, seed=0, threads=0, time_limit=None,
                    samples=None, crop=None, progress=None, max_depth=None, aovs=None, transparent=false,
                    guiding=None))]
#[allow(clippy::too_many_arguments)]
fn render(
    py: Python<'_>,
    scene: Py<Scene>,
    spp: Option<u32>,
    width: Option<usize>,
    height: Option<usize>,
    seed: u64,
    threads: usize,
    time_limit: Option<f64>,
    samples: Option<(u32, u32)>,
    crop: Option<(usize, usize, usize, usize)>,
    progress: Option<Bound<'_, PyAny>>,
    max_depth: Option<u32>,
    aovs: Option<&str>,
    transparent: bool,
    guiding: Option<&str>,
) -> PyResult<RawImage> {
    let scene = scene.get();
    let guiding = match guiding {
        None => GuidingMode::default(),
        Some(name) => GuidingMode::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = GuidingMode::CHOICES.iter().map(|(n, _)| *n).collect();
            PyValueError::new_err(format!(
                "guiding '{name}' is not one of {}",
                names.join(", ")
            ))
        })?,
    };
    if spp == Some(0) || width == Some(0) || height == Some(0) {
        return Err(PyValueError::new_err(
            "spp, width and height must be at least 1",
        ));
    }
    let time_limit = match time_limit {
        Some(t) => Some(Duration::try_from_secs_f64(t).map_err(|_| {
            PyValueError::new_err(format!(
                "time_limit {t} is not a non-negative number of seconds"
            ))
        })?),
        None => None,
    };
    let aovs = aovs
        .map(AovSelection::parse)
        .transpose()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let (width, height) = RenderSettings::frame_size(&scene.scene, width, height);
    let spp = spp.unwrap_or(if time_limit.is_some() { u32::MAX } else { 64 });
    let settings = RenderSettings {
        width,
        height,
        spp,
        seed,
        threads,
        max_depth: RenderSettings::max_depth_for(&scene.scene, max_depth),
        time_limit,
        media_mis: scene.media_mis,
        limits: scene.limits,
        aovs,
        transparent,
        guiding,
        ..RenderSettings::default()
    };
    let is_part = samples.is_some() || crop.is_some();
    let region = render_region(samples, crop, &settings)?;
    let hash = scene.scene_hash(&settings)?;
    let renderer = Renderer::new(settings);
    let (film, stats) = render_on_worker(py, &renderer, &scene.scene, &region, progress.as_ref())?;
    let stats_json = stats_json(&stats)?;
    let metadata = ImageMetadata::for_render(
        &scene.scene,
        renderer.settings(),
        &scene.label(),
        scene.frame,
        hash,
        &stats,
    );
    let part = is_part.then(|| {
        PartInfo::new(renderer.settings(), hash, &region, &stats).with_metadata(metadata.clone())
    });
    Ok(raw_image(film, &stats, stats_json, metadata, part))
}

/// The image of a finished render with its header attributes: a part keeps its film and its description (for
/// `write_part`); a whole render's header records its samples per pixel.
fn raw_image(
    film: Film,
    stats: &RenderStats,
    stats_json: String,
    metadata: ImageMetadata,
    part: Option<PartInfo>,
) -> RawImage {
    let mut image = film.image();
    image.metadata = metadata;
    match part {
        Some(info) => RawImage {
            image,
            stats_json,
            part: Some((film, info)),
        },
        None => {
            image
                .metadata
                .nimbus
                .insert("spp".into(), stats.samples_per_pixel.to_string());
            RawImage {
                image,
                stats_json,
                part: None,
            }
        }
    }
}

/// The region a render covers: the `crop` window (x0, y0, x1, y1) of the frame (all of it without one) and the
/// `samples` range start..end (0..spp without one), which may not go past `spp`.
fn render_region(
    samples: Option<(u32, u32)>,
    crop: Option<(usize, usize, usize, usize)>,
    settings: &RenderSettings,
) -> PyResult<RenderRegion> {
    let (width, height, spp) = (settings.width, settings.height, settings.spp);
    let region = RenderRegion {
        window: crop.map_or(PixelWindow::full(width, height), |(x0, y0, x1, y1)| {
            PixelWindow { x0, y0, x1, y1 }
        }),
        samples: samples.map_or(0..spp.max(1), |(start, end)| start..end),
    };
    if region.samples.end > spp {
        return Err(RegionError::new_err(format!(
            "samples {}..{} go past spp {spp}",
            region.samples.start, region.samples.end
        )));
    }
    Ok(region)
}

/// Renders `region` of `scene` with `renderer` on a thread of its own while this one [`wait`]s with the GIL
/// released, calling `progress`; Ctrl-C or an exception from `progress` cancels the render and is returned.
fn render_on_worker(
    py: Python<'_>,
    renderer: &Renderer,
    scene: &nimbus::Scene,
    region: &RenderRegion,
    progress: Option<&Bound<'_, PyAny>>,
) -> PyResult<(Film, RenderStats)> {
    let cancel = CancelToken::new();
    let shared = (Mutex::new(Shared::default()), Condvar::new());
    let total = region.samples.len() as u32;
    let result = std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let result = renderer.render_resumable(
                scene,
                region,
                None,
                &mut |p, _| {
                    if let Ok(mut state) = shared.0.lock() {
                        state.progress = Some((p.samples_done, total));
                    }
                    shared.1.notify_all();
                    true
                },
                &cancel,
            );
            if let Ok(mut state) = shared.0.lock() {
                state.done = true;
            }
            shared.1.notify_all();
            result
        });
        let outcome = wait(py, &shared, progress);
        if outcome.is_err() {
            cancel.cancel();
        }
        let result = py.detach(|| worker.join());
        outcome.map(|()| result)
    })?;
    match result {
        Ok(r) => r.map(|(film, stats, _)| (film, stats)).map_err(py_error),
        Err(_) => Err(Error::new_err("the render thread panicked")),
    }
}

/// Waits for the render of `shared` to end with the GIL released, waking every [`POLL`] to run Python's
/// signal handlers and to call `progress` with the latest pass (at most every [`PROGRESS_INTERVAL`], and once
/// more with the last pass). An exception from either ends the wait.
fn wait(
    py: Python<'_>,
    shared: &(Mutex<Shared>, Condvar),
    progress: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let mut reported: Option<(u32, u32)> = None;
    let mut last_call: Option<Instant> = None;
    loop {
        let (latest, done) = py.detach(|| {
            let state = shared.0.lock().unwrap_or_else(|e| e.into_inner());
            let (state, _) = shared
                .1
                .wait_timeout_while(state, POLL, |s| !s.done)
                .unwrap_or_else(|e| e.into_inner());
            (state.progress, state.done)
        });
        py.check_signals()?;
        if let (Some(callback), Some(p)) = (progress, latest) {
            let due = last_call.is_none_or(|t| t.elapsed() >= PROGRESS_INTERVAL);
            if reported != Some(p) && (due || done) {
                callback.call1(p)?;
                reported = Some(p);
                last_call = Some(Instant::now());
            }
        }
        if done {
            return Ok(());
        }
    }
}

/// The statistics as `nimbus render --stats` writes them.
fn stats_json(stats: &RenderStats) -> PyResult<String> {
    serde_json::to_string(stats).map_err(|e| Error::new_err(e.to_string()))
}

/// The `nimbus info --json` text of a VDB file.
#[pyfunction]
fn info_json(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    let info = py
        .detach(|| nimbus::vdb::file_info(&path))
        .map_err(py_error)?;
    serde_json::to_string(&info).map_err(|e| Error::new_err(e.to_string()))
}

/// Merges the part files at `paths` as `nimbus merge` does: the image one render would have made, bit for bit.
#[pyfunction]
fn merge(py: Python<'_>, paths: Vec<PathBuf>) -> PyResult<RawImage> {
    let merged = py
        .detach(|| nimbus::farm::merge_parts(&paths))
        .map_err(py_error)?;
    let stats = RenderStats {
        samples_per_pixel: merged.spp,
        nan_samples: merged.nan_samples,
        clamped_samples: merged.clamped_samples,
        ..RenderStats::default()
    };
    Ok(RawImage {
        image: merged.image,
        stats_json: stats_json(&stats)?,
        part: None,
    })
}

/// The PNG preview of `image` as bytes (for notebooks), exposed by `exposure` stops.
#[pyfunction]
fn png_bytes<'py>(
    py: Python<'py>,
    image: &RawImage,
    exposure: f32,
    scratch: PathBuf,
) -> PyResult<Bound<'py, PyBytes>> {
    let bytes = py.detach(|| -> PyResult<Vec<u8>> {
        nimbus::write_png_preview(&image.image, &scratch, exposure).map_err(py_error)?;
        let bytes = std::fs::read(&scratch)
            .map_err(|e| OutputError::new_err(format!("{}: {e}", scratch.display())));
        let _ = std::fs::remove_file(&scratch);
        bytes
    })?;
    Ok(PyBytes::new(py, &bytes))
}

/// The extension module.
#[pymodule]
fn _nimbus(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Error", py.get_type::<Error>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add("VdbError", py.get_type::<VdbError>())?;
    m.add("RegionError", py.get_type::<RegionError>())?;
    m.add("FarmError", py.get_type::<FarmError>())?;
    m.add("RenderError", py.get_type::<RenderError>())?;
    m.add_class::<Scene>()?;
    m.add_class::<RawImage>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(info_json, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(png_bytes, m)?)?;
    Ok(())
}
