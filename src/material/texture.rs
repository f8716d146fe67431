//! Image textures: decoded once at load time to linear floating-point RGBA with a mip pyramid, and sampled as
//! each glTF texture's own sampler says.
//!
//! glTF keys read: `sampler.wrapS`, `sampler.wrapT` (REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT; default REPEAT),
//! `sampler.magFilter` (NEAREST, LINEAR; default LINEAR) and `sampler.minFilter` (NEAREST, LINEAR and the four
//! `*_MIPMAP_*` modes; default LINEAR_MIPMAP_LINEAR, as glTF viewers do). Colour textures (`baseColorTexture`,
//! `emissiveTexture`) are decoded from sRGB; data textures (`metallicRoughnessTexture`, `normalTexture`) are kept
//! linear. The texture coordinate origin is the top-left of the image, as in glTF; texel centres sit at
//! half-integers (OpenGL's convention).
//!
//! Filtering follows OpenGL's rules (the OpenGL 4.6 specification, §8.14 "Texture Minification" and §8.15
//! "Texture Magnification"), with the footprint given as a width in texture coordinates ([`TexCoord`]): the level
//! of detail is λ = log₂(footprint · √(w·h)); λ ≤ 0 magnifies with `magFilter`, λ > 0 minifies with `minFilter`.
//! The footprint comes from the ray cone at the hit (see [`crate::integrator`]).
//!
//! The mip pyramid halves each dimension per level (rounding down, at least 1) with an exact box filter: every
//! texel of a level is the area-weighted mean of the finer texels it covers, so every level keeps the image
//! mean.

use crate::math::{srgb_to_linear, Vec2, Vec4};
use std::sync::Arc;

/// How texture coordinates outside \[0, 1\] are mapped back into the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// Tile the image.
    Repeat,
    /// Repeat the edge texel.
    ClampToEdge,
    /// Tile with every other copy mirrored.
    MirroredRepeat,
}

/// Reconstruction within one image level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Filter {
    /// The texel whose area contains the point.
    Nearest,
    /// Bilinear interpolation between the four nearest texel centres.
    Linear,
}

/// How a texture is sampled: glTF's `sampler` object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sampler {
    /// Wrap mode in u (glTF `wrapS`).
    pub wrap_s: Wrap,
    /// Wrap mode in v (glTF `wrapT`).
    pub wrap_t: Wrap,
    /// Filter when a texel covers more than the footprint (glTF `magFilter`).
    pub mag: Filter,
    /// Filter within a level when minifying (the first word of glTF's `minFilter`).
    pub min: Filter,
    /// How levels are chosen when minifying (the word after `MIPMAP_` in glTF's `minFilter`): `None` reads the
    /// full-resolution image only, `Nearest` the nearest level, `Linear` blends the two nearest.
    pub mip: Option<Filter>,
}

impl Default for Sampler {
    /// glTF's defaults as viewers apply them: REPEAT, LINEAR magnification, LINEAR_MIPMAP_LINEAR minification.
    fn default() -> Self {
        Self {
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
            mag: Filter::Linear,
            min: Filter::Linear,
            mip: Some(Filter::Linear),
        }
    }
}

impl Sampler {
    /// A sampler that reads the full-resolution image with `filter` for both minification and magnification.
    pub fn unfiltered(filter: Filter, wrap: Wrap) -> Self {
        Self {
            wrap_s: wrap,
            wrap_t: wrap,
            mag: filter,
            min: filter,
            mip: None,
        }
    }
}

/// Where a texture is read: texture coordinates and the width of the region they stand for.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TexCoord {
    /// Texture coordinates.
    pub uv: Vec2,
    /// Width of the filter footprint in texture-coordinate units; 0 reads the full-resolution image.
    pub footprint: f32,
}

impl TexCoord {
    /// A point lookup (no footprint): the full-resolution image with the magnification filter.
    pub fn point(uv: Vec2) -> Self {
        Self { uv, footprint: 0.0 }
    }
}

