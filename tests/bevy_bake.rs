//! Headless ECS tests of the Bevy plugin (no GPU): bake a Bevy world in the app and check
//! the meshes, `Lightmap` components, images and pixel values — against the physics (shadow,
//! colour bleeding) and against the `bake` command run on the same scene.

mod bevy_common;

use lightbake::Stage;
use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use bevy::mesh::VertexAttributeValues;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_common::{headless_app, run_until};
use bevy_lightbake::convert::extract_scene;
use bevy_lightbake::images::texel;
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::Method;
use serde_json::Value;

const TIMEOUT: Duration = Duration::from_secs(600);

/// Preview quality at 64 texels/m: a few seconds per bake in a test build.
fn settings(method: Method) -> BakeSettings {
    {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(64.0);
        s.layout.texel_density_from_scene = false;
        s.method = method;
        s.threads = 1;
        s
    }
}

/// The Cornell box spawned as Bevy entities, baked in the app. Returns the app and the
/// entity of each instance by name.
fn baked_cornell(assets: &Path, light: CornellLight) -> (App, HashMap<String, Entity>) {
    let mut app = headless_app(assets, false);
    app.world_mut().resource_mut::<LightbakeConfig>().settings = settings(Method::Radiosity);
    let scene = cornell_box(light);
    let entities = spawn_scene(app.world_mut(), &scene);
    let names = scene
        .instances
        .iter()
        .map(|i| i.name.clone())
        .zip(entities)
        .collect();
    app.update();
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the bake and its lightmaps", TIMEOUT, |world| {
        let status = world.resource::<BakeStatus>();
        if let BakePhase::Failed(e) = &status.phase {
            panic!("bake failed: {e}");
        }
        let completed = status.completed;
        let mut shown = world.query::<(&Lightmapped, Option<&Lightmap>)>();
        completed == 1 && shown.iter(world).all(|(l, m)| l.is_shown_by(m))
    });
    (app, names)
}

/// Baked E/π at the surface of `entity` nearest `point`.
fn baked_at(world: &World, entity: Entity, point: Vec3) -> Vec3 {
    let mesh = &world.get::<Mesh3d>(entity).unwrap().0;
    let mesh = world.resource::<Assets<Mesh>>().get(mesh).unwrap();
    let lm = world.get::<Lightmap>(entity).unwrap();
    let image = world.resource::<Assets<Image>>().get(&lm.image).unwrap();
    let t = world.get::<GlobalTransform>(entity).unwrap();
    sample_lightmap(mesh, t, lm.uv_rect, image, point).unwrap()
}

