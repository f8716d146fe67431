//! Homogeneous media: constant coefficients, tracked in closed form.
//!
//! Declared by:
//! - `KHR_materials_volume` on a closed mesh with transmission and `thicknessFactor` > 0: absorption only,
//!   σ_a = −ln(`attenuationColor`) / `attenuationDistance` (Beer's law, the thesis's homogeneous volume);
//! - material `extras.nimbus_medium`: `{"sigma_a": [r,g,b], "sigma_s": [r,g,b], "anisotropy": g}` per metre
//!   (defaults: 0, 0, 0).
//!
//! Methods ("model no more than a scene needs"):
//! - absorption only: no collision is ever sampled; the path is weighted by T = exp(−σ_a d);
//! - grey σ_t: analog free-flight sampling by inverting Beer–Lambert, t = −ln(1−u)/σ_t (weights are 1);
//! - chromatic σ_t: one-sample spectral MIS (Miller, Georgiev, Jarosz 2019, "A null-scattering path integral
//!   formulation of light transport", §5.2; the balance heuristic over channels): a channel is chosen with
//!   probability proportional to the path's throughput in it (as Cycles and Mitsuba 3 do), and its exponential
//!   sampled; the pdf is the mixture p̄(t) = Σ_c w_c σ_c exp(−σ_c t), so the throughput weight
//!   σ_t T(t) / p̄(t) stays bounded for any chromaticity.
//!
//! [`ChannelChoice`] overrides the automatic pick, so that benchmarks (`cargo bench --bench method_choices`) can
//! measure what each choice wins: forced spectral MIS on a grey medium, or a uniform channel choice.

use super::{
    ChannelSampling, Collision, ConstantScattering, Flight, FreeFlight, Medium, MediumMethod,
    MethodReason, PhaseFunction, TentativeEmission, TrackingCounters, TransmittanceMethod,
};
use crate::math::{Aabb, Ray, Rgb, Rng, Vec3};

/// How free-flight sampling picks the channel whose exponential it samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChannelChoice {
    /// Grey σ_t samples its one exponential with weight 1; chromatic σ_t uses [`ChannelChoice::Throughput`].
    #[default]
    Auto,
    /// Spectral MIS with channel probabilities ∝ path throughput, even when σ_t is grey.
    #[cfg(any(test, feature = "testing"))]
    Throughput,
    /// Spectral MIS with each channel chosen with probability 1/3 (the mixture pdf of hero-wavelength
    /// sampling); its weights grow with the path's chromatic history.
    #[cfg(any(test, feature = "testing"))]
    Uniform,
}

/// A medium with constant σ_a, σ_s and phase function.
#[derive(Clone, Debug)]
pub struct HomogeneousMedium {
    name: String,
    sigma_s: Rgb,
    sigma_t: Rgb,
    phase: PhaseFunction,
    channel_choice: ChannelChoice,
}

/// Beer–Lambert transmittance `exp(−σ t)` per channel over a distance `t ≥ 0` that may be infinite (a path
/// that leaves the scene with this medium still on its stack: an open or unclosed mesh): 0 where σ > 0 and
/// `t = ∞`, and exactly 1 where σ = 0, for any `t`. The plain product `σ t` would be `0 · ∞`, a NaN, there
/// (issue 33: NaN samples from glass whose `attenuationColor` is 1 in a channel).
pub(crate) fn beer_lambert(sigma: Rgb, t: f32) -> Rgb {
    let channel = |s: f32| if s > 0.0 { (-s * t).exp() } else { 1.0 };
    Rgb::new(channel(sigma.x), channel(sigma.y), channel(sigma.z))
}

impl HomogeneousMedium {
    /// A medium with absorption `sigma_a` and scattering `sigma_s` per metre and Henyey–Greenstein `g`.
    pub fn new(name: &str, sigma_a: Rgb, sigma_s: Rgb, g: f32) -> Self {
        let sigma_a = sigma_a.max(Rgb::ZERO);
        let sigma_s = sigma_s.max(Rgb::ZERO);
        Self {
            name: name.to_owned(),
            sigma_s,
            sigma_t: sigma_a + sigma_s,
            phase: PhaseFunction::henyey_greenstein(g),
            channel_choice: ChannelChoice::Auto,
        }
    }

