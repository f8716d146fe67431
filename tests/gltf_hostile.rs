//! Hostile glTF input (issue 14): each case is the validation scene `area-light-floor` with one element made
//! hostile in code, and must give a one-line error naming the element (never a panic, an endless read or a
//! runaway allocation). Every case failed on the loader before the issue 14 checks.

mod common;

use nimbus::limits::Limits;
use nimbus::scene::{gltf, LoadOptions, SceneError, SceneErrorKind};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// The validation scene's folder (its `scene.bin` resolves the buffer URI), or `None` to skip.
fn scene_dir() -> Option<PathBuf> {
    Some(common::shared_dir()?.join("validation/area-light-floor"))
}

/// The validation scene's JSON.
fn scene_json(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("scene.gltf")).unwrap()).unwrap()
}

/// Loads `doc` as if it were a file `hostile.gltf` beside the validation scene.
fn load_with(dir: &Path, doc: &Value, options: &LoadOptions) -> Result<(), SceneError> {
    let bytes = serde_json::to_vec(doc).unwrap();
    gltf::load_slice(&bytes, &dir.join("hostile.gltf"), options).map(|_| ())
}

/// The error `doc` must give, checked to be one line of printable ASCII containing each of `names`.
fn error_of(dir: &Path, doc: &Value, names: &[&str]) -> SceneError {
    let err =
        load_with(dir, doc, &LoadOptions::default()).expect_err("a hostile file must not load");
    assert_one_line(&err, names);
    err
}

fn assert_one_line(err: &SceneError, names: &[&str]) {
    let msg = err.to_string();
    assert!(
        msg.chars().all(|c| c.is_ascii_graphic() || c == ' '),
        "not one printable line: {msg:?}"
    );
    for name in names {
        assert!(msg.contains(name), "{msg:?} should name {name:?}");
    }
}

/// Applies `edit` to the validation scene and returns the error, which must name each of `names`.
fn hostile(edit: impl FnOnce(&mut Value), names: &[&str]) -> Option<SceneError> {
    let dir = scene_dir()?;
    let mut doc = scene_json(&dir);
    edit(&mut doc);
    Some(error_of(&dir, &doc, names))
}

#[test]
fn the_validation_scene_itself_loads() {
    let Some(dir) = scene_dir() else { return };
    load_with(&dir, &scene_json(&dir), &LoadOptions::default()).unwrap();
}

#[test]
fn huge_field_of_view_is_refused() {
    hostile(
        |d| d["cameras"][0]["perspective"]["yfov"] = json!(1e308),
        &["cameras[0]", "yfov"],
    );
    hostile(
        |d| d["cameras"][0]["perspective"]["yfov"] = json!(0),
        &["cameras[0]", "yfov"],
    );
    hostile(
        |d| d["cameras"][0]["perspective"]["aspectRatio"] = json!(-1),
        &["cameras[0]", "aspectRatio"],
    );
    hostile(
        |d| d["cameras"][0]["perspective"]["zfar"] = json!(0.001),
        &["cameras[0]", "zfar"],
    );
}

#[test]
fn camera_without_its_projection_object_is_refused() {
    hostile(
        |d| d["cameras"][0] = json!({"type": "orthographic"}),
        &["cameras[0]", "orthographic"],
    );
    hostile(
        |d| d["cameras"][0] = json!({"type": "perspective"}),
        &["cameras[0]", "perspective"],
    );
    hostile(
        |d| d["cameras"][0] = json!({"type": "orthographic", "orthographic": {"xmag": 0, "ymag": 1, "znear": 0, "zfar": 1}}),
        &["cameras[0]", "xmag"],
    );
}

#[test]
fn position_accessor_past_the_end_is_refused() {
    hostile(
        |d| {
            let n = d["accessors"].as_array().unwrap().len();
            d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(n);
        },
        &["meshes[0]", "POSITION", "accessors"],
    );
    hostile(
        |d| {
            let n = d["bufferViews"].as_array().unwrap().len();
            d["accessors"][0]["bufferView"] = json!(n);
        },
        &["accessors[0]", "bufferView"],
    );
}

#[test]
fn signed_byte_indices_are_refused() {
    hostile(
        |d| d["accessors"][2]["componentType"] = json!(5120),
        &["accessor 2", "componentType"],
    );
}

#[test]
fn wrong_accessor_types_are_refused() {
    // POSITION as VEC2, and an empty accessor.
    hostile(
        |d| d["accessors"][0]["type"] = json!("VEC2"),
        &["accessor 0"],
    );
    hostile(|d| d["accessors"][2]["count"] = json!(0), &["accessor 2"]);
}

