//! UsdVol: `Volume` prims with `OpenVDBAsset` fields, and the `nimbus:` attributes of [`VolumeSpec`].

use super::values::{number, token, vec3};
use super::Loader;
use crate::math::{Mat4, Rgb};
use crate::scene::SceneError;
use crate::volume::VolumeSpec;
use openusd::usd;

impl Loader<'_> {
    pub(super) fn volume(&mut self, prim: &usd::Prim, world: &Mat4) -> Result<(), SceneError> {
        let at = prim.path().as_str().to_owned();
        let mut fields = Vec::new();
        for name in ["field:density", "field:temperature"] {
            let targets = prim
                .relationship(name)
                .targets()
                .map_err(|e| self.error(&at, format!("{e:#}")))?;
            let field = match targets.first() {
                Some(t) => {
                    let asset = self.stage.prim(t.prim_path().as_str());
                    let kind = self.type_name(&asset)?;
                    if kind != "OpenVDBAsset" {
                        return Err(self.error(
                            &at,
                            format!("{name} targets a '{kind}', not an OpenVDBAsset"),
                        ));
                    }
                    let file = self
                        .asset(&asset, "filePath")?
                        .ok_or_else(|| self.error(asset.path().as_str(), "filePath is required"))?;
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
                    Some((file, grid))
                }
                None => None,
            };
            fields.push(field);
        }
        let (Some((file, density_grid)), temperature) = (fields[0].clone(), fields[1].clone())
        else {
            self.warn(format!(
                "{at}: Volume without a field:density relationship; skipped"
            ));
            return Ok(());
        };
        let mut spec = VolumeSpec::new(&at, file.clone(), *world);
        spec.density_grid = density_grid;
        if let Some((t_file, t_grid)) = temperature {
            if t_file != file {
                return Err(self.error(
                    &at,
                    "density and temperature fields must come from the same VDB file",
                ));
            }
            spec.temperature_grid = Some(t_grid);
        }
        spec.density_scale = self.float(prim, "nimbus:density_scale", spec.density_scale)?;
        spec.albedo = match self.value(prim, "nimbus:albedo")? {
            None => spec.albedo,
            Some(v) => vec3(&v)
                .or_else(|| number(&v).map(|a| Rgb::splat(a as f32)))
                .ok_or_else(|| self.error(&at, "nimbus:albedo must be a color3f or a float"))?,
        };
        spec.anisotropy = self.float(prim, "nimbus:anisotropy", spec.anisotropy)?;
        spec.emission_scale = self.float(prim, "nimbus:emission_scale", spec.emission_scale)?;
        spec.temperature_scale =
            self.float(prim, "nimbus:temperature_scale", spec.temperature_scale)?;
        spec.temperature_offset =
            self.float(prim, "nimbus:temperature_offset", spec.temperature_offset)?;
        spec.validate().map_err(|m| self.error(&at, m))?;
        self.volumes.push(spec);
        Ok(())
    }
}
