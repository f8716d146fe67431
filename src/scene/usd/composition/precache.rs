//! The pre-caching of inherit and specialize targets that `openusd` 0.6 runs as it composes each prim
//! (`IndexCache::precache_inherit_targets`), modelled on prim paths so that a stage on which it would recurse
//! without end, or for exponential time, is refused before the stage is opened.
//!
//! For a prim `T` with parent `P`, `openusd` reads the inherit and specialize targets authored at every site of
//! `P` (its path in its own namespace and in each namespace an arc maps onto it) and at those sites' child named
//! like `T`. It takes each target as a path of the stage, whatever layer stack authored it, adds the target
//! mapped through the arcs of `P`'s ancestors, composes each (its ancestors first, each pre-caching its own
//! targets as it is composed), and recurses into each target the same way, remembering none. A target that leads back to itself recurses until the stack overflows; targets that lead
//! to one another in a diamond are followed once per path.
//!
//! The model over-approximates: every layer's prims are merged into one namespace (so a target authored in a
//! referenced layer stack is met under the stage path it names, as `openusd` takes it), every arc anywhere maps
//! namespaces, and variants count whichever is selected. A cycle of targets is refused as a composition cycle,
//! and a target that leads to more targets (counted per path, as the recursion follows them) than the prim
//! limit is refused with the prim limit's message.

use super::{inside, parent, ArcKind, CompositionError, Layers};
use std::collections::{HashMap, HashSet};
use std::rc::Rc;

/// The most sites of one prim the model follows through arc maps: a bound on the model's own work. Sites past
/// it are left out (the stages the model guards against need a few).
const MAX_SITES: usize = 4096;

/// The most children composed through sites (beyond the authored and once-mapped prims) the model starts from:
/// a bound on the model's own work, which grows with each level of children (the stages it guards against need
/// a few). Those past it are left out, as sites past [`MAX_SITES`] are.
const MAX_COMPOSED_CHILDREN: usize = 4096;

/// An inherit or specialize arc: the prim that authors it, its kind, its target.
#[derive(Clone)]
struct ClassArc {
    at: String,
    kind: ArcKind,
    target: String,
}

/// The targets pre-cached for a path, each with the arc that gives it.
type Targets = Rc<[(String, ClassArc)]>;

/// A prim's sites, in the order found, and as a set.
type Sites = (Vec<String>, HashSet<String>);

/// A path the model is following: its targets, how many have been taken, and the targets counted so far.
type Frame = (String, Targets, usize, u64);

/// The stage's prim paths, merged over every layer read, with the arcs the pre-caching follows.
pub(super) struct Precache {
    /// Inherit and specialize arcs by the prim that authors them.
    class: HashMap<String, Vec<ClassArc>>,
    /// The parents of the prims that author inherit and specialize arcs.
    class_parents: HashSet<String>,
    /// Every arc as a namespace map, by the prim that authors it: the target paths it maps onto that prim.
    maps: HashMap<String, Vec<String>>,
    /// Every authored prim path, and each mapped once through an arc: where the pre-caching starts.
    prims: Vec<String>,
    /// The deepest prim path authored or targeted, in path elements: sites deeper than twice this are left out.
    depth: usize,
    /// The names of the children authored under each prim path, in any layer.
    children: HashMap<String, Vec<String>>,
    /// Each prim's sites, once found.
    sites: HashMap<String, Rc<Sites>>,
    /// Each path's targets (and the arc that gives each), once found.
    targets: HashMap<String, Targets>,
}

/// The elements of a prim path (`/` has none).
pub(super) fn depth(path: &str) -> usize {
    path.matches('/').count() - usize::from(path == "/")
}

/// `path` moved from under `from` to under `to`, when it is `from` or lies inside it.
pub(super) fn map(path: &str, from: &str, to: &str) -> Option<String> {
    if path == from {
        Some(to.to_owned())
    } else if inside(path, from) {
        let rest = &path[from.len()..];
        Some(if to == "/" {
            rest.to_owned()
        } else {
            format!("{to}{rest}")
        })
    } else {
        None
    }
}

