//! The scene model (surfaces, materials, textures, lights, camera) and its loaders.
//!
//! Loaders fill a [`SceneBuilder`]; [`SceneBuilder::build`] flattens the meshes into one BVH, turns emissive
//! triangles into area lights and builds the light-selection distribution.

mod builder;
mod camera;
mod error;
pub mod gltf;
pub mod obj;
pub mod usd;

pub use builder::BUILDER_PATH;
pub use camera::Camera;
pub use error::{SceneError, SceneErrorKind};

use crate::geometry::{Bvh, Mesh, SurfacePoint};
use crate::light::{AreaLight, EnvironmentLight, Light, LightSampler};
use crate::material::{Material, TexCoord, Texture};
use crate::math::{Aabb, Frame, Ray, Vec2, Vec3};
use crate::volume::Medium;
use std::path::Path;
use std::sync::Arc;

/// Reads a scene file into a builder (to be adjusted, then built), choosing the loader by extension.
pub fn load_builder(path: &Path) -> Result<SceneBuilder, SceneError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("gltf") | Some("glb") => gltf::load(path),
        Some("obj") => obj::load(path),
        Some("usd") | Some("usda") | Some("usdc") | Some("usdz") => usd::load(path),
        _ => Err(SceneError::new(path, SceneErrorKind::UnknownFormat)),
    }
}

/// Like [`load_builder`], passing every VDB volume declaration through `override_volume` before its medium is
/// built (OBJ scenes have none).
pub fn load_builder_with(
    path: &Path,
    override_volume: gltf::VolumeOverride,
) -> Result<SceneBuilder, SceneError> {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb") => {
            gltf::load_with(path, override_volume)
        }
        _ => load_builder(path),
    }
}

/// Everything a loader produces, before acceleration structures are built.
#[derive(Default)]
pub struct SceneBuilder {
    /// World-space meshes.
    pub meshes: Vec<Mesh>,
    /// Materials indexed by `Mesh::material`.
    pub materials: Vec<Material>,
    /// Textures indexed by material texture ids.
    pub textures: Vec<Texture>,
    /// Punctual lights and the environment (area lights are added by `build`).
    pub lights: Vec<Light>,
    /// The camera, or `None` for one framing the scene.
    pub camera: Option<Camera>,
    /// Maximum bounces requested by the scene file (glTF `extras.max_bounces`), if any.
    pub max_bounces: Option<u32>,
    /// Non-fatal problems met while loading (unknown optional extensions, dropped primitives).
    pub warnings: Vec<String>,
    /// Participating media: mesh interiors (referenced by `Material::interior`) and position-filled volumes.
    pub media: Vec<Arc<dyn Medium>>,
}

impl SceneBuilder {
    /// Loads the VDB volume `spec` describes and adds it as a position-filled medium; returns its index.
    /// Errors name the VDB file (missing file or grid, unreadable grid).
    pub fn add_volume(&mut self, spec: &crate::volume::VolumeSpec) -> Result<u32, SceneError> {
        let medium = crate::volume::load_grid_medium(spec)?;
        Ok(self.add_medium(medium))
    }

    /// Adds a medium and returns its index.
    pub fn add_medium(&mut self, medium: Arc<dyn Medium>) -> u32 {
        self.warnings.extend(medium.warnings());
        self.media.push(medium);
        (self.media.len() - 1) as u32
    }

    /// Adds a material and returns its index.
    pub fn add_material(&mut self, material: Material) -> u32 {
        self.materials.push(material);
        (self.materials.len() - 1) as u32
    }

    /// Adds a world-space mesh, generating normals when it has none.
    pub fn add_mesh(&mut self, mut mesh: Mesh) {
        if mesh.normals.len() != mesh.positions.len() {
            mesh.generate_normals();
        }
        self.meshes.push(mesh);
    }

    /// Replaces any environment light with `env`.
    pub fn set_environment(&mut self, env: EnvironmentLight) {
        self.lights.retain(|l| !matches!(l, Light::Environment(_)));
        self.lights.push(Light::Environment(env));
    }

