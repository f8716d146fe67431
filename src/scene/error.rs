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
    /// The file is not valid for its format (malformed JSON, truncated GLB, bad header...).
    #[error("malformed: {0}")]
    Malformed(String),
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