/// `path` and its ancestors, the path first, `/` left out.
pub(super) fn ancestors(path: &str) -> impl Iterator<Item = &str> {
    std::iter::successors(Some(path), |p| Some(parent(p))).take_while(|p| *p != "/")
}

impl Precache {
    /// The model of every layer in `layers`.
    pub(super) fn new(layers: &Layers) -> Self {
        let mut model = Self {
            class: HashMap::new(),
            class_parents: HashSet::new(),
            maps: HashMap::new(),
            prims: Vec::new(),
            depth: layers.deepest_path(),
            children: HashMap::new(),
            sites: HashMap::new(),
            targets: HashMap::new(),
        };
        let mut seen = HashSet::new();
        for layer in layers.layers.iter().flatten() {
            for (path, prim) in &layer.prims {
                if path != "/" && seen.insert(path.clone()) {
                    model.prims.push(path.clone());
                    let name = &path[path.rfind('/').map_or(0, |at| at + 1)..];
                    let children = model.children.entry(parent(path).to_owned()).or_default();
                    children.push(name.to_owned());
                }
                for arc in &prim.arcs {
                    let target = match (arc.layer, arc.path.is_empty()) {
                        (Some(layer), true) => layers.layers[layer]
                            .as_ref()
                            .and_then(|l| l.default_prim.clone()),
                        (None, true) => None,
                        (_, false) => Some(arc.path.clone()),
                    };
                    let Some(target) = target else { continue };
                    // A default prim's path, which `deepest_path` does not see in the arc.
                    model.depth = model.depth.max(depth(&target));
                    let maps = model.maps.entry(path.clone()).or_default();
                    if !maps.contains(&target) {
                        maps.push(target.clone());
                    }
                    if arc.kind.is_class() {
                        model.class.entry(path.clone()).or_default().push(ClassArc {
                            at: path.clone(),
                            kind: arc.kind,
                            target,
                        });
                    }
                }
            }
        }
        model.class_parents = model.class.keys().map(|at| parent(at).to_owned()).collect();
        // A class target is a path of the layer stack that authors it, which the arcs of the author's ancestors
        // map into the stage (Pcp composes the class there): the prim's arc maps its namespace onto that path
        // too. `openusd` adds the class node there and maps pre-cached targets through it.
        let mut composed_targets = Vec::new();
        for (at, arcs) in &model.class {
            for arc in arcs {
                for ancestor in ancestors(at).skip(1) {
                    for from in model.maps.get(ancestor).into_iter().flatten() {
                        if let Some(mapped) = map(&arc.target, from, ancestor) {
                            composed_targets.push((at.clone(), mapped));
                        }
                    }
                }
            }
        }
        for (at, mapped) in composed_targets {
            let maps = model.maps.entry(at).or_default();
            if !maps.contains(&mapped) {
                maps.push(mapped);
            }
        }
        // Prims composed through an arc are pre-cached too: each authored prim mapped once onto every prim
        // whose arc targets it or an ancestor.
        let mut mapped = Vec::new();
        for (at, targets) in &model.maps {
            for target in targets {
                for prim in &model.prims {
                    if let Some(path) = map(prim, target, at) {
                        if seen.insert(path.clone()) {
                            mapped.push(path);
                        }
                    }
                }
            }
        }
        model.prims.extend(mapped);
        model.prims.sort_unstable();
        model
    }

