//! glTF 2.0 loader (`.gltf` with external or data-URI buffers, and `.glb`), on top of the `gltf` crate.
//!
//! Reads the default scene's node hierarchy (TRS and matrix transforms), triangle meshes (indexed or not,
//! strips and fans triangulated; POSITION, NORMAL, TANGENT, TEXCOORD_0, TEXCOORD_1, COLOR_0, sparse or not,
//! with the component types of `KHR_mesh_quantization`; see `gltf_accessors`), morph targets at their default
//! weights and skins at their rest pose (see `gltf_deform`), every camera (perspective or orthographic, with the
//! node's or the camera object's `extras.nimbus_camera` lens; the first met in traversal order renders unless
//! another is chosen by name; see `Loader::load_camera`),
//! metallic-roughness materials with textures and the extensions listed in [`SUPPORTED_EXTENSIONS`] (the keys
//! read are listed in [`crate::material::Material`]), and `KHR_lights_punctual` lights. Normal-mapped meshes
//! without TANGENT get MikkTSpace tangents when the scene is built. Every texture reference's `texCoord` (sets 0
//! and 1) and `KHR_texture_transform` (`offset`, `rotation`, `scale`, `texCoord`) are read, for the core
//! textures and those of the extensions alike. `KHR_materials_variants`: a primitive takes the material its
//! `mappings` give the variant [`LoadOptions::variant`] names, else its own; without a variant, a file that has
//! some warns once, listing them.
//!
//! Scene `extras` read: `nimbus_environment` (see [`crate::light::EnvironmentLight`]), `max_bounces`, and
//! `nimbus_light_units`: `"photometric"` (the default) or `"radiometric"`.
//!
//! Light units: `KHR_lights_punctual` gives point and spot intensities in candela and directional ones in lux.
//! By default they are converted as Blender's importer, three.js and Bevy read them, at 683 lm/W: W/sr =
//! cd / 683 and W/m² = lx / 683 ([`LUMENS_PER_WATT`]). With `"nimbus_light_units": "radiometric"` the values
//! are taken as W/sr and W/m² unchanged. Emission (`emissiveFactor` × `emissiveStrength`) is radiance in
//! either case.
//!
//! Hostile input: before the `gltf` crate validates or reads anything, every index field, the node forest,
//! cameras, lights and node transforms are checked here (see `gltf_check`), since the crate panics on some
//! of them; then the crate's validation runs, except that the extensions Nimbus implements may be listed in
//! `extensionsRequired` (the crate rejects some of them). Each accessor's type, component type, byte range and
//! sparse indices are checked as it is read (by hand, not by the crate's reader), material factors when the
//! material is built. The scene, buffer and image files are read within [`LoadOptions::limits`], and images
//! decode under it. Animation channels with a target path the crate does not know (`KHR_animation_pointer`)
//! are removed before it parses the file, with a warning. A static mesh drawn more than once (by several
//! nodes or by `EXT_mesh_gpu_instancing`) is read once as object-space prototypes and placed as instances in the
//! two-level BVH (`Loader::place_mesh`); skinned, morphed and moving meshes are copied per node. Each copy's and
//! prototype's size, and each instance record, counts against the memory budget before it is made
//! ([`SceneBuilder::check_mesh`]), and posing meshes (joint
//! matrices once per skin and pose, morph-target and skinned vertices) against the work it allows. A
//! malformed file is an error naming the element, never a panic.

use super::gltf_accessors::{check_bytes, read_floats, read_indices, Usage};
use super::gltf_check::SkippedChannels;
use super::{gltf_animation, gltf_deform};
use super::{
    Camera, CameraMotion, LightTag, LoadOptions, MediumTag, NamedCamera, Projection, SceneBuilder,
    SceneError, SceneErrorKind, ThinLens,
};
use crate::geometry::{CompositingTags, Mesh, MeshMotion};
use crate::light::{
    DirectionalLight, EnvironmentLight, EnvironmentMap, Light, PointLight, SpotLight,
    LUMENS_PER_WATT,
};
use crate::limits::{one_line, Limits, WorkBudget};
use crate::material::{
    AlphaMode, Anisotropy, ClearcoatLayer, ColorSpace, DiffuseTransmission, Filter, Iridescence,
    Material, MipImage, Sampler, SheenLayer, SpecularGlossiness, Texture, UvTransform, Wrap,
    UV_SETS,
};
use crate::math::{Mat4, Quat, Rgb, Vec2, Vec3, Vec4};
use crate::params::{parse_rgb, unknown_json_keys, unknown_json_names, UnknownKey};
use gltf::json::validation::Validate;
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;

/// The glTF extensions Nimbus implements; any other extension in `extensionsRequired` is an error, and any
/// other in `extensionsUsed` a warning.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_volume",
    "KHR_materials_specular",
    "KHR_materials_unlit",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_variants",
    "KHR_materials_anisotropy",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_dispersion",
    "KHR_materials_iridescence",
    "KHR_texture_transform",
    "EXT_mesh_gpu_instancing",
];

/// Deepest node hierarchy accepted; deeper hierarchies are errors (cycles are refused before loading).
const MAX_NODE_DEPTH: usize = 256;

/// Longest text quoted from the file (a URI) in an error message.
const QUOTE: usize = 120;

/// Reads the bytes a buffer or image URI names: a `data:` URI decoded, else a file (a relative path, an
/// absolute one or a `file://` URI, percent-decoded) read within the memory budget. Errors are one line.
fn read_uri(uri: &str, base: &Path, limits: &crate::limits::Limits) -> Result<Vec<u8>, String> {
    if uri.starts_with("data:") {
        return gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), Some(base))
            .map(|d| d.0)
            .map_err(|e| one_line(&e.to_string(), QUOTE));
    }
    let rest = uri.strip_prefix("file://").unwrap_or(uri);
    if rest.len() == uri.len() && uri.contains("://") {
        return Err("only data: and file URIs are read".into());
    }
    let decoded = percent_decode(rest).ok_or("the URI is not valid percent-encoded UTF-8")?;
    crate::limits::read_file(&base.join(decoded), limits)
        .map_err(|e| one_line(&e.to_string(), QUOTE))
}

/// `%XX` escapes decoded; `None` if one is malformed or the result is not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Loads a `.gltf` or `.glb` file.
pub fn load(path: &Path, options: &LoadOptions) -> Result<SceneBuilder, SceneError> {
    let bytes = crate::limits::read_file(path, &options.limits)
        .map_err(|e| SceneError::new(path, SceneErrorKind::Io(e)))?;
    load_slice(&bytes, path, options)
}

/// Loads glTF or GLB bytes; `path` names the file in errors and its folder resolves external URIs.
pub fn load_slice(
    bytes: &[u8],
    path: &Path,
    options: &LoadOptions,
) -> Result<SceneBuilder, SceneError> {
    let err = |kind| SceneError::new(path, kind);
    let malformed = |m: String| err(SceneErrorKind::Malformed(m));
    let (root, blob, skipped) = parse(bytes).map_err(malformed)?;
    super::gltf_check::check_document(&root).map_err(&err)?;
    let mut warnings = validate(&root).map_err(&err)?;
    warnings.extend(skipped.warnings.iter().cloned());
    let document = gltf::Document::from_json_without_validation(root);
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let variants = variant_names(&document).map_err(malformed)?;
    let variant = choose_variant(&variants, options.variant).map_err(&err)?;
    if options.variant.is_none() && !variants.is_empty() {
        let names: Vec<String> = variants.iter().map(|n| one_line(n, QUOTE)).collect();
        warnings.push(format!(
            "the file has material variants: {} (--variant NAME chooses one)",
            names.join(", ")
        ));
    }

    let mut blob = blob;
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let name = match buffer.source() {
            gltf::buffer::Source::Bin => {
                format!("buffers[{}] (the GLB binary chunk)", buffer.index())
            }
            gltf::buffer::Source::Uri(u) if u.starts_with("data:") => {
                format!("buffers[{}] (data URI)", buffer.index())
            }
            gltf::buffer::Source::Uri(u) => {
                format!("buffers[{}] ('{}')", buffer.index(), one_line(u, QUOTE))
            }
        };
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                malformed(format!(
                    "{name}: the file has no binary chunk (or two buffers use it)"
                ))
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, &base, &options.limits)
                .map_err(|e| err(SceneErrorKind::InvalidReference(format!("{name}: {e}"))))?,
        };
        if data.len() < buffer.length() {
            return Err(malformed(format!(
                "{name} holds {} bytes but declares byteLength {}",
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(gltf::buffer::Data(data));
    }
    // A still with a shutter is frame 1 of the shot, as VDB sequences read it.
    let frame = options.frame.or(options.shutter.map(|_| 1));
    let fps = options.fps.unwrap_or(crate::frames::DEFAULT_FPS);
    let animations = match frame {
        Some(_) if document.animations().len() > 0 => Some(
            gltf_animation::Animations::read(&document, &buffers, &options.limits, &skipped)
                .map_err(&err)?,
        ),
        _ => None,
    };
    let pose = match (frame, &animations) {
        (Some(frame), Some(animations)) => {
            warnings.extend(animations.warnings.iter().cloned());
            animations.pose_at(&document, (frame as f64 / fps) as f32)
        }
        _ => gltf_animation::Pose {
            locals: document
                .nodes()
                .map(|n| Mat4::from_cols_array_2d(&n.transform().matrix()))
                .collect(),
            weights: vec![None; document.nodes().len()],
        },
    };
    let motion = match (frame, options.shutter, &animations) {
        (Some(frame), Some(shutter), Some(animations)) => {
            gltf_animation::shutter_poses(animations, &document, frame, fps, shutter)
        }
        _ => None,
    };
    let mut loader = Loader {
        pose,
        motion,
        path,
        document: &document,
        base,
        buffers: &buffers,
        builder: SceneBuilder::with_limits(options.limits),
        texture_cache: HashMap::new(),
        images: HashMap::new(),
        material_map: HashMap::new(),
        options,
        light_unit_scale: 1.0 / LUMENS_PER_WATT,
        node_worlds: Vec::new(),
        skin_warned: false,
        joints: RefCell::new(HashMap::new()),
        work: WorkBudget::new(&options.limits),
        variant,
        variant_count: variants.len(),
        mesh_users: mesh_users(&document),
        prototypes: HashMap::new(),
    };
    loader.builder.warnings.append(&mut warnings);
    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| malformed("the file has no scene".into()))?;
    loader.read_light_units(scene.extras())?;
    for node in scene.nodes() {
        let top = NodeContext {
            tags: CompositingTags::default(),
            asset: node_name(&node),
        };
        loader.visit(node, Mat4::IDENTITY, 0, &top)?;
    }
    loader.read_scene_extras(scene.extras())?;
    Ok(loader.builder)
}

type JsonParse = (gltf::json::Root, Option<Vec<u8>>, SkippedChannels);

/// A mesh's name for messages and as its Cryptomatte object name: its own, else `mesh N`.
fn mesh_name(mesh: &gltf::Mesh) -> String {
    mesh.name()
        .map_or_else(|| format!("mesh {}", mesh.index()), |n| one_line(n, QUOTE))
}

/// How many nodes of the document draw each mesh, by mesh index.
fn mesh_users(document: &gltf::Document) -> Vec<u32> {
    let mut users = vec![0u32; document.meshes().len()];
    for node in document.nodes() {
        if let Some(n) = node.mesh().and_then(|m| users.get_mut(m.index())) {
            *n = n.saturating_add(1);
        }
    }
    users
}

fn parse(bytes: &[u8]) -> Result<JsonParse, String> {
    if bytes.starts_with(b"glTF") {
        // The crate subtracts the header size from the declared length unchecked.
        let length = bytes
            .get(8..12)
            .map(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]));
        if length.is_none_or(|l| l < 12) {
            return Err(format!(
                "GLB container: the header's length field ({}) is shorter than the 12-byte header",
                length.map_or_else(|| "missing".to_owned(), |l| l.to_string())
            ));
        }
        let mut glb =
            gltf::binary::Glb::from_slice(bytes).map_err(|e| format!("GLB container: {e}"))?;
        let (root, skipped) = parse_json(&glb.json).map_err(|e| format!("JSON chunk: {e}"))?;
        Ok((root, glb.bin.take().map(|b| b.into_owned()), skipped))
    } else {
        let (root, skipped) = parse_json(bytes).map_err(|e| format!("JSON: {e}"))?;
        Ok((root, None, skipped))
    }
}

