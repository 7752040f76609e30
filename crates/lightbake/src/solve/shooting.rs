//! Progressive refinement radiosity (Cohen, Chen, Wallace & Greenberg 1988, "A Progressive
//! Refinement Approach to Fast Radiosity Image Generation"), i.e. Southwell relaxation:
//!
//! 1. the unshot radiosity ΔB starts as S and B as 0;
//! 2. the node j with the largest unshot power |ΔB_j|·A_j (luminance) shoots: B_j += ΔB_j,
//!    and every node i that sees it receives ΔBᵢ += ρᵢ·F_ij·ΔB_j (column j of F);
//! 3. repeat until ‖ΔB‖ / ‖S‖ is below the tolerance (ΔB *is* the residual S + ρFB − B).
//!
//! An indexed max-heap of the unshot powers finds the next shooter. For intermediate display the
//! *ambient term* (Cohen et al. 1988, §5) estimates the light not yet shot:
//! ambient = Σ_j ΔB_j·A_j / Σ A_j · 1/(1 − ρ̄), ρ̄ the area-weighted mean albedo, and a
//! partial solution is shown as Bᵢ + ρᵢ·ambient ([`display`]).

use glam::DVec3;

use super::transport::Transport;
use super::{Recorder, Solution, SolveOptions, System, norm, to_f32, to_f64};
use crate::color::luminance;

/// A max-heap of node powers with one entry per node and O(log n) key updates (an indexed
/// binary heap), so a shot's updates do not pile up stale entries.
struct PowerHeap {
    heap: Vec<u32>,
    position: Vec<u32>,
    power: Vec<f32>,
}

impl PowerHeap {
    fn new(power: Vec<f32>) -> Self {
        let n = power.len();
        let mut h = Self {
            heap: (0..n as u32).collect(),
            position: (0..n as u32).collect(),
            power,
        };
        for i in (0..n / 2).rev() {
            h.sift_down(i);
        }
        h
    }

    /// Higher power first; ties to the lower node index (deterministic).
    fn above(&self, a: u32, b: u32) -> bool {
        let (pa, pb) = (self.power[a as usize], self.power[b as usize]);
        pa > pb || (pa == pb && a < b)
    }

    fn swap(&mut self, i: usize, j: usize) {
        self.heap.swap(i, j);
        self.position[self.heap[i] as usize] = i as u32;
        self.position[self.heap[j] as usize] = j as u32;
    }

    fn sift_up(&mut self, mut i: usize) {
        while i > 0 {
            let parent = (i - 1) / 2;
            if !self.above(self.heap[i], self.heap[parent]) {
                break;
            }
            self.swap(i, parent);
            i = parent;
        }
    }

    fn sift_down(&mut self, mut i: usize) {
        let n = self.heap.len();
        loop {
            let (l, r) = (2 * i + 1, 2 * i + 2);
            let mut best = i;
            if l < n && self.above(self.heap[l], self.heap[best]) {
                best = l;
            }
            if r < n && self.above(self.heap[r], self.heap[best]) {
                best = r;
            }
            if best == i {
                break;
            }
            self.swap(i, best);
            i = best;
        }
    }

    fn top(&self) -> Option<(u32, f32)> {
        self.heap.first().map(|&j| (j, self.power[j as usize]))
    }

    fn set(&mut self, node: usize, power: f32) {
        let old = self.power[node];
        self.power[node] = power;
        let i = self.position[node] as usize;
        if power > old {
            self.sift_up(i);
        } else {
            self.sift_down(i);
        }
    }
}

#[cfg(any(test, feature = "internals"))]
/// The ambient term of a partial solution with unshot radiosity `unshot`.
pub fn ambient(system: &System<'_>, unshot: &[DVec3]) -> DVec3 {
    let (mut power, mut area, mut rho_area) = (DVec3::ZERO, 0.0f64, DVec3::ZERO);
    for i in 0..unshot.len() {
        let a = system.area[i] as f64;
        power += unshot[i] * a;
        area += a;
        rho_area += system.rho(i) * a;
    }
    if area <= 0.0 {
        return DVec3::ZERO;
    }
    let rho_mean = rho_area / area;
    power / area / (DVec3::ONE - rho_mean).max(DVec3::splat(1e-9))
}

