//! A mesh's charts scaled one by one and packed again: how the texel density that follows the
//! light (`crate::density`) gives each chart its own share of the texel budget.
//!
//! Each chart of an xatlas unwrap keeps its shape: its texel-space vertices are scaled about
//! their lower corner by the chart's factor, moved to start half a texel in (so its texels are
//! whole, as for [`super::pieces`]' charts) and the charts are packed into a new rectangle
//! with the padding between them (shelves, or blocks of their own for BC6H pages:
//! [`super::block_pack`]). When the rectangle would not fit a page, every chart is scaled
//! down together until it does.

use std::collections::HashMap;

use glam::Vec2;

use super::block_pack::pack_items;
use super::items::{Item, assemble, shrink_to_page};
use super::{Density, MeshUnwrap, UvOrigin};
use crate::scene::Mesh;
use crate::settings::BakeSettings;

/// `unwrap` with chart `c` drawn at `scales[c]` times its texels per metre (per axis),
/// repacked; `None` when the unwrap is the mesh's own `TEXCOORD_1` (kept as it is) or no
/// scale fits a page. Triangles in no chart (degenerate ones xatlas left out) are kept on a
/// texel of their own.
pub(crate) fn rescale_charts(
    mesh: &Mesh,
    unwrap: &MeshUnwrap,
    scales: &[f32],
    settings: &BakeSettings,
) -> Option<MeshUnwrap> {
    if unwrap.origin != UvOrigin::Xatlas || scales.len() != unwrap.chart_count as usize {
        return None;
    }
    let size = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let source = |v: u32| unwrap.xref.as_ref().map_or(v, |x| x[v as usize]);
    // Per chart, and one more for the triangles of none: (source triangle, output corners).
    let charts = unwrap.chart_count as usize;
    let mut members: Vec<Vec<(u32, [u32; 3])>> = vec![Vec::new(); charts + 1];
    for t in 0..unwrap.indices.len() / 3 {
        let corners = [0, 1, 2].map(|k| unwrap.indices[3 * t + k]);
        let c = unwrap.triangle_charts[t] as usize;
        members[c.min(charts)].push((t as u32, corners));
    }
    let max_page = settings.layout.max_page_size;
    let mut fit = 1.0f32;
    for _attempt in 0..8 {
        let items: Vec<Item> = members
            .iter()
            .enumerate()
            .filter(|(c, tris)| *c < charts || !tris.is_empty())
            .map(|(c, tris)| {
                let scale = scales.get(c).map_or(0.0, |s| s * fit);
                chart_item(
                    tris,
                    c < charts,
                    scale,
                    |v| unwrap.uv1[v as usize] * size,
                    source,
                )
            })
            .collect();
        let (corners, width, height) = pack_items(&items, settings);
        if width.max(height) > max_page {
            fit *= shrink_to_page(width, height, max_page) as f32;
            continue;
        }
        let request = Density {
            texels_per_unit: 1.0,
            texels_per_metre: unwrap.texels_per_metre,
        };
        let mut out = assemble(mesh, &items, &corners, width, height, request, fit as f64);
        out.scaled_to_fit |= unwrap.scaled_to_fit;
        return Some(out);
    }
    None
}

