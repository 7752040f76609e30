//! The bake report: settings, plan, per-stage wall time and ray counts, texel statistics and
//! warnings. The CLI prints it as a table, writes it as `report.json`, and the Bevy plugin
//! exposes it. Every type the report holds is re-exported here.

use crate::stage::{Stage, StageRun};
use serde::Serialize;

pub use crate::bvh::workload::RayRates;
pub use crate::error_estimate::ErrorEstimate;
pub use crate::lightmap::contacts::ContactStats;
pub use crate::lightmap::denoise::DenoiseStats;
pub use crate::lightmap::seams::SeamJumps;
pub use crate::lightmap::stitch::{OpenSeam, OpenWhy, StitchStats};
pub use crate::memory::MemoryEstimate;
pub use crate::plan::{BakePlan, DirectSource, LightReach, PlannedSource, PlannedStage};
pub use crate::progress::{RayKind, StageStats};
pub use crate::radiosity::hierarchical::CoarseReport;
pub use crate::radiosity::{RadiosityReport, SolverPlan};
use crate::settings::BakeSettings;
pub use crate::solve::{HistoryEntry, Solution};
pub use crate::vpl::VplReport;

/// One part of the bake's error estimate ([`BakeReport::error_budget`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ErrorShare {
    /// What the part is.
    pub part: String,
    /// Its RMS error, lux.
    pub rms: f64,
    /// Its share of the estimate's mean square (0–1; the shares add up to 1).
    pub share: f64,
}

/// Where the estimate `total` of a bake with stages `stages` comes from: the direct light's
/// texel grid (the `grid error` stage) and the rest (the sampling stages' noise, after the
/// denoiser when it ran, and the coarse level's bias), the rest shared out over the sampling
/// stages that estimated their error in proportion to their mean squares before the
/// denoiser (the denoiser filters each by its own noise; the proportion is its input's).
/// Empty without an estimate. The parts add in quadrature, as the estimate does
/// ([`ErrorEstimate::combine`]). A stage run in rounds counts with its last round.
pub fn error_budget(stages: &[StageStats], total: Option<&ErrorEstimate>) -> Vec<ErrorShare> {
    let Some(total) = total.filter(|t| t.rms > 0.0) else {
        return Vec::new();
    };
    let total_sq = total.rms * total.rms;
    let error_of = |s: &StageStats| s.error.as_ref().map_or(0.0, |e| e.rms * e.rms);
    let grid_sq: f64 = (stages.iter())
        .filter(|s| s.run.stage == Stage::GridError)
        .map(error_of)
        .sum::<f64>()
        .min(total_sq);
    // A stage run in rounds (a target error) counts once: its last round's estimate.
    let mut sampling: Vec<(String, f64)> = Vec::new();
    for (k, st) in stages.iter().enumerate() {
        let last = !stages[k + 1..].iter().any(|o| o.run.stage == st.run.stage);
        if last && st.run.stage != Stage::GridError && error_of(st) > 0.0 {
            let part = match st.run.stage {
                Stage::Direct => "the direct light's noise".to_string(),
                Stage::ErrorEstimate => "the indirect light's noise and bias".to_string(),
                other => format!("the {other} stage's noise"),
            };
            sampling.push((part, error_of(st)));
        }
    }
    let denoised = stages.iter().any(|s| s.run.stage == Stage::Denoise);
    let rest_sq = total_sq - grid_sq;
    let sampling_sq: f64 = sampling.iter().map(|s| s.1).sum();
    let mut parts = Vec::new();
    if sampling_sq > 0.0 {
        for (name, sq) in sampling {
            let part_sq = rest_sq * sq / sampling_sq;
            parts.push(ErrorShare {
                part: if denoised {
                    format!("{name} after the denoiser")
                } else {
                    name
                },
                rms: part_sq.sqrt(),
                share: part_sq / total_sq,
            });
        }
    } else if rest_sq > 0.0 {
        parts.push(ErrorShare {
            part: "sampling noise and the coarse level's bias".into(),
            rms: rest_sq.sqrt(),
            share: rest_sq / total_sq,
        });
    }
    if grid_sq > 0.0 {
        parts.push(ErrorShare {
            part: "the direct light's texel grid".into(),
            rms: grid_sq.sqrt(),
            share: grid_sq / total_sq,
        });
    }
    parts
}

