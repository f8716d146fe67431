//! Image textures: decoded once at load time to linear floating-point RGBA and sampled bilinearly.
//!
//! glTF keys read: `sampler.wrapS`, `sampler.wrapT` (REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT). Colour textures
//! (`baseColorTexture`, `emissiveTexture`) are decoded from sRGB; data textures (`metallicRoughnessTexture`,
//! `normalTexture`) are kept linear. The texture coordinate origin is the top-left of the image, as in glTF.

use crate::math::{srgb_to_linear, Vec2, Vec4};

/// How texture coordinates outside \[0, 1\] are mapped back into the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    /// Tile the image.
    Repeat,
    /// Repeat the edge texel.
    ClampToEdge,
    /// Tile with every other copy mirrored.
    MirroredRepeat,
}

/// Whether 8-bit texel values are sRGB-encoded colours or linear data.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorSpace {
    /// sRGB-encoded colour; decoded to linear on load (alpha stays linear).
    Srgb,
    /// Linear data (roughness, metalness, normals).
    Linear,
}

/// A decoded texture: linear RGBA texels, row 0 at the top (v = 0).
#[derive(Clone, Debug)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<Vec4>,
    wrap_s: Wrap,
    wrap_t: Wrap,
}

impl Texture {
    /// Builds a texture from 8-bit RGBA data, decoding colour channels per `space`.
    /// Returns `None` when `rgba8` does not hold `width × height` texels.
    pub fn from_rgba8(
        width: usize,
        height: usize,
        rgba8: &[u8],
        space: ColorSpace,
    ) -> Option<Texture> {
        if width == 0 || height == 0 || rgba8.len() != width.checked_mul(height)?.checked_mul(4)? {
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
        Some(Texture {
            width,
            height,
            texels,
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        })
    }

    /// Builds a texture from linear float RGBA texels (row-major, top row first).
    /// Returns `None` when the texel count does not match.
    pub fn from_linear(width: usize, height: usize, texels: Vec<Vec4>) -> Option<Texture> {
        (width > 0 && height > 0 && texels.len() == width * height).then_some(Texture {
            width,
            height,
            texels,
            wrap_s: Wrap::Repeat,
            wrap_t: Wrap::Repeat,
        })
    }

    /// Sets the wrap modes for u (s) and v (t).
    pub fn with_wrap(mut self, wrap_s: Wrap, wrap_t: Wrap) -> Self {
        self.wrap_s = wrap_s;
        self.wrap_t = wrap_t;
        self
    }

    /// Image width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Bytes held by the texels.
    pub fn memory_bytes(&self) -> usize {
        self.texels.len() * std::mem::size_of::<Vec4>()
    }

    /// The texel at integer coordinates after wrapping.
    fn texel(&self, x: i64, y: i64) -> Vec4 {
        let x = wrap_index(x, self.width, self.wrap_s);
        let y = wrap_index(y, self.height, self.wrap_t);
        self.texels[y * self.width + x]
    }

    /// Bilinear lookup at texture coordinates `uv` (texel centres at half-integers, as in OpenGL).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = self.texel(x0, y0).lerp(self.texel(x0 + 1, y0), fx);
        let bottom = self.texel(x0, y0 + 1).lerp(self.texel(x0 + 1, y0 + 1), fx);
        top.lerp(bottom, fy)
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
    fn bilinear_interpolates_between_texel_centres() {
        let t = Texture::from_linear(2, 1, vec![Vec4::ZERO, Vec4::ONE])
            .unwrap()
            .with_wrap(Wrap::ClampToEdge, Wrap::ClampToEdge);
        assert!((t.sample(Vec2::new(0.25, 0.5)).x - 0.0).abs() < 1e-6);
        assert!((t.sample(Vec2::new(0.5, 0.5)).x - 0.5).abs() < 1e-6);
        assert!((t.sample(Vec2::new(0.75, 0.5)).x - 1.0).abs() < 1e-6);
        assert!((t.sample(Vec2::new(5.0, 0.5)).x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn wrap_modes() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
    }

    #[test]
    fn srgb_decoding() {
        let t = Texture::from_rgba8(1, 1, &[255, 128, 0, 255], ColorSpace::Srgb).unwrap();
        let v = t.sample(Vec2::splat(0.5));
        assert!((v.x - 1.0).abs() < 1e-6 && (v.y - 0.2158).abs() < 1e-3 && v.z == 0.0);
        assert!(Texture::from_rgba8(2, 2, &[0; 4], ColorSpace::Linear).is_none());
    }
}
