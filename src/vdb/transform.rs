//! Grid transforms: the OpenVDB linear maps, composed into one index-to-world matrix.
//!
//! OpenVDB stores matrices for row vectors (`world = [i j k 1] · M`); [`Transform::index_to_world`] is the
//! transpose, for column vectors (`world = M · [i j k 1]ᵀ`) as glam uses.

use super::error::{KResult, VdbErrorKind};
use super::stream::Reader;
use glam::{DMat4, DVec3, DVec4};

/// A grid's index-to-world transform.
#[derive(Clone, Debug, PartialEq)]
pub struct Transform {
    /// The OpenVDB map type name, e.g. `UniformScaleMap`.
    pub map_type: String,
    /// Index-to-world matrix, column-vector convention (translation in the last column).
    pub index_to_world: DMat4,
}

impl Transform {
    /// Length in world units of one voxel step along each index axis.
    pub fn voxel_size(&self) -> DVec3 {
        let m = &self.index_to_world;
        DVec3::new(
            m.x_axis.truncate().length(),
            m.y_axis.truncate().length(),
            m.z_axis.truncate().length(),
        )
    }
}

/// Builds the column-vector matrix `x ↦ scale ⊙ x + translation`.
pub fn scale_translate(scale: DVec3, translation: DVec3) -> DMat4 {
    DMat4::from_cols(
        DVec4::new(scale.x, 0.0, 0.0, 0.0),
        DVec4::new(0.0, scale.y, 0.0, 0.0),
        DVec4::new(0.0, 0.0, scale.z, 0.0),
        translation.extend(1.0),
    )
}

/// Converts a row-major OpenVDB (row-vector) 4×4 matrix to a column-vector `DMat4`.
pub fn from_openvdb_rows(m: [f64; 16]) -> DMat4 {
    // Row r of the OpenVDB matrix multiplies component r of the row vector, so it is column r here.
    DMat4::from_cols_array(&m)
}

/// Reads a transform: the map type name, then that map's fields.
pub(crate) fn read_transform(r: &mut Reader<'_>) -> KResult<Transform> {
    let map_type = r.string("map type")?;
    let m = match map_type.as_str() {
        "UniformScaleMap" | "ScaleMap" => {
            let scale = r.dvec3("map scale")?;
            // voxel size, inverse scale, inverse scale squared, inverse twice scale (derived, skipped)
            r.take(4 * 24, "map derived values")?;
            scale_translate(scale, DVec3::ZERO)
        }
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let translation = r.dvec3("map translation")?;
            let scale = r.dvec3("map scale")?;
            r.take(4 * 24, "map derived values")?;
            scale_translate(scale, translation)
        }
        "TranslationMap" => scale_translate(DVec3::ONE, r.dvec3("map translation")?),
        "AffineMap" | "UnitaryMap" => {
            let mut a = [0.0; 16];
            for v in a.iter_mut() {
                *v = r.f64("affine matrix")?;
            }
            from_openvdb_rows(a)
        }
        _ => return Err(VdbErrorKind::UnsupportedMap(map_type)),
    };
    if !m.is_finite() || m.determinant().abs() < 1e-300 {
        return Err(VdbErrorKind::Corrupt(format!(
            "{map_type} matrix is singular or not finite"
        )));
    }
    Ok(Transform {
        map_type,
        index_to_world: m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn composition_and_conventions() {
        let m = scale_translate(DVec3::new(0.1, 0.2, 0.5), DVec3::new(1.0, 2.0, 3.0));
        let p = m.transform_point3(DVec3::new(10.0, 10.0, 10.0));
        assert!((p - DVec3::new(2.0, 4.0, 8.0)).length() < 1e-12);
        // Row-vector matrix with translation in the last row becomes a column-vector matrix.
        let rows = [
            0.0, 1.0, 0.0, 0.0, //
            -1.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 2.0, 0.0, //
            5.0, 6.0, 7.0, 1.0,
        ];
        let a = from_openvdb_rows(rows);
        // [1 0 0 1]·M = row0 + row3
        let p = a.transform_point3(DVec3::X);
        assert!((p - DVec3::new(5.0, 7.0, 7.0)).length() < 1e-12);
        let t = Transform {
            map_type: "AffineMap".into(),
            index_to_world: a,
        };
        let back = t.index_to_world.inverse().transform_point3(p);
        assert!((back - DVec3::X).length() < 1e-12);
        assert!((t.voxel_size() - DVec3::new(1.0, 1.0, 2.0)).length() < 1e-12);
    }

    #[test]
    fn frustum_is_an_error() {
        let mut v = 19u32.to_le_bytes().to_vec();
        v.extend_from_slice(b"NonlinearFrustumMap");
        assert!(matches!(
            read_transform(&mut Reader::new(&v)),
            Err(VdbErrorKind::UnsupportedMap(_))
        ));
    }
}
