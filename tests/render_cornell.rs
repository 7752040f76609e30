//! The Cornell box baked in the app and drawn by Bevy's renderer (software Vulkan, Mesa
//! lavapipe): the floor is lit, the short block shadows it, the walls bleed colour onto it,
//! what the renderer shows is what was baked, and chart borders leave no dark seams. Skips
//! when no Vulkan driver is installed (fails instead with `LIGHTBAKE_REQUIRE_VULKAN=1`, which
//! `.ci/run` sets after installing one).

mod render_common;
#[path = "../examples/support/mod.rs"]
mod support;

use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy_lightbake::prelude::*;
use bevy_lightbake::spawn::spawn_scene;
use lightbake::scene::testscenes::{CORNELL_WHITE, CornellLight, cornell_box};
use render_common::{lightmap_at, mean_at, pixel};

const W: u32 = 320;
const H: u32 = 240;
const EV100: f32 = 8.0;

#[test]
fn rendered_cornell_box_shows_the_bake() {
    if !support::render_tests_can_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (mut app, target) = support::render_test_app(dir.path(), W, H);
    app.world_mut()
        .resource_mut::<LightbakeConfig>()
        .settings
        .layout
        .texel_density = Some(128.0);

    let world = app.world_mut();
    let scene = cornell_box(CornellLight::Point);
    let entities = spawn_scene(world, &scene);
    // The light's specular highlight (which Bevy always draws) stays unshadowed, so that the
    // picture is the lightmap's alone up to a smooth highlight.
    let mut lights = world.query::<&mut PointLight>();
    for mut l in lights.iter_mut(world) {
        l.shadow_maps_enabled = false;
    }
    world.spawn(render_common::test_camera(
        target,
        Transform::from_xyz(0.0, 0.2744, 1.35).looking_at(Vec3::new(0.0, 0.2744, 0.0), Vec3::Y),
        EV100,
    ));
    world.write_message(RequestBake::default());
    let frame = support::capture_when_ready(&mut app, |world| {
        let mut shown = world.query::<(&Lightmapped, Option<&Lightmap>)>();
        world.resource::<BakeStatus>().completed == 1
            && shown.iter(world).all(|(l, m)| l.is_shown_by(m))
    });
    let world = app.world_mut();
    frame
        .save_png(&std::env::temp_dir().join("lightbake_render_cornell.png"))
        .unwrap();

    // Points on the floor (Cornell coordinates / 1000, centred; +z is the open front).
    let open = Vec3::new(-0.15, 0.0, 0.2);
    let shadow = Vec3::new(0.064, 0.0, 0.204); // in front of the short block, light hidden
    let near_red = Vec3::new(-0.26, 0.0, -0.05);
    let middle = Vec3::new(0.0, 0.0, -0.05);
    let lit = mean_at(&frame, pixel(world, open), 2);
    let dark = mean_at(&frame, pixel(world, shadow), 2);
    assert!(lit.x > 0.1, "the open floor is lit: {lit}");
    assert!(dark.x < 0.6 * lit.x, "shadow {dark} vs open floor {lit}");
    let (r, m) = (
        mean_at(&frame, pixel(world, near_red), 2),
        mean_at(&frame, pixel(world, middle), 2),
    );
    assert!(
        r.x / r.y > 1.1 * m.x / m.y,
        "bleeding: near the red wall {r}, middle {m}"
    );

    // The renderer shows albedo × lightmap × exposure. Checked on the back wall, which faces
    // the camera: each pixel's centre is traced to the wall and the lightmap sampled there,
    // so the 5×5-pixel means compare like with like. (The light's specular adds a little:
    // Bevy always draws it, and the materials have roughness 1 and reflectance 0.5.)
    let back = entities[scene
        .instances
        .iter()
        .position(|i| i.name == "back_wall")
        .unwrap()];
    let wall_z = -0.2796;
    let exposure = 2f32.powf(-EV100) / 1.2;
    let mut worst: f32 = 0.0;
    for (x, y) in [
        (-0.2, 0.4),
        (-0.05, 0.4),
        (0.05, 0.35),
        (0.15, 0.45),
        (0.2, 0.3),
        (0.22, 0.2),
    ] {
        let (px, py) = pixel(world, Vec3::new(x, y, wall_z));
        let mut expected = Vec3::ZERO;
        for j in py - 2..py + 3 {
            for i in px - 2..px + 3 {
                let mut q = world.query::<(&Camera, &GlobalTransform)>();
                let (camera, t) = q.single(world).unwrap();
                let ray = camera
                    .viewport_to_world(t, Vec2::new(i as f32 + 0.5, j as f32 + 0.5))
                    .unwrap();
                let d = (wall_z - ray.origin.z) / ray.direction.z;
                let on_wall = ray.origin + d * ray.direction.as_vec3();
                expected += lightmap_at(world, back, on_wall);
            }
        }
        let expected = Vec3::from_array(CORNELL_WHITE.to_array()) * expected / 25.0 * exposure;
        let rendered = mean_at(&frame, (px, py), 2);
        assert!(
            rendered.max_element() < 0.95,
            "clipped at ({x}, {y}): {rendered}"
        );
        let rel = (rendered - expected).abs().max_element() / expected.max_element();
        println!(
            "back wall ({x:+.2}, {y:.2}): rendered {rendered:.4}, albedo × lightmap × exposure {expected:.4}, {:.2}%",
            100.0 * rel
        );
        worst = worst.max(rel);
    }
    assert!(
        worst < 0.02,
        "the renderer departs from the lightmap by {:.1}%",
        100.0 * worst
    );

    // No dark seams. Every pixel is traced (the core's BVH over the same scene) to find which
    // surface it shows. Inside a surface no line of pixels may be much darker than both
    // neighbours across it — a one-pixel dark line is what a seam between charts looks like
    // (a lone darker pixel is Monte Carlo noise, not a seam). At the
    // edges where faces meet (where charts end) light may fall off fast (contact shadows,
    // shadow edges), but an edge pixel may not be nearly black next to a lit pixel two steps
    // further into its own face: a quarter of it at least.
    let rays = lightbake::bvh::RayScene::build(&scene);
    let mut q = world.query::<(&Camera, &GlobalTransform)>();
    let (camera, t) = q.single(world).unwrap();
    let surface: Vec<Option<(u32, i32, i32, i32)>> = (0..W * H)
        .map(|i| {
            let ray = camera
                .viewport_to_world(t, Vec2::new((i % W) as f32 + 0.5, (i / W) as f32 + 0.5))
                .unwrap();
            let o = glam::Vec3::from_array(ray.origin.to_array());
            let d = glam::Vec3::from_array(ray.direction.as_vec3().to_array());
            // A surface is one flat face of one instance: (instance, face normal).
            rays.closest_hit(o, d, 0.0, 10.0).map(|h| {
                let info = rays.triangles[h.triangle as usize];
                let n = (info.normal * 100.0).round().as_ivec3();
                (info.instance, n.x, n.y, n.z)
            })
        })
        .collect();
    let at = |x: u32, y: u32| surface[(y * W + x) as usize];
    let v = |x: u32, y: u32| frame.linear(x, y).max_element();
    let (mut interior_seams, mut edge_seams, mut edges, mut worst_edge) = (0, 0, 0, f32::MAX);
    for y in 2..H - 2 {
        for x in 2..W - 2 {
            let Some(s) = at(x, y) else { continue };
            let n = [(1i32, 0i32), (-1, 0), (0, 1), (0, -1)];
            let same = |(dx, dy): (i32, i32), k: i32| {
                at((x as i32 + k * dx) as u32, (y as i32 + k * dy) as u32) == Some(s)
            };
            if n.iter().all(|&d| same(d, 1)) {
                // Darker than both neighbours across a line, and so is the next pixel along
                // it: a seam is a line, a lone dark pixel is noise.
                let dip_x = |x: u32, y: u32| v(x, y) < 0.7 * v(x - 1, y).min(v(x + 1, y));
                let dip_y = |x: u32, y: u32| v(x, y) < 0.7 * v(x, y - 1).min(v(x, y + 1));
                let (l, r, u, d) = (v(x - 1, y), v(x + 1, y), v(x, y - 1), v(x, y + 1));
                let line_x = dip_x(x, y) && (dip_x(x, y - 1) || dip_x(x, y + 1));
                let line_y = dip_y(x, y) && (dip_y(x - 1, y) || dip_y(x + 1, y));
                if line_x || line_y {
                    interior_seams += 1;
                    println!(
                        "interior dark pixel ({x}, {y}) on {} value {} neighbours {l} {r} {u} {d}",
                        scene.instances[s.0 as usize].name,
                        v(x, y)
                    );
                }
                continue;
            }
            // An edge pixel: step away from the other surface.
            for &(dx, dy) in &n {
                if !same((dx, dy), 1) && same((-dx, -dy), 1) && same((-dx, -dy), 2) {
                    edges += 1;
                    let inside = v((x as i32 - 2 * dx) as u32, (y as i32 - 2 * dy) as u32);
                    if inside > 0.02 {
                        let ratio = v(x, y) / inside;
                        worst_edge = worst_edge.min(ratio);
                        if ratio < 0.25 {
                            println!(
                                "edge dark pixel ({x}, {y}) on {} ratio {ratio} dir ({dx},{dy})",
                                scene.instances[s.0 as usize].name
                            );
                            edge_seams += 1;
                        }
                    }
                }
            }
        }
    }
    println!(
        "seams: {interior_seams} interior pixels, {edge_seams} of {edges} edge pixels; darkest edge pixel {worst_edge:.2} of the pixel two steps in"
    );
    assert_eq!(interior_seams, 0, "dark lines inside surfaces");
    assert_eq!(edge_seams, 0, "dark seams where surfaces meet");
}
