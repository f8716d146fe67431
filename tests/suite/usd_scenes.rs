//! USD features of issue 13 on small stages written by the tests (time samples, gprims, instancing, GeomSubset
//! bindings, texture scale/bias, missing textures) and on the real files under `realworld/usd` of the shared
//! folder (McUsd's camera, BoxAnimated, RoughnessTest's packaged textures, NormalsTextureBiasAndScale).

use crate::common;

use nimbus::geometry::Mesh;
use nimbus::limits::Limits;
use nimbus::math::{Mat4, Quat, Vec2, Vec3};
use nimbus::scene::{usd, SceneBuilder};
use std::path::{Path, PathBuf};

/// A fresh folder for one test's files.
fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_usd_scenes_{}_{tag}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes a `.usda` stage and reads it.
fn read_text(tag: &str, text: &str) -> SceneBuilder {
    let path = temp_dir(tag).join("stage.usda");
    std::fs::write(&path, text).unwrap();
    let (b, volumes) = usd::read(&path).unwrap_or_else(|e| panic!("{tag}: {e}"));
    assert!(volumes.is_empty());
    b
}

fn mesh<'a>(b: &'a SceneBuilder, name: &str) -> &'a Mesh {
    b.meshes()
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| {
            let names: Vec<&str> = b.meshes().iter().map(|m| m.name.as_str()).collect();
            panic!("no mesh {name} in {names:?}")
        })
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    a.distance(b) <= tol
}

/// The real-world USD folder, or `None` (skip) when the shared folder is absent.
fn realworld(sub: &str) -> Option<PathBuf> {
    let dir = common::shared_dir()?.join("realworld/usd").join(sub);
    assert!(dir.is_dir(), "{} is missing", dir.display());
    Some(dir)
}

