//! Solvers of the radiosity system (I − diag(ρ)·F)·B = S over the texel nodes, RGB.
//!
//! In lightbake's split formulation (see [`crate::radiosity`]) S = ρ·H_direct, so B is the
//! exitance of *reflected* light and H = H_direct + F·B the total irradiance a texel stores
//! (over π). Every solver records a history ([`HistoryEntry`]) of (time, iteration, relative residual
//! ‖S + ρFB − B‖ / ‖S‖, error bound) with ‖·‖ the area-weighted RMS over nodes and channels.
//!
//! | solver | module | source |
//! |---|---|---|
//! | Jacobi | [`jacobi`] | gathering, B ← S + ρFB |
//! | Gauss–Seidel | [`gauss_seidel`] | gathering in place |
//! | progressive refinement (Southwell) | [`shooting`] | Cohen, Chen, Wallace & Greenberg 1988 |
//! | stochastic Jacobi (matrix-free) | [`crate::radiosity::stochastic_jacobi`] (it traces rays) | Bekaert; Dutré et al. ch. 6.3 |
//! | BiCGStab, conjugate gradients | [`krylov`] | van der Vorst 1992; Hestenes & Stiefel 1952 |
//! | dense LU | [`lu`] | partial pivoting; the reference |
//!
//! For the contracting iterations (Jacobi, Gauss–Seidel) the a-posteriori bound
//! ‖B − Bₖ‖∞ ≤ ρ_max/(1 − ρ_max)·‖Bₖ − Bₖ₋₁‖∞ is recorded (F's rows sum to at most 1).

pub mod gauss_seidel;
pub mod jacobi;
pub mod krylov;
pub mod lu;
pub mod shooting;
pub mod transport;

use std::time::Instant;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};

use crate::progress::Progress;
use crate::settings::SolverChoice;
pub use transport::Transport;

impl SolverChoice {
    /// Bytes a matrix solver allocates beside a transport matrix of `matrix_bytes` for `n`
    /// nodes: its double-precision RGB vectors (24 bytes per node each, counted from the
    /// solvers' code, with the final residual and F·B products), plus the copies of the
    /// matrix that shooting (the transpose) and CG (transpose, symmetrised rows and the packed
    /// result) build. 0 for `Auto`, for stochastic Jacobi, which builds no matrix (its
    /// per-node vectors are small, and it merges its ray deposits in bounded blocks), and for
    /// the hierarchical solve, which `radiosity::plan_solver` plans.
    pub fn working_bytes(self, n: usize, matrix_bytes: u64) -> u64 {
        let vector = n as u64 * size_of::<DVec3>() as u64;
        match self {
            Self::Auto | Self::StochasticJacobi => 0,
            // The hierarchical solve builds no full matrix; its working memory depends on the
            // page grid too (`radiosity::hierarchical::planned_bytes`).
            Self::Hierarchical => 0,
            Self::Jacobi => 5 * vector,
            Self::GaussSeidel => 4 * vector,
            Self::Shooting => matrix_bytes + 4 * vector,
            Self::Krylov => 10 * vector,
            Self::KrylovCg => 3 * matrix_bytes + 16 * vector,
            Self::Direct => 8 * n as u64 * n as u64 + 4 * vector,
        }
    }
}

/// The linear system (I − diag(ρ)·F)·B = S.
#[derive(Clone, Copy)]
pub struct System<'a> {
    /// F.
    pub transport: &'a Transport,
    /// ρ per node.
    pub albedo: &'a [Vec3],
    /// S per node.
    pub source: &'a [Vec3],
    /// Node areas (weights of the norms).
    pub area: &'a [f32],
    /// Where to publish the error estimate after every sweep (see
    /// [`crate::progress::ProgressSnapshot::error_estimate`]), if anywhere.
    pub progress: Option<&'a Progress>,
}

