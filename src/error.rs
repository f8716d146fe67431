//! The crate-level error: one type for hosts that load, render and write through the public API.

/// Any error of the public API, so that a host can use one `Result<T, nimbus::Error>` throughout.
///
/// Each variant wraps the module's own typed error, reachable through [`std::error::Error::source`].
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A scene file could not be loaded or a programmatic scene is invalid.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// An output image could not be written or read.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A VDB file could not be read.
    #[error(transparent)]
    Vdb(#[from] crate::vdb::VdbError),
    /// A render region is invalid, or its worker threads could not start.
    #[error(transparent)]
    Region(#[from] crate::render::RegionError),
    /// A farm split or merge failed.
    #[error(transparent)]
    Farm(#[from] crate::farm::FarmError),
    /// A convergence study could not run.
    #[error(transparent)]
    Converge(#[from] crate::converge::ConvergeError),
    /// A render could not start: its worker threads, or a film over the memory budget.
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
}

/// `Result` with the crate-level [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
