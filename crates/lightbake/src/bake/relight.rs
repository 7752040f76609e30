//! A bake with light groups relit from its cache ([`crate::incremental::relight`]): the
//! layout kept, each group's cached pages weighted by the change of its light, their sum
//! the bake's pages. Nothing is lit; the report's one stage says what was weighted. And what
//! a bake with light groups keeps for it ([`group_cache`]).

use std::time::Instant;

use glam::Vec3;

use super::{BakeOutput, GroupPages, half_float_warning};
use crate::error::{BakeError, Result};
use crate::incremental::{
    BakeCache, IncrementalReport, KeptGroup, KeptGroups, KeptPage, Relighting, StageValues,
};
use crate::lightmap::LightmapPage;
use crate::memory::{self, MemoryEstimate};
use crate::plan::BakePlan;
use crate::progress::{Progress, StageStats};
use crate::report::{BakeReport, GroupReport, TexelStats};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::stage::{Stage, StageRun};

/// The bake of `scene` with `settings` that `relighting` says is the weighted sum of the
/// cached groups' pages.
///
/// # Errors
/// Invalid settings or scene; [`crate::BakeError::OverMemoryBudget`] when the relit pages
/// would not fit the memory budget; [`crate::BakeError::Cancelled`].
pub(super) fn relit(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    relighting: Relighting,
) -> Result<BakeOutput> {
    settings.validate()?;
    scene.validate()?;
    let start = Instant::now();
    let Relighting {
        lines,
        weights,
        cache,
    } = relighting;
    let kept = cache.groups.bytes();
    let estimate = MemoryEstimate::default()
        .with("program", memory::PROGRAM_BYTES)
        .with("the cached light groups' pages", kept)
        .with("the relit groups' pages and their sum", kept + kept / 2);
    estimate.check(settings.memory_budget_mib)?;
    progress.begin(StageRun::first(Stage::Relight), 1);
    let members = crate::scene::groups::resolve(scene, &settings.groups)?;
    let relit = cache.groups.relit(&weights);
    if progress.is_cancelled() {
        return Err(BakeError::Cancelled);
    }
    let layout = cache.layout.clone();
    let baked_scene = layout.apply(scene);
    let weighted: Vec<String> = (relit.groups.iter().zip(&weights))
        .filter(|(_, w)| **w != Vec3::ONE)
        .map(|(g, w)| format!("{} × ({:.4}, {:.4}, {:.4})", g.name, w.x, w.y, w.z))
        .collect();
    let groups: Vec<GroupPages> = (relit.groups.into_iter())
        .map(|g| GroupPages {
            report: GroupReport {
                name: g.name.clone(),
                members: (members.iter())
                    .find(|m| m.name == g.name)
                    .map(|m| m.describe(scene))
                    .unwrap_or_default(),
                seconds: 0.0,
                rays: 0,
                error: g.error,
            },
            name: g.name,
            pages: g.pages.into_iter().map(page).collect(),
            irradiance_volumes: Vec::new(),
        })
        .collect();
    let mut plan = BakePlan::new(scene, settings);
    plan.texel_density = cache.density;
    plan.texel_density_source = "the cached bake's layout".into();
    let pages: Vec<LightmapPage> = relit.pages.into_iter().map(page).collect();
    let covered: usize = (pages.iter())
        .map(|p| p.covered.iter().filter(|&&c| c).count())
        .sum();
    let seconds = start.elapsed().as_secs_f64();
    let note = if weighted.is_empty() {
        format!("{} light group(s) kept as they were", groups.len())
    } else {
        format!(
            "{} of {} light group(s) weighted: {}",
            weighted.len(),
            groups.len(),
            weighted.join(", ")
        )
    };
    let stage = StageStats {
        run: StageRun::first(Stage::Relight),
        seconds,
        rays: 0,
        ray_kind: Default::default(),
        shadow_rays: 0,
        error: None,
        note,
    };
    progress.advance(1);
    progress.record_stage(0, &stage);
    let mut warnings = scene.warnings.clone();
    warnings.extend(half_float_warning(&pages));
    let report = BakeReport {
        lightbake_version: env!("CARGO_PKG_VERSION"),
        scene: scene.name.clone(),
        settings: settings.clone(),
        plan,
        decisions: Vec::new(),
        density: None,
        stages: vec![stage],
        texels: TexelStats {
            pages: layout.pages.len(),
            page_texels: layout.page_texels(),
            patches: covered,
            ..TexelStats::default()
        },
        triangles: scene.instanced_triangle_count(),
        threads: 1,
        radiosity: None,
        vpl: None,
        contact_fit: None,
        denoise: None,
        seams: None,
        split: Vec::new(),
        irradiance_volumes: Vec::new(),
        groups: groups.iter().map(|g| g.report.clone()).collect(),
        memory: estimate,
        error_budget: Vec::new(),
        error: relit.error,
        floor: None,
        verification: None,
        warnings,
        texcoord_0_added: Vec::new(),
        incremental: Some(IncrementalReport {
            full: None,
            changes: lines,
            layout: vec!["the cached bake's layout kept whole".into()],
            stages: Vec::new(),
            recomputed: 0.0,
        }),
        total_seconds: seconds,
        peak_resident_mib: memory::peak_resident_bytes().map(|b| b as f64 / 1048576.0),
        outputs: Vec::new(),
    };
    Ok(BakeOutput {
        layout,
        baked_scene,
        pages,
        irradiance_volumes: Vec::new(),
        groups,
        report,
        cache: Some(cache),
    })
}

/// What a bake with light groups keeps for the next: its layout and its groups' finished
/// pages and estimates (no split stage's values: they are lit over every texel).
pub(super) fn group_cache(scene: &Scene, settings: &BakeSettings, out: &BakeOutput) -> BakeCache {
    let error = out.report.error.as_ref();
    let groups = KeptGroups {
        groups: (out.groups.iter())
            .map(|g| KeptGroup {
                name: g.name.clone(),
                pages: g.pages.iter().map(kept).collect(),
                error: g.report.error.clone(),
            })
            .collect(),
        value_rms: error.map_or(0.0, |e| e.value_rms),
    };
    BakeCache::new(
        scene,
        settings,
        out.report.plan.texel_density,
        &out.layout,
        StageValues::default(),
        error.map_or(0.0, |e| e.relative_rms as f32),
    )
    .with_groups(groups)
}

/// The bake's page as the cache keeps it.
fn kept(p: &LightmapPage) -> KeptPage {
    KeptPage {
        width: p.width,
        height: p.height,
        texels: p.texels.clone(),
        covered: p.covered.clone(),
    }
}

/// A cached page as the bake's page.
fn page(p: KeptPage) -> LightmapPage {
    LightmapPage {
        width: p.width,
        height: p.height,
        texels: p.texels,
        covered: p.covered,
    }
}
