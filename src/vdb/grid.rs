//! The renderer's sparse grid: a flat, index-linked VDB tree in the spirit of NanoVDB.
//!
//! Each level of the 5-4-3 tree has its own type: a [`Root`] table of 4096³ regions, each a tile or an
//! [`UpperNode`] (32³ slots of 128³ voxels), whose slots are tiles or [`LowerNode`]s (16³ slots of 8³), whose
//! slots are tiles or [`Leaf`]s (8³ voxels). The sizes are associated constants of those types (`DIM`,
//! `LOG2DIM`, `CHILD_DIM`), so the slot arithmetic is written once, here. Nodes live in flat vectors and refer
//! to children by `u32` index; lookups use bit arithmetic only (no hashing). Every node and leaf carries the
//! min/max of all values a lookup inside it can return (active or not), so a majorant built from them is a true
//! bound.
//!
//! Code outside the reader needs no node internals: [`Tree::regions`] and [`Tree::regions_in`] list the leaves
//! and tiles (with the range of values a lookup inside each can return), and [`Tree::update_values`] rewrites
//! stored values and refreshes the ranges.

use glam::{IVec3, Vec3};
use rayon::prelude::*;

/// Sentinel child index meaning "this slot is a tile".
pub(crate) const NO_CHILD: u32 = u32::MAX;

/// A voxel value type the tree can store: `f32` (scalar grids) or `Vec3` (vector grids).
pub trait VoxelValue: Copy + Default + PartialEq + std::fmt::Debug + Send + Sync + 'static {
    /// Number of scalar components.
    const COMPONENTS: usize;
    /// Builds a value from its components.
    fn from_components(c: impl Fn(usize) -> f32) -> Self;
    /// Scalar used for statistics: the value itself, or the vector length.
    fn magnitude(self) -> f64;
    /// Component-wise minimum.
    fn min_of(self, o: Self) -> Self;
    /// Component-wise maximum.
    fn max_of(self, o: Self) -> Self;
    /// Component-wise negation.
    fn neg(self) -> Self;
    /// Linear interpolation `a + (b - a) t`.
    fn lerp(a: Self, b: Self, t: f32) -> Self;
}

impl VoxelValue for f32 {
    const COMPONENTS: usize = 1;
    fn from_components(c: impl Fn(usize) -> f32) -> Self {
        c(0)
    }
    fn magnitude(self) -> f64 {
        self as f64
    }
    fn min_of(self, o: Self) -> Self {
        self.min(o)
    }
    fn max_of(self, o: Self) -> Self {
        self.max(o)
    }
    fn neg(self) -> Self {
        -self
    }
    #[inline(always)]
    fn lerp(a: Self, b: Self, t: f32) -> Self {
        a + (b - a) * t
    }
}

impl VoxelValue for Vec3 {
    const COMPONENTS: usize = 3;
    fn from_components(c: impl Fn(usize) -> f32) -> Self {
        Vec3::new(c(0), c(1), c(2))
    }
    fn magnitude(self) -> f64 {
        self.as_dvec3().length()
    }
    fn min_of(self, o: Self) -> Self {
        self.min(o)
    }
    fn max_of(self, o: Self) -> Self {
        self.max(o)
    }
    fn neg(self) -> Self {
        -self
    }
    #[inline(always)]
    fn lerp(a: Self, b: Self, t: f32) -> Self {
        a + (b - a) * t
    }
}

fn bit(mask: &[u64], i: usize) -> bool {
    mask[i >> 6] >> (i & 63) & 1 != 0
}

#[cfg(any(test, feature = "testing"))]
fn set_bit(mask: &mut [u64], i: usize) {
    mask[i >> 6] |= 1 << (i & 63);
}

/// (min, max) of `values` (component-wise for vectors), which holds at least one value.
fn value_range<T: VoxelValue>(values: &[T]) -> (T, T) {
    let (mut lo, mut hi) = (values[0], values[0]);
    for &v in &values[1..] {
        lo = lo.min_of(v);
        hi = hi.max_of(v);
    }
    (lo, hi)
}

/// An 8³ block of voxels, the tree's lowest level.
#[derive(Clone, Debug)]
pub struct Leaf<T> {
    /// Index coordinate of voxel (0,0,0) of the leaf (a multiple of [`Leaf::DIM`]).
    pub(crate) origin: IVec3,
    /// Active-voxel bits, voxel `(x<<6)|(y<<3)|z`.
    pub(crate) value_mask: [u64; 8],
    /// All 512 stored values (inactive ones keep what the file stored).
    pub(crate) values: [T; 512],
    /// Minimum over all 512 values.
    pub(crate) min: T,
    /// Maximum over all 512 values.
    pub(crate) max: T,
}

impl<T: VoxelValue> Leaf<T> {
    /// The leaf at `origin` holding `values`, whose active voxels are the bits of `value_mask`; its range
    /// computed.
    pub(crate) fn with_values(origin: IVec3, value_mask: [u64; 8], values: [T; 512]) -> Self {
        let (min, max) = value_range(&values);
        Self {
            origin,
            value_mask,
            values,
            min,
            max,
        }
    }
}

impl<T: Copy> Leaf<T> {
    /// log2 of the edge in voxels.
    pub const LOG2DIM: i32 = 3;
    /// Edge in voxels.
    pub const DIM: i32 = 1 << Self::LOG2DIM;

    /// Offset of index coordinate `p` in the values of the leaf that holds it, `(x<<6)|(y<<3)|z`.
    #[inline(always)]
    pub(crate) fn offset(p: IVec3) -> usize {
        let m = Self::DIM - 1;
        (((p.x & m) << (2 * Self::LOG2DIM)) | ((p.y & m) << Self::LOG2DIM) | (p.z & m)) as usize
    }

    /// Index coordinate of the voxel at offset `i` (see [`Leaf::offset`]).
    fn voxel(&self, i: usize) -> IVec3 {
        let (i, m) = (i as i32, Self::DIM - 1);
        self.origin + IVec3::new(i >> (2 * Self::LOG2DIM), (i >> Self::LOG2DIM) & m, i & m)
    }

    /// Index coordinate of voxel (0,0,0) of the leaf.
    #[cfg(any(test, feature = "testing"))]
    pub fn origin(&self) -> IVec3 {
        self.origin
    }

    /// (min, max) over all 512 stored values, active or not: every value a lookup inside the leaf can return.
    pub fn range(&self) -> (T, T) {
        (self.min, self.max)
    }

    /// The stored value of the voxel at index coordinate `p` (which must lie in the leaf).
    #[cfg(any(test, feature = "testing"))]
    pub fn value(&self, p: IVec3) -> T {
        self.values[Self::offset(p)]
    }

