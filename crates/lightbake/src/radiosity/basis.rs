//! The nodes made whole ([`Nodes::new`]) and the area of each node's basis function, ∫φᵢ dA:
//! split from the texels' open areas by the basis weights, in closed form inside a chart
//! (`exact_split`) and by stratified footprint samples elsewhere.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::hit_mapper::HitMapper;
use super::nodes::Nodes;
use super::support::SUPPORT_MARGIN;
use crate::context::BakeContext;
use crate::error::Result;
use crate::incremental::codec::{Reader, Writer};
use crate::incremental::patch_geometry;
use crate::raster::Patch;
use crate::runner::{StageRunner, WorkScope};
use crate::sampling::sobol_02;
use crate::scene::hashes::Hasher;
use crate::settings::Basis;
use crate::stage::Stage;
use crate::unwrap::InstanceRect;

/// One chunk of [`basis_areas`]' work: (node, area share) entries, and the sliver nodes.
type AreaChunk = (Vec<(u32, f32)>, Vec<u32>);

/// Footprint samples per texel for the basis areas.
const AREA_SAMPLES: u32 = 16;

/// Patches per chunk of work.
const CHUNK_PATCHES: usize = 512;
/// Chunks whose shares are made before they are added up: their entries (up to nine per
/// patch) are all that exists beside the result.
const BLOCK_CHUNKS: usize = 64;

impl Nodes {
    /// One node per valid patch, with its albedo, the area of its basis function
    /// ([`basis_areas`]) and where geometry cuts its support (`HitMapper::split_flags`).
    pub fn new(ctx: &BakeContext<'_>, basis: Basis) -> Self {
        Self::keeping(ctx, basis, None).0
    }

    /// [`Self::new`], with the basis areas and sliver flags (which read only the geometry and
    /// its layout) taken from `kept` ([`Self::geometry_bytes`] of an earlier bake's nodes
    /// under the same [`Self::geometry_key`]) when they fit these nodes; the albedo and the
    /// split flags are made again. Gives the nodes and whether `kept` was taken.
    pub fn keeping(ctx: &BakeContext<'_>, basis: Basis, kept: Option<&[u8]>) -> (Self, bool) {
        let mut nodes = Nodes::unknowns(ctx);
        let mapper = HitMapper::new(*ctx, &nodes, basis);
        let split = mapper.split_flags();
        let taken = kept.and_then(|b| read_geometry(b, nodes.len()));
        let was_kept = taken.is_some();
        let (area, sliver) = taken.unwrap_or_else(|| basis_areas(ctx, &nodes, &mapper));
        drop(mapper);
        nodes.area = area;
        nodes.split = split;
        nodes.sliver = sliver;
        (nodes, was_kept)
    }

    /// What the nodes' basis areas and sliver flags are made from, hashed: the geometry and
    /// layout of the texel patches, the basis and the seed.
    pub fn geometry_key(ctx: &BakeContext<'_>, basis: Basis) -> u64 {
        let mut h = Hasher::default();
        h.u64(patch_geometry(ctx.scene, ctx.layout))
            .u32(u32::from(basis == Basis::Linear))
            .u32(ctx.settings.seed)
            .u64(ctx.patches.patches.len() as u64);
        h.finish()
    }

    /// The basis areas and sliver flags as bytes, for a later bake ([`Self::keeping`]).
    pub fn geometry_bytes(&self) -> Vec<u8> {
        let mut w = Writer::default();
        w.f32s(&self.area);
        let sliver: Vec<u8> = self.sliver.iter().map(|&s| u8::from(s)).collect();
        w.bytes(&sliver);
        w.into_bytes()
    }
}

