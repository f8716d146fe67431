//! glTF and OBJ loading: features that must work, and malformed input that must give an error naming the
//! file, never a panic.

use crate::common;

use nimbus::scene::{gltf, load_builder, SceneErrorKind};
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nimbus-gltf-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// One triangle's positions (3 × vec3 f32) followed by u16 indices 0,1,2 (+ padding).
fn triangle_buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

/// A glTF document with one triangle mesh under a translated, scaled node and a camera node.
fn document(buffer_uri: &str, count: usize, extra: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "nodes":[{{"mesh":0,"translation":[10,0,0],"scale":[2,2,2]}},
                 {{"camera":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.5,"znear":0.1,"aspectRatio":2.0}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{count},"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":8}}],
        "buffers":[{{"uri":"{buffer_uri}","byteLength":44}}]{extra}}}"#
    )
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn data_uri_buffer_transforms_and_camera() {
    let dir = temp_dir("datauri");
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        common::base64(&triangle_buffer())
    );
    let path = write(&dir, "tri.gltf", &document(&uri, 3, ""));
    let scene = load_builder(&path, &Default::default())
        .expect("loads")
        .build()
        .unwrap();
    assert_eq!(scene.triangle_count(), 1);
    // translation 10 and scale 2: x spans [10, 12], y [0, 2].
    assert!(
        (scene.bounds().min.x - 10.0).abs() < 1e-6 && (scene.bounds().max.x - 12.0).abs() < 1e-6
    );
    assert!((scene.bounds().max.y - 2.0).abs() < 1e-6);
    assert_eq!(scene.camera().yfov, 0.5);
    assert_eq!(scene.camera().aspect_ratio, Some(2.0));
    assert!((scene.camera().position().z - 5.0).abs() < 1e-6);
    // The default glTF material is not double-sided; normals were generated from the CCW winding (+z).
    assert!(scene.meshes()[0]
        .normals
        .iter()
        .all(|n| (n.z - 1.0).abs() < 1e-6));
}

#[test]
fn external_buffer_and_missing_buffer() {
    let dir = temp_dir("external");
    std::fs::write(dir.join("tri.bin"), triangle_buffer()).unwrap();
    let ok = write(&dir, "ok.gltf", &document("tri.bin", 3, ""));
    assert_eq!(
        load_builder(&ok, &Default::default())
            .unwrap()
            .build()
            .unwrap()
            .triangle_count(),
        1
    );
    let missing = write(&dir, "missing.gltf", &document("nope.bin", 3, ""));
    let err = load_builder(&missing, &Default::default())
        .err()
        .expect("missing buffer is an error");
    assert!(
        matches!(err.kind, SceneErrorKind::InvalidReference(_)),
        "{err}"
    );
    assert!(
        err.to_string().contains("missing.gltf") && err.to_string().contains("nope.bin"),
        "{err}"
    );
}

#[test]
fn malformed_json_is_an_error() {
    let dir = temp_dir("json");
    let p = write(
        &dir,
        "bad.gltf",
        "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [",
    );
    let err = load_builder(&p, &Default::default()).err().expect("error");
    assert!(matches!(err.kind, SceneErrorKind::Malformed(_)));
    assert!(err.to_string().contains("bad.gltf"));
}

#[test]
fn accessor_past_its_buffer_view_is_an_error() {
    let dir = temp_dir("accessor");
    std::fs::write(dir.join("tri.bin"), triangle_buffer()).unwrap();
    let p = write(&dir, "bad.gltf", &document("tri.bin", 300, ""));
    let err = load_builder(&p, &Default::default()).err().expect("error");
    assert!(err.to_string().contains("accessor 0"), "{err}");
}

