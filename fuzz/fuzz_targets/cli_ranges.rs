//! Fuzz target: the command line's parsers of ranges and sizes. The first byte picks the parser: `--frames`
//! (`nimbus::frames::FrameRange::parse`), `--shutter` (`Shutter::parse`), `--crop` (`nimbus::farm::parse_crop`),
//! `--samples` (`nimbus::farm::parse_samples`) or `--memory-limit` (`nimbus::limits::parse_size`); the rest is
//! the flag's value. Nothing may panic (overflow checks are on), and what parses must hold its invariants: a
//! frame range of at least one frame whose frames the iterator gives, and which prints back to itself; a finite
//! shutter with open <= close; a non-empty crop that prints back to itself; a non-empty sample range.
//!
//! Run with `cargo +nightly fuzz run cli_ranges` from `fuzz/`.

#![no_main]

#[path = "../cli_ranges_check.rs"]
mod check;

libfuzzer_sys::fuzz_target!(|data: &[u8]| check::run(data));
