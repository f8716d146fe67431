//! What each of Nimbus's per-medium method choices wins ("model no more than a scene needs"), measured side by
//! side in one run on scenes where the choice applies.
//!
//! `cargo bench --bench method_choices -- [--quick] [--threads N] [--out DIR]` (defaults: 2 threads, `--out
//! target/method_choices`; `--out docs` regenerates the figures `docs/method_choices.md` shows).
//!
//! Every scene is a box of medium in a constant environment, so every configuration estimates the same image and
//! its error is measured against a known answer: white furnaces (albedo 1, radiance 1 everywhere) or, for the
//! absorbing slab, a 1024-spp render of the closed form. Configurations compared render interleaved, a few
//! seeds each; each reports seconds per render, MSE, and efficiency 1/(MSE·seconds), the quantity a choice must
//! win. Comparisons:
//! - constant density: the homogeneous closed form against the same box as a constant 64³ VDB-style grid
//!   (delta tracking over its auto-chosen majorants), per ray without geometry, and in whole renders inside the
//!   same box mesh and without one;
//! - absorption only: no collisions sampled against tracking a medium with σ_s = 10⁻⁶ σ_a;
//! - grey σ_t: one exponential for all channels against spectral MIS forced on;
//! - chromaticity sweep: σ_t = (1/√r, 1, √r) for r from 1 to 100, spectral MIS with the channel chosen by path
//!   throughput (Nimbus's pick) against a uniform channel choice and against three grey renders, one per
//!   channel. Writes `chromaticity.csv` and a log-log chart `chromaticity.png`/`.svg` of worst-channel
//!   relative MSE × seconds (lower is better) against r.

#[path = "../tests/common/mod.rs"]
mod common;
mod support;

use glam::{DMat4, DVec3, IVec3};
use nimbus::converge::{draw_loglog_chart, LegendCorner, LogLogChart, Series};
use nimbus::light::EnvironmentLight;
use nimbus::math::sampling::uniform_sphere;
use nimbus::math::{Ray, Rgb, Rng, Vec3};
use nimbus::render::{RenderImage, RenderSettings, Renderer};
use nimbus::scene::{Camera, SceneBuilder};
use nimbus::vdb::{GridTree, Tree};
use nimbus::volume::density::GridDensity;
use nimbus::volume::grid::GridMedium;
use nimbus::volume::homogeneous::{ChannelChoice, HomogeneousMedium};
use nimbus::volume::{Medium, TentativeEmission, TrackingCounters};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// Image size, samples per pixel and seeds per configuration.
#[derive(Clone, Copy)]
struct Budget {
    size: usize,
    spp: u32,
    seeds: u64,
    threads: usize,
}

/// A box medium [-1,1]³ seen from +z against a constant environment of radiance 1.
fn box_scene(medium: Arc<dyn Medium>, with_boundary: bool) -> SceneBuilder {
    let mut b = SceneBuilder::default();
    let id = b.add_medium(medium);
    if with_boundary {
        let mat = b.add_material(common::boundary(id));
        b.add_mesh(common::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), mat));
    }
    b.set_environment(EnvironmentLight::Constant(Rgb::ONE));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::ZERO,
        30f32.to_radians(),
    ));
    b
}

fn homogeneous_box(medium: HomogeneousMedium) -> SceneBuilder {
    box_scene(Arc::new(medium), true)
}

/// A purely scattering (albedo 1) grey medium of extinction `sigma`, for white furnaces.
fn grey_medium(sigma: f32) -> HomogeneousMedium {
    HomogeneousMedium::new("grey", Rgb::ZERO, Rgb::splat(sigma), 0.0)
}

/// The box [-1,1]³ as a constant grid of 64³ voxels of density `sigma`, albedo 1.
fn constant_grid(sigma: f32) -> GridMedium {
    let n = 64;
    let voxel = 2.0 / n as f64;
    let voxels = (0..n)
        .flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| (IVec3::new(x, y, z), 1.0f32))));
    let tree = Tree::from_voxels(0.0, voxels);
    // Voxel centres at (i + ½)·voxel − 1, so the constant interior spans [-1, 1]³.
    let index_to_world = DMat4::from_translation(DVec3::splat(-1.0 + 0.5 * voxel))
        * DMat4::from_scale(DVec3::splat(voxel));
    let density = GridDensity::from_tree(Arc::new(GridTree::Float(tree)), index_to_world, sigma)
        .expect("a constant grid is valid");
    GridMedium::with_chosen_majorants("grid", density, Rgb::ONE, 0.0)
}

