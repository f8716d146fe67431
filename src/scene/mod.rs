//! The scene model (surfaces, materials, textures, lights, camera) and its loaders.
//!
//! Loaders fill a [`SceneBuilder`]; [`SceneBuilder::build`] flattens the meshes into one BVH (moving ones into a
//! motion BVH, instances of prototypes into a two-level one), turns emissive triangles into area lights and
//! builds the light-selection distribution.

mod builder;
mod camera;
mod error;
internal! { pub mod gltf; }
mod gltf_accessors;
mod gltf_animation;
mod gltf_check;
mod gltf_deform;
mod instancing;
mod names;
internal! {
    pub mod obj;
    pub mod usd;
    pub use builder::BUILDER_PATH;
    pub use camera::{blender_focal_length, CameraMotion, CAMERA_KEYS};
    pub use names::{Emitter, LightTag, MediumTag, SceneNames, ENVIRONMENT_NAME};
    pub use instancing::{MeshInstance, BYTES_PER_INSTANCE};
}
pub use camera::{Camera, LensError, NamedCamera, Projection, ThinLens, UnknownCamera};
#[cfg(feature = "testing")]
pub use names::CryptoNames;

pub use crate::volume::{DensityError, MissingFrame, VolumeError};
pub use error::{SceneError, SceneErrorKind};

use crate::geometry::{Bvh, InstanceBvh, Mesh, MotionBvh, SurfacePoint, TriangleHierarchy};
use crate::geometry::{Instance, TriangleHit};
use crate::light::{AreaLight, EnvironmentLight, Light, LightBvh, LightSampler};
use crate::material::{AlphaMode, Material, ShadingPoint, TexCoord, Texture};
use crate::math::{hash_to_unit, Aabb, Frame, Ray, Rgb, Vec2, Vec3, Vec4};
use crate::volume::Medium;
use names::SurfaceObject;
use std::path::Path;
use std::sync::{Arc, OnceLock};

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

/// Radiance of the neutral environment that lights a scene without lighting of its own (see
/// [`SceneBuilder::has_own_lighting`]), as glTF viewers light such files: the CLI adds it.
pub const DEFAULT_ENVIRONMENT_RADIANCE: f32 = 1.0;

/// A scene's own light sources by kind ([`SceneBuilder::own_lighting`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OwnLighting {
    /// Point, spot and directional lights.
    pub punctual: usize,
    /// Whether the scene has an environment light.
    pub environment: bool,
    /// Meshes whose material has untextured emission (light fixtures).
    pub emissive_meshes: usize,
    /// Meshes whose emission an `emissiveTexture` modulates: detail, not lighting (they are still sampled as
    /// lights).
    pub textured_emissive_meshes: usize,
    /// Media that emit (fire, glowing gas).
    pub emitting_media: usize,
}

impl OwnLighting {
    /// Whether these sources light the scene (everything but textured emission counts).
    pub fn lights_the_scene(&self) -> bool {
        self.punctual > 0 || self.environment || self.emissive_meshes > 0 || self.emitting_media > 0
    }

    /// The sources that count, in words ("2 punctual lights, 1 emissive mesh"); empty when there is none.
    pub fn describe(&self) -> String {
        let count = crate::light::counted;
        let mut parts = Vec::new();
        if self.punctual > 0 {
            parts.push(count(self.punctual, "punctual light", "punctual lights"));
        }
        if self.environment {
            parts.push("an environment light".to_owned());
        }
        if self.emissive_meshes > 0 {
            parts.push(count(
                self.emissive_meshes,
                "mesh with untextured emission",
                "meshes with untextured emission",
            ));
        }
        if self.emitting_media > 0 {
            parts.push(count(
                self.emitting_media,
                "emitting medium",
                "emitting media",
            ));
        }
        parts.join(", ")
    }
}

/// Reports the keys in `unknown`, found at `at` (`node 'smoke': nimbus_volume`), which the loader will ignore:
/// one warning each, or when `strict` ([`LoadOptions::strict`]) an error naming the first.
pub(crate) fn report_unknown_keys(
    builder: &mut SceneBuilder,
    strict: bool,
    at: &str,
    unknown: &[crate::params::UnknownKey],
) -> Result<(), SceneErrorKind> {
    let shown = |key: &crate::params::UnknownKey, verb: &str| {
        crate::limits::one_line(&format!("{at}: {key}{verb}{}", key.hint()), 300)
    };
    if let (true, Some(first)) = (strict, unknown.first()) {
        return Err(SceneErrorKind::UnknownKey(shown(first, "")));
    }
    for key in unknown {
        builder.warn(shown(key, " ignored"));
    }
    Ok(())
}

