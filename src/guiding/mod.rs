//! Path guiding: a cache of incident light learned from the render's own paths, from which paths sample
//! directions at medium scattering events (Müller et al. 2017, "Practical Path Guiding for Efficient
//! Light-Transport Simulation", CGF 36(4): their spatial tree, with the von Mises–Fisher mixtures that Herholz
//! et al. 2019, "Volume Path Guiding Based on Zero-Variance Random Walk Theory", TOG 38(3), guide volumes with).
//!
//! - [`vmf`]: the directional distributions (von Mises–Fisher mixtures fitted by EM) and their product with the
//!   phase function or the cosine, sampled at guided events.
//! - [`field`]: the spatial tree of cells and the cache ([`GuidingField`]).
//! - [`lit`]: the grid of the direct light the decoupled direct-light samples received, and the guided
//!   distances it gives them ([`lit::DistanceGuide`]).
//! - [`shadow`]: guided Russian roulette on shadow rays (of medium collisions, decoupled samples and surfaces),
//!   from the transmittance the training's shadow rays found (on a grid of the lit grid's voxels).
//! - [`adjoint`]: guided Russian roulette and splitting from the cache's radiance and the training's pixel values.
//! - [`pilot`]: what `--guiding auto` decides for a scene, and why.
//! - [`GuidePath`]: what a training path remembers of its vertices, turned into [`RadianceRecord`]s at its end.
//!
//! The training passes (fixed seeds, rows in order) are the renderer's (`render::guiding`); the guided sampling
//! and its one-sample MIS with the phase function are the integrator's.

pub mod adjoint;
pub mod field;
pub mod lit;
pub mod pilot;
pub mod shadow;
pub mod vmf;

pub use field::{GuidingField, RadianceRecord};
pub use lit::LitRecord;
pub use pilot::{decide_from_shadow_pilot, GuidingDecision};
pub use vmf::VmfMixture;

use crate::math::{Rgb, Vec3};

/// Probability that a guided scattering event of a training path samples the cache's distribution rather than
/// the phase function (the one-sample MIS selection probability α of Müller et al. 2017, fixed at 0.5 as
/// there), and the largest a cell may learn for the image's paths ([`field::SELECTION_CHOICES`]).
pub const GUIDE_PROBABILITY: f32 = 0.5;

/// Paths whose throughput (largest channel) is above this sample the phase function alone: guided weights,
/// each at most 1/(1 − [`GUIDE_PROBABILITY`]), cannot compound beyond it over a long walk (our safeguard,
/// kept beside the weight window of [`adjoint`]).
pub const GUIDE_MAX_THROUGHPUT: f32 = 1.0;

/// Probability that a decoupled direct-light sample draws its distance from the learned lit regions
/// ([`lit::DistanceGuide`]) rather than the truncated free-flight density, in their one-sample mixture: its
/// density is at least 1 − this times the free flight's, so the sample's weight is at most 1/(1 − this) times
/// what it was unguided.
pub const GUIDED_DISTANCE_PROBABILITY: f32 = 0.5;

/// Training iterations before the image's samples: iteration k takes `2^k` samples per pixel of the whole
/// frame (1, 2, 4: Müller et al. 2017's doubling iterations), and the cache of the last one guides the image.
pub const TRAINING_ITERATIONS: u32 = 3;

/// `--guiding`: whether paths are guided.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum GuidingMode {
    /// Guided where guiding is measured to pay: no scene yet, so unguided; `--explain` (`GuidingMode::explain`)
    /// says what the pilot measured of the scene's media.
    #[default]
    Auto,
    /// Always guided (a scene without scattering media trains a cache that guides nothing).
    On,
    /// Never guided.
    Off,
}

impl crate::params::Choice for GuidingMode {
    const CHOICES: &'static [(&'static str, Self)] =
        &[("auto", Self::Auto), ("on", Self::On), ("off", Self::Off)];
}

/// One guided vertex of a training path: where it scattered, the direction it sampled and that direction's
/// density, the path throughput after the event (its weight included), and the radiance the path had gathered
/// before it left (its next-event estimate there included).
#[derive(Clone, Copy, Debug)]
struct GuideVertex {
    p: Vec3,
    dir: Vec3,
    pdf: f32,
    densities: StrategyDensities,
    throughput: Rgb,
    radiance_before: Rgb,
}

/// The densities of a guided event's two strategies at the direction it sampled: the unguided one (the phase
/// function or the BSDF) and the guide's (`None` where the event looked up no guide), from which the cache
/// learns each cell's selection probability ([`GuidingField::guide_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrategyDensities {
    /// The phase function's or the BSDF's density.
    pub unguided: f32,
    /// The guide's density.
    pub guide: Option<f32>,
}

