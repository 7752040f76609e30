//! Punctual lights as the scene describes them (`KHR_lights_punctual`). What they emit is
//! computed in [`crate::lights`].

use glam::Vec3;
use serde::Serialize;

use crate::error::{BakeError, Result};

/// What kind of punctual light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum LightKind {
    /// Emits equally in every direction from `position`.
    Point,
    /// A point light limited to a cone around `direction`; full intensity inside
    /// `inner_cone_angle`, smoothly falling to zero at `outer_cone_angle` (radians, from the
    /// axis), with the glTF/Bevy falloff.
    Spot {
        /// Radians, [0, outer).
        inner_cone_angle: f32,
        /// Radians, (inner, π/2].
        outer_cone_angle: f32,
    },
    /// Parallel light travelling along `direction` (the sun).
    Directional {
        /// Angular radius of the disc, radians (0 = hard shadows; the sun is ≈ 0.00465).
        angular_radius: f32,
    },
}

/// A punctual light (`KHR_lights_punctual`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Light {
    /// Name used in messages and the plan.
    pub name: String,
    /// Type and shape.
    pub kind: LightKind,
    /// Linear RGB colour; multiplied by `intensity`.
    pub color: Vec3,
    /// Candela for point and spot lights; lux for directional lights.
    pub intensity: f32,
    /// Distance (m) beyond which the light has no effect, with the smooth window
    /// `(1 − (d/range)⁴)²` that Bevy uses; `None` = infinite.
    pub range: Option<f32>,
    /// World position (point and spot).
    pub position: Vec3,
    /// Unit world direction the light travels (spot axis, sun direction): the node's −Z.
    pub direction: Vec3,
}

impl Light {
    /// Checks that parameters are finite and in range.
    ///
    /// # Errors
    /// [`BakeError::BadLight`] naming the light.
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| BakeError::BadLight {
            light: self.name.clone(),
            message,
        };
        if !self.color.is_finite() || self.color.min_element() < 0.0 {
            return Err(bad(format!(
                "colour {:?} must be finite and non-negative",
                self.color
            )));
        }
        if !self.intensity.is_finite() || self.intensity < 0.0 {
            return Err(bad(format!(
                "intensity {} must be finite and non-negative",
                self.intensity
            )));
        }
        if let Some(r) = self.range {
            if !(r.is_finite() && r > 0.0) {
                return Err(bad(format!("range {r} must be positive")));
            }
        }
        if !self.position.is_finite() {
            return Err(bad(format!("position {:?} is not finite", self.position)));
        }
        if !self.direction.is_finite() || (self.direction.length() - 1.0).abs() > 1e-3 {
            return Err(bad(format!(
                "direction {:?} must be a unit vector",
                self.direction
            )));
        }
        match self.kind {
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                if !(0.0..=std::f32::consts::FRAC_PI_2).contains(&outer_cone_angle)
                    || !(0.0..=outer_cone_angle).contains(&inner_cone_angle)
                {
                    return Err(bad(format!(
                        "cone angles inner {inner_cone_angle} / outer {outer_cone_angle} rad must satisfy 0 ≤ inner ≤ outer ≤ π/2"
                    )));
                }
            }
            LightKind::Directional { angular_radius } => {
                if !(0.0..=0.5).contains(&angular_radius) {
                    return Err(bad(format!(
                        "angular radius {angular_radius} rad must be in [0, 0.5]"
                    )));
                }
            }
            LightKind::Point => {}
        }
        Ok(())
    }

    /// Whether the light sits at a point (point and spot lights), rather than at infinity.
    pub fn is_punctual(&self) -> bool {
        matches!(self.kind, LightKind::Point | LightKind::Spot { .. })
    }

    /// Short type name for the plan and messages.
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional { .. } => "directional",
        }
    }
}
