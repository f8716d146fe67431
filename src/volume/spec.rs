//! The declaration of a VDB volume, shared by every scene format: glTF's node `extras.nimbus_volume` and USD's
//! `Volume` prims with `nimbus:` attributes.
//!
//! The keys are one table, [`VOLUME_KEYS`] (name, type, default, meaning, USD attribute): both loaders read
//! through it ([`VolumeSpec::read_params`]) and the key table of docs/reference.md is generated from it (a test keeps them
//! in agreement). σ_t(x) = density_scale · ρ(x) per world metre, ρ the trilinear lookup (OpenVDB BoxSampler
//! convention); σ_s = albedo · σ_t, σ_a = σ_t − σ_s; emission σ_a · L_e with L_e = emission_scale ·
//! blackbody(temperature_scale · T(x) + temperature_offset), normalised RGB (pbrt-v4's convention for grid
//! media).
//!
//! Placement: index space → the VDB's own index-to-world matrix → the node's world matrix.

use super::error::VolumeError;
use super::grid::ShadowEstimator;
use super::majorant::MajorantKind;
use super::method::ChromaticTracking;
use crate::math::{Mat4, Rgb};
use crate::params::{
    JsonParams, ParamDefault, ParamError, ParamKey, ParamRead, ParamSource, ParamType,
    TableDefaults, UsdBinding,
};
use std::path::PathBuf;

/// The `"majorant"` names: `auto`, then every [`MajorantKind::name`] (a test keeps them in agreement).
const MAJORANT_CHOICES: &[&str] = &["auto", "global", "grid16", "adaptive"];

