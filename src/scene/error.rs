//! The error type of every scene loader: it names the file and what is wrong with it.

use std::path::PathBuf;

/// A scene could not be loaded.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct SceneError {
    /// The file that failed (the scene, or a buffer, image or volume it references).
    pub path: PathBuf,
    /// What went wrong; also the error's `source`, so a host can walk down to the cause.
    #[source]
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
    /// A medium declared in the file could not be built: its parameters, its VDB file or its grids.
    #[error("{at}: {source}")]
    Volume {
        /// Where the file declares it: the node, material or prim, and the key (`node 'smoke': nimbus_volume`).
        at: String,
        /// Why it could not be built.
        #[source]
        source: crate::volume::VolumeError,
    },
    /// The file extension names no format Nimbus reads.
    #[error("unknown scene format (expected .gltf, .glb, .obj, .usd, .usda, .usdc or .usdz)")]
    UnknownFormat,
}

impl SceneError {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, kind: SceneErrorKind) -> Self {
        Self {
            path: path.into(),
            kind,
        }
    }
}
