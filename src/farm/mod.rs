//! Render-farm splits: a still is cut into parts by sample range (`--samples START..END`) and by crop window
//! (`--crop x0,y0,x1,y1`), each part is rendered anywhere (one task of a Slurm array, a Kubernetes Indexed
//! Job, an Open Job Description step), and `nimbus merge` joins the parts into the image that one process
//! would have rendered, bit for bit.
//!
//! Why the merge is exact: sample `s` of pixel `i` is a pure function of the seed, `i` and `s`
//! (`Rng::for_sample`), and the film sums samples in fixed-point integers (`PixelSums`), so the
//! sums of any partition of the samples add up to the same integers in any order. A part file
//! (`part.rs`) stores those integer sums beside its viewable float image, and the merge adds the integers of
//! all parts and takes the image of the total with the same code as a single render.
//!
//! A merge refuses parts that do not belong together (different scene hash, resolution, seed, max depth,
//! samples per pixel or Nimbus version), that overlap (a pixel sample held twice) or that leave a gap (a
//! pixel sample held by none), with a one-line [`FarmError`] that names the files. The scene hash is
//! described in `hash.rs`; the job-index helpers of array jobs are in `chunk.rs`.
//!
//! Frames are the outer unit of a farm: a future frame number joins the keys a part carries and a merge
//! checks, and nothing here assumes a still beyond that.

pub mod checkpoint;
#[cfg(feature = "testing")]
pub mod chunk;
#[cfg(not(feature = "testing"))]
pub(crate) mod chunk;
#[cfg(feature = "testing")]
pub mod hash;
#[cfg(not(feature = "testing"))]
pub(crate) mod hash;
#[cfg(feature = "testing")]
pub mod merge;
#[cfg(not(feature = "testing"))]
pub(crate) mod merge;
#[cfg(feature = "testing")]
pub mod part;
#[cfg(not(feature = "testing"))]
pub(crate) mod part;
#[cfg(feature = "testing")]
pub use hash::SceneHasher;
#[cfg(feature = "testing")]
pub use merge::check_parts;

pub use chunk::{chunk_output_path, sample_chunk, task_index, TaskIndex, TASK_INDEX_VARIABLES};
pub use hash::{scene_hash, SceneOverrides};
pub use merge::{merge_parts, Merged};
pub use part::{read_part, read_part_info, write_part, PartInfo};

use crate::render::PixelWindow;
use std::ops::Range;
use std::path::PathBuf;

/// Why a farm split or merge failed. Every message is one line and names the files or flags involved.
#[derive(Debug, thiserror::Error)]
pub enum FarmError {
    /// A flag's value does not parse.
    #[error("{flag} '{value}': {reason}")]
    Syntax {
        /// The flag, e.g. `--samples`.
        flag: &'static str,
        /// The value given.
        value: String,
        /// What is wrong with it.
        reason: String,
    },
    /// The EXR encoder or decoder failed.
    #[error(transparent)]
    Output(#[from] crate::output::OutputError),
    /// A file is not a usable part: no part keys, a bad key, missing sum channels, or sums that disagree
    /// with its image.
    #[error("part {path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// `nimbus merge` was given no part.
    #[error("no parts to merge")]
    NoParts,
    /// Two parts come from different renders.
    #[error(
        "parts {first} and {other} do not belong together: {what} {first_value} vs {other_value}"
    )]
    Mismatch {
        /// The first part given.
        first: PathBuf,
        /// The part that differs from it.
        other: PathBuf,
        /// What differs (`seed`, `resolution`, `scene hash`...).
        what: &'static str,
        /// The first part's value.
        first_value: String,
        /// The other part's value.
        other_value: String,
    },
    /// Two parts hold some of the same samples of the same pixels.
    #[error(
        "parts {first} and {other} overlap: both hold samples {}..{} of the pixels in {window}",
        samples.start, samples.end
    )]
    Overlap {
        /// One part.
        first: PathBuf,
        /// The other part.
        other: PathBuf,
        /// The samples both hold.
        samples: Range<u32>,
        /// The pixels both hold (`x0,y0,x1,y1`).
        window: PixelWindow,
    },
    /// Some samples of some pixels are in no part.
    #[error(
        "the {parts} parts leave samples {}..{} of the pixels in {window} unrendered",
        samples.start, samples.end
    )]
    Gap {
        /// Number of parts given.
        parts: usize,
        /// Samples no part holds.
        samples: Range<u32>,
        /// Pixels (`x0,y0,x1,y1`) where they are missing.
        window: PixelWindow,
    },
    /// The merge output would overwrite one of its inputs.
    #[error("output {path} is one of the parts to merge")]
    OutputIsInput {
        /// The file.
        path: PathBuf,
    },
    /// No job index in the environment, or one that is not a chunk index.
    #[error("--chunk-from-env: {reason}")]
    TaskIndex {
        /// What is wrong.
        reason: String,
    },
    /// `--chunks` cannot split the samples: zero chunks, or more chunks than samples per pixel.
    #[error("--chunks {chunks}: {reason}")]
    Chunks {
        /// The number of chunks asked for.
        chunks: u32,
        /// What is wrong.
        reason: String,
    },
}

