//! Stability on extreme inputs: the same scene at 1 mm, 1 m and 10 km; light intensities from
//! 10⁻⁶ to 10⁹ (and what happens beyond half-float range); a closed furnace filled with tiny,
//! sliver, zero-area, coincident and sharply meeting faces. Each case checks finite output and
//! agreement with a known answer. The table of cases and results is in `docs/stability.md`.

mod common;

use common::{all_finite, bake, hard_furnace, method_settings as settings, triangles};
use glam::{Affine3A, Vec3};
use lightbake::analysis::study::relative_rms_error;
use lightbake::scene::testscenes::{CornellLight, cornell_box, cuboid, furnace_box};
use lightbake::scene::{Instance, Material, Mesh, Scene};
use lightbake::settings::SolverChoice;
use lightbake::settings::{BakeSettings, Method};

/// `scene` with every length multiplied by `s` (instances, lights, ranges).
fn scaled(scene: &Scene, s: f32) -> Scene {
    let mut out = scene.clone();
    for inst in &mut out.instances {
        inst.transform = Affine3A::from_scale(Vec3::splat(s)) * inst.transform;
    }
    for l in &mut out.lights {
        l.position *= s;
        l.range = l.range.map(|r| r * s);
    }
    out
}

#[test]
fn the_same_scene_at_1_mm_1_m_and_10_km_gives_the_same_lightmap() {
    // The area-lit Cornell box: emitted luminance does not depend on scale, so neither does
    // the irradiance anywhere. No density is given: the texel budget chooses one from the
    // scene's area, so the layout is the same at every scale.
    let auto = {
        let mut s = BakeSettings::medium();
        s.method = Method::Radiosity;
        s.layout.texel_density = None;
        s.layout.texel_density_from_scene = false;
        s.layout.texel_budget = 2_500;
        s
    };
    let base = cornell_box(CornellLight::Area);
    let reference = bake(&base, &auto);
    let reference_density = reference.report.plan.texel_density;
    assert!(
        reference
            .report
            .plan
            .texel_density_source
            .contains("budget"),
        "{}",
        reference.report.plan.texel_density_source
    );
    for s in [1e-3f32, 1e4] {
        let out = bake(&scaled(&base, s), &auto);
        assert!(all_finite(&out), "scale {s}: non-finite texels");
        let density = out.report.plan.texel_density;
        assert!(
            (density * s / reference_density - 1.0).abs() < 1e-4,
            "scale {s}: density {density} against {reference_density} at 1 m"
        );
        assert_eq!(
            out.report.texels.patches, reference.report.texels.patches,
            "scale {s}: the layout changed"
        );
        let diff = relative_rms_error(&out.pages, &reference.pages);
        println!(
            "scale {s}: {density} texels per unit, {} patches, {} moved, {} invalid; relative RMS difference {diff:.5}",
            out.report.texels.patches, out.report.texels.moved, out.report.texels.invalid
        );
        assert!(
            diff < 0.01,
            "scale {s}: lightmap differs from the 1 m bake by {:.2}%",
            100.0 * diff
        );
    }
}

/// A whole scene 0.5 mm wide at an absolute 32 texels per metre, and a 0.1 mm cube in a 1 m
/// room: every mesh gets a chart (the smallest, with a warning), none an unwrap error.
#[test]
fn meshes_smaller_than_a_texel_get_the_smallest_chart() {
    let mut tiny = scaled(&cornell_box(CornellLight::Area), 0.5e-3 / 0.555);
    tiny.texel_density_hint = None;
    let out = bake(&tiny, &settings(Method::Direct, 32.0));
    assert!(all_finite(&out));
    assert!(
        out.layout.instances.iter().all(Option::is_some),
        "every instance has a rectangle"
    );
    assert!(
        out.report
            .warnings
            .iter()
            .any(|w| w.contains("smallest chart")),
        "{:?}",
        out.report.warnings
    );

    let mut room = cornell_box(CornellLight::Area);
    let m = room.add_mesh(cuboid(
        "crumb",
        Vec3::splat(0.2),
        Vec3::splat(0.2001),
        false,
    ));
    room.instances
        .push(Instance::new("crumb", m, Affine3A::IDENTITY));
    let out = bake(&room, &settings(Method::Direct, 32.0));
    let crumb = out
        .layout
        .instances
        .last()
        .unwrap()
        .expect("the crumb is baked");
    assert!(crumb.width >= 2 && crumb.height >= 2, "{crumb:?}");
    assert!(
        out.report
            .warnings
            .iter()
            .any(|w| w.contains("smallest chart") && w.contains("crumb")),
        "{:?}",
        out.report.warnings
    );
}

