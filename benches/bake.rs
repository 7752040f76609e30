//! Whole bakes and their stages: the Cornell box (area light, at its 256 texels/m hint) and
//! the sunlit room, at the default (medium) settings. Per-stage times of one bake are printed
//! from the bake report before criterion measures the whole. Results: `docs/benchmarks.md`.
//!
//! `cargo bench --bench bake`

#![allow(missing_docs)] // criterion_group! and criterion_main! generate undocumented items

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use lightbake::bvh::RayScene;
use lightbake::progress::Progress;
use lightbake::raster::Patches;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::BakeSettings;
use lightbake::unwrap::unwrap_scene;

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
    g.finish();
}

criterion_group!(benches, bakes, stages);
criterion_main!(benches);