/// The ray-tracing floor: the shortest time the bake's rays can take at the rates the BVH
/// measured on this scene and these threads, and how far the bake is above it.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Floor {
    /// Measured rates (all worker threads).
    pub rates: RayRates,
    /// Closest-hit rays the bake traced.
    pub closest_rays: u64,
    /// Shadow rays the bake traced.
    pub shadow_rays: u64,
    /// closest_rays / closest rate + shadow_rays / shadow rate, seconds.
    pub seconds: f64,
    /// Total bake time / floor (1 = nothing but rays at the measured rate).
    pub ratio: f64,
    /// Per stage that traced rays: (name, its time / the floor of its own rays).
    pub stages: Vec<(StageRun, f64)>,
}

impl Floor {
    /// The floor of `stages` at `rates`, against a bake that took `total_seconds`.
    pub fn new(stages: &[StageStats], rates: RayRates, total_seconds: f64) -> Self {
        let per = |n: u64, rate: f64| if rate > 0.0 { n as f64 / rate } else { 0.0 };
        let floor_of = |(closest, shadow): (u64, u64)| {
            per(closest, rates.closest_per_second) + per(shadow, rates.shadow_per_second)
        };
        let (closest_rays, shadow_rays) = stages
            .iter()
            .map(StageStats::rays_by_kind)
            .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        let seconds = floor_of((closest_rays, shadow_rays));
        let ratio = |time: f64, floor: f64| if floor > 0.0 { time / floor } else { 0.0 };
        Self {
            rates,
            closest_rays,
            shadow_rays,
            seconds,
            ratio: ratio(total_seconds, seconds),
            stages: stages
                .iter()
                .filter(|s| s.ray_kind != RayKind::None)
                .map(|s| (s.run, ratio(s.seconds, floor_of(s.rays_by_kind()))))
                .collect(),
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
    /// Of the moved patches, those whose centre is hidden (inside or behind geometry) but
    /// whose footprint is partly open: lit from the visible part.
    pub partly_hidden: usize,
    /// Hidden patches: no point of their footprint is open surface, so no view can see them
    /// (filled from their chart for the GPU's bilinear filter, or left black).
    pub invalid: usize,
    /// Hidden patches in which a second search found open surface after all: visible, but
    /// not lit by the bake (see `raster::validity`). Zero when the first search is dense
    /// enough.
    pub visible_unlit: usize,
    /// Hidden texels filled from their chart.
    pub filled: usize,
    /// Hidden texels left black: their chart has no lit texel next to them.
    pub unfilled: usize,
    /// Padding texels set by dilation.
    pub dilated: usize,
}

/// One point of a [`Verification`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VerifiedPoint {
    /// The instance (scene node) it lies on.
    pub instance: String,
    /// World position, m.
    pub position: [f32; 3],
    /// The surface's unit normal there (world): which face of the instance it is.
    pub normal: [f32; 3],
    /// Luminance of the lightmap's E/π there, as the GPU reads it (bilinear), nits.
    pub baked: f32,
    /// Luminance of the path tracer's E/π there, nits.
    pub reference: f32,
}

/// A bake checked against the in-tree path tracer (`lightbake::analysis::reference`) at
/// points spread over the baked surfaces a viewer can see (`lightbake::analysis::verify`).
/// Errors are of the luminance of E/π, relative to the RMS reference value.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Verification {
    /// Points compared.
    pub points: usize,
    /// Paths the path tracer traced per point.
    pub paths: u32,
    /// Relative RMS error, the reference's own noise taken out.
    pub relative_rms: f64,
    /// Relative mean error (bake − reference): negative when the bake is too dark.
    pub relative_bias: f64,
    /// The reference's own noise, relative RMS per point (taken out of `relative_rms`).
    pub reference_noise: f64,
    /// One standard deviation of `relative_rms` from the choice of points and the
    /// reference's noise: m² = Σ(d² − var r) / Σ r² (d = b − r) is a ratio estimator, with
    /// var m² ≈ Σ(d² − var r − m² r²)² / (Σ r²)² (the delta method, over the points) plus
    /// the reference's part below; half the width of √(m² ± √var m²).
    pub uncertainty: f64,
    /// The part of that from the reference's noise alone (what more paths would shrink, and
    /// what two checks at the same points differ by): var Σd² ≈ Σ(4d²·var r + 2 var² r).
    pub reference_uncertainty: f64,
    /// The worst point's share of the squared error Σ(b − r)². Errors on real levels are
    /// heavy-tailed (a few points at a leak or a shadow edge carry most of it): when one
    /// point carries much, a check at more points measures the error more surely than
    /// `uncertainty` says.
    pub worst_share: f64,
    /// Share of the points more than 10% off the reference (points where both are black,
    /// below 1% of the RMS reference, left out).
    pub beyond_10: f64,
    /// Share of the points more than 25% off the reference.
    pub beyond_25: f64,
    /// Points the path tracer finds lit (at least 5% of the RMS reference) where the
    /// lightmap holds less than a tenth of it: the independent count of visible texels left
    /// black.
    pub lit_but_black: usize,
    /// The bake's own estimate, relative RMS (none when it made none).
    pub estimated: Option<f64>,
    /// Estimate / measured (none without an estimate or a measurable error).
    pub estimate_ratio: Option<f64>,
    /// Whether the estimate includes the texel grid's error of the direct light (the bake's
    /// `grid error` stage ran: `crate::lightmap::grid_error`).
    pub estimate_covers_grid: bool,
    /// Wall time of the check, s.
    pub seconds: f64,
    /// The points with the largest error, worst first (at most 10).
    pub worst: Vec<VerifiedPoint>,
}

