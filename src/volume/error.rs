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
    /// A VDB sequence has no file for the frame (and `missing_frame` is `error`, or `hold` found none).
    #[error("{}: frame {frame} of the sequence {} is missing (set missing_frame to hold or empty to go on without it)", file.display(), pattern.display())]
    MissingFrame {
        /// The sequence's file pattern.
        pattern: PathBuf,
        /// The file frame asked for (the shot frame plus `frame_offset`).
        frame: i64,
        /// The file looked for.
        file: PathBuf,
    },
    /// A structure built for the medium would exceed the memory budget.
    #[error("{}: {source}", file.display())]
    OverBudget {
        /// The VDB file.
        file: PathBuf,
        /// What was refused.
        #[source]
        source: crate::limits::OverBudget,
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
    /// The grid is a level set: a narrow-band signed distance to a surface (negative inside), not a density.
    #[error(
        "it is a level set (a signed distance to a surface, negative inside), not a fog volume; convert it to a \
         fog volume first (OpenVDB's sdfToFogVolume, Houdini's Convert VDB, Blender's Mesh to Volume)"
    )]
    LevelSet,
    /// The grid's background (its value outside all data) is not zero, so the medium would fill all space.
    #[error("a density grid needs a zero background, found {0}")]
    NonZeroBackground(f32),
    /// The density scale is negative or not finite.
    #[error("invalid density scale {0}")]
    InvalidScale(f32),
    /// The grid holds data beyond `super::density::MAX_INDEX_COORD` voxels from the index origin (a corrupt
    /// node origin, for one).
    #[error(
        "it holds voxels at index {origin:?}, beyond +/-{} voxels where single-precision lookups lose voxel precision",
        super::density::MAX_INDEX_COORD
    )]
    IndexRange {
        /// Origin of the first leaf or tile found out of range.
        origin: [i32; 3],
    },
    /// The grid cannot be placed in the scene: its transform is not finite and invertible, or puts it beyond
    /// `super::density::MAX_WORLD_COORD`.
    #[error("{0}")]
    Placement(String),
}
