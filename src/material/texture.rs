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
//! Each texture also carries its UV mapping, as pbrt-v4's image textures carry a `TextureMapping2D`: which
//! texture-coordinate set it reads (glTF `textureInfo.texCoord`, `TEXCOORD_0` or `TEXCOORD_1`) and the
//! `KHR_texture_transform` applied to it ([`UvTransform`]). Textures that share an image share its pixels
//! whatever their samplers and mappings.
//!
//! The mip pyramid halves each dimension per level (rounding down, at least 1) with an exact box filter: every
//! texel of a level is the area-weighted mean of the finer texels it covers, so every level keeps the image
//! mean.

use crate::math::{srgb_to_linear, Vec2, Vec4};
use std::sync::Arc;

/// The number of texture-coordinate sets a mesh may carry (glTF `TEXCOORD_0` and `TEXCOORD_1`).
pub const UV_SETS: usize = 2;

/// A `KHR_texture_transform`: texture coordinates are mapped by `uv' = T · R · S · uv` (the extension's
/// specification, "Overview"): scaled, then rotated by `rotation` radians counter-clockwise in the image as
/// seen (the matrix `[[cos, sin], [−sin, cos]]` on (u, v), v running down the image), then offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// `offset`: added last. Default (0, 0).
    pub offset: Vec2,
    /// `rotation` in radians. Default 0.
    pub rotation: f32,
    /// `scale`: applied first. Default (1, 1).
    pub scale: Vec2,
}

impl Default for UvTransform {
    /// The identity.
    fn default() -> Self {
        Self {
            offset: Vec2::ZERO,
            rotation: 0.0,
            scale: Vec2::ONE,
        }
    }
}

impl UvTransform {
    /// `T · R · S · uv`.
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y) + self.offset
    }

    /// How much the transform stretches lengths on average, `√|sx · sy|` (rotations and offsets keep them): a
    /// footprint in the untransformed coordinates times this is one in the transformed coordinates.
    pub fn footprint_scale(&self) -> f32 {
        (self.scale.x * self.scale.y).abs().sqrt()
    }

    /// True for the identity.
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }
}

/// What a material reads at a surface point: the texture coordinates of each set, each with its filter
/// footprint, and the interpolated vertex colour (glTF `COLOR_0`; white without one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingPoint {
    /// Texture coordinates of `TEXCOORD_0` and `TEXCOORD_1` (zero where the mesh lacks the set).
    pub uv: [TexCoord; UV_SETS],
    /// Linear RGBA vertex colour.
    pub color: Vec4,
}

impl From<TexCoord> for ShadingPoint {
    /// `tc` for every texture-coordinate set and a white vertex colour.
    fn from(tc: TexCoord) -> Self {
        Self {
            uv: [tc; UV_SETS],
            color: Vec4::ONE,
        }
    }
}

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
    #[cfg(any(test, feature = "testing"))]
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
    #[cfg(any(test, feature = "testing"))]
    pub fn width(&self) -> usize {
        self.levels[0].width
    }

    /// Height of the full-resolution image.
    #[cfg(any(test, feature = "testing"))]
    pub fn height(&self) -> usize {
        self.levels[0].height
    }

    /// Number of levels, the full-resolution image included.
    #[cfg(test)]
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Bytes held by the texels of every level.
    #[cfg(any(test, feature = "testing"))]
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

/// A texture: a shared image, the sampler one glTF texture reads it with, and its UV mapping (the
/// texture-coordinate set and transform of the `textureInfo` that refers to it).
#[derive(Clone, Debug)]
pub struct Texture {
    image: Arc<MipImage>,
    sampler: Sampler,
    uv_set: usize,
    transform: UvTransform,
}

impl Texture {
    /// A texture reading `image` with `sampler`, from `TEXCOORD_0` untransformed.
    pub fn new(image: Arc<MipImage>, sampler: Sampler) -> Self {
        Self {
            image,
            sampler,
            uv_set: 0,
            transform: UvTransform::default(),
        }
    }

    /// Sets the UV mapping: the texture-coordinate set read (below [`UV_SETS`]; larger values read the last
    /// set) and the transform applied to it.
    pub fn with_mapping(mut self, uv_set: usize, transform: UvTransform) -> Self {
        self.uv_set = uv_set.min(UV_SETS - 1);
        self.transform = transform;
        self
    }

    /// The texture-coordinate set the texture reads.
    pub fn uv_set(&self) -> usize {
        self.uv_set
    }

    /// The transform applied to the texture coordinates.
    #[cfg(any(test, feature = "testing"))]
    pub fn transform(&self) -> UvTransform {
        self.transform
    }

    /// Maps texture coordinates of the texture's set through its transform; the footprint scales with it.
    pub fn map(&self, tc: TexCoord) -> TexCoord {
        if self.transform.is_identity() {
            return tc;
        }
        TexCoord {
            uv: self.transform.apply(tc.uv),
            footprint: tc.footprint * self.transform.footprint_scale(),
        }
    }

