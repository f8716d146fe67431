//! The directional albedo `E(μo, α, η) = ∫ (f_r + η² f_t) |cos θi| dωi` of the single-scattering rough
//! dielectric ([`super::dielectric::Dielectric`], Walter et al. 2007, GGX with height-correlated Smith
//! masking-shadowing, exact Fresnel, no thin film), tabulated for the multiple-scattering compensation of
//! Turquin 2019, "Practical multiple scattering compensation for microfacet models" (the BSDF scaled so that
//! a lossless interface conserves energy; the scalings are [`reflection_scale`] and [`refraction_scale`]).
//!
//! `η` is the relative index η(far side)/η(wo's side), and refraction's radiance factor 1/η² is undone in
//! `E`, so a lossless interface would have `E = 1` with every microfacet interaction counted. Three tables:
//! `ALBEDO_DENSER` (`E · 65535`) and `TRANSMISSION_DENSER` (the refraction's factor `t · 4096`) for η ≥ 1
//! (light arriving from the optically thinner side), indexed by η, and `ALBEDO_RARER` for η < 1, indexed by
//! 1/η; each over [`COS_NODES`] cosines `(i + ½)/COS_NODES`, [`ROUGHNESS_NODES`] roughnesses
//! `√α = j/(N − 1)` and [`ETA_NODES`] indices `1 + (MAX_ETA − 1) k/(N − 1)`, rounded to `u16` (table.rs,
//! written by the ignored test `generate_tables` from a lattice quadrature over visible normals). Lookups
//! interpolate trilinearly and clamp to the grid: indices above [`MAX_ETA`] use its entries.

mod table;

/// Number of tabulated cosines of the outgoing direction, at `(i + ½)/COS_NODES`.
const COS_NODES: usize = 32;
/// Number of tabulated roughnesses `√α`, evenly spaced over [0, 1].
const ROUGHNESS_NODES: usize = 32;
/// Number of tabulated relative indices (or their inverses), evenly spaced over [1, `MAX_ETA`].
const ETA_NODES: usize = 16;
/// The largest tabulated relative index (or inverse index).
const MAX_ETA: f32 = 3.0;
/// Entries per table.
const TABLE_LEN: usize = COS_NODES * ROUGHNESS_NODES * ETA_NODES;

/// Flat index of the node (cosine `i`, roughness `j`, index `k`).
fn flat_index(i: usize, j: usize, k: usize) -> usize {
    (k * ROUGHNESS_NODES + j) * COS_NODES + i
}

/// The lower node and the fraction toward the next one of a continuous grid coordinate, clamped to the grid.
fn grid_cell(x: f32, nodes: usize) -> (usize, f32) {
    let x = x.clamp(0.0, (nodes - 1) as f32);
    let lower = (x.floor() as usize).min(nodes - 2);
    (lower, x - lower as f32)
}

/// A table's stored value at (cos θo, α, η or 1/η as `index`), interpolated trilinearly in
/// (cos θo, √α, index) and clamped to the grid.
fn interpolate(table: &[u16], cos_o: f32, alpha: f32, index: f32) -> f32 {
    let (i, ti) = grid_cell(cos_o * COS_NODES as f32 - 0.5, COS_NODES);
    let (j, tj) = grid_cell(
        alpha.max(0.0).sqrt() * (ROUGHNESS_NODES - 1) as f32,
        ROUGHNESS_NODES,
    );
    let scaled_index = (index - 1.0) / (MAX_ETA - 1.0) * (ETA_NODES - 1) as f32;
    let (k, tk) = grid_cell(scaled_index, ETA_NODES);
    let mut value = 0.0;
    for (dk, wk) in [(0, 1.0 - tk), (1, tk)] {
        for (dj, wj) in [(0, 1.0 - tj), (1, tj)] {
            for (di, wi) in [(0, 1.0 - ti), (1, ti)] {
                let stored = table
                    .get(flat_index(i + di, j + dj, k + dk))
                    .copied()
                    .unwrap_or(0);
                value += wi * wj * wk * f32::from(stored);
            }
        }
    }
    value
}

/// Stored units per unit of directional albedo.
const ALBEDO_UNITS: f32 = 65535.0;
/// Stored units per unit of transmission scale (scales up to 16).
const TRANSMISSION_UNITS: f32 = 4096.0;

/// The single-scattering directional albedo `E` for an outgoing direction of cosine `cos_o` (> 0, mirrored
/// above the surface), GGX `alpha` and relative index `eta`. Between 0 and 1; never below `1/65535`.
pub(super) fn single_scattering_albedo(cos_o: f32, alpha: f32, eta: f32) -> f32 {
    let (table, index) = if eta >= 1.0 {
        (&table::ALBEDO_DENSER, eta)
    } else {
        (&table::ALBEDO_RARER, 1.0 / eta)
    };
    (interpolate(table, cos_o, alpha, index) / ALBEDO_UNITS).max(1.0 / ALBEDO_UNITS)
}

