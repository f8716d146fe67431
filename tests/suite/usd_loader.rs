//! The USD loader against stages authored by Pixar's USD library (`tests/usd/make_stages.py`): what each stage
//! holds, the volume declaration, robustness to damaged files, and the same Cornell box rendered from USD and
//! from glTF.

use nimbus::light::Light;
use nimbus::math::{Rgb, Vec2, Vec3};
use nimbus::render::{RenderImage, RenderSettings, Renderer};
use nimbus::scene::{usd, Scene, SceneBuilder, SceneErrorKind};
use std::path::{Path, PathBuf};

fn stage(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/usd")
        .join(name)
}

fn read(name: &str) -> SceneBuilder {
    let (builder, volumes) = usd::read(&stage(name)).unwrap_or_else(|e| panic!("{e}"));
    assert!(volumes.is_empty());
    builder
}

/// Checks the Cornell box as `make_stages.py` authors it.
fn check_cornell(b: &SceneBuilder) {
    // 5 walls of 1 quad, 2 boxes of 6 quads, and the rect light's quad.
    assert_eq!(b.meshes().len(), 8);
    let triangles: usize = b.meshes().iter().map(|m| m.indices.len()).sum();
    assert_eq!(triangles, 36);
    assert!(b.lights().is_empty(), "the rect light is an emissive mesh");
    assert!(b.warnings().is_empty(), "{:?}", b.warnings());
    let cam = b.camera().expect("camera");
    assert!((cam.yfov - 2.0 * (12.0f32 / 35.0).atan()).abs() < 1e-5);
    assert_eq!(cam.aspect_ratio, Some(1.0));
    assert!(cam.position().distance(Vec3::new(0.0, 1.0, 3.6)) < 1e-5);
    // The light: 0.5 x 0.4 at y = 1.98, emitting downward, radiance colour x 6 x 2^1.
    let light = b
        .meshes()
        .iter()
        .find(|m| m.name == "/World/Light")
        .unwrap();
    let bounds = light.bounds();
    assert!((bounds.max.x - 0.25).abs() < 1e-5 && (bounds.max.z - 0.2).abs() < 1e-5);
    assert!((bounds.min.y - 1.98).abs() < 1e-5);
    let [a, b2, c] = light.triangle(0);
    assert!((b2 - a).cross(c - a).normalize().distance(-Vec3::Y) < 1e-5);
    let emission = b.materials()[light.material as usize].emission;
    assert!(emission.distance(Rgb::new(1.0, 0.85, 0.7) * 12.0) < 1e-4);
    let red = b
        .materials()
        .iter()
        .find(|m| m.name == "/World/Materials/Red")
        .unwrap();
    assert!(
        red.base_color
            .truncate()
            .distance(Rgb::new(0.65, 0.05, 0.05))
            < 1e-6
    );
    assert_eq!(
        (red.metallic, red.roughness, red.specular_factor),
        (0.0, 0.9, 1.0)
    );
}

#[test]
fn cornell_usda_loads() {
    let b = read("cornell.usda");
    check_cornell(&b);
    let scene = b.build().unwrap();
    assert_eq!(scene.triangle_count(), 36);
    let area_lights = scene
        .lights()
        .iter()
        .filter(|l| matches!(l, Light::Area(_)))
        .count();
    assert_eq!(area_lights, 2);
}

#[test]
fn cornell_usdc_matches_usda() {
    let a = read("cornell.usda");
    let c = read("cornell.usdc");
    check_cornell(&c);
    for (x, y) in a.meshes().iter().zip(c.meshes()) {
        assert_eq!(x.name, y.name);
        assert_eq!(x.positions, y.positions);
        assert_eq!(x.indices, y.indices);
    }
}

#[test]
fn referenced_layer_overrides_apply() {
    let b = read("override.usda");
    assert_eq!(
        b.meshes().iter().map(|m| m.indices.len()).sum::<usize>(),
        36
    );
    let red = b
        .materials()
        .iter()
        .find(|m| m.name == "/World/Materials/Red")
        .unwrap();
    assert!(
        red.base_color
            .truncate()
            .distance(Rgb::new(0.05, 0.05, 0.65))
            < 1e-6
    );
    let tall = b
        .meshes()
        .iter()
        .find(|m| m.name == "/World/TallBox/Geom")
        .unwrap();
    assert!((tall.bounds().center().z + 0.5).abs() < 1e-5);
    assert!(b.camera().is_some());
}

#[test]
fn volume_spec_from_usdvol() {
    let (b, volumes) = usd::read(&stage("volume.usda")).unwrap();
    assert!(b.meshes().is_empty());
    assert!(b.warnings().is_empty(), "{:?}", b.warnings());
    assert_eq!(volumes.len(), 1);
    let v = &volumes[0];
    assert_eq!(v.name, "/World/Cloud");
    assert_eq!(
        v.file.canonicalize().unwrap(),
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("assets/cloud.vdb")
            .canonicalize()
            .unwrap()
    );
    assert_eq!(v.density_grid, "density");
    assert_eq!(v.temperature_grid.as_deref(), Some("temperature"));
    assert_eq!(v.density_scale, 8.0);
    assert!(v.albedo.distance(Rgb::new(0.9, 0.8, 0.7)) < 1e-6);
    assert_eq!(
        (
            v.anisotropy,
            v.emission_scale,
            v.temperature_scale,
            v.temperature_offset
        ),
        (0.6, 2.0, 1.5, -100.0)
    );
    // Z-up centimetres: translate (10, 20, 30) cm lands at (0.1, 0.3, -0.2) m in Y-up; the 100x scale cancels
    // the 0.01 m unit, and the stage's +Z becomes +Y.
    let m = v.node_to_world;
    assert!(
        m.transform_point3(Vec3::ZERO)
            .distance(Vec3::new(0.1, 0.3, -0.2))
            < 1e-5
    );
    assert!(m.transform_vector3(Vec3::Z).distance(Vec3::Y) < 1e-5);
    assert!(m.transform_vector3(Vec3::X).distance(Vec3::X) < 1e-5);
}

#[test]
fn load_builder_dispatches_usd_extensions() {
    let b = nimbus::scene::load_builder(&stage("cornell.usdc"), &Default::default()).unwrap();
    assert_eq!(b.meshes().len(), 8);
}

