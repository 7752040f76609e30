//! Gathering VPLs into texel patches (Keller 1997, eq. 3 evaluated per texel instead of per
//! pixel), with the 1/r² singularity clamped and, optionally, the clamped energy restored by
//! bias compensation (Kollig & Keller 2004, "Illumination in the Presence of Weak
//! Singularities").
//!
//! A diffuse VPL of power Φ at y (normal n_y) gives the point x (normal n_x) the irradiance
//! E = Φ/π · G(x, y) · V(x, y), G = cosθ_x·cosθ_y / r². Near corners G grows without bound,
//! so it is clamped: G_c = min(G, b), **b = 1/d_c²** with d_c the clamp distance
//! (`vpl_clamp_distance`, by default 2% of the scene's diagonal) — a VPL closer than d_c
//! contributes as if it were d_c away and facing x. The energy this removes,
//! Φ/π·(G − b)⁺·V summed over texels (× texel area), is reported.
//!
//! Bias compensation restores the clamped energy ([`super::compensation`]).
//!
//! Shadow rays are batched per tile of texels: each tile of 64 neighbouring texels (page
//! order) visits every VPL in turn, so consecutive rays leave nearby points towards the same
//! VPL. Before any ray is traced a VPL is culled when it lies behind the texel's surface, the
//! texel lies behind the VPL's surface, or the texel is outside a punctual light's range.

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::walk::{Vpl, VplKind};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::lights::LightSource;
use crate::progress::Progress;
use crate::raster::{Patch, SurfacePoint};

/// Texels per gather tile.
const TILE: usize = 64;

/// What the gather produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gathered {
    /// Irradiance per patch, lux, linear RGB.
    pub irradiance: Vec<Vec3>,
    /// Irradiance the clamp removed per patch, lux.
    pub clamped: Vec<Vec3>,
    /// Standard error of each patch's irradiance over the particle paths, lux (luminance;
    /// the VPLs of one path are one sample, punctual lights gathered exactly count for none).
    pub standard_error: Vec<f32>,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// VPL–texel pairs culled before tracing.
    pub culled: u64,
}

/// Gathers `vpls` (made by `particles` particle paths) at every valid patch, with G clamped at
/// `bound`.
pub fn gather(
    ctx: &BakeContext<'_>,
    vpls: &[Vpl],
    particles: u32,
    bound: f32,
    progress: &Progress,
) -> Gathered {
    let tiles: Vec<Gathered> = ctx
        .patches
        .patches
        .par_chunks(TILE)
        .map(|tile| {
            let g = if progress.is_cancelled() {
                Gathered {
                    irradiance: vec![Vec3::ZERO; tile.len()],
                    clamped: vec![Vec3::ZERO; tile.len()],
                    standard_error: vec![0.0; tile.len()],
                    ..Gathered::default()
                }
            } else {
                gather_tile(ctx, vpls, particles, bound, tile)
            };
            progress.advance(tile.len() as u64);
            g
        })
        .collect();
    let mut out = Gathered::default();
    for t in tiles {
        out.irradiance.extend(t.irradiance);
        out.clamped.extend(t.clamped);
        out.standard_error.extend(t.standard_error);
        out.shadow_rays += t.shadow_rays;
        out.culled += t.culled;
    }
    out
}

/// What one VPL gives one texel.
enum Received {
    /// Nothing, known before tracing (behind either surface, out of range).
    Culled,
    /// Nothing: the VPL sits on the texel's point.
    Coincident,
    /// Nothing: the shadow ray was blocked.
    Hidden,
    /// Irradiance (lux), and what the clamp removed of it (when it did).
    Light(Vec3, Option<Vec3>),
}

