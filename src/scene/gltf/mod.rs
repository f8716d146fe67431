//! glTF 2.0 loader (`.gltf` with external or data-URI buffers, and `.glb`), on top of the `gltf` crate.
//!
//! Reads the default scene's node hierarchy (TRS and matrix transforms), triangle meshes (indexed or not,
//! strips and fans triangulated; POSITION, NORMAL, TANGENT, TEXCOORD_0, TEXCOORD_1, COLOR_0, sparse or not,
//! with the component types of `KHR_mesh_quantization`; see `accessors`), morph targets at their default
//! weights and skins at their rest pose (see `deform`), every camera (perspective or orthographic, with the
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
//! cameras, lights and node transforms are checked here (see `check`), since the crate panics on some
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

mod accessors;
mod animation;
mod camera;
mod check;
mod deform;
mod extras;
mod instancing;
mod lights;
mod material_extensions;
mod materials;
mod meshes;
mod nodes;
mod textures;
mod variants;

use super::{LoadOptions, SceneBuilder, SceneError, SceneErrorKind};
use crate::geometry::CompositingTags;
use crate::light::LUMENS_PER_WATT;
use crate::limits::{one_line, Limits, WorkBudget};
use crate::material::{ColorSpace, MipImage};
use crate::math::Mat4;
use crate::params::UnknownKey;
use crate::scene::MalformedPart;
use check::SkippedChannels;
use gltf::json::validation::Validate;
use meshes::{mesh_users, JointCache};
use nodes::{node_name, NodeContext};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;
use variants::{choose_variant, variant_names};

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

/// Why the bytes a buffer or image URI names could not be read ([`read_uri`]); each message is one line.
#[derive(Debug, thiserror::Error)]
enum UriError {
    /// A `data:` URI the `gltf` crate cannot decode: its message.
    #[error("{0}")]
    DataUri(String),
    /// A URI with a scheme other than `data:` or `file://`.
    #[error("only data: and file URIs are read")]
    Scheme,
    /// A `%XX` escape that is malformed or decodes to invalid UTF-8.
    #[error("the URI is not valid percent-encoded UTF-8")]
    PercentEncoding,
    /// The file could not be read within the budget: the reader's message.
    #[error("{0}")]
    File(String),
}

/// Reads the bytes a buffer or image URI names: a `data:` URI decoded, else a file (a relative path, an
/// absolute one or a `file://` URI, percent-decoded) read within the memory budget.
fn read_uri(uri: &str, base: &Path, limits: &crate::limits::Limits) -> Result<Vec<u8>, UriError> {
    if uri.starts_with("data:") {
        return gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), Some(base))
            .map(|d| d.0)
            .map_err(|e| UriError::DataUri(one_line(&e.to_string(), QUOTE)));
    }
    let rest = uri.strip_prefix("file://").unwrap_or(uri);
    if rest.len() == uri.len() && uri.contains("://") {
        return Err(UriError::Scheme);
    }
    let decoded = percent_decode(rest).ok_or(UriError::PercentEncoding)?;
    crate::limits::read_file(&base.join(decoded), limits)
        .map_err(|e| UriError::File(one_line(&e.to_string(), QUOTE)))
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
    let malformed = |part, m: String| err(SceneErrorKind::malformed(part, m));
    let (root, blob, skipped) =
        parse(bytes).map_err(|e| malformed(MalformedPart::File, e.to_string()))?;
    check::check_document(&root).map_err(&err)?;
    let mut warnings = validate(&root).map_err(&err)?;
    warnings.extend(skipped.warnings.iter().cloned());
    let document = gltf::Document::from_json_without_validation(root);
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let variants =
        variant_names(&document).map_err(|e| malformed(MalformedPart::Material, e.to_string()))?;
    let variant = choose_variant(&variants, options.variant).map_err(&err)?;
    if options.variant.is_none() && !variants.is_empty() {
        let names: Vec<String> = variants.iter().map(|n| one_line(n, QUOTE)).collect();
        warnings.push(format!(
            "the file has material variants: {} (--variant NAME chooses one)",
            names.join(", ")
        ));
    }
    let buffers = read_buffers(&document, blob, &base, path, &options.limits)?;
    let (pose, motion) =
        read_pose(&document, &buffers, options, &skipped, &mut warnings).map_err(&err)?;
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
    loader.load_default_scene()?;
    Ok(loader.builder)
}

