//! glTF materials (issue 13, items 4 and 5): `KHR_texture_transform` and `texCoord` on every texture,
//! `COLOR_0`, `KHR_materials_unlit`, `KHR_materials_clearcoat`, `KHR_materials_sheen`,
//! `KHR_materials_emissive_strength` with an emissive texture, `occlusionTexture`, and per-texture samplers of
//! one image. The real files of `../shared/realworld/gltf` are checked against their documented look; the
//! rest against values composed here by hand.

use crate::common;

use nimbus::geometry::Mesh;
use nimbus::light::Light;
use nimbus::material::{ShadingPoint, TexCoord, UvTransform};
use nimbus::math::{srgb_to_linear, Mat3, Rgb, Vec2, Vec3, Vec4};
use nimbus::scene::{load_builder, SceneBuilder};
use std::path::{Path, PathBuf};

/// A file of `realworld/gltf`, or `None` (skip) when the shared folder is missing.
fn realworld(rel: &str) -> Option<PathBuf> {
    common::shared_dir().map(|d| d.join("realworld/gltf").join(rel))
}

fn load(path: &Path) -> SceneBuilder {
    load_builder(path, &Default::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The mesh named `name` in world space (a mesh drawn by several nodes is an instance: its placed copy).
fn mesh(b: &SceneBuilder, name: &str) -> Mesh {
    b.world_meshes()
        .into_iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no mesh named {name}"))
}

/// World positions and TEXCOORD_0 at a grid of `n`×`n` barycentric points inside every triangle of `mesh`.
fn surface_points(mesh: &Mesh, n: usize) -> Vec<(Vec3, Vec2)> {
    let uvs = mesh.uvs.as_ref().expect("texture coordinates");
    let mut out = Vec::new();
    for tri in &mesh.indices {
        let [a, b, c] = tri.map(|i| i as usize);
        for i in 0..n {
            for j in 0..n - i {
                let (b1, b2) = ((i as f32 + 0.3) / n as f32, (j as f32 + 0.3) / n as f32);
                let b0 = 1.0 - b1 - b2;
                let p = mesh.positions[a] * b0 + mesh.positions[b] * b1 + mesh.positions[c] * b2;
                out.push((p, uvs[a] * b0 + uvs[b] * b1 + uvs[c] * b2));
            }
        }
    }
    out
}

/// The base colour (× texture) of `mesh`'s material at TEXCOORD_0 `uv`, read at full resolution.
fn base_color(b: &SceneBuilder, mesh: &Mesh, uv: Vec2) -> Vec4 {
    let m = &b.materials()[mesh.material as usize];
    m.base_color_at(&ShadingPoint::from(TexCoord::point(uv)), b.textures())
}

fn centre(mesh: &Mesh) -> Vec3 {
    let b = mesh.bounds();
    (b.min + b.max) * 0.5
}

fn no_warning_about(b: &SceneBuilder, what: &str) {
    assert!(
        !b.warnings().iter().any(|w| w.contains(what)),
        "{what}: {:?}",
        b.warnings()
    );
}

/// The UV test quads show the quadrant of UV.png their offset selects: green "U", blue "V", cyan "UV";
/// never the yellow "not supported" quadrant the untransformed coordinates [0, 0.5]² read.
#[test]
fn texture_transform_offsets_select_the_documented_quadrant() {
    let Some(path) = realworld("TextureTransformTest/TextureTransformTest.gltf") else {
        return;
    };
    let b = load(&path);
    no_warning_about(&b, "KHR_texture_transform");
    // UV.png's quadrants: (192, 192, 0), (0, 192, 0), (0, 0, 192), (0, 192, 192) in sRGB, white marks.
    let class = |c: Vec4| -> &'static str {
        if c.min_element() > 0.8 {
            return "white";
        }
        match (c.x > 0.3, c.y > 0.3, c.z > 0.3) {
            (true, true, false) => "yellow",
            (false, true, false) => "green",
            (false, false, true) => "blue",
            (false, true, true) => "cyan",
            _ => "other",
        }
    };
    for (name, expected) in [
        ("Offset U", "green"),
        ("Offset V", "blue"),
        ("Offset UV", "cyan"),
    ] {
        let m = &mesh(&b, name);
        let mut counts = std::collections::HashMap::new();
        for (_, uv) in surface_points(m, 12) {
            *counts.entry(class(base_color(&b, m, uv))).or_insert(0usize) += 1;
        }
        let total: usize = counts.values().sum();
        let hits = counts.get(expected).copied().unwrap_or(0);
        assert!(
            hits * 2 > total && !counts.contains_key("yellow"),
            "{name}: {counts:?}"
        );
    }
}

/// The arrow quads read Arrow.png through `T · R · S` composed here from the extension's matrices; and the
/// rotated arrow points at its "Correct" marker, not at "Not Supported" (the untransformed look) or "Error".
#[test]
fn texture_transform_rotation_and_scale_follow_the_extension_matrices() {
    let Some(path) = realworld("TextureTransformTest/TextureTransformTest.gltf") else {
        return;
    };
    let b = load(&path);
    let arrow = image::open(path.with_file_name("Arrow.png"))
        .unwrap()
        .to_luma8();
    let (w, h) = (arrow.width() as i64, arrow.height() as i64);
    // The texel under uv (CLAMP_TO_EDGE) when its 3×3 neighbourhood is all black or all white.
    let expected = |uv: Vec2| -> Option<f32> {
        let (x, y) = (
            (uv.x * w as f32).floor() as i64,
            (uv.y * h as f32).floor() as i64,
        );
        let texel = |dx: i64, dy: i64| {
            arrow.get_pixel(
                (x + dx).clamp(0, w - 1) as u32,
                (y + dy).clamp(0, h - 1) as u32,
            )[0]
        };
        let all = |f: &dyn Fn(u8) -> bool| (-1..=1).all(|dy| (-1..=1).all(|dx| f(texel(dx, dy))));
        if all(&|v| v < 10) {
            Some(0.0)
        } else if all(&|v| v > 245) {
            Some(1.0)
        } else {
            None
        }
    };
    let matrix = |offset: Vec2, rotation: f32, scale: Vec2| {
        let t = Mat3::from_cols_array(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, offset.x, offset.y, 1.0]);
        let (s, c) = rotation.sin_cos();
        let r = Mat3::from_cols_array(&[c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0]);
        t * r * Mat3::from_diagonal(Vec3::new(scale.x, scale.y, 1.0))
    };
    for (name, m) in [
        (
            "Rotation",
            matrix(Vec2::ZERO, std::f32::consts::FRAC_PI_8, Vec2::ONE),
        ),
        ("Scale", matrix(Vec2::ZERO, 0.0, Vec2::splat(1.5))),
        ("All", matrix(Vec2::new(-0.2, -0.1), 0.3, Vec2::splat(1.5))),
    ] {
        let quad = &mesh(&b, name);
        let mut compared = 0;
        for (_, uv) in surface_points(quad, 40) {
            let Some(want) = expected((m * uv.extend(1.0)).truncate()) else {
                continue;
            };
            let got = base_color(&b, quad, uv).x;
            assert!(
                (got - want).abs() < 0.02,
                "{name} at uv {uv}: {got} vs {want}"
            );
            compared += 1;
        }
        assert!(compared > 300, "{name}: only {compared} points compared");
    }
    // Where the rotated arrow points: its black texels come closest to the "Correct" marker.
    let quad = &mesh(&b, "Rotation");
    let black: Vec<Vec3> = surface_points(quad, 40)
        .into_iter()
        .filter(|&(_, uv)| base_color(&b, quad, uv).x < 0.1)
        .map(|(p, _)| p)
        .collect();
    let nearest = |marker: &str| {
        let c = centre(&mesh(&b, marker));
        black
            .iter()
            .map(|p| (p.truncate() - c.truncate()).length())
            .fold(f32::INFINITY, f32::min)
    };
    let correct = nearest("Rotation - Correct");
    let not_supported = nearest("Rotation - Not Supported");
    let error = nearest("Rotation - Error");
    assert!(
        correct < 0.6 * not_supported && correct < 0.6 * error,
        "arrow to Correct {correct}, Not Supported {not_supported}, Error {error}"
    );
}

