//! Participating media after Fong, Wrenninge, Kulla, Habel 2017, "Production Volume Rendering" (SIGGRAPH
//! course), §4–5: a medium integrates its own interval of a ray and the light integrator never needs to know
//! which tracking method it uses.
//!
//! Every medium implements [`Medium`]:
//! - [`Medium::sample_free_flight`] proposes the distance of the next real collision (or none);
//! - [`Medium::free_flight_weight`] gives the path-throughput factor that makes that proposal unbiased
//!   (1 for analog methods such as closed-form or delta tracking of grey media);
//! - [`Medium::collision`] gives the albedo, emission and phase function at a collision;
//! - [`Medium::transmittance`] estimates beam transmittance for shadow rays.
//!
//! Overlapping media combine exactly: each proposes its own first collision and the nearest wins, because the
//! first event of independent exponential processes is the event of their sum (the integrator's
//! `MediumSegment`). Implementations, each the cheapest exact method for what it models:
//! - [`homogeneous`]: closed-form tracking, spectral MIS for chromatic extinction, no collisions at all when
//!   absorption-only (Beer's law);
//! - [`noise`]: the thesis's absorption-only procedural noise medium, ratio-tracked transmittance only;
//! - [`grid`]: VDB grids, delta tracking over subdivided majorants, ratio or residual ratio tracking for
//!   shadow rays.

pub mod density;
pub mod emission;
pub mod grid;
pub mod homogeneous;
pub mod majorant;
pub mod majorant_choice;
pub mod noise;
pub mod phase;
pub mod spec;
pub mod tracking;

use crate::math::{Aabb, Ray, Rgb, Rng, Vec3};
pub use grid::load_grid_medium;
pub use phase::PhaseFunction;
pub use spec::VolumeSpec;
pub use tracking::TrackingCounters;

/// What happens at a real collision inside a medium.
#[derive(Clone, Copy, Debug)]
pub struct Collision {
    /// Single-scattering albedo σ_s/σ_t per channel: the path continues with this weight.
    pub albedo: Rgb,
    /// Emitted radiance times σ_a/σ_t, added at the collision (collision estimator of emission).
    pub emission: Rgb,
    /// The phase function at the collision.
    pub phase: PhaseFunction,
}

/// A participating medium.
pub trait Medium: Send + Sync {
    /// Name for statistics and messages (the glTF node or material).
    fn name(&self) -> &str;

    /// The method used, as reported by `--stats` (e.g. "closed-form", "delta-tracking/adaptive").
    fn method(&self) -> String;

    /// Bytes held by the medium's own data (grids, majorants).
    fn memory_bytes(&self) -> usize {
        std::mem::size_of_val(self)
    }

    /// World bounds of the region the medium fills by position (VDB volumes), or `None` for a medium that fills
    /// the interior of a closed mesh (entered and left through its boundary).
    fn fill_bounds(&self) -> Option<Aabb>;

    /// Problems found in the medium's data (bad voxels replaced by zero), reported as warnings.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }

    /// True when the medium never scatters, so paths only need its transmittance.
    fn is_absorbing_only(&self) -> bool;

    /// Proposes the distance of the next real collision in `(0, t_max)`, or `None`. `throughput` is the path's
    /// current throughput, which chromatic media use to choose the channel to sample.
    fn sample_free_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Option<f32>;

    /// Throughput factor for the free flight from the ray origin to `t`: when `collided`, this medium's own
    /// collision at `t` (σ_t(t)·T(t)/p(t)); otherwise surviving to `t` (T(t)/P(no collision before t)).
    /// Analog samplers return 1 for both. `throughput` must be the value given to `sample_free_flight`.
    fn free_flight_weight(
        &self,
        ray: &Ray,
        t: f32,
        collided: bool,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb;

    /// Albedo, emission and phase function at a collision point.
    fn collision(&self, p: Vec3) -> Collision;

    /// An unbiased estimate of the transmittance over `(0, t_max)`.
    fn transmittance(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb;
}

/// Parses a material's `extras.nimbus_medium`: `{"sigma_a": [r,g,b], "sigma_s": [r,g,b], "anisotropy": g}`
/// (a homogeneous medium; defaults 0, 0, 0) or `{"noise": {"scale": s, "max_density": d, "seed": n}}` (the
/// absorption-only Perlin-noise medium). Errors say which key is wrong.
pub fn parse_nimbus_medium(
    spec: &serde_json::Value,
    name: &str,
) -> Result<std::sync::Arc<dyn Medium>, String> {
    let number = |key: &str, default: f64| -> Result<f64, String> {
        match spec.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .filter(|v| v.is_finite())
                .ok_or(format!("'{key}' must be a number")),
        }
    };
    if let Some(noise) = spec.get("noise") {
        let get = |key: &str, default: f64| -> Result<f64, String> {
            match noise.get(key) {
                None => Ok(default),
                Some(v) => v
                    .as_f64()
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .ok_or(format!("noise '{key}' must be a non-negative number")),
            }
        };
        let medium = noise::NoiseMedium::new(
            name,
            get("scale", 1.0)? as f32,
            get("max_density", 1.0)? as f32,
            get("seed", 0.0)? as u64,
        );
        return Ok(std::sync::Arc::new(medium));
    }
    let rgb = |key: &str| -> Result<Rgb, String> {
        match spec.get(key) {
            None => Ok(Rgb::ZERO),
            Some(v) => crate::scene::gltf::parse_rgb(v).ok_or(format!(
                "'{key}' must be three non-negative numbers per metre"
            )),
        }
    };
    let g = number("anisotropy", 0.0)?;
    if g.abs() >= 1.0 {
        return Err(format!("'anisotropy' {g} must lie in (-1, 1)"));
    }
    Ok(std::sync::Arc::new(homogeneous::HomogeneousMedium::new(
        name,
        rgb("sigma_a")?,
        rgb("sigma_s")?,
        g as f32,
    )))
}
