//! Hostile command-line values get a one-line error and exit code 1: never a panic (exit 101), an abort or
//! a runaway allocation.

use crate::common;

use std::path::Path;
use std::process::Command;

fn demo_scene() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/constant_grid.gltf")
}

#[test]
fn huge_sizes_and_durations_are_refused_with_one_line() {
    let scene = demo_scene();
    let out = std::env::temp_dir().join(format!("nimbus-cli-flags-{}.exr", std::process::id()));
    let cases: [&[&str]; 5] = [
        &["--time-limit", "1e300"],
        &["--width", "18446744073709551615"],
        &["--width", "4294967296", "--height", "4294967296"],
        &["--width", "65537", "--height", "1"],
        &["--width", "16384", "--height", "16384"],
    ];
    for flags in cases {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&scene)
            .args(flags)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{flags:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{flags:?}: {stderr}");
        let last = stderr.lines().last().unwrap_or_default();
        assert!(
            last.contains("too large") || last.contains("--time-limit"),
            "{flags:?}: {stderr}"
        );
    }
    assert!(!out.exists());
}

#[test]
fn the_memory_limit_flag_bounds_files_and_films() {
    let scene = demo_scene();
    let out = std::env::temp_dir().join(format!("nimbus-cli-memory-{}.exr", std::process::id()));
    // The scene's VDB (11.5 KiB) is over a 4 KiB budget; a 64×64 film (a few hundred KiB) is over 100 KiB.
    let cases: [(&[&str], &str); 3] = [
        (&["--memory-limit", "4K"], "memory budget"),
        (
            &["--memory-limit", "100K", "--width", "64", "--height", "64"],
            "film",
        ),
        (&["--memory-limit", "lots"], "not a size"),
    ];
    for (flags, expect) in cases {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&scene)
            .args(flags)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{flags:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{flags:?}: {stderr}");
        assert!(stderr.contains(expect), "{flags:?}: {stderr}");
    }
    assert!(!out.exists());
}