    /// The same medium with free-flight channels chosen by `choice` instead of automatically.
    #[cfg(any(test, feature = "testing"))]
    pub fn with_channel_choice(mut self, choice: ChannelChoice) -> Self {
        self.channel_choice = choice;
        self
    }

    /// True when free flights sample one exponential shared by all channels (weights 1, no MIS).
    fn samples_single_channel(&self) -> bool {
        self.channel_choice == ChannelChoice::Auto && self.is_grey()
    }

    /// How spectral MIS chooses channels: `None` when free flights sample one exponential.
    fn spectral_mis(&self) -> Option<ChannelSampling> {
        match self.channel_choice {
            _ if self.samples_single_channel() => None,
            #[cfg(any(test, feature = "testing"))]
            ChannelChoice::Uniform => Some(ChannelSampling::Uniform),
            _ => Some(ChannelSampling::Throughput),
        }
    }

    /// Proposes the distance of the next real collision in `(0, t_max)`, or `None`: the exponential of one
    /// channel, chosen by spectral MIS for a path of `throughput` unless σ_t is grey.
    fn sample_distance(
        &self,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Option<f32> {
        if self.is_absorbing_only() {
            return None;
        }
        let channel = match self.spectral_mis() {
            None => 0,
            Some(choice) => channel_of(channel_weights(choice, throughput), rng.next_f32()),
        };
        let sigma = self.sigma_t[channel];
        let u = rng.next_f32();
        if sigma <= 0.0 {
            return None;
        }
        let t = -(1.0 - u).ln() / sigma;
        (t < t_max).then(|| {
            counters.real_collisions += 1;
            t
        })
    }

    /// The throughput factor of a flight that ends at `t`: when `collided`, σ_t T(t) / p̄(t) with p̄ the
    /// mixture density Σ_c w_c σ_c exp(−σ_c t) of the channels' exponentials; otherwise T(t) / P(no collision
    /// before t). 1 for both without spectral MIS; T(t) for an absorber.
    fn flight_weight(&self, t: f32, collided: bool, throughput: Rgb) -> Rgb {
        let transmittance = beer_lambert(self.sigma_t, t);
        if self.is_absorbing_only() {
            return transmittance;
        }
        let Some(choice) = self.spectral_mis() else {
            return Rgb::ONE;
        };
        let w = channel_weights(choice, throughput);
        if collided {
            let pdf = (self.sigma_t * transmittance).dot(w);
            if pdf > 0.0 {
                self.sigma_t * transmittance / pdf
            } else {
                Rgb::ZERO
            }
        } else {
            let p = transmittance.dot(w);
            if p > 0.0 {
                transmittance / p
            } else {
                Rgb::ZERO
            }
        }
    }

    /// True when all channels share one σ_t.
    pub fn is_grey(&self) -> bool {
        self.sigma_t.x == self.sigma_t.y && self.sigma_t.y == self.sigma_t.z
    }

    /// Extinction per channel.
    #[cfg(any(test, feature = "testing"))]
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_t
    }
}

impl Medium for HomogeneousMedium {
    fn name(&self) -> &str {
        &self.name
    }

    fn method(&self) -> MediumMethod {
        let (free_flight, why) = if self.is_absorbing_only() {
            (FreeFlight::None, MethodReason::AbsorptionOnly)
        } else if self.samples_single_channel() {
            (FreeFlight::ClosedForm, MethodReason::GreyExtinction)
        } else {
            match (self.channel_choice, self.is_grey()) {
                #[cfg(any(test, feature = "testing"))]
                (ChannelChoice::Uniform, _) => (
                    FreeFlight::SpectralMis(ChannelSampling::Uniform),
                    MethodReason::Forced,
                ),
                (_, true) => (
                    FreeFlight::SpectralMis(ChannelSampling::Throughput),
                    MethodReason::Forced,
                ),
                (_, false) => (
                    FreeFlight::SpectralMis(ChannelSampling::Throughput),
                    MethodReason::ChromaticExtinction,
                ),
            }
        };
        MediumMethod {
            free_flight,
            majorant: None,
            shadow: TransmittanceMethod::ClosedForm,
            why,
        }
    }

    fn fill_bounds(&self) -> Option<Aabb> {
        None
    }

    fn is_absorbing_only(&self) -> bool {
        self.sigma_s.max_element() <= 0.0
    }

