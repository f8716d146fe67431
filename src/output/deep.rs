//! The deep scanline OpenEXR writer (OpenEXR 2.0 deep data), our own code after OpenEXR's public "OpenEXR File
//! Layout" document: the `exr` crate writes no deep data.
//!
//! The file is single-part, with the version field's "non-image" (deep) bit set, and holds six 32-bit `float`
//! channels per sample, in the header's (alphabetical) order: `A`, `B`, `G`, `R` (alpha and premultiplied
//! colour), `Z` and `ZBack` (the sample's front and back depth along the camera's view axis; see
//! [`crate::render::deep`]). Header attributes: `channels`, `chunkCount`, `compression`, `dataWindow`,
//! `displayWindow`, `lineOrder` (increasing y), `maxSamplesPerPixel`, `pixelAspectRatio`,
//! `screenWindowCenter`, `screenWindowWidth`, `type` (`deepscanline`), `version` (1), and the camera's
//! `worldToCamera` and `worldToNDC` when known.
//!
//! One chunk per scan line (NONE and ZIPS both take one line), located by the offset table (one `u64` file
//! offset per line). A chunk is: the line's `y` (`i32`); the packed size of its sample count table, the packed
//! size of its sample data and the unpacked size of its sample data (`u64` each); the sample count table,
//! `width` `i32`s each the running total of samples up to and including that pixel; and the sample data, channel
//! after channel, each channel's values pixel after pixel and sample after sample. With ZIPS the table and the
//! data are each compressed as OpenEXR's ZIP compresses a block (bytes split into even and odd halves, deltas of
//! successive bytes plus 128, then zlib), and stored as they are where that would not make them smaller (a
//! reader tells by the packed size equalling the unpacked one). All numbers are little-endian.

use super::{write_atomically, OutputError};
use crate::render::{DeepImage, ImageMetadata};
use std::io::Write;
use std::path::{Path, PathBuf};

/// OpenEXR's magic number.
const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
/// File format version 2 with bit 11, "non-image" (deep) data.
const VERSION: u32 = 2 | 0x800;
/// The channels, in the order the header lists and the chunks store them.
pub const DEEP_CHANNELS: [&str; 6] = ["A", "B", "G", "R", "Z", "ZBack"];

/// How the chunks of a deep file are compressed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeepCompression {
    /// None (OpenEXR's NONE).
    None,
    /// zlib, one scan line per chunk (OpenEXR's ZIPS).
    #[default]
    Zips,
}

impl DeepCompression {
    /// The value of OpenEXR's `compression` attribute.
    fn code(self) -> u8 {
        match self {
            DeepCompression::None => 0,
            DeepCompression::Zips => 2,
        }
    }
}

/// The deep file beside the flat EXR `exr_path`: `render.exr` → `render.deep.exr`.
pub fn deep_path(exr_path: &Path) -> PathBuf {
    exr_path.with_extension("deep.exr")
}

/// One header attribute: name, type name, size and value.
fn attribute(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.extend_from_slice(kind.as_bytes());
    out.push(0);
    out.extend_from_slice(&(value.len() as u32).to_le_bytes());
    out.extend_from_slice(value);
}

/// The little-endian bytes of `values`.
fn le_bytes<const N: usize, T: Copy>(values: &[T], bytes: impl Fn(T) -> [u8; N]) -> Vec<u8> {
    values.iter().flat_map(|&v| bytes(v)).collect()
}

/// A row-vector `m44f` attribute value.
fn matrix(m: &[[f32; 4]; 4]) -> Vec<u8> {
    le_bytes(m.as_flattened(), f32::to_le_bytes)
}