/// Writes `bytes` to a fresh file with `ext` in the temporary folder.
fn temp_file(tag: &str, ext: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_usd_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("{tag}.{ext}"));
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn truncated_and_corrupted_stages_are_errors_not_panics() {
    let mut caught_panics = Vec::new();
    for (name, ext) in [("cornell.usda", "usda"), ("cornell.usdc", "usdc")] {
        let bytes = std::fs::read(stage(name)).unwrap();
        let first_def = if ext == "usda" {
            String::from_utf8_lossy(&bytes).find("def ").unwrap()
        } else {
            0
        };
        let step = (bytes.len() / 97).max(1);
        for cut in (0..bytes.len() - 1).step_by(step) {
            let p = temp_file(&format!("cut{cut}"), ext, &bytes[..cut]);
            let r = usd::read(&p);
            if let Err(e) = &r {
                if matches!(e.kind, SceneErrorKind::ReaderPanicked { .. }) {
                    caught_panics.push(format!("{name} cut at {cut}: {e}"));
                }
            }
            if cut > first_def {
                assert!(r.is_err(), "{name} truncated at {cut} loaded");
            }
            if ext == "usdc" {
                // The same damaged layer reached through a reference.
                let layer = format!(
                    "#usda 1.0\ndef \"R\" (\n    references = @./cut{cut}.usdc@</World>\n)\n{{\n}}\n"
                );
                let root = temp_file(&format!("ref{cut}"), "usda", layer.as_bytes());
                assert!(
                    usd::read(&root).is_err(),
                    "reference to {name} cut at {cut}"
                );
                std::fs::remove_file(&root).unwrap();
            }
            std::fs::remove_file(&p).unwrap();
        }
        let mut rng = 0x2545F4914F6CDD1Du64;
        for i in 0..64 {
            let mut damaged = bytes.clone();
            for _ in 0..4 {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                let at = (rng % bytes.len() as u64) as usize;
                damaged[at] ^= (rng >> 32) as u8 | 1;
            }
            let p = temp_file(&format!("flip{i}"), ext, &damaged);
            // Loading or an error are both fine; a panic, even one the loader catches, is not.
            if let Err(e) = usd::read(&p) {
                if matches!(e.kind, SceneErrorKind::ReaderPanicked { .. }) {
                    caught_panics.push(format!("{name} flip {i}: {e}"));
                }
            }
            std::fs::remove_file(&p).unwrap();
        }
    }
    // openusd 0.6 still panics on 3 of these 64 bit-flipped .usdc files (out-of-bounds indices that
    // `crate_check` does not yet rule out); the loader catches them quietly, and this test
    // sees them. The hostile-input issue removes them; until then any new one fails here.
    const KNOWN_OPENUSD_PANICS: usize = 3;
    eprintln!("{}", caught_panics.join("\n"));
    assert!(
        caught_panics.len() <= KNOWN_OPENUSD_PANICS,
        "{} damaged stages panicked inside openusd:\n{}",
        caught_panics.len(),
        caught_panics.join("\n")
    );
}

