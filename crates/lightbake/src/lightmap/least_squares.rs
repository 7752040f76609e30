//! Least squares over lightmap texels, shared by the contact fit ([`super::contacts`]) and the
//! seam stitch ([`super::stitch`]): the unknowns (page texels, padding included), relative
//! weights, and the normal equations N·x = b with N = Σ a·t·tᵀ + Λ (rows t of a few texels
//! each, so N has a few entries per unknown), solved by Jacobi-preconditioned conjugate
//! gradients, one channel at a time, in double precision. Rows are summed in the order they
//! are added and each product N·x sums a row in a fixed order, so the result does not depend
//! on the thread count.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{Assembly, TexelState};
use crate::color::luminance;
use crate::raster::Patches;

/// The texels a least-squares problem solves for, each a (page, texel index) pair, in sorted
/// order.
pub struct Unknowns {
    keys: Vec<u64>,
    index: HashMap<u64, u32>,
}

/// Page and texel index as one key.
fn key(page: u32, texel: u32) -> u64 {
    ((page as u64) << 32) | texel as u64
}

impl Unknowns {
    /// The distinct texels of `texels`.
    pub fn new(texels: impl Iterator<Item = (u32, u32)>) -> Self {
        let mut keys: Vec<u64> = texels.map(|(p, t)| key(p, t)).collect();
        keys.sort_unstable();
        keys.dedup();
        let index = keys
            .iter()
            .enumerate()
            .map(|(i, &k)| (k, i as u32))
            .collect();
        Self { keys, index }
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether there are none.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The unknown of texel `texel` of page `page`.
    ///
    /// # Panics
    /// When it is not one of the unknowns.
    pub fn index(&self, page: u32, texel: u32) -> u32 {
        self.index[&key(page, texel)]
    }

    /// (page, texel index) of every unknown, in order.
    pub fn iter(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        self.keys.iter().map(|&k| ((k >> 32) as u32, k as u32))
    }

    /// The current values of the unknowns on the pages.
    pub fn values(&self, a: &Assembly) -> Vec<Vec3> {
        self.iter()
            .map(|(p, t)| a.pages[p as usize].texels[t as usize])
            .collect()
    }

    /// Lowers each value of `x` to at most `ceiling` (per unknown, per channel) and to the
    /// brightest covered texel of its page: a texel a fit reads with a small bilinear weight
    /// would otherwise take the light it needs divided by that weight, far above any light
    /// in the scene and beyond the half-float range, and the GPU shows it wherever else it
    /// reads that texel. Returns how many values were lowered.
    pub fn cap(&self, a: &Assembly, x: &mut [Vec3], ceiling: &[Vec3]) -> usize {
        let brightest: Vec<Vec3> = a
            .pages
            .iter()
            .map(|p| {
                p.texels
                    .iter()
                    .zip(&p.covered)
                    .filter(|(_, c)| **c)
                    .fold(Vec3::ZERO, |m, (t, _)| m.max(*t))
            })
            .collect();
        let mut capped = 0;
        for ((v, c), (page, _)) in x.iter_mut().zip(ceiling).zip(self.iter()) {
            let low = v.min(c.min(brightest[page as usize]));
            capped += usize::from(low != *v);
            *v = low;
        }
        capped
    }

    /// Writes `x` (held at zero or above) to the pages, marking the texels set.
    pub fn write(&self, a: &mut Assembly, x: &[Vec3]) {
        for ((p, t), v) in self.iter().zip(x) {
            a.set(p as usize, t as usize, v.max(Vec3::ZERO));
        }
    }
}

/// Whether texel `texel` of page `page` holds a value of its own (a valid patch's) rather
/// than one the pages are free to choose (padding, a hidden texel's fill).
pub fn holds_value(a: &Assembly, patches: &Patches, page: u32, texel: u32) -> bool {
    let pi = patches.page_index[page as usize][texel as usize];
    a.state[page as usize][texel as usize] == TexelState::Set
        && pi != u32::MAX
        && patches.patches[pi as usize].is_valid()
}

/// The relative weight 1/(L(v)² + L₀²) of an error at a texel value `v`, with L₀ 1% of the
/// RMS luminance of the pages' set texels (so black texels do not weigh without bound).
pub fn relative_weight(a: &Assembly) -> impl Fn(Vec3) -> f64 + use<> {
    let (mut sum, mut n) = (0.0f64, 0.0f64);
    for (page, st) in a.pages.iter().zip(&a.state) {
        for (t, s) in page.texels.iter().zip(st) {
            if *s == TexelState::Set {
                sum += (luminance(*t) as f64).powi(2);
                n += 1.0;
            }
        }
    }
    let floor2 = 1e-4 * sum / n.max(1.0);
    move |v: Vec3| 1.0 / ((luminance(v) as f64).powi(2) + floor2).max(1e-300)
}

/// Normal equations over a set of unknowns (see the module docs).
pub struct LeastSquares {
    /// Per unknown: (column, value), merged.
    entries: Vec<Vec<(u32, f64)>>,
    rhs: Vec<DVec3>,
    /// Per unknown: Σ a·t_i² and Σ a·t_i²·g over the rows added, for [`Self::free`].
    mass: Vec<f64>,
    pull: Vec<DVec3>,
}

/// Conjugate-gradient iterations at most, per channel.
const MAX_ITERATIONS: u32 = 500;
/// Relative residual at which the iterations stop.
const TOLERANCE: f64 = 1e-8;

impl LeastSquares {
    /// No rows yet over `n` unknowns.
    pub fn new(n: usize) -> Self {
        Self {
            entries: vec![Vec::new(); n],
            rhs: vec![DVec3::ZERO; n],
            mass: vec![0.0; n],
            pull: vec![DVec3::ZERO; n],
        }
    }