    fn free_flight(
        &self,
        _ray: &Ray,
        t_max: f32,
        throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
        _emission: &mut TentativeEmission,
    ) -> Flight {
        let collision = self.sample_distance(t_max, throughput, rng, counters);
        let weight =
            self.flight_weight(collision.unwrap_or(t_max), collision.is_some(), throughput);
        Flight {
            collision,
            throughput: throughput * weight,
        }
    }

    fn collision(&self, _p: Vec3, _time: f32) -> Collision {
        // The weight σ_t T/p̄ multiplies by σ_t per channel, so the albedo here is σ_s/σ_t per channel and the
        // product is σ_s T/p̄, as the radiative transfer equation needs.
        Collision {
            albedo: albedo(self.sigma_s, self.sigma_t),
            emission: Rgb::ZERO,
            phase: self.phase,
        }
    }

    /// Beer–Lambert's closed form times the weight: exact, so no roulette of its own to compound.
    fn weighted_transmittance(
        &self,
        weight: f32,
        _ray: &Ray,
        t_max: f32,
        _rng: &mut Rng,
        _c: &mut TrackingCounters,
    ) -> Rgb {
        beer_lambert(self.sigma_t, t_max) * weight
    }

    fn constant_scattering(&self) -> Option<ConstantScattering> {
        (!self.is_absorbing_only()).then_some(ConstantScattering {
            sigma_s: self.sigma_s,
            sigma_t: self.sigma_t,
            phase: self.phase,
            spectral_mis: self.spectral_mis(),
        })
    }
}

/// Channel-selection probabilities of spectral MIS by `choice` for a path of `throughput`.
pub(crate) fn channel_weights(choice: ChannelSampling, throughput: Rgb) -> Rgb {
    match choice {
        #[cfg(any(test, feature = "testing"))]
        ChannelSampling::Uniform => Rgb::splat(1.0 / 3.0),
        ChannelSampling::Throughput => throughput_weights(throughput),
    }
}

/// The channel that `u` ∈ \[0, 1) picks with the channel probabilities `w`: the first whose running sum of
/// probabilities exceeds `u`.
pub(crate) fn channel_of(w: Rgb, u: f32) -> usize {
    if u < w.x {
        0
    } else if u < w.x + w.y {
        1
    } else {
        2
    }
}

/// Channel-selection probabilities ∝ throughput (uniform when the throughput is zero or not finite).
fn throughput_weights(throughput: Rgb) -> Rgb {
    let t = throughput.abs();
    let sum = t.x + t.y + t.z;
    if sum > 0.0 && sum.is_finite() {
        t / sum
    } else {
        Rgb::splat(1.0 / 3.0)
    }
}

/// The scattering albedo σ_s/σ_t per channel, 0 where σ_t is 0.
pub(crate) fn albedo(sigma_s: Rgb, sigma_t: Rgb) -> Rgb {
    Rgb::new(
        ratio(sigma_s.x, sigma_t.x),
        ratio(sigma_s.y, sigma_t.y),
        ratio(sigma_s.z, sigma_t.z),
    )
}

