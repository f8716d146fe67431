//! Majorants for tracking through heterogeneous media: piecewise-constant upper bounds σ̄ ≥ σ_t along a ray.
//!
//! Every structure lives in the field's local space (index space for grids) and hands out ray segments
//! `[t0, t1)` with a majorant `sigma_max` and a minorant `sigma_min` (used as a control by residual ratio
//! tracking). Segments of zero majorant are skipped: empty space costs nothing.
//!
//! Three kinds ([`MajorantKind`]):
//! - `Global`: one maximum over the whole field (the approach of Mitsuba 3);
//! - `Grid16`: a 16³ grid of maxima over the field's bounds, walked with a 3D DDA (Amanatides & Woo 1987,
//!   "A Fast Voxel Traversal Algorithm for Ray Tracing"), as pbrt-v4 does for grid media;
//! - `Adaptive`: a two-level hierarchy aligned with the VDB tree — 128³-voxel cells (the tree's lower nodes)
//!   refined into 16³ bricks of 8³-voxel cells (its leaves) only where the data varies, with a 4³ mid level of
//!   32³-voxel cells inside each brick to skip its empty or uniform quarters — walked with a
//!   hierarchical DDA in the spirit of the multi-level DDA over VDB trees of Hofmann and Evans 2021
//!   ("Efficient Unbiased Volume Path Tracing on the GPU", Ray Tracing Gems II). Empty 128³ cells are skipped in
//!   one DDA step; uniform ones keep no brick. Along the ray, neighbouring segments are merged when merging adds
//!   less than [`MERGE_TAU`] of majorant optical depth (the expected number of extra null collisions), which
//!   trades DDA segments against null collisions.
//!
//! Trackers pull the segments from a [`MajorantIterator`] ([`Majorants::segments`]), an external iterator that
//! keeps the DDA state between calls to `next()`, as pbrt-v4's `DDAMajorantIterator` does (Pharr, Jakob,
//! Humphreys, "Physically Based Rendering", 4th ed., §11.4.3 "Majorant grids"); here the state is one DDA per
//! level of the structure.
//!
//! Bounds are conservative for trilinear interpolation: a lookup at `x` reads voxels `floor(x)` and
//! `floor(x) + 1`, so a cell's bound covers every voxel its points can read, one voxel beyond the cell.

use super::dda::{Dda, UniformGrid};
#[cfg(test)]
use super::density::AnalyticDensity;
#[cfg(test)]
use super::density::DensityField;
use super::density::{nonzero_regions, GridDensity};
use crate::limits::{Limits, OverBudget};
use crate::math::{Aabb, Ray, Vec3};
use crate::vdb::{floor_ivec3, FloatTree, Leaf, LowerNode};
use glam::IVec3;

/// Resolution per axis of the [`MajorantKind::Grid16`] grid.
pub const GRID16_RES: i32 = 16;
/// Extra majorant optical depth below which [`MajorantKind::Adaptive`] merges neighbouring segments, measured
/// as σ̄ × ray parameter (an optical depth for rays whose world direction has unit length).
pub const MERGE_TAU: f32 = 0.25;
/// log2 of the coarse cell edge in voxels: a lower node of the VDB tree.
const COARSE_LOG2: i32 = LowerNode::<f32>::LOG2DIM;
/// log2 of the fine cell edge in voxels: a leaf of the VDB tree.
const FINE_LOG2: i32 = Leaf::<f32>::LOG2DIM;
/// Fine cells per brick edge.
const BRICK: i32 = 1 << (COARSE_LOG2 - FINE_LOG2);
const BRICK_CELLS: usize = (BRICK * BRICK * BRICK) as usize;
const NO_BRICK: u32 = u32::MAX;
/// Mid-level cells per brick edge.
const MID: i32 = 4;
const MID_CELLS: usize = (MID * MID * MID) as usize;
/// Fine cells per mid-level cell edge.
const FINE_PER_MID: i32 = BRICK / MID;

/// A 16³ brick of 8³-voxel cells under one 128³ cell, with a 4³ mid level of 32³-voxel cells that lets the DDA
/// skip empty or uniform quarters of the brick in one step. Entries are (min, max).
#[derive(Clone, Debug)]
struct Brick {
    mid: [(f32, f32); MID_CELLS],
    /// Bit per mid cell: walk it as one segment (its fine cells would save less than [`MERGE_TAU`]).
    flat: u64,
    fine: [(f32, f32); BRICK_CELLS],
}

/// Which majorant structure to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum MajorantKind {
    /// One global maximum.
    Global,
    /// A fixed 16³ grid of maxima with DDA traversal.
    Grid16,
    /// Nimbus's tree-aligned two-level hierarchy with hierarchical DDA and empty-space skipping.
    Adaptive,
}

impl MajorantKind {
    /// All kinds, in the order benchmarks report them.
    pub const ALL: [MajorantKind; 3] = [Self::Global, Self::Grid16, Self::Adaptive];

