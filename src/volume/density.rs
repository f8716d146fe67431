//! Extinction fields for heterogeneous media: a sparse VDB grid placed in the scene ([`GridDensity`]) and
//! closed-form fields for tests and benchmarks ([`AnalyticDensity`]).
//!
//! Every field is evaluated in its own *local* space, reached from world space by an affine matrix
//! ([`DensityField::world_to_local`]). A ray mapped by that matrix without renormalising its direction keeps
//! the same parameter `t`, so tracking can run entirely in local (for grids: index) space.

use super::error::DensityError;
use crate::math::{Aabb, Mat4, Ray, Vec3};
use crate::vdb::{FloatTree, Grid, GridTree, Region};
use glam::{DMat4, IVec3};
use std::sync::Arc;

/// Lookups of a field along one tracking walk: the state may keep what the last lookup found (a grid's tree
/// nodes around it), since consecutive tentative collisions along a ray mostly fall in the same leaf.
pub trait DensityLookup {
    /// σ_t at local point `p`, exactly [`DensityField::density_local`].
    fn density_local(&mut self, p: Vec3) -> f32;

    /// (min, max) of σ_t over the voxel cell `[cell, cell + 1)³` of local space, for fields that are trilinear
    /// over voxels of unit edge there: the density in the cell is a convex combination of the eight voxels
    /// `cell + {0, 1}³`, so their smallest and largest values bound it exactly. `None` for fields that are not
    /// voxels (the default).
    fn cell_bounds(&mut self, _cell: IVec3) -> Option<(f32, f32)> {
        None
    }
}

/// Lookups of a closed-form field, which keep nothing between calls.
pub struct Stateless<'a, F: ?Sized>(pub &'a F);

impl<F: DensityField + ?Sized> DensityLookup for Stateless<'_, F> {
    #[inline]
    fn density_local(&mut self, p: Vec3) -> f32 {
        self.0.density_local(p)
    }
}

/// A scalar extinction field σ_t (per metre, already scaled) that tracking estimators can query.
pub trait DensityField: Send + Sync {
    /// The lookup state one tracking walk keeps.
    type Lookup<'a>: DensityLookup
    where
        Self: 'a;
    /// A fresh lookup state for one walk.
    fn lookup(&self) -> Self::Lookup<'_>;
    /// World-space extinction σ_t (per metre) at world point `p`; never negative.
    fn density(&self, p: Vec3) -> f32;
    /// Conservative world bounds of the region where σ_t may be non-zero.
    fn bounds(&self) -> Aabb;
    /// Affine map from world space to the field's local space (index space for grids).
    fn world_to_local(&self) -> Mat4 {
        Mat4::IDENTITY
    }
    /// σ_t (per world metre) at a point given in local space; equals `density(local_to_world(p))`.
    fn density_local(&self, p: Vec3) -> f32 {
        self.density(p)
    }
    /// Conservative local-space bounds of the region where σ_t may be non-zero.
    fn local_bounds(&self) -> Aabb {
        self.bounds().transformed(&self.world_to_local())
    }
}

/// Maps a world ray to the local space of `field`, keeping the ray parameter (the direction is not renormalised).
pub fn local_ray<F: DensityField + ?Sized>(field: &F, ray: &Ray) -> Ray {
    let m = field.world_to_local();
    Ray::new(m.transform_point3(ray.origin), m.transform_vector3(ray.dir)).at_time(ray.time)
}

/// A density grid from a VDB file placed in the scene: σ_t(x) = `density_scale` · trilinear(world_to_index(x)).
///
/// Placement: index space → the VDB's own `index_to_world` → the node's world matrix. The tree is shared
/// (an `Arc`), never copied. Negative stored values are clamped to zero (σ_t is non-negative).
#[derive(Clone, Debug)]
pub struct GridDensity {
    tree: Arc<GridTree>,
    index_to_world: Mat4,
    world_to_index: Mat4,
    scale: f32,
    index_bounds: Aabb,
    bad_values: BadValues,
}

