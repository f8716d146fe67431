//! Reading a 5-4-3 tree: root topology, internal-node tiles, leaf masks, then the leaf value buffers.
//!
//! Value arrays go through OpenVDB's "compressed values" scheme: a metadata byte (file version ≥ 222) says how
//! inactive values were encoded, optionally followed by one or two inactive values and a selection mask; with
//! active-mask compression only the active values are stored and the rest are rebuilt.

use super::compression::{decode, read_stored, Codec, COMPRESS_ACTIVE_MASK};
use super::error::{corrupt, KResult, VdbErrorKind};
use super::grid::{InternalNode, Leaf, LowerNode, Root, RootSlot, Tree, UpperNode, VoxelValue};
use super::half::half_to_f32;
use super::stream::Reader;
use glam::IVec3;
use rayon::prelude::*;

/// File version that introduced the per-buffer compression metadata byte and node-mask compression.
pub const VERSION_NODE_MASK_COMPRESSION: u32 = 222;

/// Inactive-value encodings of the compressed-values metadata byte.
pub mod mask_mode {
    /// All inactive values are the background.
    pub const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
    /// All inactive values are minus the background.
    pub const NO_MASK_AND_MINUS_BG: u8 = 1;
    /// All inactive values equal one stored value.
    pub const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
    /// Inactive values are ±background, chosen by a selection mask.
    pub const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
    /// Inactive values are a stored value or the background, chosen by a selection mask.
    pub const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
    /// Inactive values are one of two stored values, chosen by a selection mask.
    pub const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
    /// Every value is stored.
    pub const NO_MASK_AND_ALL_VALS: u8 = 6;
}
use mask_mode::*;

/// Scalar storage of the values on disk.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    F32,
    F64,
}

/// Settings for reading one grid's tree.
pub(crate) struct TreeCtx {
    pub version: u32,
    pub compression: u32,
    pub scalar: Scalar,
    pub half: bool,
    /// The stored bytes of the internal-node array being read.
    stored: Vec<u8>,
    /// Its decoded bytes.
    scratch: Vec<u8>,
}

impl TreeCtx {
    pub fn new(version: u32, compression: u32, scalar: Scalar, half: bool) -> Self {
        Self {
            version,
            compression,
            scalar,
            half,
            stored: Vec::new(),
            scratch: Vec::new(),
        }
    }

    /// Bytes of one value at full precision in the file.
    fn full_size<T: VoxelValue>(&self) -> usize {
        T::COMPONENTS * if self.scalar == Scalar::F64 { 8 } else { 4 }
    }

    /// Bytes of one value in a value buffer: half or full precision.
    fn stored_size<T: VoxelValue>(&self) -> usize {
        if self.half {
            2 * T::COMPONENTS
        } else {
            self.full_size::<T>()
        }
    }
}

fn decode_full<T: VoxelValue>(b: &[u8], scalar: Scalar) -> T {
    match scalar {
        Scalar::F32 => {
            T::from_components(|c| f32::from_le_bytes(b[4 * c..4 * c + 4].try_into().expect("4")))
        }
        Scalar::F64 => T::from_components(|c| {
            f64::from_le_bytes(b[8 * c..8 * c + 8].try_into().expect("8")) as f32
        }),
    }
}

fn read_full<T: VoxelValue>(r: &mut Reader<'_>, ctx: &TreeCtx, what: &'static str) -> KResult<T> {
    let b = r.take(ctx.full_size::<T>() as u64, what)?;
    Ok(decode_full(b, ctx.scalar))
}

fn read_mask_vec(r: &mut Reader<'_>, words: usize, what: &'static str) -> KResult<Vec<u64>> {
    let b = r.take(8 * words as u64, what)?;
    Ok(b.chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8")))
        .collect())
}

fn popcount(m: &[u64]) -> usize {
    m.iter().map(|w| w.count_ones() as usize).sum()
}

/// The header of one array under the compressed-values scheme: what fills its inactive values and how many
/// values its stored bytes hold.
struct ValuesHeader<T> {
    /// The inactive value where no selection bit is set (`background` or its negation unless the mode stores
    /// it).
    inactive0: T,
    /// The inactive value where a selection bit is set (`background` unless the mode stores it).
    inactive1: T,
    /// The selection mask, for the modes that store one.
    selection: Option<Vec<u64>>,
    /// Values stored: the active ones with active-mask compression, else all.
    count: usize,
}

