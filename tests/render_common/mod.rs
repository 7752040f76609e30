//! Shared by the render tests that compare places of one picture: pixels of world points,
//! their means, a surface's lightmap value there, and the exposure that shows it mid-grey.

#![allow(dead_code)]

pub mod combos;

use bevy::camera::{Exposure, RenderTarget, ShadowLodOrigin};
use bevy::core_pipeline::tonemapping::{DebandDither, Tonemapping};
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use bevy::render::view::Msaa;
use bevy_lightbake::capture::CapturedFrame;
use bevy_lightbake::groups::GltfPage;
use bevy_lightbake::prelude::*;
use bevy_lightbake::sample::sample_lightmap;

/// A camera drawing into the capture image `target` from `transform` at `ev100`, as the render
/// tests compare pictures: no tonemapping, dithering or MSAA; the shadow maps' detail placed
/// at it (no camera draws to a window).
pub fn test_camera(target: Handle<Image>, transform: Transform, ev100: f32) -> impl Bundle {
    (
        Camera3d::default(),
        transform,
        RenderTarget::Image(target.into()),
        ShadowLodOrigin,
        DebandDither::Disabled,
        Tonemapping::None,
        Msaa::Off,
        Exposure { ev100 },
    )
}

/// The entity `spawn_scene` gave the instance of `scene` named `name`.
pub fn instance_entity(scene: &lightbake::scene::Scene, entities: &[Entity], name: &str) -> Entity {
    let i = (scene.instances.iter()).position(|i| i.name == name);
    entities[i.unwrap_or_else(|| panic!("no instance named {name}"))]
}

/// The pixel where the (single) camera sees world point `p`.
pub fn pixel(world: &mut World, p: Vec3) -> (u32, u32) {
    let mut q = world.query::<(&Camera, &GlobalTransform)>();
    let (camera, t) = q.single(world).unwrap();
    let v = camera.world_to_viewport(t, p).unwrap();
    (v.x as u32, v.y as u32)
}

/// Mean linear colour of the (2r + 1)² pixels around `(x, y)`.
pub fn mean_at(frame: &CapturedFrame, (x, y): (u32, u32), r: u32) -> Vec3 {
    frame.mean_linear(x - r, y - r, x + r + 1, y + r + 1)
}

/// E/π of `entity`'s lightmap at the surface point nearest `p`.
pub fn lightmap_at(world: &World, entity: Entity, p: Vec3) -> Vec3 {
    let mesh = world
        .resource::<Assets<Mesh>>()
        .get(&world.get::<Mesh3d>(entity).unwrap().0)
        .unwrap();
    let lm = world.get::<Lightmap>(entity).unwrap();
    let image = world.resource::<Assets<Image>>().get(&lm.image).unwrap();
    let t = world.get::<GlobalTransform>(entity).unwrap();
    sample_lightmap(mesh, t, lm.uv_rect, image, p).unwrap()
}

/// The `ev100` at which Bevy shows `entity`'s lightmapped surface at `p` (its albedo times its
/// lightmap) at a third of white: Bevy multiplies by 2^−ev100 / 1.2.
pub fn exposure_for(world: &World, entity: Entity, p: Vec3) -> f32 {
    let e = lightmap_at(world, entity, p);
    let material = world
        .get::<MeshMaterial3d<StandardMaterial>>(entity)
        .unwrap();
    let albedo = world
        .resource::<Assets<StandardMaterial>>()
        .get(&material.0)
        .unwrap()
        .base_color
        .to_linear();
    let shown = (e * Vec3::new(albedo.red, albedo.green, albedo.blue)).max_element();
    (shown.max(1e-6) / (0.33 * 1.2)).log2()
}

/// Updates `app` until its `n`-th bake has finished, every lightmap is attached and `also`
/// holds; panics when the bake fails.
pub fn wait_for_bake(app: &mut App, n: u32, mut also: impl FnMut(&mut World) -> bool) {
    loop {
        app.update();
        let world = app.world_mut();
        if let BakePhase::Failed(e) = &world.resource::<BakeStatus>().phase {
            panic!("bake failed: {e}");
        }
        let mut shown = world.query::<(&Lightmapped, Option<&Lightmap>)>();
        if world.resource::<BakeStatus>().completed == n
            && shown.iter(world).all(|(l, m)| l.is_shown_by(m))
            && also(world)
        {
            return;
        }
    }
}

/// The floor of a baked glTF of the sunlit room (the mesh entity under the node named
/// `floor`): its entity, page and albedo.
pub fn gltf_floor(world: &mut World) -> Option<(Entity, GltfPage, Vec3)> {
    let mut q = world.query::<(
        Entity,
        &GltfPage,
        &ChildOf,
        &MeshMaterial3d<StandardMaterial>,
    )>();
    let (entity, page, _, material) = q.iter(world).find(|(_, _, p, _)| {
        world
            .get::<Name>(p.parent())
            .is_some_and(|n| n.as_str() == "floor")
    })?;
    let c = world
        .resource::<Assets<StandardMaterial>>()
        .get(&material.0)?
        .base_color
        .to_linear();
    Some((entity, page.clone(), Vec3::new(c.red, c.green, c.blue)))
}

/// A camera 2.9 m above the sunlit room's floor looking down, its 100° view over most of the
/// floor (in the sun and in the shade), drawing into `target`.
pub fn sunlit_floor_camera(target: Handle<Image>) -> impl Bundle {
    (
        test_camera(
            target,
            Transform::from_xyz(-0.9, 2.9, -0.7)
                .looking_at(Vec3::new(-0.9, 0.0, -0.7), Vec3::NEG_Z),
            Exposure::default().ev100,
        ),
        Projection::Perspective(PerspectiveProjection {
            fov: 100f32.to_radians(),
            ..default()
        }),
    )
}

/// The mean of `value` over the points of the floor plane y = 0 that the (2r + 1)² pixels
/// around `(x, y)` see: what `mean_at` reads of the picture, texel noise and all.
pub fn mean_over_floor(
    world: &mut World,
    (x, y): (u32, u32),
    r: u32,
    value: impl Fn(&World, Vec3) -> Vec3,
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
            sum += value(world, ray.origin + along * *ray.direction);
        }
    }
    sum / ((2 * r + 1) * (2 * r + 1)) as f32
}
