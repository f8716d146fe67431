//! The renderable [`Scene`] a builder makes: its hierarchies, lights, media and camera, and the ray queries
//! the integrator asks of it (closest hit with alpha testing, occlusion, normal mapping).

use super::build::bounding_radius;
use super::{instancing, load_builder, Camera, LoadOptions, SceneError, SceneNames, SurfaceHit};
use crate::geometry::{
    Bvh, InstanceBvh, Mesh, MotionBvh, SurfacePoint, TriangleHierarchy, TriangleHit,
};
use crate::light::{EnvironmentLight, Light, LightBvh, LightSampler};
use crate::material::{AlphaMode, Material, MaterialShading, ShadingPoint, TexCoord, Texture};
use crate::math::{hash_to_unit, Aabb, Frame, Ray, Vec2, Vec3, Vec4};
use crate::volume::Medium;
use std::borrow::Cow;
use std::path::Path;
use std::sync::{Arc, OnceLock};

/// A renderable scene, made by [`SceneBuilder::build`]; read-only (its acceleration structure is built over
/// its meshes).
pub struct Scene {
    /// World-space meshes.
    pub(crate) meshes: Vec<Mesh>,
    /// Object-space meshes that instances place.
    pub(super) prototypes: Vec<Mesh>,
    /// The instances, in the order of their surface objects (after the meshes) and triangle numbers.
    pub(super) placed: Vec<instancing::Placed>,
    /// The instances' two-level hierarchy, if there are instances: global triangle indices from
    /// `prims.len()` on.
    pub(super) instanced: Option<InstanceBvh>,
    /// Materials.
    pub(crate) materials: Vec<Material>,
    /// Textures.
    pub(crate) textures: Vec<Texture>,
    /// Per material, its shading where it has no textures ([`Material::constant_shading`]): made once here
    /// instead of at every hit.
    pub(super) constant_shading: Vec<Option<MaterialShading>>,
    /// All lights, area lights included.
    pub(crate) lights: Vec<Light>,
    /// Light selection by power.
    pub(crate) light_sampler: LightSampler,
    /// Light selection by importance at the shading point, built on first use (only renders that choose it
    /// pay for it).
    pub(super) light_bvh: OnceLock<LightBvh>,
    /// Index of the environment light in `lights`, if any.
    pub(crate) environment: Option<usize>,
    /// The camera.
    pub(crate) camera: Camera,
    /// Bounds of all surfaces and of the regions media fill by position.
    pub(crate) bounds: Aabb,
    /// Maximum bounces requested by the scene file, if any.
    pub(crate) max_bounces: Option<u32>,
    /// Problems met while loading.
    pub(crate) warnings: Vec<String>,
    /// Participating media.
    pub(crate) media: Vec<Arc<dyn Medium>>,
    /// The motion-blur shutter the scene was loaded for; camera rays sample their time in it.
    pub(crate) shutter: Option<crate::frames::Shutter>,
    /// Indices of the media that fill a region by position (VDB volumes), not a mesh interior.
    pub(crate) filled_media: Vec<u32>,
    /// The static triangles: global triangle indices `0 .. static_count`.
    pub(super) bvh: Bvh,
    /// The moving triangles (transform motion blur), if any: global indices from `static_count` on.
    pub(super) motion: Option<MotionBvh>,
    /// The number of static triangles.
    pub(super) static_count: u32,
    /// True when some material is a cut-out or partly covering, so hits must be alpha-tested.
    pub(super) has_alpha: bool,
    /// True when some material may be an invisible (index-matched) boundary, which shadow rays pass through;
    /// without one, any surface between a point and a light blocks it.
    pub(super) has_invisible_boundaries: bool,
    /// The emitters (for light groups), Cryptomatte names, holdouts and shadow catchers.
    pub(super) names: SceneNames,
    /// Whether the scene file asks for a transparent film.
    pub(super) transparent: bool,
    /// The mesh and triangle of each global triangle index.
    pub(super) prims: Vec<(u32, u32)>,
    /// The area light of each global triangle index (`u32::MAX`: none).
    pub(super) light_of_prim: Vec<u32>,
}
impl Scene {
    /// Loads a scene file, choosing the loader by extension (.gltf, .glb, .obj, .usd, .usda,
    /// .usdc, .usdz).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        load_builder(path, &LoadOptions::default())?.build()
    }

    /// Number of triangles, each instance counting its prototype's.
    pub fn triangle_count(&self) -> usize {
        self.prims.len()
            + self
                .instanced
                .as_ref()
                .map_or(0, InstanceBvh::triangle_count)
    }

    /// Number of instances: placements of a shared object-space mesh, traced through the two-level hierarchy
    /// (their triangles are in [`Self::triangle_count`] once per placement).
    pub fn instance_count(&self) -> usize {
        self.placed.len()
    }

    /// Number of moving triangles (transform motion blur).
    pub fn moving_triangle_count(&self) -> usize {
        self.motion.as_ref().map_or(0, MotionBvh::triangle_count)
    }

    internal! {
        /// Radius of a sphere around the scene bounds.
        #[cfg(any(test, feature = "testing"))]
        pub fn radius(&self) -> f32 {
            bounding_radius(&self.bounds)
        }
    }

    internal! {
        /// The meshes, in world space.
        #[cfg(any(test, feature = "testing"))]
        pub fn meshes(&self) -> &[Mesh] {
            &self.meshes
        }
    }

    /// The materials, by index.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    internal! {
        /// The textures, by index.
        #[cfg(any(test, feature = "testing"))]
        pub fn textures(&self) -> &[Texture] {
            &self.textures
        }
    }

    internal! {
        /// The emitters, Cryptomatte names, holdouts and shadow catchers of the scene.
        pub fn names(&self) -> &SceneNames {
            &self.names
        }
    }

    /// Whether the scene file asks for a transparent film (glTF scene extras `nimbus_transparent`).
    pub fn transparent(&self) -> bool {
        self.transparent
    }

    internal! {
        /// The surface object of global triangle index `prim`, as [`SceneNames`] numbers them: its mesh, or for
        /// an instance's triangle the number of meshes plus the instance's index.
        pub fn mesh_of_prim(&self, prim: u32) -> usize {
            match self.prims.get(prim as usize) {
                Some(p) => p.0 as usize,
                None => self
                    .locate_instanced(prim)
                    .map_or(0, |(i, _)| self.meshes.len() + i as usize),
            }
        }
    }

    /// The instance and the prototype triangle of global triangle index `prim`, if an instance's.
    fn locate_instanced(&self, prim: u32) -> Option<(u32, u32)> {
        let base = self.prims.len() as u32;
        self.instanced.as_ref()?.locate(prim.checked_sub(base)?)
    }

    /// The mesh holding global triangle `prim` (a prototype for an instance's), the triangle's index in it and
    /// the instance's placement, if any.
    fn surface_of(&self, prim: u32) -> (&Mesh, usize, Option<&instancing::Placed>) {
        if let Some(&(mesh, tri)) = self.prims.get(prim as usize) {
            return (&self.meshes[mesh as usize], tri as usize, None);
        }
        let (instance, tri) = self.locate_instanced(prim).unwrap_or_default();
        let placed = &self.placed[instance as usize];
        (
            &self.prototypes[placed.prototype as usize],
            tri as usize,
            Some(placed),
        )
    }

    internal! {
        /// Every light, area lights included.
        pub fn lights(&self) -> &[Light] {
            &self.lights
        }
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The motion-blur shutter the scene was loaded for (`None`: an instant).
    pub fn shutter(&self) -> Option<crate::frames::Shutter> {
        self.shutter
    }

    internal! {
        /// Bounds of all surfaces and of the regions media fill by position (VDB volumes).
        #[cfg(any(test, feature = "testing"))]
        pub fn bounds(&self) -> Aabb {
            self.bounds
        }
    }

    /// The maximum number of bounces the scene file asks for, if any.
    pub fn max_bounces(&self) -> Option<u32> {
        self.max_bounces
    }

    /// Problems met while loading.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The scene's lights counted by kind, in words: "36 emissive triangles, 1 punctual light, an environment"
    /// ("no lights" for none).
    pub fn describe_lights(&self) -> String {
        crate::light::describe_lights(&self.lights)
    }

    /// One line per medium, in scene order: its name and the estimators it renders with, and why (`--explain`).
    pub fn explain_media(&self) -> Vec<String> {
        self.media
            .iter()
            .map(|m| format!("medium '{}': {}", m.name(), m.method()))
            .collect()
    }

    internal! {
        /// The participating media, by index.
        pub fn media(&self) -> &[Arc<dyn Medium>] {
            &self.media
        }
    }

    /// True when some material may be an invisible (index-matched) boundary that shadow rays pass through;
    /// when false, a shadow ray is blocked by any surface hit, and one any-hit query ([`Scene::occluded`])
    /// decides its visibility.
    pub(crate) fn has_invisible_boundaries(&self) -> bool {
        self.has_invisible_boundaries
    }

    internal! {
        /// True when something blocks the segment `(t_min, t_max)` of `ray` (alpha cut-outs and partial coverage
        /// let it through as in [`Self::intersect`]).
        /// Moving triangles are met where they are at the ray's time.
        pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
            let blocked = if self.has_alpha {
                self.bvh
                    .occluded_where(ray, t_min, t_max, &|hit| self.covers(ray, hit))
            } else {
                self.bvh.occluded(ray, t_min, t_max)
            };
            blocked
                || self.motion.as_ref().is_some_and(|m| {
                    if self.has_alpha {
                        m.occluded_where(ray, t_min, t_max, &|hit| {
                            self.covers(ray, &self.moving_hit(hit))
                        })
                    } else {
                        m.occluded(ray, t_min, t_max)
                    }
                })
                || self.instanced.as_ref().is_some_and(|i| {
                    if self.has_alpha {
                        i.occluded_where(ray, t_min, t_max, &|hit| {
                            self.covers(ray, &self.instanced_hit(hit))
                        })
                    } else {
                        i.occluded(ray, t_min, t_max)
                    }
                })
        }
    }

    /// A hit reported by the moving triangles' hierarchy with its global triangle index.
    fn moving_hit(&self, hit: &TriangleHit) -> TriangleHit {
        TriangleHit {
            prim: hit.prim + self.static_count,
            ..*hit
        }
    }

    /// A hit reported by the instances' hierarchy with its global triangle index.
    fn instanced_hit(&self, hit: &TriangleHit) -> TriangleHit {
        TriangleHit {
            prim: hit.prim + self.prims.len() as u32,
            ..*hit
        }
    }

    /// The closest triangle hit in `(t_min, t_max)`, static, moving (at the ray's time) or instanced,
    /// alpha-tested; a later hierarchy's hit replaces an earlier one's only when strictly closer, so ties go to
    /// the lower global index.
    fn closest_triangle(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<TriangleHit> {
        let mut hit = if self.has_alpha {
            self.bvh
                .intersect_where(ray, t_min, t_max, &|hit| self.covers(ray, hit))
        } else {
            self.bvh.intersect(ray, t_min, t_max)
        };
        if let Some(motion) = &self.motion {
            let limit = hit.map_or(t_max, |h| h.t);
            let moving = if self.has_alpha {
                motion.intersect_where(ray, t_min, limit, &|h| {
                    self.covers(ray, &self.moving_hit(h))
                })
            } else {
                motion.intersect(ray, t_min, limit)
            };
            if let Some(m) = moving.filter(|m| hit.is_none_or(|h| m.t < h.t)) {
                hit = Some(self.moving_hit(&m));
            }
        }
        if let Some(instanced) = &self.instanced {
            let limit = hit.map_or(t_max, |h| h.t);
            let found = if self.has_alpha {
                instanced.intersect_where(ray, t_min, limit, &|h| {
                    self.covers(ray, &self.instanced_hit(h))
                })
            } else {
                instanced.intersect(ray, t_min, limit)
            };
            if let Some(f) = found.filter(|f| hit.is_none_or(|h| f.t < h.t)) {
                hit = Some(self.instanced_hit(&f));
            }
        }
        hit
    }

    /// Whether a candidate hit counts, by its material's [`AlphaMode`]: opaque surfaces always do; a cut-out
    /// where its alpha reaches the cut-off; partial coverage with probability alpha, decided by a hash of the
    /// ray and the triangle, so a ray and its shadow rays need no generator and the estimate stays unbiased
    /// (stochastic transparency: the expected result is alpha × the surface + (1 − alpha) × what is behind).
    fn covers(&self, ray: &Ray, hit: &TriangleHit) -> bool {
        let (mesh, tri, _) = self.surface_of(hit.prim);
        let material = &self.materials[mesh.material as usize];
        let alpha = |m: &Material| {
            let idx = mesh.indices[tri].map(|i| i as usize);
            let b = [1.0 - hit.b1 - hit.b2, hit.b1, hit.b2];
            let uv = |set: Option<&[Vec2]>| {
                TexCoord::point(set.map_or(Vec2::ZERO, |uv| at_barycentrics(uv, idx, b)))
            };
            let color = mesh
                .colors
                .as_deref()
                .map_or(Vec4::ONE, |c| at_barycentrics(c, idx, b));
            let at = ShadingPoint {
                uv: [uv(mesh.uv_set(0)), uv(mesh.uv_set(1))],
                color,
            };
            m.alpha_at(&at, &self.textures)
        };
        match material.alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => alpha(material) >= cutoff,
            AlphaMode::Blend => {
                let (o, d) = (ray.origin, ray.dir);
                let key = [o.x, o.y, o.z, d.x, d.y, d.z].map(f32::to_bits);
                let u = hash_to_unit(&[key[0], key[1], key[2], key[3], key[4], key[5], hit.prim]);
                u < alpha(material)
            }
        }
    }

    /// The parameters and BSDF of material `material` at `at` (a hit's [`SurfaceHit::shading_point`]); the
    /// same as [`Material::pbr_params`] and [`Material::bsdf`], taken from [`Self::constant_shading`] where
    /// the material has no textures (borrowed from there, not copied).
    pub(crate) fn shading(&self, material: u32, at: &ShadingPoint) -> Cow<'_, MaterialShading> {
        let index = material as usize;
        MaterialShading::at(
            self.constant_shading.get(index).and_then(Option::as_ref),
            &self.materials[index],
            at,
            &self.textures,
        )
    }

    /// The index in `lights` of the area light on triangle `prim`, if it emits.
    pub(crate) fn area_light_of(&self, prim: u32) -> Option<usize> {
        let l = *self.light_of_prim.get(prim as usize)?;
        (l != u32::MAX).then_some(l as usize)
    }

    /// The light BVH over the scene's lights, built on the first call.
    pub(crate) fn light_bvh(&self) -> &LightBvh {
        self.light_bvh.get_or_init(|| {
            LightBvh::new(&self.lights, &self.textures, bounding_radius(&self.bounds))
        })
    }

    /// The environment light, if any.
    pub(crate) fn environment_light(&self) -> Option<&EnvironmentLight> {
        match self.environment.map(|i| &self.lights[i]) {
            Some(Light::Environment(e)) => Some(e),
            _ => None,
        }
    }

    internal! {
        /// The closest surface hit along `ray` in `(t_min, t_max)`.
        /// Surfaces whose material is a cut-out or partly covering are passed through where they do not cover
        /// (see [`AlphaMode`]). A moving mesh is hit, and its hit point, normals and error bound computed, where
        /// its vertices are at the ray's time.
        pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<SurfaceHit> {
            let hit = self.closest_triangle(ray, t_min, t_max)?;
            let (mesh, tri, placed) = self.surface_of(hit.prim);
            let [i0, i1, i2] = mesh.indices[tri].map(|i| i as usize);
            let (b1, b2) = (hit.b1, hit.b2);
            let b0 = 1.0 - b1 - b2;
            let ([v0, v1, v2], normals) = match &mesh.motion {
                Some(motion) => motion.at([i0, i1, i2], ray.time),
                None => (
                    [mesh.positions[i0], mesh.positions[i1], mesh.positions[i2]],
                    [mesh.normals[i0], mesh.normals[i1], mesh.normals[i2]],
                ),
            };
            let ([v0, v1, v2], normals, geometric_normal, point) = match placed {
                None => {
                    let geometric_normal = (v1 - v0).cross(v2 - v0).normalize_or_zero();
                    let point =
                        SurfacePoint::on_triangle([v0, v1, v2], b0, b1, b2, geometric_normal);
                    ([v0, v1, v2], normals, geometric_normal, point)
                }
                Some(placed) => {
                    let world = placed.triangle([v0, v1, v2], normals, [b0, b1, b2]);
                    (
                        world.vertices,
                        world.normals,
                        world.geometric_normal,
                        world.point,
                    )
                }
            };
            let front_face = geometric_normal.dot(ray.dir) < 0.0;
            let mut n = (normals[0] * b0 + normals[1] * b1 + normals[2] * b2).normalize_or_zero();
            if n == Vec3::ZERO {
                n = geometric_normal;
            }
            let (uv1, uv1_per_world) = interpolate_uv(
                mesh.uvs1.as_deref(),
                [i0, i1, i2],
                [v0, v1, v2],
                [b0, b1, b2],
            );
            let color = mesh.colors.as_deref().map_or(Vec4::ONE, |c| {
                at_barycentrics(c, [i0, i1, i2], [b0, b1, b2])
            });
            let (uv, uv_per_world) = interpolate_uv(
                mesh.uvs.as_deref(),
                [i0, i1, i2],
                [v0, v1, v2],
                [b0, b1, b2],
            );
            let mut frame = self.tangent_frame(mesh, placed, [i0, i1, i2], n, Vec2::new(b1, b2));
            // Keep the shading normal on the geometric normal's side so that one-sided BSDFs see the front.
            if frame.n.dot(geometric_normal) < 0.0 {
                frame = Frame::from_normal(geometric_normal);
            }
            Some(SurfaceHit {
                t: hit.t,
                p: point.p,
                p_error: point.error,
                geometric_normal,
                shading: frame,
                front_face,
                uv,
                uv_per_world,
                uv1,
                uv1_per_world,
                color,
                material: mesh.material,
                prim: hit.prim,
                #[cfg(any(test, feature = "testing"))]
                barycentrics: Vec2::new(b1, b2),
            })
        }
    }

    /// Bends the hit's shading frame by its material's normal map read at `tc`, if it has one. The mapped
    /// normal stays on the geometric normal's side.
    pub(crate) fn apply_normal_map(&self, hit: &mut SurfaceHit, at: &ShadingPoint) {
        let material = &self.materials[hit.material as usize];
        let Some(mapped) = material.normal_map(at, &self.textures) else {
            return;
        };
        let n_mapped = hit.shading.to_world(mapped).normalize_or_zero();
        if n_mapped != Vec3::ZERO {
            // Keep the frame's handedness (a mirrored uv mapping's bitangent sign), which anisotropy
            // directions given in tangent space depend on.
            let mirrored = hit.shading.t.dot(hit.shading.n.cross(hit.shading.s)) < 0.0;
            hit.shading = Frame::from_normal_tangent(n_mapped, hit.shading.s);
            if mirrored {
                hit.shading.t = -hit.shading.t;
            }
            if hit.shading.n.dot(hit.geometric_normal) < 0.0 {
                hit.shading = Frame::from_normal(hit.geometric_normal);
            }
        }
    }

    /// The tangent frame at a hit: from vertex tangents when present (given by the file, or MikkTSpace ones
    /// generated for normal-mapped meshes; an instance's carried to world space by its `placed` transform),
    /// with the bitangent `w · cross(n, t)`; else arbitrary around the normal.
    fn tangent_frame(
        &self,
        mesh: &Mesh,
        placed: Option<&instancing::Placed>,
        idx: [usize; 3],
        n: Vec3,
        b: Vec2,
    ) -> Frame {
        let b0 = 1.0 - b.x - b.y;
        if let Some(t) = &mesh.tangents {
            let t = idx.map(|i| match placed {
                Some(p) => p.tangent(t[i]),
                None => t[i],
            });
            let tangent = t[0].truncate() * b0 + t[1].truncate() * b.x + t[2].truncate() * b.y;
            let frame = Frame::from_normal_tangent(n, tangent);
            // The bitangent sign (w) says whether the uv mapping is mirrored.
            if t[0].w < 0.0 {
                return Frame {
                    s: frame.s,
                    t: -frame.t,
                    n: frame.n,
                };
            }
            return frame;
        }
        Frame::from_normal(n)
    }
}

/// Texture coordinates of one set at barycentrics `b` of a triangle, and the set's texture-coordinate units per
/// world unit (see [`SurfaceHit::uv_per_world`]); zeros without the set.
fn interpolate_uv(uvs: Option<&[Vec2]>, idx: [usize; 3], v: [Vec3; 3], b: [f32; 3]) -> (Vec2, f32) {
    let Some(uv) = uvs else {
        return (Vec2::ZERO, 0.0);
    };
    let (t0, t1, t2) = (uv[idx[0]], uv[idx[1]], uv[idx[2]]);
    let uv_area = 0.5 * (t1 - t0).perp_dot(t2 - t0).abs();
    let world_area = 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length();
    let scale = (uv_area / world_area).sqrt();
    (
        at_barycentrics(uv, idx, b),
        if scale.is_finite() { scale } else { 0.0 },
    )
}

/// A per-vertex attribute of triangle `idx` at barycentrics `b`.
fn at_barycentrics<T>(values: &[T], idx: [usize; 3], b: [f32; 3]) -> T
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    values[idx[0]] * b[0] + values[idx[1]] * b[1] + values[idx[2]] * b[2]
}
