//! The hierarchical solve (a coarse solve over texel clusters, then a per-texel final gather)
//! against the full transport matrix on the shipped scenes; its error estimate sees a coarse
//! level that is too coarse; its refinement reaches the tolerance, also with several fields
//! (light groups) on one cut; `auto` takes it beyond the
//! full matrix's node limit and says why; the final gather's rays shared out by noise give
//! less noise than the same rays spread evenly. (The furnace at ρ = 0.3 … 0.999, the hard furnace
//! and the thread-count determinism cover it with the other solvers.)

mod common;

use glam::Vec3;
use lightbake::BakeOutput;
use lightbake::Stage;
use lightbake::analysis::study::relative_rms_error;
use lightbake::context::Prepared;
use lightbake::progress::Progress;
use lightbake::radiosity::coarse;
use lightbake::radiosity::coarse_kept::{self, KeptCoarse};
use lightbake::radiosity::hierarchical::{Coarse, HierarchyOptions, coarse_solve_fields};
use lightbake::radiosity::{HitMapper, Nodes, hierarchy_options};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, SolverChoice};

/// The medium preset at `density` texels/m with `solver`.
fn settings(density: f32, solver: SolverChoice) -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    s.radiosity.solver = solver;
    // The solves compared as they are: the denoiser would filter the hierarchical solve's
    // noise (it has a per-texel estimate) and not the full matrix's.
    s.finish.denoise = false;
    // The final gather with the rays of the full matrix's rows at every node
    // (`adaptive_gather_has_less_noise_than_even_rays` checks the adaptive one).
    s.radiosity.adaptive_gather = false;
    s
}

