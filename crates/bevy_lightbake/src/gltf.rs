//! Lightmaps for glTF scenes baked by the `bake` command.
//!
//! The baked glTF carries `TEXCOORD_1` (Bevy's `UV_1`) on every baked primitive and, on each
//! baked node, `extras.lightbake.lightmaps = [{ primitive, page, image, uv_rect }]`, with
//! `image` relative to the glTF file. Bevy puts node extras on the node entity as
//! `GltfExtras` and spawns one child entity per primitive, whose `Mesh3d` handle is labelled
//! `MeshM/PrimitiveP`. So each new mesh entity without a lightmap is looked up once: its
//! parent's extras, its primitive index, and the page image (loaded through the
//! `AssetServer`, so the file watcher reloads it when the `bake` command rewrites it). Where
//! the bake also wrote the page as BC6H (`image_bc6h`), that one is loaded instead when
//! [`loads_bc6h`].
//!
//! Baked lights carry `extras.lightbake.baked = true`; Bevy puts light extras on the light
//! entity, and the plugin turns off their diffuse light on lightmapped meshes.

use bevy::gltf::GltfExtras;
use bevy::prelude::*;
use bevy::render::renderer::RenderDevice;
use lightbake::scene::extras::{self, LightExtras, NodeExtras, NodeLightmap};

use crate::LightbakeSystems;
use crate::components::{BakedLight, LightbakeConfig, Lightmapped};
use crate::groups::GltfPage;
use crate::images::loads_bc6h;

/// glTF scenes: the lightmaps and baked lights a baked glTF names, found when its scene
/// spawns ([`LightbakeSystems::Gltf`]).
pub struct GltfScenesPlugin;

impl Plugin for GltfScenesPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(
            Update,
            (attach_gltf_lightmaps, mark_baked_gltf_lights).in_set(LightbakeSystems::Gltf),
        );
    }
}

/// A mesh entity already looked up (with or without a lightmap).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct LightmapLookedUp;

/// A node's lightmaps from its extras JSON (`extras.lightbake.lightmaps`, the core's
/// [`NodeExtras`] schema); malformed entries are skipped, and `None` when the node has none.
pub fn parse_node_lightmaps(extras: &str) -> Option<Vec<NodeLightmap>> {
    let lb: NodeExtras = extras::read(Some(extras), "node", &mut Vec::new());
    (!lb.lightmaps.is_empty()).then_some(lb.lightmaps)
}

/// The primitive index in a glTF mesh label `MeshM/PrimitiveP`.
pub fn primitive_of_label(label: &str) -> Option<usize> {
    label.split_once("/Primitive")?.1.parse().ok()
}

/// Whether a light's extras say it was baked (the core's [`LightExtras`] schema).
pub fn is_baked_light(extras: &str) -> bool {
    extras::read::<LightExtras>(Some(extras), "light", &mut Vec::new()).baked
}

/// Gives every mesh entity of a baked glTF its [`Lightmapped`] from its node's extras (its
/// BC6H page where [`loads_bc6h`]).
pub(crate) fn attach_gltf_lightmaps(
    mut commands: Commands,
    server: Res<AssetServer>,
    config: Res<LightbakeConfig>,
    device: Option<Res<RenderDevice>>,
    meshes: Res<Assets<Mesh>>,
    candidates: Query<
        (Entity, &Mesh3d, Option<&ChildOf>),
        (Without<Lightmapped>, Without<LightmapLookedUp>),
    >,
    extras: Query<&GltfExtras>,
) {
    let bc6h = loads_bc6h(&config, device.as_deref());
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
        let image = match &entry.image_bc6h {
            Some(compressed) if bc6h => compressed,
            _ => &entry.image,
        };
        let image_path = match path.without_label().resolve_embed_str(image) {
            Ok(p) => p,
            Err(e) => {
                warn!("lightbake: {path}: bad lightmap path {image:?}: {e}");
                continue;
            }
        };
        let [u0, v0, u1, v1] = entry.uv_rect;
        commands.entity(entity).insert((
            Lightmapped {
                image: server.load(image_path),
                uv_rect: Rect::new(u0, v0, u1, v1),
            },
            GltfPage {
                gltf: path.without_label().into_owned(),
                page: entry.page,
            },
        ));
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
            vec![NodeLightmap {
                primitive: 1,
                page: 0,
                image: "lightmaps/lightmap_0.exr".into(),
                image_bc6h: None,
                uv_rect: [0.0, 0.5, 0.25, 1.0],
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
