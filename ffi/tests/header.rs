//! The committed header `include/nimbus.h` must be what cbindgen generates from the sources now. Run with
//! `NIMBUS_BLESS_HEADER=1` to rewrite it.

use std::path::Path;

#[test]
fn header_is_up_to_date() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_config(config)
        .with_src(root.join("src/lib.rs"))
        .generate()
        .expect("cbindgen parses src/lib.rs")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("UTF-8 header");
    let path = root.join("include/nimbus.h");
    if std::env::var("NIMBUS_BLESS_HEADER").as_deref() == Ok("1") {
        std::fs::write(&path, &generated).expect("write include/nimbus.h");
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} is stale: regenerate it with `NIMBUS_BLESS_HEADER=1 cargo test -p nimbus-ffi --test header`",
        path.display()
    );
}
