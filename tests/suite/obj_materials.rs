//! OBJ/MTL textures and material keys: `map_Kd`, `map_Ke`, `map_d`, `map_Bump`/`bump` (height maps turned into
//! normal maps), `norm`, `d`/`Tr`, texture options, Windows paths and case-insensitive names, missing textures,
//! non-UTF-8 names; and the real `realworld/obj/spider`, whose `map_Kd` textures must show in its albedo.

use crate::common;

use nimbus::material::AlphaMode;
use nimbus::math::{srgb_to_linear, Vec2, Vec3};
use nimbus::scene::{load_builder, LoadOptions, SceneBuilder};
use std::path::{Path, PathBuf};

/// A fresh folder for one test.
fn folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_objmat_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Writes a PNG of `width × height` RGBA8 pixels given by `f(x, y)`.
fn png(dir: &Path, name: &str, width: u32, height: u32, f: impl Fn(u32, u32) -> [u8; 4]) {
    let img = image::RgbaImage::from_fn(width, height, |x, y| image::Rgba(f(x, y)));
    let p = dir.join(name);
    std::fs::create_dir_all(p.parent().unwrap()).unwrap();
    img.save(&p).unwrap();
}

/// A unit quad in the XY plane with texture coordinates (0,0) at its lower-left corner, using material `a`.
const QUAD: &str =
    "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
usemtl a\nf 1/1 2/2 3/3 4/4\n";

fn load(path: &Path) -> SceneBuilder {
    load_builder(path, &LoadOptions::default()).unwrap()
}

fn material_a(b: &SceneBuilder) -> &nimbus::material::Material {
    b.materials()
        .iter()
        .find(|m| m.name == "a")
        .expect("material a")
}

#[test]
fn map_kd_is_an_srgb_base_colour_texture_multiplied_by_kd() {
    let dir = folder("kd");
    // Left half red 200, right half blue 100 (sRGB bytes); OBJ's v runs up, the image's rows down.
    png(&dir, "tex/Checker.PNG", 4, 2, |x, _| {
        if x < 2 {
            [200, 0, 0, 255]
        } else {
            [0, 0, 100, 255]
        }
    });
    // A Windows exporter's backslashes and a name whose case differs from the file's.
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 0.5 1 1\nmap_Kd .\\tex\\checker.png\n",
    );
    let obj = write(&dir, "s.obj", QUAD);
    let b = load(&obj);
    let m = material_a(&b);
    let id = m.base_color_texture.expect("map_Kd read") as usize;
    let t = &b.textures()[id];
    assert_eq!((t.width(), t.height()), (4, 2));
    let left = t.sample(Vec2::new(0.125, 0.5));
    let right = t.sample(Vec2::new(0.875, 0.5));
    assert!(
        (left.x - srgb_to_linear(200.0 / 255.0)).abs() < 1e-5,
        "{left}"
    );
    assert!(
        (right.z - srgb_to_linear(100.0 / 255.0)).abs() < 1e-5,
        "{right}"
    );
    assert_eq!(m.base_color.truncate(), Vec3::new(0.5, 1.0, 1.0));
    // Rendered albedo: Kd × texture on each half.
    let mut b = b;
    b.set_camera(nimbus::scene::Camera::look_at(
        Vec3::new(0.5, 0.5, 3.0),
        Vec3::new(0.5, 0.5, 0.0),
        15f32.to_radians(),
    ));
    let (img, _) = common::render_square(b, 16, 1, 0, 1);
    let px = |x, y| img.albedo[img.pixel_index(x, y)];
    let expect_left = 0.5 * srgb_to_linear(200.0 / 255.0);
    assert!((px(3, 8).x - expect_left).abs() < 1e-3, "{}", px(3, 8));
    assert!(
        (px(12, 8).z - srgb_to_linear(100.0 / 255.0)).abs() < 1e-3,
        "{}",
        px(12, 8)
    );
    assert!(b_warnings_clean(&obj));
}