fn read_real(path: &Path) -> SceneBuilder {
    usd::read(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .0
}

const TRIANGLE: &str = "point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        uniform token subdivisionScheme = \"none\"";

#[test]
fn time_sampled_ops_are_read_at_the_default_time_and_interpolated() {
    let stage = |meta: &str| {
        format!(
            "#usda 1.0\n({meta})\n\
             def Mesh \"M\" {{\n {TRIANGLE}\n\
               double3 xformOp:translate.timeSamples = {{ 5: (1, 0, 0), 15: (3, 0, 0) }}\n\
               quatf xformOp:orient.timeSamples = {{ 5: (1, 0, 0, 0), 15: (0.70710678, 0, 0.70710678, 0) }}\n\
               uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:orient\"]\n}}\n"
        )
    };
    // The corner (1, 0, 0) after a rotation of `deg` about +Y and the translation.
    let corner = |deg: f32, x: f32| {
        Mat4::from_translation(Vec3::new(x, 0.0, 0.0))
            * Mat4::from_quat(Quat::from_rotation_y(deg.to_radians()))
    };
    // No startTimeCode: the earliest sample.
    let b = read_text("samples_earliest", &stage("upAxis = \"Y\""));
    let p = mesh(&b, "/M").positions[1];
    assert!(
        close(p, corner(0.0, 1.0).transform_point3(Vec3::X), 1e-5),
        "{p}"
    );
    // startTimeCode 10: halfway, translation lerped and rotation slerped to 45°.
    let text = stage("startTimeCode = 10");
    let b = read_text("samples_start", &text);
    let p = mesh(&b, "/M").positions[1];
    assert!(
        close(p, corner(45.0, 2.0).transform_point3(Vec3::X), 1e-5),
        "{p}"
    );
    // An explicit time past the last sample holds the last value.
    let path = temp_dir("samples_at").join("stage.usda");
    std::fs::write(&path, &text).unwrap();
    let (b, _) = usd::read_at_time(&path, &Limits::default(), Some(40.0)).unwrap();
    let p = mesh(&b, "/M").positions[1];
    assert!(
        close(p, corner(90.0, 3.0).transform_point3(Vec3::X), 1e-5),
        "{p}"
    );
    // A shot frame is a time code at timeCodesPerSecond / framesPerSecond per frame (both default 24): frame
    // 10 reads time code 10 by default; at 12 time codes per second and 24 frames per second, frame 10 reads
    // time code 5, the first sample, and frame 30 time code 15, the last.
    for (meta, frame, deg, x) in [
        ("upAxis = \"Y\"", 10, 45.0, 2.0),
        (
            "timeCodesPerSecond = 12\n framesPerSecond = 24",
            10,
            0.0,
            1.0,
        ),
        (
            "timeCodesPerSecond = 12\n framesPerSecond = 24",
            30,
            90.0,
            3.0,
        ),
    ] {
        let path = temp_dir(&format!("samples_frame_{frame}_{}", meta.len())).join("stage.usda");
        std::fs::write(&path, stage(meta)).unwrap();
        let (b, _) = usd::read_at_frame(&path, &Limits::default(), Some(frame)).unwrap();
        let p = mesh(&b, "/M").positions[1];
        assert!(
            close(p, corner(deg, x).transform_point3(Vec3::X), 1e-5),
            "{meta}, frame {frame}: {p}"
        );
    }
}

#[test]
fn box_animated_loads_at_its_first_sample() {
    let Some(dir) = realworld("BoxAnimated") else {
        return;
    };
    let b = read_real(&dir.join("BoxAnimated.usdz"));
    assert_eq!(b.meshes().len(), 2, "the outer and the inner box");
    // glTF's BoxAnimated: at t = 0 the inner box sits inside the outer one (its translation sample is
    // (0, 2.5, 0) at 1.25 s and (0, 0, 0) before), so its bounds lie within the outer box's bounds.
    let bounds: Vec<_> = b.meshes().iter().map(|m| m.bounds()).collect();
    let (outer, inner) = if bounds[0].max.length() > bounds[1].max.length() {
        (bounds[0], bounds[1])
    } else {
        (bounds[1], bounds[0])
    };
    for axis in 0..3 {
        assert!(
            inner.min[axis] >= outer.min[axis] - 1e-4 && inner.max[axis] <= outer.max[axis] + 1e-4,
            "inner {inner:?} outside outer {outer:?}"
        );
    }
}

#[test]
fn gprims_are_tessellated_with_their_xforms_and_materials() {
    let b = read_text(
        "gprims",
        "#usda 1.0\n(upAxis = \"Y\")\n\
         def Cube \"C\" { double size = 3\n double3 xformOp:translate = (10, 0, 0)\n\
           uniform token[] xformOpOrder = [\"xformOp:translate\"]\n\
           color3f[] primvars:displayColor = [(1, 0, 0)] }\n\
         def Sphere \"S\" { double radius = 0.5\n rel material:binding = </Looks/Green>\n bool doubleSided = 1 }\n\
         def Cylinder \"Cy\" { double radius = 0.25\n double height = 4\n uniform token axis = \"X\" }\n\
         def Cone \"Co\" { uniform token axis = \"Y\" }\n\
         def Capsule \"Ca\" { double radius = 0.5\n double height = 1 }\n\
         def Plane \"P\" { double width = 4\n double length = 6\n uniform token axis = \"Y\" }\n\
         def Scope \"Looks\" { def Material \"Green\" {\n\
           token outputs:surface.connect = </Looks/Green/S.outputs:surface>\n\
           def Shader \"S\" { uniform token info:id = \"UsdPreviewSurface\"\n\
             color3f inputs:diffuseColor = (0, 1, 0)\n token outputs:surface } } }\n",
    );
    assert!(
        !b.warnings().iter().any(|w| w.contains("not supported")),
        "{:?}",
        b.warnings()
    );
    let cube = mesh(&b, "/C");
    let bb = cube.bounds();
    assert!(
        close(bb.min, Vec3::new(8.5, -1.5, -1.5), 1e-5)
            && close(bb.max, Vec3::new(11.5, 1.5, 1.5), 1e-5)
    );
    let red = &b.materials()[cube.material as usize];
    assert_eq!(red.base_color.truncate(), Vec3::X);
    assert!(!red.double_sided);
    let sphere = mesh(&b, "/S");
    let green = &b.materials()[sphere.material as usize];
    assert_eq!(green.base_color.truncate(), Vec3::Y);
    assert!(green.double_sided);
    for p in &sphere.positions {
        assert!((p.length() - 0.5).abs() < 1e-5);
    }
    // Normals outward, front faces counter-clockwise seen from outside.
    for t in 0..sphere.indices.len() {
        let [a, b2, c] = sphere.triangle(t);
        assert!((b2 - a).cross(c - a).dot(a + b2 + c) > 0.0);
    }
    let cyl = mesh(&b, "/Cy").bounds();
    assert!(close(cyl.max, Vec3::new(2.0, 0.25, 0.25), 1e-5), "{cyl:?}");
    let cone = mesh(&b, "/Co").bounds();
    assert!(close(cone.max, Vec3::new(1.0, 1.0, 1.0), 1e-5), "{cone:?}");
    assert!((cone.min.y + 1.0).abs() < 1e-5);
    let cap = mesh(&b, "/Ca").bounds();
    assert!(close(cap.max, Vec3::new(0.5, 0.5, 1.0), 1e-5), "{cap:?}");
    let plane = mesh(&b, "/P");
    let pb = plane.bounds();
    assert!(close(pb.max, Vec3::new(2.0, 0.0, 3.0), 1e-6), "{pb:?}");
    let [a, b2, c] = plane.triangle(0);
    assert!((b2 - a).cross(c - a).normalize().distance(Vec3::Y) < 1e-6);
    assert!(plane.uvs.is_some());
}

#[test]
fn point_instancer_places_its_prototypes() {
    let b = read_text(
        "instancer",
        "#usda 1.0\n(upAxis = \"Y\")\n\
         def PointInstancer \"I\" {\n\
           rel prototypes = [</I/Protos/Box>, </I/Protos/Ball>]\n\
           int[] protoIndices = [0, 1, 0, 1]\n\
           point3f[] positions = [(0, 0, 0), (5, 0, 0), (0, 5, 0), (9, 9, 9)]\n\
           quath[] orientations = [(1, 0, 0, 0), (1, 0, 0, 0), (0.70710678, 0, 0, 0.70710678), (1, 0, 0, 0)]\n\
           float3[] scales = [(1, 1, 1), (2, 2, 2), (1, 3, 1), (1, 1, 1)]\n\
           int64[] invisibleIds = [3]\n\
           def Scope \"Protos\" {\n\
             def Cube \"Box\" { double size = 1\n double3 xformOp:translate = (0, 1, 0)\n\
               uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n\
             def Sphere \"Ball\" { double radius = 0.5 }\n\
           }\n}\n",
    );
    // Four instances, one invisible, of two prototypes read once; the prototypes themselves are not rendered.
    assert!(b.meshes().is_empty());
    assert_eq!(b.prototypes().len(), 2);
    let placed = b.world_meshes();
    assert_eq!(
        placed.len(),
        3,
        "{:?}",
        placed.iter().map(|m| &m.name).collect::<Vec<_>>()
    );
    let mesh = |_: &SceneBuilder, name: &str| {
        placed
            .iter()
            .find(|m| m.name == name)
            .unwrap_or_else(|| panic!("no mesh {name}"))
            .clone()
    };
    let box0 = mesh(&b, "/I/Protos/Box[0]").bounds();
    assert!(
        close(box0.min, Vec3::new(-0.5, 0.5, -0.5), 1e-5),
        "{box0:?}"
    );
    let ball = mesh(&b, "/I/Protos/Ball[1]").bounds();
    assert!(
        close(ball.min, Vec3::new(4.0, -1.0, -1.0), 1e-4),
        "{ball:?}"
    );
    // Instance 2: the prototype's own translate (0, 1, 0), then scale (1, 3, 1), then 90° about +Z, then (0, 5, 0).
    let m = Mat4::from_translation(Vec3::new(0.0, 5.0, 0.0))
        * Mat4::from_quat(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2))
        * Mat4::from_scale(Vec3::new(1.0, 3.0, 1.0))
        * Mat4::from_translation(Vec3::Y);
    let box2 = mesh(&b, "/I/Protos/Box[2]");
    let want = m.transform_point3(Vec3::splat(0.5));
    assert!(
        box2.positions.iter().any(|p| close(*p, want, 1e-4)),
        "{want}"
    );
    let bb = box2.bounds();
    assert!(close(bb.min, Vec3::new(-4.5, 4.5, -0.5), 1e-4), "{bb:?}");
}

