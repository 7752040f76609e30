//! How much an edit can change each texel's direct light: an upper bound per patch (lux,
//! luminance), infinite where the change is not bounded cheaply and the texel must be lit
//! again. The runner weighs it, over the texel's earlier light, against a share of the bake's
//! estimated error.
//!
//! * A light that changed (moved, turned, switched on or off, another intensity, colour,
//!   range or cone) changes every texel it reaches, before or after: a texel within its
//!   range and cone, in front of it, from which a shadow ray of its centre or of a corner of
//!   its footprint to the light (each corner of a rect light; the sun's disc's centre and
//!   rim) is open, gets an infinite bound.
//! * Geometry that moved, changed, came or went (each instance's box before and after) can
//!   cast or lift a shadow: a texel whose shadow segment to any light crosses a box (grown by
//!   the texel and the light's size) gets an infinite bound, as does a texel within a box's
//!   bounding sphere. Against the sky and emitting surfaces it can hide at most what the box
//!   covers: the luminance behind it times the solid angle of its bounding sphere.
//! * An emitting surface whose light changed changes a texel's light by at most its
//!   luminance times its solid angle; a sky of another colour by the largest change of its
//!   luminance times π.

use glam::Vec3;
use rayon::prelude::*;

use super::edits::{Aabb, Edits};
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::raster::{Patch, Patches};
use crate::scene::{Light, LightKind};

/// The bound of every patch's change of direct light (lux, luminance): 0 where the edits
/// cannot reach it, `f32::INFINITY` where it must be lit again. `lights` are the scene's
/// lights now; `hidden` the largest luminance a moved box can hide or uncover (the sky's,
/// before or after, and every emitting surface's), nits.
pub(crate) fn direct_bounds(
    edits: &Edits,
    lights: &[Light],
    hidden: f32,
    rays: &RayScene,
    patches: &Patches,
) -> Vec<f32> {
    (patches.patches.par_iter())
        .map(|p| {
            if !p.is_valid() {
                return 0.0;
            }
            let at = Texel::of(p, rays);
            for l in edits.lights.iter().flat_map(|(a, b)| [a, b]).flatten() {
                if at.reaches(l, rays) {
                    return f32::INFINITY;
                }
            }
            let mut bound = 0.0f32;
            for b in &edits.boxes {
                if lights.iter().any(|l| at.shadow_crosses(l, *b, rays)) {
                    return f32::INFINITY;
                }
                bound += hidden * at.solid_angle(*b);
            }
            for (b, lum) in &edits.emitters {
                bound += lum * at.solid_angle(*b);
            }
            if let Some((was, now)) = edits.sky {
                bound += luminance((now - was).abs()).max((now - was).abs().max_element())
                    * std::f32::consts::PI;
            }
            bound
        })
        .collect()
}

/// A texel as the bounds see it: its centre and footprint corners, off the surface.
struct Texel {
    points: [Vec3; 5],
    normal: Vec3,
    size: f32,
}

impl Texel {
    fn of(p: &Patch, rays: &RayScene) -> Self {
        let n = p.geometric_normal;
        let u = n.any_orthonormal_vector();
        let v = n.cross(u);
        let h = 0.5 * p.texel_size;
        let lift = |q: Vec3| rays.offset(q, n);
        Self {
            points: [
                lift(p.position),
                lift(p.position + (u + v) * h),
                lift(p.position + (u - v) * h),
                lift(p.position - (u + v) * h),
                lift(p.position - (u - v) * h),
            ],
            normal: n,
            size: p.texel_size.max(0.0),
        }
    }

    /// The points a light's shadow rays go to (empty for a directional light).
    fn targets(l: &Light) -> Vec<Vec3> {
        match l.kind {
            LightKind::Rect {
                right,
                width,
                height,
            } => {
                let up = l.direction.cross(right) * (0.5 * height);
                let r = right * (0.5 * width);
                vec![
                    l.position,
                    l.position + r + up,
                    l.position + r - up,
                    l.position - r + up,
                    l.position - r - up,
                ]
            }
            LightKind::Directional { .. } => Vec::new(),
            _ => vec![l.position],
        }
    }