/// A reference to a layer that does not exist is skipped with a warning naming it, and the rest of the stage is
/// read, as usdview shows such a stage (Pixar's USD 26.11 opens it and reports the unresolved asset). It used to
/// abort the whole stage.
#[test]
fn a_missing_reference_is_skipped_with_a_warning_naming_the_layer() {
    let p = temp_file(
        "dangling",
        "usda",
        b"#usda 1.0\n\ndef \"World\" (\n    references = @./nowhere.usda@\n)\n{\n}\n\n\
def Mesh \"Floor\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n\
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 0, 1)]\n}\n",
    );
    let (b, _) = usd::read(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(b.meshes().len(), 1, "the floor is read");
    assert!(
        b.warnings()
            .iter()
            .any(|w| w.contains("nowhere.usda") && w.contains("skipped")),
        "{:?}",
        b.warnings()
    );
}

/// A DistantLight warns about its angle (rendered as a delta light) only where the file authors one above 0:
/// UsdLux's unauthored default of 0.53 degrees is in every file and is not worth a word.
#[test]
fn a_distant_light_warns_about_its_angle_only_when_the_file_authors_one() {
    let warnings = |tag: &str, angle: &str| {
        let text = format!(
            "#usda 1.0\n\ndef DistantLight \"Sun\"\n{{\n    float inputs:intensity = 2\n{angle}}}\n"
        );
        let (b, _) = usd::read(&temp_file(tag, "usda", text.as_bytes())).unwrap();
        assert_eq!(b.lights().len(), 1, "{tag}: the sun is read");
        b.warnings()
            .iter()
            .filter(|w| w.contains("inputs:angle"))
            .count()
    };
    assert_eq!(warnings("sun_default", ""), 0);
    assert_eq!(warnings("sun_point", "    float inputs:angle = 0\n"), 0);
    assert_eq!(warnings("sun_disc", "    float inputs:angle = 1.5\n"), 1);
}

fn render(scene: &Scene) -> RenderImage {
    let settings = RenderSettings {
        width: 24,
        height: 24,
        spp: 16,
        seed: 3,
        threads: 2,
        max_depth: 8,
        ..RenderSettings::default()
    };
    Renderer::new(settings)
        .render(scene, &mut |_| true)
        .unwrap()
        .0
}

#[test]
fn usd_and_gltf_cornell_boxes_render_alike() {
    let from_usd = read("cornell.usda").build().unwrap();
    let from_gltf = Scene::load(&stage("cornell.gltf")).unwrap();
    let (a, b) = (render(&from_usd), render(&from_gltf));
    for c in 0..3 {
        let stats = |img: &RenderImage| {
            let n = img.pixel_count() as f64;
            let mean = img.beauty.iter().map(|p| p[c] as f64).sum::<f64>() / n;
            let var = img.variance.iter().map(|p| p[c] as f64).sum::<f64>() / (n * n);
            (mean, var)
        };
        let ((ma, va), (mb, vb)) = (stats(&a), stats(&b));
        let se = (va + vb).sqrt();
        assert!(ma > 0.01, "channel {c}: the USD box is lit ({ma})");
        assert!(
            (ma - mb).abs() < 4.0 * se,
            "channel {c}: USD {ma} vs glTF {mb} (se {se})"
        );
    }
}

#[test]
fn hand_written_stage_exercises_ops_primvars_and_lights() {
    let p = temp_file(
        "features",
        "usda",
        br#"#usda 1.0
def Xform "X" {
    double3 xformOp:translate = (1, 0, 0)
    float3 xformOp:rotateXYZ = (0, 90, 0)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    def Mesh "M" {
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        uniform token orientation = "leftHanded"
        uniform token subdivisionScheme = "none"
        uniform bool doubleSided = 1
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (interpolation = "faceVarying")
    }
    def SphereLight "S" {
        float inputs:radius = 0.1
        float inputs:intensity = 2
        bool treatAsPoint = 1
    }
    def DomeLight "D" {
        color3f inputs:color = (0.5, 0.25, 1)
    }
    def BasisCurves "C" {}
    def BasisCurves "C2" {}
}
"#,
    );
    let (b, _) = usd::read(&p).unwrap();
    assert_eq!(b.meshes().len(), 1);
    let m = &b.meshes()[0];
    assert_eq!(m.name, "/X/M");
    assert_eq!(m.indices.len(), 2);
    // translate (1, 0, 0) after rotateY 90: the local +X corner lands at (1, 0, -1). (Without normals each
    // triangle has its own flat-shaded corners, so the corner is looked for, not indexed.)
    assert!(m
        .positions
        .iter()
        .any(|p| p.distance(Vec3::new(1.0, 0.0, -1.0)) < 1e-5));
    // leftHanded: the front face is local -Z, i.e. world -X after the rotation.
    let [a, b2, c] = m.triangle(0);
    assert!((b2 - a).cross(c - a).normalize().distance(-Vec3::X) < 1e-5);
    let uv = m.uvs.as_ref().unwrap();
    assert_eq!(uv[0], nimbus::math::Vec2::new(0.0, 1.0), "USD's t runs up");
    assert!(b.materials()[m.material as usize].double_sided);
    let point = b.lights().iter().find_map(|l| match l {
        Light::Point(p) => Some(p),
        _ => None,
    });
    let expected = 2.0 * std::f32::consts::PI * 0.01;
    assert!((point.unwrap().intensity.x - expected).abs() < 1e-6);
    assert!(b.lights().iter().any(|l| matches!(
        l,
        Light::Environment(nimbus::light::EnvironmentLight::Constant(c)) if *c == Rgb::new(0.5, 0.25, 1.0)
    )));
    let curve_warnings = b
        .warnings()
        .iter()
        .filter(|w| w.contains("'BasisCurves'"))
        .count();
    assert_eq!(curve_warnings, 1, "{:?}", b.warnings());
}

#[test]
fn cornell_usdz_package_loads() {
    check_cornell(&read("cornell.usdz"));
}

#[test]
fn preview_surface_reads_uv_texture() {
    let b = read("textured.usda");
    assert_eq!(b.meshes().len(), 1);
    let m = &b.materials()[b.meshes()[0].material as usize];
    let tex = m
        .base_color_texture
        .expect("diffuseColor connects to a UsdUVTexture");
    assert_eq!(m.base_color.truncate(), Rgb::ONE);
    // checker.png's top-left texel is red; USD's st (0, 0) is the image's bottom-left (blue).
    let t = &b.textures()[tex as usize];
    let top_left = t.sample(nimbus::math::Vec2::new(0.25, 0.25)).truncate();
    assert!(top_left.distance(Rgb::X) < 1e-3, "{top_left:?}");
    assert_eq!(
        b.meshes()[0].uvs.as_ref().unwrap()[0],
        nimbus::math::Vec2::Y
    );
    let bottom_left = t.sample(nimbus::math::Vec2::new(0.25, 0.75)).truncate();
    assert!(bottom_left.distance(Rgb::Z) < 1e-3, "{bottom_left:?}");
}

#[test]
fn bad_topology_and_values_are_errors_naming_the_prim() {
    for (tag, body) in [
        (
            "index",
            "point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n int[] faceVertexCounts = [3]\n \
             int[] faceVertexIndices = [0, 1, 7]",
        ),
        (
            "counts",
            "point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n int[] faceVertexCounts = [4]\n \
             int[] faceVertexIndices = [0, 1, 2]",
        ),
        (
            "normals",
            "point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0)]\n int[] faceVertexCounts = [3]\n \
             int[] faceVertexIndices = [0, 1, 2]\n normal3f[] normals = [(0, 0, 1)] (interpolation = \"faceVarying\")",
        ),
        (
            "xform",
            "float xformOp:translate = 3\n uniform token[] xformOpOrder = [\"xformOp:translate\"]",
        ),
    ] {
        let text = format!("#usda 1.0\ndef Mesh \"Bad\" {{\n {body}\n}}\n");
        let p = temp_file(&format!("bad_{tag}"), "usda", text.as_bytes());
        let err = usd::read(&p).err().unwrap_or_else(|| panic!("{tag} loaded"));
        assert!(err.to_string().contains("/Bad"), "{tag}: {err}");
    }
}

/// A text layer of `levels` nested `Xform` prims.
fn nested_layer(levels: usize) -> String {
    let mut text = String::from("#usda 1.0\n");
    for i in 0..levels {
        text.push_str(&format!("def Xform \"a{i}\" {{\n"));
    }
    text.push_str(&"}\n".repeat(levels));
    text
}

/// `err` is one line of printable ASCII containing `needle`.
fn one_line_error(err: &nimbus::scene::SceneError, needle: &str) {
    let msg = err.to_string();
    assert!(
        msg.chars().all(|c| c.is_ascii_graphic() || c == ' '),
        "not one printable line: {msg:?}"
    );
    assert!(msg.contains(needle), "{msg:?} should contain {needle:?}");
}

/// A `.usdz` package holding `layers` (name, text), the first the root.
fn package(tag: &str, layers: &[(&str, &[u8])]) -> PathBuf {
    let mut writer = openusd::usdz::ArchiveWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, bytes) in layers {
        writer.add_layer(name, bytes).unwrap();
    }
    let bytes = writer.finish().unwrap().into_inner();
    temp_file(tag, "usdz", &bytes)
}