/// A 2×2 RGBA8 PNG as a data URI: texels (left to right, top to bottom) `t`.
fn png_uri(t: [[u8; 4]; 4]) -> String {
    let mut img = image::RgbaImage::new(2, 2);
    for (i, p) in t.iter().enumerate() {
        img.put_pixel(i as u32 % 2, i as u32 / 2, image::Rgba(*p));
    }
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    format!("data:image/png;base64,{}", common::base64(bytes.get_ref()))
}

/// The quad of the in-memory files: (−1, −1, 0) … (1, 1, 0) facing +z, two triangles [0, 1, 2], [0, 2, 3].
const QUAD: [[f32; 3]; 4] = [
    [-1.0, -1.0, 0.0],
    [1.0, -1.0, 0.0],
    [1.0, 1.0, 0.0],
    [-1.0, 1.0, 0.0],
];
/// TEXCOORD_0 and TEXCOORD_1 of the quad: set 1 is set 0 mirrored in u.
const UV0: [[f32; 2]; 4] = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
const UV1: [[f32; 2]; 4] = [[1.0, 1.0], [0.0, 1.0], [0.0, 0.0], [1.0, 0.0]];

/// A one-quad glTF (requiring the extensions implemented here; a camera at z = 3 looks down −z) whose primitive
/// has POSITION, TEXCOORD_0, TEXCOORD_1 and a COLOR_0 given as `(componentType, type, normalized, bytes)`, and
/// material 0 given as JSON; one texture (image `image`, default sampler).
fn quad_gltf(color: (u32, &str, bool, Vec<u8>), material: &str, image: &str) -> String {
    let mut buf = Vec::new();
    for v in QUAD
        .iter()
        .flatten()
        .chain(UV0.iter().flatten())
        .chain(UV1.iter().flatten())
    {
        buf.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    let color_offset = buf.len();
    buf.extend_from_slice(&color.3);
    let (ctype, ty, normalized, bytes) = (color.0, color.1, color.2, color.3.len());
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "extensionsUsed":["KHR_texture_transform","KHR_materials_specular","KHR_materials_clearcoat","KHR_materials_sheen","KHR_materials_unlit","KHR_materials_emissive_strength"],
        "extensionsRequired":["KHR_texture_transform","KHR_materials_clearcoat","KHR_materials_sheen","KHR_materials_unlit"],
        "nodes":[{{"mesh":0}},{{"camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.3,"znear":0.1,"aspectRatio":1.0}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1,"TEXCOORD_1":2,"COLOR_0":4}},"indices":3,"material":0}}]}}],
        "materials":[{material}],
        "textures":[{{"source":0}}],
        "images":[{{"uri":"{image}"}}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
          {{"bufferView":0,"byteOffset":48,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":0,"byteOffset":80,"componentType":5126,"count":4,"type":"VEC2"}},
          {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}},
          {{"bufferView":2,"componentType":{ctype},"normalized":{normalized},"count":4,"type":"{ty}"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":112}},{{"buffer":0,"byteOffset":112,"byteLength":12}},
                       {{"buffer":0,"byteOffset":{color_offset},"byteLength":{bytes}}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{}","byteLength":{}}}]}}"#,
        common::base64(&buf),
        buf.len()
    )
}

fn white_colors() -> (u32, &'static str, bool, Vec<u8>) {
    (5121, "VEC4", true, vec![255; 16])
}

fn write(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-gltf-materials-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Every texture reference, core or extension, carries its texCoord and KHR_texture_transform (the
/// extension's texCoord overriding the reference's).
#[test]
fn every_texture_reference_reads_tex_coord_and_transform() {
    let material = r#"{
      "pbrMetallicRoughness":{
        "baseColorTexture":{"index":0,"extensions":{"KHR_texture_transform":{"offset":[0.5,0],"texCoord":1}}},
        "metallicRoughnessTexture":{"index":0,"texCoord":1,"extensions":{"KHR_texture_transform":{"rotation":0.5}}}},
      "normalTexture":{"index":0,"scale":0.7,"extensions":{"KHR_texture_transform":{"scale":[2,3]}}},
      "occlusionTexture":{"index":0,"strength":0.4,"texCoord":1},
      "emissiveTexture":{"index":0,"extensions":{"KHR_texture_transform":{"offset":[0,0.25]}}},
      "emissiveFactor":[1,1,1],
      "extensions":{
        "KHR_materials_emissive_strength":{"emissiveStrength":4},
        "KHR_materials_clearcoat":{"clearcoatFactor":0.8,"clearcoatTexture":{"index":0,"texCoord":1},
          "clearcoatRoughnessFactor":0.3,
          "clearcoatRoughnessTexture":{"index":0,"extensions":{"KHR_texture_transform":{"rotation":1}}},
          "clearcoatNormalTexture":{"index":0,"scale":0.5,"extensions":{"KHR_texture_transform":{"offset":[0.1,0.2],"texCoord":1}}}},
        "KHR_materials_sheen":{"sheenColorFactor":[0.5,0.4,0.3],"sheenColorTexture":{"index":0,"texCoord":1},
          "sheenRoughnessFactor":0.6,
          "sheenRoughnessTexture":{"index":0,"extensions":{"KHR_texture_transform":{"scale":[0.5,0.5]}}}}}}"#;
    let image = png_uri([[255; 4]; 4]);
    let path = write("refs.gltf", &quad_gltf(white_colors(), material, &image));
    let b = load(&path);
    for ext in ["KHR_texture_transform", "clearcoat", "sheen", "unlit"] {
        no_warning_about(&b, ext);
    }
    let m = &b.materials()[0];
    let t = |id: u32| &b.textures()[id as usize];
    let check = |slot: &str, id: u32, set: usize, x: UvTransform| {
        assert_eq!((t(id).uv_set(), t(id).transform()), (set, x), "{slot}");
    };
    let offset = |x: f32, y: f32| UvTransform {
        offset: Vec2::new(x, y),
        ..Default::default()
    };
    let rotation = |r: f32| UvTransform {
        rotation: r,
        ..Default::default()
    };
    let scale = |x: f32, y: f32| UvTransform {
        scale: Vec2::new(x, y),
        ..Default::default()
    };
    check(
        "baseColor",
        m.base_color_texture.unwrap(),
        1,
        offset(0.5, 0.0),
    );
    check(
        "metallicRoughness",
        m.metallic_roughness_texture.unwrap(),
        1,
        rotation(0.5),
    );
    let (normal, normal_scale) = m.normal_texture.unwrap();
    check("normal", normal, 0, scale(2.0, 3.0));
    assert_eq!(normal_scale, 0.7);
    let (occlusion, strength) = m.occlusion_texture.unwrap();
    check("occlusion", occlusion, 1, UvTransform::default());
    assert_eq!(strength, 0.4);
    check(
        "emissive",
        m.emission_texture.unwrap(),
        0,
        offset(0.0, 0.25),
    );
    let coat = m.clearcoat.unwrap();
    assert_eq!((coat.factor, coat.roughness), (0.8, 0.3));
    check(
        "clearcoat",
        coat.texture.unwrap(),
        1,
        UvTransform::default(),
    );
    check(
        "clearcoatRoughness",
        coat.roughness_texture.unwrap(),
        0,
        rotation(1.0),
    );
    let (coat_normal, coat_scale) = coat.normal_texture.unwrap();
    check("clearcoatNormal", coat_normal, 1, offset(0.1, 0.2));
    assert_eq!(coat_scale, 0.5);
    let sheen = m.sheen.unwrap();
    assert_eq!(
        (sheen.color, sheen.roughness),
        (Rgb::new(0.5, 0.4, 0.3), 0.6)
    );
    check(
        "sheenColor",
        sheen.color_texture.unwrap(),
        1,
        UvTransform::default(),
    );
    check(
        "sheenRoughness",
        sheen.roughness_texture.unwrap(),
        0,
        scale(0.5, 0.5),
    );
    // The same image, decoded once per colour space, is shared by every mapping.
    assert!(std::sync::Arc::ptr_eq(
        t(normal).image(),
        t(coat_normal).image()
    ));
}

/// A texture reading TEXCOORD_1 through an offset reads the mesh's second set; the emissive texture is
/// multiplied by emissiveFactor × emissiveStrength, the same through the material and through the area light
/// that light sampling uses.
#[test]
fn second_uv_set_transform_and_emissive_strength_with_a_texture() {
    // Texels: red, green / blue, white (sRGB 8-bit; 128 decodes to 0.2158 linear).
    let image = png_uri([
        [255, 0, 0, 255],
        [0, 255, 0, 255],
        [0, 0, 128, 255],
        [128, 128, 128, 255],
    ]);
    let material = r#"{"pbrMetallicRoughness":{"metallicFactor":0,
        "baseColorTexture":{"index":0,"extensions":{"KHR_texture_transform":{"offset":[0.5,0],"texCoord":1}}}},
      "emissiveFactor":[1,0.5,1],
      "emissiveTexture":{"index":0,"texCoord":1,"extensions":{"KHR_texture_transform":{"offset":[0,0.5]}}},
      "extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":5}}}"#;
    let path = write("uv1.gltf", &quad_gltf(white_colors(), material, &image));
    let scene = load(&path).build().unwrap();
    // A ray straight down onto (0.5, 0.5): TEXCOORD_0 (0.75, 0.25), TEXCOORD_1 (0.25, 0.25).
    let ray = nimbus::math::Ray::new(Vec3::new(0.5, 0.5, 1.0), -Vec3::Z);
    let hit = scene.intersect(&ray, 0.0, f32::INFINITY).expect("the quad");
    let at = hit.point_shading();
    assert!(at.uv[1].uv.distance(Vec2::new(0.25, 0.25)) < 1e-5);
    let m = &scene.materials()[0];
    // Base colour: set 1 offset by (0.5, 0) → (0.75, 0.25), the green texel's centre.
    let base = m.base_color_at(&at, scene.textures());
    assert!(base.truncate().distance(Vec3::Y) < 1e-5, "{base}");
    // Emission: set 1 offset by (0, 0.5) → (0.25, 0.75), the blue texel (128 → 0.2158), × (1, 0.5, 1) × 5.
    let blue = 0.215_861;
    let expected = Rgb::new(0.0, 0.0, 5.0 * blue);
    let le = m.emission_at(&at, scene.textures());
    assert!(le.distance(expected) < 1e-4, "{le} vs {expected}");
    let light = scene
        .lights()
        .iter()
        .find_map(|l| match l {
            Light::Area(a) if a.prim == hit.prim => Some(a),
            _ => None,
        })
        .expect("the emissive triangle is a light");
    let (b1, b2) = (hit.barycentrics.x, hit.barycentrics.y);
    let from_light = light.radiance(b1, b2, Vec3::Z, scene.textures());
    assert!(
        from_light.distance(expected) < 1e-4,
        "{from_light} vs {expected}"
    );
}

/// COLOR_0 as float vec3, normalised u8 vec4 and normalised u16 vec4: read per vertex, interpolated at the
/// hit, and multiplied into the base colour and its alpha.
#[test]
fn vertex_colors_multiply_the_base_color() {
    let colors: [[f32; 4]; 4] = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 0.5],
        [0.0, 0.0, 1.0, 1.0],
        [1.0, 1.0, 1.0, 0.0],
    ];
    let f32_vec3: Vec<u8> = colors
        .iter()
        .flat_map(|c| c[..3].iter().flat_map(|v| v.to_le_bytes()))
        .collect();
    let u8_vec4: Vec<u8> = colors
        .iter()
        .flat_map(|c| c.map(|v| (v * 255.0).round() as u8))
        .collect();
    let u16_vec4: Vec<u8> = colors
        .iter()
        .flat_map(|c| c.map(|v| (v * 65535.0).round() as u16))
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,0.8]}}"#;
    for (name, color, has_alpha) in [
        ("float vec3", (5126, "VEC3", false, f32_vec3), false),
        ("u8 vec4", (5121, "VEC4", true, u8_vec4), true),
        ("u16 vec4", (5123, "VEC4", true, u16_vec4), true),
    ] {
        let path = write(
            "colors.gltf",
            &quad_gltf(color, material, &png_uri([[255; 4]; 4])),
        );
        let b = load(&path);
        let read = b.meshes()[0].colors.as_ref().expect("COLOR_0 read");
        // The quad has no normals, so its triangles [0, 1, 2] and [0, 2, 3] get their own flat-shaded corners.
        let corners = [0, 1, 2, 0, 2, 3];
        assert_eq!(read.len(), corners.len(), "{name}");
        for (got, want) in read.iter().zip(corners.map(|c| colors[c])) {
            let want = Vec4::new(
                want[0],
                want[1],
                want[2],
                if has_alpha { want[3] } else { 1.0 },
            );
            assert!(got.distance(want) < 2e-3, "{name}: {got} vs {want}");
        }
        let scene = b.build().unwrap();
        // (0.2, −0.2) is in triangle [0, 1, 2] at barycentrics (0.4, 0.2, 0.4).
        let ray = nimbus::math::Ray::new(Vec3::new(0.2, -0.2, 1.0), -Vec3::Z);
        let hit = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap();
        let c = |i: usize| {
            Vec4::new(
                colors[i][0],
                colors[i][1],
                colors[i][2],
                if has_alpha { colors[i][3] } else { 1.0 },
            )
        };
        let want = (c(0) * 0.4 + c(1) * 0.2 + c(2) * 0.4) * Vec4::new(0.5, 0.5, 0.5, 0.8);
        let got = scene.materials()[0].base_color_at(&hit.point_shading(), scene.textures());
        assert!(got.distance(want) < 2e-3, "{name}: {got} vs {want}");
    }
}

