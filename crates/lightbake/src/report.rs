//! The bake report: settings, plan, per-stage wall time and ray counts, texel statistics and
//! warnings. The CLI prints it as a table, writes it as `report.json`, and the Bevy plugin
//! exposes it.

use serde::Serialize;

use crate::memory::MemoryEstimate;
use crate::plan::BakePlan;
use crate::settings::BakeSettings;

/// Counters of one stage.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StageStats {
    /// Stage name.
    pub name: String,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Rays traced.
    pub rays: u64,
    /// A short note (counts, sizes).
    pub note: String,
}

impl StageStats {
    /// Million rays per second (0 when no rays).
    pub fn mrays_per_second(&self) -> f64 {
        if self.rays == 0 || self.seconds <= 0.0 {
            0.0
        } else {
            self.rays as f64 / self.seconds / 1e6
        }
    }
}

/// Texel counts.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TexelStats {
    /// Atlas pages.
    pub pages: usize,
    /// Texels over all pages.
    pub page_texels: u64,
    /// Covered texels (patches).
    pub patches: usize,
    /// Patches moved out of geometry.
    pub moved: usize,
    /// Patches found inside geometry.
    pub invalid: usize,
    /// Invalid texels filled from their chart.
    pub filled: usize,
    /// Padding texels set by dilation.
    pub dilated: usize,
}

/// Everything a bake records about itself.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BakeReport {
    /// The baker's version.
    pub lightbake_version: &'static str,
    /// Scene name.
    pub scene: String,
    /// Settings used.
    pub settings: BakeSettings,
    /// The plan, with the reason for every skipped stage.
    pub plan: BakePlan,
    /// Stages in order.
    pub stages: Vec<StageStats>,
    /// Texel counts.
    pub texels: TexelStats,
    /// Instanced triangles.
    pub triangles: usize,
    /// Worker threads.
    pub threads: usize,
    /// The radiosity pass, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub indirect: Option<crate::indirect::IndirectReport>,
    /// The instant-radiosity pass, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vpl: Option<crate::vpl::VplReport>,
    /// The memory estimate the bake was admitted with.
    pub memory: MemoryEstimate,
    /// Repairs, compromises and clamps.
    pub warnings: Vec<String>,
    /// Wall time of the whole bake (writing excluded), seconds.
    pub total_seconds: f64,
    /// Files written, relative to the output directory (filled in by the writer).
    pub outputs: Vec<String>,
}

impl BakeReport {
    /// Total rays of every stage.
    pub fn total_rays(&self) -> u64 {
        self.stages.iter().map(|s| s.rays).sum()
    }

    /// A fixed-width table: stage, time, rays, Mrays/s, note.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:<14} {:>9} {:>12} {:>8}  {}\n",
            "stage", "time", "rays", "Mrays/s", "note"
        );
        for st in &self.stages {
            s.push_str(&format!(
                "{:<14} {:>8.3}s {:>12} {:>8}  {}\n",
                st.name,
                st.seconds,
                if st.rays > 0 {
                    st.rays.to_string()
                } else {
                    "-".into()
                },
                if st.rays > 0 {
                    format!("{:.2}", st.mrays_per_second())
                } else {
                    "-".into()
                },
                st.note
            ));
        }
        let rays = self.total_rays();
        s.push_str(&format!(
            "{:<14} {:>8.3}s {:>12} {:>8}  {} threads\n",
            "total",
            self.total_seconds,
            rays,
            if self.total_seconds > 0.0 {
                format!("{:.2}", rays as f64 / self.total_seconds / 1e6)
            } else {
                "-".into()
            },
            self.threads
        ));
        s
    }
}
