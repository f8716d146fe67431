//! Farm-grade reliability of the command line: a render killed with SIGKILL at any moment leaves each output
//! (EXR, PNG preview, statistics) either absent or complete and readable, never torn, because every file is
//! written beside its final name and renamed into place.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("nimbus-reliability-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A render of the bundled demo whose writing takes a while: a large frame with every layer.
fn render_command(dir: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_nimbus"));
    cmd.args([
        "render",
        "--width",
        "400",
        "--height",
        "300",
        "--spp",
        "1",
        "--aovs",
        "all",
        "--threads",
        "2",
        "--stats",
        "stats.json",
        "-o",
        "out.exr",
    ])
    .current_dir(dir)
    .stdout(Stdio::null())
    .stderr(Stdio::null());
    cmd
}

/// Whether each output that exists is complete: the EXR reads with all its channels, the PNG decodes, the
/// statistics parse. Returns the outputs found.
fn check_outputs(dir: &Path, when: &str) -> usize {
    let mut found = 0;
    let exr = dir.join("out.exr");
    if exr.exists() {
        let layers = nimbus::output::read_exr_layers(&exr)
            .unwrap_or_else(|e| panic!("killed at {when}: torn EXR: {e}"));
        assert_eq!(
            (layers.width, layers.height),
            (400, 300),
            "killed at {when}"
        );
        assert!(layers.channels.len() > 90, "killed at {when}");
        found += 1;
    }
    let png = dir.join("out.png");
    if png.exists() {
        let bytes = std::fs::read(&png).unwrap();
        let img = image::load_from_memory(&bytes)
            .unwrap_or_else(|e| panic!("killed at {when}: torn PNG: {e}"));
        assert_eq!((img.width(), img.height()), (400, 300), "killed at {when}");
        found += 1;
    }
    let stats = dir.join("stats.json");
    if stats.exists() {
        let text = std::fs::read(&stats).unwrap();
        serde_json::from_slice::<serde_json::Value>(&text)
            .unwrap_or_else(|e| panic!("killed at {when}: torn statistics: {e}"));
        found += 1;
    }
    found
}

/// Runs the render in `dir` (emptied first); once its first file appears (the moment writing starts), kills it
/// with SIGKILL after `kill_after`, or lets it finish. Returns how long it ran after writing started.
fn run_watching_writes(dir: &Path, kill_after: Option<Duration>) -> Duration {
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        std::fs::remove_file(entry.path()).unwrap();
    }
    let mut child = render_command(dir).spawn().unwrap();
    while std::fs::read_dir(dir).unwrap().next().is_none() {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    let writing = Instant::now();
    match kill_after {
        Some(after) => {
            std::thread::sleep(after);
            let _ = child.kill(); // SIGKILL
            let _ = child.wait();
        }
        None => assert!(child.wait().unwrap().success()),
    }
    writing.elapsed()
}

