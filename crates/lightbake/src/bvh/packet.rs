//! The leaf packets of [`super::wide`] (four triangles each, structure of arrays), the ray
//! prepared for them, and the watertight test of [`super::watertight`] on the eight lanes of
//! two packets at once, written lane by lane so the compiler runs each step on all lanes (two
//! SSE halves, or one AVX2 operation where the traversal is compiled for it). A packet keeps
//! its triangles' exact vertices (the test needs the bits two triangles share on an edge to be
//! the same) and a caller's tag per lane, which a hit returns.

use glam::{Vec3, Vec4};

use super::watertight::{Shear, edge_functions_f64};

/// Four triangles, structure of arrays: their three vertices, exactly as given (the
/// watertight test needs the bits two triangles share on an edge to be the same).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// Per vertex, its x, y and z over the four lanes.
    pub(super) v: [[Vec4; 3]; 3],
    /// The caller's tag of each lane (`u32::MAX` for padding lanes, whose vertices are NaN).
    pub(super) id: [u32; 4],
}

/// A ray prepared for the slab tests and the watertight triangle test.
#[derive(Clone, Copy, Debug)]
pub struct Ray4 {
    /// Origin.
    pub(super) o: [f32; 3],
    /// 1 / direction, ±`f32::MAX` where that overflows (for the node tests).
    pub(super) inv: [f32; 3],
    /// The ray's frame for the triangle test.
    pub(super) shear: Shear,
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
            shear,
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
}

