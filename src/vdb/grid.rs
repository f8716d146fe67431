//! The renderer's sparse grid: a flat, index-linked VDB tree in the spirit of NanoVDB.
//!
//! A [`Tree`] is a sorted root table of 4096³ regions, each a tile or an [`UpperNode`] (32³ slots of 128³),
//! whose slots are tiles or [`LowerNode`]s (16³ slots of 8³), whose slots are tiles or [`Leaf`]s (8³ voxels).
//! Nodes live in flat vectors and refer to children by `u32` index; lookups use bit arithmetic only (no hashing).
//! Every node and leaf carries the min/max of all values a lookup inside it can return (active or not), so a
//! majorant built from them is a true bound.

use glam::{IVec3, Vec3};

/// Sentinel child index meaning "this slot is a tile".
pub const NO_CHILD: u32 = u32::MAX;
/// log2 of the leaf edge (8 voxels).
pub const LEAF_LOG2: i32 = 3;
/// log2 of the lower-node edge in voxels (128).
pub const LOWER_LOG2: i32 = 7;
/// log2 of the upper-node edge in voxels (4096).
pub const UPPER_LOG2: i32 = 12;

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

fn set_bit(mask: &mut [u64], i: usize) {
    mask[i >> 6] |= 1 << (i & 63);
}

/// An 8³ block of voxels.
#[derive(Clone, Debug)]
pub struct Leaf<T> {
    /// Index coordinate of voxel (0,0,0) of the leaf (a multiple of 8).
    pub origin: IVec3,
    /// Active-voxel bits, voxel `(x<<6)|(y<<3)|z`.
    pub value_mask: [u64; 8],
    /// All 512 stored values (inactive ones keep what the file stored).
    pub values: [T; 512],
    /// Minimum over all 512 values.
    pub min: T,
    /// Maximum over all 512 values.
    pub max: T,
}

impl<T> Leaf<T> {
    /// Inclusive index bounding box covered by the leaf.
    pub fn bbox(&self) -> (IVec3, IVec3) {
        (self.origin, self.origin + IVec3::splat(7))
    }

    /// Whether voxel `i` (`(x<<6)|(y<<3)|z`) is active.
    pub fn is_active(&self, i: usize) -> bool {
        bit(&self.value_mask, i)
    }
}

/// A node of `N` slots, each a child (by index) or a tile value.
#[derive(Clone, Debug)]
pub struct InternalNode<T> {
    /// Index coordinate of the node's first voxel.
    pub origin: IVec3,
    /// Child index per slot, or [`NO_CHILD`] for a tile.
    pub children: Box<[u32]>,
    /// Tile value per slot (meaningless where a child is present).
    pub tiles: Box<[T]>,
    /// Active-tile bits per slot.
    pub value_mask: Box<[u64]>,
    /// Minimum over tiles and children (all values a lookup inside the node can return).
    pub min: T,
    /// Maximum over tiles and children.
    pub max: T,
}

/// A 16³ node over 8³ leaves (128³ voxels).
pub type LowerNode<T> = InternalNode<T>;
/// A 32³ node over lower nodes (4096³ voxels).
pub type UpperNode<T> = InternalNode<T>;

impl<T: VoxelValue> InternalNode<T> {
    fn new(origin: IVec3, log2: u32, fill: T) -> Self {
        let n = 1usize << (3 * log2);
        Self {
            origin,
            children: vec![NO_CHILD; n].into_boxed_slice(),
            tiles: vec![fill; n].into_boxed_slice(),
            value_mask: vec![0u64; n / 64].into_boxed_slice(),
            min: fill,
            max: fill,
        }
    }

    /// Edge length of the node in voxels (128 for lower nodes, 4096 for upper nodes).
    pub fn edge(&self) -> i32 {
        if self.children.len() == 4096 {
            1 << LOWER_LOG2
        } else {
            1 << UPPER_LOG2
        }
    }

    /// Inclusive index bounding box covered by the node.
    pub fn bbox(&self) -> (IVec3, IVec3) {
        (self.origin, self.origin + IVec3::splat(self.edge() - 1))
    }

