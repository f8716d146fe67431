//! Free-flight benchmark: the work of one free flight through a VDB grid as its density scale grows 1× → 100×,
//! for each majorant structure and each free-flight method: delta tracking on the structure's own segments (the
//! method before voxel refinement), and delta or decomposition tracking with thick segments refined to voxel
//! cells (`nimbus::volume::tracking::REFINE_TAU`).
//!
//! `cargo bench --bench free_flight -- [--walks N] [--rounds R] [--scales S[,S...]] [--only NAME]`
//! (defaults: 4000 walks, 3 rounds, scales 1,10,100).
//!
//! The grids are the bundled cloud (`assets/cloud.gltf`: `cloud.vdb` at density scale 30, moved up 1 m), the
//! plume of the peer benchmark (`benches/peers/scenes/plume.gltf`: the corpus file `real/mjurczyk_smoke.vdb` at
//! scale 40 under a 0.02 scale), and corpus grids `real/elyg_pig.vdb` and `generated/e_big256.vdb` at the scale
//! that gives a mean optical depth of 1 along the pilot rays; each is then multiplied by every `--scales` factor.
//! Grids are read from `$NIMBUS_SHARED_DIR` or `../shared`; a missing one is skipped.
//!
//! A walk is what a path does in a scattering medium: a ray from the grid's bounding sphere towards a point
//! inside (the fixed-seed rays of the majorant pilot), and at each real collision an isotropic scattering into a
//! new free flight from there, up to 4 flights (albedo 1; the walk ends when a flight leaves the grid). Every
//! combination replays the same walks' random numbers. Per free flight it reports density lookups, null and
//! real collisions, voxel cells whose bounds were read (eight voxels each), majorant cells walked and the time relative to grid16 with delta tracking at the same scale
//! (single-threaded; the combinations are timed interleaved over the rounds and each keeps its fastest round,
//! since a shared machine makes absolute times meaningless). Counted work is exact and machine-independent.
//! Last, the structure `auto` picks at that scale and the pilot's estimates.

mod support;

use glam::{DMat4, DVec3};
use nimbus::math::{Ray, Rng, Vec3};
use nimbus::volume::density::GridDensity;
use nimbus::volume::majorant::{MajorantKind, Majorants};
use nimbus::volume::majorant_choice::{choose, pilot_rays};
use nimbus::volume::tracking::{
    decomposition_tracking, optical_depth_quadrature, sample_collision, TrackingCounters,
};
use std::path::PathBuf;
use std::time::Instant;

/// Free flights per walk at most.
const MAX_FLIGHTS: usize = 4;

fn shared_dir() -> PathBuf {
    std::env::var_os("NIMBUS_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"))
}

/// A grid as a scene places it: file, node matrix and density scale (`None`: mean optical depth 1 on the
/// pilot rays).
struct Scene {
    name: &'static str,
    file: PathBuf,
    node: DMat4,
    scale: Option<f32>,
}

fn scenes() -> Vec<Scene> {
    let shared = shared_dir();
    let corpus = shared.join("vdb-corpus");
    vec![
        Scene {
            name: "cloud",
            file: PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/cloud.vdb"),
            node: DMat4::from_translation(DVec3::new(0.0, 1.0, 0.0)),
            scale: Some(30.0),
        },
        Scene {
            name: "plume",
            file: corpus.join("real/mjurczyk_smoke.vdb"),
            node: DMat4::from_translation(DVec3::new(0.1, 0.27, 0.0))
                * DMat4::from_scale(DVec3::splat(0.02)),
            scale: Some(40.0),
        },
        Scene {
            name: "pig",
            file: corpus.join("real/elyg_pig.vdb"),
            node: DMat4::IDENTITY,
            scale: None,
        },
        Scene {
            name: "big256",
            file: corpus.join("generated/e_big256.vdb"),
            node: DMat4::IDENTITY,
            scale: None,
        },
    ]
}

/// A free-flight sampler.
type Sampler =
    fn(&GridDensity, &Majorants, &Ray, f32, f32, &mut Rng, &mut TrackingCounters) -> Option<f32>;

/// The free-flight methods compared: the sampler, and whether thick segments are refined to voxel cells.
/// The first (delta tracking on the structure's own segments) is the method before refinement existed.
const METHODS: [(&str, Sampler, bool); 3] = [
    ("delta", sample_collision::<GridDensity>, false),
    ("delta + voxels", sample_collision::<GridDensity>, true),
    (
        "decomposition + voxels",
        decomposition_tracking::<GridDensity>,
        true,
    ),
];