const FILE: ParamKey = ParamKey {
    name: "file",
    ty: ParamType::Text,
    default: ParamDefault::Required,
    doc: "the VDB file, relative to the scene file that names it; a sequence names its frame with `####`, \
          `$F4` or `%04d` (`smoke.####.vdb`)",
    usd: UsdBinding::Elsewhere("`filePath` of the `field:density` asset"),
};
const DENSITY_GRID: ParamKey = ParamKey {
    name: "density_grid",
    ty: ParamType::Text,
    default: ParamDefault::Text("density"),
    doc: "the grid holding density ρ: scalar, or vec3 for an RGB extinction (σ_t per channel)",
    usd: UsdBinding::Elsewhere("`fieldName` of the `field:density` asset"),
};
const DENSITY_SCALE: ParamKey = ParamKey {
    name: "density_scale",
    ty: ParamType::Number,
    default: ParamDefault::Number(1.0),
    doc: "σ_t = density_scale · ρ per world metre; ≥ 0",
    usd: UsdBinding::Attribute,
};
const ALBEDO: ParamKey = ParamKey {
    name: "albedo",
    ty: ParamType::GreyOrRgb,
    default: ParamDefault::Rgb([1.0; 3]),
    doc: "σ_s = albedo · σ_t; each component in [0, 1]",
    usd: UsdBinding::Attribute,
};
const ANISOTROPY: ParamKey = ParamKey {
    name: "anisotropy",
    ty: ParamType::Number,
    default: ParamDefault::Number(0.0),
    doc: "Henyey–Greenstein g, in (−1, 1)",
    usd: UsdBinding::Attribute,
};
const TEMPERATURE_GRID: ParamKey = ParamKey {
    name: "temperature_grid",
    ty: ParamType::Text,
    default: ParamDefault::Unset,
    doc: "the grid holding temperature T, for blackbody emission",
    usd: UsdBinding::Elsewhere("`fieldName` of the `field:temperature` asset"),
};
const EMISSION_SCALE: ParamKey = ParamKey {
    name: "emission_scale",
    ty: ParamType::Number,
    default: ParamDefault::Number(1.0),
    doc: "multiplies the blackbody emission; ≥ 0",
    usd: UsdBinding::Attribute,
};
const TEMPERATURE_SCALE: ParamKey = ParamKey {
    name: "temperature_scale",
    ty: ParamType::Number,
    default: ParamDefault::Number(1.0),
    doc: "Kelvin = temperature_scale · T + temperature_offset; ≥ 0",
    usd: UsdBinding::Attribute,
};
const TEMPERATURE_OFFSET: ParamKey = ParamKey {
    name: "temperature_offset",
    ty: ParamType::Number,
    default: ParamDefault::Number(0.0),
    doc: "Kelvin added to the scaled temperature",
    usd: UsdBinding::Attribute,
};
const FRAME_OFFSET: ParamKey = ParamKey {
    name: "frame_offset",
    ty: ParamType::Number,
    default: ParamDefault::Number(0.0),
    doc: "a whole number added to the shot's frame to pick the sequence's file (frame 1 of the shot reads \
          file frame 1 + frame_offset)",
    usd: UsdBinding::Attribute,
};
const MISSING_FRAME: ParamKey = ParamKey {
    name: "missing_frame",
    ty: ParamType::Choice(MissingFrame::NAMES),
    default: ParamDefault::Text("error"),
    doc: "when a sequence's file for the frame is missing: `error`, `hold` (the nearest earlier frame, else \
          the first later one) or `empty` (no volume in that frame, with a warning)",
    usd: UsdBinding::Attribute,
};
const FLAME_GRID: ParamKey = ParamKey {
    name: "flame_grid",
    ty: ParamType::Text,
    default: ParamDefault::Unset,
    doc: "a scalar grid of flame intensity: L_e += flame_scale · flame · colour (emission is σ_a · L_e)",
    usd: UsdBinding::Elsewhere("`fieldName` of the `field:flame` asset"),
};
const FLAME_SCALE: ParamKey = ParamKey {
    name: "flame_scale",
    ty: ParamType::NonNegative,
    default: ParamDefault::Number(1.0),
    doc: "multiplies the flame emission",
    usd: UsdBinding::Attribute,
};
const FLAME_COLOR: ParamKey = ParamKey {
    name: "flame_color",
    ty: ParamType::GreyOrRgb,
    default: ParamDefault::Unset,
    doc:
        "the flame's colour (linear RGB); without it, the normalised blackbody of flame_temperature",
    usd: UsdBinding::Attribute,
};
const FLAME_TEMPERATURE: ParamKey = ParamKey {
    name: "flame_temperature",
    ty: ParamType::NonNegative,
    default: ParamDefault::Number(1500.0),
    doc: "Kelvin of the blackbody that colours the flame when flame_color is not given",
    usd: UsdBinding::Attribute,
};
const COLOR_GRID: ParamKey = ParamKey {
    name: "color_grid",
    ty: ParamType::Text,
    default: ParamDefault::Unset,
    doc: "a vec3 (or scalar) colour grid, Houdini's `Cd`, multiplying the albedo",
    usd: UsdBinding::Elsewhere("`fieldName` of the `field:Cd` asset"),
};
const ALBEDO_GRID: ParamKey = ParamKey {
    name: "albedo_grid",
    ty: ParamType::Text,
    default: ParamDefault::Unset,
    doc: "a scalar or vec3 grid multiplying the albedo: albedo(x) = albedo · albedo_grid · color_grid, \
          clamped to [0, 1]",
    usd: UsdBinding::Elsewhere("`fieldName` of the `field:albedo` asset"),
};
const VELOCITY_GRID: ParamKey = ParamKey {
    name: "velocity_grid",
    ty: ParamType::Text,
    default: ParamDefault::Unset,
    doc: "with `--shutter`: the velocity (world units per second), a vec3 grid or the scalar grids \
          `NAME.x/.y/.z`; the volume is blurred by looking up x − velocity_scale · v · t (none: `vel` or \
          `vel.x/.y/.z` where the file has them, else no blur; a grid named here must be in the file)",
    usd: UsdBinding::Attribute,
};
const VELOCITY_SCALE: ParamKey = ParamKey {
    name: "velocity_scale",
    ty: ParamType::Number,
    default: ParamDefault::Number(1.0),
    doc: "multiplies the velocities (0 turns velocity blur off)",
    usd: UsdBinding::Attribute,
};
const MAJORANT: ParamKey = ParamKey {
    name: "majorant",
    ty: ParamType::Choice(MAJORANT_CHOICES),
    default: ParamDefault::Text("auto"),
    doc: "majorant structure for tracking; `auto` picks the cheapest by a fixed-seed pilot",
    usd: UsdBinding::Elsewhere("not read (auto)"),
};
const SHADOW_ESTIMATOR: ParamKey = ParamKey {
    name: "shadow_estimator",
    ty: ParamType::Choice(ShadowEstimator::NAMES),
    default: ParamDefault::Text("ratio"),
    doc: "shadow-ray transmittance: ratio or residual ratio tracking",
    usd: UsdBinding::Elsewhere("not read (ratio)"),
};

