//! Fuzz target: any byte string as an `.obj` file (with a fixed `.mtl` library beside it) must make the OBJ
//! loader return `Ok` or `Err`, never panic or abort; a scene that loads must build.
//!
//! Run with `cargo +nightly fuzz run obj_load` from the repository root (seed it with small `.obj` files).

#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../scratch.rs"]
mod scratch;

/// The scratch folder, holding the library `m.mtl` that every input names.
fn folder() -> &'static std::path::Path {
    static MTL: std::sync::Once = std::sync::Once::new();
    MTL.call_once(|| {
        std::fs::write(
            scratch::folder().join("m.mtl"),
            "newmtl a\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\nNs 20\nnewmtl lamp\nKe 2 2 2\n",
        )
        .unwrap();
    });
    scratch::folder()
}

fuzz_target!(|data: &[u8]| {
    let path = folder().join("fuzz.obj");
    std::fs::write(&path, data).unwrap();
    if let Ok(builder) = nimbus::scene::load_builder(&path, &Default::default()) {
        let _ = builder.build();
    }
});
