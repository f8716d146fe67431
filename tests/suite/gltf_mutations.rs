//! Deterministic mutation sweep of the glTF loader (issue 14): the validation scenes and `assets/demo.glb`,
//! truncated, bit-flipped (the GLB binary chunk included) and edited as JSON (a number made huge, negative,
//! zero or 2³²; an index one past the end of its array; a key deleted; a node added to another's children),
//! by a fixed SplitMix64 sequence. Every case must end in `Ok` or `Err` without a panic; one that loads must
//! also build and render at 8×8, 1 spp with no NaN on the film. Each case runs on a worker thread, and one
//! that takes longer than [`HANG`] fails the test as a hang (a hang detector only, not a speed test).

use crate::common;

use common::splitmix as mix;
use nimbus::render::{RenderSettings, Renderer};
use nimbus::scene::{gltf, LoadOptions};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

/// A case still running after this long is reported as a hang.
const HANG: Duration = Duration::from_secs(10);

/// Mutated cases per input file.
const CASES_PER_FILE: u64 = 80;

/// A stream of pseudo-random numbers from one seed.
struct Stream(u64);

impl Stream {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(1);
        mix(self.0)
    }

    /// A number below `n` (which must be > 0).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// How a case ended, when it did not panic.
#[derive(Debug, PartialEq)]
enum Outcome {
    LoadError,
    BuildError,
    Rendered,
}

/// Loads, builds and renders `bytes` as the file `path` on a worker thread, and panics, naming the case, if
/// that panics, hangs or puts a NaN on the film.
fn run_case(bytes: Vec<u8>, path: PathBuf, label: String) -> Outcome {
    let (send, receive) = mpsc::channel();
    let worker_label = label.clone();
    std::thread::spawn(move || {
        let outcome = std::panic::catch_unwind(move || {
            let Ok(builder) = gltf::load_slice(&bytes, &path, &LoadOptions::default()) else {
                return Ok(Outcome::LoadError);
            };
            let Ok(scene) = builder.build() else {
                return Ok(Outcome::BuildError);
            };
            let settings = RenderSettings {
                width: 8,
                height: 8,
                spp: 1,
                threads: 1,
                max_depth: 8,
                ..RenderSettings::default()
            };
            let (image, _) = Renderer::new(settings)
                .render(&scene, &mut |_| true)
                .map_err(|e| format!("render failed: {e}"))?;
            if let Some(p) = image.beauty.iter().position(|c| c.is_nan()) {
                return Err(format!("pixel {p} is NaN"));
            }
            Ok(Outcome::Rendered)
        });
        let _ = send.send(outcome.map_err(|_| format!("{worker_label}: panicked")));
    });
    match receive.recv_timeout(HANG) {
        Ok(Ok(Ok(outcome))) => outcome,
        Ok(Ok(Err(problem))) => panic!("{label}: {problem}"),
        Ok(Err(panic)) => panic!("{panic}"),
        Err(_) => panic!("{label}: still running after {HANG:?} (a hang?)"),
    }
}

/// A GLB container's JSON and binary chunks, or `None` for a `.gltf` (JSON) file.
fn split_glb(bytes: &[u8]) -> Option<(Value, Vec<u8>)> {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    if !bytes.starts_with(b"glTF") {
        return None;
    }
    let json_len = word(12);
    let json = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin = bytes[bin_at + 8..bin_at + 8 + word(bin_at)].to_vec();
    Some((json, bin))
}

/// A GLB container holding `json` and `bin`.
fn join_glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    j.resize(j.len().next_multiple_of(4), b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().next_multiple_of(4), 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = b"glTF".to_vec();
    for w in [2, total, j.len()] {
        out.extend_from_slice(&(w as u32).to_le_bytes());
    }
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// JSON pointers to every number, and to every object member, in `v`.
fn pointers(v: &Value, at: &str, numbers: &mut Vec<String>, members: &mut Vec<String>) {
    match v {
        Value::Number(_) => numbers.push(at.to_owned()),
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                pointers(item, &format!("{at}/{i}"), numbers, members);
            }
        }
        Value::Object(map) => {
            for (k, item) in map {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                members.push(p.clone());
                pointers(item, &p, numbers, members);
            }
        }
        _ => {}
    }
}

/// The top-level array a number at `pointer` indexes, judged by its key.
fn indexed_array(pointer: &str) -> Option<&'static str> {
    let mut parts = pointer.rsplit('/');
    let last = parts.next()?;
    let key = if last.parse::<usize>().is_ok() {
        parts.next()?
    } else {
        last
    };
    Some(match key {
        "bufferView" => "bufferViews",
        "buffer" => "buffers",
        "source" => "images",
        "sampler" => "samplers",
        "index" => "textures",
        "mesh" => "meshes",
        "camera" => "cameras",
        "material" => "materials",
        "scene" => "scenes",
        "children" | "nodes" | "node" | "joints" | "skeleton" => "nodes",
        "indices" | "input" | "output" | "POSITION" | "NORMAL" | "TANGENT" | "TEXCOORD_0"
        | "TEXCOORD_1" | "COLOR_0" => "accessors",
        _ => return None,
    })
}

