//! Convergence curves, their CSV, and the equal-time / efficiency summary.

use super::methods::Method;
use super::metrics::ErrorMetrics;
use std::fmt::Write;

/// The header of `convergence.csv`.
pub const CSV_HEADER: &str = "method,spp,seconds,rmse,relmse,bias";

/// Error of a method's image after some samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checkpoint {
    /// Samples per pixel rendered.
    pub spp: u32,
    /// Render seconds spent to get there (measurement time excluded).
    pub seconds: f64,
    /// Error against the reference.
    pub metrics: ErrorMetrics,
}

/// The checkpoints of one method, in rendering order.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve {
    /// The method.
    pub method: Method,
    /// Checkpoints, spp and seconds increasing.
    pub points: Vec<Checkpoint>,
}

/// `convergence.csv`: the header, then one row per checkpoint.
pub fn csv(curves: &[Curve]) -> String {
    let mut out = format!("{CSV_HEADER}\n");
    for c in curves {
        for p in &c.points {
            let m = &p.metrics;
            let _ = writeln!(
                out,
                "{},{},{:.6},{:.6e},{:.6e},{:.6e}",
                c.method, p.spp, p.seconds, m.rmse, m.relmse, m.bias
            );
        }
    }
    out
}

/// RMSE of `points` at time `t`: log-log interpolation between the checkpoints around `t`, or the nearest
/// checkpoint extrapolated as 1/√t outside them. `None` without checkpoints.
pub fn rmse_at(points: &[Checkpoint], t: f64) -> Option<f64> {
    let first = points.first()?;
    let last = points.last()?;
    let scaled = |p: &Checkpoint| p.metrics.rmse * (p.seconds / t).sqrt();
    if t <= first.seconds {
        return Some(scaled(first));
    }
    if t >= last.seconds {
        return Some(scaled(last));
    }
    let i = points.iter().position(|p| p.seconds >= t)?;
    let (a, b) = (&points[i - 1], &points[i]);
    let ln = |x: f64| x.max(1e-300).ln();
    let f = (ln(t) - ln(a.seconds)) / (ln(b.seconds) - ln(a.seconds)).max(1e-300);
    Some((ln(a.metrics.rmse) + f * (ln(b.metrics.rmse) - ln(a.metrics.rmse))).exp())
}

/// Monte Carlo efficiency 1 / (MSE · t).
pub fn efficiency(mse: f64, seconds: f64) -> f64 {
    1.0 / (mse * seconds).max(f64::MIN_POSITIVE)
}

/// What the summary says about one method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MethodSummary {
    /// The method.
    pub method: Method,
    /// Samples per pixel at its last checkpoint.
    pub final_spp: u32,
    /// Render seconds at its last checkpoint.
    pub final_seconds: f64,
    /// RMSE at its last checkpoint.
    pub final_rmse: f64,
    /// RMSE interpolated at the common time.
    pub equal_time_rmse: f64,
    /// Efficiency 1/(MSE·t) at its last checkpoint.
    pub efficiency: f64,
    /// Efficiency divided by the `default` method's (`None` when `default` was not rendered).
    pub relative_efficiency: Option<f64>,
    /// The RMSE of the last two checkpoints fell by less than 10 % while the samples doubled.
    pub possible_bias: bool,
}

/// The summary: the common time (the smallest final time over methods) and one row per method with
/// checkpoints.
pub fn summarize(curves: &[Curve]) -> (f64, Vec<MethodSummary>) {
    let common = curves
        .iter()
        .filter_map(|c| c.points.last())
        .map(|p| p.seconds)
        .fold(f64::INFINITY, f64::min);
    let mut rows: Vec<MethodSummary> = curves
        .iter()
        .filter_map(|c| {
            let last = c.points.last()?;
            let possible_bias = match c.points.as_slice() {
                [.., a, b] => b.spp >= 2 * a.spp && b.metrics.rmse > 0.9 * a.metrics.rmse,
                _ => false,
            };
            Some(MethodSummary {
                method: c.method,
                final_spp: last.spp,
                final_seconds: last.seconds,
                final_rmse: last.metrics.rmse,
                equal_time_rmse: rmse_at(&c.points, common)?,
                efficiency: efficiency(last.metrics.mse(), last.seconds),
                relative_efficiency: None,
                possible_bias,
            })
        })
        .collect();
    let base = rows
        .iter()
        .find(|r| r.method == Method::Default)
        .map(|r| r.efficiency);
    for r in &mut rows {
        r.relative_efficiency = base.map(|b| r.efficiency / b);
    }
    (common, rows)
}

