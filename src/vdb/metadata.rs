//! OpenVDB metadata maps (file-level and per-grid): `i32` count, then name, type name, `u32` size and value bytes.
//!
//! Values of unknown types (including the `__delayedload` block that OpenVDB writes for delayed loading) are
//! skipped by their size.

use super::error::{corrupt, KResult};
use super::stream::Reader;
use glam::{DVec3, IVec3, Vec3};

/// One metadata value.
#[derive(Clone, Debug, PartialEq)]
pub enum MetaValue {
    /// `string`
    String(String),
    /// `bool`
    Bool(bool),
    /// `int32`
    Int32(i32),
    /// `int64`
    Int64(i64),
    /// `float`
    Float(f32),
    /// `double`
    Double(f64),
    /// `vec3i`
    Vec3i(IVec3),
    /// `vec3s`
    Vec3s(Vec3),
    /// `vec3d`
    Vec3d(DVec3),
    /// Any other type, skipped: its type name and byte size.
    Other {
        /// OpenVDB type name.
        type_name: String,
        /// Size of the skipped value in bytes.
        size: usize,
    },
}

/// An ordered list of named metadata values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Metadata {
    /// The entries in file order.
    pub entries: Vec<(String, MetaValue)>,
}

impl Metadata {
    /// The value stored under `name`, if any.
    pub fn get(&self, name: &str) -> Option<&MetaValue> {
        self.entries.iter().find(|(n, _)| n == name).map(|(_, v)| v)
    }

    /// The string stored under `name`, if it is a string.
    pub fn get_str(&self, name: &str) -> Option<&str> {
        match self.get(name) {
            Some(MetaValue::String(s)) => Some(s),
            _ => None,
        }
    }

    /// An integer stored under `name` (int32 or int64), if any.
    #[cfg(test)]
    pub fn get_int(&self, name: &str) -> Option<i64> {
        match self.get(name) {
            Some(MetaValue::Int32(v)) => Some(*v as i64),
            Some(MetaValue::Int64(v)) => Some(*v),
            _ => None,
        }
    }

    /// The `vec3i` stored under `name`, if any.
    #[cfg(test)]
    pub fn get_vec3i(&self, name: &str) -> Option<IVec3> {
        match self.get(name) {
            Some(MetaValue::Vec3i(v)) => Some(*v),
            _ => None,
        }
    }
}

/// Reads a metadata map.
pub(crate) fn read_metadata(r: &mut Reader<'_>) -> KResult<Metadata> {
    let count = r.i32("metadata count")?;
    // Each entry takes at least 12 bytes (three u32 lengths).
    if count < 0 || count as u64 * 12 > r.remaining() as u64 {
        return corrupt(format!("metadata count {count} does not fit the data"));
    }
    let mut entries = Vec::with_capacity(count as usize);
    for _ in 0..count {
        let name = r.string("metadata name")?;
        let type_name = r.string("metadata type")?;
        let size = r.u32("metadata size")?;
        let b = r.take(size as u64, "metadata value")?;
        let f32_at = |i: usize| f32::from_le_bytes(b[i..i + 4].try_into().expect("4"));
        let f64_at = |i: usize| f64::from_le_bytes(b[i..i + 8].try_into().expect("8"));
        let i32_at = |i: usize| i32::from_le_bytes(b[i..i + 4].try_into().expect("4"));
        let v = match (type_name.as_str(), b.len()) {
            ("string", _) => MetaValue::String(String::from_utf8_lossy(b).into_owned()),
            ("bool", 1) => MetaValue::Bool(b[0] != 0),
            ("int32", 4) => MetaValue::Int32(i32_at(0)),
            ("int64", 8) => MetaValue::Int64(i64::from_le_bytes(b.try_into().expect("8"))),
            ("float", 4) => MetaValue::Float(f32_at(0)),
            ("double", 8) => MetaValue::Double(f64_at(0)),
            ("vec3i", 12) => MetaValue::Vec3i(IVec3::new(i32_at(0), i32_at(4), i32_at(8))),
            ("vec3s", 12) => MetaValue::Vec3s(Vec3::new(f32_at(0), f32_at(4), f32_at(8))),
            ("vec3d", 24) => MetaValue::Vec3d(DVec3::new(f64_at(0), f64_at(8), f64_at(16))),
            _ => MetaValue::Other {
                type_name,
                size: b.len(),
            },
        };
        entries.push((name, v));
    }
    Ok(Metadata { entries })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(v: &mut Vec<u8>, x: &str) {
        v.extend_from_slice(&(x.len() as u32).to_le_bytes());
        v.extend_from_slice(x.as_bytes());
    }

    #[test]
    fn parses_known_and_skips_unknown() {
        let mut v = 3i32.to_le_bytes().to_vec();
        s(&mut v, "class");
        s(&mut v, "string");
        s(&mut v, "fog volume");
        s(&mut v, "file_delayed_load");
        s(&mut v, "__delayedload");
        v.extend_from_slice(&5u32.to_le_bytes());
        v.extend_from_slice(&[9; 5]);
        s(&mut v, "n");
        s(&mut v, "int64");
        v.extend_from_slice(&8u32.to_le_bytes());
        v.extend_from_slice(&7i64.to_le_bytes());
        let m = read_metadata(&mut Reader::new(&v)).unwrap();
        assert_eq!(m.get_str("class"), Some("fog volume"));
        assert_eq!(m.get_int("n"), Some(7));
        assert!(matches!(
            m.get("file_delayed_load"),
            Some(MetaValue::Other { size: 5, .. })
        ));
        assert!(read_metadata(&mut Reader::new(&v[..v.len() - 1])).is_err());
    }
}
