//! The perspective pinhole camera (glTF `camera.perspective`: `yfov` vertical field of view, `aspectRatio`).
//! The camera looks down its local −Z axis with +Y up, as in glTF.
//!
//! Camera motion blur: a camera that moves across the shutter carries its rigid poses at the motion steps
//! ([`CameraMotion`]); a ray at time `t` starts from the pose between the two steps around `t`, its position
//! interpolated linearly and its rotation by slerp ([`Camera::generate_ray_at`]).

use crate::geometry::MotionSteps;
use crate::math::{Aabb, Mat4, Quat, Ray, Vec2, Vec3};

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera-to-world matrix (rigid; scale is removed by the loader).
    pub camera_to_world: Mat4,
    /// Vertical field of view in radians.
    pub yfov: f32,
    /// Width / height from the scene file, used when the user gives only a width.
    pub aspect_ratio: Option<f32>,
    /// The camera's poses across the shutter when it moves (camera motion blur); `None` for a still camera,
    /// which is at `camera_to_world` at every time.
    pub motion: Option<CameraMotion>,
}

/// A moving camera's rigid poses at its motion steps.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraMotion {
    /// When the poses are.
    pub steps: MotionSteps,
    /// The position and rotation of the camera-to-world transform at each step.
    pub poses: Vec<(Vec3, Quat)>,
}

impl CameraMotion {
    /// The poses of rigid camera-to-world matrices (see [`Camera::rigid`]) at `steps`.
    pub fn from_matrices(steps: MotionSteps, matrices: &[Mat4]) -> Self {
        let poses = matrices
            .iter()
            .map(|m| (m.w_axis.truncate(), Quat::from_mat4(m).normalize()))
            .collect();
        Self { steps, poses }
    }

    /// The camera-to-world matrix at `time`: the position lerped and the rotation slerped (along the shorter
    /// arc) between the poses around it; held at the end poses outside the steps.
    pub fn camera_to_world_at(&self, time: f32) -> Mat4 {
        let (i, f) = self.steps.segment(time);
        let ((p0, q0), (p1, q1)) = (self.poses[i], self.poses[i + 1]);
        Mat4::from_rotation_translation(q0.slerp(q1, f), p0.lerp(p1, f))
    }

