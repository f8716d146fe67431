//! The multi-layer OpenEXR writer and a generic reader.
//!
//! [`write_exr`] writes one single-part scanline file with Nuke-style channel names in one flat, alphabetically
//! sorted channel list: every channel the image writes ([`RenderImage::channel_list`]: `R`, `G`, `B`, `A`,
//! `albedo.R`..., `diffuse_direct.R`..., `lg_key.R`..., `CryptoObject00.r`...). OpenEXR and Nuke split such
//! names at the last `.` into layer and channel. [`ExrOptions`] choose the compression (ZIP by default, 16 lines
//! per block) and whether colour layers are stored as half floats.
//!
//! The header carries:
//! - the OpenEXR standard attributes `software` (`Nimbus <version>`), `capDate` (`YYYY:MM:DD hh:mm:ss`, UTC, with
//!   `utcOffset` 0; from `SOURCE_DATE_EPOCH` when that is set, for reproducible files), and, when the image's
//!   [`ImageMetadata`](crate::render::ImageMetadata) has them, `worldToCamera` and `worldToNDC`;
//! - `nimbus/version` and the image's `nimbus/<key>` text attributes (spp, seed, render seconds, scene, scene
//!   hash, frame);
//! - for each Cryptomatte kind, `cryptomatte/<key>/name`, `hash`, `conversion` and `manifest` (see
//!   [`crate::render::cryptomatte`]).

use super::{validate, OutputError};
use crate::math::Rgb;
use crate::render::cryptomatte::manifest_json;
use crate::render::{ChannelKind, RenderImage};
use ::exr::meta::attribute::{AttributeValue, Text};
use ::exr::prelude::{
    f16, read, AnyChannel, AnyChannels, Compression, Encoding, FlatSamples, Image, Layer,
    LayerAttributes, LineOrder, ReadChannels, ReadLayers, WritableImage,
};
use ::exr::prelude::{SmallVec, Vec2};
use std::collections::BTreeMap;
use std::path::Path;

/// The compression of an EXR file (`--compression`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExrCompression {
    /// Lossless zlib, 16 lines per block (OpenEXR's ZIP).
    #[default]
    Zip,
    /// Lossless wavelet (OpenEXR's PIZ): often smaller for noisy images.
    Piz,
    /// 32-bit floats rounded to 24 bits, then zlib: lossy for `float` channels (refused with Cryptomatte,
    /// whose IDs are the bits of 32-bit floats).
    Pxr24,
    /// Lossy 4×4 blocks for half-float channels (others stored as they are).
    B44,
    /// Lossless run lengths.
    Rle,
    /// No compression.
    None,
}

impl crate::params::Choice for ExrCompression {
    const CHOICES: &'static [(&'static str, Self)] = &[
        ("zip", Self::Zip),
        ("piz", Self::Piz),
        ("pxr24", Self::Pxr24),
        ("b44", Self::B44),
        ("rle", Self::Rle),
        ("none", Self::None),
    ];
}

impl ExrCompression {
    /// The `exr` crate's compression.
    fn to_exr(self) -> Compression {
        match self {
            ExrCompression::Zip => Compression::ZIP16,
            ExrCompression::Piz => Compression::PIZ,
            ExrCompression::Pxr24 => Compression::PXR24,
            ExrCompression::B44 => Compression::B44,
            ExrCompression::Rle => Compression::RLE,
            ExrCompression::None => Compression::Uncompressed,
        }
    }
}

/// Which channels `--half` stores as 16-bit floats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HalfFloats {
    /// Every channel 32-bit.
    #[default]
    Off,
    /// The colour layers beyond the beauty (albedo, normal, light paths, colours, light groups, shadow catcher);
    /// the beauty, depth, variance and Cryptomatte stay 32-bit.
    Aovs,
    /// The beauty and its alpha too.
    All,
}

impl crate::params::Choice for HalfFloats {
    const CHOICES: &'static [(&'static str, Self)] =
        &[("off", Self::Off), ("aovs", Self::Aovs), ("all", Self::All)];
}

/// How [`write_exr_with`] stores an image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExrOptions {
    /// The compression.
    pub compression: ExrCompression,
    /// Which channels are half floats.
    pub half: HalfFloats,
}

