//! Shots (issue 17, first part): VDB sequences named with a frame pattern, read frame by frame with
//! `frame_offset` and the `missing_frame` policy, and `nimbus render --frame/--frames` writing one EXR, PNG and
//! statistics file per frame.

use nimbus::math::Aabb;
use nimbus::scene::{load_builder, LoadOptions, SceneBuilder};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A folder holding `shot.gltf`, a volume over the sequence `grid.####.vdb` with `extra` keys in its
/// `nimbus_volume`, and that sequence's frames 1 (the constant test grid) and 3 (the bundled cloud, a grid of
/// other bounds); frame 2 is missing.
fn sequence_scene(name: &str, extra: &str) -> (PathBuf, PathBuf) {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("nimbus-shots-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        manifest.join("tests/scenes/constant_grid.vdb"),
        dir.join("grid.0001.vdb"),
    )
    .unwrap();
    std::fs::copy(manifest.join("assets/cloud.vdb"), dir.join("grid.0003.vdb")).unwrap();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,
        "scenes":[{{"nodes":[0,1],"extras":{{"nimbus_environment":{{"color":[1,1,1]}}}}}}],
        "nodes":[{{"name":"smoke","extras":{{"nimbus_volume":{{"file":"grid.####.vdb","density_scale":2.0{extra}}}}}}},
                 {{"name":"camera","camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.6,"aspectRatio":1.0,"znear":0.01}}}}]}}"#
    );
    let scene = dir.join("shot.gltf");
    std::fs::write(&scene, gltf).unwrap();
    (dir, scene)
}

fn load_frame(scene: &Path, frame: i64) -> Result<SceneBuilder, String> {
    load_builder(
        scene,
        &LoadOptions {
            frame: Some(frame),
            ..LoadOptions::default()
        },
    )
    .map_err(|e| e.to_string())
}

/// The bounds of the one volume in frame `frame`, or `None` when the frame has no volume.
fn volume_bounds(scene: &Path, frame: i64) -> Option<Aabb> {
    let builder = load_frame(scene, frame).unwrap();
    assert!(builder.media().len() <= 1);
    builder.media().first().map(|m| m.fill_bounds().unwrap())
}

#[test]
fn each_frame_reads_its_own_file() {
    let (dir, scene) = sequence_scene("own", "");
    let first = volume_bounds(&scene, 1).unwrap();
    let third = volume_bounds(&scene, 3).unwrap();
    assert_ne!(first, third, "frames 1 and 3 are different grids");
    // Without a shot frame, a sequence reads frame 1.
    let still = load_builder(&scene, &LoadOptions::default()).unwrap();
    assert_eq!(still.media()[0].fill_bounds(), Some(first));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_missing_frame_is_an_error_naming_the_file_by_default() {
    let (dir, scene) = sequence_scene("error", "");
    let message = load_frame(&scene, 2).err().expect("frame 2 is missing");
    assert!(message.contains("grid.0002.vdb"), "{message}");
    assert!(message.contains("frame 2"), "{message}");
    assert!(message.contains("missing_frame"), "{message}");
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn hold_uses_the_nearest_earlier_frame_else_the_first_later_one() {
    let (dir, scene) = sequence_scene("hold", r#","missing_frame":"hold""#);
    let first = volume_bounds(&scene, 1).unwrap();
    let third = volume_bounds(&scene, 3).unwrap();
    assert_eq!(volume_bounds(&scene, 2), Some(first));
    assert_eq!(
        volume_bounds(&scene, 0),
        Some(first),
        "nothing earlier: the first later frame"
    );
    assert_eq!(volume_bounds(&scene, 50), Some(third));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn empty_leaves_the_volume_out_of_a_missing_frame_with_a_warning() {
    let (dir, scene) = sequence_scene("empty", r#","missing_frame":"empty""#);
    let builder = load_frame(&scene, 2).unwrap();
    assert!(builder.media().is_empty());
    assert!(
        builder.warnings().iter().any(|w| w.contains("frame 2")),
        "{:?}",
        builder.warnings()
    );
    assert!(volume_bounds(&scene, 3).is_some());
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn frame_offset_shifts_the_file_frame() {
    let (dir, scene) = sequence_scene("offset", r#","frame_offset":2"#);
    let third = {
        let (d, s) = sequence_scene("offset-ref", "");
        let b = volume_bounds(&s, 3);
        std::fs::remove_dir_all(d).ok();
        b
    };
    assert_eq!(
        volume_bounds(&scene, 1),
        third,
        "shot frame 1 reads file frame 3"
    );
    let (dir2, bad) = sequence_scene("offset-bad", r#","frame_offset":0.5"#);
    let message = load_frame(&bad, 1).err().expect("a fractional offset");
    assert!(message.contains("frame_offset"), "{message}");
    std::fs::remove_dir_all(dir).ok();
    std::fs::remove_dir_all(dir2).ok();
}

fn nimbus(args: &[&str], dir: &Path) -> (bool, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap();
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn the_cli_renders_a_range_of_frames_to_numbered_files() {
    let (dir, _) = sequence_scene("cli", r#","missing_frame":"hold""#);
    let small = ["--width", "8", "--height", "8", "--spp", "2"];
    let mut args = vec![
        "render",
        "shot.gltf",
        "--frames",
        "1..3",
        "-o",
        "out/shot.####.exr",
    ];
    args.extend(["--stats", "out/stats.%04d.json"]);
    args.extend(small);
    let (ok, stderr) = nimbus(&args, &dir);
    assert!(ok, "{stderr}");
    for f in 1..=3 {
        for name in [
            format!("shot.{f:04}.exr"),
            format!("shot.{f:04}.png"),
            format!("stats.{f:04}.json"),
        ] {
            assert!(dir.join("out").join(&name).is_file(), "{name}: {stderr}");
        }
    }
    // A name without a pattern gets one, so frames never overwrite each other; a step skips frames.
    let mut args = vec![
        "render",
        "shot.gltf",
        "--frames",
        "1..3:2",
        "-o",
        "plain.exr",
    ];
    args.extend(small);
    let (ok, stderr) = nimbus(&args, &dir);
    assert!(ok, "{stderr}");
    assert!(stderr.contains("plain.####.exr"), "{stderr}");
    assert!(dir.join("plain.0001.exr").is_file() && dir.join("plain.0003.exr").is_file());
    assert!(!dir.join("plain.0002.exr").exists());
    // One frame, by --frame; the missing frame with the default policy fails before writing anything.
    let mut args = vec!["render", "shot.gltf", "--frame", "3", "-o", "one.$F4.exr"];
    args.extend(small);
    let (ok, stderr) = nimbus(&args, &dir);
    assert!(ok, "{stderr}");
    assert!(dir.join("one.0003.exr").is_file());
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn bad_frame_ranges_are_refused() {
    let dir = std::env::temp_dir();
    for range in ["3..1", "1..4:0", "1-4"] {
        let (ok, stderr) = nimbus(&["render", "--frames", range], &dir);
        assert!(!ok, "{range}");
        assert!(stderr.contains(range), "{range}: {stderr}");
    }
    let (ok, stderr) = nimbus(&["render", "--frames", "1..2", "--samples", "0..1"], &dir);
    assert!(!ok && stderr.contains("--samples"), "{stderr}");
}