#[test]
fn in_app_bake_gives_uvs_lightmaps_shadows_and_bleeding_and_matches_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("assets");
    let (mut app, names) = baked_cornell(&assets, CornellLight::Area);
    let world = app.world_mut();

    // The files are in the assets folder, with a manifest naming every baked entity.
    let out = assets.join("lightbake");
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(manifest["instances"].as_array().unwrap().len(), names.len());

    // Every baked mesh has UV_1 in [0, 1] and a Lightmap matching what the plugin keeps.
    let report = world
        .resource::<BakeStatus>()
        .last_report
        .clone()
        .expect("a report");
    // The progress resource lists every finished stage with its time, rays and estimate.
    let finished = &world.resource::<BakeStatus>().finished_stages;
    assert_eq!(finished.len(), report.stages.len());
    let direct = finished
        .iter()
        .find(|s| s.run.stage == Stage::Direct)
        .expect("direct");
    assert!(direct.rays > 0 && direct.error.as_ref().is_some_and(|e| e.relative_rms > 0.0));
    assert!(report.error.is_some() && report.floor.is_some());
    for (name, &e) in &names {
        let mesh = world
            .resource::<Assets<Mesh>>()
            .get(&world.get::<Mesh3d>(e).unwrap().0)
            .unwrap();
        let Some(VertexAttributeValues::Float32x2(uv1)) = mesh.attribute(Mesh::ATTRIBUTE_UV_1)
        else {
            panic!("{name} has no UV_1");
        };
        assert_eq!(uv1.len(), mesh.count_vertices());
        assert!(
            uv1.iter().flatten().all(|v| (0.0..=1.0).contains(v)),
            "{name}"
        );
        let lm = world
            .get::<Lightmap>(e)
            .unwrap_or_else(|| panic!("{name} has no Lightmap"));
        let kept = world.get::<Lightmapped>(e).unwrap();
        assert_eq!((lm.image.id(), lm.uv_rect), (kept.image.id(), kept.uv_rect));
        assert!(lm.uv_rect.min.cmpge(Vec2::ZERO).all() && lm.uv_rect.max.cmple(Vec2::ONE).all());
        assert!(lm.uv_rect.width() > 0.0 && lm.uv_rect.height() > 0.0);
        let image = world.resource::<Assets<Image>>().get(&lm.image).unwrap();
        assert_eq!(
            image.texture_descriptor.format,
            bevy::render::render_resource::TextureFormat::Rgba16Float
        );
        let entry = manifest["instances"]
            .as_array()
            .unwrap()
            .iter()
            .find(|i| i["name"] == name.as_str())
            .unwrap();
        let page = &manifest["pages"][entry["page"].as_u64().unwrap() as usize];
        assert_eq!(
            (image.width() as u64, image.height() as u64),
            (
                page["width"].as_u64().unwrap(),
                page["height"].as_u64().unwrap()
            ),
            "{name}: image size"
        );
    }

    // In front of the short block the ceiling light is hidden by the block (the line from
    // (0.064, 0, 0.204) to the light's centre enters the block at 0.14 m from the back); the
    // front-left floor sees the light. Cornell coordinates / 1000, centred, +z to the open
    // front.
    let floor = names["floor"];
    let shadowed = baked_at(world, floor, Vec3::new(0.064, 0.0, 0.204));
    let lit = baked_at(world, floor, Vec3::new(-0.15, 0.0, 0.2));
    assert!(lit.x > 0.0);
    assert!(
        shadowed.x < 0.5 * lit.x,
        "in the block's shadow {shadowed} vs open floor {lit}"
    );

    // The floor next to the red wall (x = −0.27) is redder than the middle of the floor.
    let near_red = baked_at(world, floor, Vec3::new(-0.26, 0.0, -0.05));
    let middle = baked_at(world, floor, Vec3::new(0.0, 0.0, -0.05));
    let redness = |v: Vec3| v.x / v.y;
    assert!(
        redness(near_red) > 1.1 * redness(middle),
        "near the red wall {near_red}, middle {middle}"
    );
    let near_green = baked_at(world, floor, Vec3::new(0.26, 0.0, -0.05));
    // The green wall (albedo 0.14, 0.45, 0.09 against the red wall's 0.63, 0.065, 0.05)
    // tints less, but visibly.
    let greenness = |v: Vec3| v.y / v.x;
    assert!(
        greenness(near_green) > 1.02 * greenness(middle)
            && greenness(near_green) > 1.3 * greenness(near_red),
        "green side {near_green}, middle {middle}, red side {near_red}"
    );

    // The `bake` command on the same scene (the world as the plugin reads it, written as
    // glTF) gives the same texels: the core is deterministic whatever the thread count and
    // the plugin adds nothing of its own. The only differences are float roundings of the
    // glTF text (an emissive 5000 × 0.85 stored as factor and strength), so texels agree to a
    // half-float step and nearly all of them bit for bit.
    let mut fresh = headless_app(&dir.path().join("fresh"), false);
    spawn_scene(fresh.world_mut(), &cornell_box(CornellLight::Area));
    fresh.update();
    let (scene, _) = extract_scene(
        fresh.world_mut(),
        "cornell",
        SkySource::GlobalAmbient,
        &mut {
            let mut s = BakeSettings::default();
            s.layout.texel_density = Some(64.0);
            s
        },
    )
    .unwrap();
    let gltf = dir.path().join("cornell.gltf");
    write_scene_gltf(&scene, &gltf).unwrap();
    let cli_out = dir.path().join("cli");
    lightbake_cli::run_from([
        "bake",
        gltf.to_str().unwrap(),
        "-o",
        cli_out.to_str().unwrap(),
        "--quality",
        "preview",
        "--texel-density",
        "64",
        "--threads",
        "2",
        "--quiet",
    ])
    .unwrap();
    let cli_manifest: Value =
        serde_json::from_slice(&std::fs::read(cli_out.join("manifest.json")).unwrap()).unwrap();
    let cli_report: Value =
        serde_json::from_slice(&std::fs::read(cli_out.join("report.json")).unwrap()).unwrap();
    let mut app_settings = serde_json::to_value(&report.settings).unwrap();
    let mut cli_settings = cli_report["settings"].clone();
    app_settings["threads"] = Value::Null;
    cli_settings["threads"] = Value::Null;
    assert_eq!(app_settings, cli_settings, "same settings on both sides");

    let read_exr = |path: &Path| -> (usize, Vec<[f32; 3]>) {
        let img = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
            |(w, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * *w + pos.x()] = [r, g, b]
            },
        )
        .unwrap();
        img.layer_data.channel_data.pixels
    };
    let (mut compared, mut identical) = (0, 0);
    for inst in cli_manifest["instances"].as_array().unwrap() {
        let name = inst["name"].as_str().unwrap();
        let (cw, cli_px) = read_exr(&cli_out.join(inst["image"].as_str().unwrap()));
        let entity = names[name];
        let lm = world.get::<Lightmap>(entity).unwrap();
        let image = world.resource::<Assets<Image>>().get(&lm.image).unwrap();
        let app_entry = manifest["instances"]
            .as_array()
            .unwrap()
            .iter()
            .find(|i| i["name"] == name)
            .unwrap();
        let r = |e: &Value, k: usize| e["rect"][k].as_u64().unwrap() as u32;
        assert_eq!(
            (r(inst, 2), r(inst, 3)),
            (r(app_entry, 2), r(app_entry, 3)),
            "{name}: rect size"
        );
        for y in 0..r(inst, 3) {
            for x in 0..r(inst, 2) {
                let c = cli_px[((r(inst, 1) + y) as usize) * cw + (r(inst, 0) + x) as usize];
                let a = texel(image, r(app_entry, 0) + x, r(app_entry, 1) + y).unwrap();
                for k in 0..3 {
                    let step = 2f32.powi(-10) * c[k].abs().max(2f32.powi(-14));
                    assert!(
                        (a[k] - c[k]).abs() <= step,
                        "{name} texel ({x}, {y}): plugin {a} vs command {c:?}"
                    );
                }
                identical += usize::from(a.to_array() == c);
                compared += 1;
            }
        }
    }
    println!("plugin vs command: {identical} of {compared} texels bit-identical");
    assert!(compared > 1000, "{compared} texels compared");
    assert!(
        identical as f64 > 0.99 * compared as f64,
        "{identical} of {compared} texels bit-identical"
    );
}

