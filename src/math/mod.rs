//! Math foundations shared by every other module: glam re-exports, rays, bounds, orthonormal frames,
//! floating-point error bounds, sampling warps, tabulated distributions, the deterministic random-number
//! generator and RGB helpers.

mod bounds;
#[cfg(test)]
pub(crate) mod chi2;
mod distribution;
mod float;
mod frame;
mod ray;
mod rng;
#[cfg(feature = "testing")]
pub mod sampling;
#[cfg(not(feature = "testing"))]
pub(crate) mod sampling;
#[cfg(feature = "testing")]
pub mod sobol;
#[cfg(not(feature = "testing"))]
pub(crate) mod sobol;
internal! {
    pub use bounds::Aabb;
    pub use distribution::{Distribution1D, Distribution2D};
    pub use float::gamma;
    pub use frame::Frame;
}
pub use glam::{Mat3, Mat4, Quat, Vec2, Vec3, Vec4};
internal! {
    pub use ray::Ray;
    pub use rng::{hash_to_unit, Rng};
}

/// Linear RGB radiance, reflectance or throughput. Channels are (R, G, B) in linear Rec.709 primaries.
pub type Rgb = Vec3;

internal! {
    /// The wavelength, in nanometres, at which the spectrally dependent materials evaluate each RGB channel (the
    /// dispersion of `KHR_materials_dispersion` and the thin-film interference of `KHR_materials_iridescence`):
    /// the dominant wavelengths of the Rec.709/sRGB primaries seen against the D65 white point (CIE 1931
    /// chromaticity diagram: the line from D65 through each primary meets the spectral locus at about 611.3 nm,
    /// 549.1 nm and 464.3 nm).
    pub const RGB_WAVELENGTHS_NM: [f32; 3] = [611.3, 549.1, 464.3];
}

internal! {
    /// Relative luminance of a linear Rec.709 colour (ITU-R BT.709 weights).
    pub fn luminance(c: Rgb) -> f32 {
        0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
    }
}

internal! {
    /// Converts one sRGB-encoded channel in \[0, 1\] to linear (IEC 61966-2-1).
    pub fn srgb_to_linear(v: f32) -> f32 {
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    }
}

internal! {
    /// Converts one linear channel to its sRGB encoding (IEC 61966-2-1); the input is clamped to \[0, 1\].
    pub fn linear_to_srgb(v: f32) -> f32 {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.003_130_8 {
            v * 12.92
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    }
}

internal! {
    /// True when every channel is finite.
    pub fn is_finite_rgb(c: Rgb) -> bool {
        c.x.is_finite() && c.y.is_finite() && c.z.is_finite()
    }
}
