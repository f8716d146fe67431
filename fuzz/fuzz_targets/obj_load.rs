//! Fuzz target: any byte string as an `.obj` file (with a fixed `.mtl` library beside it) must make the OBJ
//! loader return `Ok` or `Err`, never panic or abort; a scene that loads must build.
//!
//! Run with `cargo +nightly fuzz run obj_load` from the repository root (seed it with small `.obj` files).

#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

/// A folder of this process's own, in memory where `/dev/shm` exists, holding `m.mtl`.
fn folder() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = std::path::Path::new("/dev/shm");
        let base = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("nimbus_fuzz_obj_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(
            dir.join("m.mtl"),
            "newmtl a\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\nNs 20\nnewmtl lamp\nKe 2 2 2\n",
        )
        .unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let path = folder().join("fuzz.obj");
    std::fs::write(&path, data).unwrap();
    if let Ok(builder) = nimbus::scene::load_builder(&path, &Default::default()) {
        let _ = builder.build();
    }
});
