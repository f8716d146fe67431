//! Blackbody emission for grid media with a temperature grid.
//!
//! L_e(T) is Planck's law normalised by its own peak (Wien's displacement law), as pbrt-v4's
//! `BlackbodySpectrum` does for grid media, converted to linear Rec.709 RGB through CIE 1931 XYZ. The colour
//! matching functions use the multi-lobe Gaussian fit of Wyman, Sloan, Shirley 2013, "Simple Analytic
//! Approximations to the CIE XYZ Color Matching Functions" (JCGT 2(2)), eq. 2–4.

use crate::math::Rgb;
use std::sync::LazyLock;

/// Planck's law: spectral radiance of a blackbody at wavelength `lambda_nm` and temperature `t` Kelvin.
fn planck(lambda_nm: f64, t: f64) -> f64 {
    let l = lambda_nm * 1e-9;
    planck_at(l, l.powi(5), t)
}

/// Planck's law at wavelength `l` metres, given `l⁵`, and temperature `t` Kelvin.
fn planck_at(l: f64, fifth_power: f64, t: f64) -> f64 {
    const C: f64 = 299_792_458.0;
    const H: f64 = 6.626_070_15e-34;
    const KB: f64 = 1.380_649e-23;
    2.0 * H * C * C / (fifth_power * ((H * C / (l * KB * t)).exp() - 1.0))
}

fn gaussian(x: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let s = if x < mu { s1 } else { s2 };
    (-0.5 * ((x - mu) / s).powi(2)).exp()
}

/// CIE 1931 2° colour matching functions at `l` nm (Wyman et al. 2013, eq. 2–4).
fn cie_xyz(l: f64) -> [f64; 3] {
    let x = 1.056 * gaussian(l, 599.8, 37.9, 31.0) + 0.362 * gaussian(l, 442.0, 16.0, 26.7)
        - 0.065 * gaussian(l, 501.1, 20.4, 26.2);
    let y = 0.821 * gaussian(l, 568.8, 46.9, 40.5) + 0.286 * gaussian(l, 530.9, 16.3, 31.1);
    let z = 1.217 * gaussian(l, 437.0, 11.8, 36.0) + 0.681 * gaussian(l, 459.0, 26.0, 13.8);
    [x, y, z]
}

/// The wavelengths of the blackbody integral: 360 to 830 nm every 1 nm.
const WAVELENGTHS: usize = 471;
/// The first wavelength of the integral, in nm.
const FIRST_WAVELENGTH: f64 = 360.0;

/// The CIE 1931 colour matching functions at the integral's wavelengths and the sum of their ȳ, computed once
/// per table in the order [`blackbody_rgb`] sums them, so that a table built from them is bit-identical to it.
struct CieSamples {
    /// (wavelength in m, its fifth power, x̄ ȳ z̄) at each wavelength.
    samples: Vec<(f64, f64, [f64; 3])>,
    /// Σ ȳ over the wavelengths, summed in wavelength order.
    y_integral: f64,
}

impl CieSamples {
    fn new() -> Self {
        let mut samples = Vec::with_capacity(WAVELENGTHS);
        let mut y_integral = 0.0;
        let mut l = FIRST_WAVELENGTH;
        for _ in 0..WAVELENGTHS {
            let xyz = cie_xyz(l);
            y_integral += xyz[1];
            let metres = l * 1e-9;
            samples.push((metres, metres.powi(5), xyz));
            l += 1.0;
        }
        Self {
            samples,
            y_integral,
        }
    }

    /// [`blackbody_rgb`] at `t` Kelvin from the stored samples: the same operations in the same order.
    fn blackbody_rgb(&self, t: f32) -> Rgb {
        if t.is_nan() || t <= 0.0 {
            return Rgb::ZERO;
        }
        let t = t as f64;
        // Wien's displacement law gives the peak used for normalisation.
        let peak = planck(WIEN_METRE_KELVIN / t * 1e9, t);
        let (mut x, mut y, mut z) = (0.0, 0.0, 0.0);
        for &(metres, fifth_power, [cx, cy, cz]) in &self.samples {
            let b = planck_at(metres, fifth_power, t) / peak;
            x += b * cx;
            y += b * cy;
            z += b * cz;
        }
        xyz_to_rgb(
            x / self.y_integral,
            y / self.y_integral,
            z / self.y_integral,
        )
    }
}

/// Wien's displacement constant in m·K: the peak of Planck's law lies at `WIEN_METRE_KELVIN / t` metres.
const WIEN_METRE_KELVIN: f64 = 2.897_771_955e-3;

