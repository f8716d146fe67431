//! The glTF material extensions of issue 37 item 3 that the current Khronos sample set uses, read from files
//! and rendered against closed forms:
//! - `KHR_materials_diffuse_transmission`: a thin wall lit by a directional light from behind shows its
//!   Lambertian transmission `E · dt · c_dt / π`, from either face, a single-sided one included;
//! - `KHR_materials_dispersion`: a glass plate seen head-on under a white environment shows, per channel, the
//!   reflected `F` plus the refracted `(1 − F)/n²` at the channel's Cauchy index; dispersion 0 renders bit
//!   for bit as no extension;
//! - `KHR_materials_iridescence`: a mirror metal under a thin film seen head-on shows the film's Airy
//!   reflectance per channel; `iridescenceFactor` 0 renders bit for bit as no extension.
//!
//! Bad values are errors naming the field, and the three extensions are supported (required ones load).

use crate::common;

use nimbus::math::{Rgb, RGB_WAVELENGTHS_NM};
use nimbus::render::RenderImage;
use nimbus::scene::{load_builder, SceneBuilder};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// Where the camera stands on the z axis (it looks at the origin) and, when there is one, where the
/// directional light comes from (`true`: from behind the quad, shining toward +z); whether a constant white
/// environment lights the scene; and whether the mesh is the quad or a closed slab behind it.
struct Setup {
    camera_z: f32,
    light_from_behind: Option<bool>,
    environment: bool,
    slab: bool,
}

/// The vertices (four per face) and triangles of the quad (−1, −1, 0) … (1, 1, 0) facing +z, or of the closed
/// slab (−1, −1, −0.2) … (1, 1, 0) whose front face is that quad, wound counter-clockwise seen from outside.
fn mesh(slab: bool) -> (Vec<[f32; 3]>, Vec<u16>) {
    let (lo, hi) = ([-1.0f32, -1.0, -0.2], [1.0f32, 1.0, 0.0]);
    // Each face: the axis it faces along, its sign.
    let faces: &[(usize, bool)] = if slab {
        &[
            (2, true),
            (2, false),
            (0, true),
            (0, false),
            (1, true),
            (1, false),
        ]
    } else {
        &[(2, true)]
    };
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    for &(axis, plus) in faces {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let base = positions.len() as u16;
        for (a, b) in [(0, 0), (1, 0), (1, 1), (0, 1)] {
            let mut p = [0.0; 3];
            p[axis] = if plus { hi[axis] } else { lo[axis] };
            p[u] = if a == 1 { hi[u] } else { lo[u] };
            p[v] = if b == 1 { hi[v] } else { lo[v] };
            positions.push(p);
        }
        // (u, v, axis) is right-handed: counter-clockwise about +axis; reversed for the −axis face.
        let tris = if plus {
            [0, 1, 2, 0, 2, 3]
        } else {
            [0, 2, 1, 0, 3, 2]
        };
        indices.extend(tris.iter().map(|i| base + i));
    }
    (positions, indices)
}

