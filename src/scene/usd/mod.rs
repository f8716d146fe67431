//! USD loader (`.usd`, `.usda`, `.usdc`, `.usdz`), on top of the `openusd` crate, which parses the three
//! encodings and composes sublayers, references and payloads. Nimbus reads the composed stage at one time code
//! (see `read_at_time`: `startTimeCode`, else each attribute's earliest sample) and maps it onto the same scene
//! model as glTF. Under a motion-blur shutter it reads the stage again at each motion step and keeps what moved
//! (`add_motion_steps`).
//!
//! Stage metadata read: `upAxis` (`"Z"` is rotated −90° about X to Nimbus's +Y up) and `metersPerUnit`
//! (everything is scaled to metres).
//!
//! Prims and attributes read:
//! - every prim: `xformOpOrder` with the ops `translate`, `pivot` (a translate), `scale`, `rotateX/Y/Z`,
//!   `rotateXYZ`/`XZY`/`YXZ`/`YZX`/`ZXY`/`ZYX` (degrees), `orient` (quaternion) and `transform` (matrix4d),
//!   with `!invert!` and `!resetXformStack!`, composed through the hierarchy; `active`, `visibility`
//!   (`invisible` hides the subtree), the specifier (only `def` prims are drawn, not `class` or `over`);
//!   `material:binding` (inherited by descendants);
//! - `Mesh`: `points`, `faceVertexCounts`, `faceVertexIndices` (polygons triangulated as fans), `normals` /
//!   `primvars:normals` and `primvars:st` (with `interpolation` vertex, varying, faceVarying, uniform or
//!   constant, and `:indices`), `orientation` (`leftHanded` flips the winding), `doubleSided`,
//!   `primvars:displayColor` (the diffuse colour of an unbound mesh); `GeomSubset` children of the
//!   `materialBind` family bind materials per face;
//! - the gprims `Cube`, `Sphere`, `Cylinder`, `Cone`, `Capsule`, `Plane`, tessellated (`usd/shapes.rs`);
//! - `PointInstancer` (`usd/instancing.rs`) and native instances (composed by `openusd` as instance proxies):
//!   static prototype meshes read once and placed as instances, the rest copied to world meshes;
//! - `Camera` (every one, named by its prim name and path; the first met renders unless another is chosen):
//!   `projection` (`perspective`: yfov from `verticalAperture` and `focalLength`; `orthographic`: a film
//!   `horizontalAperture` by `verticalAperture` tenths of a scene unit), the aspect ratio from the apertures'
//!   ratio, and depth of field from `fStop` (0: none) and `focusDistance`: aperture radius = focalLength / 10 /
//!   (2 fStop) scene units (UsdGeomCamera's units: apertures and focal length in tenths of a scene unit); lengths
//!   in metres through the camera's world scale (`metersPerUnit` and any xform scale, its x axis's); clipping
//!   is ignored;
//! - `Material` → `outputs:surface` → a `UsdPreviewSurface` `Shader` (`info:id`): `inputs:diffuseColor`,
//!   `emissiveColor`, `metallic`, `roughness`, `opacity`, `ior`, `normal`, `useSpecularWorkflow` (see
//!   `usd/shading.rs` for the mapping); colour and normal inputs may connect to a `UsdUVTexture`
//!   (`inputs:file`, read from the `.usdz` package when its layer is inside one, `inputs:sourceColorSpace`,
//!   `inputs:scale`, `inputs:bias`); a texture that cannot be read or a `.mtlx` file is a warning;
//! - UsdLux (`inputs:intensity`, `inputs:exposure`, `inputs:color`, `inputs:normalize`): `RectLight`
//!   (`inputs:width`, `inputs:height`), `DiskLight` (`inputs:radius`), `SphereLight` (`inputs:radius`,
//!   `treatAsPoint`), `DistantLight` (`inputs:angle` ignored), `DomeLight` (`inputs:texture:file`);
//! - UsdVol: `Volume` with `field:density` / `field:temperature` relationships to `OpenVDBAsset` prims
//!   (`filePath`, `fieldName`, `fieldIndex`), and the `nimbus:` attributes of [`VolumeSpec`].
//!
//! Lights: the emitted radiance is `color × intensity × 2^exposure`, divided by the light's world-space area
//! when `normalize` is set (UsdLux). Rect and disk lights become one-sided emissive meshes emitting along the
//! −Z axis of their frame; sphere lights become emissive spheres, or with `treatAsPoint` a point light of
//! intensity `L·πr²` (the intensity of a sphere of radiance L). A dome light maps its texture with Nimbus's
//! latitude–longitude contract (see [`crate::light::EnvironmentLight`]: top row +Y, u = 0 toward −Z,
//! u = 0.25 toward +X) after the up-axis correction, so the top row is the stage's up axis; the dome's rotation
//! relative to the stage is ignored (a warning says so). A dome without texture is a constant environment.
//!
//! Asset paths (`filePath`, `inputs:file`, `inputs:texture:file`) resolve relative to the layer that authored
//! them. Prim types Nimbus does not render are listed once each in the warnings.
//!
//! The loader is split by USD schema domain: `xform` (UsdGeomXformable ops), `geom` (meshes and primvars),
//! `shapes` (intrinsic gprims), `instancing` (UsdGeomPointInstancer),
//! `shading` (UsdShade / UsdPreviewSurface), `lux` (UsdLux), `vol` (UsdVol), with `values` converting
//! attribute values, `layers` checking every layer (text nesting, packages), `crate_check` bounds-checking
//! `.usdc` layers before openusd reads them, and `composition` checking the arcs between them before openusd
//! composes them.

