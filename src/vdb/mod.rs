//! OpenVDB file reader, written from the file format, producing the renderer's own sparse grids.
//!
//! Supported: file versions 219–224; `Tree_float_5_4_3`, `Tree_double_5_4_3` (stored as `f32`) and
//! `Tree_vec3s_5_4_3`, each also with half-float storage; value buffers raw, zlib or Blosc/LZ4, with active-mask
//! compression; instanced grids; the linear transforms (uniform/non-uniform scale, translation, affine, unitary).
//! Everything else is an error that names the file (and the grid) — never a panic or a silently empty grid.
//!
//! The public part is what `nimbus info` prints: [`file_info`] opens a file and describes its grids.
//!
//! ```no_run
//! let info = nimbus::vdb::file_info(std::path::Path::new("smoke.vdb"))?;
//! for grid in &info.grids {
//!     println!("{} {} {} active voxels", grid.name, grid.value_type, grid.stats.active_voxels);
//! }
//! # Ok::<(), nimbus::VdbError>(())
//! ```

#![warn(missing_docs)]

mod compression;
mod error;
mod grid;
mod half;
mod header;
mod info;
mod metadata;
mod stream;
mod transform;
mod tree_io;

pub use error::{VdbError, VdbErrorKind};
pub use grid::TreeStats;
pub use info::{file_info, FileInfo, GridInfo};
internal! {
    pub use grid::{
        floor_ivec3, Accessor, FloatTree, Leaf, LowerNode, Region, Tree, Vec3Tree, VoxelValue,
    };
    pub use header::FileHeader;
}
#[cfg(feature = "testing")]
pub use grid::{InternalNode, Root, Tile, UpperNode};
#[cfg(feature = "testing")]
pub use metadata::MetaValue;
#[cfg(feature = "testing")]
pub use metadata::Metadata;

use error::KResult;
#[cfg(test)]
use glam::Vec3;
use glam::{DMat4, DVec3};
use header::GridDescriptor;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use stream::Reader;
use transform::Transform;
use tree_io::{read_tree, Scalar, TreeCtx};

internal! {
    /// A whole VDB file.
    #[derive(Clone, Debug)]
    pub struct VdbFile {
        /// File format version.
        #[cfg(any(test, feature = "testing"))]
        pub version: u32,
        /// The file header.
        #[cfg(any(test, feature = "testing"))]
        pub header: FileHeader,
        /// File-level metadata.
        #[cfg(any(test, feature = "testing"))]
        pub metadata: Metadata,
        /// The grids, in file order.
        pub grids: Vec<Grid>,
        /// Grids left out because of an unsupported type, as (name, type name); only with
        /// [`ReadOptions::skip_unsupported`].
        #[cfg(any(test, feature = "testing"))]
        pub skipped: Vec<(String, String)>,
    }
}

internal! {
    /// Options for [`read_file_with`] / [`read_bytes_with`].
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
    pub struct ReadOptions {
        /// Leave out grids of unsupported types (listing them in [`VdbFile::skipped`]) instead of failing.
        pub skip_unsupported: bool,
        /// The memory budget: a file larger than it is refused before it is read, and a device or pipe is read
        /// at most [`crate::limits::MAX_STREAM_BYTES`].
        pub limits: crate::limits::Limits,
    }
}

impl VdbFile {
    /// The first grid called `name`.
    pub fn grid(&self, name: &str) -> Option<&Grid> {
        self.grids.iter().find(|g| g.name == name)
    }
}

internal! {
    /// The grid class from the `class` metadata.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
    pub enum GridClass {
        /// Density-like data, zero background.
        FogVolume,
        /// Narrow-band signed distance field.
        LevelSet,
        /// Staggered (MAC) vector field.
        Staggered,
        /// Unknown or absent class.
        Unknown,
    }
}

impl GridClass {
    fn from_meta(s: Option<&str>) -> Self {
        match s {
            Some("fog volume") => Self::FogVolume,
            Some("level set") => Self::LevelSet,
            Some("staggered") => Self::Staggered,
            _ => Self::Unknown,
        }
    }
}

internal! {
    /// Value type as stored in the file.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
    pub enum ValueType {
        /// 32-bit float.
        Float,
        /// 64-bit float (converted to `f32` in the tree).
        Double,
        /// Vector of three 32-bit floats.
        Vec3s,
    }
}

internal! {
    /// A grid's tree, by value kind.
    #[derive(Clone, Debug)]
    pub enum GridTree {
        /// Scalar grid (float or double in the file).
        Float(FloatTree),
        /// Vector grid.
        Vec3(Vec3Tree),
    }
}

