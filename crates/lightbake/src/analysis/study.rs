//! Convergence study: every method over a sweep of budgets, each run's error measured against
//! a reference bake and set against its run time — the data behind `bake convergence` and the
//! plots in `docs/convergence.md`.
//!
//! * **Reference.** A radiosity bake far beyond the sweeps (direct 1024 footprint samples,
//!   4096 form-factor rays per node, BiCGStab to 10⁻⁷; its matrix may take the whole memory
//!   budget) with a *different seed*, so its
//!   remaining noise is independent of the runs' and small next to theirs. The direct-light
//!   curve has its own direct-only reference (same samples, same seed change).
//! * **Measured error.** Relative RMS of the luminance over the covered texels of every page:
//!   √(Σ(L − L_ref)²) / √(Σ L_ref²) — the normalisation of [`crate::error_estimate`], so a run's
//!   own estimate (`report.error`) can be compared with it; the study records their ratio.
//! * **Time.** Wall time of the whole bake (writing excluded), so curves include the fixed
//!   costs (unwrap, texel patches, BVH) every method pays.
//!
//! The curves: direct light over footprint samples; each radiosity solver (Jacobi,
//! Gauss–Seidel, shooting, BiCGStab, CG, stochastic Jacobi) over its tolerance at a fixed
//! matrix; Monte Carlo form factors over rays per node for the piecewise-linear and the
//! piecewise-constant basis; the hierarchical solve over its final gather's rays per node
//! (without and with the denoiser) and over its refinement tolerance (from a coarse first
//! cut, where its bias shows); hemicube
//! form factors over resolution (piecewise constant); and instant radiosity (hybrid) over
//! particle counts.

use std::time::Instant;

use serde::Serialize;

use crate::bake::bake;
use crate::color::luminance;
use crate::context::Prepared;
use crate::direct::direct_irradiance;
use crate::error::{BakeError, Result};
use crate::lightmap::{LightmapPage, assemble};
use crate::plan::{density_text, texel_density};
use crate::progress::Progress;
use crate::radiosity::hemicube::build_hemicube;
use crate::radiosity::{self, Nodes};
use crate::scene::Scene;
use crate::settings::{BakeSettings, Basis, Method, SolverChoice};
use crate::solve::{self, SolveOptions};

/// One run of the study.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StudyRow {
    /// The curve (method) it belongs to.
    pub curve: String,
    /// The budget parameter's name.
    pub parameter: String,
    /// Its value.
    pub budget: f64,
    /// Wall time of the bake, s.
    pub seconds: f64,
    /// Rays traced.
    pub rays: u64,
    /// Measured relative RMS error against the reference.
    pub measured: f64,
    /// The bake's own estimate (relative RMS), when it made one.
    pub estimated: Option<f64>,
}

impl StudyRow {
    /// estimated / measured, when both exist and the measured error is not zero.
    pub fn estimate_ratio(&self) -> Option<f64> {
        self.estimated
            .filter(|_| self.measured > 0.0)
            .map(|e| e / self.measured)
    }

    /// The CSV header matching [`StudyRow::csv`].
    pub const CSV_HEADER: &'static str =
        "curve,parameter,budget,seconds,rays,measured_rel_rms,estimated_rel_rms,estimate_ratio";

    /// One CSV line (no newline).
    pub fn csv(&self) -> String {
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
        format!(
            "{},{},{},{:.6},{},{:.6e},{},{}",
            self.curve,
            self.parameter,
            self.budget,
            self.seconds,
            self.rays,
            self.measured,
            opt(self.estimated),
            opt(self.estimate_ratio())
        )
    }
}

/// A run the study could not make, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SkippedRun {
    /// The curve it belongs to.
    pub curve: String,
    /// The budget parameter's name and value.
    pub budget: String,
    /// Why (the bake's refusal: its memory, its solver's limits).
    pub reason: String,
}

