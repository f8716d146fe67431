//! Up-front checks of a parsed glTF document, run before the `gltf` crate's own validation (which indexes
//! some arrays without checking) and before anything is read: every index field against its array, the node
//! graph a forest, cameras and `KHR_lights_punctual` lights with their projection or cone present and their
//! numbers in range, node transforms and morph weights finite, skins with at least one joint. The crate's accessors that would panic on such data (`projection()`,
//! `kind()`, `children()`...) are then safe to call.
//!
//! Before those, [`skip_unknown_channels`] reads the JSON for animation channels whose target path the crate
//! does not know (`KHR_animation_pointer`'s `"pointer"`): the crate panics on such a path, and refuses the
//! target without a `node` that the extension writes. They are removed, with a warning each.

use crate::scene::MalformedPart;
use crate::scene::SceneErrorKind;
use gltf::json::validation::Checked;
use gltf::json::{Index, Root};
use serde::Deserialize;
use std::f32::consts::{FRAC_PI_2, PI};

/// What the up-front checks refuse, each naming the field it was found at (`nodes[3].camera`).
#[derive(Debug, thiserror::Error)]
pub(super) enum CheckError {
    /// An index past the end of the array it names.
    #[error("{field} is {index}, past the end of {array} ({len} entries)")]
    IndexOutOfRange {
        /// Where the index was read.
        field: String,
        /// The index.
        index: usize,
        /// The array it names.
        array: String,
        /// The array's length.
        len: usize,
    },
    /// An image with neither a `uri` nor a `bufferView`, or with a `bufferView` but no `mimeType`.
    #[error("{0}")]
    ImageSource(String),
    /// The node graph is not a forest rooted at the scenes' nodes (a cycle, a node with two parents...).
    #[error("{0}")]
    NotAForest(String),
    /// A number that must be finite is not.
    #[error("{field} is {value}")]
    NotFinite {
        /// Where it was read (with its position in an array of numbers).
        field: String,
        /// The number.
        value: f32,
    },
    /// A skin (by index) without joints.
    #[error("skins[{0}] has no joints")]
    SkinWithoutJoints(usize),
    /// A camera without its projection, or with a number out of range.
    #[error("{0}")]
    Camera(String),
    /// A `KHR_lights_punctual` light without its type's object, or with a number out of range.
    #[error("{0}")]
    Light(String),
}

/// The target paths the `gltf` crate reads (glTF 2.0 §3.11).
const KNOWN_PATHS: [&str; 4] = ["translation", "rotation", "scale", "weights"];

/// The animation channels that [`skip_unknown_channels`] removed, by animation, with their warnings.
#[derive(Debug, Default)]
pub(super) struct SkippedChannels {
    /// For each animation, the file's indices of its removed channels, ascending.
    pub removed: Vec<Vec<usize>>,
    /// One warning per removed channel.
    pub warnings: Vec<String>,
}

impl SkippedChannels {
    /// The file's index of channel `kept` of animation `animation` as the crate numbers the channels left.
    pub fn file_index(&self, animation: usize, kept: usize) -> usize {
        let removed = self.removed.get(animation).map_or(&[][..], Vec::as_slice);
        let mut index = kept;
        for &r in removed {
            if r <= index {
                index += 1;
            }
        }
        index
    }
}

/// The parts of a document [`skip_unknown_channels`] reads: each channel's target path.
#[derive(Deserialize)]
struct Scan {
    #[serde(default)]
    animations: Vec<ScanAnimation>,
}

#[derive(Deserialize)]
struct ScanAnimation {
    #[serde(default)]
    channels: Vec<ScanChannel>,
}

#[derive(Deserialize)]
struct ScanChannel {
    target: Option<ScanTarget>,
}

#[derive(Deserialize)]
struct ScanTarget {
    path: Option<serde_json::Value>,
}

