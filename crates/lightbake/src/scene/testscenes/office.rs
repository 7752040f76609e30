//! A generated office floor: the corpus's large scene, with many instances of shared meshes
//! and more than 200 000 triangles at its default size.
//!
//! A grid of rooms 6 m × 5 m × 3 m under one ceiling slab, on one floor slab. The façades on
//! −Z and +Z have a window per room; the walls between rooms are 12 cm thick, each with a
//! door opening. Each room holds four desks and four chairs, two bookshelves, a plant in a
//! pot and a globe lamp hanging under the ceiling (the high-polygon parts), all instances of
//! shared meshes placed with a little deterministic jitter; a point light hangs under each
//! globe. The sun and a sky light the façades and shine in through the windows; a ground
//! plane surrounds the building. Walls are boxes of their own (each a mesh), so every
//! contact — a wall standing on the slab, a desk against a wall, a shelf on the floor — is
//! real geometry meeting real geometry.

use glam::{Affine3A, Quat, Vec2, Vec3};

use super::{cuboid, merge, plane};
use crate::sampling::{hash_words, unit_float};
use crate::scene::{Instance, Light, LightKind, Material, Mesh, Scene};

/// Room size, m (x, height, z).
const ROOM: Vec3 = Vec3::new(6.0, 3.0, 5.0);
/// Exterior wall thickness, m.
const OUTER: f32 = 0.25;
/// Interior wall thickness, m.
const INNER: f32 = 0.12;
/// Slab thickness, m.
const SLAB: f32 = 0.3;

/// A UV sphere of `radius` about the origin with `rings` × `segments` quads (the poles' as
/// triangles), normals outward.
pub fn uv_sphere(name: &str, radius: f32, rings: u32, segments: u32) -> Mesh {
    let mut m = Mesh {
        name: name.into(),
        ..Mesh::default()
    };
    let mut uv0 = Vec::new();
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            m.positions.push(n * radius);
            m.normals.push(n);
            uv0.push(Vec2::new(
                s as f32 / segments as f32,
                r as f32 / rings as f32,
            ));
        }
    }
    let row = segments + 1;
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            // Counter-clockwise seen from outside: (a, b, d) and (a, d, c).
            if r > 0 {
                m.indices.extend_from_slice(&[a, b, d]);
            }
            if r + 1 < rings {
                m.indices.extend_from_slice(&[a, d, c]);
            }
        }
    }
    m.uv0 = Some(uv0);
    m
}

/// A closed cylinder of `radius` standing on the origin, `height` tall, with `segments` sides.
pub fn cylinder(name: &str, radius: f32, height: f32, segments: u32) -> Mesh {
    let mut parts = Vec::new();
    let at = |k: u32| {
        let phi = std::f32::consts::TAU * k as f32 / segments as f32;
        Vec3::new(phi.cos(), 0.0, phi.sin())
    };
    for k in 0..segments {
        let (a, b) = (at(k), at(k + 1));
        let up = Vec3::Y * height;
        // The side, wound outwards, with radial normals at its edges.
        parts.push(Mesh {
            name: name.into(),
            positions: vec![a * radius, a * radius + up, b * radius + up, b * radius],
            normals: vec![a, a, b, b],
            uv0: Some(vec![Vec2::ZERO; 4]),
            indices: vec![0, 1, 2, 0, 2, 3],
            ..Mesh::default()
        });
        parts.push(triangle_mesh(
            name,
            [up, b * radius + up, a * radius + up],
            Vec3::Y,
        ));
        parts.push(triangle_mesh(
            name,
            [Vec3::ZERO, a * radius, b * radius],
            Vec3::NEG_Y,
        ));
    }
    merge(name, parts)
}

/// One flat triangle wound to face `facing`.
fn triangle_mesh(name: &str, mut c: [Vec3; 3], facing: Vec3) -> Mesh {
    if (c[1] - c[0]).cross(c[2] - c[0]).dot(facing) < 0.0 {
        c.swap(1, 2);
    }
    let n = (c[1] - c[0]).cross(c[2] - c[0]).normalize();
    Mesh {
        name: name.into(),
        positions: c.to_vec(),
        normals: vec![n; 3],
        uv0: Some(vec![Vec2::ZERO; 3]),
        indices: vec![0, 1, 2],
        ..Mesh::default()
    }
}

/// Boxes (min, max) merged into one mesh, each open at the bottom when it stands on y = 0.
fn boxes(name: &str, parts: &[(Vec3, Vec3)]) -> Mesh {
    merge(
        name,
        parts
            .iter()
            .map(|&(lo, hi)| cuboid(name, lo, hi, lo.y <= 0.0)),
    )
}

