//! The lighting passes of a bake as stages: direct light, then the indirect light of the
//! method (instant radiosity, or radiosity's nodes, transport, solve and error estimate).
//! With a target error each sampling stage gets an equal share of it (they add in
//! quadrature) and takes rounds until its estimate reaches the share ([`until_target`]).

use glam::Vec3;

use super::stages::{Stages, scaled, until_target};
use super::{direct_pass_runs, valid};
use crate::context::BakeContext;
use crate::direct::{DirectResult, direct_light_of, error_method};
use crate::error::Result;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lights::Emitters;
use crate::progress::RayKind;
use crate::radiosity::hierarchical::CoarseReport;
use crate::radiosity::{self, Nodes, RadiosityReport, hierarchical_solve};
use crate::runner::{StageRunner, WorkScope};
use crate::settings::{MAX_VPL_DEPTH, Method, SolverChoice};
use crate::solve::{Solution, Transport};
use crate::stage::{Stage, StageRun};
use crate::vpl::{VplReport, instant_radiosity};

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
    let settings = ctx.settings;
    let direct_runs = direct_pass_runs(settings.method);
    let indirect_runs = ctx.plan.runs(Stage::Indirect);
    let sampling_stages = u32::from(direct_runs) + u32::from(indirect_runs);
    let share = settings
        .target_error
        .map(|t| t as f64 / (sampling_stages.max(1) as f64).sqrt());
    let mut light = Lighting {
        irradiance: vec![Vec3::ZERO; ctx.patches.patches.len()],
        errors: Vec::new(),
        texel_error: vec![0.0; ctx.patches.patches.len()],
        direct: Vec::new(),
        indirect: None,
        coarse_bias: None,
        radiosity: None,
        vpl: None,
        indirect_reason: None,
    };
    let mut realtime = Vec::new();
    if direct_runs {
        let (irradiance, texel_error, error, rt) = direct(ctx, emitters, share, stages, warnings)?;
        light.irradiance = irradiance;
        light.texel_error = texel_error;
        light.errors.extend(error);
        realtime = rt;
        let shown: Vec<Vec3> = if realtime.is_empty() {
            light.irradiance.clone()
        } else {
            light
                .irradiance
                .iter()
                .zip(&realtime)
                .map(|(e, r)| (*e - *r).max(Vec3::ZERO))
                .collect()
        };
        if ctx.plan.runs(Stage::GridError) {
            light.direct = shown.clone();
        }
        stages.preview_direct(ctx, shown);
    }
    if !(indirect_runs && settings.method == Method::Radiosity) {
        // No split stage follows (instant radiosity and direct-only bakes): a shard stops.
        stages.scope().stop_after_split()?;
    }
    if indirect_runs && matches!(settings.method, Method::Vpl | Method::Hybrid) {
        let (from_vpls, report) = vpl(ctx, emitters, &light.irradiance, share, stages, warnings)?;
        for (e, v) in light.irradiance.iter_mut().zip(&from_vpls) {
            *e += *v;
        }
        light.errors.push(report.error.clone());
        light.indirect_reason = Some(format!(
            "instant radiosity: {} particles ({}), {} VPLs, clamp distance {:.3e} m",
            report.particles, report.particles_reason, report.vpls, report.clamp_distance
        ));
        light.vpl = Some(report);
    } else if indirect_runs {
        let (reflected, reflected_error, report, error) =
            radiosity(ctx, &light.irradiance, share, stages, warnings)?;
        for (e, r) in light.irradiance.iter_mut().zip(&reflected) {
            *e += *r;
        }
        if let Some(re) = reflected_error
            && ctx.plan.runs(Stage::Denoise)
        {
            light.indirect = Some((reflected, re));
        }
        light.coarse_bias = report.coarse_bias;
        light.errors.extend(error);
        light.indirect_reason = Some(format!(
            "radiosity, solver {}: {}",
            report.solver, report.solver_reason
        ));
        light.radiosity = Some(report);
    }
    // Lights baked indirect only: their direct light fed the interreflections above and
    // leaves the lightmaps now (the engine draws it in real time).
    for (e, r) in light.irradiance.iter_mut().zip(&realtime) {
        *e = (*e - *r).max(Vec3::ZERO);
    }
    Ok(light)
}

