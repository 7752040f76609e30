//! Every baked real level draws in Bevy (software Vulkan, Mesa lavapipe). Each level of the
//! corpus (`assets/corpus/`: the FZK house, Kenney's two starter levels, four OpenArena
//! levels and the two assimp test scenes) and a scene built for the attribute combinations
//! Bevy's `StandardMaterial` shader has to compile for (no `TEXCOORD_0`, no normals, vertex
//! colours, tangents, a mesh's own `TEXCOORD_1`, double-sided, emissive, transmissive,
//! clear-coated, blended and masked materials) is baked by the core, written as a baked
//! glTF, and spawned in one Bevy app, one after the other. For each one a camera placed by
//! tracing the level (the view that sees most of its front faces) draws a frame, and:
//! no render pipeline failed to build and no error was logged; the share of pixels that are
//! not the clear colour is at least the share of the camera's rays that hit a visible face
//! (less a margin for edges); and at spots on flat untextured surfaces (5 × 5 pixels each,
//! every one tracing to the same face) the picture is the surface's albedo × its lightmap ×
//! the exposure within 5% (the built scene, the house and the OpenArena levels, untextured,
//! have such spots; Kenney's levels are textured throughout). Set
//! `LIGHTBAKE_RENDER_CORPUS_PNG=DIR` to keep the pictures. Skips when no Vulkan driver is
//! installed (fails instead with `LIGHTBAKE_REQUIRE_VULKAN=1`, which `.ci/run` sets).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use bevy::camera::Exposure;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::capture::{CapturedFrame, FrameCapture};
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;
use lightbake::bvh::RayScene;
use serde_json::Value;

const W: u32 = 320;
const H: u32 = 240;
const FOV_DEGREES: f32 = 70.0;
/// Pure magenta: no baked level shows it.
const CLEAR: [u8; 3] = [255, 0, 255];

/// The corpus levels, relative to `assets/corpus/`.
const LEVELS: [&str; 9] = [
    "house.gltf",
    "kenney_fps/kenney_fps.gltf",
    "kenney_platformer/kenney_platformer.gltf",
    "openarena/aggressor.gltf",
    "openarena/q3dm6ish.gltf",
    "openarena/oa_bases3.gltf",
    "openarena/kaos.gltf",
    "assimp/teapots.gltf",
    "assimp/mirrored_cubes.gltf",
];