    /// Whether the voxel at index coordinate `p` (which must lie in the leaf) is active.
    #[cfg(any(test, feature = "testing"))]
    pub fn is_active(&self, p: IVec3) -> bool {
        bit(&self.value_mask, Self::offset(p))
    }

    /// The active voxels, as (index coordinate, value), in offset order.
    pub fn active_voxels(&self) -> impl Iterator<Item = (IVec3, T)> + '_ {
        self.value_mask
            .iter()
            .enumerate()
            .flat_map(|(w, &word)| {
                let mut word = word;
                std::iter::from_fn(move || {
                    (word != 0).then(|| {
                        let b = word.trailing_zeros() as usize;
                        word &= word - 1;
                        w * 64 + b
                    })
                })
            })
            .map(|i| (self.voxel(i), self.values[i]))
    }
}

/// An internal node of (2^`LOG2`)³ slots, each a tile or a child of edge 2^`CHILD_LOG2` voxels. The two internal
/// levels of a 5-4-3 tree, [`UpperNode`] and [`LowerNode`], are distinct types of this family.
#[derive(Clone, Debug)]
pub struct InternalNode<T, const LOG2: i32, const CHILD_LOG2: i32> {
    /// Index coordinate of the node's first voxel.
    pub(crate) origin: IVec3,
    /// Child index per slot, or [`NO_CHILD`] for a tile.
    pub(crate) children: Box<[u32]>,
    /// Tile value per slot (meaningless where a child is present).
    pub(crate) tiles: Box<[T]>,
    /// Active-tile bits per slot.
    pub(crate) value_mask: Box<[u64]>,
    /// Minimum over tiles and children (all values a lookup inside the node can return).
    pub(crate) min: T,
    /// Maximum over tiles and children.
    pub(crate) max: T,
}

/// The lower internal level: 16³ slots over 8³ leaves (128³ voxels).
pub type LowerNode<T> = InternalNode<T, 4, { Leaf::<f32>::LOG2DIM }>;
/// The upper internal level: 32³ slots over lower nodes (4096³ voxels).
pub type UpperNode<T> = InternalNode<T, 5, { LowerNode::<f32>::LOG2DIM }>;

impl<T, const LOG2: i32, const CHILD_LOG2: i32> InternalNode<T, LOG2, CHILD_LOG2> {
    /// log2 of the edge in voxels.
    pub const LOG2DIM: i32 = LOG2 + CHILD_LOG2;
    /// Edge in voxels.
    pub const DIM: i32 = 1 << Self::LOG2DIM;
    /// Edge of a slot (a child or a tile) in voxels.
    pub const CHILD_DIM: i32 = 1 << CHILD_LOG2;
    /// Number of slots.
    pub const SLOTS: usize = 1 << (3 * LOG2);

    /// The slot that holds index coordinate `p` in the node of this level that contains it.
    #[inline(always)]
    pub(crate) fn slot(p: IVec3) -> usize {
        let m = Self::DIM - 1;
        ((((p.x & m) >> CHILD_LOG2) << (2 * LOG2))
            | (((p.y & m) >> CHILD_LOG2) << LOG2)
            | ((p.z & m) >> CHILD_LOG2)) as usize
    }

    /// Origin of the node of this level that contains index coordinate `p`.
    #[inline(always)]
    pub(crate) fn origin_of(p: IVec3) -> IVec3 {
        p & !(Self::DIM - 1)
    }

    /// Index origin of slot `i` (a child's or a tile's first voxel).
    pub(crate) fn slot_origin(&self, i: usize) -> IVec3 {
        let (i, m) = (i as i32, (1 << LOG2) - 1);
        self.origin + IVec3::new(i >> (2 * LOG2), (i >> LOG2) & m, i & m) * Self::CHILD_DIM
    }

    /// The child index in slot `i`, or `None` where the slot is a tile.
    #[inline(always)]
    pub(crate) fn child(&self, i: usize) -> Option<u32> {
        let c = self.children[i];
        (c != NO_CHILD).then_some(c)
    }

    /// The slots whose cubes meet the inclusive index box `[lo, hi]` (which must meet the node), in slot order.
    fn slots_in(&self, lo: IVec3, hi: IVec3) -> impl Iterator<Item = usize> {
        let last = self.origin + (Self::DIM - 1);
        let a = (lo.max(self.origin) - self.origin) >> CHILD_LOG2;
        let b = (hi.min(last) - self.origin) >> CHILD_LOG2;
        (a.x..=b.x).flat_map(move |x| {
            (a.y..=b.y).flat_map(move |y| {
                (a.z..=b.z).map(move |z| ((x << (2 * LOG2)) | (y << LOG2) | z) as usize)
            })
        })
    }
}

impl<T: VoxelValue, const LOG2: i32, const CHILD_LOG2: i32> InternalNode<T, LOG2, CHILD_LOG2> {
    /// A node at `origin` whose slots are all inactive tiles of value `fill`.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new(origin: IVec3, fill: T) -> Self {
        Self::from_tiles(
            origin,
            vec![fill; Self::SLOTS],
            vec![0; Self::SLOTS / 64],
            fill,
        )
    }

    /// A node without children from its tile values and active-tile bits; `range` stands for its min and max
    /// until [`Tree::finalize`].
    pub(crate) fn from_tiles(origin: IVec3, tiles: Vec<T>, value_mask: Vec<u64>, range: T) -> Self {
        Self {
            origin,
            children: vec![NO_CHILD; Self::SLOTS].into_boxed_slice(),
            tiles: tiles.into_boxed_slice(),
            value_mask: value_mask.into_boxed_slice(),
            min: range,
            max: range,
        }
    }

    /// Slot `i` as a tile region (the slot must hold no child).
    fn tile(&self, i: usize) -> Tile<T> {
        Tile {
            origin: self.slot_origin(i),
            edge: Self::CHILD_DIM,
            value: self.tiles[i],
            active: bit(&self.value_mask, i),
        }
    }

    /// Sets min/max to the range of the tiles and of the children's ranges (`child(index)`).
    fn update_range(&mut self, child: impl Fn(usize) -> (T, T)) {
        let mut r: Option<(T, T)> = None;
        for (i, &c) in self.children.iter().enumerate() {
            let (a, b) = if c == NO_CHILD {
                (self.tiles[i], self.tiles[i])
            } else {
                child(c as usize)
            };
            r = Some(match r {
                None => (a, b),
                Some((lo, hi)) => (lo.min_of(a), hi.max_of(b)),
            });
        }
        if let Some((lo, hi)) = r {
            self.min = lo;
            self.max = hi;
        }
    }

    /// Approximate heap plus inline size in bytes.
    fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.children.len() * (4 + std::mem::size_of::<T>())
            + self.value_mask.len() * 8
    }
}

