//! Texture filtering in renders: a fine checker on a ground plane seen at grazing angles. With glTF's default
//! LINEAR_MIPMAP_LINEAR minification the far checker is filtered to its mean over each pixel's footprint (the
//! ray cone), so one sample per pixel already gives a smooth grey; with NEAREST and no mip-maps the same pixels
//! alias to random black and white.

use nimbus::geometry::Mesh;
use nimbus::material::{Filter, Sampler, Texture, Wrap};
use nimbus::math::{Rgb, Vec2, Vec3, Vec4};
use nimbus::render::{RenderSettings, Renderer};
use nimbus::{Camera, Material, SceneBuilder};

/// Renders the plane with `sampler` and returns the albedo AOV's green channel, row by row, with `None` for
/// pixels whose sample missed the plane.
fn render_plane_albedo(sampler: Sampler, size: usize) -> Vec<Option<f32>> {
    let n = 64;
    // A one-texel checker of linear 0 and 1: its mean is 0.5.
    let texels = (0..n * n)
        .map(|i| Vec4::splat(((i % n + i / n) % 2) as f32))
        .collect();
    let texture = Texture::from_linear(n, n, texels)
        .unwrap()
        .with_sampler(sampler);
    let mut b = SceneBuilder::default();
    b.add_texture(texture);
    let mut material = Material::lambertian("checker", Rgb::ONE);
    material.base_color_texture = Some(0);
    let m = b.add_material(material);
    let (s, repeats) = (200.0, 40.0);
    b.add_mesh(Mesh {
        name: "ground".into(),
        positions: vec![
            Vec3::new(-s, 0.0, -s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(s, 0.0, -s),
        ],
        normals: vec![Vec3::Y; 4],
        uvs: Some(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(0.0, repeats),
            Vec2::new(repeats, repeats),
            Vec2::new(repeats, 0.0),
        ]),
        uvs1: None,
        colors: None,
        tangents: None,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: m,
        motion: None,
        ..Default::default()
    });
    // Eye 1 m up, looking 10° down: the lower rows are close (magnified), the upper rows far and grazing.
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0 - 10f32.to_radians().tan(), -1.0),
        20f32.to_radians(),
    ));
    let scene = b.build().unwrap();
    let settings = RenderSettings {
        width: size,
        height: size,
        spp: 1,
        seed: 5,
        threads: 2,
        max_depth: 0,
        ..Default::default()
    };
    let (img, _) = Renderer::new(settings)
        .render(&scene, &mut |_| true)
        .unwrap();
    img.albedo
        .iter()
        .zip(&img.depth)
        .map(|(a, &d)| (d > 0.0).then_some(a.y))
        .collect()
}

fn mean_and_spread(values: &[f32]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / n;
    let var = values
        .iter()
        .map(|&v| (v as f64 - mean).powi(2))
        .sum::<f64>()
        / n;
    (mean, var.sqrt())
}

#[test]
fn mip_mapping_filters_a_distant_checker_to_its_mean() {
    let size = 48;
    // The image centre looks 10° down and the top row at the horizon: the top eighth sees the plane 15 m to
    // 200 m away, tens to hundreds of texels per pixel. Pixels whose sample missed the plane are left out.
    let far_rows = |img: &[Option<f32>]| -> Vec<f32> {
        img[..size * size / 8].iter().flatten().copied().collect()
    };
    let near_rows = |img: &[Option<f32>]| -> Vec<f32> {
        img[size * size * 7 / 8..]
            .iter()
            .flatten()
            .copied()
            .collect()
    };
    let mipmapped = render_plane_albedo(Sampler::default(), size);
    let nearest = render_plane_albedo(Sampler::unfiltered(Filter::Nearest, Wrap::Repeat), size);
    let (mean_mip, spread_mip) = mean_and_spread(&far_rows(&mipmapped));
    let (mean_nearest, spread_nearest) = mean_and_spread(&far_rows(&nearest));
    println!("far rows: mip-mapped {mean_mip:.3} ± {spread_mip:.3}, nearest {mean_nearest:.3} ± {spread_nearest:.3}");
    // Without filtering each far pixel is one random texel: 0 or 1, spread 0.5.
    assert!(spread_nearest > 0.4, "{spread_nearest}");
    // Filtered, the far pixels sit close to the checker's mean.
    assert!(spread_mip < 0.1, "{spread_mip}");
    assert!((mean_mip - 0.5).abs() < 0.05, "{mean_mip}");
    // Close to the camera a texel covers more than a pixel, so the texture is magnified and keeps its contrast:
    // NEAREST shows black and white (spread 0.5); LINEAR magnification of a one-texel checker blends them
    // bilinearly, 0.5 + (1 − 2x)(1 − 2y)/2 over a texel, whose spread is 1/6 ≈ 0.17.
    let (near_mip, near_nearest) = (
        mean_and_spread(&near_rows(&mipmapped)).1,
        mean_and_spread(&near_rows(&nearest)).1,
    );
    println!("near rows: spread mip-mapped {near_mip:.3}, nearest {near_nearest:.3}");
    assert!(near_mip > 0.1 && near_nearest > 0.4);
}
