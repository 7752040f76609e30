//! The pipeline: plan → memory check → unwrap → texel patches → BVH → validity → direct
//! light → pages (fill, dilate). Each stage runs only when the plan says the scene needs it.
//!
//! [`bake`] works in memory and returns [`BakeOutput`]; [`crate::output::write_outputs`]
//! writes it. Work runs on a rayon pool of `settings.threads` threads; the result does not
//! depend on the thread count.

use std::time::Instant;

use glam::Vec3;

use crate::bvh::RayScene;
use crate::bvh::workload::{RayRates, calibrate};
use crate::direct::{Emitters, direct_light};
use crate::error::{BakeError, Result};
use crate::estimate::{ErrorEstimate, rms_luminance};
use crate::indirect::{self, IndirectReport};
use crate::lightmap::{LightmapPage, assemble};
use crate::memory;
use crate::plan::BakePlan;
use crate::progress::Progress;
use crate::raster::Patches;
use crate::report::{BakeReport, Floor, RayKind, StageStats, TexelStats};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::settings::Method;
use crate::transport::{Nodes, Transport};
use crate::unwrap::{Layout, unwrap_scene};
use crate::vpl::instant_radiosity;

/// Rays of each kind the floor calibration traces.
const CALIBRATION_RAYS: usize = 65_536;

/// What every lighting pass reads: the unwrapped scene, its layout, the ray-tracing structure,
/// the texel patches, the settings and the plan.
#[derive(Clone, Copy)]
pub struct BakeContext<'a> {
    /// The unwrapped scene ([`Layout::apply`]).
    pub scene: &'a Scene,
    /// Lightmap layout.
    pub layout: &'a Layout,
    /// Ray queries.
    pub rays: &'a RayScene,
    /// Texel patches (validated).
    pub patches: &'a Patches,
    /// Settings.
    pub settings: &'a BakeSettings,
    /// The plan.
    pub plan: &'a BakePlan,
}

/// Everything a bake produces, in memory.
#[derive(Clone, Debug)]
pub struct BakeOutput {
    /// The lightmap layout: per-mesh UVs and per-instance rectangles.
    pub layout: Layout,
    /// The scene as baked: meshes split along seams, `uv1` set.
    pub baked_scene: Scene,
    /// Lightmap pages (E/π, linear RGB).
    pub pages: Vec<LightmapPage>,
    /// Timings, counts, plan and warnings.
    pub report: BakeReport,
}

/// Bakes `scene` with `settings`, reporting progress to (and obeying cancellation from)
/// `progress`.
///
/// # Errors
/// Invalid settings or scene ([`BakeError::BadSetting`] and the scene errors),
/// [`BakeError::OverMemoryBudget`], [`BakeError::Unwrap`], [`BakeError::Cancelled`].
pub fn bake(scene: &Scene, settings: &BakeSettings, progress: &Progress) -> Result<BakeOutput> {
    settings.validate()?;
    scene.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(settings.threads)
        .build()
        .map_err(|e| BakeError::BadSetting {
            name: "threads",
            value: settings.threads.to_string(),
            message: e.to_string(),
        })?;
    pool.install(|| bake_in_pool(scene, settings, progress, pool.current_num_threads()))
}

struct Stages {
    list: Vec<StageStats>,
}

impl Stages {
    fn run<T>(
        &mut self,
        name: &str,
        progress: &Progress,
        total: u64,
        f: impl FnOnce() -> Result<(T, u64, String)>,
    ) -> Result<T> {
        progress.begin(name, total);
        let start = Instant::now();
        let (value, rays, note) = f()?;
        self.list.push(StageStats {
            name: name.to_string(),
            seconds: start.elapsed().as_secs_f64(),
            rays,
            ray_kind: if rays > 0 {
                RayKind::Closest
            } else {
                RayKind::None
            },
            error: None,
            note,
        });
        progress.record_stage(self.list.len() - 1, &self.list[self.list.len() - 1]);
        if progress.is_cancelled() {
            return Err(BakeError::Cancelled);
        }
        Ok(value)
    }

