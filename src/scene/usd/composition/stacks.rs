//! Layer stacks as the walk enters them: each counted as `openusd` builds it (a sublayer named twice counts
//! twice, a sublayer cycle refused) and its layers' prims merged.

use super::{CompositionError, Prim, Stack, Walk};
use std::collections::{HashMap, HashSet};

impl<'a> Walk<'a> {
    /// The index of the layer stack whose root is `layer`, counting its entries against the limit and merging
    /// its layers' prims the first time.
    pub(super) fn stack(&mut self, layer: usize) -> Result<usize, CompositionError> {
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
                merged.variants |= prim.variants;
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
    pub(super) fn members(&self, layer: usize) -> Vec<usize> {
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
    pub(super) fn sublayers(&self, layer: usize) -> &'a [usize] {
        self.layers.layers[layer]
            .as_ref()
            .map_or(&[][..], |l| l.sublayers.as_slice())
    }

    /// The entries the layer stack whose root is `layer` expands to, as `openusd` builds it: the layer, then each
    /// sublayer's own entries in turn. Counted without recursion, each layer once (a layer's count is kept for
    /// every stack that names it), saturating. A sublayer already on the path is a sublayer cycle, which Pixar's
    /// USD reports as a composition error ("Sublayer hierarchy ... has cycles"), and is refused.
    pub(super) fn entries(&mut self, layer: usize) -> Result<u64, CompositionError> {
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
}
