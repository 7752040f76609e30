//! Four triangles at a time: the leaf packets of [`super::wide`], the ray prepared for them,
//! and the watertight test of [`super::watertight`] on four lanes with glam's `Vec4` (SSE on
//! x86-64). A packet keeps its triangles' exact vertices (the test needs the bits two triangles
//! share on an edge to be the same) and a caller's tag per lane, which a hit returns.

use glam::{Vec3, Vec4};

use super::watertight::{Shear, edge_functions_f64};

/// Four triangles, structure of arrays: their three vertices, exactly as given (the
/// watertight test needs the bits two triangles share on an edge to be the same).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    pub(super) v: [[Vec4; 3]; 3],
    /// The caller's tag of each lane (`u32::MAX` for padding lanes, whose vertices are zero).
    pub(super) id: [u32; 4],
}

/// A ray prepared for the slab tests and the watertight triangle test.
#[derive(Clone, Copy, Debug)]
pub struct Ray4 {
    /// Origin and 1 / direction (±`f32::MAX` where that overflows), for the node tests.
    pub(super) o: [f32; 3],
    pub(super) inv: [f32; 3],
    /// The origin splatted, for the triangle tests.
    pub(super) org: [Vec4; 3],
    /// The ray's frame for the triangle test.
    pub(super) shear: Shear,
    /// The shear's factors, splatted.
    pub(super) s4: [Vec4; 3],
    /// Per axis: the direction is negative (near planes are the upper corners).
    pub(super) neg: [bool; 3],
    /// Entry bound.
    pub tmin: f32,
    /// Exit bound (shrinks as closer hits are found).
    pub tmax: f32,
}

impl Ray4 {
    /// A ray from `origin` along unit `dir` for t in [tmin, tmax].
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        let inv = |d: f32| {
            let i = 1.0 / d;
            if i.is_finite() {
                i
            } else {
                f32::MAX.copysign(d)
            }
        };
        let shear = Shear::new(dir);
        Self {
            o: origin.to_array(),
            inv: [dir.x, dir.y, dir.z].map(inv),
            org: [origin.x, origin.y, origin.z].map(Vec4::splat),
            shear,
            s4: shear.s.map(Vec4::splat),
            neg: [dir.x < 0.0, dir.y < 0.0, dir.z < 0.0],
            tmin,
            tmax,
        }
    }
}

/// A hit in a packet (and so in a [`super::wide::Bvh8`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit4 {
    /// The caller's tag of the triangle hit (see [`super::wide::Bvh8::collapse`]).
    pub tag: u32,
    /// Distance along the ray's direction.
    pub t: f32,
    /// Barycentric weight of the second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
    /// The ray met the side that the vertices' counter-clockwise order faces (the sign of the
    /// edge functions' sum, so it agrees with the test that found the hit).
    pub ccw: bool,
}

/// Packs up to four triangles with their tags; unused lanes have zero vertices (their edge
/// functions are all zero, so they never hit) and the tag `u32::MAX`.
pub(super) fn pack(prims: &[u32], tris: &[[Vec3; 3]], tags: &[u32]) -> Tri4 {
    debug_assert!(!prims.is_empty() && prims.len() <= 4);
    let mut t = Tri4 {
        v: [[Vec4::ZERO; 3]; 3],
        id: [u32::MAX; 4],
    };
    for (lane, &p) in prims.iter().enumerate() {
        for (k, vertex) in tris[p as usize].iter().enumerate() {
            for axis in 0..3 {
                t.v[k][axis][lane] = vertex[axis];
            }
        }
        debug_assert_ne!(tags[p as usize], u32::MAX, "u32::MAX marks padding lanes");
        t.id[lane] = tags[p as usize];
    }
    t
}

/// World vertices of lane `lane`.
pub(super) fn lane_vertices(t: &Tri4, lane: usize) -> [Vec3; 3] {
    t.v.map(|v| Vec3::new(v[0][lane], v[1][lane], v[2][lane]))
}

