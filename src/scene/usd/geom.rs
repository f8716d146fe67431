//! USD geometry: `Mesh` prims (points, face topology, normals and `st` primvars with their interpolation).

use super::values::{number, token, vec2_array, vec3_array};
use super::Loader;
use crate::geometry::{
    BoundaryRule, CreaseMethod, FaceVaryingRule, Mesh, PolygonMesh, Scheme, SubdivisionRules,
};
use crate::math::{Mat4, Rgb, Vec2, Vec3};
use crate::scene::MalformedPart;
use crate::scene::SceneError;
use openusd::{sdf, usd};

/// Catmull-Clark levels of a `catmullClark` mesh that neither the command line nor the mesh's `refineLevel`
/// sets.
pub const DEFAULT_SUBDIVISION_LEVEL: u32 = 2;

/// The most Catmull-Clark levels read (each multiplies the faces by 4).
pub const MAX_SUBDIVISION_LEVEL: u32 = 8;

/// Memory a subdivided quad takes while it is made and once it is a mesh: its points, corners, normals,
/// texture coordinates and colours, in the subdivision and in the two triangles it becomes.
const SUBDIVIDED_QUAD_BYTES: u64 = 320;

impl Loader<'_> {
    /// Reads the `Mesh` prim `prim` (at `world`, under the inherited material `binding`): its faces, with their
    /// materials, normals, texture coordinates and colours, subdivided when its scheme asks, and adds one
    /// triangle mesh per material.
    pub(super) fn mesh(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let points = match self.value(prim, "points")? {
            Some(v) => vec3_array(&v).ok_or_else(|| {
                self.error(MalformedPart::Mesh, &at, "points must be a point3f[]")
            })?,
            None => return Ok(()),
        };
        let counts = self.int_array(prim, "faceVertexCounts")?;
        let indices = self.int_array(prim, "faceVertexIndices")?;
        self.check_faces(&at, &points, &counts, &indices)?;
        let normals = self.primvar(prim, &["primvars:normals", "normals"], "vertex", vec3_array)?;
        let uvs = self.primvar(prim, &["primvars:st"], "vertex", vec2_array)?;
        let topology = Topology {
            counts: &counts,
            indices: &indices,
            points: points.len(),
        };
        let normals = normals
            .map(|p| topology.expand(p))
            .transpose()
            .map_err(|m| self.error(MalformedPart::Mesh, &at, m))?;
        let uvs = uvs
            .map(|p| topology.expand(p))
            .transpose()
            .map_err(|m| self.error(MalformedPart::Mesh, &at, m))?;
        let left_handed = self
            .value(prim, "orientation")?
            .and_then(|v| token(&v))
            .is_some_and(|o| o == "leftHanded");
        let double_sided = self
            .value(prim, "doubleSided")?
            .is_some_and(|v| matches!(v, sdf::Value::Bool(true)));
        let face_material = self.face_materials(prim, binding, double_sided, counts.len())?;
        let uvs = uvs.map(|st| {
            st.into_iter()
                .map(|t: Vec2| Vec2::new(t.x, 1.0 - t.y))
                .collect::<Vec<_>>()
        });
        let normals = normals.unwrap_or_default();
        let colors = self.corner_colors(prim, &at, &topology, &face_material)?;
        let cage = PolygonMesh {
            points,
            counts: counts.iter().map(|&c| c.max(0) as u32).collect(),
            indices: indices.iter().map(|&i| i as u32).collect(),
            uvs,
            colors,
            face_tags: face_material,
            ..Default::default()
        };
        let (surface, normals) = match self.subdivision(prim, &at, &cage)? {
            Some((scheme, level)) => {
                let surface = self.subdivide(prim, &at, cage, scheme, level)?;
                // A subdivision surface's normals are its own (authored ones apply to the cage only).
                let normals = surface.corner_normals();
                (surface, normals)
            }
            None => (cage, normals),
        };
        for mut mesh in meshes_per_material(&at, &surface, &normals, left_handed) {
            mesh.transform(world);
            self.add_mesh(mesh)?;
        }
        Ok(())
    }

    /// Checks a mesh's faces: `counts` must add up to the length of `indices`, each index must name one of the
    /// `points`, and the points must be finite.
    fn check_faces(
        &self,
        at: &str,
        points: &[Vec3],
        counts: &[i32],
        indices: &[i32],
    ) -> Result<(), SceneError> {
        let total: usize = counts.iter().map(|&c| c.max(0) as usize).sum();
        if total != indices.len() {
            return Err(self.error(
                MalformedPart::Mesh,
                at,
                format!(
                    "faceVertexCounts sum to {total} but faceVertexIndices has {} entries",
                    indices.len()
                ),
            ));
        }
        if let Some(bad) = indices
            .iter()
            .find(|&&i| i < 0 || i as usize >= points.len())
        {
            return Err(self.error(
                MalformedPart::Mesh,
                at,
                format!(
                    "face vertex index {bad} is out of range ({} points)",
                    points.len()
                ),
            ));
        }
        if !points.iter().all(|p| p.is_finite()) {
            return Err(self.error(MalformedPart::Mesh, at, "points must be finite"));
        }
        Ok(())
    }

    /// The material of each of `faces` faces of `prim`: the mesh's (from `binding` or its own binding), or
    /// that of the `materialBind` subset holding the face.
    fn face_materials(
        &mut self,
        prim: &usd::Prim,
        binding: Option<&str>,
        double_sided: bool,
        faces: usize,
    ) -> Result<Vec<u32>, SceneError> {
        let material = self.material(prim, binding, double_sided, true)?;
        let mut face_material = vec![material; faces];
        for (subset, subset_faces) in self.material_subsets(prim, faces)? {
            let id = self.material(prim, Some(&subset), double_sided, true)?;
            for f in subset_faces {
                face_material[f] = id;
            }
        }
        Ok(face_material)
    }

    /// The colour of each face corner for the materials that read their colour from a primvar (interpolated as
    /// the primvar says, else the reader's fallback), white on the faces of other materials (the vertex colour
    /// multiplies the base colour); `None` when no face's material reads one.
    fn corner_colors(
        &mut self,
        prim: &usd::Prim,
        at: &str,
        topology: &Topology,
        face_material: &[u32],
    ) -> Result<Option<Vec<Rgb>>, SceneError> {
        let corners = topology.indices.len();
        let mut colors: Option<Vec<Rgb>> = None;
        let mut corner = 0usize;
        for (f, &c) in topology.counts.iter().enumerate() {
            let c = c.max(0) as usize;
            if let Some(read) = self.primvar_color(face_material[f]).cloned() {
                let values =
                    match self.primvar(prim, &[read.attribute.as_str()], "constant", vec3_array)? {
                        Some(p) => topology
                            .expand(p)
                            .map_err(|m| self.error(MalformedPart::Mesh, at, m))?,
                        None => vec![read.fallback; corners],
                    };
                colors.get_or_insert_with(|| vec![Rgb::ONE; corners])[corner..corner + c]
                    .copy_from_slice(&values[corner..corner + c]);
            }
            corner += c;
        }
        Ok(colors)
    }

    /// The scheme and level to subdivide the mesh `prim` to, or `None` to render its control cage: none unless
    /// its `subdivisionScheme` is `catmullClark` (USD's default) or `loop`; then `--subdivision-level`, else
    /// the mesh's `refineLevel`, else [`DEFAULT_SUBDIVISION_LEVEL`] (at most [`MAX_SUBDIVISION_LEVEL`]).
    /// `bilinear` is its own cage; a `loop` mesh with faces other than triangles (which Loop's rules do not
    /// cover) and an unknown scheme render the cage with a warning.
    fn subdivision(
        &mut self,
        prim: &usd::Prim,
        at: &str,
        cage: &PolygonMesh,
    ) -> Result<Option<(Scheme, u32)>, SceneError> {
        let name = self
            .value(prim, "subdivisionScheme")?
            .and_then(|v| token(&v))
            .unwrap_or_else(|| "catmullClark".into());
        let scheme = match name.as_str() {
            "catmullClark" => Scheme::CatmullClark,
            "loop" if cage.counts.iter().all(|&c| c == 3) => Scheme::Loop,
            "loop" => {
                self.warn(format!(
                    "{at}: subdivisionScheme 'loop' needs triangles, and the mesh has other polygons; its \
                     control cage is rendered"
                ));
                return Ok(None);
            }
            "none" | "bilinear" => return Ok(None),
            other => {
                self.warn(format!(
                    "{at}: subdivisionScheme '{other}' is not supported; its control cage is rendered"
                ));
                return Ok(None);
            }
        };
        let level = match self.subdivision_level {
            Some(level) => level,
            None => match self.value(prim, "refineLevel")? {
                Some(v) => match number(&v) {
                    Some(l) if l.is_finite() && l >= 0.0 => l as u32,
                    _ => {
                        return Err(self.error(
                            MalformedPart::Mesh,
                            at,
                            "refineLevel must be a whole number of 0 or more",
                        ))
                    }
                },
                None => DEFAULT_SUBDIVISION_LEVEL,
            },
        };
        Ok((level > 0).then_some((scheme, level.min(MAX_SUBDIVISION_LEVEL))))
    }

    /// The Catmull-Clark surface of `cage` at `level`, with the mesh's creases (`creaseIndices`,
    /// `creaseLengths`, `creaseSharpnesses`: one sharpness per crease, or one per crease edge) and corners
    /// (`cornerIndices`, `cornerSharpnesses`). Faces of fewer than 3 vertices are left out; the faces it makes
    /// count against the memory budget before any is made.
    fn subdivide(
        &mut self,
        prim: &usd::Prim,
        at: &str,
        mut cage: PolygonMesh,
        scheme: Scheme,
        level: u32,
    ) -> Result<PolygonMesh, SceneError> {
        if cage.counts.iter().any(|&c| c < 3) {
            cage = without_degenerate_faces(cage);
        }
        let faces = cage.faces_after_with(scheme, level);
        self.limits
            .check_items(
                format_args!(
                    "{at}: {} subdivision to level {level} ({faces} faces)",
                    scheme.name()
                ),
                faces,
                SUBDIVIDED_QUAD_BYTES,
            )
            .map_err(|e| self.error(MalformedPart::Mesh, at, e.to_string()))?;
        let points = cage.points.len();
        let vertex = |i: i32| {
            usize::try_from(i)
                .ok()
                .filter(|&i| i < points)
                .map(|i| i as u32)
        };
        let crease_indices = self.int_array(prim, "creaseIndices")?;
        let crease_lengths = self.int_array(prim, "creaseLengths")?;
        let sharpnesses = self.float_values(prim, "creaseSharpnesses")?;
        let per_edge = sharpnesses.len() != crease_lengths.len();
        let (mut next, mut edge) = (0usize, 0usize);
        for (crease, &length) in crease_lengths.iter().enumerate() {
            let length = usize::try_from(length).unwrap_or(0);
            let chain = crease_indices.get(next..next + length).ok_or_else(|| {
                self.error(
                    MalformedPart::Mesh,
                    at,
                    "creaseLengths sum to more than creaseIndices holds",
                )
            })?;
            next += length;
            for pair in chain.windows(2) {
                let (Some(a), Some(b)) = (vertex(pair[0]), vertex(pair[1])) else {
                    return Err(self.error(
                        MalformedPart::Mesh,
                        at,
                        "a crease index is out of range",
                    ));
                };
                let sharpness = sharpnesses
                    .get(if per_edge { edge } else { crease })
                    .copied()
                    .ok_or_else(|| {
                        self.error(MalformedPart::Mesh, at, "creaseSharpnesses is too short")
                    })?;
                edge += 1;
                cage.creases
                    .insert((a.min(b), a.max(b)), sharpness.max(0.0));
            }
        }
        let corner_indices = self.int_array(prim, "cornerIndices")?;
        let corner_sharpnesses = self.float_values(prim, "cornerSharpnesses")?;
        for (k, &i) in corner_indices.iter().enumerate() {
            let v = vertex(i).ok_or_else(|| {
                self.error(MalformedPart::Mesh, at, "a corner index is out of range")
            })?;
            let s = corner_sharpnesses.get(k).copied().ok_or_else(|| {
                self.error(MalformedPart::Mesh, at, "cornerSharpnesses is too short")
            })?;
            cage.corners.insert(v, s.max(0.0));
        }
        cage.rules = self.subdivision_rules(prim, at)?;
        cage.subdivide_with(scheme, level)
            .map_err(|e| self.error(MalformedPart::Mesh, at, e.to_string()))
    }

    /// The mesh's `interpolateBoundary`, `creaseMethod` and `faceVaryingLinearInterpolation` (USD's defaults
    /// where absent). A value Nimbus does not subdivide by (`interpolateBoundary = "none"`, an unknown token) is
    /// warned about and the default used; `triangleSubdivisionRule = "smooth"` is warned about.
    fn subdivision_rules(
        &mut self,
        prim: &usd::Prim,
        at: &str,
    ) -> Result<SubdivisionRules, SceneError> {
        let mut rules = SubdivisionRules::default();
        if let Some(name) = self
            .value(prim, "interpolateBoundary")?
            .and_then(|v| token(&v))
        {
            match name.as_str() {
                "edgeAndCorner" => rules.boundary = BoundaryRule::EdgeAndCorner,
                "edgeOnly" => rules.boundary = BoundaryRule::EdgeOnly,
                other => self.warn(format!(
                    "{at}: interpolateBoundary '{other}' is not supported; subdivided as edgeAndCorner"
                )),
            }
        }
        if let Some(name) = self.value(prim, "creaseMethod")?.and_then(|v| token(&v)) {
            match name.as_str() {
                "uniform" => rules.crease_method = CreaseMethod::Uniform,
                "chaikin" => rules.crease_method = CreaseMethod::Chaikin,
                other => self.warn(format!(
                    "{at}: creaseMethod '{other}' is not supported; subdivided as uniform"
                )),
            }
        }
        if let Some(name) = self
            .value(prim, "faceVaryingLinearInterpolation")?
            .and_then(|v| token(&v))
        {
            rules.face_varying = match name.as_str() {
                "none" => FaceVaryingRule::None,
                "cornersOnly" => FaceVaryingRule::CornersOnly,
                "cornersPlus1" => FaceVaryingRule::CornersPlus1,
                "cornersPlus2" => FaceVaryingRule::CornersPlus2,
                "boundaries" => FaceVaryingRule::Boundaries,
                "all" => FaceVaryingRule::All,
                other => {
                    self.warn(format!(
                        "{at}: faceVaryingLinearInterpolation '{other}' is not supported; subdivided as \
                         cornersPlus1"
                    ));
                    FaceVaryingRule::CornersPlus1
                }
            };
        }
        if let Some(rule) = self
            .value(prim, "triangleSubdivisionRule")?
            .and_then(|v| token(&v))
        {
            if rule != "catmullClark" {
                self.warn(format!(
                    "{at}: triangleSubdivisionRule '{rule}' is not supported; triangles are subdivided by \
                     Catmull-Clark's rule"
                ));
            }
        }
        Ok(rules)
    }

    /// A `float[]` attribute's values (empty when absent); non-finite values are an error naming it.
    fn float_values(&self, prim: &usd::Prim, name: &str) -> Result<Vec<f32>, SceneError> {
        let at = format!("{}.{name}", prim.path().as_str());
        let values = match self.value(prim, name)? {
            None => return Ok(Vec::new()),
            Some(sdf::Value::FloatVec(v)) => v,
            Some(sdf::Value::DoubleVec(v)) => v.into_iter().map(|x| x as f32).collect(),
            Some(_) => return Err(self.error(MalformedPart::Mesh, &at, "expected a float[]")),
        };
        if values.iter().any(|v| !v.is_finite()) {
            return Err(self.error(MalformedPart::Mesh, &at, "values must be finite"));
        }
        Ok(values)
    }

    /// The `GeomSubset` children of a mesh with `familyName = "materialBind"` and `elementType = "face"`
    /// that bind a material: (material path, face indices). Indices out of range are an error naming the
    /// subset.
    fn material_subsets(
        &self,
        prim: &usd::Prim,
        faces: usize,
    ) -> Result<Vec<(String, Vec<usize>)>, SceneError> {
        let mut subsets = Vec::new();
        for child in self.children(prim)? {
            if self.type_name(&child)? != "GeomSubset" {
                continue;
            }
            let family = self.value(&child, "familyName")?.and_then(|v| token(&v));
            let element = self.value(&child, "elementType")?.and_then(|v| token(&v));
            if family.as_deref() != Some("materialBind")
                || element.as_deref().is_some_and(|e| e != "face")
            {
                continue;
            }
            let Some(material) = self.binding(&child)? else {
                continue;
            };
            let at = child.path().as_str();
            let indices = self
                .int_array(&child, "indices")?
                .into_iter()
                .map(|i| usize::try_from(i).ok().filter(|&i| i < faces).ok_or(i))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|i| {
                    self.error(
                        MalformedPart::Mesh,
                        at,
                        format!("face index {i} is out of range ({faces} faces)"),
                    )
                })?;
            subsets.push((material, indices));
        }
        Ok(subsets)
    }

    pub(super) fn int_array(&self, prim: &usd::Prim, name: &str) -> Result<Vec<i32>, SceneError> {
        match self.value(prim, name)? {
            None => Ok(Vec::new()),
            Some(sdf::Value::IntVec(v)) => Ok(v),
            Some(_) => Err(self.error(
                MalformedPart::Mesh,
                &format!("{}.{name}", prim.path().as_str()),
                "expected an int[]",
            )),
        }
    }

    /// A primvar's values (from the first of `names` authored), its interpolation and its optional indices.
    pub(super) fn primvar<T: Copy>(
        &self,
        prim: &usd::Prim,
        names: &[&str],
        default_interpolation: &str,
        convert: fn(&sdf::Value) -> Option<Vec<T>>,
    ) -> Result<Option<Primvar<T>>, SceneError> {
        for name in names {
            let Some(v) = self.value(prim, name)? else {
                continue;
            };
            let at = format!("{}.{name}", prim.path().as_str());
            let values = convert(&v)
                .ok_or_else(|| self.error(MalformedPart::Mesh, &at, "unexpected value type"))?;
            let attr = prim.attribute(*name);
            let interpolation = attr
                .get_metadata::<sdf::Value>("interpolation")
                .map_err(|e| self.error(MalformedPart::Mesh, &at, format!("{e:#}")))?
                .and_then(|v| token(&v))
                .unwrap_or_else(|| default_interpolation.to_owned());
            let indices = match self.value(prim, &format!("{name}:indices"))? {
                Some(sdf::Value::IntVec(ix)) => Some(ix),
                Some(_) => {
                    return Err(self.error(MalformedPart::Mesh, &at, "indices must be an int[]"))
                }
                None => None,
            };
            let values = match indices {
                Some(ix) => ix
                    .iter()
                    .map(|&i| usize::try_from(i).ok().and_then(|i| values.get(i).copied()))
                    .collect::<Option<Vec<T>>>()
                    .ok_or_else(|| {
                        self.error(MalformedPart::Mesh, &at, "primvar index out of range")
                    })?,
                None => values,
            };
            return Ok(Some(Primvar {
                name: (*name).to_owned(),
                values,
                interpolation,
            }));
        }
        Ok(None)
    }
}

