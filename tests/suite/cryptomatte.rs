//! Cryptomatte against independent references: each object's mask against its exact area coverage, decoded by
//! our reading of the specification and by PyPI's `cryptomatte-api` (a decoder someone else wrote); the ranks
//! of a pixel summing to its alpha; and the IDs Cycles 5.0 wrote for the same names
//! (`tests/cryptomatte/cycles_ids.json`, made by `tests/cryptomatte/make_cycles_ids.py`).

use crate::common;

use common::quad;
use nimbus::light::{EnvironmentLight, Light};
use nimbus::material::Material;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::aovs::AovSelection;
use nimbus::render::cryptomatte::{murmur3_32, name_id, CryptoKind};
use nimbus::render::{AovLayer, RenderImage, RenderSettings, Renderer};
use nimbus::scene::SceneBuilder;
use nimbus::{Camera, Scene};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Three quads facing the camera at these depths, with these image-plane rectangles (x0, y0, x1, y1) at their
/// own depth: back, middle and front overlap.
const QUADS: [(&str, f32, [f32; 4]); 3] = [
    ("back", -1.0, [-0.9, -0.7, 0.6, 0.8]),
    ("middle", -0.5, [-0.3, -0.9, 0.9, 0.1]),
    ("front", 0.0, [-0.6, 0.05, 0.2, 0.55]),
];
/// The camera's distance from the origin, on +Z.
const EYE: f32 = 4.0;
/// The image's side in pixels.
const SIZE: usize = 16;

fn yfov() -> f32 {
    30f32.to_radians()
}

/// The three quads (asset "set", materials "<name> paint") under a uniform environment.
fn quads_scene() -> Scene {
    let mut b = SceneBuilder::new();
    for (name, z, [x0, y0, x1, y1]) in QUADS {
        let m = b.add_material(Material::lambertian(
            &format!("{name} paint"),
            Rgb::splat(0.5),
        ));
        let mut mesh = quad(
            [
                Vec3::new(x0, y0, z),
                Vec3::new(x1, y0, z),
                Vec3::new(x1, y1, z),
                Vec3::new(x0, y1, z),
            ],
            m,
        );
        mesh.name = name.into();
        mesh.asset = "set".into();
        b.add_mesh(mesh);
    }
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, EYE),
        Vec3::ZERO,
        yfov(),
    ));
    b.build().unwrap()
}

fn render(scene: &Scene, width: usize, spp: u32) -> RenderImage {
    let settings = RenderSettings {
        width,
        height: width,
        spp,
        seed: 7,
        threads: 2,
        aovs: Some(AovSelection::parse("cryptomatte").unwrap()),
        transparent: true,
        ..RenderSettings::default()
    };
    Renderer::new(settings)
        .render(scene, &mut |_| true)
        .unwrap()
        .0
}

/// The exact coverage of quad `name` in pixel (px, py): the share of a 64 × 64 grid of points of the pixel
/// where it is the nearest quad (the rectangles' edges fall between grid points).
fn exact(name: &str, px: usize, py: usize) -> f64 {
    let grid = 64;
    let tan = (yfov() * 0.5).tan();
    let mut hits = 0;
    for gy in 0..grid {
        for gx in 0..grid {
            let fx = (px as f32 + (gx as f32 + 0.5) / grid as f32) / SIZE as f32;
            let fy = (py as f32 + (gy as f32 + 0.5) / grid as f32) / SIZE as f32;
            let (dx, dy) = ((2.0 * fx - 1.0) * tan, (1.0 - 2.0 * fy) * tan);
            let seen = QUADS
                .iter()
                .rev()
                .find(|(_, z, r)| {
                    let (x, y) = (dx * (EYE - z), dy * (EYE - z));
                    x >= r[0] && x <= r[2] && y >= r[1] && y <= r[3]
                })
                .map(|(n, _, _)| *n);
            hits += (seen == Some(name)) as usize;
        }
    }
    hits as f64 / (grid * grid) as f64
}

/// The rank layers of `kind`.
fn rank_layers<'a>(img: &'a RenderImage, kind: &str) -> Vec<&'a AovLayer> {
    img.aovs
        .iter()
        .filter(|l| l.name.starts_with(kind))
        .collect()
}

