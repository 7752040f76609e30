//! Mixed lighting drawn by Bevy's renderer (software Vulkan, Mesa lavapipe): the Cornell box
//! with its ceiling point light baked in full (its light in the lightmaps, the light off for
//! lightmapped meshes), then again with the light [`BakeMode::IndirectOnly`] (only what it
//! reflects in the lightmaps, the light itself drawn in real time with Bevy's shadows). The two
//! pictures must agree within 5% on the floor, in the light and in the blocks' shadows, away
//! from shadow edges. Skips when no Vulkan driver is installed (fails instead with
//! `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use bevy::camera::Exposure;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy_lightbake::capture::{CapturedFrame, FrameCapture};
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use render_common::{exposure_for, mean_at, pixel, wait_for_bake};

const W: u32 = 320;
const H: u32 = 240;

/// One frame at each exposure.
fn frames(app: &mut App, camera: Entity, exposures: &[f32]) -> Vec<CapturedFrame> {
    exposures
        .iter()
        .map(|&ev100| {
            let world = app.world_mut();
            world.entity_mut(camera).insert(Exposure { ev100 });
            world.resource_mut::<FrameCapture>().rearm();
            support::capture_when_ready(app, |_| true)
        })
        .collect()
}

#[test]
fn a_mixed_bake_renders_like_a_full_bake() {
    if !support::render_tests_can_run() {
        return;
    }
    let scene = cornell_box(CornellLight::Point);
    let rays = lightbake::bvh::RayScene::build(&scene);
    let lamp = scene.lights[0].position;
    let lit = |s: Vec2| {
        let p = glam::Vec3::new(s.x, 0.001, s.y);
        let to = lamp - p;
        !rays.occluded(p, to.normalize(), 0.0, to.length() - 1e-3)
    };
    // Floor points with everything within 2 cm in the same light: three lit, two in the
    // blocks' shadows.
    let clear = |s: Vec2| {
        [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y]
            .iter()
            .all(|d| lit(s + 0.02 * *d) == lit(s))
    };
    let mut spots: Vec<(Vec2, bool)> = Vec::new();
    for k in 0..400 {
        let s = Vec2::new(
            -0.24 + 0.024 * (k % 20) as f32,
            -0.24 + 0.024 * (k / 20) as f32,
        );
        let wanted = if lit(s) { 3 } else { 2 };
        if clear(s) && spots.iter().filter(|x| x.1 == lit(s)).count() < wanted {
            // Spread out: not next to a spot already taken.
            if spots.iter().all(|x| x.0.distance(s) > 0.1) {
                spots.push((s, lit(s)));
            }
        }
    }
    assert_eq!(spots.len(), 5, "{spots:?}");

    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    app.world_mut()
        .resource_mut::<LightbakeConfig>()
        .settings
        .layout
        .texel_density = Some(128.0);
    let world = app.world_mut();
    let entities = spawn_scene(world, &scene);
    let floor = entities[scene
        .instances
        .iter()
        .position(|i| i.name == "floor")
        .unwrap()];
    world.insert_resource(GlobalAmbientLight::NONE);
    let camera = world
        .spawn(render_common::test_camera(
            target,
            // From above: the ceiling faces down, so Bevy culls it.
            Transform::from_xyz(0.0, 1.2, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
            Exposure::default().ev100,
        ))
        .id();
    // Full: the light's light is baked.
    app.world_mut().write_message(RequestBake::default());
    wait_for_bake(&mut app, 1, |_| true);
    // One exposure for the light and one for the shadows: the brightest floor spot of each
    // at about a third of white.
    let world = app.world_mut();
    let level = |lit: bool| {
        spots
            .iter()
            .filter(|s| s.1 == lit)
            .map(|s| exposure_for(world, floor, Vec3::new(s.0.x, 0.0, s.0.y)))
            .fold(f32::MIN, f32::max)
    };
    let exposures = [level(true), level(false)];
    let full = frames(&mut app, camera, &exposures);
    let world = app.world_mut();
    let mut lights = world.query_filtered::<Entity, With<PointLight>>();
    let light = lights.single(world).unwrap();
    world.entity_mut(light).insert(BakeMode::IndirectOnly);
    // Mixed: only what the light reflects is baked; the light is drawn in real time.
    world.write_message(RequestBake::default());
    wait_for_bake(&mut app, 2, |_| true);
    let world = app.world_mut();
    let l = world.get::<PointLight>(light).unwrap();
    assert!(l.affects_lightmapped_mesh_diffuse && l.shadow_maps_enabled);
    let mixed = frames(&mut app, camera, &exposures);
    for (name, f) in [("full", &full[0]), ("mixed", &mixed[0])] {
        f.save_png(&std::env::temp_dir().join(format!("lightbake_render_mixed_{name}.png")))
            .unwrap();
    }

    let world = app.world_mut();
    let mut worst: f32 = 0.0;
    for (s, lit) in &spots {
        let k = usize::from(!lit);
        let p = pixel(world, Vec3::new(s.x, 0.0, s.y));
        let (a, b) = (mean_at(&full[k], p, 2), mean_at(&mixed[k], p, 2));
        assert!(a.max_element() > 0.05 && a.max_element() < 0.95, "{s}: {a}");
        let rel = (a - b).abs().max_element() / a.max_element();
        println!(
            "({:+.3}, {:+.3}) {}: full bake {a:.4}, mixed {b:.4}, {:.1}%",
            s.x,
            s.y,
            if *lit { "lit" } else { "in shadow" },
            100.0 * rel
        );
        worst = worst.max(rel);
    }
    assert!(
        worst < 0.05,
        "mixed and full differ by {:.1}%",
        100.0 * worst
    );
}
