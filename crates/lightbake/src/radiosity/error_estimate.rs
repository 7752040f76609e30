//! The radiosity pass's estimate of its own error: independent re-gathers of sample nodes
//! compared with the solution.

use glam::Vec3;
use rayon::prelude::*;

use super::hit_mapper::HitMapper;
use super::monte_carlo;
use super::nodes::Nodes;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::settings::BakeSettings;

/// Nodes re-gathered by [`gather_error`] at most.
pub const ERROR_SAMPLE_NODES: usize = 2048;

/// The error of the reflected light, from [`ERROR_SAMPLE_NODES`] evenly spaced nodes (or
/// all, when fewer). Each gathers (F·B)ᵢ from the solved exitance twice, with `rays` rays
/// under two other seeds, so both gathers g₁, g₂ are independent of each other, of the
/// matrix rows' rays and of stochastic Jacobi's shooting; they are compared with the
/// solution's own hᵢ = (F·B)ᵢ. With ḡ their mean, E[(ḡ − h)²] = Var ḡ + E[(h − E ḡ)²] and
/// E[(g₁ − g₂)²] = 4·Var ḡ, so the mean of (ḡ − h)² − (g₁ − g₂)²/4 estimates the mean
/// squared error of h: the noise of the matrix row, or of the shooting, together with an
/// unconverged solve's remainder. No variance model is needed: the spread of one gather's
/// quasi-random rays would overstate their error (Sobol rays beat independent-sample
/// variance), and would not see stochastic Jacobi's shooting noise at all. What the gathers share is not seen: the noise other nodes' rows carried into
/// B, and the basis' own discretisation bias. Relative to the direct plus reflected light of
/// the same nodes. Its p95 is that of the per-node terms' square roots (negative terms count
/// as zero): each is a one-sample estimate, so their spread is wider than the nodes' errors.
/// Returns the estimate and the rays traced.
pub fn gather_error(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    indirect: &[Vec3],
    direct: &[Vec3],
    rays: u32,
) -> (ErrorEstimate, u64) {
    let n = nodes.len();
    if n == 0 {
        return (ErrorEstimate::default(), 0);
    }
    let mapper = HitMapper::new(*ctx, nodes, ctx.settings.radiosity.basis);
    let picked = picked_nodes(n);
    let gathers = regathers(ctx, &mapper, nodes, &picked, b, |_| rays, [1, 2]);
    let terms: Vec<f64> = picked
        .iter()
        .zip(&gathers)
        .map(|(&i, &(g1, g2))| noise_term(g1, g2, luminance(indirect[i]) as f64))
        .collect();
    let method = format!(
        "two independent re-gathers of {} nodes with {rays} rays each",
        picked.len()
    );
    let est = summarise(&terms, method).relative_to(value_rms(nodes, &picked, indirect, direct));
    (est, 2 * picked.len() as u64 * rays as u64)
}

/// The per-node fields of a hierarchical solve ([`super::hierarchical`]) that its error
/// estimate reads.
pub struct HierarchicalFields<'a> {
    /// b = ρ∘(H_d + C̃): the exitance the final gather read (C̃ the coarse level's reflected
    /// irradiance, prolonged to the nodes).
    pub exitance: &'a [Vec3],
    /// H₁: the final gather's result, lux.
    pub gathered: &'a [Vec3],
    /// ρ∘(H₁ − C̃): the exitance the correction read.
    pub missed: &'a [Vec3],
    /// Δ: the correction's result, lux (the baked reflected irradiance is H₁ + Δ).
    pub correction: &'a [Vec3],
    /// Each node's final-gather rays when they were shared out by noise
    /// ([`super::ray_allocation`]); `None`: the same rays at every node.
    pub gather_rays: Option<&'a [u32]>,
}

