//! An 8-wide bounding volume hierarchy over world-space triangles, built as a binary SAH tree.
//!
//! **Build.** Top-down binned SAH after Wald 2007, "On fast construction of SAH-based bounding volume
//! hierarchies" (IEEE Symposium on Interactive Ray Tracing): primitive centroids are binned into
//! `BINS` equal slabs of the node's centroid bounds along each axis, one sweep per axis evaluates the
//! surface area heuristic (Goldsmith and Salmon 1987; MacDonald and Booth 1990) at every bin boundary, and
//! a node becomes a leaf when that is cheaper than its best split and holds at most `MAX_LEAF` triangles.
//! A leaf's primitives are costed in blocks of those tested together (four for [`Bvh`]'s packs, one for
//! the moving triangles and instances), as Embree's builders do.
//! Subtrees above `PARALLEL_MIN` triangles are built in parallel with `rayon::join`; every decision is a
//! pure function of the triangles, so the tree is the same whatever the thread count.
//!
//! **Layout.** The binary SAH tree (32-byte nodes: six bounds, a child or triangle offset, a count) is
//! collapsed into 8-wide nodes (Dammertz, Hanika, Keller 2008, "Shallow bounding volume hierarchies for fast
//! SIMD ray tracing of incoherent rays", EGSR): 256 bytes holding the eight child boxes in
//! structure-of-arrays form, their offsets, counts and visiting orders, so two 4-lane SIMD slab tests cover all
//! eight. Which binary nodes become wide nodes, slots or leaves is chosen by the cost-driven dynamic programme
//! of Ylitie, Karras and Laine 2017 ([`Collapse`]), which may also merge a subtree of up to `WIDE_MAX_LEAF`
//! primitives into one leaf slot: on the benchmark mesh (`benches/bvh.rs`, 1M triangles) the nodes hold 7.5
//! slots on average (a greedy collapse that opened the largest child first left 3.9, with 42 % of the nodes
//! holding two), and against 4-wide nodes a ray took 36–38 % fewer node steps, coherent rays traced 3 % more
//! and incoherent ones 21–31 % more per CPU-second (docs/performance.md). Triangles are copied into leaf
//! order, four to a structure-of-arrays pack
//! ([`Triangle4`], 40 bytes a triangle with its input index), each leaf starting a pack, so a leaf is one
//! contiguous run of packs tested four triangles at a time, like the four-triangle leaves of Embree (Wald et
//! al. 2014, "Embree: a kernel framework for efficient CPU ray tracing", ACM TOG 33(4)). The SAH counts a
//! leaf's cost in packs (`⌈n/4⌉`), which favours leaves of four. On the benchmark mesh this traced 6–9%
//! (coherent) and 20–35% (incoherent) more rays per CPU-second than testing a leaf's triangles one at a
//! time (back-to-back runs on a loaded 2-core machine).
//!
//! **Traversal.** A stack-based loop. Of a node's hit children the first in a front-to-back order is visited
//! next directly and the others are pushed with their entry distances; a popped entry is skipped if a closer
//! hit was found meanwhile. The order needs no distance sort: at the collapse each wide node records, for each
//! of the eight direction octants, the order of its slots that takes the two sides of every binary split inside
//! it by the sign of the direction along the axis on which the two sides' centres lie farthest apart (the
//! ordered traversal of shallow BVHs in Dammertz et al. 2008, with the split axis taken from the boxes). With
//! that order the pushes are branch-free: every slot's entry is written into the eight entries above the top
//! (one bounds check a node) and the top advances past the hit ones, while the first hit child in the order is
//! kept from the same loop (a select, not a pop of what was just written). Each query clears a 32-entry stack
//! first; a ray that would overflow it (none of the bench's) is traced again from the start with a stack that
//! always suffices. An any-hit query pops without comparing distances (its clip never moves). On CPUs with AVX2
//! a second copy of the traversal, chosen once a query, tests a node's eight boxes as one 8-lane slab test, lane
//! by lane the operations of the 4-lane one (no FMA), so its answers are bit for bit the same. These three took
//! coherent rays on the benchmark mesh from 3.28 to 4.03 (closest) and from 3.88 to 4.77 (occlusion) Mrays per
//! CPU-second (docs/performance.md).
//! On the benchmark mesh, against distance-sorted pushes, nodes and triangles per ray stayed within 5 %; this
//! traversal with the min/max slab test below traced 15–17 % more coherent closest-hit rays and 8–10 % more
//! coherent occlusion rays per CPU-second than the previous one, and incoherent rays no differently beyond the
//! machine's noise (docs/performance.md). The slab test (Williams, Barrus, Morley,
//! Shirley 2005, "An efficient and robust ray-box intersection algorithm", JGT 10(1)) uses a precomputed
//! inverse direction with per-axis near/far planes picked by the direction's sign, ignores the NaN of a ray
//! lying in a slab plane, and widens the far distance to cover floating-point error (Ize 2013, "Robust BVH Ray
//! Traversal", JCGT 2(2)), as Woop et al. 2013 also require; its running maximum and minimum are SSE's
//! `maxps`/`minps`, whose definition (`a > b ? a : b`) is that of the select it replaces. The per-ray setup is
//! kept small for meshes of a few triangles, where it is most of a query's work: the triangle test's constants
//! ([`WatertightRay`]) are computed at the first leaf a ray reaches, so a ray that misses every leaf box never
//! pays for them (on a cloud over a two-triangle ground this and a branch-free setup took 3.8 % off the render's
//! instructions, docs/performance.md).
//!
//! **Exactness.** Among hits at exactly the same distance the lowest input index wins, and the boxes are
//! widened enough that a triangle the brute-force test would hit is never culled, so
//! [`Bvh::intersect`] returns bit for bit what testing every triangle in input order returns.

use super::triangle::{Triangle4, TriangleHit, WatertightRay};
use crate::math::{gamma, Aabb, Ray, Vec3, Vec4};

/// Number of centroid bins per axis in the binned SAH (Wald 2007 bins into a small fixed number of slabs; 16–32 is usual).
const BINS: usize = 32;
/// Largest number of triangles in a leaf.
const MAX_LEAF: usize = 8;
/// Triangles per [`Triangle4`] pack: a [`Bvh`] leaf is tested this many triangles at a time.
const PACK: usize = 4;
/// Subtrees with at least this many triangles are built with `rayon::join`.
const PARALLEL_MIN: usize = 4096;
/// SAH cost of one traversal step, relative to one triangle test.
const COST_TRAVERSAL: f32 = 2.0;
/// SAH cost of one triangle test.
const COST_INTERSECT: f32 = 1.0;
/// Below this depth splits are chosen by the SAH; deeper nodes are split at the object median, which bounds
/// the tree depth by `SAH_MAX_DEPTH + 32` and so the traversal stack.
const SAH_MAX_DEPTH: u32 = 64;
/// Children of a wide node.
const WIDTH: usize = 8;
/// Largest number of primitives in a leaf slot of a wide node: the collapse may merge binary leaves into one
/// leaf slot up to this many ([`Collapse::plan`]).
const WIDE_MAX_LEAF: usize = 16;
/// Cost of testing one wide node in the collapse's SAH, relative to testing one block of a leaf (one pack of
/// four triangles).
const COST_NODE: f32 = 3.0;
/// Traversal stack size that always suffices: a wide node pushes at most `WIDTH - 1` entries after popping
/// one, and the wide tree is no deeper than the binary one.
const STACK_MAX: usize = (WIDTH - 1) * (SAH_MAX_DEPTH as usize + 32) + WIDTH + PUSH_SLACK;
/// Stack entries beyond those a ray can need that the octant-ordered push may write (it writes an entry for
/// every slot of a node and keeps the hit ones).
const PUSH_SLACK: usize = WIDTH;
/// Stack size of a query's first traversal; a ray that would overflow it is traced again from the start with
/// `STACK_MAX` entries. Every query clears its stack, so a smaller one costs each ray less; trees of up to
/// three levels of wide nodes (a few thousand triangles) can never overflow it, and on the bench's 1 M-triangle
/// mesh, whose bound is 71 entries, none of its 2²¹ rays did (docs/performance.md).
const STACK_FIRST: usize = 32;

/// Scale of a box's far distance. Ize 2013 shows `1 + 2γ(3)` covers the slab test's own rounding; we
/// double it so it also covers the rounding of the triangle test's distance, so that a hit on a box's
/// boundary is never culled.
const FAR_SCALE: f32 = 1.0 + 4.0 * gamma(3.0);

/// A 32-byte node. Interior nodes have `count == 0` and their children at `offset` and `offset + 1`;
/// leaves hold triangles `offset .. offset + count` of the reordered triangle array.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(32))]
struct Node {
    min: [f32; 3],
    max: [f32; 3],
    offset: u32,
    count: u32,
}

impl Node {
    fn new(bounds: &Aabb, offset: u32, count: u32) -> Self {
        Self {
            min: bounds.min.to_array(),
            max: bounds.max.to_array(),
            offset,
            count,
        }
    }

    /// The same node with its child offset moved by `base` (leaves are unchanged: their offsets index the
    /// triangle array, which does not move).
    fn shifted(self, base: usize) -> Self {
        if self.count == 0 {
            Self {
                offset: self.offset + base as u32,
                ..self
            }
        } else {
            self
        }
    }
}

/// A bounding volume hierarchy over triangles, for closest-hit and any-hit ray queries.
///
/// See the module documentation for the algorithms (binned SAH build after Wald 2007, watertight triangle
/// test after Woop et al. 2013, robust slab test after Williams et al. 2005 and Ize 2013).
#[derive(Clone, Debug)]
pub struct Bvh {
    /// The hierarchy over the triangles' boxes; its leaf slots name runs of `packs`.
    tree: Tree,
    /// The triangles in leaf order, four to a pack; each leaf starts a pack.
    packs: Vec<Triangle4>,
}

/// The node hierarchy over primitive boxes and its traversal, shared by [`Bvh`] (static triangles) and
/// [`crate::geometry::MotionBvh`] (moving ones), which differ only in what a leaf holds and how it is hit.
#[derive(Clone, Debug)]
pub(super) struct Tree {
    /// 8-wide nodes; the root is node 0.
    nodes: Vec<Node8>,
    /// Bounds of all primitives.
    bounds: Aabb,
    /// For each primitive in leaf order, its index in the input list (released by [`Tree::pack_leaves`]).
    prim_ids: Vec<u32>,
    /// Number of primitives given to the build (including those left out as non-finite).
    input_count: usize,
}

/// A triangle reference during the build: its bounds and input index.
#[derive(Clone, Copy, Debug)]
pub(super) struct PrimRef {
    min: Vec3,
    max: Vec3,
    id: u32,
}

impl PrimRef {
    /// The reference to input primitive `id` with box `bounds`.
    pub(super) fn new(bounds: Aabb, id: u32) -> Self {
        Self {
            min: bounds.min,
            max: bounds.max,
            id,
        }
    }

    fn centroid(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
}

/// One centroid bin: the bounds of the triangles whose centroids fall in it, and their number.
#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

impl Default for Bin {
    fn default() -> Self {
        Self {
            bounds: Aabb::EMPTY,
            count: 0,
        }
    }
}

/// What to do with a node: make it a leaf, or split it after the first `usize` (already partitioned) refs.
enum Plan {
    Leaf,
    Split(usize),
}

/// Maps centroids to bins along one axis: `bin = (c - lo)·scale`, clamped to the last bin.
#[derive(Clone, Copy)]
struct Binning {
    lo: Vec3,
    scale: Vec3,
}

impl Binning {
    fn new(centroids: &Aabb) -> Self {
        let extent = centroids.extent();
        // Slightly fewer than BINS slabs so the maximum centroid lands inside the last bin.
        let k = BINS as f32 * (1.0 - 1e-5);
        let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), k / extent, Vec3::ZERO);
        Self {
            lo: centroids.min,
            scale,
        }
    }

    fn bin(&self, c: Vec3, axis: usize) -> usize {
        (((c[axis] - self.lo[axis]) * self.scale[axis]) as usize).min(BINS - 1)
    }
}

