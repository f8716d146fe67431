//! glTF geometry beyond plain float accessors (issue 13, item 4, and item 3's tangents): sparse accessors,
//! `KHR_mesh_quantization`, morph targets at their default weights, skins at their rest pose, and MikkTSpace
//! tangents for normal maps. Expected values come from the files' own data read here by hand, from closed forms
//! and from the real files' documented look, never from Nimbus.

use crate::common;

use nimbus::math::{Mat4, Quat, Vec2, Vec3};
use nimbus::scene::{load_builder, Camera, LoadOptions, SceneBuilder, SceneErrorKind};
use nimbus::{RenderSettings, Renderer};
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "nimbus-gltf-geometry-{}-{name}",
        std::process::id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn le<T: Copy, const N: usize>(values: &[T], to: fn(T) -> [u8; N]) -> Vec<u8> {
    values.iter().flat_map(|&v| to(v)).collect()
}

fn f32s(v: &[f32]) -> Vec<u8> {
    le(v, f32::to_le_bytes)
}

fn u16s(v: &[u16]) -> Vec<u8> {
    le(v, u16::to_le_bytes)
}

fn i16s(v: &[i16]) -> Vec<u8> {
    le(v, i16::to_le_bytes)
}

/// A glTF document assembled in a test: one external buffer of views, and accessors given as JSON.
#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    /// Each view's byte offset in `bin`.
    offsets: Vec<usize>,
    views: Vec<String>,
    accessors: Vec<String>,
}

impl Doc {
    /// Appends `bytes` (4-byte aligned) as a new buffer view; returns its index.
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.offsets.push(self.bin.len());
        self.views.push(format!(
            r#"{{"buffer":0,"byteOffset":{},"byteLength":{}}}"#,
            self.bin.len(),
            bytes.len()
        ));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// Adds an accessor given as JSON; returns its index.
    fn accessor(&mut self, json: String) -> usize {
        self.accessors.push(json);
        self.accessors.len() - 1
    }

    /// Writes `name.gltf` and its buffer into `dir`; `rest` holds the other top-level members (after a comma).
    fn write(&self, dir: &Path, name: &str, rest: &str) -> PathBuf {
        std::fs::write(dir.join(format!("{name}.bin")), &self.bin).unwrap();
        let text = format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{name}.bin","byteLength":{}}}],"bufferViews":[{}],"accessors":[{}],{rest}}}"#,
            self.bin.len(),
            self.views.join(","),
            self.accessors.join(",")
        );
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, text).unwrap();
        path
    }
}

