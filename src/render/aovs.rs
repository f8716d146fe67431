//! The compositing layers a render can write beyond the beauty, how a user chooses them (`--aovs`), and the
//! plan the film follows to accumulate them.
//!
//! Every additive layer is a per-pixel exact sum like the beauty (see `render/exact.rs`): the film keeps one RGB
//! *slot* of sums per light-path layer, colour, light group, and the shadow catcher's two sums, so parts of a
//! render merge bit for bit. Cryptomatte keeps per-pixel ID → coverage sums ([`super::cryptomatte`]).
//!
//! Light-path layers follow the first scattering event of each path (a surface's lobe class, see
//! [`crate::material::LobeClass`], or a medium), as Cycles' passes and Arnold's LPEs do:
//! - `emission`: emitters seen directly (no scattering before them), surfaces and media; `environment`: the
//!   environment seen directly;
//! - `<class>_direct`: light reaching the camera after exactly one scattering event of that class (next-event
//!   estimation there, or an emitter hit right after it); `<class>_indirect`: after two or more, classed by the
//!   first; `class` is `diffuse`, `glossy`, `transmission` or `volume`;
//! - at a surface, the light is split between the classes in proportion to each lobe class's share of the BSDF
//!   value, per channel (Cycles does the same), and a delta lobe gives all of it to its class;
//! - `diffuse_color`, `glossy_color`, `transmission_color`: the classes' colours at the first surface (their
//!   directional albedo estimates, `crate::material::Bsdf::colors`, times the path throughput there).
//!   As in Cycles, the surface light-path layers are written divided by their class's colour, so that
//!   `(direct + indirect) × color` rebuilds the light:
//!
//!   beauty = Σ_{c ∈ diffuse, glossy, transmission} (c_direct + c_indirect) × c_color + volume_direct +
//!   volume_indirect + emission + environment
//!
//!   (without `--transparent`; with it the beauty leaves `environment` out).
//!
//! Light groups (`lg_<name>`) split the beauty by the emitter each contribution came from; they sum to the
//! beauty. The shadow catcher's layer is the ratio of the light reaching catcher surfaces with and without the
//! scene's occlusion (1: no shadow).

use super::cryptomatte::{name_id, CryptoKind, Manifest, DEFAULT_DEPTH, MAX_DEPTH};
use crate::scene::{Scene, ENVIRONMENT_NAME};
use std::fmt;

/// The light-path classes of contributions, in the order of their layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightPath {
    /// One diffuse event.
    DiffuseDirect,
    /// A diffuse first event, then more.
    DiffuseIndirect,
    /// One glossy event.
    GlossyDirect,
    /// A glossy first event, then more.
    GlossyIndirect,
    /// One transmission event.
    TransmissionDirect,
    /// A transmission first event, then more.
    TransmissionIndirect,
    /// One medium scattering event.
    VolumeDirect,
    /// A medium first event, then more.
    VolumeIndirect,
    /// Emitters seen directly.
    Emission,
    /// The environment seen directly.
    Environment,
}

impl LightPath {
    /// Every class, in layer order.
    pub const ALL: [LightPath; 10] = [
        LightPath::DiffuseDirect,
        LightPath::DiffuseIndirect,
        LightPath::GlossyDirect,
        LightPath::GlossyIndirect,
        LightPath::TransmissionDirect,
        LightPath::TransmissionIndirect,
        LightPath::VolumeDirect,
        LightPath::VolumeIndirect,
        LightPath::Emission,
        LightPath::Environment,
    ];

    /// The layer's name.
    pub fn name(self) -> &'static str {
        [
            "diffuse_direct",
            "diffuse_indirect",
            "glossy_direct",
            "glossy_indirect",
            "transmission_direct",
            "transmission_indirect",
            "volume_direct",
            "volume_indirect",
            "emission",
            "environment",
        ][self as usize]
    }

    /// The surface lobe class whose colour divides this layer, if any.
    pub fn color(self) -> Option<crate::material::LobeClass> {
        use crate::material::LobeClass;
        match self {
            LightPath::DiffuseDirect | LightPath::DiffuseIndirect => Some(LobeClass::Diffuse),
            LightPath::GlossyDirect | LightPath::GlossyIndirect => Some(LobeClass::Glossy),
            LightPath::TransmissionDirect | LightPath::TransmissionIndirect => {
                Some(LobeClass::Transmission)
            }
            _ => None,
        }
    }
}

