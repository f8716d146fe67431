//! Velocity motion blur of grid media (`nimbus_volume` keys `velocity_grid`, `velocity_scale`).
//!
//! A simulation exports one velocity grid per frame (Houdini and Blender name it `vel`: a vec3 grid, or the
//! scalar grids `vel.x`, `vel.y`, `vel.z`), in the VDB's world units per second. Blur is Eulerian, as in
//! production renderers: at time τ seconds from the frame, the density (and every other channel) at x is the
//! frame's value at x − s·v(x)·τ, with s = `velocity_scale`. Velocities are read at voxel centres (a staggered
//! grid's half-voxel offset is not applied) and taken as vectors in the VDB's world space, which the volume's
//! node matrix then turns with the grid.
//!
//! Tracking stays unbiased because the majorants are built over the field dilated by the largest displacement
//! the shutter allows ([`super::majorant::Majorants::build_reaching`]): per axis of the density's index space,
//! the reach is Σⱼ |Mᵢⱼ| · max|vⱼ| · s · max(|open|, |close|) / fps, with M the VDB's world-to-index linear map.
//! A lookup above its majorant would still be counted in `majorant_violations`.

use super::density::{DensityField, DensityLookup, GridDensity, GridLookup};
use super::error::DensityError;
use crate::math::{Aabb, Mat3, Mat4, Vec3};
use crate::vdb::{Grid, GridTree, Tree, VoxelValue};
use glam::DMat4;
use std::sync::Arc;

/// The grids velocities are read from.
#[derive(Clone, Debug)]
enum Components {
    /// One vec3 grid.
    Vector(Arc<GridTree>),
    /// Three scalar grids (x, y, z) on one transform.
    Scalars([Arc<GridTree>; 3]),
}

/// A velocity field placed with a density grid: turns a point of the density's index space into its
/// displacement per second, in the same index space.
#[derive(Clone, Debug)]
pub struct VelocityField {
    components: Components,
    /// Density index space → velocity index space.
    density_index_to_velocity_index: Mat4,
    /// VDB world vectors → density index vectors (the density grid's own world-to-index linear part: the node
    /// matrix turns both alike and cancels).
    world_to_density_index: Mat3,
    /// Per axis of the density's index space, the largest displacement per second anywhere.
    reach_per_second: Vec3,
}

impl VelocityField {
    /// Places the velocity `grids` (one vec3 grid, or three scalar grids x, y, z sharing one transform) with
    /// `density`, the grid `density_grid` of the same file under the same node matrix. Errors when a grid has
    /// the wrong type, the three transforms differ, or a velocity is not finite.
    pub fn new(grids: &[&Grid], density_grid: &Grid) -> Result<Self, DensityError> {
        let components = match grids {
            [g] => match &*g.tree {
                GridTree::Vec3(_) => Components::Vector(g.tree.clone()),
                GridTree::Float(_) => {
                    return Err(DensityError::Placement(
                        "a velocity grid must hold vectors (or name the scalar grids vel.x, vel.y and vel.z)"
                            .into(),
                    ))
                }
            },
            [x, y, z] => {
                for g in [y, z] {
                    if !g.index_to_world.abs_diff_eq(x.index_to_world, 1e-9) {
                        return Err(DensityError::Placement(
                            "the velocity component grids must share one transform".into(),
                        ));
                    }
                }
                if [x, y, z].iter().any(|g| g.tree.as_float().is_none()) {
                    return Err(DensityError::Placement(
                        "a velocity component grid must be scalar".into(),
                    ));
                }
                Components::Scalars([x.tree.clone(), y.tree.clone(), z.tree.clone()])
            }
            _ => {
                return Err(DensityError::Placement(
                    "velocity needs one vec3 grid or three scalar grids".into(),
                ))
            }
        };
        if !grids.iter().all(|g| g.tree.is_finite()) {
            return Err(DensityError::Placement(
                "the velocity grid holds a NaN or infinite value".into(),
            ));
        }
        let velocity_index_to_world = grids[0].index_to_world;
        let density_index_to_velocity_index: DMat4 =
            velocity_index_to_world.inverse() * density_grid.index_to_world;
        let world_to_density_index = glam::DMat3::from_mat4(density_grid.index_to_world).inverse();
        if !(density_index_to_velocity_index.is_finite() && world_to_density_index.is_finite()) {
            return Err(DensityError::Placement(
                "the velocity grid's transform is not invertible".into(),
            ));
        }
        let world_to_density_index = world_to_density_index.as_mat3();
        let largest = match &components {
            Components::Vector(t) => t.as_vec3().map_or(Vec3::ZERO, largest_abs),
            Components::Scalars(ts) => {
                Vec3::from_array(ts.each_ref().map(|t| t.as_float().map_or(0.0, largest_abs)))
            }
        };
        let m = world_to_density_index;
        let abs = Mat3::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        Ok(Self {
            components,
            density_index_to_velocity_index: density_index_to_velocity_index.as_mat4(),
            world_to_density_index,
            reach_per_second: abs * largest,
        })
    }

