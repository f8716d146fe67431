//! Surface geometry: world-space triangle meshes, instances of object-space ones (a two-level hierarchy), the watertight ray–triangle test, the bounding volume
//! hierarchies over static and moving triangles, and the robust spawning of rays off surfaces.

mod bvh;
mod instance;
mod mesh;
mod motion;
mod spawn;
mod subdivision;
mod tags;
mod tangents;
mod triangle;

#[cfg(feature = "testing")]
pub use bvh::TraversalCounts;
pub use bvh::{Bvh, TooManyTriangles, TriangleHierarchy};
pub use instance::{Instance, InstanceBvh};
pub use mesh::{Mesh, MeshMotion};
#[cfg(feature = "testing")]
pub use motion::{lerp, MovingTriangle};
pub use motion::{MotionBvh, MotionSteps};
pub use spawn::{ShadowSegment, SurfacePoint};
pub use subdivision::{
    BoundaryRule, CreaseMethod, FaceVaryingRule, PolygonMesh, Scheme, SubdivisionRules,
};
#[cfg(feature = "testing")]
pub use subdivision::{SubdivisionError, INFINITELY_SHARP};
pub use tags::CompositingTags;
pub use triangle::TriangleHit;