/// Chooses how to treat the node holding `refs` and partitions `refs` for a split: the binned SAH of Wald
/// 2007, with an object-median fallback when all centroids coincide or the tree gets too deep. A side of `n`
/// primitives costs `⌈n / block⌉` tests, `block` being how many a leaf test handles at once.
fn plan(refs: &mut [PrimRef], bounds: &Aabb, depth: u32, block: u32) -> Plan {
    let n = refs.len();
    if n <= 1 {
        return Plan::Leaf;
    }
    let centroids = refs.iter().fold(Aabb::EMPTY, |b, r| b.extend(r.centroid()));
    let extent = centroids.extent();
    let axis = extent.max_position();

    let median = |refs: &mut [PrimRef]| {
        if n <= MAX_LEAF {
            return Plan::Leaf;
        }
        let mid = n / 2;
        refs.select_nth_unstable_by(mid, |a, b| {
            a.centroid()[axis]
                .total_cmp(&b.centroid()[axis])
                .then(a.id.cmp(&b.id))
        });
        Plan::Split(mid)
    };
    if depth >= SAH_MAX_DEPTH || extent[axis] <= 0.0 {
        return median(refs);
    }

    let binning = Binning::new(&centroids);
    let mut bins = [[Bin::default(); BINS]; 3];
    for r in refs.iter() {
        let c = r.centroid();
        let rb = Aabb::new(r.min, r.max);
        for (a, axis_bins) in bins.iter_mut().enumerate() {
            let bin = &mut axis_bins[binning.bin(c, a)];
            bin.bounds = bin.bounds.union(&rb);
            bin.count += 1;
        }
    }

    // Sweep each axis: the SAH numerator A_L·N_L + A_R·N_R at each of the BINS - 1 boundaries.
    let mut best = (f32::INFINITY, 0usize, 0usize);
    for (a, axis_bins) in bins.iter().enumerate() {
        if extent[a] <= 0.0 {
            continue;
        }
        let mut right_cost = [0.0f32; BINS];
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0u32);
        for i in (1..BINS).rev() {
            acc = acc.union(&axis_bins[i].bounds);
            cnt += axis_bins[i].count;
            right_cost[i] = if cnt > 0 {
                acc.surface_area() * cnt.div_ceil(block) as f32
            } else {
                f32::NAN
            };
        }
        let (mut acc, mut cnt) = (Aabb::EMPTY, 0u32);
        for i in 0..BINS - 1 {
            acc = acc.union(&axis_bins[i].bounds);
            cnt += axis_bins[i].count;
            // Boundary after bin i: both sides must be non-empty (NaN on the right side compares false).
            let cost = acc.surface_area() * cnt.div_ceil(block) as f32 + right_cost[i + 1];
            if cnt > 0 && cost < best.0 {
                best = (cost, a, i);
            }
        }
    }
    if !best.0.is_finite() {
        return median(refs);
    }

    let area = bounds.surface_area();
    let leaf_cost = COST_INTERSECT * (n as u32).div_ceil(block) as f32 * area;
    let split_cost = COST_TRAVERSAL * area + COST_INTERSECT * best.0;
    if n <= MAX_LEAF && leaf_cost <= split_cost {
        return Plan::Leaf;
    }

    let (_, split_axis, split_bin) = best;
    let mid = partition(refs, |r| binning.bin(r.centroid(), split_axis) <= split_bin);
    Plan::Split(mid)
}

