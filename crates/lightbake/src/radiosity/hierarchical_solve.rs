//! One round of the hierarchical solve as stages (Hanrahan, Salzman & Aupperle 1991, with a
//! per-texel final gather), composed here and run through the driver's [`StageRunner`]:
//!
//! 1. **coarse solve**: the clusters' radiosity system, refined until its oracle is met
//!    ([`hierarchical::coarse_solve_fields`]);
//! 2. **gather pilot** and **final gather**: H₁ at every node from the fine exitance, a pilot
//!    first and then each node's rays by its noise ([`ray_allocation`]), or one pass of the
//!    settings' rays, or (`cache_spacing`) at the irradiance cache's records only, interpolated
//!    between them ([`gather_cache`]);
//! 3. **correction**: what the coarse level missed, ρ(H₁ − C), gathered once more;
//! 4. **reflection**: near geometry, where the missed light is largest, the correction's own
//!    reflection gathered too;
//! 5. **error estimate**: the round's noise and the coarse level's bias
//!    ([`hierarchical_error`]).
//!
//! The final gather and the correction are split stages: each node's value is computed where
//! the runner's [`WorkScope`] says, and a process of a split bake stops after the correction.

use std::ops::Range;

use glam::Vec3;

use super::coarse_kept::{self, KeptCoarse};
use super::error_estimate::HierarchicalFields;
use super::gather_cache::{self, CacheOptions};
use super::hierarchical::{self, Coarse, CoarseReport, Gather, GatherRays};
use super::{HitMapper, Nodes, hierarchical_error, hierarchy_options, per_patch, ray_allocation};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::error::Result;
use crate::error_estimate::ErrorEstimate;
use crate::progress::RayKind;
use crate::raster::Patch;
use crate::runner::{StageRunner, WorkScope};
use crate::solve::Solution;
use crate::stage::{Stage, StageRun};

/// What one round of the hierarchical solve gives.
pub struct HierarchicalRound {
    /// The solve: B and the reflected irradiance per node, and how the coarse level ended.
    pub solution: Solution,
    /// The round's error estimate.
    pub error: ErrorEstimate,
    /// The coarse level's counters.
    pub coarse: CoarseReport,
    /// The coarse level's estimated bias (relative RMS).
    pub bias: f64,
    /// Each node's standard error of its reflected irradiance (luminance, lux).
    pub node_error: Vec<f32>,
}

/// Round `round` of the hierarchical solve over `nodes` (`direct`: the direct irradiance per
/// patch, lux), each step a stage of `stages`.
///
/// # Errors
/// A cancel, a split bake's part that cannot be read, or a shard's stop after its part.
pub fn solve_round<'p>(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    direct: &[Vec3],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<HierarchicalRound> {
    let mapper = HitMapper::new(*ctx, nodes, ctx.settings.radiosity.basis);
    let coarse = coarse_stage(ctx, &mapper, nodes, direct, round, stages)?;
    let cell_indirect = &coarse.solution.indirect;
    let b = hierarchical::fine_exitance(nodes, direct, &coarse.clusters, cell_indirect);
    let coarse_per_node = coarse.clusters.prolong(cell_indirect);
    // What each node's gathers read, in one number: the coarse light it gathers.
    let summary: Vec<f32> = coarse_per_node.iter().map(|c| luminance(*c)).collect();
    let grid = (&mapper, nodes, summary.as_slice());
    let gathered = final_gather(ctx, grid, &b, direct, &coarse, round, stages)?;
    let missed = hierarchical::missed_exitance(nodes, &gathered.light, &coarse_per_node);
    drop(coarse_per_node);
    let correction_rays = correction_rays(ctx.settings.radiosity.transport_rays);
    let corrected = correction_stages(ctx, grid, &missed, round, stages)?;
    let (correction, mut node_error) = (corrected.light, gathered.error);
    for (e, ce) in node_error.iter_mut().zip(&corrected.error) {
        *e = e.hypot(*ce);
    }
    let (indirect, clamped) = hierarchical::corrected(&gathered.light, &correction);
    let fields = HierarchicalFields {
        exitance: &b,
        gathered: &gathered.light,
        missed: &missed,
        correction: &correction,
        gather_rays: gathered.rays.as_deref(),
    };
    let estimate = error_stage(ctx, &mapper, nodes, &fields, direct, round, stages)?;
    let words = format!("{}, correction of {correction_rays}", gathered.words);
    let light = (b, indirect, clamped);
    Ok(finished_round(coarse, light, &words, estimate, node_error))
}