/// How a scene file is loaded: the same options for every format (glTF, OBJ, USD).
#[derive(Clone, Copy, Default)]
pub struct LoadOptions<'a> {
    /// Applied to every VDB volume declaration (glTF `nimbus_volume`, USD `Volume`) after it is read and before
    /// its medium is built, to compare majorant structures or shadow estimators on the same scene.
    /// Only the crate itself makes one (`nimbus converge`, and its tests with the `testing` feature): volume
    /// declarations are not part of the API.
    pub volume_override: Option<VolumeOverride<'a>>,
    /// VDB files given in memory by name: a volume whose `file` equals one of these names reads its bytes
    /// instead of the file system (the bundled demo).
    pub embedded: &'a [(&'a str, &'static [u8])],
    /// The memory budget for allocations sized by the files (whole-file reads, majorant structures, decoded
    /// textures).
    pub limits: crate::limits::Limits,
    /// The shot's frame: VDB sequences read this frame's file (frame 1 when `None`), glTF animations are
    /// sampled at `frame / fps` seconds (not at all when `None`, unless a shutter is set: then at frame 1)
    /// and USD stages read at the frame's time code.
    pub frame: Option<i64>,
    /// Frames per second of the shot (`--fps`): glTF's default is [`crate::frames::DEFAULT_FPS`]; a USD stage's
    /// own is its `framesPerSecond`.
    pub fps: Option<f64>,
    /// The motion-blur shutter (`--shutter`), in frames relative to the frame; `None` renders an instant.
    /// Moving things are sampled across it (glTF cameras and meshes at motion steps, see
    /// `gltf_animation::shutter_poses`) and media with a velocity grid are blurred over it.
    pub shutter: Option<crate::frames::Shutter>,
    /// Catmull-Clark levels of every USD mesh whose `subdivisionScheme` is `catmullClark` (`--subdivision-level`),
    /// over the mesh's own `refineLevel`; `None`: its `refineLevel`, else 2.
    pub subdivision_level: Option<u32>,
    /// The glTF `KHR_materials_variants` variant to load, by name (`--variant`): each primitive whose mappings
    /// name it takes the mapped material, every other its own. `None` loads every primitive's own material,
    /// and a file with variants warns once, listing them. A name the file does not declare is an error that
    /// lists its variants; so is any name for OBJ and USD files, which have no material variants.
    pub variant: Option<&'a str>,
    /// Refuse scene-file keys the renderer does not know (`--strict`): a `nimbus_*` extras key, a key inside a
    /// `nimbus_volume`, `nimbus_medium`, `nimbus_camera` or `nimbus_environment` object, or a USD `nimbus:`
    /// attribute that no table declares. Without it each is a warning naming the closest known key.
    pub strict: bool,
}

/// A change applied to every volume declaration a loader reads ([`LoadOptions::volume_override`]): a rendering
/// method forced on every medium ([`VolumeOverride::method`], `nimbus converge`'s and the Python module's
/// `volume_method`), or, inside the crate, any change to the declaration.
#[derive(Clone, Copy)]
pub struct VolumeOverride<'a>(Override<'a>);

/// What a [`VolumeOverride`] does.
#[derive(Clone, Copy)]
enum Override<'a> {
    /// Calls the function on each declaration.
    Function(&'a dyn Fn(&mut crate::volume::VolumeSpec)),
    /// Forces the method on each medium.
    Method(crate::converge::Method),
}

impl<'a> VolumeOverride<'a> {
    internal! {
        /// The override that calls `f` on each volume declaration.
        pub fn new(f: &'a dyn Fn(&mut crate::volume::VolumeSpec)) -> Self {
            VolumeOverride(Override::Function(f))
        }
    }

    /// The override that renders every medium by `method` (its free-flight estimator and majorants), as
    /// `nimbus converge` compares them.
    pub fn method(method: crate::converge::Method) -> Self {
        VolumeOverride(Override::Method(method))
    }
}

