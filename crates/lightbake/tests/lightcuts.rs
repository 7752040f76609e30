//! Instant radiosity through lightcuts (`vpl::cut`, `vpl::gather::gather_cut`): against
//! Keller's gather of every VPL on the same VPLs, and at its defaults against the path tracer.

mod common;

use glam::Vec3;
use lightbake::analysis::verify::verify;
use lightbake::context::Prepared;
use lightbake::lights::Emitters;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, Method};
use lightbake::vpl::gather::{Gathered, gather, gather_cut};
use lightbake::vpl::walk::{VplSet, WalkSettings, walk};

fn prepared(scene: &Scene, density: f32) -> Prepared {
    let mut s = BakeSettings::medium();
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    Prepared::new(scene, &s).unwrap()
}

/// The VPLs of `particles` walks from the Cornell box's lights (the first generation kept,
/// as method `vpl` does), and the clamp bound of the default clamp distance.
fn cornell_vpls(prep: &Prepared, particles: u32) -> (VplSet, f32) {
    let emitters = Emitters::collect(&prep.scene, &prep.rays);
    let set = walk(
        &prep.scene,
        &prep.rays,
        &emitters,
        &WalkSettings {
            particles,
            sequence: prep.settings.vpl.sequence,
            seed: 1,
            max_depth: 16,
            first_generation: true,
        },
    );
    let d_c = lightbake::vpl::clamp_distance(&prep.ctx());
    (set, 1.0 / (d_c * d_c))
}

/// The VPLs of `set` gathered through cuts of `size` nodes, picks seeded with `seed`.
fn through_cuts(prep: &Prepared, set: &VplSet, bound: f32, size: usize, seed: u32) -> Gathered {
    let progress = Progress::new();
    gather_cut(
        &prep.ctx(),
        &set.vpls,
        set.particles,
        bound,
        size,
        seed,
        &progress,
    )
}

/// Method `vpl` at 16 texels/m with `particles` and cuts of `cut` nodes.
fn vpl_settings(particles: u32, cut: u32) -> BakeSettings {
    let mut s = common::settings(16.0, 4);
    s.method = Method::Vpl;
    s.vpl.particles = particles;
    s.vpl.cut_size = cut;
    s
}

/// Relative RMS difference of `a` from `b` over the valid patches (luminance).
fn relative(prep: &Prepared, a: &[Vec3], b: &[Vec3]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (i, p) in prep.patches.patches.iter().enumerate() {
        if p.is_valid() {
            let (x, y) = (a[i].dot(Vec3::ONE) as f64, b[i].dot(Vec3::ONE) as f64);
            num += (x - y) * (x - y);
            den += y * y;
        }
    }
    (num / den.max(1e-30)).sqrt()
}

