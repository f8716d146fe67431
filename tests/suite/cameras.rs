//! Cameras from scene files and in renders: every glTF and USD camera kept with its names, `nimbus_camera`
//! lenses (the node's over the camera object's, `f_stop` through Blender's focal length, unknown keys warned,
//! bad values refused with the file named), USD `fStop` / `focusDistance` / orthographic apertures, choosing a
//! camera by name, orthographic film extents in a render, and thin-lens renders that are the same for any
//! thread count and any split into sample ranges.

use nimbus::material::Material;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::{
    CancelToken, PixelWindow, RenderImage, RenderRegion, RenderSettings, Renderer,
};
use nimbus::scene::{
    blender_focal_length, load_builder, Camera, LoadOptions, Projection, SceneBuilder,
    SceneErrorKind, ThinLens,
};
use std::path::{Path, PathBuf};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-cameras-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A glTF with three camera nodes and no meshes: `wide` (perspective, yfov 0.6, aspect 1.5, a lens on the node
/// and another on the camera object), an unnamed node with the orthographic camera `top` (xmag 2, ymag 1,
/// lens on the camera object), and an unnamed node with an unnamed perspective camera. `node_lens` replaces
/// the first node's `nimbus_camera`.
fn cameras_gltf(node_lens: &str) -> String {
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1,2]}}],
        "nodes":[{{"name":"wide","camera":0,"translation":[0,1,5],"extras":{{"nimbus_camera":{node_lens}}}}},
                 {{"camera":1,"translation":[0,10,0],"rotation":[-0.7071068,0,0,0.7071068]}},
                 {{"camera":2,"translation":[3,0,0]}}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.6,"aspectRatio":1.5,"znear":0.1}},
                     "extras":{{"nimbus_camera":{{"aperture_radius":0.5,"focus_distance":9}}}}}},
                   {{"name":"top","type":"orthographic","orthographic":{{"xmag":2,"ymag":1,"znear":0.1,"zfar":100}},
                     "extras":{{"nimbus_camera":{{"aperture_radius":0.01,"focus_distance":4}}}}}},
                   {{"type":"perspective","perspective":{{"yfov":0.8,"znear":0.1}}}}]}}"#
    )
}