// The levels nest: a lower node's slot is a leaf, an upper node's slot a lower node.
const _: () = assert!(LowerNode::<f32>::CHILD_DIM == Leaf::<f32>::DIM);
const _: () = assert!(UpperNode::<f32>::CHILD_DIM == LowerNode::<f32>::DIM);

/// One entry of the root table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum RootSlot<T> {
    /// A tile of [`Root::DIM`]³ voxels.
    Tile {
        /// Its value.
        value: T,
        /// Whether it is active.
        active: bool,
    },
    /// Index of an [`UpperNode`] of the tree.
    Child(u32),
}

/// The top level: a table of [`Root::DIM`]³ regions sorted by origin `(x, y, z)`, each a tile or an upper node.
#[derive(Clone, Debug)]
pub struct Root<T> {
    pub(crate) entries: Vec<(IVec3, RootSlot<T>)>,
}

impl<T> Root<T> {
    /// Edge of a root region in voxels (an upper node's edge).
    pub const DIM: i32 = UpperNode::<f32>::DIM;

    /// Origin of the root region that contains index coordinate `p`.
    #[inline(always)]
    pub(crate) fn key(p: IVec3) -> IVec3 {
        p & !(Self::DIM - 1)
    }

    /// The entry of the region that holds `p`, if any.
    #[inline]
    pub(crate) fn get(&self, p: IVec3) -> Option<&RootSlot<T>> {
        let key = Self::key(p);
        if self.entries.len() <= 8 {
            self.entries.iter().find(|(k, _)| *k == key).map(|(_, s)| s)
        } else {
            self.search(key).ok().map(|i| &self.entries[i].1)
        }
    }

    fn search(&self, key: IVec3) -> Result<usize, usize> {
        self.entries.binary_search_by(|(k, _)| key_cmp(*k, key))
    }
}

/// Summary statistics over the active values of a tree (tiles weighted by their voxel count).
///
/// Serialised (for `nimbus info --json`) with the keys `active_voxels`, `leaf_voxels`, `tiles`, `leaves`, `sum`,
/// `min`, `max`, `bbox_min` and `bbox_max` (the inclusive active bounding box, zeros when nothing is active).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// Active voxels, tiles counted with all their voxels.
    pub active_voxels: u64,
    /// Active voxels inside leaves.
    pub leaf_voxels: u64,
    /// Active tiles at every level.
    pub tiles: u64,
    /// Number of leaves.
    pub leaves: u64,
    /// Sum of active values (magnitudes for vectors).
    pub sum: f64,
    /// Minimum active value (magnitude for vectors); 0 when empty.
    pub min: f64,
    /// Maximum active value (magnitude for vectors); 0 when empty.
    pub max: f64,
    /// Inclusive active index bounding box (min, max); `None` when nothing is active.
    pub bbox: Option<(IVec3, IVec3)>,
}

impl serde::Serialize for TreeStats {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let (bmin, bmax) = self.bbox.unwrap_or_default();
        let mut st = s.serialize_struct("TreeStats", 9)?;
        st.serialize_field("active_voxels", &self.active_voxels)?;
        st.serialize_field("leaf_voxels", &self.leaf_voxels)?;
        st.serialize_field("tiles", &self.tiles)?;
        st.serialize_field("leaves", &self.leaves)?;
        st.serialize_field("sum", &self.sum)?;
        st.serialize_field("min", &self.min)?;
        st.serialize_field("max", &self.max)?;
        st.serialize_field("bbox_min", &bmin.to_array())?;
        st.serialize_field("bbox_max", &bmax.to_array())?;
        st.end()
    }
}

/// A tile: a cube of index space, at any level of the tree, holding one value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tile<T> {
    /// Its first voxel.
    pub origin: IVec3,
    /// Its edge in voxels: [`Root::DIM`], [`UpperNode::CHILD_DIM`] or [`LowerNode::CHILD_DIM`].
    pub edge: i32,
    /// Its value.
    pub value: T,
    /// Whether it is active.
    pub active: bool,
}

/// A cube of index space where the tree stores data: a leaf, or a tile of any level. The regions of a tree do
/// not overlap; outside them every lookup returns the background.
#[derive(Clone, Copy, Debug)]
pub enum Region<'a, T> {
    /// A leaf of [`Leaf::DIM`]³ voxels.
    Leaf(&'a Leaf<T>),
    /// A tile.
    Tile(Tile<T>),
}

impl<T: Copy> Region<'_, T> {
    /// The region's first voxel.
    pub fn origin(&self) -> IVec3 {
        match self {
            Self::Leaf(l) => l.origin,
            Self::Tile(t) => t.origin,
        }
    }

    /// The region's edge in voxels.
    pub fn edge(&self) -> i32 {
        match self {
            Self::Leaf(_) => Leaf::<T>::DIM,
            Self::Tile(t) => t.edge,
        }
    }

    /// (min, max) of the values a lookup inside the region can return, active or not.
    pub fn range(&self) -> (T, T) {
        match self {
            Self::Leaf(l) => l.range(),
            Self::Tile(t) => (t.value, t.value),
        }
    }
}

/// A sparse VDB tree with 5-4-3 node sizes, values of type `T`.
#[derive(Clone, Debug)]
pub struct Tree<T> {
    /// Value returned outside all nodes and tiles.
    pub(crate) background: T,
    pub(crate) root: Root<T>,
    pub(crate) uppers: Vec<UpperNode<T>>,
    pub(crate) lowers: Vec<LowerNode<T>>,
    pub(crate) leaves: Vec<Leaf<T>>,
}

/// A scalar tree.
pub type FloatTree = Tree<f32>;
/// A vector tree.
pub type Vec3Tree = Tree<Vec3>;

#[inline(always)]
fn key_cmp(a: IVec3, b: IVec3) -> std::cmp::Ordering {
    (a.x, a.y, a.z).cmp(&(b.x, b.y, b.z))
}

/// `floor` of each component as integers, without a libm call (baseline x86-64 has no SSE4.1 `roundps`).
/// Valid for |x| < 2³¹.
#[inline(always)]
pub fn floor_ivec3(x: Vec3) -> IVec3 {
    let t = x.as_ivec3(); // truncates toward zero
    t - x.cmplt(t.as_vec3()).into_ivec3_mask()
}

trait MaskToInt {
    fn into_ivec3_mask(self) -> IVec3;
}
impl MaskToInt for glam::BVec3 {
    #[inline(always)]
    fn into_ivec3_mask(self) -> IVec3 {
        IVec3::new(self.x as i32, self.y as i32, self.z as i32)
    }
}

