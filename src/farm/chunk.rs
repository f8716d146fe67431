//! Job-index helpers, so that one command line serves every task of an array job: `--chunk-from-env` takes
//! the task's index from the scheduler's environment and `--chunks N` splits the samples per pixel into `N`
//! nearly equal ranges, one per index.

use super::FarmError;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The environment variables that hold a task's index, in the order they are read: an explicit
/// `NIMBUS_TASK_INDEX`, then a Slurm array task's `SLURM_ARRAY_TASK_ID`, then a Kubernetes Indexed Job's
/// `JOB_COMPLETION_INDEX`. Indices run from 0 (`sbatch --array=0-(N-1)`).
pub const TASK_INDEX_VARIABLES: [&str; 3] = [
    "NIMBUS_TASK_INDEX",
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
];

/// A task's chunk index and where it came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TaskIndex {
    /// The index, below the number of chunks.
    pub index: u32,
    /// The environment variable it was read from.
    pub variable: &'static str,
}

/// The task index for `chunks` chunks from the first of [`TASK_INDEX_VARIABLES`] that `lookup` finds set
/// (pass `|k| std::env::var(k).ok()` for the process environment).
pub fn task_index(
    lookup: impl Fn(&str) -> Option<String>,
    chunks: u32,
) -> Result<TaskIndex, FarmError> {
    let found = TASK_INDEX_VARIABLES
        .iter()
        .find_map(|&v| lookup(v).map(|value| (v, value)));
    let Some((variable, value)) = found else {
        return Err(FarmError::TaskIndex {
            reason: format!(
                "none of {} is set (run it as an array task, or set NIMBUS_TASK_INDEX)",
                TASK_INDEX_VARIABLES.join(", ")
            ),
        });
    };
    match value.trim().parse::<u32>() {
        Ok(index) if index < chunks => Ok(TaskIndex { index, variable }),
        Ok(index) => Err(FarmError::TaskIndex {
            reason: format!(
                "{variable}={index} is not below --chunks {chunks} (array indices run from 0 to {})",
                chunks.saturating_sub(1)
            ),
        }),
        Err(e) => Err(FarmError::TaskIndex {
            reason: format!("{variable}='{value}' is not a task index: {e}"),
        }),
    }
}

/// The samples of chunk `index` of `chunks` over `0..spp`: `index·spp/chunks .. (index+1)·spp/chunks`, so the
/// chunks cover the samples once each and differ in size by at most one.
///
/// ```
/// let ranges: Vec<_> = (0..3).map(|i| nimbus::farm::sample_chunk(i, 3, 16).unwrap()).collect();
/// assert_eq!(ranges, [0..5, 5..10, 10..16]);
/// ```
pub fn sample_chunk(index: u32, chunks: u32, spp: u32) -> Result<Range<u32>, FarmError> {
    let refuse = |reason: String| FarmError::Chunks { chunks, reason };
    if chunks == 0 {
        return Err(refuse("at least one chunk is needed".into()));
    }
    if chunks > spp {
        return Err(refuse(format!(
            "more chunks than the {spp} samples per pixel (--spp) to split"
        )));
    }
    if index >= chunks {
        return Err(refuse(format!("chunk index {index} is not below {chunks}")));
    }
    let bound = |i: u32| (i as u64 * spp as u64 / chunks as u64) as u32;
    Ok(bound(index)..bound(index + 1))
}

/// Where chunk `index` of `chunks` writes when the command line names `path`: `shot.exr` becomes
/// `shot.chunk03.exr`, the index zero-padded to the width of `chunks - 1`, so that every task of one command
/// line writes its own file and a shell glob lists them in order.
pub fn chunk_output_path(path: &Path, index: u32, chunks: u32) -> PathBuf {
    let digits = chunks.saturating_sub(1).max(1).to_string().len();
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let name = match path.extension() {
        Some(ext) => format!("{stem}.chunk{index:0digits$}.{}", ext.to_string_lossy()),
        None => format!("{stem}.chunk{index:0digits$}"),
    };
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn chunks_cover_every_sample_once_and_differ_by_at_most_one() {
        for spp in 1..40 {
            for chunks in 1..=spp {
                let ranges: Vec<_> = (0..chunks)
                    .map(|i| sample_chunk(i, chunks, spp).unwrap())
                    .collect();
                assert_eq!(ranges[0].start, 0);
                assert_eq!(ranges.last().unwrap().end, spp);
                for w in ranges.windows(2) {
                    assert_eq!(w[0].end, w[1].start);
                }
                let lens: Vec<_> = ranges.iter().map(|r| r.len()).collect();
                let (min, max) = (lens.iter().min().unwrap(), lens.iter().max().unwrap());
                assert!(
                    *min >= 1 && max - min <= 1,
                    "{spp} spp / {chunks}: {lens:?}"
                );
            }
        }
        assert_eq!(sample_chunk(3, 4, u32::MAX).unwrap().end, u32::MAX);
    }

    #[test]
    fn impossible_chunks_are_refused() {
        assert!(sample_chunk(0, 0, 8)
            .unwrap_err()
            .to_string()
            .contains("--chunks 0"));
        let err = sample_chunk(0, 9, 8).unwrap_err().to_string();
        assert!(
            err.contains("--chunks 9") && err.contains("8 samples"),
            "{err}"
        );
        assert!(sample_chunk(4, 4, 8).is_err());
    }

    #[test]
    fn task_index_is_read_in_order_and_checked() {
        let t = task_index(env(&[("SLURM_ARRAY_TASK_ID", "2")]), 4).unwrap();
        assert_eq!((t.index, t.variable), (2, "SLURM_ARRAY_TASK_ID"));
        let t = task_index(env(&[("JOB_COMPLETION_INDEX", "3")]), 4).unwrap();
        assert_eq!((t.index, t.variable), (3, "JOB_COMPLETION_INDEX"));
        let both = [("SLURM_ARRAY_TASK_ID", "2"), ("NIMBUS_TASK_INDEX", "1")];
        assert_eq!(task_index(env(&both), 4).unwrap().index, 1);
        let err = task_index(env(&[]), 4).unwrap_err().to_string();
        assert!(err.contains("SLURM_ARRAY_TASK_ID") && err.contains("JOB_COMPLETION_INDEX"));
        let err = task_index(env(&[("SLURM_ARRAY_TASK_ID", "4")]), 4)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("SLURM_ARRAY_TASK_ID=4") && err.contains("0 to 3"),
            "{err}"
        );
        let err = task_index(env(&[("JOB_COMPLETION_INDEX", "x")]), 4)
            .unwrap_err()
            .to_string();
        assert!(err.contains("JOB_COMPLETION_INDEX='x'"), "{err}");
    }

    #[test]
    fn chunk_paths_are_distinct_and_sort_in_order() {
        let p = Path::new("out/shot.exr");
        assert_eq!(chunk_output_path(p, 3, 4), Path::new("out/shot.chunk3.exr"));
        assert_eq!(
            chunk_output_path(p, 3, 16),
            Path::new("out/shot.chunk03.exr")
        );
        assert_eq!(chunk_output_path(p, 0, 1), Path::new("out/shot.chunk0.exr"));
        assert_eq!(
            chunk_output_path(Path::new("part"), 7, 100),
            Path::new("part.chunk07")
        );
        let names: Vec<_> = (0..12).map(|i| chunk_output_path(p, i, 12)).collect();
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(names, sorted);
    }
}