/// One chart as an item to pack: its vertices scaled by `scale` about their lower corner,
/// starting half a texel in. Triangles of no chart (`charted` false) collapse onto the
/// middle of one texel.
fn chart_item(
    tris: &[(u32, [u32; 3])],
    charted: bool,
    scale: f32,
    texel_position: impl Fn(u32) -> Vec2,
    source: impl Fn(u32) -> u32,
) -> Item {
    let mut local: HashMap<u32, u32> = HashMap::new();
    let mut item = Item {
        charts: u32::from(charted),
        ..Item::default()
    };
    for &(t, corners) in tris {
        let corners = corners.map(|v| {
            let next = item.vertices.len() as u32;
            *local.entry(v).or_insert_with(|| {
                item.vertices.push((source(v), texel_position(v)));
                next
            })
        });
        item.triangles
            .push((t, corners, if charted { 0 } else { u32::MAX }));
    }
    let (min, max) = item.vertices.iter().fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(_, p)| (lo.min(p), hi.max(p)),
    );
    if item.vertices.is_empty() {
        item.width = 1;
        item.height = 1;
        return item;
    }
    let scale = if charted { scale } else { 0.0 };
    for v in &mut item.vertices {
        v.1 = (v.1 - min) * scale + Vec2::splat(0.5);
    }
    let extent = (max - min) * scale + Vec2::ONE;
    item.width = extent.x.ceil().max(1.0) as u32;
    item.height = extent.y.ceil().max(1.0) as u32;
    item
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box};
    use crate::unwrap::unwrap_scene;

    #[test]
    fn each_chart_takes_its_scale_squared_in_texels_and_keeps_its_triangles() {
        let scene = cornell_box(CornellLight::Point);
        let settings = BakeSettings::default();
        let layout = unwrap_scene(&scene, &settings, 64.0).unwrap();
        let (m, u) = layout
            .meshes
            .iter()
            .enumerate()
            .find_map(|(m, u)| u.as_ref().filter(|u| u.chart_count >= 2).map(|u| (m, u)))
            .expect("a mesh of several charts");
        let scales: Vec<f32> = (0..u.chart_count)
            .map(|c| if c % 2 == 0 { 2.0 } else { 0.5 })
            .collect();
        let r = rescale_charts(&scene.meshes[m], u, &scales, &settings).unwrap();
        assert_eq!(r.chart_count, u.chart_count);
        assert_eq!(r.triangle_charts, u.triangle_charts);
        assert!(
            r.uv1
                .iter()
                .all(|p| p.min_element() >= 0.0 && p.max_element() <= 1.0)
        );
        for (c, (before, after)) in u.chart_texels().iter().zip(r.chart_texels()).enumerate() {
            let ratio = after / before;
            let want = (scales[c] * scales[c]) as f64;
            assert!(
                (ratio / want - 1.0).abs() < 1e-3,
                "chart {c}: {ratio} against {want}"
            );
        }
        // Same source vertex at every corner.
        let src = |u: &MeshUnwrap, i: usize| {
            u.xref
                .as_ref()
                .map_or(u.indices[i], |x| x[u.indices[i] as usize])
        };
        for i in 0..u.indices.len() {
            assert_eq!(src(u, i), src(&r, i));
        }
        // Charts do not overlap: no texel centre lies inside triangles of two charts.
        let size = Vec2::new(r.width as f32, r.height as f32);
        let mut owner = vec![u32::MAX; (r.width * r.height) as usize];
        for t in 0..r.indices.len() / 3 {
            let p = [0, 1, 2].map(|k| r.uv1[r.indices[3 * t + k] as usize] * size);
            let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            for y in lo.y.floor() as u32..(hi.y.ceil() as u32).min(r.height) {
                for x in lo.x.floor() as u32..(hi.x.ceil() as u32).min(r.width) {
                    let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let side = |a: Vec2, b: Vec2| (b - a).perp_dot(q - a);
                    let s = [side(p[0], p[1]), side(p[1], p[2]), side(p[2], p[0])];
                    let inside = s.iter().all(|&v| v > 1e-4) || s.iter().all(|&v| v < -1e-4);
                    if inside {
                        let o = &mut owner[(y * r.width + x) as usize];
                        assert!(
                            *o == u32::MAX || *o == r.triangle_charts[t],
                            "texel ({x}, {y}) in two charts"
                        );
                        *o = r.triangle_charts[t];
                    }
                }
            }
        }
    }

    #[test]
    fn a_mesh_scaled_past_the_page_is_fitted_to_it() {
        let scene = cornell_box(CornellLight::Point);
        let settings = {
            let mut s = BakeSettings::default();
            s.layout.max_page_size = 256;
            s
        };
        let layout = unwrap_scene(&scene, &settings, 64.0).unwrap();
        let (m, u) = layout
            .meshes
            .iter()
            .enumerate()
            .find_map(|(m, u)| u.as_ref().map(|u| (m, u)))
            .unwrap();
        let scales = vec![16.0; u.chart_count as usize];
        let r = rescale_charts(&scene.meshes[m], u, &scales, &settings).unwrap();
        assert!(r.width <= 256 && r.height <= 256);
        assert!(r.scaled_to_fit);
        assert!(r.texels_per_metre < 16.0 * u.texels_per_metre);
    }
}
