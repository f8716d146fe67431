//! Frames of a shot: frame ranges (`--frames A..B[:STEP]`) and the frame-number patterns in file names that
//! sequences use, both for outputs (`-o shot.####.exr`) and for VDB sequences (`smoke.$F4.vdb`).
//!
//! Three pattern spellings are understood, as the tools that write sequences spell them:
//! - a run of `#` (Houdini, Nuke): `####` is the frame zero-padded to 4 digits;
//! - `$F` followed by an optional width digit (Houdini): `$F4` pads to 4, `$F` does not pad;
//! - printf's `%d` or `%0Nd` (Blender, ffmpeg): `%04d` pads to 4.
//!
//! A negative frame keeps its sign inside the width (`-001` for frame −1 at width 4), as Rust's `{:04}` does.

use std::fmt;

/// Frames per second of a shot when neither the command line nor the scene says (film's 24).
pub const DEFAULT_FPS: f64 = 24.0;

/// An inclusive range of frames with a step: `first`, `first + step`, … up to `last`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    /// The first frame.
    pub first: i64,
    /// The last frame (included when the step lands on it).
    pub last: i64,
    /// The step between frames, at least 1.
    pub step: i64,
}

/// The most frames one range may hold: a shot of a day at 24 fps is about 2 million frames, far beyond.
const MAX_FRAMES: i64 = 1 << 20;

/// Why a `--frames` value is not a frame range.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameRangeError {
    /// Not of the form `A..B[:STEP]`.
    #[error("'{0}' is not a frame range A..B[:STEP]")]
    NotARange(String),
    /// An end that is not a whole number.
    #[error("frame '{text}': {source}")]
    BadFrame {
        /// The end as given.
        text: String,
        /// Why it does not parse.
        source: std::num::ParseIntError,
    },
    /// A step that is not a whole number.
    #[error("step '{text}': {source}")]
    BadStep {
        /// The step as given.
        text: String,
        /// Why it does not parse.
        source: std::num::ParseIntError,
    },
    /// A step below 1.
    #[error("the step of '{0}' must be at least 1")]
    StepBelowOne(String),
    /// The first frame follows the last.
    #[error("'{0}' runs backwards: the first frame must not follow the last")]
    Backwards(String),
    /// More frames than one range may hold.
    #[error("'{text}' holds {frames} frames; at most {MAX_FRAMES} in one range")]
    TooMany {
        /// The range as given.
        text: String,
        /// How many frames it holds.
        frames: u64,
    },
}

/// Why a `--shutter` value is not a shutter interval.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShutterError {
    /// Not of the form `OPEN,CLOSE`.
    #[error("'{0}' is not a shutter OPEN,CLOSE (in frames, e.g. -0.25,0.25)")]
    NotAShutter(String),
    /// A time that is not a number.
    #[error("shutter time '{text}': {source}")]
    BadTime {
        /// The time as given.
        text: String,
        /// Why it does not parse.
        source: std::num::ParseFloatError,
    },
    /// A time that is not finite or lies beyond ±16 frames.
    #[error("shutter time '{0}' must be finite and within +/-{MAX_SHUTTER_FRAMES} frames")]
    OutOfRange(String),
    /// The shutter opens after it closes.
    #[error("the shutter opens at {open} after it closes at {close}")]
    Reversed {
        /// When it opens.
        open: f32,
        /// When it closes.
        close: f32,
    },
}

impl FrameRange {
    /// A single frame.
    pub fn single(frame: i64) -> Self {
        Self {
            first: frame,
            last: frame,
            step: 1,
        }
    }

    /// Parses `A..B` or `A..B:STEP` (both ends included, STEP ≥ 1; A ≤ B).
    pub fn parse(text: &str) -> Result<Self, FrameRangeError> {
        let (range, step) = match text.split_once(':') {
            Some((r, s)) => (
                r,
                s.trim()
                    .parse::<i64>()
                    .map_err(|source| FrameRangeError::BadStep {
                        text: s.to_owned(),
                        source,
                    })?,
            ),
            None => (text, 1),
        };
        let (a, b) = range
            .split_once("..")
            .ok_or_else(|| FrameRangeError::NotARange(text.to_owned()))?;
        let parse = |s: &str| {
            s.trim()
                .parse::<i64>()
                .map_err(|source| FrameRangeError::BadFrame {
                    text: s.to_owned(),
                    source,
                })
        };
        let (first, last) = (parse(a)?, parse(b)?);
        if step < 1 {
            return Err(FrameRangeError::StepBelowOne(text.to_owned()));
        }
        if first > last {
            return Err(FrameRangeError::Backwards(text.to_owned()));
        }
        let range = Self { first, last, step };
        if range.len() > MAX_FRAMES as u64 {
            return Err(FrameRangeError::TooMany {
                text: text.to_owned(),
                frames: range.len(),
            });
        }
        Ok(range)
    }