/// Reorders `refs` so those satisfying `left` come first; returns how many do.
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> usize {
    let (mut i, mut j) = (0, refs.len());
    loop {
        while i < j && left(&refs[i]) {
            i += 1;
        }
        while i < j && !left(&refs[j - 1]) {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        refs.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}

fn bounds_of(refs: &[PrimRef]) -> Aabb {
    refs.iter().fold(Aabb::EMPTY, |b, r| {
        Aabb::new(b.min.min(r.min), b.max.max(r.max))
    })
}

/// Builds the subtree over `refs` (which start at index `first` of the final triangle order) sequentially.
/// Descendants are appended to `nodes`; the subtree's root is returned for the caller to place.
fn build_serial(
    refs: &mut [PrimRef],
    first: usize,
    depth: u32,
    block: u32,
    nodes: &mut Vec<Node>,
) -> Node {
    let bounds = bounds_of(refs);
    match plan(refs, &bounds, depth, block) {
        Plan::Leaf => Node::new(&bounds, first as u32, refs.len() as u32),
        Plan::Split(mid) => {
            let at = nodes.len();
            nodes.push(Node::new(&Aabb::EMPTY, 0, 0));
            nodes.push(Node::new(&Aabb::EMPTY, 0, 0));
            let (l, r) = refs.split_at_mut(mid);
            nodes[at] = build_serial(l, first, depth + 1, block, nodes);
            nodes[at + 1] = build_serial(r, first + mid, depth + 1, block, nodes);
            Node::new(&bounds, at as u32, 0)
        }
    }
}

/// Builds the subtree over `refs` with `rayon::join` on large nodes. Returns its root and its descendants,
/// whose child offsets are relative to the start of the returned vector. The layout equals
/// `build_serial`'s: the pair of children, then the left subtree, then the right.
fn build_parallel(refs: &mut [PrimRef], first: usize, depth: u32, block: u32) -> (Node, Vec<Node>) {
    if refs.len() < PARALLEL_MIN {
        let mut nodes = Vec::new();
        let root = build_serial(refs, first, depth, block, &mut nodes);
        return (root, nodes);
    }
    let bounds = bounds_of(refs);
    match plan(refs, &bounds, depth, block) {
        Plan::Leaf => (
            Node::new(&bounds, first as u32, refs.len() as u32),
            Vec::new(),
        ),
        Plan::Split(mid) => {
            let (l, r) = refs.split_at_mut(mid);
            let ((lroot, lnodes), (rroot, rnodes)) = rayon::join(
                || build_parallel(l, first, depth + 1, block),
                || build_parallel(r, first + mid, depth + 1, block),
            );
            let right_base = 2 + lnodes.len();
            let mut nodes = Vec::with_capacity(right_base + rnodes.len());
            nodes.push(lroot.shifted(2));
            nodes.push(rroot.shifted(right_base));
            nodes.extend(lnodes.into_iter().map(|n| n.shifted(2)));
            nodes.extend(rnodes.into_iter().map(|n| n.shifted(right_base)));
            (Node::new(&bounds, 0, 0), nodes)
        }
    }
}

/// An 8-wide node (256 bytes, four cache lines): the boxes of up to eight children in structure-of-arrays
/// form, two groups of four lanes per plane, so two 4-lane SIMD slab tests cover all eight, after the "multi
/// bounding volume hierarchies" of Ernst and Greiner 2008, the QBVH of Dammertz, Hanika, Keller 2008
/// ("Shallow bounding volume hierarchies for fast SIMD ray tracing of incoherent rays", EGSR) and the 8-wide
/// nodes of Embree (Wald et al. 2014). Slot `i` is a leaf with triangles `child[i] .. child[i] + count` when its
/// count ([`Node8::count`]) is not 0, else an inner node `child[i]`; unused slots hold an empty box, which no
/// ray hits.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct Node8 {
    /// `bounds[0][a][h]` and `bounds[1][a][h]`: the lower and upper bounds on axis `a` of boxes `4h .. 4h + 4`,
    /// so a ray picks its near and far planes by indexing with the sign of its direction.
    bounds: [[[Vec4; 2]; 3]; 2],
    child: [u32; WIDTH],
    /// Two fields in one word, so the node fits four cache lines: bits 0-23 of `meta[k]` are the slots in the
    /// order a ray of direction octant `k` (bit `a` set: negative along axis `a`) should visit them, three bits
    /// a slot, first slot lowest ([`Node8::order`]); bits 24-31 are slot `k`'s leaf primitive count (at most
    /// `MAX_LEAF`), 0 for an inner node or an unused slot ([`Node8::count`]).
    meta: [u32; WIDTH],
}

/// Bits of [`Node8::meta`] below the count.
const ORDER_BITS: u32 = 24;

/// Slots 0 to 7 in that order, as [`Node8::order`] encodes it.
const IDENTITY_ORDER: u32 = 0o76543210;

// A leaf's count must fit the top byte of `Node8::meta`, and an order its low bits.
const _: () = assert!(
    MAX_LEAF <= WIDE_MAX_LEAF
        && WIDE_MAX_LEAF <= u8::MAX as usize
        && 3 * WIDTH as u32 == ORDER_BITS
);

impl Node8 {
    const EMPTY: Node8 = Node8 {
        bounds: [[[Vec4::INFINITY; 2]; 3], [[Vec4::NEG_INFINITY; 2]; 3]],
        child: [0; WIDTH],
        meta: [IDENTITY_ORDER; WIDTH],
    };

    /// Puts the box of `node` in slot `i`: a leaf of `count` primitives at `child`, or with `count` 0 the
    /// wide node `child`.
    fn set_slot(&mut self, i: usize, node: &Node, child: u32, count: u32) {
        for a in 0..3 {
            self.bounds[0][a][i / 4][i % 4] = node.min[a];
            self.bounds[1][a][i / 4][i % 4] = node.max[a];
        }
        self.child[i] = child;
        // Leaves hold at most WIDE_MAX_LEAF primitives (see `Collapse::plan`), so the count always fits.
        debug_assert!(count as usize <= WIDE_MAX_LEAF);
        self.meta[i] = self.order(i) | count << ORDER_BITS;
    }

    /// Slot `i`'s leaf primitive count, 0 for an inner node or an unused slot.
    #[inline(always)]
    fn count(&self, i: usize) -> usize {
        (self.meta[i] >> ORDER_BITS) as usize
    }

    /// The visiting order of the slots for a ray of direction octant `octant`, three bits a slot, first lowest.
    #[inline(always)]
    fn order(&self, octant: usize) -> u32 {
        self.meta[octant] & ((1 << ORDER_BITS) - 1)
    }

    /// Sets the visiting order for direction octant `octant` (encoded as [`Node8::order`]).
    fn set_order(&mut self, octant: usize, order: u32) {
        self.meta[octant] = self.meta[octant] & !((1 << ORDER_BITS) - 1) | order;
    }

    /// Whether slot `i` holds a box (a leaf or an inner node) rather than nothing.
    fn slot_used(&self, i: usize) -> bool {
        self.bounds[0][0][i / 4][i % 4] <= self.bounds[1][0][i / 4][i % 4]
    }
}

/// Collapses the binary tree into 8-wide nodes by the dynamic programme of Ylitie, Karras and Laine 2017
/// ("Efficient incoherent ray traversal on GPUs through compressed wide BVHs", HPG, §3.1): for every binary node
/// and every budget of one to eight slots it finds the cheapest way to represent the node's subtree in that
/// many slots of its parent wide node ([`Collapse::plan`]), then fills the wide nodes top down from those
/// choices. The binary tree's splits are kept; which of its nodes become wide nodes, slots or leaves is chosen
/// by cost. `block` primitives are tested at a time (the SAH's `block`).
fn collapse(binary: &[Node], block: u32) -> Vec<Node8> {
    let plan = Collapse::plan(binary, block);
    let mut wide = vec![Node8::EMPTY];
    if plan.choice[0][WIDTH - 1] == Choice::LEAF {
        wide[0].set_slot(0, &binary[0], plan.first[0], plan.count[0]);
    } else {
        plan.fill(binary, 0, &mut wide, 0);
    }
    // The nodes were pushed one at a time: drop the spare capacity the vector grew by (about a tenth of the
    // hierarchy on a large mesh), held otherwise for the render's whole life.
    wide.shrink_to_fit();
    wide
}

/// How the subtree of a binary node is represented in `i` slots of its parent wide node: as one leaf slot,
/// as one slot holding a wide node of its own, or split between its two children, the left one getting `k`
/// slots (`Choice(k)`, `1 <= k < i`) and the right one the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Choice(u8);

impl Choice {
    /// One leaf slot holding every primitive of the subtree.
    const LEAF: Choice = Choice(0);
    /// One slot holding a wide node filled from the subtree.
    const INNER: Choice = Choice(WIDTH as u8);
}

/// The dynamic programme's table (Ylitie et al. 2017, §3.1): for binary node `n` and `i + 1` slots, the
/// least SAH cost `cost[n][i]` of its subtree (areas times the tests a ray entering it makes: `COST_NODE` per
/// wide node, one per block of a leaf) and the choice `choice[n][i]` that reaches it; with each node's run of
/// primitives in leaf order (`first`, `count`), which a leaf slot made of a whole subtree holds.
struct Collapse {
    cost: Vec<[f32; WIDTH]>,
    choice: Vec<[Choice; WIDTH]>,
    /// For an inner binary node, how many of a wide node's eight slots the best split gives its left child.
    split: Vec<u8>,
    first: Vec<u32>,
    count: Vec<u32>,
}

impl Collapse {
    /// Fills the table bottom up (a binary node's children follow it in `binary`). With `C(n, i)` the cost of
    /// `n` in at most `i` slots (Ylitie et al. 2017, eqs. 1-3):
    /// `C(n, 1) = min(C_leaf(n), C_node(n))`, `C(n, i) = min(C(n, i - 1), min_k C(l, k) + C(r, i - k))`,
    /// `C_node(n) = A(n)·COST_NODE + min_k C(l, k) + C(r, 8 - k)`, `C_leaf(n) = A(n)·⌈count / block⌉` for a
    /// subtree of at most `WIDE_MAX_LEAF` primitives (a binary leaf is always a leaf).
    fn plan(binary: &[Node], block: u32) -> Collapse {
        let n = binary.len();
        let mut table = Collapse {
            cost: vec![[0.0; WIDTH]; n],
            choice: vec![[Choice::LEAF; WIDTH]; n],
            split: vec![0; n],
            first: vec![0; n],
            count: vec![0; n],
        };
        let leaf_cost = |count: u32| count.div_ceil(block) as f32;
        for b in (0..n).rev() {
            let node = &binary[b];
            let a = area(node);
            if node.count > 0 {
                table.first[b] = node.offset;
                table.count[b] = node.count;
                table.cost[b] = [a * leaf_cost(node.count); WIDTH];
                continue;
            }
            let (l, r) = (node.offset as usize, node.offset as usize + 1);
            table.first[b] = table.first[l];
            table.count[b] = table.count[l] + table.count[r];
            // Best split of i + 1 slots between the children, for i = 1..8 (two slots or more). The first
            // split stands unless another is cheaper, so an infinite or NaN cost (a box whose area overflows)
            // still gives a valid choice.
            let mut split = [(f32::INFINITY, Choice::LEAF); WIDTH];
            for (i, best) in split.iter_mut().enumerate().skip(1) {
                *best = (table.cost[l][0] + table.cost[r][i - 1], Choice(1));
                for k in 2..=i {
                    let c = table.cost[l][k - 1] + table.cost[r][i - k];
                    if c < best.0 {
                        *best = (c, Choice(k as u8));
                    }
                }
            }
            let as_leaf = a * leaf_cost(table.count[b]);
            let as_node = a * COST_NODE + split[WIDTH - 1].0;
            table.split[b] = split[WIDTH - 1].1 .0;
            let mut best = if table.count[b] as usize <= WIDE_MAX_LEAF && as_leaf <= as_node {
                (as_leaf, Choice::LEAF)
            } else {
                (as_node, Choice::INNER)
            };
            for (i, &option) in split.iter().enumerate() {
                if option.0 < best.0 {
                    best = option;
                }
                table.cost[b][i] = best.0;
                table.choice[b][i] = best.1;
            }
        }
        table
    }

    /// Appends to `slots` the binary nodes that fill at most `i + 1` slots for binary node `b`, as chosen, each
    /// with whether it is a leaf slot.
    fn slots(&self, binary: &[Node], b: usize, i: usize, slots: &mut Vec<(usize, bool)>) {
        match self.choice[b][i] {
            Choice::LEAF => slots.push((b, true)),
            Choice::INNER => slots.push((b, false)),
            Choice(k) => {
                let (l, k) = (binary[b].offset as usize, k as usize);
                self.slots(binary, l, k - 1, slots);
                self.slots(binary, l + 1, i - k, slots);
            }
        }
    }

    /// Fills wide node `at` from the binary node `b` chosen as a wide node, then its inner children, depth
    /// first.
    fn fill(&self, binary: &[Node], b: usize, wide: &mut Vec<Node8>, at: usize) {
        let (l, k) = (binary[b].offset as usize, self.split[b] as usize);
        let mut slots = Vec::with_capacity(WIDTH);
        self.slots(binary, l, k - 1, &mut slots);
        self.slots(binary, l + 1, WIDTH - 1 - k, &mut slots);
        // Children of one wide node are stored next to each other.
        let mut node = Node8::EMPTY;
        let mut inner = Vec::new();
        for (i, &(s, leaf)) in slots.iter().enumerate() {
            if leaf {
                node.set_slot(i, &binary[s], self.first[s], self.count[s]);
            } else {
                node.set_slot(i, &binary[s], wide.len() as u32, 0);
                inner.push((s, wide.len()));
                wide.push(Node8::EMPTY);
            }
        }
        let ids: Vec<usize> = slots.iter().map(|&(s, _)| s).collect();
        for octant in 0..8 {
            node.set_order(octant, octant_order(binary, b, &ids, octant));
        }
        wide[at] = node;
        for (s, w) in inner {
            self.fill(binary, s, wide, w);
        }
    }
}

/// The most stack entries a traversal of `wide` from node `at` can hold: a node's hit children are all
/// pushed but the first in visiting order, which is descended into while the others wait (counted here as
/// all pushed, then one popped).
fn stack_needed(wide: &[Node8], at: usize) -> usize {
    let node = &wide[at];
    let slots = (0..WIDTH).filter(|&i| node.slot_used(i)).count();
    (0..WIDTH)
        .filter(|&i| node.count(i) == 0 && node.slot_used(i))
        .map(|i| slots - 1 + stack_needed(wide, node.child[i] as usize))
        .max()
        .unwrap_or(slots)
}

fn area(node: &Node) -> f32 {
    Aabb::new(Vec3::from_array(node.min), Vec3::from_array(node.max)).surface_area()
}

/// The order in which a ray whose direction lies in `octant` (bit `a` set: negative along axis `a`) should
/// visit the slots of the wide node filled from binary node `b`, `slots` being the binary nodes placed in
/// them, encoded as [`Node8::order`]. Each binary split inside the wide node is ordered by the sign of the
/// direction along the axis on which its two children's centres lie farthest apart, the child whose centre is
/// lower on that axis first for a positive direction: front to back without any distance. Unused slots come
/// last.
fn octant_order(binary: &[Node], b: usize, slots: &[usize], octant: usize) -> u32 {
    let mut seq = Vec::with_capacity(WIDTH);
    push_in_octant_order(binary, b, slots, octant, &mut seq);
    seq.extend((0..WIDTH).filter(|i| !seq.contains(i)).collect::<Vec<_>>());
    seq.iter()
        .enumerate()
        .fold(0, |code, (k, &slot)| code | (slot as u32) << (3 * k))
}

/// Appends to `seq` the slots under binary node `s` (itself a slot, or split inside the wide node) in the
/// order of [`octant_order`].
fn push_in_octant_order(
    binary: &[Node],
    s: usize,
    slots: &[usize],
    octant: usize,
    seq: &mut Vec<usize>,
) {
    if let Some(slot) = slots.iter().position(|&x| x == s) {
        seq.push(slot);
        return;
    }
    let (left, right) = (binary[s].offset as usize, binary[s].offset as usize + 1);
    let centre = |n: &Node| Vec3::from_array(n.min) + Vec3::from_array(n.max);
    let gap = centre(&binary[right]) - centre(&binary[left]);
    let axis = gap.abs().max_position();
    let positive = octant >> axis & 1 == 0;
    let (first, second) = if (gap[axis] >= 0.0) == positive {
        (left, right)
    } else {
        (right, left)
    };
    push_in_octant_order(binary, first, slots, octant, seq);
    push_in_octant_order(binary, second, slots, octant, seq);
}

/// Per-ray constants for traversal, splatted across the four SIMD lanes.
struct TraversalRay {
    origin: [Vec4; 3],
    inv_dir: [Vec4; 3],
    /// Per axis, whether the direction is negative (sign bit set, so `-0.0` counts), which swaps the near
    /// and far planes (Williams et al. 2005).
    neg: [bool; 3],
    /// The direction's octant, bit `a` set when `neg[a]`: the index into [`Node8::order`].
    octant: usize,
}

impl TraversalRay {
    /// The splatted origin and inverse direction, and the direction's signs. Written out axis by axis: an
    /// array `map` over the axes is a call per array in release builds, which a ray through a mesh of a few
    /// triangles pays as much as for its whole traversal.
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let (o, d) = (ray.origin, ray.dir);
        let inv = d.recip();
        let (neg, octant) = direction_signs(d);
        Self {
            origin: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            inv_dir: [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
            neg,
            octant,
        }
    }

    /// Slab test of the eight child boxes of `node` (Williams et al. 2005, Ize 2013), as two tests of four
    /// ([`TraversalRay::slab4`]): a bit mask of the children the ray meets within `[t_min, t_clip]`, and their
    /// entry distances.
    #[inline(always)]
    fn slab8(&self, node: &Node8, t_min: f32, t_clip: f32) -> (u32, [f32; WIDTH]) {
        let (low_mask, low_near) = self.slab4(node, 0, t_min, t_clip);
        let (high_mask, high_near) = self.slab4(node, 1, t_min, t_clip);
        let mut near = [0.0; WIDTH];
        low_near.write_to_slice(&mut near[..4]);
        high_near.write_to_slice(&mut near[4..]);
        (low_mask | high_mask << 4, near)
    }

    /// Slab test of boxes `4h .. 4h + 4` of `node`: a bit mask of those the ray meets within `[t_min,
    /// t_clip]`, and their entry distances. The near plane of each axis is `bounds[neg]` and the far one
    /// `bounds[!neg]`, picked by indexing rather than a branch. A ray lying in a slab's plane with a zero
    /// direction component gives `0·∞ = NaN` for that plane, which [`greater_or_second`] and
    /// [`less_or_second`] ignore (a comparison with NaN is false): the slab then constrains nothing, so
    /// boundary hits are kept.
    #[inline(always)]
    fn slab4(&self, node: &Node8, h: usize, t_min: f32, t_clip: f32) -> (u32, Vec4) {
        let mut near = Vec4::splat(t_min);
        let mut far = Vec4::INFINITY;
        for a in 0..3 {
            let lo = node.bounds[usize::from(self.neg[a])][a][h];
            let hi = node.bounds[usize::from(!self.neg[a])][a][h];
            let tn = (lo - self.origin[a]) * self.inv_dir[a];
            let tf = (hi - self.origin[a]) * self.inv_dir[a];
            near = greater_or_second(tn, near);
            far = less_or_second(tf, far);
        }
        let far = (far * FAR_SCALE).min(Vec4::splat(t_clip));
        (near.cmple(far).bitmask(), near)
    }
}

/// Per axis whether `d` is negative (sign bit set, so `-0.0` counts), and the octant with bit `a` set for each
/// negative axis: what both box tests' per-ray constants ([`TraversalRay`] and the AVX2 copy's) take from the
/// direction.
#[inline(always)]
fn direction_signs(d: Vec3) -> ([bool; 3], usize) {
    let neg = [
        d.x.is_sign_negative(),
        d.y.is_sign_negative(),
        d.z.is_sign_negative(),
    ];
    let octant = usize::from(neg[0]) | usize::from(neg[1]) << 1 | usize::from(neg[2]) << 2;
    (neg, octant)
}

/// Lane by lane `if a > b { a } else { b }`: `b` where `a` is NaN, and `b` where the two are equal (so
/// `-0.0` against `0.0` gives the second). On x86_64 this is exactly the definition of SSE's `maxps a, b`,
/// which glam's `Vec4::max` is there: one instruction instead of a compare and a three-instruction select.
#[inline(always)]
fn greater_or_second(a: Vec4, b: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    return a.max(b);
    #[cfg(not(target_arch = "x86_64"))]
    return Vec4::select(a.cmpgt(b), a, b);
}

/// Lane by lane `if a < b { a } else { b }`, as [`greater_or_second`] (SSE's `minps a, b` on x86_64).
#[inline(always)]
fn less_or_second(a: Vec4, b: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    return a.min(b);
    #[cfg(not(target_arch = "x86_64"))]
    return Vec4::select(a.cmplt(b), a, b);
}

/// The traversal compiled a second time with AVX2, picked at run time on CPUs that have it (the crate is built
/// for the x86-64 baseline, SSE2, so that its binaries run on any x86-64 machine). In this copy a wide node's
/// eight boxes are one 8-lane slab test ([`avx2::Ray8::slab8`]) instead of two 4-lane ones. Every lane does the
/// operations of [`TraversalRay::slab4`] in the same order (`vmaxps` and `vminps` are defined as `maxps` and
/// `minps`; FMA is not enabled, and Rust never contracts a multiply and an add), so the answers are bit for bit
/// those of the baseline copy (a unit test compares the two).
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{
        direction_signs, Leaves, Node8, Ray, Tree, TriangleHit, Vec4, FAR_SCALE, STACK_FIRST, WIDTH,
    };
    use std::arch::x86_64::{
        __m256, _mm256_castps256_ps128, _mm256_cmp_ps, _mm256_extractf128_ps, _mm256_max_ps,
        _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_set_m128,
        _mm256_sub_ps, _CMP_LE_OQ,
    };

    /// [`Tree::traverse_with`] with the 8-lane box test where this CPU has AVX2 (detected once by `std`, then a
    /// cached flag); `None` elsewhere.
    #[inline(always)]
    #[allow(unsafe_code)] // calls the AVX2 copy (see SAFETY below)
    pub(super) fn traverse<const ANY_HIT: bool>(
        tree: &Tree,
        ray: &Ray,
        t_range: [f32; 2],
        hooks: (&impl Leaves, &impl Fn()),
    ) -> Option<Option<TriangleHit>> {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return None;
        }
        // SAFETY: a `target_feature` function may only run on a CPU with those features, and this CPU has just
        // been found to have AVX2.
        Some(unsafe { traverse_avx2::<ANY_HIT>(tree, ray, t_range, hooks) })
    }

    /// The traversal, its leaf tests inlined, compiled with AVX2.
    #[target_feature(enable = "avx2")]
    fn traverse_avx2<const ANY_HIT: bool>(
        tree: &Tree,
        ray: &Ray,
        t_range: [f32; 2],
        hooks: (&impl Leaves, &impl Fn()),
    ) -> Option<TriangleHit> {
        let r = Ray8::new(ray);
        tree.traverse_with::<ANY_HIT, STACK_FIRST>(
            ray,
            t_range,
            hooks,
            r.octant,
            &|node, t0, t1| r.slab8(node, t0, t1),
        )
    }

    /// Per-ray constants of the 8-lane slab test, splatted across the eight lanes (as
    /// [`super::TraversalRay`]).
    struct Ray8 {
        origin: [__m256; 3],
        inv_dir: [__m256; 3],
        neg: [bool; 3],
        octant: usize,
    }

    impl Ray8 {
        #[target_feature(enable = "avx2")]
        #[inline]
        fn new(ray: &Ray) -> Self {
            let (o, d) = (ray.origin, ray.dir);
            let inv = d.recip();
            let (neg, octant) = direction_signs(d);
            Self {
                origin: [
                    _mm256_set1_ps(o.x),
                    _mm256_set1_ps(o.y),
                    _mm256_set1_ps(o.z),
                ],
                inv_dir: [
                    _mm256_set1_ps(inv.x),
                    _mm256_set1_ps(inv.y),
                    _mm256_set1_ps(inv.z),
                ],
                neg,
                octant,
            }
        }

        /// [`super::TraversalRay::slab8`] as one test of eight lanes.
        #[target_feature(enable = "avx2")]
        #[inline]
        fn slab8(&self, node: &Node8, t_min: f32, t_clip: f32) -> (u32, [f32; WIDTH]) {
            let lanes = |v: &[Vec4; 2]| _mm256_set_m128(v[1].into(), v[0].into());
            let mut near = _mm256_set1_ps(t_min);
            let mut far = _mm256_set1_ps(f32::INFINITY);
            for a in 0..3 {
                let lo = lanes(&node.bounds[usize::from(self.neg[a])][a]);
                let hi = lanes(&node.bounds[usize::from(!self.neg[a])][a]);
                let tn = _mm256_mul_ps(_mm256_sub_ps(lo, self.origin[a]), self.inv_dir[a]);
                let tf = _mm256_mul_ps(_mm256_sub_ps(hi, self.origin[a]), self.inv_dir[a]);
                near = _mm256_max_ps(tn, near);
                far = _mm256_min_ps(tf, far);
            }
            let far = _mm256_min_ps(
                _mm256_mul_ps(far, _mm256_set1_ps(FAR_SCALE)),
                _mm256_set1_ps(t_clip),
            );
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            let mut out = [0.0; WIDTH];
            Vec4::from(_mm256_castps256_ps128(near)).write_to_slice(&mut out[..4]);
            Vec4::from(_mm256_extractf128_ps::<1>(near)).write_to_slice(&mut out[4..]);
            (mask, out)
        }
    }
}