#[test]
fn native_instances_share_their_prototype_and_prototypes_are_not_drawn() {
    let b = read_text(
        "native",
        "#usda 1.0\n(upAxis = \"Y\")\n\
         class Xform \"Proto\" { def Mesh \"Tri\" {\n\
           point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n\
           uniform token subdivisionScheme = \"none\"\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2] } }\n\
         def Xform \"A\" ( instanceable = true\n references = </Proto> ) {\n\
           double3 xformOp:translate = (10, 0, 0)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n\
         def Xform \"B\" ( instanceable = true\n references = </Proto> ) {\n\
           double3 xformOp:translate = (0, 0, 7)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n",
    );
    // Both instances share one prototype mesh, read once; each is named by its own proxy path.
    assert_eq!((b.prototypes().len(), b.instances().len()), (1, 2));
    let placed = b.world_meshes();
    let mut names: Vec<&str> = placed.iter().map(|m| m.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["/A/Tri", "/B/Tri"]);
    let a = placed
        .iter()
        .find(|m| m.bounds().min.x > 9.0)
        .expect("instance A");
    assert!(close(a.bounds().max, Vec3::new(11.0, 1.0, 0.0), 1e-6));
    let b2 = placed
        .iter()
        .find(|m| m.bounds().min.z > 6.0)
        .expect("instance B");
    assert!(close(b2.bounds().min, Vec3::new(0.0, 0.0, 7.0), 1e-6));
}

