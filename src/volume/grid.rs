//! Grid media: VDB density (and optional temperature) grids placed in the scene by a glTF node's
//! `extras.nimbus_volume` or a USD `Volume` prim (keys in [`super::spec`]).
//!
//! - σ_t(x) = density_scale · ρ(x) per world metre (ρ: OpenVDB BoxSampler trilinear lookup), grey; σ_s = albedo ·
//!   σ_t; Henyey–Greenstein phase function.
//! - Free flights: delta tracking (Woodcock et al. 1965) over a majorant structure
//!   (`"majorant": "auto" | "adaptive" | "grid16" | "global"`); `auto`, the default, picks the cheapest for this
//!   grid at this density scale by a fixed-seed pilot ([`super::majorant_choice`]). Segments of constant
//!   density are tracked in closed form.
//! - Shadow rays: ratio tracking (Novák et al. 2014, eq. 6), or residual ratio tracking (Novák et al. 2014, §4)
//!   with `"shadow_estimator": "residual_ratio"`.
//! - Emission: σ_a · L_e with L_e = emission_scale · blackbody(temperature_scale · T(x) + temperature_offset),
//!   added at real collisions as (σ_a/σ_t) · L_e (the collision estimator).

use super::density::{DensityField, GridDensity};
use super::emission::BlackbodyTable;
use super::error::VolumeError;
use super::majorant::{MajorantKind, Majorants};
use super::majorant_choice::{self, MajorantEstimate};
use super::tracking::{ratio_tracking, residual_ratio_tracking, sample_collision};
use super::{
    Collision, FreeFlight, Medium, MediumMethod, MethodReason, PhaseFunction, TrackingCounters,
    TransmittanceMethod, VolumeSpec,
};
use crate::limits::Limits;
use crate::math::{Aabb, Ray, Rgb, Rng, Vec3};
use std::sync::Arc;

/// The estimator used for shadow-ray transmittance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowEstimator {
    /// Ratio tracking.
    Ratio,
    /// Residual ratio tracking with the majorant segments' minorants as control.
    ResidualRatio,
}

impl ShadowEstimator {
    /// Every estimator, in the order of [`ShadowEstimator::NAMES`].
    pub const ALL: [ShadowEstimator; 2] = [Self::Ratio, Self::ResidualRatio];

    /// The scene-file names (`"shadow_estimator"` key), in the order of [`ShadowEstimator::ALL`].
    pub const NAMES: &'static [&'static str] = &["ratio", "residual_ratio"];

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// The estimator of a scene-file name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }
}

/// Temperature lookup and the blackbody table for an emitting grid.
struct Emission {
    temperature: GridDensity,
    table: BlackbodyTable,
    scale: f32,
    temperature_scale: f32,
    temperature_offset: f32,
}

/// A heterogeneous medium backed by a sparse VDB grid.
pub struct GridMedium {
    name: String,
    density: GridDensity,
    majorants: Majorants,
    /// The pilot's estimates when the structure was chosen automatically.
    majorant_estimates: Vec<MajorantEstimate>,
    albedo: Rgb,
    phase: PhaseFunction,
    shadow: ShadowEstimator,
    emission: Option<Emission>,
}

impl GridMedium {
    /// Builds a medium from a placed density field and its parameters.
    pub fn new(name: &str, density: GridDensity, kind: MajorantKind, albedo: Rgb, g: f32) -> Self {
        let majorants = Majorants::build(kind, &density);
        Self::with_parts(name, density, majorants, Vec::new(), albedo, g)
    }

    /// Builds a medium whose majorant structure is the cheapest by the pilot of [`majorant_choice::choose`],
    /// among those that fit the default memory budget.
    pub fn with_chosen_majorants(name: &str, density: GridDensity, albedo: Rgb, g: f32) -> Self {
        Self::chosen_within(name, density, albedo, g, &Limits::default())
    }