/// The hierarchical solve's error ([`super::hierarchical`]): the noise of its two gathers and
/// the coarse level's remaining bias.
///
/// * **Noise.** The final gather H₁ and the correction Δ are each re-gathered twice at the
///   sampled nodes from the exitance they read (as in [`gather_error`]), which gives each
///   one's squared noise without a variance model. The final gather's re-gathers take each
///   node's own rays (`gather_rays`): the estimator is unbiased with any, but its own spread
///   comes from the re-gathers, and a node given 16 × the pilot for its noise would otherwise
///   be re-gathered with a quarter of its rays.
/// * **Bias.** With H* the exact reflected irradiance (of the same Monte Carlo transport F)
///   and u = E[H₁] − C̃ what the coarse level misses, E[H₁] = H* − (I − Fρ)⁻¹·Fρ·u, and the
///   correction gathers E[Δ] = Fρ·u, so the bias left in H₁ + Δ is
///   Σ_{k≥1} (Fρ)ᵏ·E[Δ]: the coarse level's error enters only from the third bounce on. Its
///   first term δ = Fρ·Δ is gathered twice under independent seeds at the sampled nodes
///   (δ₁·δ₂ estimates δ² without the noise's own square), and the series is summed as
///   δ/(1 − r), r = ‖δ‖/‖Δ‖ the contraction measured on this field (Δ's noise taken out of
///   ‖Δ‖), at most the largest albedo.
///
/// Each node's squared error is the sum of the three. Returns the estimate, the bias part
/// (relative RMS) and the rays traced.
pub fn hierarchical_error(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    fields: &HierarchicalFields<'_>,
    direct: &[Vec3],
    rays: u32,
    correction_rays: u32,
) -> (ErrorEstimate, f64, u64) {
    let n = nodes.len();
    if n == 0 {
        return (ErrorEstimate::default(), 0.0, 0);
    }
    let picked = picked_nodes(n);
    let gather_rays = |i: usize| fields.gather_rays.map_or(rays, |r| r[i]);
    let gathers = regathers(
        ctx,
        mapper,
        nodes,
        &picked,
        fields.exitance,
        gather_rays,
        [1, 2],
    );
    let corrections = regathers(
        ctx,
        mapper,
        nodes,
        &picked,
        fields.missed,
        |_| correction_rays,
        [3, 4],
    );
    let reflected: Vec<Vec3> = (0..n)
        .map(|i| nodes.albedo[i] * fields.correction[i])
        .collect();
    let deltas = regathers(ctx, mapper, nodes, &picked, &reflected, |_| rays, [5, 6]);
    drop(reflected);
    let lum = |v: &[Vec3], i: usize| luminance(v[i]) as f64;
    let gather_noise: Vec<f64> = picked
        .iter()
        .zip(&gathers)
        .map(|(&i, &(g1, g2))| noise_term(g1, g2, lum(fields.gathered, i)))
        .collect();
    let correction_noise: Vec<f64> = picked
        .iter()
        .zip(&corrections)
        .map(|(&i, &(d1, d2))| noise_term(d1, d2, lum(fields.correction, i)))
        .collect();
    let delta_sq: Vec<f64> = deltas.iter().map(|&(d1, d2)| d1 * d2).collect();
    let field_sq: f64 = picked
        .iter()
        .zip(&correction_noise)
        .map(|(&i, &e)| lum(fields.correction, i).powi(2) - e.max(0.0))
        .sum();
    let r = if field_sq > 0.0 {
        (delta_sq.iter().sum::<f64>().max(0.0) / field_sq).sqrt()
    } else {
        0.0
    }
    .min(nodes.max_albedo() as f64);
    let amplification = 1.0 / (1.0 - r).max(1e-6);
    let bias: Vec<f64> = delta_sq
        .iter()
        .map(|&d| d * amplification * amplification)
        .collect();
    let terms: Vec<f64> = (0..picked.len())
        .map(|k| gather_noise[k] + correction_noise[k] + bias[k])
        .collect();
    let indirect: Vec<Vec3> = picked
        .iter()
        .map(|&i| fields.gathered[i] + fields.correction[i])
        .collect();
    let values = {
        let v: Vec<Vec3> = picked
            .iter()
            .zip(&indirect)
            .map(|(&i, &h)| direct[nodes.patch[i] as usize] + h)
            .collect();
        rms_luminance(&v)
    };
    let bias_rms = (bias.iter().sum::<f64>() / picked.len() as f64)
        .max(0.0)
        .sqrt();
    let own = if fields.gather_rays.is_some() {
        "each node's own rays".to_string()
    } else {
        format!("{rays} rays")
    };
    let method = format!(
        "two re-gathers of {} nodes for each of the final gather ({own}) and the correction ({correction_rays} rays), two gathers of the correction's reflection for the coarse level's bias (×{amplification:.2}: r = {r:.3})",
        picked.len()
    );
    let est = summarise(&terms, method).relative_to(values);
    let bias_relative = if values > 0.0 { bias_rms / values } else { 0.0 };
    let own_rays: u64 = picked.iter().map(|&i| gather_rays(i) as u64).sum();
    let traced = 2 * (own_rays + picked.len() as u64 * (rays as u64 + correction_rays as u64));
    (est, bias_relative, traced)
}

