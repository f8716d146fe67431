//! Fuzz target: any byte string as a USD layer must make the USD loader return `Ok` or `Err`, never panic or
//! abort (its reader's own panics are caught and returned as errors). The first byte picks the extension
//! (`.usda`, `.usdc` or `.usdz`), the rest is the file; a scene that loads must build.
//!
//! Run with `cargo +nightly fuzz run usd_load` from the repository root (seed it with small USD files, each
//! prefixed with 0, 1 or 2 for its encoding).

#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../scratch.rs"]
mod scratch;
use scratch::folder;

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