fn load(path: &Path) -> SceneBuilder {
    load_builder(path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    a.distance(b) <= tol
}

/// The `count` VEC3 floats of accessor `index` of a real glTF file, read here from its JSON and buffer.
fn real_vec3s(dir: &Path, json: &serde_json::Value, index: usize) -> Vec<Vec3> {
    let a = &json["accessors"][index];
    assert_eq!(a["componentType"], 5126);
    assert!(a.get("sparse").is_none());
    let view = &json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
    let buffer = &json["buffers"][view["buffer"].as_u64().unwrap() as usize];
    let bin = std::fs::read(dir.join(buffer["uri"].as_str().unwrap())).unwrap();
    let start = view["byteOffset"].as_u64().unwrap_or(0) + a["byteOffset"].as_u64().unwrap_or(0);
    let stride = view["byteStride"].as_u64().unwrap_or(12);
    let f = |at: u64| f32::from_le_bytes(bin[at as usize..at as usize + 4].try_into().unwrap());
    (0..a["count"].as_u64().unwrap())
        .map(|i| {
            let at = start + i * stride;
            Vec3::new(f(at), f(at + 4), f(at + 8))
        })
        .collect()
}

#[test]
fn the_real_sparse_accessor_raises_its_three_vertices() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let path = shared.join("realworld/gltf/SimpleSparseAccessor/SimpleSparseAccessor.gltf");
    let builder = load(&path);
    let mesh = &builder.meshes()[0];
    // The base view is a 7 × 2 grid of points (x = 0..6, y = 0 and 1); the sparse accessor moves the top
    // row's vertices 8, 10 and 12 (x = 1, 3, 5) up to y = 2, 3 and 4 (the model's README figure), so that the
    // accessor's declared max, [6, 4, 0], is reached. The file has no normals, so each triangle gets its own
    // (flat-shaded) corners: every corner must be one of the 14 expected points, and the three raised points
    // must be used while the three base points they replace must not.
    let expected: Vec<Vec3> = (0..14)
        .map(|i| match i {
            8 => Vec3::new(1.0, 2.0, 0.0),
            10 => Vec3::new(3.0, 3.0, 0.0),
            12 => Vec3::new(5.0, 4.0, 0.0),
            _ => Vec3::new((i % 7) as f32, (i / 7) as f32, 0.0),
        })
        .collect();
    for p in &mesh.positions {
        assert!(
            expected.iter().any(|w| close(*p, *w, 1e-6)),
            "corner {p} is not a point of the sparse grid"
        );
    }
    let used = |w: Vec3| mesh.positions.iter().any(|p| close(*p, w, 1e-6));
    for i in [8, 10, 12] {
        assert!(used(expected[i]), "raised vertex {i} is not used");
        let base = Vec3::new((i % 7) as f32, 1.0, 0.0);
        assert!(!used(base), "vertex {i} kept its base position {base}");
    }
    let bounds = builder.build().unwrap().bounds();
    assert!(close(bounds.max, Vec3::new(6.0, 4.0, 0.0), 1e-6));
}

/// A quad whose POSITION, indices, TEXCOORD_0 and morph target are sparse: the positions over a base view with
/// u32 sparse indices, the others without a view (zeros) with u8 or u16 sparse indices.
fn sparse_quad(dir: &Path, name: &str, edit: impl Fn(&mut Doc, [usize; 6])) -> PathBuf {
    let mut d = Doc::default();
    let base = d.view(&f32s(&[0., 0., 0., 1., 0., 0., 1., 1., 0., 0., 1., 0.]));
    let pos_idx = d.view(&le(&[1u32, 3], u32::to_le_bytes));
    let pos_val = d.view(&f32s(&[2., 0., 0., 0., 3., 0.]));
    let ind_idx = d.view(&[1u8, 2, 4, 5]);
    let ind_val = d.view(&u16s(&[1, 2, 2, 3]));
    let uv_idx = d.view(&u16s(&[2]));
    let uv_val = d.view(&f32s(&[0.5, 0.25]));
    let morph_idx = d.view(&[0u8]);
    let morph_val = d.view(&f32s(&[0., 0., 1.]));
    d.accessor(format!(
        r#"{{"bufferView":{base},"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[2,3,0],
        "sparse":{{"count":2,"indices":{{"bufferView":{pos_idx},"componentType":5125}},"values":{{"bufferView":{pos_val}}}}}}}"#
    ));
    d.accessor(format!(
        r#"{{"componentType":5123,"count":6,"type":"SCALAR",
        "sparse":{{"count":4,"indices":{{"bufferView":{ind_idx},"componentType":5121}},"values":{{"bufferView":{ind_val}}}}}}}"#
    ));
    d.accessor(format!(
        r#"{{"componentType":5126,"count":4,"type":"VEC2",
        "sparse":{{"count":1,"indices":{{"bufferView":{uv_idx},"componentType":5123}},"values":{{"bufferView":{uv_val}}}}}}}"#
    ));
    d.accessor(format!(
        r#"{{"componentType":5126,"count":4,"type":"VEC3",
        "sparse":{{"count":1,"indices":{{"bufferView":{morph_idx},"componentType":5121}},"values":{{"bufferView":{morph_val}}}}}}}"#
    ));
    edit(
        &mut d,
        [pos_idx, pos_val, ind_idx, ind_val, uv_idx, morph_idx],
    );
    d.write(
        dir,
        name,
        r#""scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"weights":[0.5],"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":2},"indices":1,"targets":[{"POSITION":3}]}]}]"#,
    )
}

