//! The settings of the irradiance volume for dynamic objects ([`VolumeSettings`],
//! `BakeSettings::volume`; the stage is [`crate::probes`]).
//!
//! | field | unit | range | preview | medium | high |
//! |---|---|---|---|---|---|
//! | `enabled` | – | bool | false | false | false |
//! | `probe_spacing` | m | > 0 or none (16 texels at the bake's density, or the rooms' headroom over `probes_per_headroom`) | none | none | none |
//! | `probes_per_headroom` | probes | 1..=64 | 4 | 6 | 8 |
//! | `probe_rays` | rays per probe | 1..=65 536 | 256 | 512 | 1024 |
//! | `regions` | volumes | 1..=64 | 8 | 8 | 8 |
//! | `oriented` | – | bool | true | true | true |

use serde::{Deserialize, Serialize};

use super::{Quality, Rule};

/// Whether and how densely the irradiance volume is baked.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VolumeSettings {
    /// Also bake an irradiance volume: a grid of probes over the baked instances, each the
    /// light from the six axis directions read from the lightmaps (without the direct light
    /// of the lights, which the engine draws on dynamic objects itself), written as
    /// `irradiance_volumes/volume_0.ktx2` in the layout Bevy's `IrradianceVolume` reads.
    /// Default false.
    pub enabled: bool,
    /// Distance between the volume's probes, m (per scene unit). Default none: 16 lightmap
    /// texels at the bake's density, or the level's median headroom over its roofed floors
    /// divided by [`Self::probes_per_headroom`] where that is finer
    /// (`crate::probes::headroom`: the rooms a moving object walks in are resolved whatever
    /// the lightmaps' density), widened so each volume has at most 65 536 probes (the plan
    /// says which and why). An explicit spacing giving over 2²⁰ probes is refused.
    pub probe_spacing: Option<f32>,
    /// With no `probe_spacing`: the least probes from a floor up to the surface over it (the
    /// level's median headroom). Range 1..=64. Default 4 (preview), 6 (medium), 8 (high):
    /// over two office rooms, 5 cm, 0.3 m and 1 m over the floor, the volumes are within 10%
    /// of the path tracer at 6 and 8 and within 15% at 4 (`tests/volume_regions.rs`).
    pub probes_per_headroom: u32,
    /// Rays per probe (plus a quarter as many samples of emissive surfaces). Range
    /// 1..=65 536. Default 256 (preview), 512 (medium), 1024 (high).
    pub probe_rays: u32,
    /// Most volumes: the level is cut at its walls into rooms, one volume each, neighbours
    /// overlapping by a spacing and blended by Bevy's light-probe falloff
    /// (`crate::probes::regions`). 1: one volume over every baked instance. Range 1..=64.
    /// Default 8, the most irradiance volumes Bevy 0.20 draws in one view
    /// (`MAX_VIEW_LIGHT_PROBES`; beyond that it keeps the nearest).
    pub regions: u32,
    /// Turn the volumes about the vertical with the level's walls when they are off the
    /// world axes (a level under a rotated node). Default true.
    pub oriented: bool,
}

impl Default for VolumeSettings {
    fn default() -> Self {
        Self::preset(Quality::Medium)
    }
}

impl VolumeSettings {
    /// The volume of a quality preset (off in all of them).
    pub fn preset(quality: Quality) -> Self {
        Self {
            enabled: false,
            probe_spacing: None,
            probes_per_headroom: match quality {
                Quality::Preview => 4,
                Quality::Medium => 6,
                Quality::High => 8,
            },
            regions: 8,
            oriented: true,
            probe_rays: match quality {
                Quality::Preview => 256,
                Quality::Medium => 512,
                Quality::High => 1024,
            },
        }
    }

    /// The group's rows of the validation table.
    pub(super) fn rules(&self) -> Vec<(&'static str, Rule)> {
        vec![
            (
                "volume.probe_spacing",
                Rule::Positive(
                    self.probe_spacing.map(f64::from),
                    "a positive distance in metres",
                ),
            ),
            (
                "volume.probes_per_headroom",
                Rule::count(self.probes_per_headroom, 1, 64, " probes"),
            ),
            (
                "volume.probe_rays",
                Rule::count(self.probe_rays, 1, 65_536, ""),
            ),
            ("volume.regions", Rule::count(self.regions, 1, 64, "")),
        ]
    }
}
