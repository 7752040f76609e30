//! Radiosity against known answers: the closed furnace B = E/(1 − ρ) for every solver;
//! every iterative solver against the dense LU solve; form factors of parallel and
//! perpendicular squares (Monte Carlo and hemicube) against their closed forms, with
//! reciprocity; energy balance; colour bleeding in the Cornell box.

mod common;

use common::{radiosity_settings, two_squares};
use lightbake::Stage;

use glam::{Affine3A, DVec3, Vec3};
use lightbake::context::Prepared;
use lightbake::progress::Progress;
use lightbake::radiosity::{Nodes, hemicube::build_hemicube, monte_carlo};
use lightbake::scene::testscenes::{CornellLight, cornell_box, furnace_box};
use lightbake::scene::{Light, LightKind, Material, Mesh, Scene};
use lightbake::settings::Basis;
use lightbake::settings::SolverChoice;
use lightbake::settings::{BakeSettings, Method};
use lightbake::solve::Transport;
use lightbake::solve::{self, SolveOptions, System};

#[test]
fn furnace_gives_e_over_one_minus_rho_for_every_solver() {
    let luminance = 100.0f32;
    for rho in [0.3f32, 0.9, 0.99, 0.999] {
        let scene = furnace_box(1.0, rho, luminance);
        for solver in common::ALL_SOLVERS {
            let stiff_capable = matches!(
                solver,
                SolverChoice::Krylov
                    | SolverChoice::KrylovCg
                    | SolverChoice::Direct
                    | SolverChoice::Hierarchical
            );
            if rho > 0.99 && !stiff_capable {
                continue;
            }
            let mut settings = radiosity_settings(8.0, solver);
            settings.radiosity.solver_tolerance = 2e-3;
            // Stochastic Jacobi shoots about N₀/(1 − ρ) rays in all: fewer per node when stiff.
            settings.radiosity.stochastic_rays_per_node = if rho >= 0.99 { 256 } else { 1024 };
            let out = common::bake(&scene, &settings);
            let expected = luminance / (1.0 - rho);
            let values: Vec<f32> = common::texels(&out, 0).iter().map(|t| t.value.x).collect();
            assert!(
                values.iter().all(|v| v.is_finite()),
                "{solver:?} ρ={rho}: non-finite texel"
            );
            let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64;
            let worst = values
                .iter()
                .map(|&v| common::rel(v, expected))
                .fold(0.0f32, f32::max);
            let rms = (values
                .iter()
                .map(|&v| common::rel(v, expected).powi(2) as f64)
                .sum::<f64>()
                / values.len() as f64)
                .sqrt();
            let report = out.report.radiosity.as_ref().unwrap();
            let why = &report.solution.stop_reason;
            assert!(
                common::rel(mean as f32, expected) < 0.01,
                "{solver:?} ρ={rho}: mean {mean} vs {expected} ({why})"
            );
            if solver == SolverChoice::StochasticJacobi {
                // Unbiased (the mean above); each texel carries Monte Carlo noise.
                assert!(rms < 0.05, "{solver:?} ρ={rho}: RMS {rms} ({why})");
            } else {
                assert!(worst < 0.01, "{solver:?} ρ={rho}: worst {worst} ({why})");
            }
            assert!(
                report.solution.converged,
                "{solver:?} ρ={rho}: {}",
                report.solution.stop_reason
            );
        }
    }
}

/// A small Cornell box prepared for direct solver comparisons.
fn small_cornell() -> (Prepared, Nodes, Transport, Vec<Vec3>) {
    let scene = cornell_box(CornellLight::Area);
    let settings = radiosity_settings(20.0, SolverChoice::Direct);
    let prep = Prepared::new(&scene, &settings).unwrap();
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Linear);
    let transport = monte_carlo::build(&ctx, &nodes, 64, Basis::Linear, &Progress::new());
    let direct = lightbake::direct::direct_irradiance(&prep.ctx());
    let source = lightbake::radiosity::source(&nodes, &direct);
    (prep, nodes, transport, source)
}

