//! Texel clusters: the elements of the hierarchical solve's coarse level.
//!
//! Every chart of every instance carries a quadtree over its texels: a cell at level k holds
//! the nodes whose page texel (x, y) has the same (x >> k, y >> k), so it covers at most
//! 2ᵏ × 2ᵏ texels, and its four children are the quadrants one level down. A [`Clusters`] is
//! a cut through these trees: every node belongs to exactly one cell of the cut. The coarse
//! solve treats each cell as a patch of uniform reflected exitance (Smits, Arvo & Greenberg
//! 1994 cluster texels into such elements), and [`Clusters::split`] refines the cut where the
//! coarse solution is too coarse (Cohen & Wallace 1993, ch. 8, adaptive subdivision).
//!
//! A cell is one piece of surface: it never spans two charts, and within a quadtree cell the
//! nodes fall into the pieces that geometry leaves connected ([`Links`]): a floor chart that
//! runs under the walls of several rooms gives each room's part of a cell a value of its own,
//! so the light of one room does not reach the next through a shared coarse value.

use glam::Vec3;
use rayon::prelude::*;

use super::nodes::Nodes;
use crate::context::BakeContext;
use crate::raster::{Patch, Patches};

/// One cell of the cut: a quadtree cell of one chart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Cell {
    /// Instance of its texels.
    pub instance: u32,
    /// Chart of its texels within the instance's mesh.
    pub chart: u32,
    /// Level: the cell covers at most 2^level × 2^level texels.
    pub level: u8,
    /// Cell column (page texel x >> level).
    pub x: u32,
    /// Cell row (page texel y >> level).
    pub y: u32,
    /// Which connected piece of the quadtree cell: the smallest node index in it.
    pub part: u32,
}

/// Which neighbouring nodes lie on one connected piece of surface: per node, bit 0 for the
/// node of the next texel along x, bit 1 along y (page texels of the same instance and
/// chart). Texels away from geometry are always linked; texels near geometry only when each
/// representative point sees the other's (no wall between them, a rug's gap on neither or
/// both sides: [`crate::raster::Patch::COVERED`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Links {
    bits: Vec<u8>,
    /// Per page: its width in texels.
    widths: Vec<u32>,
    /// Visibility rays traced.
    pub rays: u64,
}

impl Links {
    /// The links of `nodes`' texels.
    pub fn new(ctx: &BakeContext<'_>, nodes: &Nodes) -> Self {
        let patches = ctx.patches;
        let traced: Vec<(u8, u64)> = (0..nodes.len())
            .into_par_iter()
            .with_min_len(256)
            .map(|i| {
                let p = &patches.patches[nodes.patch[i] as usize];
                let w = ctx.layout.pages[p.page as usize].width;
                let h = ctx.layout.pages[p.page as usize].height;
                let index = &patches.page_index[p.page as usize];
                let (mut bits, mut rays) = (0u8, 0u64);
                for (bit, (x, y)) in [(1u8, (p.x + 1, p.y)), (2u8, (p.x, p.y + 1))] {
                    if x >= w || y >= h {
                        continue;
                    }
                    let pj = index[(y * w + x) as usize];
                    if pj == u32::MAX || nodes.of_patch[pj as usize] == u32::MAX {
                        continue;
                    }
                    let q = &patches.patches[pj as usize];
                    if q.instance != p.instance || q.chart != p.chart {
                        continue;
                    }
                    let near = (p.flags | q.flags) & Patch::NEAR_GEOMETRY != 0;
                    if !near {
                        bits |= bit;
                        continue;
                    }
                    if (p.flags ^ q.flags) & Patch::COVERED != 0 {
                        continue;
                    }
                    rays += 1;
                    let a = ctx.rays.offset(p.position, p.geometric_normal);
                    let b = ctx.rays.offset(q.position, q.geometric_normal);
                    let d = b - a;
                    let len = d.length();
                    if !(len > 0.0 && ctx.rays.occluded(a, d / len, 0.0, len)) {
                        bits |= bit;
                    }
                }
                (bits, rays)
            })
            .collect();
        Self {
            rays: traced.iter().map(|t| t.1).sum(),
            bits: traced.into_iter().map(|t| t.0).collect(),
            widths: ctx.layout.pages.iter().map(|p| p.width).collect(),
        }
    }

    /// The node of the texel (dx, dy) from patch `p`'s on its page, if there is one.
    fn neighbour(&self, patches: &Patches, nodes: &Nodes, p: &Patch, d: (u32, u32)) -> Option<u32> {
        let (x, y) = (p.x + d.0, p.y + d.1);
        let w = self.widths[p.page as usize];
        if x >= w {
            return None;
        }
        let pj = *patches.page_index[p.page as usize].get((y * w + x) as usize)?;
        (pj != u32::MAX)
            .then(|| nodes.of_patch[pj as usize])
            .filter(|&j| j != u32::MAX)
    }
}

/// A cut through the per-chart quadtrees, with each cell's aggregate area, albedo and
/// source.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Clusters {
    /// The cells, ordered by (instance, chart, level, y, x) of the cut they were made in.
    pub cells: Vec<Cell>,
    /// Per node: its cell.
    pub of_node: Vec<u32>,
    /// Cell `c`'s nodes are `members[start[c]..start[c + 1]]`, in node order.
    pub start: Vec<u32>,
    /// The nodes of each cell (see [`Self::start`]).
    pub members: Vec<u32>,
    /// Per cell: Σ of its nodes' basis areas, m².
    pub area: Vec<f32>,
    /// Per cell: the area-weighted mean of its nodes' albedos.
    pub albedo: Vec<Vec3>,
}