/// The document in `json`, less the animation channels the `gltf` crate cannot read (see
/// `gltf_check::skip_unknown_channels`), and which those were.
fn parse_json(json: &[u8]) -> Result<(gltf::json::Root, SkippedChannels), String> {
    let (edited, skipped) = super::gltf_check::skip_unknown_channels(json)?;
    let root = match edited {
        Some(document) => gltf::json::deserialize::from_value(document),
        None => gltf::json::deserialize::from_slice(json),
    }
    .map_err(|e| e.to_string())?;
    Ok((root, skipped))
}

/// Runs the `gltf` crate's validation, accepting the required extensions Nimbus implements. Returns warnings
/// for used-but-unknown extensions.
fn validate(root: &gltf::json::Root) -> Result<Vec<String>, SceneErrorKind> {
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        errors.push((path().to_string(), error));
    });
    let mut fatal = Vec::new();
    for (path, error) in errors {
        // Required extensions are checked below against Nimbus's own list.
        let required_extension = matches!(error, gltf::json::validation::Error::Unsupported)
            && path.starts_with("extensionsRequired");
        if !required_extension {
            fatal.push(one_line(&format!("{path}: {error}"), QUOTE));
        }
    }
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(SceneErrorKind::Unsupported(format!(
                "required extension {}",
                one_line(ext, QUOTE)
            )));
        }
    }
    if !fatal.is_empty() {
        return Err(SceneErrorKind::Malformed(one_line(
            &fatal.join("; "),
            4 * QUOTE,
        )));
    }
    Ok(root
        .extensions_used
        .iter()
        .filter(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str()))
        .map(|e| format!("optional extension {e} is not supported and is ignored"))
        .collect())
}

/// Skins' joint matrices by pose (0: the frame's, k + 1: motion step k) and skin index.
type JointCache = RefCell<HashMap<(usize, usize), Rc<[Mat4]>>>;

/// How a node's mesh is posed at one instant: morph weights, then skin joint matrices or the world matrix.
struct Deformation {
    weights: Vec<f32>,
    joints: Option<Rc<[Mat4]>>,
    world: Mat4,
}

struct Loader<'a> {
    path: &'a Path,
    /// Every node's local matrix and animated morph weights: the file's, or at the shot's frame.
    pose: gltf_animation::Pose,
    /// The animation at the motion steps across the shutter, when there are both.
    motion: Option<gltf_animation::ShutterPoses>,
    /// The document: texture references and the skins' joint nodes.
    document: &'a gltf::Document,
    base: PathBuf,
    buffers: &'a [gltf::buffer::Data],
    builder: SceneBuilder,
    /// Textures made so far, by glTF texture, colour space and UV mapping (set and transform bits).
    texture_cache: HashMap<(usize, ColorSpace, usize, [u32; 5]), u32>,
    images: HashMap<(usize, ColorSpace), Arc<MipImage>>,
    material_map: HashMap<Option<usize>, u32>,
    options: &'a LoadOptions<'a>,
    /// Watts per unit of a `KHR_lights_punctual` intensity (1/683 photometric, 1 radiometric).
    light_unit_scale: f32,
    /// Every node's world matrix, computed when the first skin is met.
    node_worlds: Vec<Mat4>,
    /// Whether the rest-pose warning was given.
    skin_warned: bool,
    /// Each skin's joint matrices, by pose and skin, computed once.
    joints: JointCache,
    /// The load-time work of posing meshes: joint matrices, skinned vertices and morph-target vertices.
    work: WorkBudget,
    /// The chosen `KHR_materials_variants` variant (index into the root's `variants`), if any.
    variant: Option<usize>,
    /// How many variants the file declares.
    variant_count: usize,
    /// How many nodes draw each mesh, by mesh index: a static mesh drawn more than once is instanced.
    mesh_users: Vec<u32>,
    /// The prototypes (one per triangle primitive) of each instanced mesh, by mesh index, read once.
    prototypes: HashMap<usize, Rc<[u32]>>,
}

