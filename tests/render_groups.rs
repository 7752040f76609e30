//! Light groups drawn by Bevy's renderer (software Vulkan, Mesa lavapipe): the shipped sunlit
//! room baked by the core with its sun in group `sun` and its sky in `ungrouped`, and an
//! irradiance volume, loaded as a baked glTF. At each set of [`LightGroupWeights`] the
//! plugin's GPU pass sums the group pages and volumes in the frame the weights change; the
//! floor, in the sun and in the shade, renders as its albedo times the weighted sum of the
//! group pages there (sampled on the CPU) within 1%, and a plate lit by the volume alone
//! renders as the same weighted sum of what it shows with each group alone, within 2%.
//! Skips when no Vulkan driver is installed (fails instead with
//! `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use std::path::Path;

use bevy::camera::Exposure;
use bevy::diagnostic::FrameCount;
use bevy::light::{GlobalAmbientLight, IrradianceVolume};
use bevy::prelude::*;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::groups::{GltfPage, GroupSums, SummedVolume};
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;
use lightbake::settings::LightGroup as GroupSetting;
use render_common::{gltf_floor, mean_at, mean_over_floor, pixel};

const W: u32 = 320;
const H: u32 = 240;

/// Bakes the shipped sunlit room with its sun in group `sun`, and its irradiance volume, into
/// `out`.
fn bake_groups(out: &Path) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sunlit_room.gltf");
    let imported =
        lightbake::import_gltf(&path, lightbake::LightConvention::GltfSpec).expect("the room");
    let mut settings = BakeSettings::preview();
    settings.volume.enabled = true;
    // One volume, which every GPU draws (see `bevy_lightbake::volumes::draws_several_volumes`).
    settings.volume.regions = 1;
    settings.groups = vec![GroupSetting {
        name: "sun".into(),
        members: vec!["sun".into()],
    }];
    let out_bake =
        lightbake::bake(&imported.scene, &settings, &lightbake::Progress::new()).expect("the bake");
    lightbake::write_outputs(
        out,
        &out_bake,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .expect("written");
}

/// Σ weight × group page at floor point `p`, sampled on the CPU from the group images.
fn weighted_at(world: &World, entity: Entity, page: &GltfPage, p: Vec3) -> Vec3 {
    let mesh = world
        .resource::<Assets<Mesh>>()
        .get(&world.get::<Mesh3d>(entity).unwrap().0)
        .unwrap();
    let t = world.get::<GlobalTransform>(entity).unwrap();
    let rect = world.get::<Lightmapped>(entity).unwrap().uv_rect;
    let weights = world.resource::<LightGroupWeights>();
    let images = world.resource::<Assets<Image>>();
    let sums = world.resource::<GroupSums>();
    (sums.sources(page).iter())
        .map(|(g, h)| {
            weights.get(g) * sample_lightmap(mesh, t, rect, images.get(h).unwrap(), p).unwrap()
        })
        .sum()
}