    /// Refuses a cycle of pre-cached targets, and a path from which the pre-caching follows more than
    /// `max_prims` targets.
    pub(super) fn check(&mut self, max_prims: u64) -> Result<(), CompositionError> {
        if self.class.is_empty() {
            return Ok(());
        }
        // The targets followed from each path, counting itself; `None` while it is being followed.
        let mut counted: HashMap<String, Option<u64>> = HashMap::new();
        // Where the pre-caching starts: every prim, then the ancestors of every target followed, which
        // `openusd` composes before the target (each pre-caching its own targets as it is composed).
        let mut starts = self.prims.clone();
        // The children each start composes through its sites are starts too (`openusd` composes each prim's
        // children as the stage is read), each once, [`MAX_COMPOSED_CHILDREN`] of them at most.
        let mut started: HashSet<String> = starts.iter().cloned().collect();
        let max_starts = starts.len() + MAX_COMPOSED_CHILDREN;
        let mut next_start = 0;
        while let Some(start) = starts.get(next_start).cloned() {
            next_start += 1;
            for child in self.composed_children(&start) {
                if started.len() < max_starts && started.insert(child.clone()) {
                    starts.push(child);
                }
            }
            if counted.contains_key(&start) {
                continue;
            }
            counted.insert(start.clone(), None);
            // (path, its targets, how many taken, the count so far).
            let mut frames = vec![(start.clone(), self.targets_of(&start), 0usize, 1u64)];
            while let Some(top) = frames.last_mut() {
                let Some((next, _)) = top.1.get(top.2).cloned() else {
                    let (done, _, _, count) = frames.pop().expect("a frame");
                    if count > max_prims {
                        return Err(CompositionError::Precache {
                            max_prims,
                            from: done,
                        });
                    }
                    counted.insert(done, Some(count));
                    if let Some(parent) = frames.last_mut() {
                        parent.3 = parent.3.saturating_add(count);
                    }
                    continue;
                };
                top.2 += 1;
                match counted.get(&next) {
                    Some(Some(count)) => top.3 = top.3.saturating_add(*count),
                    Some(None) => return Err(cycle(&frames, &next)),
                    None => {
                        counted.insert(next.clone(), None);
                        starts.extend(ancestors(&next).skip(1).map(str::to_owned));
                        let targets = self.targets_of(&next);
                        frames.push((next, targets, 0, 1));
                    }
                }
            }
        }
        Ok(())
    }

    /// The children prim `path` composes through its sites: each child authored at one of them, named under
    /// `path`, deeper paths than the sites' bound left out.
    fn composed_children(&mut self, path: &str) -> Vec<String> {
        let max_depth = 2 * self.depth + 2;
        if depth(path) >= max_depth {
            return Vec::new();
        }
        let mut children = Vec::new();
        for site in &self.sites_of(path).0 {
            for child in self.children.get(site).into_iter().flatten() {
                let composed = if path == "/" {
                    format!("/{child}")
                } else {
                    format!("{path}/{child}")
                };
                if !children.contains(&composed) {
                    children.push(composed);
                }
            }
        }
        children
    }

    /// The sites of prim `path`: itself, and the paths the arcs of it and its ancestors (in any of its sites)
    /// map onto it, in turn.
    fn sites_of(&mut self, path: &str) -> Rc<Sites> {
        if let Some(sites) = self.sites.get(path) {
            return sites.clone();
        }
        // The sites of the path's strict ancestors, each with the ancestor: a class target inside one of them
        // is composed at the ancestor too (mapped back through the arcs that led there).
        let above: Vec<(String, Rc<Sites>)> = ancestors(path)
            .skip(1)
            .map(|ancestor| (ancestor.to_owned(), self.sites_of(ancestor)))
            .collect();
        let max_depth = 2 * self.depth + 2;
        let mut sites = vec![path.to_owned()];
        let mut seen = HashSet::from([path.to_owned()]);
        let mut next = 0;
        while let Some(site) = sites.get(next).cloned() {
            next += 1;
            let mut found = Vec::new();
            for ancestor in ancestors(&site) {
                for target in self.maps.get(ancestor).into_iter().flatten() {
                    found.extend(map(&site, ancestor, target));
                }
            }
            // Pcp's implied classes: a class arc met at a site reached through arcs is also composed with its
            // target mapped back through them, onto the path or an ancestor of it (`openusd` adds that node and
            // the nodes of its own arcs to the index, and maps pre-cached targets through them).
            // Only a site that is the target or holds it maps it: each of the target's ancestors looked up.
            for arc in self.class.get(&site).into_iter().flatten() {
                for (ancestor, its_sites) in std::iter::once((path, &seen))
                    .chain(above.iter().map(|(a, s)| (a.as_str(), &s.1)))
                {
                    for from in ancestors(&arc.target) {
                        if from != ancestor && its_sites.contains(from) {
                            found.extend(map(&arc.target, from, ancestor));
                        }
                    }
                }
            }
            for mapped in found {
                if sites.len() < MAX_SITES
                    && depth(&mapped) <= max_depth
                    && seen.insert(mapped.clone())
                {
                    sites.push(mapped);
                }
            }
        }
        let sites = Rc::new((sites, seen));
        self.sites.insert(path.to_owned(), sites.clone());
        sites
    }