#[test]
fn outputs_and_counts_are_checked_before_rendering() {
    let scene = demo_scene();
    let dir = std::env::temp_dir().join(format!("nimbus-cli-outputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, b"").unwrap();
    let exr = dir.join("out.exr").display().to_string();
    let png = dir.join("out.png").display().to_string();
    let under_file = blocker.join("out.exr").display().to_string();
    let cases: [(&[&str], &str); 4] = [
        (&["--spp", "0", "-o", &exr], "--spp"),
        (&["--width", "0", "-o", &exr], "--width"),
        (&["-o", &png], "must name an .exr"),
        (&["-o", &under_file], "a-file"),
    ];
    for (flags, expect) in cases {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&scene)
            .args(flags)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{flags:?}: {stderr}");
        assert!(stderr.contains(expect), "{flags:?}: {stderr}");
        assert!(
            !stderr.contains("triangles"),
            "refused before loading: {stderr}"
        );
    }
    assert!(!dir.join("out.exr").exists() && !dir.join("out.png").exists());
    // A negative exposure is a value, not a flag.
    let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("render")
        .arg(&scene)
        .args(["--exposure", "-9", "--width", "8", "--spp", "1", "-o", &exr])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(dir.join("out.exr").exists() && dir.join("out.png").exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// Renders `scene` at `size` with 4 spp and `flags` into `dir/out.exr`: the stderr, and the mean grey level of
/// the PNG preview (0 to 255).
fn render_preview(scene: &Path, dir: &Path, size: &[&str], flags: &[&str]) -> (String, f64) {
    let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("render")
        .arg(scene)
        .args(size)
        .args(["--spp", "4", "-o"])
        .arg(dir.join("out.exr"))
        .args(flags)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(output.status.success(), "{stderr}");
    let png = image::open(dir.join("out.png")).unwrap().to_luma8();
    let mean = png.pixels().map(|p| p[0] as f64).sum::<f64>() / png.len() as f64;
    (stderr, mean)
}

#[test]
fn a_scene_without_light_gets_a_default_environment_unless_told_to_stay_dark() {
    // A grey floor seen from above, with no light of any kind: it used to render pure black, silently.
    let dir = std::env::temp_dir().join(format!("nimbus-cli-unlit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = dir.join("floor.obj");
    std::fs::write(
        &obj,
        "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\nf 1 4 3\n",
    )
    .unwrap();
    let render = |flags: &[&str]| render_preview(&obj, &dir, &["--width", "16"], flags);
    let (stderr, mean) = render(&[]);
    assert!(stderr.contains("no light"), "{stderr}");
    assert!(
        mean > 20.0,
        "the default environment lights the floor: mean {mean}"
    );
    let (stderr, mean) = render(&["--env-color", "0,0,0"]);
    assert!(!stderr.contains("no light"), "{stderr}");
    assert_eq!(mean, 0.0, "an explicit black environment keeps it dark");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn volume_sampling_and_sampler_flags_are_explained_and_counted() {
    // The peer benchmark's haze: a homogeneous scattering box with a point light inside.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/scenes/haze.gltf");
    let dir = std::env::temp_dir().join(format!("nimbus-cli-sampling-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = |flags: &[&str]| {
        let stats = dir.join("stats.json");
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&scene)
            .args(["--width", "8", "--spp", "4", "--explain", "--stats"])
            .arg(&stats)
            .arg("-o")
            .arg(dir.join("out.exr"))
            .args(flags)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_eq!(output.status.code(), Some(0), "{flags:?}: {stderr}");
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        (stderr, stats["rays"]["equiangular"].as_u64().unwrap())
    };
    let (stderr, equiangular) = render(&[]);
    assert!(
        stderr.contains("equiangular sampling toward 1 point/spot light"),
        "{stderr}"
    );
    assert!(equiangular > 0);
    let (stderr, equiangular) =
        render(&["--volume-sampling", "distance", "--sampler", "independent"]);
    assert!(
        stderr.contains("distance sampling alone (--volume-sampling distance)"),
        "{stderr}"
    );
    assert_eq!(equiangular, 0);
    assert_value_refused(&scene, "--sampler", "halton");
    assert_value_refused(&scene, "--volume-sampling", "equiangular");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn what_auto_guiding_decided_is_explained_after_its_pilot() {
    // Before rendering `--explain` can only say how `auto` will decide; after, it says what its pilot decided.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("nimbus-cli-guiding-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = |scene: &str, guiding: &str| {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(root.join(scene))
            .args([
                "--width",
                "64",
                "--spp",
                "16",
                "--explain",
                "--guiding",
                guiding,
            ])
            .arg("-o")
            .arg(dir.join("out.exr"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_eq!(output.status.code(), Some(0), "{scene}: {stderr}");
        stderr
    };
    // The sun behind a dense cloud: guided shadow roulette would save most shadow rays.
    let stderr = render("benches/peers/scenes/backlit.gltf", "auto");
    assert!(
        stderr.contains("path guiding: decided by a pilot of unguided paths before the training"),
        "{stderr}"
    );
    assert!(
        stderr.contains("path guiding decided: on (auto): on a pilot of unguided paths"),
        "{stderr}"
    );
    // The bundled cloud, lit from the front: it would not.
    let stderr = render("assets/cloud.gltf", "auto");
    assert!(
        stderr.contains("path guiding decided: off (auto): on a pilot of unguided paths"),
        "{stderr}"
    );
    // A forced mode was explained before rendering, and needs no second line.
    let stderr = render("assets/cloud.gltf", "on");
    assert!(
        stderr.contains("path guiding: on (--guiding on)"),
        "{stderr}"
    );
    assert!(!stderr.contains("path guiding decided"), "{stderr}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_light_sampler_flag_is_explained() {
    // The peer benchmark's Cornell box: one quad light, two emissive triangles.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/peers/scenes/cornell.gltf");
    let dir = std::env::temp_dir().join(format!("nimbus-cli-lights-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = |flags: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&scene)
            .args(["--width", "8", "--spp", "2", "--explain", "-o"])
            .arg(dir.join("out.exr"))
            .args(flags)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        assert_eq!(output.status.code(), Some(0), "{flags:?}: {stderr}");
        stderr
    };
    let stderr = render(&[]);
    assert!(
        stderr.contains(
            "light sampler: power: 2 bounded light(s) in 1 emitter(s), fewer than the 16"
        ),
        "{stderr}"
    );
    let stderr = render(&["--light-sampler", "bvh"]);
    assert!(
        stderr.contains("light sampler: light BVH over 2 bounded light(s) (--light-sampler bvh)"),
        "{stderr}"
    );
    assert_value_refused(&scene, "--light-sampler", "uniform");
    std::fs::remove_dir_all(&dir).ok();
}

/// Rendering `scene` with `flag value` fails with a message naming the value, without a panic.
fn assert_value_refused(scene: &Path, flag: &str, value: &str) {
    let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("render")
        .arg(scene)
        .args([flag, value])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !output.status.success() && !stderr.contains("panicked"),
        "{flag} {value}: {stderr}"
    );
    assert!(stderr.contains(value), "{flag} {value}: {stderr}");
}

/// A floor lit only by its file's own 3 lx sun (KHR_lights_punctual, read as 3/683 W/m²), as the Khronos sample
/// assets light themselves: the render is about 0.001 in linear radiance. The preview used to be black with no
/// word; now the automatic exposure lifts it, the lighting line says why no environment was added, and a fixed
/// `--exposure 0` warns that the image is almost black.
#[test]
fn a_physically_dim_scene_gets_a_viewable_preview_and_says_why() {
    let dir = std::env::temp_dir().join(format!("nimbus-cli-dim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("dim.gltf");
    // A 2 m grey floor (base colour 0.8, not metallic), a camera 3 m above looking down, and a directional light
    // of 3 lx shining down.
    let down = r#""rotation": [-0.70710678, 0, 0, 0.70710678]"#;
    std::fs::write(
        &scene,
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "directional", "intensity": 3}}]}}}},
  "scene": 0, "scenes": [{{"nodes": [0, 1, 2]}}],
  "nodes": [{{"mesh": 0}}, {{"camera": 0, "translation": [0, 3, 0], {down}}},
            {{"extensions": {{"KHR_lights_punctual": {{"light": 0}}}}, {down}}}],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.5, "znear": 0.1}}}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "buffers": [{{"byteLength": 60, "uri": "data:application/octet-stream;base64,AACAvwAAAAAAAIC/AACAPwAAAAAAAIC/AACAPwAAAAAAAIA/AACAvwAAAAAAAIA/AAACAAEAAAADAAIA"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                  "min": [-1, 0, -1], "max": [1, 0, 1]}},
                {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}]}}"#
        ),
    )
    .unwrap();
    let render =
        |flags: &[&str]| render_preview(&scene, &dir, &["--width", "16", "--height", "16"], flags);
    let (stderr, mean) = render(&[]);
    assert!(
        stderr.contains("lights itself (1 punctual light)") && stderr.contains("--env-color 1,1,1"),
        "{stderr}"
    );
    assert!(stderr.contains("almost black"), "{stderr}");
    assert!(
        stderr.contains("2 triangles, 1 punctual light, 16x16"),
        "{stderr}"
    );
    // 0.8/π · 3/683 W/m² = 1.12e-3: the key is 7.33 stops below middle grey; auto exposure brings it to one
    // stop below (6.33 stops), sRGB code 84.
    let stops: f64 = stderr
        .split("exposed by ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no exposure in {stderr}"));
    assert!((stops - 6.33).abs() < 0.05, "{stops}: {stderr}");
    assert!(
        (mean - 84.0).abs() < 6.0,
        "auto exposure shows the floor: mean {mean}"
    );
    let (stderr, mean) = render(&["--exposure", "0"]);
    assert!(
        stderr.contains("almost black") && stderr.contains("--exposure auto would expose"),
        "{stderr}"
    );
    assert!(mean < 10.0, "the linear preview is dark: {mean}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A small emitter (radiance 0.5, which switches the default environment off) in front of a black backdrop
/// that fills most of the frame, as in the Khronos EmissiveStrengthTest: the backdrop's pixels are covered but
/// exactly black. The automatic exposure used to meter them as δ, 26 stops below white, and exposed the
/// emitter 16 stops too bright (pure white); they carry no exposure information, so the emitter, already in
/// the meter's range, stays at 0 stops: sRGB 188 for 0.5.
#[test]
fn unlit_geometry_does_not_push_the_auto_exposure_up() {
    let dir =
        std::env::temp_dir().join(format!("nimbus-cli-unlit-backdrop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("backdrop.gltf");
    // Quads facing +Z: the backdrop ±1.2 m at z = 0 (base colour black), the emitter ±0.4 m at z = 0.01; a
    // camera at z = 3 looking down −Z.
    std::fs::write(
        &scene,
        r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
  "nodes": [{"mesh": 0}, {"mesh": 1}, {"camera": 0, "translation": [0, 0, 3]}],
  "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
  "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0}},
                {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0},
                 "emissiveFactor": [0.5, 0.5, 0.5]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 0}]},
             {"primitives": [{"attributes": {"POSITION": 1}, "indices": 2, "material": 1}]}],
  "buffers": [{"byteLength": 108, "uri": "data:application/octet-stream;base64,mpmZv5qZmb8AAAAAmpmZP5qZmb8AAAAAmpmZP5qZmT8AAAAAmpmZv5qZmT8AAAAAzczMvs3MzL4K1yM8zczMPs3MzL4K1yM8zczMPs3MzD4K1yM8zczMvs3MzD4K1yM8AAABAAIAAAACAAMA"}],
  "bufferViews": [{"buffer": 0, "byteLength": 96}, {"buffer": 0, "byteOffset": 96, "byteLength": 12}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [-1.2, -1.2, 0], "max": [1.2, 1.2, 0]},
                {"bufferView": 0, "byteOffset": 48, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [-0.4, -0.4, 0.01], "max": [0.4, 0.4, 0.01]},
                {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]}"#,
    )
    .unwrap();
    let (stderr, _) = render_preview(&scene, &dir, &["--width", "16", "--height", "16"], &[]);
    assert!(stderr.contains("lights itself"), "{stderr}");
    assert!(stderr.contains("preview exposure +0.00 stops"), "{stderr}");
    // The centre pixel sees the emitter: linear 0.5 is sRGB 188.
    let png = image::open(dir.join("out.png")).unwrap().to_luma8();
    let centre = png.get_pixel(8, 8)[0];
    assert!(
        (180..=196).contains(&centre),
        "emitter at sRGB {centre}: {stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `docs/reference.md`.
fn reference() -> String {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/reference.md"))
        .expect("docs/reference.md")
}

/// The backticked spans of `text`.
fn backticked(text: &str) -> impl Iterator<Item = &str> {
    text.split('`').skip(1).step_by(2)
}

/// The backticked names in the section of `reference` that starts at the heading line `heading` and ends at
/// the next heading.
fn documented_names(reference: &str, heading: &str) -> std::collections::BTreeSet<String> {
    let section: String = reference
        .lines()
        .skip_while(|line| line.trim_end() != heading)
        .skip(1)
        .take_while(|line| !line.starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n");
    assert!(
        !section.is_empty(),
        "docs/reference.md has no section {heading:?}"
    );
    backticked(&section).map(str::to_owned).collect()
}

/// The keys of `value` (see [`json_keys`]) that `documented` does not name, with where each was met.
fn unnamed_keys(
    value: &serde_json::Value,
    at: &str,
    documented: &std::collections::BTreeSet<String>,
) -> Vec<(String, String)> {
    let mut keys = Vec::new();
    json_keys(value, at, &mut keys);
    assert!(keys.len() > 10, "{keys:?}");
    keys.retain(|(k, _)| !documented.contains(k));
    keys
}

/// Every key of `value` (objects nested in objects and arrays included), with the path where it was met.
fn json_keys(value: &serde_json::Value, at: &str, out: &mut Vec<(String, String)>) {
    match value {
        serde_json::Value::Object(map) => {
            for (key, inner) in map {
                out.push((key.clone(), at.to_owned()));
                json_keys(inner, &format!("{at}.{key}"), out);
            }
        }
        serde_json::Value::Array(items) => {
            for item in items {
                json_keys(item, &format!("{at}[]"), out);
            }
        }
        _ => {}
    }
}

/// `--stats` reports the time to the first pixel: there, finite, and no later than the render's end.
#[test]
fn the_stats_report_the_time_to_the_first_pixel() {
    let dir = std::env::temp_dir().join(format!("nimbus-first-pixel-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stats = dir.join("stats.json");
    let scene = demo_scene();
    let (ok, _, stderr) = common::run_nimbus(
        &[
            "render",
            scene.to_str().unwrap(),
            "--width",
            "16",
            "--spp",
            "4",
            "--stats",
            "stats.json",
            "-o",
            "out.exr",
        ],
        &dir,
    );
    assert!(ok, "{stderr}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let first = stats["first_pixel_seconds"].as_f64().unwrap();
    let total = stats["render_seconds"].as_f64().unwrap();
    assert!(
        first.is_finite() && first >= 0.0 && first <= total,
        "first pixel {first} s, render {total} s"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The reference tables are checked against the code: every long flag `nimbus render --help` lists has a row
/// in docs/reference.md's flag table and every row names a real flag; every key a `--stats` file holds (a render
/// with a grid medium, light paths and Cryptomatte, so that the media entries and layers are there) is named in
/// the `--stats` section; every key of `nimbus info --json` in its section. A flag or key added without its
/// documentation, or a documented one removed, fails here.
#[test]
fn the_reference_documents_every_flag_and_every_json_key() {
    let dir = std::env::temp_dir().join(format!("nimbus-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |args: &[&str]| {
        let (ok, stdout, stderr) = common::run_nimbus(args, &dir);
        assert!(ok, "{args:?}: {stderr}");
        stdout
    };
    let reference = reference();

    // Flags: the long ones of `render --help` against the table rows' first cells.
    let help = run(&["render", "--help"]);
    let flags: std::collections::BTreeSet<String> = help
        .split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == '=')
        .filter(|w| w.starts_with("--") && w.len() > 2)
        .map(|w| {
            w.trim_end_matches(|c: char| !c.is_ascii_alphanumeric())
                .to_owned()
        })
        .filter(|w| w != "--help" && w != "--version")
        .collect();
    let rows: std::collections::BTreeSet<String> = reference
        .lines()
        .filter(|line| line.starts_with("| `-"))
        .flat_map(|line| {
            let first = line.split('|').nth(1).unwrap_or("");
            backticked(first)
                .filter(|name| name.starts_with("--"))
                .map(str::to_owned)
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(flags.len() > 30, "render --help lists its flags: {flags:?}");
    let undocumented: Vec<_> = flags.difference(&rows).collect();
    let stale: Vec<_> = rows.difference(&flags).collect();
    assert!(
        undocumented.is_empty(),
        "render flags without a row in docs/reference.md: {undocumented:?}"
    );
    assert!(
        stale.is_empty(),
        "rows of docs/reference.md no render flag has: {stale:?}"
    );

    // --stats keys.
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/scenes/constant_grid.gltf"
    );
    run(&[
        "render",
        scene,
        "-o",
        "stats.exr",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "2",
        "--stats",
        "stats.json",
        "--aovs",
        "default,lightpaths,cryptomatte",
    ]);
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap()).unwrap();
    assert!(
        !stats["media"].as_array().unwrap().is_empty(),
        "the scene has a medium"
    );
    let documented = documented_names(&reference, "### `--stats` JSON keys");
    let missing = unnamed_keys(&stats, "stats", &documented);
    assert!(
        missing.is_empty(),
        "--stats keys docs/reference.md does not name: {missing:?}"
    );

    // `info --json` keys.
    let vdb = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/scenes/constant_grid.vdb"
    );
    let info: serde_json::Value = serde_json::from_str(&run(&["info", vdb, "--json"])).unwrap();
    let documented = documented_names(&reference, "### `nimbus info --json` keys");
    // The section lists the grid keys in one braced, comma-separated span.
    let documented: std::collections::BTreeSet<String> = documented
        .iter()
        .flat_map(|span| span.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')))
        .filter(|w| !w.is_empty())
        .map(str::to_owned)
        .collect();
    let missing = unnamed_keys(&info, "info", &documented);
    assert!(
        missing.is_empty(),
        "info --json keys docs/reference.md does not name: {missing:?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