/// The channels of an EXR file as 32-bit floats, keyed by full channel name (`"R"`, `"albedo.R"`, ...).
#[derive(Clone, Debug, PartialEq)]
pub struct ExrLayers {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Channel name → row-major samples (row 0 at the top), `width * height` of them.
    pub channels: BTreeMap<String, Vec<f32>>,
}

impl ExrLayers {
    /// The samples of channel `name`, if the file has it.
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels.get(name).map(Vec::as_slice)
    }

    /// The three channels `prefix` + `R`/`G`/`B` as RGB pixels (`prefix` is `""` for the beauty,
    /// `"albedo."` or `"variance."` for those layers); `None` when one is missing.
    pub fn rgb(&self, prefix: &str) -> Option<Vec<Rgb>> {
        let r = self.channel(&format!("{prefix}R"))?;
        let g = self.channel(&format!("{prefix}G"))?;
        let b = self.channel(&format!("{prefix}B"))?;
        Some(
            r.iter()
                .zip(g)
                .zip(b)
                .map(|((&r, &g), &b)| Rgb::new(r, g, b))
                .collect(),
        )
    }
}

/// Writes `image` to `path` as a single-part multi-layer scanline EXR, ZIP compressed, every channel 32-bit
/// (see the module docs for the channel names and header). Non-finite samples are written as they are.
pub fn write_exr(image: &RenderImage, path: &Path) -> Result<(), OutputError> {
    write_exr_with(image, path, &ExrOptions::default())
}

/// Writes `image` to `path` as [`write_exr`] does, with the compression and half floats of `options`.
/// `Pxr24` is refused for an image with Cryptomatte layers.
pub fn write_exr_with(
    image: &RenderImage,
    path: &Path,
    options: &ExrOptions,
) -> Result<(), OutputError> {
    validate(image, path)?;
    if options.compression == ExrCompression::Pxr24 && !image.cryptomatte.is_empty() {
        return Err(OutputError::Invalid {
            path: path.to_path_buf(),
            reason: "--compression pxr24 rounds 32-bit floats to 24 bits, which destroys Cryptomatte IDs; \
                     use zip, piz, rle or none"
                .into(),
        });
    }
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = image
        .channel_list()
        .into_iter()
        .map(|c| {
            let half = match c.kind {
                ChannelKind::Beauty => options.half == HalfFloats::All,
                ChannelKind::Color => options.half != HalfFloats::Off,
                ChannelKind::Data => false,
            };
            if half {
                let samples = c.samples.iter().map(|&v| f16::from_f32(v)).collect();
                samples_channel(&c.name, FlatSamples::F16(samples))
            } else {
                channel(&c.name, c.samples)
            }
        })
        .collect();
    let encoding = Encoding {
        compression: options.compression.to_exr(),
        line_order: LineOrder::Increasing,
        ..Encoding::SMALL_LOSSLESS
    };
    let layer = Layer::new(
        Vec2(image.width, image.height),
        header_attributes(image),
        encoding,
        AnyChannels::sort(list),
    );
    write_sorted(&Image::from_layer(layer), path)
}

/// Writes a single-part image to `path` (atomically, see [`super::write_atomically`]) with its header attributes
/// in name order, as the OpenEXR library
/// writes them: the `exr` crate keeps custom attributes in a hash map, whose order changes from process to
/// process, and files of the same image must be the same bytes (a merged render is compared with a single one).
pub(crate) fn write_sorted(
    image: &Image<Layer<AnyChannels<FlatSamples>>>,
    path: &Path,
) -> Result<(), OutputError> {
    let exr_error = |source| OutputError::Exr {
        path: path.to_path_buf(),
        source,
    };
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write().to_buffered(&mut bytes).map_err(exr_error)?;
    let mut bytes = bytes.into_inner();
    sort_header_attributes(&mut bytes);
    super::write_atomically(path, &bytes).map_err(|e| exr_error(::exr::error::Error::from(e)))
}

