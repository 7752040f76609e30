//! The exitance of every node laid out on the lightmap pages, for gathers that read a field
//! B at millions of ray hits (the hierarchical solve's final gather, its correction and their
//! error estimates).
//!
//! [`HitMapper::weights`] finds a hit's four bilinear corners through the texel grid, and the
//! gather then reads each corner's B from the node array: two scattered loads per corner,
//! behind two per-triangle tables. Here each page texel carries its node's B and an owner key
//! (one per chart of each instance) in one 16-byte record, and each triangle its lightmap UVs
//! already in page texels, so a hit costs one triangle record and the two grid rows of its
//! corners. The result is the same bilinear reconstruction as the mapper's piecewise-linear
//! basis: corners of other charts are left out and the rest renormalised. Where the mapper
//! does more — a corner whose node is split by geometry (its visibility is traced), a point
//! with no corner in its chart (the nearest texel stands in), the piecewise-constant basis —
//! the lookup goes through the mapper itself, so the two always agree.

use glam::{Vec2, Vec3};

use super::hit_mapper::HitMapper;
use crate::bvh::Hit;
use crate::raster::bilinear_corners;
use crate::settings::Basis;

/// No owner: the texel has no node.
const NONE: u32 = u32::MAX;
/// Flag in [`Texel::owner`]: the node is split by geometry (see [`HitMapper`]).
const SPLIT: u32 = 1 << 31;
/// Flag in [`Triangle::owner`]: the triangle is double-sided (its back carries light too).
const DOUBLE_SIDED: u32 = 1 << 31;

/// One page texel: its node's exitance and owner key (`NONE`, or the chart key with
/// [`SPLIT`]).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Texel {
    b: [f32; 3],
    owner: u32,
}

/// One triangle: its lightmap UVs (in its instance's rectangle, [0, 1]²), the rectangle
/// (page, left, top, width, height in texels) and its owner key (`NONE` for triangles that
/// are not baked; [`DOUBLE_SIDED`] flagged).
#[derive(Clone, Copy, Debug)]
struct Triangle {
    uv: [Vec2; 3],
    rect: [u32; 4],
    page: u32,
    owner: u32,
}

/// A field B per node, on the page grid (see the module docs).
pub struct ExitanceGrid<'a> {
    mapper: &'a HitMapper<'a>,
    b: &'a [Vec3],
    /// Per page: its texels, row-major.
    pages: Vec<Vec<Texel>>,
    /// Per page: its width in texels.
    widths: Vec<i64>,
    /// Per global triangle.
    triangles: Vec<Triangle>,
}

impl<'a> ExitanceGrid<'a> {
    /// The field `b` (one value per node of `mapper`) on the pages.
    pub fn new(mapper: &'a HitMapper<'a>, b: &'a [Vec3]) -> Self {
        let ctx = &mapper.ctx;
        // One key per (instance, chart): the instance's first key plus the chart.
        let mut first_key = Vec::with_capacity(ctx.scene.instances.len());
        let mut next = 0u32;
        for (i, inst) in ctx.scene.instances.iter().enumerate() {
            first_key.push(next);
            if let (Some(_), Some(u)) = (ctx.layout.instances[i], &ctx.layout.meshes[inst.mesh]) {
                next += u.chart_count;
            }
        }
        assert!(next < SPLIT, "more charts than the owner keys can hold");
        let pages = mapper
            .texel_pages()
            .iter()
            .map(|cells| {
                cells
                    .iter()
                    .map(|t| match t.node() {
                        None => Texel {
                            b: [0.0; 3],
                            owner: NONE,
                        },
                        Some((j, instance, chart, split)) => Texel {
                            b: b[j as usize].to_array(),
                            owner: (first_key[instance as usize] + chart)
                                | if split { SPLIT } else { 0 },
                        },
                    })
                    .collect()
            })
            .collect();
        let widths = ctx.layout.pages.iter().map(|p| p.width as i64).collect();
        let triangles = (0..ctx.rays.triangles.len() as u32)
            .map(|t| {
                let info = ctx.rays.triangles[t as usize];
                match mapper.triangle_texels(t) {
                    // A triangle xatlas left out (degenerate) has no chart: no texel matches
                    // it, as in the mapper.
                    Some((uv, instance, chart)) if chart != u32::MAX => {
                        let rect = ctx.layout.instances[instance as usize]
                            .expect("a baked triangle's instance has a rectangle");
                        Triangle {
                            uv,
                            rect: [rect.x, rect.y, rect.width, rect.height],
                            page: rect.page,
                            owner: (first_key[instance as usize] + chart)
                                | if info.double_sided { DOUBLE_SIDED } else { 0 },
                        }
                    }
                    _ => Triangle {
                        uv: [Vec2::ZERO; 3],
                        rect: [0; 4],
                        page: 0,
                        owner: NONE,
                    },
                }
            })
            .collect();
        Self {
            mapper,
            b,
            pages,
            widths,
            triangles,
        }
    }

    /// B at a ray hit: the bilinear reconstruction of the field there, zero where the hit
    /// surface carries no radiosity (not baked, or its back). The same arithmetic, in the same
    /// order, as [`HitMapper::weights`] followed by Σ b_j·w_j, so the two give the same bits.
    #[inline]
    pub fn at(&self, hit: &Hit) -> Vec3 {
        let tri = self.triangles[hit.triangle as usize];
        if tri.owner == NONE || (!hit.front_face && tri.owner & DOUBLE_SIDED == 0) {
            return Vec3::ZERO;
        }
        if self.mapper.basis != Basis::Linear {
            return self.slow(hit);
        }
        let owner = tri.owner & !DOUBLE_SIDED;
        let [rx, ry, rw, rh] = tri.rect.map(i64::from);
        let uv = tri.uv[0] * (1.0 - hit.u - hit.v) + tri.uv[1] * hit.u + tri.uv[2] * hit.v;
        let q = uv * Vec2::new(rw as f32, rh as f32);
        let corners = bilinear_corners(q);
        let page = &self.pages[tri.page as usize];
        let page_w = self.widths[tri.page as usize];
        let mut found = [(Vec3::ZERO, 0.0f32); 4];
        let (mut n, mut sum) = (0, 0.0f32);
        for (cx, cy, w) in corners {
            if w <= 0.0 || cx < 0 || cy < 0 || cx >= rw || cy >= rh {
                continue;
            }
            let t = page[((ry + cy) * page_w + rx + cx) as usize];
            if t.owner & !SPLIT != owner {
                continue;
            }
            if t.owner & SPLIT != 0 {
                // Geometry cuts this corner's support: the mapper traces its visibility.
                return self.slow(hit);
            }
            found[n] = (Vec3::from_array(t.b), w);
            sum += w;
            n += 1;
        }
        if n == 0 || sum <= 0.0 {
            return self.slow(hit);
        }
        found[..n]
            .iter()
            .fold(Vec3::ZERO, |s, &(b, w)| s + b * (w / sum))
    }

    /// B at a hit through the mapper's weights.
    fn slow(&self, hit: &Hit) -> Vec3 {
        let mut out = [(0u32, 0f32); 4];
        let n = self.mapper.weights(hit, &mut out);
        out[..n]
            .iter()
            .fold(Vec3::ZERO, |s, &(j, w)| s + self.b[j as usize] * w)
    }

    /// Bytes held per page texel and per triangle.
    pub const BYTES_PER_PAGE_TEXEL: u64 = size_of::<Texel>() as u64;
    /// Bytes held per triangle.
    pub const BYTES_PER_TRIANGLE: u64 = size_of::<Triangle>() as u64;
}
