//! The hierarchical solve's gathers as stages: the final gather (a pilot, then each node's
//! rays by its noise: [`ray_allocation`]) and the split of any gather across the shards of a
//! split bake.

use std::ops::Range;

use glam::Vec3;

use super::stages::{Scope, Stages};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::error::Result;
use crate::progress::RayKind;
use crate::radiosity::hierarchical::{self, Gather, GatherRays};
use crate::radiosity::{HitMapper, Nodes, ray_allocation};
use crate::stage::{Stage, StageRun};

/// A gather over every node (`compute(only)` of the nodes `only` marks), its nodes in `scope`
/// by their patches.
pub(super) fn gather_split(
    scope: Scope<'_>,
    stage: Stage,
    nodes: &Nodes,
    compute: impl FnOnce(Option<&[bool]>) -> (Vec<Vec3>, Vec<f32>, GatherRays),
) -> Result<(Vec<Vec3>, Vec<f32>, GatherRays)> {
    let (values, rays) = scope.split(
        stage,
        nodes.len(),
        |i| nodes.patch[i] as usize,
        |only| {
            let (h, se, rays) = compute(only);
            let values = h.into_iter().zip(se).collect();
            (values, [rays.closest, rays.visibility])
        },
    )?;
    let (h, se) = values.into_iter().unzip();
    let rays = GatherRays {
        closest: rays[0],
        visibility: rays[1],
    };
    Ok((h, se, rays))
}

/// Rays per node of the hierarchical solve's correction gather: a quarter of the final
/// gather's (at least 4). The field it gathers, ρ(H₁ − C), is a few per cent of the light,
/// so its noise is small at fewer rays.
pub(super) fn correction_rays(gather_rays: u32) -> u32 {
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
pub(super) struct FinalGather {
    /// H₁ per node, lux.
    pub(super) light: Vec<Vec3>,
    /// Its standard error per node (luminance, lux).
    pub(super) error: Vec<f32>,
    /// Each node's rays when they were shared out by noise (`None`: the settings' rays at
    /// every node).
    pub(super) rays: Option<Vec<u32>>,
    /// The rays per node, in words.
    pub(super) words: String,
}

/// The final gather H₁ from exitance `b` (`direct`: the direct irradiance per patch, lux;
/// `cell_of`: each node's cell of the coarse level),
/// as stages: with at least [`ray_allocation::MIN_ADAPTIVE_RAYS`] rays per node a pilot
/// (`gather pilot`) and the rest of each node's rays by its noise (`final gather`), else one
/// pass of the settings' rays.
#[allow(clippy::too_many_arguments)]
pub(super) fn final_gather(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    direct: &[Vec3],
    cell_of: &[u32],
    round: u32,
    stages: &mut Stages<'_>,
) -> Result<FinalGather> {
    let rays = ctx.settings.transport_rays;
    let stage = |stage: Stage| StageRun { stage, round };
    let pilot = ray_allocation::pilot_rays(rays).filter(|_| ctx.settings.adaptive_gather);
    let Some(pilot) = pilot else {
        let (h, se) = gather_stage(
            ctx,
            mapper,
            nodes,
            b,
            &|_: usize| 0..rays,
            stage(Stage::FinalGather),
            |r| gather_note(format!("{rays} rays/node"), r),
            stages,
        )?;
        return Ok(FinalGather {
            light: h,
            error: se,
            rays: None,
            words: format!("{rays} rays per node"),
        });
    };
    let (pilot_h, pilot_se) = gather_stage(
        ctx,
        mapper,
        nodes,
        b,
        &|_: usize| 0..pilot,
        stage(Stage::GatherPilot),
        |r| gather_note(format!("{pilot} rays/node"), r),
        stages,
    )?;
    let light: Vec<f32> = (0..nodes.len())
        .map(|i| luminance(direct[nodes.patch[i] as usize] + pilot_h[i]))
        .collect();
    let allocation = ray_allocation::allocate(nodes, cell_of, &light, &pilot_se, pilot, rays);
    drop(light);
    let (rest_h, rest_se) = gather_stage(
        ctx,
        mapper,
        nodes,
        b,
        &|i: usize| allocation.rest(i),
        stage(Stage::FinalGather),
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

/// One stage of the final gather, `run`: rays `rays(i)` of every node's sequence (a split
/// bake's work folder names its parts by the stage, whatever the round).
#[allow(clippy::too_many_arguments)]
fn gather_stage(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    rays: &(dyn Fn(usize) -> Range<u32> + Sync),
    run: StageRun,
    note: impl FnOnce(GatherRays) -> String,
    stages: &mut Stages<'_>,
) -> Result<(Vec<Vec3>, Vec<f32>)> {
    let progress = stages.progress();
    let scope = stages.scope();
    let (h, se, visibility) = stages.run(run, nodes.len() as u64, || {
        let (h, se, traced) = gather_split(scope, run.stage, nodes, |only| {
            hierarchical::final_gather(ctx, mapper, nodes, b, rays, Gather::Final, only, progress)
        })?;
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
