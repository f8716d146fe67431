//! Part files: the EXR a `--samples`, `--crop` or `--chunk-from-env` render writes.
//!
//! A part is one scanline EXR part, ZIP compressed, whose data window is the crop (the whole frame without
//! `--crop`) and whose display window is the full frame. It holds:
//! - the float channels of an ordinary render (`R`, `G`, `B`, `A`, `albedo.*`, `normal.*`, `depth.Z`,
//!   `variance.*`, and the layers of its plan) for the part's own samples, so any EXR viewer shows it;
//! - the exact sums of the film as `uint` channels: the core's 63 `nimbus.count`, `nimbus.sum.R.0` … (see
//!   [`PixelSums::WORD_NAMES`]), each slot's 12 `nimbus.slot.<slot>.<R|G|B>.<0..3>` (light-path layers,
//!   colours, light groups, shadow catcher; see [`crate::render::LayerPlan`]) and, for each Cryptomatte kind,
//!   `nimbus.crypto.<kind>.<entry>.id`, `.w0`, `.w1` (an ID and its 64-bit coverage sum, the pixel's IDs in
//!   ascending order, zero-filled): what the merge adds;
//! - the image's camera attributes (`worldToCamera`, `worldToNDC`) and, as `nimbus.meta.<key>`, its
//!   `nimbus/` attributes, which the merged image takes over;
//! - header attributes (all text) with what a merge checks:
//!
//! | key | value |
//! |---|---|
//! | `nimbus.format` | `nimbus-part-2` |
//! | `nimbus.version` | the Nimbus version that rendered it |
//! | `nimbus.scene_hash` | 16 hex digits (see [`super::hash`]) |
//! | `nimbus.seed`, `nimbus.max_depth` | the render settings |
//! | `nimbus.spp` | samples per pixel of the whole render |
//! | `nimbus.samples` | this part's samples, `START..END` (END exclusive) |
//! | `nimbus.sample_count` | `END - START` |
//! | `nimbus.nan_samples`, `nimbus.clamped_samples` | the part's dropped and clamped samples |
//! | `nimbus.layers` | the layer plan: `slots=…;written=…;depth=N` |
//! | `nimbus.estimators` | each medium's estimator (free flights, majorant structure, shadow rays) |
//! | `nimbus.crypto.<kind>.manifest`, `nimbus.crypto.<kind>.entries` | each Cryptomatte kind's manifest (JSON) and its number of entry channels |
//!
//! A checkpoint (`--checkpoint`, see [`super::checkpoint`]) is a part of an unfinished render: its format is
//! `nimbus-checkpoint-1`, its `nimbus.samples` end with the most samples any pixel holds, and two keys say
//! which pixels hold which: `nimbus.complete` (every pixel holds `START..complete`) and `nimbus.stopped_pass`
//! (`none`, or `END;` and the pixels of each row that also hold `complete..END`, run-length coded as
//! `PIXELSxROWS,…` from the top row). `nimbus merge` refuses checkpoints; `nimbus render --resume` reads them.

use super::FarmError;
use crate::limits::one_line;
use crate::output::OutputError;
use crate::render::cryptomatte::{manifest_json, parse_manifest, CryptoKind, IdCoverage};
use crate::render::resume::{ProgressMismatch, RegionProgress, StoppedPass};
use crate::render::{
    Film, ImageMetadata, LayerPlan, PixelSums, PixelWindow, RenderImage, RenderRegion,
    RenderSettings, RenderStats, ValueSum,
};
use ::exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use ::exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image, ImageAttributes, Layer, LayerAttributes,
    SmallVec, Vec2,
};
use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;
use std::sync::Arc;

/// The value of `nimbus.format` in a part written by this version.
pub const PART_FORMAT: &str = "nimbus-part-2";
/// The value of `nimbus.format` in a checkpoint written by this version.
pub const CHECKPOINT_FORMAT: &str = "nimbus-checkpoint-1";
/// Prefix of the header keys and sum channels of a part.
const PREFIX: &str = "nimbus.";

