//! Transform motion blur (issue 17, "Shots"): glTF nodes, USD xforms and cameras animated across the shutter
//! (`LoadOptions::shutter`, `--shutter`), checked against the closed-form share of the shutter during which a
//! moving quad covers a fixed camera ray (or a moving camera's ray meets a fixed quad).
//!
//! The scenes are built here: an unlit black quad in front of a white environment seen through a 1×1 image
//! with a field of view of 10⁻⁴ rad, so every camera ray is (to 10⁻⁴ of the quad's motion) the same ray and a
//! pixel's value is 1 − the fraction of its samples' times at which the quad covers it. Each sample is a
//! Bernoulli trial, and the film's variance of the mean gives the standard error the tolerances use (4 s.e.).

use crate::common;

use nimbus::frames::Shutter;
use nimbus::math::Vec2;
use nimbus::render::{RenderImage, RenderSettings, Renderer};
use nimbus::scene::{load_builder, LoadOptions, Scene};
use std::path::{Path, PathBuf};

/// Speed of the animated node: from x = −48 at 0 s to x = 48 at 1 s, 96 units a second, or 4 units a frame at
/// the default 24 fps; at frame 12 (0.5 s) it is at x = 0.
const TRACK: f32 = 48.0;

/// What the test scene holds.
struct Setup {
    /// The quad spans x ∈ [quad_x, quad_x + 1] (y ∈ [−½, ½], z = 0) when its node is at the origin.
    quad_x: f32,
    /// Whether the quad's node translates along the track.
    quad_moves: bool,
    /// The camera's x (it looks down −z from z = 5).
    camera_x: f32,
    /// Whether the camera's node translates along the track (offset by `camera_x`).
    camera_moves: bool,
    /// Vertical field of view (radians).
    yfov: f32,
    /// True: the quad is unlit black; false: a grey diffuse surface.
    unlit: bool,
}

/// Writes the scene `setup` describes (see the module documentation) as a glTF file in `dir`.
fn write_scene(dir: &Path, name: &str, setup: &Setup) -> PathBuf {
    let (x0, x1) = (setup.quad_x, setup.quad_x + 1.0);
    let cx = setup.camera_x;
    let floats: Vec<f32> = [
        // Two triangles (offset 0, 72 bytes), counter-clockwise seen from +z.
        x0,
        -0.5,
        0.0,
        x1,
        -0.5,
        0.0,
        x1,
        0.5,
        0.0,
        x0,
        -0.5,
        0.0,
        x1,
        0.5,
        0.0,
        x0,
        0.5,
        0.0,
        // Key times 0 s and 1 s (offset 72).
        0.0,
        1.0, // The quad's translations (offset 80).
        -TRACK,
        0.0,
        0.0,
        TRACK,
        0.0,
        0.0, // The camera's translations (offset 104).
        cx - TRACK,
        0.0,
        5.0,
        cx + TRACK,
        0.0,
        5.0,
    ]
    .to_vec();
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let mut channels = Vec::new();
    if setup.quad_moves {
        channels.push(r#"{"sampler":0,"target":{"node":0,"path":"translation"}}"#);
    }
    if setup.camera_moves {
        channels.push(r#"{"sampler":1,"target":{"node":1,"path":"translation"}}"#);
    }
    // An animation that moves nothing in view keeps the file animated when neither the quad nor the camera
    // moves (node 2 is an empty).
    channels.push(r#"{"sampler":0,"target":{"node":2,"path":"translation"}}"#);
    let material = if setup.unlit {
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0,0,0,1]},"extensions":{"KHR_materials_unlit":{}}}"#
    } else {
        r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0,"roughnessFactor":1}}"#
    };
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"extensionsUsed":["KHR_materials_unlit"],
        "scenes":[{{"nodes":[0,1,2],"extras":{{"nimbus_environment":{{"color":[1,1,1]}}}}}}],
        "nodes":[{{"mesh":0}},{{"camera":0,"translation":[{cx},0,5]}},{{"name":"empty"}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":{yfov},"aspectRatio":1.0,"znear":0.01}}}}],
        "materials":[{material}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"material":0}}]}}],
        "buffers":[{{"byteLength":{len},"uri":"data:application/octet-stream;base64,{b64}"}}],
        "bufferViews":[{{"buffer":0,"byteLength":{len}}}],
        "accessors":[
          {{"bufferView":0,"byteOffset":0,"componentType":5126,"count":6,"type":"VEC3","min":[{x0},-0.5,0],"max":[{x1},0.5,0]}},
          {{"bufferView":0,"byteOffset":72,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]}},
          {{"bufferView":0,"byteOffset":80,"componentType":5126,"count":2,"type":"VEC3"}},
          {{"bufferView":0,"byteOffset":104,"componentType":5126,"count":2,"type":"VEC3"}}],
        "animations":[{{"samplers":[{{"input":1,"output":2}},{{"input":1,"output":3}}],
          "channels":[{channels}]}}]}}"#,
        yfov = setup.yfov,
        channels = channels.join(","),
        len = bytes.len(),
        b64 = common::base64(&bytes)
    );
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, gltf).unwrap();
    path
}

