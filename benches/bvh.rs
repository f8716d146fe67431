//! BVH benchmark: build time, memory and ray throughput on a procedural ~1M-triangle bumpy sphere; then a scene
//! of 64 instances of a 51 k-triangle sphere, as a two-level `InstanceBvh` and flattened into one `Bvh`.
//!
//! Run with `cargo bench --bench bvh`. After the throughput table it gives the mean number of wide nodes and
//! triangles each query tests per ray (`Bvh::traversal_counts`). Rays are generated up front; each figure is the best of a few runs
//! of the whole ray set on a rayon pool with the given number of threads. Throughput is given per second of
//! wall time and per second of CPU time summed over threads (steadier on a shared machine; with two
//! threads it is per-core throughput, so the wall figure shows the scaling).
//!
//! `cargo bench --bench bvh -- --export DIR` also writes the mesh, both ray sets and Nimbus's answers to `DIR`
//! as little-endian binary arrays, so that a peer traces the very same work (`benches/peers/embree_rays.py`):
//! `triangles.f32` (9 floats a triangle), `primary.f32` and `random.f32` (origin then direction, 6 floats a ray,
//! every ray from t = 0 to infinity), `primary_closest.f32` and `random_closest.f32` (the closest hit's distance,
//! infinity for a miss), `primary_occluded.u8` and `random_occluded.u8` (1 where the ray hits anything).

mod support;

use nimbus::geometry::{Bvh, Instance, InstanceBvh, TriangleHierarchy};
use nimbus::math::sampling::uniform_sphere;
use nimbus::math::{Mat4, Quat, Ray, Rng, Vec3};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// A closed UV sphere whose vertices are displaced radially by a smooth bump field plus per-vertex noise,
/// so neighbouring triangles are not coplanar and the surface folds slightly: `2·rings·segments` triangles
/// (less the pole caps' shared rows).
fn bumpy_sphere(rings: usize, segments: usize, rng: &mut Rng) -> Vec<[Vec3; 3]> {
    use std::f32::consts::{PI, TAU};
    let point = |theta: f32, phi: f32, rng: &mut Rng| {
        let bump = 0.08 * (7.0 * theta).sin() * (11.0 * phi).sin() + 0.03 * (rng.next_f32() - 0.5);
        (1.0 + bump)
            * Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
    };
    let north = point(0.0, 0.0, rng);
    let south = point(PI, 0.0, rng);
    let grid: Vec<Vec<Vec3>> = (1..rings)
        .map(|i| {
            (0..segments)
                .map(|j| {
                    point(
                        PI * i as f32 / rings as f32,
                        TAU * j as f32 / segments as f32,
                        rng,
                    )
                })
                .collect()
        })
        .collect();
    let mut tris = Vec::with_capacity(2 * rings * segments);
    for j in 0..segments {
        let k = (j + 1) % segments;
        tris.push([north, grid[0][j], grid[0][k]]);
        tris.push([south, grid[rings - 2][k], grid[rings - 2][j]]);
        for i in 0..rings - 2 {
            tris.push([grid[i][j], grid[i + 1][j], grid[i][k]]);
            tris.push([grid[i][k], grid[i + 1][j], grid[i + 1][k]]);
        }
    }
    tris
}

/// Primary rays of a `res`×`res` pinhole camera looking at the origin.
fn camera_rays(res: usize) -> Vec<Ray> {
    let eye = Vec3::new(0.4, 0.6, 2.6);
    let forward = (-eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    let tan_half = (50.0f32.to_radians() * 0.5).tan();
    (0..res * res)
        .map(|p| {
            let (x, y) = ((p % res) as f32 + 0.5, (p / res) as f32 + 0.5);
            let sx = (2.0 * x / res as f32 - 1.0) * tan_half;
            let sy = (1.0 - 2.0 * y / res as f32) * tan_half;
            Ray::new(eye, (forward + sx * right + sy * up).normalize())
        })
        .collect()
}

/// Rays with uniform random origins inside `bvh`'s bounds and uniform random directions.
fn random_rays(n: usize, bvh: &Bvh, rng: &mut Rng) -> Vec<Ray> {
    let b = bvh.bounds();
    (0..n)
        .map(|_| {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(b.min + u * b.extent(), uniform_sphere(rng.next_2d()))
        })
        .collect()
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
}

/// CPU time consumed so far by this process, all threads (including exited ones) together, in seconds:
/// `utime + stime` of Linux's `/proc/self/stat`, in 10 ms clock ticks; `None` elsewhere. On a shared machine
/// this is steadier than wall time, which also counts time spent waiting for a core.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15 of the whole line.
    let rest = &stat[stat.rfind(')')? + 2..];
    let mut fields = rest.split_whitespace().skip(11);
    let utime: u64 = fields.next()?.parse().ok()?;
    let stime: u64 = fields.next()?.parse().ok()?;
    Some((utime + stime) as f64 / 100.0)
}

