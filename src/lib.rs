//! Nimbus: a production volumetric path tracer for glTF, OBJ and USD scenes with OpenVDB volumes.
//!
//! See `ARCHITECTURE.md` for the module map and `docs/embedding.md` for embedding Nimbus in an application,
//! from Rust or through the C API of the `nimbus-ffi` crate.
//!
//! # Embedding in three steps
//!
//! 1. Get a [`Scene`]: load a file with [`Scene::load`] (glTF `.gltf`/`.glb`, Wavefront `.obj`), or build one in
//!    code with a [`SceneBuilder`] (meshes, materials, lights, camera).
//! 2. Render it with a [`Renderer`] made from [`RenderSettings`]: [`Renderer::render`] reports [`Progress`]
//!    after every pass to a callback that returns `false` to stop, and [`Renderer::render_with_cancel`] also
//!    stops when a [`CancelToken`] is cancelled from any thread.
//! 3. Use the [`RenderImage`] (beauty and its alpha, the first-hit AOVs albedo, normal, depth and variance, and
//!    the compositing layers [`RenderSettings::aovs`] chooses: light paths, light groups, shadow catcher,
//!    Cryptomatte; see [`render::aovs`]) and the [`RenderStats`], or write the image with [`write_exr`]
//!    (multi-layer EXR; [`output::write_exr_with`] for half floats and other compressions) and
//!    [`write_png_preview`] (8-bit sRGB).
//!
//! A render can also be cut into parts, by sample range and crop window, rendered on a farm and merged bit for
//! bit: see [`farm`] and [`Renderer::render_region`].
//!
//! The public API is what these steps need (`docs/api.md` lists it, and `tests/public_api.txt` holds every public
//! item); the rest of the crate is internal.
//!
//! Nimbus keeps no global state: scenes, renderers and images are plain values, and every render builds its own
//! worker pool. Every fallible call returns a typed error; [`Error`] wraps them all for hosts that want one
//! `Result` type.
//!
//! # Example: a programmatic scene
//!
//! ```
//! use nimbus::math::{Rgb, Vec3};
//! use nimbus::{Camera, Material, RenderSettings, Renderer, SceneBuilder};
//!
//! # fn main() -> nimbus::Result<()> {
//! let mut builder = SceneBuilder::new();
//! let grey = builder.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
//! // A 2 m square floor at y = 0, facing up.
//! let floor = vec![
//!     Vec3::new(-1.0, 0.0, -1.0),
//!     Vec3::new(-1.0, 0.0, 1.0),
//!     Vec3::new(1.0, 0.0, 1.0),
//!     Vec3::new(1.0, 0.0, -1.0),
//! ];
//! builder.add_triangle_mesh(floor, vec![[0, 1, 2], [0, 2, 3]], grey)?;
//! builder.add_point_light(Vec3::new(0.0, 1.0, 0.0), Rgb::splat(2.0));
//! builder.set_camera(Camera::look_at(Vec3::new(0.0, 1.0, 2.0), Vec3::ZERO, 0.8));
//! let scene = builder.build()?; // checks every index the builder was given
//!
//! let settings = RenderSettings { width: 8, height: 8, spp: 1, ..RenderSettings::default() };
//! let (image, stats) = Renderer::new(settings).render(&scene, &mut |progress| {
//!     assert!(progress.fraction <= 1.0);
//!     true // keep going
//! })?;
//! assert_eq!((image.width, image.height), (8, 8));
//! assert_eq!(stats.samples_per_pixel, 1);
//! assert!(image.beauty.iter().all(|c| c.is_finite()));
//! assert!(image.beauty.iter().any(|c| c.max_element() > 0.0), "the lit floor shows");
//!
//! let exr = std::env::temp_dir().join(format!("nimbus-doc-{}.exr", std::process::id()));
//! nimbus::write_exr(&image, &exr)?;
//! nimbus::write_png_preview(&image, &exr.with_extension("png"), 0.0)?;
//! # std::fs::remove_file(&exr).ok();
//! # std::fs::remove_file(exr.with_extension("png")).ok();
//! # Ok(())
//! # }
//! ```
//!
//! # Example: cancelling from another thread
//!
//! ```
//! use nimbus::{CancelToken, RenderSettings, Renderer, SceneBuilder};
//!
//! let scene = SceneBuilder::new().build().expect("an empty scene is valid");
//! let token = CancelToken::new();
//! token.clone().cancel(); // e.g. from a UI thread
//! let settings = RenderSettings { width: 8, height: 8, spp: 4, ..RenderSettings::default() };
//! let (image, stats) = Renderer::new(settings)
//!     .render_with_cancel(&scene, &mut |_| true, &token)
//!     .expect("worker threads start");
//! assert!(stats.cancelled);
//! assert_eq!(stats.samples_per_pixel, 0);
//! assert_eq!(image.width, 8);
//! ```
//!
//! # Example: a file that does not load
//!
//! ```
//! let err = nimbus::Scene::load(std::path::Path::new("missing.glb")).err().unwrap();
//! let err = nimbus::Error::from(err);
//! assert!(err.to_string().contains("missing.glb"));
//! ```

