//! The environment light: radiance arriving from infinitely far away.
//!
//! Scene `extras.nimbus_environment`: `{"color": [r, g, b]}` (constant radiance) or
//! `{"map": "sky.exr", "intensity": s}` (an equirectangular map, importance-sampled by luminance). The CLI's
//! `--env-color r,g,b` overrides it; the default is black.
//!
//! Orientation (a contract, Mitsuba's latitude–longitude mapping): map coordinates (u, v) ∈ \[0,1\]², v = 0 the
//! top row, face the direction `(sin 2πu · sin πv, cos πv, −cos 2πu · sin πv)`. The top row is +Y, u = 0 is −Z
//! and u = 0.25 is +X.
//!
//! Reconstruction (also Mitsuba 3's `envmap`): the texels are samples of a bilinear surface. Texel (i, j) of a
//! w × h map sits at u = (i + ½)/w, wrapping around in u, and at v = j/(h − 1): the first row is the +Y pole
//! and the last row the −Y pole. Between four neighbouring texels the radiance is their bilinear blend.
//!
//! Sampling: a piecewise-constant density over those bilinear patches (w × (h − 1) of them), each weighted by
//! its mean radiance (the mean of its four corners, luminance) × sin θ at its centre (PBRT 4th ed. §12.5.2),
//! so the density is positive wherever the radiance is.

use super::LightSample;
use crate::limits::Limits;
use crate::math::{luminance, Distribution2D, Rgb, Vec2, Vec3};
use exr::prelude::{ReadChannels as _, ReadLayers as _};
use std::f32::consts::PI;
use std::path::PathBuf;