/// The bytes of every buffer of `document`: the GLB binary chunk `blob` (for the one buffer that uses it), a
/// data URI decoded or a file read relative to `base` within `limits`, each at least its declared length.
fn read_buffers(
    document: &gltf::Document,
    mut blob: Option<Vec<u8>>,
    base: &Path,
    path: &Path,
    limits: &Limits,
) -> Result<Vec<gltf::buffer::Data>, SceneError> {
    let err = |kind| SceneError::new(path, kind);
    let malformed = |m: String| err(SceneErrorKind::malformed(MalformedPart::Data, m));
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
            gltf::buffer::Source::Uri(uri) => read_uri(uri, base, limits)
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
    Ok(buffers)
}

/// The pose the nodes are read in (the file's, or the animations sampled at the shot's frame) and, under a
/// shutter, the poses at its motion steps; the animations' warnings are added to `warnings`.
fn read_pose(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    options: &LoadOptions,
    skipped: &SkippedChannels,
    warnings: &mut Vec<String>,
) -> Result<(animation::Pose, Option<animation::ShutterPoses>), SceneErrorKind> {
    // A still with a shutter is frame 1 of the shot, as VDB sequences read it.
    let frame = options.frame.or(options.shutter.map(|_| 1));
    let fps = options.fps.unwrap_or(crate::frames::DEFAULT_FPS);
    let animations = match frame {
        Some(_) if document.animations().len() > 0 => Some(animation::Animations::read(
            document,
            buffers,
            &options.limits,
            skipped,
        )?),
        _ => None,
    };
    let pose = match (frame, &animations) {
        (Some(frame), Some(animations)) => {
            warnings.extend(animations.warnings.iter().cloned());
            animations.pose_at(document, (frame as f64 / fps) as f32)
        }
        _ => animation::Pose {
            locals: document
                .nodes()
                .map(|n| Mat4::from_cols_array_2d(&n.transform().matrix()))
                .collect(),
            weights: vec![None; document.nodes().len()],
        },
    };
    let motion = match (frame, options.shutter, &animations) {
        (Some(frame), Some(shutter), Some(animations)) => {
            animation::shutter_poses(animations, document, frame, fps, shutter)
        }
        _ => None,
    };
    Ok((pose, motion))
}

/// A parsed document, its GLB binary chunk if any, and the animation channels skipped.
type JsonParse = (gltf::json::Root, Option<Vec<u8>>, SkippedChannels);

/// Why a file is not a glTF or GLB document the loader can read.
#[derive(Debug, thiserror::Error)]
enum ParseError {
    /// A GLB header whose length field is missing or shorter than the header.
    #[error(
        "GLB container: the header's length field ({length}) is shorter than the 12-byte header"
    )]
    ShortGlbHeader {
        /// The length field, or `missing`.
        length: String,
    },
    /// A GLB container the `gltf` crate refuses.
    #[error("GLB container: {0}")]
    Glb(gltf::Error),
    /// A GLB file's JSON chunk that does not parse.
    #[error("JSON chunk: {0}")]
    JsonChunk(JsonError),
    /// A `.gltf` file's JSON that does not parse.
    #[error("JSON: {0}")]
    Json(JsonError),
}

