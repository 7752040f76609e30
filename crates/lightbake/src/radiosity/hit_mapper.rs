//! From a ray hit to the nodes that represent radiosity there: the texel grid of every page
//! with each texel's node and owner, the bilinear (or constant) basis weights at a point,
//! and the visibility test that drops corners geometry cuts off (a wall standing on a floor).
//!
//! # Bases
//! * **piecewise linear** (default): bilinear interpolation of the four texel centres around a
//!   point, exactly what the GPU's bilinear sampling of the lightmap shows. Only nodes of the
//!   same instance and chart count; when some of the four are missing (a chart border, a texel
//!   inside geometry) the rest are renormalised, and when none is left the texel containing
//!   the point (or its nearest valid neighbour in the chart) takes the whole weight;
//! * **piecewise constant**: the texel containing the point (classic patch radiosity).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::nodes::Nodes;
use crate::bvh::Hit;
use crate::context::BakeContext;
use crate::raster::{Surface, bilinear_corners};
use crate::settings::Basis;
use crate::unwrap::InstanceRect;

/// Turns a ray hit into the nodes (and weights) that represent radiosity there.
pub struct HitMapper<'a> {
    pub(super) ctx: BakeContext<'a>,
    pub(super) basis: Basis,
    /// Per page, per texel: the node there and who owns it, so a lookup touches one small
    /// record instead of the page index, the patch and the node table (the hit lookups are
    /// the hottest loads of the transport build).
    grid: Vec<Vec<TexelNode>>,
    /// Per node: its patch (for the anchor point of the visibility test).
    node_patch: &'a [u32],
    /// Surface lookups (texel point → world point) for the rays' start points.
    pub(super) surface: Surface<'a>,
    /// Per global triangle: its lightmap UVs and owner, so a hit finds its texels in one load.
    triangles: Vec<TriangleTexels>,
}

/// What a hit on one triangle needs to find its texels: the triangle's lightmap UVs (`TEXCOORD_1`,
/// unscaled) and its owner; `instance == u32::MAX` when the triangle is not baked.
#[derive(Clone, Copy, Debug)]
struct TriangleTexels {
    uv: [Vec2; 3],
    instance: u32,
    chart: u32,
}

/// A texel's node and its owner (instance, chart); `node == u32::MAX` when it has none.
/// [`SPLIT`] in `instance` marks a node that cannot see the anchor of a neighbour in its
/// chart: geometry (a wall standing on a floor) cuts its basis support.
#[derive(Clone, Copy, Debug)]
pub(super) struct TexelNode {
    node: u32,
    instance: u32,
    chart: u32,
}

/// Flag bit in [`TexelNode::instance`].
const SPLIT: u32 = 1 << 31;

impl TexelNode {
    /// (node, instance, chart, split), or `None` when the texel has no node.
    #[inline]
    pub(super) fn node(&self) -> Option<(u32, u32, u32, bool)> {
        (self.node != u32::MAX).then_some((
            self.node,
            self.instance & !SPLIT,
            self.chart,
            self.instance & SPLIT != 0,
        ))
    }
}

/// One instance rectangle of a mapper's texel grid, seen from one chart.
#[derive(Clone, Copy)]
pub(super) struct GridView<'g> {
    grid: &'g [TexelNode],
    page_w: i64,
    rect: InstanceRect,
    instance: u32,
    chart: u32,
}

impl GridView<'_> {
    /// The node at rect-local texel (x, y), if it belongs to the view's instance and chart, and
    /// whether it is split.
    #[inline]
    pub(super) fn at(&self, x: i64, y: i64) -> Option<(u32, bool)> {
        let r = self.rect;
        if x < 0 || y < 0 || x >= r.width as i64 || y >= r.height as i64 {
            return None;
        }
        let t = self.grid[((r.y as i64 + y) * self.page_w + r.x as i64 + x) as usize];
        (t.node != u32::MAX && t.instance & !SPLIT == self.instance && t.chart == self.chart)
            .then_some((t.node, t.instance & SPLIT != 0))
    }
}

