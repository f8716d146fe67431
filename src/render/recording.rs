//! From a path's record to the film's layers: maps each contribution's origin and emitter onto the plan's
//! slots (light-path layers, light groups), and adds the first surface's colours, the shadow catcher's light
//! and the Cryptomatte coverage, all as exact sums.

use super::aovs::{color_layer_name, LayerPlan, LightGroups, LightPath, CATCHER_LIT, CATCHER_OPEN};
use super::cryptomatte::{name_id, CryptoKind};
use super::film::{add_clamped, FilmPixel};
use crate::integrator::{EventClass, Origin, SampleRecord};
use crate::material::LobeClass;
use crate::math::Rgb;
use crate::scene::Scene;

/// How one render's path records reach its film.
#[derive(Clone, Debug, Default)]
pub struct LayerRecorder {
    /// The slot of each light-path layer ([`LightPath::ALL`] order), when kept.
    light_paths: [Option<usize>; 10],
    /// The slot of each lobe class's colour ([`LobeClass::ALL`] order), when kept.
    colors: [Option<usize>; 3],
    /// The slot of each emitter's light group, when kept.
    group_of_emitter: Vec<Option<usize>>,
    /// The shadow catcher's two slots, when kept.
    catcher: Option<(usize, usize)>,
    /// For each Cryptomatte kind of the plan, the ID of each item (meshes, then media).
    ids: Vec<Vec<u32>>,
}

impl LayerRecorder {
    /// The recorder of a render of `scene` with `plan` and light `groups`.
    pub fn new(scene: &Scene, plan: &LayerPlan, groups: &LightGroups) -> Self {
        let group_of_emitter = groups
            .group_of_emitter
            .iter()
            .map(|&g| plan.slot(&groups.names[g as usize]))
            .collect();
        let ids = plan
            .cryptomatte
            .iter()
            .map(|(kind, _)| {
                scene
                    .names()
                    .items
                    .iter()
                    .map(|item| {
                        name_id(match kind {
                            CryptoKind::Object => &item.object,
                            CryptoKind::Material => &item.material,
                            CryptoKind::Asset => &item.asset,
                        })
                    })
                    .collect()
            })
            .collect();
        Self {
            light_paths: LightPath::ALL.map(|p| plan.slot(p.name())),
            colors: LobeClass::ALL.map(|c| plan.slot(&color_layer_name(c))),
            group_of_emitter,
            catcher: plan.slot(CATCHER_LIT).zip(plan.slot(CATCHER_OPEN)),
            ids,
        }
    }

    /// The light-path layer of a contribution from `origin`.
    pub fn light_path(origin: Origin) -> LightPath {
        use LightPath::*;
        match origin {
            Origin::Emitted => Emission,
            Origin::Environment => Environment,
            Origin::Scattered { first, direct } => match (first, direct) {
                (EventClass::Surface(LobeClass::Diffuse), true) => DiffuseDirect,
                (EventClass::Surface(LobeClass::Diffuse), false) => DiffuseIndirect,
                (EventClass::Surface(LobeClass::Glossy), true) => GlossyDirect,
                (EventClass::Surface(LobeClass::Glossy), false) => GlossyIndirect,
                (EventClass::Surface(LobeClass::Transmission), true) => TransmissionDirect,
                (EventClass::Surface(LobeClass::Transmission), false) => TransmissionIndirect,
                (EventClass::Volume, true) => VolumeDirect,
                (EventClass::Volume, false) => VolumeIndirect,
            },
        }
    }

    /// Adds one sample's record (of a sample whose radiance is finite, with coverage `alpha`) to `pixel`.
    /// Returns true when a value had to be clamped into the film's range.
    pub fn commit(&self, record: &SampleRecord, alpha: f32, pixel: &mut FilmPixel) -> bool {
        let mut clamped = false;
        let mut add = |slot: usize, value: Rgb| {
            for c in 0..3 {
                clamped |= add_clamped(&mut pixel.slots[3 * slot + c], value[c]);
            }
        };
        for contribution in &record.contributions {
            if let Some(slot) = self.light_paths[Self::light_path(contribution.origin) as usize] {
                add(slot, contribution.value);
            }
            let group = contribution
                .emitter
                .and_then(|e| self.group_of_emitter.get(e as usize).copied().flatten());
            if let (Some(slot), true) = (group, contribution.in_beauty) {
                add(slot, contribution.value);
            }
        }
        for (class, slot) in LobeClass::ALL.into_iter().zip(self.colors) {
            if let Some(slot) = slot {
                add(slot, record.colors.get(class));
            }
        }
        if let (Some((lit, open)), Some((lit_value, open_value))) = (self.catcher, record.catcher) {
            add(lit, lit_value);
            add(open, open_value);
        }
        if let Some(item) = record.covered_by {
            for (ids, coverage) in self.ids.iter().zip(pixel.crypto.iter_mut()) {
                if let Some(&id) = ids.get(item as usize) {
                    coverage.add(id, alpha);
                }
            }
        }
        clamped
    }
}
