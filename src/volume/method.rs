//! What a medium does and why, as data: [`MediumMethod`] (returned by `Medium::method`). Its `Display` is the
//! sentence `--explain` prints and `--stats` writes under `method`; its fields are the structured `--stats`
//! keys (`free_flight`, `channel_choice`, `closed_form_segments`, `majorant`, `shadow_estimator`,
//! `method_reason`, `majorant_pilot`, `chromatic_tracking`), so that tests and tools never parse the sentence.

use super::majorant::MajorantKind;
use super::majorant_choice::{MajorantEstimate, PILOT_RAYS};
use super::tracking::REFINE_TAU;
use serde::ser::SerializeMap;
use std::fmt;

/// How a medium samples free flights (the distance to the next real collision).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FreeFlight {
    /// None: the medium only absorbs, so paths need its transmittance only.
    #[default]
    None,
    /// One closed-form exponential for all channels (grey σ_t; analog, weight 1).
    ClosedForm,
    /// Closed-form exponentials with spectral MIS over the channels, the channel chosen as given.
    SpectralMis(ChannelSampling),
    /// Delta tracking against a majorant structure; with `closed_form_segments`, segments of constant density
    /// are sampled in closed form.
    DeltaTracking {
        /// True when the majorant structure stores minorants, so constant-density segments are found.
        closed_form_segments: bool,
        /// True for decomposition tracking (Kutz et al. 2017, §4): tentative collisions under the segment's
        /// minorant are real without a lookup (same distribution as delta tracking).
        decomposition: bool,
        /// True when segments thicker than `tracking::REFINE_TAU` per voxel are walked voxel cell by voxel cell,
        /// each bounded by its eight voxels.
        voxel_refinement: bool,
        /// For an RGB extinction, how a path's free flight handles its three channels; `None` when grey.
        chromatic: Option<Chromatic>,
    },
}

/// How free flights through a medium whose extinction differs per channel (an RGB density grid) handle the
/// channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChromaticTracking {
    /// The path carries one channel, chosen by throughput, and delta-tracks it.
    OneChannel,
    /// Spectral tracking (Kutz et al. 2017, §5): the path keeps all three channels, collision probabilities from
    /// the throughput-weighted extinctions, vector weights at every collision.
    Spectral,
}

impl ChromaticTracking {
    /// Both methods, in the order of [`ChromaticTracking::NAMES`].
    pub const ALL: [ChromaticTracking; 2] = [Self::OneChannel, Self::Spectral];

    /// The scene-file and `--stats` names (`"chromatic_tracking"`), in the order of [`ChromaticTracking::ALL`].
    pub const NAMES: &'static [&'static str] = &["one_channel", "spectral"];

    /// What `"chromatic_tracking": "auto"` picks, by the efficiency measured on mildly and strongly chromatic
    /// grids (docs/reference.md, "What each choice wins").
    pub const AUTO: ChromaticTracking = ChromaticTracking::Spectral;

    /// Why `auto` picks [`ChromaticTracking::AUTO`], as `--explain` says it.
    const AUTO_WHY: &'static str =
        "auto: 2.8x to 8.5x the efficiency of one channel per path, measured on \
         clouds of RGB extinction 1:1.5:2 and 1:10:100, albedo 0.8 and 1";

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The method of a scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// The chromatic method of a medium, and whether the scene asked for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Chromatic {
    /// The method.
    pub tracking: ChromaticTracking,
    /// True when the scene named it (`"chromatic_tracking"`); false when `auto` chose it.
    pub requested: bool,
}

/// How spectral MIS picks the channel whose exponential is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelSampling {
    /// With probability ∝ the path throughput.
    Throughput,
    /// With probability 1/3 each (tests and benches force it).
    #[cfg(any(test, feature = "testing"))]
    Uniform,
}

/// How a medium estimates the transmittance of shadow rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TransmittanceMethod {
    /// The closed form exp(−σ_t d).
    #[default]
    ClosedForm,
    /// Ratio tracking (Novák et al. 2014).
    RatioTracking,
    /// Residual ratio tracking (Novák et al. 2014, §4).
    ResidualRatioTracking,
}

