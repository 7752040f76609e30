//! Triangles an unwrap squashed or stretched. A triangle whose lightmap area is less than a
//! quarter of what the texel density gives its surface (under half the density along some
//! direction, on average) gets too few texels for the light on it, and bilinear filtering
//! fills it from its chart's neighbours; an edge drawn more than [`STRETCHED`] times longer
//! than the density makes it runs across texels that belong to other surfaces, and the seam
//! stitch along it pulls them all. xatlas does both to charts full of slivers: on OpenArena's
//! `oa_bases3` it mapped a 34 m² ceiling triangle to 1% of the density (a point 1 m from a
//! lamp read a tenth of its light); on `kaos` it drew a 0.33 m sliver's edge across 2 042
//! texels, and the stitch pulled a lit strip of wall on that row down to 4% of its light.
//! [`squashed`] finds such triangles after an unwrap, so the mesh can be charted another way
//! (`unwrap::pieces`, every flat region projected onto its own plane).

use glam::Vec2;

use super::MeshUnwrap;
use crate::scene::Mesh;

/// A triangle is squashed below this share of the density (its lightmap area below its
/// square).
pub(super) const SQUASHED_SCALE: f32 = 0.5;
/// An edge is stretched when its lightmap length is more than this many times the density's
/// (and more than [`STRETCH_SLACK`] texels beyond it).
pub(super) const STRETCHED: f32 = 4.0;
/// Texels an edge may run beyond [`STRETCHED`] times its length (short edges of small charts
/// are rounded up to whole texels by the packing).
pub(super) const STRETCH_SLACK: f32 = 2.0;

/// What [`squashed`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Distortion {
    /// Triangles of at least one texel given less than [`SQUASHED_SCALE`] of the density.
    pub(super) squashed: usize,
    /// The smallest share of the density a squashed triangle gets (1 when none is).
    pub(super) least: f32,
    /// Triangles with an edge more than [`STRETCHED`] times the density's length (and
    /// [`STRETCH_SLACK`] texels) that are not squashed.
    pub(super) stretched: usize,
}

impl Distortion {
    /// Squashed and stretched triangles.
    pub(super) fn count(&self) -> usize {
        self.squashed + self.stretched
    }

    /// For a warning: how many of each, and how squashed.
    pub(super) fn describe(&self) -> String {
        format!(
            "{} triangle(s) below half the texel density (down to {:.1}%), {} with an edge over {STRETCHED} times its length",
            self.squashed,
            100.0 * self.least,
            self.stretched
        )
    }
}

/// The triangles the unwrap squashes or stretches at `texels_per_unit` (see [`Distortion`]).
/// Triangles without a chart (degenerate ones xatlas leaves out) are not counted.
pub(super) fn squashed(mesh: &Mesh, unwrap: &MeshUnwrap, texels_per_unit: f32) -> Distortion {
    let size = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let position = |v: u32| {
        let source = unwrap.xref.as_ref().map_or(v, |x| x[v as usize]);
        mesh.positions[source as usize]
    };
    let mut found = Distortion {
        squashed: 0,
        least: 1.0,
        stretched: 0,
    };
    for (t, tri) in unwrap.indices.chunks_exact(3).enumerate() {
        if unwrap.triangle_charts.get(t).is_none_or(|&c| c == u32::MAX) {
            continue;
        }
        let world = [tri[0], tri[1], tri[2]].map(position);
        let uv = [tri[0], tri[1], tri[2]].map(|v| unwrap.uv1[v as usize] * size);
        let stretched = (0..3).any(|k| {
            let (i, j) = (k, (k + 1) % 3);
            let allowed = STRETCHED * world[i].distance(world[j]) * texels_per_unit + STRETCH_SLACK;
            uv[i].distance(uv[j]) > allowed
        });
        let [a, b, c] = world;
        let wanted = 0.5 * (b - a).cross(c - a).length() * texels_per_unit * texels_per_unit;
        let [p, q, r] = uv;
        let got = 0.5 * (q - p).perp_dot(r - p).abs();
        let scale = (got / wanted).sqrt();
        let squashed = wanted >= 1.0 && wanted.is_finite() && scale < SQUASHED_SCALE;
        if squashed {
            found.squashed += 1;
            found.least = found.least.min(scale);
        } else if stretched {
            found.stretched += 1;
        }
    }
    found
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
        assert_eq!(squashed(&mesh, &good, 2.0).count(), 0);
        // The fourth vertex pulled onto the diagonal's end: the second triangle has a tenth
        // of its height.
        let bad = full(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 0.1),
        ]);
        let found = squashed(&mesh, &bad, 2.0);
        assert_eq!((found.squashed, found.stretched), (1, 0));
        assert!((found.least - 0.1f32.sqrt()).abs() < 1e-3, "{found:?}");
        // At a tenth of the density the quad is under a texel: not squashed, but a lightmap
        // edge of 4 texels for 0.2 texels' length is stretched (both triangles hold it).
        let found = squashed(&mesh, &good, 0.1);
        assert_eq!((found.squashed, found.stretched), (0, 2));
    }
}
