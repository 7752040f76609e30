//! Scenes built in code: the shipped assets (`assets/*.gltf` are written from these by
//! `cargo run --example make_assets`), test fixtures and benchmark scenes.
//!
//! * [`cornell_box`]: the classic Cornell box (Cornell Program of Computer Graphics
//!   measurements, converted from millimetres to metres and turned 180° about +Y so the open
//!   side faces +Z as a glTF camera expects), lit by its ceiling area light or by a point light.
//! * [`sunlit_room`]: a room with thick walls, a window, two pillars and a thin partition,
//!   lit by the sun and the sky through the window.
//! * [`office_level`]: a generated office floor, the corpus's large scene (many instances,
//!   200 000+ triangles; [`office`]).
//! * [`contact_room`]: a room of contacts (a box on the floor, a cabinet against a wall, a rug,
//!   a partition thinner than a texel), for the edge tests ([`edges`]).
//! * [`plane`], [`quad`], [`cuboid`], [`grid`]: mesh builders.

use glam::{Affine3A, Vec2, Vec3};

use super::{Instance, Light, LightKind, Material, Mesh, Scene};

pub mod edges;
pub mod office;
pub use edges::{contact_room, seam_room};
pub use office::office_level;

/// A flat quad with corners `c` (any winding), triangulated as (0,1,2),(0,2,3) and wound so
/// its front face looks along `facing`.
pub fn quad(name: &str, c: [Vec3; 4], facing: Vec3) -> Mesh {
    let n = (c[1] - c[0]).cross(c[2] - c[0]);
    let corners = if n.dot(facing) >= 0.0 {
        c
    } else {
        [c[0], c[3], c[2], c[1]]
    };
    let normal = (corners[1] - corners[0])
        .cross(corners[2] - corners[0])
        .normalize();
    let uv0 = vec![
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    Mesh {
        name: name.into(),
        positions: corners.to_vec(),
        normals: vec![normal; 4],
        uv0: Some(uv0),
        uv1: None,
        indices: vec![0, 1, 2, 0, 2, 3],
        material: None,
        source: None,
    }
}

/// A square plane of side `size` metres in XZ at y = 0, facing +Y, centred on the origin.
pub fn plane(name: &str, size: f32) -> Mesh {
    let h = 0.5 * size;
    quad(
        name,
        [
            Vec3::new(-h, 0.0, -h),
            Vec3::new(h, 0.0, -h),
            Vec3::new(h, 0.0, h),
            Vec3::new(-h, 0.0, h),
        ],
        Vec3::Y,
    )
}

/// A plane of side `size` in XZ facing +Y, split into `n × n` cells (2n² triangles).
pub fn grid(name: &str, size: f32, n: u32) -> Mesh {
    let mut m = Mesh {
        name: name.into(),
        ..Mesh::default()
    };
    let h = 0.5 * size;
    let mut uv0 = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
            m.positions
                .push(Vec3::new(-h + size * u, 0.0, -h + size * v));
            m.normals.push(Vec3::Y);
            uv0.push(Vec2::new(u, v));
        }
    }
    let row = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * row + i;
            // Counter-clockwise seen from +Y.
            m.indices
                .extend_from_slice(&[a, a + row, a + row + 1, a, a + row + 1, a + 1]);
        }
    }
    m.uv0 = Some(uv0);
    m
}

/// An axis-aligned box from `min` to `max` with outward-facing flat-shaded faces
/// (24 vertices, 12 triangles). `skip_bottom` leaves out the −Y face (boxes resting on a floor).
pub fn cuboid(name: &str, min: Vec3, max: Vec3, skip_bottom: bool) -> Mesh {
    let c = |x: bool, y: bool, z: bool| {
        Vec3::new(
            if x { max.x } else { min.x },
            if y { max.y } else { min.y },
            if z { max.z } else { min.z },
        )
    };
    let faces: [([Vec3; 4], Vec3); 6] = [
        (
            [
                c(true, false, false),
                c(true, true, false),
                c(true, true, true),
                c(true, false, true),
            ],
            Vec3::X,
        ),
        (
            [
                c(false, false, false),
                c(false, false, true),
                c(false, true, true),
                c(false, true, false),
            ],
            Vec3::NEG_X,
        ),
        (
            [
                c(false, true, false),
                c(false, true, true),
                c(true, true, true),
                c(true, true, false),
            ],
            Vec3::Y,
        ),
        (
            [
                c(false, false, false),
                c(true, false, false),
                c(true, false, true),
                c(false, false, true),
            ],
            Vec3::NEG_Y,
        ),
        (
            [
                c(false, false, true),
                c(true, false, true),
                c(true, true, true),
                c(false, true, true),
            ],
            Vec3::Z,
        ),
        (
            [
                c(false, false, false),
                c(false, true, false),
                c(true, true, false),
                c(true, false, false),
            ],
            Vec3::NEG_Z,
        ),
    ];
    merge(
        name,
        faces
            .iter()
            .filter(|(_, n)| !(skip_bottom && *n == Vec3::NEG_Y))
            .map(|(corners, n)| quad(name, *corners, *n)),
    )
}

