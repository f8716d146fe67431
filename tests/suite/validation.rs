//! Renders every validation scene and compares it with its reference from another renderer (Mitsuba 3).
//!
//! Scenes come from `../shared/validation/` (required in CI) and from this repository's own
//! `tests/validation/` (made by `tests/validation/make_scenes.py`, referenced with
//! `../shared/tools/gltf2mitsuba.py` by `tests/validation/make_references.sh`). Each scene folder holds
//! `scene.gltf`, `reference_*_128.exr` (the reference's mean) and `reference_*_128_se.exr` (the per-pixel
//! standard error of that mean, from the spread of the reference's independent passes).
//!
//! Nimbus renders each scene at the reference's 128×128, with `max_depth` from the scene's `extras.max_bounces`
//! and a fixed seed. Tolerances come from the measured noise of both images, never from a fixed percentage
//! (see `../shared/validation/README.md`):
//! - **each channel's image mean** must agree within 4 combined standard errors, the render's from its
//!   `variance` layer, the reference's from its `_se` image;
//! - **8×8-blurred blocks**: z = (B_img − B_ref) / √(SE_img² + SE_ref²) for every block and channel. Fireflies
//!   make single renders heavy-tailed, so the distribution of z is judged, not its maximum: few blocks may lie
//!   beyond 4;
//! - **regional bias**: the image is cut into 4×4 regions of 32×32 pixels, and each region's mean must agree
//!   with the reference's within 4.5 combined standard errors in every channel (48 tests: a false alarm
//!   once in about 400 seeds). This is where a localised bias shows, such as a wrong shadow or a wrong texture
//!   filter. The mean of the block z values, which the validation README also suggests, is printed but not
//!   asserted: with heavy-tailed samples a block's mean and its estimated variance are correlated (blocks that
//!   missed a rare bright sample are both darker and look less noisy), which drags the mean of z below 0
//!   without any bias; pooling a region's 1024 pixels before dividing avoids that;
//! - **the blurred relative RMSE** over the blocks must stay near its noise floor, the value that the two
//!   images' standard errors alone would give.
//!
//! The compositing layers are compared the same way with references of their own (see
//! `tests/validation/README.md`): the direct light (the `*_direct` layers times their colours, plus `emission`
//! and `environment`) with Mitsuba renders limited to one scattering event, each light group's layer with a
//! Mitsuba render of that group's emitters alone, and the alpha with Mitsuba's alpha. Those layers have no
//! variance layer of their own: each scene is rendered as [`PARTS`] sample ranges (merged exactly into the
//! beauty's render), and a layer's per-pixel standard error comes from the spread of the parts.
//!
//! Run `cargo test --release --test suite validation:: -- --nocapture` for the table of every figure. With
//! `NIMBUS_TEST_GUIDING=on` (or `off`, `auto`: the default) every scene renders with that `--guiding` mode, so
//! that the suite also checks that path guiding leaves every mean unchanged.

use crate::common;

use nimbus::math::Rgb;
use nimbus::output::read_exr_layers;
use nimbus::render::aovs::AovSelection;
use nimbus::render::{
    CancelToken, Film, GuidingMode, PixelWindow, RenderImage, RenderRegion, RenderSettings,
    Renderer,
};
use nimbus::Scene;
use std::path::{Path, PathBuf};

/// Side of the blur blocks, in pixels.
const BLOCK: usize = 8;
/// Combined standard errors allowed between the two image means.
const MEAN_Z_LIMIT: f64 = 4.0;
/// Fraction of (block, channel) pairs allowed beyond |z| = 4. Under Gaussian noise the expected fraction is
/// 6e-5; the margin covers heavy-tailed blocks whose standard error is underestimated at low sample counts.
const OUTLIER_FRACTION_LIMIT: f64 = 0.02;
/// Side of the regions of the bias test, in pixels.
const REGION: usize = 32;
/// Combined standard errors allowed between a region's mean and the reference's.
const REGION_Z_LIMIT: f64 = 4.5;
/// Allowed ratio of the blurred relative RMSE to its noise floor.
const REL_RMSE_RATIO_LIMIT: f64 = 1.5;
/// Seed of every render.
const SEED: u64 = 1;
/// Sample ranges each scene is rendered in, for the standard errors of layers without a variance layer.
const PARTS: u32 = 16;

