//! glTF cameras: `perspective` (`yfov`, `aspectRatio`) and `orthographic` (`xmag`, `ymag`), placed by their
//! node (a rigid transform), with a thin lens from `extras.nimbus_camera` (keys [`crate::scene::CAMERA_KEYS`])
//! on the node or the camera object, and motion across the shutter when the node is animated.

use super::{Loader, QUOTE};
use crate::limits::one_line;
use crate::math::Mat4;
use crate::params::unknown_json_keys;
use crate::scene::MalformedPart;
use crate::scene::{
    Camera, CameraMotion, NamedCamera, Projection, SceneError, SceneErrorKind, ThinLens,
};

impl Loader<'_> {
    /// Adds the camera of `node` to the scene's cameras, named by the node (else by the camera object, else
    /// `camera N` for node index N). Perspective: `yfov` and `aspectRatio`; orthographic: `ymag` is the film's
    /// half height and `xmag / ymag` its aspect ratio (the image's own aspect ratio widens or narrows the film
    /// around the same height, as it does a perspective camera's field of view); magnitudes are taken as
    /// absolute values. A lens comes from `extras.nimbus_camera` ([`crate::scene::CAMERA_KEYS`]) on the node, else on
    /// the camera object; keys it does not know are warnings.
    pub(super) fn load_camera(
        &mut self,
        node: &gltf::Node,
        camera: gltf::Camera,
        world: &Mat4,
        node_extras: Option<&serde_json::Value>,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .or(camera.name())
            .map_or_else(|| format!("camera {}", node.index()), str::to_owned);
        let (yfov, projection, aspect_ratio, focal_length) = match camera.projection() {
            gltf::camera::Projection::Perspective(p) => (
                p.yfov(),
                Projection::Perspective,
                p.aspect_ratio(),
                Some(crate::scene::blender_focal_length(
                    p.yfov(),
                    p.aspect_ratio(),
                )),
            ),
            gltf::camera::Projection::Orthographic(o) => (
                // Unused by an orthographic camera; a valid perspective angle keeps the numbers checkable.
                std::f32::consts::FRAC_PI_2,
                Projection::Orthographic {
                    half_height: o.ymag().abs(),
                },
                Some(o.xmag().abs() / o.ymag().abs()),
                None,
            ),
        };
        let at = format!("camera '{}': nimbus_camera", one_line(&name, QUOTE));
        let lens = self.camera_lens(&camera, node_extras, focal_length, &at)?;
        let camera_to_world = Camera::rigid(world);
        let motion = self.camera_motion(node, &camera_to_world);
        self.builder.add_camera(NamedCamera {
            name,
            path: None,
            camera: Camera {
                camera_to_world,
                yfov,
                projection,
                lens,
                aspect_ratio,
                motion,
            },
        });
        Ok(())
    }

    /// The thin lens of a camera from `extras.nimbus_camera` ([`crate::scene::CAMERA_KEYS`]) on its node
    /// (`node_extras`), else on the camera object; `None` without one. `focal_length` is the perspective
    /// camera's Blender focal length; `at` names the object in messages.
    fn camera_lens(
        &mut self,
        camera: &gltf::Camera,
        node_extras: Option<&serde_json::Value>,
        focal_length: Option<f32>,
        at: &str,
    ) -> Result<Option<ThinLens>, SceneError> {
        let camera_extras = match camera.extras() {
            Some(raw) => Some(
                serde_json::from_str::<serde_json::Value>(raw.get()).map_err(|e| {
                    self.error(SceneErrorKind::malformed(
                        MalformedPart::Camera,
                        format!("{at}: {e}"),
                    ))
                })?,
            ),
            None => None,
        };
        let declared = node_extras
            .and_then(|e| e.get("nimbus_camera"))
            .or_else(|| camera_extras.as_ref().and_then(|e| e.get("nimbus_camera")));
        Ok(match declared {
            None => None,
            Some(value) => {
                if !value.is_object() {
                    return Err(self.error(SceneErrorKind::Camera {
                        at: at.into(),
                        source: crate::params::ParamError::WrongType {
                            key: "nimbus_camera".into(),
                            expected: "an object".into(),
                        }
                        .into(),
                    }));
                }
                self.unknown_keys(at, &unknown_json_keys(value, crate::scene::CAMERA_KEYS))?;
                ThinLens::from_params(&crate::params::JsonParams::new(value), focal_length)
                    .map_err(|source| {
                        self.error(SceneErrorKind::Camera {
                            at: at.into(),
                            source,
                        })
                    })?
            }
        })
    }

    /// The motion of the camera on `node` across the shutter, when its pose at some motion step differs from
    /// the frame's (`camera_to_world`).
    fn camera_motion(&self, node: &gltf::Node, camera_to_world: &Mat4) -> Option<CameraMotion> {
        // The camera moves when its pose at some motion step differs from the frame's.
        self.motion.as_ref().and_then(|m| {
            let poses: Vec<Mat4> = m
                .worlds
                .iter()
                .map(|w| Camera::rigid(&w[node.index()]))
                .collect();
            poses
                .iter()
                .any(|p| p != camera_to_world)
                .then(|| CameraMotion::from_matrices(m.steps, &poses))
        })
    }
}