/// What VPL `v` gives the texel point `sp` (shadow rays from `origin`), G clamped at `bound`.
fn receive(
    ctx: &BakeContext<'_>,
    v: &Vpl,
    sp: &SurfacePoint,
    origin: Vec3,
    bound: f32,
) -> Received {
    match v.kind {
        VplKind::Diffuse { normal } => {
            let d = v.position - sp.position;
            let r2 = d.length_squared();
            if r2 <= 0.0 {
                return Received::Coincident;
            }
            let r = r2.sqrt();
            let l = d / r;
            let cos_x = sp.normal.dot(l);
            let cos_y = -normal.dot(l);
            if cos_x <= 0.0 || cos_y <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
                return Received::Culled;
            }
            let tmax = r - ctx.rays.epsilon(v.position);
            if ctx.rays.occluded(origin, l, 0.0, tmax) {
                return Received::Hidden;
            }
            let g = cos_x * cos_y / r2;
            let scale = std::f32::consts::FRAC_1_PI;
            let lost = (g > bound).then(|| v.power * (scale * (g - bound)));
            Received::Light(v.power * (scale * g.min(bound)), lost)
        }
        VplKind::Punctual { light } => {
            let light = &ctx.scene.lights[light as usize];
            match light.incident(sp, Vec2::ZERO, ctx.rays) {
                None => Received::Culled,
                Some(incident) if incident.visible(ctx.rays, origin) => {
                    Received::Light(incident.irradiance, None)
                }
                Some(_) => Received::Hidden,
            }
        }
        VplKind::Directional {
            direction,
            irradiance,
        } => {
            let l = -direction;
            let cos = sp.normal.dot(l);
            if cos <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
                return Received::Culled;
            }
            if ctx
                .rays
                .occluded(origin, l, 0.0, ctx.rays.escape_distance())
            {
                return Received::Hidden;
            }
            Received::Light(irradiance * cos, None)
        }
    }
}

/// The gather of one tile of texels: every VPL in turn, against every texel of the tile.
fn gather_tile(
    ctx: &BakeContext<'_>,
    vpls: &[Vpl],
    particles: u32,
    bound: f32,
    tile: &[Patch],
) -> Gathered {
    // Each texel sums one term per VPL: f64, so 10⁷ terms lose nothing (an f32 sum of 10⁷
    // equal terms is off by tens of percent; tests/stability.rs).
    let mut e = vec![DVec3::ZERO; tile.len()];
    let mut lost = vec![DVec3::ZERO; tile.len()];
    let points: Vec<_> = tile.iter().map(|p| p.representative()).collect();
    let origins: Vec<Vec3> = points
        .iter()
        .map(|sp| ctx.rays.offset(sp.position, sp.geometric_normal))
        .collect();
    let (mut traced, mut culled) = (0u64, 0u64);
    // Per-path luminance sums for the error estimate: the current path's contribution and the
    // sum of squared path contributions, per texel.
    let mut path_sum = vec![0.0f64; tile.len()];
    let mut path_sq = vec![0.0f64; tile.len()];
    let mut sampled = vec![0.0f64; tile.len()];
    let mut current_path = Vpl::EXACT;
    for v in vpls {
        if v.path != current_path {
            for (c, q) in path_sum.iter_mut().zip(&mut path_sq) {
                *q += *c * *c;
                *c = 0.0;
            }
            current_path = v.path;
        }
        for (k, p) in tile.iter().enumerate() {
            if !p.is_valid() {
                continue;
            }
            let added = match receive(ctx, v, &points[k], origins[k], bound) {
                Received::Culled => {
                    culled += 1;
                    continue;
                }
                Received::Coincident => continue,
                Received::Hidden => {
                    traced += 1;
                    continue;
                }
                Received::Light(added, clamped) => {
                    traced += 1;
                    if let Some(c) = clamped {
                        lost[k] += c.as_dvec3();
                    }
                    added
                }
            };
            e[k] += added.as_dvec3();
            if v.path != Vpl::EXACT {
                let y = luminance(added) as f64;
                path_sum[k] += y;
                sampled[k] += y;
            }
        }
    }
    // Var(E) = Σ_p g_p² − (Σ_p g_p)²/N for E = Σ_p g_p over N i.i.d. paths.
    let n = particles.max(1) as f64;
    let standard_error = (0..tile.len())
        .map(|k| {
            let sum_sq = path_sq[k] + path_sum[k] * path_sum[k];
            (sum_sq - sampled[k] * sampled[k] / n).max(0.0).sqrt() as f32
        })
        .collect();
    let to_f32 = |v: Vec<DVec3>| v.into_iter().map(|x| x.as_vec3()).collect::<Vec<_>>();
    Gathered {
        irradiance: to_f32(e),
        clamped: to_f32(lost),
        standard_error,
        shadow_rays: traced,
        culled,
    }
}
