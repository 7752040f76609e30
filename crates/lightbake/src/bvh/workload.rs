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

/// Measured ray rates of a scene's BVH on the current rayon pool, rays per second.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RayRates {
    /// Incoherent closest-hit gather rays per second.
    pub closest_per_second: f64,
    /// Any-hit shadow rays per second.
    pub shadow_per_second: f64,
}

/// Gather rays from `origins` (points and their unit normals, picked at random), offset
/// along the normal, with cosine-distributed directions; and shadow rays from one picked
/// origin to another, ending just short of it.
pub fn rays_from(
    rays: &RayScene,
    origins: &[(Vec3, Vec3)],
    count: usize,
    seed: u32,
) -> (Vec<BenchRay>, Vec<BenchRay>) {
    let pick = |key: u32| origins[(key as usize) % origins.len()];
    let gather = (0..count as u32)
        .map(|i| {
            let key = hash_words(&[seed, i]);
            let (p, n) = pick(key);
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
        .collect();
    let shadow = (0..count as u32)
        .filter_map(|i| {
            let key = hash_words(&[seed ^ 0x5bd1_e995, i]);
            let (p, n) = pick(key);
            let (q, m) = pick(hash_words(&[key, 9]));
            let (o, target) = (rays.offset(p, n), rays.offset(q, m));
            let d = target - o;
            let len = d.length();
            (len > 0.0).then(|| BenchRay {
                origin: o,
                direction: d / len,
                tmax: len,
            })
        })
        .collect();
    (gather, shadow)
}

/// Times `count` gather rays and `count` shadow rays through `rays` on the current rayon
/// pool: the rates the bake's ray-tracing floor is computed with. The rays start at
/// `origins` ([`rays_from`]: the points the bake's own rays start from, so the rates are
/// those of rays like the bake's), or at area-weighted surface points when there are none
/// ([`gather_rays`], [`shadow_rays`]).
pub fn calibrate(rays: &RayScene, origins: &[(Vec3, Vec3)], count: usize, seed: u32) -> RayRates {
    use rayon::prelude::*;
    if rays.triangles.iter().all(|t| t.area <= 0.0) || count == 0 {
        return RayRates::default();
    }
    let (gather, shadow) = if origins.is_empty() {
        (
            gather_rays(rays, count, seed),
            shadow_rays(rays, count, seed ^ 0x5bd1_e995, |_| true),
        )
    } else {
        rays_from(rays, origins, count, seed)
    };
    let time = |n: usize, f: &dyn Fn() -> usize| {
        let start = std::time::Instant::now();
        std::hint::black_box(f());
        n as f64 / start.elapsed().as_secs_f64().max(1e-9)
    };
    let closest = time(gather.len(), &|| {
        gather
            .par_iter()
            .with_min_len(256)
            .filter(|r| {
                rays.closest_hit(r.origin, r.direction, 0.0, r.tmax)
                    .is_some()
            })
            .count()
    });
    let shadow = time(shadow.len(), &|| {
        shadow
            .par_iter()
            .with_min_len(256)
            .filter(|r| rays.occluded(r.origin, r.direction, 0.0, r.tmax))
            .count()
    });
    RayRates {
        closest_per_second: closest,
        shadow_per_second: shadow,
    }
}

/// The ray benchmark's workload (`benches/trace.rs`, `examples/ray_workload.rs`): the Cornell
/// box with every quad split 80 × 80 (204 800 triangles), `count` gather rays (seed 1) and
/// `count` shadow rays towards the ceiling light (seed 2).
#[cfg(all(feature = "testscenes", feature = "internals"))]
pub fn cornell_workload(count: usize) -> (RayScene, Vec<BenchRay>, Vec<BenchRay>) {
    use crate::scene::testscenes::{CornellLight, cornell_box_dense};
    let scene = cornell_box_dense(CornellLight::Area, 80);
    let rays = RayScene::build(&scene);
    let light = scene
        .instances
        .iter()
        .position(|i| i.name == "light")
        .expect("the Cornell box has a light");
    let (lo, hi) = (
        rays.instance_first_triangle[light],
        rays.instance_first_triangle[light + 1],
    );
    let gather = gather_rays(&rays, count, 1);
    let shadow = shadow_rays(&rays, count, 2, |g| (lo..hi).contains(&g));
    (rays, gather, shadow)
}

/// A real-scene workload: the triangles of every instance of `scene`, `count` gather rays
/// (seed 1) and `count` shadow rays between two area-weighted surface points (seed 2; the
/// visibility queries of a form factor or a validity probe).
#[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the benchmarks
pub fn scene_workload(
    scene: &crate::scene::Scene,
    count: usize,
) -> (RayScene, Vec<BenchRay>, Vec<BenchRay>) {
    let rays = RayScene::build(scene);
    let gather = gather_rays(&rays, count, 1);
    let shadow = shadow_rays(&rays, count, 2, |_| true);
    (rays, gather, shadow)
}