/// Samples per pixel for a scene: enough for a meaningful noise floor, few enough to keep the whole test under
/// three minutes on two cores.
fn spp_for(scene: &str) -> u32 {
    match scene {
        "point-in-medium" => 1024,
        _ => 512,
    }
}

/// The relative error allowed to a layer reference beyond its standard error, where it was measured apart.
///
/// `point-in-medium`'s direct light: where the floor is lit by the point light through the haze sphere (the
/// bottom rows), Nimbus's direct light is deterministic (closed-form transmittance through the homogeneous
/// medium) and matches a closed form of its own, ρ/π · I cos θ / r² · e^(−σ_t ℓ) with ℓ the chord through the
/// sphere's mesh, to 0.02 % (100 pixels, pixel centres), while the 65536-spp Mitsuba reference is 0.11 % above
/// it (measured 2026-12-03 with a numpy ray–mesh intersection). Its regions there sit 6 to 8 of its own
/// standard errors above Nimbus; 0.15 % covers that.
fn reference_allowance(scene: &str, what: &str) -> f64 {
    match (scene, what) {
        ("point-in-medium", "direct light") => 0.0015,
        _ => 0.0,
    }
}

/// A scene folder with its reference images.
struct ValidationScene {
    name: String,
    gltf: PathBuf,
    reference: PathBuf,
    reference_se: PathBuf,
}

