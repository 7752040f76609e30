//! Rectangular area lights (Bevy's `RectLight`): a one-sided rectangle of uniform luminance L
//! (nits) facing `direction`. Unoccluded, a surface point x with normal n receives Lambert's
//! closed form for the polygon (see `crate::form_factor`; Baum, Rushmeier & Winget 1989):
//!
//! E = π·L·F(x, n, rectangle) · W(d),  W(d) = saturate(1 − (d/range)⁴)²
//!
//! with d the distance to the rectangle's centre (Bevy's `getRangeFalloff` for rect lights).
//! Visibility is one shadow ray per sample towards a point spread uniformly over the
//! rectangle (sample `u`), so the footprint's samples average to the rectangle's visible
//! share: exact when it is all seen or all hidden, and in a penumbra the visible *area*
//! fraction rather than the form-factor-weighted one (the ratio estimator of the emissive
//! triangles makes the same trade, [`super::emissive`]). Bevy converts the light's lumens Φ
//! to L = Φ / (π·width·height); the light emits Φ, Lambertian, into the half-space it faces.

use glam::{Vec2, Vec3};

use super::{Emission, Incident, Start};
use crate::bvh::RayScene;
use crate::form_factor::point_to_polygon_form_factor;
use crate::raster::SurfacePoint;
use crate::sampling::cosine_hemisphere;
use crate::scene::Light;

/// The rectangle's half-axes: along its width (`right`) and its height (`up`, with
/// `up × right` = the facing, as Bevy's `cross(up, right)`).
fn half_axes(light: &Light, right: Vec3, width: f32, height: f32) -> (Vec3, Vec3) {
    let up = right.cross(light.direction);
    (right * (0.5 * width), up * (0.5 * height))
}

/// The four corners, in order around the rectangle.
pub fn corners(light: &Light, right: Vec3, width: f32, height: f32) -> [Vec3; 4] {
    let (r, u) = half_axes(light, right, width, height);
    let c = light.position;
    [c + r - u, c - r - u, c - r + u, c + r + u]
}

/// The light at `at` for the rectangle sample `u` (see the module docs).
pub fn incident(
    light: &Light,
    right: Vec3,
    width: f32,
    height: f32,
    at: &SurfacePoint,
    u: Vec2,
    rays: &RayScene,
) -> Option<Incident> {
    let from_light = at.position - light.position;
    if light.direction.dot(from_light) <= 0.0 {
        return None;
    }
    let window = match light.range {
        Some(r) => {
            let f = from_light.length_squared() / (r * r);
            let s = (1.0 - f * f).clamp(0.0, 1.0);
            s * s
        }
        None => 1.0,
    };
    let quad = corners(light, right, width, height);
    let f = point_to_polygon_form_factor(at.position, at.normal, &quad);
    let e = light.color * (std::f32::consts::PI * light.intensity * f * window);
    if e.max_element() <= 0.0 {
        return None;
    }
    // A point of the rectangle above the surface's horizon for the shadow ray: the sample,
    // its mirror image through the centre, the centre, or the highest corner.
    let (r, up) = half_axes(light, right, width, height);
    let above = |y: Vec3| at.geometric_normal.dot(y - at.position) > 0.0;
    let sample = light.position + r * (2.0 * u.x - 1.0) + up * (2.0 * u.y - 1.0);
    let mirror = 2.0 * light.position - sample;
    let highest = quad
        .into_iter()
        .max_by(|a, b| {
            let h = |y: &Vec3| at.geometric_normal.dot(*y - at.position);
            h(a).total_cmp(&h(b))
        })
        .unwrap_or(light.position);
    let y = [sample, mirror, light.position, highest]
        .into_iter()
        .find(|&y| above(y))?;
    let to = y - at.position;
    let d = to.length();
    if d <= 0.0 {
        return None;
    }
    Some(Incident {
        irradiance: e,
        direction: to / d,
        tmax: d - rays.epsilon(y),
    })
}

/// π·L·width·height, lumens (what Bevy's `RectLight::intensity` gives).
pub fn power(light: &Light, width: f32, height: f32) -> Vec3 {
    light.color * (std::f32::consts::PI * light.intensity * width * height)
}

