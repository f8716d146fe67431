//! The PNG preview's exposure: a fixed number of stops, or an automatic one metered from the image as a camera's
//! average meter does. Only the preview is exposed; the EXR keeps the linear radiance.
//!
//! The meter (Reinhard, Stark, Shirley, Ferwerda 2002, "Photographic Tone Reproduction for Digital Images",
//! eq. 1 and 2): the scene's key is the log-average luminance L̄ = exp(Σ wᵢ·log(δ + Lᵢ) / Σ wᵢ), and the exposure
//! that maps it to middle grey a = 0.18 is EV = log₂(a / L̄). The weights wᵢ are the pixels' coverage (alpha), so
//! a small object in front of an empty background is exposed for the object, not for the void around it; an
//! image with no coverage at all (an environment seen alone) weighs every pixel alike. Pixels that are exactly
//! black (geometry that no light reaches, in a scene lit only by its own emitters) are left out as well: with
//! the δ of eq. 1 each would count as log δ, 26 stops below white, and a third of the frame unlit would
//! expose the lit rest 8 stops too bright (the Khronos EmissiveStrengthTest's backdrop).
//!
//! The automatic exposure leaves a normally exposed image alone: it is the exposure nearest to 0 that puts the
//! key within [`KEY_RANGE`]: from one stop below middle grey, for a low-key scene, up to white, for a high-key
//! one such as a bright sky, snow, or an object under the default white environment. A render 683× too dark (a file's lux read as W/m²) is lifted
//! until its key is one stop below middle grey; a daylight scene already in range stays at 0 stops.

use crate::math::luminance;
use crate::render::RenderImage;

/// Middle grey: the luminance the metered key is mapped to (Reinhard et al. 2002, §2: the "normal-key" value).
pub const MIDDLE_GREY: f32 = 0.18;

/// The most stops the automatic exposure moves the preview either way: enough for a scene lit in lux read as
/// W/m² (683×, 9.4 stops) and for an image with a sun in it, not enough to lift pure float noise into view.
pub const MAX_AUTO_STOPS: f32 = 16.0;

/// The keys the automatic exposure accepts as they are: from one stop below [`MIDDLE_GREY`] to white.
pub const KEY_RANGE: (f32, f32) = (MIDDLE_GREY * 0.5, 1.0);

/// Below this luminance a pixel is "black" for [`Metering::almost_black`]: sRGB code 25 of 255, a tenth of the
/// way to white on the preview.
pub const BLACK_LUMINANCE: f32 = 0.01;

/// An image is almost black when fewer than this share of its pixels reaches [`BLACK_LUMINANCE`].
pub const BLACK_SHARE: f64 = 0.001;

/// `δ` of the log-average: keeps log(δ + L) finite for the smallest positive luminances, far below any visible
/// one (exactly black pixels are not metered).
const LOG_DELTA: f64 = 1e-8;

/// How the PNG preview is exposed (`--exposure auto` or `--exposure STOPS`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exposure {
    /// Metered from the image ([`meter`]).
    Auto,
    /// A fixed exposure in stops: linear values are scaled by 2^stops.
    Stops(f32),
}

impl Exposure {
    /// Parses `auto` or a finite number of stops.
    pub fn parse(text: &str) -> Option<Self> {
        if text.eq_ignore_ascii_case("auto") {
            return Some(Self::Auto);
        }
        text.parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Self::Stops)
    }
}

/// What the meter read from an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metering {
    /// The coverage-weighted log-average luminance (the scene's key, L̄) of the pixels that are not black.
    pub key: f32,
    /// The exposure in stops that maps the key to `MIDDLE_GREY`, clamped to ±`MAX_AUTO_STOPS`; 0 for an
    /// image without one finite non-zero pixel.
    pub key_stops: f32,
    /// `--exposure auto`: the exposure nearest to 0 that brings the key into `KEY_RANGE`.
    pub auto_stops: f32,
    /// Whether fewer than [`BLACK_SHARE`] of the pixels reach [`BLACK_LUMINANCE`] before exposure: the
    /// preview at 0 stops would look black.
    pub almost_black: bool,
}

