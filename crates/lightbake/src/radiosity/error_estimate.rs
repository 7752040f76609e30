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
    let mapper = HitMapper::new(*ctx, nodes, ctx.settings.basis);
    let reseeded = |k: u32| BakeSettings {
        seed: crate::sampling::hash_words(&[ctx.settings.seed, 0x57_0c4a, k]),
        ..ctx.settings.clone()
    };
    let (s1, s2) = (reseeded(1), reseeded(2));
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
    let picked = n.min(ERROR_SAMPLE_NODES);
    // Per node: (ḡ − h)² − (g₁ − g₂)²/4, lux² (an unbiased term, negative at times).
    let mut per_node: Vec<f64> = (0..picked)
        .into_par_iter()
        .map(|k| {
            let i = k * n / picked;
            let g1 = monte_carlo::gather_luminance(&c1, &mapper, nodes, i, rays, b);
            let g2 = monte_carlo::gather_luminance(&c2, &mapper, nodes, i, rays, b);
            let h = luminance(indirect[i]) as f64;
            let mean = 0.5 * (g1 + g2);
            (mean - h) * (mean - h) - 0.25 * (g1 - g2) * (g1 - g2)
        })
        .collect();
    let mean_sq = per_node.iter().sum::<f64>() / picked as f64;
    for v in &mut per_node {
        *v = v.max(0.0).sqrt();
    }
    let k = ((picked as f64 * 0.95).ceil() as usize).clamp(1, picked) - 1;
    let (_, p95, _) = per_node.select_nth_unstable_by(k, f64::total_cmp);
    let values: Vec<Vec3> = (0..picked)
        .map(|k| {
            let i = k * n / picked;
            direct[nodes.patch[i] as usize] + indirect[i]
        })
        .collect();
    let est = ErrorEstimate {
        rms: mean_sq.max(0.0).sqrt(),
        p95_abs: *p95,
        texels: picked,
        method: format!("two independent re-gathers of {picked} nodes with {rays} rays each"),
        ..ErrorEstimate::default()
    }
    .relative_to(rms_luminance(&values));
    (est, 2 * picked as u64 * rays as u64)
}

