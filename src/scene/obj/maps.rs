//! MTL texture files: finding them (paths relative to the MTL file, Windows separators, case-insensitive
//! fallback, a bare file name next to the MTL), decoding them within the memory budget, and making the
//! [`Texture`]s each statement feeds.
//!
//! - `map_Kd`, `map_Ke`: sRGB colour textures.
//! - `norm`: a tangent-space normal map (glTF's convention: +X right, +Y up in the image), read linearly.
//! - `map_d`: coverage from the `-imfchan` channel, by default the alpha channel of an image that has one and
//!   the luminance of one that has none, stored in the first channel.
//! - `map_Bump` / `bump`: a height map (the `-imfchan` channel, by default luminance, read linearly), turned into
//!   a tangent-space normal map at load time, because the material model perturbs normals only through normal
//!   maps. Central differences give the height's slope per texel, `-bm` multiplies it, and the normal is
//!   `normalize(−bm·∂h/∂x, −bm·∂h/∂y, 1)` with x to the right and y up the image: a height step of 1 (the full
//!   range) over one texel tilts the normal by 45° at `-bm 1`. This is the per-texel convention of
//!   height-to-normal converters; the strength of pbrt's or Cycles' bump mapping, whose heights are scene
//!   lengths, is not reproduced. An image that is already a normal map (bluish: mean blue above 0.7, mean red
//!   and green near ½, and coloured) is read as the normal map it is, with a warning, as exporters often write
//!   normal maps as `map_Bump`.
//!
//! `-clamp on` makes a texture clamp to its edge instead of repeating; `-o` and `-s` move and scale the texture
//! coordinates of the meshes using the material (see [`super::load`]).

use super::mtl::{MapKind, TextureMap};
use super::QUOTE_CHARS;
use crate::limits::{one_line, read_file, Limits};
use crate::material::{ColorSpace, MipImage, Sampler, Texture, Wrap};
use crate::math::{Vec3, Vec4};
use crate::scene::MalformedPart;
use crate::scene::{SceneBuilder, SceneError, SceneErrorKind};
use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use std::sync::Arc;

/// Makes and caches the textures of MTL statements.
pub(super) struct TextureMaps<'a> {
    limits: &'a Limits,
    /// Decoded images by file.
    images: HashMap<PathBuf, Arc<image::DynamicImage>>,
    /// Texture ids by file, what they feed, the bump multiplier's bits, the channel and the clamp.
    textures: HashMap<(PathBuf, MapKind, u32, Option<char>, bool), u32>,
}

impl<'a> TextureMaps<'a> {
    /// An empty cache reading files within `limits`.
    pub fn new(limits: &'a Limits) -> Self {
        Self {
            limits,
            images: HashMap::new(),
            textures: HashMap::new(),
        }
    }

    /// The texture for `map` of the MTL file `mtl`, added to `builder`; `Ok(None)` with a builder warning when
    /// its file is missing. An unreadable or undecodable file is an error naming it.
    pub fn texture(
        &mut self,
        mtl: &Path,
        map: &TextureMap,
        builder: &mut SceneBuilder,
    ) -> Result<Option<u32>, SceneError> {
        let Some(kind) = map.kind else {
            return Ok(None);
        };
        let base = mtl.parent().unwrap_or(Path::new(""));
        let Some(file) = resolve(base, &map.file) else {
            builder.warn(format!(
                "{}: line {}: {} texture '{}' not found; the material is untextured there",
                mtl.display(),
                map.line,
                map.key,
                one_line(&map.file, QUOTE_CHARS)
            ));
            return Ok(None);
        };
        let key = (
            file.clone(),
            kind,
            map.bump_multiplier.to_bits(),
            map.channel,
            map.clamp,
        );
        if let Some(&id) = self.textures.get(&key) {
            return Ok(Some(id));
        }
        let image = self.image(mtl, map, &file)?;
        let wrap = if map.clamp {
            Wrap::ClampToEdge
        } else {
            Wrap::Repeat
        };
        let sampler = Sampler {
            wrap_s: wrap,
            wrap_t: wrap,
            ..Sampler::default()
        };
        let mip = mip_image(mtl, map, kind, &image, wrap, builder).ok_or_else(|| {
            SceneError::new(
                &file,
                SceneErrorKind::malformed(MalformedPart::Texture, "the image is empty"),
            )
        })?;
        let id = builder.add_texture(Texture::new(Arc::new(mip), sampler));
        self.textures.insert(key, id);
        Ok(Some(id))
    }

