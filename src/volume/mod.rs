//! Participating media after Fong, Wrenninge, Kulla, Habel 2017, "Production Volume Rendering" (SIGGRAPH
//! course), §4–5: a medium integrates its own interval of a ray and the light integrator never needs to know
//! which tracking method it uses.
//!
//! Every medium implements [`Medium`]:
//! - [`Medium::free_flight`] answers for an interval of a ray: the next real collision (or none) and the path
//!   throughput the walk's weights leave ([`Flight`]; the weights are 1 for analog methods such as closed-form or
//!   delta tracking of grey media);
//! - [`Medium::collision`] gives the albedo, emission and phase function at a collision;
//! - an emitting medium gathers its emission along the free flight, at the tentative collisions of its walk
//!   (null or real), into [`TentativeEmission`] (Miller, Georgiev, Jarosz 2019, eq. 9, blended with the collision
//!   estimator: [`tracking::TentativeCollision::emission_weight`]), not only at the real collision;
//! - [`Medium::transmittance`] estimates beam transmittance for shadow rays.
//!
//! Overlapping media combine exactly: each flies in turn over the part of the segment before the nearest
//! collision of those before it (a walk cut at a distance independent of it stays unbiased, Kutz et al. 2017,
//! §5), so their free flights together sample the sum of their extinctions, whatever each one's estimator (the
//! integrator's `combined_flight`). Implementations, each the cheapest exact method for what it models:
//! - [`homogeneous`]: closed-form tracking, spectral MIS for chromatic extinction, no collisions at all when
//!   absorption-only (Beer's law);
//! - [`noise`]: the thesis's absorption-only procedural noise medium, ratio-tracked transmittance only;
//! - [`grid`]: VDB grids, delta tracking over subdivided majorants (spectral tracking for an RGB extinction),
//!   ratio or residual ratio tracking for shadow rays.

pub mod channels;
pub(crate) mod dda;
pub mod density;
pub mod emission;
pub mod error;
pub mod grid;
pub mod homogeneous;
pub mod majorant;
pub mod majorant_choice;
pub mod method;
pub mod noise;
pub mod phase;
pub mod spec;
pub mod tracking;
pub mod velocity;

use crate::math::sampling::TruncatedExponential;
use crate::math::{Aabb, Ray, Rgb, Rng, Vec2, Vec3};
use crate::params::{
    JsonParams, ParamDefault, ParamError, ParamKey, ParamRead, ParamType, UsdBinding,
};
pub use error::{DensityError, VolumeError};
pub use grid::load_grid_medium;
pub use method::{
    ChannelSampling, Chromatic, ChromaticTracking, FreeFlight, MediumMethod, MethodReason,
    TransmittanceMethod,
};
pub use phase::PhaseFunction;
pub use spec::{MissingFrame, VolumeSpec};
pub use tracking::TrackingCounters;

/// What happens at a real collision inside a medium.
#[derive(Clone, Copy, Debug)]
pub struct Collision {
    /// Single-scattering albedo σ_s/σ_t per channel: the path continues with this weight.
    pub albedo: Rgb,
    /// Emitted radiance times σ_a/σ_t at the point: what a real collision there would gather (the collision
    /// estimator of emission). Free flights gather it at every tentative collision instead, times σ_t/σ̄
    /// ([`TentativeEmission`]).
    pub emission: Rgb,
    /// The phase function at the collision.
    pub phase: PhaseFunction,
}

/// The light a medium emitted along one segment of a path, gathered at the tentative collisions of its free
/// flights: each sample is (ray parameter, radiance reaching the segment's start, already times the path
/// throughput the walk carried there). The integrator weights each sample by the transmittance of the media
/// that flew after its medium on the segment. Reused across segments (the buffer allocates only for emitting
/// media).
///
/// A flight that looked up [`Medium::collision`] at its real collision to gather the emission there keeps it
/// ([`Self::keep_real`]), so the integrator scattering there reads it instead of looking it up again
/// ([`Self::real_collision`]): the same pure function of the same point, so the image is unchanged.
#[derive(Clone, Debug, Default)]
pub struct TentativeEmission {
    samples: Vec<(f32, Rgb, u32)>,
    medium: u32,
    /// The medium, ray parameter and collision of the last real collision kept.
    real: Option<(u32, f32, Collision)>,
}

