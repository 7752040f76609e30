//! Bake requests and status: [`RequestBake`] and [`CancelBake`] messages, the core baker run
//! in the background, its progress copied into [`BakeStatus`] and its results carried back
//! into the world ([`BakeFinished`]).

use std::time::Instant;

use bevy::prelude::*;
use bevy::render::renderer::RenderDevice;
use lightbake::bake::{PreviewKind, PreviewSlot};
use lightbake::{BakeError, BakeHandle, BakeOutput, BakeSettings, Scene};

use crate::LightbakeSystems;
use crate::components::{
    BakeFinished, BakeOutcome, BakePhase, BakeStatus, CancelBake, LightbakeConfig, RequestBake,
};
use crate::convert::{SceneMapping, extract_scene};
use crate::images::loads_bc6h;
use crate::lightmaps::{
    apply_meshes, attach_lightmaps, file_pages, mark_lights_baked, memory_pages,
};
use crate::preview::Previewing;
use crate::volumes::spawn_bake_volumes;

/// Bake requests and status: reads the messages, starts and polls bakes
/// ([`LightbakeSystems::Requests`], [`LightbakeSystems::Bake`]).
pub struct BakeRequestsPlugin;

impl Plugin for BakeRequestsPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<LightbakeConfig>()
            .init_resource::<BakeStatus>()
            .init_resource::<PendingRequest>()
            .add_message::<RequestBake>()
            .add_message::<CancelBake>()
            .add_message::<BakeFinished>()
            .add_systems(
                Update,
                (
                    read_requests.in_set(LightbakeSystems::Requests),
                    (start_bake, poll_bake)
                        .chain()
                        .in_set(LightbakeSystems::Bake),
                ),
            );
    }
}

/// A bake request waiting for the running bake (if any) to stop.
#[derive(Resource, Default)]
pub(crate) struct PendingRequest(Option<RequestBake>);

/// What the bake task hands back.
struct Finished {
    output: BakeOutput,
    /// Asset paths of the page images written, when files were written.
    page_paths: Option<Vec<String>>,
    /// Asset paths of the BC6H pages written besides them (`formats.ktx2_bc6h` with another
    /// format), one per page; empty when there are none.
    bc6h_paths: Vec<String>,
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
    mapping: SceneMapping,
    /// The previews shown so far, and what they replaced.
    previewing: Previewing,
}

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
        Err(e) => return fail(world, started, e.to_string()),
    };
    for w in &scene.warnings {
        warn!("lightbake: {w}");
    }
    // The sky's group, unless a group of the settings already holds the sky.
    let sky = lightbake::settings::groups::SKY;
    if let Some(sky_group) = &config.sky_group
        && scene.sky.max_element() > 0.0
        && !(settings.groups.iter()).any(|g| g.members.iter().any(|m| m == sky))
    {
        lightbake::scene::groups::add_member(&mut settings.groups, sky_group, sky.into());
    }
    let out_dir = config
        .write_files
        .then(|| config.assets_folder.join(&config.output_dir));
    let output_dir = config.output_dir.clone();
    // The check against the path tracer, when the settings ask for it
    // (`settings.checks.verify_points`), runs on the bake thread before the files are written,
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
    // The bake follows the last finished one in the app where it can
    // (`lightbake::incremental`); the plan says what it keeps and why.
    let kept = world.resource::<crate::rebake::KeptBake>().0.clone();
    let plan = lightbake::incremental::plan(Ok(kept), &scene, &settings, request.full);
    info!("lightbake: {}", plan.describe().trim_end());
    crate::rebake::bake_started(world);
    let spawned = lightbake::BakeBuilder::new(scene)
        .settings(settings)
        .following(plan)
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
        previewing: Previewing::default(),
    });
    if config.previews {
        // The previews show in place of the last bake's light-group sums.
        crate::groups::apply_in_app_groups(world, &[], &[]);
    }
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
    mut output: BakeOutput,
    scene: &Scene,
    settings: &BakeSettings,
    out_dir: Option<&std::path::Path>,
    output_dir: &str,
) -> Result<Finished, BakeError> {
    let (page_paths, bc6h_paths, volume_paths) = match out_dir {
        Some(dir) => {
            // The app keeps the cache for its next bake in memory (`rebake::KeptBake`): none
            // is written into the assets folder, where the game would ship it.
            let cache = output.cache.take();
            let written = lightbake::write_outputs(dir, &output, scene, None, settings);
            output.cache = cache;
            written?;
            let pages = lightbake::output::page_files(&output, settings);
            let volumes = lightbake::output::volumes(&output);
            let bc6h: Option<Vec<String>> = (pages.iter())
                .map(|p| Some(format!("{output_dir}/{}", p.bc6h_besides_primary()?)))
                .collect();
            (
                Some(
                    pages
                        .iter()
                        .map(|p| format!("{output_dir}/{}", p.primary().unwrap_or_default()))
                        .collect(),
                ),
                bc6h.unwrap_or_default(),
                Some(
                    volumes
                        .iter()
                        .map(|v| format!("{output_dir}/{}", v.image))
                        .collect(),
                ),
            )
        }
        None => (None, Vec::new(), None),
    };
    Ok(Finished {
        output,
        page_paths,
        bc6h_paths,
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
            && preview.sequence > job.previewing.shown()
            && preview.kind != PreviewKind::Final
        {
            job.previewing.show(world, &job.mapping, &preview);
        }
        world.insert_resource(job);
        return;
    };
    let seconds = job.started.elapsed().as_secs_f64();
    if result.is_err() && job.previewing.restore(world, &job.mapping) {
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

/// Puts a finished bake into the world: meshes get `UV_1`, baked mesh entities get
/// [`Lightmapped`], baked lights stop lighting lightmapped meshes. Returns how many mesh
/// entities got a lightmap.
fn apply_bake(world: &mut World, finished: Finished, mapping: &SceneMapping) -> usize {
    let Finished {
        output,
        page_paths,
        bc6h_paths,
        volume_paths,
    } = finished;
    if output.cache.is_some() {
        world.resource_mut::<crate::rebake::KeptBake>().0 = output.cache.clone();
    }
    let new_handles = apply_meshes(world, &output.layout, mapping);
    let bc6h = !bc6h_paths.is_empty()
        && loads_bc6h(
            world.resource::<LightbakeConfig>(),
            world.get_resource::<RenderDevice>(),
        );
    let handles = match page_paths.as_deref() {
        Some(_) if bc6h => file_pages(world, &bc6h_paths, &output.pages, true),
        Some(paths) => file_pages(world, paths, &output.pages, false),
        None => memory_pages(world, &output.pages),
    };
    let lightmapped = attach_lightmaps(world, &output.layout, mapping, &new_handles, &handles);
    let pages: Vec<(Entity, u32)> = (mapping.instances.iter().zip(&output.layout.instances))
        .filter_map(|(&e, rect)| Some((e, rect.as_ref()?.page)))
        .collect();
    crate::groups::apply_in_app_groups(world, &output.groups, &pages);
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