impl<'a> HitMapper<'a> {
    /// A mapper for `basis`. The split flags come from `nodes` (traced when they are missing).
    pub fn new(ctx: BakeContext<'a>, nodes: &'a Nodes, basis: Basis) -> Self {
        let none = TexelNode {
            node: u32::MAX,
            instance: u32::MAX,
            chart: u32::MAX,
        };
        let grid = ctx
            .patches
            .page_index
            .iter()
            .map(|index| {
                index
                    .iter()
                    .map(|&pi| {
                        if pi == u32::MAX {
                            return none;
                        }
                        let p = &ctx.patches.patches[pi as usize];
                        TexelNode {
                            node: nodes.of_patch[pi as usize],
                            instance: p.instance,
                            chart: p.chart,
                        }
                    })
                    .collect()
            })
            .collect();
        let mut mapper = Self {
            ctx,
            basis,
            grid,
            node_patch: &nodes.patch,
            surface: Surface::new(ctx.scene, ctx.layout, ctx.rays),
            triangles: ctx
                .rays
                .triangles
                .iter()
                .map(|info| {
                    let ii = info.instance as usize;
                    let inst = &ctx.scene.instances[ii];
                    let mesh = &ctx.scene.meshes[inst.mesh];
                    match (ctx.layout.instances[ii], &ctx.layout.meshes[inst.mesh]) {
                        (Some(_), Some(unwrap)) => {
                            let uv1 = mesh.uv1.as_ref().expect("unwrapped meshes carry uv1");
                            let [a, b, c] = mesh.triangle(info.local as usize);
                            TriangleTexels {
                                uv: [uv1[a], uv1[b], uv1[c]],
                                instance: info.instance,
                                chart: unwrap.triangle_charts[info.local as usize],
                            }
                        }
                        _ => TriangleTexels {
                            uv: [Vec2::ZERO; 3],
                            instance: u32::MAX,
                            chart: u32::MAX,
                        },
                    }
                })
                .collect(),
        };
        if nodes.split.len() == nodes.len() {
            for grid in &mut mapper.grid {
                for t in grid.iter_mut() {
                    if t.node != u32::MAX && nodes.split[t.node as usize] {
                        t.instance |= SPLIT;
                    }
                }
            }
        } else {
            mapper.mark_split_nodes();
        }
        mapper
    }

    /// Per node: whether it is flagged split.
    pub(super) fn split_flags(&self) -> Vec<bool> {
        let mut split = vec![false; self.node_patch.len()];
        for t in self.grid.iter().flatten() {
            if t.node != u32::MAX && t.instance & SPLIT != 0 {
                split[t.node as usize] = true;
            }
        }
        split
    }

    /// Flags nodes whose anchor cannot see the anchor of a neighbouring node of the same
    /// chart (8-neighbourhood). Lookups near
    /// such nodes then drop corners hidden from the looked-up point, so a floor texel
    /// straddling a thin wall does not carry light from one side to the other.
    fn mark_split_nodes(&mut self) {
        let ctx = self.ctx;
        let patches = &ctx.patches.patches;
        let anchor = |node: u32| {
            let p = &patches[self.node_patch[node as usize] as usize];
            ctx.rays.offset(p.position, p.geometric_normal)
        };
        for (page, grid) in self.grid.iter_mut().enumerate() {
            let w = ctx.layout.pages[page].width as usize;
            let h = grid.len() / w.max(1);
            // Each neighbouring pair is tested once (the four forward neighbours); both ends of
            // a hidden pair are flagged.
            let cells: &[TexelNode] = grid;
            let split: Vec<(usize, usize)> = (0..cells.len())
                .into_par_iter()
                .flat_map_iter(|k| {
                    let t = cells[k];
                    let (x, y) = ((k % w) as i64, (k / w) as i64);
                    let neighbours = [(1, 0), (-1, 1), (0, 1), (1, 1)];
                    neighbours.into_iter().filter_map(move |(dx, dy)| {
                        let (nx, ny) = (x + dx, y + dy);
                        if t.node == u32::MAX || nx < 0 || nx >= w as i64 || ny >= h as i64 {
                            return None;
                        }
                        let j = ny as usize * w + nx as usize;
                        let o = cells[j];
                        if o.node == u32::MAX || o.instance != t.instance || o.chart != t.chart {
                            return None;
                        }
                        let (a, b) = (anchor(t.node), anchor(o.node));
                        let d = b - a;
                        let len = d.length();
                        (len > 0.0 && ctx.rays.occluded(a, d / len, 0.0, len)).then_some((k, j))
                    })
                })
                .collect();
            for (k, j) in split {
                grid[k].instance |= SPLIT;
                grid[j].instance |= SPLIT;
            }
        }
    }

    /// Per page, per texel: its node and owner.
    pub(super) fn texel_pages(&self) -> &[Vec<TexelNode>] {
        &self.grid
    }

    /// Global triangle `t`'s lightmap UVs (in its instance's rectangle, [0, 1]²), instance
    /// and chart; `None` when it is not baked.
    pub(super) fn triangle_texels(&self, t: u32) -> Option<([Vec2; 3], u32, u32)> {
        let tri = self.triangles[t as usize];
        (tri.instance != u32::MAX).then_some((tri.uv, tri.instance, tri.chart))
    }

    /// Whether node `node`'s anchor is visible from `from` (a point and the normal of the side
    /// it is seen from).
    fn sees(&self, from: (Vec3, Vec3), node: u32) -> bool {
        let ctx = &self.ctx;
        let p = &ctx.patches.patches[self.node_patch[node as usize] as usize];
        let a = ctx.rays.offset(from.0, from.1);
        let b = ctx.rays.offset(p.position, p.geometric_normal);
        let d = b - a;
        let len = d.length();
        len <= 0.0 || !ctx.rays.occluded(a, d / len, 0.0, len)
    }

