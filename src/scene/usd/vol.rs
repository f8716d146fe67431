//! UsdVol: `Volume` prims with `OpenVDBAsset` fields, and the `nimbus:` attributes of
//! [`VOLUME_KEYS`](crate::volume::spec::VOLUME_KEYS), read through the same table as glTF's keys.

use super::values::{number, token, vec3};
use super::Loader;
use crate::math::{Mat4, Rgb};
use crate::params::{ParamError, ParamKey, ParamSource, ParamType, ParamValue, UsdBinding};
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use crate::volume::VolumeSpec;
use openusd::{sdf, usd};
use std::path::PathBuf;

/// A prim's `nimbus:` attributes as a parameter source: keys bound to [`UsdBinding::Attribute`] are read from
/// `nimbus:<key>`, the others are not given.
struct UsdParams<'a>(&'a usd::Prim);

impl ParamSource for UsdParams<'_> {
    fn spelling(&self, key: &ParamKey) -> String {
        format!("nimbus:{}", key.name)
    }

    fn get(&self, key: &ParamKey) -> Result<Option<ParamValue>, ParamError> {
        if key.usd != UsdBinding::Attribute {
            return Ok(None);
        }
        let value = self
            .0
            .attribute(self.spelling(key))
            .get::<sdf::Value>()
            .map_err(|e| ParamError::Unreadable {
                key: self.spelling(key),
                message: format!("{e:#}"),
            })?;
        let Some(v) = value else {
            return Ok(None);
        };
        let finite = number(&v).filter(|x| x.is_finite());
        let converted = match key.ty {
            ParamType::Number => finite.map(ParamValue::Number),
            ParamType::NonNegative => finite.filter(|x| *x >= 0.0).map(ParamValue::Number),
            ParamType::Rgb => vec3(&v)
                .filter(|c| c.is_finite() && c.min_element() >= 0.0)
                .map(ParamValue::Rgb),
            ParamType::GreyOrRgb => vec3(&v)
                .or_else(|| number(&v).map(|a| Rgb::splat(a as f32)))
                .map(ParamValue::Rgb),
            ParamType::Text => token(&v).map(ParamValue::Text),
            ParamType::Choice(names) => match token(&v) {
                Some(t) if !names.contains(&t.as_str()) => {
                    return Err(ParamError::UnknownChoice {
                        key: self.spelling(key),
                        value: t,
                        choices: names,
                    })
                }
                t => t.map(ParamValue::Text),
            },
            ParamType::Object(_) => None,
        };
        converted.map(Some).ok_or_else(|| ParamError::WrongType {
            key: self.spelling(key),
            expected: key.ty.describe(),
        })
    }
}

impl Loader<'_> {
    /// Reads the `Volume` prim `prim` (at `world`): its OpenVDB fields (density required, temperature, flame,
    /// Cd and albedo optional, all from one file) and its `nimbus:` medium parameters.
    pub(super) fn volume(&mut self, prim: &usd::Prim, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let mut fields = Vec::new();
        for name in [
            "field:density",
            "field:temperature",
            "field:flame",
            "field:Cd",
            "field:albedo",
        ] {
            let field = self.volume_field(prim, &at, name)?;
            fields.push(field);
        }
        let Some((file, density_grid)) = fields[0].clone() else {
            self.warn(format!(
                "{at}: Volume without a field:density relationship; skipped"
            ));
            return Ok(());
        };
        let mut spec = VolumeSpec::new(&at, file.clone(), *world);
        // Velocities are per second: a shutter's frames are seconds at the stage's rate (unless --fps).
        spec.fps = self.frames_per_second()?;
        spec.density_grid = density_grid;
        let channels = [
            &mut spec.temperature_grid,
            &mut spec.flame_grid,
            &mut spec.color_grid,
            &mut spec.albedo_grid,
        ];
        for (field, slot) in fields[1..].iter().zip(channels) {
            if let Some((other_file, grid)) = field {
                if *other_file != file {
                    return Err(self.error(MalformedPart::Volume,
                        &at,
                        "every field of a Volume (density, temperature, flame, Cd, albedo) must come from the same VDB file",
                    ));
                }
                *slot = Some(grid.clone());
            }
        }
        spec.read_params(&UsdParams(prim)).map_err(|e| {
            SceneError::new(
                self.path,
                SceneErrorKind::Volume {
                    at: at.as_str().into(),
                    source: e.into(),
                },
            )
        })?;
        spec.asset = self.asset.clone();
        spec.tags = self.tags.clone();
        self.volumes.push(spec);
        Ok(())
    }

    /// The file and grid name of the `OpenVDBAsset` that field relationship `name` of the Volume `prim` (at
    /// `at`) targets, or `None` when it targets none.
    fn volume_field(
        &mut self,
        prim: &usd::Prim,
        at: &str,
        name: &str,
    ) -> Result<Option<(PathBuf, String)>, SceneError> {
        let targets = prim
            .relationship(name)
            .targets()
            .map_err(|e| self.error(MalformedPart::Volume, at, format!("{e:#}")))?;
        let Some(t) = targets.first() else {
            return Ok(None);
        };
        let asset = self.stage.prim(t.prim_path().as_str());
        let kind = self.type_name(&asset)?;
        if kind != "OpenVDBAsset" {
            return Err(self.error(
                MalformedPart::Volume,
                at,
                format!("{name} targets a '{kind}', not an OpenVDBAsset"),
            ));
        }
        let file = self.asset(&asset, "filePath")?.ok_or_else(|| {
            self.error(
                MalformedPart::Volume,
                asset.path().as_str(),
                "filePath is required",
            )
        })?;
        let grid = self
            .value(&asset, "fieldName")?
            .and_then(|v| token(&v))
            .unwrap_or_else(|| name["field:".len()..].to_owned());
        if self.float(&asset, "fieldIndex", 0.0)? != 0.0 {
            self.warn(format!(
                "{}: fieldIndex is ignored (the grid is found by name)",
                asset.path().as_str()
            ));
        }
        Ok(Some((file, grid)))
    }
}