impl Loader<'_> {
    fn error(&self, kind: SceneErrorKind) -> SceneError {
        SceneError::new(self.path, kind)
    }

    /// Warns about (or under `--strict` refuses) the keys at `at` that the loader ignores.
    fn unknown_keys(&mut self, at: &str, unknown: &[UnknownKey]) -> Result<(), SceneError> {
        super::report_unknown_keys(&mut self.builder, self.options.strict, at, unknown)
            .map_err(|kind| self.error(kind))
    }

    fn visit(
        &mut self,
        node: gltf::Node,
        parent: Mat4,
        depth: usize,
        outer: &NodeContext,
    ) -> Result<(), SceneError> {
        if depth > MAX_NODE_DEPTH {
            return Err(self.error(SceneErrorKind::Malformed(format!(
                "node {} is nested deeper than {MAX_NODE_DEPTH} levels (a cycle?)",
                node.index()
            ))));
        }
        let world = parent * self.pose.locals[node.index()];
        if !world.is_finite() {
            return Err(self.error(SceneErrorKind::Malformed(format!(
                "node {} has a non-finite transform",
                node.index()
            ))));
        }
        let extras = self.node_extras(&node)?;
        if let Some(extras) = &extras {
            let at = format!("node '{}': extras", one_line(&node_name(&node), QUOTE));
            self.unknown_keys(&at, &unknown_json_names(extras, NODE_EXTRAS, "nimbus_"))?;
        }
        let context = NodeContext {
            tags: node_tags(extras.as_ref())
                .map_err(|m| {
                    self.error(SceneErrorKind::Malformed(format!(
                        "node '{}': extras: {m}",
                        node_name(&node)
                    )))
                })?
                .or(&outer.tags),
            asset: outer.asset.clone(),
        };
        if let Some(mesh) = node.mesh() {
            let instances = self.instances(&node)?;
            let placements = instances.as_deref().unwrap_or(&[Mat4::IDENTITY]);
            if self.instanceable(&node, &mesh, &world, instances.is_some()) {
                for placement in placements {
                    self.place_mesh(&node, &mesh, &(world * *placement), &context)?;
                }
            } else {
                for placement in placements {
                    self.load_mesh(&node, mesh.clone(), &world, placement, &context)?;
                }
            }
        }
        if let Some(camera) = node.camera() {
            self.load_camera(&node, camera, &world, extras.as_ref())?;
        }
        if let Some(light) = node.light() {
            let tag = LightTag {
                name: light.name().map_or_else(|| node_name(&node), str::to_owned),
                light_group: context.tags.light_group.clone(),
            };
            self.load_light(light, &world, tag);
        }
        if let Some(extras) = &extras {
            self.load_volume(&node, extras, &world, &context)?;
        }
        for child in node.children() {
            self.visit(child, world, depth + 1, &context)?;
        }
        Ok(())
    }

    /// Adds the camera of `node` to the scene's cameras, named by the node (else by the camera object, else
    /// `camera N` for node index N). Perspective: `yfov` and `aspectRatio`; orthographic: `ymag` is the film's
    /// half height and `xmag / ymag` its aspect ratio (the image's own aspect ratio widens or narrows the film
    /// around the same height, as it does a perspective camera's field of view); magnitudes are taken as
    /// absolute values. A lens comes from `extras.nimbus_camera` ([`super::CAMERA_KEYS`]) on the node, else on
    /// the camera object; keys it does not know are warnings.
    fn load_camera(
        &mut self,
        node: &gltf::Node,
        camera: gltf::Camera,
        world: &Mat4,
        node_extras: Option<&serde_json::Value>,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .or(camera.name())
            .map_or_else(|| format!("camera {}", node.index()), str::to_owned);
        let (yfov, projection, aspect_ratio, focal_length) = match camera.projection() {
            gltf::camera::Projection::Perspective(p) => (
                p.yfov(),
                Projection::Perspective,
                p.aspect_ratio(),
                Some(super::blender_focal_length(p.yfov(), p.aspect_ratio())),
            ),
            gltf::camera::Projection::Orthographic(o) => (
                // Unused by an orthographic camera; a valid perspective angle keeps the numbers checkable.
                std::f32::consts::FRAC_PI_2,
                Projection::Orthographic {
                    half_height: o.ymag().abs(),
                },
                Some(o.xmag().abs() / o.ymag().abs()),
                None,
            ),
        };
        let at = format!("camera '{}': nimbus_camera", one_line(&name, QUOTE));
        let camera_extras = match camera.extras() {
            Some(raw) => Some(
                serde_json::from_str::<serde_json::Value>(raw.get())
                    .map_err(|e| self.error(SceneErrorKind::Malformed(format!("{at}: {e}"))))?,
            ),
            None => None,
        };
        let declared = node_extras
            .and_then(|e| e.get("nimbus_camera"))
            .or_else(|| camera_extras.as_ref().and_then(|e| e.get("nimbus_camera")));
        let lens = match declared {
            None => None,
            Some(value) => {
                if !value.is_object() {
                    return Err(self.error(SceneErrorKind::Camera {
                        at: at.into(),
                        source: crate::params::ParamError::WrongType {
                            key: "nimbus_camera".into(),
                            expected: "an object".into(),
                        }
                        .into(),
                    }));
                }
                self.unknown_keys(&at, &unknown_json_keys(value, super::CAMERA_KEYS))?;
                ThinLens::from_params(&crate::params::JsonParams::new(value), focal_length)
                    .map_err(|source| {
                        self.error(SceneErrorKind::Camera {
                            at: at.clone().into(),
                            source,
                        })
                    })?
            }
        };
        let camera_to_world = Camera::rigid(world);
        // The camera moves when its pose at some motion step differs from the frame's.
        let motion = self.motion.as_ref().and_then(|m| {
            let poses: Vec<Mat4> = m
                .worlds
                .iter()
                .map(|w| Camera::rigid(&w[node.index()]))
                .collect();
            poses
                .iter()
                .any(|p| *p != camera_to_world)
                .then(|| CameraMotion::from_matrices(m.steps, &poses))
        });
        self.builder.add_camera(NamedCamera {
            name,
            path: None,
            camera: Camera {
                camera_to_world,
                yfov,
                projection,
                lens,
                aspect_ratio,
                motion,
            },
        });
        Ok(())
    }

    /// A node's `extras` as JSON, if it has any.
    fn node_extras(&self, node: &gltf::Node) -> Result<Option<serde_json::Value>, SceneError> {
        let Some(raw) = node.extras() else {
            return Ok(None);
        };
        serde_json::from_str(raw.get()).map(Some).map_err(|e| {
            self.error(SceneErrorKind::Malformed(format!(
                "node '{}': extras: {e}",
                node_name(node)
            )))
        })
    }

    /// A node's `extras.nimbus_volume` becomes a grid medium placed by the node's world matrix, with the
    /// node's asset and compositing tags.
    fn load_volume(
        &mut self,
        node: &gltf::Node,
        extras: &serde_json::Value,
        world: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .map_or_else(|| format!("node {}", node.index()), |n| one_line(n, QUOTE));
        let Some(value) = extras.get("nimbus_volume") else {
            return Ok(());
        };
        let volume_error = |source| {
            self.error(SceneErrorKind::Volume {
                at: format!("node '{name}': nimbus_volume").into(),
                source,
            })
        };
        let mut spec = crate::volume::VolumeSpec::from_json(value, &name, &self.base, *world)
            .map_err(volume_error)?;
        let unknown = unknown_json_keys(value, crate::volume::spec::VOLUME_KEYS);
        self.unknown_keys(&format!("node '{name}': nimbus_volume"), &unknown)?;
        let file = value.get("file").and_then(|f| f.as_str());
        spec.embedded = file.and_then(|f| self.options.embedded_file(f));
        self.options.apply_volume_override(&mut spec);
        spec.asset = context.asset.clone();
        spec.tags = context.tags.clone();
        match self.builder.add_volume(&spec) {
            Ok(_) => Ok(()),
            Err(source) => Err(self.error(SceneErrorKind::Volume {
                at: format!("node '{name}': nimbus_volume").into(),
                source,
            })),
        }
    }

    fn load_light(&mut self, light: gltf::khr_lights_punctual::Light, world: &Mat4, tag: LightTag) {
        let color = Rgb::from(light.color()) * (light.intensity() * self.light_unit_scale);
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(-Vec3::Z).normalize_or_zero();
        let l = match light.kind() {
            gltf::khr_lights_punctual::Kind::Point => Light::Point(PointLight {
                position,
                intensity: color,
            }),
            gltf::khr_lights_punctual::Kind::Directional => Light::Directional(DirectionalLight {
                direction,
                irradiance: color,
            }),
            gltf::khr_lights_punctual::Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => Light::Spot(SpotLight {
                position,
                direction,
                intensity: color,
                cos_inner: inner_cone_angle.cos(),
                cos_outer: outer_cone_angle.cos(),
            }),
        };
        if light.range().is_some() {
            self.builder.warnings.push(format!(
                "light {}: 'range' is ignored (physical inverse-square falloff)",
                light.index()
            ));
        }
        self.builder.add_tagged_light(l, tag);
    }

    /// `EXT_mesh_gpu_instancing` on `node`: one matrix per instance, T·R·S from its `TRANSLATION`, `ROTATION`
    /// (a unit quaternion) and `SCALE` accessors (each optional, all of one count; the extension's
    /// specification), placed in the node's frame; `None` without the extension. A static mesh's instances
    /// share its prototypes ([`Self::place_mesh`]); a skinned, morphed or moving one is copied per instance.
    fn instances(&self, node: &gltf::Node) -> Result<Option<Vec<Mat4>>, SceneError> {
        let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
            return Ok(None);
        };
        let at = format!(
            "node '{}': extensions.EXT_mesh_gpu_instancing",
            one_line(&node_name(node), QUOTE)
        );
        let attributes = ext
            .get("attributes")
            .and_then(|a| a.as_object())
            .ok_or_else(|| self.malformed(format!("{at}: attributes must be an object")))?;
        let read =
            |key: &str, usage: Usage, components: usize| -> Result<Option<Vec<f32>>, SceneError> {
                let Some(value) = attributes.get(key) else {
                    return Ok(None);
                };
                let accessor = value
                    .as_u64()
                    .and_then(|i| usize::try_from(i).ok())
                    .and_then(|i| self.document.accessors().nth(i))
                    .ok_or_else(|| self.malformed(format!("{at}.{key}: no such accessor")))?;
                let floats = read_floats(&accessor, usage, self.buffers, &self.options.limits)
                    .map_err(|m| self.malformed(format!("{at}.{key}: {m}")))?;
                if floats.len() % components != 0 || floats.iter().any(|v| !v.is_finite()) {
                    return Err(self.malformed(format!("{at}.{key}: values must be finite")));
                }
                Ok(Some(floats))
            };
        let translation = read("TRANSLATION", Usage::KeyVec3, 3)?;
        let rotation = read("ROTATION", Usage::KeyRotation, 4)?;
        let scale = read("SCALE", Usage::KeyVec3, 3)?;
        let counts = [
            translation.as_ref().map(|t| t.len() / 3),
            rotation.as_ref().map(|r| r.len() / 4),
            scale.as_ref().map(|s| s.len() / 3),
        ];
        let mut known = counts.iter().flatten();
        let Some(&count) = known.next() else {
            return Err(self.malformed(format!("{at}: needs TRANSLATION, ROTATION or SCALE")));
        };
        if known.any(|&c| c != count) {
            return Err(self.malformed(format!(
                "{at}: the attributes have different counts {counts:?}"
            )));
        }
        let vec3 = |v: &Option<Vec<f32>>, i: usize, default: Vec3| {
            v.as_ref()
                .map_or(default, |v| Vec3::from_slice(&v[3 * i..3 * i + 3]))
        };
        Ok(Some(
            (0..count)
                .map(|i| {
                    let q = rotation.as_ref().map_or(Quat::IDENTITY, |r| {
                        Quat::from_slice(&r[4 * i..4 * i + 4]).normalize()
                    });
                    Mat4::from_scale_rotation_translation(
                        vec3(&scale, i, Vec3::ONE),
                        if q.is_finite() { q } else { Quat::IDENTITY },
                        vec3(&translation, i, Vec3::ZERO),
                    )
                })
                .collect(),
        ))
    }

    /// Whether `node`'s `mesh` at `world` becomes instances of shared prototypes rather than world-space
    /// copies: when the mesh is drawn more than once (by several nodes, or by `EXT_mesh_gpu_instancing`) and
    /// is static: no skin, no morph targets, and (under a shutter) the same world matrix at every motion step.
    fn instanceable(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world: &Mat4,
        gpu_instanced: bool,
    ) -> bool {
        let reused = gpu_instanced || self.mesh_users.get(mesh.index()).is_some_and(|&n| n > 1);
        let deformed = node.skin().is_some()
            || mesh
                .primitives()
                .any(|p| p.morph_targets().next().is_some());
        let moving = self
            .motion
            .as_ref()
            .is_some_and(|m| m.worlds.iter().any(|w| w[node.index()] != *world));
        reused && !deformed && !moving
    }

    /// Places `mesh` at `world` as instances of its prototypes (one per triangle primitive, read the first
    /// time the mesh is placed and counted once against the memory budget), each instance named as a
    /// flattened copy would be (the node's name, else the mesh's) with the node's asset and tags.
    fn place_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let prototypes = match self.prototypes.get(&mesh.index()) {
            Some(p) => p.clone(),
            None => {
                let p = self.read_prototypes(node, mesh)?;
                self.prototypes.insert(mesh.index(), p.clone());
                p
            }
        };
        let name = node.name().map_or_else(|| mesh_name(mesh), str::to_owned);
        for &prototype in prototypes.iter() {
            let instance = super::MeshInstance {
                prototype,
                object_to_world: *world,
                name: name.clone(),
                asset: context.asset.clone(),
                tags: context.tags.clone(),
            };
            self.builder
                .add_instance(instance)
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        }
        Ok(())
    }

    /// The description of `primitive` (`MESH, primitive N`) when it holds triangles (a list, strip or fan);
    /// any other mode is warned about and skipped (`None`).
    fn triangle_primitive(&mut self, mesh_name: &str, primitive: &gltf::Primitive) -> Option<String> {
        let what = format!("{mesh_name}, primitive {}", primitive.index());
        let mode = primitive.mode();
        if matches!(
            mode,
            gltf::mesh::Mode::Triangles
                | gltf::mesh::Mode::TriangleStrip
                | gltf::mesh::Mode::TriangleFan
        ) {
            return Some(what);
        }
        self.builder.warnings.push(format!(
            "{what}: {mode:?} primitives are not triangles; skipped"
        ));
        None
    }

    /// Reads the triangle primitives of `mesh` (first placed by `node`) as object-space prototypes with
    /// their materials, each checked against the memory budget first; returns their indices.
    fn read_prototypes(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
    ) -> Result<Rc<[u32]>, SceneError> {
        let mesh_name = mesh_name(mesh);
        let mut ids = Vec::new();
        for primitive in mesh.primitives() {
            let Some(what) = self.triangle_primitive(&mesh_name, &primitive) else {
                continue;
            };
            let (triangles, vertices) = primitive_size(&primitive);
            self.builder
                .check_mesh(
                    format_args!("{what} on node {}", node.index()),
                    triangles,
                    vertices,
                )
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
            let mut m = self.read_primitive(&primitive, &what)?;
            if m.normals.is_empty() {
                m.generate_normals();
            }
            m.name.clone_from(&mesh_name);
            m.material = match self.variant_material(&primitive, &what)? {
                Some(i) => {
                    let material = self.document.materials().nth(i).expect("index checked");
                    self.material(material)?
                }
                None => self.material(primitive.material())?,
            };
            ids.push(self.builder.add_prototype(m));
        }
        Ok(ids.into())
    }

    /// Loads a node's mesh: each triangle primitive's attributes, morphed by the pose's weights, then posed
    /// by the node's skin or placed by the node's world matrix (times `instance`, an `EXT_mesh_gpu_instancing`
    /// instance's own, else the identity). Under a shutter, the same is done at each motion step, and a mesh
    /// whose vertices differ at some step from the frame's gets those steps as its motion (transform, morph
    /// and skin blur alike).
    fn load_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: gltf::Mesh,
        node_world: &Mat4,
        instance: &Mat4,
        context: &NodeContext,
    ) -> Result<(), SceneError> {
        let world = &(*node_world * *instance);
        let mesh_name = mesh_name(&mesh);
        if node.skin().is_some() && !std::mem::replace(&mut self.skin_warned, true) {
            self.builder.warnings.push(
                "skinned meshes are posed at their rest pose (the joints' own node transforms); animations are not played".into(),
            );
        }
        if node.skin().is_some() && self.node_worlds.is_empty() {
            self.node_worlds = gltf_deform::node_worlds(self.document, &self.pose.locals);
        }
        let frame_deform =
            self.deformation(node, &mesh, &self.pose, 0, &self.node_worlds, world)?;
        let step_deforms = match &self.motion {
            Some(m) => Some(
                m.poses
                    .iter()
                    .zip(&m.worlds)
                    .enumerate()
                    .map(|(k, (pose, worlds))| {
                        let world = worlds[node.index()] * *instance;
                        self.deformation(node, &mesh, pose, k + 1, worlds, &world)
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            ),
            None => None,
        };
        for primitive in mesh.primitives() {
            let Some(what) = self.triangle_primitive(&mesh_name, &primitive) else {
                continue;
            };
            let (triangles, vertices) = primitive_size(&primitive);
            let copies = 1 + step_deforms.as_ref().map_or(0, Vec::len) as u64;
            self.builder
                .check_mesh(
                    format_args!("{what} on node {}", node.index()),
                    triangles,
                    vertices.saturating_mul(copies),
                )
                .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
            let base = self.read_primitive(&primitive, &what)?;
            let mut m = self.deformed(&base, &primitive, &frame_deform, &what)?;
            if let (Some(deforms), Some(motion)) = (&step_deforms, &self.motion) {
                let mut positions = Vec::with_capacity(deforms.len());
                let mut normals = Vec::with_capacity(deforms.len());
                for d in deforms {
                    let step = self.deformed(&base, &primitive, d, &what)?;
                    if step.indices != m.indices {
                        // A mirroring transform at some steps only (a scale through zero) flips the winding.
                        self.builder.warnings.push(format!(
                            "{what}: its winding flips across the shutter; not motion-blurred"
                        ));
                        positions.clear();
                        break;
                    }
                    positions.push(step.positions);
                    normals.push(step.normals);
                }
                if positions.iter().any(|p| *p != m.positions) {
                    m.motion = Some(MeshMotion {
                        steps: motion.steps,
                        positions,
                        normals,
                    });
                }
            }
            m.name = node.name().map_or_else(|| mesh_name.clone(), str::to_owned);
            m.asset = context.asset.clone();
            m.tags = context.tags.clone();
            m.material = match self.variant_material(&primitive, &what)? {
                Some(i) => {
                    let material = self.document.materials().nth(i).expect("index checked");
                    self.material(material)?
                }
                None => self.material(primitive.material())?,
            };
            self.builder.add_mesh(m);
        }
        Ok(())
    }

    /// What poses a node's mesh in `pose` (number `pose_index`: 0 the frame's, k + 1 motion step k): its morph
    /// weights, and its skin's joint matrices (from the node `worlds` of that pose) or else its world matrix
    /// `world`.
    fn deformation(
        &self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        pose: &gltf_animation::Pose,
        pose_index: usize,
        worlds: &[Mat4],
        world: &Mat4,
    ) -> Result<Deformation, SceneError> {
        let weights: Vec<f32> = match &pose.weights[node.index()] {
            Some(animated) => animated.clone(),
            None => gltf_deform::morph_weights(node, mesh).to_vec(),
        };
        let joints = match node.skin() {
            Some(skin) => Some(self.joint_matrices(&skin, pose_index, worlds)?),
            None => None,
        };
        Ok(Deformation {
            weights,
            joints,
            world: *world,
        })
    }

    /// The joint matrices of `skin` in pose `pose_index` (see [`Self::deformation`]), computed on first use
    /// and counted against the work budget, one step a joint.
    fn joint_matrices(
        &self,
        skin: &gltf::Skin,
        pose_index: usize,
        worlds: &[Mat4],
    ) -> Result<Rc<[Mat4]>, SceneError> {
        let key = (pose_index, skin.index());
        if let Some(joints) = self.joints.borrow().get(&key) {
            return Ok(joints.clone());
        }
        let count = skin.joints().len() as u64;
        self.work
            .spend(
                format_args!("skin {}: {count} joint matrices", skin.index()),
                count,
            )
            .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        let joints: Rc<[Mat4]> =
            gltf_deform::joint_matrices(skin, worlds, self.buffers, &self.options.limits)
                .map_err(|e| self.error(SceneErrorKind::Malformed(e)))?
                .into();
        self.joints.borrow_mut().insert(key, joints.clone());
        Ok(joints)
    }

    /// The object-space primitive `base` morphed and posed by `d`, with flat normals where it has none. The
    /// morph targets read (one step a vertex each) and the skinned vertices count against the work budget.
    fn deformed(
        &self,
        base: &Mesh,
        primitive: &gltf::Primitive,
        d: &Deformation,
        what: &str,
    ) -> Result<Mesh, SceneError> {
        let vertices = base.positions.len() as u64;
        let targets = d.weights.iter().filter(|&&w| w != 0.0).count() as u64;
        let (skinned, how) = match d.joints {
            Some(_) => (vertices, ", skinned"),
            None => (0, ""),
        };
        self.work
            .spend(
                format_args!("{what}: posing {vertices} vertices ({targets} morph targets{how})"),
                targets.saturating_mul(vertices).saturating_add(skinned),
            )
            .map_err(|e| self.error(SceneErrorKind::OverLimit(e.to_string())))?;
        let mut m = base.clone();
        let limits = &self.options.limits;
        gltf_deform::apply_morph_targets(&mut m, primitive, &d.weights, self.buffers, limits)
            .and_then(|()| match &d.joints {
                Some(j) => gltf_deform::apply_skin(&mut m, primitive, j, self.buffers, limits),
                None => {
                    m.transform(&d.world);
                    Ok(())
                }
            })
            .map_err(|e| self.error(SceneErrorKind::Malformed(format!("{what}: {e}"))))?;
        if m.normals.is_empty() {
            m.generate_normals();
        }
        Ok(m)
    }

    /// A primitive's vertices in object space: POSITION, NORMAL, TANGENT and TEXCOORD_0 (sparse or quantized
    /// accessors decoded), its index list triangulated, every other attribute's bytes checked.
    fn read_primitive(&self, primitive: &gltf::Primitive, what: &str) -> Result<Mesh, SceneError> {
        use gltf::Semantic as S;
        let (buffers, limits) = (self.buffers, &self.options.limits);
        let bad = |m: String| self.error(SceneErrorKind::InvalidReference(format!("{what}: {m}")));
        let floats = |semantic: &S, usage| match primitive.get(semantic) {
            Some(a) => read_floats(&a, usage, buffers, limits)
                .map(Some)
                .map_err(bad),
            None => Ok(None),
        };
        let positions: Vec<Vec3> = floats(&S::Positions, Usage::Position)?
            .ok_or_else(|| {
                self.error(SceneErrorKind::Malformed(format!("{what} has no POSITION")))
            })?
            .chunks_exact(3)
            .map(Vec3::from_slice)
            .collect();
        let count = positions.len();
        let normals: Vec<Vec3> = floats(&S::Normals, Usage::Normal)?
            .map(|f| f.chunks_exact(3).map(Vec3::from_slice).collect())
            .unwrap_or_default();
        let uvs: Option<Vec<Vec2>> = floats(&S::TexCoords(0), Usage::TexCoord)?
            .map(|f| f.chunks_exact(2).map(Vec2::from_slice).collect());
        let tangents: Option<Vec<Vec4>> = floats(&S::Tangents, Usage::Tangent)?
            .map(|f| f.chunks_exact(4).map(Vec4::from_slice).collect());
        let uvs1: Option<Vec<Vec2>> = floats(&S::TexCoords(1), Usage::TexCoord)?
            .map(|f| f.chunks_exact(2).map(Vec2::from_slice).collect());
        let colors: Option<Vec<Vec4>> = match primitive.get(&S::Colors(0)) {
            Some(a) if a.dimensions() == gltf::accessor::Dimensions::Vec3 => {
                floats(&S::Colors(0), Usage::ColorRgb)?.map(|f| {
                    f.chunks_exact(3)
                        .map(|c| Vec3::from_slice(c).extend(1.0))
                        .collect()
                })
            }
            Some(_) => floats(&S::Colors(0), Usage::ColorRgba)?
                .map(|f| f.chunks_exact(4).map(Vec4::from_slice).collect()),
            None => None,
        };
        for (semantic, accessor) in primitive.attributes() {
            if !matches!(
                semantic,
                S::Positions
                    | S::Normals
                    | S::Tangents
                    | S::TexCoords(0)
                    | S::TexCoords(1)
                    | S::Colors(0)
            ) {
                check_bytes(&accessor, buffers, limits)
                    .map_err(|e| bad(format!("{semantic:?}: {e}")))?;
            }
        }
        let flat: Vec<u32> = match primitive.indices() {
            Some(a) => read_indices(&a, buffers, limits).map_err(bad)?,
            None => (0..count as u32).collect(),
        };
        if let Some(i) = flat.iter().find(|&&i| i as usize >= count) {
            return Err(bad(format!(
                "index {i} is out of range for {count} vertices"
            )));
        }
        let same_len = |n: usize| n == count;
        if (!normals.is_empty() && !same_len(normals.len()))
            || uvs.as_ref().is_some_and(|u| !same_len(u.len()))
            || uvs1.as_ref().is_some_and(|u| !same_len(u.len()))
            || colors.as_ref().is_some_and(|c| !same_len(c.len()))
            || tangents.as_ref().is_some_and(|t| !same_len(t.len()))
        {
            return Err(self.error(SceneErrorKind::Malformed(format!(
                "{what}: attribute counts differ from POSITION's {count}"
            ))));
        }
        let bad = [
            ("POSITION", positions.iter().position(|v| !v.is_finite())),
            ("NORMAL", normals.iter().position(|v| !v.is_finite())),
            (
                "TEXCOORD_0",
                uvs.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "TEXCOORD_1",
                uvs1.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "COLOR_0",
                colors.iter().flatten().position(|v| !v.is_finite()),
            ),
            (
                "TANGENT",
                tangents.iter().flatten().position(|v| !v.is_finite()),
            ),
        ];
        if let Some((name, Some(i))) = bad.into_iter().find(|(_, i)| i.is_some()) {
            return Err(self.error(SceneErrorKind::Malformed(format!(
                "{what}: {name}[{i}] is not finite"
            ))));
        }
        Ok(Mesh {
            positions,
            normals,
            uvs,
            uvs1,
            colors,
            tangents,
            indices: triangulate(&flat, primitive.mode()),
            ..Default::default()
        })
    }

    /// The material index `KHR_materials_variants` gives the chosen variant on a primitive, if the primitive
    /// maps it. Every mapping is checked, whichever variant is chosen: `material` must name a material, and
    /// each of `variants` a variant of the file, at most once on the primitive (the extension's rule).
    fn variant_material(
        &self,
        primitive: &gltf::Primitive,
        what: &str,
    ) -> Result<Option<usize>, SceneError> {
        let Some(ext) = primitive.extension_value("KHR_materials_variants") else {
            return Ok(None);
        };
        let at = format!("{what}: extensions.KHR_materials_variants");
        let mappings = ext
            .get("mappings")
            .and_then(|m| m.as_array())
            .ok_or_else(|| self.malformed(format!("{at}.mappings must be an array")))?;
        let materials = self.document.materials().len();
        // The mapping that named each variant met so far: the work follows the primitive's own mappings, not
        // the file's count of variants.
        let mut mapped_at: HashMap<usize, usize> = HashMap::new();
        let mut chosen = None;
        for (i, mapping) in mappings.iter().enumerate() {
            let material = mapping
                .get("material")
                .and_then(|m| m.as_u64())
                .filter(|&m| m < materials as u64)
                .ok_or_else(|| {
                    self.error(SceneErrorKind::InvalidReference(format!(
                        "{at}.mappings[{i}].material must be the index of a material ({materials} materials)"
                    )))
                })? as usize;
            let variants = mapping
                .get("variants")
                .and_then(|v| v.as_array())
                .ok_or_else(|| {
                    self.malformed(format!("{at}.mappings[{i}].variants must be an array"))
                })?;
            for v in variants {
                let index = v
                    .as_u64()
                    .filter(|&v| v < self.variant_count as u64)
                    .ok_or_else(|| {
                        self.error(SceneErrorKind::InvalidReference(format!(
                            "{at}.mappings[{i}].variants: {} is not the index of a variant ({} variants)",
                            one_line(&v.to_string(), QUOTE),
                            self.variant_count
                        )))
                    })? as usize;
                if let Some(first) = mapped_at.insert(index, i) {
                    return Err(self.malformed(format!(
                        "{at}: variant {index} is mapped by mappings[{first}] and mappings[{i}]"
                    )));
                }
                if self.variant == Some(index) {
                    chosen = Some(material);
                }
            }
        }
        Ok(chosen)
    }

    fn material(&mut self, material: gltf::Material) -> Result<u32, SceneError> {
        if let Some(&id) = self.material_map.get(&material.index()) {
            return Ok(id);
        }
        let pbr = material.pbr_metallic_roughness();
        let emissive_strength = material.emissive_strength().unwrap_or(1.0);
        self.check_material_numbers(&material, emissive_strength)?;
        let at = material_path(&material);
        // With the specular-glossiness extension, the core metallic-roughness is only its fallback: unread.
        let specular_glossiness = self.specular_glossiness(&material, &at)?;
        let metallic_roughness = specular_glossiness.is_none();
        let base_color_texture = self.info_texture(
            pbr.base_color_texture().filter(|_| metallic_roughness),
            ColorSpace::Srgb,
            &format!("{at}.pbrMetallicRoughness.baseColorTexture"),
        )?;
        let metallic_roughness_texture = self.info_texture(
            pbr.metallic_roughness_texture()
                .filter(|_| metallic_roughness),
            ColorSpace::Linear,
            &format!("{at}.pbrMetallicRoughness.metallicRoughnessTexture"),
        )?;
        let normal_texture = match material.normal_texture() {
            Some(t) => {
                let r = self.raw_ref(
                    t.texture().index(),
                    t.tex_coord(),
                    t.extensions(),
                    &format!("{at}.normalTexture"),
                )?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, t.scale()))
            }
            None => None,
        };
        let occlusion_texture = match material.occlusion_texture() {
            Some(t) => {
                let r = self.raw_ref(
                    t.texture().index(),
                    t.tex_coord(),
                    t.extensions(),
                    &format!("{at}.occlusionTexture"),
                )?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, t.strength()))
            }
            None => None,
        };
        let emission_texture = self.info_texture(
            material.emissive_texture(),
            ColorSpace::Srgb,
            &format!("{at}.emissiveTexture"),
        )?;
        // The specular-glossiness model fixes the dielectric F0 at 0.04 (ior 1.5, full specular): the ior and
        // specular extensions, which its specification excludes beside it, are not read.
        let fixed_f0 = specular_glossiness.is_some();
        if fixed_f0 && (material.ior().is_some() || material.specular().is_some()) {
            self.builder.warnings.push(format!(
                "{at}: KHR_materials_ior and KHR_materials_specular are not read beside \
                 KHR_materials_pbrSpecularGlossiness (its dielectric F0 is 0.04)"
            ));
        }
        let specular = material.specular().filter(|_| !fixed_f0);
        let (specular_factor, specular_color) = specular.as_ref().map_or((1.0, Rgb::ONE), |s| {
            (s.specular_factor(), Rgb::from(s.specular_color_factor()))
        });
        let specular_texture = self.info_texture(
            specular.as_ref().and_then(|s| s.specular_texture()),
            ColorSpace::Linear,
            &format!("{at}.extensions.KHR_materials_specular.specularTexture"),
        )?;
        let specular_color_texture = self.info_texture(
            specular.as_ref().and_then(|s| s.specular_color_texture()),
            ColorSpace::Srgb,
            &format!("{at}.extensions.KHR_materials_specular.specularColorTexture"),
        )?;
        let transmission_texture = self.info_texture(
            material
                .transmission()
                .and_then(|t| t.transmission_texture()),
            ColorSpace::Linear,
            &format!("{at}.extensions.KHR_materials_transmission.transmissionTexture"),
        )?;
        let clearcoat = self.clearcoat(&material, &at)?;
        let sheen = self.sheen(&material, &at)?;
        let anisotropy = self.anisotropy(&material, &at)?;
        let diffuse_transmission = self.diffuse_transmission(&material, &at)?;
        let iridescence = self.iridescence(&material, &at)?;
        let dispersion = self.dispersion(&material, &at)?;
        let m = Material {
            name: material.name().map_or_else(
                || format!("material {}", material.index().map_or(-1, |i| i as i64)),
                str::to_owned,
            ),
            base_color: Vec4::from(pbr.base_color_factor()),
            base_color_texture,
            metallic: pbr.metallic_factor(),
            roughness: pbr.roughness_factor(),
            metallic_roughness_texture,
            normal_texture,
            occlusion_texture,
            emission: Rgb::from(material.emissive_factor()) * emissive_strength,
            emission_texture,
            ior: material.ior().filter(|_| !fixed_f0).unwrap_or(1.5),
            specular_factor,
            specular_color,
            transmission: material
                .transmission()
                .map_or(0.0, |t| t.transmission_factor()),
            transmission_texture,
            specular_texture,
            specular_color_texture,
            double_sided: material.double_sided(),
            interior: None,
            alpha_mode: alpha_mode(&material),
            alpha_texture: None,
            unlit: material.unlit(),
            clearcoat,
            sheen,
            specular_glossiness,
            anisotropy,
            diffuse_transmission,
            iridescence,
            dispersion,
            tags: CompositingTags::default(),
        };
        let mut m = m;
        m.tags = self.material_tags(&material, &m.name)?;
        m.interior = self.interior_medium(&material, &m)?;
        if let Some(interior) = m.interior {
            let tag = MediumTag {
                asset: String::new(),
                tags: m.tags.clone(),
            };
            self.builder.set_medium_tag(interior, tag);
        }
        let id = self.builder.add_material(m);
        self.material_map.insert(material.index(), id);
        Ok(id)
    }

    /// `KHR_materials_clearcoat` of a material, when present: factors checked (finite, in \[0, 1\]) and
    /// textures read.
    fn clearcoat(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<ClearcoatLayer>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_clearcoat");
        let Some(ext) = self.extension_object(material, "KHR_materials_clearcoat", &at)? else {
            return Ok(None);
        };
        let factor = self.unit_number(&ext, "clearcoatFactor", 0.0, &at)?;
        let roughness = self.unit_number(&ext, "clearcoatRoughnessFactor", 0.0, &at)?;
        let texture = self.ext_texture(&ext, "clearcoatTexture", ColorSpace::Linear, &at)?;
        let roughness_texture =
            self.ext_texture(&ext, "clearcoatRoughnessTexture", ColorSpace::Linear, &at)?;
        let normal_texture = match ext.get("clearcoatNormalTexture") {
            Some(v) => {
                let field = format!("{at}.clearcoatNormalTexture");
                let scale = match v.get("scale") {
                    Some(s) => s.as_f64().filter(|s| s.is_finite()).ok_or_else(|| {
                        self.malformed(format!("{field}.scale must be a finite number"))
                    })? as f32,
                    None => 1.0,
                };
                let r = self.json_ref(v, &field)?;
                Some((self.texture_ref(&r, ColorSpace::Linear)?, scale))
            }
            None => None,
        };
        Ok(Some(ClearcoatLayer {
            factor,
            texture,
            roughness,
            roughness_texture,
            normal_texture,
        }))
    }

    /// `KHR_materials_sheen` of a material, when present: factors checked and textures read.
    fn sheen(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<SheenLayer>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_sheen");
        let Some(ext) = self.extension_object(material, "KHR_materials_sheen", &at)? else {
            return Ok(None);
        };
        let color = match ext.get("sheenColorFactor") {
            Some(v) => crate::params::parse_rgb(v)
                .filter(|c| c.max_element() <= 1.0)
                .ok_or_else(|| {
                    self.malformed(format!(
                        "{at}.sheenColorFactor must be three numbers in [0, 1]"
                    ))
                })?,
            None => Rgb::ZERO,
        };
        let roughness = self.unit_number(&ext, "sheenRoughnessFactor", 0.0, &at)?;
        let color_texture = self.ext_texture(&ext, "sheenColorTexture", ColorSpace::Srgb, &at)?;
        let roughness_texture =
            self.ext_texture(&ext, "sheenRoughnessTexture", ColorSpace::Linear, &at)?;
        Ok(Some(SheenLayer {
            color,
            color_texture,
            roughness,
            roughness_texture,
        }))
    }

    /// `KHR_materials_pbrSpecularGlossiness` of a material, when present: factors checked (finite, in
    /// \[0, 1\]) and textures read (both sRGB colour with linear alpha, as the extension specifies).
    fn specular_glossiness(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<SpecularGlossiness>, SceneError> {
        let name = "KHR_materials_pbrSpecularGlossiness";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let mut sg = SpecularGlossiness::default();
        if let Some(v) = ext.get("diffuseFactor") {
            let d = unit_numbers::<4>(v).ok_or_else(|| {
                self.malformed(format!("{at}.diffuseFactor must be four numbers in [0, 1]"))
            })?;
            sg.diffuse = Vec4::from(d);
        }
        if let Some(v) = ext.get("specularFactor") {
            let s = unit_numbers::<3>(v).ok_or_else(|| {
                self.malformed(format!(
                    "{at}.specularFactor must be three numbers in [0, 1]"
                ))
            })?;
            sg.specular = Rgb::from(s);
        }
        sg.glossiness = self.unit_number(&ext, "glossinessFactor", 1.0, &at)?;
        sg.diffuse_texture = self.ext_texture(&ext, "diffuseTexture", ColorSpace::Srgb, &at)?;
        sg.specular_glossiness_texture =
            self.ext_texture(&ext, "specularGlossinessTexture", ColorSpace::Srgb, &at)?;
        Ok(Some(sg))
    }

    /// `KHR_materials_anisotropy` of a material, when present: `anisotropyStrength` in \[0, 1\] (default 0),
    /// `anisotropyRotation` a finite number of radians (default 0), `anisotropyTexture` read as linear data.
    fn anisotropy(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<Anisotropy>, SceneError> {
        let at = format!("{at}.extensions.KHR_materials_anisotropy");
        let Some(ext) = self.extension_object(material, "KHR_materials_anisotropy", &at)? else {
            return Ok(None);
        };
        let strength = self.unit_number(&ext, "anisotropyStrength", 0.0, &at)?;
        let rotation = match ext.get("anisotropyRotation") {
            None => 0.0,
            Some(v) => v
                .as_f64()
                .map(|r| r as f32)
                .filter(|r| r.is_finite())
                .ok_or_else(|| {
                    self.malformed(format!(
                        "{at}.anisotropyRotation must be a finite number (radians)"
                    ))
                })?,
        };
        let texture = self.ext_texture(&ext, "anisotropyTexture", ColorSpace::Linear, &at)?;
        Ok(Some(Anisotropy {
            strength,
            rotation,
            texture,
        }))
    }

    /// `KHR_materials_diffuse_transmission` of a material, when present: `diffuseTransmissionFactor` in
    /// \[0, 1\] (default 0), `diffuseTransmissionColorFactor` three numbers in \[0, 1\] (default white),
    /// `diffuseTransmissionTexture` read as linear data (its alpha is used), `diffuseTransmissionColorTexture`
    /// as sRGB colour.
    fn diffuse_transmission(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<DiffuseTransmission>, SceneError> {
        let name = "KHR_materials_diffuse_transmission";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let factor = self.unit_number(&ext, "diffuseTransmissionFactor", 0.0, &at)?;
        let color = match ext.get("diffuseTransmissionColorFactor") {
            Some(v) => Rgb::from(unit_numbers::<3>(v).ok_or_else(|| {
                self.malformed(format!(
                    "{at}.diffuseTransmissionColorFactor must be three numbers in [0, 1]"
                ))
            })?),
            None => Rgb::ONE,
        };
        let texture =
            self.ext_texture(&ext, "diffuseTransmissionTexture", ColorSpace::Linear, &at)?;
        let color_texture = self.ext_texture(
            &ext,
            "diffuseTransmissionColorTexture",
            ColorSpace::Srgb,
            &at,
        )?;
        Ok(Some(DiffuseTransmission {
            factor,
            texture,
            color,
            color_texture,
        }))
    }

    /// `KHR_materials_iridescence` of a material, when present: `iridescenceFactor` in \[0, 1\] (default 0),
    /// `iridescenceIor` a finite number ≥ 1 (default 1.3), `iridescenceThicknessMinimum` and
    /// `iridescenceThicknessMaximum` finite numbers ≥ 0 of nanometres (defaults 100 and 400), the textures read
    /// as linear data.
    fn iridescence(
        &mut self,
        material: &gltf::Material,
        at: &str,
    ) -> Result<Option<Iridescence>, SceneError> {
        let name = "KHR_materials_iridescence";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(None);
        };
        let defaults = Iridescence::default();
        let number = |key: &str, default: f32, min: f32| match ext.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .map(|v| v as f32)
                .filter(|v| v.is_finite() && *v >= min)
                .ok_or_else(|| {
                    self.malformed(format!("{at}.{key} must be a finite number >= {min}"))
                }),
        };
        let ior = number("iridescenceIor", defaults.ior, 1.0)?;
        let thickness_min = number("iridescenceThicknessMinimum", defaults.thickness_min, 0.0)?;
        let thickness_max = number("iridescenceThicknessMaximum", defaults.thickness_max, 0.0)?;
        let factor = self.unit_number(&ext, "iridescenceFactor", 0.0, &at)?;
        let texture = self.ext_texture(&ext, "iridescenceTexture", ColorSpace::Linear, &at)?;
        let thickness_texture =
            self.ext_texture(&ext, "iridescenceThicknessTexture", ColorSpace::Linear, &at)?;
        Ok(Some(Iridescence {
            factor,
            texture,
            ior,
            thickness_min,
            thickness_max,
            thickness_texture,
        }))
    }

    /// `KHR_materials_dispersion.dispersion` of a material (a finite number ≥ 0, default 0). It applies to the
    /// volume of a `KHR_materials_volume` material only (the extension's rule): without one, or with a thin
    /// wall (`thicknessFactor` 0), a warning says it is ignored and the result is 0.
    fn dispersion(&mut self, material: &gltf::Material, at: &str) -> Result<f32, SceneError> {
        let name = "KHR_materials_dispersion";
        let at = format!("{at}.extensions.{name}");
        let Some(ext) = self.extension_object(material, name, &at)? else {
            return Ok(0.0);
        };
        let dispersion = match ext.get("dispersion") {
            None => 0.0,
            Some(v) => v
                .as_f64()
                .map(|v| v as f32)
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| {
                    self.malformed(format!("{at}.dispersion must be a finite number >= 0"))
                })?,
        };
        let volume = material
            .volume()
            .is_some_and(|v| v.thickness_factor() > 0.0);
        if dispersion > 0.0 && !volume {
            self.builder.warnings.push(format!(
                "{at}: dispersion needs KHR_materials_volume with thicknessFactor > 0 and is ignored"
            ));
            return Ok(0.0);
        }
        Ok(dispersion)
    }

    fn malformed(&self, message: String) -> SceneError {
        self.error(SceneErrorKind::Malformed(one_line(&message, 4 * QUOTE)))
    }

    /// The JSON object of extension `name` on a material, if present (an error if it is not an object).
    fn extension_object(
        &self,
        material: &gltf::Material,
        name: &str,
        at: &str,
    ) -> Result<Option<serde_json::Map<String, serde_json::Value>>, SceneError> {
        match material.extensions().and_then(|e| e.get(name)) {
            None => Ok(None),
            Some(serde_json::Value::Object(o)) => Ok(Some(o.clone())),
            Some(_) => Err(self.malformed(format!("{at} must be an object"))),
        }
    }

    /// A number in \[0, 1\] of an extension object, or `default` when absent.
    fn unit_number(
        &self,
        ext: &serde_json::Map<String, serde_json::Value>,
        key: &str,
        default: f32,
        at: &str,
    ) -> Result<f32, SceneError> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .filter(|v| (0.0..=1.0).contains(v))
                .map(|v| v as f32)
                .ok_or_else(|| self.malformed(format!("{at}.{key} must be a number in [0, 1]"))),
        }
    }

    /// A texture of an extension object (a `textureInfo`), read into the scene, if present.
    fn ext_texture(
        &mut self,
        ext: &serde_json::Map<String, serde_json::Value>,
        key: &str,
        space: ColorSpace,
        at: &str,
    ) -> Result<Option<u32>, SceneError> {
        match ext.get(key) {
            None => Ok(None),
            Some(v) => {
                let r = self.json_ref(v, &format!("{at}.{key}"))?;
                Ok(Some(self.texture_ref(&r, space)?))
            }
        }
    }

    /// The texture of a `textureInfo` the `gltf` crate parsed (`at` names it in errors), if the material or
    /// extension gives one.
    fn info_texture(
        &mut self,
        info: Option<gltf::texture::Info>,
        space: ColorSpace,
        at: &str,
    ) -> Result<Option<u32>, SceneError> {
        match info {
            Some(info) => {
                let r = self.info_ref(&info, at)?;
                Ok(Some(self.texture_ref(&r, space)?))
            }
            None => Ok(None),
        }
    }

    /// A `textureInfo` given as JSON: `index`, `texCoord` and `extensions.KHR_texture_transform`.
    fn json_ref(&self, value: &serde_json::Value, at: &str) -> Result<TexRef, SceneError> {
        let index = value
            .get("index")
            .and_then(|i| i.as_u64())
            .ok_or_else(|| self.malformed(format!("{at}.index must be a texture index")))?;
        let tex_coord = match value.get("texCoord") {
            Some(t) => t
                .as_u64()
                .filter(|&t| t <= u32::MAX as u64)
                .ok_or_else(|| {
                    self.malformed(format!("{at}.texCoord must be a non-negative integer"))
                })? as u32,
            None => 0,
        };
        let extensions = value.get("extensions").and_then(|e| e.as_object());
        self.raw_ref(index as usize, tex_coord, extensions, at)
    }

    /// A texture reference from its texture index, `texCoord` and raw `extensions` object.
    fn raw_ref(
        &self,
        texture: usize,
        tex_coord: u32,
        extensions: Option<&serde_json::Map<String, serde_json::Value>>,
        at: &str,
    ) -> Result<TexRef, SceneError> {
        if texture >= self.document.textures().len() {
            return Err(self.error(SceneErrorKind::InvalidReference(format!(
                "{at}: texture {texture} does not exist ({} textures)",
                self.document.textures().len()
            ))));
        }
        let mut r = TexRef {
            texture,
            tex_coord,
            transform: UvTransform::default(),
        };
        if let Some(t) = extensions.and_then(|e| e.get("KHR_texture_transform")) {
            let bad = || self.malformed(format!("{at}.extensions.KHR_texture_transform: {t}"));
            let pair = |key: &str, default: [f32; 2]| match t.get(key) {
                None => Some(default),
                Some(v) => {
                    let a = v.as_array().filter(|a| a.len() == 2)?;
                    Some([a[0].as_f64()? as f32, a[1].as_f64()? as f32])
                }
            };
            let offset = pair("offset", [0.0, 0.0]).ok_or_else(bad)?;
            let scale = pair("scale", [1.0, 1.0]).ok_or_else(bad)?;
            let rotation = match t.get("rotation") {
                None => 0.0,
                Some(v) => v.as_f64().ok_or_else(bad)? as f32,
            };
            if let Some(c) = t.get("texCoord") {
                r.tex_coord = c
                    .as_u64()
                    .filter(|&c| c <= u32::MAX as u64)
                    .ok_or_else(bad)? as u32;
            }
            r.transform = checked_transform(offset, rotation, scale).ok_or_else(bad)?;
        }
        Ok(r)
    }

    /// A core `textureInfo` (base colour, metallic-roughness, emissive) with its `KHR_texture_transform`.
    fn info_ref(&self, info: &gltf::texture::Info, at: &str) -> Result<TexRef, SceneError> {
        let mut r = self.raw_ref(info.texture().index(), info.tex_coord(), None, at)?;
        if let Some(t) = info.texture_transform() {
            r.transform =
                checked_transform(t.offset(), t.rotation(), t.scale()).ok_or_else(|| {
                    self.malformed(format!(
                        "{at}.extensions.KHR_texture_transform holds a non-finite number"
                    ))
                })?;
            if let Some(c) = t.tex_coord() {
                r.tex_coord = c;
            }
        }
        Ok(r)
    }

    /// The scene texture for a texture reference: the glTF texture's image and sampler with the reference's
    /// UV set and transform, made once per distinct mapping.
    fn texture_ref(&mut self, r: &TexRef, space: ColorSpace) -> Result<u32, SceneError> {
        if r.tex_coord as usize >= UV_SETS {
            self.builder.warnings.push(format!(
                "texture {} uses TEXCOORD_{}; only TEXCOORD_0 and TEXCOORD_1 are read (TEXCOORD_1 used)",
                r.texture, r.tex_coord
            ));
        }
        let set = (r.tex_coord as usize).min(UV_SETS - 1);
        let t = r.transform;
        let bits = [
            t.offset.x.to_bits(),
            t.offset.y.to_bits(),
            t.rotation.to_bits(),
            t.scale.x.to_bits(),
            t.scale.y.to_bits(),
        ];
        let key = (r.texture, space, set, bits);
        if let Some(&id) = self.texture_cache.get(&key) {
            return Ok(id);
        }
        let texture = self
            .document
            .textures()
            .nth(r.texture)
            .expect("texture index checked by raw_ref");
        // Each glTF texture pairs an image with its own sampler; textures sharing an image share its pixels.
        let image = self.mip_image(texture.source(), space)?;
        let t = Texture::new(image, sampler_of(&texture.sampler())).with_mapping(set, t);
        self.builder.textures.push(t);
        let id = (self.builder.textures.len() - 1) as u32;
        self.texture_cache.insert(key, id);
        Ok(id)
    }
    /// Refuses a non-finite factor, or a negative emission, with an error naming the material and field.
    fn check_material_numbers(
        &self,
        material: &gltf::Material,
        emissive_strength: f32,
    ) -> Result<(), SceneError> {
        let pbr = material.pbr_metallic_roughness();
        let mut fields: Vec<(&str, Vec<f32>, bool)> = vec![
            (
                "pbrMetallicRoughness.baseColorFactor",
                pbr.base_color_factor().to_vec(),
                false,
            ),
            (
                "pbrMetallicRoughness.metallicFactor",
                vec![pbr.metallic_factor()],
                false,
            ),
            (
                "pbrMetallicRoughness.roughnessFactor",
                vec![pbr.roughness_factor()],
                false,
            ),
            ("emissiveFactor", material.emissive_factor().to_vec(), true),
            (
                "KHR_materials_emissive_strength.emissiveStrength",
                vec![emissive_strength],
                true,
            ),
        ];
        if let Some(t) = material.normal_texture() {
            fields.push(("normalTexture.scale", vec![t.scale()], false));
        }
        if let Some(cutoff) = material.alpha_cutoff() {
            fields.push(("alphaCutoff", vec![cutoff], true));
        }
        if let Some(ior) = material.ior() {
            fields.push(("KHR_materials_ior.ior", vec![ior], false));
        }
        if let Some(t) = material.transmission() {
            let f = t.transmission_factor();
            fields.push((
                "KHR_materials_transmission.transmissionFactor",
                vec![f],
                false,
            ));
        }
        if let Some(s) = material.specular() {
            fields.push((
                "KHR_materials_specular.specularFactor",
                vec![s.specular_factor()],
                false,
            ));
            let c = s.specular_color_factor().to_vec();
            fields.push(("KHR_materials_specular.specularColorFactor", c, false));
        }
        if let Some(v) = material.volume() {
            let t = v.thickness_factor();
            fields.push(("KHR_materials_volume.thicknessFactor", vec![t], false));
            let c = v.attenuation_color().to_vec();
            fields.push(("KHR_materials_volume.attenuationColor", c, false));
        }
        let at = material.index().map_or_else(
            || "the default material".to_owned(),
            |i| format!("materials[{i}]"),
        );
        for (field, values, non_negative) in fields {
            if let Some(v) = values
                .iter()
                .find(|v| !v.is_finite() || (non_negative && **v < 0.0))
            {
                let rule = if non_negative {
                    "finite and >= 0"
                } else {
                    "finite"
                };
                return Err(self.error(SceneErrorKind::Malformed(format!(
                    "{at}.{field} holds {v}; it must be {rule}"
                ))));
            }
        }
        Ok(())
    }

    /// The compositing tags in a material's `extras` (see [`node_tags`]).
    fn material_tags(
        &self,
        material: &gltf::Material,
        name: &str,
    ) -> Result<CompositingTags, SceneError> {
        let bad = |msg: String| {
            self.error(SceneErrorKind::Malformed(format!(
                "material '{}': extras: {msg}",
                one_line(name, QUOTE)
            )))
        };
        let Some(raw) = material.extras() else {
            return Ok(CompositingTags::default());
        };
        let extras: serde_json::Value =
            serde_json::from_str(raw.get()).map_err(|e| bad(e.to_string()))?;
        node_tags(Some(&extras)).map_err(bad)
    }

    /// The medium filling meshes with this material: `extras.nimbus_medium`, else `KHR_materials_volume` with
    /// `thicknessFactor` > 0 on a material that transmits, specularly or diffusely (absorption only).
    fn interior_medium(
        &mut self,
        material: &gltf::Material,
        m: &Material,
    ) -> Result<Option<u32>, SceneError> {
        let path = self.path;
        let bad = |msg: String| {
            SceneError::new(
                path,
                SceneErrorKind::Malformed(format!(
                    "material '{}': {msg}",
                    one_line(&m.name, QUOTE)
                )),
            )
        };
        if let Some(raw) = material.extras() {
            let extras: serde_json::Value =
                serde_json::from_str(raw.get()).map_err(|e| bad(format!("extras: {e}")))?;
            let at = format!("material '{}'", one_line(&m.name, QUOTE));
            let unknown = unknown_json_names(&extras, MATERIAL_EXTRAS, "nimbus_");
            self.unknown_keys(&format!("{at}: extras"), &unknown)?;
            if let Some(spec) = extras.get("nimbus_medium") {
                let unknown = unknown_json_keys(spec, crate::volume::MEDIUM_KEYS);
                self.unknown_keys(&format!("{at}: nimbus_medium"), &unknown)?;
                let medium =
                    crate::volume::parse_nimbus_medium(spec, &m.name).map_err(|source| {
                        self.error(SceneErrorKind::Volume {
                            at: format!("material '{}': nimbus_medium", one_line(&m.name, QUOTE))
                                .into(),
                            source,
                        })
                    })?;
                return Ok(Some(self.builder.add_medium(medium)));
            }
        }
        if let Some(volume) = material.volume() {
            if volume.thickness_factor() > 0.0 && (m.transmission > 0.0 || m.transmits_diffusely())
            {
                let distance = volume.attenuation_distance();
                let color = Rgb::from(volume.attenuation_color());
                if distance.is_nan() || distance <= 0.0 || color.min_element() <= 0.0 {
                    return Err(bad(
                        "KHR_materials_volume needs attenuationDistance > 0 and a positive attenuationColor".into(),
                    ));
                }
                // Beer's law: attenuationColor is the transmittance after attenuationDistance (infinite: none).
                let sigma_a = if distance.is_finite() {
                    Rgb::new(-color.x.ln(), -color.y.ln(), -color.z.ln()).max(Rgb::ZERO) / distance
                } else {
                    Rgb::ZERO
                };
                let medium = crate::volume::homogeneous::HomogeneousMedium::new(
                    &m.name,
                    sigma_a,
                    Rgb::ZERO,
                    0.0,
                );
                return Ok(Some(self.builder.add_medium(std::sync::Arc::new(medium))));
            }
        }
        Ok(None)
    }

    /// The decoded image with its mip pyramid, decoded once per colour space.
    fn mip_image(
        &mut self,
        image: gltf::Image,
        space: ColorSpace,
    ) -> Result<Arc<MipImage>, SceneError> {
        let key = (image.index(), space);
        if let Some(img) = self.images.get(&key) {
            return Ok(img.clone());
        }
        let index = image.index();
        let rgba = self.decode_image(image)?;
        let mip = MipImage::from_rgba8(
            rgba.width() as usize,
            rgba.height() as usize,
            rgba.as_raw(),
            space,
        )
        .ok_or_else(|| self.error(SceneErrorKind::Malformed(format!("image {index} is empty"))))?;
        let mip = Arc::new(mip);
        self.images.insert(key, mip.clone());
        Ok(mip)
    }

    fn decode_image(&mut self, image: gltf::Image) -> Result<image::RgbaImage, SceneError> {
        let name = match image.source() {
            gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                format!("image {} ('{}')", image.index(), one_line(uri, QUOTE))
            }
            _ => format!("image {}", image.index()),
        };
        let bytes: Vec<u8> = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let buffer = &self.buffers[view.buffer().index()];
                let end = view.offset().checked_add(view.length());
                match end {
                    Some(end) if end <= buffer.len() => buffer[view.offset()..end].to_vec(),
                    _ => {
                        return Err(self.error(SceneErrorKind::InvalidReference(format!(
                            "{name}: buffer view {} runs past its buffer",
                            view.index()
                        ))))
                    }
                }
            }
            gltf::image::Source::Uri { uri, .. } => read_uri(uri, &self.base, &self.options.limits)
                .map_err(|e| {
                    self.error(SceneErrorKind::InvalidReference(format!("{name}: {e}")))
                })?,
        };
        let budget = self.options.limits;
        let malformed = |e: String| {
            self.error(SceneErrorKind::Malformed(format!(
                "{name}: {}",
                one_line(&e, QUOTE)
            )))
        };
        // The RGBA8 copy and the float mip pyramid (16 bytes a texel, 4/3 for the levels) stay in the budget.
        let decoded = crate::limits::decode_image(&bytes, &budget, 4 + 22)
            .map_err(malformed)?
            .to_rgba8();
        Ok(decoded)
    }

    /// Reads `nimbus_light_units` from the scene extras, before any light is loaded.
    fn read_light_units(&mut self, extras: &gltf::json::Extras) -> Result<(), SceneError> {
        let Some(raw) = extras else { return Ok(()) };
        let value: serde_json::Value = serde_json::from_str(raw.get())
            .map_err(|e| self.error(SceneErrorKind::Malformed(format!("scene extras: {e}"))))?;
        self.light_unit_scale = match value.get("nimbus_light_units") {
            None => 1.0 / LUMENS_PER_WATT,
            Some(v) => match v.as_str() {
                Some("photometric") => 1.0 / LUMENS_PER_WATT,
                Some("radiometric") => 1.0,
                _ => {
                    return Err(self.error(SceneErrorKind::Malformed(format!(
                        "scene extras: nimbus_light_units must be \"photometric\" or \"radiometric\", not {v}"
                    ))))
                }
            },
        };
        Ok(())
    }

    fn read_scene_extras(&mut self, extras: &gltf::json::Extras) -> Result<(), SceneError> {
        let Some(raw) = extras else { return Ok(()) };
        let value: serde_json::Value = serde_json::from_str(raw.get())
            .map_err(|e| self.error(SceneErrorKind::Malformed(format!("scene extras: {e}"))))?;
        self.unknown_keys(
            "scene extras",
            &unknown_json_names(&value, SCENE_EXTRAS, "nimbus_"),
        )?;
        if let Some(env) = value.get("nimbus_environment") {
            let unknown = unknown_json_names(env, ENVIRONMENT_KEYS, "");
            self.unknown_keys("scene extras: nimbus_environment", &unknown)?;
        }
        if let Some(b) = value.get("max_bounces") {
            let b = b.as_u64().ok_or_else(|| {
                self.error(SceneErrorKind::Malformed(
                    "scene extras: max_bounces must be a non-negative integer".into(),
                ))
            })?;
            self.builder.max_bounces = Some(b.min(u32::MAX as u64) as u32);
        }
        if let Some(env) = value.get("nimbus_environment") {
            let (env, group) = parse_environment(env, &self.base, &self.options.limits)
                .map_err(|kind| self.error(kind))?;
            self.builder.set_environment(env);
            self.builder.set_environment_group(group);
        }
        if let Some(t) = value.get("nimbus_transparent") {
            let t = t.as_bool().ok_or_else(|| {
                self.error(SceneErrorKind::Malformed(
                    "scene extras: nimbus_transparent must be true or false".into(),
                ))
            })?;
            self.builder.set_transparent(t);
        }
        Ok(())
    }
}

