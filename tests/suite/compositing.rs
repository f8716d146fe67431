//! Compositing layers against closed forms: alpha as coverage (a homogeneous slab, a half-covered pixel), the
//! transparent film's environment layer, the light-path layers and light groups summing to the beauty, holdouts
//! and the shadow catcher (Cryptomatte is in `tests/suite/cryptomatte.rs`).
//!
//! Tolerances are 4 standard errors, the standard error measured from independent renders (seeds) of the same
//! scene where a layer has no variance layer of its own.

use crate::common;

use common::{boundary, cuboid, quad};
use nimbus::light::{EnvironmentLight, Light, PointLight};
use nimbus::material::Material;
use nimbus::math::{Rgb, Vec3};
use nimbus::render::aovs::AovSelection;
use nimbus::render::{LightGroupMode, RenderImage, RenderSettings, Renderer};
use nimbus::scene::{LightTag, SceneBuilder};
use nimbus::volume::homogeneous::HomogeneousMedium;
use nimbus::{Camera, Scene};
use std::sync::Arc;

/// Renders `scene` at `width`² with `spp`, `seed`, the layers `aovs` and a transparent film when asked.
fn render(
    scene: &Scene,
    width: usize,
    spp: u32,
    seed: u64,
    aovs: &str,
    transparent: bool,
) -> RenderImage {
    let settings = RenderSettings {
        width,
        height: width,
        spp,
        seed,
        threads: 2,
        max_depth: 16,
        aovs: Some(AovSelection::parse(aovs).unwrap()),
        transparent,
        light_groups: LightGroupMode::PerLight,
        ..RenderSettings::default()
    };
    Renderer::new(settings)
        .render(scene, &mut |_| true)
        .unwrap()
        .0
}

/// The mean of `value` over the images of `seeds` independent renders and its standard error (the spread of
/// the per-seed means).
fn mean_over_seeds(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// The mean of a channel's samples.
fn mean(samples: &[f32]) -> f64 {
    samples.iter().map(|&v| v as f64).sum::<f64>() / samples.len() as f64
}

/// A camera on +Z looking at the origin with a narrow field of view (rays within 0.6° of −Z).
fn narrow_camera() -> Camera {
    Camera::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 1.2f32.to_radians())
}

/// A slab 0.5 m thick (z from −0.25 to 0.25), filled with a homogeneous medium, in front of a uniform
/// environment of radiance 1; nothing else.
fn slab_scene(sigma_a: Rgb, sigma_s: Rgb) -> Scene {
    let mut b = SceneBuilder::new();
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "slab", sigma_a, sigma_s, 0.0,
    )));
    common::fill_box(
        &mut b,
        medium,
        Vec3::new(-5.0, -5.0, -0.25),
        Vec3::new(5.0, 5.0, 0.25),
    );
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(narrow_camera());
    b.build().unwrap()
}

#[test]
fn a_homogeneous_slab_covers_one_minus_its_transmittance() {
    // Grey extinction: every sample's alpha is 0 or 1 (analog tracking), mean 1 − e^−τ.
    let (sigma_a, sigma_s) = (Rgb::splat(0.6), Rgb::splat(1.4));
    let tau: f64 = 2.0 * 0.5;
    let scene = slab_scene(sigma_a, sigma_s);
    let img = render(&scene, 16, 64, 1, "environment", true);
    let alpha = mean(&img.alpha);
    let expected = 1.0 - (-tau).exp();
    let n = (img.pixel_count() * 64) as f64;
    let se = (expected * (1.0 - expected) / n).sqrt();
    eprintln!("grey slab: alpha {alpha:.5}, expected {expected:.5}, s.e. {se:.5}");
    assert!(
        (alpha - expected).abs() < 4.0 * se,
        "alpha {alpha} vs 1 - e^-tau = {expected} (s.e. {se})"
    );
    // A transparent film leaves the environment seen through the slab out of the beauty, in its own layer:
    // the environment's radiance times the transmittance.
    let env = img.aov("environment").unwrap().rgb_pixels();
    let env_mean = env.iter().map(|c| c.x as f64).sum::<f64>() / env.len() as f64;
    let transmitted = (-tau).exp();
    assert!(
        (env_mean - transmitted).abs() < 4.0 * se,
        "environment layer {env_mean} vs e^-tau = {transmitted}"
    );
}

