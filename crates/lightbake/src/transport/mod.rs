//! Light transport between texel patches: the form-factor matrix F of the radiosity equation
//! B = S + ρ·F·B (Cohen & Wallace 1993; Dutré et al., *Advanced Global Illumination*, ch. 6).
//!
//! # Nodes and bases
//! Every *valid* texel patch is a node ([`Nodes`]). Radiosity lives at nodes and is
//! reconstructed over the lightmap grid with one of two bases ([`Basis`]):
//!
//! * **piecewise linear** (default): bilinear interpolation of the four texel centres around a
//!   point, exactly what the GPU's bilinear sampling of the lightmap shows. Only nodes of the
//!   same instance and chart count; when some of the four are missing (a chart border, a texel
//!   inside geometry) the rest are renormalised, and when none is left the texel containing
//!   the point (or its nearest valid neighbour in the chart) takes the whole weight;
//! * **piecewise constant**: the texel containing the point (classic patch radiosity).
//!
//! # Form factors
//! * [`Transport::build_monte_carlo`]: `rays` cosine-distributed rays per node from its
//!   representative point, stratified by an Owen-scrambled (0,2)-sequence. Row i of F holds,
//!   for every node j, the mean basis weight of node j at the rays' hits: F_ij = (1/N)·Σ_k
//!   w_j(y_k). The irradiance at node i from reflected light is H_i = Σ_j F_ij·B_j. Duplicate
//!   targets are merged; weights are f32 and columns u32. [`Transport::estimate_bytes`] traces
//!   a pilot sample of rows first so the memory can be checked against a budget before the
//!   matrix is built.
//! * [`hemicube`]: Cohen & Greenberg's hemicube, for comparison.
//! * The closed-form point-to-polygon factor is [`crate::direct::polygon`].
//!
//! Rays that leave the scene escape (the sky is direct light, not part of F); rays that hit
//! the back of a single-sided surface see the inside of a solid, which is black.

pub mod hemicube;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::bake::BakeContext;
use crate::bvh::Hit;
use crate::direct::Footprint;
use crate::progress::Progress;
use crate::raster::{Patch, Surface};
use crate::sampling::{Sobol02, cosine_hemisphere, sobol_02};

/// How radiosity is reconstructed between texel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Basis {
    /// Bilinear over the four surrounding texel centres (what the GPU shows).
    #[default]
    Linear,
    /// Constant over each texel.
    Constant,
}

/// Random-number stream of the transport rays (mixed into a texel's key).
const STREAM_TRANSPORT: u32 = 200;
/// Footprint samples averaged for a texel's albedo.
const ALBEDO_SAMPLES: u32 = 16;

/// The unknowns: one node per valid patch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Nodes {
    /// Node → patch index.
    pub patch: Vec<u32>,
    /// Patch → node index (`u32::MAX` for invalid patches).
    pub of_patch: Vec<u32>,
    /// Area of each node's basis function, ∫φᵢ dA, m²: for the constant basis the texel's
    /// covered area; for the linear basis the surface its bilinear weight spreads over (the
    /// texel area inside a chart, different at chart borders). Reciprocity (A_i·F_ij =
    /// A_j·F_ji) and power (B·A) are in these areas.
    pub area: Vec<f32>,
    /// Diffuse albedo of each node: base colour × (1 − metallic) × the base-colour texture
    /// averaged over the texel's footprint.
    pub albedo: Vec<Vec3>,
    /// Per node: whether geometry cuts its basis support (its anchor cannot see the anchor of
    /// a neighbouring node of its chart; see [`HitMapper`]). Traced once here, for every
    /// mapper made for these nodes.
    pub split: Vec<bool>,
    /// Per node: none of its texel's footprint points is open surface (the texel lies under
    /// geometry, and validity moved its point to the open side of it, possibly past the
    /// texel). Its representative point then stands for it: in its basis area, and as the
    /// start of its transport rays, as in the hemicube and the VPL gather. Sampling its
    /// support instead would find no start point (an empty row: no reflected light) or, at
    /// high ray counts, a few from a sliver of surface, so the row would depend on the ray
    /// count.
    pub sliver: Vec<bool>,
}

