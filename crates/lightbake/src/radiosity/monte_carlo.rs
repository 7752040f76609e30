//! Form factors by Monte Carlo (Galerkin): row i of F from `rays` rays per node, started at
//! points of the node's basis support ([`super::support`]) and cosine-distributed about the
//! surface there, stratified by Owen-scrambled (0,2)-sequences. Row i holds, for every node j,
//! the importance-weighted mean basis weight of node j at the rays' hits, so the irradiance at
//! node i from reflected light is H_i = Σ_j F_ij·B_j. Duplicate targets are merged; weights are
//! f32 and columns u32. [`estimate_bytes`] traces a pilot sample of rows first so the memory
//! can be checked against a budget before the matrix is built.
//!
//! Rays that leave the scene escape (the sky is direct light, not part of F); rays that hit
//! the back of a single-sided surface see the inside of a solid, which is black.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::exitance_grid::ExitanceGrid;
use super::hit_mapper::HitMapper;
use super::nodes::Nodes;
use super::support::{SupportFrame, support_point};
use crate::bvh::Hit;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::raster::SurfacePoint;
use crate::sampling::{Sobol02, cosine_hemisphere};
use crate::settings::Basis;
use crate::solve::transport::{RowBlock, Transport};

/// Random-number stream of the transport rays and of the final gather (mixed into a texel's
/// key): a texel's final-gather rays are the rays of its matrix row.
pub(super) const STREAM_TRANSPORT: u32 = 200;

/// Rows the Monte Carlo build makes before packing them into the matrix.
const BUILD_BLOCK_ROWS: usize = 16_384;

/// Where one transport ray ended.
pub(super) enum RayEnd {
    /// It pointed below the surface: no light arrives from there.
    Below,
    /// It left the scene.
    Escaped,
    /// It hit a surface (front or back).
    Hit(Hit),
}

/// The rays of one row of Monte Carlo transport: rays `rays` of node `i`'s sequence (`0..n`
/// for a row of n rays), from points of its basis support (from its representative point
/// when it is a [`Nodes::sliver`], or when no support point of the range is open),
/// cosine-distributed about the surface there, numbered by random-number `stream`. Calls
/// `f(weight, end, k)` for every start point, `k` the ray's index in the node's sequence.
/// Returns the visibility rays the start points took (see [`support_point`]).
#[inline]
pub(super) fn for_each_ray(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: Range<u32>,
    stream: u32,
    mut f: impl FnMut(f32, RayEnd, u32),
) -> u64 {
    let p = &ctx.patches.patches[nodes.patch[i] as usize];
    let key = p.rng(ctx.settings.seed, stream);
    let (starts, directions) = (Sobol02::new(key), Sobol02::new(key ^ 0x6a09_e667));
    let mut trace = |sp: &SurfacePoint, weight: f32, k: u32| {
        let dir = cosine_hemisphere(sp.normal, directions.point(k));
        if dir.dot(sp.geometric_normal) <= 0.0 {
            f(weight, RayEnd::Below, k);
            return;
        }
        let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
        match ctx.rays.closest_hit(origin, dir, 0.0, f32::INFINITY) {
            None => f(weight, RayEnd::Escaped, k),
            Some(hit) => f(weight, RayEnd::Hit(hit), k),
        }
    };
    let mut started = 0u32;
    let mut visibility = 0u64;
    if !nodes.sliver.get(i).copied().unwrap_or(false) {
        let fast = SupportFrame::new(ctx, mapper, i, p);
        for k in rays.clone() {
            let start = match &fast {
                Some(frame) => frame.point(starts.point(k)),
                None => support_point(ctx, mapper, i, p, k, key, &mut visibility),
            };
            if let Some((sp, weight)) = start {
                started += 1;
                trace(&sp, weight, k);
            }
        }
    }
    if started == 0 {
        let sp = p.representative();
        for k in rays {
            trace(&sp, 1.0, k);
        }
    }
    visibility
}

