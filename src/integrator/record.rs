//! What a camera path tells the compositing layers besides its radiance: each contribution with where it came
//! from (the path's first scattering event and whether the light is direct, and the emitter that produced it),
//! the colours of the first surface, the item that covered the sample (Cryptomatte) and, at a shadow catcher,
//! its light with and without occlusion. The integrator knows nothing about layer names; the renderer maps
//! these tags onto the film's slots.

use crate::material::{LobeClass, LobeSplit};
use crate::math::Rgb;

/// The class of a path's first scattering event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventClass {
    /// A surface lobe of this class.
    Surface(LobeClass),
    /// Scattering in a medium.
    Volume,
}

/// Where a contribution came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Origin {
    /// An emitter (surface or medium) seen directly, with no scattering event before it.
    Emitted,
    /// The environment seen directly.
    Environment,
    /// Light that reached the camera through scattering events; `direct` when there was exactly one.
    Scattered {
        /// The class of the first scattering event.
        first: EventClass,
        /// True after exactly one scattering event.
        direct: bool,
    },
}

/// One contribution to a sample's radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contribution {
    /// The radiance added (already weighted by the path throughput and any MIS weight).
    pub value: Rgb,
    /// Where it came from.
    pub origin: Origin,
    /// The emitter that produced it ([`crate::scene::SceneNames::emitters`]), when known.
    pub emitter: Option<u32>,
    /// False for light left out of the beauty (the environment seen directly on a transparent film).
    pub in_beauty: bool,
}

/// The first scattering event of a path so far, with how its later light is shared between classes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum FirstEvent {
    /// No scattering event yet.
    #[default]
    None,
    /// A surface: each lobe class's share of the sampled direction's BSDF value, per channel.
    Surface(LobeSplit),
    /// A medium.
    Volume,
}

/// What decided a camera path's coverage (its alpha), at a distance along the camera ray: what deep output
/// bins the path by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraEvent {
    /// An opaque surface (coverage 1).
    Surface(f32),
    /// A real collision in a medium (coverage 1).
    Collision(f32),
    /// The end of the camera ray with neither: it escaped (an infinite distance) or a holdout cut it; the
    /// coverage is what media in front took.
    Ended(f32),
}

/// Everything a camera sample records for the compositing layers; reused from sample to sample.
#[derive(Clone, Debug, Default)]
pub struct SampleRecord {
    /// Whether the shadow catcher's light is wanted (the layer is written).
    pub shadow_catcher: bool,
    /// The contributions, in the order the path found them.
    pub contributions: Vec<Contribution>,
    /// The lobe classes' colours at the first surface that scatters, times the path throughput there.
    pub colors: LobeSplit,
    /// The Cryptomatte item (a mesh, then a medium: [`crate::scene::SceneNames::items`]) that covered the
    /// sample, with the sample's alpha as its weight.
    pub covered_by: Option<u32>,
    /// At the first shadow catcher the camera ray passed through: its direct light with the scene's occlusion
    /// and without, times the path throughput.
    pub catcher: Option<(Rgb, Rgb)>,
    /// Whether deep output is wanted: the camera event and media span are recorded.
    pub deep: bool,
    /// What decided the sample's coverage, when deep output is wanted.
    pub camera_event: Option<CameraEvent>,
    /// The distances along the camera ray, nearest and farthest, between which it crossed media (before the
    /// camera event), when deep output is wanted.
    pub media_span: Option<(f32, f32)>,
}

impl SampleRecord {
    /// A record for the next sample (keeps the allocation and the `shadow_catcher` and `deep` choices).
    pub fn clear(&mut self) {
        self.contributions.clear();
        self.colors = LobeSplit::default();
        self.covered_by = None;
        self.catcher = None;
        self.camera_event = None;
        self.media_span = None;
    }

    /// Widens the media span to `[near, far]` (camera-ray distances), when deep output is wanted.
    pub(super) fn cross_media(&mut self, near: f32, far: f32) {
        if self.deep && near < far {
            self.media_span = Some(match self.media_span {
                Some((a, b)) => (a.min(near), b.max(far)),
                None => (near, far),
            });
        }
    }

    /// Records `value` from `origin`, split between the classes of the path's first event for light that
    /// scattered (a surface's shares; everything for a medium).
    pub(super) fn add(
        &mut self,
        value: Rgb,
        first: FirstEvent,
        direct: bool,
        emitter: Option<u32>,
    ) {
        match first {
            FirstEvent::None => self.push(value, Origin::Emitted, emitter, true),
            FirstEvent::Volume => self.push(
                value,
                Origin::Scattered {
                    first: EventClass::Volume,
                    direct,
                },
                emitter,
                true,
            ),
            FirstEvent::Surface(shares) => self.add_split(shares * value, direct, emitter),
        }
    }

    /// Records light whose classes are known per lobe: next-event estimation at the first surface (the BSDF
    /// value split by class), or later light times the first surface's shares.
    pub(super) fn add_split(&mut self, split: LobeSplit, direct: bool, emitter: Option<u32>) {
        for class in LobeClass::ALL {
            let value = split.get(class);
            if value.max_element() > 0.0 {
                let origin = Origin::Scattered {
                    first: EventClass::Surface(class),
                    direct,
                };
                self.push(value, origin, emitter, true);
            }
        }
    }

    /// Records one contribution.
    pub fn push(&mut self, value: Rgb, origin: Origin, emitter: Option<u32>, in_beauty: bool) {
        self.contributions.push(Contribution {
            value,
            origin,
            emitter,
            in_beauty,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn later_light_is_shared_by_the_first_surface_classes() {
        let mut r = SampleRecord::default();
        let shares = LobeSplit {
            diffuse: Rgb::new(1.0, 0.5, 0.0),
            glossy: Rgb::new(0.0, 0.5, 1.0),
            transmission: Rgb::ZERO,
        };
        r.add(Rgb::splat(2.0), FirstEvent::Surface(shares), false, Some(3));
        assert_eq!(r.contributions.len(), 2);
        let total = r.contributions.iter().fold(Rgb::ZERO, |a, c| a + c.value);
        assert_eq!(total, Rgb::splat(2.0));
        assert!(r
            .contributions
            .iter()
            .all(|c| c.emitter == Some(3)
                && matches!(c.origin, Origin::Scattered { direct: false, .. })));
        r.add(Rgb::ONE, FirstEvent::None, true, None);
        assert_eq!(r.contributions[2].origin, Origin::Emitted);
        r.clear();
        assert!(r.contributions.is_empty());
    }
}
