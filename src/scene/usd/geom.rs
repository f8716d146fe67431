//! USD geometry: `Mesh` prims (points, face topology, normals and `st` primvars with their interpolation).

use super::values::{token, vec2_array, vec3_array};
use super::Loader;
use crate::geometry::Mesh;
use crate::math::{Mat4, Rgb, Vec2};
use crate::scene::SceneError;
use openusd::{sdf, usd};

impl Loader<'_> {
    pub(super) fn mesh(
        &mut self,
        prim: &usd::Prim,
        world: &Mat4,
        binding: Option<&str>,
    ) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let points = match self.value(prim, "points")? {
            Some(v) => {
                vec3_array(&v).ok_or_else(|| self.error(&at, "points must be a point3f[]"))?
            }
            None => return Ok(()),
        };
        let counts = self.int_array(prim, "faceVertexCounts")?;
        let indices = self.int_array(prim, "faceVertexIndices")?;
        let total: usize = counts.iter().map(|&c| c.max(0) as usize).sum();
        if total != indices.len() {
            return Err(self.error(
                &at,
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
                &at,
                format!(
                    "face vertex index {bad} is out of range ({} points)",
                    points.len()
                ),
            ));
        }
        if !points.iter().all(|p| p.is_finite()) {
            return Err(self.error(&at, "points must be finite"));
        }
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
            .map_err(|m| self.error(&at, m))?;
        let uvs = uvs
            .map(|p| topology.expand(p))
            .transpose()
            .map_err(|m| self.error(&at, m))?;
        let left_handed = self
            .value(prim, "orientation")?
            .and_then(|v| token(&v))
            .is_some_and(|o| o == "leftHanded");
        let double_sided = self
            .value(prim, "doubleSided")?
            .is_some_and(|v| matches!(v, sdf::Value::Bool(true)));
        let material = self.material(prim, binding, double_sided, true)?;
        // The material of each face: the mesh's, or that of the `materialBind` subset holding the face.
        let mut face_material = vec![material; counts.len()];
        for (subset, faces) in self.material_subsets(prim, counts.len())? {
            let id = self.material(prim, Some(&subset), double_sided, true)?;
            for f in faces {
                face_material[f] = id;
            }
        }
        let uvs = uvs.map(|st| {
            st.into_iter()
                .map(|t: Vec2| Vec2::new(t.x, 1.0 - t.y))
                .collect::<Vec<_>>()
        });
        let normals = normals.unwrap_or_default();
        // One mesh per material, one vertex per face corner: simple, and right for every interpolation.
        let mut starts = Vec::with_capacity(counts.len());
        let mut start = 0usize;
        for &c in &counts {
            starts.push(start);
            start += c.max(0) as usize;
        }
        let mut groups: Vec<u32> = face_material.clone();
        groups.sort_unstable();
        groups.dedup();
        for &group in &groups {
            // A material that reads its colour from a primvar: one colour per face corner.
            let colors = match self.primvar_color(group).cloned() {
                Some(read) => Some(
                    match self.primvar(prim, &[read.attribute.as_str()], "constant", vec3_array)? {
                        Some(p) => topology.expand(p).map_err(|m| self.error(&at, m))?,
                        None => vec![read.fallback; indices.len()],
                    },
                ),
                None => None,
            };
            let mut mesh = Mesh {
                name: at.clone(),
                material: group,
                uvs: uvs.as_ref().map(|_| Vec::new()),
                colors: colors.as_ref().map(|_| Vec::new()),
                ..Default::default()
            };
            for (f, &c) in counts.iter().enumerate() {
                if face_material[f] != group {
                    continue;
                }
                let (from, c) = (starts[f], c.max(0) as usize);
                let base = mesh.positions.len() as u32;
                let corners = from..from + c;
                mesh.positions
                    .extend(indices[corners.clone()].iter().map(|&i| points[i as usize]));
                if !normals.is_empty() {
                    mesh.normals.extend_from_slice(&normals[corners.clone()]);
                }
                if let (Some(all), Some(own)) = (&colors, &mut mesh.colors) {
                    own.extend(
                        all[corners.clone()]
                            .iter()
                            .map(|c| c.clamp(Rgb::ZERO, Rgb::ONE).extend(1.0)),
                    );
                }
                if let (Some(all), Some(own)) = (&uvs, &mut mesh.uvs) {
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
            mesh.transform(world);
            self.add_mesh(mesh)?;
        }
        Ok(())
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
            let values = convert(&v).ok_or_else(|| self.error(&at, "unexpected value type"))?;
            let attr = prim.attribute(*name);
            let interpolation = attr
                .get_metadata::<sdf::Value>("interpolation")
                .map_err(|e| self.error(&at, format!("{e:#}")))?
                .and_then(|v| token(&v))
                .unwrap_or_else(|| default_interpolation.to_owned());
            let indices = match self.value(prim, &format!("{name}:indices"))? {
                Some(sdf::Value::IntVec(ix)) => Some(ix),
                Some(_) => return Err(self.error(&at, "indices must be an int[]")),
                None => None,
            };
            let values = match indices {
                Some(ix) => ix
                    .iter()
                    .map(|&i| usize::try_from(i).ok().and_then(|i| values.get(i).copied()))
                    .collect::<Option<Vec<T>>>()
                    .ok_or_else(|| self.error(&at, "primvar index out of range"))?,
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

impl Topology<'_> {
    /// One value per face corner, from any interpolation.
    fn expand<T: Copy>(&self, p: Primvar<T>) -> Result<Vec<T>, String> {
        let need = |n: usize| {
            if p.values.len() < n {
                Err(format!(
                    "{}: {} interpolation needs {n} values, has {}",
                    p.name,
                    p.interpolation,
                    p.values.len()
                ))
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
            other => Err(format!("{}: unknown interpolation '{other}'", p.name)),
        }
    }
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