    /// The number of frames.
    pub fn len(&self) -> u64 {
        ((self.last as i128 - self.first as i128) / self.step as i128 + 1) as u64
    }

    /// True when the range holds no frame (never, for a parsed range).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The frames in order.
    pub fn frames(&self) -> impl Iterator<Item = i64> {
        let Self { first, step, .. } = *self;
        (0..self.len() as i64).map(move |i| first + i * step)
    }
}

impl fmt::Display for FrameRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..{}", self.first, self.last)?;
        if self.step != 1 {
            write!(f, ":{}", self.step)?;
        }
        Ok(())
    }
}

/// The shutter interval of motion blur (`--shutter OPEN,CLOSE`), in frames relative to the frame being rendered:
/// `-0.25,0.25` keeps the shutter open for half a frame centred on it (a 180° shutter). Camera rays sample
/// their time uniformly in it (a box shutter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shutter {
    /// When the shutter opens, in frames from the frame.
    pub open: f32,
    /// When the shutter closes, in frames from the frame; at least `open`.
    pub close: f32,
}

/// The widest shutter accepted, in frames either side of the frame.
const MAX_SHUTTER_FRAMES: f32 = 16.0;

impl Shutter {
    /// Parses `OPEN,CLOSE` (frames, finite, OPEN ≤ CLOSE, each within ±16 frames).
    pub fn parse(text: &str) -> Result<Self, ShutterError> {
        let (a, b) = text
            .split_once(',')
            .ok_or_else(|| ShutterError::NotAShutter(text.to_owned()))?;
        let parse = |s: &str| {
            let v = s
                .trim()
                .parse::<f32>()
                .map_err(|source| ShutterError::BadTime {
                    text: s.to_owned(),
                    source,
                })?;
            if v.is_finite() && v.abs() <= MAX_SHUTTER_FRAMES {
                Ok(v)
            } else {
                Err(ShutterError::OutOfRange(s.to_owned()))
            }
        };
        let (open, close) = (parse(a)?, parse(b)?);
        if open > close {
            return Err(ShutterError::Reversed { open, close });
        }
        Ok(Self { open, close })
    }

    /// The time (frames from the frame) at fraction `u` ∈ [0, 1) of the interval.
    pub fn time_at(&self, u: f32) -> f32 {
        self.open + (self.close - self.open) * u
    }

    /// The instants at which moving things are sampled: `steps` (≥ 2) times evenly spaced from open to close.
    pub fn sample_times(&self, steps: usize) -> Vec<f32> {
        let steps = steps.max(2);
        (0..steps)
            .map(|i| self.time_at(i as f32 / (steps - 1) as f32))
            .collect()
    }
}

impl fmt::Display for Shutter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{}", self.open, self.close)
    }
}

/// Where a frame-number token sits in a file name, and how wide it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Token {
    start: usize,
    end: usize,
    width: usize,
}

/// The last frame-number token in `text` (the file name's, when a folder name also holds one), if any.
fn find_token(text: &str) -> Option<Token> {
    let bytes = text.as_bytes();
    let mut found = None;
    let mut i = 0;
    while i < bytes.len() {
        let token = match bytes[i] {
            b'#' => {
                let end = i + bytes[i..].iter().take_while(|&&b| b == b'#').count();
                Some(Token {
                    start: i,
                    end,
                    width: end - i,
                })
            }
            b'$' if bytes.get(i + 1) == Some(&b'F') => {
                match bytes.get(i + 2).filter(|b| b.is_ascii_digit()) {
                    Some(d) => Some(Token {
                        start: i,
                        end: i + 3,
                        width: (d - b'0') as usize,
                    }),
                    None => Some(Token {
                        start: i,
                        end: i + 2,
                        width: 1,
                    }),
                }
            }
            b'%' => {
                let digits = bytes[i + 1..]
                    .iter()
                    .take_while(|b| b.is_ascii_digit())
                    .count();
                let d_at = i + 1 + digits;
                (bytes.get(d_at) == Some(&b'd')).then(|| {
                    let spec = &text[i + 1..d_at];
                    Token {
                        start: i,
                        end: d_at + 1,
                        width: spec.parse::<usize>().unwrap_or(1).clamp(1, 32),
                    }
                })
            }
            _ => None,
        };
        match token {
            Some(t) => {
                i = t.end;
                found = Some(t);
            }
            None => i += 1,
        }
    }
    found
}

/// True when `text` holds a frame-number token (`####`, `$F4`, `%04d`).
pub fn has_frame_token(text: &str) -> bool {
    find_token(text).is_some()
}

/// `text` with its (last) frame-number token replaced by `frame`, or `None` when it has no token.
pub fn with_frame(text: &str, frame: i64) -> Option<String> {
    let t = find_token(text)?;
    Some(format!(
        "{}{:0width$}{}",
        &text[..t.start],
        frame,
        &text[t.end..],
        width = t.width
    ))
}

