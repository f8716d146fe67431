//! Checkpoints of a render (`nimbus render --checkpoint SECONDS`, continued with `--resume`): the film's exact
//! sums written as a part (format `nimbus-checkpoint-1`, see `super::part`) beside the output, atomically,
//! with which samples each pixel holds ([`RegionProgress`]). Because the film sums exactly and every sample is
//! a pure function of the seed, the pixel and the sample number, a render continued from a checkpoint writes
//! the image of an uninterrupted render, bit for bit.

use super::part::{read_part, write_part, PartInfo};
use super::FarmError;
use crate::render::resume::{RegionProgress, ResumeFrom};
use crate::render::Film;
use std::path::{Path, PathBuf};

/// The checkpoint of the render whose output is `output`: `NAME.checkpoint.exr` beside `NAME.exr` (any other
/// extension is kept before `.checkpoint.exr`).
pub fn checkpoint_path(output: &Path) -> PathBuf {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let stem = name.strip_suffix(".exr").unwrap_or(&name);
    output.with_file_name(format!("{stem}.checkpoint.exr"))
}

/// Writes the checkpoint of `film`, which holds the samples `progress` says of the region `info` describes
/// (whose `samples` start where the region's do; its end is set from `progress`), atomically.
pub fn write_checkpoint(
    path: &Path,
    film: &Film,
    info: &PartInfo,
    progress: &RegionProgress,
) -> Result<(), FarmError> {
    let start = info.samples.start;
    let info = PartInfo {
        samples: start..start + progress.most_samples(start),
        progress: Some(progress.clone()),
        ..info.clone()
    };
    write_part(path, film, &info)
}

/// Reads the checkpoint at `path`: its description (to compare with the render's) and where to resume from.
pub fn read_checkpoint(path: &Path) -> Result<(PartInfo, ResumeFrom), FarmError> {
    let (info, film) = read_part(path)?;
    let Some(progress) = info.progress.clone() else {
        return Err(FarmError::Invalid {
            path: path.to_path_buf(),
            reason: "a finished part, not a checkpoint".into(),
        });
    };
    let from = ResumeFrom {
        film,
        progress,
        nan_samples: info.nan_samples,
        clamped_samples: info.clamped_samples,
    };
    Ok((info, from))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_checkpoint_sits_beside_the_output() {
        assert_eq!(
            checkpoint_path(Path::new("shots/a/out.0012.exr")),
            Path::new("shots/a/out.0012.checkpoint.exr")
        );
        assert_eq!(
            checkpoint_path(Path::new("beauty")),
            Path::new("beauty.checkpoint.exr")
        );
    }
}
