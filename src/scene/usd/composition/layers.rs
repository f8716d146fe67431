//! The layers a stage reaches, each read once through the loader's checks and summarised for the walk: its
//! sublayers, default prim, and each prim's children and arcs.

use super::{parent, precache};
use openusd::{ar, sdf};
use std::collections::{HashMap, HashSet};
use std::io::Read;

/// How an arc composes its target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ArcKind {
    Inherits,
    Specializes,
    References,
    Payload,
}

impl ArcKind {
    /// The arc's name as a layer spells it.
    pub(super) fn name(self) -> &'static str {
        match self {
            ArcKind::Inherits => "inherits",
            ArcKind::Specializes => "specializes",
            ArcKind::References => "references",
            ArcKind::Payload => "payload",
        }
    }

    /// Inherits and specializes: the class-based arcs, which `openusd` pre-caches for the prim's children too.
    pub(super) fn is_class(self) -> bool {
        matches!(self, ArcKind::Inherits | ArcKind::Specializes)
    }
}

/// One composition arc authored on a prim.
#[derive(Clone, Debug)]
pub(super) struct Arc {
    pub(super) kind: ArcKind,
    /// The layer whose layer stack holds the target (an index into [`Layers::layers`]); `None` for an internal
    /// arc, whose target is in the layer stack the prim is composed in.
    pub(super) layer: Option<usize>,
    /// The target prim's path; empty for the target layer's default prim.
    pub(super) path: String,
    /// The asset path as authored (empty for an internal arc), for messages.
    pub(super) asset: String,
    /// Whether the arc is authored inside a variant (of its prim or of an ancestor).
    pub(super) in_variant: bool,
}

impl Arc {
    /// The arc as a layer spells it: `inherits </A>`, `references @a.usda@</B>`.
    pub(super) fn describe(&self) -> String {
        let asset = if self.asset.is_empty() {
            String::new()
        } else {
            format!("@{}@", self.asset)
        };
        let path = if self.path.is_empty() {
            String::new()
        } else {
            format!("<{}>", self.path)
        };
        format!("{} {asset}{path}", self.kind.name())
    }
}

/// What one prim spec contributes: its children (paths), its arcs, and whether it authors variants.
#[derive(Default)]
pub(super) struct Prim {
    pub(super) children: Vec<String>,
    pub(super) arcs: Vec<Arc>,
    /// Whether a layer authors a variant of the prim (of any of its variant sets).
    pub(super) variants: bool,
}

/// What one layer contributes to composition.
#[derive(Default)]
pub(super) struct Layer {
    /// Its sublayers in order (indices into [`Layers::layers`]).
    pub(super) sublayers: Vec<usize>,
    /// `/` and its `defaultPrim`, if authored.
    pub(super) default_prim: Option<String>,
    /// The prims it authors, by path (variant selections removed), `/` holding the root prims.
    pub(super) prims: HashMap<String, Prim>,
    /// What the layer authors twice, if anything: a prim in one scope, or one item in one arc list. Pixar's USD
    /// refuses such a layer ("Duplicate prim", "Duplicate items exist for field"), while `openusd` 0.6 keeps
    /// both, which let several of the fuzz target's stages compose for minutes.
    pub(super) duplicate: Option<String>,
}

/// The layers a stage reaches through sublayers, references and payloads, each read once.
pub(super) struct Layers<'a> {
    pub(super) resolver: &'a dyn ar::Resolver,
    /// Layer index by identifier.
    pub(super) ids: HashMap<String, usize>,
    /// Each layer's summary; `None` for a layer that cannot be read.
    pub(super) layers: Vec<Option<Layer>>,
    /// Each layer's identifier, for messages.
    pub(super) names: Vec<String>,
    /// Layers found but not read yet: (index, identifier).
    pub(super) pending: Vec<(usize, String)>,
}

impl<'a> Layers<'a> {
    /// Reads the layer at `root` and every layer it reaches; also returns the root's index (`None` when the
    /// root names no layer).
    pub(super) fn load(resolver: &'a dyn ar::Resolver, root: &str) -> (Self, Option<usize>) {
        let mut layers = Self {
            resolver,
            ids: HashMap::new(),
            layers: Vec::new(),
            names: Vec::new(),
            pending: Vec::new(),
        };
        let root = layers.index(root, None);
        while let Some((index, identifier)) = layers.pending.pop() {
            layers.layers[index] = layers.read(&identifier);
        }
        (layers, root)
    }