// With the `testing` feature internal items are `pub`, and some of them use crate-private types: the check that
// every type in a signature can be named is for the API without the feature (CI's `--no-default-features` clippy).
#![cfg_attr(feature = "testing", allow(unnameable_types, private_interfaces))]

/// Declares internal items: `pub` with the `testing` feature, so that the crate's integration tests and benches
/// reach them (see `nimbus::testing` when it is on), and `pub(crate)` without it, so that they are not part of the
/// API an embedder sees. It takes any number of `pub use TREE;` items, or one other item. (Internal modules are
/// declared as a `#[cfg(feature = "testing")]` pair instead, which rustfmt follows into their files.)
macro_rules! internal {
    () => {};
    ($(#[$attr:meta])* pub use $($rest:tt)*) => {
        internal! { @use [$(#[$attr])*] [] $($rest)* }
    };
    (@use [$($attr:tt)*] [$($tree:tt)*] ; $($rest:tt)*) => {
        #[cfg(feature = "testing")]
        $($attr)*
        pub use $($tree)*;
        #[cfg(not(feature = "testing"))]
        $($attr)*
        pub(crate) use $($tree)*;
        internal! { $($rest)* }
    };
    (@use [$($attr:tt)*] [$($tree:tt)*] $next:tt $($rest:tt)*) => {
        internal! { @use [$($attr)*] [$($tree)* $next] $($rest)* }
    };
    ($(#[$attr:meta])* pub $($item:tt)*) => {
        #[cfg(feature = "testing")]
        $(#[$attr])*
        pub $($item)*
        #[cfg(not(feature = "testing"))]
        $(#[$attr])*
        pub(crate) $($item)*
    };
}

mod error;

pub mod converge;
#[cfg(feature = "denoise")]
pub mod denoise;
pub mod farm;
pub mod frames;
#[cfg(feature = "testing")]
pub mod geometry;
#[cfg(not(feature = "testing"))]
pub(crate) mod geometry;
#[cfg(feature = "testing")]
pub mod guiding;
#[cfg(not(feature = "testing"))]
pub(crate) mod guiding;
mod integrator;
pub mod light;
pub mod limits;
pub mod material;
pub mod math;
pub mod output;
pub mod params;
pub mod render;
pub mod scene;
#[cfg(feature = "testing")]
pub mod testing;
pub mod vdb;
#[cfg(feature = "testing")]
pub mod volume;
#[cfg(not(feature = "testing"))]
pub(crate) mod volume;

pub use error::{Error, Result};
pub use material::Material;
pub use output::{write_exr, write_png_preview, OutputError};
pub use render::{
    channel_names, CancelToken, Progress, RenderImage, RenderRegion, RenderSettings, RenderStats,
    Renderer,
};
pub use scene::{Camera, LoadOptions, Scene, SceneBuilder, SceneError, VolumeError};
pub use vdb::VdbError;

/// The Rust examples of `docs/embedding.md`, compiled as doctests so that the guide cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../docs/embedding.md")]
pub struct EmbeddingGuide;

/// The Rust examples of `docs/api.md`, compiled as doctests for the same reason.
#[cfg(doctest)]
#[doc = include_str!("../docs/api.md")]
pub struct ApiGuide;

/// The Rust example of `README.md`, compiled (not run) as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeExample;