#[test]
fn deeply_nested_layers_are_errors_not_stack_overflows() {
    let deep = nested_layer(10_000);
    let limit = usd::MAX_NESTING;
    let p = temp_file("deep", "usda", deep.as_bytes());
    one_line_error(&usd::read(&p).err().expect("too deep"), "nested deeper");
    // The same layer as a sublayer, a reference, inside a package and referenced inside a package.
    let sub = temp_file(
        "deep_sub",
        "usda",
        b"#usda 1.0\n(\n    subLayers = [@./deep.usda@]\n)\n",
    );
    one_line_error(&usd::read(&sub).err().expect("too deep"), "nested deeper");
    let reference = temp_file(
        "deep_ref",
        "usda",
        b"#usda 1.0\ndef \"R\" (\n    references = @./deep.usda@</a0>\n)\n{\n}\n",
    );
    one_line_error(
        &usd::read(&reference).err().expect("too deep"),
        "nested deeper",
    );
    let usdz = package("deep_pkg", &[("root.usda", deep.as_bytes())]);
    one_line_error(&usd::read(&usdz).err().expect("too deep"), "nested deeper");
    let inner = package(
        "deep_inner",
        &[
            ("root.usda", nested_layer(2).as_bytes()),
            ("deep.usda", deep.as_bytes()),
        ],
    );
    one_line_error(&usd::read(&inner).err().expect("too deep"), "nested deeper");
    let packaged_ref = temp_file(
        "deep_pkg_ref",
        "usda",
        b"#usda 1.0\ndef \"R\" (\n    references = @./deep_inner.usdz[deep.usda]@</a0>\n)\n{\n}\n",
    );
    one_line_error(
        &usd::read(&packaged_ref).err().expect("too deep"),
        "nested deeper",
    );
    // Just under the limit (each prim level is one pair of braces) reads, here on the test's own 2 MiB thread.
    let fits = temp_file("fits", "usda", nested_layer(limit - 1).as_bytes());
    usd::read(&fits).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn endless_devices_and_package_bombs_are_clear_errors() {
    let zero = Path::new("/dev/zero");
    if zero.exists() {
        let link =
            std::env::temp_dir().join(format!("nimbus_usd_zero_{}.usda", std::process::id()));
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(zero, &link).unwrap();
        let err = usd::read(&link).err().expect("an endless device");
        one_line_error(&err, "endless device");
        assert!(matches!(err.kind, SceneErrorKind::Io(_)));
        let sub = temp_file(
            "zero_sub",
            "usda",
            format!("#usda 1.0\n(\n    subLayers = [@{}@]\n)\n", link.display()).as_bytes(),
        );
        // openusd resolves the link to /dev/zero, which has no format; either way it is never read whole.
        one_line_error(
            &usd::read(&sub).err().expect("an endless device"),
            "/dev/zero",
        );
        std::fs::remove_file(&link).unwrap();
    }
    // A package whose layer expands beyond the memory budget.
    let mut big = b"#usda 1.0\n".to_vec();
    big.resize(4 << 20, b' ');
    let usdz = package("bomb", &[("root.usda", &big)]);
    let limits = nimbus::limits::Limits::with_memory(1 << 20);
    let err = usd::read_with_limits(&usdz, &limits)
        .err()
        .expect("too big");
    one_line_error(&err, "memory budget");
    // Under a budget it fits, and the entry is read.
    usd::read(&usdz).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn a_caught_openusd_panic_prints_one_line_and_no_backtrace() {
    // The same flips as `damaged_stages_are_errors_not_panics`: find one on which openusd panics.
    let bytes = std::fs::read(stage("cornell.usdc")).unwrap();
    let mut rng = 0x2545F4914F6CDD1Du64;
    let panicking = (0..64).find_map(|i| {
        let mut damaged = bytes.clone();
        for _ in 0..4 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let at = (rng % bytes.len() as u64) as usize;
            damaged[at] ^= (rng >> 32) as u8 | 1;
        }
        let p = temp_file(&format!("quiet{i}"), "usdc", &damaged);
        match usd::read(&p) {
            Err(e) if matches!(e.kind, SceneErrorKind::ReaderPanicked { .. }) => Some(p),
            _ => None,
        }
    });
    let Some(path) = panicking else {
        eprintln!("no flip panics inside openusd any more; nothing to check");
        return;
    };
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("render")
        .arg(&path)
        .args(["--width", "8", "--spp", "1", "-o"])
        .arg(path.with_extension("exr"))
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("nimbus: error:"), "{stderr}");
    assert!(
        !stderr.contains("panicked at") && !stderr.contains("backtrace"),
        "{stderr}"
    );
}

/// A fresh, empty folder for a stage of several layers.
fn stage_folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_usd_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The issue's reproducer (a prim that inherits itself, with a child) and its kin: a prim that specializes itself,
/// and two that inherit each other. `openusd` 0.6 pre-caches inherit and specialize targets recursively without
/// remembering the ones it has seen, so composing the child overflowed the reader thread's stack, which aborts the
/// process.
#[test]
fn an_inherits_cycle_with_a_child_is_an_error_not_a_stack_overflow() {
    for (tag, text, arc) in [
        (
            "self",
            "#usda 1.0\ndef Xform \"A\" (inherits = </A>) { def Xform \"C\" {} }",
            "/A: inherits </A>",
        ),
        (
            "specializes",
            "#usda 1.0\ndef Xform \"A\" (specializes = </A>) { def Xform \"C\" {} }",
            "/A: specializes </A>",
        ),
        (
            "mutual",
            "#usda 1.0\ndef Xform \"A\" (inherits = </B>) { def Xform \"C\" {} }\n\
             class Xform \"B\" (inherits = </A>) {}\n",
            "/A: inherits </B>",
        ),
    ] {
        let p = temp_file(&format!("cycle_{tag}"), "usda", text.as_bytes());
        let err = usd::read(&p).err().expect("an arc cycle is an error");
        one_line_error(&err, arc);
        one_line_error(&err, "composition cycle");
    }
}

/// Cycles of `openusd`'s pre-caching that no arc cycle of the layers shows. `openusd` takes an inherit or
/// specialize target as a path of the stage whatever layer stack authored it, and maps it through every arc of
/// the prim's ancestors, whatever layer stack the arc targets: a target mapped onto a child of the prim that
/// authors it (through a payload to another layer), and a target in a referenced layer that names a stage prim
/// specializing the child of the referencing prim, each overflowed the reader thread's stack.
#[test]
fn pre_caching_cycles_through_other_layer_stacks_are_errors_not_stack_overflows() {
    for (tag, root, other, arc) in [
        (
            "payload_map",
            "def Xform \"A\" (specializes = </D/B> payload = @./other.usda@</D>) { def Xform \"C\" {} }",
            "",
            "/A: specializes </D/B>",
        ),
        (
            "stage_path",
            "def Xform \"A\" (references = @./other.usda@</X>) { def Xform \"C\" {} }\n\
             def \"Q\" (specializes = </A/B>) {}",
            "def \"X\" (specializes = </Q>) {}",
            // The walk meets it as a class implied back through the reference, before the pre-caching model.
            "/X: specializes </Q>",
        ),
    ] {
        let dir = stage_folder(&format!("precache_{tag}"));
        std::fs::write(dir.join("root.usda"), format!("#usda 1.0\n{root}\n")).unwrap();
        std::fs::write(dir.join("other.usda"), format!("#usda 1.0\n{other}\n")).unwrap();
        let err = usd::read(&dir.join("root.usda"))
            .err()
            .expect("a pre-caching cycle is an error");
        one_line_error(&err, arc);
        one_line_error(&err, "composition cycle");
    }
}

