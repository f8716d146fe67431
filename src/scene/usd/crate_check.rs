//! A bounds check of binary `.usdc` (crate) files before `openusd` 0.6 reads them.
//!
//! `openusd` 0.6 sizes buffers from counts read in the file without comparing them to the file's length, so a
//! damaged count makes it request terabytes and the process aborts (an allocation failure cannot be caught).
//! This walks the same structure first (header, table of contents, the TOKENS, STRINGS, FIELDS, FIELDSETS,
//! PATHS and SPECS sections, then the element count of every array value and the first compressed block of
//! compressed arrays) and rejects any count that the file could not hold: LZ4 expands at most 255-fold, so no
//! decoded buffer exceeds 256 × the file size, and no compressed block runs past the end of the file. Crate
//! versions before 0.4.0 (uncompressed structural sections) are refused rather than checked.

use crate::limits::{read_file, Limits};
use openusd::ar;
use openusd::usdc::CrateFile;
use std::io::{self, Cursor};
use std::path::Path;

/// Checks `bytes`, a `.usdc` file, for counts that would make the reader allocate beyond the data.
pub(super) fn check(bytes: &[u8]) -> Result<(), CrateError> {
    if bytes.get(..8) != Some(b"PXR-USDC".as_slice()) {
        return Err(CrateError::BadMagic);
    }
    let version = (
        bytes.get(8).copied(),
        bytes.get(9).copied(),
        bytes.get(10).copied(),
    );
    let (Some(major), Some(minor), Some(patch)) = version else {
        return Err(CrateError::TruncatedHeader);
    };
    let version = (major, minor, patch);
    if version < (0, 4, 0) {
        return Err(CrateError::OldVersion(major, minor, patch));
    }
    check_sections(bytes)?;
    // The structure is sound: let the crate reader decode it, then check every array value's length.
    let file = CrateFile::open(Cursor::new(bytes)).map_err(CrateError::reader)?;
    file.validate().map_err(CrateError::reader)?;
    if let Some(deep) = file
        .paths
        .iter()
        .find(|p| p.element_count() > super::layers::MAX_NESTING)
    {
        return Err(CrateError::PathTooDeep(deep.element_count()));
    }
    for field in &file.fields {
        let rep = field.value_rep;
        if !rep.is_array() && !rep.is_inlined() {
            let ty = (rep.0 >> 48) & 0xFF;
            counted_vectors(bytes, rep.payload(), ty)?;
            if ty == DICTIONARY {
                let mut budget = Reader { bytes, pos: 0 }.limit();
                dictionary(bytes, rep.payload(), 0, &mut budget, version)?;
            }
        }
        array_value(bytes, rep.0, version)?;
    }
    Ok(())
}

/// Why a `.usdc` file is refused before `openusd` reads it ([`check`]).
#[derive(Debug, thiserror::Error)]
pub(super) enum CrateError {
    /// The file does not start with the crate magic.
    #[error("not a USD crate file (bad magic)")]
    BadMagic,
    /// The file ends inside its header.
    #[error("truncated header")]
    TruncatedHeader,
    /// A crate version (major, minor, patch) before 0.4.0.
    #[error("crate version {0}.{1}.{2} is older than 0.4.0")]
    OldVersion(u8, u8, u8),
    /// `openusd`'s crate reader refused the file, saying this (its whole chain of causes).
    #[error("{0}")]
    Reader(String),
    /// A path with this many elements, more than [`super::layers::MAX_NESTING`].
    #[error("a path nests deeper than {max} levels ({0} elements)", max = super::layers::MAX_NESTING)]
    PathTooDeep(usize),
    /// A table of contents with this many sections (none, or 64 and more).
    #[error("{0} sections")]
    Sections(u64),
    /// The named section runs past the end of the file.
    #[error("section {0} runs past the end of the file")]
    SectionPastEnd(String),
    /// The STRINGS section's byte count overflows.
    #[error("string count overflows")]
    StringCountOverflow,
    /// Dictionaries nest deeper than [`super::layers::MAX_NESTING`].
    #[error("dictionaries nest deeper than {} levels", super::layers::MAX_NESTING)]
    DictionaryTooDeep,
    /// A dictionary at `payload` claims `n` entries, more than the file could hold.
    #[error("a dictionary at offset {payload} claims {n} entries")]
    DictionaryEntries { payload: u64, n: u64 },
    /// A dictionary entry at this offset jumps outside the file.
    #[error("a dictionary entry at offset {0} jumps outside the file")]
    DictionaryJump(i64),
    /// An array claims this many elements, more than the file could hold.
    #[error("an array claims {0} elements")]
    ArrayElements(u64),
    /// A vector of crate type `ty` at `payload` claims `n` items, more than the file holds.
    #[error("a vector of type {ty} at offset {payload} claims {n} items")]
    VectorItems { ty: u64, payload: u64, n: u64 },
    /// An offset past the end of the file.
    #[error("offset {0} is past the end of the file")]
    OffsetPastEnd(u64),
    /// `n` bytes at offset `at` run past the end of the file.
    #[error("{n} bytes at offset {at} run past the end of the file")]
    BytesPastEnd { n: usize, at: usize },
    /// A count of `n` at offset `at`, more than the file could hold.
    #[error("a count of {n} at offset {at} exceeds the file")]
    CountExceeds { n: u64, at: usize },
    /// A compressed block's size does not fit memory.
    #[error("compressed size overflows")]
    CompressedSizeOverflow,
}