impl<T: VoxelValue> ValuesHeader<T> {
    /// Reads the header of an array of `values` values whose active bits are `value_mask` (OpenVDB
    /// `readCompressedValues`, up to the value bytes).
    fn read(
        r: &mut Reader<'_>,
        ctx: &TreeCtx,
        background: T,
        value_mask: &[u64],
        values: usize,
    ) -> KResult<Self> {
        let new_format = ctx.version >= VERSION_NODE_MASK_COMPRESSION;
        let mode = if new_format {
            r.u8("compression metadata")?
        } else {
            NO_MASK_AND_ALL_VALS
        };
        if mode > NO_MASK_AND_ALL_VALS {
            return corrupt(format!("invalid compression metadata {mode}"));
        }
        let mut inactive1 = background;
        // The modes that store the inactive value replace it below.
        let mut inactive0 = match mode {
            NO_MASK_OR_INACTIVE_VALS => background,
            NO_MASK_AND_MINUS_BG => background.neg(),
            _ => background.neg(),
        };
        if matches!(
            mode,
            NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            inactive0 = read_full(r, ctx, "inactive value")?;
            if mode == MASK_AND_TWO_INACTIVE_VALS {
                inactive1 = read_full(r, ctx, "second inactive value")?;
            }
        }
        let selection = if matches!(
            mode,
            MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            Some(read_mask_vec(r, values / 64, "selection mask")?)
        } else {
            None
        };
        let mask_compressed = ctx.compression & COMPRESS_ACTIVE_MASK != 0;
        let count = if mask_compressed && mode != NO_MASK_AND_ALL_VALS && new_format {
            popcount(value_mask)
        } else {
            values
        };
        Ok(Self {
            inactive0,
            inactive1,
            selection,
            count,
        })
    }

    /// Reads the array's stored bytes (after its header), appending them to `sink`: their codec, or `None` when
    /// nothing is stored (OpenVDB's half reader returns before touching the stream when there is nothing to
    /// read).
    fn read_stored(
        &self,
        r: &mut Reader<'_>,
        ctx: &TreeCtx,
        sink: &mut Vec<u8>,
    ) -> KResult<Option<Codec>> {
        if ctx.half && self.count == 0 {
            return Ok(None);
        }
        read_stored(
            r,
            ctx.compression,
            self.count * ctx.stored_size::<T>(),
            sink,
        )
        .map(Some)
    }

    /// Fills `out` from the decoded bytes of the stored values `decoded` (`count` of them) and the inactive
    /// values, by the active bits `value_mask`.
    fn fill(&self, ctx: &TreeCtx, decoded: &[u8], value_mask: &[u64], out: &mut [T]) {
        let elem = ctx.stored_size::<T>();
        let (half, scalar) = (ctx.half, ctx.scalar);
        let get = |b: &[u8]| -> T {
            if half {
                T::from_components(|c| half_to_f32(u16::from_le_bytes([b[2 * c], b[2 * c + 1]])))
            } else {
                decode_full(b, scalar)
            }
        };
        if self.count == out.len() {
            for (o, b) in out.iter_mut().zip(decoded.chunks_exact(elem)) {
                *o = get(b);
            }
            return;
        }
        let mut stored = decoded.chunks_exact(elem);
        for (i, o) in out.iter_mut().enumerate() {
            let on = value_mask[i >> 6] >> (i & 63) & 1 != 0;
            *o = if on {
                // count == popcount(value_mask), so a stored value is always left here.
                stored.next().map_or(self.inactive0, get)
            } else if self
                .selection
                .as_ref()
                .is_some_and(|s| s[i >> 6] >> (i & 63) & 1 != 0)
            {
                self.inactive1
            } else {
                self.inactive0
            };
        }
    }

    /// Decodes the stored bytes `stored` (of `codec`, `None` for none) into `out`, through `scratch`.
    fn decode(
        &self,
        ctx: &TreeCtx,
        stored: Option<(Codec, &[u8])>,
        scratch: &mut Vec<u8>,
        value_mask: &[u64],
        out: &mut [T],
    ) -> KResult<()> {
        let nbytes = self.count * ctx.stored_size::<T>();
        let decoded: &[u8] = match stored {
            Some((Codec::Raw, bytes)) => bytes,
            Some((codec, bytes)) => {
                scratch.clear();
                scratch.resize(nbytes, 0);
                decode(codec, bytes, scratch)?;
                scratch
            }
            // Nothing stored: every value is inactive (a half array with no active values).
            None => &[],
        };
        self.fill(ctx, decoded, value_mask, out);
        Ok(())
    }
}