/// The `"chromatic_tracking"` names: `auto`, then every [`ChromaticTracking::name`] (a test keeps them in
/// agreement).
const CHROMATIC_TRACKING_CHOICES: &[&str] = &["auto", "one_channel", "spectral"];
const CHROMATIC_TRACKING: ParamKey = ParamKey {
    name: "chromatic_tracking",
    ty: ParamType::Choice(CHROMATIC_TRACKING_CHOICES),
    default: ParamDefault::Text("auto"),
    doc: "free flights through an RGB density: `spectral` tracking keeps all three channels, `one_channel` makes \
          the path carry one; `auto` picks by the measured efficiency (see docs/reference.md)",
    usd: UsdBinding::Elsewhere("not read (auto)"),
};

/// The keys of a VDB volume declaration (glTF `extras.nimbus_volume`, USD `Volume` prims), in docs/reference.md's
/// order.
pub const VOLUME_KEYS: &[ParamKey] = &[
    FILE,
    DENSITY_GRID,
    DENSITY_SCALE,
    ALBEDO,
    ANISOTROPY,
    TEMPERATURE_GRID,
    EMISSION_SCALE,
    TEMPERATURE_SCALE,
    TEMPERATURE_OFFSET,
    FLAME_GRID,
    FLAME_SCALE,
    FLAME_COLOR,
    FLAME_TEMPERATURE,
    COLOR_GRID,
    ALBEDO_GRID,
    VELOCITY_GRID,
    VELOCITY_SCALE,
    MAJORANT,
    SHADOW_ESTIMATOR,
    CHROMATIC_TRACKING,
    FRAME_OFFSET,
    MISSING_FRAME,
];

/// What a VDB sequence does in a frame whose file is missing (`"missing_frame"`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MissingFrame {
    /// The load fails, naming the missing file (the default).
    #[default]
    Error,
    /// The nearest earlier frame's file is used, else the first later one.
    Hold,
    /// The volume is left out of that frame, with a warning.
    Empty,
}

impl MissingFrame {
    /// The key's names, in the order of the variants.
    pub const NAMES: &'static [&'static str] = &["error", "hold", "empty"];

    fn from_name(name: &str) -> Option<Self> {
        match name {
            "error" => Some(Self::Error),
            "hold" => Some(Self::Hold),
            "empty" => Some(Self::Empty),
            _ => None,
        }
    }
}

/// The most directory entries scanned for a held frame of a sequence.
const MAX_SEQUENCE_ENTRIES: usize = 1 << 20;