    /// The filtered value at a shading point: its texture coordinates of this texture's set, mapped (see
    /// [`Texture::map`]), then [`Texture::lookup`].
    pub fn lookup_at(&self, at: &ShadingPoint) -> Vec4 {
        self.lookup(self.map(at.uv[self.uv_set]))
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
    #[cfg(any(test, feature = "testing"))]
    pub fn with_sampler(mut self, sampler: Sampler) -> Self {
        self.sampler = sampler;
        self
    }

    /// The sampler.
    #[cfg(any(test, feature = "testing"))]
    pub fn sampler(&self) -> Sampler {
        self.sampler
    }

    /// The image.
    #[cfg(any(test, feature = "testing"))]
    pub fn image(&self) -> &Arc<MipImage> {
        &self.image
    }

    /// Image width in texels.
    #[cfg(any(test, feature = "testing"))]
    pub fn width(&self) -> usize {
        self.image.width()
    }

    /// Image height in texels.
    #[cfg(any(test, feature = "testing"))]
    pub fn height(&self) -> usize {
        self.image.height()
    }

    /// Bytes held by the image (shared images count in full for each texture).
    #[cfg(any(test, feature = "testing"))]
    pub fn memory_bytes(&self) -> usize {
        self.image.memory_bytes()
    }

    /// The value at texture coordinates `uv` of the full-resolution image, with the magnification filter
    /// (`uv` is read as given: the texture's mapping is not applied).
    #[cfg(any(test, feature = "testing"))]
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        self.lookup(TexCoord::point(uv))
    }

    /// The filtered value over the footprint `tc` (OpenGL's minification and magnification rules); `tc` is
    /// read as given (see [`Texture::lookup_at`] for the mapped lookup).
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
        match filter {
            Filter::Nearest => {
                let column = wrap_index(x.floor() as i64, l.width, self.sampler.wrap_s);
                let row = wrap_index(y.floor() as i64, l.height, self.sampler.wrap_t);
                l.texels[row * l.width + column]
            }
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                // The two columns and two rows are wrapped once per pair, not once per texel.
                let (left, right) = wrap_pair(x0, l.width, self.sampler.wrap_s);
                let (top_row, bottom_row) = wrap_pair(y0, l.height, self.sampler.wrap_t);
                let (top_row, bottom_row) = (top_row * l.width, bottom_row * l.width);
                let top = l.texels[top_row + left].lerp(l.texels[top_row + right], fx);
                let bottom = l.texels[bottom_row + left].lerp(l.texels[bottom_row + right], fx);
                top.lerp(bottom, fy)
            }
        }
    }
}

/// The wrapped indices of `i` and `i + 1` along an axis of `n` texels: for [`Wrap::Repeat`] the second comes
/// from the first without a second integer division (the second measured 1.0 % of the render instructions of
/// the peer benchmark's glass scene, whose floor is textured); the same as two [`wrap_index`]es.
fn wrap_pair(i: i64, n: usize, wrap: Wrap) -> (usize, usize) {
    match wrap {
        Wrap::Repeat => {
            let first = wrap_index(i, n, wrap);
            (first, if first + 1 == n { 0 } else { first + 1 })
        }
        _ => (wrap_index(i, n, wrap), wrap_index(i + 1, n, wrap)),
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

    #[test]
    fn wrap_pair_is_two_wrap_indices() {
        for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
            for n in 1..6 {
                for i in -20..20 {
                    let expected = (wrap_index(i, n, wrap), wrap_index(i + 1, n, wrap));
                    assert_eq!(wrap_pair(i, n, wrap), expected, "{wrap:?} n {n} i {i}");
                }
            }
        }
    }

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
    fn uv_transform_is_translation_rotation_scale_in_that_order() {
        // The extension's three matrices (row-major in its text), composed by hand as glam column-major
        // matrices: T · R · S.
        let (offset, rotation, scale) = (Vec2::new(0.25, -0.5), 0.7f32, Vec2::new(1.5, 0.5));
        let t =
            glam::Mat3::from_cols_array(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, offset.x, offset.y, 1.0]);
        let (sin, cos) = rotation.sin_cos();
        let r = glam::Mat3::from_cols_array(&[cos, -sin, 0.0, sin, cos, 0.0, 0.0, 0.0, 1.0]);
        let s = glam::Mat3::from_diagonal(glam::Vec3::new(scale.x, scale.y, 1.0));
        let m = t * r * s;
        let x = UvTransform {
            offset,
            rotation,
            scale,
        };
        for uv in [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::new(0.3, 0.8)] {
            let expected = (m * uv.extend(1.0)).truncate();
            assert!(x.apply(uv).distance(expected) < 1e-6, "{uv}");
        }
        // A quarter turn takes +u to −v.
        let quarter = UvTransform {
            rotation: std::f32::consts::FRAC_PI_2,
            ..Default::default()
        };
        assert!(quarter.apply(Vec2::X).distance(Vec2::new(0.0, -1.0)) < 1e-6);
        assert!((x.footprint_scale() - 0.75f32.sqrt()).abs() < 1e-6);
        // Through a texture: the mapped lookup reads the transformed point and scales the footprint.
        let ramp: Vec<Vec4> = (0..4).map(|i| Vec4::splat(i as f32)).collect();
        let tex = Texture::from_linear(4, 1, ramp)
            .unwrap()
            .with_sampler(Sampler::unfiltered(Filter::Nearest, Wrap::ClampToEdge))
            .with_mapping(
                1,
                UvTransform {
                    offset: Vec2::new(0.5, 0.0),
                    ..Default::default()
                },
            );
        let at = ShadingPoint {
            uv: [
                TexCoord::point(Vec2::new(0.9, 0.5)),
                TexCoord {
                    uv: Vec2::new(0.1, 0.5),
                    footprint: 0.0,
                },
            ],
            color: Vec4::ONE,
        };
        assert_eq!(tex.lookup_at(&at).x, 2.0, "set 1, offset by 0.5");
    }

    #[test]
    fn srgb_decoding() {
        let t = Texture::from_rgba8(1, 1, &[255, 128, 0, 255], ColorSpace::Srgb).unwrap();
        let v = t.sample(Vec2::splat(0.5));
        assert!((v.x - 1.0).abs() < 1e-6 && (v.y - 0.2158).abs() < 1e-3 && v.z == 0.0);
        assert!(Texture::from_rgba8(2, 2, &[0; 4], ColorSpace::Linear).is_none());
    }
}
