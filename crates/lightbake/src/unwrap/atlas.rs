//! One mesh unwrapped by xatlas at the density its most demanding instance asks for,
//! lowered until the atlas fits on a page.

use glam::Vec2;

use super::items::shrink_to_page;
use super::{Density, MeshUnwrap, UvOrigin, block_pack, xatlas};
use crate::error::{BakeError, Result};
use crate::scene::Mesh;
use crate::settings::BakeSettings;

/// Texels a mesh's longest extent gets at least, so a mesh smaller than a texel still has a
/// chart.
pub(super) const MIN_MESH_TEXELS: f32 = 2.0;

/// The power of two that scales `extent` into [1, 2) (1 for an empty or non-finite extent).
pub(super) fn unit_scale(extent: f32) -> f32 {
    if !(extent.is_finite() && extent > 0.0) {
        return 1.0;
    }
    let exponent = extent.log2().floor().clamp(-120.0, 120.0);
    2f32.powi(-(exponent as i32))
}

/// The longest side of a mesh's bounding box, mesh units.
pub(super) fn mesh_extent(mesh: &Mesh) -> f32 {
    let (lo, hi) = mesh.positions.iter().fold(
        (
            glam::Vec3::splat(f32::INFINITY),
            glam::Vec3::splat(f32::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    (hi - lo).max_element().max(0.0)
}

/// Runs xatlas on one mesh at the requested density (raised, and `raised` set, when the mesh
/// would be smaller than [`MIN_MESH_TEXELS`]), lowering the density until the result fits on
/// a page.
pub(super) fn xatlas_unwrap(
    mesh: &Mesh,
    request: Density,
    settings: &BakeSettings,
    warnings: &mut Vec<String>,
    raised: &mut bool,
) -> Result<MeshUnwrap> {
    // The longest triangle must fit a page: lower the density up front when it does not (as
    // the loop below does for whole atlases), but refuse a mesh that would need less than
    // 1/1000 of the requested density: xatlas crashed (SIGSEGV) on a fuzzed mesh with a
    // 1.5·10⁸ m sliver next to 0.3 m faces.
    let max_chart = settings
        .layout
        .max_page_size
        .saturating_sub(2 * settings.layout.padding + 2)
        .max(1) as f32;
    let (mut longest, mut longest_t) = (0.0f32, 0);
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t).map(|i| mesh.positions[i]);
        let edge = (b - a).length().max((c - b).length()).max((a - c).length());
        if edge.is_nan() || edge > longest {
            (longest, longest_t) = (edge, t);
        }
    }
    let texels = longest * request.texels_per_unit;
    let fit = max_chart / texels;
    if fit.is_nan() || fit < 1e-3 {
        return Err(BakeError::Unwrap {
            mesh: mesh.name.clone(),
            message: format!(
                "triangle {longest_t} is {longest:e} units long, {texels:e} texels at {:e} texels per unit: a {}-texel page holds it only below 1/1000 of the requested density; split it or check the mesh",
                request.texels_per_unit, settings.layout.max_page_size
            ),
        });
    }
    // xatlas judges degenerate triangles and welds vertices by absolute tolerances, so it is
    // given the mesh scaled by a power of two to an extent in [1, 2): exact in floating point
    // (texel coordinates, position × texels per unit, keep their bits), and a 0.1 mm part is
    // not mistaken for dust.
    let unit = unit_scale(mesh_extent(mesh));
    let positions: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| (*p * unit).to_array())
        .collect();
    let normals: Vec<[f32; 3]> = mesh.normals.iter().map(|p| p.to_array()).collect();
    // TEXCOORD_0 only guides xatlas' chart seams; absurd values are left out, not passed on.
    let uvs: Option<Vec<[f32; 2]>> = mesh
        .uv0
        .as_ref()
        .filter(|u| u.iter().all(|p| p.abs().max_element() <= 1e6))
        .map(|u| u.iter().map(|p| p.to_array()).collect());
    let input = xatlas::Input {
        positions: &positions,
        normals: Some(&normals),
        uvs: uvs.as_deref(),
        indices: &mesh.indices,
    };
    let max_page = settings.layout.max_page_size;
    // A mesh smaller than a texel still gets a chart: at least MIN_MESH_TEXELS across.
    let extent = mesh_extent(mesh);
    let tpu = if extent * request.texels_per_unit < MIN_MESH_TEXELS && extent > 0.0 {
        *raised = true;
        MIN_MESH_TEXELS / extent
    } else {
        request.texels_per_unit
    };
    let mut pack = xatlas::PackOptions {
        texels_per_unit: tpu / unit,
        padding: settings.layout.padding,
        max_chart_size: max_page
            .saturating_sub(2 * settings.layout.padding + 2)
            .max(1),
        ..xatlas::PackOptions::default()
    };
    let bc6h = settings.formats.ktx2_bc6h;
    let mut scaled = false;
    if fit < 1.0 {
        pack.texels_per_unit *= 0.97 * fit;
        scaled = true;
    }
    for _attempt in 0..8 {
        let out =
            xatlas::generate(&input, &xatlas::ChartOptions::default(), &pack).map_err(|e| {
                BakeError::Unwrap {
                    mesh: mesh.name.clone(),
                    message: e.to_string(),
                }
            })?;
        if out.width == 0 || out.height == 0 {
            // Charts below a texel: ask again at twice the density.
            *raised = true;
            pack.texels_per_unit *= 2.0;
            continue;
        }
        let largest = out.width.max(out.height);
        if largest > max_page {
            scaled = true;
            pack.texels_per_unit *= 0.97 * (max_page as f32 / largest as f32);
            continue;
        }
        let achieved = pack.texels_per_unit * unit;
        let (w, h) = (out.width as f32, out.height as f32);
        let uv1 = out
            .vertices
            .iter()
            .map(|v| Vec2::new((v.uv[0] / w).clamp(0.0, 1.0), (v.uv[1] / h).clamp(0.0, 1.0)))
            .collect();
        let mut unwrap = MeshUnwrap {
            width: out.width,
            height: out.height,
            uv1,
            xref: Some(out.vertices.iter().map(|v| v.xref).collect()),
            indices: out.indices,
            triangle_charts: out.triangle_charts,
            chart_count: out.chart_count,
            origin: UvOrigin::Xatlas,
            texels_per_metre: request.texels_per_metre * achieved / request.texels_per_unit,
            scaled_to_fit: scaled,
        };
        if bc6h {
            // BC6H pages: each chart on blocks of its own, lower when they fit no page.
            match block_pack::onto_blocks(mesh, &unwrap, settings) {
                Ok(moved) => unwrap = moved,
                Err((width, height)) => {
                    scaled = true;
                    pack.texels_per_unit *= shrink_to_page(width, height, max_page) as f32;
                    continue;
                }
            }
        }
        if scaled {
            warnings.push(format!(
                "mesh '{}' needs more than one {max_page}² page at the requested density; baked at {:.0}% of it",
                mesh.name,
                100.0 * achieved / tpu
            ));
        }
        return Ok(unwrap);
    }
    if bc6h {
        // Charts on their own 4×4 blocks fit no page: pack them as for the other formats, and
        // say so.
        let mut plain = settings.clone();
        plain.formats.ktx2_bc6h = false;
        let out = xatlas_unwrap(mesh, request, &plain, warnings, raised)?;
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