/// Sorts the attributes of a single-part file's header by name, in place (the header keeps its length, so
/// the offset table and chunks stay where they are). Files of another layout are left as they are.
fn sort_header_attributes(bytes: &mut [u8]) {
    // Magic number and version field; bit 12 of the version marks a multi-part file.
    if bytes.len() < 8 || bytes[5] & 0x10 != 0 {
        return;
    }
    let nul =
        |from: usize, bytes: &[u8]| bytes[from..].iter().position(|&b| b == 0).map(|n| from + n);
    let mut attributes: Vec<(Vec<u8>, std::ops::Range<usize>)> = Vec::new();
    let mut at = 8;
    loop {
        let Some(name_end) = nul(at, bytes) else {
            return;
        };
        if name_end == at {
            break;
        }
        let Some(type_end) = nul(name_end + 1, bytes) else {
            return;
        };
        let Some(size) = bytes.get(type_end + 1..type_end + 5) else {
            return;
        };
        let size = u32::from_le_bytes([size[0], size[1], size[2], size[3]]) as usize;
        let end = type_end + 5 + size;
        if end > bytes.len() {
            return;
        }
        attributes.push((bytes[at..name_end].to_vec(), at..end));
        at = end;
    }
    let start = 8;
    let mut sorted = attributes.clone();
    sorted.sort_by(|a, b| a.0.cmp(&b.0));
    let header: Vec<u8> = sorted
        .iter()
        .flat_map(|(_, range)| bytes[range.clone()].to_vec())
        .collect();
    bytes[start..at].copy_from_slice(&header);
}

/// The header attributes of `image` (see the module docs).
fn header_attributes(image: &RenderImage) -> LayerAttributes {
    let text = |t: &str| Text::new_or_none(t).unwrap_or_else(|| Text::from("?"));
    let mut attributes = LayerAttributes {
        software_name: Some(text(&format!("Nimbus {}", env!("CARGO_PKG_VERSION")))),
        capture_date: Some(text(&capture_date())),
        utc_offset: Some(0.0),
        world_to_camera: image.metadata.world_to_camera.map(flatten),
        world_to_normalized_device: image.metadata.world_to_ndc.map(flatten),
        ..LayerAttributes::default()
    };
    let mut put = |key: String, value: &str| {
        attributes
            .other
            .insert(text(&key), AttributeValue::Text(text(value)));
    };
    put("nimbus/version".into(), env!("CARGO_PKG_VERSION"));
    for (key, value) in &image.metadata.nimbus {
        put(format!("nimbus/{key}"), value);
    }
    for (kind, manifest) in &image.cryptomatte {
        let prefix = format!("cryptomatte/{}", kind.metadata_key());
        put(format!("{prefix}/name"), kind.layer_name());
        put(format!("{prefix}/hash"), "MurmurHash3_32");
        put(format!("{prefix}/conversion"), "uint32_to_float32");
        put(format!("{prefix}/manifest"), &manifest_json(manifest));
    }
    attributes
}

/// A row-major 4×4 matrix as OpenEXR's `m44f` stores it.
fn flatten(m: [[f32; 4]; 4]) -> [f32; 16] {
    std::array::from_fn(|i| m[i / 4][i % 4])
}

/// `capDate`: `SOURCE_DATE_EPOCH` (seconds since 1970, the reproducible-builds convention) when set, else now;
/// as `YYYY:MM:DD hh:mm:ss` in UTC.
fn capture_date() -> String {
    let seconds = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<i64>().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs() as i64)
        });
    format_utc(seconds)
}

/// `YYYY:MM:DD hh:mm:ss` of `seconds` after 1970-01-01 00:00:00 UTC (the proleptic Gregorian calendar's
/// civil date of a day count, after Hinnant's "chrono-Compatible Low-Level Date Algorithms").
fn format_utc(seconds: i64) -> String {
    let (days, secs) = (seconds.div_euclid(86_400), seconds.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}:{month:02}:{day:02} {:02}:{:02}:{:02}",
        secs / 3600,
        secs % 3600 / 60,
        secs % 60
    )
}

/// A full-resolution f32 channel. `pLinear` is left off, as the OpenEXR library does by default: it tells the
/// lossy B44 compressor that the values are linear light, which it then quantises in a perceptual (log) space.
fn channel(name: &str, samples: Vec<f32>) -> AnyChannel<FlatSamples> {
    samples_channel(name, FlatSamples::F32(samples))
}

/// A full-resolution channel of `samples`, `pLinear` off (see [`channel`]).
fn samples_channel(name: &str, samples: FlatSamples) -> AnyChannel<FlatSamples> {
    AnyChannel {
        name: name.into(),
        sample_data: samples,
        quantize_linearly: false,
        sampling: Vec2(1, 1),
    }
}

