//! `KHR_materials_variants`: `LoadOptions::variant` and `nimbus render --variant NAME` select each primitive's
//! mapped material; without one the primitives keep their own materials and one warning lists the variants; an
//! unknown name is an error listing them; the variant is part of a farm part's scene hash.

use crate::common;

use nimbus::scene::{load_builder, LoadOptions, SceneBuilder};
use std::path::{Path, PathBuf};

/// A quad (−1, −1, 0) … (1, 1, 0) facing a camera at z = 3 that it fills, with unlit material 0 (blue, its
/// own), 1 (red) and 2 (green); the root declares variants "red" and "green", and the primitive maps them to
/// materials 1 and 2 by `mappings`.
fn variants_gltf(mappings: &str, variants: &str) -> String {
    let mut buf = Vec::new();
    for v in [
        -1.0f32, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
    ] {
        buf.extend_from_slice(&v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    let unlit = |name: &str, rgb: &str| {
        format!(
            r#"{{"name":"{name}","pbrMetallicRoughness":{{"baseColorFactor":[{rgb},1]}},"extensions":{{"KHR_materials_unlit":{{}}}}}}"#
        )
    };
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
        "extensionsUsed":["KHR_materials_variants","KHR_materials_unlit"],
        "extensions":{{"KHR_materials_variants":{{"variants":{variants}}}}},
        "nodes":[{{"mesh":0}},{{"camera":0,"translation":[0,0,3]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.3,"znear":0.1,"aspectRatio":1.0}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0,
          "extensions":{{"KHR_materials_variants":{{"mappings":{mappings}}}}}}}]}}],
        "materials":[{},{},{}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5123,"count":6,"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":12}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{}","byteLength":{}}}]}}"#,
        unlit("blue", "0,0,1"),
        unlit("red", "1,0,0"),
        unlit("green", "0,1,0"),
        common::base64(&buf),
        buf.len()
    )
}

const MAPPINGS: &str = r#"[{"material":1,"variants":[0]},{"material":2,"variants":[1]}]"#;
const VARIANTS: &str = r#"[{"name":"red"},{"name":"green"}]"#;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nimbus-variants-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("variants.gltf");
    std::fs::write(&p, text).unwrap();
    p
}

fn load(path: &Path, variant: Option<&str>) -> Result<SceneBuilder, String> {
    let options = LoadOptions {
        variant,
        ..LoadOptions::default()
    };
    load_builder(path, &options).map_err(|e| e.to_string())
}

/// The error of a load that must fail.
fn load_error(path: &Path, variant: Option<&str>) -> String {
    load(path, variant)
        .err()
        .unwrap_or_else(|| panic!("{} loads with {variant:?}", path.display()))
}

/// The name of the quad's material.
fn material_name(b: &SceneBuilder) -> &str {
    &b.materials()[b.meshes()[0].material as usize].name
}

const WARNING: &str = "the file has material variants: red, green (--variant NAME chooses one)";

