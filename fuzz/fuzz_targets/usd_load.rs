//! Fuzz target: any byte string as a USD layer must make the USD loader return `Ok` or `Err`, never panic or
//! abort (its reader's own panics are caught and returned as errors). The first byte picks the extension
//! (`.usda`, `.usdc` or `.usdz`), the rest is the file; a scene that loads must build.
//!
//! Run with `cargo +nightly fuzz run usd_load` from the repository root (seed it with small USD files, each
//! prefixed with 0, 1 or 2 for its encoding).

#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

/// A folder of this process's own, in memory where `/dev/shm` exists.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = std::path::Path::new("/dev/shm");
        let base = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("nimbus_fuzz_usd_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let ext = ["usda", "usdc", "usdz"][pick as usize % 3];
    let path = folder().join(format!("fuzz.{ext}"));
    std::fs::write(&path, file).unwrap();
    if let Ok(builder) = nimbus::scene::load_builder(&path, &Default::default()) {
        let _ = builder.build();
    }
});