/// Every scene folder under `root` that has a `scene.gltf` and a reference pair.
fn scenes_in(root: &Path) -> Vec<ValidationScene> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(root) else {
        return out;
    };
    for entry in entries.flatten() {
        let dir = entry.path();
        let gltf = dir.join("scene.gltf");
        if !gltf.is_file() {
            continue;
        }
        let reference = std::fs::read_dir(&dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .find(|p| {
                let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
                name.starts_with("reference_") && name.ends_with("_128.exr")
            });
        let Some(reference) = reference else {
            panic!(
                "{}: scene.gltf without a reference_*_128.exr",
                dir.display()
            );
        };
        let reference_se = reference.with_file_name(
            reference
                .file_name()
                .unwrap()
                .to_str()
                .unwrap()
                .replace(".exr", "_se.exr"),
        );
        assert!(
            reference_se.is_file(),
            "{} is missing",
            reference_se.display()
        );
        out.push(ValidationScene {
            name: dir.file_name().unwrap().to_string_lossy().into_owned(),
            gltf,
            reference,
            reference_se,
        });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// Reads the beauty of an EXR as RGB pixels (a file with only an `A` channel, an alpha reference, as grey).
fn read_rgb(path: &Path) -> (usize, usize, Vec<Rgb>) {
    let layers = read_exr_layers(path).unwrap_or_else(|e| panic!("{e}"));
    let rgb = layers
        .rgb("")
        .or_else(|| {
            let a = layers.channel("A")?;
            Some(a.iter().map(|&a| Rgb::splat(a)).collect())
        })
        .unwrap_or_else(|| panic!("{} has no R, G, B (or A) channels", path.display()));
    (layers.width, layers.height, rgb)
}

/// An image's estimate: per pixel, the mean and the variance of that mean.
struct Estimate {
    width: usize,
    height: usize,
    mean: Vec<Rgb>,
    var: Vec<Rgb>,
}

impl Estimate {
    /// The beauty of a render, with its variance layer.
    fn of_beauty(img: &RenderImage) -> Self {
        Self {
            width: img.width,
            height: img.height,
            mean: img.beauty.clone(),
            var: img.variance.clone(),
        }
    }

    /// The mean of independent parts' images of the same quantity (equal sample counts), with the variance of
    /// that mean from their spread.
    fn of_parts(parts: &[Vec<Rgb>], width: usize, height: usize) -> Self {
        let k = parts.len() as f32;
        let mut mean = vec![Rgb::ZERO; width * height];
        let mut var = vec![Rgb::ZERO; width * height];
        for i in 0..width * height {
            let m = parts.iter().fold(Rgb::ZERO, |a, p| a + p[i]) / k;
            let ss = parts
                .iter()
                .fold(Rgb::ZERO, |a, p| a + (p[i] - m) * (p[i] - m));
            mean[i] = m;
            var[i] = ss / (k - 1.0) / k;
        }
        Self {
            width,
            height,
            mean,
            var,
        }
    }
}

/// The direct light of a render from its light-path layers: Σ (c_direct × c_color) over the surface classes,
/// plus `volume_direct`, `emission` and `environment` (what Mitsuba renders with one scattering event).
fn direct_light(img: &RenderImage) -> Vec<Rgb> {
    let layer = |name: &str| {
        img.aov(name)
            .unwrap_or_else(|| panic!("no {name} layer"))
            .rgb_pixels()
    };
    let mut sum = layer("emission");
    for name in ["environment", "volume_direct"] {
        sum.iter_mut().zip(layer(name)).for_each(|(s, v)| *s += v);
    }
    for class in ["diffuse", "glossy", "transmission"] {
        let color = layer(&format!("{class}_color"));
        let light = layer(&format!("{class}_direct"));
        for ((s, l), c) in sum.iter_mut().zip(light).zip(color) {
            *s += l * c;
        }
    }
    sum
}

/// What the comparison of one scene measured.
#[derive(Debug)]
struct Comparison {
    mean: [f64; 3],
    reference_mean: [f64; 3],
    mean_z: [f64; 3],
    outlier_fraction: f64,
    /// Per channel: the mean of the block z values × √(blocks) (reported, not asserted; see the module docs).
    bias_z: [f64; 3],
    /// The region z value furthest from 0, with its region and channel.
    worst_region: (f64, usize, usize, usize),
    rel_rmse: f64,
    rel_rmse_floor: f64,
}

impl Comparison {
    fn failures(&self) -> Vec<String> {
        let mut out = Vec::new();
        for c in 0..3 {
            if self.mean_z[c].abs() > MEAN_Z_LIMIT || !self.mean_z[c].is_finite() {
                out.push(format!(
                    "channel {c} mean {:.5} vs reference {:.5} (z = {:.1})",
                    self.mean[c], self.reference_mean[c], self.mean_z[c]
                ));
            }
        }
        if self.outlier_fraction > OUTLIER_FRACTION_LIMIT {
            out.push(format!(
                "{:.1}% of blurred blocks beyond |z| = 4 (limit {:.1}%)",
                100.0 * self.outlier_fraction,
                100.0 * OUTLIER_FRACTION_LIMIT
            ));
        }
        let (z, rx, ry, c) = self.worst_region;
        if z.abs() > REGION_Z_LIMIT || !z.is_finite() {
            out.push(format!(
                "region ({rx}, {ry}) of {REGION}×{REGION} pixels is biased in channel {c}: z = {z:.1}"
            ));
        }
        if self.rel_rmse.is_nan() || self.rel_rmse > REL_RMSE_RATIO_LIMIT * self.rel_rmse_floor {
            out.push(format!(
                "blurred relative RMSE {:.4} above {REL_RMSE_RATIO_LIMIT} × its noise floor {:.4}",
                self.rel_rmse, self.rel_rmse_floor
            ));
        }
        out
    }
}

/// Compares an estimate (mean and variance of the mean per pixel) with a reference (mean and standard error).
/// `allowance` is a relative error of the reference itself, measured apart (see [`reference_allowance`]),
/// added to every standard error in quadrature.
fn compare(img: &Estimate, reference: &[Rgb], reference_se: &[Rgb], allowance: f64) -> Comparison {
    let (w, h) = (img.width, img.height);
    let n = (w * h) as f64;
    let mut mean = [0.0; 3];
    let mut reference_mean = [0.0; 3];
    let mut mean_z = [0.0; 3];
    for c in 0..3 {
        let sum: f64 = img.mean.iter().map(|p| p[c] as f64).sum();
        let var: f64 = img.var.iter().map(|v| v[c] as f64).sum();
        let ref_sum: f64 = reference.iter().map(|p| p[c] as f64).sum();
        let ref_var: f64 = reference_se.iter().map(|s| (s[c] as f64).powi(2)).sum();
        mean[c] = sum / n;
        reference_mean[c] = ref_sum / n;
        let se = ((var + ref_var) / (n * n) + (allowance * reference_mean[c]).powi(2)).sqrt();
        mean_z[c] = (mean[c] - reference_mean[c]) / se.max(1e-12 * reference_mean[c].abs());
    }
    // 8×8 blocks.
    let (bw, bh) = (w / BLOCK, h / BLOCK);
    let per_block = (BLOCK * BLOCK) as f64;
    let image_scale = reference_mean.iter().sum::<f64>() / 3.0;
    // Relative errors are taken against the block's reference value, with a floor of 1% of the image mean so
    // that black blocks do not divide by zero.
    let eps = 0.01 * image_scale.max(1e-12);
    let mut zs = Vec::new();
    let mut channel_z_sum = [0.0; 3];
    let (mut rel_sq, mut floor_sq) = (0.0, 0.0);
    for by in 0..bh {
        for bx in 0..bw {
            for c in 0..3 {
                let (mut b_img, mut b_ref, mut v_img, mut v_ref) = (0.0, 0.0, 0.0, 0.0);
                for y in by * BLOCK..(by + 1) * BLOCK {
                    for x in bx * BLOCK..(bx + 1) * BLOCK {
                        let i = y * w + x;
                        b_img += img.mean[i][c] as f64;
                        b_ref += reference[i][c] as f64;
                        v_img += img.var[i][c] as f64;
                        v_ref += (reference_se[i][c] as f64).powi(2);
                    }
                }
                b_img /= per_block;
                b_ref /= per_block;
                let se2 = (v_img + v_ref) / (per_block * per_block) + (allowance * b_ref).powi(2);
                let diff = b_img - b_ref;
                // Blocks without noise in either image (e.g. a constant background) must agree to rounding.
                let se = se2.sqrt().max(1e-5 * b_ref.abs() + 1e-9);
                zs.push(diff / se);
                channel_z_sum[c] += diff / se;
                let denom = b_ref * b_ref + eps * eps;
                rel_sq += diff * diff / denom;
                floor_sq += se2 / denom;
            }
        }
    }
    let count = zs.len() as f64;
    let outliers = zs
        .iter()
        .filter(|z| z.abs() > 4.0 || !z.is_finite())
        .count() as f64;
    let blocks = (bw * bh) as f64;
    Comparison {
        mean,
        reference_mean,
        mean_z,
        outlier_fraction: outliers / count,
        bias_z: channel_z_sum.map(|s| s / blocks * blocks.sqrt()),
        worst_region: worst_region(img, reference, reference_se, allowance),
        rel_rmse: (rel_sq / count).sqrt(),
        rel_rmse_floor: (floor_sq / count).sqrt(),
    }
}

/// The region z value furthest from 0: `(z, region x, region y, channel)`.
fn worst_region(
    img: &Estimate,
    reference: &[Rgb],
    reference_se: &[Rgb],
    allowance: f64,
) -> (f64, usize, usize, usize) {
    let w = img.width;
    let mut worst = (0.0f64, 0, 0, 0);
    for ry in 0..img.height / REGION {
        for rx in 0..w / REGION {
            for c in 0..3 {
                let (mut diff, mut var, mut sum) = (0.0, 0.0, 0.0);
                for y in ry * REGION..(ry + 1) * REGION {
                    for x in rx * REGION..(rx + 1) * REGION {
                        let i = y * w + x;
                        diff += img.mean[i][c] as f64 - reference[i][c] as f64;
                        var += img.var[i][c] as f64 + (reference_se[i][c] as f64).powi(2);
                        sum += reference[i][c] as f64;
                    }
                }
                // As for blocks: a region without noise (constant background) must agree to rounding.
                let pixels = (REGION * REGION) as f64;
                let var = var + (allowance * sum).powi(2);
                let z = diff / var.sqrt().max(1e-5 * sum.abs() + 1e-9 * pixels);
                if z.abs() > worst.0.abs() || !z.is_finite() {
                    worst = (z, rx, ry, c);
                }
            }
        }
    }
    worst
}

/// The reference pair `reference_mitsuba_<what>_*_128.exr` and its `_se` in `dir`, if there is one.
fn reference_pair(dir: &Path, what: &str) -> Option<(PathBuf, PathBuf)> {
    let prefix = format!("reference_mitsuba_{what}_");
    let file = std::fs::read_dir(dir)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            name.starts_with(&prefix) && name.ends_with("spp_128.exr")
        })?;
    let se = file.with_file_name(file.file_name()?.to_str()?.replace(".exr", "_se.exr"));
    Some((file, se))
}