/// Reads one array of `out.len()` values under the compressed-values scheme (OpenVDB `readCompressedValues`).
pub(crate) fn read_values<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    background: T,
    value_mask: &[u64],
    out: &mut [T],
) -> KResult<()> {
    let header = ValuesHeader::read(r, ctx, background, value_mask, out.len())?;
    let mut stored = std::mem::take(&mut ctx.stored);
    stored.clear();
    let codec = header.read_stored(r, ctx, &mut stored)?;
    let mut scratch = std::mem::take(&mut ctx.scratch);
    let decoded = header.decode(
        ctx,
        codec.map(|c| (c, &stored[..])),
        &mut scratch,
        value_mask,
        out,
    );
    ctx.stored = stored;
    ctx.scratch = scratch;
    decoded
}

/// Reads an internal node's masks and tile values; returns the node and its child mask.
fn read_internal<T: VoxelValue, const LOG2: i32, const CHILD_LOG2: i32>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    background: T,
    origin: IVec3,
) -> KResult<(InternalNode<T, LOG2, CHILD_LOG2>, Vec<u64>)> {
    let n = InternalNode::<T, LOG2, CHILD_LOG2>::SLOTS;
    let child_mask = read_mask_vec(r, n / 64, "internal child mask")?;
    let value_mask = read_mask_vec(r, n / 64, "internal value mask")?;
    let mut tiles = vec![background; n];
    read_values(r, ctx, background, &value_mask, &mut tiles)?;
    let node = InternalNode::from_tiles(origin, tiles, value_mask, background);
    Ok((node, child_mask))
}

fn set_bits(mask: &[u64]) -> impl Iterator<Item = usize> + '_ {
    mask.iter().enumerate().flat_map(|(w, &word)| {
        let mut word = word;
        std::iter::from_fn(move || {
            if word == 0 {
                return None;
            }
            let b = word.trailing_zeros() as usize;
            word &= word - 1;
            Some(w * 64 + b)
        })
    })
}

/// Reads the topology of the upper node at `origin` under the root: its lower nodes go to `tree.lowers` and the
/// origins of its leaves (whose buffers come later) to `leaf_origins`, in depth-first order.
fn read_upper<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    tree: &mut Tree<T>,
    leaf_origins: &mut Vec<IVec3>,
    origin: IVec3,
) -> KResult<UpperNode<T>> {
    let background = tree.background;
    let (mut upper, umask): (UpperNode<T>, _) = read_internal(r, ctx, background, origin)?;
    for ui in set_bits(&umask) {
        let lorigin = upper.slot_origin(ui);
        let (mut lower, lmask): (LowerNode<T>, _) = read_internal(r, ctx, background, lorigin)?;
        for li in set_bits(&lmask) {
            // The topology's value mask; the buffer repeats it, and the buffer's is the one kept.
            r.mask::<8>("leaf value mask")?;
            lower.children[li] = leaf_origins.len() as u32;
            leaf_origins.push(lower.slot_origin(li));
        }
        upper.children[ui] = tree.lowers.len() as u32;
        tree.lowers.push(lower);
    }
    Ok(upper)
}

/// The stored bytes of the leaf buffers read in one batch, with at least this many bytes (or the last leaves).
const LEAF_BATCH_BYTES: usize = 1 << 20;

/// One leaf buffer as the sequential scan found it: its active mask, its header and where its stored bytes lie
/// in the batch.
struct LeafRecord<T> {
    value_mask: [u64; 8],
    header: ValuesHeader<T>,
    /// Codec and byte range in [`LeafBatch::bytes`]; `None` when nothing is stored.
    stored: Option<(Codec, std::ops::Range<usize>)>,
}

/// The buffers of a run of consecutive leaves: read sequentially from the file, then decoded in parallel.
struct LeafBatch<T> {
    /// Index of the first leaf.
    first: usize,
    records: Vec<LeafRecord<T>>,
    /// The stored bytes of every record, one after the other.
    bytes: Vec<u8>,
}