/// BoxVertexColors: COLOR_0 (float vec4) is read as the file stores it (decoded here from buffer.bin).
#[test]
fn box_vertex_colors_are_read() {
    let Some(path) = realworld("BoxVertexColors/BoxVertexColors.gltf") else {
        return;
    };
    let b = load(&path);
    no_warning_about(&b, "COLOR");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let accessor = json["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"]
        .as_u64()
        .unwrap() as usize;
    let view =
        &json["bufferViews"][json["accessors"][accessor]["bufferView"].as_u64().unwrap() as usize];
    let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    let bin = std::fs::read(path.with_file_name("buffer.bin")).unwrap();
    let colors = b.meshes()[0].colors.as_ref().expect("COLOR_0");
    assert_eq!(colors.len(), 24);
    for (i, c) in colors.iter().enumerate() {
        let f = |k: usize| {
            let at = offset + 16 * i + 4 * k;
            f32::from_le_bytes(bin[at..at + 4].try_into().unwrap())
        };
        assert_eq!(*c, Vec4::new(f(0), f(1), f(2), f(3)), "vertex {i}");
    }
    assert!(
        colors.iter().any(|c| *c != colors[0]),
        "the box's colours vary"
    );
}

/// KHR_materials_unlit: the surface shows base colour × vertex colour, whatever the lighting (here: none).
#[test]
fn unlit_surfaces_show_their_base_color() {
    let material = r#"{"pbrMetallicRoughness":{"baseColorFactor":[0.2,0.5,0.8,1]},
        "extensions":{"KHR_materials_unlit":{}}}"#;
    // Vertex colour (0.5, 1, 1, 1) everywhere.
    let colors = (
        5126,
        "VEC4",
        false,
        [0.5f32, 1.0, 1.0, 1.0]
            .repeat(4)
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect(),
    );
    let path = write(
        "unlit.gltf",
        &quad_gltf(colors, material, &png_uri([[255; 4]; 4])),
    );
    let b = load(&path);
    no_warning_about(&b, "unlit");
    assert!(b.materials()[0].unlit);
    let (img, _) = common::render_square(b, 8, 4, 4, 7);
    for (c, want) in [0.1, 0.5, 0.8].into_iter().enumerate() {
        let (mean, _) = common::mean_and_se(&img, c);
        assert!((mean - want).abs() < 1e-4, "channel {c}: {mean} vs {want}");
    }
}

