//! The plugin's systems: take bake requests, run the core baker in the background, carry its
//! results back into the world, and keep Bevy's `Lightmap` components in step with their
//! images.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use bevy::asset::AssetId;
use bevy::diagnostic::FrameCount;
use bevy::light::GlobalAmbientLight;
use bevy::mesh::{Indices, MeshAccessError};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use lightbake::bake::{PreviewKind, PreviewSlot};
use lightbake::{
    BakeError, BakeHandle, BakeOutput, BakeSettings, Layout, MeshUnwrap, Scene, UvOrigin,
};

use crate::components::{
    BakeFinished, BakeOutcome, BakePhase, BakeStatus, BakedLight, CancelBake, LightbakeConfig,
    Lightmapped, RequestBake, ShowLightmaps,
};
use crate::convert::{SceneMapping, extract_scene};
use crate::images::{is_ready, narrow_to_half, page_image};
use crate::preview::{Restore, show_preview};
use crate::volumes::spawn_bake_volumes;

/// A bake request waiting for the running bake (if any) to stop.
#[derive(Resource, Default)]
pub(crate) struct PendingRequest(Option<RequestBake>);

/// What the bake task hands back.
struct Finished {
    output: BakeOutput,
    /// Asset paths of the page images written, when files were written.
    page_paths: Option<Vec<String>>,
    /// Asset paths of the irradiance volumes written, when files were written.
    volume_paths: Option<Vec<String>>,
}

/// The running bake.
///
/// It runs on a thread of its own ([`BakeHandle`], with its own rayon pool of
/// `settings.threads` workers), not on Bevy's `AsyncComputeTaskPool`: Bevy compiles render
/// pipelines on that pool, which has a single thread on a 2-core machine, and a bake holding
/// it stalls the first frames waiting for pipelines. The frame loop only polls the handle.
#[derive(Resource)]
pub(crate) struct BakeJob {
    handle: BakeHandle<Finished>,
    started: Instant,
    pub(crate) mapping: SceneMapping,
    /// The last preview shown (its sequence number; 0 before the first).
    pub(crate) shown: u32,
    /// What the first preview replaced, put back when the bake is cancelled or fails.
    pub(crate) restore: Option<Restore>,
    /// The meshes the first preview split off into assets of their own (by core mesh).
    pub(crate) preview_meshes: Option<HashMap<usize, Handle<Mesh>>>,
}

/// In-memory page images of earlier bakes, reused so a re-bake of the same size updates the
/// GPU texture in place.
#[derive(Resource, Default)]
pub(crate) struct MemoryPages(Vec<Handle<Image>>);

/// Images whose size changed this frame (their `Lightmap`s must be re-inserted).
#[derive(Resource, Default)]
pub(crate) struct ResizedImages(HashSet<AssetId<Image>>);

/// A `Lightmap` removed to be re-inserted: not before this frame.
#[derive(Component, Clone, Copy, Debug)]
pub(crate) struct ReinsertAfter(u32);

/// Takes [`RequestBake`] and [`CancelBake`] messages. A request while a bake runs cancels
/// that bake; the new one starts when it has stopped.
pub(crate) fn read_requests(
    mut requests: MessageReader<RequestBake>,
    mut cancels: MessageReader<CancelBake>,
    mut pending: ResMut<PendingRequest>,
    job: Option<Res<BakeJob>>,
) {
    if let Some(r) = requests.read().last() {
        pending.0 = Some(r.clone());
        if let Some(job) = &job {
            job.handle.cancel();
        }
    }
    if cancels.read().count() > 0 {
        pending.0 = None;
        if let Some(job) = &job {
            job.handle.cancel();
        }
    }
}