#[test]
fn every_gltf_camera_is_kept_with_its_name_and_lens() {
    let dir = temp_dir("gltf");
    let path = write(
        &dir,
        "cams.gltf",
        &cameras_gltf(r#"{"f_stop":2.8,"focus_distance":3}"#),
    );
    let mut b = load_builder(&path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert!(b.warnings().is_empty(), "{:?}", b.warnings());
    let names: Vec<&str> = b.cameras().iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["wide", "top", "camera 2"]);
    // The node's lens wins over the camera object's; f_stop through a 36 mm sensor on the wider side.
    let wide = b.cameras()[0].camera.clone();
    let focal = 0.018 / (1.5 * 0.3f32.tan());
    assert!((blender_focal_length(0.6, Some(1.5)) - focal).abs() < 1e-7);
    let lens = wide.lens.unwrap();
    assert!(
        (lens.aperture_radius - focal / 5.6).abs() < 1e-7,
        "{lens:?}"
    );
    assert_eq!(lens.focus_distance, 3.0);
    assert_eq!(wide.projection, Projection::Perspective);
    // The camera object's lens when the node has none; xmag / ymag is the aspect ratio.
    let top = b.cameras()[1].camera.clone();
    assert_eq!(
        top.projection,
        Projection::Orthographic { half_height: 1.0 }
    );
    assert_eq!(top.aspect_ratio, Some(2.0));
    assert_eq!(
        top.lens,
        Some(ThinLens {
            aperture_radius: 0.01,
            focus_distance: 4.0
        })
    );
    assert_eq!(b.cameras()[2].camera.lens, None);
    // The first camera renders unless another is chosen.
    assert_eq!(b.camera(), Some(&wide));
    b.select_camera("top").unwrap();
    assert_eq!(b.camera().unwrap().projection, top.projection);
    let scene = b.build().unwrap();
    let ray = scene
        .camera()
        .generate_ray(nimbus::math::Vec2::new(0.0, 0.0), 2.0);
    // Looking straight down from y = 10 (the node turned -90° about x): the top-left corner of the 4 x 2 film.
    assert!(ray.dir.distance(-Vec3::Y) < 1e-5, "{ray:?}");
    assert!(
        ray.origin.distance(Vec3::new(-2.0, 10.0, -1.0)) < 1e-5,
        "{ray:?}"
    );
}

#[test]
fn an_unknown_camera_name_lists_the_cameras() {
    let dir = temp_dir("select");
    let path = write(&dir, "cams.gltf", &cameras_gltf("{}"));
    let mut b = load_builder(&path, &LoadOptions::default()).unwrap();
    let e = b.select_camera("Wide").unwrap_err();
    assert_eq!(e.available, ["wide", "top", "camera 2"]);
    assert_eq!(
        e.to_string(),
        "no camera named 'Wide'; the scene's cameras: wide, top, camera 2"
    );
    // The first camera is still the one.
    assert_eq!(b.camera().unwrap().yfov, 0.6);
    let mut empty = SceneBuilder::new();
    assert!(empty
        .select_camera("x")
        .unwrap_err()
        .to_string()
        .contains("the scene has no cameras"));
}

#[test]
fn unknown_nimbus_camera_keys_are_warnings() {
    let dir = temp_dir("unknown");
    let path = write(
        &dir,
        "cams.gltf",
        &cameras_gltf(r#"{"aperture_radius":0.1,"focus_distance":2,"fstop":2}"#),
    );
    let b = load_builder(&path, &LoadOptions::default()).unwrap();
    assert_eq!(b.warnings().len(), 1, "{:?}", b.warnings());
    let w = &b.warnings()[0];
    assert!(
        w.contains(
            "camera 'wide': nimbus_camera: unknown key 'fstop' ignored (did you mean 'f_stop'?)"
        ),
        "{w}"
    );
    assert_eq!(b.cameras()[0].camera.lens.unwrap().aperture_radius, 0.1);
}

#[test]
fn bad_lenses_are_errors_naming_the_file_and_the_key() {
    let dir = temp_dir("bad");
    for (i, (lens, expect)) in [
        (
            r#"{"f_stop":0,"focus_distance":1}"#,
            "'f_stop' 0 must be finite and > 0",
        ),
        (
            r#"{"f_stop":-2,"focus_distance":1}"#,
            "'f_stop' must be a non-negative number",
        ),
        (
            r#"{"f_stop":2,"aperture_radius":0.1,"focus_distance":1}"#,
            "give 'f_stop' or 'aperture_radius', not both",
        ),
        (
            r#"{"aperture_radius":-0.1,"focus_distance":1}"#,
            "'aperture_radius' must be a non-negative number",
        ),
        (r#"{"aperture_radius":0.1}"#, "'focus_distance' is required"),
        (
            r#"{"aperture_radius":0.1,"focus_distance":0}"#,
            "'focus_distance' 0 must be finite and > 0",
        ),
        (
            r#"{"aperture_radius":0.1,"focus_distance":1e300}"#,
            "'focus_distance' 1e300 must fit single precision",
        ),
        (r#""wide""#, "'nimbus_camera' must be an object"),
    ]
    .into_iter()
    .enumerate()
    {
        let path = write(&dir, &format!("bad{i}.gltf"), &cameras_gltf(lens));
        let e = match load_builder(&path, &LoadOptions::default()) {
            Ok(_) => panic!("{lens}: loaded"),
            Err(e) => e,
        };
        assert!(
            matches!(e.kind, SceneErrorKind::Camera { .. }),
            "{lens}: {e}"
        );
        let text = e.to_string();
        assert!(
            text.starts_with(&path.display().to_string())
                && text.contains("camera 'wide': nimbus_camera: ")
                && text.contains(expect),
            "{lens}: {text}"
        );
    }
    // f_stop on an orthographic camera (no focal length).
    let text = cameras_gltf("{}").replace(
        r#""aperture_radius":0.01,"focus_distance":4"#,
        r#""f_stop":4,"focus_distance":4"#,
    );
    let path = write(&dir, "ortho.gltf", &text);
    let e = load_builder(&path, &LoadOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("camera 'top': nimbus_camera: 'f_stop' needs a perspective camera"),
        "{e}"
    );
}

/// A stage in centimetres with a perspective camera with depth of field, an orthographic one, and one
/// without `fStop`.
const STAGE: &str = r#"#usda 1.0
(
    metersPerUnit = 0.01
    upAxis = "Y"
)

def Xform "World"
{
    def Camera "Persp"
    {
        float focalLength = 50
        float horizontalAperture = 36
        float verticalAperture = 24
        float fStop = 2
        float focusDistance = 300
        double3 xformOp:translate = (0, 100, 500)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }

    def Camera "Top"
    {
        token projection = "orthographic"
        float horizontalAperture = 200
        float verticalAperture = 100
    }

    def Camera "Plain"
    {
        float focusDistance = 300
    }
}
"#;

#[test]
fn usd_cameras_read_fstop_focus_and_orthographic_apertures() {
    let dir = temp_dir("usd");
    let path = write(&dir, "cams.usda", STAGE);
    let mut b = load_builder(&path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert!(b.warnings().is_empty(), "{:?}", b.warnings());
    let names: Vec<(&str, Option<&str>)> = b
        .cameras()
        .iter()
        .map(|c| (c.name.as_str(), c.path.as_deref()))
        .collect();
    assert_eq!(
        names,
        [
            ("Persp", Some("/World/Persp")),
            ("Top", Some("/World/Top")),
            ("Plain", Some("/World/Plain"))
        ]
    );
    let persp = &b.cameras()[0].camera;
    // focalLength 50 tenths of a centimetre = 5 cm; radius 5 / (2 · 2) cm = 1.25 cm; focus 3 m.
    let lens = persp.lens.unwrap();
    assert!((lens.aperture_radius - 0.0125).abs() < 1e-7, "{lens:?}");
    assert!((lens.focus_distance - 3.0).abs() < 1e-6, "{lens:?}");
    assert!((persp.yfov - 2.0 * (12.0f32 / 50.0).atan()).abs() < 1e-6);
    assert!(persp.position().distance(Vec3::new(0.0, 1.0, 5.0)) < 1e-5);
    // 200 by 100 tenths of a centimetre: a 0.2 m by 0.1 m film.
    let top = &b.cameras()[1].camera;
    let Projection::Orthographic { half_height } = top.projection else {
        panic!("{:?}", top.projection)
    };
    assert!((half_height - 0.05).abs() < 1e-7, "{half_height}");
    assert_eq!(top.aspect_ratio, Some(2.0));
    assert_eq!(top.lens, None);
    assert_eq!(b.cameras()[2].camera.lens, None, "fStop 0: no lens");
    b.select_camera("/World/Top").unwrap();
    assert!(matches!(
        b.camera().unwrap().projection,
        Projection::Orthographic { .. }
    ));
    b.select_camera("Plain").unwrap();
    assert_eq!(b.camera().unwrap().projection, Projection::Perspective);

    let bad = STAGE.replace("float fStop = 2", "float fStop = -1");
    let path = write(&dir, "bad.usda", &bad);
    let e = load_builder(&path, &LoadOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with(&path.display().to_string()) && e.contains("/World/Persp.fStop"),
        "{e}"
    );
    let bad = STAGE.replace(
        "token projection = \"orthographic\"",
        "token projection = \"orthographic\"\n        float3 xformOp:scale = (0, 0, 0)\n        uniform token[] xformOpOrder = [\"xformOp:scale\"]",
    );
    let path = write(&dir, "flat.usda", &bad);
    let e = load_builder(&path, &LoadOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.starts_with(&path.display().to_string())
            && e.contains("/World/Top: an orthographic film 0 m high"),
        "{e}"
    );
    let bad = STAGE.replace("float focusDistance = 300\n        double3", "double3");
    let path = write(&dir, "nofocus.usda", &bad);
    let e = load_builder(&path, &LoadOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains("camera /World/Persp: 'focusDistance' 0 must be finite and > 0"),
        "{e}"
    );
}

/// A 1 x 1 quad at the origin facing +z, lit by a white environment, nothing else.
fn quad_scene(camera: Camera) -> nimbus::Scene {
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambertian("white", Rgb::splat(0.8)));
    b.add_triangle_mesh(
        vec![
            Vec3::new(-0.5, -0.5, 0.0),
            Vec3::new(0.5, -0.5, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
            Vec3::new(-0.5, 0.5, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
        m,
    )
    .unwrap();
    b.set_environment(nimbus::light::EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(camera);
    b.build().unwrap()
}

fn render(scene: &nimbus::Scene, size: usize, spp: u32, threads: usize) -> RenderImage {
    Renderer::new(RenderSettings {
        width: size,
        height: size,
        spp,
        seed: 7,
        threads,
        max_depth: 4,
        ..RenderSettings::default()
    })
    .render(scene, &mut |_| true)
    .unwrap()
    .0
}

/// An orthographic film 2 units tall sees the unit quad as the middle quarter of the image at any distance:
/// its pixels' edges fall on the quad's, so the coverage is exactly 1/4 (a perspective camera's would
/// depend on the distance).
#[test]
fn an_orthographic_film_covers_its_extent_at_any_distance() {
    for distance in [2.0, 50.0] {
        let mut camera = Camera::look_at(Vec3::new(0.0, 0.0, distance), Vec3::ZERO, 0.5);
        camera.projection = Projection::Orthographic { half_height: 1.0 };
        let img = render(&quad_scene(camera), 16, 4, 2);
        let coverage: f32 = img.alpha.iter().sum::<f32>() / img.alpha.len() as f32;
        assert_eq!(coverage, 0.25, "distance {distance}");
        for (i, a) in img.alpha.iter().enumerate() {
            let (x, y) = (i % 16, i / 16);
            let inside = (4..12).contains(&x) && (4..12).contains(&y);
            assert_eq!(*a, if inside { 1.0 } else { 0.0 }, "pixel {x},{y}");
        }
    }
}

/// A thin-lens render is the same for one thread and two, and its sample ranges merge into the whole
/// render bit for bit; an out-of-focus quad edge is blurred over several pixels where the pinhole's is sharp.
#[test]
fn thin_lens_renders_are_deterministic_and_blurred() {
    let mut camera = Camera::look_at(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO, 0.9);
    let pinhole = quad_scene(camera.clone());
    camera.lens = Some(ThinLens {
        aperture_radius: 0.2,
        focus_distance: 6.0,
    });
    let scene = quad_scene(camera);
    let size = 32;
    let one = render(&scene, size, 16, 1);
    let two = render(&scene, size, 16, 2);
    assert_eq!(one.beauty, two.beauty);
    assert_eq!(one.alpha, two.alpha);
    let renderer = Renderer::new(RenderSettings {
        width: size,
        height: size,
        spp: 16,
        seed: 7,
        threads: 2,
        max_depth: 4,
        ..RenderSettings::default()
    });
    let part = |samples| {
        renderer
            .render_region(
                &scene,
                &RenderRegion {
                    window: PixelWindow::full(size, size),
                    samples,
                },
                &mut |_| true,
                &CancelToken::new(),
            )
            .unwrap()
            .0
    };
    let mut merged = part(0..5);
    merged.merge(&part(5..16)).unwrap();
    assert_eq!(merged.image().beauty, one.beauty);
    // The quad spans pixels 8..24 at this distance (tan(0.45) · 2 = 0.966 half height): its edge at
    // depth 2 with the focus at 6 spreads over a circle of confusion 2 r |1/2 − 1/6| / (2 tan(0.45) / 32)
    // ≈ 4.4 pixels wide. The pinhole's alpha is 0 or 1 away from the edge pixels; the lens's has a ramp.
    let partial = |img: &RenderImage| {
        img.alpha
            .iter()
            .filter(|a| **a > 0.02 && **a < 0.98)
            .count()
    };
    let sharp = render(&pinhole, size, 16, 2);
    assert!(partial(&sharp) <= 4 * 17, "{}", partial(&sharp));
    assert!(partial(&one) >= 4 * 16 * 2, "{}", partial(&one));
    assert!(one.beauty.iter().all(|c| c.is_finite()));
}

/// Emitter-edge supersampling marks the pixels an outline's pinhole projection crosses: with a thin lens the
/// outline is defocused beyond them, so `auto` leaves it off (and on for the same scene through a pinhole).
#[test]
fn emitter_edges_stay_off_for_a_thin_lens() {
    let mut camera = Camera::look_at(Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO, 0.9);
    let scene = |camera: Camera| {
        let mut b = SceneBuilder::new();
        let mut lamp = Material::lambertian("lamp", Rgb::ZERO);
        lamp.emission = Rgb::ONE;
        let m = b.add_material(lamp);
        b.add_triangle_mesh(
            vec![
                Vec3::new(-0.5, -0.5, 0.0),
                Vec3::new(0.5, -0.5, 0.0),
                Vec3::new(0.0, 0.5, 0.0),
            ],
            vec![[0, 1, 2]],
            m,
        )
        .unwrap();
        b.set_camera(camera);
        b.build().unwrap()
    };
    let auto = nimbus::render::EmitterEdgeSampling::Auto;
    assert!(matches!(
        auto.decide(&scene(camera.clone()), 512, 512),
        nimbus::render::EdgeDecision::On(_)
    ));
    camera.lens = Some(ThinLens {
        aperture_radius: 0.1,
        focus_distance: 5.0,
    });
    match auto.decide(&scene(camera), 512, 512) {
        nimbus::render::EdgeDecision::Off(why) => assert!(why.contains("thin lens"), "{why}"),
        nimbus::render::EdgeDecision::On(_) => panic!("on with a thin lens"),
    }
}

/// Renders samples `samples` (of 2) of `scene_and_flags` (the scene, then any flags) at 8² in `dir`, as the
/// part `out`.
fn render_part(dir: &Path, scene_and_flags: &[&str], samples: &str, out: &str) {
    let mut args = vec!["render"];
    args.extend_from_slice(scene_and_flags);
    args.extend([
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "2",
        "--samples",
        samples,
        "-o",
        out,
    ]);
    let (code, _, stderr) = nimbus(&args, dir);
    assert_eq!(code, Some(0), "{stderr}");
}

/// In `dir`, the parts `a.exr` and `b.exr` merge, and `a.exr` and `c.exr` are refused for their scene hash.
fn assert_only_a_and_b_merge(dir: &Path) {
    let (code, _, stderr) = nimbus(&["merge", "a.exr", "b.exr", "-o", "ab.exr"], dir);
    assert_eq!(code, Some(0), "{stderr}");
    let (code, _, stderr) = nimbus(&["merge", "a.exr", "c.exr", "-o", "ac.exr"], dir);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("scene hash"), "{stderr}");
}

/// Runs `nimbus` with `args` in `dir`; returns the exit code, stdout and stderr.
fn nimbus(args: &[&str], dir: &Path) -> (Option<i32>, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_cli_lists_and_chooses_cameras() {
    let dir = temp_dir("cli");
    write(
        &dir,
        "cams.gltf",
        &cameras_gltf(r#"{"aperture_radius":0.05,"focus_distance":3}"#),
    );
    let (code, stdout, stderr) = nimbus(&["render", "cams.gltf", "--list-cameras"], &dir);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        stdout,
        "wide\tperspective\tyfov 34.38°\taspect 1.5000\taperture radius 0.05\tfocus distance 3\n\
         top\torthographic\theight 2\taspect 2.0000\taperture radius 0.01\tfocus distance 4\n\
         camera 2\tperspective\tyfov 45.84°\tpinhole\n"
    );
    assert!(!dir.join("render.exr").exists(), "nothing rendered");
    let (code, _, stderr) = nimbus(&["render", "cams.gltf", "--camera", "nope"], &dir);
    assert_eq!(code, Some(1));
    assert_eq!(
        stderr.trim_end(),
        "nimbus: error: cams.gltf: --camera: no camera named 'nope'; the scene's cameras: wide, top, camera 2"
    );
    // Parts from different cameras (or apertures) do not merge; parts from the same one do.
    render_part(&dir, &["cams.gltf", "--camera", "top"], "0..1", "a.exr");
    render_part(&dir, &["cams.gltf", "--camera", "top"], "1..2", "b.exr");
    render_part(&dir, &["cams.gltf", "--camera", "wide"], "1..2", "c.exr");
    assert_only_a_and_b_merge(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The part hash reads the scene file's bytes, not the layers it refers to: a lens changed in a USD sublayer
/// must still keep parts apart, so the chosen camera's lens is hashed too.
#[test]
fn parts_with_different_lenses_do_not_merge() {
    let dir = temp_dir("lens-hash");
    write(
        &dir,
        "shot.usda",
        "#usda 1.0\n(\n    subLayers = [@cam.usda@]\n)\n",
    );
    let camera = |f_stop: f32| {
        format!(
            "#usda 1.0\ndef Camera \"Cam\"\n{{\n    float fStop = {f_stop}\n    float focusDistance = 5\n}}\n"
        )
    };
    write(&dir, "cam.usda", &camera(2.0));
    render_part(&dir, &["shot.usda"], "0..1", "a.exr");
    render_part(&dir, &["shot.usda"], "1..2", "b.exr");
    write(&dir, "cam.usda", &camera(4.0));
    render_part(&dir, &["shot.usda"], "1..2", "c.exr");
    assert_only_a_and_b_merge(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
}