/// Parses `--samples START..END`: the samples `START` to `END - 1` of every pixel's sample sequence.
///
/// ```
/// assert_eq!(nimbus::farm::parse_samples("8..16").unwrap(), 8..16);
/// assert!(nimbus::farm::parse_samples("16..8").is_err());
/// ```
pub fn parse_samples(value: &str) -> Result<Range<u32>, FarmError> {
    let syntax = |reason: &str| FarmError::Syntax {
        flag: "--samples",
        value: value.to_string(),
        reason: reason.to_string(),
    };
    let (start, end) = value
        .split_once("..")
        .ok_or_else(|| syntax("expected START..END, e.g. 0..16"))?;
    let number = |s: &str| {
        s.trim()
            .parse::<u32>()
            .map_err(|e| syntax(&format!("'{s}': {e}")))
    };
    let (start, end) = (number(start)?, number(end)?);
    if start >= end {
        return Err(syntax("START must be below END (END is exclusive)"));
    }
    Ok(start..end)
}

/// Parses `--crop x0,y0,x1,y1`: the pixels `x0 ≤ x < x1`, `y0 ≤ y < y1` of the frame, `(0, 0)` the top-left
/// pixel. Whether it fits the frame is checked when the frame size is known.
///
/// ```
/// let w = nimbus::farm::parse_crop("16,0,48,24").unwrap();
/// assert_eq!((w.x0, w.y0, w.x1, w.y1), (16, 0, 48, 24));
/// assert!(nimbus::farm::parse_crop("16,0,16,24").is_err());
/// ```
pub fn parse_crop(value: &str) -> Result<PixelWindow, FarmError> {
    let syntax = |reason: &str| FarmError::Syntax {
        flag: "--crop",
        value: value.to_string(),
        reason: reason.to_string(),
    };
    let numbers = value
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<usize>()
                .map_err(|e| syntax(&format!("'{s}': {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let [x0, y0, x1, y1] = numbers[..] else {
        return Err(syntax("expected four numbers x0,y0,x1,y1"));
    };
    if x0 >= x1 || y0 >= y1 {
        return Err(syntax(
            "x0 < x1 and y0 < y1 are needed (x1 and y1 are exclusive)",
        ));
    }
    Ok(PixelWindow { x0, y0, x1, y1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_parse_and_refuse_bad_ranges() {
        assert_eq!(parse_samples("0..1").unwrap(), 0..1);
        assert_eq!(parse_samples(" 3 .. 10 ").unwrap(), 3..10);
        for bad in ["", "5", "5..5", "6..5", "a..4", "-1..4", "0..4..8", "0...4"] {
            let err = parse_samples(bad).unwrap_err().to_string();
            assert!(err.starts_with("--samples '"), "{bad}: {err}");
        }
    }

    #[test]
    fn crops_parse_and_refuse_bad_windows() {
        assert_eq!(
            parse_crop("1,2,3,4").unwrap(),
            PixelWindow {
                x0: 1,
                y0: 2,
                x1: 3,
                y1: 4
            }
        );
        for bad in [
            "",
            "1,2,3",
            "1,2,3,4,5",
            "3,0,3,4",
            "0,4,3,4",
            "a,0,1,1",
            "-1,0,2,2",
        ] {
            let err = parse_crop(bad).unwrap_err().to_string();
            assert!(err.starts_with("--crop '"), "{bad}: {err}");
        }
    }
}
