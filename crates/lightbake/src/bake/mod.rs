//! The driver: plan → memory check → unwrap → BVH → texel patches → validity → direct light
//! → indirect light (radiosity or instant radiosity) → pages (fill, dilate). Each stage runs
//! only when the plan says the scene needs it, and is timed, counted and recorded in the
//! report (`bake::stages`); the lighting passes are `bake::passes`.
//!
//! [`bake`] works in memory and returns [`BakeOutput`]; [`crate::output::write_outputs`]
//! writes it. [`BakeBuilder`] sets up any other bake: with progressive previews
//! ([`preview`]), on a thread of its own ([`BakeHandle`]), or as one process of a bake split
//! across processes ([`shard`]). Work runs on a rayon pool of `settings.threads` threads; the
//! result does not depend on the thread count.

mod estimate;
mod finite;
#[cfg(feature = "internals")]
pub use finite::inject_nan;
mod builder;
mod gathers;
mod handle;
mod passes;
pub mod preview;
pub mod shard;
mod stages;

use std::time::Instant;

use glam::Vec3;

use crate::bvh::RayScene;
use crate::bvh::workload::{RayRates, calibrate};
use crate::context::BakeContext;
use crate::error::{BakeError, Result};
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lightmap::contacts::{ContactStats, contact_fit};
use crate::lightmap::denoise::{DenoiseStats, denoise, denoise_parts};
use crate::lightmap::seams::find_seams;
use crate::lightmap::stitch::{StitchStats, stitch};
use crate::lightmap::{Assembly, HALF_MAX, LightmapPage};
use crate::lights::Emitters;
use crate::memory;
use crate::plan::BakePlan;
use crate::probes::gather::Solution;
use crate::probes::{IrradianceVolume, VolumeGrid, VolumeStats, bake_volume};
use crate::progress::{Progress, RayKind};
use crate::raster::Patches;
use crate::report::{BakeReport, Decision, Floor, TexelStats};
use crate::sampling::hash_words;
use crate::scene::Scene;
use crate::settings::{BakeSettings, Method};
use crate::stage::Stage;
use crate::unwrap::{Layout, unwrap_scene};
pub use builder::{BakeBuilder, SplitOutcome};
use estimate::{denoised_error, with_grid_error};
pub use handle::BakeHandle;
pub use preview::{Preview, PreviewKind, PreviewSlot};
use shard::Units;
pub use shard::{Role, ShardRun};
use stages::Stages;

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
    /// The irradiance volume for dynamic objects, when the settings ask for one
    /// ([`BakeSettings::irradiance_volume`]).
    pub irradiance_volume: Option<IrradianceVolume>,
    /// Timings, counts, plan and warnings.
    pub report: BakeReport,
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
    bake_with(scene, settings, progress, &PreviewSlot::default(), None)
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
        Some(run),
    ) {
        Ok(output) => Ok(SplitOutcome::Merged(Box::new(output))),
        Err(BakeError::Cancelled) if !progress.is_cancelled() => match run.stopped() {
            Some(done) => Ok(SplitOutcome::PartDone(done)),
            None => Err(BakeError::Cancelled),
        },
        Err(e) => Err(e),
    }
}

fn bake_with(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    shards: Option<&ShardRun>,
) -> Result<BakeOutput> {
    settings.validate()?;
    scene.validate()?;
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
            shards,
            pool.current_num_threads(),
            notes,
        )
    })
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
    volume: Option<(IrradianceVolume, VolumeStats)>,
    /// Stages the plan meant to run that the bake found it could not, with why.
    skipped: Vec<(Stage, String)>,
}