    /// The decoded image of `file`, read once.
    fn image(
        &mut self,
        mtl: &Path,
        map: &TextureMap,
        file: &Path,
    ) -> Result<Arc<image::DynamicImage>, SceneError> {
        if let Some(image) = self.images.get(file) {
            return Ok(image.clone());
        }
        let context = |e: String| {
            SceneError::new(
                file,
                SceneErrorKind::malformed(
                    MalformedPart::Texture,
                    format!(
                        "{} (named by {} line {})",
                        one_line(&e, 200),
                        mtl.file_name()
                            .map_or_else(String::new, |f| f.to_string_lossy().into_owned()),
                        map.line
                    ),
                ),
            )
        };
        let bytes = read_file(file, self.limits).map_err(|e| context(e.to_string()))?;
        // The RGBA8 copy and the float mip pyramid (16 bytes a texel, 4/3 for the levels) stay in the budget.
        let image = crate::limits::decode_image(&bytes, self.limits, 4 + 22)
            .map_err(|e| context(e.to_string()))?;
        let image = Arc::new(image);
        self.images.insert(file.to_path_buf(), image.clone());
        Ok(image)
    }
}

/// The mip-mapped image of `map` (of kind `kind`, in the MTL file `mtl`) from its decoded `image`: colour
/// maps as sRGB, normal maps as linear data, a dissolve map's channel as grey, a bump map's heights made
/// normals (or, when it looks like a normal map, read as one with a warning); `None` for an empty image.
fn mip_image(
    mtl: &Path,
    map: &TextureMap,
    kind: MapKind,
    image: &image::DynamicImage,
    wrap: Wrap,
    builder: &mut SceneBuilder,
) -> Option<MipImage> {
    let rgba = image.to_rgba8();
    let (w, h) = (rgba.width() as usize, rgba.height() as usize);
    match kind {
        MapKind::Diffuse | MapKind::Emission => {
            MipImage::from_rgba8(w, h, rgba.as_raw(), ColorSpace::Srgb)
        }
        MapKind::Normal => MipImage::from_rgba8(w, h, rgba.as_raw(), ColorSpace::Linear),
        MapKind::Dissolve => {
            let channel = map
                .channel
                .unwrap_or(if image.color().has_alpha() { 'm' } else { 'l' });
            let texels = scalars(&rgba, channel)
                .map(|c| Vec4::new(c, c, c, 1.0))
                .collect();
            MipImage::new(w, h, texels)
        }
        MapKind::Bump => {
            let linear = MipImage::from_rgba8(w, h, rgba.as_raw(), ColorSpace::Linear);
            if map.channel.is_none() && looks_like_normal_map(&rgba) {
                builder.warn(format!(
                    "{}: line {}: {} image '{}' is a tangent-space normal map (bluish), not a height map; read \
                     as a normal map",
                    mtl.display(),
                    map.line,
                    map.key,
                    one_line(&map.file, QUOTE_CHARS)
                ));
                linear
            } else {
                let heights: Vec<f32> = scalars(&rgba, map.channel.unwrap_or('l')).collect();
                MipImage::new(
                    w,
                    h,
                    height_to_normals(&heights, w, h, map.bump_multiplier, wrap),
                )
            }
        }
    }
}

/// The file an MTL statement names: `name` with `\` read as a separator, relative to `base` (an absolute path
/// as it is), then the same with each component matched case-insensitively, then the bare file name next to
/// the MTL file (for absolute paths from the exporter's machine, like `C:\Users\...\wood.jpg`).
fn resolve(base: &Path, name: &str) -> Option<PathBuf> {
    let name = name.replace('\\', "/");
    let path = Path::new(&name);
    let exact = base.join(path);
    if exact.is_file() {
        return Some(exact);
    }
    if let Some(found) = case_insensitive(base, path) {
        return Some(found);
    }
    let file_name = path.file_name()?;
    case_insensitive(base, Path::new(file_name))
}

