//! The compositing layers as files, read by other people's readers: OpenEXR's `exrheader` and OpenImageIO's
//! `oiiotool --info -v` must list every channel and header attribute of a render with every layer, at every
//! storage option (`--half`, `--compression`); `--stats` names the layers written; `--list-aovs` lists them.
//!
//! The tools come from Debian's `openexr` and `openimageio-tools`; a test whose tool is missing is skipped,
//! unless `NIMBUS_REQUIRE_TOOLS=1` (CI), which makes it fail.

use crate::common;

use common::{run_nimbus, run_tool};
use std::path::{Path, PathBuf};

/// The bundled demo scene.
fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cloud.gltf")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("nimbus-compositing-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The header attributes every render carries.
const ATTRIBUTES: [&str; 10] = [
    "worldToCamera",
    "worldToNDC",
    "software",
    "nimbus/version",
    "nimbus/spp",
    "nimbus/seed",
    "nimbus/render_seconds",
    "nimbus/scene",
    "nimbus/scene_hash",
    "nimbus/transparent",
];

#[test]
fn every_layer_and_attribute_reads_back_in_exrheader_and_oiiotool() {
    let dir = temp_dir("tools");
    let scene = demo();
    let base = [
        "render",
        scene.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--spp",
        "4",
        "--aovs",
        "all",
        "--transparent",
        "--light-groups",
        "per-light",
    ];
    let variants: [(&str, &[&str]); 4] = [
        ("zip.exr", &[]),
        ("half.exr", &["--half"]),
        ("half_all_piz.exr", &["--half=all", "--compression", "piz"]),
        ("b44.exr", &["--half", "--compression", "b44"]),
    ];
    for (file, extra) in variants {
        let mut args: Vec<&str> = base.to_vec();
        args.extend(extra);
        args.extend(["--stats", "stats.json", "-o", file]);
        let (ok, _, err) = run_nimbus(&args, &dir);
        assert!(ok, "{err}");
        let path = dir.join(file);
        let layers = nimbus::output::read_exr_layers(&path).unwrap();
        let names: Vec<&String> = layers.channels.keys().collect();
        assert_eq!(names.len(), 98, "{names:?}");
        if let Some(header) = run_tool("exrheader", &[path.to_str().unwrap()], Path::new(".")) {
            for name in &names {
                assert!(
                    header.contains(&format!("    {name}, ")),
                    "exrheader {file} lacks channel {name}"
                );
            }
            for key in ATTRIBUTES.iter().chain(&["capDate"]) {
                assert!(
                    header.contains(&format!("{key} (type")),
                    "exrheader {file} lacks {key}"
                );
            }
            assert_eq!(header.matches("/manifest (type string)").count(), 3);
            let half = header.matches("16-bit floating-point").count();
            let expected_half = match file {
                "zip.exr" => 0,
                // Colour AOVs: albedo, normal, 10 light paths, 3 colours, 2 light groups, shadow catcher.
                "half.exr" | "b44.exr" => 3 * 18,
                _ => 3 * 18 + 4,
            };
            assert_eq!(half, expected_half, "{file}: half channels");
        }
        if let Some(info) = run_tool(
            "oiiotool",
            &["--info", "-v", path.to_str().unwrap()],
            Path::new("."),
        ) {
            assert!(info.contains("98 channel"), "{info}");
            for name in &names {
                assert!(info.contains(name.as_str()), "oiiotool {file} lacks {name}");
            }
            for key in ATTRIBUTES {
                assert!(
                    info.contains(&format!("{key}:")),
                    "oiiotool {file} lacks {key}"
                );
            }
            assert!(info.contains("cryptomatte/") && info.contains("MurmurHash3_32"));
        }
    }
    // --stats names the layers written.
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("stats.json")).unwrap()).unwrap();
    let layers: Vec<&str> = stats["layers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert!(layers.contains(&"diffuse_direct") && layers.contains(&"CryptoAsset"));
    assert!(layers.contains(&"lg_environment") && stats["transparent"] == true);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn aov_choices_are_listed_and_checked() {
    let dir = temp_dir("list");
    let (ok, out, err) = run_nimbus(&["render", "--list-aovs"], &dir);
    assert!(ok, "{err}");
    for name in [
        "diffuse_direct",
        "volume_indirect",
        "transmission_color",
        "lg_<group>",
        "shadow_catcher",
        "CryptoMaterial00",
        "lightpaths",
        "cryptomatte",
    ] {
        assert!(out.contains(name), "--list-aovs lacks {name}:\n{out}");
    }
    let scene = demo();
    let scene = scene.to_str().unwrap();
    let (ok, out, _) = run_nimbus(
        &[
            "render",
            scene,
            "--list-aovs",
            "--light-groups",
            "per-light",
        ],
        &dir,
    );
    assert!(ok && out.contains("lg_environment"), "{out}");
    // A layer that does not exist, and a light group the scene does not have, are refused in one line.
    let (ok, _, err) = run_nimbus(&["render", scene, "--aovs", "difuse_direct"], &dir);
    assert!(
        !ok && err.contains("unknown layer 'difuse_direct'"),
        "{err}"
    );
    let (ok, _, err) = run_nimbus(
        &[
            "render", scene, "--spp", "1", "--width", "8", "--aovs", "lg_key",
        ],
        &dir,
    );
    assert!(
        !ok && err.contains("lg_key") && err.contains("none"),
        "{err}"
    );
    let (ok, _, err) = run_nimbus(
        &[
            "render",
            scene,
            "--aovs",
            "cryptomatte",
            "--compression",
            "pxr24",
            "--spp",
            "1",
            "--width",
            "8",
        ],
        &dir,
    );
    assert!(!ok && err.contains("Cryptomatte"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
