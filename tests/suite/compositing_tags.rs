//! The compositing tags as the loaders read them: glTF node and material `extras` (`nimbus_light_group`,
//! `nimbus_holdout`, `nimbus_shadow_catcher`; inherited by child nodes), `nimbus_environment.light_group`,
//! scene `extras.nimbus_transparent`, and USD's `nimbus:lightGroup`, `nimbus:holdout`, `nimbus:shadowCatcher`
//! (inherited by child prims) with Cryptomatte's asset (the `component` model); wrong types are errors naming
//! the node.

use crate::common;
use nimbus::render::{LightGroupMode, LightGroups};
use nimbus::Scene;
use std::path::PathBuf;

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nimbus-tags-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// A glTF with one triangle mesh used by several nodes, an emissive material, a point light and an
/// environment; `extras` as given.
fn gltf(rig_extras: &str, lamp_material_extras: &str, scene_extras: &str) -> String {
    // One triangle: 3 positions (36 bytes) and 3 u16 indices (6 bytes, padded to 8).
    let mut bytes: Vec<u8> = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bytes.extend([0u8, 0, 1, 0, 2, 0, 0, 0]);
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        common::base64(&bytes)
    );
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0,
  "extensionsUsed": ["KHR_lights_punctual"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [{{"name": "key light", "type": "point", "intensity": 10}}]}}}},
  "scenes": [{{"nodes": [0, 3, 4], "extras": {scene_extras}}}],
  "nodes": [
    {{"name": "Rig", "children": [1, 2], "extras": {rig_extras}}},
    {{"name": "Crate", "mesh": 0, "extras": {{"nimbus_holdout": true}}}},
    {{"name": "Lamp", "mesh": 1}},
    {{"name": "Floor", "mesh": 0, "extras": {{"nimbus_shadow_catcher": true}}}},
    {{"name": "Bulb", "translation": [0, 2, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}
  ],
  "meshes": [
    {{"name": "tri", "primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}},
    {{"name": "lamp", "primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 1}}]}}
  ],
  "materials": [
    {{"name": "grey"}},
    {{"name": "glow", "emissiveFactor": [1, 1, 1], "extras": {lamp_material_extras}}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}}
  ],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}],
  "buffers": [{{"byteLength": 44, "uri": "{uri}"}}]
}}"#
    )
}

#[test]
fn gltf_extras_give_groups_mattes_assets_and_a_transparent_film() {
    let path = temp_file(
        "tags.gltf",
        &gltf(
            r#"{"nimbus_light_group": "practicals"}"#,
            r#"{"nimbus_light_group": "overridden by the node"}"#,
            r#"{"nimbus_transparent": true, "nimbus_environment": {"color": [0.1, 0.2, 0.3], "light_group": "sky"}}"#,
        ),
    );
    let scene = Scene::load(&path).unwrap();
    assert!(scene.transparent());
    let names = scene.names();
    let emitters: Vec<(&str, Option<&str>)> = names
        .emitters
        .iter()
        .map(|e| (e.name.as_str(), e.light_group.as_deref()))
        .collect();
    // The lamp mesh inherits its parent's group (a node's own tags win over its material's); the light has
    // none; the environment is in "sky".
    assert_eq!(
        emitters,
        [
            ("Lamp", Some("practicals")),
            ("key light", None),
            ("environment", Some("sky"))
        ]
    );
    let groups = LightGroups::new(&scene, LightGroupMode::Scene).unwrap();
    assert_eq!(groups.names, ["lg_practicals", "lg_default", "lg_sky"]);
    let per_light = LightGroups::new(&scene, LightGroupMode::PerLight).unwrap();
    assert_eq!(
        per_light.names,
        ["lg_Lamp", "lg_key_light", "lg_environment"]
    );
    // Crate (holdout), Lamp, Floor (catcher); assets are the top-level nodes. Crate and Floor draw one mesh, so
    // they are instances, numbered after the meshes (the emitting Lamp is copied to world space).
    let mut items: Vec<(&str, &str, &str)> = names
        .items
        .iter()
        .map(|i| (i.object.as_str(), i.material.as_str(), i.asset.as_str()))
        .collect();
    items.sort();
    assert_eq!(
        items,
        [
            ("Crate", "grey", "Rig"),
            ("Floor", "grey", "Floor"),
            ("Lamp", "glow", "Rig")
        ]
    );
    let object = |name: &str| names.items.iter().position(|i| i.object == name).unwrap();
    let (crate_, lamp, floor) = (object("Crate"), object("Lamp"), object("Floor"));
    assert!(names.mesh_is_holdout(crate_) && !names.mesh_is_holdout(lamp));
    assert!(names.mesh_is_shadow_catcher(floor) && !names.mesh_is_shadow_catcher(crate_));
    // Wrong types are errors naming the node.
    for (rig, want) in [
        (r#"{"nimbus_holdout": "yes"}"#, "Rig"),
        (r#"{"nimbus_light_group": 3}"#, "nimbus_light_group"),
        (r#"{"nimbus_light_group": ""}"#, "nimbus_light_group"),
    ] {
        let path = temp_file("bad.gltf", &gltf(rig, "{}", "{}"));
        let err = Scene::load(&path).err().expect("refused").to_string();
        assert!(err.contains(want), "{err}");
    }
}

#[test]
fn usd_attributes_give_groups_mattes_and_component_assets() {
    let stage = r#"#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
)

def Xform "World"
{
    def Xform "Set" (
        kind = "component"
    )
    {
        custom string nimbus:lightGroup = "practicals"

        def Mesh "Lamp"
        {
            int[] faceVertexCounts = [3]
            int[] faceVertexIndices = [0, 1, 2]
            point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        }

        def SphereLight "Bulb"
        {
            float inputs:intensity = 5
            float inputs:radius = 0.1
            bool treatAsPoint = true
        }
    }

    def Mesh "Matte"
    {
        custom bool nimbus:holdout = true
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 1), (1, 0, 1), (0, 1, 1)]
    }

    def Mesh "Ground"
    {
        custom bool nimbus:shadowCatcher = true
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 2), (1, 0, 2), (0, 1, 2)]
    }

    def DomeLight "Sky"
    {
        custom string nimbus:lightGroup = "sky"
        float inputs:intensity = 1
    }
}
"#;
    let path = temp_file("tags.usda", stage);
    let scene = Scene::load(&path).unwrap();
    let names = scene.names();
    let emitters: Vec<(&str, Option<&str>)> = names
        .emitters
        .iter()
        .map(|e| (e.name.as_str(), e.light_group.as_deref()))
        .collect();
    assert_eq!(
        emitters,
        [
            ("/World/Set/Bulb", Some("practicals")),
            ("environment", Some("sky"))
        ]
    );
    let items: Vec<(&str, &str)> = names
        .items
        .iter()
        .map(|i| (i.object.as_str(), i.asset.as_str()))
        .collect();
    assert_eq!(
        items,
        [
            ("/World/Set/Lamp", "/World/Set"),
            ("/World/Matte", "/World"),
            ("/World/Ground", "/World")
        ]
    );
    assert!(names.mesh_is_holdout(1) && names.mesh_is_shadow_catcher(2));
    assert!(!names.mesh_is_holdout(0) && !names.mesh_is_shadow_catcher(0));
    let bad = stage.replace(
        "custom bool nimbus:holdout = true",
        "custom float nimbus:holdout = 2",
    );
    let err = Scene::load(&temp_file("bad.usda", &bad))
        .err()
        .expect("refused")
        .to_string();
    assert!(err.contains("nimbus:holdout"), "{err}");
}