/// The name of a colour layer (`diffuse_color`...).
pub fn color_layer_name(class: crate::material::LobeClass) -> String {
    format!("{}_color", class.name())
}

/// The first-hit layers every render accumulates; each is written when chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FirstHit {
    /// `albedo.R/G/B`.
    Albedo,
    /// `normal.X/Y/Z`.
    Normal,
    /// `depth.Z`.
    Depth,
    /// `variance.R/G/B`.
    Variance,
}

impl FirstHit {
    /// Every first-hit layer.
    pub const ALL: [FirstHit; 4] = [
        FirstHit::Albedo,
        FirstHit::Normal,
        FirstHit::Depth,
        FirstHit::Variance,
    ];

    /// The layer's name.
    pub fn name(self) -> &'static str {
        ["albedo", "normal", "depth", "variance"][self as usize]
    }
}

/// One chosen layer (or set of layers) of `--aovs`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Aov {
    /// A first-hit layer.
    FirstHit(FirstHit),
    /// A light-path layer.
    LightPath(LightPath),
    /// A colour layer.
    Color(crate::material::LobeClass),
    /// One light group's layer (`lg_<name>`, given by the layer's name).
    LightGroup(String),
    /// Every light group's layer.
    AllLightGroups,
    /// The shadow catcher's layer.
    ShadowCatcher,
    /// A Cryptomatte kind.
    Cryptomatte(CryptoKind),
}

/// The names `--aovs` takes for sets of layers, and what each stands for.
pub const AOV_SETS: [(&str, &str); 6] = [
    ("default", "albedo, normal, depth, variance"),
    (
        "lightpaths",
        "the ten light-path layers (diffuse_direct ... environment)",
    ),
    ("colors", "diffuse_color, glossy_color, transmission_color"),
    ("lightgroups", "every light group's lg_<name> layer"),
    ("cryptomatte", "CryptoObject, CryptoMaterial, CryptoAsset"),
    ("all", "every layer above and shadow_catcher"),
];

/// The layers of a render beyond the beauty and alpha (which are always written), as `--aovs` chooses them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AovSelection {
    /// The chosen layers, without repeats, in the order given.
    pub aovs: Vec<Aov>,
}

impl Default for AovSelection {
    /// The first-hit layers (`default`).
    fn default() -> Self {
        Self {
            aovs: FirstHit::ALL.into_iter().map(Aov::FirstHit).collect(),
        }
    }
}

/// Why an `--aovs` list cannot be read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown layer '{name}' in the layer list; `nimbus render --list-aovs` lists them")]
pub struct UnknownAov {
    /// The name given.
    pub name: String,
}

impl AovSelection {
    /// Nothing beyond the beauty and alpha.
    pub fn none() -> Self {
        Self { aovs: Vec::new() }
    }

    /// Reads a comma-separated list of layer names and set names ([`AOV_SETS`]), `none` for no layer. Light
    /// groups are named by their layer (`lg_key`).
    pub fn parse(list: &str) -> Result<Self, UnknownAov> {
        use crate::material::LobeClass;
        let mut out = Self::none();
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            let add: Vec<Aov> = match name {
                "none" => Vec::new(),
                "default" => Self::default().aovs,
                "lightpaths" => LightPath::ALL.into_iter().map(Aov::LightPath).collect(),
                "colors" => LobeClass::ALL.into_iter().map(Aov::Color).collect(),
                "lightgroups" => vec![Aov::AllLightGroups],
                "cryptomatte" => CryptoKind::ALL.into_iter().map(Aov::Cryptomatte).collect(),
                "all" => {
                    let mut all = Self::parse("default,lightpaths,colors,lightgroups,cryptomatte")?;
                    all.aovs.push(Aov::ShadowCatcher);
                    all.aovs
                }
                "shadow_catcher" => vec![Aov::ShadowCatcher],
                _ => vec![Self::single(name).ok_or_else(|| UnknownAov {
                    name: crate::limits::one_line(name, 64),
                })?],
            };
            for aov in add {
                if !out.aovs.contains(&aov) {
                    out.aovs.push(aov);
                }
            }
        }
        Ok(out)
    }

    /// One layer by its name.
    fn single(name: &str) -> Option<Aov> {
        use crate::material::LobeClass;
        if let Some(f) = FirstHit::ALL.into_iter().find(|f| f.name() == name) {
            return Some(Aov::FirstHit(f));
        }
        if let Some(p) = LightPath::ALL.into_iter().find(|p| p.name() == name) {
            return Some(Aov::LightPath(p));
        }
        if let Some(c) = LobeClass::ALL
            .into_iter()
            .find(|&c| color_layer_name(c) == name)
        {
            return Some(Aov::Color(c));
        }
        if let Some(k) = CryptoKind::from_layer_name(name) {
            return Some(Aov::Cryptomatte(k));
        }
        match name.strip_prefix("lg_") {
            Some(group) if !group.is_empty() => Some(Aov::LightGroup(name.to_owned())),
            _ => None,
        }
    }

    /// The layers a render writes when `--aovs` is not given: the first-hit layers, `environment` on a
    /// transparent film (what it leaves out of the beauty), every light group when the render has groups, and
    /// `shadow_catcher` when the scene has a catcher.
    pub fn for_scene(scene: &Scene, transparent: bool, groups: &LightGroups) -> Self {
        let mut s = Self::default();
        if transparent {
            s.aovs.push(Aov::LightPath(LightPath::Environment));
        }
        if !groups.names.is_empty() {
            s.aovs.push(Aov::AllLightGroups);
        }
        if scene.names().has_shadow_catcher() {
            s.aovs.push(Aov::ShadowCatcher);
        }
        s
    }

    /// True when `aov` is chosen.
    pub fn contains(&self, aov: &Aov) -> bool {
        self.aovs.contains(aov)
    }
}