    /// The deepest prim path authored or targeted by an arc in any layer read, in path elements.
    pub(super) fn deepest_path(&self) -> usize {
        let layers = self.layers.iter().flatten();
        let prims = layers.flat_map(|l| &l.prims);
        let paths = prims.flat_map(|(path, prim)| {
            std::iter::once(path).chain(prim.arcs.iter().map(|a| &a.path))
        });
        paths.map(|p| precache::depth(p)).max().unwrap_or(0)
    }

    /// The index of the layer `asset` names (relative to `anchor`), queued to be read the first time it is
    /// named; `None` for an expression (its variables are `openusd`'s to evaluate) or an empty identifier.
    pub(super) fn index(
        &mut self,
        asset: &str,
        anchor: Option<&ar::ResolvedPath>,
    ) -> Option<usize> {
        if asset.is_empty() || sdf::expr::is_expression(asset) {
            return None;
        }
        let identifier = self.resolver.create_identifier(asset, anchor);
        if identifier.is_empty() {
            return None;
        }
        if let Some(&index) = self.ids.get(&identifier) {
            return Some(index);
        }
        let index = self.layers.len();
        self.layers.push(None);
        self.names.push(identifier.clone());
        self.ids.insert(identifier.clone(), index);
        self.pending.push((index, identifier));
        Some(index)
    }

    /// Reads and summarises the layer `identifier` names, as `openusd` would open it: a package opens its first
    /// layer, and a `.usd` file is binary or text by its first bytes.
    pub(super) fn read(&mut self, identifier: &str) -> Option<Layer> {
        let resolved = self.resolver.resolve(identifier)?;
        let real = match sdf::LayerRegistry::find_by_extension(&extension(&resolved)) {
            Some(format) => format.resolve_layer(self.resolver, &resolved)?,
            None => resolved,
        };
        let data = self.format(&real)?.read(self.resolver, &real).ok()?;
        Some(self.summarise(data.as_ref(), &real))
    }