#[test]
fn light_groups_render_as_their_weighted_sum() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    bake_groups(&dir.path().join("baked"));
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    let server = app.world().resource::<AssetServer>().clone();
    let world = app.world_mut();
    world.spawn(WorldAssetRoot(server.load(
        GltfAssetLabel::Scene(0).from_asset("baked/sunlit_room.gltf"),
    )));
    world.insert_resource(GlobalAmbientLight::NONE);
    let camera = world.spawn(render_common::sunlit_floor_camera(target)).id();
    // Until the sums are on the GPU and shown, the floor's and the volume's.
    let (floor, page, albedo) = loop {
        app.update();
        let world = app.world_mut();
        let Some(found) = gltf_floor(world) else {
            continue;
        };
        let mut volumes = world.query::<(&SummedVolume, &IrradianceVolume)>();
        let sums = world.resource::<GroupSums>();
        let volume_shown = (volumes
            .iter(world)
            .map(|(s, v)| sums.volume_target(&s.0) == Some(&v.voxels)))
        .collect::<Vec<_>>();
        let shown = sums
            .target(&found.1)
            .is_some_and(|t| world.get::<Lightmapped>(found.0).unwrap().image == *t);
        if sums.applied() && shown && volume_shown == [true] {
            break found;
        }
    };
    // A plate in the shade beside the shade's spot, not baked: the volume lights it.
    let world = app.world_mut();
    let material = world
        .get::<MeshMaterial3d<StandardMaterial>>(floor)
        .unwrap()
        .clone();
    let plate_at = Vec3::new(-2.8, 0.0, -1.6);
    let mesh = world
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(0.3, 0.004, 0.3));
    world.spawn((
        Mesh3d(mesh),
        material,
        Transform::from_translation(plate_at + 0.002 * Vec3::Y),
    ));
    // The sun's light is baked: only its specular would remain. Without it the floor shows
    // its lightmap alone.
    let world = app.world_mut();
    let mut lights = world.query_filtered::<Entity, With<DirectionalLight>>();
    for l in lights.iter(world).collect::<Vec<_>>() {
        world.despawn(l);
    }
    let sums = world.resource::<GroupSums>();
    let names: Vec<String> = sums.sources(&page).into_iter().map(|(g, _)| g).collect();
    assert_eq!(names, ["sun", "ungrouped"]);

    // A spot in the sun and one in the shade (as the volume's render test picks them).
    let spots = [Vec3::new(1.0, 0.0, 0.6), Vec3::new(-2.8, 0.0, -2.0)];
    let mut worst: f32 = 0.0;
    // Per set of weights, the plate's brightness (before the exposure).
    let mut plate = Vec::new();
    let sets = [(1.0, 1.0), (0.0, 1.0), (1.0, 0.0), (0.5, 2.0), (3.0, 0.0)];
    for (k, weights) in sets.iter().enumerate() {
        let world = app.world_mut();
        world
            .resource_mut::<LightGroupWeights>()
            .set("sun", weights.0)
            .set("ungrouped", weights.1);
        // The frame whose update changed the weights renders with them.
        app.update();
        let changed_in = app.world().resource::<FrameCount>().0;
        let summed_in = loop {
            if let Some(f) = app.world().resource::<GroupSums>().summed_in_frame() {
                break f;
            }
            app.update();
        };
        assert_eq!(
            summed_in, changed_in,
            "weights {weights:?}: changed in frame {changed_in}, summed in frame {summed_in}"
        );
        for (s, spot) in spots.iter().enumerate() {
            let world = app.world_mut();
            let at = pixel(world, *spot);
            let expected = albedo
                * mean_over_floor(world, at, 2, |world, p| weighted_at(world, floor, &page, p));
            if expected.max_element() <= 0.0 {
                // The sun's group alone in the shade: nothing to show.
                assert_eq!(weights.1, 0.0);
                continue;
            }
            // Bevy shows albedo × lightmap × 2^−ev100 / 1.2: about a third of white.
            let ev100 = (expected.max_element() / (0.33 * 1.2)).log2();
            world.entity_mut(camera).insert(Exposure { ev100 });
            world.resource_mut::<FrameCapture>().rearm();
            let frame = support::capture_when_ready(&mut app, |_| true);
            frame
                .save_png(
                    &std::env::temp_dir().join(format!("lightbake_render_groups_{k}_{s}.png")),
                )
                .unwrap();
            let shown = mean_at(&frame, at, 2);
            let want = expected * 2f32.powf(-ev100) / 1.2;
            if s == 1 {
                // The plate in the shade, at the exposure of the floor beside it.
                let on_plate = mean_at(&frame, pixel(app.world_mut(), plate_at), 2);
                assert!(on_plate.max_element() < 0.95, "clipped: {on_plate}");
                plate.push(on_plate * 1.2 / 2f32.powf(-ev100));
            }
            let rel = (shown - want).abs().max_element() / want.max_element();
            println!(
                "weights sun {} ungrouped {}, {}: rendered {shown:.4}, albedo × Σ weight × group {want:.4}, {:.2}%",
                weights.0,
                weights.1,
                if s == 0 { "in the sun" } else { "in the shade" },
                100.0 * rel
            );
            worst = worst.max(rel);
        }
    }
    assert!(worst < 0.01, "{:.2}%", 100.0 * worst);

    // The volume's light on the plate adds up as the groups' weights say: each set against
    // the sun's group alone and the sky's alone.
    let (sun, sky) = (plate[2], plate[1]);
    assert!(sun.max_element() > 0.0 && sky.max_element() > 0.0);
    let mut worst_plate: f32 = 0.0;
    for (weights, shown) in sets.iter().zip(&plate) {
        let want = weights.0 * sun + weights.1 * sky;
        let rel = (*shown - want).abs().max_element() / want.max_element();
        println!(
            "weights sun {} ungrouped {}: the plate lit by the volume {shown:.4}, Σ weight × the group alone {want:.4}, {:.2}%",
            weights.0,
            weights.1,
            100.0 * rel
        );
        worst_plate = worst_plate.max(rel);
    }
    assert!(
        worst_plate < 0.02,
        "the volume's groups: {:.2}%",
        100.0 * worst_plate
    );
}