/// A fresh folder for one test's files.
fn test_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-motion-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The scene at frame 12 (default 24 fps) with `shutter`.
fn load(path: &Path, shutter: Option<Shutter>) -> Scene {
    let mut builder = load_builder(
        path,
        &LoadOptions {
            frame: Some(12),
            shutter,
            ..LoadOptions::default()
        },
    )
    .unwrap();
    builder.set_max_bounces(4);
    builder.build().unwrap()
}

/// Renders `scene` at `size`² with `spp` samples and a fixed seed, on two threads.
fn render(scene: &Scene, size: usize, spp: u32) -> RenderImage {
    let settings = RenderSettings {
        width: size,
        height: size,
        spp,
        seed: 7,
        threads: 2,
        max_depth: 4,
        ..Default::default()
    };
    Renderer::new(settings)
        .render(scene, &mut |_| true)
        .unwrap()
        .0
}

/// The fraction of the one pixel's samples at which the black quad covers it (1 − its value), and the standard
/// error of that fraction.
fn coverage(scene: &Scene, spp: u32) -> (f64, f64) {
    let img = render(scene, 1, spp);
    let (mean, se) = common::mean_and_se(&img, 0);
    (1.0 - mean, se)
}

/// Asserts that `scene`'s one pixel is covered for the analytic share `expect` of the shutter, within 4 standard
/// errors of 8192 samples, and prints the figures under `what`.
fn assert_covered_share(scene: &Scene, expect: f64, what: &str) {
    let (fraction, se) = coverage(scene, 8192);
    eprintln!("{what}: covered {fraction:.5} ± {se:.5} of the shutter, analytic {expect:.5}");
    assert!(
        se > 0.0 && (fraction - expect).abs() < 4.0 * se,
        "{what}: {fraction} ± {se} vs {expect}"
    );
}

fn shutter(open: f32, close: f32) -> Option<Shutter> {
    Some(Shutter { open, close })
}

/// The quad x ∈ [0, 1] moves 4 units a frame; over the shutter [−¼, ½] frame its offset runs over [−1, 2]. A
/// ray down −z at x = −0.5 is covered while the offset is in [−1.5, −0.5], i.e. for [−1, −0.5]: 1/6 of the
/// shutter. Without a shutter the quad is at its frame pose, x ∈ [0, 1], which the ray misses; a ray at
/// x = 0.5 is covered.
#[test]
fn a_translating_quad_covers_a_ray_for_its_analytic_share_of_the_shutter() {
    let dir = test_dir("quad");
    let setup = |camera_x| Setup {
        quad_x: 0.0,
        quad_moves: true,
        camera_x,
        camera_moves: false,
        yfov: 1e-4,
        unlit: true,
    };
    let path = write_scene(&dir, "quad", &setup(-0.5));
    let blurred = load(&path, shutter(-0.25, 0.5));
    assert_eq!(blurred.moving_triangle_count(), 2);
    assert_covered_share(&blurred, 1.0 / 6.0, "moving quad");

    let still = load(&path, None);
    assert_eq!(still.moving_triangle_count(), 0);
    assert_eq!(
        coverage(&still, 64),
        (0.0, 0.0),
        "the frame pose misses the ray"
    );
    let hit = load(&write_scene(&dir, "quad-hit", &setup(0.5)), None);
    assert_eq!(coverage(&hit, 64).0, 1.0, "the frame pose covers x = 0.5");
    std::fs::remove_dir_all(dir).ok();
}

