//! The driver: plan → memory check → unwrap → BVH → texel patches → validity → direct light
//! → indirect light (radiosity or instant radiosity) → pages (fill, dilate). Each stage runs
//! only when the plan says the scene needs it, and is timed, counted and recorded in the
//! report. `bake::stages` is the driver's stage runner (the `runner` seam the passes run
//! through: timing, progress, previews, and where a stage's work units run);
//! `bake::prefix` the passes before the lighting, `bake::passes` the lighting passes (each
//! algorithm composes its own stages, such as `radiosity::hierarchical_solve`) and
//! `bake::finish` the passes over the pages.
//!
//! [`bake`] works in memory and returns [`BakeOutput`]; [`crate::output::write_outputs`]
//! writes it. [`BakeBuilder`] sets up any other bake: with progressive previews
//! ([`preview`]), on a thread of its own ([`BakeHandle`]), or as one process of a bake split
//! across processes ([`shard`]). Work runs on a rayon pool of `settings.threads` threads; the
//! result does not depend on the thread count.

mod estimate;
mod finish;
mod finite;
mod prefix;
#[cfg(feature = "internals")]
pub use finite::inject_nan;
mod builder;
mod group_lighting;
mod groups;
mod handle;
mod passes;
pub mod preview;
mod relight;
pub mod shard;
mod stages;
mod subset;

use std::time::Instant;

use glam::Vec3;

use crate::bvh::RayScene;
use crate::bvh::workload::RayRates;
use crate::context::BakeContext;
use crate::error::{BakeError, Result};
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::incremental::BakeCache;
pub use crate::incremental::StageValues;
use crate::lightmap::contacts::ContactStats;
use crate::lightmap::denoise::DenoiseStats;
use crate::lightmap::stitch::StitchStats;
use crate::lightmap::{Assembly, HALF_MAX, LightmapPage};
use crate::lights::Emitters;
use crate::memory;
use crate::plan::BakePlan;
use crate::probes::{IrradianceVolume, VolumeGrid, VolumeStats};
use crate::progress::Progress;
use crate::raster::Patches;
use crate::report::{BakeReport, Decision, Floor, TexelStats};
use crate::runner::{StageRunner, WorkScope};
use crate::sampling::hash_words;
use crate::scene::Scene;
use crate::scene::groups::GroupMembers;
use crate::settings::{BakeSettings, Method};
use crate::stage::Stage;
use crate::unwrap::Layout;
pub use builder::{BakeBuilder, SplitOutcome};
use estimate::with_grid_error;
pub use groups::GroupPages;
pub use handle::BakeHandle;
pub use preview::{Preview, PreviewKind, PreviewSlot};
pub use shard::{Role, ShardRun};
use stages::{Scope, Stages};
pub use subset::{Checkpoint, TexelRun};

/// Rays of each kind the floor calibration traces.
const CALIBRATION_RAYS: usize = 65_536;

/// Everything a bake produces, in memory.
#[derive(Clone, Debug)]
pub struct BakeOutput {
    /// The lightmap layout: per-mesh UVs and per-instance rectangles.
    pub layout: Layout,
    /// The scene as baked: meshes split along seams, `uv1` set.
    pub baked_scene: Scene,
    /// Lightmap pages (E/π, linear RGB).
    pub pages: Vec<LightmapPage>,
    /// The irradiance volumes for dynamic objects, one per region of the level, when the
    /// settings ask for them
    /// ([`VolumeSettings::enabled`](crate::settings::VolumeSettings::enabled),
    /// [`VolumeSettings::regions`](crate::settings::VolumeSettings::regions)); empty
    /// otherwise.
    pub irradiance_volumes: Vec<IrradianceVolume>,
    /// With light groups ([`BakeSettings::groups`]): each group's pages and volumes, whose
    /// sum is `pages` and `irradiance_volumes`. Empty without groups.
    pub groups: Vec<GroupPages>,
    /// Timings, counts, plan and warnings.
    pub report: BakeReport,
    /// What the next bake of the scene can follow ([`BakeBuilder::following`]): written
    /// beside the outputs as `lightbake.cache`. None for other bakes.
    pub cache: Option<BakeCache>,
}