fn ratio(a: f32, b: f32) -> f32 {
    if b > 0.0 {
        (a / b).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Transmittance estimated as the weighted fraction of free flights that pass a slab of depth `d`,
    /// compared with exp(−σ_t d) per channel within 4 standard errors.
    fn check_slab(m: &HomogeneousMedium, d: f32) {
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        let mut rng = Rng::new(11, 5);
        let mut c = TrackingCounters::default();
        let n = 200_000;
        let mut sum = [0.0f64; 3];
        let mut sum2 = [0.0f64; 3];
        for _ in 0..n {
            let flight = m.free_flight(
                &ray,
                d,
                Rgb::ONE,
                &mut rng,
                &mut c,
                &mut TentativeEmission::default(),
            );
            let w = match flight.collision {
                Some(_) => Rgb::ZERO,
                None => flight.throughput,
            };
            for k in 0..3 {
                sum[k] += w[k] as f64;
                sum2[k] += (w[k] * w[k]) as f64;
            }
        }
        for k in 0..3 {
            let mean = sum[k] / n as f64;
            let se = ((sum2[k] / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            let truth = (-(m.sigma_t()[k] as f64) * d as f64).exp();
            assert!(
                (mean - truth).abs() <= 4.0 * se + 1e-7,
                "channel {k}: {mean} vs {truth} (se {se})"
            );
        }
    }

    #[test]
    fn free_flight_pdf_is_the_density_of_the_sampled_collisions() {
        // Grey (one exponential), chromatic (the throughput mixture), and grey forced to uniform channels.
        let cases = [
            HomogeneousMedium::new("grey", Rgb::splat(0.3), Rgb::splat(1.2), 0.0),
            HomogeneousMedium::new("rgb", Rgb::new(0.1, 0.5, 2.0), Rgb::new(0.4, 1.0, 0.2), 0.3),
            HomogeneousMedium::new("uniform", Rgb::splat(0.2), Rgb::splat(0.5), 0.0)
                .with_channel_choice(ChannelChoice::Uniform),
        ];
        let throughput = Rgb::new(0.2, 0.5, 1.3);
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        let t_max = 2.5;
        for (i, m) in cases.iter().enumerate() {
            let mut rng = Rng::new(17, i as u64);
            let mut c = TrackingCounters::default();
            crate::math::chi2::assert_interval_sampler_fits(
                &format!("homogeneous free flight {}", m.name),
                100_000,
                (0.0, t_max as f64),
                || {
                    m.free_flight(
                        &ray,
                        t_max,
                        throughput,
                        &mut rng,
                        &mut c,
                        &mut TentativeEmission::default(),
                    )
                    .collision
                    .unwrap_or(f32::INFINITY)
                },
                |t| {
                    let constant = m.constant_scattering().unwrap();
                    constant.free_flight_pdf(t as f32, throughput) as f64
                },
            );
        }
        // Nothing to sample in an absorber.
        let absorber = HomogeneousMedium::new("a", Rgb::ONE, Rgb::ZERO, 0.0);
        assert!(absorber.constant_scattering().is_none());
        assert!(cases[0].constant_scattering().is_some());
    }

    #[test]
    fn slab_transmittance_grey_chromatic_and_absorbing() {
        check_slab(
            &HomogeneousMedium::new("grey", Rgb::splat(0.2), Rgb::splat(0.8), 0.0),
            1.5,
        );
        check_slab(
            &HomogeneousMedium::new("chromatic", Rgb::ZERO, Rgb::new(0.1, 1.0, 10.0), 0.0),
            0.7,
        );
        check_slab(
            &HomogeneousMedium::new("absorbing", Rgb::new(0.4, 0.8, 1.2), Rgb::ZERO, 0.0),
            2.0,
        );
    }

    #[test]
    fn an_infinite_flight_keeps_the_clear_channels_and_loses_the_others() {
        // Beer's law as t → ∞: exp(−σ t) → 0 for σ > 0 and stays 1 for σ = 0 (issue 33: `0 · ∞` was a NaN). An
        // escaping path survives every medium's free flight with that transmittance, over the probability of
        // no collision.
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        let (mut rng, mut c) = (Rng::new(1, 2), TrackingCounters::default());
        let clear_blue = Rgb::new(6.9, 2.2, 0.0);
        for (name, medium, expected) in [
            (
                "absorbing",
                HomogeneousMedium::new("a", clear_blue, Rgb::ZERO, 0.0),
                Rgb::new(0.0, 0.0, 1.0),
            ),
            (
                "scattering",
                HomogeneousMedium::new("s", clear_blue, Rgb::new(0.3, 0.3, 0.0), 0.0),
                // The flight survives only in blue, so the channel mixture's survival probability is blue's
                // weight, 1/3 for a white path: T / P = 3 in blue.
                Rgb::new(0.0, 0.0, 3.0),
            ),
        ] {
            let t = f32::INFINITY;
            let weight = medium.flight_weight(t, false, Rgb::ONE);
            assert_eq!(weight, expected, "{name}: free-flight weight at infinity");
            let tr = medium.transmittance(&ray, t, &mut rng, &mut c);
            assert_eq!(tr, Rgb::new(0.0, 0.0, 1.0), "{name}: transmittance");
            if let Some(constant) = medium.constant_scattering() {
                let pdf = constant.free_flight_pdf(t, Rgb::ONE);
                assert!(pdf.is_finite() && pdf >= 0.0, "{name}: pdf {pdf}");
            }
        }
    }

    #[test]
    fn every_channel_choice_gives_the_slab_transmittance() {
        for choice in [ChannelChoice::Throughput, ChannelChoice::Uniform] {
            let grey = HomogeneousMedium::new("grey", Rgb::splat(0.3), Rgb::splat(0.5), 0.0)
                .with_channel_choice(choice);
            check_slab(&grey, 1.2);
            let chromatic =
                HomogeneousMedium::new("chromatic", Rgb::ZERO, Rgb::new(0.2, 2.0, 20.0), 0.0)
                    .with_channel_choice(choice);
            check_slab(&chromatic, 0.3);
        }
    }

    #[test]
    fn method_says_which_estimator_and_why() {
        let method = |m: &HomogeneousMedium| {
            let method = m.method();
            let text = method.to_string();
            (method.free_flight, method.why, text)
        };
        let absorbing = HomogeneousMedium::new("a", Rgb::ONE, Rgb::ZERO, 0.0);
        let (free_flight, why, text) = method(&absorbing);
        assert_eq!(
            (free_flight, why),
            (FreeFlight::None, MethodReason::AbsorptionOnly)
        );
        assert!(text.contains("absorption only"), "{text}");
        let grey = HomogeneousMedium::new("g", Rgb::ZERO, Rgb::ONE, 0.0);
        let (free_flight, why, text) = method(&grey);
        assert_eq!(
            (free_flight, why),
            (FreeFlight::ClosedForm, MethodReason::GreyExtinction)
        );
        assert!(text.contains("no spectral MIS"), "{text}");
        let forced = grey.clone().with_channel_choice(ChannelChoice::Throughput);
        let (free_flight, why, text) = method(&forced);
        let throughput = FreeFlight::SpectralMis(ChannelSampling::Throughput);
        assert_eq!((free_flight, why), (throughput, MethodReason::Forced));
        assert!(text.contains("forced on grey"), "{text}");
        let uniform = grey.clone().with_channel_choice(ChannelChoice::Uniform);
        let (free_flight, why, _) = method(&uniform);
        let uniform_mis = FreeFlight::SpectralMis(ChannelSampling::Uniform);
        assert_eq!((free_flight, why), (uniform_mis, MethodReason::Forced));
        let chromatic = HomogeneousMedium::new("c", Rgb::ZERO, Rgb::new(1.0, 10.0, 100.0), 0.0);
        let (free_flight, why, text) = method(&chromatic);
        assert_eq!(
            (free_flight, why),
            (throughput, MethodReason::ChromaticExtinction)
        );
        assert!(text.contains("chromatic sigma_t"), "{text}");
    }

    #[test]
    fn chromatic_collision_density_integrates_to_the_scattered_fraction() {
        // E[weight · albedo at a collision] over paths = ∫ σ_s T dt = (σ_s/σ_t)(1 − exp(−σ_t d)) per channel.
        let m = HomogeneousMedium::new(
            "chromatic",
            Rgb::new(0.5, 0.0, 1.0),
            Rgb::new(0.5, 2.0, 9.0),
            0.0,
        );
        let ray = Ray::new(Vec3::ZERO, Vec3::Z);
        let mut rng = Rng::new(3, 3);
        let mut c = TrackingCounters::default();
        let (n, d) = (200_000, 0.8f32);
        let mut sum = Rgb::ZERO.as_dvec3();
        let mut sum2 = Rgb::ZERO.as_dvec3();
        for _ in 0..n {
            let flight = m.free_flight(
                &ray,
                d,
                Rgb::ONE,
                &mut rng,
                &mut c,
                &mut TentativeEmission::default(),
            );
            if let Some(t) = flight.collision {
                let w = (flight.throughput * m.collision(ray.at(t), 0.0).albedo).as_dvec3();
                sum += w;
                sum2 += w * w;
            }
        }
        for k in 0..3 {
            let mean = sum[k] / n as f64;
            let se = ((sum2[k] / n as f64 - mean * mean) / n as f64).sqrt();
            let (s, t) = (m.sigma_s[k] as f64, m.sigma_t[k] as f64);
            let truth = s / t * (1.0 - (-t * d as f64).exp());
            assert!(
                (mean - truth).abs() <= 4.0 * se,
                "channel {k}: {mean} vs {truth} (se {se})"
            );
        }
    }
}
