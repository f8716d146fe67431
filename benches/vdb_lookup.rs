//! VDB lookup benchmark: load time, random and coherent lookups, trilinear samples and memory per voxel.
//!
//! `cargo bench --bench vdb_lookup -- [FILE.vdb] [GRID]` (default: the shared corpus `generated/e_big256.vdb`,
//! first scalar grid). Goals: random lookups ≤ 80 ns, coherent accessor walks ≤ 10 ns.

use glam::{IVec3, Vec3};
use nimbus::vdb::{floor_ivec3, read_file, FloatTree};
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Instant;

struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// On-CPU time of this thread in ns (Linux `schedstat`), so that a loaded machine does not inflate the figures;
/// falls back to wall time elsewhere.
fn cpu_ns(wall: Instant) -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| wall.elapsed().as_nanos() as u64)
}

/// Times `f`, returning (wall ns, on-CPU ns).
fn timed(f: impl FnOnce()) -> (f64, f64) {
    let origin = Instant::now();
    let c0 = cpu_ns(origin);
    let t = Instant::now();
    f();
    let wall = t.elapsed().as_nanos() as f64;
    (wall, (cpu_ns(origin) - c0) as f64)
}

fn report(label: &str, (wall, cpu): (f64, f64), n: usize) {
    println!(
        "{label}: {:.2} ns (on-CPU), {:.2} ns (wall)",
        cpu / n as f64,
        wall / n as f64
    );
}

fn default_path() -> PathBuf {
    let shared = std::env::var_os("NIMBUS_SHARED_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"));
    shared.join("vdb-corpus/generated/e_big256.vdb")
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let path = args.first().map(PathBuf::from).unwrap_or_else(default_path);
    let grid_name = args.get(1).cloned();

    let mut best_load = f64::INFINITY;
    let mut file = None;
    for _ in 0..3 {
        let t = Instant::now();
        let f = read_file(&path).unwrap_or_else(|e| panic!("{e}"));
        best_load = best_load.min(t.elapsed().as_secs_f64());
        file = Some(f);
    }
    let file = file.expect("loaded");
    let grid = file
        .grids
        .iter()
        .find(|g| grid_name.as_ref().is_none_or(|n| &g.name == n) && g.tree.as_float().is_some())
        .expect("no scalar grid");
    let tree: &FloatTree = grid.tree.as_float().expect("scalar");
    let stats = tree.stats();
    let (lo, hi) = stats.bbox.expect("empty grid");
    println!("file: {}", path.display());
    println!(
        "grid '{}': {} active voxels, {} leaves, {} tiles, bbox {lo}..{hi}",
        grid.name, stats.active_voxels, stats.leaves, stats.tiles
    );
    println!("load (best of 3): {:.1} ms", best_load * 1e3);
    println!(
        "memory: {:.1} MiB, {:.2} bytes per active voxel",
        tree.memory_bytes() as f64 / 1048576.0,
        tree.memory_bytes() as f64 / stats.active_voxels as f64
    );

    // Random lookups inside the active bbox, coordinates precomputed.
    const N: usize = 10_000_000;
    let mut rng = SplitMix(42);
    let ext = (hi - lo + IVec3::ONE).as_i64vec3();
    let coords: Vec<IVec3> = (0..N)
        .map(|_| {
            lo + IVec3::new(
                (rng.next() % ext.x as u64) as i32,
                (rng.next() % ext.y as u64) as i32,
                (rng.next() % ext.z as u64) as i32,
            )
        })
        .collect();
    let t = timed(|| {
        let mut s = 0.0f32;
        for &p in &coords {
            s += tree.value(p);
        }
        black_box(s);
    });
    report("random lookups, Tree::value, per lookup", t, N);
    let t = timed(|| {
        let mut acc = tree.accessor();
        let mut s = 0.0f32;
        for &p in &coords {
            s += acc.value(p);
        }
        black_box(s);
    });
    report("random lookups, Accessor, per lookup", t, N);
    drop(coords);

    // Scanlines: every voxel of the bbox in x, y, z order (the accessor's best case).
    let per_pass = (ext.x * ext.y * ext.z) as usize;
    let passes = (N / per_pass).max(1);
    let scan_n = per_pass * passes;
    let t = timed(|| {
        let mut acc = tree.accessor();
        let mut s = 0.0f32;
        for x in (0..passes).flat_map(|_| lo.x..=hi.x) {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    s += acc.value(IVec3::new(x, y, z));
                }
            }
        }
        black_box(s);
    });
    report(
        "scanline walk over the bbox, Accessor, per lookup",
        t,
        scan_n,
    );

    // Coherent walks: rays from random points in random directions, one lookup per unit step.
    let size = (hi - lo + IVec3::ONE).as_vec3();
    let steps = size.max_element() as usize;
    let nrays = N / steps;
    let rays: Vec<(Vec3, Vec3)> = (0..nrays)
        .map(|_| {
            let o = lo.as_vec3() + Vec3::new(rng.unit(), rng.unit(), rng.unit()) * size;
            let z = 2.0 * rng.unit() - 1.0;
            let phi = std::f32::consts::TAU * rng.unit();
            let r = (1.0 - z * z).max(0.0).sqrt();
            (o, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect();
    let t = timed(|| {
        let mut s = 0.0f32;
        let mut acc = tree.accessor();
        for &(o, d) in &rays {
            let mut p = o;
            for _ in 0..steps {
                s += acc.value(floor_ivec3(p));
                p += d;
            }
        }
        black_box(s);
    });
    report(
        &format!("coherent ray walks ({nrays} rays x {steps} unit steps), Accessor, per lookup"),
        t,
        nrays * steps,
    );
    let t = timed(|| {
        let mut s = 0.0f32;
        let mut acc = tree.accessor();
        for &(o, d) in &rays {
            let mut p = o;
            for _ in 0..steps {
                s += acc.sample_trilinear(p);
                p += d;
            }
        }
        black_box(s);
    });
    report(
        "trilinear samples along the rays, Accessor, per sample",
        t,
        nrays * steps,
    );
    let m = 2_000_000;
    let pts: Vec<Vec3> = (0..m)
        .map(|_| lo.as_vec3() + Vec3::new(rng.unit(), rng.unit(), rng.unit()) * size)
        .collect();
    let t = timed(|| {
        let mut s = 0.0f32;
        for &p in &pts {
            s += tree.sample_trilinear(p);
        }
        black_box(s);
    });
    report("trilinear samples at random points, per sample", t, m);
}