impl Verification {
    /// Lines for the CLI: the error, its spread, the estimate against it, the worst points.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "verify: {} points at {} paths each in {:.1} s: error {:.2}% ± {:.2}% RMS (± {:.2}% from the reference's noise of {:.2}%), bias {:+.2}%, {:.1}% of points beyond ±10%, {:.1}% beyond ±25%, {} lit but black\n",
            self.points,
            self.paths,
            self.seconds,
            100.0 * self.relative_rms,
            100.0 * self.uncertainty,
            100.0 * self.reference_uncertainty,
            100.0 * self.reference_noise,
            100.0 * self.relative_bias,
            100.0 * self.beyond_10,
            100.0 * self.beyond_25,
            self.lit_but_black
        );
        if self.worst_share > 0.1 {
            s.push_str(&format!(
                "verify: the worst point carries {:.0}% of the squared error: the error is heavy-tailed, and a check at more points measures it more surely\n",
                100.0 * self.worst_share
            ));
        }
        match (self.estimated, self.estimate_ratio) {
            (Some(e), Some(r)) => {
                let judged = if (0.7..=1.5).contains(&r) {
                    "within 0.7–1.5× of the measured error"
                } else if r < 0.7 && self.estimate_covers_grid {
                    "below the measured error: the estimate covers sampling noise, the coarse level's bias and the direct light's texel grid, not the indirect light's grid error or what the contact fit and the stitch change, and its own points see a heavy-tailed error less surely than more points would"
                } else if r < 0.7 {
                    "below the measured error: the estimate covers sampling noise and the coarse level's bias, not the texel grid's own error (light leaking at contacts, shadow edges finer than a texel, black texels)"
                } else {
                    "above the measured error: it is cautious"
                };
                s.push_str(&format!(
                    "verify: the bake's estimate {:.2}% is {r:.2}× the measured error, {judged}\n",
                    100.0 * e
                ));
            }
            (Some(e), None) => s.push_str(&format!(
                "verify: the bake's estimate {:.2}%; the measured error is within the reference's noise\n",
                100.0 * e
            )),
            _ => {}
        }
        for p in self.worst.iter().take(3) {
            s.push_str(&format!(
                "verify: worst: {} at ({:.3}, {:.3}, {:.3}) m facing ({:.2}, {:.2}, {:.2}): baked {:.4}, path tracer {:.4}\n",
                p.instance,
                p.position[0],
                p.position[1],
                p.position[2],
                p.normal[0],
                p.normal[1],
                p.normal[2],
                p.baked,
                p.reference
            ));
        }
        s
    }
}

/// A decision the bake took once it knew what the plan could not.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Decision {
    /// The planned stage it concerns.
    pub stage: Stage,
    /// Whether the stage ran.
    pub ran: bool,
    /// What was decided, or why the stage did not run after all.
    pub what: String,
}

impl Decision {
    /// `stage` ran, and `what` the bake decided for it.
    pub fn ran(stage: Stage, what: String) -> Self {
        Self {
            stage,
            ran: true,
            what,
        }
    }

    /// `stage`, planned, did not run after all, for `why`.
    pub fn skipped(stage: Stage, why: String) -> Self {
        Self {
            stage,
            ran: false,
            what: why,
        }
    }
}

