//! Headless Bevy apps for the plugin tests: Bevy's default plugins with no GPU (the render
//! plugin is asked for no backend, so there is no render world), no window, no log.

#![allow(dead_code)]

use std::path::Path;
use std::time::{Duration, Instant};

use bevy::app::PluginsState;
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::WgpuSettings;
use bevy::window::ExitCondition;
use bevy_lightbake::prelude::*;

/// An app reading assets from `assets` (created if missing), with the plugin added and
/// `LightbakeConfig::assets_folder` pointing there. `watch`: Bevy's file watcher on.
pub fn headless_app(assets: &Path, watch: bool) -> App {
    std::fs::create_dir_all(assets).unwrap();
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(RenderPlugin {
                render_creation: WgpuSettings {
                    backends: None,
                    ..default()
                }
                .into(),
                ..default()
            })
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .set(AssetPlugin {
                file_path: assets.to_string_lossy().into_owned(),
                watch_for_changes_override: Some(watch),
                ..default()
            })
            .disable::<bevy::winit::WinitPlugin>()
            .disable::<bevy::log::LogPlugin>(),
    )
    .add_plugins(LightbakePlugin);
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    app.world_mut()
        .resource_mut::<LightbakeConfig>()
        .assets_folder = assets.to_path_buf();
    app
}

/// What the plugin is doing, for timeout messages: the bake's phase and stage, and the
/// lightmapped meshes still waiting for their `Lightmap` with the load state of each image.
pub fn describe(world: &mut World) -> String {
    let status = world.get_resource::<BakeStatus>().map_or_else(
        || "no BakeStatus".to_string(),
        |s| {
            format!(
                "bake {:?}, stage {:?} ({:.0}%), {} completed, {:.1} s",
                s.phase,
                s.stage,
                100.0 * s.fraction,
                s.completed,
                s.elapsed_seconds
            )
        },
    );
    let mut waiting = world.query_filtered::<&Lightmapped, Without<bevy::pbr::Lightmap>>();
    let images: Vec<Handle<Image>> = waiting.iter(world).map(|l| l.image.clone()).collect();
    let server = world.resource::<AssetServer>();
    let states: Vec<String> = images
        .iter()
        .map(|h| {
            format!(
                "{:?}: {:?}",
                h.path(),
                server.get_load_state(h.id()).map(|s| format!("{s:?}"))
            )
        })
        .collect();
    format!(
        "{status}; {} mesh(es) wait for a Lightmap: {states:?}",
        images.len()
    )
}

/// Updates the app until `done` holds, sleeping a little between updates so background tasks
/// (the bake, asset loads, the file watcher) progress. Panics with `what` after `timeout`.
pub fn run_until(
    app: &mut App,
    what: &str,
    timeout: Duration,
    mut done: impl FnMut(&mut World) -> bool,
) {
    let start = Instant::now();
    loop {
        app.update();
        if done(app.world_mut()) {
            return;
        }
        assert!(
            start.elapsed() < timeout,
            "timed out after {timeout:?} waiting for {what}; {}",
            describe(app.world_mut())
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}
