//! The stage of the `usd_compose` fuzz target, built from the fuzz input: shared by the target
//! (`fuzz_targets/usd_compose.rs`) and its replay in `tests/suite/fuzz_regressions.rs`, so that a saved input composes
//! the same stage in both.
//!
//! The input is read one byte at a time (bytes past its end read as 0). It describes up to four text layers
//! `l0.usda` … `l3.usda`, the first the root. Each may name a default prim and up to three sublayers among the four
//! (itself, one layer twice, a ring: whatever the bytes say), and holds up to six prims nested up to three deep.
//! Prims are named from a small set so that arcs meet: each has a specifier (`def`, `over`, `class`), may be
//! `instanceable`, and has up to three arcs (inherits, specializes, references or payloads; internal, or to a layer
//! with or without a prim path) to paths built from the same names, authored on the prim or inside a selected
//! variant. Cycles, fan-out and diamonds of sublayers and arcs come easily.

use std::path::Path;

/// The names prims take and arc targets are built from.
const NAMES: [&str; 4] = ["A", "B", "C", "D"];

/// The arcs, as a layer spells them.
const ARCS: [&str; 4] = ["inherits", "specializes", "references", "payload"];

/// The limits the stage is loaded with: the defaults, with prim and layer-stack limits small enough that every
/// input runs in milliseconds (a stage within them that takes long is a finding).
fn limits() -> nimbus::limits::Limits {
    nimbus::limits::Limits {
        usd_prims: 20_000,
        usd_layer_stack: 64,
        ..nimbus::limits::Limits::with_memory(4 << 30)
    }
}

/// Writes the layers `data` describes into `dir`, then loads the root with [`limits`] and builds the scene: this
/// must end in `Ok` or `Err`, never a panic, an abort or a hang.
pub fn load(data: &[u8], dir: &Path) {
    for (name, text) in layers(data) {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let options = nimbus::scene::LoadOptions {
        limits: limits(),
        ..Default::default()
    };
    if let Ok(builder) = nimbus::scene::load_builder(&dir.join("l0.usda"), &options) {
        let _ = builder.build();
    }
}

/// Reads the input one byte at a time; bytes past its end read as 0.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
}

impl Bytes<'_> {
    /// The next byte, below `n`.
    fn below(&mut self, n: u8) -> usize {
        let byte = self.data.get(self.at).copied().unwrap_or(0);
        self.at += 1;
        (byte % n) as usize
    }

    /// A prim path of one to three names.
    fn path(&mut self) -> String {
        (0..=self.below(3))
            .map(|_| format!("/{}", NAMES[self.below(4)]))
            .collect()
    }
}

/// The layers the input describes, as (file name, text); the first is the root. All four are written, so that
/// arcs and sublayers always find their files: those the input leaves out are empty layers.
fn layers(data: &[u8]) -> Vec<(String, String)> {
    let mut bytes = Bytes { data, at: 0 };
    let count = 1 + bytes.below(4);
    (0..4)
        .map(|i| {
            let text = if i < count {
                layer(&mut bytes, count)
            } else {
                "#usda 1.0\n".to_owned()
            };
            (format!("l{i}.usda"), text)
        })
        .collect()
}

/// One layer: its metadata (default prim, sublayers), then its prims.
fn layer(bytes: &mut Bytes, count: usize) -> String {
    let mut text = String::from("#usda 1.0\n(\n");
    if bytes.below(2) == 1 {
        text.push_str(&format!(
            "    defaultPrim = \"{}\"\n",
            NAMES[bytes.below(4)]
        ));
    }
    let sublayers: Vec<String> = (0..bytes.below(4))
        .map(|_| format!("@./l{}.usda@", bytes.below(count as u8)))
        .collect();
    if !sublayers.is_empty() {
        text.push_str(&format!("    subLayers = [{}]\n", sublayers.join(", ")));
    }
    text.push_str(")\n");
    for _ in 0..bytes.below(7) {
        prim(bytes, count, 0, &mut text);
    }
    text
}

/// One prim at nesting `depth`, with its arcs and children, appended to `text`.
fn prim(bytes: &mut Bytes, count: usize, depth: usize, text: &mut String) {
    let indent = "    ".repeat(depth);
    let specifier = ["def", "over", "class"][bytes.below(3)];
    let name = NAMES[bytes.below(4)];
    let instanceable = bytes.below(4) == 0;
    let arcs = arcs(bytes, count);
    let in_variant = !arcs.is_empty() && bytes.below(4) == 0;
    let mut metadata = Vec::new();
    if instanceable {
        metadata.push("instanceable = true".to_owned());
    }
    if in_variant {
        metadata.push("variants = { string v = \"x\" }".to_owned());
        metadata.push("prepend variantSets = \"v\"".to_owned());
    } else {
        metadata.extend(arcs.iter().cloned());
    }
    text.push_str(&format!(
        "{indent}{specifier} Xform \"{name}\" ({})\n{indent}{{\n",
        metadata.join("\n")
    ));
    if in_variant {
        text.push_str(&format!(
            "{indent}    variantSet \"v\" = {{\n{indent}        \"x\" ({}) {{}}\n{indent}    }}\n",
            arcs.join("\n")
        ));
    }
    if depth < 2 {
        for _ in 0..bytes.below(3) {
            prim(bytes, count, depth + 1, text);
        }
    }
    text.push_str(&format!("{indent}}}\n"));
}

/// Up to three arcs, as list-op statements (`prepend inherits = [</A>]`), one per kind at most.
fn arcs(bytes: &mut Bytes, count: usize) -> Vec<String> {
    let mut targets: [Vec<String>; 4] = Default::default();
    for _ in 0..bytes.below(4) {
        let kind = bytes.below(4);
        let path = bytes.path();
        let target = if kind < 2 {
            format!("<{path}>")
        } else {
            match bytes.below(3) {
                0 => format!("<{path}>"),
                1 => format!("@./l{}.usda@<{path}>", bytes.below(count as u8)),
                _ => format!("@./l{}.usda@", bytes.below(count as u8)),
            }
        };
        targets[kind].push(target);
    }
    ARCS.iter()
        .zip(targets)
        .filter(|(_, t)| !t.is_empty())
        .map(|(arc, t)| format!("prepend {arc} = [{}]", t.join(", ")))
        .collect()
}
