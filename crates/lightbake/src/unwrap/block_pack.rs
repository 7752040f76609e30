//! Charts packed on 4×4 blocks for BC6H pages, so that no block holds a texel two charts read.
//!
//! BC6H stores each 4×4 block as two endpoints and per-texel indices between them
//! ([Khronos Data Format 1.3, §BC6H](https://registry.khronos.org/DataFormat/specs/1.3/dataformat.1.3.html#bptc_bc6h)),
//! so a block that holds texels of two charts spends its endpoints on both, and each chart's
//! texels take the other's error. Here every chart owns whole blocks:
//!
//! 1. **What a chart reads.** Bilinear filtering at a point `p` of the chart reads the texels
//!    whose centres lie within one texel of `p` on each axis. A texel is the chart's when a
//!    triangle of the chart meets the open square of half-width [`reach`] around its centre
//!    (a separating-axis test): wider than the bilinear footprint (1), so that the charts'
//!    covered texels keep the padding between them.
//! 2. **Its blocks.** Those texels, moved by a whole number of texels (so the chart's
//!    sampling is unchanged), fall on a set of 4×4 blocks. A small chart tries the 16 offsets
//!    within a block and keeps the one that needs the fewest blocks; a large one starts its
//!    first texel on a block.
//! 3. **Packing.** The charts' block masks are packed first-fit, tallest first, on a grid of
//!    blocks about as wide as it is tall, each at the first free place scanning down the rows.
//!    Masks are shapes, not rectangles: a small chart can sit in a larger one's notch.

use std::collections::HashMap;

use glam::Vec2;

use super::items::{Item, assemble, shelf_pack};
use super::{Density, MeshUnwrap};
use crate::scene::Mesh;
use crate::settings::BakeSettings;

/// Half-width of the square around a texel's centre that a chart must meet to own the texel,
/// texels: `⌈padding / 2⌉ + 1` (2 at the default padding of 2; bilinear filtering reads within
/// 1). Two charts that own no texel in common then keep `padding` empty texels between the
/// texels they touch, however their edges fall between texel centres (a chart ending exactly
/// on a texel's edge touches that texel).
pub(super) fn reach(padding: u32) -> f32 {
    (padding.div_ceil(2) + 1) as f32
}

/// Charts of at most this many texels in their read box try all 16 offsets in a block.
const PHASE_SEARCH_TEXELS: usize = 64 * 64;

/// The block cells one item covers at its chosen offset.
struct Mask {
    /// Blocks across and down.
    width: u32,
    height: u32,
    /// One bit per block, row by row, `words` words a row.
    bits: Vec<u64>,
    words: usize,
    /// The item's corner relative to its mask's top-left block, texels.
    offset: (i64, i64),
    /// Blocks covered.
    count: u32,
}

/// The texels `item` reads (see the module docs): their box's first texel and size, and a
/// bit per texel of the box.
fn read_texels(item: &Item, half: f32) -> (i64, i64, usize, usize, Vec<bool>) {
    let (lo, hi) = item.vertices.iter().fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(_, p)| (lo.min(p), hi.max(p)),
    );
    if item.vertices.is_empty() || !(lo.is_finite() && hi.is_finite()) {
        return (0, 0, 1, 1, vec![true]);
    }
    let x0 = (lo.x - 0.5 - half).floor() as i64;
    let y0 = (lo.y - 0.5 - half).floor() as i64;
    let w = ((hi.x - 0.5 + half).ceil() as i64 - x0 + 1).max(1) as usize;
    let h = ((hi.y - 0.5 + half).ceil() as i64 - y0 + 1).max(1) as usize;
    let mut bits = vec![false; w * h];
    // A triangle touching a square only along its border does not read it.
    let e = half - 1e-3;
    for &(_, corners, _) in &item.triangles {
        let tri = corners.map(|v| item.vertices[v as usize].1);
        let (tlo, thi) = (
            tri[0].min(tri[1]).min(tri[2]),
            tri[0].max(tri[1]).max(tri[2]),
        );
        let axes: Vec<(Vec2, f32, f32)> = (0..3)
            .filter_map(|k| {
                let n = (tri[(k + 1) % 3] - tri[k]).perp();
                (n.length_squared() > 1e-12).then(|| {
                    let d = tri.map(|p| n.dot(p));
                    (n, d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
                })
            })
            .collect();
        let tx0 = ((tlo.x - 0.5 - e).floor() as i64).max(x0);
        let tx1 = ((thi.x - 0.5 + e).ceil() as i64).min(x0 + w as i64 - 1);
        let ty0 = ((tlo.y - 0.5 - e).floor() as i64).max(y0);
        let ty1 = ((thi.y - 0.5 + e).ceil() as i64).min(y0 + h as i64 - 1);
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let c = Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5);
                let apart = tlo.x >= c.x + e
                    || thi.x <= c.x - e
                    || tlo.y >= c.y + e
                    || thi.y <= c.y - e
                    || axes.iter().any(|&(n, lo, hi)| {
                        let (at, reach) = (n.dot(c), e * (n.x.abs() + n.y.abs()));
                        hi <= at - reach || lo >= at + reach
                    });
                if !apart {
                    bits[(ty - y0) as usize * w + (tx - x0) as usize] = true;
                }
            }
        }
    }
    // Cropped to the texels read (the box above is the vertices' reach).
    let (mut lo, mut hi) = ((w, h), (0, 0));
    for j in 0..h {
        for i in (0..w).filter(|&i| bits[j * w + i]) {
            (lo, hi) = ((lo.0.min(i), lo.1.min(j)), (hi.0.max(i), hi.1.max(j)));
        }
    }
    if lo.0 > hi.0 {
        return (x0, y0, 1, 1, vec![true]);
    }
    let (cw, ch) = (hi.0 - lo.0 + 1, hi.1 - lo.1 + 1);
    let cropped = (0..ch)
        .flat_map(|j| {
            bits[(lo.1 + j) * w + lo.0..(lo.1 + j) * w + lo.0 + cw]
                .iter()
                .copied()
        })
        .collect();
    (x0 + lo.0 as i64, y0 + lo.1 as i64, cw, ch, cropped)
}