/// ClearCoatTest: every coated material carries the file's clearcoat factors and textures.
#[test]
fn clear_coat_test_materials_are_read() {
    let Some(path) = realworld("ClearCoatTest/ClearCoatTest.gltf") else {
        return;
    };
    let b = load(&path);
    no_warning_about(&b, "KHR_materials_clearcoat");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let mut coated = 0;
    for m in json["materials"].as_array().unwrap() {
        let name = m["name"].as_str().unwrap();
        let material = b.materials().iter().find(|x| x.name == name).unwrap();
        let ext = &m["extensions"]["KHR_materials_clearcoat"];
        if ext.is_null() {
            assert!(material.clearcoat.is_none(), "{name}");
            continue;
        }
        coated += 1;
        let c = material
            .clearcoat
            .unwrap_or_else(|| panic!("{name} has no coat"));
        let number = |k: &str| ext[k].as_f64().unwrap_or(0.0) as f32;
        assert_eq!(c.factor, number("clearcoatFactor"), "{name}");
        assert_eq!(c.roughness, number("clearcoatRoughnessFactor"), "{name}");
        assert_eq!(
            c.texture.is_some(),
            !ext["clearcoatTexture"].is_null(),
            "{name}"
        );
        assert_eq!(
            c.roughness_texture.is_some(),
            !ext["clearcoatRoughnessTexture"].is_null(),
            "{name}"
        );
        assert_eq!(
            c.normal_texture.is_some(),
            !ext["clearcoatNormalTexture"].is_null(),
            "{name}"
        );
    }
    assert_eq!(coated, 6);
}