/// Bakes `source` at preview quality and a small texel budget into `out`; returns the
/// baked glTF's path and what the writer added and warned.
fn bake(source: &Path, out: &Path) -> (PathBuf, lightbake::output::Written) {
    let imported = lightbake::import_gltf(source, lightbake::LightConvention::GltfSpec)
        .unwrap_or_else(|e| panic!("{}: {e}", source.display()));
    let mut settings = BakeSettings::preview();
    settings.layout.texel_budget = 40_000;
    let baked = lightbake::bake(&imported.scene, &settings, &lightbake::Progress::new())
        .unwrap_or_else(|e| panic!("{}: {e}", source.display()));
    let written = lightbake::write_outputs(
        out,
        &baked,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    let file = (written.files.iter())
        .find(|f| f.extension().is_some_and(|x| x == "gltf" || x == "glb"))
        .unwrap()
        .clone();
    (file, written)
}

/// A camera: eye, unit view direction.
#[derive(Clone, Copy, Debug)]
struct View {
    eye: Vec3,
    dir: Vec3,
}

impl View {
    /// The ray through `(px, py)` (pixel units, from the top left) of a `W × H` picture at
    /// `FOV_DEGREES` vertical.
    fn ray(&self, px: f32, py: f32) -> Vec3 {
        let right = self.dir.cross(Vec3::Y).normalize();
        let up = right.cross(self.dir);
        let t = (FOV_DEGREES.to_radians() / 2.0).tan();
        let x = (2.0 * px / W as f32 - 1.0) * t * W as f32 / H as f32;
        let y = (1.0 - 2.0 * py / H as f32) * t;
        (self.dir + right * x + up * y).normalize()
    }
}

/// Whether a traced hit is drawn by Bevy: its front face, or either face of a double-sided
/// material.
fn drawn(scene: &lightbake::scene::Scene, rays: &RayScene, hit: &lightbake::bvh::Hit) -> bool {
    let instance = rays.triangles[hit.triangle as usize].instance as usize;
    let mesh = &scene.meshes[scene.instances[instance].mesh];
    let two_sided = mesh
        .material
        .is_some_and(|m| scene.materials[m].double_sided);
    hit.front_face || two_sided
}

/// What a 32 × 24 grid of `view`'s rays see: the share that hit a face Bevy draws, a score
/// of how much of the level the view shows (the drawn faces hit past a tenth of `reach`,
/// plus five per instance seen that way), and whether the eye is inside a solid (a third of
/// the hits on back faces of single-sided materials).
fn survey(
    scene: &lightbake::scene::Scene,
    rays: &RayScene,
    view: View,
    reach: f32,
) -> (f32, f32, bool) {
    let (mut seen, mut back, mut far, mut n) = (0, 0, 0, 0);
    let mut instances = std::collections::HashSet::new();
    for j in 0..24 {
        for i in 0..32 {
            let d = view.ray(
                (i as f32 + 0.5) * W as f32 / 32.0,
                (j as f32 + 0.5) * H as f32 / 24.0,
            );
            n += 1;
            let g = |v: Vec3| glam::Vec3::from_array(v.to_array());
            if let Some(h) = rays.closest_hit(g(view.eye), g(d), 0.0, f32::MAX) {
                if !drawn(scene, rays, &h) {
                    back += 1;
                    continue;
                }
                seen += 1;
                if h.t > 0.1 * reach {
                    far += 1;
                    instances.insert(rays.triangles[h.triangle as usize].instance);
                }
            }
        }
    }
    let score = far as f32 + 5.0 * instances.len() as f32;
    (seen as f32 / n as f32, score, back * 3 > n)
}

/// Views of the level, those that show most of it first (see [`survey`]): eyes on a grid
/// inside its bounds and at its first 32 lamps (four headings, looking 25° down) and one
/// in front of it looking at its centre; each with the share of its rays that hit a drawn
/// face.
fn frame(scene: &lightbake::scene::Scene, rays: &RayScene) -> Vec<(View, f32)> {
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for inst in &scene.instances {
        for p in &scene.meshes[inst.mesh].positions {
            let q = inst.transform.transform_point3(*p);
            let q = Vec3::from_array(q.to_array());
            lo = lo.min(q);
            hi = hi.max(q);
        }
    }
    let size = hi - lo;
    let reach = size.length();
    let centre = (lo + hi) / 2.0;
    let front = centre
        + Vec3::new(
            0.0,
            0.4 * size.max_element(),
            hi.z - centre.z + size.max_element(),
        );
    let mut views = vec![View {
        eye: front,
        dir: (centre - front).normalize(),
    }];
    let pitch = -25f32.to_radians();
    let mut eyes = Vec::new();
    for fx in [0.25, 0.5, 0.75] {
        for fz in [0.25, 0.5, 0.75] {
            for fy in [0.25, 0.5] {
                eyes.push(lo + size * Vec3::new(fx, fy, fz));
            }
        }
    }
    // Beside the first lamps too: in a large dark level, where something is lit.
    let lamps = (scene.lights.iter())
        .filter(|l| !matches!(l.kind, lightbake::scene::LightKind::Directional { .. }));
    eyes.extend(
        lamps
            .take(32)
            .map(|l| Vec3::from_array(l.position.to_array())),
    );
    for eye in eyes {
        for k in 0..4 {
            let yaw = k as f32 * std::f32::consts::FRAC_PI_2;
            let dir = Vec3::new(
                yaw.sin() * pitch.cos(),
                pitch.sin(),
                -yaw.cos() * pitch.cos(),
            );
            views.push(View { eye, dir });
        }
    }
    let mut ranked: Vec<(View, f32, f32)> = (views.into_iter())
        .map(|v| (v, survey(scene, rays, v, reach)))
        .filter(|(_, (_, _, inside))| !inside)
        .map(|(v, (share, score, _))| (v, share, score))
        .collect();
    ranked.sort_by(|a, b| b.2.total_cmp(&a.2));
    assert!(!ranked.is_empty(), "every view is inside a solid");
    ranked.into_iter().map(|(v, share, _)| (v, share)).collect()
}

/// A mesh entity of the spawned glTF by (its node's name, glTF mesh, primitive), as Bevy
/// names nodes (`GltfNode{i}` when unnamed) and labels meshes (`Mesh{m}/Primitive{p}`).
type EntityKey = (String, usize, usize);

/// The lightmapped mesh entities of the spawned scene by [`EntityKey`].
fn entities_by_key(world: &mut World) -> HashMap<EntityKey, Vec<Entity>> {
    let mut q = world.query_filtered::<(Entity, &Mesh3d, &ChildOf), With<Lightmap>>();
    let server = world.resource::<AssetServer>();
    let mut out: HashMap<EntityKey, Vec<Entity>> = HashMap::new();
    for (e, mesh, parent) in q.iter(world) {
        let Some(label) = server
            .get_path(mesh.0.id())
            .and_then(|p| p.label().map(str::to_string))
        else {
            continue;
        };
        let Some((m, p)) = label
            .strip_prefix("Mesh")
            .and_then(|r| r.split_once("/Primitive"))
            .and_then(|(m, p)| Some((m.parse().ok()?, p.parse().ok()?)))
        else {
            continue;
        };
        let Some(name) = world.get::<Name>(parent.parent()) else {
            continue;
        };
        out.entry((name.as_str().to_string(), m, p))
            .or_default()
            .push(e);
    }
    out
}

/// The [`EntityKey`] of each instance of the core's import of the baked glTF `json`.
fn instance_keys(scene: &lightbake::scene::Scene, json: &Value) -> Vec<Option<EntityKey>> {
    (scene.instances.iter())
        .map(|inst| {
            let node = inst.gltf_node?;
            let source = scene.meshes[inst.mesh].source?;
            let name = json["nodes"][node]["name"]
                .as_str()
                .map_or_else(|| format!("GltfNode{node}"), str::to_string);
            Some((name, source.mesh, source.primitive))
        })
        .collect()
}

/// The diffuse colour Bevy multiplies `entity`'s lightmap by when it shows a plain colour
/// (no base colour texture, no vertex colours, no emission, opaque and lit): base colour ×
/// (1 − metallic) × (1 − specular transmission) × (1 − diffuse transmission), as Bevy's
/// `calculate_diffuse_color`.
fn plain_albedo(world: &World, entity: Entity) -> Option<Vec3> {
    let mesh = world
        .resource::<Assets<Mesh>>()
        .get(&world.get::<Mesh3d>(entity)?.0)?;
    let material = world.get::<MeshMaterial3d<StandardMaterial>>(entity)?;
    let m = world
        .resource::<Assets<StandardMaterial>>()
        .get(&material.0)?;
    let plain = m.base_color_texture.is_none()
        && !m.unlit
        && m.alpha_mode == AlphaMode::Opaque
        && m.emissive.to_f32_array()[..3].iter().all(|&c| c == 0.0)
        && !mesh.contains_attribute(Mesh::ATTRIBUTE_COLOR);
    let c = m.base_color.to_linear();
    let kept =
        (1.0 - m.metallic) * (1.0 - m.specular_transmission) * (1.0 - m.diffuse_transmission);
    plain.then(|| Vec3::new(c.red, c.green, c.blue) * kept)
}

/// E/π of `entity`'s lightmap at its surface point nearest `p`.
fn lightmap_value(world: &World, entity: Entity, p: Vec3) -> Option<Vec3> {
    let mesh = world
        .resource::<Assets<Mesh>>()
        .get(&world.get::<Mesh3d>(entity)?.0)?;
    let lm = world.get::<Lightmap>(entity)?;
    let image = world.resource::<Assets<Image>>().get(&lm.image)?;
    sample_lightmap(
        mesh,
        world.get::<GlobalTransform>(entity)?,
        lm.uv_rect,
        image,
        p,
    )
}

/// A spot of 5 × 5 pixels on one flat face of one plain-coloured lightmapped surface: its
/// centre pixel, the mean of albedo × lightmap over the points its pixels see, and the
/// ratio of the brightest of those to the darkest (luminance).
struct Spot {
    pixel: (u32, u32),
    expected: Vec3,
    spread: f32,
}

/// Spots on a grid of the picture where all 25 pixels trace to one face of one plain
/// surface seen at less than 70° from its normal, whose entity is known by its key alone.
fn spots(
    world: &mut World,
    scene: &lightbake::scene::Scene,
    rays: &RayScene,
    keys: &[Option<EntityKey>],
) -> Vec<Spot> {
    let entities = entities_by_key(world);
    let mut q = world.query::<(&Camera, &GlobalTransform)>();
    let (camera, t) = q.single(world).unwrap();
    let (camera, t) = (camera.clone(), *t);
    let mut out = Vec::new();
    // Why grid places were left out: a pixel sees nothing drawn; the pixels see several faces
    // or one at a grazing angle; the surface's entity is not known by its key alone; it is
    // not plain-coloured; its lightmap could not be read there.
    let mut left_out = [0; 5];
    for cy in (12..H - 12).step_by(24) {
        for cx in (12..W - 12).step_by(24) {
            let mut face = None;
            let mut points = Vec::new();
            let mut ok = true;
            'pixels: for py in cy - 2..=cy + 2 {
                for px in cx - 2..=cx + 2 {
                    let ray = camera
                        .viewport_to_world(&t, Vec2::new(px as f32 + 0.5, py as f32 + 0.5))
                        .unwrap();
                    let g = |v: Vec3| glam::Vec3::from_array(v.to_array());
                    let d = ray.direction.as_vec3();
                    let hit = rays.closest_hit(g(ray.origin), g(d), 0.0, f32::MAX);
                    let Some(h) = hit.filter(|h| drawn(scene, rays, h)) else {
                        ok = false;
                        left_out[0] += 1;
                        break 'pixels;
                    };
                    let info = rays.triangles[h.triangle as usize];
                    let n = Vec3::from_array(info.normal.to_array());
                    let key = (info.instance, (n * 1000.0).round().as_ivec3());
                    if face.is_some_and(|f| f != key) || n.dot(d).abs() < 0.34 {
                        ok = false;
                        left_out[1] += 1;
                        break 'pixels;
                    }
                    face = Some(key);
                    points.push(ray.origin + d * h.t);
                }
            }
            if !ok {
                continue;
            }
            let Some((instance, _)) = face else { continue };
            let entity = match keys[instance as usize]
                .as_ref()
                .and_then(|k| entities.get(k))
            {
                Some(list) if list.len() == 1 => list[0],
                _ => {
                    left_out[2] += 1;
                    continue;
                }
            };
            let Some(albedo) = plain_albedo(world, entity) else {
                left_out[3] += 1;
                continue;
            };
            let values: Option<Vec<Vec3>> = (points.iter())
                .map(|&p| lightmap_value(world, entity, p))
                .collect();
            let Some(values) = values else {
                left_out[4] += 1;
                continue;
            };
            let mean = values.iter().sum::<Vec3>() / values.len() as f32;
            let y = |v: &Vec3| v.dot(Vec3::new(0.2126, 0.7152, 0.0722));
            let (lo, hi) = (values.iter().map(y))
                .fold((f32::MAX, 0.0f32), |(lo, hi), v| (lo.min(v), hi.max(v)));
            out.push(Spot {
                pixel: (cx, cy),
                expected: albedo * mean,
                spread: hi / lo.max(1e-12),
            });
        }
    }
    println!(
        "  spots: {} kept; left out: {} see nothing drawn, {} several faces or grazing, {} entity not known, {} not plain-coloured, {} no lightmap value",
        out.len(),
        left_out[0],
        left_out[1],
        left_out[2],
        left_out[3],
        left_out[4]
    );
    out
}