/// The blocks the read texels fall on when the item is moved by `phase` texels.
fn mask_at(read: &(i64, i64, usize, usize, Vec<bool>), phase: (i64, i64)) -> Mask {
    let (x0, y0, w, h, bits) = read;
    let bx0 = (x0 + phase.0).div_euclid(4);
    let by0 = (y0 + phase.1).div_euclid(4);
    let width = ((x0 + phase.0 + *w as i64 - 1).div_euclid(4) - bx0 + 1) as u32;
    let height = ((y0 + phase.1 + *h as i64 - 1).div_euclid(4) - by0 + 1) as u32;
    let words = (width as usize).div_ceil(64);
    let mut mask = Mask {
        width,
        height,
        bits: vec![0; words * height as usize],
        words,
        offset: (phase.0 - 4 * bx0, phase.1 - 4 * by0),
        count: 0,
    };
    for j in 0..*h {
        for i in 0..*w {
            if bits[j * w + i] {
                let bx = ((x0 + phase.0 + i as i64).div_euclid(4) - bx0) as usize;
                let by = ((y0 + phase.1 + j as i64).div_euclid(4) - by0) as usize;
                let word = &mut mask.bits[by * words + bx / 64];
                if *word & (1 << (bx % 64)) == 0 {
                    *word |= 1 << (bx % 64);
                    mask.count += 1;
                }
            }
        }
    }
    mask
}

/// The item's mask at the offset needing the fewest blocks (see the module docs).
fn item_mask(item: &Item, half: f32) -> Mask {
    let read = read_texels(item, half);
    let aligned = ((-read.0).rem_euclid(4), (-read.1).rem_euclid(4));
    if read.2 * read.3 > PHASE_SEARCH_TEXELS {
        return mask_at(&read, aligned);
    }
    let mut best = mask_at(&read, aligned);
    for py in 0..4 {
        for px in 0..4 {
            let m = mask_at(&read, (px, py));
            if m.count < best.count {
                best = m;
            }
        }
    }
    best
}

/// The grid of blocks being filled: one bit per block.
struct Grid {
    width: u32,
    words: usize,
    rows: Vec<Vec<u64>>,
    /// Blocks taken in each row.
    taken: Vec<u32>,
}

impl Grid {
    fn row(&self, y: usize) -> Option<&[u64]> {
        self.rows.get(y).map(Vec::as_slice)
    }

    /// Whether `mask` fits with its top-left block at (`x`, `y`).
    fn fits(&self, mask: &Mask, x: u32, y: usize) -> bool {
        let (word, shift) = ((x / 64) as usize, x % 64);
        (0..mask.height as usize).all(|r| {
            let Some(row) = self.row(y + r) else {
                return true;
            };
            let m = &mask.bits[r * mask.words..(r + 1) * mask.words];
            m.iter().enumerate().all(|(k, &bits)| {
                let low = bits << shift;
                let high = if shift == 0 { 0 } else { bits >> (64 - shift) };
                row.get(word + k).is_none_or(|g| g & low == 0)
                    && row.get(word + k + 1).is_none_or(|g| g & high == 0)
            })
        })
    }