    /// Builds the renderable scene.
    pub fn build(self) -> Scene {
        let mut prims = Vec::new();
        let mut triangles = Vec::new();
        let mut lights = self.lights;
        for (mesh_index, mesh) in self.meshes.iter().enumerate() {
            let material = &self.materials[mesh.material as usize];
            for tri in 0..mesh.indices.len() {
                let vertices = mesh.triangle(tri);
                let prim = triangles.len() as u32;
                if material.is_emissive() {
                    let uvs = match &mesh.uvs {
                        Some(uv) => mesh.indices[tri].map(|i| uv[i as usize]),
                        None => [Vec2::ZERO; 3],
                    };
                    if let Some(l) = AreaLight::new(
                        vertices,
                        uvs,
                        material.emission,
                        material.emission_texture,
                        prim,
                    ) {
                        lights.push(Light::Area(l));
                    }
                }
                triangles.push(vertices);
                prims.push((mesh_index as u32, tri as u32));
            }
        }
        let mut light_of_prim = vec![u32::MAX; triangles.len()];
        for (i, l) in lights.iter().enumerate() {
            if let Light::Area(a) = l {
                light_of_prim[a.prim as usize] = i as u32;
            }
        }
        let bvh = Bvh::build(&triangles);
        let bounds = bvh.bounds();
        let radius = if bounds.is_empty() {
            1.0
        } else {
            (bounds.extent().length() * 0.5).max(1e-3)
        };
        let light_sampler = LightSampler::new(&lights, radius);
        let environment = lights
            .iter()
            .position(|l| matches!(l, Light::Environment(_)));
        let filled_media = (0..self.media.len() as u32)
            .filter(|&m| self.media[m as usize].fill_bounds().is_some())
            .collect();
        Scene {
            media: self.media,
            filled_media,
            camera: self.camera.unwrap_or_else(|| Camera::framing(&bounds)),
            meshes: self.meshes,
            materials: self.materials,
            textures: self.textures,
            lights,
            light_sampler,
            environment,
            bvh,
            prims,
            light_of_prim,
            bounds,
            max_bounces: self.max_bounces,
            warnings: self.warnings,
        }
    }
}

/// A renderable scene.
pub struct Scene {
    /// World-space meshes.
    pub meshes: Vec<Mesh>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Textures.
    pub textures: Vec<Texture>,
    /// All lights, area lights included.
    pub lights: Vec<Light>,
    /// Light selection by power.
    pub light_sampler: LightSampler,
    /// Index of the environment light in `lights`, if any.
    pub environment: Option<usize>,
    /// The camera.
    pub camera: Camera,
    /// Bounds of all surfaces.
    pub bounds: Aabb,
    /// Maximum bounces requested by the scene file, if any.
    pub max_bounces: Option<u32>,
    /// Problems met while loading.
    pub warnings: Vec<String>,
    /// Participating media.
    pub media: Vec<Arc<dyn Medium>>,
    /// Indices of the media that fill a region by position (VDB volumes), not a mesh interior.
    pub filled_media: Vec<u32>,
    bvh: Bvh,
    prims: Vec<(u32, u32)>,
    light_of_prim: Vec<u32>,
}

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
    /// Shading frame: the interpolated normal (normal-mapped once [`Scene::apply_normal_map`] has run), kept
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
    /// Material index.
    pub material: u32,
    /// Global triangle index.
    pub prim: u32,
    /// Barycentrics of the hit (of vertices 1 and 2).
    pub barycentrics: Vec2,
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
    pub fn tex_coord(&self, width: f32, dir: Vec3) -> TexCoord {
        let cos = self.geometric_normal.dot(dir).abs().max(1e-3);
        let footprint = width / cos * self.uv_per_world;
        TexCoord {
            uv: self.uv,
            footprint: if footprint.is_finite() {
                footprint
            } else {
                0.0
            },
        }
    }

    /// Texture coordinates with no footprint (the full-resolution image).
    pub fn point_tex_coord(&self) -> TexCoord {
        TexCoord::point(self.uv)
    }
}

