//! Directional lights (the sun): parallel light of illuminance E⊥ (lux) on a surface facing
//! it, so E = E⊥·cosθ. A sun with an angular radius is a disc: each sample takes a direction
//! uniformly in its cone, which softens shadows. As a particle source it sends E⊥·A lumens
//! through the disc of area A that covers the scene ([`super::SceneDisc`]).

use glam::{Vec2, Vec3};

use super::{Emission, Incident, SceneDisc, Start};
use crate::bvh::RayScene;
use crate::raster::SurfacePoint;
use crate::sampling::uniform_cone;
use crate::scene::Light;

/// The direction light travels for sample `u`: the light's own, or one of its disc's.
fn travel(light: &Light, angular_radius: f32, u: Vec2) -> Vec3 {
    if angular_radius > 0.0 {
        uniform_cone(light.direction, angular_radius.cos(), u)
    } else {
        light.direction
    }
}

/// The light at `at` from the point `u` of the sun's disc.
#[inline]
pub fn incident(
    light: &Light,
    angular_radius: f32,
    at: &SurfacePoint,
    u: Vec2,
    rays: &RayScene,
) -> Option<Incident> {
    let to_sun = -light.direction;
    let dir = if angular_radius > 0.0 {
        uniform_cone(to_sun, angular_radius.cos(), u)
    } else {
        to_sun
    };
    let cos = at.normal.dot(dir);
    (cos > 0.0 && at.geometric_normal.dot(dir) > 0.0).then(|| Incident {
        irradiance: light.color * (light.intensity * cos),
        direction: dir,
        tmax: rays.escape_distance(),
    })
}

/// E⊥ times the disc's area, lumens.
pub fn power(light: &Light, disc: &SceneDisc) -> Vec3 {
    light.color * light.intensity * disc.area()
}

/// A particle entering through the scene's disc.
pub fn emit(
    light: &Light,
    angular_radius: f32,
    u_position: Vec2,
    u_direction: Vec2,
    disc: &SceneDisc,
) -> Emission {
    let d = travel(light, angular_radius, u_direction);
    Emission {
        origin: disc.entry(d, u_position),
        direction: d,
        weight: 1.0,
        start: Start::Disc,
    }
}