impl TentativeEmission {
    /// Empties the buffer for a new segment.
    pub fn clear(&mut self) {
        self.samples.clear();
        self.real = None;
    }

    /// Keeps `collision`, what [`Medium::collision`] gave at the real collision at ray parameter `t` of the
    /// medium last begun.
    pub fn keep_real(&mut self, t: f32, collision: Collision) {
        self.real = Some((self.medium, t, collision));
    }

    /// The collision kept for a real collision of medium `m` at ray parameter `t`, if its flight kept one.
    pub fn real_collision(&self, m: u32, t: f32) -> Option<Collision> {
        self.real
            .filter(|&(medium, at, _)| medium == m && at == t)
            .map(|(_, _, collision)| collision)
    }

    /// Makes the samples pushed next belong to medium `m` (the integrator's index).
    pub fn begin(&mut self, m: u32) {
        self.medium = m;
    }

    /// Adds `radiance` gathered at ray parameter `t` by the medium last begun.
    pub fn push(&mut self, t: f32, radiance: Rgb) {
        self.samples.push((t, radiance, self.medium));
    }

    /// The samples: (ray parameter, radiance, medium).
    pub fn samples(&self) -> &[(f32, Rgb, u32)] {
        &self.samples
    }
}

/// The coefficients of a scattering medium that are the same everywhere, as light-driven (equiangular)
/// sampling needs them: the transmittance over a distance t is exp(−σ_t t) in closed form.
#[derive(Clone, Copy, Debug)]
pub struct ConstantScattering {
    /// Scattering coefficient per metre, per channel.
    pub sigma_s: Rgb,
    /// Extinction coefficient per metre, per channel.
    pub sigma_t: Rgb,
    /// The phase function.
    pub phase: PhaseFunction,
    /// How [`Medium::free_flight`] samples distances: `None` for one exponential shared by every channel (grey
    /// σ_t), else the channel choice of its spectral MIS.
    pub spectral_mis: Option<ChannelSampling>,
}

impl ConstantScattering {
    /// The transmittance exp(−σ_t t) per channel over a distance `t`.
    pub fn transmittance(&self, t: f32) -> Rgb {
        homogeneous::beer_lambert(self.sigma_t, t)
    }

    /// Density, per metre, with which [`Medium::free_flight`] returns a real collision at distance `t` for a
    /// path of `throughput`: σ_t exp(−σ_t t) for grey σ_t, else the channel mixture Σ_c w_c σ_c exp(−σ_c t) of
    /// spectral MIS. The other strategy in the multiple importance sampling of equiangular sampling.
    pub fn free_flight_pdf(&self, t: f32, throughput: Rgb) -> f32 {
        let density = self.sigma_t * self.transmittance(t);
        match self.spectral_mis {
            None => density.x,
            Some(choice) => density.dot(homogeneous::channel_weights(choice, throughput)),
        }
    }

    /// The path throughput after a real collision at `t` returned by [`Medium::free_flight`] for a path of
    /// `throughput`, and the collision's albedo: `throughput` σ_s/σ_t for grey σ_t, else `throughput`
    /// σ_s T(t) / p̄(t) with p̄ the spectral-MIS mixture ([`Self::free_flight_pdf`]).
    pub fn throughput_at_collision(&self, t: f32, throughput: Rgb) -> Rgb {
        let albedo = homogeneous::albedo(self.sigma_s, self.sigma_t);
        if self.spectral_mis.is_none() {
            return throughput * albedo;
        }
        let pdf = self.free_flight_pdf(t, throughput);
        if pdf > 0.0 {
            throughput * (self.sigma_t * self.transmittance(t) / pdf) * albedo
        } else {
            Rgb::ZERO
        }
    }

