//! Value-buffer codecs: raw, zlib ("zip") and the Blosc 1 container (LZ4 codec, byte shuffle), decoded by hand.
//!
//! OpenVDB writes a compressed buffer as an `i64` byte count followed by the bytes; a count `<= 0` means the
//! following `-count` bytes are stored uncompressed (used for tiny buffers and when compression does not help).

use super::error::{KResult, VdbErrorKind};
use super::stream::Reader;
use std::io::Read;

/// Per-grid compression flag: zlib.
pub const COMPRESS_ZIP: u32 = 0x1;
/// Per-grid compression flag: inactive values are omitted and rebuilt from the active mask.
pub const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// Per-grid compression flag: Blosc.
pub const COMPRESS_BLOSC: u32 = 0x4;

fn decomp(msg: impl Into<String>) -> VdbErrorKind {
    VdbErrorKind::Decompress(msg.into())
}

/// How a value buffer's stored bytes encode its decoded bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Codec {
    /// Stored as they are.
    Raw,
    /// A zlib stream.
    Zlib,
    /// A Blosc 1 frame.
    Blosc,
}

/// Reads the stored bytes of a buffer of `nbytes` decoded bytes, written with the given compression flags,
/// appending them to `sink`; returns how they are encoded (for [`decode`]).
pub(crate) fn read_stored(
    r: &mut Reader<'_>,
    compression: u32,
    nbytes: usize,
    sink: &mut Vec<u8>,
) -> KResult<Codec> {
    if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        r.append_to(nbytes as u64, "raw value buffer", sink)?;
        return Ok(Codec::Raw);
    }
    let n = r.i64("compressed byte count")?;
    if n <= 0 {
        let raw = n.unsigned_abs();
        if raw != nbytes as u64 {
            return Err(decomp(format!(
                "uncompressed block holds {raw} bytes, expected {nbytes}"
            )));
        }
        r.append_to(raw, "uncompressed value buffer", sink)?;
        return Ok(Codec::Raw);
    }
    r.append_to(n as u64, "compressed value buffer", sink)?;
    Ok(if compression & COMPRESS_BLOSC != 0 {
        Codec::Blosc
    } else {
        Codec::Zlib
    })
}

/// Decodes the stored bytes `src` (as [`read_stored`] read them, with its `codec`) into exactly `out.len()`
/// bytes.
pub(crate) fn decode(codec: Codec, src: &[u8], out: &mut [u8]) -> KResult<()> {
    match codec {
        // read_stored took exactly the decoded size.
        Codec::Raw => out.copy_from_slice(src),
        Codec::Zlib => zlib_decompress(src, out)?,
        Codec::Blosc => blosc_decompress(src, out)?,
    }
    Ok(())
}

/// Inflates a zlib stream into exactly `out.len()` bytes.
pub fn zlib_decompress(src: &[u8], out: &mut [u8]) -> KResult<()> {
    let mut dec = flate2::read::ZlibDecoder::new(src);
    dec.read_exact(out)
        .map_err(|e| decomp(format!("zlib: {e}")))?;
    Ok(())
}

const BLOSC_HEADER: usize = 16;
const FLAG_SHUFFLE: u8 = 0x1;
const FLAG_MEMCPYED: u8 = 0x2;
const FLAG_BITSHUFFLE: u8 = 0x4;
const FLAG_DONT_SPLIT: u8 = 0x10;

