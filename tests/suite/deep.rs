//! Deep output (`--deep`, OpenEXR 2.0 deep scanline), proven by other people's readers and by a closed form:
//! - OpenEXR's `exrheader` and `exrinfo --strict` read the deep file's header;
//! - PyPI's `OpenEXR` module (OpenEXR's own Python binding) reads back every sample of a written deep image, bit
//!   for bit, both uncompressed and ZIPS;
//! - OpenImageIO's `oiiotool --flatten` of the deep file equals the flat EXR's beauty and alpha within 1e-4
//!   relative, with and without merging down to a few samples per pixel (it reads every chunk: a wrong offset,
//!   count table or channel order shows here);
//! - a homogeneous slab held out by a plane halfway through it (`oiiotool --deepholdout`, and our own samples
//!   split at the plane by OpenEXR's rule) keeps the alpha `1 - exp(-sigma_t d / cos)` in front of the plane,
//!   within a tolerance from the binomial variance of the fixed-seed estimate.
//!
//! The tools come from Debian's `openexr` and `openimageio-tools`, the Python module from PyPI (`$NIMBUS_PYTHON`,
//! CI's virtual environment, else `python3`); a check whose tool is missing is skipped, unless
//! `NIMBUS_REQUIRE_TOOLS=1` (CI), which makes it fail.

use crate::common;

use common::{run_nimbus, run_tool};
use nimbus::render::{DeepImage, RenderSettings, Renderer};
use nimbus::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The slab's extinction (grey: scattering 1.5, absorption 0.5), per scene unit.
const SIGMA_T: f64 = 2.0;
/// The slab's front and the holdout plane, as depths along the view axis (camera at z = 3 looking down -z; the
/// slab spans z in [-1, 1], the plane is z = 0).
const FRONT: f64 = 2.0;
const PLANE: f64 = 3.0;
/// Image size and samples of the slab renders (vertical field of view 45°, square).
const SIZE: usize = 32;
const SPP: u32 = 256;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-deep-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes the test scene into `dir` and returns its path: the homogeneous slab of `slab_homogeneous.gltf` made
/// grey (sigma_t 2) and 20 × 20 × 2 wide, and, with `surfaces`, an opaque grey box inside the slab (its front
/// at depth 2.7) and a wall behind it covering the right half of the image (front at depth 4.9).
fn slab_scene(dir: &Path, surfaces: bool) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/slab_homogeneous.gltf");
    let mut gltf: serde_json::Value =
        serde_json::from_slice(&std::fs::read(source).unwrap()).unwrap();
    gltf["materials"][0]["extras"]["nimbus_medium"] = serde_json::json!({
        "sigma_a": [0.5, 0.5, 0.5], "sigma_s": [1.5, 1.5, 1.5], "anisotropy": 0.0
    });
    gltf["nodes"][0]["scale"] = serde_json::json!([10, 10, 4]);
    if surfaces {
        gltf["materials"].as_array_mut().unwrap().push(serde_json::json!({
            "name": "grey",
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0.0,
                                     "roughnessFactor": 1.0}
        }));
        let mut opaque = gltf["meshes"][0].clone();
        opaque["name"] = "opaque".into();
        opaque["primitives"][0]["material"] = 1.into();
        gltf["meshes"].as_array_mut().unwrap().push(opaque);
        let nodes = gltf["nodes"].as_array_mut().unwrap();
        nodes.push(
            serde_json::json!({"name": "box", "mesh": 1, "translation": [-0.4, 0.0, 0.0],
                                      "scale": [0.3, 0.3, 1.2]}),
        );
        nodes.push(
            serde_json::json!({"name": "wall", "mesh": 1, "translation": [10.3, 0.0, -2.0],
                                      "scale": [10.0, 10.0, 0.4]}),
        );
        gltf["scenes"][0]["nodes"] = serde_json::json!([0, 1, 2, 3]);
    }
    let path = dir.join(if surfaces {
        "slab_surfaces.gltf"
    } else {
        "slab.gltf"
    });
    std::fs::write(&path, serde_json::to_vec(&gltf).unwrap()).unwrap();
    path
}

