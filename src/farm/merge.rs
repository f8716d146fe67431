//! `nimbus merge`: checks that parts belong together and cover every sample of every pixel once, then adds
//! their exact sums and takes the image of the total, exactly as a single render does.

use super::part::{read_part, read_part_info, PartInfo};
use super::FarmError;
use crate::render::{Film, FilmMergeError, PixelWindow, RenderImage};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The result of a merge.
#[derive(Clone, Debug, PartialEq)]
pub struct Merged {
    /// The image: bit for bit the single render's.
    pub image: RenderImage,
    /// Samples per pixel of the whole.
    pub spp: u32,
    /// Number of parts merged.
    pub parts: usize,
    /// Samples dropped as NaN or infinite over all parts.
    pub nan_samples: u64,
    /// Samples clamped into the film's range over all parts.
    pub clamped_samples: u64,
}

/// Merges the parts at `paths` (in any order): reads their headers, refuses parts that do not belong
/// together or do not cover every sample of every pixel once (`check_parts`), then reads and adds their
/// sums.
pub fn merge_parts(paths: &[PathBuf]) -> Result<Merged, FarmError> {
    let infos = paths
        .iter()
        .map(|p| Ok((p.clone(), read_part_info(p)?)))
        .collect::<Result<Vec<_>, FarmError>>()?;
    check_parts(&infos)?;
    let (first_path, first) = &infos[0];
    // The frame comes from a header: its film is checked against the memory budget before it is allocated.
    let film_bytes =
        std::mem::size_of::<crate::render::PixelSums>() + first.plan.film_bytes_per_pixel();
    crate::limits::Limits::default()
        .check_items(
            format_args!("the merged film of {}x{} pixels", first.width, first.height),
            first.width as u64 * first.height as u64,
            film_bytes as u64,
        )
        .map_err(|e| FarmError::Invalid {
            path: first_path.clone(),
            reason: e.to_string(),
        })?;
    let mut film = Film::with_plan(
        first.width,
        first.height,
        PixelWindow::full(first.width, first.height),
        std::sync::Arc::new(first.plan.clone()),
    );
    let (mut nan_samples, mut clamped_samples) = (0u64, 0u64);
    for (path, header) in &infos {
        let invalid = |reason: String| FarmError::Invalid {
            path: path.clone(),
            reason,
        };
        let (info, part) = read_part(path)?;
        if info != *header {
            return Err(invalid("the file changed while it was merged".into()));
        }
        match film.merge(&part) {
            Ok(()) => {}
            Err(FilmMergeError::DoesNotFit) => {
                return Err(invalid("the file changed while it was merged".into()))
            }
            Err(FilmMergeError::Overflow { x, y }) => {
                return Err(invalid(format!(
                "pixel ({x}, {y}): its sums overflow when added to the parts before it, more than \
                     any samples could give (a damaged or forged part)"
            )))
            }
        }
        // Each part's counts are at most its pixel-samples (checked when read), and disjoint parts hold at
        // most the frame's, so these sums cannot wrap.
        nan_samples += info.nan_samples;
        clamped_samples += info.clamped_samples;
    }
    let mut image = film.image();
    image.metadata = merged_metadata(&infos);
    Ok(Merged {
        image,
        spp: first.spp,
        parts: infos.len(),
        nan_samples,
        clamped_samples,
    })
}

/// The header attributes of the merged image: the first part's, with `render_seconds` the sum of every part's
/// (when every part has one).
fn merged_metadata(parts: &[(PathBuf, PartInfo)]) -> crate::render::ImageMetadata {
    let mut metadata = parts[0].1.metadata.clone();
    let seconds: Option<f64> = parts
        .iter()
        .map(|(_, p)| p.metadata.nimbus.get("render_seconds")?.parse::<f64>().ok())
        .sum();
    match seconds {
        Some(s) => metadata
            .nimbus
            .insert("render_seconds".into(), format!("{s:.3}")),
        None => metadata.nimbus.remove("render_seconds"),
    };
    metadata
}

/// Checks that `parts` (file and header) can merge: one render (same resolution, seed, max depth, samples
/// per pixel, scene hash and Nimbus version), no sample of a pixel in two parts, and none in no part.
pub fn check_parts(parts: &[(PathBuf, PartInfo)]) -> Result<(), FarmError> {
    let Some((first_path, first)) = parts.first() else {
        return Err(FarmError::NoParts);
    };
    if let Some((path, _)) = parts.iter().find(|(_, p)| p.progress.is_some()) {
        return Err(FarmError::Invalid {
            path: path.clone(),
            reason: "a checkpoint of an unfinished render, not a part: finish it with nimbus render --resume".into(),
        });
    }
    for (path, info) in &parts[1..] {
        check_same(first_path, first, path, info)?;
    }
    for (i, (a_path, a)) in parts.iter().enumerate() {
        for (b_path, b) in &parts[i + 1..] {
            if a.window.overlaps(&b.window) && overlap(&a.samples, &b.samples).is_some() {
                return Err(FarmError::Overlap {
                    first: a_path.clone(),
                    other: b_path.clone(),
                    samples: overlap(&a.samples, &b.samples).unwrap_or(0..0),
                    window: intersection(&a.window, &b.window),
                });
            }
        }
    }
    // Disjoint parts cover everything exactly when their pixel-samples add up to the whole.
    let volume: u128 = parts
        .iter()
        .map(|(_, p)| p.window.pixel_count() as u128 * p.samples.len() as u128)
        .sum();
    if volume != first.width as u128 * first.height as u128 * first.spp as u128 {
        return Err(find_gap(parts));
    }
    Ok(())
}