/// A hint to bring the cache line at `p` into the cache; it never faults and has no other effect.
#[inline(always)]
#[allow(unsafe_code)] // a prefetch (see SAFETY below)
pub(super) fn prefetch(p: *const i8) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: SSE is part of the x86_64 baseline, and a prefetch is a hint that never faults, whatever
        // the address, and never changes memory.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(p) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// The distance up to which boxes must still be visited when the best hit so far is at `t`: widened like a
/// box's far distance, so a triangle hit within rounding of `t` (which may win the index tie-break) is seen.
fn clip_of(t: f32) -> f32 {
    t + t.abs() * (FAR_SCALE - 1.0)
}

/// The traversal stack: `entries[..len]` hold child slots (`node·8 + slot`) still to visit and their entry
/// distances, the next to visit last.
struct Stack<const N: usize> {
    entries: [(u32, f32); N],
    len: usize,
}

impl<const N: usize> Stack<N> {
    /// Removes and returns the top entry.
    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        self.len = self.len.checked_sub(1)?;
        self.entries.get(self.len).copied()
    }
}

/// What [`Tree::push_children`] left to visit next.
enum Pushed {
    /// Slot `i` of the node, which was not pushed.
    Next(usize),
    /// No child was hit.
    Nothing,
    /// The stack was full.
    Overflow,
}

/// A triangle list too long for the hierarchy's 32-bit node and triangle indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0} triangles, more than the {max} a scene may hold", max = Bvh::MAX_TRIANGLES)]
pub struct TooManyTriangles(pub usize);

impl Bvh {
    /// The most triangles one hierarchy holds (its node and triangle indices are 32-bit, with flag bits).
    pub const MAX_TRIANGLES: usize = (1 << 30) - 1;

    /// Builds the hierarchy over world-space triangles with the parallel binned SAH, then collapses it to
    /// 8-wide nodes (see the module documentation). Triangles with a non-finite coordinate can never be hit
    /// and are left out; degenerate (zero-area) triangles are kept and never hit. An empty list gives an
    /// empty hierarchy. More than [`Bvh::MAX_TRIANGLES`] triangles is an error.
    pub fn build(triangles: &[[Vec3; 3]]) -> Result<Bvh, TooManyTriangles> {
        let refs = triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| t.iter().all(|v| v.is_finite()))
            .map(|(i, t)| {
                PrimRef::new(
                    Aabb::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])),
                    i as u32,
                )
            })
            .collect();
        let mut tree = Tree::build(refs, triangles.len(), PACK as u32)?;
        let packs = tree.pack_leaves(triangles);
        Ok(Bvh { tree, packs })
    }

    /// Bounds of all (finite) triangles; [`Aabb::EMPTY`] for an empty hierarchy.
    pub fn bounds(&self) -> Aabb {
        self.tree.bounds
    }

    /// Heap and inline bytes held: nodes, reordered triangles and their input indices.
    #[cfg(any(test, feature = "testing"))]
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.tree.heap_bytes()
            + self.packs.capacity() * std::mem::size_of::<Triangle4>()
    }

    /// Number of triangles given to [`Bvh::build`], including any left out as non-finite.
    pub fn triangle_count(&self) -> usize {
        self.tree.input_count
    }
}

/// The queries a triangle hierarchy answers, over one traversal ([`TriangleHierarchy::query`]) that each
/// hierarchy supplies with its own leaves: [`Bvh`] (still triangles) and
/// [`MotionBvh`](crate::geometry::MotionBvh) (triangles met where they are at the ray's time). Hits count from
/// either side of a triangle. Among hits at exactly the same distance the triangle with the lowest input index
/// is returned, so a closest hit equals testing every triangle in input order.
pub trait TriangleHierarchy {
    /// The traversal: with `ANY_HIT`, the first hit found that `accept` keeps; otherwise the closest such hit,
    /// with `t_min <= t <= t_max`.
    fn query<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> Option<TriangleHit>;

    /// The closest hit with `t_min <= t <= t_max`.
    #[inline(always)]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        self.query::<false>(ray, t_min, t_max, &|_| true)
    }

    /// Whether any triangle is hit with `t_min <= t <= t_max` (shadow rays); stops at the first hit found.
    #[inline(always)]
    fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.query::<true>(ray, t_min, t_max, &|_| true).is_some()
    }

    /// As [`Self::intersect`], counting only the hits that `accept` keeps: a rejected hit (an alpha cut-out)
    /// is passed through as if the triangle were not there.
    #[inline(always)]
    fn intersect_where(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> Option<TriangleHit> {
        self.query::<false>(ray, t_min, t_max, accept)
    }

    /// As [`Self::occluded`], counting only the hits that `accept` keeps.
    #[inline(always)]
    fn occluded_where(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> bool {
        self.query::<true>(ray, t_min, t_max, accept).is_some()
    }
}

impl TriangleHierarchy for Bvh {
    /// The tree's traversal with this hierarchy's leaves: runs of triangle packs, each tested four triangles
    /// at a time, their hits offered in leaf order.
    #[inline(always)]
    fn query<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> Option<TriangleHit> {
        self.query_counted::<ANY_HIT>(ray, [t_min, t_max], accept, &|| {}, &|_| {})
    }
}

/// How much work one query did: the wide nodes whose eight boxes it tested and the triangles it tested.
#[cfg(feature = "testing")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalCounts {
    /// Wide nodes visited (one 8-box slab test each).
    pub nodes: u64,
    /// Triangles tested (the valid lanes of the packs tested).
    pub triangles: u64,
}

