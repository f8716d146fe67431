//! Wavefront OBJ + MTL loader (the thesis renderer's format), on top of `tobj`.
//!
//! MTL keys read and their mapping onto the glTF material model:
//! - `Kd` → base colour; a material with no specular (`Ks` = 0) is exactly Lambertian;
//! - `Ks` → a specular layer; when `Kd` is black the surface is a metal with `Ks` as its colour;
//! - `Ns` (Phong exponent) → roughness via α = √(2 / (Ns + 2)) (Walter et al. 2007, §5.2), roughness = √α;
//! - `Ke` → emitted radiance (an area light);
//! - `Ni` → index of refraction, `d` < 1 → transmission 1 − d (a dielectric).
//!
//! OBJ has no cameras or lights besides emissive faces: the default camera frames the scene.
//!
//! Untrusted input: the OBJ and every MTL it names are read with [`crate::limits::read_file`] (size-capped) and
//! checked line by line before `tobj` parses them, so that what `tobj` would panic on or accept silently is an
//! error naming the file and the line: vertices, texture coordinates and normals must be finite `f32` numbers,
//! coordinates stay within ±1e12,
//! a face needs three corners whose indices name existing vertices (negative indices count back from the
//! last), a file without faces is an error, and MTL colours (`Ka`, `Kd`, `Ks`, `Ke`, `Tf`, `Kt`) are exactly
//! three finite numbers (the `spectral` and `xyz` forms are refused), numeric keys one finite number. Line
//! elements (`l`) are checked but not rendered. A missing MTL file is a warning, and its materials default.

use super::{LoadOptions, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::Mesh;
use crate::limits::{one_line, read_file, Limits};
use crate::material::Material;
use crate::math::{Rgb, Vec2, Vec3};
use std::cell::{Cell, RefCell};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// Largest vertex coordinate magnitude accepted. Far beyond any real model, and below the magnitudes (around
/// 1e20, whose squares overflow `f32`) at which the acceleration structure's traversal breaks down.
const MAX_COORDINATE: f32 = 1e12;

/// Longest quotation from a file in an error message.
const QUOTE_CHARS: usize = 48;

/// Loads an `.obj` file and its `.mtl` libraries. OBJ has no volumes; of `options` only the memory budget
/// (`limits`, which caps the size of every file read) applies.
pub fn load(path: &Path, options: &LoadOptions) -> Result<SceneBuilder, SceneError> {
    let bytes = read_file(path, &options.limits)
        .map_err(|e| SceneError::new(path, SceneErrorKind::Io(e)))?;
    let text = utf8(&bytes).map_err(|m| malformed(path, m))?;
    let scan = scan_obj(text)
        .map_err(|(kind, line, m)| SceneError::new(path, kind(format!("line {line}: {m}"))))?;
    let mut builder = SceneBuilder::default();
    let tobj_options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let libraries = Libraries {
        obj: path,
        limits: &options.limits,
        lines: scan.mtllib_lines,
        next: Cell::new(0),
        seen: RefCell::new(HashSet::new()),
        missing: RefCell::new(Vec::new()),
        error: RefCell::new(None),
    };
    let result = tobj::load_obj_buf(&mut text.as_bytes(), &tobj_options, |mtl| {
        libraries.load(mtl)
    });
    if let Some(e) = libraries.error.into_inner() {
        return Err(e);
    }
    for missing in libraries.missing.into_inner() {
        builder.warnings.push(format!(
            "{}: material library {missing} not found; its materials use defaults",
            path.display()
        ));
    }
    if scan.lines > 0 {
        builder.warnings.push(format!(
            "{}: {} line elements (l) are not rendered",
            path.display(),
            scan.lines
        ));
    }
    let (models, materials) = result.map_err(|e| malformed(path, e.to_string()))?;
    // Missing libraries were reported above; with none found `tobj` returns their error here.
    let materials = materials.unwrap_or_default();
    let ids: Vec<u32> = materials
        .iter()
        .map(|m| builder.add_material(convert_material(m)))
        .collect();
    let default_material = builder.add_material(Material::lambertian("default", Rgb::splat(0.8)));
    for model in models {
        let m = &model.mesh;
        let positions: Vec<Vec3> = m
            .positions
            .chunks_exact(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let count = positions.len();
        let normals: Vec<Vec3> = if m.normals.len() == count * 3 {
            m.normals
                .chunks_exact(3)
                .map(|n| Vec3::new(n[0], n[1], n[2]).normalize_or_zero())
                .collect()
        } else {
            Vec::new()
        };
        // OBJ's v runs upward; glTF's (and Nimbus's) downward from the top of the image.
        let uvs = (m.texcoords.len() == count * 2).then(|| {
            m.texcoords
                .chunks_exact(2)
                .map(|t| Vec2::new(t[0], 1.0 - t[1]))
                .collect()
        });
        let material = match m.material_id {
            Some(i) => *ids.get(i).ok_or_else(|| {
                SceneError::new(
                    path,
                    SceneErrorKind::InvalidReference(format!(
                        "object '{}' uses material {i}, which is missing",
                        one_line(&model.name, QUOTE_CHARS)
                    )),
                )
            })?,
            None => default_material,
        };
        let mut mesh = Mesh {
            name: model.name.clone(),
            positions,
            normals,
            uvs,
            uvs1: None,
            colors: None,
            tangents: None,
            indices: m
                .indices
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect(),
            material,
        };
        let dropped = mesh.remove_invalid_triangles();
        if dropped > 0 {
            return Err(SceneError::new(
                path,
                SceneErrorKind::InvalidReference(format!(
                    "object '{}': {dropped} faces index missing vertices",
                    one_line(&model.name, QUOTE_CHARS)
                )),
            ));
        }
        builder.add_mesh(mesh);
    }
    Ok(builder)
}

fn malformed(path: &Path, message: String) -> SceneError {
    SceneError::new(path, SceneErrorKind::Malformed(message))
}

/// `bytes` as UTF-8 text, or an error naming the line of the first invalid byte.
fn utf8(bytes: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        format!("line {line}: not UTF-8 text")
    })
}