impl Nodes {
    /// One node per valid patch, with its albedo and basis area.
    pub fn new(ctx: &BakeContext<'_>, basis: Basis) -> Self {
        let patches = &ctx.patches.patches;
        let mut of_patch = vec![u32::MAX; patches.len()];
        let mut patch = Vec::new();
        for (i, p) in patches.iter().enumerate() {
            if p.is_valid() {
                of_patch[i] = patch.len() as u32;
                patch.push(i as u32);
            }
        }
        let surface = Surface::new(ctx.scene, ctx.layout, ctx.rays);
        let albedo = patch
            .par_iter()
            .map(|&pi| texel_albedo(ctx, &surface, &patches[pi as usize]))
            .collect();
        let mut nodes = Self {
            patch,
            of_patch,
            area: Vec::new(),
            albedo,
            split: Vec::new(),
            sliver: Vec::new(),
        };
        let mapper = HitMapper::new(*ctx, &nodes, basis);
        let split = mapper.split_flags();
        let (area, sliver) = basis_areas(ctx, &nodes, &mapper);
        drop(mapper);
        nodes.area = area;
        nodes.split = split;
        nodes.sliver = sliver;
        nodes
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.patch.len()
    }

    /// Whether there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.patch.is_empty()
    }

    /// Largest albedo component (the contraction factor bound of Jacobi-type iterations).
    pub fn max_albedo(&self) -> f32 {
        self.albedo
            .iter()
            .fold(0.0f32, |m, a| m.max(a.max_element()))
    }
}

/// One chunk of [`basis_areas`]' work: (node, area share) entries, and the sliver nodes.
type AreaChunk = (Vec<(u32, f32)>, Vec<u32>);

/// Footprint samples per texel for the basis areas.
const AREA_SAMPLES: u32 = 16;

/// ∫φᵢ dA of every node: each texel's open area (see [`crate::raster::Patches::open_point`];
/// invalid texels contribute their open rim), split over stratified points of its footprint,
/// given to the nodes by the basis weights at those points.
///
/// Also returns, per node, whether none of its texel's footprint points is open (see
/// [`Nodes::sliver`]).
fn basis_areas(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    mapper: &HitMapper<'_>,
) -> (Vec<f32>, Vec<bool>) {
    let patches = &ctx.patches.patches;
    let chunks: Vec<AreaChunk> = patches
        .par_chunks(512)
        .enumerate()
        .map(|(c, chunk)| {
            let mut out = Vec::new();
            let mut slivers = Vec::new();
            let mut w = [(0u32, 0f32); 4];
            for (k, p) in chunk.iter().enumerate() {
                let Some(rect) = ctx.layout.instances[p.instance as usize] else {
                    continue;
                };
                if exact_split(mapper, p, rect, &mut out) {
                    continue;
                }
                let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
                let footprint = ctx.patches.footprint_of(p);
                // Full-texel world area per sample; a valid texel's samples share its
                // (already visibility-reduced) area instead.
                let mut points: Vec<(u32, Vec2, (Vec3, Vec3))> =
                    Vec::with_capacity(AREA_SAMPLES as usize);
                let mut on_surface = 0;
                for s in 0..AREA_SAMPLES {
                    let q = texel + sobol_02(s, p.rng(ctx.settings.seed, 0xa4ea));
                    let Some(sp) = footprint
                        .iter()
                        .find_map(|&t| mapper.surface.point(t, q, 0.0))
                    else {
                        continue;
                    };
                    on_surface += 1;
                    let from = (sp.position, sp.geometric_normal);
                    let n = mapper.weights_at(sp.triangle, q, from, &mut w);
                    let Some(&(anchor, _)) = w[..n].iter().max_by(|a, b| a.1.total_cmp(&b.1))
                    else {
                        continue;
                    };
                    let anchor_patch = &patches[nodes.patch[anchor as usize] as usize];
                    if ctx.patches.open_point(p, &sp, anchor_patch, ctx.rays) {
                        points.push((sp.triangle, q, from));
                    }
                }
                if p.is_valid() && points.is_empty() {
                    // A sliver: its representative point stands for it.
                    slivers.push(nodes.of_patch[c * 512 + k]);
                    points.push((
                        p.triangle,
                        texel + Vec2::splat(0.5),
                        (p.position, p.geometric_normal),
                    ));
                }
                if points.is_empty() {
                    continue;
                }
                let share = if p.is_valid() {
                    p.area / points.len() as f32
                } else {
                    p.area / on_surface.max(1) as f32
                };
                for (t, q, from) in points {
                    let n = mapper.weights_at(t, q, from, &mut w);
                    out.extend(w[..n].iter().map(|&(j, wj)| (j, wj * share)));
                }
            }
            (out, slivers)
        })
        .collect();
    let mut area = vec![0.0f32; nodes.len()];
    let mut sliver = vec![false; nodes.len()];
    for (chunk, slivers) in chunks {
        for (j, a) in chunk {
            area[j as usize] += a;
        }
        for j in slivers {
            sliver[j as usize] = true;
        }
    }
    // Every node keeps at least a sliver of its own area.
    for (i, a) in area.iter_mut().enumerate() {
        *a = a.max(1e-3 * patches[nodes.patch[i] as usize].area);
    }
    (area, sliver)
}