mod composition;
mod crate_check;
mod geom;
mod instancing;
mod layers;
mod lux;
mod shading;
mod shapes;
mod values;
mod vol;
mod xform;

use super::camera::{Camera, CameraMotion, NamedCamera, Projection, ThinLens};
use super::{report_unknown_keys, LoadOptions, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::{CompositingTags, Mesh, MeshMotion, MotionSteps};
use crate::limits::{catch_quietly, one_line, read_file, Limits};
use crate::math::{Mat4, Rgb, Vec3};
use crate::params::{closest_name, UnknownKey, UsdBinding};
use crate::scene::MalformedPart;
use crate::volume::spec::VOLUME_KEYS;
use crate::volume::VolumeSpec;
use openusd::{ar, pcp, sdf, usd};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use values::{number, token, vec3};

/// Deepest prim hierarchy read (guards the recursion).
const MAX_DEPTH: usize = 256;

/// Prim types that carry nothing to render by themselves (grouping, shading networks, volume fields).
const STRUCTURAL_TYPES: &[&str] = &[
    "",
    "Xform",
    "Scope",
    "Material",
    "Shader",
    "NodeGraph",
    "OpenVDBAsset",
    "GeomSubset",
];

/// Stack of the thread that parses and reads a stage: `openusd` recurses once per nesting level of a layer,
/// and [`MAX_NESTING`] levels must fit whatever the caller's stack (the main thread has 8 MiB, rayon's
/// workers 2 MiB).
pub const READER_STACK_BYTES: usize = 64 << 20;

/// How long the reader thread may take before the load gives up with an error (the thread is then left to
/// finish on its own): a guard against compositions that `openusd` resolves in pathological time.
pub const READER_TIME_LIMIT: std::time::Duration = std::time::Duration::from_secs(120);

#[cfg(feature = "testing")]
pub use layers::MAX_NESTING;

/// Loads a USD stage and adds its volumes (see [`read_with_limits`]), each passed through the options' volume
/// override first.
/// A shot frame ([`LoadOptions::frame`]) reads every attribute at that frame's time code (see [`read_at_frame`]).
pub fn load(path: &Path, options: &LoadOptions) -> Result<SceneBuilder, SceneError> {
    // A still with a shutter is frame 1 of the shot, as glTF files and VDB sequences read it.
    let frame = options.frame.or(options.shutter.map(|_| 1));
    let when = match frame {
        Some(frame) => When::Frame(frame as f64, options.fps),
        None => When::Default,
    };
    let (mut builder, volumes) = read_when(
        path,
        &options.limits,
        when,
        options.subdivision_level,
        options.strict,
    )?;
    if let (Some(frame), Some(shutter)) = (frame, options.shutter) {
        add_motion_steps(&mut builder, path, options, frame, shutter)?;
    }
    for mut spec in volumes {
        options.apply_volume_override(&mut spec);
        builder.add_volume(&spec).map_err(|source| {
            SceneError::new(
                path,
                SceneErrorKind::Volume {
                    at: spec.name.as_str().into(),
                    source,
                },
            )
        })?;
    }
    Ok(builder)
}

/// Motion steps of a stage under a shutter: the stage is read again at each of [`USD_MOTION_STEPS`] times evenly
/// spread over the shutter (frame + t), and every mesh whose points there differ from the frame's (animated
/// xforms of it or its ancestors, time-sampled points) keeps its world positions and normals at each step, as
/// the camera keeps its poses. The prim walk visits prims in the same order at every time, so meshes pair up by
/// position; a stage whose meshes change across the shutter (visibility, topology) is not blurred, with a
/// warning.
fn add_motion_steps(
    builder: &mut SceneBuilder,
    path: &Path,
    options: &LoadOptions,
    frame: i64,
    shutter: crate::frames::Shutter,
) -> Result<(), SceneError> {
    let times = shutter.sample_times(USD_MOTION_STEPS);
    let steps = MotionSteps {
        open: shutter.open,
        close: shutter.close,
        count: USD_MOTION_STEPS as u32,
    };
    let mut reads = Vec::with_capacity(times.len());
    for t in times {
        let when = When::Frame(frame as f64 + t as f64, options.fps);
        reads.push(
            read_when(
                path,
                &options.limits,
                when,
                options.subdivision_level,
                options.strict,
            )?
            .0,
        );
    }
    let same_meshes = reads.iter().all(|r| {
        r.meshes.len() == builder.meshes.len()
            && r.meshes
                .iter()
                .zip(&builder.meshes)
                .all(|(a, b)| a.indices == b.indices && a.positions.len() == b.positions.len())
    });
    if !same_meshes {
        builder.warn(format!(
            "{}: the stage's meshes change across the shutter (visibility or topology); not motion-blurred",
            path.display()
        ));
        return Ok(());
    }
    for (i, mesh) in builder.meshes.iter_mut().enumerate() {
        if reads
            .iter()
            .all(|r| r.meshes[i].positions == mesh.positions)
        {
            continue;
        }
        mesh.motion = Some(MeshMotion {
            steps,
            positions: reads
                .iter()
                .map(|r| r.meshes[i].positions.clone())
                .collect(),
            normals: reads.iter().map(|r| r.meshes[i].normals.clone()).collect(),
        });
    }
    if let Some(camera) = &mut builder.camera {
        let poses: Vec<Mat4> = reads
            .iter()
            .filter_map(|r| r.camera.as_ref().map(|c| c.camera_to_world))
            .collect();
        if poses.len() == reads.len() && poses.iter().any(|p| *p != camera.camera_to_world) {
            camera.motion = Some(CameraMotion::from_matrices(steps, &poses));
        }
    }
    Ok(())
}

/// Motion steps of a USD stage under a shutter (each one a read of the stage).
pub const USD_MOTION_STEPS: usize = 3;

/// [`read_with_limits`] with the default memory budget.
#[cfg(any(test, feature = "testing"))]
pub fn read(path: &Path) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    read_with_limits(path, &Limits::default())
}

