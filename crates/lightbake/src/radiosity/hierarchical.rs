//! Hierarchical radiosity for lightmaps: a coarse multi-bounce solve over texel clusters,
//! refined where it is too coarse, then a per-texel final gather.
//!
//! With H_d the direct irradiance of every node (from the direct pass) and C the coarse
//! solution's reflected irradiance of every cell ([`Clusters`]), the lightmap's reflected
//! irradiance at node i is the final gather
//!
//! H_i = Σ_j F̂_ij·b_j,  b_j = ρ_j·(H_d,j + C_{cell(j)}),
//!
//! F̂_i the Monte Carlo row of node i ([`super::monte_carlo::gather`]: the rays of the full
//! matrix's row i, summed as they come, never stored). Every ray's hit reads the direct light
//! at full texel resolution, so the first reflection is as sharp as the full matrix's; only
//! the light reflected twice or more goes through the coarse level. This is the split of
//! Hanrahan, Salzman & Aupperle (1991; coarse links where the transported light is small)
//! with a final gather as in production lightmappers (Enlighten's cluster → texel transport):
//! the coarse level holds O(cells) entries, the gather O(1) per node, so memory is linear in
//! the texels.
//!
//! The final gather's rays per node are shared out by the noise a pilot of a quarter of them
//! measures ([`super::ray_allocation`]; `settings.radiosity.adaptive_gather`), so with the same
//! rays in all a node's row has 1/2 to 4 × the rays of a matrix row: the rays of a row of
//! that length.
//!
//! The coarse level (Cohen & Wallace 1993, ch. 8, adaptive subdivision on texel cells):
//! 1. start from the cut of [`HierarchyOptions::top_level`] (cells of 2^level texels square);
//! 2. build the cells' form factors ([`coarse::build`]) and solve the coarse system
//!    (B_c = S_c + ρ_c·(F·B)_c, S_c the restricted ρ∘H_d) with the matrix solvers;
//! 3. measure every cell's missed detail ([`coarse::missed_detail`]: the variance of the
//!    gathered light between its quadrants) and split the cells that carry the most, until
//!    the rest is within [`HierarchyOptions::tolerance`] of the irradiance, the coarse matrix
//!    reaches its memory cap, or every cell is one texel; back to 2.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use super::clusters::{Clusters, Links};
use super::exitance_grid::ExitanceGrid;
use super::hit_mapper::HitMapper;
use super::monte_carlo::{self, GatherSample, STREAM_TRANSPORT};
use super::nodes::Nodes;
use super::{coarse, residual_tolerance};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::solve::{self, Solution, SolveOptions, System};

/// How the coarse level is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HierarchyOptions {
    /// Level of the first cut: cells of up to 2^level × 2^level texels.
    pub top_level: u8,
    /// Form-factor rays per cell (shared out over its nodes, at least one each); the oracle
    /// traces as many.
    pub cell_rays: u32,
    /// Refinement stops when the missed detail left, as an RMS over the surface, is at most
    /// this fraction of the RMS irradiance.
    pub tolerance: f64,
    /// Cap on the coarse matrix, bytes.
    pub max_matrix_bytes: u64,
    /// The coarse solve's relative residual target (see [`SolveOptions::tolerance`]).
    pub solver_tolerance: f64,
    /// The coarse solve's iteration cap.
    pub max_iterations: u32,
}

/// What the coarse level ended as, for the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoarseReport {
    /// Cells of the final cut.
    pub cells: usize,
    /// Cells per level of the final cut (index = level; level k is 2ᵏ texels square).
    pub cells_per_level: Vec<usize>,
    /// Build–solve–measure rounds.
    pub rounds: u32,
    /// Stored entries of the final coarse matrix.
    pub matrix_entries: usize,
    /// Bytes of the final coarse matrix.
    pub matrix_bytes: u64,
    /// The missed detail left (RMS over the surface of ρ·√V per cell, over the RMS
    /// irradiance): what the refinement drove below the tolerance.
    pub missed_detail: f64,
    /// Why the refinement stopped, in words.
    pub stop_reason: String,
    /// The last coarse solve's solver.
    pub solver: &'static str,
    /// Rays traced for the coarse rows and the oracle, over all rounds.
    pub rays: u64,
}

/// The coarse level's result.
pub struct Coarse {
    /// The final cut.
    pub clusters: Clusters,
    /// The last coarse solve (per cell: `b` = ρ∘C, `indirect`
    /// = C, the reflected irradiance).
    pub solution: Solution,
    /// What it ended as.
    pub report: CoarseReport,
    /// Progressive radiosity's ambient term for what the last coarse solve left unsolved
    /// ([`System::ambient_term`]), irradiance, lux.
    pub ambient: Vec3,
}

