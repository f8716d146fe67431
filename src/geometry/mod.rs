//! Surface geometry: world-space triangle meshes, the watertight ray–triangle test, the bounding volume
//! hierarchy over all triangles, and the robust spawning of rays off surfaces.

pub mod bvh;
pub mod mesh;
pub mod spawn;
pub mod triangle;

pub use bvh::{Bvh, TooManyTriangles};
pub use mesh::Mesh;
pub use spawn::{ShadowSegment, SurfacePoint};
pub use triangle::TriangleHit;
