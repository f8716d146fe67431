//! The camera: perspective (glTF `camera.perspective`: `yfov` vertical field of view, `aspectRatio`; USD
//! `projection = "perspective"`) or orthographic (glTF `camera.orthographic`, USD `projection = "orthographic"`),
//! through a pinhole or a thin lens (depth of field). The camera looks down its local −Z axis with +Y up, as in
//! glTF.
//!
//! The thin lens is pbrt-v4's (Pharr, Jakob and Humphreys, *Physically Based Rendering*, 4th ed., §5.2.3, "The
//! Thin Lens Model and Depth of Field"): a lens disk of radius `r` centred on the pinhole, perpendicular to the
//! view axis, and a plane of focus at distance `f` along the view axis (camera-space `z = −f`). The pinhole ray
//! through a film position, `o + t·d` in camera space (`d.z = −1`), meets the plane of focus at
//! `p_f = o + f·d`; the lens ray starts at the lens point `o + r·(x, y, 0)`, with `(x, y)` a point of the unit
//! disk from the concentric mapping of a 2-D sample (Shirley and Chiu 1997,
//! [`crate::math::sampling::concentric_disk`]), and goes toward `p_f`. Every lens ray through one film position
//! therefore meets at one point of the plane of focus, which is in focus; a point at depth `z` is spread over a
//! circle of confusion of diameter `2 r |f − z| / z` on the plane of focus. For an orthographic camera `o` varies
//! over the film and `d = (0, 0, −1)`, so the same construction applies.
//!
//! Camera motion blur: a camera that moves across the shutter carries its rigid poses at the motion steps
//! ([`CameraMotion`]); a ray at time `t` starts from the pose between the two steps around `t`, its position
//! interpolated linearly and its rotation by slerp ([`Camera::generate_ray_at`]).

use crate::geometry::MotionSteps;
use crate::math::sampling::concentric_disk;
use crate::math::{Aabb, Mat4, Quat, Ray, Vec2, Vec3};
use crate::params::{
    ParamDefault, ParamError, ParamKey, ParamRead, ParamSource, ParamType, UsdBinding,
};

/// A camera: a projection, a placement, and optionally a thin lens.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera-to-world matrix (rigid; scale is removed by the loader).
    pub camera_to_world: Mat4,
    /// Vertical field of view in radians, for [`Projection::Perspective`]; an orthographic camera ignores it.
    pub yfov: f32,
    /// How the film maps onto rays: perspective (through `yfov`) or orthographic.
    pub projection: Projection,
    /// The thin lens of a camera with depth of field; `None` for a pinhole (everything in focus).
    pub lens: Option<ThinLens>,
    /// Width / height from the scene file, used when the user gives only a width.
    pub aspect_ratio: Option<f32>,
    /// The camera's poses across the shutter when it moves (camera motion blur); `None` for a still camera,
    /// which is at `camera_to_world` at every time. (Internal without the `testing` feature: see
    /// [`Camera::is_moving`].)
    #[cfg(feature = "testing")]
    pub motion: Option<CameraMotion>,
    /// The camera's poses across the shutter when it moves.
    #[cfg(not(feature = "testing"))]
    pub(crate) motion: Option<CameraMotion>,
}

/// How a camera maps film positions onto rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from the pinhole (the lens centre) through the film, spanning the vertical field of view
    /// [`Camera::yfov`] and the image's aspect ratio times its tangent horizontally.
    Perspective,
    /// Parallel rays along the view axis (−Z) from a film `2 · half_height` tall in scene units (glTF `ymag`,
    /// USD `verticalAperture / 20`), and the image's aspect ratio times that wide: the film's top edge is at
    /// camera-space `y = half_height`.
    Orthographic {
        /// Half the film's height, in scene units (> 0).
        half_height: f32,
    },
}

/// A thin lens: depth of field (pbrt-v4 §5.2.3; see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinLens {
    /// Radius of the lens disk, in scene units (> 0).
    pub aperture_radius: f32,
    /// Distance from the lens to the plane of focus, along the view axis, in scene units (> 0).
    pub focus_distance: f32,
}

/// The sensor width Blender's cameras default to, in metres: with sensor fit AUTO it spans the larger side of
/// the image, which makes a glTF camera's `f_stop` mean what it means in Blender (see [`CAMERA_KEYS`]).
pub(crate) const BLENDER_SENSOR_WIDTH: f32 = 0.036;

/// The largest aperture radius over focus distance a lens may have: far beyond any optics (a real lens's ratio
/// is below 1), and small enough that a lens ray's direction keeps its single-precision length.
pub(crate) const MAX_APERTURE_OVER_FOCUS: f32 = 1e6;