/// The largest optical depth one voxel may have, along its longest edge: denser stored values are clamped to it
/// when the field is built (and counted in [`BadValues::too_dense`]). A voxel at this limit passes
/// e^-1000 of the light, which no film can tell from zero, while a far larger value (a corrupt 2.5e21, or a
/// node scaled by 1e38) would give majorants so large that tracking takes practically endless steps.
pub const MAX_VOXEL_OPTICAL_DEPTH: f32 = 1000.0;

/// The largest index coordinate (in voxels, either sign) a density grid may hold data at: 2^24, beyond which
/// single-precision index coordinates cannot tell neighbouring voxels apart.
pub const MAX_INDEX_COORD: i32 = 1 << 24;

/// The largest world coordinate (metres, either sign) the placed grid's bounds may reach.
pub const MAX_WORLD_COORD: f64 = 1e15;

/// Stored values a density grid cannot use as they are: NaN, infinite and negative ones are replaced by zero,
/// too dense ones clamped, when the field is built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BadValues {
    /// NaN voxels and tiles.
    pub nan: u64,
    /// Infinite voxels and tiles.
    pub infinite: u64,
    /// Negative voxels and tiles.
    pub negative: u64,
    /// Voxels and tiles denser than [`MAX_VOXEL_OPTICAL_DEPTH`] per voxel, clamped to it.
    pub too_dense: u64,
}

impl BadValues {
    /// Total number of replaced or clamped values.
    #[cfg(any(test, feature = "testing"))]
    pub fn total(&self) -> u64 {
        self.nan + self.infinite + self.negative + self.too_dense
    }

    /// Adds `other`'s counts.
    pub fn add(&mut self, other: &BadValues) {
        self.nan += other.nan;
        self.infinite += other.infinite;
        self.negative += other.negative;
        self.too_dense += other.too_dense;
    }

    fn check(&mut self, v: &mut f32, cap: f32) {
        if v.is_nan() {
            self.nan += 1;
        } else if v.is_infinite() {
            self.infinite += 1;
        } else if *v < 0.0 {
            self.negative += 1;
        } else if *v > cap {
            self.too_dense += 1;
            *v = cap;
            return;
        } else {
            return;
        }
        *v = 0.0;
    }
}

/// Replaces NaN, infinite and negative values (voxels and tiles, active or not) by zero, clamps values above
/// `cap` to it, and recomputes the node ranges, so majorants stay finite and tracking takes a bounded number
/// of steps. Returns what was changed; the tree is untouched when nothing was.
fn sanitize(tree: &FloatTree, cap: f32) -> Option<(FloatTree, BadValues)> {
    if !tree.any_value(|v| !v.is_finite() || v < 0.0 || v > cap) {
        return None;
    }
    let mut t = tree.clone();
    let mut counts = BadValues::default();
    t.update_values(|v| counts.check(v, cap));
    Some((t, counts))
}

/// The largest stored value a grid may keep: [`MAX_VOXEL_OPTICAL_DEPTH`] over (density scale × the longest
/// voxel edge in metres); infinite when either is zero.
fn density_cap(index_to_world: &DMat4, density_scale: f32) -> f32 {
    let edge = [
        index_to_world.x_axis,
        index_to_world.y_axis,
        index_to_world.z_axis,
    ]
    .iter()
    .map(|a| a.truncate().length())
    .fold(0.0f64, f64::max);
    let per_unit = density_scale as f64 * edge;
    if per_unit > 0.0 {
        (MAX_VOXEL_OPTICAL_DEPTH as f64 / per_unit).min(f32::MAX as f64) as f32
    } else {
        f32::INFINITY
    }
}

/// The leaves and tiles of `tree` whose values are not all zero, with the range of values a lookup inside each
/// can return.
pub(crate) fn nonzero_regions(tree: &FloatTree) -> impl Iterator<Item = Region<'_, f32>> {
    tree.regions().filter(|r| r.range() != (0.0, 0.0))
}