#[test]
fn baked_lights_stop_lighting_lightmapped_meshes_and_unit_conversion_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let (mut app, _) = baked_cornell(&dir.path().join("assets"), CornellLight::Point);
    let world = app.world_mut();
    let mut lights = world.query::<(&PointLight, Option<&bevy_lightbake::BakedLight>)>();
    let (light, marker) = lights.single(world).unwrap();
    assert!(marker.is_some());
    assert!(!light.affects_lightmapped_mesh_diffuse);
    // 50 cd in the core scene ↔ 4π·50 lm in Bevy.
    assert!((light.intensity - 4.0 * std::f32::consts::PI * 50.0).abs() < 1e-3);
    let ambient = world.resource::<GlobalAmbientLight>();
    assert!(!ambient.affects_lightmapped_meshes);

    // Core scene → Bevy entities → core scene keeps every number the bake uses.
    let mut fresh = headless_app(&dir.path().join("fresh"), false);
    let original = cornell_box(CornellLight::Point);
    spawn_scene(fresh.world_mut(), &original);
    fresh.update();
    let (back, mapping) = extract_scene(fresh.world_mut(), "x", SkySource::GlobalAmbient, &mut {
        let mut s = BakeSettings::default();
        s.layout.texel_density = Some(64.0);
        s
    })
    .unwrap();
    assert_eq!(back.instances.len(), original.instances.len());
    assert_eq!(mapping.instances.len(), original.instances.len());
    for inst in &back.instances {
        let o = original
            .instances
            .iter()
            .find(|o| o.name == inst.name)
            .unwrap();
        assert_eq!(inst.transform, o.transform, "{}", inst.name);
        let (m, om) = (&back.meshes[inst.mesh], &original.meshes[o.mesh]);
        assert_eq!(
            (&m.positions, &m.normals, &m.indices),
            (&om.positions, &om.normals, &om.indices)
        );
        let (mat, omat) = (back.material_of(inst.mesh), original.material_of(o.mesh));
        assert_eq!(
            (mat.base_color, mat.emissive, mat.metallic),
            (omat.base_color, omat.emissive, omat.metallic)
        );
    }
    // An entity's own density holds when the bake chooses the rest from its texel budget:
    // the base density is fixed over the scene first, and the entity's scale is its own
    // density over that base.
    let floor = fresh
        .world_mut()
        .query::<(Entity, &Name)>()
        .iter(fresh.world())
        .find(|(_, n)| n.as_str() == "floor")
        .map(|(e, _)| e)
        .expect("the Cornell box has a floor");
    fresh
        .world_mut()
        .entity_mut(floor)
        .insert(Lightbaked::with_density(200.0));
    let mut auto = BakeSettings::default();
    assert_eq!(auto.layout.texel_density, None);
    let (scene, _) =
        extract_scene(fresh.world_mut(), "x", SkySource::GlobalAmbient, &mut auto).unwrap();
    let base = auto
        .layout
        .texel_density
        .expect("the base density is fixed");
    assert!(base > 0.0);
    for inst in &scene.instances {
        let want = if inst.name == "floor" {
            200.0 / base
        } else {
            1.0
        };
        assert!(
            (inst.texel_density_scale - want).abs() < 1e-5,
            "{}: scale {} against {want}",
            inst.name,
            inst.texel_density_scale
        );
    }
    let (l, ol) = (&back.lights[0], &original.lights[0]);
    assert!(
        (l.intensity - ol.intensity).abs() < 1e-4 * ol.intensity,
        "{} cd vs {} cd",
        l.intensity,
        ol.intensity
    );
    assert!((l.color - ol.color).abs().max_element() < 1e-6);
    assert!((l.position - ol.position).length() < 1e-6);
    assert!((l.direction - ol.direction).length() < 1e-5);
    // An unbounded core light comes back with a range far beyond the scene.
    let (lo, hi) = original.bounds();
    assert!(l.range.unwrap() >= 9.0 * (hi - lo).length());
    assert_eq!(back.sky, original.sky);
}

