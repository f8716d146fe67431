//! Texture references (`textureInfo`: `index`, `texCoord`, `extensions.KHR_texture_transform` with `offset`,
//! `rotation`, `scale`, `texCoord`), `textures[]` (`source`, `sampler`), `samplers[]` (`magFilter`,
//! `minFilter`, `wrapS`, `wrapT`) and `images[]` (`uri` or `bufferView`), decoded once per colour space within
//! the memory budget.

use super::{read_uri, Loader, QUOTE};
use crate::limits::one_line;
use crate::material::{ColorSpace, Filter, MipImage, Sampler, Texture, UvTransform, Wrap, UV_SETS};
use crate::math::Vec2;
use crate::scene::MalformedPart;
use crate::scene::{SceneError, SceneErrorKind};
use std::sync::Arc;

impl Loader<'_> {
    /// A texture of an extension object (a `textureInfo`), read into the scene, if present.
    pub(super) fn ext_texture(
        &mut self,
        ext: &serde_json::Map<String, serde_json::Value>,
        key: &str,
        space: ColorSpace,
        at: &str,
    ) -> Result<Option<u32>, SceneError> {
        match ext.get(key) {
            None => Ok(None),
            Some(v) => {
                let r = self.json_ref(v, &format!("{at}.{key}"))?;
                Ok(Some(self.texture_ref(&r, space)?))
            }
        }
    }

    /// The texture of a `textureInfo` the `gltf` crate parsed (`at` names it in errors), if the material or
    /// extension gives one.
    pub(super) fn info_texture(
        &mut self,
        info: Option<gltf::texture::Info>,
        space: ColorSpace,
        at: &str,
    ) -> Result<Option<u32>, SceneError> {
        match info {
            Some(info) => {
                let r = self.info_ref(&info, at)?;
                Ok(Some(self.texture_ref(&r, space)?))
            }
            None => Ok(None),
        }
    }

    /// A `textureInfo` given as JSON: `index`, `texCoord` and `extensions.KHR_texture_transform`.
    pub(super) fn json_ref(
        &self,
        value: &serde_json::Value,
        at: &str,
    ) -> Result<TexRef, SceneError> {
        let index = value.get("index").and_then(|i| i.as_u64()).ok_or_else(|| {
            self.malformed(
                MalformedPart::Texture,
                format!("{at}.index must be a texture index"),
            )
        })?;
        let tex_coord = match value.get("texCoord") {
            Some(t) => t
                .as_u64()
                .filter(|&t| t <= u32::MAX as u64)
                .ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Texture,
                        format!("{at}.texCoord must be a non-negative integer"),
                    )
                })? as u32,
            None => 0,
        };
        let extensions = value.get("extensions").and_then(|e| e.as_object());
        self.raw_ref(index as usize, tex_coord, extensions, at)
    }

    /// A texture reference from its texture index, `texCoord` and raw `extensions` object.
    pub(super) fn raw_ref(
        &self,
        texture: usize,
        tex_coord: u32,
        extensions: Option<&serde_json::Map<String, serde_json::Value>>,
        at: &str,
    ) -> Result<TexRef, SceneError> {
        if texture >= self.document.textures().len() {
            return Err(self.error(SceneErrorKind::InvalidReference(format!(
                "{at}: texture {texture} does not exist ({} textures)",
                self.document.textures().len()
            ))));
        }
        let mut r = TexRef {
            texture,
            tex_coord,
            transform: UvTransform::default(),
        };
        if let Some(t) = extensions.and_then(|e| e.get("KHR_texture_transform")) {
            let bad = || {
                self.malformed(
                    MalformedPart::Texture,
                    format!("{at}.extensions.KHR_texture_transform: {t}"),
                )
            };
            let pair = |key: &str, default: [f32; 2]| match t.get(key) {
                None => Some(default),
                Some(v) => {
                    let a = v.as_array().filter(|a| a.len() == 2)?;
                    Some([a[0].as_f64()? as f32, a[1].as_f64()? as f32])
                }
            };
            let offset = pair("offset", [0.0, 0.0]).ok_or_else(bad)?;
            let scale = pair("scale", [1.0, 1.0]).ok_or_else(bad)?;
            let rotation = match t.get("rotation") {
                None => 0.0,
                Some(v) => v.as_f64().ok_or_else(bad)? as f32,
            };
            if let Some(c) = t.get("texCoord") {
                r.tex_coord = c
                    .as_u64()
                    .filter(|&c| c <= u32::MAX as u64)
                    .ok_or_else(bad)? as u32;
            }
            r.transform = checked_transform(offset, rotation, scale).ok_or_else(bad)?;
        }
        Ok(r)
    }

    /// A core `textureInfo` (base colour, metallic-roughness, emissive) with its `KHR_texture_transform`.
    fn info_ref(&self, info: &gltf::texture::Info, at: &str) -> Result<TexRef, SceneError> {
        let mut r = self.raw_ref(info.texture().index(), info.tex_coord(), None, at)?;
        if let Some(t) = info.texture_transform() {
            r.transform =
                checked_transform(t.offset(), t.rotation(), t.scale()).ok_or_else(|| {
                    self.malformed(
                        MalformedPart::Texture,
                        format!("{at}.extensions.KHR_texture_transform holds a non-finite number"),
                    )
                })?;
            if let Some(c) = t.tex_coord() {
                r.tex_coord = c;
            }
        }
        Ok(r)
    }

    /// The scene texture for a texture reference: the glTF texture's image and sampler with the reference's
    /// UV set and transform, made once per distinct mapping.
    pub(super) fn texture_ref(&mut self, r: &TexRef, space: ColorSpace) -> Result<u32, SceneError> {
        if r.tex_coord as usize >= UV_SETS {
            self.builder.warnings.push(format!(
                "texture {} uses TEXCOORD_{}; only TEXCOORD_0 and TEXCOORD_1 are read (TEXCOORD_1 used)",
                r.texture, r.tex_coord
            ));
        }
        let set = (r.tex_coord as usize).min(UV_SETS - 1);
        let t = r.transform;
        let bits = [
            t.offset.x.to_bits(),
            t.offset.y.to_bits(),
            t.rotation.to_bits(),
            t.scale.x.to_bits(),
            t.scale.y.to_bits(),
        ];
        let key = (r.texture, space, set, bits);
        if let Some(&id) = self.texture_cache.get(&key) {
            return Ok(id);
        }
        let texture = self
            .document
            .textures()
            .nth(r.texture)
            .expect("texture index checked by raw_ref");
        // Each glTF texture pairs an image with its own sampler; textures sharing an image share its pixels.
        let image = self.mip_image(texture.source(), space)?;
        let t = Texture::new(image, sampler_of(&texture.sampler())).with_mapping(set, t);
        self.builder.textures.push(t);
        let id = (self.builder.textures.len() - 1) as u32;
        self.texture_cache.insert(key, id);
        Ok(id)
    }

    /// The decoded image with its mip pyramid, decoded once per colour space.
    fn mip_image(
        &mut self,
        image: gltf::Image,
        space: ColorSpace,
    ) -> Result<Arc<MipImage>, SceneError> {
        let key = (image.index(), space);
        if let Some(img) = self.images.get(&key) {
            return Ok(img.clone());
        }
        let index = image.index();
        let rgba = self.decode_image(image)?;
        let mip = MipImage::from_rgba8(
            rgba.width() as usize,
            rgba.height() as usize,
            rgba.as_raw(),
            space,
        )
        .ok_or_else(|| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Texture,
                format!("image {index} is empty"),
            ))
        })?;
        let mip = Arc::new(mip);
        self.images.insert(key, mip.clone());
        Ok(mip)
    }

    /// The RGBA8 pixels of an image (embedded in a buffer view, a data URI or a file), decoded within the
    /// memory budget.
    fn decode_image(&mut self, image: gltf::Image) -> Result<image::RgbaImage, SceneError> {
        let name = match image.source() {
            gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                format!("image {} ('{}')", image.index(), one_line(uri, QUOTE))
            }
            _ => format!("image {}", image.index()),
        };
        let bytes: Vec<u8> = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let buffer = &self.buffers[view.buffer().index()];
                let end = view.offset().checked_add(view.length());
                match end {
                    Some(end) if end <= buffer.len() => buffer[view.offset()..end].to_vec(),
                    _ => {
                        return Err(self.error(SceneErrorKind::InvalidReference(format!(
                            "{name}: buffer view {} runs past its buffer",
                            view.index()
                        ))))
                    }
                }
            }
            gltf::image::Source::Uri { uri, .. } => read_uri(uri, &self.base, &self.options.limits)
                .map_err(|e| {
                    self.error(SceneErrorKind::InvalidReference(format!("{name}: {e}")))
                })?,
        };
        let budget = self.options.limits;
        let malformed = |e: String| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Texture,
                format!("{name}: {}", one_line(&e, QUOTE)),
            ))
        };
        // The RGBA8 copy and the float mip pyramid (16 bytes a texel, 4/3 for the levels) stay in the budget.
        let decoded = crate::limits::decode_image(&bytes, &budget, 4 + 22)
            .map_err(|e| malformed(e.to_string()))?
            .to_rgba8();
        Ok(decoded)
    }
}