impl GridDensity {
    /// Places `grid` (a scalar grid) in the scene under the node matrix `node_to_world` (column-vector
    /// convention). Errors if the grid is not scalar or its background is not zero (a density grid's
    /// outside must be empty).
    pub fn new(
        grid: &Grid,
        node_to_world: DMat4,
        density_scale: f32,
    ) -> Result<Self, DensityError> {
        Self::from_tree(
            grid.tree.clone(),
            node_to_world * grid.index_to_world,
            density_scale,
        )
    }

    /// Places a scalar grid that is not an extinction (a temperature): like [`new`](Self::new) with scale 1,
    /// but values are not clamped to [`MAX_VOXEL_OPTICAL_DEPTH`].
    pub fn scalar(grid: &Grid, node_to_world: DMat4) -> Result<Self, DensityError> {
        Self::build(
            grid.tree.clone(),
            node_to_world * grid.index_to_world,
            1.0,
            f32::INFINITY,
        )
    }

    /// Builds the field from a shared tree and its full index-to-world matrix (column-vector convention).
    /// Values denser than [`MAX_VOXEL_OPTICAL_DEPTH`] per voxel are clamped to it.
    pub fn from_tree(
        tree: Arc<GridTree>,
        index_to_world: DMat4,
        density_scale: f32,
    ) -> Result<Self, DensityError> {
        let cap = density_cap(&index_to_world, density_scale);
        Self::build(tree, index_to_world, density_scale, cap)
    }

    /// The field, with stored values above `cap` clamped to it.
    fn build(
        tree: Arc<GridTree>,
        index_to_world: DMat4,
        density_scale: f32,
        cap: f32,
    ) -> Result<Self, DensityError> {
        let Some(t) = tree.as_float() else {
            return Err(DensityError::NotScalar);
        };
        if t.background() != 0.0 {
            return Err(DensityError::NonZeroBackground(t.background()));
        }
        if !(density_scale.is_finite() && density_scale >= 0.0) {
            return Err(DensityError::InvalidScale(density_scale));
        }
        let world_to_index = index_to_world.inverse();
        if !(index_to_world.is_finite()
            && world_to_index.is_finite()
            && index_to_world.determinant().abs() > 0.0)
        {
            return Err(DensityError::Placement(
                "the index-to-world transform (VDB transform times node matrix) is not finite and invertible"
                    .into(),
            ));
        }
        let (tree, bad_values) = match sanitize(t, cap) {
            Some((clean, counts)) => (Arc::new(GridTree::Float(clean)), counts),
            None => (tree, BadValues::default()),
        };
        let Some(t) = tree.as_float() else {
            return Err(DensityError::NotScalar);
        };
        // A trilinear lookup at x reads voxels floor(x) and floor(x) + 1, so a region [o, o + e) of voxels can
        // influence the continuous positions [o - 1, o + e).
        let mut b = Aabb::EMPTY;
        for r in t.regions().filter(|r| r.range().1 > 0.0) {
            let (o, e) = (r.origin(), r.edge());
            let reach = (o - 1).abs().max((o + e).abs()).max_element();
            if reach > MAX_INDEX_COORD {
                return Err(DensityError::IndexRange {
                    origin: o.to_array(),
                });
            }
            b = b.union(&Aabb::new((o - 1).as_vec3(), (o + e).as_vec3()));
        }
        if !b.is_empty() {
            let corners = (0..8).map(|i| {
                let pick = |bit: i32, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi } as f64;
                index_to_world.transform_point3(glam::DVec3::new(
                    pick(1, b.min.x, b.max.x),
                    pick(2, b.min.y, b.max.y),
                    pick(4, b.min.z, b.max.z),
                ))
            });
            let reach = corners.fold(0.0f64, |m, c| m.max(c.abs().max_element()));
            if reach.is_nan() || reach > MAX_WORLD_COORD {
                return Err(DensityError::Placement(format!(
                    "the placed grid reaches {reach:.3e} m from the origin, beyond the limit of {MAX_WORLD_COORD:.0e} m (check the node's scale)"
                )));
            }
        }
        Ok(Self {
            tree,
            index_to_world: index_to_world.as_mat4(),
            world_to_index: world_to_index.as_mat4(),
            scale: density_scale,
            index_bounds: b,
            bad_values,
        })
    }

    /// NaN, infinite and negative values found in the grid and replaced by zero.
    pub fn bad_values(&self) -> BadValues {
        self.bad_values
    }

    /// The scalar tree (shared with the VDB file).
    pub fn tree(&self) -> &FloatTree {
        match self.tree.as_float() {
            Some(t) => t,
            None => unreachable!("checked scalar in GridDensity::from_tree"),
        }
    }

    /// The world-to-index matrix (column-vector convention).
    pub fn world_to_index(&self) -> Mat4 {
        self.world_to_index
    }

    /// The index-to-world matrix (column-vector convention), node placement included.
    pub fn index_to_world(&self) -> Mat4 {
        self.index_to_world
    }

    /// The density scale applied to stored values.
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// Conservative index-space bounds of the non-zero region (continuous coordinates).
    pub fn index_bounds(&self) -> Aabb {
        self.index_bounds
    }

    /// σ_t at a continuous index-space position (OpenVDB BoxSampler convention), clamped to be non-negative.
    #[inline]
    pub fn density_index(&self, p_index: Vec3) -> f32 {
        (self.scale * self.tree().sample_trilinear(p_index)).max(0.0)
    }

    /// Bytes owned by this field, the shared tree included.
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.tree.memory_bytes()
    }
}