/// A camera moving 4 units a frame along x over a fixed quad x ∈ [0.25, 1.25]: over the shutter [−¼, ½] it
/// is at x ∈ [−1, 2], over the quad for [0.25, 1.25], 1/3 of the shutter. Its rays start at the lerp of its
/// poses. Without the shutter it is at x = 0, beside the quad.
#[test]
fn a_translating_camera_sees_a_fixed_quad_for_its_analytic_share_of_the_shutter() {
    let dir = test_dir("camera");
    let path = write_scene(
        &dir,
        "camera",
        &Setup {
            quad_x: 0.25,
            quad_moves: false,
            camera_x: 0.0,
            camera_moves: true,
            yfov: 1e-4,
            unlit: true,
        },
    );
    let blurred = load(&path, shutter(-0.25, 0.5));
    assert_eq!(blurred.moving_triangle_count(), 0, "the quad stands still");
    let camera = blurred.camera();
    assert!(camera.motion.is_some());
    for time in [-0.25f32, -0.1, 0.0, 0.3, 0.5] {
        let ray = camera.generate_ray_at(Vec2::splat(0.5), 1.0, time);
        // 4 units a frame; the steps lie on the straight track, so the lerp between them is exact.
        assert!(
            (ray.origin.x - 4.0 * time).abs() < 1e-4 && (ray.origin.z - 5.0).abs() < 1e-5,
            "t = {time}: {}",
            ray.origin
        );
        assert_eq!(ray.time, time);
    }
    assert_covered_share(&blurred, 1.0 / 3.0, "moving camera");

    let still = load(&path, None);
    assert!(still.camera().motion.is_none());
    assert_eq!(
        coverage(&still, 64),
        (0.0, 0.0),
        "at x = 0 the camera misses the quad"
    );
    std::fs::remove_dir_all(dir).ok();
}

/// With a wide view of a moving quad, the blurred render differs from the still one only where the quad
/// passes: pixels the quad never reaches across the shutter are the same bit for bit.
#[test]
fn blur_changes_only_the_pixels_the_motion_sweeps() {
    let dir = test_dir("sweep");
    let path = write_scene(
        &dir,
        "sweep",
        &Setup {
            quad_x: -0.5,
            quad_moves: true,
            camera_x: 0.0,
            camera_moves: false,
            yfov: 1.2,
            unlit: true,
        },
    );
    let size = 64;
    let still = render(&load(&path, None), size, 32);
    let blurred = render(&load(&path, shutter(-0.2, 0.2)), size, 32);
    // The quad x ∈ [−0.5, 0.5] moves by ±0.8: it sweeps x ∈ [−1.3, 1.3] at z = 0, 5 units from the camera.
    let tan_half = (0.6f32).tan();
    let column_x = |c: usize| ((c as f32 + 0.5) / size as f32 * 2.0 - 1.0) * tan_half * 5.0;
    let row_y = |r: usize| (1.0 - (r as f32 + 0.5) / size as f32 * 2.0) * tan_half * 5.0;
    let (mut changed_inside, mut inside) = (0, 0);
    for r in 0..size {
        for c in 0..size {
            let (x, y) = (column_x(c), row_y(r));
            let (a, b) = (still.beauty[r * size + c], blurred.beauty[r * size + c]);
            // A margin of more than a pixel's footprint (0.11 units) around the swept region and the quad.
            let far_outside = x.abs() > 1.3 + 0.25 || y.abs() > 0.5 + 0.25;
            let in_the_wake = x.abs() > 0.5 + 0.25 && x.abs() < 1.3 - 0.25 && y.abs() < 0.5 - 0.25;
            if far_outside {
                assert_eq!(a, b, "pixel ({c}, {r}) at ({x}, {y}) is never swept");
            }
            if in_the_wake {
                inside += 1;
                changed_inside += (a != b) as usize;
                // Still, the quad is not there: the white environment.
                assert_eq!(a[0], 1.0, "pixel ({c}, {r})");
            }
        }
    }
    // A wake pixel is covered for 16–34 % of the shutter, so a few of its 32 samples see the quad; a pixel
    // whose samples all miss it is rare (at most 0.84³² ≈ 0.4 %).
    assert!(
        inside > 20 && changed_inside * 10 >= inside * 9,
        "{changed_inside} of {inside} swept pixels changed"
    );
    std::fs::remove_dir_all(dir).ok();
}

/// A still scene (its animation moves only an empty) renders bit for bit the same with a shutter as without:
/// static meshes get no motion, the static hierarchy is the same, and the shutter's times come from a stream
/// of their own.
#[test]
fn a_still_scene_renders_the_same_with_a_shutter() {
    let dir = test_dir("still");
    let path = write_scene(
        &dir,
        "still",
        &Setup {
            quad_x: -0.5,
            quad_moves: false,
            camera_x: 0.0,
            camera_moves: false,
            yfov: 0.6,
            unlit: false,
        },
    );
    let with = load(&path, shutter(-0.25, 0.25));
    assert_eq!(with.moving_triangle_count(), 0);
    assert!(with.meshes().iter().all(|m| m.motion.is_none()));
    assert!(with.camera().motion.is_none());
    let without = load(&path, None);
    let (a, b) = (render(&with, 12, 8), render(&without, 12, 8));
    assert!(
        a.beauty.iter().any(|p| p[0] > 0.0 && p[0] < 1.0),
        "the diffuse quad is in view"
    );
    assert_eq!(a.beauty, b.beauty);
    assert_eq!(a.variance, b.variance);
    std::fs::remove_dir_all(dir).ok();
}

