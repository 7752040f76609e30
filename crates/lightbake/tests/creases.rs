//! Normals averaged across hard edges (`Mesh::corner_normals`): a cube whose faces are grids
//! welded at its edges, with every vertex normal the average of the faces around it (as CAD
//! and IFC exports, and meshes smoothed without a crease angle, write them), lit by a point
//! light in front. Its faces are flat: the light on each is the point light's E = I·cosθ/r²
//! with the face's own normal, and the sides the light cannot see are black. Followed
//! blindly, the averaged normals would tilt the front face's edge texels 45° away from the
//! light (a dark line along every edge, as on a real kitchen's cabinet fronts) and turn the
//! sides' front edges towards it (a lit strip where no light falls).
//!
//! Texels store E/π; every comparison divides the analytic irradiance by π.

mod common;

use std::f32::consts::PI;

use common::{add, bake, settings, texels};
use glam::{Affine3A, Vec3};
use lightbake::scene::{Light, LightKind, Mesh, Scene};

/// A unit cube centred on the origin, each face an n × n grid, vertices shared along the
/// edges and corners, normals averaged over the faces around each vertex (smooth).
fn welded_cube(n: u32) -> Mesh {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut indices = Vec::new();
    let index_of = |p: Vec3, positions: &mut Vec<Vec3>| -> u32 {
        let key = (p * 2.0 * n as f32).round();
        match positions
            .iter()
            .position(|q| (*q * 2.0 * n as f32).round() == key)
        {
            Some(i) => i as u32,
            None => {
                positions.push(p);
                positions.len() as u32 - 1
            }
        }
    };
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let normal = Vec3::AXES[axis] * sign;
            // Two tangents with u × v = normal, so the winding faces out.
            let u = Vec3::AXES[(axis + 1) % 3];
            let v = normal.cross(u);
            let at = |i: u32, j: u32| {
                normal * 0.5 + u * (i as f32 / n as f32 - 0.5) + v * (j as f32 / n as f32 - 0.5)
            };
            for i in 0..n {
                for j in 0..n {
                    let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                        .map(|p| index_of(p, &mut positions));
                    indices.extend([c[0], c[1], c[2], c[0], c[2], c[3]]);
                }
            }
        }
    }
    let mut mesh = Mesh {
        name: "cabinet".into(),
        positions,
        indices,
        ..Mesh::default()
    };
    mesh.compute_normals();
    mesh
}

#[test]
fn a_box_with_normals_averaged_across_its_edges_is_lit_as_its_flat_faces() {
    let mesh = welded_cube(6);
    // The normals really are averaged at the edges: a vertex on the front face's right edge
    // points 45° away from the front.
    let edge = mesh
        .positions
        .iter()
        .position(|p| (*p - Vec3::new(0.5, 0.0, 0.5)).length() < 1e-5)
        .expect("an edge vertex");
    assert!((mesh.normals[edge].dot(Vec3::Z) - 0.5f32.sqrt()).abs() < 1e-5);
    let mut s = Scene::default();
    let cube = add(&mut s, mesh, Vec3::splat(0.5), Affine3A::IDENTITY, true);
    let light = Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 100.0,
        range: None,
        position: Vec3::new(0.0, 0.0, 3.0),
        direction: Vec3::NEG_Z,
        bake: lightbake::scene::LightBake::Full,
    };
    s.lights.push(light.clone());
    let out = bake(&s, &settings(48.0, 16));
    let (mut front, mut worst_front, mut brightest_side) = (0, 0.0f32, 0.0f32);
    let centre = light.intensity / (2.5 * 2.5) / PI;
    for t in texels(&out, cube) {
        let p = t.position;
        let near_edge = |a: f32| a.abs() > 0.5 - 1e-4;
        if near_edge(p.z) && p.z > 0.0 && !near_edge(p.x) && !near_edge(p.y) {
            // The front face: E = I·cosθ/r² with its own normal +Z.
            let to = light.position - p;
            let expected = light.intensity * to.normalize().z / to.length_squared() / PI;
            worst_front = worst_front.max((t.value.x / expected - 1.0).abs());
            front += 1;
        } else if (near_edge(p.x) || near_edge(p.y)) && !near_edge(p.z) {
            // A side: the light lies in or behind its plane.
            brightest_side = brightest_side.max(t.value.x);
        }
    }
    assert!(front > 1500, "{front} front texels");
    assert!(
        worst_front < 0.02,
        "a front texel is {:.1}% off the point light's E/π",
        100.0 * worst_front
    );
    assert!(
        brightest_side < 0.01 * centre,
        "a side texel holds {brightest_side}, {:.1}% of the front's centre",
        100.0 * brightest_side / centre
    );
}