/// Reads a USD stage into a builder, returning the `Volume` prims as [`VolumeSpec`]s not yet added.
///
/// Every layer is read with the size cap of `limits` and checked before `openusd` parses it (see `layers`
/// and `crate_check`): text nested deeper than [`MAX_NESTING`] levels is refused, `.usdc` counts are
/// bounds-checked, `.usdz` entries are decompressed with a cap. The whole read runs on a thread of its own
/// with a [`READER_STACK_BYTES`] stack, given up after [`READER_TIME_LIMIT`]. `openusd` 0.6 still indexes out of bounds on some damaged `.usdc`
/// files: such a panic is caught without printing anything and returned as
/// [`SceneErrorKind::ReaderPanicked`].
#[cfg(any(test, feature = "testing"))]
pub fn read_with_limits(
    path: &Path,
    limits: &Limits,
) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    read_when(path, limits, When::Default, None, false)
}

/// When a stage is read: at its default time, at a time code, or at a frame of the shot.
#[derive(Clone, Copy)]
enum When {
    Default,
    #[cfg(any(test, feature = "testing"))]
    TimeCode(f64),
    /// A frame of the shot, at the shot's frames per second if given (else the stage's `framesPerSecond`).
    Frame(f64, Option<f64>),
}

/// [`read_with_limits`] at frame `frame` of the shot, or at the stage's default time when `None`. A frame is
/// a time in seconds at the stage's `framesPerSecond` (default 24), read at time code
/// `frame × timeCodesPerSecond / framesPerSecond` (`timeCodesPerSecond` default 24): frame 12 of a stage at 24
/// time codes and 24 frames per second reads time code 12, and of one at 48 time codes per second, 24.
#[cfg(any(test, feature = "testing"))]
pub fn read_at_frame(
    path: &Path,
    limits: &Limits,
    frame: Option<i64>,
) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    read_when(
        path,
        limits,
        frame.map_or(When::Default, |f| When::Frame(f as f64, None)),
        None,
        false,
    )
}

/// [`read_with_limits`] at time code `time` (in the stage's time codes, not seconds: a frame at `s` seconds is
/// time code `s × timeCodesPerSecond`), or at the stage's default time when `None`: its `startTimeCode`
/// metadata if authored, else the earliest time sample of each attribute. Every attribute is read at that time:
/// time samples are interpolated linearly between the bracketing samples (quaternions by slerp) and held
/// beyond the first and last (AOUSD Core §12.5); an attribute without samples gives its default value.
#[cfg(any(test, feature = "testing"))]
pub fn read_at_time(
    path: &Path,
    limits: &Limits,
    time: Option<f64>,
) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    read_when(
        path,
        limits,
        time.map_or(When::Default, When::TimeCode),
        None,
        false,
    )
}

/// Reads the stage at `when` on a reader thread of its own (see [`read_with_limits`]); `strict` refuses
/// `nimbus:` attributes that no table declares ([`LoadOptions::strict`]).
fn read_when(
    path: &Path,
    limits: &Limits,
    time: When,
    subdivision_level: Option<u32>,
    strict: bool,
) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    let limits = *limits;
    let owned = path.to_path_buf();
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("nimbus-usd".into())
        .stack_size(READER_STACK_BYTES)
        .spawn(move || {
            let read =
                catch_quietly(|| read_stage(&owned, &limits, time, subdivision_level, strict))
                    .unwrap_or_else(|message| {
                        Err(SceneError::new(
                            &owned,
                            SceneErrorKind::ReaderPanicked {
                                reader: "openusd",
                                message: one_line(&message.0, MESSAGE_CHARS),
                            },
                        ))
                    });
            let _ = send.send(read);
        })
        .map_err(|e| SceneError::new(path, SceneErrorKind::Io(e)))?;
    receive.recv_timeout(READER_TIME_LIMIT).unwrap_or_else(|e| {
        let message = match e {
            std::sync::mpsc::RecvTimeoutError::Timeout => format!(
                "did not finish reading the stage within {} s",
                READER_TIME_LIMIT.as_secs()
            ),
            std::sync::mpsc::RecvTimeoutError::Disconnected => "the reader thread failed".into(),
        };
        Err(SceneError::new(
            path,
            SceneErrorKind::ReaderPanicked {
                reader: "openusd",
                message,
            },
        ))
    })
}