/// `summary.md`: the equal-time table and the notes, for `scene` rendered at `width`×`height`.
/// `noise_floor` is the reference's RMS standard error, when known (it was subtracted from every MSE).
pub fn summary_markdown(
    scene: &str,
    width: usize,
    height: usize,
    curves: &[Curve],
    noise_floor: Option<f64>,
) -> String {
    let (common, rows) = summarize(curves);
    let mut out = format!(
        "# Convergence: {scene}\n\n{width}×{height} pixels. Equal-time RMSE is interpolated (log-log) at \
         {common:.3} s, the shortest final time over the methods. Efficiency is 1/(MSE·t) at each method's \
         last checkpoint, relative to `default`.\n\n\
         | method | final spp | final s | final RMSE | RMSE at {common:.2} s | efficiency vs default | note |\n\
         |---|---:|---:|---:|---:|---:|---|\n"
    );
    for r in &rows {
        let _ = writeln!(
            out,
            "| {} | {} | {:.2} | {:.4e} | {:.4e} | {} | {} |",
            r.method,
            r.final_spp,
            r.final_seconds,
            r.final_rmse,
            r.equal_time_rmse,
            r.relative_efficiency
                .map_or("n/a".to_string(), |e| format!("{e:.2}×")),
            if r.possible_bias { "possible bias" } else { "" }
        );
    }
    out.push_str(
        "\n\"possible bias\": the RMSE of the last two checkpoints fell by less than 10 % while the samples \
         doubled (the error stopped decreasing; a noisy reference also floors the RMSE).\n",
    );
    match noise_floor {
        Some(f) => {
            let _ = writeln!(
                out,
                "\nThe reference's own noise (RMS standard error {f:.4e}) is subtracted from every squared error, \
                 so the RMSE estimates the error against the noise-free image."
            );
        }
        None => out.push_str(
            "\nThe reference's noise is not known, so it is included in every RMSE (which cannot fall below it).\n",
        ),
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(spp: u32, seconds: f64, rmse: f64) -> Checkpoint {
        Checkpoint {
            spp,
            seconds,
            metrics: ErrorMetrics {
                rmse,
                relmse: 0.0,
                bias: 0.0,
            },
        }
    }

    #[test]
    fn csv_header_and_rows() {
        let curves = [Curve {
            method: Method::NoMediaMis,
            points: vec![point(1, 0.5, 0.25)],
        }];
        let text = csv(&curves);
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("method,spp,seconds,rmse,relmse,bias"));
        let row: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(row.len(), 6);
        assert_eq!((row[0], row[1]), ("no-media-mis", "1"));
        assert_eq!(row[3].parse::<f64>().unwrap(), 0.25);
        assert_eq!(lines.next(), None);
    }

    #[test]
    fn efficiency_relative_to_default() {
        assert!((efficiency(0.01, 2.0) - 50.0).abs() < 1e-9);
        // default: MSE 0.01 at 4 s → 25; the other: MSE 0.0025 at 8 s → 50, twice as efficient.
        let curves = [
            Curve {
                method: Method::Default,
                points: vec![
                    point(1, 1.0, 0.2),
                    point(2, 2.0, 0.2 / 2f64.sqrt()),
                    point(4, 4.0, 0.1),
                ],
            },
            Curve {
                method: Method::GlobalMajorant,
                points: vec![point(1, 2.0, 0.1), point(2, 4.0, 0.08), point(4, 8.0, 0.05)],
            },
        ];
        let (common, rows) = summarize(&curves);
        assert_eq!(common, 4.0);
        assert!((rows[0].efficiency - 25.0).abs() < 1e-9);
        assert!((rows[1].efficiency - 50.0).abs() < 1e-9);
        assert!((rows[0].relative_efficiency.unwrap() - 1.0).abs() < 1e-12);
        assert!((rows[1].relative_efficiency.unwrap() - 2.0).abs() < 1e-9);
        // Equal time: default's last checkpoint; the other's checkpoint at 4 s.
        assert!((rows[0].equal_time_rmse - 0.1).abs() < 1e-12);
        assert!((rows[1].equal_time_rmse - 0.08).abs() < 1e-12);
        assert!(!rows[0].possible_bias && !rows[1].possible_bias);
        let md = summary_markdown("s.gltf", 16, 16, &curves, Some(1e-3));
        assert!(
            md.contains("| global-majorant | 4 | 8.00 |") && md.contains("2.00×"),
            "{md}"
        );
        assert!(md.contains("RMS standard error 1.0000e-3"), "{md}");
        assert!(summary_markdown("s.gltf", 16, 16, &curves, None).contains("is not known"));
    }

    #[test]
    fn interpolation_and_bias_flag() {
        let points = [point(1, 1.0, 0.4), point(2, 4.0, 0.1)];
        // Halfway in log time (2 s) is halfway in log RMSE (0.2).
        assert!((rmse_at(&points, 2.0).unwrap() - 0.2).abs() < 1e-12);
        // Before the first checkpoint: 1/√t from it.
        assert!((rmse_at(&points, 0.25).unwrap() - 0.8).abs() < 1e-12);
        assert_eq!(rmse_at(&[], 1.0), None);
        let stalled = [Curve {
            method: Method::Default,
            points: vec![point(4, 1.0, 0.1), point(8, 2.0, 0.095)],
        }];
        assert!(summarize(&stalled).1[0].possible_bias);
    }
}