/// The sampler a glTF texture reads with: its wrap modes and filters, with glTF viewers' defaults (LINEAR
/// magnification, LINEAR_MIPMAP_LINEAR minification) where the file names none.
fn sampler_of(sampler: &gltf::texture::Sampler) -> Sampler {
    use gltf::texture::{MagFilter, MinFilter, WrappingMode};
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    let mag = match sampler.mag_filter() {
        Some(MagFilter::Nearest) => Filter::Nearest,
        Some(MagFilter::Linear) | None => Filter::Linear,
    };
    let (min, mip) = match sampler.min_filter() {
        Some(MinFilter::Nearest) => (Filter::Nearest, None),
        Some(MinFilter::Linear) => (Filter::Linear, None),
        Some(MinFilter::NearestMipmapNearest) => (Filter::Nearest, Some(Filter::Nearest)),
        Some(MinFilter::LinearMipmapNearest) => (Filter::Linear, Some(Filter::Nearest)),
        Some(MinFilter::NearestMipmapLinear) => (Filter::Nearest, Some(Filter::Linear)),
        Some(MinFilter::LinearMipmapLinear) | None => (Filter::Linear, Some(Filter::Linear)),
    };
    Sampler {
        wrap_s: wrap(sampler.wrap_s()),
        wrap_t: wrap(sampler.wrap_t()),
        mag,
        min,
        mip,
    }
}

/// A texture reference (glTF `textureInfo`): the glTF texture, its texture-coordinate set and its transform.
pub(super) struct TexRef {
    texture: usize,
    tex_coord: u32,
    transform: UvTransform,
}

/// A `KHR_texture_transform` from its fields, `None` if a number is not finite.
fn checked_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Option<UvTransform> {
    let finite = offset.iter().chain(&scale).all(|v| v.is_finite()) && rotation.is_finite();
    finite.then(|| UvTransform {
        offset: Vec2::from(offset),
        rotation,
        scale: Vec2::from(scale),
    })
}
