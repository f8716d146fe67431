//! [`SceneBuilder::build`]: a builder's meshes flattened into the static, moving-triangle and instance
//! hierarchies, emissive triangles made area lights, the memory budget checked first, and the scene's bounds.

use super::instancing;
use super::names::{SceneNames, SurfaceObject};
use super::{mesh_bytes, mesh_counts, MeshInstance, BUILDER_PATH, BYTES_PER_INSTANCE};
use super::{Camera, Scene, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::{Bvh, Instance, InstanceBvh, Mesh, MotionBvh, TooManyTriangles};
use crate::light::{AreaLight, Light, LightSampler};
use crate::material::{AlphaMode, Material};
use crate::math::{Aabb, Vec2, Vec3};
use std::sync::OnceLock;

/// The triangles of a builder's world meshes, numbered: static ones first, in mesh order (so a scene without
/// motion numbers them as it always did), then the moving ones.
struct Triangles {
    /// The mesh and the triangle in it of each global triangle index.
    prims: Vec<(u32, u32)>,
    /// The static triangles' vertices.
    fixed: Vec<[Vec3; 3]>,
    /// The moving triangles' hierarchy, if there are any.
    motion: Option<MotionBvh>,
}

/// A triangle count past what a hierarchy indexes, as a scene error.
fn too_many(e: TooManyTriangles) -> SceneError {
    SceneError::new(BUILDER_PATH, SceneErrorKind::Unsupported(e.to_string()))
}

/// The hierarchies a scene is traced through, and its bounds.
struct Hierarchies {
    /// The static triangles.
    bvh: Bvh,
    /// The moving triangles, if any.
    motion: Option<MotionBvh>,
    /// The instances, if any.
    instanced: Option<InstanceBvh>,
    /// The number of static triangles.
    static_count: u32,
}

impl SceneBuilder {
    /// Builds the renderable scene: flattens the meshes into one BVH, turns emissive triangles into area
    /// lights and builds the light-selection distribution. Fails on a dangling reference (see
    /// [`SceneBuilder`]), and before allocating when the meshes do not fit the memory budget at
    /// `BYTES_PER_TRIANGLE` and `BYTES_PER_VERTEX`.
    pub fn build(mut self) -> Result<Scene, SceneError> {
        self.validate()?;
        let instances = self.flatten_emissive_instances()?;
        self.generate_tangents();
        self.keep_emitters_still();
        let mut lights = std::mem::take(&mut self.lights);
        let Triangles {
            prims,
            fixed,
            motion,
        } = self.number_triangles(&mut lights)?;
        let static_count = fixed.len() as u32;
        let mut light_of_prim = vec![u32::MAX; prims.len()];
        for (i, l) in lights.iter().enumerate() {
            if let Light::Area(a) = l {
                light_of_prim[a.prim as usize] = i as u32;
            }
        }
        let bvh = Bvh::build(&fixed).map_err(too_many)?;
        drop(fixed);
        let instanced = self.instance_hierarchy(&instances, prims.len())?;
        let hierarchies = Hierarchies {
            bvh,
            motion,
            instanced,
            static_count,
        };
        Ok(self.into_scene(hierarchies, lights, instances, prims, light_of_prim))
    }

    /// Takes the instances out of the builder, after checking that the scene's meshes fit the memory budget:
    /// an emissive prototype's instances become world meshes (area lights are world triangles); the others
    /// are returned.
    fn flatten_emissive_instances(&mut self) -> Result<Vec<MeshInstance>, SceneError> {
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
        Ok(instances)
    }

    /// Normal maps and anisotropy need a tangent frame: MikkTSpace where the file gives no tangents (glTF 2.0
    /// §3.7.2.1). Without texture coordinates there is none to build, and anisotropy follows an arbitrary
    /// direction (a warning says so). A prototype's tangents are made in object space and carried to world
    /// space with it.
    fn generate_tangents(&mut self) {
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
    }

    /// Emitters stay at the frame's pose, where their area lights are sampled: a moving emissive mesh loses
    /// its motion, with a warning.
    fn keep_emitters_still(&mut self) {
        for mesh in &mut self.meshes {
            if mesh.motion.is_some() && self.materials[mesh.material as usize].is_emissive() {
                mesh.motion = None;
                self.warnings.push(format!(
                    "mesh '{}' emits light, so it is not motion-blurred: area lights stay at the frame's pose",
                    mesh.name
                ));
            }
        }
    }

    /// The world meshes' triangles, numbered (see [`Triangles`]), the moving ones in their hierarchy; each
    /// emissive static triangle's area light is added to `lights`.
    fn number_triangles(&self, lights: &mut Vec<Light>) -> Result<Triangles, SceneError> {
        let order: Vec<usize> = (0..self.meshes.len())
            .filter(|&m| self.meshes[m].motion.is_none())
            .chain((0..self.meshes.len()).filter(|&m| self.meshes[m].motion.is_some()))
            .collect();
        let (mut prims, mut fixed, mut moving) = (Vec::new(), Vec::new(), Vec::new());
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
                let prim = fixed.len() as u32;
                if material.is_emissive() {
                    lights.extend(self.area_light(mesh_index, tri, prim, vertices));
                }
                fixed.push(vertices);
            }
        }
        let motion = if moving.is_empty() {
            None
        } else {
            Some(MotionBvh::build(&moving).map_err(too_many)?)
        };
        Ok(Triangles {
            prims,
            fixed,
            motion,
        })
    }

    /// The area light of static triangle `tri` of emissive mesh `mesh_index` (global index `prim`) with its
    /// `vertices`, if it has an area.
    fn area_light(
        &self,
        mesh_index: usize,
        tri: usize,
        prim: u32,
        vertices: [Vec3; 3],
    ) -> Option<Light> {
        let mesh = &self.meshes[mesh_index];
        let material = &self.materials[mesh.material as usize];
        // The emissive texture's own UV set; its transform is applied by the light.
        let set = material
            .emission_texture
            .and_then(|t| self.textures.get(t as usize))
            .map_or(0, |t| t.uv_set());
        let uvs = match mesh.uv_set(set) {
            Some(uv) => mesh.indices[tri].map(|i| uv[i as usize]),
            None => [Vec2::ZERO; 3],
        };
        AreaLight::new(
            vertices,
            uvs,
            material.emission,
            material.emission_texture,
            [prim, mesh_index as u32],
        )
        .map(Light::Area)
    }

    /// The two-level hierarchy over `instances` (`None` without any), refused when the instances' triangles
    /// and the `world_triangles` before them cannot all be numbered.
    fn instance_hierarchy(
        &self,
        instances: &[MeshInstance],
        world_triangles: usize,
    ) -> Result<Option<InstanceBvh>, SceneError> {
        if instances.is_empty() {
            return Ok(None);
        }
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
        let hierarchy = InstanceBvh::build(&prototype_triangles, &placements).map_err(too_many)?;
        let total = world_triangles as u64 + hierarchy.triangle_count() as u64;
        if total > u32::MAX as u64 {
            return Err(too_many(TooManyTriangles(total as usize)));
        }
        Ok(Some(hierarchy))
    }

    /// Bounds of the surfaces and of the regions that media fill by position (a VDB placed by a node): the
    /// default camera frames both, and lights at infinity light both.
    fn scene_bounds(&self, hierarchies: &Hierarchies, instances: &[MeshInstance]) -> Aabb {
        let bounds = match &hierarchies.motion {
            Some(m) => hierarchies.bvh.bounds().union(&m.bounds()),
            None => hierarchies.bvh.bounds(),
        };
        let bounds = match &hierarchies.instanced {
            Some(i) => bounds.union(&instance_bounds(&self.prototypes, instances, i)),
            None => bounds,
        };
        self.media
            .iter()
            .filter_map(|m| m.fill_bounds())
            .filter(|b| !b.is_empty() && b.min.is_finite() && b.max.is_finite())
            .fold(bounds, |all, b| all.union(&b))
    }

    /// The scene made of the builder's parts, its `hierarchies`, all its `lights` (area lights included), its
    /// `instances`, and its triangles' numbering (`prims`, `light_of_prim`).
    fn into_scene(
        self,
        hierarchies: Hierarchies,
        lights: Vec<Light>,
        instances: Vec<MeshInstance>,
        prims: Vec<(u32, u32)>,
        light_of_prim: Vec<u32>,
    ) -> Scene {
        let bounds = self.scene_bounds(&hierarchies, &instances);
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
        Scene {
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
            instanced: hierarchies.instanced,
            constant_shading: self
                .materials
                .iter()
                .map(Material::constant_shading)
                .collect(),
            materials: self.materials,
            textures: self.textures,
            lights,
            light_sampler,
            light_bvh: OnceLock::new(),
            environment,
            bvh: hierarchies.bvh,
            motion: hierarchies.motion,
            static_count: hierarchies.static_count,
            prims,
            light_of_prim,
            bounds,
            max_bounces: self.max_bounces,
            warnings: self.warnings,
        }
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