fn rel_diff(a: &[Vec3], b: &[Vec3], area: &[f32]) -> (f64, f64) {
    let (da, db): (Vec<DVec3>, Vec<DVec3>) = (solve::to_f64(a), solve::to_f64(b));
    let diff: Vec<DVec3> = da.iter().zip(&db).map(|(x, y)| *x - *y).collect();
    (
        solve::norm(&diff, area) / solve::norm(&db, area),
        solve::max_norm(&diff) / solve::max_norm(&db),
    )
}

#[test]
fn iterative_solvers_agree_with_the_dense_solve() {
    let (_prep, nodes, transport, source) = small_cornell();
    assert!(
        nodes.len() > 300 && nodes.len() < 2000,
        "{} nodes",
        nodes.len()
    );
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let options = SolveOptions {
        tolerance: 1e-7,
        max_iterations: 100_000,
    };
    let reference = solve::solve_matrix(SolverChoice::Direct, &system, &options);
    for solver in [
        SolverChoice::Jacobi,
        SolverChoice::GaussSeidel,
        SolverChoice::Shooting,
        SolverChoice::Krylov,
    ] {
        let s = solve::solve_matrix(solver, &system, &options);
        let (rms, max) = rel_diff(&s.b, &reference.b, &nodes.area);
        assert!(
            rms < 1e-4 && max < 1e-4,
            "{solver:?}: rms {rms:.2e} max {max:.2e} ({})",
            s.stop_reason
        );
        // The history ends at the tolerance and the residuals fall.
        let h = &s.history;
        assert!(
            h.last().unwrap().residual < 2e-7
                && h.first().unwrap().residual > h.last().unwrap().residual
        );
    }
    // CG solves the reciprocity-symmetrised system: compare with LU of that system.
    let sym = transport.symmetrized(&nodes.area);
    let sym_system = System {
        transport: &sym,
        ..system
    };
    let sym_reference = solve::solve_matrix(SolverChoice::Direct, &sym_system, &options);
    let cg = solve::solve_matrix(SolverChoice::KrylovCg, &system, &options);
    let (rms, max) = rel_diff(&cg.b, &sym_reference.b, &nodes.area);
    assert!(rms < 1e-4 && max < 1e-4, "CG: rms {rms:.2e} max {max:.2e}");
    // The symmetrised system is close to the original (Monte Carlo noise apart).
    let (rms, _) = rel_diff(&sym_reference.b, &reference.b, &nodes.area);
    assert!(rms < 0.05, "symmetrisation moved B by {rms}");
}

/// The error bounds in the solvers' histories hold: at a loose and a tight tolerance, the
/// last entry's bound is at least the true ∞-norm error against the dense solve, and
/// BiCGStab (the default) has a bound at every iteration.
#[test]
fn solver_error_bounds_hold_against_the_dense_solve() {
    let (_prep, nodes, transport, source) = small_cornell();
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let reference = solve::solve_matrix(SolverChoice::Direct, &system, &SolveOptions::default());
    for solver in [
        SolverChoice::Jacobi,
        SolverChoice::GaussSeidel,
        SolverChoice::Krylov,
    ] {
        for tolerance in [3e-2, 1e-4] {
            let options = SolveOptions {
                tolerance,
                max_iterations: 100_000,
            };
            let s = solve::solve_matrix(solver, &system, &options);
            let bound = s.history.last().unwrap().error_bound.unwrap();
            let (_, max) = rel_diff(&s.b, &reference.b, &nodes.area);
            assert!(
                max > 0.0 && max <= bound * 1.05,
                "{solver:?} at {tolerance:e}: error {max:.3e} above its bound {bound:.3e}"
            );
            if solver == SolverChoice::Krylov {
                assert!(s.history.iter().all(|h| h.error_bound.is_some()));
            }
        }
    }
}

