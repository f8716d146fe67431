//! A 3D DDA (Amanatides & Woo 1987, "A Fast Voxel Traversal Algorithm for Ray Tracing") through a uniform grid:
//! the cells a ray crosses, in order, with the parameter interval of each. The majorant grids walk it
//! ([`super::majorant`]), and so does path guiding's grid of the direct light (`crate::guiding::lit`).

use crate::math::{Ray, Vec3};
use crate::vdb::floor_ivec3;
use glam::IVec3;

/// A uniform grid of cells over `origin + cell · [0, res)` in local space.
#[derive(Clone, Debug)]
pub(crate) struct UniformGrid {
    /// The corner of cell (0, 0, 0).
    pub(crate) origin: Vec3,
    /// A cell's edges.
    pub(crate) cell: Vec3,
    /// Cells per axis.
    pub(crate) res: IVec3,
}

impl UniformGrid {
    /// The index of cell `c` in a flat array of the cells, z fastest.
    pub(crate) fn index(&self, c: IVec3) -> usize {
        ((c.x * self.res.y + c.y) * self.res.z + c.z) as usize
    }

    /// The cell of [`Self::index`] `i`.
    pub(crate) fn coords(&self, i: usize) -> IVec3 {
        let i = i as i32;
        IVec3::new(
            i / (self.res.y * self.res.z),
            i / self.res.z % self.res.y,
            i % self.res.z,
        )
    }

    pub(crate) fn cells(&self) -> usize {
        self.cell_count() as usize
    }

    /// The number of cells, without overflow.
    pub(crate) fn cell_count(&self) -> u64 {
        self.res.x as u64 * self.res.y as u64 * self.res.z as u64
    }

    /// Raises `values` of the cells `a..=b` (clamped to the grid) to at least `v`.
    pub(crate) fn raise(&self, values: &mut [f32], a: IVec3, b: IVec3, v: f32) {
        let (a, b) = (a.max(IVec3::ZERO), b.min(self.res - 1));
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    let m = &mut values[self.index(IVec3::new(x, y, z))];
                    *m = m.max(v);
                }
            }
        }
    }
}

/// A 3D DDA through a [`UniformGrid`] (Amanatides & Woo 1987): per axis, the parameter of the next cell
/// boundary `t_next` and the parameter step per cell `t_delta`; each step advances the axis with the smallest
/// `t_next`. Plain arrays: indexing glam vectors by a runtime axis compiles to a branch per access.
///
/// `t_next` is the first boundary's parameter plus the steps taken times `t_delta` (one rounding), not a
/// running sum: summed, the round-off of hundreds of steps moved the boundaries by 1/200 of a cell.
#[derive(Clone, Debug)]
pub(crate) struct Dda {
    cell: [i32; 3],
    t_next: [f32; 3],
    /// Per axis, the parameter of the first boundary crossed.
    t_first: [f32; 3],
    /// Per axis, the boundaries crossed so far.
    steps: [f32; 3],
    t_delta: [f32; 3],
    step: [i32; 3],
    res: [i32; 3],
    /// Parameter where the current cell is entered.
    t: f32,
    /// End of the walk.
    t_end: f32,
    done: bool,
}

impl Dda {
    /// A walk that visits nothing.
    pub(crate) const EMPTY: Dda = Dda {
        cell: [0; 3],
        t_next: [0.0; 3],
        t_first: [0.0; 3],
        steps: [0.0; 3],
        t_delta: [0.0; 3],
        step: [0; 3],
        res: [0; 3],
        t: 0.0,
        t_end: 0.0,
        done: true,
    };

    /// Walks the cells of `grid` pierced by `ray` over `[t0, t1]`, clipped to the grid.
    pub(crate) fn clipped(grid: &UniformGrid, ray: &Ray, inv_dir: Vec3, t0: f32, t1: f32) -> Self {
        let ta = (grid.origin - ray.origin) * inv_dir;
        let tb = (grid.origin + grid.cell * grid.res.as_vec3() - ray.origin) * inv_dir;
        let t0 = ta.min(tb).max_element().max(t0);
        let t1 = ta.max(tb).min_element().min(t1);
        if t0 < t1 {
            Self::inside(grid, ray, inv_dir, t0, t1)
        } else {
            Self::EMPTY
        }
    }

    /// Walks the cells of `grid` pierced by `ray` over `[ta, tb]`, known to lie in the grid up to round-off.
    pub(crate) fn inside(grid: &UniformGrid, ray: &Ray, inv_dir: Vec3, ta: f32, tb: f32) -> Self {
        // Start from the cell of the interval's entry point (clamped inside against round-off).
        let c =
            floor_ivec3((ray.at(ta) - grid.origin) / grid.cell).clamp(IVec3::ZERO, grid.res - 1);
        let flat = ray.dir.cmpeq(Vec3::ZERO);
        let up = ray.dir.cmpgt(Vec3::ZERO);
        let step = IVec3::select(up, IVec3::ONE, IVec3::NEG_ONE);
        let boundary =
            grid.origin + (c + IVec3::select(up, IVec3::ONE, IVec3::ZERO)).as_vec3() * grid.cell;
        let t_next = Vec3::select(flat, Vec3::INFINITY, (boundary - ray.origin) * inv_dir);
        let t_delta = Vec3::select(flat, Vec3::INFINITY, grid.cell * inv_dir.abs());
        Self {
            cell: c.to_array(),
            t_next: t_next.to_array(),
            t_first: t_next.to_array(),
            steps: [0.0; 3],
            t_delta: t_delta.to_array(),
            step: step.to_array(),
            res: grid.res.to_array(),
            t: ta,
            t_end: tb,
            done: false,
        }
    }

    /// The next cell of non-zero length and its parameter interval, adding every cell stepped through to
    /// `cells`; `None` once the walk has left the interval or the grid.
    #[inline]
    pub(crate) fn next(&mut self, cells: &mut u64) -> Option<(IVec3, f32, f32)> {
        while !self.done {
            *cells += 1;
            let t = &self.t_next;
            let a = if t[0] <= t[1] && t[0] <= t[2] {
                0
            } else if t[1] <= t[2] {
                1
            } else {
                2
            };
            let cell = self.cell;
            let (t0, t1) = (self.t, self.t_next[a].min(self.t_end));
            if t1 >= self.t_end {
                self.done = true;
            } else {
                self.t = t1;
                self.cell[a] += self.step[a];
                self.done = self.cell[a] < 0 || self.cell[a] >= self.res[a];
                self.steps[a] += 1.0;
                self.t_next[a] = self.t_first[a] + self.steps[a] * self.t_delta[a];
            }
            if t1 > t0 {
                return Some((IVec3::from_array(cell), t0, t1));
            }
        }
        None
    }
}