/// Refuses `b` when it comes from another render than `a`.
fn check_same(a_path: &Path, a: &PartInfo, b_path: &Path, b: &PartInfo) -> Result<(), FarmError> {
    let layers = |p: &PartInfo| {
        let kinds: Vec<&str> = p
            .plan
            .cryptomatte
            .iter()
            .map(|(k, _)| k.layer_name())
            .collect();
        format!("{} cryptomatte={}", p.plan.describe(), kinds.join(","))
    };
    if a.plan != b.plan && layers(a) == layers(b) {
        return Err(FarmError::Mismatch {
            first: a_path.to_path_buf(),
            other: b_path.to_path_buf(),
            what: "Cryptomatte manifest",
            first_value: "one set of names".into(),
            other_value: "another".into(),
        });
    }
    let fields: [(&'static str, String, String); 8] = [
        (
            "resolution",
            format!("{}x{}", a.width, a.height),
            format!("{}x{}", b.width, b.height),
        ),
        ("seed", a.seed.to_string(), b.seed.to_string()),
        (
            "max depth",
            a.max_depth.to_string(),
            b.max_depth.to_string(),
        ),
        ("samples per pixel", a.spp.to_string(), b.spp.to_string()),
        (
            "scene hash (scene file or settings)",
            format!("{:016x}", a.scene_hash),
            format!("{:016x}", b.scene_hash),
        ),
        ("Nimbus version", a.version.clone(), b.version.clone()),
        (
            "layers (--aovs, --light-groups, --cryptomatte-depth)",
            layers(a),
            layers(b),
        ),
        (
            "media estimators (the majorant structure chosen under each node's --memory-limit)",
            a.estimators.clone(),
            b.estimators.clone(),
        ),
    ];
    match fields.into_iter().find(|(_, x, y)| x != y) {
        Some((what, first_value, other_value)) => Err(FarmError::Mismatch {
            first: a_path.to_path_buf(),
            other: b_path.to_path_buf(),
            what,
            first_value,
            other_value,
        }),
        None => Ok(()),
    }
}

/// The samples two ranges share, if any.
fn overlap(a: &Range<u32>, b: &Range<u32>) -> Option<Range<u32>> {
    let r = a.start.max(b.start)..a.end.min(b.end);
    (!r.is_empty()).then_some(r)
}

/// The pixels two overlapping windows share.
fn intersection(a: &PixelWindow, b: &PixelWindow) -> PixelWindow {
    PixelWindow {
        x0: a.x0.max(b.x0),
        y0: a.y0.max(b.y0),
        x1: a.x1.min(b.x1),
        y1: a.y1.min(b.y1),
    }
}

/// The first gap of disjoint parts that do not cover the whole: the frame is cut into cells along every
/// window edge, so that the same parts cover every pixel of a cell, and each cell's sample ranges are
/// walked from 0 to spp.
fn find_gap(parts: &[(PathBuf, PartInfo)]) -> FarmError {
    let first = &parts[0].1;
    let edges = |full: usize, ends: &dyn Fn(&PixelWindow) -> [usize; 2]| {
        let mut e: Vec<usize> = parts.iter().flat_map(|(_, p)| ends(&p.window)).collect();
        e.extend([0, full]);
        e.sort_unstable();
        e.dedup();
        e
    };
    let xs = edges(first.width, &|w| [w.x0, w.x1]);
    let ys = edges(first.height, &|w| [w.y0, w.y1]);
    for y in ys.windows(2) {
        for x in xs.windows(2) {
            let cell = PixelWindow {
                x0: x[0],
                y0: y[0],
                x1: x[1],
                y1: y[1],
            };
            let mut ranges: Vec<&Range<u32>> = parts
                .iter()
                .filter(|(_, p)| p.window.contains(&cell))
                .map(|(_, p)| &p.samples)
                .collect();
            ranges.sort_by_key(|r| r.start);
            let mut next = 0;
            for r in ranges
                .iter()
                .chain(std::iter::once(&&(first.spp..first.spp)))
            {
                if r.start > next {
                    return FarmError::Gap {
                        parts: parts.len(),
                        samples: next..r.start,
                        window: cell,
                    };
                }
                next = next.max(r.end);
            }
        }
    }
    // Unreachable for disjoint parts whose volume falls short; said plainly all the same.
    FarmError::Gap {
        parts: parts.len(),
        samples: 0..first.spp,
        window: PixelWindow::full(first.width, first.height),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(window: [usize; 4], samples: Range<u32>) -> PartInfo {
        PartInfo {
            version: "0".into(),
            scene_hash: 1,
            width: 10,
            height: 6,
            seed: 0,
            max_depth: 8,
            spp: 16,
            samples,
            window: PixelWindow {
                x0: window[0],
                y0: window[1],
                x1: window[2],
                y1: window[3],
            },
            nan_samples: 0,
            clamped_samples: 0,
            plan: crate::render::LayerPlan::default(),
            metadata: crate::render::ImageMetadata::default(),
            estimators: String::new(),
            progress: None,
        }
    }

    fn named(parts: Vec<PartInfo>) -> Vec<(PathBuf, PartInfo)> {
        parts
            .into_iter()
            .enumerate()
            .map(|(i, p)| (PathBuf::from(format!("p{i}.exr")), p))
            .collect()
    }

    #[test]
    fn tiles_times_sample_ranges_pass() {
        let mut parts = Vec::new();
        for (x0, x1) in [(0, 3), (3, 10)] {
            for (y0, y1) in [(0, 5), (5, 6)] {
                for r in [0..7, 7..9, 9..16] {
                    parts.push(part([x0, y0, x1, y1], r));
                }
            }
        }
        check_parts(&named(parts)).unwrap();
        // Different splits in different tiles are fine too.
        let parts = vec![
            part([0, 0, 10, 3], 0..16),
            part([0, 3, 10, 6], 0..1),
            part([0, 3, 4, 6], 1..16),
            part([4, 3, 10, 6], 1..5),
            part([4, 3, 10, 6], 5..16),
        ];
        check_parts(&named(parts)).unwrap();
    }

    #[test]
    fn overlaps_and_gaps_are_found_and_named() {
        let err = check_parts(&named(vec![
            part([0, 0, 10, 6], 0..8),
            part([0, 0, 10, 6], 6..16),
        ]))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "parts p0.exr and p1.exr overlap: both hold samples 6..8 of the pixels in 0,0,10,6"
        );
        let err = check_parts(&named(vec![
            part([0, 0, 10, 6], 0..16),
            part([9, 5, 10, 6], 15..16),
        ]))
        .unwrap_err();
        assert!(err
            .to_string()
            .contains("samples 15..16 of the pixels in 9,5,10,6"));
        let err = check_parts(&named(vec![
            part([0, 0, 10, 6], 0..8),
            part([0, 0, 10, 6], 12..16),
        ]))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "the 2 parts leave samples 8..12 of the pixels in 0,0,10,6 unrendered"
        );
        let err = check_parts(&named(vec![
            part([0, 0, 10, 6], 0..8),
            part([0, 0, 10, 2], 8..16),
            part([0, 2, 7, 6], 8..16),
        ]))
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "the 3 parts leave samples 8..16 of the pixels in 7,2,10,6 unrendered"
        );
        let err = check_parts(&named(vec![part([0, 0, 10, 6], 0..15)])).unwrap_err();
        assert!(err.to_string().contains("samples 15..16"), "{err}");
        assert!(matches!(check_parts(&[]), Err(FarmError::NoParts)));
    }

    #[test]
    fn parts_of_other_renders_are_refused() {
        let base = part([0, 0, 10, 6], 0..8);
        let cases: [(&str, PartInfo); 6] = [
            (
                "resolution 10x6 vs 10x7",
                PartInfo {
                    height: 7,
                    ..base.clone()
                },
            ),
            (
                "seed 0 vs 3",
                PartInfo {
                    seed: 3,
                    ..base.clone()
                },
            ),
            (
                "max depth 8 vs 9",
                PartInfo {
                    max_depth: 9,
                    ..base.clone()
                },
            ),
            (
                "samples per pixel 16 vs 32",
                PartInfo {
                    spp: 32,
                    ..base.clone()
                },
            ),
            (
                "scene hash (scene file or settings) 0000000000000001 vs 0000000000000002",
                PartInfo {
                    scene_hash: 2,
                    ..base.clone()
                },
            ),
            (
                "Nimbus version 0 vs 1",
                PartInfo {
                    version: "1".into(),
                    ..base.clone()
                },
            ),
        ];
        for (message, mut other) in cases {
            other.samples = 8..16;
            let err = check_parts(&named(vec![base.clone(), other])).unwrap_err();
            assert_eq!(
                err.to_string(),
                format!("parts p0.exr and p1.exr do not belong together: {message}")
            );
        }
    }
}