/// The furniture meshes, in their own frames (standing on y = 0, centred on x = z = 0).
struct Furniture {
    desk: usize,
    chair: usize,
    shelf: usize,
    pot: usize,
    plant: usize,
    globe: usize,
}

impl Furniture {
    fn add(s: &mut Scene) -> Self {
        let wood = s.add_material(Material::diffuse("desk wood", Vec3::new(0.55, 0.4, 0.25)));
        let fabric = s.add_material(Material::diffuse("chair fabric", Vec3::new(0.2, 0.3, 0.55)));
        let shelf_board = s.add_material(Material::diffuse("shelf", Vec3::splat(0.6)));
        let clay = s.add_material(Material::diffuse("clay", Vec3::new(0.6, 0.3, 0.2)));
        let leaves = s.add_material(Material::diffuse("leaves", Vec3::new(0.15, 0.4, 0.1)));
        let glass = s.add_material(Material::diffuse("lamp globe", Vec3::splat(0.9)));
        let leg = 0.05;
        let legs = |w: f32, d: f32, h: f32| -> Vec<(Vec3, Vec3)> {
            [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|&(sx, sz)| {
                    let c = Vec3::new(sx * (w / 2.0 - leg), 0.0, sz * (d / 2.0 - leg));
                    (
                        c - Vec3::new(leg / 2.0, 0.0, leg / 2.0),
                        c + Vec3::new(leg / 2.0, h, leg / 2.0),
                    )
                })
                .collect()
        };
        let mut desk = legs(1.6, 0.8, 0.7);
        desk.push((Vec3::new(-0.8, 0.7, -0.4), Vec3::new(0.8, 0.74, 0.4)));
        let mut chair = legs(0.46, 0.46, 0.45);
        chair.push((Vec3::new(-0.23, 0.45, -0.23), Vec3::new(0.23, 0.5, 0.23)));
        chair.push((Vec3::new(-0.23, 0.5, 0.18), Vec3::new(0.23, 0.95, 0.23)));
        let mut shelf = vec![
            (Vec3::new(-0.5, 0.0, -0.18), Vec3::new(-0.48, 2.0, 0.18)),
            (Vec3::new(0.48, 0.0, -0.18), Vec3::new(0.5, 2.0, 0.18)),
            (Vec3::new(-0.48, 0.0, 0.16), Vec3::new(0.48, 2.0, 0.18)),
        ];
        for k in 0..5 {
            let y = 0.05 + 0.45 * k as f32;
            shelf.push((Vec3::new(-0.48, y, -0.18), Vec3::new(0.48, y + 0.02, 0.16)));
        }
        let mut add = |mesh: Mesh, material: usize| {
            s.add_mesh(Mesh {
                material: Some(material),
                ..mesh
            })
        };
        let mut plant = uv_sphere("plant", 0.35, 24, 48);
        for p in &mut plant.positions {
            *p += Vec3::new(0.0, 0.75, 0.0);
        }
        Self {
            desk: add(boxes("desk", &desk), wood),
            chair: add(boxes("chair", &chair), fabric),
            shelf: add(boxes("bookshelf", &shelf), shelf_board),
            pot: add(cylinder("pot", 0.2, 0.4, 32), clay),
            plant: add(plant, leaves),
            globe: add(uv_sphere("lamp globe", 0.25, 32, 64), glass),
        }
    }
}