impl<T: VoxelValue> LeafBatch<T> {
    fn new() -> Self {
        Self {
            first: 0,
            records: Vec::new(),
            bytes: Vec::new(),
        }
    }

    /// The leaf after the batch's last.
    fn end(&self) -> usize {
        self.first + self.records.len()
    }

    /// Reads the buffers of the leaves from `first` on, in file order, until the batch holds
    /// [`LEAF_BATCH_BYTES`] or the leaf `leaves - 1` is read. On an error the batch keeps the leaves before it.
    fn scan(
        &mut self,
        r: &mut Reader<'_>,
        ctx: &TreeCtx,
        background: T,
        first: usize,
        leaves: usize,
    ) -> KResult<()> {
        self.first = first;
        self.records.clear();
        self.bytes.clear();
        while self.end() < leaves && self.bytes.len() < LEAF_BATCH_BYTES {
            let value_mask = r.mask::<8>("leaf buffer mask")?;
            if ctx.version < VERSION_NODE_MASK_COMPRESSION {
                r.ivec3("leaf origin")?;
                let nbuf = r.u8("leaf buffer count")?;
                if nbuf != 1 {
                    return corrupt(format!("leaf has {nbuf} buffers, expected 1"));
                }
            }
            let header = ValuesHeader::read(r, ctx, background, &value_mask, 512)?;
            let start = self.bytes.len();
            let codec = header.read_stored(r, ctx, &mut self.bytes)?;
            self.records.push(LeafRecord {
                value_mask,
                header,
                stored: codec.map(|c| (c, start..self.bytes.len())),
            });
        }
        Ok(())
    }

    /// Decodes the batch's leaves in parallel, appending them to `tree.leaves` in order (at `leaf_origins`);
    /// the first failing leaf's error, in file order.
    fn decode(
        &self,
        ctx: &TreeCtx,
        leaf_origins: &[IVec3],
        leaves: &mut Vec<Leaf<T>>,
    ) -> KResult<()> {
        let first_error = FirstError::default();
        let origins = &leaf_origins[self.first..self.end()];
        let decoded = self
            .records
            .par_iter()
            .zip(origins.par_iter())
            .enumerate()
            .map_init(Vec::new, |scratch, (i, (record, &origin))| {
                // Every value is written by the decoding (or the leaf is dropped with the error).
                let mut values = [record.header.inactive0; 512];
                let stored = record
                    .stored
                    .as_ref()
                    .map(|(codec, range)| (*codec, &self.bytes[range.clone()]));
                if let Err(e) =
                    record
                        .header
                        .decode(ctx, stored, scratch, &record.value_mask, &mut values)
                {
                    first_error.offer(i, e);
                }
                Leaf::with_values(origin, record.value_mask, values)
            });
        leaves.par_extend(decoded);
        first_error.into_result()
    }
}

/// The error of the first failing item (by index) among items processed in parallel.
#[derive(Default)]
struct FirstError(std::sync::Mutex<Option<(usize, VdbErrorKind)>>);

impl FirstError {
    /// Records the error of item `index`, kept if no earlier item's is.
    fn offer(&self, index: usize, error: VdbErrorKind) {
        let mut first = self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if first.as_ref().is_none_or(|(i, _)| index < *i) {
            *first = Some((index, error));
        }
    }

    /// The first error recorded, if any.
    fn into_result(self) -> KResult<()> {
        match self
            .0
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
        {
            Some((_, error)) => Err(error),
            None => Ok(()),
        }
    }
}

/// Reads the buffers of the leaves at `leaf_origins` (in the depth-first order of the topology) into
/// `tree.leaves`: each leaf's value mask and values. The file is read sequentially, a batch at a time, while
/// the batch read before it is decoded in parallel; an error is the first in file order, as when read one by
/// one.
fn read_leaf_buffers<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &TreeCtx,
    tree: &mut Tree<T>,
    leaf_origins: &[IVec3],
) -> KResult<()> {
    let (background, count) = (tree.background, leaf_origins.len());
    tree.leaves = Vec::with_capacity(count);
    let (mut batch, mut next) = (LeafBatch::new(), LeafBatch::new());
    let mut scanned = batch.scan(r, ctx, background, 0, count);
    loop {
        if scanned.is_err() || batch.end() == count {
            // The leaves read before a scan error decode first: one of them may fail earlier in the file.
            batch.decode(ctx, leaf_origins, &mut tree.leaves)?;
            return scanned;
        }
        let leaves = &mut tree.leaves;
        let (decoded, next_scanned) = rayon::join(
            || batch.decode(ctx, leaf_origins, leaves),
            || next.scan(r, ctx, background, batch.end(), count),
        );
        decoded?;
        scanned = next_scanned;
        std::mem::swap(&mut batch, &mut next);
    }
}

