//! Triangles an unwrap squashed: a triangle whose lightmap area is less than a quarter of
//! what the texel density gives its surface (under half the density along some direction, on
//! average) gets too few texels for the light on it, and bilinear filtering fills it from its
//! chart's neighbours. xatlas does this to large triangles of charts full of slivers: on
//! OpenArena's `oa_bases3` it mapped a 34 m² ceiling triangle to 1% of the density (a point
//! 1 m from a lamp read a tenth of its light). [`squashed`] finds such triangles after an
//! unwrap, so the mesh can be charted another way (`unwrap::pieces`, every flat region
//! projected onto its own plane).

use glam::Vec2;

use super::MeshUnwrap;
use crate::scene::Mesh;

/// A triangle is squashed below this share of the density (its lightmap area below its
/// square).
pub(super) const SQUASHED_SCALE: f32 = 0.5;

/// How many triangles of at least one texel at `texels_per_unit` the unwrap gives less than
/// [`SQUASHED_SCALE`] of that density, and the smallest share any of them gets (1 when none).
/// Triangles without a chart (degenerate ones xatlas leaves out) are not counted.
pub(super) fn squashed(mesh: &Mesh, unwrap: &MeshUnwrap, texels_per_unit: f32) -> (usize, f32) {
    let size = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let position = |v: u32| {
        let source = unwrap.xref.as_ref().map_or(v, |x| x[v as usize]);
        mesh.positions[source as usize]
    };
    let (mut count, mut least) = (0usize, 1.0f32);
    for (t, tri) in unwrap.indices.chunks_exact(3).enumerate() {
        if unwrap.triangle_charts.get(t).is_none_or(|&c| c == u32::MAX) {
            continue;
        }
        let [a, b, c] = [tri[0], tri[1], tri[2]].map(position);
        let wanted = 0.5 * (b - a).cross(c - a).length() * texels_per_unit * texels_per_unit;
        if !(wanted >= 1.0 && wanted.is_finite()) {
            continue;
        }
        let [p, q, r] = [tri[0], tri[1], tri[2]].map(|v| unwrap.uv1[v as usize] * size);
        let got = 0.5 * (q - p).perp_dot(r - p).abs();
        let scale = (got / wanted).sqrt();
        if scale < SQUASHED_SCALE {
            count += 1;
            least = least.min(scale);
        }
    }
    (count, least)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::unwrap::UvOrigin;

    /// A 4 × 2 texel rectangle holding two triangles of a 2 m × 1 m quad at 2 texels per unit:
    /// one mapped at full density, one squashed into a sliver.
    #[test]
    fn finds_the_squashed_triangle_and_its_scale() {
        let mesh = Mesh {
            positions: vec![
                glam::Vec3::ZERO,
                glam::Vec3::new(2.0, 0.0, 0.0),
                glam::Vec3::new(2.0, 1.0, 0.0),
                glam::Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: vec![glam::Vec3::Z; 4],
            indices: vec![0, 1, 2, 0, 2, 3],
            ..Mesh::default()
        };
        let full = |uv: Vec<Vec2>| MeshUnwrap {
            width: 4,
            height: 2,
            uv1: uv,
            xref: None,
            indices: mesh.indices.clone(),
            triangle_charts: vec![0, 0],
            chart_count: 1,
            origin: UvOrigin::Xatlas,
            texels_per_metre: 2.0,
            scaled_to_fit: false,
        };
        let good = full(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]);
        assert_eq!(squashed(&mesh, &good, 2.0), (0, 1.0));
        // The fourth vertex pulled onto the diagonal's end: the second triangle has a tenth
        // of its height.
        let bad = full(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.1),
        ]);
        let (count, least) = squashed(&mesh, &bad, 2.0);
        assert_eq!(count, 1);
        assert!((least - 0.1f32.sqrt()).abs() < 1e-3, "{least}");
    }
}
