//! Incremental bakes (`lightbake::incremental`) against full bakes of the same edited scene:
//! the Cornell box with its point light and the FZK house at the default (medium) settings,
//! each edit of `lightbake::analysis::edit_cases` that applies to the scene baked following
//! the unedited scene's cache, and in full. Results: `docs/benchmarks.md`.
//!
//! `cargo bench -p lightbake --features internals,testscenes --bench incremental`
//! (`-- house` for the house only; it takes about ten minutes).

#![allow(missing_docs)] // criterion_group! and criterion_main! generate undocumented items

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use lightbake::analysis::edit_cases::EditCase;
use lightbake::incremental::{BakeCache, Plan, plan};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::BakeSettings;
use lightbake::{BakeBuilder, BakeOutput, LightConvention};

fn bake(scene: &Scene, s: &BakeSettings, following: Plan) -> BakeOutput {
    BakeBuilder::new(scene.clone())
        .settings(s.clone())
        .following(following)
        .run()
        .expect("bake")
}

fn scene_bench(c: &mut Criterion, name: &str, scene: &Scene, edits: &[EditCase]) {
    let s = BakeSettings::medium();
    let base = bake(scene, &s, Plan::Full("the first bake".into()));
    let cache: BakeCache = base.cache.expect("a cache");
    let mut g = c.benchmark_group(format!("incremental_{name}"));
    g.sample_size(10);
    g.bench_function("full", |b| {
        b.iter(|| black_box(bake(scene, &s, Plan::Full("full".into()))))
    });
    for &case in edits {
        let Some((edited, what)) = case.apply(scene) else {
            continue;
        };
        let followed = bake(
            &edited,
            &s,
            plan(Ok(Some(cache.clone())), &edited, &s, false),
        );
        if let Some(inc) = &followed.report.incremental {
            eprintln!(
                "{name}: {what}: {:.1}% of the split stages' items computed again",
                100.0 * inc.recomputed
            );
        }
        g.bench_function(case.name(), |b| {
            b.iter(|| {
                let following = plan(Ok(Some(cache.clone())), &edited, &s, false);
                black_box(bake(&edited, &s, following))
            })
        });
    }
    g.finish();
}

fn cornell(c: &mut Criterion) {
    let scene = cornell_box(CornellLight::Point);
    scene_bench(c, "cornell_point", &scene, &EditCase::ALL);
}

fn house(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus/house.gltf");
    let scene = lightbake::import_gltf(&path, LightConvention::GltfSpec)
        .expect("the house")
        .scene;
    scene_bench(
        c,
        "house",
        &scene,
        &[
            EditCase::LampColour,
            EditCase::LampMoved,
            EditCase::MeshMoved,
            EditCase::Albedo,
        ],
    );
}

criterion_group!(benches, cornell, house);
criterion_main!(benches);