/// Decodes one Blosc 1 frame (16-byte header, block offsets, per-block split streams) into `out`.
///
/// Supports the LZ4 codec (OpenVDB's choice) and uncompressed ("memcpyed") frames, with or without byte shuffle.
pub fn blosc_decompress(src: &[u8], out: &mut [u8]) -> KResult<()> {
    if src.len() < BLOSC_HEADER {
        return Err(decomp("blosc frame shorter than its header"));
    }
    let flags = src[2];
    let typesize = src[3].max(1) as usize;
    let rd = |o: usize| u32::from_le_bytes(src[o..o + 4].try_into().expect("4 bytes")) as usize;
    let nbytes = rd(4);
    let blocksize = rd(8);
    let cbytes = rd(12);
    if nbytes != out.len() {
        return Err(decomp(format!(
            "blosc frame holds {nbytes} bytes, expected {}",
            out.len()
        )));
    }
    if cbytes > src.len() {
        return Err(decomp("blosc frame longer than its buffer"));
    }
    if flags & FLAG_BITSHUFFLE != 0 {
        return Err(decomp("blosc bit-shuffle is not supported"));
    }
    if nbytes == 0 {
        return Ok(());
    }
    if flags & FLAG_MEMCPYED != 0 {
        let body = src
            .get(BLOSC_HEADER..BLOSC_HEADER + nbytes)
            .ok_or_else(|| decomp("blosc memcpy frame truncated"))?;
        out.copy_from_slice(body);
        return Ok(());
    }
    let codec = flags >> 5;
    if codec != 1 {
        return Err(decomp(format!(
            "blosc codec {codec} is not supported (only LZ4)"
        )));
    }
    if blocksize == 0 {
        return Err(decomp("blosc block size is invalid"));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    let starts_end = BLOSC_HEADER + 4 * nblocks;
    if starts_end > cbytes {
        return Err(decomp("blosc block table truncated"));
    }
    let src = &src[..cbytes];
    let mut tmp = vec![0u8; blocksize.min(nbytes)];
    for b in 0..nblocks {
        let start = rd(BLOSC_HEADER + 4 * b);
        let bsize = if b + 1 == nblocks && nbytes % blocksize != 0 {
            nbytes % blocksize
        } else {
            blocksize
        };
        let leftover = bsize != blocksize;
        let dst = &mut out[b * blocksize..b * blocksize + bsize];
        let shuffle = flags & FLAG_SHUFFLE != 0 && typesize > 1;
        let target: &mut [u8] = if shuffle { &mut tmp[..bsize] } else { dst };
        let nsplits = if flags & FLAG_DONT_SPLIT == 0
            && typesize <= 16
            && blocksize / typesize >= 128
            && !leftover
        {
            typesize
        } else {
            1
        };
        if bsize % nsplits != 0 {
            return Err(decomp("blosc block not divisible into its streams"));
        }
        decode_streams(src, start, target, nsplits)?;
        if shuffle {
            unshuffle(&tmp[..bsize], dst, typesize);
        }
    }
    Ok(())
}

/// Decodes one Blosc block's `nsplits` streams, which start at byte `start` of the frame `src`, into `target`
/// (each stream fills an equal share of it): a stream of exactly its share's size is stored, any other is LZ4.
fn decode_streams(src: &[u8], start: usize, target: &mut [u8], nsplits: usize) -> KResult<()> {
    let neblock = target.len() / nsplits;
    let mut pos = start;
    for piece in target.chunks_exact_mut(neblock) {
        let len_bytes = src
            .get(pos..pos + 4)
            .ok_or_else(|| decomp("blosc stream header out of range"))?;
        let clen = i32::from_le_bytes(len_bytes.try_into().expect("4 bytes"));
        pos += 4;
        if clen < 0 {
            return Err(decomp("blosc stream with negative size"));
        }
        let clen = clen as usize;
        let stream = src
            .get(pos..pos + clen)
            .ok_or_else(|| decomp("blosc stream out of range"))?;
        pos += clen;
        if clen == neblock {
            piece.copy_from_slice(stream);
        } else {
            let n = lz4_flex::block::decompress_into(stream, piece)
                .map_err(|e| decomp(format!("lz4: {e}")))?;
            if n != neblock {
                return Err(decomp("lz4 stream decoded to the wrong size"));
            }
        }
    }
    Ok(())
}

/// Reverses Blosc's byte shuffle: byte `i` of element `j` was stored at `i * n + j`; trailing bytes that do not
/// fill a whole element are stored as they are.
pub fn unshuffle(src: &[u8], dst: &mut [u8], typesize: usize) {
    let n = src.len() / typesize;
    if typesize == 4 {
        // The common case (OpenVDB writes 4-byte elements): four streams, no per-byte bounds checks.
        let (s0, rest) = src.split_at(n);
        let (s1, rest) = rest.split_at(n);
        let (s2, s3) = rest.split_at(n);
        for (j, d) in dst[..4 * n].chunks_exact_mut(4).enumerate() {
            d.copy_from_slice(&[s0[j], s1[j], s2[j], s3[j]]);
        }
    } else {
        for j in 0..n {
            for i in 0..typesize {
                dst[j * typesize + i] = src[i * n + j];
            }
        }
    }
    let tail = n * typesize;
    dst[tail..].copy_from_slice(&src[tail..]);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unshuffle_roundtrip() {
        let src = [0u8, 4, 1, 5, 2, 6, 3, 7, 9];
        // elements of typesize 2: shuffled layout is [lo bytes..., hi bytes...]
        let shuffled = [0u8, 1, 2, 3, 4, 5, 6, 7, 9];
        let mut out = [0u8; 9];
        unshuffle(&shuffled, &mut out, 2);
        assert_eq!(out, src);
    }

    fn frame(flags: u8, typesize: u8, nbytes: u32, blocksize: u32, body: &[u8]) -> Vec<u8> {
        let mut v = vec![2u8, 1, flags, typesize];
        v.extend_from_slice(&nbytes.to_le_bytes());
        v.extend_from_slice(&blocksize.to_le_bytes());
        v.extend_from_slice(&((16 + body.len()) as u32).to_le_bytes());
        v.extend_from_slice(body);
        v
    }

    #[test]
    fn blosc_memcpy_and_lz4() {
        let data: Vec<u8> = (0..64u8).collect();
        let f = frame(FLAG_MEMCPYED, 4, 64, 64, &data);
        let mut out = vec![0u8; 64];
        blosc_decompress(&f, &mut out).unwrap();
        assert_eq!(out, data);

        // One block, no split (leftover-free but blocksize/typesize < 128), LZ4, shuffled with typesize 4.
        let mut shuffled = vec![0u8; 64];
        for j in 0..16 {
            for i in 0..4 {
                shuffled[i * 16 + j] = data[j * 4 + i];
            }
        }
        let comp = lz4_flex::block::compress(&shuffled);
        let mut body = Vec::new();
        body.extend_from_slice(&20u32.to_le_bytes()); // block start: header + one offset
        body.extend_from_slice(&(comp.len() as i32).to_le_bytes());
        body.extend_from_slice(&comp);
        let f = frame(FLAG_SHUFFLE | (1 << 5), 4, 64, 64, &body);
        let mut out = vec![0u8; 64];
        blosc_decompress(&f, &mut out).unwrap();
        assert_eq!(out, data);
        // Wrong size and truncation are errors.
        assert!(blosc_decompress(&f, &mut [0u8; 32]).is_err());
        assert!(blosc_decompress(&f[..20], &mut out).is_err());
    }

    #[test]
    fn raw_and_negative_count() {
        let mut bytes = (-4i64).to_le_bytes().to_vec();
        bytes.extend_from_slice(&[1, 2, 3, 4]);
        let mut r = Reader::new(&bytes);
        let mut stored = vec![9];
        assert_eq!(
            read_stored(&mut r, COMPRESS_ZIP, 4, &mut stored).unwrap(),
            Codec::Raw
        );
        assert_eq!(stored, [9, 1, 2, 3, 4]);
        let mut out = [0u8; 4];
        decode(Codec::Raw, &stored[1..], &mut out).unwrap();
        assert_eq!(out, [1, 2, 3, 4]);
        let mut r = Reader::new(&bytes);
        assert!(read_stored(&mut r, COMPRESS_BLOSC, 8, &mut stored).is_err());
    }
}
