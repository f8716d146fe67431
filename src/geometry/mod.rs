//! Surface geometry: triangles and the bounding volume hierarchy over them.

pub mod bvh;
pub mod triangle;

pub use bvh::Bvh;
pub use triangle::TriangleHit;