/// Bytes the hierarchical solve holds at its peak beside the nodes and the hit mapper, for `nodes`
/// nodes, `page_texels` page texels and `triangles` triangles: the largest of its phases. The
/// coarse level holds the cells of every node (8 bytes: its cell and its place in the cell order),
/// the links between neighbouring nodes (1), the fine exitance its oracle reads (12), the transient
/// of a split (the cells and the sort order, 28) and its matrix (at most
/// [`solve::COARSE_BYTES_PER_NODE`]); the final gather the exitance (12), its pilot's light and
/// error and the rest's (16 each), each node's rays (4) and the exitance grid, less than the
/// correction; the correction holds the exitance, the gathered light, the missed light and its
/// result (12 each), the two gathers' standard errors (4 each) and the exitance grid
/// ([`ExitanceGrid`]); the reflection of the correction the same with the reflected field and its
/// result (12 each), and which nodes lie near geometry (1); the error estimate the exitance, the
/// gathered, missed and corrected light, the correction and its reflection (12 each) and the nodes'
/// errors (4).
pub fn planned_bytes(nodes: usize, page_texels: u64, triangles: usize) -> u64 {
    let n = nodes as u64;
    let clusters = 8 * n;
    let grid = page_texels * ExitanceGrid::BYTES_PER_PAGE_TEXEL
        + triangles as u64 * ExitanceGrid::BYTES_PER_TRIANGLE;
    let coarse = clusters + (1 + 12 + 28 + solve::COARSE_BYTES_PER_NODE) * n;
    let correction = clusters + (4 * 12 + 2 * 4) * n + grid;
    let reflection = clusters + (6 * 12 + 2 * 4 + 1) * n + grid;
    let estimate = clusters + (6 * 12 + 4) * n;
    coarse.max(correction).max(reflection).max(estimate)
}

/// Most refinement rounds (each takes a cell at most one level down).
const MAX_ROUNDS: u32 = 4;

/// One field's coarse solve over the current cut.
pub(super) struct FieldSolve {
    pub(super) solution: Solution,
    pub(super) ambient: Vec3,
    /// The fine exitance the oracle reads.
    b: Vec<Vec3>,
    /// RMS luminance of H_d + C, lux.
    value_rms: f64,
}

