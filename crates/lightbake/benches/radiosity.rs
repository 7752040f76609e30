//! Radiosity: transport build and every solver on the same system, for the Cornell box at its
//! default density (256 texels/m, 128 rays per node) and the furnace at ρ = 0.99. Prints a
//! table of time and iterations to a relative residual of 10⁻³ (what `docs/benchmarks.md`
//! records), then criterion measures one sweep / iteration of each solver.
//!
//! `cargo bench -p lightbake --bench radiosity`

#![allow(missing_docs)] // criterion_group! and criterion_main! generate undocumented items

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{DVec3, Vec3};
use lightbake::context::Prepared;
use lightbake::progress::Progress;
use lightbake::radiosity::stochastic_jacobi::{self, StochasticOptions};
use lightbake::radiosity::{HitMapper, Nodes, monte_carlo};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, furnace_box};
use lightbake::settings::BakeSettings;
use lightbake::settings::Basis;
use lightbake::settings::SolverChoice;
use lightbake::solve::Transport;
use lightbake::solve::shooting;
use lightbake::solve::{self, SolveOptions};

struct Case {
    prep: Prepared,
    nodes: Nodes,
    transport: Transport,
    source: Vec<Vec3>,
}

fn case(name: &str, scene: &Scene, density: Option<f32>) -> Case {
    let mut settings = BakeSettings::medium();
    if let Some(d) = density {
        settings.layout.texel_density = Some(d);
        settings.layout.texel_density_from_scene = false;
    }
    let prep = Prepared::new(scene, &settings).expect("prepare");
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Linear);
    let direct = lightbake::direct::direct_irradiance(&prep.ctx());
    let source = lightbake::radiosity::source(&nodes, &direct);
    let start = Instant::now();
    let transport = monte_carlo::build(
        &ctx,
        &nodes,
        settings.radiosity.transport_rays,
        Basis::Linear,
        &Progress::new(),
    );
    eprintln!(
        "{name}: {} nodes; transport {:.2} s, {} rays, {} entries, {:.1} MiB",
        nodes.len(),
        start.elapsed().as_secs_f64(),
        transport.rays,
        transport.nnz(),
        transport.bytes() as f64 / 1048576.0
    );
    Case {
        prep,
        nodes,
        transport,
        source,
    }
}

fn table(name: &str, c: &Case) {
    let system = lightbake::radiosity::system(&c.transport, &c.nodes, &c.source);
    let options = SolveOptions {
        tolerance: 1e-3,
        max_iterations: 100_000,
    };
    eprintln!("{name}: solver, seconds, iterations to relative residual 1e-3");
    for choice in [
        SolverChoice::Jacobi,
        SolverChoice::GaussSeidel,
        SolverChoice::Shooting,
        SolverChoice::Krylov,
        SolverChoice::KrylovCg,
        SolverChoice::Direct,
    ] {
        if choice == SolverChoice::Direct && c.nodes.len() > solve::DIRECT_MAX_NODES {
            eprintln!(
                "  direct: skipped ({} nodes > {})",
                c.nodes.len(),
                solve::DIRECT_MAX_NODES
            );
            continue;
        }
        let start = Instant::now();
        let s = solve::solve_matrix(choice, &system, &options);
        eprintln!(
            "  {:<18} {:>8.3} s {:>9.1}  {}",
            s.solver,
            start.elapsed().as_secs_f64(),
            s.iterations,
            s.stop_reason
        );
    }
    let ctx = c.prep.ctx();
    let mapper = HitMapper::new(ctx, &c.nodes, Basis::Linear);
    let start = Instant::now();
    let options = StochasticOptions {
        first_iteration_rays: c.nodes.len() as u64 * 64,
        tolerance: 1e-3,
        max_iterations: 100_000,
    };
    let s = stochastic_jacobi::solve(
        &ctx,
        &c.nodes,
        &mapper,
        &c.source,
        &options,
        &Progress::new(),
    );
    eprintln!(
        "  {:<18} {:>8.3} s {:>9.1}  {} ({} rays, matrix-free)",
        s.solver,
        start.elapsed().as_secs_f64(),
        s.iterations,
        s.stop_reason,
        s.rays
    );
}

