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
//! Bias compensation adds, at every texel, the light the clamp removed from nearby surfaces:
//! cosine-distributed rays from x find y′, and E_comp = (1/K)·Σ B(y′)·(1 − b/G(x, y′))⁺, with
//! B(y′) the exitance there read through the radiosity basis
//! ([`crate::transport::HitMapper`]). Kollig & Keller evaluate B(y′) recursively, because the
//! clamp also removed light near y′. Here the near-field rays are traced once into a sparse
//! operator ([`NearField`]), and the compensation is solved as its fixed point,
//! E_comp = C·(ρ·(E_clamped + E_direct + E_comp) + emission); see
//! [`super::instant_radiosity`]. The one-bounce form (B read from the clamped result alone)
//! leaves most of the light missing inside sharp wedges, where nearly everything a texel sees
//! is within the clamp distance.
//!
//! Shadow rays are batched per tile of texels: each tile of 64 neighbouring texels (page
//! order) visits every VPL in turn, so consecutive rays leave nearby points towards the same
//! VPL. Before any ray is traced a VPL is culled when it lies behind the texel's surface, the
//! texel lies behind the VPL's surface, or the texel is outside a punctual light's range.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::walk::{Vpl, VplKind};
use crate::bake::BakeContext;
use crate::direct::{luminance, punctual, representative};
use crate::progress::Progress;
use crate::sampling::{cosine_hemisphere, sobol_02};
use crate::transport::HitMapper;

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
    let patches = &ctx.patches.patches;
    let rays_count = AtomicU64::new(0);
    let culled_count = AtomicU64::new(0);
    let far = ctx.rays.extent * 4.0 + 1.0;
    let tiles: Vec<(Vec<Vec3>, Vec<Vec3>, Vec<f32>)> = patches
        .par_chunks(TILE)
        .map(|tile| {
            // Each texel sums one term per VPL: f64, so 10⁷ terms lose nothing (an f32 sum of
            // 10⁷ equal terms is off by tens of percent; tests/stability.rs).
            let mut e = vec![DVec3::ZERO; tile.len()];
            let mut lost = vec![DVec3::ZERO; tile.len()];
            if progress.is_cancelled() {
                let zero = vec![Vec3::ZERO; tile.len()];
                return (zero.clone(), zero, vec![0.0; tile.len()]);
            }
            let points: Vec<_> = tile.iter().map(representative).collect();
            let origins: Vec<Vec3> = points
                .iter()
                .map(|sp| ctx.rays.offset(sp.position, sp.geometric_normal))
                .collect();
            let (mut traced, mut culled) = (0u64, 0u64);
            // Per-path luminance sums for the error estimate: the current path's contribution
            // and the sum of squared path contributions, per texel.
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
                    let sp = &points[k];
                    let added = match v.kind {
                        VplKind::Diffuse { normal } => {
                            let d = v.position - sp.position;
                            let r2 = d.length_squared();
                            if r2 <= 0.0 {
                                continue;
                            }
                            let r = r2.sqrt();
                            let l = d / r;
                            let cos_x = sp.normal.dot(l);
                            let cos_y = -normal.dot(l);
                            if cos_x <= 0.0 || cos_y <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
                                culled += 1;
                                continue;
                            }
                            traced += 1;
                            let tmax = r - ctx.rays.epsilon(v.position);
                            if ctx.rays.occluded(origins[k], l, 0.0, tmax) {
                                continue;
                            }
                            let g = cos_x * cos_y / r2;
                            let scale = std::f32::consts::FRAC_1_PI;
                            if g > bound {
                                lost[k] += (v.power * (scale * (g - bound))).as_dvec3();
                            }
                            v.power * (scale * g.min(bound))
                        }
                        VplKind::Punctual { light } => {
                            let light = &ctx.scene.lights[light as usize];
                            let Some((irr, l, d)) = punctual(light, sp) else {
                                culled += 1;
                                continue;
                            };
                            traced += 1;
                            let tmax = d - ctx.rays.epsilon(light.position);
                            if ctx.rays.occluded(origins[k], l, 0.0, tmax) {
                                continue;
                            }
                            irr
                        }
                        VplKind::Directional {
                            direction,
                            irradiance,
                        } => {
                            let l = -direction;
                            let cos = sp.normal.dot(l);
                            if cos <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
                                culled += 1;
                                continue;
                            }
                            traced += 1;
                            if ctx.rays.occluded(origins[k], l, 0.0, far) {
                                continue;
                            }
                            irradiance * cos
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
            let se: Vec<f32> = (0..tile.len())
                .map(|k| {
                    let sum_sq = path_sq[k] + path_sum[k] * path_sum[k];
                    (sum_sq - sampled[k] * sampled[k] / n).max(0.0).sqrt() as f32
                })
                .collect();
            rays_count.fetch_add(traced, Ordering::Relaxed);
            culled_count.fetch_add(culled, Ordering::Relaxed);
            progress.advance(tile.len() as u64);
            let to_f32 = |v: Vec<DVec3>| v.into_iter().map(|x| x.as_vec3()).collect::<Vec<_>>();
            (to_f32(e), to_f32(lost), se)
        })
        .collect();
    let mut out = Gathered {
        shadow_rays: rays_count.into_inner(),
        culled: culled_count.into_inner(),
        ..Gathered::default()
    };
    for (e, lost, se) in tiles {
        out.irradiance.extend(e);
        out.clamped.extend(lost);
        out.standard_error.extend(se);
    }
    out
}