/// `nimbus_camera.aperture_radius`.
const APERTURE_RADIUS: ParamKey = ParamKey {
    name: "aperture_radius",
    ty: ParamType::NonNegative,
    default: ParamDefault::Unset,
    doc: "radius of the thin lens in metres (0: a pinhole, everything in focus); not with `f_stop`",
    usd: UsdBinding::Elsewhere("from `fStop` and `focalLength`"),
};

/// `nimbus_camera.f_stop`.
const F_STOP: ParamKey = ParamKey {
    name: "f_stop",
    ty: ParamType::NonNegative,
    default: ParamDefault::Unset,
    doc: "the lens's f-number N, as in Blender: aperture radius = focal length / (2 N), the focal length that \
          of a 36 mm sensor spanning the image's larger side (Blender's sensor fit AUTO: 0.018 m / tan(fov/2), \
          fov the horizontal field of view when `aspectRatio` ≥ 1 or is absent, else `yfov`); > 0, perspective \
          cameras only; not with `aperture_radius`",
    usd: UsdBinding::Elsewhere("`fStop` (0: no depth of field)"),
};

/// `nimbus_camera.focus_distance`.
const FOCUS_DISTANCE: ParamKey = ParamKey {
    name: "focus_distance",
    ty: ParamType::NonNegative,
    default: ParamDefault::Unset,
    doc: "distance from the lens to the plane in focus, along the view axis, in metres (> 0); required with a \
          lens (`aperture_radius` > 0 or `f_stop`)",
    usd: UsdBinding::Elsewhere("`focusDistance`"),
};

internal! {
    /// The keys of a glTF camera's `extras.nimbus_camera` (on the camera node or on the camera object; the node's
    /// wins), in docs/reference.md's order. Other keys are reported as warnings and ignored.
    pub const CAMERA_KEYS: &[ParamKey] = &[APERTURE_RADIUS, F_STOP, FOCUS_DISTANCE];
}

/// A `nimbus_camera` declaration (or a USD camera's lens attributes) that cannot be a lens.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LensError {
    /// A key is missing, of the wrong type or out of range.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// Both `f_stop` and `aperture_radius` are given.
    #[error("give 'f_stop' or 'aperture_radius', not both")]
    Both,
    /// `f_stop` on a camera without a focal length (orthographic).
    #[error("'f_stop' needs a perspective camera (an orthographic one has no focal length); give 'aperture_radius'")]
    NoFocalLength,
}

impl ThinLens {
    /// The lens from an aperture radius and a focus distance (scene units): `None` for a radius of 0 (a
    /// pinhole); an error for a value that is negative, not finite, a focus distance that is not > 0, or one
    /// below the radius over `MAX_APERTURE_OVER_FOCUS`.
    /// `names` are the keys as the scene file spells them (radius, focus distance), for the messages.
    pub fn new(
        aperture_radius: f32,
        focus_distance: Option<f32>,
        names: [&str; 2],
    ) -> Result<Option<Self>, LensError> {
        if !(aperture_radius.is_finite() && aperture_radius >= 0.0) {
            return Err(ParamError::OutOfRange {
                key: names[0].to_owned(),
                value: aperture_radius.to_string(),
                constraint: "be finite and ≥ 0",
            }
            .into());
        }
        if aperture_radius == 0.0 {
            return Ok(None);
        }
        let Some(focus_distance) = focus_distance else {
            return Err(ParamError::Missing {
                key: names[1].to_owned(),
            }
            .into());
        };
        if !(focus_distance.is_finite() && focus_distance > 0.0) {
            return Err(ParamError::OutOfRange {
                key: names[1].to_owned(),
                value: focus_distance.to_string(),
                constraint: "be finite and > 0",
            }
            .into());
        }
        // Both are finite and > 0 here, so the ratio is a number (infinite when it overflows).
        if aperture_radius / focus_distance > MAX_APERTURE_OVER_FOCUS {
            return Err(ParamError::OutOfRange {
                key: names[1].to_owned(),
                value: focus_distance.to_string(),
                constraint: "be at least a millionth of the aperture radius",
            }
            .into());
        }
        Ok(Some(Self {
            aperture_radius,
            focus_distance,
        }))
    }

