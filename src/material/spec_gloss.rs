//! `KHR_materials_pbrSpecularGlossiness` (the archived Khronos extension, superseded by
//! `KHR_materials_specular`; spec: github.com/KhronosGroup/glTF, `extensions/2.0/Archived/
//! KHR_materials_pbrSpecularGlossiness/README.md`) read as the metallic-roughness model the renderer has.
//!
//! The extension gives a diffuse colour `d` (`diffuseFactor` × `diffuseTexture`, alpha included), a specular
//! colour `s` (`specularFactor` × the RGB of `specularGlossinessTexture`) and a glossiness `g`
//! (`glossinessFactor` × its alpha). Its shading model has the diffuse reflectance `d · (1 − max(s))`, the
//! Fresnel reflectance at normal incidence `s`, and the GGX α `(1 − g)²`; so roughness is `1 − g`.
//!
//! The metallic-roughness model (glTF 2.0 Appendix B) has the diffuse reflectance `b · (1 − 0.04) · (1 − m)`
//! and the normal-incidence reflectance `0.04 · (1 − m) + b · m` for base colour `b` and metalness `m`. The
//! conversion ([`to_metallic_roughness`]) solves for `m` and `b` as the Khronos converter of the extension's
//! examples does (`examples/convert-between-workflows`, beside the spec; the glTF-Sample-Viewer and
//! gltf-pipeline era): written here from the following derivation, not from its code.
//!
//! 1. Colours are reduced to one number by their perceived brightness `P(c) = √(0.299 r² + 0.587 g² + 0.114
//!    b²)` (the HSP colour model, Darel Rex Finley 2006). Let `D = P(d) · (1 − max(s))` (the diffuse
//!    reflectance) and `S = P(s)`.
//! 2. From `D = b · 0.96 · (1 − m)`, `b = D / (0.96 (1 − m))`; putting it into `S = 0.04 (1 − m) + b m` and
//!    multiplying by `1 − m` gives the quadratic `0.04 m² + (D / 0.96 + S − 0.08) m + (0.04 − S) = 0`. Its
//!    larger root, clamped to \[0, 1\], is `m`; a specular below the dielectric 0.04 means `m = 0`.
//! 3. Each channel of `b` has two readings: from the diffuse, `d · (1 − max(s)) / (0.96 (1 − m))`, and from
//!    the specular, `(s − 0.04 (1 − m)) / m`. They are blended by `m²` (the diffuse reading where the surface
//!    is mostly dielectric, the specular one where it is mostly metal) and clamped to \[0, 1\].
//!
//! The conversion is exact for pure dielectrics (`s` = 0.04 grey: `m` = 0, `b` = `d`) and pure metals (`d`
//! black: `m` = 1, `b` = `s`), and approximate between (a coloured specular over a coloured diffuse has no
//! exact metallic-roughness equivalent). Nimbus evaluates it where the material is shaded, on the filtered
//! texels of each texture read through its own sampler, UV set and `KHR_texture_transform`, rather than baking
//! new textures at load time: the two textures of the extension may differ in size, sampler and mapping, so a
//! baked pair would need one common parameterisation that the file does not have.

use super::surface::TextureId;
use crate::math::{Rgb, Vec4};

/// The dielectric reflectance at normal incidence both models assume (ior 1.5).
const DIELECTRIC_F0: f32 = 0.04;

/// Smallest divisor of the base-colour readings (the diffuse one at `m` = 1, the specular one at `m` = 0).
const EPSILON: f32 = 1e-6;

/// The parameters of `KHR_materials_pbrSpecularGlossiness` on a material. When a [`super::Material`] has them,
/// they replace its base colour, metalness and roughness (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpecularGlossiness {
    /// `diffuseFactor`: linear RGB and alpha, each in \[0, 1\] (default 1).
    pub diffuse: Vec4,
    /// `diffuseTexture` (sRGB colour, linear alpha): multiplies `diffuse`.
    pub diffuse_texture: Option<TextureId>,
    /// `specularFactor`: linear RGB in \[0, 1\] (default 1).
    pub specular: Rgb,
    /// `glossinessFactor` in \[0, 1\] (default 1).
    pub glossiness: f32,
    /// `specularGlossinessTexture`: its RGB (sRGB) multiplies `specular`, its alpha (linear) `glossiness`.
    pub specular_glossiness_texture: Option<TextureId>,
}