/// The constant grid in the furnace. A grid medium needs no boundary mesh (its bounds are its active voxels);
/// `inside_mesh` adds the homogeneous box's mesh as an empty index-matched surface, so that both scenes
/// intersect the same geometry.
fn constant_grid_box(sigma: f32, inside_mesh: bool) -> SceneBuilder {
    let mut b = box_scene(Arc::new(constant_grid(sigma)), false);
    if inside_mesh {
        let mut surface = common::boundary(0);
        surface.interior = None;
        let mat = b.add_material(surface);
        b.add_mesh(common::cuboid(Vec3::splat(-1.0), Vec3::splat(1.0), mat));
    }
    b
}

/// A medium's estimators alone, without geometry, on rays from uniform points of [-0.95, 0.95]³ (where the
/// grid's trilinear density is exactly constant) in uniform directions, up to that box's exit: ns per ray for a
/// free flight plus a shadow-ray transmittance (best of 3 rounds, one thread), the transmittance estimate's MSE
/// against exp(−σ d), and density lookups per ray.
fn per_ray(medium: &dyn Medium, sigma: f32, n: usize) -> (f64, f64, f64) {
    let mut rng = Rng::new(5, 9);
    let half = 0.95f32;
    let rays: Vec<(Ray, f32)> = (0..n)
        .map(|_| {
            let o = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0) * half;
            let d = uniform_sphere(rng.next_2d());
            let exit = (0..3)
                .map(|k| (half.copysign(d[k]) - o[k]) / d[k])
                .fold(f32::INFINITY, f32::min);
            (Ray::new(o, d), exit)
        })
        .collect();
    let mut best = f64::INFINITY;
    let mut counters = TrackingCounters::default();
    let mut squared_error = 0.0;
    for _round in 0..3 {
        counters = TrackingCounters::default();
        squared_error = 0.0;
        let mut rng = Rng::new(17, 1);
        let mut sink = 0.0f32;
        let start = Instant::now();
        for (ray, t_max) in &rays {
            let t = medium
                .free_flight(
                    ray,
                    *t_max,
                    Rgb::ONE,
                    &mut rng,
                    &mut counters,
                    &mut TentativeEmission::default(),
                )
                .collision;
            sink += t.unwrap_or(*t_max);
            let estimate = medium.transmittance(ray, *t_max, &mut rng, &mut counters).y;
            squared_error += ((estimate - (-sigma * t_max).exp()) as f64).powi(2);
        }
        best = best.min(start.elapsed().as_nanos() as f64 / n as f64);
        std::hint::black_box(sink);
    }
    (
        best,
        squared_error / n as f64,
        counters.density_lookups as f64 / n as f64,
    )
}

/// One configuration's renders: total seconds, per-channel MSE against the answer, and the method it used.
#[derive(Clone, Debug, Default)]
struct Measured {
    seconds: f64,
    mse: [f64; 3],
    renders: u32,
    method: String,
}

impl Measured {
    fn seconds_per_render(&self) -> f64 {
        self.seconds / self.renders.max(1) as f64
    }

    fn mean_mse(&self) -> [f64; 3] {
        self.mse.map(|m| m / self.renders.max(1) as f64)
    }

    /// MSE averaged over channels.
    fn mse_grey(&self) -> f64 {
        self.mean_mse().iter().sum::<f64>() / 3.0
    }

    /// 1 / (MSE · seconds), the inverse cost of a given error.
    fn efficiency(&self) -> f64 {
        1.0 / (self.mse_grey() * self.seconds_per_render())
    }
}

fn render(builder: SceneBuilder, budget: Budget, seed: u64) -> (RenderImage, f64, String) {
    let scene = builder.build().unwrap();
    let settings = RenderSettings {
        width: budget.size,
        height: budget.size,
        spp: budget.spp,
        seed,
        threads: budget.threads,
        max_depth: 100_000,
        ..Default::default()
    };
    let start = Instant::now();
    let (img, stats) = Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .expect("render");
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(stats.nan_samples, 0, "NaN samples");
    let method = stats
        .media
        .first()
        .map(|m| m.method.clone())
        .unwrap_or_default();
    (img, seconds, method)
}

/// Per-channel mean squared error of `img` against `answer` (one value per pixel).
fn mse(img: &RenderImage, answer: &dyn Fn(usize) -> Rgb) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for (i, p) in img.beauty.iter().enumerate() {
        let a = answer(i);
        for (c, s) in sum.iter_mut().enumerate() {
            *s += ((p[c] - a[c]) as f64).powi(2);
        }
    }
    sum.map(|s| s / img.pixel_count() as f64)
}