#[test]
fn a_chromatic_slab_covers_one_minus_its_mean_transmittance() {
    // Extinction 1:2:4 per channel: samples carry fractional weights (spectral MIS), and alpha is 1 − the mean
    // over channels of the transmittance, e^−τ_c averaged.
    let sigma_t = Rgb::new(1.0, 2.0, 4.0);
    let scene = slab_scene(sigma_t * 0.3, sigma_t * 0.7);
    let means: Vec<f64> = (0..8)
        .map(|seed| mean(&render(&scene, 8, 32, seed, "none", false).alpha))
        .collect();
    let (alpha, se) = mean_over_seeds(&means);
    let expected = 1.0
        - (0..3)
            .map(|c| (-sigma_t[c] as f64 * 0.5).exp())
            .sum::<f64>()
            / 3.0;
    eprintln!("chromatic slab: alpha {alpha:.5} ± {se:.5}, expected {expected:.5}");
    assert!(
        (alpha - expected).abs() < 4.0 * se.max(1e-4),
        "alpha {alpha} vs {expected} (s.e. {se})"
    );
}

#[test]
fn a_pixel_half_covered_by_an_edge_has_alpha_one_half() {
    // An opaque quad in the plane z = 0 whose right edge runs through the centres of pixel column 8 of 16.
    let mut b = SceneBuilder::new();
    let grey = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
    let yfov = 40f32.to_radians();
    let edge = (2.0 * 8.5 / 16.0 - 1.0) * (yfov * 0.5).tan() * 5.0;
    b.add_mesh(quad(
        [
            Vec3::new(-10.0, -10.0, 0.0),
            Vec3::new(edge, -10.0, 0.0),
            Vec3::new(edge, 10.0, 0.0),
            Vec3::new(-10.0, 10.0, 0.0),
        ],
        grey,
    ));
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, yfov));
    let scene = b.build().unwrap();
    let spp = 256;
    let img = render(&scene, 16, spp, 3, "none", true);
    let column = |x: usize| -> Vec<f32> { (0..16).map(|y| img.alpha[y * 16 + x]).collect() };
    let half = mean(&column(8));
    let se = (0.25 / (16.0 * spp as f64)).sqrt();
    eprintln!("edge column alpha {half:.5} (s.e. of independent samples {se:.5})");
    assert!((half - 0.5).abs() < 4.0 * se, "edge column alpha {half}");
    assert!(column(7).iter().all(|&a| a == 1.0));
    assert!(column(9).iter().all(|&a| a == 0.0));
    // Premultiplied: the transparent film's beauty is zero where nothing covers.
    assert!((0..16).all(|y| img.beauty[y * 16 + 12] == Rgb::ZERO));
}

/// A scene with every kind of light path: a diffuse floor, a metal box, a glass sphere, a scattering medium in
/// a box, an emissive panel, a point light and an environment, each light in its own group.
fn everything_scene() -> Scene {
    let mut b = SceneBuilder::new();
    let floor = b.add_material(Material::lambertian("floor", Rgb::new(0.7, 0.6, 0.5)));
    let mut metal = Material::lambertian("metal", Rgb::new(0.9, 0.7, 0.4));
    metal.metallic = 1.0;
    metal.roughness = 0.3;
    metal.specular_factor = 1.0;
    let metal = b.add_material(metal);
    let mut glass = Material::lambertian("glass", Rgb::ONE);
    glass.transmission = 1.0;
    glass.roughness = 0.0;
    glass.specular_factor = 1.0;
    let glass = b.add_material(glass);
    let mut lamp = Material::lambertian("lamp", Rgb::ONE);
    lamp.emission = Rgb::new(4.0, 3.5, 3.0);
    lamp.tags.light_group = Some("panel".into());
    let lamp = b.add_material(lamp);
    let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
        "fog",
        Rgb::splat(0.3),
        Rgb::new(1.5, 1.2, 0.9),
        0.3,
    )));
    let fog = b.add_material(boundary(medium));
    b.add_mesh(quad(
        [
            Vec3::new(-3.0, 0.0, -3.0),
            Vec3::new(-3.0, 0.0, 3.0),
            Vec3::new(3.0, 0.0, 3.0),
            Vec3::new(3.0, 0.0, -3.0),
        ],
        floor,
    ));
    b.add_mesh(cuboid(
        Vec3::new(-1.2, 0.0, -0.8),
        Vec3::new(-0.4, 0.8, 0.0),
        metal,
    ));
    b.add_mesh(common::uv_sphere(
        Vec3::new(0.6, 0.5, 0.2),
        0.45,
        16,
        32,
        glass,
    ));
    b.add_mesh(cuboid(
        Vec3::new(0.3, 0.0, -1.4),
        Vec3::new(1.3, 1.0, -0.6),
        fog,
    ));
    b.add_mesh(quad(
        [
            Vec3::new(-0.5, 2.5, -0.5),
            Vec3::new(0.5, 2.5, -0.5),
            Vec3::new(0.5, 2.5, 0.5),
            Vec3::new(-0.5, 2.5, 0.5),
        ],
        lamp,
    ));
    // A small panel of the same lamp facing the camera, to be seen directly.
    b.add_mesh(quad(
        [
            Vec3::new(-0.3, 0.2, -2.9),
            Vec3::new(0.3, 0.2, -2.9),
            Vec3::new(0.3, 0.6, -2.9),
            Vec3::new(-0.3, 0.6, -2.9),
        ],
        lamp,
    ));
    b.add_tagged_light(
        Light::Point(PointLight {
            position: Vec3::new(1.5, 1.5, 1.0),
            intensity: Rgb::splat(2.0),
        }),
        LightTag {
            name: "bulb".into(),
            light_group: Some("bulb".into()),
        },
    );
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::new(
        0.3, 0.4, 0.6,
    ))));
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, 1.6, 4.0),
        Vec3::new(0.0, 0.5, 0.0),
        50f32.to_radians(),
    ));
    b.build().unwrap()
}