/// Best-of-`reps` wall and CPU seconds for `f` (CPU time summed over threads), and its last result.
fn time<R>(reps: usize, mut f: impl FnMut() -> R) -> (f64, Option<f64>, R) {
    let (mut wall, mut cpu) = (f64::INFINITY, None::<f64>);
    let mut out = None;
    for _ in 0..reps {
        let (start, cpu0) = (Instant::now(), cpu_seconds());
        out = Some(f());
        wall = wall.min(start.elapsed().as_secs_f64());
        if let (Some(a), Some(b)) = (cpu0, cpu_seconds()) {
            cpu = Some(cpu.map_or(b - a, |c| c.min(b - a)));
        }
    }
    (wall, cpu, out.expect("at least one repetition"))
}

/// Mrays per second of wall time and per CPU-second, and the hit fraction, of `query` over `rays` on
/// `threads` threads (best of 3).
fn throughput(
    h: &(impl TriangleHierarchy + Sync),
    rays: &[Ray],
    query: &str,
    threads: usize,
) -> (f64, f64, f64) {
    let p = pool(threads);
    let (secs, cpu, hits) = time(3, || {
        p.install(|| {
            rays.par_chunks(1024)
                .map(|chunk| {
                    chunk
                        .iter()
                        .filter(|r| match query {
                            "closest" => h.intersect(r, 0.0, f32::INFINITY).is_some(),
                            _ => h.occluded(r, 0.0, f32::INFINITY),
                        })
                        .count()
                })
                .sum::<usize>()
        })
    });
    let mrays = |s: f64| rays.len() as f64 / s / 1e6;
    (
        mrays(secs),
        cpu.map_or(f64::NAN, mrays),
        hits as f64 / rays.len() as f64,
    )
}

