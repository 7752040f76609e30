//! Jacobi gathering: Bₖ₊₁ = S + ρ∘(F·Bₖ), from B₀ = S, until the relative residual is below
//! the tolerance. Each sweep is one sparse matrix–vector product, parallel over rows, in
//! double precision.
//!
//! The residual of Bₖ is rₖ = S + ρF·Bₖ − Bₖ = Bₖ₊₁ − Bₖ, so it comes free with the update;
//! the error bound of Bₖ₊₁ is ρ_max/(1 − ρ_max)·‖Bₖ₊₁ − Bₖ‖∞ (relative to ‖Bₖ₊₁‖∞).

use glam::DVec3;
use rayon::prelude::*;

use super::{Recorder, Solution, SolveOptions, System, max_norm, norm, to_f32, to_f64};

/// Solves `system` by Jacobi iteration.
pub fn solve(system: &System<'_>, options: &SolveOptions) -> Solution {
    let n = system.len();
    let mut rec = Recorder::new(system.progress);
    let rho_max = system.max_albedo() as f64;
    let s_norm = system.source_norm();
    let mut b = to_f64(system.source);
    let mut fb = vec![DVec3::ZERO; n];
    let mut next = vec![DVec3::ZERO; n];
    let mut iteration = 0u32;
    let (converged, reason) = loop {
        system.transport.mul64(&b, &mut fb);
        next.par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(i, x)| *x = system.s(i) + system.rho(i) * fb[i]);
        let delta: Vec<DVec3> = next.iter().zip(&b).map(|(a, c)| *a - *c).collect();
        // This residual is b's; the bound is next's.
        let residual = norm(&delta, system.area) / s_norm;
        let bound = (rho_max < 1.0)
            .then(|| rho_max / (1.0 - rho_max) * max_norm(&delta) / max_norm(&next).max(1e-300));
        rec.record(iteration as f64, residual, bound);
        std::mem::swap(&mut b, &mut next);
        iteration += 1;
        if residual < options.tolerance {
            break (
                true,
                format!(
                    "relative residual {residual:.2e} < {:.1e} after {iteration} sweeps",
                    options.tolerance
                ),
            );
        }
        if iteration >= options.max_iterations {
            break (
                false,
                format!("stopped after {iteration} sweeps at relative residual {residual:.2e}"),
            );
        }
    };
    Solution {
        solver: "jacobi",
        b: to_f32(&b),
        indirect: Vec::new(),
        history: rec.history,
        converged,
        iterations: iteration as f64,
        rays: 0,
        stop_reason: reason,
    }
}