/// The exposure that shows the median of the lit spots at a third of white (a level's unlit
/// corners would put it at a black one).
fn exposure(spots: &[Spot]) -> f32 {
    let brightest = (spots.iter()).fold(0.0f32, |m, s| m.max(s.expected.max_element()));
    let mut levels: Vec<f32> = (spots.iter())
        .map(|s| s.expected.max_element())
        .filter(|&v| v > 1e-3 * brightest)
        .collect();
    levels.sort_by(f32::total_cmp);
    let median = levels
        .get(levels.len() / 2)
        .copied()
        .unwrap_or(1.0)
        .max(1e-6);
    (median / (0.33 * 1.2)).log2()
}

/// Whether a spot is checked at `ev100`: within the picture's range (above 8-bit sRGB's
/// coarse steps and below white), and where the light is smooth over it (across a steep
/// gradient the GPU's bilinear weights, with 8 bits of sub-texel position on lavapipe, differ
/// from exact ones by several percent).
fn checkable(s: &Spot, ev100: f32) -> bool {
    let want = s.expected.max_element() * 2f32.powf(-ev100) / 1.2;
    (0.08..=0.9).contains(&want) && s.spread <= 1.5
}

/// Updates `app` until the scene under `root` has spawned and every lightmapped entity
/// shows its lightmap (at least `at_least` of them).
fn wait_for_lightmaps(app: &mut App, at_least: usize, what: &str) {
    for frame in 0.. {
        app.update();
        let world = app.world_mut();
        let mut q = world.query::<(&Lightmapped, Option<&Lightmap>)>();
        let list: Vec<bool> = q.iter(world).map(|(l, m)| l.is_shown_by(m)).collect();
        let loaded = {
            let mut q = world.query::<&Lightmap>();
            let images = world.resource::<Assets<Image>>();
            q.iter(world).all(|l| images.get(&l.image).is_some())
        };
        if list.len() >= at_least && list.iter().all(|&s| s) && loaded {
            return;
        }
        assert!(
            frame < 5000,
            "{what}: {} of {at_least} lightmaps shown after {frame} frames",
            list.iter().filter(|&&s| s).count()
        );
    }
}

