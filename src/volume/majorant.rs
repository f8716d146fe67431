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
//! Bounds are conservative for trilinear interpolation: a lookup at `x` reads voxels `floor(x)` and
//! `floor(x) + 1`, so a cell's bound covers every voxel its points can read, one voxel beyond the cell.

use super::density::{for_each_region, AnalyticDensity, DensityField, GridDensity};
use crate::math::{Aabb, Ray, Vec3};
use crate::vdb::{floor_ivec3, FloatTree, RootSlot, NO_CHILD};
use glam::IVec3;
use std::ops::ControlFlow;

/// Resolution per axis of the [`MajorantKind::Grid16`] grid.
pub const GRID16_RES: i32 = 16;
/// Extra majorant optical depth below which [`MajorantKind::Adaptive`] merges neighbouring segments, measured
/// as σ̄ × ray parameter (an optical depth for rays whose world direction has unit length).
pub const MERGE_TAU: f32 = 0.25;
const COARSE_LOG2: i32 = 7;
const FINE_LOG2: i32 = 3;
const BRICK: i32 = 1 << (COARSE_LOG2 - FINE_LOG2);
const NO_BRICK: u32 = u32::MAX;
/// Mid-level cells per brick edge.
const MID: i32 = 4;
/// Fine cells per mid-level cell edge.
const FINE_PER_MID: i32 = BRICK / MID;

/// A 16³ brick of 8³-voxel cells under one 128³ cell, with a 4³ mid level of 32³-voxel cells that lets the DDA
/// skip empty or uniform quarters of the brick in one step. Entries are (min, max).
#[derive(Clone, Debug)]
struct Brick {
    mid: [(f32, f32); (MID * MID * MID) as usize],
    /// Bit per mid cell: walk it as one segment (its fine cells would save less than [`MERGE_TAU`]).
    flat: u64,
    fine: [(f32, f32); (BRICK * BRICK * BRICK) as usize],
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

/// A uniform grid of cells over `origin + cell · [0, res)` in local space.
#[derive(Clone, Debug)]
struct UniformGrid {
    origin: Vec3,
    cell: Vec3,
    res: IVec3,
}

impl UniformGrid {
    fn index(&self, c: IVec3) -> usize {
        ((c.x * self.res.y + c.y) * self.res.z + c.z) as usize
    }

    fn cells(&self) -> usize {
        (self.res.x * self.res.y * self.res.z) as usize
    }

    /// Walks the cells pierced by `ray` over `[t0, t1]`, clipped to the grid; see [`Self::walk_inside`].
    fn walk(
        &self,
        ray: &Ray,
        inv_dir: Vec3,
        t0: f32,
        t1: f32,
        cells: &mut u64,
        f: impl FnMut(IVec3, f32, f32) -> ControlFlow<()>,
    ) -> ControlFlow<()> {
        let ta = (self.origin - ray.origin) * inv_dir;
        let tb = (self.origin + self.cell * self.res.as_vec3() - ray.origin) * inv_dir;
        let t0 = ta.min(tb).max_element().max(t0);
        let t1 = ta.max(tb).min_element().min(t1);
        if t0 < t1 {
            self.walk_inside(ray, inv_dir, t0, t1, cells, f)
        } else {
            ControlFlow::Continue(())
        }
    }