/// Concatenates meshes into one (same material).
pub fn merge(name: &str, parts: impl IntoIterator<Item = Mesh>) -> Mesh {
    let mut m = Mesh {
        name: name.into(),
        uv0: Some(Vec::new()),
        ..Mesh::default()
    };
    for p in parts {
        let base = m.positions.len() as u32;
        m.positions.extend_from_slice(&p.positions);
        m.normals.extend_from_slice(&p.normals);
        let uv = p.uv0.unwrap_or_else(|| vec![Vec2::ZERO; p.positions.len()]);
        m.uv0.as_mut().expect("set above").extend(uv);
        m.indices.extend(p.indices.iter().map(|i| i + base));
    }
    m
}

/// Splits every triangle pair of a quad mesh built by [`quad`]/[`merge`] into an n × n grid of
/// quads (2n² triangles per quad), keeping positions, normals and UV0 bilinear.
pub fn subdivide_quads(mesh: &Mesh, n: u32) -> Mesh {
    assert!(
        mesh.indices.len().is_multiple_of(6),
        "expects quads made of two triangles"
    );
    let mut out = Mesh {
        name: mesh.name.clone(),
        material: mesh.material,
        uv0: Some(Vec::new()),
        ..Mesh::default()
    };
    let uv0 = mesh
        .uv0
        .clone()
        .unwrap_or_else(|| vec![Vec2::ZERO; mesh.positions.len()]);
    for q in mesh.indices.chunks_exact(6) {
        // quad() emits (0,1,2),(0,2,3).
        let c = [q[0], q[1], q[2], q[5]].map(|i| i as usize);
        let base = out.positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
                let bil = |v: [Vec3; 4]| v[0].lerp(v[1], s).lerp(v[3].lerp(v[2], s), t);
                out.positions.push(bil(c.map(|k| mesh.positions[k])));
                out.normals
                    .push(bil(c.map(|k| mesh.normals[k])).normalize());
                let u = c.map(|k| uv0[k]);
                out.uv0
                    .as_mut()
                    .expect("set above")
                    .push(u[0].lerp(u[1], s).lerp(u[3].lerp(u[2], s), t));
            }
        }
        let row = n + 1;
        for j in 0..n {
            for i in 0..n {
                let a = base + j * row + i;
                out.indices
                    .extend_from_slice(&[a, a + 1, a + row + 1, a, a + row + 1, a + row]);
            }
        }
    }
    out
}

/// The Cornell box with every quad split into n × n cells: 32·n² triangles (n = 80 gives
/// 204 800), for ray-tracing benchmarks.
pub fn cornell_box_dense(light: CornellLight, n: u32) -> Scene {
    let mut s = cornell_box(light);
    for m in &mut s.meshes {
        *m = subdivide_quads(m, n);
    }
    s.name = format!("{}_dense{n}", s.name);
    s
}

/// Which light the Cornell box has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CornellLight {
    /// The classic 130 × 105 mm ceiling area light, luminance 5000 nits × (1, 0.85, 0.6).
    Area,
    /// A 50 cd point light 5 cm under the centre of the ceiling, colour (1, 0.9, 0.8).
    Point,
}

/// Millimetre coordinates of the classic Cornell box → metres, turned so the opening faces +Z.
fn cornell(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(-(x - 278.0), y, -(z - 279.6)) / 1000.0
}

/// The white, red and green of the Cornell box as linear RGB albedos.
pub const CORNELL_WHITE: Vec3 = Vec3::new(0.73, 0.73, 0.73);
/// Red (left) wall albedo.
pub const CORNELL_RED: Vec3 = Vec3::new(0.63, 0.065, 0.05);
/// Green (right) wall albedo.
pub const CORNELL_GREEN: Vec3 = Vec3::new(0.14, 0.45, 0.091);

