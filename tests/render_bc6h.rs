//! BC6H pages drawn by Bevy's renderer (software Vulkan, Mesa lavapipe): the shipped sunlit
//! room baked by the core with EXR and BC6H pages, loaded as a baked glTF. Where the GPU
//! samples BC textures the plugin loads the BC6H pages (`LightbakeConfig::bc6h`), else the EXR
//! ones; the floor, in the sun and in the shade, renders as its albedo times the page it
//! loaded (the file decoded on the CPU) within 1%. With light groups, the groups' BC6H pages
//! are the ones summed. An in-app bake writing BC6H pages shows them too, once read from
//! its files. Skips when no Vulkan driver is installed (fails instead with
//! `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use std::path::Path;

use bevy::camera::Exposure;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy::render::renderer::RenderDevice;
use bevy_lightbake::capture::FrameCapture;
use bevy_lightbake::groups::{GltfPage, GroupSums};
use bevy_lightbake::images::{loads_bc6h, page_image};
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::lightmap::LightmapPage;
use lightbake::scene::testscenes::{CORNELL_WHITE, CornellLight, cornell_box};
use lightbake::settings::LightGroup as GroupSetting;
use render_common::{gltf_floor, mean_at, mean_over_floor, pixel};

const W: u32 = 320;
const H: u32 = 240;

/// Bakes the shipped sunlit room with EXR and BC6H pages (its sun in group `sun` when
/// `groups`) into `out`.
fn bake(out: &Path, groups: bool) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/sunlit_room.gltf");
    let imported =
        lightbake::import_gltf(&path, lightbake::LightConvention::GltfSpec).expect("the room");
    let mut settings = BakeSettings::preview();
    settings.formats.ktx2_bc6h = true;
    if groups {
        settings.groups = vec![GroupSetting {
            name: "sun".into(),
            members: vec!["sun".into()],
        }];
    }
    let baked =
        lightbake::bake(&imported.scene, &settings, &lightbake::Progress::new()).expect("the bake");
    lightbake::write_outputs(
        out,
        &baked,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .expect("written");
}

/// A page file decoded on the CPU, as the image Bevy would hold.
fn decoded(file: &Path) -> Image {
    let name = file.to_string_lossy();
    let page = if name.ends_with(".bc6h.ktx2") {
        let bytes = std::fs::read(file).unwrap();
        let (w, h, texels) = lightbake::output::bc6h::decode_ktx2_bc6h(&bytes).unwrap();
        let mut page = LightmapPage::black(w, h);
        page.texels = texels;
        page
    } else {
        let exr = exr::prelude::read_first_rgba_layer_from_file(
            file,
            |res, _| LightmapPage::black(res.width() as u32, res.height() as u32),
            |page: &mut LightmapPage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = pos.y() * page.width as usize + pos.x();
                page.texels[i] = glam::Vec3::new(r, g, b);
            },
        )
        .unwrap();
        exr.layer_data.channel_data.pixels
    };
    page_image(&page)
}

/// The EXR page beside a BC6H page file (the same file when it is one).
fn exr_beside(file: &Path) -> std::path::PathBuf {
    let name = file.file_name().unwrap().to_string_lossy();
    file.with_file_name(name.replace(".bc6h.ktx2", ".exr"))
}

/// The relative difference between the floor rendered at `at` and `expected` (albedo × the
/// page there, E/π), the exposure putting it at about a third of white.
fn rendered_against(app: &mut App, camera: Entity, spot: Vec3, expected: Vec3) -> f32 {
    let ev100 = (expected.max_element() / (0.33 * 1.2)).log2();
    let world = app.world_mut();
    world.entity_mut(camera).insert(Exposure { ev100 });
    world.resource_mut::<FrameCapture>().rearm();
    let frame = support::capture_when_ready(app, |_| true);
    let shown = mean_at(&frame, pixel(app.world_mut(), spot), 2);
    let want = expected * 2f32.powf(-ev100) / 1.2;
    (shown - want).abs().max_element() / want.max_element()
}

