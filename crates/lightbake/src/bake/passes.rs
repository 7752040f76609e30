//! The lighting passes of a bake as stages: direct light, then the indirect light of the
//! method (instant radiosity, or radiosity's nodes, transport, solve and error estimate).
//! With a target error each sampling stage gets an equal share of it (they add in
//! quadrature) and takes rounds until its estimate reaches the share ([`until_target`]).

use glam::Vec3;

use super::stages::{Scope, Stages, scaled, until_target};
use super::{direct_pass_runs, valid};
use crate::context::BakeContext;
use crate::direct::{DirectResult, direct_light_of, error_method};
use crate::error::Result;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lights::Emitters;
use crate::progress::{Progress, RayKind};
use crate::radiosity::hierarchical::CoarseReport;
use crate::radiosity::{self, Nodes, RadiosityReport, hierarchical_solve};
use crate::runner::{StageRunner, WorkScope};
use crate::settings::vpl::MAX_CUT;
use crate::settings::{BakeSettings, MAX_VPL_DEPTH, Method, SolverChoice};
use crate::solve::{Solution, Transport};
use crate::stage::{Stage, StageRun};
use crate::vpl::{FromVpls, VplReport, instant_radiosity};

/// What the lighting passes produced.
pub(super) struct Lighting {
    /// Irradiance per patch, lux: direct plus indirect.
    pub(super) irradiance: Vec<Vec3>,
    /// The sampling stages' error estimates.
    pub(super) errors: Vec<ErrorEstimate>,
    /// Per patch, the standard error of its direct irradiance (luminance, lux).
    pub(super) texel_error: Vec<f32>,
    /// The direct irradiance per patch the lightmap shows (lux: lights baked indirect only
    /// left out), kept for the texel grid's check; empty when that does not run.
    pub(super) direct: Vec<Vec3>,
    /// The indirect irradiance per patch (lux, a part of `irradiance`) and its standard
    /// error (luminance, lux), kept for the denoiser when the indirect pass estimates its
    /// noise texel by texel (the hierarchical solve's gathers) and the denoiser runs.
    pub(super) indirect: Option<(Vec<Vec3>, Vec<f32>)>,
    /// The hierarchical solve's estimated bias from its coarse level (relative RMS).
    pub(super) coarse_bias: Option<f64>,
    pub(super) radiosity: Option<RadiosityReport>,
    pub(super) vpl: Option<VplReport>,
    /// How the indirect light was computed, for the plan.
    pub(super) indirect_reason: Option<String>,
}