/// One light group of a bake ([`crate::settings::groups`]): what it holds and what its
/// lighting cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GroupReport {
    /// The group's name.
    pub name: String,
    /// Its members: `light NAME`, `material NAME`, `sky`.
    pub members: Vec<String>,
    /// Wall time of its own lighting and finishing stages, seconds. Not counted: the stages
    /// before them, from the plan to the texel patches, and those its radiosity shares with
    /// the other groups (its nodes, coarse level and gathers, marked `[shared]` in the stage
    /// table).
    pub seconds: f64,
    /// Rays its own stages traced (the shared ones not counted).
    pub rays: u64,
    /// Its stages' error estimate, relative to its own RMS texel (none when nothing was
    /// sampled).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorEstimate>,
}

impl GroupReport {
    /// One line: name, members, time, rays and error.
    pub fn summary(&self) -> String {
        format!(
            "light group {}: {} — {:.3} s, {} rays{}",
            self.name,
            self.members.join(", "),
            self.seconds,
            self.rays,
            self.error.as_ref().map_or(String::new(), |e| format!(
                ", estimated error {:.2}% RMS",
                100.0 * e.relative_rms
            ))
        )
    }
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
    /// The plan, as decided before any work, with the reason for every skipped stage.
    pub plan: BakePlan,
    /// What the bake decided once it knew what the plan could not (the density, the solver,
    /// the volume's grid; a planned stage it found it could not run, and why).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub decisions: Vec<Decision>,
    /// How the texel density follows the light (each chart's scale and error), when it does.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub density: Option<crate::density::DensityReport>,
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
    pub radiosity: Option<RadiosityReport>,
    /// The instant-radiosity pass, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vpl: Option<VplReport>,
    /// The contact fit, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact_fit: Option<ContactStats>,
    /// The denoiser, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoise: Option<DenoiseStats>,
    /// The seams and their stitch (the jumps across them before and after), when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seams: Option<StitchStats>,
    /// For the merge of a split bake: its split stages with every shard's part (items,
    /// seconds, rays).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub split: Vec<SplitStage>,
    /// The irradiance volumes, one per region of the level; empty when none was baked.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub irradiance_volumes: Vec<crate::probes::VolumeStats>,
    /// The light groups, when the bake has any: each one's members, time, rays and error.
    /// The other fields describe the whole bake (its stages list each group's, their notes
    /// prefixed with the group's name); the radiosity, instant-radiosity and finishing
    /// reports are the first group's.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub groups: Vec<GroupReport>,
    /// The memory estimate the bake was admitted with.
    pub memory: MemoryEstimate,
    /// The bake's estimate of its own error: the stages' estimates added in quadrature,
    /// relative to the final lightmap (none when nothing was sampled).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorEstimate>,
    /// Where the estimate's error comes from, by stage ([`error_budget`]); empty without an
    /// estimate.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub error_budget: Vec<ErrorShare>,
    /// The ray-tracing floor (none when no rays were traced).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub floor: Option<Floor>,
    /// The bake checked against the path tracer at surface points
    /// ([`CheckSettings::verify_points`](crate::settings::CheckSettings::verify_points);
    /// filled in by `lightbake::analysis::verify`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub verification: Option<Verification>,
    /// Repairs, compromises and clamps.
    pub warnings: Vec<String>,
    /// The baked glTF's primitives given a `TEXCOORD_0` naming their `TEXCOORD_1`'s
    /// accessor, as `mesh 'NAME' primitive P` (filled in by the writer): Bevy's
    /// `StandardMaterial` shader does not compile for a mesh with `UV_1` and no `UV_0`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub texcoord_0_added: Vec<String>,
    /// How the bake followed the cached bake in its output folder, when it was run to
    /// ([`crate::BakeBuilder::following`]): full (and why) or the edits it followed, how
    /// the layout was kept, and each split stage's items computed again.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub incremental: Option<crate::incremental::IncrementalReport>,
    /// Wall time of the whole bake (writing excluded), seconds.
    pub total_seconds: f64,
    /// The process's peak resident memory when the bake ended, MiB (`VmHWM`; none where the
    /// system does not say).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_resident_mib: Option<f64>,
    /// Files written, relative to the output directory (filled in by the writer).
    pub outputs: Vec<String>,
}