/// A cut as large as the tree is every VPL, each exactly: the same light as Keller's gather
/// (to rounding), so the bounds dropped no VPL that reaches a texel. With small cuts, the mean
/// over independent picks converges to it: the picks are unbiased.
#[test]
fn cuts_are_unbiased_for_the_light_of_every_vpl() {
    let prep = prepared(&cornell_box(CornellLight::Area), 16.0);
    let ctx = prep.ctx();
    let (set, bound) = cornell_vpls(&prep, 1024);
    let full = gather(&ctx, &set.vpls, set.particles, bound, &Progress::new());
    let everything = through_cuts(&prep, &set, bound, set.vpls.len() + 1, 7);
    let exact = relative(&prep, &everything.irradiance, &full.irradiance);
    assert!(exact < 1e-5, "every VPL through the cut: {exact:.2e}");
    // Cuts of 32 nodes, 32 seeds of picks: the light summed over the texels, per run, is
    // Keller's sum within the runs' own standard error of the mean; and the mean over the
    // runs is nearer Keller's gather texel by texel than one run is.
    let runs: Vec<Gathered> = (0..32)
        .map(|seed| through_cuts(&prep, &set, bound, 32, seed))
        .collect();
    let sum = |v: &[Vec3]| v.iter().map(|x| x.dot(Vec3::ONE) as f64).sum::<f64>();
    let sums: Vec<f64> = runs.iter().map(|r| sum(&r.irradiance)).collect();
    let n = sums.len() as f64;
    let mean_sum = sums.iter().sum::<f64>() / n;
    let se = (sums.iter().map(|s| (s - mean_sum).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt();
    let target = sum(&full.irradiance);
    let one = relative(&prep, &runs[0].irradiance, &full.irradiance);
    let mean: Vec<Vec3> = (0..full.irradiance.len())
        .map(|i| runs.iter().map(|r| r.irradiance[i]).sum::<Vec3>() / n as f32)
        .collect();
    let averaged = relative(&prep, &mean, &full.irradiance);
    println!(
        "cuts of 32: one run {one:.4}, mean of 32 {averaged:.4}; sums: mean {mean_sum:.1} ± {se:.1}, Keller's {target:.1}"
    );
    assert!(one > 0.01, "cuts of 32 nodes are noisy: {one}");
    assert!(
        (mean_sum - target).abs() < 4.0 * se + 1e-6 * target,
        "{mean_sum} ± {se} vs {target}"
    );
    assert!(averaged < 0.5 * one, "{averaged} vs {one}");
    // Rays: one per node of the cut and texel at most, against one per VPL.
    assert!(runs[0].shadow_rays + runs[0].culled < full.shadow_rays / 10);
}

/// The standard error a cut gather states per texel is of the size of the spread of its
/// picks over seeds (it pairs adjacent nodes, which overstates rather than understates).
#[test]
fn the_stated_noise_of_a_cut_covers_the_spread_of_its_picks() {
    let prep = prepared(&cornell_box(CornellLight::Area), 16.0);
    let (set, bound) = cornell_vpls(&prep, 1024);
    let runs: Vec<Gathered> = (0..16)
        .map(|seed| through_cuts(&prep, &set, bound, 64, seed))
        .collect();
    let (mut spread, mut stated) = (0.0f64, 0.0f64);
    for (i, p) in prep.patches.patches.iter().enumerate() {
        if !p.is_valid() {
            continue;
        }
        let ys: Vec<f64> = runs
            .iter()
            .map(|r| lightbake::color::luminance(r.irradiance[i]) as f64)
            .collect();
        let m = ys.iter().sum::<f64>() / ys.len() as f64;
        spread += ys.iter().map(|y| (y - m) * (y - m)).sum::<f64>() / (ys.len() - 1) as f64;
        // The stated error includes the particle paths' part, which the picks' spread over
        // seeds does not show (the VPLs are the same): take it out by running a cut of
        // every VPL, whose picks are exact.
        stated += runs
            .iter()
            .map(|r| (r.standard_error[i] as f64).powi(2))
            .sum::<f64>()
            / runs.len() as f64;
    }
    let everything = through_cuts(&prep, &set, bound, set.vpls.len() + 1, 0);
    let paths: f64 = prep
        .patches
        .patches
        .iter()
        .enumerate()
        .filter(|(_, p)| p.is_valid())
        .map(|(i, _)| (everything.standard_error[i] as f64).powi(2))
        .sum();
    let ratio = ((stated - paths).max(0.0) / spread).sqrt();
    println!("stated pick noise / spread over seeds: {ratio:.2}");
    assert!((0.8..=3.0).contains(&ratio), "ratio {ratio:.2}");
}

/// Method `vpl` at its defaults (medium) lands within 5% of the path tracer on the Cornell
/// box and the sunlit room, with no lit point left black.
#[test]
fn instant_radiosity_at_its_defaults_is_within_five_percent_of_the_path_tracer() {
    for (name, scene) in [
        ("Cornell box", cornell_box(CornellLight::Area)),
        ("sunlit room", sunlit_room()),
    ] {
        let mut settings = BakeSettings::medium();
        settings.method = Method::Vpl;
        settings.checks.verify_points = 256;
        settings.checks.verify_paths = 1024;
        let mut out = common::bake(&scene, &settings);
        verify(&scene, &mut out);
        let v = out.report.verification.clone().unwrap();
        let vpl = out.report.vpl.as_ref().unwrap();
        println!(
            "{name}: {} VPLs, cuts of {}: {:.2}% ± {:.2}%",
            vpl.vpls,
            vpl.cut_size,
            100.0 * v.relative_rms,
            100.0 * v.uncertainty
        );
        assert!(vpl.cut_size > 0 && vpl.vpls > 10_000, "{vpl:?}");
        assert!(v.relative_rms < 0.05, "{name}: {v:?}");
        assert_eq!(v.lit_but_black, 0, "{name}");
    }
}

/// The walk and cut settings a bake reports are the ones it used, and a cut of 0 is
/// Keller's gather (one ray per VPL and texel).
#[test]
fn a_cut_of_zero_is_kellers_gather() {
    let scene = cornell_box(CornellLight::Area);
    let mut s = vpl_settings(256, 0);
    let out = common::bake(&scene, &s);
    let vpl = out.report.vpl.clone().unwrap();
    assert_eq!(vpl.cut_size, 0);
    let t = &out.report.texels;
    let valid = (t.patches - t.invalid) as u64;
    assert_eq!(
        vpl.shadow_rays + vpl.culled,
        valid * vpl.vpls as u64,
        "{vpl:?}"
    );
    s.vpl.cut_size = 16;
    let out = common::bake(&scene, &s);
    let vpl = out.report.vpl.clone().unwrap();
    assert_eq!(vpl.cut_size, 16);
    assert!(vpl.shadow_rays + vpl.culled <= valid * 16, "{vpl:?}");
}

/// The memory plan counts the VPLs: ten million particles in the Cornell box (about 2.4 VPLs
/// each) are refused before anything is traced, and the refusal names them.
#[test]
fn the_memory_plan_counts_the_vpls() {
    let scene = cornell_box(CornellLight::Area);
    let mut s = vpl_settings(10_000_000, 256);
    s.memory_budget_mib = 2048;
    match lightbake::bake(&scene, &s, &Progress::new()) {
        Err(lightbake::BakeError::OverMemoryBudget {
            needed_mib,
            breakdown,
            ..
        }) => {
            println!("refused: {needed_mib:.0} MiB ({breakdown})");
            assert!(breakdown.contains("virtual point lights"), "{breakdown}");
            assert!(needed_mib > 2048.0);
        }
        other => panic!("not refused: {:?}", other.map(|o| o.report.vpl)),
    }
    s.vpl.particles = 65_536;
    assert!(lightbake::bake(&scene, &s, &Progress::new()).is_ok());
}

/// A time budget sets the cut (from a pilot's time per shadow ray); the particles stay as set,
/// so the memory the plan admitted for the VPLs holds; the report says so.
#[test]
fn a_time_budget_sets_the_cut_and_leaves_the_particles() {
    let scene = cornell_box(CornellLight::Area);
    let mut s = vpl_settings(65_536, 256);
    s.vpl.time_budget_s = Some(0.5);
    let out = common::bake(&scene, &s);
    let vpl = out.report.vpl.clone().unwrap();
    println!(
        "{} particles, cuts of {}: {}",
        vpl.particles, vpl.cut_size, vpl.particles_reason
    );
    assert!(
        (16..=lightbake::settings::vpl::MAX_CUT).contains(&vpl.cut_size),
        "{vpl:?}"
    );
    assert_eq!(vpl.particles, s.vpl.particles);
    assert!(
        vpl.particles_reason.contains("cuts of"),
        "{}",
        vpl.particles_reason
    );
}

/// A target error raises the cut (not the particles) until the estimate reaches its share;
/// where the particles' own noise is above the target, the bake says it stopped short.
#[test]
fn a_target_error_raises_the_cut() {
    let scene = cornell_box(CornellLight::Area);
    let mut s = vpl_settings(65_536, 16);
    let pilot = common::bake(&scene, &s);
    let pilot_error = pilot.report.vpl.as_ref().unwrap().error.relative_rms;
    assert!(pilot_error > 0.1, "the pilot is already at {pilot_error}");
    s.target_error = Some(0.1);
    let out = common::bake(&scene, &s);
    let vpl = out.report.vpl.clone().unwrap();
    println!(
        "pilot: cuts of 16, {:.2}%; with the target: cuts of {}, {:.2}%",
        100.0 * pilot_error,
        vpl.cut_size,
        100.0 * vpl.error.relative_rms
    );
    assert!(vpl.cut_size > 16 && vpl.particles == 65_536, "{vpl:?}");
    assert!(vpl.error.relative_rms <= 0.1, "{vpl:?}");
    assert!(
        out.report
            .warnings
            .iter()
            .all(|w| !w.contains("above its share"))
    );
    // 8 192 particles leave about 6% of noise in their paths, which no cut removes.
    s.vpl.particles = 8192;
    s.target_error = Some(0.03);
    let out = common::bake(&scene, &s);
    let warned = out
        .report
        .warnings
        .iter()
        .any(|w| w.contains("above its share"));
    assert!(warned, "{:?}", out.report.warnings);
}
