//! Reading baked light back at a point in the world, the way the GPU shows it: for tests, for
//! debugging tools, and for games that tint dynamic objects by the lightmap under them.

use bevy::math::Rect;
use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;

use crate::images::sample_bilinear;

/// Where a world point lands on a lightmapped mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceHit {
    /// Triangle index in the mesh.
    pub triangle: usize,
    /// The closest point on that triangle, world space.
    pub point: Vec3,
    /// Distance from the query point, metres.
    pub distance: f32,
    /// Interpolated `UV_1` of the closest point (before `uv_rect`).
    pub uv1: Vec2,
}

/// Closest point on triangle abc to p, with its barycentric weights (of a, b and c).
fn closest_on_triangle(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Vec3) {
    // The core's glam may be another version than Bevy's: the points cross as arrays.
    let core = |v: Vec3| lightbake::glam::Vec3::from_array(v.to_array());
    let (q, vw) = lightbake::scene::closest_on_triangle(core(p), [core(a), core(b), core(c)]);
    (
        Vec3::from_array(q.to_array()),
        Vec3::new(1.0 - vw.x - vw.y, vw.x, vw.y),
    )
}

/// The point of `mesh` (placed by `transform`) closest to `world_point`, with its `UV_1`.
/// `None` when the mesh has no readable positions and `UV_1`.
pub fn closest_surface_point(
    mesh: &Mesh,
    transform: &GlobalTransform,
    world_point: Vec3,
) -> Option<SurfaceHit> {
    let Some(VertexAttributeValues::Float32x3(pos)) =
        mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION).ok()?
    else {
        return None;
    };
    let Some(VertexAttributeValues::Float32x2(uv1)) =
        mesh.try_attribute_option(Mesh::ATTRIBUTE_UV_1).ok()?
    else {
        return None;
    };
    let indices: Vec<usize> = match mesh.try_indices_option().ok()? {
        Some(Indices::U16(i)) => i.iter().map(|&i| i as usize).collect(),
        Some(Indices::U32(i)) => i.iter().map(|&i| i as usize).collect(),
        None => (0..pos.len()).collect(),
    };
    let world: Vec<Vec3> = pos
        .iter()
        .map(|p| transform.transform_point(Vec3::from_array(*p)))
        .collect();
    let mut best: Option<SurfaceHit> = None;
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        let [a, b, c] = [tri[0], tri[1], tri[2]];
        if a.max(b).max(c) >= world.len() {
            continue;
        }
        let (q, bary) = closest_on_triangle(world_point, world[a], world[b], world[c]);
        let d = q.distance(world_point);
        if best.is_none_or(|h| d < h.distance) {
            let uv = Vec2::from_array(uv1[a]) * bary.x
                + Vec2::from_array(uv1[b]) * bary.y
                + Vec2::from_array(uv1[c]) * bary.z;
            best = Some(SurfaceHit {
                triangle: t,
                point: q,
                distance: d,
                uv1: uv,
            });
        }
    }
    best
}

/// The baked value (E/π, linear RGB) that Bevy shows at the surface point of `mesh` closest
/// to `world_point`: `UV_1` interpolated, mapped through `uv_rect`, bilinearly sampled from
/// `image`. `None` when the mesh has no `UV_1` or the image is not a float image on the CPU.
pub fn sample_lightmap(
    mesh: &Mesh,
    transform: &GlobalTransform,
    uv_rect: Rect,
    image: &Image,
    world_point: Vec3,
) -> Option<Vec3> {
    let hit = closest_surface_point(mesh, transform, world_point)?;
    let uv = uv_rect.min + hit.uv1 * (uv_rect.max - uv_rect.min);
    sample_bilinear(image, uv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_regions() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let check = |p: Vec3, want: Vec3| {
            let (q, w) = closest_on_triangle(p, a, b, c);
            assert!(q.distance(want) < 1e-6, "{p}: {q} vs {want}");
            assert!((w.x + w.y + w.z - 1.0).abs() < 1e-6);
            assert!((a * w.x + b * w.y + c * w.z).distance(q) < 1e-6);
        };
        check(Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.2, 0.2, 0.0)); // face
        check(Vec3::new(-1.0, -1.0, 0.0), a); // vertex regions
        check(Vec3::new(2.0, -0.5, 0.0), b);
        check(Vec3::new(-0.5, 2.0, 0.0), c);
        check(Vec3::new(0.5, -1.0, 0.0), Vec3::new(0.5, 0.0, 0.0)); // edge ab
        check(Vec3::new(-1.0, 0.5, 0.0), Vec3::new(0.0, 0.5, 0.0)); // edge ac
        check(Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.5, 0.5, 0.0)); // edge bc
    }
}
