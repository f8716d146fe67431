//! Alpha coverage (glTF `alphaMode`, issue 13 item 2): MASK is a cut-out that camera and shadow rays both
//! respect, BLEND lets a ray through with probability 1 − alpha. The references are independent of the
//! renderer: the coverage a texture's own texels give (decoded here with the `image` crate), or a binomial
//! fraction with its standard error.

use crate::common;

use nimbus::geometry::Mesh;
use nimbus::material::{AlphaMode, Filter, Material, Sampler, Texture, Wrap};
use nimbus::math::{Ray, Rng, Vec2, Vec3, Vec4};
use nimbus::scene::{Scene, SceneBuilder};
use std::path::Path;

/// A unit quad in the plane z = `z`, facing +z, with texture coordinates u = x and v = y.
fn textured_quad(z: f32, material: u32) -> Mesh {
    let mut mesh = common::quad(
        [
            Vec3::new(0.0, 0.0, z),
            Vec3::new(1.0, 0.0, z),
            Vec3::new(1.0, 1.0, z),
            Vec3::new(0.0, 1.0, z),
        ],
        material,
    );
    mesh.uvs = Some(vec![
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ]);
    mesh
}

/// A front quad at z = 0 with `front` over an opaque back quad at z = −1.
fn two_quads(front: Material, textures: Vec<Texture>) -> Scene {
    let mut b = SceneBuilder::new();
    for t in textures {
        b.add_texture(t);
    }
    let front = b.add_material(front);
    let back = b.add_material(Material::lambertian("back", Vec3::ONE));
    b.add_mesh(textured_quad(0.0, front));
    b.add_mesh(textured_quad(-1.0, back));
    b.add_point_light(Vec3::new(0.5, 0.5, 3.0), Vec3::ONE);
    b.build().unwrap()
}

fn down_at(x: f32, y: f32) -> Ray {
    Ray::new(Vec3::new(x, y, 1.0), Vec3::NEG_Z)
}

#[test]
fn mask_cuts_out_for_camera_and_shadow_rays() {
    // Two texels: alpha 0.2 on the left half, 0.9 on the right; cut-off 0.5.
    let alpha = Texture::from_linear(
        2,
        1,
        vec![Vec4::new(1.0, 1.0, 1.0, 0.2), Vec4::new(1.0, 1.0, 1.0, 0.9)],
    )
    .unwrap()
    .with_sampler(Sampler::unfiltered(Filter::Nearest, Wrap::ClampToEdge));
    let mut m = Material::lambertian("mask", Vec3::ONE);
    m.base_color_texture = Some(0);
    m.alpha_mode = AlphaMode::Mask { cutoff: 0.5 };
    let scene = two_quads(m, vec![alpha]);
    for i in 0..20 {
        let x = 0.025 + 0.05 * i as f32;
        let ray = down_at(x, 0.5);
        let hit = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap();
        let covered = x > 0.5;
        let expected_t = if covered { 1.0 } else { 2.0 };
        assert!(
            (hit.t - expected_t).abs() < 1e-4,
            "x {x}: hit at t {} instead of {expected_t}",
            hit.t
        );
        assert_eq!(
            scene.occluded(&ray, 0.0, 1.5),
            covered,
            "shadow ray at x {x}"
        );
    }
}

#[test]
fn an_opaque_material_ignores_alpha() {
    let mut m = Material::lambertian("opaque", Vec3::ONE);
    m.base_color.w = 0.0;
    let scene = two_quads(m, Vec::new());
    let hit = scene
        .intersect(&down_at(0.3, 0.3), 0.0, f32::INFINITY)
        .unwrap();
    assert!((hit.t - 1.0).abs() < 1e-4);
}

/// Fraction of `n` random vertical rays over the unit square that hit the front quad (closest hits), and
/// that the front quad shadows.
fn blend_fractions(scene: &Scene, n: u32) -> (f64, f64) {
    let mut rng = Rng::new(11, 5);
    let (mut hits, mut shadows) = (0u32, 0u32);
    for _ in 0..n {
        let ray = down_at(rng.next_f32(), rng.next_f32());
        let hit = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap();
        hits += u32::from(hit.t < 1.5);
        shadows += u32::from(scene.occluded(&ray, 0.0, 1.5));
    }
    (hits as f64 / n as f64, shadows as f64 / n as f64)
}

#[test]
fn blend_passes_rays_with_probability_one_minus_alpha() {
    for alpha in [0.0f32, 0.3, 0.75, 1.0] {
        let mut m = Material::lambertian("blend", Vec3::ONE);
        m.base_color.w = alpha;
        m.alpha_mode = AlphaMode::Blend;
        let scene = two_quads(m, Vec::new());
        let n = 20_000;
        let (hit, shadow) = blend_fractions(&scene, n);
        let a = alpha as f64;
        let tolerance = 4.0 * (a * (1.0 - a) / n as f64).sqrt() + 1e-9;
        assert!(
            (hit - a).abs() <= tolerance,
            "alpha {alpha}: hit fraction {hit}"
        );
        assert!(
            (shadow - a).abs() <= tolerance,
            "alpha {alpha}: shadowed fraction {shadow}"
        );
    }
}

