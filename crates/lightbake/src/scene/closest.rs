//! Closest points on triangles (for placing check points on surfaces and for sampling a
//! lightmap at a dynamic object's nearest surface).

use glam::{Vec2, Vec3};

/// The point of triangle `t` nearest `p`, and its barycentrics (of the second and third
/// vertices); Ericson, *Real-Time Collision Detection*, 5.1.5.
pub fn closest_on_triangle(p: Vec3, t: [Vec3; 3]) -> (Vec3, Vec2) {
    let [a, b, c] = t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Vec2::ZERO);
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Vec2::new(1.0, 0.0));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Vec2::new(v, 0.0));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Vec2::new(0.0, 1.0));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Vec2::new(0.0, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Vec2::new(1.0 - w, w));
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (a + ab * v + ac * w, Vec2::new(v, w))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_and_barycentrics() {
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let (q, b) = closest_on_triangle(Vec3::new(0.25, 0.25, 1.0), t);
        assert!((q - Vec3::new(0.25, 0.25, 0.0)).length() < 1e-6);
        assert!((b - Vec2::new(0.25, 0.25)).length() < 1e-6);
        let (q, b) = closest_on_triangle(Vec3::new(2.0, -1.0, 0.0), t);
        assert_eq!((q, b), (Vec3::X, Vec2::new(1.0, 0.0)));
        let (q, b) = closest_on_triangle(Vec3::new(1.0, 1.0, 0.0), t);
        assert!((q - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6);
        assert!((b - Vec2::new(0.5, 0.5)).length() < 1e-6);
    }
}