/// The samples of one row of Monte Carlo transport ([`for_each_ray`]), mapped to nodes:
/// calls `f(weight, hit)` for every start point, with `hit` the nodes and bilinear weights
/// the ray reached (empty when it escaped, was absorbed or pointed below the surface);
/// returns the escaped weight.
pub(super) fn for_each_sample(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: u32,
    stream: u32,
    mut f: impl FnMut(f32, &[(u32, f32)]),
) -> f32 {
    let mut escaped = 0.0f32;
    let mut out = [(0u32, 0f32); 4];
    let _ = for_each_ray(
        ctx,
        mapper,
        nodes,
        i,
        0..rays,
        stream,
        |weight, end, _| match end {
            RayEnd::Below => f(weight, &[]),
            RayEnd::Escaped => {
                escaped += weight;
                f(weight, &[]);
            }
            RayEnd::Hit(hit) => {
                let n = mapper.weights(&hit, &mut out);
                f(weight, &out[..n]);
            }
        },
    );
    escaped
}

/// One row of Monte Carlo transport (see [`for_each_sample`]), self-normalised by
/// the sample weights. Returns the row and its escaped fraction.
fn mc_row(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: u32,
) -> (Vec<(u32, f32)>, f32) {
    let mut rows = RowBlock::default();
    let escaped = mc_row_into(ctx, mapper, nodes, i, rays, &mut Vec::new(), &mut rows);
    (rows.cols.into_iter().zip(rows.vals).collect(), escaped)
}

/// [`mc_row`] appended to `out` (its columns, weights and length), with `scratch`
/// as the row's sort buffer (both reused across rows). Returns the escaped fraction.
fn mc_row_into(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: u32,
    scratch: &mut Vec<u64>,
    out: &mut RowBlock,
) -> f32 {
    // Entries packed as (node << 32 | weight bits): one integer sort orders them by node
    // (weights are non-negative, so their bits order like their values).
    scratch.clear();
    let mut total = 0.0f32;
    let escaped = for_each_sample(
        ctx,
        mapper,
        nodes,
        i,
        rays,
        STREAM_TRANSPORT,
        |weight, hit| {
            total += weight;
            scratch.extend(
                hit.iter()
                    .map(|&(j, wj)| (j as u64) << 32 | (wj * weight).to_bits() as u64),
            );
        },
    );
    let start = out.cols.len();
    if total > 0.0 {
        scratch.sort_unstable();
        for &e in scratch.iter() {
            let (j, v) = ((e >> 32) as u32, f32::from_bits(e as u32));
            if out.cols.len() > start && out.cols.last() == Some(&j) {
                *out.vals.last_mut().expect("a value per column") += v;
            } else {
                out.cols.push(j);
                out.vals.push(v);
            }
        }
        for v in &mut out.vals[start..] {
            *v /= total;
        }
    }
    out.lens.push((out.cols.len() - start) as u32);
    if total > 0.0 { escaped / total } else { 0.0 }
}

/// Node `i`'s gathered irradiance (F·B)ᵢ from exitance `b`, with its row estimated by
/// `rays` rays as [`build`] does, without storing the matrix (lux).
pub fn gather_row(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: u32,
    b: &[Vec3],
) -> Vec3 {
    let (row, _) = mc_row(ctx, mapper, nodes, i, rays);
    row.iter()
        .fold(Vec3::ZERO, |s, &(j, w)| s + b[j as usize] * w)
}

