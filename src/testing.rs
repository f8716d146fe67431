//! The crate's internals, for its own integration tests and benches only (feature `testing`; docs/api.md).
//!
//! Without the feature the library's API is what an embedder needs: loading and building scenes, render
//! settings, rendering, images and their layers, output files, farm parts and VDB file information. Its tests and
//! benches also reach inside: tracking estimators, majorant structures, BSDFs, the BVH, loaders' internals. With
//! the feature, the items and modules declared with the crate's `internal!` macro become `pub` instead of
//! `pub(crate)`, at their usual paths (`nimbus::volume::tracking`, `nimbus::geometry::Bvh`, ...).
//!
//! The package's dev-dependency on itself turns the feature on for `cargo test` and `cargo bench`; nothing else
//! should: these items change without notice, and `tests/public_api.rs` does not list them.
//!
//! This module itself holds the closed forms that unit tests beside the code and integration tests both check
//! renders against.

#[cfg(any(test, feature = "testing"))]
use glam::DVec3;

/// Irradiance at `p` (normal `n`) from a polygon of uniform radiance `radiance` wholly above `p`'s horizon and
/// unoccluded: Lambert's contour formula E = L/2 · |Σ_i Θ_i (n · ĝ_i)|, with Θ_i the angle the edge i subtends
/// at `p` and ĝ_i the unit normal of the plane through `p` and that edge (Lambert's formula for polygonal
/// sources, as in Arvo 1994, "The Irradiance Jacobian for Partially Occluded Polyhedral Sources").
#[cfg(any(test, feature = "testing"))]
pub fn polygon_irradiance(p: DVec3, n: DVec3, vertices: &[DVec3], radiance: f64) -> f64 {
    let sum: f64 = (0..vertices.len())
        .map(|i| {
            let a = (vertices[i] - p).normalize();
            let b = (vertices[(i + 1) % vertices.len()] - p).normalize();
            a.dot(b).clamp(-1.0, 1.0).acos() * n.dot(a.cross(b).normalize())
        })
        .sum();
    0.5 * radiance * sum.abs()
}
