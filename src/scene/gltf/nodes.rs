//! The default scene's node hierarchy: each node's world matrix (its pose's local matrix under its parent's,
//! refused past `MAX_NODE_DEPTH` levels or when not finite), its `extras` (the `nimbus_*` keys in
//! [`NODE_EXTRAS`]: `nimbus_volume`, `nimbus_camera`, `nimbus_light_group`, `nimbus_holdout`,
//! `nimbus_shadow_catcher`; others warned about), and what it carries: `mesh` (copied or instanced, see
//! `instancing`), `camera`, `extensions.KHR_lights_punctual.light` and an `extras.nimbus_volume`. A node's
//! compositing tags pass to its children; the top-level node names Cryptomatte's asset.

use super::extras::node_tags;
use super::{Loader, MAX_NODE_DEPTH, QUOTE};
use crate::geometry::CompositingTags;
use crate::limits::one_line;
use crate::math::Mat4;
use crate::params::unknown_json_names;
use crate::scene::MalformedPart;
use crate::scene::{LightTag, SceneError, SceneErrorKind};

impl Loader<'_> {
    /// Loads `node` and its subtree under the `parent` world matrix at `depth`, with the compositing tags and
    /// asset its ancestors pass down (`outer`).
    pub(super) fn visit(
        &mut self,
        node: gltf::Node,
        parent: Mat4,
        depth: usize,
        outer: &NodeContext,
    ) -> Result<(), SceneError> {
        if depth > MAX_NODE_DEPTH {
            return Err(self.error(SceneErrorKind::malformed(
                MalformedPart::Node,
                format!(
                    "node {} is nested deeper than {MAX_NODE_DEPTH} levels (a cycle?)",
                    node.index()
                ),
            )));
        }
        let world = parent * self.pose.locals[node.index()];
        if !world.is_finite() {
            return Err(self.error(SceneErrorKind::malformed(
                MalformedPart::Node,
                format!("node {} has a non-finite transform", node.index()),
            )));
        }
        let extras = self.node_extras(&node)?;
        if let Some(extras) = &extras {
            let at = format!("node '{}': extras", one_line(&node_name(&node), QUOTE));
            self.unknown_keys(&at, &unknown_json_names(extras, NODE_EXTRAS, "nimbus_"))?;
        }
        let context = NodeContext {
            tags: node_tags(extras.as_ref())
                .map_err(|m| {
                    self.error(SceneErrorKind::malformed(
                        MalformedPart::Node,
                        format!("node '{}': extras: {m}", node_name(&node)),
                    ))
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

    /// A node's `extras` as JSON, if it has any.
    fn node_extras(&self, node: &gltf::Node) -> Result<Option<serde_json::Value>, SceneError> {
        let Some(raw) = node.extras() else {
            return Ok(None);
        };
        serde_json::from_str(raw.get()).map(Some).map_err(|e| {
            self.error(SceneErrorKind::malformed(
                MalformedPart::Node,
                format!("node '{}': extras: {e}", node_name(node)),
            ))
        })
    }
}

/// The `nimbus_*` keys a node's `extras` may hold.
const NODE_EXTRAS: &[&str] = &[
    "nimbus_volume",
    "nimbus_camera",
    "nimbus_light_group",
    "nimbus_holdout",
    "nimbus_shadow_catcher",
];

/// What a node passes to its children: its compositing tags (its own over its parents') and the name of the
/// top-level node above it, Cryptomatte's asset.
pub(super) struct NodeContext {
    /// The node's compositing tags over its parents'.
    pub(super) tags: CompositingTags,
    /// The name of the top-level node above it (Cryptomatte's asset).
    pub(super) asset: String,
}

/// A node's name for messages, Cryptomatte and per-light groups: its own, else its mesh's (as Blender's importer
/// names an unnamed node), else `node <index>`.
pub(super) fn node_name(node: &gltf::Node) -> String {
    node.name()
        .or_else(|| node.mesh().and_then(|m| m.name()))
        .map_or_else(|| format!("node {}", node.index()), str::to_owned)
}
