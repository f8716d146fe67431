//! Fuzz target: glTF animation and skins. The first byte picks the frame (its low 6 bits) and whether a
//! shutter is open (bit 6); the rest is a `.gltf` or `.glb` file, loaded at that frame, so that every
//! animation channel is read and sampled (across the shutter's motion steps too) and every skin and morph
//! target posed, under a 256 MiB budget; a scene that loads must also build. Nothing may panic, abort or run
//! away.
//!
//! Run with `cargo +nightly fuzz run gltf_animation` from `fuzz/` (seed it with small animated, skinned and
//! morphed files, each prefixed with its byte). External URIs resolve in an empty temporary folder.

#![no_main]

use libfuzzer_sys::fuzz_target;
use nimbus::frames::Shutter;
use nimbus::limits::Limits;
use nimbus::scene::LoadOptions;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let dir = std::env::temp_dir().join("nimbus-fuzz-gltf-animation");
    let _ = std::fs::create_dir_all(&dir);
    let options = LoadOptions {
        limits: Limits::with_memory(256 << 20),
        frame: Some(i64::from(pick & 63)),
        shutter: (pick & 64 != 0).then_some(Shutter {
            open: -0.25,
            close: 0.25,
        }),
        ..Default::default()
    };
    if let Ok(builder) = nimbus::scene::gltf::load_slice(file, &dir.join("fuzz.gltf"), &options) {
        let _ = builder.build();
    }
});