    fn place(&mut self, mask: &Mask, x: u32, y: usize) {
        let (word, shift) = ((x / 64) as usize, x % 64);
        while self.rows.len() < y + mask.height as usize {
            self.rows.push(vec![0; self.words + 1]);
            self.taken.push(0);
        }
        for r in 0..mask.height as usize {
            let m = &mask.bits[r * mask.words..(r + 1) * mask.words];
            for (k, &bits) in m.iter().enumerate() {
                self.rows[y + r][word + k] |= bits << shift;
                if shift > 0 {
                    self.rows[y + r][word + k + 1] |= bits >> (64 - shift);
                }
                self.taken[y + r] += bits.count_ones();
            }
        }
    }
}

/// Packs items, one mesh's charts or pieces, into its rectangle for the page format: on 4×4
/// blocks of their own for BC6H pages ([`pack_blocks`]), else shelf-packed with the padding
/// between them. Returns each item's corner and the rectangle's size.
pub(super) fn pack_items(items: &[Item], settings: &BakeSettings) -> (Vec<(i32, i32)>, u32, u32) {
    let (padding, max_page) = (settings.layout.padding, settings.layout.max_page_size);
    if settings.formats.ktx2_bc6h {
        pack_blocks(items, reach(padding), max_page)
    } else {
        let (corners, w, h) = shelf_pack(items, padding + 1, max_page);
        let signed = corners.iter().map(|&(x, y)| (x as i32, y as i32)).collect();
        (signed, w, h)
    }
}

/// Packs `items` so that no 4×4 block holds a texel two of them read (see the module docs);
/// each item should hold one chart. Returns each item's corner (texels: where its origin goes;
/// its texels are all inside the rectangle) and the rectangle's width and height, multiples of
/// 4; a rectangle wider or taller than `max_page` means the items do not fit.
pub(super) fn pack_blocks(
    items: &[Item],
    reach: f32,
    max_page: u32,
) -> (Vec<(i32, i32)>, u32, u32) {
    let masks: Vec<Mask> = items.iter().map(|it| item_mask(it, reach)).collect();
    let area: f64 = masks.iter().map(|m| m.count as f64).sum();
    let widest = masks.iter().map(|m| m.width).max().unwrap_or(1);
    let width = ((1.1 * area).sqrt().ceil() as u32)
        .max(widest)
        .min((max_page / 4).max(widest));
    let mut grid = Grid {
        width,
        words: (width as usize).div_ceil(64),
        rows: Vec::new(),
        taken: Vec::new(),
    };
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| {
        (masks[b].height, masks[b].count)
            .cmp(&(masks[a].height, masks[a].count))
            .then(a.cmp(&b))
    });
    let mut corners = vec![(0, 0); items.len()];
    let (mut used_w, mut first_open) = (0u32, 0usize);
    for i in order {
        let m = &masks[i];
        while grid.taken.get(first_open).is_some_and(|&t| t == grid.width) {
            first_open += 1;
        }
        let first_row = m.bits[..m.words]
            .iter()
            .map(|b| b.count_ones())
            .sum::<u32>();
        let mut y = first_open;
        let x = loop {
            let taken = grid.taken.get(y).copied().unwrap_or(0);
            if grid.width - taken >= first_row
                && let Some(x) = (0..=grid.width - m.width).find(|&x| grid.fits(m, x, y))
            {
                break x;
            }
            // Past the last row every place is free, so the loop ends there at the latest.
            y += 1;
        };
        grid.place(m, x, y);
        used_w = used_w.max(x + m.width);
        // A corner may lie left of or above the mask's first block (an item whose texels
        // start past its corner), never its texels: they lie on the mask's blocks.
        let corner = |at: u32, off: i64| (4 * at as i64 + off) as i32;
        corners[i] = (corner(x, m.offset.0), corner(y as u32, m.offset.1));
    }
    let rows = grid.rows.len() as u32;
    (corners, 4 * used_w.max(1), 4 * rows.max(1))
}

