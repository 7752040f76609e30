//! Lightmaps applied to the world: meshes get the unwrap's `UV_1`, baked mesh entities get
//! their pages as Bevy's `Lightmap`, baked lights stop lighting lightmapped meshes, and the
//! `Lightmap` components are kept in step with their images ([`LightbakeSystems::Lightmaps`]).
//!
//! Bevy 0.20's `StandardMaterial` shader does not compile for a mesh that has `UV_1` but no
//! `UV_0` (it reads `uv`, which it declares only with `UV_0`), and such a mesh is not drawn.
//! So every mesh that has `UV_1` and no `UV_0` is given a `UV_0`, a copy of its `UV_1`
//! ([`give_uv0`]): an in-app bake's meshes when they get their `UV_1`, and any other mesh
//! (a baked glTF's, loaded from a file written before the `bake` command wrote `TEXCOORD_0`
//! itself, or a mesh of the game's) in `Update` after it is added or changed, before its
//! entities are first drawn.

use std::collections::{HashMap, HashSet};

use bevy::asset::AssetId;
use bevy::diagnostic::FrameCount;
use bevy::light::GlobalAmbientLight;
use bevy::mesh::{Indices, MeshAccessError, VertexAttributeValues};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use lightbake::{Layout, MeshUnwrap, UvOrigin};

use crate::LightbakeSystems;
use crate::components::{BakedLight, LightbakeConfig, Lightmapped, ShowLightmaps};
use crate::convert::SceneMapping;
use crate::images::{is_ready, narrow_to_half, page_image};

/// Applying lightmaps: prepares page images and keeps `Lightmap` components in step
/// (`PostUpdate`, [`LightbakeSystems::Lightmaps`]).
pub struct LightmapsPlugin;

impl Plugin for LightmapsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<ShowLightmaps>()
            .init_resource::<MemoryPages>()
            .init_resource::<ResizedImages>()
            .add_systems(
                PostUpdate,
                (prepare_lightmap_images, sync_lightmaps)
                    .chain()
                    .in_set(LightbakeSystems::Lightmaps),
            )
            .add_systems(Update, give_meshes_uv0.in_set(LightbakeSystems::Gltf));
    }
}

/// Gives `mesh` a `UV_0` when it has `UV_1` and none, so Bevy's `StandardMaterial` shader
/// compiles for it (see the module docs): a copy of `UV_1` when that is plain `Float32x2`,
/// else zeros (a compressed `UV_1` cannot be copied without its range). A texture sampled by
/// `UV_0` needs a `UV_0` of its own, so nothing a textured mesh shows changes. Returns whether
/// it added one.
///
/// # Errors
/// When the mesh's data is only on the GPU.
pub fn give_uv0(mesh: &mut Mesh) -> Result<bool, MeshAccessError> {
    if mesh.try_contains_attribute(Mesh::ATTRIBUTE_UV_0)?
        || !mesh.try_contains_attribute(Mesh::ATTRIBUTE_UV_1)?
    {
        return Ok(false);
    }
    let uv0 = match mesh.try_attribute(Mesh::ATTRIBUTE_UV_1)? {
        VertexAttributeValues::Float32x2(uv) => uv.clone(),
        other => vec![[0.0, 0.0]; other.len()],
    };
    mesh.try_insert_attribute(Mesh::ATTRIBUTE_UV_0, uv0)?;
    Ok(true)
}

