//! File header and grid descriptors.

use super::compression::{COMPRESS_ACTIVE_MASK, COMPRESS_ZIP};
use super::error::{corrupt, KResult, VdbErrorKind};
use super::stream::Reader;

/// OpenVDB magic number (`" BDV"` in the low four bytes of an `i64`).
pub const MAGIC: i64 = 0x5644_4220;
/// Oldest file version this reader accepts (the "new transform" / "no grid map" layout).
pub const MIN_VERSION: u32 = 219;
/// Newest file version this reader accepts (multi-pass I/O).
pub const MAX_VERSION: u32 = 224;

/// The fixed file header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileHeader {
    /// File format version.
    pub version: u32,
    /// Library (major, minor) version that wrote the file.
    pub library_version: (u32, u32),
    /// Whether grids are stored with offsets (required by this reader).
    pub has_grid_offsets: bool,
    /// File-wide compression flags (used for files older than version 222).
    pub compression: u32,
    /// The 36-character file UUID.
    pub uuid: String,
}

/// One grid's entry in the file's grid table.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GridDescriptor {
    /// Unique name in the file (duplicate names get a `\x1e`-separated suffix).
    pub unique_name: String,
    /// The grid's name (unique name without the suffix).
    pub name: String,
    /// Tree type name without the `_HalfFloat` suffix, e.g. `Tree_float_5_4_3`.
    pub type_name: String,
    /// Whether values are stored as 16-bit halves.
    pub half: bool,
    /// Unique name of the grid whose tree this one shares; empty if not an instance.
    pub instance_parent: String,
    /// Offset of the grid's data (compression, metadata, transform, tree).
    pub grid_pos: u64,
    /// Offset of the grid's value buffers.
    pub block_pos: u64,
    /// Offset just past the grid.
    pub end_pos: u64,
}

pub(crate) fn read_header(r: &mut Reader<'_>) -> KResult<FileHeader> {
    if r.i64("magic number")? != MAGIC {
        return Err(VdbErrorKind::BadMagic);
    }
    let version = r.u32("file version")?;
    if !(MIN_VERSION..=MAX_VERSION).contains(&version) {
        return Err(VdbErrorKind::UnsupportedVersion(version));
    }
    let library_version = (r.u32("library major")?, r.u32("library minor")?);
    let has_grid_offsets = r.u8("grid offsets flag")? != 0;
    let mut compression = COMPRESS_ZIP | COMPRESS_ACTIVE_MASK;
    if (220..222).contains(&version) {
        compression = if r.u8("compression flag")? != 0 {
            COMPRESS_ZIP
        } else {
            0
        };
    }
    let uuid = String::from_utf8_lossy(r.take(36, "file uuid")?).into_owned();
    Ok(FileHeader {
        version,
        library_version,
        has_grid_offsets,
        compression,
        uuid,
    })
}

pub(crate) fn read_descriptor(r: &mut Reader<'_>) -> KResult<GridDescriptor> {
    let unique_name = r.string("grid name")?;
    let mut type_name = r.string("grid type")?;
    let half = type_name.ends_with("_HalfFloat");
    if half {
        type_name.truncate(type_name.len() - "_HalfFloat".len());
    }
    let instance_parent = r.string("instance parent name")?;
    let pos = |r: &mut Reader<'_>, what| -> KResult<u64> {
        let p = r.i64(what)?;
        if p < 0 {
            return corrupt(format!("negative {what} {p}"));
        }
        Ok(p as u64)
    };
    let grid_pos = pos(r, "grid offset")?;
    let block_pos = pos(r, "block offset")?;
    let end_pos = pos(r, "end offset")?;
    if !(grid_pos <= block_pos && block_pos <= end_pos) {
        return corrupt(format!(
            "grid '{unique_name}' offsets out of order ({grid_pos}, {block_pos}, {end_pos})"
        ));
    }
    let name = unique_name
        .split('\u{1e}')
        .next()
        .unwrap_or_default()
        .to_string();
    Ok(GridDescriptor {
        unique_name,
        name,
        type_name,
        half,
        instance_parent,
        grid_pos,
        block_pos,
        end_pos,
    })
}
