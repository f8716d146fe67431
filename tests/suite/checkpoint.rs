//! Checkpoint and resume (`--checkpoint SECONDS`, `--resume`) and what a render stopped by a signal writes.
//!
//! The film sums exactly and every sample is a pure function of the seed, the pixel and the sample number, so a
//! render stopped at any moment (SIGTERM, SIGINT or SIGKILL), then resumed from its checkpoint, must write the
//! file of an uninterrupted render byte for byte (`SOURCE_DATE_EPOCH` keeps the time out of the header). The
//! kill times are random (a fixed seed), over the length of an uninterrupted render measured first.
//! `NIMBUS_KILL_TRIALS` sets the trials per signal and thread count (default 5: 20 kills in all).

use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// The tests of this file time renders and stop them: one at a time, so that their renders do not slow each
/// other's down.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-checkpoint-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A render of the bundled demo, small but with enough samples to be stopped part way.
fn render(dir: &Path, threads: u32, extra: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_nimbus"));
    let threads = threads.to_string();
    cmd.args([
        "render",
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "512",
        "--threads",
    ])
    .arg(&threads)
    .args(["-o", "out.exr"])
    .args(extra)
    .env("SOURCE_DATE_EPOCH", "0")
    .current_dir(dir)
    .stdout(Stdio::null())
    .stderr(Stdio::piped());
    cmd
}

/// Sends `signal` (`TERM`, `INT`, `KILL`) to process `pid`.
fn send(signal: &str, pid: u32) {
    let _ = Command::new("kill")
        .args([format!("-{signal}"), pid.to_string()])
        .status();
}

/// xorshift64*: the kill times.
struct Times(u64);