/// The nodes the estimates sample: [`ERROR_SAMPLE_NODES`] evenly spaced ones, or all.
fn picked_nodes(n: usize) -> Vec<usize> {
    let picked = n.min(ERROR_SAMPLE_NODES);
    (0..picked).map(|k| k * n / picked).collect()
}

/// Two gathers of luminance(`b`) at each of `picked`, with `rays(i)` rays at node i under two
/// seeds derived from the bake's seed and `keys` (independent of every other ray of the bake).
fn regathers(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    picked: &[usize],
    b: &[Vec3],
    rays: impl Fn(usize) -> u32 + Sync,
    keys: [u32; 2],
) -> Vec<(f64, f64)> {
    let reseeded = |k: u32| BakeSettings {
        seed: crate::sampling::hash_words(&[ctx.settings.seed, 0x57_0c4a, k]),
        ..ctx.settings.clone()
    };
    let (s1, s2) = (reseeded(keys[0]), reseeded(keys[1]));
    let (c1, c2) = (
        BakeContext {
            settings: &s1,
            ..*ctx
        },
        BakeContext {
            settings: &s2,
            ..*ctx
        },
    );
    picked
        .par_iter()
        .map(|&i| {
            (
                monte_carlo::gather_luminance(&c1, mapper, nodes, i, rays(i), b),
                monte_carlo::gather_luminance(&c2, mapper, nodes, i, rays(i), b),
            )
        })
        .collect()
}

/// (ḡ − h)² − (g₁ − g₂)²/4, lux²: an unbiased estimate of h's squared error (negative at
/// times).
fn noise_term(g1: f64, g2: f64, h: f64) -> f64 {
    let mean = 0.5 * (g1 + g2);
    (mean - h) * (mean - h) - 0.25 * (g1 - g2) * (g1 - g2)
}

/// RMS of the per-node squared-error terms, and the p95 of their square roots (negative
/// terms count as zero), absolute.
fn summarise(terms: &[f64], method: String) -> ErrorEstimate {
    let picked = terms.len();
    let mean_sq = terms.iter().sum::<f64>() / picked as f64;
    let mut roots: Vec<f64> = terms.iter().map(|v| v.max(0.0).sqrt()).collect();
    let k = ((picked as f64 * 0.95).ceil() as usize).clamp(1, picked) - 1;
    let (_, p95, _) = roots.select_nth_unstable_by(k, f64::total_cmp);
    ErrorEstimate {
        rms: mean_sq.max(0.0).sqrt(),
        p95_abs: *p95,
        texels: picked,
        method,
        ..ErrorEstimate::default()
    }
}

/// RMS luminance of direct plus reflected light at `picked`, lux.
fn value_rms(nodes: &Nodes, picked: &[usize], indirect: &[Vec3], direct: &[Vec3]) -> f64 {
    let values: Vec<Vec3> = picked
        .iter()
        .map(|&i| direct[nodes.patch[i] as usize] + indirect[i])
        .collect();
    rms_luminance(&values)
}
