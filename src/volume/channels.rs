//! Production pyro channels of a grid medium, beside its density (`nimbus_volume` keys):
//! - `flame_grid`: emission intensity; L_e += `flame_scale` · flame(x) · colour, the colour `flame_color`, or
//!   else the normalised blackbody of `flame_temperature` Kelvin;
//! - `color_grid` (Houdini's `Cd`) and `albedo_grid`: spatially varying single-scattering albedo, each a
//!   scalar or vec3 grid, multiplying `albedo`: albedo(x) = albedo · albedo_grid(x) · color_grid(x), clamped
//!   to \[0, 1\].
//!
//! Each is looked up trilinearly (OpenVDB BoxSampler) in its own index space, placed by the same node matrix
//! as the density. Emission follows the medium's convention, σ_a · L_e (pbrt-v4's for grid media), so a
//! flame shows where its density absorbs.

use super::error::DensityError;
use crate::math::{Mat4, Rgb, Vec3};
use crate::vdb::{Grid, GridTree};
use glam::DMat4;
use std::sync::Arc;

/// A scalar or vec3 grid placed in the scene, read as a colour (a scalar as grey).
#[derive(Clone, Debug)]
pub struct ChannelGrid {
    tree: Arc<GridTree>,
    world_to_index: Mat4,
}

impl ChannelGrid {
    /// Places `grid` under the node matrix `node_to_world`. Errors when the placement is not invertible or a
    /// value is not finite.
    pub fn new(grid: &Grid, node_to_world: DMat4) -> Result<Self, DensityError> {
        let world_to_index = (node_to_world * grid.index_to_world).inverse();
        if !world_to_index.is_finite() {
            return Err(DensityError::Placement(
                "the grid's transform (VDB transform times node matrix) is not invertible".into(),
            ));
        }
        if !grid.tree.is_finite() {
            return Err(DensityError::Placement(
                "the grid holds a NaN or infinite value".into(),
            ));
        }
        Ok(Self {
            tree: grid.tree.clone(),
            world_to_index: world_to_index.as_mat4(),
        })
    }

    /// Whether the grid holds vectors (colours) rather than scalars.
    #[cfg(test)]
    pub fn is_vector(&self) -> bool {
        self.tree.as_vec3().is_some()
    }

    /// The value at world point `p`: a vec3 grid's (x, y, z) as (r, g, b), a scalar grid's as grey.
    #[inline]
    pub fn rgb(&self, p: Vec3) -> Rgb {
        let q = self.world_to_index.transform_point3(p);
        match &*self.tree {
            GridTree::Float(t) => Rgb::splat(t.sample_trilinear(q)),
            GridTree::Vec3(t) => t.sample_trilinear(q),
        }
    }

    /// The value at world point `p` of a scalar grid (a vec3 grid's mean component).
    #[inline]
    pub fn scalar(&self, p: Vec3) -> f32 {
        let q = self.world_to_index.transform_point3(p);
        match &*self.tree {
            GridTree::Float(t) => t.sample_trilinear(q),
            GridTree::Vec3(t) => t.sample_trilinear(q).element_sum() / 3.0,
        }
    }

    /// Bytes held by the grid's tree.
    pub fn memory_bytes(&self) -> usize {
        self.tree.memory_bytes()
    }
}

/// Flame emission: intensity from a grid times a colour.
#[derive(Clone, Debug)]
pub struct Flame {
    /// The intensity grid.
    pub grid: ChannelGrid,
    /// `flame_scale` times the colour.
    pub radiance: Rgb,
}

impl Flame {
    /// Emitted radiance at world point `p` (never negative).
    #[inline]
    pub fn radiance_at(&self, p: Vec3) -> Rgb {
        self.radiance * self.grid.scalar(p).max(0.0)
    }
}

/// The spatially varying albedo factors (`albedo_grid`, `color_grid`).
#[derive(Clone, Debug, Default)]
pub struct AlbedoGrids {
    /// The grids whose values multiply the constant albedo.
    pub factors: Vec<ChannelGrid>,
}

impl AlbedoGrids {
    /// `albedo` times every factor at world point `p`, clamped to \[0, 1\].
    #[inline]
    pub fn albedo_at(&self, albedo: Rgb, p: Vec3) -> Rgb {
        self.factors
            .iter()
            .fold(albedo, |a, g| a * g.rgb(p))
            .clamp(Rgb::ZERO, Rgb::ONE)
    }

    /// Bytes held by the grids.
    pub fn memory_bytes(&self) -> usize {
        self.factors.iter().map(ChannelGrid::memory_bytes).sum()
    }
}