fn bake_in_pool(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    shards: Option<&ShardRun>,
    threads: usize,
    notes: Vec<String>,
) -> Result<BakeOutput> {
    let start = Instant::now();
    let mut stages = Stages::new(progress, previews, shards);
    let mut warnings = scene.warnings.clone();
    warnings.extend(notes);

    // Plan, and refuse early when the texel count alone would not fit.
    let mut decisions = Vec::new();
    let decide = |stage: Stage, ran: bool, what: String| Decision { stage, ran, what };
    let plan = stages.run(Stage::Plan, 1, || {
        let plan = BakePlan::new(scene, settings);
        let note = format!("{} texels/m", crate::plan::density_text(plan.texel_density));
        Ok((plan, 0, note))
    })?;
    memory::estimate_from_area(scene, plan.texel_density).check(settings.memory_budget_mib)?;
    plan.check_rays(settings)?;

    let layout = stages.run(Stage::Unwrap, scene.meshes.len() as u64, || {
        let layout = unwrap_scene(scene, settings, plan.texel_density)?;
        let note = format!(
            "{} mesh(es) xatlas, {} kept, {} page(s)",
            plan.meshes_to_unwrap,
            plan.meshes_keeping_uv1,
            layout.pages.len()
        );
        Ok((layout, 0, note))
    })?;
    // The density that follows the light: a pilot on the first layout, which is then
    // repacked; the ray scene it traces is the lighting passes' (same triangles).
    let (layout, early_rays, density) = if plan.runs(Stage::Density) {
        let (layout, rays, density) = stages.run(Stage::Density, 1, || {
            let rays = RayScene::build(scene);
            match crate::density::adapt(scene, settings, &plan, &layout, &rays) {
                Ok((adapted, report)) => {
                    let note = report.summary();
                    let traced = report.rays;
                    Ok(((adapted, rays, Ok(report)), traced, note))
                }
                Err(reason) => Ok(((layout, rays, Err(reason.clone())), 0, reason)),
            }
        })?;
        match density {
            Ok(report) => {
                decisions.push(decide(Stage::Density, true, report.summary()));
                (layout, Some(rays), Some(report))
            }
            Err(reason) => {
                decisions.push(decide(Stage::Density, false, reason));
                (layout, Some(rays), None)
            }
        }
    } else {
        (layout, None, None)
    };
    warnings.extend(layout.warnings.iter().cloned());
    let mut estimate = memory::estimate_from_layout(scene, &layout);
    // The volume's grid, planned here so that a spacing it cannot take is refused before
    // the lighting passes run.
    let volume_grid = if plan.runs(Stage::Volume) {
        let grid = VolumeGrid::plan(scene, &layout, settings, plan.texel_density)?;
        if grid.is_none() {
            decisions.push(decide(
                Stage::Volume,
                false,
                "no instance has a lightmap".into(),
            ));
        }
        grid
    } else {
        None
    };
    if let Some(grid) = &volume_grid {
        estimate = estimate.with(
            "irradiance volume",
            grid.len() as u64 * crate::probes::volume::BYTES_PER_PROBE,
        );
        decisions.push(decide(
            Stage::Volume,
            true,
            format!(
                "irradiance volume for dynamic objects: {} × {} × {} probes {:.3e} m apart ({}), {} rays each",
                grid.resolution.x,
                grid.resolution.y,
                grid.resolution.z,
                grid.spacing,
                grid.reason,
                settings.probe_rays
            ),
        ));
    }
    if previews.is_enabled() {
        // The direct light kept per patch (at most one per page texel, 12 bytes) and two
        // sets of pages alive at once (the preview shown and the one being made, 16 each).
        estimate = estimate.with("progressive previews", layout.page_texels() * (12 + 2 * 16));
    }
    estimate.check(settings.memory_budget_mib)?;
    let baked_scene = layout.apply(scene);

    let mut lit = if plan.nothing_to_bake {
        Lit {
            pages: layout
                .pages
                .iter()
                .map(|p| LightmapPage::black(p.width, p.height))
                .collect(),
            ..Lit::default()
        }
    } else {
        let rays = stages.run(Stage::Bvh, 1, || {
            // The density pilot's ray scene has the same triangles as the unwrapped scene's.
            let reused = early_rays.is_some();
            let rays = early_rays.unwrap_or_else(|| RayScene::build(&baked_scene));
            let (nodes, packets, bytes) = rays.bvh_size();
            let note = format!(
                "{} triangles, {nodes} nodes, {packets} leaf packets, {:.1} MiB{}",
                rays.bvh_triangle_count(),
                bytes as f64 / 1048576.0,
                if reused {
                    " (built for the density pilot)"
                } else {
                    ""
                }
            );
            Ok((rays, 0, note))
        })?;
        light_scene(
            &baked_scene,
            &layout,
            settings,
            &plan,
            (rays, volume_grid),
            &mut stages,
            &mut warnings,
        )?
    };
    lit.texels.pages = layout.pages.len();
    lit.texels.page_texels = layout.page_texels();
    warnings.extend(half_float_warning(&lit.pages));
    if let Some(reason) = lit.indirect_reason.take() {
        decisions.push(decide(Stage::Indirect, true, reason));
    }
    for (stage, reason) in lit.skipped.drain(..) {
        decisions.push(decide(stage, false, reason));
    }
    let total_seconds = start.elapsed().as_secs_f64();
    let (irradiance_volume, volume_stats) = lit.volume.take().unzip();
    stages.preview(PreviewKind::Final, &layout, Vec3::ZERO, || {
        lit.pages.clone()
    });
    let floor = (stages.list.iter().any(|s| s.rays > 0) && lit.rates.closest_per_second > 0.0)
        .then(|| Floor::new(&stages.list, lit.rates, total_seconds));
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
        irradiance_volume: volume_stats,
        split: shards.map(ShardRun::split_stages).unwrap_or_default(),
        texels: lit.texels,
        triangles: scene.instanced_triangle_count(),
        threads,
        memory: estimate,
        warnings,
        error: lit.error,
        floor,
        verification: None,
        total_seconds,
        peak_resident_mib: memory::peak_resident_bytes().map(|b| b as f64 / 1048576.0),
        outputs: Vec::new(),
    };
    Ok(BakeOutput {
        layout,
        baked_scene,
        pages: lit.pages,
        irradiance_volume,
        report,
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
/// scene and the volume's grid: the texel patches, the lighting passes, the floor
/// calibration and the pages.
fn light_scene(
    scene: &Scene,
    layout: &Layout,
    settings: &BakeSettings,
    plan: &BakePlan,
    (rays, volume_grid): (RayScene, Option<VolumeGrid>),
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    let mut lit = Lit::default();
    let reader = stages.shards().filter(|run| run.reads_patches());
    let patches = match reader {
        // A shard or the merge of a split bake reads prepare's patches.
        Some(run) => stages.run(Stage::Patches, 1, || {
            let p = run.read_prepared(layout, rays.triangles.len(), scene.instances.len())?;
            let note = format!(
                "{} texel patches, read from the work folder",
                p.patches.len()
            );
            Ok((p, 0, note))
        })?,
        None => {
            let mut patches = stages.run(Stage::Raster, 1, || {
                let p = Patches::build(scene, layout, &rays);
                let note = format!("{} texel patches", p.patches.len());
                Ok((p, 0, note))
            })?;
            stages.run(Stage::Validity, patches.patches.len() as u64, || {
                patches.fix_validity(scene, layout, &rays);
                let note = format!(
                    "{} moved ({} seen only in part), {} hidden, {} visible but unlit",
                    patches.moved, patches.rescued, patches.invalid, patches.visible_unlit
                );
                Ok(((), patches.rays, note))
            })?;
            stages.annotate(RayKind::Shadow, None);
            if let Some(run) = stages.shards() {
                // Prepare writes the patches and the work units here, and stops.
                let units = Units::plan(&patches, layout, settings, scene.lights.len(), plan.sky);
                run.prepared(units, &patches)?;
            }
            patches
        }
    };
    lit.texels.patches = patches.patches.len();
    lit.texels.moved = patches.moved;
    lit.texels.partly_hidden = patches.rescued;
    lit.texels.invalid = patches.invalid;
    lit.texels.visible_unlit = patches.visible_unlit;
    if patches.visible_unlit > 0 {
        warnings.push(format!(
            "{} texels were judged hidden (inside or behind geometry), yet a second look found part of them open: they are filled from their chart, not lit",
            patches.visible_unlit
        ));
    }
    let emitters = Emitters::collect(scene, &rays);
    warnings.extend(emitter_warnings(&emitters, &rays, scene));
    let ctx = BakeContext {
        scene,
        layout,
        rays: &rays,
        patches: &patches,
        settings,
        plan,
    };
    let mut light = passes::lighting(&ctx, &emitters, stages, warnings)?;
    stages.shard_stops()?;
    lit.radiosity = light.radiosity;
    lit.vpl = light.vpl;
    lit.indirect_reason = light.indirect_reason;
    if !light.errors.is_empty() {
        let value = rms_luminance(&valid(&patches, &light.irradiance));
        lit.error = Some(ErrorEstimate::combine(&light.errors, value));
    }
    // The rates the floor is measured at: a short calibration on the same pool.
    lit.rates = stages.run(Stage::Calibrate, 1, || {
        let r = calibrate(
            &rays,
            &calibration_origins(&patches, settings.seed),
            CALIBRATION_RAYS,
            settings.seed,
        );
        let note = format!(
            "BVH rates for the floor: {:.2} Mrays/s closest, {:.2} shadow",
            r.closest_per_second / 1e6,
            r.shadow_per_second / 1e6
        );
        Ok((r, 0, note))
    })?;
    let mut irradiance = light.irradiance;
    if let Some((indirect, _)) = light.indirect.as_mut() {
        finite::patches("indirect", scene, &patches, indirect)?;
    }
    finite::patches("lighting", scene, &patches, &mut irradiance)?;
    let mut assembly = Assembly::new(layout, &patches, &irradiance);
    if plan.runs(Stage::Denoise) {
        let covers = light.indirect.is_some() || !plan.runs(Stage::Indirect);
        if covers {
            let (st, error) = stages.run(Stage::Denoise, 1, || {
                let radius = settings.denoise_radius;
                let (st, error) = match &light.indirect {
                    // Direct and indirect light apart, each with its own noise (scaled as the
                    // sum is to the bake's estimate).
                    Some((indirect, indirect_noise)) => {
                        let total: Vec<f32> = light
                            .texel_error
                            .iter()
                            .zip(indirect_noise)
                            .map(|(d, i)| d.hypot(*i))
                            .collect();
                        let scale = calibration(&patches, &total, lit.error.as_ref(), light.coarse_bias);
                        let scaled = |n: &[f32]| n.iter().map(|&v| v * scale).collect::<Vec<f32>>();
                        let direct: Vec<Vec3> =
                            irradiance.iter().zip(indirect).map(|(t, i)| *t - *i).collect();
                        let (a, st, error) = denoise_parts(
                            layout,
                            &patches,
                            [
                                (&direct, &scaled(&light.texel_error)),
                                (indirect, &scaled(indirect_noise)),
                            ],
                            radius,
                        );
                        assembly = a;
                        (st, error)
                    }
                    None => {
                        let noise = &light.texel_error;
                        let scale = calibration(&patches, noise, lit.error.as_ref(), light.coarse_bias);
                        let noise: Vec<f32> = noise.iter().map(|&v| v * scale).collect();
                        denoise(&mut assembly, &patches, &noise, radius)
                    }
                };
                let note = format!(
                    "radius {} texels, {} texels, mean strength {:.2}; noise {:.3} → {:.3} lux RMS, bias added {:.3} lux RMS{}",
                    st.radius,
                    st.texels,
                    st.mean_strength,
                    st.noise_before,
                    st.noise_after,
                    st.bias,
                    if light.indirect.is_some() { "; direct and indirect light filtered apart" } else { "" }
                );
                Ok(((st, error), 0, note))
            })?;
            if let Some(e) = &lit.error {
                lit.error = Some(denoised_error(&patches, &error, e, light.coarse_bias));
            }
            finite::pages("denoise", scene, &patches, &mut assembly.pages)?;
            lit.denoise = Some(st);
        } else {
            lit.skipped.push((
                Stage::Denoise,
                "the indirect pass gives no per-texel noise estimate (only the hierarchical solve's gathers do)".to_string(),
            ));
        }
    }
    if plan.runs(Stage::GridError) && !light.direct.is_empty() {
        let value = (lit.error.as_ref().map(|e| e.value_rms))
            .unwrap_or_else(|| rms_luminance(&valid(&patches, &irradiance)));
        let (direct, se) = (&light.direct, &light.texel_error);
        let before = lit.error.take();
        lit.error = with_grid_error(&ctx, &rays, &emitters, stages, direct, se, before, value)?;
    }
    drop(irradiance);
    assembly.fill_hidden(&patches);
    if plan.runs(Stage::ContactFit) {
        let st = stages.run(Stage::ContactFit, 1, || {
            let st = contact_fit(&mut assembly, scene, layout, &patches, &rays);
            let note = if st.texels == 0 {
                "no texel next to geometry shows light of the wrong side".to_string()
            } else {
                format!(
                    "{} texels next to geometry ({} samples cut), {} values fitted ({} capped), {} CG iterations",
                    st.texels, st.cut_samples, st.unknowns, st.capped, st.iterations
                )
            };
            Ok((st, st.rays, note))
        })?;
        stages.annotate(RayKind::Shadow, None);
        finite::pages("contact fit", scene, &patches, &mut assembly.pages)?;
        lit.contact = Some(st);
    }
    stages.run(Stage::Dilate, 1, || {
        assembly.dilate(settings.padding + 2);
        let st = assembly.stats;
        lit.texels.filled = st.filled;
        lit.texels.dilated = st.dilated;
        lit.texels.unfilled = st.unfilled;
        let note = format!("{} filled, {} padding texels", st.filled, st.dilated);
        Ok(((), 0, note))
    })?;
    finite::pages("dilate", scene, &patches, &mut assembly.pages)?;
    if plan.runs(Stage::Stitch) {
        let st = stages.run(Stage::Stitch, 1, || {
            let seams = find_seams(scene, layout);
            let st = stitch(&mut assembly, &patches, &seams, &rays);
            let note = if seams.is_empty() {
                "no seams: no smooth surface is split between charts (chart borders lie on hard edges)"
                    .to_string()
            } else {
                format!(
                    "{} seam edges, jump {:.2}% mean / {:.2}% max before, {:.2}% / {:.2}% after ({} values capped)",
                    st.before.seams,
                    100.0 * st.before.mean,
                    100.0 * st.before.max,
                    100.0 * st.after.mean,
                    100.0 * st.after.max,
                    st.capped
                )
            };
            Ok((st, 0, note))
        })?;
        finite::pages("stitch", scene, &patches, &mut assembly.pages)?;
        lit.seams = Some(st);
    }
    lit.pages = assembly.pages;
    if let Some(grid) = volume_grid {
        lit.volume = Some(volume_stage(
            scene, layout, settings, grid, &rays, &emitters, &lit.pages, stages,
        )?);
        if lit.volume.as_ref().is_some_and(|v| v.1.unfilled > 0) {
            warnings.push(
                "every probe of the irradiance volume is inside geometry: the volume is black"
                    .to_string(),
            );
        }
    }
    Ok(lit)
}

/// The irradiance volume stage ([`crate::probes`]): every probe of `grid` gathered from the
/// finished `pages`.
#[allow(clippy::too_many_arguments)]
fn volume_stage(
    scene: &Scene,
    layout: &Layout,
    settings: &BakeSettings,
    grid: VolumeGrid,
    rays: &RayScene,
    emitters: &Emitters,
    pages: &[LightmapPage],
    stages: &mut Stages<'_>,
) -> Result<(IrradianceVolume, VolumeStats)> {
    let solution = Solution {
        scene,
        layout,
        pages,
        rays,
        emitters,
    };
    let progress = stages.progress();
    let volume = stages.run(Stage::Volume, grid.len() as u64, || {
        let (volume, st) = bake_volume(&solution, grid, settings.probe_rays, settings.seed, progress);
        let note = format!(
            "{} × {} × {} probes, {:.3e} m apart, {} moved out of geometry, {} filled; noise {:.2}%",
            st.resolution[0],
            st.resolution[1],
            st.resolution[2],
            st.spacing,
            st.moved,
            st.filled,
            100.0 * st.relative_standard_error
        );
        let rays = st.rays;
        Ok(((volume, st), rays, note))
    })?;
    let mut volume = volume;
    finite::probes(&mut volume.0.voxels)?;
    Ok(volume)
}

/// The factor that scales the per-patch noise so its RMS over the valid patches matches the
/// sampling stages' own estimate (`estimate`, less the hierarchical solve's coarse bias
/// `coarse_bias`, relative): the per-texel figures give the shape, the stage estimates
/// (independent re-gathers for radiosity) the scale.
fn calibration(
    patches: &Patches,
    noise: &[f32],
    estimate: Option<&ErrorEstimate>,
    coarse_bias: Option<f64>,
) -> f32 {
    let Some(e) = estimate else {
        return 1.0;
    };
    let bias = coarse_bias.unwrap_or(0.0) * e.value_rms;
    let target = (e.rms * e.rms - bias * bias).max(0.0).sqrt();
    let own = rms_of(&valid(patches, noise));
    if own > 0.0 {
        (target / own) as f32
    } else {
        1.0
    }
}

/// RMS of `values`.
fn rms_of(values: &[f32]) -> f64 {
    let n = values.len().max(1) as f64;
    (values.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / n).sqrt()
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
