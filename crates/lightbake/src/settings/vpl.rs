//! The settings of instant radiosity (Keller 1997): the particles traced from the lights
//! and how their virtual point lights are gathered ([`VplSettings`], `BakeSettings::vpl`).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `particles` | particles | 1..=10⁷ | 16 384 | 65 536 | 262 144 |
//! | `cut_size` | nodes (shadow rays per texel) | 0 (every VPL) or 1..=65 536 | 64 | 256 | 1024 |
//! | `time_budget_s` | s | > 0 or none | none | none | none |
//! | `sequence` | – | [`Sequence`] | scrambled Halton | scrambled Halton | scrambled Halton |
//! | `clamp_distance` | m | > 0 or none (2% of the diagonal) | none | none | none |
//! | `bias_compensation` | – | bool | false | false | false |
//! | `compensation_rays` | rays per texel | any | 64 | 64 | 64 |
//! | `max_depth` | reflections | 0..=29 | 16 | 16 | 16 |

use serde::{Deserialize, Serialize};

use super::{MAX_VPL_DEPTH, Quality, Rule, Sequence};

/// The largest cut ([`VplSettings::cut_size`]).
pub const MAX_CUT: u32 = 65_536;

/// How instant radiosity traces and gathers its virtual point lights.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VplSettings {
    /// Particles started from the lights (N); about N/(1 − ρ̄) VPLs result.
    /// Range 1..=10⁷. Default 65 536 (medium), 16 384 (preview), 262 144 (high).
    pub particles: u32,
    /// Nodes of the VPL tree each texel gathers one VPL from (lightcuts: `vpl::cut`), so a
    /// texel traces this many shadow rays however many VPLs there are; 0 gathers every VPL at
    /// every texel (Keller's own gather, for the convergence study). Range 0..=65 536.
    /// Default 256 (medium), 64 (preview), 1024 (high).
    pub cut_size: u32,
    /// Fit the gather into this many seconds (measured against a pilot): through cuts it sets
    /// the cut and leaves N as set; with `cut_size` 0 it chooses N. Default none.
    pub time_budget_s: Option<f64>,
    /// The number pattern of the walks. Default [`Sequence::ScrambledHalton`] (plain Halton
    /// converges as fast but its higher bases are correlated at small N).
    pub sequence: Sequence,
    /// VPLs closer than this (m) are clamped (G ≤ 1/d²). Default 2% of the scene's diagonal.
    pub clamp_distance: Option<f32>,
    /// Restore the clamped energy (Kollig & Keller 2004). Default off.
    pub bias_compensation: bool,
    /// Rays per texel of the bias compensation. Default 64.
    pub compensation_rays: u32,
    /// Deepest reflection followed (≤ [`MAX_VPL_DEPTH`]). Default 16.
    pub max_depth: u32,
}

impl Default for VplSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl VplSettings {
    /// Instant radiosity at a quality preset.
    pub fn preset(quality: Quality) -> Self {
        Self {
            particles: match quality {
                Quality::Preview => 16_384,
                Quality::Medium => 65_536,
                Quality::High => 262_144,
            },
            cut_size: match quality {
                Quality::Preview => 64,
                Quality::Medium => 256,
                Quality::High => 1024,
            },
            time_budget_s: None,
            sequence: Sequence::ScrambledHalton,
            clamp_distance: None,
            bias_compensation: false,
            compensation_rays: 64,
            max_depth: 16,
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        let distance = "a positive distance in metres";
        vec![
            (
                "vpl.particles",
                Rule::count(self.particles, 1, 10_000_000, ""),
            ),
            (
                "vpl.cut_size",
                Rule::count(self.cut_size, 0, MAX_CUT as u64, ""),
            ),
            (
                "vpl.time_budget_s",
                Rule::Positive(self.time_budget_s, "a positive number of seconds"),
            ),
            (
                "vpl.clamp_distance",
                Rule::Positive(self.clamp_distance.map(f64::from), distance),
            ),
            (
                "vpl.max_depth",
                Rule::count(self.max_depth, 0, MAX_VPL_DEPTH as u64, ""),
            ),
        ]
    }
}