/// Finds the animation channels of the JSON `json` whose target path is a string the `gltf` crate does not
/// know, and returns the document without them (`None` when there are none, or when the JSON does not parse,
/// for the crate's parser to report), with the channels removed. A document with such channels that cannot be
/// read whole to remove them (a string of invalid UTF-8 in a field the crate's parser would skip unread) is an
/// error: left to the crate, the channel would reach it and panic.
pub(super) fn skip_unknown_channels(
    json: &[u8],
) -> Result<(Option<serde_json::Value>, SkippedChannels), UnskippableChannel> {
    let mut skipped = SkippedChannels::default();
    let mut first_unknown = None;
    let Ok(scan) = serde_json::from_slice::<Scan>(json) else {
        return Ok((None, skipped));
    };
    for (a, animation) in scan.animations.iter().enumerate() {
        let unknown = animation
            .channels
            .iter()
            .enumerate()
            .filter_map(|(c, channel)| {
                let path = channel.target.as_ref()?.path.as_ref()?.as_str()?;
                (!KNOWN_PATHS.contains(&path)).then_some((c, path))
            });
        let mut removed = Vec::new();
        for (c, path) in unknown {
            first_unknown.get_or_insert_with(|| (a, c, crate::limits::one_line(path, 60)));
            skipped.warnings.push(format!(
                "animations[{a}].channels[{c}]: target path \"{}\" is not played (only {}; KHR_animation_pointer is not supported); its target keeps its rest pose",
                crate::limits::one_line(path, 60),
                KNOWN_PATHS.join(", ")
            ));
            removed.push(c);
        }
        skipped.removed.push(removed);
    }
    if skipped.warnings.is_empty() {
        return Ok((None, skipped));
    }
    let mut document = serde_json::from_slice::<serde_json::Value>(json).map_err(|source| {
        let (animation, channel, path) = first_unknown.expect("a warning was given for a channel");
        UnskippableChannel {
            animation,
            channel,
            path,
            source,
        }
    })?;
    for (a, removed) in skipped.removed.iter().enumerate() {
        if let Some(channels) = document["animations"][a]["channels"].as_array_mut() {
            for &c in removed.iter().rev() {
                channels.remove(c);
            }
        }
    }
    Ok((Some(document), skipped))
}

/// An animation channel with a target path the `gltf` crate does not know, in a document that cannot be read
/// whole to remove it (see [`skip_unknown_channels`]).
#[derive(Debug, thiserror::Error)]
#[error("animations[{animation}].channels[{channel}]: target path \"{path}\" would be skipped, but the document cannot be read to skip it: {source}")]
pub(super) struct UnskippableChannel {
    /// The animation's index.
    animation: usize,
    /// The channel's index in the file.
    channel: usize,
    /// The target path, cut to one short line.
    path: String,
    /// Why the document cannot be read whole.
    source: serde_json::Error,
}

/// All the checks, in order: indices first (the others follow them).
pub(super) fn check_document(root: &Root) -> Result<(), SceneErrorKind> {
    let invalid = |e: CheckError| SceneErrorKind::InvalidReference(e.to_string());
    let malformed =
        |part: MalformedPart| move |e: CheckError| SceneErrorKind::malformed(part, e.to_string());
    check_indices(root).map_err(invalid)?;
    check_forest(root).map_err(malformed(MalformedPart::Node))?;
    check_nodes(root).map_err(malformed(MalformedPart::Node))?;
    check_cameras(root).map_err(malformed(MalformedPart::Camera))?;
    check_lights(root).map_err(malformed(MalformedPart::Light))
}

/// `Ok` if `index` names an element of the array `array` of `len` elements; `field` names where it was read.
fn within<T>(
    field: impl FnOnce() -> String,
    index: Index<T>,
    array: &str,
    len: usize,
) -> Result<(), CheckError> {
    let i = index.value();
    if i < len {
        Ok(())
    } else {
        Err(CheckError::IndexOutOfRange {
            field: field(),
            index: i,
            array: array.to_owned(),
            len,
        })
    }
}