/// The layer references of a scene (see the module docs): (what, the function giving it from a render,
/// reference, standard error).
type LayerCheck = (
    String,
    Box<dyn Fn(&RenderImage) -> Vec<Rgb>>,
    PathBuf,
    PathBuf,
);

/// The layer references of scene `name` under `tests/validation/{direct,groups,alpha}/<name>/`.
fn layer_checks(name: &str) -> Vec<LayerCheck> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/validation");
    let mut out: Vec<LayerCheck> = Vec::new();
    if let Some((r, se)) = reference_pair(&root.join("direct").join(name), "direct") {
        out.push(("direct light".into(), Box::new(direct_light), r, se));
    }
    if let Some((r, se)) = reference_pair(&root.join("alpha").join(name), "alpha") {
        out.push((
            "alpha".into(),
            Box::new(|img: &RenderImage| img.alpha.iter().map(|&a| Rgb::splat(a)).collect()),
            r,
            se,
        ));
    }
    let groups = std::fs::read_dir(root.join("groups").join(name))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let file = e.file_name().to_str()?.to_owned();
            let group = file.strip_prefix("reference_mitsuba_group_")?;
            let group = &group[..group.find('_')?];
            (!file.ends_with("_se.exr")).then(|| group.to_owned())
        })
        .collect::<std::collections::BTreeSet<String>>();
    for group in groups {
        let (r, se) =
            reference_pair(&root.join("groups").join(name), &format!("group_{group}")).unwrap();
        let layer = format!("lg_{group}");
        out.push((
            format!("light group {group}"),
            Box::new(move |img: &RenderImage| {
                img.aov(&layer)
                    .unwrap_or_else(|| panic!("no layer {layer}"))
                    .rgb_pixels()
            }),
            r,
            se,
        ));
    }
    out
}