#[test]
fn dangling_index_is_an_error() {
    let dir = temp_dir("dangling");
    std::fs::write(dir.join("tri.bin"), triangle_buffer()).unwrap();
    let text = document("tri.bin", 3, "").replace(r#""indices":1"#, r#""indices":7"#);
    let p = write(&dir, "bad.gltf", &text);
    assert!(load_builder(&p, &Default::default()).is_err());
}

#[test]
fn required_extensions_supported_or_refused() {
    let dir = temp_dir("ext");
    std::fs::write(dir.join("tri.bin"), triangle_buffer()).unwrap();
    let ok = write(
        &dir,
        "ok.gltf",
        &document(
            "tri.bin",
            3,
            r#","extensionsUsed":["KHR_materials_volume","KHR_materials_specular","EXT_fancy"],"extensionsRequired":["KHR_materials_volume","KHR_materials_specular"]"#,
        ),
    );
    let builder = load_builder(&ok, &Default::default())
        .expect("the extensions Nimbus implements may be required");
    assert!(
        builder.warnings().iter().any(|w| w.contains("EXT_fancy")),
        "{:?}",
        builder.warnings()
    );
    let bad = write(
        &dir,
        "bad.gltf",
        &document(
            "tri.bin",
            3,
            r#","extensionsUsed":["EXT_fancy"],"extensionsRequired":["EXT_fancy"]"#,
        ),
    );
    let err = load_builder(&bad, &Default::default())
        .err()
        .expect("error");
    assert!(matches!(err.kind, SceneErrorKind::Unsupported(_)), "{err}");
}

#[test]
fn truncated_glb_is_an_error_at_every_length() {
    let glb = include_bytes!("../../assets/demo.glb");
    let path = Path::new("demo.glb");
    for len in (0..glb.len() - 1).step_by(glb.len() / 97) {
        let result = std::panic::catch_unwind(|| {
            gltf::load_slice(&glb[..len], path, &Default::default()).map(|_| ())
        });
        let result = result.unwrap_or_else(|_| panic!("panic at length {len}"));
        assert!(result.is_err(), "truncated at {len} should fail");
    }
    assert!(gltf::load_slice(glb, path, &Default::default()).is_ok());
}

#[test]
fn obj_with_mtl_maps_diffuse_and_emission() {
    let dir = temp_dir("obj");
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl wall\nKd 0.5 0.25 0.125\nnewmtl lamp\nKd 0 0 0\nKe 4 4 4\n",
    )
    .unwrap();
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl wall\nf 1 2 3 4\nusemtl lamp\nf 1 3 2\n";
    let p = write(&dir, "scene.obj", obj);
    let scene = load_builder(&p, &Default::default())
        .unwrap()
        .build()
        .unwrap();
    assert_eq!(scene.triangle_count(), 3);
    let wall = scene.materials().iter().find(|m| m.name == "wall").unwrap();
    assert_eq!(
        wall.base_color.truncate(),
        nimbus::math::Vec3::new(0.5, 0.25, 0.125)
    );
    assert_eq!(wall.specular_factor, 0.0, "no Ks: exactly Lambertian");
    assert_eq!(
        scene.lights().len(),
        1,
        "the emissive face is an area light"
    );
    let err = load_builder(&dir.join("absent.obj"), &Default::default())
        .err()
        .unwrap();
    assert!(err.to_string().contains("absent.obj"));
}

/// `realworld/gltf/TextureSettingsTest` pairs two images with five samplers: each texture must keep its own
/// sampler, even where another texture already uses the same image.
#[test]
fn textures_sharing_an_image_keep_their_own_samplers() {
    use nimbus::material::Wrap::{ClampToEdge, MirroredRepeat, Repeat};
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let path = shared.join("realworld/gltf/TextureSettingsTest/TextureSettingsTest.gltf");
    let builder = load_builder(&path, &Default::default()).unwrap();
    let expected = [
        ("TextureMirrorMaterialT", Repeat, MirroredRepeat),
        ("TextureMirrorMaterialS", MirroredRepeat, Repeat),
        ("TextureRepeatMaterialT", ClampToEdge, Repeat),
        ("TextureClampMaterialT", Repeat, ClampToEdge),
        ("TextureRepeatMaterialS", Repeat, ClampToEdge),
        ("TextureClampMaterialS", ClampToEdge, Repeat),
        ("DoubleSidedMaterial", Repeat, Repeat),
    ];
    for (name, wrap_s, wrap_t) in expected {
        let material = builder
            .materials()
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("material {name} missing"));
        let texture = &builder.textures()[material.base_color_texture.unwrap() as usize];
        let sampler = texture.sampler();
        assert_eq!((sampler.wrap_s, sampler.wrap_t), (wrap_s, wrap_t), "{name}");
        // NEAREST_MIPMAP_LINEAR minification, LINEAR magnification.
        assert_eq!(sampler.min, nimbus::material::Filter::Nearest, "{name}");
        assert_eq!(
            sampler.mip,
            Some(nimbus::material::Filter::Linear),
            "{name}"
        );
        assert_eq!(sampler.mag, nimbus::material::Filter::Linear, "{name}");
    }
    // Textures of one image share its decoded pixels: TextureMirrorTextureT and TextureRepeatTextureT both
    // read CheckAndX_V.png.
    let texture_of = |name: &str| {
        let m = builder.materials().iter().find(|m| m.name == name).unwrap();
        &builder.textures()[m.base_color_texture.unwrap() as usize]
    };
    assert!(std::sync::Arc::ptr_eq(
        texture_of("TextureMirrorMaterialT").image(),
        texture_of("TextureRepeatMaterialT").image()
    ));
}

