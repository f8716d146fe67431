//! [`SceneBuilder`]: what a loader (or code) fills before the scene is built: meshes, prototypes and
//! instances, materials, textures, lights, media and cameras, counted against the memory budget as they are
//! added ([`BYTES_PER_TRIANGLE`](super::BYTES_PER_TRIANGLE), [`BYTES_PER_VERTEX`](super::BYTES_PER_VERTEX)); and the convenience methods for building a scene in
//! code rather than loading it from a file.

use super::names::{self, LightTag, MediumTag};
use super::{mesh_bytes, mesh_counts, MeshInstance, BYTES_PER_INSTANCE};
use super::{Camera, NamedCamera, SceneError, SceneErrorKind, UnknownCamera};
use crate::geometry::Mesh;
use crate::light::{DirectionalLight, EnvironmentLight, Light, PointLight};
use crate::material::{Material, Texture};
use crate::math::{Rgb, Vec3};
use crate::scene::MalformedPart;
use crate::volume::Medium;
use std::sync::Arc;

/// The name that errors about a programmatic scene give in place of a file path.
pub const BUILDER_PATH: &str = "<scene builder>";

/// Everything a loader produces, before acceleration structures are built: add meshes, materials, textures,
/// lights and media, then [`build`](Self::build) the renderable [`Scene`]. References between them (a mesh's
/// material, a material's textures and interior medium) are checked when the scene is built, so a dangling
/// index is an error, never a panic.
#[derive(Default)]
pub struct SceneBuilder {
    pub(super) meshes: Vec<Mesh>,
    /// Object-space meshes that `instances` place.
    pub(super) prototypes: Vec<Mesh>,
    /// Placements of `prototypes`, each with its own identity.
    pub(super) instances: Vec<MeshInstance>,
    pub(super) materials: Vec<Material>,
    pub(super) textures: Vec<Texture>,
    /// Punctual lights and the environment (area lights are added by `build`).
    pub(super) lights: Vec<Light>,
    /// The name and light group of each light in `lights`.
    pub(super) light_tags: Vec<LightTag>,
    /// The camera the scene renders from: the first of `cameras` unless one was chosen or set.
    pub(super) camera: Option<Camera>,
    /// Every camera of the scene file with its names, in the order the loader met them.
    pub(super) cameras: Vec<NamedCamera>,
    pub(super) max_bounces: Option<u32>,
    pub(super) warnings: Vec<String>,
    /// Mesh interiors (referenced by `Material::interior`) and position-filled volumes.
    pub(super) media: Vec<Arc<dyn Medium>>,
    /// The asset and compositing tags of each medium in `media`.
    pub(super) media_tags: Vec<MediumTag>,
    /// The motion-blur shutter, in frames relative to the frame.
    pub(super) shutter: Option<crate::frames::Shutter>,
    /// Whether the scene asks for a transparent film (glTF scene extras `nimbus_transparent`).
    pub(super) transparent: bool,
    /// The load's memory budget, which the scene's meshes must fit (see [`SceneBuilder::check_mesh`]).
    pub(super) limits: crate::limits::Limits,
    /// Triangles in `meshes` and `prototypes`.
    pub(super) triangles: u64,
    /// Vertices in `meshes` and `prototypes`, counted once more for each motion step.
    pub(super) vertices: u64,
}
impl SceneBuilder {
    /// An empty builder whose meshes must fit `limits` (a default builder has the default limits).
    pub(crate) fn with_limits(limits: crate::limits::Limits) -> Self {
        Self {
            limits,
            ..Self::default()
        }
    }

    /// `Ok` if a mesh of `triangles` and `vertices` (counted once more per motion step) fits the memory budget
    /// with the meshes added so far, at [`BYTES_PER_TRIANGLE`] and [`BYTES_PER_VERTEX`]. Loaders call it before
    /// making a mesh (an instance, an expanded prototype), so that a file reusing one mesh many times is
    /// refused before the copies are made; `what` names the mesh.
    pub(crate) fn check_mesh(
        &self,
        what: impl std::fmt::Display,
        triangles: u64,
        vertices: u64,
    ) -> Result<(), crate::limits::OverBudget> {
        let triangles = self.triangles.saturating_add(triangles);
        let vertices = self.vertices.saturating_add(vertices);
        let instances = self.instances.len() as u64;
        self.limits.check(
            format_args!(
                "{what}: the scene's meshes with it ({triangles} triangles, {vertices} vertices, {instances} instances)"
            ),
            mesh_bytes(triangles, vertices)
                .saturating_add(instances.saturating_mul(BYTES_PER_INSTANCE)),
        )
    }