    #[cfg(any(test, feature = "internals"))]
    /// Surface lookups for the mapper's scene.
    pub fn surface(&self) -> &Surface<'a> {
        &self.surface
    }

    #[cfg(any(test, feature = "internals"))]
    /// The basis.
    pub fn basis(&self) -> Basis {
        self.basis
    }

    /// Node weights at a hit, written to `out`; returns how many. Weights sum to 1, or there
    /// are none (the hit surface is not baked, or shows its back).
    pub fn weights(&self, hit: &Hit, out: &mut [(u32, f32); 4]) -> usize {
        let ctx = &self.ctx;
        let info = ctx.rays.triangles[hit.triangle as usize];
        if !hit.front_face && !info.double_sided {
            return 0;
        }
        let tri = self.triangles[hit.triangle as usize];
        if tri.instance == u32::MAX {
            return 0;
        }
        let Some(rect) = ctx.layout.instances[tri.instance as usize] else {
            return 0;
        };
        let uv = tri.uv[0] * (1.0 - hit.u - hit.v) + tri.uv[1] * hit.u + tri.uv[2] * hit.v;
        let q = uv * Vec2::new(rect.width as f32, rect.height as f32);
        // The world point is only needed next to split nodes, so it is formed only there.
        let from = || {
            let [v0, v1, v2] = ctx.rays.triangle_vertices(hit.triangle);
            let point = v0 * (1.0 - hit.u - hit.v) + v1 * hit.u + v2 * hit.v;
            let side = if hit.front_face {
                info.normal
            } else {
                -info.normal
            };
            (point, side)
        };
        let grid = self.grid_lookup(rect, tri.instance, tri.chart);
        self.weights_with(grid, q, from, out)
    }

    /// Node weights at texel-space point `q` (in the instance's rectangle) on global triangle
    /// `triangle`, seen at world point `from.0` from the side of normal `from.1`: corners
    /// flagged as split whose anchor that point cannot see are left out (the rest are
    /// renormalised).
    pub fn weights_at(
        &self,
        triangle: u32,
        q: Vec2,
        from: (Vec3, Vec3),
        out: &mut [(u32, f32); 4],
    ) -> usize {
        let tri = self.triangles[triangle as usize];
        if tri.instance == u32::MAX {
            return 0;
        }
        let Some(rect) = self.ctx.layout.instances[tri.instance as usize] else {
            return 0;
        };
        let grid = self.grid_lookup(rect, tri.instance, tri.chart);
        self.weights_with(grid, q, || from, out)
    }

    /// The lookup of rect-local texels of instance `instance`'s rectangle `rect`, chart `chart`.
    pub(super) fn grid_lookup(
        &self,
        rect: InstanceRect,
        instance: u32,
        chart: u32,
    ) -> GridView<'_> {
        GridView {
            grid: &self.grid[rect.page as usize],
            page_w: self.ctx.layout.pages[rect.page as usize].width as i64,
            rect,
            instance,
            chart,
        }
    }

    /// [`Self::weights_at`] with the texel lookup `grid` (see [`GridView::at`]); `from` gives
    /// the seen point and side, called only when a split node needs its visibility test.
    #[inline]
    fn weights_with(
        &self,
        grid: GridView<'_>,
        q: Vec2,
        from: impl Fn() -> (Vec3, Vec3),
        out: &mut [(u32, f32); 4],
    ) -> usize {
        if self.basis == Basis::Linear {
            let corners = bilinear_corners(q);
            // Plain loops over a fixed array: this runs for every ray end and start point.
            let mut found = [(0u32, 0f32, false); 4];
            let mut m = 0;
            let mut split = false;
            for (cx, cy, w) in corners {
                if w > 0.0
                    && let Some((node, node_split)) = grid.at(cx, cy)
                {
                    found[m] = (node, w, node_split);
                    split |= node_split;
                    m += 1;
                }
            }
            let mut n = 0;
            let mut sum = 0.0;
            for &(node, w, node_split) in &found[..m] {
                if split && node_split && !self.sees(from(), node) {
                    continue;
                }
                out[n] = (node, w);
                sum += w;
                n += 1;
            }
            if n > 0 && sum > 0.0 {
                for e in &mut out[..n] {
                    e.1 /= sum;
                }
                return n;
            }
        }
        // Constant basis, and the linear basis' fallback: the texel under the point, else the
        // nearest valid texel of the chart around it.
        let (tx, ty) = (q.x.floor() as i64, q.y.floor() as i64);
        let usable = |f: Option<(u32, bool)>| {
            f.filter(|&(node, split)| !split || self.sees(from(), node))
                .map(|(node, _)| node)
        };
        if let Some(node) = usable(grid.at(tx, ty)) {
            out[0] = (node, 1.0);
            return 1;
        }
        let mut best: Option<(f32, u32)> = None;
        for dy in -1..=1 {
            for dx in -1..=1 {
                if let Some(node) = usable(grid.at(tx + dx, ty + dy)) {
                    let centre = Vec2::new((tx + dx) as f32 + 0.5, (ty + dy) as f32 + 0.5);
                    let d = centre.distance_squared(q);
                    if best.is_none_or(|b| d < b.0) {
                        best = Some((d, node));
                    }
                }
            }
        }
        match best {
            Some((_, node)) => {
                out[0] = (node, 1.0);
                1
            }
            None => 0,
        }
    }
}