/// KHR_lights_punctual intensities are photometric (cd, lx) and become W/sr and W/m² at 683 lm/W, unless the
/// scene's extras say they are radiometric already.
#[test]
fn punctual_light_units_are_photometric_unless_the_scene_says_radiometric() {
    use nimbus::light::Light;
    let dir = temp_dir("light-units");
    let lights = r#""extensionsUsed":["KHR_lights_punctual"],
        "extensions":{"KHR_lights_punctual":{"lights":[
            {"type":"point","intensity":683.0,"color":[1,0.5,0.25]},
            {"type":"directional","intensity":1366.0}]}},"#;
    let nodes = r#""nodes":[{"extensions":{"KHR_lights_punctual":{"light":0}}},
                            {"extensions":{"KHR_lights_punctual":{"light":1}}}]"#;
    let intensities = |scene_extras: &str| {
        let text = format!(
            r#"{{"asset":{{"version":"2.0"}},{lights}"scene":0,
                "scenes":[{{"nodes":[0,1]{scene_extras}}}],{nodes}}}"#
        );
        let path = write(&dir, "lights.gltf", &text);
        let b = load_builder(&path, &Default::default()).map_err(|e| e.to_string())?;
        let point = b.lights().iter().find_map(|l| match l {
            Light::Point(p) => Some(p.intensity),
            _ => None,
        });
        let sun = b.lights().iter().find_map(|l| match l {
            Light::Directional(d) => Some(d.irradiance),
            _ => None,
        });
        Ok::<_, String>((point.unwrap(), sun.unwrap()))
    };
    let (point, sun) = intensities("").unwrap();
    assert!(
        (point - nimbus::math::Vec3::new(1.0, 0.5, 0.25))
            .abs()
            .max_element()
            < 1e-6
    );
    assert!((sun.x - 2.0).abs() < 1e-6);
    let (point, sun) = intensities(r#","extras":{"nimbus_light_units":"photometric"}"#).unwrap();
    assert!((point.x - 1.0).abs() < 1e-6 && (sun.x - 2.0).abs() < 1e-6);
    let (point, sun) = intensities(r#","extras":{"nimbus_light_units":"radiometric"}"#).unwrap();
    assert!((point.x - 683.0).abs() < 1e-3 && (sun.x - 1366.0).abs() < 1e-3);
    let err = intensities(r#","extras":{"nimbus_light_units":"watts"}"#).unwrap_err();
    assert!(
        err.contains("nimbus_light_units") && err.contains("lights.gltf"),
        "{err}"
    );
}

#[test]
fn a_missing_or_corrupt_environment_map_is_a_typed_error_naming_the_map() {
    use nimbus::light::EnvironmentError;
    use nimbus::scene::SceneErrorKind;
    use std::error::Error as _;
    let dir = temp_dir("env-map");
    std::fs::write(dir.join("corrupt.exr"), b"not an exr").unwrap();
    let buffer = format!(
        "data:application/octet-stream;base64,{}",
        common::base64(&triangle_buffer())
    );
    for (map, missing) in [("absent.exr", true), ("corrupt.exr", false)] {
        let scene = format!(
            r#""scenes":[{{"nodes":[0,1],"extras":{{"nimbus_environment":{{"map":"{map}"}}}}}}]"#
        );
        let text = document(&buffer, 3, "").replace(r#""scenes":[{"nodes":[0,1]}]"#, &scene);
        let path = write(&dir, "env.gltf", &text);
        let Err(err) = nimbus::scene::load_builder(&path, &Default::default()) else {
            panic!("{map} loaded");
        };
        assert!(err.to_string().contains(map), "{err}");
        assert!(
            err.source().is_some(),
            "the reader's or decoder's error is kept as the source"
        );
        match (&err.kind, missing) {
            (SceneErrorKind::Environment(EnvironmentError::Io { path, source }), true) => {
                assert!(path.ends_with(map));
                assert_eq!(source.kind(), std::io::ErrorKind::NotFound, "{source:?}");
            }
            (SceneErrorKind::Environment(EnvironmentError::Exr { path, .. }), false) => {
                assert!(path.ends_with(map));
            }
            _ => panic!("not the expected environment map error: {err:?}"),
        }
    }
}

/// `EXT_mesh_gpu_instancing`: a node (at y = 1) instances its triangle three times by TRANSLATION, ROTATION and
/// SCALE accessors. By hand, the vertex (1, 0, 0) lands at (1, 1, 0) (identity), (4, 1, 0) (scale 2, then
/// x + 2) and (0, 2, −3) (90° about z, then z − 3). The extension used to be ignored: one triangle; then each
/// instance was a copy; now they are instances of one prototype.
#[test]
fn gpu_instancing_places_every_instance() {
    let dir = std::env::temp_dir().join(format!("nimbus-gltf-instancing-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("instanced.gltf");
    std::fs::write(
        &path,
        r#"{"asset": {"version": "2.0"}, "extensionsUsed": ["EXT_mesh_gpu_instancing"],
  "scene": 0, "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0, "translation": [0, 1, 0],
             "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 1, "ROTATION": 2, "SCALE": 3}}}}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
  "buffers": [{"byteLength": 156, "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAAAAAAAAQAAAAAAAAAAAAAAAAAAAAAAAAEDAAAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAPMENT/zBDU/AACAPwAAgD8AAIA/AAAAQAAAAEAAAABAAACAPwAAgD8AAIA/"}],
  "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 72, "byteLength": 48}, {"buffer": 0, "byteOffset": 120, "byteLength": 36}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
                {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4"},
                {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC3"}]}"#,
    )
    .unwrap();
    let b = load_builder(&path, &Default::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(b.instances().len(), 3, "one instance each");
    assert_eq!(b.prototypes().len(), 1, "of one prototype");
    let want = [
        nimbus::math::Vec3::new(1.0, 1.0, 0.0),
        nimbus::math::Vec3::new(4.0, 1.0, 0.0),
        nimbus::math::Vec3::new(0.0, 2.0, -3.0),
    ];
    for (mesh, want) in b.world_meshes().iter().zip(want) {
        assert!(
            mesh.positions.iter().any(|p| p.distance(want) < 1e-5),
            "{:?} lacks {want}",
            mesh.positions
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A triangle document whose scene, node and material `extras` hold misspelt `nimbus_*` keys and keys inside
/// `nimbus_environment` and `nimbus_medium`, beside another tool's key (`blender_prop`), which stays quiet.
fn misspelt_keys_document() -> String {
    let buffer = common::base64(&triangle_buffer());
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,
        "scenes":[{{"nodes":[0],"extras":{{"blender_prop":1,"nimbus_enviroment":{{"color":[1,1,1]}},
                   "nimbus_environment":{{"color":[1,1,1],"intensty":2}}}}}}],
        "nodes":[{{"mesh":0,"extras":{{"nimbus_holdot":true,"blender_prop":2}}}}],
        "materials":[{{"name":"fog","extras":{{"nimbus_medium":{{"sigma_a":[1,1,1],"sigma_z":[1,1,1]}}}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":8}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{buffer}","byteLength":44}}]}}"#
    )
}

/// Keys the renderer ignores are warnings naming the key, where it is and the closest known key; `--strict`
/// (`LoadOptions::strict`) refuses them. Before, all of them were silently ignored (issue 35).
#[test]
fn unknown_nimbus_keys_are_warned_with_the_closest_key_or_refused_when_strict() {
    let json = misspelt_keys_document();
    let path = Path::new("misspelt.gltf");
    let builder = gltf::load_slice(json.as_bytes(), path, &Default::default()).unwrap();
    let warnings = builder.warnings().join("\n");
    for expected in [
        "scene extras: unknown key 'nimbus_enviroment' ignored (did you mean 'nimbus_environment'?)",
        "scene extras: nimbus_environment: unknown key 'intensty' ignored (did you mean 'intensity'?)",
        "node 'node 0': extras: unknown key 'nimbus_holdot' ignored (did you mean 'nimbus_holdout'?)",
        "material 'fog': nimbus_medium: unknown key 'sigma_z' ignored (did you mean 'sigma_a'?)",
    ] {
        assert!(warnings.contains(expected), "missing {expected:?} in:\n{warnings}");
    }
    assert!(!warnings.contains("blender_prop"), "{warnings}");

    let strict = nimbus::scene::LoadOptions {
        strict: true,
        ..Default::default()
    };
    let Err(err) = gltf::load_slice(json.as_bytes(), path, &strict) else {
        panic!("--strict loaded a file with unknown keys")
    };
    assert!(matches!(err.kind, SceneErrorKind::UnknownKey(_)), "{err}");
    let msg = err.to_string();
    assert!(
        msg.contains("misspelt.gltf") && msg.contains("nimbus_holdot") && msg.contains("--strict"),
        "{msg}"
    );

    // A misspelt volume key is refused before the VDB file is looked for.
    let volume = json.replace(
        r#""nimbus_holdot":true"#,
        r#""nimbus_volume":{"file":"absent.vdb","densty_scale":2}"#,
    );
    let volume = volume.replace(r#""nimbus_enviroment":{"color":[1,1,1]},"#, "");
    let volume = volume.replace(r#","intensty":2"#, "");
    let volume = volume.replace(r#","sigma_z":[1,1,1]"#, "");
    let Err(err) = gltf::load_slice(volume.as_bytes(), path, &strict) else {
        panic!("--strict loaded a misspelt volume key")
    };
    assert!(
        err.to_string()
            .contains("nimbus_volume: unknown key 'densty_scale' (did you mean 'density_scale'?)"),
        "{err}"
    );
}
