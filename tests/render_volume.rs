//! A dynamic object next to lightmapped geometry, drawn by Bevy's renderer (software Vulkan,
//! Mesa lavapipe): a thin plate lying on the floor, not baked (no `Lightbaked`), takes its
//! diffuse light from the irradiance volume the in-app bake spawned (and any real-time light),
//! the floor beside it from its lightmap; where both see the same light they must be as bright
//! within 10%. In the Cornell box (lit by its emissive ceiling panel, which Bevy does not draw
//! in real time: all of the plate's light comes from the volume) and the sunlit room (sky and
//! interreflection from the volume; in the sun patch Bevy's real-time sun adds the direct
//! light, with its shadows); and two office rooms lit by the sky through their windows, plates
//! in each room and across the wall between them. Each scene gets the volumes a default bake
//! places (a volume per room, more over the ground) where the driver has texture binding
//! arrays, as Mesa 25's lavapipe does, and one volume where it has none (Mesa 22's), without
//! which Bevy reads every volume from one texture; `LIGHTBAKE_REQUIRE_BINDING_ARRAYS=1`, which
//! `.ci/run` sets on Debian 12 after installing Mesa 25 from its backports, makes the tests
//! fail there instead. Skips when no Vulkan driver is installed (fails instead with
//! `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use bevy::camera::Exposure;
use bevy::camera::visibility::RenderLayers;
use bevy::light::{GlobalAmbientLight, IrradianceVolume};
use bevy::prelude::*;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, office_level, sunlit_room};
use render_common::{exposure_for, mean_at, pixel, wait_for_bake};

const W: u32 = 320;
const H: u32 = 240;

/// Per spot, the indices of the volumes Bevy draws whose boxes hold it.
type Holders = Vec<Vec<usize>>;

/// Bakes `scene` in the app with `settings` (volumes among them), lays a plate of `size` m
/// (the floor's material, not baked) on the floor (the instance `floor_name`) at each of
/// `spots`, and renders from `camera` (the instances named in `hidden` out of its sight; the
/// scene's sky baked when `sky`, else none),
/// once per spot with the exposure that puts the floor there at about a third of white.
/// Returns, per spot, the plate's brightness and the floor's (the mean of four points `size`
/// m beside the plate); and, where the GPU draws several volumes, the volumes each spot lies in.
fn plates_against_floor(
    scene: &Scene,
    mut settings: BakeSettings,
    (spots, size): (&[Vec2], f32),
    (floor_name, hidden, sky): (&str, &[&str], bool),
    camera: (Transform, Projection),
    name: &str,
) -> (Vec<(Vec3, Vec3)>, Option<Holders>) {
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    let device = app
        .world()
        .resource::<bevy::render::renderer::RenderDevice>();
    let several = bevy_lightbake::volumes::draws_several_volumes(device);
    if !several {
        // `.ci/run` installs a driver that has them.
        assert!(
            !std::env::var("LIGHTBAKE_REQUIRE_BINDING_ARRAYS").is_ok_and(|v| v == "1"),
            "LIGHTBAKE_REQUIRE_BINDING_ARRAYS=1 but this Vulkan driver has no texture binding arrays, so Bevy draws one irradiance volume (Debian 12: mesa-vulkan-drivers from bookworm-backports has them)"
        );
        // Bevy would read every volume from the first one's texture here.
        println!("{name}: this GPU draws one irradiance volume: baking one");
        settings.volume.regions = 1;
    }

    app.world_mut().resource_mut::<LightbakeConfig>().settings = settings;
    let world = app.world_mut();
    let entities = spawn_scene(world, scene);
    if !sky {
        world.insert_resource(GlobalAmbientLight::NONE);
    }
    let floor = render_common::instance_entity(scene, &entities, floor_name);
    for h in hidden {
        let e = render_common::instance_entity(scene, &entities, h);
        world.entity_mut(e).insert(RenderLayers::layer(1));
    }
    let material = world
        .get::<MeshMaterial3d<StandardMaterial>>(floor)
        .unwrap()
        .clone();
    let plate = world
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(size, 0.004, size));
    for s in spots {
        world.spawn((
            Mesh3d(plate.clone()),
            material.clone(),
            Transform::from_xyz(s.x, 0.002, s.y),
        ));
    }
    let camera = world
        .spawn((
            render_common::test_camera(target, camera.0, Exposure::default().ev100),
            camera.1,
        ))
        .id();
    world.write_message(RequestBake::default());
    wait_for_bake(&mut app, 1, |world| {
        let mut volumes = world.query::<&IrradianceVolume>();
        let ready = volumes
            .iter(world)
            .all(|v| world.resource::<Assets<Image>>().get(&v.voxels).is_some());
        let baked = (world.resource::<BakeStatus>().last_report.as_ref())
            .map(|r| r.irradiance_volumes.len());
        assert_ne!(baked, Some(0), "the bake made no volume");
        ready && baked == Some(volumes.iter(world).count())
    });
    // Per spot, the volumes whose box (a unit cube scaled and placed by its transform) holds it.
    let boxes: Vec<Mat4> = app
        .world_mut()
        .query_filtered::<&GlobalTransform, With<IrradianceVolume>>()
        .iter(app.world())
        .map(|t| t.to_matrix().inverse())
        .collect();
    let holders: Vec<Vec<usize>> = spots
        .iter()
        .map(|s| {
            let p = Vec3::new(s.x, 0.002, s.y);
            (0..boxes.len())
                .filter(|&k| boxes[k].transform_point3(p).abs().max_element() <= 0.5)
                .collect()
        })
        .collect();
    println!(
        "{name}: Bevy draws {} irradiance volume(s); the spots lie in {holders:?}",
        boxes.len()
    );
    let mut results = Vec::new();
    for (k, s) in spots.iter().enumerate() {
        let world = app.world_mut();
        // The floor there at about a third of white.
        let ev100 = exposure_for(world, floor, Vec3::new(s.x, 0.0, s.y));
        world.entity_mut(camera).insert(Exposure { ev100 });
        world.resource_mut::<FrameCapture>().rearm();
        let frame = support::capture_when_ready(&mut app, |_| true);
        frame
            .save_png(&std::env::temp_dir().join(format!("lightbake_render_volume_{name}_{k}.png")))
            .unwrap();
        let world = app.world_mut();
        let on_plate = mean_at(&frame, pixel(world, Vec3::new(s.x, 0.0, s.y)), 2);
        let beside: Vec3 = [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            .iter()
            .map(|(dx, dz)| {
                let p = Vec3::new(s.x + dx * size, 0.0, s.y + dz * size);
                mean_at(&frame, pixel(world, p), 2)
            })
            .sum::<Vec3>()
            / 4.0;
        results.push((on_plate, beside));
    }
    (results, several.then_some(holders))
}

