//! Surface geometry: world-space triangle meshes, the watertight ray–triangle test, the bounding volume
//! hierarchies over static and moving triangles, and the robust spawning of rays off surfaces.

mod bvh;
mod mesh;
mod motion;
mod spawn;
mod subdivision;
mod tags;
mod tangents;
mod triangle;

pub use bvh::{Bvh, TooManyTriangles, TriangleHierarchy};
pub use mesh::{Mesh, MeshMotion};
pub use motion::{lerp, MotionBvh, MotionSteps, MovingTriangle};
pub use spawn::{ShadowSegment, SurfacePoint};
pub use subdivision::{
    BoundaryRule, CreaseMethod, FaceVaryingRule, PolygonMesh, Scheme, SubdivisionError,
    SubdivisionRules, INFINITELY_SHARP,
};
pub use tags::CompositingTags;
pub use triangle::TriangleHit;