/// The mean number of wide nodes and triangles a query tests per ray, over `rays`.
fn counts_per_ray(bvh: &Bvh, rays: &[Ray], query: &str) -> (f64, f64) {
    let (nodes, triangles) = rays
        .par_iter()
        .map(|r| {
            let counts = match query {
                "closest" => bvh.traversal_counts::<false>(r, 0.0, f32::INFINITY).1,
                _ => bvh.traversal_counts::<true>(r, 0.0, f32::INFINITY).1,
            };
            (counts.nodes, counts.triangles)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let n = rays.len() as f64;
    (nodes as f64 / n, triangles as f64 / n)
}

/// 64 instances of one bumpy sphere on a 4×4×4 lattice, rotated and non-uniformly scaled: the two-level
/// hierarchy against the same triangles flattened into one hierarchy (build, memory, rays).
fn instanced_scene(rng: &mut Rng) {
    let proto = bumpy_sphere(160, 160, rng);
    let instances: Vec<Instance> = (0..64)
        .map(|i| {
            let at = Vec3::new((i % 4) as f32, ((i / 4) % 4) as f32, (i / 16) as f32) * 3.0;
            let axis = uniform_sphere(rng.next_2d());
            let scale = Vec3::new(0.8 + rng.next_f32(), 0.8 + rng.next_f32(), 0.8);
            Instance {
                prototype: 0,
                object_to_world: Mat4::from_scale_rotation_translation(
                    scale,
                    Quat::from_axis_angle(axis, 3.0 * rng.next_f32()),
                    at,
                ),
            }
        })
        .collect();
    let flat: Vec<[Vec3; 3]> = instances
        .iter()
        .flat_map(|i| {
            proto
                .iter()
                .map(move |t| t.map(|v| i.object_to_world.transform_point3(v)))
        })
        .collect();
    println!();
    println!(
        "instanced scene: 64 instances of a {}-triangle sphere ({} triangles flattened)",
        proto.len(),
        flat.len()
    );
    let p = pool(2);
    let protos = vec![proto];
    let (ib, icpu, inst) = time(2, || {
        p.install(|| InstanceBvh::build(&protos, &instances).expect("within the limits"))
    });
    let (fb, fcpu, flat_bvh) = time(2, || {
        p.install(|| Bvh::build(&flat).expect("within the triangle limit"))
    });
    let mib = |b: usize| b as f64 / (1 << 20) as f64;
    println!(
        "{:<12} {:>12} {:>12} {:>11}",
        "hierarchy", "build wall s", "build CPU s", "memory MiB"
    );
    println!(
        "{:<12} {:>12.3} {:>12.3} {:>11.1}",
        "two-level",
        ib,
        icpu.unwrap_or(f64::NAN),
        mib(inst.memory_bytes())
    );
    println!(
        "{:<12} {:>12.3} {:>12.3} {:>11.1}",
        "flattened",
        fb,
        fcpu.unwrap_or(f64::NAN),
        mib(flat_bvh.memory_bytes())
    );
    let b = flat_bvh.bounds();
    let random: Vec<Ray> = (0..1 << 18)
        .map(|_| {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(b.min + u * b.extent(), uniform_sphere(rng.next_2d()))
        })
        .collect();
    println!(
        "{:<12} {:<9} {:>7} {:>14} {:>18} {:>9}",
        "hierarchy", "query", "threads", "Mrays/s wall", "Mrays/CPU-second", "hit frac"
    );
    for query in ["closest", "occluded"] {
        // Alternated, so that both see the same machine load.
        for _ in 0..2 {
            let rows = [
                ("two-level", throughput(&inst, &random, query, 1)),
                ("flattened", throughput(&flat_bvh, &random, query, 1)),
            ];
            for (name, (wall, cpu, hits)) in rows {
                println!(
                    "{:<12} {:<9} {:>7} {:>14.2} {:>18.2} {:>9.3}",
                    name, query, 1, wall, cpu, hits
                );
            }
        }
    }
}

/// Writes `values` to `dir/name` as little-endian `f32`s.
fn write_f32s(dir: &Path, name: &str, values: impl Iterator<Item = f32>) {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    std::fs::write(dir.join(name), bytes).expect("writing an export file");
}

/// Writes the mesh, the ray sets and Nimbus's closest-hit distances and occlusion answers to `dir` (see the
/// module documentation).
fn export(dir: &Path, tris: &[[Vec3; 3]], bvh: &Bvh, sets: &[(&str, Vec<Ray>)]) {
    std::fs::create_dir_all(dir).expect("creating the export folder");
    write_f32s(
        dir,
        "triangles.f32",
        tris.iter().flatten().flat_map(|v| v.to_array()),
    );
    for (name, rays) in sets {
        let set = name.split(' ').next().expect("a set name");
        write_f32s(
            dir,
            &format!("{set}.f32"),
            rays.iter()
                .flat_map(|r| r.origin.to_array().into_iter().chain(r.dir.to_array())),
        );
        let closest: Vec<f32> = rays
            .par_iter()
            .map(|r| {
                bvh.intersect(r, 0.0, f32::INFINITY)
                    .map_or(f32::INFINITY, |h| h.t)
            })
            .collect();
        write_f32s(dir, &format!("{set}_closest.f32"), closest.into_iter());
        let occluded: Vec<u8> = rays
            .par_iter()
            .map(|r| u8::from(bvh.occluded(r, 0.0, f32::INFINITY)))
            .collect();
        std::fs::write(dir.join(format!("{set}_occluded.u8")), occluded)
            .expect("writing an export file");
    }
    println!("exported the mesh, rays and answers to {}", dir.display());
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let export_dir = support::flag_value(&args, "--export").map(PathBuf::from);
    let mut rng = Rng::new(2024, 1);
    let tris = bumpy_sphere(708, 708, &mut rng);
    println!("mesh: bumpy sphere, {} triangles", tris.len());

    let mut bvh = None;
    for threads in [1, 2] {
        let p = pool(threads);
        let (secs, cpu, built) = time(2, || {
            p.install(|| Bvh::build(&tris).expect("within the triangle limit"))
        });
        println!(
            "build ({threads} thread{}): {:.3} s wall, {:.3} s CPU",
            if threads > 1 { "s" } else { "" },
            secs,
            cpu.unwrap_or(f64::NAN)
        );
        bvh = Some(built);
    }
    let bvh = bvh.expect("built");
    println!(
        "memory: {:.1} MiB ({:.1} bytes/triangle)",
        bvh.memory_bytes() as f64 / (1 << 20) as f64,
        bvh.memory_bytes() as f64 / tris.len() as f64
    );

    let sets = [
        ("primary (coherent)", camera_rays(1024)),
        ("random (incoherent)", random_rays(1 << 20, &bvh, &mut rng)),
    ];
    if let Some(dir) = &export_dir {
        export(dir, &tris, &bvh, &sets);
    }
    println!();
    println!(
        "{:<20} {:<9} {:>7} {:>14} {:>18} {:>9}",
        "rays", "query", "threads", "Mrays/s wall", "Mrays/CPU-second", "hit frac"
    );
    for (name, rays) in &sets {
        for query in ["closest", "occluded"] {
            for threads in [1, 2] {
                let (wall, cpu, hits) = throughput(&bvh, rays, query, threads);
                println!(
                    "{:<20} {:<9} {:>7} {:>14.2} {:>18.2} {:>9.3}",
                    name, query, threads, wall, cpu, hits
                );
            }
        }
    }
    println!();
    println!(
        "{:<20} {:<9} {:>14} {:>18}",
        "rays", "query", "nodes per ray", "triangles per ray"
    );
    for (name, rays) in &sets {
        for query in ["closest", "occluded"] {
            let (nodes, triangles) = counts_per_ray(&bvh, rays, query);
            println!("{name:<20} {query:<9} {nodes:>14.1} {triangles:>18.1}");
        }
    }
    instanced_scene(&mut rng);
}