    /// Loads the VDB volume `spec` describes and adds it as a position-filled medium; returns its index, or
    /// `None` when a sequence has no file for the frame and its `missing_frame` is `empty` (a warning says so).
    pub(crate) fn add_volume(
        &mut self,
        spec: &crate::volume::VolumeSpec,
    ) -> Result<Option<u32>, crate::volume::VolumeError> {
        match crate::volume::load_grid_medium(spec)? {
            Some(medium) => {
                let index = self.add_medium(medium);
                self.set_medium_tag(
                    index,
                    MediumTag {
                        asset: spec.asset.clone(),
                        tags: spec.tags.clone(),
                    },
                );
                Ok(Some(index))
            }
            None => {
                self.warn(format!(
                    "volume '{}': the sequence {} has no file for frame {}; the volume is empty in this frame",
                    spec.name,
                    spec.file.display(),
                    spec.file_frame()
                ));
                Ok(None)
            }
        }
    }

    internal! {
        /// Adds a medium and returns its index. Its Cryptomatte names are its own name; see
        /// [`set_medium_tag`](Self::set_medium_tag) for an asset and compositing tags.
        pub fn add_medium(&mut self, medium: Arc<dyn Medium>) -> u32 {
            self.warnings.extend(medium.warnings());
            self.media.push(medium);
            self.media_tags.push(MediumTag::default());
            (self.media.len() - 1) as u32
        }
    }

    /// Gives medium `index` (as [`add_medium`](Self::add_medium) returned it) its asset name and compositing
    /// tags; an index that names no medium is ignored.
    pub(crate) fn set_medium_tag(&mut self, index: u32, tag: MediumTag) {
        if let Some(t) = self.media_tags.get_mut(index as usize) {
            *t = tag;
        }
    }

    /// Adds a material and returns its index. Its texture and medium indices must refer to textures and media
    /// added to this builder by the time the scene is built.
    pub fn add_material(&mut self, material: Material) -> u32 {
        self.materials.push(material);
        (self.materials.len() - 1) as u32
    }

    internal! {
        /// Adds a texture and returns its index.
        pub fn add_texture(&mut self, texture: Texture) -> u32 {
            self.textures.push(texture);
            (self.textures.len() - 1) as u32
        }
    }

    internal! {
        /// Adds a world-space mesh, generating normals when it has none. Its material index must refer to a
        /// material added by the time the scene is built.
        pub fn add_mesh(&mut self, mut mesh: Mesh) {
            // A mesh whose indices, attributes or motion steps do not fit its positions keeps its normals as given,
            // and `build` names the problem: generating normals would index past the end of one of them.
            if mesh.normals.len() != mesh.positions.len() && mesh.indices_fit_attributes() {
                mesh.generate_normals();
            }
            let (triangles, vertices) = mesh_counts(&mesh);
            self.triangles = self.triangles.saturating_add(triangles);
            self.vertices = self.vertices.saturating_add(vertices);
            self.meshes.push(mesh);
        }
    }

    /// Removes and returns the meshes added after the first `at` (a USD prototype flattened for instancing).
    pub(crate) fn split_meshes_off(&mut self, at: usize) -> Vec<Mesh> {
        let taken = self.meshes.split_off(at);
        for (triangles, vertices) in taken.iter().map(mesh_counts) {
            self.triangles = self.triangles.saturating_sub(triangles);
            self.vertices = self.vertices.saturating_sub(vertices);
        }
        taken
    }

    internal! {
        /// Adds a light (area lights come from emissive materials instead; an environment replaces any other),
        /// named `light<i>` in no light group.
        pub fn add_light(&mut self, light: Light) {
            let tag = LightTag {
                name: format!("light{}", self.lights.len()),
                light_group: None,
            };
            self.add_tagged_light(light, tag);
        }
    }

    internal! {
        /// Adds a light with its name (for per-light groups) and light group.
        pub fn add_tagged_light(&mut self, light: Light, tag: LightTag) {
            match light {
                Light::Environment(env) => {
                    self.set_environment(env);
                    self.set_environment_group(tag.light_group);
                }
                other => {
                    self.lights.push(other);
                    self.light_tags.push(tag);
                }
            }
        }
    }

    /// Replaces any environment light with `env`, keeping the old one's light group.
    pub fn set_environment(&mut self, env: EnvironmentLight) {
        let group = self.environment_tag().and_then(|t| t.light_group.clone());
        let old = self
            .lights
            .iter()
            .position(|l| matches!(l, Light::Environment(_)));
        if let Some(i) = old {
            self.lights.remove(i);
            self.light_tags.remove(i);
        }
        self.lights.push(Light::Environment(env));
        self.light_tags.push(LightTag {
            name: names::ENVIRONMENT_NAME.into(),
            light_group: group,
        });
    }

