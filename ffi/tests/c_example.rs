//! Compiles `examples/render.c` with the system C compiler against the built shared library and runs it on the
//! demo scene at a tiny size.
//!
//! The compiler is `$CC`, else the first of `cc`, `gcc`, `clang` on `PATH`. Without one the test prints a
//! notice and passes, unless `NIMBUS_REQUIRE_CC=1` (CI sets it), when it fails.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The first working C compiler, or `None`.
fn find_c_compiler() -> Option<String> {
    let candidates = std::env::var("CC")
        .ok()
        .into_iter()
        .chain(["cc", "gcc", "clang"].map(String::from));
    candidates.into_iter().find(|cc| {
        Command::new(cc)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

/// The folder holding the shared library built for this test run: `cargo test` leaves it in
/// `<target>/<profile>/deps/`, beside this test's executable (only `cargo build` copies it up a level, so the
/// copy there may be stale or missing).
fn library_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.parent()
        .expect("test executable lies in <target>/<profile>/deps")
        .to_path_buf()
}

#[test]
fn c_example_renders_the_demo_scene() {
    let Some(cc) = find_c_compiler() else {
        assert!(
            std::env::var("NIMBUS_REQUIRE_CC").as_deref() != Ok("1"),
            "no C compiler found ($CC, cc, gcc, clang) and NIMBUS_REQUIRE_CC=1"
        );
        eprintln!("SKIP: no C compiler found ($CC, cc, gcc, clang); set NIMBUS_REQUIRE_CC=1 to fail instead");
        return;
    };
    let ffi = Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib_dir = library_dir();
    let shared = lib_dir.join(format!(
        "{}nimbus_c{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    ));
    assert!(shared.is_file(), "{} was not built", shared.display());

    let work = std::env::temp_dir().join(format!("nimbus-ffi-c-example-{}", std::process::id()));
    std::fs::create_dir_all(&work).unwrap();
    let exe = work.join("render");
    let compile = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"])
        .arg("-I")
        .arg(ffi.join("include"))
        .arg(ffi.join("examples/render.c"))
        .arg("-o")
        .arg(&exe)
        .arg("-L")
        .arg(&lib_dir)
        .args(["-lnimbus_c", "-lm"])
        .output()
        .expect("run the C compiler");
    assert!(
        compile.status.success(),
        "{cc} failed:\n{}",
        String::from_utf8_lossy(&compile.stderr)
    );

    let output = work.join("demo.exr");
    let run = Command::new(&exe)
        .arg(ffi.join("../assets/demo.glb"))
        .args(["16", "12", "2"])
        .arg(&output)
        .env("LD_LIBRARY_PATH", &lib_dir)
        .env("DYLD_LIBRARY_PATH", &lib_dir)
        .output()
        .expect("run the compiled example");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "render.c failed: {stderr}");
    assert!(String::from_utf8_lossy(&run.stdout).contains("render: 16x12"));
    assert!(output.is_file() && output.with_extension("png").is_file());

    let bad = Command::new(&exe)
        .arg(work.join("missing.glb"))
        .env("LD_LIBRARY_PATH", &lib_dir)
        .env("DYLD_LIBRARY_PATH", &lib_dir)
        .output()
        .expect("run the compiled example");
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert_eq!(bad.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("missing.glb"), "{stderr}");
    std::fs::remove_dir_all(&work).ok();
}