impl<T: VoxelValue> Tree<T> {
    /// An empty tree that returns `background` everywhere.
    pub fn new(background: T) -> Self {
        Self {
            background,
            root: Root {
                entries: Vec::new(),
            },
            uppers: Vec::new(),
            lowers: Vec::new(),
            leaves: Vec::new(),
        }
    }

    /// The value returned outside all leaves and tiles.
    pub fn background(&self) -> T {
        self.background
    }

    /// Builds a tree from active voxels (later duplicates win); inactive voxels of new leaves hold `background`.
    #[cfg(any(test, feature = "testing"))]
    pub fn from_voxels(background: T, voxels: impl IntoIterator<Item = (IVec3, T)>) -> Self {
        let mut t = Self::new(background);
        for (p, v) in voxels {
            t.set_active(p, v);
        }
        t.finalize();
        t
    }

    /// Sets voxel `p` to `v` and marks it active, creating nodes as needed. Call [`Self::finalize`] afterwards
    /// to refresh min/max.
    #[cfg(any(test, feature = "testing"))]
    pub fn set_active(&mut self, p: IVec3, v: T) {
        let key = Root::<T>::key(p);
        let u = match self.root.search(key) {
            Ok(i) => match self.root.entries[i].1 {
                RootSlot::Child(u) => u,
                RootSlot::Tile { value, .. } => {
                    let u = self.push_upper(key, value);
                    self.root.entries[i].1 = RootSlot::Child(u);
                    u
                }
            },
            Err(i) => {
                let u = self.push_upper(key, self.background);
                self.root.entries.insert(i, (key, RootSlot::Child(u)));
                u
            }
        };
        let us = UpperNode::<T>::slot(p);
        let up = &self.uppers[u as usize];
        let l = match up.child(us) {
            Some(l) => l,
            None => {
                let fill = up.tiles[us];
                let l = self.lowers.len() as u32;
                self.lowers
                    .push(LowerNode::new(LowerNode::<T>::origin_of(p), fill));
                self.uppers[u as usize].children[us] = l;
                l
            }
        };
        let ls = LowerNode::<T>::slot(p);
        let lo = &self.lowers[l as usize];
        let leaf = match lo.child(ls) {
            Some(c) => c,
            None => {
                let fill = lo.tiles[ls];
                let id = self.leaves.len() as u32;
                self.leaves.push(Leaf {
                    origin: p & !(Leaf::<T>::DIM - 1),
                    value_mask: [0; 8],
                    values: [fill; 512],
                    min: fill,
                    max: fill,
                });
                self.lowers[l as usize].children[ls] = id;
                id
            }
        };
        let lf = &mut self.leaves[leaf as usize];
        let i = Leaf::<T>::offset(p);
        lf.values[i] = v;
        set_bit(&mut lf.value_mask, i);
    }

    #[cfg(any(test, feature = "testing"))]
    fn push_upper(&mut self, origin: IVec3, fill: T) -> u32 {
        self.uppers.push(UpperNode::new(origin, fill));
        (self.uppers.len() - 1) as u32
    }

    /// Recomputes every leaf's and node's min/max (bottom-up); the leaves in parallel.
    pub fn finalize(&mut self) {
        self.leaves
            .par_iter_mut()
            .for_each(|lf| (lf.min, lf.max) = value_range(&lf.values));
        self.finalize_nodes();
    }

    /// Recomputes every internal node's min/max (bottom-up) from its children's, the leaves' being current.
    pub(crate) fn finalize_nodes(&mut self) {
        let leaves = &self.leaves;
        for n in &mut self.lowers {
            n.update_range(|c| (leaves[c].min, leaves[c].max));
        }
        let lowers = &self.lowers;
        for n in &mut self.uppers {
            n.update_range(|c| (lowers[c].min, lowers[c].max));
        }
    }

    /// Every leaf and every tile (of any level, active or not, whatever its value), depth first in root order.
    /// Together they cover all of index space where a lookup returns something other than the background.
    pub fn regions(&self) -> impl Iterator<Item = Region<'_, T>> + '_ {
        self.regions_in(IVec3::MIN, IVec3::MAX)
    }

    /// The leaves and tiles that meet the inclusive index box `[lo, hi]`, as [`Tree::regions`] lists them; only
    /// the nodes that meet the box are visited.
    pub fn regions_in(&self, lo: IVec3, hi: IVec3) -> impl Iterator<Item = Region<'_, T>> + '_ {
        let meets = move |origin: IVec3, edge: i32| {
            origin.cmple(hi).all() && (origin + (edge - 1)).cmpge(lo).all()
        };
        self.root
            .entries
            .iter()
            .filter(move |(origin, _)| meets(*origin, Root::<T>::DIM))
            .flat_map(move |&(origin, slot)| {
                let (tile, upper) = match slot {
                    RootSlot::Tile { value, active } => (
                        Some(Region::Tile(Tile {
                            origin,
                            edge: Root::<T>::DIM,
                            value,
                            active,
                        })),
                        None,
                    ),
                    RootSlot::Child(u) => (None, Some(self.upper_regions(u, lo, hi))),
                };
                tile.into_iter().chain(upper.into_iter().flatten())
            })
    }

