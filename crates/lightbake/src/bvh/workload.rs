//! Baker-style ray workloads for benchmarks and comparisons (the same rays can be written out
//! for other tracers, such as the Embree harness in `benches/`).
//!
//! * **Gather rays** (incoherent closest hit): an area-weighted random point on a random
//!   triangle, offset along its normal, and a cosine-distributed direction about it — what a
//!   radiosity gather or a sky pass traces.
//! * **Shadow rays** (any hit): the same kind of origins towards a random point of a target
//!   triangle set (a ceiling light), ending just short of it.

use glam::Vec3;

use super::RayScene;
use crate::sampling::{cosine_hemisphere, hash_words, uniform_triangle, unit_float};

/// One ray: origin, unit direction, [0, tmax].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BenchRay {
    /// Origin, m.
    pub origin: Vec3,
    /// Unit direction.
    pub direction: Vec3,
    /// Far end of the segment, m (∞ for gather rays).
    pub tmax: f32,
}

fn area_cdf(rays: &RayScene, filter: impl Fn(u32) -> bool) -> (Vec<u32>, Vec<f64>) {
    let mut ids = Vec::new();
    let mut cdf = Vec::new();
    let mut total = 0.0f64;
    for (g, t) in rays.triangles.iter().enumerate() {
        if t.area > 0.0 && filter(g as u32) {
            total += t.area as f64;
            ids.push(g as u32);
            cdf.push(total);
        }
    }
    (ids, cdf.into_iter().map(|c| c / total).collect())
}

fn sample_point(rays: &RayScene, ids: &[u32], cdf: &[f64], key: u32) -> (Vec3, Vec3) {
    let u = unit_float(hash_words(&[key, 1])) as f64;
    let k = cdf.partition_point(|&c| c <= u).min(ids.len() - 1);
    let g = ids[k];
    let v = rays.triangle_vertices(g);
    let b = uniform_triangle(glam::Vec2::new(
        unit_float(hash_words(&[key, 2])),
        unit_float(hash_words(&[key, 3])),
    ));
    let p = v[0] * (1.0 - b.x - b.y) + v[1] * b.x + v[2] * b.y;
    (p, rays.triangles[g as usize].normal)
}

/// `count` incoherent gather rays from random surface points.
pub fn gather_rays(rays: &RayScene, count: usize, seed: u32) -> Vec<BenchRay> {
    let (ids, cdf) = area_cdf(rays, |_| true);
    (0..count as u32)
        .map(|i| {
            let key = hash_words(&[seed, i]);
            let (p, n) = sample_point(rays, &ids, &cdf, key);
            let u = glam::Vec2::new(
                unit_float(hash_words(&[key, 4])),
                unit_float(hash_words(&[key, 5])),
            );
            BenchRay {
                origin: rays.offset(p, n),
                direction: cosine_hemisphere(n, u),
                tmax: f32::INFINITY,
            }
        })
        .collect()
}

/// `count` shadow rays from random surface points to random points on the triangles accepted
/// by `target` (for example the emitter's).
pub fn shadow_rays(
    rays: &RayScene,
    count: usize,
    seed: u32,
    target: impl Fn(u32) -> bool,
) -> Vec<BenchRay> {
    let (ids, cdf) = area_cdf(rays, |_| true);
    let (tids, tcdf) = area_cdf(rays, target);
    assert!(!tids.is_empty(), "no target triangles");
    (0..count as u32)
        .map(|i| {
            let key = hash_words(&[seed, i]);
            let (p, n) = sample_point(rays, &ids, &cdf, key);
            let (q, _) = sample_point(rays, &tids, &tcdf, hash_words(&[key, 9]));
            let o = rays.offset(p, n);
            let d = q - o;
            let len = d.length();
            BenchRay {
                origin: o,
                direction: d / len,
                tmax: len - 2.0 * rays.epsilon(q),
            }
        })
        .collect()
}
