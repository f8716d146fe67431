//! [`SceneBuilder::build`]: a builder's meshes flattened into the static, moving-triangle and instance
//! hierarchies, emissive triangles made area lights, the memory budget checked first, and the scene's bounds.

use super::instancing;
use super::names::{SceneNames, SurfaceObject};
use super::{mesh_bytes, mesh_counts, MeshInstance, BUILDER_PATH, BYTES_PER_INSTANCE};
use super::{Camera, Scene, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::{Bvh, Instance, InstanceBvh, Mesh, MotionBvh};
use crate::light::{AreaLight, Light, LightSampler};
use crate::material::AlphaMode;
use crate::math::{Aabb, Vec2, Vec3};
use std::sync::OnceLock;

impl SceneBuilder {
    /// Builds the renderable scene: flattens the meshes into one BVH, turns emissive triangles into area
    /// lights and builds the light-selection distribution. Fails on a dangling reference (see
    /// [`SceneBuilder`]), and before allocating when the meshes do not fit the memory budget at
    /// `BYTES_PER_TRIANGLE` and `BYTES_PER_VERTEX`.
    pub fn build(mut self) -> Result<Scene, SceneError> {
        self.validate()?;
        // An emissive prototype's instances become world meshes: area lights are world triangles.
        let (instances, flattened): (Vec<MeshInstance>, Vec<MeshInstance>) =
            std::mem::take(&mut self.instances)
                .into_iter()
                .partition(|i| {
                    let material = self.prototypes[i.prototype as usize].material;
                    !self.materials[material as usize].is_emissive()
                });
        let flattened_counts = flattened
            .iter()
            .map(|i| mesh_counts(&self.prototypes[i.prototype as usize]));
        let (triangles, vertices) = self
            .meshes
            .iter()
            .chain(&self.prototypes)
            .map(mesh_counts)
            .chain(flattened_counts)
            .fold((0u64, 0u64), |(t, v), (mt, mv)| {
                (t.saturating_add(mt), v.saturating_add(mv))
            });
        let instance_count = instances.len() as u64;
        self.limits
            .check(
                format_args!("the scene's meshes ({triangles} triangles, {vertices} vertices, {instance_count} instances)"),
                mesh_bytes(triangles, vertices)
                    .saturating_add(instance_count.saturating_mul(BYTES_PER_INSTANCE)),
            )
            .map_err(|e| SceneError::new(BUILDER_PATH, SceneErrorKind::OverLimit(e.to_string())))?;
        for instance in &flattened {
            let mesh = instancing::flatten(&self.prototypes[instance.prototype as usize], instance);
            self.meshes.push(mesh);
        }
        // Normal maps and anisotropy need a tangent frame: MikkTSpace where the file gives no tangents (glTF 2.0
        // §3.7.2.1). Without texture coordinates there is none to build, and anisotropy follows an arbitrary
        // direction. A prototype's tangents are made in object space and carried to world space with it.
        for mesh in self.meshes.iter_mut().chain(&mut self.prototypes) {
            let material = &self.materials[mesh.material as usize];
            if mesh.tangents.is_none() && material.needs_tangents() {
                if mesh.uvs.is_some() {
                    mesh.generate_tangents();
                } else if material.is_anisotropic() {
                    self.warnings.push(format!(
                        "mesh '{}' has an anisotropic material but neither tangents nor texture coordinates: \
                         its anisotropy direction is arbitrary",
                        mesh.name
                    ));
                }
            }
        }
        // Emitters stay at the frame's pose: their area lights are sampled there.
        for mesh in &mut self.meshes {
            if mesh.motion.is_some() && self.materials[mesh.material as usize].is_emissive() {
                mesh.motion = None;
                self.warnings.push(format!(
                    "mesh '{}' emits light, so it is not motion-blurred: area lights stay at the frame's pose",
                    mesh.name
                ));
            }
        }
        // Static triangles first, in mesh order (so a scene without motion numbers them as it always did),
        // then the moving ones.
        let order: Vec<usize> = (0..self.meshes.len())
            .filter(|&m| self.meshes[m].motion.is_none())
            .chain((0..self.meshes.len()).filter(|&m| self.meshes[m].motion.is_some()))
            .collect();
        let mut prims = Vec::new();
        let mut triangles = Vec::new();
        let mut moving = Vec::new();
        let mut lights = self.lights;
        for mesh_index in order {
            let mesh = &self.meshes[mesh_index];
            let material = &self.materials[mesh.material as usize];
            for tri in 0..mesh.indices.len() {
                prims.push((mesh_index as u32, tri as u32));
                if let Some(motion) = &mesh.motion {
                    moving.push(motion.triangle(mesh.indices[tri]));
                    continue;
                }
                let vertices = mesh.triangle(tri);
                let prim = triangles.len() as u32;
                if material.is_emissive() {
                    // The emissive texture's own UV set; its transform is applied by the light.
                    let set = material
                        .emission_texture
                        .and_then(|t| self.textures.get(t as usize))
                        .map_or(0, |t| t.uv_set());
                    let uvs = match mesh.uv_set(set) {
                        Some(uv) => mesh.indices[tri].map(|i| uv[i as usize]),
                        None => [Vec2::ZERO; 3],
                    };
                    if let Some(l) = AreaLight::new(
                        vertices,
                        uvs,
                        material.emission,
                        material.emission_texture,
                        [prim, mesh_index as u32],
                    ) {
                        lights.push(Light::Area(l));
                    }
                }
                triangles.push(vertices);
            }
        }
        let too_many = |e: crate::geometry::TooManyTriangles| {
            SceneError::new(BUILDER_PATH, SceneErrorKind::Unsupported(e.to_string()))
        };
        let static_count = triangles.len() as u32;
        let motion = if moving.is_empty() {
            None
        } else {
            Some(MotionBvh::build(&moving).map_err(too_many)?)
        };
        let mut light_of_prim = vec![u32::MAX; prims.len()];
        for (i, l) in lights.iter().enumerate() {
            if let Light::Area(a) = l {
                light_of_prim[a.prim as usize] = i as u32;
            }
        }
        let bvh = Bvh::build(&triangles).map_err(too_many)?;
        drop(triangles);
        let instanced = if instances.is_empty() {
            None
        } else {
            let prototype_triangles: Vec<Vec<[Vec3; 3]>> = self
                .prototypes
                .iter()
                .map(|m| (0..m.indices.len()).map(|t| m.triangle(t)).collect())
                .collect();
            let placements: Vec<Instance> = instances
                .iter()
                .map(|i| Instance {
                    prototype: i.prototype,
                    object_to_world: i.object_to_world,
                })
                .collect();
            let hierarchy =
                InstanceBvh::build(&prototype_triangles, &placements).map_err(too_many)?;
            let total = prims.len() as u64 + hierarchy.triangle_count() as u64;
            if total > u32::MAX as u64 {
                return Err(too_many(crate::geometry::TooManyTriangles(total as usize)));
            }
            Some(hierarchy)
        };
        // Surfaces and the regions that media fill by position (a VDB placed by a node): the default camera
        // frames both, and lights at infinity light both.
        let bounds = match &motion {
            Some(m) => bvh.bounds().union(&m.bounds()),
            None => bvh.bounds(),
        };
        let bounds = match &instanced {
            Some(i) => bounds.union(&instance_bounds(&self.prototypes, &instances, i)),
            None => bounds,
        };
        let bounds = self
            .media
            .iter()
            .filter_map(|m| m.fill_bounds())
            .filter(|b| !b.is_empty() && b.min.is_finite() && b.max.is_finite())
            .fold(bounds, |all, b| all.union(&b));
        let light_sampler = LightSampler::new(&lights, bounding_radius(&bounds));
        let environment = lights
            .iter()
            .position(|l| matches!(l, Light::Environment(_)));
        let filled_media = (0..self.media.len() as u32)
            .filter(|&m| self.media[m as usize].fill_bounds().is_some())
            .collect();
        let has_alpha = self
            .materials
            .iter()
            .any(|m| m.alpha_mode != AlphaMode::Opaque);
        let has_invisible_boundaries = self.materials.iter().any(|m| m.may_be_index_matched());
        let objects = self
            .meshes
            .iter()
            .map(SurfaceObject::of_mesh)
            .chain(instances.iter().map(|i| SurfaceObject {
                name: &i.name,
                asset: &i.asset,
                tags: &i.tags,
                material: self.prototypes[i.prototype as usize].material,
            }));
        let names = SceneNames::new(
            objects,
            &self.materials,
            &lights,
            &self.light_tags,
            &self.media,
            &self.media_tags,
        );
        Ok(Scene {
            names,
            transparent: self.transparent,
            has_alpha,
            has_invisible_boundaries,
            media: self.media,
            shutter: self.shutter,
            filled_media,
            camera: self.camera.unwrap_or_else(|| Camera::framing(&bounds)),
            meshes: self.meshes,
            prototypes: self.prototypes,
            placed: instances.iter().map(instancing::Placed::new).collect(),
            instanced,
            materials: self.materials,
            textures: self.textures,
            lights,
            light_sampler,
            light_bvh: OnceLock::new(),
            environment,
            bvh,
            motion,
            static_count,
            prims,
            light_of_prim,
            bounds,
            max_bounces: self.max_bounces,
            warnings: self.warnings,
        })
    }
}

/// Most vertex transforms spent on the exact world bounds of a scene's instances; past it, the hierarchy's
/// boxes (each instance's object box transformed, a little looser) bound them.
const EXACT_INSTANCE_BOUNDS_WORK: u64 = 1 << 24;

/// The world bounds of `instances`: exactly those of their transformed vertices, as the same meshes copied to
/// world space would have (so that the default camera frames a scene alike whether its meshes are instanced or
/// not), unless that takes more than [`EXACT_INSTANCE_BOUNDS_WORK`] vertex transforms; then `hierarchy`'s.
fn instance_bounds(
    prototypes: &[Mesh],
    instances: &[MeshInstance],
    hierarchy: &InstanceBvh,
) -> Aabb {
    let work = instances.iter().fold(0u64, |w, i| {
        w.saturating_add(prototypes[i.prototype as usize].positions.len() as u64)
    });
    if work > EXACT_INSTANCE_BOUNDS_WORK {
        return hierarchy.bounds();
    }
    instances.iter().fold(Aabb::EMPTY, |b, i| {
        let m = &i.object_to_world;
        prototypes[i.prototype as usize]
            .positions
            .iter()
            .map(|p| m.transform_point3(*p))
            .filter(|p| p.is_finite())
            .fold(b, |b, p| b.extend(p))
    })
}

/// Radius of a sphere around `bounds` (half its diagonal, at least 1 mm; 1 for empty bounds): the size of the
/// disc that lights at infinity illuminate, and of the default camera's framing.
pub(crate) fn bounding_radius(bounds: &Aabb) -> f32 {
    if bounds.is_empty() {
        1.0
    } else {
        (bounds.extent().length() * 0.5).max(1e-3)
    }
}