/// The largest relative difference over pixels and channels between `sum` and `beauty`, against
/// `max(beauty, floor)`.
fn largest_relative_difference(sum: &[Rgb], beauty: &[Rgb], floor: f32) -> f32 {
    sum.iter()
        .zip(beauty)
        .flat_map(|(s, b)| (0..3).map(move |c| (s[c] - b[c]).abs() / b[c].max(floor)))
        .fold(0.0, f32::max)
}

/// The light-path recombination: Σ (c_direct + c_indirect) × c_color over the surface classes, plus the
/// volume layers, emission and environment.
fn recombined(img: &RenderImage) -> Vec<Rgb> {
    let layer = |name: &str| img.aov(name).unwrap().rgb_pixels();
    let mut sum = layer("emission");
    let mut add = |v: Vec<Rgb>| sum.iter_mut().zip(v).for_each(|(s, v)| *s += v);
    add(layer("environment"));
    add(layer("volume_direct"));
    add(layer("volume_indirect"));
    for class in ["diffuse", "glossy", "transmission"] {
        let color = layer(&format!("{class}_color"));
        for part in ["direct", "indirect"] {
            let light = layer(&format!("{class}_{part}"));
            add(light.iter().zip(&color).map(|(l, c)| *l * *c).collect());
        }
    }
    sum
}

#[test]
fn light_paths_and_light_groups_sum_to_the_beauty_in_every_pixel() {
    let scene = everything_scene();
    for transparent in [false, true] {
        let img = render(
            &scene,
            48,
            16,
            5,
            "lightpaths,colors,lightgroups",
            transparent,
        );
        let mut beauty = img.beauty.clone();
        if transparent {
            // The transparent beauty leaves out what the environment layer holds.
            let env = img.aov("environment").unwrap().rgb_pixels();
            beauty.iter_mut().zip(&env).for_each(|(b, e)| *b += *e);
        }
        let paths = largest_relative_difference(&recombined(&img), &beauty, 1e-2);
        let groups: Vec<String> = img
            .aovs
            .iter()
            .filter(|l| l.name.starts_with("lg_"))
            .map(|l| l.name.clone())
            .collect();
        // Per light: the emissive panels (both named after their meshes, "quad", so one group), the point
        // light and the environment.
        assert_eq!(groups, ["lg_quad", "lg_bulb", "lg_environment"]);
        let mut group_sum = vec![Rgb::ZERO; img.pixel_count()];
        for g in &groups {
            for (s, v) in group_sum.iter_mut().zip(img.aov(g).unwrap().rgb_pixels()) {
                *s += v;
            }
        }
        let lg = largest_relative_difference(&group_sum, &img.beauty, 1e-2);
        eprintln!(
            "transparent {transparent}: light paths vs beauty {paths:.2e}, light groups {lg:.2e} (relative)"
        );
        assert!(paths < 1e-5, "light-path layers miss the beauty by {paths}");
        assert!(lg < 1e-5, "light groups miss the beauty by {lg}");
        // Every kind of light is there.
        for name in [
            "diffuse_direct",
            "diffuse_indirect",
            "glossy_direct",
            "transmission_indirect",
            "volume_direct",
            "volume_indirect",
            "emission",
            "environment",
        ] {
            let l = img.aov(name).unwrap().rgb_pixels();
            assert!(l.iter().any(|c| c.max_element() > 0.0), "{name} is empty");
        }
    }
}

