//! Big meshes charted in pieces, in time linear in their triangles.
//!
//! The bundled xatlas grows each chart by re-ranking all of its candidate faces at every step
//! (`AtlasBuilder::updatePriorities`), so a chart costs about the square of its faces: a flat
//! grid of 10 000 triangles took 17 s, of 40 000 over 300 s. A mesh of more than
//! [`BIG_MESH_TRIANGLES`] triangles is therefore charted here first:
//!
//! 1. **Planar regions** — edge-connected triangles whose normals agree within 0.5° and that
//!    lie in one plane — of at least [`MIN_PLANAR`] triangles become charts of their own,
//!    projected orthogonally onto their plane (no distortion at all), cut into tiles when
//!    larger than a page allows.
//! 2. **Pieces**: the other triangles are split by a k-d partition of their centroids into
//!    pieces of at most [`PIECE_TRIANGLES`], and xatlas unwraps each piece on its own.
//! 3. The charts and the pieces' atlases are shelf-packed into the mesh's rectangle, with the
//!    padding between them (for BC6H pages every chart is packed on blocks of its own,
//!    [`super::block_pack`]); the density is lowered until the rectangle fits a page.
//!
//! Chart borders between tiles and pieces are seams like xatlas' own, which the stitch stage
//! makes agree.

use std::collections::HashMap;

use glam::{DVec3, Vec2};

use super::block_pack::{self, pack_items};
use super::items::{Item, assemble, shrink_to_page};
use super::{Density, MeshUnwrap, xatlas};
use crate::error::{BakeError, Result};
use crate::scene::Mesh;
use crate::settings::BakeSettings;

/// Meshes with more triangles than this are charted in pieces.
pub(super) const BIG_MESH_TRIANGLES: usize = 4096;

/// Most triangles xatlas sees at once (a curved piece of 1 024 took 0.24 s, of 256 about a
/// sixteenth of that).
const PIECE_TRIANGLES: usize = 256;

/// Fewest triangles a planar region needs to be charted directly (smaller ones go to xatlas
/// with their neighbours).
pub(super) const MIN_PLANAR: usize = 64;

/// cos 0.5°: normals of one planar region agree this closely.
const PLANAR_COS: f64 = 0.999_961_923;

/// Unit face normals (zero for degenerate triangles) and each vertex's position class
/// (vertices at the same position share one), in f64.
fn face_normals(mesh: &Mesh) -> Vec<DVec3> {
    (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.triangle(t).map(|i| mesh.positions[i].as_dvec3());
            (b - a).cross(c - a).normalize_or_zero()
        })
        .collect()
}

/// Triangles sharing an edge (by position, so split vertices still connect), as a list per
/// triangle.
fn neighbours(mesh: &Mesh) -> Vec<Vec<u32>> {
    let mut class: HashMap<[u32; 3], u32> = HashMap::new();
    let ids: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let next = class.len() as u32;
            *class.entry(p.to_array().map(f32::to_bits)).or_insert(next)
        })
        .collect();
    let mut edges: Vec<(u64, u32)> = Vec::with_capacity(3 * mesh.triangle_count());
    for t in 0..mesh.triangle_count() {
        let v = mesh.triangle(t).map(|i| ids[i]);
        for k in 0..3 {
            let (a, b) = (v[k].min(v[(k + 1) % 3]), v[k].max(v[(k + 1) % 3]));
            if a != b {
                edges.push(((a as u64) << 32 | b as u64, t as u32));
            }
        }
    }
    edges.sort_unstable();
    let mut out = vec![Vec::new(); mesh.triangle_count()];
    for group in edges.chunk_by(|x, y| x.0 == y.0) {
        for &(_, a) in group {
            for &(_, b) in group {
                if a != b {
                    out[a as usize].push(b);
                }
            }
        }
    }
    out
}

