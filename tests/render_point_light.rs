//! Bevy's renderer (software Vulkan, Mesa lavapipe) shows a plane lit only by a *baked*
//! point light as bright as an identical plane lit by Bevy's own real-time `PointLight` of
//! the same intensity: this pins down the unit convention end to end (lumens → candela, the
//! E/π texel, `lightmap_exposure` 1, Bevy's range window). Skips when no Vulkan driver is
//! installed (fails instead with `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after
//! installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use bevy::camera::ScalingMode;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::prelude::*;

const SIZE: u32 = 256;
/// Half the width of the orthographic view, metres.
const HALF_VIEW: f32 = 2.25;
/// One pixel, metres.
const PIXEL: f32 = 2.0 * HALF_VIEW / SIZE as f32;
/// The planes' centres: baked on the left, real-time on the right, a whole number of pixels
/// apart so that the same offset from each falls on the same place within a pixel.
const BAKED_X: f32 = -68.0 * PIXEL;
const LIVE_X: f32 = 68.0 * PIXEL;

fn pixel_of(x: f32, z: f32) -> (u32, u32) {
    let to = |v: f32| (((v + HALF_VIEW) / (2.0 * HALF_VIEW)) * SIZE as f32) as u32;
    (to(x), to(z))
}

#[test]
fn baked_point_light_matches_bevys_real_time_point_light() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), SIZE, SIZE);
    app.insert_resource(GlobalAmbientLight::NONE)
        .insert_resource(ClearColor(Color::BLACK));
    {
        let mut config = app.world_mut().resource_mut::<LightbakeConfig>();
        config.settings.layout.texel_density = Some(64.0);
        config.settings.method = lightbake::settings::Method::Direct;
    }

    let world = app.world_mut();
    let plane = world
        .resource_mut::<Assets<Mesh>>()
        .add(Plane3d::default().mesh().size(1.0, 1.0).subdivisions(3));
    // White, no specular (reflectance 0 gives F0 = 0 and f90 = 0): only diffuse light shows.
    let white = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial {
            base_color: Color::WHITE,
            reflectance: 0.0,
            perceptual_roughness: 0.5,
            ..default()
        });
    let light = || PointLight {
        intensity: 4.0 * std::f32::consts::PI * 1.0, // 1 cd
        range: 2.0,
        ..default()
    };
    world.spawn((
        Mesh3d(plane.clone()),
        MeshMaterial3d(white.clone()),
        Transform::from_xyz(BAKED_X, 0.0, 0.0),
        Lightbaked::default(),
    ));
    world.spawn((light(), Transform::from_xyz(BAKED_X, 0.5, 0.0)));
    world.spawn((
        Mesh3d(plane),
        MeshMaterial3d(white),
        Transform::from_xyz(LIVE_X, 0.0, 0.0),
    ));
    world.spawn((light(), Transform::from_xyz(LIVE_X, 0.5, 0.0), NotBaked));
    world.spawn((
        Projection::Orthographic(OrthographicProjection {
            scaling_mode: ScalingMode::Fixed {
                width: 2.0 * HALF_VIEW,
                height: 2.0 * HALF_VIEW,
            },
            ..OrthographicProjection::default_3d()
        }),
        // Looking down -Y with -Z up in the image: image x = world x, image y = world z.
        render_common::test_camera(
            target,
            Transform::from_xyz(0.0, 3.0, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
            1.0,
        ),
    ));
    world.write_message(RequestBake::default());

    let frame = support::capture_when_ready(&mut app, |world| {
        let mut lit = world.query::<(&Lightmapped, Option<&Lightmap>)>();
        lit.iter(world).count() == 1 && lit.iter(world).all(|(l, m)| l.is_shown_by(m))
    });
    frame
        .save_png(&std::env::temp_dir().join("lightbake_render_point_light.png"))
        .unwrap();

    // Compare 9×9-pixel means at the same offsets from each light's foot.
    let mut worst: f32 = 0.0;
    for (dx, dz) in [
        (0.0, 0.0),
        (0.25, 0.0),
        (-0.3, 0.2),
        (0.0, -0.35),
        (0.35, 0.35),
    ] {
        let mean = |cx: f32| {
            let (px, py) = pixel_of(cx + dx, dz);
            frame.mean_linear(px - 4, py - 4, px + 5, py + 5)
        };
        let (baked, live) = (mean(BAKED_X), mean(LIVE_X));
        assert!(
            live.x > 0.05,
            "the real-time plane is lit ({live}) at ({dx}, {dz})"
        );
        let rel = (baked - live).abs().max_element() / live.max_element();
        println!(
            "offset ({dx:+.2}, {dz:+.2}): baked {baked:.4}, real-time {live:.4}, {:.2}%",
            100.0 * rel
        );
        worst = worst.max(rel);
    }
    assert!(
        worst < 0.05,
        "baked and real-time differ by {:.1}%",
        100.0 * worst
    );
    // Away from both planes the image is black (the lights reach nothing else).
    assert!(frame.linear(SIZE / 2, 4).max_element() < 0.01);
}