#[test]
fn hand_built_sparse_accessors_with_and_without_a_base_view() {
    let dir = temp_dir("sparse");
    let builder = load(&sparse_quad(&dir, "quad", |_, _| {}));
    let mesh = &builder.meshes()[0];
    // Vertex 0 gets half of the sparse morph displacement (0, 0, 1); vertices 1 and 3 the sparse positions.
    let want = [
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 3.0, 0.0),
    ];
    // Without normals the triangles [0, 1, 2] and [0, 2, 3] get their own flat-shaded corners.
    let corners = [0, 1, 2, 0, 2, 3];
    assert_eq!(mesh.positions.len(), corners.len());
    for (p, &c) in mesh.positions.iter().zip(&corners) {
        assert!(close(*p, want[c], 1e-6), "{p} != {}", want[c]);
    }
    assert_eq!(mesh.indices, vec![[0, 1, 2], [3, 4, 5]]);
    let uvs = mesh.uvs.as_ref().unwrap();
    for (uv, &c) in uvs.iter().zip(&corners) {
        let w = if c == 2 {
            Vec2::new(0.5, 0.25)
        } else {
            Vec2::ZERO
        };
        assert_eq!(*uv, w, "corner of vertex {c}");
    }
}

#[test]
fn malformed_sparse_accessors_are_errors_naming_the_problem() {
    let dir = temp_dir("sparse-bad");
    type Edit = Box<dyn Fn(&mut Doc, [usize; 6])>;
    // The index accessor's sparse indices (u8 at view v[2]) rewritten in place.
    let indices = |bytes: [u8; 4]| -> Edit {
        Box::new(move |d: &mut Doc, v: [usize; 6]| {
            let o = d.offsets[v[2]];
            d.bin[o..o + 4].copy_from_slice(&bytes);
        })
    };
    let cases: Vec<(&str, Edit, &str)> = vec![
        ("unordered", indices([2, 1, 4, 5]), "strictly increasing"),
        ("repeated", indices([1, 2, 2, 5]), "strictly increasing"),
        (
            "out-of-range",
            indices([1, 2, 4, 9]),
            "past the accessor's 6 elements",
        ),
        (
            "values-past-view",
            Box::new(|d: &mut Doc, _| {
                d.accessors[0] =
                    d.accessors[0].replace(r#""sparse":{"count":2"#, r#""sparse":{"count":3"#);
            }),
            "sparse",
        ),
        (
            "count-over-accessor",
            Box::new(|d: &mut Doc, _| {
                d.accessors[2] =
                    d.accessors[2].replace(r#""sparse":{"count":1"#, r#""sparse":{"count":5"#);
            }),
            "sparse.count is 5",
        ),
        (
            "huge-without-view",
            Box::new(|d: &mut Doc, _| {
                d.accessors[2] = d.accessors[2].replace(
                    r#""count":4,"type":"VEC2""#,
                    r#""count":4000000000,"type":"VEC2""#,
                );
            }),
            "memory budget",
        ),
    ];
    for (name, edit, needle) in cases {
        let path = sparse_quad(&dir, name, edit);
        let options = LoadOptions {
            limits: nimbus::limits::Limits::with_memory(1 << 30),
            ..Default::default()
        };
        let err = load_builder(&path, &options)
            .err()
            .unwrap_or_else(|| panic!("{name}: loaded"));
        let text = err.to_string();
        assert!(text.contains(&format!("{name}.gltf")), "{name}: {text}");
        assert!(text.contains(needle), "{name}: {text}");
    }
}

#[test]
fn quantized_attributes_decode_per_khr_mesh_quantization() {
    let dir = temp_dir("quantized");
    let mut d = Doc::default();
    // Mesh 0: u16 positions scaled by the node (the usual dequantization), i8 normalized normals, i16
    // normalized tangents, u16 normalized texture coordinates.
    let v = d.view(&u16s(&[0, 0, 0, 1000, 0, 0, 0, 2000, 0, 0]));
    d.accessor(format!(r#"{{"bufferView":{v},"componentType":5123,"count":3,"type":"VEC3","min":[0,0,0],"max":[1000,2000,0]}}"#));
    // Normals: +z as 127 (1.0) and −128 clamped to −1 on the second; each element padded to 4 bytes.
    let v = d.view(&[0, 0, 127, 0, 0, 0, 0x80, 0, 0, 0, 127, 0]);
    d.accessor(format!(r#"{{"bufferView":{v},"byteOffset":0,"componentType":5120,"normalized":true,"count":3,"type":"VEC3"}}"#));
    let v = d.view(&i16s(&[
        32767, 0, 0, 32767, 0, -32768, 0, -32767, 0, 0, 32767, 32767,
    ]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5122,"normalized":true,"count":3,"type":"VEC4"}}"#
    ));
    let v = d.view(&u16s(&[0, 65535, 65535, 32768, 0, 0]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5123,"normalized":true,"count":3,"type":"VEC2"}}"#
    ));
    // Mesh 1: i8 normalized positions, i8 unnormalized texture coordinates.
    let v = d.view(&[0, 0, 0, 0, 127, 0, 0, 0, 0, 0x81, 0, 0]);
    d.accessor(format!(r#"{{"bufferView":{v},"byteOffset":0,"componentType":5120,"normalized":true,"count":3,"type":"VEC3","min":[0,-127,0],"max":[127,0,0]}}"#));
    let v = d.view(&[0, 0, 3, 0xFE, 0xF9, 7]);
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5120,"count":3,"type":"VEC2"}}"#
    ));
    // Element strides of 4 bytes for the padded i8 VEC3s.
    for view in [1, 4] {
        d.views[view] = d.views[view].replace('}', r#","byteStride":4}"#);
    }
    let path = d.write(
        &dir,
        "quantized",
        r#""extensionsUsed":["KHR_mesh_quantization"],"extensionsRequired":["KHR_mesh_quantization"],
        "scenes":[{"nodes":[0,1]}],
        "nodes":[{"mesh":0,"scale":[0.001,0.001,0.001]},{"mesh":1,"translation":[0,0,5]}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TANGENT":2,"TEXCOORD_0":3}}]},
                  {"primitives":[{"attributes":{"POSITION":4,"TEXCOORD_0":5}}]}]"#,
    );
    let builder = load(&path);
    let [a, b] = builder.meshes() else {
        panic!("two meshes")
    };
    let want = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::Y];
    for (p, w) in a.positions.iter().zip(want) {
        assert!(close(*p, w, 1e-6), "{p} != {w}");
    }
    assert!(close(a.normals[0], Vec3::Z, 1e-6) && close(a.normals[2], Vec3::Z, 1e-6));
    assert!(close(a.normals[1], -Vec3::Z, 1e-6), "{}", a.normals[1]);
    let t = a.tangents.as_ref().unwrap();
    assert!(
        close(t[0].truncate(), Vec3::X, 1e-6) && t[0].w == 1.0,
        "{}",
        t[0]
    );
    assert!(
        close(t[1].truncate(), -Vec3::Y, 1e-6) && t[1].w == -1.0,
        "{}",
        t[1]
    );
    assert!(
        close(t[2].truncate(), Vec3::Z, 1e-6) && t[2].w == 1.0,
        "{}",
        t[2]
    );
    let uv = a.uvs.as_ref().unwrap();
    assert_eq!(uv[0], Vec2::new(0.0, 1.0));
    assert_eq!(uv[1], Vec2::new(1.0, 32768.0 / 65535.0));
    let want = [
        Vec3::new(0.0, 0.0, 5.0),
        Vec3::new(1.0, 0.0, 5.0),
        Vec3::new(0.0, -1.0, 5.0),
    ];
    for (p, w) in b.positions.iter().zip(want) {
        assert!(close(*p, w, 1e-6), "{p} != {w}");
    }
    assert_eq!(
        b.uvs.as_ref().unwrap(),
        &vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(3.0, -2.0),
            Vec2::new(-7.0, 7.0)
        ]
    );
}