/// Why the medium uses its method.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum MethodReason {
    /// σ_s = 0: nothing scatters.
    #[default]
    AbsorptionOnly,
    /// σ_t is the same in every channel.
    GreyExtinction,
    /// σ_t differs between channels.
    ChromaticExtinction,
    /// The caller forced the channel choice.
    Forced,
    /// The scene (or the caller) named the majorant structure.
    Requested,
    /// `auto`: the cheapest majorant structure in a fixed-seed pilot, with each structure's estimate.
    Pilot(Vec<MajorantEstimate>),
    /// Velocity motion blur: a 16³ grid (or the global bound, if requested) dilated by the largest
    /// displacement over the shutter.
    VelocityBlur {
        /// That displacement, in voxels along the widest axis.
        reach_voxels: f32,
    },
}

/// The method a medium uses, as reported by `--explain` and `--stats`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MediumMethod {
    /// How free flights are sampled.
    pub free_flight: FreeFlight,
    /// The majorant structure that bounds σ_t for tracking, if the medium tracks.
    pub majorant: Option<MajorantKind>,
    /// How shadow rays estimate transmittance.
    pub shadow: TransmittanceMethod,
    /// Why.
    pub why: MethodReason,
}

impl MediumMethod {
    /// The estimator alone, without why it was chosen: two renders whose media have the same keys sample the
    /// same random decisions, so their farm parts may merge (a memory limit that rules out a majorant
    /// structure changes it).
    pub fn estimator_key(&self) -> String {
        format!(
            "{:?} {:?} {:?}",
            self.free_flight, self.majorant, self.shadow
        )
    }
}

/// How a majorant structure reads in the sentence.
fn majorant_phrase(kind: MajorantKind) -> &'static str {
    match kind {
        MajorantKind::Global => "a global majorant",
        MajorantKind::Grid16 => "a 16^3 majorant grid",
        MajorantKind::Adaptive => "adaptive majorants",
    }
}

impl fmt::Display for MediumMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let shadow = match self.shadow {
            TransmittanceMethod::ClosedForm => "closed-form transmittance",
            TransmittanceMethod::RatioTracking => "ratio tracking",
            TransmittanceMethod::ResidualRatioTracking => "residual ratio tracking",
        };
        match self.free_flight {
            FreeFlight::None => match self.shadow {
                TransmittanceMethod::ClosedForm => write!(
                    f,
                    "closed-form transmittance exp(-sigma_a d), no collisions sampled (absorption only: sigma_s = 0)"
                ),
                _ => write!(
                    f,
                    "{shadow} for transmittance, no collisions (absorption only; {})",
                    self.majorant.map_or("no majorant", majorant_phrase)
                ),
            },
            FreeFlight::ClosedForm => write!(
                f,
                "closed-form free flight, one exponential for all channels (grey sigma_t: no spectral MIS)"
            ),
            FreeFlight::SpectralMis(channel) => {
                let choice = match channel {
                    ChannelSampling::Throughput => "channel by path throughput",
                    #[cfg(any(test, feature = "testing"))]
                    ChannelSampling::Uniform => "uniform channel choice",
                };
                let why = match (&self.why, channel) {
                    #[cfg(any(test, feature = "testing"))]
                    (MethodReason::Forced, ChannelSampling::Uniform) => "forced",
                    (MethodReason::Forced, ChannelSampling::Throughput) => "forced on grey sigma_t",
                    (MethodReason::GreyExtinction, _) => "grey sigma_t",
                    _ => "chromatic sigma_t",
                };
                write!(
                    f,
                    "closed-form free flight, spectral MIS over channels, {choice} ({why})"
                )
            }
            FreeFlight::DeltaTracking {
                closed_form_segments,
                decomposition,
                voxel_refinement,
                chromatic,
            } => {
                let tracking = if chromatic.is_some_and(|c| c.tracking == ChromaticTracking::Spectral) {
                    "spectral tracking (all three channels of the RGB extinction at once)"
                } else if decomposition {
                    "decomposition tracking (delta tracking whose collisions under the segment minorant need no lookup)"
                } else {
                    "delta tracking"
                };
                write!(
                    f,
                    "{tracking} over {}",
                    self.majorant.map_or("no majorant", majorant_phrase)
                )?;
                write_reason(f, &self.why)?;
                if let Some(c) = chromatic {
                    write_chromatic(f, &c)?;
                }
                if voxel_refinement {
                    write!(
                        f,
                        ", refined to voxel cells (bounded by their 8 voxels) where the majorant optical depth per voxel exceeds {REFINE_TAU}"
                    )?;
                }
                if closed_form_segments {
                    write!(f, ", closed form on constant-density segments")?;
                }
                write!(f, "; {shadow} for shadow rays")
            }
        }
    }
}

