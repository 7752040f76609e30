//! The light groups' lighting passes with their transport shared
//! ([`crate::radiosity::group_solve`]): every group's direct pass, then one radiosity pass for
//! all of them — one set of nodes, one coarse level (its cut, rows and oracle traced once,
//! each group's own solve), and the hierarchical solve's gathers traced once and read in
//! every group's light. Their stages are marked in the stage table: `[NAME]` for a
//! group's own, `[shared]` for those of every group.

use glam::Vec3;

use super::passes::{
    Lighting, Solved, add_reflected, direct_lighting, radiosity_nodes, radiosity_over, reflected,
    without_realtime,
};
use super::stages::Stages;
use crate::context::BakeContext;
use crate::error::Result;
use crate::lights::Emitters;
use crate::radiosity::{self, group_solve};
use crate::runner::StageRunner;
use crate::settings::{Method, SolverChoice};
use crate::stage::Stage;

/// Whether light groups at `ctx` share their transport: radiosity in one round (no target
/// error) gathering every node (no irradiance cache), in one process (not a split bake's
/// shard, not a subset of the texels).
pub(super) fn shares_transport(ctx: &BakeContext<'_>, stages: &Stages<'_>) -> bool {
    let r = &ctx.settings.radiosity;
    ctx.settings.method == Method::Radiosity
        && ctx.settings.target_error.is_none()
        && r.cache_spacing <= 1
        && stages.scope().split_bake().is_none()
        && stages.scope().texel_run().is_none()
}

/// What each group's stages cost: seconds and rays of the stages marked with its name.
pub(super) struct GroupCost {
    pub(super) seconds: f64,
    pub(super) rays: u64,
}

/// The lighting passes of every group (`ctxs[g]`, `emitters[g]`, `names[g]`; its warnings
/// into `warnings[g]`, the bake's own into `general`), their radiosity shared when the solver is hierarchical (else each
/// group's solve runs over the one set of nodes). Gives each group's lighting and the cost
/// of its own stages.
pub(super) fn lighting_groups(
    ctxs: &[BakeContext<'_>],
    emitters: &[Emitters],
    names: &[&str],
    stages: &mut Stages<'_>,
    (warnings, general): (&mut [Vec<String>], &mut Vec<String>),
) -> Result<(Vec<Lighting>, Vec<GroupCost>)> {
    // Whose each stage from here is (`None`: shared).
    let start = stages.list.len();
    let mut owner: Vec<Option<usize>> = Vec::new();
    let mark = |stages: &Stages<'_>, owner: &mut Vec<Option<usize>>, g: Option<usize>| {
        owner.resize(stages.list.len() - start, g);
    };
    let mut parts = Vec::with_capacity(ctxs.len());
    for (g, (ctx, e)) in ctxs.iter().zip(emitters).enumerate() {
        parts.push(direct_lighting(ctx, e, stages, &mut warnings[g])?);
        mark(stages, &mut owner, Some(g));
    }
    let runs: Vec<usize> = (0..ctxs.len())
        .filter(|&g| ctxs[g].plan.runs(Stage::Indirect))
        .collect();
    if let Some(&first) = runs.first() {
        let nodes = radiosity_nodes(&ctxs[first], stages)?;
        mark(stages, &mut owner, None);
        let plan = radiosity::plan_solver(&ctxs[first], &nodes)?;
        let (needed, budget) = radiosity::groups_bytes(&ctxs[first], &nodes, runs.len());
        let hierarchical = plan.choice == SolverChoice::Hierarchical;
        if hierarchical && runs.len() > 1 && needed > budget {
            general.push(format!(
                "the {} light groups' shared radiosity would hold {:.0} MiB, over the solvers' {:.0} MiB: each group's radiosity ran on its own (the same light, at each group's full cost)",
                runs.len(),
                needed as f64 / 1048576.0,
                budget as f64 / 1048576.0
            ));
        }
        if hierarchical && runs.len() > 1 && needed <= budget {
            let group_ctxs: Vec<BakeContext<'_>> = runs.iter().map(|&g| ctxs[g]).collect();
            let directs: Vec<&[Vec3]> = (runs.iter())
                .map(|&g| parts[g].0.irradiance.as_slice())
                .collect();
            let from = stages.list.len();
            let rounds = group_solve::solve_round_groups(&group_ctxs, &nodes, &directs, 1, stages)?;
            drop(directs);
            // A group's own stages in the solve: its error estimate, in the order of the
            // groups; the coarse level and the gathers are shared.
            let mut estimates = runs.iter();
            for s in &stages.list[from..] {
                let own = match s.run.stage {
                    Stage::ErrorEstimate => estimates.next(),
                    _ => None,
                };
                owner.push(own.copied());
            }
            for (&g, r) in runs.iter().zip(rounds) {
                if !r.solution.converged {
                    warnings[g].push(format!(
                        "the hierarchical solver did not reach the tolerance {:.1e}: {}",
                        ctxs[g].settings.radiosity.solver_tolerance, r.solution.stop_reason
                    ));
                }
                let solved = Solved {
                    plan: plan.clone(),
                    transport: None,
                    solution: r.solution,
                    error: r.error,
                    coarse: Some((r.coarse, r.bias)),
                    node_error: Some(r.node_error),
                };
                let got = reflected(&ctxs[g], &nodes, solved);
                add_reflected(&ctxs[g], &mut parts[g].0, got);
            }
        } else {
            for &g in &runs {
                let (light, _, share) = &parts[g];
                let got = radiosity_over(
                    &ctxs[g],
                    &nodes,
                    &light.irradiance,
                    *share,
                    stages,
                    &mut warnings[g],
                )?;
                add_reflected(&ctxs[g], &mut parts[g].0, got);
                mark(stages, &mut owner, Some(g));
            }
        }
    }
    let mut costs: Vec<GroupCost> = (0..ctxs.len())
        .map(|_| GroupCost {
            seconds: 0.0,
            rays: 0,
        })
        .collect();
    for (s, own) in stages.list[start..].iter_mut().zip(&owner) {
        let tag = match own {
            Some(g) => {
                costs[*g].seconds += s.seconds;
                costs[*g].rays += s.rays;
                names[*g]
            }
            None => "shared",
        };
        s.note = format!("[{tag}] {}", s.note);
    }
    let lights = (parts.into_iter())
        .map(|(mut light, realtime, _)| {
            without_realtime(&mut light, &realtime);
            light
        })
        .collect();
    Ok((lights, costs))
}