#[test]
fn the_variant_option_selects_each_primitive_s_mapped_material() {
    let d = dir("load");
    let path = write(&d, &variants_gltf(MAPPINGS, VARIANTS));
    for (variant, material) in [
        (Some("red"), "red"),
        (Some("green"), "green"),
        (None, "blue"),
    ] {
        let b = load(&path, variant).unwrap();
        assert_eq!(material_name(&b), material, "{variant:?}");
        let warned = b.warnings().iter().filter(|w| *w == WARNING).count();
        assert_eq!(warned, usize::from(variant.is_none()), "{:?}", b.warnings());
        assert!(
            !b.warnings().iter().any(|w| w.contains("not supported")),
            "{:?}",
            b.warnings()
        );
    }
    // A variant the primitive does not map keeps its own material.
    let one = r#"[{"material":1,"variants":[0]}]"#;
    let b = load(&write(&d, &variants_gltf(one, VARIANTS)), Some("green")).unwrap();
    assert_eq!(material_name(&b), "blue");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn unknown_variants_and_bad_mappings_are_errors() {
    let d = dir("errors");
    let path = write(&d, &variants_gltf(MAPPINGS, VARIANTS));
    let err = load_error(&path, Some("blue"));
    assert!(
        err.contains("no material variant 'blue'; its variants are: red, green"),
        "{err}"
    );
    for (mappings, variants, expected) in [
        (
            r#"[{"material":7,"variants":[0]}]"#,
            VARIANTS,
            "mappings[0].material must be the index of a material (3 materials)",
        ),
        (
            r#"[{"material":1,"variants":[2]}]"#,
            VARIANTS,
            "mappings[0].variants: 2 is not the index of a variant (2 variants)",
        ),
        (
            r#"[{"material":1,"variants":[0]},{"material":2,"variants":[0]}]"#,
            VARIANTS,
            "variant 0 is mapped by mappings[0] and mappings[1]",
        ),
        (
            r#"{"material":1}"#,
            VARIANTS,
            "KHR_materials_variants.mappings must be an array",
        ),
        (
            r#"[{"material":1,"variants":"red"}]"#,
            VARIANTS,
            "mappings[0].variants must be an array",
        ),
        (
            MAPPINGS,
            r#"[{"name":"red"},{"label":"green"}]"#,
            "extensions.KHR_materials_variants.variants[1].name must be a string",
        ),
        (
            MAPPINGS,
            r#"{"red":0}"#,
            "extensions.KHR_materials_variants.variants must be an array",
        ),
    ] {
        let path = write(&d, &variants_gltf(mappings, variants));
        let err = load_error(&path, None);
        assert!(err.contains(expected), "{mappings} {variants}: {err}");
    }
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn render_variant_picks_the_colour_and_the_default_warns_once() {
    let d = dir("cli");
    write(&d, &variants_gltf(MAPPINGS, VARIANTS));
    // Mean sRGB (R, G, B) of the preview, which the unlit quad fills.
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "variants.gltf",
            "--width",
            "8",
            "--spp",
            "2",
            "--exposure",
            "0",
            "-o",
            "out.exr",
        ];
        args.extend(extra);
        let (ok, _, err) = common::run_nimbus(&args, &d);
        assert!(ok, "{err}");
        let png = image::open(d.join("out.png")).unwrap().to_rgb8();
        let mut mean = [0.0; 3];
        for p in png.pixels() {
            for c in 0..3 {
                mean[c] += p[c] as f64 / png.len() as f64 * 3.0;
            }
        }
        (mean, err)
    };
    let (red, err) = render(&["--variant", "red"]);
    assert!(red[0] > 250.0 && red[1] < 5.0 && red[2] < 5.0, "{red:?}");
    assert!(!err.contains("material variants"), "{err}");
    let (green, _) = render(&["--variant", "green"]);
    assert!(
        green[1] > 250.0 && green[0] < 5.0 && green[2] < 5.0,
        "{green:?}"
    );
    let (blue, err) = render(&[]);
    assert!(
        blue[2] > 250.0 && blue[0] < 5.0 && blue[1] < 5.0,
        "{blue:?}"
    );
    let warning = format!("nimbus: warning: {WARNING}");
    assert_eq!(err.lines().filter(|l| *l == warning).count(), 1, "{err}");
    let (ok, _, err) = common::run_nimbus(
        &[
            "render",
            "variants.gltf",
            "--variant",
            "blue",
            "-o",
            "x.exr",
        ],
        &d,
    );
    assert!(!ok);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("its variants are: red, green"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// Parts rendered with different variants carry different scene hashes and refuse to merge; parts of the same
/// variant merge.
#[test]
fn parts_of_different_variants_refuse_to_merge() {
    let d = dir("farm");
    write(&d, &variants_gltf(MAPPINGS, VARIANTS));
    let part = |variant: &str, samples: &str, out: &str| {
        let args = [
            "render",
            "variants.gltf",
            "--width",
            "8",
            "--spp",
            "4",
            "--samples",
            samples,
            "--variant",
            variant,
            "-o",
            out,
        ];
        let (ok, _, err) = common::run_nimbus(&args, &d);
        assert!(ok, "{err}");
    };
    part("red", "0..2", "a.exr");
    part("red", "2..4", "b.exr");
    part("green", "2..4", "c.exr");
    let (ok, _, err) = common::run_nimbus(&["merge", "a.exr", "b.exr", "-o", "ab.exr"], &d);
    assert!(ok, "{err}");
    let (ok, _, err) = common::run_nimbus(&["merge", "a.exr", "c.exr", "-o", "ac.exr"], &d);
    assert!(!ok, "parts of different variants merged");
    assert!(err.contains("scene hash"), "{err}");
    std::fs::remove_dir_all(&d).ok();
}

/// OBJ and USD files have no material variants: asking for one is an error.
#[test]
fn a_variant_for_a_format_without_variants_is_an_error() {
    let d = dir("obj");
    let obj = d.join("tri.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let err = load_error(&obj, Some("red"));
    assert!(
        err.contains("material variants are read from glTF files"),
        "{err}"
    );
    assert!(load(&obj, None).is_ok());
    std::fs::remove_dir_all(&d).ok();
}
