//! Charts and pieces as items to pack into a mesh's rectangle, shelf packing, and the mesh's
//! unwrap assembled from the packed items.

use glam::Vec2;

use super::{Density, MeshUnwrap, UvOrigin};
use crate::scene::Mesh;

/// One rectangle to pack: its local vertices (source vertex, position in texels from the
/// rectangle's corner) and triangles (source triangle, local vertices, local chart).
#[derive(Default)]
pub(super) struct Item {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) vertices: Vec<(u32, Vec2)>,
    pub(super) triangles: Vec<(u32, [u32; 3], u32)>,
    pub(super) charts: u32,
}

/// Shelf-packs items (tallest first) with `gap` texels between them; returns each item's
/// corner and the rectangle's size.
pub(super) fn shelf_pack(items: &[Item], gap: u32, max_page: u32) -> (Vec<(u32, u32)>, u32, u32) {
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| items[b].height.cmp(&items[a].height).then(a.cmp(&b)));
    let area: f64 = items
        .iter()
        .map(|i| (i.width + gap) as f64 * (i.height + gap) as f64)
        .sum();
    let widest = items.iter().map(|i| i.width).max().unwrap_or(1);
    let shelf_width = (area.sqrt().ceil() as u32)
        .max(widest)
        .min(max_page.max(widest));
    let mut corners = vec![(0, 0); items.len()];
    let (mut x, mut y, mut shelf_h, mut width) = (0u32, 0u32, 0u32, 0u32);
    for i in order {
        let it = &items[i];
        if x > 0 && x + it.width > shelf_width {
            y += shelf_h + gap;
            x = 0;
            shelf_h = 0;
        }
        corners[i] = (x, y);
        width = width.max(x + it.width);
        x += it.width + gap;
        shelf_h = shelf_h.max(it.height);
    }
    (corners, width.max(1), (y + shelf_h).max(1))
}

/// The factor on the density that should bring a `width × height` shelf packing into a
/// `max_page`² page. Shelves wrap at the page's width, so the area tells the scale better than
/// the longer side (which only bounds it); 3% is taken off so the next attempt fits.
pub(super) fn shrink_to_page(width: u32, height: u32, max_page: u32) -> f64 {
    let (w, h, page) = (width as f64, height as f64, max_page as f64);
    let by_area = (page * page / (w * h)).sqrt().min(1.0);
    0.97 * by_area.max(page / w.max(h))
}

/// The mesh's unwrap from its packed items: output vertices item by item, source triangle
/// order kept, charts numbered across items.
pub(super) fn assemble(
    mesh: &Mesh,
    items: &[Item],
    corners: &[(i32, i32)],
    width: u32,
    height: u32,
    request: Density,
    tpu: f64,
) -> MeshUnwrap {
    let size = Vec2::new(width as f32, height as f32);
    let mut uv1 = Vec::new();
    let mut xref = Vec::new();
    let mut indices = vec![0u32; 3 * mesh.triangle_count()];
    let mut triangle_charts = vec![u32::MAX; mesh.triangle_count()];
    let mut chart_base = 0u32;
    for (item, &(x, y)) in items.iter().zip(corners) {
        let base = uv1.len() as u32;
        let offset = Vec2::new(x as f32, y as f32);
        for &(src, p) in &item.vertices {
            uv1.push(((p + offset) / size).clamp(Vec2::ZERO, Vec2::ONE));
            xref.push(src);
        }
        for &(t, corners, chart) in &item.triangles {
            let t = t as usize;
            for k in 0..3 {
                indices[3 * t + k] = base + corners[k];
            }
            triangle_charts[t] = if chart == u32::MAX {
                u32::MAX
            } else {
                chart_base + chart
            };
        }
        chart_base += item.charts;
    }
    let scale = tpu / request.texels_per_unit as f64;
    MeshUnwrap {
        width,
        height,
        uv1,
        xref: Some(xref),
        indices,
        triangle_charts,
        chart_count: chart_base,
        origin: UvOrigin::Xatlas,
        texels_per_metre: (request.texels_per_metre as f64 * scale) as f32,
        scaled_to_fit: scale < 1.0,
    }
}