/// A particle from a uniformly chosen point of the rectangle, leaving cosine-distributed
/// around its facing.
pub fn emit(
    light: &Light,
    right: Vec3,
    width: f32,
    height: f32,
    u_position: Vec2,
    u_direction: Vec2,
) -> Emission {
    let (r, up) = half_axes(light, right, width, height);
    Emission {
        origin: light.position + r * (2.0 * u_position.x - 1.0) + up * (2.0 * u_position.y - 1.0),
        direction: cosine_hemisphere(light.direction, u_direction),
        weight: 1.0,
        start: Start::Surface {
            normal: light.direction,
        },
    }
}

/// Why the light cannot reach the box `[lo, hi]`: all of it behind the rectangle's plane, or
/// beyond its range (`None` when it may).
pub fn misses(light: &Light, lo: Vec3, hi: Vec3) -> Option<&'static str> {
    let in_front = (0..8).any(|k| {
        let corner = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        light.direction.dot(corner - light.position) > 0.0
    });
    if !in_front {
        return Some("behind the light");
    }
    super::point::misses(light, lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{LightBake, LightKind};

    /// Lambert's form factor from a point under the corner of an a × b rectangle at height h
    /// (Howell's catalogue, configuration B-3): the centre sees four such quarters.
    fn corner_factor(a: f64, b: f64, h: f64) -> f64 {
        let (x, y) = (a / h, b / h);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
    }

    fn light(width: f32, height: f32) -> Light {
        Light {
            name: "panel".into(),
            kind: LightKind::Rect {
                right: Vec3::X,
                width,
                height,
            },
            color: Vec3::ONE,
            intensity: 1000.0,
            range: None,
            position: Vec3::new(0.0, 2.0, 0.0),
            direction: Vec3::NEG_Y,
            bake: LightBake::Full,
        }
    }

    #[test]
    fn irradiance_under_the_centre_is_lamberts_closed_form() {
        let l = light(1.0, 0.5);
        l.validate().unwrap();
        let rays = RayScene::build(&crate::scene::Scene::default());
        let at = SurfacePoint {
            position: Vec3::ZERO,
            normal: Vec3::Y,
            geometric_normal: Vec3::Y,
            triangle: 0,
            bary: Vec2::ZERO,
        };
        let LightKind::Rect {
            right,
            width,
            height,
        } = l.kind
        else {
            unreachable!()
        };
        let i = incident(&l, right, width, height, &at, Vec2::splat(0.3), &rays).unwrap();
        let f = 4.0 * corner_factor(0.5, 0.25, 2.0);
        let expected = std::f64::consts::PI * 1000.0 * f;
        assert!(
            ((i.irradiance.x as f64) / expected - 1.0).abs() < 1e-4,
            "{} vs {expected}",
            i.irradiance.x
        );
        // Far from a small panel the closed form tends to L·A/d² on its axis.
        assert!((expected / (1000.0 * 0.5 / 4.0) - 1.0).abs() < 0.05);
        // The shadow ray aims at the rectangle, and behind it nothing arrives.
        assert!(i.direction.y > 0.9 && (i.tmax - 2.0).abs() < 0.6);
        let behind = SurfacePoint {
            position: Vec3::new(0.0, 3.0, 0.0),
            ..at
        };
        assert!(incident(&l, right, width, height, &behind, Vec2::splat(0.3), &rays).is_none());
        assert_eq!(
            misses(&l, Vec3::new(-1.0, 2.5, -1.0), Vec3::new(1.0, 4.0, 1.0)),
            Some("behind the light")
        );
        assert_eq!(misses(&l, Vec3::splat(-1.0), Vec3::splat(1.0)), None);
    }

    #[test]
    fn power_is_pi_l_a_and_particles_leave_the_front() {
        let l = light(2.0, 0.5);
        assert!((power(&l, 2.0, 0.5).x - std::f32::consts::PI * 1000.0).abs() < 1e-2);
        for k in 0..64u32 {
            let u = Vec2::new((k % 8) as f32 / 8.0 + 0.06, (k / 8) as f32 / 8.0 + 0.06);
            let e = emit(&l, Vec3::X, 2.0, 0.5, u, Vec2::new(u.y, u.x));
            assert!(e.direction.dot(l.direction) > 0.0);
            assert!((e.origin.y - 2.0).abs() < 1e-6);
            assert!(e.origin.x.abs() <= 1.0 && e.origin.z.abs() <= 0.25 + 1e-6);
        }
    }
}
