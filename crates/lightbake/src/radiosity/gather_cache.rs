//! Irradiance caching in the final gather: the gather made at a sparse set of texel nodes
//! (the cache's *records*) and interpolated between them where the cache can tell the light
//! varies smoothly (Ward, Rubinstein & Clear, "A ray tracing solution for diffuse
//! interreflection", SIGGRAPH 1988). The records are placed by a quadtree over the texel
//! grid, not by Ward's octree over space, so interpolation follows the lightmap's own
//! reconstruction and never leaves a chart.
//!
//! Each lightmap page is cut into square cells of [`CacheOptions::spacing`] texels. A cell is
//! a **candidate** when, its edges included:
//!
//! 1. at least two of its four corner texels are nodes, all of one chart, and every other
//!    texel is either outside every chart or a node of that chart (a texel under geometry,
//!    an invalid patch, stops it).
//!
//! A candidate's corners are gathered (rays `0..R` of each node's final-gather sequence, as
//! the dense gather traces), and the cell is **interpolated** (the bilinear weights of its
//! corners, renormalised over those present, at every texel inside: the reconstruction the
//! GPU makes between texels) when also:
//!
//! 2. **Ward's error bound** holds at each corner k for the farthest texel of the cell:
//!    d/R_k + √(1 − n_k·n_l) ≤ a, with d the cell's diagonal (m), R_k the harmonic mean
//!    distance of the corner's rays to the surfaces they hit (the radius over which the
//!    irradiance can change by its own size; Ward et al. 1988, eq. 4), n the corners' shading
//!    normals and a [`CacheOptions::accuracy`];
//! 3. the corners' light agrees: each corner's luminance is within
//!    [`CacheOptions::spread`] of their mean, beyond twice its own standard error, so a
//!    shadow edge of the reflected light between two corners (which the distances do not
//!    see) splits the cell.
//!
//! In an interpolated cell, the nodes whose support geometry cuts or whose texel lies under
//! geometry (`Nodes::split`, `Nodes::sliver`: contacts) and the texels whose present corners
//! weigh under [`MIN_WEIGHT`] are gathered as records of their own. A cell that fails is cut
//! into four cells of half its edge, whose new corners are gathered in their turn; cells of
//! one texel are all corners, so every node is either gathered or interpolated. A texel on
//! the edge of two interpolated cells takes the smaller cell's value (the one nearer
//! records), and the top cell first in (page, row, column) order between equals. Every
//! decision reads only the records of its own cell, and the cells containing a node are all
//! refined when the node is asked for, so a node's value does not depend on which others a
//! process computes: a split bake's shards and a subset run give the bits of the whole bake.
//!
//! An interpolated node's standard error is that of the weighted corners,
//! √(Σ w_k²·se_k²). The hierarchical solve's error estimate re-gathers sampled nodes,
//! interpolated ones among them ([`super::error_estimate::hierarchical_error`]), but the
//! denoiser and the estimate after it read these per-texel errors, which take the corners'
//! noise as independent where it is shared across the cell: on the Cornell box the estimate
//! is 0.68× the measured error with the cache (docs/benchmarks.md), and the dense gather is
//! the default.

use std::collections::BTreeSet;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::exitance_grid::ExitanceGrid;
use super::hit_mapper::HitMapper;
use super::monte_carlo::{self, GatherSample, STREAM_TRANSPORT};
use super::nodes::Nodes;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;

/// [`CacheOptions::spread`] of the bake: a corner a tenth off its cell's mean splits it.
pub const SPREAD: f32 = 0.1;

/// How the cache places its records (`RadiositySettings::cache_spacing`,
/// `RadiositySettings::cache_accuracy`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CacheOptions {
    /// Edge of the first cells, texels (a power of two ≥ 2): at most one record per
    /// spacing² texels where the light is smooth.
    pub spacing: u32,
    /// Ward's a: the largest d/R + √(1 − n·n') over a cell (module docs, test 2).
    pub accuracy: f32,
    /// Largest relative difference of a corner's luminance from the corners' mean, beyond
    /// their noise (module docs, test 3).
    pub spread: f32,
}