/// The closed-form alpha in front of the plane for the centre of pixel (x, y): the camera ray of that pixel
/// crosses `PLANE - FRONT` of depth over a length `(PLANE - FRONT) / cos`.
fn closed_form(x: usize, y: usize) -> f64 {
    let tan = (std::f64::consts::PI / 8.0).tan();
    let u = (2.0 * (x as f64 + 0.5) / SIZE as f64 - 1.0) * tan;
    let v = (2.0 * (y as f64 + 0.5) / SIZE as f64 - 1.0) * tan;
    let cos = 1.0 / (1.0 + u * u + v * v).sqrt();
    1.0 - (-SIGMA_T * (PLANE - FRONT) / cos).exp()
}

/// Checks measured alphas in front of the plane (row-major, `SIZE` × `SIZE`) against the closed form: every
/// pixel within 5 standard deviations of a binomial estimate from `SPP` paths, and their mean within 4 of its
/// own. Returns the mean error and its standard deviation.
fn check_holdout(alpha: &[f64], what: &str) -> (f64, f64) {
    let (mut error, mut variance) = (0.0, 0.0);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let want = closed_form(x, y);
            let var = want * (1.0 - want) / SPP as f64;
            let got = alpha[y * SIZE + x];
            assert!(
                (got - want).abs() < 5.0 * var.sqrt(),
                "{what}: pixel ({x}, {y}) holds out to alpha {got}, the closed form is {want}"
            );
            error += got - want;
            variance += var;
        }
    }
    let n = (SIZE * SIZE) as f64;
    let (mean, sd) = (error / n, variance.sqrt() / n);
    assert!(
        mean.abs() < 4.0 * sd,
        "{what}: mean alpha error {mean} against a standard deviation {sd}"
    );
    eprintln!("{what}: mean alpha error in front of the plane {mean:.2e} (sd {sd:.2e})");
    (mean, sd)
}

fn render_deep(scene: &Path, max_samples: usize) -> (nimbus::render::RenderImage, DeepImage) {
    let scene = Scene::load(scene).unwrap();
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: SPP,
        seed: 7,
        deep_samples: Some(max_samples),
        ..RenderSettings::default()
    };
    let (mut image, _) = Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap();
    let deep = image.deep.take().expect("a deep image");
    (image, deep)
}