fn read_stage(
    path: &Path,
    limits: &Limits,
    time: When,
    subdivision_level: Option<u32>,
    strict: bool,
) -> Result<(SceneBuilder, Vec<VolumeSpec>), SceneError> {
    let stage = open(path, limits)?;
    let mut loader = Loader {
        path,
        stage: &stage,
        builder: SceneBuilder::with_limits(*limits),
        volumes: Vec::new(),
        materials: HashMap::new(),
        primvar_colors: HashMap::new(),
        textures: HashMap::new(),
        transformed_textures: HashMap::new(),
        unsupported: HashSet::new(),
        native: HashMap::new(),
        root: Mat4::IDENTITY,
        limits: *limits,
        prims: 0,
        subdivision_level,
        strict,
        time: usd::TimeCode::EARLIEST,
        packages: HashMap::new(),
        tags: CompositingTags::default(),
        asset: String::new(),
    };
    loader.root = loader.stage_root()?;
    loader.time = match time {
        #[cfg(any(test, feature = "testing"))]
        When::TimeCode(t) => usd::TimeCode::new(t),
        When::Frame(f, fps) => usd::TimeCode::new(f * loader.time_codes_per_frame(fps)?),
        When::Default => loader.default_time()?,
    };
    for child in loader.children(&stage.prim("/"))? {
        loader.visit(&child, loader.root, None, 0)?;
    }
    // References and payloads report their errors as the prims that use them are composed.
    let skipped = composition_errors(path, &stage)?;
    loader.builder.warnings.extend(skipped);
    Ok((loader.builder, loader.volumes))
}

/// Opens and composes a stage; any parse or composition error is a [`SceneError`] naming the layer. The root
/// layer is read and checked here first, so that an unreadable or hostile root is an error about that file, and
/// the arcs of every layer it reaches are checked before `openusd` composes them (see `composition`).
fn open(path: &Path, limits: &Limits) -> Result<usd::Stage, SceneError> {
    let bytes =
        read_file(path, limits).map_err(|e| SceneError::new(path, SceneErrorKind::Io(e)))?;
    layers::check_layer(&bytes, limits)
        .map_err(|e| malformed(path, MalformedPart::File, e.to_string()))?;
    drop(bytes);
    let name = path.to_str().ok_or_else(|| {
        malformed(
            path,
            MalformedPart::File,
            "the path is not valid UTF-8".into(),
        )
    })?;
    let resolver = || crate_check::CheckingResolver {
        inner: ar::DefaultResolver::new(),
        limits: *limits,
    };
    composition::check(name, &resolver(), limits)
        .map_err(|e| malformed(path, MalformedPart::File, e.to_string()))?;
    let stage = usd::Stage::builder()
        .resolver(resolver())
        .open(name)
        .map_err(|e| malformed(path, MalformedPart::File, format!("{e:#}")))?;
    // Only the errors here; their warnings are collected once the whole stage is read.
    composition_errors(path, &stage)?;
    Ok(stage)
}

/// The composition errors met so far, as one error, and the problems that are only warnings. As usdview does,
/// an arc whose target is missing is skipped with a warning and the rest of the stage is read: a sublayer, a
/// reference or a payload naming a layer that does not exist, to a prim the layer does not define, or to a layer without a
/// `defaultPrim`, and an arc to a muted layer. So is an arc to a MaterialX document (`.mtlx`, which `openusd`
/// cannot read as a layer): the prims it would have brought fall back to defaults. Cycles, layers that exist but
/// do not parse, and malformed arcs stay errors.
fn composition_errors(path: &Path, stage: &usd::Stage) -> Result<Vec<String>, SceneError> {
    let mut warnings = Vec::new();
    let mut errors = Vec::new();
    for error in stage.composition_errors() {
        let text = one_line(&error.to_string(), MESSAGE_CHARS);
        if text.to_ascii_lowercase().contains(".mtlx") {
            warnings.push(format!(
                "{text}; MaterialX documents are not read, the prims they define use defaults"
            ));
            continue;
        }
        match error {
            pcp::Error::UnresolvedLayer { .. }
            | pcp::Error::UnresolvedSublayer { .. }
            | pcp::Error::UnresolvedPrimPath { .. }
            | pcp::Error::MissingDefaultPrim { .. }
            | pcp::Error::MutedAssetPath { .. } => warnings.push(format!(
                "{text}; the arc is skipped, the rest of the stage is read"
            )),
            _ => errors.push(text),
        }
    }
    if !errors.is_empty() {
        return Err(malformed(
            path,
            MalformedPart::File,
            format!("composition: {}", errors.join("; ")),
        ));
    }
    Ok(warnings)
}

/// Longest message quoted from `openusd` (its errors can quote a whole layer's text).
const MESSAGE_CHARS: usize = 600;

/// A malformed-file error, its message cut to one printable line (it may quote the file).
fn malformed(path: &Path, part: MalformedPart, message: String) -> SceneError {
    SceneError::new(
        path,
        SceneErrorKind::malformed(part, one_line(&message, MESSAGE_CHARS)),
    )
}