/// An app showing `baked/sunlit_room.gltf` under `dir` from above the floor, once the floor's
/// lightmap (and, with groups, their sum) is shown: the app, its camera, the floor, its page
/// and albedo, and whether the plugin loads BC6H pages on this GPU.
fn show(dir: &Path, groups: bool) -> (App, Entity, (Entity, GltfPage, Vec3), bool) {
    let (mut app, target) = support::render_test_app(dir, W, H);
    let server = app.world().resource::<AssetServer>().clone();
    let bc6h = loads_bc6h(
        app.world().resource::<LightbakeConfig>(),
        app.world().get_resource::<RenderDevice>(),
    );
    let world = app.world_mut();
    world.spawn(WorldAssetRoot(server.load(
        GltfAssetLabel::Scene(0).from_asset("baked/sunlit_room.gltf"),
    )));
    world.insert_resource(GlobalAmbientLight::NONE);
    let camera = world.spawn(render_common::sunlit_floor_camera(target)).id();
    let mut frames = 0;
    let found = loop {
        app.update();
        frames += 1;
        let world = app.world_mut();
        assert!(frames < 3000, "the floor's lightmap never showed");
        let Some(found) = gltf_floor(world) else {
            continue;
        };
        let Some(lm) = world.get::<bevy::pbr::Lightmap>(found.0) else {
            if frames % 200 == 0 {
                let l = world.get::<Lightmapped>(found.0).unwrap();
                let server = world.resource::<AssetServer>();
                println!(
                    "frame {frames}: {:?} {:?}",
                    server.get_path(l.image.id()),
                    server.get_load_state(l.image.id())
                );
            }
            continue;
        };
        let loaded = world.resource::<Assets<Image>>().get(&lm.image).is_some();
        let sums = world.resource::<GroupSums>();
        let summed = sums.target(&found.1).is_some_and(|t| lm.image == *t);
        if loaded && (!groups || (sums.applied() && summed)) {
            break found;
        }
    };
    // The sun's light is baked: only its specular would remain.
    let world = app.world_mut();
    let mut lights = world.query_filtered::<Entity, With<DirectionalLight>>();
    for l in lights.iter(world).collect::<Vec<_>>() {
        world.despawn(l);
    }
    (app, camera, found, bc6h)
}

/// The file an asset handle was loaded from, under `dir`.
fn file_of(world: &World, dir: &Path, image: &Handle<Image>) -> std::path::PathBuf {
    let path = world
        .resource::<AssetServer>()
        .get_path(image.id())
        .unwrap();
    dir.join(path.path())
}

/// E/π of `image`, a page of the mesh `floor` shows at `rect`, at floor point `p`.
fn floor_value(world: &World, (floor, rect): (Entity, Rect), image: &Image, p: Vec3) -> Vec3 {
    let mesh = (world.resource::<Assets<Mesh>>())
        .get(&world.get::<Mesh3d>(floor).unwrap().0)
        .unwrap();
    let t = world.get::<GlobalTransform>(floor).unwrap();
    sample_lightmap(mesh, t, rect, image, p).unwrap()
}

/// A spot in the sun and one in the shade (as the volume's render test picks them).
const SPOTS: [Vec3; 2] = [Vec3::new(1.0, 0.0, 0.6), Vec3::new(-2.8, 0.0, -2.0)];

