//! Headless ECS tests (no GPU) of what the plugin shows while and after it bakes: the
//! progressive previews (direct light, then coarse indirect light, then the result), a
//! cancelled bake putting the previous lightmaps back, the irradiance volume of an in-app bake,
//! and lights baked indirect only (mixed lighting, `RectLight`).

mod bevy_common;

use std::time::Duration;

use bevy::light::{GlobalAmbientLight, IrradianceVolume, LightProbe, RectLight};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::render::render_resource::TextureDimension;
use bevy_common::{headless_app, run_until};
use bevy_lightbake::BakedLight;
use bevy_lightbake::convert::extract_scene;
use bevy_lightbake::images::texel;
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::scene::{LightBake, LightKind};
use lightbake::settings::Method;

const TIMEOUT: Duration = Duration::from_secs(600);

/// Mean luminance over every texel of the images the baked entities show (each image once),
/// and whether all are finite.
fn shown_mean(world: &mut World) -> (f64, bool) {
    let mut q = world.query::<&Lightmapped>();
    let mut handles: Vec<Handle<Image>> = q.iter(world).map(|l| l.image.clone()).collect();
    handles.sort_by_key(|h| h.id());
    handles.dedup();
    let images = world.resource::<Assets<Image>>();
    let (mut sum, mut n, mut finite) = (0.0f64, 0usize, true);
    for h in &handles {
        let Some(image) = images.get(h) else {
            return (f64::NAN, false);
        };
        for y in 0..image.height() {
            for x in 0..image.width() {
                let t = texel(image, x, y).unwrap_or(Vec3::NAN);
                finite &= t.is_finite();
                sum += (0.2126 * t.x + 0.7152 * t.y + 0.0722 * t.z) as f64;
                n += 1;
            }
        }
    }
    (sum / n.max(1) as f64, finite)
}

#[test]
fn previews_show_direct_then_indirect_light_then_the_result_brightening() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = headless_app(&dir.path().join("assets"), false);
    // The scene's own 256 texels/m: the hierarchical solve, whose coarse level is previewed
    // well before its final gather ends.
    app.world_mut().resource_mut::<LightbakeConfig>().settings = BakeSettings {
        threads: 1,
        ..BakeSettings::preview()
    };
    spawn_scene(app.world_mut(), &cornell_box(CornellLight::Area));
    app.update();
    app.world_mut().write_message(RequestBake::default());
    let mut seen: Vec<(PreviewKind, f64, bool)> = Vec::new();
    run_until(&mut app, "the bake with its previews", TIMEOUT, |w| {
        let status = w.resource::<BakeStatus>();
        if let BakePhase::Failed(e) = &status.phase {
            panic!("bake failed: {e}");
        }
        let (preview, done) = (status.preview, status.completed == 1);
        // Every entity shows the image the plugin keeps for it, and it is loaded.
        let mut shown = w.query::<(&Lightmapped, Option<&Lightmap>)>();
        let settled = shown.iter(w).all(|(kept, lm)| {
            lm.is_some_and(|lm| lm.image == kept.image)
                && w.resource::<Assets<Image>>().get(&kept.image).is_some()
        });
        if let Some(kind) = preview
            && seen.last().is_none_or(|s| s.0 != kind)
            && (kind != PreviewKind::Final || settled)
        {
            let (mean, finite) = shown_mean(w);
            if mean.is_finite() || !finite {
                seen.push((kind, mean, finite));
            }
        }
        done && settled && seen.last().is_some_and(|s| s.0 == PreviewKind::Final)
    });
    println!("previews shown: {seen:?}");
    let kinds: Vec<PreviewKind> = seen.iter().map(|s| s.0).collect();
    assert_eq!(
        kinds,
        [
            PreviewKind::Direct,
            PreviewKind::Indirect,
            PreviewKind::Final
        ]
    );
    assert!(seen.iter().all(|s| s.2), "every image shown is finite");
    let (direct, indirect, last) = (seen[0].1, seen[1].1, seen[2].1);
    assert!(direct < indirect, "{direct} then {indirect}");
    assert!(indirect <= 1.05 * last, "{indirect} overshoots {last}");
    assert!((indirect - last).abs() < (last - direct).abs());
}