/// The sampler a glTF texture reads with: its wrap modes and filters, with glTF viewers' defaults (LINEAR
/// magnification, LINEAR_MIPMAP_LINEAR minification) where the file names none.
fn sampler_of(sampler: &gltf::texture::Sampler) -> Sampler {
    use gltf::texture::{MagFilter, MinFilter, WrappingMode};
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    let mag = match sampler.mag_filter() {
        Some(MagFilter::Nearest) => Filter::Nearest,
        Some(MagFilter::Linear) | None => Filter::Linear,
    };
    let (min, mip) = match sampler.min_filter() {
        Some(MinFilter::Nearest) => (Filter::Nearest, None),
        Some(MinFilter::Linear) => (Filter::Linear, None),
        Some(MinFilter::NearestMipmapNearest) => (Filter::Nearest, Some(Filter::Nearest)),
        Some(MinFilter::LinearMipmapNearest) => (Filter::Linear, Some(Filter::Nearest)),
        Some(MinFilter::NearestMipmapLinear) => (Filter::Nearest, Some(Filter::Linear)),
        Some(MinFilter::LinearMipmapLinear) | None => (Filter::Linear, Some(Filter::Linear)),
    };
    Sampler {
        wrap_s: wrap(sampler.wrap_s()),
        wrap_t: wrap(sampler.wrap_t()),
        mag,
        min,
        mip,
    }
}

