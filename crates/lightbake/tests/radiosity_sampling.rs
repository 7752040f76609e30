//! The radiosity pass's sampling against slow, obvious versions of itself: fast support
//! frames against the general sampler, sliver nodes against the hemicube, closed-form node
//! areas against the sampled split, affine footprints against the searched points, the
//! exitance grid against the hit mapper.

mod common;

use common::{radiosity_settings, two_squares};

use glam::{Affine3A, Vec3};
use lightbake::context::Prepared;
use lightbake::progress::Progress;
use lightbake::radiosity::{Nodes, hemicube::build_hemicube, monte_carlo};
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::scene::{Light, LightKind, Material, Mesh, Scene};
use lightbake::settings::Basis;
use lightbake::settings::SolverChoice;
use lightbake::solve::Transport;

/// A curved-normal grid (shading normals vary across every triangle) under a rotated,
/// non-uniformly scaled instance transform, lit by a point light.
fn bent_grid() -> Scene {
    let mut bent = Scene::default();
    let mat = bent.add_material(Material::diffuse("grey", Vec3::splat(0.5)));
    let mut g = lightbake::scene::testscenes::grid("bent", 2.0, 6);
    // Shading normals that vary across every triangle.
    for (n, p) in g.normals.iter_mut().zip(&g.positions) {
        *n = (Vec3::Y + Vec3::new(0.4 * p.x, 0.0, -0.3 * p.z * p.x)).normalize();
    }
    let id = bent.add_mesh(Mesh {
        material: Some(mat),
        ..g
    });
    bent.instances.push(lightbake::scene::Instance::new(
        "bent",
        id,
        Affine3A::from_scale_rotation_translation(
            Vec3::new(1.5, 1.0, 0.7),
            glam::Quat::from_rotation_z(0.6) * glam::Quat::from_rotation_x(0.3),
            Vec3::new(0.2, 0.1, -0.4),
        ),
    ));
    bent.lights.push(Light {
        name: "l".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 1.0,
        range: None,
        position: Vec3::new(0.0, 2.0, 0.0),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    bent
}

/// The fast support sampler of interior nodes ([`SupportFrame`]) against the slow general one
/// ([`support_point`]): the same start points, normals and weights, on the Cornell box and on
/// a curved-normal grid under a rotated, non-uniformly scaled instance transform.
#[test]
fn fast_support_frames_match_the_slow_sampler() {
    use lightbake::radiosity::HitMapper;
    use lightbake::radiosity::support::{SupportFrame, support_point};
    let cornell = cornell_box(CornellLight::Area);
    let bent = bent_grid();
    for (name, scene, density) in [("cornell", cornell, 64.0), ("bent grid", bent, 48.0)] {
        let prep =
            Prepared::new(&scene, &radiosity_settings(density, SolverChoice::Direct)).unwrap();
        let ctx = prep.ctx();
        let nodes = Nodes::new(&ctx, Basis::Linear);
        let mapper = HitMapper::new(ctx, &nodes, Basis::Linear);
        let (mut fast_nodes, mut samples, mut worst) = (0, 0, (0.0f32, 0.0f32, 0.0f32));
        let mut weight_diff_sum = 0.0f64;
        for i in 0..nodes.len() {
            let p = &ctx.patches.patches[nodes.patch[i] as usize];
            let Some(frame) = SupportFrame::new(&ctx, &mapper, i, p) else {
                continue;
            };
            fast_nodes += 1;
            let key = 0x9e37_79b9 ^ i as u32;
            for k in 0..32 {
                let fast = frame.point(lightbake::sampling::sobol_02(k, key));
                let slow = support_point(&ctx, &mapper, i, p, k, key, &mut 0);
                let (Some((f, fw)), Some((s, sw))) = (fast, slow) else {
                    assert_eq!(
                        fast.is_some(),
                        slow.is_some(),
                        "{name}: node {i} sample {k}"
                    );
                    continue;
                };
                samples += 1;
                assert_eq!(f.triangle, s.triangle, "{name}: node {i} sample {k}");
                worst.0 = worst.0.max(f.position.distance(s.position) / p.texel_size);
                worst.1 = worst.1.max(f.normal.distance(s.normal));
                worst.2 = worst.2.max((fw / sw - 1.0).abs());
                weight_diff_sum += (fw / sw - 1.0).abs() as f64;
            }
        }
        println!(
            "{name}: {fast_nodes} of {} nodes fast, {samples} samples; worst position {:.1e} texels, normal {:.1e}, weight {:.1e} (mean {:.1e})",
            nodes.len(),
            worst.0,
            worst.1,
            worst.2,
            weight_diff_sum / samples as f64
        );
        // Most nodes are interior, and not all (chart borders take the slow path).
        assert!(
            fast_nodes * 3 > nodes.len() && fast_nodes < nodes.len(),
            "{name}"
        );
        assert!(samples > 1000, "{name}");
        // The weights differ by the slow path's rounding of its bilinear weights, relative to
        // weights that go to zero at the support's edge: small on average, larger at the edge.
        assert!(
            worst.0 < 1e-3 && worst.1 < 1e-4 && worst.2 < 1e-2,
            "{name}: {worst:?}"
        );
        assert!(weight_diff_sum / (samples as f64) < 1e-5, "{name}");
    }
}

/// Nodes whose texel lies under geometry, with its point moved past it (`Nodes::sliver`),
/// must still gather light: before the fix their Monte Carlo rows found no open start point
/// and came out empty (1 990 of the sunlit room's 32 757 nodes got no reflected light), while
/// the hemicube, which starts at the representative point, saw the light there.
#[test]
fn sliver_nodes_gather_like_the_hemicube() {
    let scene = lightbake::scene::testscenes::sunlit_room();
    let prep = Prepared::new(&scene, &radiosity_settings(8.0, SolverChoice::Direct)).unwrap();
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, Basis::Constant);
    let slivers: Vec<usize> = (0..nodes.len()).filter(|&i| nodes.sliver[i]).collect();
    let mc = monte_carlo::build(&ctx, &nodes, 64, Basis::Constant, &Progress::new());
    let hemicube = build_hemicube(&ctx, &nodes, 8, &Progress::new());
    let seen = |t: &Transport, i: usize| t.row(i).1.iter().sum::<f32>() + t.escaped[i];
    let empty = slivers.iter().filter(|&&i| seen(&mc, i) <= 0.0).count();
    let diff = slivers
        .iter()
        .map(|&i| (seen(&mc, i) - seen(&hemicube, i)).abs() as f64)
        .sum::<f64>()
        / slivers.len().max(1) as f64;
    println!(
        "{} of {} nodes are slivers; {empty} empty Monte Carlo rows; mean |row sum + escaped| difference to the hemicube {diff:.4}",
        slivers.len(),
        nodes.len()
    );
    assert!(
        slivers.len() > 100,
        "the sunlit room has texels under its walls"
    );
    assert_eq!(empty, 0);
    assert!(diff < 0.05, "{diff}");
}

/// ∫φᵢ dA: the node areas add up to the surface, and inside a flat square (texels whose
/// 3 × 3 block lies in one triangle) the linear basis' tent gives each node exactly one texel
/// of area; the 16-point sampled split is off by about a percent there.
#[test]
fn node_areas_add_up_and_are_exact_inside_a_square() {
    let scene = two_squares(false);
    let settings = radiosity_settings(24.0, SolverChoice::Auto);
    let prep = Prepared::new(&scene, &settings).unwrap();
    let ctx = prep.ctx();
    for basis in [Basis::Linear, Basis::Constant] {
        let nodes = Nodes::new(&ctx, basis);
        let patches = &prep.patches.patches;
        let surface: f64 = patches.iter().map(|p| p.area as f64).sum();
        let total: f64 = nodes.area.iter().map(|&a| a as f64).sum();
        assert!(
            (total - surface).abs() < 1e-4 * surface,
            "{basis:?}: node areas {total} vs texel areas {surface}"
        );
        let mut inside: Vec<f64> = (0..nodes.len())
            .filter_map(|i| {
                let p = &patches[nodes.patch[i] as usize];
                let margin = 2.5 * p.texel_size;
                let c = p.position;
                let away = |v: f32| v > margin && v < 1.0 - margin;
                (away(c.x) && away(c.z))
                    .then(|| ((nodes.area[i] / (p.texel_size * p.texel_size)) as f64 - 1.0).abs())
            })
            .collect();
        assert!(
            inside.len() > 300,
            "{basis:?}: {} inner nodes",
            inside.len()
        );
        inside.sort_by(f64::total_cmp);
        let median = inside[inside.len() / 2];
        assert!(
            median < 1e-5,
            "{basis:?}: median relative area error {median}"
        );
    }
}

/// Footprint points of texels inside one triangle come from an affine map of the texel square
/// instead of a search of the footprint triangles: the same points (Cornell box, and the
/// curved-normal grid under a rotated, non-uniformly scaled instance).
#[test]
fn affine_footprints_match_the_searched_points() {
    use lightbake::raster::Footprint;
    use lightbake::raster::Surface;
    for (name, scene, density) in [
        ("cornell", cornell_box(CornellLight::Area), 64.0),
        ("bent grid", bent_grid(), 48.0),
    ] {
        let prep =
            Prepared::new(&scene, &radiosity_settings(density, SolverChoice::Direct)).unwrap();
        let ctx = prep.ctx();
        let surface = Surface::new(ctx.scene, ctx.layout, ctx.rays);
        let (mut affine, mut valid, mut worst) = (0, 0, (0.0f32, 0.0f32, 0.0f32));
        for p in ctx.patches.patches.iter().filter(|p| p.is_valid()) {
            valid += 1;
            let footprint = Footprint::new(ctx.layout, ctx.patches, &surface, ctx.rays, p, 7);
            if !footprint.is_affine() {
                continue;
            }
            affine += 1;
            for s in 0..16 {
                let mut rays = 0;
                let (f, g) = (
                    footprint.point(s, &mut rays),
                    footprint.searched_point(s, &mut rays),
                );
                assert_eq!(rays, 0, "{name}: texels of affine footprints trace no rays");
                assert_eq!(f.triangle, g.triangle, "{name}");
                worst.0 = worst.0.max(f.position.distance(g.position) / p.texel_size);
                worst.1 = worst.1.max(f.normal.distance(g.normal));
                worst.2 = worst.2.max((f.bary - g.bary).abs().max_element());
            }
        }
        println!("{name}: {affine} of {valid} texels affine; worst {worst:?}");
        assert!(affine * 2 > valid && affine < valid, "{name}");
        assert!(
            worst.0 < 1e-3 && worst.1 < 1e-4 && worst.2 < 1e-4,
            "{name}: {worst:?}"
        );
    }
}

#[test]
fn the_exitance_grid_reads_what_the_hit_mapper_weights_give() {
    use lightbake::bvh::workload::gather_rays;
    use lightbake::radiosity::HitMapper;
    use lightbake::radiosity::exitance_grid::ExitanceGrid;
    // The Cornell box (blocks standing on the floor split nodes along their bases), the
    // hard furnace (slivers, a wedge, coincident and double-sided faces) and the sunlit room
    // (thin walls, a window).
    let scenes = [
        (cornell_box(CornellLight::Area), 48.0),
        (
            common::hard_furnace(0.9, 10.0, &["tiny_cube", "wedge", "slivers", "coincident"]),
            24.0,
        ),
        (lightbake::scene::testscenes::sunlit_room(), 16.0),
    ];
    for (scene, density) in scenes {
        for basis in [Basis::Linear, Basis::Constant] {
            let prep =
                Prepared::new(&scene, &radiosity_settings(density, SolverChoice::Auto)).unwrap();
            let ctx = prep.ctx();
            let nodes = Nodes::new(&ctx, basis);
            let mapper = HitMapper::new(ctx, &nodes, basis);
            // A field that differs from node to node in every channel.
            let b: Vec<Vec3> = (0..nodes.len())
                .map(|i| Vec3::new((i % 7) as f32, (i % 11) as f32 + 0.5, (i % 13) as f32))
                .collect();
            let grid = ExitanceGrid::new(&mapper, &b);
            let (mut hits, mut split_hits) = (0, 0);
            for ray in gather_rays(&prep.rays, 20_000, 3) {
                let Some(hit) = prep
                    .rays
                    .closest_hit(ray.origin, ray.direction, 0.0, ray.tmax)
                else {
                    continue;
                };
                let mut w = [(0u32, 0f32); 4];
                let n = mapper.weights(&hit, &mut w);
                let slow = w[..n]
                    .iter()
                    .fold(Vec3::ZERO, |s, &(j, wj)| s + b[j as usize] * wj);
                let fast = grid.at(&hit);
                assert!(
                    fast.to_array().map(f32::to_bits) == slow.to_array().map(f32::to_bits),
                    "{} {basis:?}: triangle {} at ({}, {}): grid {fast} against the mapper's {slow}",
                    scene.name,
                    hit.triangle,
                    hit.u,
                    hit.v
                );
                hits += 1;
                split_hits += usize::from(w[..n].iter().any(|&(j, _)| nodes.split[j as usize]));
            }
            println!(
                "{} {basis:?}: {hits} hits, {split_hits} next to split nodes",
                scene.name
            );
            assert!(hits > 4_000, "{} {basis:?}: {hits} hits", scene.name);
        }
    }
}
