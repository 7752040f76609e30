//! Conservative rasterisation of one mesh's triangles into its lightmap rectangle: each
//! triangle is clipped against every texel square of its bounding box (Sutherland–Hodgman);
//! any texel with a non-empty intersection is covered, and the clipped areas give the
//! texel's exact share of each triangle. Done once per mesh and shared by its instances.
//!
//! A covered texel's representative point is the texel centre when a triangle contains it,
//! otherwise the centroid of the largest clipped piece (inside the triangle *and* the texel).

use glam::Vec2;

/// One texel of one mesh's rectangle, in mesh-local terms (before instancing).
#[derive(Clone, Debug)]
pub(crate) struct LocalTexel {
    pub(crate) x: u32,
    pub(crate) y: u32,
    /// Its pieces: `MeshRaster::pieces[start..start + len]`.
    pub(crate) start: u32,
    pub(crate) len: u32,
    /// Owner triangle and the texel-space point to represent the texel.
    pub(crate) owner: u32,
    pub(crate) point: Vec2,
}

/// The rasterised lightmap of one mesh, shared by its instances.
#[derive(Clone, Debug, Default)]
pub struct MeshRaster {
    pub(crate) texels: Vec<LocalTexel>,
    /// Per texel, in texel order: the local triangles overlapping it with their clipped
    /// areas (texel² units). One flat array, not one small vector per texel: a million
    /// texels' pieces would otherwise cost a million allocations.
    pub(crate) pieces: Vec<(u32, f32)>,
}

impl MeshRaster {
    /// The pieces of texel `t`.
    pub(crate) fn pieces_of(&self, t: &LocalTexel) -> &[(u32, f32)] {
        &self.pieces[t.start as usize..(t.start + t.len) as usize]
    }
}

/// Area and centroid of the part of triangle `t` inside the unit square at (x, y).
fn clip_to_texel(t: [Vec2; 3], x: f32, y: f32) -> (f32, Vec2) {
    let mut poly: Vec<Vec2> = t.to_vec();
    let planes = [
        (Vec2::X, x),
        (Vec2::NEG_X, -(x + 1.0)),
        (Vec2::Y, y),
        (Vec2::NEG_Y, -(y + 1.0)),
    ];
    for (n, d) in planes {
        if poly.is_empty() {
            break;
        }
        let mut out = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let (da, db) = (n.dot(a) - d, n.dot(b) - d);
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        poly = out;
    }
    if poly.len() < 3 {
        return (0.0, Vec2::ZERO);
    }
    let (mut area2, mut c) = (0.0f32, Vec2::ZERO);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let cross = a.perp_dot(b);
        area2 += cross;
        c += (a + b) * cross;
    }
    if area2.abs() < 1e-12 {
        return (0.0, Vec2::ZERO);
    }
    (0.5 * area2.abs(), c / (3.0 * area2))
}

/// Barycentric coordinates (of vertices 1 and 2) of `q` in the 2D triangle `t`, if inside
/// (with a tolerance of `tol` in barycentric units).
pub(crate) fn barycentric_2d(t: [Vec2; 3], q: Vec2, tol: f32) -> Option<Vec2> {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], q - t[0]);
    let det = e1.perp_dot(e2);
    if det.abs() < 1e-20 {
        return None;
    }
    let u = d.perp_dot(e2) / det;
    let v = e1.perp_dot(d) / det;
    (u >= -tol && v >= -tol && u + v <= 1.0 + tol).then_some(Vec2::new(u, v))
}

/// How far (texels) a texel's representative point is pulled into its triangle.
const INSET: f32 = 0.05;