/// What the study ran against.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Study {
    /// Scene name.
    pub scene: String,
    /// The texel density every run used, texels per metre.
    pub texel_density: f32,
    /// Where it came from: the settings, or lowered until the reference's full transport
    /// matrix fits the memory budget.
    pub density_reason: String,
    /// Covered texels compared.
    pub texels: usize,
    /// Wall time of the full reference bake, s.
    pub reference_seconds: f64,
    /// Wall time of the direct-only reference, s.
    pub direct_reference_seconds: f64,
    /// The runs, curve by curve.
    pub rows: Vec<StudyRow>,
    /// The runs that did not fit, with why.
    pub skipped: Vec<SkippedRun>,
}

/// How big the sweeps are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StudySize {
    /// Two or three budgets per curve (for tests).
    Quick,
    /// The full sweeps.
    Full,
}

/// Relative RMS luminance difference of `pages` against `reference` over the reference's
/// covered texels: √(Σ(L − L_ref)²) / √(Σ L_ref²).
///
/// # Panics
/// When the page lists differ in count or size (the study bakes one layout).
pub fn relative_rms_error(pages: &[LightmapPage], reference: &[LightmapPage]) -> f64 {
    assert_eq!(pages.len(), reference.len(), "page count differs");
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for (p, r) in pages.iter().zip(reference) {
        assert_eq!(p.texels.len(), r.texels.len(), "page size differs");
        for ((a, b), &c) in p.texels.iter().zip(&r.texels).zip(&r.covered) {
            if c {
                let (la, lb) = (luminance(*a) as f64, luminance(*b) as f64);
                diff += (la - lb) * (la - lb);
                norm += lb * lb;
            }
        }
    }
    if norm > 0.0 {
        (diff / norm).sqrt()
    } else {
        diff.sqrt()
    }
}

/// Runs the study on `scene` with `base` settings (texel density, threads and the like come
/// from it), calling `on_row` after every run so a caller can show progress.
///
/// # Errors
/// As [`bake`].
pub fn run_study(
    scene: &Scene,
    base: &BakeSettings,
    size: StudySize,
    mut on_row: impl FnMut(&StudyRow),
) -> Result<Study> {
    let progress = Progress::new();
    let (base, full_ref, reference, density_reason) = fitted_reference(scene, base, size)?;
    let direct_reference = BakeSettings {
        method: Method::Direct,
        ..reference.clone()
    };
    let direct_ref = bake(scene, &direct_reference, &progress)?;
    let texels = full_ref
        .pages
        .iter()
        .map(|p| p.covered.iter().filter(|&&c| c).count())
        .sum();
    let mut rows = Vec::new();
    let mut skipped = Vec::new();
    for case in cases(&base, size) {
        let against = match case.against {
            Against::Direct => &direct_ref.pages,
            Against::Full => &full_ref.pages,
        };
        let run = match case.hemicube {
            Some(resolution) => hemicube_run(scene, &case.settings, resolution, against),
            None => bake(scene, &case.settings, &progress).map(|out| StudyRow {
                curve: case.curve.clone(),
                parameter: case.parameter.to_string(),
                budget: case.budget,
                seconds: out.report.total_seconds,
                rays: out.report.total_rays(),
                measured: relative_rms_error(&out.pages, against),
                estimated: out.report.error.as_ref().map(|e| e.relative_rms),
            }),
        };
        match run {
            Ok(row) => {
                on_row(&row);
                rows.push(row);
            }
            // A run whose method does not fit this scene is left out, with the refusal.
            Err(e @ (BakeError::OverMemoryBudget { .. } | BakeError::BadSetting { .. })) => {
                skipped.push(SkippedRun {
                    curve: case.curve,
                    budget: format!("{} = {}", case.parameter, case.budget),
                    reason: e.to_string(),
                });
            }
            Err(e) => return Err(e),
        }
    }
    Ok(Study {
        scene: scene.name.clone(),
        texel_density: base.layout.texel_density.unwrap_or_default(),
        density_reason,
        texels,
        reference_seconds: full_ref.report.total_seconds,
        direct_reference_seconds: direct_ref.report.total_seconds,
        rows,
        skipped,
    })
}