/// Whether 8-bit texel values are sRGB-encoded colours or linear data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorSpace {
    /// sRGB-encoded colour; decoded to linear on load (alpha stays linear).
    Srgb,
    /// Linear data (roughness, metalness, normals).
    Linear,
}

/// One level of a mip pyramid: linear RGBA texels, row 0 at the top (v = 0).
#[derive(Clone, Debug)]
struct Level {
    width: usize,
    height: usize,
    texels: Vec<Vec4>,
}

/// A decoded image and its mip pyramid, shared by every texture that samples it.
#[derive(Clone, Debug)]
pub struct MipImage {
    levels: Vec<Level>,
}

impl MipImage {
    /// Builds the pyramid from linear RGBA texels (row-major, top row first). `None` when the size is zero or
    /// the texel count does not match it.
    pub fn new(width: usize, height: usize, texels: Vec<Vec4>) -> Option<Self> {
        if width == 0 || height == 0 || texels.len() != width.checked_mul(height)? {
            return None;
        }
        let mut levels = vec![Level {
            width,
            height,
            texels,
        }];
        loop {
            let last = levels.last().expect("at least one level");
            if last.width == 1 && last.height == 1 {
                break;
            }
            let next = downsample(last);
            levels.push(next);
        }
        Some(Self { levels })
    }

    /// Decodes 8-bit RGBA data, colour channels per `space`, and builds the pyramid. `None` when `rgba8` does
    /// not hold `width × height` texels.
    pub fn from_rgba8(
        width: usize,
        height: usize,
        rgba8: &[u8],
        space: ColorSpace,
    ) -> Option<Self> {
        if rgba8.len() != width.checked_mul(height)?.checked_mul(4)? {
            return None;
        }
        let decode = |v: u8| {
            let f = v as f32 / 255.0;
            match space {
                ColorSpace::Srgb => srgb_to_linear(f),
                ColorSpace::Linear => f,
            }
        };
        let texels = rgba8
            .chunks_exact(4)
            .map(|p| {
                Vec4::new(
                    decode(p[0]),
                    decode(p[1]),
                    decode(p[2]),
                    p[3] as f32 / 255.0,
                )
            })
            .collect();
        Self::new(width, height, texels)
    }

    /// Width of the full-resolution image.
    pub fn width(&self) -> usize {
        self.levels[0].width
    }

    /// Height of the full-resolution image.
    pub fn height(&self) -> usize {
        self.levels[0].height
    }

    /// Number of levels, the full-resolution image included.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Bytes held by the texels of every level.
    pub fn memory_bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| l.texels.len() * std::mem::size_of::<Vec4>())
            .sum()
    }
}

/// The weights with which the `n` fine texels contribute to each of the `m` coarse ones of a box filter that
/// maps `[0, n)` onto `[0, m)`: coarse texel `j` covers `[j·n/m, (j+1)·n/m)`. Returns `(first fine texel,
/// weights)` per coarse texel; the weights of one coarse texel sum to 1.
fn box_weights(n: usize, m: usize) -> Vec<(usize, Vec<f32>)> {
    let ratio = n as f64 / m as f64;
    (0..m)
        .map(|j| {
            let (lo, hi) = (j as f64 * ratio, (j + 1) as f64 * ratio);
            let first = lo.floor() as usize;
            let last = (hi.ceil() as usize).min(n);
            let weights = (first..last)
                .map(|i| {
                    let overlap = (hi.min(i as f64 + 1.0) - lo.max(i as f64)).max(0.0);
                    (overlap / ratio) as f32
                })
                .collect();
            (first, weights)
        })
        .collect()
}

/// The next level: half the size in each dimension (at least 1), exact box filtering.
fn downsample(level: &Level) -> Level {
    let (w, h) = ((level.width / 2).max(1), (level.height / 2).max(1));
    let xs = box_weights(level.width, w);
    let ys = box_weights(level.height, h);
    let mut texels = Vec::with_capacity(w * h);
    for (y0, wy) in &ys {
        for (x0, wx) in &xs {
            let mut sum = Vec4::ZERO;
            for (dy, &fy) in wy.iter().enumerate() {
                let row = (y0 + dy) * level.width;
                for (dx, &fx) in wx.iter().enumerate() {
                    sum += level.texels[row + x0 + dx] * (fx * fy);
                }
            }
            texels.push(sum);
        }
    }
    Level {
        width: w,
        height: h,
        texels,
    }
}