/// Renders one scene in [`PARTS`] sample ranges and compares the beauty (and any layer references) with its
/// references; returns the table rows and any failures.
fn validate(scene: &ValidationScene) -> (Vec<String>, Vec<String>) {
    let (w, h, reference) = read_rgb(&scene.reference);
    let (ws, hs, reference_se) = read_rgb(&scene.reference_se);
    assert_eq!((w, h), (ws, hs), "{}: reference sizes differ", scene.name);
    let loaded = Scene::load(&scene.gltf).unwrap_or_else(|e| panic!("{e}"));
    let spp = spp_for(&scene.name);
    let checks = layer_checks(&scene.name);
    let settings = RenderSettings {
        width: w,
        height: h,
        spp,
        seed: SEED,
        threads: 0,
        max_depth: loaded.max_bounces().unwrap_or(64),
        aovs: Some(AovSelection::parse("default,lightpaths,colors,lightgroups").unwrap()),
        guiding: guiding_mode(),
        ..Default::default()
    };
    let renderer = Renderer::new(settings);
    let start = std::time::Instant::now();
    let (mut whole, mut parts, mut nan_samples) = (None::<Film>, Vec::new(), 0);
    for k in 0..PARTS {
        let region = RenderRegion {
            window: PixelWindow::full(w, h),
            samples: k * spp / PARTS..(k + 1) * spp / PARTS,
        };
        let (film, stats) = renderer
            .render_region(&loaded, &region, &mut |_| true, &CancelToken::new())
            .unwrap();
        nan_samples += stats.nan_samples;
        parts.push(film.image());
        match &mut whole {
            Some(f) => assert_eq!(f.merge(&film), Ok(())),
            None => whole = Some(film),
        }
    }
    let img = whole.unwrap().image();
    let seconds = start.elapsed().as_secs_f64();
    let mut failures = Vec::new();
    if nan_samples > 0 {
        failures.push(format!("{nan_samples} NaN/Inf samples"));
    }
    let mut rows = vec![row(
        &scene.name,
        spp,
        &compare(&Estimate::of_beauty(&img), &reference, &reference_se, 0.0),
        seconds,
        &mut failures,
    )];
    for (what, layer, file, se_file) in &checks {
        let (_, _, reference) = read_rgb(file);
        let (_, _, reference_se) = read_rgb(se_file);
        let values: Vec<Vec<Rgb>> = parts.iter().map(layer).collect();
        let estimate = Estimate::of_parts(&values, w, h);
        let mut layer_failures = Vec::new();
        let cmp = compare(
            &estimate,
            &reference,
            &reference_se,
            reference_allowance(&scene.name, what),
        );
        rows.push(row(
            &format!("{} ({what})", scene.name),
            spp,
            &cmp,
            0.0,
            &mut layer_failures,
        ));
        failures.extend(layer_failures.into_iter().map(|f| format!("{what}: {f}")));
    }
    (rows, failures)
}