/// Builds, solves and refines the coarse level for one or several fields at once: `directs[f]`
/// is field f's direct irradiance per patch (light groups: each group's own). The cells' rows and
/// the oracle's gathers are traced once and read in every field; each field solves its own
/// coarse system over the shared matrix. A cell is split by its missed detail summed over the
/// fields, each over its own target (so a dim field's detail counts as much as a bright
/// one's), and refinement goes on until every field's missed detail is within the tolerance.
/// With one field, its own refinement (see the module docs). Gives each field's level, its
/// cut the same (each report's rays are the shared rays), and the last round's matrix and
/// first bounce (what a later bake keeps: [`super::coarse_kept`]).
pub fn coarse_solve_fields(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    directs: &[&[Vec3]],
    options: &HierarchyOptions,
    progress: &Progress,
) -> (Vec<Coarse>, coarse::CoarseRows) {
    let total_area: f64 = nodes.area.iter().map(|&a| a as f64).sum();
    let links = Links::new(ctx, nodes);
    let mut clusters = Clusters::at_level(nodes, ctx.patches, &links, options.top_level);
    let mut rays = links.rays;
    let mut round = 0;
    loop {
        round += 1;
        let coarse::CoarseRows {
            matrix,
            first_bounce,
        } = coarse::build(
            ctx,
            mapper,
            nodes,
            &clusters,
            options.cell_rays,
            directs,
            progress,
        );
        rays += matrix.rays;
        let solved: Vec<FieldSolve> = (directs.iter().zip(&first_bounce))
            .map(|(direct, first)| field_solve(nodes, direct, &clusters, &matrix, first, options))
            .collect();
        // A cancelled bake measures nothing more (the caller returns the cancel).
        let (detail, oracle_rays) = if progress.is_cancelled() {
            (vec![vec![0.0; clusters.len()]; directs.len()], 0)
        } else {
            let bs: Vec<&[Vec3]> = solved.iter().map(|f| f.b.as_slice()).collect();
            coarse::missed_detail(ctx, mapper, nodes, &clusters, &bs, options.cell_rays)
        };
        rays += oracle_rays;
        let relative = |power: f64, value_rms: f64| {
            if value_rms > 0.0 && total_area > 0.0 {
                (power / total_area).sqrt() / value_rms
            } else {
                0.0
            }
        };
        let remaining: Vec<f64> = detail.iter().map(|d| d.iter().sum()).collect();
        let targets: Vec<f64> = (solved.iter())
            .map(|f| (options.tolerance * f.value_rms).powi(2) * total_area)
            .collect();
        // The field furthest over its target names the missed detail.
        let worst = (0..directs.len())
            .map(|f| relative(remaining[f], solved[f].value_rms))
            .fold(0.0f64, f64::max);
        let bytes_per_cell = matrix.bytes() as f64 / clusters.len().max(1) as f64;
        let max_cells =
            ((options.max_matrix_bytes as f64 / bytes_per_cell.max(1.0)) as usize).min(nodes.len());
        let within = remaining.iter().zip(&targets).all(|(r, t)| r <= t);
        let stop = if within {
            Some(format!(
                "missed detail {:.2}% within the tolerance {:.2}%",
                100.0 * worst,
                100.0 * options.tolerance
            ))
        } else if round >= MAX_ROUNDS {
            Some(format!("{MAX_ROUNDS} rounds"))
        } else {
            None
        };
        let picked = if stop.is_none() {
            pick(&clusters, &detail, &targets, max_cells)
        } else {
            Vec::new()
        };
        let stop = stop.or_else(|| {
            picked.is_empty().then(|| {
                if clusters.cells.iter().all(|c| c.level == 0) {
                    "every cell is one texel".to_string()
                } else {
                    format!(
                        "the coarse matrix reached its cap of {:.0} MiB ({max_cells} cells)",
                        options.max_matrix_bytes as f64 / 1048576.0
                    )
                }
            })
        });
        if let Some(stop_reason) = stop {
            let last = solved.len().saturating_sub(1);
            let matrix_entries = matrix.nnz();
            let matrix_bytes = matrix.bytes();
            let levels = (solved.into_iter().zip(remaining).enumerate())
                .map(|(f, (field, remaining))| {
                    let report = CoarseReport {
                        cells: clusters.len(),
                        cells_per_level: clusters.levels(),
                        rounds: round,
                        matrix_entries,
                        matrix_bytes,
                        missed_detail: relative(remaining, field.value_rms),
                        stop_reason: stop_reason.clone(),
                        solver: field.solution.solver,
                        rays,
                    };
                    // The last field takes the cut; the others a copy of it.
                    let clusters = if f == last {
                        std::mem::take(&mut clusters)
                    } else {
                        clusters.clone()
                    };
                    Coarse {
                        clusters,
                        solution: field.solution,
                        report,
                        ambient: field.ambient,
                    }
                })
                .collect();
            let rows = coarse::CoarseRows {
                matrix,
                first_bounce,
            };
            return (levels, rows);
        }
        let mut split = vec![false; clusters.len()];
        for c in picked {
            split[c] = true;
        }
        clusters = clusters.split(nodes, ctx.patches, &links, &split);
    }
}

/// The coarse system of one field over `matrix` (its first bounce `first_bounce` per cell),
/// solved: C = E₁ + F·(ρ∘C), and what the oracle reads of it.
pub(super) fn field_solve(
    nodes: &Nodes,
    direct: &[Vec3],
    clusters: &Clusters,
    matrix: &solve::transport::Transport,
    first_bounce: &[Vec3],
    options: &HierarchyOptions,
) -> FieldSolve {
    // C = E₁ + F·(ρ∘C): with B' = ρ∘C the system B' = ρ∘E₁ + ρ∘(F·B').
    let source: Vec<Vec3> = first_bounce
        .iter()
        .zip(&clusters.albedo)
        .map(|(e, r)| *e * *r)
        .collect();
    let system = System {
        transport: matrix,
        albedo: &clusters.albedo,
        source: &source,
        area: &clusters.area,
        progress: None,
    };
    let max_albedo = system.max_albedo();
    let (choice, _) = solve::choose(clusters.len(), max_albedo, |_| true);
    let solve_options = SolveOptions {
        tolerance: residual_tolerance(options.solver_tolerance, max_albedo),
        max_iterations: options.max_iterations,
    };
    let mut solution = solve::solve_matrix(choice, &system, &solve_options);
    let ambient = system.ambient_term(&solve::to_f64(&solution.b));
    for (c, e) in solution.indirect.iter_mut().zip(first_bounce) {
        *c += *e;
    }
    let b = fine_exitance(nodes, direct, clusters, &solution.indirect);
    let value_rms = irradiance_rms(nodes, direct, clusters, &solution.indirect);
    FieldSolve {
        solution,
        ambient,
        b,
        value_rms,
    }
}

