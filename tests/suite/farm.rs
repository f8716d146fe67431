//! Render-farm splits: sample-range and crop parts of the bundled cloud scene (a VDB medium over a lit ground
//! plane), written as part files and merged, must equal the single render bit for bit in every channel,
//! whatever the split, the order of the parts and the thread counts; parts of different renders, overlapping
//! parts and gaps are refused with one line naming the files. Through the library and through the CLI.

use crate::common::render_part;
use nimbus::farm::{self, FarmError, PartInfo};
use nimbus::light::EnvironmentLight;
use nimbus::math::Rgb;
use nimbus::render::{
    GuidingMode, PixelWindow, RenderImage, RenderRegion, RenderSettings, Renderer,
};
use nimbus::{channel_names, Scene};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::Command;

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/cloud.gltf");
/// An odd frame, so that no split lines up with anything.
const WIDTH: usize = 41;
const HEIGHT: usize = 29;
const SPP: u32 = 12;

fn settings(threads: usize) -> RenderSettings {
    RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        spp: SPP,
        seed: 5,
        threads,
        max_depth: 16,
        ..Default::default()
    }
}

/// The bundled cloud under a faint sky (10⁻⁹): a pixel on an edge sums sky samples 2^30 times dimmer than the lit
/// cloud and ground, where float sums of the same samples round differently in different groupings (the case
/// the exact sums are for), and every pixel's squared values do.
fn scene() -> Scene {
    let mut builder = nimbus::scene::load_builder(Path::new(SCENE), &Default::default()).unwrap();
    builder.set_environment(EnvironmentLight::Constant(Rgb::splat(1e-9)));
    builder.build().unwrap()
}

/// A fresh folder for one test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-farm-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn window(x0: usize, y0: usize, x1: usize, y1: usize) -> PixelWindow {
    PixelWindow { x0, y0, x1, y1 }
}

/// Asserts that two images hold the same bits in every channel, naming the first difference.
fn assert_bit_identical(got: &RenderImage, want: &RenderImage, what: &str) {
    assert_eq!((got.width, got.height), (want.width, want.height), "{what}");
    for name in channel_names() {
        let (g, w) = (got.channel(&name).unwrap(), want.channel(&name).unwrap());
        if let Some(i) = (0..g.len()).find(|&i| g[i].to_bits() != w[i].to_bits()) {
            panic!(
                "{what}: channel {name} differs at pixel ({}, {}): {} vs {}",
                i % got.width,
                i / got.width,
                g[i],
                w[i]
            );
        }
    }
}

/// The single render, the same on 1, 2 and 3 threads.
fn single(scene: &Scene) -> RenderImage {
    let images: Vec<RenderImage> = [1, 2, 3]
        .into_iter()
        .map(|t| {
            Renderer::new(settings(t))
                .render(scene, &mut |_| true)
                .unwrap()
                .0
        })
        .collect();
    assert_bit_identical(&images[1], &images[0], "2 threads against 1");
    assert_bit_identical(&images[2], &images[0], "3 threads against 1");
    let hit = images[0].depth.iter().filter(|d| **d > 0.0).count();
    assert!(
        hit > 0 && hit < WIDTH * HEIGHT,
        "the test scene should show both the ground and the sky"
    );
    images.into_iter().next().unwrap()
}