/// The compensation factor on the single-scattering reflection between directions of cosines `cos_o` and
/// `cos_i` (both mirrored above): `1/√(E(μo) E(μi))`, symmetric, from the thinner side (η ≥ 1);
/// `1/E(μo)` from the denser side.
pub(super) fn reflection_scale(cos_o: f32, cos_i: f32, alpha: f32, eta: f32) -> f32 {
    let e_o = single_scattering_albedo(cos_o, alpha, eta);
    if eta >= 1.0 {
        1.0 / (e_o * single_scattering_albedo(cos_i, alpha, eta)).sqrt()
    } else {
        1.0 / e_o
    }
}

/// The compensation factor on the single-scattering refraction for an outgoing direction of cosine `cos_o`:
/// from the thinner side (η ≥ 1) the tabulated `t(μo) = (1 − E_rg(μo)) / E_t(μo)` that closes the energy
/// balance once the reflection is scaled by [`reflection_scale`] (`E_rg` that scaled reflection's albedo,
/// `E_t` the refraction's); `1/E(μo)` from the denser side.
pub(super) fn refraction_scale(cos_o: f32, alpha: f32, eta: f32) -> f32 {
    if eta >= 1.0 {
        interpolate(&table::TRANSMISSION_DENSER, cos_o, alpha, eta) / TRANSMISSION_UNITS
    } else {
        1.0 / single_scattering_albedo(cos_o, alpha, eta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::dielectric::Dielectric;
    use crate::material::fresnel;
    use crate::material::microfacet::Ggx;
    use crate::math::{Rgb, Rng, Vec2, Vec3};
    use std::fmt::Write;

    /// One visible-normal sample's weight under the lattice rule, for the lobe it falls in.
    enum LatticeWeight {
        /// A reflection leaving on the outgoing side: `F(wo·h) G2/G1(wo)`, and the cosine of its direction.
        Reflected(f32, f32),
        /// A refraction leaving on the other side: `(1 − F) G2/G1(wo)`.
        Refracted(f32),
    }

    /// Walks the lattice rule over the visible-normal sampler's square ([`lattice_point`]; Heitz 2018) for one
    /// node, handing `visit` each visible normal's reflection and refraction weights in order (the sample
    /// weights of `f_r` and of `η² f_t` under visible-normal sampling, Walter et al. 2007 eqs. 14, 17, 20,
    /// 21), none where the direction leaves on the wrong side.
    fn walk_lattice(cos_o: f32, alpha: f32, eta: f32, mut visit: impl FnMut(LatticeWeight)) {
        let wo = Vec3::new((1.0 - cos_o * cos_o).max(0.0).sqrt(), 0.0, cos_o);
        let ggx = Ggx::isotropic(alpha);
        let g1 = ggx.g1(wo);
        for n in 0..LATTICE_POINTS {
            let h = ggx.sample_visible(wo, lattice_point(n));
            let oh = wo.dot(h);
            if oh <= 0.0 {
                continue;
            }
            let f = fresnel::dielectric(oh, eta);
            let reflected = fresnel::reflect(wo, h);
            if reflected.z > 0.0 {
                visit(LatticeWeight::Reflected(
                    f * ggx.g2(wo, reflected) / g1,
                    reflected.z,
                ));
            }
            if let Some(t) = fresnel::refract(wo, h, eta).filter(|t| t.z < 0.0) {
                visit(LatticeWeight::Refracted((1.0 - f) * ggx.g2(wo, t) / g1));
            }
        }
    }

    /// `E` at one node by the lattice rule: the mean of every reflection and refraction weight.
    fn quadrature_albedo(cos_o: f32, alpha: f32, eta: f32) -> f64 {
        let mut sum = 0.0f64;
        walk_lattice(cos_o, alpha, eta, |weight| match weight {
            LatticeWeight::Reflected(w, _) | LatticeWeight::Refracted(w) => sum += f64::from(w),
        });
        sum / LATTICE_POINTS as f64
    }

    /// The node values of the cosine, roughness (√α) and index axes.
    fn nodes(i: usize, j: usize, k: usize) -> (f32, f32, f32) {
        let cos_o = (i as f32 + 0.5) / COS_NODES as f32;
        let roughness = j as f32 / (ROUGHNESS_NODES - 1) as f32;
        let eta = 1.0 + (MAX_ETA - 1.0) * k as f32 / (ETA_NODES - 1) as f32;
        (cos_o, roughness, eta)
    }

    /// `t(μo)` at one node by the same lattice rule: the reflection weights divided by `√(E(μo) E(μi))`
    /// (`albedo` interpolates the albedo table just computed) give `E_rg`, the refraction weights `E_t`;
    /// `t = (1 − E_rg)/E_t`, 1 where nothing refracts.
    fn quadrature_transmission_scale(
        cos_o: f32,
        alpha: f32,
        eta: f32,
        albedo: impl Fn(f32) -> f32,
    ) -> f64 {
        let e_o = albedo(cos_o);
        let (mut reflected_sum, mut refracted_sum) = (0.0f64, 0.0f64);
        walk_lattice(cos_o, alpha, eta, |weight| match weight {
            LatticeWeight::Reflected(w, cos_i) => {
                reflected_sum += f64::from(w * (1.0 / (e_o * albedo(cos_i)).sqrt()));
            }
            LatticeWeight::Refracted(w) => refracted_sum += f64::from(w),
        });
        let cells = LATTICE_POINTS as f64;
        if refracted_sum <= 0.0 {
            return 1.0;
        }
        ((1.0 - reflected_sum / cells) / (refracted_sum / cells)).max(0.0)
    }

    /// Both tables of one side, for η (`inverse` false) or 1/η (`inverse` true): `E · 65535` and
    /// `t · 4096` (used from the thinner side only). The smooth column (`√α = 0`) is exactly 1 in both.
    fn compute_tables(inverse: bool) -> (Vec<u16>, Vec<u16>) {
        let mut albedo = vec![0u16; TABLE_LEN];
        let mut transmission = vec![0u16; TABLE_LEN];
        let quantize =
            |v: f64, units: f32| (v * f64::from(units)).round().clamp(0.0, 65535.0) as u16;
        for pass in 0..if inverse { 1 } else { 2 } {
            for k in 0..ETA_NODES {
                for j in 0..ROUGHNESS_NODES {
                    for i in 0..COS_NODES {
                        let (cos_o, roughness, eta) = nodes(i, j, k);
                        let eta = if inverse { 1.0 / eta } else { eta };
                        let alpha = roughness * roughness;
                        let index = flat_index(i, j, k);
                        if pass == 0 {
                            let e = if j == 0 {
                                1.0
                            } else {
                                quadrature_albedo(cos_o, alpha, eta)
                            };
                            albedo[index] = quantize(e.min(1.0), ALBEDO_UNITS);
                        } else {
                            let node_index = if inverse { 1.0 / eta } else { eta };
                            let lookup = |c: f32| {
                                (interpolate(&albedo, c, alpha, node_index) / ALBEDO_UNITS)
                                    .max(1.0 / ALBEDO_UNITS)
                            };
                            let t = if j == 0 {
                                1.0
                            } else {
                                quadrature_transmission_scale(cos_o, alpha, eta, lookup)
                            };
                            transmission[index] = quantize(t, TRANSMISSION_UNITS);
                        }
                    }
                }
            }
        }
        (albedo, transmission)
    }

    /// Points of the Fibonacci lattice the quadratures use (the Fibonacci number F₂₂).
    const LATTICE_POINTS: usize = 17711;
    /// The lattice's generator (F₂₁).
    const LATTICE_GENERATOR: usize = 10946;

    /// Point `n` of the Fibonacci lattice `((n + ½)/N, {n g / N})` over the unit square: a rank-1 lattice
    /// rule (Sloan & Joe 1994) whose rows are all distinct, so that no ring of visible normals (the total
    /// internal reflection cone, nearly a row `u.x = const` of the sampler's square) aliases with it as a
    /// midpoint grid's rows did (0.3% off at α 0.1 from inside).
    fn lattice_point(n: usize) -> Vec2 {
        let v = ((n * LATTICE_GENERATOR) % LATTICE_POINTS) as f32 + 0.5;
        Vec2::new(
            (n as f32 + 0.5) / LATTICE_POINTS as f32,
            v / LATTICE_POINTS as f32,
        )
    }

    /// Writes the table source; run by hand after changing the model or the grid:
    /// `cargo test --lib material::dielectric_albedo::tests::generate_tables -- --ignored`.
    #[test]
    #[ignore]
    fn generate_tables() {
        let mut text = String::from(
            "//! Generated by `cargo test --lib material::dielectric_albedo::tests::generate_tables -- \
             --ignored`;\n//! do not edit. The single-scattering rough dielectric's directional albedo × 65535 \
             and the\n//! refraction's compensation factor × 4096 (see the parent module).\n",
        );
        for (suffix, inverse) in [("DENSER", false), ("RARER", true)] {
            let (albedo, transmission) = compute_tables(inverse);
            let side = if inverse {
                "η < 1, indexed by 1/η"
            } else {
                "η ≥ 1"
            };
            for (what, values) in [("ALBEDO", albedo), ("TRANSMISSION", transmission)] {
                if inverse && what == "TRANSMISSION" {
                    continue;
                }
                let meaning = if what == "ALBEDO" {
                    "`E · 65535`"
                } else {
                    "`t · 4096`"
                };
                writeln!(text, "\n/// {meaning} for {side}.\n#[rustfmt::skip]").unwrap();
                writeln!(
                    text,
                    "pub(super) static {what}_{suffix}: [u16; super::TABLE_LEN] = ["
                )
                .unwrap();
                for row in values.chunks(16) {
                    let row: Vec<String> = row.iter().map(|v| v.to_string()).collect();
                    writeln!(text, "    {},", row.join(", ")).unwrap();
                }
                writeln!(text, "];").unwrap();
            }
        }
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/src/material/dielectric_albedo/table.rs"
        );
        std::fs::write(path, text).unwrap();
    }

    /// Monte Carlo estimate of `E` by the BSDF's own sampler and its single-scattering value (an independent
    /// route: random visible normals, the lobe picked by Fresnel, `eval`/`pdf` ratios), with its standard error.
    fn monte_carlo_albedo(cos_o: f32, alpha: f32, eta: f32, n: usize, seed: u64) -> (f64, f64) {
        let (ior, sign) = if eta >= 1.0 {
            (eta, 1.0)
        } else {
            (1.0 / eta, -1.0)
        };
        let glass = Dielectric {
            ior,
            alpha,
            tint: Rgb::ONE,
            film: None,
        };
        let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o) * sign;
        let mut rng = Rng::new(seed, seed);
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let Some(smp) = glass.sample(wo, rng.next_f32(), rng.next_2d()) else {
                continue;
            };
            let pdf = glass.pdf(wo, smp.wi);
            if pdf <= 0.0 {
                continue;
            }
            let scale = if smp.wi.z * wo.z < 0.0 {
                eta * eta
            } else {
                1.0
            };
            let f = glass.eval_single_scattering(wo, smp.wi).x;
            let w = f64::from(f * smp.wi.z.abs() / pdf * scale);
            s += w;
            s2 += w * w;
        }
        let mean = s / n as f64;
        (
            mean,
            ((s2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt(),
        )
    }

    #[test]
    fn table_entries_match_monte_carlo() {
        // (cosine node, roughness node, index node) from both sides; the index node 0 (η = 1) is skipped,
        // where the BSDF is smooth.
        let picks = [
            (0, 31, 5),
            (31, 31, 15),
            (10, 20, 3),
            (20, 10, 7),
            (5, 5, 10),
            (16, 25, 1),
        ];
        for (n, &(i, j, k)) in picks.iter().enumerate() {
            let (cos_o, roughness, eta) = nodes(i, j, k);
            for (name, table, eta) in [
                ("DENSER", &table::ALBEDO_DENSER, eta),
                ("RARER", &table::ALBEDO_RARER, 1.0 / eta),
            ] {
                let stored = f64::from(table[flat_index(i, j, k)]) / 65535.0;
                let (mean, se) =
                    monte_carlo_albedo(cos_o, roughness * roughness, eta, 100_000, n as u64);
                assert!(
                    (stored - mean).abs() <= 4.0 * se + 1.0 / 65535.0,
                    "{name} cos {cos_o} √α {roughness} η {eta}: table {stored}, Monte Carlo {mean} ± {se}"
                );
            }
        }
    }

    #[test]
    fn lookups_at_nodes_return_the_stored_values_and_clamp_outside() {
        let (cos_o, roughness, eta) = nodes(7, 12, 4);
        let stored = f32::from(table::ALBEDO_DENSER[flat_index(7, 12, 4)]) / 65535.0;
        let looked_up = single_scattering_albedo(cos_o, roughness * roughness, eta);
        assert!((looked_up - stored).abs() < 1e-4, "{looked_up} vs {stored}");
        let inside = f32::from(table::ALBEDO_RARER[flat_index(7, 12, 4)]) / 65535.0;
        let looked_up = single_scattering_albedo(cos_o, roughness * roughness, 1.0 / eta);
        assert!((looked_up - inside).abs() < 1e-4, "{looked_up} vs {inside}");
        assert_eq!(single_scattering_albedo(0.5, 0.0, 1.5), 1.0);
        let beyond = single_scattering_albedo(0.5, 1.0, 10.0);
        assert_eq!(beyond, single_scattering_albedo(0.5, 1.0, MAX_ETA));
    }
}