impl GridTree {
    /// The scalar tree, if this is one.
    pub fn as_float(&self) -> Option<&FloatTree> {
        match self {
            Self::Float(t) => Some(t),
            Self::Vec3(_) => None,
        }
    }
    /// The vector tree, if this is one.
    pub fn as_vec3(&self) -> Option<&Vec3Tree> {
        match self {
            Self::Vec3(t) => Some(t),
            Self::Float(_) => None,
        }
    }
    /// True when every stored value (voxels, tiles and background; every component of a vector) is finite.
    pub fn is_finite(&self) -> bool {
        match self {
            Self::Float(t) => t.background().is_finite() && !t.any_value(|v| !v.is_finite()),
            Self::Vec3(t) => t.background().is_finite() && !t.any_value(|v| !v.is_finite()),
        }
    }
    /// Statistics over the active values.
    pub fn stats(&self) -> TreeStats {
        match self {
            Self::Float(t) => t.stats(),
            Self::Vec3(t) => t.stats(),
        }
    }
    /// Approximate memory in bytes.
    pub fn memory_bytes(&self) -> usize {
        match self {
            Self::Float(t) => t.memory_bytes(),
            Self::Vec3(t) => t.memory_bytes(),
        }
    }
}

/// Background value of a grid.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum Background {
    /// Scalar background.
    Float(f32),
    /// Vector background.
    Vec3([f32; 3]),
}

internal! {
    /// One grid of a VDB file.
    #[derive(Clone, Debug)]
    pub struct Grid {
        /// Grid name (duplicates allowed).
        pub name: String,
        /// Grid class.
        pub class: GridClass,
        /// Value type in the file.
        pub value_type: ValueType,
        /// Whether the file stored the values as halves.
        pub half: bool,
        /// OpenVDB map type name.
        pub map_type: String,
        /// Index-to-world matrix, column-vector convention (`world = M · [i j k 1]ᵀ`).
        pub index_to_world: DMat4,
        /// Background value.
        pub background: Background,
        /// Per-grid metadata (file bbox, voxel count, ... where present).
        #[cfg(any(test, feature = "testing"))]
        pub metadata: Metadata,
        /// Name of the grid whose tree this one shares, if it is an instance.
        #[cfg(any(test, feature = "testing"))]
        pub instance_of: Option<String>,
        /// The sparse tree (shared between instances).
        pub tree: Arc<GridTree>,
    }
}

impl Grid {
    /// World-to-index matrix.
    #[cfg(test)]
    pub fn world_to_index(&self) -> DMat4 {
        self.index_to_world.inverse()
    }
    /// Maps a world point to continuous index space.
    #[cfg(test)]
    pub fn world_to_index_point(&self, p: DVec3) -> Vec3 {
        self.world_to_index().transform_point3(p).as_vec3()
    }
    /// World size of one voxel step along each index axis.
    pub fn voxel_size(&self) -> DVec3 {
        Transform {
            map_type: self.map_type.clone(),
            index_to_world: self.index_to_world,
        }
        .voxel_size()
    }
}

internal! {
    /// Reads a VDB file from disk; any grid of an unsupported type is an error.
    pub fn read_file(path: &Path) -> Result<VdbFile, VdbError> {
        read_file_with(path, &ReadOptions::default())
    }
}

internal! {
    /// Reads a VDB file from disk with options. A regular file is streamed: only the leaf buffers being
    /// decoded are held (two batches of about 1 MiB), never the whole file (a device is read whole first, within
    /// the budget).
    pub fn read_file_with(path: &Path, options: &ReadOptions) -> Result<VdbFile, VdbError> {
        let error = |kind: VdbErrorKind| VdbError {
            path: path.to_path_buf(),
            kind,
        };
        match crate::limits::open_file(path, &options.limits).map_err(|e| error(e.into()))? {
            crate::limits::OpenedFile::Regular(file, len) => {
                read_impl(Reader::from_file(file, len), options).map_err(error)
            }
            crate::limits::OpenedFile::Read(bytes) => read_bytes_with(&bytes, path, options),
        }
    }
}

internal! {
    /// Reads a VDB file held in memory; `path_for_errors` names it in errors.
    pub fn read_bytes(bytes: &[u8], path_for_errors: &Path) -> Result<VdbFile, VdbError> {
        read_bytes_with(bytes, path_for_errors, &ReadOptions::default())
    }
}

internal! {
    /// Reads a VDB file held in memory with options; `path_for_errors` names it in errors.
    pub fn read_bytes_with(
        bytes: &[u8],
        path_for_errors: &Path,
        options: &ReadOptions,
    ) -> Result<VdbFile, VdbError> {
        read_impl(Reader::new(bytes), options).map_err(|kind| VdbError {
            path: PathBuf::from(path_for_errors),
            kind,
        })
    }
}

fn in_grid(name: &str) -> impl FnOnce(VdbErrorKind) -> VdbErrorKind + '_ {
    move |e| match e {
        e @ VdbErrorKind::UnsupportedGridType { .. } => e,
        e => VdbErrorKind::InGrid {
            grid: name.to_string(),
            source: Box::new(e),
        },
    }
}

