//! Ray throughput of the BVH on a 204 800-triangle Cornell box (every quad split 80 × 80):
//! incoherent closest-hit gather rays and any-hit shadow rays towards the ceiling light, on
//! one core and on every core. Results: `docs/benchmarks.md`.
//!
//! `cargo bench -p lightbake --bench trace`

#![allow(missing_docs)] // criterion_group! and criterion_main! generate undocumented items

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lightbake::bvh::RayScene;
use lightbake::bvh::workload::{BenchRay, cornell_workload};
use lightbake::scene::testscenes::{CornellLight, cornell_box_dense};
use rayon::prelude::*;

const RAYS: usize = 100_000;

fn setup() -> (RayScene, Vec<BenchRay>, Vec<BenchRay>) {
    cornell_workload(RAYS)
}

fn closest(rs: &RayScene, r: &BenchRay) -> f32 {
    rs.closest_hit(r.origin, r.direction, 0.0, r.tmax)
        .map_or(-1.0, |h| h.t)
}

fn any(rs: &RayScene, r: &BenchRay) -> bool {
    rs.occluded(r.origin, r.direction, 0.0, r.tmax)
}

fn trace(c: &mut Criterion) {
    let (rs, gather, shadow) = setup();
    eprintln!(
        "scene: {} triangles; BVH build {:.3} s (single thread)",
        rs.bvh_triangle_count(),
        rs.build_time.as_secs_f64()
    );
    let mut g = c.benchmark_group("trace_rays");
    g.sample_size(10);
    g.throughput(Throughput::Elements(RAYS as u64));
    g.bench_function("closest_hit_1_thread", |b| {
        b.iter(|| gather.iter().map(|r| closest(&rs, r)).sum::<f32>())
    });
    g.bench_function("any_hit_1_thread", |b| {
        b.iter(|| shadow.iter().filter(|r| any(&rs, r)).count())
    });
    g.bench_function("closest_hit_all_threads", |b| {
        b.iter(|| gather.par_iter().map(|r| closest(&rs, r)).sum::<f32>())
    });
    g.bench_function("any_hit_all_threads", |b| {
        b.iter(|| shadow.par_iter().filter(|r| any(&rs, r)).count())
    });
    g.finish();
}

fn build(c: &mut Criterion) {
    let scene = cornell_box_dense(CornellLight::Area, 80);
    let mut g = c.benchmark_group("bvh_build");
    g.sample_size(10);
    g.throughput(Throughput::Elements(scene.instanced_triangle_count() as u64));
    g.bench_function("cornell_204800", |b| {
        b.iter(|| black_box(RayScene::build(&scene)))
    });
    g.finish();
}

criterion_group!(benches, trace, build);
criterion_main!(benches);