/// How an error found while scanning a file is typed: the kind's constructor, the line, the message.
type LineError = (fn(String) -> SceneErrorKind, usize, String);

/// A face corner's error: its kind's constructor and the message.
type CornerError = (fn(String) -> SceneErrorKind, String);

fn bad(line: usize, message: String) -> LineError {
    (SceneErrorKind::Malformed, line, message)
}

/// What the scan of an OBJ file found.
struct ObjScan {
    /// The line number of each `mtllib` statement, in order (`tobj` loads them in the same order).
    mtllib_lines: Vec<usize>,
    /// Line elements (`l`), which are not rendered.
    lines: usize,
}

/// Checks every statement of an OBJ file that `tobj` reads numbers or indices from.
fn scan_obj(text: &str) -> Result<ObjScan, LineError> {
    let (mut v, mut vt, mut vn, mut faces) = (0usize, 0usize, 0usize, 0usize);
    let mut scan = ObjScan {
        mtllib_lines: Vec::new(),
        lines: 0,
    };
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        let args: Vec<&str> = words.collect();
        match key {
            "v" => {
                let x = numbers(n, "vertex", &args)?;
                let position = match x.len() {
                    3 | 6 => [x[0], x[1], x[2]],
                    4 if x[3] != 0.0 => [x[0] / x[3], x[1] / x[3], x[2] / x[3]],
                    4 => return Err(bad(n, "vertex: weight w is 0".into())),
                    k => {
                        return Err(bad(
                            n,
                            format!("vertex: expected 3 coordinates (then a weight or a colour), found {k} numbers"),
                        ))
                    }
                };
                if position.iter().any(|c| !c.is_finite()) {
                    return Err(bad(n, "vertex: coordinate / weight is not finite".into()));
                }
                if position.iter().any(|c| c.abs() > MAX_COORDINATE) {
                    return Err(bad(
                        n,
                        format!("vertex: a coordinate beyond +-{MAX_COORDINATE:e}"),
                    ));
                }
                v += 1;
            }
            "vt" => {
                let x = numbers(n, "texture coordinate", &args)?;
                if !(2..=3).contains(&x.len()) {
                    return Err(bad(
                        n,
                        format!(
                            "texture coordinate: expected 2 or 3 numbers, found {}",
                            x.len()
                        ),
                    ));
                }
                vt += 1;
            }
            "vn" => {
                let x = numbers(n, "normal", &args)?;
                if x.len() != 3 {
                    return Err(bad(
                        n,
                        format!("normal: expected 3 numbers, found {}", x.len()),
                    ));
                }
                vn += 1;
            }
            "f" | "l" => {
                let what = if key == "f" { "face" } else { "line element" };
                let least = if key == "f" { 3 } else { 2 };
                if args.len() < least {
                    return Err(bad(
                        n,
                        format!("{what}: {} corners (at least {least} needed)", args.len()),
                    ));
                }
                for corner in &args {
                    check_corner(corner, [v, vt, vn]).map_err(|(kind, m)| {
                        (
                            kind,
                            n,
                            format!("{what} corner '{}': {m}", one_line(corner, QUOTE_CHARS)),
                        )
                    })?;
                }
                if key == "f" {
                    faces += 1;
                } else {
                    scan.lines += 1;
                }
            }
            "mtllib" => {
                // `tobj` takes everything after the first space as the file name.
                if line
                    .split_once(' ')
                    .is_none_or(|(_, f)| f.trim().is_empty())
                {
                    return Err(bad(n, "mtllib: no file name".into()));
                }
                scan.mtllib_lines.push(n);
            }
            "usemtl"
                if line
                    .split_once(' ')
                    .is_none_or(|(_, m)| m.trim().is_empty()) =>
            {
                return Err(bad(n, "usemtl: no material name".into()));
            }
            _ => {}
        }
    }
    if faces == 0 {
        return Err(bad(text.lines().count(), "no faces".into()));
    }
    Ok(scan)
}