/// The nodes as stage `nodes`: their basis areas and sliver flags taken from the earlier bake
/// this one follows when it kept them under the same [`Nodes::geometry_key`]
/// ([`WorkScope::earlier_state`]), and kept for a later bake.
///
/// # Errors
/// A cancel seen when the stage ends.
pub fn nodes_stage<'p>(ctx: &BakeContext<'_>, stages: &mut impl StageRunner<'p>) -> Result<Nodes> {
    let basis = ctx.settings.radiosity.basis;
    let key = Nodes::geometry_key(ctx, basis);
    let scope = stages.scope();
    let earlier = scope.earlier_state(Stage::Nodes, key);
    let nodes = stages.run(Stage::Nodes, 1, || {
        let (nodes, kept) = Nodes::keeping(ctx, basis, earlier.as_deref());
        let note = format!(
            "{} nodes, max albedo {:.3}{}",
            nodes.len(),
            nodes.max_albedo(),
            if kept {
                "; basis areas kept from the earlier bake (the geometry and its layout did not change)"
            } else {
                ""
            }
        );
        Ok((nodes, 0, note))
    })?;
    scope.keep_state(Stage::Nodes, key, || nodes.geometry_bytes());
    Ok(nodes)
}

/// [`Nodes::geometry_bytes`] read back for `n` nodes; `None` when they do not fit.
fn read_geometry(bytes: &[u8], n: usize) -> Option<(Vec<f32>, Vec<bool>)> {
    let mut r = Reader::part(bytes);
    let area = r.f32s().ok()?;
    let sliver: Vec<bool> = r.bytes().ok()?.iter().map(|&b| b != 0).collect();
    r.end().ok()?;
    let fits = area.len() == n && sliver.len() == n && area.iter().all(|a| a.is_finite());
    fits.then_some((area, sliver))
}

/// ∫φᵢ dA of every node: each texel's open area (see [`crate::raster::Patches::open_point`];
/// invalid texels contribute their open rim), split over stratified points of its footprint,
/// given to the nodes by the basis weights at those points.
///
/// Also returns, per node, whether none of its texel's footprint points is open (see
/// [`Nodes::sliver`]).
pub(super) fn basis_areas(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    mapper: &HitMapper<'_>,
) -> (Vec<f32>, Vec<bool>) {
    let patches = &ctx.patches.patches;
    let mut area = vec![0.0f32; nodes.len()];
    let mut sliver = vec![false; nodes.len()];
    // Blocks of chunks, added up in order (the same sums whatever the thread count).
    for (b, block) in patches.chunks(CHUNK_PATCHES * BLOCK_CHUNKS).enumerate() {
        let first = b * CHUNK_PATCHES * BLOCK_CHUNKS;
        let chunks: Vec<AreaChunk> = block
            .par_chunks(CHUNK_PATCHES)
            .enumerate()
            .map(|(c, chunk)| area_chunk(ctx, nodes, mapper, first + c * CHUNK_PATCHES, chunk))
            .collect();
        for (chunk, slivers) in chunks {
            for (j, a) in chunk {
                area[j as usize] += a;
            }
            for j in slivers {
                sliver[j as usize] = true;
            }
        }
    }
    // Every node keeps at least a sliver of its own area.
    for (i, a) in area.iter_mut().enumerate() {
        *a = a.max(1e-3 * patches[nodes.patch[i] as usize].area);
    }
    (area, sliver)
}

/// The area shares of the patches `chunk` (the first of which is patch `first`): (node,
/// share) entries, and the sliver nodes.
fn area_chunk(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    mapper: &HitMapper<'_>,
    first: usize,
    chunk: &[Patch],
) -> AreaChunk {
    let patches = &ctx.patches.patches;
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
        let mut points: Vec<(u32, Vec2, (Vec3, Vec3))> = Vec::with_capacity(AREA_SAMPLES as usize);
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
            let Some(&(anchor, _)) = w[..n].iter().max_by(|a, b| a.1.total_cmp(&b.1)) else {
                continue;
            };
            let anchor_patch = &patches[nodes.patch[anchor as usize] as usize];
            if ctx.patches.open_point(p, &sp, anchor_patch, ctx.rays) {
                points.push((sp.triangle, q, from));
            }
        }
        if p.is_valid() && points.is_empty() {
            // A sliver: its representative point stands for it.
            slivers.push(nodes.of_patch[first + k]);
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
    rect: InstanceRect,
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