/// Runs the walks from `rays` with `sampler` over `majorants`; returns the counters and the free flights.
fn walks(
    field: &GridDensity,
    majorants: &Majorants,
    sampler: Sampler,
    rays: &[Ray],
    t_max: f32,
) -> (TrackingCounters, u64) {
    let mut c = TrackingCounters::default();
    let mut flights = 0;
    for (i, first) in rays.iter().enumerate() {
        let mut rng = Rng::new(77, i as u64);
        let mut ray = *first;
        for _ in 0..MAX_FLIGHTS {
            flights += 1;
            let Some(t) = sampler(field, majorants, &ray, 0.0, t_max, &mut rng, &mut c) else {
                break;
            };
            let z = 1.0 - 2.0 * rng.next_f32();
            let phi = std::f32::consts::TAU * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            ray = Ray::new(ray.at(t), Vec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    (c, flights)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| support::flag_value(&args, flag);
    let n_walks: usize = value("--walks").map_or(4000, |v| v.parse().expect("--walks N"));
    let rounds: usize = value("--rounds").map_or(3, |v| v.parse().expect("--rounds R"));
    let scales: Vec<f32> = value("--scales").map_or(vec![1.0, 10.0, 100.0], |v| {
        v.split(',').map(|s| s.parse().expect("--scales")).collect()
    });
    let only = value("--only");
    println!(
        "| grid | scale | majorant | sampler | lookups | voxel cells | null | real | null/real | cells | time / grid16 delta |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let mut picks = Vec::new();
    for scene in scenes() {
        if only.is_some_and(|o| o != scene.name) {
            continue;
        }
        let Some(grid) = support::scalar_grid(&scene.file) else {
            continue;
        };
        let base = scene.scale.unwrap_or_else(|| {
            let unit = GridDensity::new(&grid, scene.node, 1.0).expect("a density grid");
            let (probe, t_max) = pilot_rays(&unit, 256, 99);
            let tau = probe
                .iter()
                .map(|r| optical_depth_quadrature(&unit, r, 0.0, t_max, 2048))
                .sum::<f64>()
                / probe.len() as f64;
            (1.0 / tau.max(1e-30)) as f32
        });
        for &mult in &scales {
            let field = GridDensity::new(&grid, scene.node, base * mult).expect("a density grid");
            let (rays, t_max) = pilot_rays(&field, n_walks, 7);
            let built: Vec<Majorants> = MajorantKind::ALL
                .iter()
                .map(|&k| Majorants::build(k, &field))
                .collect();
            let plain: Vec<Majorants> = built
                .iter()
                .map(|m| m.clone().with_voxel_refinement(false))
                .collect();
            let majorants = |m: usize, s: usize| if METHODS[s].2 { &built[m] } else { &plain[m] };
            let combos: Vec<(usize, usize)> = (0..built.len())
                .flat_map(|m| (0..METHODS.len()).map(move |s| (m, s)))
                .collect();
            let mut best = vec![f64::INFINITY; combos.len()];
            let mut counts = vec![(TrackingCounters::default(), 0u64); combos.len()];
            for _ in 0..rounds {
                for (i, &(m, s)) in combos.iter().enumerate() {
                    let start = Instant::now();
                    counts[i] = walks(&field, majorants(m, s), METHODS[s].1, &rays, t_max);
                    best[i] = best[i].min(start.elapsed().as_secs_f64());
                }
            }
            let reference = combos
                .iter()
                .position(|&(m, s)| built[m].kind() == MajorantKind::Grid16 && s == 0)
                .map_or(f64::NAN, |i| best[i] / counts[i].1 as f64);
            for (i, &(m, s)) in combos.iter().enumerate() {
                let (c, flights) = counts[i];
                let per = |x: u64| x as f64 / flights as f64;
                println!(
                    "| {} | {mult}× | {} | {} | {:.2} | {:.2} | {:.2} | {:.3} | {:.1} | {:.2} | {:.2} |",
                    scene.name,
                    built[m].kind().name(),
                    METHODS[s].0,
                    per(c.density_lookups),
                    per(c.voxel_cells),
                    per(c.null_collisions),
                    per(c.real_collisions),
                    c.null_collisions as f64 / c.real_collisions.max(1) as f64,
                    per(c.majorant_cells),
                    best[i] / flights as f64 / reference
                );
                assert_eq!(c.majorant_violations, 0, "{} {mult}×", scene.name);
            }
            let (chosen, estimates) = choose(&field, &nimbus::limits::Limits::default());
            picks.push(format!(
                "{} {mult}×: auto picks {} (pilot ns/ray: {})",
                scene.name,
                chosen.kind().name(),
                estimates
                    .iter()
                    .map(|e| format!("{} {:.0}", e.kind.name(), e.cost_ns))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    println!();
    for p in picks {
        println!("{p}");
    }
}