impl Times {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Starts `cmd`, sends `signal` after `after`, and waits for the process; returns its status and stderr.
fn run_and_stop(mut cmd: Command, signal: &str, after: Duration) -> (ExitStatus, String) {
    let child = cmd.spawn().unwrap();
    let pid = child.id();
    let start = Instant::now();
    let waiter = std::thread::spawn(move || child.wait_with_output().unwrap());
    while start.elapsed() < after && !waiter.is_finished() {
        std::thread::sleep(Duration::from_millis(2));
    }
    if !waiter.is_finished() {
        send(signal, pid);
    }
    let output = waiter.join().unwrap();
    (
        output.status,
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Times an uninterrupted render in `dir` on 2 threads, then renders with `extra` and sends `signal` at a half,
/// 30% and 15% of that time until a render is stopped before it finishes; returns that render's status and
/// stderr.
fn stop_part_way(dir: &Path, extra: &[&str], signal: &str) -> (ExitStatus, String) {
    let start = Instant::now();
    assert!(render(dir, 2, &[]).status().unwrap().success());
    let length = start.elapsed();
    std::fs::remove_file(dir.join("out.exr")).unwrap();
    for fraction in [0.5, 0.3, 0.15] {
        let (status, stderr) =
            run_and_stop(render(dir, 2, extra), signal, length.mul_f64(fraction));
        if !status.success() {
            return (status, stderr);
        }
    }
    panic!("every render finished before its SIG{signal}");
}

/// The exit status a stop by `signal` must give: 128 + the signal for SIGTERM and SIGINT (the CLI writes
/// what it has and exits), death by the signal for SIGKILL.
fn stopped_as_expected(status: ExitStatus, signal: &str) -> bool {
    use std::os::unix::process::ExitStatusExt;
    match signal {
        "TERM" => status.code() == Some(143),
        "INT" => status.code() == Some(130),
        _ => status.signal() == Some(9),
    }
}

#[test]
fn a_render_stopped_at_random_moments_resumes_to_the_uninterrupted_file_bit_for_bit() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let trials: usize = std::env::var("NIMBUS_KILL_TRIALS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(5);
    let reference_dir = temp_dir("reference");
    let start = Instant::now();
    let out = render(&reference_dir, 1, &[]).output().unwrap();
    let one_thread = start.elapsed();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let reference = std::fs::read(reference_dir.join("out.exr")).unwrap();
    let mut times = Times(0x9e37_79b9_7f4a_7c15);
    let mut report = Vec::new();
    for threads in [1, 2] {
        // Kill times spread over the uninterrupted render's length on this many threads.
        let length = one_thread.as_secs_f64() / threads as f64;
        for signal in ["TERM", "KILL"] {
            let (mut stopped, mut stopped_in_resumed, mut resumed_from_stopped_pass) = (0, 0, 0);
            for trial in 0..trials {
                let dir = temp_dir(&format!("{threads}-{signal}-{trial}"));
                let flags = ["--checkpoint", "0.02", "--resume"];
                // Every other trial is stopped twice: the second stop lands in a resumed render.
                for stop in 0..1 + trial % 2 {
                    // 5-65% of the way: a machine busier during the timing run than now still stops
                    // most renders part way.
                    let after = Duration::from_secs_f64(length * (0.05 + 0.6 * times.next()));
                    let (status, stderr) =
                        run_and_stop(render(&dir, threads, &flags), signal, after);
                    if status.success() {
                        // Finished before the stop: the last run below renders it again from the start.
                        std::fs::remove_file(dir.join("out.exr")).unwrap();
                        break;
                    }
                    assert!(
                        stopped_as_expected(status, signal),
                        "{threads} thread(s), SIG{signal} after {after:?}: {status:?}\n{stderr}"
                    );
                    stopped += 1;
                    stopped_in_resumed += stop;
                    assert!(
                        !dir.join("out.exr").exists(),
                        "a render stopped with a checkpoint wrote its final image"
                    );
                }
                let out = render(&dir, threads, &flags).output().unwrap();
                let stderr = String::from_utf8_lossy(&out.stderr);
                assert!(out.status.success(), "{stderr}");
                resumed_from_stopped_pass += stderr.contains("a pass stopped part way") as usize;
                assert!(
                    std::fs::read(dir.join("out.exr")).unwrap() == reference,
                    "{threads} thread(s), SIG{signal}, trial {trial}: the resumed file differs from the uninterrupted one\n{stderr}"
                );
                assert!(
                    !dir.join("out.checkpoint.exr").exists(),
                    "the checkpoint outlived the finished render"
                );
                let _ = std::fs::remove_dir_all(&dir);
            }
            report.push(format!(
                "{threads} thread(s), SIG{signal}: {trials} trials, {stopped} stops ({stopped_in_resumed} of them in resumed renders), {resumed_from_stopped_pass} resumes of a pass stopped part way, every file identical"
            ));
            // Kill times span the render, so most trials must have been stopped part way.
            assert!(
                stopped * 2 >= trials,
                "only {stopped} of {trials} renders were stopped before they finished"
            );
        }
    }
    eprintln!("{}", report.join("\n"));
    let _ = std::fs::remove_dir_all(&reference_dir);
}

#[test]
fn sigterm_without_checkpoint_writes_a_partial_image_marked_so_and_fails() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("partial");
    let (status, stderr) = stop_part_way(&dir, &["--stats", "stats.json"], "TERM");
    assert_eq!(status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("partial image out.exr"), "{stderr}");
    let meta = exr::meta::MetaData::read_from_file(dir.join("out.exr"), false).unwrap();
    let text = |key: &str| match meta.headers[0]
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from(key))
    {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{key}: {other:?}"),
    };
    assert_eq!(text("nimbus/partial"), "true");
    assert_eq!(text("nimbus/interrupted_by"), "SIGTERM");
    let spp: u32 = text("nimbus/spp").parse().unwrap();
    assert!(spp < 512);
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["partial"], true);
    assert_eq!(stats["interrupted_by"], "SIGTERM");
    assert_eq!(stats["samples_per_pixel"], spp);
    assert!(!dir.join("out.checkpoint.exr").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_checkpoint_of_another_render_is_refused_and_merge_refuses_checkpoints() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("mismatch");
    let (status, stderr) = stop_part_way(&dir, &["--checkpoint", "0.02"], "INT");
    assert_eq!(status.code(), Some(130), "{stderr}");
    assert!(dir.join("out.checkpoint.exr").exists());
    let out = render(&dir, 2, &["--resume", "--seed", "7"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("checkpoint out.checkpoint.exr: its scene hash")
            && stderr.contains("render without --resume"),
        "{stderr}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(["merge", "out.checkpoint.exr", "-o", "merged.exr"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("a checkpoint of an unfinished render"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes a glTF grid of `n × n` quads (2n² triangles) with its buffer beside it: a scene whose loading and
/// BVH build take a while, and whose render at a few pixels does not.
fn large_grid_scene(dir: &Path, n: u32) -> PathBuf {
    let mut buffer = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            for c in [i as f32 / n as f32, j as f32 / n as f32, 0.0] {
                buffer.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let positions = buffer.len();
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            for index in [a, a + 1, a + row, a + 1, a + row + 1, a + row] {
                buffer.extend_from_slice(&index.to_le_bytes());
            }
        }
    }
    std::fs::write(dir.join("grid.bin"), &buffer).unwrap();
    let vertices = row * row;
    let indices = 6 * n * n;
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0}},{{"camera":0,"translation":[0.5,0.5,2]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,"znear":0.1}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{vertices},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5125,"count":{indices},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{positions}}},
                       {{"buffer":0,"byteOffset":{positions},"byteLength":{}}}],
        "buffers":[{{"uri":"grid.bin","byteLength":{}}}]}}"#,
        buffer.len() - positions,
        buffer.len()
    );
    let path = dir.join("grid.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

/// A signal while the scene loads ends the process at once: nothing of the frame exists to be written, and a
/// long load (a large USD stage) would otherwise outlast a scheduler's grace period before it stops. Before,
/// the signal only cancelled the render, which began after the whole load and BVH build.
#[test]
fn a_signal_while_the_scene_loads_stops_the_process_at_once() {
    let _alone = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let dir = temp_dir("loading");
    let scene = large_grid_scene(&dir, 1200);
    let render = || {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_nimbus"));
        cmd.arg("render")
            .arg(&scene)
            .args([
                "--width", "4", "--height", "4", "--spp", "1", "-o", "out.exr",
            ])
            .current_dir(&dir)
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        cmd
    };
    let start = Instant::now();
    let out = render().output().unwrap();
    let length = start.elapsed();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        length > Duration::from_millis(1000),
        "the load must take a while for the test to mean anything: {length:?}"
    );
    std::fs::remove_file(dir.join("out.exr")).unwrap();
    let signal_at = length.mul_f64(0.3);
    let start = Instant::now();
    let (status, stderr) = run_and_stop(render(), "TERM", signal_at);
    let after_signal = start.elapsed().saturating_sub(signal_at);
    assert_eq!(status.code(), Some(143), "{stderr}");
    assert!(stderr.contains("while loading the scene"), "{stderr}");
    assert!(!dir.join("out.exr").exists());
    // The rest of the load took 70% of the uninterrupted run; stopping at once takes a few milliseconds.
    assert!(
        after_signal < length.mul_f64(0.25),
        "exited {after_signal:?} after the signal; the whole run takes {length:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