/// Starts the pending bake when none is running: converts the marked world into a core
/// scene here (cheap), then bakes and writes files on the bake thread (see [`BakeJob`]).
pub(crate) fn start_bake(world: &mut World) {
    if world.contains_resource::<BakeJob>() {
        return;
    }
    let Some(request) = world.resource_mut::<PendingRequest>().0.take() else {
        return;
    };
    let started = Instant::now();
    let config = world.resource::<LightbakeConfig>().clone();
    let mut settings = request.settings.unwrap_or_else(|| config.settings.clone());
    // The sky is read from the ambient light as the game set it, not as a shown volume
    // turned it down (`volumes::sync_volumes` turns it down again).
    crate::volumes::restore_ambient(world);
    let (scene, mapping) = match extract_scene(world, "bevy world", config.sky, &mut settings) {
        Ok(x) => x,
        Err(message) => return fail(world, started, message),
    };
    for w in &scene.warnings {
        warn!("lightbake: {w}");
    }
    let out_dir = config
        .write_files
        .then(|| config.assets_folder.join(&config.output_dir));
    let output_dir = config.output_dir.clone();
    // The check against the path tracer, when the settings ask for it
    // (`BakeSettings::verify_points`), runs on the bake thread before the files are written,
    // so `report.json` and the report the app sees hold it.
    let then = move |mut output, scene: &Scene, settings: &BakeSettings| {
        lightbake::analysis::verify::verify(scene, &mut output);
        write_files(output, scene, settings, out_dir.as_deref(), &output_dir)
    };
    let previews = if config.previews {
        PreviewSlot::enabled()
    } else {
        PreviewSlot::default()
    };
    let spawned = lightbake::BakeBuilder::new(scene)
        .settings(settings)
        .previews(std::sync::Arc::new(previews))
        .spawn_then(then);
    let handle = match spawned {
        Ok(h) => h,
        Err(e) => return fail(world, started, e.to_string()),
    };
    world.insert_resource(BakeJob {
        handle,
        started,
        mapping,
        shown: 0,
        restore: None,
        preview_meshes: None,
    });
    let mut status = world.resource_mut::<BakeStatus>();
    status.phase = BakePhase::Running;
    status.stage = None;
    status.stage_index = 0;
    status.fraction = 0.0;
    status.error_estimate = None;
    status.finished_stages.clear();
    status.elapsed_seconds = 0.0;
    status.preview = None;
}

/// After the bake, on its thread: (optionally) write the outputs atomically into the assets
/// folder.
fn write_files(
    output: BakeOutput,
    scene: &Scene,
    settings: &BakeSettings,
    out_dir: Option<&std::path::Path>,
    output_dir: &str,
) -> Result<Finished, BakeError> {
    let (page_paths, volume_paths) = match out_dir {
        Some(dir) => {
            lightbake::write_outputs(dir, &output, scene, None, settings)?;
            let pages = lightbake::output::page_files(&output, settings);
            let volumes = lightbake::output::volumes(&output);
            (
                Some(
                    pages
                        .iter()
                        .map(|p| format!("{output_dir}/{}", p.primary().unwrap_or_default()))
                        .collect(),
                ),
                Some(
                    volumes
                        .iter()
                        .map(|v| format!("{output_dir}/{}", v.image))
                        .collect(),
                ),
            )
        }
        None => (None, None),
    };
    Ok(Finished {
        output,
        page_paths,
        volume_paths,
    })
}

fn fail(world: &mut World, started: Instant, message: String) {
    error!("lightbake: {message}");
    world.resource_mut::<BakeStatus>().phase = BakePhase::Failed(message.clone());
    world.write_message(BakeFinished {
        outcome: BakeOutcome::Failed(message),
        seconds: started.elapsed().as_secs_f64(),
        lightmapped: 0,
    });
}

/// Copies the running bake's progress into [`BakeStatus`] and, when it has finished, applies
/// its results.
pub(crate) fn poll_bake(world: &mut World) {
    let Some(mut job) = world.remove_resource::<BakeJob>() else {
        return;
    };
    let snap = job.handle.snapshot();
    {
        let mut status = world.resource_mut::<BakeStatus>();
        status.stage = snap.stage;
        status.stage_index = snap.stage_index;
        status.fraction = snap.fraction();
        status.error_estimate = snap.error_estimate;
        status.finished_stages = snap.finished;
        status.elapsed_seconds = job.started.elapsed().as_secs_f32();
    }
    let Some(result) = job.handle.try_join() else {
        if let Some(preview) = job.handle.preview()
            && preview.sequence > job.shown
            && preview.kind != PreviewKind::Final
        {
            show_preview(world, &mut job, &preview);
        }
        world.insert_resource(job);
        return;
    };
    let seconds = job.started.elapsed().as_secs_f64();
    if result.is_err()
        && let Some(restore) = job.restore.take()
    {
        restore.apply(world, &job.mapping);
        world.resource_mut::<BakeStatus>().preview = None;
    }
    match result {
        Ok(finished) => {
            let lightmapped = apply_bake(world, finished, &job.mapping);
            info!("lightbake: baked {lightmapped} mesh(es) in {seconds:.2} s");
            world.write_message(BakeFinished {
                outcome: BakeOutcome::Baked,
                seconds,
                lightmapped,
            });
        }
        Err(BakeError::Cancelled) => {
            info!("lightbake: bake cancelled after {seconds:.2} s");
            world.resource_mut::<BakeStatus>().phase = BakePhase::Cancelled;
            world.write_message(BakeFinished {
                outcome: BakeOutcome::Cancelled,
                seconds,
                lightmapped: 0,
            });
        }
        Err(e) => fail(world, job.started, e.to_string()),
    }
}