#[test]
fn a_bake_cancelled_after_its_first_preview_puts_the_previous_lightmaps_back() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = headless_app(&dir.path().join("assets"), false);
    let quick = {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(48.0);
        s.layout.texel_density_from_scene = false;
        s.method = Method::Direct;
        s.threads = 1;
        s
    };
    app.world_mut().resource_mut::<LightbakeConfig>().settings = quick;
    spawn_scene(app.world_mut(), &cornell_box(CornellLight::Point));
    app.update();
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the first bake", TIMEOUT, |w| {
        w.resource::<BakeStatus>().completed == 1
    });
    let world = app.world_mut();
    let mut q = world.query::<(Entity, &Lightmapped, &Mesh3d)>();
    let mut before: Vec<(Entity, Lightmapped, AssetId<Mesh>)> = q
        .iter(world)
        .map(|(e, l, m)| (e, l.clone(), m.id()))
        .collect();
    before.sort_by_key(|b| b.0);
    let uv1_before = |world: &World, id: AssetId<Mesh>| {
        world
            .resource::<Assets<Mesh>>()
            .get(id)
            .and_then(|m| m.attribute(Mesh::ATTRIBUTE_UV_1).cloned())
            .map(|a| format!("{a:?}"))
    };
    let uv1: Vec<Option<String>> = before.iter().map(|b| uv1_before(world, b.2)).collect();

    // A long bake at another density: cancelled once its first preview shows.
    world.write_message(RequestBake {
        settings: Some({
            let mut s = BakeSettings::high();
            s.layout.texel_density = Some(200.0);
            s.threads = 1;
            s
        }),
        full: false,
    });
    run_until(&mut app, "the first preview", TIMEOUT, |w| {
        w.resource::<BakeStatus>().preview == Some(PreviewKind::Direct)
    });
    let world = app.world_mut();
    let mut q = world.query::<&Lightmapped>();
    assert!(
        q.iter(world)
            .all(|l| !before.iter().any(|b| b.1.image == l.image)),
        "the preview is shown"
    );
    world.write_message(CancelBake);
    run_until(&mut app, "the cancellation", TIMEOUT, |w| {
        w.resource::<BakeStatus>().phase == BakePhase::Cancelled
    });
    let world = app.world_mut();
    assert_eq!(world.resource::<BakeStatus>().preview, None);
    let mut q = world.query::<(Entity, &Lightmapped, &Mesh3d)>();
    let mut after: Vec<(Entity, Lightmapped, AssetId<Mesh>)> = q
        .iter(world)
        .map(|(e, l, m)| (e, l.clone(), m.id()))
        .collect();
    after.sort_by_key(|b| b.0);
    assert_eq!(before, after, "the previous lightmaps are back");
    let uv1_after: Vec<Option<String>> = after.iter().map(|b| uv1_before(world, b.2)).collect();
    assert_eq!(uv1, uv1_after, "and the meshes' UV_1 with them");
}