/// Why a delta-tracking method was chosen, as the sentence's parenthesis: the pilot's cost estimates, velocity
/// blur's dilation, an RGB density's majorants, or "as requested".
fn write_reason(f: &mut fmt::Formatter<'_>, why: &MethodReason) -> fmt::Result {
    match why {
        MethodReason::Pilot(estimates) => {
            let costs: Vec<String> = estimates
                .iter()
                .map(|e| {
                    let stopped = if e.rays_traced < PILOT_RAYS {
                        format!(", stopped after {} rays at the work cap", e.rays_traced)
                    } else {
                        String::new()
                    };
                    format!(
                        "{} {:.0} ({:.1} lookups, {:.1} cells{stopped})",
                        e.kind.name(),
                        e.cost_ns,
                        e.lookups_per_ray,
                        e.cells_per_ray
                    )
                })
                .collect();
            write!(
                f,
                " (auto: cheapest in a {PILOT_RAYS}-ray pilot, estimated ns per ray: {})",
                costs.join(", ")
            )?;
        }
        MethodReason::VelocityBlur { reach_voxels } => write!(
            f,
            " (velocity blur: majorants dilated by up to {reach_voxels:.1} voxels over the shutter)"
        )?,
        MethodReason::ChromaticExtinction => {
            write!(f, " (RGB density: majorants of the channels' maximum)")?
        }
        _ => write!(f, " (as requested)")?,
    }
    Ok(())
}

/// How a chromatic medium's collisions are sampled, and why.
fn write_chromatic(f: &mut fmt::Formatter<'_>, c: &Chromatic) -> fmt::Result {
    let why = if c.requested {
        "as requested"
    } else {
        ChromaticTracking::AUTO_WHY
    };
    match c.tracking {
            ChromaticTracking::Spectral => write!(
                f,
                ", history-aware collision probabilities over the path throughput ({why}; beside other media too, over the part of a segment before the collisions of the media asked before it)"
            )?,
            ChromaticTracking::OneChannel => write!(
                f,
                ", a path carrying the one channel it is given, chosen by throughput ({why})"
            )?,
        }
    Ok(())
}

