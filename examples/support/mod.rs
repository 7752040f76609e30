//! Shared by the Bevy examples and the render tests (`#[path]`-included): the plugin set for a
//! window or for headless rendering, and the `--screenshot PATH` command line.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Duration;

use bevy::app::{PluginGroupBuilder, ScheduleRunnerPlugin};
use bevy::log::tracing::field::{Field, Visit};
use bevy::log::tracing::{Event, Level, Subscriber};
use bevy::log::tracing_subscriber::Layer;
use bevy::log::tracing_subscriber::layer::Context;
use bevy::log::{BoxedLayer, LogPlugin};
use bevy::prelude::*;
use bevy::window::ExitCondition;
use bevy_lightbake::capture::{FrameCapture, FrameCapturePlugin};

/// `--screenshot PATH` from the command line, if given.
pub fn screenshot_arg() -> Option<PathBuf> {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == "--screenshot")
        .map(|i| PathBuf::from(args.get(i + 1).expect("--screenshot needs a PATH")))
}

/// The value of option `name` (`--name VALUE`), if given.
pub fn option_arg(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    let i = args.iter().position(|a| a == name)?;
    Some(
        args.get(i + 1)
            .unwrap_or_else(|| panic!("{name} needs a value"))
            .clone(),
    )
}

/// The first argument that is not an option (or an option's value), if any.
pub fn positional_arg() -> Option<String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut skip = false;
    for a in args {
        if skip {
            skip = false;
            continue;
        }
        if ["--screenshot", "--weights", "--camera", "--ev100"].contains(&a.as_str()) {
            skip = true;
            continue;
        }
        if !a.starts_with("--") {
            return Some(a);
        }
    }
    None
}

/// Error-level log messages of this process (at most 1 000), as `target: message`.
static ERRORS: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// The error-level messages logged so far by the apps [`default_plugins`] made headless
/// (Bevy's shader and pipeline errors among them), as `target: message`. The first such
/// app sets the process's log subscriber, so one app per test process sees them all.
pub fn logged_errors() -> Vec<String> {
    ERRORS.lock().map(|e| e.clone()).unwrap_or_default()
}

/// Keeps error-level events in [`ERRORS`].
struct ErrorLog;

/// The `message` field of an event.
struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.0 = format!("{value:?}");
        }
    }
}

impl<S: Subscriber> Layer<S> for ErrorLog {
    fn on_event(&self, event: &Event<'_>, _: Context<'_, S>) {
        if *event.metadata().level() != Level::ERROR {
            return;
        }
        let mut message = Message(String::new());
        event.record(&mut message);
        if let Ok(mut errors) = ERRORS.lock()
            && errors.len() < 1000
        {
            errors.push(format!("{}: {}", event.metadata().target(), message.0));
        }
    }
}

fn error_log(_: &mut App) -> Option<BoxedLayer> {
    Some(Box::new(ErrorLog))
}

/// Bevy's default plugins, reading assets from `assets` (absolute, or relative to the
/// workspace). Headless: no window, no winit, a run loop; rendering goes to images only, and
/// error-level messages are kept for [`logged_errors`].
pub fn default_plugins(headless: bool, assets: &Path) -> PluginGroupBuilder {
    let group = DefaultPlugins.build().set(AssetPlugin {
        file_path: assets.to_string_lossy().into_owned(),
        ..default()
    });
    if headless {
        group
            .set(LogPlugin {
                custom_layer: error_log,
                ..default()
            })
            .set(WindowPlugin {
                primary_window: None,
                exit_condition: ExitCondition::DontExit,
                ..default()
            })
            .disable::<bevy::winit::WinitPlugin>()
            .add(ScheduleRunnerPlugin::run_loop(Duration::ZERO))
    } else {
        group.set(WindowPlugin {
            primary_window: Some(Window {
                title: "lightbake".into(),
                ..default()
            }),
            ..default()
        })
    }
}

/// The workspace's `assets` folder.
pub fn workspace_assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