/// What a part says about itself: everything a merge checks.
#[derive(Clone, Debug, PartialEq)]
pub struct PartInfo {
    /// Version of Nimbus that rendered it.
    pub version: String,
    /// Scene hash (see `super::hash`).
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
    /// What the film keeps and writes beyond its core ([`write_part`] writes the film's own).
    pub plan: LayerPlan,
    /// The header attributes the merged image takes over (camera matrices, `nimbus/` keys).
    pub metadata: ImageMetadata,
    /// Each medium's estimator (`name: key`, see `crate::volume::MediumMethod::estimator_key`), joined by
    /// `; `: the majorant structure chosen under the memory limit changes the samples, so parts of renders that
    /// chose differently must not merge.
    pub estimators: String,
    /// For a checkpoint, which of `samples` each pixel holds; `None` for a part (every pixel holds them all).
    pub progress: Option<RegionProgress>,
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
            plan: LayerPlan::default(),
            metadata: ImageMetadata::default(),
            estimators: stats
                .media
                .iter()
                .map(|m| format!("{}: {}", m.name, m.method_details.estimator_key()))
                .collect::<Vec<_>>()
                .join("; "),
            progress: None,
        }
    }

    /// Each medium's estimator of `scene`, as [`PartInfo::estimators`] holds them.
    pub fn estimators_of(scene: &crate::scene::Scene) -> String {
        scene
            .media()
            .iter()
            .map(|m| format!("{}: {}", m.name(), m.method().estimator_key()))
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// This description with the header attributes the merged image is to take over.
    pub fn with_metadata(self, metadata: ImageMetadata) -> Self {
        Self { metadata, ..self }
    }

    /// The header attributes, keyed without the `nimbus.` prefix.
    fn keys(&self) -> Vec<(&'static str, String)> {
        let format = match self.progress {
            Some(_) => CHECKPOINT_FORMAT,
            None => PART_FORMAT,
        };
        let mut keys = vec![
            ("format", format.to_string()),
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
            ("layers", self.plan.describe()),
            ("estimators", self.estimators.clone()),
        ];
        if let Some(progress) = &self.progress {
            keys.push(("complete", progress.complete.to_string()));
            keys.push(("stopped_pass", format_stopped_pass(progress)));
        }
        keys
    }
}

