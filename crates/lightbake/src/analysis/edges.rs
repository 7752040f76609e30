//! Edges: where a lightmap goes wrong first. Points sampled densely next to **contacts**
//! (a block standing on a floor, a cabinet against a wall, a wall meeting the floor) and
//! across **seams** (one surface split between two charts, [`crate::lightmap::seams`]) are
//! scored against the path tracer as [`super::points`] scores the whole surface, next to
//! points away from both.
//!
//! * **Contact points**: open surface points (as in [`super::points`]) from which a probe
//!   finds other geometry within `band` metres: eight rays along the surface (lifted off it by
//!   the ray offset) and one along the normal.
//! * **Seam points**: points of a seam's triangles within `band` of the seam, the edge
//!   parameter and the distance from it uniform.
//! * **Interior points**: open surface points whose probe finds nothing within `band`.
//!
//! Every point is also in view ([`is_seen`]): points in gaps thinner than a few texels, which
//! no camera sees, are left out.
//!
//! `band` is two texels of the bake's texel density ([`band`]), so the points cover the
//! texels whose bilinear reconstruction a contact or a seam touches.
//!
//! Per class, [`edge_score`] reports the relative RMS of [`super::points::score`] and the share
//! of points whose baked luminance is more than 25% off the reference, split into too bright
//! and too dark (points where both are black, below 1% of the RMS reference, are left out of
//! the shares).

// Without `internals` only `verify` and `study` use this module; the rest is for the tests
// and the benchmarks.
#![cfg_attr(not(feature = "internals"), allow(dead_code))]

use glam::{Vec2, Vec3};
use serde::Serialize;

use super::points::{
    ScorePoint, ScorePoints, is_open, references, sample_bake, sample_surface, surface_point,
};
use crate::bake::BakeOutput;
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::lightmap::seams::find_seams;
use crate::raster::SurfacePoint;
use crate::sampling::{basis, cosine_hemisphere, hash_words, sobol_02, unit_float};
use crate::scene::Scene;

/// Which kind of place a point lies at.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EdgeKind {
    /// Within `band` of other geometry.
    Contact,
    /// Within `band` of a seam.
    Seam,
    /// Neither (a contact probe finds nothing within `band`; seams are not checked).
    Interior,
}

/// The edge points of one bake's layout and their reference.
#[derive(Clone, Debug)]
pub struct EdgePoints {
    /// Points with the path tracer's reference.
    pub points: ScorePoints,
    /// The kind of each point.
    pub kinds: Vec<EdgeKind>,
    /// Width of the band around contacts and seams, m.
    pub band: f32,
}

/// Two texels at the bake's texel density, m: the band [`edge_points`] samples.
pub fn band(out: &BakeOutput) -> f32 {
    2.0 / out.report.plan.texel_density
}

/// Rays of [`is_seen`]'s fan, and how many of them must travel [`SEEN_BANDS`] bands.
const SEEN_RAYS: u32 = 16;
const SEEN_NEEDED: usize = 4;
/// How far (in bands) a point must see to count as in view.
const SEEN_BANDS: f32 = 4.0;

/// Whether a viewer can see `sp` from a few texels away: at least a quarter of a cosine fan
/// of rays (scrambled by `key`) travels four bands before hitting anything. A point in a gap
/// thinner than that (under a rug, between a slab and the ground 1 mm below it) is left out:
/// no camera of the level sees it, and its light, whatever it is, shows nowhere.
pub fn is_seen(rays: &RayScene, sp: &SurfacePoint, band: f32, key: u32) -> bool {
    let g = sp.geometric_normal;
    let origin = rays.offset(sp.position, g);
    (0..SEEN_RAYS)
        .filter(|&s| {
            let dir = cosine_hemisphere(g, sobol_02(s, key));
            !rays.occluded(origin, dir, 0.0, SEEN_BANDS * band)
        })
        .take(SEEN_NEEDED)
        .count()
        == SEEN_NEEDED
}

