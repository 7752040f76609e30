//! Scenes for the edge tests: [`contact_room`], a room full of the contacts a level has (a box
//! standing on the floor, a cabinet against a wall, a rug lying just above the floor, and a
//! partition thinner than a texel that splits the room into a lamp-lit half and a half lit
//! only through a doorway), and [`seam_room`], smooth surfaces the unwrap has to cut into
//! charts.

use glam::{Affine3A, Vec3};

use super::office::uv_sphere;
use super::{cuboid, plane, quad};
use crate::scene::{Instance, Light, LightKind, Material, Mesh, Scene};

/// The contact room: 4 × 2.5 × 3 m inside, 0.2 m thick walls, floor and ceiling; a 2 cm
/// partition at x = 0.5 from the back wall to a 0.8 m doorway; a 200 cd lamp in the left
/// half; a box (0.5 m) on the floor and a cabinet against the back wall on the left, a rug
/// (a double-sided plate 5 mm above the floor) in front of them, a box on the floor of the
/// right half. 20 texels per metre (`texel_density_hint`): the partition is 0.4 texels thick.
pub fn contact_room() -> Scene {
    let mut s = Scene {
        name: "contact_room".into(),
        texel_density_hint: Some(20.0),
        ..Scene::default()
    };
    let plaster = s.add_material(Material::diffuse("plaster", Vec3::new(0.78, 0.76, 0.72)));
    let wood = s.add_material(Material::diffuse("wood", Vec3::new(0.5, 0.36, 0.22)));
    let paint = s.add_material(Material::diffuse("paint", Vec3::new(0.35, 0.5, 0.72)));
    let rug = s.add_material(Material {
        double_sided: true,
        ..Material::diffuse("rug", Vec3::new(0.7, 0.2, 0.15))
    });
    let t = 0.2;
    let (x0, x1, y1, z0, z1) = (-2.0f32, 2.0f32, 2.5f32, -1.5f32, 1.5f32);
    let boxes: [(&str, Vec3, Vec3, usize); 10] = [
        (
            "floor",
            Vec3::new(x0 - t, -t, z0 - t),
            Vec3::new(x1 + t, 0.0, z1 + t),
            wood,
        ),
        (
            "ceiling",
            Vec3::new(x0 - t, y1, z0 - t),
            Vec3::new(x1 + t, y1 + t, z1 + t),
            plaster,
        ),
        (
            "wall_left",
            Vec3::new(x0 - t, 0.0, z0 - t),
            Vec3::new(x0, y1, z1 + t),
            plaster,
        ),
        (
            "wall_right",
            Vec3::new(x1, 0.0, z0 - t),
            Vec3::new(x1 + t, y1, z1 + t),
            plaster,
        ),
        (
            "wall_back",
            Vec3::new(x0, 0.0, z0 - t),
            Vec3::new(x1, y1, z0),
            plaster,
        ),
        (
            "wall_front",
            Vec3::new(x0, 0.0, z1),
            Vec3::new(x1, y1, z1 + t),
            plaster,
        ),
        (
            "partition",
            Vec3::new(0.49, 0.0, z0),
            Vec3::new(0.51, y1, 0.7),
            paint,
        ),
        (
            "box",
            Vec3::new(-1.4, 0.0, -1.0),
            Vec3::new(-0.9, 0.5, -0.5),
            paint,
        ),
        (
            "cabinet",
            Vec3::new(-0.6, 0.0, z0),
            Vec3::new(0.2, 0.9, -1.1),
            wood,
        ),
        (
            "box_dark",
            Vec3::new(1.2, 0.0, -0.8),
            Vec3::new(1.7, 0.4, -0.3),
            paint,
        ),
    ];
    for (name, lo, hi, mat) in boxes {
        let m = s.add_mesh(Mesh {
            material: Some(mat),
            ..cuboid(name, lo, hi, lo.y == 0.0)
        });
        s.instances.push(Instance::new(name, m, Affine3A::IDENTITY));
    }
    let y = 0.005;
    let m = s.add_mesh(Mesh {
        material: Some(rug),
        ..quad(
            "rug",
            [
                Vec3::new(-1.8, y, 0.2),
                Vec3::new(-0.6, y, 0.2),
                Vec3::new(-0.6, y, 1.0),
                Vec3::new(-1.8, y, 1.0),
            ],
            Vec3::Y,
        )
    });
    s.instances
        .push(Instance::new("rug", m, Affine3A::IDENTITY));
    s.lights.push(Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::new(1.0, 0.92, 0.8),
        intensity: 200.0,
        range: None,
        position: Vec3::new(-1.0, 2.0, 0.0),
        direction: Vec3::NEG_Y,
        bake: crate::scene::LightBake::Full,
    });
    s
}

