//! Replays the inputs the fuzz targets in `fuzz/` found (minimised with `cargo fuzz tmin`, then committed under
//! `fuzz/regressions/<target>/`) through the same entry points as the targets, so a fixed crash stays fixed
//! without nightly or cargo-fuzz. Each input must end in `Ok` or `Err`: no panic, and no hang (10 s per input).

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

#[path = "../../fuzz/compose_stage.rs"]
mod compose_stage;

/// The committed inputs of one fuzz target, sorted by name.
fn regressions(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/regressions")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

/// A scratch folder for inputs that loaders read from disk.
fn scratch(target: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "nimbus-fuzz-regressions-{}-{target}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `entry` on every regression input of `target` on a worker thread, failing on a panic or a hang.
fn replay(target: &'static str, entry: fn(&[u8], &Path)) {
    let dir = scratch(target);
    for file in regressions(target) {
        let bytes = std::fs::read(&file).unwrap();
        let (send, receive) = mpsc::channel();
        let scratch = dir.clone();
        std::thread::spawn(move || {
            entry(&bytes, &scratch);
            let _ = send.send(());
        });
        receive
            .recv_timeout(Duration::from_secs(10))
            .unwrap_or_else(|_| panic!("{}: a panic or a hang", file.display()));
    }
}

/// The `vdb_read` target: read, then the statistics of every grid.
fn vdb_read(data: &[u8], _: &Path) {
    if let Ok(file) = nimbus::vdb::read_bytes(data, Path::new("fuzz.vdb")) {
        for g in &file.grids {
            let _ = g.tree.stats();
        }
    }
}

/// The `gltf_load` target: glTF or GLB bytes, then build.
fn gltf_load(data: &[u8], dir: &Path) {
    let options = nimbus::scene::LoadOptions::default();
    if let Ok(builder) = nimbus::scene::gltf::load_slice(data, &dir.join("fuzz.gltf"), &options) {
        let _ = builder.build();
    }
}

/// The `gltf_animation` target: the first byte picks the frame and the shutter, the rest is the file, loaded
/// under a 256 MiB budget, then built.
fn gltf_animation(data: &[u8], dir: &Path) {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let options = nimbus::scene::LoadOptions {
        limits: nimbus::limits::Limits::with_memory(256 << 20),
        frame: Some(i64::from(pick & 63)),
        shutter: (pick & 64 != 0).then_some(nimbus::frames::Shutter {
            open: -0.25,
            close: 0.25,
        }),
        ..Default::default()
    };
    if let Ok(builder) = nimbus::scene::gltf::load_slice(file, &dir.join("fuzz.gltf"), &options) {
        let _ = builder.build();
    }
}

/// The `obj_load` target: an OBJ file (beside an MTL library `m.mtl`), then build.
fn obj_load(data: &[u8], dir: &Path) {
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl a\nKd 0.5 0.5 0.5\nKs 0.1 0.1 0.1\nNs 20\nnewmtl lamp\nKe 2 2 2\n",
    )
    .unwrap();
    let path = dir.join("fuzz.obj");
    std::fs::write(&path, data).unwrap();
    if let Ok(builder) = nimbus::scene::load_builder(&path, &Default::default()) {
        let _ = builder.build();
    }
}

/// The `usd_load` target: the first byte picks `.usda`, `.usdc` or `.usdz`, the rest is the layer.
fn usd_load(data: &[u8], dir: &Path) {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let path = dir.join(format!(
        "fuzz.{}",
        ["usda", "usdc", "usdz"][pick as usize % 3]
    ));
    std::fs::write(&path, file).unwrap();
    if let Ok(builder) = nimbus::scene::load_builder(&path, &Default::default()) {
        let _ = builder.build();
    }
}

#[path = "../../fuzz/cli_ranges_check.rs"]
mod cli_ranges_check;
#[path = "../../fuzz/farm_part_check.rs"]
mod farm_part_check;

#[test]
fn fuzz_findings_stay_fixed() {
    replay("vdb_read", vdb_read);
    replay("gltf_load", gltf_load);
    replay("gltf_animation", gltf_animation);
    replay("obj_load", obj_load);
    replay("usd_load", usd_load);
    replay("cli_ranges", |data, _| cli_ranges_check::run(data));
    replay("farm_part", farm_part_check::run);
    replay("usd_compose", compose_stage::load);
}
