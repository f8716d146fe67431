//! The environment light: radiance arriving from infinitely far away.
//!
//! Scene `extras.nimbus_environment`: `{"color": [r, g, b]}` (constant radiance) or
//! `{"map": "sky.exr", "intensity": s}` (an equirectangular map, importance-sampled by luminance). The CLI's
//! `--env-color r,g,b` overrides it; the default is black.
//!
//! Orientation (a contract, Mitsuba's latitude–longitude mapping): map coordinates (u, v) ∈ \[0,1\]², v = 0 the
//! top row, face the direction `(sin 2πu · sin πv, cos πv, −cos 2πu · sin πv)`. The top row is +Y, u = 0 is −Z
//! and u = 0.25 is +X.

use super::LightSample;
use crate::math::{luminance, Distribution2D, Rgb, Vec2, Vec3};
use std::f32::consts::PI;

/// An equirectangular radiance map with its sampling distribution.
#[derive(Clone, Debug)]
pub struct EnvironmentMap {
    width: usize,
    height: usize,
    texels: Vec<Rgb>,
    distribution: Distribution2D,
    average_luminance: f32,
}

impl EnvironmentMap {
    /// Builds a map from linear RGB texels (row-major, top row first), scaled by `intensity`.
    /// Returns `None` when the texel count does not match the size.
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>, intensity: f32) -> Option<Self> {
        if width == 0 || height == 0 || texels.len() != width * height {
            return None;
        }
        let texels: Vec<Rgb> = texels
            .into_iter()
            .map(|t| {
                let t = t * intensity;
                if crate::math::is_finite_rgb(t) {
                    t.max(Rgb::ZERO)
                } else {
                    Rgb::ZERO
                }
            })
            .collect();
        // Weight rows by sin θ so the density in solid angle follows luminance (PBRT4 §12.5.2).
        let mut weights = Vec::with_capacity(texels.len());
        let mut solid_angle_weighted = 0.0f64;
        for y in 0..height {
            let sin_theta = (PI * (y as f32 + 0.5) / height as f32).sin();
            for x in 0..width {
                let l = luminance(texels[y * width + x]);
                weights.push(l * sin_theta);
                solid_angle_weighted += (l * sin_theta) as f64;
            }
        }
        let average_luminance =
            (solid_angle_weighted * (PI as f64 / 2.0) / (width * height) as f64) as f32;
        Some(Self {
            distribution: Distribution2D::new(&weights, width, height),
            width,
            height,
            texels,
            average_luminance,
        })
    }

    /// Loads an equirectangular map from an EXR (its RGB channels, linear) or a PNG/JPEG (sRGB-decoded).
    /// The error message names the file.
    pub fn load(path: &std::path::Path, intensity: f32) -> Result<Self, String> {
        let name = path.display();
        let is_exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        let (width, height, texels) = if is_exr {
            let image = exr::prelude::read_first_rgba_layer_from_file(
                path,
                |res, _| (res.width(), vec![Rgb::ZERO; res.width() * res.height()]),
                |(w, px): &mut (usize, Vec<Rgb>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    px[pos.y() * *w + pos.x()] = Rgb::new(r, g, b);
                },
            )
            .map_err(|e| format!("{name}: {e}"))?;
            let size = image.layer_data.size;
            (
                size.width(),
                size.height(),
                image.layer_data.channel_data.pixels.1,
            )
        } else {
            let img = image::open(path)
                .map_err(|e| format!("{name}: {e}"))?
                .to_rgb32f();
            let (w, h) = (img.width() as usize, img.height() as usize);
            let texels = img
                .pixels()
                .map(|p| {
                    Rgb::new(p[0], p[1], p[2])
                        .to_array()
                        .map(crate::math::srgb_to_linear)
                        .into()
                })
                .collect();
            (w, h, texels)
        };
        Self::new(width, height, texels, intensity)
            .ok_or_else(|| format!("{name}: the map is empty"))
    }

    fn lookup(&self, uv: Vec2) -> Rgb {
        let x = ((uv.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as usize).min(self.height - 1);
        self.texels[y * self.width + x]
    }
}

/// The direction that map coordinates `uv` face.
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let (sin_phi, cos_phi) = (2.0 * PI * uv.x).sin_cos();
    let (sin_theta, cos_theta) = (PI * uv.y).sin_cos();
    Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta)
}