/// TextureSettingsTest: CheckAndX.png and CheckAndX_V.png are each read by three textures with different
/// wrap modes. The model's quads are laid out so that the right wrap mode shows the green check mark (or the
/// green edge bar) and a wrong one a red cross (or the red edge bar): each quad must show green and no red.
/// Sharing one sampler per image (any of the three) puts red on at least one quad.
#[test]
fn texture_settings_rows_follow_each_texture_s_own_sampler() {
    let Some(path) = realworld("TextureSettingsTest/TextureSettingsTest.gltf") else {
        return;
    };
    let b = load(&path);
    for name in [
        "TextureMirrorMeshS",
        "TextureRepeatMeshS",
        "TextureClampMeshS",
        "TextureMirrorMeshT",
        "TextureRepeatMeshT",
        "TextureClampMeshT",
    ] {
        let quad = &mesh(&b, name);
        let (mut green, mut red) = (0, 0);
        for (_, uv) in surface_points(quad, 40) {
            let c = base_color(&b, quad, uv);
            if c.y > 0.2 && c.x < 0.1 {
                green += 1;
            }
            if c.x > 0.4 && c.y < 0.1 {
                red += 1;
            }
        }
        assert!(
            green > 20 && red == 0,
            "{name}: {green} green, {red} red samples"
        );
    }
}

/// KHR_materials_sheen renders: a sheen over black adds light at grazing views (more than head-on), none
/// without it, never more than a white Lambertian would.
#[test]
fn sheen_brightens_grazing_views_of_a_black_base() {
    let with = |sheen: &str| {
        let material = format!(
            r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[0,0,0,1],"metallicFactor":0}},
            "extensions":{{"KHR_materials_specular":{{"specularFactor":0}}{sheen}}}}}"#
        );
        let path = write(
            "sheen.gltf",
            &quad_gltf(white_colors(), &material, &png_uri([[255; 4]; 4])),
        );
        load(&path).build().unwrap()
    };
    let sheen =
        with(r#","KHR_materials_sheen":{"sheenColorFactor":[1,1,1],"sheenRoughnessFactor":0.5}"#);
    let plain = with("");
    let m = &sheen.materials()[0];
    let at = ShadingPoint::from(TexCoord::point(Vec2::splat(0.5)));
    let bsdf = m.bsdf(&at, sheen.textures());
    let albedo = |cos: f32, b: &nimbus::material::Bsdf| {
        let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
        let mut rng = nimbus::math::Rng::new(3, 3);
        let n = 20_000;
        (0..n)
            .filter_map(|_| b.sample(wo, rng.next_f32(), rng.next_2d()))
            .map(|s| (s.f.x * s.wi.z.abs() / s.pdf) as f64)
            .sum::<f64>()
            / n as f64
    };
    let (head_on, grazing) = (albedo(0.95, &bsdf), albedo(0.15, &bsdf));
    assert!(
        grazing > head_on && grazing < 1.0 && head_on > 0.0,
        "{head_on} {grazing}"
    );
    let black = plain.materials()[0].bsdf(&at, plain.textures());
    assert_eq!(albedo(0.15, &black), 0.0);
}