/// How emitters are put in light groups (`--light-groups`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightGroupMode {
    /// The groups the scene declares (`nimbus_light_group`, `nimbus:lightGroup`); emitters in none go to
    /// `default`. No group layer when the scene declares none.
    #[default]
    Scene,
    /// One group per emitter (an emissive mesh, a punctual light, the environment, an emitting medium), named
    /// after it; emitters of the same name share a group.
    PerLight,
    /// No light groups.
    Off,
}

impl crate::params::Choice for LightGroupMode {
    const CHOICES: &'static [(&'static str, Self)] = &[
        ("scene", Self::Scene),
        ("per-light", Self::PerLight),
        ("off", Self::Off),
    ];
}

/// The most light groups a render writes: each is a layer of 3 channels and 48 bytes of film per pixel.
pub const MAX_LIGHT_GROUPS: usize = 64;

/// The light groups of a render: their layer names and each emitter's group.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LightGroups {
    /// The layer names, `lg_<group>`, in the order groups were first met.
    pub names: Vec<String>,
    /// The group of each emitter of the scene (`crate::scene::SceneNames::emitters`).
    pub group_of_emitter: Vec<u16>,
}

/// Why a render cannot have its light groups.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{count} light groups, more than the {MAX_LIGHT_GROUPS} a render writes; group lights with nimbus_light_group instead of --light-groups per-light")]
pub struct TooManyLightGroups {
    /// How many the scene would have.
    pub count: usize,
}

impl LightGroups {
    /// The groups of `scene` under `mode`.
    pub fn new(scene: &Scene, mode: LightGroupMode) -> Result<Self, TooManyLightGroups> {
        let emitters = &scene.names().emitters;
        let group_name: Box<dyn Fn(&crate::scene::Emitter) -> String> = match mode {
            LightGroupMode::Off => return Ok(Self::default()),
            LightGroupMode::Scene if !scene.names().declares_light_groups() => {
                return Ok(Self::default())
            }
            LightGroupMode::Scene => Box::new(|e| {
                e.light_group
                    .clone()
                    .unwrap_or_else(|| DEFAULT_GROUP.to_owned())
            }),
            LightGroupMode::PerLight => Box::new(|e| e.name.clone()),
        };
        let mut groups = Self::default();
        let mut by_group: Vec<String> = Vec::new();
        for e in emitters {
            let group = group_name(e);
            let index = match by_group.iter().position(|g| *g == group) {
                Some(i) => i,
                None => {
                    let layer = unique_layer_name(&group, &groups.names);
                    groups.names.push(layer);
                    by_group.push(group);
                    by_group.len() - 1
                }
            };
            groups.group_of_emitter.push(index as u16);
        }
        if groups.names.len() > MAX_LIGHT_GROUPS {
            return Err(TooManyLightGroups {
                count: groups.names.len(),
            });
        }
        Ok(groups)
    }
}

/// The group of emitters that declare none, in a scene that declares some (Arnold's name for it).
pub const DEFAULT_GROUP: &str = "default";