/// The cache's result over the nodes it was asked for.
#[derive(Clone, Debug, Default)]
pub struct Cached {
    /// H₁ per node, lux (zero at nodes not asked for).
    pub light: Vec<Vec3>,
    /// Its standard error per node (luminance, lux).
    pub error: Vec<f32>,
    /// Records gathered, per cell edge: `(edge in texels, records)`, the first cells first.
    pub records: Vec<(u32, u64)>,
    /// Nodes asked for that were interpolated.
    pub interpolated: u64,
    /// Closest-hit rays traced (the records' gathers).
    pub closest: u64,
    /// Any-hit rays traced (visibility of start points near geometry).
    pub visibility: u64,
}

impl Cached {
    /// Records gathered in all.
    pub fn record_count(&self) -> u64 {
        self.records.iter().map(|r| r.1).sum()
    }
}

/// A cell of the quadtree: page, top-left texel and edge (texels).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Cell {
    page: u32,
    y: u32,
    x: u32,
    edge: u32,
}

/// The final gather H₁ from exitance `b` through the cache: `rays` rays per record, at the
/// nodes `only` marks (`None`: every node).
#[allow(clippy::too_many_arguments)]
pub fn cached_gather(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    rays: u32,
    options: CacheOptions,
    only: Option<&[bool]>,
    progress: &Progress,
) -> Cached {
    let n = nodes.len();
    let lattice = Lattice { ctx, nodes };
    let grid = ExitanceGrid::new(mapper, b);
    let mut record: Vec<Option<GatherSample>> = vec![None; n];
    let mut out = Cached {
        light: vec![Vec3::ZERO; n],
        error: vec![0.0; n],
        ..Cached::default()
    };
    let (closest, visibility) = (AtomicU64::new(0), AtomicU64::new(0));
    let mut cells = lattice.top_cells(options.spacing, only);
    let mut leaves: Vec<(Cell, Corners)> = Vec::new();
    let gather = |new: &[usize]| -> Vec<GatherSample> {
        new.par_iter()
            .with_min_len(16)
            .map(|&i| {
                let g =
                    monte_carlo::gather(ctx, mapper, nodes, i, 0..rays, STREAM_TRANSPORT, &grid);
                closest.fetch_add(rays as u64, Ordering::Relaxed);
                visibility.fetch_add(g.visibility, Ordering::Relaxed);
                g
            })
            .collect()
    };
    // Gathers the nodes of `at` not yet records, each once, in node order; how many.
    let add = |record: &mut Vec<Option<GatherSample>>, at: BTreeSet<usize>| {
        let new: Vec<usize> = at.into_iter().filter(|&i| record[i].is_none()).collect();
        for (&i, g) in new.iter().zip(gather(&new)) {
            record[i] = Some(g);
        }
        new.len() as u64
    };
    while !cells.is_empty() && !progress.is_cancelled() {
        let edge = cells[0].edge;
        // Cells of one chart with no texel under geometry are candidates, whose corners are
        // gathered; the rest are quartered at once (at one texel, every corner is gathered).
        let (candidates, rest): (Vec<_>, Vec<_>) = cells
            .into_iter()
            .map(|c| (c, lattice.uniform(&c)))
            .partition(|(_, corners)| corners.is_some());
        let corners_of: BTreeSet<usize> = if edge > 1 {
            candidates
                .iter()
                .flat_map(|(_, k)| k.expect("a candidate"))
                .flatten()
                .collect()
        } else {
            rest.iter()
                .flat_map(|(c, _)| lattice.corners(c))
                .flatten()
                .collect()
        };
        let mut count = add(&mut record, corners_of);
        let mut next = Vec::new();
        let mut passed = Vec::new();
        for (c, corners) in candidates.into_iter().chain(rest) {
            match corners {
                Some(k) if edge > 1 && smooth(&lattice, (edge, k), &record, &options) => {
                    passed.push((c, k));
                }
                _ if edge > 1 => next.extend(lattice.quarters(&c)),
                _ => {}
            }
        }
        // The texels of a passing cell too far from its gathered corners are records too.
        let far: BTreeSet<usize> = passed
            .iter()
            .flat_map(|(c, k)| {
                lattice
                    .texels(c)
                    .filter(|&(i, x, y)| lattice.cut(i) || weights(c, *k, x, y).is_none())
                    .map(|(i, _, _)| i)
            })
            .collect();
        count += add(&mut record, far);
        leaves.extend(passed);
        out.records.push((edge, count));
        cells = next;
    }
    // Records keep their own gather; the rest take the smallest interpolated cell around them.
    for (i, r) in record.iter().enumerate() {
        if let Some(g) = r {
            (out.light[i], out.error[i]) = (g.h, g.se);
        }
    }
    leaves.sort_by_key(|(c, _)| (c.edge, *c));
    let mut done: Vec<bool> = record.iter().map(Option::is_some).collect();
    for (c, k) in &leaves {
        for (i, x, y) in lattice.texels(c) {
            if done[i] {
                continue;
            }
            done[i] = true;
            let w = weights(c, *k, x, y).expect("texels without weights are records");
            let corner =
                |j: usize| record[k[j].expect("weighted corners are nodes")].expect("gathered");
            let present = (0..4).filter(|&j| w[j] > 0.0);
            out.light[i] = present
                .clone()
                .fold(Vec3::ZERO, |s, j| s + corner(j).h * w[j]);
            out.error[i] = present
                .map(|j| (w[j] * corner(j).se).powi(2))
                .sum::<f32>()
                .sqrt();
            if only.is_none_or(|o| o[i]) {
                out.interpolated += 1;
            }
        }
    }
    let asked = only.map_or(n as u64, |o| o.iter().filter(|&&m| m).count() as u64);
    progress.advance(asked);
    out.closest = closest.into_inner();
    out.visibility = visibility.into_inner();
    out
}