/// Bad extension data is an error naming the material and field, never a panic or a silent default.
#[test]
fn bad_extension_data_is_an_error_naming_the_field() {
    let image = png_uri([[255; 4]; 4]);
    for (material, expected) in [
        (
            r#"{"extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":1,"clearcoatTexture":{"index":9}}}}"#,
            "materials[0].extensions.KHR_materials_clearcoat.clearcoatTexture",
        ),
        (
            r#"{"extensions":{"KHR_materials_sheen":{"sheenRoughnessFactor":"rough"}}}"#,
            "materials[0].extensions.KHR_materials_sheen.sheenRoughnessFactor",
        ),
        (
            r#"{"normalTexture":{"index":0,"extensions":{"KHR_texture_transform":{"scale":[1]}}}}"#,
            "materials[0].normalTexture.extensions.KHR_texture_transform",
        ),
        (
            r#"{"extensions":{"KHR_materials_clearcoat":{"clearcoatNormalTexture":{"index":0,"scale":"x"}}}}"#,
            "clearcoatNormalTexture.scale",
        ),
    ] {
        let path = write("bad.gltf", &quad_gltf(white_colors(), material, &image));
        let err = load_builder(&path, &Default::default())
            .err()
            .unwrap_or_else(|| panic!("{material} loads"));
        assert!(err.to_string().contains(expected), "{err}");
    }
}

/// `transmissionTexture` (red), `specularTexture` (alpha) and `specularColorTexture` (sRGB RGB) multiply their
/// factors per texel, as KHR_materials_transmission and KHR_materials_specular define them. Sampled at the
/// centres of a 2×2 image's top texels (one plain, one bright): transmission 0.8 × 0.2 and 0.8 × 1, specular
/// 0.5 × 0.8 and 0.5 × 0.2, specular colour (1, 0.5, 0.25) × sRGB⁻¹(0.2, 0, 0) and × 1. All three used to be
/// ignored without a word.
#[test]
fn transmission_and_specular_textures_multiply_their_factors() {
    let image = png_uri([[51, 0, 0, 204], [255, 255, 255, 51], [0; 4], [0; 4]]);
    let material = r#"{"pbrMetallicRoughness":{"metallicFactor":0},"extensions":{
        "KHR_materials_transmission":{"transmissionFactor":0.8,"transmissionTexture":{"index":0}},
        "KHR_materials_specular":{"specularFactor":0.5,"specularColorFactor":[1,0.5,0.25],
          "specularTexture":{"index":0},"specularColorTexture":{"index":0}}}}"#;
    let text = quad_gltf(white_colors(), material, &image).replace(
        r#""extensionsUsed":["#,
        r#""extensionsUsed":["KHR_materials_transmission","#,
    );
    let b = load(&write("transmission_specular_textures.gltf", &text));
    let m = &b.materials()[0];
    let at = |u: f32| {
        m.pbr_params(
            &ShadingPoint::from(TexCoord::point(Vec2::new(u, 0.25))),
            b.textures(),
        )
    };
    let srgb_02 = ((0.2f32 + 0.055) / 1.055).powf(2.4);
    for (u, transmission, specular, color) in [
        (0.25, 0.16, 0.4, Vec3::new(srgb_02, 0.0, 0.0)),
        (0.75, 0.8, 0.1, Vec3::new(1.0, 0.5, 0.25)),
    ] {
        let p = at(u);
        let what = format!("u = {u}: {p:?}");
        assert!((p.transmission - transmission).abs() < 2e-3, "{what}");
        assert!((p.specular_factor - specular).abs() < 2e-3, "{what}");
        assert!(
            (p.specular_color - color).abs().max_element() < 2e-3,
            "{what}"
        );
    }
}

/// The textures of `KHR_materials_iridescence` (`iridescenceTexture` red × factor; `iridescenceThicknessTexture`
/// green between the minimum and maximum thickness) and `KHR_materials_diffuse_transmission`
/// (`diffuseTransmissionTexture` alpha × factor; `diffuseTransmissionColorTexture` sRGB RGB × colour) are read
/// per texel, as the extensions define them: at the same two texels as above, iridescence 0.5 × 0.2 and 0.5 × 1,
/// thickness 100 and 400 nm, diffuse transmission 0.5 × 0.8 and 0.5 × 0.2, colour (1, 0.5, 0.25) × sRGB⁻¹(0.2,
/// 0, 0) and × 1.
#[test]
fn iridescence_and_diffuse_transmission_textures_are_read_per_texel() {
    let image = png_uri([[51, 0, 0, 204], [255, 255, 255, 51], [0; 4], [0; 4]]);
    let material = r#"{"pbrMetallicRoughness":{"metallicFactor":0},"extensions":{
        "KHR_materials_iridescence":{"iridescenceFactor":0.5,"iridescenceTexture":{"index":0},
          "iridescenceThicknessMinimum":100,"iridescenceThicknessMaximum":400,
          "iridescenceThicknessTexture":{"index":0}},
        "KHR_materials_diffuse_transmission":{"diffuseTransmissionFactor":0.5,
          "diffuseTransmissionTexture":{"index":0},"diffuseTransmissionColorFactor":[1,0.5,0.25],
          "diffuseTransmissionColorTexture":{"index":0}}}}"#;
    let text = quad_gltf(white_colors(), material, &image).replace(
        r#""extensionsUsed":["#,
        r#""extensionsUsed":["KHR_materials_iridescence","KHR_materials_diffuse_transmission","#,
    );
    let b = load(&write("iridescence_diffuse_textures.gltf", &text));
    let m = &b.materials()[0];
    let srgb_02 = ((0.2f32 + 0.055) / 1.055).powf(2.4);
    for (u, iridescence, thickness, transmission, color) in [
        (0.25, 0.1, 100.0, 0.4, Vec3::new(srgb_02, 0.0, 0.0)),
        (0.75, 0.5, 400.0, 0.1, Vec3::new(1.0, 0.5, 0.25)),
    ] {
        let p = m.pbr_params(
            &ShadingPoint::from(TexCoord::point(Vec2::new(u, 0.25))),
            b.textures(),
        );
        let what = format!("u = {u}: {p:?}");
        assert!((p.iridescence - iridescence).abs() < 2e-3, "{what}");
        assert!((p.iridescence_thickness - thickness).abs() < 0.5, "{what}");
        assert!(
            (p.diffuse_transmission - transmission).abs() < 2e-3,
            "{what}"
        );
        assert!(
            (p.diffuse_transmission_color - color).abs().max_element() < 2e-3,
            "{what}"
        );
    }
}