/// The coverage of `id` in pixel `i`, summed over the ranks holding it (the specification's decoding).
fn decoded(layers: &[&AovLayer], id: u32, i: usize) -> f64 {
    layers
        .iter()
        .flat_map(|l| [(0, 1), (2, 3)].map(|(a, c)| (l.data[a][i], l.data[c][i])))
        .filter(|(v, _)| v.to_bits() == id)
        .map(|(_, c)| c as f64)
        .sum()
}

#[test]
fn masks_match_the_exact_coverage_and_ranks_sum_to_alpha() {
    let img = render(&quads_scene(), SIZE, 256);
    let layers = rank_layers(&img, "CryptoObject");
    assert_eq!(layers.len(), 3, "6 ranks: CryptoObject00..02");
    for (name, _, _) in QUADS {
        let id = name_id(name);
        let mut error = 0.0;
        for py in 0..SIZE {
            for px in 0..SIZE {
                error += (decoded(&layers, id, py * SIZE + px) - exact(name, px, py)).abs();
            }
        }
        let mae = error / (SIZE * SIZE) as f64;
        eprintln!("{name}: mean absolute error of the decoded mask {mae:.4}");
        assert!(mae < 0.02, "{name}: mask error {mae}");
    }
    // The ranks of a pixel sum to its alpha; the three quads share the asset "set".
    for i in 0..img.pixel_count() {
        let total: f64 = layers
            .iter()
            .flat_map(|l| [l.data[1][i], l.data[3][i]])
            .map(|c| c as f64)
            .sum();
        assert!((total - img.alpha[i] as f64).abs() < 1e-6, "pixel {i}");
    }
    let asset = img.aov("CryptoAsset00").unwrap();
    for i in 0..img.pixel_count() {
        if img.alpha[i] > 0.0 {
            assert_eq!(asset.data[0][i].to_bits(), name_id("set"));
            assert!((asset.data[1][i] - img.alpha[i]).abs() < 1e-6);
        }
    }
    let materials = &img
        .cryptomatte
        .iter()
        .find(|(k, _)| *k == CryptoKind::Material)
        .unwrap()
        .1;
    assert_eq!(
        materials.get("middle paint"),
        Some(&name_id("middle paint"))
    );
}

/// The three quads as instances of one unit-square prototype (each placed by a scale and a translation), named
/// per instance: the same masks as three meshes, each instance under its own name. Before, an instance had no
/// name of its own (instances were copies).
#[test]
fn instances_have_their_own_masks() {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambertian("paint", Rgb::splat(0.5)));
    let unit = quad(
        [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        m,
    );
    let proto = b.add_prototype(unit);
    for (name, z, [x0, y0, x1, y1]) in QUADS {
        let object_to_world = nimbus::math::Mat4::from_translation(Vec3::new(x0, y0, z))
            * nimbus::math::Mat4::from_scale(Vec3::new(x1 - x0, y1 - y0, 1.0));
        b.add_instance(nimbus::scene::MeshInstance {
            prototype: proto,
            object_to_world,
            name: name.into(),
            asset: "set".into(),
            ..Default::default()
        })
        .unwrap();
    }
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, EYE),
        Vec3::ZERO,
        yfov(),
    ));
    let scene = b.build().unwrap();
    assert_eq!((scene.instance_count(), scene.triangle_count()), (3, 6));
    let img = render(&scene, SIZE, 256);
    let layers = rank_layers(&img, "CryptoObject");
    for (name, _, _) in QUADS {
        let id = name_id(name);
        let mut error = 0.0;
        for py in 0..SIZE {
            for px in 0..SIZE {
                error += (decoded(&layers, id, py * SIZE + px) - exact(name, px, py)).abs();
            }
        }
        let mae = error / (SIZE * SIZE) as f64;
        eprintln!("instance {name}: mean absolute error of the decoded mask {mae:.4}");
        assert!(mae < 0.02, "{name}: mask error {mae}");
    }
    let asset = img.aov("CryptoAsset00").unwrap();
    for i in 0..img.pixel_count() {
        if img.alpha[i] > 0.0 {
            assert_eq!(asset.data[0][i].to_bits(), name_id("set"));
        }
    }
}

