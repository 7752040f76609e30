//! A core [`Scene`] → ordinary Bevy entities: meshes with `StandardMaterial`s, Bevy lights in
//! Bevy's units, and the sky as `GlobalAmbientLight`. The inverse of
//! [`crate::convert::extract_scene`] — the examples spawn the core's test scenes with it, and
//! the tests check that a scene survives the round trip.

use std::f32::consts::PI;

use bevy::asset::RenderAssetUsages;
use bevy::image::{ImageAddressMode, ImageSampler, ImageSamplerDescriptor};
use bevy::light::{GlobalAmbientLight, RectLight};
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use lightbake::scene::{LightKind, Scene, Wrap};

use crate::components::Lightbaked;

/// Range given to a core light with no range (infinite): this many scene diagonals. Bevy's
/// range window (1 − (d/r)⁴)² then differs from 1 by less than 2·10⁻⁴ inside the scene.
pub const UNBOUNDED_RANGE_DIAGONALS: f32 = 10.0;

fn v3(v: lightbake::glam::Vec3) -> Vec3 {
    Vec3::from_array(v.to_array())
}

/// A core mesh as a Bevy triangle list (positions, normals, `UV_0` and `UV_1` when present).
pub fn bevy_mesh(mesh: &lightbake::scene::Mesh) -> Mesh {
    let mut out = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        mesh.positions
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        mesh.normals
            .iter()
            .map(|p| p.to_array())
            .collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(mesh.indices.clone()));
    if let Some(uv) = &mesh.uv0 {
        out.insert_attribute(
            Mesh::ATTRIBUTE_UV_0,
            uv.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        );
    }
    if let Some(uv) = &mesh.uv1 {
        out.insert_attribute(
            Mesh::ATTRIBUTE_UV_1,
            uv.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        );
    }
    out
}

