//! Fuzz target: USD composition. The input describes a few small text layers (sublayers, references,
//! payloads, inherits and specializes between prims of a few shared names, so that cycles, fan-out and
//! sublayer diamonds come easily; see `../compose_stage.rs`); the root must load or be refused with an error,
//! never panic, overflow its stack, abort or hang, and a scene that loads must build.
//!
//! Run with `cargo +nightly fuzz run usd_compose` from `fuzz/` (no seeds needed: every byte string is a stage).

#![no_main]

#[path = "../compose_stage.rs"]
mod compose_stage;

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
        let dir = base.join(format!("nimbus_fuzz_compose_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    compose_stage::load(data, folder());
});