/// `levels` levels of prims `L<i>`, each with two children that reference `L<i-1>`: `L<levels>` composes to
/// 2^(levels + 1) − 1 prims from a file of a few lines per level.
fn reference_fan_out(levels: usize) -> String {
    let mut text = String::from("#usda 1.0\ndef Xform \"L0\" {}\n");
    for i in 1..=levels {
        text.push_str(&format!(
            "def Xform \"L{i}\" {{\n    def Xform \"a\" (references = </L{p}>) {{}}\n    \
             def Xform \"b\" (references = </L{p}>) {{}}\n}}\n",
            p = i - 1
        ));
    }
    text
}

/// 20 levels of 2 internal references make 2^20 prims at the bottom level alone; reading them all ran into the
/// reader's 120 s limit. The prims the arcs would compose are counted before `openusd` composes them.
#[test]
fn a_reference_fan_out_is_refused_by_the_prim_limit() {
    let p = temp_file("fan_out", "usda", reference_fan_out(20).as_bytes());
    let start = std::time::Instant::now();
    let err = usd::read(&p).err().expect("2^20 prims are refused");
    let took = start.elapsed();
    one_line_error(&err, "--max-prims");
    assert!(took < std::time::Duration::from_secs(10), "took {took:?}");
}

/// Under `--max-prims` a smaller fan-out loads, and over it the command line says which flag raises the limit.
#[test]
fn the_max_prims_flag_sets_the_prim_limit() {
    // L10 composes 2^12 − 3 prims; the stage, L0 to L10, 8,155.
    let p = temp_file("fan_out_10", "usda", reference_fan_out(10).as_bytes());
    let limits = |usd_prims| nimbus::limits::Limits {
        usd_prims,
        ..Default::default()
    };
    usd::read_with_limits(&p, &limits(8155)).unwrap_or_else(|e| panic!("{e}"));
    let err = usd::read_with_limits(&p, &limits(8154))
        .err()
        .expect("over 8154 prims");
    one_line_error(&err, "the stage composes 8155 prims");
    let render = |flags: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
            .arg("render")
            .arg(&p)
            .args(["--width", "8", "--spp", "1", "-o"])
            .arg(p.with_extension("exr"))
            .args(flags)
            .output()
            .unwrap()
    };
    let refused = render(&["--max-prims", "4000"]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("/L10 composes 4093 prims") && stderr.contains("--max-prims"),
        "{stderr}"
    );
    let rendered = render(&["--max-prims", "10000"]);
    assert!(
        rendered.status.success(),
        "{}",
        String::from_utf8_lossy(&rendered.stderr)
    );
}

/// What an ancestor's arc maps onto an arc's target is not in the count made before composing (each `X<k>`
/// inherits `/P/q`, which holds the 100 cubes of `/Base/q` through `/P`'s reference): every prim read is counted
/// too.
#[test]
fn prims_an_ancestor_arc_maps_are_counted_as_the_stage_is_read() {
    let mut text = String::from("#usda 1.0\ndef \"Base\" {\n    def \"q\" {\n");
    for k in 0..100 {
        text.push_str(&format!("        def Cube \"c{k}\" {{}}\n"));
    }
    text.push_str("    }\n}\ndef \"P\" (references = </Base>) {}\n");
    for k in 0..10 {
        text.push_str(&format!("def \"X{k}\" (inherits = </P/q>) {{}}\n"));
    }
    let p = temp_file("mapped_prims", "usda", text.as_bytes());
    let (b, _) = usd::read(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        b.meshes().len(),
        1200,
        "the cubes of /Base/q, /P/q and every X<k>"
    );
    // The check before composing follows each X<k> to /P/q and, through /P's reference (an ancestor's arc),
    // to /Base/q and its 100 cubes; the count as the stage is read backs it up.
    let limits = nimbus::limits::Limits {
        usd_prims: 500,
        ..Default::default()
    };
    let err = usd::read_with_limits(&p, &limits)
        .err()
        .expect("over 500 prims");
    one_line_error(
        &err,
        "more than 500 prims through its arcs and children (each counted once per arc that brings it in), over \
         the limit of 500 prims (raise it with --max-prims)",
    );
}

/// Writes `levels` layers `d0.usda` … into `dir`, each naming the next twice as a sublayer (the last holds a
/// cube): the layer stack of `d0` expands to 2^levels − 1 entries, 2^(levels − 1) of them the last layer.
fn sublayer_diamond(dir: &Path, levels: usize) -> PathBuf {
    for i in 0..levels {
        let text = if i + 1 < levels {
            format!(
                "#usda 1.0\n(\n    subLayers = [@./d{n}.usda@, @./d{n}.usda@]\n)\n",
                n = i + 1
            )
        } else {
            "#usda 1.0\ndef Cube \"Leaf\" {}\n".to_owned()
        };
        std::fs::write(dir.join(format!("d{i}.usda")), text).unwrap();
    }
    dir.join("d0.usda")
}

/// 25 layers that each name the next twice expand to a layer stack of 2^24 entries, which `openusd` builds
/// entry by entry (a hang of minutes, and gigabytes). The layer stack is counted before `openusd` opens it.
#[test]
fn a_sublayer_diamond_is_refused_by_the_layer_stack_limit() {
    let root = sublayer_diamond(&stage_folder("diamond"), 25);
    let start = std::time::Instant::now();
    let err = usd::read(&root)
        .err()
        .expect("2^24 layer-stack entries are refused");
    let took = start.elapsed();
    one_line_error(&err, "--max-sublayers");
    assert!(took < std::time::Duration::from_secs(10), "took {took:?}");
}

