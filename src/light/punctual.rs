//! Punctual lights from `KHR_lights_punctual`, in radiometric units: W/sr for point and spot lights, W/m² for
//! directional lights. The glTF loader converts the file's photometric candela and lux at
//! [`LUMENS_PER_WATT`] unless the scene says its values are radiometric.
//!
//! glTF keys read: `type`, `color`, `intensity`, `spot.innerConeAngle` (default 0), `spot.outerConeAngle`
//! (default π/4). The light shines along the node's −Z axis.

use super::LightSample;
use crate::geometry::SurfacePoint;
use crate::math::{luminance, Rgb, Vec3};
use std::f32::consts::PI;

/// The luminous efficacy, in lm/W, that converts glTF's photometric light units (candela, lux) to radiometric
/// ones (W/sr, W/m²): the peak efficacy of photopic vision, which Blender's glTF importer also uses.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// A point light emitting `intensity` W/sr in every direction.
#[derive(Clone, Debug)]
pub struct PointLight {
    /// World position.
    pub position: Vec3,
    /// Radiant intensity, W/sr per channel (colour × intensity).
    pub intensity: Rgb,
}

impl PointLight {
    /// The inverse-square illumination at `p`.
    pub fn sample_li(&self, p: Vec3) -> Option<LightSample> {
        delta_sample(self.position, p, self.intensity)
    }

    /// Emitted power 4π·I (luminance).
    pub fn power(&self) -> f32 {
        4.0 * PI * luminance(self.intensity)
    }
}

/// A spot light: a point light restricted to a cone with the glTF smooth angular falloff.
#[derive(Clone, Debug)]
pub struct SpotLight {
    /// World position.
    pub position: Vec3,
    /// Unit direction of the cone axis (where the light shines).
    pub direction: Vec3,
    /// Radiant intensity on the axis, W/sr.
    pub intensity: Rgb,
    /// Cosine of the inner cone angle (full intensity inside).
    pub cos_inner: f32,
    /// Cosine of the outer cone angle (no light outside).
    pub cos_outer: f32,
}

impl SpotLight {
    /// The angular falloff recommended by the KHR_lights_punctual specification ("Inner and Outer Cone
    /// Angles"): a squared linear ramp in cos θ between the outer and inner cones. When the two cones are equal
    /// the edge is hard, as Blender's importer and three.js render it (the specification's sample code keeps
    /// a ramp 0.001 wide in cos θ there only to avoid dividing by zero).
    pub fn falloff(&self, cos_theta: f32) -> f32 {
        let width = self.cos_inner - self.cos_outer;
        if width <= 0.0 {
            return if cos_theta >= self.cos_outer {
                1.0
            } else {
                0.0
            };
        }
        let t = ((cos_theta - self.cos_outer) / width).clamp(0.0, 1.0);
        t * t
    }

    /// The illumination at `p`.
    pub fn sample_li(&self, p: Vec3) -> Option<LightSample> {
        let wi = (self.position - p).normalize_or_zero();
        let falloff = self.falloff(self.direction.dot(-wi));
        if falloff <= 0.0 {
            return None;
        }
        delta_sample(self.position, p, self.intensity * falloff)
    }

    /// Emitted power, approximating the falloff by the average of the two cones' solid angles.
    pub fn power(&self) -> f32 {
        let solid_angle = 2.0 * PI * (1.0 - 0.5 * (self.cos_inner + self.cos_outer));
        solid_angle * luminance(self.intensity)
    }
}

/// A directional light: parallel light of irradiance `irradiance` W/m² on a surface facing it.
#[derive(Clone, Debug)]
pub struct DirectionalLight {
    /// Unit direction the light travels in.
    pub direction: Vec3,
    /// Irradiance at normal incidence, W/m² per channel.
    pub irradiance: Rgb,
}

impl DirectionalLight {
    /// The light's direction and irradiance, from anywhere.
    pub fn sample_li(&self) -> LightSample {
        LightSample {
            wi: -self.direction,
            radiance: self.irradiance,
            pdf: 1.0,
            point: None,
            is_delta: true,
        }
    }
}

fn delta_sample(light: Vec3, p: Vec3, intensity: Rgb) -> Option<LightSample> {
    let d = light - p;
    let dist2 = d.length_squared();
    if dist2.is_nan() || dist2 <= 0.0 {
        return None;
    }
    let distance = dist2.sqrt();
    Some(LightSample {
        wi: d / distance,
        radiance: intensity / dist2,
        pdf: 1.0,
        point: Some(SurfacePoint::free(light)),
        is_delta: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_is_inverse_square() {
        let l = PointLight {
            position: Vec3::new(0.0, 2.0, 0.0),
            intensity: Rgb::splat(8.0),
        };
        let s = l.sample_li(Vec3::ZERO).unwrap();
        assert!(
            (s.radiance.x - 2.0).abs() < 1e-6
                && s.wi.distance(Vec3::Y) < 1e-6
                && s.distance_from(Vec3::ZERO) == 2.0
        );
    }

    #[test]
    fn spot_falloff_is_one_inside_and_zero_outside() {
        let l = SpotLight {
            position: Vec3::ZERO,
            direction: -Vec3::Y,
            intensity: Rgb::ONE,
            cos_inner: 0.9,
            cos_outer: 0.8,
        };
        assert_eq!(l.falloff(0.95), 1.0);
        assert_eq!(l.falloff(0.7), 0.0);
        assert!((l.falloff(0.85) - 0.25).abs() < 1e-5);
        assert!(l.sample_li(Vec3::new(0.0, -1.0, 0.0)).is_some());
        assert!(l.sample_li(Vec3::new(0.0, 1.0, 0.0)).is_none());
        // Equal cones: a hard edge, full intensity right up to it.
        let hard = SpotLight {
            cos_inner: 0.8,
            ..l
        };
        assert_eq!(hard.falloff(0.8001), 1.0);
        assert_eq!(hard.falloff(0.7999), 0.0);
    }
}