/// Stopping rules.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SolveOptions {
    /// Stop when the relative residual ‖S + ρFB − B‖/‖S‖ falls below this. Default 10⁻³.
    /// (The bake derives it from its error target: target × (1 − ρ_max).)
    pub tolerance: f64,
    /// Give up after this many iterations (sweeps; for shooting, shots / nodes). Default 20 000.
    pub max_iterations: u32,
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-3,
            max_iterations: 20_000,
        }
    }
}

/// One point of a solver's history.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct HistoryEntry {
    /// Seconds since the solve started.
    pub seconds: f64,
    /// Iterations so far (sweeps; equivalent sweeps for shooting).
    pub iteration: f64,
    /// ‖S + ρFB − B‖ / ‖S‖ (for stochastic Jacobi: ‖ΔB‖ / ‖B‖, the unshot fraction).
    pub residual: f64,
    /// A bound on ‖B − Bₖ‖∞ / ‖Bₖ‖∞, when the method has one.
    pub error_bound: Option<f64>,
}

/// A solver's result.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Solution {
    /// Solver used.
    pub solver: &'static str,
    /// Reflected exitance B per node.
    #[serde(skip)]
    pub b: Vec<Vec3>,
    /// Irradiance from reflected light per node, F·B (filled by `finish` for matrix
    /// solvers; accumulated directly by stochastic Jacobi).
    #[serde(skip)]
    pub indirect: Vec<Vec3>,
    /// History, in order.
    pub history: Vec<HistoryEntry>,
    /// The tolerance was reached.
    pub converged: bool,
    /// Iterations done.
    pub iterations: f64,
    /// Rays traced by the solver itself (stochastic Jacobi).
    pub rays: u64,
    /// Why it stopped, in words.
    pub stop_reason: String,
}

/// Area-weighted RMS over nodes and channels.
pub fn norm(x: &[DVec3], area: &[f32]) -> f64 {
    let (mut s, mut a) = (0.0f64, 0.0f64);
    for (v, &w) in x.iter().zip(area) {
        s += w as f64 * v.length_squared();
        a += w as f64;
    }
    if a > 0.0 { (s / a).sqrt() } else { 0.0 }
}

/// Largest component over all nodes.
pub fn max_norm(x: &[DVec3]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs().max_element()))
}

/// Widens to double precision.
pub fn to_f64(x: &[Vec3]) -> Vec<DVec3> {
    x.iter().map(|v| v.as_dvec3()).collect()
}

/// Narrows to single precision.
pub fn to_f32(x: &[DVec3]) -> Vec<Vec3> {
    x.iter().map(|v| v.as_vec3()).collect()
}