/// The header of `image`.
fn header(image: &DeepImage, compression: DeepCompression, metadata: &ImageMetadata) -> Vec<u8> {
    let mut h = Vec::new();
    let mut channels = Vec::new();
    for name in DEEP_CHANNELS {
        channels.extend_from_slice(name.as_bytes());
        channels.push(0);
        // Pixel type FLOAT (2), pLinear 0 and three reserved bytes, x and y sampling 1.
        channels.extend_from_slice(&2i32.to_le_bytes());
        channels.extend_from_slice(&[0, 0, 0, 0]);
        channels.extend_from_slice(&1i32.to_le_bytes());
        channels.extend_from_slice(&1i32.to_le_bytes());
    }
    channels.push(0);
    let window = le_bytes(
        &[0, 0, image.width as i32 - 1, image.height as i32 - 1],
        i32::to_le_bytes,
    );
    attribute(&mut h, "channels", "chlist", &channels);
    attribute(
        &mut h,
        "chunkCount",
        "int",
        &(image.height as i32).to_le_bytes(),
    );
    attribute(&mut h, "compression", "compression", &[compression.code()]);
    attribute(&mut h, "dataWindow", "box2i", &window);
    attribute(&mut h, "displayWindow", "box2i", &window);
    attribute(&mut h, "lineOrder", "lineOrder", &[0]);
    attribute(
        &mut h,
        "maxSamplesPerPixel",
        "int",
        &(image.most_samples() as i32).to_le_bytes(),
    );
    attribute(&mut h, "pixelAspectRatio", "float", &1f32.to_le_bytes());
    attribute(&mut h, "screenWindowCenter", "v2f", &[0; 8]);
    attribute(&mut h, "screenWindowWidth", "float", &1f32.to_le_bytes());
    attribute(&mut h, "type", "string", b"deepscanline");
    attribute(&mut h, "version", "int", &1i32.to_le_bytes());
    if let Some(m) = &metadata.world_to_camera {
        attribute(&mut h, "worldToCamera", "m44f", &matrix(m));
    }
    if let Some(m) = &metadata.world_to_ndc {
        attribute(&mut h, "worldToNDC", "m44f", &matrix(m));
    }
    h.push(0);
    h
}

/// `raw` as OpenEXR's ZIP compression stores a block: even bytes then odd bytes, each byte replaced by its
/// difference to the one before plus 128 (mod 256), then zlib; or `raw` itself where that is not smaller.
fn zip_block(raw: &[u8]) -> Vec<u8> {
    let half = raw.len().div_ceil(2);
    let mut split = vec![0u8; raw.len()];
    for (i, &b) in raw.iter().enumerate() {
        split[if i % 2 == 0 { i / 2 } else { half + i / 2 }] = b;
    }
    let mut previous = split.first().copied().unwrap_or(0);
    for b in split.iter_mut().skip(1) {
        let value = *b;
        *b = value.wrapping_sub(previous).wrapping_add(128);
        previous = value;
    }
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    let packed = encoder
        .write_all(&split)
        .and_then(|()| encoder.finish())
        .unwrap_or_default();
    if packed.is_empty() || packed.len() >= raw.len() {
        raw.to_vec()
    } else {
        packed
    }
}

/// The chunk of scan line `y`.
fn chunk(image: &DeepImage, y: usize, compression: DeepCompression) -> Vec<u8> {
    let pixels = y * image.width..(y + 1) * image.width;
    let base = image.offsets[pixels.start];
    let counts: Vec<i32> = pixels
        .clone()
        .map(|i| (image.offsets[i + 1] - base) as i32)
        .collect();
    let samples = &image.samples[base..image.offsets[pixels.end]];
    let mut data = Vec::with_capacity(samples.len() * 4 * DEEP_CHANNELS.len());
    for channel in 0..DEEP_CHANNELS.len() {
        for s in samples {
            let v = match channel {
                0 => s.a,
                1 => s.rgb[2],
                2 => s.rgb[1],
                3 => s.rgb[0],
                4 => s.z,
                _ => s.z_back,
            };
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let table = le_bytes(&counts, i32::to_le_bytes);
    let (packed_table, packed_data) = match compression {
        DeepCompression::None => (table, data.clone()),
        DeepCompression::Zips => (zip_block(&table), zip_block(&data)),
    };
    let mut out = Vec::with_capacity(28 + packed_table.len() + packed_data.len());
    out.extend_from_slice(&(y as i32).to_le_bytes());
    out.extend_from_slice(&(packed_table.len() as u64).to_le_bytes());
    out.extend_from_slice(&(packed_data.len() as u64).to_le_bytes());
    out.extend_from_slice(&(data.len() as u64).to_le_bytes());
    out.extend_from_slice(&packed_table);
    out.extend_from_slice(&packed_data);
    out
}

/// The bytes of the deep scanline file of `image` (see the module docs), with the camera matrices of
/// `metadata`.
pub fn encode_deep_exr(
    image: &DeepImage,
    compression: DeepCompression,
    metadata: &ImageMetadata,
) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&header(image, compression, metadata));
    let chunks: Vec<Vec<u8>> = (0..image.height)
        .map(|y| chunk(image, y, compression))
        .collect();
    let mut offset = (out.len() + 8 * chunks.len()) as u64;
    for c in &chunks {
        out.extend_from_slice(&offset.to_le_bytes());
        offset += c.len() as u64;
    }
    for c in chunks {
        out.extend_from_slice(&c);
    }
    out
}