    /// The displacement per second at density index point `p`, in density index units.
    pub fn index_velocity(&self, p: Vec3) -> Vec3 {
        self.lookup().index_velocity(p)
    }

    /// Lookups that keep their tree accessors between calls.
    pub fn lookup(&self) -> VelocityLookup<'_> {
        let accessors = match &self.components {
            Components::Vector(t) => t.as_vec3().map(|t| VelocityAccessors::Vector(t.accessor())),
            Components::Scalars(ts) => match ts.each_ref().map(|t| t.as_float()) {
                [Some(x), Some(y), Some(z)] => Some(VelocityAccessors::Scalars([
                    x.accessor(),
                    y.accessor(),
                    z.accessor(),
                ])),
                _ => None,
            },
        };
        VelocityLookup {
            field: self,
            accessors,
        }
    }

    /// Per axis of the density's index space, the largest displacement `seconds` can bring (index units).
    pub fn reach(&self, seconds: f32) -> Vec3 {
        self.reach_per_second * seconds.abs()
    }

    /// Bytes held by the velocity trees.
    pub fn memory_bytes(&self) -> usize {
        match &self.components {
            Components::Vector(t) => t.memory_bytes(),
            Components::Scalars(ts) => ts.iter().map(|t| t.memory_bytes()).sum(),
        }
    }
}

/// Tree accessors of a velocity field's grids.
enum VelocityAccessors<'a> {
    Vector(crate::vdb::Accessor<'a, Vec3>),
    Scalars([crate::vdb::Accessor<'a, f32>; 3]),
}

/// Velocity lookups along one walk (their accessors' cached nodes serve the next lookup).
pub struct VelocityLookup<'a> {
    field: &'a VelocityField,
    /// `None` only for grids of the wrong type, which [`VelocityField::new`] refuses.
    accessors: Option<VelocityAccessors<'a>>,
}

impl VelocityLookup<'_> {
    /// The displacement per second at density index point `p`, in density index units.
    #[inline]
    pub fn index_velocity(&mut self, p: Vec3) -> Vec3 {
        let q = self
            .field
            .density_index_to_velocity_index
            .transform_point3(p);
        let v = match &mut self.accessors {
            Some(VelocityAccessors::Vector(a)) => a.sample_trilinear(q),
            Some(VelocityAccessors::Scalars(a)) => Vec3::new(
                a[0].sample_trilinear(q),
                a[1].sample_trilinear(q),
                a[2].sample_trilinear(q),
            ),
            None => Vec3::ZERO,
        };
        self.field.world_to_density_index * v
    }
}

/// The largest |value| (per component) a lookup can return, background included.
fn largest_abs<T: VoxelValue>(t: &Tree<T>) -> T {
    let abs = |v: T| v.max_of(v.neg());
    t.regions()
        .map(|r| {
            let (lo, hi) = r.range();
            abs(lo).max_of(abs(hi))
        })
        .fold(abs(t.background()), T::max_of)
}

/// A density field seen at `seconds` from its frame: σ_t at index point p is the frame's σ_t at
/// p − v(p)·seconds (velocity already scaled by `velocity_scale`).
pub struct Displaced<'a> {
    /// The frame's density.
    pub density: &'a GridDensity,
    /// Its velocity.
    pub velocity: &'a VelocityField,
    /// Seconds from the frame, times `velocity_scale`.
    pub seconds: f32,
}

impl Displaced<'_> {
    /// The frame-time index point whose value reaches index point `p` at this time.
    #[inline]
    pub fn source(&self, p: Vec3) -> Vec3 {
        p - self.velocity.index_velocity(p) * self.seconds
    }
}

/// Lookups of a [`Displaced`] field: the density's and the velocity's accessors.
pub struct DisplacedLookup<'a> {
    density: GridLookup<'a>,
    velocity: VelocityLookup<'a>,
    seconds: f32,
}

impl DensityLookup for DisplacedLookup<'_> {
    #[inline]
    fn density_local(&mut self, p: Vec3) -> f32 {
        let source = p - self.velocity.index_velocity(p) * self.seconds;
        self.density.density_local(source)
    }
}

impl DensityField for Displaced<'_> {
    type Lookup<'b>
        = DisplacedLookup<'b>
    where
        Self: 'b;
    fn lookup(&self) -> DisplacedLookup<'_> {
        DisplacedLookup {
            density: self.density.lookup(),
            velocity: self.velocity.lookup(),
            seconds: self.seconds,
        }
    }
    fn density(&self, p: Vec3) -> f32 {
        self.density_local(self.density.world_to_index().transform_point3(p))
    }
    fn bounds(&self) -> Aabb {
        self.local_bounds()
            .transformed(&self.density.index_to_world())
    }
    fn world_to_local(&self) -> Mat4 {
        self.density.world_to_index()
    }
    #[inline]
    fn density_local(&self, p: Vec3) -> f32 {
        self.density.density_index(self.source(p))
    }
    fn local_bounds(&self) -> Aabb {
        let b = self.density.index_bounds();
        if b.is_empty() {
            return b;
        }
        let reach = self.velocity.reach(self.seconds);
        Aabb::new(b.min - reach, b.max + reach)
    }
}
