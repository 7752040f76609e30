//! The hemicube (Cohen & Greenberg 1985, "The Hemi-Cube: A Radiosity Solution for Complex
//! Environments"): the scene is rasterised with a z-buffer onto the five faces of a half cube
//! around a patch, and every pixel adds its precomputed delta form factor to the patch it sees:
//!
//! * top face (z = 1): ΔF = ΔA / (π·(x² + y² + 1)²)
//! * side faces (x = 1, upper half): ΔF = z·ΔA / (π·(y² + z² + 1)²)
//!
//! with ΔA = (2/res)² the pixel area. The visible point of each pixel is mapped to the texel
//! containing it (a patch-level, piecewise-constant form factor). This exists to compare its
//! error and cost with Monte Carlo form factors; it is not the default.

use glam::{Mat3, Vec2, Vec3};
use rayon::prelude::*;

use super::hit_mapper::HitMapper;
use super::nodes::Nodes;
use crate::bvh::Hit;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::sampling::basis;
use crate::settings::Basis;
use crate::solve::transport::Transport;

/// One face: rotation from world to face-local (x, y, depth) and its pixel extent in y.
struct Face {
    to_local: Mat3,
    /// Rows cover y ∈ [y0, 1].
    y0: f32,
    top: bool,
}

/// Pixel hit record: depth along the face axis and the triangle.
#[derive(Clone, Copy)]
struct Pixel {
    depth: f32,
    triangle: u32,
}

/// Builds F with a hemicube of `resolution` × `resolution` pixels on the top face at every node
/// (piecewise-constant basis).
pub fn build_hemicube(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    resolution: u32,
    progress: &Progress,
) -> Transport {
    let mapper = HitMapper::new(*ctx, nodes, Basis::Constant);
    let rows: Vec<(Vec<(u32, f32)>, f32)> = (0..nodes.len())
        .into_par_iter()
        .map(|i| {
            let r = hemicube_row(ctx, &mapper, nodes, i, resolution);
            progress.advance(1);
            r
        })
        .collect();
    let pixels = resolution as u64 * resolution as u64 * 3;
    Transport::from_rows(
        nodes.len(),
        rows,
        pixels * nodes.len() as u64,
        Basis::Constant,
    )
}

fn hemicube_row(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    i: usize,
    res: u32,
) -> (Vec<(u32, f32)>, f32) {
    let p = &ctx.patches.patches[nodes.patch[i] as usize];
    let n = p.normal;
    let (t, b) = basis(n);
    let origin = ctx.rays.offset(p.position, p.geometric_normal);
    // Face-local frames: rows of the rotation are (x axis, y axis, depth axis) in world space.
    let faces = [
        Face {
            to_local: Mat3::from_cols(t, b, n).transpose(),
            y0: -1.0,
            top: true,
        },
        Face {
            to_local: Mat3::from_cols(b, n, t).transpose(),
            y0: 0.0,
            top: false,
        },
        Face {
            to_local: Mat3::from_cols(-b, n, -t).transpose(),
            y0: 0.0,
            top: false,
        },
        Face {
            to_local: Mat3::from_cols(-t, n, b).transpose(),
            y0: 0.0,
            top: false,
        },
        Face {
            to_local: Mat3::from_cols(t, n, -b).transpose(),
            y0: 0.0,
            top: false,
        },
    ];
    let near = ctx.rays.epsilon(p.position) * 0.5;
    let delta_area = (2.0 / res as f32).powi(2);
    let mut row: Vec<(u32, f32)> = Vec::new();
    let mut escaped = 0.0f32;
    let mut out = [(0u32, 0f32); 4];
    for face in &faces {
        let rows = if face.top { res } else { res / 2 };
        let mut buffer = vec![
            Pixel {
                depth: f32::INFINITY,
                triangle: u32::MAX
            };
            (res * rows) as usize
        ];
        // Rasterise every triangle.
        for (g, info) in ctx.rays.triangles.iter().enumerate() {
            if info.area <= 0.0 {
                continue;
            }
            let v = ctx
                .rays
                .triangle_vertices(g as u32)
                .map(|w| face.to_local * (w - origin));
            rasterize(&v, face, res, rows, near, g as u32, &mut buffer);
        }
        // Accumulate delta form factors.
        for py in 0..rows {
            for px in 0..res {
                let x = -1.0 + (px as f32 + 0.5) * 2.0 / res as f32;
                let y = face.y0 + (py as f32 + 0.5) * 2.0 / res as f32;
                let df = if face.top {
                    delta_area / (std::f32::consts::PI * (x * x + y * y + 1.0).powi(2))
                } else {
                    y * delta_area / (std::f32::consts::PI * (x * x + y * y + 1.0).powi(2))
                };
                let pix = buffer[(py * res + px) as usize];
                if pix.triangle == u32::MAX {
                    escaped += df;
                    continue;
                }
                let local_dir = Vec3::new(x, y, 1.0);
                let world_dir = face.to_local.transpose() * local_dir;
                let point = origin + world_dir * pix.depth;
                let Some(hit) = hit_on_triangle(ctx, pix.triangle, point, world_dir) else {
                    continue;
                };
                let k = mapper.weights(&hit, &mut out);
                for &(j, w) in &out[..k] {
                    row.push((j, w * df));
                }
            }
        }
    }
    row.sort_unstable_by_key(|e| e.0);
    let mut merged: Vec<(u32, f32)> = Vec::with_capacity(row.len());
    for (j, v) in row {
        match merged.last_mut() {
            Some(last) if last.0 == j => last.1 += v,
            _ => merged.push((j, v)),
        }
    }
    (merged, escaped)
}

