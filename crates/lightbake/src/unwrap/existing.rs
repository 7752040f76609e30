//! A mesh's own `TEXCOORD_1`, validated (in [0, 1], no texel claimed twice) and kept, with
//! its charts found from shared vertices (for BC6H pages `super::unwrap_scene` moves them by
//! whole texels onto 4×4 blocks of their own, `super::block_pack::onto_blocks`).

use glam::Vec2;

use super::{Density, MeshUnwrap, UvOrigin};
use crate::scene::Mesh;
use crate::settings::BakeSettings;

/// Validates a mesh's own `TEXCOORD_1` and sizes its rectangle for `tpu` texels per mesh unit.
pub(super) fn existing_uvs(
    mesh: &Mesh,
    request: Density,
    settings: &BakeSettings,
) -> Result<MeshUnwrap, String> {
    let tpu = request.texels_per_unit;
    let uv = mesh.uv1.as_ref().ok_or("no TEXCOORD_1")?;
    let tol = 1e-4;
    if let Some(bad) = uv
        .iter()
        .position(|p| p.min_element() < -tol || p.max_element() > 1.0 + tol)
    {
        return Err(format!("vertex {bad} has uv {:?}, outside [0, 1]", uv[bad]));
    }
    let uv_area: f32 = (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.triangle(t);
            0.5 * (uv[b] - uv[a]).perp_dot(uv[c] - uv[a]).abs()
        })
        .sum();
    if uv_area <= 1e-9 {
        return Err("its triangles cover no area in UV space".into());
    }
    let texels = (tpu * tpu * mesh.area() / uv_area).sqrt().ceil() as u32;
    let size = texels.clamp(8, settings.layout.max_page_size);
    let overlapping = overlapping_texels(mesh, uv, size, size);
    if overlapping > 0 {
        return Err(format!(
            "{overlapping} texels of a {size}² lightmap are covered by more than one triangle (overlapping or mirrored UVs)"
        ));
    }
    let (triangle_charts, chart_count) = uv_charts(mesh);
    Ok(MeshUnwrap {
        width: size,
        height: size,
        uv1: uv.iter().map(|p| p.clamp(Vec2::ZERO, Vec2::ONE)).collect(),
        xref: None,
        indices: mesh.indices.clone(),
        triangle_charts,
        chart_count,
        origin: UvOrigin::Existing,
        texels_per_metre: size as f32 * (uv_area / mesh.area()).sqrt() * request.texels_per_metre
            / tpu,
        scaled_to_fit: size < texels,
    })
}

/// Counts texel centres claimed by more than one triangle, rasterising with the top-left rule
/// so triangles that share an edge never both claim a centre on it.
pub fn overlapping_texels(mesh: &Mesh, uv: &[Vec2], width: u32, height: u32) -> usize {
    let mut owner = vec![u32::MAX; (width * height) as usize];
    let mut overlaps = 0usize;
    let scale = glam::DVec2::new(width as f64, height as f64);
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let mut p = [uv[a], uv[b], uv[c]].map(|q| q.as_dvec2() * scale);
        let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        if area == 0.0 {
            continue;
        }
        if area < 0.0 {
            p.swap(1, 2);
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
        let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
        let x1 = ((hi.x - 0.5).floor() as i64).min(width as i64 - 1);
        let y1 = ((hi.y - 0.5).floor() as i64).min(height as i64 - 1);
        for y in y0 as i64..=y1 {
            for x in x0 as i64..=x1 {
                let q = glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                if inside_top_left(&p, q) {
                    let slot = &mut owner[(y as u32 * width + x as u32) as usize];
                    if *slot != u32::MAX && *slot != t as u32 {
                        overlaps += 1;
                    }
                    *slot = t as u32;
                }
            }
        }
    }
    overlaps
}

/// Point-in-triangle for a counter-clockwise (positive area, y down) triangle with the
/// top-left fill rule: points on an edge belong to it only for "top" or "left" edges.
fn inside_top_left(p: &[glam::DVec2; 3], q: glam::DVec2) -> bool {
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        let e = (b - a).perp_dot(q - a);
        if e < 0.0 {
            return false;
        }
        if e == 0.0 {
            let d = b - a;
            let top_or_left = (d.y == 0.0 && d.x < 0.0) || d.y > 0.0;
            if !top_or_left {
                return false;
            }
        }
    }
    true
}

/// Charts of a mesh with its own UVs: triangles connected through shared vertex indices.
fn uv_charts(mesh: &Mesh) -> (Vec<u32>, u32) {
    let n = mesh.positions.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let ra = find(&mut parent, a as u32);
        for v in [b, c] {
            let rv = find(&mut parent, v as u32);
            if rv != ra {
                parent[rv as usize] = ra;
            }
        }
    }
    let mut ids = vec![u32::MAX; n];
    let mut count = 0u32;
    let charts = (0..mesh.triangle_count())
        .map(|t| {
            let root = find(&mut parent, mesh.triangle(t)[0] as u32) as usize;
            if ids[root] == u32::MAX {
                ids[root] = count;
                count += 1;
            }
            ids[root]
        })
        .collect();
    (charts, count)
}
