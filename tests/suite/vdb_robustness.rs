//! Truncated and bit-flipped corpus files must give `Err` or `Ok`, never a panic, and quickly.

use crate::common;

use common::splitmix as mix;
use nimbus::vdb::{read_bytes, VdbErrorKind};
use std::path::Path;
use std::time::Instant;

fn no_panic(bytes: &[u8], label: &str) -> bool {
    let r = std::panic::catch_unwind(|| read_bytes(bytes, Path::new(label)).is_ok());
    match r {
        Ok(ok) => ok,
        Err(_) => panic!("reader panicked on {label}"),
    }
}

#[test]
fn truncated_and_bit_flipped_files_never_panic() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let t0 = Instant::now();
    let files = [
        ("generated/f_affine.vdb", 200),
        ("generated/h_tiles.vdb", 200),
        ("real/lukasgartmair_grid.vdb", 200),
        ("generated/c_half_comp_zip_am_unknownclass.vdb", 60),
        ("real/mjurczyk_smoke.vdb", 40),
    ];
    for (name, n) in files {
        let data = std::fs::read(dir.join(name)).unwrap();
        let len = data.len() as u64;
        assert!(no_panic(&data, name), "{name} should read");
        let mut errs = 0;
        for i in 0..n as u64 {
            // Truncation: half the cuts in the first 16 KiB (header, metadata, topology), half anywhere.
            let cut = if i % 2 == 0 {
                mix(i) % len.min(16384)
            } else {
                mix(i) % len
            } as usize;
            let label = format!("{name} cut at {cut}");
            if !no_panic(&data[..cut], &label) {
                errs += 1;
            }
            // Bit flip, same split between the head and the whole file.
            let pos = if i % 2 == 0 {
                mix(i + 1_000_000) % len.min(16384)
            } else {
                mix(i + 1_000_000) % len
            } as usize;
            let mut flipped = data.clone();
            flipped[pos] ^= 1 << (mix(i + 2_000_000) % 8);
            no_panic(&flipped, &format!("{name} bit flip at {pos}"));
        }
        assert_eq!(errs, n, "{name}: every truncated file must be an error");
    }
    eprintln!("robustness: {:.2} s", t0.elapsed().as_secs_f64());
    common::assert_sweep_peak_memory("VDB sweep");
}

#[test]
fn unsupported_grid_type_is_a_named_error() {
    let Some(dir) = common::vdb_corpus_dir() else {
        return;
    };
    let mut data = std::fs::read(dir.join("generated/f_affine.vdb")).unwrap();
    let pat = b"Tree_float_5_4_3";
    let at = data.windows(pat.len()).position(|w| w == pat).unwrap();
    data[at..at + pat.len()].copy_from_slice(b"Tree_int32_5_4_3");
    let err = read_bytes(&data, Path::new("x.vdb")).unwrap_err();
    match &err.kind {
        VdbErrorKind::UnsupportedGridType { grid, type_name } => {
            assert_eq!(grid, "density");
            assert_eq!(type_name, "Tree_int32_5_4_3");
        }
        k => panic!("unexpected error {k}"),
    }
    let msg = err.to_string();
    assert!(msg.contains("x.vdb") && msg.contains("density"), "{msg}");
    // With skip_unsupported the grid is listed instead of failing the file.
    let opts = nimbus::vdb::ReadOptions {
        skip_unsupported: true,
        ..Default::default()
    };
    let f = nimbus::vdb::read_bytes_with(&data, Path::new("x.vdb"), &opts).unwrap();
    assert!(f.grids.is_empty());
    assert_eq!(
        f.skipped,
        vec![("density".to_string(), "Tree_int32_5_4_3".to_string())]
    );
}

#[test]
fn not_a_vdb_file() {
    let err = read_bytes(b"hello world, not a vdb", Path::new("t.txt")).unwrap_err();
    assert!(matches!(err.kind, VdbErrorKind::BadMagic));
    let err = nimbus::vdb::read_file(Path::new("/nonexistent/file.vdb")).unwrap_err();
    assert!(matches!(err.kind, VdbErrorKind::Io(_)));
}