/// `lg_<group>` with every character outside `[A-Za-z0-9_-]` replaced by `_` (EXR and Nuke split channel names
/// at `.`), made unique among `taken` with a `_2`, `_3`... suffix.
fn unique_layer_name(group: &str, taken: &[String]) -> String {
    let clean: String = group
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let base = format!("lg_{clean}");
    let mut name = base.clone();
    let mut k = 2;
    while taken.contains(&name) {
        name = format!("{base}_{k}");
        k += 1;
    }
    name
}

impl fmt::Display for Aov {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Aov::FirstHit(h) => write!(f, "{}", h.name()),
            Aov::LightPath(p) => write!(f, "{}", p.name()),
            Aov::Color(c) => write!(f, "{}", color_layer_name(*c)),
            Aov::LightGroup(name) => write!(f, "{name}"),
            Aov::AllLightGroups => write!(f, "lightgroups"),
            Aov::ShadowCatcher => write!(f, "shadow_catcher"),
            Aov::Cryptomatte(k) => write!(f, "{}", k.layer_name()),
        }
    }
}

/// Every layer name with its meaning, for `--list-aovs` and the documentation (light groups as `lg_<group>`,
/// Cryptomatte kinds as their layer names).
pub fn layer_catalog() -> Vec<(String, &'static str)> {
    use crate::material::LobeClass;
    let mut out: Vec<(String, &'static str)> = vec![
        ("R, G, B".into(), "beauty: linear Rec.709 radiance, premultiplied by alpha"),
        ("A".into(), "alpha: coverage, 1 − the camera ray's transmittance to the environment, averaged over the pixel's samples (holdouts cut it)"),
        ("albedo".into(), "albedo of the first surface hit, or the scattering albedo at the first collision in a medium (0 where nothing was hit)"),
        ("normal".into(), "world-space shading normal of the first surface hit, facing the camera (at a first collision in a medium: the direction to the camera)"),
        ("depth".into(), "distance from the camera to the first hit or collision in a medium (0 where nothing was hit)"),
        ("variance".into(), "variance of the beauty mean (its square root is the standard error)"),
    ];
    let light_path_meaning = |p: LightPath| {
        match p {
        LightPath::Emission => "emitters seen directly (surfaces and media)",
        LightPath::Environment => "the environment seen directly (left out of the beauty on a transparent film)",
        p if p.name().ends_with("_direct") => {
            "light after exactly one scattering event of this class; surface classes divided by their colour"
        }
        _ => "light after two or more scattering events, classed by the first; surface classes divided by their colour",
    }
    };
    for p in LightPath::ALL {
        out.push((p.name().into(), light_path_meaning(p)));
    }
    for c in LobeClass::ALL {
        out.push((
            color_layer_name(c),
            "the class's colour (directional albedo estimate) at the first surface hit",
        ));
    }
    out.push((
        "lg_<group>".into(),
        "the light of one light group's emitters; the groups sum to the beauty",
    ));
    out.push((
        "shadow_catcher".into(),
        "light on shadow-catcher surfaces with the scene's occlusion over without it (1: unshadowed); multiplies a plate",
    ));
    for k in CryptoKind::ALL {
        out.push((
            format!("{}00..", k.layer_name()),
            "Cryptomatte ID/coverage rank pairs (--cryptomatte-depth ranks)",
        ));
    }
    out
}

/// The name of the environment as a light group under `--light-groups per-light`: `lg_environment`.
pub fn environment_group_layer() -> String {
    format!("lg_{ENVIRONMENT_NAME}")
}

/// How many Cryptomatte ranks per pixel a render writes by default.
pub const DEFAULT_CRYPTOMATTE_DEPTH: usize = DEFAULT_DEPTH;

/// What the film accumulates and writes beyond the beauty, alpha and first-hit sums, for one render; parts
/// carry it in their header, so that a merge rebuilds the same image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayerPlan {
    /// The RGB slots of exact sums each pixel keeps, by name: light-path layers, colours (also those only
    /// needed to divide a light-path layer), light groups, and the shadow catcher's `shadow_catcher.lit` and
    /// `shadow_catcher.open`.
    pub slots: Vec<String>,
    /// The layers written after the beauty and alpha, in order: first-hit layers, light-path layers, colours,
    /// light groups, `shadow_catcher`, Cryptomatte kinds.
    pub written: Vec<String>,
    /// The Cryptomatte kinds kept, each with its manifest.
    pub cryptomatte: Vec<(CryptoKind, Manifest)>,
    /// Ranks per pixel written for each Cryptomatte kind (even: two per layer).
    pub cryptomatte_depth: usize,
}