    /// The regions under upper node `u` that meet `[lo, hi]`.
    fn upper_regions(&self, u: u32, lo: IVec3, hi: IVec3) -> impl Iterator<Item = Region<'_, T>> {
        let n = &self.uppers[u as usize];
        n.slots_in(lo, hi).flat_map(move |i| {
            let (tile, lower) = match n.child(i) {
                None => (Some(Region::Tile(n.tile(i))), None),
                Some(l) => (None, Some(self.lower_regions(l, lo, hi))),
            };
            tile.into_iter().chain(lower.into_iter().flatten())
        })
    }

    /// The regions under lower node `l` that meet `[lo, hi]`.
    fn lower_regions(&self, l: u32, lo: IVec3, hi: IVec3) -> impl Iterator<Item = Region<'_, T>> {
        let n = &self.lowers[l as usize];
        n.slots_in(lo, hi).map(move |i| match n.child(i) {
            None => Region::Tile(n.tile(i)),
            Some(c) => Region::Leaf(&self.leaves[c as usize]),
        })
    }

    /// True when `pred` holds for any stored value: a voxel of any leaf (active or not), or a tile of any level
    /// (including the unused tile values of slots that hold a child).
    pub fn any_value(&self, pred: impl Fn(T) -> bool) -> bool {
        self.leaves
            .iter()
            .any(|l| l.values.iter().any(|v| pred(*v)))
            || self.uppers.iter().any(|n| n.tiles.iter().any(|v| pred(*v)))
            || self.lowers.iter().any(|n| n.tiles.iter().any(|v| pred(*v)))
            || self
                .root
                .entries
                .iter()
                .any(|(_, s)| matches!(s, RootSlot::Tile { value, .. } if pred(*value)))
    }

    /// Passes every stored value that [`Tree::any_value`] tests to `f`, which may change it, then refreshes the
    /// min/max of every leaf and node.
    pub fn update_values(&mut self, mut f: impl FnMut(&mut T)) {
        for leaf in &mut self.leaves {
            leaf.values.iter_mut().for_each(&mut f);
        }
        for node in &mut self.uppers {
            node.tiles.iter_mut().for_each(&mut f);
        }
        for node in &mut self.lowers {
            node.tiles.iter_mut().for_each(&mut f);
        }
        for (_, slot) in &mut self.root.entries {
            if let RootSlot::Tile { value, .. } = slot {
                f(value);
            }
        }
        self.finalize();
    }

    /// The tree of the same topology whose every stored value (voxels, tiles, background) is `f` of this one's,
    /// with the node ranges recomputed: one channel of a vector grid, for instance.
    pub fn map<U: VoxelValue>(&self, f: impl Fn(T) -> U) -> Tree<U> {
        // Node ranges are placeholders until `finalize` recomputes them from the new values.
        fn node<T: Copy, U, const L: i32, const C: i32>(
            n: &InternalNode<T, L, C>,
            f: &impl Fn(T) -> U,
        ) -> InternalNode<U, L, C> {
            InternalNode {
                origin: n.origin,
                children: n.children.clone(),
                tiles: n.tiles.iter().map(|v| f(*v)).collect(),
                value_mask: n.value_mask.clone(),
                min: f(n.min),
                max: f(n.max),
            }
        }
        let mut tree = Tree {
            background: f(self.background),
            root: Root {
                entries: self
                    .root
                    .entries
                    .iter()
                    .map(|(k, s)| {
                        let slot = match s {
                            RootSlot::Tile { value, active } => RootSlot::Tile {
                                value: f(*value),
                                active: *active,
                            },
                            RootSlot::Child(c) => RootSlot::Child(*c),
                        };
                        (*k, slot)
                    })
                    .collect(),
            },
            uppers: self.uppers.iter().map(|n| node(n, &f)).collect(),
            lowers: self.lowers.iter().map(|n| node(n, &f)).collect(),
            leaves: self
                .leaves
                .iter()
                .map(|l| Leaf {
                    origin: l.origin,
                    value_mask: l.value_mask,
                    values: l.values.map(&f),
                    min: f(l.min),
                    max: f(l.max),
                })
                .collect(),
        };
        tree.finalize();
        tree
    }

    /// The value at index coordinate `p`: the stored voxel or tile value, or the background outside the tree.
    #[inline]
    #[cfg(any(test, feature = "testing"))]
    pub fn value(&self, p: IVec3) -> T {
        match self.root.get(p) {
            None => self.background,
            Some(RootSlot::Tile { value, .. }) => *value,
            Some(RootSlot::Child(u)) => self.upper_value(*u, p),
        }
    }

    #[inline(always)]
    #[cfg(any(test, feature = "testing"))]
    fn upper_value(&self, u: u32, p: IVec3) -> T {
        let n = &self.uppers[u as usize];
        let s = UpperNode::<T>::slot(p);
        match n.child(s) {
            None => n.tiles[s],
            Some(l) => self.lower_value(l, p),
        }
    }

    #[inline(always)]
    #[cfg(any(test, feature = "testing"))]
    fn lower_value(&self, l: u32, p: IVec3) -> T {
        let n = &self.lowers[l as usize];
        let s = LowerNode::<T>::slot(p);
        match n.child(s) {
            None => n.tiles[s],
            Some(c) => self.leaves[c as usize].values[Leaf::<T>::offset(p)],
        }
    }

    /// Whether the voxel at `p` is active (in an active leaf voxel or active tile).
    #[cfg(any(test, feature = "testing"))]
    pub fn is_active(&self, p: IVec3) -> bool {
        match self.root.get(p) {
            None => false,
            Some(RootSlot::Tile { active, .. }) => *active,
            Some(RootSlot::Child(u)) => {
                let n = &self.uppers[*u as usize];
                let s = UpperNode::<T>::slot(p);
                let Some(l) = n.child(s) else {
                    return bit(&n.value_mask, s);
                };
                let n = &self.lowers[l as usize];
                let s = LowerNode::<T>::slot(p);
                match n.child(s) {
                    None => bit(&n.value_mask, s),
                    Some(c) => self.leaves[c as usize].is_active(p),
                }
            }
        }
    }

    /// An accessor that caches the last leaf and nodes, for coherent lookups.
    pub fn accessor(&self) -> Accessor<'_, T> {
        Accessor::new(self)
    }

    /// Trilinear interpolation at a continuous index position (OpenVDB `BoxSampler`: values sit at integer
    /// index coordinates).
    pub fn sample_trilinear(&self, index_pos: Vec3) -> T {
        self.accessor().sample_trilinear(index_pos)
    }

    /// Approximate heap plus inline size of the tree in bytes.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        size_of::<Self>()
            + self.root.entries.capacity() * size_of::<(IVec3, RootSlot<T>)>()
            + self
                .uppers
                .iter()
                .map(UpperNode::memory_bytes)
                .sum::<usize>()
            + self
                .lowers
                .iter()
                .map(LowerNode::memory_bytes)
                .sum::<usize>()
            + self.leaves.capacity() * size_of::<Leaf<T>>()
    }

    /// Statistics over active values: counts, sum, min, max (magnitudes for vectors) and the active bbox.
    /// The regions are summarised in parallel, a chunk at a time, then added up in their order: the sum of each
    /// leaf's values in offset order, the leaves' sums in region order, the tiles' apart.
    pub fn stats(&self) -> TreeStats {
        const CHUNK: usize = 1 << 14;
        let mut total = StatsTotal::default();
        let mut regions = self.regions();
        let mut chunk = Vec::with_capacity(CHUNK);
        loop {
            chunk.clear();
            chunk.extend(regions.by_ref().take(CHUNK));
            if chunk.is_empty() {
                return total.stats();
            }
            let summaries: Vec<RegionSummary> = chunk.par_iter().map(RegionSummary::of).collect();
            summaries.iter().for_each(|summary| total.add(summary));
        }
    }
}

/// The running totals of [`Tree::stats`], region by region.
struct StatsTotal {
    stats: TreeStats,
    lo: f64,
    hi: f64,
    bmin: IVec3,
    bmax: IVec3,
    tile_sum: f64,
    leaf_sum: f64,
}

impl Default for StatsTotal {
    fn default() -> Self {
        Self {
            stats: TreeStats::default(),
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            bmin: IVec3::splat(i32::MAX),
            bmax: IVec3::splat(i32::MIN),
            tile_sum: 0.0,
            leaf_sum: 0.0,
        }
    }
}