/// The `--stats` keys, written flat into each `media` entry.
impl serde::Serialize for MediumMethod {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let (free_flight, channel, segments) = match self.free_flight {
            FreeFlight::None => ("none", None, false),
            FreeFlight::ClosedForm => ("closed_form", None, false),
            FreeFlight::SpectralMis(c) => (
                "spectral_mis",
                Some(match c {
                    ChannelSampling::Throughput => "throughput",
                    #[cfg(any(test, feature = "testing"))]
                    ChannelSampling::Uniform => "uniform",
                }),
                false,
            ),
            FreeFlight::DeltaTracking {
                closed_form_segments,
                ..
            } => ("delta_tracking", None, closed_form_segments),
        };
        let (decomposition, voxel_refinement, chromatic) = match self.free_flight {
            FreeFlight::DeltaTracking {
                decomposition,
                voxel_refinement,
                chromatic,
                ..
            } => (
                decomposition,
                voxel_refinement,
                chromatic.map(|c| c.tracking.name()),
            ),
            _ => (false, false, None),
        };
        let shadow = match self.shadow {
            TransmittanceMethod::ClosedForm => "closed_form",
            TransmittanceMethod::RatioTracking => "ratio",
            TransmittanceMethod::ResidualRatioTracking => "residual_ratio",
        };
        let (reason, pilot) = match &self.why {
            MethodReason::AbsorptionOnly => ("absorption_only", &[][..]),
            MethodReason::GreyExtinction => ("grey_extinction", &[][..]),
            MethodReason::ChromaticExtinction => ("chromatic_extinction", &[][..]),
            MethodReason::Forced => ("forced", &[][..]),
            MethodReason::Requested => ("requested", &[][..]),
            MethodReason::Pilot(estimates) => ("pilot", estimates.as_slice()),
            MethodReason::VelocityBlur { .. } => ("velocity_blur", &[][..]),
        };
        let pilot: Vec<PilotEntry> = pilot.iter().map(PilotEntry::from).collect();
        let mut map = serializer.serialize_map(Some(10))?;
        map.serialize_entry("free_flight", free_flight)?;
        map.serialize_entry("channel_choice", &channel)?;
        map.serialize_entry("closed_form_segments", &segments)?;
        map.serialize_entry("decomposition_tracking", &decomposition)?;
        map.serialize_entry("voxel_refinement", &voxel_refinement)?;
        map.serialize_entry("majorant", &self.majorant.map(MajorantKind::name))?;
        map.serialize_entry("shadow_estimator", shadow)?;
        map.serialize_entry("method_reason", reason)?;
        map.serialize_entry("majorant_pilot", &pilot)?;
        map.serialize_entry("chromatic_tracking", &chromatic)?;
        map.end()
    }
}

/// One structure's pilot estimate under `majorant_pilot`.
#[derive(serde::Serialize)]
struct PilotEntry {
    majorant: &'static str,
    cost_ns: f64,
    lookups_per_ray: f64,
    cells_per_ray: f64,
    rays_traced: usize,
}

impl From<&MajorantEstimate> for PilotEntry {
    fn from(e: &MajorantEstimate) -> Self {
        Self {
            majorant: e.kind.name(),
            cost_ns: e.cost_ns,
            lookups_per_ray: e.lookups_per_ray,
            cells_per_ray: e.cells_per_ray,
            rays_traced: e.rays_traced,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_keys_and_sentence() {
        let m = MediumMethod {
            free_flight: FreeFlight::DeltaTracking {
                closed_form_segments: true,
                decomposition: false,
                voxel_refinement: false,
                chromatic: None,
            },
            majorant: Some(MajorantKind::Global),
            shadow: TransmittanceMethod::ResidualRatioTracking,
            why: MethodReason::Requested,
        };
        assert_eq!(
            m.to_string(),
            "delta tracking over a global majorant (as requested), closed form on constant-density segments; \
             residual ratio tracking for shadow rays"
        );
        let json = serde_json::to_value(&m).unwrap();
        assert_eq!(
            json,
            serde_json::json!({"free_flight": "delta_tracking", "channel_choice": null,
                "closed_form_segments": true, "decomposition_tracking": false, "voxel_refinement": false,
                "majorant": "global", "shadow_estimator": "residual_ratio", "method_reason": "requested",
                "majorant_pilot": [], "chromatic_tracking": null})
        );
        // Decomposition tracking with voxel refinement, as grid media use it.
        let m = MediumMethod {
            free_flight: FreeFlight::DeltaTracking {
                closed_form_segments: false,
                decomposition: true,
                voxel_refinement: true,
                chromatic: None,
            },
            majorant: Some(MajorantKind::Grid16),
            shadow: TransmittanceMethod::RatioTracking,
            why: MethodReason::Requested,
        };
        assert_eq!(
            m.to_string(),
            "decomposition tracking (delta tracking whose collisions under the segment minorant need no lookup) \
             over a 16^3 majorant grid (as requested), refined to voxel cells (bounded by their 8 voxels) where the \
             majorant optical depth per voxel exceeds 4; ratio tracking for shadow rays"
        );
        let json = serde_json::to_value(&m).unwrap();
        assert_eq!(json["decomposition_tracking"], true);
        assert_eq!(json["voxel_refinement"], true);
    }
}