impl Bvh {
    /// The closest hit (or with `ANY_HIT` whether any), and how many nodes and triangles the query tested,
    /// for the statistics of `benches/bvh.rs`.
    #[cfg(feature = "testing")]
    pub fn traversal_counts<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> (Option<TriangleHit>, TraversalCounts) {
        let (nodes, triangles) = (std::cell::Cell::new(0), std::cell::Cell::new(0));
        let hit = self.query_counted::<ANY_HIT>(
            ray,
            [t_min, t_max],
            &|_| true,
            &|| nodes.set(nodes.get() + 1),
            &|n| triangles.set(triangles.get() + n as u64),
        );
        let counts = TraversalCounts {
            nodes: nodes.get(),
            triangles: triangles.get(),
        };
        (hit, counts)
    }

    /// The query of [`TriangleHierarchy::query`], calling `node_visited()` for each wide node tested and
    /// `tested(n)` for each `n` triangles tested (no-ops outside the statistics).
    #[inline(always)]
    fn query_counted<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_range: [f32; 2],
        accept: &impl Fn(&TriangleHit) -> bool,
        node_visited: &impl Fn(),
        tested: &impl Fn(usize),
    ) -> Option<TriangleHit> {
        let leaves = PackLeaves::<'_, _, _, ANY_HIT> {
            packs: &self.packs,
            t_min: t_range[0],
            accept,
            tested,
        };
        self.tree
            .query_counted::<ANY_HIT>(ray, t_range, &leaves, node_visited)
    }
}

/// The leaves of a [`Bvh`] for one query: runs of triangle packs, each tested four triangles at a time,
/// their hits offered in leaf order to the query's [`Closest`] (with `ANY_HIT`, until one is kept).
struct PackLeaves<'a, A, T, const ANY_HIT: bool> {
    packs: &'a [Triangle4],
    t_min: f32,
    /// Which hits count (alpha cut-outs).
    accept: &'a A,
    /// Called with the number of triangles of each leaf tested (the statistics).
    tested: &'a T,
}

impl<A, T, const ANY_HIT: bool> Leaves for PackLeaves<'_, A, T, ANY_HIT>
where
    A: Fn(&TriangleHit) -> bool,
    T: Fn(usize),
{
    #[inline(always)]
    fn intersect(
        &self,
        first: usize,
        count: usize,
        ray: &WatertightRay,
        best: &mut Closest,
    ) -> bool {
        (self.tested)(count);
        let packs = self
            .packs
            .get(first..first + count.div_ceil(PACK))
            .unwrap_or_default();
        for (p, pack) in packs.iter().enumerate() {
            let valid = (1u32 << (count - p * PACK).min(PACK)) - 1;
            let hits = pack.intersect(ray, valid, self.t_min, best.limit());
            let mut m = hits.mask;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                let hit = TriangleHit {
                    t: hits.t[i],
                    prim: pack.ids[i],
                    b1: hits.b1[i],
                    b2: hits.b2[i],
                };
                if best.offer::<ANY_HIT>(hit, self.accept) {
                    return true;
                }
            }
        }
        false
    }

    #[inline(always)]
    fn prefetch(&self, first: usize) {
        if let Some(pack) = self.packs.get(first) {
            let p = pack as *const Triangle4 as *const i8;
            prefetch(p);
            prefetch(p.wrapping_add(64));
        }
    }
}

/// The leaves of a [`Tree`] as its traversal sees them.
pub(super) trait Leaves {
    /// Intersects the leaf of `count` primitives at `first` (an index into the leaf order, or whatever the
    /// hierarchy made it), offers each hit to `best` ([`Closest::offer`]) and returns whether `offer` ended
    /// the query.
    fn intersect(
        &self,
        first: usize,
        count: usize,
        ray: &WatertightRay,
        best: &mut Closest,
    ) -> bool;

    /// Starts loading the leaf at `first`.
    fn prefetch(&self, first: usize);
}

/// Leaves given as two closures: `.0` intersects (as [`Leaves::intersect`]), `.1` prefetches.
struct LeafFns<'a, L, P>(&'a L, &'a P);

impl<L, P> Leaves for LeafFns<'_, L, P>
where
    L: Fn(usize, usize, &WatertightRay, &mut Closest) -> bool,
    P: Fn(usize),
{
    #[inline(always)]
    fn intersect(
        &self,
        first: usize,
        count: usize,
        ray: &WatertightRay,
        best: &mut Closest,
    ) -> bool {
        (self.0)(first, count, ray, best)
    }

    #[inline(always)]
    fn prefetch(&self, first: usize) {
        (self.1)(first)
    }
}

/// The best hit a query has accepted so far and the distances that bound the rest of its search; leaves
/// offer their hits to it in leaf order with [`Closest::offer`].
pub(super) struct Closest {
    best: Option<TriangleHit>,
    /// The largest distance a hit may still have: `t_max`, then the best hit's.
    best_t: f32,
    /// Boxes entered beyond this distance are skipped: `best_t` widened by [`clip_of`].
    clip: f32,
}

impl Closest {
    fn new(t_max: f32) -> Self {
        Self {
            best: None,
            best_t: t_max,
            clip: clip_of(t_max),
        }
    }

    /// The largest distance at which a leaf's hit can still be kept.
    #[inline(always)]
    pub(super) fn limit(&self) -> f32 {
        self.best_t
    }

    /// Offers a hit: it is kept when `accept` keeps it and it is closer than the best so far, or as close with
    /// a lower input index (so equally close hits resolve as in a test of every triangle in input order).
    /// Returns whether the query is over, which with `ANY_HIT` is as soon as a hit is kept.
    #[inline(always)]
    pub(super) fn offer<const ANY_HIT: bool>(
        &mut self,
        hit: TriangleHit,
        accept: &impl Fn(&TriangleHit) -> bool,
    ) -> bool {
        let t = hit.t;
        let better =
            t < self.best_t || (t == self.best_t && self.best.is_none_or(|b| hit.prim < b.prim));
        if better && accept(&hit) {
            self.best = Some(hit);
            if ANY_HIT {
                return true;
            }
            self.best_t = t;
            self.clip = clip_of(t);
        }
        false
    }
}

impl Tree {
    /// Builds the hierarchy over `refs`, the boxes of the primitives that can be hit among `input_count`
    /// (see [`Bvh::build`]). A leaf's primitives are tested `block` at a time, which the SAH costs count in.
    pub(super) fn build(
        mut refs: Vec<PrimRef>,
        input_count: usize,
        block: u32,
    ) -> Result<Tree, TooManyTriangles> {
        if input_count > Bvh::MAX_TRIANGLES {
            return Err(TooManyTriangles(input_count));
        }
        let (nodes, bounds): (Vec<Node8>, Aabb) = if refs.is_empty() {
            (Vec::new(), Aabb::EMPTY)
        } else {
            let (root, desc) = build_parallel(&mut refs, 0, 0, block);
            let mut binary = Vec::with_capacity(1 + desc.len());
            binary.push(root.shifted(1));
            binary.extend(desc.into_iter().map(|n| n.shifted(1)));
            let bounds = Aabb::new(Vec3::from_array(root.min), Vec3::from_array(root.max));
            (collapse(&binary, block), bounds)
        };
        // Stack entries name a slot as `node·8 + slot` in 32 bits. Only a hierarchy of close to
        // `MAX_TRIANGLES` one-triangle leaves could have more nodes than that allows.
        if nodes.len() > (u32::MAX as usize + 1) / WIDTH {
            return Err(TooManyTriangles(input_count));
        }
        // The object-median splits below SAH_MAX_DEPTH bound the depth, and so the stack, by construction.
        debug_assert!(nodes.is_empty() || stack_needed(&nodes, 0) + PUSH_SLACK <= STACK_MAX);
        Ok(Tree {
            nodes,
            bounds,
            prim_ids: refs.iter().map(|r| r.id).collect(),
            input_count,
        })
    }

    /// For each primitive in leaf order, its index in the input list.
    pub(super) fn prim_ids(&self) -> &[u32] {
        &self.prim_ids
    }

    /// Bounds of all primitives that can be hit.
    pub(super) fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Number of primitives given to the build.
    pub(super) fn input_count(&self) -> usize {
        self.input_count
    }

