//! Lightmaps for glTF scenes baked by the `bake` command.
//!
//! The baked glTF carries `TEXCOORD_1` (Bevy's `UV_1`) on every baked primitive and, on each
//! baked node, `extras.lightbake.lightmaps = [{ primitive, page, image, uv_rect }]`, with
//! `image` relative to the glTF file. Bevy puts node extras on the node entity as
//! `GltfExtras` and spawns one child entity per primitive, whose `Mesh3d` handle is labelled
//! `MeshM/PrimitiveP`. So each new mesh entity without a lightmap is looked up once: its
//! parent's extras, its primitive index, and the page image (loaded through the
//! `AssetServer`, so the file watcher reloads it when the `bake` command rewrites it).
//!
//! Baked lights carry `extras.lightbake.baked = true`; Bevy puts light extras on the light
//! entity, and the plugin turns off their diffuse light on lightmapped meshes.

use bevy::gltf::GltfExtras;
use bevy::prelude::*;
use serde_json::Value;

use crate::components::{BakedLight, Lightmapped};

/// A mesh entity already looked up (with or without a lightmap).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct LightmapLookedUp;

/// One entry of a node's `extras.lightbake.lightmaps`.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeLightmapEntry {
    /// Primitive index within the node's mesh.
    pub primitive: usize,
    /// Page image path, relative to the glTF file.
    pub image: String,
    /// `[min u, min v, max u, max v]`.
    pub uv_rect: Rect,
}

/// Parses a node's extras JSON. Entries that are malformed are skipped; `None` when the node
/// has no lightmaps.
pub fn parse_node_lightmaps(extras: &str) -> Option<Vec<NodeLightmapEntry>> {
    let json: Value = serde_json::from_str(extras).ok()?;
    let list = json.pointer("/lightbake/lightmaps")?.as_array()?;
    Some(
        list.iter()
            .filter_map(|e| {
                let r = e["uv_rect"].as_array()?;
                let f = |k: usize| r.get(k).and_then(Value::as_f64).map(|v| v as f32);
                Some(NodeLightmapEntry {
                    primitive: e["primitive"].as_u64()? as usize,
                    image: e["image"].as_str()?.to_string(),
                    uv_rect: Rect::new(f(0)?, f(1)?, f(2)?, f(3)?),
                })
            })
            .collect(),
    )
}

/// The primitive index in a glTF mesh label `MeshM/PrimitiveP`.
pub fn primitive_of_label(label: &str) -> Option<usize> {
    label.split_once("/Primitive")?.1.parse().ok()
}

/// Whether a light's extras say it was baked.
pub fn is_baked_light(extras: &str) -> bool {
    serde_json::from_str::<Value>(extras)
        .ok()
        .and_then(|v| v.pointer("/lightbake/baked").and_then(Value::as_bool))
        .unwrap_or(false)
}

/// Gives every mesh entity of a baked glTF its [`Lightmapped`] from its node's extras.
pub(crate) fn attach_gltf_lightmaps(
    mut commands: Commands,
    server: Res<AssetServer>,
    meshes: Res<Assets<Mesh>>,
    candidates: Query<
        (Entity, &Mesh3d, Option<&ChildOf>),
        (Without<Lightmapped>, Without<LightmapLookedUp>),
    >,
    extras: Query<&GltfExtras>,
) {
    for (entity, mesh3d, parent) in &candidates {
        let done = |commands: &mut Commands| {
            commands.entity(entity).insert(LightmapLookedUp);
        };
        let Some(path) = server.get_path(mesh3d.id()) else {
            done(&mut commands); // not from a file
            continue;
        };
        let Some(primitive) = path.label().and_then(primitive_of_label) else {
            done(&mut commands);
            continue;
        };
        let Some(entry) = parent
            .and_then(|p| extras.get(p.parent()).ok())
            .and_then(|x| parse_node_lightmaps(&x.value))
            .and_then(|list| list.into_iter().find(|e| e.primitive == primitive))
        else {
            done(&mut commands);
            continue;
        };
        let Some(mesh) = meshes.get(mesh3d.id()) else {
            continue; // not loaded yet: look again next frame
        };
        done(&mut commands);
        if !mesh.contains_attribute(Mesh::ATTRIBUTE_UV_1) {
            warn!("lightbake: {path} has a lightmap but no UV_1; it is left unlit by the bake");
            continue;
        }
        let image_path = match path.without_label().resolve_embed_str(&entry.image) {
            Ok(p) => p,
            Err(e) => {
                warn!(
                    "lightbake: {path}: bad lightmap path {:?}: {e}",
                    entry.image
                );
                continue;
            }
        };
        commands.entity(entity).insert(Lightmapped {
            image: server.load(image_path),
            uv_rect: entry.uv_rect,
        });
    }
}

/// Turns off the diffuse light of baked glTF lights on lightmapped meshes.
pub(crate) fn mark_baked_gltf_lights(
    mut commands: Commands,
    mut lights: Query<
        (
            Entity,
            &GltfExtras,
            Option<&mut PointLight>,
            Option<&mut SpotLight>,
            Option<&mut DirectionalLight>,
        ),
        (Added<GltfExtras>, Without<BakedLight>),
    >,
) {
    for (entity, extras, point, spot, sun) in &mut lights {
        if (point.is_none() && spot.is_none() && sun.is_none()) || !is_baked_light(&extras.value) {
            continue;
        }
        if let Some(mut l) = point {
            l.affects_lightmapped_mesh_diffuse = false;
        }
        if let Some(mut l) = spot {
            l.affects_lightmapped_mesh_diffuse = false;
        }
        if let Some(mut l) = sun {
            l.affects_lightmapped_mesh_diffuse = false;
        }
        commands.entity(entity).insert(BakedLight);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extras_and_labels_parse() {
        let x = r#"{"other": 1, "lightbake": {"lightmaps": [
            {"primitive": 1, "page": 0, "image": "lightmaps/lightmap_0.exr", "uv_rect": [0.0, 0.5, 0.25, 1.0]},
            {"primitive": "bad"}
        ]}}"#;
        let list = parse_node_lightmaps(x).unwrap();
        assert_eq!(
            list,
            vec![NodeLightmapEntry {
                primitive: 1,
                image: "lightmaps/lightmap_0.exr".into(),
                uv_rect: Rect::new(0.0, 0.5, 0.25, 1.0),
            }]
        );
        assert_eq!(parse_node_lightmaps(r#"{"a": 1}"#), None);
        assert_eq!(parse_node_lightmaps("not json"), None);
        assert_eq!(primitive_of_label("Mesh3/Primitive12"), Some(12));
        assert_eq!(primitive_of_label("Material0"), None);
        assert!(is_baked_light(r#"{"lightbake": {"baked": true}}"#));
        assert!(!is_baked_light(r#"{"lightbake": {}}"#));
    }
}