/// Planar regions of at least `min_planar` triangles, or that are whole connected parts of the
/// mesh (a loose triangle, a flat card), and the triangles in none.
fn planar_regions(
    mesh: &Mesh,
    normals: &[DVec3],
    extent: f64,
    min_planar: usize,
) -> (Vec<Vec<u32>>, Vec<u32>) {
    let adjacent = neighbours(mesh);
    let tolerance = 1e-6 * extent.max(f64::MIN_POSITIVE);
    let mut region = vec![u32::MAX; mesh.triangle_count()];
    let (mut regions, mut rest) = (Vec::new(), Vec::new());
    for seed in 0..mesh.triangle_count() {
        if region[seed] != u32::MAX {
            continue;
        }
        let n = normals[seed];
        if n == DVec3::ZERO {
            region[seed] = u32::MAX - 1;
            rest.push(seed as u32);
            continue;
        }
        let origin = mesh.positions[mesh.triangle(seed)[0]].as_dvec3();
        let id = regions.len() as u32;
        let mut members = vec![seed as u32];
        region[seed] = id;
        // Whether every neighbour of the region is in it (the region is a loose part).
        let mut whole = true;
        let mut k = 0;
        while k < members.len() {
            let t = members[k] as usize;
            k += 1;
            for &u in &adjacent[t] {
                let u = u as usize;
                if region[u] == id {
                    continue;
                }
                let on_plane = region[u] == u32::MAX
                    && normals[u].dot(n) >= PLANAR_COS
                    && mesh.triangle(u).iter().all(|&v| {
                        (mesh.positions[v].as_dvec3() - origin).dot(n).abs() <= tolerance
                    });
                if on_plane {
                    region[u] = id;
                    members.push(u as u32);
                } else {
                    whole = false;
                }
            }
        }
        if members.len() >= min_planar || whole {
            regions.push(members);
        } else {
            // Back to the pool: marked so they are not seeded again.
            for &t in &members {
                region[t as usize] = u32::MAX - 1;
            }
            rest.extend(members);
        }
    }
    rest.sort_unstable();
    (regions, rest)
}

/// A planar region projected onto its plane at `tpu` texels per unit, cut into tiles of at
/// most `tile` texels a side (by triangle centroid).
fn planar_items(mesh: &Mesh, region: &[u32], normal: DVec3, tpu: f64, tile: f64) -> Vec<Item> {
    let u_axis = normal.any_orthonormal_vector();
    let v_axis = normal.cross(u_axis);
    let project = |i: usize| {
        let p = mesh.positions[i].as_dvec3();
        (p.dot(u_axis) * tpu, p.dot(v_axis) * tpu)
    };
    let (mut lo_u, mut lo_v) = (f64::INFINITY, f64::INFINITY);
    for &t in region {
        for i in mesh.triangle(t as usize) {
            let (u, v) = project(i);
            lo_u = lo_u.min(u);
            lo_v = lo_v.min(v);
        }
    }
    let mut tiles: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
    for &t in region {
        let c = mesh
            .triangle(t as usize)
            .map(project)
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p.0 / 3.0, a.1 + p.1 / 3.0));
        let key = (((c.0 - lo_u) / tile) as i64, ((c.1 - lo_v) / tile) as i64);
        tiles.entry(key).or_default().push(t);
    }
    let mut keys: Vec<(i64, i64)> = tiles.keys().copied().collect();
    keys.sort_unstable();
    keys.into_iter()
        .map(|key| {
            let tris = &tiles[&key];
            let mut local: HashMap<u32, u32> = HashMap::new();
            let mut item = Item {
                charts: 1,
                ..Item::default()
            };
            let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
            for &t in tris {
                let corners = mesh.triangle(t as usize).map(|i| {
                    let next = item.vertices.len() as u32;
                    *local.entry(i as u32).or_insert_with(|| {
                        let (u, v) = project(i);
                        let p = Vec2::new(u as f32, v as f32);
                        min = min.min(p);
                        max = max.max(p);
                        item.vertices.push((i as u32, p));
                        next
                    })
                });
                item.triangles.push((t, corners, 0));
            }
            // Content starts half a texel in, so its texels are whole.
            let shift = Vec2::splat(0.5) - min;
            for v in &mut item.vertices {
                v.1 += shift;
            }
            let size = max - min + Vec2::ONE;
            item.width = size.x.ceil().max(1.0) as u32;
            item.height = size.y.ceil().max(1.0) as u32;
            item
        })
        .collect()
}