/// A round from its coarse level, its exitance b, its reflected light per node (and how many
/// nodes were held at zero), its gathers' rays in words, its error estimate and coarse bias,
/// and each node's standard error.
pub(super) fn finished_round(
    coarse: Coarse,
    (b, indirect, clamped): (Vec<Vec3>, Vec<Vec3>, usize),
    gathers: &str,
    (error, bias): (ErrorEstimate, f64),
    node_error: Vec<f32>,
) -> HierarchicalRound {
    let Coarse {
        solution: c,
        report,
        ..
    } = coarse;
    let solution = Solution {
        solver: "hierarchical",
        b,
        indirect,
        history: c.history,
        converged: c.converged,
        iterations: c.iterations,
        rays: 0,
        stop_reason: format!(
            "coarse level of {} cells ({}): {}; final gather of {gathers} ({clamped} node(s) held at zero)",
            report.cells, c.solver, c.stop_reason
        ),
    };
    HierarchicalRound {
        solution,
        error,
        coarse: report,
        bias,
        node_error,
    }
}

/// The coarse level as a stage, and its preview (each node the reflected light of its cell).
pub(super) fn coarse_stage<'p>(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    direct: &[Vec3],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<Coarse> {
    let coarse = coarse_stage_fields(ctx, mapper, nodes, &[direct], round, stages)?;
    Ok(coarse.into_iter().next().expect("one field's coarse level"))
}

/// The coarse level of one or several fields (light groups: `directs[g]` is group g's direct
/// irradiance per patch) as one stage: one cut, its rows and oracle traced once
/// ([`hierarchical::coarse_solve_fields`]), each field's own solve; its preview shows their
/// sum (each node the reflected light of its cell).
pub(super) fn coarse_stage_fields<'p>(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    directs: &[&[Vec3]],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<Vec<Coarse>> {
    let progress = stages.progress();
    // The plan admitted the coarse matrix at its per-node cap.
    let options = hierarchy_options(ctx, nodes, u64::MAX);
    // One field's coarse level is kept for a later bake, and taken from an earlier one over
    // the same nodes in the same round ([`coarse_kept`]).
    let scope = stages.scope();
    let key = (directs.len() == 1).then(|| coarse_kept::key(ctx, nodes, &options, round));
    let earlier = key
        .and_then(|k| scope.earlier_state(Stage::CoarseSolve, k))
        .and_then(|b| KeptCoarse::read(&b, nodes).ok());
    let mut keep = None;
    let coarse = stages.run(
        StageRun {
            stage: Stage::CoarseSolve,
            round,
        },
        0,
        || {
            let updated = (earlier.zip(directs.first())).map(|(kept, direct)| {
                coarse_kept::update(ctx, mapper, nodes, direct, kept, &options, progress)
            });
            let mut not_kept = String::new();
            let c = match updated {
                Some(Ok((c, kept))) => {
                    keep = Some(kept);
                    vec![c]
                }
                other => {
                    if let Some(Err(why)) = other {
                        not_kept = format!("; the earlier bake's coarse level not kept: {why}");
                    }
                    let (c, rows) = hierarchical::coarse_solve_fields(
                        ctx, mapper, nodes, directs, &options, progress,
                    );
                    if let (Some(first), Some(direct), Some(_)) = (c.first(), directs.first(), key)
                    {
                        keep = KeptCoarse::new(first, rows, coarse_kept::source(nodes, direct));
                    }
                    c
                }
            };
            let Some(r) = c.first().map(|c| &c.report) else {
                return Ok((c, 0, String::new()));
            };
            let missed: Vec<String> = (c.iter())
                .map(|c| format!("{:.2}%", 100.0 * c.report.missed_detail))
                .collect();
            let solves: Vec<&str> = (c.iter())
                .map(|c| c.solution.stop_reason.as_str())
                .collect();
            let fields = if c.len() > 1 {
                format!("{} fields: ", c.len())
            } else {
                String::new()
            };
            let note = format!(
                "{fields}{} cells, {} round(s), {} entries, {:.1} MiB, missed detail {} ({}); {}",
                r.cells,
                r.rounds,
                r.matrix_entries,
                r.matrix_bytes as f64 / 1048576.0,
                missed.join(" / "),
                r.stop_reason,
                solves.join(" / ")
            ) + &not_kept;
            let rays = r.rays;
            Ok((c, rays, note))
        },
    )?;
    if let (Some(kept), Some(key)) = (keep, key) {
        scope.keep_state(Stage::CoarseSolve, key, || kept.to_bytes());
    }
    if stages.previewing() {
        let patches = ctx.patches.patches.len();
        let mut sum = vec![Vec3::ZERO; patches];
        let mut ambient = Vec3::ZERO;
        for c in &coarse {
            let per_node = c.clusters.prolong(&c.solution.indirect);
            for (s, v) in sum.iter_mut().zip(per_patch(nodes, &per_node, patches)) {
                *s += v;
            }
            ambient += c.ambient;
        }
        stages.preview_indirect(ctx, &sum, ambient);
    }
    Ok(coarse)
}