/// Writes `film` (a finished, uncancelled render) as the part `info` describes, with the film's layer plan.
/// The film's frame and window must be `info`'s.
pub fn write_part(path: &Path, film: &Film, info: &PartInfo) -> Result<(), FarmError> {
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    check_film_fits(film, info).map_err(|e| invalid(e.to_string()))?;
    let info = &PartInfo {
        plan: film.plan().clone(),
        ..info.clone()
    };
    let mut channels = image_channels(film);
    channels.extend(sum_channels(film));
    let (crypto_channels, crypto_keys) = cryptomatte_channels(film);
    channels.extend(crypto_channels);
    let attributes =
        part_attributes(film, info, crypto_keys).map_err(|e| invalid(e.to_string()))?;
    let layer = Layer::new(
        Vec2(info.window.width(), info.window.height()),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    let display = IntegerBounds::from_dimensions(Vec2(info.width, info.height));
    let image = Image::new(ImageAttributes::new(display), layer);
    crate::output::write_sorted(&image, path)?;
    Ok(())
}

/// Channels of a part: some `f32`, most `u32` words.
type PartChannels = SmallVec<[AnyChannel<FlatSamples>; 4]>;

/// Refuses a film whose frame or window is not the part's, a sample range that is empty or past the spp, and
/// checkpoint progress that does not fit the film or ends elsewhere than the range.
fn check_film_fits(film: &Film, info: &PartInfo) -> Result<(), PartProblem> {
    if (film.width, film.height, film.window()) != (info.width, info.height, info.window) {
        return Err(PartProblem::FilmWindow {
            film_window: film.window(),
            film_width: film.width,
            film_height: film.height,
            window: info.window,
            width: info.width,
            height: info.height,
        });
    }
    if info.samples.is_empty() || info.samples.end > info.spp {
        return Err(PartProblem::Samples {
            samples: info.samples.clone(),
            spp: info.spp,
        });
    }
    if let Some(progress) = &info.progress {
        progress
            .fits(film, &info.samples)
            .map_err(PartProblem::Progress)?;
        let most = progress.most_samples(info.samples.start);
        if most != info.samples.len() as u32 {
            return Err(PartProblem::ProgressEnd {
                most,
                samples: info.samples.clone(),
            });
        }
    }
    Ok(())
}

/// What makes a film or a header value unfit for a part: the reason of a [`FarmError::Invalid`].
#[derive(Debug, thiserror::Error)]
enum PartProblem {
    /// The film's frame or window is not the part's.
    #[error(
        "film of {film_window} in {film_width}x{film_height} does not match the part's crop {window} in \
         {width}x{height}"
    )]
    FilmWindow {
        film_window: PixelWindow,
        film_width: usize,
        film_height: usize,
        window: PixelWindow,
        width: usize,
        height: usize,
    },
    /// The sample range is empty or goes past the spp.
    #[error("samples {}..{} are not a non-empty range within {spp} spp", samples.start, samples.end)]
    Samples { samples: Range<u32>, spp: u32 },
    /// The checkpoint progress does not fit the film.
    #[error("checkpoint progress: {0}")]
    Progress(ProgressMismatch),
    /// The checkpoint progress ends elsewhere than the range.
    #[error(
        "checkpoint progress ends at {most} samples, the range {}..{} at {}",
        samples.start,
        samples.end,
        samples.len()
    )]
    ProgressEnd { most: u32, samples: Range<u32> },
    /// A header value is not plain text.
    #[error("{key} '{value}' is not plain text")]
    NotPlainText { key: String, value: String },
}

/// The film's image as `f32` channels (what a compositor reads from a part).
fn image_channels(film: &Film) -> PartChannels {
    film.image()
        .channels()
        .into_iter()
        .map(|(name, samples)| AnyChannel::new(name.as_str(), FlatSamples::F32(samples)))
        .collect()
}

/// A `u32` channel.
fn word_channel(name: &str, samples: Vec<u32>) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::U32(samples))
}

/// The exact sums a merge adds: each pixel's sums and each slot value's, word by word.
fn sum_channels(film: &Film) -> PartChannels {
    let mut list = PartChannels::new();
    let words: Vec<[u32; PixelSums::WORDS]> = film.pixels().iter().map(|p| p.to_words()).collect();
    for (k, name) in PixelSums::WORD_NAMES.iter().enumerate() {
        let samples = words.iter().map(|w| w[k]).collect();
        list.push(word_channel(&format!("{PREFIX}{name}"), samples));
    }
    let values = film.plan().values_per_pixel();
    for (j, name) in slot_word_names(film.plan()).into_iter().enumerate() {
        let (value, word) = (j / ValueSum::WORDS, j % ValueSum::WORDS);
        let samples = film
            .slots()
            .chunks_exact(values.max(1))
            .map(|pixel| pixel[value].to_words()[word])
            .collect();
        list.push(word_channel(&name, samples));
    }
    list
}

