//! Checks of every layer before `openusd` 0.6 parses it, for what it would abort or overflow on.
//!
//! - Text layers (`.usda`, a text `.usd`): `openusd`'s parser recurses once per nesting level, so a file nested
//!   thousands of levels deep overflows the stack and aborts the process (a stack overflow cannot be caught).
//!   [`text_nesting`] measures the deepest nesting of braces, brackets and parentheses outside comments,
//!   strings, paths (`<...>`) and asset paths (`@...@`), the same tokens `openusd`'s lexer skips, and a layer
//!   nested deeper than [`MAX_NESTING`] is refused.
//! - Binary layers (`.usdc`): bounds-checked by `crate_check`, which also refuses prim paths deeper than
//!   [`MAX_NESTING`].
//! - Packages (`.usdz`): every layer inside is decompressed with a size cap (a zip bomb is refused) and checked
//!   as above.

use super::crate_check::{self, CrateError};
use crate::limits::{Limits, MAX_STREAM_BYTES};
use std::io::{Cursor, Read};

/// Deepest nesting of braces, brackets and parentheses accepted in a text layer, and deepest prim path in a
/// binary one. Real stages stay far below it (each prim level takes one pair of braces); `openusd` needs far
/// less stack than the loader's thread has for this many levels.
pub const MAX_NESTING: usize = 200;

/// Why a layer or package is refused before `openusd` parses it, or a file in a package cannot be read.
#[derive(Debug, thiserror::Error)]
pub(super) enum LayerError {
    /// A `.usdc` layer fails the crate bounds check.
    #[error(transparent)]
    Crate(#[from] CrateError),
    /// A path literal of a text layer, starting `start`, runs past the end of its line.
    #[error("line {line}: the path starting '<{start}' runs past the end of its line")]
    UnclosedPath { line: usize, start: String },
    /// A text layer nests deeper than [`MAX_NESTING`] at `line`.
    #[error("line {line}: nested deeper than {MAX_NESTING} levels")]
    TooDeep { line: usize },
    /// A package file cannot be read.
    #[error("{0}")]
    Read(std::io::Error),
    /// A package that is not a zip archive.
    #[error("not a valid package: {0}")]
    Package(zip::result::ZipError),
    /// Entry `index` of a package cannot be opened.
    #[error("package entry {index}: {error}")]
    Entry {
        index: usize,
        error: zip::result::ZipError,
    },
    /// A package entry cannot be decompressed.
    #[error("package entry '{name}': {error}")]
    EntryRead { name: String, error: std::io::Error },
    /// A package entry expands to more than `cap` bytes.
    #[error("package entry '{name}' expands to more than {}", crate::limits::format_bytes(*cap))]
    EntryTooLarge { name: String, cap: u64 },
    /// A layer inside a package fails its check.
    #[error("package entry '{name}': {error}")]
    InEntry {
        name: String,
        error: Box<LayerError>,
    },
}

/// Checks one layer or package by its content: a crate file, a zip package or (anything else) text.
pub(super) fn check_layer(bytes: &[u8], limits: &Limits) -> Result<(), LayerError> {
    if bytes.starts_with(b"PXR-USDC") {
        Ok(crate_check::check(bytes)?)
    } else if bytes.starts_with(b"PK\x03\x04") {
        check_package(bytes, limits)
    } else {
        text_nesting(bytes)
    }
}

/// Checks every layer in a `.usdz` package, decompressing each with a cap of the memory budget (at most
/// [`MAX_STREAM_BYTES`]).
fn check_package(bytes: &[u8], limits: &Limits) -> Result<(), LayerError> {
    let mut archive = zip::ZipArchive::new(Cursor::new(bytes)).map_err(LayerError::Package)?;
    for i in 0..archive.len() {
        let name = archive
            .by_index(i)
            .map_err(|error| LayerError::Entry { index: i, error })?
            .name()
            .to_owned();
        let layer = [".usda", ".usdc", ".usd"]
            .iter()
            .any(|ext| name.to_ascii_lowercase().ends_with(ext));
        if !layer {
            continue;
        }
        let data = read_entry(&mut archive, i, limits)?;
        let inner = if data.starts_with(b"PXR-USDC") {
            crate_check::check(&data).map_err(LayerError::from)
        } else {
            text_nesting(&data)
        };
        inner.map_err(|error| LayerError::InEntry {
            name,
            error: Box::new(error),
        })?;
    }
    Ok(())
}

/// Decompresses entry `index` of a package with a cap of the memory budget (at most [`MAX_STREAM_BYTES`]): a
/// zip bomb is an error, not an allocation.
fn read_entry<R: Read + std::io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    index: usize,
    limits: &Limits,
) -> Result<Vec<u8>, LayerError> {
    let cap = MAX_STREAM_BYTES.min(limits.memory_bytes);
    let mut entry = archive
        .by_index(index)
        .map_err(|error| LayerError::Entry { index, error })?;
    let name = entry.name().to_owned();
    let mut data = Vec::new();
    (&mut entry)
        .take(cap + 1)
        .read_to_end(&mut data)
        .map_err(|error| LayerError::EntryRead {
            name: name.clone(),
            error,
        })?;
    if data.len() as u64 > cap {
        return Err(LayerError::EntryTooLarge { name, cap });
    }
    Ok(data)
}

