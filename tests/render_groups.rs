//! Light groups drawn by Bevy's renderer (software Vulkan, Mesa lavapipe): the shipped sunlit
//! room baked by the core with its sun in group `sun` and its sky in `ungrouped`, loaded as a
//! baked glTF. At each set of [`LightGroupWeights`] the plugin's GPU pass sums the group pages
//! in the frame the weights change, and the floor, in the sun and in the shade, renders as its
//! albedo times the weighted sum of the group pages there (sampled on the CPU) within 1%.
//! Skips when no Vulkan driver is installed (fails instead with
//! `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use std::path::Path;

use bevy::camera::Exposure;
use bevy::diagnostic::FrameCount;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::groups::{GltfPage, GroupSums};
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;
use lightbake::settings::LightGroup as GroupSetting;
use render_common::{mean_at, pixel};

const W: u32 = 320;
const H: u32 = 240;

/// Bakes the shipped sunlit room with its sun in group `sun` into `out`.
fn bake_groups(out: &Path) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sunlit_room.gltf");
    let imported =
        lightbake::import_gltf(&path, lightbake::LightConvention::GltfSpec).expect("the room");
    let mut settings = BakeSettings::preview();
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

/// The floor's mesh entity (the child of the node named `floor`), its page and its albedo.
fn floor(world: &mut World) -> Option<(Entity, GltfPage, Vec3)> {
    let mut q = world.query::<(
        Entity,
        &GltfPage,
        &ChildOf,
        &MeshMaterial3d<StandardMaterial>,
    )>();
    let (entity, page, parent, material) = q.iter(world).find(|(_, _, p, _)| {
        world
            .get::<Name>(p.parent())
            .is_some_and(|n| n.as_str() == "floor")
    })?;
    let _ = parent;
    let c = world
        .resource::<Assets<StandardMaterial>>()
        .get(&material.0)?
        .base_color
        .to_linear();
    Some((entity, page.clone(), Vec3::new(c.red, c.green, c.blue)))
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

/// The mean of `weighted_at` over the floor points the (2r + 1)² pixels around `(x, y)` see:
/// what `mean_at` reads of the picture, texel noise and all.
fn weighted_mean_at(
    world: &mut World,
    (entity, page): (Entity, &GltfPage),
    (x, y): (u32, u32),
    r: u32,
) -> Vec3 {
    let mut q = world.query::<(&Camera, &GlobalTransform)>();
    let (camera, t) = q.single(world).unwrap();
    let (camera, t) = (camera.clone(), *t);
    let mut sum = Vec3::ZERO;
    for py in y - r..=y + r {
        for px in x - r..=x + r {
            let ray = camera
                .viewport_to_world(&t, Vec2::new(px as f32 + 0.5, py as f32 + 0.5))
                .unwrap();
            let along = -ray.origin.y / ray.direction.y;
            sum += weighted_at(world, entity, page, ray.origin + along * *ray.direction);
        }
    }
    sum / ((2 * r + 1) * (2 * r + 1)) as f32
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
    let camera = world
        .spawn((
            render_common::test_camera(
                target,
                Transform::from_xyz(-0.9, 2.9, -0.7)
                    .looking_at(Vec3::new(-0.9, 0.0, -0.7), Vec3::NEG_Z),
                Exposure::default().ev100,
            ),
            Projection::Perspective(PerspectiveProjection {
                fov: 100f32.to_radians(),
                ..default()
            }),
        ))
        .id();
    // Until the sum is on the GPU and shown.
    let (floor, page, albedo) = loop {
        app.update();
        let world = app.world_mut();
        let Some(found) = floor(world) else {
            continue;
        };
        let sums = world.resource::<GroupSums>();
        let shown = sums
            .target(&found.1)
            .is_some_and(|t| world.get::<Lightmapped>(found.0).unwrap().image == *t);
        if sums.applied() && shown {
            break found;
        }
    };
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
    for (k, weights) in [(1.0, 1.0), (0.0, 1.0), (0.5, 2.0), (3.0, 0.0)]
        .iter()
        .enumerate()
    {
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
            let expected = albedo * weighted_mean_at(world, (floor, &page), at, 2);
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
}

/// A bake in the app with the Cornell box's lamp in a group (a [`LightGroup`] component):
/// its meshes show the group's sum, and weight 0 leaves the lamp's light out entirely.
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
    world.resource_mut::<LightbakeConfig>().settings = BakeSettings::preview();
    let entities = bevy_lightbake::spawn::spawn_scene(world, &scene);
    let floor = render_common::instance_entity(&scene, &entities, "floor");
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
        sums.applied()
            && page.is_some_and(|p| sums.shows_sum(p, world.get::<Lightmapped>(floor).unwrap()))
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
    let mut shown = Vec::new();
    for w in [1.0, 0.0] {
        app.world_mut()
            .resource_mut::<LightGroupWeights>()
            .set("lamp", w);
        app.world_mut().resource_mut::<FrameCapture>().rearm();
        let frame = support::capture_when_ready(&mut app, |w| w.resource::<GroupSums>().applied());
        shown.push(mean_at(&frame, centre, 2));
    }
    println!(
        "the floor's centre: {:.4} with the lamp's group at weight 1, {:.4} at weight 0",
        shown[0], shown[1]
    );
    assert!(shown[0].max_element() > 0.05, "lit: {}", shown[0]);
    assert_eq!(shown[1], Vec3::ZERO, "weight 0 leaves the lamp out");
}