    /// The scene-file name of the kind (`"majorant"` key).
    pub fn name(self) -> &'static str {
        match self {
            Self::Global => "global",
            Self::Grid16 => "grid16",
            Self::Adaptive => "adaptive",
        }
    }
}

/// A ray interval `[t0, t1)` on which `sigma_min ≤ σ_t ≤ sigma_max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start parameter.
    pub t0: f32,
    /// End parameter.
    pub t1: f32,
    /// Majorant σ̄ (per metre).
    pub sigma_max: f32,
    /// Minorant (per metre), a valid control density for residual ratio tracking.
    pub sigma_min: f32,
}

impl Segment {
    /// True when the bounds meet (σ_min = σ̄ > 0): the density is constant on the segment, so trackers use the
    /// closed form there (the homogeneous-medium solution) instead of tentative collisions.
    #[inline]
    pub fn is_uniform(&self) -> bool {
        self.sigma_min >= self.sigma_max && self.sigma_max > 0.0
    }
}

/// The unit cells `[c, c + 1)³` of local space that a ray crosses over `[t0, t1]`, in order: the voxel cells
/// of a grid, each bounded by its eight voxels, for tracking that refines a thick majorant segment to voxels.
pub(crate) struct VoxelCells {
    ray: Ray,
    dda: Dda,
}

impl VoxelCells {
    /// The cells of the local-space `ray` over `[t0, t1]` (`t0 < t1`, a majorant segment's interval).
    pub(crate) fn new(ray: &Ray, t0: f32, t1: f32) -> Self {
        let (a, b) = (ray.at(t0), ray.at(t1));
        let origin = floor_ivec3(a.min(b)) - 1;
        let grid = UniformGrid {
            origin: origin.as_vec3(),
            cell: Vec3::ONE,
            res: floor_ivec3(a.max(b)) - origin + 2,
        };
        Self {
            ray: *ray,
            dda: Dda::inside(&grid, ray, ray.dir.recip(), t0, t1),
        }
    }

    /// The next cell and its parameter interval, adding each cell stepped through to `cells`. The cell is the
    /// one holding the interval's midpoint: where the segment's end was computed by another walk, the DDA's
    /// last interval can be a sliver of round-off past a face, whose DDA cell lies beyond the segment (and
    /// beyond what its majorant bounds) although its points do not.
    #[inline]
    pub(crate) fn next(&mut self, cells: &mut u64) -> Option<(IVec3, f32, f32)> {
        let (_, t0, t1) = self.dda.next(cells)?;
        Some((floor_ivec3(self.ray.at(0.5 * (t0 + t1))), t0, t1))
    }
}

/// The [`MajorantKind::Adaptive`] structure: coarse 128³ cells with optional bricks.
#[derive(Clone, Debug)]
struct Hierarchy {
    coarse: UniformGrid,
    /// Per coarse cell: (min, max, brick index or `NO_BRICK`).
    cells: Vec<(f32, f32, u32)>,
    /// Bricks of 16³ (min, max) pairs.
    bricks: Vec<Brick>,
}

#[derive(Clone, Debug)]
enum Repr {
    Global,
    Grid { grid: UniformGrid, values: Vec<f32> },
    Adaptive(Hierarchy),
}

/// A majorant structure over a density field's local space.
#[derive(Clone, Debug)]
pub struct Majorants {
    kind: MajorantKind,
    /// Whether tracking refines thick segments to voxel cells (`tracking::REFINE_TAU`).
    voxel_refinement: bool,
    bounds: Aabb,
    sigma_min: f32,
    sigma_max: f32,
    repr: Repr,
}

impl Majorants {
    /// One global bound `[sigma_min, sigma_max]` over the local box `bounds` (Mitsuba 3 style). Also the way to
    /// build a deliberately wrong majorant for tests.
    pub fn global(bounds: Aabb, sigma_min: f32, sigma_max: f32) -> Self {
        Self {
            kind: MajorantKind::Global,
            voxel_refinement: true,
            bounds,
            sigma_min,
            sigma_max,
            repr: Repr::Global,
        }
    }

    /// The exact global bound of an analytic field (its local space is world space).
    #[cfg(test)]
    pub fn analytic(field: &AnalyticDensity) -> Self {
        let (lo, hi) = field.range();
        Self::global(field.bounds(), lo.max(0.0), hi)
    }

    /// Builds a structure of the given kind over a grid, in its index space.
    pub fn build(kind: MajorantKind, field: &GridDensity) -> Self {
        let tree = field.tree();
        let s = field.scale();
        let bounds = field.index_bounds();
        let global_max = nonzero_regions(tree).fold(0.0f32, |m, r| m.max(r.range().1)) * s;
        if bounds.is_empty() || global_max <= 0.0 {
            return Self::global(Aabb::EMPTY, 0.0, 0.0);
        }
        let repr = match kind {
            MajorantKind::Global => Repr::Global,
            MajorantKind::Grid16 => {
                let (grid, values) = grid16_reaching(tree, s, bounds, Vec3::ZERO);
                Repr::Grid { grid, values }
            }
            MajorantKind::Adaptive => {
                let m = field.index_to_world();
                let voxel = (m.x_axis.truncate().length()
                    + m.y_axis.truncate().length()
                    + m.z_axis.truncate().length())
                    / 3.0;
                Repr::Adaptive(Hierarchy::build(tree, s, bounds, voxel))
            }
        };
        Self {
            kind,
            voxel_refinement: true,
            bounds,
            sigma_min: 0.0,
            sigma_max: global_max,
            repr,
        }
    }