/// A VDB volume to place in the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeSpec {
    /// Name for messages and statistics (the node or prim).
    pub name: String,
    /// The VDB file, already resolved against the scene file's folder.
    pub file: PathBuf,
    /// Grid holding density.
    pub density_grid: String,
    /// Multiplier from grid density to extinction per metre.
    pub density_scale: f32,
    /// Single-scattering albedo per channel.
    pub albedo: Rgb,
    /// Henyey–Greenstein anisotropy.
    pub anisotropy: f32,
    /// Grid holding temperature (Kelvin after scale and offset), for blackbody emission.
    pub temperature_grid: Option<String>,
    /// Emission multiplier.
    pub emission_scale: f32,
    /// Temperature multiplier.
    pub temperature_scale: f32,
    /// Temperature offset, Kelvin.
    pub temperature_offset: f32,
    /// Grid holding flame intensity, for flame emission.
    pub flame_grid: Option<String>,
    /// Flame emission multiplier.
    pub flame_scale: f32,
    /// The flame's colour; `None`: the blackbody of `flame_temperature`.
    pub flame_color: Option<Rgb>,
    /// Kelvin of the blackbody colouring the flame.
    pub flame_temperature: f32,
    /// Colour grid (Houdini's `Cd`) multiplying the albedo.
    pub color_grid: Option<String>,
    /// Albedo grid multiplying the albedo.
    pub albedo_grid: Option<String>,
    /// Velocity grid for motion blur; `None`: `vel` if the file has it (or `vel.x/.y/.z`).
    pub velocity_grid: Option<String>,
    /// Multiplier of the velocities.
    pub velocity_scale: f32,
    /// The node's world matrix, applied after the VDB's own transform.
    pub node_to_world: Mat4,
    /// Majorant structure for tracking (`"majorant"`: `"auto"` (default; `None`, the cheapest by a pilot, see
    /// [`super::majorant_choice`]), `"adaptive"`, `"grid16"` or `"global"`).
    pub majorant: Option<MajorantKind>,
    /// Shadow-ray estimator (`"shadow_estimator"`: `"ratio"` (default) or `"residual_ratio"`).
    pub shadow_estimator: ShadowEstimator,
    /// Free flights through an RGB density (`"chromatic_tracking"`: `"auto"` (default; `None`, see
    /// [`super::grid`]), `"one_channel"` or `"spectral"`).
    pub chromatic_tracking: Option<ChromaticTracking>,
    /// The VDB file's bytes when they are embedded in the program (the bundled demo); otherwise `file` is read.
    pub embedded: Option<&'static [u8]>,
    /// The memory budget for reading the VDB file and building the majorant structure (set by the loaders from
    /// [`crate::scene::LoadOptions::limits`]).
    pub limits: crate::limits::Limits,
    /// Added to the shot's frame to choose a sequence's file.
    pub frame_offset: i64,
    /// What a sequence does when the frame's file is missing.
    pub missing_frame: MissingFrame,
    /// The shot's frame (set by the loaders from [`crate::scene::LoadOptions::frame`]); `None` reads frame 1.
    pub frame: Option<i64>,
    /// The motion-blur shutter in frames (from [`crate::scene::LoadOptions::shutter`]): a velocity grid blurs
    /// the medium over it.
    pub shutter: Option<crate::frames::Shutter>,
    /// The asset the volume belongs to, for Cryptomatte (the top-level glTF node above it, its USD model
    /// root); empty: the volume's own name.
    pub asset: String,
    /// Its light group and holdout tag, from the node's extras or the prim's attributes.
    pub tags: crate::geometry::CompositingTags,
    /// Frames per second of the shot, converting shutter frames to the seconds velocities are given in:
    /// [`crate::scene::LoadOptions::fps`] if given, else a USD stage's `framesPerSecond`, else 24.
    pub fps: f64,
}

impl VolumeSpec {
    /// A volume with every optional key at its default. The defaults of [`VOLUME_KEYS`] are declared only
    /// there: they are applied by the code that applies a file's values ([`TableDefaults`] read like a file).
    pub fn new(name: &str, file: PathBuf, node_to_world: Mat4) -> Self {
        let mut spec = Self {
            name: name.to_owned(),
            file,
            // The fields of VOLUME_KEYS: blank here, set from the table's defaults below (a key without a
            // default, `ParamDefault::Unset`, leaves its `None`).
            density_grid: String::new(),
            density_scale: 0.0,
            albedo: Rgb::ZERO,
            anisotropy: 0.0,
            temperature_grid: None,
            emission_scale: 0.0,
            temperature_scale: 0.0,
            temperature_offset: 0.0,
            flame_grid: None,
            flame_scale: 0.0,
            flame_color: None,
            flame_temperature: 0.0,
            color_grid: None,
            albedo_grid: None,
            velocity_grid: None,
            velocity_scale: 0.0,
            majorant: None,
            shadow_estimator: ShadowEstimator::Ratio,
            chromatic_tracking: None,
            frame_offset: 0,
            missing_frame: MissingFrame::Error,
            // The fields no key sets.
            node_to_world,
            embedded: None,
            limits: crate::limits::Limits::default(),
            frame: None,
            shutter: None,
            fps: crate::frames::DEFAULT_FPS,
            asset: String::new(),
            tags: crate::geometry::CompositingTags::default(),
        };
        // Only the static table reaches this (no input does): the defaults are constants, so an error here is a
        // bug in VOLUME_KEYS, which every debug build's tests of volumes would trip, not something a file can
        // cause. Hence an internal invariant's debug assertion, not a typed error.
        let applied = spec.apply_params(&TableDefaults);
        debug_assert!(
            applied.is_ok(),
            "a VOLUME_KEYS default does not read as its key's type: {applied:?}"
        );
        spec
    }

    /// The sequence frame this volume reads: the shot's frame (1 without one) plus `frame_offset`.
    pub fn file_frame(&self) -> i64 {
        self.frame.unwrap_or(1).saturating_add(self.frame_offset)
    }

