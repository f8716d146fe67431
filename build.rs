//! Build script: with the `denoise` feature, the binaries and tests find Intel Open Image Denoise at run time
//! where they were linked against it. The `oidn` crate's own build script links `$OIDN_DIR/lib`; this adds the
//! same folder as an rpath, so neither `LD_LIBRARY_PATH` nor an installed library is needed. Without the
//! feature it does nothing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_DENOISE").is_none() {
        return;
    }
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    let Some(dir) = std::env::var_os("OIDN_DIR").filter(|d| !d.is_empty()) else {
        // The oidn crate then found the library through pkg-config, whose folder the loader searches itself.
        return;
    };
    let lib = std::path::Path::new(&dir).join("lib");
    let lib = lib.canonicalize().unwrap_or(lib);
    let os = std::env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if os == "linux" || os == "macos" {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
