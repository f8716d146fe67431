//! The declaration of a VDB volume, shared by every scene format: glTF's node `extras.nimbus_volume` and USD's
//! `Volume` prims with `nimbus:` attributes.
//!
//! Keys (glTF) / attributes (USD, prefixed `nimbus:`), all but `file` optional:
//! - `file`: the VDB file, relative to the scene file that names it;
//! - `density_grid` (default `"density"`), `density_scale` (1): σ_t(x) = density_scale · ρ(x) per world metre,
//!   ρ the trilinear lookup (OpenVDB BoxSampler convention);
//! - `albedo` (\[1, 1, 1\]): σ_s = albedo · σ_t, σ_a = σ_t − σ_s; each component in \[0, 1\];
//! - `anisotropy` (0): Henyey–Greenstein g, |g| < 1;
//! - `temperature_grid` (none), `emission_scale` (1), `temperature_scale` (1), `temperature_offset` (0):
//!   emission σ_a · L_e with L_e = emission_scale · blackbody(temperature_scale · T(x) + temperature_offset),
//!   normalised RGB (pbrt-v4's convention for grid media).
//!
//! Placement: index space → the VDB's own index-to-world matrix → the node's world matrix.

use super::grid::ShadowEstimator;
use super::majorant::MajorantKind;
use crate::math::{Mat4, Rgb};
use std::path::PathBuf;

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
    /// The node's world matrix, applied after the VDB's own transform.
    pub node_to_world: Mat4,
    /// Majorant structure for tracking (`"majorant"`: `"auto"` (default; `None`, the cheapest by a pilot, see
    /// [`super::majorant_choice`]), `"adaptive"`, `"grid16"` or `"global"`).
    pub majorant: Option<MajorantKind>,
    /// Shadow-ray estimator (`"shadow_estimator"`: `"ratio"` (default) or `"residual_ratio"`).
    pub shadow_estimator: ShadowEstimator,
    /// The VDB file's bytes when they are embedded in the program (the bundled demo); otherwise `file` is read.
    pub embedded: Option<&'static [u8]>,
}

impl VolumeSpec {
    /// A volume with every optional key at its default.
    pub fn new(name: &str, file: PathBuf, node_to_world: Mat4) -> Self {
        Self {
            name: name.to_owned(),
            file,
            density_grid: "density".into(),
            density_scale: 1.0,
            albedo: Rgb::ONE,
            anisotropy: 0.0,
            temperature_grid: None,
            emission_scale: 1.0,
            temperature_scale: 1.0,
            temperature_offset: 0.0,
            node_to_world,
            majorant: None,
            shadow_estimator: ShadowEstimator::Ratio,
            embedded: None,
        }
    }

    /// Checks the parameters: albedo in \[0, 1\], |g| < 1, finite non-negative scales.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.albedo.cmpge(Rgb::ZERO).all() && self.albedo.cmple(Rgb::ONE).all()) {
            return Err(format!(
                "albedo {:?} must lie in [0, 1]",
                self.albedo.to_array()
            ));
        }
        if self.anisotropy.is_nan() || self.anisotropy.abs() >= 1.0 {
            return Err(format!(
                "anisotropy {} must lie in (-1, 1)",
                self.anisotropy
            ));
        }
        for (key, v) in [
            ("density_scale", self.density_scale),
            ("emission_scale", self.emission_scale),
            ("temperature_scale", self.temperature_scale),
        ] {
            if !v.is_finite() || v < 0.0 {
                return Err(format!("{key} {v} must be a finite non-negative number"));
            }
        }
        if !self.temperature_offset.is_finite() {
            return Err("temperature_offset must be finite".into());
        }
        Ok(())
    }

    /// Reads glTF's `extras.nimbus_volume` object; `base` is the glTF file's folder.
    pub fn from_json(
        value: &serde_json::Value,
        name: &str,
        base: &std::path::Path,
        node_to_world: Mat4,
    ) -> Result<Self, String> {
        let file = value
            .get("file")
            .and_then(|f| f.as_str())
            .ok_or("'file' (the VDB path) is required")?;
        let mut spec = Self::new(name, base.join(file), node_to_world);
        let number = |key: &str| -> Result<Option<f32>, String> {
            match value.get(key) {
                None => Ok(None),
                Some(v) => v
                    .as_f64()
                    .filter(|v| v.is_finite())
                    .map(|v| Some(v as f32))
                    .ok_or(format!("'{key}' must be a number")),
            }
        };
        let string = |key: &str| -> Result<Option<String>, String> {
            match value.get(key) {
                None => Ok(None),
                Some(v) => v
                    .as_str()
                    .map(|s| Some(s.to_owned()))
                    .ok_or(format!("'{key}' must be a string")),
            }
        };
        if let Some(g) = string("density_grid")? {
            spec.density_grid = g;
        }
        spec.temperature_grid = string("temperature_grid")?;
        if let Some(v) = number("density_scale")? {
            spec.density_scale = v;
        }
        if let Some(v) = number("anisotropy")? {
            spec.anisotropy = v;
        }
        if let Some(v) = number("emission_scale")? {
            spec.emission_scale = v;
        }
        if let Some(v) = number("temperature_scale")? {
            spec.temperature_scale = v;
        }
        if let Some(v) = number("temperature_offset")? {
            spec.temperature_offset = v;
        }
        if let Some(m) = string("majorant")? {
            spec.majorant = match m.as_str() {
                "auto" => None,
                "adaptive" => Some(MajorantKind::Adaptive),
                "grid16" => Some(MajorantKind::Grid16),
                "global" => Some(MajorantKind::Global),
                other => {
                    return Err(format!(
                        "'majorant' {other:?} is not auto, adaptive, grid16 or global"
                    ))
                }
            };
        }
        if let Some(m) = string("shadow_estimator")? {
            spec.shadow_estimator = match m.as_str() {
                "ratio" => ShadowEstimator::Ratio,
                "residual_ratio" => ShadowEstimator::ResidualRatio,
                other => {
                    return Err(format!(
                        "'shadow_estimator' {other:?} is not ratio or residual_ratio"
                    ))
                }
            };
        }
        if let Some(a) = value.get("albedo") {
            spec.albedo = match a.as_f64() {
                Some(x) => Rgb::splat(x as f32),
                None => crate::scene::gltf::parse_rgb(a)
                    .ok_or("'albedo' must be a number or [r, g, b]")?,
            };
        }
        spec.validate()?;
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
        assert!(VolumeSpec::from_json(&json!({}), "n", base, Mat4::IDENTITY).is_err());
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
}