impl StatsTotal {
    /// Adds the next region's summary.
    fn add(&mut self, summary: &RegionSummary) {
        let s = &mut self.stats;
        match summary.kind {
            RegionKind::ActiveTile => {
                s.active_voxels += summary.active;
                s.tiles += 1;
                self.tile_sum += summary.sum;
            }
            RegionKind::InactiveTile => return,
            RegionKind::Leaf => {
                s.leaves += 1;
                s.leaf_voxels += summary.active;
                self.leaf_sum += summary.sum;
            }
        }
        self.lo = self.lo.min(summary.min);
        self.hi = self.hi.max(summary.max);
        if let Some((a, b)) = summary.bbox {
            self.bmin = self.bmin.min(a);
            self.bmax = self.bmax.max(b);
        }
    }

    /// The statistics of the regions added.
    fn stats(self) -> TreeStats {
        let mut s = self.stats;
        s.sum = self.tile_sum + self.leaf_sum;
        s.active_voxels += s.leaf_voxels;
        if s.active_voxels > 0 {
            s.min = self.lo;
            s.max = self.hi;
            s.bbox = Some((self.bmin, self.bmax));
        }
        s
    }
}

/// What [`Tree::stats`] counts of a region.
#[derive(Clone, Copy, PartialEq, Eq)]
enum RegionKind {
    ActiveTile,
    InactiveTile,
    Leaf,
}

/// One region's share of [`Tree::stats`].
struct RegionSummary {
    kind: RegionKind,
    /// Active voxels.
    active: u64,
    /// Sum of the active magnitudes: a leaf's in offset order, a tile's its magnitude times its voxels.
    sum: f64,
    /// Least and greatest active magnitude (∞ and −∞ when none).
    min: f64,
    max: f64,
    /// Inclusive bounding box of the active voxels, if any.
    bbox: Option<(IVec3, IVec3)>,
}

impl RegionSummary {
    fn of<T: VoxelValue>(region: &Region<'_, T>) -> Self {
        match region {
            Region::Tile(t) => {
                let m = t.value.magnitude();
                let n = (t.edge as u64).pow(3);
                Self {
                    kind: if t.active {
                        RegionKind::ActiveTile
                    } else {
                        RegionKind::InactiveTile
                    },
                    active: n,
                    sum: m * n as f64,
                    min: m,
                    max: m,
                    bbox: Some((t.origin, t.origin + (t.edge - 1))),
                }
            }
            Region::Leaf(leaf) => {
                let (mut sum, mut min, mut max) = (0.0, f64::INFINITY, f64::NEG_INFINITY);
                for (_, v) in leaf.active_voxels() {
                    let m = v.magnitude();
                    sum += m;
                    min = min.min(m);
                    max = max.max(m);
                }
                Self {
                    kind: RegionKind::Leaf,
                    active: leaf.value_mask.iter().map(|w| w.count_ones() as u64).sum(),
                    sum,
                    min,
                    max,
                    bbox: mask_bbox(&leaf.value_mask)
                        .map(|(a, b)| (leaf.origin + a, leaf.origin + b)),
                }
            }
        }
    }
}

/// The inclusive bounding box, in voxels from a leaf's origin, of the set bits of its value mask (voxel
/// `(x<<6)|(y<<3)|z`: word `x`, byte `y`, bit `z`); `None` when no bit is set.
fn mask_bbox(mask: &[u64; 8]) -> Option<(IVec3, IVec3)> {
    let x0 = mask.iter().position(|&w| w != 0)?;
    let x1 = mask.iter().rposition(|&w| w != 0)?;
    let union = mask.iter().fold(0, |a, &w| a | w);
    let bytes = union.to_le_bytes();
    let y_bits = (0..8).fold(0u8, |a, y| a | u8::from(bytes[y] != 0) << y);
    let z_bits = bytes.iter().fold(0u8, |a, &b| a | b);
    let low = |bits: u8| bits.trailing_zeros() as i32;
    let high = |bits: u8| 7 - bits.leading_zeros() as i32;
    Some((
        IVec3::new(x0 as i32, low(y_bits), low(z_bits)),
        IVec3::new(x1 as i32, high(y_bits), high(z_bits)),
    ))
}

/// Cached, coherent access to a [`Tree`]: remembers the last leaf, lower and upper node it visited.
///
/// The innermost cache is a region (a leaf, or a tile of any level, or an empty root region) with its values:
/// a lookup inside it is one masked compare and one load, whether the region holds voxels or a constant.
/// For incoherent (random) lookups [`Tree::value`] is a little faster: it has no cache to update.
pub struct Accessor<'a, T> {
    tree: &'a Tree<T>,
    /// Key mask of the cached region (`!(DIM - 1)` of a leaf, a lower node or a root region).
    region_mask: i32,
    /// Origin of the cached region.
    region_key: IVec3,
    /// Values of the cached region: a leaf's 512 values, or one tile value.
    region_values: &'a [T],
    /// `511` for a leaf, `0` for a constant region.
    value_mask: usize,
    lower_key: IVec3,
    lower: u32,
    upper_key: IVec3,
    upper: u32,
}

const NO_KEY: IVec3 = IVec3::splat(i32::MAX);

impl<'a, T: VoxelValue> Accessor<'a, T> {
    /// A fresh accessor with an empty cache.
    pub fn new(tree: &'a Tree<T>) -> Self {
        Self {
            tree,
            region_mask: !(Leaf::<T>::DIM - 1),
            region_key: NO_KEY,
            region_values: std::slice::from_ref(&tree.background),
            value_mask: 0,
            lower_key: NO_KEY,
            lower: 0,
            upper_key: NO_KEY,
            upper: 0,
        }
    }

    /// The value at index coordinate `p` (same result as [`Tree::value`]).
    #[inline(always)]
    pub fn value(&mut self, p: IVec3) -> T {
        if p & IVec3::splat(self.region_mask) == self.region_key {
            return self.region_values[Leaf::<T>::offset(p) & self.value_mask];
        }
        self.value_slow(p)
    }

    #[inline(always)]
    fn cache(&mut self, p: IVec3, mask: i32, values: &'a [T], value_mask: usize) -> T {
        self.region_mask = mask;
        self.region_key = p & IVec3::splat(mask);
        self.region_values = values;
        self.value_mask = value_mask;
        values[Leaf::<T>::offset(p) & value_mask]
    }