/// Each Cryptomatte kind's per-pixel (id, weight) entries as `u32` channels, and the header keys that go with
/// them: the kind's manifest and its entry count.
fn cryptomatte_channels(film: &Film) -> (PartChannels, Vec<(String, String)>) {
    let mut list = PartChannels::new();
    let mut keys = Vec::new();
    let kinds = film.plan().cryptomatte.len();
    for (k, (kind, manifest)) in film.plan().cryptomatte.iter().enumerate() {
        let maps: Vec<&IdCoverage> = film.crypto().iter().skip(k).step_by(kinds).collect();
        let entries = maps.iter().map(|m| m.entries().len()).max().unwrap_or(0);
        for e in 0..entries {
            let entry = |f: &dyn Fn(&(u32, u64)) -> u32| -> Vec<u32> {
                maps.iter()
                    .map(|m| m.entries().get(e).map_or(0, f))
                    .collect()
            };
            let base = format!("{PREFIX}crypto.{}.{e:03}", kind.layer_name());
            list.push(word_channel(&format!("{base}.id"), entry(&|p| p.0)));
            list.push(word_channel(&format!("{base}.w0"), entry(&|p| p.1 as u32)));
            list.push(word_channel(
                &format!("{base}.w1"),
                entry(&|p| (p.1 >> 32) as u32),
            ));
        }
        keys.push((
            format!("crypto.{}.manifest", kind.layer_name()),
            manifest_json(manifest),
        ));
        keys.push((
            format!("crypto.{}.entries", kind.layer_name()),
            entries.to_string(),
        ));
    }
    (list, keys)
}

/// The part's layer attributes: its window's position, the camera matrices, and every key of `info`, the
/// Cryptomatte kinds and `crypto_keys`, and the image metadata, as `PREFIX`ed text; a value that is not plain text
/// is refused.
fn part_attributes(
    film: &Film,
    info: &PartInfo,
    crypto_keys: Vec<(String, String)>,
) -> Result<LayerAttributes, PartProblem> {
    let mut attributes = LayerAttributes {
        layer_position: Vec2(to_i32(info.window.x0), to_i32(info.window.y0)),
        world_to_camera: info.metadata.world_to_camera.map(flatten),
        world_to_normalized_device: info.metadata.world_to_ndc.map(flatten),
        ..LayerAttributes::default()
    };
    let cryptomatte_list = film
        .plan()
        .cryptomatte
        .iter()
        .map(|(kind, _)| kind.layer_name())
        .collect::<Vec<_>>()
        .join(",");
    let keys = info
        .keys()
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .chain(std::iter::once((
            "cryptomatte".to_owned(),
            cryptomatte_list,
        )))
        .chain(crypto_keys)
        .chain(
            info.metadata
                .nimbus
                .iter()
                .map(|(k, v)| (format!("meta.{k}"), v.clone())),
        );
    for (key, value) in keys {
        let Some(text) = Text::new_or_none(&value) else {
            return Err(PartProblem::NotPlainText { key, value });
        };
        attributes.other.insert(
            Text::from(format!("{PREFIX}{key}").as_str()),
            AttributeValue::Text(text),
        );
    }
    Ok(attributes)
}

/// The `uint` channel names of a plan's slot sums, in the order of the film's values and their words.
fn slot_word_names(plan: &LayerPlan) -> Vec<String> {
    plan.slots
        .iter()
        .flat_map(|slot| {
            ["R", "G", "B"].into_iter().flat_map(move |c| {
                (0..ValueSum::WORDS).map(move |w| format!("{PREFIX}slot.{slot}.{c}.{w}"))
            })
        })
        .collect()
}

/// A row-major 4×4 matrix as OpenEXR's `m44f` stores it.
fn flatten(m: [[f32; 4]; 4]) -> [f32; 16] {
    std::array::from_fn(|i| m[i / 4][i % 4])
}

/// The inverse of [`flatten`].
fn unflatten(m: [f32; 16]) -> [[f32; 4]; 4] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[4 * r + c]))
}

/// Pixel coordinates fit `i32` for every frame the renderer can hold; saturate rather than wrap otherwise.
fn to_i32(v: usize) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