fn bevy_image(t: &lightbake::scene::Texture) -> Image {
    let mut image = Image::new(
        Extent3d {
            width: t.width,
            height: t.height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        t.rgba8.iter().flatten().copied().collect(),
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    );
    let mode = |w: Wrap| match w {
        Wrap::Repeat => ImageAddressMode::Repeat,
        Wrap::MirroredRepeat => ImageAddressMode::MirrorRepeat,
        Wrap::ClampToEdge => ImageAddressMode::ClampToEdge,
    };
    image.sampler = ImageSampler::Descriptor(ImageSamplerDescriptor {
        address_mode_u: mode(t.wrap_u),
        address_mode_v: mode(t.wrap_v),
        ..ImageSamplerDescriptor::linear()
    });
    image
}

/// Spawns `scene` into `world`: one entity per instance (`Mesh3d`, `MeshMaterial3d`,
/// `Transform`, `Name`, and [`Lightbaked::default`] — or [`Lightbaked::occluder`] for an
/// instance that is not baked), one per light (lumens = 4π × candela; shadow maps on, so that
/// Bevy's real-time lighting of the scene casts shadows too), and the sky as
/// `GlobalAmbientLight` (brightness = the sky's largest channel, colour = the sky over it).
/// Returns the instance entities in scene order.
pub fn spawn_scene(world: &mut World, scene: &Scene) -> Vec<Entity> {
    let textures: Vec<Handle<Image>> = {
        let mut images = world.resource_mut::<Assets<Image>>();
        scene
            .textures
            .iter()
            .map(|t| images.add(bevy_image(t)))
            .collect()
    };
    let materials: Vec<Handle<StandardMaterial>> = {
        let mut assets = world.resource_mut::<Assets<StandardMaterial>>();
        scene
            .materials
            .iter()
            .map(|m| assets.add(standard_material(m, &textures)))
            .collect()
    };
    let default_material = world
        .resource_mut::<Assets<StandardMaterial>>()
        .add(StandardMaterial {
            perceptual_roughness: 1.0,
            ..default()
        });
    let meshes: Vec<Handle<Mesh>> = {
        let mut assets = world.resource_mut::<Assets<Mesh>>();
        scene
            .meshes
            .iter()
            .map(|m| assets.add(bevy_mesh(m)))
            .collect()
    };
    let mut entities = Vec::new();
    for inst in &scene.instances {
        let mesh = &scene.meshes[inst.mesh];
        let material = mesh
            .material
            .map_or_else(|| default_material.clone(), |m| materials[m].clone());
        let transform = Transform::from_matrix(Mat4::from_cols_array(
            &lightbake::glam::Mat4::from(inst.transform).to_cols_array(),
        ));
        let baked = if inst.bake {
            Lightbaked::default()
        } else {
            Lightbaked::occluder()
        };
        entities.push(
            world
                .spawn((
                    Mesh3d(meshes[inst.mesh].clone()),
                    MeshMaterial3d(material),
                    transform,
                    baked,
                    Name::new(inst.name.clone()),
                ))
                .id(),
        );
    }
    let (lo, hi) = scene.bounds();
    let unbounded = UNBOUNDED_RANGE_DIAGONALS * (hi - lo).length().max(1e-3);
    for l in &scene.lights {
        spawn_light(world, l, unbounded);
    }
    let peak = scene.sky.max_element();
    let sky_color = if peak > 0.0 {
        scene.sky / peak
    } else {
        lightbake::glam::Vec3::ONE
    };
    world.insert_resource(GlobalAmbientLight {
        color: Color::linear_rgb(sky_color.x, sky_color.y, sky_color.z),
        brightness: peak,
        ..default()
    });
    entities
}

/// A core material as a `StandardMaterial` (roughness 1; back faces culled when single-sided).
fn standard_material(
    m: &lightbake::scene::Material,
    textures: &[Handle<Image>],
) -> StandardMaterial {
    let c = m.base_color;
    StandardMaterial {
        base_color: Color::linear_rgba(c.x, c.y, c.z, c.w),
        base_color_texture: m.base_color_texture.map(|t| textures[t.texture].clone()),
        emissive: LinearRgba::rgb(m.emissive.x, m.emissive.y, m.emissive.z),
        emissive_texture: m.emissive_texture.map(|t| textures[t.texture].clone()),
        metallic: m.metallic,
        perceptual_roughness: 1.0,
        double_sided: m.double_sided,
        cull_mode: if m.double_sided {
            None
        } else {
            Some(bevy::render::render_resource::Face::Back)
        },
        ..default()
    }
}

/// Spawns one core light as Bevy's light of its kind (lumens = 4π × candela; a light with no
/// range gets `unbounded`).
fn spawn_light(world: &mut World, l: &lightbake::scene::Light, unbounded: f32) {
    let color = Color::linear_rgb(l.color.x, l.color.y, l.color.z);
    let position = v3(l.position);
    let looking = Transform::from_translation(position)
        .looking_to(v3(l.direction), perpendicular(v3(l.direction)));
    let lumens = l.intensity * 4.0 * PI;
    let range = l.range.unwrap_or(unbounded);
    let name = Name::new(l.name.clone());
    let mut entity = match l.kind {
        LightKind::Point => world.spawn((
            PointLight {
                color,
                intensity: lumens,
                range,
                shadow_maps_enabled: true,
                ..default()
            },
            looking,
            name,
        )),
        LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => world.spawn((
            SpotLight {
                color,
                intensity: lumens,
                range,
                inner_angle: inner_cone_angle,
                outer_angle: outer_cone_angle,
                shadow_maps_enabled: true,
                ..default()
            },
            looking,
            name,
        )),
        LightKind::Directional { angular_radius } => {
            let mut e = world.spawn((
                DirectionalLight {
                    color,
                    illuminance: l.intensity,
                    shadow_maps_enabled: true,
                    ..default()
                },
                looking,
                name,
            ));
            if angular_radius > 0.0 {
                e.insert(bevy::light::SunDisk {
                    angular_size: 2.0 * angular_radius,
                    intensity: 1.0,
                });
            }
            e
        }
        LightKind::Rect {
            right,
            width,
            height,
        } => {
            // Local −Z along the facing and local X along `right` (so local Y = right ×
            // facing): Bevy's rectangle frame.
            let facing = v3(l.direction);
            let up = v3(right).cross(facing).normalize_or(perpendicular(facing));
            let frame = Transform::from_translation(position).looking_to(facing, up);
            world.spawn((
                RectLight {
                    color,
                    intensity: l.intensity * PI * width * height,
                    range,
                    width,
                    height,
                },
                frame,
                name,
            ))
        }
    };
    if !l.direct_is_baked() {
        entity.insert(crate::components::BakeMode::IndirectOnly);
    }
}

/// Any unit vector perpendicular to `d` (an "up" for `looking_to`).
fn perpendicular(d: Vec3) -> Vec3 {
    if d.y.abs() < 0.9 { Vec3::Y } else { Vec3::Z }
}
