//! Why a stage's composition is refused ([`CompositionError`]), and the details of an implied class's cycle.

/// Why a stage's composition is refused before `openusd` composes it ([`check`](super::check)): what Pixar's USD refuses, what
/// `openusd` 0.6 would follow without end or for exponential time, and what passes the limits.
#[derive(Debug, thiserror::Error)]
pub(in crate::scene::usd) enum CompositionError {
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
    /// An arc authored inside a variant of the prim `path`, targeting a path inside `holder`, which has a variant
    /// set and composes `path` as `image` through `composing`.
    #[error(
        "{path}: {arc} (authored inside a variant) targets a path inside {holder}, which has a variant set and \
         composes {path} as {image} through its {composing}: openusd 0.6 re-composes that target through \
         {holder}'s variant ever deeper, up to 100 nested prim indices (seconds to minutes), so it is refused"
    )]
    VariantRecursion {
        path: String,
        arc: String,
        holder: String,
        composing: String,
        image: String,
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
    LayerStack {
        layer: String,
        entries: u64,
        max: u64,
    },
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
pub(in crate::scene::usd) struct ImpliedClassCycle {
    pub(super) class_arc: String,
    pub(super) through: String,
    pub(super) below: String,
    pub(super) referencing: String,
    pub(super) implied: String,
    pub(super) nested_with: String,
}
