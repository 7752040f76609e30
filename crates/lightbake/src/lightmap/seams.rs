//! Seams: mesh edges whose two sides lie in different charts (of one mesh, or of two meshes
//! that share the edge) while the surface goes on smoothly across them. The lightmap shows
//! each side through its own texels, so after bilinear filtering the two sides of a seam can
//! differ at the same world point; [`seam_jumps_where`] measures by how much, and
//! [`super::stitch`] makes them agree.
//!
//! An edge is a seam when it is an open edge of its chart on both sides (the two triangles
//! do not share the vertex indices: the unwrap split them), the two sides' world endpoints
//! coincide (to 10⁻⁶ of the scene's extent), their shading normals agree at both endpoints
//! (within [`SMOOTH_COS`]: a hard edge such as a box's corner is not a seam, its light may
//! jump there) and their faces meet at less than 30° ([`FOLD_COS`]).

use glam::{Vec2, Vec3};

use super::{LightmapPage, bilinear_taps};
use crate::color::luminance;
use crate::scene::Scene;
use crate::unwrap::Layout;

/// Shading normals this close (cosine) at a shared vertex make an edge smooth.
pub const SMOOTH_COS: f32 = 0.995;
/// The two sides' faces this close (cosine, 30°): a sharper fold with smoothed normals is
/// a crease whose sides see different light, not one surface.
pub const FOLD_COS: f32 = 0.866;

/// One side of a seam: the triangle and where the edge lies on its page.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeamSide {
    /// Scene instance.
    pub instance: u32,
    /// Chart of the triangle within its mesh.
    pub chart: u32,
    /// Triangle within the instance's mesh.
    pub triangle: u32,
    /// Atlas page.
    pub page: u32,
    /// The edge's endpoints in page texel units (texel (x, y) covers [x, x+1] × [y, y+1]), in
    /// the order of [`Seam::world`].
    pub texels: [Vec2; 2],
}

/// A seam edge and its two sides.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seam {
    /// World endpoints, m.
    pub world: [Vec3; 2],
    /// The two sides' unit geometric normals.
    pub normals: [Vec3; 2],
    /// The two sides.
    pub sides: [SeamSide; 2],
}

impl Seam {
    /// Points along the seam at which it is sampled: about two per texel of its longer side,
    /// at least two, at the middles of equal pieces (parameters in (0, 1)).
    pub fn samples(&self) -> impl Iterator<Item = f32> + use<> {
        let len = self
            .sides
            .iter()
            .map(|s| s.texels[0].distance(s.texels[1]))
            .fold(0.0f32, f32::max);
        let n = ((2.0 * len).ceil() as u32).clamp(2, 1 << 16);
        (0..n).map(move |k| (k as f32 + 0.5) / n as f32)
    }

    /// Side `side`'s point at parameter `t` along the edge, in page texel units.
    pub fn at(&self, side: usize, t: f32) -> Vec2 {
        let s = &self.sides[side];
        s.texels[0].lerp(s.texels[1], t)
    }
}

/// An open edge of a chart (one triangle only uses its two vertex indices).
#[derive(Clone, Copy)]
struct OpenEdge {
    /// Quantised world endpoints, the smaller first.
    key: [[i64; 3]; 2],
    instance: u32,
    triangle: u32,
    /// Mesh vertex indices in the key's order.
    vertices: [u32; 2],
}

/// Every seam of the baked scene (`scene` is the unwrapped scene, [`Layout::apply`]).
pub fn find_seams(scene: &Scene, layout: &Layout) -> Vec<Seam> {
    let (lo, hi) = scene.bounds();
    let quantum = ((hi - lo).length() * 1e-6).max(f32::MIN_POSITIVE) as f64;
    let quantise = |p: Vec3| {
        p.as_dvec3()
            .to_array()
            .map(|c| (c / quantum).round() as i64)
    };
    // Open edges of each mesh's charts, by vertex indices (once per mesh).
    let open: Vec<Vec<(u32, [u32; 2])>> = scene
        .meshes
        .iter()
        .enumerate()
        .map(|(m, mesh)| {
            if layout.meshes.get(m).is_none_or(Option::is_none) {
                return Vec::new();
            }
            let mut edges: Vec<([u32; 2], u32)> = (0..mesh.triangle_count())
                .flat_map(|t| {
                    let i = &mesh.indices[3 * t..3 * t + 3];
                    (0..3).map(move |k| {
                        let (a, b) = (i[k], i[(k + 1) % 3]);
                        ([a.min(b), a.max(b)], t as u32)
                    })
                })
                .collect();
            edges.sort_unstable();
            edges
                .chunk_by(|a, b| a.0 == b.0)
                .filter(|run| run.len() == 1)
                .map(|run| (run[0].1, run[0].0))
                .collect()
        })
        .collect();
    let mut edges: Vec<OpenEdge> = Vec::new();
    for (ii, inst) in scene.instances.iter().enumerate() {
        if layout.instances[ii].is_none() {
            continue;
        }
        let mesh = &scene.meshes[inst.mesh];
        for &(t, [a, b]) in &open[inst.mesh] {
            let (pa, pb) = (
                quantise(inst.transform.transform_point3(mesh.positions[a as usize])),
                quantise(inst.transform.transform_point3(mesh.positions[b as usize])),
            );
            if pa == pb {
                continue;
            }
            let (key, vertices) = if pa <= pb {
                ([pa, pb], [a, b])
            } else {
                ([pb, pa], [b, a])
            };
            edges.push(OpenEdge {
                key,
                instance: ii as u32,
                triangle: t,
                vertices,
            });
        }
    }
    edges.sort_unstable_by(|a, b| a.key.cmp(&b.key).then(a.instance.cmp(&b.instance)));
    edges
        .chunk_by(|a, b| a.key == b.key)
        .filter(|run| run.len() == 2)
        .filter_map(|run| seam(scene, layout, &run[0], &run[1]))
        .collect()
}