/// Reads a whole tree (topology then buffers) at the reader's position.
pub(crate) fn read_tree<T: VoxelValue>(r: &mut Reader<'_>, ctx: &mut TreeCtx) -> KResult<Tree<T>> {
    let buffer_count = r.i32("tree buffer count")?;
    if buffer_count != 1 {
        return corrupt(format!("tree buffer count {buffer_count}, expected 1"));
    }
    let background: T = read_full(r, ctx, "background")?;
    let num_tiles = r.u32("root tile count")? as u64;
    let num_children = r.u32("root child count")? as u64;
    let tile_bytes = 12 + ctx.full_size::<T>() as u64 + 1;
    // An origin and an upper node's child and value masks.
    let min_child_bytes = 12 + 2 * (UpperNode::<T>::SLOTS / 8) as u64;
    if num_tiles * tile_bytes + num_children * min_child_bytes > r.remaining() as u64 {
        return corrupt(format!(
            "root claims {num_tiles} tiles and {num_children} children, more than the data holds"
        ));
    }
    let mut tree = Tree::new(background);
    let mut leaf_origins = Vec::new();
    for _ in 0..num_tiles {
        let origin = r.ivec3("root tile origin")?;
        let value = read_full(r, ctx, "root tile value")?;
        let active = r.u8("root tile active flag")? != 0;
        if Root::<T>::key(origin) != origin {
            return corrupt(format!(
                "root tile origin {origin} is not aligned to {}",
                Root::<T>::DIM
            ));
        }
        tree.root
            .entries
            .push((origin, RootSlot::Tile { value, active }));
    }
    for _ in 0..num_children {
        let origin = r.ivec3("root child origin")?;
        if Root::<T>::key(origin) != origin {
            return corrupt(format!(
                "root child origin {origin} is not aligned to {}",
                Root::<T>::DIM
            ));
        }
        let upper = read_upper(r, ctx, &mut tree, &mut leaf_origins, origin)?;
        tree.root
            .entries
            .push((origin, RootSlot::Child(tree.uppers.len() as u32)));
        tree.uppers.push(upper);
    }
    tree.root.entries.sort_by_key(|e| (e.0.x, e.0.y, e.0.z));
    if tree.root.entries.windows(2).any(|w| w[0].0 == w[1].0) {
        return corrupt("duplicate root table entries");
    }
    read_leaf_buffers(r, ctx, &mut tree, &leaf_origins)?;
    tree.lowers.shrink_to_fit();
    tree.uppers.shrink_to_fit();
    // The leaves' ranges were computed as they were decoded.
    tree.finalize_nodes();
    Ok(tree)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vdb::compression::COMPRESS_ZIP;

    fn ctx(compression: u32) -> TreeCtx {
        TreeCtx::new(224, compression, Scalar::F32, false)
    }

    fn mask_first(n: usize, count: usize) -> Vec<u64> {
        let mut m = vec![0u64; n / 64];
        for i in 0..count {
            m[i / 64] |= 1 << (i % 64);
        }
        m
    }

    fn run(mode: u8, extra: &[f32], sel: Option<&[u64]>, active: usize) -> Vec<f32> {
        let mut bytes = vec![mode];
        for v in extra {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(s) = sel {
            for w in s {
                bytes.extend_from_slice(&w.to_le_bytes());
            }
        }
        let n_stored = if mode == NO_MASK_AND_ALL_VALS {
            64
        } else {
            active
        };
        for i in 0..n_stored {
            bytes.extend_from_slice(&(100.0 + i as f32).to_le_bytes());
        }
        let mut out = vec![0.0f32; 64];
        let mask = mask_first(64, active);
        let mut c = ctx(COMPRESS_ACTIVE_MASK);
        let mut r = Reader::new(&bytes);
        read_values(&mut r, &mut c, 2.0, &mask, &mut out).unwrap();
        assert_eq!(r.remaining(), 0);
        out
    }

    #[test]
    fn all_seven_mask_modes() {
        let o = run(NO_MASK_OR_INACTIVE_VALS, &[], None, 3);
        assert_eq!(&o[..4], &[100.0, 101.0, 102.0, 2.0]);
        let o = run(NO_MASK_AND_MINUS_BG, &[], None, 3);
        assert_eq!(o[63], -2.0);
        let o = run(NO_MASK_AND_ONE_INACTIVE_VAL, &[7.0], None, 3);
        assert_eq!(o[10], 7.0);
        let sel = [1u64 << 10];
        let o = run(MASK_AND_NO_INACTIVE_VALS, &[], Some(&sel), 3);
        assert_eq!((o[9], o[10]), (-2.0, 2.0));
        let o = run(MASK_AND_ONE_INACTIVE_VAL, &[7.0], Some(&sel), 3);
        assert_eq!((o[9], o[10]), (7.0, 2.0));
        let o = run(MASK_AND_TWO_INACTIVE_VALS, &[7.0, 8.0], Some(&sel), 3);
        assert_eq!((o[9], o[10], o[2]), (7.0, 8.0, 102.0));
        let o = run(NO_MASK_AND_ALL_VALS, &[], None, 3);
        assert_eq!(o[63], 163.0);
    }

    #[test]
    fn bad_mode_and_zip_zero_count() {
        let mut c = ctx(COMPRESS_ACTIVE_MASK);
        let mut out = vec![0.0f32; 64];
        assert!(read_values(&mut Reader::new(&[9]), &mut c, 0.0, &[0], &mut out).is_err());
        // Zero active values with zip: an empty (count 0) block.
        let mut bytes = vec![NO_MASK_OR_INACTIVE_VALS];
        bytes.extend_from_slice(&0i64.to_le_bytes());
        let mut c = ctx(COMPRESS_ACTIVE_MASK | COMPRESS_ZIP);
        read_values(&mut Reader::new(&bytes), &mut c, 1.5, &[0], &mut out).unwrap();
        assert!(out.iter().all(|&v| v == 1.5));
    }

    fn words(bytes: &mut Vec<u8>, words: &[u64]) {
        words
            .iter()
            .for_each(|w| bytes.extend_from_slice(&w.to_le_bytes()));
    }

    /// A zip-compressed tree (with active-mask compression) of one upper and one lower node over
    /// `buffers.len()` leaves in the lower node's first slots, every voxel active; leaf `i`'s buffer is its
    /// all-on mask, the mode "every value stored" and then `buffers[i]`.
    fn tree_bytes(buffers: &[Vec<u8>]) -> Vec<u8> {
        let mut b = Vec::new();
        for field in [
            1i32.to_le_bytes(),
            0f32.to_le_bytes(),
            [0; 4],
            1u32.to_le_bytes(),
        ] {
            b.extend_from_slice(&field);
        }
        b.extend_from_slice(&[0; 12]);
        // Upper node: child 0, no active tiles, its tile array (nothing stored: an empty uncompressed block).
        let mut upper_children = vec![0u64; 512];
        upper_children[0] = 1;
        words(&mut b, &upper_children);
        words(&mut b, &[0; 512]);
        b.push(NO_MASK_OR_INACTIVE_VALS);
        b.extend_from_slice(&0i64.to_le_bytes());
        let mut lower_children = vec![0u64; 64];
        (0..buffers.len()).for_each(|i| lower_children[i / 64] |= 1 << (i % 64));
        words(&mut b, &lower_children);
        words(&mut b, &[0; 64]);
        b.push(NO_MASK_OR_INACTIVE_VALS);
        b.extend_from_slice(&0i64.to_le_bytes());
        buffers.iter().for_each(|_| words(&mut b, &[u64::MAX; 8]));
        for buffer in buffers {
            words(&mut b, &[u64::MAX; 8]);
            b.push(NO_MASK_AND_ALL_VALS);
            b.extend_from_slice(buffer);
        }
        b
    }

    /// Leaf `i`'s values all `i`, stored uncompressed (a negative byte count).
    fn stored_leaf(i: usize) -> Vec<u8> {
        let mut b = (-2048i64).to_le_bytes().to_vec();
        (0..512).for_each(|_| b.extend_from_slice(&(i as f32).to_le_bytes()));
        b
    }

    fn read(bytes: &[u8]) -> KResult<Tree<f32>> {
        let mut c = ctx(COMPRESS_ACTIVE_MASK | COMPRESS_ZIP);
        read_tree(&mut Reader::new(bytes), &mut c)
    }

    /// 3000 leaves span several batches (decoded in parallel, a batch while the next is read): every leaf gets
    /// its own values, and of two corrupt leaves the error is the first one's in file order, whether each is
    /// found reading (a wrong uncompressed size) or decoding (a bad zlib stream), in one batch or two.
    #[test]
    fn leaves_decoded_in_parallel_keep_their_values_and_the_first_error() {
        let leaves = 3000;
        let good: Vec<Vec<u8>> = (0..leaves).map(stored_leaf).collect();
        let tree = read(&tree_bytes(&good)).unwrap();
        assert_eq!(tree.leaves.len(), leaves);
        for (i, leaf) in tree.leaves.iter().enumerate() {
            assert!(leaf.values.iter().all(|&v| v == i as f32), "leaf {i}");
            assert_eq!(leaf.range(), (i as f32, i as f32));
        }
        let compressed = |data: &[u8]| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            std::io::Write::write_all(&mut z, data).unwrap();
            let z = z.finish().unwrap();
            let mut b = (z.len() as i64).to_le_bytes().to_vec();
            b.extend_from_slice(&z);
            b
        };
        // Read: an uncompressed block of the wrong size. Decoded: a zlib stream cut short, and one of garbage.
        let wrong_size = [(-100i64).to_le_bytes().to_vec(), vec![0; 100]].concat();
        let cut_short = {
            let full = compressed(
                &(0..2048)
                    .map(|i| (i * 7919 % 251) as u8)
                    .collect::<Vec<_>>(),
            );
            let half = (full.len() - 8) / 2;
            let mut cut = full[..8 + half].to_vec();
            cut[..8].copy_from_slice(&(half as i64).to_le_bytes());
            cut
        };
        let garbage = [4i64.to_le_bytes().to_vec(), vec![1, 2, 3, 4]].concat();
        let message = |first: (usize, &Vec<u8>), second: (usize, &Vec<u8>)| {
            let mut buffers = good.clone();
            buffers[first.0] = first.1.clone();
            buffers[second.0] = second.1.clone();
            read(&tree_bytes(&buffers)).unwrap_err().to_string()
        };
        let alone = |(i, buffer): (usize, &Vec<u8>)| message((i, buffer), (i, buffer));
        let (size_error, cut_error, garbage_error) = (
            alone((1600, &wrong_size)),
            alone((1600, &cut_short)),
            alone((1600, &garbage)),
        );
        assert!(
            size_error.contains("uncompressed block holds 100"),
            "{size_error}"
        );
        assert_ne!(cut_error, garbage_error);
        for (a, b) in [(1600, 1610), (1600, 2600), (10, 2990)] {
            assert_eq!(message((a, &wrong_size), (b, &garbage)), size_error);
            assert_eq!(message((a, &garbage), (b, &wrong_size)), garbage_error);
            assert_eq!(message((a, &cut_short), (b, &garbage)), cut_error);
            assert_eq!(message((a, &garbage), (b, &cut_short)), garbage_error);
        }
        // A file ending inside leaf 2000's values: the error names the field and its offset in the file,
        // unless an earlier leaf failed.
        let record = 64 + 1 + 8 + 2048;
        let whole = tree_bytes(&good);
        let values_at = whole.len() - (leaves - 2000) * record + 64 + 1 + 8;
        match read(&whole[..values_at + 10]) {
            Err(VdbErrorKind::Truncated {
                what,
                offset,
                needed,
                remaining,
            }) => assert_eq!(
                (what, offset, needed, remaining),
                ("uncompressed value buffer", values_at, 2048, 10)
            ),
            other => panic!("{:?}", other.map(|_| ())),
        }
        let mut buffers = good.clone();
        buffers[1990] = garbage.clone();
        let cut = tree_bytes(&buffers);
        let cut = &cut[..cut.len() - (leaves - 2000) * record + 64 + 1 + 8 + 10];
        assert_eq!(read(cut).unwrap_err().to_string(), garbage_error);
    }
}
