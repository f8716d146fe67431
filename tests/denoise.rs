//! Denoising with Intel Open Image Denoise (feature `denoise`; docs/denoising.md).
//!
//! With the feature: the denoised 16-spp bundled demo (128x72) has at most 1/4 the relative MSE of the raw
//! 16-spp image against Mitsuba 3's render of it (`tests/denoise/reference_demo_128.exr`, made by
//! `tests/denoise/make_reference.py`), and `nimbus denoise` adds the `denoised` layer to a frame, keeping every
//! other channel. Those tests print a line and pass when the feature is off. Always: `--denoise` is refused for a
//! farm part, with the reason; without the feature, `--denoise` and `nimbus denoise` are refused with how to build
//! one that denoises.
//!
//! `.ci/run` builds the feature (OIDN from PyPI's pyoidn wheel) and runs this file with it.

use std::path::{Path, PathBuf};
use std::process::Command;

fn nimbus() -> Command {
    Command::new(env!("CARGO_BIN_EXE_nimbus"))
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-denoise-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Renders the bundled demo at 128x72 to `out` with `flags`; panics with stderr when it fails.
fn render_demo(out: &Path, spp: u32, flags: &[&str]) {
    let output = nimbus()
        .args(["render", "--width", "128", "--height", "72", "--spp"])
        .arg(spp.to_string())
        .arg("-o")
        .arg(out)
        .args(flags)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Asserts that the command behind `output` (`what`, for the message) failed with one line of stderr that
/// contains `reason`.
fn assert_refused_in_one_line(output: &std::process::Output, reason: &str, what: &str) {
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{what}");
    assert!(
        stderr.contains(reason) && stderr.lines().count() == 1,
        "{what}: {stderr}"
    );
}

/// Asserts that the refused commands left `dir` empty, then removes it.
fn assert_nothing_written(dir: &Path) {
    assert_eq!(
        std::fs::read_dir(dir).unwrap().count(),
        0,
        "nothing written"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// Relative MSE, the mean over pixels and channels of (x − ref)² / (ref² + 0.01).
fn rel_mse(x: &[f32], reference: &[f32]) -> f64 {
    assert_eq!(x.len(), reference.len());
    x.iter()
        .zip(reference)
        .map(|(&x, &r)| {
            let (x, r) = (f64::from(x), f64::from(r));
            (x - r).powi(2) / (r * r + 1e-2)
        })
        .sum::<f64>()
        / x.len() as f64
}

/// The channels `names` of `layers`, one after the other.
fn channels(layers: &nimbus::output::ExrLayers, names: [&str; 3]) -> Vec<f32> {
    names
        .iter()
        .flat_map(|n| {
            layers
                .channel(n)
                .unwrap_or_else(|| panic!("no channel {n}"))
                .to_vec()
        })
        .collect()
}

#[test]
fn the_denoised_16_spp_demo_has_a_quarter_of_the_raw_error_at_most() {
    if !cfg!(feature = "denoise") {
        eprintln!("skipped: built without the `denoise` feature (cargo test --features denoise --test denoise)");
        return;
    }
    let dir = folder("demo");
    let out = dir.join("demo16.exr");
    render_demo(&out, 16, &["--denoise"]);
    let image = nimbus::output::read_exr_layers(&out).unwrap();
    let reference = nimbus::output::read_exr_layers(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/denoise/reference_demo_128.exr"
    )))
    .unwrap();
    assert_eq!((reference.width, reference.height), (128, 72));
    let reference = channels(&reference, ["R", "G", "B"]);
    let raw = rel_mse(&channels(&image, ["R", "G", "B"]), &reference);
    let denoised = rel_mse(
        &channels(&image, ["denoised.R", "denoised.G", "denoised.B"]),
        &reference,
    );
    eprintln!(
        "demo 128x72, 16 spp: relative MSE raw {raw:.3e}, denoised {denoised:.3e} ({:.1}x less)",
        raw / denoised
    );
    assert!(
        denoised <= raw / 4.0,
        "denoised relative MSE {denoised:.3e} is more than 1/4 of the raw {raw:.3e}"
    );
    assert!(out.with_extension("png").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nimbus_denoise_adds_the_denoised_layer_and_keeps_the_rest() {
    if !cfg!(feature = "denoise") {
        eprintln!("skipped: built without the `denoise` feature (cargo test --features denoise --test denoise)");
        return;
    }
    let dir = folder("command");
    let frame = dir.join("frame.exr");
    render_demo(&frame, 4, &[]);
    let before = nimbus::output::read_exr_layers(&frame).unwrap();
    assert!(before.channel("denoised.R").is_none());
    let out = dir.join("out").join("denoised.exr");
    let output = nimbus()
        .arg("denoise")
        .arg(&frame)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    let after = nimbus::output::read_exr_layers(&out).unwrap();
    for (name, samples) in &before.channels {
        assert_eq!(after.channel(name), Some(samples.as_slice()), "{name}");
    }
    let denoised = channels(&after, ["denoised.R", "denoised.G", "denoised.B"]);
    assert!(denoised.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert_eq!(after.channels.len(), before.channels.len() + 3);
    assert!(out.with_extension("png").is_file());
    // Denoising the output again replaces its layer (the file may be its own input) and leaves no temporary.
    let again = nimbus()
        .arg("denoise")
        .arg(&out)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(again.status.success());
    assert_eq!(
        nimbus::output::read_exr_layers(&out)
            .unwrap()
            .channels
            .len(),
        after.channels.len()
    );
    let names: Vec<String> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.starts_with('.')),
        "temporaries left: {names:?}"
    );
    // A file without the auxiliary layers is refused, naming the missing channel.
    let bare = dir.join("bare.exr");
    render_demo(&bare, 1, &["--aovs", "none"]);
    let refused = nimbus()
        .arg("denoise")
        .arg(&bare)
        .arg("-o")
        .arg(dir.join("x.exr"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && stderr.contains("albedo.R"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn denoise_is_refused_for_a_farm_part_with_the_reason() {
    let dir = folder("part");
    for flags in [
        &["--samples", "0..2"][..],
        &["--crop", "0,0,8,8"][..],
        &["--chunk-from-env", "--chunks", "2"][..],
    ] {
        let output = nimbus()
            .args(["render", "--width", "16", "--spp", "4", "--denoise", "-o"])
            .arg(dir.join("part.exr"))
            .args(flags)
            .env("NIMBUS_TASK_INDEX", "0")
            .output()
            .unwrap();
        assert_refused_in_one_line(
            &output,
            "denoising runs after the merge",
            &format!("{flags:?}"),
        );
    }
    assert_nothing_written(&dir);
}

#[test]
fn without_the_feature_denoising_is_refused_with_how_to_build_it() {
    if cfg!(feature = "denoise") {
        eprintln!("skipped: built with the `denoise` feature");
        return;
    }
    let dir = folder("nofeature");
    let render = nimbus()
        .args(["render", "--width", "16", "--spp", "1", "--denoise", "-o"])
        .arg(dir.join("r.exr"))
        .output()
        .unwrap();
    let denoise = nimbus()
        .arg("denoise")
        .arg(dir.join("r.exr"))
        .arg("-o")
        .arg(dir.join("d.exr"))
        .output()
        .unwrap();
    for (output, what) in [(render, "render"), (denoise, "denoise")] {
        assert_refused_in_one_line(&output, "--features denoise", what);
    }
    assert_nothing_written(&dir);
}

#[test]
fn preview_every_rewrites_the_png_while_the_render_runs() {
    let dir = folder("preview");
    let exr = dir.join("long.exr");
    let png = exr.with_extension("png");
    let mut child = nimbus()
        .args([
            "render",
            "--width",
            "128",
            "--height",
            "72",
            "--spp",
            "256",
            "--preview-every",
            "0.001",
            "-o",
        ])
        .arg(&exr)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The final PNG follows the EXR; a PNG without the EXR is a preview written during the render.
    let mut seen_during = false;
    while child.try_wait().unwrap().is_none() {
        if png.is_file() && !exr.exists() {
            seen_during = true;
            let bytes = std::fs::read(&png).unwrap();
            assert!(
                bytes.starts_with(b"\x89PNG"),
                "a whole PNG, never a torn one"
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert!(child.wait().unwrap().success());
    assert!(seen_during, "no preview was written while the render ran");
    assert!(png.is_file() && exr.is_file());
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.starts_with('.')),
        "temporaries left: {names:?}"
    );
    // Not for a farm part: the preview is of the whole frame.
    let part = nimbus()
        .args(["render", "--width", "16", "--spp", "2", "--samples", "0..1"])
        .args(["--preview-every", "1", "-o"])
        .arg(dir.join("part.exr"))
        .output()
        .unwrap();
    assert!(!part.status.success());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The denoised layer equals, bit for bit, what OIDN's own Python bindings (PyPI's pyoidn) make of the same
/// beauty, albedo and normal with OIDN's documented prefiltering (an RT filter over each auxiliary alone, then
/// the beauty with `cleanAux`), and differs from OIDN's noisy-auxiliary mode: an independent check of the C API
/// calls in `src/denoise.rs`. Needs `NIMBUS_OIDN_PYTHON`, a Python with pyoidn, numpy and OpenEXR (`.ci/run` sets
/// it; under `NIMBUS_REQUIRE_TOOLS=1` its absence fails).
#[test]
fn the_denoised_layer_is_oidns_prefiltered_pipeline_bit_for_bit() {
    if !cfg!(feature = "denoise") {
        println!("skipped: built without the `denoise` feature");
        return;
    }
    let Ok(python) = std::env::var("NIMBUS_OIDN_PYTHON") else {
        assert!(
            std::env::var("NIMBUS_REQUIRE_TOOLS").as_deref() != Ok("1"),
            "NIMBUS_OIDN_PYTHON (a Python with pyoidn, numpy and OpenEXR) is required"
        );
        println!("skipped: NIMBUS_OIDN_PYTHON is not set");
        return;
    };
    let dir = folder("pyoidn");
    let exr = dir.join("demo.exr");
    render_demo(&exr, 16, &["--denoise"]);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/denoise/pyoidn_check.py");
    let out = Command::new(python)
        .arg(&script)
        .arg(&exr)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let figures: Vec<f64> = text
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert_eq!(figures.len(), 2, "{text}");
    assert_eq!(
        figures[0], 0.0,
        "differs from pyoidn's prefiltered pipeline: {text}"
    );
    assert!(
        figures[1] > 1e-3,
        "equal to the noisy-auxiliary mode: {text}"
    );
}