/// The radiosity stage's own error estimate (relative RMS), and the hierarchical solve's
/// bias part of it.
fn radiosity_estimate(out: &BakeOutput) -> (f64, Option<f64>) {
    let stage = out
        .report
        .stages
        .iter()
        .find(|s| s.run.stage == Stage::ErrorEstimate)
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
        s.radiosity.cluster_texels = 256;
        s.radiosity.cluster_tolerance = 0.99;
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
    s.radiosity.cluster_texels = 16;
    s.radiosity.cluster_tolerance = 0.004;
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

/// A direct field per patch: `inside` on the patches within `share` of the scene's extent
/// along x from its low end, `outside` on the rest (lux).
fn one_end(
    patches: &[lightbake::raster::Patch],
    share: f32,
    inside: Vec3,
    outside: Vec3,
) -> Vec<Vec3> {
    let (lo, hi) = (patches.iter()).fold((f32::MAX, f32::MIN), |(lo, hi), p| {
        (lo.min(p.position.x), hi.max(p.position.x))
    });
    (patches.iter())
        .map(|p| {
            if p.position.x < lo + share * (hi - lo) {
                inside
            } else {
                outside
            }
        })
        .collect()
}

#[test]
fn fields_share_one_cut_refined_until_each_ones_detail_is_within_the_tolerance() {
    // Light groups' coarse level: one cut for every group's field, its rows and oracle traced
    // once. Two direct fields over the sunlit room's texels: light on one end of the room only
    // (a sharp edge across the floor and walls), an even light, and their sum. The first
    // needs no refinement on its own, the second does: the shared cut follows the second.
    let scene = sunlit_room();
    let mut s = settings(24.0, SolverChoice::Hierarchical);
    s.radiosity.cluster_texels = 16;
    s.radiosity.cluster_tolerance = 0.004;
    let prep = Prepared::new(&scene, &s).unwrap_or_else(|e| panic!("{e}"));
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, s.radiosity.basis);
    let mapper = HitMapper::new(ctx, &nodes, s.radiosity.basis);
    let options = hierarchy_options(&ctx, &nodes, u64::MAX);
    let patches = &prep.patches.patches;
    let even = vec![Vec3::splat(100.0); patches.len()];
    let end = one_end(patches, 0.3, Vec3::splat(2000.0), Vec3::ZERO);
    let sum: Vec<Vec3> = even.iter().zip(&end).map(|(a, b)| *a + *b).collect();
    let solve = |fields: &[&[Vec3]]| {
        coarse_solve_fields(&ctx, &mapper, &nodes, fields, &options, &Progress::new()).0
    };
    let shared = solve(&[&end, &even, &sum]);
    let alone: Vec<Coarse> = [&end, &even]
        .map(|f| solve(&[f.as_slice()]).remove(0))
        .into();
    for (name, c) in ["one end", "even", "sum"].iter().zip(&shared) {
        println!("shared cut, {name}: {:?}", c.report);
    }
    for (name, c) in ["one end", "even"].iter().zip(&alone) {
        println!("alone, {name}: {:?}", c.report);
    }
    // One cut for every field.
    for c in &shared[1..] {
        assert!(c.clusters.of_node == shared[0].clusters.of_node);
    }
    // Refined until every field's detail is within the tolerance (or the report says what
    // stopped it), so at least as fine as the field that needs the most cells on its own.
    let r = &shared[0].report;
    assert_eq!(alone[0].report.rounds, 1, "{:?}", alone[0].report);
    assert!(r.rounds > 1, "{r:?}");
    for c in &shared {
        assert!(
            c.report.missed_detail <= 0.004 || !c.report.stop_reason.contains("within"),
            "{:?}",
            c.report
        );
    }
    let most = alone.iter().map(|c| c.report.cells).max().unwrap();
    assert!(r.cells >= most, "{} cells shared, {most} alone", r.cells);
    // Light adds up: over the shared matrix, the sum's coarse light is the fields' sum
    // (within the coarse solves' tolerance).
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for ((a, b), c) in (shared[0].solution.indirect.iter())
        .zip(&shared[1].solution.indirect)
        .zip(&shared[2].solution.indirect)
    {
        diff += f64::from((*a + *b - *c).length_squared());
        norm += f64::from(c.length_squared());
    }
    let relative = (diff / norm).sqrt();
    println!("the sum's coarse light against the fields' sum: {relative:.2e}");
    assert!(relative < 1e-3, "{relative}");
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

/// Two closed rooms on one floor slab, split by a 20 cm wall standing on it, a lamp in one:
/// the other room gets no light at all. The floor is one chart that runs under the wall, so
/// a coarse cell of 64 × 64 texels spans both rooms; its nodes fall into the two pieces the
/// wall leaves connected (`radiosity::clusters::Links`), each with a value of its own, and
/// the lamp's light does not reach the dark room through a shared coarse value.
#[test]
fn coarse_cells_do_not_carry_light_under_a_wall() {
    use glam::{Affine3A, Vec3};
    use lightbake::scene::testscenes::cuboid;
    use lightbake::scene::{Instance, Light, LightKind, Material, Mesh};
    let mut scene = Scene {
        name: "two_rooms".into(),
        ..Scene::default()
    };
    let white = scene.add_material(Material::diffuse("white", Vec3::splat(0.8)));
    let (t, h) = (0.2, 2.5);
    let boxes = [
        ("floor", Vec3::new(-3.2, -t, -1.7), Vec3::new(3.2, 0.0, 1.7)),
        (
            "ceiling",
            Vec3::new(-3.2, h, -1.7),
            Vec3::new(3.2, h + t, 1.7),
        ),
        ("west", Vec3::new(-3.2, 0.0, -1.7), Vec3::new(-3.0, h, 1.7)),
        ("east", Vec3::new(3.0, 0.0, -1.7), Vec3::new(3.2, h, 1.7)),
        ("north", Vec3::new(-3.0, 0.0, -1.7), Vec3::new(3.0, h, -1.5)),
        ("south", Vec3::new(-3.0, 0.0, 1.5), Vec3::new(3.0, h, 1.7)),
        ("wall", Vec3::new(-0.1, 0.0, -1.5), Vec3::new(0.1, h, 1.5)),
    ];
    for (name, lo, hi) in boxes {
        let m = scene.add_mesh(Mesh {
            material: Some(white),
            ..cuboid(name, lo, hi, lo.y == 0.0)
        });
        scene
            .instances
            .push(Instance::new(name, m, Affine3A::IDENTITY));
    }
    scene.lights.push(Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 100.0,
        range: None,
        position: Vec3::new(-1.5, 2.0, 0.0),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    let mut s = settings(16.0, SolverChoice::Hierarchical);
    s.radiosity.cluster_texels = 64;
    let out = common::bake(&scene, &s);
    let coarse = out
        .report
        .radiosity
        .as_ref()
        .unwrap()
        .coarse
        .as_ref()
        .unwrap();
    println!("{} cells", coarse.cells);
    let texel = 1.0 / 16.0;
    let floor = common::texels(&out, 0);
    let (mut dark, mut lit) = (0, 0);
    for t in &floor {
        if t.position.y < -0.01 || t.position.x.abs() > 3.0 || t.position.z.abs() > 1.5 {
            continue; // the slab's other faces
        }
        if t.position.x > 0.1 + 1.5 * texel {
            assert_eq!(
                t.value,
                Vec3::ZERO,
                "floor texel at {:?} of the dark room is lit",
                t.position
            );
            dark += 1;
        } else if t.position.x < -0.1 - 1.5 * texel {
            lit += usize::from(t.value.x > 0.0);
        }
    }
    assert!(dark > 1000 && lit > 1000, "{dark} {lit}");
}

/// The gather stages' rays of a bake (closest and visibility).
fn gather_rays(out: &BakeOutput) -> u64 {
    out.report
        .stages
        .iter()
        .filter(|s| s.run.stage == Stage::GatherPilot || s.run.stage == Stage::FinalGather)
        .map(|s| s.rays)
        .sum()
}

#[test]
fn adaptive_gather_has_less_noise_than_even_rays() {
    // The noise of a bake is half the RMS difference of two bakes under two seeds, √2 × the
    // noise of each; the direct light's share is made small with many samples.
    let scene = cornell_box(CornellLight::Area);
    let bake = |adaptive: bool, seed: u32| {
        let mut s = settings(64.0, SolverChoice::Hierarchical);
        s.radiosity.adaptive_gather = adaptive;
        s.direct.samples_per_texel = 256;
        s.seed = seed;
        common::bake(&scene, &s)
    };
    let noise = |adaptive: bool| {
        let (a, b) = (bake(adaptive, 1), bake(adaptive, 2));
        let rays = gather_rays(&a);
        (relative_rms_error(&a.pages, &b.pages), rays)
    };
    let ((even, even_rays), (adaptive, adaptive_rays)) = (noise(false), noise(true));
    println!(
        "seed difference: even rays {even:.4} ({even_rays} rays), adaptive {adaptive:.4} ({adaptive_rays} rays)"
    );
    assert!(
        adaptive_rays as f64 <= 1.02 * even_rays as f64,
        "{adaptive_rays} rays against {even_rays}"
    );
    assert!(
        adaptive < 0.95 * even,
        "shared out by noise {adaptive:.4}, even {even:.4}"
    );
}

/// The coarse level a bake keeps for a later one (`lightbake::radiosity::coarse_kept`),
/// updated by shooting the change of the reflected direct light from the nodes where it
/// changed: with nothing changed it gives the kept level's bits; with one end of the room
/// brighter, the change of its first bounce is the change that gathering again over the same
/// cut (with the kept build's rays) gives, within the shot rays' noise, and carries the
/// same power.
#[test]
fn a_kept_coarse_level_updated_by_shooting_agrees_with_gathering_again() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings(24.0, SolverChoice::Hierarchical);
    let prep = Prepared::new(&scene, &s).unwrap_or_else(|e| panic!("{e}"));
    let ctx = prep.ctx();
    let nodes = Nodes::new(&ctx, s.radiosity.basis);
    let mapper = HitMapper::new(ctx, &nodes, s.radiosity.basis);
    let options = hierarchy_options(&ctx, &nodes, u64::MAX);
    let patches = &prep.patches.patches;
    let before = vec![Vec3::splat(100.0); patches.len()];
    let after = one_end(
        patches,
        0.2,
        Vec3::new(160.0, 140.0, 120.0),
        Vec3::splat(100.0),
    );
    let progress = Progress::new();
    let (levels, rows) =
        coarse_solve_fields(&ctx, &mapper, &nodes, &[&before], &options, &progress);
    let source = coarse_kept::source(&nodes, &before);
    let kept = KeptCoarse::new(&levels[0], rows, source).expect("one field");
    // The kept level read back from its bytes is the same.
    let read = KeptCoarse::read(&kept.to_bytes(), &nodes).expect("its own bytes");
    assert!(
        read == kept,
        "the kept coarse level changed through its bytes"
    );
    let mut damaged = kept.to_bytes();
    damaged.truncate(damaged.len() - 3);
    assert!(KeptCoarse::read(&damaged, &nodes).is_err());
    // Nothing changed: the kept level's bits.
    let bits = |v: &[Vec3]| -> Vec<u32> {
        (v.iter())
            .flat_map(|x| x.to_array())
            .map(f32::to_bits)
            .collect()
    };
    let (same, _) = coarse_kept::update(
        &ctx,
        &mapper,
        &nodes,
        &before,
        kept.clone(),
        &options,
        &progress,
    )
    .expect("nothing to shoot");
    assert_eq!(same.report.rays, 0);
    assert_eq!(
        bits(&same.solution.indirect),
        bits(&levels[0].solution.indirect)
    );
    // Where most of the light went, the level is built again, with the reason.
    let dark = vec![Vec3::ZERO; patches.len()];
    let why = coarse_kept::update(
        &ctx,
        &mapper,
        &nodes,
        &dark,
        kept.clone(),
        &options,
        &progress,
    )
    .err()
    .expect("no shot change for a room gone dark");
    assert!(why.contains("power"), "{why}");
    // Shots add up (each adds its own noise): changed back and forth, the level is built
    // again once the changes shot since it was built carry a quarter of the light's power.
    let mut chained = kept.clone();
    let mut shots = 0;
    let why = loop {
        let target = if shots % 2 == 0 { &after } else { &before };
        match coarse_kept::update(
            &ctx,
            &mapper,
            &nodes,
            target,
            chained.clone(),
            &options,
            &progress,
        ) {
            Ok((_, next)) => {
                chained = next;
                shots += 1;
            }
            Err(why) => break why,
        }
        assert!(shots < 20, "{shots} shots and never built again");
    };
    println!("built again after {shots} shots: {why}");
    assert!(shots >= 2 && why.contains("shot since"), "{shots}: {why}");
    // One end brighter: the change shot, against the change gathered with the same rays
    // before and after, at the build's rays per cell and at four times as many.
    let change = |cell_rays: u32| {
        let options = HierarchyOptions {
            cell_rays,
            ..options
        };
        // (As many rays as it takes: the share of the kept level's rays is not tested here.)
        let kept = KeptCoarse {
            rays: u64::MAX / 4,
            ..kept.clone()
        };
        let (_, updated) = coarse_kept::update(
            &ctx,
            &mapper,
            &nodes,
            &after,
            kept.clone(),
            &options,
            &progress,
        )
        .expect("a small change to shoot");
        let build = |direct: &[Vec3]| {
            let rows = coarse::build(
                &ctx,
                &mapper,
                &nodes,
                &kept.clusters,
                cell_rays,
                &[direct],
                &progress,
            );
            rows.first_bounce.into_iter().next().expect("one field")
        };
        let (b0, b1) = (build(&before), build(&after));
        let area = &kept.clusters.area;
        let (mut diff, mut norm, mut shot_power, mut gathered_power) = (0.0f64, 0.0, 0.0, 0.0);
        for c in 0..area.len() {
            let a = f64::from(area[c]);
            let shot = updated.first_bounce[c] - kept.first_bounce[c];
            let again = b1[c] - b0[c];
            diff += a * f64::from((shot - again).length_squared());
            norm += a * f64::from(again.length_squared());
            shot_power += a * f64::from(shot.element_sum());
            gathered_power += a * f64::from(again.element_sum());
        }
        let (relative, power) = ((diff / norm).sqrt(), shot_power / gathered_power);
        println!(
            "{} cells, {cell_rays} rays per cell: the change shot against gathered {:.2}% RMS, power {power:.4}",
            area.len(),
            100.0 * relative
        );
        (relative, power)
    };
    let (coarse_rays, power) = change(options.cell_rays);
    assert!(coarse_rays < 0.3, "{coarse_rays}");
    assert!((power - 1.0).abs() < 0.03, "{power}");
    let (fine_rays, power) = change(4 * options.cell_rays);
    assert!(
        fine_rays < 0.7 * coarse_rays,
        "{fine_rays} against {coarse_rays}"
    );
    assert!((power - 1.0).abs() < 0.03, "{power}");
}