/// Sublayers named more than once are legitimate within the limit: 10 levels make 1,023 entries, over the
/// default 1,000 and within `--max-sublayers 1023`; the leaf's prim is composed once.
#[test]
fn a_small_sublayer_diamond_loads_within_the_max_sublayers_flag() {
    let root = sublayer_diamond(&stage_folder("diamond_10"), 10);
    let err = usd::read(&root)
        .err()
        .expect("1023 entries, over the default limit");
    one_line_error(&err, "expands to 1023 layers");
    let limits = nimbus::limits::Limits {
        usd_layer_stack: 1023,
        ..Default::default()
    };
    let (b, _) = usd::read_with_limits(&root, &limits).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(b.meshes().len(), 1);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .arg("render")
        .arg(&root)
        .args([
            "--max-sublayers",
            "1023",
            "--width",
            "8",
            "--spp",
            "1",
            "-o",
        ])
        .arg(root.with_extension("exr"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
}

/// `displayColor` of every interpolation, and a `UsdPrimvarReader_float3` on `diffuseColor`, give per-vertex
/// base colours (`tests/usd/primvar_colors.usda`; Pixar's USD 26.11 opens it and flattens the vertex
/// `displayColor` to the four colours below). Only the first value used to be read, so no gradient showed.
#[test]
fn display_colors_and_primvar_readers_colour_each_vertex() {
    let b = read("primvar_colors.usda");
    let mesh = |name: &str| {
        b.meshes()
            .iter()
            .find(|m| m.name.ends_with(name))
            .unwrap_or_else(|| panic!("no mesh {name}"))
    };
    // The colour at each triangle corner, in triangle order.
    let rgb = |m: &nimbus::geometry::Mesh| -> Vec<[f32; 3]> {
        let colors = m
            .colors
            .as_ref()
            .unwrap_or_else(|| panic!("{}: no vertex colours", m.name));
        m.indices
            .iter()
            .flatten()
            .map(|&i| colors[i as usize].truncate().to_array())
            .collect()
    };
    let white = |m: &nimbus::geometry::Mesh| {
        let base = b.materials()[m.material as usize].base_color;
        assert_eq!(base.truncate(), Rgb::ONE, "{}: base colour {base}", m.name);
    };
    // Vertex: one colour per point, each face corner taking its point's (the quad is fanned from point 0).
    let gradient = mesh("Gradient");
    white(gradient);
    let (r, g, bl, w) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0; 3]);
    assert_eq!(rgb(gradient), [r, g, bl, r, bl, w]);
    // Uniform: one colour per face.
    let per_face = mesh("PerFace");
    white(per_face);
    assert_eq!(
        rgb(per_face),
        [
            [0.25, 0.5, 0.75],
            [0.25, 0.5, 0.75],
            [0.25, 0.5, 0.75],
            [0.5, 0.5, 0.5],
            [0.5, 0.5, 0.5],
            [0.5, 0.5, 0.5]
        ]
    );
    // A primvar reader of `tint` (faceVarying), and its fallback on a mesh without the primvar.
    let read_mesh = mesh("Read");
    white(read_mesh);
    assert_eq!(
        rgb(read_mesh),
        [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]]
    );
    let fallback = mesh("NoTint");
    white(fallback);
    assert_eq!(rgb(fallback), [[0.9, 0.6, 0.3]; 3]);
}

/// A `UsdTransform2d` between the st reader and the texture (`tests/usd/transform2d.usda`: rotation 90°,
/// scale (2, 1), translation (0.25, 0)) maps texture coordinates as the UsdPreviewSurface specification says,
/// st' = translation + R(90°)·(scale ⊙ st): st (1, 0) → (0.25, 2) and st (0, 1) → (−0.75, 0), by hand. It used
/// to be ignored.
#[test]
fn a_usd_transform_2d_maps_the_texture_coordinates() {
    let b = read("transform2d.usda");
    let material = &b.materials()[b.meshes()[0].material as usize];
    let texture = &b.textures()[material.base_color_texture.expect("textured") as usize];
    // Nimbus's texture coordinates are (s, 1 − t).
    for (st, want) in [
        ((1.0, 0.0), (0.25, 2.0)),
        ((0.0, 1.0), (-0.75, 0.0)),
        ((0.0, 0.0), (0.25, 0.0)),
    ] {
        let uv = texture
            .transform()
            .apply(nimbus::math::Vec2::new(st.0, 1.0 - st.1));
        let got = (uv.x, 1.0 - uv.y);
        assert!(
            (got.0 - want.0).abs() < 1e-5 && (got.1 - want.1).abs() < 1e-5,
            "st {st:?}: {got:?} vs {want:?}"
        );
    }
}

/// Roughness and metallic read from the r and g channels of one `UsdUVTexture` (`tests/usd/scalar_textures.usda`:
/// raw, scale 0.5 and bias 0.25 on r) become glTF's packed texture: G = 0.5·r + 0.25, B = g, with factors 1.
/// The 2×2 `checker.png` is red, green / blue, white (as the `image` crate decodes it). Textured scalar inputs
/// used to be warned about and their untextured values used.
#[test]
fn textured_roughness_and_metallic_are_read_per_texel() {
    let b = read("scalar_textures.usda");
    let material = &b.materials()[b.meshes()[0].material as usize];
    assert_eq!((material.roughness, material.metallic), (1.0, 1.0));
    let texture = &b.textures()[material
        .metallic_roughness_texture
        .expect("a metallic-roughness texture") as usize];
    let png = image::open(stage("checker.png")).unwrap().to_rgb8();
    for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let p = png.get_pixel(x, y).0;
        let (r, g) = (p[0] as f32 / 255.0, p[1] as f32 / 255.0);
        // The texel centre; its bilinear value is the texel's own.
        let uv = nimbus::math::Vec2::new((x as f32 + 0.5) / 2.0, (y as f32 + 0.5) / 2.0);
        let texel = texture.sample(uv);
        assert!(
            (texel.y - (0.5 * r + 0.25)).abs() < 1e-5 && (texel.z - g).abs() < 1e-5,
            "texel ({x}, {y}): {texel} for r {r}, g {g}"
        );
    }
}

