//! `nimbus converge` end to end on the bundled constant-density VDB grid: a reference is rendered, every method
//! gets at least six checkpoints, and the CSV, chart and summary are written.

use nimbus::volume::majorant::MajorantKind;
use std::path::Path;

#[test]
fn converge_writes_csv_chart_and_summary() {
    let dir = std::env::temp_dir().join(format!("nimbus_converge_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/constant_grid.gltf");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("converge")
        .arg(&scene)
        .args([
            "--budget",
            "0.5",
            "--width",
            "16",
            "--height",
            "16",
            "--threads",
            "2",
        ])
        .arg("-o")
        .arg(&dir)
        .status()
        .unwrap();
    assert!(status.success());
    let csv = std::fs::read_to_string(dir.join("convergence.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("method,spp,seconds,rmse,relmse,bias"));
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    for method in nimbus::converge::Method::ALL {
        let mine: Vec<_> = rows.iter().filter(|r| r[0] == method.name()).collect();
        assert!(mine.len() >= 6, "{method}: {} rows", mine.len());
        assert_eq!(mine[0][1], "1");
        for r in &mine {
            assert_eq!(r.len(), 6);
            assert!(r[3].parse::<f64>().unwrap().is_finite());
        }
    }
    for file in [
        "convergence.png",
        "convergence.svg",
        "summary.md",
        "reference.exr",
    ] {
        assert!(dir.join(file).is_file(), "{file} missing");
    }
    // The reference given back: same size, no re-render.
    let again = dir.join("again");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("converge")
        .arg(&scene)
        .arg("--reference")
        .arg(dir.join("reference.exr"))
        .args(["--methods", "default,no-media-mis", "--budget", "0.2", "-o"])
        .arg(&again)
        .status()
        .unwrap();
    assert!(status.success());
    assert!(!again.join("reference.exr").exists());
    let summary = std::fs::read_to_string(again.join("summary.md")).unwrap();
    assert!(summary.contains("| default |") && summary.contains("| no-media-mis |"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Mean of the beauty's green channel over the image, and its standard error from the variance layer.
///
/// One channel only: the channels of one path are correlated (fully, in a grey medium), so summing their
/// variances would understate the spread of a channel sum by up to √3. Pixels are independent, so their
/// variances of the mean add. Measured on this scene over 24 seeds: spread of means / reported s.e. = 1.05.
fn mean_and_se(image: &nimbus::render::RenderImage) -> (f64, f64) {
    let n = image.beauty.len() as f64;
    let sum: f64 = image.beauty.iter().map(|p| p.y as f64).sum();
    let var: f64 = image.variance.iter().map(|v| v.y as f64).sum();
    (sum / n, var.sqrt() / n)
}

/// Loads `path` with `method`'s volume override, through the one load path every format shares; returns the
/// scene and how many volume declarations the override saw.
fn load_with_method(path: &Path, method: nimbus::converge::Method) -> (nimbus::Scene, usize) {
    let seen = std::cell::Cell::new(0);
    let apply = |s: &mut nimbus::volume::VolumeSpec| {
        seen.set(seen.get() + 1);
        method.apply_to_volume(s);
    };
    let options = nimbus::scene::LoadOptions {
        volume_override: Some(nimbus::scene::VolumeOverride::new(&apply)),
        ..Default::default()
    };
    let scene = nimbus::scene::load_builder(path, &options)
        .unwrap()
        .build()
        .unwrap();
    (scene, seen.get())
}

#[test]
fn light_sampling_only_in_media_and_overridden_majorants_agree_with_the_default() {
    use nimbus::converge::Method;
    use nimbus::render::{RenderSettings, Renderer};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/constant_grid.gltf");
    let render = |method: Method, seed: u64| {
        let (scene, volumes) = load_with_method(&path, method);
        assert_eq!(volumes, 1);
        let settings = RenderSettings {
            width: 16,
            height: 16,
            spp: 128,
            seed,
            threads: 2,
            media_mis: method.media_mis(),
            ..RenderSettings::default()
        };
        let (image, _) = Renderer::new(settings)
            .render(&scene, &mut |_| true)
            .unwrap();
        (mean_and_se(&image), scene.media()[0].method().majorant)
    };
    // Independent seeds, so that the standard errors of the differences combine.
    let ((base, base_se), _) = render(Method::Default, 1);
    let (global, majorant) = render(Method::GlobalMajorant, 2);
    assert_eq!(majorant, Some(MajorantKind::Global));
    let (no_mis, _) = render(Method::NoMediaMis, 3);
    for (name, (m, se)) in [("global-majorant", global), ("no-media-mis", no_mis)] {
        let combined = (se * se + base_se * base_se).sqrt();
        assert!(
            (m - base).abs() <= 4.0 * combined,
            "{name}: {m} ± {se} vs default {base} ± {base_se}"
        );
    }
}

/// The volume override reaches USD volumes too (it used to apply to glTF only, so `converge` on a USD stage
/// rendered every method identically), and `converge` refuses a method that changes volumes on a scene that
/// has none instead of charting identical curves.
#[test]
fn converge_methods_reach_usd_volumes_and_need_a_volume() {
    use nimbus::converge::Method;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let stage = root.join("tests/usd/volume.usda");
    let (scene, volumes) = load_with_method(&stage, Method::GlobalMajorant);
    assert_eq!(volumes, 1, "the override saw the USD Volume prim");
    let majorant = scene.media()[0].method().majorant;
    assert_eq!(majorant, Some(MajorantKind::Global));
    let (scene, _) = load_with_method(&stage, Method::AdaptiveMajorant);
    let majorant = scene.media()[0].method().majorant;
    assert_eq!(majorant, Some(MajorantKind::Adaptive));

    let dir = std::env::temp_dir().join(format!("nimbus_converge_usd_{}", std::process::id()));
    let run = |scene: &Path, out: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("converge")
            .arg(scene)
            .args([
                "--methods",
                "default,global-majorant",
                "--budget",
                "0.3",
                "--width",
                "8",
                "--height",
                "8",
                "-o",
            ])
            .arg(out)
            .output()
            .unwrap()
    };
    let usd = run(&stage, &dir.join("usd"));
    assert!(
        usd.status.success(),
        "{}",
        String::from_utf8_lossy(&usd.stderr)
    );
    let surfaces = root.join("tests/usd/cornell.usda");
    let refused = run(&surfaces, &dir.join("cornell"));
    assert!(!refused.status.success());
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(
        message.contains("global-majorant") && message.contains("has none"),
        "{message}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A reference with NaN pixels gave RMSE 0 for every method (issue 36): the comparison skipped what it could not
/// subtract. A reference must be finite everywhere; one that is not is refused, naming the file and the pixel.
#[test]
fn a_reference_that_is_not_finite_is_refused() {
    let dir = std::env::temp_dir().join(format!("nimbus_converge_nan_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/constant_grid.gltf");
    for (name, bad) in [("all-nan.exr", None), ("one-inf.exr", Some((3, 2)))] {
        let reference = dir.join(name);
        exr::prelude::write_rgb_file(&reference, 16, 16, |x, y| match bad {
            None => (f32::NAN, f32::NAN, f32::NAN),
            Some(at) if (x, y) == at => (0.5, f32::INFINITY, 0.5),
            Some(_) => (0.5, 0.5, 0.5),
        })
        .unwrap();
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("converge")
            .arg(&scene)
            .arg("--reference")
            .arg(&reference)
            .args(["--methods", "default", "--budget", "0.2", "-o"])
            .arg(dir.join("out"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{name}: {stderr}");
        assert!(stderr.contains(name), "{name}: {stderr}");
        let pixel = if bad.is_some() { "(3, 2)" } else { "(0, 0)" };
        assert!(stderr.contains(pixel), "{name}: {stderr}");
        assert!(!dir.join("out/convergence.csv").exists(), "{name}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
