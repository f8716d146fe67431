//! `KHR_materials_anisotropy`: the extension's keys read and checked, tangents made for anisotropic meshes, and a
//! render of an anisotropic metal plane against a Mitsuba 3 reference
//! (tests/validation/anisotropy/mitsuba_reference.py).

use crate::common;

use nimbus::material::{Bsdf, ShadingPoint, TexCoord};
use nimbus::math::{Vec2, Vec3};
use nimbus::render::{RenderSettings, Renderer};
use nimbus::scene::{load_builder, SceneBuilder};
use std::path::PathBuf;

/// Half the side of the plane: far wider than the orthographic camera's view of it.
const HALF: f32 = 50.0;

/// A glTF of one square of side `2 HALF` in z = 0 facing +z (POSITION, NORMAL, TEXCOORD_0 with u along +x and v
/// down the image, i.e. along −y, so that MikkTSpace's tangent is +x and its bitangent +y), with material 0
/// given as JSON and one texture of image `image`; an orthographic camera 10 units away along `view` looking at
/// the origin; a constant environment of radiance 1.
fn plane_gltf(material: &str, image: &str, view: Vec3) -> String {
    let mut buf = Vec::new();
    let corners = [[-HALF, -HALF], [HALF, -HALF], [HALF, HALF], [-HALF, HALF]];
    for [x, y] in corners {
        for v in [x, y, 0.0] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }
    for _ in corners {
        for v in [0.0f32, 0.0, 1.0] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }
    for [x, y] in corners {
        for v in [(x + HALF) / (2.0 * HALF), (HALF - y) / (2.0 * HALF)] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    // The camera looks down its −z: z = view, x horizontal.
    let z = view.normalize();
    let up = if z.z.abs() > 0.9 { Vec3::Y } else { Vec3::Z };
    let x = up.cross(z).normalize();
    let y = z.cross(x);
    let t = 10.0 * z;
    let matrix = [
        x.x, x.y, x.z, 0.0, y.x, y.y, y.z, 0.0, z.x, z.y, z.z, 0.0, t.x, t.y, t.z, 1.0,
    ]
    .map(|v| v.to_string())
    .join(",");
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,
        "scenes":[{{"nodes":[0,1],"extras":{{"nimbus_environment":{{"color":[1,1,1]}}}}}}],
        "extensionsUsed":["KHR_materials_anisotropy"],
        "nodes":[{{"mesh":0,"name":"plane"}},{{"camera":0,"matrix":[{matrix}]}}],
        "cameras":[{{"type":"orthographic","orthographic":{{"xmag":1,"ymag":1,"znear":0.1,"zfar":100}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3,"material":0}}]}}],
        "materials":[{material}],
        "textures":[{{"source":0}}],
        "images":[{{"uri":"{image}"}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-{HALF},-{HALF},0],"max":[{HALF},{HALF},0]}},
          {{"bufferView":0,"byteOffset":48,"componentType":5126,"count":4,"type":"VEC3"}},
          {{"bufferView":0,"byteOffset":96,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":128}},{{"buffer":0,"byteOffset":128,"byteLength":12}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{}","byteLength":{}}}]}}"#,
        common::base64(&buf),
        buf.len()
    )
}

/// A 1×1 PNG of one RGBA texel, as a data URI.
fn png_uri(texel: [u8; 4]) -> String {
    let mut img = image::RgbaImage::new(1, 1);
    img.put_pixel(0, 0, image::Rgba(texel));
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    format!("data:image/png;base64,{}", common::base64(bytes.get_ref()))
}

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-gltf-anisotropy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A metal of base colour 1 (Schlick Fresnel 1) and roughness 0.3 with `KHR_materials_anisotropy` given as the
/// JSON object `anisotropy`.
fn metal(anisotropy: &str) -> String {
    format!(
        r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,1],"metallicFactor":1,"roughnessFactor":0.3}},
        "extensions":{{"KHR_materials_anisotropy":{anisotropy}}}}}"#
    )
}

fn load(name: &str, material: &str, texel: [u8; 4]) -> SceneBuilder {
    let path = write(name, &plane_gltf(material, &png_uri(texel), Vec3::Z));
    load_builder(&path, &Default::default()).unwrap()
}