impl Default for SpecularGlossiness {
    /// The extension's defaults: white diffuse, white specular, glossiness 1, no textures.
    fn default() -> Self {
        Self {
            diffuse: Vec4::ONE,
            diffuse_texture: None,
            specular: Rgb::ONE,
            glossiness: 1.0,
            specular_glossiness_texture: None,
        }
    }
}

/// A point of the metallic-roughness model: what [`to_metallic_roughness`] returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// Linear base colour, each channel in \[0, 1\].
    pub base_color: Rgb,
    /// Metalness in \[0, 1\].
    pub metallic: f32,
    /// Perceptual roughness in \[0, 1\].
    pub roughness: f32,
}

/// Perceived brightness of a linear colour, `√(0.299 r² + 0.587 g² + 0.114 b²)` (the HSP colour model).
fn perceived_brightness(c: Rgb) -> f32 {
    (0.299 * c.x * c.x + 0.587 * c.y * c.y + 0.114 * c.z * c.z).sqrt()
}

/// Converts a specular-glossiness point (diffuse colour, specular colour, glossiness; linear, in \[0, 1\]) to
/// metallic-roughness by the solve of the module documentation. Inputs outside \[0, 1\] are clamped first.
pub fn to_metallic_roughness(diffuse: Rgb, specular: Rgb, glossiness: f32) -> MetallicRoughness {
    let d = diffuse.clamp(Rgb::ZERO, Rgb::ONE);
    let s = specular.clamp(Rgb::ZERO, Rgb::ONE);
    let one_minus_strength = 1.0 - s.max_element();
    let diffuse_brightness = perceived_brightness(d) * one_minus_strength;
    let specular_brightness = perceived_brightness(s);
    let metallic = if specular_brightness < DIELECTRIC_F0 {
        0.0
    } else {
        // 0.04 m² + b m + c = 0 (step 2); the larger root. c ≤ 0 here, so the discriminant is at least b².
        let a = DIELECTRIC_F0;
        let b =
            diffuse_brightness / (1.0 - DIELECTRIC_F0) + specular_brightness - 2.0 * DIELECTRIC_F0;
        let c = DIELECTRIC_F0 - specular_brightness;
        let discriminant = (b * b - 4.0 * a * c).max(0.0);
        ((discriminant.sqrt() - b) / (2.0 * a)).clamp(0.0, 1.0)
    };
    let from_diffuse =
        d * (one_minus_strength / (1.0 - DIELECTRIC_F0) / (1.0 - metallic).max(EPSILON));
    let from_specular = (s - Rgb::splat(DIELECTRIC_F0 * (1.0 - metallic))) / metallic.max(EPSILON);
    let base_color = from_diffuse
        .lerp(from_specular, metallic * metallic)
        .clamp(Rgb::ZERO, Rgb::ONE);
    MetallicRoughness {
        base_color,
        metallic,
        roughness: (1.0 - glossiness).clamp(0.0, 1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() < 1e-5
    }

    #[test]
    fn grey_brightness_is_the_grey_level() {
        // 0.299 + 0.587 + 0.114 = 1.
        assert!(close(perceived_brightness(Rgb::splat(0.3)), 0.3));
    }

    #[test]
    fn a_specular_below_the_dielectric_f0_is_a_dielectric() {
        let mr = to_metallic_roughness(Rgb::splat(0.5), Rgb::splat(0.02), 0.25);
        assert_eq!(mr.metallic, 0.0);
        assert!(close(mr.roughness, 0.75));
        // b = d · 0.98 / 0.96.
        assert!(close(mr.base_color.x, 0.5 * 0.98 / 0.96), "{mr:?}");
    }

    #[test]
    fn out_of_range_inputs_are_clamped() {
        let mr = to_metallic_roughness(Rgb::splat(2.0), Rgb::splat(-1.0), 3.0);
        assert!(mr.base_color.max_element() <= 1.0 && mr.metallic == 0.0 && mr.roughness == 0.0);
    }
}