/// Why an asset file (a texture) named by the stage could not be read.
#[derive(Debug, thiserror::Error)]
enum AssetError {
    /// The file on disk cannot be read.
    #[error("{0}")]
    File(std::io::Error),
    /// The `.usdz` package holding it cannot be opened, or its entry read.
    #[error(transparent)]
    Package(#[from] layers::LayerError),
    /// The package holds no such entry.
    #[error("the package {} holds no file '{member}'", package.display())]
    NotInPackage {
        /// The package file.
        package: PathBuf,
        /// The path inside it.
        member: String,
    },
}

struct Loader<'a> {
    path: &'a Path,
    stage: &'a usd::Stage,
    builder: SceneBuilder,
    volumes: Vec<VolumeSpec>,
    /// (material prim path, double-sided) → material index.
    materials: HashMap<(String, bool), u32>,
    /// Materials whose base colour a mesh primvar gives per vertex (a `UsdPrimvarReader_float3` on
    /// `diffuseColor`, or an unbound mesh's varying `displayColor`): material index → the primvar.
    primvar_colors: HashMap<u32, shading::PrimvarColor>,
    /// Texture file, colour space, role and scale/bias → texture index.
    textures: HashMap<shading::TextureKey, u32>,
    /// (texture index, the bits of a `UsdTransform2d`'s offset, rotation and scale) → the texture read
    /// through it.
    transformed_textures: HashMap<(u32, [u32; 5]), u32>,
    unsupported: HashSet<String>,
    /// What each native instance prototype (by prototype path and inherited material binding) became.
    native: HashMap<(String, Option<String>), instancing::NativePrototype>,
    /// Stage units and up axis to Nimbus's metres and +Y up.
    root: Mat4,
    /// The memory budget for textures and environment maps, and the most prims to read.
    limits: Limits,
    /// Prims visited so far.
    prims: u64,
    /// `--subdivision-level`: the Catmull-Clark level of every `catmullClark` mesh, over its `refineLevel`.
    subdivision_level: Option<u32>,
    /// `--strict`: unknown `nimbus:` attributes are errors, not warnings.
    strict: bool,
    /// The time code every attribute is read at (see `read_at_time`).
    time: usd::TimeCode,
    /// `.usdz` packages opened for the files inside them, by package path.
    packages: HashMap<PathBuf, layers::Package>,
    /// The compositing tags of the prim being visited: its own `nimbus:` attributes over its ancestors'.
    tags: CompositingTags,
    /// Cryptomatte's asset for the prim being visited: the nearest enclosing `component` model, else the
    /// top-level prim.
    asset: String,
}

/// The `nimbus:` attributes of the compositing tags, which any prim may hold (without the namespace).
const TAG_ATTRIBUTES: &[&str] = &["lightGroup", "holdout", "shadowCatcher"];