/// `item`'s charts as items of one chart each, every chart moved by whole texels so its
/// lowest vertex lies in [½, 1½) (its sampling unchanged). Triangles of no chart become one
/// item on the middle of a texel.
pub(super) fn split_charts(item: &Item) -> Vec<Item> {
    let mut groups: HashMap<u32, Vec<usize>> = HashMap::new();
    for (k, tri) in item.triangles.iter().enumerate() {
        groups.entry(tri.2).or_default().push(k);
    }
    let mut keys: Vec<u32> = groups.keys().copied().collect();
    keys.sort_unstable();
    keys.into_iter()
        .map(|chart| {
            let mut local: HashMap<u32, u32> = HashMap::new();
            let mut out = Item {
                charts: u32::from(chart != u32::MAX),
                ..Item::default()
            };
            for &k in &groups[&chart] {
                let (t, corners, _) = item.triangles[k];
                let corners = corners.map(|v| {
                    let next = out.vertices.len() as u32;
                    *local.entry(v).or_insert_with(|| {
                        out.vertices.push(item.vertices[v as usize]);
                        next
                    })
                });
                let local_chart = if chart == u32::MAX { u32::MAX } else { 0 };
                out.triangles.push((t, corners, local_chart));
            }
            let lo = out
                .vertices
                .iter()
                .fold(Vec2::splat(f32::INFINITY), |lo, v| lo.min(v.1));
            let hi = out
                .vertices
                .iter()
                .fold(Vec2::splat(f32::NEG_INFINITY), |hi, v| hi.max(v.1));
            let shift = (lo - Vec2::splat(0.5)).floor();
            for v in &mut out.vertices {
                v.1 = if chart == u32::MAX || !shift.is_finite() {
                    Vec2::splat(0.5)
                } else {
                    v.1 - shift
                };
            }
            let extent = if chart == u32::MAX {
                Vec2::ONE
            } else {
                hi - shift
            };
            out.width = extent.x.ceil().max(1.0) as u32;
            out.height = extent.y.ceil().max(1.0) as u32;
            out
        })
        .collect()
}

/// `unwrap` with each of its charts moved by a whole number of texels (its sampling
/// unchanged) onto 4×4 blocks of its own, packed by [`pack_items`]; its origin, density and
/// `scaled_to_fit` kept. `Err((width, height))`: the packed charts need a page that large,
/// over `layout.max_page_size`.
pub(super) fn onto_blocks(
    mesh: &Mesh,
    unwrap: &MeshUnwrap,
    settings: &BakeSettings,
) -> Result<MeshUnwrap, (u32, u32)> {
    let items = chart_items(unwrap);
    let (corners, width, height) = pack_items(&items, settings);
    if width.max(height) > settings.layout.max_page_size {
        return Err((width, height));
    }
    let same = Density {
        texels_per_unit: 1.0,
        texels_per_metre: unwrap.texels_per_metre,
    };
    let mut moved = assemble(mesh, &items, &corners, width, height, same, 1.0);
    moved.origin = unwrap.origin;
    moved.scaled_to_fit = unwrap.scaled_to_fit;
    Ok(moved)
}

/// A mesh's unwrap as items of one chart each (see [`split_charts`]).
fn chart_items(unwrap: &MeshUnwrap) -> Vec<Item> {
    split_charts(&unwrap_item(unwrap))
}

