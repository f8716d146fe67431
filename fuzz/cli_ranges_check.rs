//! The body of the `cli_ranges` fuzz target, shared with its replay in `tests/suite/fuzz_regressions.rs` so that a saved
//! input is checked the same way in both.

/// Runs one input (see `fuzz_targets/cli_ranges.rs`).
pub fn run(data: &[u8]) {
    let Some((&pick, text)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(text) else {
        return;
    };
    match pick % 5 {
        0 => {
            if let Ok(range) = nimbus::frames::FrameRange::parse(text) {
                assert!(!range.is_empty());
                let frames: Vec<i64> = range.frames().take(3).collect();
                assert_eq!(frames.len() as u64, range.len().min(3));
                assert_eq!(frames[0], range.first);
                let again = nimbus::frames::FrameRange::parse(&range.to_string()).unwrap();
                assert_eq!(again.to_string(), range.to_string());
            }
        }
        1 => {
            if let Ok(shutter) = nimbus::frames::Shutter::parse(text) {
                assert!(shutter.open.is_finite() && shutter.close.is_finite());
                assert!(shutter.open <= shutter.close);
            }
        }
        2 => {
            if let Ok(window) = nimbus::farm::parse_crop(text) {
                assert!(window.x0 < window.x1 && window.y0 < window.y1);
                assert!(window.pixel_count() > 0);
                assert_eq!(
                    nimbus::farm::parse_crop(&window.to_string()).unwrap(),
                    window
                );
            }
        }
        3 => {
            if let Ok(samples) = nimbus::farm::parse_samples(text) {
                assert!(samples.start < samples.end);
            }
        }
        _ => {
            let _ = nimbus::limits::parse_size(text);
        }
    }
}
