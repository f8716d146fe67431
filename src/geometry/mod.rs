//! Geometry: world-space triangle meshes and the BVH that intersects rays with them.

pub mod bvh;
pub mod mesh;

pub use bvh::{Bvh, TriangleHit};
pub use mesh::Mesh;