/// Triangles split by a k-d partition of their centroids into pieces of at most
/// [`PIECE_TRIANGLES`] (median cuts along the longest axis).
fn kd_pieces(mesh: &Mesh, mut tris: Vec<u32>) -> Vec<Vec<u32>> {
    let centroid = |t: u32| {
        let [a, b, c] = mesh.triangle(t as usize).map(|i| mesh.positions[i]);
        (a + b + c) / 3.0
    };
    let mut out = Vec::new();
    let mut stack = vec![std::mem::take(&mut tris)];
    while let Some(mut set) = stack.pop() {
        if set.len() <= PIECE_TRIANGLES {
            if !set.is_empty() {
                out.push(set);
            }
            continue;
        }
        let (lo, hi) = set.iter().fold(
            (
                glam::Vec3::splat(f32::INFINITY),
                glam::Vec3::splat(f32::NEG_INFINITY),
            ),
            |(lo, hi), &t| (lo.min(centroid(t)), hi.max(centroid(t))),
        );
        let axis = (hi - lo).max_position();
        let mid = set.len() / 2;
        set.select_nth_unstable_by(mid, |&a, &b| {
            centroid(a)[axis]
                .total_cmp(&centroid(b)[axis])
                .then(a.cmp(&b))
        });
        let right = set.split_off(mid);
        stack.push(right);
        stack.push(set);
    }
    out
}

/// One piece unwrapped by xatlas at `tpu` texels per unit.
fn xatlas_item(
    mesh: &Mesh,
    tris: &[u32],
    tpu: f64,
    settings: &BakeSettings,
    max_chart: u32,
) -> Result<Item> {
    let mut local: HashMap<u32, u32> = HashMap::new();
    let mut source: Vec<u32> = Vec::new();
    let mut indices = Vec::with_capacity(3 * tris.len());
    for &t in tris {
        for i in mesh.triangle(t as usize) {
            let next = source.len() as u32;
            indices.push(*local.entry(i as u32).or_insert_with(|| {
                source.push(i as u32);
                next
            }));
        }
    }
    // Positions scaled by a power of two to an extent in [1, 2), as for whole meshes.
    let (lo, hi) = source.iter().fold(
        (
            glam::Vec3::splat(f32::INFINITY),
            glam::Vec3::splat(f32::NEG_INFINITY),
        ),
        |(lo, hi), &i| {
            (
                lo.min(mesh.positions[i as usize]),
                hi.max(mesh.positions[i as usize]),
            )
        },
    );
    let unit = super::atlas::unit_scale((hi - lo).max_element());
    let positions: Vec<[f32; 3]> = source
        .iter()
        .map(|&i| (mesh.positions[i as usize] * unit).to_array())
        .collect();
    let normals: Vec<[f32; 3]> = source
        .iter()
        .map(|&i| mesh.normals[i as usize].to_array())
        .collect();
    let input = xatlas::Input {
        positions: &positions,
        normals: Some(&normals),
        uvs: None,
        indices: &indices,
    };
    let pack = xatlas::PackOptions {
        texels_per_unit: (tpu / unit as f64) as f32,
        padding: settings.layout.padding,
        max_chart_size: max_chart,
        ..xatlas::PackOptions::default()
    };
    let out = xatlas::generate(&input, &xatlas::ChartOptions::default(), &pack).map_err(|e| {
        BakeError::Unwrap {
            mesh: mesh.name.clone(),
            message: e.to_string(),
        }
    })?;
    let mut item = Item {
        width: out.width.max(1),
        height: out.height.max(1),
        charts: out.chart_count.max(1),
        ..Item::default()
    };
    // A piece whose charts are all below a texel is one texel.
    let collapse = out.width == 0 || out.height == 0;
    item.vertices = out
        .vertices
        .iter()
        .map(|v| {
            let p = if collapse {
                Vec2::splat(0.5)
            } else {
                Vec2::from_array(v.uv)
            };
            (source[v.xref as usize], p)
        })
        .collect();
    item.triangles = tris
        .iter()
        .enumerate()
        .map(|(k, &t)| {
            let corners = [0, 1, 2].map(|j| out.indices.get(3 * k + j).copied().unwrap_or(0));
            let chart = out.triangle_charts.get(k).copied().unwrap_or(u32::MAX);
            (t, corners, if collapse { 0 } else { chart })
        })
        .collect();
    Ok(item)
}