/// Runs the direct pass and the method's indirect pass.
pub(super) fn lighting(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lighting> {
    let (mut light, realtime, share) = direct_lighting(ctx, emitters, stages, warnings)?;
    if ctx.plan.runs(Stage::Indirect) {
        indirect(ctx, emitters, share, stages, warnings, &mut light)?;
    }
    without_realtime(&mut light, &realtime);
    Ok(light)
}

/// The direct pass alone: the lighting so far, the part of its irradiance from lights baked
/// indirect only (lux per patch; empty when there are none) and the indirect pass's share of
/// a target error.
pub(super) fn direct_lighting(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<(Lighting, Vec<Vec3>, Option<f64>)> {
    let settings = ctx.settings;
    let direct_runs = direct_pass_runs(settings.method);
    let indirect_runs = ctx.plan.runs(Stage::Indirect);
    let sampling_stages = u32::from(direct_runs) + u32::from(indirect_runs);
    let share = settings
        .target_error
        .map(|t| t as f64 / (sampling_stages.max(1) as f64).sqrt());
    let patches = ctx.patches.patches.len();
    let mut light = Lighting {
        irradiance: vec![Vec3::ZERO; patches],
        errors: Vec::new(),
        texel_error: vec![0.0; patches],
        direct: Vec::new(),
        indirect: None,
        coarse_bias: None,
        radiosity: None,
        vpl: None,
        indirect_reason: None,
    };
    let mut realtime = Vec::new();
    if direct_runs {
        let pass = direct(ctx, emitters, share, stages, warnings)?;
        let shown: Vec<Vec3> = if pass.realtime.is_empty() {
            pass.irradiance.clone()
        } else {
            (pass.irradiance.iter().zip(&pass.realtime))
                .map(|(e, r)| (*e - *r).max(Vec3::ZERO))
                .collect()
        };
        if ctx.plan.runs(Stage::GridError) {
            light.direct = shown.clone();
        }
        stages.preview_direct(ctx, shown);
        light.irradiance = pass.irradiance;
        light.texel_error = pass.texel_error;
        light.errors.extend(pass.error);
        realtime = pass.realtime;
    }
    if !(indirect_runs && settings.method == Method::Radiosity) {
        // No split stage follows (instant radiosity and direct-only bakes): a shard stops.
        stages.scope().stop_after_split()?;
    }
    Ok((light, realtime, share))
}

/// Lights baked indirect only: their direct light fed the interreflections and leaves the
/// lightmaps now (the engine draws it in real time).
pub(super) fn without_realtime(light: &mut Lighting, realtime: &[Vec3]) {
    for (e, r) in light.irradiance.iter_mut().zip(realtime) {
        *e = (*e - *r).max(Vec3::ZERO);
    }
}

/// The method's indirect pass (instant radiosity or radiosity), added to `light`.
fn indirect(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
    light: &mut Lighting,
) -> Result<()> {
    if matches!(ctx.settings.method, Method::Vpl | Method::Hybrid) {
        let FromVpls {
            irradiance: from_vpls,
            report,
            ..
        } = vpl(ctx, emitters, &light.irradiance, share, stages, warnings)?;
        for (e, v) in light.irradiance.iter_mut().zip(&from_vpls) {
            *e += *v;
        }
        light.errors.push(report.error.clone());
        light.indirect_reason = Some(format!(
            "instant radiosity: {} particles ({}), {} VPLs, clamp distance {:.3e} m",
            report.particles, report.particles_reason, report.vpls, report.clamp_distance
        ));
        light.vpl = Some(report);
        return Ok(());
    }
    let reflected = radiosity(ctx, &light.irradiance, share, stages, warnings)?;
    add_reflected(ctx, light, reflected);
    Ok(())
}

/// Adds radiosity's reflected light to `light`, with its error and report.
pub(super) fn add_reflected(ctx: &BakeContext<'_>, light: &mut Lighting, reflected: Reflected) {
    let Reflected {
        irradiance: reflected,
        texel_error,
        report,
        error,
    } = reflected;
    for (e, r) in light.irradiance.iter_mut().zip(&reflected) {
        *e += *r;
    }
    if let Some(re) = texel_error
        && ctx.plan.runs(Stage::Denoise)
    {
        light.indirect = Some((reflected, re));
    }
    light.coarse_bias = report.coarse_bias;
    light.errors.push(error);
    light.indirect_reason = Some(format!(
        "radiosity, solver {}: {}",
        report.solver, report.solver_reason
    ));
    light.radiosity = Some(report);
}

/// What the direct stage gives.
struct DirectPass {
    /// Irradiance per patch, lux.
    irradiance: Vec<Vec3>,
    /// Its standard error per patch (luminance, lux).
    texel_error: Vec<f32>,
    /// The stage's error estimate (none from one sample per texel).
    error: Option<ErrorEstimate>,
    /// The part of the irradiance from lights baked indirect only, lux per patch (empty
    /// when there are none).
    realtime: Vec<Vec3>,
}

/// One round of the direct stage, at the counts of `settings`.
struct DirectRound {
    pass: DirectPass,
    settings: BakeSettings,
    rays: u64,
}

/// The direct stage: irradiance per patch and its error estimate, in rounds towards its
/// share of a target error.
fn direct(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<DirectPass> {
    let mut pilot = ctx.settings.clone();
    if share.is_some() {
        // A variance needs samples to spread: the pilot takes at least 4.
        pilot.direct.samples_per_texel = pilot.direct.samples_per_texel.max(4);
    }
    let (scope, progress) = (stages.scope(), stages.progress());
    let units = ctx.patches.patches.len() as u64;
    let rounds = stages.run(Stage::Direct, units, || {
        let mut rays = 0;
        let rounds = until_target(
            share,
            pilot,
            |s, round| {
                if round > 1 {
                    progress.begin(
                        StageRun {
                            stage: Stage::Direct,
                            round,
                        },
                        units,
                    );
                }
                let r = direct_round(
                    &BakeContext {
                        settings: s,
                        ..*ctx
                    },
                    emitters,
                    scope,
                    progress,
                )?;
                rays += r.rays;
                let relative = r.pass.error.as_ref().map(|e| e.relative_rms);
                Ok((r, relative))
            },
            |s, _, factor| {
                let next = (
                    scaled(s.direct.samples_per_texel, factor, 4096),
                    scaled(s.direct.sky_samples, factor, 65_536),
                );
                let changed = next != (s.direct.samples_per_texel, s.direct.sky_samples);
                (s.direct.samples_per_texel, s.direct.sky_samples) = next;
                changed
            },
        )?;
        let note = direct_note(ctx, emitters, &rounds.value.settings, rounds.round);
        Ok((rounds, rays, note))
    })?;
    let pass = rounds.value.pass;
    if let Some(e) = pass.error.as_ref().filter(|_| rounds.missed) {
        warnings.push(format!(
            "direct light stopped at an estimated {:.2}% error, above its share {:.2}% of the target (sample counts capped or rounds used up)",
            100.0 * e.relative_rms,
            100.0 * share.unwrap_or(0.0)
        ));
    }
    stages.annotate(RayKind::Shadow, pass.error.clone());
    Ok(pass)
}

/// The direct light of every patch at `ctx`'s counts, split across the shards of a split
/// bake (the rounds of a target error are refused there), and its error estimate.
fn direct_round(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    scope: Scope<'_>,
    progress: &Progress,
) -> Result<DirectRound> {
    let patches = ctx.patches;
    let any_realtime = ctx.scene.lights.iter().any(|l| !l.direct_is_baked());
    let (values, split_rays) = scope.split(
        Stage::Direct,
        patches.patches.len(),
        |p| p,
        None,
        |only| {
            let r = direct_light_of(ctx, emitters, only, progress);
            let realtime = |i: usize| r.realtime.get(i).copied().unwrap_or_default();
            let values = (0..r.irradiance.len())
                .map(|i| (r.irradiance[i], r.standard_error[i], realtime(i)))
                .collect();
            (values, [0, r.rays])
        },
    )?;
    let r = DirectResult {
        irradiance: values.iter().map(|v| v.0).collect(),
        standard_error: values.iter().map(|v| v.1).collect(),
        rays: split_rays[1],
        realtime: if any_realtime {
            values.iter().map(|v| v.2).collect()
        } else {
            Vec::new()
        },
    };
    let s = ctx.settings;
    // One sample has no spread: no estimate then.
    let error = (s.direct.samples_per_texel >= 2).then(|| {
        ErrorEstimate::from_standard_errors(
            &valid(patches, &r.standard_error),
            rms_luminance(&valid(patches, &r.irradiance)),
            error_method(s, ctx.plan.sky),
        )
    });
    Ok(DirectRound {
        pass: DirectPass {
            irradiance: r.irradiance,
            texel_error: r.standard_error,
            error,
            realtime: r.realtime,
        },
        settings: s.clone(),
        rays: r.rays,
    })
}

/// The direct stage's note: its counts at `s` after `round` rounds.
fn direct_note(ctx: &BakeContext<'_>, emitters: &Emitters, s: &BakeSettings, round: u32) -> String {
    format!(
        "{} spp, {} light(s), {} emitter triangle(s){}{}",
        s.direct.samples_per_texel,
        ctx.plan.lights.iter().filter(|l| l.instances > 0).count(),
        emitters.list.len(),
        if ctx.plan.sky {
            format!(", {} sky rays/texel", s.direct.sky_samples)
        } else {
            String::new()
        },
        if round > 1 {
            format!(", {round} rounds")
        } else {
            String::new()
        }
    )
}

/// The instant-radiosity stage: irradiance per patch from the VPLs (all of it for method
/// `vpl`, the indirect part for `hybrid`) and the report.
fn vpl(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    direct: &[Vec3],
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<FromVpls> {
    let settings = ctx.settings;
    let vpl_only = settings.method == Method::Vpl;
    let progress = stages.progress();
    let got = stages.run(Stage::Vpl, ctx.patches.patches.len() as u64, || {
        let direct = (!vpl_only).then_some(direct);
        let mut rays = 0;
        let rounds = until_target(
            share,
            settings.clone(),
            |s, _| {
                let c = BakeContext {
                    settings: s,
                    ..*ctx
                };
                let got = instant_radiosity(&c, emitters, vpl_only, direct, progress);
                rays += got.rays;
                let relative = got.report.error.relative_rms;
                Ok((got, Some(relative)))
            },
            |s, FromVpls { report, .. }, factor| {
                s.vpl.time_budget_s = None;
                if report.cut_size > 0 {
                    // Through cuts the picks' noise is raised by the cut alone: more
                    // particles would outgrow the memory the plan admitted for the VPLs.
                    let next = scaled(report.cut_size, factor, MAX_CUT);
                    s.vpl.cut_size = next;
                    return next != report.cut_size;
                }
                let next = scaled(report.particles, factor, 10_000_000);
                s.vpl.particles = next;
                next != report.particles
            },
        )?;
        let note = vpl_note(&rounds.value.report, rounds.round);
        Ok((rounds.value, rays, note))
    })?;
    vpl_warnings(settings, &got.report, share, warnings);
    stages.annotate(RayKind::Shadow, Some(got.report.error.clone()));
    Ok(got)
}

/// The instant-radiosity stage's note after `round` rounds.
fn vpl_note(report: &VplReport, round: u32) -> String {
    format!(
        "{} particles, {} VPLs (ρ̄ {:.3}){}, {:.1}% clamped{}{}",
        report.particles,
        report.vpls,
        report.mean_reflectivity,
        if report.cut_size > 0 {
            format!(", cuts of {} nodes", report.cut_size)
        } else {
            String::new()
        },
        100.0 * report.clamped_fraction,
        if report.compensated {
            format!(
                ", compensated ({} iterations)",
                report.compensation_iterations
            )
        } else {
            String::new()
        },
        if round > 1 {
            format!(", {round} rounds")
        } else {
            String::new()
        }
    )
}

/// What instant radiosity leaves out or could not reach, as warnings: the bias
/// compensation's note, the light beyond the deepest reflection, a missed target share.
fn vpl_warnings(
    settings: &BakeSettings,
    report: &VplReport,
    share: Option<f64>,
    warnings: &mut Vec<String>,
) {
    if let Some(note) = &report.compensation_note {
        warnings.push(note.clone());
    }
    // Keller's walk follows at most `vpl.max_depth` reflections: in a closed scene the light
    // beyond them is ρ̄^(d+1) of the total, and it is not baked.
    let depth = settings.vpl.max_depth.min(MAX_VPL_DEPTH);
    let lost = (report.mean_reflectivity as f64).powi(depth as i32 + 1);
    if lost > 0.01 {
        warnings.push(format!(
            "instant radiosity follows at most {depth} reflections; with mean reflectivity {:.3} the light beyond them, up to {:.1}% of the total in a closed scene, is not baked (raise vpl.max_depth, --vpl-max-depth, at most {MAX_VPL_DEPTH}, or use the radiosity method)",
            report.mean_reflectivity,
            100.0 * lost,
        ));
    }
    if let Some(t) = share.filter(|&t| report.error.relative_rms > t) {
        warnings.push(format!(
            "instant radiosity stopped at an estimated {:.2}% error, above its share {:.2}% of the target",
            100.0 * report.error.relative_rms,
            100.0 * t
        ));
    }
}

/// One radiosity round's result.
pub(super) struct Solved {
    pub(super) plan: radiosity::SolverPlan,
    pub(super) transport: Option<Transport>,
    pub(super) solution: Solution,
    pub(super) error: ErrorEstimate,
    /// The hierarchical solve's coarse level and its estimated bias (relative RMS).
    pub(super) coarse: Option<(CoarseReport, f64)>,
    /// Per node, the standard error of its reflected irradiance (luminance, lux), where the
    /// solver estimates it node by node (the hierarchical solve's gathers).
    pub(super) node_error: Option<Vec<f32>>,
}

/// What the radiosity stages give.
pub(super) struct Reflected {
    /// Reflected irradiance per patch, lux.
    irradiance: Vec<Vec3>,
    /// Its standard error per patch (luminance, lux), when the solver estimates it node by
    /// node (the hierarchical solve's gathers).
    texel_error: Option<Vec<f32>>,
    report: RadiosityReport,
    error: ErrorEstimate,
}

/// The radiosity stages (nodes, then rounds of transport, solve and error estimate towards
/// the stage's share of a target error).
fn radiosity(
    ctx: &BakeContext<'_>,
    direct: &[Vec3],
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Reflected> {
    let nodes = radiosity_nodes(ctx, stages)?;
    radiosity_over(ctx, &nodes, direct, share, stages, warnings)
}

/// The radiosity nodes, as a stage ([`radiosity::basis::nodes_stage`]).
pub(super) fn radiosity_nodes(ctx: &BakeContext<'_>, stages: &mut Stages<'_>) -> Result<Nodes> {
    radiosity::basis::nodes_stage(ctx, stages)
}

/// Rounds of transport, solve and error estimate over `nodes` towards the stage's share of a
/// target error.
pub(super) fn radiosity_over(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    direct: &[Vec3],
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Reflected> {
    let settings = ctx.settings;
    let mut s = settings.clone();
    if let Some(t) = settings.target_error {
        s.radiosity.solver_tolerance = s.radiosity.solver_tolerance.min(t as f64 / 4.0);
    }
    let tolerance = s.radiosity.solver_tolerance;
    let rounds = until_target(
        share,
        s,
        |s, round| {
            let c = BakeContext {
                settings: s,
                ..*ctx
            };
            let solved = radiosity_round(&c, nodes, direct, round, stages)?;
            let relative = solved.error.relative_rms;
            Ok((solved, Some(relative)))
        },
        |s, solved, factor| {
            if solved.coarse.is_some() {
                // The final gather's rays set its noise; the coarse level's tolerance its
                // bias: both are tightened by the same factor of error.
                let next = scaled(s.radiosity.transport_rays, factor, 65_536);
                let tolerance = (s.radiosity.cluster_tolerance / factor.sqrt()).max(1e-4);
                let changed = next != s.radiosity.transport_rays
                    || tolerance != s.radiosity.cluster_tolerance;
                (s.radiosity.transport_rays, s.radiosity.cluster_tolerance) = (next, tolerance);
                return changed;
            }
            // The count that sets the noise: form-factor rays, or the shooting's rays.
            let count = if solved.transport.is_some() {
                &mut s.radiosity.transport_rays
            } else {
                &mut s.radiosity.stochastic_rays_per_node
            };
            let next = scaled(*count, factor, 65_536);
            let changed = next != *count;
            *count = next;
            changed
        },
    )?;
    if rounds.missed {
        warnings.push(format!(
            "radiosity stopped at an estimated {:.2}% error, above its share {:.2}% of the target",
            100.0 * rounds.value.error.relative_rms,
            100.0 * share.unwrap_or(0.0)
        ));
    }
    let solution = &rounds.value.solution;
    if settings.radiosity.cache_spacing > 0 && rounds.value.coarse.is_none() {
        warnings.push(format!(
            "the irradiance cache (radiosity.cache_spacing, --gather-cache) is the hierarchical \
             solve's final gather; the {} solver was chosen ({}), so every node was gathered",
            solution.solver, rounds.value.plan.reason
        ));
    }
    if !solution.converged {
        warnings.push(format!(
            "the {} solver did not reach the tolerance {tolerance:.1e}: {}",
            solution.solver, solution.stop_reason
        ));
    }
    Ok(reflected(ctx, nodes, rounds.value))
}

/// The solved round `solved` per patch, and its report (which outlives the lighting
/// passes, so it keeps no per-node vectors).
pub(super) fn reflected(ctx: &BakeContext<'_>, nodes: &Nodes, solved: Solved) -> Reflected {
    let Solved {
        plan,
        transport,
        mut solution,
        error,
        coarse,
        node_error,
    } = solved;
    let patches = ctx.patches.patches.len();
    let irradiance = radiosity::per_patch(nodes, &solution.indirect, patches);
    let texel_error = node_error.map(|e| {
        let mut out = vec![0.0f32; patches];
        for (n, &p) in nodes.patch.iter().enumerate() {
            out[p as usize] = e[n];
        }
        out
    });
    solution.b = Vec::new();
    solution.indirect = Vec::new();
    let report = RadiosityReport {
        solver: solution.solver,
        solver_reason: plan.reason.clone(),
        basis: ctx.settings.radiosity.basis,
        nodes: nodes.len(),
        max_albedo: nodes.max_albedo(),
        transport_nnz: transport.as_ref().map_or(0, Transport::nnz),
        transport_bytes: transport.as_ref().map_or(0, Transport::bytes),
        transport_estimate_bytes: plan.transport_estimate_bytes,
        solver_working_bytes: plan.solver_working_bytes,
        solution,
        coarse_bias: coarse.as_ref().map(|c| c.1),
        coarse: coarse.map(|c| c.0),
    };
    Reflected {
        irradiance,
        texel_error,
        report,
        error,
    }
}

/// One round of radiosity at `ctx`'s counts: the solver plan, the transport matrix (when the
/// solver needs one), the solve and the error estimate, each a stage (`#round` appended
/// after the first round).
fn radiosity_round(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    direct: &[Vec3],
    round: u32,
    stages: &mut Stages<'_>,
) -> Result<Solved> {
    let s = ctx.settings;
    let progress = stages.progress();
    let at = |stage: Stage| StageRun { stage, round };
    let plan = radiosity::plan_solver(ctx, nodes)?;
    if plan.choice == SolverChoice::Hierarchical {
        let r = hierarchical_solve::solve_round(ctx, nodes, direct, round, stages)?;
        return Ok(Solved {
            plan,
            transport: None,
            solution: r.solution,
            error: r.error,
            coarse: Some((r.coarse, r.bias)),
            node_error: Some(r.node_error),
        });
    }
    // The matrix solvers' stages are not split: a shard stops, the merge runs them.
    stages.scope().stop_after_split()?;
    let source = radiosity::source(nodes, direct);
    let transport = if plan.choice.needs_matrix() {
        Some(stages.run(at(Stage::Transport), nodes.len() as u64, || {
            let t = radiosity::build_transport(ctx, nodes, progress);
            let note = format!(
                "{} rays/node, {} entries, {:.1} MiB (estimated {:.1})",
                s.radiosity.transport_rays,
                t.nnz(),
                t.bytes() as f64 / 1048576.0,
                plan.transport_estimate_bytes as f64 / 1048576.0
            );
            let rays = t.rays;
            Ok((t, rays, note))
        })?)
    } else {
        None
    };
    let solution = stages.run(at(Stage::Solve), 0, || {
        let sol = radiosity::solve_system(ctx, nodes, &plan, transport.as_ref(), &source, progress);
        let note = format!("{}: {}", sol.solver, sol.stop_reason);
        let rays = sol.rays;
        Ok((sol, rays, note))
    })?;
    // The preview of the solve, with the ambient term of its residual (stochastic Jacobi
    // keeps no matrix to take one).
    if stages.previewing() {
        let ambient = transport.as_ref().map_or(Vec3::ZERO, |t| {
            radiosity::system(t, nodes, &source).ambient_term(&crate::solve::to_f64(&solution.b))
        });
        let indirect = radiosity::per_patch(nodes, &solution.indirect, ctx.patches.patches.len());
        stages.preview_indirect(ctx, &indirect, ambient);
    }
    // The Monte Carlo error of the matrix rows, or of stochastic Jacobi's shooting.
    let error = stages.run(at(Stage::ErrorEstimate), 1, || {
        let (e, rays) = radiosity::gather_error(
            ctx,
            nodes,
            &solution.b,
            &solution.indirect,
            direct,
            s.radiosity.transport_rays,
        );
        let note = format!("{:.2}% from {}", 100.0 * e.relative_rms, e.method);
        Ok((e, rays, note))
    })?;
    stages.annotate(RayKind::Closest, Some(error.clone()));
    Ok(Solved {
        plan,
        transport,
        solution,
        error,
        coarse: None,
        node_error: None,
    })
}