/// Lookups of a [`GridDensity`] through one tree accessor, whose cached nodes serve the next lookup.
pub struct GridLookup<'a> {
    accessor: crate::vdb::Accessor<'a, f32>,
    scale: f32,
}

impl DensityLookup for GridLookup<'_> {
    #[inline]
    fn density_local(&mut self, p: Vec3) -> f32 {
        (self.scale * self.accessor.sample_trilinear(p)).max(0.0)
    }

    #[inline]
    fn cell_bounds(&mut self, cell: IVec3) -> Option<(f32, f32)> {
        let v = self.accessor.corners(cell);
        let (lo, hi) = v[1..]
            .iter()
            .fold((v[0], v[0]), |(a, b), &x| (a.min(x), b.max(x)));
        Some(((self.scale * lo).max(0.0), (self.scale * hi).max(0.0)))
    }
}

impl DensityField for GridDensity {
    type Lookup<'a> = GridLookup<'a>;
    fn lookup(&self) -> GridLookup<'_> {
        GridLookup {
            accessor: self.tree().accessor(),
            scale: self.scale,
        }
    }
    fn density(&self, p: Vec3) -> f32 {
        self.density_index(self.world_to_index.transform_point3(p))
    }
    fn bounds(&self) -> Aabb {
        if self.index_bounds.is_empty() {
            return Aabb::EMPTY;
        }
        self.index_bounds.transformed(&self.index_to_world)
    }
    fn world_to_local(&self) -> Mat4 {
        self.world_to_index
    }
    fn density_local(&self, p: Vec3) -> f32 {
        self.density_index(p)
    }
    fn local_bounds(&self) -> Aabb {
        self.index_bounds
    }
}

/// Closed-form extinction fields inside an axis-aligned box (zero outside), for tests and benchmarks.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg(test)]
pub enum AnalyticDensity {
    /// σ_t = `sigma` inside `bounds`.
    Constant {
        /// The box.
        bounds: Aabb,
        /// Extinction per metre.
        sigma: f32,
    },
    /// σ_t rises linearly from `sigma0` at `bounds.min[axis]` to `sigma1` at `bounds.max[axis]`.
    Ramp {
        /// The box.
        bounds: Aabb,
        /// Axis index (0, 1 or 2).
        axis: usize,
        /// Extinction at the low face.
        sigma0: f32,
        /// Extinction at the high face.
        sigma1: f32,
    },
    /// σ_t = `sigma0` · exp(−`falloff` · (x[axis] − `bounds.min[axis]`)).
    Exponential {
        /// The box.
        bounds: Aabb,
        /// Axis index (0, 1 or 2).
        axis: usize,
        /// Extinction at the low face.
        sigma0: f32,
        /// Falloff rate per metre (non-negative).
        falloff: f32,
    },
}