fn read_impl(mut r: Reader<'_>, options: &ReadOptions) -> KResult<VdbFile> {
    let header = header::read_header(&mut r)?;
    let metadata = metadata::read_metadata(&mut r)?;
    #[cfg(not(any(test, feature = "testing")))]
    let _ = metadata; // read past; only the tests look at it
    if !header.has_grid_offsets {
        return Err(VdbErrorKind::Unsupported(
            "files without grid offsets (streamed archives)".into(),
        ));
    }
    let count = r.i32("grid count")?;
    // A descriptor is at least 3 strings + 3 offsets = 36 bytes.
    if count < 0 || count as u64 * 36 > r.remaining() as u64 {
        return error::corrupt(format!("grid count {count} does not fit the data"));
    }
    let mut descs = Vec::with_capacity(count as usize);
    let mut grids: Vec<Grid> = Vec::with_capacity(count as usize);
    let mut skipped = Vec::new();
    for _ in 0..count {
        let d = header::read_descriptor(&mut r)?;
        if d.end_pos <= r.pos() as u64 {
            return error::corrupt(format!("grid '{}' end offset points backwards", d.name));
        }
        match read_grid(&mut r, &header, &d) {
            Err(VdbErrorKind::UnsupportedGridType { grid, type_name })
                if options.skip_unsupported =>
            {
                skipped.push((grid, type_name));
            }
            g => {
                grids.push(g.map_err(in_grid(&d.name))?);
                descs.push(d.clone());
            }
        }
        r.seek(d.end_pos)?;
    }
    // Resolve instances: share the parent's tree.
    for i in 0..grids.len() {
        if descs[i].instance_parent.is_empty() {
            continue;
        }
        let parent = &descs[i].instance_parent;
        let p = descs
            .iter()
            .position(|d| &d.unique_name == parent && d.instance_parent.is_empty())
            .ok_or_else(|| {
                in_grid(&descs[i].name)(VdbErrorKind::Corrupt(format!(
                    "instance parent '{parent}' not found"
                )))
            })?;
        grids[i].tree = grids[p].tree.clone();
        grids[i].background = grids[p].background;
    }
    Ok(VdbFile {
        #[cfg(any(test, feature = "testing"))]
        version: header.version,
        #[cfg(any(test, feature = "testing"))]
        header,
        #[cfg(any(test, feature = "testing"))]
        metadata,
        grids,
        #[cfg(any(test, feature = "testing"))]
        skipped,
    })
}

/// Reads the grid `d` describes: the bytes from its `grid_pos` to its `end_pos`, with `r`'s end limited to the
/// latter while it does (and restored after).
fn read_grid(r: &mut Reader<'_>, header: &FileHeader, d: &GridDescriptor) -> KResult<Grid> {
    let end = r.limit_to(d.end_pos);
    let grid = read_grid_within(r, header, d);
    r.set_end(end);
    grid
}

/// [`read_grid`] once `r` ends at the grid's end.
fn read_grid_within(r: &mut Reader<'_>, header: &FileHeader, d: &GridDescriptor) -> KResult<Grid> {
    let (value_type, scalar) = match d.type_name.as_str() {
        "Tree_float_5_4_3" => (ValueType::Float, Scalar::F32),
        "Tree_double_5_4_3" => (ValueType::Double, Scalar::F64),
        "Tree_vec3s_5_4_3" => (ValueType::Vec3s, Scalar::F32),
        _ => {
            return Err(VdbErrorKind::UnsupportedGridType {
                grid: d.name.clone(),
                type_name: d.type_name.clone(),
            })
        }
    };
    r.seek(d.grid_pos)?;
    let compression = if header.version >= tree_io::VERSION_NODE_MASK_COMPRESSION {
        r.u32("grid compression")?
    } else {
        header.compression
    };
    let metadata = metadata::read_metadata(r)?;
    let transform = transform::read_transform(r)?;
    let class = GridClass::from_meta(metadata.get_str("class"));
    let (tree, background) = if !d.instance_parent.is_empty() {
        // Placeholder; replaced by the parent's tree once all grids are read.
        (GridTree::Float(FloatTree::new(0.0)), Background::Float(0.0))
    } else {
        let mut ctx = TreeCtx::new(header.version, compression, scalar, d.half);
        if value_type == ValueType::Vec3s {
            let t: Vec3Tree = read_tree(r, &mut ctx)?;
            let b = Background::Vec3(t.background.to_array());
            (GridTree::Vec3(t), b)
        } else {
            let t: FloatTree = read_tree(r, &mut ctx)?;
            let b = Background::Float(t.background);
            (GridTree::Float(t), b)
        }
    };
    Ok(Grid {
        name: d.name.clone(),
        class,
        value_type,
        half: d.half,
        map_type: transform.map_type,
        index_to_world: transform.index_to_world,
        background,
        #[cfg(any(test, feature = "testing"))]
        metadata,
        #[cfg(any(test, feature = "testing"))]
        instance_of: (!d.instance_parent.is_empty()).then(|| d.instance_parent.clone()),
        tree: Arc::new(tree),
    })
}
