//! Closed-form irradiance from a uniform Lambertian polygon at a point — Lambert's formula for
//! the differential-area-to-polygon form factor (Lambert 1760; Baum, Rushmeier & Winget 1989,
//! eq. 4; Dutré et al., *Advanced Global Illumination*, §6.2):
//!
//! F = 1/(2π) · Σᵢ Θᵢ · (n · Γ̂ᵢ),  Γ̂ᵢ = (Rᵢ × Rᵢ₊₁)/|Rᵢ × Rᵢ₊₁|,  Θᵢ = ∠(Rᵢ, Rᵢ₊₁)
//!
//! with Rᵢ = vᵢ − p. The polygon is first clipped to the receiver's upper half-space (parts
//! below the horizon send nothing). Irradiance from radiance L is E = π·L·F.

use glam::{DVec3, Vec3};

/// The unoccluded form factor from a differential patch at `p` with unit normal `n` to the
/// convex polygon `poly` (any winding), in [0, 1].
pub fn point_to_polygon_form_factor(p: Vec3, n: Vec3, poly: &[Vec3]) -> f32 {
    // A polygon lying in the receiver's tangent plane (the receiver's own triangle, or a
    // coplanar neighbour) is on the horizon and sends nothing. Without this test the clip
    // keeps it whole and, when it contains p, Lambert's sum gives a full 2π: a double-sided
    // emitter would light itself with its own radiance.
    if poly
        .iter()
        .all(|&v| n.dot(v - p).abs() <= 1e-5 * (v - p).length())
    {
        return 0.0;
    }
    // Clip to the half-space n·(x − p) ≥ 0 (Sutherland–Hodgman against one plane), summing
    // Lambert's edge terms over the clipped polygon's edges as its vertices come out (no
    // vertex list is kept: this runs for every emitter at every footprint sample).
    let n64 = n.as_dvec3();
    let mut sum = 0.0f64;
    let mut count = 0usize;
    let (mut first, mut last) = (DVec3::ZERO, DVec3::ZERO);
    let mut emit = |v: Vec3| {
        let r = (v - p).as_dvec3();
        if count == 0 {
            first = r;
        } else {
            sum += edge_term(last, r, n64);
        }
        last = r;
        count += 1;
    };
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = (n.dot(a - p), n.dot(b - p));
        if da >= 0.0 {
            emit(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            emit(a + (b - a) * (da / (da - db)));
        }
    }
    if count < 3 {
        return 0.0;
    }
    sum += edge_term(last, first, n64);
    // The sign follows the winding as seen from p; the magnitude is the form factor.
    ((sum.abs() / (2.0 * std::f64::consts::PI)) as f32).min(1.0)
}

/// Lambert's term of one polygon edge from `a` to `b` (relative to the receiver):
/// Θ·(n · Γ̂) with Θ the angle between them and Γ̂ the unit normal of their plane; zero for
/// a degenerate edge.
#[inline]
fn edge_term(a: DVec3, b: DVec3, n: DVec3) -> f64 {
    let c = a.cross(b);
    let len = c.length();
    if len <= 0.0 {
        return 0.0;
    }
    len.atan2(a.dot(b)) * n.dot(c) / len
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn a_polygon_in_the_receivers_plane_sends_nothing() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Z];
        // Inside the triangle, on its edge, outside it, either normal.
        for p in [
            Vec3::new(0.2, 0.0, 0.2),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 2.0),
        ] {
            for n in [Vec3::Y, Vec3::NEG_Y] {
                assert_eq!(point_to_polygon_form_factor(p, n, &tri), 0.0, "{p} {n}");
            }
        }
        // Lifted just off the plane, the triangle fills almost the whole hemisphere below.
        let f = point_to_polygon_form_factor(Vec3::new(0.2, -1e-4, 0.2), Vec3::Y, &tri);
        assert!(f > 0.99, "{f}");
    }

    /// Howell's catalogue, configuration B-3: differential element parallel to a rectangle
    /// a × b at height c, the element under one corner.
    pub(crate) fn corner_parallel(a: f64, b: f64, c: f64) -> f64 {
        let (x, y) = (a / c, b / c);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
    }

    #[test]
    fn matches_howell_parallel_rectangle() {
        for (a, b, c) in [(1.0f32, 1.0f32, 1.0f32), (0.2, 0.5, 2.0), (3.0, 0.1, 0.3)] {
            let poly = [
                Vec3::new(0.0, c, 0.0),
                Vec3::new(a, c, 0.0),
                Vec3::new(a, c, b),
                Vec3::new(0.0, c, b),
            ];
            let f = point_to_polygon_form_factor(Vec3::ZERO, Vec3::Y, &poly) as f64;
            let expected = corner_parallel(a as f64, b as f64, c as f64);
            assert!(
                (f - expected).abs() < 1e-5 * expected.max(1e-3),
                "{f} vs {expected}"
            );
        }
    }

    #[test]
    fn hemisphere_covering_polygon_gives_one() {
        let s = 1.0e4f32;
        let poly = [
            Vec3::new(-s, 1.0, -s),
            Vec3::new(s, 1.0, -s),
            Vec3::new(s, 1.0, s),
            Vec3::new(-s, 1.0, s),
        ];
        let f = point_to_polygon_form_factor(Vec3::ZERO, Vec3::Y, &poly);
        assert!((f - 1.0).abs() < 1e-3, "{f}");
    }

    #[test]
    fn polygon_below_the_horizon_is_clipped() {
        // Perpendicular unit square sharing an edge with the receiver plane, half below it.
        let poly = [
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, 1.0, 1.0),
            Vec3::new(0.5, -1.0, 1.0),
        ];
        let full = point_to_polygon_form_factor(Vec3::ZERO, Vec3::Y, &poly);
        let upper = [
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
            Vec3::new(0.5, 1.0, 1.0),
            Vec3::new(0.5, 0.0, 1.0),
        ];
        let half = point_to_polygon_form_factor(Vec3::ZERO, Vec3::Y, &upper);
        assert!((full - half).abs() < 1e-6 && full > 0.0);
        // Entirely below: nothing.
        let below = poly.map(|v| v - Vec3::Y * 2.0);
        assert_eq!(
            point_to_polygon_form_factor(Vec3::ZERO, Vec3::Y, &below),
            0.0
        );
    }
}
