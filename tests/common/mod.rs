//! Helpers shared by integration tests.

#![allow(dead_code)]

use nimbus::farm::{self, PartInfo};
use nimbus::render::{CancelToken, PixelWindow, RenderRegion, RenderSettings, Renderer};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Renders the samples `samples` of `window` of `scene` with `settings` and writes them to `path` as a farm part,
/// its scene hash taken over `scene_file` as the scene file's bytes.
pub fn render_part(
    scene: &nimbus::Scene,
    scene_file: &[u8],
    settings: RenderSettings,
    window: PixelWindow,
    samples: Range<u32>,
    path: &Path,
) {
    let hash = farm::SceneOverrides::default().scene_hash(&[scene_file], &settings, scene);
    let region = RenderRegion { window, samples };
    let renderer = Renderer::new(settings);
    let (film, stats) = renderer
        .render_region(scene, &region, &mut |_| true, &CancelToken::new())
        .unwrap();
    let info = PartInfo::new(renderer.settings(), hash, &region, &stats);
    farm::write_part(path, &film, &info).unwrap();
}

/// The shared test-data folder: `$NIMBUS_SHARED_DIR` if set, else `$CARGO_MANIFEST_DIR/../shared`.
///
/// Returns `None` (after printing a skip notice) when it is missing, unless `NIMBUS_REQUIRE_SHARED=1`, in which
/// case it panics so that the calling test fails.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("NIMBUS_SHARED_DIR") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"),
    };
    if dir.is_dir() {
        return Some(dir);
    }
    if std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!(
            "shared data folder {} is missing and NIMBUS_REQUIRE_SHARED=1",
            dir.display()
        );
    }
    eprintln!(
        "SKIP: shared data folder {} not found (set NIMBUS_SHARED_DIR)",
        dir.display()
    );
    None
}

/// The VDB corpus folder inside the shared folder, if present.
pub fn vdb_corpus_dir() -> Option<PathBuf> {
    let d = shared_dir()?.join("vdb-corpus");
    if d.join("truth.tsv").is_file() {
        Some(d)
    } else if std::env::var("NIMBUS_REQUIRE_SHARED").as_deref() == Ok("1") {
        panic!("VDB corpus missing under {}", d.display());
    } else {
        eprintln!("SKIP: no VDB corpus under {}", d.display());
        None
    }
}

use nimbus::geometry::Mesh;
use nimbus::math::Vec3;

/// A closed UV sphere with outward normals and counter-clockwise front faces.
pub fn uv_sphere(center: Vec3, radius: f32, rings: u32, segments: u32, material: u32) -> Mesh {
    Mesh::uv_sphere(center, radius, rings, segments, material)
}

/// A quad from four corners, counter-clockwise seen from its front.
pub fn quad(corners: [Vec3; 4], material: u32) -> Mesh {
    let n = (corners[1] - corners[0])
        .cross(corners[3] - corners[0])
        .normalize();
    Mesh {
        name: "quad".into(),
        positions: corners.to_vec(),
        normals: vec![n; 4],
        uvs: None,
        uvs1: None,
        colors: None,
        tangents: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        motion: None,
        ..Default::default()
    }
}

/// An axis-aligned box with outward normals and counter-clockwise front faces (flat-shaded, 24 vertices).
pub fn cuboid(min: Vec3, max: Vec3, material: u32) -> Mesh {
    let c = |x: usize, y: usize, z: usize| {
        Vec3::new([min.x, max.x][x], [min.y, max.y][y], [min.z, max.z][z])
    };
    // Each face: four corners counter-clockwise seen from outside.
    let faces = [
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +x
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -x
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +y
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -y
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +z
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -z
    ];
    let mut mesh = Mesh {
        name: "box".into(),
        material,
        ..Default::default()
    };
    for f in faces {
        let base = mesh.positions.len() as u32;
        let n = (f[1] - f[0]).cross(f[3] - f[0]).normalize();
        mesh.positions.extend_from_slice(&f);
        mesh.normals.extend_from_slice(&[n; 4]);
        mesh.indices.push([base, base + 1, base + 2]);
        mesh.indices.push([base, base + 2, base + 3]);
    }
    mesh
}

/// An index-matched boundary material (transmission 1, ior 1, smooth) owning `medium` as its interior.
pub fn boundary(medium: u32) -> nimbus::material::Material {
    let mut m = nimbus::material::Material::lambertian("boundary", Vec3::ONE);
    m.transmission = 1.0;
    m.ior = 1.0;
    m.roughness = 0.0;
    m.specular_factor = 1.0;
    m.interior = Some(medium);
    m
}

/// Fills the box [`min`, `max`] with the medium `medium` of `builder`: an index-matched [`boundary`] around it.
pub fn fill_box(builder: &mut nimbus::scene::SceneBuilder, medium: u32, min: Vec3, max: Vec3) {
    let material = builder.add_material(boundary(medium));
    builder.add_mesh(cuboid(min, max, material));
}

