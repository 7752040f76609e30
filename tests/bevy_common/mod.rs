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
    // Bevy 0.19 without a render world still puts render-synced components on entities, and
    // their removal hooks need `PendingSyncEntity`, which only the render world's plugin
    // adds: despawning a glTF scene (a hot reload re-spawns it) would panic without this.
    .add_plugins(bevy::render::sync_world::SyncWorldPlugin)
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
            "timed out after {timeout:?} waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}