/// Every index in the document points inside the array it names (glTF 2.0 §3.2 and the extensions' own
/// arrays): an index past the end is an error naming the field, the index and the array's length.
fn check_indices(root: &Root) -> Result<(), CheckError> {
    check_scene_and_node_indices(root)?;
    check_mesh_indices(root)?;
    check_buffer_and_image_indices(root)?;
    check_texture_indices(root)?;
    check_material_texture_indices(root)?;
    check_skin_and_animation_indices(root)
}

/// The default scene, each scene's root nodes, and each node's children, camera, mesh, skin and light.
fn check_scene_and_node_indices(root: &Root) -> Result<(), CheckError> {
    let nodes = root.nodes.len();
    if let Some(s) = root.scene {
        within(|| "scene".into(), s, "scenes", root.scenes.len())?;
    }
    for (i, scene) in root.scenes.iter().enumerate() {
        for (j, &n) in scene.nodes.iter().enumerate() {
            within(|| format!("scenes[{i}].nodes[{j}]"), n, "nodes", nodes)?;
        }
    }
    let lights = root
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
        .map_or(0, |l| l.lights.len());
    for (i, node) in root.nodes.iter().enumerate() {
        for (j, &c) in node.children.iter().flatten().enumerate() {
            within(|| format!("nodes[{i}].children[{j}]"), c, "nodes", nodes)?;
        }
        if let Some(c) = node.camera {
            within(
                || format!("nodes[{i}].camera"),
                c,
                "cameras",
                root.cameras.len(),
            )?;
        }
        if let Some(m) = node.mesh {
            within(
                || format!("nodes[{i}].mesh"),
                m,
                "meshes",
                root.meshes.len(),
            )?;
        }
        if let Some(s) = node.skin {
            within(|| format!("nodes[{i}].skin"), s, "skins", root.skins.len())?;
        }
        if let Some(l) = node
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
        {
            let field = || format!("nodes[{i}].extensions.KHR_lights_punctual.light");
            within(field, l.light, "KHR_lights_punctual.lights", lights)?;
        }
    }
    Ok(())
}

/// Each primitive's attribute, index and morph-target accessors and its material.
fn check_mesh_indices(root: &Root) -> Result<(), CheckError> {
    let accessors = root.accessors.len();
    for (i, mesh) in root.meshes.iter().enumerate() {
        for (j, p) in mesh.primitives.iter().enumerate() {
            let at = || format!("meshes[{i}].primitives[{j}]");
            for (semantic, &a) in &p.attributes {
                let name = match semantic {
                    Checked::Valid(s) => s.to_string(),
                    Checked::Invalid => "(invalid)".into(),
                };
                within(
                    || format!("{}.attributes.{name}", at()),
                    a,
                    "accessors",
                    accessors,
                )?;
            }
            if let Some(a) = p.indices {
                within(|| format!("{}.indices", at()), a, "accessors", accessors)?;
            }
            if let Some(m) = p.material {
                let len = root.materials.len();
                within(|| format!("{}.material", at()), m, "materials", len)?;
            }
            for (k, t) in p.targets.iter().flatten().enumerate() {
                for a in [t.positions, t.normals, t.tangents].into_iter().flatten() {
                    within(
                        || format!("{}.targets[{k}]", at()),
                        a,
                        "accessors",
                        accessors,
                    )?;
                }
            }
        }
    }
    Ok(())
}

