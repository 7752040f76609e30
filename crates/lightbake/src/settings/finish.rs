//! The settings of the finishing passes over the lightmap pages: the contact fit, the
//! denoiser and the seam stitch ([`FinishSettings`], `BakeSettings::finish`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `contact_fit` | – | bool | true | true | true |
//! | `denoise` | – | bool | false | true | true |
//! | `denoise_radius` | texels | 1..=8 | 3 | 3 | 3 |
//! | `stitch_seams` | – | bool | true | true | true |

use serde::{Deserialize, Serialize};

use super::{Quality, Rule};

/// Which finishing passes run over the lightmap pages.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FinishSettings {
    /// Fit the texels next to geometry so that the lightmap's bilinear reconstruction is right
    /// on the visible surface (a floor texel whose centre is under a thin wall, a texel
    /// under a rug, padding beside a contact). Default true.
    pub contact_fit: bool,
    /// Filter each chart's texels with an edge-aware denoiser, as strongly as each texel's
    /// estimated noise warrants, and carry the error estimate through it. Default off
    /// (preview), on (medium, high).
    pub denoise: bool,
    /// The denoiser's radius, texels. Range 1..=8. Default 3.
    pub denoise_radius: u32,
    /// Make the two sides of every seam (a surface split between charts) agree after
    /// bilinear filtering, by a least-squares stitch of the texels along it. Default true.
    pub stitch_seams: bool,
}

impl Default for FinishSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl FinishSettings {
    /// The finishing passes of a quality preset.
    pub fn preset(quality: Quality) -> Self {
        Self {
            contact_fit: true,
            denoise: quality != Quality::Preview,
            denoise_radius: 3,
            stitch_seams: true,
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        vec![(
            "finish.denoise_radius",
            Rule::count(self.denoise_radius, 1, 8, " texels"),
        )]
    }
}
