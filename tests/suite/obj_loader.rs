//! The OBJ loader on hostile input: MTL colours that made `tobj` panic, non-finite or overflowing numbers,
//! faces with too few corners or out-of-range indices, empty files and endless devices are each a one-line
//! error naming the file and the line; a missing MTL library is a warning.

use nimbus::limits::Limits;
use nimbus::scene::{load_builder, LoadOptions, SceneError, SceneErrorKind};
use std::path::{Path, PathBuf};

/// A fresh folder for one test.
fn folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus_obj_{}_{tag}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";

/// Loads `path`, expecting an error whose message is one line of printable ASCII containing each of `needles`.
fn load_err(path: &Path, needles: &[&str]) -> SceneError {
    let err = match load_builder(path, &LoadOptions::default()) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => e,
    };
    let msg = err.to_string();
    assert!(
        msg.chars().all(|c| c.is_ascii_graphic() || c == ' '),
        "not one printable line: {msg:?}"
    );
    for n in needles {
        assert!(msg.contains(n), "{msg:?} should contain {n:?}");
    }
    err
}

#[test]
fn short_or_odd_mtl_colours_are_errors_naming_the_mtl_line() {
    let dir = folder("colours");
    let obj = format!("mtllib m.mtl\n{QUAD}usemtl a\nf 1 2 3 4\n");
    let obj = write(&dir, "scene.obj", &obj);
    for (line, expect) in [
        ("Ks 0", "expected 3 numbers"),
        ("Ke -2", "expected 3 numbers"),
        ("Ke nan", "finite"),
        ("Kd 0.5 0.5", "expected 3 numbers"),
        ("Kd 0.5 0.5 1e39", "finite"),
        ("Ka", "expected 3 numbers"),
        ("Tf 1 1", "expected 3 numbers"),
        ("Kd spectral tungsten.rfl", "spectral"),
        ("Ks xyz 1 1 1", "xyz"),
        ("Ns inf", "finite"),
        ("Ni", "expected 1 number"),
        ("d -halo 0.5", "not a number"),
        ("illum x", "illum"),
    ] {
        write(&dir, "m.mtl", &format!("newmtl a\n{line}\n"));
        let err = load_err(&obj, &["m.mtl", "line 2", expect]);
        assert!(err.path.ends_with("m.mtl"), "{err}");
    }
    write(
        &dir,
        "m.mtl",
        "newmtl a\nKd 0.5 0.25 0.125\nKe 0 0 0\nNs 10\n",
    );
    let b = load_builder(&obj, &LoadOptions::default()).unwrap();
    assert!(b.materials().iter().any(|m| m.name == "a"));
}

#[test]
fn non_finite_and_overflowing_numbers_are_errors_with_the_line() {
    let dir = folder("numbers");
    for (bad, expect) in [
        ("v nan 0 0", "finite"),
        ("v 0 inf 0", "finite"),
        ("v 0 0 1e39", "finite"),
        ("v 0 0 -1e39", "finite"),
        ("v 1 2", "expected 3 coordinates"),
        ("v 0 99999999999999999999 0", "beyond"),
        ("v 1 2 3 0", "w is 0"),
        ("v 1e30 0 0 1e-30", "not finite"),
        ("vt nan 0", "finite"),
        ("vn 0 0 1e39", "finite"),
        ("vn 0 1", "expected 3"),
    ] {
        let p = write(&dir, "v.obj", &format!("{QUAD}{bad}\nf 1 2 3\n"));
        load_err(&p, &["v.obj", "line 5", expect]);
    }
}

#[test]
fn faces_need_three_corners_and_valid_indices() {
    let dir = folder("faces");
    for (face, expect) in [
        ("f 1", "1 corners"),
        ("f 1 2", "2 corners"),
        ("f", "0 corners"),
        ("f 1 2 0", "index 0"),
        ("f 1 2 5", "vertex index 5"),
        ("f 1 2 -5", "vertex index -5"),
        ("f 1 2 99999999999999999999", "not an integer"),
        ("f 1 2 -9223372036854775808", "vertex index"),
        ("f 1/1 2/1 3/1", "texture coordinate index 1"),
        ("f 1//7 2//7 3//7", "normal index 7"),
        ("f 1/-5/ 2 3", "texture coordinate index -5"),
        ("f 1/1/1/1 2 3", "more than three"),
        ("f /1 2 3", "no vertex index"),
        ("l 1 9", "vertex index 9"),
    ] {
        let p = write(&dir, "f.obj", &format!("{QUAD}{face}\n"));
        load_err(&p, &["f.obj", "line 5", expect]);
    }
    // Relative indices within range are fine.
    let p = write(&dir, "ok.obj", &format!("{QUAD}f -4 -3 -2 -1\n"));
    let b = load_builder(&p, &LoadOptions::default()).unwrap();
    assert_eq!(b.meshes()[0].indices.len(), 2);
}

