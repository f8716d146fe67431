//! Wavefront OBJ + MTL loader (the thesis renderer's format), on top of `tobj`.
//!
//! MTL keys read (see [`mtl`] for the syntax and [`maps`] for the textures) and their mapping onto the glTF
//! material model:
//! - `Kd` → base colour; a material with no specular (`Ks` = 0) is exactly Lambertian; `map_Kd` → the sRGB
//!   base-colour texture, multiplied by `Kd` as the MTL specification says (`Kd` is 1 when only `map_Kd` is given);
//! - `Ks` → a specular layer; when `Kd` is black the surface is a metal with `Ks` as its colour;
//! - `Ns` (Phong exponent) → roughness via α = √(2 / (Ns + 2)) (Walter et al. 2007, §5.2), roughness = √α;
//! - `Ke` → emitted radiance (an area light); `map_Ke` → the sRGB emission texture, multiplied by `Ke` (1 when
//!   only `map_Ke` is given);
//! - `map_Bump` / `bump` (with `-bm`) → a height map, converted to a tangent-space normal map; `norm` → a
//!   tangent-space normal map (`-bm` is its scale);
//! - `d` (or `Tr` = 1 − `d`) → coverage: with `map_d` a cut-out (glTF `MASK`, cutoff ½) whose coverage texture
//!   is multiplied by `d`; without, `d` < 1 is partial coverage (glTF `BLEND`, alpha `d`). Only with a glass
//!   illumination model (`illum` 4, 6, 7 or 9) does `d` < 1 make a dielectric with transmission 1 − `d` and
//!   index `Ni` instead;
//! - `-o` / `-s` texture options offset and scale the texture coordinates of the meshes using the material (one
//!   transform per material: the first textured statement's, with a warning when others differ); `-clamp on`
//!   clamps. Options Nimbus does not honour (`-blendu`, `-mm`, ...) and texture keys it does not read (`map_Ks`,
//!   `map_Ns`, `refl`, ...) are listed in one warning per library.
//!
//! OBJ has no cameras or lights besides emissive faces: the default camera frames the scene.
//!
//! Text: lines that are not UTF-8 (an exporter's Latin-1 material or object names) are read as Latin-1, with a
//! warning naming them, so that one such name does not fail the file; `usemtl` and `newmtl` names then still
//! match each other.
//!
//! Untrusted input: the OBJ and every MTL and texture it names are read with [`crate::limits::read_file`]
//! (size-capped) and checked line by line before `tobj` parses the OBJ, so that what `tobj` would panic on or
//! accept silently is an error naming the file and the line: vertices, texture coordinates and normals must be
//! finite `f32` numbers, coordinates stay within ±1e12, a face needs three corners whose indices name existing
//! vertices (negative indices count back from the last), a file without faces is an error, and MTL statements
//! are checked as [`mtl`] says. Line elements (`l`) are checked but not rendered. A missing MTL file or texture
//! is a warning, and its materials default or stay untextured.

mod maps;
mod mtl;

use super::{LoadOptions, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::Mesh;
use crate::limits::{one_line, read_file, Limits};
use crate::material::{AlphaMode, Material};
use crate::math::{Rgb, Vec2, Vec3};
use crate::scene::MalformedPart;
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
    let mut builder = SceneBuilder::with_limits(options.limits);
    let text = text(&bytes, path, &mut builder);
    let scan = scan_obj(&text)
        .map_err(|(kind, line, m)| SceneError::new(path, kind(format!("line {line}: {m}"))))?;
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
        materials: RefCell::new(Vec::new()),
        warnings: RefCell::new(Vec::new()),
    };
    let result = tobj::load_obj_buf(&mut text.as_bytes(), &tobj_options, |mtl| {
        libraries.load(mtl)
    });
    if let Some(e) = libraries.error.into_inner() {
        return Err(e);
    }
    builder.warnings.extend(libraries.warnings.into_inner());
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
    let (models, _) = result.map_err(|e| malformed(path, e.to_string()))?;
    // `tobj` numbers materials in the order the libraries returned them, which is the order of this list.
    let mut maps = maps::TextureMaps::new(&options.limits);
    let mut converted = Vec::new();
    for (mtl, material) in libraries.materials.into_inner() {
        let (m, uv_transform) = convert_material(&mtl, &material, &mut maps, &mut builder)?;
        converted.push((builder.add_material(m), uv_transform));
    }
    let mut default_material = Material::lambertian("default", Rgb::splat(0.8));
    default_material.double_sided = true;
    let default_material = builder.add_material(default_material);
    for model in models {
        builder.add_mesh(model_mesh(path, &model, &converted, default_material)?);
    }
    Ok(builder)
}