    /// The channel mixture whose truncated exponentials [`Self::sample_in_segment`] draws from: the spectral-MIS
    /// channel probabilities of a path of `throughput`, or channel 0 alone for grey σ_t.
    fn segment_channels(&self, throughput: Rgb) -> Rgb {
        match self.spectral_mis {
            None => Rgb::new(1.0, 0.0, 0.0),
            Some(choice) => homogeneous::channel_weights(choice, throughput),
        }
    }

    /// A distance on a segment `[0, length]` from `u`, drawn from the free-flight density truncated to the
    /// segment (Novák et al. 2018, §5: a point on every segment, where free flights collide with probability
    /// 1 − T(length)), and its density ([`Self::segment_pdf`]): for chromatic σ_t a channel is chosen by `u.y`
    /// as free flights choose it (throughput-proportional spectral MIS) and its truncated exponential sampled
    /// by `u.x`. `None` for an unbounded or empty segment.
    pub fn sample_in_segment(&self, u: Vec2, length: f32, throughput: Rgb) -> Option<(f32, f32)> {
        let channel = homogeneous::channel_of(self.segment_channels(throughput), u.y);
        let (t, _) = TruncatedExponential::new(self.sigma_t[channel], length)?.sample(u.x);
        Some((t, self.segment_pdf(t, length, throughput)))
    }

    /// Density, per metre, of [`Self::sample_in_segment`] at `t`: the mixture Σ_c w_c σ_c e^{−σ_c t} /
    /// (1 − e^{−σ_c length}) over the channel probabilities w_c (one term for grey σ_t).
    pub fn segment_pdf(&self, t: f32, length: f32, throughput: Rgb) -> f32 {
        let w = self.segment_channels(throughput);
        (0..3)
            .filter(|&c| w[c] > 0.0)
            .filter_map(|c| {
                TruncatedExponential::new(self.sigma_t[c], length).map(|d| w[c] * d.pdf(t))
            })
            .sum()
    }
}

/// What one free flight through a medium ([`Medium::free_flight`]) did: where it collided, and the path
/// throughput that the walk's weights leave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flight {
    /// The parameter of the real collision, or `None` when the path left the interval.
    pub collision: Option<f32>,
    /// The path throughput after the flight: the throughput it started with, times σ_t(x) T(x)/p(x) at the
    /// collision, or T/P(no collision) on leaving, per channel.
    pub throughput: Rgb,
}

/// A participating medium.
pub trait Medium: Send + Sync {
    /// Name for statistics and messages (the glTF node or material).
    fn name(&self) -> &str;

    /// The method used and why, as reported by `--explain` (its `Display`) and `--stats`.
    fn method(&self) -> MediumMethod;

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

    /// True when the medium emits light (a grid with a blackbody temperature field), so that a scene lit only
    /// by it is not unlit.
    fn is_emissive(&self) -> bool {
        false
    }