/// The watertight test ([`super::watertight`]) against four triangles at once: the nearest
/// hit with t in [tmin, tmax], as (primitive id, t, u, v).
#[inline(always)]
pub(super) fn intersect4(tri: &Tri4, ray: &Ray4) -> Option<Hit4> {
    let [kx, ky, kz] = ray.shear.axes;
    let [sx, sy, sz] = ray.s4;
    // The vertices relative to the origin, sheared into the ray's frame.
    let rel = |k: usize| {
        let v = &tri.v[k];
        let z = v[kz] - ray.org[kz];
        (
            v[kx] - ray.org[kx] - sx * z,
            v[ky] - ray.org[ky] - sy * z,
            z,
        )
    };
    let (ax, ay, az) = rel(0);
    let (bx, by, bz) = rel(1);
    let (cx, cy, cz) = rel(2);
    // The edge functions; exact zeros (a ray through an edge or a vertex) are redone in
    // double precision.
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    let zero = (u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO)).bitmask();
    if zero != 0 {
        (u, v, w) = redo_in_f64(tri, ray, zero, (u, v, w));
    }
    let negative = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
    let positive = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
    let det = u + v + w;
    // t·det, compared scaled by |det| (signs folded in), so only lanes that hit pay for the
    // division (as Embree's intersectors do).
    let t = (u * az + v * bz + w * cz) * sz;
    let sign = det.signum();
    let abs_det = det.abs();
    let t_abs = t * sign;
    let inside = (negative & positive).bitmask() ^ 0b1111;
    let ok = abs_det.cmpgt(Vec4::ZERO)
        & abs_det.cmplt(Vec4::INFINITY)
        & t_abs.cmpge(abs_det * ray.tmin)
        & t_abs.cmple(abs_det * ray.tmax);
    let mask = ok.bitmask() & inside;
    if mask == 0 {
        return None;
    }
    // The edge functions' sum is the triangle's signed area seen along the ray: positive
    // where the counter-clockwise normal faces back along it.
    let det_positive = det.cmpgt(Vec4::ZERO).bitmask();
    let inv = Vec4::ONE / det;
    let (t, u, v) = (
        (t * inv).to_array(),
        (v * inv).to_array(),
        (w * inv).to_array(),
    );
    let mut best: Option<Hit4> = None;
    for lane in 0..4 {
        if mask & (1 << lane) != 0 && best.is_none_or(|b| t[lane] < b.t) {
            // The division may round just outside the interval the scaled test accepted.
            let t = t[lane].clamp(ray.tmin, ray.tmax);
            best = Some(Hit4 {
                tag: tri.id[lane],
                t,
                u: u[lane],
                v: v[lane],
                ccw: det_positive & (1 << lane) != 0,
            });
        }
    }
    best
}

/// The edge functions of the lanes in `lanes` (a bit mask) recomputed in double precision;
/// padding lanes keep theirs (zero: they never hit).
#[cold]
#[inline(never)]
fn redo_in_f64(tri: &Tri4, ray: &Ray4, lanes: u32, uvw: (Vec4, Vec4, Vec4)) -> (Vec4, Vec4, Vec4) {
    let (mut u, mut v, mut w) = (uvw.0.to_array(), uvw.1.to_array(), uvw.2.to_array());
    let origin = Vec3::new(ray.org[0].x, ray.org[1].x, ray.org[2].x);
    for lane in 0..4 {
        if lanes & (1 << lane) == 0 || tri.id[lane] == u32::MAX {
            continue;
        }
        let [a, b, c] = lane_vertices(tri, lane).map(|p| p - origin);
        [u[lane], v[lane], w[lane]] = edge_functions_f64(&ray.shear, a, b, c);
    }
    (
        Vec4::from_array(u),
        Vec4::from_array(v),
        Vec4::from_array(w),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packet_test_matches_one_triangle_at_a_time() {
        let tris = [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 0.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [Vec3::ZERO, Vec3::ZERO, Vec3::ZERO],
        ];
        let packet = pack(&[0, 1, 2], &tris, &[0, 1, 2]);
        // From below, the nearer triangle (z = 0) wins.
        let ray = Ray4::new(Vec3::new(0.2, 0.3, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        let Hit4 { tag, t, u, v, ccw } = intersect4(&packet, &ray).unwrap();
        assert_eq!(tag, 0);
        // From below: the counter-clockwise normal (+z) faces away from the ray.
        assert!(!ccw);
        assert!((t - 1.0).abs() < 1e-6 && (u - 0.2).abs() < 1e-6 && (v - 0.3).abs() < 1e-6);
        // From above, the z = 1 triangle; a short ray misses both; the degenerate lane never hits.
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, f32::INFINITY);
        let hit = intersect4(&packet, &ray).unwrap();
        assert_eq!(hit.tag, 1);
        assert!(hit.ccw);
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect4(&packet, &ray).is_none());
        let ray = Ray4::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(intersect4(&packet, &ray).is_some_and(|h| h.tag != 2));
    }
}