/// The numbers of a statement, each a finite `f32`.
fn numbers(line: usize, what: &str, args: &[&str]) -> Result<Vec<f32>, LineError> {
    args.iter()
        .map(|a| match a.parse::<f32>() {
            Ok(x) if x.is_finite() => Ok(x),
            Ok(_) => Err(bad(
                line,
                format!(
                    "{what}: '{}' is not a finite 32-bit number",
                    one_line(a, QUOTE_CHARS)
                ),
            )),
            Err(_) => Err(bad(
                line,
                format!("{what}: '{}' is not a number", one_line(a, QUOTE_CHARS)),
            )),
        })
        .collect()
}

/// Checks one face corner `v`, `v/vt`, `v//vn` or `v/vt/vn` against the counts of vertices, texture
/// coordinates and normals declared so far.
fn check_corner(corner: &str, counts: [usize; 3]) -> Result<(), CornerError> {
    const NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let parts: Vec<&str> = corner.split('/').collect();
    if parts.len() > 3 {
        return Err((SceneErrorKind::Malformed, "more than three indices".into()));
    }
    if parts[0].is_empty() {
        return Err((SceneErrorKind::Malformed, "no vertex index".into()));
    }
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() {
            continue;
        }
        let Ok(index) = part.parse::<i64>() else {
            return Err((
                SceneErrorKind::Malformed,
                "an index is not an integer".into(),
            ));
        };
        let (name, count) = (NAMES[k], counts[k] as i64);
        let valid = if index > 0 {
            index <= count
        } else {
            index < 0 && count + index >= 0
        };
        if !valid {
            let why = if index == 0 {
                format!("{name} index 0 (indices count from 1)")
            } else {
                format!("{name} index {index}, but {count} are declared before it")
            };
            return Err((SceneErrorKind::InvalidReference, why));
        }
    }
    Ok(())
}

/// The MTL loader handed to `tobj`: it reads each library once, checks it, and records the first error (which
/// `tobj` would otherwise only keep when no library loads) and the libraries that are missing.
struct Libraries<'a> {
    obj: &'a Path,
    limits: &'a Limits,
    /// The OBJ line of each `mtllib`, in the order `tobj` asks for them.
    lines: Vec<usize>,
    next: Cell<usize>,
    seen: RefCell<HashSet<PathBuf>>,
    missing: RefCell<Vec<String>>,
    error: RefCell<Option<SceneError>>,
}

