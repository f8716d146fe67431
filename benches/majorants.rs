//! Majorant benchmark: Global vs Grid16 vs Adaptive majorants for delta and ratio tracking through VDB grids, and
//! how close `auto` (the pilot of `nimbus::volume::majorant_choice`) comes to the fastest.
//!
//! `cargo bench --bench majorants -- [FILE.vdb ...] [--rays N] [--tau T[,T...]] [--kind KIND] [--csv]
//! [--chart DIR]`
//! (defaults: the shared corpus `generated/e_big256.vdb` and `real/elyg_pig.vdb` under `$NIMBUS_SHARED_DIR` or
//! `../shared`, 20000 rays, a density scale giving a mean optical depth T = 10 along the rays).
//! Single-threaded; times are wall-clock, the best of 3 interleaved rounds (build: best of 3).
//! For each majorant kind it reports build time, memory, per-ray majorant cells walked, density lookups, null
//! collisions per real collision, segments per ray, ns per delta-tracked free flight and per ratio-tracked
//! transmittance, and the mean transmittance (which must agree across kinds within the printed standard errors);
//! then auto's pick. With every kind it ends with a markdown table of auto against the fastest per case. `--csv`
//! adds machine-readable rows, the input of `benches/fit_majorant_costs.py` (which fits the pilot's cost
//! constants). `--chart DIR` writes `DIR/majorants_time_per_ray.png`/`.svg`: per optical depth, each structure's
//! and auto's time relative to the fastest structure, geometric mean over the grids.

mod support;

use glam::DMat4;
use nimbus::converge::{draw_loglog_chart, LegendCorner, LogLogChart, Series};
use nimbus::math::Rng;
use nimbus::volume::density::GridDensity;
use nimbus::volume::majorant::{MajorantKind, Majorants};
use nimbus::volume::majorant_choice::{choose, pilot_rays};
use nimbus::volume::tracking::{
    optical_depth_quadrature, ratio_tracking, sample_collision, TrackingCounters,
};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Wall-clock ns taken by `f`, and its result.
fn timed<R>(f: impl FnOnce() -> R) -> (f64, R) {
    let t = Instant::now();
    let r = f();
    (t.elapsed().as_nanos() as f64, r)
}

fn shared_dir() -> PathBuf {
    std::env::var_os("NIMBUS_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"))
}

/// One grid at one optical depth: measured ns per ray (free flight + transmittance) per kind, and auto's pick.
struct Case {
    grid: String,
    tau: f64,
    ns: Vec<(MajorantKind, f64)>,
    auto: MajorantKind,
}

impl Case {
    /// Measured ns per ray of `kind` (NaN when it was not run).
    fn ns_of(&self, kind: MajorantKind) -> f64 {
        self.ns
            .iter()
            .find(|x| x.0 == kind)
            .map_or(f64::NAN, |x| x.1)
    }

    /// The fastest structure's ns per ray.
    fn fastest(&self) -> f64 {
        self.ns.iter().map(|x| x.1).fold(f64::INFINITY, f64::min)
    }
}

