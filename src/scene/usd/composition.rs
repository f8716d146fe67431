//! A check of a stage's composition before `openusd` 0.6 composes it: arc cycles, the prims the arcs compose, and
//! the entries of every layer stack.
//!
//! `openusd` pre-caches the inherit and specialize targets of a prim and of its parent recursively, without
//! remembering the targets it has seen: a prim that inherits or specializes itself, or prims that inherit one
//! another, make that recursion endless as soon as a child of theirs is composed, and the stack overflow aborts
//! the process (no stack is deep enough, and an overflow cannot be caught on any thread).
//!
//! So before the stage is opened, every layer the root layer reaches through sublayers, references and payloads
//! is read once (through [`CheckingResolver`], with every check and cap of the loader) and summarised: its
//! sublayers, and for each prim its children and its arcs (those authored inside variants count whichever
//! variant is selected). A walk over the sites composition visits (a layer stack and a prim path), from the root
//! layer stack's pseudo-root, follows each site to its children, to the targets of its arcs, and to the inherit
//! and specialize targets of its parent (what `openusd`'s pre-caching follows). Refused as a composition cycle,
//! with one line naming the prim and the arc: an arc back onto, into or above a prim of the arc chain it extends
//! (Pcp's cycle rule, which `openusd` applies to references but misses for inherits and specializes, overflowing
//! its stack the same way), and a site met again while it is being walked, through arcs and children or through
//! inherits and specializes alone (see `cycle_back`).
//!
//! The same walk counts the prims composition would bring in, each site once per arc or parent that brings it
//! (a site's count is itself, its children's counts and its arcs' targets' counts): a few lines of internal
//! references that fan out level after level compose millions of prims, which `openusd` would compose one by one
//! (and Nimbus read) for minutes. A count over [`Limits::usd_prims`] is refused before anything is composed,
//! naming the prim and the flag that raises the limit. The count is an upper bound for what a site's own specs and
//! arcs bring (children met through several arcs are counted each time); what an ancestor's arcs map onto a target
//! is not in it, and is counted as the stage is read instead (see `Loader::visit`).
//!
//! Every layer stack the walk enters (the root's, and each arc target's) is counted first as `openusd` builds it:
//! the root layer, then each sublayer in turn with its own sublayers, a layer named twice counting twice. A
//! layer already on the path, a sublayer cycle, is refused, as Pixar's USD reports it. Twenty-five layers that
//! each name the next twice make 2²⁴ entries, which `openusd` builds one by one and every prim then reads
//! through; a stack over
//! [`Limits::usd_layer_stack`] entries is refused before the stage is opened, naming its root layer and the flag
//! that raises the limit.
//!
//! A site also composes what the arcs of its ancestors map onto it (Pcp's ancestral arcs): a prim `/A/B` under
//! `/A`, which references `/X`, composes `/X/B` in the reference's layer stack. The walk steps there too, so
//! that arcs back into the run through an ancestor are cycles (as Pixar's USD reports them), and arcs that map
//! a prim ever deeper into its own namespace are stopped by the same rule; an ancestor whose own arc targets its
//! namespace is refused where it is met. A class arc met below a reference is implied onto the referencing
//! layer stack (Pcp's implied classes): landing back in the run that way is refused too, and so is a class arc
//! of a prim below the referenced one implied onto the prim it composes there, its ancestors or descendants.
//! Both rules (an arc back into the run, an implied class) are also applied at the level of the prims that
//! author the arcs, each mapped back through the arc before it: Pcp composes the ancestors first and finds the
//! cycle there, while the sites themselves may grow ever deeper without ever nesting.
//! `openusd` 0.6 followed each of these for minutes (the fuzz target's slow inputs, replayed under `tests/`).
//! The nodes of each site's prim index (each arc's target with its own arcs, once per path) are counted against
//! the prim limit, and the sites and steps of the walk are bounded by four times it. The walk also follows the
//! nodes Pcp adds beyond a site's own arcs: each class arc met below a reference is walked again where Pcp
//! implies it (on the referencing prim, its target mapped through the reference, with its own arcs, and up
//! through every reference above), and each specializes arc below the root of a prim index again where Pcp
//! copies it (that root), so that their work counts against the same bound. A site that an ancestor's arc
//! maps deeper than twice the deepest prim path the layers author or target (plus two) is refused: only arcs
//! that map prims ever deeper reach it, which `openusd` 0.6 and Pixar's USD both follow for minutes.
//!
//! The walk is iterative and visits each site once. It works on layer stacks, while `openusd`'s pre-caching takes
//! every inherit and specialize target as a path of the stage and maps it through arcs to any layer stack: a last
//! check models that pre-caching on prim paths ([`precache`]) and refuses its cycles, which the fuzz target
//! `usd_compose` found past the walk. Cycles neither can see in the layers alone (through paths that an
//! ancestor's arc maps) are left to `openusd`, which reports them as composition errors.

mod precache;

use super::crate_check::CheckingResolver;
use crate::limits::Limits;
use openusd::{ar, sdf};
use std::collections::{HashMap, HashSet};
use std::io::Read;
use std::rc::Rc;

/// Checks the composition of the stage whose root layer is `root` (as `openusd` is given it) against `limits`,
/// reading every layer through `resolver`. Layers that cannot be read are passed over: `openusd` reports them
/// when it opens the stage.
pub(super) fn check(
    root: &str,
    resolver: &CheckingResolver,
    limits: &Limits,
) -> Result<(), CompositionError> {
    let (layers, root) = Layers::load(resolver, root);
    for (layer, name) in layers.layers.iter().zip(&layers.names) {
        if let Some(twice) = layer.as_ref().and_then(|l| l.duplicate.as_ref()) {
            return Err(CompositionError::Duplicate {
                layer: name.clone(),
                twice: twice.clone(),
            });
        }
    }
    match root {
        Some(root) => {
            Walk::new(&layers, limits).run(root)?;
            precache::Precache::new(&layers).check(limits.usd_prims)
        }
        None => Ok(()),
    }
}

/// Why a stage's composition is refused before `openusd` composes it ([`check`]): what Pixar's USD refuses, what
/// `openusd` 0.6 would follow without end or for exponential time, and what passes the limits.
#[derive(Debug, thiserror::Error)]
pub(super) enum CompositionError {
    /// A layer lists a prim, or an item of an arc list, twice.
    #[error(
        "{layer} {twice}: Pixar's USD refuses such a layer (\"Duplicate prim\", \"Duplicate items exist for \
         field\")"
    )]
    Duplicate { layer: String, twice: String },
    /// Arcs that lead back into the run they extend: `named` (the first authored arc, or where the cycle ends),
    /// the `chain` of steps, and where it `lands` when not on its start.
    #[error("{named} is a composition cycle ({chain}{lands})")]
    Cycle {
        named: String,
        chain: String,
        lands: String,
    },
    /// Following the arcs takes more than `max_steps` steps.
    #[error(
        "following the stage's arcs takes more than {max_steps} steps (four per prim of the limit of {max_prims} \
         prims; raise it with --max-prims)"
    )]
    Steps { max_steps: u64, max_prims: u64 },
    /// The stage composes more prims than the limit, counted along its paths.
    #[error(
        "the stage composes more than {0} prims through its arcs and children (each counted once per arc that \
         brings it in), over the limit of {0} prims (raise it with --max-prims)"
    )]
    StagePrims(u64),
    /// A class arc that Pcp's implied classes carry back into the run (boxed: the largest variant).
    #[error(transparent)]
    ImpliedClass(Box<ImpliedClassCycle>),
    /// A prim index of more nodes than the prim limit.
    #[error(
        "composing {site} reaches {nodes} arc targets (each arc's target with its own and its ancestors' arcs, \
         once per path that leads to it), over the limit of {max_prims} (raise it with --max-prims)"
    )]
    IndexNodes {
        site: String,
        nodes: u64,
        max_prims: u64,
    },
    /// A site (`what`: the stage, or a prim's path) that composes more prims than the limit.
    #[error(
        "{what} composes {prims} prims through its arcs and children (each counted once per arc that brings it \
         in), over the limit of {max_prims} prims (raise it with --max-prims)"
    )]
    SitePrims {
        what: String,
        prims: u64,
        max_prims: u64,
    },
    /// Arcs that map prims onto more sites than four per prim of the limit.
    #[error(
        "the stage's arcs map its prims onto more than {max_sites} sites (a prim in each layer stack an arc \
         brings in, four per prim of the limit of {max_prims} prims; raise it with --max-prims)"
    )]
    Sites { max_sites: u64, max_prims: u64 },
    /// An ancestor's arc that targets the ancestor's own namespace.
    #[error(
        "{ancestor}: {arc} is a composition cycle (it targets {ancestor}'s own namespace; met composing {path})"
    )]
    OwnNamespace {
        ancestor: String,
        arc: String,
        path: String,
    },
    /// An ancestor's arc that maps a prim deeper than the walk's bound on mapped paths.
    #[error(
        "{path} is under {ancestor}, whose {arc} maps it onto {mapped}, {depth} prims deep: deeper than twice the \
         deepest prim path the stage's layers author or target, plus two ({max_depth}); arcs that map prims ever \
         deeper make openusd 0.6 compose for exponential time, so it is refused"
    )]
    MappedTooDeep {
        path: String,
        ancestor: String,
        arc: String,
        mapped: String,
        depth: usize,
        max_depth: usize,
    },
    /// A class arc whose target an ancestor's arc maps onto the prim or a child of it.
    #[error(
        "{path}: {class_arc} lies inside the target of {ancestor}'s {arc}, which maps it onto {mapped}: openusd \
         0.6 pre-caches that without end (a stack overflow), so it is refused"
    )]
    MappedOntoItself {
        path: String,
        class_arc: String,
        ancestor: String,
        arc: String,
        mapped: String,
    },
    /// A layer stack (`root`'s) in which `layer` names a sublayer (`names`) already on the path to it.
    #[error(
        "{root}: its subLayers lead back to a layer on their path: {layer} names {names}, a layer on the path of \
         sublayers that leads to it (a sublayer cycle)"
    )]
    SublayerCycle {
        root: String,
        layer: String,
        names: String,
    },
    /// A layer stack of more entries than the limit.
    #[error(
        "the layer stack of {layer} expands to {entries} layers (a sublayer named twice counts twice), over the \
         limit of {max} (raise it with --max-sublayers)"
    )]
    LayerStack { layer: String, entries: u64, max: u64 },
    /// `openusd`'s pre-caching of inherit and specialize targets follows more than the limit from `from`.
    #[error(
        "openusd 0.6 pre-caches more than {max_prims} inherit and specialize targets from {from} (each once per \
         path that leads to it), over the limit of {max_prims} prims (raise it with --max-prims)"
    )]
    Precache { max_prims: u64, from: String },
    /// A cycle of pre-cached targets: the arc of the prim `at` of `kind` to `target`, and the `chain` of paths.
    #[error(
        "{at}: {kind} <{target}> is a composition cycle for openusd 0.6, whose pre-caching of inherit and \
         specialize targets would follow {chain} without end (a stack overflow)"
    )]
    PrecacheCycle {
        at: String,
        kind: &'static str,
        target: String,
        chain: String,
    },
}

