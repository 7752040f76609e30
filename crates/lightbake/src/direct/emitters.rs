//! The emissive-triangle term of the direct pass, per footprint sample.
//!
//! * With at most `max_closed_form_emitters` triangles (`RatioEstimate`): the unoccluded
//!   irradiance of every triangle in closed form, and shadow rays for the visible fraction
//!   only — a ratio estimator that picks the triangle in proportion to its closed-form share
//!   and a point on it, E ≈ E_unoccluded · Σ wᵢVᵢ / Σ wᵢ with wᵢ = f(yᵢ)/p(yᵢ). Exact wherever
//!   the emitter is fully visible or fully hidden.
//! * With more (`sampled`): a triangle picked by power and the plain estimator f·V/p.

use glam::Vec3;

use super::{Ctx, stream};
use crate::color::luminance;
use crate::lights::emissive::emitter_direction;
use crate::raster::{Patch, SurfacePoint};
use crate::sampling::{hash, sobol_02, unit_float};

/// The pick of footprint sample `s` of patch `p` among the emitter triangles, in [0, 1).
fn pick(ctx: &Ctx<'_>, p: &Patch, s: u32) -> f32 {
    unit_float(hash(
        p.rng(ctx.settings.seed, stream::EMITTER_PICK) ^ s.wrapping_mul(0x2c1b_3c6d),
    ))
}

/// The sums of the closed-form ratio estimator over a texel's footprint samples.
#[derive(Default)]
pub(super) struct RatioEstimate {
    /// Σ unoccluded closed-form irradiance, lux.
    pub(super) unoccluded: Vec3,
    /// Σ w over the samples whose shadow ray was clear.
    pub(super) w_visible: f32,
    /// Σ w over all samples.
    pub(super) w_total: f32,
    /// Running sums of each triangle's luminance share (reused between samples).
    contributions: Vec<f32>,
}

impl RatioEstimate {
    /// Adds footprint sample `s` at `sp` (shadow rays from `origin`); rays traced are added to
    /// `rays`.
    pub(super) fn add(
        &mut self,
        ctx: &Ctx<'_>,
        p: &Patch,
        s: u32,
        sp: &SurfacePoint,
        origin: Vec3,
        rays: &mut u64,
    ) {
        self.contributions.clear();
        let mut total = Vec3::ZERO;
        let mut lum_total = 0.0f32;
        for em in &ctx.emitters.list {
            let e = em.unoccluded_irradiance(sp);
            total += e;
            let l = luminance(e).max(0.0);
            lum_total += l;
            self.contributions.push(lum_total);
        }
        self.unoccluded += total;
        if lum_total <= 0.0 {
            return;
        }
        // Pick a triangle by its share of the unoccluded irradiance, then a point on it.
        let contributions = &self.contributions;
        let pick = pick(ctx, p, s) * lum_total;
        let i = contributions
            .partition_point(|&c| c <= pick)
            .min(contributions.len() - 1);
        let prev = if i == 0 { 0.0 } else { contributions[i - 1] };
        let prob = (contributions[i] - prev) / lum_total;
        if prob <= 0.0 {
            return;
        }
        let em = &ctx.emitters.list[i];
        let u = sobol_02(s, p.rng(ctx.settings.seed, stream::EMITTER));
        let Some((l, d, measure)) = emitter_direction(em, origin, u) else {
            return;
        };
        let cos_r = sp.normal.dot(l);
        if cos_r <= 0.0 {
            return;
        }
        let w = luminance(em.radiance) * cos_r * measure / prob;
        self.w_total += w;
        *rays += 1;
        let tmax = d - 2.0 * ctx.rays.epsilon(origin + l * d);
        if !ctx.rays.occluded(origin, l, 0.0, tmax) {
            self.w_visible += w;
        }
    }

    /// The visible fraction R = Σ w·V / Σ w (0 when no weight was drawn).
    pub(super) fn visible_fraction(&self) -> f64 {
        if self.w_total > 0.0 {
            (self.w_visible / self.w_total) as f64
        } else {
            0.0
        }
    }
}

/// One footprint sample of the plain Monte Carlo emitter estimator (many emitters): the
/// irradiance it adds, lux.
pub(super) fn sampled(
    ctx: &Ctx<'_>,
    p: &Patch,
    s: u32,
    sp: &SurfacePoint,
    origin: Vec3,
    rays: &mut u64,
) -> Vec3 {
    let u = sobol_02(s, p.rng(ctx.settings.seed, stream::EMITTER));
    match ctx
        .emitters
        .incident(sp, origin, pick(ctx, p, s), u, ctx.rays)
    {
        Some(incident) => {
            *rays += 1;
            if incident.visible(ctx.rays, origin) {
                incident.irradiance
            } else {
                Vec3::ZERO
            }
        }
        None => Vec3::ZERO,
    }
}