/// The map coordinates a unit direction falls on; the inverse of [`uv_to_direction`].
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    // atan2 keeps θ accurate near the poles, where acos(y) loses precision in f32.
    let v = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y) / PI;
    let mut u = d.x.atan2(-d.z) / (2.0 * PI);
    if u < 0.0 {
        u += 1.0;
    }
    Vec2::new(u.min(1.0 - f32::EPSILON), v)
}

/// Light from infinitely far away: a constant colour, or a map.
#[derive(Clone, Debug)]
pub enum EnvironmentLight {
    /// The same radiance from every direction.
    Constant(Rgb),
    /// An importance-sampled equirectangular map.
    Map(Box<EnvironmentMap>),
}

impl EnvironmentLight {
    /// Radiance arriving along direction `-dir`, i.e. seen when looking toward `dir`.
    pub fn radiance(&self, dir: Vec3) -> Rgb {
        match self {
            EnvironmentLight::Constant(c) => *c,
            EnvironmentLight::Map(m) => m.lookup(direction_to_uv(dir)),
        }
    }

    /// Samples a direction toward the environment.
    pub fn sample_li(&self, u: Vec2) -> Option<LightSample> {
        let (wi, pdf) = match self {
            EnvironmentLight::Constant(_) => (
                crate::math::sampling::uniform_sphere(u),
                crate::math::sampling::UNIFORM_SPHERE_PDF,
            ),
            EnvironmentLight::Map(m) => {
                let (uv, map_pdf) = m.distribution.sample(u);
                let sin_theta = (PI * uv.y).sin();
                if map_pdf <= 0.0 || sin_theta <= 0.0 {
                    return None;
                }
                (uv_to_direction(uv), map_pdf / (2.0 * PI * PI * sin_theta))
            }
        };
        Some(LightSample {
            wi,
            radiance: self.radiance(wi),
            pdf,
            distance: f32::INFINITY,
            is_delta: false,
        })
    }

    /// Solid-angle density of [`Self::sample_li`] choosing `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self {
            EnvironmentLight::Constant(_) => crate::math::sampling::UNIFORM_SPHERE_PDF,
            EnvironmentLight::Map(m) => {
                let uv = direction_to_uv(dir);
                let sin_theta = (PI * uv.y).sin();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                m.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta)
            }
        }
    }

    /// Mean luminance over the sphere of directions.
    pub fn average_luminance(&self) -> f32 {
        match self {
            EnvironmentLight::Constant(c) => luminance(*c),
            EnvironmentLight::Map(m) => m.average_luminance,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_contract() {
        assert!(uv_to_direction(Vec2::new(0.0, 0.5)).distance(-Vec3::Z) < 1e-6);
        assert!(uv_to_direction(Vec2::new(0.25, 0.5)).distance(Vec3::X) < 1e-6);
        assert!(uv_to_direction(Vec2::new(0.3, 0.0)).distance(Vec3::Y) < 1e-6);
        for uv in [
            Vec2::new(0.1, 0.2),
            Vec2::new(0.6, 0.7),
            Vec2::new(0.9, 0.4),
        ] {
            assert!(direction_to_uv(uv_to_direction(uv)).distance(uv) < 1e-5);
        }
    }

    #[test]
    fn map_sampling_density_matches_pdf_and_integrates_to_one() {
        let (w, h) = (16, 8);
        let texels = (0..w * h)
            .map(|i| Rgb::splat(1.0 + (i % 7) as f32))
            .collect();
        let env = EnvironmentLight::Map(Box::new(EnvironmentMap::new(w, h, texels, 1.0).unwrap()));
        let mut rng = crate::math::Rng::new(9, 2);
        let n = 20_000;
        // E[1/pdf] over samples of the density is the measure of its support: 4π.
        let mut sum = 0.0f64;
        let mut sum2 = 0.0f64;
        for _ in 0..n {
            let s = env.sample_li(rng.next_2d()).unwrap();
            // The density is piecewise constant; away from texel edges (where rounding may pick the
            // neighbour) the density recomputed from the direction equals the sampled one.
            let uv = direction_to_uv(s.wi) * Vec2::new(w as f32, h as f32);
            if (uv - uv.round()).abs().min_element() > 1e-3 {
                let again = env.pdf(s.wi);
                assert!((again - s.pdf).abs() < 2e-3 * s.pdf, "{again} vs {}", s.pdf);
            }
            let x = 1.0 / s.pdf as f64;
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - 4.0 * std::f64::consts::PI).abs() < 4.0 * se,
            "mean {mean} se {se}"
        );
    }
}