/// The `nimbus_*` keys a scene's `extras` may hold (its other keys belong to other tools).
const SCENE_EXTRAS: &[&str] = &[
    "nimbus_environment",
    "nimbus_transparent",
    "nimbus_light_units",
];

/// The `nimbus_*` keys a node's `extras` may hold.
const NODE_EXTRAS: &[&str] = &[
    "nimbus_volume",
    "nimbus_camera",
    "nimbus_light_group",
    "nimbus_holdout",
    "nimbus_shadow_catcher",
];

/// The `nimbus_*` keys a material's `extras` may hold.
const MATERIAL_EXTRAS: &[&str] = &[
    "nimbus_medium",
    "nimbus_light_group",
    "nimbus_holdout",
    "nimbus_shadow_catcher",
];

/// The keys of a `nimbus_environment` object.
const ENVIRONMENT_KEYS: &[&str] = &["color", "map", "intensity", "light_group"];

/// Parses a `nimbus_environment` object: `{"color": [r,g,b]}` or `{"map": "file", "intensity": s}`, with an
/// optional `"light_group": "name"`; the map path is relative to `base`. Returns the light and its group.
pub fn parse_environment(
    value: &serde_json::Value,
    base: &Path,
    limits: &Limits,
) -> Result<(EnvironmentLight, Option<String>), SceneErrorKind> {
    let malformed = |m: &str| SceneErrorKind::Malformed(format!("nimbus_environment: {m}"));
    let group = match value.get("light_group") {
        None => None,
        Some(g) => Some(
            light_group_name(g)
                .map_err(|m| SceneErrorKind::Malformed(format!("nimbus_environment: {m}")))?,
        ),
    };
    parse_environment_light(value, base, limits, &malformed).map(|env| (env, group))
}