    /// [`with_chosen_majorants`](Self::with_chosen_majorants) under the budget `limits`.
    fn chosen_within(
        name: &str,
        density: GridDensity,
        albedo: Rgb,
        g: f32,
        limits: &Limits,
    ) -> Self {
        let (majorants, estimates) = majorant_choice::choose(&density, limits);
        Self::with_parts(name, density, majorants, estimates, albedo, g)
    }

    fn with_parts(
        name: &str,
        density: GridDensity,
        majorants: Majorants,
        majorant_estimates: Vec<MajorantEstimate>,
        albedo: Rgb,
        g: f32,
    ) -> Self {
        Self {
            name: name.to_owned(),
            density,
            majorants,
            majorant_estimates,
            albedo,
            phase: PhaseFunction::henyey_greenstein(g),
            shadow: ShadowEstimator::Ratio,
            emission: None,
        }
    }

    /// Uses `shadow` for shadow-ray transmittance.
    pub fn with_shadow_estimator(mut self, shadow: ShadowEstimator) -> Self {
        self.shadow = shadow;
        self
    }

    /// Replaces the majorant structure (for benchmarks and tests of under-estimated majorants).
    pub fn with_majorants(mut self, majorants: Majorants) -> Self {
        self.majorants = majorants;
        self.majorant_estimates.clear();
        self
    }

    /// The density field.
    pub fn density(&self) -> &GridDensity {
        &self.density
    }

    /// Loads the grids `spec` names and builds the medium. Errors name the VDB file and the grid.
    pub fn load(spec: &VolumeSpec) -> Result<Self, VolumeError> {
        let file = match spec.embedded {
            Some(bytes) => crate::vdb::read_bytes(bytes, &spec.file),
            None => crate::vdb::read_file_with(
                &spec.file,
                &crate::vdb::ReadOptions {
                    limits: spec.limits,
                    ..Default::default()
                },
            ),
        }?;
        // `scale` None: a temperature grid, not an extinction, so never clamped as too dense.
        let place = |name: &str, scale: Option<f32>| {
            let grid = file.grid(name).ok_or_else(|| VolumeError::GridMissing {
                file: spec.file.clone(),
                grid: name.to_owned(),
                available: file.grids.iter().map(|g| g.name.clone()).collect(),
            })?;
            let node_to_world = spec.node_to_world.as_dmat4();
            match scale {
                Some(s) => GridDensity::new(grid, node_to_world, s),
                None => GridDensity::scalar(grid, node_to_world),
            }
            .map_err(|source| VolumeError::Density {
                file: spec.file.clone(),
                grid: name.to_owned(),
                source,
            })
        };
        let density = place(&spec.density_grid, Some(spec.density_scale))?;
        let medium = match spec.majorant {
            Some(kind) => {
                let majorants =
                    Majorants::try_build(kind, &density, &spec.limits).map_err(|source| {
                        VolumeError::OverBudget {
                            file: spec.file.clone(),
                            source,
                        }
                    })?;
                Self::with_parts(
                    &spec.name,
                    density,
                    majorants,
                    Vec::new(),
                    spec.albedo,
                    spec.anisotropy,
                )
            }
            None => Self::chosen_within(
                &spec.name,
                density,
                spec.albedo,
                spec.anisotropy,
                &spec.limits,
            ),
        };
        let mut medium = medium.with_shadow_estimator(spec.shadow_estimator);
        if let Some(t) = &spec.temperature_grid {
            let temperature = place(t, None)?;
            medium.emission = Some(Emission {
                temperature,
                table: BlackbodyTable::new(),
                scale: spec.emission_scale,
                temperature_scale: spec.temperature_scale,
                temperature_offset: spec.temperature_offset,
            });
        }
        Ok(medium)
    }
}

impl Medium for GridMedium {
    fn name(&self) -> &str {
        &self.name
    }