/// A `.usdz` package opened to read the files inside it (textures), USDZ spec: a zip archive whose asset paths
/// resolve relative to the layer inside the package that names them.
pub(super) struct Package {
    archive: zip::ZipArchive<Cursor<Vec<u8>>>,
}

impl Package {
    /// Opens the package at `path`, read whole with the memory budget's size cap.
    pub(super) fn open(path: &std::path::Path, limits: &Limits) -> Result<Self, LayerError> {
        let bytes = crate::limits::read_file(path, limits).map_err(LayerError::Read)?;
        let archive = zip::ZipArchive::new(Cursor::new(bytes)).map_err(LayerError::Package)?;
        Ok(Self { archive })
    }

    /// The bytes of the entry at `member` (a `/`-separated path inside the package, `.` and `..` resolved),
    /// decompressed with a cap; `Ok(None)` when the package holds no such entry.
    pub(super) fn read(
        &mut self,
        member: &str,
        limits: &Limits,
    ) -> Result<Option<Vec<u8>>, LayerError> {
        let mut parts: Vec<&str> = Vec::new();
        for part in member.split(['/', '\\']) {
            match part {
                "" | "." => {}
                ".." => {
                    parts.pop();
                }
                p => parts.push(p),
            }
        }
        let name = parts.join("/");
        let Some(index) = self.archive.index_for_name(&name) else {
            return Ok(None);
        };
        read_entry(&mut self.archive, index, limits).map(Some)
    }
}

/// Refuses a text layer whose braces, brackets and parentheses nest deeper than [`MAX_NESTING`]. Unterminated
/// comments, strings and paths end the scan: `openusd`'s lexer stops there too.
pub(super) fn text_nesting(bytes: &[u8]) -> Result<(), LayerError> {
    let find = |from: usize, pat: &[u8]| {
        bytes
            .get(from..)
            .and_then(|rest| rest.windows(pat.len()).position(|w| w == pat))
            .map(|at| from + at + pat.len())
    };
    let (mut depth, mut line, mut i) = (0usize, 1usize, 0usize);
    let end = bytes.len();
    while i < end {
        let c = bytes[i];
        let next = match c {
            b'#' => find(i, b"\n").map(|e| e - 1),
            b'/' if bytes.get(i + 1) == Some(&b'*') => find(i + 2, b"*/"),
            b'"' | b'\'' if bytes.get(i + 1) == Some(&c) && bytes.get(i + 2) == Some(&c) => {
                find(i + 3, &[c, c, c])
            }
            b'"' | b'\'' => {
                let mut j = i + 1;
                loop {
                    match bytes.get(j) {
                        None => break None,
                        Some(b'\\') => j += 2,
                        Some(&q) if q == c => break Some(j + 1),
                        Some(_) => j += 1,
                    }
                }
            }
            b'<' => {
                let close = find(i + 1, b">");
                // A path literal is one token: a line break or other control byte inside means an unclosed
                // `<`, which `openusd` reads as a path running on into the following lines (one such path
                // made its instancing resolution run for minutes).
                let inside = &bytes[i + 1..close.map_or(end, |c| c - 1)];
                if close.is_some() && inside.iter().any(u8::is_ascii_control) {
                    return Err(LayerError::UnclosedPath {
                        line,
                        start: crate::limits::one_line(
                            &String::from_utf8_lossy(&inside[..inside.len().min(40)]),
                            40,
                        ),
                    });
                }
                close
            }
            b'@' if bytes.get(i + 1..i + 3) == Some(b"@@".as_slice()) => find(i + 3, b"@@@"),
            b'@' => find(i + 1, b"@"),
            b'{' | b'[' | b'(' => {
                depth += 1;
                if depth > MAX_NESTING {
                    return Err(LayerError::TooDeep { line });
                }
                Some(i + 1)
            }
            b'}' | b']' | b')' => {
                depth = depth.saturating_sub(1);
                Some(i + 1)
            }
            _ => Some(i + 1),
        };
        let next = next.unwrap_or(end).min(end);
        line += bytes[i..next].iter().filter(|&&b| b == b'\n').count();
        i = next.max(i + 1);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nesting_skips_comments_strings_and_paths() {
        let deep = |n: usize| "{".repeat(n) + &"}".repeat(n);
        assert!(text_nesting(deep(MAX_NESTING).as_bytes()).is_ok());
        let err = text_nesting(format!("#usda 1.0\n\n{}", deep(MAX_NESTING + 1)).as_bytes());
        assert_eq!(
            err.unwrap_err().to_string(),
            format!("line 3: nested deeper than {MAX_NESTING} levels")
        );
        let hidden = "{".repeat(MAX_NESTING + 1);
        for text in [
            format!("# {hidden}\n"),
            format!("/* {hidden} */"),
            format!("\"{hidden}\\\"\""),
            format!("'{hidden}'"),
            format!("\"\"\"{hidden}\"\"\""),
            format!("'''{hidden}'''"),
            format!("</a{hidden}>"),
            format!("@{hidden}@"),
            format!("@@@{hidden}@@@"),
        ] {
            assert!(text_nesting(text.as_bytes()).is_ok(), "{text}");
        }
        // Closing brackets inside a string do not hide the nesting around them.
        let masked = format!(
            "{}\"{}\"{}",
            "(".repeat(150),
            "}".repeat(300),
            "[".repeat(60)
        );
        assert!(text_nesting(masked.as_bytes()).is_err());
    }
}