/// The light of a `nimbus_environment` object (see [`parse_environment`]).
fn parse_environment_light(
    value: &serde_json::Value,
    base: &Path,
    limits: &Limits,
    malformed: &dyn Fn(&str) -> SceneErrorKind,
) -> Result<EnvironmentLight, SceneErrorKind> {
    if let Some(c) = value.get("color") {
        let rgb = parse_rgb(c)
            .ok_or_else(|| malformed("'color' must be an array of three non-negative numbers"))?;
        return Ok(EnvironmentLight::Constant(rgb));
    }
    if let Some(m) = value.get("map") {
        let file = m
            .as_str()
            .ok_or_else(|| malformed("'map' must be a file name"))?;
        let intensity = match value.get("intensity") {
            Some(v) => v
                .as_f64()
                .filter(|v| v.is_finite() && *v >= 0.0)
                .ok_or_else(|| malformed("'intensity' must be a non-negative number"))?
                as f32,
            None => 1.0,
        };
        let map = EnvironmentMap::load(&base.join(file), intensity, limits)?;
        return Ok(EnvironmentLight::Map(Box::new(map)));
    }
    Err(malformed("expected 'color' or 'map'"))
}

/// What a node passes to its children: its compositing tags (its own over its parents') and the name of the
/// top-level node above it, Cryptomatte's asset.
struct NodeContext {
    tags: CompositingTags,
    asset: String,
}