/// Node `i`'s gathered irradiance Σw·B(hit) / Σw from the field on `grid` over rays `rays` of
/// stream `stream` (`0..n`: the rays [`build`] traces for a row of n rays when `stream` is
/// [`STREAM_TRANSPORT`]; a later range continues the same sequence), summed as the rays come,
/// without forming the row (lux): (F·B)ᵢ of the matrix row those rays would make. The final
/// gather of the hierarchical solve.
///
/// Also returns the standard error of its luminance, the visibility rays of the start points
/// and the harmonic mean distance to the surfaces its rays hit. The error comes from
/// [`GATHER_BLOCKS`] blocks of consecutive rays: each block of a (0, 2)-sequence of a
/// power-of-two length is a stratified replicate of the whole, so the spread of the blocks'
/// estimates is the stratified estimator's (the spread of single rays would overstate it); the
/// variance of the mean is the blocks' sample variance / blocks.
pub fn gather(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: Range<u32>,
    stream: u32,
    grid: &ExitanceGrid<'_>,
) -> GatherSample {
    let mut out = [GatherSample::default()];
    gather_fields(ctx, mapper, nodes, i, rays, stream, &[grid], &mut out);
    out[0]
}

/// [`gather`] of several fields at once (`grids`, one sample each into `out`): each ray is
/// traced once and reads every field at its hit, so the fields' estimates share their rays
/// (the light groups' transport, [`super::group_solve`]). Every sample's `visibility` and
/// `distance` are the rays' (the same in all).
#[allow(clippy::too_many_arguments)]
pub fn gather_fields(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: Range<u32>,
    stream: u32,
    grids: &[&ExitanceGrid<'_>],
    out: &mut [GatherSample],
) {
    let k = grids.len();
    let (mut total, mut inverse) = (0.0f32, 0.0f64);
    let mut sums = vec![Vec3::ZERO; k];
    // Per field, per block: (Σw, Σw·luminance).
    let mut blocks = vec![[(0.0f64, 0.0f64); GATHER_BLOCKS]; k];
    let (first, len) = (rays.start, rays.len().max(1));
    let visibility = for_each_ray(ctx, mapper, nodes, i, rays, stream, |weight, end, r| {
        total += weight;
        let block = ((r - first) as usize * GATHER_BLOCKS) / len;
        for b in blocks.iter_mut() {
            b[block].0 += weight as f64;
        }
        if let RayEnd::Hit(hit) = end {
            for ((grid, sum), b) in grids.iter().zip(&mut sums).zip(&mut blocks) {
                let v = grid.at(&hit) * weight;
                *sum += v;
                b[block].1 += luminance(v) as f64;
            }
            inverse += weight as f64 / (hit.t as f64).max(1e-6);
        }
    });
    let distance = if inverse > 0.0 {
        (total as f64 / inverse) as f32
    } else {
        f32::INFINITY
    };
    for ((o, sum), b) in out.iter_mut().zip(&sums).zip(&blocks) {
        *o = GatherSample {
            h: if total > 0.0 {
                *sum / total
            } else {
                Vec3::ZERO
            },
            se: block_error(b),
            visibility,
            distance,
        };
    }
}

/// One node's gather ([`gather`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct GatherSample {
    /// The gathered irradiance, lux.
    pub h: Vec3,
    /// The standard error of its luminance, lux.
    pub se: f32,
    /// Any-hit rays: the visibility tests of its start points.
    pub visibility: u64,
    /// The harmonic mean distance to the surfaces its rays hit (escaped rays count as
    /// infinitely far; `INFINITY` when none hit), m: Ward's record radius
    /// ([`super::gather_cache`]).
    pub distance: f32,
}

/// Blocks of a gather's rays for its error estimate (see [`gather`]).
pub const GATHER_BLOCKS: usize = 4;

/// The standard error of the self-normalised mean Σ(w·v)/Σw from per-block (Σw, Σw·v): the
/// sample variance of the block estimates over the number of blocks (zero with fewer than
/// two blocks that have weight).
fn block_error(blocks: &[(f64, f64)]) -> f32 {
    let estimates: Vec<f64> = blocks
        .iter()
        .filter(|b| b.0 > 0.0)
        .map(|b| b.1 / b.0)
        .collect();
    let n = estimates.len();
    if n < 2 {
        return 0.0;
    }
    let mean = estimates.iter().sum::<f64>() / n as f64;
    let var = estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (var / n as f64).sqrt() as f32
}