/// A bake in the app with the Cornell box's lamp in a group (a [`LightGroup`] component):
/// its meshes and its irradiance volume show the group's sum, and weight 0 leaves the lamp's
/// light out entirely, of the lightmaps and of the volume (a plate the volume lights).
#[test]
fn an_in_app_bake_takes_light_groups_from_components() {
    if !support::render_tests_can_run() {
        return;
    }
    let scene = lightbake::scene::testscenes::cornell_box(
        lightbake::scene::testscenes::CornellLight::Point,
    );
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    let world = app.world_mut();
    let mut settings = BakeSettings::preview();
    settings.volume.enabled = true;
    settings.volume.regions = 1;
    world.resource_mut::<LightbakeConfig>().settings = settings;
    let entities = bevy_lightbake::spawn::spawn_scene(world, &scene);
    let floor = render_common::instance_entity(&scene, &entities, "floor");
    // A plate on the floor, not baked: the volume lights it.
    let material = world
        .get::<MeshMaterial3d<StandardMaterial>>(floor)
        .unwrap()
        .clone();
    let plate_at = Vec3::new(0.15, 0.0, 0.15);
    let mesh = world
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(0.08, 0.004, 0.08));
    world.spawn((
        Mesh3d(mesh),
        material,
        Transform::from_translation(plate_at + 0.002 * Vec3::Y),
    ));
    world.insert_resource(GlobalAmbientLight::NONE);
    let mut lights = world.query_filtered::<Entity, With<PointLight>>();
    let lamp = lights.single(world).unwrap();
    world.entity_mut(lamp).insert(LightGroup("lamp".into()));
    world.spawn(render_common::test_camera(
        target,
        Transform::from_xyz(0.0, 1.2, 0.0).looking_at(Vec3::ZERO, Vec3::NEG_Z),
        7.0,
    ));
    world.write_message(RequestBake::default());
    render_common::wait_for_bake(&mut app, 1, |world| {
        let sums = world.resource::<GroupSums>();
        let page = world.get::<bevy_lightbake::groups::SummedPage>(floor);
        let page_shown =
            page.is_some_and(|p| sums.shows_sum(p, world.get::<Lightmapped>(floor).unwrap()));
        let mut volumes = world.query::<(&SummedVolume, &IrradianceVolume)>();
        let sums = world.resource::<GroupSums>();
        let volume_shown: Vec<bool> = (volumes.iter(world))
            .map(|(s, v)| sums.volume_target(&s.0) == Some(&v.voxels))
            .collect();
        sums.applied() && page_shown && volume_shown == [true]
    });
    let world = app.world_mut();
    // The lamp's light is baked: only its specular would remain. Without it the floor shows
    // its lightmap alone.
    world.get_mut::<PointLight>(lamp).unwrap().intensity = 0.0;
    let report = world.resource::<BakeStatus>().last_report.clone().unwrap();
    let names: Vec<&str> = report.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        names,
        ["lamp"],
        "one group: the lamp (no sky, nothing else)"
    );
    let centre = pixel(world, Vec3::ZERO);
    let on_plate = pixel(world, plate_at);
    let mut shown = Vec::new();
    for w in [1.0, 0.0] {
        app.world_mut()
            .resource_mut::<LightGroupWeights>()
            .set("lamp", w);
        app.world_mut().resource_mut::<FrameCapture>().rearm();
        let frame = support::capture_when_ready(&mut app, |w| w.resource::<GroupSums>().applied());
        shown.push((mean_at(&frame, centre, 2), mean_at(&frame, on_plate, 1)));
    }
    println!(
        "the floor's centre: {:.4} with the lamp's group at weight 1, {:.4} at weight 0; the plate lit by the volume: {:.4}, {:.4}",
        shown[0].0, shown[1].0, shown[0].1, shown[1].1
    );
    assert!(shown[0].0.max_element() > 0.05, "lit: {}", shown[0].0);
    assert!(shown[0].1.max_element() > 0.05, "lit: {}", shown[0].1);
    assert_eq!(shown[1].0, Vec3::ZERO, "weight 0 leaves the lamp out");
    assert_eq!(
        shown[1].1,
        Vec3::ZERO,
        "weight 0 leaves the lamp out of the volume"
    );
}