#[test]
fn bc6h_pages_load_where_the_gpu_samples_them_and_render_as_decoded() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    bake(&dir.path().join("baked"), false);
    let (mut app, camera, (floor, _, albedo), bc6h) = show(dir.path(), false);
    let world = app.world();
    let lightmapped = world.get::<Lightmapped>(floor).unwrap().clone();
    let file = file_of(world, dir.path(), &lightmapped.image);
    let name = file.to_string_lossy().into_owned();
    println!("BC6H on this GPU: {bc6h}; the floor's page: {name}");
    assert_eq!(name.ends_with(".bc6h.ktx2"), bc6h, "{name}");
    assert_eq!(!bc6h, name.ends_with(".exr"), "{name}");
    let page = decoded(&file);
    let exr = decoded(&exr_beside(&file));
    let mut worst: f32 = 0.0;
    for (s, spot) in SPOTS.iter().enumerate() {
        let rect = lightmapped.uv_rect;
        let world = app.world_mut();
        let px = pixel(world, *spot);
        let on = (floor, rect);
        let expected = albedo * mean_over_floor(world, px, 2, |w, p| floor_value(w, on, &page, p));
        let half_float = albedo * mean_over_floor(world, px, 2, |w, p| floor_value(w, on, &exr, p));
        let rel = rendered_against(&mut app, camera, *spot, expected);
        println!(
            "{}: rendered against albedo × the loaded page {:.2}%; the loaded page against the EXR page {:.2}%",
            if s == 0 { "in the sun" } else { "in the shade" },
            100.0 * rel,
            100.0 * (expected - half_float).abs().max_element() / half_float.max_element()
        );
        worst = worst.max(rel);
    }
    assert!(worst < 0.01, "{:.2}%", 100.0 * worst);
}

#[test]
fn light_groups_sum_their_bc6h_pages() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    bake(&dir.path().join("baked"), true);
    let (mut app, camera, (floor, page, albedo), bc6h) = show(dir.path(), true);
    let world = app.world();
    let sources = world.resource::<GroupSums>().sources(&page);
    let files: Vec<(String, Image)> = (sources.iter())
        .map(|(g, h)| {
            let file = file_of(world, dir.path(), h);
            let name = file.to_string_lossy().into_owned();
            assert_eq!(name.ends_with(".bc6h.ktx2"), bc6h, "{g}: {name}");
            (g.clone(), decoded(&file))
        })
        .collect();
    let names: Vec<&str> = files.iter().map(|(g, _)| g.as_str()).collect();
    assert_eq!(names, ["sun", "ungrouped"]);
    let rect = world.get::<Lightmapped>(floor).unwrap().uv_rect;
    let mut worst: f32 = 0.0;
    for weights in [(1.0, 1.0), (0.0, 1.0)] {
        app.world_mut()
            .resource_mut::<LightGroupWeights>()
            .set("sun", weights.0)
            .set("ungrouped", weights.1);
        for frame in 0.. {
            app.update();
            if app.world().resource::<GroupSums>().applied() {
                break;
            }
            assert!(frame < 600, "the sum at {weights:?} was never applied");
        }
        for spot in SPOTS {
            let world = app.world_mut();
            let at = pixel(world, spot);
            let sum = mean_over_floor(world, at, 2, |world, p| {
                let w = [weights.0, weights.1];
                (files.iter().zip(w))
                    .map(|((_, image), w)| w * floor_value(world, (floor, rect), image, p))
                    .sum()
            });
            let rel = rendered_against(&mut app, camera, spot, albedo * sum);
            println!(
                "weights sun {} ungrouped {}: rendered against albedo × Σ weight × decoded group page {:.2}%",
                weights.0,
                weights.1,
                100.0 * rel
            );
            worst = worst.max(rel);
        }
    }
    assert!(worst < 0.01, "{:.2}%", 100.0 * worst);
}

/// The Cornell box's floor (Cornell coordinates / 1000, centred) where the camera above it
/// sees no block: in the open, beside the red wall, and in the back corner by the green
/// wall.
const CORNELL_SPOTS: [Vec3; 3] = [
    Vec3::new(-0.15, 0.0, 0.2),
    Vec3::new(-0.24, 0.0, 0.15),
    Vec3::new(0.22, 0.0, -0.22),
];