    /// The VDB file to read for this frame: `file` itself, or for a sequence (a file name with a frame token,
    /// see [`crate::frames`]) the file of frame `frame + frame_offset` (frame 1 without a shot frame). `None`
    /// when that file is missing and `missing_frame` is `empty`.
    pub fn frame_file(&self) -> Result<Option<PathBuf>, VolumeError> {
        let pattern = match self.file.to_str() {
            Some(p) if self.embedded.is_none() && crate::frames::has_frame_token(p) => p,
            _ => return Ok(Some(self.file.clone())),
        };
        let frame = self.file_frame();
        let path = PathBuf::from(crate::frames::with_frame(pattern, frame).unwrap_or_default());
        if path.is_file() {
            return Ok(Some(path));
        }
        let missing = || VolumeError::MissingFrame {
            pattern: self.file.clone(),
            frame,
            file: path.clone(),
        };
        match self.missing_frame {
            MissingFrame::Error => Err(missing()),
            MissingFrame::Empty => Ok(None),
            MissingFrame::Hold => self.held_frame(frame).map(Some).ok_or_else(missing),
        }
    }

    /// The sequence file nearest before `frame`, else the first after it, found by listing the folder.
    fn held_frame(&self, frame: i64) -> Option<PathBuf> {
        let dir = match self.file.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => std::path::Path::new("."),
        };
        let name_pattern = self.file.file_name()?.to_str()?;
        let frames: Vec<(i64, PathBuf)> = std::fs::read_dir(dir)
            .ok()?
            .take(MAX_SEQUENCE_ENTRIES)
            .filter_map(|e| {
                let e = e.ok()?;
                let n = crate::frames::frame_of(name_pattern, e.file_name().to_str()?)?;
                e.path().is_file().then(|| (n, e.path()))
            })
            .collect();
        let before = frames
            .iter()
            .filter(|(n, _)| *n <= frame)
            .max_by_key(|(n, _)| *n);
        let after = frames
            .iter()
            .filter(|(n, _)| *n > frame)
            .min_by_key(|(n, _)| *n);
        before.or(after).map(|(_, p)| p.clone())
    }

    /// Checks the parameters: albedo in \[0, 1\], |g| < 1, finite non-negative scales.
    pub fn validate(&self) -> Result<(), ParamError> {
        let out_of_range = |key: &ParamKey, value: String, constraint| ParamError::OutOfRange {
            key: key.name.to_owned(),
            value,
            constraint,
        };
        if !(self.albedo.cmpge(Rgb::ZERO).all() && self.albedo.cmple(Rgb::ONE).all()) {
            return Err(out_of_range(
                &ALBEDO,
                format!("{:?}", self.albedo.to_array()),
                "lie in [0, 1]",
            ));
        }
        if self.anisotropy.is_nan() || self.anisotropy.abs() >= 1.0 {
            return Err(out_of_range(
                &ANISOTROPY,
                self.anisotropy.to_string(),
                "lie in (-1, 1)",
            ));
        }
        for (key, v) in [
            (&DENSITY_SCALE, self.density_scale),
            (&EMISSION_SCALE, self.emission_scale),
            (&TEMPERATURE_SCALE, self.temperature_scale),
            (&FLAME_SCALE, self.flame_scale),
            (&FLAME_TEMPERATURE, self.flame_temperature),
        ] {
            if !v.is_finite() || v < 0.0 {
                return Err(out_of_range(
                    key,
                    v.to_string(),
                    "be a finite non-negative number",
                ));
            }
        }
        if !self.temperature_offset.is_finite() {
            return Err(out_of_range(
                &TEMPERATURE_OFFSET,
                self.temperature_offset.to_string(),
                "be finite",
            ));
        }
        if !self.velocity_scale.is_finite() {
            return Err(out_of_range(
                &VELOCITY_SCALE,
                self.velocity_scale.to_string(),
                "be finite",
            ));
        }
        if let Some(c) = self
            .flame_color
            .filter(|c| !(c.is_finite() && c.min_element() >= 0.0))
        {
            return Err(out_of_range(
                &FLAME_COLOR,
                format!("{:?}", c.to_array()),
                "be finite and non-negative",
            ));
        }
        Ok(())
    }

    /// Reads every key of [`VOLUME_KEYS`] but `file` that `params` gives, leaving the others as they are, then
    /// validates. glTF gives every key; a USD prim gives its `nimbus:` attributes (the grids come from its
    /// field relationships).
    pub fn read_params(&mut self, params: &impl ParamSource) -> Result<(), ParamError> {
        self.apply_params(params)?;
        self.validate()
    }

    /// Sets the field of every key of [`VOLUME_KEYS`] but `file` that `params` gives, leaving the others as
    /// they are; the shared step of reading a file ([`Self::read_params`]) and of taking the table's defaults
    /// ([`Self::new`]).
    fn apply_params(&mut self, params: &impl ParamSource) -> Result<(), ParamError> {
        if let Some(g) = params.text(&DENSITY_GRID)? {
            self.density_grid = g;
        }
        for (key, field) in [
            (&TEMPERATURE_GRID, &mut self.temperature_grid),
            (&FLAME_GRID, &mut self.flame_grid),
            (&COLOR_GRID, &mut self.color_grid),
            (&ALBEDO_GRID, &mut self.albedo_grid),
            (&VELOCITY_GRID, &mut self.velocity_grid),
        ] {
            if let Some(g) = params.text(key)? {
                *field = Some(g);
            }
        }
        if let Some(c) = params.rgb(&FLAME_COLOR)? {
            self.flame_color = Some(c);
        }
        for (key, field) in [
            (&DENSITY_SCALE, &mut self.density_scale),
            (&ANISOTROPY, &mut self.anisotropy),
            (&EMISSION_SCALE, &mut self.emission_scale),
            (&TEMPERATURE_SCALE, &mut self.temperature_scale),
            (&TEMPERATURE_OFFSET, &mut self.temperature_offset),
            (&FLAME_SCALE, &mut self.flame_scale),
            (&FLAME_TEMPERATURE, &mut self.flame_temperature),
            (&VELOCITY_SCALE, &mut self.velocity_scale),
        ] {
            if let Some(v) = params.number(key)? {
                *field = v;
            }
        }
        if let Some(a) = params.rgb(&ALBEDO)? {
            self.albedo = a;
        }
        if let Some(m) = params.text(&MAJORANT)? {
            self.majorant = MajorantKind::ALL.into_iter().find(|k| k.name() == m);
        }
        if let Some(m) = params.text(&SHADOW_ESTIMATOR)? {
            self.shadow_estimator = ShadowEstimator::from_name(&m).unwrap_or(self.shadow_estimator);
        }
        if let Some(m) = params.text(&CHROMATIC_TRACKING)? {
            self.chromatic_tracking = ChromaticTracking::from_name(&m);
        }
        if let Some(m) = params.text(&MISSING_FRAME)? {
            self.missing_frame = MissingFrame::from_name(&m).unwrap_or(self.missing_frame);
        }
        if let Some(offset) = params.number(&FRAME_OFFSET)? {
            if offset.fract() != 0.0 || offset.abs() > 1e9 {
                return Err(ParamError::OutOfRange {
                    key: FRAME_OFFSET.name.to_owned(),
                    value: offset.to_string(),
                    constraint: "be a whole number of frames within +/-1e9",
                });
            }
            self.frame_offset = offset as i64;
        }
        Ok(())
    }

    /// Reads glTF's `extras.nimbus_volume` object; `base` is the glTF file's folder.
    pub fn from_json(
        value: &serde_json::Value,
        name: &str,
        base: &std::path::Path,
        node_to_world: Mat4,
    ) -> Result<Self, VolumeError> {
        let params = JsonParams::new(value);
        let file = params.required_text(&FILE)?;
        let mut spec = Self::new(name, base.join(file), node_to_world);
        spec.read_params(&params)?;
        Ok(spec)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn defaults_and_validation() {
        let base = std::path::Path::new("/scenes");
        let s = VolumeSpec::from_json(&json!({"file": "smoke.vdb"}), "n", base, Mat4::IDENTITY)
            .unwrap();
        assert_eq!(s.file, PathBuf::from("/scenes/smoke.vdb"));
        assert_eq!(
            (
                s.density_grid.as_str(),
                s.density_scale,
                s.albedo,
                s.anisotropy
            ),
            ("density", 1.0, Rgb::ONE, 0.0)
        );
        assert!(matches!(
            VolumeSpec::from_json(&json!({}), "n", base, Mat4::IDENTITY),
            Err(VolumeError::Param(ParamError::Missing { .. }))
        ));
        assert!(VolumeSpec::from_json(
            &json!({"file": "a", "albedo": [1.2, 0, 0]}),
            "n",
            base,
            Mat4::IDENTITY
        )
        .is_err());
        assert!(VolumeSpec::from_json(
            &json!({"file": "a", "anisotropy": 1.0}),
            "n",
            base,
            Mat4::IDENTITY
        )
        .is_err());
        let full = json!({"file": "a", "density_grid": "d", "density_scale": 10.0, "albedo": [0.9, 0.8, 0.7],
                          "anisotropy": 0.3, "temperature_grid": "t", "emission_scale": 2.0,
                          "temperature_scale": 3.0, "temperature_offset": 4.0});
        let s = VolumeSpec::from_json(&full, "n", base, Mat4::IDENTITY).unwrap();
        assert_eq!(s.temperature_grid.as_deref(), Some("t"));
        assert_eq!(
            (
                s.density_scale,
                s.emission_scale,
                s.temperature_scale,
                s.temperature_offset
            ),
            (10.0, 2.0, 3.0, 4.0)
        );
    }

    #[test]
    fn omitting_a_key_is_giving_its_table_default() {
        let base = std::path::Path::new("/");
        let omitted =
            VolumeSpec::from_json(&json!({"file": "a"}), "n", base, Mat4::IDENTITY).unwrap();
        let mut checked = 0;
        for key in VOLUME_KEYS {
            let Some(default) = crate::params::default_as_json(key) else {
                continue;
            };
            let given = json!({"file": "a", key.name: default});
            let explicit = VolumeSpec::from_json(&given, "n", base, Mat4::IDENTITY).unwrap();
            assert_eq!(
                explicit, omitted,
                "'{}' given as its default {default}",
                key.name
            );
            checked += 1;
        }
        assert!(checked >= 15, "only {checked} keys have a default");
    }

    #[test]
    fn majorant_choices_are_the_kinds_names() {
        let names: Vec<&str> = MajorantKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(MAJORANT_CHOICES[0], "auto");
        assert_eq!(&MAJORANT_CHOICES[1..], names.as_slice());
        let base = std::path::Path::new("/");
        for kind in MajorantKind::ALL {
            let v =
                json!({"file": "a", "majorant": kind.name(), "shadow_estimator": "residual_ratio"});
            let s = VolumeSpec::from_json(&v, "n", base, Mat4::IDENTITY).unwrap();
            assert_eq!(s.majorant, Some(kind));
            assert_eq!(s.shadow_estimator, ShadowEstimator::ResidualRatio);
        }
        let v = json!({"file": "a", "majorant": "grid8"});
        let e = VolumeSpec::from_json(&v, "n", base, Mat4::IDENTITY).unwrap_err();
        assert!(
            matches!(e, VolumeError::Param(ParamError::UnknownChoice { .. })),
            "{e}"
        );
    }

    #[test]
    fn chromatic_tracking_choices_are_the_methods_names() {
        let names: Vec<&str> = ChromaticTracking::NAMES.to_vec();
        assert_eq!(CHROMATIC_TRACKING_CHOICES[0], "auto");
        assert_eq!(&CHROMATIC_TRACKING_CHOICES[1..], names.as_slice());
        let base = std::path::Path::new("/");
        for m in ChromaticTracking::ALL {
            let v = json!({"file": "a", "chromatic_tracking": m.name()});
            let s = VolumeSpec::from_json(&v, "n", base, Mat4::IDENTITY).unwrap();
            assert_eq!(s.chromatic_tracking, Some(m));
        }
        let v = json!({"file": "a", "chromatic_tracking": "auto"});
        let s = VolumeSpec::from_json(&v, "n", base, Mat4::IDENTITY).unwrap();
        assert_eq!(s.chromatic_tracking, None);
        let v = json!({"file": "a", "chromatic_tracking": "hero"});
        let e = VolumeSpec::from_json(&v, "n", base, Mat4::IDENTITY).unwrap_err();
        assert!(
            matches!(e, VolumeError::Param(ParamError::UnknownChoice { .. })),
            "{e}"
        );
    }

    #[test]
    fn reference_key_tables_are_the_code_tables() {
        let readme =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/reference.md"))
                .unwrap();
        for (what, keys) in [
            ("nimbus_volume", VOLUME_KEYS),
            ("nimbus_medium", super::super::MEDIUM_KEYS),
        ] {
            let table = crate::params::markdown_table(keys);
            assert!(
                readme.contains(&table),
                "docs/reference.md's {what} key table is not the code's; it should read:\n{table}"
            );
        }
    }
}
