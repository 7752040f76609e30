//! The settings of the direct pass: shadow rays to the lights, the emitters and the sky
//! ([`DirectSettings`], `BakeSettings::direct`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `samples_per_texel` | samples | 1..=4096 | 8 | 32 | 64 |
//! | `sky_samples` | rays per texel | 1..=65 536 | 16 | 64 | 128 |
//! | `max_closed_form_emitters` | emissive triangles | any | 256 | 256 | 256 |
//!
//! The sample counts come from the convergence study (`docs/convergence.md`): direct light
//! costs little per sample, and at 16 samples it was the larger half of the Cornell box's
//! error at 128 form-factor rays.

use serde::{Deserialize, Serialize};

use super::{Quality, Rule};

/// How densely the direct pass samples each texel.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DirectSettings {
    /// Samples per texel for direct light: each is a point in the texel's footprint and one
    /// sample of every light, so shadow edges are antialiased. Range 1..=4096.
    /// Default 32 (medium), 8 (preview), 64 (high).
    pub samples_per_texel: u32,
    /// Cosine-distributed rays per texel towards the uniform sky (only when the sky is not
    /// black). Range 1..=65 536. Default 64 (medium), 16 (preview), 128 (high).
    pub sky_samples: u32,
    /// Emitters (emissive triangles) up to which each texel evaluates the closed-form,
    /// unoccluded point-to-polygon irradiance and uses the shadow rays only for the visible
    /// fraction (a ratio estimator, exact where the emitter is fully visible). Above it the
    /// emitters are sampled by power. Default 256.
    pub max_closed_form_emitters: u32,
}

impl Default for DirectSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl DirectSettings {
    /// The direct pass of a quality preset.
    pub fn preset(quality: Quality) -> Self {
        let (samples_per_texel, sky_samples) = match quality {
            Quality::Preview => (8, 16),
            Quality::Medium => (32, 64),
            Quality::High => (64, 128),
        };
        Self {
            samples_per_texel,
            sky_samples,
            max_closed_form_emitters: 256,
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        vec![
            (
                "direct.samples_per_texel",
                Rule::count(self.samples_per_texel, 1, 4096, ""),
            ),
            (
                "direct.sky_samples",
                Rule::count(self.sky_samples, 1, 65_536, ""),
            ),
        ]
    }
}