/// The study's density and its reference bake: the settings' density (or the one the plan
/// chooses), lowered — by the square root of what the memory budget holds over what the
/// reference's full transport matrix needs, which grows with the texels — until that matrix
/// fits. Returns the settings every run starts from (with the density fixed), the reference
/// bake, its settings, and where the density came from.
fn fitted_reference(
    scene: &Scene,
    base: &BakeSettings,
    size: StudySize,
) -> Result<(BakeSettings, crate::bake::BakeOutput, BakeSettings, String)> {
    let (density, source) = texel_density(scene, base);
    let mut base = {
        let mut s = base.clone();
        s.layout.texel_density = Some(density);
        s.layout.texel_density_from_scene = false;
        s
    };
    let mut reason = format!("{} texels/m, {source}", density_text(density));
    for _attempt in 0..6 {
        let reference = reference_settings(&base, size);
        match bake(scene, &reference, &Progress::new()) {
            Ok(out) => return Ok((base, out, reference, reason)),
            Err(BakeError::OverMemoryBudget {
                needed_mib,
                budget_mib,
                ..
            }) => {
                let d = base.layout.texel_density.unwrap_or(density);
                let lower = d * (0.9 * budget_mib / needed_mib.max(1.0)).sqrt() as f32;
                base.layout.texel_density = Some(lower);
                reason = format!(
                    "{} texels/m: lowered from {} texels/m ({source}) so the reference's full transport matrix ({:.0} MiB at {} texels/m) fits the memory budget of {budget_mib:.0} MiB",
                    density_text(lower),
                    density_text(density),
                    needed_mib,
                    density_text(d)
                );
            }
            Err(e) => return Err(e),
        }
    }
    Err(BakeError::OverMemoryBudget {
        needed_mib: 0.0,
        budget_mib: base.memory_budget_mib as f64,
        breakdown: "no density tried let the study's reference fit".into(),
    })
}

/// The reference bake's settings: another seed, far more samples, a converged solve.
fn reference_settings(base: &BakeSettings, size: StudySize) -> BakeSettings {
    let mut reference = base.clone();
    reference.seed = base.seed.wrapping_add(0x5eed);
    reference.method = Method::Radiosity;
    reference.direct.samples_per_texel = 1024;
    reference.direct.sky_samples = 4096;
    reference.radiosity.transport_rays = match size {
        StudySize::Full => 4096,
        StudySize::Quick => 1024,
    };
    // The reference may use the whole memory budget for its matrix.
    reference.radiosity.transport_budget_mib = reference
        .radiosity
        .transport_budget_mib
        .max(base.memory_budget_mib);
    reference.radiosity.solver = SolverChoice::Krylov;
    reference.radiosity.solver_tolerance = 1e-7;
    reference.target_error = None;
    // A reference is converged, not filtered: the denoiser's bias would be in it.
    reference.finish.denoise = false;
    reference
}

/// Which reference a run is measured against.
#[derive(Clone, Copy)]
enum Against {
    /// The direct-only reference.
    Direct,
    /// The full (radiosity) reference.
    Full,
}

/// One run of the study, before it runs.
struct Case {
    curve: String,
    parameter: &'static str,
    budget: f64,
    settings: BakeSettings,
    against: Against,
    /// A hemicube run at this resolution instead of a bake.
    hemicube: Option<u32>,
}