fn b_warnings_clean(obj: &Path) -> bool {
    load(obj).warnings().is_empty()
}

#[test]
fn map_ke_map_d_norm_and_dissolve_fill_their_fields() {
    let dir = folder("keys");
    png(&dir, "glow.png", 2, 2, |_, _| [255, 128, 0, 255]);
    png(&dir, "cut.png", 2, 2, |x, _| {
        [if x == 0 { 255 } else { 0 }; 4]
    });
    png(&dir, "n.png", 2, 2, |_, _| [128, 128, 255, 255]);
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 1 1 1\nKe 2 2 2\nmap_Ke glow.png\nmap_d -imfchan r cut.png\nnorm n.png\n\
         newmtl b\nKd 1 1 1\nd 0.25\nnewmtl c\nKd 1 1 1\nTr 0.75\nnewmtl glass\nKd 1 1 1\nd 0.5\nillum 7\n",
    );
    let obj = write(&dir, "s.obj", QUAD);
    let b = load(&obj);
    let m = material_a(&b);
    let glow = &b.textures()[m.emission_texture.expect("map_Ke") as usize];
    assert!((glow.sample(Vec2::splat(0.5)).y - srgb_to_linear(128.0 / 255.0)).abs() < 1e-5);
    assert_eq!(m.emission, Vec3::splat(2.0));
    assert_eq!(m.alpha_mode, AlphaMode::Mask { cutoff: 0.5 });
    let cut = &b.textures()[m.alpha_texture.expect("map_d") as usize];
    assert!(cut.sample(Vec2::new(0.25, 0.5)).x > 0.99 && cut.sample(Vec2::new(0.75, 0.5)).x < 0.01);
    let (n, scale) = m.normal_texture.expect("norm");
    assert_eq!(scale, 1.0);
    let flat = b.textures()[n as usize].sample(Vec2::splat(0.5));
    assert!(
        (flat.z - 1.0).abs() < 1e-6 && (flat.x - 128.0 / 255.0).abs() < 1e-6,
        "norm is linear: {flat}"
    );
    for (name, alpha) in [("b", 0.25), ("c", 0.25)] {
        let m = b.materials().iter().find(|m| m.name == name).unwrap();
        assert_eq!(m.alpha_mode, AlphaMode::Blend, "{name}");
        assert!(
            (m.base_color.w - alpha).abs() < 1e-6,
            "{name}: {}",
            m.base_color
        );
        assert_eq!(
            m.transmission, 0.0,
            "{name}: dissolve is coverage, not refraction"
        );
    }
    let glass = b.materials().iter().find(|m| m.name == "glass").unwrap();
    assert_eq!(glass.alpha_mode, AlphaMode::Opaque);
    assert!((glass.transmission - 0.5).abs() < 1e-6, "illum 7 refracts");
}

#[test]
fn a_bump_height_map_becomes_a_tangent_space_normal_map() {
    let dir = folder("bump");
    // Height rises to the right (columns 0..8) and is constant in v: the normal tilts toward −u (left).
    png(&dir, "h.png", 8, 8, |x, _| {
        [(x * 30) as u8, (x * 30) as u8, (x * 30) as u8, 255]
    });
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 1 1 1\nmap_Bump -bm 2 h.png\nnewmtl b\nKd 1 1 1\nbump h.png\n",
    );
    let obj = write(&dir, "s.obj", QUAD);
    let b = load(&obj);
    let normal = |name: &str| {
        let m = b.materials().iter().find(|m| m.name == name).unwrap();
        let (id, scale) = m.normal_texture.expect("bump read");
        assert_eq!(scale, 1.0);
        let t = b.textures()[id as usize].sample(Vec2::new(0.5, 0.5));
        Vec3::new(t.x * 2.0 - 1.0, t.y * 2.0 - 1.0, t.z * 2.0 - 1.0)
    };
    // Central differences: 30/255 per texel; the slope is bm × that per texel, n ∝ (−slope, 0, 1).
    for (name, bm) in [("a", 2.0f32), ("b", 1.0)] {
        let n = normal(name);
        let slope = bm * 30.0 / 255.0;
        let expect = Vec3::new(-slope, 0.0, 1.0).normalize();
        assert!((n - expect).length() < 2e-3, "{name}: {n} vs {expect}");
    }
}