impl LoadOptions<'_> {
    /// Gives `spec` the memory budget, then applies the volume override, if any. Every loader calls this on
    /// each volume it declares.
    pub(crate) fn apply_volume_override(&self, spec: &mut crate::volume::VolumeSpec) {
        spec.limits = self.limits;
        spec.frame = self.frame;
        spec.shutter = self.shutter;
        if let Some(fps) = self.fps {
            spec.fps = fps;
        }
        match self.volume_override {
            Some(VolumeOverride(Override::Function(f))) => f(spec),
            Some(VolumeOverride(Override::Method(m))) => m.apply_to_volume(spec),
            None => {}
        }
    }

    /// The bytes of the embedded file named `file`, if there is one.
    pub(crate) fn embedded_file(&self, file: &str) -> Option<&'static [u8]> {
        self.embedded
            .iter()
            .find(|(name, _)| *name == file)
            .map(|(_, bytes)| *bytes)
    }
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

/// Everything a loader produces, before acceleration structures are built: add meshes, materials, textures,
/// lights and media, then [`build`](Self::build) the renderable [`Scene`]. References between them (a mesh's
/// material, a material's textures and interior medium) are checked when the scene is built, so a dangling
/// index is an error, never a panic.
#[derive(Default)]
pub struct SceneBuilder {
    meshes: Vec<Mesh>,
    /// Object-space meshes that `instances` place.
    prototypes: Vec<Mesh>,
    /// Placements of `prototypes`, each with its own identity.
    instances: Vec<MeshInstance>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    /// Punctual lights and the environment (area lights are added by `build`).
    lights: Vec<Light>,
    /// The name and light group of each light in `lights`.
    light_tags: Vec<LightTag>,
    /// The camera the scene renders from: the first of `cameras` unless one was chosen or set.
    camera: Option<Camera>,
    /// Every camera of the scene file with its names, in the order the loader met them.
    cameras: Vec<NamedCamera>,
    max_bounces: Option<u32>,
    warnings: Vec<String>,
    /// Mesh interiors (referenced by `Material::interior`) and position-filled volumes.
    media: Vec<Arc<dyn Medium>>,
    /// The asset and compositing tags of each medium in `media`.
    media_tags: Vec<MediumTag>,
    /// The motion-blur shutter, in frames relative to the frame.
    shutter: Option<crate::frames::Shutter>,
    /// Whether the scene asks for a transparent film (glTF scene extras `nimbus_transparent`).
    transparent: bool,
    /// The load's memory budget, which the scene's meshes must fit (see [`SceneBuilder::check_mesh`]).
    limits: crate::limits::Limits,
    /// Triangles in `meshes` and `prototypes`.
    triangles: u64,
    /// Vertices in `meshes` and `prototypes`, counted once more for each motion step.
    vertices: u64,
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

    /// Whether the scene lights itself: a punctual or environment light, an emitting medium, or a mesh whose
    /// material has untextured emission (a light fixture, such as a Cornell box's ceiling light). Emission that an
    /// `emissiveTexture` modulates (the screens and lamps on an asset such as DamagedHelmet) does not count:
    /// it is detail, which glTF viewers show under their own default environment. The CLI lights a scene for
    /// which this is false with a neutral environment.
    pub fn has_own_lighting(&self) -> bool {
        self.own_lighting().lights_the_scene()
    }

    /// Lights a scene without lighting of its own ([`Self::has_own_lighting`] false) as the CLI and the Python
    /// module do: with a uniform environment of radiance [`DEFAULT_ENVIRONMENT_RADIANCE`]. Returns whether it
    /// was added (a scene that lights itself is left as it is).
    pub fn light_by_default(&mut self) -> bool {
        if self.has_own_lighting() {
            return false;
        }
        self.set_environment(EnvironmentLight::Constant(Rgb::splat(
            DEFAULT_ENVIRONMENT_RADIANCE,
        )));
        true
    }

