//! Dynamic objects and mixed lighting: the Cornell box baked in the app with an irradiance
//! volume, its ceiling lamp baked indirect only (it stays a real-time light with Bevy's
//! shadows), and a sphere that moves (not baked) lit by the lamp in real time and by the
//! volume's baked indirect light — the red and green walls' colour on its sides, its shadow
//! on the lightmapped floor.
//!
//! ```text
//! cargo run --release --example dynamic_objects
//! cargo run --release --example dynamic_objects -- --screenshot dynamic.png
//! ```
//!
//! While the bake runs the lightmaps show its progress (direct light, then the coarse indirect
//! light, then the result). Keys: `M` switch the lamp between mixed (indirect only baked) and
//! fully baked and bake again, `Space` switch between baked and real-time lighting.
//!
//! With `--screenshot PATH` it renders headless (a software Vulkan driver such as Mesa's
//! lavapipe is enough), the sphere held still, saves one frame as PNG and exits.

#[path = "support/mod.rs"]
mod support;

use bevy::camera::{Exposure, RenderTarget};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::IrradianceVolume;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::lightbake::scene::testscenes::{CornellLight, cornell_box};
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;

#[derive(Component)]
struct Moving;

#[derive(Component)]
struct Overlay;

#[derive(Resource)]
struct Headless(Option<Handle<Image>>);

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
        config.settings.volume.enabled = true;
        config.settings.volume.probe_spacing = Some(0.04);
    }
    let target = screenshot
        .clone()
        .map(|path| support::add_capture(&mut app, 640, 480, Some(path)));
    app.insert_resource(Headless(target))
        .add_systems(Startup, setup)
        .add_systems(Update, (keys, move_sphere, overlay, arm_capture))
        .run()
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    headless: Res<Headless>,
) {
    commands.queue(|world: &mut World| {
        spawn_scene(world, &cornell_box(CornellLight::Point));
        let mut lamps = world.query_filtered::<Entity, With<PointLight>>();
        let lamps: Vec<Entity> = lamps.iter(world).collect();
        for lamp in lamps {
            world.entity_mut(lamp).insert(BakeMode::IndirectOnly);
        }
        world.write_message(RequestBake::default());
    });
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.06).mesh().uv(48, 24))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.9, 0.9, 0.9),
            perceptual_roughness: 0.9,
            reflectance: 0.1,
            ..default()
        })),
        Transform::from_xyz(-0.12, 0.12, 0.14),
        Moving,
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        Transform::from_xyz(0.0, 0.2744, 1.05).looking_at(Vec3::new(0.0, 0.2744, 0.0), Vec3::Y),
        Exposure { ev100: 7.5 },
    ));
    match &headless.0 {
        Some(image) => {
            // No camera draws to a window: this one places the shadow maps' detail.
            camera.insert((
                RenderTarget::Image(image.clone().into()),
                Tonemapping::None,
                bevy::core_pipeline::tonemapping::DebandDither::Disabled,
                bevy::camera::ShadowLodOrigin,
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

/// `M`: the lamp mixed ↔ fully baked, and bake again; `Space`: baked ↔ real-time lighting.
fn keys(
    input: Option<Res<ButtonInput<KeyCode>>>,
    mut commands: Commands,
    lamps: Query<(Entity, &BakeMode)>,
    mut bake: MessageWriter<RequestBake>,
    mut show: ResMut<ShowLightmaps>,
) {
    let Some(input) = input else { return };
    if input.just_pressed(KeyCode::KeyM) {
        for (e, mode) in &lamps {
            let next = match mode {
                BakeMode::Full => BakeMode::IndirectOnly,
                BakeMode::IndirectOnly => BakeMode::Full,
            };
            commands.entity(e).insert(next);
        }
        bake.write(RequestBake::default());
    }
    if input.just_pressed(KeyCode::Space) {
        show.0 = !show.0;
    }
}

/// The sphere circles the box (held still for a screenshot).
fn move_sphere(
    time: Res<Time>,
    headless: Res<Headless>,
    mut spheres: Query<&mut Transform, With<Moving>>,
) {
    if headless.0.is_some() {
        return;
    }
    let t = time.elapsed_secs() * 0.6;
    for mut tf in &mut spheres {
        tf.translation = Vec3::new(
            0.17 * t.cos(),
            0.12 + 0.05 * (2.0 * t).sin(),
            0.18 * t.sin(),
        );
    }
}

fn overlay(
    status: Res<BakeStatus>,
    lamps: Query<&BakeMode>,
    mut text: Query<&mut Text, With<Overlay>>,
) {
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
    let lamp = match lamps.iter().next() {
        Some(BakeMode::IndirectOnly) => "mixed: real-time lamp, baked indirect light",
        _ => "fully baked lamp",
    };
    text.0 = format!("{what}\n{lamp}\nM: mixed / fully baked   Space: baked / real-time");
}

fn arm_capture(
    capture: Option<ResMut<FrameCapture>>,
    status: Res<BakeStatus>,
    shown: Query<(&Lightmapped, Option<&Lightmap>)>,
    volumes: Query<&IrradianceVolume>,
    images: Res<Assets<Image>>,
) {
    let Some(mut capture) = capture else { return };
    let volume_ready = !volumes.is_empty() && volumes.iter().all(|v| images.contains(&v.voxels));
    if status.completed > 0
        && volume_ready
        && !shown.is_empty()
        && shown.iter().all(|(l, m)| l.is_shown_by(m))
    {
        capture.armed = true;
    }
    if let BakePhase::Failed(e) = &status.phase {
        capture.failed = Some(e.clone());
    }
}