/// The direct stage's irradiance per patch, its per-patch standard error, its error
/// estimate, and the part of the irradiance from lights baked indirect only.
type DirectPass = (Vec<Vec3>, Vec<f32>, Option<ErrorEstimate>, Vec<Vec3>);

/// The direct stage: irradiance per patch and its error estimate.
fn direct(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<DirectPass> {
    let patches = ctx.patches;
    let progress = stages.progress();
    let mut pilot = ctx.settings.clone();
    if share.is_some() {
        // A variance needs samples to spread: the pilot takes at least 4.
        pilot.direct.samples_per_texel = pilot.direct.samples_per_texel.max(4);
    }
    let scope = stages.scope();
    let any_realtime = ctx.scene.lights.iter().any(|l| !l.direct_is_baked());
    let rounds = stages.run(Stage::Direct, patches.patches.len() as u64, || {
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
                        patches.patches.len() as u64,
                    );
                }
                let c = BakeContext {
                    settings: s,
                    ..*ctx
                };
                // Split across the shards of a split bake (the rounds of a target error are
                // refused there).
                let (values, split_rays) = scope.split(
                    Stage::Direct,
                    patches.patches.len(),
                    |p| p,
                    |only| {
                        let r = direct_light_of(&c, emitters, only, progress);
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
                rays += r.rays;
                // One sample has no spread: no estimate then.
                let est = (s.direct.samples_per_texel >= 2).then(|| {
                    ErrorEstimate::from_standard_errors(
                        &valid(patches, &r.standard_error),
                        rms_luminance(&valid(patches, &r.irradiance)),
                        error_method(s, ctx.plan.sky),
                    )
                });
                let relative = est.as_ref().map(|e| e.relative_rms);
                Ok((
                    (r.irradiance, r.standard_error, est, s.clone(), r.realtime),
                    relative,
                ))
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
        let s = &rounds.value.3;
        let note = format!(
            "{} spp, {} light(s), {} emitter triangle(s){}{}",
            s.direct.samples_per_texel,
            ctx.plan.lights.iter().filter(|l| l.instances > 0).count(),
            emitters.list.len(),
            if ctx.plan.sky {
                format!(", {} sky rays/texel", s.direct.sky_samples)
            } else {
                String::new()
            },
            if rounds.round > 1 {
                format!(", {} rounds", rounds.round)
            } else {
                String::new()
            }
        );
        Ok((rounds, rays, note))
    })?;
    let (irradiance, texel_error, error, _, realtime) = rounds.value;
    if let Some(e) = error.as_ref().filter(|_| rounds.missed) {
        warnings.push(format!(
            "direct light stopped at an estimated {:.2}% error, above its share {:.2}% of the target (sample counts capped or rounds used up)",
            100.0 * e.relative_rms,
            100.0 * share.unwrap_or(0.0)
        ));
    }
    stages.annotate(RayKind::Shadow, error.clone());
    Ok((irradiance, texel_error, error, realtime))
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
) -> Result<(Vec<Vec3>, VplReport)> {
    let settings = ctx.settings;
    let vpl_only = settings.method == Method::Vpl;
    let progress = stages.progress();
    let (from_vpls, report) = stages.run(Stage::Vpl, ctx.patches.patches.len() as u64, || {
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
                let (e, report, r) = instant_radiosity(&c, emitters, vpl_only, direct, progress);
                rays += r;
                let relative = report.error.relative_rms;
                Ok(((e, report), Some(relative)))
            },
            |s, (_, report), factor| {
                let next = scaled(report.particles, factor, 10_000_000);
                s.vpl.particles = next;
                s.vpl.time_budget_s = None;
                next != report.particles
            },
        )?;
        let (e, report) = rounds.value;
        let note = format!(
            "{} particles, {} VPLs (ρ̄ {:.3}), {:.1}% clamped{}{}",
            report.particles,
            report.vpls,
            report.mean_reflectivity,
            100.0 * report.clamped_fraction,
            if report.compensated {
                format!(
                    ", compensated ({} iterations)",
                    report.compensation_iterations
                )
            } else {
                String::new()
            },
            if rounds.round > 1 {
                format!(", {} rounds", rounds.round)
            } else {
                String::new()
            }
        );
        Ok(((e, report), rays, note))
    })?;
    if let Some(note) = &report.compensation_note {
        warnings.push(note.clone());
    }
    // Keller's walk follows at most `vpl_max_depth` reflections: in a closed scene the light
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
    stages.annotate(RayKind::Shadow, Some(report.error.clone()));
    Ok((from_vpls, report))
}

