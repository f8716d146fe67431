//! The errors of building a medium, each keeping its cause as its `source`: [`VolumeError`] (reading a
//! declared medium: its parameters, its VDB file, its grids) and [`DensityError`] (placing one grid as a
//! density field). Loaders wrap a [`VolumeError`] in their own error, naming the scene file and the node,
//! material or prim that declared the medium, so a host can walk `source()` down to the cause.

use crate::params::ParamError;
use crate::vdb::VdbError;
use std::path::PathBuf;

/// A medium could not be built from its declaration.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// A parameter is missing, of the wrong type or out of range.
    #[error("{0}")]
    Param(#[from] ParamError),
    /// The VDB file could not be read (missing, truncated, corrupt, unsupported).
    #[error("{0}")]
    Vdb(#[from] VdbError),
    /// The VDB file has no grid of the name the declaration gives.
    #[error("{}: no grid named '{grid}' (the file has {available:?})", file.display())]
    GridMissing {
        /// The VDB file.
        file: PathBuf,
        /// The grid asked for.
        grid: String,
        /// The grids the file has.
        available: Vec<String>,
    },
    /// A grid cannot serve as a density (or temperature) field.
    #[error("{}: grid '{grid}': {source}", file.display())]
    Density {
        /// The VDB file.
        file: PathBuf,
        /// The grid.
        grid: String,
        /// Why it cannot.
        #[source]
        source: DensityError,
    },
}

/// A grid cannot be placed as a density field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DensityError {
    /// The grid holds vectors, not scalars.
    #[error("a density grid must be scalar")]
    NotScalar,
    /// The grid's background (its value outside all data) is not zero, so the medium would fill all space.
    #[error("a density grid needs a zero background, found {0}")]
    NonZeroBackground(f32),
    /// The density scale is negative or not finite.
    #[error("invalid density scale {0}")]
    InvalidScale(f32),
}