#[test]
fn light_intensities_from_1e_minus_6_to_1e9_scale_the_lightmap_linearly() {
    // The point-lit Cornell box, direct light and radiosity: the equations are linear in the
    // light, so the lightmap must scale with it exactly up to float rounding.
    let base = cornell_box(CornellLight::Point);
    let s = settings(Method::Radiosity, 24.0);
    let reference = bake(&base, &s);
    for k in [1e-6f32, 1e3, 1e9] {
        let mut scene = base.clone();
        for l in &mut scene.lights {
            l.intensity *= k;
        }
        let out = bake(&scene, &s);
        assert!(all_finite(&out), "intensity × {k}: non-finite texels");
        let unscaled: Vec<_> = out
            .pages
            .iter()
            .map(|p| lightbake::lightmap::LightmapPage {
                texels: p.texels.iter().map(|t| *t / k).collect(),
                ..p.clone()
            })
            .collect();
        let diff = relative_rms_error(&unscaled, &reference.pages);
        println!("intensity × {k:e}: relative RMS difference after ÷{k:e}: {diff:.2e}");
        assert!(diff < 1e-4, "intensity × {k}: not linear ({diff:e})");
        let warned = out
            .report
            .warnings
            .iter()
            .any(|w| w.contains("exceeds the half-float range"));
        let max = out
            .pages
            .iter()
            .flat_map(|p| p.texels.iter())
            .fold(0.0f32, |m, t| m.max(t.max_element()));
        assert_eq!(
            warned,
            max > 65504.0,
            "intensity × {k}: brightest texel {max}, warning {warned}"
        );
    }
}

#[test]
fn texels_beyond_half_float_range_are_written_clamped_never_infinite() {
    let mut scene = cornell_box(CornellLight::Point);
    for l in &mut scene.lights {
        l.intensity *= 1e9;
    }
    let mut s = settings(Method::Direct, 16.0);
    s.formats.exr = true;
    s.formats.ktx2 = true;
    let out = bake(&scene, &s);
    assert!(
        out.report
            .warnings
            .iter()
            .any(|w| w.contains("exceeds the half-float range")),
        "{:?}",
        out.report.warnings
    );
    let dir = tempfile::tempdir().unwrap();
    lightbake::output::write_outputs(dir.path(), &out, &scene, None, &s).unwrap();
    let values = exr::prelude::read_first_rgba_layer_from_file(
        dir.path().join("lightmaps/lightmap_0.exr"),
        |_, _| Vec::<f32>::new(),
        |v, _, (r, g, b, _a): (f32, f32, f32, f32)| v.extend([r, g, b]),
    )
    .unwrap()
    .layer_data
    .channel_data
    .pixels;
    assert!(
        values.iter().all(|v| v.is_finite()),
        "the EXR holds a non-finite value"
    );
    let max = values.iter().copied().fold(0.0f32, f32::max);
    assert!(
        (max - 65504.0).abs() < 1.0,
        "the brightest EXR value is {max}, not the half-float maximum"
    );
}

