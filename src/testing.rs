//! The crate's internals, for its own integration tests and benches only (feature `testing`; docs/api.md).
//!
//! Without the feature the library's API is what an embedder needs: loading and building scenes, render
//! settings, rendering, images and their layers, output files, farm parts and VDB file information. Its tests and
//! benches also reach inside: tracking estimators, majorant structures, BSDFs, the BVH, loaders' internals. With
//! the feature, the items and modules declared with the crate's `internal!` macro become `pub` instead of
//! `pub(crate)`, at their usual paths (`nimbus::volume::tracking`, `nimbus::geometry::Bvh`, ...).
//!
//! The package's dev-dependency on itself turns the feature on for `cargo test` and `cargo bench`; nothing else
//! should: these items change without notice, and `tests/public_api.rs` does not list them.