    /// The targets pre-cached for prim `path`, each with the arc that gives it: the inherit and specialize
    /// targets authored at each site of its parent and at that site's child named like `path`, as authored,
    /// mapped from each arc target of the sites' ancestors back onto them, and mapped from each site of the
    /// parent's ancestors (the parent too) back onto that ancestor (a chain of arcs, as `openusd` composes
    /// their maps).
    fn targets_of(&mut self, path: &str) -> Targets {
        if let Some(targets) = self.targets.get(path) {
            return targets.clone();
        }
        let name = &path[path.rfind('/').map_or(0, |at| at + 1)..];
        let sites = self.sites_of(parent(path));
        // Each ancestor of the parent (the parent too) with its sites: a target inside a site maps back onto
        // the ancestor through the whole chain of arcs that led to the site.
        let ancestor_sites: Vec<(String, Rc<Sites>)> = ancestors(parent(path))
            .map(|ancestor| (ancestor.to_owned(), self.sites_of(ancestor)))
            .collect();
        // The arcs of the sites' ancestors as (target, ancestor) pairs, each once: a target inside the arc's
        // target maps back onto the ancestor.
        let mut scope_maps: Vec<(&str, &str)> = Vec::new();
        let mut scope_seen = HashSet::new();
        for scope in &sites.0 {
            for ancestor in ancestors(scope) {
                for from in self.maps.get(ancestor).into_iter().flatten() {
                    if scope_seen.insert((from.as_str(), ancestor)) {
                        scope_maps.push((from, ancestor));
                    }
                }
            }
        }
        let mut targets: Vec<(String, ClassArc)> = Vec::new();
        let mut seen = HashSet::new();
        let mut add = |target: String, arc: &ClassArc| {
            if seen.insert(target.clone()) {
                targets.push((target, arc.clone()));
            }
        };
        // Only sites that author a class arc, or whose child does, give targets: the others are passed over
        // before a child path is made.
        let relevant = sites.0.iter().filter(|site| {
            self.class.contains_key(site.as_str()) || self.class_parents.contains(site.as_str())
        });
        for site in relevant {
            let child = if site == "/" {
                format!("/{name}")
            } else {
                format!("{site}/{name}")
            };
            for at in [site.as_str(), child.as_str()] {
                for arc in self.class.get(at).into_iter().flatten() {
                    add(arc.target.clone(), arc);
                    for &(from, ancestor) in &scope_maps {
                        if let Some(mapped) = map(&arc.target, from, ancestor) {
                            add(mapped, arc);
                        }
                    }
                    for (ancestor, its_sites) in &ancestor_sites {
                        for site in ancestors(&arc.target) {
                            if site != ancestor && its_sites.1.contains(site) {
                                add(map(&arc.target, site, ancestor).expect("inside"), arc);
                            }
                        }
                    }
                }
            }
        }
        let targets: Targets = targets.into();
        self.targets.insert(path.to_owned(), targets.clone());
        targets
    }
}

/// The error for a pre-caching that reached `path` again while following it: the targets from `path` round to
/// it, named by the arc that first leads back.
fn cycle(frames: &[Frame], path: &str) -> CompositionError {
    let from = frames.iter().position(|f| f.0 == path).unwrap_or(0);
    let chain: Vec<&str> = frames[from..]
        .iter()
        .map(|f| f.0.as_str())
        .chain([path])
        .collect();
    let arc = &frames[from].1[frames[from].2 - 1].1;
    CompositionError::PrecacheCycle {
        at: arc.at.clone(),
        kind: arc.kind.name(),
        target: arc.target.clone(),
        chain: chain.join(" -> "),
    }
}
