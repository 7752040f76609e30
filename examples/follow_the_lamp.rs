//! Incremental rebakes in a running app: the Cornell box baked in the app with
//! `LightbakeConfig::auto_rebake`; the arrow keys move its lamp, and once the lamp has stayed
//! put for a moment the lightmaps are baked again, following the last bake (the layout is
//! kept, only the texels the move can change are computed again), with the progressive
//! previews on the way.
//!
//! ```text
//! cargo run --release --example follow_the_lamp
//! cargo run --release --example follow_the_lamp -- --screenshot follow.png
//! ```
//!
//! Keys: arrows move the lamp 5 cm (left, right, back, forth), `Space` switches between baked
//! and real-time lighting. The overlay gives the last bake's time and share of texels
//! computed again.
//!
//! With `--screenshot PATH` it renders headless (a software Vulkan driver such as Mesa's
//! lavapipe is enough): after the first bake the lamp moves 5 cm to the right, and the frame
//! after the rebake is saved as PNG.

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

#[derive(Component)]
struct Overlay;

#[derive(Resource)]
struct Headless(Option<Handle<Image>>);

/// The lamp's step per key press, metres.
const STEP: f32 = 0.05;

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
        config.auto_rebake = true;
    }
    let target = screenshot
        .clone()
        .map(|path| support::add_capture(&mut app, 640, 480, Some(path)));
    app.insert_resource(Headless(target))
        .add_systems(Startup, setup)
        .add_systems(Update, (keys, overlay, headless_edit))
        .run()
}

fn setup(mut commands: Commands, headless: Res<Headless>) {
    commands.queue(|world: &mut World| {
        spawn_scene(world, &cornell_box(CornellLight::Point));
        world.write_message(RequestBake::default());
    });
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 0.2744, 1.05).looking_at(Vec3::new(0.0, 0.2744, 0.0), Vec3::Y),
        Exposure { ev100: 7.5 },
    ));
    match &headless.0 {
        Some(image) => {
            camera.insert((
                RenderTarget::Image(image.clone().into()),
                Tonemapping::None,
                bevy::core_pipeline::tonemapping::DebandDither::Disabled,
            ));
        }
        None => {
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
}

/// Arrows: the lamp moves; `Space`: baked ↔ real-time lighting.
fn keys(
    input: Option<Res<ButtonInput<KeyCode>>>,
    mut lamps: Query<&mut Transform, With<PointLight>>,
    mut show: ResMut<ShowLightmaps>,
) {
    let Some(input) = input else { return };
    let step = [
        (KeyCode::ArrowLeft, Vec3::NEG_X),
        (KeyCode::ArrowRight, Vec3::X),
        (KeyCode::ArrowUp, Vec3::NEG_Z),
        (KeyCode::ArrowDown, Vec3::Z),
    ]
    .into_iter()
    .filter(|(k, _)| input.just_pressed(*k))
    .map(|(_, d)| d * STEP)
    .sum::<Vec3>();
    if step != Vec3::ZERO {
        for mut t in &mut lamps {
            t.translation += step;
        }
    }
    if input.just_pressed(KeyCode::Space) {
        show.0 = !show.0;
    }
}

fn overlay(status: Res<BakeStatus>, mut text: Query<&mut Text, With<Overlay>>) {
    let Ok(mut text) = text.single_mut() else {
        return;
    };
    let showing = status
        .preview
        .map_or("the previous lightmaps", |p| p.describe());
    let what = if status.is_running() {
        format!(
            "baking: {} {:.0}%, showing {showing}",
            status.stage.map_or_else(String::new, |s| s.to_string()),
            100.0 * status.fraction
        )
    } else {
        format!("showing {showing}")
    };
    let last = status.last_report.as_ref().map_or_else(String::new, |r| {
        let again = r.incremental.as_ref().map_or(1.0, |i| i.recomputed);
        format!(
            "last bake {:.2} s, {:.0}% of the texels' work computed again",
            r.total_seconds,
            100.0 * again
        )
    });
    text.0 = format!("{what}\n{last}\narrows: move the lamp   Space: baked / real-time");
}

/// Headless: once the first bake shows, the lamp moves a step; once the rebake shows, the
/// capture is armed.
fn headless_edit(
    headless: Res<Headless>,
    capture: Option<ResMut<FrameCapture>>,
    status: Res<BakeStatus>,
    shown: Query<(&Lightmapped, Option<&Lightmap>)>,
    mut lamps: Query<&mut Transform, With<PointLight>>,
    mut moved: Local<bool>,
) {
    let (Some(_), Some(mut capture)) = (&headless.0, capture) else {
        return;
    };
    let all_shown = !shown.is_empty() && shown.iter().all(|(l, m)| l.is_shown_by(m));
    if !*moved && status.completed == 1 && all_shown && !status.is_running() {
        for mut t in &mut lamps {
            t.translation.x += STEP;
        }
        *moved = true;
    }
    capture.armed |= *moved && status.completed >= 2 && all_shown && !status.is_running();
}