#[test]
fn the_real_morph_targets_apply_their_default_weights() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("realworld/gltf/MorphPrimitivesTest");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("MorphPrimitivesTest.gltf")).unwrap())
            .unwrap();
    let builder = load(&dir.join("MorphPrimitivesTest.gltf"));
    let weight = json["meshes"][0]["weights"][0].as_f64().unwrap() as f32;
    assert_eq!(weight, 0.5);
    let primitives = json["meshes"][0]["primitives"].as_array().unwrap();
    assert_eq!(builder.meshes().len(), primitives.len());
    let mut raised = 0;
    for (mesh, primitive) in builder.meshes().iter().zip(primitives) {
        let index = |v: &serde_json::Value| v.as_u64().unwrap() as usize;
        let base = real_vec3s(&dir, &json, index(&primitive["attributes"]["POSITION"]));
        let delta = real_vec3s(&dir, &json, index(&primitive["targets"][0]["POSITION"]));
        assert_eq!(mesh.positions.len(), base.len());
        for (i, p) in mesh.positions.iter().enumerate() {
            let want = base[i] + weight * delta[i];
            assert!(close(*p, want, 1e-6), "vertex {i}: {p} != {want}");
            raised += usize::from(delta[i].y > 0.0);
        }
    }
    // The targets raise some vertices by up to 0.2 (their accessors' max): at weight 0.5, 0.1.
    assert!(raised > 0);
    let top = builder
        .meshes()
        .iter()
        .flat_map(|m| &m.positions)
        .map(|p| p.y);
    assert!((top.fold(f32::MIN, f32::max) - 0.1).abs() < 1e-6);
}