#[test]
fn sample_splits_merge_bit_identically() {
    let scene = scene();
    let want = single(&scene);
    let dir = temp_dir("samples");
    let even: Vec<Range<u32>> = vec![0..6, 6..12];
    let uneven: Vec<Range<u32>> = vec![0..1, 1..10, 10..12];
    let seven: Vec<Range<u32>> = (0..7)
        .map(|i| farm::sample_chunk(i, 7, SPP).unwrap())
        .collect();
    let full = PixelWindow::full(WIDTH, HEIGHT);
    for (k, ranges) in [even, uneven, seven].into_iter().enumerate() {
        let mut paths = Vec::new();
        for (i, samples) in ranges.iter().enumerate() {
            let path = dir.join(format!("split{k}_part{i}.exr"));
            // Every part on its own thread count: 1, 2, 3, 1, ...
            render_part(
                &scene,
                b"cloud",
                settings(1 + i % 3),
                full,
                samples.clone(),
                &path,
            );
            paths.push(path);
        }
        let merged = farm::merge_parts(&paths).unwrap();
        assert_eq!((merged.parts, merged.spp), (ranges.len(), SPP));
        assert_bit_identical(&merged.image, &want, &format!("{} parts", ranges.len()));
        paths.reverse();
        let reversed = farm::merge_parts(&paths).unwrap();
        assert_bit_identical(&reversed.image, &want, "parts in reverse order");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tile_and_mixed_splits_merge_bit_identically() {
    let scene = scene();
    let want = single(&scene);
    let dir = temp_dir("tiles");
    // Crops on no grid: columns 0..13, 13..14, 14..41; rows 0..10, 10..29; each tile with its own sample split.
    let columns = [(0, 13), (13, 14), (14, 41)];
    let rows = [(0, 10), (10, 29)];
    let whole = 0..SPP;
    let splits: [&[Range<u32>]; 3] = [
        std::slice::from_ref(&whole),
        &[0..5, 5..12],
        &[0..1, 1..2, 2..11, 11..12],
    ];
    let mut paths = Vec::new();
    let mut k = 0;
    for (x0, x1) in columns {
        for (y0, y1) in rows {
            for samples in splits[k % 3] {
                let path = dir.join(format!("tile{k}_{}.exr", samples.start));
                render_part(
                    &scene,
                    b"cloud",
                    settings(1 + k % 3),
                    window(x0, y0, x1, y1),
                    samples.clone(),
                    &path,
                );
                paths.push(path);
            }
            k += 1;
        }
    }
    let merged = farm::merge_parts(&paths).unwrap();
    assert_bit_identical(&merged.image, &want, "tiles with sample splits");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parts_carry_their_keys_and_windows_in_the_exr_header() {
    let scene = scene();
    let dir = temp_dir("header");
    let path = dir.join("part.exr");
    let crop = window(3, 4, 20, 9);
    render_part(&scene, b"cloud", settings(2), crop, 2..7, &path);
    let info = farm::read_part_info(&path).unwrap();
    assert_eq!(
        (info.width, info.height, info.window),
        (WIDTH, HEIGHT, crop)
    );
    assert_eq!(
        (info.seed, info.max_depth, info.spp, info.samples),
        (5, 16, SPP, 2..7)
    );
    assert_eq!(info.version, env!("CARGO_PKG_VERSION"));
    let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
    let header = &meta.headers[0];
    let display = header.shared_attributes.display_window;
    assert_eq!((display.position.x(), display.position.y()), (0, 0));
    assert_eq!((display.size.x(), display.size.y()), (WIDTH, HEIGHT));
    let data = header.data_window();
    assert_eq!((data.position.x(), data.position.y()), (3, 4));
    assert_eq!((data.size.x(), data.size.y()), (17, 5));
    let text = |key: &str| match header
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from(key))
    {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{key}: {other:?}"),
    };
    assert_eq!(text("nimbus.samples"), "2..7");
    assert_eq!(text("nimbus.sample_count"), "5");
    assert_eq!(text("nimbus.spp"), "12");
    assert_eq!(text("nimbus.format"), "nimbus-part-2");
    let names: Vec<String> = header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let farm_words = ["nimbus.count", "nimbus.sumsq.B.5"].map(String::from);
    for name in channel_names().iter().chain(&farm_words) {
        assert!(
            names.iter().any(|n| n == name),
            "channel {name} in {names:?}"
        );
    }
    // The float channels show the part's own samples: the image of its film.
    let (_, film) = farm::read_part(&path).unwrap();
    let layers = nimbus::output::read_exr_layers(&path).unwrap();
    assert_eq!((layers.width, layers.height), (17, 5));
    assert_eq!(layers.rgb("").unwrap(), film.image().beauty);
    assert!(film.pixels().iter().all(|p| p.count() == 5));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parts_of_other_renders_overlaps_and_gaps_are_refused() {
    let scene = scene();
    let dir = temp_dir("refuse");
    let full = PixelWindow::full(WIDTH, HEIGHT);
    let part = |name: &str, s: RenderSettings, w: PixelWindow, samples: Range<u32>| {
        let path = dir.join(name);
        render_part(&scene, b"cloud", s, w, samples, &path);
        path
    };
    let first = part("first.exr", settings(2), full, 0..5);
    let rest = part("rest.exr", settings(2), full, 5..12);
    farm::merge_parts(&[first.clone(), rest.clone()]).unwrap();
    let refused = |paths: &[&PathBuf], expected: &str| {
        let paths: Vec<PathBuf> = paths.iter().map(|p| (*p).clone()).collect();
        let err = farm::merge_parts(&paths).unwrap_err().to_string();
        assert!(!err.contains('\n'), "one line: {err}");
        assert!(err.contains(expected), "expected '{expected}' in: {err}");
        err
    };
    let seed = part(
        "seed.exr",
        RenderSettings {
            seed: 6,
            ..settings(2)
        },
        full,
        5..12,
    );
    let err = refused(&[&first, &seed], "do not belong together: seed 5 vs 6");
    assert!(err.contains("first.exr") && err.contains("seed.exr"));
    let wide = RenderSettings {
        width: WIDTH + 1,
        ..settings(2)
    };
    let wide = part(
        "wide.exr",
        wide,
        PixelWindow::full(WIDTH + 1, HEIGHT),
        5..12,
    );
    refused(&[&first, &wide], "resolution 41x29 vs 42x29");
    let depth = part(
        "depth.exr",
        RenderSettings {
            max_depth: 3,
            ..settings(2)
        },
        full,
        5..12,
    );
    refused(&[&first, &depth], "max depth 16 vs 3");
    let spp = part(
        "spp.exr",
        RenderSettings {
            spp: 24,
            ..settings(2)
        },
        full,
        5..24,
    );
    refused(&[&first, &spp], "samples per pixel 12 vs 24");
    let overlap = part("overlap.exr", settings(1), full, 4..12);
    refused(
        &[&first, &overlap],
        "overlap: both hold samples 4..5 of the pixels in 0,0,41,29",
    );
    let gap = part("gap.exr", settings(1), full, 6..12);
    refused(
        &[&first, &gap],
        "leave samples 5..6 of the pixels in 0,0,41,29 unrendered",
    );
    refused(&[&first], "leave samples 5..12");
    let left = part("left.exr", settings(1), window(0, 0, 20, HEIGHT), 5..12);
    let right = part(
        "right.exr",
        settings(1),
        window(19, 0, WIDTH, HEIGHT),
        5..12,
    );
    refused(
        &[&first, &left, &right],
        "overlap: both hold samples 5..12 of the pixels in 19,0,20,29",
    );
    refused(
        &[&first, &left],
        "samples 5..12 of the pixels in 20,0,41,29 unrendered",
    );
    assert!(matches!(farm::merge_parts(&[]), Err(FarmError::NoParts)));
    // A different scene file: the hash of other bytes.
    let other_scene = dir.join("other_scene.exr");
    render_part(
        &scene,
        b"another scene",
        settings(2),
        full,
        5..12,
        &other_scene,
    );
    refused(
        &[&first, &other_scene],
        "scene hash (scene file or settings)",
    );
    // A plain render is no part.
    let plain = dir.join("plain.exr");
    let image = Renderer::new(settings(2))
        .render(&scene, &mut |_| true)
        .unwrap()
        .0;
    nimbus::write_exr(&image, &plain).unwrap();
    refused(&[&plain, &rest], "no nimbus.format header key");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_damaged_part_is_refused() {
    use exr::prelude::*;
    let scene = scene();
    let dir = temp_dir("damaged");
    let path = dir.join("part.exr");
    render_part(
        &scene,
        b"cloud",
        settings(2),
        window(1, 1, 9, 7),
        0..12,
        &path,
    );
    let mut image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(&path)
        .unwrap();
    let layer = &mut image.layer_data[0];
    let sum = layer
        .channel_data
        .list
        .iter_mut()
        .find(|c| c.name.to_string() == "nimbus.sum.G.1")
        .unwrap();
    let FlatSamples::U32(words) = &mut sum.sample_data else {
        panic!("sum channel is not uint");
    };
    words[10] ^= 1 << 4;
    let damaged = dir.join("damaged.exr");
    image.write().to_file(&damaged).unwrap();
    let err = farm::read_part(&damaged).unwrap_err().to_string();
    assert!(
        err.contains("damaged.exr") && err.contains("channel G at pixel (3, 2)"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs `nimbus` with `args` and the environment `env`; returns success and stderr. `SOURCE_DATE_EPOCH` makes
/// the files reproducible (a fixed `capDate`, no render time in the header), so that merged and single
/// renders can be compared byte for byte.
fn nimbus(args: &[&str], env: &[(&str, &str)], dir: &Path) -> (bool, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_nimbus"));
    cmd.args(args)
        .current_dir(dir)
        .env("SOURCE_DATE_EPOCH", "0");
    for v in farm::TASK_INDEX_VARIABLES {
        cmd.env_remove(v);
    }
    cmd.envs(env.iter().copied());
    let out = cmd.output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn cli_splits_merge_to_the_same_files_as_one_render() {
    let dir = temp_dir("cli");
    let common = [
        "render",
        SCENE,
        "--width",
        "37",
        "--height",
        "23",
        "--spp",
        "10",
        "--seed",
        "9",
        "--env-color",
        "1e-9,1e-9,1e-9",
    ];
    let run = |extra: &[&str], env: &[(&str, &str)]| {
        let args: Vec<&str> = common.iter().chain(extra).copied().collect();
        let (ok, err) = nimbus(&args, env, &dir);
        assert!(ok, "{args:?}: {err}");
    };
    run(&["--threads", "2", "-o", "single.exr"], &[]);
    // Chunks from each scheduler's variable, on different thread counts.
    for (i, var) in farm::TASK_INDEX_VARIABLES.iter().enumerate() {
        let threads = (i + 1).to_string();
        run(
            &[
                "--chunks",
                "3",
                "--chunk-from-env",
                "--threads",
                &threads,
                "-o",
                "chunks/shot.exr",
            ],
            &[(var, &i.to_string())],
        );
    }
    let (ok, err) = nimbus(
        &[
            "merge",
            "chunks/shot.chunk0.exr",
            "chunks/shot.chunk1.exr",
            "chunks/shot.chunk2.exr",
            "-o",
            "merged.exr",
        ],
        &[],
        &dir,
    );
    assert!(ok, "{err}");
    // Tiles with explicit sample ranges, none aligned.
    for (crop, samples) in [
        ("0,0,37,5", "0..10"),
        ("0,5,11,23", "0..3"),
        ("0,5,11,23", "3..10"),
        ("11,5,37,23", "0..10"),
    ] {
        let out = format!(
            "tiles/{}_{}.exr",
            crop.replace(',', "-"),
            samples.replace("..", "-")
        );
        run(
            &[
                "--crop",
                crop,
                "--samples",
                samples,
                "--threads",
                "1",
                "-o",
                &out,
            ],
            &[],
        );
    }
    let mut args = vec!["merge"];
    let tiles: Vec<String> = std::fs::read_dir(dir.join("tiles"))
        .unwrap()
        .map(|e| format!("tiles/{}", e.unwrap().file_name().to_string_lossy()))
        .collect();
    args.extend(tiles.iter().map(String::as_str));
    args.extend(["-o", "tiles.exr"]);
    let (ok, err) = nimbus(&args, &[], &dir);
    assert!(ok, "{err}");
    let bytes = |name: &str| std::fs::read(dir.join(name)).unwrap();
    for merged in ["merged", "tiles"] {
        assert!(
            bytes(&format!("{merged}.exr")) == bytes("single.exr"),
            "{merged}.exr differs from single.exr"
        );
        assert!(
            bytes(&format!("{merged}.png")) == bytes("single.png"),
            "{merged}.png differs from single.png"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cli_refuses_parts_of_another_scene_or_seed_with_one_line() {
    let dir = temp_dir("cli-refuse");
    // The same scene with one more byte: another scene hash.
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let mut gltf = std::fs::read(assets.join("cloud.gltf")).unwrap();
    gltf.push(b'\n');
    std::fs::write(dir.join("cloud.gltf"), gltf).unwrap();
    std::fs::copy(assets.join("cloud.vdb"), dir.join("cloud.vdb")).unwrap();
    let part = |scene: &str, extra: &[&str], out: &str| {
        let mut args = vec![
            "render",
            scene,
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "4",
            "--threads",
            "1",
        ];
        args.extend(extra);
        args.extend(["-o", out]);
        let (ok, err) = nimbus(&args, &[], &dir);
        assert!(ok, "{err}");
    };
    part(SCENE, &["--samples", "0..2"], "a.exr");
    part("cloud.gltf", &["--samples", "2..4"], "edited.exr");
    part(SCENE, &["--samples", "2..4", "--seed", "1"], "seed.exr");
    part(
        SCENE,
        &["--samples", "2..4", "--env-color", "1,1,1"],
        "env.exr",
    );
    part(SCENE, &["--samples", "2..4"], "b.exr");
    let refused = |b: &str, expected: &str| {
        let (ok, err) = nimbus(&["merge", "a.exr", b, "-o", "out.exr"], &[], &dir);
        assert!(!ok, "merge of a.exr and {b} succeeded");
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with("nimbus: error: parts a.exr and ") && err.contains(expected),
            "{err}"
        );
    };
    refused("edited.exr", "scene hash");
    refused("seed.exr", "seed 0 vs 1");
    refused("env.exr", "scene hash");
    let (ok, err) = nimbus(&["merge", "a.exr", "b.exr", "-o", "out.exr"], &[], &dir);
    assert!(ok, "{err}");
    // Flags that cannot make a part.
    let bad: [(&[&str], &str); 4] = [
        (&["--samples", "2..5"], "--samples 2..5 goes past --spp 4"),
        (
            &["--crop", "0,0,17,12"],
            "--crop 0,0,17,12 does not fit the 16x12 frame",
        ),
        (
            &["--chunks", "5", "--chunk-from-env"],
            "--chunks 5: more chunks than the 4 samples",
        ),
        (
            &["--chunks", "2", "--chunk-from-env"],
            "none of NIMBUS_TASK_INDEX",
        ),
    ];
    for (extra, expected) in bad {
        let mut args = vec![
            "render", SCENE, "--width", "16", "--height", "12", "--spp", "4", "-o", "x.exr",
        ];
        args.extend(extra);
        let env: &[(&str, &str)] = if extra[0] == "--chunks" && extra[1] == "5" {
            &[("NIMBUS_TASK_INDEX", "0")]
        } else {
            &[]
        };
        let (ok, err) = nimbus(&args, env, &dir);
        assert!(!ok && err.contains(expected), "{extra:?}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The `command` array of a Kubernetes manifest (kept as one JSON flow sequence per line).
fn k8s_command(manifest: &str) -> Vec<String> {
    let line = manifest
        .lines()
        .find_map(|l| l.trim().strip_prefix("command:"))
        .expect("a command line");
    serde_json::from_str(line.trim()).expect("command is a JSON array")
}

#[test]
fn kubernetes_example_chunks_match_its_completions_and_merge_glob() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("farm/kubernetes");
    let render = std::fs::read_to_string(dir.join("render-job.yaml")).unwrap();
    let merge = std::fs::read_to_string(dir.join("merge-job.yaml")).unwrap();
    let field = |name: &str| -> u32 {
        render
            .lines()
            .find_map(|l| l.trim().strip_prefix(name))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("{name} in render-job.yaml"))
    };
    assert!(render.contains("completionMode: Indexed"));
    let command = k8s_command(&render);
    let flag = |name: &str| {
        let i = command
            .iter()
            .position(|a| a == name)
            .unwrap_or_else(|| panic!("{name}"));
        command[i + 1].clone()
    };
    assert_eq!(command[..2], ["nimbus", "render"]);
    assert!(command.iter().any(|a| a == "--chunk-from-env"));
    let chunks: u32 = flag("--chunks").parse().unwrap();
    assert_eq!(
        chunks,
        field("completions:"),
        "--chunks must equal completions"
    );
    let spp: u32 = flag("--spp").parse().unwrap();
    farm::sample_chunk(chunks - 1, chunks, spp).unwrap();
    // The merge's glob matches every chunk file the render writes, and nothing else of its.
    let output = PathBuf::from(flag("-o"));
    let merge_command = k8s_command(&merge).join(" ");
    let glob = format!(
        "{}/{}.chunk*.exr",
        output.parent().unwrap().display(),
        output.file_stem().unwrap().to_string_lossy()
    );
    assert!(
        merge_command.contains(&format!("nimbus merge {glob}")),
        "{merge_command}"
    );
    let last = farm::chunk_output_path(&output, chunks - 1, chunks);
    let last = last.file_name().unwrap().to_string_lossy();
    assert!(
        last.starts_with("shot.chunk") && last.ends_with(".exr"),
        "{last}"
    );
}

#[test]
fn samples_whose_float_sums_depend_on_grouping_merge_exactly_through_part_files() {
    use nimbus::render::Film;
    use nimbus::render::PathSample;
    // Per pixel: four samples whose f64 running sum and split sums round to different f32 means (see the
    // film's unit tests), scaled per pixel, with AOVs that vary too.
    let values = [1.0f32, 2f32.powi(-24), 2f32.powi(-54), 3.0 * 2f32.powi(-55)];
    let sample = |pixel: usize, k: usize| {
        let scale = (1 + pixel % 7) as f32;
        PathSample {
            radiance: Rgb::new(values[k], values[k] * 0.5, values[3 - k]) * scale,
            albedo: Rgb::splat(values[k]),
            normal: nimbus::math::Vec3::new(values[k], 1.0, -values[3 - k]),
            depth: 1.0 + values[k],
            alpha: values[k],
        }
    };
    let (width, height) = (5, 3);
    let mut whole = Film::new(width, height);
    for (i, p) in whole.pixels_mut().iter_mut().enumerate() {
        (0..4).for_each(|k| {
            p.add(&sample(i, k));
        });
    }
    let dir = temp_dir("crafted");
    let settings = RenderSettings {
        width,
        height,
        spp: 4,
        ..Default::default()
    };
    let mut paths = Vec::new();
    for samples in [0..2, 2..4] {
        let mut film = Film::new(width, height);
        for (i, p) in film.pixels_mut().iter_mut().enumerate() {
            samples.clone().for_each(|k| {
                p.add(&sample(i, k as usize));
            });
        }
        let stats = nimbus::RenderStats {
            samples_per_pixel: samples.len() as u32,
            ..Default::default()
        };
        let region = RenderRegion {
            window: PixelWindow::full(width, height),
            samples: samples.clone(),
        };
        let path = dir.join(format!("part{}.exr", samples.start));
        farm::write_part(&path, &film, &PartInfo::new(&settings, 1, &region, &stats)).unwrap();
        paths.push(path);
    }
    let merged = farm::merge_parts(&paths).unwrap();
    assert_bit_identical(&merged.image, &whole.image(), "crafted samples");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parts_with_every_layer_merge_bit_for_bit_cryptomatte_ranks_included() {
    // Every layer: light paths, colours, per-light groups, the shadow catcher, all three Cryptomatte kinds; a
    // transparent film. Tiles × sample ranges, on different thread counts; unguided, then guided (the
    // training's 7 samples the image's first: the ranges 0..5 and 5..12 split them, 0..7 holds them whole).
    for guiding in [GuidingMode::Off, GuidingMode::On] {
        every_layer_parts_merge_bit_for_bit(guiding);
    }
}

/// The parts of `parts_with_every_layer_merge_bit_for_bit_cryptomatte_ranks_included` with `guiding`.
fn every_layer_parts_merge_bit_for_bit(guiding: GuidingMode) {
    let scene = scene();
    let with_layers = |threads: usize| RenderSettings {
        aovs: Some(nimbus::render::AovSelection::parse("all").unwrap()),
        transparent: true,
        light_groups: nimbus::render::LightGroupMode::PerLight,
        cryptomatte_depth: 4,
        guiding,
        ..settings(threads)
    };
    let (single, _) = Renderer::new(with_layers(2))
        .render(&scene, &mut |_| true)
        .unwrap();
    let dir = temp_dir(&format!("layers-{guiding:?}"));
    let mut paths = Vec::new();
    for (k, (w, samples)) in [
        (window(0, 0, 41, 13), 0..5),
        (window(0, 0, 41, 13), 5..12),
        (window(0, 13, 20, 29), 0..12),
        (window(20, 13, 41, 29), 0..7),
        (window(20, 13, 41, 29), 7..12),
    ]
    .into_iter()
    .enumerate()
    {
        let path = dir.join(format!("part{k}.exr"));
        render_part(&scene, b"cloud", with_layers(1 + k % 2), w, samples, &path);
        paths.push(path);
    }
    paths.reverse();
    let merged = farm::merge_parts(&paths).unwrap();
    let names = single.channel_names();
    assert_eq!(merged.image.channel_names(), names);
    assert!(names.iter().any(|n| n == "CryptoAsset01.a"));
    assert!(names.iter().any(|n| n == "lg_environment.G"));
    for name in &names {
        let (g, w) = (
            merged.image.channel(name).unwrap(),
            single.channel(name).unwrap(),
        );
        if let Some(i) = (0..g.len()).find(|&i| g[i].to_bits() != w[i].to_bits()) {
            panic!("channel {name} differs at pixel {i}: {} vs {}", g[i], w[i]);
        }
    }
    // A part of the same render with other layers (the default ones) does not merge with these.
    let other = dir.join("other.exr");
    let default_layers = RenderSettings {
        aovs: None,
        ..with_layers(1)
    };
    render_part(
        &scene,
        b"cloud",
        default_layers,
        window(0, 0, 41, 13),
        0..5,
        &other,
    );
    let err = farm::merge_parts(&[paths[0].clone(), other]).unwrap_err();
    assert!(err.to_string().contains("(--aovs"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parts_whose_media_chose_other_estimators_are_refused() {
    // The same scene file and settings, but one part's medium tracks over another majorant structure (as a
    // node whose --memory-limit rules out the cheapest structure would pick): the samples differ, so the
    // parts must not merge. Before the estimators were in the part header this merged into a wrong image.
    let dir = temp_dir("estimators");
    use nimbus::volume::majorant::MajorantKind;
    let load = |kind: MajorantKind| {
        let force = move |spec: &mut nimbus::volume::VolumeSpec| {
            spec.majorant = Some(kind);
        };
        let options = nimbus::scene::LoadOptions {
            volume_override: Some(nimbus::scene::VolumeOverride::new(&force)),
            ..Default::default()
        };
        let mut builder = nimbus::scene::load_builder(Path::new(SCENE), &options).unwrap();
        builder.set_environment(EnvironmentLight::Constant(Rgb::splat(1e-9)));
        builder.build().unwrap()
    };
    let (a, b) = (dir.join("grid16.exr"), dir.join("global.exr"));
    render_part(
        &load(MajorantKind::Grid16),
        b"cloud",
        settings(1),
        window(0, 0, 41, 29),
        0..6,
        &a,
    );
    render_part(
        &load(MajorantKind::Global),
        b"cloud",
        settings(1),
        window(0, 0, 41, 29),
        6..12,
        &b,
    );
    let err = match farm::merge_parts(&[a, b]) {
        Ok(_) => panic!("parts whose media chose other estimators merged"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("media estimators"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An edit of a part file's image.
type Forgery = fn(&mut exr::prelude::FlatImage);

/// Rewrites the part at `path` with `edit` applied to its one layer, then makes its float channels agree with
/// its sums again (as a hostile file would), taking the values the reader names in turn.
fn forge_part(path: &Path, edit: impl FnOnce(&mut exr::prelude::FlatImage)) {
    use exr::prelude::*;
    let read_back = || {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .unwrap()
    };
    let mut image = read_back();
    edit(&mut image);
    image.write().to_file(path).unwrap();
    for _ in 0..64 {
        let Err(err) = farm::read_part(path) else {
            return;
        };
        let err = err.to_string();
        // "channel NAME at pixel (X, Y) is A, but its sums give B (damaged file?)"
        let Some(rest) = err
            .split("channel ")
            .nth(1)
            .filter(|_| err.contains("sums give"))
        else {
            return; // refused for another reason: what the caller asserts on
        };
        let name = rest.split(" at pixel").next().unwrap();
        let xy: Vec<usize> = rest
            .split(['(', ')'])
            .nth(1)
            .unwrap()
            .split(", ")
            .map(|v| v.parse().unwrap())
            .collect();
        let value: f32 = rest
            .split("sums give ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        let mut image = read_back();
        let layer = &mut image.layer_data[0];
        let origin = layer.attributes.layer_position;
        let width = layer.size.x();
        let channel = layer
            .channel_data
            .list
            .iter_mut()
            .find(|c| c.name.to_string() == name)
            .unwrap();
        let FlatSamples::F32(values) = &mut channel.sample_data else {
            panic!("{name} is not float")
        };
        values[(xy[1] - origin.y() as usize) * width + xy[0] - origin.x() as usize] = value;
        image.write().to_file(path).unwrap();
    }
    panic!("could not make {} consistent", path.display());
}

/// Two parts that each hold a sum or a count near the top of its type merged into a wrapped value: an i128
/// value sum near 2^127 in each part, or `nimbus.nan_samples` of 2^64 - 1 (issue 36). Each part is refused:
/// a part's dropped samples cannot exceed its pixel-samples, and sums that overflow when added are refused,
/// naming the pixel.
#[test]
fn parts_whose_sums_or_counts_would_wrap_when_merged_are_refused() {
    use exr::prelude::*;
    let scene = scene();
    let dir = temp_dir("wrap");
    let halves = [dir.join("a.exr"), dir.join("b.exr")];
    let ranges = [0..6, 6..12];
    let whole = window(0, 0, WIDTH, HEIGHT);
    let huge_sum = |image: &mut FlatImage| {
        let layer = &mut image.layer_data[0];
        for (word, value) in [
            (0, u32::MAX),
            (1, u32::MAX),
            (2, u32::MAX),
            (3, 0x7fff_ffff),
        ] {
            let name = format!("nimbus.sum.R.{word}");
            let channel = layer
                .channel_data
                .list
                .iter_mut()
                .find(|c| c.name.to_string() == name)
                .unwrap();
            let FlatSamples::U32(words) = &mut channel.sample_data else {
                panic!("{name}")
            };
            words[0] = value;
        }
    };
    let huge_count = |image: &mut FlatImage| {
        let key = Text::from("nimbus.nan_samples");
        image.layer_data[0].attributes.other.insert(
            key,
            AttributeValue::Text(Text::from(u64::MAX.to_string().as_str())),
        );
    };
    let edits: [(&str, Forgery); 2] = [("value sum", huge_sum), ("nan_samples", huge_count)];
    for (what, edit) in edits {
        for (path, samples) in halves.iter().zip(ranges.clone()) {
            render_part(&scene, b"cloud", settings(2), whole, samples, path);
            forge_part(path, edit);
        }
        let merged = std::panic::catch_unwind(|| farm::merge_parts(&halves));
        let err = match merged {
            Ok(Err(e)) => e.to_string(),
            Ok(Ok(m)) => panic!("{what}: merged, with nan_samples {}", m.nan_samples),
            Err(_) => panic!("{what}: the merge overflowed"),
        };
        // The value sums are each possible alone and overflow only when the second part is added; the count
        // is impossible in the first part already.
        let (file, names) = match what {
            "value sum" => ("b.exr", "pixel (0, 0)"),
            _ => ("a.exr", "nan_samples"),
        };
        assert!(err.contains(file) && err.contains(names), "{what}: {err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Sets the `name` box2i header attribute of the EXR `bytes` to (0, 0) - (`max`, `max`).
fn patch_box(bytes: &mut [u8], name: &str, max: i32) {
    let key = format!("{name}\0box2i\0");
    let at = bytes
        .windows(key.len())
        .position(|w| w == key.as_bytes())
        .unwrap()
        + key.len()
        + 4;
    for (i, v) in [0i32, 0, max, max].iter().enumerate() {
        bytes[at + 4 * i..at + 4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
}

#[test]
fn a_part_whose_header_declares_a_huge_frame_is_refused_before_its_samples_are_allocated() {
    let scene = scene();
    let dir = temp_dir("huge-header");
    let path = dir.join("part.exr");
    render_part(
        &scene,
        b"cloud",
        settings(2),
        window(0, 0, 12, 8),
        0..12,
        &path,
    );
    let mut bytes = std::fs::read(&path).unwrap();
    // A 65536x65536 frame and data window: some 70 channels of 4 bytes are 1.2 TB of samples.
    patch_box(&mut bytes, "displayWindow", 65535);
    patch_box(&mut bytes, "dataWindow", 65535);
    let huge = dir.join("huge.exr");
    std::fs::write(&huge, &bytes).unwrap();
    let err = farm::read_part(&huge).unwrap_err().to_string();
    assert!(err.contains("huge.exr") && err.contains("memory"), "{err}");
    let err = farm::merge_parts(std::slice::from_ref(&huge))
        .unwrap_err()
        .to_string();
    assert!(err.contains("huge.exr"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}
