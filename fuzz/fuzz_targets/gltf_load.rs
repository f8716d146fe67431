//! Fuzz target: any byte string, read as a `.gltf` or `.glb` file, must make the glTF loader return `Ok` or
//! `Err`, never panic or abort; a scene that loads must also build.
//!
//! Run with `cargo +nightly fuzz run gltf_load` from the repository root (seed it with small `.gltf` and
//! `.glb` files). External URIs resolve in an empty temporary folder.

#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join("nimbus-fuzz-gltf");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("fuzz.gltf");
    let options = nimbus::scene::LoadOptions::default();
    if let Ok(builder) = nimbus::scene::gltf::load_slice(data, &path, &options) {
        let _ = builder.build();
    }
});