    /// The free flight of a path through this medium over `(0, t_max)` of `ray`, as if the medium were alone
    /// there: the next real collision (or none), and the path throughput `throughput` times the weight of the
    /// whole walk (σ_t·T/p at a collision, T/P(no collision) on passing, with any spectral-MIS or
    /// spectral-tracking weights; 1 for analog samplers). The walk is unbiased for every channel: the expected
    /// weighted outcome is the collision integral ∫ σ_t T h + T(t_max) h(t_max) for any function h of where the
    /// flight ends. An emitting medium pushes its emission at each tentative collision into `emission`, already
    /// times the path throughput there. A medium that never collides ([`Medium::is_absorbing_only`]) returns
    /// no collision and its transmittance estimate to `t_max` as the weight.
    ///
    /// This one answer is all the integrator asks of a medium along a path: where media overlap, each answers
    /// for the interval up to the nearest collision of those asked before it (see the integrator's
    /// `sample_segment_media`).
    fn free_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        emission: &mut TentativeEmission,
    ) -> Flight;

    /// Albedo, emission and phase function at a collision point, for a ray at `time` (frames from the frame;
    /// a moving medium reads its values where they were at the frame).
    fn collision(&self, p: Vec3, time: f32) -> Collision;

    /// An unbiased estimate of the transmittance over `(0, t_max)`: [`Medium::weighted_transmittance`] with
    /// weight 1.
    fn transmittance(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb {
        self.weighted_transmittance(1.0, ray, t_max, rng, counters)
    }

    /// An unbiased estimate of `weight` times the transmittance over `(0, t_max)`; `weight` is 1 for an
    /// ordinary shadow ray and 1/q for one that guided shadow roulette kept with probability q
    /// (`crate::guiding::shadow`). Every medium decides how the weight enters its estimate, so there is no
    /// default: a closed-form transmittance multiplies by it, but an estimator that plays Russian roulette of
    /// its own (ratio tracking's, below a threshold of its running estimate) must start its walk from the
    /// weight, or the two roulettes compound and the shadow ray's variance grows with the weight.
    fn weighted_transmittance(
        &self,
        weight: f32,
        ray: &Ray,
        t_max: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb;

    /// The medium's coefficients when they are constant and it scatters, so that the integrator can also
    /// sample its segments toward point and spot lights (equiangular sampling); `None` (the default) for media
    /// whose transmittance has no closed form.
    fn constant_scattering(&self) -> Option<ConstantScattering> {
        None
    }
}

const NO_USD: UsdBinding = UsdBinding::Elsewhere("none (glTF only)");

const SIGMA_A: ParamKey = ParamKey {
    name: "sigma_a",
    ty: ParamType::Rgb,
    default: ParamDefault::Rgb([0.0; 3]),
    doc: "absorption coefficient per metre (homogeneous medium)",
    usd: NO_USD,
};
const SIGMA_S: ParamKey = ParamKey {
    name: "sigma_s",
    ty: ParamType::Rgb,
    default: ParamDefault::Rgb([0.0; 3]),
    doc: "scattering coefficient per metre (homogeneous medium)",
    usd: NO_USD,
};
const ANISOTROPY: ParamKey = ParamKey {
    name: "anisotropy",
    ty: ParamType::Number,
    default: ParamDefault::Number(0.0),
    doc: "Henyey–Greenstein g, in (−1, 1)",
    usd: NO_USD,
};
const NOISE_SCALE: ParamKey = ParamKey {
    name: "scale",
    ty: ParamType::NonNegative,
    default: ParamDefault::Number(1.0),
    doc: "noise frequency per metre",
    usd: NO_USD,
};
const NOISE_MAX_DENSITY: ParamKey = ParamKey {
    name: "max_density",
    ty: ParamType::NonNegative,
    default: ParamDefault::Number(1.0),
    doc: "the largest σ_a per metre",
    usd: NO_USD,
};
const NOISE_SEED: ParamKey = ParamKey {
    name: "seed",
    ty: ParamType::NonNegative,
    default: ParamDefault::Number(0.0),
    doc: "the noise's permutation seed (an integer)",
    usd: NO_USD,
};
/// The keys of `nimbus_medium.noise`.
const NOISE_KEYS: &[ParamKey] = &[NOISE_SCALE, NOISE_MAX_DENSITY, NOISE_SEED];
const NOISE: ParamKey = ParamKey {
    name: "noise",
    ty: ParamType::Object(NOISE_KEYS),
    default: ParamDefault::Unset,
    doc: "instead of the above: the absorption-only Perlin-noise medium",
    usd: NO_USD,
};

/// The keys of a material's `extras.nimbus_medium` (a closed mesh's interior), in docs/reference.md's order.
pub const MEDIUM_KEYS: &[ParamKey] = &[SIGMA_A, SIGMA_S, ANISOTROPY, NOISE];

/// Parses a material's `extras.nimbus_medium` ([`MEDIUM_KEYS`]): `{"sigma_a": [r,g,b], "sigma_s": [r,g,b],
/// "anisotropy": g}` (a homogeneous medium; defaults 0, 0, 0) or `{"noise": {"scale": s, "max_density": d,
/// "seed": n}}` (the absorption-only Perlin-noise medium). Errors say which key is wrong.
pub fn parse_nimbus_medium(
    spec: &serde_json::Value,
    name: &str,
) -> Result<std::sync::Arc<dyn Medium>, VolumeError> {
    Ok(match MediumParams::from_json(spec)? {
        MediumParams::Homogeneous {
            sigma_a,
            sigma_s,
            anisotropy,
        } => std::sync::Arc::new(homogeneous::HomogeneousMedium::new(
            name, sigma_a, sigma_s, anisotropy,
        )),
        MediumParams::Noise {
            scale,
            max_density,
            seed,
        } => std::sync::Arc::new(noise::NoiseMedium::new(name, scale, max_density, seed)),
    })
}

/// The values of a `nimbus_medium` declaration, each key absent from the file at its [`MEDIUM_KEYS`] default.
#[derive(Clone, Debug, PartialEq)]
enum MediumParams {
    /// `sigma_a`, `sigma_s`, `anisotropy`.
    Homogeneous {
        sigma_a: Rgb,
        sigma_s: Rgb,
        anisotropy: f32,
    },
    /// The keys of `noise`.
    Noise {
        scale: f32,
        max_density: f32,
        seed: u64,
    },
}

impl MediumParams {
    /// Reads and checks the declaration; a key's default is taken from its table (`*_or_default`).
    fn from_json(spec: &serde_json::Value) -> Result<Self, ParamError> {
        let params = JsonParams::new(spec);
        if let Some(noise) = params.nested(&NOISE)? {
            return Ok(Self::Noise {
                scale: noise.number_f64_or_default(&NOISE_SCALE)? as f32,
                max_density: noise.number_f64_or_default(&NOISE_MAX_DENSITY)? as f32,
                seed: noise.number_f64_or_default(&NOISE_SEED)? as u64,
            });
        }
        let g = params.number_f64_or_default(&ANISOTROPY)?;
        if g.abs() >= 1.0 {
            return Err(ParamError::OutOfRange {
                key: ANISOTROPY.name.to_owned(),
                value: g.to_string(),
                constraint: "lie in (-1, 1)",
            });
        }
        Ok(Self::Homogeneous {
            sigma_a: params.rgb_or_default(&SIGMA_A)?,
            sigma_s: params.rgb_or_default(&SIGMA_S)?,
            anisotropy: g as f32,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// Every key of `keys` with a default is given it in turn inside `wrap` (the declaration around the keys);
    /// the result must be the declaration that omits it.
    fn check_defaults(
        keys: &[ParamKey],
        wrap: impl Fn(serde_json::Value) -> serde_json::Value,
    ) -> usize {
        let omitted = MediumParams::from_json(&wrap(json!({}))).unwrap();
        let mut checked = 0;
        for key in keys {
            let Some(default) = crate::params::default_as_json(key) else {
                continue;
            };
            let given = MediumParams::from_json(&wrap(json!({key.name: default}))).unwrap();
            assert_eq!(
                given, omitted,
                "'{}' given as its default {default}",
                key.name
            );
            checked += 1;
        }
        checked
    }

    #[test]
    fn omitting_a_medium_key_is_giving_its_table_default() {
        assert_eq!(check_defaults(MEDIUM_KEYS, |keys| keys), 3);
        assert_eq!(check_defaults(NOISE_KEYS, |keys| json!({"noise": keys})), 3);
    }
}