    #[inline(never)]
    fn value_slow(&mut self, p: IVec3) -> T {
        // Key masks of the three cached levels: a leaf-sized block, a lower node, a root region.
        let (leaf, lower, root) = (
            !(Leaf::<T>::DIM - 1),
            !(LowerNode::<T>::DIM - 1),
            !(Root::<T>::DIM - 1),
        );
        let t = self.tree;
        if LowerNode::<T>::origin_of(p) != self.lower_key {
            if Root::<T>::key(p) != self.upper_key {
                match t.root.get(p) {
                    None => return self.cache(p, root, std::slice::from_ref(&t.background), 0),
                    Some(RootSlot::Tile { value, .. }) => {
                        return self.cache(p, root, std::slice::from_ref(value), 0)
                    }
                    Some(RootSlot::Child(u)) => {
                        self.upper = *u;
                        self.upper_key = Root::<T>::key(p);
                    }
                }
            }
            let n = &t.uppers[self.upper as usize];
            let s = UpperNode::<T>::slot(p);
            match n.child(s) {
                None => return self.cache(p, lower, std::slice::from_ref(&n.tiles[s]), 0),
                Some(l) => {
                    self.lower = l;
                    self.lower_key = LowerNode::<T>::origin_of(p);
                }
            }
        }
        let n = &t.lowers[self.lower as usize];
        let s = LowerNode::<T>::slot(p);
        match n.child(s) {
            None => self.cache(p, leaf, std::slice::from_ref(&n.tiles[s]), 0),
            Some(c) => self.cache(p, leaf, &t.leaves[c as usize].values, 511),
        }
    }

    /// Trilinear interpolation at a continuous index position (OpenVDB `BoxSampler` convention).
    #[inline]
    pub fn sample_trilinear(&mut self, index_pos: Vec3) -> T {
        let p = floor_ivec3(index_pos);
        let f = index_pos - p.as_vec3();
        let corners = self.corners(p);
        let c00 = T::lerp(corners[0], corners[1], f.z);
        let c01 = T::lerp(corners[2], corners[3], f.z);
        let c10 = T::lerp(corners[4], corners[5], f.z);
        let c11 = T::lerp(corners[6], corners[7], f.z);
        let c0 = T::lerp(c00, c01, f.y);
        let c1 = T::lerp(c10, c11, f.y);
        T::lerp(c0, c1, f.x)
    }

    /// The eight voxels `p + {0, 1}³` that a trilinear lookup in the cell `[p, p + 1)³` reads, in the order
    /// (x, y, z) = 000, 001, 010, 011, 100, 101, 110, 111. Always inlined: as a call it made every trilinear
    /// lookup of the peer benchmark's plume 14% slower.
    #[inline(always)]
    pub fn corners(&mut self, p: IVec3) -> [T; 8] {
        let last = Leaf::<T>::DIM - 1;
        if (p & last).cmpne(IVec3::splat(last)).all() {
            // All eight corners lie in one leaf-sized cell: read them from the cached region directly.
            self.value(p);
            let base = Leaf::<T>::offset(p);
            let m = self.value_mask;
            let v = self.region_values;
            let g = |o: usize| v[(base + o) & m];
            [g(0), g(1), g(8), g(9), g(64), g(65), g(72), g(73)]
        } else {
            let mut v = |dx: i32, dy: i32, dz: i32| self.value(p + IVec3::new(dx, dy, dz));
            [
                v(0, 0, 0),
                v(0, 0, 1),
                v(0, 1, 0),
                v(0, 1, 1),
                v(1, 0, 0),
                v(1, 0, 1),
                v(1, 1, 0),
                v(1, 1, 1),
            ]
        }
    }
}

