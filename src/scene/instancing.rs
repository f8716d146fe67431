//! Mesh instances: an object-space mesh (a *prototype*) placed several times by object-to-world transforms,
//! each placement with its own identity (name, asset, compositing tags), traced through the two-level
//! [`InstanceBvh`](crate::geometry::InstanceBvh) instead of being copied to world space.
//!
//! Loaders add a prototype once ([`SceneBuilder::add_prototype`]) and each placement
//! ([`SceneBuilder::add_instance`]); the budget counts the prototype's triangles and vertices once and
//! [`BYTES_PER_INSTANCE`] per placement. What cannot be instanced is flattened when the scene is built: an
//! emissive prototype's placements become world meshes, because area lights are world triangles (see
//! [`flatten`]). Skinned, morphed and motion-blurred meshes never become prototypes: loaders pose them per
//! node as before.

use super::SceneBuilder;
use crate::geometry::{CompositingTags, Mesh, SurfacePoint};
use crate::math::{Mat3, Mat4, Vec3, Vec4};

internal! {
    /// Bytes one instance is counted at against the memory budget: its transforms (object-to-world,
    /// world-to-object, normal matrix), its top-level BVH share, its names and tables (about 300 bytes),
    /// rounded up.
    pub const BYTES_PER_INSTANCE: u64 = 512;
}

internal! {
    /// One placement of a prototype ([`SceneBuilder::add_prototype`]) with its own identity, as Cryptomatte,
    /// light groups and holdouts see it.
    #[derive(Clone, Debug, Default)]
    pub struct MeshInstance {
        /// The prototype's index.
        pub prototype: u32,
        /// Object-to-world transform (affine).
        pub object_to_world: Mat4,
        /// Its name (its Cryptomatte object name).
        pub name: String,
        /// The asset it belongs to (empty: its own name).
        pub asset: String,
        /// Its light group, holdout and shadow-catcher tags.
        pub tags: CompositingTags,
    }
}

impl SceneBuilder {
    internal! {
        /// Adds an object-space mesh that instances place ([`add_instance`](Self::add_instance)), generating
        /// normals when it has none, and returns its index. It is counted once against the memory budget (a
        /// loader calls [`check_mesh`](Self::check_mesh) first); a prototype no instance places is not
        /// rendered.
        pub fn add_prototype(&mut self, mut mesh: Mesh) -> u32 {
            if mesh.normals.len() != mesh.positions.len() && mesh.indices_fit_attributes() {
                mesh.generate_normals();
            }
            mesh.motion = None;
            let (triangles, vertices) = super::mesh_counts(&mesh);
            self.triangles = self.triangles.saturating_add(triangles);
            self.vertices = self.vertices.saturating_add(vertices);
            self.prototypes.push(mesh);
            (self.prototypes.len() - 1) as u32
        }
    }

    internal! {
        /// Places a prototype, after checking that it fits the memory budget: one more instance record, or
        /// when the prototype's material (already added) emits, the world-space copy it will become.
        pub fn add_instance(
            &mut self,
            instance: MeshInstance,
        ) -> Result<(), crate::limits::OverBudget> {
            let copy = self
                .prototypes
                .get(instance.prototype as usize)
                .filter(|m| {
                    let material = self.materials.get(m.material as usize);
                    material.is_some_and(crate::material::Material::is_emissive)
                })
                .map(super::mesh_counts);
            match copy {
                Some((triangles, vertices)) => {
                    self.check_mesh(&instance.name, triangles, vertices)?;
                    self.triangles = self.triangles.saturating_add(triangles);
                    self.vertices = self.vertices.saturating_add(vertices);
                }
                None => self.check_instances(&instance.name, 1)?,
            }
            self.instances.push(instance);
            Ok(())
        }
    }

    /// `Ok` if `count` more instance records fit the memory budget with the meshes and instances added so
    /// far; `what` names them.
    pub(crate) fn check_instances(
        &self,
        what: impl std::fmt::Display,
        count: u64,
    ) -> Result<(), crate::limits::OverBudget> {
        let instances = (self.instances.len() as u64).saturating_add(count);
        self.limits.check(
            format_args!(
                "{what}: the scene's meshes with it ({} triangles, {} vertices, {instances} instances)",
                self.triangles, self.vertices
            ),
            super::mesh_bytes(self.triangles, self.vertices)
                .saturating_add(instances.saturating_mul(BYTES_PER_INSTANCE)),
        )
    }