    /// Heap bytes held by the nodes and the input indices.
    #[cfg(any(test, feature = "testing"))]
    pub(super) fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node8>()
            + self.prim_ids.capacity() * std::mem::size_of::<u32>()
    }

    /// The closest (or with `ANY_HIT` the first found) hit with `t_min <= t <= t_max` that the leaves keep:
    /// `leaf(first, count, ray, best)` intersects the leaf of `count` primitives at `first` (an index into the
    /// leaf order, or whatever [`Tree::pack_leaves`] made it), offers each hit to `best` ([`Closest::offer`])
    /// and returns whether `offer` ended the query; `prefetch_leaf(first)` starts loading a leaf.
    #[inline(always)]
    pub(super) fn query<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        leaf: &impl Fn(usize, usize, &WatertightRay, &mut Closest) -> bool,
        prefetch_leaf: &impl Fn(usize),
    ) -> Option<TriangleHit> {
        self.query_counted::<ANY_HIT>(ray, [t_min, t_max], &LeafFns(leaf, prefetch_leaf), &|| {})
    }

    /// [`Tree::query`], calling `node_visited()` for each wide node whose boxes are tested (for the
    /// traversal statistics of the benches; a no-op costs nothing).
    #[inline(always)]
    fn query_counted<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        [t_min, t_max]: [f32; 2],
        leaves: &impl Leaves,
        node_visited: &impl Fn(),
    ) -> Option<TriangleHit> {
        // A non-finite origin or direction, or a NaN interval, meets nothing. Such a ray would make every
        // slab comparison NaN, which the slab test reads as "no constraint", so it would "hit" every slot.
        if self.nodes.is_empty()
            || !(ray.origin.is_finite() && ray.dir.is_finite())
            || t_min.is_nan()
            || t_max.is_nan()
        {
            return None;
        }
        let hooks = (leaves, node_visited);
        #[cfg(target_arch = "x86_64")]
        if let Some(hit) = avx2::traverse::<ANY_HIT>(self, ray, [t_min, t_max], hooks) {
            return hit;
        }
        self.traverse_baseline::<ANY_HIT>(ray, [t_min, t_max], hooks)
    }

    /// [`Tree::traverse_with`] with the build target's box test (two 4-lane tests, [`TraversalRay::slab8`]),
    /// whatever the CPU.
    #[inline(always)]
    fn traverse_baseline<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        t_range: [f32; 2],
        hooks: (&impl Leaves, &impl Fn()),
    ) -> Option<TriangleHit> {
        let r = TraversalRay::new(ray);
        self.traverse_with::<ANY_HIT, STACK_FIRST>(
            ray,
            t_range,
            hooks,
            r.octant,
            &|node, t0, t1| r.slab8(node, t0, t1),
        )
    }

    /// [`Tree::traverse`] with a `FIRST`-entry stack (`STACK_FIRST`), testing a node's eight boxes with `slab8`
    /// (as [`TraversalRay::slab8`], for a ray of direction octant `octant`), and for a ray that overflows it
    /// [`Tree::traverse_deep`], which starts over, so the answer is the same either way.
    #[inline(always)]
    fn traverse_with<const ANY_HIT: bool, const FIRST: usize>(
        &self,
        ray: &Ray,
        [t_min, t_max]: [f32; 2],
        hooks: (&impl Leaves, &impl Fn()),
        octant: usize,
        slab8: &impl Fn(&Node8, f32, f32) -> (u32, [f32; WIDTH]),
    ) -> Option<TriangleHit> {
        let box_test = (octant, slab8);
        // Rays seldom need more than a few stack entries, and each clears its stack: first with a small one,
        // then, only where that overflowed, again from the start with one that always suffices.
        match self.traverse::<ANY_HIT, FIRST>(ray, t_min, t_max, hooks, box_test) {
            Ok(hit) => hit,
            Err(_) => self.traverse_deep::<ANY_HIT>(ray, [t_min, t_max], hooks),
        }
    }

    /// [`Tree::traverse_baseline`] with `STACK_MAX` entries, for a ray that overflowed the first stack. Out of
    /// line: it seldom runs, and inlined at every call site beside the first traversal it made a render of a small
    /// mesh 3 % slower (docs/performance.md). Its answers are those of either box test.
    #[cold]
    #[inline(never)]
    fn traverse_deep<const ANY_HIT: bool>(
        &self,
        ray: &Ray,
        [t_min, t_max]: [f32; 2],
        hooks: (&impl Leaves, &impl Fn()),
    ) -> Option<TriangleHit> {
        let r = TraversalRay::new(ray);
        let box_test = (r.octant, &|node: &Node8, t0, t1| r.slab8(node, t0, t1));
        self.traverse::<ANY_HIT, STACK_MAX>(ray, t_min, t_max, hooks, box_test)
            .unwrap_or_else(|partial| partial)
    }

    /// Stack-based traversal of the 8-wide tree with a stack of `STACK` entries. Stack entries name a child
    /// slot (`node·8 + slot`) and its entry distance. Of a node's hit children the first in visiting order is
    /// visited next without going through the stack, the others are pushed so that they pop in that order, and
    /// an entry is dropped when popped if a closer hit has been found since. The visiting order is given by
    /// [`Tree::push_children`]. Hits that `accept` rejects are skipped. `Err` (with the best hit found so far)
    /// when the stack was too small for this ray; with `STACK_MAX` entries that cannot happen.
    #[inline(always)]
    fn traverse<const ANY_HIT: bool, const STACK: usize>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        (leaves, node_visited): (&impl Leaves, &impl Fn()),
        (octant, slab8): (usize, &impl Fn(&Node8, f32, f32) -> (u32, [f32; WIDTH])),
    ) -> Result<Option<TriangleHit>, Option<TriangleHit>> {
        // The triangle test's constants, computed at the first leaf: a ray that meets no leaf box (most of
        // them, in a scene of a few large triangles) never needs them.
        let mut tri: Option<WatertightRay> = None;
        let mut best = Closest::new(t_max);
        let mut stack = Stack {
            entries: [(0u32, 0.0f32); STACK],
            len: 0,
        };
        // What to visit: a wide node (count 0) or a leaf's `count` primitives at `child`.
        let (mut child, mut count) = (0usize, 0usize);
        loop {
            if count == 0 {
                node_visited();
                let node = &self.nodes[child];
                let (mask, near) = slab8(node, t_min, best.clip);
                match self.push_children::<STACK>(child, mask, &near, octant, &mut stack, leaves) {
                    Pushed::Next(i) => {
                        (child, count) = (node.child[i] as usize, node.count(i));
                        continue;
                    }
                    Pushed::Nothing => {}
                    // Never an overrun: the caller traces the ray again with a larger stack.
                    Pushed::Overflow => return Err(best.best),
                }
            } else {
                if leaves.intersect(
                    child,
                    count,
                    tri.get_or_insert_with(|| WatertightRay::new(ray)),
                    &mut best,
                ) {
                    return Ok(best.best);
                }
            }
            // Pop until an entry still within reach.
            loop {
                let Some((slot, t)) = stack.pop() else {
                    return Ok(best.best);
                };
                // An any-hit query's clip never moves, and every entry was pushed within it.
                if ANY_HIT || t <= best.clip {
                    let parent = &self.nodes[slot as usize / WIDTH];
                    let i = slot as usize % WIDTH;
                    (child, count) = (parent.child[i] as usize, parent.count(i));
                    break;
                }
            }
        }
    }

    /// Pushes the children of wide node `at` in `mask` (their entry distances in `near`) but the one to visit
    /// first, which it returns. The order is the node's precomputed order for the ray's octant
    /// ([`octant_order`]), front to back along the ray without comparing distances, for closest-hit and
    /// any-hit queries alike; the entry distances still let a popped entry be skipped.
    #[inline(always)]
    fn push_children<const N: usize>(
        &self,
        at: usize,
        mask: u32,
        near: &[f32; WIDTH],
        octant: usize,
        stack: &mut Stack<N>,
        leaves: &impl Leaves,
    ) -> Pushed {
        if mask == 0 {
            return Pushed::Nothing;
        }
        if mask & (mask - 1) == 0 {
            return Pushed::Next(mask.trailing_zeros() as usize);
        }
        let node = &self.nodes[at];
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            self.prefetch_slot(node, i, leaves);
        }
        // Every slot is written into the eight entries above the top, last in visiting order first, and the
        // write position advances past the hit ones only: no branch depends on which children were hit. The
        // first hit child in visiting order (written last) is not pushed but visited next.
        let order = node.order(octant & 7);
        let Some(window) = stack.entries.get_mut(stack.len..stack.len + WIDTH) else {
            return Pushed::Overflow;
        };
        let (mut written, mut first) = (0, 0);
        for k in (0..WIDTH).rev() {
            let i = (order >> (3 * k) & 7) as usize;
            // `written` is at most `k` here, below WIDTH: the mask only spares the bounds check.
            window[written % WIDTH] = ((at * WIDTH + i) as u32, near[i]);
            let hit = (mask >> i & 1) as usize;
            written += hit;
            first = if hit != 0 { i } else { first };
        }
        // At least two children were hit.
        stack.len += written - 1;
        Pushed::Next(first)
    }

    /// Packs the primitives of each leaf, in leaf order, into [`Triangle4`]s of `triangles` (indexed by input
    /// index), each leaf starting a pack, and points each leaf slot at its first pack. The input indices then
    /// live in the packs, so `prim_ids` is released.
    fn pack_leaves(&mut self, triangles: &[[Vec3; 3]]) -> Vec<Triangle4> {
        let mut leaves: Vec<(u32, usize, usize)> = (0..self.nodes.len())
            .flat_map(|n| (0..WIDTH).map(move |i| (n, i)))
            .filter(|&(n, i)| self.nodes[n].count(i) > 0)
            .map(|(n, i)| (self.nodes[n].child[i], n, i))
            .collect();
        leaves.sort_unstable();
        let mut packs = Vec::with_capacity(self.prim_ids.len().div_ceil(PACK) + leaves.len());
        for (first, n, i) in leaves {
            let first = first as usize;
            let ids = &self.prim_ids[first..first + self.nodes[n].count(i)];
            self.nodes[n].child[i] = packs.len() as u32;
            for chunk in ids.chunks(PACK) {
                let tris: Vec<[Vec3; 3]> = chunk.iter().map(|&id| triangles[id as usize]).collect();
                packs.push(Triangle4::new(&tris, chunk));
            }
        }
        self.prim_ids = Vec::new();
        // Reserved for the worst case (every leaf's last pack partly empty); keep only what is used.
        packs.shrink_to_fit();
        packs
    }

    /// Starts loading what visiting child `i` of `node` will read, so that the memory latency overlaps the
    /// work on its siblings: the child's node (four cache lines) or the leaf's first primitive.
    #[inline(always)]
    fn prefetch_slot(&self, node: &Node8, i: usize, leaves: &impl Leaves) {
        let child = node.child[i] as usize;
        if node.count(i) == 0 {
            let p = &self.nodes[child] as *const Node8 as *const i8;
            for line in 0..4 {
                prefetch(p.wrapping_add(64 * line));
            }
        } else {
            leaves.prefetch(child);
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::triangle::intersect_triangle;
    use super::*;
    use crate::math::sampling::uniform_sphere;
    use crate::math::Rng;

    /// Reference: every triangle in input order, keeping the first of equally close hits.
    fn brute_closest(tris: &[[Vec3; 3]], ray: &Ray, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        brute_closest_of(tris.iter().copied().map(Some), ray, t_min, t_max)
    }

    /// The closest hit among `tris` (`None`: a triangle left out) tested in order, keeping the first of equally
    /// close hits; `prim` is the position in `tris`.
    pub(in crate::geometry) fn brute_closest_of(
        tris: impl Iterator<Item = Option<[Vec3; 3]>>,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
    ) -> Option<TriangleHit> {
        let r = WatertightRay::new(ray);
        let mut best: Option<TriangleHit> = None;
        for (i, tri) in tris.enumerate() {
            let Some(tri) = tri else { continue };
            let limit = best.map_or(t_max, |b| b.t);
            if let Some((t, b1, b2)) = intersect_triangle(&r, &tri, t_min, limit) {
                if best.is_none_or(|b| t < b.t) {
                    best = Some(TriangleHit {
                        t,
                        prim: i as u32,
                        b1,
                        b2,
                    });
                }
            }
        }
        best
    }

    fn brute_occluded(tris: &[[Vec3; 3]], ray: &Ray, t_min: f32, t_max: f32) -> bool {
        let r = WatertightRay::new(ray);
        tris.iter()
            .any(|t| intersect_triangle(&r, t, t_min, t_max).is_some())
    }

    /// A closed UV sphere: every vertex position is computed once and shared by its triangles.
    fn sphere(center: Vec3, radius: f32, rings: usize, segments: usize) -> Vec<[Vec3; 3]> {
        let north = center + Vec3::Y * radius;
        let south = center - Vec3::Y * radius;
        let grid: Vec<Vec<Vec3>> = (1..rings)
            .map(|i| {
                let theta = std::f32::consts::PI * i as f32 / rings as f32;
                (0..segments)
                    .map(|j| {
                        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                        center
                            + radius
                                * Vec3::new(
                                    theta.sin() * phi.cos(),
                                    theta.cos(),
                                    theta.sin() * phi.sin(),
                                )
                    })
                    .collect()
            })
            .collect();
        let mut tris = Vec::new();
        for j in 0..segments {
            let k = (j + 1) % segments;
            tris.push([north, grid[0][j], grid[0][k]]);
            tris.push([south, grid[rings - 2][k], grid[rings - 2][j]]);
            for i in 0..rings - 2 {
                let (a, b) = (grid[i][j], grid[i][k]);
                let (c, d) = (grid[i + 1][j], grid[i + 1][k]);
                tris.push([a, c, b]);
                tris.push([b, c, d]);
            }
        }
        tris
    }

    pub(in crate::geometry) fn random_point(rng: &mut Rng, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32())
    }

    pub(in crate::geometry) fn soup(rng: &mut Rng, n: usize) -> Vec<[Vec3; 3]> {
        (0..n)
            .map(|i| {
                let c = random_point(rng, Vec3::splat(-10.0), Vec3::splat(10.0));
                let size = if i % 7 == 0 { 6.0 } else { 0.8 };
                let mut t = [0; 3].map(|_| c + size * uniform_sphere(rng.next_2d()));
                match i % 23 {
                    0 => t[2] = t[1],                       // repeated vertex
                    1 => t[2] = t[0] + (t[1] - t[0]) * 2.0, // collinear
                    2 => t = [c; 3],                        // a point
                    _ => {}
                }
                t
            })
            .collect()
    }

    /// A random ray, sometimes with zero or negative-zero direction components.
    pub(in crate::geometry) fn random_ray(rng: &mut Rng, lo: Vec3, hi: Vec3) -> Ray {
        let o = random_point(rng, lo, hi);
        let mut d = uniform_sphere(rng.next_2d());
        match rng.next_u32() % 8 {
            0 => {
                d = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z]
                    [rng.next_u32() as usize % 6]
            }
            1 => {
                let a = rng.next_u32() as usize % 3;
                d[a] = if rng.next_u32().is_multiple_of(2) {
                    0.0
                } else {
                    -0.0
                };
                d = d.normalize();
            }
            _ => {}
        }
        Ray::new(o, d)
    }

    pub(in crate::geometry) fn random_interval(rng: &mut Rng) -> (f32, f32) {
        match rng.next_u32() % 4 {
            0 => (0.0, f32::INFINITY),
            1 => (rng.next_f32() * 5.0, f32::INFINITY),
            2 => (0.0, rng.next_f32() * 10.0),
            _ => {
                let a = rng.next_f32() * 10.0;
                (a, a + rng.next_f32() * 5.0)
            }
        }
    }

    fn check_agreement(tris: &[[Vec3; 3]], rays: &[(Ray, f32, f32)]) {
        let bvh = Bvh::build(tris).unwrap();
        let mut hits = 0;
        for (k, (ray, t0, t1)) in rays.iter().enumerate() {
            let expect = brute_closest(tris, ray, *t0, *t1);
            let got = bvh.intersect(ray, *t0, *t1);
            assert_eq!(got, expect, "ray {k}: {ray:?} [{t0}, {t1}]");
            assert_eq!(
                bvh.occluded(ray, *t0, *t1),
                brute_occluded(tris, ray, *t0, *t1),
                "ray {k}: {ray:?} [{t0}, {t1}]"
            );
            hits += expect.is_some() as usize;
        }
        // The cases must not be trivial either way.
        assert!(hits > rays.len() / 10 && hits < rays.len(), "{hits}");
    }

    #[test]
    fn empty_hierarchy() {
        let bvh = Bvh::build(&[]).unwrap();
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(bvh.intersect(&ray, 0.0, f32::INFINITY).is_none());
        assert!(!bvh.occluded(&ray, 0.0, f32::INFINITY));
        assert!(bvh.bounds().is_empty());
        assert_eq!(bvh.triangle_count(), 0);
        assert!(bvh.memory_bytes() >= std::mem::size_of::<Bvh>());
    }

    #[test]
    fn hierarchy_holds_no_spare_capacity() {
        // The nodes are pushed one at a time while the tree is collapsed, and the packs reserved for the worst
        // case; memory past what the hierarchy uses is held for the render's whole life (6.8 MiB on the bench's
        // 1 M-triangle mesh).
        let mut rng = Rng::new(5, 6);
        let bvh = Bvh::build(&soup(&mut rng, 3000)).unwrap();
        assert_eq!(bvh.tree.nodes.capacity(), bvh.tree.nodes.len());
        assert_eq!(bvh.packs.capacity(), bvh.packs.len());
    }

    #[test]
    fn non_finite_rays_miss_without_panicking() {
        let mut rng = Rng::new(3, 4);
        let bvh = Bvh::build(&soup(&mut rng, 3000)).unwrap();
        let rays = [
            (
                Ray::new(Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 1.0)),
                0.0,
                f32::INFINITY,
            ),
            (Ray::new(Vec3::splat(f32::NAN), Vec3::X), 0.0, f32::INFINITY),
            (
                Ray::new(Vec3::new(f32::INFINITY, 0.0, 0.0), -Vec3::X),
                0.0,
                f32::INFINITY,
            ),
            (
                Ray::new(Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0)),
                0.0,
                f32::INFINITY,
            ),
            (Ray::new(Vec3::ZERO, Vec3::X), f32::NAN, f32::INFINITY),
            (Ray::new(Vec3::ZERO, Vec3::X), 0.0, f32::NAN),
        ];
        for (ray, t0, t1) in rays {
            assert!(
                bvh.intersect(&ray, t0, t1).is_none(),
                "{ray:?} [{t0}, {t1}]"
            );
            assert!(!bvh.occluded(&ray, t0, t1), "{ray:?} [{t0}, {t1}]");
        }
    }

    /// The leaves of `bvh` for a query run outside [`Bvh::query_counted`].
    fn pack_leaves<const ANY_HIT: bool>(
        bvh: &Bvh,
        t_min: f32,
    ) -> PackLeaves<'_, impl Fn(&TriangleHit) -> bool, impl Fn(usize), ANY_HIT> {
        PackLeaves {
            packs: &bvh.packs,
            t_min,
            accept: &|_: &TriangleHit| true,
            tested: &|_| {},
        }
    }

    #[test]
    fn rays_that_overflow_the_first_stack_match_brute_force() {
        // With a first stack of 12 entries (a push needs 8 free), many rays through a random soup overflow it and
        // are traced again with `STACK_MAX`; the answers must still be those of brute force.
        const FIRST: usize = 12;
        let mut rng = Rng::new(5, 6);
        let tris = soup(&mut rng, 2000);
        let bvh = Bvh::build(&tris).unwrap();
        let bits = |h: Option<TriangleHit>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits(), h.b2.to_bits()))
        };
        let (mut overflowed, mut hits) = (0, 0);
        for k in 0..1500 {
            let ray = random_ray(&mut rng, Vec3::splat(-14.0), Vec3::splat(14.0));
            let (t0, t1) = random_interval(&mut rng);
            let r = TraversalRay::new(&ray);
            let box_test = (r.octant, &|node: &Node8, a, b| r.slab8(node, a, b));
            let closest = (&pack_leaves::<false>(&bvh, t0), &|| {});
            let first = bvh
                .tree
                .traverse::<false, FIRST>(&ray, t0, t1, closest, box_test);
            overflowed += usize::from(first.is_err());
            let got = bvh.tree.traverse_with::<false, FIRST>(
                &ray,
                [t0, t1],
                closest,
                box_test.0,
                box_test.1,
            );
            let expect = brute_closest(&tris, &ray, t0, t1);
            assert_eq!(bits(got), bits(expect), "ray {k}: {ray:?} [{t0}, {t1}]");
            let any = (&pack_leaves::<true>(&bvh, t0), &|| {});
            let got =
                bvh.tree
                    .traverse_with::<true, FIRST>(&ray, [t0, t1], any, box_test.0, box_test.1);
            assert_eq!(
                got.is_some(),
                brute_occluded(&tris, &ray, t0, t1),
                "ray {k}: {ray:?} [{t0}, {t1}]"
            );
            hits += usize::from(expect.is_some());
        }
        assert!(
            overflowed > 100 && hits > 150,
            "{overflowed} rays overflowed, {hits} hit"
        );
    }

    #[test]
    fn dispatched_traversal_matches_the_baseline_bit_for_bit() {
        // On a CPU with AVX2 the queries run the AVX2 copy of the traversal (an 8-lane box test); the baseline
        // copy must give the very same bits and occlusion answers. Elsewhere both are one copy.
        let mut rng = Rng::new(41, 42);
        let mut tris = soup(&mut rng, 3000);
        tris.extend(bumpy_sphere(24, 48, &mut rng));
        let bvh = Bvh::build(&tris).unwrap();
        let bits = |h: Option<TriangleHit>| {
            h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits(), h.b2.to_bits()))
        };
        let mut hits = [0; 2];
        for k in 0..4000 {
            let ray = random_ray(&mut rng, Vec3::splat(-12.0), Vec3::splat(12.0));
            let (t0, t1) = random_interval(&mut rng);
            let hooks = (&pack_leaves::<false>(&bvh, t0), &|| {});
            let base = bvh.tree.traverse_baseline::<false>(&ray, [t0, t1], hooks);
            assert_eq!(
                bits(bvh.intersect(&ray, t0, t1)),
                bits(base),
                "ray {k}: {ray:?} [{t0}, {t1}]"
            );
            let hooks = (&pack_leaves::<true>(&bvh, t0), &|| {});
            let base_any = bvh.tree.traverse_baseline::<true>(&ray, [t0, t1], hooks);
            assert_eq!(
                bvh.occluded(&ray, t0, t1),
                base_any.is_some(),
                "ray {k}: {ray:?} [{t0}, {t1}]"
            );
            hits[0] += usize::from(base.is_some());
            hits[1] += usize::from(base_any.is_some());
        }
        assert!(hits.iter().all(|&h| h > 400 && h < 3600), "{hits:?}");
    }

    #[test]
    fn nodes_are_32_bytes_per_child() {
        assert_eq!(std::mem::size_of::<Node>(), 32);
        assert_eq!(std::mem::size_of::<Node8>(), WIDTH * 32);
    }

    #[test]
    fn random_soup_matches_brute_force() {
        let mut rng = Rng::new(1, 2);
        let tris = soup(&mut rng, 3000);
        let rays: Vec<_> = (0..4000)
            .map(|_| {
                let ray = random_ray(&mut rng, Vec3::splat(-14.0), Vec3::splat(14.0));
                let (a, b) = random_interval(&mut rng);
                (ray, a, b)
            })
            .collect();
        check_agreement(&tris, &rays);
    }

    #[test]
    fn sphere_matches_brute_force_inside_and_outside() {
        let tris = sphere(Vec3::new(0.5, -0.25, 1.0), 2.0, 40, 80);
        let mut rng = Rng::new(3, 4);
        let rays: Vec<_> = (0..4000)
            .map(|i| {
                // Half from inside the sphere, half from anywhere around it.
                let half = if i % 2 == 0 { 1.0 } else { 4.0 };
                let c = Vec3::new(0.5, -0.25, 1.0);
                let ray = random_ray(&mut rng, c - half, c + half);
                let (a, b) = random_interval(&mut rng);
                (ray, a, b)
            })
            .collect();
        check_agreement(&tris, &rays);
    }

    #[test]
    fn rays_at_shared_edges_and_vertices_match_brute_force() {
        let tris = sphere(Vec3::ZERO, 1.0, 24, 48);
        let mut rng = Rng::new(5, 6);
        let rays: Vec<_> = (0..3000)
            .map(|i| {
                let tri = tris[i % tris.len()];
                let target = match i % 3 {
                    0 => tri[0],
                    1 => (tri[0] + tri[1]) * 0.5,
                    _ => tri[1],
                };
                let o = if i % 2 == 0 {
                    random_point(&mut rng, Vec3::splat(-0.5), Vec3::splat(0.5))
                } else {
                    3.0 * uniform_sphere(rng.next_2d())
                };
                (Ray::new(o, (target - o).normalize()), 0.0, f32::INFINITY)
            })
            .collect();
        check_agreement(&tris, &rays);
    }

    #[test]
    fn axis_rays_in_box_planes_match_brute_force() {
        // Origins share coordinates with mesh vertices, so axis-aligned rays lie exactly in the planes of
        // many node boxes (the `0·∞ = NaN` case of the slab test) and pass exactly through vertices.
        let tris = sphere(Vec3::new(0.25, 0.0, -0.5), 1.0, 16, 32);
        let mut rng = Rng::new(13, 14);
        let axes = [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::X, -Vec3::Y, -Vec3::Z];
        let rays: Vec<_> = (0..3000)
            .map(|i| {
                let v = tris[rng.next_u32() as usize % tris.len()][i % 3];
                let w = tris[rng.next_u32() as usize % tris.len()][(i + 1) % 3];
                let d = axes[i % 6];
                // The coordinates across the ray stay exactly those of `v` (or of `w` on one axis),
                // since `d` has exact zeros there; every fifth ray points away from the mesh.
                let mut o = v;
                if i % 2 == 0 {
                    o.x = w.x;
                }
                let o = o - d * 5.0;
                let d = if i % 5 == 0 { -d } else { d };
                (Ray::new(o, d), 0.0, f32::INFINITY)
            })
            .collect();
        check_agreement(&tris, &rays);
    }

    /// A sphere whose vertices are pushed in and out by a smooth bump field plus per-vertex noise (the
    /// benchmark's mesh, smaller), so neighbouring triangles are not coplanar.
    fn bumpy_sphere(rings: usize, segments: usize, rng: &mut Rng) -> Vec<[Vec3; 3]> {
        sphere(Vec3::ZERO, 1.0, rings, segments)
            .into_iter()
            .map(|tri| {
                tri.map(|v| {
                    let (theta, phi) = (v.y.clamp(-1.0, 1.0).acos(), v.z.atan2(v.x));
                    let bump = 0.08 * (7.0 * theta).sin() * (11.0 * phi).sin();
                    v * (1.0 + bump) + 0.004 * (random_point(rng, -Vec3::ONE, Vec3::ONE))
                })
            })
            .collect()
    }

    #[test]
    fn camera_rays_match_brute_force() {
        // Coherent rays from a pinhole camera, as primary rays are: neighbouring rays take nearly the same
        // path, many nodes have several children hit, and every ray is checked against testing every
        // triangle. The noise breaks shared vertices apart, so some rays slip through cracks.
        let mut rng = Rng::new(15, 16);
        let tris = bumpy_sphere(48, 96, &mut rng);
        let eye = Vec3::new(0.4, 0.6, 2.6);
        let forward = (-eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        let res = 56;
        let rays: Vec<_> = (0..res * res)
            .map(|p| {
                let (x, y) = ((p % res) as f32 + 0.5, (p / res) as f32 + 0.5);
                let (sx, sy) = (x / res as f32 - 0.5, 0.5 - y / res as f32);
                let ray = Ray::new(eye, (forward + sx * right + sy * up).normalize());
                (ray, 0.0, f32::INFINITY)
            })
            .collect();
        check_agreement(&tris, &rays);
    }

    #[test]
    fn slab_min_max_keep_the_second_operand_on_nan_and_ties() {
        // The slab test relies on these exact semantics (NaN planes ignored, ties kept), which the select
        // form states; check them against it lane by lane.
        let values = [
            f32::NAN,
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            3.5,
        ];
        for &x in &values {
            for &y in &values {
                let (a, b) = (Vec4::new(x, y, x, 1.0), Vec4::new(y, x, 2.0, x));
                let bits = |v: Vec4| v.to_array().map(f32::to_bits);
                let greater = Vec4::select(a.cmpgt(b), a, b);
                let less = Vec4::select(a.cmplt(b), a, b);
                assert_eq!(bits(greater_or_second(a, b)), bits(greater), "{x} {y}");
                assert_eq!(bits(less_or_second(a, b)), bits(less), "{x} {y}");
            }
        }
    }

    #[test]
    fn octant_orders_are_permutations_of_the_slots() {
        let mut rng = Rng::new(17, 18);
        let bvh = Bvh::build(&soup(&mut rng, 5000)).unwrap();
        for node in &bvh.tree.nodes {
            for octant in 0..8 {
                let code = node.order(octant);
                let mut seen = [false; WIDTH];
                for k in 0..WIDTH {
                    seen[(code >> (3 * k) & 7) as usize] = true;
                }
                assert_eq!(seen, [true; WIDTH], "{code:024b}");
            }
        }
    }

    #[test]
    fn wide_nodes_of_every_fill_match_brute_force_on_random_and_degenerate_meshes() {
        // Meshes from one triangle up: the root holds 1 to 8 slots, and larger trees have inner nodes with
        // every number of used slots, both halves of the slab test, and pushes of 2 to 8 hit children. Each
        // mesh also repeats some of its triangles (and holds zero-area ones), so equally close hits in different
        // slots and leaves must still resolve to the lowest input index.
        let mut rng = Rng::new(19, 20);
        let mut fills = [false; WIDTH + 1];
        for n in [1, 2, 3, 5, 8, 9, 16, 17, 40, 64, 65, 130, 700, 2500] {
            let mut tris = soup(&mut rng, n);
            for k in 0..n / 3 {
                tris.push(tris[(k * 7) % n]);
            }
            let bvh = Bvh::build(&tris).unwrap();
            for node in &bvh.tree.nodes {
                fills[(0..WIDTH).filter(|&i| node.slot_used(i)).count()] = true;
            }
            let rays: Vec<_> = (0..600)
                .map(|k| {
                    let ray = if k % 2 == 0 {
                        random_ray(&mut rng, Vec3::splat(-14.0), Vec3::splat(14.0))
                    } else {
                        // Aimed at a triangle's centroid, so most rays hit and many hit repeated triangles.
                        let tri = tris[rng.next_u32() as usize % tris.len()];
                        let o = random_point(&mut rng, Vec3::splat(-14.0), Vec3::splat(14.0));
                        let target = (tri[0] + tri[1] + tri[2]) / 3.0;
                        Ray::new(o, (target - o).normalize())
                    };
                    let (a, b) = random_interval(&mut rng);
                    (ray, a, b)
                })
                .collect();
            for (k, (ray, t0, t1)) in rays.iter().enumerate() {
                let expect = brute_closest(&tris, ray, *t0, *t1);
                assert_eq!(
                    bvh.intersect(ray, *t0, *t1),
                    expect,
                    "{n} triangles, ray {k}"
                );
                assert_eq!(
                    bvh.occluded(ray, *t0, *t1),
                    brute_occluded(&tris, ray, *t0, *t1),
                    "{n} triangles, ray {k}"
                );
            }
        }
        // Every fill from one slot (a root leaf) to eight occurred.
        assert_eq!(fills[1..], [true; WIDTH], "{fills:?}");
    }

    #[test]
    fn closed_mesh_is_watertight() {
        let tris = sphere(Vec3::new(0.1, 0.2, -0.3), 1.5, 64, 128);
        let bvh = Bvh::build(&tris).unwrap();
        let mut rng = Rng::new(7, 8);
        let mut misses = 0;
        let mut rays = 0;
        for tri in &tris {
            let targets = [
                tri[0],
                tri[1],
                tri[2],
                (tri[0] + tri[1]) * 0.5,
                (tri[1] + tri[2]) * 0.5,
            ];
            for target in targets {
                let o = Vec3::new(0.1, 0.2, -0.3)
                    + random_point(&mut rng, Vec3::splat(-0.7), Vec3::splat(0.7));
                let ray = Ray::new(o, (target - o).normalize());
                rays += 1;
                if bvh.intersect(&ray, 0.0, f32::INFINITY).is_none()
                    || !bvh.occluded(&ray, 0.0, f32::INFINITY)
                {
                    misses += 1;
                }
            }
        }
        assert_eq!(misses, 0, "{misses} of {rays} rays escaped the closed mesh");
    }

    #[test]
    fn hit_reports_input_index_and_barycentrics() {
        let mut rng = Rng::new(9, 10);
        let tris = soup(&mut rng, 500);
        let bvh = Bvh::build(&tris).unwrap();
        let mut checked = 0;
        for _ in 0..2000 {
            let ray = random_ray(&mut rng, Vec3::splat(-12.0), Vec3::splat(12.0));
            if let Some(h) = bvh.intersect(&ray, 0.0, f32::INFINITY) {
                let [v0, v1, v2] = tris[h.prim as usize];
                let p = (1.0 - h.b1 - h.b2) * v0 + h.b1 * v1 + h.b2 * v2;
                assert!((p - ray.at(h.t)).length() < 1e-3, "{p} vs {}", ray.at(h.t));
                checked += 1;
            }
        }
        assert!(checked > 100);
    }

    #[test]
    fn degenerate_inputs_build_and_miss() {
        // Many identical zero-area triangles: no SAH split exists, the median fallback must terminate.
        let point = [[Vec3::ONE; 3]; 1000];
        let bvh = Bvh::build(&point).unwrap();
        assert_eq!(bvh.triangle_count(), 1000);
        assert_eq!(bvh.bounds(), Aabb::new(Vec3::ONE, Vec3::ONE));
        let ray = Ray::new(Vec3::ZERO, Vec3::ONE.normalize());
        assert!(bvh.intersect(&ray, 0.0, f32::INFINITY).is_none());
        // Non-finite triangles are left out; the rest still work.
        let tris = [
            [Vec3::NAN, Vec3::X, Vec3::Y],
            [
                Vec3::new(-1.0, -1.0, 2.0),
                Vec3::new(3.0, -1.0, 2.0),
                Vec3::new(-1.0, 3.0, 2.0),
            ],
            [Vec3::INFINITY, Vec3::X, Vec3::Y],
        ];
        let bvh = Bvh::build(&tris).unwrap();
        let hit = bvh
            .intersect(&Ray::new(Vec3::ZERO, Vec3::Z), 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!((hit.prim, hit.t), (1, 2.0));
        assert_eq!(bvh.triangle_count(), 3);
    }

    #[test]
    fn huge_coordinates_whose_box_areas_overflow_match_brute_force() {
        // Boxes whose surface areas overflow to infinity (coordinates near 1e37), and flat ones spanning more
        // than `f32::MAX` along one axis, whose areas are NaN (an infinite extent times a zero one): the
        // collapse's costs are then infinite or NaN, and it must still build a tree that culls no hit.
        let mut rng = Rng::new(23, 24);
        let mut tris: Vec<[Vec3; 3]> = soup(&mut rng, 300)
            .into_iter()
            .map(|t| t.map(|v| v * 1e37))
            .collect();
        for k in 0..40 {
            let x = if k % 2 == 0 { 3e38 } else { -3e38 };
            let z = k as f32 * 1e36;
            tris.push([
                Vec3::new(x, 0.0, z),
                Vec3::new(0.0, 0.0, z + 1e36),
                Vec3::new(x * 0.5, 0.0, z + 2e36),
            ]);
        }
        let bvh = Bvh::build(&tris).unwrap();
        for k in 0..600 {
            let (lo, hi) = (Vec3::splat(-14e37), Vec3::splat(14e37));
            let ray = if k % 2 == 0 {
                random_ray(&mut rng, lo, hi)
            } else {
                let tri = tris[rng.next_u32() as usize % tris.len()];
                let o = random_point(&mut rng, lo, hi);
                let target = tri[0] / 3.0 + tri[1] / 3.0 + tri[2] / 3.0;
                Ray::new(o, (target - o).normalize())
            };
            assert_eq!(
                bvh.intersect(&ray, 0.0, f32::INFINITY),
                brute_closest(&tris, &ray, 0.0, f32::INFINITY),
                "ray {k}"
            );
            assert_eq!(
                bvh.occluded(&ray, 0.0, f32::INFINITY),
                brute_occluded(&tris, &ray, 0.0, f32::INFINITY),
                "ray {k}"
            );
        }
    }

    #[test]
    fn build_is_independent_of_thread_count() {
        let mut rng = Rng::new(11, 12);
        let tris = soup(&mut rng, 40_000);
        let build_with = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| Bvh::build(&tris).unwrap())
        };
        let (a, b) = (build_with(1), build_with(3));
        assert!(a.tree.nodes.len() > tris.len() / (WIDTH * MAX_LEAF));
        assert_eq!(a.tree.nodes, b.tree.nodes);
        assert_eq!(a.packs, b.packs);
    }
}
