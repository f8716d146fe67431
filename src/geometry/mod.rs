//! Surface geometry: world-space triangle meshes, the watertight ray–triangle test, the bounding volume
//! hierarchy over all triangles, and the robust spawning of rays off surfaces.

mod bvh;
mod mesh;
mod spawn;
mod tangents;
mod triangle;

pub use bvh::{Bvh, TooManyTriangles};
pub use mesh::Mesh;
pub use spawn::{ShadowSegment, SurfacePoint};
pub use triangle::TriangleHit;
