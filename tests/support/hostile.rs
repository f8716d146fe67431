//! Shared by the mutation sweeps (`obj_mutations.rs`, `usd_mutations.rs`): a deterministic pseudo-random
//! sequence, and one damaged scene loaded, built and rendered on a worker thread, so that a panic is reported
//! with the case's label and a hang is detected.

use crate::common::splitmix as mix;
use nimbus::render::{RenderSettings, Renderer};
use nimbus::scene::{load_builder, LoadOptions};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

/// How long one case may take before it counts as a hang (detection only: cases take milliseconds).
const HANG: Duration = Duration::from_secs(10);

/// The byte ranges of the whitespace-separated tokens of `text`.
fn tokens(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, b) in text.iter().enumerate() {
        match (b.is_ascii_whitespace(), start) {
            (false, None) => start = Some(i),
            (true, Some(s)) => {
                out.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, text.len()));
    }
    out
}

/// The `i`-th mutation of `data` (not empty): a truncation, a byte flip, one of `replacements` in place of a
/// token, or a dropped token, in turn; with a description.
pub fn mutate(data: &[u8], i: u64, replacements: &[&str]) -> (Vec<u8>, String) {
    let r = mix(i);
    let spans = tokens(data);
    match i % 4 {
        0 => {
            let cut = (r % data.len() as u64) as usize;
            (data[..cut].to_vec(), format!("cut at {cut}"))
        }
        1 => {
            let at = (r % data.len() as u64) as usize;
            let mut d = data.to_vec();
            d[at] ^= 1 << (mix(r) % 8);
            (d, format!("bit flip at {at}"))
        }
        k => {
            let (s, e) = spans[(r % spans.len() as u64) as usize];
            let with = if k == 2 {
                replacements[(mix(r) % replacements.len() as u64) as usize]
            } else {
                ""
            };
            let mut d = data[..s].to_vec();
            d.extend_from_slice(with.as_bytes());
            d.extend_from_slice(&data[e..]);
            (d, format!("token at {s} replaced by '{with}'"))
        }
    }
}

/// What one case ended in.
#[derive(Debug, PartialEq, Eq)]
pub enum Outcome {
    /// It loaded, built and rendered without NaN.
    Rendered,
    /// The loader or the builder returned an error (one line of printable ASCII).
    Refused,
}

/// Loads `path`, and if it loads builds it and renders it at 8 × 8, 1 spp, on a worker thread. Panics (failing
/// the test) naming `label` if any step panics, takes longer than the hang limit, gives a multi-line or
/// non-ASCII error, or renders a NaN.
pub fn run_case(path: PathBuf, label: &str) -> Outcome {
    let (send, receive) = mpsc::channel();
    let thread_label = label.to_owned();
    std::thread::Builder::new()
        .name(format!("case {label}"))
        .spawn(move || {
            let _ = send.send(case(path, &thread_label));
        })
        .unwrap();
    match receive.recv_timeout(HANG) {
        Ok(outcome) => outcome,
        Err(mpsc::RecvTimeoutError::Timeout) => {
            panic!("{label}: no answer after {HANG:?} (a hang?)")
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => panic!("{label}: the loader panicked"),
    }
}

fn case(path: PathBuf, label: &str) -> Outcome {
    let scene = load_builder(&path, &LoadOptions::default()).and_then(|b| b.build());
    let scene = match scene {
        Ok(s) => s,
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.chars().all(|c| c.is_ascii_graphic() || c == ' '),
                "{label}: the error is not one printable line: {msg:?}"
            );
            return Outcome::Refused;
        }
    };
    let settings = RenderSettings {
        width: 8,
        height: 8,
        spp: 1,
        seed: 1,
        threads: 1,
        max_depth: 4,
        ..RenderSettings::default()
    };
    let (image, _) = Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap();
    assert!(
        image.beauty.iter().all(|p| !p.is_nan()),
        "{label}: the render has NaN pixels"
    );
    Outcome::Rendered
}