/// A USD stage in the same set-up as [`write_scene`]: the quad x ∈ [`quad_x`, `quad_x` + 1] under an Xform, a
/// black surface that reflects nothing (diffuse 0, ior 1: no Fresnel), a white dome light and a camera with a
/// 10⁻⁴ rad field of view at x = `camera_x`, z = 5. What moves has its translate time-sampled from −48 to +48
/// along x between time codes 0 and 24 (4 units a frame at 24 time codes and frames per second).
fn write_usd_scene(
    dir: &Path,
    name: &str,
    quad_x: f32,
    camera_x: f32,
    camera_moves: bool,
) -> PathBuf {
    let (x0, x1) = (quad_x, quad_x + 1.0);
    let quad_translate = if camera_moves {
        "double3 xformOp:translate = (0, 0, 0)".to_owned()
    } else {
        "double3 xformOp:translate.timeSamples = { 0: (-48, 0, 0), 24: (48, 0, 0) }".to_owned()
    };
    let camera_translate = if camera_moves {
        format!(
            "double3 xformOp:translate.timeSamples = {{ 0: ({}, 0, 5), 24: ({}, 0, 5) }}",
            camera_x - 48.0,
            camera_x + 48.0
        )
    } else {
        format!("double3 xformOp:translate = ({camera_x}, 0, 5)")
    };
    let usda = format!(
        r#"#usda 1.0
(
    timeCodesPerSecond = 24
    framesPerSecond = 24
    upAxis = "Y"
    metersPerUnit = 1
)
def Xform "Mover"
{{
    {quad_translate}
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def Mesh "Quad"
    {{
        uniform token subdivisionScheme = "none"
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [({x0}, -0.5, 0), ({x1}, -0.5, 0), ({x1}, 0.5, 0), ({x0}, 0.5, 0)]
        rel material:binding = </Black>
    }}
}}
def Material "Black"
{{
    token outputs:surface.connect = </Black/Surface.outputs:surface>
    def Shader "Surface"
    {{
        uniform token info:id = "UsdPreviewSurface"
        color3f inputs:diffuseColor = (0, 0, 0)
        float inputs:ior = 1
        token outputs:surface
    }}
}}
def DomeLight "Sky"
{{
    color3f inputs:color = (1, 1, 1)
    float inputs:intensity = 1
}}
def Camera "Camera"
{{
    float focalLength = 50
    float horizontalAperture = 0.005
    float verticalAperture = 0.005
    {camera_translate}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"#
    );
    let path = dir.join(format!("{name}.usda"));
    std::fs::write(&path, usda).unwrap();
    path
}

/// USD xform time samples blur like glTF animation (the stage is read again at each motion step): the quad's
/// analytic 1/6 of the shutter for the ray at x = −0.5, and the moving camera's 1/3 over the quad at
/// [0.25, 1.25], as in the glTF tests above.
#[test]
fn usd_xforms_animated_across_the_shutter_blur_by_their_analytic_share() {
    let dir = test_dir("usd");
    let path = write_usd_scene(&dir, "quad", 0.0, -0.5, false);
    let blurred = load(&path, shutter(-0.25, 0.5));
    assert_eq!(blurred.moving_triangle_count(), 2);
    assert_covered_share(&blurred, 1.0 / 6.0, "USD moving quad");
    let still = load(&path, None);
    assert_eq!(still.moving_triangle_count(), 0);
    assert_eq!(coverage(&still, 64).0, 0.0);
    // A ray over the frame pose meets the quad (which returns at most a trace of light: 1 − 4e-5).
    let over = load(&write_usd_scene(&dir, "over", 0.0, 0.5, false), None);
    assert!(coverage(&over, 64).0 > 0.999);

    let camera = load(
        &write_usd_scene(&dir, "camera", 0.25, 0.0, true),
        shutter(-0.25, 0.5),
    );
    assert_eq!(camera.moving_triangle_count(), 0, "the quad stands still");
    let ray = camera.camera().generate_ray_at(Vec2::splat(0.5), 1.0, 0.3);
    assert!((ray.origin.x - 1.2).abs() < 1e-4, "{}", ray.origin);
    assert_covered_share(&camera, 1.0 / 3.0, "USD moving camera");
    std::fs::remove_dir_all(dir).ok();
}