/// The nodes on the lightmap pages' texel grid.
struct Lattice<'a> {
    ctx: &'a BakeContext<'a>,
    nodes: &'a Nodes,
}

impl Lattice<'_> {
    /// The node at texel (x, y) of page `page`, if that texel is one.
    fn node(&self, page: u32, x: u32, y: u32) -> Option<usize> {
        let size = self.ctx.layout.pages[page as usize];
        if x >= size.width || y >= size.height {
            return None;
        }
        let patch = self.ctx.patches.page_index[page as usize][(y * size.width + x) as usize];
        if patch == u32::MAX {
            return None;
        }
        let node = self.nodes.of_patch[patch as usize];
        (node != u32::MAX).then_some(node as usize)
    }

    /// The cells of edge `spacing` that contain (edges included) a node `only` marks, in
    /// (page, row, column) order.
    fn top_cells(&self, spacing: u32, only: Option<&[bool]>) -> Vec<Cell> {
        let mut cells = BTreeSet::new();
        for (i, &pi) in self.nodes.patch.iter().enumerate() {
            if only.is_some_and(|o| !o[i]) {
                continue;
            }
            let p = &self.ctx.patches.patches[pi as usize];
            let starts = |v: u32| {
                let s = v / spacing * spacing;
                [
                    Some(s),
                    (v.is_multiple_of(spacing) && v > 0).then(|| v - spacing),
                ]
            };
            for y in starts(p.y).into_iter().flatten() {
                for x in starts(p.x).into_iter().flatten() {
                    cells.insert(Cell {
                        page: p.page,
                        y,
                        x,
                        edge: spacing,
                    });
                }
            }
        }
        cells.into_iter().collect()
    }

    /// The cell's four corners (top-left, top-right, bottom-left, bottom-right), as nodes.
    fn corners(&self, c: &Cell) -> [Option<usize>; 4] {
        let (x1, y1) = (c.x + c.edge, c.y + c.edge);
        [(c.x, c.y), (x1, c.y), (c.x, y1), (x1, y1)].map(|(x, y)| self.node(c.page, x, y))
    }

    /// The cell's nodes (edges included) with their texels; texels that are no node left out.
    fn texels<'s>(&'s self, c: &Cell) -> impl Iterator<Item = (usize, u32, u32)> + 's {
        let c = *c;
        (c.y..=c.y + c.edge).flat_map(move |y| {
            (c.x..=c.x + c.edge).filter_map(move |x| self.node(c.page, x, y).map(|i| (i, x, y)))
        })
    }

    /// The four cells of half `c`'s edge that hold a node.
    fn quarters(&self, c: &Cell) -> Vec<Cell> {
        let h = c.edge / 2;
        [(0, 0), (h, 0), (0, h), (h, h)]
            .into_iter()
            .map(|(dx, dy)| Cell {
                x: c.x + dx,
                y: c.y + dy,
                edge: h,
                ..*c
            })
            .filter(|q| self.texels(q).next().is_some())
            .collect()
    }

    /// Cell `c`'s corners when it may be interpolated as far as the texel grid can tell
    /// (module docs, test 1): an edge of two texels or more, two corners or more that are
    /// nodes of one chart, and every texel of the cell either outside every chart or a node
    /// of that chart (a texel under geometry, an invalid patch, fails it).
    fn uniform(&self, c: &Cell) -> Option<Corners> {
        if c.edge < 2 {
            return None;
        }
        let corners = self.corners(c);
        if corners.iter().flatten().count() < 2 {
            return None;
        }
        let patches = &self.ctx.patches.patches;
        let patch = |i: usize| &patches[self.nodes.patch[i] as usize];
        let first = corners.into_iter().flatten().next()?;
        let chart = (patch(first).instance, patch(first).chart);
        let size = self.ctx.layout.pages[c.page as usize];
        let index = &self.ctx.patches.page_index[c.page as usize];
        let open = |x: u32, y: u32| {
            if x >= size.width || y >= size.height {
                return true;
            }
            let pi = index[(y * size.width + x) as usize];
            if pi == u32::MAX {
                return true;
            }
            let i = self.nodes.of_patch[pi as usize];
            if i == u32::MAX {
                return false;
            }
            let p = patch(i as usize);
            (p.instance, p.chart) == chart
        };
        (c.y..=c.y + c.edge)
            .all(|y| (c.x..=c.x + c.edge).all(|x| open(x, y)))
            .then_some(corners)
    }

    /// Whether geometry cuts node `i`'s support, or its texel lies under geometry: such a
    /// node is a record of its own, never interpolated.
    fn cut(&self, i: usize) -> bool {
        self.nodes.split.get(i).copied().unwrap_or(false)
            || self.nodes.sliver.get(i).copied().unwrap_or(false)
    }

    /// The world distance across a cell of edge `edge` texels at node `i`, m.
    fn diagonal(&self, i: usize, edge: u32) -> f32 {
        let p = &self.ctx.patches.patches[self.nodes.patch[i] as usize];
        edge as f32 * std::f32::consts::SQRT_2 * p.texel_size
    }
}