#[test]
fn stochastic_jacobi_converges_to_the_dense_solve() {
    let (prep, nodes, _, source) = small_cornell();
    // A reference with little noise of its own.
    let transport = monte_carlo::build(&prep.ctx(), &nodes, 4096, Basis::Linear, &Progress::new());
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let reference = solve::solve_matrix(SolverChoice::Direct, &system, &SolveOptions::default());
    let ctx = prep.ctx();
    let mapper = lightbake::radiosity::HitMapper::new(ctx, &nodes, Basis::Linear);
    let mut errors = Vec::new();
    for rays_per_node in [256u64, 4096] {
        let options = lightbake::radiosity::stochastic_jacobi::StochasticOptions {
            first_iteration_rays: nodes.len() as u64 * rays_per_node,
            tolerance: 1e-4,
            max_iterations: 100,
        };
        let s = lightbake::radiosity::stochastic_jacobi::solve(
            &ctx,
            &nodes,
            &mapper,
            &source,
            &options,
            &Progress::new(),
        );
        // Compare the reflected irradiance F·B, what the lightmap adds.
        errors.push(rel_diff(&s.indirect, &reference.indirect, &nodes.area).0);
    }
    // Both are Monte Carlo estimates of the same Galerkin system (the matrix with 4096 rays
    // per node, itself about 1% noisy per node); 16× the rays bring the stochastic estimate
    // markedly closer. What remains (about 2%) is where shooting and gathering differ at
    // chart borders, where the bilinear weights are renormalised.
    assert!(
        errors[1] < 0.03 && errors[1] < 0.7 * errors[0],
        "{errors:?}"
    );
}

/// Closed form: identical, parallel, directly opposed rectangles a × b at distance c.
fn parallel_rectangles(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (x2, y2) = (x * x, y * y);
    2.0 / (std::f64::consts::PI * x * y)
        * ((((1.0 + x2) * (1.0 + y2)) / (1.0 + x2 + y2)).sqrt().ln()
            + x * (1.0 + y2).sqrt() * (x / (1.0 + y2).sqrt()).atan()
            + y * (1.0 + x2).sqrt() * (y / (1.0 + x2).sqrt()).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Closed form: perpendicular rectangles with a common edge of length l, widths w (from)
/// and h (to) (Howell's catalogue C-14).
fn perpendicular_rectangles(l: f64, w: f64, h: f64) -> f64 {
    let (hh, ww) = (h / l, w / l);
    let (h2, w2) = (hh * hh, ww * ww);
    let log = ((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2)).ln()
        + w2 * (w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2))).ln()
        + h2 * (h2 * (1.0 + h2 + w2) / ((1.0 + h2) * (h2 + w2))).ln();
    (ww * (1.0 / ww).atan() + hh * (1.0 / hh).atan()
        - (h2 + w2).sqrt() * (1.0 / (h2 + w2).sqrt()).atan()
        + 0.25 * log)
        / (std::f64::consts::PI * ww)
}

#[test]
fn closed_forms_are_right() {
    assert!((parallel_rectangles(1.0, 1.0, 1.0) - 0.19982).abs() < 1e-4);
    assert!((perpendicular_rectangles(1.0, 1.0, 1.0) - 0.20004).abs() < 1e-4);
}

/// Builds a transport matrix for the nodes at a multiple of the base ray count.
type Builder<'a> = dyn Fn(&Nodes, u32) -> Transport + 'a;