#[test]
fn files_without_faces_are_errors() {
    let dir = folder("empty");
    load_err(&write(&dir, "empty.obj", ""), &["empty.obj", "no faces"]);
    load_err(
        &write(&dir, "points.obj", &format!("{QUAD}# nothing else\n")),
        &["points.obj", "no faces"],
    );
}

#[test]
fn endless_devices_and_oversized_files_are_clear_errors() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        return;
    }
    let dir = folder("devices");
    let link = dir.join("zero.obj");
    std::os::unix::fs::symlink(zero, &link).unwrap();
    let err = load_err(&link, &["zero.obj", "endless device"]);
    assert!(matches!(err.kind, SceneErrorKind::Io(_)));
    // The same device named as a material library.
    let obj = write(
        &dir,
        "lib.obj",
        &format!("mtllib /dev/zero\n{QUAD}f 1 2 3\n"),
    );
    load_err(&obj, &["/dev/zero", "endless device"]);
    // A regular file over the memory budget.
    let options = LoadOptions {
        limits: Limits::with_memory(16),
        ..Default::default()
    };
    let err = load_builder(&obj, &options).err().expect("over the budget");
    assert!(err.to_string().contains("memory budget"), "{err}");
}

#[test]
fn a_missing_material_library_is_a_warning() {
    let dir = folder("missing");
    let obj = write(
        &dir,
        "scene.obj",
        &format!("mtllib absent.mtl\n{QUAD}usemtl a\nf 1 2 3 4\n"),
    );
    let b = load_builder(&obj, &LoadOptions::default()).unwrap();
    assert!(
        b.warnings().iter().any(|w| w.contains("absent.mtl")),
        "{:?}",
        b.warnings()
    );
    assert_eq!(b.meshes().len(), 1);
    b.build().unwrap();
}

/// `mtllib a.mtl b.mtl` names two libraries (the OBJ format allows several on one line) but was read as one
/// file named "a.mtl b.mtl", missing both (issue 36). Each is loaded now; a single library whose name holds a
/// space, as Blender writes it unquoted, still loads as one file.
#[test]
fn several_libraries_on_one_mtllib_line_are_each_loaded() {
    let dir = folder("mtllibs");
    write(&dir, "a.mtl", "newmtl red\nKd 0.8 0.1 0.1\n");
    write(&dir, "b.mtl", "newmtl blue\nKd 0.1 0.1 0.8\n");
    write(&dir, "my lib.mtl", "newmtl green\nKd 0.1 0.8 0.1\n");
    let faces = "usemtl red\nf 1 2 3\nusemtl blue\nf 1 3 4\n";
    let cases = [
        (
            "two.obj",
            format!("mtllib a.mtl b.mtl\n{QUAD}{faces}"),
            vec![("red", 0.8), ("blue", 0.1)],
        ),
        (
            "tabs.obj",
            format!("mtllib a.mtl\tb.mtl \n{QUAD}{faces}"),
            vec![("red", 0.8), ("blue", 0.1)],
        ),
        (
            "spaced.obj",
            format!("mtllib my lib.mtl\n{QUAD}usemtl green\nf 1 2 3\n"),
            vec![("green", 0.1)],
        ),
    ];
    for (name, text, expected) in cases {
        let obj = write(&dir, name, &text);
        let b = load_builder(&obj, &LoadOptions::default()).unwrap();
        assert!(
            b.warnings().iter().all(|w| !w.contains("not found")),
            "{name}: {:?}",
            b.warnings()
        );
        let used: Vec<(String, f32)> = b
            .meshes()
            .iter()
            .map(|m| {
                let material = &b.materials()[m.material as usize];
                (material.name.clone(), material.base_color.x)
            })
            .collect();
        for (material, red) in expected {
            assert!(
                used.iter()
                    .any(|(n, r)| n == material && (r - red).abs() < 1e-6),
                "{name}: {material} not used with red {red}: {used:?}"
            );
        }
    }
}
