//! Nimbus's `extras`: the scene's ([`SCENE_EXTRAS`]: `nimbus_environment` with [`ENVIRONMENT_KEYS`] `color`,
//! `map`, `intensity`, `light_group`; `nimbus_transparent`; and `max_bounces`), the compositing tags of a node
//! or material (`nimbus_light_group`, `nimbus_holdout`, `nimbus_shadow_catcher`), and a node's
//! `nimbus_volume` (the keys of `crate::volume::spec::VOLUME_KEYS`), a VDB medium placed by the node.

use super::nodes::NodeContext;
use super::{Loader, QUOTE};
use crate::geometry::CompositingTags;
use crate::light::{EnvironmentLight, EnvironmentMap};
use crate::limits::{one_line, Limits};
use crate::math::Mat4;
use crate::params::{parse_rgb, unknown_json_keys, unknown_json_names};
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use std::path::Path;

impl Loader<'_> {
    /// Reads the scene's `extras`: `max_bounces`, `nimbus_environment` and `nimbus_transparent` (unknown
    /// `nimbus_*` keys warned about, or refused under `--strict`).
    pub(super) fn read_scene_extras(
        &mut self,
        extras: &gltf::json::Extras,
    ) -> Result<(), SceneError> {
        let Some(raw) = extras else { return Ok(()) };
        let value: serde_json::Value = serde_json::from_str(raw.get()).map_err(|e| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Settings,
                format!("scene extras: {e}"),
            ))
        })?;
        self.unknown_keys(
            "scene extras",
            &unknown_json_names(&value, SCENE_EXTRAS, "nimbus_"),
        )?;
        if let Some(env) = value.get("nimbus_environment") {
            let unknown = unknown_json_names(env, ENVIRONMENT_KEYS, "");
            self.unknown_keys("scene extras: nimbus_environment", &unknown)?;
        }
        if let Some(b) = value.get("max_bounces") {
            let b = b.as_u64().ok_or_else(|| {
                self.error(SceneErrorKind::malformed(
                    MalformedPart::Settings,
                    "scene extras: max_bounces must be a non-negative integer",
                ))
            })?;
            self.builder.max_bounces = Some(b.min(u32::MAX as u64) as u32);
        }
        if let Some(env) = value.get("nimbus_environment") {
            let (env, group) = parse_environment(env, &self.base, &self.options.limits)
                .map_err(|kind| self.error(kind))?;
            self.builder.set_environment(env);
            self.builder.set_environment_group(group);
        }
        if let Some(t) = value.get("nimbus_transparent") {
            let t = t.as_bool().ok_or_else(|| {
                self.error(SceneErrorKind::malformed(
                    MalformedPart::Settings,
                    "scene extras: nimbus_transparent must be true or false",
                ))
            })?;
            self.builder.set_transparent(t);
        }
        Ok(())
    }

    /// A node's `extras.nimbus_volume` becomes a grid medium placed by the node's world matrix, with the
    /// node's asset and compositing tags.
    pub(super) fn load_volume(
        &mut self,
        node: &gltf::Node,
        extras: &serde_json::Value,
        world: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .map_or_else(|| format!("node {}", node.index()), |n| one_line(n, QUOTE));
        let Some(value) = extras.get("nimbus_volume") else {
            return Ok(());
        };
        let volume_error = |source| {
            self.error(SceneErrorKind::Volume {
                at: format!("node '{name}': nimbus_volume").into(),
                source,
            })
        };
        let mut spec = crate::volume::VolumeSpec::from_json(value, &name, &self.base, *world)
            .map_err(volume_error)?;
        let unknown = unknown_json_keys(value, crate::volume::spec::VOLUME_KEYS);
        self.unknown_keys(&format!("node '{name}': nimbus_volume"), &unknown)?;
        let file = value.get("file").and_then(|f| f.as_str());
        spec.embedded = file.and_then(|f| self.options.embedded_file(f));
        self.options.apply_volume_override(&mut spec);
        spec.asset = context.asset.clone();
        spec.tags = context.tags.clone();
        match self.builder.add_volume(&spec) {
            Ok(_) => Ok(()),
            Err(source) => Err(self.error(SceneErrorKind::Volume {
                at: format!("node '{name}': nimbus_volume").into(),
                source,
            })),
        }
    }
}