#[test]
fn native_instances_with_a_light_inside_are_copied() {
    // A prototype holding a light besides its mesh cannot be shared (lights are world objects): both instances
    // are read as before, each with its own light and mesh copy.
    let b = read_text(
        "native_light",
        "#usda 1.0\n(upAxis = \"Y\")\n\
         class Xform \"Proto\" { def Mesh \"Tri\" {\n\
           point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n\
           uniform token subdivisionScheme = \"none\"\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2] }\n\
           def SphereLight \"Bulb\" { float inputs:intensity = 5\n bool treatAsPoint = true } }\n\
         def Xform \"A\" ( instanceable = true\n references = </Proto> ) {\n\
           double3 xformOp:translate = (10, 0, 0)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n\
         def Xform \"B\" ( instanceable = true\n references = </Proto> ) {\n\
           double3 xformOp:translate = (0, 0, 7)\n uniform token[] xformOpOrder = [\"xformOp:translate\"] }\n",
    );
    assert!(b.instances().is_empty() && b.prototypes().is_empty());
    let mut names: Vec<&str> = b.meshes().iter().map(|m| m.name.as_str()).collect();
    names.sort();
    assert_eq!(names, ["/A/Tri", "/B/Tri"]);
    assert_eq!(b.lights().len(), 2);
    assert!(b.meshes().iter().any(|m| m.bounds().min.x > 9.0));
}

#[test]
fn geom_subsets_bind_their_faces_materials() {
    let looks = |name: &str, rgb: &str| {
        format!(
            "def Material \"{name}\" {{ token outputs:surface.connect = </Looks/{name}/S.outputs:surface>\n\
             def Shader \"S\" {{ uniform token info:id = \"UsdPreviewSurface\"\n\
             color3f inputs:diffuseColor = {rgb}\n token outputs:surface }} }}\n"
        )
    };
    let b = read_text(
        "subsets",
        &format!(
            "#usda 1.0\n(upAxis = \"Y\")\n\
             def Mesh \"M\" {{\n\
               point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]\n\
               uniform token subdivisionScheme = \"none\"\n int[] faceVertexCounts = [4, 3, 3]\n int[] faceVertexIndices = [0, 1, 2, 3, 1, 4, 5, 1, 5, 2]\n\
               rel material:binding = </Looks/Red>\n\
               def GeomSubset \"Right\" {{ uniform token elementType = \"face\"\n\
                 uniform token familyName = \"materialBind\"\n int[] indices = [1, 2]\n\
                 rel material:binding = </Looks/Blue> }}\n\
             }}\n\
             def Scope \"Looks\" {{ {} {} }}\n",
            looks("Red", "(1, 0, 0)"),
            looks("Blue", "(0, 0, 1)")
        ),
    );
    assert_eq!(b.meshes().len(), 2);
    let color = |m: &Mesh| b.materials()[m.material as usize].base_color.truncate();
    let red = b
        .meshes()
        .iter()
        .find(|m| color(m) == Vec3::X)
        .expect("red part");
    let blue = b
        .meshes()
        .iter()
        .find(|m| color(m) == Vec3::Z)
        .expect("blue part");
    assert_eq!(red.indices.len(), 2, "the quad");
    assert_eq!(blue.indices.len(), 2, "the two triangles");
    assert!(blue.bounds().min.x >= 1.0 && red.bounds().max.x <= 1.0);
}