/// A texel's area split over the nodes in closed form, where the sampled split of
/// [`basis_areas`] can only approximate it: the texel is valid, away from other geometry and
/// its square lies inside its triangle (every point of it is open surface), and each texel of
/// the 3 × 3 block around it carries an unsplit node of its chart. The bilinear weight of the
/// node `d` texels away then integrates over the texel square to g(dx)·g(dy), with
/// g(0) = 3/4 and g(±1) = 1/8 (the texel's own node under the constant basis takes it all).
/// Appends the shares to `out` and returns whether it applied.
fn exact_split(
    mapper: &HitMapper<'_>,
    p: &Patch,
    rect: crate::unwrap::InstanceRect,
    out: &mut Vec<(u32, f32)>,
) -> bool {
    if !p.is_valid() || p.flags & (Patch::NEAR_GEOMETRY | Patch::MOVED) != 0 {
        return false;
    }
    let (x, y) = ((p.x - rect.x) as i64, (p.y - rect.y) as i64);
    let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
    let Some(frame) = mapper.surface.frame(p.triangle, centre) else {
        return false;
    };
    if !frame.covers(0.5, SUPPORT_MARGIN) {
        return false;
    }
    let grid = mapper.grid_lookup(rect, p.instance, p.chart);
    if mapper.basis == Basis::Constant {
        let Some((node, false)) = grid.at(x, y) else {
            return false;
        };
        out.push((node, p.area));
        return true;
    }
    let mut block = [(0u32, 0f32); 9];
    const G: [f32; 3] = [0.125, 0.75, 0.125];
    for (k, entry) in block.iter_mut().enumerate() {
        let (dx, dy) = (k as i64 % 3 - 1, k as i64 / 3 - 1);
        let Some((node, false)) = grid.at(x + dx, y + dy) else {
            return false;
        };
        *entry = (node, p.area * G[(dx + 1) as usize] * G[(dy + 1) as usize]);
    }
    out.extend(block);
    true
}

/// Albedo of one texel: the material's factor times its texture averaged over the footprint.
fn texel_albedo(ctx: &BakeContext<'_>, surface: &Surface<'_>, p: &Patch) -> Vec3 {
    let inst = &ctx.scene.instances[p.instance as usize];
    let material = ctx.scene.material_of(inst.mesh);
    let factor = material.base_color.truncate() * (1.0 - material.metallic);
    let (Some(tref), Some(uv0)) = (
        material.base_color_texture,
        ctx.scene.meshes[inst.mesh].uv0.as_ref(),
    ) else {
        return factor;
    };
    let texture = &ctx.scene.textures[tref.texture];
    if tref.tex_coord != 0 {
        return factor * texture.mean_srgb().truncate();
    }
    let mesh = &ctx.scene.meshes[inst.mesh];
    let mut sum = Vec3::ZERO;
    let mut rays = 0;
    let footprint = Footprint::new(
        ctx.layout,
        ctx.patches,
        surface,
        ctx.rays,
        p,
        ctx.settings.seed,
    );
    for s in 0..ALBEDO_SAMPLES {
        let sp = footprint.point(s, &mut rays);
        let info = ctx.rays.triangles[sp.triangle as usize];
        let [a, b, c] = mesh.triangle(info.local as usize);
        let uv = uv0[a] * (1.0 - sp.bary.x - sp.bary.y) + uv0[b] * sp.bary.x + uv0[c] * sp.bary.y;
        sum += texture.sample_srgb(uv).truncate();
    }
    factor * sum / ALBEDO_SAMPLES as f32
}

