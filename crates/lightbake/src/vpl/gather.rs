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
//! [`gather`] is Keller's gather of every VPL at every texel; [`gather_cut`] takes one VPL
//! per node of a lightcut per texel ([`super::cut`]), 32 texels close in space and facing
//! about the same way sharing one cut.
//!
//! Shadow rays are batched per tile of texels: each tile of 64 neighbouring texels (page
//! order) visits every VPL in turn, so consecutive rays leave nearby points towards the same
//! VPL. Before any ray is traced a VPL is culled when it lies behind the texel's surface, the
//! texel lies behind the VPL's surface, or the texel is outside a punctual light's range.

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::cut::{Receivers, VplTree};
use super::walk::{Vpl, VplKind};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::lights::LightSource;
use crate::progress::Progress;
use crate::raster::{Patch, SurfacePoint};
use crate::sampling::{hash_words, unit_float};

/// Texels per gather tile.
const TILE: usize = 64;

/// Texels that share one cut ([`gather_cut`]): neighbours in space facing about the same way.
const CUT_TILE: usize = 32;

/// Salt of the cut gather's picks.
const CUT_SALT: u32 = 0x0c07_11e5;

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

impl Gathered {
    /// No light at `n` patches.
    fn dark(n: usize) -> Self {
        Self {
            irradiance: vec![Vec3::ZERO; n],
            clamped: vec![Vec3::ZERO; n],
            standard_error: vec![0.0; n],
            ..Self::default()
        }
    }
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
                Gathered::dark(tile.len())
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

/// Gathers `vpls` (made by `particles` particle paths) at every valid patch through cuts of
/// at most `size` nodes of a [`VplTree`] ([`super::cut`]), G clamped at `bound`; the picks
/// are indexed by (patch, node, `seed`). Punctual lights are evaluated exactly at every
/// texel. The standard error per patch adds the picks' noise (one pick per node: adjacent
/// nodes of the cut taken pairwise, the collapsed-strata estimate, which overstates rather
/// than understates) and the particle paths' (Σ of each picked VPL's light squared over its
/// probability: the paths taken as independent, each VPL as its own path).
pub fn gather_cut(
    ctx: &BakeContext<'_>,
    vpls: &[Vpl],
    particles: u32,
    bound: f32,
    size: usize,
    seed: u32,
    progress: &Progress,
) -> Gathered {
    let tree = VplTree::build(vpls);
    let exact: Vec<&Vpl> = vpls
        .iter()
        .filter(|v| matches!(v.kind, VplKind::Punctual { .. }))
        .collect();
    let patches = &ctx.patches.patches;
    let order = tile_order(patches);
    let tiles: Vec<Gathered> = order
        .par_chunks(CUT_TILE)
        .map(|tile| {
            let g = if progress.is_cancelled() {
                Gathered::dark(tile.len())
            } else {
                let cut = CutGather {
                    ctx,
                    tree: &tree,
                    exact: &exact,
                    particles,
                    bound,
                    size,
                    seed,
                };
                cut.tile(tile)
            };
            progress.advance(tile.len() as u64);
            g
        })
        .collect();
    let mut out = Gathered::dark(patches.len());
    for (t, chunk) in tiles.into_iter().zip(order.chunks(CUT_TILE)) {
        for (k, &i) in chunk.iter().enumerate() {
            out.irradiance[i as usize] = t.irradiance[k];
            out.clamped[i as usize] = t.clamped[k];
            out.standard_error[i as usize] = t.standard_error[k];
        }
        out.shadow_rays += t.shadow_rays;
        out.culled += t.culled;
    }
    out
}

/// The valid patches in the order tiles take them: by the axis their normal faces most, then
/// along a Morton curve through the scene's box.
fn tile_order(patches: &[Patch]) -> Vec<u32> {
    let valid: Vec<u32> = (0..patches.len() as u32)
        .filter(|&i| patches[i as usize].is_valid())
        .collect();
    let (lo, hi) = valid.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &i| {
            let p = patches[i as usize].representative().position;
            (lo.min(p), hi.max(p))
        },
    );
    let scale = (hi - lo).max_element().max(1e-20);
    let spread = |x: u32| -> u64 {
        let mut v = x as u64 & 0x1f_ffff;
        v = (v | v << 32) & 0x1f_0000_0000_ffff;
        v = (v | v << 16) & 0x1f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        (v | v << 2) & 0x1249_2492_4924_9249
    };
    let key = |i: u32| -> (u8, u64, u32) {
        let sp = patches[i as usize].representative();
        let n = sp.normal;
        let a = n.abs().max_position();
        let face = (2 * a + usize::from(n[a] < 0.0)) as u8;
        let q =
            ((sp.position - lo) / scale * 2_097_151.0).clamp(Vec3::ZERO, Vec3::splat(2_097_151.0));
        let m = spread(q.x as u32) | spread(q.y as u32) << 1 | spread(q.z as u32) << 2;
        (face, m, i)
    };
    let mut keyed: Vec<(u8, u64, u32)> = valid.into_iter().map(key).collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|k| k.2).collect()
}