    /// The lens of a glTF `nimbus_camera` object ([`CAMERA_KEYS`]) for a camera with `focal_length` (metres;
    /// `None` for an orthographic camera): `aperture_radius`, or `f_stop` converted as the key table says.
    pub(crate) fn from_params(
        params: &impl ParamSource,
        focal_length: Option<f32>,
    ) -> Result<Option<Self>, LensError> {
        let radius = params.number(&APERTURE_RADIUS)?;
        let f_stop = params.number(&F_STOP)?;
        let focus = params.number(&FOCUS_DISTANCE)?;
        let radius = match (radius, f_stop) {
            (Some(_), Some(_)) => return Err(LensError::Both),
            (Some(r), None) => r,
            (None, Some(n)) => {
                if !(n > 0.0 && n.is_finite()) {
                    return Err(ParamError::OutOfRange {
                        key: params.spelling(&F_STOP),
                        value: n.to_string(),
                        constraint: "be finite and > 0",
                    }
                    .into());
                }
                focal_length.ok_or(LensError::NoFocalLength)? / (2.0 * n)
            }
            (None, None) => 0.0,
        };
        Self::new(
            radius,
            focus,
            [
                &params.spelling(&APERTURE_RADIUS),
                &params.spelling(&FOCUS_DISTANCE),
            ],
        )
    }
}

internal! {
    /// The focal length (metres) that makes a glTF perspective camera's `yfov` and `aspectRatio` those of a
    /// Blender camera with a 36 mm sensor and sensor fit AUTO: the sensor spans the larger side of the image, the
    /// horizontal one when `aspect_ratio` (width / height) is at least 1 or absent, so the focal length is
    /// `0.018 / tan(fov/2)` with `tan(fov/2) = max(aspect_ratio, 1) · tan(yfov/2)`.
    pub fn blender_focal_length(yfov: f32, aspect_ratio: Option<f32>) -> f32 {
        let tan_large = aspect_ratio.unwrap_or(1.0).max(1.0) * (yfov * 0.5).tan();
        0.5 * BLENDER_SENSOR_WIDTH / tan_large
    }
}

/// A camera of a scene file with the names it can be chosen by (`--camera`).
#[derive(Clone, Debug, PartialEq)]
pub struct NamedCamera {
    /// The name: the glTF node's name (else the camera object's, else `camera N` for node index N); the USD
    /// prim's name.
    pub name: String,
    /// The USD prim path (`/World/cam`); `None` in glTF.
    pub path: Option<String>,
    /// The camera.
    pub camera: Camera,
}

impl NamedCamera {
    /// Whether `name` chooses this camera: its name or its prim path.
    pub fn is_named(&self, name: &str) -> bool {
        self.name == name || self.path.as_deref() == Some(name)
    }

    /// One line for `--list-cameras`: the name (and prim path), the projection with its field of view or
    /// extent, and the lens's aperture radius and focus distance if any.
    pub fn describe(&self) -> String {
        let c = &self.camera;
        let mut line = match &self.path {
            Some(path) if *path != self.name => format!("{} ({path})", self.name),
            _ => self.name.clone(),
        };
        match c.projection {
            Projection::Perspective => {
                line.push_str(&format!("\tperspective\tyfov {:.2}°", c.yfov.to_degrees()))
            }
            Projection::Orthographic { half_height } => {
                line.push_str(&format!("\torthographic\theight {}", 2.0 * half_height))
            }
        }
        if let Some(a) = c.aspect_ratio {
            line.push_str(&format!("\taspect {a:.4}"));
        }
        match c.lens {
            Some(l) => line.push_str(&format!(
                "\taperture radius {}\tfocus distance {}",
                l.aperture_radius, l.focus_distance
            )),
            None => line.push_str("\tpinhole"),
        }
        line
    }
}

/// `--camera NAME` names none of the scene's cameras.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("no camera named '{name}'; {}", if available.is_empty() { "the scene has no cameras".to_owned() } else { format!("the scene's cameras: {}", available.join(", ")) })]
pub struct UnknownCamera {
    /// The name asked for.
    pub name: String,
    /// The names (and USD prim paths) of the scene's cameras.
    pub available: Vec<String>,
}