/// What a training path remembers of its medium scattering events, so that at its end each learns the
/// incident radiance along the direction it sampled: the radiance gathered after it, divided by the throughput
/// that carried it (an unbiased estimate of L_i(x, ω), as Müller et al. 2017 record it).
#[derive(Clone, Debug, Default)]
pub struct GuidePath {
    vertices: Vec<GuideVertex>,
    /// What its decoupled direct-light samples received.
    lit: Vec<LitRecord>,
    /// The transmittance its medium collisions' shadow rays found ([`shadow`]).
    shadow: Vec<LitRecord>,
    /// The transmittance its decoupled samples' shadow rays found ([`shadow`]).
    decoupled_shadow: Vec<LitRecord>,
    /// The transmittance its surfaces' shadow rays found ([`shadow`]).
    surface_shadow: Vec<LitRecord>,
}

impl GuidePath {
    /// Forgets the previous path's vertices (keeps the allocation).
    pub fn clear(&mut self) {
        self.vertices.clear();
        self.lit.clear();
        self.shadow.clear();
        self.decoupled_shadow.clear();
        self.surface_shadow.clear();
    }

    /// Remembers that a decoupled direct-light sample at `p` received `value` ([`LitRecord`]).
    pub fn push_lit(&mut self, p: Vec3, value: f32) {
        self.lit.push(LitRecord { p, value });
    }

    /// The records of the path's decoupled direct-light samples.
    pub fn lit(&self) -> &[LitRecord] {
        &self.lit
    }

    /// Remembers that a shadow ray of next-event estimation at a medium scattering event at `p` found the
    /// transmittance `value` (its largest channel; [`shadow`]).
    pub fn push_shadow(&mut self, p: Vec3, value: f32) {
        self.shadow.push(LitRecord { p, value });
    }

    /// The records of the path's medium collisions' shadow rays.
    pub fn shadow(&self) -> &[LitRecord] {
        &self.shadow
    }

    /// Remembers that a shadow ray of a decoupled direct-light sample at `p` found the transmittance `value`
    /// (its largest channel; [`shadow`]).
    pub fn push_decoupled_shadow(&mut self, p: Vec3, value: f32) {
        self.decoupled_shadow.push(LitRecord { p, value });
    }

    /// The records of the path's decoupled samples' shadow rays.
    pub fn decoupled_shadow(&self) -> &[LitRecord] {
        &self.decoupled_shadow
    }

    /// Remembers that a shadow ray of next-event estimation at a surface point `p` found the transmittance
    /// `value` (its largest channel; [`shadow`]).
    pub fn push_surface_shadow(&mut self, p: Vec3, value: f32) {
        self.surface_shadow.push(LitRecord { p, value });
    }

    /// The records of the path's surfaces' shadow rays.
    pub fn surface_shadow(&self) -> &[LitRecord] {
        &self.surface_shadow
    }

    /// Remembers a scattering event at `p` that sampled `dir` with density `pdf` (the strategies' own
    /// `densities` there), leaving throughput `throughput`, when the path had gathered `radiance_before`.
    pub fn push(
        &mut self,
        p: Vec3,
        (dir, pdf): (Vec3, f32),
        densities: StrategyDensities,
        throughput: Rgb,
        radiance_before: Rgb,
    ) {
        self.vertices.push(GuideVertex {
            p,
            dir,
            pdf,
            densities,
            throughput,
            radiance_before,
        });
    }

    /// The light a path that ended with `radiance` gathered found after its first remembered event's
    /// next-event estimate (its continuation from there; nothing where it remembered no event): the part of a
    /// pixel's value that guided Russian roulette compares continuations with ([`adjoint::PixelEstimates`]).
    pub fn continuation(&self, radiance: Rgb) -> Rgb {
        self.vertices
            .first()
            .map_or(Rgb::ZERO, |v| radiance - v.radiance_before)
    }

    /// The records of the path, which ended with `radiance` gathered, appended to `out`.
    pub fn finish(&self, radiance: Rgb, out: &mut Vec<RadianceRecord>) {
        for v in &self.vertices {
            let carried = v.throughput.element_sum();
            let gathered = (radiance - v.radiance_before).element_sum();
            let incident = if carried > 0.0 {
                (gathered / carried).max(0.0)
            } else {
                0.0
            };
            out.push(RadianceRecord {
                p: v.p,
                dir: v.dir,
                radiance: incident,
                pdf: v.pdf,
                unguided_pdf: v.densities.unguided,
                guide_pdf: v.densities.guide,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path's continuation is what it gathered after its first remembered event's next-event estimate: the
    /// light before it (emission seen, that estimate) is left out, later events' light kept; a path that
    /// remembered no event has none.
    #[test]
    fn the_continuation_starts_after_the_first_event() {
        let mut path = GuidePath::default();
        let densities = StrategyDensities {
            unguided: 1.0,
            guide: None,
        };
        assert_eq!(path.continuation(Rgb::splat(3.0)), Rgb::ZERO);
        path.push(
            Vec3::ZERO,
            (Vec3::Z, 1.0),
            densities,
            Rgb::ONE,
            Rgb::splat(2.0),
        );
        path.push(
            Vec3::ONE,
            (Vec3::Y, 1.0),
            densities,
            Rgb::ONE,
            Rgb::splat(2.5),
        );
        assert_eq!(
            path.continuation(Rgb::new(3.0, 2.0, 4.0)),
            Rgb::new(1.0, 0.0, 2.0)
        );
    }
}