#[test]
fn deep_samples_are_tidy_and_hold_out_a_slab_as_the_closed_form() {
    let dir = temp_dir("api");
    let scene = slab_scene(&dir, false);
    for max_samples in [32, 4] {
        let (image, deep) = render_deep(&scene, max_samples);
        assert!(deep.most_samples() <= max_samples);
        assert!(
            deep.most_samples() >= 4,
            "media are intervals per depth bucket"
        );
        let mut alpha = Vec::new();
        for i in 0..SIZE * SIZE {
            let samples = deep.pixel(i);
            // Sorted, not overlapping, intervals in the slab, the environment behind.
            for w in samples.windows(2) {
                assert!(w[0].z <= w[0].z_back && w[0].z_back <= w[1].z, "{w:?}");
            }
            assert!(samples.iter().all(|s| s.z >= FRONT as f32 - 1e-4));
            // Flattened: the beauty and alpha of the flat image.
            let (rgb, a) = nimbus::render::deep::flatten(samples);
            for c in 0..3 {
                let want = image.beauty[i][c];
                assert!(
                    (rgb[c] - want).abs() <= 1e-5 * want.abs() + 1e-7,
                    "{rgb} {want}"
                );
            }
            assert!((a - image.alpha[i]).abs() <= 1e-5);
            // Held out by the plane: OpenEXR's split of a volume sample, alpha 1 - (1 - A)^fraction.
            let mut transmittance = 1.0f64;
            for s in samples {
                let (z, back) = (s.z as f64, s.z_back as f64);
                let fraction = if back > z {
                    ((PLANE - z) / (back - z)).clamp(0.0, 1.0)
                } else {
                    (z < PLANE) as u32 as f64
                };
                transmittance *= (1.0 - s.a as f64).powf(fraction);
            }
            alpha.push(1.0 - transmittance);
        }
        check_holdout(&alpha, &format!("own split, {max_samples} samples"));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The R, G, B and A channels of the EXR at `path`.
fn rgba(path: &Path) -> [Vec<f32>; 4] {
    let layers = nimbus::output::read_exr_layers(path).unwrap();
    ["R", "G", "B", "A"].map(|c| layers.channel(c).unwrap().to_vec())
}

#[test]
fn deep_files_read_in_openexr_and_flatten_in_oiiotool_to_the_flat_image() {
    let dir = temp_dir("tools");
    let surfaces = slab_scene(&dir, true);
    let demo = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cloud.gltf");
    let size = SIZE.to_string();
    let cases: [(&Path, &str, &[&str]); 4] = [
        (&surfaces, "surfaces.exr", &[]),
        (&surfaces, "merged.exr", &["--deep-samples", "3"]),
        (
            &surfaces,
            "plain.exr",
            &["--compression", "none", "--transparent"],
        ),
        (&demo, "cloud.exr", &[]),
    ];
    for (scene, out, extra) in cases {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--width",
            &size,
            "--height",
            &size,
            "--spp",
            "16",
            "--deep",
            "-o",
            out,
        ];
        args.extend(extra);
        let (ok, _, err) = run_nimbus(&args, &dir);
        assert!(ok, "{err}");
        let deep = nimbus::output::deep_path(Path::new(out));
        let deep = deep.to_str().unwrap();
        assert!(err.contains(&format!("wrote {deep}")), "{err}");
        if let Some(header) = run_tool("exrheader", &[deep], &dir) {
            assert!(header.contains("flags 0x800"), "{header}");
            assert!(
                header.contains("type (type string): \"deepscanline\""),
                "{header}"
            );
            for channel in nimbus::output::DEEP_CHANNELS {
                assert!(header.contains(&format!("    {channel}, 32-bit floating-point")));
            }
        }
        if let Some(info) = run_tool("exrinfo", &["--strict", "-v", deep], &dir) {
            assert!(
                info.contains("deepscanline") && info.contains("maxSamplesPerPixel"),
                "{info}"
            );
            if extra.contains(&"3") {
                assert!(info.contains("maxSamplesPerPixel: int 3"), "{info}");
            }
        }
        let flat = format!("{out}.flat.exr");
        if run_tool("oiiotool", &[deep, "--flatten", "-o", &flat], &dir).is_none() {
            continue;
        }
        let (want, got) = (rgba(&dir.join(out)), rgba(&dir.join(&flat)));
        let mut worst = 0.0f32;
        for c in 0..4 {
            for (i, (&w, &g)) in want[c].iter().zip(&got[c]).enumerate() {
                let error = (g - w).abs() / w.abs().max(1e-3);
                worst = worst.max(error);
                assert!(
                    error <= 1e-4,
                    "{out}: channel {c} of pixel {i}: flattened {g}, flat {w}"
                );
            }
        }
        let bytes = std::fs::metadata(dir.join(deep)).unwrap().len();
        eprintln!("{out}: {deep} {bytes} bytes; worst relative flatten error {worst:.2e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn oiiotool_holds_out_the_slab_by_a_plane_as_the_closed_form() {
    let dir = temp_dir("holdout");
    let scene = slab_scene(&dir, false);
    let (size, spp) = (SIZE.to_string(), SPP.to_string());
    let (ok, _, err) = run_nimbus(
        &[
            "render",
            scene.to_str().unwrap(),
            "--width",
            &size,
            "--height",
            &size,
            "--spp",
            &spp,
            "--seed",
            "7",
            "--deep",
            "-o",
            "slab.exr",
        ],
        &dir,
    );
    assert!(ok, "{err}");
    // The holdout: an opaque deep plane at depth PLANE in every pixel.
    let pattern = format!("constant:color=0,0,0,1,{PLANE}");
    let resolution = format!("{SIZE}x{SIZE}");
    let made = run_tool(
        "oiiotool",
        &[
            "--pattern",
            &pattern,
            &resolution,
            "5",
            "--chnames",
            "R,G,B,A,Z",
            "--deepen",
            "-o",
            "plane.exr",
        ],
        &dir,
    );
    if made.is_none() {
        return;
    }
    run_tool(
        "oiiotool",
        &[
            "slab.deep.exr",
            "plane.exr",
            "--deepholdout",
            "--flatten",
            "-o",
            "held.exr",
        ],
        &dir,
    );
    let alpha: Vec<f64> = rgba(&dir.join("held.exr"))[3]
        .iter()
        .map(|&a| a as f64)
        .collect();
    check_holdout(&alpha, "oiiotool --deepholdout");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Prints every pixel's samples of a deep EXR as JSON: per pixel, a list of [Z, ZBack, A, R, G, B].
const READ_DEEP: &str = r#"
import json, sys, OpenEXR
part = OpenEXR.File(sys.argv[1]).parts[0]
assert part.type() == OpenEXR.deepscanline, part.type()
rgba, z, back = (part.channels[n].pixels for n in ("RGBA", "Z", "ZBack"))
pixels = []
for y in range(rgba.shape[0]):
    for x in range(rgba.shape[1]):
        c = rgba[y][x]
        n = 0 if c is None else len(c)
        pixels.append([[float(z[y][x][i]), float(back[y][x][i]), float(c[i][3]), float(c[i][0]),
                        float(c[i][1]), float(c[i][2])] for i in range(n)])
print(json.dumps(pixels))
"#;

#[test]
fn openexrs_python_module_reads_back_every_sample() {
    let python = std::env::var("NIMBUS_PYTHON").unwrap_or_else(|_| "python3".into());
    let has_module = Command::new(&python)
        .args(["-c", "import OpenEXR"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_module {
        assert!(
            std::env::var("NIMBUS_REQUIRE_TOOLS").as_deref() != Ok("1"),
            "{python} cannot import OpenEXR and NIMBUS_REQUIRE_TOOLS=1"
        );
        eprintln!("SKIP: {python} cannot import OpenEXR (pip install OpenEXR)");
        return;
    }
    let dir = temp_dir("python");
    let (_, deep) = render_deep(&slab_scene(&dir, true), 5);
    for (name, compression) in [
        ("none.deep.exr", nimbus::output::DeepCompression::None),
        ("zips.deep.exr", nimbus::output::DeepCompression::Zips),
    ] {
        let path = dir.join(name);
        nimbus::output::write_deep_exr(&deep, &path, compression, &Default::default()).unwrap();
        let out = Command::new(&python)
            .args(["-c", READ_DEEP, path.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let pixels: Vec<Vec<[f32; 6]>> = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(pixels.len(), SIZE * SIZE);
        for (i, read) in pixels.iter().enumerate() {
            let ours: Vec<[f32; 6]> = deep
                .pixel(i)
                .iter()
                .map(|s| [s.z, s.z_back, s.a, s.rgb[0], s.rgb[1], s.rgb[2]])
                .collect();
            assert_eq!(read, &ours, "{name}: pixel {i}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn farm_parts_and_checkpoints_refuse_deep_output_in_one_line() {
    let dir = temp_dir("parts");
    for extra in [
        &["--samples", "0..2"][..],
        &["--crop", "0,0,4,4"],
        &["--checkpoint", "60"],
        &["--resume"],
    ] {
        let mut args = vec!["render", "--width", "8", "--spp", "4", "--deep"];
        args.extend(extra);
        let (ok, _, err) = run_nimbus(&args, &dir);
        assert!(!ok, "{extra:?}");
        assert!(
            err.contains("--deep renders whole frames only") && err.trim().lines().count() == 1,
            "{extra:?}: {err}"
        );
    }
    assert!(
        std::fs::read_dir(&dir).unwrap().next().is_none(),
        "nothing written"
    );
    // --deep-samples needs --deep.
    let (ok, _, err) = run_nimbus(&["render", "--deep-samples", "4"], &dir);
    assert!(!ok && err.contains("--deep"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