#[test]
fn cancel_keeps_nothing_and_a_new_request_restarts() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("assets");
    let mut app = headless_app(&assets, false);
    // A bake long enough to cancel: high quality.
    app.world_mut().resource_mut::<LightbakeConfig>().settings = BakeSettings {
        threads: 1,
        ..BakeSettings::high()
    };
    spawn_scene(app.world_mut(), &cornell_box(CornellLight::Area));
    app.update();
    app.world_mut().write_message(RequestBake::default());
    // The status names the running stage.
    run_until(&mut app, "the bake to start", TIMEOUT, |w| {
        let s = w.resource::<BakeStatus>();
        s.is_running() && s.stage_index > 0 && s.stage.is_some()
    });
    app.world_mut().write_message(CancelBake);
    let mut finished = Vec::new();
    run_until(&mut app, "the cancellation", TIMEOUT, |w| {
        let mut reader = w.resource_mut::<Messages<BakeFinished>>();
        finished.extend(reader.drain().map(|m| m.outcome));
        !finished.is_empty()
    });
    assert_eq!(finished, vec![BakeOutcome::Cancelled]);
    assert_eq!(
        app.world().resource::<BakeStatus>().phase,
        BakePhase::Cancelled
    );
    let world = app.world_mut();
    let mut with_lightmap = world.query_filtered::<(), Or<(With<Lightmap>, With<Lightmapped>)>>();
    assert_eq!(with_lightmap.iter(world).count(), 0);
    assert!(
        !assets.join("lightbake").exists(),
        "a cancelled bake writes nothing"
    );

    // A request while a bake runs cancels it and starts again with the new settings.
    world.resource_mut::<LightbakeConfig>().settings = settings(Method::Direct);
    world.write_message(RequestBake {
        settings: Some(BakeSettings::high()),
        full: false,
    });
    run_until(&mut app, "the second bake to start", TIMEOUT, |w| {
        w.resource::<BakeStatus>().is_running()
    });
    app.world_mut().write_message(RequestBake::default());
    let mut outcomes = Vec::new();
    run_until(&mut app, "the restarted bake", TIMEOUT, |w| {
        outcomes.extend(
            w.resource_mut::<Messages<BakeFinished>>()
                .drain()
                .map(|m| m.outcome),
        );
        outcomes.contains(&BakeOutcome::Baked)
    });
    assert_eq!(outcomes, vec![BakeOutcome::Cancelled, BakeOutcome::Baked]);
    let report = app
        .world()
        .resource::<BakeStatus>()
        .last_report
        .clone()
        .unwrap();
    assert_eq!(
        report.settings.method,
        Method::Direct,
        "the newer request's settings"
    );
}