    /// Sets the last stage's ray kind and error estimate (and publishes the estimate).
    fn annotate(&mut self, kind: RayKind, error: Option<ErrorEstimate>, progress: &Progress) {
        let index = self.list.len().saturating_sub(1);
        if let Some(last) = self.list.last_mut() {
            if last.rays > 0 {
                last.ray_kind = kind;
            }
            if let Some(e) = &error {
                progress.set_error_estimate(e.relative_rms);
            }
            last.error = error;
            progress.record_stage(index, last);
        }
    }
}

/// Rounds a sampling stage may take to reach its share of `target_error`.
const TARGET_ROUNDS: u32 = 3;

/// The factor on a sample count that brings `error` down to `target` (error ∝ 1/√count),
/// with a 20% margin; 1 when already there.
fn count_factor(error: f64, target: f64) -> f64 {
    if error <= target || target <= 0.0 {
        1.0
    } else {
        (error / target).powi(2) * 1.2
    }
}

/// `count` × `factor`, rounded up and capped at `max`.
fn scaled(count: u32, factor: f64, max: u32) -> u32 {
    ((count as f64 * factor).ceil()).min(max as f64) as u32
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

fn bake_in_pool(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    threads: usize,
) -> Result<BakeOutput> {
    let start = Instant::now();
    let mut stages = Stages { list: Vec::new() };
    let mut warnings = scene.warnings.clone();

    // Plan, and refuse early when the texel count alone would not fit.
    let mut plan = stages.run("plan", progress, 1, || {
        let plan = BakePlan::new(scene, settings);
        let note = format!("{} texels/m", plan.texel_density);
        Ok((plan, 0, note))
    })?;
    let estimate = memory::estimate_from_area(scene, plan.texel_density);
    estimate.check(settings.memory_budget_mib)?;

    // Unwrap.
    let layout = stages.run("unwrap", progress, scene.meshes.len() as u64, || {
        let layout = unwrap_scene(scene, settings, plan.texel_density)?;
        let note = format!(
            "{} mesh(es) xatlas, {} kept, {} page(s)",
            plan.meshes_to_unwrap,
            plan.meshes_keeping_uv1,
            layout.pages.len()
        );
        Ok((layout, 0, note))
    })?;
    warnings.extend(layout.warnings.iter().cloned());
    let estimate = memory::estimate_from_layout(scene, &layout);
    estimate.check(settings.memory_budget_mib)?;
    let baked_scene = layout.apply(scene);

    let mut texels = TexelStats {
        pages: layout.pages.len(),
        page_texels: layout.page_texels(),
        ..TexelStats::default()
    };
    let mut indirect_report = None;
    let mut vpl_report = None;
    let mut solver_reason = None;
    let mut bake_error = None;
    let mut rates = RayRates::default();
    let pages = if plan.nothing_to_bake {
        layout
            .pages
            .iter()
            .map(|p| LightmapPage::black(p.width, p.height))
            .collect()
    } else {
        let rays = stages.run("bvh", progress, 1, || {
            let rays = RayScene::build(&baked_scene);
            let (nodes, packets, bytes) = rays.bvh_size();
            let note = format!(
                "{} triangles, {nodes} nodes, {packets} leaf packets, {:.1} MiB",
                rays.bvh_triangle_count(),
                bytes as f64 / 1048576.0
            );
            Ok((rays, 0, note))
        })?;
        let mut patches = stages.run("raster", progress, 1, || {
            let p = Patches::build(&baked_scene, &layout, &rays);
            let note = format!("{} texel patches", p.patches.len());
            Ok((p, 0, note))
        })?;
        stages.run("validity", progress, patches.patches.len() as u64, || {
            patches.fix_validity(&baked_scene, &layout, &rays);
            let note = format!("{} moved, {} invalid", patches.moved, patches.invalid);
            Ok(((), patches.rays, note))
        })?;
        stages.annotate(RayKind::Shadow, None, progress);
        texels.patches = patches.patches.len();
        texels.moved = patches.moved;
        texels.invalid = patches.invalid;
        let emitters = Emitters::collect(&baked_scene, &rays);
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
                    baked_scene.instances[info.instance as usize].name, info.local
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
                if emitters.overlapping_count > listed.len() { ", …" } else { "" }
            ));
        }
        let ctx = BakeContext {
            scene: &baked_scene,
            layout: &layout,
            rays: &rays,
            patches: &patches,
            settings,
            plan: &plan,
        };
        let vpl_only = settings.method == Method::Vpl;
        let indirect_runs = plan.runs("indirect");
        // Each sampling stage gets an equal share of the target error (they add in
        // quadrature).
        let sampling_stages = u32::from(!vpl_only) + u32::from(indirect_runs);
        let share = settings
            .target_error
            .map(|t| t as f64 / (sampling_stages.max(1) as f64).sqrt());
        let mut stage_errors: Vec<ErrorEstimate> = Vec::new();
        let irradiance = if vpl_only {
            vec![Vec3::ZERO; patches.patches.len()]
        } else {
            let (irradiance, error, missed) =
                stages.run("direct", progress, patches.patches.len() as u64, || {
                    let mut s = settings.clone();
                    if share.is_some() {
                        // A variance needs samples to spread: the pilot takes at least 4.
                        s.samples_per_texel = s.samples_per_texel.max(4);
                    }
                    let mut rays = 0;
                    for round in 1..=TARGET_ROUNDS {
                        let c = BakeContext {
                            settings: &s,
                            ..ctx
                        };
                        if round > 1 {
                            progress.begin(
                                &format!("direct (round {round})"),
                                patches.patches.len() as u64,
                            );
                        }
                        let r = direct_light(&c, &emitters, progress);
                        rays += r.rays;
                        // One sample has no spread: no estimate then.
                        let est = (s.samples_per_texel >= 2).then(|| {
                            ErrorEstimate::from_standard_errors(
                                &valid(&patches, &r.standard_error),
                                rms_luminance(&valid(&patches, &r.irradiance)),
                                crate::direct::error_method(&s, c.plan.sky),
                            )
                        });
                        let factor = match (share, &est) {
                            (Some(t), Some(e)) => count_factor(e.relative_rms, t),
                            _ => 1.0,
                        };
                        let next = (
                            scaled(s.samples_per_texel, factor, 4096),
                            scaled(s.sky_samples, factor, 65_536),
                        );
                        let done = factor <= 1.0 || next == (s.samples_per_texel, s.sky_samples);
                        if done || round == TARGET_ROUNDS {
                            let note = format!(
                                "{} spp, {} light(s), {} emitter triangle(s){}{}",
                                s.samples_per_texel,
                                plan.lights.iter().filter(|l| l.instances > 0).count(),
                                emitters.list.len(),
                                if plan.sky {
                                    format!(", {} sky rays/texel", s.sky_samples)
                                } else {
                                    String::new()
                                },
                                if round > 1 {
                                    format!(", {round} rounds")
                                } else {
                                    String::new()
                                }
                            );
                            let missed = factor > 1.0;
                            return Ok(((r.irradiance, est, missed), rays, note));
                        }
                        (s.samples_per_texel, s.sky_samples) = next;
                    }
                    unreachable!("the last round returns")
                })?;
            if let Some(e) = error.as_ref().filter(|_| missed) {
                warnings.push(format!(
                    "direct light stopped at an estimated {:.2}% error, above its share {:.2}% of the target (sample counts capped or rounds used up)",
                    100.0 * e.relative_rms,
                    100.0 * share.unwrap_or(0.0)
                ));
            }
            stages.annotate(RayKind::Shadow, error.clone(), progress);
            stage_errors.extend(error);
            irradiance
        };
        let mut irradiance = irradiance;
        if indirect_runs && matches!(settings.method, Method::Vpl | Method::Hybrid) {
            let (from_vpls, report) =
                stages.run("vpl", progress, patches.patches.len() as u64, || {
                    let direct = (!vpl_only).then_some(irradiance.as_slice());
                    let mut s = settings.clone();
                    let mut rays = 0;
                    for round in 1..=TARGET_ROUNDS {
                        let c = BakeContext {
                            settings: &s,
                            ..ctx
                        };
                        let (e, report, r) =
                            instant_radiosity(&c, &emitters, vpl_only, direct, progress);
                        rays += r;
                        let factor =
                            share.map_or(1.0, |t| count_factor(report.error.relative_rms, t));
                        let next = scaled(report.particles, factor, 10_000_000);
                        if factor <= 1.0 || next == report.particles || round == TARGET_ROUNDS {
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
                                if round > 1 {
                                    format!(", {round} rounds")
                                } else {
                                    String::new()
                                }
                            );
                            return Ok(((e, report), rays, note));
                        }
                        s.vpl_particles = next;
                        s.vpl_time_budget_s = None;
                    }
                    unreachable!("the last round returns")
                })?;
            if let Some(note) = &report.compensation_note {
                warnings.push(note.clone());
            }
            // Keller's walk follows at most `vpl_max_depth` reflections: in a closed scene the
            // light beyond them is ρ̄^(d+1) of the total, and it is not baked.
            let depth = settings.vpl_max_depth.min(crate::vpl::walk::MAX_DEPTH);
            let lost = (report.mean_reflectivity as f64).powi(depth as i32 + 1);
            if lost > 0.01 {
                warnings.push(format!(
                    "instant radiosity follows at most {depth} reflections; with mean reflectivity {:.3} the light beyond them, up to {:.1}% of the total in a closed scene, is not baked (raise vpl_max_depth, at most {}, or use the radiosity method)",
                    report.mean_reflectivity,
                    100.0 * lost,
                    crate::vpl::walk::MAX_DEPTH
                ));
            }
            if let Some(t) = share.filter(|&t| report.error.relative_rms > t) {
                warnings.push(format!(
                    "instant radiosity stopped at an estimated {:.2}% error, above its share {:.2}% of the target",
                    100.0 * report.error.relative_rms,
                    100.0 * t
                ));
            }
            stages.annotate(RayKind::Shadow, Some(report.error.clone()), progress);
            stage_errors.push(report.error.clone());
            for (e, v) in irradiance.iter_mut().zip(&from_vpls) {
                *e += *v;
            }
            solver_reason = Some(format!(
                "instant radiosity: {} particles ({}), {} VPLs, clamp distance {:.3e} m",
                report.particles, report.particles_reason, report.vpls, report.clamp_distance
            ));
            vpl_report = Some(report);
        } else if indirect_runs {
            let nodes = stages.run("nodes", progress, 1, || {
                let nodes = Nodes::new(&ctx, settings.basis);
                let note = format!(
                    "{} nodes, max albedo {:.3}",
                    nodes.len(),
                    nodes.max_albedo()
                );
                Ok((nodes, 0, note))
            })?;
            let source = indirect::source(&nodes, &irradiance);
            let mut s = settings.clone();
            if let Some(t) = settings.target_error {
                s.solver_tolerance = s.solver_tolerance.min(t as f64 / 4.0);
            }
            let mut round = 1;
            let (solver_plan, transport, solution, error) = loop {
                let c = BakeContext {
                    settings: &s,
                    ..ctx
                };
                let suffix = if round > 1 {
                    format!(" #{round}")
                } else {
                    String::new()
                };
                let solver_plan = indirect::plan_solver(&c, &nodes)?;
                let transport = if solver_plan.choice.needs_matrix() {
                    let t = stages.run(
                        &format!("transport{suffix}"),
                        progress,
                        nodes.len() as u64,
                        || {
                            let t = indirect::build_transport(&c, &nodes, progress);
                            let note = format!(
                                "{} rays/node, {} entries, {:.1} MiB (estimated {:.1})",
                                s.transport_rays,
                                t.nnz(),
                                t.bytes() as f64 / 1048576.0,
                                solver_plan.transport_estimate_bytes as f64 / 1048576.0
                            );
                            let rays = t.rays;
                            Ok((t, rays, note))
                        },
                    )?;
                    Some(t)
                } else {
                    None
                };
                let solution = stages.run(&format!("solve{suffix}"), progress, 0, || {
                    let sol = indirect::solve_system(
                        &c,
                        &nodes,
                        &solver_plan,
                        transport.as_ref(),
                        &source,
                        progress,
                    );
                    let note = format!("{}: {}", sol.solver, sol.stop_reason);
                    let rays = sol.rays;
                    Ok((sol, rays, note))
                })?;
                // The Monte Carlo error of the matrix rows, or of stochastic Jacobi's shooting.
                let error = stages.run(&format!("estimate{suffix}"), progress, 1, || {
                    let (e, rays) = indirect::gather_error(
                        &c,
                        &nodes,
                        &solution.b,
                        &solution.indirect,
                        &irradiance,
                        s.transport_rays,
                    );
                    let note = format!("{:.2}% from {}", 100.0 * e.relative_rms, e.method);
                    Ok((e, rays, note))
                })?;
                stages.annotate(RayKind::Closest, Some(error.clone()), progress);
                let factor = share.map_or(1.0, |t| count_factor(error.relative_rms, t));
                // The count that sets the noise: form-factor rays, or the shooting's rays.
                let count = if transport.is_some() {
                    &mut s.transport_rays
                } else {
                    &mut s.stochastic_rays_per_node
                };
                let next = scaled(*count, factor, 65_536);
                if factor <= 1.0 || next == *count || round == TARGET_ROUNDS {
                    if factor > 1.0 {
                        warnings.push(format!(
                            "radiosity stopped at an estimated {:.2}% error, above its share {:.2}% of the target",
                            100.0 * error.relative_rms,
                            100.0 * share.unwrap_or(0.0)
                        ));
                    }
                    break (solver_plan, transport, solution, Some(error));
                }
                drop(transport);
                *count = next;
                round += 1;
            };
            if let Some(e) = error {
                stage_errors.push(e);
            }
            if !solution.converged {
                warnings.push(format!(
                    "the {} solver did not reach the tolerance {:.1e}: {}",
                    solution.solver, s.solver_tolerance, solution.stop_reason
                ));
            }
            let reflected = indirect::per_patch(&nodes, &solution.indirect, patches.patches.len());
            for (e, r) in irradiance.iter_mut().zip(&reflected) {
                *e += *r;
            }
            solver_reason = Some(format!(
                "radiosity, solver {}: {}",
                solver_plan.choice.name(),
                solver_plan.reason
            ));
            indirect_report = Some(IndirectReport {
                solver: solution.solver,
                solver_reason: solver_plan.reason.clone(),
                basis: settings.basis,
                nodes: nodes.len(),
                max_albedo: nodes.max_albedo(),
                transport_nnz: transport.as_ref().map_or(0, Transport::nnz),
                transport_bytes: transport.as_ref().map_or(0, Transport::bytes),
                transport_estimate_bytes: solver_plan.transport_estimate_bytes,
                solver_working_bytes: solver_plan.solver_working_bytes,
                solution,
            });
        }
        if !stage_errors.is_empty() {
            let value = rms_luminance(&valid(&patches, &irradiance));
            bake_error = Some(ErrorEstimate::combine(&stage_errors, value));
        }
        // The rates the floor is measured at: a short calibration on the same pool.
        rates = stages.run("calibrate", progress, 1, || {
            let r = calibrate(&rays, CALIBRATION_RAYS, settings.seed);
            let note = format!(
                "BVH rates for the floor: {:.2} Mrays/s closest, {:.2} shadow",
                r.closest_per_second / 1e6,
                r.shadow_per_second / 1e6
            );
            Ok((r, 0, note))
        })?;
        if let Some(bad) = irradiance.iter().position(|e| !e.is_finite()) {
            // An internal error: report it rather than write garbage.
            return Err(BakeError::BadSetting {
                name: "scene",
                value: format!("patch {bad}"),
                message: format!(
                    "direct light produced a non-finite value {:?}",
                    irradiance[bad]
                ),
            });
        }
        stages.run("dilate", progress, 1, || {
            let (pages, st) = assemble(&layout, &patches, &irradiance, settings.padding + 2);
            texels.filled = st.filled;
            texels.dilated = st.dilated;
            if st.unfilled > 0 {
                warnings.push(format!(
                    "{} texels inside geometry had no valid neighbour in their chart and were left black",
                    st.unfilled
                ));
            }
            let note = format!("{} filled, {} padding texels", st.filled, st.dilated);
            Ok((pages, 0, note))
        })?
    };
    let max = pages
        .iter()
        .flat_map(|p| p.texels.iter())
        .fold(Vec3::ZERO, |m, t| m.max(*t));
    if let Some(reason) = solver_reason {
        plan.set_reason("indirect", reason);
    }
    let total_seconds = start.elapsed().as_secs_f64();
    let floor = (stages.list.iter().any(|s| s.rays > 0) && rates.closest_per_second > 0.0)
        .then(|| Floor::new(&stages.list, rates, total_seconds));
    let report = BakeReport {
        lightbake_version: env!("CARGO_PKG_VERSION"),
        scene: scene.name.clone(),
        settings: settings.clone(),
        plan,
        stages: stages.list,
        indirect: indirect_report,
        vpl: vpl_report,
        texels,
        triangles: scene.instanced_triangle_count(),
        threads,
        memory: estimate,
        warnings: {
            if max.max_element() > crate::output::images::HALF_MAX {
                warnings.push(format!(
                    "the brightest texel ({:.3e}) exceeds the half-float range; EXR and KTX2 outputs clamp it to 65504",
                    max.max_element()
                ));
            }
            warnings
        },
        error: bake_error,
        floor,
        total_seconds,
        outputs: Vec::new(),
    };
    Ok(BakeOutput {
        layout,
        baked_scene,
        pages,
        report,
    })
}

