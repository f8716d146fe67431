//! Arcs authored inside variants that `openusd` 0.6 re-composes through another prim's variant ever deeper.
//!
//! `openusd`'s indexer composes an arc's target below a root prim as a sub-index of its own, skipping variants,
//! and when it grafts that sub-index re-evaluates the variant sets above each grafted node (Pcp's ancestral
//! variants) as sub-indices again. For a prim `R` with a variant set and an arc to a prim `A`, whose child `P`
//! bears `R`'s own name and authors an arc inside a variant to a path inside `R`, each such turn composes the
//! target again one level deeper (`/C/B/D`, `/C{v=x}B/D/B/D`, ...), which `openusd`'s cycle check does not stop
//! (no site repeats), until its depth limit of 100 nested indices: `fuzz/open` stage `cc20016f` composed for
//! 19-23 s, and variations of it for 0.1 s to past 10 s, while Pixar's USD composes them in 0.03 s or less. With
//! either arc outside its variant, `R` without variants, `P` named otherwise or deeper below `A`, or the target
//! outside `R`, `openusd` composes them in milliseconds; those load as before. A target inside `P`'s own image
//! in `R` (`R` with `P`'s path below `A`) recurses the same way, and is an arc cycle the walk refuses already.

use super::{parent, Arc, CompositionError, Walk};

impl<'a> Walk<'a> {
    /// Applies [`Walk::variant_recursion_at`] to every site the walk stepped from, after the walk's other rules
    /// (a stage they refuse keeps their message).
    pub(super) fn no_variant_recursion(&self) -> Result<(), CompositionError> {
        let walked = self
            .sites
            .iter()
            .zip(&self.steps)
            .filter(|(_, steps)| steps.is_some());
        for ((stack, path), _) in walked {
            self.variant_recursion_at(*stack, path)?;
        }
        Ok(())
    }

    /// Refuses an arc of the prim at `path`, authored inside a variant and targeting its own layer stack, whose
    /// target lies strictly inside a prim `R` of that stack that has a variant set, bears the prim's name, and
    /// authors an arc (to the same stack) to the prim's parent.
    fn variant_recursion_at(&self, stack: usize, path: &str) -> Result<(), CompositionError> {
        let prims = &self.stacks[stack].prims;
        let Some(own) = prims.get(path) else {
            return Ok(());
        };
        let name = path.rsplit('/').next().unwrap_or(path);
        let here = |arc: &&Arc| self.in_stack(stack, arc);
        for arc in own.arcs.iter().filter(|a| a.in_variant).filter(here) {
            let Some(target) = self.target_path(arc) else {
                continue;
            };
            let mut holder = parent(&target);
            while holder != "/" {
                let named = holder.rsplit('/').next() == Some(name);
                if let Some(r) = prims.get(holder).filter(|r| named && r.variants) {
                    let composing = r
                        .arcs
                        .iter()
                        .filter(here)
                        .find(|a| self.target_path(a).as_deref() == Some(parent(path)));
                    if let Some(composing) = composing {
                        return Err(CompositionError::VariantRecursion {
                            path: path.to_owned(),
                            arc: arc.describe(),
                            holder: holder.to_owned(),
                            composing: composing.describe(),
                            image: format!("{holder}/{name}"),
                        });
                    }
                }
                holder = parent(holder);
            }
        }
        Ok(())
    }
}