/// A texture: a shared image and the sampler one glTF texture reads it with.
#[derive(Clone, Debug)]
pub struct Texture {
    image: Arc<MipImage>,
    sampler: Sampler,
}

impl Texture {
    /// A texture reading `image` with `sampler`.
    pub fn new(image: Arc<MipImage>, sampler: Sampler) -> Self {
        Self { image, sampler }
    }

    /// Builds a texture from 8-bit RGBA data, decoding colour channels per `space`, with the default sampler.
    /// Returns `None` when `rgba8` does not hold `width × height` texels.
    pub fn from_rgba8(
        width: usize,
        height: usize,
        rgba8: &[u8],
        space: ColorSpace,
    ) -> Option<Texture> {
        let image = MipImage::from_rgba8(width, height, rgba8, space)?;
        Some(Self::new(Arc::new(image), Sampler::default()))
    }

    /// Builds a texture from linear float RGBA texels (row-major, top row first), with the default sampler.
    /// Returns `None` when the texel count does not match.
    pub fn from_linear(width: usize, height: usize, texels: Vec<Vec4>) -> Option<Texture> {
        let image = MipImage::new(width, height, texels)?;
        Some(Self::new(Arc::new(image), Sampler::default()))
    }

    /// Sets the sampler.
    pub fn with_sampler(mut self, sampler: Sampler) -> Self {
        self.sampler = sampler;
        self
    }

    /// The sampler.
    pub fn sampler(&self) -> Sampler {
        self.sampler
    }

    /// The image.
    pub fn image(&self) -> &Arc<MipImage> {
        &self.image
    }

    /// Image width in texels.
    pub fn width(&self) -> usize {
        self.image.width()
    }

    /// Image height in texels.
    pub fn height(&self) -> usize {
        self.image.height()
    }

    /// Bytes held by the image (shared images count in full for each texture).
    pub fn memory_bytes(&self) -> usize {
        self.image.memory_bytes()
    }

    /// The value at texture coordinates `uv` of the full-resolution image, with the magnification filter.
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        self.lookup(TexCoord::point(uv))
    }

    /// The filtered value over the footprint `tc` (OpenGL's minification and magnification rules).
    pub fn lookup(&self, tc: TexCoord) -> Vec4 {
        let uv = tc.uv;
        if !uv.is_finite() {
            return self.image.levels[0].texels[0];
        }
        let base = &self.image.levels[0];
        let scale = ((base.width * base.height) as f32).sqrt();
        let lod = (tc.footprint * scale).log2();
        // λ ≤ 0 magnifies; NaN (a NaN footprint) falls back to magnification too.
        if lod.is_nan() || lod <= 0.0 {
            return self.filter_level(0, uv, self.sampler.mag);
        }
        let last = (self.image.levels.len() - 1) as f32;
        match self.sampler.mip {
            None => self.filter_level(0, uv, self.sampler.min),
            Some(Filter::Nearest) => {
                // OpenGL picks level ⌈λ + ½⌉ − 1, i.e. λ rounded to the nearest integer (halves down).
                let level = ((lod + 0.5).ceil() - 1.0).clamp(0.0, last) as usize;
                self.filter_level(level, uv, self.sampler.min)
            }
            Some(Filter::Linear) => {
                let lod = lod.min(last);
                let fine = lod.floor();
                let t = lod - fine;
                let a = self.filter_level(fine as usize, uv, self.sampler.min);
                if t == 0.0 {
                    return a;
                }
                let b = self.filter_level(fine as usize + 1, uv, self.sampler.min);
                a.lerp(b, t)
            }
        }
    }

    /// One level, filtered with `filter` at `uv`.
    fn filter_level(&self, level: usize, uv: Vec2, filter: Filter) -> Vec4 {
        let l = &self.image.levels[level];
        let x = uv.x * l.width as f32;
        let y = uv.y * l.height as f32;
        let texel = |x: i64, y: i64| {
            let x = wrap_index(x, l.width, self.sampler.wrap_s);
            let y = wrap_index(y, l.height, self.sampler.wrap_t);
            l.texels[y * l.width + x]
        };
        match filter {
            Filter::Nearest => texel(x.floor() as i64, y.floor() as i64),
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let top = texel(x0, y0).lerp(texel(x0 + 1, y0), fx);
                let bottom = texel(x0, y0 + 1).lerp(texel(x0 + 1, y0 + 1), fx);
                top.lerp(bottom, fy)
            }
        }
    }
}