/// Bakes `scene` with `settings` on this thread, reporting progress to (and obeying
/// cancellation from) `progress`: the short form of
/// `BakeBuilder::new(scene).settings(settings).run()` for a borrowed scene. [`BakeBuilder`]
/// also runs a bake with previews, on a thread of its own ([`BakeHandle`]) or as one process
/// of a split bake.
///
/// # Errors
/// Invalid settings or scene ([`BakeError::BadSetting`] and the scene errors),
/// [`BakeError::OverMemoryBudget`], [`BakeError::Unwrap`], [`BakeError::Cancelled`].
pub fn bake(scene: &Scene, settings: &BakeSettings, progress: &Progress) -> Result<BakeOutput> {
    bake_with(
        scene,
        settings,
        progress,
        &PreviewSlot::default(),
        Scope::All,
    )
}

/// One process of a bake split across processes ([`shard`]): `run` says which (prepare,
/// shard I of N, merge) and where the work folder is. The merge returns the bake, bit for bit
/// the output of [`bake`] with the same scene and settings; prepare and the shards say what
/// they did.
///
/// # Errors
/// As [`bake`]; [`BakeError::Shard`] when the work folder is incomplete or from another
/// preparation; [`BakeError::BadSetting`] for a target error (its rounds need each whole
/// stage's estimate).
fn bake_split(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    run: &ShardRun,
) -> Result<SplitOutcome> {
    if let Some(t) = settings.target_error {
        return Err(BakeError::BadSetting {
            name: "target_error",
            value: t.to_string(),
            message: "a split bake takes fixed sample counts: its rounds would need every shard's estimate".into(),
        });
    }
    match bake_with(
        scene,
        settings,
        progress,
        &PreviewSlot::default(),
        Scope::Split(run),
    ) {
        Ok(output) => Ok(SplitOutcome::Merged(Box::new(output))),
        Err(BakeError::Cancelled) if !progress.is_cancelled() => match run.stopped() {
            Some(done) => Ok(SplitOutcome::PartDone(done)),
            None => Err(BakeError::Cancelled),
        },
        Err(e) => Err(e),
    }
}

/// A bake that computes the texels `run` marks, the others' split-stage values taken from an
/// earlier run ([`TexelRun`]).
///
/// # Errors
/// As [`bake`]; [`BakeError::Subset`] when the earlier values do not fit;
/// [`BakeError::BadSetting`] for a target error (its rounds would make the stages depend on
/// the subset's estimate).
fn bake_texels(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    run: &TexelRun,
) -> Result<BakeOutput> {
    if let Some(t) = settings.target_error {
        return Err(BakeError::BadSetting {
            name: "target_error",
            value: t.to_string(),
            message: "a bake over a subset of the texels takes fixed sample counts: its rounds would depend on the subset's own estimate".into(),
        });
    }
    bake_with(scene, settings, progress, previews, Scope::Subset(run))
}