#[test]
fn an_in_app_bake_shows_its_bc6h_pages_where_the_gpu_samples_them() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    let bc6h = loads_bc6h(
        app.world().resource::<LightbakeConfig>(),
        app.world().get_resource::<RenderDevice>(),
    );
    {
        let mut config = app.world_mut().resource_mut::<LightbakeConfig>();
        config.settings = BakeSettings::preview();
        config.settings.layout.texel_density = Some(96.0);
        config.settings.formats.ktx2_bc6h = true;
    }
    let world = app.world_mut();
    let scene = cornell_box(CornellLight::Point);
    let entities = spawn_scene(world, &scene);
    let floor = entities[(scene.instances.iter())
        .position(|i| i.name == "floor")
        .unwrap()];
    // Inside the box under its ceiling, looking down at the floor.
    let camera = world
        .spawn((
            render_common::test_camera(
                target,
                Transform::from_xyz(-0.05, 0.5, 0.05)
                    .looking_at(Vec3::new(-0.05, 0.0, 0.05), Vec3::NEG_Z),
                Exposure::default().ev100,
            ),
            Projection::Perspective(PerspectiveProjection {
                fov: 70f32.to_radians(),
                ..default()
            }),
        ))
        .id();
    world.insert_resource(GlobalAmbientLight::NONE);
    world.write_message(RequestBake::default());
    // The bake finishes, the floor shows its page, and (on a GPU that samples BC textures)
    // that page's asset is the BC6H file's blocks.
    for frame in 0.. {
        app.update();
        let world = app.world_mut();
        if let BakePhase::Failed(e) = &world.resource::<BakeStatus>().phase {
            panic!("bake failed: {e}");
        }
        assert!(frame < 20_000, "the bake's pages never showed");
        if world.resource::<BakeStatus>().completed == 0 {
            continue;
        }
        let lightmapped = world.get::<Lightmapped>(floor).unwrap();
        let format = (world.resource::<Assets<Image>>())
            .get(&lightmapped.image)
            .map(|i| i.texture_descriptor.format);
        if !lightmapped.is_shown_by(world.get::<bevy::pbr::Lightmap>(floor)) {
            continue;
        }
        let want = if bc6h {
            bevy::render::render_resource::TextureFormat::Bc6hRgbUfloat
        } else {
            bevy::render::render_resource::TextureFormat::Rgba16Float
        };
        if format == Some(want) {
            break;
        }
    }
    // The lamp's light is baked: only its specular would remain.
    let world = app.world_mut();
    let mut lights = world.query_filtered::<Entity, With<PointLight>>();
    for l in lights.iter(world).collect::<Vec<_>>() {
        world.despawn(l);
    }
    let lightmapped = world.get::<Lightmapped>(floor).unwrap().clone();
    let file = file_of(world, dir.path(), &lightmapped.image);
    let name = file.to_string_lossy().into_owned();
    println!("BC6H on this GPU: {bc6h}; the floor's page: {name}");
    assert_eq!(name.ends_with(".bc6h.ktx2"), bc6h, "{name}");
    let page = decoded(&file);
    let exr = decoded(&exr_beside(&file));
    let albedo = Vec3::from_array(CORNELL_WHITE.to_array());
    let mut worst: f32 = 0.0;
    for spot in CORNELL_SPOTS {
        let world = app.world_mut();
        let px = pixel(world, spot);
        let on = (floor, lightmapped.uv_rect);
        let expected = albedo * mean_over_floor(world, px, 2, |w, p| floor_value(w, on, &page, p));
        let half_float = albedo * mean_over_floor(world, px, 2, |w, p| floor_value(w, on, &exr, p));
        let rel = rendered_against(&mut app, camera, spot, expected);
        println!(
            "in-app bake, floor at {spot}: rendered against albedo × the loaded page {:.2}%; the loaded page against the EXR page {:.2}%",
            100.0 * rel,
            100.0 * (expected - half_float).abs().max_element() / half_float.max_element()
        );
        worst = worst.max(rel);
    }
    // Showing the half-float page instead would be 0.4–0.9% off at these spots (the BC6H
    // page's difference from it), over the bound at two of them.
    assert!(worst < 0.005, "{:.2}%", 100.0 * worst);
}