internal! {
    /// A moving camera's rigid poses at its motion steps.
    #[derive(Clone, Debug, PartialEq)]
    pub struct CameraMotion {
        /// When the poses are.
        pub steps: MotionSteps,
        /// The position and rotation of the camera-to-world transform at each step.
        pub poses: Vec<(Vec3, Quat)>,
    }
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
    pub(crate) fn is_valid(&self) -> bool {
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
    /// Whether the camera moves across the shutter (camera motion blur).
    pub fn is_moving(&self) -> bool {
        self.motion.is_some()
    }

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
            projection: Projection::Perspective,
            lens: None,
            aspect_ratio: None,
            motion: None,
        }
    }

    internal! {
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
            let dir =
                (areas / areas.max_element().max(f32::MIN_POSITIVE) + front * 1e-3).normalize();
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
            for corner in bounds.corners() {
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
                projection: Projection::Perspective,
                lens: None,
                aspect_ratio: None,
                motion: None,
            }
        }
    }

    /// A camera-to-world matrix from a scene node's world matrix: its scale and shear removed, its rotation
    /// (the x axis, then the y axis made orthogonal to it) and position kept.
    pub(crate) fn rigid(m: &Mat4) -> Mat4 {
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
    /// Level of Detail Using Ray Cones", JCGT 10(1), §3). 0 for an orthographic camera, whose rays are parallel
    /// (its cones start [`Self::pixel_width`] wide instead). A thin lens keeps the pinhole's spread, as pbrt-v4
    /// does: the cone describes the pixel's footprint, not the defocus.
    pub(crate) fn pixel_spread_angle(&self, height: usize) -> f32 {
        if matches!(self.projection, Projection::Orthographic { .. }) {
            return 0.0;
        }
        let spread = (2.0 * (self.yfov * 0.5).tan() / height.max(1) as f32).atan();
        if spread.is_finite() {
            spread
        } else {
            0.0
        }
    }

    /// The width of a camera ray cone where it starts, in scene units: one pixel's height on an orthographic
    /// film (`2·half_height / height`), 0 for a perspective camera (its cones start at the pinhole).
    pub(crate) fn pixel_width(&self, height: usize) -> f32 {
        match self.projection {
            Projection::Perspective => 0.0,
            Projection::Orthographic { half_height } => 2.0 * half_height / height.max(1) as f32,
        }
    }

    internal! {
        /// The primary ray through film position `film` in \[0,1\]² ((0,0) = top-left) for an image of `aspect`
        /// = width / height, from the centre of the lens (a thin lens's centre ray is the pinhole's).
        #[cfg(any(test, feature = "testing"))]
        pub fn generate_ray(&self, film: Vec2, aspect: f32) -> Ray {
            self.ray_from(&self.camera_to_world, film, aspect, None)
        }
    }

    internal! {
        /// The primary ray through `film` (as [`Self::generate_ray`]) at `time` (frames from the frame): from the
        /// camera's pose at that time when it moves ([`CameraMotion::camera_to_world_at`]), else from its one
        /// pose; the ray carries the time.
        #[cfg(any(test, feature = "testing"))]
        pub fn generate_ray_at(&self, film: Vec2, aspect: f32, time: f32) -> Ray {
            self.sample_ray(film, None, aspect, Some(time))
        }
    }

    /// The primary ray of one camera sample: through `film` (as [`Self::generate_ray`]), from the lens point of
    /// the 2-D sample `lens` in \[0,1)² when the camera has a [`ThinLens`] (mapped onto the lens disk by
    /// [`concentric_disk`]; see the module documentation), at `time` when given (as [`Self::generate_ray_at`]).
    /// Without a lens, or with `lens` `None`, the ray starts at the lens centre (the pinhole).
    pub(crate) fn sample_ray(
        &self,
        film: Vec2,
        lens: Option<Vec2>,
        aspect: f32,
        time: Option<f32>,
    ) -> Ray {
        let lens = lens.filter(|_| self.lens.is_some());
        match (&self.motion, time) {
            (Some(m), Some(t)) => self
                .ray_from(&m.camera_to_world_at(t), film, aspect, lens)
                .at_time(t),
            (None, Some(t)) => self
                .ray_from(&self.camera_to_world, film, aspect, lens)
                .at_time(t),
            (_, None) => self.ray_from(&self.camera_to_world, film, aspect, lens),
        }
    }

    /// The film position in \[0,1\]² ((0,0) = top-left, as [`Self::generate_ray`] takes it) where the camera
    /// sees `p_camera`, a point in camera space (see [`Self::to_camera_space`]) in front of the camera
    /// (`z < 0`); `None` for a point on or behind the camera plane. The inverse of [`Self::generate_ray`]:
    /// positions outside \[0,1\]² are outside the image. For a thin lens this is where the point is seen through
    /// the lens centre, the centre of its circle of confusion.
    pub(crate) fn film_position(&self, p_camera: Vec3, aspect: f32) -> Option<Vec2> {
        if p_camera.z.is_nan() || p_camera.z >= 0.0 {
            return None;
        }
        let (x, y) = match self.projection {
            Projection::Perspective => {
                let tan_half = (self.yfov * 0.5).tan();
                (
                    p_camera.x / -p_camera.z / (tan_half * aspect),
                    p_camera.y / -p_camera.z / tan_half,
                )
            }
            Projection::Orthographic { half_height } => (
                p_camera.x / (half_height * aspect),
                p_camera.y / half_height,
            ),
        };
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
    /// corner and (1, 1) its bottom-right (OpenEXR's normalised device coordinates of the display window).
    /// Perspective: Z/W is 1/depth along the view; a thin lens has the pinhole's matrix (where the lens centre
    /// sees the point). Orthographic: the matrix is affine, W = 1 and Z is the depth.
    pub fn exr_world_to_ndc(&self, aspect: f32) -> [[f32; 4]; 4] {
        let projection = match self.projection {
            Projection::Perspective => {
                let tan_y = (self.yfov * 0.5).tan();
                let tan_x = tan_y * aspect;
                // On OpenEXR camera space (column vectors): X = z/2 + x/(2 tan_x), Y = z/2 − y/(2 tan_y), Z = 1,
                // W = z.
                Mat4::from_cols_array_2d(&[
                    [0.5 / tan_x, 0.0, 0.0, 0.0],
                    [0.0, -0.5 / tan_y, 0.0, 0.0],
                    [0.5, 0.5, 0.0, 1.0],
                    [0.0, 0.0, 1.0, 0.0],
                ])
            }
            Projection::Orthographic { half_height } => {
                // X = 1/2 + x/(2 aspect half_height), Y = 1/2 − y/(2 half_height), Z = z, W = 1.
                Mat4::from_cols_array_2d(&[
                    [0.5 / (half_height * aspect), 0.0, 0.0, 0.0],
                    [0.0, -0.5 / half_height, 0.0, 0.0],
                    [0.0, 0.0, 1.0, 0.0],
                    [0.5, 0.5, 0.0, 1.0],
                ])
            }
        };
        let flip_z = Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0));
        (projection * flip_z * self.camera_to_world.inverse()).to_cols_array_2d()
    }

    /// `p` (world space) in the still camera's space: the camera at the origin looking down −Z, +Y up.
    pub(crate) fn to_camera_space(&self, p: Vec3) -> Vec3 {
        self.camera_to_world.inverse().transform_point3(p)
    }

    /// Whether the camera's numbers can make rays: a finite placement, 0 < yfov < π (perspective) or a finite
    /// half height > 0 (orthographic), a finite positive aspect ratio if any, a lens with a finite radius > 0
    /// and a finite focus distance > 0 (the radius at most [`MAX_APERTURE_OVER_FOCUS`] times it) if any. Motion
    /// is checked by
    /// [`CameraMotion::is_valid`].
    pub(crate) fn is_valid(&self) -> bool {
        let projection = match self.projection {
            Projection::Perspective => self.yfov > 0.0 && self.yfov < std::f32::consts::PI,
            Projection::Orthographic { half_height } => {
                half_height.is_finite() && half_height > 0.0
            }
        };
        let lens = self.lens.is_none_or(|l| {
            l.aperture_radius.is_finite()
                && l.aperture_radius > 0.0
                && l.focus_distance.is_finite()
                && l.focus_distance > 0.0
                && l.aperture_radius / l.focus_distance <= MAX_APERTURE_OVER_FOCUS
        });
        self.camera_to_world.is_finite()
            && projection
            && lens
            && self.aspect_ratio.is_none_or(|a| a.is_finite() && a > 0.0)
    }

    /// The ray through `film` for the camera-to-world matrix `to_world`, from the lens point of the sample
    /// `lens` (the lens centre when `None`).
    fn ray_from(&self, to_world: &Mat4, film: Vec2, aspect: f32, lens: Option<Vec2>) -> Ray {
        let sx = 2.0 * film.x - 1.0;
        let sy = 1.0 - 2.0 * film.y;
        // The pinhole ray in camera space: origin and direction with z = −1.
        let (origin, dir) = match self.projection {
            Projection::Perspective => {
                let tan_half = (self.yfov * 0.5).tan();
                (
                    Vec3::ZERO,
                    Vec3::new(sx * tan_half * aspect, sy * tan_half, -1.0),
                )
            }
            Projection::Orthographic { half_height } => (
                Vec3::new(sx * half_height * aspect, sy * half_height, 0.0),
                Vec3::NEG_Z,
            ),
        };
        let (origin, dir) = match (self.lens, lens) {
            (Some(l), Some(u)) => {
                // pbrt-v4 §5.2.3: the point of the plane of focus (z = −focus_distance) on the pinhole ray,
                // o + f·d, seen from the sampled point of the lens disk, o + r·p: the direction f·d − r·p,
                // here divided by f (which does not turn it, and cannot overflow for any focus distance).
                let offset = (l.aperture_radius * concentric_disk(u)).extend(0.0);
                (origin + offset, dir - offset * (1.0 / l.focus_distance))
            }
            _ => (origin, dir),
        };
        Ray::new(
            to_world.transform_point3(origin),
            to_world.transform_vector3(dir).normalize(),
        )
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

    fn lens_camera() -> Camera {
        let mut cam = Camera::look_at(Vec3::new(0.5, 1.0, 4.0), Vec3::new(0.0, 0.2, -1.0), 0.8);
        cam.lens = Some(ThinLens {
            aperture_radius: 0.1,
            focus_distance: 2.5,
        });
        cam
    }

    /// The lens ray of the disk's centre (sample (½, ½)) is the pinhole's ray; a camera without a lens
    /// ignores the sample, bit for bit.
    #[test]
    fn the_lens_centre_ray_is_the_pinhole_ray() {
        let cam = lens_camera();
        let pinhole = Camera {
            lens: None,
            ..cam.clone()
        };
        for film in [
            Vec2::new(0.5, 0.5),
            Vec2::new(0.1, 0.8),
            Vec2::new(0.95, 0.02),
        ] {
            let a = cam.sample_ray(film, Some(Vec2::splat(0.5)), 1.5, None);
            let b = pinhole.generate_ray(film, 1.5);
            assert!(a.origin.distance(b.origin) < 1e-6, "{a:?} {b:?}");
            assert!(a.dir.distance(b.dir) < 1e-6, "{a:?} {b:?}");
            let c = pinhole.sample_ray(film, Some(Vec2::new(0.9, 0.1)), 1.5, None);
            assert_eq!(c, b);
        }
    }

    /// Every lens ray through one film position passes through the point of the plane of focus that the
    /// pinhole ray meets, `focus_distance · (x tan·aspect, y tan, −1)` in camera space (pbrt-v4 §5.2.3), and
    /// starts on the lens disk: at the aperture radius for samples on the square's edge.
    #[test]
    fn lens_rays_through_one_film_point_meet_on_the_plane_of_focus() {
        let cam = lens_camera();
        let aspect = 1.5;
        let film = Vec2::new(0.3, 0.7);
        let tan = (cam.yfov * 0.5).tan();
        let want = cam.camera_to_world.transform_point3(
            2.5 * Vec3::new(
                (2.0 * 0.3 - 1.0) * tan * aspect,
                (1.0 - 2.0 * 0.7) * tan,
                -1.0,
            ),
        );
        let centre = cam.position();
        let mut spread = 0f32;
        for u in [
            Vec2::new(0.1, 0.2),
            Vec2::new(0.9, 0.6),
            Vec2::new(0.5, 0.99),
            Vec2::new(1.0, 0.5),
            Vec2::new(0.0, 0.0),
        ] {
            let ray = cam.sample_ray(film, Some(u), aspect, None);
            let p = cam.to_camera_space(ray.origin);
            assert!(p.z.abs() < 1e-5, "the lens is the plane z = 0: {p}");
            let r = ray.origin.distance(centre);
            assert!(r <= 0.1 + 1e-5, "{u}: off the lens, {r}");
            if u.x == 1.0 || u.x == 0.0 {
                assert!(
                    (r - 0.1).abs() < 1e-5,
                    "{u}: an edge sample is on the rim, {r}"
                );
            }
            spread = spread.max(r);
            // Where the ray crosses the plane of focus.
            let depth = -cam.to_camera_space(ray.origin + ray.dir).z + p.z;
            let hit = ray.origin + ray.dir * (2.5 / depth);
            assert!(hit.distance(want) < 1e-4, "{u}: {hit} vs {want}");
        }
        assert!(spread > 0.09, "the samples cover the lens: {spread}");
    }

    /// Extreme but valid lenses keep rays finite: a focus distance near the largest float with a field of view
    /// near 180° and a wide image (whose pinhole direction times the focus distance overflows).
    #[test]
    fn extreme_lenses_give_finite_rays() {
        let mut cam = Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, 3.1);
        for (r, f) in [(1e-3, 3e38), (1e30, 1e24), (1e-30, 1e-30), (1e6, 1.0)] {
            cam.lens = Some(ThinLens {
                aperture_radius: r,
                focus_distance: f,
            });
            assert!(cam.is_valid());
            for film in [Vec2::ZERO, Vec2::ONE, Vec2::splat(0.5)] {
                let ray = cam.sample_ray(film, Some(Vec2::new(0.9, 0.1)), 100.0, None);
                assert!(
                    ray.origin.is_finite() && (ray.dir.length() - 1.0).abs() < 1e-5,
                    "{r} {f}: {ray:?}"
                );
            }
        }
    }

    /// A moving camera with a lens: the rays of one film position meet on the plane of focus of the pose at
    /// the ray's time.
    #[test]
    fn a_moving_lens_focuses_from_its_pose_at_the_ray_time() {
        let steps = MotionSteps {
            open: 0.0,
            close: 1.0,
            count: 2,
        };
        let mut cam = lens_camera();
        let moved = Mat4::from_translation(Vec3::new(2.0, 0.0, 0.0)) * cam.camera_to_world;
        cam.motion = Some(CameraMotion::from_matrices(
            steps,
            &[cam.camera_to_world, moved],
        ));
        let film = Vec2::new(0.6, 0.4);
        let centre = cam.generate_ray_at(film, 1.0, 1.0);
        assert!(centre.origin.distance(moved.transform_point3(Vec3::ZERO)) < 1e-5);
        let focus = |ray: &Ray| {
            let to_cam = moved.inverse();
            let o = to_cam.transform_point3(ray.origin);
            let d = to_cam.transform_vector3(ray.dir);
            ray.origin + ray.dir * ((-2.5 - o.z) / d.z)
        };
        let want = focus(&centre);
        for u in [Vec2::new(0.2, 0.3), Vec2::new(0.8, 0.9)] {
            let ray = cam.sample_ray(film, Some(u), 1.0, Some(1.0));
            assert_eq!(ray.time, 1.0);
            assert!(ray.origin.distance(centre.origin) > 1e-3);
            assert!(focus(&ray).distance(want) < 1e-4);
        }
    }

    /// An orthographic camera's rays are all parallel to its view axis and start on a film `2·half_height`
    /// tall and `aspect` times as wide; its cones start one pixel wide and do not spread; the EXR matrix is
    /// affine and `film_position` inverts the rays.
    #[test]
    fn orthographic_rays_are_parallel_and_span_the_film() {
        let mut cam = Camera::look_at(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1.0, 2.0, -1.0), 0.5);
        cam.projection = Projection::Orthographic { half_height: 0.75 };
        let aspect = 2.0;
        for (film, x, y) in [
            (Vec2::new(0.0, 0.0), -1.5, 0.75),
            (Vec2::new(1.0, 1.0), 1.5, -0.75),
            (Vec2::new(0.5, 0.5), 0.0, 0.0),
            (Vec2::new(0.25, 0.75), -0.75, -0.375),
        ] {
            let ray = cam.generate_ray(film, aspect);
            assert!(ray.dir.distance(-Vec3::Z) < 1e-6, "{film}: {}", ray.dir);
            assert!(
                ray.origin.distance(Vec3::new(1.0 + x, 2.0 + y, 3.0)) < 1e-5,
                "{film}: {}",
                ray.origin
            );
            let p = cam.to_camera_space(ray.at(2.0));
            let back = cam.film_position(p, aspect).unwrap();
            assert!(back.distance(film) < 1e-5, "{film} -> {back}");
        }
        assert_eq!(cam.pixel_spread_angle(100), 0.0);
        assert!((cam.pixel_width(100) - 0.015).abs() < 1e-7);
        let m = cam.exr_world_to_ndc(aspect);
        assert_eq!([m[0][3], m[1][3], m[2][3], m[3][3]], [0.0, 0.0, 0.0, 1.0]);
        // A point 4 units in front, right and below the centre lands a quarter of the way in.
        let p = Vec3::new(1.75, 1.625, -1.0);
        let v = [p.x, p.y, p.z, 1.0];
        let ndc: [f32; 4] = std::array::from_fn(|j| (0..4).map(|i| v[i] * m[i][j]).sum());
        assert!(
            (ndc[0] - 0.75).abs() < 1e-5 && (ndc[1] - 0.75).abs() < 1e-5,
            "{ndc:?}"
        );
        assert!((ndc[2] - 4.0).abs() < 1e-5 && ndc[3] == 1.0, "{ndc:?}");
    }

    /// Blender's convention: a 50 mm lens on a 36 mm sensor fitted to the larger side. Landscape: the
    /// horizontal field of view is 2·atan(18/50); portrait: the vertical one.
    #[test]
    fn focal_lengths_follow_blenders_sensor_fit() {
        let xfov = 2.0 * (18.0f32 / 50.0).atan();
        let aspect = 16.0 / 9.0;
        let yfov = 2.0 * ((xfov * 0.5).tan() / aspect).atan();
        assert!((blender_focal_length(yfov, Some(aspect)) - 0.05).abs() < 1e-6);
        assert!((blender_focal_length(xfov, Some(0.5)) - 0.05).abs() < 1e-6);
        assert!((blender_focal_length(xfov, None) - 0.05).abs() < 1e-6);
    }

    #[test]
    fn nimbus_camera_keys_make_a_lens_or_a_typed_error() {
        use crate::params::JsonParams;
        use serde_json::json;
        let lens = |v: serde_json::Value, focal: Option<f32>| {
            ThinLens::from_params(&JsonParams::new(&v), focal)
        };
        assert_eq!(
            lens(
                json!({"aperture_radius": 0.02, "focus_distance": 3.0}),
                None
            ),
            Ok(Some(ThinLens {
                aperture_radius: 0.02,
                focus_distance: 3.0
            }))
        );
        let l = lens(json!({"f_stop": 2.0, "focus_distance": 3.0}), Some(0.05))
            .unwrap()
            .unwrap();
        assert!((l.aperture_radius - 0.0125).abs() < 1e-7);
        assert_eq!(lens(json!({"aperture_radius": 0.0}), None), Ok(None));
        assert_eq!(lens(json!({}), Some(0.05)), Ok(None));
        let err =
            |v: serde_json::Value, focal: Option<f32>| lens(v, focal).unwrap_err().to_string();
        assert_eq!(
            lens(
                json!({"f_stop": 2.0, "aperture_radius": 0.1, "focus_distance": 1.0}),
                Some(0.05)
            ),
            Err(LensError::Both)
        );
        assert!(
            err(json!({"f_stop": 0.0, "focus_distance": 1.0}), Some(0.05)).contains("'f_stop' 0")
        );
        assert!(
            err(json!({"f_stop": -1.0, "focus_distance": 1.0}), Some(0.05)).contains("'f_stop'")
        );
        assert!(err(
            json!({"aperture_radius": -0.1, "focus_distance": 1.0}),
            None
        )
        .contains("'aperture_radius'"));
        assert!(err(
            json!({"aperture_radius": "wide", "focus_distance": 1.0}),
            None
        )
        .contains("'aperture_radius' must be a non-negative number"));
        assert!(err(json!({"aperture_radius": 0.1}), None).contains("'focus_distance' is required"));
        assert!(
            err(json!({"aperture_radius": 0.1, "focus_distance": 0.0}), None)
                .contains("'focus_distance' 0 must be finite and > 0")
        );
        assert!(err(
            json!({"aperture_radius": 0.1, "focus_distance": 1e39}),
            None
        )
        .contains("'focus_distance'"));
        assert_eq!(
            lens(json!({"f_stop": 2.0, "focus_distance": 1.0}), None),
            Err(LensError::NoFocalLength)
        );
        assert!(ThinLens::new(f32::NAN, Some(1.0), ["r", "f"]).is_err());
        assert!(ThinLens::new(0.1, Some(f32::NAN), ["r", "f"]).is_err());
        assert!(ThinLens::new(1e30, Some(1e-30), ["r", "f"]).is_err());
        assert!(ThinLens::new(2e6, Some(1.0), ["r", "f"]).is_err());
        assert!(ThinLens::new(1e6, Some(1.0), ["r", "f"]).unwrap().is_some());
    }

    /// `is_valid` refuses what would put NaN on the film: a zero or non-finite lens or orthographic extent.
    #[test]
    fn invalid_lenses_and_extents_are_refused() {
        let mut cam = lens_camera();
        assert!(cam.is_valid());
        for lens in [
            (0.0, 1.0),
            (0.1, 0.0),
            (f32::NAN, 1.0),
            (0.1, f32::INFINITY),
        ] {
            cam.lens = Some(ThinLens {
                aperture_radius: lens.0,
                focus_distance: lens.1,
            });
            assert!(!cam.is_valid(), "{lens:?}");
        }
        cam.lens = None;
        for h in [0.0, -1.0, f32::NAN] {
            cam.projection = Projection::Orthographic { half_height: h };
            assert!(!cam.is_valid(), "{h}");
        }
    }

    #[test]
    fn the_reference_key_table_is_the_code_table() {
        let reference =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/reference.md"))
                .unwrap();
        let table = crate::params::markdown_table(CAMERA_KEYS);
        assert!(
            reference.contains(&table),
            "docs/reference.md's nimbus_camera key table is not the code's; it should read:\n{table}"
        );
    }
}