/// The seam between open edges `a` and `b` (same world endpoints), if it is one.
fn seam(scene: &Scene, layout: &Layout, a: &OpenEdge, b: &OpenEdge) -> Option<Seam> {
    let side = |e: &OpenEdge| -> Option<(SeamSide, [Vec3; 2], [Vec3; 2], Vec3)> {
        let inst = &scene.instances[e.instance as usize];
        let mesh = &scene.meshes[inst.mesh];
        let unwrap = layout.meshes[inst.mesh].as_ref()?;
        let rect = layout.instances[e.instance as usize]?;
        let chart = *unwrap.triangle_charts.get(e.triangle as usize)?;
        if chart == u32::MAX {
            return None;
        }
        let uv1 = mesh.uv1.as_ref()?;
        let nm = inst.normal_matrix();
        let [i0, i1, i2] = mesh.triangle(e.triangle as usize);
        // Through the normal matrix, which keeps the front of a mirrored instance's triangle.
        let l = [i0, i1, i2].map(|k| mesh.positions[k]);
        let geometric = (nm * (l[1] - l[0]).cross(l[2] - l[0])).normalize_or_zero();
        let texel = |v: u32| {
            let uv = uv1[v as usize];
            Vec2::new(
                rect.x as f32 + uv.x * rect.width as f32,
                rect.y as f32 + uv.y * rect.height as f32,
            )
        };
        let world = e
            .vertices
            .map(|v| inst.transform.transform_point3(mesh.positions[v as usize]));
        let normals = e
            .vertices
            .map(|v| (nm * mesh.normals[v as usize]).normalize_or_zero());
        Some((
            SeamSide {
                instance: e.instance,
                chart,
                triangle: e.triangle,
                page: rect.page,
                texels: e.vertices.map(texel),
            },
            world,
            normals,
            geometric,
        ))
    };
    let (sa, wa, na, ga) = side(a)?;
    let (sb, _, nb, gb) = side(b)?;
    if sa.instance == sb.instance && sa.chart == sb.chart {
        return None;
    }
    let smooth = na[0].dot(nb[0]) >= SMOOTH_COS && na[1].dot(nb[1]) >= SMOOTH_COS;
    (smooth && ga.dot(gb) > FOLD_COS).then_some(Seam {
        world: wa,
        normals: [ga, gb],
        sides: [sa, sb],
    })
}

/// How far the two sides of the seams disagree after bilinear filtering, over every seam
/// sample: the jump |L_a − L_b| of the luminance of E/π, relative to the sample's mean
/// ½(L_a + L_b) — at least 1% of the mean texel luminance of the pages, so black seams
/// count as agreeing.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct SeamJumps {
    /// Seam edges with a sample counted.
    pub seams: usize,
    /// Samples along them.
    pub samples: usize,
    /// Mean relative jump.
    pub mean: f64,
    /// Largest relative jump.
    pub max: f64,
}

/// Page `page`'s E/π at page texel point `q`, as the GPU's bilinear filter reads it.
pub fn sample_at(page: &LightmapPage, q: Vec2) -> Vec3 {
    bilinear_taps(
        page.width,
        page.height,
        q.x / page.width as f32,
        q.y / page.height as f32,
    )
    .iter()
    .map(|&((x, y), w)| page.get(x, y) * w)
    .sum()
}

/// Measures the jumps across `seams` on `pages` (see [`SeamJumps`]) over the samples
/// `keep(seam, sample)` selects (indices into `seams` and into the seam's
/// [`Seam::samples`]), each relative to a mean of at least `floor` ([`jump_floor`] of
/// `pages`).
pub fn seam_jumps_where(
    seams: &[Seam],
    pages: &[LightmapPage],
    floor: f64,
    keep: impl Fn(usize, usize) -> bool,
) -> SeamJumps {
    let mut out = SeamJumps {
        seams: 0,
        ..SeamJumps::default()
    };
    let mut total = 0.0f64;
    for (i, s) in seams.iter().enumerate() {
        let mut counted = false;
        for (k, t) in s.samples().enumerate() {
            if !keep(i, k) {
                continue;
            }
            let jump = sample_jump(s, t, pages, floor);
            total += jump;
            out.max = out.max.max(jump);
            out.samples += 1;
            counted = true;
        }
        out.seams += usize::from(counted);
    }
    out.mean = total / out.samples.max(1) as f64;
    out
}

/// The least mean luminance a seam sample's jump is taken relative to: 1% of the mean
/// luminance of the pages' covered texels.
pub fn jump_floor(pages: &[LightmapPage]) -> f64 {
    let (mut sum, mut count) = (0.0f64, 0.0f64);
    for p in pages {
        for (t, &c) in p.texels.iter().zip(&p.covered) {
            if c {
                sum += luminance(*t) as f64;
                count += 1.0;
            }
        }
    }
    0.01 * sum / count.max(1.0)
}

/// The relative jump across `seam` at parameter `t` on `pages` ([`SeamJumps`]), its mean
/// taken as at least `floor`.
pub fn sample_jump(seam: &Seam, t: f32, pages: &[LightmapPage], floor: f64) -> f64 {
    let l = [0, 1].map(|k| {
        luminance(sample_at(
            &pages[seam.sides[k].page as usize],
            seam.at(k, t),
        )) as f64
    });
    (l[0] - l[1]).abs() / (0.5 * (l[0] + l[1])).max(floor).max(1e-30)
}
