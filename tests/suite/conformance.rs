//! Conformance on real files: every scene file under `../shared/realworld/` (found by walking the folder, so a
//! new file is picked up) is loaded, lit as the CLI lights it, and rendered small. For each file the test
//! asserts that
//! - nothing panics (loading, building and rendering run on a thread of their own; a panic is a failure
//!   naming the file);
//! - every file loads (no file there uses an extension Nimbus refuses: Draco, meshopt and KTX2/Basis, whose
//!   refusal by name `tests/suite/gltf_geometry.rs` checks);
//! - no sample is NaN or infinite (the renderer's `nan_samples` counter), and every channel of the image
//!   (beauty, albedo, normal, depth, variance) is finite;
//! - the image is not black: its mean luminance is at least [`MIN_MEAN_LUMINANCE`].
//!
//! Each file is a test of its own (`conformance_cases!`), so one failing file hides no other, and a test checks
//! that the folder holds exactly the files the cases list.
//! `docs/conformance.md` has the per-file table (loads, renders, looks right, what is unsupported and why).

use crate::common;

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

/// The realworld folder, or `None` (the test skips) when `../shared` or its `realworld/` is missing and not
/// required.
fn realworld_dir() -> Option<PathBuf> {
    let dir = common::shared_dir()?.join("realworld");
    if !dir.is_dir() {
        assert!(
            std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() != Ok("1"),
            "{} is missing and NIMBUS_REQUIRE_SHARED=1",
            dir.display()
        );
        eprintln!("SKIP: {} not found", dir.display());
        return None;
    }
    Some(dir)
}

/// Loads, renders and checks one file (relative to the realworld folder) on a thread of its own, so that a panic
/// is reported as this file's failure; fails listing every problem found.
fn conform(file: &str) {
    let Some(dir) = realworld_dir() else {
        return;
    };
    let path: PathBuf = dir.join(file);
    let outcome = std::thread::Builder::new()
        .name(file.to_owned())
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
    assert!(
        problems.is_empty(),
        "{file}: {} problems:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

/// One test per realworld file (so that one failing file hides no other), and the list they make.
macro_rules! conformance_cases {
    ($($test:ident => $file:literal,)*) => {
        $(
            #[test]
            fn $test() {
                conform($file);
            }
        )*

        /// Every file the tests above cover, relative to the realworld folder.
        const CASES: &[&str] = &[$($file),*];
    };
}

conformance_cases! {
    box_gltf => "gltf/Box/Box.gltf",
    box_textured_gltf => "gltf/BoxTextured/BoxTextured.gltf",
    box_vertex_colors_gltf => "gltf/BoxVertexColors/BoxVertexColors.gltf",
    cameras_gltf => "gltf/Cameras/Cameras.gltf",
    clear_coat_test_gltf => "gltf/ClearCoatTest/ClearCoatTest.gltf",
    damaged_helmet_gltf => "gltf/DamagedHelmet/DamagedHelmet.gltf",
    duck_gltf => "gltf/Duck/Duck.gltf",
    morph_primitives_test_gltf => "gltf/MorphPrimitivesTest/MorphPrimitivesTest.gltf",
    normal_tangent_test_gltf => "gltf/NormalTangentTest/NormalTangentTest.gltf",
    simple_sparse_accessor_gltf => "gltf/SimpleSparseAccessor/SimpleSparseAccessor.gltf",
    texture_coordinate_test_gltf => "gltf/TextureCoordinateTest/TextureCoordinateTest.gltf",
    texture_settings_test_gltf => "gltf/TextureSettingsTest/TextureSettingsTest.gltf",
    texture_transform_test_gltf => "gltf/TextureTransformTest/TextureTransformTest.gltf",
    blender_01_alpha_blend_gltf => "gltf/blender-io-01_alpha_blend/01_alpha_blend.gltf",
    blender_01_alpha_mask_gltf => "gltf/blender-io-01_alpha_mask/01_alpha_mask.gltf",
    blender_15_transmission_gltf => "gltf/blender-io-15_transmission/15_transmission.gltf",
    blender_16_volume_gltf => "gltf/blender-io-16_volume/16_volume.gltf",
    blender_17_ior_gltf => "gltf/blender-io-17_ior/17_ior.gltf",
    blender_20_specular_gltf => "gltf/blender-io-20_specular/20_specular.gltf",
    spider_obj => "obj/spider/spider.obj",
    box_animated_usdz => "usd/BoxAnimated/BoxAnimated.usdz",
    mc_usd_usda => "usd/McUsd/McUsd.usda",
    normals_texture_bias_and_scale_usda => "usd/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda",
    normals_texture_bias_and_scale_usdz => "usd/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usdz",
    roughness_test_usdz => "usd/RoughnessTest/RoughnessTest.usdz",
}

/// A scene file added to `../shared/realworld/` (or removed from it) must get (or lose) its test above: the
/// walked folder and the list agree.
#[test]
fn every_realworld_file_has_its_own_test() {
    let Some(dir) = realworld_dir() else {
        return;
    };
    let mut listed: Vec<String> = CASES.iter().map(|f| f.to_string()).collect();
    listed.sort();
    assert_eq!(
        scene_files(&dir),
        listed,
        "the scene files under {} and the conformance cases differ",
        dir.display()
    );
}
