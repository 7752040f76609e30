//! The form-factor matrix F of the radiosity equation in compressed sparse rows, and its
//! algebra: products in single and double precision, the transpose (shooting's columns), the
//! reciprocity-symmetrised matrix (conjugate gradients) and the checks of its invariants.
//! Built by [`crate::radiosity`] (Monte Carlo rows or the hemicube).

use glam::DVec3;
use rayon::prelude::*;

use crate::settings::Basis;

/// A run of consecutive matrix rows in flat arrays: columns and weights one row after the
/// other, and each row's length.
#[derive(Default)]
pub(crate) struct RowBlock {
    pub(crate) cols: Vec<u32>,
    pub(crate) vals: Vec<f32>,
    pub(crate) lens: Vec<u32>,
}

/// The sparse form-factor matrix F in compressed rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Transport {
    /// Number of nodes (rows and columns).
    pub n: usize,
    row_ptr: Vec<u64>,
    pub(crate) cols: Vec<u32>,
    pub(crate) vals: Vec<f32>,
    /// Per row: the fraction of its rays that left the scene.
    pub escaped: Vec<f32>,
    /// Rays traced to build it.
    pub rays: u64,
    /// Basis the weights are in.
    pub basis: Basis,
}

/// What [`Transport::validate`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
#[cfg(any(test, feature = "internals"))]
pub struct TransportCheck {
    /// Largest row sum (must not exceed 1).
    pub max_row_sum: f32,
    /// Area-weighted mean row sum (≈ 1 in a closed room).
    pub mean_row_sum: f32,
    /// ‖AF − (AF)ᵀ‖_F / ‖AF‖_F with A = diag(area): 0 for exact reciprocity.
    pub reciprocity_error: f32,
}

impl Transport {
    /// An empty matrix of `n` rows, to be filled by [`Self::push_rows`].
    pub(crate) fn empty(n: usize, basis: Basis) -> Self {
        let mut row_ptr = Vec::with_capacity(n + 1);
        row_ptr.push(0);
        Transport {
            n,
            row_ptr,
            cols: Vec::new(),
            vals: Vec::new(),
            escaped: Vec::with_capacity(n),
            rays: 0,
            basis,
        }
    }

    /// Appends rows produced in order.
    pub(crate) fn push_rows(&mut self, rows: Vec<(Vec<(u32, f32)>, f32)>) {
        for (row, escaped) in rows {
            for (c, v) in row {
                self.cols.push(c);
                self.vals.push(v);
            }
            self.row_ptr.push(self.cols.len() as u64);
            self.escaped.push(escaped);
        }
    }

    /// Appends a run of rows made in order (see [`RowBlock`]) and their escaped fractions.
    pub(crate) fn push_block(&mut self, rows: RowBlock, escaped: Vec<f32>) {
        self.cols.extend_from_slice(&rows.cols);
        self.vals.extend_from_slice(&rows.vals);
        let mut end = *self.row_ptr.last().expect("row_ptr starts with 0");
        for len in rows.lens {
            end += len as u64;
            self.row_ptr.push(end);
        }
        self.escaped.extend(escaped);
    }

    /// Builds F from rows produced in order (used by the builders).
    pub(crate) fn from_rows(
        n: usize,
        rows: Vec<(Vec<(u32, f32)>, f32)>,
        rays: u64,
        basis: Basis,
    ) -> Self {
        let nnz: usize = rows.iter().map(|r| r.0.len()).sum();
        let mut t = Self::empty(n, basis);
        t.cols.reserve_exact(nnz);
        t.vals.reserve_exact(nnz);
        t.push_rows(rows);
        t.rays = rays;
        t
    }

    /// Its storage: (row pointers, columns, weights, escaped fractions), as
    /// [`Self::from_parts`] takes them.
    pub(crate) fn parts(&self) -> (&[u64], &[u32], &[f32], &[f32]) {
        (&self.row_ptr, &self.cols, &self.vals, &self.escaped)
    }

    /// A matrix of `n` rows from its storage ([`Self::parts`]); `None` when the parts do not
    /// fit together (row pointers from 0, non-decreasing, ending at the entries; a column
    /// below `n` per entry; an escaped fraction per row).
    pub(crate) fn from_parts(
        n: usize,
        (row_ptr, cols, vals, escaped): (Vec<u64>, Vec<u32>, Vec<f32>, Vec<f32>),
        rays: u64,
        basis: Basis,
    ) -> Option<Self> {
        let fits = row_ptr.len() == n + 1
            && row_ptr.first() == Some(&0)
            && row_ptr.windows(2).all(|w| w[0] <= w[1])
            && row_ptr.last() == Some(&(cols.len() as u64))
            && vals.len() == cols.len()
            && escaped.len() == n
            && cols.iter().all(|&c| (c as usize) < n);
        fits.then_some(Transport {
            n,
            row_ptr,
            cols,
            vals,
            escaped,
            rays,
            basis,
        })
    }