/// XYZ to linear Rec.709 (sRGB primaries, D65 white), negative channels clamped to 0.
fn xyz_to_rgb(x: f64, y: f64, z: f64) -> Rgb {
    let r = 3.240_97 * x - 1.537_383 * y - 0.498_611 * z;
    let g = -0.969_244 * x + 1.875_968 * y + 0.041_555 * z;
    let b = 0.055_630 * x - 0.203_977 * y + 1.056_972 * z;
    Rgb::new(r as f32, g as f32, b as f32).max(Rgb::ZERO)
}

/// The normalised blackbody colour at `t` Kelvin in linear Rec.709 RGB; black at or below 0 K. The reference
/// [`BlackbodyTable`]'s nodes are checked against: Planck's law and the CIE fit evaluated at each wavelength.
#[cfg(test)]
pub fn blackbody_rgb(t: f32) -> Rgb {
    if t.is_nan() || t <= 0.0 {
        return Rgb::ZERO;
    }
    let t = t as f64;
    // Wien's displacement law gives the peak used for normalisation.
    let peak = planck(WIEN_METRE_KELVIN / t * 1e9, t);
    let (mut x, mut y, mut z, mut y_integral) = (0.0, 0.0, 0.0, 0.0);
    let mut l = 360.0;
    while l <= 830.0 {
        let b = planck(l, t) / peak;
        let [cx, cy, cz] = cie_xyz(l);
        x += b * cx;
        y += b * cy;
        z += b * cz;
        y_integral += cy;
        l += 1.0;
    }
    xyz_to_rgb(x / y_integral, y / y_integral, z / y_integral)
}

/// A table of the blackbody colour every `STEP` Kelvin, linearly interpolated, for lookups at collisions. Built
/// once per process ([`BlackbodyTable::shared`]): 4001 temperatures × 471 wavelengths.
#[derive(Clone, Debug)]
pub struct BlackbodyTable {
    values: Vec<Rgb>,
}

impl BlackbodyTable {
    const STEP: f32 = 10.0;
    const MAX_KELVIN: f32 = 40_000.0;

    /// Tabulates 0..40 000 K.
    fn new() -> Self {
        let n = (Self::MAX_KELVIN / Self::STEP) as usize + 1;
        let cie = CieSamples::new();
        Self {
            values: (0..n)
                .map(|i| cie.blackbody_rgb(i as f32 * Self::STEP))
                .collect(),
        }
    }

    /// The process's one table, built on first use.
    pub fn shared() -> &'static Self {
        static TABLE: LazyLock<BlackbodyTable> = LazyLock::new(BlackbodyTable::new);
        &TABLE
    }

    /// Interpolated colour at `t` Kelvin (clamped to the table's range; black below 0 or for NaN).
    pub fn lookup(&self, t: f32) -> Rgb {
        if t.is_nan() || t <= 0.0 {
            return Rgb::ZERO;
        }
        let x = (t.min(Self::MAX_KELVIN) / Self::STEP).min((self.values.len() - 1) as f32);
        let i = (x as usize).min(self.values.len() - 2);
        let f = x - i as f32;
        self.values[i].lerp(self.values[i + 1], f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blackbody_colours_run_from_red_to_blue() {
        let warm = blackbody_rgb(1500.0);
        let sun = blackbody_rgb(5800.0);
        let hot = blackbody_rgb(12000.0);
        assert!(
            warm.x > warm.y && warm.y > warm.z,
            "1500 K is red-orange: {warm:?}"
        );
        assert!(
            (sun.x / sun.z - 1.0).abs() < 0.35,
            "5800 K is near white: {sun:?}"
        );
        assert!(hot.z > hot.x, "12000 K is blue: {hot:?}");
        assert_eq!(blackbody_rgb(0.0), Rgb::ZERO);
        let table = BlackbodyTable::shared();
        assert!(table.lookup(1500.0).distance(warm) < 1e-3 * warm.length().max(1.0));
        assert_eq!(table.lookup(f32::NAN), Rgb::ZERO);
    }

    /// The table, built from CIE samples computed once, holds at every node exactly (bit for bit) what
    /// Planck's law and the CIE fit evaluated wavelength by wavelength give, and a lookup at a node returns it.
    #[test]
    fn the_table_equals_the_direct_evaluation_at_its_nodes() {
        let table = BlackbodyTable::shared();
        assert_eq!(table.values.len(), 4001);
        for (i, value) in table.values.iter().enumerate() {
            let kelvin = i as f32 * BlackbodyTable::STEP;
            let direct = blackbody_rgb(kelvin);
            assert_eq!(
                value.to_array().map(f32::to_bits),
                direct.to_array().map(f32::to_bits),
                "{kelvin} K"
            );
            if i + 1 < table.values.len() {
                assert_eq!(table.lookup(kelvin), direct, "lookup at {kelvin} K");
            }
        }
    }
}
