//! The hierarchical solve's coarse level: the form factors between the cells of a
//! [`Clusters`] cut, by Monte Carlo (Galerkin over piecewise-constant cells), and the
//! refinement oracle that says which cells are too coarse.
//!
//! Row c of the coarse matrix is the area-weighted mean of its nodes' Monte Carlo rows
//! ([`super::monte_carlo`]) with every hit node replaced by its cell: F_cd = Σ_{i∈c} (A_i/A_c)
//! · F̂_i(d), F̂_i(d) the weight of node i's rays landing on cell d. A cell's rays are shared
//! out evenly over its nodes (at least one each), so every node's surface, normal and
//! occluders are sampled. The same rays gather the reflected direct light at full node
//! resolution where they land, so the coarse level's first bounce does not spread a sharp
//! source (a sun patch) uniformly over its cells. Both the rows and the oracle read any
//! number of fields with one set of rays (light groups share them:
//! [`super::hierarchical::coarse_solve_fields`]).

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::clusters::Clusters;
use super::hit_mapper::HitMapper;
use super::monte_carlo::for_each_sample;
use super::nodes::Nodes;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::solve::transport::{RowBlock, Transport};

/// Random-number stream of the coarse rows' rays.
const STREAM_COARSE: u32 = 210;
/// Random-number stream of the refinement oracle's rays.
const STREAM_ORACLE: u32 = 220;

/// Rays per node of cell `c` for `rays` per cell: shared out evenly, at least `least` each.
fn per_node(rays: u32, members: usize, least: u32) -> u32 {
    rays.div_ceil(members.max(1) as u32).max(least)
}

/// Row `c` of the coarse matrix appended to `out`, with `scratch` as its sort buffer.
/// Returns the escaped fraction and, per field of `directs`, the cell's first bounce.
#[allow(clippy::too_many_arguments)]
fn cell_row_into(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    clusters: &Clusters,
    c: usize,
    rays: u32,
    directs: &[&[Vec3]],
    scratch: &mut Vec<u64>,
    out: &mut RowBlock,
) -> CellResult {
    let members = clusters.members_of(c);
    let area = clusters.area[c];
    let r = per_node(rays, members.len(), 1);
    scratch.clear();
    let mut escaped = 0.0f32;
    let mut gathered = vec![Vec3::ZERO; directs.len()];
    let mut sum = vec![Vec3::ZERO; directs.len()];
    let mut hits: Vec<(u32, f32)> = Vec::new();
    for &m in members {
        let m = m as usize;
        hits.clear();
        let mut total = 0.0f32;
        sum.fill(Vec3::ZERO);
        let e = for_each_sample(ctx, mapper, nodes, m, r, STREAM_COARSE, |weight, hit| {
            total += weight;
            for &(j, wj) in hit {
                hits.push((clusters.of_node[j as usize], wj * weight));
                let j = j as usize;
                for (s, direct) in sum.iter_mut().zip(directs) {
                    *s += nodes.albedo[j] * direct[nodes.patch[j] as usize] * (wj * weight);
                }
            }
        });
        if total <= 0.0 {
            continue;
        }
        let share = if area > 0.0 {
            nodes.area[m] / area
        } else {
            1.0 / members.len() as f32
        };
        let scale = share / total;
        escaped += e * scale;
        for (g, s) in gathered.iter_mut().zip(&sum) {
            *g += *s * scale;
        }
        // Entries packed as (cell << 32 | weight bits): weights are non-negative, so one
        // integer sort orders them by cell.
        scratch.extend(
            hits.iter()
                .map(|&(d, w)| (d as u64) << 32 | (w * scale).to_bits() as u64),
        );
    }
    scratch.sort_unstable();
    let start = out.cols.len();
    for &e in scratch.iter() {
        let (d, v) = ((e >> 32) as u32, f32::from_bits(e as u32));
        if out.cols.len() > start && out.cols.last() == Some(&d) {
            *out.vals.last_mut().expect("a value per column") += v;
        } else {
            out.cols.push(d);
            out.vals.push(v);
        }
    }
    out.lens.push((out.cols.len() - start) as u32);
    (escaped, gathered)
}

/// A cell's escaped fraction and, per field, its first bounce.
type CellResult = (f32, Vec<Vec3>);

/// The coarse level's matrix and first bounce.
pub struct CoarseRows {
    /// F between the cells.
    pub matrix: Transport,
    /// Per field, per cell: the irradiance its rays gather from the field's reflected direct
    /// light ρ∘H_d, read at full node resolution at every hit (lux).
    pub first_bounce: Vec<Vec<Vec3>>,
}

