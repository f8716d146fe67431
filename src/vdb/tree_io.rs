//! Reading a 5-4-3 tree: root topology, internal-node tiles, leaf masks, then the leaf value buffers.
//!
//! Value arrays go through OpenVDB's "compressed values" scheme: a metadata byte (file version ≥ 222) says how
//! inactive values were encoded, optionally followed by one or two inactive values and a selection mask; with
//! active-mask compression only the active values are stored and the rest are rebuilt.

use super::compression::{read_data, COMPRESS_ACTIVE_MASK};
use super::error::{corrupt, KResult};
use super::grid::{InternalNode, Leaf, LowerNode, Root, RootSlot, Tree, UpperNode, VoxelValue};
use super::half::half_to_f32;
use super::stream::Reader;
use glam::IVec3;

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
    scratch: Vec<u8>,
}

impl TreeCtx {
    pub fn new(version: u32, compression: u32, scalar: Scalar, half: bool) -> Self {
        Self {
            version,
            compression,
            scalar,
            half,
            scratch: Vec::new(),
        }
    }

    fn full_size<T: VoxelValue>(&self) -> usize {
        T::COMPONENTS * if self.scalar == Scalar::F64 { 8 } else { 4 }
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

/// The inactive values of one compressed array and, for the modes that store one, its selection mask: `inactive0`
/// is the value where no selection bit is set (`background` or its negation unless the mode stores it),
/// `inactive1` where one is (`background` unless stored). `values` is the array's length.
fn read_inactive<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    mode: u8,
    background: T,
    values: usize,
) -> KResult<(T, T, Option<Vec<u64>>)> {
    let mut inactive1 = background;
    // The inactive value where no selection bit is set; the modes that store it replace it below.
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
    Ok((inactive0, inactive1, selection))
}

/// Reads one array of `out.len()` values under the compressed-values scheme (OpenVDB `readCompressedValues`).
pub(crate) fn read_values<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    background: T,
    value_mask: &[u64],
    out: &mut [T],
) -> KResult<()> {
    let mask_compressed = ctx.compression & COMPRESS_ACTIVE_MASK != 0;
    let new_format = ctx.version >= VERSION_NODE_MASK_COMPRESSION;
    let mode = if new_format {
        r.u8("compression metadata")?
    } else {
        NO_MASK_AND_ALL_VALS
    };
    if mode > NO_MASK_AND_ALL_VALS {
        return corrupt(format!("invalid compression metadata {mode}"));
    }
    let (inactive0, inactive1, selection) = read_inactive(r, ctx, mode, background, out.len())?;
    let count = if mask_compressed && mode != NO_MASK_AND_ALL_VALS && new_format {
        popcount(value_mask)
    } else {
        out.len()
    };
    let elem = if ctx.half {
        2 * T::COMPONENTS
    } else {
        ctx.full_size::<T>()
    };
    let nbytes = count * elem;
    ctx.scratch.clear();
    ctx.scratch.resize(nbytes, 0);
    // OpenVDB's half reader returns before touching the stream when there is nothing to read.
    if !(ctx.half && count == 0) {
        read_data(r, ctx.compression, &mut ctx.scratch)?;
    }
    let buf = &ctx.scratch;
    let half = ctx.half;
    let scalar = ctx.scalar;
    let get = |b: &[u8]| -> T {
        if half {
            T::from_components(|c| half_to_f32(u16::from_le_bytes([b[2 * c], b[2 * c + 1]])))
        } else {
            decode_full(b, scalar)
        }
    };
    if count == out.len() {
        for (o, b) in out.iter_mut().zip(buf.chunks_exact(elem)) {
            *o = get(b);
        }
    } else {
        let mut stored = buf.chunks_exact(elem);
        for (i, o) in out.iter_mut().enumerate() {
            let on = value_mask[i >> 6] >> (i & 63) & 1 != 0;
            *o = if on {
                // count == popcount(value_mask), so a stored value is always left here.
                stored.next().map_or(inactive0, get)
            } else if selection
                .as_ref()
                .is_some_and(|s| s[i >> 6] >> (i & 63) & 1 != 0)
            {
                inactive1
            } else {
                inactive0
            };
        }
    }
    Ok(())
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

/// Reads the topology of the upper node at `origin` under the root: its lower nodes go to `tree.lowers` and its
/// leaves (values still `background`; their buffers come later) to `tree.leaves`, in depth-first order.
fn read_upper<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    tree: &mut Tree<T>,
    background: T,
    origin: IVec3,
) -> KResult<UpperNode<T>> {
    let (mut upper, umask): (UpperNode<T>, _) = read_internal(r, ctx, background, origin)?;
    for ui in set_bits(&umask) {
        let lorigin = upper.slot_origin(ui);
        let (mut lower, lmask): (LowerNode<T>, _) = read_internal(r, ctx, background, lorigin)?;
        for li in set_bits(&lmask) {
            let value_mask = r.mask::<8>("leaf value mask")?;
            lower.children[li] = tree.leaves.len() as u32;
            tree.leaves.push(Leaf {
                origin: lower.slot_origin(li),
                value_mask,
                values: [background; 512],
                min: background,
                max: background,
            });
        }
        upper.children[ui] = tree.lowers.len() as u32;
        tree.lowers.push(lower);
    }
    Ok(upper)
}

/// Reads the buffers of `tree`'s leaves, in the depth-first order of the topology: each leaf's value mask and
/// values.
fn read_leaf_buffers<T: VoxelValue>(
    r: &mut Reader<'_>,
    ctx: &mut TreeCtx,
    tree: &mut Tree<T>,
    background: T,
) -> KResult<()> {
    for i in 0..tree.leaves.len() {
        let mask = r.mask::<8>("leaf buffer mask")?;
        if ctx.version < VERSION_NODE_MASK_COMPRESSION {
            r.ivec3("leaf origin")?;
            let nbuf = r.u8("leaf buffer count")?;
            if nbuf != 1 {
                return corrupt(format!("leaf has {nbuf} buffers, expected 1"));
            }
        }
        let leaf = &mut tree.leaves[i];
        read_values(r, ctx, background, &mask, &mut leaf.values)?;
        leaf.value_mask = mask;
    }
    Ok(())
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
        let upper = read_upper(r, ctx, &mut tree, background, origin)?;
        tree.root
            .entries
            .push((origin, RootSlot::Child(tree.uppers.len() as u32)));
        tree.uppers.push(upper);
    }
    tree.root.entries.sort_by_key(|e| (e.0.x, e.0.y, e.0.z));
    if tree.root.entries.windows(2).any(|w| w[0].0 == w[1].0) {
        return corrupt("duplicate root table entries");
    }
    read_leaf_buffers(r, ctx, &mut tree, background)?;
    tree.leaves.shrink_to_fit();
    tree.lowers.shrink_to_fit();
    tree.uppers.shrink_to_fit();
    tree.finalize();
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
}