impl CrateError {
    /// The error of `openusd`'s crate reader, with its whole chain of causes.
    fn reader(error: impl std::fmt::Display) -> Self {
        CrateError::Reader(format!("{error:#}"))
    }
}

/// Checks the table of contents and, in each section `openusd` reads, the counts and compressed blocks that
/// size its allocations: each must lie within the file.
fn check_sections(bytes: &[u8]) -> Result<(), CrateError> {
    let mut c = Reader { bytes, pos: 16 };
    let toc = c.u64()?;
    c.seek(toc)?;
    let sections = c.u64()?;
    if sections == 0 || sections >= 64 {
        return Err(CrateError::Sections(sections));
    }
    for _ in 0..sections {
        let name = c.take(16)?.to_vec();
        let (start, size) = (c.u64()?, c.u64()?);
        // The name up to its first NUL, as `openusd` reads it (bytes after the NUL do not count: a name
        // "TOKENS\0...\x04" is the TOKENS section to the reader, so it must be to this check).
        let name_end = name.iter().position(|&b| b == 0).unwrap_or(name.len());
        let name = String::from_utf8_lossy(&name[..name_end]).into_owned();
        if start
            .checked_add(size)
            .is_none_or(|end| end > bytes.len() as u64)
        {
            return Err(CrateError::SectionPastEnd(name));
        }
        let mut s = Reader { bytes, pos: 0 };
        s.seek(start)?;
        match name.as_str() {
            "TOKENS" => {
                s.count()?;
                s.count()?;
                s.compressed()?;
            }
            "STRINGS" => {
                let n = s.count()?;
                s.take(n.checked_mul(4).ok_or(CrateError::StringCountOverflow)?)?;
            }
            "FIELDS" => {
                s.count()?;
                s.compressed()?;
                s.compressed()?;
            }
            "FIELDSETS" | "SPECS" => {
                s.count()?;
                let blocks = if name == "SPECS" { 3 } else { 1 };
                for _ in 0..blocks {
                    s.compressed()?;
                }
            }
            "PATHS" => {
                s.count()?;
                s.count()?;
                for _ in 0..3 {
                    s.compressed()?;
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The crate type of a dictionary value.
const DICTIONARY: u64 = 31;

/// Checks a dictionary value at `payload` the way `openusd` reads it (a count, then per entry a string index,
/// a relative jump to the entry's value representation, read in place): `openusd` recurses once per nested
/// dictionary and follows the jumps without checking them, so nesting deeper than
/// [`super::layers::MAX_NESTING`], a jump outside the file, or more entries in all than the file could hold
/// (jumps can revisit entries, even in a loop) is refused. `budget` counts down the entries visited.
fn dictionary(
    bytes: &[u8],
    payload: u64,
    depth: usize,
    budget: &mut u64,
    version: (u8, u8, u8),
) -> Result<(), CrateError> {
    if depth > super::layers::MAX_NESTING {
        return Err(CrateError::DictionaryTooDeep);
    }
    let mut r = Reader { bytes, pos: 0 };
    r.seek(payload)?;
    let n = r.u64()?;
    if n > bytes.len() as u64 / 12 || n > *budget {
        return Err(CrateError::DictionaryEntries { payload, n });
    }
    *budget -= n;
    for _ in 0..n {
        r.take(4)?;
        let at = r.pos as i64;
        let jump = i64::from_le_bytes(r.take(8)?.try_into().unwrap_or_default());
        let target = at
            .checked_add(jump)
            .filter(|t| *t >= 0)
            .ok_or(CrateError::DictionaryJump(at))?;
        r.seek(target as u64)?;
        // A value representation: type in bits 48..56, "inlined" bit 62, payload in bits 0..48.
        let rep = r.u64()?;
        if (rep >> 48) & 0xFF == DICTIONARY && rep & (1 << 62) == 0 {
            dictionary(bytes, rep & ((1 << 48) - 1), depth + 1, budget, version)?;
        }
        // An array entry is read like an array field: its count is allocated first.
        array_value(bytes, rep, version)?;
    }
    Ok(())
}

/// Checks the array a value representation `rep` points at, if it is a non-inlined array: its element count
/// must fit what the file could hold, and a compressed one must hold a whole LZ4 block (the reader allocates
/// the count, and the block's decoded size, before reading them).
fn array_value(bytes: &[u8], rep: u64, version: (u8, u8, u8)) -> Result<(), CrateError> {
    let is_array = rep & (1 << 63) != 0;
    let is_inlined = rep & (1 << 62) != 0;
    let is_compressed = rep & (1 << 61) != 0;
    let payload = rep & ((1 << 48) - 1);
    if !is_array || is_inlined || payload == 0 {
        return Ok(());
    }
    let mut a = Reader { bytes, pos: 0 };
    a.seek(payload)?;
    if version < (0, 5, 0) {
        a.take(4)?;
    }
    let n = if version < (0, 7, 0) {
        u32::from_le_bytes(a.take(4)?.try_into().unwrap_or_default()) as u64
    } else {
        a.u64()?
    };
    if n > a.limit() {
        return Err(CrateError::ArrayElements(n));
    }
    if is_compressed && n >= 4 {
        // Compressed integer arrays hold an LZ4 block; compressed float arrays a codec byte before one (or
        // before a lookup table). Which it is follows the element type, as the reader decides.
        match (rep >> 48) & 0xFF {
            3..=6 => Reader { bytes, pos: a.pos }.compressed()?,
            ty @ 7..=9 => {
                let mut r = Reader { bytes, pos: a.pos };
                match r.take(1)?[0] {
                    b'i' => r.compressed()?,
                    b't' => {
                        // A lookup table of elements (2, 4 or 8 bytes), then the compressed indices.
                        let entries = u32::from_le_bytes(r.take(4)?.try_into().unwrap_or_default());
                        let size = [2usize, 4, 8][(ty - 7) as usize];
                        r.take((entries as usize).saturating_mul(size))?;
                        r.compressed()?;
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Checks the count-prefixed vectors of a non-array value of crate type `ty` at `payload` (the reader
/// allocates each count before reading): token, string and path vectors and list ops hold 4-byte indices,
/// 64-bit list ops 8 bytes, double vectors 8 and layer-offset vectors 16; reference, payload and unregistered
/// list ops hold items of varying size, of which only the first list's count is bounded (one byte per item).
fn counted_vectors(bytes: &[u8], payload: u64, ty: u64) -> Result<(), CrateError> {
    let (list_op, item) = match ty {
        40 | 41 | 50 => (false, 4),
        48 => (false, 8),
        49 => (false, 16),
        32 | 33 | 34 | 36 | 38 => (true, 4),
        37 | 39 => (true, 8),
        35 | 54 | 55 => (true, 0),
        _ => return Ok(()),
    };
    let mut r = Reader { bytes, pos: 0 };
    r.seek(payload)?;
    // A list op's header byte: bit 0 says "explicit", each further bit one list that follows.
    let lists = if list_op {
        (r.take(1)?[0] >> 1).count_ones()
    } else {
        1
    };
    for _ in 0..lists {
        let n = r.u64()?;
        let room = (bytes.len() - r.pos) as u64;
        if n.checked_mul(item.max(1)).is_none_or(|b| b > room) {
            return Err(CrateError::VectorItems { ty, payload, n });
        }
        if item == 0 {
            break;
        }
        r.take((n * item) as usize)?;
    }
    Ok(())
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    /// The largest count or decoded size the file could justify.
    fn limit(&self) -> u64 {
        256 * self.bytes.len() as u64 + 1024
    }

    fn seek(&mut self, pos: u64) -> Result<(), CrateError> {
        if pos > self.bytes.len() as u64 {
            return Err(CrateError::OffsetPastEnd(pos));
        }
        self.pos = pos as usize;
        Ok(())
    }

    fn take(&mut self, n: usize) -> Result<&[u8], CrateError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or(CrateError::BytesPastEnd { n, at: self.pos })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u64(&mut self) -> Result<u64, CrateError> {
        let b = self.take(8)?;
        Ok(u64::from_le_bytes(b.try_into().unwrap_or_default()))
    }

    /// A count or decoded size, bounded by what the file could hold.
    fn count(&mut self) -> Result<usize, CrateError> {
        let n = self.u64()?;
        if n > self.limit() {
            return Err(CrateError::CountExceeds {
                n,
                at: self.pos - 8,
            });
        }
        Ok(n as usize)
    }

    /// A compressed block: its size, then that many bytes.
    fn compressed(&mut self) -> Result<(), CrateError> {
        let n = self.u64()?;
        let n = usize::try_from(n).map_err(|_| CrateError::CompressedSizeOverflow)?;
        self.take(n).map(|_| ())
    }
}

/// The default file-system resolver, with every layer it opens (the root layer, sublayers, references and
/// payloads, `.usdz` packages and the layers inside them) read with the memory budget's size cap and checked by
/// [`super::layers::check_layer`] (crate bounds via [`check`], text nesting, package entries) before `openusd`
/// parses it. A failed check is an `InvalidData` error naming the layer, which `openusd` reports as a load or
/// composition error.
pub(super) struct CheckingResolver {
    /// The resolver that finds and opens the files.
    pub(super) inner: ar::DefaultResolver,
    /// The size cap of every file read.
    pub(super) limits: Limits,
}

impl ar::Resolver for CheckingResolver {
    fn create_identifier(&self, asset_path: &str, anchor: Option<&ar::ResolvedPath>) -> String {
        self.inner.create_identifier(asset_path, anchor)
    }

    fn resolve(&self, asset_path: &str) -> Option<ar::ResolvedPath> {
        self.inner.resolve(asset_path)
    }

    fn resolve_for_new_asset(&self, asset_path: &str) -> Option<ar::ResolvedPath> {
        self.inner.resolve_for_new_asset(asset_path)
    }

    fn open_asset(&self, resolved_path: &ar::ResolvedPath) -> io::Result<Box<dyn ar::Asset>> {
        let invalid = |m: super::layers::LayerError| {
            io::Error::new(io::ErrorKind::InvalidData, format!("{resolved_path}: {m}"))
        };
        let name = resolved_path.to_str().unwrap_or_default();
        let bytes = if ar::is_package_relative_path(name) {
            // A layer inside a package: check the whole package first (its entries with a size cap).
            if let Some((package, _)) = ar::split_package_relative_path_outer(name) {
                let outer = read_file(Path::new(&package), &self.limits)?;
                super::layers::check_layer(&outer, &self.limits).map_err(invalid)?;
            }
            self.inner.open_asset(resolved_path)?.read_all()?
        } else {
            read_file(resolved_path, &self.limits)?
        };
        super::layers::check_layer(&bytes, &self.limits).map_err(invalid)?;
        Ok(Box::new(Cursor::new(bytes)))
    }

    fn get_extension<'a>(&self, asset_path: &'a str) -> &'a str {
        self.inner.get_extension(asset_path)
    }

    fn get_asset_info(&self, asset_path: &str, resolved_path: &ar::ResolvedPath) -> ar::AssetInfo {
        self.inner.get_asset_info(asset_path, resolved_path)
    }

    fn get_modification_timestamp(
        &self,
        asset_path: &str,
        resolved_path: &ar::ResolvedPath,
    ) -> Option<std::time::SystemTime> {
        self.inner
            .get_modification_timestamp(asset_path, resolved_path)
    }

    fn identity(&self) -> String {
        self.inner.identity()
    }
}