/// A node's name for messages, Cryptomatte and per-light groups: its own, else its mesh's (as Blender's importer
/// names an unnamed node), else `node <index>`.
fn node_name(node: &gltf::Node) -> String {
    node.name()
        .or_else(|| node.mesh().and_then(|m| m.name()))
        .map_or_else(|| format!("node {}", node.index()), str::to_owned)
}

/// The compositing tags in a node's or a material's `extras` (see [`CompositingTags`]): `nimbus_light_group`
/// (a non-empty string), `nimbus_holdout` and `nimbus_shadow_catcher` (booleans). An error names the key.
pub(crate) fn node_tags(extras: Option<&serde_json::Value>) -> Result<CompositingTags, String> {
    let Some(extras) = extras else {
        return Ok(CompositingTags::default());
    };
    let flag = |key: &str| match extras.get(key) {
        None => Ok(false),
        Some(v) => v
            .as_bool()
            .ok_or_else(|| format!("{key} must be true or false")),
    };
    Ok(CompositingTags {
        light_group: match extras.get("nimbus_light_group") {
            None => None,
            Some(g) => Some(light_group_name(g).map_err(|m| format!("nimbus_light_group: {m}"))?),
        },
        holdout: flag("nimbus_holdout")?,
        shadow_catcher: flag("nimbus_shadow_catcher")?,
    })
}

