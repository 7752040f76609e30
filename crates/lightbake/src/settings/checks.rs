//! The settings of the bake's checks of itself: the texel grid's error and the comparison
//! with the in-tree path tracer ([`CheckSettings`], `BakeSettings::checks`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `grid_error_points` | points | 0..=10⁶ | 16 384 | 16 384 | 16 384 |
//! | `verify_points` | points | 0..=10⁵ | 0 | 0 | 0 |
//! | `verify_paths` | paths per point | 2..=2²⁰ | 4096 | 4096 | 4096 |

use serde::{Deserialize, Serialize};

use super::Rule;

/// Where and how hard the bake checks its own result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CheckSettings {
    /// Points at which the bake checks its own texel grid: the direct light's bilinear
    /// reconstruction against the direct light at the point, added to the error estimate;
    /// 0 leaves the check out (the estimate then covers sampling noise only). Range
    /// 0..=1 000 000. Default 16 384.
    pub grid_error_points: u32,
    /// Points at which the finished bake is checked against the in-tree path tracer
    /// (`lightbake::analysis::verify`; the CLI's `--verify N`), spread over the baked
    /// surfaces a viewer can see; 0 leaves the check out. Range 0..=100 000. Default 0.
    pub verify_points: u32,
    /// Paths per point of that check: its reference's noise falls as 1/√paths. Range
    /// 2..=1 048 576. Default 4096.
    pub verify_paths: u32,
}

impl Default for CheckSettings {
    fn default() -> Self {
        Self {
            grid_error_points: 16_384,
            verify_points: 0,
            verify_paths: 4096,
        }
    }
}

impl CheckSettings {
    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        vec![
            (
                "checks.grid_error_points",
                Rule::count(self.grid_error_points, 0, 1_000_000, " points"),
            ),
            (
                "checks.verify_points",
                Rule::count(self.verify_points, 0, 100_000, " points"),
            ),
            (
                "checks.verify_paths",
                Rule::count(self.verify_paths, 2, 1_048_576, " paths per point"),
            ),
        ]
    }
}