    /// The scene's own light sources by kind, as [`Self::has_own_lighting`] counts them.
    pub fn own_lighting(&self) -> OwnLighting {
        let emitting_meshes = |textured: bool| {
            let emits = |mesh: &Mesh| {
                self.materials
                    .get(mesh.material as usize)
                    .is_some_and(|m| m.is_emissive() && m.emission_texture.is_some() == textured)
            };
            // An emissive prototype's instances become meshes of their own when the scene is built.
            let instances = self
                .instances
                .iter()
                .filter(|i| self.prototypes.get(i.prototype as usize).is_some_and(emits));
            self.meshes.iter().filter(|m| emits(m)).count() + instances.count()
        };
        OwnLighting {
            punctual: self
                .lights
                .iter()
                .filter(|l| !matches!(l, Light::Environment(_) | Light::Area(_)))
                .count(),
            environment: self
                .lights
                .iter()
                .any(|l| matches!(l, Light::Environment(_))),
            emissive_meshes: emitting_meshes(false),
            textured_emissive_meshes: emitting_meshes(true),
            emitting_media: self.media.iter().filter(|m| m.is_emissive()).count(),
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

    /// Checks every reference between the parts (a mesh's material and vertex indices and attribute lengths, a
    /// material's textures and interior medium) and the numbers every loader must have checked already, as a
    /// last guard for scenes built in code: a camera that [`Camera::is_valid`], finite lights, positions and
    /// emission.
    fn validate(&self) -> Result<(), SceneError> {
        let invalid =
            |what: String| SceneError::new(BUILDER_PATH, SceneErrorKind::InvalidReference(what));
        let malformed =
            |what: String| SceneError::new(BUILDER_PATH, SceneErrorKind::Malformed(what));
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            if mesh.material as usize >= self.materials.len() {
                return Err(invalid(format!(
                    "mesh '{}' uses material {}, but there are {} materials",
                    mesh.name,
                    mesh.material,
                    self.materials.len()
                )));
            }
            let n = mesh.positions.len();
            if let Some(i) = mesh.indices.iter().flatten().find(|&&i| i as usize >= n) {
                return Err(invalid(format!(
                    "mesh '{}' has vertex index {i}, but {n} positions",
                    mesh.name
                )));
            }
        }
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            let Some(m) = &mesh.motion else { continue };
            let count = m.steps.count as usize;
            let consistent = count >= 2
                && m.steps.open.is_finite()
                && m.steps.close.is_finite()
                && m.steps.open <= m.steps.close
                && m.positions.len() == count
                && m.normals.len() == count
                && m.positions.iter().all(|p| p.len() == mesh.positions.len())
                && m.normals.iter().all(|n| n.len() == mesh.positions.len());
            if !consistent {
                return Err(invalid(format!(
                    "mesh '{}' has motion steps that are not at least 2 finite, ordered instants with one position and normal per vertex each",
                    mesh.name
                )));
            }
            if !m.positions.iter().flatten().all(|p| p.is_finite()) {
                return Err(malformed(format!(
                    "mesh '{}' has a non-finite position in a motion step",
                    mesh.name
                )));
            }
        }
        // After the motion steps, so that a short step is named as such rather than as the normals that could
        // not be generated for it.
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            let n = mesh.positions.len();
            let lengths_match = mesh.normals.len() == n
                && mesh.uvs.as_ref().is_none_or(|u| u.len() == n)
                && mesh.uvs1.as_ref().is_none_or(|u| u.len() == n)
                && mesh.colors.as_ref().is_none_or(|c| c.len() == n)
                && mesh.tangents.as_ref().is_none_or(|t| t.len() == n);
            if !lengths_match {
                return Err(invalid(format!(
                    "mesh '{}' has normals, texture coordinates, colours or tangents not one per position",
                    mesh.name
                )));
            }
        }
        if let Some(c) = &self.camera {
            if !c.is_valid() {
                return Err(malformed(format!(
                    "the camera needs a finite placement, 0 < yfov < pi (perspective) or a positive half height (orthographic), a positive aspect ratio and a lens with a positive radius and focus distance (yfov {}, {:?}, aspect ratio {:?}, lens {:?})",
                    c.yfov, c.projection, c.aspect_ratio, c.lens
                )));
            }
            if c.motion.as_ref().is_some_and(|m| !m.is_valid()) {
                return Err(malformed(
                    "the camera's motion needs one finite pose per step, at least two, at ordered instants"
                        .into(),
                ));
            }
        }
        for (i, light) in self.lights.iter().enumerate() {
            let finite = match light {
                Light::Point(l) => l.position.is_finite() && l.intensity.is_finite(),
                Light::Spot(l) => {
                    l.position.is_finite() && l.direction.is_finite() && l.intensity.is_finite()
                }
                Light::Directional(l) => l.direction.is_finite() && l.irradiance.is_finite(),
                Light::Area(_) | Light::Environment(_) => true,
            };
            if !finite {
                return Err(malformed(format!(
                    "light {i} has a non-finite position, direction or intensity"
                )));
            }
        }
        for mesh in self.meshes.iter().chain(&self.prototypes) {
            if !mesh.positions.iter().all(|p| p.is_finite()) {
                return Err(malformed(format!(
                    "mesh '{}' has a non-finite position",
                    mesh.name
                )));
            }
        }
        for (i, instance) in self.instances.iter().enumerate() {
            if instance.prototype as usize >= self.prototypes.len() {
                return Err(invalid(format!(
                    "instance {i} '{}' places prototype {}, but there are {} prototypes",
                    instance.name,
                    instance.prototype,
                    self.prototypes.len()
                )));
            }
            if !instance.object_to_world.is_finite() {
                return Err(malformed(format!(
                    "instance {i} '{}' has a non-finite transform",
                    instance.name
                )));
            }
        }
        for m in &self.materials {
            if let Some(t) = m.texture_ids().find(|&t| t as usize >= self.textures.len()) {
                return Err(invalid(format!(
                    "material '{}' uses texture {t}, but there are {} textures",
                    m.name,
                    self.textures.len()
                )));
            }
            if !(m.emission.is_finite() && m.emission.min_element() >= 0.0) {
                return Err(malformed(format!(
                    "material '{}' has emission {:?}, not finite and non-negative",
                    m.name, m.emission
                )));
            }
            if let Some(i) = m.interior.filter(|&i| i as usize >= self.media.len()) {
                return Err(invalid(format!(
                    "material '{}' fills its interior with medium {i}, but there are {} media",
                    m.name,
                    self.media.len()
                )));
            }
        }
        Ok(())
    }

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