/// Barycentrics of a point known to lie on triangle `g`, as a [`Hit`].
fn hit_on_triangle(ctx: &BakeContext<'_>, g: u32, point: Vec3, dir: Vec3) -> Option<Hit> {
    let [a, b, c] = ctx.rays.triangle_vertices(g);
    let (e1, e2, d) = (b - a, c - a, point - a);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (dp1, dp2) = (d.dot(e1), d.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det <= 0.0 {
        return None;
    }
    let u = ((d22 * dp1 - d12 * dp2) / det).clamp(0.0, 1.0);
    let v = ((d11 * dp2 - d12 * dp1) / det).clamp(0.0, 1.0 - u);
    Some(Hit {
        t: 0.0,
        triangle: g,
        u,
        v,
        front_face: ctx.rays.triangles[g as usize].normal.dot(dir) < 0.0,
    })
}

/// Clips the face-local triangle to depth ≥ `near`, projects it and z-buffers it.
fn rasterize(
    v: &[Vec3; 3],
    face: &Face,
    res: u32,
    rows: u32,
    near: f32,
    id: u32,
    buffer: &mut [Pixel],
) {
    // Clip against depth ≥ near.
    let mut poly: Vec<Vec3> = Vec::with_capacity(4);
    for i in 0..3 {
        let (a, b) = (v[i], v[(i + 1) % 3]);
        if a.z >= near {
            poly.push(a);
        }
        if (a.z >= near) != (b.z >= near) {
            let t = (near - a.z) / (b.z - a.z);
            poly.push(a + (b - a) * t);
        }
    }
    if poly.len() < 3 {
        return;
    }
    // Plane of the triangle in face-local space, for per-pixel depth.
    let normal = (v[1] - v[0]).cross(v[2] - v[0]);
    let plane_d = normal.dot(v[0]);
    let proj: Vec<Vec2> = poly
        .iter()
        .map(|q| Vec2::new(q.x / q.z, q.y / q.z))
        .collect();
    let to_px = |q: Vec2| {
        Vec2::new(
            (q.x + 1.0) * 0.5 * res as f32,
            (q.y - face.y0) * 0.5 * res as f32,
        )
    };
    let pts: Vec<Vec2> = proj.iter().map(|&q| to_px(q)).collect();
    let lo = pts
        .iter()
        .fold(Vec2::splat(f32::INFINITY), |m, p| m.min(*p));
    let hi = pts
        .iter()
        .fold(Vec2::splat(f32::NEG_INFINITY), |m, p| m.max(*p));
    let x0 = lo.x.floor().max(0.0) as u32;
    let y0 = lo.y.floor().max(0.0) as u32;
    let x1 = (hi.x.ceil().max(0.0) as u32).min(res);
    let y1 = (hi.y.ceil().max(0.0) as u32).min(rows);
    // Fan triangulation of the clipped polygon.
    for k in 1..pts.len() - 1 {
        let tri = [pts[0], pts[k], pts[k + 1]];
        let area = (tri[1] - tri[0]).perp_dot(tri[2] - tri[0]);
        if area.abs() < 1e-12 {
            continue;
        }
        for py in y0..y1 {
            for px in x0..x1 {
                let c = Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
                let inside = (0..3).all(|e| {
                    let (a, b) = (tri[e], tri[(e + 1) % 3]);
                    (b - a).perp_dot(c - a) * area.signum() >= 0.0
                });
                if !inside {
                    continue;
                }
                let x = -1.0 + c.x * 2.0 / res as f32;
                let y = face.y0 + c.y * 2.0 / res as f32;
                let dir = Vec3::new(x, y, 1.0);
                let denom = normal.dot(dir);
                if denom.abs() < 1e-20 {
                    continue;
                }
                let depth = plane_d / denom;
                if depth < near {
                    continue;
                }
                let slot = &mut buffer[(py * res + px) as usize];
                if depth < slot.depth {
                    *slot = Pixel {
                        depth,
                        triangle: id,
                    };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn delta_form_factors_sum_to_one() {
        let res = 256u32;
        let da = (2.0 / res as f64).powi(2);
        let mut sum = 0.0f64;
        for py in 0..res {
            for px in 0..res {
                let x = -1.0 + (px as f64 + 0.5) * 2.0 / res as f64;
                let y = -1.0 + (py as f64 + 0.5) * 2.0 / res as f64;
                sum += da / (std::f64::consts::PI * (x * x + y * y + 1.0).powi(2));
            }
        }
        for _ in 0..4 {
            for py in 0..res / 2 {
                for px in 0..res {
                    let x = -1.0 + (px as f64 + 0.5) * 2.0 / res as f64;
                    let y = (py as f64 + 0.5) * 2.0 / res as f64;
                    sum += y * da / (std::f64::consts::PI * (x * x + y * y + 1.0).powi(2));
                }
            }
        }
        assert!((sum - 1.0).abs() < 1e-4, "{sum}");
    }
}