/// Every run of the study, curve by curve (see the module docs).
fn cases(base: &BakeSettings, size: StudySize) -> Vec<Case> {
    let pick = |full: &[f64], quick: &[f64]| -> Vec<f64> {
        match size {
            StudySize::Full => full.to_vec(),
            StudySize::Quick => quick.to_vec(),
        }
    };
    // Every curve measures its method as it is, unfiltered, but for the denoised one. The
    // reference is a bake on the same texel grid, so the grid's own error is in neither the
    // measured error nor (with its check off) the estimate.
    let s = {
        let mut s = base.clone();
        s.target_error = None;
        s.finish.denoise = false;
        s.checks.grid_error_points = 0;
        s
    };
    let case = |curve: &str, parameter, budget, settings, against| Case {
        curve: curve.to_string(),
        parameter,
        budget,
        settings,
        against,
        hemicube: None,
    };
    let mut cases = Vec::new();
    // Direct light over footprint samples.
    for spp in pick(&[1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0], &[2.0, 8.0]) {
        let mut d = s.clone();
        d.method = Method::Direct;
        d.direct.samples_per_texel = spp as u32;
        d.direct.sky_samples = (4 * spp as u32).max(4);
        cases.push(case("direct", "spp", spp, d, Against::Direct));
    }
    // Radiosity solvers over their tolerance at a fixed matrix.
    let solvers = [
        SolverChoice::Jacobi,
        SolverChoice::GaussSeidel,
        SolverChoice::Shooting,
        SolverChoice::Krylov,
        SolverChoice::KrylovCg,
        SolverChoice::StochasticJacobi,
    ];
    for solver in solvers {
        let tolerances = if solver == SolverChoice::StochasticJacobi {
            pick(&[0.3, 0.1, 0.03, 0.01], &[0.1])
        } else {
            pick(&[0.3, 0.1, 0.03, 0.01, 1e-3, 1e-4], &[0.1, 1e-3])
        };
        for tol in tolerances {
            let mut r = s.clone();
            r.method = Method::Radiosity;
            r.radiosity.solver = solver;
            r.radiosity.solver_tolerance = tol;
            r.radiosity.transport_rays = 256;
            if solver == SolverChoice::StochasticJacobi {
                r.radiosity.stochastic_rays_per_node = 256;
            }
            cases.push(case(solver.name(), "tolerance", tol, r, Against::Full));
        }
    }
    // Monte Carlo form factors over rays per node, both bases.
    for basis in [Basis::Linear, Basis::Constant] {
        for rays in pick(
            &[16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0],
            &[16.0, 128.0],
        ) {
            let mut r = s.clone();
            r.method = Method::Radiosity;
            r.radiosity.solver = SolverChoice::GaussSeidel;
            r.radiosity.solver_tolerance = 1e-4;
            r.radiosity.basis = basis;
            r.radiosity.transport_rays = rays as u32;
            let curve = match basis {
                Basis::Linear => "mc-linear",
                Basis::Constant => "mc-constant",
            };
            cases.push(case(curve, "rays/node", rays, r, Against::Full));
        }
    }
    // The hierarchical solve over its final gather's rays per node (its coarse level at the
    // preset's settings), and over its refinement tolerance from a deliberately coarse first
    // cut (64 × 64 texels) at 256 rays, where its bias is a visible share of the error. Its
    // final gather has the same rays at every node, as a matrix row (the rays shared out by
    // noise are measured against it in the benchmarks).
    for rays in pick(
        &[16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0],
        &[16.0, 128.0],
    ) {
        let mut r = s.clone();
        r.method = Method::Radiosity;
        r.radiosity.solver = SolverChoice::Hierarchical;
        r.radiosity.adaptive_gather = false;
        r.radiosity.transport_rays = rays as u32;
        cases.push(case(
            "hierarchical",
            "rays/node",
            rays,
            r.clone(),
            Against::Full,
        ));
        // The same bakes through the denoiser, scored the same way.
        r.finish.denoise = true;
        cases.push(case(
            "hierarchical-denoised",
            "rays/node",
            rays,
            r,
            Against::Full,
        ));
    }
    for tolerance in pick(&[0.3, 0.1, 0.03, 0.01, 0.003], &[0.3, 0.01]) {
        let mut r = s.clone();
        r.method = Method::Radiosity;
        r.radiosity.solver = SolverChoice::Hierarchical;
        r.radiosity.adaptive_gather = false;
        r.radiosity.transport_rays = 256;
        r.radiosity.cluster_texels = 64;
        r.radiosity.cluster_tolerance = tolerance;
        cases.push(case(
            "hierarchical-coarse",
            "cluster tolerance",
            tolerance,
            r,
            Against::Full,
        ));
    }
    // Hemicube form factors over resolution (piecewise constant).
    for res in pick(&[8.0, 16.0, 32.0, 64.0], &[8.0]) {
        cases.push(Case {
            hemicube: Some(res as u32),
            ..case("hemicube", "resolution", res, s.clone(), Against::Full)
        });
    }
    // Instant radiosity (hybrid) over particles, Keller's gather of every VPL at every texel.
    for n in pick(&[64.0, 256.0, 1024.0, 4096.0, 16384.0], &[64.0, 1024.0]) {
        let mut v = s.clone();
        v.method = Method::Hybrid;
        v.vpl.particles = n as u32;
        v.vpl.cut_size = 0;
        v.vpl.time_budget_s = None;
        cases.push(case("vpl-hybrid", "particles", n, v, Against::Full));
    }
    // Instant radiosity (hybrid) through lightcuts over the cut's size, with the preset's
    // 512 particles per node of the cut.
    for c in pick(
        &[16.0, 32.0, 64.0, 128.0, 256.0, 512.0, 1024.0],
        &[32.0, 128.0],
    ) {
        let mut v = s.clone();
        v.method = Method::Hybrid;
        v.vpl.cut_size = c as u32;
        v.vpl.particles = 512 * c as u32;
        v.vpl.time_budget_s = None;
        cases.push(case("vpl-cut", "cut size", c, v, Against::Full));
    }
    cases
}