impl Default for LayerPlan {
    /// The plan of a render with the default layers: the first-hit layers, and no slot.
    fn default() -> Self {
        Self {
            slots: Vec::new(),
            written: FirstHit::ALL.iter().map(|f| f.name().to_owned()).collect(),
            cryptomatte: Vec::new(),
            cryptomatte_depth: DEFAULT_DEPTH,
        }
    }
}

/// The slot of the shadow catcher's light with the scene's occlusion.
pub const CATCHER_LIT: &str = "shadow_catcher.lit";
/// The slot of the shadow catcher's light without occlusion.
pub const CATCHER_OPEN: &str = "shadow_catcher.open";

/// Why a render's layers cannot be planned.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    /// `--aovs` names a light group the render does not have.
    #[error("the layer list names {name}, but the render's light groups are: {available}")]
    UnknownLightGroup {
        /// The layer asked for.
        name: String,
        /// The render's group layers, comma-separated (or "none").
        available: String,
    },
    /// Too many light groups.
    #[error(transparent)]
    TooManyGroups(#[from] TooManyLightGroups),
    /// A Cryptomatte depth out of range.
    #[error("--cryptomatte-depth {depth} must be between 1 and {MAX_DEPTH}")]
    Depth {
        /// The depth asked for.
        depth: usize,
    },
}

/// Refuses a light group that `selection` names but `groups` lacks, listing the groups there are.
fn check_light_groups(selection: &AovSelection, groups: &LightGroups) -> Result<(), PlanError> {
    for aov in &selection.aovs {
        if let Aov::LightGroup(name) = aov {
            if !groups.names.contains(name) {
                return Err(PlanError::UnknownLightGroup {
                    name: name.clone(),
                    available: if groups.names.is_empty() {
                        "none".into()
                    } else {
                        groups.names.join(", ")
                    },
                });
            }
        }
    }
    Ok(())
}

/// The Cryptomatte manifest of `kind` for `scene`: each name item's object, material or asset name with its ID.
fn cryptomatte_manifest(scene: &Scene, kind: CryptoKind) -> Manifest {
    scene
        .names()
        .items
        .iter()
        .map(|item| {
            let name = match kind {
                CryptoKind::Object => &item.object,
                CryptoKind::Material => &item.material,
                CryptoKind::Asset => &item.asset,
            };
            (name.clone(), name_id(name))
        })
        .collect()
}

impl LayerPlan {
    /// The plan of a render of `scene` writing `selection`, with the light `groups` and `cryptomatte_depth`
    /// ranks per Cryptomatte kind (rounded up to even).
    pub fn new(
        scene: &Scene,
        selection: &AovSelection,
        groups: &LightGroups,
        cryptomatte_depth: usize,
    ) -> Result<Self, PlanError> {
        use crate::material::LobeClass;
        if !(1..=MAX_DEPTH).contains(&cryptomatte_depth) {
            return Err(PlanError::Depth {
                depth: cryptomatte_depth,
            });
        }
        let mut plan = LayerPlan {
            slots: Vec::new(),
            written: Vec::new(),
            cryptomatte: Vec::new(),
            cryptomatte_depth: cryptomatte_depth.div_ceil(2) * 2,
        };
        for f in FirstHit::ALL {
            if selection.contains(&Aov::FirstHit(f)) {
                plan.written.push(f.name().into());
            }
        }
        let paths: Vec<LightPath> = LightPath::ALL
            .into_iter()
            .filter(|p| selection.contains(&Aov::LightPath(*p)))
            .collect();
        for p in &paths {
            plan.slots.push(p.name().into());
            plan.written.push(p.name().into());
        }
        for c in LobeClass::ALL {
            let written = selection.contains(&Aov::Color(c));
            if written || paths.iter().any(|p| p.color() == Some(c)) {
                plan.slots.push(color_layer_name(c));
            }
            if written {
                plan.written.push(color_layer_name(c));
            }
        }
        let all_groups = selection.contains(&Aov::AllLightGroups);
        check_light_groups(selection, groups)?;
        for name in &groups.names {
            if all_groups || selection.contains(&Aov::LightGroup(name.clone())) {
                plan.slots.push(name.clone());
                plan.written.push(name.clone());
            }
        }
        if selection.contains(&Aov::ShadowCatcher) {
            plan.slots.push(CATCHER_LIT.into());
            plan.slots.push(CATCHER_OPEN.into());
            plan.written.push("shadow_catcher".into());
        }
        for kind in CryptoKind::ALL {
            if !selection.contains(&Aov::Cryptomatte(kind)) {
                continue;
            }
            plan.cryptomatte
                .push((kind, cryptomatte_manifest(scene, kind)));
            plan.written.push(kind.layer_name().into());
        }
        Ok(plan)
    }