/// Smooth surfaces split between charts: a sphere (0.5 m, smooth normals, cut by the unwrap
/// and along its own UV seam) resting on a 4 m floor, and a smooth-shaded cylinder (0.3 m,
/// 1.2 m high) standing beside it, lit by a 40 cd lamp; 40 texels per metre.
pub fn seam_room() -> Scene {
    let mut s = Scene {
        name: "seam_room".into(),
        texel_density_hint: Some(40.0),
        ..Scene::default()
    };
    let grey = s.add_material(Material::diffuse("grey", Vec3::splat(0.6)));
    let white = s.add_material(Material::diffuse("white", Vec3::new(0.8, 0.78, 0.75)));
    let floor = s.add_mesh(Mesh {
        material: Some(grey),
        ..plane("floor", 4.0)
    });
    s.instances
        .push(Instance::new("floor", floor, Affine3A::IDENTITY));
    let sphere = s.add_mesh(Mesh {
        material: Some(white),
        ..uv_sphere("sphere", 0.5, 24, 48)
    });
    s.instances.push(Instance::new(
        "sphere",
        sphere,
        Affine3A::from_translation(Vec3::new(-0.6, 0.5, 0.0)),
    ));
    let cylinder = s.add_mesh(Mesh {
        material: Some(white),
        ..smooth_cylinder("cylinder", 0.3, 1.2, 32)
    });
    s.instances.push(Instance::new(
        "cylinder",
        cylinder,
        Affine3A::from_translation(Vec3::new(0.8, 0.0, -0.3)),
    ));
    s.lights.push(Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 40.0,
        range: None,
        position: Vec3::new(0.4, 2.2, 1.2),
        direction: Vec3::NEG_Y,
        bake: crate::scene::LightBake::Full,
    });
    s
}

/// The side of a cylinder of `radius` and `height` standing on y = 0, with `segments` quads
/// and outward normals interpolated around it (a smooth surface), and a flat top.
fn smooth_cylinder(name: &str, radius: f32, height: f32, segments: u32) -> Mesh {
    let mut m = Mesh {
        name: name.into(),
        ..Mesh::default()
    };
    for k in 0..=segments {
        let phi = std::f32::consts::TAU * k as f32 / segments as f32;
        let n = Vec3::new(phi.cos(), 0.0, phi.sin());
        for y in [0.0, height] {
            m.positions.push(n * radius + Vec3::Y * y);
            m.normals.push(n);
        }
    }
    for k in 0..segments {
        let (a, b, c, d) = (2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3);
        // Counter-clockwise seen from outside.
        m.indices.extend_from_slice(&[a, b, d, a, d, c]);
    }
    let centre = m.positions.len() as u32;
    m.positions.push(Vec3::Y * height);
    m.normals.push(Vec3::Y);
    let first = centre + 1;
    for k in 0..=segments {
        let phi = std::f32::consts::TAU * k as f32 / segments as f32;
        m.positions
            .push(Vec3::new(phi.cos() * radius, height, phi.sin() * radius));
        m.normals.push(Vec3::Y);
    }
    for k in 0..segments {
        m.indices
            .extend_from_slice(&[centre, first + k + 1, first + k]);
    }
    m
}
