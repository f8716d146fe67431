//! A bounds-checked little-endian byte reader: every read checks the remaining input first. It reads from bytes
//! in memory or streams from a file, so that reading a VDB file from disk never holds the whole file: only the
//! value buffers being decoded, a batch at a time (OpenVDB's own reader streams too).

use super::error::{corrupt, KResult, VdbErrorKind};
use glam::{DVec3, IVec3};
use std::io::Read;

/// Where a [`Reader`]'s bytes come from.
enum Source<'a> {
    /// Bytes in memory.
    Slice(&'a [u8]),
    /// A file read through a buffer; `scratch` holds the bytes of the last [`Reader::take`].
    File {
        file: std::io::BufReader<std::fs::File>,
        scratch: Vec<u8>,
    },
}

/// Cursor over the bytes `0..end` of a file or an in-memory slice.
pub(crate) struct Reader<'a> {
    source: Source<'a>,
    pos: usize,
    end: usize,
}

impl<'a> Reader<'a> {
    /// A reader at the start of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self {
            source: Source::Slice(data),
            pos: 0,
            end: data.len(),
        }
    }

    /// A reader at the start of `file`, whose length is `len` bytes.
    pub fn from_file(file: std::fs::File, len: u64) -> Self {
        Self {
            source: Source::File {
                file: std::io::BufReader::with_capacity(1 << 16, file),
                scratch: Vec::new(),
            },
            pos: 0,
            end: usize::try_from(len).unwrap_or(usize::MAX),
        }
    }

    /// Current byte offset.
    pub fn pos(&self) -> usize {
        self.pos
    }

    /// Bytes left after the cursor.
    pub fn remaining(&self) -> usize {
        self.end - self.pos
    }

    /// Moves the end of the readable bytes to `end` (never past the input's own end, nor before the cursor);
    /// returns the end it replaced, for [`Self::set_end`] to restore.
    pub fn limit_to(&mut self, end: u64) -> usize {
        let old = self.end;
        self.end = usize::try_from(end)
            .unwrap_or(usize::MAX)
            .clamp(self.pos, old);
        old
    }

    /// Restores an end [`Self::limit_to`] returned.
    pub fn set_end(&mut self, end: usize) {
        self.end = end;
    }

    /// Moves the cursor to an absolute offset inside the input.
    pub fn seek(&mut self, pos: u64) -> KResult<()> {
        if pos > self.end as u64 {
            return corrupt(format!(
                "offset {pos} beyond the end of the data ({} bytes)",
                self.end
            ));
        }
        if let Source::File { file, .. } = &mut self.source {
            // A relative seek keeps the buffer when the target lies inside it.
            file.seek_relative(pos as i64 - self.pos as i64)?;
        }
        self.pos = pos as usize;
        Ok(())
    }

    /// Fails unless at least `n` bytes remain.
    pub fn ensure(&self, n: u64, what: &'static str) -> KResult<()> {
        if n > self.remaining() as u64 {
            return Err(VdbErrorKind::Truncated {
                what,
                offset: self.pos,
                needed: n,
                remaining: self.remaining(),
            });
        }
        Ok(())
    }

    /// Takes the next `n` bytes (from a file: into a buffer the next read reuses, never more than the file
    /// holds).
    pub fn take(&mut self, n: u64, what: &'static str) -> KResult<&[u8]> {
        self.ensure(n, what)?;
        let n = n as usize;
        let start = self.pos;
        self.pos += n;
        match &mut self.source {
            Source::Slice(data) => Ok(&data[start..start + n]),
            Source::File { file, scratch } => {
                scratch.resize(n, 0);
                file.read_exact(scratch)?;
                Ok(scratch)
            }
        }
    }

    /// Appends the next `n` bytes to `sink` (from a file: read straight into it, never more than the file
    /// holds).
    pub fn append_to(&mut self, n: u64, what: &'static str, sink: &mut Vec<u8>) -> KResult<()> {
        self.ensure(n, what)?;
        let n = n as usize;
        let start = self.pos;
        self.pos += n;
        match &mut self.source {
            Source::Slice(data) => sink.extend_from_slice(&data[start..start + n]),
            Source::File { file, .. } => {
                let old = sink.len();
                sink.resize(old + n, 0);
                file.read_exact(&mut sink[old..])?;
            }
        }
        Ok(())
    }

    fn arr<const N: usize>(&mut self, what: &'static str) -> KResult<[u8; N]> {
        let s = self.take(N as u64, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }

    /// Reads one byte.
    pub fn u8(&mut self, what: &'static str) -> KResult<u8> {
        Ok(self.arr::<1>(what)?[0])
    }
    /// Reads a little-endian `u32`.
    pub fn u32(&mut self, what: &'static str) -> KResult<u32> {
        Ok(u32::from_le_bytes(self.arr(what)?))
    }
    /// Reads a little-endian `i32`.
    pub fn i32(&mut self, what: &'static str) -> KResult<i32> {
        Ok(i32::from_le_bytes(self.arr(what)?))
    }
    /// Reads a little-endian `i64`.
    pub fn i64(&mut self, what: &'static str) -> KResult<i64> {
        Ok(i64::from_le_bytes(self.arr(what)?))
    }
    /// Reads a little-endian `f64`.
    pub fn f64(&mut self, what: &'static str) -> KResult<f64> {
        Ok(f64::from_le_bytes(self.arr(what)?))
    }
    /// Reads three `i32`.
    pub fn ivec3(&mut self, what: &'static str) -> KResult<IVec3> {
        Ok(IVec3::new(
            self.i32(what)?,
            self.i32(what)?,
            self.i32(what)?,
        ))
    }
    /// Reads three `f64`.
    pub fn dvec3(&mut self, what: &'static str) -> KResult<DVec3> {
        Ok(DVec3::new(
            self.f64(what)?,
            self.f64(what)?,
            self.f64(what)?,
        ))
    }
    /// Reads a `u32` length followed by that many bytes, as (lossy) UTF-8.
    pub fn string(&mut self, what: &'static str) -> KResult<String> {
        let n = self.u32(what)?;
        let b = self.take(n as u64, what)?;
        Ok(String::from_utf8_lossy(b).into_owned())
    }
    /// Reads a bit mask of `W` little-endian 64-bit words.
    pub fn mask<const W: usize>(&mut self, what: &'static str) -> KResult<[u64; W]> {
        let s = self.take(8 * W as u64, what)?;
        let mut m = [0u64; W];
        for (w, c) in m.iter_mut().zip(s.chunks_exact(8)) {
            *w = u64::from_le_bytes(c.try_into().expect("8 bytes"));
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_bounds() {
        let d = [1u8, 0, 0, 0, 2, 0, 0, 0, b'a'];
        let mut r = Reader::new(&d);
        assert_eq!(r.u32("a").unwrap(), 1);
        assert!(r.string("s").is_err());
        let mut r = Reader::new(&d[4..]);
        assert!(r.string("s").is_err());
        let mut r = Reader::new(&[1, 0, 0, 0, b'x']);
        assert_eq!(r.string("s").unwrap(), "x");
        assert!(r.u8("end").is_err());
        assert!(r.seek(6).is_err());
    }

    /// A file streams the same values as its bytes in memory, through forward and backward seeks and a limited
    /// end, and a read past the end is refused before anything is read.
    #[test]
    fn a_file_reads_as_its_bytes() {
        let data: Vec<u8> = (0..200_000u32).flat_map(|i| i.to_le_bytes()).collect();
        let path = std::env::temp_dir().join(format!("nimbus-stream-{}.bin", std::process::id()));
        std::fs::write(&path, &data).unwrap();
        let file = std::fs::File::open(&path).unwrap();
        let mut from_file = Reader::from_file(file, data.len() as u64);
        let mut in_memory = Reader::new(&data);
        for r in [&mut from_file, &mut in_memory] {
            assert_eq!(r.u32("a").unwrap(), 0);
            r.seek(4 * 150_000).unwrap();
            assert_eq!(r.u32("b").unwrap(), 150_000);
            r.seek(4 * 7).unwrap();
            assert_eq!(r.u32("c").unwrap(), 7);
            assert_eq!(r.take(8, "d").unwrap(), &[8, 0, 0, 0, 9, 0, 0, 0]);
            let mut sink = vec![1];
            r.append_to(4, "appended", &mut sink).unwrap();
            assert_eq!(sink, [1, 10, 0, 0, 0]);
            r.seek(4 * 10).unwrap();
            let old = r.limit_to(4 * 11);
            assert_eq!(r.u32("e").unwrap(), 10);
            assert!(r.u32("past the limit").is_err());
            r.set_end(old);
            assert_eq!(r.u32("f").unwrap(), 11);
            assert!(r.take(u64::MAX / 2, "huge").is_err());
            assert!(r.seek(data.len() as u64 + 1).is_err());
        }
        std::fs::remove_file(&path).ok();
    }
}