/// The guiding mode `NIMBUS_TEST_GUIDING` names (auto when unset).
fn guiding_mode() -> GuidingMode {
    use nimbus::params::Choice;
    match std::env::var("NIMBUS_TEST_GUIDING") {
        Ok(name) => GuidingMode::from_name(&name)
            .unwrap_or_else(|| panic!("NIMBUS_TEST_GUIDING={name}: not auto, on or off")),
        Err(_) => GuidingMode::Auto,
    }
}

/// The table row of one comparison; its failures are added to `failures`.
fn row(name: &str, spp: u32, cmp: &Comparison, seconds: f64, failures: &mut Vec<String>) -> String {
    failures.extend(cmp.failures());
    format!(
        "| {} | {spp} | {:.4} {:.4} {:.4} | {:.4} {:.4} {:.4} | {:+.1} {:+.1} {:+.1} | {:.2}% | {:+.1} {:+.1} {:+.1} | {:+.1} | {:.4} | {:.4} | {:.1} |",
        name,
        cmp.mean[0],
        cmp.mean[1],
        cmp.mean[2],
        cmp.reference_mean[0],
        cmp.reference_mean[1],
        cmp.reference_mean[2],
        cmp.mean_z[0],
        cmp.mean_z[1],
        cmp.mean_z[2],
        100.0 * cmp.outlier_fraction,
        cmp.bias_z[0],
        cmp.bias_z[1],
        cmp.bias_z[2],
        cmp.worst_region.0,
        cmp.rel_rmse,
        cmp.rel_rmse_floor,
        seconds,
    )
}

