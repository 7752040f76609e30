//! The transport matrix and the solver within their memory budgets: over budget, `auto`
//! goes hierarchical (no full matrix) and a matrix solver is refused, counting the solver's working memory and
//! what the memory budget leaves beside the rest of the bake.

mod common;

use common::radiosity_settings;
use lightbake::Stage;

use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::BakeSettings;
use lightbake::settings::SolverChoice;

#[test]
fn transport_over_budget_goes_hierarchical_or_is_refused() {
    let (scene, mut settings, out) = krylov_cornell_bake();
    let matrix_mib = out
        .report
        .radiosity
        .as_ref()
        .unwrap()
        .transport_estimate_bytes as f64
        / 1048576.0;
    assert!(matrix_mib >= 4.0, "the test needs a matrix of a few MiB");
    settings.radiosity.transport_budget_mib = (matrix_mib / 2.0).ceil() as u64;
    let out = common::bake(&scene, &settings);
    let report = out.report.radiosity.as_ref().unwrap();
    assert_eq!(report.solver, "hierarchical", "{}", report.solver_reason);
    assert!(report.solver_reason.contains("budget") && report.transport_nnz == 0);
    assert!(
        out.report
            .decisions
            .iter()
            .any(|d| d.stage == Stage::Indirect && d.what.contains("hierarchical"))
    );
    settings.radiosity.solver = SolverChoice::GaussSeidel;
    assert_over_budget(&scene, &settings, "gauss-seidel");
    assert_over_budget(&scene, &settings, "--solver hierarchical");
    // A budget that cannot hold even the hierarchical solve's vectors is refused as well.
    settings.radiosity.solver = SolverChoice::Auto;
    settings.radiosity.transport_budget_mib = 0;
    assert_over_budget(&scene, &settings, "hierarchical solve");
}

/// The area-lit Cornell box at 48 texels/m with `auto`, which picks BiCGStab: the scene, its
/// settings and the bake (the budget tests' baseline).
fn krylov_cornell_bake() -> (Scene, BakeSettings, lightbake::BakeOutput) {
    let scene = cornell_box(CornellLight::Area);
    let settings = radiosity_settings(48.0, SolverChoice::Auto);
    let out = common::bake(&scene, &settings);
    let report = out.report.radiosity.as_ref().unwrap();
    assert_eq!(report.solver, "krylov", "{}", report.solver_reason);
    (scene, settings, out)
}

/// The bake is refused as over its memory budget, with `needle` in the breakdown.
fn assert_over_budget(scene: &Scene, settings: &BakeSettings, needle: &str) {
    match lightbake::bake(scene, settings, &Progress::new()) {
        Err(lightbake::BakeError::OverMemoryBudget { breakdown, .. }) => {
            assert!(breakdown.contains(needle), "{breakdown}");
        }
        other => panic!(
            "expected a refusal, got {:?}",
            other.map(|o| o.report.texels)
        ),
    }
}

/// The transport budget holds the solver's own memory too: shooting builds the transpose (a
/// second matrix), so a budget that holds one matrix refuses it, and says what it needed.
#[test]
fn transport_budget_counts_the_solvers_working_memory() {
    let (scene, mut settings, out) = krylov_cornell_bake();
    let report = out.report.radiosity.as_ref().unwrap();
    // BiCGStab's vectors, and what every radiosity pass holds beside them (nodes, the hit
    // mapper's texel grid).
    let vectors = SolverChoice::Krylov.working_bytes(report.nodes, report.transport_estimate_bytes);
    assert!(vectors >= 10 * 24 * report.nodes as u64);
    assert!(
        report.solver_working_bytes > vectors
            && report.solver_working_bytes < vectors + 64 * report.nodes as u64,
        "{} bytes of working memory beside {vectors} of vectors",
        report.solver_working_bytes
    );
    assert!(
        report.transport_bytes <= report.transport_estimate_bytes
            && report.transport_bytes * 5 >= report.transport_estimate_bytes * 4,
        "matrix {} bytes against the estimate {}",
        report.transport_bytes,
        report.transport_estimate_bytes
    );
    let matrix_mib = report.transport_estimate_bytes.div_ceil(1 << 20);
    assert!(matrix_mib >= 4, "the test needs a matrix of a few MiB");
    settings.radiosity.solver = SolverChoice::Shooting;
    settings.radiosity.transport_budget_mib = matrix_mib + 1;
    assert_over_budget(&scene, &settings, "beside it");
    settings.radiosity.transport_budget_mib = 2 * matrix_mib + 2;
    assert!(lightbake::bake(&scene, &settings, &Progress::new()).is_ok());
}

/// The matrix and the solver share the memory budget with the rest of the bake: with a
/// large transport budget and a memory budget that leaves no room for the matrix, `auto` goes
/// hierarchical and a matrix solver is refused with the memory budget named.
#[test]
fn memory_budget_also_bounds_the_transport() {
    let (scene, mut settings, out) = krylov_cornell_bake();
    let report = out.report.radiosity.as_ref().unwrap();
    let rest_mib = out.report.memory.mib();
    let matrix_mib = report.transport_estimate_bytes as f64 / 1048576.0;
    assert!(matrix_mib >= 4.0, "the test needs a matrix of a few MiB");
    settings.radiosity.transport_budget_mib = 1 << 20;
    settings.memory_budget_mib = (rest_mib + 0.5 * matrix_mib).ceil() as u64;
    let out = common::bake(&scene, &settings);
    let report = out.report.radiosity.as_ref().unwrap();
    assert_eq!(report.solver, "hierarchical", "{}", report.solver_reason);
    settings.radiosity.solver = SolverChoice::Jacobi;
    assert_over_budget(&scene, &settings, "memory budget");
    settings.memory_budget_mib = (rest_mib + 3.0 * matrix_mib).ceil() as u64;
    assert!(lightbake::bake(&scene, &settings, &Progress::new()).is_ok());
}

/// `bake convergence` on a scene with no density hint, where the reference's full transport
/// matrix does not fit the memory budget at the density the texel budget gives: the study
/// lowers the density until it fits (and says so), and leaves out, with the reason, the runs
/// that still do not fit; it completes.
#[test]
fn the_convergence_study_fits_its_density_to_the_memory_budget() {
    use lightbake::analysis::study::{StudySize, run_study};
    let scene = cornell_box(CornellLight::Area);
    let mut base = BakeSettings::medium();
    base.layout.texel_density_from_scene = false;
    base.memory_budget_mib = 160;
    let mut rows = 0;
    let study = run_study(&scene, &base, StudySize::Quick, |_| rows += 1).unwrap();
    assert!(
        study.density_reason.contains("lowered"),
        "{}",
        study.density_reason
    );
    assert!(study.texel_density > 0.0 && study.texel_density < 256.0);
    assert_eq!(rows, study.rows.len());
    assert!(rows > 0);
    assert!(study.rows.iter().all(|r| r.measured.is_finite()));
    for k in &study.skipped {
        assert!(
            k.reason.contains("MiB") || k.reason.contains("solver"),
            "{k:?}"
        );
    }
    assert!(study.markdown().contains("lowered from"));
    println!("{}", study.markdown());
}
