//! The scene model (surfaces, materials, textures, lights, camera) and its loaders.
//!
//! Loaders fill a [`SceneBuilder`]; [`SceneBuilder::build`] flattens the meshes into one BVH (moving ones into a
//! motion BVH, instances of prototypes into a two-level one), turns emissive triangles into area lights and
//! builds the light-selection distribution.

mod build;
mod builder;
mod camera;
mod error;
#[cfg(feature = "testing")]
pub mod gltf;
#[cfg(not(feature = "testing"))]
pub(crate) mod gltf;
mod hit;
mod instancing;
mod model;
mod names;
#[cfg(feature = "testing")]
pub mod obj;
#[cfg(not(feature = "testing"))]
pub(crate) mod obj;
mod options;
mod own_lighting;
#[cfg(feature = "testing")]
pub mod usd;
#[cfg(not(feature = "testing"))]
pub(crate) mod usd;
mod validate;
internal! {
    pub use builder::BUILDER_PATH;
    pub use camera::{blender_focal_length, CameraMotion, CAMERA_KEYS};
    pub use hit::SurfaceHit;
    pub use instancing::{MeshInstance, BYTES_PER_INSTANCE};
    pub use names::{Emitter, LightTag, MediumTag, SceneNames, ENVIRONMENT_NAME};
}
pub use builder::SceneBuilder;
pub use camera::{Camera, LensError, NamedCamera, Projection, ThinLens, UnknownCamera};
pub use model::Scene;
#[cfg(feature = "testing")]
pub use names::CryptoNames;
pub use options::{LoadOptions, VolumeOverride};
pub use own_lighting::{OwnLighting, DEFAULT_ENVIRONMENT_RADIANCE};

pub use crate::volume::{DensityError, MissingFrame, VolumeError};
pub use error::{MalformedError, MalformedPart, SceneError, SceneErrorKind};

pub(crate) use build::bounding_radius;
pub(crate) use options::report_unknown_keys;

use crate::geometry::Mesh;
use std::path::Path;

internal! {
    /// Bytes one triangle of a scene is counted at against the memory budget: its three indices and what
    /// [`SceneBuilder::build`] makes of it (the flattened triangle, its BVH copy, build references, nodes and
    /// per-triangle tables: about 150 bytes), rounded up.
    pub const BYTES_PER_TRIANGLE: u64 = 192;
}

internal! {
    /// Bytes one mesh vertex is counted at against the memory budget, once for the mesh and once for each motion
    /// step: position, normal, two texture-coordinate sets and a tangent (56 bytes), rounded up.
    pub const BYTES_PER_VERTEX: u64 = 64;
}

/// The bytes `triangles` and `vertices` are counted at ([`BYTES_PER_TRIANGLE`], [`BYTES_PER_VERTEX`]).
fn mesh_bytes(triangles: u64, vertices: u64) -> u64 {
    triangles
        .saturating_mul(BYTES_PER_TRIANGLE)
        .saturating_add(vertices.saturating_mul(BYTES_PER_VERTEX))
}

/// The triangles and vertices `mesh` is counted with: its vertices once, and again at each motion step.
fn mesh_counts(mesh: &Mesh) -> (u64, u64) {
    let steps = mesh.motion.as_ref().map_or(0, |m| m.positions.len() as u64);
    let vertices = mesh.positions.len() as u64;
    (
        mesh.indices.len() as u64,
        vertices.saturating_mul(1 + steps),
    )
}
/// Reads glTF or GLB bytes into a builder, like [`load_builder`] reads a file: `path` names the file in errors
/// and its folder resolves external URIs (the CLI's bundled demo scene, with its VDB in
/// [`LoadOptions::embedded`]).
pub fn load_gltf_slice(
    bytes: &[u8],
    path: &Path,
    options: &LoadOptions,
) -> Result<SceneBuilder, SceneError> {
    gltf::load_slice(bytes, path, options)
}

/// Reads a scene file into a builder (to be adjusted, then built), choosing the loader by extension.
pub fn load_builder(path: &Path, options: &LoadOptions) -> Result<SceneBuilder, SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let mut builder = match ext.as_deref() {
        Some("gltf") | Some("glb") => gltf::load(path, options),
        Some("obj" | "usd" | "usda" | "usdc" | "usdz") if options.variant.is_some() => {
            Err(SceneError::new(
                path,
                SceneErrorKind::Unsupported(
                    "material variants are read from glTF files (KHR_materials_variants) only"
                        .into(),
                ),
            ))
        }
        Some("obj") => obj::load(path, options),
        Some("usd") | Some("usda") | Some("usdc") | Some("usdz") => usd::load(path, options),
        _ => Err(SceneError::new(path, SceneErrorKind::UnknownFormat)),
    }?;
    builder.set_shutter(options.shutter);
    Ok(builder)
}