/// A class arc that Pcp's implied classes carry back into the run ([`CompositionError::ImpliedClass`]): the
/// arc, the reference it is met through, the step below which it is met, and where it is implied.
#[derive(Debug, thiserror::Error)]
#[error(
    "{class_arc} is a composition cycle for openusd 0.6, which follows it for exponential time ({through}, below \
     which {below}: a class arc implied onto {referencing}'s layer stack as {implied}, nested with {nested_with})"
)]
pub(super) struct ImpliedClassCycle {
    class_arc: String,
    through: String,
    below: String,
    referencing: String,
    implied: String,
    nested_with: String,
}

/// How an arc composes its target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ArcKind {
    Inherits,
    Specializes,
    References,
    Payload,
}

impl ArcKind {
    /// The arc's name as a layer spells it.
    fn name(self) -> &'static str {
        match self {
            ArcKind::Inherits => "inherits",
            ArcKind::Specializes => "specializes",
            ArcKind::References => "references",
            ArcKind::Payload => "payload",
        }
    }

    /// Inherits and specializes: the class-based arcs, which `openusd` pre-caches for the prim's children too.
    fn is_class(self) -> bool {
        matches!(self, ArcKind::Inherits | ArcKind::Specializes)
    }
}

/// One composition arc authored on a prim.
#[derive(Clone, Debug)]
struct Arc {
    kind: ArcKind,
    /// The layer whose layer stack holds the target (an index into [`Layers::layers`]); `None` for an internal
    /// arc, whose target is in the layer stack the prim is composed in.
    layer: Option<usize>,
    /// The target prim's path; empty for the target layer's default prim.
    path: String,
    /// The asset path as authored (empty for an internal arc), for messages.
    asset: String,
}