/// The share of the frame's pixels that are not the clear colour.
fn drawn_share(frame: &CapturedFrame) -> f32 {
    let clear = (frame.rgba.chunks_exact(4))
        .filter(|p| p[..3] == CLEAR)
        .count();
    1.0 - clear as f32 / (frame.width * frame.height) as f32
}

/// What one level showed.
struct Shown {
    drawn: f32,
    traced: f32,
    spots: usize,
    worst: f32,
    median: f32,
}

/// Spawns the baked glTF `file` (relative to the app's asset folder), frames it, captures a
/// frame and checks it; despawns it again.
fn show(app: &mut App, camera: Entity, baked: &Path, file: &str, name: &str) -> Shown {
    let imported = lightbake::import_gltf(baked, lightbake::LightConvention::GltfSpec).unwrap();
    let scene = imported.scene;
    let rays = RayScene::build(&scene);
    let views = frame(&scene, &rays);
    let manifest: Value = serde_json::from_slice(
        &std::fs::read(baked.parent().unwrap().join("manifest.json")).unwrap(),
    )
    .unwrap();
    let instances = manifest["instances"].as_array().unwrap().len();
    let server = app.world().resource::<AssetServer>().clone();
    let root = (app.world_mut())
        .spawn(WorldAssetRoot(
            server.load(GltfAssetLabel::Scene(0).from_asset(file.to_string())),
        ))
        .id();
    wait_for_lightmaps(app, instances, name);
    let world = app.world_mut();
    // The lights' diffuse light is in the lightmaps; only their specular would remain.
    let mut lights = world
        .query_filtered::<Entity, Or<(With<PointLight>, With<SpotLight>, With<DirectionalLight>)>>(
        );
    for l in lights.iter(world).collect::<Vec<_>>() {
        world.despawn(l);
    }
    let json: Value = serde_json::from_slice(&std::fs::read(baked).unwrap()).unwrap();
    let keys = instance_keys(&scene, &json);
    // Of the twelve views that show most of the level, the one with most spots to check.
    let mut best: Option<(usize, Transform, f32, Vec<Spot>, f32)> = None;
    for (view, traced) in views.into_iter().take(12) {
        let transform = Transform::from_translation(view.eye).looking_to(view.dir, Vec3::Y);
        app.world_mut().entity_mut(camera).insert(transform);
        app.update();
        let spots = spots(app.world_mut(), &scene, &rays, &keys);
        let ev100 = exposure(&spots);
        let checked = spots.iter().filter(|s| checkable(s, ev100)).count();
        if best.as_ref().is_none_or(|b| checked > b.0) {
            best = Some((checked, transform, traced, spots, ev100));
        }
    }
    let (_, transform, traced, spots, ev100) = best.unwrap();
    app.world_mut().entity_mut(camera).insert(transform);
    let world = app.world_mut();
    world.entity_mut(camera).insert(Exposure { ev100 });
    world.resource_mut::<FrameCapture>().rearm();
    let picture = support::capture_when_ready(app, |_| true);
    if let Ok(dir) = std::env::var("LIGHTBAKE_RENDER_CORPUS_PNG") {
        let path = Path::new(&dir).join(format!("{}.png", name.replace('/', "_")));
        picture.save_png(&path).unwrap();
    }
    let scale = 2f32.powf(-ev100) / 1.2;
    let mut errors = Vec::new();
    for s in spots.iter().filter(|s| checkable(s, ev100)) {
        let want = s.expected * scale;
        let shown = render_common::mean_at(&picture, s.pixel, 2);
        let rel = (shown - want).abs().max_element() / want.max_element();
        if rel > 0.03 {
            println!(
                "{name}: spot {:?} rendered {shown:.4} against albedo × lightmap × exposure {want:.4}: {:.1}%",
                s.pixel,
                100.0 * rel
            );
        }
        errors.push(rel);
    }
    errors.sort_by(f32::total_cmp);
    app.world_mut().despawn(root);
    app.update();
    Shown {
        drawn: drawn_share(&picture),
        traced,
        spots: errors.len(),
        worst: errors.last().copied().unwrap_or(0.0),
        median: errors.get(errors.len() / 2).copied().unwrap_or(0.0),
    }
}