/// Writes the deep scanline file of `image` to `path`, atomically ([`write_atomically`]).
pub fn write_deep_exr(
    image: &DeepImage,
    path: &Path,
    compression: DeepCompression,
    metadata: &ImageMetadata,
) -> Result<(), OutputError> {
    let invalid = |reason: String| OutputError::Invalid {
        path: path.to_path_buf(),
        reason,
    };
    let n = image.width.checked_mul(image.height).unwrap_or(0);
    if n == 0 || image.offsets.len() != n + 1 || image.offsets.last() != Some(&image.samples.len())
    {
        return Err(invalid(format!(
            "deep image {}x{} holds {} pixel offsets for {} samples",
            image.width,
            image.height,
            image.offsets.len(),
            image.samples.len()
        )));
    }
    if image.width > i32::MAX as usize
        || image.height > i32::MAX as usize
        || image.samples.len() > i32::MAX as usize
    {
        return Err(invalid(
            "deep image too large for OpenEXR's 32-bit counts".into(),
        ));
    }
    let bytes = encode_deep_exr(image, compression, metadata);
    write_atomically(path, &bytes).map_err(|e| invalid(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::DeepSample;
    use std::io::Read;

    fn image() -> DeepImage {
        let s = |z: f32, a: f32| DeepSample {
            z,
            z_back: z + 1.0,
            a,
            rgb: [a, 0.5 * a, 0.25 * a],
        };
        DeepImage {
            width: 2,
            height: 2,
            max_samples: 4,
            offsets: vec![0, 2, 2, 3, 6],
            samples: vec![
                s(1.0, 0.5),
                s(2.0, 0.25),
                s(3.0, 1.0),
                s(1.0, 0.1),
                s(2.0, 0.2),
                s(3.0, 0.3),
            ],
        }
    }

    #[test]
    fn deep_path_is_beside_the_flat_file() {
        assert_eq!(
            deep_path(Path::new("out/shot.0001.exr")),
            PathBuf::from("out/shot.0001.deep.exr")
        );
    }

    #[test]
    fn the_offset_table_points_at_each_line_and_the_tables_count_cumulatively() {
        let bytes = encode_deep_exr(&image(), DeepCompression::None, &ImageMetadata::default());
        assert_eq!(&bytes[..4], &MAGIC);
        assert_eq!(u32::from_le_bytes(bytes[4..8].try_into().unwrap()), 0x802);
        let header_end =
            8 + header(&image(), DeepCompression::None, &ImageMetadata::default()).len();
        let read_u64 =
            |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
        let read_i32 = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let line1 = read_u64(header_end + 8);
        assert_eq!(read_i32(line1), 1);
        // Line 1: pixel 0 has one sample, pixel 1 three: counts 1, 4; 4 samples × 6 channels × 4 bytes.
        assert_eq!(
            (
                read_u64(line1 + 4),
                read_u64(line1 + 12),
                read_u64(line1 + 20)
            ),
            (8, 96, 96)
        );
        assert_eq!((read_i32(line1 + 28), read_i32(line1 + 32)), (1, 4));
        // The A channel comes first, pixel by pixel: 1.0, then 0.1, 0.2, 0.3; Z fifth.
        let data = line1 + 36;
        let f = |k: usize| {
            f32::from_le_bytes(bytes[data + 4 * k..data + 4 * k + 4].try_into().unwrap())
        };
        assert_eq!([f(0), f(1), f(2), f(3)], [1.0, 0.1, 0.2, 0.3]);
        assert_eq!([f(16), f(17), f(18), f(19)], [3.0, 1.0, 2.0, 3.0]);
        assert_eq!(line1 + 36 + 96, bytes.len());
    }

    #[test]
    fn zip_blocks_undo_to_the_raw_bytes() {
        let raw: Vec<u8> = (0..4000u32)
            .flat_map(|i| ((i % 97) as f32).to_le_bytes())
            .collect();
        let packed = zip_block(&raw);
        assert!(packed.len() < raw.len());
        let mut split = Vec::new();
        flate2::read::ZlibDecoder::new(&packed[..])
            .read_to_end(&mut split)
            .unwrap();
        for i in 1..split.len() {
            split[i] = split[i - 1].wrapping_add(split[i]).wrapping_sub(128);
        }
        let half = raw.len().div_ceil(2);
        let back: Vec<u8> = (0..raw.len())
            .map(|i| split[if i % 2 == 0 { i / 2 } else { half + i / 2 }])
            .collect();
        assert_eq!(back, raw);
        assert_eq!(zip_block(&[7]), vec![7], "too small to pack: stored raw");
    }
}