    /// Adds a·(t·x − g)² for the row `taps` (unknown, coefficient).
    pub fn add_row(&mut self, taps: &[(u32, f64)], a: f64, g: DVec3) {
        for &(i, wi) in taps {
            self.rhs[i as usize] += g * (a * wi);
            for &(j, wj) in taps {
                add(&mut self.entries[i as usize], j, a * wi * wj);
            }
        }
    }

    /// Records that a row of weight `a` wants unknown `i` itself at `value` (the value the
    /// reconstruction should show where the row samples it); [`Self::free`] holds `i` at the
    /// mean of these.
    pub fn add_target(&mut self, i: u32, a: f64, value: DVec3) {
        self.mass[i as usize] += a;
        self.pull[i as usize] += value * a;
    }

    /// Holds unknown `i` at `value` with weight `lambda`: adds λ·(x_i − value)².
    pub fn hold(&mut self, i: usize, lambda: f64, value: DVec3) {
        add(&mut self.entries[i], i as u32, lambda);
        self.rhs[i] += value * lambda;
    }

    /// Keeps unknown `i`, whose value the problem is free to choose, from drifting where the
    /// rows leave it undetermined: holds it at the mean of its targets ([`Self::add_target`])
    /// with `fraction` of their weight; at `fallback` when it has none. Call after every
    /// target is added.
    pub fn free(&mut self, i: usize, fraction: f64, fallback: DVec3) {
        if self.mass[i] > 0.0 {
            let value = self.pull[i] / self.mass[i];
            self.hold(i, fraction * self.mass[i], value);
        } else {
            self.hold(i, 1.0, fallback);
        }
    }

    /// The solution from `start`, and the most iterations a channel took.
    pub fn solve(&self, start: &[Vec3]) -> (Vec<Vec3>, u32) {
        let n = self.rhs.len();
        let diag: Vec<f64> = (0..n)
            .map(|i| {
                self.entries[i]
                    .iter()
                    .find(|e| e.0 as usize == i)
                    .map_or(1.0, |e| e.1)
            })
            .collect();
        let mut out = vec![DVec3::ZERO; n];
        let mut most = 0;
        for c in 0..3 {
            let b: Vec<f64> = self.rhs.iter().map(|v| v[c]).collect();
            let mut x: Vec<f64> = start.iter().map(|v| v[c] as f64).collect();
            most = most.max(self.cg(&b, &diag, &mut x));
            for (o, v) in out.iter_mut().zip(x) {
                o[c] = v;
            }
        }
        (out.iter().map(|v| v.as_vec3()).collect(), most)
    }

    /// N·x.
    fn mul(&self, x: &[f64]) -> Vec<f64> {
        self.entries
            .par_iter()
            .with_min_len(1024)
            .map(|row| row.iter().map(|&(j, v)| v * x[j as usize]).sum())
            .collect()
    }