    /// Stored entries.
    pub fn nnz(&self) -> usize {
        self.cols.len()
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        (self.cols.len() * 8 + self.row_ptr.len() * 8 + self.escaped.len() * 4) as u64
    }

    /// Row `i`: (columns, weights).
    pub fn row(&self, i: usize) -> (&[u32], &[f32]) {
        let (a, b) = (self.row_ptr[i] as usize, self.row_ptr[i + 1] as usize);
        (&self.cols[a..b], &self.vals[a..b])
    }

    #[cfg(any(test, feature = "internals"))]
    /// y = F·x.
    pub fn mul(&self, x: &[glam::Vec3], y: &mut [glam::Vec3]) {
        y.par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(i, yi)| {
                let (c, v) = self.row(i);
                *yi = c
                    .iter()
                    .zip(v)
                    .fold(glam::Vec3::ZERO, |s, (&j, &w)| s + x[j as usize] * w);
            });
    }

    /// y = F·x in double precision (what the solvers use).
    pub fn mul64(&self, x: &[DVec3], y: &mut [DVec3]) {
        y.par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(i, yi)| {
                let (c, v) = self.row(i);
                *yi = c
                    .iter()
                    .zip(v)
                    .fold(DVec3::ZERO, |s, (&j, &w)| s + x[j as usize] * w as f64);
            });
    }

    /// Fᵀ in compressed rows (the columns of F, for shooting).
    pub fn transpose(&self) -> Transport {
        let mut count = vec![0u64; self.n + 1];
        for &c in &self.cols {
            count[c as usize + 1] += 1;
        }
        for i in 0..self.n {
            count[i + 1] += count[i];
        }
        let row_ptr = count.clone();
        let mut next = count;
        let mut cols = vec![0u32; self.cols.len()];
        let mut vals = vec![0f32; self.vals.len()];
        for i in 0..self.n {
            let (c, v) = self.row(i);
            for (&j, &w) in c.iter().zip(v) {
                let k = next[j as usize] as usize;
                cols[k] = i as u32;
                vals[k] = w;
                next[j as usize] += 1;
            }
        }
        Transport {
            n: self.n,
            row_ptr,
            cols,
            vals,
            escaped: vec![0.0; self.n],
            rays: self.rays,
            basis: self.basis,
        }
    }

    /// The reciprocity-symmetrised matrix F̃, for which diag(A)·F̃ is symmetric (what
    /// conjugate gradients needs), with the same row sums as F.
    ///
    /// G = (A·F + (A·F)ᵀ)/2 is symmetric, but its row sums carry the sampling noise of F's
    /// column sums, and in a stiff scene a 1% change of a row sum moves B by ρ/(1 − ρ)·1%. So
    /// G is balanced by a symmetric diagonal scaling G̃ = D·G·D whose rows sum to A∘(F·1)
    /// (symmetric Sinkhorn–Knopp iteration, d ← √(d·t / (G·d))), and F̃ = A⁻¹·G̃.
    pub fn symmetrized(&self, area: &[f32]) -> Transport {
        let t = self.transpose();
        // G = (A·F + (A·F)ᵀ)/2, row by row (merging row i of F with column i).
        let rows: Vec<(Vec<(u32, f32)>, f32)> = (0..self.n)
            .into_par_iter()
            .map(|i| {
                let (c1, v1) = self.row(i);
                let (c2, v2) = t.row(i); // entries F_ji for j in c2
                let mut merged: Vec<(u32, f32)> = Vec::with_capacity(c1.len() + c2.len());
                let (mut a, mut b) = (0, 0);
                while a < c1.len() || b < c2.len() {
                    let ja = c1.get(a).copied().unwrap_or(u32::MAX);
                    let jb = c2.get(b).copied().unwrap_or(u32::MAX);
                    let j = ja.min(jb);
                    let fij = if ja == j {
                        a += 1;
                        v1[a - 1]
                    } else {
                        0.0
                    };
                    let fji = if jb == j {
                        b += 1;
                        v2[b - 1]
                    } else {
                        0.0
                    };
                    merged.push((j, 0.5 * (area[i] * fij + area[j as usize] * fji)));
                }
                (merged, self.escaped[i])
            })
            .collect();
        drop(t);
        let mut g = Self::from_rows(self.n, rows, self.rays, self.basis);
        // Row sums to restore: A_i · Σ_j F_ij.
        let target: Vec<f64> = (0..self.n)
            .map(|i| area[i] as f64 * self.row(i).1.iter().map(|&v| v as f64).sum::<f64>())
            .collect();
        let mut d = vec![1.0f64; self.n];
        for _ in 0..200 {
            let gd: Vec<f64> = (0..self.n)
                .into_par_iter()
                .with_min_len(256)
                .map(|i| {
                    let (c, v) = g.row(i);
                    c.iter()
                        .zip(v)
                        .map(|(&j, &w)| w as f64 * d[j as usize])
                        .sum()
                })
                .collect();
            let mut worst = 0.0f64;
            for i in 0..self.n {
                if gd[i] > 0.0 && target[i] > 0.0 {
                    worst = worst.max((d[i] * gd[i] / target[i] - 1.0).abs());
                    d[i] = (d[i] * target[i] / gd[i]).sqrt();
                }
            }
            if worst < 1e-8 {
                break;
            }
        }
        // F̃ = A⁻¹·D·G·D.
        for i in 0..self.n {
            let (a, b) = (g.row_ptr[i] as usize, g.row_ptr[i + 1] as usize);
            let ai = (area[i] as f64).max(1e-30);
            for k in a..b {
                let j = g.cols[k] as usize;
                g.vals[k] = (d[i] * g.vals[k] as f64 * d[j] / ai) as f32;
            }
        }
        g
    }

    #[cfg(any(test, feature = "internals"))]
    /// Checks row sums (≤ 1) and measures reciprocity.
    ///
    /// # Errors
    /// When a row sums to more than 1 + 10⁻⁴ or holds a non-finite or negative weight.
    pub fn validate(&self, area: &[f32]) -> Result<TransportCheck, String> {
        let mut check = TransportCheck::default();
        let (mut weighted, mut total_area) = (0.0f64, 0.0f64);
        for i in 0..self.n {
            let (c, v) = self.row(i);
            if let Some(k) = v.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(format!("row {i}: weight {} for column {}", v[k], c[k]));
            }
            if c.windows(2).any(|w| w[0] >= w[1]) {
                return Err(format!("row {i}: columns are not sorted and unique"));
            }
            let sum: f32 = v.iter().sum();
            if sum > 1.0 + 1e-4 {
                return Err(format!("row {i} sums to {sum} > 1"));
            }
            check.max_row_sum = check.max_row_sum.max(sum);
            weighted += sum as f64 * area[i] as f64;
            total_area += area[i] as f64;
        }
        check.mean_row_sum = if total_area > 0.0 {
            (weighted / total_area) as f32
        } else {
            0.0
        };
        let t = self.transpose();
        let (mut diff, mut norm) = (0.0f64, 0.0f64);
        for i in 0..self.n {
            let (c1, v1) = self.row(i);
            let (c2, v2) = t.row(i);
            let lookup = |j: u32| c2.binary_search(&j).map_or(0.0, |k| v2[k]);
            for (&j, &fij) in c1.iter().zip(v1) {
                let a = area[i] as f64 * fij as f64;
                let b = area[j as usize] as f64 * lookup(j) as f64;
                diff += (a - b) * (a - b);
                norm += a * a;
            }
        }
        check.reciprocity_error = if norm > 0.0 {
            (diff / norm).sqrt() as f32
        } else {
            0.0
        };
        Ok(check)
    }

    #[cfg(any(test, feature = "internals"))]
    /// Block form factor between two node sets: F_{I→J} = Σ_{i∈I} A_i Σ_{j∈J} F_ij / Σ_{i∈I} A_i.
    pub fn block_form_factor(&self, area: &[f32], from: &[u32], to: &[u32]) -> f64 {
        let mut in_to = vec![false; self.n];
        for &j in to {
            in_to[j as usize] = true;
        }
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for &i in from {
            let (c, v) = self.row(i as usize);
            let s: f64 = c
                .iter()
                .zip(v)
                .filter(|(j, _)| in_to[**j as usize])
                .map(|(_, &w)| w as f64)
                .sum();
            num += area[i as usize] as f64 * s;
            den += area[i as usize] as f64;
        }
        if den > 0.0 { num / den } else { 0.0 }
    }
}
