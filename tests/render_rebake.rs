//! `LightbakeConfig::auto_rebake` in a running app, drawn by Bevy's renderer (lavapipe): a
//! lamp moved twice, the second time while the rebake of the first move runs, gives a
//! cancelled rebake and then an incremental one; the frame loop keeps running while it
//! bakes; the floor keeps its place in the atlas; and the rendered floor matches a full bake
//! of the edited scene within that bake's estimated error. Skips when no Vulkan driver is
//! installed (fails instead with `LIGHTBAKE_REQUIRE_VULKAN=1`).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use bevy::camera::ScalingMode;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::capture::{CapturedFrame, FrameCapture};
use bevy_lightbake::prelude::*;
use render_common::wait_for_bake;

const SIZE: u32 = 192;
const HALF_VIEW: f32 = 1.6;

fn pixel_of(x: f32, z: f32) -> (u32, u32) {
    let to = |v: f32| (((v + HALF_VIEW) / (2.0 * HALF_VIEW)) * SIZE as f32) as u32;
    (to(x), to(z))
}

/// 7×7-pixel means on a grid over the floor, away from the crate.
fn floor_spots(frame: &CapturedFrame) -> Vec<Vec3> {
    let mut spots = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let (x, z) = (-1.1 + 0.44 * i as f32, -1.1 + 0.44 * j as f32);
            if x.abs() < 0.35 && z.abs() < 0.35 {
                continue;
            }
            let (px, py) = pixel_of(x, z);
            spots.push(frame.mean_linear(px - 3, py - 3, px + 4, py + 4));
        }
    }
    spots
}

/// RMS of the spots' difference relative to the RMS of `b`'s.
fn relative_rms(a: &[Vec3], b: &[Vec3]) -> f32 {
    let diff: f32 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    let level: f32 = b.iter().map(|y| y.length_squared()).sum();
    (diff / level.max(1e-12)).sqrt()
}

fn capture(app: &mut App) -> CapturedFrame {
    app.world_mut().resource_mut::<FrameCapture>().rearm();
    support::capture_when_ready(app, |_| true)
}