/// `original` with the unwrap's vertex split applied to every attribute, its triangle list
/// replaced and `UV_1` set.
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
    Ok(mesh)
}

/// Puts a finished bake into the world: meshes get `UV_1`, baked mesh entities get
/// [`Lightmapped`], baked lights stop lighting lightmapped meshes. Returns how many mesh
/// entities got a lightmap.
fn apply_bake(world: &mut World, finished: Finished, mapping: &SceneMapping) -> usize {
    let Finished {
        output,
        page_paths,
        volume_paths,
    } = finished;
    let new_handles = apply_meshes(world, &output.layout, mapping);
    let handles = match page_paths.as_deref() {
        Some(paths) => file_pages(world, paths, &output.pages),
        None => memory_pages(world, &output.pages),
    };
    let lightmapped = attach_lightmaps(world, &output.layout, mapping, &new_handles, &handles);
    mark_lights_baked(world, mapping);
    spawn_bake_volumes(
        world,
        &output,
        volume_paths.as_deref(),
        mapping.sky_from_ambient,
    );
    for w in &output.report.warnings {
        warn!("lightbake: {w}");
    }
    let mut status = world.resource_mut::<BakeStatus>();
    status.phase = BakePhase::Done;
    status.completed += 1;
    status.fraction = 1.0;
    status.preview = Some(PreviewKind::Final);
    status.last_report = Some(Box::new(output.report));
    lightmapped
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
        let mut meshes = world.resource_mut::<Assets<Mesh>>();
        if source.needs_own_asset {
            new_handles.insert(m, meshes.add(mesh));
        } else if meshes.insert(source.handle.id(), mesh).is_err() {
            warn!("lightbake: a baked mesh asset was removed during the bake");
        }
    }

    new_handles
}

/// The page images of the files just written, by asset path, holding `pages` at once: the
/// asset of each path (loaded now if it was not) gets the new texels in memory, so the entities
/// never show a file's previous content while the file is read again; the asset stays tied
/// to its file, so a later rewrite by the `bake` command reloads it.
pub(crate) fn file_pages(
    world: &mut World,
    paths: &[String],
    pages: &[lightbake::LightmapPage],
) -> Vec<Handle<Image>> {
    let server = world.resource::<AssetServer>().clone();
    let handles: Vec<Handle<Image>> = paths
        .iter()
        .map(|p| {
            server
                .get_handle::<Image>(p)
                .unwrap_or_else(|| server.load(p))
        })
        .collect();
    let mut images = world.resource_mut::<Assets<Image>>();
    for (h, page) in handles.iter().zip(pages) {
        if images.insert(h.id(), page_image(page)).is_err() {
            warn!("lightbake: a lightmap image was removed while it was being replaced");
        }
    }
    handles
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
/// notes those whose size changed. Runs in `PostUpdate` right after the asset events are
/// published, so the render world never sees the wide version (a same-size reload then
/// updates the GPU texture in place).
pub(crate) fn prepare_lightmap_images(
    mut events: MessageReader<AssetEvent<Image>>,
    mut images: ResMut<Assets<Image>>,
    lightmapped: Query<&Lightmapped>,
    mut sizes: Local<HashMap<AssetId<Image>, UVec2>>,
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
        if let Some(old) = sizes.insert(id, image.size())
            && old != image.size()
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
        // Bevy 0.19 chooses a mesh's pipeline (lightmapped or not) only when the mesh entity
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
    }
}