/// Meters the beauty of `image` (non-finite pixels are skipped; see the module doc for the rule).
pub fn meter(image: &RenderImage) -> Metering {
    let pixels = image.beauty.len();
    let coverage = |i: usize| image.alpha.get(i).copied().unwrap_or(1.0);
    let covered = (0..pixels).any(|i| coverage(i) > 0.0);
    let (mut weight_sum, mut log_sum, mut bright, mut lit) = (0f64, 0f64, 0usize, false);
    for (i, &c) in image.beauty.iter().enumerate() {
        let l = luminance(c);
        if !l.is_finite() {
            continue;
        }
        let l = l.max(0.0);
        if l >= BLACK_LUMINANCE {
            bright += 1;
        }
        if l == 0.0 {
            // Unlit: no sample found light here, so the pixel says nothing about the exposure.
            continue;
        }
        lit = true;
        let w = if covered {
            f64::from(coverage(i).clamp(0.0, 1.0))
        } else {
            1.0
        };
        weight_sum += w;
        log_sum += w * (LOG_DELTA + f64::from(l)).ln();
    }
    let key = if weight_sum > 0.0 {
        (log_sum / weight_sum).exp() as f32
    } else {
        0.0
    };
    let key_stops = if lit && key > 0.0 {
        (MIDDLE_GREY / key)
            .log2()
            .clamp(-MAX_AUTO_STOPS, MAX_AUTO_STOPS)
    } else {
        0.0
    };
    // Exposure e maps the key to key · 2^e: into the range for e from log₂(low / key) to log₂(high / key).
    let auto_stops = if lit && key > 0.0 {
        let stops_to = |target: f32| (target / key).log2().clamp(-MAX_AUTO_STOPS, MAX_AUTO_STOPS);
        0f32.clamp(stops_to(KEY_RANGE.0), stops_to(KEY_RANGE.1))
    } else {
        0.0
    };
    Metering {
        key,
        key_stops,
        auto_stops,
        almost_black: (bright as f64) < BLACK_SHARE * pixels as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rgb;

    fn image(values: &[(f32, f32)]) -> RenderImage {
        let mut img = RenderImage::new(values.len(), 1);
        for (i, &(l, a)) in values.iter().enumerate() {
            img.beauty[i] = Rgb::splat(l);
            img.alpha[i] = a;
        }
        img
    }

    #[test]
    fn parses_auto_and_finite_stops_only() {
        assert_eq!(Exposure::parse("auto"), Some(Exposure::Auto));
        assert_eq!(Exposure::parse("AUTO"), Some(Exposure::Auto));
        assert_eq!(Exposure::parse("-9"), Some(Exposure::Stops(-9.0)));
        assert_eq!(Exposure::parse("2.5"), Some(Exposure::Stops(2.5)));
        for bad in ["nan", "inf", "-inf", "", "automatic", "1e40"] {
            assert_eq!(Exposure::parse(bad), None, "{bad}");
        }
    }

    /// The key is the geometric mean: pixels of 0.02 and 0.08 (geometric mean 0.04) are metered at
    /// log₂(0.18 / 0.04) = 2.17 stops, not at the arithmetic mean's log₂(0.18 / 0.05) = 1.85.
    #[test]
    fn the_key_is_the_log_average_mapped_to_middle_grey() {
        let m = meter(&image(&[(0.02, 1.0), (0.08, 1.0)]));
        assert!((m.key - 0.04).abs() < 1e-5, "{m:?}");
        assert!(
            (m.key_stops - (0.18f32 / 0.04).log2()).abs() < 1e-4,
            "{m:?}"
        );
        assert!(!m.almost_black);
        // A scene lit in lux taken as W/m² renders 683× too dark: the meter reads 9.4 stops more.
        let dim = meter(&image(&[(0.02 / 683.0, 1.0), (0.08 / 683.0, 1.0)]));
        assert!(
            (dim.key_stops - m.key_stops - 683f32.log2()).abs() < 1e-3,
            "{dim:?}"
        );
        assert!(dim.almost_black);
    }

    /// Auto exposure leaves keys from 0.09 to 1 alone and brings the others to the nearer end of that range.
    #[test]
    fn auto_exposure_moves_only_keys_outside_the_latitude() {
        for (key, stops) in [
            (0.18, 0.0),
            (0.364, 0.0), // the bundled demo: a bright sky over a grey floor
            (0.091, 0.0),
            (0.71, 0.0),
            (0.99, 0.0), // an object under the default white environment
            (0.18 / 683.0, 683f32.log2() - 1.0),
            (0.04, (0.09f32 / 0.04).log2()),
            (8.0, (1.0f32 / 8.0).log2()),
        ] {
            let m = meter(&image(&[(key, 1.0)]));
            assert!((m.auto_stops - stops).abs() < 1e-3, "key {key}: {m:?}");
            let exposed = key * m.auto_stops.exp2();
            assert!((0.0899..=1.0001).contains(&exposed), "key {key}: {exposed}");
        }
    }

    /// Uncovered pixels (the empty background) do not dilute the key; an image with no coverage weighs every
    /// pixel.
    #[test]
    fn coverage_weights_the_meter() {
        let object = meter(&image(&[(0.5, 1.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)]));
        assert!((object.key - 0.5).abs() < 1e-4, "{object:?}");
        let sky = meter(&image(&[(2.0, 0.0), (0.5, 0.0)]));
        assert!((sky.key - 1.0).abs() < 1e-4, "{sky:?}");
        let half = meter(&image(&[(0.5, 1.0), (0.125, 0.5)]));
        // exp((1·ln 0.5 + 0.5·ln 0.125) / 1.5) = 2^(−(1 + 1.5) / 1.5).
        assert!((half.key - 2f32.powf(-2.5 / 1.5)).abs() < 1e-4, "{half:?}");
    }

    /// Covered pixels that are exactly black (geometry no light reaches, such as the faces of
    /// EmissiveStrengthTest's backdrop turned away from its glowing cubes) do not drag the key down: with δ
    /// they would count as 26 stops below white, and a third of them exposed the lit wall 8 stops too bright.
    #[test]
    fn unlit_covered_pixels_do_not_dilute_the_key() {
        let m = meter(&image(&[(0.18, 1.0), (0.0, 1.0), (0.18, 1.0), (0.0, 1.0)]));
        assert!((m.key - 0.18).abs() < 1e-4, "{m:?}");
        assert_eq!(m.auto_stops, 0.0, "{m:?}");
        // A pixel that is dim but lit is still metered.
        let dim = meter(&image(&[(0.18, 1.0), (0.18 / 64.0, 1.0)]));
        assert!((dim.key - 0.18 / 8.0).abs() < 1e-4, "{dim:?}");
    }

    #[test]
    fn black_and_non_finite_images_keep_zero_stops() {
        let black = meter(&image(&[(0.0, 0.0), (0.0, 1.0)]));
        assert_eq!(black.auto_stops, 0.0);
        assert!(black.almost_black);
        let mut broken = image(&[(f32::NAN, 1.0), (0.3, 1.0)]);
        broken.beauty[0] = Rgb::new(f32::INFINITY, 0.0, 0.0);
        let m = meter(&broken);
        assert!(
            (m.key - 0.3).abs() < 1e-4 && m.auto_stops.is_finite(),
            "{m:?}"
        );
        // A single firefly of 1e30 on a black frame is clamped, not trusted.
        let firefly = meter(&image(&[(1e30, 1.0), (0.0, 1.0)]));
        assert_eq!(firefly.key_stops, -MAX_AUTO_STOPS, "{firefly:?}");
        assert!(firefly.auto_stops.is_finite());
    }

    #[test]
    fn almost_black_counts_pixels_that_reach_a_tenth_of_white() {
        let mut values = vec![(0.001, 1.0); 2000];
        assert!(meter(&image(&values)).almost_black);
        values[0].0 = 0.5;
        assert!(meter(&image(&values)).almost_black, "1 in 2000 is < 0.1 %");
        values[1].0 = 0.5;
        values[2].0 = 0.5;
        assert!(!meter(&image(&values)).almost_black, "3 in 2000 is > 0.1 %");
    }
}
