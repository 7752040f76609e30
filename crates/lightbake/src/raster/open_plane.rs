//! The validity pass's fast paths, answered by ball queries of the BVH instead of rays:
//! whether a texel's short probes can hit anything ([`short_probes_meet_nothing`]), and
//! whether the points of a hidden texel's footprint lie on its centre's side of every surface
//! ([`footprint_beside`]).

use glam::Vec3;

use super::{Patch, SurfacePoint};
use crate::bvh::RayScene;

/// Whether the short probes of `p` (along the surface from its lifted centre, along the
/// normal from `probe_points` of its footprint, within `reach`) can hit nothing, found
/// without tracing them: no triangle within their reach crosses the heights they run at. The
/// probes would then find nothing near and no back face, which is what the caller takes.
///
/// A probe leaves its point lifted by the ray offset ℓ ([`RayScene::offset`]), along the
/// surface (at heights ℓ ± its rounding, under 0.5ℓ) or along the normal (up from ℓ). So a
/// triangle in the ball around a tangent probe's reach meets it only if its vertices'
/// heights over the patch's plane span (0.2ℓ, 1.8ℓ), and one in the ball around the normal
/// probes only if a vertex rises above 0.2ℓ: the surface a texel lies on, and everything
/// below it, is never a candidate.
pub(super) fn short_probes_meet_nothing(
    rays: &RayScene,
    p: &Patch,
    reach: f32,
    probe_points: &[SurfacePoint],
) -> bool {
    let heights = |t: &[Vec3; 3], at: Vec3, n: Vec3| t.map(|v| (v - at).dot(n));
    let (c, n) = (p.position, p.geometric_normal);
    let lift = rays.epsilon(c);
    let along = rays.any_triangle_within(c, reach + 2.0 * lift, |t| {
        let h = heights(t, c, n);
        h.iter().any(|&h| h > 0.2 * lift) && h.iter().any(|&h| h < 1.8 * lift)
    });
    if along {
        return false;
    }
    // The probes from points on the patch's plane (within reach of its centre, at most 0.2ℓ
    // off it, facing as it does) start above 0.5ℓ and rise: one ball holds all their segments
    // (their two ends), and only a triangle with a vertex above 0.2ℓ can meet them. A probe
    // point elsewhere (a stretched texel, a crease) gets a ball of its own, over its own plane.
    let mid = c + n * (lift + 0.5 * reach);
    let mut radius = 0.0f32;
    for sp in probe_points {
        let (at, g) = (sp.position, sp.geometric_normal);
        let from = rays.offset(at, g);
        let to = from + g * reach;
        let on_plane =
            at.distance(c) <= reach && (at - c).dot(n).abs() <= 0.2 * lift && g.dot(n) >= 0.999;
        if on_plane {
            radius = radius.max(from.distance(mid)).max(to.distance(mid));
            continue;
        }
        let own = rays.epsilon(at);
        let hit = rays.any_triangle_within(0.5 * (from + to), 0.5 * reach + 2.0 * own, |t| {
            heights(t, at, g).iter().any(|&h| h > 0.2 * own)
        });
        if hit {
            return false;
        }
    }
    !rays.any_triangle_within(mid, radius + 2.0 * lift, |t| {
        heights(t, c, n).iter().any(|&h| h > 0.2 * lift)
    })
}

/// Whether every point of `points` (a texel's footprint, on its surface), lifted off the
/// surface as a ray from it would be, lies on the same side of every surface as `centre`
/// (lifted along its normal `n` in the same way) and within `within` of it: the points lie
/// on the centre's plane, and no triangle within the ball holding the segments from the
/// lifted centre to the lifted points crosses the heights they run at.
///
/// As in [`short_probes_meet_nothing`], the lifted points sit at heights within ℓ ± 0.5ℓ over
/// the plane (ℓ the ray offset, [`RayScene::offset`]), so the segments do too, and only a
/// triangle whose vertices' heights span (0.2ℓ, 1.8ℓ) can meet them: the surface the texel
/// lies on, the bottom of a crate standing on it and everything below are never candidates.
/// Where none lies in the ball, each point can be reached from the centre without crossing
/// a surface: it is in the same empty space, or inside the same solid.
pub(super) fn footprint_beside<'a>(
    rays: &RayScene,
    (centre, n): (Vec3, Vec3),
    points: impl IntoIterator<Item = &'a SurfacePoint>,
    within: f32,
) -> bool {
    let lift = rays.epsilon(centre);
    let from = rays.offset(centre, n);
    let mut radius = 0.0f32;
    for sp in points {
        let lifted = rays.offset(sp.position, sp.geometric_normal);
        let height = (lifted - centre).dot(n);
        if sp.geometric_normal.dot(n) < 0.999 || (height - lift).abs() > 0.5 * lift {
            return false;
        }
        radius = radius.max(lifted.distance(from));
    }
    radius <= within
        && !rays.any_triangle_within(from, radius + 2.0 * lift, |t| {
            let h = t.map(|v| (v - centre).dot(n));
            h.iter().any(|&h| h > 0.2 * lift) && h.iter().any(|&h| h < 1.8 * lift)
        })
}
