//! What the compositing outputs know of a surface, a light or a medium beyond its geometry: the light group its
//! emission goes to, and whether it is a holdout or a shadow catcher. Loaders fill these from the scene file
//! (glTF `extras`, USD `nimbus:` attributes); the renderer reads them through the scene's tables
//! (`crate::scene::SceneNames`).
//!
//! | glTF extras key (node, material) | USD attribute | meaning |
//! |---|---|---|
//! | `nimbus_light_group` (string) | `nimbus:lightGroup` | the light group that the emission of this node's meshes, light or volume (or of surfaces with this material) goes to: the EXR layer `lg_<name>` |
//! | `nimbus_holdout` (bool) | `nimbus:holdout` | invisible to camera rays and cuts the alpha (a matte for a live-action element); still occludes what is behind it and is seen by other rays |
//! | `nimbus_shadow_catcher` (bool) | `nimbus:shadowCatcher` | invisible to camera rays, but records the shadows the scene casts on it in the `shadow_catcher` layer |
//!
//! A node's keys apply to its children too, unless a child sets its own; a material's keys apply to every
//! surface that uses it.

/// The compositing tags of a mesh, a material or a medium.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CompositingTags {
    /// The light group of its emission, when declared.
    pub light_group: Option<String>,
    /// A holdout: invisible to camera rays, where it cuts the alpha.
    pub holdout: bool,
    /// A shadow catcher: invisible to camera rays, which record the shadows falling on it.
    pub shadow_catcher: bool,
}

impl CompositingTags {
    /// These tags, with each key unset here taken from `outer` (a parent node's, or the material's).
    pub fn or(&self, outer: &CompositingTags) -> CompositingTags {
        CompositingTags {
            light_group: self
                .light_group
                .clone()
                .or_else(|| outer.light_group.clone()),
            holdout: self.holdout || outer.holdout,
            shadow_catcher: self.shadow_catcher || outer.shadow_catcher,
        }
    }

    /// True when nothing is set.
    pub fn is_empty(&self) -> bool {
        *self == CompositingTags::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inner_keys_win_and_flags_accumulate() {
        let outer = CompositingTags {
            light_group: Some("key".into()),
            holdout: true,
            shadow_catcher: false,
        };
        let inner = CompositingTags {
            light_group: Some("fill".into()),
            shadow_catcher: true,
            ..Default::default()
        };
        let both = inner.or(&outer);
        assert_eq!(both.light_group.as_deref(), Some("fill"));
        assert!(both.holdout && both.shadow_catcher);
        assert_eq!(
            CompositingTags::default().or(&outer).light_group.as_deref(),
            Some("key")
        );
        assert!(CompositingTags::default().is_empty() && !outer.is_empty());
    }
}
