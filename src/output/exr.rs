//! The multi-layer OpenEXR writer and a generic reader.
//!
//! [`write_exr`] writes one single-part scanline file, all channels 32-bit float, ZIP compressed (16 lines
//! per block), with Nuke-style channel names in one flat, alphabetically sorted channel list: every channel
//! of the output's channel table, [`crate::render::LAYERS`] (`R`, `G`, `B`, `A` = 1, `albedo.R`...,
//! `normal.X`..., `depth.Z`, `variance.R`...). OpenEXR and Nuke split such names at the last `.` into layer
//! and channel.

use super::{validate, OutputError};
use crate::math::Rgb;
use crate::render::RenderImage;
use ::exr::prelude::{
    read, AnyChannel, AnyChannels, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    ReadChannels, ReadLayers, WritableImage,
};
use ::exr::prelude::{SmallVec, Vec2};
use std::collections::BTreeMap;
use std::path::Path;

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

/// Writes `image` to `path` as a single-part multi-layer scanline EXR (see the module docs for the
/// channel names). Non-finite samples are written as they are.
pub fn write_exr(image: &RenderImage, path: &Path) -> Result<(), OutputError> {
    validate(image, path)?;
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = image
        .channels()
        .into_iter()
        .map(|(name, samples)| channel(&name, samples))
        .collect();

    let layer = Layer::new(
        Vec2(image.width, image.height),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|source| OutputError::Exr {
            path: path.to_path_buf(),
            source,
        })
}

/// A full-resolution f32 channel. `pLinear` is left off, as the OpenEXR library does by default; it only
/// guides the lossy B44 compressors, which this writer does not use.
fn channel(name: &str, samples: Vec<f32>) -> AnyChannel<FlatSamples> {
    AnyChannel {
        name: name.into(),
        sample_data: FlatSamples::F32(samples),
        quantize_linearly: false,
        sampling: Vec2(1, 1),
    }
}

/// Reads every part, channel and attribute of the EXR at `path`, at its largest resolution level (no deep
/// data), with the samples as stored.
pub(crate) fn read_flat_image(path: &Path) -> Result<::exr::image::FlatImage, OutputError> {
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
        assert!(layers.channel("A").unwrap().iter().all(|a| *a == 1.0));
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