    /// Walks the cells pierced by `ray` over `[ta, tb]` (known to lie in the grid up to round-off) with the 3D DDA
    /// of Amanatides & Woo (1987): per axis, the parameter of the next cell boundary `t_next` and the parameter
    /// step per cell `t_delta`; each step advances the axis with the smallest `t_next`. Adds the cells visited
    /// to `cells`.
    fn walk_inside(
        &self,
        ray: &Ray,
        inv_dir: Vec3,
        ta: f32,
        tb: f32,
        cells: &mut u64,
        mut f: impl FnMut(IVec3, f32, f32) -> ControlFlow<()>,
    ) -> ControlFlow<()> {
        // Start from the cell of the interval's entry point (clamped inside against round-off).
        let c =
            floor_ivec3((ray.at(ta) - self.origin) / self.cell).clamp(IVec3::ZERO, self.res - 1);
        let flat = ray.dir.cmpeq(Vec3::ZERO);
        let up = ray.dir.cmpgt(Vec3::ZERO);
        let step = IVec3::select(up, IVec3::ONE, IVec3::NEG_ONE);
        let boundary =
            self.origin + (c + IVec3::select(up, IVec3::ONE, IVec3::ZERO)).as_vec3() * self.cell;
        let t_next = Vec3::select(flat, Vec3::INFINITY, (boundary - ray.origin) * inv_dir);
        let t_delta = Vec3::select(flat, Vec3::INFINITY, self.cell * inv_dir.abs());
        // Plain arrays: indexing glam vectors by a runtime axis compiles to a branch per access.
        let (mut t_next, t_delta, step, res) = (
            t_next.to_array(),
            t_delta.to_array(),
            step.to_array(),
            self.res.to_array(),
        );
        let mut cell = c.to_array();
        let mut t = ta;
        loop {
            *cells += 1;
            let a = if t_next[0] <= t_next[1] && t_next[0] <= t_next[2] {
                0
            } else if t_next[1] <= t_next[2] {
                1
            } else {
                2
            };
            let t_end = t_next[a].min(tb);
            if t_end > t {
                f(IVec3::from_array(cell), t, t_end)?;
            }
            if t_end >= tb {
                return ControlFlow::Continue(());
            }
            t = t_end;
            cell[a] += step[a];
            if cell[a] < 0 || cell[a] >= res[a] {
                return ControlFlow::Continue(());
            }
            t_next[a] += t_delta[a];
        }
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
    bounds: Aabb,
    sigma_min: f32,
    sigma_max: f32,
    repr: Repr,
}

/// (min, max) of the stored values a lookup can return in the 8³ block at leaf-aligned index `p`.
fn block_range(tree: &FloatTree, p: IVec3) -> (f32, f32) {
    let key = p & !4095;
    let Ok(i) = tree
        .root
        .binary_search_by(|(k, _)| (k.x, k.y, k.z).cmp(&(key.x, key.y, key.z)))
    else {
        return (tree.background, tree.background);
    };
    let u = match tree.root[i].1 {
        RootSlot::Tile { value, .. } => return (value, value),
        RootSlot::Child(u) => &tree.uppers[u as usize],
    };
    let us =
        ((((p.x & 4095) >> 7) << 10) | (((p.y & 4095) >> 7) << 5) | ((p.z & 4095) >> 7)) as usize;
    let l = match u.children[us] {
        NO_CHILD => return (u.tiles[us], u.tiles[us]),
        l => &tree.lowers[l as usize],
    };
    let ls = ((((p.x & 127) >> 3) << 8) | (((p.y & 127) >> 3) << 4) | ((p.z & 127) >> 3)) as usize;
    match l.children[ls] {
        NO_CHILD => (l.tiles[ls], l.tiles[ls]),
        c => {
            let lf = &tree.leaves[c as usize];
            (lf.min, lf.max)
        }
    }
}

impl Majorants {
    /// One global bound `[sigma_min, sigma_max]` over the local box `bounds` (Mitsuba 3 style). Also the way to
    /// build a deliberately wrong majorant for tests.
    pub fn global(bounds: Aabb, sigma_min: f32, sigma_max: f32) -> Self {
        Self {
            kind: MajorantKind::Global,
            bounds,
            sigma_min,
            sigma_max,
            repr: Repr::Global,
        }
    }

    /// The exact global bound of an analytic field (its local space is world space).
    pub fn analytic(field: &AnalyticDensity) -> Self {
        let (lo, hi) = field.range();
        Self::global(field.bounds(), lo.max(0.0), hi)
    }

