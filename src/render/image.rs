//! The render output image: the beauty pass, its alpha and its arbitrary output variables (AOVs).

use super::aovs::FirstHit;
use super::cryptomatte::{CryptoKind, Manifest};
use crate::math::{Rgb, Vec3};
use std::collections::BTreeMap;

/// One layer beyond the beauty, alpha and first-hit layers (a light-path layer, a colour, a light group, the
/// shadow catcher, a Cryptomatte rank layer), one buffer per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct AovLayer {
    /// The layer's name (`diffuse_direct`, `lg_key`, `CryptoObject00`).
    pub name: String,
    /// The channels' names within the layer (`R`, `G`, `B`; Cryptomatte's `r`, `g`, `b`, `a`).
    pub components: &'static [&'static str],
    /// One buffer per channel, row-major from the top row.
    pub data: Vec<Vec<f32>>,
    /// Whether the layer may be stored as half floats (`--half`); never for Cryptomatte, whose IDs are the
    /// bits of 32-bit floats.
    pub allows_half: bool,
}

impl AovLayer {
    /// A zero-filled RGB layer of `n` pixels.
    pub fn rgb(name: &str, n: usize) -> Self {
        Self {
            name: name.to_owned(),
            components: &["R", "G", "B"],
            data: vec![vec![0.0; n]; 3],
            allows_half: true,
        }
    }

    /// A zero-filled Cryptomatte rank layer of `n` pixels.
    pub fn cryptomatte(name: &str, n: usize) -> Self {
        Self {
            name: name.to_owned(),
            components: &["r", "g", "b", "a"],
            data: vec![vec![0.0; n]; 4],
            allows_half: false,
        }
    }

    /// The layer's RGB pixels (for an RGB layer).
    pub fn rgb_pixels(&self) -> Vec<Rgb> {
        (0..self.data.first().map_or(0, Vec::len))
            .map(|i| Rgb::new(self.data[0][i], self.data[1][i], self.data[2][i]))
            .collect()
    }
}

/// What the EXR header says about the render beyond its pixels: the OpenEXR standard camera attributes and
/// Nimbus's own `nimbus/` attributes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImageMetadata {
    /// `worldToCamera` (see [`crate::scene::Camera::exr_world_to_camera`]).
    pub world_to_camera: Option<[[f32; 4]; 4]>,
    /// `worldToNDC` (see [`crate::scene::Camera::exr_world_to_ndc`]).
    pub world_to_ndc: Option<[[f32; 4]; 4]>,
    /// `nimbus/<key>` text attributes: `spp`, `seed`, `render_seconds`, `scene`, `scene_hash`, `frame`...
    pub nimbus: BTreeMap<String, String>,
}

impl ImageMetadata {
    /// The header attributes of a render of `scene` with `settings`, as `nimbus render` and the Python module
    /// write them: the camera's `worldToCamera` and `worldToNDC`, and the `nimbus/` keys `spp` (of the whole
    /// render), `seed`, `scene` (`scene_label`: the file, or what the scene came from), `scene_hash`,
    /// `transparent`, `frame` (when given) and `render_seconds` (left out when `SOURCE_DATE_EPOCH` asks for
    /// reproducible files).
    pub fn for_render(
        scene: &crate::scene::Scene,
        settings: &super::RenderSettings,
        scene_label: &str,
        frame: Option<i64>,
        scene_hash: u64,
        stats: &super::RenderStats,
    ) -> Self {
        let aspect = settings.width as f32 / settings.height.max(1) as f32;
        let mut nimbus = BTreeMap::new();
        nimbus.insert("spp".to_owned(), settings.spp.to_string());
        nimbus.insert("seed".to_owned(), settings.seed.to_string());
        nimbus.insert("scene".to_owned(), scene_label.to_owned());
        nimbus.insert("scene_hash".to_owned(), format!("{scene_hash:016x}"));
        nimbus.insert("transparent".to_owned(), stats.transparent.to_string());
        if let Some(f) = frame {
            nimbus.insert("frame".to_owned(), f.to_string());
        }
        if std::env::var_os("SOURCE_DATE_EPOCH").is_none() {
            nimbus.insert(
                "render_seconds".to_owned(),
                format!("{:.3}", stats.render_seconds),
            );
        }
        Self {
            world_to_camera: Some(scene.camera().exr_world_to_camera()),
            world_to_ndc: Some(scene.camera().exr_world_to_ndc(aspect)),
            nimbus,
        }
    }
}