/// The frame number a file name matching `pattern` holds (`smoke.0012.vdb` for `smoke.####.vdb` gives 12), or
/// `None` when it does not match. Any number of digits matches, so unpadded and over-wide frames are found.
pub(crate) fn frame_of(pattern: &str, name: &str) -> Option<i64> {
    let t = find_token(pattern)?;
    let (prefix, suffix) = (&pattern[..t.start], &pattern[t.end..]);
    let middle = name.strip_prefix(prefix)?.strip_suffix(suffix)?;
    let digits = middle.strip_prefix('-').unwrap_or(middle);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    middle.parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_inclusive_with_steps() {
        let r = FrameRange::parse("1..24").unwrap();
        assert_eq!(r.len(), 24);
        assert_eq!(r.frames().last(), Some(24));
        let r = FrameRange::parse("1..10:4").unwrap();
        assert_eq!(r.frames().collect::<Vec<_>>(), [1, 5, 9]);
        assert_eq!(FrameRange::parse("-2..-1").unwrap().len(), 2);
        assert_eq!(FrameRange::parse("7..7").unwrap(), FrameRange::single(7));
        assert_eq!(FrameRange::parse("1..10:4").unwrap().to_string(), "1..10:4");
        for bad in ["1-24", "5..1", "1..2:0", "a..b", "1..2:x", "0..9999999999"] {
            assert!(FrameRange::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn every_spelling_of_the_token_is_replaced() {
        assert_eq!(with_frame("shot.####.exr", 7).unwrap(), "shot.0007.exr");
        assert_eq!(with_frame("shot.#.exr", 12).unwrap(), "shot.12.exr");
        assert_eq!(with_frame("smoke.$F4.vdb", 3).unwrap(), "smoke.0003.vdb");
        assert_eq!(with_frame("smoke.$F.vdb", 3).unwrap(), "smoke.3.vdb");
        assert_eq!(with_frame("smoke.%04d.vdb", 42).unwrap(), "smoke.0042.vdb");
        assert_eq!(with_frame("smoke.%d.vdb", 42).unwrap(), "smoke.42.vdb");
        assert_eq!(with_frame("smoke.####.vdb", -1).unwrap(), "smoke.-001.vdb");
        assert_eq!(
            with_frame("v1/smoke.####.vdb", 5).unwrap(),
            "v1/smoke.0005.vdb"
        );
        assert_eq!(with_frame("plain.vdb", 5), None);
        assert_eq!(with_frame("100%.exr", 5), None);
        assert_eq!(with_frame("price$5.exr", 5), None);
    }

    #[test]
    fn parse_errors_say_what_is_wrong() {
        assert_eq!(
            FrameRange::parse("5..1"),
            Err(FrameRangeError::Backwards("5..1".into()))
        );
        assert_eq!(
            FrameRange::parse("1..5:0"),
            Err(FrameRangeError::StepBelowOne("1..5:0".into()))
        );
        assert!(matches!(
            FrameRange::parse("1..x"),
            Err(FrameRangeError::BadFrame { text, .. }) if text == "x"
        ));
        assert_eq!(
            Shutter::parse("0.5,0"),
            Err(ShutterError::Reversed {
                open: 0.5,
                close: 0.0
            })
        );
        assert_eq!(
            Shutter::parse("0,17").unwrap_err().to_string(),
            "shutter time '17' must be finite and within +/-16 frames"
        );
    }

    #[test]
    fn frame_numbers_are_read_back_from_names() {
        assert_eq!(frame_of("smoke.####.vdb", "smoke.0012.vdb"), Some(12));
        assert_eq!(frame_of("smoke.$F4.vdb", "smoke.12345.vdb"), Some(12345));
        assert_eq!(frame_of("smoke.%04d.vdb", "smoke.-003.vdb"), Some(-3));
        assert_eq!(frame_of("smoke.####.vdb", "smoke.00a2.vdb"), None);
        assert_eq!(frame_of("smoke.####.vdb", "fire.0012.vdb"), None);
        assert_eq!(frame_of("smoke.####.vdb", "smoke..vdb"), None);
    }

    #[test]
    fn shutters_parse_and_spread_their_samples() {
        let s = Shutter::parse("-0.25, 0.25").unwrap();
        assert_eq!((s.open, s.close), (-0.25, 0.25));
        assert_eq!(s.sample_times(3), vec![-0.25, 0.0, 0.25]);
        assert_eq!(s.time_at(0.5), 0.0);
        assert_eq!(
            Shutter::parse("0,0").unwrap().sample_times(2),
            vec![0.0, 0.0]
        );
        for bad in ["0.25", "0.5,-0.5", "nan,1", "0,inf", "-20,0", "a,b"] {
            assert!(Shutter::parse(bad).is_err(), "{bad}");
        }
    }
}