#[test]
fn form_factors_match_closed_forms_and_reciprocity() {
    for perpendicular in [false, true] {
        let scene = two_squares(perpendicular);
        let settings = radiosity_settings(24.0, SolverChoice::Auto);
        let prep = Prepared::new(&scene, &settings).unwrap();
        let ctx = prep.ctx();
        let expected = if perpendicular {
            perpendicular_rectangles(1.0, 1.0, 1.0)
        } else {
            parallel_rectangles(1.0, 1.0, 1.0)
        };
        let progress = Progress::new();
        let builds: [(&str, Basis, &Builder); 3] = [
            ("monte carlo, linear", Basis::Linear, &|n, k| {
                monte_carlo::build(&ctx, n, 128 * k, Basis::Linear, &progress)
            }),
            ("monte carlo, constant", Basis::Constant, &|n, k| {
                monte_carlo::build(&ctx, n, 128 * k, Basis::Constant, &progress)
            }),
            ("hemicube", Basis::Constant, &|n, k| {
                build_hemicube(&ctx, n, 32 * k, &progress)
            }),
        ];
        for (name, basis, build) in builds {
            let nodes = Nodes::new(&ctx, basis);
            let of = |inst: u32| -> Vec<u32> {
                (0..nodes.len() as u32)
                    .filter(|&i| {
                        prep.patches.patches[nodes.patch[i as usize] as usize].instance == inst
                    })
                    .collect()
            };
            let (a, b) = (of(0), of(1));
            // Quadrants of both squares, for reciprocity between blocks of nodes.
            let quadrant = |i: u32| {
                let p = &prep.patches.patches[nodes.patch[i as usize] as usize];
                let c = p.position;
                (
                    p.instance,
                    (c.x > 0.5) as u8 + 2 * ((c.z.max(c.y)) > 0.5) as u8,
                )
            };
            let blocks: Vec<Vec<u32>> = (0..2u32)
                .flat_map(|inst| (0..4u8).map(move |q| (inst, q)))
                .map(|key| {
                    (0..nodes.len() as u32)
                        .filter(|&i| quadrant(i) == key)
                        .collect()
                })
                .collect();
            let block_area = |bl: &[u32]| {
                bl.iter()
                    .map(|&i| nodes.area[i as usize] as f64)
                    .sum::<f64>()
            };
            let mut asymmetry = Vec::new();
            for k in [1u32, 4] {
                let t = build(&nodes, k);
                let check = t.validate(&nodes.area).unwrap();
                assert!(check.max_row_sum <= 1.0 + 1e-4);
                let fab = t.block_form_factor(&nodes.area, &a, &b);
                let fba = t.block_form_factor(&nodes.area, &b, &a);
                assert!(
                    (fab - expected).abs() / expected < 0.02,
                    "{name} ×{k}, perpendicular {perpendicular}: F_ab {fab:.5} vs {expected:.5}"
                );
                // Equal areas: reciprocity says F_ab = F_ba.
                assert!(
                    (fab - fba).abs() / expected < 0.02,
                    "{name} ×{k}: F_ab {fab} F_ba {fba}"
                );
                // Quadrant to quadrant: A_I·F_IJ against A_J·F_JI.
                let mut worst = 0.0f64;
                for bi in &blocks[..4] {
                    for bj in &blocks[4..] {
                        let x = block_area(bi) * t.block_form_factor(&nodes.area, bi, bj);
                        let y = block_area(bj) * t.block_form_factor(&nodes.area, bj, bi);
                        worst = worst.max((x - y).abs() / (0.5 * (x + y)));
                    }
                }
                asymmetry.push(worst);
            }
            assert!(
                asymmetry[1] < 0.06,
                "{name}, perpendicular {perpendicular}: quadrant asymmetry {asymmetry:?}"
            );
        }
    }
}