    /// A structure that bounds the field displaced by anything up to `reach` index units per axis: σ̄ over a
    /// cell is the largest value a lookup within `reach` of the cell (one voxel more for trilinear reads) can
    /// return, and the bounds grow by `reach`. Velocity motion blur looks density up at x − v·t, so these
    /// majorants stay conservative over the shutter and delta tracking unbiased. `Global` keeps its maximum
    /// over the grown bounds; `Grid16` and `Adaptive` give a 16³ grid over them (the adaptive hierarchy follows
    /// the undisplaced tree). Minorants are 0.
    pub fn build_reaching(kind: MajorantKind, field: &GridDensity, reach: Vec3) -> Self {
        let tree = field.tree();
        let s = field.scale();
        let index_bounds = field.index_bounds();
        let global_max = nonzero_regions(tree).fold(0.0f32, |m, r| m.max(r.range().1)) * s;
        if index_bounds.is_empty() || global_max <= 0.0 {
            return Self::global(Aabb::EMPTY, 0.0, 0.0);
        }
        let bounds = Aabb::new(index_bounds.min - reach, index_bounds.max + reach);
        match kind {
            MajorantKind::Global => Self::global(bounds, 0.0, global_max),
            MajorantKind::Grid16 | MajorantKind::Adaptive => {
                let (grid, values) = grid16_reaching(tree, s, bounds, reach);
                Self {
                    kind: MajorantKind::Grid16,
                    voxel_refinement: true,
                    bounds,
                    sigma_min: 0.0,
                    sigma_max: global_max,
                    repr: Repr::Grid { grid, values },
                }
            }
        }
    }

    /// Bytes that a structure of `kind` over `field` allocates densely over the grid's index bounds (bricks,
    /// which follow the data, not included): what a corrupt node origin far from the data inflates. Saturates
    /// at `u64::MAX`.
    pub fn dense_bytes(kind: MajorantKind, field: &GridDensity) -> u64 {
        let bounds = field.index_bounds();
        if bounds.is_empty() {
            return 0;
        }
        match kind {
            MajorantKind::Global => 0,
            MajorantKind::Grid16 => (GRID16_RES as u64).pow(3) * 4,
            MajorantKind::Adaptive => {
                // Each coarse cell is a (min, max, brick) entry plus the f32 maximum of `coarse_maxima`.
                let entry = (std::mem::size_of::<(f32, f32, u32)>() + 4) as u64;
                Hierarchy::coarse_grid(bounds)
                    .0
                    .cell_count()
                    .saturating_mul(entry)
            }
        }
    }

    /// [`build`](Self::build), after checking its dense part ([`dense_bytes`](Self::dense_bytes)) against the
    /// memory budget.
    pub fn try_build(
        kind: MajorantKind,
        field: &GridDensity,
        limits: &Limits,
    ) -> Result<Self, OverBudget> {
        limits.check(
            format_args!("the {} majorant structure", kind.name()),
            Self::dense_bytes(kind, field),
        )?;
        Ok(Self::build(kind, field))
    }

    /// The kind of this structure.
    pub fn kind(&self) -> MajorantKind {
        self.kind
    }

    /// Turns the voxel refinement of thick segments on (the default) or off. Off, tracking uses the
    /// structure's own segments everywhere, as before the refinement existed: for benchmarks and tests that
    /// compare the two.
    #[cfg(any(test, feature = "testing"))]
    pub fn with_voxel_refinement(mut self, on: bool) -> Self {
        self.voxel_refinement = on;
        self
    }

    /// True when tracking walks segments thicker than `tracking::REFINE_TAU` per voxel voxel cell by voxel
    /// cell, on fields that bound their voxel cells (grids).
    pub fn voxel_refinement(&self) -> bool {
        self.voxel_refinement
    }

    /// True when the segments carry minorants (σ_min > 0 where the density allows), so that tracking can find
    /// segments of constant density (`Segment::is_uniform`). The 16³ grid stores majorants only.
    pub fn stores_minorants(&self) -> bool {
        self.kind != MajorantKind::Grid16
    }

    /// The local-space box the structure covers (empty for an empty field).
    pub fn local_bounds(&self) -> Aabb {
        self.bounds
    }

    /// The largest majorant anywhere.
    #[cfg(test)]
    pub fn global_max(&self) -> f32 {
        self.sigma_max
    }