/// The `nimbus_*` keys a scene's `extras` may hold (its other keys belong to other tools).
const SCENE_EXTRAS: &[&str] = &[
    "nimbus_environment",
    "nimbus_transparent",
    "nimbus_light_units",
];

/// The keys of a `nimbus_environment` object.
const ENVIRONMENT_KEYS: &[&str] = &["color", "map", "intensity", "light_group"];

/// Parses a `nimbus_environment` object: `{"color": [r,g,b]}` or `{"map": "file", "intensity": s}`, with an
/// optional `"light_group": "name"`; the map path is relative to `base`. Returns the light and its group.
pub(super) fn parse_environment(
    value: &serde_json::Value,
    base: &Path,
    limits: &Limits,
) -> Result<(EnvironmentLight, Option<String>), SceneErrorKind> {
    let malformed = |m: &str| {
        SceneErrorKind::malformed(MalformedPart::Settings, format!("nimbus_environment: {m}"))
    };
    let group = match value.get("light_group") {
        None => None,
        Some(g) => Some(light_group_name(g).map_err(|m| {
            SceneErrorKind::malformed(MalformedPart::Settings, format!("nimbus_environment: {m}"))
        })?),
    };
    parse_environment_light(value, base, limits, &malformed).map(|env| (env, group))
}

/// The light of a `nimbus_environment` object (see [`parse_environment`]).
fn parse_environment_light(
    value: &serde_json::Value,
    base: &Path,
    limits: &Limits,
    malformed: &dyn Fn(&str) -> SceneErrorKind,
) -> Result<EnvironmentLight, SceneErrorKind> {
    if let Some(c) = value.get("color") {
        let rgb = parse_rgb(c)
            .ok_or_else(|| malformed("'color' must be an array of three non-negative numbers"))?;
        return Ok(EnvironmentLight::Constant(rgb));
    }
    if let Some(m) = value.get("map") {
        let file = m
            .as_str()
            .ok_or_else(|| malformed("'map' must be a file name"))?;
        let intensity = match value.get("intensity") {
            Some(v) => v
                .as_f64()
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| malformed("'intensity' must be a non-negative number"))?
                as f32,
            None => 1.0,
        };
        let map = EnvironmentMap::load(&base.join(file), intensity, limits)?;
        return Ok(EnvironmentLight::Map(Box::new(map)));
    }
    Err(malformed("expected 'color' or 'map'"))
}

/// A compositing tag in `extras` that cannot be read.
#[derive(Debug, thiserror::Error)]
pub(super) enum TagError {
    /// `nimbus_holdout` or `nimbus_shadow_catcher` (the key) not a boolean.
    #[error("{0} must be true or false")]
    NotAFlag(&'static str),
    /// `nimbus_light_group` not a light group's name.
    #[error("nimbus_light_group: {0}")]
    LightGroup(BadLightGroup),
}

/// A light group's name that is not a non-empty string of at most 64 characters.
#[derive(Debug, thiserror::Error)]
#[error("a light group must be a non-empty string of at most 64 characters")]
pub(super) struct BadLightGroup;

/// The compositing tags in a node's or a material's `extras` (see [`CompositingTags`]): `nimbus_light_group`
/// (a non-empty string), `nimbus_holdout` and `nimbus_shadow_catcher` (booleans). An error names the key.
pub(super) fn node_tags(extras: Option<&serde_json::Value>) -> Result<CompositingTags, TagError> {
    let Some(extras) = extras else {
        return Ok(CompositingTags::default());
    };
    let flag = |key: &'static str| match extras.get(key) {
        None => Ok(false),
        Some(v) => v.as_bool().ok_or(TagError::NotAFlag(key)),
    };
    Ok(CompositingTags {
        light_group: match extras.get("nimbus_light_group") {
            None => None,
            Some(g) => Some(light_group_name(g).map_err(TagError::LightGroup)?),
        },
        holdout: flag("nimbus_holdout")?,
        shadow_catcher: flag("nimbus_shadow_catcher")?,
    })
}

/// A light group's name: a non-empty string of at most 64 characters.
fn light_group_name(value: &serde_json::Value) -> Result<String, BadLightGroup> {
    match value.as_str() {
        Some(name) if !name.trim().is_empty() && name.chars().count() <= 64 => Ok(name.to_owned()),
        _ => Err(BadLightGroup),
    }
}