    /// Builds a structure of the given kind over a grid, in its index space.
    pub fn build(kind: MajorantKind, field: &GridDensity) -> Self {
        let tree = field.tree();
        let s = field.scale();
        let bounds = field.index_bounds();
        let mut global_max = 0.0f32;
        for_each_region(tree, |_, _, _, hi| global_max = global_max.max(hi));
        let global_max = global_max * s;
        if bounds.is_empty() || global_max <= 0.0 {
            return Self::global(Aabb::EMPTY, 0.0, 0.0);
        }
        let repr = match kind {
            MajorantKind::Global => Repr::Global,
            MajorantKind::Grid16 => {
                let grid = UniformGrid {
                    origin: bounds.min,
                    cell: bounds.extent() / GRID16_RES as f32,
                    res: IVec3::splat(GRID16_RES),
                };
                let mut values = vec![0.0f32; grid.cells()];
                for_each_region(tree, |o, e, _, hi| {
                    // Positions [o - 1, o + e) can read the region: mark every cell overlapping it.
                    let lo = ((((o - 1).as_vec3()) - grid.origin) / grid.cell)
                        .floor()
                        .as_ivec3();
                    let up = (((o + e).as_vec3() - grid.origin) / grid.cell)
                        .floor()
                        .as_ivec3();
                    let (lo, up) = (lo.max(IVec3::ZERO), up.min(grid.res - 1));
                    for x in lo.x..=up.x {
                        for y in lo.y..=up.y {
                            for z in lo.z..=up.z {
                                let v = &mut values[grid.index(IVec3::new(x, y, z))];
                                *v = v.max(hi * s);
                            }
                        }
                    }
                });
                Repr::Grid { grid, values }
            }
            MajorantKind::Adaptive => {
                let m = field.index_to_world();
                let voxel = (m.x_axis.truncate().length()
                    + m.y_axis.truncate().length()
                    + m.z_axis.truncate().length())
                    / 3.0;
                Repr::Adaptive(Self::build_hierarchy(tree, s, bounds, voxel))
            }
        };
        Self {
            kind,
            bounds,
            sigma_min: 0.0,
            sigma_max: global_max,
            repr,
        }
    }

    /// Builds the two-level structure. `voxel` (mean world voxel edge) only steers where refinement pays: a cell
    /// is kept as one segment where refining would save less than [`MERGE_TAU`] of majorant optical depth per
    /// crossing, estimated as (cell max − mean of its fine maxima) × cell edge.
    fn build_hierarchy(tree: &FloatTree, s: f32, bounds: Aabb, voxel: f32) -> Hierarchy {
        let c = 1 << COARSE_LOG2;
        let lo = bounds.min.floor().as_ivec3().div_euclid(IVec3::splat(c));
        let hi = (bounds.max.ceil().as_ivec3() - 1).div_euclid(IVec3::splat(c));
        let coarse = UniformGrid {
            origin: (lo * c).as_vec3(),
            cell: Vec3::splat(c as f32),
            res: hi - lo + 1,
        };
        // Coarse maxima: the voxels read from a coarse cell are [cell, cell + 128] (one beyond), so a region
        // [o, o + e) marks the coarse cells holding the integer positions [o - 1, o + e - 1].
        let mut cmax = vec![0.0f32; coarse.cells()];
        for_each_region(tree, |o, e, _, h| {
            let a = ((o - 1).div_euclid(IVec3::splat(c)) - lo).max(IVec3::ZERO);
            let b = ((o + e - 1).div_euclid(IVec3::splat(c)) - lo).min(coarse.res - 1);
            for x in a.x..=b.x {
                for y in a.y..=b.y {
                    for z in a.z..=b.z {
                        let v = &mut cmax[coarse.index(IVec3::new(x, y, z))];
                        *v = v.max(h * s);
                    }
                }
            }
        });
        let mut cells = vec![(0.0f32, 0.0f32, NO_BRICK); coarse.cells()];
        let mut bricks = Vec::new();
        let n = BRICK as usize;
        // Blocks (8³ voxels) per fine cell edge, and fine cells per mid cell edge.
        let r = 1usize << (FINE_LOG2 - 3);
        let q = n / MID as usize;
        for x in 0..coarse.res.x {
            for y in 0..coarse.res.y {
                for z in 0..coarse.res.z {
                    let ci = IVec3::new(x, y, z);
                    let idx = coarse.index(ci);
                    if cmax[idx] <= 0.0 {
                        continue;
                    }
                    // Ranges of the 8³-voxel blocks this cell's fine cells read from (one beyond).
                    let base = (lo + ci) * c;
                    let nb = n * r + 1;
                    let mut block = vec![(0.0f32, 0.0f32); nb * nb * nb];
                    let bi = |i: usize, j: usize, k: usize| (i * nb + j) * nb + k;
                    for i in 0..nb {
                        for j in 0..nb {
                            for k in 0..nb {
                                let p = base + IVec3::new(i as i32, j as i32, k as i32) * 8;
                                let (a, b) = block_range(tree, p);
                                block[bi(i, j, k)] = (a.max(0.0) * s, b.max(0.0) * s);
                            }
                        }
                    }
                    let mut brick = [(0.0f32, 0.0f32); (BRICK * BRICK * BRICK) as usize];
                    let (mut bmin, mut bmax, mut bsum) = (f32::INFINITY, 0.0f32, 0.0f32);
                    for i in 0..n {
                        for j in 0..n {
                            for k in 0..n {
                                let (mut a, mut b) = (f32::INFINITY, 0.0f32);
                                for di in 0..=r {
                                    for dj in 0..=r {
                                        for dk in 0..=r {
                                            let v = block[bi(i * r + di, j * r + dj, k * r + dk)];
                                            a = a.min(v.0);
                                            b = b.max(v.1);
                                        }
                                    }
                                }
                                brick[(i * n + j) * n + k] = (a, b);
                                bmin = bmin.min(a);
                                bmax = bmax.max(b);
                                bsum += b;
                            }
                        }
                    }
                    let saved = (bmax - bsum / (n * n * n) as f32) * c as f32 * voxel;
                    cells[idx] = if bmin == bmax || saved < MERGE_TAU {
                        (bmin, bmax, NO_BRICK)
                    } else {
                        let mut mid = [(f32::INFINITY, 0.0f32); (MID * MID * MID) as usize];
                        let mut sum = [0.0f32; (MID * MID * MID) as usize];
                        for i in 0..n {
                            for j in 0..n {
                                for k in 0..n {
                                    let mi = (i / q * MID as usize + j / q) * MID as usize + k / q;
                                    let (a, b) = brick[(i * n + j) * n + k];
                                    mid[mi] = (mid[mi].0.min(a), mid[mi].1.max(b));
                                    sum[mi] += b;
                                }
                            }
                        }
                        let mut flat = 0u64;
                        for (mi, &(a, b)) in mid.iter().enumerate() {
                            let saved = (b - sum[mi] / (q * q * q) as f32) * (q * 8) as f32 * voxel;
                            if a == b || saved < MERGE_TAU {
                                flat |= 1 << mi;
                            }
                        }
                        bricks.push(Brick {
                            mid,
                            flat,
                            fine: brick,
                        });
                        (bmin, bmax, (bricks.len() - 1) as u32)
                    };
                }
            }
        }
        Hierarchy {
            coarse,
            cells,
            bricks,
        }
    }