/// The cells to split: those carrying the most missed detail (`detail[field][cell]`, each
/// field's over its target), largest first, until every field's rest is within its target
/// (`targets[field]`) or the cut would exceed `max_cells` (a split adds up to three).
/// A split is counted as removing three quarters of a cell's detail: the variance of a
/// smooth field over a cell falls with the square of its size, so its four children keep
/// about a quarter of it between them.
fn pick(clusters: &Clusters, detail: &[Vec<f64>], targets: &[f64], max_cells: usize) -> Vec<usize> {
    // Each field's detail over its target, relative to the first field with a target: with
    // one field, its own detail.
    let reference = targets.iter().copied().find(|&t| t > 0.0).unwrap_or(1.0);
    let weight: Vec<f64> = (targets.iter())
        .map(|&t| if t > 0.0 { reference / t } else { 0.0 })
        .collect();
    let key: Vec<f64> = (0..clusters.len())
        .map(|c| (detail.iter().zip(&weight)).map(|(d, w)| d[c] * w).sum())
        .collect();
    let mut order: Vec<usize> = (0..clusters.len())
        .filter(|&c| key[c] > 0.0 && clusters.cells[c].level > 0)
        .collect();
    order.sort_by(|&a, &b| key[b].total_cmp(&key[a]).then(a.cmp(&b)));
    let mut remaining: Vec<f64> = detail.iter().map(|d| d.iter().sum()).collect();
    let mut cells = clusters.len();
    let mut picked = Vec::new();
    for c in order {
        let within = remaining.iter().zip(targets).all(|(r, t)| r <= t);
        if within || cells + 3 > max_cells {
            break;
        }
        for (r, d) in remaining.iter_mut().zip(detail) {
            *r -= 0.75 * d[c];
        }
        cells += 3;
        picked.push(c);
    }
    picked
}

/// Per node: b_j = ρ_j·(H_d,j + C_{cell(j)}), the exitance the final gather reads (`direct`
/// per patch).
pub fn fine_exitance(
    nodes: &Nodes,
    direct: &[Vec3],
    clusters: &Clusters,
    cell_indirect: &[Vec3],
) -> Vec<Vec3> {
    (0..nodes.len())
        .map(|i| {
            let h = direct[nodes.patch[i] as usize];
            nodes.albedo[i] * (h + cell_indirect[clusters.of_node[i] as usize])
        })
        .collect()
}

/// Area-weighted RMS luminance of H_d + C over the nodes, lux (`direct` per patch).
fn irradiance_rms(
    nodes: &Nodes,
    direct: &[Vec3],
    clusters: &Clusters,
    cell_indirect: &[Vec3],
) -> f64 {
    let (mut sum, mut area) = (0.0f64, 0.0f64);
    for i in 0..nodes.len() {
        let d = direct[nodes.patch[i] as usize];
        let h = luminance(d + cell_indirect[clusters.of_node[i] as usize]) as f64;
        sum += nodes.area[i] as f64 * h * h;
        area += nodes.area[i] as f64;
    }
    if area > 0.0 { (sum / area).sqrt() } else { 0.0 }
}

/// Which gather [`final_gather`] makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gather {
    /// H₁ = F̂·ρ(H_d + C): the rays of the full matrix's rows.
    Final,
    /// Δ = F̂'·ρ(H₁ − C): the correction, with rays of their own.
    Correction,
    /// Δ₂ = F̂''·ρΔ: the correction's own reflection, with rays of their own (at nodes near
    /// geometry, see the module docs).
    Reflection,
}

/// Random-number stream of the correction gather.
const STREAM_CORRECTION: u32 = 230;

/// What a gather over every node traced.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GatherRays {
    /// Closest-hit rays: the gather's own.
    pub closest: u64,
    /// Any-hit rays: the visibility tests of start points near geometry.
    pub visibility: u64,
}