/// A scene made ready for lighting passes, without running them: plan, unwrap, BVH, texel
/// patches (validated). For tests, benchmarks and studies that drive the passes themselves.
pub struct Prepared {
    /// The unwrapped scene.
    pub scene: Scene,
    /// Its layout.
    pub layout: Layout,
    /// Ray queries.
    pub rays: RayScene,
    /// Texel patches.
    pub patches: Patches,
    /// Settings.
    pub settings: BakeSettings,
    /// The plan.
    pub plan: BakePlan,
}

impl Prepared {
    /// Plans, unwraps, builds the BVH and the validated patches of `scene`.
    ///
    /// # Errors
    /// As [`bake`] for the stages it runs.
    pub fn new(scene: &Scene, settings: &BakeSettings) -> Result<Self> {
        settings.validate()?;
        scene.validate()?;
        let plan = BakePlan::new(scene, settings);
        let layout = unwrap_scene(scene, settings, plan.texel_density)?;
        let baked = layout.apply(scene);
        let rays = RayScene::build(&baked);
        let mut patches = Patches::build(&baked, &layout, &rays);
        patches.fix_validity(&baked, &layout, &rays);
        Ok(Self {
            scene: baked,
            layout,
            rays,
            patches,
            settings: settings.clone(),
            plan,
        })
    }

    /// The context the lighting passes read.
    pub fn ctx(&self) -> BakeContext<'_> {
        BakeContext {
            scene: &self.scene,
            layout: &self.layout,
            rays: &self.rays,
            patches: &self.patches,
            settings: &self.settings,
            plan: &self.plan,
        }
    }

    /// Direct irradiance per patch (lux).
    pub fn direct(&self) -> Vec<Vec3> {
        let emitters = Emitters::collect(&self.scene, &self.rays);
        direct_light(&self.ctx(), &emitters, &Progress::new()).irradiance
    }
}