#[test]
fn a_diffuse_colour_is_the_albedo_it_divides() {
    // A Lambertian floor filling the view, lit by a point light: diffuse_color is its albedo, and
    // diffuse_direct × diffuse_color is the whole image (nothing else is lit).
    let albedo = Rgb::new(0.8, 0.5, 0.2);
    let mut b = SceneBuilder::new();
    let m = b.add_material(Material::lambertian("floor", albedo));
    b.add_mesh(quad(
        [
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(-10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, -10.0),
        ],
        m,
    ));
    b.add_point_light(Vec3::new(0.0, 1.0, 0.0), Rgb::splat(3.0));
    b.set_camera(Camera::look_at(Vec3::new(0.0, 2.0, 0.1), Vec3::ZERO, 0.6));
    let scene = b.build().unwrap();
    let img = render(&scene, 16, 4, 1, "diffuse_direct,diffuse_color", false);
    let color = img.aov("diffuse_color").unwrap().rgb_pixels();
    assert!(color
        .iter()
        .all(|c| (*c - albedo).abs().max_element() < 1e-6));
    let direct = img.aov("diffuse_direct").unwrap().rgb_pixels();
    for i in 0..img.pixel_count() {
        let rebuilt = direct[i] * color[i];
        assert!(
            (rebuilt - img.beauty[i]).abs().max_element() <= 1e-5 * img.beauty[i].max_element()
        );
        // Divided by the colour, the layer is the light the surface received: grey for a white light.
        assert!((direct[i].x - direct[i].z).abs() <= 1e-4 * direct[i].x);
    }
}

#[test]
fn a_holdout_cuts_the_alpha_and_still_occludes() {
    // A lit background plane; a holdout quad in front of its left half; a thin fog slab in front of both.
    let build = |fog: bool| {
        let mut b = SceneBuilder::new();
        let wall = b.add_material(Material::lambertian("wall", Rgb::splat(0.8)));
        let mut matte = Material::lambertian("matte", Rgb::splat(0.8));
        matte.tags.holdout = true;
        let matte = b.add_material(matte);
        b.add_mesh(quad(
            [
                Vec3::new(-5.0, -5.0, -1.0),
                Vec3::new(5.0, -5.0, -1.0),
                Vec3::new(5.0, 5.0, -1.0),
                Vec3::new(-5.0, 5.0, -1.0),
            ],
            wall,
        ));
        b.add_mesh(quad(
            [
                Vec3::new(-5.0, -5.0, 0.0),
                Vec3::new(0.0, -5.0, 0.0),
                Vec3::new(0.0, 5.0, 0.0),
                Vec3::new(-5.0, 5.0, 0.0),
            ],
            matte,
        ));
        if fog {
            let medium = b.add_medium(Arc::new(HomogeneousMedium::new(
                "fog",
                Rgb::splat(0.5),
                Rgb::ZERO,
                0.0,
            )));
            common::fill_box(
                &mut b,
                medium,
                Vec3::new(-5.0, -5.0, 0.5),
                Vec3::new(5.0, 5.0, 1.5),
            );
        }
        b.add_point_light(Vec3::new(0.0, 0.0, 3.0), Rgb::splat(5.0));
        b.set_camera(narrow_camera());
        b.build().unwrap()
    };
    let scene = build(false);
    let img = render(&scene, 16, 16, 2, "none", false);
    for y in 0..16 {
        for x in 0..16 {
            let i = y * 16 + x;
            if x < 7 {
                assert_eq!(img.alpha[i], 0.0, "holdout pixel ({x}, {y})");
                assert_eq!(img.beauty[i], Rgb::ZERO, "holdout pixel ({x}, {y})");
                // Its first-hit depth is the holdout's (it occludes the wall behind it).
                assert!((img.depth[i] - 10.0).abs() < 0.01, "{}", img.depth[i]);
            } else if x > 8 {
                assert_eq!(img.alpha[i], 1.0);
                assert!(img.beauty[i].x > 0.0);
            }
        }
    }
    // Absorbing fog of optical depth 0.5 in front: the holdout's alpha is the fog's opacity, 1 − e^−0.5.
    let fogged = build(true);
    let img = render(&fogged, 16, 64, 2, "none", false);
    let left: Vec<f32> = (0..16)
        .flat_map(|y| (0..6).map(move |x| y * 16 + x))
        .map(|i| img.alpha[i])
        .collect();
    let got = mean(&left);
    let expected = 1.0 - (-0.5f64).exp();
    let se = (expected * (1.0 - expected) / (left.len() * 64) as f64).sqrt();
    eprintln!("holdout behind fog: alpha {got:.4}, expected {expected:.4} (s.e. {se:.4})");
    assert!(
        (got - expected).abs() < 4.0 * se,
        "alpha {got} vs {expected}"
    );
}

