//! The start points of transport rays: points of a node's basis support, drawn as the
//! Galerkin form of the radiosity equation asks, with their importance weights; and the fast
//! affine form of the same for interior nodes ([`SupportFrame`]).

use glam::Vec2;

use super::hit_mapper::HitMapper;
use crate::context::BakeContext;
use crate::raster::{Patch, SurfaceFrame, SurfacePoint};
use crate::sampling::sobol_02;
use crate::settings::Basis;

/// Draws the start of transport ray `k` of node `i` from the node's basis support, as the
/// Galerkin form of the radiosity equation asks (A_i·F_ij = ∫φᵢ(x)·∫ w_j(y(x, ω)) cosθ/π dω dx,
/// which is reciprocal): a tent-distributed offset of at most one texel around the node
/// (piecewise linear) or a uniform point of its texel (piecewise constant), mapped onto the
/// surface. Returns the point and its importance weight φᵢ(x)·a(x)/density(x), with a(x) the
/// world area of a texel there; `None` when the offset leaves the surface or the node's chart
/// or lands on a part of a texel hidden under geometry (those samples carry no weight, as they
/// carry no area in [`Nodes::area`](super::Nodes::area)). Adds the visibility rays it traces
/// (two when the point's texel lies near geometry) to `traced`.
pub fn support_point(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    node: usize,
    p: &Patch,
    k: u32,
    key: u32,
    traced: &mut u64,
) -> Option<(SurfacePoint, f32)> {
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
    if !texel.is_valid() || texel.flags & Patch::NEAR_GEOMETRY != 0 {
        *traced += 2;
    }
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
    frame: SurfaceFrame,
    /// World area of one texel, m².
    texel_area: f32,
}

/// Barycentric margin the support square must keep inside its triangle for [`SupportFrame`]
/// (so rounding cannot put a sample outside where the slow path would pick another triangle).
pub(super) const SUPPORT_MARGIN: f32 = 1e-4;

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
    pub fn point(&self, u: Vec2) -> Option<(SurfacePoint, f32)> {
        let (d, density) = tent_offset(u);
        (density > 0.0).then(|| (self.frame.point(d), self.texel_area))
    }
}
