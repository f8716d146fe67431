//! Floating-point error bounds for conservative geometry (Pharr, Jakob, Humphreys, "Physically Based Rendering",
//! 4th ed., §6.8 "Managing Rounding Error").

/// `γ(n) = n·ε / (1 − n·ε)` with the unit roundoff `ε = 2⁻²⁴`: the bound on the relative error accumulated by `n`
/// rounded `f32` operations (PBRT 4th ed., eq. 6.26).
pub const fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    n * e / (1.0 - n * e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_bounds_the_error_of_a_sum() {
        // Summing 1000 values of 0.1 in f32 accumulates at most γ(999) relative error against the exact sum.
        let mut s = 0.0f32;
        for _ in 0..1000 {
            s += 0.1;
        }
        let exact = 1000.0 * 0.1f32 as f64;
        assert!(((s as f64) - exact).abs() <= gamma(999.0) as f64 * exact);
        assert!(gamma(1.0) > f32::EPSILON * 0.5 && gamma(3.0) < 2.0 * f32::EPSILON);
    }
}