    /// The kind of this structure.
    pub fn kind(&self) -> MajorantKind {
        self.kind
    }

    /// True when the segments carry minorants (σ_min > 0 where the density allows), so that tracking can find
    /// segments of constant density (`Segment::is_uniform`). The 16³ grid stores majorants only.
    pub fn stores_minorants(&self) -> bool {
        self.kind != MajorantKind::Grid16
    }

    /// The largest majorant anywhere.
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

    /// Calls `f` for each segment of non-zero majorant along the local-space `ray` over `[t_min, t_max]`, in
    /// increasing `t`, until `f` breaks. Returns `Break` when `f` did. Adds the structure's cells visited (DDA
    /// steps at every level, empty ones included; 1 for a global bound) to `cells`, the traversal work.
    pub fn for_each_segment(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        cells: &mut u64,
        mut f: impl FnMut(Segment) -> ControlFlow<()>,
    ) -> ControlFlow<()> {
        let inv_dir = ray.dir.recip();
        match &self.repr {
            Repr::Global => match self.bounds.intersect(ray, t_min, t_max) {
                Some((t0, t1)) if self.sigma_max > 0.0 && t1 > t0 => {
                    *cells += 1;
                    f(Segment {
                        t0,
                        t1,
                        sigma_max: self.sigma_max,
                        sigma_min: self.sigma_min,
                    })
                }
                _ => ControlFlow::Continue(()),
            },
            Repr::Grid { grid, values } => {
                grid.walk(ray, inv_dir, t_min, t_max, cells, |c, t0, t1| {
                    let m = values[grid.index(c)];
                    if m > 0.0 {
                        f(Segment {
                            t0,
                            t1,
                            sigma_max: m,
                            sigma_min: 0.0,
                        })
                    } else {
                        ControlFlow::Continue(())
                    }
                })
            }
            Repr::Adaptive(h) => {
                let mut pending: Option<Segment> = None;
                let mut emit = |s: Segment| -> ControlFlow<()> {
                    if let Some(p) = &mut pending {
                        let m = p.sigma_max.max(s.sigma_max);
                        let extra =
                            (m - p.sigma_max) * (p.t1 - p.t0) + (m - s.sigma_max) * (s.t1 - s.t0);
                        // Contiguous up to round-off (a brick's entry is recomputed from its own box).
                        let contiguous = s.t0 - p.t1 <= 1e-6 * (1.0 + s.t0.abs());
                        if contiguous && extra < MERGE_TAU {
                            p.t1 = s.t1;
                            p.sigma_max = m;
                            p.sigma_min = p.sigma_min.min(s.sigma_min);
                            return ControlFlow::Continue(());
                        }
                        let done = *p;
                        *p = s;
                        return f(done);
                    }
                    pending = Some(s);
                    ControlFlow::Continue(())
                };
                // Cells of the brick levels, counted apart from the walks that hold the outer counters.
                let (mut mid_cells, mut fine_cells) = (0u64, 0u64);
                let walked = h
                    .coarse
                    .walk(ray, inv_dir, t_min, t_max, cells, |c, t0, t1| {
                        let (lo, hi, b) = h.cells[h.coarse.index(c)];
                        if hi <= 0.0 {
                            return ControlFlow::Continue(());
                        }
                        if b == NO_BRICK {
                            return emit(Segment {
                                t0,
                                t1,
                                sigma_max: hi,
                                sigma_min: lo,
                            });
                        }
                        let brick = &h.bricks[b as usize];
                        let fine_edge = (1 << FINE_LOG2) as f32;
                        let mid = UniformGrid {
                            origin: h.coarse.origin + c.as_vec3() * h.coarse.cell,
                            cell: Vec3::splat(fine_edge * FINE_PER_MID as f32),
                            res: IVec3::splat(MID),
                        };
                        mid.walk_inside(ray, inv_dir, t0, t1, &mut mid_cells, |mc, ma, mb| {
                            let mi = ((mc.x * MID + mc.y) * MID + mc.z) as usize;
                            let (lo, hi) = brick.mid[mi];
                            if hi <= 0.0 {
                                return ControlFlow::Continue(());
                            }
                            if brick.flat >> mi & 1 != 0 {
                                return emit(Segment {
                                    t0: ma,
                                    t1: mb,
                                    sigma_max: hi,
                                    sigma_min: lo,
                                });
                            }
                            let fine = UniformGrid {
                                origin: mid.origin + mc.as_vec3() * mid.cell,
                                cell: Vec3::splat(fine_edge),
                                res: IVec3::splat(FINE_PER_MID),
                            };
                            fine.walk_inside(ray, inv_dir, ma, mb, &mut fine_cells, |fc, a, b| {
                                let f = mc * FINE_PER_MID + fc;
                                let (lo, hi) =
                                    brick.fine[((f.x * BRICK + f.y) * BRICK + f.z) as usize];
                                if hi > 0.0 {
                                    emit(Segment {
                                        t0: a,
                                        t1: b,
                                        sigma_max: hi,
                                        sigma_min: lo,
                                    })
                                } else {
                                    ControlFlow::Continue(())
                                }
                            })
                        })
                    });
                *cells += mid_cells + fine_cells;
                walked?;
                match pending {
                    Some(p) => f(p),
                    None => ControlFlow::Continue(()),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Rng;
    use crate::volume::density::test_fields::sphere_grid;

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
            let (mut checked, mut segments) = (0, 0);
            for _ in 0..2000 {
                // Rays in index space from outside towards random points of the bounds.
                let target = b.min + u3(&mut rng) * b.extent();
                let from = b.center() + (u3(&mut rng) - 0.5) * 3.0 * b.extent();
                let ray = Ray::new(from, target - from);
                let mut last = f32::NEG_INFINITY;
                let _ = m.for_each_segment(&ray, 0.0, 3.0, &mut 0, |s| {
                    segments += 1;
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
                    ControlFlow::Continue(())
                });
            }
            assert!(checked > 4000, "{kind:?}: {checked}");
            // Empty space is skipped: points outside all segments must have zero density.
            let ray = Ray::new(b.min - 5.0, b.extent());
            let mut covered = Vec::new();
            let _ = m.for_each_segment(&ray, 0.0, 1.0, &mut 0, |s| {
                covered.push((s.t0, s.t1));
                ControlFlow::Continue(())
            });
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
                let _ = m.for_each_segment(&ray, 0.0, 300.0, &mut 0, |s| {
                    total[i] += ((s.t1 - s.t0) * s.sigma_max) as f64;
                    ControlFlow::Continue(())
                });
            }
        }
        assert!(
            total[2] < 0.8 * total[0] && total[1] < 0.8 * total[0],
            "{total:?}"
        );
    }
}