/// Accessors' (and their sparse parts') buffer views, views' buffers, and images' buffer views (an image needs
/// a `uri` or a `bufferView` with a `mimeType`).
fn check_buffer_and_image_indices(root: &Root) -> Result<(), CheckError> {
    let views = root.buffer_views.len();
    for (i, a) in root.accessors.iter().enumerate() {
        if let Some(v) = a.buffer_view {
            within(
                || format!("accessors[{i}].bufferView"),
                v,
                "bufferViews",
                views,
            )?;
        }
        if let Some(s) = &a.sparse {
            let field = || format!("accessors[{i}].sparse.indices.bufferView");
            within(field, s.indices.buffer_view, "bufferViews", views)?;
            let field = || format!("accessors[{i}].sparse.values.bufferView");
            within(field, s.values.buffer_view, "bufferViews", views)?;
        }
    }
    for (i, v) in root.buffer_views.iter().enumerate() {
        let len = root.buffers.len();
        within(
            || format!("bufferViews[{i}].buffer"),
            v.buffer,
            "buffers",
            len,
        )?;
    }
    for (i, image) in root.images.iter().enumerate() {
        match (image.buffer_view, &image.uri) {
            (Some(v), _) => {
                within(
                    || format!("images[{i}].bufferView"),
                    v,
                    "bufferViews",
                    views,
                )?;
                if image.mime_type.is_none() {
                    return Err(CheckError::ImageSource(format!(
                        "images[{i}] has a bufferView but no mimeType"
                    )));
                }
            }
            (None, Some(_)) => {}
            (None, None) => {
                return Err(CheckError::ImageSource(format!(
                    "images[{i}] has neither a uri nor a bufferView"
                )))
            }
        }
    }
    Ok(())
}

/// Each texture's image and sampler.
fn check_texture_indices(root: &Root) -> Result<(), CheckError> {
    for (i, t) in root.textures.iter().enumerate() {
        within(
            || format!("textures[{i}].source"),
            t.source,
            "images",
            root.images.len(),
        )?;
        if let Some(s) = t.sampler {
            let len = root.samplers.len();
            within(|| format!("textures[{i}].sampler"), s, "samplers", len)?;
        }
    }
    Ok(())
}

/// The textures each material refers to, core and the extensions the `gltf` crate parses.
fn check_material_texture_indices(root: &Root) -> Result<(), CheckError> {
    let textures = root.textures.len();
    for (i, m) in root.materials.iter().enumerate() {
        let pbr = &m.pbr_metallic_roughness;
        let mut uses = vec![
            (
                "pbrMetallicRoughness.baseColorTexture",
                pbr.base_color_texture.as_ref().map(|t| t.index),
            ),
            (
                "pbrMetallicRoughness.metallicRoughnessTexture",
                pbr.metallic_roughness_texture.as_ref().map(|t| t.index),
            ),
            ("normalTexture", m.normal_texture.as_ref().map(|t| t.index)),
            (
                "occlusionTexture",
                m.occlusion_texture.as_ref().map(|t| t.index),
            ),
            (
                "emissiveTexture",
                m.emissive_texture.as_ref().map(|t| t.index),
            ),
        ];
        if let Some(e) = &m.extensions {
            uses.push((
                "KHR_materials_transmission.transmissionTexture",
                e.transmission
                    .as_ref()
                    .and_then(|t| t.transmission_texture.as_ref().map(|t| t.index)),
            ));
            uses.push((
                "KHR_materials_volume.thicknessTexture",
                e.volume
                    .as_ref()
                    .and_then(|v| v.thickness_texture.as_ref().map(|t| t.index)),
            ));
            if let Some(s) = &e.specular {
                uses.push((
                    "KHR_materials_specular.specularTexture",
                    s.specular_texture.as_ref().map(|t| t.index),
                ));
                uses.push((
                    "KHR_materials_specular.specularColorTexture",
                    s.specular_color_texture.as_ref().map(|t| t.index),
                ));
            }
        }
        for (field, t) in uses {
            if let Some(t) = t {
                within(
                    || format!("materials[{i}].{field}"),
                    t,
                    "textures",
                    textures,
                )?;
            }
        }
    }
    Ok(())
}