#[test]
fn a_shadow_catcher_records_the_shadow_area_of_a_point_light() {
    // A point light at (−2, 2, 0); a horizontal square occluder of side 0.2 centred at (−1, 1, 0); the catcher
    // plane y = 0. The shadow is the occluder scaled by 2/(2 − 1) about the light: a square of side 0.4
    // centred at the origin, area 0.16 m². The camera looks straight down, so every pixel covers the same area
    // of the plane; the occluder's own image lies far left of the shadow.
    let mut b = SceneBuilder::new();
    let mut catcher = Material::lambertian("catcher", Rgb::splat(0.5));
    catcher.tags.shadow_catcher = true;
    let catcher = b.add_material(catcher);
    let grey = b.add_material(Material::lambertian("occluder", Rgb::splat(0.5)));
    b.add_mesh(quad(
        [
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(-10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, -10.0),
        ],
        catcher,
    ));
    let mut occluder = quad(
        [
            Vec3::new(-1.1, 1.0, -0.1),
            Vec3::new(-1.1, 1.0, 0.1),
            Vec3::new(-0.9, 1.0, 0.1),
            Vec3::new(-0.9, 1.0, -0.1),
        ],
        grey,
    );
    // Two-sided: the light sees its underside.
    occluder.indices.push([0, 2, 1]);
    occluder.indices.push([0, 3, 2]);
    b.add_mesh(occluder);
    b.add_point_light(Vec3::new(-2.0, 2.0, 0.0), Rgb::splat(4.0));
    let height = 5.0;
    let yfov = 20f32.to_radians();
    b.set_camera(Camera::look_at(
        Vec3::new(0.0, height, 0.0),
        Vec3::ZERO,
        yfov,
    ));
    let scene = b.build().unwrap();
    let size = 64;
    let side = 2.0 * height * (yfov * 0.5).tan();
    let pixel_area = (side / size as f32).powi(2) as f64;
    let areas: Vec<f64> = (0..4)
        .map(|seed| {
            let img = render(&scene, size, 16, seed, "shadow_catcher", true);
            let layer = img.aov("shadow_catcher").unwrap().rgb_pixels();
            // Catcher pixels are invisible: nothing covers them on a transparent film.
            assert!(img.alpha.iter().all(|&a| a == 0.0));
            layer.iter().map(|c| 1.0 - c.x as f64).sum::<f64>() * pixel_area
        })
        .collect();
    let (area, se) = mean_over_seeds(&areas);
    eprintln!("shadow area {area:.5} m² ± {se:.5}, closed form 0.16 m²");
    assert!(
        (area - 0.16).abs() < 4.0 * se.max(1e-4),
        "shadow area {area} vs 0.16"
    );
}

#[test]
fn a_blend_surface_covers_with_its_alpha() {
    // A BLEND quad of alpha 0.3 filling the view in front of the environment: each camera ray meets it with
    // probability 0.3 (stochastic transparency), so the alpha is 0.3.
    let mut b = SceneBuilder::new();
    let mut veil = Material::lambertian("veil", Rgb::splat(0.5));
    veil.alpha_mode = nimbus::material::AlphaMode::Blend;
    veil.base_color.w = 0.3;
    let veil = b.add_material(veil);
    b.add_mesh(quad(
        [
            Vec3::new(-5.0, -5.0, 0.0),
            Vec3::new(5.0, -5.0, 0.0),
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(-5.0, 5.0, 0.0),
        ],
        veil,
    ));
    b.add_light(Light::Environment(EnvironmentLight::Constant(Rgb::ONE)));
    b.set_camera(narrow_camera());
    let scene = b.build().unwrap();
    let spp = 64;
    let img = render(&scene, 16, spp, 9, "none", true);
    let alpha = mean(&img.alpha);
    let se = (0.3f64 * 0.7 / (img.pixel_count() as f64 * spp as f64)).sqrt();
    eprintln!("BLEND alpha 0.3: {alpha:.4} (s.e. {se:.4})");
    assert!((alpha - 0.3).abs() < 4.0 * se, "alpha {alpha}");
}