/// One `tobj` model as a mesh: its positions, normals (kept when there is one per vertex), texture coordinates
/// (through its material's texture transform, then flipped to glTF's downward v) and triangles, with the material
/// `converted` gives its material id (`default_material` without one). A face that indexes a missing vertex is an
/// error naming the object.
fn model_mesh(
    path: &Path,
    model: &tobj::Model,
    converted: &[(u32, Option<(Vec2, Vec2)>)],
    default_material: u32,
) -> Result<Mesh, SceneError> {
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
    let (material, uv_transform) = match m.material_id {
        Some(i) => *converted.get(i).ok_or_else(|| {
            SceneError::new(
                path,
                SceneErrorKind::InvalidReference(format!(
                    "object '{}' uses material {i}, which is missing",
                    one_line(&model.name, QUOTE_CHARS)
                )),
            )
        })?,
        None => (default_material, None),
    };
    // The texture options' transform (u' = u·s + o), then the flip: OBJ's v runs upward, glTF's (and
    // Nimbus's) downward from the top of the image.
    let (scale, offset) = uv_transform.unwrap_or((Vec2::ONE, Vec2::ZERO));
    let uvs = (m.texcoords.len() == count * 2).then(|| {
        m.texcoords
            .chunks_exact(2)
            .map(|t| {
                let t = Vec2::new(t[0], t[1]) * scale + offset;
                Vec2::new(t.x, 1.0 - t.y)
            })
            .collect()
    });
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
        motion: None,
        ..Mesh::default()
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
    Ok(mesh)
}

fn malformed(path: &Path, message: String) -> SceneError {
    SceneError::new(path, malformed_statement(message))
}

/// Most line numbers a warning about non-UTF-8 lines lists.
const LISTED_LINES: usize = 5;

/// `bytes` as text, line by line: UTF-8 where a line is valid UTF-8, else Latin-1 (every byte one character, so
/// that equal byte strings stay equal and different ones different), with one warning on `builder` listing the
/// first such lines.
fn text(bytes: &[u8], path: &Path, builder: &mut SceneBuilder) -> String {
    if let Ok(text) = std::str::from_utf8(bytes) {
        return text.to_owned();
    }
    let mut out = String::with_capacity(bytes.len() + bytes.len() / 8);
    let mut latin1 = Vec::new();
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        match std::str::from_utf8(line) {
            Ok(l) => out.push_str(l),
            Err(_) => {
                latin1.push(i + 1);
                out.extend(line.iter().map(|&b| b as char));
            }
        }
    }
    let listed: Vec<String> = latin1
        .iter()
        .take(LISTED_LINES)
        .map(|l| l.to_string())
        .collect();
    let more = if latin1.len() > LISTED_LINES {
        format!(" and {} more", latin1.len() - LISTED_LINES)
    } else {
        String::new()
    };
    builder.warn(format!(
        "{}: line {}{more} not UTF-8; read as Latin-1",
        path.display(),
        listed.join(", ")
    ));
    out
}

/// How an error found while scanning a file is typed: the kind's constructor, the line, the message.
type LineError = (fn(String) -> SceneErrorKind, usize, String);

/// A face corner's error: its kind's constructor and the message.
type CornerError = (fn(String) -> SceneErrorKind, String);

fn bad(line: usize, message: String) -> LineError {
    (malformed_statement, line, message)
}

/// A statement of an OBJ or MTL file that does not parse: the file's syntax.
fn malformed_statement(message: String) -> SceneErrorKind {
    SceneErrorKind::malformed(MalformedPart::File, message)
}