#[test]
fn blend_decisions_are_deterministic() {
    let mut m = Material::lambertian("blend", Vec3::ONE);
    m.base_color.w = 0.5;
    m.alpha_mode = AlphaMode::Blend;
    let scene = two_quads(m, Vec::new());
    let ray = down_at(0.37, 0.61);
    let first = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap().t;
    for _ in 0..10 {
        assert_eq!(scene.intersect(&ray, 0.0, f32::INFINITY).unwrap().t, first);
    }
}

/// The texture's alpha at `uv` (nearest texel, repeating), read from the PNG with the `image` crate.
fn png_alpha(image: &image::RgbaImage, uv: Vec2) -> f32 {
    let (w, h) = image.dimensions();
    let x = ((uv.x.rem_euclid(1.0) * w as f32) as u32).min(w - 1);
    let y = ((uv.y.rem_euclid(1.0) * h as f32) as u32).min(h - 1);
    image.get_pixel(x, y)[3] as f32 / 255.0
}

/// For `samples` random points on the meshes of `material` in the real file, the ray that arrives there along
/// the face normal, with the alpha of the file's own PNG at the point: (hits the point?, png alpha).
fn real_file_probes(scene: &Scene, png: &Path, material: &str, samples: usize) -> Vec<(bool, f32)> {
    let image = image::open(png).unwrap().to_rgba8();
    let mut rng = Rng::new(3, 9);
    let meshes: Vec<&Mesh> = scene
        .meshes()
        .iter()
        .filter(|m| scene.materials()[m.material as usize].name == material)
        .collect();
    assert!(!meshes.is_empty(), "no mesh uses material {material}");
    let mut probes = Vec::new();
    while probes.len() < samples {
        let mesh = meshes[(rng.next_f32() * meshes.len() as f32) as usize % meshes.len()];
        let tri = (rng.next_f32() * mesh.indices.len() as f32) as usize % mesh.indices.len();
        let (mut b1, mut b2) = (rng.next_f32(), rng.next_f32());
        if b1 + b2 > 1.0 {
            (b1, b2) = (1.0 - b1, 1.0 - b2);
        }
        let [p0, p1, p2] = mesh.triangle(tri);
        let p = p0 * (1.0 - b1 - b2) + p1 * b1 + p2 * b2;
        let [i0, i1, i2] = mesh.indices[tri].map(|i| i as usize);
        let uv = mesh.uvs.as_ref().unwrap();
        let uv = uv[i0] * (1.0 - b1 - b2) + uv[i1] * b1 + uv[i2] * b2;
        let n = (p1 - p0).cross(p2 - p0).normalize();
        let origin = p + n * 0.5;
        let ray = Ray::new(origin, -n);
        let hit = scene.intersect(&ray, 0.0, f32::INFINITY);
        let hits_point = hit.is_some_and(|h| (h.t - 0.5).abs() < 1e-3);
        probes.push((hits_point, png_alpha(&image, uv)));
    }
    probes
}

#[test]
fn blender_alpha_mask_file_cuts_out_where_its_texture_says() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("realworld/gltf/blender-io-01_alpha_mask");
    let scene = Scene::load(&dir.join("01_alpha_mask.gltf")).unwrap();
    let cutoff = 0.42;
    let probes = real_file_probes(&scene, &dir.join("01_alpha_mask.png"), "Alpha_Mask", 4000);
    // Texels at the cut-off's edge can go either way under bilinear filtering: allow 3% disagreement.
    let wrong = probes
        .iter()
        .filter(|(hit, a)| *hit != (*a >= cutoff))
        .count();
    let covered = probes.iter().filter(|(_, a)| *a >= cutoff).count();
    assert!(
        covered > 400 && covered < 3600,
        "the texture should cut out part of the plane ({covered} of 4000 covered)"
    );
    assert!(
        wrong * 100 <= 3 * probes.len(),
        "{wrong} of {} probes disagree with the texture's coverage",
        probes.len()
    );
}

#[test]
fn blender_alpha_blend_file_covers_in_proportion_to_alpha() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let dir = shared.join("realworld/gltf/blender-io-01_alpha_blend");
    let scene = Scene::load(&dir.join("01_alpha_blend.gltf")).unwrap();
    let probes = real_file_probes(
        &scene,
        &dir.join("01_alpha_blend.png"),
        "Transparent_Plane",
        8000,
    );
    let n = probes.len() as f64;
    let hit_fraction = probes.iter().filter(|(hit, _)| *hit).count() as f64 / n;
    let mean_alpha = probes.iter().map(|(_, a)| *a as f64).sum::<f64>() / n;
    // Each probe hits with probability alpha(uv): the variance of the fraction is at most 1/(4n); bilinear
    // against nearest texels adds a little, covered by the extra 0.01.
    let tolerance = 4.0 * (0.25 / n).sqrt() + 0.01;
    assert!(
        mean_alpha < 0.9,
        "the texture should be partly transparent (mean alpha {mean_alpha})"
    );
    assert!(
        (hit_fraction - mean_alpha).abs() <= tolerance,
        "hit fraction {hit_fraction} against mean alpha {mean_alpha} (tolerance {tolerance})"
    );
}