/// Distance to the nearest other geometry within `reach` of `sp`: eight rays along the surface
/// and one along the normal, from the point lifted by the ray offset.
pub fn contact_distance(rays: &RayScene, sp: &SurfacePoint, reach: f32) -> Option<f32> {
    let g = sp.geometric_normal;
    let (t, b) = basis(g);
    let origin = rays.offset(sp.position, g);
    let along = (0..8).map(|k| {
        let phi = std::f32::consts::TAU * k as f32 / 8.0;
        (t * phi.cos() + b * phi.sin()).normalize()
    });
    along
        .chain(std::iter::once(g))
        .filter_map(|dir| rays.closest_hit(origin, dir, 0.0, reach).map(|h| h.t))
        .reduce(f32::min)
}

/// `count` points of each kind of `out`'s scene (`scene` is the scene that was baked), with
/// the reference at `paths` paths each (see the module docs); half as many interior points.
/// Numbers from `seed`.
pub fn edge_points(
    scene: &Scene,
    out: &BakeOutput,
    count: usize,
    paths: u32,
    seed: u32,
) -> EdgePoints {
    let start = std::time::Instant::now();
    let band = band(out);
    let rays = RayScene::build(scene);
    let seen = |sp: &SurfacePoint| is_seen(&rays, sp, band, hash_words(&[seed, sp.triangle]));
    let contacts = sample_surface(scene, &rays, count, seed, |sp| {
        contact_distance(&rays, sp, band).is_some() && seen(sp)
    });
    let interior = sample_surface(scene, &rays, count / 2, seed ^ 0x1e7e, |sp| {
        contact_distance(&rays, sp, band).is_none() && seen(sp)
    });
    let seams = seam_points(out, &rays, band, count, seed);
    let mut kinds = vec![EdgeKind::Contact; contacts.len()];
    kinds.extend(std::iter::repeat_n(EdgeKind::Seam, seams.len()));
    kinds.extend(std::iter::repeat_n(EdgeKind::Interior, interior.len()));
    let candidates: Vec<SurfacePoint> = contacts.into_iter().chain(seams).chain(interior).collect();
    let points = references(scene, &rays, &candidates, paths, seed);
    EdgePoints {
        points: ScorePoints {
            points,
            paths: 2 * paths.div_ceil(2),
            seconds: start.elapsed().as_secs_f64(),
        },
        kinds,
        band,
    }
}

/// `count` open points within `band` of `out`'s seams (see the module docs).
fn seam_points(
    out: &BakeOutput,
    rays: &RayScene,
    band: f32,
    count: usize,
    seed: u32,
) -> Vec<SurfacePoint> {
    let seams = find_seams(&out.baked_scene, &out.layout);
    // Both sides of every seam, by length.
    let sides: Vec<(usize, usize)> = (0..seams.len()).flat_map(|s| [(s, 0), (s, 1)]).collect();
    let mut cdf = Vec::with_capacity(sides.len());
    let mut total = 0.0f64;
    for &(s, _) in &sides {
        total += seams[s].world[0].distance(seams[s].world[1]) as f64;
        cdf.push(total);
    }
    let mut points = Vec::with_capacity(count);
    let mut attempt = 0u32;
    while points.len() < count && total > 0.0 && attempt < 64 * count as u32 {
        attempt += 1;
        let key = hash_words(&[seed, 0x5ea3, attempt]);
        let u = |k: u32| unit_float(hash_words(&[key, k]));
        let pick = cdf.partition_point(|&c| c <= u(1) as f64 * total);
        let (s, side) = sides[pick.min(sides.len() - 1)];
        let seam = &seams[s];
        let sd = seam.sides[side];
        let g = rays.instance_first_triangle[sd.instance as usize] + sd.triangle;
        let [v0, v1, v2] = rays.triangle_vertices(g);
        // From the edge point inwards, perpendicular to the edge in the triangle's plane.
        let on_edge = seam.world[0].lerp(seam.world[1], u(2));
        let along = (seam.world[1] - seam.world[0]).normalize_or_zero();
        let normal = rays.triangles[g as usize].normal;
        let mut inward = normal.cross(along);
        let centroid = (v0 + v1 + v2) / 3.0;
        if inward.dot(centroid - on_edge) < 0.0 {
            inward = -inward;
        }
        let p = on_edge + inward * (band * u(3));
        let Some(bary) = barycentrics([v0, v1, v2], p) else {
            continue;
        };
        let sp = surface_point(&out.baked_scene, rays, g, bary);
        if is_open(rays, sp.position, sp.geometric_normal, key) && is_seen(rays, &sp, band, key) {
            points.push(sp);
        }
    }
    points
}