/// Renders every configuration `seeds` times, interleaved, and measures each against `answer`.
fn measure(
    configs: &[&dyn Fn() -> SceneBuilder],
    answer: &dyn Fn(usize) -> Rgb,
    budget: Budget,
) -> Vec<Measured> {
    let mut out = vec![Measured::default(); configs.len()];
    for seed in 0..budget.seeds {
        for (config, m) in configs.iter().zip(&mut out) {
            let (img, seconds, method) = render(config(), budget, 1000 + seed);
            let e = mse(&img, answer);
            m.seconds += seconds;
            for (sum, e) in m.mse.iter_mut().zip(e) {
                *sum += e;
            }
            m.renders += 1;
            m.method = method;
        }
    }
    out
}

fn white(_: usize) -> Rgb {
    Rgb::ONE
}

/// Prints configurations as a markdown table, Nimbus's pick first, with each one's speed and efficiency relative
/// to the pick.
fn print_comparison(title: &str, labels: &[&str], m: &[Measured]) {
    println!("\n### {title}\n");
    println!(
        "| configuration | method (stats) | ms per render | MSE | efficiency 1/(MSE·s) | pick's speed-up | pick's efficiency gain |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (label, m_i) in labels.iter().zip(m) {
        println!(
            "| {label} | {} | {:.1} | {:.3e} | {:.3e} | {:.2}× | {:.3}× |",
            m_i.method,
            1e3 * m_i.seconds_per_render(),
            m_i.mse_grey(),
            m_i.efficiency(),
            m_i.seconds_per_render() / m[0].seconds_per_render(),
            m[0].efficiency() / m_i.efficiency()
        );
    }
}

fn constant_density(budget: Budget) {
    let sigma = 2.0;
    let grid = constant_grid(sigma);
    let n = if budget.spp < 64 { 20_000 } else { 200_000 };
    let (h_ns, h_mse, h_lookups) = per_ray(&grey_medium(sigma), sigma, n);
    let (g_ns, g_mse, g_lookups) = per_ray(&grid, sigma, n);
    println!("\n### Constant density → closed form: the estimators alone ({n} rays inside the box, no geometry)\n");
    println!("| medium | ns per ray (free flight + transmittance) | transmittance MSE | lookups per ray |");
    println!("|---|---|---|---|");
    println!("| homogeneous (closed form) | {h_ns:.0} | {h_mse:.3e} | {h_lookups:.2} |");
    println!("| constant 64³ grid | {g_ns:.0} | {g_mse:.3e} | {g_lookups:.2} |");
    println!(
        "\nThe closed form: {:.1}× faster per ray, and its transmittance is exact.",
        g_ns / h_ns
    );
    let m = measure(
        &[
            &|| homogeneous_box(grey_medium(sigma)),
            &|| constant_grid_box(sigma, true),
            &|| constant_grid_box(sigma, false),
        ],
        &white,
        budget,
    );
    print_comparison(
        "Constant density → closed form, whole renders (white furnace, σ_t = 2/m in a 2 m box, albedo 1)",
        &[
            "homogeneous (closed form), bounded by a box mesh",
            "constant 64³ grid in the same (empty, index-matched) box mesh",
            "constant 64³ grid, no mesh (bounded by its voxels)",
        ],
        &m,
    );
}

fn absorption_only(budget: Budget) {
    let sigma_a = Rgb::new(0.5, 1.0, 2.0);
    let absorbing = move || homogeneous_box(HomogeneousMedium::new("box", sigma_a, Rgb::ZERO, 0.0));
    let reference_budget = Budget {
        spp: 1024,
        seeds: 1,
        ..budget
    };
    let (reference, _, _) = render(absorbing(), reference_budget, 7);
    let answer = |i: usize| reference.beauty[i];
    let m = measure(
        &[&absorbing, &move || {
            homogeneous_box(HomogeneousMedium::new("box", sigma_a, sigma_a * 1e-6, 0.0))
        }],
        &answer,
        budget,
    );
    print_comparison(
        "Absorption only → no scattering events (σ_a = (0.5, 1, 2)/m; error against a 1024-spp closed-form render)",
        &["absorption only", "tracked, σ_s = 10⁻⁶ σ_a"],
        &m,
    );
}

fn grey_extinction(budget: Budget) {
    let m = measure(
        &[&|| homogeneous_box(grey_medium(2.0)), &|| {
            homogeneous_box(grey_medium(2.0).with_channel_choice(ChannelChoice::Throughput))
        }],
        &white,
        budget,
    );
    print_comparison(
        "Grey σ_t → no per-channel MIS (white furnace, σ_t = 2/m, albedo 1)",
        &["grey (one exponential)", "spectral MIS forced on"],
        &m,
    );
}