/// An office floor of `rooms_x` × `rooms_z` rooms (see the module docs). 8 × 6 rooms give
/// 336 846 triangles in 939 instances, and 49 point lights.
pub fn office_level(rooms_x: u32, rooms_z: u32) -> Scene {
    let mut s = Scene {
        name: format!("office_{rooms_x}x{rooms_z}"),
        sky: Vec3::new(0.6, 0.75, 1.0) * 2000.0,
        ..Scene::default()
    };
    let plaster = s.add_material(Material::diffuse("plaster", Vec3::new(0.8, 0.78, 0.74)));
    let carpet = s.add_material(Material::diffuse("carpet", Vec3::new(0.35, 0.33, 0.3)));
    let concrete = s.add_material(Material::diffuse("concrete", Vec3::splat(0.55)));
    let ground = s.add_material(Material::diffuse("ground", Vec3::new(0.2, 0.3, 0.1)));
    let furniture = Furniture::add(&mut s);
    let (w, h, d) = (ROOM.x * rooms_x as f32, ROOM.y, ROOM.z * rooms_z as f32);
    let solid = |s: &mut Scene, name: String, lo: Vec3, hi: Vec3, material: usize| {
        let m = s.add_mesh(Mesh {
            material: Some(material),
            ..cuboid(&name, lo, hi, lo.y == 0.0)
        });
        s.instances.push(Instance::new(name, m, Affine3A::IDENTITY));
    };
    let o = OUTER;
    solid(
        &mut s,
        "floor slab".into(),
        Vec3::new(-o, -SLAB, -o),
        Vec3::new(w + o, 0.0, d + o),
        carpet,
    );
    solid(
        &mut s,
        "ceiling slab".into(),
        Vec3::new(-o, h, -o),
        Vec3::new(w + o, h + SLAB, d + o),
        concrete,
    );
    // Side façades (x = 0 and x = w): solid, full depth.
    solid(
        &mut s,
        "facade west".into(),
        Vec3::new(-o, 0.0, -o),
        Vec3::new(0.0, h, d + o),
        plaster,
    );
    solid(
        &mut s,
        "facade east".into(),
        Vec3::new(w, 0.0, -o),
        Vec3::new(w + o, h, d + o),
        plaster,
    );
    // Front and back façades: a window 2 m × 1.4 m (sill 0.9 m) in every room.
    for (side, z0, z1) in [("south", -o, 0.0), ("north", d, d + o)] {
        for ix in 0..rooms_x {
            let x0 = ix as f32 * ROOM.x;
            let (wx0, wx1) = (x0 + 2.0, x0 + 4.0);
            let name = |part: &str| format!("facade {side} {ix} {part}");
            solid(
                &mut s,
                name("left"),
                Vec3::new(x0, 0.0, z0),
                Vec3::new(wx0, h, z1),
                plaster,
            );
            solid(
                &mut s,
                name("right"),
                Vec3::new(wx1, 0.0, z0),
                Vec3::new(x0 + ROOM.x, h, z1),
                plaster,
            );
            solid(
                &mut s,
                name("sill"),
                Vec3::new(wx0, 0.0, z0),
                Vec3::new(wx1, 0.9, z1),
                plaster,
            );
            solid(
                &mut s,
                name("lintel"),
                Vec3::new(wx0, 2.3, z0),
                Vec3::new(wx1, h, z1),
                plaster,
            );
        }
    }
    // Interior walls with a door (0.9 m × 2.1 m): along x between room columns (full
    // depth of each room), along z between room rows (between the x walls).
    let t = INNER / 2.0;
    for ix in 1..rooms_x {
        let x = ix as f32 * ROOM.x;
        for iz in 0..rooms_z {
            let (z0, z1) = (iz as f32 * ROOM.z, (iz + 1) as f32 * ROOM.z);
            let (dz0, dz1) = (z0 + 1.0, z0 + 1.9);
            let name = |part: &str| format!("wall x{ix} z{iz} {part}");
            solid(
                &mut s,
                name("a"),
                Vec3::new(x - t, 0.0, z0),
                Vec3::new(x + t, h, dz0),
                plaster,
            );
            solid(
                &mut s,
                name("b"),
                Vec3::new(x - t, 0.0, dz1),
                Vec3::new(x + t, h, z1),
                plaster,
            );
            solid(
                &mut s,
                name("over door"),
                Vec3::new(x - t, 2.1, dz0),
                Vec3::new(x + t, h, dz1),
                plaster,
            );
        }
    }
    for iz in 1..rooms_z {
        let z = iz as f32 * ROOM.z;
        for ix in 0..rooms_x {
            let x0 = ix as f32 * ROOM.x + if ix > 0 { t } else { 0.0 };
            let x1 = (ix + 1) as f32 * ROOM.x - if ix + 1 < rooms_x { t } else { 0.0 };
            let (dx0, dx1) = (x0 + 4.5, x0 + 5.4);
            let name = |part: &str| format!("wall z{iz} x{ix} {part}");
            solid(
                &mut s,
                name("a"),
                Vec3::new(x0, 0.0, z - t),
                Vec3::new(dx0, h, z + t),
                plaster,
            );
            solid(
                &mut s,
                name("b"),
                Vec3::new(dx1, 0.0, z - t),
                Vec3::new(x1, h, z + t),
                plaster,
            );
            solid(
                &mut s,
                name("over door"),
                Vec3::new(dx0, 2.1, z - t),
                Vec3::new(dx1, h, z + t),
                plaster,
            );
        }
    }
    // Furniture and lights, room by room.
    for iz in 0..rooms_z {
        for ix in 0..rooms_x {
            furnish(&mut s, &furniture, ix, iz);
        }
    }
    let ground_mesh = s.add_mesh(Mesh {
        material: Some(ground),
        ..plane("ground", 4.0 * w.max(d))
    });
    let mut g = Instance::new(
        "ground",
        ground_mesh,
        Affine3A::from_translation(Vec3::new(w / 2.0, -SLAB - 0.001, d / 2.0)),
    );
    g.texel_density_scale = 0.125;
    s.instances.push(g);
    let (elevation, azimuth) = (35f32.to_radians(), 200f32.to_radians());
    s.lights.push(Light {
        name: "sun".into(),
        kind: LightKind::Directional {
            angular_radius: 0.00465,
        },
        color: Vec3::new(1.0, 0.95, 0.88),
        intensity: 80_000.0,
        range: None,
        position: Vec3::ZERO,
        direction: -Vec3::new(
            elevation.cos() * azimuth.sin(),
            elevation.sin(),
            elevation.cos() * azimuth.cos(),
        ),
        bake: crate::scene::LightBake::Full,
    });
    s
}