/// Reads every part, channel and attribute of the EXR at `path`, at its largest resolution level (no deep
/// data), with the samples as stored. The headers are read first: samples that the data windows and channels
/// would decode to beyond the memory budget (the default, half the physical memory) are refused before they are
/// allocated, since a file of a few bytes can declare any size.
pub(crate) fn read_flat_image(path: &Path) -> Result<::exr::image::FlatImage, OutputError> {
    let invalid = |reason: String| OutputError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    crate::limits::refuse_pipes_and_sockets(path).map_err(|e| invalid(e.to_string()))?;
    let meta =
        ::exr::meta::MetaData::read_from_file(path, false).map_err(|source| OutputError::Exr {
            path: path.to_path_buf(),
            source,
        })?;
    let mut bytes = 0u64;
    for header in &meta.headers {
        let pixels = (header.layer_size.x() as u64).saturating_mul(header.layer_size.y() as u64);
        let per_pixel: u64 = header
            .channels
            .list
            .iter()
            .map(|c| c.sample_type.bytes_per_sample() as u64)
            .sum();
        bytes = bytes.saturating_add(pixels.saturating_mul(per_pixel));
    }
    crate::limits::Limits::default()
        .check(
            format_args!("the samples of {} EXR part(s)", meta.headers.len()),
            bytes,
        )
        .map_err(|e| invalid(e.to_string()))?;
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|source| OutputError::Exr {
            path: path.to_path_buf(),
            source,
        })
}