impl Loader<'_> {
    /// An error about a malformed `part` of the stage, found at `at` (a prim path, or `stage metadata`).
    fn error(&self, part: MalformedPart, at: &str, message: impl std::fmt::Display) -> SceneError {
        malformed(self.path, part, format!("{at}: {message}"))
    }

    fn warn(&mut self, message: String) {
        self.builder.warnings.push(message);
    }

    /// The stage's default time: `startTimeCode` if authored, else the earliest sample of each attribute.
    fn default_time(&self) -> Result<usd::TimeCode, SceneError> {
        let start = self
            .stage
            .stage_metadata("startTimeCode")
            .map_err(|e| {
                self.error(
                    MalformedPart::File,
                    "stage metadata",
                    format!("startTimeCode: {e:#}"),
                )
            })?
            .and_then(|v| number(&v))
            .filter(|t| t.is_finite());
        Ok(start.map_or(usd::TimeCode::EARLIEST, usd::TimeCode::new))
    }

    /// Time codes per frame of the shot: `timeCodesPerSecond / fps`, `fps` the shot's if given, else the
    /// stage's `framesPerSecond` (both default 24).
    fn time_codes_per_frame(&self, fps: Option<f64>) -> Result<f64, SceneError> {
        let fps = match fps {
            Some(f) => f,
            None => self.frames_per_second()?,
        };
        Ok(self.stage_rate("timeCodesPerSecond")? / fps)
    }

    /// The stage's `framesPerSecond` (default 24).
    fn frames_per_second(&self) -> Result<f64, SceneError> {
        self.stage_rate("framesPerSecond")
    }

    /// A positive rate from the stage metadata `key` (default 24).
    fn stage_rate(&self, key: &str) -> Result<f64, SceneError> {
        let value = self
            .stage
            .stage_metadata(key)
            .map_err(|e| {
                self.error(
                    MalformedPart::File,
                    "stage metadata",
                    format!("{key}: {e:#}"),
                )
            })?
            .and_then(|v| number(&v))
            .unwrap_or(24.0);
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(self.error(
                MalformedPart::File,
                "stage metadata",
                format!("{key} {value} must be positive"),
            ))
        }
    }

    /// The matrix from stage units and axes to Nimbus's metres and +Y up.
    fn stage_root(&self) -> Result<Mat4, SceneError> {
        let meta = |key: &str| {
            self.stage.stage_metadata(key).map_err(|e| {
                self.error(
                    MalformedPart::File,
                    "stage metadata",
                    format!("{key}: {e:#}"),
                )
            })
        };
        let up = meta("upAxis")?.and_then(|v| token(&v));
        let mpu = meta("metersPerUnit")?
            .and_then(|v| number(&v))
            .unwrap_or(1.0);
        if !(mpu.is_finite() && mpu > 0.0) {
            return Err(self.error(
                MalformedPart::File,
                "stage metadata",
                format!("metersPerUnit {mpu} must be positive"),
            ));
        }
        let rotate = match up.as_deref() {
            Some("Z") => Mat4::from_rotation_x(-std::f32::consts::FRAC_PI_2),
            _ => Mat4::IDENTITY,
        };
        Ok(rotate * Mat4::from_scale(Vec3::splat(mpu as f32)))
    }

    fn children(&self, prim: &usd::Prim) -> Result<Vec<usd::Prim>, SceneError> {
        prim.children()
            .map_err(|e| self.error(MalformedPart::Node, prim.path().as_str(), format!("{e:#}")))
    }

    /// The value of attribute `name` on `prim` at the loader's time code, if authored. A name that is not a USD property name (identifiers joined by
    /// `:`) is an error before `openusd` sees it: names come from the file too (`xformOpOrder`), and `openusd`
    /// resolving a malformed one (a line break inside, from a damaged string) walked path parents for minutes.
    fn value(&self, prim: &usd::Prim, name: &str) -> Result<Option<sdf::Value>, SceneError> {
        if !is_property_name(name) {
            return Err(self.error(
                MalformedPart::Node,
                prim.path().as_str(),
                format!(
                    "'{}' is not a valid attribute name",
                    one_line(name, MESSAGE_CHARS / 4)
                ),
            ));
        }
        prim.attribute(name)
            .get_at::<sdf::Value>(self.time)
            .map_err(|e| {
                self.error(
                    MalformedPart::Node,
                    &format!("{}.{name}", prim.path().as_str()),
                    format!("{e:#}"),
                )
            })
    }

    fn float(&self, prim: &usd::Prim, name: &str, default: f32) -> Result<f32, SceneError> {
        match self.value(prim, name)? {
            None => Ok(default),
            Some(v) => number(&v)
                .filter(|x| x.is_finite())
                .map(|x| x as f32)
                .ok_or_else(|| {
                    self.error(
                        MalformedPart::Node,
                        &format!("{}.{name}", prim.path().as_str()),
                        "expected a number",
                    )
                }),
        }
    }

    fn color(&self, prim: &usd::Prim, name: &str, default: Rgb) -> Result<Rgb, SceneError> {
        match self.value(prim, name)? {
            None => Ok(default),
            Some(v) => vec3(&v).filter(|c| c.is_finite()).ok_or_else(|| {
                self.error(
                    MalformedPart::Node,
                    &format!("{}.{name}", prim.path().as_str()),
                    "expected a colour",
                )
            }),
        }
    }

    fn type_name(&self, prim: &usd::Prim) -> Result<String, SceneError> {
        Ok(prim
            .type_name()
            .map_err(|e| self.error(MalformedPart::Node, prim.path().as_str(), format!("{e:#}")))?
            .map(|t| t.as_str().to_owned())
            .unwrap_or_default())
    }

    fn visit(
        &mut self,
        prim: &usd::Prim,
        parent: Mat4,
        binding: Option<String>,
        depth: usize,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        if depth > MAX_DEPTH {
            return Err(self.error(
                MalformedPart::Node,
                &at,
                format!("nested deeper than {MAX_DEPTH} levels"),
            ));
        }
        // The composition check counts prims before composing, but not those an ancestor's arcs map onto an
        // arc's target: every prim composed is counted here too.
        self.prims += 1;
        if self.prims > self.limits.usd_prims {
            return Err(self.error(
                MalformedPart::Node,
                &at,
                format!(
                    "the stage has more than {} prims (raise the limit with --max-prims)",
                    self.limits.usd_prims
                ),
            ));
        }
        if !prim
            .is_active()
            .map_err(|e| self.error(MalformedPart::Node, &at, format!("{e:#}")))?
        {
            return Ok(());
        }
        // Only defined, non-abstract prims are drawn: a `class` (an abstract prototype for references and
        // inherits) or a bare `over` is not (UsdPrimDefaultPredicate). Their children are skipped with them.
        let specifier = prim
            .specifier()
            .map_err(|e| self.error(MalformedPart::Node, &at, format!("{e:#}")))?;
        if !matches!(specifier, Some(sdf::Specifier::Def)) {
            return Ok(());
        }
        // `visibility` is inherited: an invisible prim hides its whole subtree (UsdGeomImageable).
        if self
            .value(prim, "visibility")?
            .and_then(|v| token(&v))
            .is_some_and(|v| v == "invisible")
        {
            return Ok(());
        }
        let (local, reset) = self.local_transform(prim)?;
        let world = if reset { local } else { parent * local };
        if !world.is_finite() {
            return Err(self.error(MalformedPart::Node, &at, "non-finite transform"));
        }
        let outer = (self.tags.clone(), self.asset.clone());
        self.check_nimbus_attributes(prim)?;
        self.tags = self.prim_tags(prim)?.or(&outer.0);
        if depth == 0 || self.is_component(prim)? {
            self.asset = at.clone();
        }
        let visited = self.visit_prim(prim, &world, binding, depth);
        (self.tags, self.asset) = outer;
        visited
    }

    /// Draws what `prim` is (mesh, gprim, light, camera, volume...) and visits its children; the compositing
    /// tags and asset are already the prim's.
    fn visit_prim(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: Option<String>,
        depth: usize,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let world = *world;
        let binding = self.binding(prim)?.or(binding);
        let kind = self.type_name(prim)?;
        match kind.as_str() {
            "Mesh" => self.mesh(prim, &world, binding.as_deref())?,
            "Cube" | "Sphere" | "Cylinder" | "Cone" | "Capsule" | "Plane" => {
                self.gprim(prim, &kind, &world, binding.as_deref())?
            }
            // The prototypes below an instancer render only as its instances.
            "PointInstancer" => return self.point_instancer(prim, &world, binding, depth),
            "Camera" => self.camera(prim, &world)?,
            "RectLight" | "DiskLight" | "SphereLight" | "DistantLight" | "DomeLight" => {
                self.light(prim, &kind, &world)?
            }
            "Volume" => self.volume(prim, &world)?,
            k if STRUCTURAL_TYPES.contains(&k) => {}
            k => {
                if self.unsupported.insert(k.to_owned()) {
                    self.warn(format!(
                        "USD prim type '{k}' is not supported (first at {at}); skipped"
                    ));
                }
            }
        }
        // A native instance whose prototype holds only static meshes places them as instances.
        if self.native_instance(prim, &world, &binding, depth)? {
            return Ok(());
        }
        for child in self.children(prim)? {
            self.visit(&child, world, binding.clone(), depth + 1)?;
        }
        Ok(())
    }

    /// Warns about (or under `--strict` refuses) the prim's `nimbus:` attributes that the loader ignores: any
    /// but the compositing tags, and on a `Volume` the attributes of [`VOLUME_KEYS`].
    fn check_nimbus_attributes(&mut self, prim: &usd::Prim) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let names = prim
            .property_names()
            .map_err(|e| self.error(MalformedPart::Node, &at, format!("{e:#}")))?;
        let volume = prim
            .type_name()
            .map_err(|e| self.error(MalformedPart::Node, &at, format!("{e:#}")))?
            .is_some_and(|t| t.as_str() == "Volume");
        let known: Vec<&'static str> = TAG_ATTRIBUTES
            .iter()
            .copied()
            .chain(
                VOLUME_KEYS
                    .iter()
                    .filter(|k| volume && k.usd == UsdBinding::Attribute)
                    .map(|k| k.name),
            )
            .collect();
        let unknown: Vec<UnknownKey> = names
            .iter()
            .filter_map(|name| name.as_str().strip_prefix("nimbus:"))
            .filter(|name| !known.contains(name))
            .map(|name| UnknownKey {
                key: format!("nimbus:{name}"),
                closest: closest_name(name, known.iter().copied()).map(|c| format!("nimbus:{c}")),
            })
            .collect();
        report_unknown_keys(&mut self.builder, self.strict, &at, &unknown)
            .map_err(|kind| SceneError::new(self.path, kind))
    }

    /// The prim's own `nimbus:lightGroup` (string or token), `nimbus:holdout` and `nimbus:shadowCatcher`
    /// (bool) attributes (see [`CompositingTags`]).
    fn prim_tags(&self, prim: &usd::Prim) -> Result<CompositingTags, SceneError> {
        let at = prim.path().as_str();
        let flag = |name: &str| -> Result<bool, SceneError> {
            match self.value(prim, name)? {
                None => Ok(false),
                Some(sdf::Value::Bool(b)) => Ok(b),
                Some(_) => Err(self.error(
                    MalformedPart::Node,
                    &format!("{at}.{name}"),
                    "expected a bool",
                )),
            }
        };
        let light_group = match self.value(prim, "nimbus:lightGroup")? {
            None => None,
            Some(v) => match token(&v) {
                Some(name) if !name.trim().is_empty() && name.chars().count() <= 64 => Some(name),
                _ => {
                    return Err(self.error(
                        MalformedPart::Node,
                        &format!("{at}.nimbus:lightGroup"),
                        "a light group must be a non-empty string of at most 64 characters",
                    ))
                }
            },
        };
        Ok(CompositingTags {
            light_group,
            holdout: flag("nimbus:holdout")?,
            shadow_catcher: flag("nimbus:shadowCatcher")?,
        })
    }

    /// True when `prim` is a `component` model (USD's model hierarchy: an asset).
    fn is_component(&self, prim: &usd::Prim) -> Result<bool, SceneError> {
        let kind = prim
            .kind()
            .map_err(|e| self.error(MalformedPart::Node, prim.path().as_str(), format!("{e:#}")))?;
        Ok(kind.is_some_and(|k| k.as_str() == "component"))
    }

    /// Adds a mesh drawn from the prim being visited, with that prim's asset and compositing tags, if it fits
    /// the memory budget with the scene's meshes so far ([`SceneBuilder::check_mesh`]).
    fn add_mesh(&mut self, mut mesh: Mesh) -> Result<(), SceneError> {
        let (triangles, vertices) = (mesh.indices.len() as u64, mesh.positions.len() as u64);
        self.check_mesh(&mesh.name, triangles, vertices)?;
        mesh.asset = self.asset.clone();
        mesh.tags = self.tags.clone();
        self.builder.add_mesh(mesh);
        Ok(())
    }

    /// `Ok` if `triangles` and `vertices` made at `at` fit the memory budget with the scene's meshes so far.
    fn check_mesh(&self, at: &str, triangles: u64, vertices: u64) -> Result<(), SceneError> {
        self.builder
            .check_mesh(at, triangles, vertices)
            .map_err(|e| SceneError::new(self.path, SceneErrorKind::OverLimit(e.to_string())))
    }

    /// The file an asset-valued attribute names, resolved against the layer that authored it.
    fn asset(&self, prim: &usd::Prim, name: &str) -> Result<Option<PathBuf>, SceneError> {
        let at = format!("{}.{name}", prim.path().as_str());
        let file = match self.value(prim, name)? {
            None => return Ok(None),
            Some(sdf::Value::AssetPath(a)) => a.asset_path().to_owned(),
            Some(sdf::Value::String(s)) => s,
            Some(_) => return Err(self.error(MalformedPart::Node, &at, "expected an asset path")),
        };
        if file.is_empty() {
            return Ok(None);
        }
        let stack = prim
            .attribute(name)
            .property_stack()
            .map_err(|e| self.error(MalformedPart::Node, &at, format!("{e:#}")))?;
        let base = stack
            .first()
            .map(|(layer, _)| layer_folder(layer))
            .or_else(|| self.path.parent().map(Path::to_path_buf))
            .unwrap_or_default();
        Ok(Some(base.join(file)))
    }

    /// The bytes of an asset [`Loader::asset`] resolved: a file on disk, or an entry of a `.usdz` package when
    /// a folder of the path is a package file (the asset was named by a layer inside the package).
    fn read_asset(&mut self, file: &Path) -> Result<Vec<u8>, AssetError> {
        let in_package = file.ancestors().skip(1).find_map(|folder| {
            let member = file.strip_prefix(folder).ok()?;
            (is_package_name(folder) && folder.is_file()).then_some((folder, member))
        });
        let Some((package, member)) = in_package else {
            return read_file(file, &self.limits).map_err(AssetError::File);
        };
        let member = member.to_string_lossy().into_owned();
        let limits = self.limits;
        let opened = match self.packages.entry(package.to_path_buf()) {
            std::collections::hash_map::Entry::Occupied(entry) => entry.into_mut(),
            std::collections::hash_map::Entry::Vacant(entry) => {
                entry.insert(layers::Package::open(package, &limits)?)
            }
        };
        opened
            .read(&member, &limits)?
            .ok_or_else(|| AssetError::NotInPackage {
                package: package.to_path_buf(),
                member,
            })
    }

    fn camera(&mut self, prim: &usd::Prim, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let focal = self.float(prim, "focalLength", 50.0)?;
        let h = self.float(prim, "horizontalAperture", 20.955)?;
        let v = self.float(prim, "verticalAperture", 15.2908)?;
        if !(focal > 0.0 && h > 0.0 && v > 0.0) {
            return Err(self.error(
                MalformedPart::Camera,
                &at,
                "focalLength and apertures must be positive",
            ));
        }
        let f_stop = self.float(prim, "fStop", 0.0)?;
        let focus = self.float(prim, "focusDistance", 0.0)?;
        // Scene units to metres along the camera's axes (the world matrix carries metersPerUnit).
        let unit = world.x_axis.truncate().length();
        let (yfov, projection) = match self.value(prim, "projection")?.and_then(|p| token(&p)) {
            Some(p) if p == "orthographic" => (
                // Unused by an orthographic camera; a valid perspective angle keeps the numbers checkable.
                std::f32::consts::FRAC_PI_2,
                Projection::Orthographic {
                    half_height: 0.05 * v * unit,
                },
            ),
            other => {
                if let Some(p) = other.filter(|p| p != "perspective") {
                    self.warn(format!(
                        "camera {at}: projection '{}' is neither perspective nor orthographic; rendered as perspective",
                        one_line(&p, MESSAGE_CHARS / 4)
                    ));
                }
                (2.0 * (0.5 * v / focal).atan(), Projection::Perspective)
            }
        };
        if let Projection::Orthographic { half_height } = projection {
            if !(half_height.is_finite() && half_height > 0.0) {
                return Err(self.error(MalformedPart::Camera,
                    &at,
                    format!("an orthographic film {half_height} m high (verticalAperture {v} tenths of a scene unit at the camera's scale {unit}) must be finite and > 0"),
                ));
            }
        }
        if !(f_stop.is_finite() && f_stop >= 0.0) {
            return Err(self.error(
                MalformedPart::Camera,
                &format!("{at}.fStop"),
                format!("{f_stop} must be ≥ 0"),
            ));
        }
        let radius = if f_stop > 0.0 {
            0.1 * focal / (2.0 * f_stop) * unit
        } else {
            0.0
        };
        let lens = ThinLens::new(radius, Some(focus * unit), ["fStop", "focusDistance"]).map_err(
            |source| {
                SceneError::new(
                    self.path,
                    SceneErrorKind::Camera {
                        at: format!("camera {at}").into(),
                        source,
                    },
                )
            },
        )?;
        let name = prim.path().name().unwrap_or(&at).to_owned();
        self.builder.add_camera(NamedCamera {
            name,
            path: Some(at),
            camera: Camera {
                camera_to_world: Camera::rigid(world),
                yfov,
                projection,
                lens,
                aspect_ratio: Some(h / v),
                motion: None,
            },
        });
        Ok(())
    }
}