#[test]
fn energy_is_conserved() {
    // An open unit box (no +Z face) with a point light at its centre: a sixth of the power
    // leaves directly through the opening.
    let mut scene = Scene::default();
    let mat = scene.add_material(Material::diffuse("wall", Vec3::new(0.7, 0.5, 0.3)));
    let mut inner =
        lightbake::scene::testscenes::cuboid("box", Vec3::splat(-0.5), Vec3::splat(0.5), false);
    // Drop the +Z face (its two triangles), then turn the rest inwards.
    let keep: Vec<u32> = inner
        .indices
        .chunks_exact(3)
        .filter(|t| !t.iter().all(|&i| inner.positions[i as usize].z > 0.49))
        .flatten()
        .copied()
        .collect();
    inner.indices = keep;
    for t in inner.indices.chunks_exact_mut(3) {
        t.swap(1, 2);
    }
    for n in &mut inner.normals {
        *n = -*n;
    }
    let id = scene.add_mesh(Mesh {
        material: Some(mat),
        ..inner
    });
    scene.instances.push(lightbake::scene::Instance::new(
        "box",
        id,
        Affine3A::IDENTITY,
    ));
    let intensity = 10.0f32;
    scene.lights.push(Light {
        name: "bulb".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity,
        range: None,
        position: Vec3::ZERO,
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    let mut settings = radiosity_settings(32.0, SolverChoice::GaussSeidel);
    settings.radiosity.transport_rays = 256;
    settings.direct.samples_per_texel = 16;
    let prep = Prepared::new(&scene, &settings).unwrap();
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Linear);
    assert_eq!(
        nodes.len(),
        prep.patches.patches.len(),
        "every texel of the box is valid"
    );
    let transport = monte_carlo::build(
        &ctx,
        &nodes,
        settings.radiosity.transport_rays,
        Basis::Linear,
        &Progress::new(),
    );
    let direct = lightbake::direct::direct_irradiance(&prep.ctx());
    let source = lightbake::radiosity::source(&nodes, &direct);
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let s = solve::solve_matrix(
        SolverChoice::GaussSeidel,
        &system,
        &SolveOptions {
            tolerance: 1e-6,
            max_iterations: 1000,
        },
    );
    let emitted = 4.0 * std::f64::consts::PI * intensity as f64; // per channel, white light
    let escaped_direct = emitted / 6.0;
    let (mut absorbed, mut escaped_reflected) = (DVec3::ZERO, DVec3::ZERO);
    for i in 0..nodes.len() {
        let h = (direct[nodes.patch[i] as usize] + s.indirect[i]).as_dvec3();
        let rho = nodes.albedo[i].as_dvec3();
        let a = nodes.area[i] as f64;
        absorbed += (DVec3::ONE - rho) * h * a;
        escaped_reflected += s.b[i].as_dvec3() * a * transport.escaped[i] as f64;
    }
    let total = absorbed + escaped_reflected + DVec3::splat(escaped_direct);
    for c in 0..3 {
        let err = (total[c] - emitted).abs() / emitted;
        assert!(
            err < 0.005,
            "channel {c}: absorbed {} + escaped {} + {escaped_direct} vs emitted {emitted} ({err:.4})",
            absorbed[c],
            escaped_reflected[c]
        );
    }
}

#[test]
fn cornell_box_bleeds_colour_and_lights_the_ceiling() {
    let scene = cornell_box(CornellLight::Area);
    let settings = radiosity_settings(48.0, SolverChoice::Auto);
    let out = common::bake(&scene, &settings);
    let index = |name: &str| scene.instances.iter().position(|i| i.name == name).unwrap();
    let floor = common::texels(&out, index("floor"));
    // Red wall at x ≈ −0.28, green at x ≈ +0.28 (see testscenes::cornell_box).
    let ratio = |sel: &dyn Fn(f32) -> bool| {
        let (mut r, mut g) = (0.0f64, 0.0f64);
        for t in floor
            .iter()
            .filter(|t| sel(t.position.x) && t.position.z > 0.1)
        {
            r += t.value.x as f64;
            g += t.value.y as f64;
        }
        r / g
    };
    let near_red = ratio(&|x| x < -0.22);
    let near_green = ratio(&|x| x > 0.22);
    assert!(
        near_red > near_green * 1.05,
        "R/G near red {near_red:.3}, near green {near_green:.3}"
    );
    // The ceiling gets no direct light from the downward-facing lamp: all it has is indirect.
    let ceiling = common::texels(&out, index("ceiling"));
    let lit = ceiling
        .iter()
        .filter(|t| t.value.min_element() > 0.5)
        .count();
    assert!(
        lit > ceiling.len() * 9 / 10,
        "{lit} of {} ceiling texels lit",
        ceiling.len()
    );
    let direct_only = common::bake(
        &scene,
        &BakeSettings {
            method: Method::Direct,
            ..settings.clone()
        },
    );
    let dark = common::texels(&direct_only, index("ceiling"))
        .iter()
        .filter(|t| t.value.max_element() > 0.0)
        .count();
    assert!(
        dark < ceiling.len() / 10,
        "{dark} ceiling texels have direct light"
    );
    let report = out.report.radiosity.as_ref().unwrap();
    assert!(report.solution.converged && out.report.plan.runs(Stage::Indirect));
}

#[test]
fn shooting_ambient_term_improves_a_partial_solution() {
    let (_prep, nodes, transport, source) = small_cornell();
    let system = lightbake::radiosity::system(&transport, &nodes, &source);
    let reference = solve::solve_matrix(SolverChoice::Direct, &system, &SolveOptions::default());
    let mut rec = solve::Recorder::new(None);
    let (state, _) = solve::shooting::shoot(
        &system,
        &SolveOptions::default(),
        nodes.len() as u64 / 4,
        &mut rec,
    );
    let plain = solve::to_f32(&state.b);
    let shown = solve::shooting::display(&system, &state.b, &state.unshot);
    let (err_plain, _) = rel_diff(&plain, &reference.b, &nodes.area);
    let (err_shown, _) = rel_diff(&shown, &reference.b, &nodes.area);
    assert!(
        err_shown < err_plain * 0.7,
        "ambient: {err_shown:.3} vs without: {err_plain:.3}"
    );
}

#[test]
fn krylov_needs_far_fewer_iterations_than_jacobi_when_stiff() {
    for rho in [0.99f32, 0.999] {
        let scene = furnace_box(1.0, rho, 100.0);
        // Perturb: a non-uniform source so the problem is not solved by the first iterate.
        let settings = radiosity_settings(6.0, SolverChoice::Direct);
        let prep = Prepared::new(&scene, &settings).unwrap();
        let ctx = prep.ctx();
        let nodes = Nodes::new(&ctx, Basis::Linear);
        let transport = monte_carlo::build(&ctx, &nodes, 64, Basis::Linear, &Progress::new());
        let source: Vec<Vec3> = (0..nodes.len())
            .map(|i| Vec3::splat(if i % 7 == 0 { 1.0 } else { 0.0 }))
            .collect();
        let system = lightbake::radiosity::system(&transport, &nodes, &source);
        let options = SolveOptions {
            tolerance: 1e-6,
            max_iterations: 50_000,
        };
        let jacobi = solve::solve_matrix(SolverChoice::Jacobi, &system, &options);
        let krylov = solve::solve_matrix(SolverChoice::Krylov, &system, &options);
        let cg = solve::solve_matrix(SolverChoice::KrylovCg, &system, &options);
        assert!(jacobi.converged && krylov.converged && cg.converged);
        // Jacobi needs about ln(ε)/ln(ρ) sweeps; the Krylov methods about its square root.
        let predicted = (1e-6f64).ln() / (rho as f64).ln();
        assert!(
            jacobi.iterations > 0.5 * predicted,
            "ρ={rho}: Jacobi {} vs {predicted}",
            jacobi.iterations
        );
        assert!(
            krylov.iterations * 10.0 < jacobi.iterations,
            "ρ={rho}: BiCGStab {} Jacobi {}",
            krylov.iterations,
            jacobi.iterations
        );
        assert!(
            cg.iterations * 10.0 < jacobi.iterations,
            "ρ={rho}: CG {} Jacobi {}",
            cg.iterations,
            jacobi.iterations
        );
        eprintln!(
            "ρ = {rho}: Jacobi {} sweeps, BiCGStab {} iterations, CG {} iterations",
            jacobi.iterations, krylov.iterations, cg.iterations
        );
    }
}