#[test]
fn node_graph_must_be_a_forest() {
    hostile(|d| d["nodes"][1]["children"] = json!([1]), &["nodes[1]"]);
    hostile(
        |d| {
            d["nodes"][1]["children"] = json!([2]);
            d["nodes"][2]["children"] = json!([1]);
            d["scenes"][0]["nodes"] = json!([0, 3, 4]);
        },
        &["nodes[1]", "nodes[2]", "cycle"],
    );
    hostile(
        |d| {
            d["nodes"][0]["children"] = json!([3]);
            d["nodes"][1]["children"] = json!([3]);
            d["scenes"][0]["nodes"] = json!([0, 1, 2, 4]);
        },
        &["nodes[3]", "nodes[0]", "nodes[1]"],
    );
    hostile(
        |d| {
            d["nodes"][0]["children"] = json!([3, 3]);
            d["scenes"][0]["nodes"] = json!([0, 1, 2, 4]);
        },
        &["nodes[0]", "nodes[3]", "twice"],
    );
    hostile(
        |d| d["nodes"][0]["children"] = json!([3]),
        &["scenes[0]", "nodes[3]", "nodes[0]"],
    );
}

#[test]
fn non_finite_node_transforms_are_refused() {
    hostile(
        |d| d["nodes"][3]["scale"] = json!([1e308, 1, 1]),
        &["nodes[3].scale[0]"],
    );
    hostile(
        |d| d["nodes"][3]["translation"] = json!([0, -1e39, 0]),
        &["nodes[3].translation[1]"],
    );
    // Finite parts whose product overflows.
    hostile(
        |d| {
            d["nodes"][0]["scale"] = json!([3e38, 3e38, 3e38]);
            d["nodes"][0]["children"] = json!([3]);
            d["nodes"][3]["scale"] = json!([3e38, 3e38, 3e38]);
            d["scenes"][0]["nodes"] = json!([0, 1, 2, 4]);
        },
        &["node 3", "transform"],
    );
}

/// The scene with a `KHR_lights_punctual` light on the `light` node.
fn with_light(d: &mut Value, light: Value) {
    d["extensionsUsed"]
        .as_array_mut()
        .unwrap()
        .push(json!("KHR_lights_punctual"));
    d["extensions"] = json!({"KHR_lights_punctual": {"lights": [light]}});
    d["nodes"][1]["extensions"] = json!({"KHR_lights_punctual": {"light": 0}});
}

#[test]
fn bad_light_numbers_are_refused() {
    let Some(dir) = scene_dir() else { return };
    let mut ok = scene_json(&dir);
    with_light(
        &mut ok,
        json!({"type": "point", "intensity": 5, "color": [1, 1, 1]}),
    );
    load_with(&dir, &ok, &LoadOptions::default()).unwrap();
    let cases = [
        (json!({"type": "point", "intensity": -1}), "intensity"),
        (json!({"type": "point", "intensity": 1e308}), "intensity"),
        (json!({"type": "point", "color": [1, 1e39, 1]}), "color"),
        (json!({"type": "point", "range": 0}), "range"),
        (
            json!({"type": "spot", "spot": {"innerConeAngle": 0.5, "outerConeAngle": 3}}),
            "outerConeAngle",
        ),
        (
            json!({"type": "spot", "spot": {"innerConeAngle": 0.5, "outerConeAngle": 0.2}}),
            "innerConeAngle",
        ),
        (json!({"type": "spot"}), "spot"),
    ];
    for (light, name) in cases {
        hostile(|d| with_light(d, light), &["lights[0]", name]);
    }
}

#[test]
fn bad_material_numbers_are_refused() {
    hostile(
        |d| d["materials"][1]["emissiveFactor"] = json!([1, 1e39, 1]),
        &["materials[1]", "emissiveFactor"],
    );
    hostile(
        |d| {
            d["materials"][1]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] =
                json!(-2)
        },
        &["materials[1]", "emissiveStrength"],
    );
    hostile(
        |d| d["materials"][2]["pbrMetallicRoughness"]["baseColorFactor"] = json!([1, 1, 1e300, 1]),
        &["materials[2]", "baseColorFactor"],
    );
    hostile(
        |d| {
            d["extensionsUsed"]
                .as_array_mut()
                .unwrap()
                .push(json!("KHR_materials_volume"));
            d["materials"][2]["extensions"]["KHR_materials_volume"] =
                json!({"thicknessFactor": 1, "attenuationColor": [1e39, 1, 1]});
        },
        &["materials[2]", "attenuationColor"],
    );
}

