//! Fuzz target: any byte string must make the VDB reader return `Ok` or `Err`, never panic or abort.
//!
//! Run with `cargo +nightly fuzz run vdb_read` from the repository root (seed it with small `.vdb` files).

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(file) = nimbus::vdb::read_bytes(data, std::path::Path::new("fuzz.vdb")) {
        for g in &file.grids {
            let _ = g.tree.stats();
        }
    }
});