/// Replacement numbers: overflowing (to ∞ as an `f32`), negative, zero, 2³² and non-integer.
const NUMBERS: [f64; 7] = [1e308, -1.0, 4_294_967_296.0, 0.0, -1e39, 0.5, 1e39];

/// One JSON-aware edit of `doc`; returns what it did.
fn edit_json(doc: &mut Value, r: &mut Stream) -> String {
    let (mut numbers, mut members) = (Vec::new(), Vec::new());
    pointers(doc, "", &mut numbers, &mut members);
    match r.below(4) {
        0 => {
            let p = &numbers[r.below(numbers.len())];
            let n = NUMBERS[r.below(NUMBERS.len())];
            *doc.pointer_mut(p).unwrap() = serde_json::json!(n);
            format!("{p} = {n}")
        }
        1 => {
            let indices: Vec<_> = numbers
                .iter()
                .filter_map(|p| Some((p, indexed_array(p)?)))
                .collect();
            let (p, array) = indices[r.below(indices.len())];
            let len = doc[array].as_array().map_or(0, Vec::len);
            *doc.pointer_mut(p).unwrap() = serde_json::json!(len);
            format!("{p} = {len} (one past the end of {array})")
        }
        2 => {
            let p = &members[r.below(members.len())];
            let (parent, key) = p.rsplit_once('/').unwrap();
            let key = key.replace("~1", "/").replace("~0", "~");
            if let Some(obj) = doc.pointer_mut(parent).and_then(Value::as_object_mut) {
                obj.remove(&key);
            }
            format!("{p} deleted")
        }
        _ => {
            let n = doc["nodes"].as_array().map_or(0, Vec::len);
            if n == 0 {
                return "no nodes to edit".into();
            }
            let (child, parent) = (r.below(n), r.below(n));
            let node = &mut doc["nodes"][parent];
            match node.get_mut("children").and_then(Value::as_array_mut) {
                Some(c) => c.push(serde_json::json!(child)),
                None => node["children"] = serde_json::json!([child]),
            }
            format!("nodes[{child}] added to the children of nodes[{parent}]")
        }
    }
}

/// The mutated bytes of case `i` of `bytes`, and what was done.
fn mutate(bytes: &[u8], i: u64) -> (Vec<u8>, String) {
    let mut r = Stream(mix(i));
    match r.below(3) {
        0 => {
            let cut = r.below(bytes.len());
            (bytes[..cut].to_vec(), format!("truncated at {cut}"))
        }
        1 => {
            let mut b = bytes.to_vec();
            // A quarter of the flips in the first 32 bytes: the GLB header and chunk headers, or the JSON's start.
            let at = if r.below(4) == 0 {
                r.below(b.len().min(32))
            } else {
                r.below(b.len())
            };
            let bit = r.below(8);
            b[at] ^= 1 << bit;
            (b, format!("bit {bit} of byte {at} flipped"))
        }
        _ => match split_glb(bytes) {
            Some((mut json, bin)) => {
                let what = edit_json(&mut json, &mut r);
                (join_glb(&json, &bin), what)
            }
            None => {
                let mut json: Value = serde_json::from_slice(bytes).unwrap();
                let what = edit_json(&mut json, &mut r);
                (serde_json::to_vec(&json).unwrap(), what)
            }
        },
    }
}

#[test]
fn mutated_scenes_never_panic_hang_or_render_nan() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let mut inputs: Vec<PathBuf> = std::fs::read_dir(shared.join("validation"))
        .unwrap()
        .map(|e| e.unwrap().path().join("scene.gltf"))
        .filter(|p| p.is_file())
        .collect();
    inputs.sort();
    assert!(!inputs.is_empty(), "no validation scenes");
    inputs.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/demo.glb"));
    let mut tally = [0usize; 3];
    for (f, path) in inputs.iter().enumerate() {
        let bytes = std::fs::read(path).unwrap();
        let name = path
            .strip_prefix(&shared)
            .unwrap_or(path)
            .display()
            .to_string();
        // The unmutated file must render, or the sweep tests nothing.
        let original = run_case(bytes.clone(), path.clone(), name.clone());
        assert_eq!(original, Outcome::Rendered, "{name}");
        for i in 0..CASES_PER_FILE {
            let case = (f as u64) << 32 | i;
            let (mutated, what) = mutate(&bytes, case);
            let outcome = run_case(mutated, path.clone(), format!("{name} case {i}: {what}"));
            tally[outcome as usize] += 1;
        }
    }
    eprintln!(
        "glTF mutations: {} load errors, {} build errors, {} rendered",
        tally[0], tally[1], tally[2]
    );
    common::assert_sweep_peak_memory("glTF sweep");
}
