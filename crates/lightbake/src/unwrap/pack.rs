//! Shelf packing of the instances' rectangles onto atlas pages.

use super::{InstanceRect, Layout, PageSize};
use crate::scene::Scene;
use crate::settings::BakeSettings;

/// Shelf packing of every baked instance's rectangle into pages (tallest first, stable
/// order). Shelves wrap at a width chosen for a roughly square page (the square root of the
/// total rectangle area, at least the widest rectangle, at most `max_page_size`). For BC6H
/// pages every rectangle starts on a 4×4 block and the next one starts on the first block past
/// its padding, so no block holds texels of two instances.
pub(super) fn pack_instances(scene: &Scene, settings: &BakeSettings, layout: &mut Layout) {
    let order: Vec<(usize, u32, u32)> = scene
        .instances
        .iter()
        .enumerate()
        .filter(|(_, inst)| inst.bake)
        .filter_map(|(i, inst)| {
            layout.meshes[inst.mesh]
                .as_ref()
                .map(|u| (i, u.width, u.height))
        })
        .collect();
    let (rects, pages) = shelf_pack(order, settings);
    for (i, rect) in rects {
        layout.instances[i] = Some(rect);
    }
    layout.pages = pages;
}

/// Shelf packing of rectangles `(instance, width, height)` onto new pages (see
/// [`pack_instances`]): each instance's rectangle (pages numbered from 0) and the pages.
pub(super) fn shelf_pack(
    mut order: Vec<(usize, u32, u32)>,
    settings: &BakeSettings,
) -> (Vec<(usize, InstanceRect)>, Vec<PageSize>) {
    let gap = settings.layout.padding;
    let block = if settings.formats.ktx2_bc6h { 4 } else { 1 };
    let up = |v: u32| v.next_multiple_of(block);
    let max = settings.layout.max_page_size;
    order.sort_by(|a, b| b.2.cmp(&a.2).then(b.1.cmp(&a.1)).then(a.0.cmp(&b.0)));
    let area: u64 = order
        .iter()
        .map(|&(_, w, h)| (w + gap) as u64 * (h + gap) as u64)
        .sum();
    let widest = order.iter().map(|&(_, w, _)| w).max().unwrap_or(0);
    let shelf_width = ((area as f64).sqrt().ceil() as u32).max(widest).min(max);

    struct Shelf {
        y: u32,
        height: u32,
        x: u32,
    }
    struct Page {
        shelves: Vec<Shelf>,
        used_w: u32,
        used_h: u32,
    }
    let mut pages: Vec<Page> = Vec::new();
    let mut rects = Vec::with_capacity(order.len());
    for (inst, w, h) in order {
        let mut placed = None;
        'pages: for (pi, page) in pages.iter_mut().enumerate() {
            for shelf in &mut page.shelves {
                if h <= shelf.height && shelf.x + w <= shelf_width {
                    placed = Some((pi, shelf.x, shelf.y));
                    shelf.x += up(w + gap);
                    break 'pages;
                }
            }
            let next_y = page.shelves.last().map_or(0, |s| up(s.y + s.height + gap));
            if next_y + h <= max {
                page.shelves.push(Shelf {
                    y: next_y,
                    height: h,
                    x: up(w + gap),
                });
                placed = Some((pi, 0, next_y));
                break;
            }
        }
        let (pi, x, y) = placed.unwrap_or_else(|| {
            pages.push(Page {
                shelves: vec![Shelf {
                    y: 0,
                    height: h,
                    x: up(w + gap),
                }],
                used_w: 0,
                used_h: 0,
            });
            (pages.len() - 1, 0, 0)
        });
        let page = &mut pages[pi];
        page.used_w = page.used_w.max(x + w);
        page.used_h = page.used_h.max(y + h);
        rects.push((
            inst,
            InstanceRect {
                page: pi as u32,
                x,
                y,
                width: w,
                height: h,
            },
        ));
    }
    // Pages are trimmed to what is used (plus the gap, so dilation has room), rounded up to a
    // multiple of 4 for block compression.
    let sizes = pages
        .iter()
        .map(|p| PageSize {
            width: round4((p.used_w + gap).min(max)),
            height: round4((p.used_h + gap).min(max)),
        })
        .collect();
    (rects, sizes)
}

fn round4(v: u32) -> u32 {
    v.div_ceil(4) * 4
}
