//! Cryptomatte ID mattes after the public Psyop specification v1.1 ("Cryptomatte Specification", Friedman &
//! Jones): names hashed with MurmurHash3_x86_32, the hash stored as a float, and per pixel the IDs ranked by their
//! coverage.
//!
//! - Three kinds ([`CryptoKind`]): `CryptoObject` (glTF node or USD prim of a surface, a medium's name),
//!   `CryptoMaterial` (material name; a medium's own name) and `CryptoAsset` (the top-level node or USD
//!   `component` model).
//! - An ID is the 32-bit MurmurHash3 of the name's UTF-8 bytes with seed 0 ([`murmur3_32`]); the float in the
//!   pixels is the hash's bits with the exponent clamped to \[1, 254\] ([`id_to_float`]), so that no ID is a
//!   NaN, an infinity or a denormal.
//! - Each kind writes `depth / 2` layers `<Kind>00`, `<Kind>01`, … whose channels `r`, `g`, `b`, `a` hold rank
//!   `2k`'s ID and coverage and rank `2k + 1`'s (the specification's lower-case channel names, as Cycles writes
//!   them). A pixel's ranks are its IDs sorted by coverage, largest first (ties by ID), cut after `depth`.
//! - The header carries `cryptomatte/<key>/name`, `hash` (`MurmurHash3_32`), `conversion`
//!   (`uint32_to_float32`) and `manifest`, a JSON object of name → the 8 hexadecimal digits of the float ID's
//!   bits (the specification's convention; Cycles 5.0 writes the hash before the exponent clamp there, which
//!   differs for 1 name in 128). `<key>` is the first 7 hexadecimal digits of the hash of the layer's name.
//!
//! Coverage: every camera sample gives its whole coverage (its alpha) to the one item that covered it: the
//! first surface its camera ray hits, or the medium it first scatters in (see the integrator). A pixel's ID
//! coverage is the mean over its samples, so the ranks of a pixel sum to its alpha.

use std::collections::BTreeMap;

/// The kinds of Cryptomatte names, in the order the film keeps them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CryptoKind {
    /// Objects: glTF nodes (meshes and volumes), USD prims.
    Object,
    /// Materials (a medium's own name).
    Material,
    /// Assets: top-level glTF nodes, USD `component` models.
    Asset,
}

impl CryptoKind {
    /// Every kind.
    pub const ALL: [CryptoKind; 3] = [CryptoKind::Object, CryptoKind::Material, CryptoKind::Asset];

    /// The layer name: `CryptoObject`, `CryptoMaterial` or `CryptoAsset`.
    pub fn layer_name(self) -> &'static str {
        match self {
            CryptoKind::Object => "CryptoObject",
            CryptoKind::Material => "CryptoMaterial",
            CryptoKind::Asset => "CryptoAsset",
        }
    }

    /// The kind whose layer name is `name`.
    pub fn from_layer_name(name: &str) -> Option<CryptoKind> {
        Self::ALL.into_iter().find(|k| k.layer_name() == name)
    }

    /// The 7-hexadecimal-digit metadata key of this kind's layer: the start of the hash of its name.
    pub fn metadata_key(self) -> String {
        format!("{:08x}", murmur3_32(self.layer_name().as_bytes(), 0))[..7].to_owned()
    }
}

/// The default number of ranks a pixel keeps (the specification's suggestion: three layers).
pub const DEFAULT_DEPTH: usize = 6;

/// The largest number of ranks `--cryptomatte-depth` takes.
pub const MAX_DEPTH: usize = 16;

/// The most ID entries per pixel and kind a part file may declare (a part of `n` samples holds at most `n`
/// IDs in a pixel); more is refused as a damaged file.
pub const MAX_PART_ENTRIES: usize = 1 << 16;