/// The folders holding validation scenes: `tests/validation`, and `../shared/validation` when it is there.
fn scene_roots() -> Vec<PathBuf> {
    let mut roots = vec![Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/validation")];
    roots.extend(common::shared_dir().map(|shared| shared.join("validation")));
    roots
}

/// Renders the validation scene `name` and compares it with its references, printing its rows of the table.
/// A shared scene is skipped when `../shared` is absent, unless CI requires it.
fn validate_scene(name: &str) {
    let Some(scene) = scene_roots()
        .iter()
        .flat_map(|root| scenes_in(root))
        .find(|scene| scene.name == name)
    else {
        let required = std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() == Ok("1");
        assert!(
            SHARED_SCENES.contains(&name) && !required,
            "validation scene {name} not found under {:?}",
            scene_roots()
        );
        eprintln!("skipped: validation scene {name} needs ../shared");
        return;
    };
    println!(
        "| scene | spp | Nimbus mean (R G B) | reference mean | mean z | blocks |z|>4 | block mean z·√N (R G B) | worst region z | blurred relRMSE | noise floor | seconds |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let (rows, failures) = validate(&scene);
    for row in rows {
        println!("{row}");
    }
    assert!(
        failures.is_empty(),
        "{name}: validation failures:\n{}",
        failures.join("\n")
    );
}

/// One test per validation scene, so that one failing scene does not hide the others; the lists of the shared
/// suite's scenes (`../shared/validation`) and this repository's (`tests/validation`) are made from the same names.
macro_rules! validation_tests {
    (shared: {$($shared:ident => $shared_scene:literal,)*} local: {$($local:ident => $local_scene:literal,)*}) => {
        $(
            #[test]
            fn $shared() {
                validate_scene($shared_scene);
            }
        )*
        $(
            #[test]
            fn $local() {
                validate_scene($local_scene);
            }
        )*
        /// The scenes of `../shared/validation` that have a test.
        const SHARED_SCENES: &[&str] = &[$($shared_scene),*];
        /// The scenes of `tests/validation` that have a test.
        const LOCAL_SCENES: &[&str] = &[$($local_scene),*];
    };
}

validation_tests! {
    shared: {
        area_light_floor => "area-light-floor",
        glass_sphere => "glass-sphere",
        mirror_closeup => "mirror-closeup",
        point_in_medium => "point-in-medium",
        punctual_lights => "punctual-lights",
        scattering_box => "scattering-box",
        smoke_sun => "smoke-sun",
        textures => "textures",
    }
    local: {
        diffuse_transmission => "diffuse-transmission",
        light_groups => "light-groups",
        spot_cone => "spot-cone",
        textured_emitter => "textured-emitter",
        thin_lens => "thin-lens",
    }
}

/// The names of the scene folders under `root`, sorted.
fn sorted_scene_names(root: &Path) -> Vec<String> {
    let mut names: Vec<String> = scenes_in(root).into_iter().map(|s| s.name).collect();
    names.sort_unstable();
    names
}

/// `names`, sorted, as owned strings.
fn sorted(names: &[&str]) -> Vec<String> {
    let mut names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
    names.sort_unstable();
    names
}

/// A scene folder added without its test (or a test whose folder is gone) fails here.
#[test]
fn every_validation_scene_on_disk_has_its_own_test() {
    assert_eq!(
        sorted_scene_names(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/validation")),
        sorted(LOCAL_SCENES),
        "tests/validation's scene folders"
    );
    if let Some(shared) = common::shared_dir() {
        assert_eq!(
            sorted_scene_names(&shared.join("validation")),
            sorted(SHARED_SCENES),
            "../shared/validation's scene folders"
        );
    }
}
