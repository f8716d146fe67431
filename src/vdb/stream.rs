//! A bounds-checked little-endian byte reader: every read checks the remaining input first.

use super::error::{corrupt, KResult, VdbErrorKind};
use glam::{DVec3, IVec3};

/// Cursor over an in-memory byte slice.
pub(crate) struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    /// A reader at the start of `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    /// Current byte offset.
    pub fn pos(&self) -> usize {
        self.pos
    }

    /// Bytes left after the cursor.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Moves the cursor to an absolute offset inside the input.
    pub fn seek(&mut self, pos: u64) -> KResult<()> {
        if pos > self.data.len() as u64 {
            return corrupt(format!(
                "offset {pos} beyond the end of the data ({} bytes)",
                self.data.len()
            ));
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

    /// Takes the next `n` bytes.
    pub fn take(&mut self, n: u64, what: &'static str) -> KResult<&'a [u8]> {
        self.ensure(n, what)?;
        let s = &self.data[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(s)
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
}