impl System<'_> {
    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.source.len()
    }

    #[cfg(any(test, feature = "internals"))]
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.source.is_empty()
    }

    /// Largest albedo component.
    pub fn max_albedo(&self) -> f32 {
        self.albedo
            .iter()
            .fold(0.0f32, |m, a| m.max(a.max_element()))
    }

    /// ρ of node i in double precision.
    #[inline]
    pub fn rho(&self, i: usize) -> DVec3 {
        self.albedo[i].as_dvec3()
    }

    /// S of node i in double precision.
    #[inline]
    pub fn s(&self, i: usize) -> DVec3 {
        self.source[i].as_dvec3()
    }

    /// r = S + ρ∘(F·b) − b, in double precision.
    pub fn residual(&self, b: &[DVec3]) -> Vec<DVec3> {
        let mut fb = vec![DVec3::ZERO; b.len()];
        self.transport.mul64(b, &mut fb);
        (0..b.len())
            .map(|i| self.s(i) + self.rho(i) * fb[i] - b[i])
            .collect()
    }

    /// ‖S‖ (area-weighted RMS), at least 10⁻³⁰⁰.
    pub fn source_norm(&self) -> f64 {
        let s: Vec<DVec3> = to_f64(self.source);
        norm(&s, self.area).max(1e-300)
    }

    /// ‖r‖ / ‖S‖.
    pub fn relative_residual(&self, b: &[DVec3]) -> f64 {
        norm(&self.residual(b), self.area) / self.source_norm()
    }

    /// Progressive radiosity's ambient term for the energy not yet distributed (Cohen, Chen,
    /// Wallace & Greenberg 1988, §4): with the residual r = S + ρ∘(F·b) − b as the unshot
    /// exitance, A = R·Σ rⱼ·Aⱼ / Σ Aⱼ with R = 1/(1 − ρ̄) (ρ̄ the area-weighted mean albedo,
    /// per channel), the irradiance every surface would still receive, spread evenly. Zero
    /// for a solved system; negative components (an overshoot) are kept.
    pub fn ambient_term(&self, b: &[DVec3]) -> Vec3 {
        let r = self.residual(b);
        let (mut unshot, mut albedo, mut area) = (DVec3::ZERO, DVec3::ZERO, 0.0f64);
        for i in 0..r.len() {
            let a = self.area[i] as f64;
            unshot += r[i] * a;
            albedo += self.rho(i) * a;
            area += a;
        }
        if area <= 0.0 {
            return Vec3::ZERO;
        }
        let mean_albedo = (albedo / area).min(DVec3::splat(0.999));
        (unshot / area / (DVec3::ONE - mean_albedo)).as_vec3()
    }

    /// The bound ‖B − b‖∞ / ‖b‖∞ ≤ ‖r‖∞ / ((1 − ρ_max)·‖b‖∞), from
    /// ‖(I − ρF)⁻¹‖∞ ≤ 1/(1 − ρ_max) (F's rows sum to at most 1).
    pub fn error_bound(&self, b: &[DVec3], r: &[DVec3]) -> Option<f64> {
        let rho = self.max_albedo() as f64;
        (rho < 1.0).then(|| max_norm(r) / ((1.0 - rho) * max_norm(b).max(1e-300)))
    }
}

/// Records history entries against a start time, and publishes each one's error estimate.
pub struct Recorder<'a> {
    start: Instant,
    progress: Option<&'a Progress>,
    /// The entries.
    pub history: Vec<HistoryEntry>,
}

impl<'a> Recorder<'a> {
    /// Starts the clock. Each entry's error bound (or, without one, its residual) is published
    /// to `progress`.
    pub fn new(progress: Option<&'a Progress>) -> Self {
        Self {
            start: Instant::now(),
            progress,
            history: Vec::new(),
        }
    }

    /// Adds an entry.
    pub fn record(&mut self, iteration: f64, residual: f64, error_bound: Option<f64>) {
        if let Some(p) = self.progress {
            p.set_error_estimate(error_bound.unwrap_or(residual));
        }
        self.history.push(HistoryEntry {
            seconds: self.start.elapsed().as_secs_f64(),
            iteration,
            residual,
            error_bound,
        });
    }
}

/// Fills `indirect` = F·B for a matrix solver's solution.
pub fn finish(system: &System<'_>, mut solution: Solution) -> Solution {
    let b = to_f64(&solution.b);
    let mut fb = vec![DVec3::ZERO; b.len()];
    system.transport.mul64(&b, &mut fb);
    solution.indirect = to_f32(&fb);
    solution
}

/// Runs a matrix solver (everything but stochastic Jacobi and `Auto`).
///
/// # Panics
/// For [`SolverChoice::Auto`], [`SolverChoice::StochasticJacobi`] and
/// [`SolverChoice::Hierarchical`] (resolve `Auto` with [`choose`]; the other two trace rays,
/// see [`crate::radiosity`]).
pub fn solve_matrix(choice: SolverChoice, system: &System<'_>, options: &SolveOptions) -> Solution {
    let s = match choice {
        SolverChoice::Jacobi => jacobi::solve(system, options),
        SolverChoice::GaussSeidel => gauss_seidel::solve(system, options),
        SolverChoice::Shooting => shooting::solve(system, options),
        SolverChoice::Krylov => krylov::bicgstab(system, options),
        SolverChoice::KrylovCg => krylov::conjugate_gradient(system, options),
        SolverChoice::Direct => lu::solve(system),
        SolverChoice::Auto | SolverChoice::StochasticJacobi | SolverChoice::Hierarchical => {
            panic!("solve_matrix called with {}", choice.name())
        }
    };
    finish(system, s)
}