/// The Cornell box, 0.556 × 0.549 × 0.559 m, open towards +Z; the red wall is at −X
/// (the viewer's left), the green wall at +X.
pub fn cornell_box(light: CornellLight) -> Scene {
    let mut s = Scene {
        name: match light {
            CornellLight::Area => "cornell_box".into(),
            CornellLight::Point => "cornell_box_point".into(),
        },
        texel_density_hint: Some(256.0),
        ..Scene::default()
    };
    let white = s.add_material(Material::diffuse("white", CORNELL_WHITE));
    let red = s.add_material(Material::diffuse("red", CORNELL_RED));
    let green = s.add_material(Material::diffuse("green", CORNELL_GREEN));
    let centre = cornell(278.0, 274.4, 279.6);
    let inward = |corners: [Vec3; 4]| {
        let mid = (corners[0] + corners[1] + corners[2] + corners[3]) / 4.0;
        centre - mid
    };
    let add = |s: &mut Scene, mesh: Mesh, material: usize| {
        let name = mesh.name.clone();
        let m = s.add_mesh(Mesh {
            material: Some(material),
            ..mesh
        });
        s.instances.push(Instance::new(name, m, Affine3A::IDENTITY));
    };
    let walls: [(&str, [[f32; 3]; 4], usize); 5] = [
        (
            "floor",
            [
                [552.8, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 559.2],
                [549.6, 0.0, 559.2],
            ],
            white,
        ),
        (
            "ceiling",
            [
                [556.0, 548.8, 0.0],
                [556.0, 548.8, 559.2],
                [0.0, 548.8, 559.2],
                [0.0, 548.8, 0.0],
            ],
            white,
        ),
        (
            "back_wall",
            [
                [549.6, 0.0, 559.2],
                [0.0, 0.0, 559.2],
                [0.0, 548.8, 559.2],
                [556.0, 548.8, 559.2],
            ],
            white,
        ),
        (
            "green_wall",
            [
                [0.0, 0.0, 559.2],
                [0.0, 0.0, 0.0],
                [0.0, 548.8, 0.0],
                [0.0, 548.8, 559.2],
            ],
            green,
        ),
        (
            "red_wall",
            [
                [552.8, 0.0, 0.0],
                [549.6, 0.0, 559.2],
                [556.0, 548.8, 559.2],
                [556.0, 548.8, 0.0],
            ],
            red,
        ),
    ];
    for (name, c, mat) in walls {
        let corners = c.map(|p| cornell(p[0], p[1], p[2]));
        let facing = inward(corners);
        add(&mut s, quad(name, corners, facing), mat);
    }
    let block = |name: &str, top: [[f32; 2]; 4], height: f32| -> Mesh {
        let top3 = top.map(|p| cornell(p[0], height, p[1]));
        let bottom3 = top.map(|p| cornell(p[0], 0.0, p[1]));
        let mid = (top3[0]
            + top3[1]
            + top3[2]
            + top3[3]
            + bottom3[0]
            + bottom3[1]
            + bottom3[2]
            + bottom3[3])
            / 8.0;
        let mut faces = vec![quad(name, top3, Vec3::Y)];
        for i in 0..4 {
            let j = (i + 1) % 4;
            let c = [bottom3[i], top3[i], top3[j], bottom3[j]];
            let face_mid = (c[0] + c[1] + c[2] + c[3]) / 4.0;
            faces.push(quad(name, c, face_mid - mid));
        }
        merge(name, faces)
    };
    add(
        &mut s,
        block(
            "short_block",
            [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]],
            165.0,
        ),
        white,
    );
    add(
        &mut s,
        block(
            "tall_block",
            [
                [423.0, 247.0],
                [265.0, 296.0],
                [314.0, 456.0],
                [472.0, 406.0],
            ],
            330.0,
        ),
        white,
    );
    match light {
        CornellLight::Area => {
            let lum = Vec3::new(1.0, 0.85, 0.6) * 5000.0;
            let emitter = s.add_material(Material::emitter("light", lum));
            let y = 548.8 - 1.0;
            let c = [
                [343.0, y, 227.0],
                [343.0, y, 332.0],
                [213.0, y, 332.0],
                [213.0, y, 227.0],
            ]
            .map(|p| cornell(p[0], p[1], p[2]));
            add(&mut s, quad("light", c, Vec3::NEG_Y), emitter);
        }
        CornellLight::Point => s.lights.push(Light {
            name: "ceiling_point".into(),
            kind: LightKind::Point,
            color: Vec3::new(1.0, 0.9, 0.8),
            intensity: 50.0,
            range: None,
            position: cornell(278.0, 498.8, 279.6),
            direction: Vec3::NEG_Y,
            bake: crate::scene::LightBake::Full,
        }),
    }
    s
}

