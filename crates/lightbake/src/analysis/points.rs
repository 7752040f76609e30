//! Scoring a bake at surface points against the path tracer, whatever its layout: bakes at
//! different texel densities (the presets, a scene in another unit) have different texels,
//! but the same surface.
//!
//! * **Points.** Random points of the baked surfaces, weighted by area × the instance's
//!   texel-density scale² (a ground plane baked at an eighth of the density carries a 64th
//!   of the weight; the bake's texel-grid estimate weights its points so too, whatever
//!   density the density pass gave each chart), keeping those that are
//!   open surface: a cosine fan of 16 rays from the point sees the back of a single-sided
//!   surface at most twice (points inside solids and in the crack where a wall meets the
//!   floor are left out; the bake leaves them out too).
//! * **Reference.** [`reference::irradiance`] at every point, in two independent halves, so
//!   the reference's own noise is known: the variance of the mean is (h₁ − h₂)²/4.
//! * **Bake.** The lightmap where the GPU reads it: the point's lightmap UV in the baked scene
//!   (found on the nearest triangle of its instance's baked mesh), sampled bilinearly from
//!   the page, padding included.
//! * **Error.** Relative RMS of the luminance of E/π, √((Σ(b − r)² − Σ var r) / Σ r²): the
//!   normalisation of [`crate::error_estimate`] (relative to the RMS value), with the
//!   reference's noise taken out.

// Without `internals` only `verify` and `study` use this module; the rest is for the tests
// and the benchmarks.
#![cfg_attr(not(feature = "internals"), allow(dead_code))]

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::reference;
use crate::bake::BakeOutput;
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::lights::Emitters;
use crate::plan::BakePlan;
use crate::raster::{Patches, SurfacePoint};
use crate::sampling::{cosine_hemisphere, hash_words, sobol_02, uniform_triangle, unit_float};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::unwrap::Layout;

/// One scoring point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScorePoint {
    /// Scene instance it lies on.
    pub instance: u32,
    /// World position, m.
    pub position: Vec3,
    /// Unit geometric normal (world).
    pub normal: Vec3,
    /// The path tracer's E/π there (direct and indirect; without the direct light of lights
    /// baked indirect only), linear RGB.
    pub reference: Vec3,
    /// The variance of the reference's luminance (of its mean of two halves).
    pub variance: f64,
}

/// The points of one scene and their reference.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScorePoints {
    /// The points.
    pub points: Vec<ScorePoint>,
    /// Paths per point.
    pub paths: u32,
    /// Wall time of the reference, s.
    pub seconds: f64,
}

/// A bake scored at the points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Score {
    /// Relative RMS error, the reference's noise taken out (see the module docs).
    pub relative_rms: f64,
    /// The reference's own noise, relative RMS.
    pub reference_noise: f64,
    /// Points the bake could be read at (the rest lie on instances it did not bake).
    pub points: usize,
}

/// Back faces the fan of a scoring point may see (of 16).
const OPEN_BACK: u32 = 2;