fn wrap_index(i: i64, n: usize, wrap: Wrap) -> usize {
    let n = n as i64;
    match wrap {
        Wrap::Repeat => i.rem_euclid(n) as usize,
        Wrap::ClampToEdge => i.clamp(0, n - 1) as usize,
        Wrap::MirroredRepeat => {
            let period = i.rem_euclid(2 * n);
            (if period < n {
                period
            } else {
                2 * n - 1 - period
            }) as usize
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4×4 checker of 0 and 1 texels (texel (0, 0) is 1).
    fn checker(sampler: Sampler) -> Texture {
        let texels = (0..16)
            .map(|i| Vec4::splat(((i % 4 + i / 4) % 2 == 0) as u32 as f32))
            .collect();
        Texture::from_linear(4, 4, texels)
            .unwrap()
            .with_sampler(sampler)
    }

    #[test]
    fn nearest_returns_the_texel_containing_the_point() {
        let t = checker(Sampler::unfiltered(Filter::Nearest, Wrap::Repeat));
        for (x, y) in [(0, 0), (1, 0), (2, 3), (3, 3)] {
            let expected = ((x + y) % 2 == 0) as u32 as f32;
            // Anywhere inside the texel, right up to its edges.
            for (fx, fy) in [(0.01, 0.01), (0.5, 0.5), (0.99, 0.2)] {
                let uv = Vec2::new((x as f32 + fx) / 4.0, (y as f32 + fy) / 4.0);
                assert_eq!(t.sample(uv).x, expected, "texel ({x}, {y}) at {uv}");
            }
        }
    }

    #[test]
    fn linear_interpolates_between_texel_centres() {
        let t = Texture::from_linear(2, 1, vec![Vec4::ZERO, Vec4::ONE])
            .unwrap()
            .with_sampler(Sampler::unfiltered(Filter::Linear, Wrap::ClampToEdge));
        assert!((t.sample(Vec2::new(0.25, 0.5)).x - 0.0).abs() < 1e-6);
        assert!((t.sample(Vec2::new(0.375, 0.5)).x - 0.25).abs() < 1e-6);
        assert!((t.sample(Vec2::new(0.5, 0.5)).x - 0.5).abs() < 1e-6);
        assert!((t.sample(Vec2::new(0.75, 0.5)).x - 1.0).abs() < 1e-6);
        assert!((t.sample(Vec2::new(5.0, 0.5)).x - 1.0).abs() < 1e-6);
        // With REPEAT the left edge blends the last texel with the first.
        let t = t.with_sampler(Sampler::unfiltered(Filter::Linear, Wrap::Repeat));
        assert!((t.sample(Vec2::new(0.0, 0.5)).x - 0.5).abs() < 1e-6);
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap_index(-1, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap_index(9, 4, Wrap::ClampToEdge), 3);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap_index(8, 4, Wrap::MirroredRepeat), 0);
        // Through a texture: u = 1.1 wraps to texel 0 (REPEAT), stays on texel 3 (CLAMP), mirrors onto texel 3.
        let ramp: Vec<Vec4> = (0..4).map(|i| Vec4::splat(i as f32)).collect();
        let t = |wrap| {
            Texture::from_linear(4, 1, ramp.clone())
                .unwrap()
                .with_sampler(Sampler::unfiltered(Filter::Nearest, wrap))
                .sample(Vec2::new(1.1, 0.5))
                .x
        };
        assert_eq!(t(Wrap::Repeat), 0.0);
        assert_eq!(t(Wrap::ClampToEdge), 3.0);
        assert_eq!(t(Wrap::MirroredRepeat), 3.0);
    }

    #[test]
    fn pyramid_levels_keep_the_mean_for_odd_sizes_too() {
        for (w, h) in [(8, 8), (5, 3), (7, 1), (1, 6)] {
            let texels: Vec<Vec4> = (0..w * h)
                .map(|i| Vec4::splat((i * 37 % 11) as f32))
                .collect();
            let mean = texels.iter().map(|t| t.x as f64).sum::<f64>() / (w * h) as f64;
            let image = MipImage::new(w, h, texels).unwrap();
            let top = image.levels.last().unwrap();
            assert_eq!((top.width, top.height), (1, 1), "{w}x{h}");
            for level in &image.levels {
                let m = level.texels.iter().map(|t| t.x as f64).sum::<f64>()
                    / level.texels.len() as f64;
                assert!(
                    (m - mean).abs() < 1e-5 * mean.max(1.0),
                    "{w}x{h}: {m} vs {mean}"
                );
            }
        }
    }

    #[test]
    fn minification_picks_levels_by_the_footprint() {
        // A 4×4 checker: level 1 (2×2) and level 2 (1×1) are uniformly 0.5.
        let mip_linear = checker(Sampler::default());
        let uv = Vec2::new(0.1, 0.1);
        // No footprint: magnification, bilinear on the full image.
        assert_eq!(
            mip_linear.lookup(TexCoord::point(uv)),
            mip_linear.sample(uv)
        );
        // A footprint of one texel (λ = 0) still reads level 0; two texels (λ = 1) read level 1 only.
        let one_texel = TexCoord {
            uv: Vec2::new(0.125, 0.125),
            footprint: 0.25,
        };
        assert_eq!(mip_linear.lookup(one_texel).x, 1.0);
        let two_texels = TexCoord {
            uv: Vec2::new(0.125, 0.125),
            footprint: 0.5,
        };
        assert!((mip_linear.lookup(two_texels).x - 0.5).abs() < 1e-6);
        // λ = 0.5 blends level 0 (1 at that texel's centre) and level 1 (0.5) halfway.
        let between = TexCoord {
            uv: Vec2::new(0.125, 0.125),
            footprint: 0.25 * 2f32.sqrt(),
        };
        assert!((mip_linear.lookup(between).x - 0.75).abs() < 1e-5);
        // MIPMAP_NEAREST rounds λ = 0.5 down to level 0; λ = 0.6 up to level 1.
        let mip_nearest = checker(Sampler {
            mip: Some(Filter::Nearest),
            ..Sampler::default()
        });
        assert_eq!(mip_nearest.lookup(between).x, 1.0);
        let above = TexCoord {
            footprint: 0.25 * 2f32.powf(0.6),
            ..between
        };
        assert!((mip_nearest.lookup(above).x - 0.5).abs() < 1e-6);
        // Without mip-mapping, minification reads the full image with the min filter whatever the footprint.
        let no_mips = checker(Sampler {
            min: Filter::Nearest,
            mip: None,
            ..Sampler::default()
        });
        let far = TexCoord {
            uv: Vec2::new(0.3, 0.1),
            footprint: 100.0,
        };
        assert_eq!(no_mips.lookup(far).x, 0.0);
        // A huge footprint clamps to the last level.
        assert!((mip_linear.lookup(far).x - 0.5).abs() < 1e-6);
    }

    #[test]
    fn srgb_decoding() {
        let t = Texture::from_rgba8(1, 1, &[255, 128, 0, 255], ColorSpace::Srgb).unwrap();
        let v = t.sample(Vec2::splat(0.5));
        assert!((v.x - 1.0).abs() < 1e-6 && (v.y - 0.2158).abs() < 1e-3 && v.z == 0.0);
        assert!(Texture::from_rgba8(2, 2, &[0; 4], ColorSpace::Linear).is_none());
    }
}