/// Worst channel's relative MSE × seconds per render (the furnace answer is 1, so relative MSE = MSE).
fn worst_channel_cost(m: &Measured) -> f64 {
    m.mean_mse().into_iter().fold(0.0, f64::max) * m.seconds_per_render()
}

fn chromaticity(budget: Budget, out: &std::path::Path) {
    let ratios = [1.0f32, 2.0, 4.0, 10.0, 30.0, 100.0];
    let names = [
        "spectral MIS, channel by throughput (Nimbus)",
        "spectral MIS, uniform channel",
        "three grey renders",
    ];
    let mut costs = vec![Vec::new(); names.len()];
    let mut csv =
        String::from("ratio,method,seconds_per_render,mse_r,mse_g,mse_b,worst_relmse_x_seconds\n");
    println!("\n### Chromatic σ_t = (1/√r, 1, √r)/m, albedo 1, white furnace\n");
    println!("worst-channel relative MSE × seconds per render (lower is better)\n");
    println!(
        "| r | {} | {} | {} | throughput vs uniform |",
        names[0], names[1], names[2]
    );
    println!("|---|---|---|---|---|");
    for &r in &ratios {
        let sigma = Rgb::new(1.0 / r.sqrt(), 1.0, r.sqrt());
        let chromatic = move |choice| {
            homogeneous_box(
                HomogeneousMedium::new("box", Rgb::ZERO, sigma, 0.0).with_channel_choice(choice),
            )
        };
        let m = measure(
            &[&|| chromatic(ChannelChoice::Auto), &|| {
                chromatic(ChannelChoice::Uniform)
            }],
            &white,
            budget,
        );
        // Three grey renders: channel c of the answer comes from a render of the grey medium σ_t = sigma[c].
        let greys = measure(
            &[
                &|| homogeneous_box(grey_medium(sigma.x)),
                &|| homogeneous_box(grey_medium(sigma.y)),
                &|| homogeneous_box(grey_medium(sigma.z)),
            ],
            &white,
            budget,
        );
        let three = Measured {
            seconds: greys.iter().map(|g| g.seconds).sum(),
            mse: [greys[0].mse[0], greys[1].mse[1], greys[2].mse[2]],
            renders: budget.seeds as u32,
            method: "three grey renders".into(),
        };
        let row = [&m[0], &m[1], &three];
        for (i, m) in row.iter().enumerate() {
            let mse = m.mean_mse();
            let cost = worst_channel_cost(m);
            costs[i].push((r as f64, cost));
            csv += &format!(
                "{r},{},{:.6},{:.6e},{:.6e},{:.6e},{cost:.6e}\n",
                names[i],
                m.seconds_per_render(),
                mse[0],
                mse[1],
                mse[2]
            );
        }
        println!(
            "| {r} | {:.3e} | {:.3e} | {:.3e} | {:.2}× |",
            costs[0].last().unwrap().1,
            costs[1].last().unwrap().1,
            costs[2].last().unwrap().1,
            costs[1].last().unwrap().1 / costs[0].last().unwrap().1
        );
    }
    std::fs::create_dir_all(out).expect("create the output folder");
    std::fs::write(out.join("chromaticity.csv"), csv).expect("write chromaticity.csv");
    let chart = LogLogChart {
        caption: "Chromatic extinction: cost of a given worst-channel error".into(),
        x_desc: "chromaticity r (sigma_t = 1/sqrt(r) : 1 : sqrt(r))".into(),
        y_desc: "worst-channel relMSE x seconds".into(),
        series: names
            .iter()
            .zip(costs)
            .map(|(name, points)| Series {
                label: (*name).into(),
                points,
            })
            .collect(),
        guide: None,
        legend: LegendCorner::LowerRight,
    };
    draw_loglog_chart(
        &chart,
        &out.join("chromaticity.png"),
        &out.join("chromaticity.svg"),
    )
    .expect("draw the chart");
    println!("\nwrote {}/chromaticity.{{csv,png,svg}}", out.display());
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| support::flag_value(&args, flag).cloned();
    let quick = args.iter().any(|a| a == "--quick");
    let threads = value("--threads").and_then(|t| t.parse().ok()).unwrap_or(2);
    let out = value("--out")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/method_choices"));
    let budget = if quick {
        Budget {
            size: 16,
            spp: 8,
            seeds: 2,
            threads,
        }
    } else {
        Budget {
            size: 64,
            spp: 64,
            seeds: 4,
            threads,
        }
    };
    println!(
        "method_choices: {0}×{0} px, {1} spp, {2} seeds per configuration, {3} threads",
        budget.size, budget.spp, budget.seeds, budget.threads
    );
    constant_density(budget);
    absorption_only(budget);
    grey_extinction(budget);
    chromaticity(budget, &out);
}