/// The radiosity "furnace": the inside of a closed `size`-metre cube whose six faces all emit
/// luminance `luminance` (nits) and reflect with albedo `albedo`. Every point sees only the
/// box, so the irradiance everywhere is H = π·L/(1 − ρ) and a lightmap texel stores
/// L/(1 − ρ).
pub fn furnace_box(size: f32, albedo: f32, luminance: f32) -> Scene {
    let mut s = Scene {
        name: format!("furnace_{albedo}"),
        ..Scene::default()
    };
    let mat = s.add_material(Material {
        emissive: Vec3::splat(luminance),
        ..Material::diffuse("furnace", Vec3::splat(albedo))
    });
    let h = size / 2.0;
    let outer = cuboid("box", Vec3::splat(-h), Vec3::splat(h), false);
    // Turn each face inwards: reverse the winding and the normals.
    let mut inner = outer;
    for t in inner.indices.chunks_exact_mut(3) {
        t.swap(1, 2);
    }
    for n in &mut inner.normals {
        *n = -*n;
    }
    inner.name = "furnace".into();
    inner.material = Some(mat);
    let m = s.add_mesh(inner);
    s.instances
        .push(Instance::new("furnace", m, Affine3A::IDENTITY));
    s
}

/// A room 8 × 3 × 6 m (inside) with 0.2 m thick walls, floor and ceiling; a 2.4 × 1.5 m
/// window in the +Z wall; two 0.4 m pillars; a 2 cm thin partition wall; the sun
/// (50 000 lx, angular radius 0.01 rad) shining in through the window; a blue sky of
/// 3000 nits; and a ground plane outside.
pub fn sunlit_room() -> Scene {
    let mut s = Scene {
        name: "sunlit_room".into(),
        texel_density_hint: Some(24.0),
        sky: Vec3::new(0.6, 0.75, 1.0) * 3000.0,
        ..Scene::default()
    };
    let plaster = s.add_material(Material::diffuse("plaster", Vec3::new(0.8, 0.78, 0.74)));
    let wood = s.add_material(Material::diffuse("wood_floor", Vec3::new(0.45, 0.3, 0.18)));
    let concrete = s.add_material(Material::diffuse("concrete", Vec3::splat(0.5)));
    let partition = s.add_material(Material {
        double_sided: false,
        ..Material::diffuse("partition", Vec3::new(0.3, 0.45, 0.7))
    });
    let grass = s.add_material(Material::diffuse("ground", Vec3::new(0.2, 0.3, 0.1)));
    let t = 0.2; // wall thickness
    let (w, h, d) = (8.0f32, 3.0f32, 6.0f32);
    let (x0, x1, z0, z1) = (-w / 2.0, w / 2.0, -d / 2.0, d / 2.0);
    let mut boxes: Vec<(&str, Vec3, Vec3, usize)> = vec![
        (
            "floor",
            Vec3::new(x0 - t, -t, z0 - t),
            Vec3::new(x1 + t, 0.0, z1 + t),
            wood,
        ),
        (
            "ceiling",
            Vec3::new(x0 - t, h, z0 - t),
            Vec3::new(x1 + t, h + t, z1 + t),
            plaster,
        ),
        (
            "wall_west",
            Vec3::new(x0 - t, 0.0, z0 - t),
            Vec3::new(x0, h, z1 + t),
            plaster,
        ),
        (
            "wall_east",
            Vec3::new(x1, 0.0, z0 - t),
            Vec3::new(x1 + t, h, z1 + t),
            plaster,
        ),
        (
            "wall_north",
            Vec3::new(x0, 0.0, z0 - t),
            Vec3::new(x1, h, z0),
            plaster,
        ),
    ];
    // South wall with a window from x = -1.2..1.2, y = 0.9..2.4.
    let (wx0, wx1, wy0, wy1) = (-1.2, 1.2, 0.9, 2.4);
    boxes.extend([
        (
            "wall_south_left",
            Vec3::new(x0, 0.0, z1),
            Vec3::new(wx0, h, z1 + t),
            plaster,
        ),
        (
            "wall_south_right",
            Vec3::new(wx1, 0.0, z1),
            Vec3::new(x1, h, z1 + t),
            plaster,
        ),
        (
            "wall_south_sill",
            Vec3::new(wx0, 0.0, z1),
            Vec3::new(wx1, wy0, z1 + t),
            plaster,
        ),
        (
            "wall_south_lintel",
            Vec3::new(wx0, wy1, z1),
            Vec3::new(wx1, h, z1 + t),
            plaster,
        ),
        (
            "pillar_a",
            Vec3::new(-2.2, 0.0, -0.2),
            Vec3::new(-1.8, h, 0.2),
            concrete,
        ),
        (
            "pillar_b",
            Vec3::new(1.8, 0.0, -0.2),
            Vec3::new(2.2, h, 0.2),
            concrete,
        ),
        (
            "thin_wall",
            Vec3::new(-0.5, 0.0, -1.51),
            Vec3::new(2.5, 2.2, -1.49),
            partition,
        ),
    ]);
    for (name, lo, hi, mat) in boxes {
        let skip_bottom = lo.y == 0.0 && name != "floor";
        let m = s.add_mesh(Mesh {
            material: Some(mat),
            ..cuboid(name, lo, hi, skip_bottom)
        });
        s.instances.push(Instance::new(name, m, Affine3A::IDENTITY));
    }
    let ground = s.add_mesh(Mesh {
        material: Some(grass),
        ..plane("ground", 40.0)
    });
    let mut g = Instance::new(
        "ground",
        ground,
        Affine3A::from_translation(Vec3::new(0.0, -t - 0.001, 0.0)),
    );
    g.texel_density_scale = 0.125;
    s.instances.push(g);
    s.lights.push(Light {
        name: "sun".into(),
        kind: LightKind::Directional {
            angular_radius: 0.01,
        },
        color: Vec3::new(1.0, 0.95, 0.85),
        intensity: 50_000.0,
        range: None,
        position: Vec3::ZERO,
        direction: Vec3::new(0.35, -0.55, -0.76).normalize(),
        bake: crate::scene::LightBake::Full,
    });
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_scenes_validate() {
        for s in [
            cornell_box(CornellLight::Area),
            cornell_box(CornellLight::Point),
            sunlit_room(),
            contact_room(),
            seam_room(),
        ] {
            s.validate().unwrap();
            for m in &s.meshes {
                // Normals agree with the winding.
                for t in 0..m.triangle_count() {
                    let [a, b, c] = m.triangle(t);
                    let g =
                        (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]);
                    assert!(g.dot(m.normals[a]) > 0.0, "{} triangle {t}", m.name);
                }
            }
        }
    }

    #[test]
    fn cornell_walls_face_inwards() {
        let s = cornell_box(CornellLight::Area);
        let centre = Vec3::new(0.0, 0.2744, 0.0);
        for name in ["floor", "ceiling", "back_wall", "red_wall", "green_wall"] {
            let m = s.meshes.iter().find(|m| m.name == name).unwrap();
            let to_centre = centre - m.positions[0];
            assert!(m.normals[0].dot(to_centre) > 0.0, "{name}");
        }
        // The red wall is on the viewer's left (−X) for a camera looking along −Z.
        let red = s.meshes.iter().find(|m| m.name == "red_wall").unwrap();
        assert!(red.positions.iter().all(|p| p.x < -0.27));
    }

    #[test]
    fn dense_cornell_keeps_the_surfaces() {
        let a = cornell_box(CornellLight::Area);
        let b = cornell_box_dense(CornellLight::Area, 4);
        assert_eq!(b.instanced_triangle_count(), 32 * 16);
        for (x, y) in a.meshes.iter().zip(&b.meshes) {
            assert!((x.area() - y.area()).abs() < 1e-5 * x.area().max(1e-3));
            y.validate().unwrap();
            for t in 0..y.triangle_count() {
                let [p, q, r] = y.triangle(t);
                let g = (y.positions[q] - y.positions[p]).cross(y.positions[r] - y.positions[p]);
                assert!(g.dot(y.normals[p]) > 0.0, "{} triangle {t}", y.name);
            }
        }
    }

    #[test]
    fn grid_has_requested_triangles() {
        let g = grid("g", 2.0, 10);
        assert_eq!(g.triangle_count(), 200);
        assert!((g.area() - 4.0).abs() < 1e-4);
        g.validate().unwrap();
    }
}