/// A gather's light per node (lux) and its standard error (luminance, lux).
struct Gathered {
    light: Vec<Vec3>,
    error: Vec<f32>,
}

/// The nodes a gather runs over, with their mapper and each node's input summary (the coarse
/// light it gathers, luminance, lux; see [`crate::runner::WorkScope::split`]).
type Grid<'a> = (&'a HitMapper<'a>, &'a Nodes, &'a [f32]);

/// The correction of the missed exitance `missed`, then (near geometry) the correction's own
/// reflection, as two stages; a process of a split bake stops between them.
fn correction_stages<'p>(
    ctx: &BakeContext<'_>,
    (mapper, nodes, summary): Grid<'_>,
    missed: &[Vec3],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<Gathered> {
    let rays = correction_rays(ctx.settings.radiosity.transport_rays);
    let per_node = |_: usize| 0..rays;
    let (mut correction, error) = gather_stage(
        ctx,
        (mapper, nodes, summary),
        (missed, &per_node, Gather::Correction),
        StageRun {
            stage: Stage::Correction,
            round,
        },
        |r| gather_note(format!("{rays} rays/node"), r),
        stages,
    )?;
    // The last split stage: a shard process stops here (the rest is the merge's).
    stages.scope().stop_after_split()?;
    // The light the coarse level misses is largest next to geometry (a corner darkens
    // within a few texels, inside a cell of one value), and reaches there through two more
    // reflections: near geometry the correction's own reflection is gathered too.
    let near: Vec<bool> = (0..nodes.len())
        .map(|i| ctx.patches.patches[nodes.patch[i] as usize].flags & Patch::NEAR_GEOMETRY != 0)
        .collect();
    let near_count = near.iter().filter(|&&n| n).count() as u64;
    let reflected: Vec<Vec3> = (0..nodes.len())
        .map(|i| nodes.albedo[i] * correction[i])
        .collect();
    let progress = stages.progress();
    let run = StageRun {
        stage: Stage::Reflection,
        round,
    };
    // A bake that follows an edit keeps a node's reflection where the coarse light it
    // gathers (`summary`, what the correction follows too) barely moved.
    let scope = stages.scope();
    let (reflection, visibility) = stages.run(run, near_count, || {
        let (values, traced) = scope.kept_across_edits(
            Stage::Reflection,
            nodes.len(),
            |i| nodes.patch[i] as usize,
            Some(summary),
            |only| {
                let marked: Option<Vec<bool>> =
                    only.map(|o| o.iter().zip(&near).map(|(&o, &n)| o && n).collect());
                let (d, se, traced) = hierarchical::final_gather(
                    ctx,
                    mapper,
                    nodes,
                    &reflected,
                    &per_node,
                    Gather::Reflection,
                    Some(marked.as_deref().unwrap_or(&near)),
                    progress,
                );
                let values = d.into_iter().zip(se).collect();
                (values, [traced.closest, traced.visibility])
            },
        )?;
        let traced = GatherRays {
            closest: traced[0],
            visibility: traced[1],
        };
        let note = format!(
            "{near_count} nodes near geometry, {}",
            gather_note(format!("{rays} rays/node"), traced)
        );
        let d: Vec<Vec3> = values.into_iter().map(|(d, _): (Vec3, f32)| d).collect();
        Ok((
            (d, traced.visibility),
            traced.closest + traced.visibility,
            note,
        ))
    })?;
    stages.annotate(RayKind::Closest, None);
    stages.shadow_rays(visibility);
    for (c, d) in correction.iter_mut().zip(&reflection) {
        *c += *d;
    }
    Ok(Gathered {
        light: correction,
        error,
    })
}