    /// Preconditioned conjugate gradients on N·x = b from `x`; the iterations taken.
    fn cg(&self, b: &[f64], diag: &[f64], x: &mut [f64]) -> u32 {
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let ax = self.mul(x);
        let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let target = TOLERANCE * dot(b, b).sqrt();
        let mut z: Vec<f64> = r.iter().zip(diag).map(|(r, d)| r / d).collect();
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        for it in 0..MAX_ITERATIONS {
            if dot(&r, &r).sqrt() <= target {
                return it;
            }
            let ap = self.mul(&p);
            let alpha = rz / dot(&p, &ap);
            for k in 0..x.len() {
                x[k] += alpha * p[k];
                r[k] -= alpha * ap[k];
                z[k] = r[k] / diag[k];
            }
            let rz_next = dot(&r, &z);
            let beta = rz_next / rz;
            rz = rz_next;
            for k in 0..p.len() {
                p[k] = z[k] + beta * p[k];
            }
        }
        MAX_ITERATIONS
    }
}

/// Adds `v` at column `j` of a merged sparse row.
fn add(row: &mut Vec<(u32, f64)>, j: u32, v: f64) {
    match row.iter_mut().find(|e| e.0 == j) {
        Some(e) => e.1 += v,
        None => row.push((j, v)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small system against its closed-form solution: x₀ = 1 and x₁ = 3 held weakly, and
    /// a row asking x₀ + x₁ = 2 strongly: the minimiser of (x₀ + x₁ − 2)²·100 + 0.01·((x₀ − 1)²
    /// + (x₁ − 3)²) is x₀ = 1 − δ, x₁ = 3 − δ with δ = 200/(200 + 0.01)·1 ≈ 0.99995.
    #[test]
    fn solves_a_small_system() {
        let mut ls = LeastSquares::new(2);
        ls.add_row(&[(0, 1.0), (1, 1.0)], 100.0, DVec3::splat(2.0));
        ls.hold(0, 0.01, DVec3::ONE);
        ls.hold(1, 0.01, DVec3::splat(3.0));
        let (x, _) = ls.solve(&[Vec3::ONE, Vec3::splat(3.0)]);
        let delta = 200.0 / 200.01;
        assert!((x[0].x as f64 - (1.0 - delta)).abs() < 1e-5, "{:?}", x[0]);
        assert!((x[1].y as f64 - (3.0 - delta)).abs() < 1e-5, "{:?}", x[1]);
    }

    /// A free texel read with weight 0.3 beside a held texel of 10, where the reconstruction
    /// should show 10: the row asks 0.3·x = 10 − 0.7·10 and the hold is at the row's target
    /// 10 (not at the row's right-hand side 3), so x = 10 exactly.
    #[test]
    fn a_free_texel_is_held_at_its_rows_target() {
        let mut ls = LeastSquares::new(1);
        let (a, w) = (2.0, 0.3);
        ls.add_row(&[(0, w)], a, DVec3::splat(10.0 - 0.7 * 10.0));
        ls.add_target(0, a * w * w, DVec3::splat(10.0));
        ls.free(0, 1.0, DVec3::ZERO);
        let (x, _) = ls.solve(&[Vec3::ZERO]);
        assert!((x[0].x - 10.0).abs() < 1e-4, "{:?}", x[0]);
    }

    /// The cap: a padding texel a row reads with weight 0.02 and that must lift the row by
    /// 3 takes 150 from the solve; it is lowered to the brightest covered texel of its page
    /// (3), another to its own ceiling (0.5), and one under both keeps its value.
    #[test]
    fn values_are_capped_at_their_ceiling_and_the_pages_brightest_texel() {
        let mut page = crate::lightmap::LightmapPage::black(4, 1);
        page.texels[0] = Vec3::ONE;
        page.texels[1] = Vec3::new(3.0, 2.0, 1.0);
        page.covered[0] = true;
        page.covered[1] = true;
        page.texels[3] = Vec3::splat(40.0); // padding: not covered, not a bound
        let a = Assembly {
            pages: vec![page],
            state: vec![vec![TexelState::Set; 4]],
            stats: Default::default(),
        };
        let unknowns = Unknowns::new([(0, 2), (0, 3), (0, 0)].into_iter());
        let order: Vec<u32> = unknowns.iter().map(|(_, t)| t).collect();
        let value = |t: u32| match t {
            2 => Vec3::splat(150.0),
            3 => Vec3::splat(4.0),
            _ => Vec3::splat(0.25),
        };
        let ceiling_of = |t: u32| match t {
            2 => Vec3::splat(6.0),
            3 => Vec3::splat(0.5),
            _ => Vec3::splat(1.0),
        };
        let mut x: Vec<Vec3> = order.iter().map(|&t| value(t)).collect();
        let ceiling: Vec<Vec3> = order.iter().map(|&t| ceiling_of(t)).collect();
        assert_eq!(unknowns.cap(&a, &mut x, &ceiling), 2);
        for (&t, v) in order.iter().zip(&x) {
            let expected = match t {
                2 => Vec3::new(3.0, 2.0, 1.0),
                3 => Vec3::splat(0.5),
                _ => Vec3::splat(0.25),
            };
            assert_eq!(*v, expected, "texel {t}");
        }
    }
}