/// Room (ix, iz)'s furniture, its globe lamp and the point light under it.
fn furnish(s: &mut Scene, f: &Furniture, ix: u32, iz: u32) {
    let origin = Vec3::new(ix as f32 * ROOM.x, 0.0, iz as f32 * ROOM.z);
    let jitter = |k: u32| unit_float(hash_words(&[ix, iz, k])) - 0.5;
    let mut place = |name: String, mesh: usize, at: Vec3, turn: f32| {
        let transform =
            Affine3A::from_rotation_translation(Quat::from_rotation_y(turn), origin + at);
        s.instances.push(Instance::new(name, mesh, transform));
    };
    let room = format!("room {ix} {iz}");
    // Two pairs of desks facing each other, a chair at each.
    for k in 0..4u32 {
        let (col, row) = ((k % 2) as f32, (k / 2) as f32);
        let at = Vec3::new(1.6 + 2.2 * col, 0.0, 1.6 + 1.0 * row);
        let turn = if row == 0.0 {
            0.0
        } else {
            std::f32::consts::PI
        };
        place(
            format!("{room} desk {k}"),
            f.desk,
            at,
            turn + 0.05 * jitter(k),
        );
        let side = if row == 0.0 { -0.65 } else { 0.65 };
        place(
            format!("{room} chair {k}"),
            f.chair,
            at + Vec3::new(0.2 * jitter(10 + k), 0.0, side),
            turn + 0.6 * jitter(20 + k),
        );
    }
    // Bookshelves against the west wall (their backs touch it), a plant in the corner.
    for k in 0..2u32 {
        let at = Vec3::new(INNER / 2.0 + 0.18, 0.0, 3.2 + 1.0 * k as f32);
        place(
            format!("{room} bookshelf {k}"),
            f.shelf,
            at,
            -std::f32::consts::FRAC_PI_2,
        );
    }
    let pot = Vec3::new(ROOM.x - 0.5, 0.0, ROOM.z - 0.5);
    place(format!("{room} pot"), f.pot, pot, 0.0);
    place(format!("{room} plant"), f.plant, pot, jitter(30));
    let lamp = Vec3::new(ROOM.x / 2.0, ROOM.y - 0.45, ROOM.z / 2.0);
    place(format!("{room} lamp globe"), f.globe, lamp, 0.0);
    s.lights.push(Light {
        name: format!("{room} lamp"),
        kind: LightKind::Point,
        color: Vec3::new(1.0, 0.9, 0.75),
        // About a 2 000 lm lamp; Bevy's range window ends its reach in the next rooms.
        intensity: 160.0,
        range: Some(8.0),
        position: origin + lamp - Vec3::new(0.0, 0.35, 0.0),
        direction: Vec3::NEG_Y,
        bake: crate::scene::LightBake::Full,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_office_is_large_valid_and_wound_outwards() {
        let s = office_level(8, 6);
        s.validate().unwrap();
        let triangles = s.instanced_triangle_count();
        assert!(triangles > 200_000, "{triangles} triangles");
        assert!(s.instances.len() > 500, "{} instances", s.instances.len());
        for m in &s.meshes {
            for t in 0..m.triangle_count() {
                let [a, b, c] = m.triangle(t);
                let g = (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]);
                if g.length() > 1e-9 {
                    assert!(g.dot(m.normals[a]) > 0.0, "{} triangle {t}", m.name);
                }
            }
        }
    }
}
