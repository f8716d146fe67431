//! The perspective pinhole camera (glTF `camera.perspective`: `yfov` vertical field of view, `aspectRatio`).
//! The camera looks down its local −Z axis with +Y up, as in glTF.

use crate::math::{Aabb, Mat4, Ray, Vec2, Vec3};

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera-to-world matrix (rigid; scale is removed by the loader).
    pub camera_to_world: Mat4,
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Width / height from the scene file, used when the user gives only a width.
    pub aspect_ratio: Option<f32>,
}

impl Camera {
    /// A camera at `eye` looking at `target` with +Y up.
    pub fn look_at(eye: Vec3, target: Vec3, yfov: f32) -> Self {
        let up = if (target - eye).normalize_or_zero().cross(Vec3::Y).length() < 1e-4 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        Self {
            camera_to_world: Mat4::look_at_rh(eye, target, up).inverse(),
            yfov,
            aspect_ratio: None,
        }
    }

    /// A default camera framing `bounds` from the +Z side, slightly above, with a 40° vertical field of view.
    pub fn framing(bounds: &Aabb) -> Self {
        let yfov = 40f32.to_radians();
        if bounds.is_empty() {
            return Self::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, yfov);
        }
        let center = bounds.center();
        let radius = super::bounding_radius(bounds);
        let distance = radius / (yfov * 0.5).sin() * 1.05;
        let dir = Vec3::new(0.0, 0.25, 1.0).normalize();
        Self::look_at(center + dir * distance, center, yfov)
    }

    /// A camera-to-world matrix from a scene node's world matrix: its scale and shear removed, its rotation
    /// (the x axis, then the y axis made orthogonal to it) and position kept.
    pub fn rigid(m: &Mat4) -> Mat4 {
        let x = m.x_axis.truncate().normalize_or(Vec3::X);
        let y0 = m.y_axis.truncate();
        let z = x.cross(y0).normalize_or(Vec3::Z);
        let y = z.cross(x);
        Mat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), m.w_axis)
    }

    /// World position of the pinhole.
    pub fn position(&self) -> Vec3 {
        self.camera_to_world.transform_point3(Vec3::ZERO)
    }

    /// The angle one pixel of an image `height` pixels high subtends at the image centre: the spread angle of
    /// camera ray cones, `atan(2·tan(yfov/2) / height)` (Akenine-Möller et al. 2021, "Improved Shader and Texture
    /// Level of Detail Using Ray Cones", JCGT 10(1), §3).
    pub fn pixel_spread_angle(&self, height: usize) -> f32 {
        let spread = (2.0 * (self.yfov * 0.5).tan() / height.max(1) as f32).atan();
        if spread.is_finite() {
            spread
        } else {
            0.0
        }
    }

    /// The primary ray through film position `film` in \[0,1\]² ((0,0) = top-left) for an image of `aspect`
    /// = width / height.
    pub fn generate_ray(&self, film: Vec2, aspect: f32) -> Ray {
        let tan_half = (self.yfov * 0.5).tan();
        let x = (2.0 * film.x - 1.0) * tan_half * aspect;
        let y = (1.0 - 2.0 * film.y) * tan_half;
        let dir = self
            .camera_to_world
            .transform_vector3(Vec3::new(x, y, -1.0))
            .normalize();
        Ray::new(self.position(), dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_the_target_and_corners_span_the_fov() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 90f32.to_radians());
        let r = cam.generate_ray(Vec2::splat(0.5), 1.0);
        assert!(
            r.dir.distance(-Vec3::Z) < 1e-6 && r.origin.distance(Vec3::new(0.0, 0.0, 5.0)) < 1e-6
        );
        let top = cam.generate_ray(Vec2::new(0.5, 0.0), 1.0);
        assert!(
            (top.dir.y - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5,
            "top edge is +45°: {:?}",
            top.dir
        );
    }
}