/// Charts a mesh in pieces (see the module docs) at the density `request` asks for, lowered
/// until the mesh fits a page; planar regions of at least `min_planar` triangles (or whole
/// loose parts) are charted directly.
///
/// # Errors
/// [`BakeError::Unwrap`] when xatlas refuses a piece or no density fits.
pub(super) fn unwrap_in_pieces(
    mesh: &Mesh,
    request: Density,
    settings: &BakeSettings,
    min_planar: usize,
    warnings: &mut Vec<String>,
    raised: &mut bool,
) -> Result<MeshUnwrap> {
    let normals = face_normals(mesh);
    let extent = super::atlas::mesh_extent(mesh) as f64;
    // A mesh smaller than a texel still gets a chart (as in `xatlas_unwrap`).
    let min_tpu = super::atlas::MIN_MESH_TEXELS as f64 / extent.max(f64::MIN_POSITIVE);
    let request = if (request.texels_per_unit as f64) < min_tpu && extent > 0.0 {
        *raised = true;
        Density {
            texels_per_unit: min_tpu as f32,
            ..request
        }
    } else {
        request
    };
    let (regions, rest) = planar_regions(mesh, &normals, extent, min_planar);
    let pieces = kd_pieces(mesh, rest);
    let max_page = settings.layout.max_page_size;
    let max_chart = max_page
        .saturating_sub(2 * settings.layout.padding + 2)
        .max(1);
    let gap = settings.layout.padding + 1;
    let bc6h = settings.formats.ktx2_bc6h;
    let requested = request.texels_per_unit as f64;
    let mut tpu = requested;
    for _attempt in 0..8 {
        let mut items: Vec<Item> = Vec::new();
        for region in &regions {
            let n = normals[region[0] as usize];
            items.extend(planar_items(
                mesh,
                region,
                n,
                tpu,
                (max_chart / 2).max(1) as f64,
            ));
        }
        for piece in &pieces {
            items.push(xatlas_item(mesh, piece, tpu, settings, max_chart)?);
        }
        // Each chart keeps at least a texel and its padding, however low the density: more
        // charts than a page holds are refused, not packed in vain.
        let least: u64 = items.iter().map(|_| (1 + gap as u64).pow(2)).sum();
        if least > (max_page as u64).pow(2) {
            return Err(BakeError::Unwrap {
                mesh: mesh.name.clone(),
                message: format!(
                    "its {} separate charts need at least {least} texels with {} texels of padding each, more than a {max_page}² page holds; raise --max-page-size (up to 16384), lower --padding, or merge its loose parts",
                    items.len(),
                    settings.layout.padding
                ),
            });
        }
        // BC6H pages: each chart on blocks of its own.
        if bc6h {
            items = items.iter().flat_map(block_pack::split_charts).collect();
        }
        let (corners, width, height) = pack_items(&items, settings);
        if width.max(height) > max_page {
            tpu *= shrink_to_page(width, height, max_page);
            continue;
        }
        if tpu < requested {
            warnings.push(format!(
                "mesh '{}' needs more than one {max_page}² page at the requested density; baked at {:.0}% of it",
                mesh.name,
                100.0 * tpu / requested
            ));
        }
        return Ok(assemble(
            mesh, &items, &corners, width, height, request, tpu,
        ));
    }
    if bc6h {
        // Charts on their own 4×4 blocks fit no page: pack them as for the other formats, and
        // say so.
        let mut plain = settings.clone();
        plain.formats.ktx2_bc6h = false;
        let out = unwrap_in_pieces(mesh, request, &plain, min_planar, warnings, raised)?;
        warnings.push(format!(
            "mesh '{}': its charts on their own 4×4 blocks fit no {max_page}² page; packed without, so a BC6H block may hold two of its charts",
            mesh.name
        ));
        return Ok(out);
    }
    Err(BakeError::Unwrap {
        mesh: mesh.name.clone(),
        message: format!("could not fit the mesh on a {max_page}² page"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::plane;

    /// A flat grid of `n × n` cells (shared vertices), optionally bumped.
    fn grid(n: usize, bump: f32) -> Mesh {
        let mut m = plane("grid", 1.0);
        m.positions.clear();
        m.normals.clear();
        m.indices.clear();
        m.uv0 = None;
        for j in 0..=n {
            for i in 0..=n {
                let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
                let y = bump * (x * 3.0).sin() * (z * 2.0).cos();
                m.positions.push(glam::Vec3::new(x * 10.0, y, z * 10.0));
                m.normals.push(glam::Vec3::Y);
            }
        }
        let row = (n + 1) as u32;
        for j in 0..n as u32 {
            for i in 0..n as u32 {
                let a = j * row + i;
                m.indices
                    .extend_from_slice(&[a, a + row, a + row + 1, a, a + row + 1, a + 1]);
            }
        }
        m
    }

    #[test]
    fn a_flat_grid_is_one_planar_chart_and_a_bumpy_one_is_split_into_pieces() {
        let settings = BakeSettings::default();
        let request = Density {
            texels_per_unit: 20.0,
            texels_per_metre: 20.0,
        };
        let flat = grid(60, 0.0);
        let u = unwrap_in_pieces(
            &flat,
            request,
            &settings,
            MIN_PLANAR,
            &mut Vec::new(),
            &mut false,
        )
        .unwrap();
        assert_eq!(u.chart_count, 1);
        // 10 m at 20 texels/m, plus the half-texel border.
        assert!((200..=203).contains(&u.width), "{}", u.width);
        assert_eq!(u.indices.len(), flat.indices.len());
        assert!(u.triangle_charts.iter().all(|&c| c == 0));
        // Areas are kept exactly: texel area of each triangle over its world area.
        for t in 0..flat.triangle_count() {
            let [a, b, c] = [0, 1, 2].map(|k| {
                u.uv1[u.indices[3 * t + k] as usize] * Vec2::new(u.width as f32, u.height as f32)
            });
            let texel_area = 0.5 * (b - a).perp_dot(c - a).abs();
            assert!((texel_area / (0.5 * (10.0f32 / 60.0).powi(2) * 400.0) - 1.0).abs() < 1e-3);
        }
        let bumpy = grid(60, 0.5);
        let u = unwrap_in_pieces(
            &bumpy,
            request,
            &settings,
            MIN_PLANAR,
            &mut Vec::new(),
            &mut false,
        )
        .unwrap();
        assert!(u.chart_count >= 7, "{} charts", u.chart_count);
        assert!(u.triangle_charts.iter().all(|&c| c < u.chart_count));
        assert!(
            u.uv1
                .iter()
                .all(|p| p.min_element() >= 0.0 && p.max_element() <= 1.0)
        );
        let xref = u.xref.as_ref().unwrap();
        for t in 0..bumpy.triangle_count() {
            for k in 0..3 {
                assert_eq!(
                    xref[u.indices[3 * t + k] as usize],
                    bumpy.indices[3 * t + k]
                );
            }
        }
    }

    #[test]
    fn a_planar_region_larger_than_a_page_is_tiled_or_scaled() {
        let settings = {
            let mut s = BakeSettings::default();
            s.layout.max_page_size = 128;
            s
        };
        let request = Density {
            texels_per_unit: 30.0,
            texels_per_metre: 30.0,
        };
        let mut warnings = Vec::new();
        let u = unwrap_in_pieces(
            &grid(60, 0.0),
            request,
            &settings,
            MIN_PLANAR,
            &mut warnings,
            &mut false,
        )
        .unwrap();
        assert!(u.width <= 128 && u.height <= 128);
        assert!(u.chart_count > 1);
        assert!(u.scaled_to_fit && !warnings.is_empty());
    }
}