#[test]
fn missing_textures_and_materialx_files_warn_and_fall_back() {
    let b = read_text(
        "missing_tex",
        "#usda 1.0\n(upAxis = \"Y\")\n\
         def Mesh \"M\" {\n point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n\
           uniform token subdivisionScheme = \"none\"\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n\
           rel material:binding = </L/Mat> }\n\
         def Scope \"L\" { def Material \"Mat\" { token outputs:surface.connect = </L/Mat/S.outputs:surface>\n\
           def Shader \"S\" { uniform token info:id = \"UsdPreviewSurface\"\n\
             color3f inputs:diffuseColor = (0.2, 0.4, 0.6)\n\
             color3f inputs:diffuseColor.connect = </L/Mat/T.outputs:rgb>\n\
             color3f inputs:emissiveColor.connect = </L/Mat/X.outputs:rgb>\n token outputs:surface }\n\
           def Shader \"T\" { uniform token info:id = \"UsdUVTexture\"\n asset inputs:file = @nowhere.png@\n\
             float3 outputs:rgb }\n\
           def Shader \"X\" { uniform token info:id = \"UsdUVTexture\"\n asset inputs:file = @look.mtlx@\n\
             float3 outputs:rgb } } }\n",
    );
    let m = &b.materials()[b.meshes()[0].material as usize];
    assert_eq!(m.base_color_texture, None);
    assert!(close(
        m.base_color.truncate(),
        Vec3::new(0.2, 0.4, 0.6),
        1e-6
    ));
    assert_eq!(m.emission_texture, None);
    let w = b.warnings();
    assert!(
        w.iter()
            .any(|w| w.contains("/L/Mat/T") && w.contains("nowhere.png") && !w.contains('\n')),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("/L/Mat/X") && w.contains("look.mtlx")),
        "{w:?}"
    );
}