/// Renders `builder` at `size`² with `spp` samples, `max_depth` bounces and `seed`, on two threads.
pub fn render_square(
    builder: nimbus::scene::SceneBuilder,
    size: usize,
    spp: u32,
    max_depth: u32,
    seed: u64,
) -> (nimbus::render::RenderImage, nimbus::render::RenderStats) {
    let scene = builder.build().unwrap();
    let settings = nimbus::render::RenderSettings {
        width: size,
        height: size,
        spp,
        seed,
        threads: 2,
        max_depth,
        ..Default::default()
    };
    nimbus::render::Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap()
}

/// Channel `c`'s mean over all pixels and its standard error, from each pixel's variance of its mean.
pub fn mean_and_se(img: &nimbus::render::RenderImage, c: usize) -> (f64, f64) {
    let n = img.pixel_count() as f64;
    let mean = img.beauty.iter().map(|p| p[c] as f64).sum::<f64>() / n;
    let var: f64 = img.variance.iter().map(|v| v[c] as f64).sum();
    (mean, var.sqrt() / n)
}

/// The peak resident memory a hostile-input sweep's whole test process may reach: 2 GiB. A damaged size field
/// that is believed (a film, a majorant grid, a buffer sized by the file) goes far beyond it.
pub const SWEEP_PEAK_MEMORY_BYTES: u64 = 2 << 30;

/// Asserts the process's peak resident memory so far is below [`SWEEP_PEAK_MEMORY_BYTES`] (where the platform
/// reports it), and prints it.
pub fn assert_sweep_peak_memory(sweep: &str) {
    if let Some(peak) = nimbus::render::peak_memory_bytes() {
        eprintln!(
            "{sweep}: peak memory {:.0} MiB",
            peak as f64 / (1 << 20) as f64
        );
        assert!(
            peak < SWEEP_PEAK_MEMORY_BYTES,
            "{sweep}: peak memory {peak} bytes is over the bound of {SWEEP_PEAK_MEMORY_BYTES}"
        );
    }
}

/// SplitMix64's output function: a 64-bit avalanche of `z`.
pub fn splitmix_finalize(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Value `i` of the SplitMix64 sequence: the deterministic pseudo-random numbers of the hostile-input sweeps.
pub fn splitmix(i: u64) -> u64 {
    splitmix_finalize(i.wrapping_add(0x9E37_79B9_7F4A_7C15))
}

/// Standard base64 with padding, for glTF data URIs.
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for i in 0..4 {
            out.push(if i <= chunk.len() {
                A[(n >> (18 - 6 * i) & 63) as usize] as char
            } else {
                '='
            });
        }
    }
    out
}

/// Runs the `nimbus` binary with `args` in `dir`; returns whether it succeeded, its stdout and its stderr.
pub fn run_nimbus(args: &[&str], dir: &Path) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_nimbus"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Readers whose exit status carries nothing: OpenEXR 3.1's `exrinfo` (Debian's `openexr` 3.1.5) exits with an
/// arbitrary status whatever the file (measured: 4 of 30 runs nonzero on one valid flat EXR, 8 of 30 with
/// `--strict -v` on one valid deep EXR, each time a different code; on a truncated file a random code and no
/// message). A run of one of these fails on anything it writes to stderr instead.
const STATUS_UNRELIABLE: &[&str] = &["exrinfo"];

/// Runs an independent reader (OpenEXR's `exrheader` or `exrinfo`, OpenImageIO's `oiiotool`) with `args` in
/// `dir` and returns its stdout; a run that fails fails the test (for [`STATUS_UNRELIABLE`] readers: a run that
/// reports an error). `None` when the tool is not installed, which fails the test under
/// `NIMBUS_REQUIRE_TOOLS=1` (`.ci/run` installs them).
pub fn run_tool(tool: &str, args: &[&str], dir: &Path) -> Option<String> {
    match std::process::Command::new(tool)
        .args(args)
        .current_dir(dir)
        .output()
    {
        Ok(out) => {
            let failed = if STATUS_UNRELIABLE.contains(&tool) {
                !out.stderr.is_empty()
            } else {
                !out.status.success()
            };
            assert!(
                !failed,
                "{tool} {args:?} failed: {}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            Some(String::from_utf8_lossy(&out.stdout).into_owned())
        }
        Err(_) => {
            assert!(
                std::env::var("NIMBUS_REQUIRE_TOOLS").as_deref() != Ok("1"),
                "{tool} is not installed and NIMBUS_REQUIRE_TOOLS=1"
            );
            eprintln!("SKIP: {tool} is not installed (Debian openexr, openimageio-tools)");
            None
        }
    }
}