#[cfg(any(test, feature = "internals"))]
/// What to show for a partial solution: Bᵢ + ρᵢ·ambient.
pub fn display(system: &System<'_>, b: &[DVec3], unshot: &[DVec3]) -> Vec<glam::Vec3> {
    let amb = ambient(system, unshot);
    b.iter()
        .enumerate()
        .map(|(i, bi)| (*bi + system.rho(i) * amb).as_vec3())
        .collect()
}

/// A partially or fully shot state.
pub struct ShootingState {
    /// Radiosity shot so far.
    pub b: Vec<DVec3>,
    /// Unshot radiosity (the residual).
    #[cfg_attr(not(any(test, feature = "internals")), allow(dead_code))]
    pub unshot: Vec<DVec3>,
    /// Shots done.
    pub shots: u64,
}

/// Shoots until the tolerance, `max_iterations` equivalent sweeps, or `max_shots` (whichever
/// comes first), recording history every n/8 shots.
pub fn shoot(
    system: &System<'_>,
    options: &SolveOptions,
    max_shots: u64,
    rec: &mut Recorder,
) -> (ShootingState, bool) {
    shoot_columns(
        system,
        &system.transport.transpose(),
        options,
        max_shots,
        rec,
    )
}

/// [`shoot`] with the transport's columns already transposed (`columns.row(j)` lists the
/// nodes that receive from node j).
pub fn shoot_columns(
    system: &System<'_>,
    columns: &Transport,
    options: &SolveOptions,
    max_shots: u64,
    rec: &mut Recorder,
) -> (ShootingState, bool) {
    let n = system.len();
    let s_norm = system.source_norm();
    let mut b = vec![DVec3::ZERO; n];
    let mut unshot = to_f64(system.source);
    let power = |i: usize, u: &[DVec3]| luminance(u[i].abs().as_vec3()) * system.area[i];
    let mut heap = PowerHeap::new((0..n).map(|i| power(i, &unshot)).collect());
    let record_every = (n as u64 / 8).max(1);
    let mut shots = 0u64;
    rec.record(0.0, norm(&unshot, system.area) / s_norm, None);
    let limit = (options.max_iterations as u64 * n as u64).min(max_shots);
    let mut converged = false;
    while let Some((top, current)) = heap.top() {
        let j = top as usize;
        if current <= 0.0 {
            // The largest unshot power is zero: everything is shot.
            converged = true;
            break;
        }
        let dj = unshot[j];
        b[j] += dj;
        unshot[j] = DVec3::ZERO;
        heap.set(j, 0.0);
        let (rows, weights) = columns.row(j);
        for (&i, &f) in rows.iter().zip(weights) {
            let i = i as usize;
            unshot[i] += system.rho(i) * (f as f64) * dj;
            heap.set(i, power(i, &unshot));
        }
        shots += 1;
        if shots.is_multiple_of(record_every) {
            let residual = norm(&unshot, system.area) / s_norm;
            rec.record(shots as f64 / n as f64, residual, None);
            if residual < options.tolerance {
                converged = true;
                break;
            }
        }
        if shots >= limit {
            break;
        }
    }
    let residual = norm(&unshot, system.area) / s_norm;
    if rec
        .history
        .last()
        .is_none_or(|h| h.iteration != shots as f64 / n as f64)
    {
        rec.record(shots as f64 / n.max(1) as f64, residual, None);
    }
    converged |= residual < options.tolerance;
    (ShootingState { b, unshot, shots }, converged)
}

/// Solves `system` by progressive refinement.
pub fn solve(system: &System<'_>, options: &SolveOptions) -> Solution {
    let mut rec = Recorder::new(system.progress);
    let (state, converged) = shoot(system, options, u64::MAX, &mut rec);
    let n = system.len().max(1) as f64;
    let residual = rec.history.last().map_or(0.0, |h| h.residual);
    Solution {
        solver: "shooting",
        b: to_f32(&state.b),
        indirect: Vec::new(),
        history: rec.history,
        converged,
        iterations: state.shots as f64 / n,
        rays: 0,
        stop_reason: if converged {
            format!(
                "unshot fraction {residual:.2e} < {:.1e} after {} shots",
                options.tolerance, state.shots
            )
        } else {
            format!(
                "stopped after {} shots at unshot fraction {residual:.2e}",
                state.shots
            )
        },
    }
}