/// The near field of every texel for Kollig–Keller compensation (see the module docs): per
/// patch, the nodes its compensation rays reached closer than where G exceeds the clamp
/// bound, with weights (1/K)·(1 − b/G)·w_j summed per node. [`NearField::apply`] turns node
/// exitance into the irradiance the clamp removed.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NearField {
    /// Per patch: its first entry (`row_ptr[i]..row_ptr[i + 1]`).
    row_ptr: Vec<u64>,
    entries: Vec<(u32, f32)>,
}

/// Patches whose near-field rows are traced before the memory check runs again.
const NEAR_BLOCK: usize = 16_384;

impl NearField {
    /// Patch `p`'s row: `rays` cosine rays, the hits where G > `bound`, merged per node.
    fn row(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        p: &crate::raster::Patch,
        bound: f32,
        rays: u32,
        traced: &AtomicU64,
    ) -> Vec<(u32, f32)> {
        let mut row: Vec<(u32, f32)> = Vec::new();
        if !p.is_valid() {
            return row;
        }
        let sp = representative(p);
        let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
        let key = p.rng(ctx.settings.seed, 0xc0a9);
        let mut w = [(0u32, 0f32); 4];
        // Only points closer than where G can exceed the bound matter: r² < 1/bound.
        let reach = (1.0 / bound).sqrt();
        let scale = 1.0 / rays.max(1) as f32;
        for k in 0..rays {
            let dir = cosine_hemisphere(sp.normal, sobol_02(k, key));
            if dir.dot(sp.geometric_normal) <= 0.0 {
                continue;
            }
            traced.fetch_add(1, Ordering::Relaxed);
            let Some(hit) = ctx.rays.closest_hit(origin, dir, 0.0, reach) else {
                continue;
            };
            let info = ctx.rays.triangles[hit.triangle as usize];
            let cos_x = sp.normal.dot(dir);
            let cos_y = (-info.normal.dot(dir)).abs();
            let g = cos_x * cos_y / (hit.t * hit.t);
            if g <= bound {
                continue;
            }
            let n = mapper.weights(&hit, &mut w);
            let f = (1.0 - bound / g) * scale;
            row.extend(w[..n].iter().map(|&(j, wj)| (j, wj * f)));
        }
        row.sort_unstable_by_key(|e| e.0);
        row.dedup_by(|b, a| {
            let same = a.0 == b.0;
            if same {
                a.1 += b.1;
            }
            same
        });
        row
    }

    /// Traces `rays` cosine rays per valid texel and keeps the hits where G > `bound`.
    /// Returns the operator and the rays traced, or `Err((projected bytes, rays traced))` as
    /// soon as the rows traced so far project past `max_bytes` (then nothing more is kept).
    pub fn trace(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        bound: f32,
        rays: u32,
        max_bytes: u64,
        progress: &Progress,
    ) -> Result<(Self, u64), (u64, u64)> {
        let traced = AtomicU64::new(0);
        let patches = &ctx.patches.patches;
        let mut near = NearField {
            row_ptr: Vec::with_capacity(patches.len() + 1),
            entries: Vec::new(),
        };
        near.row_ptr.push(0);
        for block in patches.chunks(NEAR_BLOCK) {
            let rows: Vec<Vec<(u32, f32)>> = block
                .par_iter()
                .map(|p| {
                    let row = Self::row(ctx, mapper, p, bound, rays, &traced);
                    progress.advance(1);
                    row
                })
                .collect();
            for row in rows {
                near.entries.extend(row);
                near.row_ptr.push(near.entries.len() as u64);
            }
            let done = near.row_ptr.len() - 1;
            let projected = (near.entries.len() as f64 / done as f64
                * patches.len() as f64
                * size_of::<(u32, f32)>() as f64) as u64;
            if projected > max_bytes {
                return Err((projected, traced.into_inner()));
            }
        }
        near.entries.shrink_to_fit();
        Ok((near, traced.into_inner()))
    }

    /// The one-bounce compensation without storing the operator (for near fields over the
    /// memory budget): each patch's row is traced and applied to `exitance` at once. Returns
    /// the irradiance per patch and the rays traced.
    pub fn trace_and_apply(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        bound: f32,
        rays: u32,
        exitance: &[Vec3],
        progress: &Progress,
    ) -> (Vec<Vec3>, u64) {
        let traced = AtomicU64::new(0);
        let out = ctx
            .patches
            .patches
            .par_iter()
            .map(|p| {
                let row = Self::row(ctx, mapper, p, bound, rays, &traced);
                progress.advance(1);
                row.iter()
                    .fold(Vec3::ZERO, |s, &(j, w)| s + exitance[j as usize] * w)
            })
            .collect();
        (out, traced.into_inner())
    }

    /// The irradiance the clamp removed at every patch, lux, for node exitance `exitance`.
    pub fn apply(&self, exitance: &[Vec3]) -> Vec<Vec3> {
        (0..self.row_ptr.len().saturating_sub(1))
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| {
                let (a, b) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
                self.entries[a..b]
                    .iter()
                    .fold(Vec3::ZERO, |s, &(j, w)| s + exitance[j as usize] * w)
            })
            .collect()
    }
}