impl Libraries<'_> {
    fn load(&self, mtl: &Path) -> tobj::MTLLoadResult {
        let line = self.lines.get(self.next.get()).copied().unwrap_or(0);
        self.next.set(self.next.get() + 1);
        if self.error.borrow().is_some() {
            return Err(tobj::LoadError::MaterialParseError);
        }
        let file = self.obj.parent().unwrap_or(Path::new("")).join(mtl);
        if !self.seen.borrow_mut().insert(file.clone()) {
            // Already loaded (or reported): its materials are known.
            return Ok((Vec::new(), Default::default()));
        }
        let fail = |e: SceneError| {
            *self.error.borrow_mut() = Some(e);
            Err(tobj::LoadError::MaterialParseError)
        };
        let bytes = match read_file(&file, self.limits) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                self.missing.borrow_mut().push(format!(
                    "'{}' (line {line})",
                    one_line(&mtl.to_string_lossy(), QUOTE_CHARS)
                ));
                return Err(tobj::LoadError::OpenFileFailed);
            }
            Err(e) => return fail(SceneError::new(file, SceneErrorKind::Io(e))),
        };
        let text = match utf8(&bytes) {
            Ok(t) => t,
            Err(m) => return fail(malformed(&file, m)),
        };
        if let Err((kind, n, m)) = check_mtl(text) {
            return fail(SceneError::new(file, kind(format!("line {n}: {m}"))));
        }
        tobj::load_mtl_buf(&mut text.as_bytes()).or_else(|e| fail(malformed(&file, e.to_string())))
    }
}

/// Checks every MTL statement `tobj` reads a value from (it panics on a colour of fewer than three numbers).
fn check_mtl(text: &str) -> Result<(), LineError> {
    const COLORS: [&str; 6] = ["Ka", "Kd", "Ks", "Ke", "Tf", "Kt"];
    const SCALARS: [&str; 12] = [
        "Ns",
        "Ni",
        "d",
        "Tr",
        "sharpness",
        "Pr",
        "Pm",
        "Ps",
        "Pc",
        "Pcr",
        "aniso",
        "anisor",
    ];
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        let trimmed = line.trim();
        let mut words = trimmed.split_whitespace();
        let Some(key) = words.next() else { continue };
        let args: Vec<&str> = words.collect();
        if COLORS.contains(&key) {
            if let Some(form) = args.first().filter(|a| **a == "spectral" || **a == "xyz") {
                return Err((
                    SceneErrorKind::Unsupported,
                    n,
                    format!("{key}: the '{form}' colour form (only r g b is read)"),
                ));
            }
            let x = numbers(n, key, &args)?;
            if x.len() != 3 {
                return Err(bad(
                    n,
                    format!("{key}: expected 3 numbers (r g b), found {}", x.len()),
                ));
            }
        } else if SCALARS.contains(&key) {
            let x = numbers(n, key, &args)?;
            if x.len() != 1 {
                return Err(bad(
                    n,
                    format!("{key}: expected 1 number, found {}", x.len()),
                ));
            }
        } else if key == "illum" {
            if args.len() != 1 || args[0].parse::<u8>().is_err() {
                return Err(bad(n, "illum: expected one integer 0 to 255".into()));
            }
        } else if (key == "newmtl" || key.starts_with("map_") || key == "bump") && args.is_empty() {
            return Err(bad(n, format!("{key}: no name")));
        }
    }
    Ok(())
}

fn rgb(c: Option<[f32; 3]>) -> Rgb {
    c.map_or(Rgb::ZERO, |c| Rgb::from(c).max(Rgb::ZERO))
}
fn convert_material(m: &tobj::Material) -> Material {
    let kd = rgb(m.diffuse);
    let ks = rgb(m.specular);
    let mut out = Material::lambertian(&m.name, kd);
    out.double_sided = true;
    if ks.max_element() > 0.0 {
        let ns = m.shininess.unwrap_or(100.0).max(0.0);
        let alpha = (2.0 / (ns + 2.0)).sqrt();
        out.roughness = alpha.sqrt();
        if kd.max_element() <= 0.0 {
            out.metallic = 1.0;
            out.base_color = ks.min(Rgb::ONE).extend(1.0);
        } else {
            out.specular_factor = 1.0;
        }
    }
    out.emission = rgb(m.emissive);
    if let Some(ni) = m.optical_density.filter(|v| v.is_finite() && *v > 0.0) {
        out.ior = ni;
    }
    if let Some(d) = m.dissolve.filter(|d| *d < 1.0) {
        out.transmission = (1.0 - d).clamp(0.0, 1.0);
        out.specular_factor = 1.0;
        out.metallic = 0.0;
        out.double_sided = false;
        if kd.max_element() <= 0.0 {
            out.base_color = Rgb::ONE.extend(1.0);
        }
    }
    out
}