#[test]
fn ten_million_vpls_sum_exactly_into_each_texel() {
    // A 0.5 m plane under 10⁷ identical VPLs 1 m above it: each texel's irradiance is a sum
    // of 10⁷ equal f32 terms, so its exact value is 10⁷ × one term. An f32 running sum
    // drifts (shown below); the gather's f64 sums must not.
    use lightbake::context::Prepared;
    use lightbake::vpl::gather::gather;
    use lightbake::vpl::walk::{Vpl, VplKind};
    let mut scene = Scene::default();
    // Lightmaps are at least 8² texels: map the plane onto a 2² corner of its rectangle.
    let mut plane = common::uv_plane("plane", 0.5);
    for uv in plane.uv1.as_mut().unwrap() {
        *uv *= 0.25;
    }
    common::add(
        &mut scene,
        plane,
        Vec3::splat(0.5),
        Affine3A::IDENTITY,
        true,
    );
    let mut s = settings(Method::Vpl, 4.0);
    s.layout.padding = 1;
    let prep = Prepared::new(&scene, &s).unwrap();
    let ctx = prep.ctx();
    let n = 10_000_000u32;
    let vpl = |i: u32| Vpl {
        position: Vec3::new(0.0, 1.0, 0.0),
        power: Vec3::new(1.0, 0.5, 0.25),
        kind: VplKind::Diffuse {
            normal: Vec3::NEG_Y,
        },
        depth: 1,
        path: i,
    };
    let vpls: Vec<Vpl> = (0..n).map(vpl).collect();
    let start = std::time::Instant::now();
    let out = gather(
        &ctx,
        &vpls,
        n,
        f32::INFINITY,
        &lightbake::progress::Progress::new(),
    );
    let seconds = start.elapsed().as_secs_f64();
    let mut checked = 0;
    let mut worst = 0.0f64;
    let mut naive_worst = 0.0f64;
    for (k, patch) in ctx.patches.patches.iter().enumerate() {
        if !patch.is_valid() {
            continue;
        }
        // One term, computed as the gather computes it.
        let sp = patch.representative();
        let d = vpl(0).position - sp.position;
        let r2 = d.length_squared();
        let l = d / r2.sqrt();
        let g = sp.normal.dot(l) * Vec3::Y.dot(l) / r2;
        let term = vpl(0).power * (std::f32::consts::FRAC_1_PI * g);
        let exact = term.x as f64 * n as f64;
        worst = worst.max((out.irradiance[k].x as f64 - exact).abs() / exact);
        let naive = (0..n).fold(0.0f32, |acc, _| acc + term.x);
        naive_worst = naive_worst.max((naive as f64 - exact).abs() / exact);
        checked += 1;
    }
    println!(
        "{checked} texels × 10⁷ VPLs in {seconds:.1} s: worst relative error {worst:.1e} (an f32 running sum: {naive_worst:.1e})"
    );
    assert!(checked > 0);
    assert!(worst < 1e-6, "worst relative error {worst:e}");
    assert!(
        naive_worst > 1e-3,
        "the f32 sum was expected to drift ({naive_worst:e})"
    );
}

#[test]
fn a_sliver_longer_than_a_page_is_refused_by_name_before_xatlas() {
    // 10⁸ m long and 10⁻⁹ m wide: 0.05 m² passes the memory plan, but no chart of it fits a
    // page; xatlas crashed (SIGSEGV) on such a mesh found by tests/fuzz_import.rs.
    let mut scene = cornell_box(CornellLight::Area);
    let sliver = triangles(
        "sliver",
        &[[
            Vec3::ZERO,
            Vec3::new(1e8, 0.0, 0.0),
            Vec3::new(1e8, 1e-9, 0.0),
        ]],
    );
    common::add(
        &mut scene,
        sliver,
        Vec3::splat(0.5),
        Affine3A::IDENTITY,
        true,
    );
    let result = lightbake::bake(
        &scene,
        &settings(Method::Direct, 16.0),
        &lightbake::progress::Progress::new(),
    );
    let Err(err) = result else {
        panic!("the sliver was baked");
    };
    let err = err.to_string();
    assert!(
        err.contains("sliver") && err.contains("triangle 0") && err.contains("1/1000"),
        "{err}"
    );
}

