//! Where the texels go: the settings the unwrap, the texel density and the atlas read
//! ([`LayoutSettings`], `BakeSettings::layout`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `texel_density` | texels per metre | (0, 10⁹] or none | none | none | none |
//! | `texel_density_from_scene` | – | bool | true | true | true |
//! | `texel_budget` | covered texels | 1 000..=10⁸ | 65 536 | 262 144 | 1 048 576 |
//! | `adaptive_density` | – | bool | true | true | true |
//! | `padding` | texels | 1..=16 | 2 | 2 | 2 |
//! | `max_page_size` | texels per side | 64..=16 384 | 2048 | 2048 | 2048 |
//! | `reunwrap` | – | bool | false | false | false |

use serde::{Deserialize, Serialize};

use super::{Quality, Rule};

/// How densely the surfaces get texels and how the atlas is packed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct LayoutSettings {
    /// Lightmap texels per metre of world-space surface (per axis; per scene unit for a scene
    /// not in metres). Range (0, 10⁹]; the memory plan refuses what does not fit. Default
    /// none: the density is chosen so the baked surfaces get about [`Self::texel_budget`]
    /// texels, whatever the scene's unit. When set, it wins over the scene's own hint
    /// (`scene.extras.lightbake.texel_density`) and over the budget; a node's
    /// `texel_density_scale` multiplies it either way.
    pub texel_density: Option<f32>,
    /// Take the scene's `texel_density` hint when it has one and `texel_density` is not set.
    /// Default true.
    pub texel_density_from_scene: bool,
    /// Covered lightmap texels to aim for when the density is chosen automatically (no
    /// `texel_density` and no scene hint): density = √(budget / Σ baked area × scale²).
    /// Range 1 000..=100 000 000. Default 65 536 (preview), 262 144 (medium), 1 048 576 (high).
    pub texel_budget: u64,
    /// When the density comes from [`Self::texel_budget`], share the budget out by a pilot of
    /// the direct light: charts whose light varies most within a texel get up to twice the
    /// density, flat ones down to half, the total kept (the plan and the report's `density`
    /// say each chart's scale). Default true.
    pub adaptive_density: bool,
    /// Empty texels kept between charts and between atlas rectangles, filled by dilation so
    /// bilinear and bicubic sampling never read unset texels. Range 1..=16. Default 2.
    pub padding: u32,
    /// Largest atlas page, in texels per side. More pages are made when one is not enough.
    /// Range 64..=16384. Default 2048.
    pub max_page_size: u32,
    /// Unwrap every mesh again with xatlas, even those that carry their own `TEXCOORD_1`.
    /// Default false.
    pub reunwrap: bool,
}

impl Default for LayoutSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl LayoutSettings {
    /// The layout of a quality preset.
    pub fn preset(quality: Quality) -> Self {
        Self {
            texel_density: None,
            texel_density_from_scene: true,
            texel_budget: match quality {
                Quality::Preview => 1 << 16,
                Quality::Medium => 1 << 18,
                Quality::High => 1 << 20,
            },
            adaptive_density: true,
            padding: 2,
            max_page_size: 2048,
            reunwrap: false,
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        vec![
            (
                "layout.texel_density",
                Rule::Holds {
                    ok: self
                        .texel_density
                        .is_none_or(|d| d.is_finite() && d > 0.0 && d <= 1e9),
                    value: format!("{:?}", self.texel_density),
                    message: "must be in (0, 10⁹] texels per metre (per scene unit)",
                },
            ),
            (
                "layout.texel_budget",
                Rule::count(self.texel_budget, 1_000, 100_000_000, " texels"),
            ),
            (
                "layout.padding",
                Rule::count(self.padding, 1, 16, " texels"),
            ),
            (
                "layout.max_page_size",
                Rule::count(self.max_page_size, 64, 16384, " texels"),
            ),
        ]
    }
}
