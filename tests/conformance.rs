//! Conformance on real files: every scene file under `../shared/realworld/` (found by walking the folder, so a
//! new file is picked up) is loaded, lit as the CLI lights it, and rendered small. For each file the test
//! asserts that
//! - nothing panics (loading, building and rendering run on a thread of their own; a panic is a failure
//!   naming the file);
//! - every file loads (no file there uses an extension Nimbus refuses: Draco, meshopt and KTX2/Basis, whose
//!   refusal by name `tests/gltf_geometry.rs` checks);
//! - no sample is NaN or infinite (the renderer's `nan_samples` counter), and every channel of the image
//!   (beauty, albedo, normal, depth, variance) is finite;
//! - the image is not black: its mean luminance is at least [`MIN_MEAN_LUMINANCE`].
//!
//! Every file is tried before anything is asserted, and the failure lists every failing file at once.
//! `docs/conformance.md` has the per-file table (loads, renders, looks right, what is unsupported and why).

mod common;

use nimbus::light::EnvironmentLight;
use nimbus::math::{luminance, Rgb, Vec3};
use nimbus::render::{RenderImage, RenderSettings, RenderStats, Renderer};
use nimbus::scene::{load_builder, LoadOptions, DEFAULT_ENVIRONMENT_RADIANCE};
use std::path::{Path, PathBuf};

/// Scene files the loaders know by extension.
const SCENE_EXTENSIONS: [&str; 7] = ["gltf", "glb", "obj", "usd", "usda", "usdc", "usdz"];

/// Image size and samples: enough to see a NaN or a black frame, small enough for a 2-core CI machine.
const WIDTH: usize = 32;
const HEIGHT: usize = 32;
const SPP: u32 = 2;

/// The least mean beauty luminance (Rec.709 weights) of an image that is "not black": 1% of the default
/// environment's radiance, about 6.6 stops below a white sky.
const MIN_MEAN_LUMINANCE: f64 = 0.01;

/// Every scene file under `dir`, sorted, as paths relative to `dir` with `/` separators.
fn scene_files(dir: &Path) -> Vec<String> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<String>) {
        let entries = std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        for entry in entries {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(root, &path, out);
            } else if path
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| SCENE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            {
                let rel = path.strip_prefix(root).unwrap();
                let parts: Vec<_> = rel.iter().map(|p| p.to_string_lossy()).collect();
                out.push(parts.join("/"));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// What became of one file.
enum Outcome {
    /// The file did not load (or its scene did not build): the error text.
    LoadError(String),
    /// The file rendered.
    Rendered(Box<(RenderImage, RenderStats)>),
}

/// Loads `path`, lights it as `nimbus render` does when it has no light, and renders it small. A render error is
/// an `Err`; a load or build error is an [`Outcome::LoadError`].
fn render_file(path: &Path) -> Result<Outcome, String> {
    let mut builder = match load_builder(path, &LoadOptions::default()) {
        Ok(b) => b,
        Err(e) => return Ok(Outcome::LoadError(e.to_string())),
    };
    // As `render` in src/main.rs: a scene that does not light itself gets a uniform white environment.
    if !builder.has_own_lighting() {
        builder.set_environment(EnvironmentLight::Constant(Rgb::splat(
            DEFAULT_ENVIRONMENT_RADIANCE,
        )));
    }
    let scene = match builder.build() {
        Ok(s) => s,
        Err(e) => return Ok(Outcome::LoadError(e.to_string())),
    };
    let settings = RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        spp: SPP,
        seed: 1,
        threads: 0,
        max_depth: scene.max_bounces().unwrap_or(64),
        ..RenderSettings::default()
    };
    Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .map(|r| Outcome::Rendered(Box::new(r)))
        .map_err(|e| format!("render error: {e}"))
}

/// The problems with one file's outcome, if any (empty when it conforms).
fn check(file: &str, outcome: Outcome) -> Vec<String> {
    let (image, stats) = match outcome {
        Outcome::LoadError(e) => return vec![format!("load error: {e}")],
        Outcome::Rendered(r) => *r,
    };
    let mut problems = Vec::new();
    if stats.nan_samples != 0 {
        problems.push(format!("{} NaN/Inf samples", stats.nan_samples));
    }
    let flat = |v: &[Vec3]| v.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>();
    let channels: [(&str, Vec<f32>); 5] = [
        ("beauty", flat(&image.beauty)),
        ("albedo", flat(&image.albedo)),
        ("normal", flat(&image.normal)),
        ("depth", image.depth.clone()),
        ("variance", flat(&image.variance)),
    ];
    for (name, values) in &channels {
        let bad = values.iter().filter(|v| !v.is_finite()).count();
        if bad > 0 {
            problems.push(format!("{bad} non-finite values in the {name} channel"));
        }
    }
    let luminance = image
        .beauty
        .iter()
        .map(|&p| luminance(p) as f64)
        .sum::<f64>()
        / image.pixel_count() as f64;
    eprintln!("{file}: mean luminance {luminance:.4}");
    if luminance.is_nan() || luminance < MIN_MEAN_LUMINANCE {
        problems.push(format!(
            "black image: mean luminance {luminance:.5} < {MIN_MEAN_LUMINANCE}"
        ));
    }
    problems
}

#[test]
fn every_realworld_file_loads_and_renders_finite_and_lit() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("realworld");
    if !dir.is_dir() {
        assert!(
            std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() != Ok("1"),
            "{} is missing and NIMBUS_REQUIRE_SHARED=1",
            dir.display()
        );
        eprintln!("SKIP: {} not found", dir.display());
        return;
    }
    let files = scene_files(&dir);
    assert!(!files.is_empty(), "no scene files under {}", dir.display());

    let mut failures = Vec::new();
    for file in &files {
        let path: PathBuf = dir.join(file);
        let outcome = std::thread::Builder::new()
            .name(file.clone())
            .stack_size(8 << 20)
            .spawn(move || render_file(&path))
            .expect("spawn a thread")
            .join();
        let problems = match outcome {
            Err(panic) => {
                let message = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                vec![format!("panicked: {message}")]
            }
            Ok(Err(e)) => vec![e],
            Ok(Ok(outcome)) => check(file, outcome),
        };
        failures.extend(problems.into_iter().map(|p| format!("{file}: {p}")));
    }
    assert!(
        failures.is_empty(),
        "{} problems in {} files:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}