    /// The index of slot `name`.
    pub fn slot(&self, name: &str) -> Option<usize> {
        self.slots.iter().position(|s| s == name)
    }

    /// True when a first-hit layer is written.
    pub fn writes(&self, name: &str) -> bool {
        self.written.iter().any(|w| w == name)
    }

    /// Number of exact value sums each pixel keeps beyond the core: three per slot.
    pub fn values_per_pixel(&self) -> usize {
        3 * self.slots.len()
    }

    /// True when paths must record where their light came from: some slot or Cryptomatte kind is kept.
    pub fn records(&self) -> bool {
        !self.slots.is_empty() || !self.cryptomatte.is_empty()
    }

    /// Bytes of film per pixel beyond the core sums (Cryptomatte's maps counted at one ID per kind).
    pub fn film_bytes_per_pixel(&self) -> usize {
        16 * self.values_per_pixel() + 40 * self.cryptomatte.len()
    }

    /// The plan as header text: `slots=...;written=...;depth=N` (names joined by `,`), with the
    /// Cryptomatte manifests carried apart.
    pub fn describe(&self) -> String {
        format!(
            "slots={};written={};depth={}",
            self.slots.join(","),
            self.written.join(","),
            self.cryptomatte_depth
        )
    }

    /// The inverse of [`describe`](Self::describe), given the manifests of the Cryptomatte kinds.
    pub fn from_description(text: &str, cryptomatte: Vec<(CryptoKind, Manifest)>) -> Option<Self> {
        let mut parts = text.split(';');
        let list = |field: Option<&str>, key: &str| -> Option<Vec<String>> {
            let value = field?.strip_prefix(key)?;
            Some(
                value
                    .split(',')
                    .filter(|s| !s.is_empty())
                    .map(str::to_owned)
                    .collect(),
            )
        };
        let slots = list(parts.next(), "slots=")?;
        let written = list(parts.next(), "written=")?;
        let depth: usize = parts.next()?.strip_prefix("depth=")?.parse().ok()?;
        // Plans are made with an even depth of ranks (two per layer) up to MAX_DEPTH; a description with any
        // other (a damaged or forged part) would index past its rank layers.
        if depth == 0 || !depth.is_multiple_of(2) || depth > MAX_DEPTH {
            return None;
        }
        Some(Self {
            slots,
            written,
            cryptomatte,
            cryptomatte_depth: depth,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::LobeClass;

    #[test]
    fn lists_and_sets_parse_without_repeats() {
        let s = AovSelection::parse("depth, lightpaths,diffuse_color,depth,lg_key,CryptoAsset")
            .unwrap();
        assert_eq!(s.aovs.len(), 1 + 10 + 1 + 1 + 1);
        assert_eq!(s.aovs[0], Aov::FirstHit(FirstHit::Depth));
        assert!(s.contains(&Aov::Color(LobeClass::Diffuse)));
        assert!(s.contains(&Aov::LightGroup("lg_key".into())));
        assert!(s.contains(&Aov::Cryptomatte(CryptoKind::Asset)));
        assert_eq!(AovSelection::parse("none").unwrap(), AovSelection::none());
        let all = AovSelection::parse("all").unwrap();
        assert_eq!(all.aovs.len(), 4 + 10 + 3 + 1 + 3 + 1);
        for bad in ["albedo.R", "lg_", "diffuse", "beauty"] {
            let err = AovSelection::parse(bad).unwrap_err();
            assert!(err.to_string().contains(bad), "{err}");
        }
        // Every name the catalogue shows (but the placeholders) parses.
        for (name, _) in layer_catalog() {
            if !name.contains(['<', ',', '.']) && name != "A" {
                AovSelection::parse(&name).unwrap();
            }
        }
    }

    #[test]
    fn layer_names_are_clean_and_unique() {
        let mut taken = Vec::new();
        for g in ["key light", "key.light", "fill", "key_light"] {
            let n = unique_layer_name(g, &taken);
            taken.push(n);
        }
        assert_eq!(
            taken,
            [
                "lg_key_light",
                "lg_key_light_2",
                "lg_fill",
                "lg_key_light_3"
            ]
        );
    }
}