/// A glTF file with one quad (−1, −1, 0) … (1, 1, 0) facing +z whose material 0 is `material` (JSON), a
/// narrow camera on the z axis looking at it, an optional directional light of 2 W/m² (radiometric units)
/// and an optional constant white environment.
fn quad_file(name: &str, material: &str, setup: &Setup) -> PathBuf {
    let (positions, indices) = mesh(setup.slab);
    let mut buf = Vec::new();
    for v in positions.iter().flatten() {
        buf.extend_from_slice(&v.to_le_bytes());
    }
    let index_offset = buf.len();
    for i in &indices {
        buf.extend_from_slice(&i.to_le_bytes());
    }
    let (vertices, index_count) = (positions.len(), indices.len());
    let index_bytes = 2 * index_count;
    // A node looking (or shining) along −z by default; turned about y to look along +z.
    let turn = |toward_plus_z: bool| {
        if toward_plus_z {
            r#","rotation":[0,1,0,0]"#
        } else {
            ""
        }
    };
    let camera = format!(
        r#"{{"camera":0,"translation":[0,0,{}]{}}}"#,
        setup.camera_z,
        turn(setup.camera_z < 0.0)
    );
    let (light_node, light_def) = match setup.light_from_behind {
        Some(behind) => (
            format!(
                r#",{{"extensions":{{"KHR_lights_punctual":{{"light":0}}}}{}}}"#,
                turn(behind)
            ),
            r#","extensions":{"KHR_lights_punctual":{"lights":[{"type":"directional","intensity":2.0}]}}"#,
        ),
        None => (String::new(), ""),
    };
    let nodes = if light_node.is_empty() {
        "[0,1]"
    } else {
        "[0,1,2]"
    };
    let environment = if setup.environment {
        r#","nimbus_environment":{"color":[1,1,1]}"#
    } else {
        ""
    };
    let text = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,
        "scenes":[{{"nodes":{nodes},"extras":{{"nimbus_light_units":"radiometric"{environment}}}}}],
        "extensionsUsed":["KHR_lights_punctual","KHR_materials_specular","KHR_materials_transmission",
          "KHR_materials_volume","KHR_materials_diffuse_transmission","KHR_materials_dispersion",
          "KHR_materials_iridescence"],
        "extensionsRequired":["KHR_materials_diffuse_transmission","KHR_materials_dispersion",
          "KHR_materials_iridescence"],
        "nodes":[{{"mesh":0}},{camera}{light_node}],
        "cameras":[{{"type":"perspective","perspective":{{"yfov":0.05,"znear":0.1,"aspectRatio":1.0}}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
        "materials":[{material}],
        "accessors":[
          {{"bufferView":0,"componentType":5126,"count":{vertices},"type":"VEC3","min":[-1,-1,-0.2],"max":[1,1,0]}},
          {{"bufferView":1,"componentType":5123,"count":{index_count},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{index_offset}}},
                       {{"buffer":0,"byteOffset":{index_offset},"byteLength":{index_bytes}}}],
        "buffers":[{{"uri":"data:application/octet-stream;base64,{}","byteLength":{}}}]{light_def}}}"#,
        common::base64(&buf),
        buf.len()
    );
    let dir = std::env::temp_dir().join(format!(
        "nimbus-gltf-material-extensions-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn load(path: &Path) -> SceneBuilder {
    load_builder(path, &Default::default()).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn render(path: &Path, size: usize, spp: u32) -> RenderImage {
    common::render_square(load(path), size, spp, 8, 11).0
}

/// A Lambertian material (no specular layer) with `KHR_materials_diffuse_transmission` `extension` (JSON
/// members).
fn translucent(extension: &str) -> String {
    format!(
        r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,1],"metallicFactor":0}},
        "extensions":{{"KHR_materials_specular":{{"specularFactor":0}},
        "KHR_materials_diffuse_transmission":{{{extension}}}}}}}"#
    )
}

/// Every pixel of `img` is `expected` within a relative 1e-4 (a delta light and nothing else to reach).
fn assert_every_pixel(img: &RenderImage, expected: Rgb, what: &str) {
    for p in &img.beauty {
        for c in 0..3 {
            assert!(
                (p[c] - expected[c]).abs() <= 1e-4 * expected[c].max(1e-3),
                "{what}: pixel {p} vs {expected}"
            );
        }
    }
}

#[test]
fn a_thin_wall_lit_from_behind_shows_its_lambertian_transmission() {
    let color = Rgb::new(1.0, 0.5, 0.25);
    let material = translucent(
        r#""diffuseTransmissionFactor":0.5,"diffuseTransmissionColorFactor":[1,0.5,0.25]"#,
    );
    let irradiance = 2.0;
    // Seen from the front face, lit from behind: E · dt · c / π.
    let front = quad_file(
        "leaf_front.gltf",
        &material,
        &Setup {
            camera_z: 3.0,
            light_from_behind: Some(true),
            environment: false,
            slab: false,
        },
    );
    let transmitted = color * (irradiance * 0.5 / std::f32::consts::PI);
    assert_every_pixel(
        &render(&front, 8, 4),
        transmitted,
        "front face, lit from behind",
    );
    // The same single-sided wall seen from its back face (not culled), lit from the front.
    let back = quad_file(
        "leaf_back.gltf",
        &material,
        &Setup {
            camera_z: -3.0,
            light_from_behind: Some(false),
            environment: false,
            slab: false,
        },
    );
    assert_every_pixel(
        &render(&back, 8, 4),
        transmitted,
        "back face, lit from the front",
    );
    // Lit on the side it is seen from: the diffuse reflection keeps 1 − dt of the base colour.
    let lit = quad_file(
        "leaf_lit.gltf",
        &material,
        &Setup {
            camera_z: 3.0,
            light_from_behind: Some(false),
            environment: false,
            slab: false,
        },
    );
    let reflected = Rgb::splat(irradiance * 0.5 / std::f32::consts::PI);
    assert_every_pixel(
        &render(&lit, 8, 4),
        reflected,
        "front face, lit from the front",
    );
}

/// The index of channel `c` for `n_d` and `dispersion` (Cauchy fitted to the Abbe number 20/dispersion, as
/// `KHR_materials_dispersion` gives it).
fn cauchy(n_d: f64, dispersion: f64, c: usize) -> f64 {
    let lambda = RGB_WAVELENGTHS_NM[c] as f64;
    (n_d + (n_d - 1.0) * dispersion / 20.0 * (523655.0 / (lambda * lambda) - 1.5168)).max(1.0)
}