#[test]
fn node_weights_override_mesh_weights_and_move_normals() {
    let dir = temp_dir("morph");
    let mut d = Doc::default();
    let v = d.view(&f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]));
    d.accessor(format!(r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}"#));
    let v = d.view(&f32s(&[0., 0., 1., 0., 0., 1., 0., 0., 1.]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3"}}"#
    ));
    let v = d.view(&f32s(&[0., 0., 4., 0., 0., 4., 0., 0., 4.]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3"}}"#
    ));
    let v = d.view(&f32s(&[4., 0., 0., 4., 0., 0., 4., 0., 0.]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3"}}"#
    ));
    // The second target's POSITION deltas are i16 (KHR_mesh_quantization), not normalized.
    let v = d.view(&i16s(&[1, 0, 0, 1, 0, 0, 1, 0, 0]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5122,"count":3,"type":"VEC3"}}"#
    ));
    let path = d.write(
        &dir,
        "morph",
        r#""scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"weights":[0.25,0.5]}],
        "meshes":[{"weights":[1,0],"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},
            "targets":[{"POSITION":2,"NORMAL":3},{"POSITION":4}]}]}]"#,
    );
    let builder = load(&path);
    let m = &builder.meshes()[0];
    // 0.25 × (0, 0, 4) + 0.5 × (1, 0, 0); the normal (0, 0, 1) + 0.25 × (4, 0, 0), normalized.
    let shift = Vec3::new(0.5, 0.0, 1.0);
    for (p, base) in m.positions.iter().zip([Vec3::ZERO, Vec3::X, Vec3::Y]) {
        assert!(close(*p, base + shift, 1e-6), "{p}");
    }
    let n = Vec3::new(1.0, 0.0, 1.0).normalize();
    assert!(
        m.normals.iter().all(|m| close(*m, n, 1e-6)),
        "{:?}",
        m.normals
    );
}