fn bake_with(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    scope: Scope<'_>,
) -> Result<BakeOutput> {
    settings.validate()?;
    scene.validate()?;
    let light_groups = crate::scene::groups::resolve(scene, &settings.groups)?;
    if !light_groups.is_empty() && !matches!(scope, Scope::All) {
        return Err(BakeError::BadSetting {
            name: "groups",
            value: settings.groups.len().to_string(),
            message: "light groups are baked in one process over every texel: a split bake or a bake of a subset of the texels takes none".into(),
        });
    }
    if settings.method == Method::Vpl
        && let Some(l) = scene.lights.iter().find(|l| !l.direct_is_baked())
    {
        return Err(BakeError::BadSetting {
            name: "method",
            value: "vpl".into(),
            message: format!(
                "light '{}' is baked indirect only, which needs the direct pass to tell its direct light apart: use the radiosity or hybrid method",
                l.name
            ),
        });
    }
    // More workers than cores only add contention (and 10⁵ of them would take the machine's
    // thread limit): clamped, with a warning.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut notes = Vec::new();
    let threads = if settings.threads > cores {
        notes.push(format!(
            "threads = {} is more than the machine's {cores} cores; the bake uses {cores}",
            settings.threads
        ));
        cores
    } else {
        settings.threads
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| BakeError::BadSetting {
            name: "threads",
            value: settings.threads.to_string(),
            message: e.to_string(),
        })?;
    pool.install(|| {
        bake_in_pool(
            scene,
            settings,
            progress,
            previews,
            (scope, &light_groups),
            pool.current_num_threads(),
            notes,
        )
    })
}

impl Lit {
    /// Black pages over `layout` (nothing to bake).
    fn black(layout: &Layout) -> Self {
        Lit {
            pages: (layout.pages.iter())
                .map(|p| LightmapPage::black(p.width, p.height))
                .collect(),
            ..Lit::default()
        }
    }
}

/// Values of the valid patches only.
fn valid<T: Copy>(patches: &Patches, values: &[T]) -> Vec<T> {
    patches
        .patches
        .iter()
        .zip(values)
        .filter(|(p, _)| p.is_valid())
        .map(|(_, v)| *v)
        .collect()
}

/// What lighting the scene produced, for the report.
#[derive(Default)]
struct Lit {
    pages: Vec<LightmapPage>,
    texels: TexelStats,
    radiosity: Option<crate::radiosity::RadiosityReport>,
    vpl: Option<crate::vpl::VplReport>,
    /// How the indirect light was computed (for the report's decisions).
    indirect_reason: Option<String>,
    error: Option<ErrorEstimate>,
    rates: RayRates,
    contact: Option<ContactStats>,
    seams: Option<StitchStats>,
    denoise: Option<DenoiseStats>,
    volumes: Vec<(IrradianceVolume, VolumeStats)>,
    /// Stages the plan meant to run that the bake found it could not, with why.
    skipped: Vec<(Stage, String)>,
    /// With light groups: each group's pages and volume, and the irradiance per patch of
    /// the group being lit (summed into the bake's estimate, then dropped).
    groups: Vec<GroupPages>,
    irradiance: Vec<Vec3>,
}