/// Luminance of node `i`'s gathered irradiance (F·B)ᵢ from exitance `b`, with its row
/// estimated by `rays` rays as [`build`] does: the self-normalised
/// mean Σw·v / Σw of the luminance v of B at each ray's hit, without forming the row (lux).
pub fn gather_luminance(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    rays: u32,
    b: &[Vec3],
) -> f64 {
    let (mut total, mut weighted) = (0.0f64, 0.0f64);
    for_each_sample(
        ctx,
        mapper,
        nodes,
        i,
        rays,
        STREAM_TRANSPORT,
        |weight, hit| {
            let v: f32 = hit
                .iter()
                .map(|&(j, wj)| wj * luminance(b[j as usize]))
                .sum();
            total += weight as f64;
            weighted += weight as f64 * v as f64;
        },
    );
    if total <= 0.0 { 0.0 } else { weighted / total }
}

/// Estimated bytes of the Monte Carlo matrix: up to 512 evenly spaced rows are traced and
/// their merged lengths extrapolated, × 1.1: the build reserves 1.1× its first block's
/// mean row length.
pub fn estimate_bytes(ctx: &BakeContext<'_>, nodes: &Nodes, rays: u32, basis: Basis) -> u64 {
    let n = nodes.len();
    if n == 0 {
        return 0;
    }
    let mapper = HitMapper::new(*ctx, nodes, basis);
    let pilot = n.min(512);
    let entries: usize = (0..pilot)
        .into_par_iter()
        .map(|k| mc_row(ctx, &mapper, nodes, k * n / pilot, rays).0.len())
        .sum();
    let per_row = entries as f64 / pilot as f64;
    (n as f64 * (per_row * 8.0 * 1.1 + 12.0)) as u64
}

/// Builds F by Monte Carlo with `rays` rays per node (see the module docs).
pub fn build(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    rays: u32,
    basis: Basis,
    progress: &Progress,
) -> Transport {
    let mapper = HitMapper::new(*ctx, nodes, basis);
    let traced = AtomicU64::new(0);
    let n = nodes.len();
    let mut t = Transport::empty(n, basis);
    // Rows are made in blocks and packed as they come, so the per-row vectors of only one
    // block exist next to the packed matrix (all of them at once would double the peak). The
    // first block's mean row length sizes the packed arrays.
    for start in (0..n).step_by(BUILD_BLOCK_ROWS) {
        let end = (start + BUILD_BLOCK_ROWS).min(n);
        // Each task makes a run of rows into flat arrays, reusing its sort buffer.
        let runs: Vec<(RowBlock, Vec<f32>)> = (start..end)
            .into_par_iter()
            .with_min_len(64)
            .fold(
                || (RowBlock::default(), Vec::new(), Vec::new()),
                |(mut rows, mut escaped, mut scratch), i| {
                    if progress.is_cancelled() {
                        rows.lens.push(0);
                        escaped.push(0.0);
                    } else {
                        escaped.push(mc_row_into(
                            ctx,
                            &mapper,
                            nodes,
                            i,
                            rays,
                            &mut scratch,
                            &mut rows,
                        ));
                        traced.fetch_add(rays as u64, Ordering::Relaxed);
                        progress.advance(1);
                    }
                    (rows, escaped, scratch)
                },
            )
            .map(|(rows, escaped, _)| (rows, escaped))
            .collect();
        if start == 0 {
            let block: usize = runs.iter().map(|r| r.0.cols.len()).sum();
            let expected = (block as f64 / (end - start) as f64 * n as f64 * 1.1) as usize;
            t.cols.reserve_exact(expected);
            t.vals.reserve_exact(expected);
        }
        for (rows, escaped) in runs {
            t.push_block(rows, escaped);
        }
    }
    t.cols.shrink_to_fit();
    t.vals.shrink_to_fit();
    t.rays = traced.into_inner();
    t
}
