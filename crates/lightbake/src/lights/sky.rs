//! The sky: uniform luminance L (nits) seen by every ray that leaves the scene. A point whose
//! whole hemisphere is open receives E = π·L; one cosine-distributed direction that escapes
//! is a one-sample estimate of it. As a particle source the sky sends 4π·L·A lumens through
//! the disc of area A that covers the scene ([`super::SceneDisc`]), from every direction.

use glam::{Vec2, Vec3};

use super::{Emission, Incident, SceneDisc, Start};
use crate::bvh::RayScene;
use crate::raster::SurfacePoint;
use crate::sampling::{cosine_hemisphere, uniform_cone};

/// One cosine-distributed sample of the sky at `at`: the direction for `u`, the estimate π·L
/// when it escapes. `None` when the direction points below the surface.
#[inline]
pub fn incident(sky: Vec3, at: &SurfacePoint, u: Vec2, rays: &RayScene) -> Option<Incident> {
    let dir = cosine_hemisphere(at.normal, u);
    (at.geometric_normal.dot(dir) > 0.0).then(|| Incident {
        irradiance: sky * std::f32::consts::PI,
        direction: dir,
        tmax: rays.escape_distance(),
    })
}

/// 4π·L·A, lumens.
pub fn power(sky: Vec3, disc: &SceneDisc) -> Vec3 {
    sky * (4.0 * std::f32::consts::PI * disc.area())
}

/// A particle entering through the scene's disc from a uniformly distributed direction.
pub fn emit(u_position: Vec2, u_direction: Vec2, disc: &SceneDisc) -> Emission {
    let d = uniform_cone(Vec3::Z, -1.0, u_direction);
    Emission {
        origin: disc.entry(d, u_position),
        direction: d,
        weight: 1.0,
        start: Start::Disc,
    }
}
