//! A glTF baked by the `bake` command, loaded into a headless Bevy app (no GPU): its meshes get
//! their lightmaps and its lights stop lighting them twice; when the command rewrites the
//! lightmaps the running app reloads them (Bevy's file watcher), and `AssetServer::reload`
//! does the same on demand. Its irradiance volume spawns with the scene and reloads the same
//! way.

mod bevy_common;

use std::path::Path;
use std::time::{Duration, Instant};

use bevy::ecs::message::MessageCursor;
use bevy::light::IrradianceVolume;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_common::{headless_app, run_until};
use bevy_lightbake::BakedLight;
use bevy_lightbake::images::texel;
use serde_json::Value;

const TIMEOUT: Duration = Duration::from_secs(300);

fn bake(out: &Path, method: &str) {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box_point.gltf");
    lightbake_cli::run_from([
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--quality",
        "preview",
        "--texel-density",
        "48",
        "--method",
        method,
        "--light-convention",
        "bevy",
        "--quiet",
    ])
    .unwrap();
}

fn read_exr(path: &Path) -> (usize, Vec<[f32; 3]>) {
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
        |(w, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b],
    )
    .unwrap();
    img.layer_data.channel_data.pixels
}

/// Whether the image behind `handle` holds exactly the EXR's texels.
fn image_matches(world: &World, handle: &Handle<Image>, exr: &(usize, Vec<[f32; 3]>)) -> bool {
    let Some(image) = world.resource::<Assets<Image>>().get(handle) else {
        return false;
    };
    let (w, px) = exr;
    if image.width() as usize != *w {
        return false;
    }
    px.iter().enumerate().all(|(i, c)| {
        texel(image, (i % w) as u32, (i / w) as u32).is_some_and(|t| t.to_array() == *c)
    })
}

fn lightmapped_count(world: &mut World) -> usize {
    let mut q = world.query_filtered::<(), With<Lightmap>>();
    q.iter(world).count()
}

#[test]
fn baked_gltf_gets_lightmaps_and_hot_reloads_when_rebaked() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("assets");
    let out = assets.join("baked");
    bake(&out, "direct");
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let instances = manifest["instances"].as_array().unwrap().len();
    let image_file = out.join(manifest["pages"][0]["exr"].as_str().unwrap());
    let first = read_exr(&image_file);

    let mut app = headless_app(&assets, true);
    let server = app.world().resource::<AssetServer>().clone();
    app.world_mut().spawn(WorldAssetRoot(
        server.load(GltfAssetLabel::Scene(0).from_asset("baked/cornell_box_point.gltf")),
    ));
    run_until(&mut app, "lightmaps on every baked mesh", TIMEOUT, |w| {
        lightmapped_count(w) == instances
    });

    // The lightmaps are the files the command wrote, and the glTF's light is marked baked.
    let world = app.world_mut();
    let mut q = world.query::<&Lightmap>();
    let handle = q.iter(world).next().unwrap().image.clone();
    assert!(image_matches(world, &handle, &first));
    let mut lights = world.query::<(&PointLight, Option<&BakedLight>)>();
    let (light, baked) = lights.single(world).unwrap();
    assert!(baked.is_some() && !light.affects_lightmapped_mesh_diffuse);

    // Re-bake with other settings into the same folder while the app runs: the watcher sees
    // the renamed files and the image changes in place (same size, new pixels).
    let mut cursor = MessageCursor::<AssetEvent<Image>>::default();
    cursor
        .read(world.resource::<Messages<AssetEvent<Image>>>())
        .for_each(drop);
    bake(&out, "radiosity");
    let second = read_exr(&image_file);
    assert_ne!(first.1, second.1, "radiosity adds indirect light");
    let written = Instant::now();
    run_until(&mut app, "the file watcher's reload", TIMEOUT, |w| {
        // The reload replaces the asset and announces it in the same update.
        let events = w.resource::<Messages<AssetEvent<Image>>>();
        let modified = cursor
            .read(events)
            .any(|e| *e == AssetEvent::Modified { id: handle.id() });
        modified && image_matches(w, &handle, &second)
    });
    println!(
        "hot reload: new pixels and AssetEvent::Modified {:.0} ms after the files were renamed into place",
        written.elapsed().as_secs_f64() * 1e3
    );
    // The command also rewrote the glTF, so the scene respawns; its meshes get lightmaps again.
    run_until(&mut app, "lightmaps after the respawn", TIMEOUT, |w| {
        lightmapped_count(w) == instances
    });

    // Without a watcher, `AssetServer::reload` picks up a rewrite on demand.
    let mut quiet = headless_app(&assets, false);
    let server = quiet.world().resource::<AssetServer>().clone();
    let image: Handle<Image> = server.load("baked/lightmaps/lightmap_0.exr");
    run_until(&mut quiet, "the lightmap to load", TIMEOUT, |w| {
        image_matches(w, &image, &second)
    });
    bake(&out, "direct");
    server.reload("baked/lightmaps/lightmap_0.exr");
    run_until(&mut quiet, "the explicit reload", TIMEOUT, |w| {
        image_matches(w, &image, &first)
    });
}