#[cfg(test)]
impl AnalyticDensity {
    fn aabb(&self) -> Aabb {
        match *self {
            Self::Constant { bounds, .. }
            | Self::Ramp { bounds, .. }
            | Self::Exponential { bounds, .. } => bounds,
        }
    }

    /// (minimum, maximum) of σ_t over the box.
    pub fn range(&self) -> (f32, f32) {
        match *self {
            Self::Constant { sigma, .. } => (sigma, sigma),
            Self::Ramp { sigma0, sigma1, .. } => (sigma0.min(sigma1), sigma0.max(sigma1)),
            Self::Exponential {
                bounds,
                axis,
                sigma0,
                falloff,
            } => (sigma0 * (-falloff * bounds.extent()[axis]).exp(), sigma0),
        }
    }

    /// Closed-form optical depth τ = ∫ σ_t(o + t d) |d| dt over `[t0, t1]` (the box clips the interval).
    pub fn optical_depth(&self, ray: &Ray, t0: f32, t1: f32) -> f64 {
        let Some((a, b)) = self.aabb().intersect(ray, t0, t1) else {
            return 0.0;
        };
        let (a, b) = (a as f64, b as f64);
        let len = ray.dir.as_dvec3().length();
        match *self {
            Self::Constant { sigma, .. } => sigma as f64 * (b - a) * len,
            Self::Ramp {
                bounds,
                axis,
                sigma0,
                sigma1,
            } => {
                // σ(t) = s0 + k (o + d t − min): linear in t, integrated exactly.
                let k = (sigma1 as f64 - sigma0 as f64) / bounds.extent()[axis] as f64;
                let c = sigma0 as f64 + k * (ray.origin[axis] as f64 - bounds.min[axis] as f64);
                let g = k * ray.dir[axis] as f64;
                len * (c * (b - a) + 0.5 * g * (b * b - a * a))
            }
            Self::Exponential {
                bounds,
                axis,
                sigma0,
                falloff,
            } => {
                let k = falloff as f64;
                let c = sigma0 as f64
                    * (-k * (ray.origin[axis] as f64 - bounds.min[axis] as f64)).exp();
                let g = k * ray.dir[axis] as f64;
                if g.abs() < 1e-12 {
                    len * c * (b - a)
                } else {
                    len * c * ((-g * a).exp() - (-g * b).exp()) / g
                }
            }
        }
    }
}

#[cfg(test)]
impl DensityField for AnalyticDensity {
    type Lookup<'a> = Stateless<'a, Self>;
    fn lookup(&self) -> Stateless<'_, Self> {
        Stateless(self)
    }
    fn density(&self, p: Vec3) -> f32 {
        let bounds = self.aabb();
        if !bounds.contains(p) {
            return 0.0;
        }
        match *self {
            Self::Constant { sigma, .. } => sigma,
            Self::Ramp {
                axis,
                sigma0,
                sigma1,
                ..
            } => {
                let u = (p[axis] - bounds.min[axis]) / bounds.extent()[axis];
                sigma0 + (sigma1 - sigma0) * u
            }
            Self::Exponential {
                axis,
                sigma0,
                falloff,
                ..
            } => sigma0 * (-falloff * (p[axis] - bounds.min[axis])).exp(),
        }
    }
    fn bounds(&self) -> Aabb {
        self.aabb()
    }
}

/// Test fields shared by the volume tests.
#[cfg(test)]
pub(crate) mod test_fields {
    use super::*;
    use crate::vdb::Tree;
    use glam::IVec3;