/// Skins' joints, skeleton and inverse bind matrices; animations' sampler accessors and channels' samplers and
/// target nodes.
fn check_skin_and_animation_indices(root: &Root) -> Result<(), CheckError> {
    let (accessors, nodes) = (root.accessors.len(), root.nodes.len());
    for (i, skin) in root.skins.iter().enumerate() {
        for (j, &n) in skin.joints.iter().enumerate() {
            within(|| format!("skins[{i}].joints[{j}]"), n, "nodes", nodes)?;
        }
        if let Some(n) = skin.skeleton {
            within(|| format!("skins[{i}].skeleton"), n, "nodes", nodes)?;
        }
        if let Some(a) = skin.inverse_bind_matrices {
            let field = || format!("skins[{i}].inverseBindMatrices");
            within(field, a, "accessors", accessors)?;
        }
    }
    for (i, anim) in root.animations.iter().enumerate() {
        for (j, s) in anim.samplers.iter().enumerate() {
            within(
                || format!("animations[{i}].samplers[{j}].input"),
                s.input,
                "accessors",
                accessors,
            )?;
            within(
                || format!("animations[{i}].samplers[{j}].output"),
                s.output,
                "accessors",
                accessors,
            )?;
        }
        for (j, c) in anim.channels.iter().enumerate() {
            let len = anim.samplers.len();
            let field = || format!("animations[{i}].channels[{j}].sampler");
            within(field, c.sampler, &format!("animations[{i}].samplers"), len)?;
            let field = || format!("animations[{i}].channels[{j}].target.node");
            within(field, c.target.node, "nodes", nodes)?;
        }
    }
    Ok(())
}

/// The node graph must be a forest whose roots are the scenes' nodes: no node its own child, no cycle, no
/// node with two parents (or listed twice by one), no scene root that is also a child.
fn check_forest(root: &Root) -> Result<(), CheckError> {
    let n = root.nodes.len();
    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (i, node) in root.nodes.iter().enumerate() {
        for c in node.children.iter().flatten() {
            let c = c.value();
            if c == i {
                return Err(CheckError::NotAForest(format!(
                    "nodes[{i}] lists itself as a child"
                )));
            }
            match parent[c] {
                Some(p) if p == i => {
                    return Err(CheckError::NotAForest(format!(
                        "nodes[{i}] lists nodes[{c}] twice as a child"
                    )))
                }
                Some(p) => {
                    return Err(CheckError::NotAForest(format!(
                        "nodes[{c}] has two parents, nodes[{p}] and nodes[{i}]"
                    )))
                }
                None => parent[c] = Some(i),
            }
        }
    }
    // With one parent each, following parents from any node either reaches a root or loops.
    const UNSEEN: u8 = 0;
    const ON_PATH: u8 = 1;
    const REACHES_ROOT: u8 = 2;
    let mut state = vec![UNSEEN; n];
    for start in 0..n {
        let mut path = Vec::new();
        let mut at = start;
        loop {
            match state[at] {
                REACHES_ROOT => break,
                ON_PATH => {
                    let from = path.iter().position(|&p| p == at).unwrap_or(0);
                    let cycle: Vec<String> = path[from..]
                        .iter()
                        .rev()
                        .chain(std::iter::once(&at))
                        .map(|p| format!("nodes[{p}]"))
                        .collect();
                    return Err(CheckError::NotAForest(format!(
                        "the node hierarchy has a cycle: {}",
                        cycle.join(" -> ")
                    )));
                }
                _ => {}
            }
            state[at] = ON_PATH;
            path.push(at);
            match parent[at] {
                Some(p) => at = p,
                None => break,
            }
        }
        for p in path {
            state[p] = REACHES_ROOT;
        }
    }
    for (s, scene) in root.scenes.iter().enumerate() {
        let mut seen = vec![false; n];
        for r in &scene.nodes {
            let r = r.value();
            if let Some(p) = parent[r] {
                return Err(CheckError::NotAForest(format!(
                    "scenes[{s}] lists nodes[{r}] as a root, but it is a child of nodes[{p}]"
                )));
            }
            if std::mem::replace(&mut seen[r], true) {
                return Err(CheckError::NotAForest(format!(
                    "scenes[{s}] lists nodes[{r}] twice"
                )));
            }
        }
    }
    Ok(())
}