#[test]
fn a_render_killed_while_it_writes_leaves_no_torn_file() {
    let dir = temp_dir("kill");
    // Kills spread over the writing of the three files, timed from one run to completion. On a busy machine the
    // writing may take longer or shorter than that run's, so that every kill lands after the end (or before
    // the first file): the series is then timed and run again, up to three times, so that the test never
    // passes without a kill inside the writing.
    let kills = 8;
    let mut hit = false;
    for series in 0..3 {
        let window = run_watching_writes(&dir, None);
        assert_eq!(check_outputs(&dir, "the end"), 3);
        let mut complete = 0;
        for k in 0..kills {
            let at = window.mul_f64(k as f64 / (kills - 1) as f64 * 1.1);
            run_watching_writes(&dir, Some(at));
            complete += check_outputs(
                &dir,
                &format!("{:.1} ms into writing", at.as_secs_f64() * 1e3),
            );
        }
        eprintln!(
            "series {series}: {kills} kills over {:.0} ms of writing: {complete} complete outputs found, no torn \
             file",
            window.as_secs_f64() * 1e3
        );
        if complete > 0 && complete < 3 * kills {
            hit = true;
            break;
        }
    }
    assert!(hit, "the kills missed the writing in three series");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A small tmpfs mounted on a fresh folder (root only), unmounted when dropped.
struct SmallDisk {
    dir: PathBuf,
}

impl SmallDisk {
    /// A tmpfs of `kib` KiB, or `None` (with a notice) where it cannot be mounted.
    fn mount(name: &str, kib: u32) -> Option<Self> {
        let dir = temp_dir(name);
        let mounted = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={kib}k"), "tmpfs"])
            .arg(&dir)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !mounted {
            eprintln!(
                "SKIP: cannot mount a tmpfs on {} (needs root)",
                dir.display()
            );
            return None;
        }
        Some(Self { dir })
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.dir).status();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[test]
fn a_full_disk_is_one_line_naming_the_file_and_leaves_no_partial_file() {
    let Some(disk) = SmallDisk::mount("full", 256) else {
        return;
    };
    // The EXR of every layer at 400x300 is several MiB: the disk fills while it is written.
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args([
            "render", "--width", "400", "--height", "300", "--spp", "1", "--aovs", "all",
        ])
        .args(["-o", "out.exr"])
        .current_dir(&disk.dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let error: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
    assert!(!out.status.success(), "{stderr}");
    assert_eq!(error.len(), 1, "{stderr}");
    assert!(
        error[0].contains("out.exr") && error[0].contains("No space"),
        "{stderr}"
    );
    let left: Vec<String> = std::fs::read_dir(&disk.dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert!(left.is_empty(), "files left on the full disk: {left:?}");
}

/// `--stats` naming the EXR or its PNG replaced the image with JSON (exit 0), and a `--stats` folder failed only
/// after the render (issue 36). Both are refused before anything is rendered, leaving an earlier image as it was.
#[test]
fn a_stats_path_that_is_the_image_or_a_folder_is_refused_before_the_render() {
    let dir = temp_dir("stats-paths");
    std::fs::create_dir_all(dir.join("folder")).unwrap();
    std::fs::write(dir.join("out.exr"), b"earlier image").unwrap();
    let cases = [
        ("out.exr", "names an image this render writes"),
        ("./out.png", "names an image this render writes"),
        ("folder", "is a folder"),
    ];
    for (stats, expect) in cases {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(["render", "--width", "8", "--height", "8", "--spp", "1"])
            .args(["--stats", stats, "-o", "out.exr"])
            .current_dir(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "--stats {stats}: {stderr}");
        assert!(stderr.contains(expect), "--stats {stats}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "--stats {stats}: {stderr}");
        assert!(!stderr.contains("rendered"), "--stats {stats}: {stderr}");
        assert_eq!(
            std::fs::read(dir.join("out.exr")).unwrap(),
            b"earlier image"
        );
        assert!(!dir.join("out.png").exists(), "--stats {stats}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A named pipe given as any input: the scene, a buffer, a texture, a material library, a VDB, an environment
/// map, `info`'s VDB, `merge`'s part and `converge`'s reference. Each was opened before its type was checked,
/// and opening a pipe with no writer blocks forever (issue 36, finding 10).
#[test]
fn a_named_pipe_as_any_input_is_a_one_line_error_not_a_hang() {
    let dir = temp_dir("fifo");
    for name in [
        "pipe.gltf",
        "pipe.bin",
        "pipe.png",
        "pipe.mtl",
        "pipe.vdb",
        "pipe.exr",
        "pipe.usda",
        "pipe.obj",
    ] {
        let made = Command::new("mkfifo").arg(dir.join(name)).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("skipped: mkfifo is not available");
            return;
        }
    }
    // One triangle whose buffer, texture, volume or environment map is the pipe.
    let triangle = "AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA";
    let gltf = |buffer: &str, extras: &str, material: &str| {
        let volume = if extras.contains("vdb") {
            r#",{"extras":{"nimbus_volume":{"file":"pipe.vdb"}}}"#
        } else {
            ""
        };
        let texture = if material.is_empty() {
            ""
        } else {
            r#","materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}],
            "textures":[{"source":0}],"images":[{"uri":"pipe.png"}]"#
        };
        let nodes = if volume.is_empty() { "[0]" } else { "[0,1]" };
        format!(
            r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":{nodes},"extras":{{{extras}}}}}],
            "nodes":[{{"mesh":0}}{volume}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}{material}}}]}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
                "min":[0,0,0],"max":[1,1,0]}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],
            "buffers":[{{"byteLength":36,"uri":"{buffer}"}}]{texture}}}"#
        )
    };
    let data = format!("data:application/octet-stream;base64,{triangle}");
    let scenes = [
        ("buffer.gltf", gltf("pipe.bin", "", "")),
        ("plain.gltf", gltf(&data, "", "")),
        ("texture.gltf", gltf(&data, "", r#","material":0"#)),
        (
            "environment.gltf",
            gltf(&data, r#""nimbus_environment":{"map":"pipe.exr"}"#, ""),
        ),
        ("volume.gltf", gltf(&data, r#""vdb":1"#, "")),
        (
            "library.obj",
            "mtllib pipe.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_owned(),
        ),
    ];
    for (name, text) in &scenes {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let render = |scene: &'static str| {
        vec![
            "render", scene, "--width", "4", "--height", "4", "--spp", "1", "-o", "out.exr",
        ]
    };
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (render("pipe.gltf"), "pipe.gltf"),
        (render("pipe.obj"), "pipe.obj"),
        (render("pipe.usda"), "pipe.usda"),
        (render("buffer.gltf"), "pipe.bin"),
        (render("texture.gltf"), "pipe.png"),
        (render("environment.gltf"), "pipe.exr"),
        (render("volume.gltf"), "pipe.vdb"),
        (render("library.obj"), "pipe.mtl"),
        (vec!["info", "pipe.vdb"], "pipe.vdb"),
        (vec!["info", "pipe.vdb", "--json"], "pipe.vdb"),
        (vec!["merge", "pipe.exr", "-o", "merged.exr"], "pipe.exr"),
        (
            vec![
                "converge",
                "plain.gltf",
                "--methods",
                "default,no-media-mis",
                "--reference",
                "pipe.exr",
                "-o",
                "chart",
            ],
            "pipe.exr",
        ),
    ];
    for (args, names) in cases {
        let mut child = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(&args)
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(20) {
                child.kill().unwrap();
                let _ = child.wait();
                panic!("{args:?} hung on a named pipe");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let output = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?}: {stderr}");
        let error: Vec<&str> = stderr.lines().filter(|l| l.contains("error")).collect();
        assert_eq!(error.len(), 1, "{args:?}: {stderr}");
        assert!(error[0].contains(names), "{args:?}: {stderr}");
        assert!(error[0].contains("named pipe"), "{args:?}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `nimbus info FILE --json | head -1` panicked with "failed printing to stdout: Broken pipe" (issue 36). A reader
/// that stops reading ends the output quietly: no panic, exit status 0.
#[test]
fn a_closed_standard_output_ends_the_listing_quietly() {
    let cloud = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cloud.vdb");
    let cases: [&[&str]; 3] = [
        &["info", cloud, "--json"],
        &["info", cloud],
        &["render", "--list-aovs"],
    ];
    for args in cases {
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(args)
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(output.status.success(), "{args:?}: {stderr}");
        assert!(stderr.is_empty(), "{args:?}: {stderr}");
    }
}

/// Usage errors are one line of printable ASCII naming the flag (issue 36, finding 11): negative numbers gave
/// 4-5-line usage errors, and clap's messages and ours printed "±", which the promise in docs/reference.md excludes.
#[test]
fn usage_errors_are_one_line_of_printable_ascii() {
    let dir = temp_dir("usage");
    let cases: [(&[&str], &str); 10] = [
        (&["merge"], "--output"),
        (&["render", "--seed", "-1"], "--seed"),
        (&["render", "--spp", "-3"], "--spp"),
        (&["render", "--threads", "-2"], "--threads"),
        (&["render", "--width", "-640"], "--width"),
        (&["render", "--shutter", "0,1e12"], "--shutter"),
        (&["render", "--exposure", "nan"], "--exposure"),
        (&["render", "--sp", "4"], "--spp"),
        (&["render", "--frames", "5..x"], "--frames"),
        (
            &["converge", "scene.gltf", "--budget", "-1", "-o", "c"],
            "--budget",
        ),
    ];
    for (args, flag) in cases {
        let output = Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(
            stderr.trim_end().bytes().all(|b| (0x20..0x7f).contains(&b)),
            "{args:?}: {stderr}"
        );
        assert!(
            !stderr.contains("\\x"),
            "our own text escaped: {args:?}: {stderr}"
        );
        assert!(stderr.contains(flag), "{args:?}: {stderr}");
        assert!(stderr.starts_with("nimbus: error: "), "{args:?}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