/// One hemicube run: the bake's own stages with the matrix from [`build_hemicube`] and a
/// Gauss–Seidel solve to 10⁻⁴ (no error estimate: the hemicube is deterministic, its error is
/// aliasing, which sample variance cannot see).
fn hemicube_run(
    scene: &Scene,
    base: &BakeSettings,
    resolution: u32,
    reference: &[LightmapPage],
) -> Result<StudyRow> {
    let start = Instant::now();
    let mut settings = base.clone();
    settings.method = Method::Radiosity;
    settings.radiosity.basis = Basis::Constant;
    let prepared = Prepared::new(scene, &settings)?;
    let ctx = prepared.ctx();
    let mut irradiance = direct_irradiance(&prepared.ctx());
    let nodes = Nodes::new(&ctx, Basis::Constant);
    // Its rows hold at most one entry (8 bytes) per hemicube pixel (3·res² of them) or per
    // node, whichever is fewer: refused over the memory budget, as a bake's matrix is.
    let n = nodes.len() as f64;
    let bytes = n * n.min(3.0 * (resolution as f64).powi(2)) * 8.0;
    let budget = settings.memory_budget_mib as f64 * 1048576.0;
    if bytes > budget {
        return Err(BakeError::OverMemoryBudget {
            needed_mib: bytes / 1048576.0,
            budget_mib: budget / 1048576.0,
            breakdown: format!("a hemicube matrix of {n} nodes at {resolution}² pixels"),
        });
    }
    let progress = Progress::new();
    let transport = build_hemicube(&ctx, &nodes, resolution, &progress);
    let source = radiosity::source(&nodes, &irradiance);
    let system = radiosity::system(&transport, &nodes, &source);
    let options = SolveOptions {
        tolerance: radiosity::residual_tolerance(1e-4, nodes.max_albedo()),
        max_iterations: settings.radiosity.max_solver_iterations,
    };
    let solution = solve::solve_matrix(SolverChoice::GaussSeidel, &system, &options);
    let reflected =
        radiosity::per_patch(&nodes, &solution.indirect, prepared.patches.patches.len());
    for (e, r) in irradiance.iter_mut().zip(&reflected) {
        *e += *r;
    }
    let (pages, _) = assemble(
        &prepared.layout,
        &prepared.patches,
        &irradiance,
        settings.layout.padding + 2,
    );
    Ok(StudyRow {
        curve: "hemicube".into(),
        parameter: "resolution".into(),
        budget: resolution as f64,
        seconds: start.elapsed().as_secs_f64(),
        rays: transport.rays,
        measured: relative_rms_error(&pages, reference),
        estimated: None,
    })
}