#[test]
fn a_reference_to_a_materialx_document_warns_and_falls_back() {
    let dir = temp_dir("mtlx_ref");
    std::fs::write(
        dir.join("look.mtlx"),
        "<?xml version=\"1.0\"?>\n<materialx version=\"1.38\">\n\
         <standard_surface name=\"SR_red\" type=\"surfaceshader\"/>\n</materialx>\n",
    )
    .unwrap();
    let path = dir.join("stage.usda");
    std::fs::write(
        &path,
        format!(
            "#usda 1.0\ndef Mesh \"M\" {{\n {TRIANGLE}\n rel material:binding = </Looks/Red> }}\n\
             def Scope \"Looks\" ( prepend references = @./look.mtlx@</MaterialX/Materials> ) {{}}\n"
        ),
    )
    .unwrap();
    let (b, _) = usd::read(&path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(b.meshes().len(), 1);
    let w = b.warnings();
    assert!(
        w.iter()
            .any(|w| w.contains("look.mtlx") && !w.contains('\n')),
        "{w:?}"
    );
}

#[test]
fn uv_texture_scale_and_bias_apply_to_the_texture_value() {
    let dir = temp_dir("scale_bias");
    // A 1x1 linear texel (0.2, 0.4, 0.6).
    let png = dir.join("t.png");
    image::RgbaImage::from_pixel(1, 1, image::Rgba([51, 102, 153, 255]))
        .save(&png)
        .unwrap();
    let text = "#usda 1.0\n(upAxis = \"Y\")\n\
         def Mesh \"M\" {\n point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n\
           uniform token subdivisionScheme = \"none\"\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n\
           rel material:binding = </L/Mat> }\n\
         def Scope \"L\" { def Material \"Mat\" { token outputs:surface.connect = </L/Mat/S.outputs:surface>\n\
           def Shader \"S\" { uniform token info:id = \"UsdPreviewSurface\"\n\
             color3f inputs:diffuseColor.connect = </L/Mat/T.outputs:rgb>\n\
             normal3f inputs:normal.connect = </L/Mat/N.outputs:rgb>\n token outputs:surface }\n\
           def Shader \"T\" { uniform token info:id = \"UsdUVTexture\"\n asset inputs:file = @t.png@\n\
             token inputs:sourceColorSpace = \"raw\"\n\
             float4 inputs:scale = (0.5, 2, 1, 1)\n float4 inputs:bias = (0.1, 0, -0.5, 0)\n float3 outputs:rgb }\n\
           def Shader \"N\" { uniform token info:id = \"UsdUVTexture\"\n asset inputs:file = @t.png@\n\
             token inputs:sourceColorSpace = \"raw\"\n\
             float4 inputs:scale = (-2, 2, 1, 1)\n float4 inputs:bias = (1, -1, 0.5, 0)\n float3 outputs:rgb } } }\n";
    let path = dir.join("stage.usda");
    std::fs::write(&path, text).unwrap();
    let (b, _) = usd::read(&path).unwrap();
    let m = &b.materials()[b.meshes()[0].material as usize];
    let t = &b.textures()[m.base_color_texture.unwrap() as usize];
    let c = t.sample(Vec2::splat(0.5)).truncate();
    assert!(
        close(c, Vec3::new(0.2 * 0.5 + 0.1, 0.4 * 2.0, 0.6 - 0.5), 1e-5),
        "{c}"
    );
    // The normal map: (0.2·−2 + 1, 0.4·2 − 1, 0.6 + 0.5) = (0.6, −0.2, 1.1), normalised.
    let tc = nimbus::material::TexCoord::point(Vec2::splat(0.5));
    let n = m
        .normal_map(&nimbus::material::ShadingPoint::from(tc), b.textures())
        .unwrap();
    let want = Vec3::new(0.6, -0.2, 1.1).normalize();
    assert!(close(n, want, 1e-5), "{n} vs {want}");
}

#[test]
fn mcusd_camera_looks_at_the_scene() {
    let Some(dir) = realworld("McUsd") else {
        return;
    };
    let b = read_real(&dir.join("McUsd.usda"));
    let cam = b.camera().expect("McUsd has a camera");
    let forward = cam.camera_to_world.transform_vector3(-Vec3::Z).normalize();
    let mut bounds = b.meshes()[0].bounds();
    for m in b.meshes() {
        bounds = bounds.union(&m.bounds());
    }
    let centre = 0.5 * (bounds.min + bounds.max);
    let to_centre = (centre - cam.position()).normalize();
    let angle = forward.dot(to_centre).clamp(-1.0, 1.0).acos().to_degrees();
    // The camera at (535, 535, 535) cm, rotateZXY (-35, 45, 0): rotated −35° about X (pitched down), then 45°
    // about Y, it looks down the diagonal toward the blocks around the origin. Angles taken by letter position
    // instead pitch it up by 45° to the sky, 90° away from the centre.
    let yfov = cam.yfov.to_degrees();
    println!(
        "McUsd: angle between the view axis and the bounds' centre {angle:.2}°, yfov {yfov:.1}°"
    );
    assert!(
        angle < 0.25 * yfov,
        "the camera looks {angle:.1}° away from the scene"
    );
}

#[test]
fn roughness_test_reads_textures_inside_its_package() {
    let Some(dir) = realworld("RoughnessTest") else {
        return;
    };
    let b = read_real(&dir.join("RoughnessTest.usdz"));
    assert!(!b.textures().is_empty(), "the textures inside the package");
    assert!(
        !b.warnings().iter().any(|w| w.contains("cannot be read")),
        "{:?}",
        b.warnings()
    );
}

/// Tangent-space normals the three cards of NormalsTextureBiasAndScale decode, per texel, sampled on a grid.
fn card_normals(b: &SceneBuilder, material: &str) -> Vec<Vec3> {
    let m = b
        .materials()
        .iter()
        .find(|m| m.name.ends_with(material))
        .unwrap_or_else(|| panic!("material {material}"));
    let mut out = Vec::new();
    for y in 0..64 {
        for x in 0..64 {
            let uv = Vec2::new((x as f32 + 0.5) / 64.0, (y as f32 + 0.5) / 64.0);
            let tc = nimbus::material::TexCoord::point(uv);
            out.push(
                m.normal_map(&nimbus::material::ShadingPoint::from(tc), b.textures())
                    .unwrap_or(Vec3::Z),
            );
        }
    }
    out
}

#[test]
fn normal_maps_decode_with_their_scale_and_bias() {
    let Some(dir) = realworld("NormalsTextureBiasAndScale") else {
        return;
    };
    for file in [
        "NormalsTextureBiasAndScale.usda",
        "NormalsTextureBiasAndScale.usdz",
    ] {
        let b = read_real(&dir.join(file));
        // Only the "AngledLight" is visible; the three others are authored invisible.
        assert_eq!(b.lights().len(), 1, "{file}");
        let plain = card_normals(&b, "/RNormals");
        // The README: (246, 127, 175) in the plain map decodes to (0.929, −0.004, 0.373), pointing right.
        let right = Vec3::new(246.0, 127.0, 175.0) / 255.0 * 2.0 - 1.0;
        let tilted = plain.iter().filter(|n| n.z < 0.95).count();
        assert!(
            tilted > 100,
            "{file}: the R's slopes ({tilted} tilted texels)"
        );
        assert!(plain.iter().any(|n| n.dot(right.normalize()) > 0.99));
        // The reversed-x (0-bias z) and reversed-y maps, decoded with their scale and bias, give the same
        // normals as the plain map: every card should look the same.
        for other in ["/RNormalsReversedX0BiasZ", "/RNormalsReversedY"] {
            let n = card_normals(&b, other);
            let mean_dot: f32 =
                plain.iter().zip(&n).map(|(a, b)| a.dot(*b)).sum::<f32>() / n.len() as f32;
            let worst_tilted = plain
                .iter()
                .zip(&n)
                .filter(|(a, _)| a.z < 0.95)
                .map(|(a, b)| a.dot(*b))
                .fold(1.0f32, f32::min);
            println!("{file} {other}: mean dot {mean_dot:.4}, worst on slopes {worst_tilted:.3}");
            assert!(mean_dot > 0.99, "{file} {other}: mean dot {mean_dot}");
            assert!(
                worst_tilted > 0.8,
                "{file} {other}: worst dot on the slopes {worst_tilted}"
            );
        }
    }
}

#[test]
fn point_instancers_share_one_memory_budget_per_scene() {
    // Two instancers of 2,000 one-triangle instances each: either fits a budget of 3,000 copies (each instance
    // record counts `BYTES_PER_INSTANCE`, a little more than a copied triangle), both together do not. Before,
    // each instancer was checked on its own and the stage loaded.
    let instancer = |name: &str| {
        let positions = vec!["(0, 0, 0)"; 2000].join(", ");
        let indices = vec!["0"; 2000].join(", ");
        format!(
            "def PointInstancer \"{name}\" {{\n\
               rel prototypes = [</{name}/Protos/Tri>]\n\
               int[] protoIndices = [{indices}]\n\
               point3f[] positions = [{positions}]\n\
               def Scope \"Protos\" {{ def Mesh \"Tri\" {{ {TRIANGLE} }} }}\n\
             }}\n"
        )
    };
    let text = format!("#usda 1.0\n{}{}", instancer("A"), instancer("B"));
    let path = temp_dir("instancer_budget").join("stage.usda");
    std::fs::write(&path, &text).unwrap();
    let per_instance = nimbus::scene::BYTES_PER_TRIANGLE + 3 * nimbus::scene::BYTES_PER_VERTEX;
    let limits = Limits::with_memory(3000 * per_instance);
    let err = usd::read_with_limits(&path, &limits)
        .err()
        .expect("4,000 instances must not fit the budget of 3,000");
    let msg = err.to_string();
    assert!(
        msg.contains("/B") && msg.contains("memory budget") && msg.contains("--memory-limit"),
        "{msg}"
    );
    // Either instancer alone loads.
    let one = format!("#usda 1.0\n{}", instancer("A"));
    std::fs::write(&path, one).unwrap();
    let (b, _) = usd::read_with_limits(&path, &limits).unwrap();
    assert_eq!(b.instances().len(), 2000);
}
