//! The walk's cycle rules: arcs back into the run they extend (as the sites map them, and at the level of the
//! prims that author them), class targets mapped onto their own prim, and the error naming a cycle's steps.

use super::{inside, nested, parent, precache, Arc, CompositionError, Frame, Step, Walk};

impl<'a> Walk<'a> {
    /// The frame of the arc run that the step just taken from the top frame extends (the frames entered through
    /// arcs, and the prim they start from) whose site is nested with `next` (is, holds or lies inside it, in the
    /// same layer stack), if any: composing `next` would follow the run's arcs forever.
    pub(super) fn lands_in_run(&self, frames: &[Frame], next: usize) -> Option<usize> {
        let target = &self.sites[next];
        (run_start(frames)..frames.len()).find(|&i| nested(&self.sites[frames[i].site], target))
    }

    /// Like [`Walk::lands_in_run`], at the level of the prims that author the run's arcs (an ancestor's arc is
    /// authored above the site it maps): the frame whose prim at that level is nested with the target of the arc
    /// just followed to `next`, that prim, and the target.
    /// Walking back from the top, each arc's author lies inside the target of the arc before it and maps back
    /// through it. Pcp composes the ancestors' indices first and finds the cycle there, while the sites
    /// themselves may grow ever deeper and never nest (`openusd` 0.6 followed them for minutes).
    pub(super) fn lands_in_run_by_authors(
        &self,
        frames: &[Frame],
        next: usize,
    ) -> Option<(usize, String, String)> {
        let top = frames.len() - 1;
        let (mut level, lands) =
            self.author(&frames[top].last_step().1, &self.sites[frames[top].site].1)?;
        let lands = (self.sites[next].0, lands);
        for i in (run_start(frames)..top).rev() {
            let (author, target) =
                self.author(&frames[i].last_step().1, &self.sites[frames[i].site].1)?;
            level = precache::map(&level, &target, &author)?;
            if nested(&(self.sites[frames[i].site].0, level.clone()), &lands) {
                return Some((i, level, lands.1));
            }
        }
        None
    }

    /// Refuses a class-based arc of the prim at `path` whose target lies strictly inside the target of an arc
    /// (of any kind; its prim path, or its layer's default prim) of the prim or of an ancestor, in the same
    /// layer stack, and maps through it onto the prim itself or a child of it: a prim that inherits `/X` and
    /// `/X/Y`, or references `/X` and specializes `/X/Y`, or under one that inherits `/X`, a prim `B` that
    /// inherits `/X/B`. Such a stage composes in USD, but `openusd` 0.6 pre-caches the mapped path, finds the
    /// same arc there again and recurses until its stack overflows.
    pub(super) fn not_mapped_onto_itself(
        &self,
        stack: usize,
        path: &str,
    ) -> Result<(), CompositionError> {
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

    /// The error for a walk that closed a cycle by stepping to `site` from the top frame: the steps from frame
    /// `from` to the top, named by the first arc among them, and where the last lands when it is not on `from`'s
    /// site itself.
    pub(super) fn cycle(&self, frames: &[Frame], from: usize, site: usize) -> CompositionError {
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

/// Whether the step just taken from the top frame, back to `site` on the path, closes a cycle: the index of the
/// frame it starts from if the steps around are arcs and children (the site composes an arc back onto itself or
/// an ancestor), or inherits and specializes alone, its own or its parent's (the loop `openusd`'s pre-caching
/// follows). Around a parent's arc and a child or a reference the site composes a target path mapped below the
/// parent's, not the site itself, so that is no cycle.
pub(super) fn cycle_back(frames: &[Frame], site: usize) -> Option<usize> {
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
pub(super) fn run_start(frames: &[Frame]) -> usize {
    let mut start = frames.len() - 1;
    while start > 0 && frames[start - 1].last_step().1.follows_arc() {
        start -= 1;
    }
    start
}