/// Least-squares slope of log(error) against log(seconds) of one curve's rows (the
/// convergence rate in time), when it has two or more rows with positive values.
pub fn log_log_slope(rows: &[&StudyRow]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.seconds > 0.0 && r.measured > 0.0)
        .map(|r| (r.seconds.ln(), r.measured.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Mean of `v`, when not empty.
fn mean(v: impl IntoIterator<Item = f64>) -> Option<f64> {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x;
        n += 1;
    }
    (n > 0).then(|| s / n as f64)
}

impl Study {
    /// The curves in the order they were run.
    pub fn curves(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for r in &self.rows {
            if !out.contains(&r.curve.as_str()) {
                out.push(&r.curve);
            }
        }
        out
    }

    /// The rows of one curve.
    pub fn curve(&self, name: &str) -> Vec<&StudyRow> {
        self.rows.iter().filter(|r| r.curve == name).collect()
    }

    /// A Markdown table per curve: budget, seconds, rays, measured and estimated error,
    /// their ratio; with the curve's log-log slope and mean estimate ratio.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Scene `{}`, {} covered texels at {}; reference bake {:.2} s (direct-only reference {:.2} s).\n\n",
            self.scene,
            self.texels,
            self.density_reason,
            self.reference_seconds,
            self.direct_reference_seconds
        );
        s.push_str(
            "| curve | budget | time (s) | rays | measured error | estimated | est./meas. |\n",
        );
        s.push_str("|---|---|---:|---:|---:|---:|---:|\n");
        for c in self.curves() {
            for r in self.curve(c) {
                s.push_str(&format!(
                    "| {} | {} = {} | {:.3} | {} | {:.3}% | {} | {} |\n",
                    r.curve,
                    r.parameter,
                    r.budget,
                    r.seconds,
                    r.rays,
                    100.0 * r.measured,
                    r.estimated
                        .map_or("-".into(), |e| format!("{:.3}%", 100.0 * e)),
                    r.estimate_ratio().map_or("-".into(), |x| format!("{x:.2}")),
                ));
            }
        }
        s.push_str(
            "\n| curve | slope d log(error) / d log(time) | mean est./meas. |\n|---|---:|---:|\n",
        );
        for c in self.curves() {
            let rows = self.curve(c);
            s.push_str(&format!(
                "| {} | {} | {} |\n",
                c,
                log_log_slope(&rows).map_or("-".into(), |x| format!("{x:.2}")),
                mean(rows.iter().filter_map(|r| r.estimate_ratio()))
                    .map_or("-".into(), |x| format!("{x:.2}"))
            ));
        }
        if !self.skipped.is_empty() {
            s.push_str("\nRuns left out (they do not fit this scene):\n\n");
            for k in &self.skipped {
                s.push_str(&format!("- {} ({}): {}\n", k.curve, k.budget, k.reason));
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn page(values: &[f32]) -> LightmapPage {
        LightmapPage {
            width: values.len() as u32,
            height: 1,
            texels: values.iter().map(|&v| Vec3::splat(v)).collect(),
            covered: vec![true; values.len()],
        }
    }

    #[test]
    fn relative_error_is_zero_on_itself_and_scales() {
        let r = [page(&[1.0, 2.0, 3.0])];
        assert_eq!(relative_rms_error(&r, &r), 0.0);
        let a = [page(&[1.1, 2.2, 3.3])];
        assert!((relative_rms_error(&a, &r) - 0.1).abs() < 1e-6);
    }

    #[test]
    fn slope_of_a_power_law() {
        let rows: Vec<StudyRow> = [1.0f64, 4.0, 16.0]
            .iter()
            .map(|&t| StudyRow {
                curve: "c".into(),
                parameter: "p".into(),
                budget: t,
                seconds: t,
                rays: 0,
                measured: 0.1 / t.sqrt(),
                estimated: Some(0.2 / t.sqrt()),
            })
            .collect();
        let refs: Vec<&StudyRow> = rows.iter().collect();
        assert!((log_log_slope(&refs).unwrap() + 0.5).abs() < 1e-9);
        assert!((rows[0].estimate_ratio().unwrap() - 2.0).abs() < 1e-9);
        assert!(rows[0].csv().starts_with("c,p,1,"));
    }
}
