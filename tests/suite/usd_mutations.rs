//! Deterministic mutation sweep of the USD loader: text layers (`tests/usd/*.usda` and the shared
//! `realworld/usd` stages) truncated, byte-flipped, with hostile tokens in place of tokens, tokens dropped or
//! nesting repeated; binary `.usdc` and `.usdz` files bit-flipped. Each case must load, build and render
//! without NaN, or be refused with a one-line error: never a panic, an abort or a hang.

use crate::common;
use crate::hostile;

use hostile::{mutate, run_case, Outcome};
use std::path::{Path, PathBuf};

/// Tokens put in place of a token of a text layer.
const HOSTILE_TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e39",
    "-1e39",
    "1e300",
    "-1",
    "0",
    "4294967297",
    "99999999999999999999",
    "{",
    "}",
    "(",
    ")",
    "[",
    "]",
    "\"",
    "@",
    "<",
    "def",
    "#",
    "",
];

/// A folder for the damaged copies of `source`, holding links to everything beside it (textures, VDB files,
/// referenced layers), so that relative asset paths still resolve.
fn folder_beside(source: &Path, tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_usdmut_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(source.parent().unwrap()).unwrap() {
        let entry = entry.unwrap().path();
        if entry != source {
            std::os::unix::fs::symlink(&entry, dir.join(entry.file_name().unwrap())).unwrap();
        }
    }
    dir
}

/// Runs `cases` damaged copies of `source` (text mutations, or for binary files bit flips) and returns how
/// many rendered and how many were refused.
fn sweep(source: &Path, cases: u64, seed: u64) -> [usize; 2] {
    let name = source.file_name().unwrap().to_string_lossy().into_owned();
    let ext = source.extension().unwrap().to_string_lossy().into_owned();
    let data = std::fs::read(source).unwrap();
    let dir = folder_beside(source, &name.replace('.', "_"));
    let path = dir.join(format!("case.{ext}"));
    std::fs::write(&path, &data).unwrap();
    let original = run_case(path.clone(), &name);
    let mut counts = [0; 2];
    for i in 0..cases {
        let (damaged, what) = if ext == "usda" {
            if i % 5 == 4 {
                nest(&data, seed + i)
            } else {
                mutate(&data, seed + i, HOSTILE_TOKENS)
            }
        } else {
            // Binary files: 1 to 4 bit flips.
            let mut d = data.clone();
            let mut flips = Vec::new();
            for k in 0..=(seed + i) % 4 {
                let r = hostile_mix(seed + i, k);
                let at = (r % d.len() as u64) as usize;
                d[at] ^= 1 << ((r >> 32) % 8);
                flips.push(at);
            }
            (d, format!("bit flips at {flips:?}"))
        };
        std::fs::write(&path, &damaged).unwrap();
        match run_case(path.clone(), &format!("{name} {what}")) {
            Outcome::Rendered => counts[0] += 1,
            Outcome::Refused => counts[1] += 1,
        }
    }
    eprintln!("{name}: original {original:?}; damaged {counts:?} rendered/refused");
    counts
}

/// A pseudo-random number for flip `k` of case `i`.
fn hostile_mix(i: u64, k: u64) -> u64 {
    // SplitMix64's finaliser over a mix of both.
    common::splitmix_finalize(
        i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k.wrapping_add(0xD1B5_4A32_D192_ED03),
    )
}

/// Repeats the text around an opening brace many times over: deep nesting, balanced or not.
fn nest(data: &[u8], i: u64) -> (Vec<u8>, String) {
    let opens: Vec<usize> = (0..data.len())
        .filter(|&k| matches!(data[k], b'{' | b'(' | b'['))
        .collect();
    let Some(&at) = opens.get((hostile_mix(i, 99) % opens.len().max(1) as u64) as usize) else {
        return (data.to_vec(), "unchanged".into());
    };
    let start = data[..at]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |p| p + 1);
    let times = [50, 199, 201, 5000][(i % 4) as usize];
    let mut d = data[..at + 1].to_vec();
    for _ in 0..times {
        d.extend_from_slice(&data[start..at + 1]);
        d.push(b'\n');
    }
    d.extend_from_slice(&data[at + 1..]);
    (
        d,
        format!("line of the opening at {at} repeated {times} times"),
    )
}

/// The text layers and binary files to damage, with a case count each.
fn sources() -> Vec<(PathBuf, u64)> {
    let tests = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/usd");
    let mut out = vec![
        (tests.join("cornell.usda"), 300),
        (tests.join("textured.usda"), 120),
        (tests.join("override.usda"), 40),
        (tests.join("cornell.usdc"), 400),
        (tests.join("cornell.usdz"), 100),
    ];
    if let Some(shared) = common::shared_dir() {
        let real = shared.join("realworld/usd");
        for (file, n) in [
            ("McUsd/McUsd.usda", 80),
            (
                "NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda",
                80,
            ),
            ("BoxAnimated/BoxAnimated.usdz", 40),
        ] {
            if real.join(file).is_file() {
                out.push((real.join(file), n));
            } else {
                eprintln!("SKIP: no {}", real.join(file).display());
            }
        }
    }
    out
}

#[test]
fn damaged_stages_never_panic_abort_or_hang() {
    let mut total = [0; 2];
    for (seed, (source, cases)) in sources().into_iter().enumerate() {
        let [rendered, refused] = sweep(&source, cases, seed as u64 * 100_000);
        total[0] += rendered;
        total[1] += refused;
    }
    assert!(total[1] > 0, "some damaged stages must be refused");
    common::assert_sweep_peak_memory("USD sweep");
}