    /// The file format that reads `resolved`.
    pub(super) fn format(
        &self,
        resolved: &ar::ResolvedPath,
    ) -> Option<&'static dyn sdf::FileFormat> {
        let ext = extension(resolved);
        if ext != "usd" {
            return sdf::LayerRegistry::find_by_extension(&ext);
        }
        let mut prefix = Vec::new();
        self.resolver
            .open_asset(resolved)
            .ok()?
            .take(8)
            .read_to_end(&mut prefix)
            .ok()?;
        let binary = sdf::LayerRegistry::find_by_id("usdc").filter(|f| f.matches_content(&prefix));
        binary.or_else(|| sdf::LayerRegistry::find_by_id("usda"))
    }

    /// The sublayers, default prim, and every prim's children and arcs of a layer read from `anchor`.
    pub(super) fn summarise(
        &mut self,
        data: &dyn sdf::AbstractData,
        anchor: &ar::ResolvedPath,
    ) -> Layer {
        let root = sdf::Path::abs_root();
        let field = |path: &sdf::Path, name: &str| data.try_field(path, name).ok().flatten();
        let sublayers = field(&root, "subLayers")
            .and_then(|v| v.into_owned().cast::<Vec<String>>().ok())
            .unwrap_or_default();
        let mut layer = Layer {
            sublayers: sublayers
                .iter()
                .filter_map(|s| self.index(s, Some(anchor)))
                .collect(),
            default_prim: field(&root, "defaultPrim")
                .and_then(|v| v.into_owned().cast::<String>().ok())
                .map(|name| format!("/{name}")),
            prims: HashMap::new(),
            duplicate: None,
        };
        for spec in data.spec_paths() {
            if layer.duplicate.is_none() {
                layer.duplicate = duplicate_child(data, &spec);
            }
            let kind = data.spec_type(&spec);
            if !matches!(kind, Some(sdf::SpecType::Prim | sdf::SpecType::Variant)) {
                continue;
            }
            let stripped = spec.strip_all_variant_selections();
            let in_variant = stripped != spec;
            let path = stripped.as_str().to_owned();
            if kind == Some(sdf::SpecType::Variant) {
                layer.prims.entry(path.clone()).or_default().variants = true;
            }
            if kind == Some(sdf::SpecType::Prim) {
                let parent = parent(&path).to_owned();
                layer
                    .prims
                    .entry(parent)
                    .or_default()
                    .children
                    .push(path.clone());
            }
            let arcs = self.arcs(data, &spec, anchor, in_variant);
            let twice = arcs.iter().enumerate().find(|(i, a)| {
                arcs[..*i].iter().any(|b| {
                    (b.kind, b.layer, &b.path, &b.asset) == (a.kind, a.layer, &a.path, &a.asset)
                })
            });
            if let (None, Some((_, arc))) = (&layer.duplicate, twice) {
                layer.duplicate = Some(format!("lists <{path}> {} twice", arc.describe()));
            }
            layer.prims.entry(path).or_default().arcs.extend(arcs);
        }
        layer
    }

    /// The arcs authored on the prim or variant spec `spec` (`in_variant` when its path selects a variant):
    /// every item its list ops add.
    pub(super) fn arcs(
        &mut self,
        data: &dyn sdf::AbstractData,
        spec: &sdf::Path,
        anchor: &ar::ResolvedPath,
        in_variant: bool,
    ) -> Vec<Arc> {
        let target = |path: &sdf::Path| {
            if path.is_empty() {
                String::new()
            } else {
                spec.make_absolute(path)
                    .strip_all_variant_selections()
                    .as_str()
                    .to_owned()
            }
        };
        let mut arcs = Vec::new();
        for (name, kind) in [
            ("inheritPaths", ArcKind::Inherits),
            ("specializes", ArcKind::Specializes),
            ("references", ArcKind::References),
            ("payload", ArcKind::Payload),
        ] {
            let Ok(Some(value)) = data.try_field(spec, name) else {
                continue;
            };
            let items: Vec<(String, String)> = match value.into_owned() {
                sdf::Value::PathListOp(op) => {
                    op.iter().map(|p| (String::new(), target(p))).collect()
                }
                sdf::Value::ReferenceListOp(op) => op
                    .iter()
                    .map(|r| (r.asset_path.clone(), target(&r.prim_path)))
                    .collect(),
                sdf::Value::PayloadListOp(op) => op
                    .iter()
                    .map(|p| (p.asset_path.clone(), target(&p.prim_path)))
                    .collect(),
                sdf::Value::Payload(p) => vec![(p.asset_path.clone(), target(&p.prim_path))],
                _ => Vec::new(),
            };
            for (asset, path) in items {
                let layer = if asset.is_empty() {
                    None
                } else {
                    match self.index(&asset, Some(anchor)) {
                        Some(index) => Some(index),
                        None => continue,
                    }
                };
                arcs.push(Arc {
                    kind,
                    layer,
                    path,
                    asset,
                    in_variant,
                });
            }
        }
        arcs
    }
}

/// The path of a child that `spec`'s `primChildren` names twice, if any.
fn duplicate_child(data: &dyn sdf::AbstractData, spec: &sdf::Path) -> Option<String> {
    let children = data.try_field(spec, "primChildren").ok().flatten()?;
    let names = children.into_owned().cast::<Vec<String>>().ok()?;
    let mut seen = HashSet::new();
    let twice = names.into_iter().find(|name| !seen.insert(name.clone()))?;
    let parent = spec.strip_all_variant_selections();
    Some(match parent.as_str() {
        "/" => format!("defines prim </{twice}> twice in one scope"),
        p => format!("defines prim <{p}/{twice}> twice in one scope"),
    })
}

/// The extension of a resolved layer, lower case; for a layer inside a package, the packaged layer's.
fn extension(resolved: &ar::ResolvedPath) -> String {
    let text = resolved.to_string_lossy();
    let inner = ar::split_package_relative_path_inner(&text).map(|(_, inner)| inner);
    std::path::Path::new(inner.as_deref().unwrap_or(&text))
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default()
}
