//! Blackbody emission for grid media with a temperature grid.
//!
//! L_e(T) is Planck's law normalised by its own peak (Wien's displacement law), as pbrt-v4's
//! `BlackbodySpectrum` does for grid media, converted to linear Rec.709 RGB through CIE 1931 XYZ. The colour
//! matching functions use the multi-lobe Gaussian fit of Wyman, Sloan, Shirley 2013, "Simple Analytic
//! Approximations to the CIE XYZ Color Matching Functions" (JCGT 2(2)), eq. 2–4.

use crate::math::Rgb;

/// Planck's law: spectral radiance of a blackbody at wavelength `lambda_nm` and temperature `t` Kelvin.
fn planck(lambda_nm: f64, t: f64) -> f64 {
    const C: f64 = 299_792_458.0;
    const H: f64 = 6.626_070_15e-34;
    const KB: f64 = 1.380_649e-23;
    let l = lambda_nm * 1e-9;
    2.0 * H * C * C / (l.powi(5) * ((H * C / (l * KB * t)).exp() - 1.0))
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

/// The normalised blackbody colour at `t` Kelvin in linear Rec.709 RGB; black at or below 0 K.
pub fn blackbody_rgb(t: f32) -> Rgb {
    if t.is_nan() || t <= 0.0 {
        return Rgb::ZERO;
    }
    let t = t as f64;
    // Wien's displacement law gives the peak used for normalisation.
    let peak = planck(2.897_771_955e-3 / t * 1e9, t);
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
    let (x, y, z) = (x / y_integral, y / y_integral, z / y_integral);
    // XYZ to linear Rec.709 (sRGB primaries, D65 white).
    let r = 3.240_97 * x - 1.537_383 * y - 0.498_611 * z;
    let g = -0.969_244 * x + 1.875_968 * y + 0.041_555 * z;
    let b = 0.055_630 * x - 0.203_977 * y + 1.056_972 * z;
    Rgb::new(r as f32, g as f32, b as f32).max(Rgb::ZERO)
}

/// A table of [`blackbody_rgb`] every `STEP` Kelvin, linearly interpolated, for lookups at collisions.
#[derive(Clone, Debug)]
pub struct BlackbodyTable {
    values: Vec<Rgb>,
}

impl BlackbodyTable {
    const STEP: f32 = 10.0;
    const MAX_KELVIN: f32 = 40_000.0;

    /// Tabulates 0..40 000 K.
    pub fn new() -> Self {
        let n = (Self::MAX_KELVIN / Self::STEP) as usize + 1;
        Self {
            values: (0..n)
                .map(|i| blackbody_rgb(i as f32 * Self::STEP))
                .collect(),
        }
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

impl Default for BlackbodyTable {
    fn default() -> Self {
        Self::new()
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
        let table = BlackbodyTable::new();
        assert!(table.lookup(1500.0).distance(warm) < 1e-3 * warm.length().max(1.0));
        assert_eq!(table.lookup(f32::NAN), Rgb::ZERO);
    }
}