/// MurmurHash3_x86_32 (Appleby 2011) of `data` with `seed`: 4-byte blocks mixed with the constants
/// 0xcc9e2d51 and 0x1b873593, the tail, then the final avalanche (`fmix32`).
pub fn murmur3_32(data: &[u8], seed: u32) -> u32 {
    const C1: u32 = 0xcc9e_2d51;
    const C2: u32 = 0x1b87_3593;
    let scramble = |k: u32| k.wrapping_mul(C1).rotate_left(15).wrapping_mul(C2);
    let mut h = seed;
    let blocks = data.chunks_exact(4);
    let tail = blocks.remainder();
    for block in blocks {
        let k = u32::from_le_bytes([block[0], block[1], block[2], block[3]]);
        h ^= scramble(k);
        h = h.rotate_left(13).wrapping_mul(5).wrapping_add(0xe654_6b64);
    }
    if !tail.is_empty() {
        let k = tail
            .iter()
            .rev()
            .fold(0u32, |acc, &b| (acc << 8) | b as u32);
        h ^= scramble(k);
    }
    h ^= data.len() as u32;
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// The float whose bits are `hash` with the exponent clamped to \[1, 254\] (the specification's
/// `uint32_to_float32`): flipping the lowest exponent bit where the exponent is all zeros or all ones.
pub fn id_to_float(hash: u32) -> f32 {
    let exponent = (hash >> 23) & 0xff;
    let bits = if exponent == 0 || exponent == 0xff {
        hash ^ (1 << 23)
    } else {
        hash
    };
    f32::from_bits(bits)
}

/// The Cryptomatte ID of a name: the bits of its float ([`id_to_float`] of [`murmur3_32`] with seed 0).
pub fn name_id(name: &str) -> u32 {
    id_to_float(murmur3_32(name.as_bytes(), 0)).to_bits()
}

/// The manifest of one kind: every name and its ID.
pub type Manifest = BTreeMap<String, u32>;

/// The manifest as the specification's JSON object: name → 8 lower-case hexadecimal digits of the ID.
pub fn manifest_json(manifest: &Manifest) -> String {
    let object: serde_json::Map<String, serde_json::Value> = manifest
        .iter()
        .map(|(name, id)| (name.clone(), format!("{id:08x}").into()))
        .collect();
    serde_json::Value::Object(object).to_string()
}

/// Reads a manifest written by [`manifest_json`]; `None` when it is not one.
pub fn parse_manifest(json: &str) -> Option<Manifest> {
    let value: serde_json::Value = serde_json::from_str(json).ok()?;
    value
        .as_object()?
        .iter()
        .map(|(name, hex)| Some((name.clone(), u32::from_str_radix(hex.as_str()?, 16).ok()?)))
        .collect()
}

/// The coverage sums of one pixel for one kind: (ID, summed coverage in units of 2^-32 of a sample), sorted by
/// ID. Integer sums, so that parts of a render add up to the bits of the whole.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IdCoverage(Vec<(u32, u64)>);

/// One sample's whole coverage in [`IdCoverage`] units.
pub const COVERAGE_UNIT: f64 = 4_294_967_296.0;

impl IdCoverage {
    /// Adds `weight` (a sample's coverage, in \[0, 1\]) to `id`.
    pub fn add(&mut self, id: u32, weight: f32) {
        let units = (weight.clamp(0.0, 1.0) as f64 * COVERAGE_UNIT).round() as u64;
        if units > 0 {
            self.add_units(id, units);
        }
    }

    /// Adds `units` of coverage to `id`.
    pub fn add_units(&mut self, id: u32, units: u64) {
        match self.0.binary_search_by_key(&id, |e| e.0) {
            Ok(i) => self.0[i].1 += units,
            Err(i) => self.0.insert(i, (id, units)),
        }
    }

    /// Adds every ID of `other`, or returns false (leaving this map as it was) where an ID's coverage would not
    /// fit: coverage read from files is not bounded by the samples behind it.
    #[must_use]
    pub fn checked_merge(&mut self, other: &IdCoverage) -> bool {
        let fits =
            other.0.iter().all(
                |&(id, units)| match self.0.binary_search_by_key(&id, |e| e.0) {
                    Ok(i) => self.0[i].1.checked_add(units).is_some(),
                    Err(_) => true,
                },
            );
        if fits {
            for &(id, units) in &other.0 {
                self.add_units(id, units);
            }
        }
        fits
    }

    /// The (ID, coverage units) pairs, sorted by ID.
    pub fn entries(&self) -> &[(u32, u64)] {
        &self.0
    }

    /// The first `depth` ranks for a pixel of `samples` samples: (ID as a float, coverage), largest coverage
    /// first, ties broken by ID; missing ranks are (0, 0).
    pub fn ranks(&self, samples: u32, depth: usize) -> Vec<(f32, f32)> {
        let mut sorted = self.0.clone();
        sorted.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        let scale = 1.0 / (COVERAGE_UNIT * samples.max(1) as f64);
        (0..depth)
            .map(|r| match sorted.get(r) {
                Some(&(id, units)) => (f32::from_bits(id), (units as f64 * scale) as f32),
                None => (0.0, 0.0),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn murmur3_matches_published_vectors() {
        // Test vectors of the reference implementation (SMHasher's MurmurHash3_x86_32).
        assert_eq!(murmur3_32(b"", 0), 0);
        assert_eq!(murmur3_32(b"", 1), 0x514e_28b7);
        assert_eq!(murmur3_32(b"", 0xffff_ffff), 0x81f1_6f39);
        assert_eq!(murmur3_32(&[0, 0, 0, 0], 0), 0x2362_f9de);
        assert_eq!(murmur3_32(b"a", 0x9747_b28c), 0x7fa0_9ea6);
        assert_eq!(murmur3_32(b"abc", 0x9747_b28c), 0xc84a_62dd);
        assert_eq!(murmur3_32(b"abcd", 0x9747_b28c), 0xf047_8627);
        assert_eq!(murmur3_32(b"Hello, world!", 0x9747_b28c), 0x2488_4cba);
        assert_eq!(
            murmur3_32(b"The quick brown fox jumps over the lazy dog", 0x9747_b28c),
            0x2fa8_26cd
        );
    }

    #[test]
    fn specification_examples() {
        // The specification's example manifest: {"bunny":"13851a76", "default":"42c9679f"},
        // {"bunny_porcelain_mat":"b24b26d4"}.
        assert_eq!(name_id("bunny"), 0x1385_1a76);
        assert_eq!(name_id("default"), 0x42c9_679f);
        assert_eq!(name_id("bunny_porcelain_mat"), 0xb24b_26d4);
        // Metadata keys are the start of the layer name's hash: Cycles 5.0 writes 542cafa for its layer
        // "ViewLayer.CryptoObject" (tests/cryptomatte/cycles_ids.json).
        assert_eq!(
            &format!("{:08x}", murmur3_32(b"ViewLayer.CryptoObject", 0))[..7],
            "542cafa"
        );
    }

    #[test]
    fn float_ids_are_never_nan_infinite_or_denormal() {
        for hash in [
            0u32,
            1,
            0x007f_ffff,
            0x7f80_0000,
            0x7fff_ffff,
            0xff80_0001,
            0x8000_0000,
        ] {
            let f = id_to_float(hash);
            assert!(f.is_normal(), "{hash:08x} -> {f}");
            // Only the lowest exponent bit ever changes.
            assert_eq!((f.to_bits() ^ hash) & !(1 << 23), 0);
        }
        assert_eq!(id_to_float(0x4000_0001).to_bits(), 0x4000_0001);
    }

    #[test]
    fn manifest_round_trips_through_json() {
        let mut m = Manifest::new();
        m.insert("Würfel \"#2\"".into(), name_id("Würfel \"#2\""));
        m.insert("floor".into(), name_id("floor"));
        let json = manifest_json(&m);
        assert!(json.contains(&format!("{:08x}", name_id("floor"))));
        assert_eq!(parse_manifest(&json), Some(m));
        assert_eq!(parse_manifest("[1]"), None);
    }

    #[test]
    fn ranks_sort_by_coverage_and_sum_to_the_coverage() {
        let mut c = IdCoverage::default();
        let (a, b, d) = (name_id("a"), name_id("b"), name_id("d"));
        for _ in 0..3 {
            c.add(a, 1.0);
        }
        c.add(b, 0.5);
        c.add(d, 1.0);
        c.add(d, 0.25);
        let mut other = IdCoverage::default();
        other.add(b, 1.0);
        assert!(c.checked_merge(&other));
        // 8 samples: a 3, b 1.5, d 1.25, 0.25 of one sample uncovered.
        let ranks = c.ranks(8, 4);
        assert_eq!(ranks[0], (f32::from_bits(a), 3.0 / 8.0));
        assert_eq!(ranks[1], (f32::from_bits(b), 1.5 / 8.0));
        assert_eq!(ranks[2], (f32::from_bits(d), 1.25 / 8.0));
        assert_eq!(ranks[3], (0.0, 0.0));
        let total: f32 = ranks.iter().map(|r| r.1).sum();
        assert!((total - 5.75 / 8.0).abs() < 1e-7);
    }
}
