//! The default camera of a scene without one: it must see planar content face-on (not edge-on) and fit the
//! bounds tightly. Coverage is measured from renders (the depth AOV); tightness by projecting the bounds'
//! corners through the camera's own pinhole model (independent of the renderer).

use crate::common;

use nimbus::math::{Aabb, Vec3};
use nimbus::scene::{load_builder, Camera, LoadOptions};
use std::path::PathBuf;

fn folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_cam_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Normalised image coordinates (−1..1 across the image's height and width, at aspect 1) of `p` through `cam`,
/// and its depth in front of the camera.
fn project(cam: &Camera, p: Vec3) -> (f32, f32, f32) {
    let q = cam.camera_to_world.inverse().transform_point3(p);
    let t = (cam.yfov * 0.5).tan();
    let depth = -q.z;
    (q.x / (depth * t), q.y / (depth * t), depth)
}

/// The fraction of a 64² render's pixels that see a surface.
fn coverage_of_obj(tag: &str, obj: &str) -> f64 {
    let dir = folder(tag);
    let path = dir.join("s.obj");
    std::fs::write(&path, obj).unwrap();
    let b = load_builder(&path, &LoadOptions::default()).unwrap();
    let (img, _) = common::render_square(b, 64, 1, 0, 3);
    img.depth.iter().filter(|&&d| d > 0.0).count() as f64 / img.depth.len() as f64
}

#[test]
fn planar_quads_in_each_axis_plane_fill_the_image() {
    let coverages: Vec<(&str, f64)> = [
        ("xy", "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\n"),
        ("yz", "v 0 0 0\nv 0 2 0\nv 0 2 2\nv 0 0 2\n"),
        ("xz", "v 0 0 0\nv 2 0 0\nv 2 0 2\nv 0 0 2\n"),
    ]
    .into_iter()
    .map(|(tag, corners)| (tag, coverage_of_obj(tag, &format!("{corners}f 1 2 3 4\n"))))
    .collect();
    eprintln!("coverage: {coverages:.3?}");
    for (tag, coverage) in coverages {
        // Face-on and tight, a square fills most of a square image (a 5 % margin leaves about 0.9).
        assert!(
            coverage > 0.6,
            "{tag}: the quad covers only {coverage:.3} of the image"
        );
    }
}

#[test]
fn a_cube_and_boxes_are_framed_tightly() {
    for (min, max) in [
        (Vec3::splat(-1.0), Vec3::splat(1.0)),
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 1.0, 1.0)),
        (Vec3::new(-3.0, 5.0, 2.0), Vec3::new(-2.0, 9.0, 2.5)),
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 4.0)),
    ] {
        let bounds = Aabb::new(min, max);
        let cam = Camera::framing(&bounds);
        let mut widest = 0f32;
        for corner in bounds.corners() {
            let (x, y, depth) = project(&cam, corner);
            assert!(
                depth > 0.0,
                "{min}..{max}: corner {corner} behind the camera"
            );
            assert!(
                x.abs() <= 1.0 && y.abs() <= 1.0,
                "{min}..{max}: corner {corner} at ({x}, {y}) is outside"
            );
            widest = widest.max(x.abs()).max(y.abs());
        }
        assert!(
            widest > 0.85,
            "{min}..{max}: loosely framed, the farthest corner is at {widest}"
        );
    }
}

/// A scene that is only a VDB volume (no surface, no camera), placed away from the origin: the default camera
/// frames the volume's bounds from outside them. It used to frame the empty surface bounds, looking at the
/// origin from (0, 0, 5), with the volume off-frame.
#[test]
fn a_volume_only_scene_is_framed_from_outside_the_volume() {
    let dir = folder("volume_only");
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes");
    std::fs::copy(
        scenes.join("constant_grid.vdb"),
        dir.join("constant_grid.vdb"),
    )
    .unwrap();
    let gltf = std::fs::read_to_string(scenes.join("constant_grid.gltf")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&gltf).unwrap();
    json["scenes"][0]["nodes"] = serde_json::json!([0]);
    json["nodes"][0]["translation"] = serde_json::json!([10.0, 3.0, -7.0]);
    let path = dir.join("volume.gltf");
    std::fs::write(&path, json.to_string()).unwrap();
    let scene = load_builder(&path, &LoadOptions::default())
        .unwrap()
        .build()
        .unwrap();
    let bounds = scene.bounds();
    assert!(
        !bounds.is_empty() && bounds.min.x > 9.0 && bounds.max.x < 11.5,
        "the scene's bounds are the volume's: {bounds:?}"
    );
    let cam = scene.camera();
    let eye = cam.position();
    assert!(
        !(bounds.min.cmple(eye).all() && eye.cmple(bounds.max).all()),
        "camera at {eye} inside {bounds:?}"
    );
    for corner in bounds.corners() {
        let (x, y, depth) = project(cam, corner);
        assert!(
            depth > 0.0 && x.abs() <= 1.0 && y.abs() <= 1.0,
            "corner {corner} at ({x}, {y}, depth {depth})"
        );
    }
}