/// The region checks the corpus tests use too (`tests/support/regions.rs`).
#[cfg(test)]
#[path = "../../tests/support/regions.rs"]
mod regions_check;

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> FloatTree {
        // f(i,j,k) = i + 10 j + 100 k on a 3x3x3 block straddling leaf and node boundaries.
        let mut v = Vec::new();
        for i in -1..2 {
            for j in 6..9 {
                for k in 126..129 {
                    v.push((IVec3::new(i, j, k), (i + 10 * j + 100 * k) as f32));
                }
            }
        }
        FloatTree::from_voxels(-5.0, v)
    }

    /// The bounding box read off a mask's words and bytes is the one of its set bits' voxels, found one by one.
    #[test]
    fn mask_bbox_is_the_box_of_the_set_voxels() {
        let mut rng = crate::math::Rng::new(7, 0);
        for case in 0..2000 {
            let mut mask = [0u64; 8];
            // From one bit to dense masks: as many random bits as the case number says, up to 64.
            for _ in 0..(case % 64) {
                let i = (rng.next_f32() * 512.0) as usize % 512;
                set_bit(&mut mask, i);
            }
            let mut expected: Option<(IVec3, IVec3)> = None;
            for i in (0..512).filter(|&i| bit(&mask, i)) {
                let p = IVec3::new(i as i32 >> 6, (i as i32 >> 3) & 7, i as i32 & 7);
                expected = Some(expected.map_or((p, p), |(a, b)| (a.min(p), b.max(p))));
            }
            assert_eq!(mask_bbox(&mask), expected, "{mask:x?}");
        }
    }

    #[test]
    fn floor_matches_std() {
        for x in [
            -2.5f32, -2.0, -0.5, -0.0, 0.0, 0.3, 1.0, 7.99, -1e-7, 123456.7,
        ] {
            let v = Vec3::new(x, -x, x * 0.5);
            assert_eq!(floor_ivec3(v), v.floor().as_ivec3(), "{v}");
        }
    }

    #[test]
    fn lookups() {
        let t = tiny();
        assert_eq!(t.value(IVec3::new(0, 7, 127)), 12770.0);
        assert_eq!(t.value(IVec3::new(-1, 8, 128)), 12879.0);
        assert_eq!(t.value(IVec3::new(5000, 0, 0)), -5.0);
        // Inactive voxel inside an existing leaf keeps its stored value (here the fill, background).
        assert_eq!(t.value(IVec3::new(3, 7, 127)), -5.0);
        assert!(t.is_active(IVec3::new(1, 6, 126)));
        assert!(!t.is_active(IVec3::new(2, 6, 126)));
        let mut a = t.accessor();
        for i in -3..4 {
            for j in 4..10 {
                for k in 120..132 {
                    let p = IVec3::new(i, j, k);
                    assert_eq!(a.value(p), t.value(p));
                }
            }
        }
        let s = t.stats();
        assert_eq!(s.active_voxels, 27);
        assert_eq!(
            s.bbox,
            Some((IVec3::new(-1, 6, 126), IVec3::new(1, 8, 128)))
        );
        assert_eq!(s.min, 12659.0);
        assert_eq!(s.max, 12881.0);
        assert_eq!(t.leaves.len(), 8);
    }

    #[test]
    fn trilinear_matches_hand_values() {
        let t = tiny();
        // A linear field is reproduced exactly inside the block.
        let p = Vec3::new(0.25, 7.5, 127.75);
        let expect = 0.25 + 75.0 + 12775.0;
        assert!((t.sample_trilinear(p) - expect).abs() < 1e-2);
        // At an integer position the sample is the voxel value.
        assert_eq!(t.sample_trilinear(Vec3::new(1.0, 8.0, 128.0)), 12881.0);
        // Half-way to an outside voxel (background -5): mean of 12881 and -5 on the x edge.
        let v = t.sample_trilinear(Vec3::new(1.5, 8.0, 128.0));
        assert!((v - (12881.0 - 5.0) / 2.0).abs() < 1e-3);
        // Negative coordinates floor correctly: x = -0.5 mixes voxels -1 and 0.
        let v = t.sample_trilinear(Vec3::new(-0.5, 6.0, 126.0));
        assert!((v - (12659.0 + 12660.0) / 2.0).abs() < 1e-3);
    }

    #[test]
    fn node_ranges_bound_values() {
        let t = tiny();
        for lf in &t.leaves {
            for &v in &lf.values {
                assert!(lf.min <= v && v <= lf.max);
            }
        }
        for n in &t.lowers {
            // Nodes hold background tiles as well as their leaves' values.
            let leaf_max = n
                .children
                .iter()
                .filter(|&&c| c != NO_CHILD)
                .map(|&c| t.leaves[c as usize].max)
                .fold(f32::MIN, f32::max);
            assert_eq!((n.min, n.max), (-5.0, leaf_max));
        }
        let upper_max = t.uppers.iter().map(|n| n.max).fold(f32::MIN, f32::max);
        assert_eq!(upper_max, 12881.0);
    }

    fn naive_trilinear(t: &FloatTree, x: Vec3) -> f32 {
        let f0 = x.floor();
        let f = x - f0;
        let p = f0.as_ivec3();
        let v = |dx, dy, dz| t.value(p + IVec3::new(dx, dy, dz));
        let l = |a: f32, b: f32, w: f32| a + (b - a) * w;
        l(
            l(
                l(v(0, 0, 0), v(0, 0, 1), f.z),
                l(v(0, 1, 0), v(0, 1, 1), f.z),
                f.y,
            ),
            l(
                l(v(1, 0, 0), v(1, 0, 1), f.z),
                l(v(1, 1, 0), v(1, 1, 1), f.z),
                f.y,
            ),
            f.x,
        )
    }

    /// Slots of the first upper and lower node of `tiny` without a child.
    fn free_slots(t: &FloatTree) -> (usize, usize) {
        let us = (0..UpperNode::<f32>::SLOTS)
            .find(|&i| t.uppers[0].child(i).is_none())
            .unwrap();
        let ls = (0..LowerNode::<f32>::SLOTS)
            .find(|&i| t.lowers[0].child(i).is_none())
            .unwrap();
        (us, ls)
    }

    /// `tiny` plus an active root tile (4096³), an inactive upper-level tile (128³) and an active lower-level tile
    /// (8³), all non-zero.
    fn tiled() -> FloatTree {
        let mut t = tiny();
        t.root.entries.push((
            IVec3::new(4096, 0, 0),
            RootSlot::Tile {
                value: 3.0,
                active: true,
            },
        ));
        let (us, ls) = free_slots(&t);
        t.uppers[0].tiles[us] = 4.0;
        t.lowers[0].tiles[ls] = 5.0;
        set_bit(&mut t.lowers[0].value_mask, ls);
        t.finalize();
        t
    }

    #[test]
    fn accessor_matches_tree_with_tiles_at_every_level() {
        let t = tiled();
        let (us, ls) = free_slots(&t);
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 33) as f32) / (1u64 << 31) as f32
        };
        let mut a = t.accessor();
        let lo = Vec3::new(-300.0, -200.0, -100.0);
        let size = Vec3::new(4700.0, 400.0, 400.0);
        for i in 0..200_000 {
            let x = if i % 2 == 0 {
                lo + Vec3::new(next(), next(), next()) * size
            } else {
                Vec3::new(-1.5, 6.0, 126.0) + Vec3::new(next(), next(), next()) * 4.0
            };
            let p = x.floor().as_ivec3();
            assert_eq!(a.value(p), t.value(p), "at {p}");
            let (s, n) = (a.sample_trilinear(x), naive_trilinear(&t, x));
            assert!(
                (s - n).abs() <= 1e-3 * n.abs().max(1.0),
                "at {x}: {s} vs {n}"
            );
        }
        assert_eq!(t.value(IVec3::new(5000, 7, 9)), 3.0);
        assert_eq!(t.value(t.uppers[0].slot_origin(us) + IVec3::splat(5)), 4.0);
        assert_eq!(t.value(t.lowers[0].slot_origin(ls) + IVec3::splat(1)), 5.0);
    }

    use super::regions_check::{active_voxels_of_regions, check_regions_in};

    #[test]
    fn regions_in_a_box_match_a_voxel_scan() {
        let t = tiled();
        let (us, ls) = free_slots(&t);
        let (upper_tile, lower_tile) = (t.uppers[0].slot_origin(us), t.lowers[0].slot_origin(ls));
        // Boxes across leaf, node and root boundaries, over each kind of tile, and one in empty space.
        let boxes = [
            (IVec3::new(-3, 4, 120), IVec3::new(3, 10, 131)),
            (lower_tile - 2, lower_tile + 9),
            (upper_tile + 120, upper_tile + 135),
            (IVec3::new(4090, -3, -3), IVec3::new(4100, 3, 3)),
            (IVec3::new(-9000, 5000, 7), IVec3::new(-8990, 5010, 17)),
        ];
        for (lo, hi) in boxes {
            check_regions_in(&t, lo, hi);
        }
        assert_eq!(
            check_regions_in(&t, IVec3::new(-1, 6, 126), IVec3::new(1, 8, 128)),
            27
        );
        // The whole tree: every active voxel lies in some region, counted as the statistics count them.
        let s = t.stats();
        assert_eq!(active_voxels_of_regions(&t), s.active_voxels);
        assert_eq!(s.active_voxels, 27 + 4096u64.pow(3) + 512);
        assert_eq!(s.tiles, 2);
        // Regions in a box are those of the whole tree that meet it.
        let (lo, hi) = (IVec3::new(-3, 4, 120), IVec3::new(3, 10, 131));
        let meets = |r: &Region<f32>| {
            r.origin().cmple(hi).all() && (r.origin() + (r.edge() - 1)).cmpge(lo).all()
        };
        let key = |r: Region<f32>| (r.origin().to_array(), r.edge());
        let all: Vec<_> = t.regions().filter(meets).map(key).collect();
        let some: Vec<_> = t.regions_in(lo, hi).map(key).collect();
        assert_eq!(all, some);
    }
}