/// Conservatively rasterises one mesh's triangles in its `width × height` texel rectangle.
pub fn rasterize_mesh(uv1: &[Vec2], indices: &[u32], width: u32, height: u32) -> MeshRaster {
    let scale = Vec2::new(width as f32, height as f32);
    let mut entries: Vec<(u32, u32, f32, Vec2, bool)> = Vec::new(); // texel, tri, area, centroid, centre inside
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        let p = [tri[0], tri[1], tri[2]].map(|i| uv1[i as usize] * scale);
        let twice_area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        if twice_area.abs() < 1e-12 {
            continue;
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        let (x0, y0) = (lo.x.floor().max(0.0) as u32, lo.y.floor().max(0.0) as u32);
        let x1 = (hi.x.ceil() as u32).min(width);
        let y1 = (hi.y.ceil() as u32).min(height);
        for y in y0..y1 {
            for x in x0..x1 {
                let (area, centroid) = clip_to_texel(p, x as f32, y as f32);
                if area <= 1e-7 {
                    continue;
                }
                let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let inside = barycentric_2d(p, centre, 0.0).is_some();
                entries.push((y * width + x, t as u32, area, centroid, inside));
            }
        }
    }
    entries.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut texels = Vec::new();
    let mut pieces = Vec::with_capacity(entries.len());
    let mut i = 0;
    while i < entries.len() {
        let texel = entries[i].0;
        let mut j = i;
        while j < entries.len() && entries[j].0 == texel {
            j += 1;
        }
        let group = &entries[i..j];
        let (x, y) = (texel % width, texel / width);
        let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        // Owner: the triangle containing the centre, else the largest piece.
        let (owner, point) = match group.iter().find(|e| e.4) {
            Some(e) => (e.1, centre),
            None => {
                let e = group
                    .iter()
                    .max_by(|a, b| a.2.total_cmp(&b.2).then(b.1.cmp(&a.1)))
                    .expect("group is not empty");
                (e.1, e.3)
            }
        };
        // xatlas offsets charts by half a texel, so border texel centres lie exactly on chart
        // edges — on the geometric edge where two walls meet. Evaluated there, half of a
        // gather hemisphere leaks out through the edge. Pull the point a little into its
        // triangle (towards the centroid, at most INSET texels).
        let tri = &indices[3 * owner as usize..3 * owner as usize + 3];
        let centroid = tri.iter().map(|&i| uv1[i as usize] * scale).sum::<Vec2>() / 3.0;
        let to_centroid = centroid - point;
        let point = point + to_centroid * (INSET / to_centroid.length().max(INSET));
        texels.push(LocalTexel {
            x,
            y,
            start: pieces.len() as u32,
            len: group.len() as u32,
            owner,
            point,
        });
        pieces.extend(group.iter().map(|e| (e.1, e.2)));
        i = j;
    }
    texels.shrink_to_fit();
    MeshRaster { texels, pieces }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_gives_exact_areas() {
        // A right triangle covering half of a 2×2 block.
        let t = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(0.0, 2.0),
        ];
        let total: f32 = (0..2)
            .flat_map(|y| (0..2).map(move |x| (x, y)))
            .map(|(x, y)| clip_to_texel(t, x as f32, y as f32).0)
            .sum();
        assert!((total - 2.0).abs() < 1e-6);
        assert!((clip_to_texel(t, 0.0, 0.0).0 - 1.0).abs() < 1e-6);
        assert!((clip_to_texel(t, 1.0, 0.0).0 - 0.5).abs() < 1e-6);
        assert_eq!(clip_to_texel(t, 1.0, 1.0).0, 0.0);
    }

    #[test]
    fn conservative_raster_covers_touched_texels() {
        // A thin sliver crossing texels without covering any centre.
        let uv = [
            Vec2::new(0.1, 0.1),
            Vec2::new(0.9, 0.12),
            Vec2::new(0.1, 0.11),
        ];
        let r = rasterize_mesh(&uv, &[0, 1, 2], 8, 8);
        assert!(r.texels.len() >= 7, "{}", r.texels.len());
        for t in &r.texels {
            assert!(r.pieces_of(t)[0].1 > 0.0);
            // The representative point is inside the texel.
            assert!(t.point.x >= t.x as f32 - 1e-4 && t.point.x <= (t.x + 1) as f32 + 1e-4);
        }
    }
}
