//! Emitter-edge supersampling (`nimbus::render::EmitterEdges`) against the exact image of an emissive square
//! seen head-on: each pixel's value is the radiance times the share of the pixel the square's projection
//! covers, computed here from the pinhole projection (independent of the renderer's code).

use crate::common;

use nimbus::material::Material;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::{EdgeDecision, EmitterEdgeSampling, RenderImage, RenderSettings, Renderer};
use nimbus::scene::{Camera, Scene, SceneBuilder};

const SIZE: usize = 64;
const RADIANCE: f32 = 20.0;
/// Half the square's side, in metres; the camera is `DISTANCE` away with a `FOV_DEGREES` vertical field.
const HALF_SIDE: f32 = 0.0561;
const DISTANCE: f32 = 5.0;
const FOV_DEGREES: f32 = 10.0;

/// An emissive square facing a camera on its axis, on a black background.
fn square_scene() -> Scene {
    let mut b = SceneBuilder::default();
    let mut light = Material::lambertian("light", Rgb::ZERO);
    light.emission = Rgb::splat(RADIANCE);
    let lm = b.add_material(light);
    let h = HALF_SIDE;
    b.add_mesh(common::quad(
        [
            Vec3::new(-h, -h, 0.0),
            Vec3::new(h, -h, 0.0),
            Vec3::new(h, h, 0.0),
            Vec3::new(-h, h, 0.0),
        ],
        lm,
    ));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 0.0, DISTANCE),
        Vec3::ZERO,
        FOV_DEGREES.to_radians(),
    ));
    b.build().unwrap()
}

/// The exact image: the square spans `±HALF_SIDE / (DISTANCE · tan(fov/2))` of the half-image, so in pixels
/// it covers `[lo, hi]²` with `lo = SIZE/2 · (1 − r)`, `hi = SIZE/2 · (1 + r)`.
fn exact_image() -> Vec<f64> {
    let tan_half_fov = (0.5 * (FOV_DEGREES as f64).to_radians()).tan();
    let r = HALF_SIDE as f64 / (DISTANCE as f64 * tan_half_fov);
    let half = SIZE as f64 / 2.0;
    let (lo, hi) = (half * (1.0 - r), half * (1.0 + r));
    let overlap = |i: usize| (hi.min(i as f64 + 1.0) - lo.max(i as f64)).max(0.0);
    (0..SIZE * SIZE)
        .map(|p| RADIANCE as f64 * overlap(p % SIZE) * overlap(p / SIZE))
        .collect()
}

fn render(scene: &Scene, edges: EmitterEdgeSampling, seed: u64, threads: usize) -> RenderImage {
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: 16,
        seed,
        threads,
        max_depth: 2,
        emitter_edges: edges,
        ..RenderSettings::default()
    };
    Renderer::new(settings)
        .render(scene, &mut |_| true)
        .unwrap()
        .0
}

/// Squared error against the exact image, summed over pixels.
fn squared_error(img: &RenderImage, exact: &[f64]) -> f64 {
    img.beauty
        .iter()
        .zip(exact)
        .map(|(p, e)| (p.x as f64 - e).powi(2))
        .sum()
}

#[test]
fn the_outline_of_a_square_is_marked_and_its_diagonal_is_not() {
    let scene = square_scene();
    let EdgeDecision::On(edges) = EmitterEdgeSampling::Auto.decide(&scene, SIZE, SIZE) else {
        panic!(
            "a visible emitter in a scene without media gets supersampling: {:?}",
            EmitterEdgeSampling::Auto.decide(&scene, SIZE, SIZE)
        );
    };
    let exact = exact_image();
    for y in 0..SIZE {
        for x in 0..SIZE {
            let v = exact[y * SIZE + x];
            let partial = v > 1e-9 && v < RADIANCE as f64 - 1e-9;
            assert_eq!(
                edges.is_marked(x, y),
                partial,
                "pixel ({x}, {y}) covered {v}"
            );
        }
    }
    assert!(matches!(
        EmitterEdgeSampling::Off.decide(&scene, SIZE, SIZE),
        EdgeDecision::Off(_)
    ));
}

#[test]
fn supersampled_edges_match_the_exact_image_with_less_error() {
    let scene = square_scene();
    let exact = exact_image();
    let (mut error_on, mut error_off) = (0.0, 0.0);
    for seed in 0..4 {
        let on = render(&scene, EmitterEdgeSampling::Auto, seed, 2);
        // Unbiased: every pixel within 4 standard errors of the exact value (pixels the square covers whole
        // or not at all have no variance and must be exact).
        for (i, (p, e)) in on.beauty.iter().zip(&exact).enumerate() {
            let se = (on.variance[i].x as f64).sqrt();
            assert!(
                (p.x as f64 - e).abs() <= 4.0 * se + 1e-4 * RADIANCE as f64,
                "seed {seed} pixel {i}: {} against exact {e} (standard error {se})",
                p.x
            );
        }
        // And the image's total, whose standard error is far smaller than any one pixel's.
        let total: f64 = on.beauty.iter().map(|p| p.x as f64).sum();
        let total_se = on.variance.iter().map(|v| v.x as f64).sum::<f64>().sqrt();
        let exact_total: f64 = exact.iter().sum();
        assert!(
            (total - exact_total).abs() <= 4.0 * total_se + 1e-5 * exact_total,
            "seed {seed}: image total {total} against exact {exact_total} (standard error {total_se})"
        );
        error_on += squared_error(&on, &exact);
        error_off += squared_error(&render(&scene, EmitterEdgeSampling::Off, seed, 2), &exact);
    }
    // 16 camera rays per sample, stratified together: far more than 4x less squared error on the outline.
    eprintln!("squared error {error_on:.4} with supersampling, {error_off:.4} without");
    assert!(
        error_on * 4.0 < error_off,
        "squared error {error_on:.4} with supersampling, {error_off:.4} without"
    );
}

#[test]
fn supersampled_renders_are_the_same_for_any_thread_count() {
    let scene = square_scene();
    let one = render(&scene, EmitterEdgeSampling::Auto, 3, 1);
    let four = render(&scene, EmitterEdgeSampling::Auto, 3, 4);
    assert_eq!(one.beauty, four.beauty);
    assert_eq!(one.variance, four.variance);
}