/// What the cut gather of one tile reads.
struct CutGather<'a> {
    ctx: &'a BakeContext<'a>,
    tree: &'a VplTree,
    exact: &'a [&'a Vpl],
    particles: u32,
    bound: f32,
    size: usize,
    seed: u32,
}

impl CutGather<'_> {
    /// The patches `tile` (indices, all valid) through one cut: node by node, each node's
    /// picks for every texel of the tile in turn (one run of the VPLs in memory, shadow rays
    /// from nearby points to nearby VPLs).
    fn tile(&self, tile: &[u32]) -> Gathered {
        let ctx = self.ctx;
        let points: Vec<SurfacePoint> = tile
            .iter()
            .map(|&i| ctx.patches.patches[i as usize].representative())
            .collect();
        let origins: Vec<Vec3> = points
            .iter()
            .map(|sp| ctx.rays.offset(sp.position, sp.geometric_normal))
            .collect();
        let receivers = Receivers::around(points.iter().map(|sp| (sp.position, sp.normal)));
        let cut = self.tree.cut(&receivers, self.size, self.bound);
        let n = tile.len();
        let mut out = Gathered::default();
        let mut e = vec![DVec3::ZERO; n];
        let mut lost = vec![DVec3::ZERO; n];
        // Per texel: the picks' light (luminance) for the noise of the picks, paired node by
        // node, and the paths' (Σ f²/p) with the picks' sum.
        let mut strata = vec![0.0f64; n];
        let mut pending: Vec<Option<f64>> = vec![None; n];
        let mut paths = vec![0.0f64; n];
        let mut sampled = vec![0.0f64; n];
        let mut record = |r: &Received| match r {
            Received::Culled => out.culled += 1,
            Received::Hidden | Received::Light(..) => out.shadow_rays += 1,
            Received::Coincident => {}
        };
        for v in self.exact {
            for k in 0..n {
                let r = receive(ctx, v, &points[k], origins[k], self.bound);
                record(&r);
                if let Received::Light(a, _) = r {
                    e[k] += a.as_dvec3();
                }
            }
        }
        let mut picked: Vec<(Vpl, f32)> = Vec::with_capacity(n);
        for &at in &cut {
            let leaf = self.tree.is_leaf(at);
            // Every texel's pick first, then their VPLs copied out: the loads are independent,
            // so their cache misses overlap instead of each waiting behind a traced ray.
            picked.clear();
            picked.extend(tile.iter().map(|&i| {
                let u = unit_float(hash_words(&[i, at, self.seed, CUT_SALT])) as f64;
                let (vi, w) = self.tree.pick(at, u);
                (*self.tree.leaf(vi), w)
            }));
            for (k, (v, w)) in picked.iter().enumerate() {
                let w = *w;
                let r = receive(ctx, v, &points[k], origins[k], self.bound);
                record(&r);
                let y = match r {
                    Received::Light(a, clamped) => {
                        e[k] += (a * w).as_dvec3();
                        if let Some(c) = clamped {
                            lost[k] += (c * w).as_dvec3();
                        }
                        let y = luminance(a) as f64;
                        paths[k] += y * y * w as f64;
                        y * w as f64
                    }
                    _ => 0.0,
                };
                sampled[k] += y;
                if !leaf {
                    // Collapsed strata: adjacent nodes of the cut taken as one stratum of two
                    // picks, (y_a − y_b)² for the variance of their sum.
                    pending[k] = match pending[k] {
                        None => Some(y),
                        Some(x) => {
                            strata[k] += (x - y) * (x - y);
                            None
                        }
                    };
                }
            }
        }
        let particles = self.particles.max(1) as f64;
        out.standard_error = (0..n)
            .map(|k| {
                let odd = pending[k].map_or(0.0, |x| x * x);
                let path_var = (paths[k] - sampled[k] * sampled[k] / particles).max(0.0);
                (strata[k] + odd + path_var).sqrt() as f32
            })
            .collect();
        out.irradiance = e.into_iter().map(|x| x.as_vec3()).collect();
        out.clamped = lost.into_iter().map(|x| x.as_vec3()).collect();
        out
    }
}