/// Reads every channel of every part of the EXR at `path` (largest resolution level, no deep data),
/// converting samples to `f32`. Channels of a named part are keyed `part_name.channel` unless the
/// channel name already starts with that prefix. All parts must share one size.
pub fn read_exr_layers(path: &Path) -> Result<ExrLayers, OutputError> {
    let image = read_flat_image(path)?;
    let invalid = |reason: String| OutputError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let first = image
        .layer_data
        .first()
        .ok_or_else(|| invalid("no layers".to_string()))?;
    let (width, height) = (first.size.x(), first.size.y());
    let mut channels = BTreeMap::new();
    for layer in &image.layer_data {
        if (layer.size.x(), layer.size.y()) != (width, height) {
            return Err(invalid(format!(
                "part size {}x{} differs from {width}x{height}",
                layer.size.x(),
                layer.size.y()
            )));
        }
        let prefix = layer
            .attributes
            .layer_name
            .as_ref()
            .map(|n| format!("{n}."));
        for channel in &layer.channel_data.list {
            let name = channel.name.to_string();
            let name = match &prefix {
                Some(p) if !name.starts_with(p.as_str()) => format!("{p}{name}"),
                _ => name,
            };
            let samples: Vec<f32> = match &channel.sample_data {
                FlatSamples::F32(v) => v.clone(),
                other => other.values().map(|s| s.to_f32()).collect(),
            };
            channels.insert(name, samples);
        }
    }
    Ok(ExrLayers {
        width,
        height,
        channels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    fn temp_path(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("nimbus-output-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    /// A 3x2 image whose every channel of every pixel holds a distinct value.
    fn distinct_image() -> RenderImage {
        let mut img = RenderImage::new(3, 2);
        for i in 0..img.pixel_count() {
            let f = i as f32;
            img.beauty[i] = Vec3::new(f + 0.1, f + 0.2, f + 0.3);
            img.albedo[i] = Vec3::new(f + 10.1, f + 10.2, f + 10.3);
            img.normal[i] = Vec3::new(f + 20.1, f + 20.2, f + 20.3);
            img.depth[i] = f + 30.5;
            img.variance[i] = Vec3::new(f + 40.1, f + 40.2, f + 40.3);
            img.alpha[i] = 1.0 / (1.0 + f);
        }
        img
    }

    #[test]
    fn round_trip_preserves_every_channel_name_and_value() {
        let img = distinct_image();
        let path = temp_path("round_trip.exr");
        write_exr(&img, &path).unwrap();
        let layers = read_exr_layers(&path).unwrap();
        assert_eq!((layers.width, layers.height), (3, 2));
        let names: Vec<&str> = layers.channels.keys().map(String::as_str).collect();
        assert_eq!(
            names,
            [
                "A",
                "B",
                "G",
                "R",
                "albedo.B",
                "albedo.G",
                "albedo.R",
                "depth.Z",
                "normal.X",
                "normal.Y",
                "normal.Z",
                "variance.B",
                "variance.G",
                "variance.R"
            ]
        );
        assert_eq!(layers.rgb("").unwrap(), img.beauty);
        assert_eq!(layers.rgb("albedo.").unwrap(), img.albedo);
        assert_eq!(layers.rgb("variance.").unwrap(), img.variance);
        for (c, axis) in ["X", "Y", "Z"].into_iter().enumerate() {
            let got = layers.channel(&format!("normal.{axis}")).unwrap();
            assert_eq!(got, img.normal.iter().map(|n| n[c]).collect::<Vec<_>>());
        }
        assert_eq!(layers.channel("depth.Z").unwrap(), img.depth.as_slice());
        assert_eq!(layers.channel("A").unwrap(), img.alpha.as_slice());
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn file_is_one_scanline_part_of_f32_zip_channels() {
        let path = temp_path("header.exr");
        write_exr(&distinct_image(), &path).unwrap();
        let meta = ::exr::meta::MetaData::read_from_file(&path, false).unwrap();
        assert_eq!(meta.headers.len(), 1);
        let header = &meta.headers[0];
        assert_eq!(header.blocks, ::exr::meta::BlockDescription::ScanLines);
        assert_eq!(header.compression, ::exr::compression::Compression::ZIP16);
        assert_eq!(header.channels.list.len(), 14);
        assert!(header
            .channels
            .list
            .iter()
            .all(|c| c.sample_type == ::exr::meta::attribute::SampleType::F32));
        assert!(header.channels.list.iter().all(|c| !c.quantize_linearly));
        let names: Vec<String> = header
            .channels
            .list
            .iter()
            .map(|c| c.name.to_string())
            .collect();
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(
            names, sorted,
            "EXR requires an alphabetically sorted channel list"
        );
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn layers_half_floats_compressions_and_header_attributes() {
        use crate::render::cryptomatte::{name_id, CryptoKind, Manifest};
        use crate::render::AovLayer;
        let mut img = distinct_image();
        let mut light = AovLayer::rgb("diffuse_direct", 6);
        let mut ids = AovLayer::cryptomatte("CryptoObject00", 6);
        for i in 0..6 {
            light.data[1][i] = 0.25 * i as f32;
            ids.data[0][i] = f32::from_bits(name_id("crate"));
            ids.data[1][i] = 0.5;
        }
        img.aovs = vec![light, ids];
        let manifest: Manifest = [("crate".to_string(), name_id("crate"))].into();
        img.cryptomatte = vec![(CryptoKind::Object, manifest)];
        let m = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [1.0, 2.0, 3.0, 1.0],
        ];
        img.metadata.world_to_camera = Some(m);
        img.metadata.nimbus.insert("spp".into(), "64".into());
        for (k, compression) in [
            ExrCompression::Zip,
            ExrCompression::Piz,
            ExrCompression::B44,
            ExrCompression::Rle,
            ExrCompression::None,
        ]
        .into_iter()
        .enumerate()
        {
            let half = [HalfFloats::Off, HalfFloats::Aovs, HalfFloats::All][k % 3];
            let path = temp_path(&format!("options_{k}.exr"));
            write_exr_with(&img, &path, &ExrOptions { compression, half }).unwrap();
            let meta = ::exr::meta::MetaData::read_from_file(&path, false).unwrap();
            let header = &meta.headers[0];
            assert_eq!(header.compression, compression.to_exr());
            let sample_type = |name: &str| {
                header
                    .channels
                    .list
                    .iter()
                    .find(|c| c.name.to_string() == name)
                    .map(|c| c.sample_type)
                    .unwrap()
            };
            use ::exr::meta::attribute::SampleType::{F16, F32};
            let aov_type = if half == HalfFloats::Off { F32 } else { F16 };
            let beauty_type = if half == HalfFloats::All { F16 } else { F32 };
            assert_eq!(sample_type("R"), beauty_type, "{compression:?} {half:?}");
            assert_eq!(sample_type("A"), beauty_type);
            assert_eq!(sample_type("albedo.G"), aov_type);
            assert_eq!(sample_type("diffuse_direct.G"), aov_type);
            assert_eq!(sample_type("depth.Z"), F32);
            assert_eq!(sample_type("variance.B"), F32);
            assert_eq!(sample_type("CryptoObject00.r"), F32);
            let attrs = &header.own_attributes;
            assert!(attrs
                .software_name
                .as_ref()
                .unwrap()
                .to_string()
                .starts_with("Nimbus "));
            let date = attrs.capture_date.as_ref().unwrap().to_string();
            assert_eq!(
                (date.len(), &date[4..5], &date[13..14]),
                (19, ":", ":"),
                "{date}"
            );
            assert_eq!(attrs.world_to_camera, Some(flatten(m)));
            let text = |key: &str| match attrs.other.get(&Text::from(key)) {
                Some(AttributeValue::Text(t)) => t.to_string(),
                other => panic!("{key}: {other:?}"),
            };
            assert_eq!(text("nimbus/spp"), "64");
            let key = CryptoKind::Object.metadata_key();
            assert_eq!(text(&format!("cryptomatte/{key}/name")), "CryptoObject");
            assert_eq!(text(&format!("cryptomatte/{key}/hash")), "MurmurHash3_32");
            assert_eq!(
                text(&format!("cryptomatte/{key}/manifest")),
                format!("{{\"crate\":\"{:08x}\"}}", name_id("crate"))
            );
            // IDs come back bit for bit, whatever the compression and half floats.
            let layers = read_exr_layers(&path).unwrap();
            let id = layers.channel("CryptoObject00.r").unwrap();
            assert!(id.iter().all(|v| v.to_bits() == name_id("crate")));
            let g = layers.channel("diffuse_direct.G").unwrap();
            assert!(g
                .iter()
                .enumerate()
                .all(|(i, &v)| (v - 0.25 * i as f32).abs() < 2e-3));
            std::fs::remove_file(&path).unwrap();
        }
        let path = temp_path("pxr24.exr");
        let options = ExrOptions {
            compression: ExrCompression::Pxr24,
            half: HalfFloats::Off,
        };
        let err = write_exr_with(&img, &path, &options).unwrap_err();
        assert!(err.to_string().contains("Cryptomatte"), "{err}");
        img.cryptomatte.clear();
        img.aovs.pop();
        write_exr_with(&img, &path, &options).unwrap();
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn capture_dates_are_utc_civil_dates() {
        assert_eq!(format_utc(0), "1970:01:01 00:00:00");
        assert_eq!(format_utc(951_782_400), "2000:02:29 00:00:00");
        assert_eq!(format_utc(1_796_316_000 + 3_723), "2026:12:03 17:42:03");
        assert_eq!(format_utc(-1), "1969:12:31 23:59:59");
    }

    #[test]
    fn reader_prefixes_part_names_once_and_widens_half_floats() {
        use ::exr::prelude::f16;
        let path = temp_path("two_parts.exr");
        let beauty = Layer::new(
            Vec2(2, 1),
            LayerAttributes::named("beauty"),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(SmallVec::from_vec(vec![channel("R", vec![0.5, 2.0])])),
        );
        let half = vec![f16::from_f32(0.25), f16::from_f32(-3.0)];
        let albedo = Layer::new(
            Vec2(2, 1),
            LayerAttributes::named("albedo"),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
                "albedo.G",
                FlatSamples::F16(half),
            )])),
        );
        Image::from_layers(
            ::exr::meta::header::ImageAttributes::with_size(Vec2(2, 1)),
            vec![beauty, albedo],
        )
        .write()
        .to_file(&path)
        .unwrap();
        let layers = read_exr_layers(&path).unwrap();
        assert_eq!(
            layers.channels.keys().collect::<Vec<_>>(),
            ["albedo.G", "beauty.R"]
        );
        assert_eq!(layers.channel("beauty.R").unwrap(), [0.5, 2.0]);
        assert_eq!(layers.channel("albedo.G").unwrap(), [0.25, -3.0]);
        assert_eq!(layers.rgb(""), None);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn rejects_mismatched_buffers_and_empty_images() {
        let path = temp_path("invalid.exr");
        let mut img = RenderImage::new(2, 2);
        img.depth.pop();
        let err = write_exr(&img, &path).unwrap_err();
        assert!(matches!(err, OutputError::Invalid { .. }));
        assert!(err.to_string().contains("depth") && err.to_string().contains("invalid.exr"));
        assert!(matches!(
            write_exr(&RenderImage::new(0, 4), &path),
            Err(OutputError::Invalid { .. })
        ));
        assert!(!path.exists());
    }

    #[test]
    fn reading_a_missing_file_names_it() {
        let path = temp_path("does_not_exist.exr");
        let err = read_exr_layers(&path).unwrap_err();
        assert!(matches!(err, OutputError::Exr { .. }));
        assert!(err.to_string().contains("does_not_exist.exr"));
    }
}
