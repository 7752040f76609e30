//! Texel clusters: the elements of the hierarchical solve's coarse level.
//!
//! Every chart of every instance carries a quadtree over its texels: a cell at level k holds
//! the nodes whose page texel (x, y) has the same (x >> k, y >> k), so it covers at most
//! 2ᵏ × 2ᵏ texels, and its four children are the quadrants one level down. A [`Clusters`] is
//! a cut through these trees: every node belongs to exactly one cell of the cut. The coarse
//! solve treats each cell as a patch of uniform reflected exitance (Smits, Arvo & Greenberg
//! 1994 cluster texels into such elements; here they never span two charts, so a cell is one
//! piece of surface), and [`Clusters::split`] refines the cut where the coarse solution is
//! too coarse (Cohen & Wallace 1993, ch. 8, adaptive subdivision).

use glam::Vec3;

use super::nodes::Nodes;
use crate::raster::Patches;

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
    /// The cut at one `level` everywhere: cells of up to 2^level × 2^level texels.
    pub fn at_level(nodes: &Nodes, patches: &Patches, level: u8) -> Self {
        let cells: Vec<Cell> = (0..nodes.len())
            .map(|i| cell_of(patches, nodes, i, level))
            .collect();
        Self::from_node_cells(nodes, cells)
    }

    /// The cut with every cell marked in `split` (and of level above 0) replaced by its
    /// children.
    pub fn split(&self, nodes: &Nodes, patches: &Patches, split: &[bool]) -> Self {
        let cells: Vec<Cell> = (0..nodes.len())
            .map(|i| {
                let c = self.of_node[i] as usize;
                let cell = self.cells[c];
                if split[c] && cell.level > 0 {
                    cell_of(patches, nodes, i, cell.level - 1)
                } else {
                    cell
                }
            })
            .collect();
        Self::from_node_cells(nodes, cells)
    }

    /// Groups nodes by their cells (sorted, so the order does not depend on the node order
    /// within a cell), with the aggregates.
    fn from_node_cells(nodes: &Nodes, node_cells: Vec<Cell>) -> Self {
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
        let mut area = vec![0.0f32; cells.len()];
        let mut weighted = vec![Vec3::ZERO; cells.len()];
        for (i, &c) in of_node.iter().enumerate() {
            area[c as usize] += nodes.area[i];
            weighted[c as usize] += nodes.albedo[i] * nodes.area[i];
        }
        let albedo = weighted
            .iter()
            .zip(&area)
            .zip(start.windows(2))
            .map(|((&w, &a), range)| {
                if a > 0.0 {
                    w / a
                } else {
                    // Zero-area nodes only: their plain mean.
                    let m = &order[range[0] as usize..range[1] as usize];
                    m.iter().map(|&i| nodes.albedo[i as usize]).sum::<Vec3>() / m.len() as f32
                }
            })
            .collect();
        Self {
            cells,
            of_node,
            start,
            members: order,
            area,
            albedo,
        }
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
    }
}