/// A face corner that names no vertex it may: the mesh's faces.
fn malformed_face(message: String) -> SceneErrorKind {
    SceneErrorKind::malformed(MalformedPart::Mesh, message)
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
                check_vertex(n, &args)?;
                v += 1;
            }
            "vt" => {
                check_texture_coordinate(n, &args)?;
                vt += 1;
            }
            "vn" => {
                check_normal(n, &args)?;
                vn += 1;
            }
            "f" | "l" => {
                check_element(n, key, &args, [v, vt, vn])?;
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

/// Checks a vertex (`v`, on line `n`): 3 finite coordinates within [`MAX_COORDINATE`], then an optional
/// non-zero weight or a colour.
fn check_vertex(n: usize, args: &[&str]) -> Result<(), LineError> {
    let x = numbers(n, "vertex", args)?;
    let position = match x.len() {
        3 | 6 => [x[0], x[1], x[2]],
        4 if x[3] != 0.0 => [x[0] / x[3], x[1] / x[3], x[2] / x[3]],
        4 => return Err(bad(n, "vertex: weight w is 0".into())),
        k => {
            return Err(bad(
                n,
                format!(
                    "vertex: expected 3 coordinates (then a weight or a colour), found {k} numbers"
                ),
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
    Ok(())
}

/// Checks a texture coordinate (`vt`, on line `n`): 2 or 3 finite numbers.
fn check_texture_coordinate(n: usize, args: &[&str]) -> Result<(), LineError> {
    let x = numbers(n, "texture coordinate", args)?;
    if !(2..=3).contains(&x.len()) {
        return Err(bad(
            n,
            format!(
                "texture coordinate: expected 2 or 3 numbers, found {}",
                x.len()
            ),
        ));
    }
    Ok(())
}

/// Checks a normal (`vn`, on line `n`): 3 finite numbers.
fn check_normal(n: usize, args: &[&str]) -> Result<(), LineError> {
    let x = numbers(n, "normal", args)?;
    if x.len() != 3 {
        return Err(bad(
            n,
            format!("normal: expected 3 numbers, found {}", x.len()),
        ));
    }
    Ok(())
}

/// Checks a face (`f`, at least 3 corners) or line element (`l`, at least 2) on line `n`: each corner's
/// indices refer to the `[v, vt, vn]` elements declared before it.
fn check_element(
    n: usize,
    key: &str,
    args: &[&str],
    declared: [usize; 3],
) -> Result<(), LineError> {
    let what = if key == "f" { "face" } else { "line element" };
    let least = if key == "f" { 3 } else { 2 };
    if args.len() < least {
        return Err(bad(
            n,
            format!("{what}: {} corners (at least {least} needed)", args.len()),
        ));
    }
    for corner in args {
        check_corner(corner, declared).map_err(|(kind, m)| {
            (
                kind,
                n,
                format!("{what} corner '{}': {m}", one_line(corner, QUOTE_CHARS)),
            )
        })?;
    }
    Ok(())
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
        return Err((malformed_face, "more than three indices".into()));
    }
    if parts[0].is_empty() {
        return Err((malformed_face, "no vertex index".into()));
    }
    for (k, part) in parts.iter().enumerate() {
        if part.is_empty() {
            continue;
        }
        let Ok(index) = part.parse::<i64>() else {
            return Err((malformed_face, "an index is not an integer".into()));
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

/// The MTL loader handed to `tobj`: it reads each library once, parses and checks it, keeps its materials (in
/// the order `tobj` numbers them) and records the first error (which `tobj` would otherwise only keep when no
/// library loads) and the libraries that are missing.
struct Libraries<'a> {
    obj: &'a Path,
    limits: &'a Limits,
    /// The OBJ line of each `mtllib`, in the order `tobj` asks for them.
    lines: Vec<usize>,
    next: Cell<usize>,
    seen: RefCell<HashSet<PathBuf>>,
    missing: RefCell<Vec<String>>,
    error: RefCell<Option<SceneError>>,
    /// Every material returned to `tobj`, with its library's path.
    materials: RefCell<Vec<(PathBuf, mtl::MtlMaterial)>>,
    /// The libraries' warnings.
    warnings: RefCell<Vec<String>>,
}

impl Libraries<'_> {
    /// Loads the libraries of one `mtllib` line, which `tobj` hands over whole: the OBJ format allows several
    /// names on the line, separated by spaces, but Blender writes one name unquoted, spaces and all. A name
    /// that is a file is one library; otherwise each word is a library.
    fn load(&self, name: &Path) -> tobj::MTLLoadResult {
        let line = self.lines.get(self.next.get()).copied().unwrap_or(0);
        self.next.set(self.next.get() + 1);
        if self.error.borrow().is_some() {
            return Err(tobj::LoadError::MaterialParseError);
        }
        let folder = self.obj.parent().unwrap_or(Path::new(""));
        let text = name.to_string_lossy();
        let names: Vec<&str> = if folder.join(name).is_file() {
            vec![&*text]
        } else {
            text.split_whitespace().collect()
        };
        let mut named = Vec::new();
        let mut any_found = false;
        for library in names {
            if let Some(materials) = self.load_one(folder, Path::new(library), line)? {
                any_found = true;
                named.extend(materials);
            }
        }
        if !any_found {
            return Err(tobj::LoadError::OpenFileFailed);
        }
        // `tobj` maps `usemtl` names to these indices (a later duplicate name wins, as in `tobj`'s own parser).
        let index = named
            .iter()
            .enumerate()
            .map(|(i, m)| (m.name.clone(), i))
            .collect();
        Ok((named, index))
    }

    /// Loads the library `name` (relative to `folder`) of the `mtllib` on OBJ line `line`: its materials, in
    /// order (none when it was loaded before), or `None` when it is missing (recorded as a warning).
    fn load_one(
        &self,
        folder: &Path,
        name: &Path,
        line: usize,
    ) -> Result<Option<Vec<tobj::Material>>, tobj::LoadError> {
        let file = folder.join(name);
        if !self.seen.borrow_mut().insert(file.clone()) {
            // Already loaded (or reported): its materials are known.
            return Ok(Some(Vec::new()));
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
                    one_line(&name.to_string_lossy(), QUOTE_CHARS)
                ));
                return Ok(None);
            }
            Err(e) => return fail(SceneError::new(file, SceneErrorKind::Io(e))),
        };
        let mut notes = SceneBuilder::default();
        let text = text(&bytes, &file, &mut notes);
        let library = match mtl::parse(&text) {
            Ok(l) => l,
            Err((kind, n, m)) => {
                return fail(SceneError::new(file, kind(format!("line {n}: {m}"))))
            }
        };
        let mut warnings = self.warnings.borrow_mut();
        warnings.extend(notes.warnings);
        if !library.ignored_options.is_empty() {
            warnings.push(format!(
                "{}: texture options {} are not supported and ignored",
                file.display(),
                library.ignored_options.join(", ")
            ));
        }
        if !library.unread_maps.is_empty() {
            warnings.push(format!(
                "{}: {} not read (the material model has no such texture)",
                file.display(),
                library.unread_maps.join(", ")
            ));
        }
        let mut materials = self.materials.borrow_mut();
        let mut named = Vec::new();
        for m in library.materials {
            named.push(tobj::Material {
                name: m.name.clone(),
                ..Default::default()
            });
            materials.push((file.clone(), m));
        }
        Ok(Some(named))
    }
}

/// A material's texture-coordinate transform from its texture options: scale, then offset.
type UvTransform = Option<(Vec2, Vec2)>;

/// How much of a surface the MTL block `m` covers (`d`, `Tr`): an illumination model with glass (4, 6, 7, 9)
/// transmits the rest, any other blends it with what is behind; `kd` is the block's diffuse colour.
fn apply_coverage(out: &mut Material, m: &mtl::MtlMaterial, kd: Rgb) {
    let coverage = m.coverage();
    let glass = matches!(m.illum, Some(4 | 6 | 7 | 9));
    if glass && coverage < 1.0 {
        out.transmission = 1.0 - coverage;
        out.specular_factor = 1.0;
        out.metallic = 0.0;
        out.double_sided = false;
        if kd.max_element() <= 0.0 {
            out.base_color = Rgb::ONE.extend(1.0);
        }
    } else {
        out.base_color.w = coverage;
        if coverage < 1.0 {
            out.alpha_mode = AlphaMode::Blend;
        }
    }
}

/// The texture-coordinate transform of the material `m` of library `mtl` whose `used` maps are read: the
/// first map's, one per material (it moves the mesh's coordinates), with a warning when another map's
/// differs; `None` for the identity.
fn shared_transform(
    mtl: &Path,
    m: &mtl::MtlMaterial,
    used: &[&mtl::TextureMap],
    builder: &mut SceneBuilder,
) -> UvTransform {
    let transform = used.first().map(|t| (t.scale, t.offset));
    if let Some(other) = used.iter().find(|t| Some((t.scale, t.offset)) != transform) {
        builder.warn(format!(
            "{}: line {}: material '{}': the -o/-s options of {} differ from those of its other textures; the \
             first ones apply to all",
            mtl.display(),
            other.line,
            one_line(&m.name, QUOTE_CHARS),
            other.key
        ));
    }
    transform.filter(|&(s, o)| s != Vec2::ONE || o != Vec2::ZERO)
}

/// The material of an MTL block of the library `mtl`, and the texture-coordinate transform of its textures.
fn convert_material(
    mtl: &Path,
    m: &mtl::MtlMaterial,
    maps: &mut maps::TextureMaps,
    builder: &mut SceneBuilder,
) -> Result<(Material, UvTransform), SceneError> {
    use mtl::MapKind;
    let mut texture = |kind: MapKind, builder: &mut SceneBuilder| -> Result<_, SceneError> {
        match m.map(kind) {
            Some(map) => Ok(maps.texture(mtl, map, builder)?.map(|id| (id, map))),
            None => Ok(None),
        }
    };
    let diffuse_map = texture(MapKind::Diffuse, builder)?;
    let emission_map = texture(MapKind::Emission, builder)?;
    let alpha_map = texture(MapKind::Dissolve, builder)?;
    let normal_map = match texture(MapKind::Normal, builder)? {
        Some((id, map)) => Some((id, map.bump_multiplier, map)),
        // The bump multiplier is baked into the normals made from a height map.
        None => texture(MapKind::Bump, builder)?.map(|(id, map)| (id, 1.0, map)),
    };

    let one_if_mapped = |c: Option<Rgb>, mapped: bool| {
        c.unwrap_or(if mapped { Rgb::ONE } else { Rgb::ZERO })
            .max(Rgb::ZERO)
    };
    // A named base-colour map makes the default `Kd` 1, even when its file is missing; an emission map only when
    // its file was read (a missing one must not make the surface glow).
    let kd = one_if_mapped(m.diffuse, m.map(MapKind::Diffuse).is_some());
    let ks = one_if_mapped(m.specular, false);
    let mut out = Material::lambertian(&m.name, kd);
    out.double_sided = true;
    out.base_color_texture = diffuse_map.map(|(id, _)| id);
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
    out.emission = one_if_mapped(m.emissive, emission_map.is_some());
    out.emission_texture = emission_map.map(|(id, _)| id);
    out.normal_texture = normal_map.map(|(id, scale, _)| (id, scale));
    if let Some(ni) = m.ior.filter(|v| v.is_finite() && *v > 0.0) {
        out.ior = ni;
    }
    apply_coverage(&mut out, m, kd);
    if let Some((id, _)) = alpha_map {
        out.alpha_texture = Some(id);
        out.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
    }

    let used: Vec<&mtl::TextureMap> = [diffuse_map, emission_map, alpha_map]
        .into_iter()
        .flatten()
        .map(|(_, map)| map)
        .chain(normal_map.map(|(_, _, map)| map))
        .collect();
    let transform = shared_transform(mtl, m, &used, builder);
    Ok((out, transform))
}