#[test]
fn baked_gltf_spawns_its_irradiance_volume_keeps_indirect_only_lights_and_reloads_it() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("assets");
    let out = assets.join("baked");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/cornell_box_point.gltf");
    let bake_with = |method: &str| {
        lightbake_cli::run_from([
            "bake",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--quality",
            "preview",
            "--texel-density",
            "48",
            "--method",
            method,
            "--irradiance-volume",
            "--probe-rays",
            "64",
            "--indirect-only",
            "ceiling_point",
            "--quiet",
        ])
        .unwrap();
    };
    bake_with("radiosity");
    let manifest: Value =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    let entry = manifest["irradiance_volumes"][0].clone();
    assert_eq!(entry["image"], "irradiance_volumes/volume_0.ktx2");

    let mut app = headless_app(&assets, true);
    let server = app.world().resource::<AssetServer>().clone();
    app.world_mut().spawn(WorldAssetRoot(
        server.load(GltfAssetLabel::Scene(0).from_asset("baked/cornell_box_point.gltf")),
    ));
    let loaded = |w: &mut World| {
        let mut q = w.query::<(&IrradianceVolume, &GlobalTransform)>();
        let found = q.iter(w).next().map(|(v, t)| (v.voxels.clone(), *t));
        found.filter(|(h, _)| w.resource::<Assets<Image>>().get(h).is_some())
    };
    run_until(&mut app, "the volume and its image", TIMEOUT, |w| {
        loaded(w).is_some()
    });
    let world = app.world_mut();
    let (handle, transform) = loaded(world).unwrap();
    let centre: Vec<f32> = (0..3)
        .map(|k| entry["center"][k].as_f64().unwrap() as f32)
        .collect();
    let size: Vec<f32> = (0..3)
        .map(|k| entry["size"][k].as_f64().unwrap() as f32)
        .collect();
    assert!((transform.translation() - Vec3::from_slice(&centre)).length() < 1e-5);
    assert!((transform.scale() - Vec3::from_slice(&size)).length() < 1e-5);
    let image = world.resource::<Assets<Image>>().get(&handle).unwrap();
    let r: Vec<u32> = (0..3)
        .map(|k| entry["resolution"][k].as_u64().unwrap() as u32)
        .collect();
    let extent = image.texture_descriptor.size;
    assert_eq!(
        (extent.width, extent.height, extent.depth_or_array_layers),
        (r[0], 2 * r[1], 3 * r[2])
    );
    assert_eq!(
        image.texture_descriptor.dimension,
        bevy::render::render_resource::TextureDimension::D3
    );
    // The light baked indirect only stays real time on the lightmapped meshes.
    let mut lights = world.query::<(&PointLight, Option<&BakedLight>)>();
    let (light, baked) = lights.single(world).unwrap();
    assert!(baked.is_none() && light.affects_lightmapped_mesh_diffuse);

    // Re-baking into the folder reloads the volume's image in the running app.
    let mut cursor = MessageCursor::<AssetEvent<Image>>::default();
    cursor
        .read(world.resource::<Messages<AssetEvent<Image>>>())
        .for_each(drop);
    let before = std::fs::read(out.join("irradiance_volumes/volume_0.ktx2")).unwrap();
    bake_with("direct");
    let after = std::fs::read(out.join("irradiance_volumes/volume_0.ktx2")).unwrap();
    assert_ne!(
        before, after,
        "without interreflection the volume is darker"
    );
    run_until(&mut app, "the volume's reload", TIMEOUT, |w| {
        let events = w.resource::<Messages<AssetEvent<Image>>>();
        cursor
            .read(events)
            .any(|e| matches!(e, AssetEvent::Modified { id } if *id == handle.id()))
    });
}
