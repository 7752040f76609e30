//! Krylov solvers for stiff scenes (albedo near 1), where Jacobi-type iterations need about
//! ln ε / ln ρ sweeps.
//!
//! * [`bicgstab`]: BiCGStab (van der Vorst 1992) on the unsymmetric system (I − ρF)·B = S.
//! * [`conjugate_gradient`]: conjugate gradients (Hestenes & Stiefel 1952) with a Jacobi
//!   preconditioner on the symmetrised system
//!   (diag(A/ρ) − diag(A)·F̃)·B = diag(A/ρ)·S, with F̃ the reciprocity-symmetrised F
//!   ([`super::transport::Transport::symmetrized`]); diag(A)·F̃ is symmetric and the matrix is
//!   diagonally dominant for ρ < 1, hence positive definite. Nodes (channels) with ρ = 0 are
//!   known (B = S) and moved to the right-hand side. It solves the symmetrised system, which
//!   differs from the Monte Carlo F by its sampling noise.
//!
//! The three colour channels are independent systems solved in lockstep, in double
//! precision: every "scalar" is a `DVec3` and products are component-wise.

use glam::DVec3;
use rayon::prelude::*;

use super::{Recorder, Solution, SolveOptions, System, norm, to_f32, to_f64};

fn dot(a: &[DVec3], b: &[DVec3]) -> DVec3 {
    a.iter().zip(b).fold(DVec3::ZERO, |s, (x, y)| s + *x * *y)
}

/// Component-wise a / b with 0 where b is 0.
fn div(a: DVec3, b: DVec3) -> DVec3 {
    DVec3::select(b.cmpeq(DVec3::ZERO), DVec3::ZERO, a / b)
}

/// y = (I − ρF)·x.
fn apply(system: &System<'_>, x: &[DVec3], y: &mut [DVec3]) {
    system.transport.mul64(x, y);
    y.par_iter_mut()
        .enumerate()
        .with_min_len(1024)
        .for_each(|(i, v)| *v = x[i] - system.rho(i) * *v);
}

/// BiCGStab on (I − ρF)·B = S from B₀ = S. Each iteration's history entry carries the error
/// bound ‖r‖∞/((1 − ρ_max)·‖x‖∞) of the recurrence's residual; the last entry is recomputed
/// from the true residual.
pub fn bicgstab(system: &System<'_>, options: &SolveOptions) -> Solution {
    let n = system.len();
    let mut rec = Recorder::new(system.progress);
    let s_norm = system.source_norm();
    let mut x = to_f64(system.source);
    let mut tmp = vec![DVec3::ZERO; n];
    apply(system, &x, &mut tmp);
    let mut r: Vec<DVec3> = (0..n).map(|i| system.s(i) - tmp[i]).collect();
    let r_hat = r.clone();
    let (mut rho_old, mut alpha, mut omega) = (DVec3::ONE, DVec3::ONE, DVec3::ONE);
    let mut v = vec![DVec3::ZERO; n];
    let mut p = vec![DVec3::ZERO; n];
    let mut s = vec![DVec3::ZERO; n];
    let mut t = vec![DVec3::ZERO; n];
    let mut iteration = 0u32;
    rec.record(
        0.0,
        norm(&r, system.area) / s_norm,
        system.error_bound(&x, &r),
    );
    let (converged, reason) = loop {
        if norm(&r, system.area) / s_norm < options.tolerance {
            break (true, "tolerance reached".to_string());
        }
        if iteration >= options.max_iterations {
            break (false, format!("stopped after {iteration} iterations"));
        }
        let rho_new = dot(&r_hat, &r);
        let beta = div(rho_new, rho_old) * div(alpha, omega);
        for i in 0..n {
            p[i] = r[i] + beta * (p[i] - omega * v[i]);
        }
        apply(system, &p, &mut v);
        alpha = div(rho_new, dot(&r_hat, &v));
        for i in 0..n {
            s[i] = r[i] - alpha * v[i];
        }
        iteration += 1;
        if norm(&s, system.area) / s_norm < options.tolerance {
            for i in 0..n {
                x[i] += alpha * p[i];
            }
            r.copy_from_slice(&s);
            rec.record(
                iteration as f64,
                norm(&r, system.area) / s_norm,
                system.error_bound(&x, &r),
            );
            continue;
        }
        apply(system, &s, &mut t);
        omega = div(dot(&t, &s), dot(&t, &t));
        for i in 0..n {
            x[i] += alpha * p[i] + omega * s[i];
            r[i] = s[i] - omega * t[i];
        }
        rho_old = rho_new;
        let res = norm(&r, system.area) / s_norm;
        rec.record(iteration as f64, res, system.error_bound(&x, &r));
        if !res.is_finite() {
            break (false, "breakdown (non-finite residual)".to_string());
        }
    };
    // Report the true residual and error bound of the result.
    let true_r = system.residual(&x);
    let true_residual = norm(&true_r, system.area) / s_norm;
    rec.record(
        iteration as f64,
        true_residual,
        system.error_bound(&x, &true_r),
    );
    Solution {
        solver: "krylov",
        b: to_f32(&x),
        indirect: Vec::new(),
        history: rec.history,
        converged: converged && true_residual < options.tolerance * 2.0,
        iterations: iteration as f64,
        rays: 0,
        stop_reason: format!(
            "BiCGStab {reason} after {iteration} iterations; true relative residual {true_residual:.2e}"
        ),
    }
}