#[test]
fn an_in_app_bake_spawns_its_irradiance_volume_and_keeps_indirect_only_lights_real_time() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("assets");
    let mut app = headless_app(&assets, false);
    app.world_mut().resource_mut::<LightbakeConfig>().settings = {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(48.0);
        s.layout.texel_density_from_scene = false;
        s.volume.enabled = true;
        s.volume.probe_rays = 64;
        s.threads = 1;
        s
    };
    spawn_scene(app.world_mut(), &cornell_box(CornellLight::Point));
    // A sky through the box's open front, from the ambient light.
    app.insert_resource(GlobalAmbientLight {
        color: Color::WHITE,
        brightness: 50.0,
        ..default()
    });
    let world = app.world_mut();
    let mut lights = world.query_filtered::<Entity, With<PointLight>>();
    let lamp = lights.single(world).unwrap();
    world.entity_mut(lamp).insert(BakeMode::IndirectOnly);
    app.update();
    app.world_mut().write_message(RequestBake::default());
    run_until(&mut app, "the bake and its volume", TIMEOUT, |w| {
        let mut volumes = w.query::<&IrradianceVolume>();
        let loaded = volumes
            .iter(w)
            .next()
            .is_some_and(|v| w.resource::<Assets<Image>>().get(&v.voxels).is_some());
        w.resource::<BakeStatus>().completed == 1 && loaded
    });
    let world = app.world_mut();
    let report = world.resource::<BakeStatus>().last_report.clone().unwrap();
    let [stats] = &report.irradiance_volumes[..] else {
        panic!("one volume: {:?}", report.irradiance_volumes);
    };
    let stats = stats.clone();
    let mut q = world.query::<(&IrradianceVolume, &LightProbe, &Transform, &BakedVolume)>();
    let (volume, _, transform, baked) = q.single(world).unwrap();
    assert!(!volume.affects_lightmapped_meshes && volume.intensity == 1.0);
    assert!(
        baked.carries_ambient,
        "the sky came from GlobalAmbientLight"
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(assets.join("lightbake/manifest.json")).unwrap())
            .unwrap();
    let entry = &manifest["irradiance_volumes"][0];
    assert_eq!(entry["image"], "irradiance_volumes/volume_0.ktx2");
    assert!((transform.scale.x - entry["size"][0].as_f64().unwrap() as f32).abs() < 1e-6);
    assert!((transform.translation.y - entry["center"][1].as_f64().unwrap() as f32).abs() < 1e-6);
    let image = world
        .resource::<Assets<Image>>()
        .get(&volume.voxels)
        .unwrap();
    assert_eq!(image.texture_descriptor.dimension, TextureDimension::D3);
    let r = stats.resolution;
    let size = image.texture_descriptor.size;
    assert_eq!(
        (size.width, size.height, size.depth_or_array_layers),
        (r[0], 2 * r[1], 3 * r[2])
    );
    // The indirect-only lamp stays real time on lightmapped meshes.
    let (light, marker) = world
        .query::<(&PointLight, Option<&BakedLight>)>()
        .get(world, lamp)
        .unwrap();
    assert!(light.affects_lightmapped_mesh_diffuse && marker.is_none());
    assert!(report.plan.describe().contains("indirect only"));
    // While the volume is shown the ambient light (whose sky it carries) is dark; hiding the
    // lightmaps hides the volume and gives it back.
    app.update();
    let ambient = app.world().resource::<GlobalAmbientLight>().brightness;
    app.insert_resource(ShowLightmaps(false));
    app.update();
    let world = app.world_mut();
    let restored = world.resource::<GlobalAmbientLight>().brightness;
    let mut q = world.query_filtered::<&Visibility, With<BakedVolume>>();
    assert_eq!(*q.single(world).unwrap(), Visibility::Hidden);
    assert_eq!((ambient, restored), (0.0, 50.0));
}

#[test]
fn rect_lights_bake_as_area_lights_indirect_only_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = headless_app(&dir.path().join("assets"), false);
    let world = app.world_mut();
    let intensity = 2000.0;
    world.spawn((
        RectLight {
            intensity,
            width: 0.5,
            height: 0.25,
            ..default()
        },
        Transform::from_xyz(0.0, 2.0, 0.0).looking_to(Vec3::NEG_Y, Vec3::Z),
        Name::new("panel"),
    ));
    world.spawn((
        RectLight {
            intensity,
            width: 0.5,
            height: 0.25,
            ..default()
        },
        Transform::from_xyz(1.0, 2.0, 0.0)
            .looking_to(Vec3::NEG_Y, Vec3::Z)
            .with_scale(Vec3::new(2.0, 1.0, 1.0)),
        Name::new("wide panel"),
        BakeMode::Full,
    ));
    spawn_scene(world, &cornell_box(CornellLight::Area));
    app.update();
    let (scene, mapping) = extract_scene(app.world_mut(), "x", SkySource::None, &mut {
        let mut s = BakeSettings::default();
        s.layout.texel_density = Some(32.0);
        s
    })
    .unwrap();
    let panel = scene.lights.iter().find(|l| l.name == "panel").unwrap();
    let LightKind::Rect {
        right,
        width,
        height,
    } = panel.kind
    else {
        panic!("{:?}", panel.kind);
    };
    assert!((width - 0.5).abs() < 1e-6 && (height - 0.25).abs() < 1e-6);
    assert!((panel.direction - glam::Vec3::NEG_Y).length() < 1e-6);
    assert!(right.dot(panel.direction).abs() < 1e-6);
    // Bevy's own conversion: L = Φ / (π·w·h).
    let expected = intensity / (std::f32::consts::PI * 0.5 * 0.25);
    assert!((panel.intensity - expected).abs() < 1e-3 * expected);
    assert_eq!(panel.bake, LightBake::IndirectOnly);
    let wide = scene
        .lights
        .iter()
        .find(|l| l.name == "wide panel")
        .unwrap();
    assert!(matches!(wide.kind, LightKind::Rect { width, .. } if (width - 1.0).abs() < 1e-5));
    assert_eq!(wide.bake, LightBake::Full);
    assert!(scene.warnings.iter().any(|w| w.contains("wide panel")));
    assert_eq!(mapping.realtime_lights.len(), 1);
    panel.validate().unwrap();
}
