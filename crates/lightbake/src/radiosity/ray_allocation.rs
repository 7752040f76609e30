//! The final gather's rays where its noise is: a pilot gather at every node, then each node's
//! rays by the noise measured around it.
//!
//! With n_i rays, node i's gathered light has noise σ_i/√n_i, σ_i the spread of one ray's
//! luminance there. A viewer sees that noise against the light at the node, and the scene's
//! error is summed over its area, so the rays are shared out to minimise
//!
//! Σ a_i·σ_i² / (n_i·(L_i + L̄)²)  under  Σ n_i = N·R,
//!
//! a_i the node's basis area, L_i its light (direct and gathered, luminance), L̄ the
//! area-weighted mean of L (so a node darker than the mean counts by its absolute error, as
//! the RMS of `--verify` and the error estimate do, and a bright one by its relative error),
//! N the nodes and R the rays per node of the settings. A Lagrange multiplier gives
//! n_i ∝ w_i = √a_i·σ_i/(L_i + L̄): Neyman's optimal allocation for stratified sampling
//! (J. Neyman, "On the two different aspects of the representative method", J. Royal
//! Statistical Society 97(4), 1934, §5), each node a stratum. Against even rays it weighs
//! (Σw_i)² / (N·Σw_i²) of their weighted variance ([`Allocation::predicted`]). Weighed by
//! the absolute error alone, the rays left dim corners (under a quarter of them at contacts
//! of the preview preset's contact room) and more of those points read 25% too bright.
//!
//! 1. **Pilot**: rays `0..P` of every node's sequence, P = R/4 ([`pilot_rays`]). Its block
//!    error ([`super::monte_carlo::gather`]) gives σ_i² = se_i²·P, from three degrees of
//!    freedom: too noisy to allocate by (a node that drew four alike blocks would keep its
//!    pilot's rays). The variance and the light are pooled over the node's cell of the coarse
//!    level ([`super::clusters::Clusters`]: up to 16 × 16 texels of one chart, smaller where
//!    the light varies), whose nodes see nearly the same surroundings.
//! 2. **Allocation** ([`allocate`]): n_i = P·2^m, m ∈ [`MIN_DOUBLINGS`]..=[`MAX_DOUBLINGS`]
//!    the power of two nearest λ·w_i/P (powers of two keep every node's rays a whole
//!    (0, 2)-net of its Sobol' sequence), λ the largest with Σ n_i ≤ N·R, found by bisection.
//!    Every node keeps at least half the settings' rays, a node whose cell shows no noise
//!    too: the pilot's few rays can all miss a small bright source that lights a dim corner
//!    (with a quarter of the rays at the preview preset, a wall lit only that way on
//!    `q3dm6ish` read a tenth of the path tracer's light), and then its cell shows no noise
//!    to weigh.
//! 3. **The rest**: rays `P..n_i` ([`Allocation::rest`]), combined with the pilot by ray count
//!    ([`combine`]).
//!
//! The allocation reads the pilot of every node, so a split bake's shards all make the same
//! one from the merged pilot, and the bits do not depend on the shard or thread count.

use std::ops::Range;

use glam::Vec3;

use super::nodes::Nodes;

/// Fewest rays per node at which the gather is made in two passes: below it the pilot would
/// be too few rays to measure a node's noise, and every node gets the same rays.
pub const MIN_ADAPTIVE_RAYS: u32 = 16;

/// Fewest doublings of the pilot's rays at one node: every node has at least 2 × the pilot,
/// half the settings' rays (see the module docs).
pub const MIN_DOUBLINGS: u32 = 1;

/// Most doublings of the pilot's rays at one node: at most 2^4 = 16 × the pilot, 4 × the
/// settings' rays per node.
pub const MAX_DOUBLINGS: u32 = 4;

/// Rays per node of the pilot gather for `rays` rays per node: a quarter (at least 4), or
/// `None` below [`MIN_ADAPTIVE_RAYS`] (one pass of `rays` everywhere).
pub fn pilot_rays(rays: u32) -> Option<u32> {
    (rays >= MIN_ADAPTIVE_RAYS).then_some(rays / 4)
}

/// Every node's rays.
#[derive(Clone, Debug, PartialEq)]
pub struct Allocation {
    /// The pilot's rays per node (rays `0..pilot` of every node's sequence).
    pub pilot: u32,
    /// The settings' rays per node: the mean the allocation keeps to (or below).
    pub target: u32,
    /// Each node's rays in all (pilot included).
    pub rays: Vec<u32>,
    /// Nodes at 1, 2, 4, … 2^[`MAX_DOUBLINGS`] × the pilot's rays.
    pub levels: [u64; MAX_DOUBLINGS as usize + 1],
    /// The gather's variance (area-weighted, by the pooled pilot noise) with these rays over
    /// its variance with the settings' rays at every node: below 1 when the noise is uneven.
    pub predicted: f64,
}

impl Allocation {
    /// The rays of node `i` after its pilot (empty when the pilot was all of them).
    pub fn rest(&self, i: usize) -> Range<u32> {
        self.pilot..self.rays[i]
    }