/// Smooth glass (ior 1.5) whose volume absorbs all but e^−9000 of the light over the slab's 0.2 thickness
/// (attenuation colour 0.01 at 10⁻⁴ m), with `KHR_materials_dispersion` when given.
fn glass(dispersion: Option<f32>) -> String {
    let ext = dispersion.map_or(String::new(), |d| {
        format!(r#","KHR_materials_dispersion":{{"dispersion":{d}}}"#)
    });
    format!(
        r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[1,1,1,1],"metallicFactor":0,"roughnessFactor":0}},
        "extensions":{{"KHR_materials_transmission":{{"transmissionFactor":1}},
        "KHR_materials_volume":{{"thicknessFactor":0.2,"attenuationDistance":0.0001,
        "attenuationColor":[0.01,0.01,0.01]}}{ext}}}}}"#
    )
}

const HEAD_ON: Setup = Setup {
    camera_z: 3.0,
    light_from_behind: None,
    environment: true,
    slab: false,
};

/// [`HEAD_ON`] with the closed slab.
const SLAB: Setup = Setup {
    slab: true,
    ..HEAD_ON
};

#[test]
fn dispersion_refracts_each_channel_with_its_cauchy_index() {
    let dispersion = 10.0;
    let path = quad_file("dispersive.gltf", &glass(Some(dispersion as f32)), &SLAB);
    let img = render(&path, 32, 256);
    for c in 0..3 {
        // Head on (the rays are within 0.04 rad of the normal), the white environment reflected by the front
        // face, F = ((n − 1)/(n + 1))² at the channel's index; the refracted light is absorbed in the slab.
        let n = cauchy(1.5, dispersion, c);
        let expected = ((n - 1.0) / (n + 1.0)).powi(2);
        let (mean, se) = common::mean_and_se(&img, c);
        println!(
            "dispersion {dispersion} channel {c}: n {n:.5}, {mean:.5} ± {se:.5} vs {expected:.5}"
        );
        assert!(
            (mean - expected).abs() < 4.0 * se + 2e-4,
            "channel {c}: {mean} ± {se} vs {expected}"
        );
    }
}

#[test]
fn no_dispersion_or_no_film_renders_bit_for_bit_as_no_extension() {
    let render_bits = |name: &str, material: &str| {
        let img = render(&quad_file(name, material, &SLAB), 8, 16);
        img.beauty
            .iter()
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        render_bits("glass.gltf", &glass(None)),
        render_bits("glass_d0.gltf", &glass(Some(0.0)))
    );
    let metal = |ext: &str| {
        format!(
            r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[0.9,0.6,0.3,1],"metallicFactor":1,"roughnessFactor":0.3}}{ext}}}"#
        )
    };
    assert_eq!(
        render_bits("metal.gltf", &metal("")),
        render_bits(
            "metal_i0.gltf",
            &metal(
                r#","extensions":{"KHR_materials_iridescence":{"iridescenceFactor":0,"iridescenceIor":1.8,"iridescenceThicknessMaximum":250}}"#
            )
        )
    );
}

/// The reflectance of a film (index `n2`, thickness `d` nm) over a substrate of index `n3` at normal
/// incidence for wavelength `lambda`: `|(r₁₂ + r₂₃ e^{2iφ})/(1 + r₁₂ r₂₃ e^{2iφ})|²`, `φ = 2π n₂ d / λ`.
fn airy_normal(n2: f64, n3: f64, d: f64, lambda: f64) -> f64 {
    let (r12, r23) = ((1.0 - n2) / (1.0 + n2), (n2 - n3) / (n2 + n3));
    let phase = 4.0 * PI * n2 * d / lambda;
    let (c, s) = (phase.cos(), phase.sin());
    let num = (r12 + r23 * c).powi(2) + (r23 * s).powi(2);
    let den = (1.0 + r12 * r23 * c).powi(2) + (r12 * r23 * s).powi(2);
    num / den
}

#[test]
fn an_iridescent_mirror_shows_the_thin_film_reflectance() {
    let base = [0.9f64, 0.6, 0.3];
    let (n2, d) = (1.8, 300.0);
    let material = format!(
        r#"{{"pbrMetallicRoughness":{{"baseColorFactor":[{},{},{},1],"metallicFactor":1,"roughnessFactor":0}},
        "extensions":{{"KHR_materials_iridescence":{{"iridescenceFactor":1,"iridescenceIor":{n2},
        "iridescenceThicknessMinimum":50,"iridescenceThicknessMaximum":{d}}}}}}}"#,
        base[0], base[1], base[2]
    );
    let img = render(&quad_file("iridescent.gltf", &material, &HEAD_ON), 8, 4);
    for c in 0..3 {
        // The substrate's index from its F0 (the base colour), as the extension's notes derive it.
        let n3 = (1.0 + base[c].sqrt()) / (1.0 - base[c].sqrt());
        let expected = airy_normal(n2, n3, d, RGB_WAVELENGTHS_NM[c] as f64);
        let (mean, _) = common::mean_and_se(&img, c);
        println!(
            "iridescence channel {c}: {mean:.5} vs Airy {expected:.5} (Schlick {})",
            base[c]
        );
        assert!(
            (mean - expected).abs() < 1e-3,
            "channel {c}: {mean} vs {expected}"
        );
    }
}