/// A two-joint skin: joint A (node 1) at z = −2, joint B (node 2) its child one unit up, rotated 90° about z
/// now but unrotated at bind time. The skinned mesh nodes (0 and 3) have transforms of their own, which glTF
/// ignores for skinned meshes.
fn two_joint_skin(dir: &Path) -> PathBuf {
    let mut d = Doc::default();
    let v = d.view(&f32s(&[1., 1., -2., 1., 1., -2., 0., 0., -2.]));
    d.accessor(format!(r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3","min":[0,0,-2],"max":[1,1,-2]}}"#));
    let v = d.view(&f32s(&[1., 0., 0., 0., 0., 1., 0., 0., 1.]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3"}}"#
    ));
    // Set 0 (u8 joints): vertex 0 all on B, vertex 1 half on A, vertex 2 all on A. Set 1 (u16 joints):
    // vertex 1's other half on B.
    let v = d.view(&[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5121,"count":3,"type":"VEC4"}}"#
    ));
    let v = d.view(&f32s(&[1., 0., 0., 0., 0.5, 0., 0., 0., 1., 0., 0., 0.]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC4"}}"#
    ));
    let v = d.view(&u16s(&[0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5123,"count":3,"type":"VEC4"}}"#
    ));
    // u8 normalized weights: 128/255 is not exactly 0.5; the weights are divided by their sum.
    let v = d.view(&[0, 0, 0, 0, 128, 0, 0, 0, 0, 0, 0, 0]);
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5121,"normalized":true,"count":3,"type":"VEC4"}}"#
    ));
    // Inverse bind matrices (column-major): translate(0, 0, 2) and translate(0, −1, 2).
    let ibm = [
        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 2., 1., //
        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., -1., 2., 1.,
    ];
    let v = d.view(&f32s(&ibm));
    d.accessor(format!(
        r#"{{"bufferView":{v},"componentType":5126,"count":2,"type":"MAT4"}}"#
    ));
    let h = std::f32::consts::FRAC_1_SQRT_2;
    d.write(
        dir,
        "skin",
        &format!(
            r#""scenes":[{{"nodes":[0,1,3]}}],
            "nodes":[{{"mesh":0,"skin":0,"translation":[100,0,0]}},
                     {{"children":[2],"translation":[0,0,-2]}},
                     {{"translation":[0,1,0],"rotation":[0,0,{h},{h}]}},
                     {{"mesh":0,"skin":0,"scale":[3,3,3]}}],
            "skins":[{{"joints":[1,2],"inverseBindMatrices":6}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"JOINTS_0":2,"WEIGHTS_0":3,"JOINTS_1":4,"WEIGHTS_1":5}}}}]}}]"#
        ),
    )
}