#[test]
fn every_baked_corpus_level_draws_in_bevy() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/corpus");
    // Bake everything first, then draw it in one app.
    let mut baked = Vec::new();
    let combos = render_common::combos::combos_scene(&dir.path().join("source"));
    let (file, written) = bake(&combos, &dir.path().join("baked/combos"));
    for w in &written.warnings {
        println!("combos: warning: {w}");
    }
    // No primitive had a TEXCOORD_0: the floor, the twelve boxes and the unlit one get one ...
    assert_eq!(
        written.texcoord_0_added.len(),
        14,
        "{:?}",
        written.texcoord_0_added
    );
    // ... and the writer says what Bevy draws other than as baked.
    assert!(
        written
            .warnings
            .iter()
            .any(|w| w.starts_with("material 'unlit'") && w.contains("no lightmap"))
    );
    assert!(
        written
            .warnings
            .iter()
            .any(|w| w.starts_with("material 'white' (mesh 'vertex_colours'")
                && w.contains("vertex colours"))
    );
    assert!(
        written
            .warnings
            .iter()
            .any(|w| w.starts_with("material 'glass'") && w.contains("transmission"))
    );
    baked.push(("combos".to_string(), file));
    for level in LEVELS {
        let name = level.trim_end_matches(".gltf").to_string();
        let (file, written) = bake(&corpus.join(level), &dir.path().join("baked").join(&name));
        println!(
            "{name}: TEXCOORD_0 added to {} primitive(s); {} warning(s) on drawing",
            written.texcoord_0_added.len(),
            written.warnings.len()
        );
        for w in &written.warnings {
            println!("  {w}");
        }
        baked.push((name, file));
    }

    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    let world = app.world_mut();
    world.insert_resource(GlobalAmbientLight::NONE);
    world.insert_resource(ClearColor(Color::srgb_u8(CLEAR[0], CLEAR[1], CLEAR[2])));
    let camera = world
        .spawn((
            render_common::test_camera(target, Transform::default(), 0.0),
            Projection::Perspective(PerspectiveProjection {
                fov: FOV_DEGREES.to_radians(),
                ..default()
            }),
        ))
        .id();
    let mut failures = Vec::new();
    for (name, file) in &baked {
        let rel = file
            .strip_prefix(dir.path())
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let shown = show(&mut app, camera, file, &rel, name);
        println!(
            "{name}: {:.1}% of the pixels drawn ({:.1}% of the rays hit a drawn face); {} spots of albedo × lightmap: median {:.2}%, worst {:.2}%",
            100.0 * shown.drawn,
            100.0 * shown.traced,
            shown.spots,
            100.0 * shown.median,
            100.0 * shown.worst
        );
        if shown.drawn < shown.traced - 0.05 {
            failures.push(format!(
                "{name}: {:.1}% of the pixels drawn where {:.1}% of the rays hit a drawn face",
                100.0 * shown.drawn,
                100.0 * shown.traced
            ));
        }
        let untextured = name == "combos" || name == "house" || name.starts_with("openarena");
        if untextured && shown.spots < 3 {
            failures.push(format!(
                "{name}: {} spots on plain surfaces to check",
                shown.spots
            ));
        }
        if shown.worst > 0.05 {
            failures.push(format!(
                "{name}: a spot {:.1}% off albedo × lightmap × exposure",
                100.0 * shown.worst
            ));
        }
    }
    let errors = support::logged_errors();
    assert!(errors.is_empty(), "errors logged: {errors:#?}");
    assert!(failures.is_empty(), "{failures:#?}");
}