/// Builds the coarse matrix of `clusters` with about `rays` rays per cell, and gathers with
/// the same rays each field's reflected direct light ρ∘H_d (`directs[f]` per patch): the
/// cells' first bounce at full resolution on the emitting side.
pub fn build(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    clusters: &Clusters,
    rays: u32,
    directs: &[&[Vec3]],
    progress: &Progress,
) -> CoarseRows {
    let m = clusters.len();
    let traced = AtomicU64::new(0);
    let runs: Vec<(RowBlock, Vec<CellResult>)> = (0..m)
        .into_par_iter()
        .with_min_len(16)
        .fold(
            || (RowBlock::default(), Vec::new(), Vec::new()),
            |(mut rows, mut escaped, mut scratch), c| {
                if progress.is_cancelled() {
                    rows.lens.push(0);
                    escaped.push((0.0, vec![Vec3::ZERO; directs.len()]));
                } else {
                    escaped.push(cell_row_into(
                        ctx,
                        mapper,
                        nodes,
                        clusters,
                        c,
                        rays,
                        directs,
                        &mut scratch,
                        &mut rows,
                    ));
                    let r = per_node(rays, clusters.members_of(c).len(), 1);
                    traced.fetch_add(
                        r as u64 * clusters.members_of(c).len() as u64,
                        Ordering::Relaxed,
                    );
                }
                (rows, escaped, scratch)
            },
        )
        .map(|(rows, escaped, _)| (rows, escaped))
        .collect();
    // Cells are piecewise constant, whatever the nodes' basis.
    let mut t = Transport::empty(m, crate::settings::Basis::Constant);
    let nnz: usize = runs.iter().map(|r| r.0.cols.len()).sum();
    t.cols.reserve_exact(nnz);
    t.vals.reserve_exact(nnz);
    let mut first_bounce = vec![Vec::with_capacity(m); directs.len()];
    for (rows, results) in runs {
        let escaped = results.iter().map(|r| r.0).collect();
        for (f, field) in first_bounce.iter_mut().enumerate() {
            field.extend(results.iter().map(|r| r.1[f]));
        }
        t.push_block(rows, escaped);
    }
    t.rays = traced.into_inner();
    CoarseRows {
        matrix: t,
        first_bounce,
    }
}

/// Texels of a cell the refinement oracle gathers at.
const ORACLE_TEXELS: usize = 4;

/// The refinement oracle: per field of `bs`, per cell, the power of the detail that its
/// uniform value misses, A_c·ρ_c²·V_c (lux²·m², ρ_c the luminance of its albedo), with V_c
/// the variance over the cell's texels of the irradiance gathered from exitance `bs[f]` (per
/// node: the fine direct light plus the coarse indirect light, reflected): what the final
/// gather will see and the cell's uniform value does not hold. It is estimated from
/// [`ORACLE_TEXELS`] texels spread over the cell (evenly through its row-major texel order),
/// each gathering with `rays / 4` rays (at least two) split into two interleaved halves; the
/// halves' difference gives each gather's noise, which is taken out: V_c = max(0, s² − mean
/// σ²), s² the texels' sample variance and σ² = (h_a − h_b)²/4 the variance of each one's
/// mean. Every field reads the same rays. Cells of level 0, or of one texel, have nothing to
/// refine (0). Returns the powers (`[field][cell]`) and the rays traced.
pub fn missed_detail(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    clusters: &Clusters,
    bs: &[&[Vec3]],
    rays: u32,
) -> (Vec<Vec<f64>>, u64) {
    let r = (rays / ORACLE_TEXELS as u32).max(2);
    let fields = bs.len();
    let results: Vec<(Vec<f64>, u64)> = (0..clusters.len())
        .into_par_iter()
        .with_min_len(16)
        .map(|c| {
            let members = clusters.members_of(c);
            if clusters.cells[c].level == 0 || members.len() < 2 {
                return (vec![0.0; fields], 0);
            }
            let k = members.len().min(ORACLE_TEXELS);
            // Per sampled texel, per field: (mean, variance of the mean) of its gather.
            let gathers: Vec<Vec<(f64, f64)>> = (0..k)
                .map(|s| {
                    let i = members[(s * members.len() + members.len() / 2) / k] as usize;
                    let mut half = vec![[(0.0f64, 0.0f64); 2]; fields];
                    let mut sample = 0usize;
                    for_each_sample(ctx, mapper, nodes, i, r, STREAM_ORACLE, |w, hit| {
                        for (h, b) in half.iter_mut().zip(bs) {
                            let v: f32 = hit
                                .iter()
                                .map(|&(j, wj)| wj * luminance(b[j as usize]))
                                .sum();
                            let h = &mut h[sample & 1];
                            h.0 += (w * v) as f64;
                            h.1 += w as f64;
                        }
                        sample += 1;
                    });
                    let mean_of = |(s, w): (f64, f64)| if w > 0.0 { s / w } else { 0.0 };
                    (half.iter())
                        .map(|h| {
                            let (ha, hb) = (mean_of(h[0]), mean_of(h[1]));
                            (0.5 * (ha + hb), 0.25 * (ha - hb) * (ha - hb))
                        })
                        .collect()
                })
                .collect();
            let traced = k as u64 * r as u64;
            let rho = luminance(clusters.albedo[c]) as f64;
            let powers = (0..fields)
                .map(|f| {
                    let mean = gathers.iter().map(|g| g[f].0).sum::<f64>() / k as f64;
                    let spread = gathers.iter().map(|g| (g[f].0 - mean).powi(2)).sum::<f64>()
                        / (k - 1) as f64;
                    let noise = gathers.iter().map(|g| g[f].1).sum::<f64>() / k as f64;
                    clusters.area[c] as f64 * rho * rho * (spread - noise).max(0.0)
                })
                .collect();
            (powers, traced)
        })
        .collect();
    let rays = results.iter().map(|r| r.1).sum();
    let mut powers = vec![Vec::with_capacity(clusters.len()); fields];
    for (p, _) in results {
        for (field, v) in powers.iter_mut().zip(p) {
            field.push(v);
        }
    }
    (powers, rays)
}