/// `Err` naming `field` if any of `values` is not finite.
fn finite(field: impl Fn() -> String, values: &[f32]) -> Result<(), CheckError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(k) if values.len() == 1 => Err(CheckError::NotFinite {
            field: field(),
            value: values[k],
        }),
        Some(k) => Err(CheckError::NotFinite {
            field: format!("{}[{k}]", field()),
            value: values[k],
        }),
    }
}

fn check_nodes(root: &Root) -> Result<(), CheckError> {
    for (i, node) in root.nodes.iter().enumerate() {
        if let Some(m) = &node.matrix {
            finite(|| format!("nodes[{i}].matrix"), m)?;
        }
        if let Some(t) = &node.translation {
            finite(|| format!("nodes[{i}].translation"), t)?;
        }
        if let Some(r) = &node.rotation {
            finite(|| format!("nodes[{i}].rotation"), &r.0)?;
        }
        if let Some(s) = &node.scale {
            finite(|| format!("nodes[{i}].scale"), s)?;
        }
        if let Some(w) = &node.weights {
            finite(|| format!("nodes[{i}].weights"), w)?;
        }
    }
    for (i, mesh) in root.meshes.iter().enumerate() {
        if let Some(w) = &mesh.weights {
            finite(|| format!("meshes[{i}].weights"), w)?;
        }
    }
    for (i, skin) in root.skins.iter().enumerate() {
        if skin.joints.is_empty() {
            return Err(CheckError::SkinWithoutJoints(i));
        }
    }
    Ok(())
}

fn check_cameras(root: &Root) -> Result<(), CheckError> {
    use gltf::json::camera::Type;
    for (i, camera) in root.cameras.iter().enumerate() {
        let bad = |field: &str, rule: &str, value: f32| {
            Err(CheckError::Camera(format!(
                "cameras[{i}].{field} is {value}; it must be {rule}"
            )))
        };
        match camera.type_ {
            Checked::Valid(Type::Perspective) => {
                let Some(p) = &camera.perspective else {
                    return Err(CheckError::Camera(format!(
                        "cameras[{i}] is of type perspective but has no 'perspective' object"
                    )));
                };
                if !(p.yfov > 0.0 && p.yfov < PI) {
                    return bad("perspective.yfov", "between 0 and pi radians", p.yfov);
                }
                if let Some(a) = p.aspect_ratio {
                    if !(a.is_finite() && a > 0.0) {
                        return bad("perspective.aspectRatio", "finite and > 0", a);
                    }
                }
                if !(p.znear.is_finite() && p.znear > 0.0) {
                    return bad("perspective.znear", "finite and > 0", p.znear);
                }
                if let Some(z) = p.zfar {
                    if !(z.is_finite() && z > p.znear) {
                        return bad("perspective.zfar", "finite and > znear", z);
                    }
                }
            }
            Checked::Valid(Type::Orthographic) => {
                let Some(o) = &camera.orthographic else {
                    return Err(CheckError::Camera(format!(
                        "cameras[{i}] is of type orthographic but has no 'orthographic' object"
                    )));
                };
                for (field, v) in [("orthographic.xmag", o.xmag), ("orthographic.ymag", o.ymag)] {
                    if !(v.is_finite() && v != 0.0) {
                        return bad(field, "finite and not 0", v);
                    }
                }
                if !(o.znear.is_finite() && o.znear >= 0.0) {
                    return bad("orthographic.znear", "finite and >= 0", o.znear);
                }
                if !(o.zfar.is_finite() && o.zfar > o.znear) {
                    return bad("orthographic.zfar", "finite and > znear", o.zfar);
                }
            }
            Checked::Invalid => {
                return Err(CheckError::Camera(format!(
                    "cameras[{i}].type must be \"perspective\" or \"orthographic\""
                )))
            }
        }
    }
    Ok(())
}