/// A renderable scene, made by [`SceneBuilder::build`]; read-only (its acceleration structure is built over
/// its meshes).
pub struct Scene {
    /// World-space meshes.
    pub(crate) meshes: Vec<Mesh>,
    /// Object-space meshes that instances place.
    prototypes: Vec<Mesh>,
    /// The instances, in the order of their surface objects (after the meshes) and triangle numbers.
    placed: Vec<instancing::Placed>,
    /// The instances' two-level hierarchy, if there are instances: global triangle indices from
    /// `prims.len()` on.
    instanced: Option<InstanceBvh>,
    /// Materials.
    pub(crate) materials: Vec<Material>,
    /// Textures.
    pub(crate) textures: Vec<Texture>,
    /// All lights, area lights included.
    pub(crate) lights: Vec<Light>,
    /// Light selection by power.
    pub(crate) light_sampler: LightSampler,
    /// Light selection by importance at the shading point, built on first use (only renders that choose it
    /// pay for it).
    light_bvh: OnceLock<LightBvh>,
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
    bvh: Bvh,
    /// The moving triangles (transform motion blur), if any: global indices from `static_count` on.
    motion: Option<MotionBvh>,
    /// The number of static triangles.
    static_count: u32,
    /// True when some material is a cut-out or partly covering, so hits must be alpha-tested.
    has_alpha: bool,
    /// True when some material may be an invisible (index-matched) boundary, which shadow rays pass through;
    /// without one, any surface between a point and a light blocks it.
    has_invisible_boundaries: bool,
    /// The emitters (for light groups), Cryptomatte names, holdouts and shadow catchers.
    names: SceneNames,
    /// Whether the scene file asks for a transparent film.
    transparent: bool,
    /// The mesh and triangle of each global triangle index.
    prims: Vec<(u32, u32)>,
    /// The area light of each global triangle index (`u32::MAX`: none).
    light_of_prim: Vec<u32>,
}

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
                    let point = SurfacePoint::on_triangle([v0, v1, v2], b0, b1, b2, geometric_normal);
                    ([v0, v1, v2], normals, geometric_normal, point)
                }
                Some(placed) => {
                    let world = placed.triangle([v0, v1, v2], normals, [b0, b1, b2]);
                    (world.vertices, world.normals, world.geometric_normal, world.point)
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