/// Adds frame capture of `width × height` pixels; returns the render target for the camera.
pub fn add_capture(
    app: &mut App,
    width: u32,
    height: u32,
    save_to: Option<PathBuf>,
) -> Handle<Image> {
    app.add_plugins(FrameCapturePlugin);
    let world = app.world_mut();
    let mut capture = FrameCapture::new(width, height, &mut world.resource_mut::<Assets<Image>>());
    capture.save_to = save_to;
    capture.exit_when_done = true;
    let target = capture.target.clone();
    world.insert_resource(capture);
    target
}

/// Whether a Vulkan driver is installed (the render tests skip without one).
pub fn vulkan_available() -> bool {
    let icd_dirs = ["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d"];
    let has_icd = icd_dirs.iter().any(|d| {
        std::fs::read_dir(d).is_ok_and(|mut r| {
            r.any(|e| e.is_ok_and(|e| e.path().extension().is_some_and(|x| x == "json")))
        })
    });
    let has_loader = [
        "/usr/lib/x86_64-linux-gnu/libvulkan.so.1",
        "/usr/lib/aarch64-linux-gnu/libvulkan.so.1",
        "/usr/lib/libvulkan.so.1",
        "/usr/lib64/libvulkan.so.1",
    ]
    .iter()
    .any(|p| Path::new(p).exists());
    has_icd && has_loader
}

/// Whether a render test can run: true when a Vulkan driver is installed. Without one it says
/// that it skips and returns false, unless `LIGHTBAKE_REQUIRE_VULKAN=1` is set (as `.ci/run`
/// does after installing lavapipe), when it panics so that the test fails instead of
/// passing silently.
pub fn render_tests_can_run() -> bool {
    if vulkan_available() {
        return true;
    }
    let required = std::env::var("LIGHTBAKE_REQUIRE_VULKAN").is_ok_and(|v| v == "1");
    assert!(
        !required,
        "LIGHTBAKE_REQUIRE_VULKAN=1 but no Vulkan driver is installed (apt-get install mesa-vulkan-drivers libvulkan1)"
    );
    eprintln!("skipping: no Vulkan driver (apt-get install mesa-vulkan-drivers libvulkan1)");
    false
}

/// A headless rendering app for the render tests: default plugins reading assets from
/// `assets`, the lightbake plugin writing there, and a `width × height` frame capture (not
/// exiting). Returns the app, ready to update, and the capture's render target.
pub fn render_test_app(assets: &Path, width: u32, height: u32) -> (App, Handle<Image>) {
    let mut app = App::new();
    app.add_plugins(default_plugins(true, assets))
        .add_plugins(bevy_lightbake::LightbakePlugin);
    app.world_mut()
        .resource_mut::<bevy_lightbake::LightbakeConfig>()
        .assets_folder = assets.to_path_buf();
    let target = add_capture(&mut app, width, height, None);
    app.world_mut()
        .resource_mut::<FrameCapture>()
        .exit_when_done = false;
    while app.plugins_state() == bevy::app::PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    (app, target)
}

/// Updates `app` until its capture has a settled frame, arming it once `ready` holds (the
/// bake is done and the lightmaps are attached). Panics if the bake or the capture fails.
pub fn capture_when_ready(
    app: &mut App,
    mut ready: impl FnMut(&mut World) -> bool,
) -> bevy_lightbake::capture::CapturedFrame {
    loop {
        app.update();
        let world = app.world_mut();
        if let bevy_lightbake::BakePhase::Failed(e) =
            &world.resource::<bevy_lightbake::BakeStatus>().phase
        {
            panic!("bake failed: {e}");
        }
        let is_ready = ready(world);
        let mut capture = world.resource_mut::<FrameCapture>();
        capture.armed |= is_ready;
        if let Some(e) = &capture.failed {
            panic!("capture failed: {e}");
        }
        if let Some(frame) = &capture.frame {
            return frame.clone();
        }
    }
}