/// A `catmullClark` cube (USD's default scheme) is subdivided: at one level its corners move from (±1)³ to
/// (±5/9)³ (Catmull & Clark's vertex rule by hand: (Q + 2R)/3 with Q = (1/3)³ and R = (2/3)³); its
/// `refineLevel` sets the level unless `--subdivision-level` does; level 0 is the cage; and with every edge
/// infinitely sharp (`creaseSharpnesses` 10) the surface stays on the cube. Cages used to render faceted, and
/// always.
#[test]
fn catmull_clark_meshes_are_subdivided_to_their_level() {
    let cube = |extra: &str| {
        format!(
            "#usda 1.0\n(\n    upAxis = \"Y\"\n    metersPerUnit = 1\n)\n\ndef Mesh \"Cube\"\n{{\n\
             point3f[] points = [(-1, -1, -1), (1, -1, -1), (-1, 1, -1), (1, 1, -1), (-1, -1, 1), (1, -1, 1), \
             (-1, 1, 1), (1, 1, 1)]\n\
             int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n\
             int[] faceVertexIndices = [0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5]\n\
             {extra}\n}}\n"
        )
    };
    let load = |tag: &str, extra: &str, level: Option<u32>| {
        let path = temp_file(tag, "usda", cube(extra).as_bytes());
        let options = nimbus::scene::LoadOptions {
            subdivision_level: level,
            ..Default::default()
        };
        let b = nimbus::scene::load_builder(&path, &options).unwrap_or_else(|e| panic!("{e}"));
        let points: Vec<Vec3> = b
            .meshes()
            .iter()
            .flat_map(|m| m.positions.clone())
            .collect();
        let triangles: usize = b.meshes().iter().map(|m| m.indices.len()).sum();
        (points, triangles)
    };
    let has = |points: &[Vec3], p: Vec3| points.iter().any(|q| q.distance(p) < 1e-5);
    let corner = Vec3::splat(1.0);
    let (points, triangles) = load("cc_level1", "int refineLevel = 1", None);
    assert_eq!(triangles, 48, "24 quads");
    assert!(has(&points, corner * (5.0 / 9.0)) && !has(&points, corner));
    assert!(points.iter().all(|p| p.abs().max_element() <= 1.0));
    let (_, triangles) = load("cc_default", "", None);
    assert_eq!(triangles, 192, "the default level 2: 96 quads");
    let (points, triangles) = load("cc_cage", "int refineLevel = 3", Some(0));
    assert_eq!(triangles, 12, "--subdivision-level 0 is the cage");
    assert!(has(&points, corner));
    let creases = "int[] creaseIndices = [0, 1, 3, 2, 0, 4, 5, 7, 6, 4, 0, 4, 1, 5, 2, 6, 3, 7]\n\
                   int[] creaseLengths = [5, 5, 2, 2, 2, 2]\n\
                   float[] creaseSharpnesses = [10, 10, 10, 10, 10, 10]";
    let (points, _) = load("cc_sharp", creases, Some(2));
    assert!(has(&points, corner));
    assert!(
        points
            .iter()
            .all(|p| (p.abs().max_element() - 1.0).abs() < 1e-5),
        "every point stays on the cube"
    );
    let (_, triangles) = load(
        "cc_none",
        "uniform token subdivisionScheme = \"none\"",
        Some(2),
    );
    assert_eq!(triangles, 12);
}