    /// A 40³ sphere of radius 16 voxels with a smooth falloff and an empty slab gap at x ∈ [18, 22), offset so
    /// that it straddles leaf, lower-node and sign boundaries; voxel size 0.05 m, rotated and translated.
    pub fn sphere_grid(density_scale: f32) -> GridDensity {
        let off = IVec3::new(100, -20, 60);
        let mut v = Vec::new();
        for x in 0..40 {
            for y in 0..40 {
                for z in 0..40 {
                    let r = (Vec3::new(x as f32, y as f32, z as f32) - Vec3::splat(19.5)).length();
                    let d = (1.0 - r / 16.0).max(0.0);
                    if d > 0.0 && !(18..22).contains(&x) {
                        v.push((off + IVec3::new(x, y, z), d * d * (3.0 - 2.0 * d)));
                    }
                }
            }
        }
        let tree = Tree::from_voxels(0.0, v);
        let m = DMat4::from_translation(glam::DVec3::new(1.0, -2.0, 0.5))
            * DMat4::from_rotation_y(0.3)
            * DMat4::from_scale(glam::DVec3::splat(0.05))
            * DMat4::from_translation(-(off.as_dvec3() + 20.0));
        GridDensity::from_tree(Arc::new(GridTree::Float(tree)), m, density_scale).unwrap()
    }

    /// A constant `n`³ block of voxels of value 1 at index origin `(5, 3, 250)`, voxel size `vs`, translated.
    pub fn block_grid(n: i32, vs: f64, density_scale: f32) -> GridDensity {
        let o = IVec3::new(5, 3, 250);
        let mut v = Vec::new();
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    v.push((o + IVec3::new(x, y, z), 1.0));
                }
            }
        }
        let tree = Tree::from_voxels(0.0, v);
        let m = DMat4::from_translation(glam::DVec3::new(-1.0, 0.0, 2.0))
            * DMat4::from_scale(glam::DVec3::splat(vs))
            * DMat4::from_translation(-o.as_dvec3());
        GridDensity::from_tree(Arc::new(GridTree::Float(tree)), m, density_scale).unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::test_fields::*;
    use super::*;

    #[test]
    fn grid_density_places_and_scales() {
        let g = block_grid(10, 0.1, 3.0);
        // Index (5+4, 3+4, 250+4) maps to world (-1, 0, 2) + 0.4.
        let p = Vec3::new(-0.6, 0.4, 2.4);
        assert!((g.density(p) - 3.0).abs() < 1e-4);
        assert_eq!(g.density(Vec3::new(5.0, 5.0, 5.0)), 0.0);
        let b = g.bounds();
        // Conservative: covers the trilinear support [-1.1, 0.0] on x (leaf-granular).
        assert!(b.contains(p) && b.min.x <= -1.1 + 1e-4 && b.max.x >= -1e-4 && b.max.x < 0.2);
        assert!(g.memory_bytes() > g.tree().stats().leaves as usize * 2048);
    }

    #[test]
    fn analytic_optical_depth_matches_quadrature() {
        let bounds = Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(2.0, 1.0, 1.0));
        let ray = Ray::new(Vec3::new(-3.0, -0.2, 0.1), Vec3::new(2.0, 0.3, -0.1));
        for f in [
            AnalyticDensity::Constant { bounds, sigma: 2.0 },
            AnalyticDensity::Ramp {
                bounds,
                axis: 0,
                sigma0: 0.5,
                sigma1: 4.0,
            },
            AnalyticDensity::Exponential {
                bounds,
                axis: 0,
                sigma0: 5.0,
                falloff: 1.3,
            },
        ] {
            let a = f.optical_depth(&ray, 0.0, 10.0);
            let q = crate::volume::tracking::optical_depth_quadrature(&f, &ray, 0.0, 10.0, 200_000);
            assert!((a - q).abs() < 1e-3 * a, "{f:?}: {a} vs {q}");
        }
    }
}