/// Conjugate gradients on the reciprocity-symmetrised system (see the module docs). The
/// matrix used is `system.transport` symmetrised; the returned B solves that system.
pub fn conjugate_gradient(system: &System<'_>, options: &SolveOptions) -> Solution {
    let sym = system.transport.symmetrized(system.area);
    let sym_system = System {
        transport: &sym,
        ..*system
    };
    cg_on_symmetric(&sym_system, options)
}

/// CG on a system whose transport already satisfies reciprocity exactly.
pub fn cg_on_symmetric(system: &System<'_>, options: &SolveOptions) -> Solution {
    let n = system.len();
    let f = system.transport;
    let mut rec = Recorder::new(system.progress);
    // Per channel: known = ρ == 0 (B = S); inv_rho = 1/ρ elsewhere and 0 where known.
    let rho: Vec<DVec3> = (0..n).map(|i| system.rho(i)).collect();
    let known: Vec<DVec3> = rho
        .iter()
        .map(|r| DVec3::select(r.cmple(DVec3::ZERO), DVec3::ONE, DVec3::ZERO))
        .collect();
    let unknown: Vec<DVec3> = known.iter().map(|k| DVec3::ONE - *k).collect();
    let inv_rho: Vec<DVec3> = rho
        .iter()
        .map(|r| DVec3::select(r.cmple(DVec3::ZERO), DVec3::ZERO, DVec3::ONE / *r))
        .collect();
    let fixed: Vec<DVec3> = (0..n).map(|i| system.s(i) * known[i]).collect();
    let area: Vec<f64> = system.area.iter().map(|&a| a as f64).collect();
    // M·x on the unknown entries.
    let apply_m = |x: &[DVec3], y: &mut [DVec3]| {
        let masked: Vec<DVec3> = (0..n).map(|i| x[i] * unknown[i]).collect();
        f.mul64(&masked, y);
        y.par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(i, v)| {
                *v = unknown[i] * (area[i] * inv_rho[i] * masked[i] - area[i] * *v);
            });
    };
    // Right-hand side: diag(A/ρ)·S + A·F̃·(known part of S), on the unknown entries.
    let mut ff = vec![DVec3::ZERO; n];
    f.mul64(&fixed, &mut ff);
    let rhs: Vec<DVec3> = (0..n)
        .map(|i| unknown[i] * (area[i] * inv_rho[i] * system.s(i) + area[i] * ff[i]))
        .collect();
    // Jacobi preconditioner: the diagonal of M (1 on known entries).
    let diag: Vec<DVec3> = (0..n)
        .map(|i| {
            let (c, v) = f.row(i);
            let fii = c.binary_search(&(i as u32)).map_or(0.0, |k| v[k] as f64);
            DVec3::select(
                known[i].cmpeq(DVec3::ONE),
                DVec3::ONE,
                area[i] * inv_rho[i] - DVec3::splat(area[i] * fii),
            )
        })
        .collect();
    let precondition =
        |r: &[DVec3]| -> Vec<DVec3> { r.iter().zip(&diag).map(|(a, d)| *a / *d).collect() };
    let full =
        |x: &[DVec3]| -> Vec<DVec3> { (0..n).map(|i| x[i] * unknown[i] + fixed[i]).collect() };

    let mut x = to_f64(system.source);
    let mut ax = vec![DVec3::ZERO; n];
    apply_m(&x, &mut ax);
    let mut r: Vec<DVec3> = (0..n).map(|i| (rhs[i] - ax[i]) * unknown[i]).collect();
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = vec![DVec3::ZERO; n];
    let mut iteration = 0u32;
    rec.record(0.0, system.relative_residual(&full(&x)), None);
    let check_every = 4;
    let (converged, reason) = loop {
        if iteration >= options.max_iterations {
            break (false, format!("stopped after {iteration} iterations"));
        }
        apply_m(&p, &mut ap);
        let alpha = div(rz, dot(&p, &ap));
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        z = precondition(&r);
        let rz_new = dot(&r, &z);
        let beta = div(rz_new, rz);
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
        rz = rz_new;
        iteration += 1;
        if iteration.is_multiple_of(check_every) {
            let res = system.relative_residual(&full(&x));
            rec.record(iteration as f64, res, None);
            if res < options.tolerance {
                break (true, "tolerance reached".to_string());
            }
            if !res.is_finite() {
                break (false, "breakdown (non-finite residual)".to_string());
            }
        }
    };
    let b = full(&x);
    let true_r = system.residual(&b);
    let res = norm(&true_r, system.area) / system.source_norm();
    rec.record(iteration as f64, res, system.error_bound(&b, &true_r));
    Solution {
        solver: "krylov-cg",
        b: to_f32(&b),
        indirect: Vec::new(),
        history: rec.history,
        converged: converged || res < options.tolerance,
        iterations: iteration as f64,
        rays: 0,
        stop_reason: format!(
            "CG (symmetrised) {reason} after {iteration} iterations; relative residual {res:.2e}"
        ),
    }
}
