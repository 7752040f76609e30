//! The watertight ray–triangle test of Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection" (JCGT 2(1), 2013): the triangle is moved into the ray's frame (origin at
//! zero, the ray along +z after a shear), where the test is three 2D edge functions of the
//! vertices. Two triangles that share an edge compute that edge's function from the same two
//! vertices with the same arithmetic, so a ray that crosses the edge is inside at least one of
//! them: no ray slips through a shared edge (Möller–Trumbore's barycentrics, computed per
//! triangle from its own edge vectors, round differently on each side and can reject the ray on
//! both). Edge functions that come out exactly zero are recomputed in double precision, as the
//! paper prescribes, so the tie on an edge is decided by exact signs.
//!
//! This module holds the per-ray shear ([`Shear`]), the scalar test ([`intersect`], the
//! brute-force reference) and the double-precision edge functions both it and the lane test
//! of [`super::packet`] fall back on.

use glam::{DVec3, Vec3};

/// A ray's frame for the test: the axis of its largest direction component becomes z, the
/// other two (swapped when that component is negative, which keeps the triangles' winding)
/// x and y, and the shear that takes the direction to (0, 0, 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shear {
    /// World axes that act as x, y and z.
    pub axes: [usize; 3],
    /// d_x / d_z, d_y / d_z and 1 / d_z.
    pub s: [f32; 3],
}

impl Shear {
    /// The frame of a ray along `dir` (non-zero).
    #[inline]
    pub fn new(dir: Vec3) -> Self {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let sz = 1.0 / dir[kz];
        Self {
            axes: [kx, ky, kz],
            s: [dir[kx] * sz, dir[ky] * sz, sz],
        }
    }
}

/// The three edge functions (U, V, W) of the triangle with vertices `a`, `b`, `c` relative
/// to the ray origin, in double precision: the fallback for edge functions that are exactly
/// zero in single precision.
#[inline(never)]
pub fn edge_functions_f64(shear: &Shear, a: Vec3, b: Vec3, c: Vec3) -> [f32; 3] {
    let [kx, ky, kz] = shear.axes;
    let (sx, sy) = (shear.s[0] as f64, shear.s[1] as f64);
    let project = |p: DVec3| (p[kx] - sx * p[kz], p[ky] - sy * p[kz]);
    let (ax, ay) = project(a.as_dvec3());
    let (bx, by) = project(b.as_dvec3());
    let (cx, cy) = project(c.as_dvec3());
    [
        (cx * by - cy * bx) as f32,
        (ax * cy - ay * cx) as f32,
        (bx * ay - by * ax) as f32,
    ]
}

/// The watertight test of the ray from `origin` with frame `shear` against the triangle
/// `v`: (t, u, v) for a hit with t in [tmin, tmax], u and v the barycentric weights of the
/// second and third vertices.
#[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
#[inline]
pub fn intersect(
    v: &[Vec3; 3],
    origin: Vec3,
    shear: &Shear,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, f32, f32)> {
    let [kx, ky, kz] = shear.axes;
    let [sx, sy, sz] = shear.s;
    let (a, b, c) = (v[0] - origin, v[1] - origin, v[2] - origin);
    let project = |p: Vec3| (p[kx] - sx * p[kz], p[ky] - sy * p[kz]);
    let (ax, ay) = project(a);
    let (bx, by) = project(b);
    let (cx, cy) = project(c);
    let mut e = [cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax];
    if e.contains(&0.0) {
        e = edge_functions_f64(shear, a, b, c);
    }
    let [eu, ev, ew] = e;
    if (eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0) {
        return None;
    }
    let det = eu + ev + ew;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let t = (eu * a[kz] + ev * b[kz] + ew * c[kz]) * sz;
    // Compared scaled by |det|, signs folded in, so only a hit pays for the division.
    let (t_abs, d_abs) = if det < 0.0 { (-t, -det) } else { (t, det) };
    if t_abs < tmin * d_abs || t_abs > tmax * d_abs {
        return None;
    }
    let inv = 1.0 / det;
    Some(((t * inv).clamp(tmin, tmax), ev * inv, ew * inv))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_through_a_shared_edge_hits_one_of_the_triangles() {
        // Two triangles sharing the diagonal of a unit square; rays through points of the
        // diagonal, from far away and at odd angles, must hit one of them.
        let (p0, p1, p2, p3) = (
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let tris = [[p0, p1, p2], [p0, p2, p3]];
        let mut missed = 0;
        for i in 0..20_000u32 {
            let s = (i as f32 + 0.5) / 20_000.0;
            let on_edge = p0.lerp(p2, s);
            let origin = Vec3::new(
                0.37 + 50.0 * (i as f32 * 0.618).sin(),
                -21.0 + 3.0 * (i as f32 * 0.31).cos(),
                7.0 + 40.0 * (i as f32 * 0.17).sin().abs(),
            );
            let dir = (on_edge - origin).normalize();
            let shear = Shear::new(dir);
            if tris
                .iter()
                .all(|t| intersect(t, origin, &shear, 0.0, f32::INFINITY).is_none())
            {
                missed += 1;
            }
        }
        assert_eq!(missed, 0);
    }

    #[test]
    fn hits_carry_distance_and_barycentrics() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        for dir in [Vec3::Z, Vec3::new(0.1, -0.2, 1.0).normalize()] {
            let origin = Vec3::new(0.2, 0.3, 0.0) - dir * 2.0;
            let (t, u, v) = intersect(&tri, origin, &Shear::new(dir), 0.0, 10.0).unwrap();
            assert!((t - 2.0).abs() < 1e-5, "{t}");
            assert!((u - 0.2).abs() < 1e-5 && (v - 0.3).abs() < 1e-5, "{u} {v}");
            // From behind, and out of range.
            let back = Vec3::new(0.2, 0.3, 0.0) + dir * 2.0;
            assert!(intersect(&tri, back, &Shear::new(-dir), 0.0, 10.0).is_some());
            assert!(intersect(&tri, origin, &Shear::new(dir), 0.0, 1.5).is_none());
            assert!(intersect(&tri, origin, &Shear::new(dir), 2.5, 10.0).is_none());
        }
        // Outside the triangle.
        let origin = Vec3::new(0.8, 0.8, -1.0);
        assert!(intersect(&tri, origin, &Shear::new(Vec3::Z), 0.0, 10.0).is_none());
    }
}