    /// Heap plus inline bytes of the structure (the density field is not included).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + match &self.repr {
                Repr::Global => 0,
                Repr::Grid { values, .. } => values.len() * 4,
                Repr::Adaptive(h) => {
                    h.cells.len() * std::mem::size_of::<(f32, f32, u32)>()
                        + h.bricks.len() * std::mem::size_of::<Brick>()
                }
            }
    }

    /// The segments of non-zero majorant along the local-space `ray` over `[t_min, t_max]`, in increasing `t`.
    pub fn segments(&self, ray: &Ray, t_min: f32, t_max: f32) -> MajorantIterator<'_> {
        let inv_dir = ray.dir.recip();
        let walk = match &self.repr {
            Repr::Global => Walk::Global(match self.bounds.intersect(ray, t_min, t_max) {
                Some((t0, t1)) if self.sigma_max > 0.0 && t1 > t0 => Some(Segment {
                    t0,
                    t1,
                    sigma_max: self.sigma_max,
                    sigma_min: self.sigma_min,
                }),
                _ => None,
            }),
            Repr::Grid { grid, values } => Walk::Grid {
                grid,
                values,
                dda: Dda::clipped(grid, ray, inv_dir, t_min, t_max),
            },
            Repr::Adaptive(h) => Walk::Adaptive(AdaptiveWalk {
                h,
                coarse: Dda::clipped(&h.coarse, ray, inv_dir, t_min, t_max),
                brick: 0,
                mid_grid: UniformGrid {
                    origin: Vec3::ZERO,
                    cell: Vec3::splat(((1 << FINE_LOG2) * FINE_PER_MID) as f32),
                    res: IVec3::splat(MID),
                },
                mid: Dda::EMPTY,
                mid_cell: IVec3::ZERO,
                fine: Dda::EMPTY,
                pending: None,
            }),
        };
        MajorantIterator {
            ray: *ray,
            inv_dir,
            cells: 0,
            walk,
        }
    }
}

/// The 16³ grid of maxima over `bounds`: each cell holds the largest value a trilinear lookup within `reach`
/// (index units per axis) of it can read.
fn grid16_reaching(tree: &FloatTree, s: f32, bounds: Aabb, reach: Vec3) -> (UniformGrid, Vec<f32>) {
    let grid = UniformGrid {
        origin: bounds.min,
        cell: bounds.extent() / GRID16_RES as f32,
        res: IVec3::splat(GRID16_RES),
    };
    let mut values = vec![0.0f32; grid.cells()];
    for r in nonzero_regions(tree) {
        // Positions [o - 1, o + e) can read the region, and points within `reach` of them can be displaced
        // there: raise every cell overlapping that box.
        let (o, e) = (r.origin(), r.edge());
        let lo = ((((o - 1).as_vec3()) - reach - grid.origin) / grid.cell)
            .floor()
            .as_ivec3();
        let up = (((o + e).as_vec3() + reach - grid.origin) / grid.cell)
            .floor()
            .as_ivec3();
        grid.raise(&mut values, lo, up, r.range().1 * s);
    }
    (grid, values)
}

impl Hierarchy {
    /// The coarse grid of 2^COARSE_LOG2-voxel cells over the index-space `bounds`, and the index of its first
    /// cell.
    fn coarse_grid(bounds: Aabb) -> (UniformGrid, IVec3) {
        let c = 1 << COARSE_LOG2;
        let lo = bounds.min.floor().as_ivec3().div_euclid(IVec3::splat(c));
        let hi = (bounds.max.ceil().as_ivec3() - 1).div_euclid(IVec3::splat(c));
        let grid = UniformGrid {
            origin: (lo * c).as_vec3(),
            cell: Vec3::splat(c as f32),
            res: hi - lo + 1,
        };
        (grid, lo)
    }

    /// Builds the two-level structure. `voxel` (mean world voxel edge) only steers where refinement pays: a cell
    /// is kept as one segment where refining would save less than [`MERGE_TAU`] of majorant optical depth per
    /// crossing, estimated as (cell max − mean of its fine maxima) × cell edge.
    fn build(tree: &FloatTree, s: f32, bounds: Aabb, voxel: f32) -> Self {
        let c = 1 << COARSE_LOG2;
        let (coarse, lo) = Self::coarse_grid(bounds);
        let cmax = coarse_maxima(tree, s, &coarse, lo);
        let mut cells = vec![(0.0f32, 0.0f32, NO_BRICK); coarse.cells()];
        let mut bricks = Vec::new();
        for (idx, &m) in cmax.iter().enumerate() {
            if m <= 0.0 {
                continue;
            }
            let base = (lo + coarse.coords(idx)) * c;
            let fine = fine_ranges(&block_ranges(tree, s, base));
            let (bmin, bmax, bsum) = fine
                .iter()
                .fold((f32::INFINITY, 0.0f32, 0.0f32), |(a, b, sum), &(mn, mx)| {
                    (a.min(mn), b.max(mx), sum + mx)
                });
            let saved = (bmax - bsum / BRICK_CELLS as f32) * c as f32 * voxel;
            cells[idx] = if bmin == bmax || saved < MERGE_TAU {
                (bmin, bmax, NO_BRICK)
            } else {
                bricks.push(Brick::new(fine, voxel));
                (bmin, bmax, (bricks.len() - 1) as u32)
            };
        }
        Self {
            coarse,
            cells,
            bricks,
        }
    }
}