fn check(name: &str, spots: &[Vec2], results: &[(Vec3, Vec3)]) {
    let mut worst: f32 = 0.0;
    for (s, (plate, floor)) in spots.iter().zip(results) {
        assert!(
            floor.max_element() > 0.03,
            "{name}: the floor at {s} is lit: {floor}"
        );
        assert!(
            plate.max_element() < 0.95 && floor.max_element() < 0.95,
            "clipped"
        );
        let rel = (*plate - *floor).abs().max_element() / floor.max_element();
        println!(
            "{name} at ({:+.2}, {:+.2}): dynamic plate {plate:.4}, lightmapped floor {floor:.4}, {:.1}%",
            s.x,
            s.y,
            100.0 * rel
        );
        worst = worst.max(rel);
    }
    assert!(
        worst < 0.10,
        "{name}: plate and floor differ by {:.1}%",
        100.0 * worst
    );
}

#[test]
fn a_dynamic_plate_lit_by_the_volume_matches_the_lightmapped_floor() {
    if !support::render_tests_can_run() {
        return;
    }
    // The Cornell box, seen from above (its ceiling and panel face down, so Bevy culls them).
    let cornell = cornell_box(CornellLight::Area);
    let spots = [Vec2::new(-0.15, 0.15), Vec2::new(0.16, -0.16)];
    let (results, _) = plates_against_floor(
        &cornell,
        {
            let mut s = BakeSettings::medium();
            s.layout.texel_density = Some(128.0);
            s.volume.enabled = true;
            s.volume.probe_spacing = Some(0.04);
            s.volume.probe_rays = 1024;
            s
        },
        (&spots, 0.06),
        ("floor", &[], false),
        (
            Transform::from_xyz(0.0, 1.2, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
            Projection::default(),
        ),
        "cornell",
    );
    check("Cornell box", &spots, &results);

    // The sunlit room, seen from under its ceiling: one plate in the shade, one in the sun.
    let room = sunlit_room();
    let rays = lightbake::bvh::RayScene::build(&room);
    let sun = room.lights[0].direction;
    let in_sun = |s: Vec2| {
        let p = glam::Vec3::new(s.x, 0.01, s.y);
        !rays.occluded(p, -sun, 0.0, 100.0)
    };
    let spots = [Vec2::new(-2.8, -2.0), Vec2::new(1.0, 0.6)];
    assert!(
        !in_sun(spots[0]) && in_sun(spots[1]),
        "one spot in the shade, one in the sun"
    );
    for s in &spots {
        // The whole plate and the floor beside it in the same light.
        for d in [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y] {
            assert_eq!(
                in_sun(*s + d * 0.45),
                in_sun(*s),
                "{s} is not near a shadow edge"
            );
        }
    }
    let (results, _) = plates_against_floor(
        &room,
        {
            let mut s = BakeSettings::medium();
            s.volume.enabled = true;
            s.volume.probe_spacing = Some(0.25);
            s.volume.probe_rays = 512;
            s
        },
        (&spots, 0.3),
        ("floor", &[], false),
        (
            Transform::from_xyz(-0.9, 2.9, -0.7)
                .looking_at(Vec3::new(-0.9, 0.0, -0.7), Vec3::NEG_Z),
            Projection::Perspective(PerspectiveProjection {
                fov: 100f32.to_radians(),
                ..default()
            }),
        ),
        "sunlit_room",
    );
    check("sunlit room", &spots, &results);
}

#[test]
fn plates_across_two_rooms_volumes_match_the_lightmapped_floor() {
    if !support::render_tests_can_run() {
        return;
    }
    // Two office rooms side by side (the wall between them at x = 6 m, a door at z = 1.0–1.9
    // m), lit by the sky alone through their windows, so Bevy draws no light in real time
    // and all of a plate's light comes from the volumes: one per room and four over the
    // ground around the building (narrowed to 19.2 m), blended by Bevy's falloff where they
    // overlap — on a GPU with texture binding arrays; on one without (Mesa 22's lavapipe),
    // one volume over the level, as the plugin's warning advises. Seen from above, the
    // ceiling slab out of the camera's sight.
    let mut rooms = office_level(2, 1);
    rooms.lights.clear();
    for inst in &mut rooms.instances {
        if inst.name == "ground" {
            inst.transform *= glam::Affine3A::from_scale(glam::Vec3::new(0.4, 1.0, 0.4));
        }
    }
    // In each room, away from the wall; across the boundary between the rooms' volumes,
    // through the door and beside the wall.
    let spots = [
        Vec2::new(2.7, 4.3),
        Vec2::new(8.7, 4.3),
        Vec2::new(5.7, 1.45),
        Vec2::new(6.3, 1.45),
        Vec2::new(5.7, 2.3),
        Vec2::new(6.3, 2.3),
    ];
    let (results, holders) = plates_against_floor(
        &rooms,
        {
            let mut s = BakeSettings::medium();
            s.volume.enabled = true;
            s.volume.probe_spacing = Some(0.25);
            s.volume.probe_rays = 512;
            s
        },
        (&spots, 0.15),
        ("floor slab", &["ceiling slab"], true),
        (
            Transform::from_xyz(6.0, 9.0, 2.5).looking_at(Vec3::new(6.0, 0.0, 2.5), Vec3::NEG_Z),
            Projection::Perspective(PerspectiveProjection {
                fov: 80f32.to_radians(),
                ..default()
            }),
        ),
        "two_rooms",
    );
    check("two rooms", &spots, &results);
    if let Some(holders) = holders {
        // The rooms in volumes of their own: the plates on either side of the wall and of
        // the door are lit from different volumes, with Bevy's falloff between them.
        for (a, b) in [(0, 1), (2, 3), (4, 5)] {
            assert!(
                !holders[a].is_empty() && !holders[b].is_empty(),
                "spots {a} and {b} lie in no volume: {holders:?}"
            );
            assert!(
                holders[a].iter().all(|k| !holders[b].contains(k)),
                "spots {a} and {b}, on either side of the wall, share a volume: {holders:?}"
            );
        }
    }
}