/// `quad_gltf` with `KHR_materials_pbrSpecularGlossiness` also used and required.
fn spec_gloss_gltf(material: &str, image: &str) -> String {
    quad_gltf(white_colors(), material, image)
        .replace(
            r#""extensionsUsed":["#,
            r#""extensionsUsed":["KHR_materials_pbrSpecularGlossiness","#,
        )
        .replace(
            r#""extensionsRequired":["#,
            r#""extensionsRequired":["KHR_materials_pbrSpecularGlossiness","#,
        )
}

/// A file requiring KHR_materials_pbrSpecularGlossiness loads (it used to be refused), and its factors become
/// the metallic-roughness the extension's Khronos converter gives, computed by hand (perceived brightness
/// P(c) = √(0.299 r² + 0.587 g² + 0.114 b²), dielectric F0 0.04; see `nimbus::material::spec_gloss`).
#[test]
fn specular_glossiness_factors_convert_to_metallic_roughness() {
    let image = png_uri([[255; 4]; 4]);
    // (diffuseFactor, specularFactor, glossinessFactor) -> (base colour, metallic, roughness).
    let cases = [
        // Pure dielectric: specular 0.04 grey, so c = 0.04 − S = 0 and the root is m = 0; b = d · 0.96 / 0.96.
        (
            "[0.6,0.3,0.1,1]",
            "[0.04,0.04,0.04]",
            0.7,
            [0.6, 0.3, 0.1],
            0.0,
            0.3,
        ),
        // Pure metal: black diffuse, so D = 0, the discriminant is (S − 0.08)² + 0.16 (S − 0.04) = S² and
        // m = (S − (S − 0.08)) / 0.08 = 1; b = (s − 0) / 1 = s.
        ("[0,0,0,1]", "[0.9,0.6,0.3]", 0.2, [0.9, 0.6, 0.3], 1.0, 0.8),
        // Mixed: d = (0.8, 0.2, 0.2), s = 0.3 grey. P(d) = √0.2194 = 0.468402, D = 0.7 · P(d) = 0.327881,
        // S = 0.3; b = D / 0.96 + 0.3 − 0.08 = 0.561543, c = −0.26, discriminant b² + 0.0416 = 0.356930,
        // m = (0.597437 − 0.561543) / 0.08 = 0.448671. From the diffuse: d · 0.7 / (0.96 · 0.551329) =
        // (1.058049, 0.264512, 0.264512); from the specular: (0.3 − 0.04 · 0.551329) / 0.448671 = 0.619490;
        // blended by m² = 0.201305: (0.969764, 0.335971, 0.335971).
        (
            "[0.8,0.2,0.2,1]",
            "[0.3,0.3,0.3]",
            0.5,
            [0.969764, 0.335971, 0.335971],
            0.448671,
            0.5,
        ),
    ];
    for (diffuse, specular, gloss, base, metallic, roughness) in cases {
        // The core metallic-roughness is the fallback for viewers without the extension: unread.
        let material = format!(
            r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[0,0,1,1],"metallicFactor":0.5,"baseColorTexture":{{"index":0}}}},
            "extensions":{{"KHR_materials_pbrSpecularGlossiness":{{
            "diffuseFactor":{diffuse},"specularFactor":{specular},"glossinessFactor":{gloss}}}}}}}"#
        );
        let path = write("spec_gloss.gltf", &spec_gloss_gltf(&material, &image));
        let b = load(&path);
        no_warning_about(&b, "pbrSpecularGlossiness");
        let m = &b.materials()[0];
        assert_eq!(m.base_color_texture, None, "the fallback is not read");
        let p = m.pbr_params(
            &ShadingPoint::from(TexCoord::point(Vec2::splat(0.5))),
            b.textures(),
        );
        let what = format!("{diffuse} {specular} {gloss}: {p:?}");
        assert!(
            (p.base_color - Vec3::from(base)).abs().max_element() < 2e-5,
            "{what}"
        );
        assert!((p.metallic - metallic).abs() < 2e-5, "{what}");
        assert!((p.roughness - roughness).abs() < 1e-6, "{what}");
    }
}