impl TexelStats {
    /// One line: patches, the moved and partly hidden ones, the hidden ones and what became
    /// of them, the visible but unlit ones.
    pub fn summary(&self) -> String {
        format!(
            "{} page(s), {} texel patches ({} moved out of geometry, {} of them lit from the visible part of their footprint; hidden: {} ({} filled from their chart, {} left black); visible but unlit: {})",
            self.pages,
            self.patches,
            self.moved,
            self.partly_hidden,
            self.invalid,
            self.filled,
            self.unfilled,
            self.visible_unlit
        )
    }
}

impl BakeReport {
    /// Whether the error estimate includes the texel grid's error of the direct light (the
    /// `grid error` stage ran and checked points).
    pub fn grid_checked(&self) -> bool {
        self.stages
            .iter()
            .any(|s| s.run.stage == Stage::GridError && s.error.is_some())
    }

    /// Total rays of every stage.
    pub fn total_rays(&self) -> u64 {
        self.stages.iter().map(|s| s.rays).sum()
    }

    /// A fixed-width table: stage, time, rays, Mrays/s, note.
    pub fn table(&self) -> String {
        let pct = |e: &Option<ErrorEstimate>| {
            e.as_ref().map_or("-".to_string(), |e| {
                format!("{:.2}%", 100.0 * e.relative_rms)
            })
        };
        let mut s = format!(
            "{:<14} {:>9} {:>12} {:>8} {:>8}  {}\n",
            "stage", "time", "rays", "Mrays/s", "error", "note"
        );
        for st in &self.stages {
            s.push_str(&format!(
                "{:<14} {:>8.3}s {:>12} {:>8} {:>8}  {}\n",
                st.run.to_string(),
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
                pct(&st.error),
                st.note
            ));
        }
        let rays = self.total_rays();
        s.push_str(&format!(
            "{:<14} {:>8.3}s {:>12} {:>8} {:>8}  {} threads{}\n",
            "total",
            self.total_seconds,
            rays,
            if self.total_seconds > 0.0 {
                format!("{:.2}", rays as f64 / self.total_seconds / 1e6)
            } else {
                "-".into()
            },
            pct(&self.error),
            self.threads,
            self.peak_resident_mib
                .map(|m| format!(", peak memory {m:.0} MiB"))
                .unwrap_or_default()
        ));
        for g in &self.groups {
            s.push_str(&g.summary());
            s.push('\n');
        }
        for d in &self.decisions {
            s.push_str(&format!(
                "decided: {} {}: {}\n",
                d.stage,
                if d.ran { "ran" } else { "skipped" },
                d.what
            ));
        }
        if let Some(e) = &self.error {
            s.push_str(&format!(
                "estimated error: {:.2}% RMS, {:.2}% at the 95th percentile (relative to the RMS texel)\n",
                100.0 * e.relative_rms,
                100.0 * e.p95
            ));
            if !self.error_budget.is_empty() {
                let parts: Vec<String> = (self.error_budget.iter())
                    .map(|p| format!("{} {:.0}%", p.part, 100.0 * p.share))
                    .collect();
                s.push_str(&format!(
                    "  shares of its mean square: {}\n",
                    parts.join(", ")
                ));
            }
            if self.verification.is_none() {
                s.push_str(if self.grid_checked() {
                    "  (the estimate covers sampling noise, the coarse level's bias and the direct light's texel grid (shadow edges and light finer than a texel), not the indirect light's grid error at contacts; `--verify N` measures the whole error against the path tracer)\n"
                } else {
                    "  (the estimate covers sampling noise and the coarse level's bias, not the texel grid's own error — shadow edges and geometry finer than a texel, light at contacts; `--verify N` measures the whole error against the path tracer)\n"
                });
            }
        }
        if let Some(st) = &self.seams {
            s.push_str(&format!(
                "seams: {} edge(s) stitched, jump across them {:.2}% mean, {:.2}% max before the stitch; {:.2}% mean, {:.2}% max after\n",
                st.before.seams,
                100.0 * st.before.mean,
                100.0 * st.before.max,
                100.0 * st.after.mean,
                100.0 * st.after.max
            ));
            if st.closed > 0 {
                s.push_str(&format!(
                    "  {} seam sample(s) where geometry stands on the seam (two rooms) left apart: {:.2}% mean, {:.2}% max\n",
                    st.closed,
                    100.0 * st.apart.mean,
                    100.0 * st.apart.max
                ));
            }
            if st.open_count > 0 {
                s.push_str(&format!(
                    "  {} seam(s) above {:.0}% after the stitch; the worst:\n",
                    st.open_count,
                    100.0 * crate::lightmap::stitch::OPEN_JUMP
                ));
                for o in st.open.iter().take(8) {
                    s.push_str(&format!(
                        "    {:.0}% at ({:.2}, {:.2}, {:.2}) m, instances {} and {}: {}\n",
                        100.0 * o.jump,
                        o.at[0],
                        o.at[1],
                        o.at[2],
                        o.instances[0],
                        o.instances[1],
                        o.why.words()
                    ));
                }
            }
        }
        for (k, v) in self.irradiance_volumes.iter().enumerate() {
            s.push_str(&format!(
                "irradiance volume {k}: {} × {} × {} probes {:.3e} m apart ({}), {} rays each, {:.2}% noise; {} moved out of geometry, {} filled from neighbours{}\n",
                v.resolution[0],
                v.resolution[1],
                v.resolution[2],
                v.spacing,
                v.spacing_reason,
                v.rays_per_probe,
                100.0 * v.relative_standard_error,
                v.moved,
                v.filled,
                if v.unfilled > 0 {
                    format!(", {} left black", v.unfilled)
                } else {
                    String::new()
                }
            ));
        }
        if let Some(f) = &self.floor {
            s.push_str(&format!(
                "ray floor: {:.3}s ({} closest at {:.2} Mrays/s, {} shadow at {:.2} Mrays/s); bake / floor = {:.2}\n",
                f.seconds,
                f.closest_rays,
                f.rates.closest_per_second / 1e6,
                f.shadow_rays,
                f.rates.shadow_per_second / 1e6,
                f.ratio
            ));
            let per_stage: Vec<String> = f
                .stages
                .iter()
                .map(|(name, r)| format!("{name} {r:.2}"))
                .collect();
            s.push_str(&format!(
                "time / ray floor per stage: {}\n",
                per_stage.join(", ")
            ));
        }
        s
    }
}

