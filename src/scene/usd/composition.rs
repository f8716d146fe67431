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

mod cycles;
mod error;
mod implied;
mod layers;
mod precache;
mod stacks;
#[cfg(test)]
mod tests;
mod variants;

use cycles::{cycle_back, run_start};
pub(super) use error::CompositionError;
use error::ImpliedClassCycle;
use implied::propagate_specializes;
use layers::{Arc, ArcKind, Layers, Prim};

use super::crate_check::CheckingResolver;
use crate::limits::Limits;
use std::collections::{HashMap, HashSet};
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
            Step::Arc(arc)
            | Step::ParentArc(arc)
            | Step::AncestorArc(arc, _)
            | Step::Implied(arc) => Some(arc),
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
            Step::Implied(arc) => {
                return Some(format!("{at}: {} (an implied class)", arc.describe()))
            }
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
    /// and arcs, as many as the prims counted, for arcs back into the chain they extend (see [`Walk::unfold`]),
    /// and last the arcs inside variants of the sites walked (see [`Walk::no_variant_recursion`]).
    fn run(&mut self, root: usize) -> Result<(), CompositionError> {
        let start = (self.stack(root)?, "/".to_owned());
        let start = self.site(start);
        self.count(start)?;
        self.unfold(start)?;
        self.no_variant_recursion()
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
                    if let Some((from, level, target)) = self.lands_in_run_by_authors(&frames, next)
                    {
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
