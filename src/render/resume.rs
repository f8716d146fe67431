//! Where a render of a region stands, so that a stopped render can be written as a checkpoint and continued
//! with the same samples it would have taken: the image of a resumed render is the uninterrupted one, bit for
//! bit, because sample `s` of pixel `i` is the same whenever it is taken and the film sums exactly.
//!
//! The renderer takes passes of samples over the window, row by row in parallel, checking for cancellation
//! before each pixel. A pass that is cancelled therefore leaves each row with a prefix of its pixels holding
//! the pass's samples and the rest holding none: [`RegionProgress`] records the samples every pixel holds and,
//! for a pass that stopped part way, that prefix per row.

use super::film::Film;
use std::ops::Range;

/// The samples a film of a region holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RegionProgress {
    /// Every pixel of the window holds the samples `region.samples.start..complete`.
    pub complete: u32,
    /// A pass that stopped part way, if any.
    pub stopped_pass: Option<StoppedPass>,
}

/// A pass cancelled part way: its samples `RegionProgress::complete..end` are in the first `row_pixels[r]`
/// pixels of each row `r` of the window, and in no other pixel.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StoppedPass {
    /// One past the pass's last sample.
    pub end: u32,
    /// For each row of the window, from the top, how many of its pixels (from the left) took the pass.
    pub row_pixels: Vec<u32>,
}

impl RegionProgress {
    /// Nothing rendered yet of samples starting at `start`.
    pub fn start(start: u32) -> Self {
        Self {
            complete: start,
            stopped_pass: None,
        }
    }

    /// The most samples any pixel holds, counted from `start`.
    pub fn most_samples(&self, start: u32) -> u32 {
        self.stopped_pass.as_ref().map_or(self.complete, |p| p.end) - start
    }

    /// The samples pixel (`column`, `row`) of the window holds (`column` and `row` from the window's corner).
    pub fn samples_of(&self, start: u32, column: usize, row: usize) -> Range<u32> {
        match &self.stopped_pass {
            Some(pass) if (pass.row_pixels.get(row).copied().unwrap_or(0) as usize) > column => {
                start..pass.end
            }
            _ => start..self.complete,
        }
    }

    /// True when no pixel holds a sample.
    pub fn is_empty(&self, start: u32) -> bool {
        self.most_samples(start) == 0
            && self
                .stopped_pass
                .as_ref()
                .is_none_or(|p| p.row_pixels.iter().all(|&n| n == 0))
    }

    /// Checks that this progress can describe `film`: a stopped pass has one entry per row of the window, no
    /// more pixels than the window's width, and ends after `complete`.
    pub fn fits(&self, film: &Film, samples: &Range<u32>) -> Result<(), ProgressMismatch> {
        let window = film.window();
        if self.complete < samples.start || self.complete > samples.end {
            return Err(ProgressMismatch::Complete {
                complete: self.complete,
                samples: samples.clone(),
            });
        }
        if let Some(pass) = &self.stopped_pass {
            if pass.end <= self.complete || pass.end > samples.end {
                return Err(ProgressMismatch::PassEnd {
                    end: pass.end,
                    first: self.complete + 1,
                    last: samples.end,
                });
            }
            if pass.row_pixels.len() != window.height() {
                return Err(ProgressMismatch::Rows {
                    rows: pass.row_pixels.len(),
                    height: window.height(),
                });
            }
            if let Some(r) = pass
                .row_pixels
                .iter()
                .position(|&n| n as usize > window.width())
            {
                return Err(ProgressMismatch::RowPixels {
                    row: r,
                    pixels: pass.row_pixels[r],
                    width: window.width(),
                });
            }
        }
        Ok(())
    }
}

/// Why a [`RegionProgress`] cannot describe a film ([`RegionProgress::fits`]).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ProgressMismatch {
    /// The complete samples end outside the sample range.
    #[error("complete samples end at {complete}, outside {}..{}", samples.start, samples.end)]
    Complete {
        /// Where the complete samples end.
        complete: u32,
        /// The sample range.
        samples: Range<u32>,
    },
    /// The stopped pass ends at or before the complete samples, or past the range.
    #[error("the stopped pass ends at sample {end}, not within {first}..{last}")]
    PassEnd {
        /// Where the stopped pass ends.
        end: u32,
        /// The first end it could have (one past the complete samples).
        first: u32,
        /// The range's end.
        last: u32,
    },
    /// The stopped pass lists another number of rows than the window has.
    #[error("the stopped pass lists {rows} rows, the window has {height}")]
    Rows {
        /// The rows listed.
        rows: usize,
        /// The window's height.
        height: usize,
    },
    /// A row of the stopped pass lists more pixels than the window is wide.
    #[error("row {row} of the stopped pass lists {pixels} pixels, the window is {width} wide")]
    RowPixels {
        /// The row, from the window's top.
        row: usize,
        /// The pixels it lists.
        pixels: u32,
        /// The window's width.
        width: usize,
    },
}

/// Where a render starts: the film a checkpoint held and how far it got, and its dropped and clamped samples.
pub struct ResumeFrom {
    /// The film so far (of the region's window, with the render's layer plan).
    pub film: Film,
    /// The samples it holds.
    pub progress: RegionProgress,
    /// Samples dropped as NaN or infinite so far.
    pub nan_samples: u64,
    /// Samples clamped so far.
    pub clamped_samples: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stopped_pass_gives_its_samples_to_the_prefix_of_each_row() {
        let progress = RegionProgress {
            complete: 8,
            stopped_pass: Some(StoppedPass {
                end: 12,
                row_pixels: vec![3, 0],
            }),
        };
        assert_eq!(progress.samples_of(4, 2, 0), 4..12);
        assert_eq!(progress.samples_of(4, 3, 0), 4..8);
        assert_eq!(progress.samples_of(4, 0, 1), 4..8);
        assert_eq!(progress.most_samples(4), 8);
        assert!(!progress.is_empty(4));
        assert!(RegionProgress::start(4).is_empty(4));
        let film = Film::new(4, 2);
        assert!(progress.fits(&film, &(4..16)).is_ok());
        assert!(progress.fits(&film, &(4..10)).is_err());
        let wide = RegionProgress {
            stopped_pass: Some(StoppedPass {
                end: 12,
                row_pixels: vec![5, 0],
            }),
            ..progress
        };
        assert!(wide.fits(&film, &(4..16)).is_err());
    }
}