/// Why a glTF document's JSON could not be read (see [`parse_json`]).
#[derive(Debug, thiserror::Error)]
enum JsonError {
    /// A channel to skip in a document that cannot be read whole to skip it.
    #[error(transparent)]
    Unskippable(#[from] check::UnskippableChannel),
    /// The `gltf` crate's parser refused the document.
    #[error(transparent)]
    Syntax(#[from] gltf::json::Error),
}

/// The document of a `.gltf` or `.glb` file, its GLB binary chunk if any, and the animation channels skipped.
fn parse(bytes: &[u8]) -> Result<JsonParse, ParseError> {
    if bytes.starts_with(b"glTF") {
        // The crate subtracts the header size from the declared length unchecked.
        let length = bytes
            .get(8..12)
            .map(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]));
        if length.is_none_or(|l| l < 12) {
            return Err(ParseError::ShortGlbHeader {
                length: length.map_or_else(|| "missing".to_owned(), |l| l.to_string()),
            });
        }
        let mut glb = gltf::binary::Glb::from_slice(bytes).map_err(ParseError::Glb)?;
        let (root, skipped) = parse_json(&glb.json).map_err(ParseError::JsonChunk)?;
        Ok((root, glb.bin.take().map(|b| b.into_owned()), skipped))
    } else {
        let (root, skipped) = parse_json(bytes).map_err(ParseError::Json)?;
        Ok((root, None, skipped))
    }
}

/// The document in `json`, less the animation channels the `gltf` crate cannot read (see
/// `check::skip_unknown_channels`), and which those were.
fn parse_json(json: &[u8]) -> Result<(gltf::json::Root, SkippedChannels), JsonError> {
    let (edited, skipped) = check::skip_unknown_channels(json)?;
    let root = match edited {
        Some(document) => gltf::json::deserialize::from_value(document),
        None => gltf::json::deserialize::from_slice(json),
    }?;
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
        return Err(SceneErrorKind::malformed(
            MalformedPart::File,
            one_line(&fatal.join("; "), 4 * QUOTE),
        ));
    }
    Ok(root
        .extensions_used
        .iter()
        .filter(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str()))
        .map(|e| format!("optional extension {e} is not supported and is ignored"))
        .collect())
}

/// The state of one glTF load: the document, its buffers and pose, and the builder being filled.
struct Loader<'a> {
    path: &'a Path,
    /// Every node's local matrix and animated morph weights: the file's, or at the shot's frame.
    pose: animation::Pose,
    /// The animation at the motion steps across the shutter, when there are both.
    motion: Option<animation::ShutterPoses>,
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
    /// Reads the default scene (else the first): its light units, its node trees, then its extras.
    fn load_default_scene(&mut self) -> Result<(), SceneError> {
        let document = self.document;
        let scene = document
            .default_scene()
            .or_else(|| document.scenes().next())
            .ok_or_else(|| self.malformed(MalformedPart::File, "the file has no scene".into()))?;
        self.read_light_units(scene.extras())?;
        for node in scene.nodes() {
            let top = NodeContext {
                tags: CompositingTags::default(),
                asset: node_name(&node),
            };
            self.visit(node, Mat4::IDENTITY, 0, &top)?;
        }
        self.read_scene_extras(scene.extras())
    }

    /// The error `kind`, naming the file.
    fn error(&self, kind: SceneErrorKind) -> SceneError {
        SceneError::new(self.path, kind)
    }

    /// Warns about (or under `--strict` refuses) the keys at `at` that the loader ignores.
    fn unknown_keys(&mut self, at: &str, unknown: &[UnknownKey]) -> Result<(), SceneError> {
        super::report_unknown_keys(&mut self.builder, self.options.strict, at, unknown)
            .map_err(|kind| self.error(kind))
    }

    /// An error about a malformed `part` of the file, naming the file, its message cut to one line.
    fn malformed(&self, part: MalformedPart, message: String) -> SceneError {
        self.error(SceneErrorKind::malformed(
            part,
            one_line(&message, 4 * QUOTE),
        ))
    }
}