/// Turns a ray hit into the nodes (and weights) that represent radiosity there.
pub struct HitMapper<'a> {
    ctx: BakeContext<'a>,
    basis: Basis,
    /// Per page, per texel: the node there and who owns it, so a lookup touches one small
    /// record instead of the page index, the patch and the node table (the hit lookups are
    /// the hottest loads of the transport build).
    grid: Vec<Vec<TexelNode>>,
    /// Per node: its patch (for the anchor point of the visibility test).
    node_patch: &'a [u32],
    /// Surface lookups (texel point → world point) for the rays' start points.
    surface: Surface<'a>,
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
struct TexelNode {
    node: u32,
    instance: u32,
    chart: u32,
}

/// Flag bit in [`TexelNode::instance`].
const SPLIT: u32 = 1 << 31;

/// One instance rectangle of a mapper's texel grid, seen from one chart.
#[derive(Clone, Copy)]
struct GridView<'g> {
    grid: &'g [TexelNode],
    page_w: i64,
    rect: crate::unwrap::InstanceRect,
    instance: u32,
    chart: u32,
}

impl GridView<'_> {
    /// The node at rect-local texel (x, y), if it belongs to the view's instance and chart, and
    /// whether it is split.
    #[inline]
    fn at(&self, x: i64, y: i64) -> Option<(u32, bool)> {
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
    fn split_flags(&self) -> Vec<bool> {
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

    /// Surface lookups for the mapper's scene.
    pub fn surface(&self) -> &Surface<'a> {
        &self.surface
    }

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
    fn grid_lookup(
        &self,
        rect: crate::unwrap::InstanceRect,
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
            let (x, y) = (q.x - 0.5, q.y - 0.5);
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let corners = [
                (x0, y0, (1.0 - fx) * (1.0 - fy)),
                (x0 + 1, y0, fx * (1.0 - fy)),
                (x0, y0 + 1, (1.0 - fx) * fy),
                (x0 + 1, y0 + 1, fx * fy),
            ];
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

/// Draws the start of transport ray `k` of node `i` from the node's basis support, as the
/// Galerkin form of the radiosity equation asks (A_i·F_ij = ∫φᵢ(x)·∫ w_j(y(x, ω)) cosθ/π dω dx,
/// which is reciprocal): a tent-distributed offset of at most one texel around the node
/// (piecewise linear) or a uniform point of its texel (piecewise constant), mapped onto the
/// surface. Returns the point and its importance weight φᵢ(x)·a(x)/density(x), with a(x) the
/// world area of a texel there; `None` when the offset leaves the surface or the node's chart
/// or lands on a part of a texel hidden under geometry (those samples carry no weight, as they
/// carry no area in [`Nodes::area`]).
pub fn support_point(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    node: usize,
    p: &Patch,
    k: u32,
    key: u32,
) -> Option<(crate::raster::SurfacePoint, f32)> {
    let rect = ctx.layout.instances[p.instance as usize]?;
    let centre = Vec2::new((p.x - rect.x) as f32 + 0.5, (p.y - rect.y) as f32 + 0.5);
    let u = sobol_02(k, key);
    let (offset, density) = match mapper.basis {
        Basis::Linear => tent_offset(u),
        Basis::Constant => (u - Vec2::splat(0.5), 1.0),
    };
    if density <= 0.0 {
        return None;
    }
    let q = centre + offset;
    // The texel under q, in the same instance and chart.
    let (tx, ty) = (q.x.floor() as i64, q.y.floor() as i64);
    if tx < 0 || ty < 0 || tx >= rect.width as i64 || ty >= rect.height as i64 {
        return None;
    }
    let page_w = ctx.layout.pages[rect.page as usize].width;
    let pi = ctx.patches.page_index[rect.page as usize]
        [((rect.y as i64 + ty) * page_w as i64 + rect.x as i64 + tx) as usize];
    if pi == u32::MAX {
        return None;
    }
    let texel = &ctx.patches.patches[pi as usize];
    if texel.instance != p.instance || texel.chart != p.chart {
        return None;
    }
    let sp = ctx
        .patches
        .footprint_of(texel)
        .iter()
        .find_map(|&t| mapper.surface.point(t, q, 0.0))?;
    // Hidden under geometry: not part of the surface (the basis areas leave it out too).
    if !ctx.patches.open_point(texel, &sp, p, ctx.rays) {
        return None;
    }
    let mut w = [(0u32, 0f32); 4];
    let n = mapper.weights_at(sp.triangle, q, (sp.position, sp.geometric_normal), &mut w);
    let phi = w[..n]
        .iter()
        .find(|e| e.0 as usize == node)
        .map_or(0.0, |e| e.1);
    if phi <= 0.0 {
        return None;
    }
    Some((sp, phi * texel.texel_size * texel.texel_size / density))
}

/// The tent offset of one linear-basis support sample: uniform `u` ∈ [0, 1)² mapped to
/// d ∈ (−1, 1)² with density (1 − |dx|)(1 − |dy|).
fn tent_offset(u: Vec2) -> (Vec2, f32) {
    let tent = |u: f32| {
        if u < 0.5 {
            (2.0 * u).sqrt() - 1.0
        } else {
            1.0 - (2.0 - 2.0 * u).sqrt()
        }
    };
    let d = Vec2::new(tent(u.x), tent(u.y));
    (d, (1.0 - d.x.abs()) * (1.0 - d.y.abs()))
}

/// The fast form of [`support_point`] for an interior node of the piecewise-linear basis:
/// the node's whole support (±1 texel about its centre) lies inside its owner triangle, and
/// the 3 × 3 texels around it are valid, of its chart, away from other geometry and not
/// split. There the surface is one affine map, all four bilinear corners exist, and the
/// sample weight φᵢ·a/density is the texel area; the slow path's lookups, visibility checks
/// and barycentric solves all give the same answer, so they are skipped. Tested against
/// [`support_point`] in this module's tests.
#[derive(Clone, Copy, Debug)]
pub struct SupportFrame {
    frame: crate::raster::SurfaceFrame,
    /// World area of one texel, m².
    texel_area: f32,
}

/// Barycentric margin the support square must keep inside its triangle for [`SupportFrame`]
/// (so rounding cannot put a sample outside where the slow path would pick another triangle).
const SUPPORT_MARGIN: f32 = 1e-4;

impl SupportFrame {
    /// The frame of node `node` (patch `p`), when it is an interior node (see the type docs).
    pub fn new(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        node: usize,
        p: &Patch,
    ) -> Option<Self> {
        if mapper.basis != Basis::Linear {
            return None;
        }
        let rect = ctx.layout.instances[p.instance as usize]?;
        let (x, y) = ((p.x - rect.x) as i64, (p.y - rect.y) as i64);
        let page_w = ctx.layout.pages[rect.page as usize].width as i64;
        let index = &ctx.patches.page_index[rect.page as usize];
        let grid = mapper.grid_lookup(rect, p.instance, p.chart);
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (tx, ty) = (x + dx, y + dy);
                if tx < 0 || ty < 0 || tx >= rect.width as i64 || ty >= rect.height as i64 {
                    return None;
                }
                let pi = index[((rect.y as i64 + ty) * page_w + rect.x as i64 + tx) as usize];
                if pi == u32::MAX {
                    return None;
                }
                let t = &ctx.patches.patches[pi as usize];
                let interior = t.is_valid()
                    && t.flags & Patch::NEAR_GEOMETRY == 0
                    && t.instance == p.instance
                    && t.chart == p.chart
                    && t.texel_size == p.texel_size;
                if !interior || !matches!(grid.at(tx, ty), Some((_, false))) {
                    return None;
                }
            }
        }
        // The node itself must be the texel's node (it is, for a valid patch).
        if grid.at(x, y).map(|g| g.0 as usize) != Some(node) {
            return None;
        }
        let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        let frame = mapper.surface.frame(p.triangle, centre)?;
        if !frame.covers(1.0, SUPPORT_MARGIN) {
            return None;
        }
        Some(Self {
            frame,
            texel_area: p.texel_size * p.texel_size,
        })
    }

    /// The support sample for uniform point `u` ∈ [0, 1)² (for sample `k` with scramble
    /// `key`, [`support_point`] uses `u = sobol_02(k, key)`).
    #[inline]
    pub fn point(&self, u: Vec2) -> Option<(crate::raster::SurfacePoint, f32)> {
        let (d, density) = tent_offset(u);
        (density > 0.0).then(|| (self.frame.point(d), self.texel_area))
    }
}