fn check_lights(root: &Root) -> Result<(), CheckError> {
    use gltf::json::extensions::scene::khr_lights_punctual::Type;
    let Some(lights) = root
        .extensions
        .as_ref()
        .and_then(|e| e.khr_lights_punctual.as_ref())
    else {
        return Ok(());
    };
    for (i, light) in lights.lights.iter().enumerate() {
        let at = format!("KHR_lights_punctual.lights[{i}]");
        if light.color.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
            return Err(CheckError::Light(format!(
                "{at}.color is {:?}; it must be three finite numbers >= 0",
                light.color
            )));
        }
        if !(light.intensity.is_finite() && light.intensity >= 0.0) {
            return Err(CheckError::Light(format!(
                "{at}.intensity is {}; it must be finite and >= 0",
                light.intensity
            )));
        }
        if let Some(r) = light.range {
            if !(r.is_finite() && r > 0.0) {
                return Err(CheckError::Light(format!(
                    "{at}.range is {r}; it must be finite and > 0"
                )));
            }
        }
        match light.type_ {
            Checked::Valid(Type::Spot) => {
                let Some(spot) = &light.spot else {
                    return Err(CheckError::Light(format!(
                        "{at} is of type spot but has no 'spot' object"
                    )));
                };
                let (inner, outer) = (spot.inner_cone_angle, spot.outer_cone_angle);
                if !(outer > 0.0 && outer <= FRAC_PI_2) {
                    return Err(CheckError::Light(format!(
                        "{at}.spot.outerConeAngle is {outer}; it must be in (0, pi/2]"
                    )));
                }
                if !(inner >= 0.0 && inner <= outer) {
                    return Err(CheckError::Light(format!(
                        "{at}.spot.innerConeAngle is {inner}; it must be >= 0 and <= outerConeAngle {outer}"
                    )));
                }
            }
            Checked::Valid(_) => {}
            Checked::Invalid => {
                return Err(CheckError::Light(format!(
                    "{at}.type must be \"directional\", \"point\" or \"spot\""
                )))
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_channel_paths_are_removed_and_kept_channels_keep_their_file_index() {
        let json = br#"{"animations": [{"channels": [
            {"sampler": 0, "target": {"path": "pointer"}},
            {"sampler": 0, "target": {"node": 0, "path": "translation"}},
            {"sampler": 0, "target": {"node": 0, "path": "pointer"}},
            {"sampler": 0, "target": {"node": 0, "path": "scale"}}]}]}"#;
        let (document, skipped) = skip_unknown_channels(json).unwrap();
        let channels = document.unwrap()["animations"][0]["channels"].clone();
        assert_eq!(channels.as_array().unwrap().len(), 2);
        assert_eq!(skipped.removed, [vec![0, 2]]);
        assert_eq!(skipped.warnings.len(), 2);
        assert_eq!(skipped.file_index(0, 0), 1);
        assert_eq!(skipped.file_index(0, 1), 3);
        assert_eq!(skipped.file_index(1, 0), 0);
        let (document, skipped) = skip_unknown_channels(b"{\"asset\": {}}").unwrap();
        assert!(document.is_none() && skipped.warnings.is_empty());
    }

    #[test]
    fn an_unknown_channel_in_a_document_that_cannot_be_read_whole_is_an_error() {
        // The sampler's unknown field holds invalid UTF-8, which the crate's parser skips unread.
        let mut json = br#"{"animations": [{"samplers": [{"x": "AB"}], "channels": [
            {"sampler": 0, "target": {"node": 0, "path": "rotatkon"}}]}]}"#
            .to_vec();
        let at = json.windows(2).position(|w| w == b"AB").unwrap();
        json[at] = 0x8a;
        let error = skip_unknown_channels(&json).unwrap_err().to_string();
        assert!(
            error.starts_with("animations[0].channels[0]: target path \"rotatkon\"")
                && error.contains("invalid unicode"),
            "{error}"
        );
    }
}
