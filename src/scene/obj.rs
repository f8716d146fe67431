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

use super::{LoadOptions, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::Mesh;
use crate::material::Material;
use crate::math::{Rgb, Vec2, Vec3};
use std::path::Path;

/// Loads an `.obj` file and its `.mtl` libraries. OBJ has no volumes, so `options` change nothing.
pub fn load(path: &Path, _options: &LoadOptions) -> Result<SceneBuilder, SceneError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let (models, materials) = tobj::load_obj(path, &options)
        .map_err(|e| SceneError::new(path, SceneErrorKind::Malformed(e.to_string())))?;
    let mut builder = SceneBuilder::default();
    let materials = materials.unwrap_or_else(|e| {
        builder.warnings.push(format!(
            "{}: material library: {e}; using defaults",
            path.display()
        ));
        Vec::new()
    });
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
                        model.name
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
                    model.name
                )),
            ));
        }
        builder.add_mesh(mesh);
    }
    Ok(builder)
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