/// Outcome of tracing one ray for transport.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayFate {
    /// Left the scene.
    Escaped,
    /// Hit a surface that carries no radiosity (not baked, or its back).
    Absorbed,
    /// Hit nodes (the weights were written).
    Nodes(usize),
}

/// Traces one transport ray from `origin` along `dir`.
#[inline]
pub fn trace_to_nodes(
    mapper: &HitMapper<'_>,
    origin: Vec3,
    dir: Vec3,
    out: &mut [(u32, f32); 4],
) -> RayFate {
    match mapper.ctx.rays.closest_hit(origin, dir, 0.0, f32::INFINITY) {
        None => RayFate::Escaped,
        Some(hit) => match mapper.weights(&hit, out) {
            0 => RayFate::Absorbed,
            n => RayFate::Nodes(n),
        },
    }
}

/// A run of consecutive matrix rows in flat arrays: columns and weights one row after the
/// other, and each row's length.
#[derive(Default)]
struct RowBlock {
    cols: Vec<u32>,
    vals: Vec<f32>,
    lens: Vec<u32>,
}

/// Rows the Monte Carlo build makes before packing them into the matrix.
const BUILD_BLOCK_ROWS: usize = 16_384;

/// The sparse form-factor matrix F in compressed rows.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Transport {
    /// Number of nodes (rows and columns).
    pub n: usize,
    row_ptr: Vec<u64>,
    cols: Vec<u32>,
    vals: Vec<f32>,
    /// Per row: the fraction of its rays that left the scene.
    pub escaped: Vec<f32>,
    /// Rays traced to build it.
    pub rays: u64,
    /// Basis the weights are in.
    pub basis: Basis,
}