#[test]
fn a_two_joint_skin_is_posed_at_its_rest_pose() {
    let dir = temp_dir("skin");
    let builder = load(&two_joint_skin(&dir));
    // Joint matrices composed by hand: A: T(0,0,−2)·T(0,0,2) = I; B: T(0,0,−2)·T(0,1,0)·Rz(90°)·T(0,−1,2).
    // Vertex 0 (1,1,−2) on B: T(0,−1,2) → (1,0,0), Rz → (0,1,0), T(0,1,0) → (0,2,0), T(0,0,−2) → (0,2,−2).
    // Vertex 1 about half on A, half on B, its weights divided by their sum. Vertex 2 on A stays.
    let b = Mat4::from_translation(Vec3::new(0.0, 0.0, -2.0))
        * Mat4::from_translation(Vec3::Y)
        * Mat4::from_quat(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2))
        * Mat4::from_translation(Vec3::new(0.0, -1.0, 2.0));
    assert!(close(
        b.transform_point3(Vec3::new(1.0, 1.0, -2.0)),
        Vec3::new(0.0, 2.0, -2.0),
        1e-6
    ));
    let on_b = (128.0 / 255.0) / (0.5 + 128.0 / 255.0);
    let want = [
        Vec3::new(0.0, 2.0, -2.0),
        Vec3::new(1.0, 1.0, -2.0).lerp(Vec3::new(0.0, 2.0, -2.0), on_b),
        Vec3::new(0.0, 0.0, -2.0),
    ];
    assert_eq!(builder.meshes().len(), 2);
    for mesh in builder.meshes() {
        for (p, w) in mesh.positions.iter().zip(want) {
            assert!(close(*p, w, 1e-5), "{p} != {w}");
        }
        // Vertex 0's normal +x turns with joint B to +y.
        assert!(close(mesh.normals[0], Vec3::Y, 1e-5), "{}", mesh.normals[0]);
        assert!(close(mesh.normals[2], Vec3::Z, 1e-5), "{}", mesh.normals[2]);
    }
    let rest: Vec<_> = builder
        .warnings()
        .iter()
        .filter(|w| w.contains("rest pose"))
        .collect();
    assert_eq!(rest.len(), 1, "{:?}", builder.warnings());
}

#[test]
fn a_skin_naming_a_joint_it_lacks_is_an_error() {
    let dir = temp_dir("skin-bad");
    let path = two_joint_skin(&dir);
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(r#""joints":[1,2]"#, r#""joints":[1]"#);
    std::fs::write(&path, text).unwrap();
    let err = load_builder(&path, &LoadOptions::default())
        .err()
        .expect("an error");
    let text = err.to_string();
    assert!(
        text.contains("skin.gltf") && text.contains("names joint 1"),
        "{text}"
    );
}

#[test]
fn compression_extensions_are_refused_by_name() {
    let dir = temp_dir("compressed");
    let mut d = Doc::default();
    let v = d.view(&f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]));
    d.accessor(format!(r#"{{"bufferView":{v},"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}}"#));
    for ext in [
        "KHR_draco_mesh_compression",
        "EXT_meshopt_compression",
        "KHR_texture_basisu",
    ] {
        let path = d.write(
            &dir,
            ext,
            &format!(
                r#""extensionsUsed":["{ext}"],"extensionsRequired":["{ext}"],"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
                "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}]"#
            ),
        );
        let err = load_builder(&path, &LoadOptions::default())
            .err()
            .expect("an error");
        assert!(matches!(err.kind, SceneErrorKind::Unsupported(_)), "{err}");
        assert!(err.to_string().contains(ext), "{err}");
    }
}

/// The normal AOV of `NormalTangentTest` seen face-on, 1 pixel = 0.01 units, with pixel centres on the
/// geometric domes' centres. The model (Ed Mackey, AGI) pairs each of its 15 test cells: on the left a real
/// dome of radius 0.1 (peaks at x = −0.96, −0.16, 0.64 and y = −0.8 ... 0.8), on the right, 0.32 further in
/// +x, a flat quad whose normal map shows the same dome with its uvs in another orientation.
fn normal_tangent_aov(path: &Path) -> nimbus::RenderImage {
    let mut builder = load(path);
    let (w, half) = (240usize, 1.2f32);
    let eye = Vec3::new(0.005, -0.125, 50.0);
    builder.set_camera(Camera::look_at(
        eye,
        eye - Vec3::Z * 50.0,
        2.0 * (half / 50.0).atan(),
    ));
    let scene = builder.build().unwrap();
    let settings = RenderSettings {
        width: w,
        height: w,
        spp: 4,
        max_depth: 1,
        ..Default::default()
    };
    Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap()
        .0
}

/// For each test cell, the angles (degrees) between the AOV normal on the real dome and on the normal-mapped
/// quad at the same offsets from their centres: 8 directions at 0.05 and 0.07 units.
fn cell_angles(image: &nimbus::RenderImage) -> Vec<Vec<f32>> {
    let normal = |x: i32, y: i32| image.normal[image.pixel_index(x as usize, y as usize)];
    let mut cells = Vec::new();
    for cx in [-0.96f32, -0.16, 0.64] {
        for cy in [-0.8f32, -0.4, 0.0, 0.4, 0.8] {
            let (px, py) = (
                ((cx - 0.005 + 1.2) / 0.01 - 0.5).round() as i32,
                ((1.075 - cy) / 0.01 - 0.5).round() as i32,
            );
            let mut angles = Vec::new();
            for r in [5.0f32, 7.0] {
                for k in 0..8 {
                    let a = k as f32 * std::f32::consts::FRAC_PI_4;
                    let (dx, dy) = ((r * a.cos()).round() as i32, (r * a.sin()).round() as i32);
                    let g = normal(px + dx, py + dy);
                    let m = normal(px + 32 + dx, py + dy);
                    assert!(
                        g.length() > 0.5 && m.length() > 0.5,
                        "a miss at cell ({cx}, {cy})"
                    );
                    angles.push(g.angle_between(m).to_degrees());
                }
            }
            cells.push(angles);
        }
    }
    cells
}

#[test]
fn normal_mapped_bumps_match_the_geometric_bumps_beside_them() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let path = shared.join("realworld/gltf/NormalTangentTest/NormalTangentTest.gltf");
    let image = normal_tangent_aov(&path);
    let cells = cell_angles(&image);
    for (i, angles) in cells.iter().enumerate() {
        let mean = angles.iter().sum::<f32>() / angles.len() as f32;
        let max = angles.iter().cloned().fold(0.0, f32::max);
        eprintln!("cell {i}: mean {mean:.1}°, max {max:.1}°");
        assert!(
            mean < 8.0 && max < 20.0,
            "cell {i}: mean {mean}°, max {max}°: {angles:?}"
        );
    }
}