#[test]
fn image_without_a_source_is_refused() {
    let with_image = |image: Value| {
        move |d: &mut Value| {
            d["images"] = json!([image]);
            d["textures"] = json!([{"source": 0}]);
            d["materials"][2]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
        }
    };
    hostile(with_image(json!({})), &["images[0]", "uri"]);
    hostile(
        with_image(json!({"bufferView": 0})),
        &["images[0]", "mimeType"],
    );
    hostile(
        |d| {
            with_image(json!({"uri": "missing.png"}))(d);
            d["textures"][0]["source"] = json!(1);
        },
        &["textures[0].source", "images"],
    );
}

#[test]
fn endless_buffer_file_is_a_one_line_error() {
    let Some(dir) = scene_dir() else { return };
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let mut doc = scene_json(&dir);
    doc["buffers"][0]["uri"] = json!("/dev/zero");
    let options = LoadOptions {
        limits: Limits::with_memory(1 << 20),
        ..Default::default()
    };
    let err = load_with(&dir, &doc, &options).unwrap_err();
    assert_one_line(&err, &["buffers[0]", "/dev/zero"]);
}

#[test]
fn endless_scene_file_is_a_one_line_error() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("nimbus-gltf-hostile-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("zero.gltf");
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(zero, &link).unwrap();
    let options = LoadOptions {
        limits: Limits::with_memory(1 << 20),
        ..Default::default()
    };
    let Err(err) = gltf::load(&link, &options) else {
        panic!("an endless scene file must not load")
    };
    assert!(matches!(err.kind, SceneErrorKind::Io(_)), "{err}");
    assert_one_line(&err, &["zero.gltf"]);
}

/// A PNG that is only a header claiming `width` × `height` RGBA8 pixels (no image data).
fn png_header(width: u32, height: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&width.to_be_bytes());
    ihdr.extend_from_slice(&height.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc32(&ihdr).to_be_bytes());
    png
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= b as u32;
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

#[test]
fn huge_image_header_is_refused_before_allocating() {
    let Some(dir) = scene_dir() else { return };
    let tmp = std::env::temp_dir().join(format!("nimbus-gltf-hostile-img-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    std::fs::write(tmp.join("huge.png"), png_header(100_000, 100_000)).unwrap();
    let mut doc = scene_json(&dir);
    doc["buffers"][0]["uri"] = json!(dir.join("scene.bin").to_str().unwrap());
    doc["images"] = json!([{"uri": "huge.png"}]);
    doc["textures"] = json!([{"source": 0}]);
    doc["materials"][2]["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
    let options = LoadOptions {
        limits: Limits::with_memory(64 << 20),
        ..Default::default()
    };
    let bytes = serde_json::to_vec(&doc).unwrap();
    let Err(err) = gltf::load_slice(&bytes, &tmp.join("hostile.gltf"), &options) else {
        panic!("a 100000 x 100000 image must not load")
    };
    assert_one_line(&err, &["image 0", "huge.png"]);
}

#[test]
fn glb_header_shorter_than_itself_is_refused() {
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo.glb");
    let mut bytes = std::fs::read(&demo).unwrap();
    bytes[8..12].copy_from_slice(&4u32.to_le_bytes());
    let Err(err) = gltf::load_slice(&bytes, &demo, &LoadOptions::default()) else {
        panic!("a GLB whose header gives a length of 4 must not load")
    };
    assert_one_line(&err, &["demo.glb", "length"]);
}

#[test]
fn non_finite_vertex_data_is_refused() {
    let Some(dir) = scene_dir() else { return };
    let tmp = std::env::temp_dir().join(format!("nimbus-gltf-hostile-bin-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let bin = std::fs::read(dir.join("scene.bin")).unwrap();
    // The floor's first position (bufferView 0) and first normal (bufferView 1, at byte 48).
    for (at, value, names) in [
        (48, f32::NAN, ["NORMAL", "floor"]),
        (0, f32::INFINITY, ["POSITION", "floor"]),
    ] {
        let mut bad = bin.clone();
        bad[at..at + 4].copy_from_slice(&value.to_le_bytes());
        let file = tmp.join(format!("bad{at}.bin"));
        std::fs::write(&file, &bad).unwrap();
        let mut doc = scene_json(&dir);
        doc["buffers"][0]["uri"] = json!(file.to_str().unwrap());
        let err = error_of(&dir, &doc, &names);
        assert!(matches!(err.kind, SceneErrorKind::Malformed(_)), "{err}");
    }
}

#[test]
fn names_from_the_file_are_quoted_on_one_line() {
    hostile(
        |d| d["extensionsRequired"] = json!(["EXT_\nbad\u{e9}"]),
        &["EXT_ / bad\\xe9"],
    );
    hostile(
        |d| {
            d["meshes"][0]["name"] = json!("floor\r\n\u{1b}[31mred");
            d["accessors"][2]["count"] = json!(0);
        },
        &["floor / \\x1b[31mred", "accessor 2"],
    );
}