    /// Drops the lights added after the first `count` (with their tags).
    pub(crate) fn truncate_lights(&mut self, count: usize) {
        self.lights.truncate(count);
        self.light_tags.truncate(count);
    }

    /// Puts the environment light, if there is one, in light group `group` (`None`: no declared group).
    pub(crate) fn set_environment_group(&mut self, group: Option<String>) {
        let env = self
            .lights
            .iter()
            .position(|l| matches!(l, Light::Environment(_)));
        if let Some(i) = env {
            self.light_tags[i].light_group = group;
        }
    }

    /// The tag of the environment light, if there is one.
    fn environment_tag(&self) -> Option<&LightTag> {
        let i = self
            .lights
            .iter()
            .position(|l| matches!(l, Light::Environment(_)))?;
        self.light_tags.get(i)
    }

    /// Sets the motion-blur shutter (frames relative to the frame): camera rays of the built scene sample
    /// their time in it. Loaders set it from [`LoadOptions::shutter`].
    pub fn set_shutter(&mut self, shutter: Option<crate::frames::Shutter>) {
        self.shutter = shutter;
    }

    /// Sets whether the scene asks for a transparent film: the directly seen environment left out of the
    /// beauty (the renderer's `transparent` setting; `--transparent` also turns it on).
    pub fn set_transparent(&mut self, transparent: bool) {
        self.transparent = transparent;
    }

    /// Sets the maximum number of bounces the scene asks for (the default of `--max-depth`).
    pub fn set_max_bounces(&mut self, bounces: u32) {
        self.max_bounces = Some(bounces);
    }

    /// Records a non-fatal problem met while loading.
    pub(crate) fn warn(&mut self, message: impl Into<String>) {
        self.warnings.push(message.into());
    }

    internal! {
        /// The meshes added so far.
        #[cfg(any(test, feature = "testing"))]
        pub fn meshes(&self) -> &[Mesh] {
            &self.meshes
        }
    }

    /// The materials added so far, by index.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    internal! {
        /// The textures added so far, by index.
        #[cfg(any(test, feature = "testing"))]
        pub fn textures(&self) -> &[Texture] {
            &self.textures
        }
    }

    internal! {
        /// The lights added so far (area lights are made by [`build`](Self::build)).
        #[cfg(any(test, feature = "testing"))]
        pub fn lights(&self) -> &[Light] {
            &self.lights
        }
    }

    /// The camera, if one was loaded or set; without one, [`build`](Self::build) frames the scene.
    pub fn camera(&self) -> Option<&Camera> {
        self.camera.as_ref()
    }

    /// Adds a camera of the scene file with its names: the first one added becomes the camera (unless one was
    /// set), the others can be chosen by [`select_camera`](Self::select_camera).
    pub fn add_camera(&mut self, camera: NamedCamera) {
        if self.camera.is_none() {
            self.camera = Some(camera.camera.clone());
        }
        self.cameras.push(camera);
    }

    /// Every camera of the scene file, in the order met (glTF: the nodes' depth-first order; USD: the prims').
    pub fn cameras(&self) -> &[NamedCamera] {
        &self.cameras
    }

    /// Makes the camera named `name` (a glTF node or camera name, a USD prim name or path; the first match in
    /// [`cameras`](Self::cameras)) the camera; an error listing the names when none has it.
    pub fn select_camera(&mut self, name: &str) -> Result<(), UnknownCamera> {
        match self.cameras.iter().find(|c| c.is_named(name)) {
            Some(c) => {
                self.camera = Some(c.camera.clone());
                Ok(())
            }
            None => Err(UnknownCamera {
                name: name.to_owned(),
                available: self
                    .cameras
                    .iter()
                    .map(|c| match &c.path {
                        Some(p) if *p != c.name => format!("{} ({p})", c.name),
                        _ => c.name.clone(),
                    })
                    .collect(),
            }),
        }
    }

    /// The maximum number of bounces the scene asks for, if any.
    pub fn max_bounces(&self) -> Option<u32> {
        self.max_bounces
    }

    /// Problems met while loading.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    internal! {
        /// The media added so far, by index.
        #[cfg(any(test, feature = "testing"))]
        pub fn media(&self) -> &[Arc<dyn Medium>] {
            &self.media
        }
    }
}