#[test]
fn a_moved_lamp_is_rebaked_incrementally_and_matches_a_full_bake() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), SIZE, SIZE);
    app.insert_resource(GlobalAmbientLight::NONE)
        .insert_resource(ClearColor(Color::BLACK));
    {
        let mut config = app.world_mut().resource_mut::<LightbakeConfig>();
        config.settings = BakeSettings::medium();
        config.settings.layout.texel_density = Some(24.0);
        config.settings.threads = 1;
        config.rebake_after_seconds = 0.1;
    }
    let world = app.world_mut();
    let floor_mesh = world
        .resource_mut::<Assets<Mesh>>()
        .add(Plane3d::default().mesh().size(3.0, 3.0).subdivisions(4));
    let crate_mesh = world
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(0.5, 0.5, 0.5));
    let grey = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial {
            base_color: Color::srgb(0.7, 0.7, 0.7),
            reflectance: 0.0,
            perceptual_roughness: 1.0,
            ..default()
        });
    let floor = world
        .spawn((
            Mesh3d(floor_mesh),
            MeshMaterial3d(grey.clone()),
            Transform::IDENTITY,
            Lightbaked::default(),
            Name::new("floor"),
        ))
        .id();
    world.spawn((
        Mesh3d(crate_mesh),
        MeshMaterial3d(grey),
        Transform::from_xyz(0.0, 0.25, 0.0),
        Lightbaked::default(),
        Name::new("crate"),
    ));
    let lamp = world
        .spawn((
            PointLight {
                intensity: 4.0 * std::f32::consts::PI * 3.0, // 3 cd
                range: 6.0,
                ..default()
            },
            Transform::from_xyz(-0.6, 0.9, 0.0),
            Name::new("lamp"),
        ))
        .id();
    world.spawn((
        Projection::Orthographic(OrthographicProjection {
            scaling_mode: ScalingMode::Fixed {
                width: 2.0 * HALF_VIEW,
                height: 2.0 * HALF_VIEW,
            },
            ..OrthographicProjection::default_3d()
        }),
        render_common::test_camera(
            target,
            Transform::from_xyz(0.0, 4.0, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
            1.0,
        ),
    ));
    world.write_message(RequestBake::default());
    wait_for_bake(&mut app, 1, |_| true);
    let before = floor_spots(&capture(&mut app));
    let rect = |world: &mut World| world.get::<Lightmap>(floor).map(|l| l.uv_rect);
    let rect_before = rect(app.world_mut());
    assert!(rect_before.is_some(), "the floor has a lightmap");

    // Auto-rebake on; the lamp moves 30 cm, and 30 cm more once that rebake runs.
    app.world_mut()
        .resource_mut::<LightbakeConfig>()
        .auto_rebake = true;
    let moved = |app: &mut App| {
        let world = app.world_mut();
        world.get_mut::<Transform>(lamp).unwrap().translation.x += 0.3;
    };
    moved(&mut app);
    let mut outcomes = Vec::new();
    let record = |world: &mut World, outcomes: &mut Vec<BakeOutcome>| {
        let mut finished = world.resource_mut::<Messages<BakeFinished>>();
        outcomes.extend(finished.drain().map(|f| f.outcome));
    };
    let mut frames_while_baking = 0u32;
    loop {
        app.update();
        record(app.world_mut(), &mut outcomes);
        if app.world().resource::<BakeStatus>().is_running() {
            frames_while_baking += 1;
            if frames_while_baking == 1 {
                moved(&mut app);
            }
        }
        if outcomes.contains(&BakeOutcome::Baked) {
            break;
        }
        if let BakePhase::Failed(e) = &app.world().resource::<BakeStatus>().phase {
            panic!("the rebake failed: {e}");
        }
    }
    wait_for_bake(&mut app, 2, |_| true);
    println!("outcomes {outcomes:?}, {frames_while_baking} frames while baking");
    assert_eq!(
        outcomes,
        [BakeOutcome::Cancelled, BakeOutcome::Baked],
        "the edit during the rebake cancels it and bakes again"
    );
    assert!(
        frames_while_baking >= 10,
        "{frames_while_baking} frames ran while the app baked"
    );
    let status = app.world().resource::<BakeStatus>();
    let report = status.last_report.clone().expect("a report");
    println!("the rebake:\n{}", report.table());
    let inc = report.incremental.clone().expect("an incremental report");
    assert!(inc.full.is_none(), "the rebake was a full bake: {inc:?}");
    assert!(inc.recomputed < 1.0, "every item computed again: {inc:?}");
    assert_eq!(
        rect(app.world_mut()),
        rect_before,
        "the floor kept its place in the atlas"
    );
    let x = app.world().get::<Transform>(lamp).unwrap().translation.x;
    assert!(x.abs() < 1e-4, "both moves were made: the lamp at x = {x}");
    let incremental = floor_spots(&capture(&mut app));

    // A full bake of the edited scene.
    app.world_mut().write_message(RequestBake {
        settings: None,
        full: true,
    });
    wait_for_bake(&mut app, 3, |_| true);
    let full_report = (app.world().resource::<BakeStatus>().last_report.clone()).unwrap();
    let estimate = full_report
        .error
        .as_ref()
        .expect("an estimate")
        .relative_rms as f32;
    assert!(
        full_report
            .incremental
            .as_ref()
            .is_some_and(|i| i.full.is_some()),
        "{:?}",
        full_report.incremental
    );
    println!("the full bake:\n{}", full_report.table());
    let full = floor_spots(&capture(&mut app));

    let moved_by = relative_rms(&before, &full);
    let off = relative_rms(&incremental, &full);
    println!(
        "floor: incremental against full {:.2}%, the full bake's estimate {:.2}%, the lamp's move changed it by {:.1}%; {:.1}% of the items computed again, {frames_while_baking} frames while baking",
        100.0 * off,
        100.0 * estimate,
        100.0 * moved_by,
        100.0 * inc.recomputed
    );
    // 8-bit sRGB read-backs, averaged over 49 pixels: about 0.3% more.
    assert!(
        off <= 1.5 * estimate + 0.003,
        "incremental against full {:.2}% over 1.5 × the estimate {:.2}%",
        100.0 * off,
        100.0 * estimate
    );
    assert!(
        moved_by > 3.0 * (1.5 * estimate + 0.003),
        "the move changed the floor by only {:.2}%",
        100.0 * moved_by
    );
    assert!(app.world().get::<Lightmapped>(floor).is_some());
}