/// The Python interpreter of the decoder checks: `$NIMBUS_PYTHON` (CI's virtual environment), else `python3`.
fn python() -> String {
    std::env::var("NIMBUS_PYTHON").unwrap_or_else(|_| "python3".into())
}

/// Whether [`python`] can import `module`; when it cannot, the test is skipped unless
/// `NIMBUS_REQUIRE_TOOLS=1` (CI), which makes it fail.
fn python_with(module: &str) -> bool {
    let ok = Command::new(python())
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("NIMBUS_REQUIRE_TOOLS").as_deref() != Ok("1"),
            "python3 cannot import {module} and NIMBUS_REQUIRE_TOOLS=1"
        );
        eprintln!("SKIP: python3 cannot import {module} (pip install cryptomatte-api)");
    }
    ok
}

#[test]
fn masks_decode_with_cryptomatte_api() {
    if !python_with("cryptomatte_api") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("nimbus-cryptomatte-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let img = render(&quads_scene(), SIZE, 256);
    let exr = dir.join("quads.exr");
    nimbus::write_exr(&img, &exr).unwrap();
    // The exact coverage of each quad, as raw little-endian floats, row-major from the top row.
    for (name, _, _) in QUADS {
        let bytes: Vec<u8> = (0..SIZE * SIZE)
            .flat_map(|i| (exact(name, i % SIZE, i / SIZE) as f32).to_le_bytes())
            .collect();
        std::fs::write(dir.join(format!("{name}.f32")), bytes).unwrap();
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/cryptomatte/decode_check.py");
    let out = Command::new(python())
        .arg(&script)
        .arg(&exr)
        .arg(&dir)
        .args(QUADS.map(|q| q.0))
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    eprintln!("{text}");
    assert!(
        out.status.success(),
        "cryptomatte-api decoding failed:\n{text}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The folder of the Cycles reference.
fn cycles_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/cryptomatte")
}

#[test]
fn ids_are_those_cycles_5_writes_for_the_same_names() {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(cycles_dir().join("cycles_ids.json")).unwrap())
            .unwrap();
    let scene = Scene::load(&cycles_dir().join("ids_scene.gltf")).unwrap();
    let img = render(&scene, 32, 16);
    let mut checked = 0;
    for (kind, manifest) in &img.cryptomatte {
        let name = kind.layer_name();
        // Cycles' manifests hold the raw hash; its pixels the float ID (the hash with the exponent clamped).
        let cycles_manifest = json["layers"][name].as_object().unwrap();
        let cycles_pixels = json["pixel_id_bits"][name].as_object().unwrap();
        for (object, hex) in cycles_pixels {
            let bits = u32::from_str_radix(hex.as_str().unwrap(), 16).unwrap();
            assert_eq!(
                manifest.get(object),
                Some(&bits),
                "{name} '{object}': Nimbus's ID vs the bits in Cycles' pixels"
            );
            let raw = u32::from_str_radix(cycles_manifest[object].as_str().unwrap(), 16).unwrap();
            assert_eq!(murmur3_32(object.as_bytes(), 0), raw, "{name} '{object}'");
            checked += 1;
        }
        // Every ID in our pixels is one of the manifest's, and every object Cycles saw is in ours.
        let ids: Vec<u32> = manifest.values().copied().collect();
        for layer in rank_layers(&img, name) {
            for (v, c) in layer.data[0].iter().zip(&layer.data[1]) {
                assert!(*c == 0.0 || ids.contains(&v.to_bits()), "{name}: stray ID");
            }
        }
    }
    eprintln!("{checked} names checked against Cycles 5.0's IDs");
    assert_eq!(
        checked,
        6 + 5 + 5,
        "every object, asset and material Cycles rendered"
    );
    // The asset of the rig's children is the rig (Blender's top-most parent).
    let names = scene.names();
    let crate_item = names.items.iter().find(|i| i.object == "Crate").unwrap();
    assert_eq!(crate_item.asset, "Rig");
}