fn bench_file(
    path: &Path,
    n_rays: usize,
    tau_target: f64,
    kinds: &[MajorantKind],
    csv: bool,
) -> Option<Case> {
    let grid = support::scalar_grid(path)?;
    let unit = match GridDensity::new(&grid, DMat4::IDENTITY, 1.0) {
        Ok(g) => g,
        Err(e) => {
            println!("skipping {}: {e}", path.display());
            return None;
        }
    };
    // Scale so that the mean optical depth along the benchmark rays is tau_target.
    let (probe, t_max) = pilot_rays(&unit, 256, 99);
    let mean_tau = probe
        .iter()
        .map(|r| optical_depth_quadrature(&unit, r, 0.0, t_max, 2048))
        .sum::<f64>()
        / probe.len() as f64;
    let scale = (tau_target / mean_tau.max(1e-30)) as f32;
    let field = GridDensity::new(&grid, DMat4::IDENTITY, scale).expect("checked above");
    let (rays, t_max) = pilot_rays(&field, n_rays, 7);
    let tree = field.tree();
    println!(
        "\n{} grid '{}': {} leaves, tree {:.1} MiB, density scale {scale:.4} (mean optical depth {tau_target} along rays), {n_rays} rays",
        path.display(),
        grid.name,
        tree.stats().leaves,
        field.memory_bytes() as f64 / 1048576.0
    );
    println!(
        "{:<9} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>17} {:>17}",
        "majorant",
        "build ms",
        "memory KiB",
        "cells/ray",
        "look/ray",
        "null/real",
        "ns/flight",
        "cells/ray",
        "look/ray",
        "ns/transm",
        "seg/ray",
        "T delta ± se",
        "T ratio ± se"
    );
    println!(
        "{:<9} {:>8} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "",
        "",
        "",
        "(delta)",
        "(delta)",
        "(delta)",
        "(delta)",
        "(ratio)",
        "(ratio)",
        "(ratio)",
        "(ratio)"
    );
    // Build each kind (best of 3), then time the kinds interleaved over ROUNDS rounds and keep the fastest
    // round of each, which filters out most of the noise of a shared machine. Every round replays the same
    // random numbers, so the counters and estimates are those of any one round.
    const ROUNDS: usize = 3;
    let built: Vec<(f64, Majorants)> = kinds
        .iter()
        .map(|&kind| {
            (0..3)
                .map(|_| timed(|| Majorants::build(kind, &field)))
                .min_by(|a, b| a.0.total_cmp(&b.0))
                .expect("three builds")
        })
        .collect();
    let mut best = vec![(f64::INFINITY, f64::INFINITY); built.len()];
    let mut results = Vec::new();
    for round in 0..ROUNDS {
        for (k, (_, maj)) in built.iter().enumerate() {
            let mut rng = Rng::new(1234, k as u64);
            let mut cd = TrackingCounters::default();
            let (delta_ns, escaped) = timed(|| {
                rays.iter()
                    .filter(|r| {
                        sample_collision(&field, maj, r, 0.0, t_max, &mut rng, &mut cd).is_none()
                    })
                    .count()
            });
            let mut cr = TrackingCounters::default();
            let (ratio_ns, (sum, sum2)) = timed(|| {
                rays.iter().fold((0.0f64, 0.0f64), |(s, s2), r| {
                    let t =
                        ratio_tracking(&field, maj, r, (0.0, t_max), 1.0, &mut rng, &mut cr) as f64;
                    (s + t, s2 + t * t)
                })
            });
            best[k] = (best[k].0.min(delta_ns), best[k].1.min(ratio_ns));
            if round == 0 {
                results.push((cd, escaped, cr, sum, sum2));
            }
        }
    }
    for (k, (build_ns, maj)) in built.iter().enumerate() {
        let (cd, escaped, cr, sum, sum2) = results[k];
        let (delta_ns, ratio_ns) = best[k];
        let kind = maj.kind();
        let n = n_rays as f64;
        let pd = escaped as f64 / n;
        let se_d = (pd * (1.0 - pd) / n).sqrt();
        let mr = sum / n;
        let se_r = ((sum2 / n - mr * mr).max(0.0) / n).sqrt();
        println!(
            "{:<9} {:>8.2} {:>10.1} {:>9.2} {:>9.2} {:>9.2} {:>9.0} {:>9.2} {:>9.2} {:>9.0} {:>9.2} {:>8.4} ± {:.4} {:>8.4} ± {:.4}",
            format!("{kind:?}"),
            build_ns / 1e6,
            maj.memory_bytes() as f64 / 1024.0,
            cd.majorant_cells as f64 / n,
            cd.density_lookups as f64 / n,
            cd.null_collisions as f64 / cd.real_collisions.max(1) as f64,
            delta_ns / n,
            cr.majorant_cells as f64 / n,
            cr.density_lookups as f64 / n,
            ratio_ns / n,
            cr.majorant_segments as f64 / n,
            pd,
            se_d,
            mr,
            se_r
        );
        if csv {
            println!(
                "CSV,{},{tau_target},{kind:?},{},{},{},{},{},{}",
                path.display(),
                cd.majorant_cells as f64 / n,
                cd.density_lookups as f64 / n,
                delta_ns / n,
                cr.majorant_cells as f64 / n,
                cr.density_lookups as f64 / n,
                ratio_ns / n
            );
        }
        if cd.majorant_violations + cr.majorant_violations > 0 {
            println!(
                "  !! {} majorant violations",
                cd.majorant_violations + cr.majorant_violations
            );
        }
    }
    let (t, (chosen, estimates)) = timed(|| choose(&field, &nimbus::limits::Limits::default()));
    println!(
        "auto ({:.1} ms pilot) picks {:?}; pilot estimates ns: {}",
        t / 1e6,
        chosen.kind(),
        estimates
            .iter()
            .map(|e| format!("{:?} {:.0}", e.kind, e.cost_ns))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Some(Case {
        grid: path
            .file_stem()
            .map_or(String::new(), |s| s.to_string_lossy().into_owned()),
        tau: tau_target,
        ns: built
            .iter()
            .zip(&best)
            .map(|((_, m), (d, r))| (m.kind(), (d + r) / n_rays as f64))
            .collect(),
        auto: chosen.kind(),
    })
}

/// Prints the markdown table of auto's pick against the measured fastest, with the geometric-mean slowdown of
/// each fixed choice and of auto relative to the fastest per case.
fn print_summary(cases: &[Case]) {
    println!("\n| grid | mean optical depth | global ns | grid16 ns | adaptive ns | auto picks | auto / fastest |");
    println!("|---|---|---|---|---|---|---|");
    let mut log_slowdown = [0.0f64; 4];
    for c in cases {
        let fastest = c.fastest();
        let cells: Vec<String> = MajorantKind::ALL
            .iter()
            .map(|&k| {
                let v = c.ns_of(k);
                if v == fastest {
                    format!("**{v:.0}**")
                } else {
                    format!("{v:.0}")
                }
            })
            .collect();
        println!(
            "| {} | {} | {} | {} | {:.2} |",
            c.grid,
            c.tau,
            cells.join(" | "),
            c.auto.name(),
            c.ns_of(c.auto) / fastest
        );
        for (i, &k) in MajorantKind::ALL.iter().enumerate() {
            log_slowdown[i] += (c.ns_of(k) / fastest).ln();
        }
        log_slowdown[3] += (c.ns_of(c.auto) / fastest).ln();
    }
    let n = cases.len().max(1) as f64;
    let g = log_slowdown.map(|l| (l / n).exp());
    println!(
        "\ngeometric-mean time relative to the fastest structure per case: global {:.2}, grid16 {:.2}, adaptive {:.2}, auto {:.2}",
        g[0], g[1], g[2], g[3]
    );
}

/// Draws each structure's and auto's time relative to the fastest per case, geometric mean over the grids at each
/// optical depth, against the optical depth.
fn draw_slowdown_chart(cases: &[Case], dir: &Path) -> Result<(), String> {
    let mut taus: Vec<f64> = cases.iter().map(|c| c.tau).collect();
    taus.sort_by(f64::total_cmp);
    taus.dedup();
    let slowdown = |pick: &dyn Fn(&Case) -> MajorantKind| -> Vec<(f64, f64)> {
        taus.iter()
            .map(|&tau| {
                let at: Vec<&Case> = cases.iter().filter(|c| c.tau == tau).collect();
                let log_sum: f64 = at
                    .iter()
                    .map(|c| (c.ns_of(pick(c)) / c.fastest()).ln())
                    .sum();
                (tau, (log_sum / at.len() as f64).exp())
            })
            .collect()
    };
    let mut series: Vec<Series> = MajorantKind::ALL
        .iter()
        .map(|&k| Series {
            label: k.name().into(),
            points: slowdown(&|_| k),
        })
        .collect();
    series.push(Series {
        label: "auto (pilot's pick)".into(),
        points: slowdown(&|c| c.auto),
    });
    let chart = LogLogChart {
        caption: "Majorant structures: time per ray relative to the fastest".into(),
        x_desc: "mean optical depth along the rays".into(),
        y_desc: "time / fastest (geometric mean over grids)".into(),
        series,
        guide: None,
        legend: LegendCorner::UpperLeft,
    };
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    draw_loglog_chart(
        &chart,
        &dir.join("majorants_time_per_ray.png"),
        &dir.join("majorants_time_per_ray.svg"),
    )
    .map_err(|e| e.to_string())
}

fn main() {
    let mut chart_dir = None;
    let mut files = Vec::new();
    let mut n_rays = 20_000usize;
    let mut taus = vec![10.0f64];
    let mut csv = false;
    let mut kinds = MajorantKind::ALL.to_vec();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--rays" => n_rays = args.next().and_then(|v| v.parse().ok()).unwrap_or(n_rays),
            "--kind" => {
                let k = args.next().unwrap_or_default();
                kinds.retain(|x| format!("{x:?}").eq_ignore_ascii_case(&k));
            }
            "--tau" => {
                taus = args
                    .next()
                    .map(|v| v.split(',').filter_map(|t| t.parse().ok()).collect())
                    .unwrap_or(taus)
            }
            "--csv" => csv = true,
            "--chart" => chart_dir = args.next().map(PathBuf::from),
            s if s.starts_with("--") => {}
            s => files.push(PathBuf::from(s)),
        }
    }
    if files.is_empty() {
        let s = shared_dir().join("vdb-corpus");
        files = vec![
            s.join("generated/e_big256.vdb"),
            s.join("real/elyg_pig.vdb"),
        ];
    }
    let mut cases = Vec::new();
    for f in &files {
        for &tau in &taus {
            cases.extend(bench_file(f, n_rays, tau, &kinds, csv));
        }
    }
    if kinds.len() == MajorantKind::ALL.len() {
        print_summary(&cases);
        if let Some(dir) = chart_dir {
            match draw_slowdown_chart(&cases, &dir) {
                Ok(()) => println!("wrote {}/majorants_time_per_ray.{{png,svg}}", dir.display()),
                Err(e) => println!("chart not written: {e}"),
            }
        }
    }
}