/// Gives every mesh added or changed since the last frame that has `UV_1` and no `UV_0` a
/// `UV_0` ([`give_uv0`]). Runs in `Update`: a glTF's meshes are loaded a frame or more before
/// its scene spawns, so its entities are drawn with the `UV_0` from their first frame.
pub(crate) fn give_meshes_uv0(
    mut events: MessageReader<AssetEvent<Mesh>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut warned: Local<HashSet<AssetId<Mesh>>>,
) {
    let ids: HashSet<AssetId<Mesh>> = (events.read())
        .filter_map(|event| match event {
            AssetEvent::Added { id }
            | AssetEvent::Modified { id }
            | AssetEvent::LoadedWithDependencies { id } => Some(*id),
            _ => None,
        })
        .collect();
    for id in ids {
        let wants = meshes.get(id).is_some_and(|m| {
            m.try_contains_attribute(Mesh::ATTRIBUTE_UV_1)
                .unwrap_or(false)
                && !m
                    .try_contains_attribute(Mesh::ATTRIBUTE_UV_0)
                    .unwrap_or(true)
        });
        if !wants {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(id) else {
            continue;
        };
        match give_uv0(&mut mesh) {
            Ok(_) => debug!("lightbake: mesh {id} has UV_1 and no UV_0; UV_0 added"),
            Err(e) if warned.insert(id) => warn!(
                "lightbake: mesh {id} has UV_1 and no UV_0, and Bevy's StandardMaterial cannot draw it; adding UV_0 failed ({e})"
            ),
            Err(_) => {}
        }
    }
}

/// In-memory page images of earlier bakes, reused so a re-bake of the same size updates the
/// GPU texture in place.
#[derive(Resource, Default)]
pub(crate) struct MemoryPages(Vec<Handle<Image>>);

/// Images whose size or format changed this frame (their `Lightmap`s must be re-inserted).
#[derive(Resource, Default)]
pub(crate) struct ResizedImages(HashSet<AssetId<Image>>);

/// A `Lightmap` removed to be re-inserted: not before this frame.
#[derive(Component, Clone, Copy, Debug)]
pub(crate) struct ReinsertAfter(u32);

/// `original` with the unwrap's vertex split applied to every attribute, its triangle list
/// replaced and `UV_1` set (and `UV_0`, a copy of it, when it had none: [`give_uv0`]).
///
/// # Errors
/// When the mesh's data is only on the GPU.
pub fn apply_unwrap(original: &Mesh, unwrap: &MeshUnwrap) -> Result<Mesh, MeshAccessError> {
    let mut mesh = original.clone();
    if let Some(xref) = &unwrap.xref {
        // New vertex k is old vertex xref[k]: Bevy's own "duplicate by index list" gathers
        // every attribute (tangents, colours, joints, ...) that way.
        mesh.try_insert_indices(Indices::U32(xref.clone()))?;
        mesh.try_duplicate_vertices()?;
    }
    let uv1: Vec<[f32; 2]> = unwrap.uv1.iter().map(|v| v.to_array()).collect();
    mesh.try_insert_attribute(Mesh::ATTRIBUTE_UV_1, uv1)?;
    mesh.try_insert_indices(Indices::U32(unwrap.indices.clone()))?;
    give_uv0(&mut mesh)?;
    Ok(mesh)
}

/// Meshes get the unwrap's `UV_1` (and vertex split), in place or as a new asset; returns the
/// new assets by core mesh.
pub(crate) fn apply_meshes(
    world: &mut World,
    layout: &Layout,
    mapping: &SceneMapping,
) -> HashMap<usize, Handle<Mesh>> {
    let mut new_handles: HashMap<usize, Handle<Mesh>> = HashMap::new();
    for (m, source) in mapping.meshes.iter().enumerate() {
        let Some(unwrap) = &layout.meshes[m] else {
            continue;
        };
        if unwrap.origin == UvOrigin::Existing && unwrap.xref.is_none() {
            continue; // it already has these UVs (and so do its other users)
        }
        let mesh = match apply_unwrap(&source.original, unwrap) {
            Ok(mesh) => mesh,
            Err(e) => {
                warn!("lightbake: cannot add UV_1 to a baked mesh ({e}); it gets no lightmap");
                continue;
            }
        };
        let summary = crate::rebake::written_summary(&mesh);
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        // An asset that already holds these UVs (a rebake of an unchanged mesh) is left as
        // it is: Bevy uploads and specializes nothing again.
        let holds = |meshes: &Assets<Mesh>| {
            (meshes.get(source.handle.id()))
                .is_some_and(|c| crate::rebake::written_summary(c) == summary)
        };
        if !source.needs_own_asset && holds(&meshes) {
            continue;
        }
        let id = if source.needs_own_asset {
            let handle = meshes.add(mesh);
            let id = handle.id();
            new_handles.insert(m, handle);
            id
        } else if meshes.insert(source.handle.id(), mesh).is_err() {
            warn!("lightbake: a baked mesh asset was removed during the bake");
            continue;
        } else {
            source.handle.id()
        };
        if let Some(mut u) = world.get_resource_mut::<crate::rebake::UnwrappedMeshes>() {
            u.insert(id, source.original.clone(), summary);
        }
    }

    new_handles
}

/// The page images of the files just written, by asset path, holding `pages` at once: the
/// asset of each path (loaded now if it was not) gets the new texels in memory, so the entities
/// never show a file's previous content while the file is read again; the asset stays tied
/// to its file, so a later rewrite by the `bake` command reloads it.
///
/// `reread`: the files hold another encoding of the pages (BC6H, for a GPU that samples BC
/// textures, [`crate::images::loads_bc6h`]): each asset shows the half-float texels until
/// its file is read (again, when it was loaded before), and then the file's blocks, a
/// quarter of the `Rgba16Float` page's memory.
pub(crate) fn file_pages(
    world: &mut World,
    paths: &[String],
    pages: &[lightbake::LightmapPage],
    reread: bool,
) -> Vec<Handle<Image>> {
    let server = world.resource::<AssetServer>().clone();
    let handles: Vec<(Handle<Image>, bool)> = paths
        .iter()
        .map(|p| match server.get_handle::<Image>(p) {
            Some(h) => (h, true),
            None => (server.load(p), false),
        })
        .collect();
    let mut images = world.resource_mut::<Assets<Image>>();
    for ((h, _), page) in handles.iter().zip(pages) {
        if images.insert(h.id(), page_image(page)).is_err() {
            warn!("lightbake: a lightmap image was removed while it was being replaced");
        }
    }
    for ((_, loaded_before), path) in handles.iter().zip(paths) {
        if reread && *loaded_before {
            server.reload(path.clone());
        }
    }
    handles.into_iter().map(|(h, _)| h).collect()
}

/// The pages as images made in memory, reusing the assets of earlier bakes and previews (so a
/// page of the same size updates its GPU texture in place).
pub(crate) fn memory_pages(
    world: &mut World,
    pages: &[lightbake::LightmapPage],
) -> Vec<Handle<Image>> {
    let mut kept = std::mem::take(&mut world.resource_mut::<MemoryPages>().0);
    let mut images = world.resource_mut::<Assets<Image>>();
    kept.truncate(pages.len());
    for (i, page) in pages.iter().enumerate() {
        let image = page_image(page);
        match kept.get(i) {
            Some(h) if images.insert(h.id(), image.clone()).is_ok() => {}
            Some(_) => kept[i] = images.add(image),
            None => kept.push(images.add(image)),
        }
    }
    world.resource_mut::<MemoryPages>().0 = kept.clone();
    kept
}

/// Every baked entity gets its lightmap (and its own mesh where the asset was split off);
/// returns how many.
pub(crate) fn attach_lightmaps(
    world: &mut World,
    layout: &Layout,
    mapping: &SceneMapping,
    new_handles: &HashMap<usize, Handle<Mesh>>,
    handles: &[Handle<Image>],
) -> usize {
    let mut lightmapped = 0;
    for (i, &entity) in mapping.instances.iter().enumerate() {
        let Ok(mut e) = world.get_entity_mut(entity) else {
            continue; // despawned during the bake
        };
        let Some(rect) = layout.instances[i] else {
            // No lightmap this time (`receive_lightmap` turned off): drop an earlier one.
            if e.contains::<Lightmapped>() {
                e.remove::<(Lightmapped, Lightmap)>();
                if let Some(mut mesh) = e.get_mut::<Mesh3d>() {
                    mesh.set_changed(); // see `sync_lightmaps`
                }
            }
            continue;
        };
        let mesh_index = mapping.instance_meshes[i];
        if let Some(h) = new_handles.get(&mesh_index) {
            e.insert(Mesh3d(h.clone()));
        }
        let [u0, v0, u1, v1] = rect.uv_rect(layout.pages[rect.page as usize]);
        e.insert(Lightmapped {
            image: handles[rect.page as usize].clone(),
            uv_rect: Rect::new(u0, v0, u1, v1),
        });
        lightmapped += 1;
    }

    lightmapped
}

/// The baked lights stop lighting lightmapped meshes: their diffuse light is in the lightmaps
/// now (and the ambient light's, when the sky came from it).
pub(crate) fn mark_lights_baked(world: &mut World, mapping: &SceneMapping) {
    let baked = mapping.lights.iter().map(|&e| (e, true));
    let realtime = mapping.realtime_lights.iter().map(|&e| (e, false));
    for (entity, is_baked) in baked.chain(realtime) {
        let Ok(mut e) = world.get_entity_mut(entity) else {
            continue;
        };
        // A light baked indirect only lights lightmapped meshes in real time (again, when an
        // earlier bake took it off them).
        set_affects_lightmapped(&mut e, !is_baked);
        if is_baked {
            e.insert(BakedLight);
        } else {
            e.remove::<BakedLight>();
        }
    }
    if mapping.sky_from_ambient
        && let Some(mut a) = world.get_resource_mut::<GlobalAmbientLight>()
    {
        a.affects_lightmapped_meshes = false;
    }
}

/// Sets `affects_lightmapped_mesh_diffuse` of the point, spot or directional light on `e`.
pub(crate) fn set_affects_lightmapped(e: &mut EntityWorldMut<'_>, affects: bool) {
    if let Some(mut l) = e.get_mut::<PointLight>() {
        l.affects_lightmapped_mesh_diffuse = affects;
    }
    if let Some(mut l) = e.get_mut::<SpotLight>() {
        l.affects_lightmapped_mesh_diffuse = affects;
    }
    if let Some(mut l) = e.get_mut::<DirectionalLight>() {
        l.affects_lightmapped_mesh_diffuse = affects;
    }
}

/// `affects_lightmapped_mesh_diffuse` of the point, spot or directional light on `e`.
pub(crate) fn affects_lightmapped(e: &EntityRef<'_>) -> Option<bool> {
    e.get::<PointLight>()
        .map(|l| l.affects_lightmapped_mesh_diffuse)
        .or_else(|| {
            e.get::<SpotLight>()
                .map(|l| l.affects_lightmapped_mesh_diffuse)
        })
        .or_else(|| {
            e.get::<DirectionalLight>()
                .map(|l| l.affects_lightmapped_mesh_diffuse)
        })
}

/// Narrows lightmap images Bevy loaded as `Rgba32Float` (EXR, HDR) to `Rgba16Float`, and
/// notes those whose size or format changed (an in-app bake's half-float page replaced by
/// its BC6H file, say), for which Bevy makes a new GPU texture. Runs in `PostUpdate` right
/// after the asset events are published, so the render world never sees the wide version
/// (a reload of the same size and format then updates the GPU texture in place).
pub(crate) fn prepare_lightmap_images(
    mut events: MessageReader<AssetEvent<Image>>,
    mut images: ResMut<Assets<Image>>,
    lightmapped: Query<&Lightmapped>,
    mut sizes: Local<HashMap<AssetId<Image>, (UVec2, TextureFormat)>>,
    mut resized: ResMut<ResizedImages>,
) {
    let ours: HashSet<AssetId<Image>> = lightmapped.iter().map(|l| l.image.id()).collect();
    let mut touched = HashSet::new();
    for event in events.read() {
        if let AssetEvent::Added { id }
        | AssetEvent::Modified { id }
        | AssetEvent::LoadedWithDependencies { id } = event
            && ours.contains(id)
        {
            touched.insert(*id);
        }
    }
    // Images that finished loading before anything referred to them send no new event.
    for id in &ours {
        if !sizes.contains_key(id) && images.get(*id).is_some() {
            touched.insert(*id);
        }
    }
    for id in touched {
        let Some(image) = images.get(id) else {
            continue;
        };
        if !is_ready(image)
            && let Some(mut image) = images.get_mut(id)
        {
            narrow_to_half(&mut image);
        }
        let Some(image) = images.get(id) else {
            continue;
        };
        let now = (image.size(), image.texture_descriptor.format);
        if let Some(old) = sizes.insert(id, now)
            && old != now
        {
            resized.0.insert(id);
        }
    }
}

/// Keeps each [`Lightmapped`] entity's Bevy `Lightmap` in step: inserted when its image is
/// ready and [`ShowLightmaps`] is on, removed when it is off, and removed and re-inserted a
/// frame later when the image or rectangle changes (Bevy's renderer reads a `Lightmap` only
/// when it first appears).
pub(crate) fn sync_lightmaps(
    mut commands: Commands,
    show: Res<ShowLightmaps>,
    images: Res<Assets<Image>>,
    frame: Res<FrameCount>,
    config: Res<LightbakeConfig>,
    mut resized: ResMut<ResizedImages>,
    mut ambient: Option<ResMut<GlobalAmbientLight>>,
    mut query: Query<(
        Entity,
        &Lightmapped,
        Option<&Lightmap>,
        Option<&ReinsertAfter>,
        Option<&mut Mesh3d>,
    )>,
) {
    let mut attached = false;
    for (entity, wanted, current, wait, mut mesh) in &mut query {
        // Bevy 0.20 chooses a mesh's pipeline (lightmapped or not) only when the mesh entity
        // changes (`check_entities_needing_specialization`), not when a `Lightmap` comes or
        // goes; a stale choice draws with the wrong bind group layout, a validation error.
        // So every insertion and removal also marks `Mesh3d` changed (this set runs before
        // that check).
        let mut respecialize = || {
            if let Some(m) = mesh.as_mut() {
                m.set_changed();
            }
        };
        let ready = show.0 && images.get(&wanted.image).is_some_and(is_ready);
        // A new image still loading (the final pages after a preview, say): the one shown
        // stays until it is ready, rather than the mesh flashing to real-time light.
        let keep = |cur: &Lightmap| {
            show.0 && cur.image != wanted.image && images.get(&cur.image).is_some_and(is_ready)
        };
        match (ready, current) {
            (false, Some(cur)) if keep(cur) => {}
            (false, Some(_)) => {
                commands.entity(entity).remove::<Lightmap>();
                respecialize();
            }
            (false, None) => {}
            (true, None) if resized.0.contains(&wanted.image.id()) => {
                // The image changed size or format this frame: Bevy's renderer takes a new
                // `Lightmap`'s texture as it finds it, and the old one may still be there.
                commands
                    .entity(entity)
                    .insert(ReinsertAfter(frame.0.wrapping_add(1)));
            }
            (true, None) => {
                if wait.is_none_or(|w| frame.0 >= w.0) {
                    commands
                        .entity(entity)
                        .remove::<ReinsertAfter>()
                        .insert(Lightmap {
                            image: wanted.image.clone(),
                            uv_rect: wanted.uv_rect,
                            bicubic_sampling: false,
                        });
                    respecialize();
                    attached = true;
                }
            }
            (true, Some(cur)) => {
                if cur.image != wanted.image
                    || cur.uv_rect != wanted.uv_rect
                    || resized.0.contains(&wanted.image.id())
                {
                    commands
                        .entity(entity)
                        .remove::<Lightmap>()
                        .insert(ReinsertAfter(frame.0.wrapping_add(1)));
                    respecialize();
                }
            }
        }
    }
    resized.0.clear();
    if attached
        && config.disable_ambient_on_lightmapped
        && let Some(a) = ambient.as_mut()
        && a.affects_lightmapped_meshes
    {
        a.affects_lightmapped_meshes = false;
    }
}

#[cfg(test)]
mod tests {
    use bevy::asset::RenderAssetUsages;
    use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
    use lightbake::glam::Vec2 as CoreVec2;

    use super::*;

    #[test]
    fn unwrap_split_gathers_every_attribute() {
        // A quad whose seam splits vertex 0 into two.
        let mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            vec![
                [0.0f32, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_COLOR,
            vec![
                [0.0f32, 0.0, 0.0, 1.0],
                [1.0, 0.0, 0.0, 1.0],
                [0.0, 1.0, 0.0, 1.0],
                [0.0, 0.0, 1.0, 1.0],
            ],
        )
        .with_inserted_indices(Indices::U32(vec![0, 1, 2, 0, 2, 3]));
        let unwrap = MeshUnwrap {
            width: 8,
            height: 8,
            uv1: [(0.1, 0.1), (0.9, 0.1), (0.9, 0.9), (0.1, 0.9), (0.2, 0.2)]
                .map(|(u, v)| CoreVec2::new(u, v))
                .to_vec(),
            xref: Some(vec![0, 1, 2, 3, 0]),
            indices: vec![0, 1, 2, 4, 2, 3],
            triangle_charts: vec![0, 1],
            chart_count: 2,
            origin: UvOrigin::Xatlas,
            texels_per_metre: 8.0,
            scaled_to_fit: false,
        };
        let out = apply_unwrap(&mesh, &unwrap).unwrap();
        assert_eq!(out.count_vertices(), 5);
        let Some(VertexAttributeValues::Float32x4(colours)) = out.attribute(Mesh::ATTRIBUTE_COLOR)
        else {
            panic!("colours lost");
        };
        assert_eq!(
            colours[4],
            [0.0, 0.0, 0.0, 1.0],
            "vertex 4 is a copy of vertex 0"
        );
        assert_eq!(colours[3], [0.0, 0.0, 1.0, 1.0]);
        let Some(VertexAttributeValues::Float32x2(uv1)) = out.attribute(Mesh::ATTRIBUTE_UV_1)
        else {
            panic!("no UV_1");
        };
        assert_eq!(uv1[4], [0.2, 0.2]);
        let indices: Vec<usize> = out.indices().unwrap().iter().collect();
        assert_eq!(indices, vec![0, 1, 2, 4, 2, 3]);
        // It had no UV_0: Bevy's StandardMaterial needs one beside UV_1, a copy of it.
        assert_eq!(
            out.attribute(Mesh::ATTRIBUTE_UV_0),
            out.attribute(Mesh::ATTRIBUTE_UV_1)
        );
    }

    fn quad(uv0: bool, uv1: Option<VertexAttributeValues>) -> Mesh {
        let mut mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            vec![[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
        );
        if uv0 {
            mesh.insert_attribute(Mesh::ATTRIBUTE_UV_0, vec![[0.5f32, 0.5]; 3]);
        }
        if let Some(uv1) = uv1 {
            mesh.insert_attribute(Mesh::ATTRIBUTE_UV_1, uv1);
        }
        mesh
    }

    #[test]
    fn uv0_is_given_only_beside_a_lone_uv1() {
        let uv1 = vec![[0.1f32, 0.2], [0.3, 0.4], [0.5, 0.6]];
        let mut lone = quad(false, Some(uv1.clone().into()));
        assert!(give_uv0(&mut lone).unwrap());
        assert_eq!(
            lone.attribute(Mesh::ATTRIBUTE_UV_0),
            Some(&VertexAttributeValues::Float32x2(uv1.clone()))
        );
        assert!(!give_uv0(&mut lone).unwrap(), "once is enough");
        // A textured mesh keeps its own UV_0; a mesh without UV_1 gets none.
        let mut textured = quad(true, Some(uv1.into()));
        assert!(!give_uv0(&mut textured).unwrap());
        assert_eq!(
            textured.attribute(Mesh::ATTRIBUTE_UV_0),
            Some(&VertexAttributeValues::Float32x2(vec![[0.5, 0.5]; 3]))
        );
        let mut plain = quad(false, None);
        assert!(!give_uv0(&mut plain).unwrap());
        assert!(!plain.contains_attribute(Mesh::ATTRIBUTE_UV_0));
    }

    #[test]
    fn meshes_added_with_a_lone_uv1_get_uv0_in_the_app() {
        let mut app = App::new();
        app.add_plugins((MinimalPlugins, AssetPlugin::default()))
            .init_asset::<Mesh>()
            .configure_sets(Update, LightbakeSystems::Gltf)
            .add_systems(Update, give_meshes_uv0.in_set(LightbakeSystems::Gltf));
        let uv1 = vec![[0.1f32, 0.2], [0.3, 0.4], [0.5, 0.6]];
        let mut meshes = app.world_mut().resource_mut::<Assets<Mesh>>();
        let lone = meshes.add(quad(false, Some(uv1.clone().into())));
        let plain = meshes.add(quad(false, None));
        // The asset events of one frame are read in the next.
        app.update();
        app.update();
        let meshes = app.world().resource::<Assets<Mesh>>();
        assert_eq!(
            meshes.get(&lone).unwrap().attribute(Mesh::ATTRIBUTE_UV_0),
            Some(&VertexAttributeValues::Float32x2(uv1))
        );
        assert!(
            !meshes
                .get(&plain)
                .unwrap()
                .contains_attribute(Mesh::ATTRIBUTE_UV_0)
        );
    }
}