/// The round's error estimate as a stage: the estimate and the coarse level's bias.
pub(super) fn error_stage<'p>(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    fields: &HierarchicalFields<'_>,
    direct: &[Vec3],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<(ErrorEstimate, f64)> {
    let rays = ctx.settings.radiosity.transport_rays;
    let (error, bias) = stages.run(
        StageRun {
            stage: Stage::ErrorEstimate,
            round,
        },
        1,
        || {
            let (e, bias, traced) = hierarchical_error(
                ctx,
                mapper,
                nodes,
                fields,
                direct,
                rays,
                correction_rays(rays),
            );
            let note = format!(
                "{:.2}% ({:.2}% the coarse level's bias) from {}",
                100.0 * e.relative_rms,
                100.0 * bias,
                e.method
            );
            Ok(((e, bias), traced, note))
        },
    )?;
    stages.annotate(RayKind::Closest, Some(error.clone()));
    Ok((error, bias))
}

/// Rays per node of the correction gather: a quarter of the final gather's (at least 4).
/// The field it gathers, ρ(H₁ − C), is a few per cent of the light, so its noise is small at
/// fewer rays.
pub fn correction_rays(gather_rays: u32) -> u32 {
    (gather_rays / 4).max(4)
}

/// A gather stage's note: its rays per node (in words), and the visibility rays of its start
/// points.
pub(super) fn gather_note(per_node: impl std::fmt::Display, rays: GatherRays) -> String {
    format!(
        "{per_node}, {} visibility rays of start points near geometry",
        rays.visibility
    )
}

/// The final gather's result.
struct FinalGather {
    /// H₁ per node, lux.
    light: Vec<Vec3>,
    /// Its standard error per node (luminance, lux).
    error: Vec<f32>,
    /// Each node's rays when they were shared out by noise (`None`: the settings' rays at
    /// every node).
    rays: Option<Vec<u32>>,
    /// The rays per node, in words.
    words: String,
}

/// The final gather H₁ from exitance `b` (`direct`: the direct irradiance per patch, lux),
/// as stages: with at least [`ray_allocation::MIN_ADAPTIVE_RAYS`] rays per node a pilot
/// (`gather pilot`) and the rest of each node's rays by its noise (`final gather`, shared
/// within `coarse`'s cells), else one pass of the settings' rays.
#[allow(clippy::too_many_arguments)]
fn final_gather<'p>(
    ctx: &BakeContext<'_>,
    grid: Grid<'_>,
    b: &[Vec3],
    direct: &[Vec3],
    coarse: &Coarse,
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<FinalGather> {
    let rays = ctx.settings.radiosity.transport_rays;
    let run = |stage: Stage| StageRun { stage, round };
    let nodes = grid.1;
    if ctx.settings.radiosity.cache_spacing > 1 {
        return cached_final_gather(ctx, grid, b, run(Stage::FinalGather), stages);
    }
    let pilot = ray_allocation::pilot_rays(rays).filter(|_| ctx.settings.radiosity.adaptive_gather);
    let Some(pilot) = pilot else {
        let (light, error) = gather_stage(
            ctx,
            grid,
            (b, &|_: usize| 0..rays, Gather::Final),
            run(Stage::FinalGather),
            |r| gather_note(format!("{rays} rays/node"), r),
            stages,
        )?;
        let words = format!("{rays} rays per node");
        return Ok(FinalGather {
            light,
            error,
            rays: None,
            words,
        });
    };
    let (pilot_h, pilot_se) = gather_stage(
        ctx,
        grid,
        (b, &|_: usize| 0..pilot, Gather::Final),
        run(Stage::GatherPilot),
        |r| gather_note(format!("{pilot} rays/node"), r),
        stages,
    )?;
    let light: Vec<f32> = (0..nodes.len())
        .map(|i| luminance(direct[nodes.patch[i] as usize] + pilot_h[i]))
        .collect();
    let cell_of = &coarse.clusters.of_node;
    let allocation = ray_allocation::allocate(nodes, cell_of, &light, &pilot_se, pilot, rays);
    drop(light);
    let (rest_h, rest_se) = gather_stage(
        ctx,
        grid,
        (b, &|i: usize| allocation.rest(i), Gather::Final),
        run(Stage::FinalGather),
        |r| gather_note(allocation.note(), r),
        stages,
    )?;
    let (h, se) = ray_allocation::combine(&allocation, (pilot_h, pilot_se), (&rest_h, &rest_se));
    let (min, max) = allocation.extremes();
    let words = format!(
        "{:.1} rays per node on average ({min} to {max}, by the noise of a pilot of {pilot})",
        allocation.mean(),
    );
    Ok(FinalGather {
        light: h,
        error: se,
        rays: Some(allocation.rays),
        words,
    })
}

