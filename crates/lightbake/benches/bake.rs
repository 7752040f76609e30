//! Whole bakes and their stages: the Cornell box (area light, at its 256 texels/m hint) and
//! the sunlit room, at the default (medium) settings. Per-stage times of one bake are printed
//! from the bake report before criterion measures the whole. Results: `docs/benchmarks.md`.
//!
//! Also each lighting pass on a prepared Cornell box: direct light, the instant-radiosity walk
//! and gather, and the re-gather behind the radiosity error estimate.
//!
//! And the irradiance volume stage on the finished bakes of both scenes, at the default
//! spacing and rays.
//!
//! `cargo bench -p lightbake --bench bake`

#![allow(missing_docs)] // criterion_group! and criterion_main! generate undocumented items

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use lightbake::bvh::RayScene;
use lightbake::context::{BakeContext, Prepared};
use lightbake::direct::direct_light;
use lightbake::lights::Emitters;
use lightbake::probes::gather::Solution;
use lightbake::probes::{AutoSpacing, VolumeGrid, bake_volume};
use lightbake::progress::Progress;
use lightbake::radiosity::{self, Nodes, monte_carlo};
use lightbake::raster::Patches;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, Method, SolverChoice};
use lightbake::unwrap::unwrap_scene;
use lightbake::vpl::instant_radiosity;

fn bakes(c: &mut Criterion) {
    let settings = BakeSettings::medium();
    let mut g = c.benchmark_group("bake");
    g.sample_size(10);
    for scene in [
        cornell_box(CornellLight::Area),
        cornell_box(CornellLight::Point),
        sunlit_room(),
    ] {
        let out = lightbake::bake(&scene, &settings, &Progress::new()).expect("bake");
        eprintln!(
            "{} ({} texels):\n{}",
            scene.name,
            out.report.texels.patches,
            out.report.table()
        );
        g.bench_function(scene.name.clone(), |b| {
            b.iter(|| {
                black_box(lightbake::bake(&scene, &settings, &Progress::new()).expect("bake"))
            })
        });
    }
    g.finish();
}

fn stages(c: &mut Criterion) {
    let scene = cornell_box(CornellLight::Area);
    let settings = BakeSettings::medium();
    let mut g = c.benchmark_group("stages_cornell");
    g.sample_size(10);
    g.bench_function("unwrap", |b| {
        b.iter(|| black_box(unwrap_scene(&scene, &settings, 256.0).expect("unwrap")))
    });
    let layout = unwrap_scene(&scene, &settings, 256.0).expect("unwrap");
    let baked = layout.apply(&scene);
    let rays = RayScene::build(&baked);
    g.bench_function("raster", |b| {
        b.iter(|| black_box(Patches::build(&baked, &layout, &rays)))
    });
    g.bench_function("validity", |b| {
        b.iter(|| {
            let mut p = Patches::build(&baked, &layout, &rays);
            p.fix_validity(&baked, &layout, &rays);
            black_box(p.invalid)
        })
    });
    g.finish();

    // The lighting passes on a prepared scene (unwrap, raster and BVH done once).
    let prepared = Prepared::new(&scene, &settings).expect("prepare");
    let ctx = prepared.ctx();
    let emitters = Emitters::collect(&prepared.scene, &prepared.rays);
    let mut g = c.benchmark_group("passes_cornell");
    g.sample_size(10);
    g.bench_function("direct_medium_preset", |b| {
        b.iter(|| black_box(direct_light(&ctx, &emitters, &Progress::new())))
    });
    let direct = lightbake::direct::direct_irradiance(&prepared.ctx());
    // Keller's gather of every VPL (256 particles), and lightcuts of 64 nodes over the VPLs
    // of 16 384 particles.
    for (name, particles, cut) in [
        ("vpl_walk_and_gather_256", 256, 0),
        ("vpl_walk_and_lightcuts_16384_cut_64", 16_384, 64),
    ] {
        let mut vpl_settings = settings.clone();
        vpl_settings.method = Method::Hybrid;
        vpl_settings.vpl.particles = particles;
        vpl_settings.vpl.cut_size = cut;
        let vpl_ctx = BakeContext {
            settings: &vpl_settings,
            ..ctx
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                black_box(instant_radiosity(
                    &vpl_ctx,
                    &emitters,
                    false,
                    Some(&direct),
                    &Progress::new(),
                ))
            })
        });
    }
    let nodes = Nodes::new(&ctx, settings.radiosity.basis);
    // The re-gather reads a full-matrix solution (`auto` would take the hierarchical solve,
    // which runs as stages of its own).
    let krylov = {
        let mut s = settings.clone();
        s.radiosity.solver = SolverChoice::Krylov;
        s
    };
    let matrix_ctx = BakeContext {
        settings: &krylov,
        ..ctx
    };
    let (irr, _) = {
        let t = monte_carlo::build(
            &matrix_ctx,
            &nodes,
            32,
            settings.radiosity.basis,
            &Progress::new(),
        );
        let plan = radiosity::plan_solver(&matrix_ctx, &nodes).expect("plan");
        let source = radiosity::source(&nodes, &direct);
        let s = radiosity::solve_system(
            &matrix_ctx,
            &nodes,
            &plan,
            Some(&t),
            &source,
            &Progress::new(),
        );
        (s, t)
    };
    g.bench_function("error_estimate_regather", |b| {
        b.iter(|| {
            black_box(radiosity::gather_error(
                &ctx,
                &nodes,
                &irr.b,
                &irr.indirect,
                &direct,
                settings.radiosity.transport_rays,
            ))
        })
    });
    g.finish();
}

fn volumes(c: &mut Criterion) {
    let settings = BakeSettings::medium();
    let mut g = c.benchmark_group("irradiance_volume");
    g.sample_size(10);
    for scene in [cornell_box(CornellLight::Area), sunlit_room()] {
        let out = lightbake::bake(&scene, &settings, &Progress::new()).expect("bake");
        let density = out.report.plan.texel_density;
        let auto = AutoSpacing::of_texels(density);
        let grid = VolumeGrid::plan(&out.baked_scene, &out.layout, &settings, &auto, None)
            .expect("grid")
            .expect("baked instances");
        // One volume over the scene (each of these is one room).
        let rays = RayScene::build(&out.baked_scene);
        let emitters = Emitters::collect(&out.baked_scene, &rays);
        let solution = Solution {
            scene: &out.baked_scene,
            layout: &out.layout,
            pages: &out.pages,
            rays: &rays,
            emitters: &emitters,
        };
        let (_, stats) = bake_volume(
            &solution,
            grid.clone(),
            settings.volume.probe_rays,
            0,
            &Progress::new(),
        );
        eprintln!("{}: {stats:?}", scene.name);
        g.bench_function(format!("{}_{}_probes", scene.name, grid.len()), |b| {
            b.iter(|| {
                black_box(bake_volume(
                    &solution,
                    grid.clone(),
                    settings.volume.probe_rays,
                    0,
                    &Progress::new(),
                ))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bakes, stages, volumes);
criterion_main!(benches);
