//! The hierarchical solve of several light groups at once, their transport shared: light adds
//! up, so every group's reflected light goes through the same operator, and the rays that
//! estimate it are traced once for all of them.
//!
//! First, shared: the coarse level ([`super::hierarchical::coarse_solve_fields`]): one cut,
//! refined until every group's missed detail is within the tolerance, its rows and the
//! oracle's gathers traced once and read in every group's light; each group solves its own
//! coarse system C_g over the shared matrix, and its fine exitance is b_g = ρ(H_d,g + C_g).
//! Then, shared as well:
//!
//! 1. **gather pilot**: every node's pilot rays, each hit read in every group's b_g and in
//!    their sum, each group scaled to the same RMS direct light; the sum's noise shares out
//!    the rest of the rays ([`super::ray_allocation`], pooled within the first group's
//!    cells), so a node gets the rays every group's light needs there, a dim group's as
//!    much as a bright one's;
//! 2. **final gather**: those rays, read in every b_g;
//! 3. **correction** and **reflection**: ρ(H₁,g − C_g) and its reflection, read likewise.
//!
//! Each group's estimate is then exactly the single-field estimator with these rays: unbiased
//! as before, its noise that of its own field over the shared rays. The error estimate runs
//! per group (its re-gathers are a small share of the rays).

use glam::Vec3;

use super::error_estimate::HierarchicalFields;
use super::hierarchical::{self, Coarse, Gather, GatherRays, GatheredField};
use super::hierarchical_solve::{
    HierarchicalRound, coarse_stage_fields, correction_rays, error_stage, finished_round,
    gather_note,
};
use super::{HitMapper, Nodes, ray_allocation};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::error::Result;
use crate::progress::RayKind;
use crate::raster::Patch;
use crate::runner::StageRunner;
use crate::stage::{Stage, StageRun};

/// Per field, the light per node (lux) and its standard error (luminance, lux).
type Fields = Vec<GatheredField>;

/// Each node's rays (a range of its sequence), which gather, and the nodes gathered at
/// (`None`: all).
type RaysOf<'a> = (
    &'a (dyn Fn(usize) -> std::ops::Range<u32> + Sync),
    Gather,
    Option<&'a [bool]>,
);