impl Arc {
    /// The arc as a layer spells it: `inherits </A>`, `references @a.usda@</B>`.
    fn describe(&self) -> String {
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

/// What one prim spec contributes: its children (paths) and its arcs.
#[derive(Default)]
struct Prim {
    children: Vec<String>,
    arcs: Vec<Arc>,
}

/// What one layer contributes to composition.
#[derive(Default)]
struct Layer {
    /// Its sublayers in order (indices into [`Layers::layers`]).
    sublayers: Vec<usize>,
    /// `/` and its `defaultPrim`, if authored.
    default_prim: Option<String>,
    /// The prims it authors, by path (variant selections removed), `/` holding the root prims.
    prims: HashMap<String, Prim>,
    /// What the layer authors twice, if anything: a prim in one scope, or one item in one arc list. Pixar's USD
    /// refuses such a layer ("Duplicate prim", "Duplicate items exist for field"), while `openusd` 0.6 keeps
    /// both, which let several of the fuzz target's stages compose for minutes.
    duplicate: Option<String>,
}

/// The layers a stage reaches through sublayers, references and payloads, each read once.
struct Layers<'a> {
    resolver: &'a dyn ar::Resolver,
    /// Layer index by identifier.
    ids: HashMap<String, usize>,
    /// Each layer's summary; `None` for a layer that cannot be read.
    layers: Vec<Option<Layer>>,
    /// Each layer's identifier, for messages.
    names: Vec<String>,
    /// Layers found but not read yet: (index, identifier).
    pending: Vec<(usize, String)>,
}

impl<'a> Layers<'a> {
    /// Reads the layer at `root` and every layer it reaches; also returns the root's index (`None` when the
    /// root names no layer).
    fn load(resolver: &'a dyn ar::Resolver, root: &str) -> (Self, Option<usize>) {
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
    fn deepest_path(&self) -> usize {
        let layers = self.layers.iter().flatten();
        let prims = layers.flat_map(|l| &l.prims);
        let paths = prims.flat_map(|(path, prim)| {
            std::iter::once(path).chain(prim.arcs.iter().map(|a| &a.path))
        });
        paths.map(|p| precache::depth(p)).max().unwrap_or(0)
    }

    /// The index of the layer `asset` names (relative to `anchor`), queued to be read the first time it is
    /// named; `None` for an expression (its variables are `openusd`'s to evaluate) or an empty identifier.
    fn index(&mut self, asset: &str, anchor: Option<&ar::ResolvedPath>) -> Option<usize> {
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
    fn read(&mut self, identifier: &str) -> Option<Layer> {
        let resolved = self.resolver.resolve(identifier)?;
        let real = match sdf::LayerRegistry::find_by_extension(&extension(&resolved)) {
            Some(format) => format.resolve_layer(self.resolver, &resolved)?,
            None => resolved,
        };
        let data = self.format(&real)?.read(self.resolver, &real).ok()?;
        Some(self.summarise(data.as_ref(), &real))
    }

    /// The file format that reads `resolved`.
    fn format(&self, resolved: &ar::ResolvedPath) -> Option<&'static dyn sdf::FileFormat> {
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
    fn summarise(&mut self, data: &dyn sdf::AbstractData, anchor: &ar::ResolvedPath) -> Layer {
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
            let path = spec.strip_all_variant_selections().as_str().to_owned();
            if kind == Some(sdf::SpecType::Prim) {
                let parent = parent(&path).to_owned();
                layer
                    .prims
                    .entry(parent)
                    .or_default()
                    .children
                    .push(path.clone());
            }
            let arcs = self.arcs(data, &spec, anchor);
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

    /// The arcs authored on the prim or variant spec `spec`: every item its list ops add.
    fn arcs(
        &mut self,
        data: &dyn sdf::AbstractData,
        spec: &sdf::Path,
        anchor: &ar::ResolvedPath,
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

/// The parent of a prim path (`/` for a root prim).
fn parent(path: &str) -> &str {
    match path.rfind('/') {
        Some(0) | None => "/",
        Some(at) => &path[..at],
    }
}

/// A layer stack: a root layer and the prims it and its sublayers author, merged.
struct Stack {
    /// The prims by path: the children of every layer, and every layer's arcs.
    prims: HashMap<String, Prim>,
}

/// A site composition visits: a layer stack (an index into [`Walk::stacks`]) and a prim path.
type Site = (usize, String);

/// How the walk goes from one site to the next.
#[derive(Clone, Debug)]
enum Step {
    /// To a child prim.
    Child,
    /// To the target of an arc authored on the site.
    Arc(Arc),
    /// To the target of a class-based arc authored on the site's parent.
    ParentArc(Arc),
    /// To the site an arc authored on an ancestor (the `String`) maps this one onto: the target with the
    /// site's path below the ancestor appended. Composition brings that site into this one's prim index (an
    /// ancestral arc), so it closes cycles like an arc; its prims are counted with the ancestor's arc.
    AncestorArc(Arc, String),
    /// To the target of a class-based arc met below a reference or payload of the site (through arcs and
    /// children), implied onto the site's layer stack with its target mapped through that reference (Pcp's
    /// implied classes; the arc holds the mapped target). Pcp adds such a node to the prim index, with the
    /// nodes of its own arcs, at every reference above the class arc: the work the walk bounds by following it.
    Implied(Arc),
}

impl Step {
    /// Whether the step's target is composed into the site (a child or an arc's target), and so counts in the
    /// site's prims; a parent's arc is already counted with the parent.
    fn counts(&self) -> bool {
        matches!(self, Step::Child | Step::Arc(_))
    }

    /// Whether the step composes its target into the site (a child, an arc's target, or an ancestor's arc's
    /// target mapped onto the site): around a loop of these, the site composes itself.
    fn composes(&self) -> bool {
        !matches!(self, Step::ParentArc(_))
    }

    /// Whether the step follows a class-based arc into the site's prim index (its own, an ancestor's, or an
    /// implied one), whose target Pcp's implied classes carry up through the references above it.
    fn implies_class(&self) -> bool {
        match self {
            Step::Arc(arc) | Step::AncestorArc(arc, _) => arc.kind.is_class(),
            Step::Implied(_) => true,
            Step::ParentArc(_) | Step::Child => false,
        }
    }

    /// Whether the step follows an arc to the site it composes (the site's own or an ancestor's): a run of
    /// these that lands nested with a site it started from is Pcp's arc cycle.
    /// An implied class starts a run of its own: it belongs to the prim the referencing site composes below
    /// the reference (the site itself, or a descendant), not to the site's run.
    fn follows_arc(&self) -> bool {
        matches!(self, Step::Arc(_) | Step::AncestorArc(..))
    }

    /// The arc the step follows, if it follows one (its own, its parent's or an ancestor's).
    fn arc(&self) -> Option<&Arc> {
        match self {
            Step::Arc(arc) | Step::ParentArc(arc) | Step::AncestorArc(arc, _) | Step::Implied(arc) => {
                Some(arc)
            }
            Step::Child => None,
        }
    }

    /// The step from the site at `at` to the site at `next`, in words: `/A holds /A/B`, `/A references </X>`,
    /// `/A/B is under /A, which references </X>`.
    fn describe(&self, at: &str, next: &str) -> String {
        match self {
            Step::Child => format!("{at} holds {next}"),
            Step::Arc(arc) => format!("{at} {}", arc.describe()),
            Step::ParentArc(arc) => {
                format!("{at} is under {}, which {}", parent(at), arc.describe())
            }
            Step::AncestorArc(arc, ancestor) => {
                format!("{at} is under {ancestor}, which {}", arc.describe())
            }
            Step::Implied(arc) => format!("{at} {} (an implied class)", arc.describe()),
        }
    }

    /// The arc the step follows from the site at `at`, named by the prim that authors it (`/A: references
    /// </X>`); `None` for a child.
    fn authored(&self, at: &str) -> Option<String> {
        let by = match self {
            Step::Child => return None,
            Step::Implied(arc) => return Some(format!("{at}: {} (an implied class)", arc.describe())),
            Step::Arc(_) => at,
            Step::ParentArc(_) => parent(at),
            Step::AncestorArc(_, ancestor) => ancestor,
        };
        self.arc().map(|arc| format!("{by}: {}", arc.describe()))
    }
}

/// The steps out of a site: to the target site (an index into [`Walk::sites`]), and how.
type Steps = Rc<[(usize, Step)]>;

/// One site on the walk's path, with the steps out of it and how many have been taken.
struct Frame {
    site: usize,
    steps: Steps,
    taken: usize,
    /// The prims counted so far (the counting pass).
    prims: u64,
    /// The nodes of the site's prim index counted so far (the counting pass): itself, and each arc's target
    /// (its own or an ancestor's) with that target's nodes.
    nodes: u64,
    /// The implied classes carried onto the site while walking below it (the unfolding pass), taken after its
    /// own steps, and their targets, each implied once (Pcp adds one node per implied site and parent).
    implied: Vec<(usize, Step)>,
    implied_sites: HashSet<usize>,
}

impl Frame {
    /// The step last taken out of this frame (the one to the next frame on the path).
    fn last_step(&self) -> &(usize, Step) {
        &self.steps[self.taken - 1]
    }
}

/// The walk over the sites of a stage's composition.
struct Walk<'a> {
    layers: &'a Layers<'a>,
    stacks: Vec<Stack>,
    /// Stack index by root layer.
    stack_of: HashMap<usize, usize>,
    /// Every site met, and its index.
    sites: Vec<Site>,
    site_ids: HashMap<Site, usize>,
    /// The steps out of each site, once found.
    steps: Vec<Option<Steps>>,
    /// The most prims the stage may compose.
    max_prims: u64,
    /// The most entries a layer stack may expand to.
    max_layer_stack: u64,
    /// The deepest path an ancestor's arc may map a site onto, in path elements: twice the deepest prim path
    /// authored or targeted in any layer, plus two. Deeper sites hold no specs: only arcs that map sites ever
    /// deeper reach them (which `openusd` follows for exponential time, and Pixar's USD for minutes too), so a
    /// deeper one is refused.
    max_mapped_depth: usize,
    /// The entries each layer's stack expands to, by layer, once counted.
    entries: HashMap<usize, u64>,
}

impl<'a> Walk<'a> {
    fn new(layers: &'a Layers<'a>, limits: &Limits) -> Self {
        Self {
            layers,
            stacks: Vec::new(),
            stack_of: HashMap::new(),
            sites: Vec::new(),
            site_ids: HashMap::new(),
            steps: Vec::new(),
            max_prims: limits.usd_prims,
            max_layer_stack: limits.usd_layer_stack,
            max_mapped_depth: 2 * layers.deepest_path() + 2,
            entries: HashMap::new(),
        }
    }

    /// Walks the composition from the pseudo-root of `root`'s layer stack: first every site once, counting the
    /// prims each composes and finding the cycles of sites (see [`Walk::count`]), then every path of children
    /// and arcs, as many as the prims counted, for arcs back into the chain they extend (see [`Walk::unfold`]).
    fn run(&mut self, root: usize) -> Result<(), CompositionError> {
        let start = (self.stack(root)?, "/".to_owned());
        let start = self.site(start);
        self.count(start)?;
        self.unfold(start)
    }

    /// The index of `site`, interned the first time.
    fn site(&mut self, site: Site) -> usize {
        if let Some(&id) = self.site_ids.get(&site) {
            return id;
        }
        let id = self.sites.len();
        self.sites.push(site.clone());
        self.site_ids.insert(site, id);
        self.steps.push(None);
        id
    }

    /// Walks every site reachable from `start` once, depth first, counting the prims each composes; a site
    /// reached again on its own path closes a cycle (see [`cycle_back`]), and a site that composes more prims
    /// than the limit is refused.
    fn count(&mut self, start: usize) -> Result<(), CompositionError> {
        // The prims and prim-index nodes of every site walked; `None` while it is being walked.
        let mut counted: HashMap<usize, Option<(u64, u64)>> = HashMap::from([(start, None)]);
        let mut frames = vec![self.frame(start)?];
        while let Some(top) = frames.last_mut() {
            let Some((next, step)) = top.steps.get(top.taken).cloned() else {
                let (site, prims, nodes) = (top.site, top.prims, top.nodes);
                frames.pop();
                self.within_limit(site, prims)?;
                self.index_within_limit(site, nodes)?;
                counted.insert(site, Some((prims, nodes)));
                add_to_last(&mut frames, prims, nodes);
                continue;
            };
            top.taken += 1;
            match counted.get(&next) {
                Some(Some((prims, nodes))) => add_to_last(&mut frames, *prims, *nodes),
                Some(None) => {
                    if let Some(from) = cycle_back(&frames, next) {
                        return Err(self.cycle(&frames, from, next));
                    }
                }
                None => {
                    // Arcs that map a site ever deeper into a namespace they came from meet no site twice:
                    // Pcp's rule stops them here (and `unfold` applies it to every path).
                    if let Some(from) = step
                        .follows_arc()
                        .then(|| self.lands_in_run(&frames, next))
                        .flatten()
                    {
                        return Err(self.cycle(&frames, from, next));
                    }
                    counted.insert(next, None);
                    let frame = self.frame(next)?;
                    frames.push(frame);
                }
            }
        }
        Ok(())
    }

    /// Follows every path of children and arcs from `start` (the counting pass found no cycle of them, and
    /// bounded their number by the prim limit), refusing an arc whose target is nested with (is, holds or lies
    /// inside) a site of the arc run it extends, in the same layer stack: the frames entered through arcs, and the
    /// prim they start from. Composing that prim would follow the arc forever: Pcp's cycle rule, which `openusd`
    /// applies to references but misses for inherits and specializes, overflowing its stack. The counting pass
    /// cannot see it, as it walks each site once and the run depends on the path.
    fn unfold(&mut self, start: usize) -> Result<(), CompositionError> {
        let mut frames = vec![self.frame(start)?];
        // Paths the counting pass left out (a step back onto a site being walked that closes no cycle) are
        // followed here too: bound them by the same limit.
        let mut prims = 0u64;
        // Every step is work, counted or not: steps to ancestors' arcs' targets are bounded with the sites.
        let mut taken = 0u64;
        let max_steps = self.max_prims.saturating_mul(4);
        while let Some(top) = frames.last_mut() {
            if top.taken == top.steps.len() && !top.implied.is_empty() {
                let mut steps = top.steps.to_vec();
                steps.append(&mut top.implied);
                top.steps = steps.into();
            }
            let Some((next, step)) = top.steps.get(top.taken).cloned() else {
                frames.pop();
                continue;
            };
            top.taken += 1;
            taken += 1;
            if taken > max_steps {
                return Err(CompositionError::Steps {
                    max_steps,
                    max_prims: self.max_prims,
                });
            }
            prims += u64::from(step.counts());
            if prims > self.max_prims {
                return Err(CompositionError::StagePrims(self.max_prims));
            }
            if step.implies_class() {
                self.imply_class(&mut frames, next);
                propagate_specializes(&mut frames, next);
            }
            match step {
                Step::ParentArc(_) => continue,
                // An implied class belongs to the prim the referencing frame composes below the reference (the
                // frame itself, or a descendant), so the run's nesting rules do not apply to it (the implied
                // class rules below model where it lands): it is walked for the work it brings.
                Step::Implied(_) => {}
                Step::Arc(arc) | Step::AncestorArc(arc, _) => {
                    if let Some(from) = self.lands_in_run(&frames, next) {
                        return Err(self.cycle(&frames, from, next));
                    }
                    if let Some((from, level, target)) = self.lands_in_run_by_authors(&frames, next) {
                        let mut cycle = self.cycle(&frames, from, next);
                        if let CompositionError::Cycle { lands, .. } = &mut cycle {
                            *lands = format!(
                                "; at the level of the prims that author the arcs, {level} composes \
                                 {target}, nested with it"
                            );
                        }
                        return Err(cycle);
                    }
                    if arc.kind.is_class() {
                        self.implied_class_in_run(&frames, next)?;
                        self.implied_class_below_children(&frames, next)?;
                    }
                }
                Step::Child => {}
            }
            let frame = self.frame(next)?;
            frames.push(frame);
        }
        Ok(())
    }

    /// Carries the class-based arc just followed from the top frame to `next` onto the layer stack of the
    /// nearest reference or payload below which it is met (through arcs and children), as Pcp's implied classes
    /// do: its target mapped through the reference (a target outside the referenced prim keeps its path, Pcp's
    /// root identity) becomes a step of the referencing frame, walked with its own arcs after that frame's own
    /// steps, and carried further up when it is followed. Pcp builds each of these nodes with the nodes its
    /// arcs bring, at every reference above the class arc, so that a few class arcs below references that fan
    /// out make exponentially many; the walk counts them as steps against the same limit.
    fn imply_class(&mut self, frames: &mut [Frame], next: usize) {
        let Some(through) = (0..frames.len()).rev().find(|&i| {
            let step = &frames[i].last_step().1;
            step.follows_arc() && !step.implies_class()
        }) else {
            return;
        };
        let passes = |f: &Frame| {
            let step = &f.last_step().1;
            step.follows_arc() || matches!(step, Step::Child | Step::Implied(_))
        };
        if !frames[through + 1..].iter().all(passes) {
            return;
        }
        let (source_stack, source) = &self.sites[frames[through].last_step().0];
        let (stack, referencing) = &self.sites[frames[through].site];
        let (target_stack, target) = &self.sites[next];
        if target_stack != source_stack {
            return;
        }
        let Some(arc) = frames.last().and_then(|f| f.last_step().1.arc()) else {
            return;
        };
        let path = precache::map(target, source, referencing).unwrap_or_else(|| target.clone());
        let implied = Arc {
            kind: arc.kind,
            layer: None,
            path: path.clone(),
            asset: String::new(),
        };
        let site = self.site((*stack, path));
        let frame = &mut frames[through];
        if frame.implied_sites.insert(site) {
            frame.implied.push((site, Step::Implied(implied)));
        }
    }

    /// The frame of the arc run that the step just taken from the top frame extends (the frames entered through
    /// arcs, and the prim they start from) whose site is nested with `next` (is, holds or lies inside it, in the
    /// same layer stack), if any: composing `next` would follow the run's arcs forever.
    fn lands_in_run(&self, frames: &[Frame], next: usize) -> Option<usize> {
        let target = &self.sites[next];
        (run_start(frames)..frames.len()).find(|&i| nested(&self.sites[frames[i].site], target))
    }

    /// Like [`Walk::lands_in_run`], at the level of the prims that author the run's arcs (an ancestor's arc is
    /// authored above the site it maps): the frame whose prim at that level is nested with the target of the arc
    /// just followed to `next`, that prim, and the target.
    /// Walking back from the top, each arc's author lies inside the target of the arc before it and maps back
    /// through it. Pcp composes the ancestors' indices first and finds the cycle there, while the sites
    /// themselves may grow ever deeper and never nest (`openusd` 0.6 followed them for minutes).
    fn lands_in_run_by_authors(
        &self,
        frames: &[Frame],
        next: usize,
    ) -> Option<(usize, String, String)> {
        let top = frames.len() - 1;
        let (mut level, lands) = self.author(&frames[top].last_step().1, &self.sites[frames[top].site].1)?;
        let lands = (self.sites[next].0, lands);
        for i in (run_start(frames)..top).rev() {
            let (author, target) = self.author(&frames[i].last_step().1, &self.sites[frames[i].site].1)?;
            level = precache::map(&level, &target, &author)?;
            if nested(&(self.sites[frames[i].site].0, level.clone()), &lands) {
                return Some((i, level, lands.1));
            }
        }
        None
    }

    /// Refuses the class arc just followed from the top frame to `next` when Pcp's implied classes carry it
    /// back into the run: a class arc met below a reference or payload is implied onto the referencing prim's
    /// layer stack, its target mapped through the reference (a target inside the referenced prim moves to the
    /// referencing prim; one outside keeps its path). When that implied target is nested with a site of the run
    /// in that stack, the referencing prim would inherit itself or its own namespace. Pixar's USD reports that
    /// as an arc cycle, or drops the reference when its target has no specs; `openusd` 0.6 follows it for
    /// exponential time. Only the nearest reference of the run is modelled; when either arc is an ancestor's,
    /// the class is also implied at the level of the prims that author them (Pcp composes the ancestors' index
    /// first), so that an ancestor of a site of the run inheriting its own namespace is refused too.
    fn implied_class_in_run(&self, frames: &[Frame], next: usize) -> Result<(), CompositionError> {
        let start = run_start(frames);
        let through = (start..frames.len()).rev().find(|&i| {
            let (target, step) = frames[i].last_step();
            let crosses = self.sites[*target].0 != self.sites[frames[i].site].0;
            crosses && step.follows_arc() && step.arc().is_some_and(|a| !a.kind.is_class())
        });
        let Some(through) = through else {
            return Ok(());
        };
        let (source_stack, source) = &self.sites[frames[through].last_step().0];
        let (stack, referencing) = &self.sites[frames[through].site];
        let (target_stack, target) = &self.sites[next];
        if target_stack != source_stack {
            return Ok(());
        }
        let implied = precache::map(target, source, referencing).unwrap_or_else(|| target.clone());
        let top = frames.last().expect("a frame");
        // The class arc implied as the sites map it, and at the level of the prims that author the two arcs
        // (an ancestor's arc is implied onto the prim that the reference's author composes).
        let mut implied = vec![(referencing.clone(), implied)];
        let authors = (
            self.author(&frames[through].last_step().1, referencing),
            self.author(&top.last_step().1, &self.sites[top.site].1),
        );
        if let (Some((by, source)), Some((class_by, class_target))) = authors {
            if (by != *referencing || class_by != self.sites[top.site].1)
                && (class_by == source || inside(&class_by, &source))
            {
                let at_level = precache::map(&class_target, &source, &by).unwrap_or(class_target);
                implied.push((by, at_level));
            }
        }
        let found = implied.into_iter().find_map(|(by, path)| {
            let site = (*stack, path);
            let from = (start..=through).find(|&i| nested(&self.sites[frames[i].site], &site))?;
            Some((by, site.1, from))
        });
        let Some((referencing, implied, from)) = found else {
            return Ok(());
        };
        let describe = |frame: &Frame| {
            let (next, step) = frame.last_step();
            step.describe(&self.sites[frame.site].1, &self.sites[*next].1)
        };
        let class_arc = top.last_step().1.authored(&self.sites[top.site].1);
        Err(CompositionError::ImpliedClass(Box::new(ImpliedClassCycle {
            class_arc: class_arc.unwrap_or_default(),
            through: describe(&frames[through]),
            below: describe(top),
            referencing,
            implied,
            nested_with: self.sites[frames[from].site].1.clone(),
        })))
    }

    /// The prim that authors the arc `step` follows from the site at `at` (the site's own path, or the ancestor
    /// whose arc it is), with the arc's target path; `None` for a child, a parent's arc, or a layer's default
    /// prim that is not authored.
    fn author(&self, step: &Step, at: &str) -> Option<(String, String)> {
        match step {
            Step::Arc(arc) => Some((at.to_owned(), self.target_path(arc)?)),
            Step::AncestorArc(arc, ancestor) => Some((ancestor.clone(), self.target_path(arc)?)),
            Step::Child | Step::ParentArc(_) | Step::Implied(_) => None,
        }
    }

    /// Refuses the class arc just followed from the top frame to `next` when the top frame was reached from a
    /// reference or payload through children alone (the prim lies below the referenced prim) and Pcp's implied
    /// classes carry the arc onto the referencing layer stack as an arc of the prim it composes there onto
    /// that prim itself, an ancestor or a descendant: `implied_class_in_run` sees only arcs, and the composed
    /// prim (the referencing prim with the top's path below the referenced one) is no site of the walk, whose
    /// children come from each stack's own specs. Pixar's USD reports an arc cycle ("CANNOT inherit from");
    /// `openusd` 0.6 maps the prim ever deeper for seconds to minutes.
    fn implied_class_below_children(
        &self,
        frames: &[Frame],
        next: usize,
    ) -> Result<(), CompositionError> {
        let mut below = frames.len() - 1;
        while below > 0 && matches!(frames[below - 1].last_step().1, Step::Child) {
            below -= 1;
        }
        let Some(reference) = below.checked_sub(1).map(|i| &frames[i]) else {
            return Ok(());
        };
        let (source_site, step) = reference.last_step();
        let by_reference = step.arc().is_some_and(|a| !a.kind.is_class());
        let (source_stack, source) = &self.sites[*source_site];
        let (stack, referencing) = &self.sites[reference.site];
        let (target_stack, target) = &self.sites[next];
        if !by_reference || source_stack == stack || target_stack != source_stack {
            return Ok(());
        }
        let top = frames.last().expect("a frame");
        let Some(composed) = precache::map(&self.sites[top.site].1, source, referencing) else {
            return Ok(());
        };
        let implied = precache::map(target, source, referencing).unwrap_or_else(|| target.clone());
        if !nested(&(*stack, implied.clone()), &(*stack, composed.clone())) {
            return Ok(());
        }
        let class_arc = top.last_step().1.authored(&self.sites[top.site].1);
        Err(CompositionError::ImpliedClass(Box::new(ImpliedClassCycle {
            class_arc: class_arc.unwrap_or_default(),
            through: step.describe(referencing, source),
            below: format!("{} composes {composed}", self.sites[top.site].1),
            referencing: referencing.clone(),
            implied,
            nested_with: composed,
        })))
    }

    /// `Ok` when the prim index of `site` holds at most as many nodes as the prim limit allows prims: the arcs a
    /// prim composes (its own and its ancestors', each target with its own arcs, once per path that reaches it)
    /// are the work of building its index, which Pixar's USD and `openusd` alike do node by node. A few
    /// payloads, each reaching the next through several arcs, make millions of nodes for one prim.
    fn index_within_limit(&self, site: usize, nodes: u64) -> Result<(), CompositionError> {
        if nodes <= self.max_prims {
            return Ok(());
        }
        Err(CompositionError::IndexNodes {
            site: self.sites[site].1.clone(),
            nodes,
            max_prims: self.max_prims,
        })
    }

    /// `Ok` when `site` composes at most the limit's prims (the pseudo-root, not a prim itself, one more).
    fn within_limit(&self, site: usize, prims: u64) -> Result<(), CompositionError> {
        let path = &self.sites[site].1;
        let (what, prims) = if path == "/" {
            ("the stage", prims - 1)
        } else {
            (path.as_str(), prims)
        };
        if prims <= self.max_prims {
            return Ok(());
        }
        Err(CompositionError::SitePrims {
            what: what.to_owned(),
            prims,
            max_prims: self.max_prims,
        })
    }

    /// A frame for `site`, its steps found the first time. The sites met are bounded by four times the prim
    /// limit: arcs that map sites ever deeper would otherwise make new ones without end.
    fn frame(&mut self, site: usize) -> Result<Frame, CompositionError> {
        let max_sites = self.max_prims.saturating_mul(4);
        if self.sites.len() as u64 > max_sites {
            return Err(CompositionError::Sites {
                max_sites,
                max_prims: self.max_prims,
            });
        }
        let steps = match &self.steps[site] {
            Some(steps) => steps.clone(),
            None => {
                let steps: Steps = self.find_steps(site)?.into();
                self.steps[site] = Some(steps.clone());
                steps
            }
        };
        Ok(Frame {
            site,
            steps,
            taken: 0,
            prims: 1,
            nodes: 1,
            implied: Vec::new(),
            implied_sites: HashSet::new(),
        })
    }

    /// The steps out of `site`: its arcs' targets, its parent's class-based arcs' targets, its ancestors' arcs'
    /// targets with the site mapped onto them, then its children.
    fn find_steps(&mut self, site: usize) -> Result<Vec<(usize, Step)>, CompositionError> {
        let (stack, path) = self.sites[site].clone();
        self.not_mapped_onto_itself(stack, &path)?;
        let prims = &self.stacks[stack].prims;
        let own = prims.get(&path);
        let arcs: Vec<Arc> = own.map(|p| p.arcs.clone()).unwrap_or_default();
        let children: Vec<String> = own.map(|p| p.children.clone()).unwrap_or_default();
        let inherited: Vec<Arc> = match prims.get(parent(&path)) {
            Some(p) if path != "/" => p
                .arcs
                .iter()
                .filter(|a| a.kind.is_class())
                .cloned()
                .collect(),
            _ => Vec::new(),
        };
        let mut steps = Vec::new();
        for arc in arcs {
            if let Some(target) = self.target(stack, &arc)? {
                steps.push((self.site(target), Step::Arc(arc)));
            }
        }
        for arc in inherited {
            if let Some(target) = self.target(stack, &arc)? {
                steps.push((self.site(target), Step::ParentArc(arc)));
            }
        }
        let ancestors: Vec<(String, Arc)> = precache::ancestors(&path)
            .skip(1)
            .flat_map(|ancestor| {
                let arcs = self.stacks[stack]
                    .prims
                    .get(ancestor)
                    .map(|p| p.arcs.clone());
                arcs.into_iter()
                    .flatten()
                    .map(|arc| (ancestor.to_owned(), arc))
            })
            .collect();
        for (ancestor, arc) in ancestors {
            if let Some((target_stack, target)) = self.target(stack, &arc)? {
                // An ancestor whose own arc lands in its own namespace is a cycle in the ancestor's index, which
                // the walk may never visit (a reference can target the prim below it directly).
                if nested(&(stack, ancestor.clone()), &(target_stack, target.clone())) {
                    return Err(CompositionError::OwnNamespace {
                        ancestor,
                        arc: arc.describe(),
                        path: path.to_owned(),
                    });
                }
                let mapped = format!("{target}{}", &path[ancestor.len()..]);
                let depth = precache::depth(&mapped);
                if depth > self.max_mapped_depth {
                    return Err(CompositionError::MappedTooDeep {
                        path: path.to_owned(),
                        ancestor,
                        arc: arc.describe(),
                        mapped,
                        depth,
                        max_depth: self.max_mapped_depth,
                    });
                }
                let site = self.site((target_stack, mapped));
                steps.push((site, Step::AncestorArc(arc, ancestor)));
            }
        }
        for child in children {
            steps.push((self.site((stack, child)), Step::Child));
        }
        Ok(steps)
    }

    /// Refuses a class-based arc of the prim at `path` whose target lies strictly inside the target of an arc
    /// (of any kind; its prim path, or its layer's default prim) of the prim or of an ancestor, in the same
    /// layer stack, and maps through it onto the prim itself or a child of it: a prim that inherits `/X` and
    /// `/X/Y`, or references `/X` and specializes `/X/Y`, or under one that inherits `/X`, a prim `B` that
    /// inherits `/X/B`. Such a stage composes in USD, but `openusd` 0.6 pre-caches the mapped path, finds the
    /// same arc there again and recurses until its stack overflows.
    fn not_mapped_onto_itself(&self, stack: usize, path: &str) -> Result<(), CompositionError> {
        let prims = &self.stacks[stack].prims;
        let Some(own) = prims.get(path) else {
            return Ok(());
        };
        let here = |arc: &&Arc| self.in_stack(stack, arc);
        for class in own.arcs.iter().filter(|a| a.kind.is_class()).filter(here) {
            let mut ancestor = path;
            while ancestor != "/" {
                let arcs = prims.get(ancestor).map_or(&[][..], |p| p.arcs.as_slice());
                for arc in arcs.iter().filter(here) {
                    let Some(target) = self.target_path(arc) else {
                        continue;
                    };
                    let Some(rest) = class.path.strip_prefix(target.as_str()) else {
                        continue;
                    };
                    let mapped = format!("{ancestor}{rest}");
                    if rest.starts_with('/') && (mapped == path || parent(&mapped) == path) {
                        let default = if arc.path.is_empty() {
                            format!(" (its default prim <{target}>)")
                        } else {
                            String::new()
                        };
                        return Err(CompositionError::MappedOntoItself {
                            path: path.to_owned(),
                            class_arc: class.describe(),
                            ancestor: ancestor.to_owned(),
                            arc: format!("{}{default}", arc.describe()),
                            mapped,
                        });
                    }
                }
                ancestor = parent(ancestor);
            }
        }
        Ok(())
    }

    /// Whether `arc`, authored in layer stack `stack`, targets that same layer stack (an internal arc, or one to
    /// the stack's root layer).
    fn in_stack(&self, stack: usize, arc: &Arc) -> bool {
        arc.layer
            .is_none_or(|layer| self.stack_of.get(&layer) == Some(&stack))
    }

    /// The site an arc authored in layer stack `stack` targets; `None` for a default prim that is not authored.
    fn target(&mut self, stack: usize, arc: &Arc) -> Result<Option<Site>, CompositionError> {
        let Some(path) = self.target_path(arc) else {
            return Ok(None);
        };
        match arc.layer {
            Some(layer) => Ok(Some((self.stack(layer)?, path))),
            None => Ok(Some((stack, path))),
        }
    }

    /// The prim path an arc targets: its own, or its layer's default prim (`None` when that is not authored).
    fn target_path(&self, arc: &Arc) -> Option<String> {
        match arc.layer {
            Some(layer) if arc.path.is_empty() => self.layers.layers[layer]
                .as_ref()
                .and_then(|l| l.default_prim.clone()),
            _ => Some(arc.path.clone()),
        }
    }

    /// The index of the layer stack whose root is `layer`, counting its entries against the limit and merging
    /// its layers' prims the first time.
    fn stack(&mut self, layer: usize) -> Result<usize, CompositionError> {
        if let Some(&index) = self.stack_of.get(&layer) {
            return Ok(index);
        }
        let entries = self.entries(layer)?;
        if entries > self.max_layer_stack {
            return Err(CompositionError::LayerStack {
                layer: self.layers.names[layer].clone(),
                entries,
                max: self.max_layer_stack,
            });
        }
        let mut prims: HashMap<String, Prim> = HashMap::new();
        for member in self.members(layer) {
            let Some(summary) = &self.layers.layers[member] else {
                continue;
            };
            for (path, prim) in &summary.prims {
                let merged = prims.entry(path.clone()).or_default();
                merged.children.extend(prim.children.iter().cloned());
                merged.arcs.extend(prim.arcs.iter().cloned());
            }
        }
        for prim in prims.values_mut() {
            prim.children.sort_unstable();
            prim.children.dedup();
        }
        let index = self.stacks.len();
        self.stacks.push(Stack { prims });
        self.stack_of.insert(layer, index);
        Ok(index)
    }

    /// The distinct layers of the layer stack whose root is `layer`: it and its sublayers, nested ones too.
    fn members(&self, layer: usize) -> Vec<usize> {
        let mut members = vec![layer];
        let mut seen = HashSet::from([layer]);
        let mut next = 0;
        while let Some(&member) = members.get(next) {
            next += 1;
            for &sub in self.sublayers(member) {
                if seen.insert(sub) {
                    members.push(sub);
                }
            }
        }
        members
    }

    /// The sublayers of `layer` (none when it cannot be read).
    fn sublayers(&self, layer: usize) -> &'a [usize] {
        self.layers.layers[layer]
            .as_ref()
            .map_or(&[][..], |l| l.sublayers.as_slice())
    }

    /// The entries the layer stack whose root is `layer` expands to, as `openusd` builds it: the layer, then each
    /// sublayer's own entries in turn. Counted without recursion, each layer once (a layer's count is kept for
    /// every stack that names it), saturating. A sublayer already on the path is a sublayer cycle, which Pixar's
    /// USD reports as a composition error ("Sublayer hierarchy ... has cycles"), and is refused.
    fn entries(&mut self, layer: usize) -> Result<u64, CompositionError> {
        if let Some(&known) = self.entries.get(&layer) {
            return Ok(known);
        }
        // (layer, sublayers gone through, entries so far) along the path from `layer`.
        let mut path = vec![(layer, 0usize, 1u64)];
        let mut on_path = HashSet::from([layer]);
        while let Some(top) = path.last_mut() {
            let Some(&sub) = self.sublayers(top.0).get(top.1) else {
                let (done, _, count) = *top;
                path.pop();
                on_path.remove(&done);
                self.entries.insert(done, count);
                if let Some(parent) = path.last_mut() {
                    parent.2 = parent.2.saturating_add(count);
                }
                continue;
            };
            top.1 += 1;
            if on_path.contains(&sub) {
                let names = &self.layers.names;
                return Err(CompositionError::SublayerCycle {
                    root: names[layer].clone(),
                    layer: names[top.0].clone(),
                    names: names[sub].clone(),
                });
            }
            match self.entries.get(&sub) {
                Some(&known) => top.2 = top.2.saturating_add(known),
                None => {
                    on_path.insert(sub);
                    path.push((sub, 0, 1));
                }
            }
        }
        Ok(self.entries[&layer])
    }

    /// The error for a walk that closed a cycle by stepping to `site` from the top frame: the steps from frame
    /// `from` to the top, named by the first arc among them, and where the last lands when it is not on `from`'s
    /// site itself.
    fn cycle(&self, frames: &[Frame], from: usize, site: usize) -> CompositionError {
        let path = |id: usize| self.sites[id].1.as_str();
        let steps: Vec<(&str, &Step, &str)> = frames[from..]
            .iter()
            .map(|f| (path(f.site), &f.last_step().1, path(f.last_step().0)))
            .collect();
        let chain: Vec<String> = steps
            .iter()
            .map(|(at, step, next)| step.describe(at, next))
            .collect();
        let named = steps.iter().find_map(|(at, step, _)| step.authored(at));
        let (start, end) = (path(frames[from].site), path(site));
        let lands = if inside(end, start) {
            format!(", back inside {start}")
        } else if inside(start, end) {
            format!(", back above {start}")
        } else {
            String::new()
        };
        CompositionError::Cycle {
            named: named.unwrap_or_else(|| end.to_owned()),
            chain: chain.join(", "),
            lands,
        }
    }
}

/// Adds the prims of a site just walked to the frame that stepped to it, if that step counts, and the nodes of
/// its prim index if the step follows an arc.
fn add_to_last(frames: &mut [Frame], prims: u64, nodes: u64) {
    if let Some(last) = frames.last_mut() {
        let step = &last.last_step().1;
        let (counts, follows_arc) = (step.counts(), step.follows_arc());
        if counts {
            last.prims = last.prims.saturating_add(prims);
        }
        if follows_arc {
            last.nodes = last.nodes.saturating_add(nodes);
        }
    }
}

/// Copies the specializes arc just followed from the top frame to `next` to the root of the prim index it lies
/// in, as Pcp propagates every specializes node below the root (with its subtree) to the root: a step of the
/// deepest frame reached from the pseudo-root through children alone (the prim whose index it is, or the
/// ancestor under which the walk composes it), taken after that frame's own steps. The copy, at the root, is
/// not propagated again.
fn propagate_specializes(frames: &mut [Frame], next: usize) {
    let top = frames.len() - 1;
    let Some(Step::Arc(arc) | Step::AncestorArc(arc, _) | Step::Implied(arc)) =
        Some(&frames[top].last_step().1)
    else {
        return;
    };
    if arc.kind != ArcKind::Specializes {
        return;
    }
    let root = (1..=top)
        .find(|&i| !matches!(frames[i - 1].last_step().1, Step::Child))
        .map_or(top, |i| i - 1);
    if root == top {
        return;
    }
    let copy = Step::Implied(arc.clone());
    let frame = &mut frames[root];
    if frame.implied_sites.insert(next) {
        frame.implied.push((next, copy));
    }
}

/// Whether the step just taken from the top frame, back to `site` on the path, closes a cycle: the index of the
/// frame it starts from if the steps around are arcs and children (the site composes an arc back onto itself or
/// an ancestor), or inherits and specializes alone, its own or its parent's (the loop `openusd`'s pre-caching
/// follows). Around a parent's arc and a child or a reference the site composes a target path mapped below the
/// parent's, not the site itself, so that is no cycle.
fn cycle_back(frames: &[Frame], site: usize) -> Option<usize> {
    let from = frames.iter().position(|f| f.site == site)?;
    let steps = || frames[from..].iter().map(|f| &f.last_step().1);
    let composes = steps().all(Step::composes);
    let precaches = steps().all(|s| match s {
        Step::Arc(arc) | Step::ParentArc(arc) => arc.kind.is_class(),
        Step::AncestorArc(..) | Step::Child | Step::Implied(_) => false,
    });
    (composes || precaches).then_some(from)
}

/// The first frame of the arc run that ends at the top frame: walking back while each frame was entered through
/// an arc.
fn run_start(frames: &[Frame]) -> usize {
    let mut start = frames.len() - 1;
    while start > 0 && frames[start - 1].last_step().1.follows_arc() {
        start -= 1;
    }
    start
}

/// Whether two sites are nested: in one layer stack, the same prim or one inside the other (the pseudo-root,
/// which holds everything, is nested with nothing).
fn nested(a: &Site, b: &Site) -> bool {
    a.0 == b.0
        && a.1 != "/"
        && b.1 != "/"
        && (a.1 == b.1 || inside(&a.1, &b.1) || inside(&b.1, &a.1))
}

/// Whether prim path `inner` lies below prim path `outer`.
fn inside(inner: &str, outer: &str) -> bool {
    inner.len() > outer.len() && inner.starts_with(outer) && inner.as_bytes()[outer.len()] == b'/'
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes `files` (name, text) to a fresh folder and checks the stage whose root is the first.
    fn check_files(tag: &str, files: &[(&str, &str)]) -> Result<(), CompositionError> {
        check_with(tag, files, Limits::default())
    }

    /// [`check_files`] under `limits`.
    fn check_with(
        tag: &str,
        files: &[(&str, &str)],
        limits: Limits,
    ) -> Result<(), CompositionError> {
        let root = write_files(tag, files);
        check(root.to_str().unwrap(), &resolver(), &limits)
    }

    /// Only the pre-caching model's check of the stage `files` make (the walk left out).
    fn precache_files(tag: &str, files: &[(&str, &str)]) -> Result<(), CompositionError> {
        let root = write_files(tag, files);
        let resolver = resolver();
        let (layers, _) = Layers::load(&resolver, root.to_str().unwrap());
        precache::Precache::new(&layers)
            .check(Limits::default().usd_prims)
    }

    /// Writes `files` (name, text) to a fresh folder; returns the path of the first, the root layer.
    fn write_files(tag: &str, files: &[(&str, &str)]) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("nimbus_composition_{}_{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, text) in files {
            std::fs::write(dir.join(name), format!("#usda 1.0\n{text}")).unwrap();
        }
        dir.join(files[0].0)
    }

    /// The resolver the loader checks layers through, with the default limits.
    fn resolver() -> CheckingResolver {
        CheckingResolver {
            inner: ar::DefaultResolver::new(),
            limits: Limits::default(),
        }
    }

    /// Pixar's USD (usd-core 26.11) reports an arc cycle on this stage; `openusd` 0.6 composed it for minutes.
    #[test]
    fn an_ancestors_arc_back_into_the_run_is_a_cycle() {
        let root = "(\n defaultPrim = \"A\"\n)\ndef \"A\" (references = @./a.usda@</C/C>) {}";
        let asset = "over \"C\" (payload = @./root.usda@) { def \"C\" {} }";
        let err =
            check_files("ancestor_cycle", &[("root.usda", root), ("a.usda", asset)]).unwrap_err().to_string();
        assert!(
            err.contains("composition cycle") && err.contains("/C/C is under /C, which payload"),
            "{err}"
        );
    }

    /// Pixar's USD reports an arc cycle: /A composes /C/D, whose parent's reference maps it onto /A/D, and so on
    /// ever deeper (`openusd` 0.6 never met the same site twice and ran for minutes).
    #[test]
    fn arcs_that_map_a_prim_ever_deeper_are_a_cycle() {
        let root =
            "def \"A\" (references = </C/D>) {}\ndef \"C\" (references = </A>) { def \"D\" {} }";
        let err = check_files("deeper", &[("root.usda", root)]).unwrap_err().to_string();
        assert!(
            err.contains("composition cycle") && err.contains("back inside /A"),
            "{err}"
        );
    }

    /// Ancestors' arcs that map a prim ever deeper, never nested with the prims they started from: in `l1`'s
    /// stack (which holds `root`), `/B` specializes `/A/B/D` and `/A` specializes `/B/B/A`, so `/B/A/C` maps to
    /// `/A/B/D/A/C`, then `/B/B/A/B/D/A/C`, and so on. `openusd` 0.6 composed this (the fuzz target's
    /// `confirm-run-7a6ce936`, reduced) for over 20 s, Pixar's USD for over 30 s; the walk used to stop
    /// following such sites silently, and now refuses the first one deeper than its bound.
    #[test]
    fn ancestors_arcs_that_map_prims_ever_deeper_are_refused() {
        let root = "def \"A\" (specializes = [</B/B/A>, </B/B/C>])\n{\n    over \"C\" (references = \
                    @l1.usda@</B/A/C>)\n    {\n        class \"C\" {\n        }\n    }\n}\n";
        let l1 = "(\n    subLayers = [@root.usda@]\n)\nover \"B\" (specializes = </A/B/D>) {\n}\ndef \"A\" {\n}\n";
        let err = check_files("ever_deeper", &[("root.usda", root), ("l1.usda", l1)])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("maps it onto") && err.contains("deeper than twice the deepest"),
            "{err}"
        );
    }

    /// Class arcs met below references are implied onto the referencing prims (and specializes copied to the
    /// root of the index), each walked with its own arcs: the fuzz target's `confirm-run-5051797f` (unreduced),
    /// which `openusd` 0.6 composed for over 20 s and Pixar's USD for over 60 s. Only through the implied
    /// classes does the walk reach the class arc that the implied-class rule refuses.
    #[test]
    fn implied_classes_are_walked_with_their_own_arcs() {
        let l0 = "(\n    defaultPrim = \"A\"\n)\ndef Xform \"A\" (prepend specializes = [</B/B/C>, </B/B/B>]\nprepend references = [</C/B>])\n{\n    over Xform \"D\" (instanceable = true\nprepend references = [@./l1.usda@</C/C>, @./l2.usda@])\n    {\n        class Xform \"B\" (variants = { string v = \"x\" }\nprepend variantSets = \"v\")\n        {\n            variantSet \"v\" = {\n                \"x\" (prepend specializes = [</D/D>]) {}\n            }\n        }\n        over Xform \"C\" (prepend references = [@./l1.usda@</C/C>])\n        {\n        }\n    }\n}\n";
        let l1 = "(\n    subLayers = [@./l2.usda@, @./l2.usda@, @./l2.usda@]\n)\ndef Xform \"B\" (prepend inherits = [</A>, </C>]\nprepend references = [</C>])\n{\n}\ndef Xform \"C\" (prepend references = [@./l0.usda@</A>]\nprepend payload = [@./l1.usda@</A/D/C>])\n{\n}\n";
        let files = [("l0.usda", l0), ("l1.usda", l1), ("l2.usda", "")];
        let err = check_files("implied_walk", &files).unwrap_err().to_string();
        assert!(err.contains("a class arc implied onto"), "{err}");
    }

    /// A class arc below a reference is implied onto the referencing prim: here /A would inherit its own child.
    /// Pixar's USD drops the reference (its target has no specs) with an error; `openusd` 0.6 keeps it and
    /// composed the stage for minutes, so it is refused.
    #[test]
    fn a_class_implied_back_into_the_referencing_prim_is_refused() {
        let root = "def \"A\" (references = @./l1.usda@</C/C>) { over \"C\" (references = @./l1.usda@</C/D>) {} }";
        let asset = "over \"C\" (inherits = </A>) {}\ndef \"A\" {}";
        let err = check_files("implied", &[("root.usda", root), ("l1.usda", asset)]).unwrap_err().to_string();
        assert!(
            err.contains("implied onto /A's layer stack as /A/C, nested with /A"),
            "{err}"
        );
    }

    /// A class arc on a child of the referenced prim (met below the reference through children, not arcs) is
    /// implied onto the referencing layer stack too: here onto /A/A/C, the prim that composes l1's /C/C/C, as
    /// an inherit of its own ancestor /A. Pixar's USD (usd-core 26.11) reports an arc cycle ("/A/A/C CANNOT
    /// inherit from /A") in 0.03 s; `openusd` 0.6 mapped the prim ever deeper for 11 s (fuzz target
    /// `usd_compose`, `final-run-60ad648e` reduced).
    #[test]
    fn a_class_implied_from_a_child_below_a_reference_onto_its_ancestor_is_refused() {
        let root = "def \"A\" { def \"A\" (references = @./l1.usda@</C/C>) {} }";
        let asset = "def \"C\" { class \"C\" { over \"C\" (inherits = </A>) {} } }";
        let files = [("root.usda", root), ("l1.usda", asset)];
        let err = check_files("implied_child", &files).unwrap_err().to_string();
        assert!(
            err.contains("implied onto /A/A's layer stack as /A, nested with /A/A/C"),
            "{err}"
        );
        // The same class arc on a global class outside the composed prim's namespace is no cycle.
        let asset = "def \"C\" { class \"C\" { over \"C\" (inherits = </K>) {} } }\nclass \"K\" {}";
        let files = [("root.usda", root), ("l1.usda", asset)];
        check_files("implied_child_global", &files).unwrap();
    }

    /// A class arc authored on an ancestor, met below a payload that an ancestor authors, is implied at the level
    /// of those ancestors: /A/C composes l1's /C/C, whose parent's payload brings /D/D/B/C, whose ancestor /D's
    /// payload brings l0's /A/D/B/C, whose ancestor /A inherits /C; implied through /D's payload onto l1, /D
    /// inherits l1's /C, the ancestor of the run's /C/C. Pixar's USD (usd-core 26.11) reports the arc cycle
    /// ("l1 </D> CANNOT inherit from l1 </C>") in 0.02 s; `openusd` 0.6 ran past 60 s (the fuzz target's
    /// `slow-composition-a867f5a8`, reduced).
    #[test]
    fn a_class_implied_at_the_level_of_the_ancestors_that_author_the_arcs_is_refused() {
        let root = "def \"A\" (inherits = </C>) { over \"C\" (references = @./l1.usda@</C/C>) {} }";
        let asset = "def \"C\" (payload = [</D/D/B>, @./l0.usda@</A/B/A>]) {}\n\
                     def \"D\" (payload = @./l0.usda@</A>) {}";
        let files = [("l0.usda", root), ("l1.usda", asset)];
        let err = check_files("implied_ancestors", &files).unwrap_err().to_string();
        assert!(
            err.starts_with("/A: inherits </C> is a composition cycle")
                && err.contains("implied onto /D's layer stack as /C, nested with /C/C"),
            "{err}"
        );
    }

    /// Arcs of ancestors that lead back into the run at the level of the prims that author them: /A/C composes
    /// l1's /B/A/C, whose ancestor /B inherits /A, whose specialize of /B/B/C lies inside /B. Pixar's USD
    /// (usd-core 26.11) reports the arc cycle ("l1 </B> inherits from l1 </A> which CANNOT refer to l1
    /// </B/B/C>"); the sites themselves never nest (/B/A/C, /A/A/C, /B/B/C/A/C, /A/B/C/A/C... ever deeper), and
    /// `openusd` 0.6 ran past 60 s (the fuzz target's `final-run-64d6ea8c`, reduced).
    #[test]
    fn ancestors_arcs_back_into_the_run_at_their_own_level_are_a_cycle() {
        let root = "def \"A\" (specializes = </B/B/C>) { over \"C\" (references = @./l1.usda@</B/A/C>) {} }";
        let asset = "(\n subLayers = [@./l0.usda@]\n)\nover \"B\" (inherits = </A> payload = </A/A>) {}";
        let files = [("l0.usda", root), ("l1.usda", asset)];
        let err = check_files("ancestor_level", &files).unwrap_err().to_string();
        // Refused as arcs that map prims ever deeper (the first rule met), or as the cycle it is at the level of
        // the prims that author the arcs.
        assert!(
            err.contains("deeper than twice the deepest")
                || (err.contains("composition cycle")
                    && err.contains("at the level of the prims that author the arcs")),
            "{err}"
        );
    }

    /// A model's usual arcs: a reference to an asset whose prim inherits a class and whose child references a
    /// part, and an override below the reference that inherits a class of the stage. Pixar's USD composes it
    /// without errors.
    #[test]
    fn ancestral_arcs_of_an_ordinary_asset_are_no_cycle() {
        let root = "def \"World\" {\n def \"Chair\" (references = @./chair.usda@</Chair>) {\n  over \"Leg\" \
                    (inherits = </World/Looks/Wood>) {}\n }\n class \"Looks\" { class \"Wood\" {} }\n}";
        let chair = "def \"Chair\" (inherits = </_class_Chair>) { def \"Leg\" (references = </Parts/Leg>) {} }\n\
                     class \"_class_Chair\" {}\nover \"Parts\" { def \"Leg\" { def \"Foot\" {} } }";
        check_files("ordinary", &[("root.usda", root), ("chair.usda", chair)]).unwrap();
    }

    /// Pixar's USD 26.11 refuses both layers ("Duplicate prim", "Duplicate items exist for field"); `openusd`
    /// 0.6 kept both copies, and fuzz inputs built on them composed for minutes or overflowed its stack.
    #[test]
    fn a_prim_or_an_arc_authored_twice_is_refused() {
        let prim =
            check_files("twice_prim", &[("root.usda", "def \"A\" {}\ndef \"A\" {}")]).unwrap_err().to_string();
        assert!(
            prim.ends_with(
                "root.usda defines prim </A> twice in one scope: Pixar's USD refuses such a layer \
                                (\"Duplicate prim\", \"Duplicate items exist for field\")"
            ),
            "{prim}"
        );
        let nested = "def \"B\" { def \"C\" {}\n def \"C\" {} }";
        let err = check_files("twice_nested", &[("root.usda", nested)]).unwrap_err().to_string();
        assert!(err.contains("defines prim </B/C> twice"), "{err}");
        let arcs = "def \"A\" (inherits = [</B>, </B>]) {}\nclass \"B\" {}";
        let err = check_files("twice_arc", &[("root.usda", arcs)]).unwrap_err().to_string();
        assert!(err.contains("lists </A> inherits </B> twice"), "{err}");
        // The same target through two kinds of arc, or in two prims, is no duplicate.
        let fine = "def \"A\" (inherits = </B> specializes = </B>) {}\ndef \"C\" (inherits = </B>) {}\nclass \"B\" {}";
        check_files("twice_fine", &[("root.usda", fine)]).unwrap();
    }

    #[test]
    fn parents_of_prim_paths() {
        assert_eq!(parent("/A/B/C"), "/A/B");
        assert_eq!(parent("/A"), "/");
        assert_eq!(parent("/"), "/");
    }

    #[test]
    fn a_parents_inherit_around_a_child_or_a_reference_is_no_cycle() {
        // /A/C composes /B/C (the parent's inherit, mapped), not /B: nothing leads back.
        let stage = "def \"A\" (inherits = </B>) { def \"C\" {} }\nclass \"B\" { def \"X\" (references = </A/C>) {} }";
        check_files("parent_ok", &[("root.usda", stage)]).unwrap();
    }

    /// `openusd` 0.6 maps each pre-cached target back through every arc of the parent's prim index, chains of
    /// arcs included: under /B, which inherits /D, /B/D composes /D/D, which inherits /X, so /X maps onto /B/D,
    /// and /B's inherit of /D/D/A maps onto /B/D/A. Pre-caching /B/D/A then finds /B/D and /B/D finds /B/D/A,
    /// until its stack overflows (the fuzz target's `final-run-63b4c7ce`, reduced). Pixar's USD (usd-core
    /// 26.11) composes the stage in 0.02 s with no error; it is refused as openusd's cycle.
    #[test]
    fn pre_caching_maps_targets_back_through_chains_of_arcs() {
        let stage = "def \"D\" {\n over \"B\" (specializes = </B/A>) {}\n def \"D\" (inherits = </X>) {}\n}\n\
                     def \"B\" (inherits = [</D/D/A>, </D>]) {}\n";
        let err = precache_files("chain", &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(
            err.contains("is a composition cycle for openusd 0.6") && err.contains("/B/D/A -> /B/D -> /B/D/A"),
            "{err}"
        );
    }

    /// `openusd` 0.6 composes the ancestors of each pre-cached target first, pre-caching theirs: /E's target
    /// /D/X/Y has none, but its ancestor /D/X takes /D's inherit of /B/A mapped through /D's reference of /B,
    /// /D/A, whose own targets are the same (its parent is /D too), /D/A among them, until its stack overflows (the
    /// fuzz target's `final-run-c15c398e`, reduced). Pixar's USD (usd-core 26.11) composes the stage in 0.02 s
    /// with no error. The walk refuses it too (an inherit mapped onto the prim's own child); the model on its own:
    #[test]
    fn pre_caching_composes_the_ancestors_of_each_target() {
        let stage = "class \"B\" {}\ndef \"D\" (inherits = </B/A> references = </B>) {}\n\
                     def \"E\" (inherits = </D/X/Y>) {}\n";
        let err = precache_files("ancestors", &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(
            err.contains("is a composition cycle for openusd 0.6") && err.contains("/D/A -> /D/A"),
            "{err}"
        );
    }

    /// A class target met through an arc is composed with its target mapped back through that arc too (Pcp's
    /// implied classes): /C inherits /A, so /C/D composes /A/D, whose specializes of /A/A is also /C/A, which
    /// inherits /A; so /C/D composes /A with /C/D's path, and /A/D's target /A/A, pre-cached for the child /C/D/A,
    /// maps onto /C/D/A itself (the fuzz target's `confirm-run2-55db2b7c`, reduced). Pixar's USD (usd-core
    /// 26.11) composes the stage with no error in 0.02 s; `openusd` 0.6 overflowed its stack.
    #[test]
    fn pre_caching_composes_class_targets_mapped_back_through_the_arcs() {
        let stage = "def \"C\" (inherits = </A>) { over \"A\" (inherits = </A>) {} }\n\
                     def \"A\" { def \"D\" (specializes = </A/A>) {} }\n";
        let err = precache_files("implied_site", &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(
            err.contains("is a composition cycle for openusd 0.6") && err.contains("/C/A/D/A -> /C/A/D/A"),
            "{err}"
        );
    }

    /// A class target is a path of the layer stack that authors it, mapped into the stage through the arcs of
    /// the author's ancestors: /D references the root layer's default prim /A, so /D/A's inherit of /A is an
    /// inherit of /D, and /A/B's specializes of /D/A/A composes /D/A below /A/B; the target /D/A/A, pre-cached
    /// for /A/B/A, maps onto /A/B/A itself (the fuzz target's `confirm-run2-6717a55a`, reduced). Pixar's USD
    /// (usd-core 26.11) composes it with no error in 0.03 s; `openusd` 0.6 overflowed its stack.
    #[test]
    fn pre_caching_maps_class_targets_through_the_authors_ancestors() {
        let stage = "(\n defaultPrim = \"A\"\n)\n\
                     over \"D\" (references = @./root.usda@) { class \"A\" (inherits = </A>) {} }\n\
                     def \"A\" { over \"B\" (specializes = </D/A/A>) {} }\n";
        let err = precache_files("author_ancestors", &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(
            err.contains("is a composition cycle for openusd 0.6") && err.contains("/A/B/A -> /A/B/A"),
            "{err}"
        );
    }

    /// The children a prim composes through its sites are pre-cached too (the fuzz target's
    /// `confirm-run-33d695f0`, reduced): /D/A composes /C through its payload and /C composes /A through its own,
    /// so /D/A/C holds /D/A/C/B, composed from /A/B, which inherits /A/C; mapped back, that target is
    /// /D/A/C/B/C, whose own targets hold it again. No authored prim or once-mapped one leads there. Pixar's USD (usd-core 26.11) composes it with no
    /// error in 0.04 s; `openusd` 0.6 overflowed its stack after 2.5 s (the stage unreduced: 9 s).
    #[test]
    fn pre_caching_starts_from_the_children_composed_through_arcs() {
        let stage = "def \"A\" { def \"B\" (inherits = </A/C>) {} }\n\
                     over \"C\" (payload = </A>) {}\n\
                     def \"D\" { over \"A\" (payload = @./root.usda@</C>) { class \"C\" (inherits = </A>) {} } }\n";
        let err = precache_files("composed_children", &[("root.usda", stage)]).unwrap_err().to_string();
        assert!(
            err.contains("is a composition cycle for openusd 0.6") && err.contains("/D/A/C/B/C -> /D/A/C/B/C"),
            "{err}"
        );
    }

    #[test]
    fn pre_caching_follows_stage_paths_across_layer_stacks() {
        // A class inside a referenced asset, and a payload beside an inherit: targets that lead nowhere back.
        let asset = "def \"X\" { def \"Geo\" (inherits = </X/_cls>) {} class \"_cls\" {} }";
        let stage = "def \"A\" (references = @./asset.usda@</X>) {}\n\
                     def \"B\" (inherits = </K> payload = @./asset.usda@</X>) { def \"C\" {} }\nclass \"K\" {}";
        check_files(
            "precache_ok",
            &[("root.usda", stage), ("asset.usda", asset)],
        )
        .unwrap();
        // A target of another layer stack's prim is taken as the stage's path: /Q, which specializes /A/B, whose
        // parent /A holds the reference whose target specializes /Q again.
        // The walk refuses it too, as an implied class (see the test above); the model on its own:
        let files = [
            (
                "root.usda",
                "def \"A\" (references = @./other.usda@</X>) {}\ndef \"Q\" (specializes = </A/B>) {}",
            ),
            ("other.usda", "def \"X\" (specializes = </Q>) {}"),
        ];
        let walk = check_files("precache_cycle", &files).unwrap_err().to_string();
        assert!(
            walk.starts_with("/X: specializes </Q> is a composition cycle"),
            "{walk}"
        );
        assert_eq!(
            precache_files("precache_model", &files).unwrap_err().to_string(),
            "/Q: specializes </A/B> is a composition cycle for openusd 0.6, whose pre-caching of inherit and \
             specialize targets would follow /Q -> /A/B -> /Q without end (a stack overflow)"
        );
    }

    #[test]
    fn class_targets_mapped_onto_their_own_prim_are_refused() {
        for (tag, stage, message) in [
            (
                "nested",
                "def \"A\" (inherits = [</X/Y>, </X>]) {}",
                "/A: inherits </X/Y> lies inside the target of /A's inherits </X>, which maps it onto /A/Y",
            ),
            (
                "reference",
                "def \"A\" (references = </X> specializes = </X/Y>) {}",
                "/A: specializes </X/Y> lies inside the target of /A's references </X>, which maps it onto /A/Y",
            ),
            (
                "ancestor",
                "def \"A\" (inherits = </X>) { def \"B\" (inherits = </X/B>) {} }",
                "/A/B: inherits </X/B> lies inside the target of /A's inherits </X>, which maps it onto /A/B",
            ),
            // A payload of a layer's default prim (here the root's own /X) maps the same way: the fuzz target's
            // `precache-overflow-e3e50b5a`, which overflowed `openusd`'s stack in 0.8 s.
            (
                "default_prim",
                "(\n defaultPrim = \"X\"\n)\ndef \"A\" (specializes = </X/A> payload = @./root.usda@) {}\n\
                 class \"X\" {}",
                "/A: specializes </X/A> lies inside the target of /A's payload @./root.usda@ (its default prim \
                 </X>), which maps it onto /A/A",
            ),
        ] {
            let err = check_files(tag, &[("root.usda", stage)]).unwrap_err().to_string();
            assert!(err.starts_with(message), "{err}");
        }
        // Mapped anywhere else, or not strictly inside, it composes (and `openusd` composes it).
        for (tag, stage) in [
            (
                "grandchild",
                "def \"A\" (references = </X> inherits = </X/Y/Z>) {}",
            ),
            (
                "sibling",
                "def \"A\" (inherits = </X>) { def \"B\" (inherits = </X/Q>) {} }",
            ),
            ("same", "def \"A\" (references = </X> inherits = </X>) {}"),
        ] {
            check_files(tag, &[("root.usda", stage)]).unwrap();
        }
    }

    #[test]
    fn class_hierarchies_references_and_variants_are_no_cycles() {
        let stage = r#"
class "_class_Char" { def "Geom" {} }
def "Chars" { def "Bob" (inherits = </_class_Char>) { def "Geom" {} } }
def "Looks" {
    def "Base" { def "Shader" {} }
    def "Red" (specializes = </Looks/Base>) { def "Shader" {} }
}
def "Proto" { def "Leaf" {} }
def "World" (variantSets = "v" references = @./asset.usda@) {
    def "A" (references = </Proto>) {}
    def "B" (references = </Proto>) {}
    variantSet "v" = { "x" (references = </Proto>) {} }
}
"#;
        let asset = "(\n defaultPrim = \"Asset\"\n)\ndef \"Asset\" (inherits = </_class_Char>) { def \"Geom\" {} }\n";
        check_files("valid", &[("root.usda", stage), ("asset.usda", asset)]).unwrap();
    }

    #[test]
    fn prims_are_counted_once_per_arc_that_brings_them_in() {
        // L<i> holds two children that reference L<i-1>: L0, L1, L2 and L3 compose 1, 5, 13 and 29 prims.
        let mut fan = String::from("def \"L0\" {}\n");
        for i in 1..=3 {
            fan.push_str(&format!(
                "def \"L{i}\" {{ def \"a\" (references = </L{p}>) {{}} def \"b\" (references = </L{p}>) {{}} }}\n",
                p = i - 1
            ));
        }
        let limit = |usd_prims| Limits {
            usd_prims,
            ..Limits::default()
        };
        check_with("fan_48", &[("root.usda", &fan)], limit(48)).unwrap();
        assert_eq!(
            check_with("fan_47", &[("root.usda", &fan)], limit(47)).unwrap_err().to_string(),
            "the stage composes 48 prims through its arcs and children (each counted once per arc that brings it \
             in), over the limit of 47 prims (raise it with --max-prims)"
        );
        let err = check_with("fan_20", &[("root.usda", &fan)], limit(20)).unwrap_err().to_string();
        assert!(err.starts_with("/L3 composes 29 prims"), "{err}");
    }

    /// Pixar's USD (usd-core 26.11) reports a sublayer cycle ("Sublayer hierarchy with root layer ... has
    /// cycles") on a layer stack whose layer names a layer it is itself a sublayer of; `openusd` 0.6 composed
    /// the fuzz target's stages with such stacks for minutes.
    #[test]
    fn a_sublayer_cycle_is_refused() {
        let files = [
            ("a.usda", "(\n subLayers = [@./b.usda@]\n)\n"),
            ("b.usda", "(\n subLayers = [@./c.usda@, @./a.usda@]\n)\n"),
            ("c.usda", "def \"C\" {}\n"),
        ];
        let err = check_files("sublayer_cycle", &files).unwrap_err().to_string();
        let cycle = "a.usda, a layer on the path of sublayers that leads to it (a sublayer cycle)";
        assert!(
            err.contains("a.usda: its subLayers lead back to a layer on their path: ")
                && err.contains("b.usda names ")
                && err.ends_with(cycle),
            "{err}"
        );
        // Through a reference too: the referenced layer stack of d names d itself.
        let files = [
            ("r.usda", "def \"A\" (references = @./d.usda@</D>) {}\n"),
            ("d.usda", "(\n subLayers = [@./d.usda@]\n)\ndef \"D\" {}\n"),
        ];
        let err = check_files("sublayer_self", &files).unwrap_err().to_string();
        let cycle = "d.usda, a layer on the path of sublayers that leads to it (a sublayer cycle)";
        assert!(err.contains("d.usda names ") && err.ends_with(cycle), "{err}");
        // A layer named twice is no cycle (Pixar's USD composes it with no error).
        let files = [
            ("t.usda", "(\n subLayers = [@./u.usda@, @./u.usda@]\n)\n"),
            ("u.usda", "def \"U\" {}\n"),
        ];
        check_files("sublayer_twice", &files).unwrap();
    }

    #[test]
    fn layer_stacks_count_every_naming_of_a_sublayer() {
        // a names b twice, b names c twice: 1 + 2 × (1 + 2) = 7 entries.
        let files = [
            ("a.usda", "(\n subLayers = [@./b.usda@, @./b.usda@]\n)\n"),
            ("b.usda", "(\n subLayers = [@./c.usda@, @./c.usda@]\n)\n"),
            ("c.usda", "def \"C\" {}\n"),
        ];
        let limit = |usd_layer_stack| Limits {
            usd_layer_stack,
            ..Limits::default()
        };
        check_with("stack_7", &files, limit(7)).unwrap();
        let err = check_with("stack_6", &files, limit(6)).unwrap_err().to_string();
        assert!(
            err.starts_with("the layer stack of ")
                && err.ends_with(
                    "a.usda expands to 7 layers (a sublayer named twice counts twice), over the limit of 6 \
                     (raise it with --max-sublayers)"
                ),
            "{err}"
        );
    }

    #[test]
    fn cycles_through_children_layers_and_parents_name_their_first_arc() {
        let err = check_files(
            "child",
            &[("root.usda", "def \"A\" { def \"C\" (inherits = </A>) {} }")],
        );
        assert_eq!(
            err.unwrap_err().to_string(),
            "/A/C: inherits </A> is a composition cycle (/A holds /A/C, /A/C inherits </A>)"
        );
        let err = check_files(
            "layers",
            &[
                ("a.usda", "def \"A\" (references = @./b.usda@</B>) {}"),
                ("b.usda", "def \"B\" (payload = @./a.usda@</A>) {}"),
            ],
        );
        assert_eq!(
            err.unwrap_err().to_string(),
            "/A: references @./b.usda@</B> is a composition cycle (/A references @./b.usda@</B>, \
             /B payload @./a.usda@</A>)"
        );
        let err = check_files(
            "inside",
            &[(
                "root.usda",
                "def \"A\" (references = </B>) {}\nclass \"B\" (specializes = </A/C>) {}",
            )],
        );
        assert_eq!(
            err.unwrap_err().to_string(),
            "/A: references </B> is a composition cycle (/A references </B>, /B specializes </A/C>, back inside /A)"
        );
        let err = check_files(
            "parent",
            &[(
                "root.usda",
                "def \"B\" (inherits = </D/E>) { def \"C\" {} }\nclass \"D\" (inherits = </B/C>) { def \"E\" {} }",
            )],
        );
        assert_eq!(
            err.unwrap_err().to_string(),
            "/D: inherits </B/C> is a composition cycle (/D/E is under /D, which inherits </B/C>, /B/C is under /B, \
             which inherits </D/E>)"
        );
    }
}