/// A primvar's values after `:indices` were applied, and its interpolation.
pub(super) struct Primvar<T> {
    /// The attribute's name, for messages.
    pub(super) name: String,
    pub(super) values: Vec<T>,
    pub(super) interpolation: String,
}

/// A polygon mesh's topology, for expanding primvars to one value per face corner.
pub(super) struct Topology<'a> {
    pub(super) counts: &'a [i32],
    pub(super) indices: &'a [i32],
    pub(super) points: usize,
}

/// Why a primvar cannot be expanded to one value per face corner.
#[derive(Debug, thiserror::Error)]
pub(super) enum PrimvarError {
    /// Fewer values than the interpolation needs.
    #[error("{name}: {interpolation} interpolation needs {need} values, has {has}")]
    TooFewValues {
        /// The attribute's name.
        name: String,
        /// Its interpolation.
        interpolation: String,
        /// How many values the interpolation needs.
        need: usize,
        /// How many it has.
        has: usize,
    },
    /// An interpolation UsdGeom does not define.
    #[error("{name}: unknown interpolation '{interpolation}'")]
    UnknownInterpolation {
        /// The attribute's name.
        name: String,
        /// The interpolation it names.
        interpolation: String,
    },
}

impl Topology<'_> {
    /// One value per face corner, from any interpolation.
    fn expand<T: Copy>(&self, p: Primvar<T>) -> Result<Vec<T>, PrimvarError> {
        let need = |n: usize| {
            if p.values.len() < n {
                Err(PrimvarError::TooFewValues {
                    name: p.name.clone(),
                    interpolation: p.interpolation.clone(),
                    need: n,
                    has: p.values.len(),
                })
            } else {
                Ok(())
            }
        };
        match p.interpolation.as_str() {
            "constant" => {
                need(1)?;
                Ok(vec![p.values[0]; self.indices.len()])
            }
            "uniform" => {
                need(self.counts.len())?;
                Ok(self
                    .counts
                    .iter()
                    .enumerate()
                    .flat_map(|(f, &c)| std::iter::repeat_n(p.values[f], c.max(0) as usize))
                    .collect())
            }
            "faceVarying" => {
                need(self.indices.len())?;
                Ok(p.values[..self.indices.len()].to_vec())
            }
            "vertex" | "varying" => {
                need(self.points)?;
                Ok(self.indices.iter().map(|&i| p.values[i as usize]).collect())
            }
            _ => Err(PrimvarError::UnknownInterpolation {
                name: p.name,
                interpolation: p.interpolation,
            }),
        }
    }
}