/// `rel` under `base`, each component matched exactly or, failing that, ignoring ASCII case.
fn case_insensitive(base: &Path, rel: &Path) -> Option<PathBuf> {
    let mut current = base.to_path_buf();
    for component in rel.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => current.push(".."),
            Component::Normal(part) => {
                let exact = current.join(part);
                if exact.exists() {
                    current = exact;
                    continue;
                }
                let part = part.to_str()?;
                let entry = std::fs::read_dir(&current)
                    .ok()?
                    .filter_map(Result::ok)
                    .find(|e| {
                        e.file_name()
                            .to_str()
                            .is_some_and(|f| f.eq_ignore_ascii_case(part))
                    })?;
                current = entry.path();
            }
            Component::RootDir | Component::Prefix(_) => return None,
        }
    }
    current.is_file().then_some(current)
}

/// One linear value per texel from `channel`: `r`, `g`, `b`, `m` (alpha) or `l`/`z` (Rec. 709 luminance).
fn scalars(rgba: &image::RgbaImage, channel: char) -> impl Iterator<Item = f32> + '_ {
    rgba.pixels().map(move |p| {
        let [r, g, b, a] = p.0.map(|v| v as f32 / 255.0);
        match channel {
            'r' => r,
            'g' => g,
            'b' => b,
            'm' => a,
            _ => 0.2126 * r + 0.7152 * g + 0.0722 * b,
        }
    })
}

/// True when the image is coloured with a bluish mean near (½, ½, 1): an encoded tangent-space normal map.
fn looks_like_normal_map(rgba: &image::RgbaImage) -> bool {
    let n = (rgba.width() as f64 * rgba.height() as f64).max(1.0);
    let (mut mean, mut chroma) = ([0f64; 3], 0f64);
    for p in rgba.pixels() {
        let [r, g, b, _] = p.0.map(|v| v as f64 / 255.0);
        mean[0] += r / n;
        mean[1] += g / n;
        mean[2] += b / n;
        chroma += ((r - g).abs() + (g - b).abs()) / n;
    }
    mean[2] > 0.7 && (mean[0] - 0.5).abs() < 0.15 && (mean[1] - 0.5).abs() < 0.15 && chroma > 0.1
}

/// Encoded tangent-space normals (`n·½ + ½`, glTF's convention) of the height field `heights` (row-major, top
/// row first), from central differences per texel scaled by `strength`; neighbours beyond the edge wrap or
/// clamp as the texture does.
fn height_to_normals(heights: &[f32], w: usize, h: usize, strength: f32, wrap: Wrap) -> Vec<Vec4> {
    let at = |x: isize, y: isize| {
        let (x, y) = match wrap {
            Wrap::ClampToEdge => (x.clamp(0, w as isize - 1), y.clamp(0, h as isize - 1)),
            _ => (x.rem_euclid(w as isize), y.rem_euclid(h as isize)),
        };
        heights[y as usize * w + x as usize]
    };
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h as isize {
        for x in 0..w as isize {
            let right = (at(x + 1, y) - at(x - 1, y)) * 0.5;
            // Rows run down the image; +y of the normal map is up.
            let up = (at(x, y - 1) - at(x, y + 1)) * 0.5;
            let n = Vec3::new(-strength * right, -strength * up, 1.0).normalize();
            out.push((n * 0.5 + Vec3::splat(0.5)).extend(1.0));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_height_ramp_up_the_image_tilts_normals_down() {
        // Heights grow toward the top row (row 0): the surface rises "up" the image, the normal leans to −y.
        let heights: Vec<f32> = (0..4).flat_map(|y| [1.0 - y as f32 * 0.25; 4]).collect();
        let n = height_to_normals(&heights, 4, 4, 1.0, Wrap::ClampToEdge)[5];
        let n = n.truncate() * 2.0 - Vec3::ONE;
        let expect = Vec3::new(0.0, -0.25, 1.0).normalize();
        assert!((n - expect).length() < 1e-6, "{n}");
    }
}