/// A rendered image with its AOVs, one value per pixel in every buffer.
///
/// All buffers are row-major with `width * height` entries; row 0 is the top of the image and column 0
/// its left edge, so pixel `(x, y)` lives at [`RenderImage::pixel_index`]`(x, y) = y * width + x`.
///
/// The AOVs:
/// - `beauty`: linear Rec.709 RGB radiance, the mean of all samples taken in the pixel.
/// - `albedo`: linear RGB albedo of the first surface hit by the camera ray (zero where nothing was hit).
/// - `normal`: world-space unit shading normal at the first surface hit (zero where nothing was hit).
/// - `depth`: distance along the camera ray from the camera to the first hit, in scene units; `0` where
///   nothing was hit (never infinity, which EXR viewers and compositors handle badly).
/// - `variance`: per-channel estimated variance of the beauty mean, i.e. the sample variance of the
///   pixel's samples divided by the sample count `N`; its square root is the standard error of `beauty`.
/// - `alpha`: coverage (see [`super::aovs`]); `aovs`: the light-path, colour, light-group, shadow-catcher and
///   Cryptomatte layers the render's plan wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderImage {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Linear RGB radiance, the per-pixel mean of the samples.
    pub beauty: Vec<Rgb>,
    /// Linear RGB albedo of the first surface hit; zero for no hit.
    pub albedo: Vec<Rgb>,
    /// World-space normal at the first surface hit; zero for no hit.
    pub normal: Vec<Vec3>,
    /// Camera distance to the first hit; `0` for no hit.
    pub depth: Vec<f32>,
    /// Per-channel variance of the beauty mean (sample variance / sample count).
    pub variance: Vec<Rgb>,
    /// Coverage: the mean over the pixel's samples of 1 − the camera ray's transmittance to the environment
    /// (see [`super::aovs`]).
    pub alpha: Vec<f32>,
    /// The first-hit layers written (all four by default).
    pub first_hit: Vec<FirstHit>,
    /// The other layers written, in order.
    pub aovs: Vec<AovLayer>,
    /// The Cryptomatte kinds written, with their manifests.
    pub cryptomatte: Vec<(CryptoKind, Manifest)>,
    /// Header attributes.
    pub metadata: ImageMetadata,
    /// The deep samples, when deep output is on.
    pub deep: Option<super::deep::DeepImage>,
}

impl RenderImage {
    /// A `width` × `height` image with every buffer zero-filled.
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            beauty: vec![Rgb::ZERO; n],
            albedo: vec![Rgb::ZERO; n],
            normal: vec![Vec3::ZERO; n],
            depth: vec![0.0; n],
            variance: vec![Rgb::ZERO; n],
            alpha: vec![0.0; n],
            first_hit: FirstHit::ALL.to_vec(),
            aovs: Vec::new(),
            cryptomatte: Vec::new(),
            metadata: ImageMetadata::default(),
            deep: None,
        }
    }

    /// The layer `name` of [`aovs`](Self::aovs), if written.
    pub fn aov(&self, name: &str) -> Option<&AovLayer> {
        self.aovs.iter().find(|l| l.name == name)
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width * self.height
    }

    /// Index into every buffer of pixel `(x, y)`, with `y = 0` the top row.
    pub fn pixel_index(&self, x: usize, y: usize) -> usize {
        debug_assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        y * self.width + x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_is_zero_filled_and_sized() {
        let img = RenderImage::new(4, 3);
        assert_eq!(img.pixel_count(), 12);
        for len in [
            img.beauty.len(),
            img.albedo.len(),
            img.normal.len(),
            img.depth.len(),
            img.variance.len(),
        ] {
            assert_eq!(len, 12);
        }
        assert!(img
            .beauty
            .iter()
            .chain(&img.variance)
            .all(|c| *c == Rgb::ZERO));
        assert!(img.depth.iter().all(|d| *d == 0.0));
    }

    #[test]
    fn pixel_index_is_row_major_from_the_top() {
        let img = RenderImage::new(4, 3);
        assert_eq!(img.pixel_index(0, 0), 0);
        assert_eq!(img.pixel_index(3, 0), 3);
        assert_eq!(img.pixel_index(0, 1), 4);
        assert_eq!(img.pixel_index(3, 2), 11);
    }
}