#[test]
fn a_bluish_bump_image_is_read_as_the_normal_map_it_is() {
    let dir = folder("bumpnormal");
    png(&dir, "nrm.png", 4, 4, |x, _| {
        [128 + x as u8 * 10, 128, 250, 255]
    });
    write(&dir, "m.mtl", "newmtl a\nKd 1 1 1\nmap_Bump nrm.png\n");
    let b = load(&write(&dir, "s.obj", QUAD));
    let (id, _) = material_a(&b).normal_texture.unwrap();
    let t = b.textures()[id as usize].sample(Vec2::new(0.125, 0.5));
    assert!(
        (t.x - 128.0 / 255.0).abs() < 1e-6 && (t.z - 250.0 / 255.0).abs() < 1e-6,
        "{t}"
    );
    assert!(
        b.warnings().iter().any(|w| w.contains("normal map")),
        "{:?}",
        b.warnings()
    );
}

#[test]
fn texture_options_scale_offset_and_clamp() {
    let dir = folder("options");
    png(&dir, "t.png", 2, 2, |_, _| [255; 4]);
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 1 1 1\nmap_Kd -clamp on -s 2 3 1 -o 0.5 0.25 t.png\n",
    );
    let b = load(&write(&dir, "s.obj", QUAD));
    let m = material_a(&b);
    let t = &b.textures()[m.base_color_texture.unwrap() as usize];
    assert_eq!(t.sampler().wrap_s, nimbus::material::Wrap::ClampToEdge);
    // u' = u·s + o, and the v flip (1 − v') after it: corner (1, 1) → (2.5, 3.25) → (2.5, −2.25).
    let uvs = b.meshes()[0].uvs.as_ref().unwrap();
    let corner = b.meshes()[0]
        .positions
        .iter()
        .position(|p| *p == Vec3::new(1.0, 1.0, 0.0))
        .unwrap();
    assert!(
        (uvs[corner] - Vec2::new(2.5, -2.25)).length() < 1e-6,
        "{}",
        uvs[corner]
    );
    // An option Nimbus does not honour is a warning naming it.
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 1 1 1\nmap_Kd -blendu off -mm 0 1 t.png\n",
    );
    let b = load(&dir.join("s.obj"));
    assert!(material_a(&b).base_color_texture.is_some());
    assert!(
        b.warnings()
            .iter()
            .any(|w| w.contains("-blendu") && w.contains("-mm")),
        "{:?}",
        b.warnings()
    );
}

#[test]
fn a_missing_texture_is_a_warning_naming_the_line_and_file() {
    let dir = folder("missingtex");
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 0.25 0.5 0.75\n\nmap_Kd C:\\Users\\someone\\absent.jpg\nnewmtl glow\nmap_Ke gone.png\n",
    );
    let b = load(&write(&dir, "s.obj", QUAD));
    let m = material_a(&b);
    assert!(m.base_color_texture.is_none());
    assert_eq!(m.base_color.truncate(), Vec3::new(0.25, 0.5, 0.75));
    let glow = b.materials().iter().find(|m| m.name == "glow").unwrap();
    assert!(
        !glow.is_emissive(),
        "a missing map_Ke must not make the surface glow"
    );
    assert!(
        b.warnings()
            .iter()
            .any(|w| w.contains("m.mtl") && w.contains("line 4") && w.contains("absent.jpg")),
        "{:?}",
        b.warnings()
    );
    b.build().unwrap();
    // A Windows absolute path whose file lies next to the MTL is found there.
    png(&dir, "absent.jpg.png", 1, 1, |_, _| [0; 4]);
    std::fs::rename(dir.join("absent.jpg.png"), dir.join("ABSENT.jpg")).unwrap();
    let b = load(&dir.join("s.obj"));
    assert!(
        material_a(&b).base_color_texture.is_some(),
        "{:?}",
        b.warnings()
    );
}