fn view(theta: f32, phi: f32) -> Vec3 {
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

#[test]
fn the_extension_is_read_with_its_texture_and_the_mesh_gets_tangents() {
    // Texel RG = the direction at 60° from the tangent, B = 0.5; rotation 30° more: the bitangent, strength
    // 0.8 × 0.5.
    let (c, s) = (60f32.to_radians().cos(), 60f32.to_radians().sin());
    let texel = [
        ((0.5 + 0.5 * c) * 255.0).round() as u8,
        ((0.5 + 0.5 * s) * 255.0).round() as u8,
        128,
        255,
    ];
    let b = load(
        "read.gltf",
        &metal(&format!(
            r#"{{"anisotropyStrength":0.8,"anisotropyRotation":{},"anisotropyTexture":{{"index":0}}}}"#,
            30f32.to_radians()
        )),
        texel,
    );
    assert!(
        b.warnings().iter().all(|w| !w.contains("anisotropy")),
        "{:?}",
        b.warnings()
    );
    let a = b.materials()[0].anisotropy.expect("anisotropy read");
    assert_eq!(a.strength, 0.8);
    assert!((a.rotation - 30f32.to_radians()).abs() < 1e-6);
    assert!(a.texture.is_some());
    assert!(b.meshes()[0].tangents.is_none());
    let scene = b.build().unwrap();
    let tangents = scene.meshes()[0]
        .tangents
        .as_ref()
        .expect("MikkTSpace tangents");
    for t in tangents {
        assert!(
            (t.truncate() - Vec3::X).length() < 1e-5 && t.w == 1.0,
            "{t}"
        );
    }
    let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
    let p = scene.materials()[0].pbr_params(&at, scene.textures());
    assert!((p.anisotropy_strength - 0.8 * 128.0 / 255.0).abs() < 1e-3);
    let d = p.anisotropy_direction;
    assert!((d - Vec2::Y).length() < 0.02, "direction {d}");
    let Bsdf::Pbr(pbr) = Bsdf::from_gltf(&p) else {
        panic!("expected the metallic-roughness BSDF");
    };
    let s = p.anisotropy_strength;
    assert!((pbr.specular.alpha_x - (0.09 + 0.91 * s * s)).abs() < 1e-5);
    assert!((pbr.specular.alpha_y - 0.09).abs() < 1e-6);
}

#[test]
fn a_mesh_without_texture_coordinates_warns_that_its_direction_is_arbitrary() {
    let text = plane_gltf(
        &metal(r#"{"anisotropyStrength":0.5}"#),
        &png_uri([255; 4]),
        Vec3::Z,
    )
    .replace(r#","TEXCOORD_0":2"#, "");
    let path = write("no-uv.gltf", &text);
    let scene = load_builder(&path, &Default::default())
        .unwrap()
        .build()
        .unwrap();
    assert!(scene.meshes()[0].tangents.is_none());
    assert!(
        scene
            .warnings()
            .iter()
            .any(|w| w.contains("neither tangents nor texture coordinates")),
        "{:?}",
        scene.warnings()
    );
}

#[test]
fn defaults_and_bad_values() {
    // An empty extension object is strength 0: exactly the isotropic BSDF.
    let b = load("empty.gltf", &metal("{}"), [255; 4]);
    let scene = b.build().unwrap();
    let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
    let m = &scene.materials()[0];
    let mut plain = m.clone();
    plain.anisotropy = None;
    assert_eq!(
        m.bsdf(&at, scene.textures()),
        plain.bsdf(&at, scene.textures())
    );
    for (ext, expected) in [
        (
            r#"{"anisotropyStrength":1.5}"#,
            "KHR_materials_anisotropy.anisotropyStrength",
        ),
        (
            r#"{"anisotropyStrength":-0.1}"#,
            "KHR_materials_anisotropy.anisotropyStrength",
        ),
        (
            r#"{"anisotropyRotation":"left"}"#,
            "KHR_materials_anisotropy.anisotropyRotation",
        ),
        (
            r#"{"anisotropyTexture":{"index":7}}"#,
            "KHR_materials_anisotropy.anisotropyTexture",
        ),
        (r#"[1]"#, "KHR_materials_anisotropy must be an object"),
    ] {
        let path = write(
            "bad.gltf",
            &plane_gltf(&metal(ext), &png_uri([255; 4]), Vec3::Z),
        );
        let err = load_builder(&path, &Default::default())
            .err()
            .unwrap_or_else(|| panic!("{ext} loads"));
        assert!(err.to_string().contains(expected), "{ext}: {err}");
    }
}

/// The references of tests/validation/anisotropy/mitsuba_reference.py (Mitsuba 3.9.1, `llvm_ad_rgb`): the
/// directional albedo of the GGX metal with α_u = 0.8271, α_v = 0.09 (roughness 0.3, strength 0.9), Fresnel 1,
/// from Mitsuba's `MicrofacetDistribution` (its D, visible-normal sampling and Smith G1) combined into the
/// height-correlated G2 that Nimbus uses, 4·10⁶ samples: (case, rotation, view θ, view φ, mean, standard error).
/// The script also renders the plane with Mitsuba's `roughconductor` (separable G) and checks that its
/// estimator reproduces that render.
const MITSUBA: [(&str, f32, f32, f32, f64, f64); 4] = [
    ("view along the tangent", 0.0, 1.3, 0.0, 0.786003, 0.000157),
    (
        "view along the bitangent",
        0.0,
        1.3,
        std::f32::consts::FRAC_PI_2,
        0.600631,
        0.000195,
    ),
    // The rotation is counter-clockwise (tangent toward bitangent): turned the other way the view would be 1.4
    // radians off the anisotropy direction, not 0.4.
    (
        "rotation 0.5, view at azimuth 0.9",
        0.5,
        1.3,
        0.9,
        0.777056,
        0.000160,
    ),
    ("head-on view", 0.0, 0.2, 0.0, 0.621074, 0.000200),
];

#[test]
fn anisotropic_metal_plane_matches_mitsuba() {
    for (k, (case, rotation, theta, phi, reference, reference_se)) in
        MITSUBA.into_iter().enumerate()
    {
        let material = metal(&format!(
            r#"{{"anisotropyStrength":0.9,"anisotropyRotation":{rotation}}}"#
        ));
        let path = write(
            &format!("plane{k}.gltf"),
            &plane_gltf(&material, &png_uri([255; 4]), view(theta, phi)),
        );
        let scene = load_builder(&path, &Default::default())
            .unwrap()
            .build()
            .unwrap();
        let settings = RenderSettings {
            width: 32,
            height: 32,
            spp: 512,
            seed: 11 + k as u64,
            threads: 2,
            max_depth: 4,
            ..Default::default()
        };
        let (img, _) = Renderer::new(settings)
            .render(&scene, &mut |_| true)
            .unwrap();
        assert!(img.beauty.iter().all(|p| p.is_finite()));
        let (mean, se) = common::mean_and_se(&img, 0);
        let z = (mean - reference) / se.hypot(reference_se);
        eprintln!(
            "{case}: Nimbus {mean:.6} ± {se:.6}, Mitsuba {reference:.6} ± {reference_se:.6}, z {z:+.2}"
        );
        assert!(z.abs() < 4.0, "{case}: z {z}");
    }
}
