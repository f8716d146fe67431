//! What can go wrong in `nimbus converge`, as a typed error a host can match on.

use crate::output::OutputError;
use crate::scene::SceneError;
use std::path::PathBuf;

/// An error of [`super::run`].
#[derive(Debug, thiserror::Error)]
pub enum ConvergeError {
    /// The time budget is not a positive number of seconds.
    #[error("--budget {0} is not a positive number of seconds")]
    InvalidBudget(f64),
    /// No method was given.
    #[error("no method to compare")]
    NoMethods,
    /// A method name is not one of [`super::Method::ALL`].
    #[error("unknown method '{name}' (known: {known})")]
    UnknownMethod {
        /// The name given.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// The scene did not load.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A method changes VDB volumes, and the scene has none: every such method would render the same image.
    #[error("{scene}: method '{method}' changes VDB volumes, and the scene has none")]
    NoVolumeToChange {
        /// The scene file.
        scene: PathBuf,
        /// The method's name.
        method: &'static str,
    },
    /// The reference (or its standard errors) could not be read or written.
    #[error(transparent)]
    Image(#[from] OutputError),
    /// The reference does not fit the render.
    #[error("{path}: {reason}")]
    Reference {
        /// The reference file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// An output file or folder could not be written.
    #[error("{path}: {source}")]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The render and the reference hold different numbers of pixels.
    #[error("render and reference differ in size: {0}")]
    SizeMismatch(#[source] super::SizeMismatch),
    /// The chart could not be drawn.
    #[cfg(feature = "charts")]
    #[error(transparent)]
    Chart(#[from] super::ChartError),
    /// A render could not start (its worker threads, or a film over the memory budget).
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
}