/// Round `round` of the hierarchical solve for every group at once: `ctxs[g]` is group g's
/// context (its emitters, over the layout, BVH and patches every group shares) and
/// `directs[g]` its direct irradiance per patch (lux). Gives each group's round, as
/// [`super::hierarchical_solve::solve_round`] would with these rays.
///
/// # Errors
/// A cancel.
pub fn solve_round_groups<'p>(
    ctxs: &[BakeContext<'_>],
    nodes: &Nodes,
    directs: &[&[Vec3]],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<Vec<HierarchicalRound>> {
    let Some(ctx) = ctxs.first() else {
        return Ok(Vec::new());
    };
    let mapper = HitMapper::new(*ctx, nodes, ctx.settings.radiosity.basis);
    let coarse = coarse_stage_fields(ctx, &mapper, nodes, directs, round, stages)?;
    let b: Vec<Vec<Vec3>> = (coarse.iter().zip(directs))
        .map(|(c, d)| hierarchical::fine_exitance(nodes, d, &c.clusters, &c.solution.indirect))
        .collect();
    let bs: Vec<&[Vec3]> = b.iter().map(Vec::as_slice).collect();
    let (gathered, allocated, words) =
        final_gather(ctx, &mapper, nodes, &bs, directs, &coarse, round, stages)?;
    let missed: Vec<Vec<Vec3>> = (coarse.iter().zip(&gathered))
        .map(|(c, (h, _))| {
            let per_node = c.clusters.prolong(&c.solution.indirect);
            hierarchical::missed_exitance(nodes, h, &per_node)
        })
        .collect();
    let ms: Vec<&[Vec3]> = missed.iter().map(Vec::as_slice).collect();
    let corrected = correction(ctx, &mapper, nodes, &ms, round, stages)?;
    let mut out = Vec::with_capacity(ctxs.len());
    let parts = ctxs.iter().zip(directs).zip(coarse).zip(b);
    let parts = parts.zip(gathered).zip(missed).zip(corrected);
    for ((((((c, direct), coarse), b), gathered), missed), correction) in parts {
        let mut node_error = gathered.1;
        for (e, ce) in node_error.iter_mut().zip(&correction.1) {
            *e = e.hypot(*ce);
        }
        let (indirect, clamped) = hierarchical::corrected(&gathered.0, &correction.0);
        let fields = HierarchicalFields {
            exitance: &b,
            gathered: &gathered.0,
            missed: &missed,
            correction: &correction.0,
            gather_rays: allocated.as_deref(),
        };
        let estimate = error_stage(c, &mapper, nodes, &fields, direct, round, stages)?;
        let gathers = format!(
            "{words}, shared by {} light groups; correction of {}",
            ctxs.len(),
            correction_rays(c.settings.radiosity.transport_rays)
        );
        let light = (b, indirect, clamped);
        out.push(finished_round(
            coarse, light, &gathers, estimate, node_error,
        ));
    }
    Ok(out)
}

/// One shared gather stage `run`: rays `rays(i)` of node i's sequence, read in every field of
/// `bs` (at the nodes `only` marks). Gives each field's light and standard error per node.
#[allow(clippy::too_many_arguments)]
fn gather_stage<'p>(
    ctx: &BakeContext<'_>,
    (mapper, nodes): (&HitMapper<'_>, &Nodes),
    bs: &[&[Vec3]],
    (rays, gather, only): RaysOf<'_>,
    run: StageRun,
    units: u64,
    note: impl FnOnce(GatherRays) -> String,
    stages: &mut impl StageRunner<'p>,
) -> Result<Fields> {
    let progress = stages.progress();
    let (fields, visibility) = stages.run(run, units, || {
        let (fields, traced) =
            hierarchical::final_gather_fields(ctx, mapper, nodes, bs, rays, gather, only, progress);
        let note = format!("{} fields: {}", bs.len(), note(traced));
        Ok((
            (fields, traced.visibility),
            traced.closest + traced.visibility,
            note,
        ))
    })?;
    stages.annotate(RayKind::Closest, None);
    stages.shadow_rays(visibility);
    Ok(fields)
}

/// The shared final gather (see the module docs): per group H₁ and its standard error, each
/// node's rays when they were shared out by noise, and the rays per node in words.
#[allow(clippy::too_many_arguments)]
fn final_gather<'p>(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    bs: &[&[Vec3]],
    directs: &[&[Vec3]],
    coarse: &[Coarse],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<(Fields, Option<Vec<u32>>, String)> {
    let rays = ctx.settings.radiosity.transport_rays;
    let run = |stage: Stage| StageRun { stage, round };
    let n = nodes.len() as u64;
    let grid = (mapper, nodes);
    let pilot = ray_allocation::pilot_rays(rays).filter(|_| ctx.settings.radiosity.adaptive_gather);
    let Some(pilot) = pilot else {
        let fields = gather_stage(
            ctx,
            grid,
            bs,
            (&|_: usize| 0..rays, Gather::Final, None),
            run(Stage::FinalGather),
            n,
            |r| gather_note(format!("{rays} rays/node"), r),
            stages,
        )?;
        return Ok((fields, None, format!("{rays} rays per node")));
    };
    // The groups' fields and their sum, each group scaled to the same RMS direct light: the
    // sum's noise shares out the rest of the rays, and a dim group's noise (a lamp at night
    // beside the sun) counts as much as a bright one's.
    let scale: Vec<f32> = directs.iter().map(|d| 1.0 / rms(nodes, d)).collect();
    let sum: Vec<Vec3> = (0..nodes.len())
        .map(|i| bs.iter().zip(&scale).map(|(b, w)| b[i] * *w).sum())
        .collect();
    let mut with_sum = bs.to_vec();
    with_sum.push(&sum);
    let mut pilots = gather_stage(
        ctx,
        grid,
        &with_sum,
        (&|_: usize| 0..pilot, Gather::Final, None),
        run(Stage::GatherPilot),
        n,
        |r| gather_note(format!("{pilot} rays/node"), r),
        stages,
    )?;
    let (sum_h, sum_se) = pilots.pop().expect("the sum's field");
    drop(sum);
    let light: Vec<f32> = (0..nodes.len())
        .map(|i| {
            let p = nodes.patch[i] as usize;
            let direct: Vec3 = directs.iter().zip(&scale).map(|(d, w)| d[p] * *w).sum();
            luminance(direct + sum_h[i])
        })
        .collect();
    let cell_of = &coarse[0].clusters.of_node;
    let allocation = ray_allocation::allocate(nodes, cell_of, &light, &sum_se, pilot, rays);
    drop((light, sum_h, sum_se));
    let rest = gather_stage(
        ctx,
        grid,
        bs,
        (&|i: usize| allocation.rest(i), Gather::Final, None),
        run(Stage::FinalGather),
        n,
        |r| gather_note(allocation.note(), r),
        stages,
    )?;
    let fields = (pilots.into_iter().zip(&rest))
        .map(|(p, (h, se))| ray_allocation::combine(&allocation, p, (h, se)))
        .collect();
    let (min, max) = allocation.extremes();
    let words = format!(
        "{:.1} rays per node on average ({min} to {max}, by the noise of a pilot of {pilot})",
        allocation.mean(),
    );
    Ok((fields, Some(allocation.rays), words))
}

/// The RMS luminance of `direct` (per patch, lux) over the nodes; 1 where there is none.
fn rms(nodes: &Nodes, direct: &[Vec3]) -> f32 {
    let n = nodes.patch.len().max(1) as f64;
    let sq: f64 = (nodes.patch.iter())
        .map(|&p| f64::from(luminance(direct[p as usize])).powi(2))
        .sum();
    let r = (sq / n).sqrt() as f32;
    if r > 0.0 && r.is_finite() { r } else { 1.0 }
}

/// The shared correction of every group's missed exitance `missed`, then (near geometry) its
/// own reflection, as two stages: per group the correction and its standard error.
fn correction<'p>(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    missed: &[&[Vec3]],
    round: u32,
    stages: &mut impl StageRunner<'p>,
) -> Result<Fields> {
    let rays = correction_rays(ctx.settings.radiosity.transport_rays);
    let per_node = |_: usize| 0..rays;
    let n = nodes.len() as u64;
    let mut corrections = gather_stage(
        ctx,
        (mapper, nodes),
        missed,
        (&per_node, Gather::Correction, None),
        StageRun {
            stage: Stage::Correction,
            round,
        },
        n,
        |r| gather_note(format!("{rays} rays/node"), r),
        stages,
    )?;
    // Near geometry the correction's own reflection too, as the single field's solve does.
    let near: Vec<bool> = (0..nodes.len())
        .map(|i| ctx.patches.patches[nodes.patch[i] as usize].flags & Patch::NEAR_GEOMETRY != 0)
        .collect();
    let near_count = near.iter().filter(|&&x| x).count() as u64;
    let reflected: Vec<Vec<Vec3>> = (corrections.iter())
        .map(|(c, _)| (0..nodes.len()).map(|i| nodes.albedo[i] * c[i]).collect())
        .collect();
    let rs: Vec<&[Vec3]> = reflected.iter().map(Vec::as_slice).collect();
    let reflections = gather_stage(
        ctx,
        (mapper, nodes),
        &rs,
        (&per_node, Gather::Reflection, Some(&near)),
        StageRun {
            stage: Stage::Reflection,
            round,
        },
        near_count,
        |r| {
            format!(
                "{near_count} nodes near geometry, {}",
                gather_note(format!("{rays} rays/node"), r)
            )
        },
        stages,
    )?;
    for ((c, _), (d, _)) in corrections.iter_mut().zip(reflections) {
        for (a, b) in c.iter_mut().zip(d) {
            *a += b;
        }
    }
    Ok(corrections)
}
