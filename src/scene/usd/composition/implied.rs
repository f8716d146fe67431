//! Pcp's implied classes and propagated specializes in the walk: class arcs met below a reference carried onto
//! the referencing layer stack (walked for their work, refused when they land back in the run), and specializes
//! copied to the root of their prim index.

use super::{
    inside, nested, precache, run_start, Arc, ArcKind, CompositionError, Frame, ImpliedClassCycle,
    Step, Walk,
};

impl<'a> Walk<'a> {
    /// Carries the class-based arc just followed from the top frame to `next` onto the layer stack of the
    /// nearest reference or payload below which it is met (through arcs and children), as Pcp's implied classes
    /// do: its target mapped through the reference (a target outside the referenced prim keeps its path, Pcp's
    /// root identity) becomes a step of the referencing frame, walked with its own arcs after that frame's own
    /// steps, and carried further up when it is followed. Pcp builds each of these nodes with the nodes its
    /// arcs bring, at every reference above the class arc, so that a few class arcs below references that fan
    /// out make exponentially many; the walk counts them as steps against the same limit.
    pub(super) fn imply_class(&mut self, frames: &mut [Frame], next: usize) {
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
            in_variant: arc.in_variant,
        };
        let site = self.site((*stack, path));
        let frame = &mut frames[through];
        if frame.implied_sites.insert(site) {
            frame.implied.push((site, Step::Implied(implied)));
        }
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
    pub(super) fn implied_class_in_run(
        &self,
        frames: &[Frame],
        next: usize,
    ) -> Result<(), CompositionError> {
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
        Err(CompositionError::ImpliedClass(Box::new(
            ImpliedClassCycle {
                class_arc: class_arc.unwrap_or_default(),
                through: describe(&frames[through]),
                below: describe(top),
                referencing,
                implied,
                nested_with: self.sites[frames[from].site].1.clone(),
            },
        )))
    }

    /// The prim that authors the arc `step` follows from the site at `at` (the site's own path, or the ancestor
    /// whose arc it is), with the arc's target path; `None` for a child, a parent's arc, or a layer's default
    /// prim that is not authored.
    pub(super) fn author(&self, step: &Step, at: &str) -> Option<(String, String)> {
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
    pub(super) fn implied_class_below_children(
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
        Err(CompositionError::ImpliedClass(Box::new(
            ImpliedClassCycle {
                class_arc: class_arc.unwrap_or_default(),
                through: step.describe(referencing, source),
                below: format!("{} composes {composed}", self.sites[top.site].1),
                referencing: referencing.clone(),
                implied,
                nested_with: composed,
            },
        )))
    }
}

/// Copies the specializes arc just followed from the top frame to `next` to the root of the prim index it lies
/// in, as Pcp propagates every specializes node below the root (with its subtree) to the root: a step of the
/// deepest frame reached from the pseudo-root through children alone (the prim whose index it is, or the
/// ancestor under which the walk composes it), taken after that frame's own steps. The copy, at the root, is
/// not propagated again.
pub(super) fn propagate_specializes(frames: &mut [Frame], next: usize) {
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