#[test]
fn mtl_errors_name_the_mtl_file_and_line() {
    let dir = folder("mtlerr");
    let obj = write(&dir, "s.obj", QUAD);
    for (line, expect) in [
        ("map_Kd -s", "-s"),
        ("map_Kd -bm x t.png", "-bm"),
        ("map_Kd -clamp maybe t.png", "-clamp"),
        ("map_Kd -unknown t.png", "-unknown"),
        ("map_Kd -o 1 2", "no file name"),
    ] {
        write(&dir, "m.mtl", format!("newmtl a\nKd 1 1 1\n{line}\n"));
        let err = load_builder(&obj, &LoadOptions::default())
            .err()
            .expect(line)
            .to_string();
        assert!(
            err.contains("m.mtl") && err.contains("line 3") && err.contains(expect),
            "{line}: {err}"
        );
    }
}

#[test]
fn a_latin1_material_name_does_not_fail_the_file() {
    let dir = folder("latin1");
    let mut mtl = b"newmtl Caf".to_vec();
    mtl.extend_from_slice(&[0xE9]);
    mtl.extend_from_slice(b"\nKd 0.2 0.4 0.6\nnewmtl plain\nKd 1 1 1\n");
    write(&dir, "m.mtl", &mtl);
    let mut obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl Caf".to_vec();
    obj.extend_from_slice(&[0xE9]);
    obj.extend_from_slice(b"\nf 1 2 3\nusemtl plain\nf 1 3 4\n");
    let b = load(&write(&dir, "s.obj", &obj));
    assert_eq!(b.meshes().len(), 2);
    let cafe = &b.materials()[b.meshes()[0].material as usize];
    assert_eq!(
        cafe.base_color.truncate(),
        Vec3::new(0.2, 0.4, 0.6),
        "{}",
        cafe.name
    );
    assert_eq!(cafe.name, "Café", "Latin-1 bytes are read as Latin-1");
    assert!(
        b.warnings().iter().any(|w| w.contains("UTF-8")),
        "{:?}",
        b.warnings()
    );
    b.build().unwrap();
}

/// `realworld/obj/spider`: five materials, each with a `map_Kd` texture (MilkShape 3D's `.\name.jpg` paths).
/// Rendered with the default camera, most covered pixels must show a textured albedo, not one of the five flat
/// `Kd` colours that the untextured materials give.
#[test]
fn the_real_spider_renders_with_its_textures() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let obj = shared.join("realworld/obj/spider/spider.obj");
    let b = load(&obj);
    assert_eq!(b.textures().len(), 5, "{:?}", b.warnings());
    assert!(
        b.materials()
            .iter()
            .filter(|m| m.base_color_texture.is_some())
            .count()
            >= 5
    );
    let kds: Vec<Vec3> = b
        .materials()
        .iter()
        .map(|m| m.base_color.truncate())
        .collect();
    let (img, _) = common::render_square(b, 48, 1, 0, 7);
    let covered: Vec<Vec3> = img
        .albedo
        .iter()
        .zip(&img.depth)
        .filter(|(_, &d)| d > 0.0)
        .map(|(a, _)| *a)
        .collect();
    assert!(
        covered.len() > 48 * 48 / 25,
        "the spider covers {} pixels",
        covered.len()
    );
    let textured = covered
        .iter()
        .filter(|a| kds.iter().all(|k| (**a - *k).abs().max_element() > 0.05))
        .count();
    let fraction = textured as f64 / covered.len() as f64;
    eprintln!(
        "spider: {} covered pixels, {:.3} textured",
        covered.len(),
        fraction
    );
    assert!(
        fraction > 0.5,
        "only {fraction:.3} of the spider's pixels show a texture"
    );
}
