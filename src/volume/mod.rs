//! Participating media after Fong, Wrenninge, Kulla, Habel 2017, "Production Volume Rendering" (SIGGRAPH
//! course), §4–5: a medium integrates its own interval of a ray and the light integrator never needs to know
//! which tracking method it uses.
//!
//! Every medium implements [`Medium`]:
//! - [`Medium::sample_free_flight`] proposes the distance of the next real collision (or none);
//! - [`Medium::free_flight_weight`] gives the path-throughput factor that makes that proposal unbiased
//!   (1 for analog methods such as closed-form or delta tracking of grey media);
//! - [`Medium::collision`] gives the albedo, emission and phase function at a collision;
//! - an emitting medium gathers its emission along the free flight, at the tentative collisions of its walk
//!   (null or real), into [`TentativeEmission`] (Miller, Georgiev, Jarosz 2019, eq. 9, blended with the collision
//!   estimator: [`tracking::TentativeCollision::emission_weight`]), not only at the real collision;
//! - [`Medium::transmittance`] estimates beam transmittance for shadow rays.
//!
//! Overlapping media combine exactly: each proposes its own first collision and the nearest wins, because the
//! first event of independent exponential processes is the event of their sum (the integrator's
//! `MediumSegment`). Implementations, each the cheapest exact method for what it models:
//! - [`homogeneous`]: closed-form tracking, spectral MIS for chromatic extinction, no collisions at all when
//!   absorption-only (Beer's law);
//! - [`noise`]: the thesis's absorption-only procedural noise medium, ratio-tracked transmittance only;
//! - [`grid`]: VDB grids, delta tracking over subdivided majorants (spectral tracking for an RGB extinction),
//!   ratio or residual ratio tracking for shadow rays.

pub mod channels;
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

use crate::math::{Aabb, Ray, Rgb, Rng, Vec3};
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
pub use tracking::{SpectralFlight, TrackingCounters};

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
/// throughput the flight started with). A sample counts only where the path has not collided before it in
/// another medium; the integrator weights it by the other media's survival there. Reused across segments (the
/// buffer allocates only for emitting media).
#[derive(Clone, Debug, Default)]
pub struct TentativeEmission {
    samples: Vec<(f32, Rgb, u32)>,
    medium: u32,
}

impl TentativeEmission {
    /// Empties the buffer for a new segment.
    pub fn clear(&mut self) {
        self.samples.clear();
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

    /// True when σ_t varies by channel in a way [`Medium::sample_free_flight`] cannot sample for all channels at
    /// once (an RGB density grid): the integrator then makes the path carry one channel before the medium tracks
    /// it, unless the medium is alone on the segment and tracks it spectrally ([`Medium::spectral_free_flight`]).
    fn is_chromatic(&self) -> bool {
        false
    }

    /// Spectral tracking of a segment `(0, t_max)` that this medium fills alone: the next real collision and the
    /// path throughput that the walk's weights leave, for all channels at once; `None` when the medium does not
    /// track spectrally (the default), and the integrator uses [`Medium::sample_free_flight`]. The weights depend
    /// on the whole walk, not only on where it ended, which is why a segment shared with other media (whose
    /// collision may come first) does not use it. An emitting medium pushes its emission at each tentative
    /// collision into `emission`, times the walk's throughput there.
    fn spectral_free_flight(
        &self,
        _ray: &Ray,
        _t_max: f32,
        _throughput: Rgb,
        _rng: &mut Rng,
        _counters: &mut TrackingCounters,
        _emission: &mut TentativeEmission,
    ) -> Option<SpectralFlight> {
        None
    }

    /// Proposes the distance of the next real collision in `(0, t_max)`, or `None`. `throughput` is the path's
    /// current throughput, which chromatic media use to choose the channel to sample. An emitting medium pushes
    /// its emission at each tentative collision into `emission`, times `throughput`.
    fn sample_free_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        emission: &mut TentativeEmission,
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

    /// Albedo, emission and phase function at a collision point, for a ray at `time` (frames from the frame;
    /// a moving medium reads its values where they were at the frame).
    fn collision(&self, p: Vec3, time: f32) -> Collision;

    /// An unbiased estimate of the transmittance over `(0, t_max)`.
    fn transmittance(
        &self,
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

    /// Density, per metre, with which [`Medium::sample_free_flight`] returns a real collision at distance `t`
    /// for a path of `throughput`: the other strategy in the multiple importance sampling of equiangular
    /// sampling. Only media with [`Medium::constant_scattering`] need it; the default is 0.
    fn free_flight_pdf(&self, _t: f32, _throughput: Rgb) -> f32 {
        0.0
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
    let params = JsonParams::new(spec);
    if let Some(noise) = params.nested(&NOISE)? {
        let get = |key: &ParamKey, default: f64| -> Result<f64, ParamError> {
            Ok(noise.number_f64(key)?.unwrap_or(default))
        };
        let medium = noise::NoiseMedium::new(
            name,
            get(&NOISE_SCALE, 1.0)? as f32,
            get(&NOISE_MAX_DENSITY, 1.0)? as f32,
            get(&NOISE_SEED, 0.0)? as u64,
        );
        return Ok(std::sync::Arc::new(medium));
    }
    let g = params.number_f64(&ANISOTROPY)?.unwrap_or(0.0);
    if g.abs() >= 1.0 {
        return Err(ParamError::OutOfRange {
            key: ANISOTROPY.name.to_owned(),
            value: g.to_string(),
            constraint: "lie in (-1, 1)",
        }
        .into());
    }
    Ok(std::sync::Arc::new(homogeneous::HomogeneousMedium::new(
        name,
        params.rgb(&SIGMA_A)?.unwrap_or(Rgb::ZERO),
        params.rgb(&SIGMA_S)?.unwrap_or(Rgb::ZERO),
        g as f32,
    )))
}