#[test]
fn a_normal_scale_of_zero_gives_the_flat_normal() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let src = shared.join("realworld/gltf/NormalTangentTest");
    let mut json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(src.join("NormalTangentTest.gltf")).unwrap())
            .unwrap();
    json["materials"][0]["normalTexture"]["scale"] = 0.0.into();
    // The copy lives in a temporary folder and names the shared files by absolute path.
    for list in ["buffers", "images"] {
        for item in json[list].as_array_mut().unwrap() {
            let uri = src.join(item["uri"].as_str().unwrap());
            item["uri"] = uri.to_str().unwrap().into();
        }
    }
    let path = temp_dir("normal-scale").join("scale0.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let image = normal_tangent_aov(&path);
    // Where the real domes tilt the normal by about 30°-45°, the mapped quads now face the camera flat.
    for angles in cell_angles(&image) {
        assert!(angles.iter().all(|a| *a > 15.0), "{angles:?}");
    }
    let flat = |x: usize, y: usize| image.normal[image.pixel_index(x, y)];
    for (x, y) in [(55, 187), (135, 107), (215, 27)] {
        assert!(
            flat(x, y).angle_between(Vec3::Z).to_degrees() < 0.5,
            "{}",
            flat(x, y)
        );
    }
}

#[test]
fn infinite_morph_weights_and_jointless_skins_are_errors() {
    let dir = temp_dir("checks");
    let path = two_joint_skin(&dir);
    let good = std::fs::read_to_string(&path).unwrap();
    for (from, to, needle) in [
        (
            r#""joints":[1,2]"#,
            r#""joints":[]"#,
            "skins[0] has no joints",
        ),
        (
            r#""scale":[3,3,3]}"#,
            r#""scale":[3,3,3],"weights":[1e39]}"#,
            "nodes[3].weights",
        ),
    ] {
        std::fs::write(&path, good.replace(from, to)).unwrap();
        let err = load_builder(&path, &LoadOptions::default())
            .err()
            .expect("an error");
        assert!(err.to_string().contains(needle), "{err}");
    }
}