    /// Whether every pose is finite, and there is one per step (at least two).
    pub fn is_valid(&self) -> bool {
        self.steps.count >= 2
            && self.poses.len() == self.steps.count as usize
            && self.steps.open.is_finite()
            && self.steps.close.is_finite()
            && self.steps.open <= self.steps.close
            && self
                .poses
                .iter()
                .all(|(p, q)| p.is_finite() && q.is_finite() && q.length() > 0.5)
    }
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
            motion: None,
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
            motion: None,
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
        self.ray_from(&self.camera_to_world, film, aspect)
    }

    /// The primary ray through `film` (as [`Self::generate_ray`]) at `time` (frames from the frame): from the
    /// camera's pose at that time when it moves ([`CameraMotion::camera_to_world_at`]), else from its one
    /// pose; the ray carries the time.
    pub fn generate_ray_at(&self, film: Vec2, aspect: f32, time: f32) -> Ray {
        match &self.motion {
            Some(m) => self.ray_from(&m.camera_to_world_at(time), film, aspect),
            None => self.generate_ray(film, aspect),
        }
        .at_time(time)
    }

    /// The film position in \[0,1\]² ((0,0) = top-left, as [`Self::generate_ray`] takes it) where the camera
    /// sees `p_camera`, a point in camera space (see [`Self::to_camera_space`]) in front of the camera
    /// (`z < 0`); `None` for a point on or behind the camera plane. The inverse of [`Self::generate_ray`]:
    /// positions outside \[0,1\]² are outside the image.
    pub fn film_position(&self, p_camera: Vec3, aspect: f32) -> Option<Vec2> {
        if p_camera.z.is_nan() || p_camera.z >= 0.0 {
            return None;
        }
        let tan_half = (self.yfov * 0.5).tan();
        let x = p_camera.x / -p_camera.z / (tan_half * aspect);
        let y = p_camera.y / -p_camera.z / tan_half;
        Some(Vec2::new(0.5 * (x + 1.0), 0.5 * (1.0 - y)))
    }

    /// OpenEXR's standard attribute `worldToCamera` for this (still) camera: the matrix that takes a world point
    /// to the renderer's camera space, in OpenEXR's convention: row vectors (`[x y z 1] · M`), camera at the
    /// origin, +x right and +y up in the image, +z the viewing direction (a left-handed space), as OpenEXR's
    /// "Standard Attributes" define it and Nuke reads it.
    pub fn exr_world_to_camera(&self) -> [[f32; 4]; 4] {
        let flip_z = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        // glam's columns of the column-vector matrix are the rows of OpenEXR's row-vector one.
        (flip_z * self.camera_to_world.inverse()).to_cols_array_2d()
    }

    /// OpenEXR's standard attribute `worldToNDC` for an image of `aspect` = width / height: with
    /// `[X Y Z W] = [x y z 1] · M`, (X/W, Y/W) is where the world point lands on the image, (0, 0) its top-left
    /// corner and (1, 1) its bottom-right (OpenEXR's normalised device coordinates of the display window);
    /// Z/W is 1/depth along the view.
    pub fn exr_world_to_ndc(&self, aspect: f32) -> [[f32; 4]; 4] {
        let tan_y = (self.yfov * 0.5).tan();
        let tan_x = tan_y * aspect;
        // On OpenEXR camera space (column vectors): X = z/2 + x/(2 tan_x), Y = z/2 − y/(2 tan_y), Z = 1, W = z.
        let projection = Mat4::from_cols_array_2d(&[
            [0.5 / tan_x, 0.0, 0.0, 0.0],
            [0.0, -0.5 / tan_y, 0.0, 0.0],
            [0.5, 0.5, 0.0, 1.0],
            [0.0, 0.0, 1.0, 0.0],
        ]);
        let flip_z = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        (projection * flip_z * self.camera_to_world.inverse()).to_cols_array_2d()
    }

    /// `p` (world space) in the still camera's space: the camera at the origin looking down −Z, +Y up.
    pub fn to_camera_space(&self, p: Vec3) -> Vec3 {
        self.camera_to_world.inverse().transform_point3(p)
    }

    /// The ray through `film` for the camera-to-world matrix `to_world`.
    fn ray_from(&self, to_world: &Mat4, film: Vec2, aspect: f32) -> Ray {
        let tan_half = (self.yfov * 0.5).tan();
        let x = (2.0 * film.x - 1.0) * tan_half * aspect;
        let y = (1.0 - 2.0 * film.y) * tan_half;
        let dir = to_world
            .transform_vector3(Vec3::new(x, y, -1.0))
            .normalize();
        Ray::new(to_world.transform_point3(Vec3::ZERO), dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_matrices_put_points_where_the_camera_sees_them() {
        let cam = Camera::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::new(-0.5, 0.3, 0.0), 0.7);
        let aspect = 1.6;
        let row = |m: [[f32; 4]; 4], p: Vec3| -> [f32; 4] {
            // Row vector times matrix: out[j] = Σ_i p[i] m[i][j] (m row-major).
            let v = [p.x, p.y, p.z, 1.0];
            std::array::from_fn(|j| (0..4).map(|i| v[i] * m[i][j]).sum())
        };
        for p in [
            Vec3::new(-0.5, 0.3, 0.0),
            Vec3::new(0.4, -0.2, 1.0),
            Vec3::new(-1.5, 1.0, -2.0),
        ] {
            let film = cam.film_position(cam.to_camera_space(p), aspect).unwrap();
            let ndc = row(cam.exr_world_to_ndc(aspect), p);
            assert!((ndc[0] / ndc[3] - film.x).abs() < 1e-4, "{ndc:?} {film}");
            assert!((ndc[1] / ndc[3] - film.y).abs() < 1e-4, "{ndc:?} {film}");
            let c = row(cam.exr_world_to_camera(), p);
            let depth = -cam.to_camera_space(p).z;
            assert!((c[2] - depth).abs() < 1e-4 && depth > 0.0);
        }
        // The camera sits at the origin of its space.
        let c = row(cam.exr_world_to_camera(), cam.position());
        assert!(c[..3].iter().all(|v| v.abs() < 1e-5));
    }

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

    /// Projecting a point seen along a camera ray gives back the film position the ray went through; points
    /// behind the camera have none.
    #[test]
    fn film_position_inverts_generate_ray() {
        let cam = Camera::look_at(Vec3::new(1.0, 2.0, 5.0), Vec3::new(0.0, 0.5, 0.0), 0.7);
        for film in [
            Vec2::new(0.5, 0.5),
            Vec2::new(0.1, 0.9),
            Vec2::new(0.97, 0.03),
        ] {
            let ray = cam.generate_ray(film, 1.5);
            let p = cam.to_camera_space(ray.origin + ray.dir * 3.7);
            let back = cam.film_position(p, 1.5).unwrap();
            assert!(back.distance(film) < 1e-5, "{film} -> {back}");
            let behind = cam.to_camera_space(ray.origin - ray.dir);
            assert!(cam.film_position(behind, 1.5).is_none());
        }
    }

    /// A camera translating along x from −1 to 3 over three steps while turning 90° about y: a ray at time t
    /// starts at the lerp of the neighbouring positions and looks along the slerped rotation.
    #[test]
    fn a_moving_camera_interpolates_its_poses() {
        let steps = MotionSteps {
            open: -0.5,
            close: 0.5,
            count: 3,
        };
        let pose = |x: f32, angle: f32| {
            Mat4::from_rotation_translation(Quat::from_rotation_y(angle), Vec3::new(x, 1.0, 2.0))
        };
        let quarter = std::f32::consts::FRAC_PI_2;
        let matrices = [
            pose(-1.0, 0.0),
            pose(0.0, quarter * 0.5),
            pose(3.0, quarter),
        ];
        let mut cam = Camera::look_at(Vec3::ZERO, -Vec3::Z, 60f32.to_radians());
        cam.camera_to_world = matrices[1];
        cam.motion = Some(CameraMotion::from_matrices(steps, &matrices));
        for (time, x, angle) in [
            (-0.5, -1.0, 0.0),
            (-0.25, -0.5, quarter * 0.25),
            (0.0, 0.0, quarter * 0.5),
            (0.125, 0.75, quarter * 0.625),
            (0.5, 3.0, quarter),
        ] {
            let r = cam.generate_ray_at(Vec2::splat(0.5), 1.0, time);
            assert_eq!(r.time, time);
            assert!(
                r.origin.distance(Vec3::new(x, 1.0, 2.0)) < 1e-5,
                "t = {time}: {}",
                r.origin
            );
            let want = Quat::from_rotation_y(angle) * -Vec3::Z;
            assert!(
                r.dir.distance(want) < 1e-5,
                "t = {time}: {} vs {want}",
                r.dir
            );
        }
        // A still camera gives its one pose at any time. The inputs are opaque to the optimiser: with constants,
        // a release build may fold `tan` at compile time in one call and not in the other (a last-bit
        // difference that no render, whose inputs are never constants, can see).
        cam.motion = None;
        let cam = std::hint::black_box(cam);
        let film = std::hint::black_box(Vec2::new(0.2, 0.7));
        let r = cam.generate_ray_at(film, 1.5, 0.4);
        assert_eq!(r, cam.generate_ray(film, 1.5).at_time(0.4));
    }
}
