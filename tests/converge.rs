//! `nimbus converge` end to end on the bundled constant-density VDB grid: a reference is rendered, every method
//! gets at least six checkpoints, and the CSV, chart and summary are written.

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

/// Mean of the beauty over the image and channels.
fn mean(image: &nimbus::render::RenderImage) -> f64 {
    let sum: f64 = image.beauty.iter().map(|p| (p.x + p.y + p.z) as f64).sum();
    sum / (3 * image.beauty.len()) as f64
}

#[test]
fn light_sampling_only_in_media_and_overridden_majorants_agree_with_the_default() {
    use nimbus::converge::Method;
    use nimbus::render::{RenderSettings, Renderer};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/constant_grid.gltf");
    let render = |method: Method| {
        let scene = nimbus::scene::load_builder_with(&path, &|s| method.apply_to_volume(s))
            .unwrap()
            .build();
        let settings = RenderSettings {
            width: 16,
            height: 16,
            spp: 128,
            seed: 3,
            threads: 2,
            media_mis: method.media_mis(),
            ..RenderSettings::default()
        };
        let (image, _) = Renderer::new(settings)
            .render(&scene, &mut |_| true)
            .unwrap();
        (mean(&image), scene.media[0].method())
    };
    let (base, _) = render(Method::Default);
    let (global, how) = render(Method::GlobalMajorant);
    assert!(how.to_lowercase().contains("global"), "{how}");
    let (no_mis, _) = render(Method::NoMediaMis);
    for (name, m) in [("global-majorant", global), ("no-media-mis", no_mis)] {
        assert!(
            (m - base).abs() < 0.02 * base,
            "{name}: {m} vs default {base}"
        );
    }
}