#[test]
fn bad_meshes_fail_with_the_entity_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = headless_app(&dir.path().join("assets"), false);
    let mesh = app.world_mut().resource_mut::<Assets<Mesh>>().add(
        Mesh::new(bevy::mesh::PrimitiveTopology::LineList, Default::default())
            .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 2]),
    );
    app.world_mut()
        .spawn((Mesh3d(mesh), Lightbaked::default(), Name::new("fence wire")));
    app.world_mut()
        .spawn((PointLight::default(), Transform::from_xyz(0.0, 2.0, 0.0)));
    app.update();
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the failure", TIMEOUT, |w| {
        matches!(w.resource::<BakeStatus>().phase, BakePhase::Failed(_))
    });
    let BakePhase::Failed(message) = &app.world().resource::<BakeStatus>().phase else {
        unreachable!()
    };
    assert!(
        message.contains("fence wire") && message.contains("triangle lists"),
        "{message}"
    );
}

#[test]
fn rebake_at_another_size_replaces_lightmaps_and_the_toggle_shows_real_time_light() {
    let dir = tempfile::tempdir().unwrap();
    let (mut app, names) = baked_cornell(&dir.path().join("assets"), CornellLight::Point);
    let floor = names["floor"];
    let size_of = |world: &World| {
        let lm = world.get::<Lightmap>(floor)?;
        world
            .resource::<Assets<Image>>()
            .get(&lm.image)
            .map(|i| i.size())
    };
    let first = size_of(app.world()).unwrap();

    // Twice the density: the bake reads the meshes as they were before the first bake gave
    // them UV_1 (`rebake::UnwrappedMeshes`) and unwraps them for the new density, the page
    // grows, and the plugin re-inserts every `Lightmap` (Bevy ignores an image that changes
    // size under an existing one).
    let mut removed = 0;
    app.world_mut().resource_mut::<LightbakeConfig>().settings = {
        let mut s = settings(Method::Direct);
        s.layout.texel_density = Some(128.0);
        s
    };
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the re-bake", TIMEOUT, |w| {
        if w.get::<Lightmap>(floor).is_none() {
            removed += 1;
        }
        w.resource::<BakeStatus>().completed == 2
            && size_of(w).is_some_and(|s| s != first)
            && w.get::<Lightmap>(floor).is_some()
    });
    let second = size_of(app.world()).unwrap();
    assert!(second.x > first.x, "{first} → {second}");
    assert!(removed > 0, "the Lightmap was removed and inserted again");
    let report = app
        .world()
        .resource::<BakeStatus>()
        .last_report
        .clone()
        .unwrap();
    let meshes = report.plan.meshes_to_unwrap;
    assert!(
        meshes > 0,
        "the second bake at another density unwraps the meshes as they were: {meshes}"
    );
    let inc = report.incremental.as_ref().expect("an incremental report");
    assert!(
        inc.full
            .as_ref()
            .is_some_and(|why| why.contains("settings")),
        "another density is a full bake: {inc:?}"
    );

    // Real-time lighting: every plugin-managed Lightmap goes, and comes back.
    let count = |app: &mut App| {
        let world = app.world_mut();
        let mut q = world.query_filtered::<(), With<Lightmap>>();
        q.iter(world).count()
    };
    app.world_mut().resource_mut::<ShowLightmaps>().0 = false;
    app.update();
    assert_eq!(count(&mut app), 0);
    app.world_mut().resource_mut::<ShowLightmaps>().0 = true;
    run_until(&mut app, "the lightmaps to return", TIMEOUT, |w| {
        w.get::<Lightmap>(floor).is_some()
    });
    assert_eq!(count(&mut app), names.len());

    // A mesh that stops receiving a lightmap loses it at the next bake (it still casts shadows).
    app.world_mut()
        .get_mut::<Lightbaked>(floor)
        .unwrap()
        .receive_lightmap = false;
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the third bake", TIMEOUT, |w| {
        w.resource::<BakeStatus>().completed == 3
    });
    app.update();
    assert!(app.world().get::<Lightmapped>(floor).is_none());
    assert!(app.world().get::<Lightmap>(floor).is_none());
    assert_eq!(count(&mut app), names.len() - 1);
}