/// The maximum per coarse cell (grid cell `lo` is the first): the voxels read from a coarse cell are
/// `[cell, cell + 128]` (one beyond), so a region `[o, o + e)` raises the cells holding the integer positions
/// `[o - 1, o + e - 1]`.
fn coarse_maxima(tree: &FloatTree, s: f32, coarse: &UniformGrid, lo: IVec3) -> Vec<f32> {
    let c = IVec3::splat(1 << COARSE_LOG2);
    let mut cmax = vec![0.0f32; coarse.cells()];
    for r in nonzero_regions(tree) {
        let (o, e) = (r.origin(), r.edge());
        let a = (o - 1).div_euclid(c) - lo;
        let b = (o + e - 1).div_euclid(c) - lo;
        coarse.raise(&mut cmax, a, b, r.range().1 * s);
    }
    cmax
}

/// Blocks (of 8³ voxels, a leaf's size) per edge that the fine cells of one coarse cell read: one beyond.
const BLOCKS: i32 = BRICK + 1;

/// The scaled (min, max), clamped at zero, of the 17³ leaf-sized blocks from `base`, block `(i, j, k)` at
/// `((i · 17 + j) · 17 + k)`: the range of the leaf or tile that holds the block, else the background.
fn block_ranges(tree: &FloatTree, s: f32, base: IVec3) -> Vec<(f32, f32)> {
    let scaled = |(a, b): (f32, f32)| (a.max(0.0) * s, b.max(0.0) * s);
    let bg = tree.background();
    let mut block = vec![scaled((bg, bg)); (BLOCKS * BLOCKS * BLOCKS) as usize];
    let last = base + ((BLOCKS << FINE_LOG2) - 1);
    for r in tree.regions_in(base, last) {
        let range = scaled(r.range());
        let a = ((r.origin() - base) >> FINE_LOG2).max(IVec3::ZERO);
        let b = ((r.origin() + (r.edge() - 1) - base) >> FINE_LOG2).min(IVec3::splat(BRICK));
        for i in a.x..=b.x {
            for j in a.y..=b.y {
                for k in a.z..=b.z {
                    block[((i * BLOCKS + j) * BLOCKS + k) as usize] = range;
                }
            }
        }
    }
    block
}

/// The (min, max) of each fine cell of a brick, `(i · 16 + j) · 16 + k`: over the 2³ blocks it reads.
fn fine_ranges(block: &[(f32, f32)]) -> [(f32, f32); BRICK_CELLS] {
    let n = BRICK as usize;
    let nb = BLOCKS as usize;
    let bi = |i: usize, j: usize, k: usize| (i * nb + j) * nb + k;
    let mut fine = [(0.0f32, 0.0f32); BRICK_CELLS];
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let (mut a, mut b) = (f32::INFINITY, 0.0f32);
                for di in 0..=1 {
                    for dj in 0..=1 {
                        for dk in 0..=1 {
                            let v = block[bi(i + di, j + dj, k + dk)];
                            a = a.min(v.0);
                            b = b.max(v.1);
                        }
                    }
                }
                fine[(i * n + j) * n + k] = (a, b);
            }
        }
    }
    fine
}

impl Brick {
    /// A brick over the fine ranges `fine`, with its mid level: each mid cell's range, and whether it is walked
    /// as one segment (uniform, or refining would save less than [`MERGE_TAU`] per crossing).
    fn new(fine: [(f32, f32); BRICK_CELLS], voxel: f32) -> Self {
        let n = BRICK as usize;
        let q = FINE_PER_MID as usize;
        let mut mid = [(f32::INFINITY, 0.0f32); MID_CELLS];
        let mut sum = [0.0f32; MID_CELLS];
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    let mi = (i / q * MID as usize + j / q) * MID as usize + k / q;
                    let (a, b) = fine[(i * n + j) * n + k];
                    mid[mi] = (mid[mi].0.min(a), mid[mi].1.max(b));
                    sum[mi] += b;
                }
            }
        }
        let mut flat = 0u64;
        for (mi, &(a, b)) in mid.iter().enumerate() {
            let saved = (b - sum[mi] / (q * q * q) as f32) * (q << FINE_LOG2) as f32 * voxel;
            if a == b || saved < MERGE_TAU {
                flat |= 1 << mi;
            }
        }
        Self { mid, flat, fine }
    }
}

/// The segments of non-zero majorant along a ray, in increasing `t` ([`Majorants::segments`]).
///
/// An external iterator in the manner of pbrt-v4's `DDAMajorantIterator` (PBRT 4th ed., §11.4.3): the DDA state
/// of every level lives in the iterator, and each `next()` walks only as far as the next segment, so a tracker
/// that stops early never pays for the rest of the ray.
pub struct MajorantIterator<'a> {
    ray: Ray,
    inv_dir: Vec3,
    cells: u64,
    walk: Walk<'a>,
}