/// `mesh` without its faces of fewer than 3 vertices (and their face-varying data).
fn without_degenerate_faces(mesh: PolygonMesh) -> PolygonMesh {
    let mut out = PolygonMesh {
        points: mesh.points,
        uvs: mesh.uvs.as_ref().map(|_| Vec::new()),
        colors: mesh.colors.as_ref().map(|_| Vec::new()),
        ..Default::default()
    };
    let mut start = 0usize;
    for (f, &c) in mesh.counts.iter().enumerate() {
        let corners = start..start + c as usize;
        start += c as usize;
        if c < 3 {
            continue;
        }
        out.counts.push(c);
        out.face_tags.push(mesh.face_tags[f]);
        out.indices
            .extend_from_slice(&mesh.indices[corners.clone()]);
        if let (Some(all), Some(own)) = (&mesh.uvs, &mut out.uvs) {
            own.extend_from_slice(&all[corners.clone()]);
        }
        if let (Some(all), Some(own)) = (&mesh.colors, &mut out.colors) {
            own.extend_from_slice(&all[corners]);
        }
    }
    out
}

/// A polygon surface as triangle meshes, one per material (face tag), with one vertex per face corner: simple,
/// and right for every interpolation. Faces are fanned from their first corner (reversed when `left_handed`);
/// `normals` are per corner (or empty), colours are clamped to [0, 1].
fn meshes_per_material(
    name: &str,
    surface: &PolygonMesh,
    normals: &[crate::math::Vec3],
    left_handed: bool,
) -> Vec<Mesh> {
    let mut starts = Vec::with_capacity(surface.counts.len());
    let mut start = 0usize;
    for &c in &surface.counts {
        starts.push(start);
        start += c as usize;
    }
    let mut groups: Vec<u32> = surface.face_tags.clone();
    groups.sort_unstable();
    groups.dedup();
    let mut meshes = Vec::with_capacity(groups.len());
    for &group in &groups {
        let mut mesh = Mesh {
            name: name.to_owned(),
            material: group,
            uvs: surface.uvs.as_ref().map(|_| Vec::new()),
            colors: surface.colors.as_ref().map(|_| Vec::new()),
            ..Default::default()
        };
        for (f, &c) in surface.counts.iter().enumerate() {
            if surface.face_tags[f] != group {
                continue;
            }
            let (from, c) = (starts[f], c as usize);
            let base = mesh.positions.len() as u32;
            let corners = from..from + c;
            mesh.positions.extend(
                surface.indices[corners.clone()]
                    .iter()
                    .map(|&i| surface.points[i as usize]),
            );
            if !normals.is_empty() {
                mesh.normals.extend_from_slice(&normals[corners.clone()]);
            }
            if let (Some(all), Some(own)) = (&surface.colors, &mut mesh.colors) {
                own.extend(
                    all[corners.clone()]
                        .iter()
                        .map(|c| c.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0)),
                );
            }
            if let (Some(all), Some(own)) = (&surface.uvs, &mut mesh.uvs) {
                own.extend_from_slice(&all[corners]);
            }
            for k in 2..c as u32 {
                let tri = [base, base + k - 1, base + k];
                mesh.indices.push(if left_handed {
                    [tri[0], tri[2], tri[1]]
                } else {
                    tri
                });
            }
        }
        meshes.push(mesh);
    }
    meshes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primvars_expand_to_face_corners() {
        let topo = Topology {
            counts: &[3, 4],
            indices: &[0, 1, 2, 0, 2, 3, 4],
            points: 5,
        };
        let uniform = Primvar {
            name: "p".into(),
            values: vec![1, 2],
            interpolation: "uniform".into(),
        };
        assert_eq!(topo.expand(uniform).unwrap(), [1, 1, 1, 2, 2, 2, 2]);
        let vertex = Primvar {
            name: "p".into(),
            values: vec![10, 11, 12, 13, 14],
            interpolation: "vertex".into(),
        };
        assert_eq!(topo.expand(vertex).unwrap(), [10, 11, 12, 10, 12, 13, 14]);
        let short = Primvar {
            name: "p".into(),
            values: vec![1, 2],
            interpolation: "faceVarying".into(),
        };
        assert!(topo.expand(short).is_err());
    }
}