/// Two rooms side by side (x < 0 and x > 0, 1 m cubes, inward faces, albedo 0.6), separated
/// by a single-sided zero-thickness partition facing the lit room, with a point light in the
/// lit room only. No light path reaches the dark room.
fn split_rooms() -> Scene {
    let mut scene = Scene {
        name: "split_rooms".into(),
        ..Scene::default()
    };
    let mut room = cuboid(
        "rooms",
        Vec3::new(-1.0, 0.0, -0.5),
        Vec3::new(1.0, 1.0, 0.5),
        false,
    );
    for t in room.indices.chunks_exact_mut(3) {
        t.swap(1, 2);
    }
    for n in &mut room.normals {
        *n = -*n;
    }
    common::add(&mut scene, room, Vec3::splat(0.6), Affine3A::IDENTITY, true);
    let partition = lightbake::scene::testscenes::quad(
        "partition",
        [
            Vec3::new(0.0, 0.0, -0.5),
            Vec3::new(0.0, 1.0, -0.5),
            Vec3::new(0.0, 1.0, 0.5),
            Vec3::new(0.0, 0.0, 0.5),
        ],
        Vec3::X,
    );
    common::add(
        &mut scene,
        partition,
        Vec3::splat(0.6),
        Affine3A::IDENTITY,
        true,
    );
    scene.lights.push(lightbake::scene::Light {
        name: "lamp".into(),
        kind: lightbake::scene::LightKind::Point,
        color: Vec3::ONE,
        intensity: 5.0,
        range: None,
        position: Vec3::new(0.5, 0.6, 0.1),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    scene
}

#[test]
fn the_dark_side_of_a_thin_single_sided_wall_stays_dark() {
    // Every method; texels of the shared walls more than 1.5 texels inside the dark room must
    // be exactly zero (the texels straddling the partition may hold light from their lit
    // half, as the GPU's bilinear filter would show anyway).
    let scene = split_rooms();
    let density = 24.0;
    let margin = 1.5 / density;
    let mut failures = Vec::new();
    for method in [
        Method::Direct,
        Method::Radiosity,
        Method::Vpl,
        Method::Hybrid,
    ] {
        for solver in [SolverChoice::Auto, SolverChoice::StochasticJacobi] {
            if solver == SolverChoice::StochasticJacobi && method != Method::Radiosity {
                continue;
            }
            let mut s = settings(method, density);
            s.radiosity.solver = solver;
            let out = bake(&scene, &s);
            assert!(all_finite(&out), "{method:?}: non-finite texels");
            let texels = common::texels(&out, 0);
            let lit: Vec<f32> = texels
                .iter()
                .filter(|t| t.position.x > margin)
                .map(|t| t.value.max_element())
                .collect();
            let dark: Vec<f32> = texels
                .iter()
                .filter(|t| t.position.x < -margin)
                .map(|t| t.value.max_element())
                .collect();
            let lit_mean = lit.iter().sum::<f32>() / lit.len() as f32;
            let leaks = dark.iter().filter(|&&v| v > 0.0).count();
            let brightest = dark.iter().copied().fold(0.0f32, f32::max);
            println!(
                "{method:?}/{solver:?}: lit mean {lit_mean:.3}, {} dark texels, {leaks} lit, brightest {brightest:e}",
                dark.len()
            );
            assert!(lit_mean > 0.0 && dark.len() > 100);
            if leaks > 0 {
                failures.push(format!(
                    "{method:?}/{solver:?}: {leaks} dark-room texels are lit (brightest {brightest:e}, lit room mean {lit_mean})"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn vpls_in_a_sharp_wedge() {
    // Inside the 5° wedge nearly everything a texel sees is within the clamp distance, so the
    // clamp removes most of the VPL light there and the compensation must give it back. The
    // one-bounce compensation read the exitance of the near field from the clamped result,
    // which lacks the same light: texels within 10 cm of the crease came out at 42–60 against
    // 95.8 at 8 192 particles, and more particles did not help. The fixed-point compensation
    // converges. This checks the bias (the means, and the texels next to the crease) and that
    // what is left is noise that falls like 1/√N.
    let (rho, e) = (0.9f32, 10.0f32);
    let scene = hard_furnace(rho, e, &["wedge"]);
    let depth = 29;
    let expected = e * (1.0 - rho.powi(depth as i32 + 1)) / (1.0 - rho);
    // Hybrid with bias compensation, `particles` and cuts of `cut` nodes (0: every VPL).
    let run = |particles: u32, cut: u32, seed: u32| {
        let mut s = settings(Method::Hybrid, 24.0);
        s.vpl.bias_compensation = true;
        s.vpl.max_depth = depth;
        s.vpl.particles = particles;
        s.vpl.cut_size = cut;
        s.direct.samples_per_texel = 128;
        s.seed = seed;
        let out = bake(&scene, &s);
        assert!(all_finite(&out));
        out
    };
    // The texels' RMS relative difference from the expected value.
    let rms_of = |values: &[f32]| {
        let sum: f32 = values.iter().map(|v| (v / expected - 1.0).powi(2)).sum();
        (sum / values.len() as f32).sqrt()
    };
    let mut rms_at = Vec::new();
    for particles in [1024u32, 4096] {
        let (mut means, mut near_means, mut rmss) = (Vec::new(), Vec::new(), Vec::new());
        for seed in [0u32, 1] {
            // Keller's gather of every VPL: this checks the walk and the compensation over
            // particles (the cut's picks, below, add noise of their own).
            let out = run(particles, 0, seed);
            let texels = common::texels(&out, 1);
            let mean_of = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
            let values: Vec<f32> = texels.iter().map(|t| t.value.x).collect();
            // Both plates' texels within 10 cm of the crease (x = −0.3).
            let near: Vec<f32> = texels
                .iter()
                .filter(|t| t.position.x + 0.3 < 0.1)
                .map(|t| t.value.x)
                .collect();
            assert!(near.len() > 20, "{} texels near the crease", near.len());
            let rms = rms_of(&values);
            let walls: Vec<f32> = common::texels(&out, 0).iter().map(|t| t.value.x).collect();
            println!(
                "{particles} particles, seed {seed}: wedge mean {:.1}, within 10 cm of the crease {:.1}, texel RMS {rms:.3}; walls {:.1}; expected {expected:.1}",
                mean_of(&values),
                mean_of(&near),
                mean_of(&walls)
            );
            assert!(common::rel(mean_of(&walls), expected) < 0.02);
            means.push(mean_of(&values));
            near_means.push(mean_of(&near));
            rmss.push(rms);
        }
        let two = |v: &[f32]| (v[0] + v[1]) / 2.0;
        rms_at.push(two(&rmss));
        if particles == 4096 {
            assert!(
                common::rel(two(&means), expected) < 0.04,
                "wedge mean {means:?} against {expected}"
            );
            assert!(
                common::rel(two(&near_means), expected) < 0.15,
                "near the crease {near_means:?} against {expected}"
            );
            assert!(rmss.iter().all(|&r| r < 0.3), "texel RMS {rmss:?}");
        }
    }
    // 4× the particles: noise halves (1/√N); a bias would not shrink.
    assert!(rms_at[1] < 0.65 * rms_at[0], "texel RMS {rms_at:?}");
    // Through cuts of 256 nodes (the medium preset) the same VPLs give the same mean: the
    // picks add noise (every VPL of the wedge is within the clamp distance of its texels, so
    // one pick per node is a coarse sample there), not bias.
    let mut means = Vec::new();
    for seed in [0u32, 1] {
        let out = run(4096, 256, seed);
        let values: Vec<f32> = common::texels(&out, 1).iter().map(|t| t.value.x).collect();
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        let rms = rms_of(&values);
        println!("cuts of 256, seed {seed}: wedge mean {mean:.1}, texel RMS {rms:.3}");
        means.push(mean);
    }
    let mean = (means[0] + means[1]) / 2.0;
    assert!(
        common::rel(mean, expected) < 0.04,
        "through cuts: wedge mean {means:?} against {expected}"
    );
}

#[test]
fn a_solver_that_cannot_converge_at_albedo_0_999_says_so() {
    // ρ = 0.999 needs thousands of Jacobi sweeps; with a budget of 300 every slow solver must
    // either still land within 1% of E/(1 − ρ) or warn that it stopped short. Never a silent
    // wrong answer.
    let (rho, e) = (0.999f32, 1.0f32);
    let scene = furnace_box(1.0, rho, e);
    let expected = e / (1.0 - rho);
    for solver in [
        SolverChoice::Jacobi,
        SolverChoice::GaussSeidel,
        SolverChoice::Shooting,
        SolverChoice::StochasticJacobi,
    ] {
        let mut s = settings(Method::Radiosity, 8.0);
        s.radiosity.solver = solver;
        s.radiosity.max_solver_iterations = 300;
        s.radiosity.solver_tolerance = 2e-3;
        s.radiosity.stochastic_rays_per_node = 64;
        let out = bake(&scene, &s);
        assert!(all_finite(&out), "{solver:?}: non-finite texels");
        let values: Vec<f32> = common::texels(&out, 0).iter().map(|t| t.value.x).collect();
        let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64;
        let warned = out
            .report
            .warnings
            .iter()
            .any(|w| w.contains("did not reach the tolerance"));
        println!("{solver:?}: mean {mean:.1} against {expected:.1}, warned {warned}");
        assert!(
            warned || common::rel(mean as f32, expected) < 0.01,
            "{solver:?}: mean {mean} against {expected} and no warning: {:?}",
            out.report.warnings
        );
        assert!(
            warned,
            "{solver:?}: converged at ρ = 0.999 within 300 iterations?"
        );
    }
}

#[test]
fn overlapping_emitters_are_named_and_meshes_are_not() {
    // Two emissive squares in one plane, the second shifted by half its side: their light
    // adds up in the overlap, so the bake names them. Coplanar neighbours (a mesh's own
    // triangles, a subdivided panel), exact duplicates (sampled once), parallel planes and
    // opposite faces do not overlap.
    let mut scene = furnace_box(1.0, 0.5, 0.0);
    let lamp = scene.add_material(Material {
        emissive: Vec3::splat(5.0),
        ..Material::diffuse("lamp", Vec3::splat(0.5))
    });
    let square = |name: &str, x0: f32, y: f32, facing: Vec3| {
        let c = [
            Vec3::new(x0, y, -0.2),
            Vec3::new(x0 + 0.4, y, -0.2),
            Vec3::new(x0 + 0.4, y, 0.2),
            Vec3::new(x0, y, 0.2),
        ];
        lightbake::scene::testscenes::quad(name, c, facing)
    };
    let put = |scene: &mut Scene, mesh: Mesh| {
        let name = mesh.name.clone();
        let m = scene.add_mesh(Mesh {
            material: Some(lamp),
            ..mesh
        });
        scene
            .instances
            .push(Instance::new(name, m, Affine3A::IDENTITY));
    };
    put(&mut scene, square("lamp_a", -0.4, 0.45, Vec3::NEG_Y));
    put(&mut scene, square("lamp_b", -0.2, 0.45, Vec3::NEG_Y));
    // Not overlaps: an exact twin of lamp_a, a parallel lamp 1 cm lower, the same square
    // facing up, and a subdivided panel elsewhere on the ceiling.
    put(&mut scene, square("lamp_a_twin", -0.4, 0.45, Vec3::NEG_Y));
    put(&mut scene, square("lamp_low", -0.4, 0.44, Vec3::NEG_Y));
    put(&mut scene, square("lamp_up", 0.1, 0.3, Vec3::Y));
    let panel = lightbake::scene::testscenes::grid("panel", 0.3, 12);
    let m = scene.add_mesh(Mesh {
        material: Some(lamp),
        ..panel
    });
    scene.instances.push(Instance::new(
        "panel",
        m,
        Affine3A::from_translation(Vec3::new(0.2, -0.49, 0.2)),
    ));
    let out = bake(&scene, &settings(Method::Direct, 8.0));
    let warning: Vec<&String> = out
        .report
        .warnings
        .iter()
        .filter(|w| w.contains("overlap in the same plane"))
        .collect();
    println!("{warning:#?}");
    assert_eq!(warning.len(), 1, "{:?}", out.report.warnings);
    let w = warning[0];
    // lamp_a and lamp_b overlap in a 0.2 × 0.4 strip: with two triangles each, 3–4 pairs.
    assert!(w.contains("'lamp_a'") && w.contains("'lamp_b'"), "{w}");
    for quiet in ["lamp_low", "lamp_up", "panel", "lamp_a_twin"] {
        assert!(!w.contains(&format!("'{quiet}'")), "{quiet} in {w}");
    }
    // The hard furnace's pieces (coincident twins, slivers, wedge, cube) overlap nowhere.
    let furnace = bake(
        &hard_furnace(0.9, 10.0, &["tiny_cube", "wedge", "slivers", "coincident"]),
        &settings(Method::Direct, 8.0),
    );
    assert!(
        !furnace
            .report
            .warnings
            .iter()
            .any(|w| w.contains("overlap in the same plane")),
        "{:?}",
        furnace.report.warnings
    );
}

/// A surface no light reaches at all (a plane under the floor, facing down into nothing) has
/// texels of exactly zero light and zero estimated noise, their neighbours too. The
/// denoiser's strength there is 0/0: it must keep the texels at zero, and every written
/// value stay finite, at every preset that denoises.
#[test]
fn a_surface_no_light_reaches_stays_black_and_finite_through_the_denoiser() {
    let mut s = Scene::default();
    let white = s.add_material(Material::diffuse("white", Vec3::splat(0.7)));
    let floor = s.add_mesh(Mesh {
        material: Some(white),
        ..lightbake::scene::testscenes::plane("floor", 2.0)
    });
    s.instances
        .push(Instance::new("floor", floor, Affine3A::IDENTITY));
    // The same plane 1 m lower, turned to face down: nothing is below it.
    s.instances.push(Instance::new(
        "underside",
        floor,
        Affine3A::from_translation(Vec3::new(0.0, -1.0, 0.0))
            * Affine3A::from_rotation_x(std::f32::consts::PI),
    ));
    s.lights.push(lightbake::scene::Light {
        name: "lamp".into(),
        kind: lightbake::scene::LightKind::Point,
        color: Vec3::ONE,
        intensity: 10.0,
        range: None,
        position: Vec3::new(0.2, 1.0, 0.1),
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    for preset in [BakeSettings::medium(), BakeSettings::high()] {
        let mut settings = preset;
        settings.layout.texel_density = Some(24.0);
        settings.layout.texel_density_from_scene = false;
        // The hierarchical solve (the default above 32 768 nodes) gives the per-texel noise
        // the denoiser works from.
        settings.radiosity.solver = SolverChoice::Hierarchical;
        assert!(settings.finish.denoise);
        let out = bake(&s, &settings);
        assert!(all_finite(&out), "a non-finite texel");
        let denoise = out.report.denoise.as_ref().expect("the denoiser ran");
        assert!(denoise.mean_strength.is_finite(), "{denoise:?}");
        let under = out.layout.instances[1].unwrap();
        let page = &out.pages[under.page as usize];
        for y in under.y..under.y + under.height {
            for x in under.x..under.x + under.width {
                assert_eq!(
                    page.get(x, y),
                    Vec3::ZERO,
                    "texel ({x}, {y}) of the underside"
                );
            }
        }
    }
}