impl SceneBuilder {
    /// An empty builder: no meshes, materials or lights, and a camera framing whatever is added.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a world-space triangle mesh made of `positions` and counter-clockwise `indices` into them, with the
    /// material at index `material` (as returned by [`add_material`](Self::add_material)). Normals are
    /// generated from the faces. Returns the index of the mesh.
    ///
    /// Fails, adding nothing, when an index is out of range, a position is not finite or the material does
    /// not exist.
    pub fn add_triangle_mesh(
        &mut self,
        positions: Vec<Vec3>,
        indices: Vec<[u32; 3]>,
        material: u32,
    ) -> Result<usize, SceneError> {
        let invalid =
            |what: String| SceneError::new(BUILDER_PATH, SceneErrorKind::InvalidReference(what));
        if material as usize >= self.materials.len() {
            return Err(invalid(format!(
                "material {material} of a mesh, but only {} materials were added",
                self.materials.len()
            )));
        }
        if let Some(i) = indices
            .iter()
            .flatten()
            .find(|&&i| i as usize >= positions.len())
        {
            return Err(invalid(format!(
                "vertex index {i} of a mesh with {} positions",
                positions.len()
            )));
        }
        if !positions.iter().all(|p| p.is_finite()) {
            return Err(SceneError::new(
                BUILDER_PATH,
                SceneErrorKind::malformed(MalformedPart::Mesh, "a mesh position is not finite"),
            ));
        }
        self.add_mesh(Mesh {
            name: format!("mesh{}", self.meshes.len()),
            positions,
            indices,
            material,
            ..Mesh::default()
        });
        Ok(self.meshes.len() - 1)
    }

