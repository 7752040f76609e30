//! Bias compensation of the VPL clamp (Kollig & Keller 2004, "Illumination in the Presence
//! of Weak Singularities"): at every texel, the light the clamp removed from nearby surfaces.
//!
//! Cosine-distributed rays from x find y′, and E_comp = (1/K)·Σ B(y′)·(1 − b/G(x, y′))⁺, with
//! B(y′) the exitance there read through the radiosity basis
//! ([`crate::radiosity::HitMapper`]). Kollig & Keller evaluate B(y′) recursively, because the
//! clamp also removed light near y′. Here the near-field rays are traced once into a sparse
//! operator ([`NearField`]), and the compensation is solved as its fixed point,
//! E_comp = C·(ρ·(E_clamped + E_direct + E_comp) + emission). The one-bounce form (B read from
//! the clamped result alone) leaves most of the light missing inside sharp wedges, where
//! nearly everything a texel sees is within the clamp distance; it is used only when the
//! operator does not fit in half the memory budget.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::radiosity::{HitMapper, Nodes};
use crate::raster::Patch;
use crate::sampling::{cosine_hemisphere, sobol_02};
use crate::settings::Basis;

/// Most fixed-point iterations of the bias compensation.
const MAX_ITERATIONS: u32 = 100;

/// The compensation stops when an iteration changes it by less than this share (luminance,
/// summed over texels).
const TOLERANCE: f64 = 1e-4;

/// What the compensation adds.
pub struct Compensation {
    /// Irradiance the clamp removed, per patch, lux.
    pub irradiance: Vec<Vec3>,
    /// Fixed-point iterations (1 for the one-bounce form).
    pub iterations: u32,
    /// Why it was cut short, when it was (a warning for the report).
    pub note: Option<String>,
    /// Rays traced.
    pub rays: u64,
}

/// The compensation of the clamped VPL gather `irradiance` (per patch, lux) with G clamped at
/// `bound`. `direct`: the exact direct light (method `hybrid`); `first_generation`: method
/// `vpl`, whose emitters' own near field was clamped too.
pub fn compensate(
    ctx: &BakeContext<'_>,
    irradiance: &[Vec3],
    direct: Option<&[Vec3]>,
    first_generation: bool,
    bound: f32,
    progress: &Progress,
) -> Compensation {
    let s = ctx.settings;
    let mut rays = 0u64;
    let mut iterations = 0u32;
    let mut note = None;
    // Exitance at the nodes: reflection of what has been gathered (plus direct light in
    // hybrid), and emission (its near field was clamped too in method vpl).
    let nodes = Nodes::new(ctx, Basis::Linear);
    // Per node: what it emits and what it reflects of the light gathered so far.
    let base: Vec<(Vec3, Vec3, usize)> = nodes
        .patch
        .iter()
        .zip(&nodes.albedo)
        .map(|(&pi, rho)| {
            let p = &ctx.patches.patches[pi as usize];
            let emitted = if first_generation {
                let mesh = ctx.scene.instances[p.instance as usize].mesh;
                ctx.scene.material_of(mesh).emissive * std::f32::consts::PI
            } else {
                Vec3::ZERO
            };
            let i = pi as usize;
            let gathered = irradiance[i] + direct.map_or(Vec3::ZERO, |d| d[i]);
            (*rho * gathered + emitted, *rho, i)
        })
        .collect();
    let mapper = HitMapper::new(*ctx, &nodes, Basis::Linear);
    let exitance_with = |extra: &[Vec3]| -> Vec<Vec3> {
        base.iter()
            .map(|&(b0, rho, i)| b0 + rho * extra[i])
            .collect()
    };
    let mut extra = vec![Vec3::ZERO; irradiance.len()];
    // The near-field operator may take half the memory budget.
    let max_bytes = s.memory_budget_mib.saturating_mul(1 << 20) / 2;
    match NearField::trace(
        ctx,
        &mapper,
        bound,
        s.vpl.compensation_rays,
        max_bytes,
        progress,
    ) {
        Ok((near, traced)) => {
            rays += traced;
            // The fixed point E_comp = C·(B₀ + ρ·E_comp): the near field's exitance lacks
            // what the clamp removed near it too. C's rows sum to at most 1, so this
            // contracts by ρ̄ or faster.
            let norm = |v: &[Vec3]| v.iter().map(|e| luminance(*e) as f64).sum::<f64>();
            for _ in 0..MAX_ITERATIONS {
                let next = near.apply(&exitance_with(&extra));
                let change: f64 = next
                    .iter()
                    .zip(&extra)
                    .map(|(a, b)| luminance((*a - *b).abs()) as f64)
                    .sum();
                extra = next;
                iterations += 1;
                if change <= TOLERANCE * norm(&extra) {
                    break;
                }
            }
        }
        Err((projected, partial)) => {
            rays += partial;
            let (one_bounce, traced) = NearField::trace_and_apply(
                ctx,
                &mapper,
                bound,
                s.vpl.compensation_rays,
                &exitance_with(&extra),
                progress,
            );
            rays += traced;
            extra = one_bounce;
            iterations = 1;
            note = Some(format!(
                "the bias compensation's near field would take {} MiB, over half the memory budget ({} MiB): it was compensated one bounce deep, which leaves light missing in sharp creases",
                projected >> 20,
                s.memory_budget_mib
            ));
        }
    }
    Compensation {
        irradiance: extra,
        iterations,
        note,
        rays,
    }
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
        p: &Patch,
        bound: f32,
        rays: u32,
        traced: &AtomicU64,
    ) -> Vec<(u32, f32)> {
        let mut row: Vec<(u32, f32)> = Vec::new();
        if !p.is_valid() {
            return row;
        }
        let sp = p.representative();
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