/// The traversal state of each kind of structure.
#[allow(
    clippy::large_enum_variant,
    reason = "one walk per ray segment, on the stack: boxing the adaptive walk would allocate per segment"
)]
enum Walk<'a> {
    /// The one segment still to hand out, if any.
    Global(Option<Segment>),
    Grid {
        grid: &'a UniformGrid,
        values: &'a [f32],
        dda: Dda,
    },
    Adaptive(AdaptiveWalk<'a>),
}

/// A walk through the [`MajorantKind::Adaptive`] hierarchy: a DDA per level (an empty one where the level above
/// needs none), and the segment being extended by merging.
struct AdaptiveWalk<'a> {
    h: &'a Hierarchy,
    coarse: Dda,
    /// The brick of the current coarse cell, and its mid-level grid.
    brick: u32,
    mid_grid: UniformGrid,
    mid: Dda,
    /// The current mid cell, whose fine cells `fine` walks.
    mid_cell: IVec3,
    fine: Dda,
    pending: Option<Segment>,
}

impl MajorantIterator<'_> {
    /// The structure's cells walked so far: DDA steps at every level, empty cells included (1 for a global
    /// bound). The traversal work, which merged segments hide.
    pub fn cells(&self) -> u64 {
        self.cells
    }
}

impl Iterator for MajorantIterator<'_> {
    type Item = Segment;

    #[inline]
    fn next(&mut self) -> Option<Segment> {
        match &mut self.walk {
            Walk::Global(s) => {
                let s = s.take()?;
                self.cells += 1;
                Some(s)
            }
            Walk::Grid { grid, values, dda } => loop {
                let (c, t0, t1) = dda.next(&mut self.cells)?;
                let m = values[grid.index(c)];
                if m > 0.0 {
                    return Some(Segment {
                        t0,
                        t1,
                        sigma_max: m,
                        sigma_min: 0.0,
                    });
                }
            },
            Walk::Adaptive(w) => w.next_merged(&self.ray, self.inv_dir, &mut self.cells),
        }
    }
}