/// Texture coordinates of a subdivision surface follow `faceVaryingLinearInterpolation`. On an open 2×1 grid whose
/// `st` is each point's (x, y) with no seam, USD's default `cornersPlus1` subdivides them exactly as the points
/// are (the boundary's corners pinned, its edges sharp, like `edgeAndCorner`'s points), so every corner's UV is
/// its position's (x, y); `all` interpolates them linearly within each cage face, which the unevenly spaced
/// grid's smoothed points leave. They used to be linear always. `creaseMethod = "chaikin"` is read with no
/// warning, `interpolateBoundary = "none"` with one naming it.
#[test]
fn face_varying_interpolation_and_crease_method_are_read() {
    let grid = |extra: &str| {
        format!(
            "#usda 1.0\n(\n    upAxis = \"Y\"\n    metersPerUnit = 1\n)\n\ndef Mesh \"Grid\"\n{{\n\
             point3f[] points = [(0, 0, 0), (1, 0, 0), (3, 0, 0), (0, 1, 0), (1, 1, 0), (3, 1, 0)]\n\
             int[] faceVertexCounts = [4, 4]\n\
             int[] faceVertexIndices = [0, 1, 4, 3, 1, 2, 5, 4]\n\
             texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1), (1, 0), (3, 0), (3, 1), (1, 1)] (\n\
                 interpolation = \"faceVarying\"\n)\n\
             int refineLevel = 2\n{extra}\n}}\n"
        )
    };
    let load = |tag: &str, extra: &str| {
        let path = temp_file(tag, "usda", grid(extra).as_bytes());
        let b = nimbus::scene::load_builder(&path, &Default::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let off_by: f32 = b
            .meshes()
            .iter()
            .flat_map(|m| {
                let uvs = m.uvs.clone().expect("the grid has UVs");
                m.positions
                    .iter()
                    .zip(uvs)
                    // Nimbus keeps glTF's texture space, v down: USD's st (s, t) is (s, 1 − t).
                    .map(|(p, uv)| p.truncate().distance(Vec2::new(uv.x, 1.0 - uv.y)))
                    .collect::<Vec<_>>()
            })
            .fold(0.0, f32::max);
        (off_by, b.warnings().to_vec())
    };
    let (off_by, warnings) = load("fv_default", "");
    assert!(off_by < 1e-5, "UVs follow the points: {off_by}");
    assert!(warnings.is_empty(), "{warnings:?}");
    let (off_by, _) = load(
        "fv_all",
        "uniform token faceVaryingLinearInterpolation = \"all\"",
    );
    assert!(off_by > 0.02, "linear UVs stay behind the points: {off_by}");
    let (off_by, warnings) = load("fv_chaikin", "uniform token creaseMethod = \"chaikin\"");
    assert!(
        off_by < 1e-5 && warnings.is_empty(),
        "{off_by} {warnings:?}"
    );
    let (_, warnings) = load("fv_none", "uniform token interpolateBoundary = \"none\"");
    assert!(
        warnings.len() == 1 && warnings[0].contains("interpolateBoundary 'none'"),
        "{warnings:?}"
    );
}

/// MaterialX `standard_surface` materials (`tests/usd/materialx.usda`; Pixar's USD 26.11 resolves each
/// material's `mtlx` surface to its shader) are read as UsdPreviewSurface ones: constants map by hand to base
/// colour 0.5 × (0.2, 0.4, 0.6), metallic 1, roughness 0.3, ior 1.4 and emission 2 × (1, 0.5, 0); an image node on
/// `base_color` is its texture (times the default base weight 0.8); a node graph (a multiply) is named in a
/// warning, its input keeping its value times 0.8, as is a `coat` that is not read.
/// They used to fall back to grey.
#[test]
fn materialx_standard_surfaces_are_read() {
    let b = read("materialx.usda");
    let material = |mesh: &str| {
        let m = b.meshes().iter().find(|m| m.name.ends_with(mesh)).unwrap();
        &b.materials()[m.material as usize]
    };
    let constants = material("A");
    assert!(
        constants
            .base_color
            .truncate()
            .distance(Vec3::new(0.1, 0.2, 0.3))
            < 1e-6
    );
    assert_eq!(
        (constants.metallic, constants.roughness, constants.ior),
        (1.0, 0.3, 1.4)
    );
    assert!(constants.emission.distance(Vec3::new(2.0, 1.0, 0.0)) < 1e-6);
    let textured = material("B");
    assert!(textured.base_color_texture.is_some());
    // The default base weight 0.8 scales the texture.
    assert!(textured.base_color.truncate().distance(Vec3::splat(0.8)) < 1e-6);
    let graph = material("C");
    assert!(
        graph
            .base_color
            .truncate()
            .distance(Vec3::new(0.08, 0.16, 0.24))
            < 1e-6
    );
    let warned = |what: &str| b.warnings().iter().any(|w| w.contains(what));
    assert!(
        warned("/Looks/Graph/Multiply") && warned("ND_multiply_color3") && warned("inputs:coat"),
        "{:?}",
        b.warnings()
    );
}

/// `nimbus:` attributes that no table declares are warnings naming the closest known attribute, and errors
/// under `--strict`; the Volume's own keys count only on a Volume (issue 35: they were silently ignored).
#[test]
fn unknown_nimbus_attributes_are_warned_or_refused_when_strict() {
    let text = std::fs::read_to_string(stage("volume.usda")).unwrap();
    let text = text
        .replace("nimbus:density_scale", "nimbus:densty_scale")
        .replace(
            "def Xform \"World\"\n{",
            "def Xform \"World\"\n{\n    custom bool nimbus:holdot = true\n    custom float nimbus:anisotropy = 0.5",
        );
    let dir = std::env::temp_dir().join(format!("nimbus-usd-keys-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("misspelt.usda");
    std::fs::write(&path, text).unwrap();
    let (builder, volumes) = usd::read(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(volumes.len(), 1);
    let warnings = builder.warnings().join("\n");
    for expected in [
        "/World: unknown key 'nimbus:holdot' ignored (did you mean 'nimbus:holdout'?)",
        "/World: unknown key 'nimbus:anisotropy' ignored",
        "/World/Cloud: unknown key 'nimbus:densty_scale' ignored (did you mean 'nimbus:density_scale'?)",
    ] {
        assert!(warnings.contains(expected), "missing {expected:?} in:\n{warnings}");
    }
    assert!(!warnings.contains("'nimbus:albedo'"), "{warnings}");
    let strict = nimbus::scene::LoadOptions {
        strict: true,
        ..Default::default()
    };
    let Err(err) = nimbus::scene::load_builder(&path, &strict) else {
        panic!("--strict loaded a stage with unknown nimbus: attributes")
    };
    assert!(matches!(err.kind, SceneErrorKind::UnknownKey(_)), "{err}");
}

/// A sublayer that does not exist is skipped with a warning and the rest of the stage is read, as Pixar's USD
/// does ("Could not load sublayer ... skipping"); before, it refused the whole stage (issue 37).
#[test]
fn a_missing_sublayer_is_a_warning_and_the_rest_of_the_stage_loads() {
    let dir = std::env::temp_dir().join(format!("nimbus-usd-sublayer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let triangle = |name: &str, z: f32| {
        format!(
            "def Mesh \"{name}\"\n{{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    \
             point3f[] points = [(0, 0, {z}), (1, 0, {z}), (0, 1, {z})]\n    uniform token subdivisionScheme = \"none\"\n}}\n"
        )
    };
    std::fs::write(
        dir.join("root.usda"),
        format!(
            "#usda 1.0\n(\n    subLayers = [@missing.usda@, @present.usda@]\n)\n{}",
            triangle("Root", 0.0)
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("present.usda"),
        format!("#usda 1.0\n{}", triangle("FromSublayer", 1.0)),
    )
    .unwrap();
    let (builder, _) = usd::read(&dir.join("root.usda")).unwrap_or_else(|e| panic!("{e}"));
    let mut names: Vec<&str> = builder.meshes().iter().map(|m| m.name.as_str()).collect();
    names.sort_unstable();
    assert_eq!(names, ["/FromSublayer", "/Root"]);
    let warnings = builder.warnings().join("\n");
    assert!(
        warnings.contains("missing.usda") && warnings.contains("skipped"),
        "{warnings}"
    );
}

/// `subdivisionScheme = "loop"` subdivides a triangle mesh by Loop's rules (before, its cage was rendered with a
/// warning): one level on the octahedron puts its vertices at 132/256 of themselves and its edge points at 3/8 of
/// their ends' sum (Loop 1987). A loop mesh of quads keeps its cage, with a warning.
#[test]
fn loop_subdivision_meshes_are_subdivided() {
    let dir = std::env::temp_dir().join(format!("nimbus-usd-loop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stage = r#"#usda 1.0
def Mesh "Octahedron"
{
    int[] faceVertexCounts = [3, 3, 3, 3, 3, 3, 3, 3]
    int[] faceVertexIndices = [0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5]
    point3f[] points = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    uniform token subdivisionScheme = "loop"
    int refineLevel = 1
}
def Mesh "Quad"
{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(0, 0, 3), (1, 0, 3), (1, 1, 3), (0, 1, 3)]
    uniform token subdivisionScheme = "loop"
}
"#;
    let path = dir.join("loop.usda");
    std::fs::write(&path, stage).unwrap();
    let (builder, _) = usd::read(&path).unwrap_or_else(|e| panic!("{e}"));
    let octahedron = builder
        .meshes()
        .iter()
        .find(|m| m.name == "/Octahedron")
        .expect("octahedron");
    assert_eq!(octahedron.indices.len(), 32);
    let has = |q: Vec3| octahedron.positions.iter().any(|p| p.distance(q) < 1e-5);
    assert!(has(Vec3::new(132.0 / 256.0, 0.0, 0.0)), "a vertex point");
    assert!(has(Vec3::new(0.375, 0.375, 0.0)), "an edge point");
    let quad = builder
        .meshes()
        .iter()
        .find(|m| m.name == "/Quad")
        .expect("quad");
    assert_eq!(quad.indices.len(), 2, "the quad's cage, as two triangles");
    let warnings = builder.warnings().join("\n");
    assert!(
        warnings.contains("/Quad") && warnings.contains("needs triangles"),
        "{warnings}"
    );
}
