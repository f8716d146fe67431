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

#[path = "../scratch.rs"]
mod scratch;
use scratch::folder;

fuzz_target!(|data: &[u8]| {
    compose_stage::load(data, folder());
});