/// The specular-glossiness model's dielectric F0 is 0.04: `KHR_materials_ior` and `KHR_materials_specular`,
/// which its specification excludes beside it, are not read (ior 1.5, specular 1), with a warning. They used to
/// be applied on top of the conversion.
#[test]
fn specular_glossiness_ignores_ior_and_specular() {
    let image = png_uri([[255; 4]; 4]);
    let material = r#"{"extensions":{"KHR_materials_pbrSpecularGlossiness":{"diffuseFactor":[0.5,0.5,0.5,1]},
        "KHR_materials_ior":{"ior":2.0},"KHR_materials_specular":{"specularFactor":0.25}}}"#;
    let path = write("spec_gloss_ior.gltf", &spec_gloss_gltf(material, &image));
    let b = load(&path);
    let m = &b.materials()[0];
    assert_eq!((m.ior, m.specular_factor), (1.5, 1.0));
    assert!(
        b.warnings()
            .iter()
            .any(|w| w.contains("KHR_materials_ior") && w.contains("not read")),
        "{:?}",
        b.warnings()
    );
}

/// Both textures are read, each through its own UV set and transform, and converted per point: the diffuse
/// texture's sRGB colour and linear alpha, the specular-glossiness texture's sRGB specular and linear
/// glossiness, times their factors.
#[test]
fn specular_glossiness_textures_convert_per_texel_through_their_own_mapping() {
    // Texels (row-major, 2×2): the diffuse reads (0, 0) at TEXCOORD_0 (0.25, 0.25); the specular-glossiness
    // texture reads TEXCOORD_1 = (0.75, 0.25) offset by (0, 0.5): texel (1, 1).
    let texels = [
        [200, 120, 40, 204],
        [10, 10, 10, 255],
        [0, 0, 0, 255],
        [90, 60, 30, 128],
    ];
    let material = r#"{"extensions":{"KHR_materials_pbrSpecularGlossiness":{
        "diffuseFactor":[1,0.5,1,0.8],"diffuseTexture":{"index":0},
        "specularFactor":[1,1,0.5],"glossinessFactor":0.9,
        "specularGlossinessTexture":{"index":0,"texCoord":1,"extensions":{"KHR_texture_transform":{"offset":[0,0.5]}}}}}}"#;
    let path = write(
        "spec_gloss_textured.gltf",
        &spec_gloss_gltf(material, &png_uri(texels)),
    );
    let b = load(&path);
    let m = &b.materials()[0];
    let sg = m.specular_glossiness.expect("the extension is read");
    let t = |id: Option<u32>| &b.textures()[id.unwrap() as usize];
    assert_eq!(
        (
            t(sg.diffuse_texture).uv_set(),
            t(sg.diffuse_texture).transform()
        ),
        (0, UvTransform::default())
    );
    let offset = UvTransform {
        offset: Vec2::new(0.0, 0.5),
        ..Default::default()
    };
    let sg_texture = t(sg.specular_glossiness_texture);
    assert_eq!((sg_texture.uv_set(), sg_texture.transform()), (1, offset));
    let at = ShadingPoint {
        uv: [
            TexCoord::point(Vec2::new(0.25, 0.25)),
            TexCoord::point(Vec2::new(0.75, 0.25)),
        ],
        color: Vec4::ONE,
    };
    let srgb = |t: [u8; 4]| Rgb::from([t[0], t[1], t[2]].map(|v| srgb_to_linear(v as f32 / 255.0)));
    let diffuse = Rgb::new(1.0, 0.5, 1.0) * srgb(texels[0]);
    let specular = Rgb::new(1.0, 1.0, 0.5) * srgb(texels[3]);
    let glossiness = 0.9 * 128.0 / 255.0;
    let want = nimbus::material::to_metallic_roughness(diffuse, specular, glossiness);
    let p = m.pbr_params(&at, b.textures());
    assert!(want.metallic > 0.05 && want.metallic < 0.95, "{want:?}");
    assert!(
        (p.base_color - want.base_color).abs().max_element() < 1e-4
            && (p.metallic - want.metallic).abs() < 1e-4
            && (p.roughness - want.roughness).abs() < 1e-4,
        "{p:?} vs {want:?}"
    );
    let alpha = m.base_color_at(&at, b.textures()).w;
    assert!((alpha - 0.8 * 204.0 / 255.0).abs() < 1e-5, "alpha {alpha}");
}

/// Bad KHR_materials_pbrSpecularGlossiness values are errors naming the field.
#[test]
fn bad_specular_glossiness_values_are_errors_naming_the_field() {
    let image = png_uri([[255; 4]; 4]);
    let at = "materials[0].extensions.KHR_materials_pbrSpecularGlossiness";
    for (ext, field) in [
        (r#"{"diffuseFactor":[1,1,1]}"#, ".diffuseFactor"),
        (r#"{"diffuseFactor":[1,1,1.5,1]}"#, ".diffuseFactor"),
        (r#"{"specularFactor":[-0.1,0,0]}"#, ".specularFactor"),
        (r#"{"glossinessFactor":"glossy"}"#, ".glossinessFactor"),
        (r#"{"glossinessFactor":2}"#, ".glossinessFactor"),
        (r#"{"diffuseTexture":{"index":9}}"#, ".diffuseTexture"),
        (
            r#"{"specularGlossinessTexture":{"index":0,"texCoord":-1}}"#,
            ".specularGlossinessTexture.texCoord",
        ),
        ("[]", " must be an object"),
    ] {
        let material =
            format!(r#"{{"extensions":{{"KHR_materials_pbrSpecularGlossiness":{ext}}}}}"#);
        let path = write("bad_spec_gloss.gltf", &spec_gloss_gltf(&material, &image));
        let err = load_builder(&path, &Default::default())
            .err()
            .unwrap_or_else(|| panic!("{ext} loads"));
        assert!(
            err.to_string().contains(&format!("{at}{field}")),
            "{ext}: {err}"
        );
    }
}