    /// Index origin of slot `i` (a child's or tile's first voxel).
    pub fn slot_origin(&self, i: usize) -> IVec3 {
        if self.children.len() == 4096 {
            lower_child_origin(self.origin, i)
        } else {
            upper_child_origin(self.origin, i)
        }
    }

    /// True when slot `i` holds an active tile.
    pub fn is_active_tile(&self, i: usize) -> bool {
        self.children[i] == NO_CHILD && bit(&self.value_mask, i)
    }
}

/// One entry of the root table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RootSlot<T> {
    /// A 4096³ tile.
    Tile {
        /// Its value.
        value: T,
        /// Whether it is active.
        active: bool,
    },
    /// Index into [`Tree::uppers`].
    Child(u32),
}

/// Summary statistics over the active values of a tree (tiles weighted by their voxel count).
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

/// A sparse VDB tree with 5-4-3 node sizes, values of type `T`.
#[derive(Clone, Debug)]
pub struct Tree<T> {
    /// Value returned outside all nodes and tiles.
    pub background: T,
    /// Root table, sorted by origin `(x, y, z)`.
    pub root: Vec<(IVec3, RootSlot<T>)>,
    /// Upper (32³) nodes.
    pub uppers: Vec<UpperNode<T>>,
    /// Lower (16³) nodes.
    pub lowers: Vec<LowerNode<T>>,
    /// Leaves (8³).
    pub leaves: Vec<Leaf<T>>,
}

/// A scalar tree.
pub type FloatTree = Tree<f32>;
/// A vector tree.
pub type Vec3Tree = Tree<Vec3>;

#[inline(always)]
fn key_cmp(a: IVec3, b: IVec3) -> std::cmp::Ordering {
    (a.x, a.y, a.z).cmp(&(b.x, b.y, b.z))
}

