//! A deterministic sweep of the transmissive BSDFs over the cases where their formulas divide by something that
//! can vanish (issue 33: NaN samples from glass): grazing and exactly tangent directions (down to denormal
//! cosines), roughness 0, at and just above the delta threshold, indices 1 and just above 1 (where the
//! refraction half vector cancels), total internal reflection, directions from below (a shading normal turned
//! away from the viewer), the mirror, refracted and opposite directions themselves, and partial transmission
//! under a metal or a diffuse base. Every value the integrator multiplies into a path must be finite and
//! non-negative: `eval`, `pdf`, the split and colours, and each sample's weight `f |cos| / pdf`.

use nimbus::material::{Bsdf, PbrParams};
use nimbus::math::{is_finite_rgb, Rgb, Vec2, Vec3};

/// Snell's law for a unit `wo` above the normal +z into index ratio `eta` (independent of the crate's own
/// `refract`); `None` under total internal reflection.
fn refract(wo: Vec3, eta: f32) -> Option<Vec3> {
    let sin2_t = (1.0 - wo.z * wo.z).max(0.0) / (eta * eta);
    (sin2_t < 1.0).then(|| Vec3::new(-wo.x / eta, -wo.y / eta, -(1.0 - sin2_t).sqrt()))
}

/// Cosines from normal incidence to exactly tangent, through denormal values.
const COSINES: [f32; 11] = [
    1.0, 0.7, 0.2, 1e-2, 1e-4, 1e-7, 1e-12, 1e-20, 1e-38, 1e-42, 0.0,
];

/// Unit directions at each cosine of [`COSINES`], above and below, at two azimuths.
fn directions() -> Vec<Vec3> {
    let mut out = Vec::new();
    for &c in &COSINES {
        let s = (1.0 - c * c).max(0.0).sqrt();
        for phi in [0.3f32, 2.0] {
            for sign in [1.0f32, -1.0] {
                out.push(Vec3::new(s * phi.cos(), s * phi.sin(), sign * c));
            }
        }
    }
    out
}

/// The materials swept: pure and partial transmission over each index and roughness of the module
/// documentation.
fn materials() -> Vec<(PbrParams, Bsdf)> {
    let mut out = Vec::new();
    for ior in [
        1.0f32, 1.000_001, 1.000_002, 1.000_01, 1.0001, 1.01, 1.33, 1.5, 2.4,
    ] {
        for roughness in [
            0.0f32, 0.005, 0.0099, 0.01, 0.0101, 0.011, 0.02, 0.1, 0.5, 1.0,
        ] {
            for (transmission, metallic) in [(1.0f32, 0.0f32), (0.5, 0.0), (0.5, 0.5)] {
                let p = PbrParams {
                    base_color: Rgb::new(0.9, 0.5, 1.0),
                    metallic,
                    roughness,
                    ior,
                    transmission,
                    ..Default::default()
                };
                out.push((p, Bsdf::from_gltf(&p)));
            }
        }
    }
    out
}

fn finite_non_negative(c: Rgb) -> bool {
    is_finite_rgb(c) && c.min_element() >= 0.0
}

#[test]
fn transmissive_bsdfs_stay_finite_in_every_degenerate_case() {
    let dirs = directions();
    let mut failures = Vec::new();
    for (p, bsdf) in materials() {
        let case = |what: &str, wo: Vec3, wi: Vec3| {
            format!(
                "{what}: ior {} roughness {} transmission {} metallic {}, wo {wo:?}, wi {wi:?}",
                p.ior, p.roughness, p.transmission, p.metallic
            )
        };
        for &wo in &dirs {
            let colors = bsdf.colors(wo);
            if !(finite_non_negative(colors.total())) {
                failures.push(case("colors", wo, Vec3::ZERO));
            }
            // Every swept direction, and the mirror, refracted and opposite directions of wo.
            let mut wis = dirs.clone();
            wis.push(Vec3::new(-wo.x, -wo.y, wo.z));
            wis.push(-wo);
            let (up, eta) = if wo.z < 0.0 {
                (-wo, 1.0 / p.ior)
            } else {
                (wo, p.ior)
            };
            if let Some(t) = refract(up, eta) {
                wis.push(if wo.z < 0.0 { -t } else { t });
            }
            for &wi in &wis {
                let f = bsdf.eval(wo, wi);
                let pdf = bsdf.pdf(wo, wi);
                let split = bsdf.eval_split(wo, wi).total();
                if !(finite_non_negative(f) && pdf.is_finite() && pdf >= 0.0) {
                    failures.push(case(&format!("eval {f:?} pdf {pdf}"), wo, wi));
                }
                if !finite_non_negative(split) {
                    failures.push(case(&format!("eval_split {split:?}"), wo, wi));
                }
            }
            for i in 0..4 {
                for j in 0..3 {
                    for k in 0..3 {
                        let u_lobe = [0.0, 0.3, 0.7, 1.0 - f32::EPSILON][i];
                        let u = Vec2::new([0.0, 0.5, 0.999_999][j], [0.0, 0.25, 0.9][k]);
                        let Some(s) = bsdf.sample(wo, u_lobe, u) else {
                            continue;
                        };
                        let weight = s.f * (s.wi.z.abs() / s.pdf);
                        let unit = (s.wi.length() - 1.0).abs() < 1e-4;
                        if !(s.pdf > 0.0
                            && s.pdf.is_finite()
                            && finite_non_negative(weight)
                            && unit)
                        {
                            failures.push(case(
                                &format!("sample {s:?} weight {weight:?}"),
                                wo,
                                s.wi,
                            ));
                        }
                    }
                }
            }
        }
    }
    // One line per failing check and pair of cosines, so that a failure names its degenerate case.
    let mut classes = std::collections::BTreeMap::<String, usize>::new();
    for f in &failures {
        let what = f.split([' ', ':']).next().unwrap_or("");
        let cos = |key: &str| {
            f.split(key)
                .nth(1)
                .and_then(|r| r.split(')').next())
                .and_then(|v| v.rsplit(", ").next())
                .unwrap_or("")
                .to_owned()
        };
        let class = format!("{what}: wo.z {}, wi.z {}", cos("wo Vec3("), cos("wi Vec3("));
        *classes.entry(class).or_default() += 1;
    }
    for (class, n) in &classes {
        eprintln!("{n:5} × {class}");
    }
    let shown: Vec<_> = failures.iter().take(20).cloned().collect();
    assert!(
        failures.is_empty(),
        "{} non-finite or negative values, the first:\n{}",
        failures.len(),
        shown.join("\n")
    );
}