/// The nodes at a cell's corners (top-left, top-right, bottom-left, bottom-right), three or
/// four of them present.
type Corners = [Option<usize>; 4];

/// Least weight of a cell's present corners at a texel for it to be interpolated: nearer a
/// missing corner than this, the texel is a record of its own.
pub const MIN_WEIGHT: f32 = 0.25;

/// The bilinear weights of cell `c`'s corners `k` at texel (x, y), renormalised over the
/// corners present (zero at the missing one); `None` when they weigh under [`MIN_WEIGHT`].
fn weights(c: &Cell, k: Corners, x: u32, y: u32) -> Option<[f32; 4]> {
    let (fx, fy) = (
        (x - c.x) as f32 / c.edge as f32,
        (y - c.y) as f32 / c.edge as f32,
    );
    let mut w = [
        (1.0 - fx) * (1.0 - fy),
        fx * (1.0 - fy),
        (1.0 - fx) * fy,
        fx * fy,
    ];
    for (wj, kj) in w.iter_mut().zip(k) {
        if kj.is_none() {
            *wj = 0.0;
        }
    }
    let sum: f32 = w.iter().sum();
    (sum >= MIN_WEIGHT).then(|| w.map(|wj| wj / sum))
}

/// Whether a uniform cell of edge `edge` with corners `corners` may be interpolated from
/// their records (module docs, tests 2 and 3).
fn smooth(
    lattice: &Lattice<'_>,
    (edge, corners): (u32, Corners),
    record: &[Option<GatherSample>],
    o: &CacheOptions,
) -> bool {
    let present: Vec<usize> = corners.into_iter().flatten().collect();
    let g: Vec<GatherSample> = present
        .iter()
        .map(|&i| record[i].expect("a candidate's corners are gathered"))
        .collect();
    let normal = |i: usize| lattice.ctx.patches.patches[lattice.nodes.patch[i] as usize].normal;
    for (k, &i) in present.iter().enumerate() {
        let bend = present
            .iter()
            .map(|&j| normal(i).dot(normal(j)))
            .fold(1.0f32, f32::min);
        let ward = lattice.diagonal(i, edge) / g[k].distance + (1.0 - bend).max(0.0).sqrt();
        if ward.is_nan() || ward > o.accuracy {
            return false;
        }
    }
    let l: Vec<f32> = g.iter().map(|s| luminance(s.h)).collect();
    let mean = l.iter().sum::<f32>() / l.len() as f32;
    l.iter()
        .zip(&g)
        .all(|(&lk, s)| (lk - mean).abs() <= o.spread * mean + 2.0 * s.se)
}
