//! Error types of the VDB reader.

use crate::limits::one_line;
use std::path::PathBuf;

/// The most characters of a name or message taken from the file that an error quotes.
const QUOTED_CHARS: usize = 64;

/// `text` from the file as printable ASCII, cut to [`QUOTED_CHARS`].
fn quoted(text: &str) -> String {
    one_line(text, QUOTED_CHARS)
}

/// An error from reading a VDB file: the file it concerns and what went wrong.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct VdbError {
    /// The file (or the name given for an in-memory buffer).
    pub path: PathBuf,
    /// What went wrong.
    pub kind: VdbErrorKind,
}

/// What went wrong while reading a VDB file.
#[derive(Debug, thiserror::Error)]
pub enum VdbErrorKind {
    /// The file could not be read from disk.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The data ended before a field was complete.
    #[error(
        "truncated data: {what} needs {needed} bytes at offset {offset}, only {remaining} left"
    )]
    Truncated {
        /// The field being read.
        what: &'static str,
        /// Byte offset of the field.
        offset: usize,
        /// Bytes the field needs.
        needed: u64,
        /// Bytes left in the input.
        remaining: usize,
    },
    /// The file does not start with the OpenVDB magic number.
    #[error("not an OpenVDB file (bad magic number)")]
    BadMagic,
    /// The file format version is outside the supported range.
    #[error("unsupported OpenVDB file version {0} (supported: 219..=224)")]
    UnsupportedVersion(u32),
    /// A grid has a value type or tree configuration this reader does not handle.
    #[error("grid '{}' has unsupported type '{}'", quoted(grid), quoted(type_name))]
    UnsupportedGridType {
        /// Name of the grid.
        grid: String,
        /// Its OpenVDB type name.
        type_name: String,
    },
    /// The transform uses a map this reader does not handle (e.g. a frustum map).
    #[error("unsupported transform map '{}'", quoted(.0))]
    UnsupportedMap(String),
    /// A feature of the format that this reader does not handle.
    #[error("unsupported feature: {}", quoted(.0))]
    Unsupported(String),
    /// A field holds an impossible value.
    #[error("corrupt data: {}", one_line(.0, 4 * QUOTED_CHARS))]
    Corrupt(String),
    /// A compressed block could not be decoded.
    #[error("decompression failed: {0}")]
    Decompress(String),
    /// An error inside one grid, with the grid's name.
    #[error("in grid '{}': {source}", quoted(grid))]
    InGrid {
        /// Name of the grid.
        grid: String,
        /// The underlying problem.
        source: Box<VdbErrorKind>,
    },
}

/// Result type used inside the reader, before the file path is attached.
pub(crate) type KResult<T> = Result<T, VdbErrorKind>;

/// Shorthand for a [`VdbErrorKind::Corrupt`] error.
pub(crate) fn corrupt<T>(msg: impl Into<String>) -> KResult<T> {
    Err(VdbErrorKind::Corrupt(msg.into()))
}
