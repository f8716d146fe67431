//! Surface geometry: world-space triangle meshes, the watertight ray–triangle test and the bounding volume
//! hierarchy over all triangles.

pub mod bvh;
pub mod mesh;
pub mod triangle;

pub use bvh::Bvh;
pub use mesh::Mesh;
pub use triangle::TriangleHit;