fn solvers(c: &mut Criterion) {
    let cornell = case("cornell_box", &cornell_box(CornellLight::Area), None);
    table("cornell_box", &cornell);
    let furnace = case("furnace ρ=0.99", &furnace_box(1.0, 0.99, 100.0), Some(32.0));
    table("furnace ρ=0.99", &furnace);
    // The same box, not emitting but lit by an off-centre point light: a stiff system whose
    // source is not an eigenvector (in the uniform furnace it is, and Krylov methods finish
    // in one step).
    let mut lamp_box = furnace_box(1.0, 0.99, 0.0);
    lamp_box.lights.push(lightbake::scene::Light {
        name: "lamp".into(),
        kind: lightbake::scene::LightKind::Point,
        color: Vec3::ONE,
        intensity: 10.0,
        range: None,
        position: Vec3::new(0.3, -0.35, 0.2),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    let lamp = case("closed box ρ=0.99, point light", &lamp_box, Some(32.0));
    table("closed box ρ=0.99, point light", &lamp);

    let mut g = c.benchmark_group("radiosity_cornell");
    g.sample_size(10);
    let n = cornell.nodes.len();
    let x: Vec<DVec3> = solve::to_f64(&cornell.source);
    let mut y = vec![DVec3::ZERO; n];
    g.bench_function("spmv_jacobi_sweep", |b| {
        b.iter(|| cornell.transport.mul64(black_box(&x), &mut y))
    });
    let system = lightbake::radiosity::system(&cornell.transport, &cornell.nodes, &cornell.source);
    let one = SolveOptions {
        tolerance: 1e-30,
        max_iterations: 1,
    };
    g.bench_function("gauss_seidel_sweep", |b| {
        b.iter(|| {
            black_box(solve::solve_matrix(
                SolverChoice::GaussSeidel,
                &system,
                &one,
            ))
        })
    });
    g.bench_function("bicgstab_iteration", |b| {
        b.iter(|| black_box(solve::solve_matrix(SolverChoice::Krylov, &system, &one)))
    });
    // Progressive refinement: the transpose it needs once, then 1 000 shots (one shooting
    // step is a thousandth of this).
    g.bench_function("shooting_transpose", |b| {
        b.iter(|| black_box(cornell.transport.transpose()))
    });
    let columns = cornell.transport.transpose();
    g.bench_function("shooting_1000_shots", |b| {
        b.iter(|| {
            let mut rec = solve::Recorder::new(None);
            black_box(shooting::shoot_columns(
                &system, &columns, &one, 1000, &mut rec,
            ))
        })
    });
    // One stochastic Jacobi iteration at the bake's first-iteration budget (64 rays per node).
    let ctx = cornell.prep.ctx();
    let mapper = HitMapper::new(ctx, &cornell.nodes, Basis::Linear);
    let first = StochasticOptions {
        first_iteration_rays: n as u64 * 64,
        tolerance: 1e-30,
        max_iterations: 1,
    };
    g.bench_function("stochastic_jacobi_iteration_64_rays_per_node", |b| {
        b.iter(|| {
            black_box(stochastic_jacobi::solve(
                &ctx,
                &cornell.nodes,
                &mapper,
                &cornell.source,
                &first,
                &Progress::new(),
            ))
        })
    });
    g.finish();

    let small = case(
        "cornell_box 64/m",
        &cornell_box(CornellLight::Area),
        Some(64.0),
    );
    let mut g = c.benchmark_group("form_factors");
    g.sample_size(10);
    let ctx = small.prep.ctx();
    g.bench_function("monte_carlo_128_rays_cornell_64", |b| {
        b.iter(|| {
            black_box(monte_carlo::build(
                &ctx,
                &small.nodes,
                128,
                Basis::Linear,
                &Progress::new(),
            ))
        })
    });
    g.finish();
}

criterion_group!(benches, solvers);
criterion_main!(benches);