/// Largest system the dense LU solver accepts (its n² memory and n³ time).
pub const DIRECT_MAX_NODES: usize = 4096;
/// Below this many nodes `Auto` picks the dense LU solve.
pub const AUTO_DIRECT_NODES: usize = 1500;
/// Up to this many nodes `Auto` builds the full matrix (at most about 100 MiB at 128 rays
/// per node); beyond, the hierarchical solve.
pub const AUTO_MATRIX_NODES: usize = 32_768;
/// Bytes of coarse matrix the hierarchical solve may hold per node: its refinement stops at
/// this cap (the shipped and corpus scenes reach their tolerance at 2–22).
pub const COARSE_BYTES_PER_NODE: u64 = 32;

/// Resolves `Auto`: (choice, reason). `fits` says whether the matrix and a solver's working
/// memory ([`SolverChoice::working_bytes`]) fit the transport budget together.
pub fn choose(
    nodes: usize,
    max_albedo: f32,
    fits: impl Fn(SolverChoice) -> bool,
) -> (SolverChoice, String) {
    if nodes <= AUTO_DIRECT_NODES && fits(SolverChoice::Direct) {
        return (
            SolverChoice::Direct,
            format!("{nodes} nodes: a dense LU solve is exact and quick"),
        );
    }
    // BiCGStab: each iteration is two sparse products, which run on every thread. Gauss–
    // Seidel needs fewer sweeps than Jacobi, but its sweep is sequential: on two threads it
    // was the slowest of the three (docs/benchmarks.md, "Choosing the default solver"). It
    // needs the fewest vectors, though, so it stands in when BiCGStab's do not fit.
    if fits(SolverChoice::Krylov) {
        let why = if max_albedo > 0.9 {
            format!(
                "max albedo {max_albedo:.3} makes Jacobi-type iterations slow (ln ε / ln ρ sweeps): BiCGStab"
            )
        } else {
            format!(
                "{nodes} nodes, max albedo {max_albedo:.3}: BiCGStab needs the fewest passes over the matrix, all of them parallel"
            )
        };
        return (SolverChoice::Krylov, why);
    }
    if fits(SolverChoice::GaussSeidel) {
        return (
            SolverChoice::GaussSeidel,
            format!(
                "{nodes} nodes: BiCGStab's vectors do not fit beside the matrix in the transport budget; Gauss-Seidel needs the fewest"
            ),
        );
    }
    (
        SolverChoice::Hierarchical,
        format!(
            "{nodes} nodes: the full transport matrix is over its memory budget; the hierarchical solve's memory is linear in the nodes"
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_picks_lu_when_small_bicgstab_when_large_and_no_matrix_when_over_budget() {
        let all = |_: SolverChoice| true;
        assert_eq!(choose(AUTO_DIRECT_NODES, 0.5, all).0, SolverChoice::Direct);
        for albedo in [0.3, 0.8, 0.95, 0.999] {
            let (choice, why) = choose(AUTO_DIRECT_NODES + 1, albedo, all);
            assert_eq!(choice, SolverChoice::Krylov, "{albedo}: {why}");
        }
        // A budget that holds the matrix and a few vectors but not BiCGStab's ten.
        let n = 100_000;
        let matrix = 50 << 20;
        let budget = matrix + SolverChoice::GaussSeidel.working_bytes(n, matrix);
        let fits = |c: SolverChoice| matrix + c.working_bytes(n, matrix) <= budget;
        assert_eq!(choose(n, 0.5, fits).0, SolverChoice::GaussSeidel);
        assert_eq!(
            choose(10, 0.5, |_| false).0,
            SolverChoice::Hierarchical,
            "a matrix over budget is never built, however small the system"
        );
    }
}
