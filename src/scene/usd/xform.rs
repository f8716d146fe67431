//! USD xform ops: `xformOpOrder` and each op's matrix (UsdGeomXformable).

use super::values::{number, tokens, vec3};
use super::Loader;
use crate::math::{Mat4, Quat};
use crate::scene::MalformedPart;
use crate::scene::SceneError;
use openusd::{sdf, usd};

impl Loader<'_> {
    /// The prim's local matrix from its `xformOpOrder`, and whether it resets the parent's transform.
    pub(super) fn local_transform(&self, prim: &usd::Prim) -> Result<(Mat4, bool), SceneError> {
        let at = prim.path().as_str();
        let Some(order) = self.value(prim, "xformOpOrder")? else {
            return Ok((Mat4::IDENTITY, false));
        };
        let ops = tokens(&order).ok_or_else(|| {
            self.error(
                MalformedPart::Node,
                at,
                "xformOpOrder must be a token array",
            )
        })?;
        let mut m = Mat4::IDENTITY;
        let mut reset = false;
        for op in ops {
            if op == "!resetXformStack!" {
                (m, reset) = (Mat4::IDENTITY, true);
                continue;
            }
            let (name, invert) = match op.strip_prefix("!invert!") {
                Some(n) => (n, true),
                None => (op.as_str(), false),
            };
            let value = self.value(prim, name)?.ok_or_else(|| {
                self.error(
                    MalformedPart::Node,
                    at,
                    format!("xformOp '{name}' has no value"),
                )
            })?;
            let op_kind = name.split(':').nth(1).unwrap_or("");
            let mut op_m = xform_op(op_kind, &value).ok_or_else(|| {
                self.error(
                    MalformedPart::Node,
                    at,
                    format!("unsupported or malformed xformOp '{name}'"),
                )
            })?;
            if invert {
                op_m = op_m.inverse();
            }
            m *= op_m;
        }
        Ok((m, reset))
    }
}

/// The matrix of one xform op (`op` is the op type, e.g. `rotateXYZ`), or `None` for an unknown op or a
/// value of the wrong type.
pub(super) fn xform_op(op: &str, value: &sdf::Value) -> Option<Mat4> {
    let rot = |axis: char, degrees: f32| {
        let a = degrees.to_radians();
        match axis {
            'X' => Mat4::from_rotation_x(a),
            'Y' => Mat4::from_rotation_y(a),
            _ => Mat4::from_rotation_z(a),
        }
    };
    match op {
        "translate" | "pivot" => Some(Mat4::from_translation(vec3(value)?)),
        "scale" => Some(Mat4::from_scale(vec3(value)?)),
        "rotateX" | "rotateY" | "rotateZ" => Some(rot(op.chars().last()?, number(value)? as f32)),
        "orient" => {
            let q = match value {
                sdf::Value::Quatf(q) => Quat::from_xyzw(q.x, q.y, q.z, q.w),
                sdf::Value::Quatd(q) => {
                    Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32)
                }
                sdf::Value::Quath(q) => {
                    Quat::from_xyzw(q.x.to_f32(), q.y.to_f32(), q.z.to_f32(), q.w.to_f32())
                }
                _ => return None,
            };
            let len = q.length();
            (len.is_finite() && len > 0.0).then(|| Mat4::from_quat(q / len))
        }
        "transform" => match value {
            // USD matrices are row-major for row vectors: the same memory layout as glam's column-major.
            sdf::Value::Matrix4d(m) => Some(Mat4::from_cols_array(&m.0.map(|x| x as f32))),
            _ => None,
        },
        _ => {
            let axes = op.strip_prefix("rotate")?;
            if axes.len() != 3 || !axes.chars().all(|c| matches!(c, 'X' | 'Y' | 'Z')) {
                return None;
            }
            // The value holds the angles by axis, (x, y, z), whatever the order; rotateABC rotates about A
            // first, then B, then C (UsdGeomXformOp), so its matrix is R_C · R_B · R_A for column vectors.
            let angles = vec3(value)?;
            let mut m = Mat4::IDENTITY;
            for axis in axes.chars() {
                let by_axis = match axis {
                    'X' => angles.x,
                    'Y' => angles.y,
                    _ => angles.z,
                };
                m = rot(axis, by_axis) * m;
            }
            Some(m)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// All six three-axis orders against matrices composed by hand from single-axis rotations: rotateABC with
    /// value (x, y, z) is R_C(angle of C) · R_B(angle of B) · R_A(angle of A), angles taken by axis.
    #[test]
    fn three_axis_rotations_take_angles_by_axis() {
        let (x, y, z) = (30.0f32, -50.0f32, 70.0f32);
        let v = sdf::Value::Vec3f([x, y, z].into());
        let rx = Mat4::from_rotation_x(x.to_radians());
        let ry = Mat4::from_rotation_y(y.to_radians());
        let rz = Mat4::from_rotation_z(z.to_radians());
        for (op, expected) in [
            ("rotateXYZ", rz * ry * rx),
            ("rotateXZY", ry * rz * rx),
            ("rotateYXZ", rz * rx * ry),
            ("rotateYZX", rx * rz * ry),
            ("rotateZXY", ry * rx * rz),
            ("rotateZYX", rx * ry * rz),
        ] {
            let m = xform_op(op, &v).unwrap();
            for p in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(0.3, -0.7, 1.1)] {
                let (got, want) = (m.transform_point3(p), expected.transform_point3(p));
                assert!(got.distance(want) < 1e-5, "{op}: {got} vs {want}");
            }
        }
        // One worked case: rotateXYZ (90, 90, 0) takes +Y by X to +Z, then by Y to +X.
        let m = xform_op("rotateXYZ", &sdf::Value::Vec3f([90.0, 90.0, 0.0].into())).unwrap();
        assert!(m.transform_vector3(Vec3::Y).distance(Vec3::X) < 1e-6);
        assert!(xform_op("rotateXYW", &v).is_none());
        assert!(xform_op("translate", &sdf::Value::Float(1.0)).is_none());
    }

    #[test]
    fn usd_matrices_keep_translation_in_the_last_row() {
        let mut a = [0.0f64; 16];
        for i in 0..4 {
            a[i * 5] = 1.0;
        }
        a[12..15].copy_from_slice(&[1.0, 2.0, 3.0]);
        let v = sdf::Value::Matrix4d(openusd::gf::Matrix4d(a));
        let m = xform_op("transform", &v).unwrap();
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(1.0, 2.0, 3.0));
    }
}
