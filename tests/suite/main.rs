//! Nimbus's integration tests, gathered into one test binary so that the library is linked once, not once per
//! file (issue 35: 41 binaries, each linking the whole library, took most of a cold `cargo test`). Each module is
//! one former `tests/NAME.rs`; run one with `cargo test --test suite NAME::`. `tests/public_api.rs` (a pinned
//! nightly) and `tests/denoise.rs` (the `denoise` feature) stay binaries of their own.

#[path = "../common/mod.rs"]
mod common;
#[path = "../support/hostile.rs"]
mod hostile;

mod bsdf_finite;
mod camera_medium;
mod cameras;
mod checkpoint;
mod cli_flags;
mod compositing;
mod compositing_files;
mod compositing_tags;
mod conformance;
mod converge;
mod cryptomatte;
mod deep;
mod default_camera;
mod emitter_edges;
mod farm;
mod fuzz_regressions;
mod ggx_energy;
mod glass_nan;
mod gltf_alpha;
mod gltf_anisotropy;
mod gltf_geometry;
mod gltf_hostile;
mod gltf_loader;
mod gltf_material_extensions;
mod gltf_materials;
mod gltf_mutations;
mod gltf_variants;
mod grid_media;
mod guiding;
mod hostile_volumes;
mod instancing;
mod motion_blur;
mod obj_loader;
mod obj_materials;
mod obj_mutations;
mod overlapping_media;
mod reliability;
mod render_accuracy;
mod shots;
mod spawn_form_factor;
mod stability;
mod texture_filtering;
mod usd_loader;
mod usd_mutations;
mod usd_scenes;
mod validation;
mod vdb_corpus;
mod vdb_robustness;
mod volume_motion;
mod volume_render;
