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

    /// The default camera for a scene without one: a 40° vertical field of view, looking at `bounds` from the
    /// direction in which they show the most area, and as close as fits them.
    ///
    /// Direction: a box of extents (a, b, c) seen along the unit direction d covers a projected area of
    /// |dₓ|·bc + |d_y|·ac + |d_z|·ab, which is largest for d ∝ (bc, ac, ab) (Cauchy–Schwarz). So planar content
    /// is seen face-on (a quad in the YZ plane from +X), a thin slab nearly so, a cube in a three-quarter view
    /// from the +X, +Y, +Z octant, and an elongated box from its long side; a segment or a point, which shows
    /// no area, is seen from the front, slightly right and above.
    ///
    /// Distance: the nearest at which every corner of the box lies within the field of view (with a 5 % margin)
    /// in both directions at an aspect ratio of 1, so the bounds are fitted tightly in any image at least as wide
    /// as it is tall (a portrait image may cut the sides).
    pub fn framing(bounds: &Aabb) -> Self {
        let yfov = 40f32.to_radians();
        if bounds.is_empty() {
            return Self::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, yfov);
        }
        let e = bounds.extent();
        let areas = Vec3::new(e.y * e.z, e.x * e.z, e.x * e.y);
        let front = Vec3::new(0.35, 0.25, 1.0);
        // Areas are relative to the largest face; the front direction only decides where they all vanish.
        let dir = (areas / areas.max_element().max(f32::MIN_POSITIVE) + front * 1e-3).normalize();
        let center = bounds.center();
        // Seen from (nearly) straight above or below, the image's up is −Z: the far side of the scene at the top,
        // as when a camera in front tilts down.
        let up = if dir.y.abs() > 0.9 { -Vec3::Z } else { Vec3::Y };
        let world_to_camera = Mat4::look_at_rh(center + dir, center, up);
        // Tangent of the half field of view, less a 5 % margin.
        let tan_half = (yfov * 0.5).tan() / 1.05;
        // The camera sits at `center + dir · distance`; a corner at camera-space (x, y, z) relative to the
        // centre is at depth distance − z, inside the view when |x|, |y| ≤ tan_half · depth.
        let mut distance = 0f32;
        let radius = super::bounding_radius(bounds);
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 {
                    bounds.min.x
                } else {
                    bounds.max.x
                },
                if i & 2 == 0 {
                    bounds.min.y
                } else {
                    bounds.max.y
                },
                if i & 4 == 0 {
                    bounds.min.z
                } else {
                    bounds.max.z
                },
            );
            let q = world_to_camera.transform_vector3(corner - center);
            // q.z is toward the camera (the camera looks down −Z).
            let needed = q.z + q.x.abs().max(q.y.abs()) / tan_half;
            distance = distance.max(needed);
        }
        // Stay outside the bounds by a hair (a point or a segment end-on needs a positive distance).
        let distance = distance.max(radius * 1e-2);
        let eye = center + dir * distance;
        Self {
            camera_to_world: Mat4::look_at_rh(eye, center, up).inverse(),
            yfov,
            aspect_ratio: None,
        }
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