    internal! {
        /// The prototypes added so far.
        #[cfg(any(test, feature = "testing"))]
        pub fn prototypes(&self) -> &[Mesh] {
            &self.prototypes
        }
    }

    internal! {
        /// The instances added so far.
        #[cfg(any(test, feature = "testing"))]
        pub fn instances(&self) -> &[MeshInstance] {
            &self.instances
        }
    }

    internal! {
        /// Every mesh in world space: the meshes, then each instance's prototype copied and placed (tests
        /// compare placements this way).
        #[cfg(any(test, feature = "testing"))]
        pub fn world_meshes(&self) -> Vec<Mesh> {
            let placed = self
                .instances
                .iter()
                .filter_map(|i| Some(flatten(self.prototypes.get(i.prototype as usize)?, i)));
            self.meshes.iter().cloned().chain(placed).collect()
        }
    }
}

/// A copy of `prototype` placed in world space by `instance`, with the instance's identity: what an instance
/// that cannot stay one (an emitter) becomes.
pub(crate) fn flatten(prototype: &Mesh, instance: &MeshInstance) -> Mesh {
    let mut mesh = prototype.clone();
    mesh.transform(&instance.object_to_world);
    mesh.name.clone_from(&instance.name);
    mesh.asset.clone_from(&instance.asset);
    mesh.tags = instance.tags.clone();
    mesh
}

/// An instance as the built scene shades it: its prototype and the transforms that carry points, normals
/// and tangents to world space.
#[derive(Clone, Debug)]
pub(crate) struct Placed {
    /// The prototype's index in the scene's prototypes.
    pub prototype: u32,
    /// Object-to-world transform.
    pub object_to_world: Mat4,
    /// Its inverse transpose (upper 3×3), which carries normals.
    pub normal_matrix: Mat3,
    /// Whether the transform mirrors (negative determinant): the winding, and so the front face, flips.
    pub mirrored: bool,
}

impl Placed {
    /// The placement of `instance`.
    pub fn new(instance: &MeshInstance) -> Self {
        let m = instance.object_to_world;
        let linear = Mat3::from_mat4(m);
        Self {
            prototype: instance.prototype,
            object_to_world: m,
            normal_matrix: linear.inverse().transpose(),
            mirrored: linear.determinant() < 0.0,
        }
    }

    /// A triangle's world vertices and unit normals and its surface point at barycentrics `b`: the point is
    /// computed in object space and carried with its error bound ([`SurfacePoint::transformed`]); the
    /// geometric normal is the world triangle's, turned so that the front face stays the counter-clockwise one
    /// of the object (as [`Mesh::transform`] swaps the winding of a mirrored copy).
    pub fn triangle(&self, object: [Vec3; 3], normals: [Vec3; 3], b: [f32; 3]) -> PlacedTriangle {
        let m = &self.object_to_world;
        let v = object.map(|p| m.transform_point3(p));
        let mut n = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
        if self.mirrored {
            n = -n;
        }
        let point =
            SurfacePoint::on_triangle(object, b[0], b[1], b[2], Vec3::ZERO).transformed(m, n);
        PlacedTriangle {
            vertices: v,
            normals: normals.map(|n| (self.normal_matrix * n).normalize_or_zero()),
            geometric_normal: n,
            point,
        }
    }

    /// A tangent (xyz, bitangent sign in w) carried to world space, as [`Mesh::transform`] carries a copy's.
    pub fn tangent(&self, t: Vec4) -> Vec4 {
        self.object_to_world
            .transform_vector3(t.truncate())
            .normalize_or_zero()
            .extend(t.w)
    }
}

/// A hit instance triangle in world space ([`Placed::triangle`]).
pub(crate) struct PlacedTriangle {
    /// World vertices (in the prototype's order).
    pub vertices: [Vec3; 3],
    /// Unit world vertex normals.
    pub normals: [Vec3; 3],
    /// Unit geometric normal of the front face.
    pub geometric_normal: Vec3,
    /// The hit point with its error bound.
    pub point: SurfacePoint,
}
