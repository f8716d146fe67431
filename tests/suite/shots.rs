//! Shots (issue 17, first part): VDB sequences named with a frame pattern, read frame by frame with
//! `frame_offset` and the `missing_frame` policy, and `nimbus render --frame/--frames` writing one EXR, PNG and
//! statistics file per frame.

use crate::common;

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

/// A triangle node and a camera node; the triangle's translation is animated LINEAR from (0, 0, 0) at 0 s to
/// (10, 0, 0) at 1 s, and the camera's STEP from z = 5 to z = 9 at 0.5 s.
fn animated_gltf(dir: &Path) -> PathBuf {
    let floats: Vec<f32> = [
        // positions (3 × vec3), offset 0
        0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, // key times 0, 1 (offset 36)
        0.0, 1.0, // translations (offset 44)
        0.0, 0.0, 0.0, 10.0, 0.0, 0.0, // camera key times 0, 0.5 (offset 68)
        0.0, 0.5, // camera translations (offset 76)
        0.0, 0.0, 5.0, 0.0, 0.0, 9.0,
    ]
    .to_vec();
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0}},{{"camera":0,"translation":[0,0,5]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,"znear":0.01}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
        "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
        "bufferViews":[{{"buffer":0,"byteLength":{len}}}],
        "accessors":[
          {{"bufferView":0,"byteOffset":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
          {{"bufferView":0,"byteOffset":36,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]}},
          {{"bufferView":0,"byteOffset":44,"componentType":5126,"count":2,"type":"VEC3"}},
          {{"bufferView":0,"byteOffset":68,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[0.5]}},
          {{"bufferView":0,"byteOffset":76,"componentType":5126,"count":2,"type":"VEC3"}}],
        "animations":[{{"samplers":[{{"input":1,"output":2}},{{"input":3,"output":4,"interpolation":"STEP"}}],
          "channels":[{{"sampler":0,"target":{{"node":0,"path":"translation"}}}},
                      {{"sampler":1,"target":{{"node":1,"path":"translation"}}}}]}}]}}"#,
        len = bytes.len(),
        b64 = common::base64(&bytes)
    );
    let path = dir.join("animated.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

#[test]
fn gltf_animations_are_sampled_at_the_frame_time() {
    let dir = std::env::temp_dir().join(format!("nimbus-shots-{}-anim", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = animated_gltf(&dir);
    let at = |frame: Option<i64>, fps: Option<f64>| {
        let b = load_builder(
            &path,
            &LoadOptions {
                frame,
                fps,
                ..LoadOptions::default()
            },
        )
        .unwrap();
        let min_x = b.meshes()[0]
            .positions
            .iter()
            .map(|p| p.x)
            .fold(f32::INFINITY, f32::min);
        let camera_z = b.camera().unwrap().camera_to_world.w_axis.z;
        (min_x, camera_z)
    };
    // A still ignores the animation: the file's own transforms.
    assert_eq!(at(None, None), (0.0, 5.0));
    // Frame 12 at the default 24 fps is 0.5 s: halfway along the LINEAR track, and the STEP track's second key.
    let (x, z) = at(Some(12), None);
    assert!((x - 5.0).abs() < 1e-5, "{x}");
    assert_eq!(z, 9.0);
    // Frame 6 at 24 fps (0.25 s) and at 12 fps (0.5 s); past the last key the value holds.
    assert!((at(Some(6), None).0 - 2.5).abs() < 1e-5);
    assert_eq!(
        at(Some(6), None).1,
        5.0,
        "STEP holds the first key before 0.5 s"
    );
    assert!((at(Some(6), Some(12.0)).0 - 5.0).abs() < 1e-5);
    assert!((at(Some(100), None).0 - 10.0).abs() < 1e-5);
    std::fs::remove_dir_all(dir).ok();
}

/// A USD stage whose `Volume` reads a sequence through a time-sampled `filePath` (UsdVol's way of naming one),
/// over the folder of [`sequence_scene`].
#[test]
fn usd_time_sampled_file_paths_read_the_frame_s_file() {
    let (dir, _) = sequence_scene("usdvol", "");
    // tests/usd/sequence.usdc (made by tests/usd/make_sequence_stage.py): filePath is grid.0001.vdb at time
    // code 1 and grid.0003.vdb at 3, at 24 time codes and 24 frames per second.
    let stage = dir.join("shot.usdc");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/usd/sequence.usdc"),
        &stage,
    )
    .unwrap();
    let first = volume_bounds(&stage, 1).unwrap();
    let third = volume_bounds(&stage, 3).unwrap();
    assert_ne!(first, third, "frames 1 and 3 name different files");
    assert_eq!(volume_bounds(&dir.join("shot.gltf"), 3), Some(third));
    // Between samples the earlier file is held (asset paths do not interpolate).
    assert_eq!(volume_bounds(&stage, 2), Some(first));
    std::fs::remove_dir_all(dir).ok();
}

/// USD `Volume` prims take the pyro channels as `field:flame`, `field:Cd` and `field:albedo` relationships.
#[test]
fn usd_volumes_read_flame_and_colour_fields() {
    let dir = std::env::temp_dir().join(format!("nimbus-shots-{}-usdpyro", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vdb = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pyro_box.vdb");
    let field = |name: &str, grid: &str| {
        format!(
            "def OpenVDBAsset \"{name}\"\n{{\ntoken fieldName = \"{grid}\"\nasset filePath = @{}@\n}}\n",
            vdb.display()
        )
    };
    let stage = dir.join("pyro.usda");
    std::fs::write(
        &stage,
        format!(
            "#usda 1.0\ndef Volume \"Fire\"\n{{\ncustom rel field:density = </Fire/density>\n\
             custom rel field:flame = </Fire/flame>\ncustom rel field:Cd = </Fire/Cd>\n\
             custom float nimbus:flame_scale = 3\ncustom color3f nimbus:flame_color = (1, 0.5, 0.25)\n{}{}{}}}\n",
            field("density", "density"),
            field("flame", "flame"),
            field("Cd", "Cd"),
        ),
    )
    .unwrap();
    let builder = load_frame(&stage, 1).unwrap();
    let medium = &builder.media()[0];
    assert!(medium.is_emissive());
    let c = medium.collision(nimbus::math::Vec3::new(0.5, 0.5, 0.5), 0.0);
    // Cd at x = 0.5 m (index 8): red (8 + 2)/19, green 0.5, blue 0.25; emission (1 − Cd) · 3 · (1, 0.5, 0.25).
    let red = 10.0 / 19.0;
    assert!((c.albedo.x - red).abs() < 1e-5 && (c.albedo.y - 0.5).abs() < 1e-6);
    let expected = [(1.0 - red) * 3.0, 0.5 * 3.0 * 0.5, 0.75 * 3.0 * 0.25];
    for (got, want) in c.emission.to_array().iter().zip(expected) {
        assert!(
            (got - want).abs() < 1e-4,
            "{:?} vs {expected:?}",
            c.emission
        );
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn the_cli_reports_the_shutter_in_explain_and_stats() {
    let (dir, _) = sequence_scene("shutter", "");
    let args = [
        "render",
        "shot.gltf",
        "--shutter=-0.25,0.25",
        "--explain",
        "--stats",
        "stats.json",
        "-o",
        "blur.exr",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "2",
    ];
    let (ok, stderr) = nimbus(&args, &dir);
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("motion blur: shutter -0.25,0.25 frames"),
        "{stderr}"
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["shutter"], serde_json::json!([-0.25, 0.25]));
    assert_eq!(stats["moving_triangles"], 0);
    assert_eq!(stats["camera_moves"], false);
    for bad in ["0.5,-0.5", "0.25", "nan,1"] {
        let (ok, stderr) = nimbus(&["render", &format!("--shutter={bad}")], &dir);
        assert!(!ok && stderr.contains("shutter"), "{bad}: {stderr}");
    }
    std::fs::remove_dir_all(dir).ok();
}
