//! The hierarchical solve (a coarse solve over texel clusters, then a per-texel final gather)
//! against the full transport matrix on the shipped scenes; its error estimate sees a coarse
//! level that is too coarse; its refinement reaches the tolerance; `auto` takes it beyond the
//! full matrix's node limit and says why. (The furnace at ρ = 0.3 … 0.999, the hard furnace
//! and the thread-count determinism cover it with the other solvers.)

mod common;

use lightbake::BakeOutput;
use lightbake::analysis::study::relative_rms_error;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, SolverChoice};

/// The medium preset at `density` texels/m with `solver`.
fn settings(density: f32, solver: SolverChoice) -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.texel_density = Some(density);
    s.texel_density_from_scene = false;
    s.solver = solver;
    s
}

/// The radiosity stage's own error estimate (relative RMS), and the hierarchical solve's
/// bias part of it.
fn radiosity_estimate(out: &BakeOutput) -> (f64, Option<f64>) {
    let stage = out
        .report
        .stages
        .iter()
        .find(|s| s.name == "error estimate")
        .expect("an error estimate stage");
    let radiosity = out.report.radiosity.as_ref().expect("a radiosity report");
    (
        stage.error.as_ref().expect("an estimate").relative_rms,
        radiosity.coarse_bias,
    )
}

/// The full matrix (BiCGStab) and the hierarchical solve of `scene` at `density`, with the
/// same seed: the final gather's rays are the matrix rows' rays, so the two differ only by
/// what the coarse level contributes (its bias, and the correction's noise).
fn both(
    scene: &Scene,
    density: f32,
    adjust: impl Fn(&mut BakeSettings),
) -> (BakeOutput, BakeOutput) {
    let full = common::bake(scene, &settings(density, SolverChoice::Krylov));
    let mut s = settings(density, SolverChoice::Hierarchical);
    adjust(&mut s);
    let hierarchical = common::bake(scene, &s);
    (full, hierarchical)
}

#[test]
fn coarse_plus_gather_agrees_with_the_full_matrix_on_the_shipped_scenes() {
    for (scene, density) in [
        (cornell_box(CornellLight::Area), 128.0),
        (sunlit_room(), 16.0),
    ] {
        let (full, hierarchical) = both(&scene, density, |_| {});
        let diff = relative_rms_error(&hierarchical.pages, &full.pages);
        let (noise, _) = radiosity_estimate(&full);
        let (estimate, bias) = radiosity_estimate(&hierarchical);
        let coarse = hierarchical
            .report
            .radiosity
            .as_ref()
            .unwrap()
            .coarse
            .clone();
        println!(
            "{}: difference {diff:.4}, full matrix's estimate {noise:.4}, hierarchical estimate {estimate:.4} (bias {bias:?}), {coarse:?}",
            scene.name
        );
        // Within the full matrix's own noise, which the final gather shares.
        assert!(
            diff < noise,
            "{}: the solves differ by {diff:.4}, more than the full matrix's estimated error {noise:.4}",
            scene.name
        );
        // The hierarchical estimate is about the full matrix's noise (each is estimated by
        // its own re-gathers) plus a little for the coarse level: neither blind to it nor
        // inflated.
        assert!(
            estimate > 0.95 * noise && estimate < 1.3 * noise,
            "{}: estimate {estimate:.4} against the full matrix's {noise:.4}",
            scene.name
        );
        assert!(
            hierarchical.pages.iter().all(|p| p
                .texels
                .iter()
                .all(|t| t.is_finite() && t.min_element() >= 0.0)),
            "{}: a texel is negative or not finite",
            scene.name
        );
    }
}

#[test]
fn the_error_estimate_sees_a_coarse_level_that_is_too_coarse() {
    // One cell per chart's 256 × 256 texels and no refinement: the coarse level is a handful
    // of cells, and what it misses from the third bounce on shows as a bias the estimate
    // must report (it would not, were the bias term left out: the gather's noise is the same
    // as the refined solve's).
    let scene = cornell_box(CornellLight::Area);
    let (full, refined) = both(&scene, 128.0, |_| {});
    let (_, coarse) = both(&scene, 128.0, |s| {
        s.cluster_texels = 256;
        s.cluster_tolerance = 0.99;
    });
    let refined_diff = relative_rms_error(&refined.pages, &full.pages);
    let coarse_diff = relative_rms_error(&coarse.pages, &full.pages);
    let (_, refined_bias) = radiosity_estimate(&refined);
    let (_, coarse_bias) = radiosity_estimate(&coarse);
    let (refined_bias, coarse_bias) = (refined_bias.unwrap(), coarse_bias.unwrap());
    println!(
        "refined: difference {refined_diff:.4}, bias estimate {refined_bias:.4}; coarse: difference {coarse_diff:.4}, bias estimate {coarse_bias:.4}"
    );
    assert!(
        coarse_diff > 2.0 * refined_diff,
        "the coarse level should be visibly worse ({coarse_diff:.4} against {refined_diff:.4})"
    );
    assert!(
        coarse_bias > 0.5 * coarse_diff && coarse_bias < 1.5 * coarse_diff,
        "bias estimate {coarse_bias:.4} against the measured difference {coarse_diff:.4}"
    );
    assert!(refined_bias < coarse_bias / 3.0);
}

#[test]
fn refinement_splits_cells_until_the_missed_detail_is_within_the_tolerance() {
    let scene = sunlit_room();
    let mut s = settings(24.0, SolverChoice::Hierarchical);
    s.cluster_texels = 16;
    s.cluster_tolerance = 0.004;
    let out = common::bake(&scene, &s);
    let coarse = out.report.radiosity.unwrap().coarse.unwrap();
    println!("{coarse:?}");
    assert!(coarse.rounds > 1, "{coarse:?}");
    // Cells were split below the first cut's level…
    assert!(
        coarse.cells_per_level[..4].iter().sum::<usize>() > 0,
        "{coarse:?}"
    );
    // …until the detail left is within the tolerance, or the report says what stopped it.
    assert!(
        coarse.missed_detail <= 0.004 || !coarse.stop_reason.contains("within"),
        "{coarse:?}"
    );
}

#[test]
fn auto_takes_the_hierarchical_solve_beyond_the_full_matrix_limit_and_says_why() {
    let scene = cornell_box(CornellLight::Area);
    let out = common::bake(&scene, &settings(128.0, SolverChoice::Auto));
    let radiosity = out.report.radiosity.as_ref().unwrap();
    assert!(radiosity.nodes > lightbake::solve::AUTO_MATRIX_NODES);
    assert_eq!(
        radiosity.solver, "hierarchical",
        "{}",
        radiosity.solver_reason
    );
    assert!(
        radiosity.solver_reason.contains("linear in the nodes"),
        "{}",
        radiosity.solver_reason
    );
    assert_eq!(radiosity.transport_nnz, 0, "no full matrix is built");
    let small = common::bake(&scene, &settings(32.0, SolverChoice::Auto));
    let radiosity = small.report.radiosity.as_ref().unwrap();
    assert!(radiosity.nodes <= lightbake::solve::AUTO_MATRIX_NODES);
    assert_ne!(
        radiosity.solver, "hierarchical",
        "{}",
        radiosity.solver_reason
    );
}