/// Barycentrics (of the second and third vertices) of `p` in triangle `t`, if it lies inside.
fn barycentrics(t: [Vec3; 3], p: Vec3) -> Option<Vec2> {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], p - t[0]);
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (d.dot(e1), d.dot(e2));
    let det = d00 * d11 - d01 * d01;
    if det <= 0.0 {
        return None;
    }
    let v = (d11 * d20 - d01 * d21) / det;
    let w = (d00 * d21 - d01 * d20) / det;
    (v >= 0.0 && w >= 0.0 && v + w <= 1.0).then_some(Vec2::new(v, w))
}

/// One kind of point scored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ClassScore {
    /// Points scored (those where the reference or the bake is not black).
    pub points: usize,
    /// Relative RMS error, the reference's noise taken out ([`super::points::score`]).
    pub relative_rms: f64,
    /// The reference's own noise, relative RMS.
    pub reference_noise: f64,
    /// Share of points whose baked luminance is more than 25% above the reference.
    pub bright: f64,
    /// Share more than 25% below.
    pub dark: f64,
}

impl ClassScore {
    /// Share of points more than 25% off either way.
    pub fn beyond(&self) -> f64 {
        self.bright + self.dark
    }
}

/// A bake scored at its edge points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct EdgeScore {
    /// Next to contacts.
    pub contact: ClassScore,
    /// Across seams.
    pub seam: ClassScore,
    /// Away from both.
    pub interior: ClassScore,
}

/// `out` scored at `points` (see the module docs).
pub fn edge_score(points: &EdgePoints, out: &BakeOutput) -> EdgeScore {
    let floor = dark_floor(&points.points);
    let class = |kind: EdgeKind| {
        let chosen: Vec<&ScorePoint> = points
            .points
            .points
            .iter()
            .zip(&points.kinds)
            .filter(|(_, k)| **k == kind)
            .map(|(p, _)| p)
            .collect();
        score_class(&chosen, out, floor)
    };
    EdgeScore {
        contact: class(EdgeKind::Contact),
        seam: class(EdgeKind::Seam),
        interior: class(EdgeKind::Interior),
    }
}

/// Luminance below which a point counts as black: 1% of the RMS reference luminance of all
/// the points. A point whose reference and bake are both below it is left out of the
/// shares (the outside of a closed room, a cupboard's inside): both are black, and a ratio
/// of two near-zero values says nothing the eye sees.
fn dark_floor(points: &ScorePoints) -> f64 {
    let n = points.points.len().max(1) as f64;
    let sum: f64 = points
        .points
        .iter()
        .map(|p| (luminance(p.reference) as f64).powi(2))
        .sum();
    0.01 * (sum / n).sqrt()
}

/// The [`ClassScore`] of `points`; `floor` from [`dark_floor`].
fn score_class(points: &[&ScorePoint], out: &BakeOutput, floor: f64) -> ClassScore {
    let (mut diff, mut norm, mut noise) = (0.0f64, 0.0f64, 0.0f64);
    let mut s = ClassScore::default();
    for p in points {
        let Some(baked) = sample_bake(out, p) else {
            continue;
        };
        let r = luminance(p.reference) as f64;
        let b = luminance(baked) as f64;
        diff += (b - r) * (b - r);
        norm += r * r;
        noise += p.variance;
        if r < floor && b < floor {
            continue;
        }
        s.points += 1;
        if b > 1.25 * r.max(floor) {
            s.bright += 1.0;
        } else if b < 0.75 * r {
            s.dark += 1.0;
        }
    }
    if s.points > 0 {
        s.bright /= s.points as f64;
        s.dark /= s.points as f64;
    }
    if norm > 0.0 {
        s.relative_rms = ((diff - noise).max(0.0) / norm).sqrt();
        s.reference_noise = (noise / norm).sqrt();
    }
    s
}