    /// Rays of every node together, pilot included.
    pub fn total(&self) -> u64 {
        self.rays.iter().map(|&r| r as u64).sum()
    }

    /// The fewest and the most rays of any node (0, 0 without nodes).
    pub fn extremes(&self) -> (u32, u32) {
        let min = self.rays.iter().min().copied().unwrap_or(0);
        (min, self.rays.iter().max().copied().unwrap_or(0))
    }

    /// Mean rays per node.
    pub fn mean(&self) -> f64 {
        self.total() as f64 / self.rays.len().max(1) as f64
    }

    /// The stage note: the pilot, the range and the share of nodes at each level.
    pub fn note(&self) -> String {
        let n = self.rays.len().max(1) as f64;
        let shares: Vec<String> = self
            .levels
            .iter()
            .map(|&c| format!("{:.0}%", 100.0 * c as f64 / n))
            .collect();
        let (min, max) = self.extremes();
        format!(
            "{min} to {max} rays/node, mean {:.1} (of {}), by the noise of a pilot of {}; nodes at 1/2/4/8/16× the pilot: {}; variance {:.2}× even rays'",
            self.mean(),
            self.target,
            self.pilot,
            shares.join("/"),
            self.predicted
        )
    }
}

/// Rays per node from each node's light (`light`: direct and the pilot's gathered irradiance,
/// luminance, lux) and the pilot gather's standard error (`pilot_error`, luminance, lux, from
/// `pilot` rays), both pooled over the cells `cell_of` gives each node, keeping the mean at or
/// below `rays` (see the module docs).
pub fn allocate(
    nodes: &Nodes,
    cell_of: &[u32],
    light: &[f32],
    pilot_error: &[f32],
    pilot: u32,
    rays: u32,
) -> Allocation {
    let n = nodes.len();
    let cells = cell_of.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
    // Per cell: Σσ², ΣL and the nodes.
    let mut pooled = vec![(0.0f64, 0.0f64, 0u32); cells];
    let (mut lit, mut area) = (0.0f64, 0.0f64);
    for i in 0..n {
        let e = pilot_error[i] as f64;
        let c = &mut pooled[cell_of[i] as usize];
        c.0 += e * e * pilot as f64;
        c.1 += light[i] as f64;
        c.2 += 1;
        lit += nodes.area[i] as f64 * light[i] as f64;
        area += nodes.area[i] as f64;
    }
    let mean_light = if area > 0.0 { lit / area } else { 0.0 };
    // w_i per node (zero for nodes without noise: they get the fewest rays).
    let weight: Vec<f64> = (0..n)
        .map(|i| {
            let (var, sum, count) = pooled[cell_of[i] as usize];
            let (var, light) = (var / count as f64, sum / count as f64);
            let w = (nodes.area[i] as f64).max(0.0).sqrt() * var.sqrt() / (light + mean_light);
            if w.is_finite() { w } else { 0.0 }
        })
        .collect();
    let log_weight: Vec<f64> = weight
        .iter()
        .map(|&w| {
            if w > 0.0 {
                (w / pilot as f64).log2()
            } else {
                f64::NAN
            }
        })
        .collect();
    let level = |lw: f64, shift: f64| -> u32 {
        if lw.is_nan() {
            MIN_DOUBLINGS
        } else {
            (lw + shift)
                .round()
                .clamp(MIN_DOUBLINGS as f64, MAX_DOUBLINGS as f64) as u32
        }
    };
    let count = |shift: f64| -> u64 {
        log_weight
            .iter()
            .map(|&lw| (pilot as u64) << level(lw, shift))
            .sum()
    };
    let budget = n as u64 * rays as u64;
    // The shift log₂ λ: at `lo` every node has the fewest rays, at `hi` every node with noise
    // has the most rays; the count grows with the shift.
    let finite = log_weight.iter().copied().filter(|lw| !lw.is_nan());
    let (min_lw, max_lw) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), lw| {
        (a.min(lw), b.max(lw))
    });
    let shift = if !min_lw.is_finite() {
        0.0
    } else {
        let (mut lo, mut hi) = (-max_lw - 1.0, MAX_DOUBLINGS as f64 - min_lw + 1.0);
        if count(hi) <= budget {
            hi
        } else {
            for _ in 0..48 {
                let mid = 0.5 * (lo + hi);
                if count(mid) <= budget {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        }
    };
    let mut levels = [0u64; MAX_DOUBLINGS as usize + 1];
    let per_node: Vec<u32> = log_weight
        .iter()
        .map(|&lw| {
            let m = level(lw, shift);
            levels[m as usize] += 1;
            pilot << m
        })
        .collect();
    // Σ w²/n_i against Σ w²/R: the variance of these rays over that of even ones.
    let (mut even, mut chosen) = (0.0f64, 0.0f64);
    for (w, &r) in weight.iter().zip(&per_node) {
        even += w * w / rays as f64;
        chosen += w * w / r as f64;
    }
    Allocation {
        pilot,
        target: rays,
        rays: per_node,
        levels,
        predicted: if even > 0.0 { chosen / even } else { 1.0 },
    }
}

/// Each node's gathered irradiance and standard error over all its rays: the pilot's
/// (`pilot`, whose arrays are reused for the result) and the rest's (`rest`, zero where a node
/// had none), weighted by their rays.
pub fn combine(
    allocation: &Allocation,
    pilot: (Vec<Vec3>, Vec<f32>),
    rest: (&[Vec3], &[f32]),
) -> (Vec<Vec3>, Vec<f32>) {
    let (mut h, mut se) = pilot;
    let p = allocation.pilot as f32;
    for i in 0..allocation.rays.len() {
        let n = allocation.rays[i] as f32;
        let r = n - p;
        h[i] = (h[i] * p + rest.0[i] * r) / n;
        se[i] = (p * se[i]).hypot(r * rest.1[i]) / n;
    }
    (h, se)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` nodes of unit area, one patch each.
    fn nodes(n: usize) -> Nodes {
        let mut nodes = Nodes::default();
        for i in 0..n {
            nodes.patch.push(i as u32);
            nodes.area.push(1.0);
            nodes.albedo.push(Vec3::splat(0.5));
        }
        nodes
    }

    /// Every node its own cell.
    fn own_cells(n: usize) -> Vec<u32> {
        (0..n as u32).collect()
    }

    #[test]
    fn even_noise_gives_every_node_the_settings_rays() {
        let n = 100;
        let a = allocate(
            &nodes(n),
            &own_cells(n),
            &vec![1.0; n],
            &vec![0.1; n],
            32,
            128,
        );
        assert!(a.rays.iter().all(|&r| r == 128), "{:?}", a.rays);
        assert_eq!(a.total(), 128 * n as u64);
        assert!((a.predicted - 1.0).abs() < 1e-12);
    }

    #[test]
    fn no_noise_gives_the_fewest_rays() {
        let n = 10;
        let a = allocate(
            &nodes(n),
            &own_cells(n),
            &vec![1.0; n],
            &vec![0.0; n],
            8,
            32,
        );
        assert!(a.rays.iter().all(|&r| r == 16));
        assert_eq!(a.rest(3), 8..16);
    }

    #[test]
    fn noisier_nodes_get_more_rays_within_the_budget() {
        let n = 1000;
        // Noise grows with the index.
        let error: Vec<f32> = (0..n).map(|i| 0.001 * (1 + i) as f32).collect();
        let a = allocate(&nodes(n), &own_cells(n), &vec![1.0; n], &error, 32, 128);
        assert!(a.total() <= 128 * n as u64);
        assert!(a.total() >= 100 * n as u64, "mean {}", a.mean());
        assert!(a.rays.windows(2).all(|w| w[0] <= w[1]));
        assert_eq!(a.rays[0], 64);
        assert!(a.rays[n - 1] > 128, "{}", a.rays[n - 1]);
        assert_eq!(a.levels.iter().sum::<u64>(), n as u64);
        // Neyman's allocation against even rays: (Σw)²/(N·Σw²) = (n+1)·3/(2·(2n+1)) ≈ 0.75,
        // rounded to powers of two.
        assert!(a.predicted < 0.85 && a.predicted > 0.7, "{}", a.predicted);
    }

    #[test]
    fn a_cell_pools_its_nodes_noise() {
        // Two cells of two nodes: one node of the first drew no spread in its pilot.
        let light = [1.0; 4];
        let a = allocate(
            &nodes(4),
            &[0, 0, 1, 1],
            &light,
            &[0.0, 0.2, 0.01, 0.01],
            32,
            128,
        );
        assert_eq!(a.rays[0], a.rays[1]);
        assert!(a.rays[0] > a.rays[2], "{:?}", a.rays);
        // The same noise where the light is 100 × brighter weighs less.
        let b = allocate(&nodes(2), &[0, 1], &[1.0, 100.0], &[0.1, 0.1], 32, 128);
        assert!(b.rays[0] > b.rays[1], "{:?}", b.rays);
    }

    #[test]
    fn combining_weights_each_part_by_its_rays() {
        let a = Allocation {
            pilot: 32,
            target: 128,
            rays: vec![32, 128],
            levels: [1, 0, 1, 0, 0],
            predicted: 1.0,
        };
        let (h, se) = combine(
            &a,
            (vec![Vec3::ONE, Vec3::ONE], vec![0.4, 0.4]),
            (&[Vec3::ZERO, Vec3::splat(5.0)], &[0.0, 0.2]),
        );
        assert_eq!(h[0], Vec3::ONE);
        assert_eq!(se[0], 0.4);
        assert!((h[1] - Vec3::splat(4.0)).abs().max_element() < 1e-6);
        let want = ((32.0f32 * 0.4).powi(2) + (96.0f32 * 0.2).powi(2)).sqrt() / 128.0;
        assert!((se[1] - want).abs() < 1e-6);
    }
}
