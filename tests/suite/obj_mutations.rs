//! Deterministic mutation sweep of the OBJ loader: truncated, byte-flipped and token-damaged OBJ and MTL files
//! (a small scene made here, and `realworld/obj/spider` from the shared folder when present) must each load,
//! build and render without NaN, or be refused with a one-line error: never a panic, an abort or a hang.

use crate::common;
use crate::hostile;

use hostile::{mutate, run_case, Outcome};
use std::path::{Path, PathBuf};

/// Tokens put in place of a number or an index.
const HOSTILE_TOKENS: &[&str] = &[
    "nan",
    "-nan",
    "inf",
    "-inf",
    "1e39",
    "-1e39",
    "-1",
    "0",
    "-0",
    "4294967297",
    "99999999999999999999",
    "-9223372036854775808",
    "1/1/1/1",
    "//",
    "",
];

const SMALL_OBJ: &str = "# a lit box corner\nmtllib m.mtl\no floor\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 1 0\nusemtl white\nf 1/1/1 2/2/1 3/3/1 4/4/1\no wall\nv -1 0 -1\n\
v -1 2 -1\nv 1 2 -1\nusemtl shiny\nf 5 -2 -1\no lamp\nv -0.2 1.9 -0.2\nv 0.2 1.9 -0.2\nv 0.2 1.9 0.2\n\
usemtl lamp\nf -3 -1 -2\n";

const SMALL_MTL: &str = "newmtl white\nKa 0 0 0\nKd 0.8 0.8 0.8\nKs 0 0 0\nNs 10\nillum 2\n\
newmtl shiny\nKd 0 0 0\nKs 0.9 0.9 0.9\nNs 200\nd 1\nNi 1.5\nnewmtl lamp\nKd 0 0 0\nKe 5 5 5\n";

/// Runs `cases` mutations of the OBJ (or, with `damage_mtl`, of the MTL) in `dir`, and returns how many
/// rendered and how many were refused.
fn sweep(
    dir: &Path,
    obj: &[u8],
    mtl: &[u8],
    damage_mtl: bool,
    cases: u64,
    seed: u64,
) -> [usize; 2] {
    let (obj_path, mtl_path) = (dir.join("case.obj"), dir.join(mtl_name(obj)));
    let mut counts = [0; 2];
    for i in 0..cases {
        let target = if damage_mtl { mtl } else { obj };
        let (damaged, what) = mutate(target, seed + i, HOSTILE_TOKENS);
        let (o, m) = if damage_mtl {
            (obj, &damaged[..])
        } else {
            (&damaged[..], mtl)
        };
        std::fs::write(&obj_path, o).unwrap();
        std::fs::write(&mtl_path, m).unwrap();
        let label = format!("{} {what}", if damage_mtl { "mtl" } else { "obj" });
        match run_case(obj_path.clone(), &label) {
            Outcome::Rendered => counts[0] += 1,
            Outcome::Refused => counts[1] += 1,
        }
    }
    counts
}

/// The file the OBJ's first `mtllib` names.
fn mtl_name(obj: &[u8]) -> String {
    String::from_utf8_lossy(obj)
        .lines()
        .find_map(|l| l.strip_prefix("mtllib ").map(|f| f.trim().to_owned()))
        .unwrap_or_else(|| "m.mtl".into())
}

fn folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_objmut_{}_{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn damaged_small_obj_and_mtl_never_panic() {
    let dir = folder("small");
    let (obj, mtl) = (SMALL_OBJ.as_bytes(), SMALL_MTL.as_bytes());
    std::fs::write(dir.join("case.obj"), obj).unwrap();
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    assert_eq!(
        run_case(dir.join("case.obj"), "original"),
        Outcome::Rendered
    );
    let o = sweep(&dir, obj, mtl, false, 800, 0);
    let m = sweep(&dir, obj, mtl, true, 400, 10_000);
    eprintln!("small OBJ: {o:?} rendered/refused; MTL: {m:?}");
    assert!(o[0] > 0 && o[1] > 0 && m[1] > 0, "{o:?} {m:?}");
    common::assert_sweep_peak_memory("OBJ sweep");
}

#[test]
fn damaged_spider_never_panics() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let src = shared.join("realworld/obj/spider");
    if !src.join("spider.obj").is_file() {
        eprintln!("SKIP: no {}", src.display());
        return;
    }
    let obj = std::fs::read(src.join("spider.obj")).unwrap();
    let mtl = std::fs::read(src.join("spider.mtl")).unwrap();
    let dir = folder("spider");
    std::fs::write(dir.join("case.obj"), &obj).unwrap();
    std::fs::write(dir.join(mtl_name(&obj)), &mtl).unwrap();
    assert_eq!(run_case(dir.join("case.obj"), "spider"), Outcome::Rendered);
    let o = sweep(&dir, &obj, &mtl, false, 150, 20_000);
    let m = sweep(&dir, &obj, &mtl, true, 80, 30_000);
    eprintln!("spider OBJ: {o:?} rendered/refused; MTL: {m:?}");
    common::assert_sweep_peak_memory("spider sweep");
}