/// True for a path whose file name ends in `.usdz`.
fn is_package_name(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("usdz"))
}

/// The folder that asset paths authored in layer `identifier` are relative to. A layer inside a package
/// (`pkg.usdz[inner/layer.usdc]`, or the package itself as the root layer) gives a folder inside the package
/// (`pkg.usdz/inner`), which [`Loader::read_asset`] reads from the package.
fn layer_folder(identifier: &str) -> PathBuf {
    if let Some(open) = identifier.find(".usdz[") {
        let package = &identifier[..open + 5];
        let inner = identifier[open + 6..].trim_end_matches(']');
        let folder = Path::new(inner).parent().unwrap_or(Path::new(""));
        return Path::new(package).join(folder);
    }
    let layer = Path::new(identifier);
    if is_package_name(layer) {
        return layer.to_path_buf();
    }
    layer.parent().map(Path::to_path_buf).unwrap_or_default()
}

/// True for a USD property name: identifiers (a letter or `_`, then letters, digits or `_`) joined by `:`.
fn is_property_name(name: &str) -> bool {
    !name.is_empty()
        && name.split(':').all(|part| {
            let mut chars = part.chars();
            chars
                .next()
                .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
}

#[cfg(test)]
mod tests {
    #[test]
    fn property_names_are_namespaced_identifiers() {
        for good in [
            "points",
            "xformOp:translate",
            "xformOp:rotateXYZ:pivot",
            "_a1",
        ] {
            assert!(super::is_property_name(good), "{good}");
        }
        for bad in [
            "",
            "xformOp}:translate",
            "xformOp:tr\nx",
            "a::b",
            "1a",
            "a b",
            ":a",
        ] {
            assert!(!super::is_property_name(bad), "{bad:?}");
        }
    }
}