/// An environment map file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum EnvironmentError {
    /// The EXR decoder failed (missing file, malformed or unsupported EXR).
    #[error("environment map {}: {source}", path.display())]
    Exr {
        /// The map file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: exr::error::Error,
    },
    /// The file could not be read (missing, unreadable, larger than the memory budget, an endless device).
    #[error("environment map {}: {source}", path.display())]
    Io {
        /// The map file.
        path: PathBuf,
        /// The read's error.
        #[source]
        source: std::io::Error,
    },
    /// The map's texels would exceed the memory budget.
    #[error("environment map {}: {source}", path.display())]
    OverBudget {
        /// The map file.
        path: PathBuf,
        /// What was refused.
        #[source]
        source: crate::limits::OverBudget,
    },
    /// The PNG/JPEG decoder failed (malformed or unsupported image, or one larger than the budget).
    #[error("environment map {}: {message}", path.display())]
    Image {
        /// The map file.
        path: PathBuf,
        /// The decoder's error, as one line.
        message: String,
    },
    /// The file decoded to no texels.
    #[error("environment map {}: the map is empty", path.display())]
    Empty {
        /// The map file.
        path: PathBuf,
    },
}

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
    /// Builds a map from linear RGB texels (row-major, top row first), scaled by `intensity`. A single row is
    /// taken as constant from pole to pole. Returns `None` when the texel count does not match the size.
    pub fn new(width: usize, height: usize, texels: Vec<Rgb>, intensity: f32) -> Option<Self> {
        if width == 0 || height == 0 || texels.len() != width.checked_mul(height)? {
            return None;
        }
        let mut texels: Vec<Rgb> = texels
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
        let height = if height == 1 {
            texels.extend_from_within(..);
            2
        } else {
            height
        };
        let luma: Vec<f32> = texels.iter().map(|&t| luminance(t)).collect();
        // Patch (x, y) lies between texel columns x and x + 1 (wrapping) and rows y and y + 1.
        let patch_rows = height - 1;
        let mut weights = Vec::with_capacity(width * patch_rows);
        let mut integral = 0.0f64;
        for y in 0..patch_rows {
            let sin_theta = (PI * (y as f32 + 0.5) / patch_rows as f32).sin();
            for x in 0..width {
                let x1 = (x + 1) % width;
                let mean = 0.25
                    * (luma[y * width + x]
                        + luma[y * width + x1]
                        + luma[(y + 1) * width + x]
                        + luma[(y + 1) * width + x1]);
                weights.push(mean * sin_theta);
                integral += (mean * sin_theta) as f64;
            }
        }
        // ∫ L dω over the sphere ≈ Σ mean · sin θ · (2π / w) · (π / (h − 1)); the average divides by 4π.
        let average_luminance =
            (integral * std::f64::consts::PI / (2.0 * (width * patch_rows) as f64)) as f32;
        Some(Self {
            distribution: Distribution2D::new(&weights, width, patch_rows),
            width,
            height,
            texels,
            average_luminance,
        })
    }

    /// Map coordinates (u, v) of the patch-space point `st` of the sampling distribution, and back: the patches
    /// start half a texel to the right of u = 0.
    fn patch_to_uv(&self, st: Vec2) -> Vec2 {
        let u = st.x + 0.5 / self.width as f32;
        Vec2::new(if u >= 1.0 { u - 1.0 } else { u }, st.y)
    }

    fn uv_to_patch(&self, uv: Vec2) -> Vec2 {
        let s = uv.x - 0.5 / self.width as f32;
        Vec2::new(if s < 0.0 { s + 1.0 } else { s }, uv.y)
    }

    internal! {
        /// Loads an equirectangular map from an EXR (its RGB channels, linear) or a PNG/JPEG (sRGB-decoded),
        /// reading the file and sizing its texels within the memory budget `limits`. The error names the file and
        /// keeps the decoder's error as its source.
        pub fn load(
            path: &std::path::Path,
            intensity: f32,
            limits: &Limits,
        ) -> Result<Self, EnvironmentError> {
            let is_exr = path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            let bytes =
                crate::limits::read_file(path, limits).map_err(|source| EnvironmentError::Io {
                    path: path.to_path_buf(),
                    source,
                })?;
            // Per texel: the RGB texels and the sampling distribution's weights, about 16 bytes.
            const TEXEL_BYTES: u64 = 16;
            let (width, height, texels) = if is_exr {
                let meta =
                    exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
                        .map_err(|source| EnvironmentError::Exr {
                            path: path.to_path_buf(),
                            source,
                        })?;
                for header in &meta.headers {
                    let size = header.layer_size;
                    limits
                        .check_items(
                            format_args!("environment map {}", path.display()),
                            size.width() as u64 * size.height() as u64,
                            TEXEL_BYTES,
                        )
                        .map_err(|source| EnvironmentError::OverBudget {
                            path: path.to_path_buf(),
                            source,
                        })?;
                }
                let image = exr::prelude::read()
                    .no_deep_data()
                    .largest_resolution_level()
                    .rgba_channels(
                        |res, _| (res.width(), vec![Rgb::ZERO; res.width() * res.height()]),
                        |(w, px): &mut (usize, Vec<Rgb>),
                         pos,
                         (r, g, b, _a): (f32, f32, f32, f32)| {
                            px[pos.y() * *w + pos.x()] = Rgb::new(r, g, b);
                        },
                    )
                    .first_valid_layer()
                    .all_attributes()
                    .from_buffered(std::io::Cursor::new(&bytes))
                    .map_err(|source| EnvironmentError::Exr {
                        path: path.to_path_buf(),
                        source,
                    })?;
                let size = image.layer_data.size;
                (
                    size.width(),
                    size.height(),
                    image.layer_data.channel_data.pixels.1,
                )
            } else {
                let img = crate::limits::decode_image(&bytes, limits, TEXEL_BYTES)
                    .map_err(|e| EnvironmentError::Image {
                        path: path.to_path_buf(),
                        message: e.to_string(),
                    })?
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
            Self::new(width, height, texels, intensity).ok_or_else(|| EnvironmentError::Empty {
                path: path.to_path_buf(),
            })
        }
    }

    /// The bilinear reconstruction at map coordinates `uv` (see the module docs for where texels sit).
    fn lookup(&self, uv: Vec2) -> Rgb {
        let x = uv.x * self.width as f32 - 0.5;
        let y = (uv.y * (self.height - 1) as f32).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor(), y.floor().min((self.height - 2) as f32));
        let (fx, fy) = (x - x0, y - y0);
        let texel = |x: f32, y: f32| {
            let x = (x as isize).rem_euclid(self.width as isize) as usize;
            self.texels[y as usize * self.width + x]
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
}

/// The direction that map coordinates `uv` face.
pub(crate) fn uv_to_direction(uv: Vec2) -> Vec3 {
    let (sin_phi, cos_phi) = (2.0 * PI * uv.x).sin_cos();
    let (sin_theta, cos_theta) = (PI * uv.y).sin_cos();
    Vec3::new(sin_phi * sin_theta, cos_theta, -cos_phi * sin_theta)
}

/// The map coordinates a unit direction falls on; the inverse of [`uv_to_direction`].
pub(crate) fn direction_to_uv(d: Vec3) -> Vec2 {
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
    internal! {
        /// Radiance arriving along direction `-dir`, i.e. seen when looking toward `dir`.
        pub fn radiance(&self, dir: Vec3) -> Rgb {
            match self {
                EnvironmentLight::Constant(c) => *c,
                EnvironmentLight::Map(m) => m.lookup(direction_to_uv(dir)),
            }
        }
    }

    /// Samples a direction toward the environment.
    pub(crate) fn sample_li(&self, u: Vec2) -> Option<LightSample> {
        let (wi, pdf) = match self {
            EnvironmentLight::Constant(_) => (
                crate::math::sampling::uniform_sphere(u),
                crate::math::sampling::UNIFORM_SPHERE_PDF,
            ),
            EnvironmentLight::Map(m) => {
                let (st, map_pdf) = m.distribution.sample(u);
                let uv = m.patch_to_uv(st);
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
            point: None,
            is_delta: false,
        })
    }

    internal! {
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
                    m.distribution.pdf(m.uv_to_patch(uv)) / (2.0 * PI * PI * sin_theta)
                }
            }
        }
    }

    /// Mean luminance over the sphere of directions.
    pub(crate) fn average_luminance(&self) -> f32 {
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
            // The density is piecewise constant over the patches between texels; away from patch edges (where
            // rounding may pick the neighbour) the density recomputed from the direction equals the sampled one.
            let uv =
                direction_to_uv(s.wi) * Vec2::new(w as f32, (h - 1) as f32) - Vec2::new(0.5, 0.0);
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

    /// One bright texel in a black map: the radiance is its bilinear spread, which reaches into the neighbouring
    /// cells, and the sampling density must cover all of it (else light sampling would miss that light).
    #[test]
    fn bilinear_radiance_is_covered_by_the_sampling_density() {
        let (w, h) = (8, 4);
        let mut texels = vec![Rgb::ZERO; w * h];
        texels[w + 3] = Rgb::ONE;
        let env = EnvironmentLight::Map(Box::new(EnvironmentMap::new(w, h, texels, 1.0).unwrap()));
        let at = |u: f32, v: f32| env.radiance(uv_to_direction(Vec2::new(u, v))).x;
        // Texel (3, 1) sits at u = 3.5/8, v = 1/3: the full value there, half of it halfway to the next texel in
        // u or in v, none a whole texel away.
        assert!((at(3.5 / 8.0, 1.0 / 3.0) - 1.0).abs() < 1e-4);
        assert!((at(4.0 / 8.0, 1.0 / 3.0) - 0.5).abs() < 1e-4);
        assert!((at(3.5 / 8.0, 0.5) - 0.5).abs() < 1e-4);
        assert!(at(4.5 / 8.0, 1.0 / 3.0).abs() < 1e-4);
        assert!(at(3.5 / 8.0, 2.0 / 3.0).abs() < 1e-4);
        let mut rng = crate::math::Rng::new(4, 1);
        for _ in 0..2000 {
            let uv = rng.next_2d();
            let dir = uv_to_direction(uv);
            if env.radiance(dir).x > 0.0 {
                assert!(env.pdf(dir) > 0.0, "radiance without density at {uv}");
            }
        }
        // u wraps around: the seam between the last and the first column interpolates between them.
        let mut texels = vec![Rgb::ZERO; w * h];
        for y in 0..h {
            texels[y * w] = Rgb::ONE;
        }
        let env = EnvironmentLight::Map(Box::new(EnvironmentMap::new(w, h, texels, 1.0).unwrap()));
        let seam = env.radiance(uv_to_direction(Vec2::new(0.0, 0.5))).x;
        assert!((seam - 0.5).abs() < 1e-4, "seam {seam}");
    }
}