    fn method(&self) -> MediumMethod {
        MediumMethod {
            free_flight: FreeFlight::DeltaTracking {
                closed_form_segments: self.majorants.stores_minorants(),
            },
            majorant: Some(self.majorants.kind()),
            shadow: match self.shadow {
                ShadowEstimator::Ratio => TransmittanceMethod::RatioTracking,
                ShadowEstimator::ResidualRatio => TransmittanceMethod::ResidualRatioTracking,
            },
            why: if self.majorant_estimates.is_empty() {
                MethodReason::Requested
            } else {
                MethodReason::Pilot(self.majorant_estimates.clone())
            },
        }
    }

    fn memory_bytes(&self) -> usize {
        self.density.memory_bytes()
            + self.majorants.memory_bytes()
            + self
                .emission
                .as_ref()
                .map_or(0, |e| e.temperature.memory_bytes())
    }

    fn fill_bounds(&self) -> Option<Aabb> {
        Some(self.density.bounds())
    }

    fn warnings(&self) -> Vec<String> {
        let mut bad = self.density.bad_values();
        if let Some(e) = &self.emission {
            bad.add(&e.temperature.bad_values());
        }
        let mut warnings = Vec::new();
        if bad.nan + bad.infinite + bad.negative > 0 {
            warnings.push(format!(
                "medium '{}': {} NaN, {} infinite and {} negative grid values were replaced by zero",
                self.name, bad.nan, bad.infinite, bad.negative
            ));
        }
        if bad.too_dense > 0 {
            warnings.push(format!(
                "medium '{}': {} grid values denser than an optical depth of {} per voxel were clamped to it",
                self.name,
                bad.too_dense,
                super::density::MAX_VOXEL_OPTICAL_DEPTH
            ));
        }
        warnings
    }

    fn is_absorbing_only(&self) -> bool {
        false
    }

    fn is_emissive(&self) -> bool {
        self.emission.as_ref().is_some_and(|e| e.scale > 0.0)
    }

    fn sample_free_flight(
        &self,
        ray: &Ray,
        t_max: f32,
        _throughput: Rgb,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Option<f32> {
        sample_collision(
            &self.density,
            &self.majorants,
            ray,
            0.0,
            t_max,
            rng,
            counters,
        )
    }

    fn free_flight_weight(
        &self,
        _: &Ray,
        _: f32,
        _: bool,
        _: Rgb,
        _: &mut Rng,
        _: &mut TrackingCounters,
    ) -> Rgb {
        // Delta tracking of a grey medium is analog.
        Rgb::ONE
    }

    fn collision(&self, p: Vec3) -> Collision {
        let emission = match &self.emission {
            Some(e) => {
                let kelvin = e.temperature_scale * e.temperature.density(p) + e.temperature_offset;
                (Rgb::ONE - self.albedo) * e.scale * e.table.lookup(kelvin)
            }
            None => Rgb::ZERO,
        };
        Collision {
            albedo: self.albedo,
            emission,
            phase: self.phase,
        }
    }

    fn transmittance(
        &self,
        ray: &Ray,
        t_max: f32,
        rng: &mut Rng,
        counters: &mut TrackingCounters,
    ) -> Rgb {
        let t = match self.shadow {
            ShadowEstimator::Ratio => ratio_tracking(
                &self.density,
                &self.majorants,
                ray,
                0.0,
                t_max,
                rng,
                counters,
            ),
            ShadowEstimator::ResidualRatio => residual_ratio_tracking(
                &self.density,
                &self.majorants,
                ray,
                0.0,
                t_max,
                rng,
                counters,
            ),
        };
        Rgb::splat(t)
    }
}

/// Loads the VDB file of `spec` (for a sequence, the file of its frame) and builds its grid medium; `None`
/// when a sequence has no file for the frame and `missing_frame` is `empty`.
pub fn load_grid_medium(spec: &VolumeSpec) -> Result<Option<Arc<dyn Medium>>, VolumeError> {
    let Some(file) = spec.frame_file()? else {
        return Ok(None);
    };
    let spec = VolumeSpec {
        file,
        ..spec.clone()
    };
    Ok(Some(Arc::new(GridMedium::load(&spec)?)))
}