/// What a gather stage gathers: the field per node, each node's rays (a range of its
/// sequence) and which gather it is.
type GatherOf<'a> = (&'a [Vec3], &'a (dyn Fn(usize) -> Range<u32> + Sync), Gather);

/// One split gather stage, `run`, over every node of `(mapper, nodes)`: rays `field.1(i)` of
/// node `i`'s sequence gathering `field.0` (a split bake's work folder names its parts by the
/// stage, whatever the round). Gives the light per node and its standard error.
fn gather_stage<'p>(
    ctx: &BakeContext<'_>,
    (mapper, nodes, summary): Grid<'_>,
    (field, rays, gather): GatherOf<'_>,
    run: StageRun,
    note: impl FnOnce(GatherRays) -> String,
    stages: &mut impl StageRunner<'p>,
) -> Result<(Vec<Vec3>, Vec<f32>)> {
    let progress = stages.progress();
    split_stage(
        (nodes, summary),
        run,
        |only| hierarchical::final_gather(ctx, mapper, nodes, field, rays, gather, only, progress),
        note,
        stages,
    )
}

/// A split stage `run` of one value per node: `compute(only)` gives the light and standard
/// error at the nodes `only` marks (`None`: every node) and the rays it traced.
fn split_stage<'p>(
    (nodes, summary): (&Nodes, &[f32]),
    run: StageRun,
    compute: impl Fn(Option<&[bool]>) -> (Vec<Vec3>, Vec<f32>, GatherRays) + Sync,
    note: impl FnOnce(GatherRays) -> String,
    stages: &mut impl StageRunner<'p>,
) -> Result<(Vec<Vec3>, Vec<f32>)> {
    let scope = stages.scope();
    let (h, se, visibility) = stages.run(run, nodes.len() as u64, || {
        let (values, traced) = scope.split(
            run.stage,
            nodes.len(),
            |i| nodes.patch[i] as usize,
            Some(summary),
            |only| {
                let (h, se, traced) = compute(only);
                let values = h.into_iter().zip(se).collect();
                (values, [traced.closest, traced.visibility])
            },
        )?;
        let (h, se): (Vec<Vec3>, Vec<f32>) = values.into_iter().unzip();
        let traced = GatherRays {
            closest: traced[0],
            visibility: traced[1],
        };
        Ok((
            (h, se, traced.visibility),
            traced.closest + traced.visibility,
            note(traced),
        ))
    })?;
    stages.annotate(RayKind::Closest, None);
    stages.shadow_rays(visibility);
    Ok((h, se))
}

/// The final gather H₁ from exitance `b` through the irradiance cache
/// ([`gather_cache`]), as the split stage `run`.
fn cached_final_gather<'p>(
    ctx: &BakeContext<'_>,
    (mapper, nodes, summary): Grid<'_>,
    b: &[Vec3],
    run: StageRun,
    stages: &mut impl StageRunner<'p>,
) -> Result<FinalGather> {
    let r = &ctx.settings.radiosity;
    let options = CacheOptions {
        spacing: r.cache_spacing,
        accuracy: r.cache_accuracy,
        spread: gather_cache::SPREAD,
    };
    let progress = stages.progress();
    let counts = std::sync::Mutex::new(None);
    let (light, error) = split_stage(
        (nodes, summary),
        run,
        |only| {
            let c = gather_cache::cached_gather(
                ctx,
                mapper,
                nodes,
                b,
                r.transport_rays,
                options,
                only,
                progress,
            );
            let traced = GatherRays {
                closest: c.closest,
                visibility: c.visibility,
            };
            let words = (c.record_count(), c.interpolated, c.records.clone());
            *counts.lock().expect("no panic holds it") = Some(words);
            (c.light, c.error, traced)
        },
        |traced| {
            let per_level = counts
                .lock()
                .expect("no panic holds it")
                .take()
                .map_or_else(String::new, |(records, interpolated, levels)| {
                    let levels: Vec<String> =
                        levels.iter().map(|(e, k)| format!("{k} at {e}")).collect();
                    format!(
                        "irradiance cache: {records} records of {} rays ({}), {interpolated} nodes interpolated; ",
                        r.transport_rays,
                        levels.join(", "),
                    )
                });
            format!(
                "{per_level}{}",
                gather_note("", traced).trim_start_matches(", ")
            )
        },
        stages,
    )?;
    let words = format!(
        "{} rays per record of an irradiance cache of {}-texel cells",
        r.transport_rays, r.cache_spacing
    );
    Ok(FinalGather {
        light,
        error,
        rays: None,
        words,
    })
}