/// Packs up to four triangles with their tags; unused lanes have NaN vertices (every test on
/// them fails, so they never hit and never ask for the double-precision redo) and the tag
/// `u32::MAX`.
pub(super) fn pack(prims: &[u32], tris: &[[Vec3; 3]], tags: &[u32]) -> Tri4 {
    debug_assert!(!prims.is_empty() && prims.len() <= 4);
    let mut t = Tri4 {
        v: [[Vec4::NAN; 3]; 3],
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

/// A packet of padding lanes, to test a lone packet eight lanes wide.
static PADDING: Tri4 = Tri4 {
    v: [[Vec4::NAN; 3]; 3],
    id: [u32::MAX; 4],
};

/// The watertight test ([`super::watertight`]) against the eight triangles of two packets at
/// once (one 256-bit operation per step where the caller is compiled for AVX2): the nearest
/// hit with t in [tmin, tmax], lanes of `a` winning ties.
#[inline(always)]
pub(super) fn intersect8(a: &Tri4, b: &Tri4, ray: &Ray4) -> Option<Hit4> {
    let join = |p: Vec4, q: Vec4| {
        let (p, q) = (p.to_array(), q.to_array());
        [p[0], p[1], p[2], p[3], q[0], q[1], q[2], q[3]]
    };
    let lanes: Lanes<8> =
        std::array::from_fn(|k| std::array::from_fn(|axis| join(a.v[k][axis], b.v[k][axis])));
    let (i, j) = (a.id, b.id);
    let id = [i[0], i[1], i[2], i[3], j[0], j[1], j[2], j[3]];
    intersect_lanes(&lanes, &id, &[a, b], ray)
}

/// The nearest hit of a leaf's packets, two at a time.
#[inline(always)]
pub(super) fn intersect_leaf(packets: &[Tri4], ray: &Ray4) -> Option<Hit4> {
    let mut best: Option<Hit4> = None;
    for pair in packets.chunks(2) {
        let hit = match pair {
            [a, b] => intersect8(a, b, ray),
            [a] => intersect8(a, &PADDING, ray),
            _ => None,
        };
        if let Some(h) = hit
            && best.is_none_or(|b| h.t < b.t)
        {
            best = Some(h);
        }
    }
    best
}

/// Vertices of `N` lanes: per vertex, x, y and z rows.
type Lanes<const N: usize> = [[[f32; N]; 3]; 3];

/// The watertight test on `N` lanes of `packets` (lane `i` is lane `i % 4` of packet `i / 4`),
/// written lane by lane so the compiler runs each step on all lanes at once (as two SSE
/// halves, or one AVX2 operation).
#[inline(always)]
fn intersect_lanes<const N: usize>(
    lanes: &Lanes<N>,
    id: &[u32; N],
    packets: &[&Tri4],
    ray: &Ray4,
) -> Option<Hit4> {
    let [kx, ky, kz] = ray.shear.axes;
    let [sx, sy, sz] = ray.shear.s;
    let o = ray.o;
    // The vertices relative to the origin, sheared into the ray's frame, and the edge
    // functions; exact zeros (a ray through an edge or a vertex) are redone in double
    // precision.
    let (mut u, mut v, mut w) = ([0f32; N], [0f32; N], [0f32; N]);
    let mut z = [[0f32; N]; 3];
    let mut zero = [false; N];
    for i in 0..N {
        let rel = |k: usize| {
            let p = &lanes[k];
            let pz = p[kz][i] - o[kz];
            (p[kx][i] - o[kx] - sx * pz, p[ky][i] - o[ky] - sy * pz, pz)
        };
        let (ax, ay, az) = rel(0);
        let (bx, by, bz) = rel(1);
        let (cx, cy, cz) = rel(2);
        u[i] = cx * by - cy * bx;
        v[i] = ax * cy - ay * cx;
        w[i] = bx * ay - by * ax;
        z[0][i] = az;
        z[1][i] = bz;
        z[2][i] = cz;
        zero[i] = (u[i] == 0.0) | (v[i] == 0.0) | (w[i] == 0.0);
    }
    if zero.contains(&true) {
        redo_in_f64(packets, ray, &zero, (&mut u, &mut v, &mut w));
    }
    // t·det, compared scaled by |det| (signs folded in), so only lanes that hit pay for the
    // division (as Embree's intersectors do).
    let mut t = [0f32; N];
    let mut det = [0f32; N];
    let mut hit = [false; N];
    for i in 0..N {
        let negative = (u[i] < 0.0) | (v[i] < 0.0) | (w[i] < 0.0);
        let positive = (u[i] > 0.0) | (v[i] > 0.0) | (w[i] > 0.0);
        det[i] = u[i] + v[i] + w[i];
        t[i] = (u[i] * z[0][i] + v[i] * z[1][i] + w[i] * z[2][i]) * sz;
        let abs_det = det[i].abs();
        let t_abs = t[i] * 1f32.copysign(det[i]);
        hit[i] = !(negative & positive)
            & (abs_det > 0.0)
            & (abs_det < f32::INFINITY)
            & (t_abs >= abs_det * ray.tmin)
            & (t_abs <= abs_det * ray.tmax);
    }
    if !hit.contains(&true) {
        return None;
    }
    let mut best: Option<Hit4> = None;
    for lane in (0..N).filter(|&lane| hit[lane]) {
        let inv = 1.0 / det[lane];
        let tl = t[lane] * inv;
        if best.is_none_or(|b| tl < b.t) {
            // The division may round just outside the interval the scaled test accepted.
            best = Some(Hit4 {
                tag: id[lane],
                t: tl.clamp(ray.tmin, ray.tmax),
                u: v[lane] * inv,
                v: w[lane] * inv,
            });
        }
    }
    best
}

/// The edge functions of the lanes marked in `lanes` recomputed in double precision; padding
/// lanes keep theirs (they never hit).
#[cold]
#[inline(never)]
fn redo_in_f64<const N: usize>(
    packets: &[&Tri4],
    ray: &Ray4,
    lanes: &[bool; N],
    (u, v, w): (&mut [f32; N], &mut [f32; N], &mut [f32; N]),
) {
    let origin = Vec3::from_array(ray.o);
    for (i, _) in lanes.iter().enumerate().filter(|(_, redo)| **redo) {
        let (tri, lane) = (packets[i / 4], i % 4);
        if tri.id[lane] == u32::MAX {
            continue;
        }
        let [a, b, c] = lane_vertices(tri, lane).map(|p| p - origin);
        [u[i], v[i], w[i]] = edge_functions_f64(&ray.shear, a, b, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::watertight::intersect;
    use crate::sampling::{hash_words, unit_float};

    /// Two packets tested as eight lanes give the scalar test's hit to the bit: the nearest,
    /// the first lane winning ties.
    #[test]
    fn eight_lanes_give_the_scalar_tests_bits() {
        let mut hits = 0;
        for case in 0..2000u32 {
            let r = |k: u32| unit_float(hash_words(&[case, k])) * 2.0 - 1.0;
            let count = 5 + (case % 4) as usize;
            let tris: Vec<[Vec3; 3]> = (0..count as u32)
                .map(|t| {
                    let c = Vec3::new(r(10 * t), r(10 * t + 1), r(10 * t + 2));
                    [0, 1, 2].map(|k| {
                        c + 0.6
                            * Vec3::new(
                                r(10 * t + 3 + 3 * k),
                                r(10 * t + 4 + 3 * k),
                                r(10 * t + 5 + 3 * k),
                            )
                    })
                })
                .collect();
            let prims: Vec<u32> = (0..count as u32).collect();
            let tags: Vec<u32> = (100..100 + count as u32).collect();
            let packets = [
                pack(&prims[..4], &tris, &tags),
                pack(&prims[4..], &tris, &tags),
            ];
            let origin = 3.0 * Vec3::new(r(90), r(91), r(92));
            let dir = (Vec3::new(r(93), r(94), r(95)) * 0.3 - origin).normalize();
            let tmax = if case % 5 == 0 { 2.5 } else { f32::INFINITY };
            let ray = Ray4::new(origin, dir, 0.0, tmax);
            let lanes = intersect_leaf(&packets, &ray);
            let mut scalar: Option<Hit4> = None;
            for (k, tri) in tris.iter().enumerate() {
                if let Some((t, u, v)) = intersect(tri, origin, &ray.shear, 0.0, tmax)
                    && scalar.is_none_or(|b| t < b.t)
                {
                    scalar = Some(Hit4 {
                        tag: tags[k],
                        t,
                        u,
                        v,
                    });
                }
            }
            let bits =
                |h: Option<Hit4>| h.map(|h| (h.tag, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()));
            assert_eq!(bits(lanes), bits(scalar), "case {case}");
            hits += usize::from(lanes.is_some());
        }
        assert!(hits > 300, "{hits} hits");
    }

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
        let Hit4 { tag, t, u, v } = intersect_leaf(&[packet], &ray).unwrap();
        assert_eq!(tag, 0);
        assert!((t - 1.0).abs() < 1e-6 && (u - 0.2).abs() < 1e-6 && (v - 0.3).abs() < 1e-6);
        // From above, the z = 1 triangle; a short ray misses both; the degenerate lane never hits.
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(intersect_leaf(&[packet], &ray).unwrap().tag, 1);
        let ray = Ray4::new(Vec3::new(0.2, 0.3, 2.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect_leaf(&[packet], &ray).is_none());
        let ray = Ray4::new(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(intersect_leaf(&[packet], &ray).is_some_and(|h| h.tag != 2));
    }
}