/// Reads the header of the part at `path`, without its pixels.
pub fn read_part_info(path: &Path) -> Result<PartInfo, FarmError> {
    crate::limits::refuse_pipes_and_sockets(path).map_err(|e| FarmError::Invalid {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
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
        &header.own_attributes,
        header.layer_size,
    )
}

/// The part's description from its header attributes, checked for consistency.
fn parse_info(
    path: &Path,
    display: &IntegerBounds,
    attributes: &LayerAttributes,
    size: Vec2<usize>,
) -> Result<PartInfo, FarmError> {
    let (position, other) = (attributes.layer_position, &attributes.other);
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let text = |key: &str| header_text(other, key, &invalid);
    let format = text("format")?;
    if format != PART_FORMAT && format != CHECKPOINT_FORMAT {
        return Err(invalid(format!(
            "part format '{format}', this Nimbus reads '{PART_FORMAT}' and '{CHECKPOINT_FORMAT}'"
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
    let get = |key: &str| header_number(other, key, &invalid);
    let spp = get("spp")?;
    let sample_count = get("sample_count")?;
    let (width, height, window) = data_window(display, position, size, &invalid)?;
    let spp = u32::try_from(spp).map_err(|_| invalid(format!("spp {spp} is too large")))?;
    if samples.end > spp || sample_count != samples.len() as u64 {
        return Err(invalid(format!(
            "samples {samples_text} (count {sample_count}) do not fit {spp} spp"
        )));
    }
    let pixel_samples = window.pixel_count() as u64 * sample_count;
    let nan_samples = dropped_samples("nan_samples", get("nan_samples")?, pixel_samples, &invalid)?;
    let clamped_samples = dropped_samples(
        "clamped_samples",
        get("clamped_samples")?,
        pixel_samples,
        &invalid,
    )?;
    let plan = parse_plan(other, &text, &invalid)?;
    let progress = if format == CHECKPOINT_FORMAT {
        let complete = get("complete")?;
        let stopped = text("stopped_pass")?;
        Some(checkpoint_progress(
            (complete, &stopped),
            (&samples, &samples_text),
            window,
            &invalid,
        )?)
    } else {
        None
    };
    Ok(PartInfo {
        plan,
        metadata: part_metadata(attributes),
        estimators: text("estimators")?,
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
        nan_samples,
        clamped_samples,
        progress,
    })
}

/// The part's frame size and pixel window, from the EXR's display window (which must start at the origin) and
/// its data window (at `position`, of `size`), which must be a non-empty window inside the frame.
fn data_window(
    display: &IntegerBounds,
    position: Vec2<i32>,
    size: Vec2<usize>,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<(usize, usize, PixelWindow), FarmError> {
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
    Ok((width, height, window))
}

/// The text of header key `nimbus.<key>`; a missing key says the file is not a part.
fn header_text(
    other: &HashMap<Text, AttributeValue>,
    key: &str,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<String, FarmError> {
    match other.get(&Text::from(format!("{PREFIX}{key}").as_str())) {
        Some(AttributeValue::Text(t)) => Ok(t.to_string()),
        Some(_) => Err(invalid(format!("header key {PREFIX}{key} is not text"))),
        None => Err(invalid(format!(
            "no {PREFIX}{key} header key (not a part: render parts with --samples, --crop or \
             --chunk-from-env)"
        ))),
    }
}

/// Header key `nimbus.<key>` read as a whole number.
fn header_number(
    other: &HashMap<Text, AttributeValue>,
    key: &str,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<u64, FarmError> {
    let value = header_text(other, key, invalid)?;
    value.parse().map_err(|_| {
        invalid(format!(
            "header key {PREFIX}{key} '{value}' is not a number"
        ))
    })
}

/// The count of NaN or clamped samples under header key `key`, which cannot exceed the part's pixel-samples.
fn dropped_samples(
    key: &str,
    value: u64,
    pixel_samples: u64,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<u64, FarmError> {
    if value > pixel_samples {
        return Err(invalid(format!(
            "{PREFIX}{key} {value} is more than the part's {pixel_samples} pixel-samples"
        )));
    }
    Ok(value)
}

/// A checkpoint's progress, from its `nimbus.complete` and `nimbus.stopped_pass` values (`stopped`), which
/// must end exactly the part's `samples` (written `samples_text`) in `window`.
fn checkpoint_progress(
    (complete, stopped): (u64, &str),
    (samples, samples_text): (&std::ops::Range<u32>, &str),
    window: PixelWindow,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<RegionProgress, FarmError> {
    let progress = parse_stopped_pass(u32::try_from(complete).unwrap_or(u32::MAX), stopped, window)
        .map_err(|e| {
            invalid(format!(
                "{PREFIX}stopped_pass '{}': {e}",
                one_line(stopped, 60)
            ))
        })?;
    if progress.complete < samples.start
        || progress.most_samples(samples.start) != samples.len() as u32
    {
        return Err(invalid(format!(
            "{PREFIX}complete {complete} and {PREFIX}stopped_pass do not end the samples {samples_text}"
        )));
    }
    Ok(progress)
}

/// The header attributes a merged image takes over: the camera matrices and the `nimbus.meta.*` text keys.
fn part_metadata(attributes: &LayerAttributes) -> ImageMetadata {
    ImageMetadata {
        world_to_camera: attributes.world_to_camera.map(unflatten),
        world_to_ndc: attributes.world_to_normalized_device.map(unflatten),
        nimbus: attributes
            .other
            .iter()
            .filter_map(|(key, value)| {
                let key = key.to_string();
                let key = key.strip_prefix(&format!("{PREFIX}meta."))?.to_owned();
                match value {
                    AttributeValue::Text(t) => Some((key, t.to_string())),
                    _ => None,
                }
            })
            .collect(),
    }
}

/// The value of `nimbus.stopped_pass`: `none`, or `END;` and the pixels of each row run-length coded.
fn format_stopped_pass(progress: &RegionProgress) -> String {
    let Some(pass) = &progress.stopped_pass else {
        return "none".into();
    };
    let mut runs: Vec<(u32, usize)> = Vec::new();
    for &pixels in &pass.row_pixels {
        match runs.last_mut() {
            Some((p, rows)) if *p == pixels => *rows += 1,
            _ => runs.push((pixels, 1)),
        }
    }
    let runs: Vec<String> = runs.iter().map(|(p, rows)| format!("{p}x{rows}")).collect();
    format!("{};{}", pass.end, runs.join(","))
}

/// The progress a checkpoint's `nimbus.complete` and `nimbus.stopped_pass` (`text`) give for `window`.
fn parse_stopped_pass(
    complete: u32,
    text: &str,
    window: PixelWindow,
) -> Result<RegionProgress, StoppedPassError> {
    use StoppedPassError as E;
    if text == "none" {
        return Ok(RegionProgress::start(complete));
    }
    let (end, runs) = text.split_once(';').ok_or(E::Form)?;
    let end: u32 = end.parse().map_err(|_| E::End)?;
    if end <= complete {
        return Err(E::EndsEarly { end, complete });
    }
    let mut row_pixels = Vec::new();
    for run in runs.split(',') {
        let (pixels, rows) = run.split_once('x').ok_or(E::Run)?;
        let pixels: u32 = pixels.parse().map_err(|_| E::Pixels)?;
        let rows: usize = rows.parse().map_err(|_| E::Rows)?;
        if pixels as usize > window.width() || rows > window.height() - row_pixels.len() {
            return Err(E::RunsOutside {
                width: window.width(),
                height: window.height(),
            });
        }
        row_pixels.extend(std::iter::repeat_n(pixels, rows));
    }
    if row_pixels.len() != window.height() {
        return Err(E::RowCount {
            rows: row_pixels.len(),
            height: window.height(),
        });
    }
    Ok(RegionProgress {
        complete,
        stopped_pass: Some(StoppedPass { end, row_pixels }),
    })
}

/// What is wrong with a checkpoint's `nimbus.stopped_pass` value (`none`, or `END;RUNS` with runs of
/// `PIXELSxROWS`).
#[derive(Debug, thiserror::Error)]
enum StoppedPassError {
    /// Neither form.
    #[error("neither 'none' nor END;RUNS")]
    Form,
    /// END does not parse.
    #[error("END is not a sample number")]
    End,
    /// The pass ends at or before the complete samples.
    #[error("the pass ends at {end}, not after {complete}")]
    EndsEarly { end: u32, complete: u32 },
    /// A run lacks its `x`.
    #[error("a run is not PIXELSxROWS")]
    Run,
    /// A run's PIXELS does not parse.
    #[error("PIXELS is not a number")]
    Pixels,
    /// A run's ROWS does not parse.
    #[error("ROWS is not a number")]
    Rows,
    /// A run is wider than the window, or runs past its last row.
    #[error("the runs do not fit the {width}x{height} window")]
    RunsOutside { width: usize, height: usize },
    /// The runs cover another number of rows than the window has.
    #[error("the runs cover {rows} rows, the window has {height}")]
    RowCount { rows: usize, height: usize },
}

/// The layer plan of a part's header: `nimbus.layers`, and the manifest of each Cryptomatte kind it lists.
fn parse_plan(
    other: &HashMap<Text, AttributeValue>,
    text: &dyn Fn(&str) -> Result<String, FarmError>,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<LayerPlan, FarmError> {
    let kinds = match other.get(&Text::from(format!("{PREFIX}cryptomatte").as_str())) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        _ => String::new(),
    };
    let mut cryptomatte = Vec::new();
    for name in kinds.split(',').filter(|k| !k.is_empty()) {
        let kind = CryptoKind::from_layer_name(name)
            .ok_or_else(|| invalid(format!("unknown Cryptomatte kind '{name}'")))?;
        let json = text(&format!("crypto.{name}.manifest"))?;
        let manifest = parse_manifest(&json).ok_or_else(|| {
            invalid(format!(
                "the {name} manifest is not an object of names to IDs"
            ))
        })?;
        cryptomatte.push((kind, manifest));
    }
    let layers = text("layers")?;
    LayerPlan::from_description(&layers, cryptomatte)
        .ok_or_else(|| invalid(format!("{PREFIX}layers '{layers}' is not a layer plan")))
}

/// Reads the part at `path`: its description and its film (the exact sums). Checks that every pixel holds
/// no more samples than the part's range, and that the part's float image is the image of its sums, bit for
/// bit (a file damaged in either is refused).
pub fn read_part(path: &Path) -> Result<(PartInfo, Film), FarmError> {
    let invalid = |reason: String| FarmError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    // The header first: a data window outside the frame is refused before its samples are read.
    read_part_info(path)?;
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
        &layer.attributes,
        layer.size,
    )?;
    let channel = |name: &str| {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .map(|c| &c.sample_data)
    };
    let n = info.window.pixel_count();
    let uint = |name: &str| -> Result<&Vec<u32>, FarmError> {
        match channel(name) {
            Some(FlatSamples::U32(v)) if v.len() == n => Ok(v),
            Some(FlatSamples::U32(v)) => Err(invalid(format!(
                "channel {name} holds {} samples, expected {n}",
                v.len()
            ))),
            Some(_) => Err(invalid(format!("channel {name} is not uint"))),
            None => Err(invalid(format!("no channel {name}"))),
        }
    };
    let words: Vec<&Vec<u32>> = PixelSums::WORD_NAMES
        .iter()
        .map(|name| uint(&format!("{PREFIX}{name}")))
        .collect::<Result<_, _>>()?;
    let slot_words: Vec<&Vec<u32>> = slot_word_names(&info.plan)
        .iter()
        .map(|name| uint(name))
        .collect::<Result<_, _>>()?;
    let crypto = read_crypto(
        &info.plan,
        n,
        other_text(&layer.attributes.other),
        &uint,
        &invalid,
    )?;
    let film = film_of_words(&info, &words, &slot_words, &crypto, &invalid)?;
    check_image(&film.image(), &info.window, &channel, &invalid)?;
    Ok((info, film))
}

/// The film of a part described by `info`, made from its channels' words: each pixel's core sums (`words`),
/// slot sums (`slot_words`) and Cryptomatte maps (`crypto`); a pixel counting more samples than its range is
/// refused.
fn film_of_words(
    info: &PartInfo,
    words: &[&Vec<u32>],
    slot_words: &[&Vec<u32>],
    crypto: &[Vec<IdCoverage>],
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<Film, FarmError> {
    let mut film = Film::with_plan(
        info.width,
        info.height,
        info.window,
        Arc::new(info.plan.clone()),
    );
    let values = info.plan.values_per_pixel();
    let n = info.window.pixel_count();
    for i in 0..n {
        let sums = PixelSums::from_words(&std::array::from_fn(|k| words[k][i]));
        let (x, y) = pixel_position(&info.window, i);
        let range = match &info.progress {
            Some(p) => p.samples_of(info.samples.start, x - info.window.x0, y - info.window.y0),
            None => info.samples.clone(),
        };
        if sums.count() > range.len() as u32 {
            return Err(invalid(format!(
                "pixel ({x}, {y}) counts {} samples, more than its range {}..{}",
                sums.count(),
                range.start,
                range.end
            )));
        }
        let slots: Vec<ValueSum> = (0..values)
            .map(|v| {
                ValueSum::from_words(std::array::from_fn(|w| {
                    slot_words[v * ValueSum::WORDS + w][i]
                }))
            })
            .collect();
        let maps = (!crypto.is_empty()).then(|| crypto.iter().map(|k| k[i].clone()).collect());
        film.set_pixel(i, sums, &slots, maps);
    }
    Ok(film)
}

/// The text header attributes of a part, by key.
fn other_text(other: &HashMap<Text, AttributeValue>) -> HashMap<String, String> {
    other
        .iter()
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect()
}

/// The Cryptomatte coverage maps of a part: for each kind of the plan, one map per pixel, read from its
/// `nimbus.crypto.<kind>.<entry>.*` channels (`nimbus.crypto.<kind>.entries` of them). An entry of ID 0 and
/// no coverage is padding.
fn read_crypto<'a>(
    plan: &LayerPlan,
    n: usize,
    keys: HashMap<String, String>,
    uint: &dyn Fn(&str) -> Result<&'a Vec<u32>, FarmError>,
    invalid: &dyn Fn(String) -> FarmError,
) -> Result<Vec<Vec<IdCoverage>>, FarmError> {
    let mut out = Vec::new();
    for (kind, _) in &plan.cryptomatte {
        let name = kind.layer_name();
        let key = format!("{PREFIX}crypto.{name}.entries");
        let entries: usize = keys
            .get(&key)
            .and_then(|e| e.parse().ok())
            .ok_or_else(|| invalid(format!("no valid {key} header key")))?;
        if entries > crate::render::cryptomatte::MAX_PART_ENTRIES {
            return Err(invalid(format!(
                "{key} is {entries}, more than {}",
                crate::render::cryptomatte::MAX_PART_ENTRIES
            )));
        }
        let mut maps = vec![IdCoverage::default(); n];
        for e in 0..entries {
            let base = format!("{PREFIX}crypto.{name}.{e:03}");
            let (ids, w0, w1) = (
                uint(&format!("{base}.id"))?,
                uint(&format!("{base}.w0"))?,
                uint(&format!("{base}.w1"))?,
            );
            for (i, map) in maps.iter_mut().enumerate() {
                let units = w0[i] as u64 | (w1[i] as u64) << 32;
                if units > 0 {
                    map.add_units(ids[i], units);
                }
            }
        }
        out.push(maps);
    }
    Ok(out)
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