/// What [`Transport::validate`] found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
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
    fn empty(n: usize, basis: Basis) -> Self {
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
    fn push_rows(&mut self, rows: Vec<(Vec<(u32, f32)>, f32)>) {
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
    fn push_block(&mut self, rows: RowBlock, escaped: Vec<f32>) {
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
    fn from_rows(n: usize, rows: Vec<(Vec<(u32, f32)>, f32)>, rays: u64, basis: Basis) -> Self {
        let nnz: usize = rows.iter().map(|r| r.0.len()).sum();
        let mut t = Self::empty(n, basis);
        t.cols.reserve_exact(nnz);
        t.vals.reserve_exact(nnz);
        t.push_rows(rows);
        t.rays = rays;
        t
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

    /// The samples of one row of Monte Carlo transport: `rays` rays from points of node `i`'s
    /// basis support (from its representative point when it is a [`Nodes::sliver`], or when
    /// no support point is open), cosine-distributed about the surface there. Calls
    /// `f(weight, hit)` for every start point, with `hit` the nodes and bilinear weights the
    /// ray reached (empty when it escaped, was absorbed or pointed below the surface); returns
    /// the escaped weight.
    fn for_each_sample(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        nodes: &Nodes,
        i: usize,
        rays: u32,
        mut f: impl FnMut(f32, &[(u32, f32)]),
    ) -> f32 {
        let p = &ctx.patches.patches[nodes.patch[i] as usize];
        let key = p.rng(ctx.settings.seed, STREAM_TRANSPORT);
        let mut escaped = 0.0f32;
        let mut out = [(0u32, 0f32); 4];
        let (starts, directions) = (Sobol02::new(key), Sobol02::new(key ^ 0x6a09_e667));
        let mut trace = |sp: &crate::raster::SurfacePoint, weight: f32, k: u32| {
            let dir = cosine_hemisphere(sp.normal, directions.point(k));
            if dir.dot(sp.geometric_normal) <= 0.0 {
                f(weight, &[]); // below the surface: no light arrives from there
                return;
            }
            let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
            match trace_to_nodes(mapper, origin, dir, &mut out) {
                RayFate::Escaped => {
                    escaped += weight;
                    f(weight, &[]);
                }
                RayFate::Absorbed => f(weight, &[]),
                RayFate::Nodes(n) => f(weight, &out[..n]),
            }
        };
        let mut started = 0u32;
        if !nodes.sliver.get(i).copied().unwrap_or(false) {
            let fast = SupportFrame::new(ctx, mapper, i, p);
            for k in 0..rays {
                let start = match &fast {
                    Some(frame) => frame.point(starts.point(k)),
                    None => support_point(ctx, mapper, i, p, k, key),
                };
                if let Some((sp, weight)) = start {
                    started += 1;
                    trace(&sp, weight, k);
                }
            }
        }
        if started == 0 {
            let sp = crate::direct::representative(p);
            for k in 0..rays {
                trace(&sp, 1.0, k);
            }
        }
        escaped
    }

    /// One row of Monte Carlo transport (see [`Self::for_each_sample`]), self-normalised by
    /// the sample weights. Returns the row and its escaped fraction.
    fn mc_row(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        nodes: &Nodes,
        i: usize,
        rays: u32,
    ) -> (Vec<(u32, f32)>, f32) {
        let mut rows = RowBlock::default();
        let escaped = Self::mc_row_into(ctx, mapper, nodes, i, rays, &mut Vec::new(), &mut rows);
        (rows.cols.into_iter().zip(rows.vals).collect(), escaped)
    }

    /// [`Self::mc_row`] appended to `out` (its columns, weights and length), with `scratch`
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
        let escaped = Self::for_each_sample(ctx, mapper, nodes, i, rays, |weight, hit| {
            total += weight;
            scratch.extend(
                hit.iter()
                    .map(|&(j, wj)| (j as u64) << 32 | (wj * weight).to_bits() as u64),
            );
        });
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
    /// `rays` rays as [`Self::build_monte_carlo`] does, without storing the matrix (lux).
    pub fn gather_row(
        ctx: &BakeContext<'_>,
        mapper: &HitMapper<'_>,
        nodes: &Nodes,
        i: usize,
        rays: u32,
        b: &[Vec3],
    ) -> Vec3 {
        let (row, _) = Self::mc_row(ctx, mapper, nodes, i, rays);
        row.iter()
            .fold(Vec3::ZERO, |s, &(j, w)| s + b[j as usize] * w)
    }

    /// Luminance of node `i`'s gathered irradiance (F·B)ᵢ from exitance `b`, with its row
    /// estimated by `rays` rays as [`Self::build_monte_carlo`] does: the self-normalised
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
        Self::for_each_sample(ctx, mapper, nodes, i, rays, |weight, hit| {
            let v: f32 = hit
                .iter()
                .map(|&(j, wj)| wj * crate::direct::luminance(b[j as usize]))
                .sum();
            total += weight as f64;
            weighted += weight as f64 * v as f64;
        });
        if total <= 0.0 { 0.0 } else { weighted / total }
    }

    /// Estimated bytes of the Monte Carlo matrix: up to 512 evenly spaced rows are traced and
    /// their merged lengths extrapolated, × 1.1: the build reserves 1.1× its first block's
    /// mean row length. The pilot alone was within 1% of the built matrix on the Cornell box
    /// at 63 k, 127 k and 979 k nodes and on the sunlit room (the margin was 1.25 before).
    pub fn estimate_bytes(ctx: &BakeContext<'_>, nodes: &Nodes, rays: u32, basis: Basis) -> u64 {
        let n = nodes.len();
        if n == 0 {
            return 0;
        }
        let mapper = HitMapper::new(*ctx, nodes, basis);
        let pilot = n.min(512);
        let entries: usize = (0..pilot)
            .into_par_iter()
            .map(|k| {
                Self::mc_row(ctx, &mapper, nodes, k * n / pilot, rays)
                    .0
                    .len()
            })
            .sum();
        let per_row = entries as f64 / pilot as f64;
        (n as f64 * (per_row * 8.0 * 1.1 + 12.0)) as u64
    }

    /// Builds F by Monte Carlo with `rays` rays per node (see the module docs).
    pub fn build_monte_carlo(
        ctx: &BakeContext<'_>,
        nodes: &Nodes,
        rays: u32,
        basis: Basis,
        progress: &Progress,
    ) -> Self {
        let mapper = HitMapper::new(*ctx, nodes, basis);
        let traced = AtomicU64::new(0);
        let n = nodes.len();
        let mut t = Self::empty(n, basis);
        // Rows are made in blocks and packed as they come, so the per-row vectors of only one
        // block exist next to the packed matrix (all of them at once doubled the peak). The
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
                            escaped.push(Self::mc_row_into(
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

    /// y = F·x.
    pub fn mul(&self, x: &[Vec3], y: &mut [Vec3]) {
        y.par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(i, yi)| {
                let (c, v) = self.row(i);
                *yi = c
                    .iter()
                    .zip(v)
                    .fold(Vec3::ZERO, |s, (&j, &w)| s + x[j as usize] * w);
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