/// A bake in the app takes the light groups of emissive meshes from their [`LightGroup`]
/// components and the sky's from [`LightbakeConfig::sky_group`]: the Cornell box's ceiling
/// panel in `panel` and the sky (coming in at its open front) in `outside`. Two more meshes
/// with the panel's material, one in another group and one in none, are warned of: their
/// light is in `panel` too.
#[test]
fn an_in_app_bake_groups_emissive_meshes_and_the_sky() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = headless_app(dir.path(), false);
    let world = app.world_mut();
    {
        let mut config = world.resource_mut::<LightbakeConfig>();
        config.settings = settings(Method::Radiosity);
        config.sky_group = Some("outside".into());
    }
    let scene = cornell_box(CornellLight::Area);
    let entities = spawn_scene(world, &scene);
    world.insert_resource(GlobalAmbientLight {
        color: Color::WHITE,
        brightness: 20.0,
        ..default()
    });
    let i = scene
        .instances
        .iter()
        .position(|i| i.name == "light")
        .unwrap();
    let panel = entities[i];
    world.entity_mut(panel).insert(LightGroup("panel".into()));
    let (mesh, material) = (
        world.get::<Mesh3d>(panel).unwrap().clone(),
        (world.get::<MeshMaterial3d<StandardMaterial>>(panel))
            .unwrap()
            .clone(),
    );
    world.spawn((
        mesh.clone(),
        material.clone(),
        Transform::from_xyz(0.0, 0.2, 0.0),
        Lightbaked::default(),
        LightGroup("other".into()),
        Name::new("second panel"),
    ));
    world.spawn((
        mesh,
        material,
        Transform::from_xyz(0.0, 0.3, 0.0),
        Lightbaked::default(),
        Name::new("third panel"),
    ));
    app.update();
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the bake", TIMEOUT, |world| {
        let status = world.resource::<BakeStatus>();
        if let BakePhase::Failed(e) = &status.phase {
            panic!("bake failed: {e}");
        }
        status.completed == 1
    });
    let report = (app.world().resource::<BakeStatus>().last_report.clone()).unwrap();
    let groups: Vec<(&str, &[String])> = (report.groups.iter())
        .map(|g| (g.name.as_str(), g.members.as_slice()))
        .collect();
    println!("{groups:?}");
    assert_eq!(groups.len(), 2, "{groups:?}");
    assert_eq!(groups[0].0, "panel");
    assert!(
        groups[0].1.len() == 1 && groups[0].1[0].starts_with("material unnamed "),
        "a material made in code is named by its place: {groups:?}"
    );
    assert_eq!(groups[1], ("outside", &["sky".to_string()][..]));
    for (who, own) in [
        ("second panel:", "to put it in 'other'"),
        ("third panel:", "to keep it ungrouped"),
    ] {
        assert!(
            (report.warnings.iter()).any(|w| w.starts_with(who)
                && w.contains("in light group 'panel'")
                && w.contains(own)),
            "{:?}",
            report.warnings
        );
    }
}
