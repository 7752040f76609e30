//! Spot lights (glTF `KHR_lights_punctual` `spot`, as Bevy shades them): a point light
//! ([`super::point`]) times the cone falloff
//!
//! S = saturate(cd·scale + offset)²,  scale = 1/max(cos θᵢ − cos θₒ, 10⁻⁴),
//! offset = −cos θₒ·scale,
//!
//! with cd the cosine between the spot axis and the direction to the point: full intensity
//! inside the inner angle θᵢ, smoothly falling to zero at the outer angle θₒ.

use glam::{Vec2, Vec3};

use super::{Emission, Incident, Start, point};
use crate::bvh::RayScene;
use crate::raster::SurfacePoint;
use crate::sampling::uniform_cone;
use crate::scene::Light;

/// The cone falloff S towards a point seen along `-l` from the light (see the module docs).
#[inline]
fn falloff(light: &Light, inner: f32, outer: f32, l: Vec3) -> f32 {
    let (ci, co) = (inner.cos(), outer.cos());
    let scale = 1.0 / (ci - co).max(1e-4);
    let offset = -co * scale;
    let cd = light.direction.dot(-l);
    let a = (cd * scale + offset).clamp(0.0, 1.0);
    a * a
}

/// The light at `at`: inverse square times the cone falloff.
#[inline]
pub fn incident(
    light: &Light,
    inner: f32,
    outer: f32,
    at: &SurfacePoint,
    rays: &RayScene,
) -> Option<Incident> {
    point::inverse_square(light, at, rays, |l| falloff(light, inner, outer, l))
}

/// Total power of the cone falloff per candela: ∫ S(θ) dω over the cone, by the midpoint rule
/// on 512 rings.
pub fn solid_angle(inner: f32, outer: f32) -> f32 {
    let (ci, co) = (inner.cos(), outer.cos());
    let scale = 1.0 / (ci - co).max(1e-4);
    let steps = 512;
    let mut sum = 0.0f32;
    for k in 0..steps {
        let theta = outer * (k as f32 + 0.5) / steps as f32;
        let a = ((theta.cos() - co) * scale).clamp(0.0, 1.0);
        sum += a * a * theta.sin() * outer / steps as f32;
    }
    std::f32::consts::TAU * sum
}

/// I·∫S dω, lumens.
pub fn power(light: &Light, inner: f32, outer: f32) -> Vec3 {
    light.color * light.intensity * solid_angle(inner, outer)
}

/// A particle leaving uniformly in the outer cone, weighted by the falloff over its mean.
pub fn emit(light: &Light, inner: f32, outer: f32, u_direction: Vec2) -> Emission {
    let d = uniform_cone(light.direction, outer.cos(), u_direction);
    let (ci, co) = (inner.cos(), outer.cos());
    let a = ((d.dot(light.direction) - co) / (ci - co).max(1e-4)).clamp(0.0, 1.0);
    let solid = std::f32::consts::TAU * (1.0 - co);
    let falloff_mean = solid_angle(inner, outer) / solid;
    Emission {
        origin: light.position,
        direction: d,
        weight: a * a / falloff_mean.max(1e-12),
        start: Start::Point,
    }
}

/// Why the light cannot reach the box: out of range, or the box's bounding sphere lies wholly
/// outside the outer cone.
pub fn misses(light: &Light, outer: f32, lo: Vec3, hi: Vec3) -> Option<&'static str> {
    if point::out_of_range(light, lo, hi) {
        return Some("out of range");
    }
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    let to = centre - light.position;
    let d = to.length();
    if d > radius {
        let angle_to_centre = light.direction.dot(to / d).clamp(-1.0, 1.0).acos();
        let angular_radius = (radius / d).clamp(0.0, 1.0).asin();
        if angle_to_centre - angular_radius > outer {
            return Some("outside the cone");
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solid_angle_matches_a_hard_cone() {
        // Inner = outer: a hard cone of solid angle 2π(1 − cos θ).
        let s = solid_angle(0.5, 0.5 + 1e-4);
        let hard = std::f32::consts::TAU * (1.0 - 0.5f32.cos());
        assert!((s - hard).abs() / hard < 0.01, "{s} {hard}");
    }
}
