//! Part files: the EXR a `--samples`, `--crop` or `--chunk-from-env` render writes.
//!
//! A part is one scanline EXR part, ZIP compressed, whose data window is the crop (the whole frame without
//! `--crop`) and whose display window is the full frame. It holds:
//! - the float channels of an ordinary render (`R`, `G`, `B`, `A`, `albedo.*`, `normal.*`, `depth.Z`,
//!   `variance.*`) for the part's own samples, so any EXR viewer shows it;
//! - the exact sums of the film as 59 `uint` channels `nimbus.count`, `nimbus.sum.R.0` … (see
//!   [`PixelSums::WORD_NAMES`]): what the merge adds;
//! - header attributes (all text) with what a merge checks:
//!
//! | key | value |
//! |---|---|
//! | `nimbus.format` | `nimbus-part-1` |
//! | `nimbus.version` | the Nimbus version that rendered it |
//! | `nimbus.scene_hash` | 16 hex digits (see [`super::hash`]) |
//! | `nimbus.seed`, `nimbus.max_depth` | the render settings |
//! | `nimbus.spp` | samples per pixel of the whole render |
//! | `nimbus.samples` | this part's samples, `START..END` (END exclusive) |
//! | `nimbus.sample_count` | `END - START` |
//! | `nimbus.nan_samples`, `nimbus.clamped_samples` | the part's dropped and clamped samples |

use super::FarmError;
use crate::output::OutputError;
use crate::render::{
    Film, PixelSums, PixelWindow, RenderImage, RenderRegion, RenderSettings, RenderStats,
};
use ::exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use ::exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, ImageAttributes, Layer, LayerAttributes,
    SmallVec, Vec2, WritableImage,
};
use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

/// The value of `nimbus.format` in a part written by this version.
pub const PART_FORMAT: &str = "nimbus-part-1";
/// Prefix of the header keys and sum channels of a part.
const PREFIX: &str = "nimbus.";

/// What a part says about itself: everything a merge checks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartInfo {
    /// Version of Nimbus that rendered it.
    pub version: String,
    /// Scene hash (see [`super::hash`]).
    pub scene_hash: u64,
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Seed of the random streams.
    pub seed: u64,
    /// Maximum scattering events per path.
    pub max_depth: u32,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// The samples of each pixel this part holds.
    pub samples: Range<u32>,
    /// The pixels this part holds.
    pub window: PixelWindow,
    /// Samples dropped as NaN or infinite.
    pub nan_samples: u64,
    /// Samples clamped into the film's range.
    pub clamped_samples: u64,
}

impl PartInfo {
    /// The description of a finished render of `region` with `settings` (whose `spp` is the whole render's)
    /// and `stats`. Under a time limit the samples are the ones actually taken.
    pub fn new(
        settings: &RenderSettings,
        scene_hash: u64,
        region: &RenderRegion,
        stats: &RenderStats,
    ) -> Self {
        let start = region.samples.start;
        Self {
            version: env!("CARGO_PKG_VERSION").to_string(),
            scene_hash,
            width: settings.width,
            height: settings.height,
            seed: settings.seed,
            max_depth: settings.max_depth,
            spp: settings.spp,
            samples: start..start + stats.samples_per_pixel,
            window: region.window,
            nan_samples: stats.nan_samples,
            clamped_samples: stats.clamped_samples,
        }
    }

    /// The header attributes, keyed without the `nimbus.` prefix.
    fn keys(&self) -> Vec<(&'static str, String)> {
        vec![
            ("format", PART_FORMAT.to_string()),
            ("version", self.version.clone()),
            ("scene_hash", format!("{:016x}", self.scene_hash)),
            ("seed", self.seed.to_string()),
            ("max_depth", self.max_depth.to_string()),
            ("spp", self.spp.to_string()),
            (
                "samples",
                format!("{}..{}", self.samples.start, self.samples.end),
            ),
            ("sample_count", self.samples.len().to_string()),
            ("nan_samples", self.nan_samples.to_string()),
            ("clamped_samples", self.clamped_samples.to_string()),
        ]
    }
}