impl Scene {
    /// Loads a scene file, choosing the loader by extension (.gltf, .glb, .obj, .usd, .usda,
    /// .usdc, .usdz).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Ok(load_builder(path)?.build())
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.prims.len()
    }

    /// Bytes held by the acceleration structure.
    pub fn bvh_memory_bytes(&self) -> usize {
        self.bvh.memory_bytes()
    }

    /// Radius of a sphere around the scene bounds.
    pub fn radius(&self) -> f32 {
        if self.bounds.is_empty() {
            1.0
        } else {
            (self.bounds.extent().length() * 0.5).max(1e-3)
        }
    }

    /// True when something blocks the segment `(t_min, t_max)` of `ray`.
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.bvh.occluded(ray, t_min, t_max)
    }

    /// The index in `lights` of the area light on triangle `prim`, if it emits.
    pub fn area_light_of(&self, prim: u32) -> Option<usize> {
        let l = *self.light_of_prim.get(prim as usize)?;
        (l != u32::MAX).then_some(l as usize)
    }

    /// The environment light, if any.
    pub fn environment_light(&self) -> Option<&EnvironmentLight> {
        match self.environment.map(|i| &self.lights[i]) {
            Some(Light::Environment(e)) => Some(e),
            _ => None,
        }
    }

    /// The closest surface hit along `ray` in `(t_min, t_max)`.
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<SurfaceHit> {
        let hit = self.bvh.intersect(ray, t_min, t_max)?;
        let (mesh_index, tri) = self.prims[hit.prim as usize];
        let mesh = &self.meshes[mesh_index as usize];
        let [i0, i1, i2] = mesh.indices[tri as usize].map(|i| i as usize);
        let (b1, b2) = (hit.b1, hit.b2);
        let b0 = 1.0 - b1 - b2;
        let [v0, v1, v2] = [mesh.positions[i0], mesh.positions[i1], mesh.positions[i2]];
        let geometric_normal = (v1 - v0).cross(v2 - v0).normalize_or_zero();
        let point = SurfacePoint::on_triangle([v0, v1, v2], b0, b1, b2, geometric_normal);
        let front_face = geometric_normal.dot(ray.dir) < 0.0;
        let mut n = (mesh.normals[i0] * b0 + mesh.normals[i1] * b1 + mesh.normals[i2] * b2)
            .normalize_or_zero();
        if n == Vec3::ZERO {
            n = geometric_normal;
        }
        let (uv, uv_per_world) = match &mesh.uvs {
            Some(uv) => {
                let (t0, t1, t2) = (uv[i0], uv[i1], uv[i2]);
                let uv_area = 0.5 * (t1 - t0).perp_dot(t2 - t0).abs();
                let world_area = 0.5 * (v1 - v0).cross(v2 - v0).length();
                let scale = (uv_area / world_area).sqrt();
                (
                    t0 * b0 + t1 * b1 + t2 * b2,
                    if scale.is_finite() { scale } else { 0.0 },
                )
            }
            None => (Vec2::ZERO, 0.0),
        };
        let mut frame = self.tangent_frame(mesh, [i0, i1, i2], n, Vec2::new(b1, b2));
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
            material: mesh.material,
            prim: hit.prim,
            barycentrics: Vec2::new(b1, b2),
        })
    }

    /// Bends the hit's shading frame by its material's normal map read at `tc`, if it has one. The mapped
    /// normal stays on the geometric normal's side.
    pub fn apply_normal_map(&self, hit: &mut SurfaceHit, tc: TexCoord) {
        let material = &self.materials[hit.material as usize];
        let Some(mapped) = material.normal_map(tc, &self.textures) else {
            return;
        };
        let n_mapped = hit.shading.to_world(mapped).normalize_or_zero();
        if n_mapped != Vec3::ZERO {
            hit.shading = Frame::from_normal_tangent(n_mapped, hit.shading.s);
            if hit.shading.n.dot(hit.geometric_normal) < 0.0 {
                hit.shading = Frame::from_normal(hit.geometric_normal);
            }
        }
    }

    /// The tangent frame at a hit: from vertex tangents when present, else from the triangle's uv gradient,
    /// else arbitrary around the normal.
    fn tangent_frame(&self, mesh: &Mesh, idx: [usize; 3], n: Vec3, b: Vec2) -> Frame {
        let b0 = 1.0 - b.x - b.y;
        if let Some(t) = &mesh.tangents {
            let tangent =
                t[idx[0]].truncate() * b0 + t[idx[1]].truncate() * b.x + t[idx[2]].truncate() * b.y;
            let frame = Frame::from_normal_tangent(n, tangent);
            // The bitangent sign (w) says whether the uv mapping is mirrored.
            if t[idx[0]].w < 0.0 {
                return Frame {
                    s: frame.s,
                    t: -frame.t,
                    n: frame.n,
                };
            }
            return frame;
        }
        if let Some(uv) = &mesh.uvs {
            let (p0, p1, p2) = (
                mesh.positions[idx[0]],
                mesh.positions[idx[1]],
                mesh.positions[idx[2]],
            );
            let (d1, d2) = (uv[idx[1]] - uv[idx[0]], uv[idx[2]] - uv[idx[0]]);
            let det = d1.x * d2.y - d1.y * d2.x;
            if det.abs() > 1e-12 {
                let dpdu = ((p1 - p0) * d2.y - (p2 - p0) * d1.y) / det;
                let dpdv = ((p2 - p0) * d1.x - (p1 - p0) * d2.x) / det;
                let frame = Frame::from_normal_tangent(n, dpdu);
                // glTF's v runs downward in the image; the normal map's +y follows +v's bitangent direction.
                if frame.t.dot(dpdv) < 0.0 {
                    return Frame {
                        s: frame.s,
                        t: -frame.t,
                        n: frame.n,
                    };
                }
                return frame;
            }
        }
        Frame::from_normal(n)
    }
}