impl Clusters {
    /// The cut at one `level` everywhere: cells of up to 2^level × 2^level texels, in the
    /// pieces `links` leaves connected.
    pub fn at_level(nodes: &Nodes, patches: &Patches, links: &Links, level: u8) -> Self {
        let cells: Vec<Cell> = (0..nodes.len())
            .map(|i| cell_of(patches, nodes, i, level))
            .collect();
        Self::from_node_cells(nodes, patches, links, cells)
    }

    /// The cut with every cell marked in `split` (and of level above 0) replaced by its
    /// children (each in its connected pieces).
    pub fn split(&self, nodes: &Nodes, patches: &Patches, links: &Links, split: &[bool]) -> Self {
        let cells: Vec<Cell> = (0..nodes.len())
            .map(|i| {
                let c = self.of_node[i] as usize;
                let cell = self.cells[c];
                if split[c] && cell.level > 0 {
                    cell_of(patches, nodes, i, cell.level - 1)
                } else {
                    Cell { part: 0, ..cell }
                }
            })
            .collect();
        Self::from_node_cells(nodes, patches, links, cells)
    }

    /// Splits each quadtree cell of `cells` (per node, `part` zero) into its connected pieces
    /// under `links`, labelled by their smallest node (union–find over the links).
    fn connect(nodes: &Nodes, patches: &Patches, links: &Links, cells: &mut [Cell]) {
        let mut parent: Vec<u32> = (0..cells.len() as u32).collect();
        fn find(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for i in 0..cells.len() {
            let p = &patches.patches[nodes.patch[i] as usize];
            let bits = links.bits[i];
            for (bit, (dx, dy)) in [(1u8, (1, 0)), (2u8, (0, 1))] {
                if bits & bit == 0 {
                    continue;
                }
                let Some(j) = links.neighbour(patches, nodes, p, (dx, dy)) else {
                    continue;
                };
                if cells[j as usize] != cells[i] {
                    continue;
                }
                let (a, b) = (find(&mut parent, i as u32), find(&mut parent, j));
                // The smaller index becomes the root, so a piece is named by its first node.
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        for i in 0..cells.len() {
            cells[i].part = find(&mut parent, i as u32);
        }
    }

    /// Groups nodes by their cells (split into connected pieces; sorted, so the order does not
    /// depend on the node order within a cell), with the aggregates.
    fn from_node_cells(
        nodes: &Nodes,
        patches: &Patches,
        links: &Links,
        mut node_cells: Vec<Cell>,
    ) -> Self {
        Self::connect(nodes, patches, links, &mut node_cells);
        let mut order: Vec<u32> = (0..node_cells.len() as u32).collect();
        order.sort_by_key(|&i| (node_cells[i as usize], i));
        let mut cells = Vec::new();
        let mut start = Vec::new();
        let mut of_node = vec![0u32; node_cells.len()];
        for (k, &i) in order.iter().enumerate() {
            let cell = node_cells[i as usize];
            if cells.last() != Some(&cell) {
                cells.push(cell);
                start.push(k as u32);
            }
            of_node[i as usize] = (cells.len() - 1) as u32;
        }
        start.push(order.len() as u32);
        let mut out = Self {
            cells,
            of_node,
            start,
            members: order,
            area: Vec::new(),
            albedo: Vec::new(),
        };
        out.aggregate(nodes);
        out
    }

    /// Sets each cell's area (Σ of its nodes' basis areas) and albedo (their area-weighted
    /// mean; the plain mean of a cell of zero-area nodes) from `nodes`: a cut kept across an
    /// edit of the albedo takes the nodes' new albedo this way.
    pub fn aggregate(&mut self, nodes: &Nodes) {
        let cells = self.cells.len();
        let mut area = vec![0.0f32; cells];
        let mut weighted = vec![Vec3::ZERO; cells];
        for (i, &c) in self.of_node.iter().enumerate() {
            area[c as usize] += nodes.area[i];
            weighted[c as usize] += nodes.albedo[i] * nodes.area[i];
        }
        let albedo = weighted
            .iter()
            .zip(&area)
            .zip(self.start.windows(2))
            .map(|((&w, &a), range)| {
                if a > 0.0 {
                    w / a
                } else {
                    // Zero-area nodes only: their plain mean.
                    let m = &self.members[range[0] as usize..range[1] as usize];
                    m.iter().map(|&i| nodes.albedo[i as usize]).sum::<Vec3>() / m.len() as f32
                }
            })
            .collect();
        self.area = area;
        self.albedo = albedo;
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    #[cfg(any(test, feature = "internals"))]
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The nodes of cell `c`.
    pub fn members_of(&self, c: usize) -> &[u32] {
        &self.members[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Per node: the value of its cell in `per_cell` (the prolongation of a per-cell field).
    pub fn prolong(&self, per_cell: &[Vec3]) -> Vec<Vec3> {
        self.of_node.iter().map(|&c| per_cell[c as usize]).collect()
    }

    /// How many cells there are at each level, finest first (index = level).
    pub fn levels(&self) -> Vec<usize> {
        let top = self.cells.iter().map(|c| c.level).max().unwrap_or(0) as usize;
        let mut out = vec![0; top + 1];
        for c in &self.cells {
            out[c.level as usize] += 1;
        }
        out
    }
}

/// Node `i`'s quadtree cell at `level`.
fn cell_of(patches: &Patches, nodes: &Nodes, i: usize, level: u8) -> Cell {
    let p = &patches.patches[nodes.patch[i] as usize];
    Cell {
        instance: p.instance,
        chart: p.chart,
        level,
        x: p.x >> level,
        y: p.y >> level,
        part: 0,
    }
}