/// `count` scoring points of `scene` with the path tracer's reference at `paths` paths each,
/// numbers from `seed`.
pub fn score_points(scene: &Scene, count: usize, paths: u32, seed: u32) -> ScorePoints {
    let start = std::time::Instant::now();
    let rays = RayScene::build(scene);
    let candidates = sample_surface(scene, &rays, count, seed, |_| true);
    let points = references(scene, &rays, &candidates, paths, seed);
    ScorePoints {
        points,
        paths: 2 * paths.div_ceil(2),
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// The path tracer's reference at `candidates` (see the module docs): two independent halves
/// of `paths` paths each point, numbers from `seed`.
pub fn references(
    scene: &Scene,
    rays: &RayScene,
    candidates: &[SurfacePoint],
    paths: u32,
    seed: u32,
) -> Vec<ScorePoint> {
    // The path tracer reads the scene, the rays and the lights; it needs no layout.
    let settings = BakeSettings::default();
    let plan = BakePlan::new(scene, &settings);
    let (layout, patches) = (Layout::default(), Patches::default());
    let ctx = BakeContext {
        scene,
        layout: &layout,
        rays,
        patches: &patches,
        settings: &settings,
        plan: &plan,
    };
    let emitters = Emitters::collect(scene, rays);
    candidates
        .par_iter()
        .enumerate()
        .map(|(k, sp)| {
            let half = |h: u32| {
                let r = reference::irradiance(
                    &ctx,
                    &emitters,
                    sp,
                    paths.div_ceil(2),
                    hash_words(&[seed, k as u32, h]),
                );
                (r.direct - r.realtime + r.indirect) / std::f32::consts::PI
            };
            let (a, b) = (half(1), half(2));
            let d = luminance(a) as f64 - luminance(b) as f64;
            ScorePoint {
                instance: rays.triangles[sp.triangle as usize].instance,
                position: sp.position,
                normal: sp.geometric_normal,
                reference: 0.5 * (a + b),
                variance: 0.25 * d * d,
            }
        })
        .collect()
}

/// Whether a point with geometric normal `normal` is open surface: at most `OPEN_BACK` (2) of
/// a cosine fan of 16 rays (scrambled by `key`) see the back of a single-sided surface.
pub fn is_open(rays: &RayScene, position: Vec3, normal: Vec3, key: u32) -> bool {
    let origin = rays.offset(position, normal);
    let backs = (0..16)
        .filter(|&s| {
            let dir = cosine_hemisphere(normal, sobol_02(s, key));
            rays.closest_hit(origin, dir, 0.0, f32::INFINITY)
                .is_some_and(|h| !h.front_face && !rays.triangles[h.triangle as usize].double_sided)
        })
        .count() as u32;
    backs <= OPEN_BACK
}

/// The surface point of global triangle `g` at barycentrics `b`, with the shading normal
/// the bake's texels use (interpolated from [`crate::scene::Mesh::corner_normals`], turned to
/// the front side).
pub fn surface_point(scene: &Scene, rays: &RayScene, g: u32, b: Vec2) -> SurfacePoint {
    let info = rays.triangles[g as usize];
    let [v0, v1, v2] = rays.triangle_vertices(g);
    let position = v0 * (1.0 - b.x - b.y) + v1 * b.x + v2 * b.y;
    let inst = &scene.instances[info.instance as usize];
    let mesh = &scene.meshes[inst.mesh];
    let local = mesh.shading_normal(info.local as usize, b);
    let mut normal = (inst.normal_matrix() * local).normalize_or_zero();
    if normal.dot(info.normal) <= 0.0 {
        normal = info.normal;
    }
    SurfacePoint {
        position,
        normal,
        geometric_normal: info.normal,
        triangle: g,
        bary: b,
    }
}

/// `count` open points of the baked surfaces (see the module docs) that `keep` accepts.
pub fn sample_surface(
    scene: &Scene,
    rays: &RayScene,
    count: usize,
    seed: u32,
    keep: impl Fn(&SurfacePoint) -> bool + Sync,
) -> Vec<SurfacePoint> {
    let mut cdf = Vec::with_capacity(rays.triangles.len());
    let mut total = 0.0f64;
    for t in &rays.triangles {
        let inst = &scene.instances[t.instance as usize];
        if inst.bake {
            let s = inst.texel_density_scale as f64;
            total += t.area as f64 * s * s;
        }
        cdf.push(total);
    }
    let mut out = Vec::with_capacity(count);
    let mut attempt = 0u32;
    // Candidates in parallel batches, kept in attempt order (the same points on any thread
    // count).
    const BATCH: u32 = 4096;
    let limit = 256 * count as u32;
    while out.len() < count && total > 0.0 && attempt < limit {
        let batch: Vec<Option<SurfacePoint>> = (attempt..attempt + BATCH)
            .into_par_iter()
            .map(|a| {
                let key = hash_words(&[seed, 0x5c0e, a + 1]);
                let u = unit_float(hash_words(&[key, 1])) as f64 * total;
                let g = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
                if rays.triangles[g].area <= 0.0 {
                    return None;
                }
                let b = uniform_triangle(Vec2::new(
                    unit_float(hash_words(&[key, 2])),
                    unit_float(hash_words(&[key, 3])),
                ));
                let sp = surface_point(scene, rays, g as u32, b);
                (keep(&sp) && is_open(rays, sp.position, sp.geometric_normal, key)).then_some(sp)
            })
            .collect();
        attempt += BATCH;
        out.extend(batch.into_iter().flatten().take(count - out.len()));
    }
    out
}

/// `out` scored at `points` (see the module docs).
pub fn score(points: &ScorePoints, out: &BakeOutput) -> Score {
    let (mut diff, mut norm, mut noise, mut n) = (0.0f64, 0.0f64, 0.0f64, 0);
    for p in &points.points {
        let Some(baked) = sample_bake(out, p) else {
            continue;
        };
        let r = luminance(p.reference) as f64;
        let b = luminance(baked) as f64;
        diff += (b - r) * (b - r);
        norm += r * r;
        noise += p.variance;
        n += 1;
    }
    if norm <= 0.0 {
        return Score {
            points: n,
            ..Score::default()
        };
    }
    Score {
        relative_rms: ((diff - noise).max(0.0) / norm).sqrt(),
        reference_noise: (noise / norm).sqrt(),
        points: n,
    }
}

/// The bake's E/π at `p`: its lightmap UV on the nearest triangle of its instance's baked
/// mesh, sampled bilinearly from the page. `None` when the instance has no lightmap.
pub fn sample_bake(out: &BakeOutput, p: &ScorePoint) -> Option<Vec3> {
    let (page, q) = baked_uv(out, p)?;
    let page = &out.pages[page as usize];
    Some(page.sample_bilinear(q.x / page.width as f32, q.y / page.height as f32))
}

/// Where the lightmap shows `p`: its page and page texel point (see [`sample_bake`]).
pub fn baked_uv(out: &BakeOutput, p: &ScorePoint) -> Option<(u32, Vec2)> {
    let i = p.instance as usize;
    let rect = out.layout.instances.get(i).copied().flatten()?;
    let inst = out.baked_scene.instances.get(i)?;
    let mesh = &out.baked_scene.meshes[inst.mesh];
    let uv1 = mesh.uv1.as_ref()?;
    let local = inst.transform.inverse().transform_point3(p.position);
    // The nearest triangle (a point on a shared edge is on both: the one facing the same way
    // wins).
    let mut best: Option<(f32, [usize; 3], Vec2)> = None;
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let (pa, pb, pc) = (mesh.positions[a], mesh.positions[b], mesh.positions[c]);
        let n = inst.normal_matrix() * (pb - pa).cross(pc - pa);
        let facing = if n.dot(p.normal) > 0.0 { 0.0 } else { 1.0 };
        let (q, bary) = crate::scene::closest_on_triangle(local, [pa, pb, pc]);
        let d = (inst.transform.transform_point3(q) - p.position).length() + facing;
        if best.is_none_or(|b| d < b.0) {
            best = Some((d, [a, b, c], bary));
        }
    }
    let (_, [a, b, c], bary) = best?;
    let uv = uv1[a] * (1.0 - bary.x - bary.y) + uv1[b] * bary.x + uv1[c] * bary.y;
    let x = rect.x as f32 + uv.x * rect.width as f32;
    let y = rect.y as f32 + uv.y * rect.height as f32;
    Some((rect.page, Vec2::new(x, y)))
}
