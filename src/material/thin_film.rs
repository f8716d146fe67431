//! Thin-film interference on the Fresnel term of the specular lobes (`KHR_materials_iridescence`), after
//! Belcour & Barla 2017, "A Practical Extension to Microfacet Theory for the Modeling of Varying Iridescence"
//! (ACM TOG 36(4), SIGGRAPH 2017).
//!
//! glTF keys read (through [`super::Iridescence`] and [`super::PbrParams`]): `iridescenceFactor` (default 0)
//! × `iridescenceTexture` (R), `iridescenceIor` (default 1.3), `iridescenceThicknessMinimum` (default 100 nm)
//! and `iridescenceThicknessMaximum` (default 400 nm), between which `iridescenceThicknessTexture` (G) blends
//! (the maximum without the texture).
//!
//! The model (Belcour & Barla 2017, §3): a film of index η₂ and thickness d lies between the outside (η₁ = 1)
//! and the substrate (η₃). Light reflected at the top interface interferes with the light that crosses the
//! film, reflects any number of times inside it and leaves again; summing the waves (the Airy summation) gives
//! the amplitude reflectance of each polarisation
//!
//! `r = (r₁₂ + r₂₃ e^{iδ}) / (1 + r₁₂ r₂₃ e^{iδ})`, with `δ = 4π η₂ d cos θ₂ / λ`
//!
//! (Born & Wolf, "Principles of Optics", §1.6: a single homogeneous film), where `r_ij` are the Fresnel
//! amplitude coefficients of the two interfaces and θ₂ the angle inside the film, from Snell's law. The
//! reflectance is `(|r_s|² + |r_p|²)/2` (unpolarised light). Past the critical angle of the film–substrate
//! interface `cos θ₃` is imaginary and `r₂₃` a unit complex number: the film then reflects everything.
//!
//! Choices, where the extension leaves them open:
//! - The substrate index comes from the specular layer's normal-incidence reflectance `F0` as the extension's
//!   implementation notes say, `η₃ = (1 + √F0)/(1 − √F0)` per channel (dielectric `F0` for the dielectric
//!   specular, the base colour for the metal, whose extinction is taken as 0).
//! - Each RGB channel is the reflectance at one wavelength, [`crate::math::RGB_WAVELENGTHS_NM`]. Belcour &
//!   Barla integrate the spectrum against the CIE matching functions instead (their §4, in Fourier space),
//!   which washes thick films (over about 1 µm) out to pastel; point samples keep them saturated. Within the
//!   extension's default thickness range the difference is a hue shift, not an artefact.
//! - The exact Fresnel coefficients are used, not Schlick's approximations of the implementation notes.
//! - The film's outside is air even under a clear coat (the extension puts the coat's index 1.5 there).
//! - A film of thickness 0, or of weight 0, leaves the Fresnel term untouched, bit for bit.
//!
//! The specular Fresnel term becomes `mix(F_schlick, R_film, weight)` (the extension's implementation notes),
//! for the dielectric specular and the metal alike.

use crate::math::{Rgb, RGB_WAVELENGTHS_NM};

/// A thin dielectric film over the specular layer at one shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilm {
    /// How much of the Fresnel term the film replaces: `iridescenceFactor` × the texture's R, in (0, 1\].
    pub weight: f32,
    /// The film's index of refraction, `iridescenceIor` (at least 1).
    pub ior: f32,
    /// The film's thickness in nanometres (positive).
    pub thickness: f32,
}

impl ThinFilm {
    /// The film for a weight, index and thickness (nm), or `None` where it changes nothing: weight or
    /// thickness not positive (or not numbers).
    pub fn new(weight: f32, ior: f32, thickness: f32) -> Option<Self> {
        (weight > 0.0 && thickness > 0.0 && thickness.is_finite()).then(|| ThinFilm {
            weight: weight.min(1.0),
            ior: if ior.is_finite() { ior.max(1.0) } else { 1.0 },
            thickness,
        })
    }

    /// The film's reflectance per channel at `cos_theta` (the cosine at the top of the film, `wo·h`) over a
    /// substrate whose normal-incidence reflectance from air is `f0` (see the module documentation).
    pub fn reflectance(&self, cos_theta: f32, f0: Rgb) -> Rgb {
        Rgb::from_array(std::array::from_fn(|c| {
            airy_reflectance(
                cos_theta,
                self.ior,
                substrate_ior(f0[c]),
                self.thickness,
                RGB_WAVELENGTHS_NM[c],
            )
        }))
    }

    /// The specular Fresnel term under the film: `schlick` (the term without it) mixed with the film's
    /// reflectance by the weight.
    pub fn fresnel(&self, schlick: Rgb, cos_theta: f32, f0: Rgb) -> Rgb {
        schlick + (self.reflectance(cos_theta, f0) - schlick) * self.weight
    }
}