/// A mesh's unwrap as one item (texel coordinates, its charts numbered as they are).
fn unwrap_item(unwrap: &MeshUnwrap) -> Item {
    let size = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let source = |v: usize| unwrap.xref.as_ref().map_or(v as u32, |x| x[v]);
    Item {
        width: unwrap.width,
        height: unwrap.height,
        vertices: (unwrap.uv1.iter().enumerate())
            .map(|(v, uv)| (source(v), *uv * size))
            .collect(),
        triangles: (0..unwrap.indices.len() / 3)
            .map(|t| {
                let corners = [0, 1, 2].map(|k| unwrap.indices[3 * t + k]);
                (t as u32, corners, unwrap.triangle_charts[t])
            })
            .collect(),
        charts: unwrap.chart_count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An item of one chart: the triangles given in texel coordinates.
    fn item(tris: &[[Vec2; 3]]) -> Item {
        let mut it = Item {
            charts: 1,
            ..Item::default()
        };
        for (t, tri) in tris.iter().enumerate() {
            let base = it.vertices.len() as u32;
            it.vertices.extend(tri.iter().map(|&p| (0, p)));
            it.triangles.push((t as u32, [base, base + 1, base + 2], 0));
        }
        it
    }

    /// The texels the item reads (see [`read_texels`]) on the page with its corner at
    /// `corner`.
    fn page_reads(it: &Item, corner: (i32, i32)) -> Vec<(i64, i64)> {
        let (x0, y0, w, h, bits) = read_texels(it, 1.0);
        (0..w * h)
            .filter(|&k| bits[k])
            .map(|k| {
                let (i, j) = ((k % w) as i64, (k / w) as i64);
                (x0 + i + corner.0 as i64, y0 + j + corner.1 as i64)
            })
            .collect()
    }

    fn tri(a: (f32, f32), b: (f32, f32), c: (f32, f32)) -> [Vec2; 3] {
        [a, b, c].map(|(x, y)| Vec2::new(x, y))
    }

    #[test]
    fn a_chart_of_one_texel_takes_one_block_and_a_larger_one_its_blocks() {
        // Two triangles filling texel (0, 0)'s centre square reads texels 0..=1 by bilinear
        // filtering at most: one block at the right offset.
        let small = item(&[tri((0.5, 0.5), (1.5, 0.5), (0.5, 1.5))]);
        assert_eq!(item_mask(&small, 1.0).count, 1);
        // A 10 × 2 texel strip reads 12 × 4 texels (or 11 × 3 inside): 3 blocks across at
        // best, one down.
        let strip = item(&[
            tri((0.5, 0.5), (10.5, 0.5), (0.5, 2.5)),
            tri((10.5, 0.5), (10.5, 2.5), (0.5, 2.5)),
        ]);
        let m = item_mask(&strip, 1.0);
        assert_eq!((m.width, m.height, m.count), (3, 1, 3));
    }

    #[test]
    fn packed_charts_share_no_block_and_stay_in_the_rectangle() {
        // Triangles and L shapes of many sizes, at odd sub-texel offsets.
        let mut items = Vec::new();
        for k in 0..60u32 {
            let s = 1.0 + (k % 7) as f32 * 2.3 + (k % 3) as f32 * 0.37;
            let o = 0.5 + (k % 5) as f32 * 0.24999;
            items.push(if k % 2 == 0 {
                item(&[tri((o, o), (o + s, o), (o, o + 0.6 * s))])
            } else {
                item(&[
                    tri((o, o), (o + s, o), (o, o + 1.0)),
                    tri((o, o), (o + 1.0, o), (o, o + s)),
                ])
            });
        }
        // Charts whose texels start a texel past their corner and fit one block only when
        // moved by 3: their corners lie left of and above their blocks.
        for _ in 0..4 {
            items.push(item(&[tri(
                (1.4999, 1.4999),
                (4.4999, 1.4999),
                (1.4999, 4.4999),
            )]));
        }
        assert_eq!(item_mask(&items[60], 1.0).offset, (-1, -1));
        let (corners, w, h) = pack_blocks(&items, 1.0, 4096);
        assert!(w % 4 == 0 && h % 4 == 0);
        let mut owner: HashMap<(i64, i64), usize> = HashMap::new();
        let mut blocks = 0;
        for (i, (it, &c)) in items.iter().zip(&corners).enumerate() {
            for (x, y) in page_reads(it, c) {
                assert!(
                    x >= 0 && y >= 0 && x < w as i64 && y < h as i64,
                    "item {i} reads ({x}, {y}) outside {w} × {h}"
                );
                let other = *owner.entry((x / 4, y / 4)).or_insert(i);
                assert!(c.0 > -4 && c.1 > -4);
                assert_eq!(
                    other,
                    i,
                    "items {other} and {i} read block ({}, {})",
                    x / 4,
                    y / 4
                );
            }
        }
        for (i, m) in items.iter().map(|it| item_mask(it, 1.0)).enumerate() {
            let mine = owner.values().filter(|&&o| o == i).count() as u32;
            assert!(mine <= m.count, "{i}: {mine} > {}", m.count);
            blocks += m.count;
        }
        // Masks nest: the rectangle is not much larger than the blocks the charts need.
        assert!(
            (w * h / 16) as f64 <= 1.6 * blocks as f64,
            "{w} × {h} for {blocks} blocks"
        );
    }

    #[test]
    fn splitting_moves_each_chart_by_whole_texels() {
        let mut it = item(&[
            tri((0.7, 0.6), (3.7, 0.6), (0.7, 2.6)),
            tri((20.25, 9.5), (25.25, 9.5), (20.25, 12.5)),
        ]);
        it.triangles[1].2 = 1;
        it.charts = 2;
        let parts = split_charts(&it);
        assert_eq!(parts.len(), 2);
        for (part, first) in parts
            .iter()
            .zip([Vec2::new(0.7, 0.6), Vec2::new(20.25, 9.5)])
        {
            let moved = first - part.vertices[0].1;
            assert_eq!(moved, moved.round(), "{moved}");
            assert!(part.vertices.iter().all(|v| v.1.min_element() >= 0.5));
            assert!(part.vertices[0].1.max_element() < 1.5);
        }
    }
}