#[test]
fn the_extensions_are_read_and_bad_values_name_their_field() {
    let setup = Setup {
        camera_z: 3.0,
        light_from_behind: None,
        environment: false,
        slab: false,
    };
    let material = r#"{"pbrMetallicRoughness":{"metallicFactor":0},"extensions":{
        "KHR_materials_transmission":{"transmissionFactor":0.5},
        "KHR_materials_volume":{"thicknessFactor":0.1},
        "KHR_materials_diffuse_transmission":{"diffuseTransmissionFactor":0.3,"diffuseTransmissionColorFactor":[0.2,0.4,0.6]},
        "KHR_materials_dispersion":{"dispersion":0.5},
        "KHR_materials_iridescence":{"iridescenceFactor":0.8,"iridescenceIor":1.6,"iridescenceThicknessMinimum":150,"iridescenceThicknessMaximum":600}}}"#;
    let b = load(&quad_file("all.gltf", material, &setup));
    assert!(
        !b.warnings().iter().any(|w| w.contains("not supported")),
        "{:?}",
        b.warnings()
    );
    let m = &b.materials()[0];
    let dt = m.diffuse_transmission.expect("diffuse transmission");
    assert_eq!((dt.factor, dt.color), (0.3, Rgb::new(0.2, 0.4, 0.6)));
    assert_eq!(m.dispersion, 0.5);
    assert!(m.is_dispersive() && m.interior.is_some());
    let film = m.iridescence.expect("iridescence");
    assert_eq!(
        (
            film.factor,
            film.ior,
            film.thickness_min,
            film.thickness_max
        ),
        (0.8, 1.6, 150.0, 600.0)
    );
    // Diffuse transmission alone fills a KHR_materials_volume interior too; dispersion without a volume
    // is ignored with a warning.
    let thick = load(&quad_file(
        "thick.gltf",
        r#"{"extensions":{"KHR_materials_volume":{"thicknessFactor":1},"KHR_materials_diffuse_transmission":{"diffuseTransmissionFactor":1}}}"#,
        &setup,
    ));
    assert!(thick.materials()[0].interior.is_some());
    let thin = load(&quad_file(
        "thin.gltf",
        r#"{"extensions":{"KHR_materials_transmission":{"transmissionFactor":1},"KHR_materials_dispersion":{"dispersion":1}}}"#,
        &setup,
    ));
    assert_eq!(thin.materials()[0].dispersion, 0.0);
    assert!(thin
        .warnings()
        .iter()
        .any(|w| w.contains("dispersion needs KHR_materials_volume")));
    for (ext, field) in [
        (
            r#""KHR_materials_diffuse_transmission":{"diffuseTransmissionFactor":1.5}"#,
            "KHR_materials_diffuse_transmission.diffuseTransmissionFactor",
        ),
        (
            r#""KHR_materials_diffuse_transmission":{"diffuseTransmissionColorFactor":[1,2]}"#,
            "KHR_materials_diffuse_transmission.diffuseTransmissionColorFactor",
        ),
        (
            r#""KHR_materials_diffuse_transmission":{"diffuseTransmissionTexture":{"index":3}}"#,
            "KHR_materials_diffuse_transmission.diffuseTransmissionTexture",
        ),
        (
            r#""KHR_materials_dispersion":{"dispersion":-1}"#,
            "KHR_materials_dispersion.dispersion",
        ),
        (
            r#""KHR_materials_iridescence":{"iridescenceIor":0.5}"#,
            "KHR_materials_iridescence.iridescenceIor",
        ),
        (
            r#""KHR_materials_iridescence":{"iridescenceThicknessMaximum":"thick"}"#,
            "KHR_materials_iridescence.iridescenceThicknessMaximum",
        ),
        (
            r#""KHR_materials_iridescence":{"iridescenceFactor":2}"#,
            "KHR_materials_iridescence.iridescenceFactor",
        ),
    ] {
        let material = format!(r#"{{"extensions":{{{ext}}}}}"#);
        let path = quad_file("bad.gltf", &material, &setup);
        let err = load_builder(&path, &Default::default())
            .err()
            .unwrap_or_else(|| panic!("{ext} loads"));
        assert!(err.to_string().contains(field), "{err}");
    }
}