/// One radiosity round's result.
struct Solved {
    plan: radiosity::SolverPlan,
    transport: Option<Transport>,
    solution: Solution,
    error: ErrorEstimate,
    /// The hierarchical solve's coarse level and its estimated bias (relative RMS).
    coarse: Option<(CoarseReport, f64)>,
    /// Per node, the standard error of its reflected irradiance (luminance, lux), where the
    /// solver estimates it node by node (the hierarchical solve's gathers).
    node_error: Option<Vec<f32>>,
}

/// Per-patch reflected irradiance and its per-patch standard error (when the solver gives
/// one), the report and the error estimate.
type RadiosityResult = (
    Vec<Vec3>,
    Option<Vec<f32>>,
    RadiosityReport,
    Option<ErrorEstimate>,
);

/// The radiosity stages (nodes, transport, solve, error estimate): reflected irradiance per
/// patch, its standard error per patch, the report and the error estimate.
fn radiosity(
    ctx: &BakeContext<'_>,
    direct: &[Vec3],
    share: Option<f64>,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<RadiosityResult> {
    let settings = ctx.settings;
    let nodes = stages.run(Stage::Nodes, 1, || {
        let nodes = Nodes::new(ctx, settings.radiosity.basis);
        let note = format!(
            "{} nodes, max albedo {:.3}",
            nodes.len(),
            nodes.max_albedo()
        );
        Ok((nodes, 0, note))
    })?;
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
            let solved = radiosity_round(&c, &nodes, direct, round, stages)?;
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
    let Solved {
        plan,
        transport,
        mut solution,
        error,
        coarse,
        node_error,
    } = rounds.value;
    if rounds.missed {
        warnings.push(format!(
            "radiosity stopped at an estimated {:.2}% error, above its share {:.2}% of the target",
            100.0 * error.relative_rms,
            100.0 * share.unwrap_or(0.0)
        ));
    }
    if !solution.converged {
        warnings.push(format!(
            "the {} solver did not reach the tolerance {tolerance:.1e}: {}",
            solution.solver, solution.stop_reason
        ));
    }
    let reflected = radiosity::per_patch(&nodes, &solution.indirect, ctx.patches.patches.len());
    let reflected_error = node_error.map(|e| {
        let mut out = vec![0.0f32; ctx.patches.patches.len()];
        for (n, &p) in nodes.patch.iter().enumerate() {
            out[p as usize] = e[n];
        }
        out
    });
    // The report outlives the lighting passes: it keeps no per-node vectors.
    solution.b = Vec::new();
    solution.indirect = Vec::new();
    let report = RadiosityReport {
        solver: solution.solver,
        solver_reason: plan.reason.clone(),
        basis: settings.radiosity.basis,
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
    Ok((reflected, reflected_error, report, Some(error)))
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
