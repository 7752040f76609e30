//! The Cornell box (with a ceiling point light), baked inside a running Bevy app.
//!
//! ```text
//! cargo run --release --example cornell_box
//! cargo run --release --example cornell_box -- --screenshot cornell.png
//! ```
//!
//! The bake starts at startup and runs on a background task while the app keeps drawing; the
//! overlay shows the stage, its progress and the solver's error estimate, and the lightmaps
//! show the bake's progress: its direct light, then the coarse indirect light, then the
//! result.
//! Keys: `B` bake again, `C` cancel, `Space` switch between the baked lightmaps and Bevy's
//! real-time lighting.
//!
//! With `--screenshot PATH` it renders headless (no window; a software Vulkan driver such
//! as Mesa's lavapipe is enough), waits for the bake and for every render pipeline, saves one
//! frame as PNG, prints the frame times measured while baking and while idle, and exits.

#[path = "support/mod.rs"]
mod support;

use bevy::camera::{Exposure, RenderTarget};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::lightbake::scene::testscenes::{CornellLight, cornell_box};
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;

/// Frame times, split by whether a bake was running.
#[derive(Resource, Default)]
struct FrameTimes {
    baking: Vec<f32>,
    idle: Vec<f32>,
}

#[derive(Component)]
struct Overlay;

fn main() -> AppExit {
    let screenshot = support::screenshot_arg();
    let assets = support::workspace_assets();
    let mut app = App::new();
    app.add_plugins(support::default_plugins(screenshot.is_some(), &assets))
        .add_plugins(LightbakePlugin);
    {
        let mut config = app.world_mut().resource_mut::<LightbakeConfig>();
        config.assets_folder = assets;
        config.settings.layout.texel_density = Some(128.0);
    }
    let target = screenshot
        .clone()
        .map(|path| support::add_capture(&mut app, 640, 480, Some(path)));
    app.insert_resource(CameraTarget(target))
        .init_resource::<FrameTimes>()
        .add_systems(Startup, (setup_scene, setup_camera))
        .add_systems(Update, (keys, overlay, measure, arm_capture))
        .add_systems(Last, report_frame_times);
    app.run()
}

#[derive(Resource)]
struct CameraTarget(Option<Handle<Image>>);

fn setup_scene(world: &mut World) {
    spawn_scene(world, &cornell_box(CornellLight::Point));
    world.write_message(RequestBake::default());
}

fn setup_camera(mut commands: Commands, target: Res<CameraTarget>) {
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 0.2744, 1.05).looking_at(Vec3::new(0.0, 0.2744, 0.0), Vec3::Y),
        // The ceiling light makes about 100 nits on the floor, direct and reflected: expose
        // for it.
        Exposure { ev100: 7.5 },
    ));
    if let Some(image) = &target.0 {
        // No camera draws to a window: this one places the shadow maps' detail.
        camera.insert((
            RenderTarget::Image(image.clone().into()),
            Tonemapping::None,
            bevy::core_pipeline::tonemapping::DebandDither::Disabled,
            bevy::camera::ShadowLodOrigin,
        ));
    } else {
        commands.spawn((
            Text::new(""),
            Node {
                position_type: PositionType::Absolute,
                top: px(8),
                left: px(8),
                ..default()
            },
            Overlay,
        ));
    }
}

fn keys(
    input: Option<Res<ButtonInput<KeyCode>>>,
    mut bake: MessageWriter<RequestBake>,
    mut cancel: MessageWriter<CancelBake>,
    mut show: ResMut<ShowLightmaps>,
) {
    let Some(input) = input else { return };
    if input.just_pressed(KeyCode::KeyB) {
        bake.write(RequestBake::default());
    }
    if input.just_pressed(KeyCode::KeyC) {
        cancel.write(CancelBake);
    }
    if input.just_pressed(KeyCode::Space) {
        show.0 = !show.0;
    }
}

fn overlay(
    status: Res<BakeStatus>,
    show: Res<ShowLightmaps>,
    mut text: Query<&mut Text, With<Overlay>>,
) {
    let Ok(mut text) = text.single_mut() else {
        return;
    };
    let what = match &status.phase {
        BakePhase::Idle => "waiting".to_string(),
        BakePhase::Running => format!(
            "baking: {} {:.0}%{}  {:.1} s",
            status.stage.map_or_else(String::new, |s| s.to_string()),
            100.0 * status.fraction,
            status
                .error_estimate
                .map_or(String::new(), |e| format!("  error ≈ {e:.1e}")),
            status.elapsed_seconds
        ),
        BakePhase::Done => format!(
            "baked in {:.2} s",
            status.last_report.as_ref().map_or(0.0, |r| r.total_seconds)
        ),
        BakePhase::Cancelled => "cancelled".into(),
        BakePhase::Failed(e) => format!("failed: {e}"),
    };
    let mode = if show.0 { "baked" } else { "real-time" };
    let showing = status
        .preview
        .map_or("the previous lightmaps", |p| p.describe());
    text.0 = format!(
        "{what}\nlighting: {mode}, showing {showing}\nB: bake again   C: cancel   Space: baked / real-time"
    );
}

/// Wall-clock frame times (`Time<Real>`: the virtual clock clamps long frames to 250 ms).
fn measure(time: Res<Time<Real>>, status: Res<BakeStatus>, mut times: ResMut<FrameTimes>) {
    let dt = time.delta_secs();
    if status.is_running() {
        times.baking.push(dt);
    } else if status.completed > 0 {
        times.idle.push(dt);
    }
}

fn arm_capture(
    capture: Option<ResMut<FrameCapture>>,
    status: Res<BakeStatus>,
    shown: Query<(&Lightmapped, Option<&Lightmap>)>,
) {
    if let Some(mut capture) = capture {
        let ready = status.completed > 0
            && !shown.is_empty()
            && shown.iter().all(|(l, m)| l.is_shown_by(m));
        if ready && !capture.armed {
            capture.armed = true;
        }
        if let BakePhase::Failed(e) = &status.phase {
            capture.failed = Some(e.clone());
        }
    }
}

fn report_frame_times(
    mut exits: MessageReader<AppExit>,
    times: Res<FrameTimes>,
    status: Res<BakeStatus>,
    capture: Option<Res<FrameCapture>>,
) {
    if exits.read().next().is_none() {
        return;
    }
    let stats = |v: &[f32]| {
        let mut s = v.to_vec();
        s.sort_by(f32::total_cmp);
        let mean = s.iter().sum::<f32>() / s.len().max(1) as f32;
        let p95 = s.get(s.len() * 95 / 100).copied().unwrap_or(0.0);
        let max = s.last().copied().unwrap_or(0.0);
        (s.len(), 1000.0 * mean, 1000.0 * p95, 1000.0 * max)
    };
    let (nb, mb, pb, xb) = stats(&times.baking);
    let (ni, mi, pi, xi) = stats(&times.idle);
    println!(
        "last bake in the app: {:.2} s ({} completed)",
        status.elapsed_seconds, status.completed
    );
    println!(
        "frame time while baking: {mb:.1} ms mean, {pb:.1} ms p95, {xb:.1} ms max over {nb} frames"
    );
    println!(
        "frame time idle:         {mi:.1} ms mean, {pi:.1} ms p95, {xi:.1} ms max over {ni} frames"
    );
    if let Some(c) = capture {
        match (&c.frame, &c.failed, &c.save_to) {
            (_, Some(e), _) => eprintln!("screenshot failed: {e}"),
            (Some(_), None, Some(p)) => println!("saved {}", p.display()),
            _ => {}
        }
    }
}