#[inline(always)]
fn upper_slot(p: IVec3) -> usize {
    ((((p.x & 4095) >> 7) << 10) | (((p.y & 4095) >> 7) << 5) | ((p.z & 4095) >> 7)) as usize
}
#[inline(always)]
fn lower_slot(p: IVec3) -> usize {
    ((((p.x & 127) >> 3) << 8) | (((p.y & 127) >> 3) << 4) | ((p.z & 127) >> 3)) as usize
}
#[inline(always)]
fn leaf_slot(p: IVec3) -> usize {
    (((p.x & 7) << 6) | ((p.y & 7) << 3) | (p.z & 7)) as usize
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

/// Index origin of slot `i` of an upper node.
pub fn upper_child_origin(origin: IVec3, i: usize) -> IVec3 {
    let i = i as i32;
    origin + IVec3::new(i >> 10, (i >> 5) & 31, i & 31) * 128
}
/// Index origin of slot `i` of a lower node.
pub fn lower_child_origin(origin: IVec3, i: usize) -> IVec3 {
    let i = i as i32;
    origin + IVec3::new(i >> 8, (i >> 4) & 15, i & 15) * 8
}
/// Index coordinate of voxel `i` of a leaf.
pub fn leaf_voxel(origin: IVec3, i: usize) -> IVec3 {
    let i = i as i32;
    origin + IVec3::new(i >> 6, (i >> 3) & 7, i & 7)
}

impl<T: VoxelValue> Tree<T> {
    /// An empty tree that returns `background` everywhere.
    pub fn new(background: T) -> Self {
        Self {
            background,
            root: Vec::new(),
            uppers: Vec::new(),
            lowers: Vec::new(),
            leaves: Vec::new(),
        }
    }

    /// Builds a tree from active voxels (later duplicates win); inactive voxels of new leaves hold `background`.
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
    pub fn set_active(&mut self, p: IVec3, v: T) {
        let key = p & !4095;
        let u = match self.root.binary_search_by(|(k, _)| key_cmp(*k, key)) {
            Ok(i) => match self.root[i].1 {
                RootSlot::Child(u) => u,
                RootSlot::Tile { value, .. } => {
                    let u = self.push_upper(key, value);
                    self.root[i].1 = RootSlot::Child(u);
                    u
                }
            },
            Err(i) => {
                let u = self.push_upper(key, self.background);
                self.root.insert(i, (key, RootSlot::Child(u)));
                u
            }
        };
        let us = upper_slot(p);
        let up = &self.uppers[u as usize];
        let l = if up.children[us] == NO_CHILD {
            let fill = up.tiles[us];
            let l = self.lowers.len() as u32;
            self.lowers.push(InternalNode::new(p & !127, 4, fill));
            self.uppers[u as usize].children[us] = l;
            l
        } else {
            up.children[us]
        };
        let ls = lower_slot(p);
        let lo = &self.lowers[l as usize];
        let leaf = if lo.children[ls] == NO_CHILD {
            let fill = lo.tiles[ls];
            let id = self.leaves.len() as u32;
            self.leaves.push(Leaf {
                origin: p & !7,
                value_mask: [0; 8],
                values: [fill; 512],
                min: fill,
                max: fill,
            });
            self.lowers[l as usize].children[ls] = id;
            id
        } else {
            lo.children[ls]
        };
        let lf = &mut self.leaves[leaf as usize];
        let i = leaf_slot(p);
        lf.values[i] = v;
        set_bit(&mut lf.value_mask, i);
    }

    fn push_upper(&mut self, origin: IVec3, fill: T) -> u32 {
        self.uppers.push(InternalNode::new(origin, 5, fill));
        (self.uppers.len() - 1) as u32
    }

    /// Recomputes every leaf's and node's min/max (bottom-up).
    pub fn finalize(&mut self) {
        for lf in &mut self.leaves {
            let (mut lo, mut hi) = (lf.values[0], lf.values[0]);
            for &v in &lf.values[1..] {
                lo = lo.min_of(v);
                hi = hi.max_of(v);
            }
            lf.min = lo;
            lf.max = hi;
        }
        let leaves = &self.leaves;
        for n in &mut self.lowers {
            node_range(n, |c| (leaves[c].min, leaves[c].max));
        }
        let lowers = &self.lowers;
        for n in &mut self.uppers {
            node_range(n, |c| (lowers[c].min, lowers[c].max));
        }
    }

    /// Root-table lookup.
    #[inline]
    fn root_slot(&self, p: IVec3) -> Option<&RootSlot<T>> {
        let key = p & !4095;
        if self.root.len() <= 8 {
            self.root.iter().find(|(k, _)| *k == key).map(|(_, s)| s)
        } else {
            self.root
                .binary_search_by(|(k, _)| key_cmp(*k, key))
                .ok()
                .map(|i| &self.root[i].1)
        }
    }

    /// The value at index coordinate `p`: the stored voxel or tile value, or the background outside the tree.
    #[inline]
    pub fn value(&self, p: IVec3) -> T {
        match self.root_slot(p) {
            None => self.background,
            Some(RootSlot::Tile { value, .. }) => *value,
            Some(RootSlot::Child(u)) => self.upper_value(*u, p),
        }
    }

    #[inline(always)]
    fn upper_value(&self, u: u32, p: IVec3) -> T {
        let n = &self.uppers[u as usize];
        let s = upper_slot(p);
        match n.children[s] {
            NO_CHILD => n.tiles[s],
            l => self.lower_value(l, p),
        }
    }

    #[inline(always)]
    fn lower_value(&self, l: u32, p: IVec3) -> T {
        let n = &self.lowers[l as usize];
        let s = lower_slot(p);
        match n.children[s] {
            NO_CHILD => n.tiles[s],
            c => self.leaves[c as usize].values[leaf_slot(p)],
        }
    }

    /// Whether the voxel at `p` is active (in an active leaf voxel or active tile).
    pub fn is_active(&self, p: IVec3) -> bool {
        match self.root_slot(p) {
            None => false,
            Some(RootSlot::Tile { active, .. }) => *active,
            Some(RootSlot::Child(u)) => {
                let n = &self.uppers[*u as usize];
                let s = upper_slot(p);
                if n.children[s] == NO_CHILD {
                    return bit(&n.value_mask, s);
                }
                let n = &self.lowers[n.children[s] as usize];
                let s = lower_slot(p);
                if n.children[s] == NO_CHILD {
                    return bit(&n.value_mask, s);
                }
                bit(
                    &self.leaves[n.children[s] as usize].value_mask,
                    leaf_slot(p),
                )
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

    /// Inclusive bounding box of the active voxels and tiles, `None` if nothing is active.
    pub fn active_bbox(&self) -> Option<(IVec3, IVec3)> {
        self.stats().bbox
    }

    /// Approximate heap plus inline size of the tree in bytes.
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        let node = |n: &InternalNode<T>| {
            size_of::<InternalNode<T>>()
                + n.children.len() * (4 + size_of::<T>())
                + n.value_mask.len() * 8
        };
        size_of::<Self>()
            + self.root.capacity() * size_of::<(IVec3, RootSlot<T>)>()
            + self.uppers.iter().map(node).sum::<usize>()
            + self.lowers.iter().map(node).sum::<usize>()
            + self.leaves.capacity() * size_of::<Leaf<T>>()
    }

    /// Statistics over active values: counts, sum, min, max (magnitudes for vectors) and the active bbox.
    pub fn stats(&self) -> TreeStats {
        let mut s = TreeStats::default();
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut bmin = IVec3::splat(i32::MAX);
        let mut bmax = IVec3::splat(i32::MIN);
        let mut tile = |s: &mut TreeStats, v: T, origin: IVec3, log2: i32| {
            let m = v.magnitude();
            let n = 1u64 << (3 * log2);
            s.active_voxels += n;
            s.tiles += 1;
            s.sum += m * n as f64;
            lo = lo.min(m);
            hi = hi.max(m);
            bmin = bmin.min(origin);
            bmax = bmax.max(origin + IVec3::splat((1 << log2) - 1));
        };
        for (origin, slot) in &self.root {
            if let RootSlot::Tile {
                value,
                active: true,
            } = slot
            {
                tile(&mut s, *value, *origin, UPPER_LOG2);
            }
        }
        for n in &self.uppers {
            for i in 0..n.children.len() {
                if n.is_active_tile(i) {
                    tile(
                        &mut s,
                        n.tiles[i],
                        upper_child_origin(n.origin, i),
                        LOWER_LOG2,
                    );
                }
            }
        }
        for n in &self.lowers {
            for i in 0..n.children.len() {
                if n.is_active_tile(i) {
                    tile(
                        &mut s,
                        n.tiles[i],
                        lower_child_origin(n.origin, i),
                        LEAF_LOG2,
                    );
                }
            }
        }
        for lf in &self.leaves {
            s.leaves += 1;
            let mut lsum = 0.0;
            for (w, &word) in lf.value_mask.iter().enumerate() {
                let mut word = word;
                while word != 0 {
                    let i = w * 64 + word.trailing_zeros() as usize;
                    word &= word - 1;
                    let m = lf.values[i].magnitude();
                    lsum += m;
                    lo = lo.min(m);
                    hi = hi.max(m);
                    let p = leaf_voxel(lf.origin, i);
                    bmin = bmin.min(p);
                    bmax = bmax.max(p);
                    s.leaf_voxels += 1;
                }
            }
            s.sum += lsum;
        }
        s.active_voxels += s.leaf_voxels;
        if s.active_voxels > 0 {
            s.min = lo;
            s.max = hi;
            s.bbox = Some((bmin, bmax));
        }
        s
    }
}

fn node_range<T: VoxelValue>(n: &mut InternalNode<T>, child: impl Fn(usize) -> (T, T)) {
    let mut r: Option<(T, T)> = None;
    for (i, &c) in n.children.iter().enumerate() {
        let (a, b) = if c == NO_CHILD {
            (n.tiles[i], n.tiles[i])
        } else {
            child(c as usize)
        };
        r = Some(match r {
            None => (a, b),
            Some((lo, hi)) => (lo.min_of(a), hi.max_of(b)),
        });
    }
    if let Some((lo, hi)) = r {
        n.min = lo;
        n.max = hi;
    }
}

/// Cached, coherent access to a [`Tree`]: remembers the last leaf, lower and upper node it visited.
///
/// The innermost cache is a region (a leaf, or a tile of any level, or an empty root region) with its values:
/// a lookup inside it is one masked compare and one load, whether the region holds voxels or a constant.
/// For incoherent (random) lookups [`Tree::value`] is a little faster: it has no cache to update.
pub struct Accessor<'a, T> {
    tree: &'a Tree<T>,
    /// Key mask of the cached region (`!7`, `!127` or `!4095`).
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
            region_mask: !7,
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
            return self.region_values[leaf_slot(p) & self.value_mask];
        }
        self.value_slow(p)
    }

    #[inline(always)]
    fn cache(&mut self, p: IVec3, mask: i32, values: &'a [T], value_mask: usize) -> T {
        self.region_mask = mask;
        self.region_key = p & IVec3::splat(mask);
        self.region_values = values;
        self.value_mask = value_mask;
        values[leaf_slot(p) & value_mask]
    }

    #[inline(never)]
    fn value_slow(&mut self, p: IVec3) -> T {
        let t = self.tree;
        if p & !127 != self.lower_key {
            if p & !4095 != self.upper_key {
                match t.root_slot(p) {
                    None => return self.cache(p, !4095, std::slice::from_ref(&t.background), 0),
                    Some(RootSlot::Tile { value, .. }) => {
                        return self.cache(p, !4095, std::slice::from_ref(value), 0)
                    }
                    Some(RootSlot::Child(u)) => {
                        self.upper = *u;
                        self.upper_key = p & !4095;
                    }
                }
            }
            let n = &t.uppers[self.upper as usize];
            let s = upper_slot(p);
            match n.children[s] {
                NO_CHILD => return self.cache(p, !127, std::slice::from_ref(&n.tiles[s]), 0),
                l => {
                    self.lower = l;
                    self.lower_key = p & !127;
                }
            }
        }
        let n = &t.lowers[self.lower as usize];
        let s = lower_slot(p);
        match n.children[s] {
            NO_CHILD => self.cache(p, !7, std::slice::from_ref(&n.tiles[s]), 0),
            c => self.cache(p, !7, &t.leaves[c as usize].values, 511),
        }
    }

    /// Trilinear interpolation at a continuous index position (OpenVDB `BoxSampler` convention).
    #[inline]
    pub fn sample_trilinear(&mut self, index_pos: Vec3) -> T {
        let p = floor_ivec3(index_pos);
        let f = index_pos - p.as_vec3();
        let corners: [T; 8] = if (p & 7).cmpne(IVec3::splat(7)).all() {
            // All eight corners lie in one leaf-sized cell: read them from the cached region directly.
            self.value(p);
            let base = leaf_slot(p);
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
        };
        let c00 = T::lerp(corners[0], corners[1], f.z);
        let c01 = T::lerp(corners[2], corners[3], f.z);
        let c10 = T::lerp(corners[4], corners[5], f.z);
        let c11 = T::lerp(corners[6], corners[7], f.z);
        let c0 = T::lerp(c00, c01, f.y);
        let c1 = T::lerp(c10, c11, f.y);
        T::lerp(c0, c1, f.x)
    }
}

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

    #[test]
    fn accessor_matches_tree_with_tiles_at_every_level() {
        let mut t = tiny();
        t.root.push((
            IVec3::new(4096, 0, 0),
            RootSlot::Tile {
                value: 3.0,
                active: true,
            },
        ));
        // An upper-level tile (128^3) and a lower-level tile (8^3) without children.
        let us = (0..t.uppers[0].children.len())
            .find(|&i| t.uppers[0].children[i] == NO_CHILD)
            .unwrap();
        t.uppers[0].tiles[us] = 4.0;
        let ls = (0..4096)
            .find(|&i| t.lowers[0].children[i] == NO_CHILD)
            .unwrap();
        t.lowers[0].tiles[ls] = 5.0;
        t.finalize();
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
        assert_eq!(
            t.value(upper_child_origin(t.uppers[0].origin, us) + IVec3::splat(5)),
            4.0
        );
        assert_eq!(
            t.value(lower_child_origin(t.lowers[0].origin, ls) + IVec3::splat(1)),
            5.0
        );
    }
}
