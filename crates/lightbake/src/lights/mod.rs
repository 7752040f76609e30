//! Light sources behind one interface, used by the direct pass ([`crate::direct`]), the
//! instant-radiosity walks ([`crate::vpl`]), the reference path tracer
//! ([`crate::analysis::reference`]) and the plan:
//!
//! * **irradiance at a point with its shadow ray** ([`LightSource::incident`]): what one
//!   sample of the light gives a surface point if nothing is in the way, and the segment a
//!   shadow ray must find empty ([`Incident::visible`]);
//! * **power for particle emission** ([`LightSource::power`]) and **emission sampling**
//!   ([`LightSource::emit`]): where a particle leaves and which way;
//! * **reach** ([`LightSource::misses`]): whether the light can reach a box at all.
//!
//! One file per kind, each citing what it implements: [`point`] and [`spot`] (glTF
//! `KHR_lights_punctual` as Bevy shades them), [`directional`] (the sun, with a disc),
//! [`rect`] (Bevy's `RectLight`, closed-form polygon irradiance), [`sky`] (uniform luminance)
//! and [`emissive`] (emissive triangles, closed-form polygon
//! irradiance). A scene's [`Light`] dispatches on its [`LightKind`] here, and nowhere else.

pub mod directional;
pub mod emissive;
pub mod point;
pub mod rect;
pub mod sky;
pub mod spot;
pub mod tree;

use glam::{Vec2, Vec3};

use crate::bvh::RayScene;
use crate::raster::SurfacePoint;
use crate::scene::{Light, LightKind};
pub use emissive::Emitters;

/// Light arriving at a surface point from one sample of a light, before visibility.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Irradiance at the point if nothing is in the way, lux, linear RGB.
    pub irradiance: Vec3,
    /// Unit direction from the point towards the light.
    pub direction: Vec3,
    /// Where the shadow ray along `direction` ends (m from the ray's origin): short of the
    /// light by the scene's ray offset, or out of the scene for lights at infinity.
    pub tmax: f32,
}

impl Incident {
    /// Whether nothing blocks the light: the shadow ray from `origin` (the point lifted off its
    /// surface, [`RayScene::offset`]) is empty.
    #[inline]
    pub fn visible(&self, rays: &RayScene, origin: Vec3) -> bool {
        !rays.occluded(origin, self.direction, 0.0, self.tmax)
    }
}

/// The disc that covers the scene, facing any direction: parallel light (the sun, the sky)
/// enters the scene through it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneDisc {
    /// Centre of the scene's bounds, m.
    pub centre: Vec3,
    /// Half the bounds' diagonal, m (at least 10⁻⁶).
    pub radius: f32,
}

impl SceneDisc {
    /// The disc around the bounds of `rays`.
    pub fn covering(rays: &RayScene) -> Self {
        Self {
            centre: 0.5 * (rays.bounds.0 + rays.bounds.1),
            radius: 0.5 * (rays.bounds.1 - rays.bounds.0).length().max(1e-6),
        }
    }

    /// Its area, m².
    pub fn area(&self) -> f32 {
        std::f32::consts::PI * self.radius * self.radius
    }

    /// Where parallel light travelling along `direction` enters: the point of the disc at
    /// concentric-disc sample `u`, moved back two radii against the light.
    pub fn entry(&self, direction: Vec3, u: Vec2) -> Vec3 {
        let (t, b) = crate::sampling::basis(direction);
        let disc = crate::sampling::concentric_disc(u) * self.radius;
        self.centre + t * disc.x + b * disc.y - direction * (2.0 * self.radius)
    }
}

/// Where a particle starts, which decides the first vertex of its path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Start {
    /// At a point light's position (the light itself is the first vertex).
    Point,
    /// On the disc covering the scene ([`SceneDisc::entry`]), as parallel light.
    Disc,
    /// On an emitting surface with this unit normal (the side it leaves from).
    Surface {
        /// Unit normal of the side the particle leaves.
        normal: Vec3,
    },
}

/// A particle leaving a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emission {
    /// Start point, m.
    pub origin: Vec3,
    /// Unit direction it travels.
    pub direction: Vec3,
    /// Factor on the particle's share of the light's power (a spot's falloff in this
    /// direction over its mean; 1 otherwise).
    pub weight: f32,
    /// What the start point is.
    pub start: Start,
}

/// What every baker stage asks of a punctual or directional light.
pub trait LightSource {
    /// The light at `at` for the sample `u` ∈ [0, 1)² (a point of the sun's disc; point
    /// lights use none), with its shadow ray's end on `rays`. `None` when it cannot arrive:
    /// behind the surface, out of range, outside the cone, or nothing emitted that way.
    fn incident(&self, at: &SurfacePoint, u: Vec2, rays: &RayScene) -> Option<Incident>;

    /// Total emitted power, lumens, linear RGB; light at infinity counts what crosses `disc`.
    fn power(&self, disc: &SceneDisc) -> Vec3;

    /// One particle, from the samples `u_position` and `u_direction` ∈ [0, 1)².
    fn emit(&self, u_position: Vec2, u_direction: Vec2, disc: &SceneDisc) -> Emission;

    /// Why the light cannot reach anything in the box [`lo`, `hi`] (`None` when it may).
    fn misses(&self, lo: Vec3, hi: Vec3) -> Option<&'static str>;
}

impl LightSource for Light {
    #[inline(always)]
    fn incident(&self, at: &SurfacePoint, u: Vec2, rays: &RayScene) -> Option<Incident> {
        match self.kind {
            LightKind::Point => point::incident(self, at, rays),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => spot::incident(self, inner_cone_angle, outer_cone_angle, at, rays),
            LightKind::Directional { angular_radius } => {
                directional::incident(self, angular_radius, at, u, rays)
            }
            LightKind::Rect {
                right,
                width,
                height,
            } => rect::incident(self, right, width, height, at, u, rays),
        }
    }

    fn power(&self, disc: &SceneDisc) -> Vec3 {
        match self.kind {
            LightKind::Point => point::power(self),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => spot::power(self, inner_cone_angle, outer_cone_angle),
            LightKind::Directional { .. } => directional::power(self, disc),
            LightKind::Rect { width, height, .. } => rect::power(self, width, height),
        }
    }

    fn emit(&self, u_position: Vec2, u_direction: Vec2, disc: &SceneDisc) -> Emission {
        match self.kind {
            LightKind::Point => point::emit(self, u_direction),
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => spot::emit(self, inner_cone_angle, outer_cone_angle, u_direction),
            LightKind::Directional { angular_radius } => {
                directional::emit(self, angular_radius, u_position, u_direction, disc)
            }
            LightKind::Rect {
                right,
                width,
                height,
            } => rect::emit(self, right, width, height, u_position, u_direction),
        }
    }

    fn misses(&self, lo: Vec3, hi: Vec3) -> Option<&'static str> {
        if self.intensity <= 0.0 || self.color.max_element() <= 0.0 {
            return Some("it emits nothing");
        }
        match self.kind {
            LightKind::Point => point::misses(self, lo, hi),
            LightKind::Spot {
                outer_cone_angle, ..
            } => spot::misses(self, outer_cone_angle, lo, hi),
            LightKind::Directional { .. } => None,
            LightKind::Rect { .. } => rect::misses(self, lo, hi),
        }
    }
}