/// Writes `film` (a finished, uncancelled render) as the part `info` describes. The film's frame and window
/// must be `info`'s.
pub fn write_part(path: &Path, film: &Film, info: &PartInfo) -> Result<(), FarmError> {
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    if (film.width, film.height, film.window()) != (info.width, info.height, info.window) {
        return Err(invalid(format!(
            "film of {} in {}x{} does not match the part's crop {} in {}x{}",
            film.window(),
            film.width,
            film.height,
            info.window,
            info.width,
            info.height
        )));
    }
    if info.samples.is_empty() || info.samples.end > info.spp {
        return Err(invalid(format!(
            "samples {}..{} are not a non-empty range within {} spp",
            info.samples.start, info.samples.end, info.spp
        )));
    }
    let image = film.image();
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (name, samples) in image.channels() {
        list.push(AnyChannel::new(name.as_str(), FlatSamples::F32(samples)));
    }
    let words: Vec<[u32; PixelSums::WORDS]> = film.pixels().iter().map(|p| p.to_words()).collect();
    for (k, name) in PixelSums::WORD_NAMES.iter().enumerate() {
        let samples = words.iter().map(|w| w[k]).collect();
        list.push(AnyChannel::new(
            format!("{PREFIX}{name}").as_str(),
            FlatSamples::U32(samples),
        ));
    }
    let mut attributes = LayerAttributes {
        layer_position: Vec2(to_i32(info.window.x0), to_i32(info.window.y0)),
        ..LayerAttributes::default()
    };
    for (key, value) in info.keys() {
        let text = Text::new_or_none(&value)
            .ok_or_else(|| invalid(format!("{key} '{value}' is not plain text")))?;
        attributes.other.insert(
            Text::from(format!("{PREFIX}{key}").as_str()),
            AttributeValue::Text(text),
        );
    }
    let layer = Layer::new(
        Vec2(info.window.width(), info.window.height()),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let display = IntegerBounds::from_dimensions(Vec2(info.width, info.height));
    Image::from_layers(ImageAttributes::new(display), vec![layer])
        .write()
        .to_file(path)
        .map_err(|source| OutputError::Exr {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(())
}

/// Pixel coordinates fit `i32` for every frame the renderer can hold; saturate rather than wrap otherwise.
fn to_i32(v: usize) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

/// Reads the header of the part at `path`, without its pixels.
pub fn read_part_info(path: &Path) -> Result<PartInfo, FarmError> {
    let meta =
        ::exr::meta::MetaData::read_from_file(path, false).map_err(|source| OutputError::Exr {
            path: path.to_path_buf(),
            source,
        })?;
    let [header] = meta.headers.as_slice() else {
        return Err(FarmError::Invalid {
            path: path.to_path_buf(),
            reason: format!("{} EXR parts, expected one", meta.headers.len()),
        });
    };
    parse_info(
        path,
        &header.shared_attributes.display_window,
        header.own_attributes.layer_position,
        header.layer_size,
        &header.own_attributes.other,
    )
}

/// The part's description from its header attributes, checked for consistency.
fn parse_info(
    path: &Path,
    display: &IntegerBounds,
    position: Vec2<i32>,
    size: Vec2<usize>,
    other: &HashMap<Text, AttributeValue>,
) -> Result<PartInfo, FarmError> {
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let text = |key: &str| -> Result<String, FarmError> {
        match other.get(&Text::from(format!("{PREFIX}{key}").as_str())) {
            Some(AttributeValue::Text(t)) => Ok(t.to_string()),
            Some(_) => Err(invalid(format!("header key {PREFIX}{key} is not text"))),
            None => Err(invalid(format!(
                "no {PREFIX}{key} header key (not a part: render parts with --samples, --crop or \
                 --chunk-from-env)"
            ))),
        }
    };
    fn number<T: std::str::FromStr>(
        key: &str,
        value: &str,
        invalid: &dyn Fn(String) -> FarmError,
    ) -> Result<T, FarmError> {
        value.parse().map_err(|_| {
            invalid(format!(
                "header key {PREFIX}{key} '{value}' is not a number"
            ))
        })
    }
    let format = text("format")?;
    if format != PART_FORMAT {
        return Err(invalid(format!(
            "part format '{format}', this Nimbus reads '{PART_FORMAT}'"
        )));
    }
    let hash = text("scene_hash")?;
    let scene_hash = u64::from_str_radix(&hash, 16)
        .map_err(|_| invalid(format!("scene hash '{hash}' is not hexadecimal")))?;
    let samples_text = text("samples")?;
    let samples = super::parse_samples(&samples_text).map_err(|_| {
        invalid(format!(
            "{PREFIX}samples '{samples_text}' is not START..END"
        ))
    })?;
    let get = |key: &str| -> Result<u64, FarmError> { number(key, &text(key)?, &invalid) };
    let spp = get("spp")?;
    let sample_count = get("sample_count")?;
    if display.position != Vec2(0, 0) {
        return Err(invalid(format!(
            "display window starts at {:?}, not at the origin",
            display.position
        )));
    }
    let (width, height) = (display.size.x(), display.size.y());
    let (x0, y0) = (
        usize::try_from(position.x()).map_err(|_| invalid("negative data window".into()))?,
        usize::try_from(position.y()).map_err(|_| invalid("negative data window".into()))?,
    );
    let window = PixelWindow {
        x0,
        y0,
        x1: x0 + size.x(),
        y1: y0 + size.y(),
    };
    if window.is_empty() || !window.fits(width, height) {
        return Err(invalid(format!(
            "data window {window} is empty or outside the {width}x{height} display window"
        )));
    }
    let spp = u32::try_from(spp).map_err(|_| invalid(format!("spp {spp} is too large")))?;
    if samples.end > spp || sample_count != samples.len() as u64 {
        return Err(invalid(format!(
            "samples {samples_text} (count {sample_count}) do not fit {spp} spp"
        )));
    }
    Ok(PartInfo {
        version: text("version")?,
        scene_hash,
        width,
        height,
        seed: get("seed")?,
        max_depth: u32::try_from(get("max_depth")?)
            .map_err(|_| invalid("max depth is too large".into()))?,
        spp,
        samples,
        window,
        nan_samples: get("nan_samples")?,
        clamped_samples: get("clamped_samples")?,
    })
}

/// Reads the part at `path`: its description and its film (the exact sums). Checks that every pixel holds
/// no more samples than the part's range, and that the part's float image is the image of its sums, bit for
/// bit (a file damaged in either is refused).
pub fn read_part(path: &Path) -> Result<(PartInfo, Film), FarmError> {
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let image = crate::output::read_flat_image(path)?;
    let [layer] = image.layer_data.as_slice() else {
        return Err(invalid(format!(
            "{} EXR parts, expected one",
            image.layer_data.len()
        )));
    };
    let info = parse_info(
        path,
        &image.attributes.display_window,
        layer.attributes.layer_position,
        layer.size,
        &layer.attributes.other,
    )?;
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| &c.sample_data)
    };
    let words: Vec<&Vec<u32>> = PixelSums::WORD_NAMES
        .iter()
        .map(|name| match channel(&format!("{PREFIX}{name}")) {
            Some(FlatSamples::U32(v)) => Ok(v),
            Some(_) => Err(invalid(format!("channel {PREFIX}{name} is not uint"))),
            None => Err(invalid(format!("no channel {PREFIX}{name}"))),
        })
        .collect::<Result<_, _>>()?;
    let n = info.window.pixel_count();
    if let Some(k) = words.iter().position(|w| w.len() != n) {
        return Err(invalid(format!(
            "channel {PREFIX}{} holds {} samples, expected {n}",
            PixelSums::WORD_NAMES[k],
            words[k].len()
        )));
    }
    let mut film = Film::with_window(info.width, info.height, info.window);
    let range = info.samples.len() as u32;
    for (i, pixel) in film.pixels_mut().iter_mut().enumerate() {
        let sums = PixelSums::from_words(&std::array::from_fn(|k| words[k][i]));
        if sums.count() > range {
            let (x, y) = pixel_position(&info.window, i);
            return Err(invalid(format!(
                "pixel ({x}, {y}) counts {} samples, more than its range {}..{}",
                sums.count(),
                info.samples.start,
                info.samples.end
            )));
        }
        *pixel = sums;
    }
    check_image(&film.image(), &info.window, &channel, &invalid)?;
    Ok((info, film))
}

/// Column and row in the frame of pixel `i` of `window`.
fn pixel_position(window: &PixelWindow, i: usize) -> (usize, usize) {
    let w = window.width().max(1);
    (window.x0 + i % w, window.y0 + i / w)
}

/// Compares the part's stored float channels with the image of its sums, bit for bit.
fn check_image<'a>(
    image: &RenderImage,
    window: &PixelWindow,
    channel: &dyn Fn(&str) -> Option<&'a FlatSamples>,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<(), FarmError> {
    for (name, expected) in image.channels() {
        let Some(FlatSamples::F32(stored)) = channel(&name) else {
            return Err(invalid(format!("no float channel {name}")));
        };
        if stored.len() != expected.len() {
            return Err(invalid(format!(
                "channel {name} holds {} samples, expected {}",
                stored.len(),
                expected.len()
            )));
        }
        if let Some(i) = (0..expected.len()).find(|&i| stored[i].to_bits() != expected[i].to_bits())
        {
            let (x, y) = pixel_position(window, i);
            return Err(invalid(format!(
                "channel {name} at pixel ({x}, {y}) is {}, but its sums give {} (damaged file?)",
                stored[i], expected[i]
            )));
        }
    }
    Ok(())
}
