//! [`SurfaceHit`]: where a ray hit a surface, with what shading needs, and where textures are read there.

use crate::geometry::SurfacePoint;
use crate::material::{ShadingPoint, TexCoord};
use crate::math::{Frame, Vec2, Vec3, Vec4};

internal! {
    /// Where a ray hit a surface, with everything shading needs.
    #[derive(Clone, Copy, Debug)]
    pub struct SurfaceHit {
        /// Distance along the ray.
        pub t: f32,
        /// World position, interpolated from the vertices with the barycentrics.
        pub p: Vec3,
        /// Bound on the rounding error of each coordinate of `p` (see [`SurfacePoint`]).
        pub p_error: Vec3,
        /// Unit geometric normal of the front (counter-clockwise) face.
        pub geometric_normal: Vec3,
        /// Shading frame: the interpolated normal (normal-mapped once [`Scene::apply_normal_map`](crate::scene::Scene::apply_normal_map) has run), kept
        /// on the front side of the geometric normal; the integrator flips it for back-face hits on double-sided
        /// materials.
        pub shading: Frame,
        /// True when the ray arrived on the front face.
        pub front_face: bool,
        /// Texture coordinates.
        pub uv: Vec2,
        /// Texture-coordinate units per world unit on this triangle, √(uv area / world area): turns a footprint
        /// width in world units into one in texture coordinates (0 without texture coordinates).
        pub uv_per_world: f32,
        /// Texture coordinates of the second set (`TEXCOORD_1`; zero without it).
        pub uv1: Vec2,
        /// `uv_per_world` of the second set.
        pub uv1_per_world: f32,
        /// Interpolated vertex colour (`COLOR_0`; white without it).
        pub color: Vec4,
        /// Material index.
        pub material: u32,
        /// Global triangle index.
        pub prim: u32,
        /// Barycentrics of the hit (of vertices 1 and 2).
        #[cfg(any(test, feature = "testing"))]
        pub barycentrics: Vec2,
    }
}

impl SurfaceHit {
    /// The hit as a point on its surface, from which rays are spawned.
    pub fn surface_point(&self) -> SurfacePoint {
        SurfacePoint {
            p: self.p,
            error: self.p_error,
            n: self.geometric_normal,
        }
    }

    /// The origin of a ray leaving the surface in direction `w` (see [`SurfacePoint::spawn_origin`]).
    pub fn spawn_origin(&self, w: Vec3) -> Vec3 {
        self.surface_point().spawn_origin(w)
    }

    /// Where textures are read at this hit, for a ray cone of world-space `width` arriving along unit `dir`:
    /// the footprint is the cone's width projected onto the surface, `width / |n · dir|`, in texture units
    /// (the ray-cone level of detail of Akenine-Möller et al. 2021, "Improved Shader and Texture Level of
    /// Detail Using Ray Cones", JCGT 10(1), given as a width rather than as its log₂).
    #[cfg(test)]
    pub fn tex_coord(&self, width: f32, dir: Vec3) -> TexCoord {
        self.shading_point(width, dir).uv[0]
    }

    /// Texture coordinates with no footprint (the full-resolution image).
    #[cfg(test)]
    pub fn point_tex_coord(&self) -> TexCoord {
        TexCoord::point(self.uv)
    }

    /// What materials read at this hit for a ray cone of world-space `width` arriving along unit `dir`: both
    /// texture-coordinate sets with their footprints (as [`SurfaceHit::tex_coord`]) and the vertex colour.
    pub fn shading_point(&self, width: f32, dir: Vec3) -> ShadingPoint {
        let cos = self.geometric_normal.dot(dir).abs().max(1e-3);
        let tc = |uv: Vec2, per_world: f32| {
            let footprint = width / cos * per_world;
            TexCoord {
                uv,
                footprint: if footprint.is_finite() {
                    footprint
                } else {
                    0.0
                },
            }
        };
        ShadingPoint {
            uv: [
                tc(self.uv, self.uv_per_world),
                tc(self.uv1, self.uv1_per_world),
            ],
            color: self.color,
        }
    }

    /// [`SurfaceHit::shading_point`] with no footprint (the full-resolution images).
    pub fn point_shading(&self) -> ShadingPoint {
        self.shading_point(0.0, -self.geometric_normal)
    }
}