    /// Whether `l` can light this texel.
    fn reaches(&self, l: &Light, rays: &RayScene) -> bool {
        let slack = 0.1;
        if let LightKind::Directional { angular_radius } = l.kind {
            let to = -l.direction;
            if self.normal.dot(to) < -slack - angular_radius.sin() {
                return false;
            }
            let mut dirs = vec![to];
            if angular_radius > 0.0 {
                let u = to.any_orthonormal_vector();
                let v = to.cross(u);
                let t = angular_radius.tan();
                dirs.extend([u, -u, v, -v].map(|w| (to + w * t).normalize()));
            }
            let far = rays.escape_distance();
            return (self.points.iter())
                .any(|&x| dirs.iter().any(|&d| !rays.occluded(x, d, 0.0, far)));
        }
        for t in Self::targets(l) {
            for &x in &self.points {
                let d = t - x;
                let dist = d.length();
                if dist <= 0.0 || l.range.is_some_and(|r| dist > r + self.size) {
                    continue;
                }
                let dir = d / dist;
                if self.normal.dot(dir) < -slack {
                    continue;
                }
                if let LightKind::Spot {
                    outer_cone_angle, ..
                } = l.kind
                    && (-dir).dot(l.direction)
                        < (outer_cone_angle + slack).min(std::f32::consts::PI).cos()
                {
                    continue;
                }
                if matches!(l.kind, LightKind::Rect { .. }) && (-dir).dot(l.direction) <= 0.0 {
                    continue;
                }
                if !rays.occluded(x, dir, 0.0, dist * (1.0 - 1e-4)) {
                    return true;
                }
            }
        }
        false
    }

    /// Whether a shadow ray from this texel to `l` can cross box `b`.
    fn shadow_crosses(&self, l: &Light, b: Aabb, rays: &RayScene) -> bool {
        let x = self.points[0];
        let grow = |by: f32| (b.0 - Vec3::splat(by), b.1 + Vec3::splat(by));
        match l.kind {
            LightKind::Directional { angular_radius } => {
                let far = rays.escape_distance();
                let reach = self.size + angular_radius.tan() * x.distance(0.5 * (b.0 + b.1)) + 1e-3;
                segment_hits(x, x - l.direction * far, grow(reach))
            }
            _ => {
                let size = match l.kind {
                    LightKind::Rect { width, height, .. } => 0.5 * width.hypot(height),
                    _ => 0.0,
                };
                if l.range
                    .is_some_and(|r| x.distance(l.position) > r + size + self.size)
                {
                    return false;
                }
                segment_hits(x, l.position, grow(self.size + size + 1e-3))
            }
        }
    }

    /// The solid angle of box `b`'s bounding sphere seen from this texel (sr): 0 behind the
    /// texel, infinite when the texel is inside it.
    fn solid_angle(&self, b: Aabb) -> f32 {
        let c = 0.5 * (b.0 + b.1);
        let r = 0.5 * (b.1 - b.0).length() + self.size;
        let to = c - self.points[0];
        let d = to.length();
        if d <= r {
            return f32::INFINITY;
        }
        if self.normal.dot(to) < -r {
            return 0.0;
        }
        let s = (r / d).min(1.0);
        std::f32::consts::TAU * (1.0 - (1.0 - s * s).sqrt())
    }
}

/// Whether the segment from `a` to `b` meets box `bx` (slab test).
fn segment_hits(a: Vec3, b: Vec3, bx: Aabb) -> bool {
    let d = b - a;
    let (mut t0, mut t1) = (0.0f32, 1.0f32);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if a[k] < bx.0[k] || a[k] > bx.1[k] {
                return false;
            }
            continue;
        }
        let (mut lo, mut hi) = ((bx.0[k] - a[k]) / d[k], (bx.1[k] - a[k]) / d[k]);
        if lo > hi {
            std::mem::swap(&mut lo, &mut hi);
        }
        t0 = t0.max(lo);
        t1 = t1.min(hi);
        if t0 > t1 {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_and_boxes() {
        let b = (Vec3::ZERO, Vec3::ONE);
        assert!(segment_hits(
            Vec3::new(-1.0, 0.5, 0.5),
            Vec3::new(2.0, 0.5, 0.5),
            b
        ));
        assert!(!segment_hits(
            Vec3::new(-1.0, 2.0, 0.5),
            Vec3::new(2.0, 2.0, 0.5),
            b
        ));
        assert!(
            !segment_hits(Vec3::new(-2.0, 0.5, 0.5), Vec3::new(-1.0, 0.5, 0.5), b),
            "stops short"
        );
        assert!(
            segment_hits(Vec3::splat(0.5), Vec3::splat(0.6), b),
            "inside"
        );
    }

    #[test]
    fn solid_angle_of_a_far_sphere_is_its_disc() {
        let t = Texel {
            points: [Vec3::ZERO; 5],
            normal: Vec3::Y,
            size: 0.0,
        };
        // A unit box 100 m up: its sphere's radius √3/2, disc π r² / d².
        let b = (Vec3::new(-0.5, 99.5, -0.5), Vec3::new(0.5, 100.5, 0.5));
        let r = 0.75f32.sqrt();
        let want = std::f32::consts::PI * r * r / 1e4;
        assert!((t.solid_angle(b) - want).abs() < 1e-3 * want);
        // Behind the texel: nothing; around it: everything.
        assert_eq!(
            t.solid_angle((Vec3::new(-0.5, -100.5, -0.5), Vec3::new(0.5, -99.5, 0.5))),
            0.0
        );
        assert_eq!(
            t.solid_angle((Vec3::splat(-1.0), Vec3::splat(1.0))),
            f32::INFINITY
        );
    }
}
