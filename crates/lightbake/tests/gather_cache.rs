//! The irradiance cache of the final gather (`radiosity::gather_cache`) against the dense
//! gather it replaces: records at every node give the dense gather's bits; any subset of the
//! nodes gets the whole cache's bits (what a split bake and a subset run rely on); on the
//! Cornell box and the sunlit room it gathers at a fraction of the nodes and lands within
//! the dense gather's own noise of a reference gather with 16× the rays.

mod common;

use common::radiosity_settings;

use glam::Vec3;
use lightbake::context::BakeContext;
use lightbake::context::Prepared;
use lightbake::progress::Progress;
use lightbake::radiosity::gather_cache::{CacheOptions, SPREAD, cached_gather};
use lightbake::radiosity::hierarchical::{Gather, GatherRays, final_gather};
use lightbake::radiosity::{HitMapper, Nodes};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{Basis, SolverChoice};

/// An exitance field to gather (lux): each node's albedo times a light that falls across
/// the scene, bright on one side, so the gathered light varies over every surface.
fn field(prep: &Prepared, nodes: &Nodes) -> Vec<Vec3> {
    (0..nodes.len())
        .map(|i| {
            let p = &prep.patches.patches[nodes.patch[i] as usize];
            nodes.albedo[i] * (100.0 + 400.0 * (p.position.x - p.position.z).abs())
        })
        .collect()
}

fn options(accuracy: f32) -> CacheOptions {
    CacheOptions {
        spacing: 8,
        accuracy,
        spread: SPREAD,
    }
}

/// Calls `f(name, ctx, mapper, nodes, field)` for each scene at its density.
fn for_each_scene<const N: usize>(
    scenes: [(&str, Scene, f32); N],
    f: impl Fn(&str, BakeContext<'_>, &HitMapper<'_>, &Nodes, &[Vec3]),
) {
    for (name, scene, density) in scenes {
        let prep = prepared(&scene, density);
        let ctx = prep.ctx();
        let nodes = Nodes::new(&ctx, Basis::Linear);
        let mapper = HitMapper::new(ctx, &nodes, Basis::Linear);
        f(name, ctx, &mapper, &nodes, &field(&prep, &nodes));
    }
}

fn prepared(scene: &Scene, density: f32) -> Prepared {
    Prepared::new(
        scene,
        &radiosity_settings(density, SolverChoice::Hierarchical),
    )
    .unwrap()
}

/// The dense final gather of `b`: rays `0..rays` at every node.
fn dense(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    b: &[Vec3],
    rays: u32,
) -> (Vec<Vec3>, Vec<f32>, GatherRays) {
    let rays = move |_: usize| 0..rays;
    final_gather(
        ctx,
        mapper,
        nodes,
        b,
        &rays,
        Gather::Final,
        None,
        &Progress::new(),
    )
}

#[test]
fn records_at_every_node_give_the_dense_gathers_bits() {
    let prep = prepared(&cornell_box(CornellLight::Area), 48.0);
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Linear);
    let mapper = HitMapper::new(ctx, &nodes, Basis::Linear);
    let b = field(&prep, &nodes);
    let progress = Progress::new();
    let rays = 32;
    // An accuracy no cell meets: every node is a record.
    let cached = cached_gather(
        &ctx,
        &mapper,
        &nodes,
        &b,
        rays,
        options(1e-9),
        None,
        &progress,
    );
    let (dense, dense_se, traced) = dense(&ctx, &mapper, &nodes, &b, rays);
    assert_eq!(cached.interpolated, 0);
    assert_eq!(cached.record_count(), nodes.len() as u64);
    assert_eq!(cached.light, dense);
    assert_eq!(cached.error, dense_se);
    assert_eq!(cached.closest, traced.closest);
}

#[test]
fn a_subset_of_the_nodes_gets_the_whole_caches_bits() {
    let scenes = [
        ("cornell box", cornell_box(CornellLight::Area), 48.0),
        ("sunlit room", sunlit_room(), 12.0),
    ];
    for_each_scene(scenes, |_, ctx, mapper, nodes, b| {
        let ctx = &ctx;
        let progress = Progress::new();
        let whole = cached_gather(ctx, mapper, nodes, b, 32, options(0.5), None, &progress);
        assert!(whole.interpolated > 0, "the cache interpolated nothing");
        for stride in [2usize, 3, 7] {
            let only: Vec<bool> = (0..nodes.len()).map(|i| (i / 5) % stride == 0).collect();
            let part = cached_gather(
                ctx,
                mapper,
                nodes,
                b,
                32,
                options(0.5),
                Some(&only),
                &progress,
            );
            for i in (0..nodes.len()).filter(|&i| only[i]) {
                assert_eq!(part.light[i], whole.light[i], "node {i}, stride {stride}");
                assert_eq!(part.error[i], whole.error[i], "node {i}, stride {stride}");
            }
        }
    });
}

/// Relative RMS difference of `a` from `reference`, by node area.
fn relative_rms(nodes: &Nodes, a: &[Vec3], reference: &[Vec3]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for i in 0..nodes.len() {
        let w = nodes.area[i] as f64;
        num += w * (a[i] - reference[i]).length_squared() as f64;
        den += w * reference[i].length_squared() as f64;
    }
    (num / den).sqrt()
}

#[test]
fn the_cache_gathers_at_a_fraction_of_the_nodes_within_the_dense_gathers_noise() {
    let scenes = [
        ("cornell box", cornell_box(CornellLight::Area), 64.0),
        ("sunlit room", sunlit_room(), 12.0),
    ];
    for_each_scene(scenes, |name, ctx, mapper, nodes, b| {
        let ctx = &ctx;
        let progress = Progress::new();
        let (reference, _, _) = dense(ctx, mapper, nodes, b, 1024);
        let (even, _, even_rays) = dense(ctx, mapper, nodes, b, 64);
        let cached = cached_gather(ctx, mapper, nodes, b, 64, options(0.5), None, &progress);
        let (e_dense, e_cached) = (
            relative_rms(nodes, &even, &reference),
            relative_rms(nodes, &cached.light, &reference),
        );
        let share = cached.record_count() as f64 / nodes.len() as f64;
        println!(
            "{name}: {} nodes, records {:.1}% ({:?}), rays {} vs {}, error {:.3}% vs dense {:.3}%",
            nodes.len(),
            100.0 * share,
            cached.records,
            cached.closest,
            even_rays.closest,
            100.0 * e_cached,
            100.0 * e_dense
        );
        assert!(
            share < 0.5,
            "{name}: records at {:.1}% of the nodes",
            100.0 * share
        );
        assert!(cached.closest < even_rays.closest / 2);
        assert!(
            e_cached < 1.5 * e_dense,
            "{name}: {e_cached} against {e_dense}"
        );
        assert!(cached.light.iter().all(|v| v.is_finite()));
    });
}