/// A light group's name: a non-empty string of at most 64 characters.
fn light_group_name(value: &serde_json::Value) -> Result<String, String> {
    match value.as_str() {
        Some(name) if !name.trim().is_empty() && name.chars().count() <= 64 => Ok(name.to_owned()),
        _ => Err("a light group must be a non-empty string of at most 64 characters".into()),
    }
}

/// Converts strip and fan index lists to triangle lists (glTF 2.0 §3.7.2.1); degenerate triangles are dropped.
fn triangulate(indices: &[u32], mode: gltf::mesh::Mode) -> Vec<[u32; 3]> {
    let tris: Vec<[u32; 3]> = match mode {
        gltf::mesh::Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i - 2], indices[i - 1], indices[i]]
                } else {
                    [indices[i - 1], indices[i - 2], indices[i]]
                }
            })
            .collect(),
        gltf::mesh::Mode::TriangleFan => (2..indices.len())
            .map(|i| [indices[0], indices[i - 1], indices[i]])
            .collect(),
        _ => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    };
    tris.into_iter()
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

/// The triangles and vertices of a primitive, from its index and POSITION counts, before anything is read:
/// a third of the corners for a triangle list, all but two for a strip or fan.
fn primitive_size(primitive: &gltf::Primitive) -> (u64, u64) {
    let vertices = primitive
        .get(&gltf::Semantic::Positions)
        .map_or(0, |a| a.count() as u64);
    let corners = primitive.indices().map_or(vertices, |a| a.count() as u64);
    let triangles = match primitive.mode() {
        gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => {
            corners.saturating_sub(2)
        }
        _ => corners / 3,
    };
    (triangles, vertices)
}

/// The material's `alphaMode` and `alphaCutoff` (default 0.5), glTF 2.0 §3.9.4.
fn alpha_mode(material: &gltf::Material) -> AlphaMode {
    match material.alpha_mode() {
        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        gltf::material::AlphaMode::Mask => AlphaMode::Mask {
            cutoff: material.alpha_cutoff().unwrap_or(0.5),
        },
        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
    }
}

/// A texture reference (glTF `textureInfo`): the glTF texture, its texture-coordinate set and its transform.
struct TexRef {
    texture: usize,
    tex_coord: u32,
    transform: UvTransform,
}

/// A `KHR_texture_transform` from its fields, `None` if a number is not finite.
fn checked_transform(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Option<UvTransform> {
    let finite = offset.iter().chain(&scale).all(|v| v.is_finite()) && rotation.is_finite();
    finite.then(|| UvTransform {
        offset: Vec2::from(offset),
        rotation,
        scale: Vec2::from(scale),
    })
}

/// The names of the file's `KHR_materials_variants` variants (the root extension's `variants[i].name`), in
/// order; none without the extension. An error names a malformed entry.
fn variant_names(document: &gltf::Document) -> Result<Vec<String>, String> {
    let Some(ext) = document.extension_value("KHR_materials_variants") else {
        return Ok(Vec::new());
    };
    let at = "extensions.KHR_materials_variants";
    let variants = ext
        .get("variants")
        .and_then(|v| v.as_array())
        .ok_or_else(|| format!("{at}.variants must be an array"))?;
    variants
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.get("name")
                .and_then(|n| n.as_str())
                .map(str::to_owned)
                .ok_or_else(|| format!("{at}.variants[{i}].name must be a string"))
        })
        .collect()
}

/// The index of the variant named `wanted` among `variants`: `None` when none is wanted; an error listing the
/// variants when the file has no variant of that name, or several.
fn choose_variant(
    variants: &[String],
    wanted: Option<&str>,
) -> Result<Option<usize>, SceneErrorKind> {
    let Some(wanted) = wanted else {
        return Ok(None);
    };
    let list = || {
        let names: Vec<String> = variants.iter().map(|n| one_line(n, QUOTE)).collect();
        one_line(&names.join(", "), 8 * QUOTE)
    };
    let matches: Vec<usize> = (0..variants.len())
        .filter(|&i| variants[i] == wanted)
        .collect();
    match matches[..] {
        [i] => Ok(Some(i)),
        [] if variants.is_empty() => Err(SceneErrorKind::InvalidReference(format!(
            "material variant '{}': the file has no material variants (KHR_materials_variants)",
            one_line(wanted, QUOTE)
        ))),
        [] => Err(SceneErrorKind::InvalidReference(format!(
            "the file has no material variant '{}'; its variants are: {}",
            one_line(wanted, QUOTE),
            list()
        ))),
        _ => Err(SceneErrorKind::Malformed(format!(
            "{} material variants are named '{}' (variants: {})",
            matches.len(),
            one_line(wanted, QUOTE),
            list()
        ))),
    }
}

/// An array of exactly `N` numbers, each in \[0, 1\]; `None` otherwise.
fn unit_numbers<const N: usize>(value: &serde_json::Value) -> Option<[f32; N]> {
    let a = value.as_array().filter(|a| a.len() == N)?;
    let mut out = [0.0; N];
    for (o, v) in out.iter_mut().zip(a) {
        *o = v.as_f64().filter(|v| (0.0..=1.0).contains(v))? as f32;
    }
    Some(out)
}

/// `materials[i]` or "the default material", for messages.
fn material_path(material: &gltf::Material) -> String {
    material.index().map_or_else(
        || "the default material".to_owned(),
        |i| format!("materials[{i}]"),
    )
}