    /// Sets the camera, replacing any from a loaded file.
    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = Some(camera);
    }

    /// Adds a point light at `position` with radiant `intensity` (W/sr per channel).
    pub fn add_point_light(&mut self, position: Vec3, intensity: Rgb) {
        self.add_light(Light::Point(PointLight {
            position,
            intensity,
        }));
    }

    /// Adds a directional light travelling along `direction` (normalised here) with `irradiance` (W/m² per
    /// channel at normal incidence).
    pub fn add_directional_light(&mut self, direction: Vec3, irradiance: Rgb) {
        self.add_light(Light::Directional(DirectionalLight {
            direction: direction.normalize_or(Vec3::NEG_Y),
            irradiance,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::EnvironmentLight;
    use crate::material::Material;
    use crate::scene::DEFAULT_ENVIRONMENT_RADIANCE;

    #[test]
    fn textured_emission_alone_does_not_light_a_scene() {
        let mut b = SceneBuilder::new();
        let tri = || (vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
        let grey = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, grey).unwrap();
        assert!(!b.has_own_lighting());
        let mut glow = Material::lambertian("glow", Rgb::splat(0.5));
        glow.emission = Rgb::ONE;
        glow.emission_texture = Some(0);
        let textured = b.add_material(glow.clone());
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, textured).unwrap();
        assert!(!b.has_own_lighting(), "textured emission is detail");
        glow.emission_texture = None;
        let fixture = b.add_material(glow);
        assert!(
            !b.has_own_lighting(),
            "an emissive material that no mesh uses lights nothing"
        );
        let (p, i) = tri();
        b.add_triangle_mesh(p, i, fixture).unwrap();
        assert!(
            b.has_own_lighting(),
            "an untextured emitter is a light fixture"
        );
        let lighting = b.own_lighting();
        assert_eq!(
            (lighting.emissive_meshes, lighting.textured_emissive_meshes),
            (1, 1)
        );
        assert_eq!(lighting.describe(), "1 mesh with untextured emission");
    }

    #[test]
    fn light_by_default_adds_the_white_environment_only_to_an_unlit_scene() {
        let mut unlit = SceneBuilder::new();
        assert!(unlit.light_by_default());
        let env = unlit.build().unwrap();
        match env.environment_light() {
            Some(EnvironmentLight::Constant(c)) => {
                assert_eq!(*c, Rgb::splat(DEFAULT_ENVIRONMENT_RADIANCE))
            }
            other => panic!("expected the constant default environment, got {other:?}"),
        }
        let mut lit = SceneBuilder::new();
        lit.add_point_light(Vec3::Y, Rgb::ONE);
        assert!(
            !lit.light_by_default(),
            "a scene that lights itself is left alone"
        );
        assert!(lit.build().unwrap().environment_light().is_none());
    }

    #[test]
    fn add_triangle_mesh_validates_indices_and_material() {
        let mut b = SceneBuilder::new();
        let tri = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        assert!(b
            .add_triangle_mesh(tri.clone(), vec![[0, 1, 2]], 0)
            .is_err());
        let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let err = b
            .add_triangle_mesh(tri.clone(), vec![[0, 1, 3]], m)
            .unwrap_err();
        assert!(err.to_string().contains("vertex index 3"), "{err}");
        assert!(b
            .add_triangle_mesh(vec![Vec3::NAN, Vec3::X, Vec3::Y], vec![[0, 1, 2]], m)
            .is_err());
        assert!(b.meshes().is_empty());
        assert_eq!(b.add_triangle_mesh(tri, vec![[0, 1, 2]], m).unwrap(), 0);
        assert_eq!(b.meshes()[0].normals.len(), 3);
        b.add_point_light(Vec3::Y, Rgb::ONE);
        b.add_directional_light(Vec3::ZERO, Rgb::ONE);
        b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, 1.0));
        let scene = b.build().unwrap();
        assert_eq!(scene.triangle_count(), 1);
        assert_eq!(scene.lights().len(), 2);
    }

    /// Meshes handed to `add_mesh` without normals get them from their faces; a dangling index must reach
    /// `build`'s typed error, not panic while the normals are generated (issue 35).
    #[test]
    fn add_mesh_with_a_dangling_index_is_an_error_at_build_not_a_panic() {
        use crate::geometry::{MeshMotion, MotionSteps};
        use crate::math::Vec2;
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let dangling = Mesh {
            name: "dangling".into(),
            positions: positions.clone(),
            indices: vec![[0, 1, 7]],
            ..Mesh::default()
        };
        let short_step = Mesh {
            name: "short step".into(),
            positions: positions.clone(),
            indices: vec![[0, 1, 2]],
            motion: Some(MeshMotion {
                steps: MotionSteps {
                    count: 2,
                    open: 0.0,
                    close: 1.0,
                },
                positions: vec![positions.clone(), positions[..2].to_vec()],
                normals: Vec::new(),
            }),
            ..Mesh::default()
        };
        let short_uvs = Mesh {
            name: "short uvs".into(),
            positions: positions.clone(),
            uvs: Some(vec![Vec2::ZERO]),
            indices: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let cases = [
            (dangling, "vertex index 7"),
            (short_step, "motion steps"),
            (short_uvs, "texture coordinates"),
        ];
        for (mesh, names) in cases {
            let mut b = SceneBuilder::new();
            b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
            b.add_mesh(mesh);
            let err = b.build().err().expect("refused");
            assert!(err.to_string().contains(names), "{err}");
        }
    }

    #[test]
    fn build_refuses_meshes_over_the_memory_budget_before_allocating() {
        use crate::scene::{BYTES_PER_TRIANGLE, BYTES_PER_VERTEX};
        // Room for two triangles and four vertices.
        let limits =
            crate::limits::Limits::with_memory(2 * BYTES_PER_TRIANGLE + 4 * BYTES_PER_VERTEX);
        let mut b = SceneBuilder::with_limits(limits);
        let m = b.add_material(Material::lambertian("grey", Rgb::splat(0.5)));
        let quad = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        b.add_triangle_mesh(quad.clone(), vec![[0, 1, 2], [1, 3, 2]], m)
            .unwrap();
        assert!(b.check_mesh("one more", 1, 0).is_err());
        assert!(b.check_mesh("one more", 0, 1).is_err());
        b.add_triangle_mesh(quad, vec![[0, 1, 2]], m).unwrap();
        let Err(err) = b.build() else {
            panic!("3 triangles and 8 vertices must not fit a budget of 2 and 4")
        };
        let msg = err.to_string();
        assert!(
            msg.contains("the scene") && msg.contains("--memory-limit"),
            "{msg}"
        );
    }

    #[test]
    fn build_refuses_non_finite_cameras_lights_and_emission() {
        /// A scene part that `build` must refuse, and a word its error names.
        type Case = (&'static str, fn(&mut SceneBuilder));
        let cases: [Case; 4] = [
            ("camera", |b| {
                b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, f32::NAN))
            }),
            ("camera", |b| {
                b.set_camera(Camera::look_at(Vec3::Z, Vec3::ZERO, 4.0))
            }),
            ("light", |b| {
                b.add_point_light(Vec3::Y, Rgb::splat(f32::INFINITY))
            }),
            ("emission", |b| {
                let mut m = Material::lambertian("lamp", Rgb::ONE);
                m.emission = Rgb::splat(f32::NAN);
                b.add_material(m);
            }),
        ];
        for (what, make) in cases {
            let mut b = SceneBuilder::new();
            make(&mut b);
            let err = b.build().err().expect("refused");
            assert!(err.to_string().contains(what), "{err}");
        }
    }
}