/// A gather from exitance `b` with the rays `rays(i)` of node i's sequence at every node (or
/// those `only` marks; a node with no rays is left out): the final gather H₁ (or a range of
/// its rays, see [`super::ray_allocation`]), the correction Δ or its reflection Δ₂ (see the
/// module docs). Returns the irradiance per node (zero at nodes left out), its standard error
/// (luminance, lux; [`monte_carlo::gather`]) and the rays traced.
#[allow(clippy::too_many_arguments)]
pub fn final_gather(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    rays: &(dyn Fn(usize) -> Range<u32> + Sync),
    which: Gather,
    only: Option<&[bool]>,
    progress: &Progress,
) -> (Vec<Vec3>, Vec<f32>, GatherRays) {
    let (mut fields, traced) =
        final_gather_fields(ctx, mapper, nodes, &[b], rays, which, only, progress);
    let (out, error) = fields.pop().expect("one field");
    (out, error, traced)
}

/// One field's gather: the irradiance per node (lux) and its standard error (luminance, lux).
pub type GatheredField = (Vec<Vec3>, Vec<f32>);

/// [`final_gather`] of several fields `bs` at once, each ray traced once and read in every
/// field (the light groups' shared transport): per field, the irradiance per node and its
/// standard error.
#[allow(clippy::too_many_arguments)]
pub fn final_gather_fields(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    bs: &[&[Vec3]],
    rays: &(dyn Fn(usize) -> Range<u32> + Sync),
    which: Gather,
    only: Option<&[bool]>,
    progress: &Progress,
) -> (Vec<GatheredField>, GatherRays) {
    let stream = match which {
        Gather::Final => STREAM_TRANSPORT,
        Gather::Correction => STREAM_CORRECTION,
        Gather::Reflection => STREAM_CORRECTION + 1,
    };
    let grids: Vec<ExitanceGrid<'_>> = bs.iter().map(|b| ExitanceGrid::new(mapper, b)).collect();
    let grids: Vec<&ExitanceGrid<'_>> = grids.iter().collect();
    let k = bs.len();
    let (visibility, closest) = (AtomicU64::new(0), AtomicU64::new(0));
    // Node i's samples into `out`, one per field (left at zero where it is not gathered).
    let sample_at = |i: usize, out: &mut [GatherSample]| {
        if progress.is_cancelled() || only.is_some_and(|o| !o[i]) {
            return;
        }
        let range = rays(i);
        if range.is_empty() {
            progress.advance(1);
            return;
        }
        closest.fetch_add(range.len() as u64, Ordering::Relaxed);
        monte_carlo::gather_fields(ctx, mapper, nodes, i, range, stream, &grids, out);
        visibility.fetch_add(out[0].visibility, Ordering::Relaxed);
        progress.advance(1);
    };
    let fields: Vec<GatheredField> = if k == 1 {
        // One field straight into its two vectors: nothing per node beside them.
        let one = (0..nodes.len())
            .into_par_iter()
            .with_min_len(64)
            .map(|i| {
                let mut out = [GatherSample::default()];
                sample_at(i, &mut out);
                (out[0].h, out[0].se)
            })
            .unzip();
        vec![one]
    } else {
        let mut flat = vec![GatherSample::default(); nodes.len() * k];
        flat.par_chunks_mut(k.max(1))
            .with_min_len(64)
            .enumerate()
            .for_each(|(i, out)| sample_at(i, out));
        (0..k)
            .map(|f| {
                (flat.iter().skip(f).step_by(k))
                    .map(|g| (g.h, g.se))
                    .unzip()
            })
            .collect()
    };
    let traced = GatherRays {
        closest: closest.into_inner(),
        visibility: visibility.into_inner(),
    };
    (fields, traced)
}

/// The reflected irradiance per node, H₁ + Δ, each channel held at zero or above, and how many
/// nodes were. The correction's rays are not the final gather's, so where the coarse level
/// overstates a dark corner's light a few correction rays can take more than the gather
/// found; the true value is never negative, so holding it at zero only moves it closer.
pub fn corrected(gathered: &[Vec3], correction: &[Vec3]) -> (Vec<Vec3>, usize) {
    let mut clamped = 0;
    let out = gathered
        .iter()
        .zip(correction)
        .map(|(h, d)| {
            let v = *h + *d;
            clamped += usize::from(v.min_element() < 0.0);
            v.max(Vec3::ZERO)
        })
        .collect();
    (out, clamped)
}

/// Per node: ρ_j·(H₁,j − C_{cell(j)}), what the correction gathers: the light the coarse
/// level missed at its second bounce, reflected.
pub fn missed_exitance(nodes: &Nodes, gathered: &[Vec3], coarse_per_node: &[Vec3]) -> Vec<Vec3> {
    (0..nodes.len())
        .map(|i| nodes.albedo[i] * (gathered[i] - coarse_per_node[i]))
        .collect()
}
