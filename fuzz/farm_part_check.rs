//! The body of the `farm_part` fuzz target, shared with its replay in `tests/suite/fuzz_regressions.rs` so that a saved
//! input is checked the same way in both.

use nimbus::render::{Film, PixelWindow};
use std::path::Path;

/// Runs one input (see `fuzz_targets/farm_part.rs`), written as a file in the folder `dir`.
pub fn run(data: &[u8], dir: &Path) {
    let path = &dir.join("part.exr");
    std::fs::write(path, data).unwrap();
    let _ = nimbus::farm::read_part_info(path);
    let _ = nimbus::farm::checkpoint::read_checkpoint(path);
    let _ = nimbus::farm::merge_parts(std::slice::from_ref(path));
    let _ = nimbus::farm::merge_parts(&[path.clone(), path.clone()]);
    if let Ok((info, film)) = nimbus::farm::read_part(path) {
        if info.width * info.height <= 1 << 20 {
            let mut whole = Film::with_plan(
                info.width,
                info.height,
                PixelWindow::full(info.width, info.height),
                std::sync::Arc::new(info.plan.clone()),
            );
            if whole.merge(&film).is_ok() {
                let _ = whole.merge(&film);
            }
            let _ = whole.image();
        }
    }
}