/// What one shard's part of a split stage cost.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct ShardPart {
    /// The shard.
    pub index: u32,
    /// Items it computed.
    pub items: u64,
    /// Seconds the stage took in it.
    pub seconds: f64,
    /// Closest-hit and any-hit rays it traced.
    pub rays: [u64; 2],
    /// Seconds from its process's start to the end of the stage (the replay of the stages
    /// before included).
    pub process_seconds: f64,
}

/// A split stage in the merged report: every shard's part.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitStage {
    /// The stage.
    pub stage: Stage,
    /// The parts, by shard.
    pub parts: Vec<ShardPart>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stage(stage: Stage, round: u32, rms: Option<f64>) -> StageStats {
        StageStats {
            run: StageRun { stage, round },
            seconds: 1.0,
            rays: 10,
            ray_kind: RayKind::Closest,
            shadow_rays: 0,
            error: rms.map(|rms| ErrorEstimate {
                rms,
                ..ErrorEstimate::default()
            }),
            note: String::new(),
        }
    }

    #[test]
    fn the_error_budget_shares_the_estimate_out_in_quadrature() {
        let total = ErrorEstimate {
            rms: 13.0,
            ..ErrorEstimate::default()
        };
        // A direct pass in two rounds (the last counts), the indirect estimate, the denoiser
        // and the grid: 13² = 5² (sampling, after the denoiser) + 12² (grid).
        let stages = [
            stage(Stage::Direct, 1, Some(10.0)),
            stage(Stage::Direct, 2, Some(6.0)),
            stage(Stage::ErrorEstimate, 1, Some(8.0)),
            stage(Stage::Denoise, 1, None),
            stage(Stage::GridError, 1, Some(12.0)),
        ];
        let budget = error_budget(&stages, Some(&total));
        let shares: Vec<f64> = budget.iter().map(|p| p.share).collect();
        // The 25 of sampling shared 36 : 64 between the direct light and the indirect.
        let expected = [9.0 / 169.0, 16.0 / 169.0, 144.0 / 169.0];
        assert_eq!(budget.len(), 3, "{budget:?}");
        for (s, e) in shares.iter().zip(expected) {
            assert!((s - e).abs() < 1e-12, "{shares:?}");
        }
        assert!((budget[2].rms - 12.0).abs() < 1e-12);
        assert_eq!(
            budget[0].part,
            "the direct light's noise after the denoiser"
        );
        assert!(error_budget(&stages, None).is_empty());
    }
}
