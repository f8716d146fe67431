//! Helpers shared by integration tests.

#![allow(dead_code)]

use std::path::PathBuf;

/// The shared test-data folder: `$NIMBUS_SHARED_DIR` if set, else `$CARGO_MANIFEST_DIR/../shared`.
///
/// Returns `None` (after printing a skip notice) when it is missing, unless `NIMBUS_REQUIRE_SHARED=1`, in which
/// case it panics so that the calling test fails.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("NIMBUS_SHARED_DIR") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"),
    };
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!(
            "shared data folder {} is missing and NIMBUS_REQUIRE_SHARED=1",
            dir.display()
        );
    }
    eprintln!(
        "SKIP: shared data folder {} not found (set NIMBUS_SHARED_DIR)",
        dir.display()
    );
    None
}

/// The VDB corpus folder inside the shared folder, if present.
pub fn vdb_corpus_dir() -> Option<PathBuf> {
    let d = shared_dir()?.join("vdb-corpus");
    if d.join("truth.tsv").is_file() {
        Some(d)
    } else if std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!("VDB corpus missing under {}", d.display());
    } else {
        eprintln!("SKIP: no VDB corpus under {}", d.display());
        None
    }
}
