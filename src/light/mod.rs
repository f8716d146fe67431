//! Lights: emissive triangles (area lights), glTF punctual lights, the environment, and the light-selection
//! distributions: by power, or by importance at the shading point through a light BVH. Every light samples incident illumination at a point (`Light::sample_li`) and
//! gives the solid-angle density of that sampling for multiple importance sampling.

mod area;
mod bvh;
mod environment;
mod punctual;
mod sampler;

pub use environment::{EnvironmentError, EnvironmentLight, EnvironmentMap};
pub use sampler::LightSamplerChoice;
internal! {
    pub use area::AreaLight;
    pub use bvh::{LightBvh, LightContext};
    pub use punctual::{DirectionalLight, PointLight, SpotLight, LUMENS_PER_WATT};
    pub use sampler::LightSampler;
}
#[cfg(feature = "testing")]
pub use sampler::{BVH_MIN_BOUNDED_LIGHTS, BVH_MIN_EMITTERS};

use crate::geometry::{ShadowSegment, SurfacePoint};
use crate::material::Texture;
use crate::math::{Rgb, Vec2, Vec3};

/// Incident illumination sampled from a light at a receiving point.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightSample {
    /// Unit direction from the receiving point toward the light.
    pub wi: Vec3,
    /// Incident radiance along `wi` (for delta lights, the irradiance-producing intensity already divided by
    /// the squared distance).
    pub radiance: Rgb,
    /// Solid-angle density of choosing `wi` (1 for delta lights, whose `is_delta` is set).
    pub pdf: f32,
    /// The sampled point on the light, with its rounding-error bound and surface normal; `None` for lights at
    /// infinity (directional, environment).
    pub point: Option<SurfacePoint>,
    /// True for point, spot and directional lights, which MIS cannot hit.
    pub is_delta: bool,
}

impl LightSample {
    /// The shadow ray that tests whether the light sample is visible from `from`: a segment between offset end
    /// points for a point on a light, an unbounded ray toward a light at infinity (see
    /// [`crate::geometry::SurfacePoint`]). `None` when the two ends coincide.
    pub fn shadow_segment(&self, from: &SurfacePoint) -> Option<ShadowSegment> {
        match &self.point {
            Some(to) => ShadowSegment::between(from, to),
            None => Some(ShadowSegment::toward_infinity(from, self.wi)),
        }
    }

    /// Distance from `p` to the sampled point; infinite for lights at infinity.
    #[cfg(test)]
    pub fn distance_from(&self, p: Vec3) -> f32 {
        self.point.map_or(f32::INFINITY, |q| q.p.distance(p))
    }
}

/// The lights of a scene counted by kind, in words: "36 emissive triangles, 1 punctual light, an environment"
/// ("no lights" for none). Every message that counts lights uses it, so they agree.
pub(crate) fn describe_lights(lights: &[Light]) -> String {
    let triangles = lights
        .iter()
        .filter(|l| matches!(l, Light::Area(_)))
        .count();
    let environment = lights.iter().any(|l| matches!(l, Light::Environment(_)));
    let punctual = lights.len() - triangles - usize::from(environment);
    let mut parts = Vec::new();
    if triangles > 0 {
        parts.push(counted(
            triangles,
            "emissive triangle",
            "emissive triangles",
        ));
    }
    if punctual > 0 {
        parts.push(counted(punctual, "punctual light", "punctual lights"));
    }
    if environment {
        parts.push("an environment".to_owned());
    }
    if parts.is_empty() {
        "no lights".to_owned()
    } else {
        parts.join(", ")
    }
}

/// `n` things in words: "1 punctual light" (`one`) or "3 punctual lights" (`many`).
pub(crate) fn counted(n: usize, one: &str, many: &str) -> String {
    match n {
        1 => format!("1 {one}"),
        _ => format!("{n} {many}"),
    }
}

internal! {
    /// One light of the scene.
    #[derive(Clone, Debug)]
    pub enum Light {
        /// An emissive triangle.
        Area(AreaLight),
        /// KHR_lights_punctual point light.
        Point(PointLight),
        /// KHR_lights_punctual spot light.
        Spot(SpotLight),
        /// KHR_lights_punctual directional light.
        Directional(DirectionalLight),
        /// Light arriving from infinitely far away in every direction.
        Environment(EnvironmentLight),
    }
}

impl Light {
    /// Samples the light as seen from `p`.
    pub fn sample_li(&self, p: Vec3, u: Vec2, textures: &[Texture]) -> Option<LightSample> {
        match self {
            Light::Area(l) => l.sample_li(p, u, textures),
            Light::Point(l) => l.sample_li(p),
            Light::Spot(l) => l.sample_li(p),
            Light::Directional(l) => Some(l.sample_li()),
            Light::Environment(l) => l.sample_li(u),
        }
    }

    /// Total emitted power (up to a constant shared by all lights), for the light-selection distribution.
    /// `scene_radius` sizes the disc that lights at infinity illuminate.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let disc = std::f32::consts::PI * scene_radius * scene_radius;
        match self {
            Light::Area(l) => l.power(),
            Light::Point(l) => l.power(),
            Light::Spot(l) => l.power(),
            Light::Directional(l) => crate::math::luminance(l.irradiance) * disc,
            Light::Environment(l) => l.average_luminance() * std::f32::consts::PI * disc,
        }
    }

    /// The position of a light that shines from one point (point and spot lights), toward which segments
    /// through media can be sampled equiangularly; `None` for every other light.
    pub fn point_position(&self) -> Option<Vec3> {
        match self {
            Light::Point(l) => Some(l.position),
            Light::Spot(l) => Some(l.position),
            _ => None,
        }
    }

    /// True for lights at infinity (directional and environment), which have no position: the light BVH
    /// chooses them apart from the bounded lights.
    pub fn is_at_infinity(&self) -> bool {
        matches!(self, Light::Directional(_) | Light::Environment(_))
    }

    /// True for lights that cannot be hit by a ray (delta position or direction).
    #[cfg(test)]
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Light::Point(_) | Light::Spot(_) | Light::Directional(_)
        )
    }
}
