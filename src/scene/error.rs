//! The error type of every scene loader: it names the file and what is wrong with it.

use std::path::{Path, PathBuf};

/// A scene could not be loaded.
///
/// Its [`source`](std::error::Error::source) is the typed cause inside [`SceneErrorKind`] (the I/O error,
/// the environment map's error...), so that a host can tell causes apart by walking the chain.
#[derive(Debug)]
pub struct SceneError {
    /// The file that failed (the scene, or a buffer, image or volume it references). Boxed, as `at` in
    /// [`SceneErrorKind::Volume`], to keep `Result<_, SceneError>` small.
    pub path: Box<Path>,
    /// What went wrong; its cause (if any) is the error's `source`.
    pub kind: SceneErrorKind,
}

/// What went wrong while loading a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneErrorKind {
    /// The file could not be read.
    #[error("cannot read: {0}")]
    Io(#[from] std::io::Error),
    /// The file is not valid for its format (malformed JSON, truncated GLB, bad header...); the error says
    /// which part of the scene ([`MalformedPart`]) and what is wrong with it.
    #[error("malformed: {0}")]
    Malformed(MalformedError),
    /// The file uses a feature Nimbus cannot render and must not ignore.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A reference inside the file points at nothing valid (accessor, buffer, image, index out of range).
    #[error("invalid reference: {0}")]
    InvalidReference(String),
    /// A key the renderer does not know, refused under `--strict` ([`super::LoadOptions::strict`]).
    #[error("{0} (--strict refuses keys the renderer would ignore)")]
    UnknownKey(String),
    /// Loading the file would pass a limit of [`crate::limits::Limits`]: the memory budget, or the load-time
    /// work it allows (`crate::limits::WorkBudget`); the message names which, and `--memory-limit`.
    #[error("over a limit: {0}")]
    OverLimit(String),
    /// A third-party reader panicked on the file (a damaged file its own checks missed), or did not finish
    /// within its time limit; the panic was caught and is reported here, so that callers and tests can tell
    /// it from an error the reader found.
    #[error("the {reader} reader failed on a damaged file: {message}")]
    ReaderPanicked {
        /// The reader (e.g. `openusd`).
        reader: &'static str,
        /// The panic's message.
        message: String,
    },
    /// An environment map the scene names could not be loaded.
    #[error("{0}")]
    Environment(#[from] crate::light::EnvironmentError),
    /// A medium declared in the file could not be built: its parameters, its VDB file or its grids.
    #[error("{at}: {source}")]
    Volume {
        /// Where the file declares it: the node, material or prim, and the key (`node 'smoke': nimbus_volume`).
        at: Box<str>,
        /// Why it could not be built.
        #[source]
        source: crate::volume::VolumeError,
    },
    /// A camera's lens declaration (glTF `nimbus_camera`, USD `fStop` / `focusDistance`) is not a lens.
    #[error("{at}: {source}")]
    Camera {
        /// Where the file declares it: the camera and the key (`camera 'shot': nimbus_camera`).
        at: Box<str>,
        /// What is wrong with it.
        #[source]
        source: crate::scene::LensError,
    },
    /// The file extension names no format Nimbus reads.
    #[error("unknown scene format (expected .gltf, .glb, .obj, .usd, .usda, .usdc or .usdz)")]
    UnknownFormat,
}

impl SceneErrorKind {
    /// A [`SceneErrorKind::Malformed`] about `part`, saying `message`.
    pub(crate) fn malformed(part: MalformedPart, message: impl Into<String>) -> Self {
        Self::Malformed(MalformedError {
            part,
            message: message.into(),
        })
    }
}

/// Which part of a scene a [`MalformedError`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum MalformedPart {
    /// The file as a whole: its syntax or container (glTF JSON and GLB chunks, a USD layer, its composition
    /// or its stage metadata, an OBJ statement), or a file without a scene.
    File,
    /// Binary data: a glTF buffer, buffer view or accessor.
    Data,
    /// A mesh: its vertices, faces or vertex attributes (glTF primitives, OBJ faces, USD meshes and shapes,
    /// meshes built in code).
    Mesh,
    /// A glTF node or a USD prim: its place in the hierarchy, its transform, its extras, or an attribute of a
    /// type the prim's schema does not give it.
    Node,
    /// A material: its parameters, extensions, extras or variants (OBJ: its MTL file).
    Material,
    /// An image, or a material's reference to a texture.
    Texture,
    /// An animation, a skin or morph targets.
    Animation,
    /// A camera.
    Camera,
    /// A light.
    Light,
    /// Instancing: glTF `EXT_mesh_gpu_instancing`, a USD `PointInstancer` or native instance.
    Instancing,
    /// A volume declared in the file (USD `Volume` prims and their `OpenVDBAsset` fields).
    Volume,
    /// Scene-wide settings: the glTF scene's extras (environment, light units, bounces, transparency).
    Settings,
}

/// A part of a scene file is malformed: which part, and what is wrong with it. Its `Display` is the message
/// alone (the [`SceneErrorKind::Malformed`] around it adds `malformed: `).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct MalformedError {
    part: MalformedPart,
    message: String,
}

impl MalformedError {
    /// Which part of the scene is malformed.
    pub fn part(&self) -> MalformedPart {
        self.part
    }

    /// What is wrong with it, naming where it was found (`node 3 has a non-finite transform`).
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.kind)
    }
}

impl std::error::Error for SceneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.kind.source()
    }
}

impl SceneError {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, kind: SceneErrorKind) -> Self {
        Self {
            path: path.into().into_boxed_path(),
            kind,
        }
    }
}
