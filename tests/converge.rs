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
