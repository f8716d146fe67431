//! Fuzz target: the farm part reader, as `nimbus merge` and `nimbus render --resume` use it, on hostile EXR
//! files. The input is written as a file and read as a part's header (`read_part_info`), as a whole part with
//! its exact sums (`read_part`, which checks them against its image), as a checkpoint (`read_checkpoint`) and as
//! a merge of itself with itself (refused as overlapping) and alone; a part that reads is then added twice into
//! a film of the whole frame (sums that would wrap are refused) and made into an image. Nothing may panic,
//! abort, or allocate without bound (the EXR reader is bounded by the file's size).
//!
//! Run with `cargo +nightly fuzz run farm_part` from `fuzz/` (seed it with parts and checkpoints that
//! `nimbus render --samples/--crop/--checkpoint` wrote; see docs/fuzzing.md).

#![no_main]

#[path = "../farm_part_check.rs"]
mod check;
#[path = "../scratch.rs"]
mod scratch;

libfuzzer_sys::fuzz_target!(|data: &[u8]| check::run(data, scratch::folder()));
