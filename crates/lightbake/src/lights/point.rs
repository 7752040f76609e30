//! Point lights (glTF `KHR_lights_punctual` `point`, as Bevy shades them): intensity I in
//! candela, so at distance d the irradiance on a surface at angle θ is
//!
//! E = I·cosθ/d² · W(d),  W(d) = saturate(1 − (d/range)⁴)²  (Bevy's range window),
//!
//! with d² clamped below at 10⁻⁴ m². The light emits 4π·I lumens, uniformly in direction.

use glam::{Vec2, Vec3};

use super::{Emission, Incident, Start};
use crate::bvh::RayScene;
use crate::raster::SurfacePoint;
use crate::sampling::uniform_cone;
use crate::scene::Light;

/// The inverse-square irradiance of a light at its position, times `falloff(l)` of the
/// direction l from the point to the light (1 for a point light, the cone for a spot).
#[inline]
pub(super) fn inverse_square(
    light: &Light,
    at: &SurfacePoint,
    rays: &RayScene,
    falloff: impl Fn(Vec3) -> f32,
) -> Option<Incident> {
    let to_light = light.position - at.position;
    let d2 = to_light.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let d = d2.sqrt();
    let l = to_light / d;
    let cos = at.normal.dot(l);
    if cos <= 0.0 || at.geometric_normal.dot(l) <= 0.0 {
        return None;
    }
    let window = match light.range {
        Some(r) => {
            let f = d2 / (r * r);
            let s = (1.0 - f * f).clamp(0.0, 1.0);
            s * s
        }
        None => 1.0,
    };
    let cone = falloff(l);
    let e = light.color * (light.intensity * cos * window * cone / d2.max(1e-4));
    (e.max_element() > 0.0).then(|| Incident {
        irradiance: e,
        direction: l,
        tmax: d - rays.epsilon(light.position),
    })
}

/// The light at `at` (see the module docs).
#[inline]
pub fn incident(light: &Light, at: &SurfacePoint, rays: &RayScene) -> Option<Incident> {
    inverse_square(light, at, rays, |_| 1.0)
}

/// 4π·I, lumens.
pub fn power(light: &Light) -> Vec3 {
    light.color * light.intensity * 4.0 * std::f32::consts::PI
}

/// A particle leaving in a uniformly distributed direction.
pub fn emit(light: &Light, u_direction: Vec2) -> Emission {
    Emission {
        origin: light.position,
        direction: uniform_cone(Vec3::Z, -1.0, u_direction),
        weight: 1.0,
        start: Start::Point,
    }
}

/// The distance from the light to the box `[lo, hi]` against its range.
pub(super) fn out_of_range(light: &Light, lo: Vec3, hi: Vec3) -> bool {
    let nearest = light.position.clamp(lo, hi);
    light
        .range
        .is_some_and(|range| nearest.distance(light.position) >= range)
}

/// Why the light cannot reach the box (`None` when it may).
pub fn misses(light: &Light, lo: Vec3, hi: Vec3) -> Option<&'static str> {
    out_of_range(light, lo, hi).then_some("out of range")
}
