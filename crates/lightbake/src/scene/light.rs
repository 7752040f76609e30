//! Punctual lights as the scene describes them (`KHR_lights_punctual`). What they emit is
//! computed in [`crate::lights`].

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::error::{BakeError, Result};

/// What kind of punctual light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
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
    /// A one-sided rectangle centred on `position`, emitting uniformly (Lambertian) towards
    /// `direction` (Bevy's `RectLight`: its local XY plane, facing local −Z); `intensity` is
    /// its luminance, nits.
    Rect {
        /// Unit world vector along the rectangle's width (the local X axis).
        right: Vec3,
        /// Width along `right`, m (> 0).
        width: f32,
        /// Height along `direction × right`, m (> 0).
        height: f32,
    },
}

/// Which part of a light's light the lightmaps hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightBake {
    /// Direct and indirect light: the engine must not light lightmapped meshes with it again
    /// (Bevy: `affects_lightmapped_mesh_diffuse = false`). The default.
    #[default]
    Full,
    /// Only the light it sends after one or more reflections: the engine keeps the light in
    /// real time, with its own shadows, for lightmapped meshes too (Bevy's mixed lighting:
    /// `affects_lightmapped_mesh_diffuse = true`). Its direct light still feeds the
    /// interreflections.
    IndirectOnly,
}

/// A punctual light (`KHR_lights_punctual`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Light {
    /// Name used in messages and the plan.
    pub name: String,
    /// Type and shape.
    pub kind: LightKind,
    /// Linear RGB colour; multiplied by `intensity`.
    pub color: Vec3,
    /// Candela for point and spot lights; lux for directional lights; nits for rect lights.
    pub intensity: f32,
    /// Distance (m) beyond which the light has no effect, with the smooth window
    /// `(1 − (d/range)⁴)²` that Bevy uses; `None` = infinite.
    pub range: Option<f32>,
    /// World position (point and spot).
    pub position: Vec3,
    /// Unit world direction the light travels (spot axis, sun direction, the side a rect
    /// light faces): the node's −Z.
    pub direction: Vec3,
    /// Which part of its light the lightmaps hold. Default [`LightBake::Full`].
    pub bake: LightBake,
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
        if let Some(r) = self.range
            && !(r.is_finite() && r > 0.0)
        {
            return Err(bad(format!("range {r} must be positive")));
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
            LightKind::Rect {
                right,
                width,
                height,
            } => {
                if !(width.is_finite() && width > 0.0 && height.is_finite() && height > 0.0) {
                    return Err(bad(format!(
                        "rectangle {width} × {height} m must have a positive, finite width and height"
                    )));
                }
                if !right.is_finite()
                    || (right.length() - 1.0).abs() > 1e-3
                    || right.dot(self.direction).abs() > 1e-3
                {
                    return Err(bad(format!(
                        "the rectangle's width axis {right:?} must be a unit vector at right angles to its facing {:?}",
                        self.direction
                    )));
                }
            }
            LightKind::Point => {}
        }
        Ok(())
    }

    /// Whether the light sits at a point (point and spot lights), rather than at infinity or
    /// over an area.
    pub fn is_punctual(&self) -> bool {
        matches!(self.kind, LightKind::Point | LightKind::Spot { .. })
    }

    /// Whether the lightmaps hold this light's direct light ([`LightBake::Full`]).
    pub fn direct_is_baked(&self) -> bool {
        self.bake == LightBake::Full
    }

    /// Short type name for the plan and messages.
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            LightKind::Point => "point",
            LightKind::Spot { .. } => "spot",
            LightKind::Directional { .. } => "directional",
            LightKind::Rect { .. } => "rect",
        }
    }
}