/// A bake on the current rayon pool: the geometry stages ([`prefix`]), the lighting and
/// finishing passes ([`light_scene`]), then the report.
fn bake_in_pool(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    (scope, light_groups): (Scope<'_>, &[GroupMembers]),
    threads: usize,
    notes: Vec<String>,
) -> Result<BakeOutput> {
    let start = Instant::now();
    let mut stages = Stages::new(progress, previews, scope);
    let mut warnings = scene.warnings.clone();
    warnings.extend(notes);
    let mut decisions = Vec::new();
    let plan = prefix::plan(scene, settings, &mut stages)?;
    let layout = prefix::unwrap(scene, settings, &plan, &mut stages)?;
    let (layout, early_rays, density) =
        prefix::density(scene, settings, &plan, layout, &mut stages, &mut decisions)?;
    warnings.extend(layout.warnings.iter().cloned());
    if let Some(run) = stages.scope().texel_run() {
        run.layout_known(scene, settings, plan.texel_density, &layout);
    }
    let admitted = prefix::admit(scene, settings, &plan, &layout, previews, &mut decisions)?;
    let baked_scene = layout.apply(scene);
    let mut lit = if plan.nothing_to_bake {
        Lit {
            groups: groups::black_groups(&layout, light_groups, scene),
            ..Lit::black(&layout)
        }
    } else {
        let rays = prefix::bvh(&baked_scene, early_rays, &mut stages)?;
        let lighting = (rays, admitted.volume_grids, light_groups);
        light_scene(
            &baked_scene,
            &layout,
            settings,
            &plan,
            lighting,
            &mut stages,
            &mut warnings,
        )?
    };
    lit.texels.pages = layout.pages.len();
    lit.texels.page_texels = layout.page_texels();
    warnings.extend(half_float_warning(&lit.pages));
    if let Some(reason) = lit.indirect_reason.take() {
        decisions.push(Decision::ran(Stage::Indirect, reason));
    }
    for (stage, reason) in lit.skipped.drain(..) {
        decisions.push(Decision::skipped(stage, reason));
    }
    let total_seconds = start.elapsed().as_secs_f64();
    stages.preview(PreviewKind::Final, &layout, Vec3::ZERO, || {
        lit.pages.clone()
    });
    let floor = (stages.list.iter().any(|s| s.rays > 0) && lit.rates.closest_per_second > 0.0)
        .then(|| Floor::new(&stages.list, lit.rates, total_seconds));
    let (irradiance_volumes, volume_stats): (Vec<_>, Vec<_>) =
        std::mem::take(&mut lit.volumes).into_iter().unzip();
    let group_reports = lit.groups.iter().map(|g| g.report.clone()).collect();
    let error_budget = crate::report::error_budget(&stages.list, lit.error.as_ref());
    let report = BakeReport {
        lightbake_version: env!("CARGO_PKG_VERSION"),
        scene: scene.name.clone(),
        settings: settings.clone(),
        plan,
        decisions,
        density,
        stages: stages.list,
        radiosity: lit.radiosity,
        vpl: lit.vpl,
        contact_fit: lit.contact,
        seams: lit.seams,
        denoise: lit.denoise,
        irradiance_volumes: volume_stats,
        groups: group_reports,
        split: (scope.split_bake())
            .map(ShardRun::split_stages)
            .unwrap_or_default(),
        texels: lit.texels,
        triangles: scene.instanced_triangle_count(),
        threads,
        memory: admitted.estimate,
        warnings,
        texcoord_0_added: Vec::new(),
        incremental: scope.texel_run().and_then(TexelRun::report),
        error: lit.error,
        error_budget,
        floor,
        verification: None,
        total_seconds,
        peak_resident_mib: memory::peak_resident_bytes().map(|b| b as f64 / 1048576.0),
        outputs: Vec::new(),
    };
    let cache = (scope.texel_run()).filter(|r| r.keeps_cache()).map(|r| {
        let error = report.error.as_ref().map_or(0.0, |e| e.relative_rms as f32);
        BakeCache::new(
            scene,
            settings,
            report.plan.texel_density,
            &layout,
            r.values(),
            error,
        )
    });
    Ok(BakeOutput {
        layout,
        baked_scene,
        pages: lit.pages,
        irradiance_volumes,
        groups: lit.groups,
        report,
        cache,
    })
}

/// The warning about texels beyond the half-float range, which every output format and
/// Bevy's `Rgba16Float` images clamp to 65504.
fn half_float_warning(pages: &[LightmapPage]) -> Option<String> {
    let over: usize = pages.iter().map(LightmapPage::channels_over_half).sum();
    let max = pages
        .iter()
        .flat_map(|p| p.texels.iter())
        .fold(0.0f32, |m, t| m.max(t.max_element()));
    (over > 0).then(|| {
        format!(
            "the brightest texel ({max:.3e}) exceeds the half-float range: {over} texel channels are clamped to {HALF_MAX} in EXR and KTX2 outputs and in Bevy's images"
        )
    })
}

/// Everything after the unwrap and the BVH for a scene with something to bake, given its ray
/// scene and the volume's grid: the texel patches, then the lighting ([`light_patches`]), once
/// or once per light group ([`groups::light_groups`]).
fn light_scene(
    scene: &Scene,
    layout: &Layout,
    settings: &BakeSettings,
    plan: &BakePlan,
    (rays, volume_grids, light_groups): (RayScene, Vec<VolumeGrid>, &[GroupMembers]),
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    let mut lit = Lit::default();
    let patches = finish::texel_patches(scene, layout, settings, plan, &rays, stages)?;
    lit.count_texels(&patches, warnings);
    let ctx = BakeContext {
        scene,
        layout,
        rays: &rays,
        patches: &patches,
        settings,
        plan,
    };
    if light_groups.is_empty() {
        light_patches(&ctx, volume_grids, true, lit, stages, warnings)
    } else {
        groups::light_groups(&ctx, light_groups, volume_grids, lit, stages, warnings)
    }
}

/// The lighting of `ctx`'s scene over its texel patches: the lighting passes, the floor
/// calibration (when `calibrate`), the pages and the finishing passes on them, and the
/// volume, added to `lit`.
fn light_patches(
    ctx: &BakeContext<'_>,
    volume_grids: Vec<VolumeGrid>,
    calibrate: bool,
    lit: Lit,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    let emitters = emitters_of(ctx, warnings);
    let light = passes::lighting(ctx, &emitters, stages, warnings)?;
    finish_patches(
        ctx,
        &emitters,
        light,
        (volume_grids, calibrate),
        lit,
        stages,
        warnings,
    )
}

/// The emitters of `ctx`'s scene, and the warnings about them.
fn emitters_of(ctx: &BakeContext<'_>, warnings: &mut Vec<String>) -> Emitters {
    let emitters = Emitters::collect(ctx.scene, ctx.rays);
    warnings.extend(emitter_warnings(&emitters, ctx.rays, ctx.scene));
    emitters
}

/// After the lighting passes of `ctx`'s scene (`light`, from `emitters`): the floor
/// calibration (when `calibrate`), the pages and the finishing passes on them, and the
/// volumes on `volume_grids`, added to `lit`.
fn finish_patches(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    mut light: passes::Lighting,
    (volume_grids, calibrate): (Vec<VolumeGrid>, bool),
    mut lit: Lit,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    let (scene, layout, rays, patches) = (ctx.scene, ctx.layout, ctx.rays, ctx.patches);
    let (settings, plan) = (ctx.settings, ctx.plan);
    stages.scope().stop_after_split()?;
    let mut irradiance = std::mem::take(&mut light.irradiance);
    lit.take_lighting(&mut light, patches, &irradiance);
    if calibrate {
        lit.rates = finish::calibrate_floor(rays, patches, settings, stages)?;
    }
    if let Some((indirect, _)) = light.indirect.as_mut() {
        finite::patches("indirect", scene, patches, indirect)?;
    }
    finite::patches("lighting", scene, patches, &mut irradiance)?;
    let mut assembly = Assembly::new(layout, patches, &irradiance);
    if plan.runs(Stage::Denoise) {
        finish::denoise_pages(ctx, &light, &irradiance, &mut assembly, &mut lit, stages)?;
    }
    if plan.runs(Stage::GridError) && !light.direct.is_empty() {
        let value = (lit.error.as_ref().map(|e| e.value_rms))
            .unwrap_or_else(|| rms_luminance(&valid(patches, &irradiance)));
        let (direct, se) = (&light.direct, &light.texel_error);
        let before = lit.error.take();
        let denoised = lit.denoise.is_some();
        lit.error = with_grid_error(
            ctx,
            rays,
            emitters,
            stages,
            direct,
            se,
            (before, denoised),
            value,
        )?;
    }
    if settings.groups.is_empty() {
        drop(irradiance);
    } else {
        lit.irradiance = irradiance;
    }
    assembly.fill_hidden(patches);
    if plan.runs(Stage::ContactFit) {
        lit.contact = Some(finish::contact_fit_pages(ctx, &mut assembly, stages)?);
    }
    finish::dilate_pages(ctx, &mut assembly, &mut lit, stages)?;
    if plan.runs(Stage::Stitch) {
        lit.seams = Some(finish::stitch_pages(ctx, &mut assembly, stages)?);
    }
    lit.pages = assembly.pages;
    if !volume_grids.is_empty() {
        let volumes = finish::volume_stage(ctx, volume_grids, emitters, &lit.pages, stages)?;
        for (k, (_, st)) in volumes.iter().enumerate() {
            if st.unfilled > 0 {
                warnings.push(format!(
                    "every probe of irradiance volume {k} is inside geometry: the volume is black"
                ));
            }
        }
        lit.volumes = volumes;
    }
    Ok(lit)
}

impl Lit {
    /// The texel counts of `patches` (and the warning about texels judged hidden that were
    /// partly open).
    fn count_texels(&mut self, patches: &Patches, warnings: &mut Vec<String>) {
        self.texels.patches = patches.patches.len();
        self.texels.moved = patches.moved;
        self.texels.partly_hidden = patches.rescued;
        self.texels.invalid = patches.invalid;
        self.texels.visible_unlit = patches.visible_unlit;
        if patches.visible_unlit > 0 {
            warnings.push(format!(
                "{} texels were judged hidden (inside or behind geometry), yet a second look found part of them open: they are filled from their chart, not lit",
                patches.visible_unlit
            ));
        }
    }

    /// The lighting passes' reports and their combined error estimate (relative to the RMS
    /// of `irradiance` over the valid patches).
    fn take_lighting(
        &mut self,
        light: &mut passes::Lighting,
        patches: &Patches,
        irradiance: &[Vec3],
    ) {
        self.radiosity = light.radiosity.take();
        self.vpl = light.vpl.take();
        self.indirect_reason = light.indirect_reason.take();
        if !light.errors.is_empty() {
            let value = rms_luminance(&valid(patches, irradiance));
            self.error = Some(ErrorEstimate::combine(&light.errors, value));
        }
    }
}

/// Points the calibration's rays start from: the points of valid texel patches picked at
/// random (as many as the calibration's rays, at most), where the lighting passes' rays
/// start. The rays then meet what the bake's rays meet: an open ground plane at a low
/// texel density, say, makes up most of the scene's area but few of its rays.
fn calibration_origins(patches: &Patches, seed: u32) -> Vec<(Vec3, Vec3)> {
    let n = patches.patches.len();
    if n == 0 {
        return Vec::new();
    }
    (0..CALIBRATION_RAYS as u32)
        .filter_map(|i| {
            let p = &patches.patches[hash_words(&[seed, 0xca1b, i]) as usize % n];
            p.is_valid().then_some((p.position, p.geometric_normal))
        })
        .collect()
}

/// Warnings about emissive triangles that lie on each other.
fn emitter_warnings(emitters: &Emitters, rays: &RayScene, scene: &Scene) -> Vec<String> {
    let mut warnings = Vec::new();
    if emitters.coincident > 0 {
        warnings.push(format!(
            "{} emissive triangles lie exactly on another emissive triangle (a duplicated mesh or face); each pair is sampled as one light",
            emitters.coincident
        ));
    }
    if emitters.overlapping_count > 0 {
        let name = |t: u32| {
            let info = rays.triangles[t as usize];
            format!(
                "'{}' triangle {}",
                scene.instances[info.instance as usize].name, info.local
            )
        };
        let listed: Vec<String> = emitters
            .overlapping
            .iter()
            .map(|&(a, b)| format!("{} and {}", name(a), name(b)))
            .collect();
        warnings.push(format!(
            "{} pair(s) of emissive triangles overlap in the same plane ({}{}); their light adds up where they overlap: remove one of each pair",
            emitters.overlapping_count,
            listed.join(", "),
            if emitters.overlapping_count > listed.len() {
                ", …"
            } else {
                ""
            }
        ));
    }
    warnings
}

/// Whether `method` computes direct light with [`crate::direct`] (method `vpl` carries it by
/// VPLs instead).
fn direct_pass_runs(method: Method) -> bool {
    method != Method::Vpl
}
