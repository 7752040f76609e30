//! A brute-force path tracer of the irradiance at one point: the reference that error
//! measurements compare against (like bevy_solari's `pathtracer`, kept "to generate
//! reference screenshots to compare against"). Slow and simple on purpose.
//!
//! From the point x with normal n, cosine-distributed directions (pdf cosθ/π) sample the
//! incoming radiance, so each path contributes π·L: at every vertex y the throughput β takes
//! the albedo ρ(y) (β·π·ρ/π·…), and direct light at y is estimated by next-event estimation —
//! every punctual light exactly with a shadow ray, the sun by one sample of its cone — and the
//! sky when a continuation ray escapes. Emitters are reached both ways, a power-sampled point
//! on them and the continuation ray hitting them, combined by multiple importance sampling
//! with the power heuristic (Veach & Guibas 1995), which keeps the estimate bounded next to
//! an emitter's edge. Paths end by Russian roulette after three bounces (survival max(β), at
//! most 0.95). The result is split into *direct* (light arriving at x without reflection) and
//! *indirect*.

use glam::{Vec2, Vec3};

use crate::context::BakeContext;
use crate::lights::{Emitters, LightSource};
use crate::raster::SurfacePoint;
use crate::sampling::{cosine_hemisphere, hash_words, sobol_02, unit_float};
use crate::vpl::walk::albedo_at;

/// Irradiance at a point split by path length.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathIrradiance {
    /// Light that reaches x with no reflection (lux): emitters, punctual lights, sun, sky.
    pub direct: Vec3,
    /// Light that reaches x after one or more reflections (lux).
    pub indirect: Vec3,
    /// The part of `direct` from lights baked indirect only
    /// ([`crate::scene::LightBake::IndirectOnly`]), which their lightmaps leave out (lux).
    pub realtime: Vec3,
}

/// Direct irradiance at a surface point from lights, the sun and emitters (one sample of each
/// sun and of the emitters, `u` the random numbers); the sky is left to the caller. The
/// second value is the part from lights baked indirect only.
fn next_event(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    sp: &SurfacePoint,
    u: [f32; 3],
) -> (Vec3, Vec3) {
    let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
    let mut e = Vec3::ZERO;
    let mut realtime = Vec3::ZERO;
    for light in &ctx.scene.lights {
        if let Some(incident) = light.incident(sp, Vec2::new(u[0], u[1]), ctx.rays)
            && incident.visible(ctx.rays, origin)
        {
            e += incident.irradiance;
            if !light.direct_is_baked() {
                realtime += incident.irradiance;
            }
        }
    }
    if !emitters.is_empty() {
        let (i, prob) = emitters.pick(u[2]);
        let em = &emitters.list[i];
        let y = em.point(Vec2::new(u[0], u[1]));
        let to = y - origin;
        let d2 = to.length_squared();
        if d2 > 0.0 && prob > 0.0 {
            let d = d2.sqrt();
            let l = to / d;
            let cos_r = sp.normal.dot(l);
            let mut cos_e = -em.normal.dot(l);
            if em.two_sided {
                cos_e = cos_e.abs();
            }
            if cos_r > 0.0
                && cos_e > 0.0
                && sp.geometric_normal.dot(l) > 0.0
                && !ctx
                    .rays
                    .occluded(origin, l, 0.0, d - 2.0 * ctx.rays.epsilon(y))
            {
                // Solid-angle pdfs of the two strategies, for the power heuristic.
                let p_light = prob * d2 / (em.area * cos_e);
                let p_cos = cos_r * std::f32::consts::FRAC_1_PI;
                let w = p_light * p_light / (p_light * p_light + p_cos * p_cos);
                e += em.radiance * (cos_r / p_light) * w;
            }
        }
    }
    (e, realtime)
}

/// What the continuation ray contributes when it hits an emitter at distance `t` (the other
/// half of the MIS pair in [`next_event`]): π·L_e weighted by the power heuristic.
fn emitter_hit(emitters: &Emitters, triangle: u32, dir: Vec3, t: f32, cos_r: f32) -> Vec3 {
    let Some(k) = emitters.index_of(triangle) else {
        return Vec3::ZERO;
    };
    let em = &emitters.list[k];
    let mut cos_e = -em.normal.dot(dir);
    if em.two_sided {
        cos_e = cos_e.abs();
    }
    if cos_e <= 0.0 || cos_r <= 0.0 {
        return Vec3::ZERO;
    }
    let p_light = emitters.probability(k) * t * t / (em.area * cos_e);
    let p_cos = cos_r * std::f32::consts::FRAC_1_PI;
    let w = p_cos * p_cos / (p_light * p_light + p_cos * p_cos);
    em.radiance * std::f32::consts::PI * w
}

/// Path-traced irradiance at `sp` with `samples` paths (numbers keyed by `key`).
pub fn irradiance(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    sp: &SurfacePoint,
    samples: u32,
    key: u32,
) -> PathIrradiance {
    let mut out = PathIrradiance::default();
    let sky = ctx.scene.sky;
    for s in 0..samples {
        let rnd = |dim: u32| unit_float(hash_words(&[key, s, dim]));
        // Direct light at x itself: next-event estimation (the sky by the first ray below).
        let (e, realtime) = next_event(ctx, emitters, sp, [rnd(1), rnd(2), rnd(3)]);
        out.direct += e;
        out.realtime += realtime;
        let mut point = *sp;
        let mut beta = Vec3::ONE;
        let mut dir = cosine_hemisphere(point.normal, sobol_02(s, key));
        for depth in 0..64u32 {
            if dir.dot(point.geometric_normal) <= 0.0 {
                break;
            }
            let origin = ctx.rays.offset(point.position, point.geometric_normal);
            let Some(hit) = ctx.rays.closest_hit(origin, dir, 0.0, f32::INFINITY) else {
                // Escaped: the sky's radiance (×π for the cosine sampling).
                let light = beta * sky * std::f32::consts::PI;
                if depth == 0 {
                    out.direct += light;
                } else {
                    out.indirect += light;
                }
                break;
            };
            let info = ctx.rays.triangles[hit.triangle as usize];
            // Emission seen by the continuation ray (MIS with the emitter sampling).
            let seen =
                beta * emitter_hit(emitters, hit.triangle, dir, hit.t, point.normal.dot(dir));
            if depth == 0 {
                out.direct += seen;
            } else {
                out.indirect += seen;
            }
            if !hit.front_face && !info.double_sided {
                break; // the inside of a solid is black
            }
            let normal = if hit.front_face {
                info.normal
            } else {
                -info.normal
            };
            beta *= albedo_at(ctx.scene, ctx.rays, &hit);
            if beta.max_element() <= 0.0 {
                break;
            }
            let y = SurfacePoint {
                position: origin + dir * hit.t,
                normal,
                geometric_normal: normal,
                triangle: hit.triangle,
                bary: Vec2::new(hit.u, hit.v),
            };
            let base = 16 + 8 * depth;
            out.indirect +=
                beta * next_event(ctx, emitters, &y, [rnd(base), rnd(base + 1), rnd(base + 2)]).0;
            // Russian roulette after three bounces.
            if depth >= 2 {
                let survive = beta.max_element().min(0.95);
                if rnd(base + 3) >= survive {
                    break;
                }
                beta /= survive;
            }
            dir = cosine_hemisphere(normal, Vec2::new(rnd(base + 4), rnd(base + 5)));
            point = y;
        }
    }
    out.direct /= samples as f32;
    out.indirect /= samples as f32;
    out.realtime /= samples as f32;
    out
}