/// The real index of a medium whose normal-incidence reflectance from air is `f0`:
/// `η = (1 + √F0)/(1 − √F0)`, the inverse of `F0 = ((η − 1)/(η + 1))²`; `f0` is kept within \[0, 0.9999\].
pub fn substrate_ior(f0: f32) -> f32 {
    let s = f0.clamp(0.0, 0.9999).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// A complex number, for the amplitudes of the Airy summation.
#[derive(Clone, Copy, Debug)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn real(re: f64) -> Self {
        Complex { re, im: 0.0 }
    }

    /// `e^{iθ}`.
    fn cis(theta: f64) -> Self {
        Complex {
            re: theta.cos(),
            im: theta.sin(),
        }
    }

    fn add(self, o: Self) -> Self {
        Complex {
            re: self.re + o.re,
            im: self.im + o.im,
        }
    }

    fn sub(self, o: Self) -> Self {
        Complex {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }

    fn mul(self, o: Self) -> Self {
        Complex {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }

    fn scale(self, k: f64) -> Self {
        Complex {
            re: self.re * k,
            im: self.im * k,
        }
    }

    fn div(self, o: Self) -> Self {
        let d = o.norm_sqr();
        Complex {
            re: (self.re * o.re + self.im * o.im) / d,
            im: (self.im * o.re - self.re * o.im) / d,
        }
    }

    fn norm_sqr(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
}

/// The Fresnel amplitude coefficients (s, p) from a medium of index `n_i` (cosine `c_i`) into one of index
/// `n_j` (cosine `c_j`, complex past the critical angle): `r_s = (n_i c_i − n_j c_j)/(n_i c_i + n_j c_j)`,
/// `r_p = (n_j c_i − n_i c_j)/(n_j c_i + n_i c_j)` (Born & Wolf §1.5.2), one sign convention for every
/// interface of the film.
fn amplitudes(n_i: f64, c_i: Complex, n_j: f64, c_j: Complex) -> (Complex, Complex) {
    let (a, b) = (c_i.scale(n_i), c_j.scale(n_j));
    let (c, d) = (c_i.scale(n_j), c_j.scale(n_i));
    (a.sub(b).div(a.add(b)), c.sub(d).div(c.add(d)))
}

/// The cosine of the refracted angle, for a direction of cosine `cos_1` in index 1 entering index `n`:
/// `√(1 − sin²θ₁/n²)`, imaginary (`i√(sin²θ₁/n² − 1)`, the evanescent wave) past the critical angle.
fn refracted_cos(cos_1: f64, n: f64) -> Complex {
    let sin2 = (1.0 - cos_1 * cos_1).max(0.0) / (n * n);
    if sin2 <= 1.0 {
        Complex::real((1.0 - sin2).sqrt())
    } else {
        Complex {
            re: 0.0,
            im: (sin2 - 1.0).sqrt(),
        }
    }
}

/// The unpolarised reflectance of a film of index `film_ior` and thickness `thickness_nm` between the outside
/// (index 1) and a substrate of index `substrate_ior`, at one wavelength (nm), for light arriving with
/// cosine `cos_theta` (its sign ignored): the Airy summation of the module documentation, averaged over the s
/// and p polarisations.
pub fn airy_reflectance(
    cos_theta: f32,
    film_ior: f32,
    substrate_ior: f32,
    thickness_nm: f32,
    wavelength_nm: f32,
) -> f32 {
    let cos_1 = (cos_theta.abs() as f64).min(1.0);
    let (n2, n3) = (film_ior as f64, substrate_ior as f64);
    let c1 = Complex::real(cos_1);
    let c2 = refracted_cos(cos_1, n2);
    if c2.im != 0.0 {
        // Total internal reflection at the top of the film (a film less dense than the outside).
        return 1.0;
    }
    let c3 = refracted_cos(cos_1, n3);
    let (r12_s, r12_p) = amplitudes(1.0, c1, n2, c2);
    let (r23_s, r23_p) = amplitudes(n2, c2, n3, c3);
    let delta =
        4.0 * std::f64::consts::PI * n2 * thickness_nm as f64 * c2.re / wavelength_nm as f64;
    let phase = Complex::cis(delta);
    let airy = |r12: Complex, r23: Complex| {
        let round = r23.mul(phase);
        r12.add(round)
            .div(Complex::real(1.0).add(r12.mul(round)))
            .norm_sqr()
    };
    let r = 0.5 * (airy(r12_s, r23_s) + airy(r12_p, r23_p));
    r.clamp(0.0, 1.0) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::fresnel;

    /// The film's amplitude reflectance at normal incidence summed wave by wave, independently of the closed
    /// form: the wave reflected at the top, `r₁₂`, plus the waves that enter (`t₁₂`), bounce k + 1 times off the
    /// substrate (`r₂₃`) and k times off the film's top from inside (`r₂₁ = −r₁₂`), and leave (`t₂₁`), each
    /// round trip adding the phase `2φ = 4π η₂ d / λ` (Stokes: `t₁₂ t₂₁ = 1 − r₁₂²`).
    fn normal_incidence_by_waves(n2: f64, n3: f64, d: f64, lambda: f64) -> f64 {
        let r12 = (1.0 - n2) / (1.0 + n2);
        let r23 = (n2 - n3) / (n2 + n3);
        let phi = 2.0 * std::f64::consts::PI * n2 * d / lambda;
        let round = Complex::cis(2.0 * phi).scale(r23);
        let mut sum = Complex::real(r12);
        let mut wave = round.scale(1.0 - r12 * r12);
        for _ in 0..400 {
            sum = sum.add(wave);
            wave = wave.mul(round).scale(-r12);
        }
        sum.norm_sqr()
    }

    #[test]
    fn normal_incidence_matches_the_summed_waves() {
        let mut worst = 0.0f64;
        for (n2, n3) in [(1.3, 1.5), (1.8, 1.5), (1.3, 4.0), (2.2, 1.2), (1.5, 1.0)] {
            for d in [0.0, 50.0, 120.0, 250.0, 400.0, 733.0, 1200.0] {
                for lambda in RGB_WAVELENGTHS_NM {
                    let r = airy_reflectance(1.0, n2 as f32, n3 as f32, d as f32, lambda) as f64;
                    let expected = normal_incidence_by_waves(n2, n3, d, lambda as f64);
                    worst = worst.max((r - expected).abs());
                    assert!(
                        (r - expected).abs() < 2e-6,
                        "n2 {n2} n3 {n3} d {d} λ {lambda}: {r} vs {expected}"
                    );
                }
            }
        }
        // The measured worst difference, for the record in the test output (`--nocapture`).
        println!("thin film at normal incidence: worst |R − waves| = {worst:.2e}");
    }

    #[test]
    fn a_vanishing_or_index_matched_film_is_the_bare_interface() {
        for i in 1..=20 {
            let cos = i as f32 / 20.0;
            for n3 in [1.2f32, 1.5, 2.4] {
                let bare = fresnel::dielectric(cos, n3);
                // No thickness: the substrate's own Fresnel reflectance, both polarisations.
                let thin = airy_reflectance(cos, 1.8, n3, 0.0, 550.0);
                // A film of the substrate's index, or of the outside's, is no interface at all.
                let same = airy_reflectance(cos, n3, n3, 321.0, 550.0);
                let air = airy_reflectance(cos, 1.0, n3, 321.0, 550.0);
                for r in [thin, same, air] {
                    assert!((r - bare).abs() < 1e-5, "cos {cos} n3 {n3}: {r} vs {bare}");
                }
            }
        }
    }

    #[test]
    fn reflectance_is_a_fraction_and_past_the_critical_angle_total() {
        for i in 0..=50 {
            let cos = i as f32 / 50.0;
            for (n2, n3) in [(1.3f32, 1.5f32), (2.0, 1.2), (1.5, 1.0)] {
                for d in [10.0f32, 300.0, 900.0] {
                    let r = airy_reflectance(cos, n2, n3, d, 500.0);
                    assert!((0.0..=1.0).contains(&r), "{r}");
                }
            }
        }
        // Into a substrate less dense than the outside, beyond its critical angle, nothing is transmitted.
        assert!((airy_reflectance(0.1, 1.4, 0.9, 200.0, 500.0) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn weight_zero_or_no_thickness_is_no_film() {
        assert_eq!(ThinFilm::new(0.0, 1.3, 400.0), None);
        assert_eq!(ThinFilm::new(1.0, 1.3, 0.0), None);
        let film = ThinFilm::new(1.0, 1.3, 400.0).unwrap();
        let f0 = Rgb::new(0.04, 0.5, 0.9);
        // Weight 1: exactly the film; each channel at its own wavelength.
        let r = film.fresnel(Rgb::splat(0.3), 0.7, f0);
        for c in 0..3 {
            let expected =
                airy_reflectance(0.7, 1.3, substrate_ior(f0[c]), 400.0, RGB_WAVELENGTHS_NM[c]);
            assert!((r[c] - expected).abs() < 1e-6);
        }
        assert!((substrate_ior(0.04) - 1.5).abs() < 1e-5);
    }
}