impl AdaptiveWalk<'_> {
    /// The next segment after merging: cell segments are joined while the join adds less than [`MERGE_TAU`] of
    /// majorant optical depth.
    fn next_merged(&mut self, ray: &Ray, inv_dir: Vec3, cells: &mut u64) -> Option<Segment> {
        while let Some(s) = self.next_cell(ray, inv_dir, cells) {
            let Some(p) = &mut self.pending else {
                self.pending = Some(s);
                continue;
            };
            let m = p.sigma_max.max(s.sigma_max);
            let extra = (m - p.sigma_max) * (p.t1 - p.t0) + (m - s.sigma_max) * (s.t1 - s.t0);
            // Contiguous up to round-off (a brick's entry is recomputed from its own box).
            let contiguous = s.t0 - p.t1 <= 1e-6 * (1.0 + s.t0.abs());
            if contiguous && extra < MERGE_TAU {
                p.t1 = s.t1;
                p.sigma_max = m;
                p.sigma_min = p.sigma_min.min(s.sigma_min);
            } else {
                return self.pending.replace(s);
            }
        }
        self.pending.take()
    }

    /// The next cell of non-zero majorant at the finest level the hierarchy keeps there: a coarse cell without a
    /// brick, a flat mid cell or a fine cell.
    fn next_cell(&mut self, ray: &Ray, inv_dir: Vec3, cells: &mut u64) -> Option<Segment> {
        let h = self.h;
        let segment = |t0, t1, (sigma_min, sigma_max): (f32, f32)| Segment {
            t0,
            t1,
            sigma_max,
            sigma_min,
        };
        loop {
            if let Some((fc, t0, t1)) = self.fine.next(cells) {
                let f = self.mid_cell * FINE_PER_MID + fc;
                let range = h.bricks[self.brick as usize].fine
                    [((f.x * BRICK + f.y) * BRICK + f.z) as usize];
                if range.1 > 0.0 {
                    return Some(segment(t0, t1, range));
                }
            } else if let Some((mc, t0, t1)) = self.mid.next(cells) {
                let brick = &h.bricks[self.brick as usize];
                let mi = ((mc.x * MID + mc.y) * MID + mc.z) as usize;
                if brick.mid[mi].1 <= 0.0 {
                    continue;
                }
                if brick.flat >> mi & 1 != 0 {
                    return Some(segment(t0, t1, brick.mid[mi]));
                }
                let fine = UniformGrid {
                    origin: self.mid_grid.origin + mc.as_vec3() * self.mid_grid.cell,
                    cell: Vec3::splat((1 << FINE_LOG2) as f32),
                    res: IVec3::splat(FINE_PER_MID),
                };
                self.mid_cell = mc;
                self.fine = Dda::inside(&fine, ray, inv_dir, t0, t1);
            } else {
                let (c, t0, t1) = self.coarse.next(cells)?;
                let (lo, hi, b) = h.cells[h.coarse.index(c)];
                if hi <= 0.0 {
                    continue;
                }
                if b == NO_BRICK {
                    return Some(segment(t0, t1, (lo, hi)));
                }
                self.brick = b;
                self.mid_grid.origin = h.coarse.origin + c.as_vec3() * h.coarse.cell;
                self.mid = Dda::inside(&self.mid_grid, ray, inv_dir, t0, t1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;
    use crate::volume::density::test_fields::{block_grid, sphere_grid};

    #[test]
    fn voxel_cells_hold_the_points_of_their_intervals() {
        // A refined segment ends on a majorant cell's face, computed by another walk than the voxel cells'
        // own: each voxel cell given must still be the cell of the points in its interval, or its eight voxels
        // bound points it does not hold (a sliver of round-off past the face, or boundaries drifted by the
        // round-off of a long walk).
        let mut rng = Rng::new(11, 0);
        let mut wrong = 0;
        for _ in 0..20_000 {
            let mut v = || rng.next_f32();
            let origin = Vec3::new(v(), v(), v()) * 64.0 - 32.0;
            let dir = (Vec3::new(v(), v(), v()) * 2.0 - 1.0).normalize_or(Vec3::X);
            let ray = Ray::new(origin, dir * (0.5 + 4.0 * v()));
            // Segment ends on planes y = 16k, as a majorant walk over 16-voxel bricks computes them.
            let plane = |k: f32| (16.0 * k - ray.origin.y) / ray.dir.y;
            let (a, b) = (plane(-1.0), plane(1.0));
            let (t0, t1) = (a.min(b).max(0.0), a.max(b));
            // At most 512 voxels long: grids' voxel counts, where f32 positions resolve 1/32768 of a voxel.
            if t0 >= t1 || !t1.is_finite() || (t1 - t0) * ray.dir.length() > 512.0 {
                continue;
            }
            let mut cells = VoxelCells::new(&ray, t0, t1);
            let mut count = 0;
            while let Some((cell, c0, c1)) = cells.next(&mut count) {
                // Points of the interval (a short one: its midpoint) must lie in the cell, up to round-off.
                let long = (c1 - c0) * ray.dir.length() > 0.05;
                let fractions: &[f32] = if long { &[0.05, 0.5, 0.95] } else { &[0.5] };
                for f in fractions {
                    if floor_ivec3(ray.at(c0 + f * (c1 - c0))) != cell {
                        wrong += 1;
                    }
                }
            }
        }
        assert_eq!(wrong, 0);
    }

    #[test]
    fn majorants_bound_the_trilinear_density() {
        let g = sphere_grid(8.0);
        let b = g.index_bounds();
        let mut rng = Rng::new(42, 7);
        let u3 = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        for kind in MajorantKind::ALL {
            let m = Majorants::build(kind, &g);
            // Small beside the tree it bounds.
            assert!(
                m.memory_bytes() < g.memory_bytes() / 2,
                "{kind:?}: {} vs tree {}",
                m.memory_bytes(),
                g.memory_bytes()
            );
            let mut checked = 0;
            for _ in 0..2000 {
                // Rays in index space from outside towards random points of the bounds.
                let target = b.min + u3(&mut rng) * b.extent();
                let from = b.center() + (u3(&mut rng) - 0.5) * 3.0 * b.extent();
                let ray = Ray::new(from, target - from);
                let mut last = f32::NEG_INFINITY;
                for s in m.segments(&ray, 0.0, 3.0) {
                    assert!(s.t0 >= last - 1e-5 && s.t1 >= s.t0 && s.sigma_max > 0.0);
                    last = s.t1;
                    for _ in 0..4 {
                        let t = s.t0 + (s.t1 - s.t0) * rng.next_f32();
                        let d = g.density_index(ray.at(t));
                        assert!(d <= s.sigma_max * (1.0 + 1e-5), "{kind:?}: {d} > {s:?}");
                        assert!(
                            d >= s.sigma_min * (1.0 - 1e-5) - 1e-6,
                            "{kind:?}: {d} < {s:?}"
                        );
                        checked += 1;
                    }
                }
            }
            assert!(checked > 4000, "{kind:?}: {checked}");
            // Empty space is skipped: points outside all segments must have zero density.
            let ray = Ray::new(b.min - 5.0, b.extent());
            let covered: Vec<_> = m.segments(&ray, 0.0, 1.0).map(|s| (s.t0, s.t1)).collect();
            for i in 0..5000 {
                let t = i as f32 / 5000.0;
                if !covered.iter().any(|&(a, b)| t >= a - 1e-5 && t <= b + 1e-5) {
                    assert_eq!(g.density_index(ray.at(t)), 0.0, "{kind:?} t={t}");
                }
            }
        }
    }

    #[test]
    fn adaptive_is_tighter_than_global() {
        // Mean majorant optical depth along random unit-speed rays (t in voxels): the subdivided structures are
        // tighter than the global bound on a sparse field.
        let g = sphere_grid(1.0);
        let b = g.index_bounds();
        let mut rng = Rng::new(5, 5);
        let mut total = [0.0f64; 3];
        let kinds = MajorantKind::ALL.map(|k| Majorants::build(k, &g));
        for _ in 0..500 {
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let v = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let (p, q) = (b.min + u * b.extent(), b.min + v * b.extent());
            let d = (q - p).normalize();
            let ray = Ray::new(p - d * 100.0, d);
            for (i, m) in kinds.iter().enumerate() {
                for s in m.segments(&ray, 0.0, 300.0) {
                    total[i] += ((s.t1 - s.t0) * s.sigma_max) as f64;
                }
            }
        }
        assert!(
            total[2] < 0.8 * total[0] && total[1] < 0.8 * total[0],
            "{total:?}"
        );
    }

    /// Checks the segments of `m` along `ray` over `[t0, t1]` against `density` sampled by brute force: in order
    /// and not overlapping, inside `[t0, t1]`, each majorant at least the largest density sampled in its segment
    /// (ends included), zero density in the gaps between them, and the cells counted. Returns the segments.
    fn check_segments(
        m: &Majorants,
        density: &dyn Fn(Vec3) -> f32,
        ray: &Ray,
        (t0, t1): (f32, f32),
    ) -> Vec<Segment> {
        let mut it = m.segments(ray, t0, t1);
        let segments: Vec<Segment> = it.by_ref().collect();
        assert!(segments.is_empty() || it.cells() >= segments.len() as u64);
        let samples = 64;
        let mut last = t0;
        for s in &segments {
            assert!(
                s.t0 >= last - 1e-5 * (1.0 + last.abs()),
                "{s:?} starts before {last}"
            );
            assert!(s.t1 > s.t0 && s.t1 <= t1 && s.sigma_max > 0.0, "{s:?}");
            // The gap before the segment is empty.
            for i in 1..samples {
                let t = last + (s.t0 - last) * i as f32 / samples as f32;
                // Points within round-off of a segment's ends may read its cells.
                if t < s.t0 - 1e-5 * (1.0 + s.t0.abs()) && t > last + 1e-5 * (1.0 + last.abs()) {
                    assert_eq!(density(ray.at(t)), 0.0, "{:?}: gap at t = {t}", m.kind());
                }
            }
            for i in 0..=samples {
                let t = s.t0 + (s.t1 - s.t0) * i as f32 / samples as f32;
                let d = density(ray.at(t));
                assert!(
                    d <= s.sigma_max * (1.0 + 1e-5),
                    "{:?}: {d} > {s:?}",
                    m.kind()
                );
                assert!(
                    d >= s.sigma_min * (1.0 - 1e-5) - 1e-6,
                    "{:?}: {d} < {s:?}",
                    m.kind()
                );
            }
            last = s.t1;
        }
        for i in 1..samples {
            let t = last + (t1 - last) * i as f32 / samples as f32;
            if t > last + 1e-5 * (1.0 + last.abs()) {
                assert_eq!(density(ray.at(t)), 0.0, "{:?}: gap at t = {t}", m.kind());
            }
        }
        segments
    }

    #[test]
    fn majorant_iterator_segments_bound_the_density_and_cover_it() {
        let g = sphere_grid(8.0);
        let b = g.index_bounds();
        let mut rng = Rng::new(3, 9);
        let u3 = |rng: &mut Rng| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let density = |p: Vec3| g.density_index(p);
        for kind in MajorantKind::ALL {
            let m = Majorants::build(kind, &g);
            for _ in 0..300 {
                let target = b.min + u3(&mut rng) * b.extent();
                let from = b.center() + (u3(&mut rng) - 0.5) * 3.0 * b.extent();
                let ray = Ray::new(from, target - from);
                // Whole rays, and rays that start or end inside the field.
                check_segments(&m, &density, &ray, (0.0, 3.0));
                check_segments(&m, &density, &ray, (0.7, 1.3));
            }
        }
        // A constant block: the segments are contiguous and cover the part of the ray inside the field's bounds
        // (the adaptive cells may reach a little beyond them).
        let g = block_grid(24, 0.1, 0.5);
        let b = g.index_bounds();
        let ray = Ray::new(
            b.min - Vec3::new(7.0, -11.3, -9.1),
            Vec3::new(1.0, 0.05, 0.02),
        );
        let (enter, exit) = b.intersect(&ray, 0.0, 1000.0).unwrap();
        for kind in MajorantKind::ALL {
            let m = Majorants::build(kind, &g);
            let segments = check_segments(&m, &|p| g.density_index(p), &ray, (0.0, 1000.0));
            let (first, last) = (segments.first().unwrap(), segments.last().unwrap());
            assert!(
                first.t0 <= enter * (1.0 + 1e-6),
                "{kind:?}: {first:?} {enter}"
            );
            assert!(last.t1 >= exit * (1.0 - 1e-6), "{kind:?}: {last:?} {exit}");
            for w in segments.windows(2) {
                assert!(w[1].t0 - w[0].t1 <= 1e-5 * w[1].t0, "{kind:?}: {w:?}");
            }
        }
    }
}
