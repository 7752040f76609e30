//! The bake's check of its own texel grid (`lightbake::lightmap::grid_error`): known answers
//! (smooth light reads almost nothing, a lightmap 10% too bright reads 10%, a sharp shadow's
//! error shrinks with the texel, a point shows 2/3 of a texel's independent noise) and, on a
//! real scene, an estimate that now meets what the path tracer measures.

mod common;

use common::add;
use glam::{Affine3A, Vec3};
use lightbake::context::Prepared;
use lightbake::direct::{DirectResult, direct_light};
use lightbake::error_estimate::rms_luminance;
use lightbake::lightmap::grid_error::{GridError, grid_error};
use lightbake::lights::Emitters;
use lightbake::scene::testscenes::{cuboid, plane};
use lightbake::scene::{Light, LightBake, LightKind, Scene};
use lightbake::{BakeSettings, Progress};

fn light(kind: LightKind, position: Vec3, direction: Vec3, intensity: f32) -> Light {
    Light {
        name: "light".into(),
        kind,
        color: Vec3::ONE,
        intensity,
        range: None,
        position,
        direction,
        bake: LightBake::Full,
    }
}

/// A 4 m grey floor, baked.
fn floor() -> Scene {
    let mut s = Scene::default();
    add(
        &mut s,
        plane("floor", 4.0),
        Vec3::splat(0.5),
        Affine3A::IDENTITY,
        true,
    );
    s
}

/// The floor under a lamp 2 m up: its light changes slowly over a texel.
fn lamp_over_floor() -> Scene {
    let mut s = floor();
    s.lights.push(light(
        LightKind::Point,
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::NEG_Y,
        40.0,
    ));
    s
}

/// The floor with a 1 m box on it under a sun with no disc (a hard-edged shadow).
fn box_in_the_sun() -> Scene {
    let mut s = floor();
    let cube = cuboid(
        "box",
        Vec3::new(-0.5, 0.0, -0.5),
        Vec3::new(0.5, 1.0, 0.5),
        true,
    );
    add(&mut s, cube, Vec3::splat(0.5), Affine3A::IDENTITY, false);
    let sun = LightKind::Directional {
        angular_radius: 0.0,
    };
    let towards = Vec3::new(0.3, -1.0, 0.2).normalize();
    s.lights.push(light(sun, Vec3::ZERO, towards, 10_000.0));
    s
}

fn settings(density: f32) -> BakeSettings {
    {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(density);
        s.layout.texel_density_from_scene = false;
        s.layout.adaptive_density = false;
        s
    }
}

/// The direct pass of `scene` at `density` texels/m, and the check of `direct × scale`.
fn check(scene: &Scene, density: f32, scale: f32) -> (GridError, DirectResult) {
    let prep = Prepared::new(scene, &settings(density)).unwrap();
    let ctx = prep.ctx();
    let emitters = Emitters::collect(&prep.scene, &prep.rays);
    let direct = direct_light(&ctx, &emitters, &Progress::new());
    let valid: Vec<Vec3> = prep
        .patches
        .patches
        .iter()
        .zip(&direct.irradiance)
        .filter(|(p, _)| p.is_valid())
        .map(|(_, e)| *e)
        .collect();
    let value = rms_luminance(&valid);
    let scaled: Vec<Vec3> = direct.irradiance.iter().map(|e| *e * scale).collect();
    let grid = grid_error(
        &prep.scene,
        &prep.layout,
        &prep.patches,
        &prep.rays,
        &prep.plan,
        &emitters,
        &prep.settings,
        &scaled,
        &direct.standard_error,
        value,
    )
    .expect("points on the floor");
    (grid, direct)
}

#[test]
fn smooth_light_reads_almost_no_grid_error_and_a_lightmap_ten_percent_bright_reads_ten() {
    let scene = lamp_over_floor();
    let (grid, _) = check(&scene, 8.0, 1.0);
    println!("smooth: {:.3}%", 100.0 * grid.estimate.relative_rms);
    assert!(grid.points > 16_000, "{}", grid.points);
    // 12.5 cm texels under a lamp 2 m up: linear interpolation misses about h²·E''/8.
    assert!(grid.estimate.relative_rms < 0.003, "{:?}", grid.estimate);
    let (bright, _) = check(&scene, 8.0, 1.1);
    println!("10% bright: {:.3}%", 100.0 * bright.estimate.relative_rms);
    assert!(
        (0.095..0.105).contains(&bright.estimate.relative_rms),
        "{:?}",
        bright.estimate
    );
}

#[test]
fn a_hard_shadow_reads_grid_error_that_shrinks_with_the_texel() {
    let scene = box_in_the_sun();
    let (coarse, _) = check(&scene, 4.0, 1.0);
    let (fine, _) = check(&scene, 16.0, 1.0);
    let (c, f) = (coarse.estimate.relative_rms, fine.estimate.relative_rms);
    println!(
        "25 cm texels: {:.2}%, 6.25 cm: {:.2}%",
        100.0 * c,
        100.0 * f
    );
    // Near a step the error is of the order of the step over a band a texel wide: its RMS
    // falls as √h, half for a quarter of the texel.
    assert!(c > 0.05, "{c}");
    assert!((0.35..0.7).contains(&(f / c)), "{f} against {c}");
}

/// `scene` baked with `settings` and the grid check at `grid_points` points, then checked
/// against the path tracer at 2 048 points: the estimate (relative RMS) and its ratio to the
/// measured error.
fn verified(scene: &Scene, mut settings: BakeSettings, grid_points: u32) -> (f64, f64) {
    settings.checks.grid_error_points = grid_points;
    settings.checks.verify_points = 2048;
    settings.checks.verify_paths = 1024;
    let mut out = lightbake::bake(scene, &settings, &Progress::new()).unwrap();
    lightbake::analysis::verify::verify(scene, &mut out);
    let v = out.report.verification.clone().unwrap();
    println!("grid points {grid_points}: {}", v.summary());
    assert_eq!(v.estimate_covers_grid, grid_points > 0);
    let estimate = out.report.error.as_ref().unwrap().relative_rms;
    (estimate, v.estimate_ratio.unwrap())
}

/// On a real scene (assimp's teapots, `assets/corpus/assimp/`, at medium) the texel grid is
/// most of the error: without its check the estimate is about a quarter of what the path tracer
/// measures; with it, within 0.7–1.5× of it.
#[test]
fn on_the_teapots_the_estimate_meets_the_measured_error_once_the_grid_is_checked() {
    let scene = common::corpus_scene("assimp/teapots.gltf");
    let without = verified(&scene, BakeSettings::medium(), 0).1;
    let with = verified(&scene, BakeSettings::medium(), 16_384).1;
    assert!(without < 0.5, "{without}");
    assert!((0.7..=1.5).contains(&with), "{with}");
}

/// A point reads four texels bilinearly, and their independent noise partly cancels: a
/// uniform point of a chart's middle shows (2/3)² of a texel's variance. Under a sky the box's
/// contact shadow is noisy texel by texel.
#[test]
fn a_point_shows_two_thirds_of_a_texels_noise() {
    let mut scene = box_in_the_sun();
    scene.lights.clear();
    scene.sky = Vec3::splat(1000.0);
    let (grid, direct) = check(&scene, 8.0, 1.0);
    assert!(direct.standard_error.iter().any(|&s| s > 0.0));
    println!(
        "under a sky: a point shows {:.3}× a texel's noise",
        grid.point_noise
    );
    assert!(
        (0.62..0.74).contains(&grid.point_noise),
        "{}",
        grid.point_noise
    );
    // A sun without a disc over a bare floor: the same light at every sample, no noise, and
    // nothing to scale.
    let mut sunlit = floor();
    let sun = LightKind::Directional {
        angular_radius: 0.0,
    };
    sunlit
        .lights
        .push(light(sun, Vec3::ZERO, Vec3::NEG_Y, 10_000.0));
    let (grid, direct) = check(&sunlit, 8.0, 1.0);
    assert!(direct.standard_error.iter().all(|&s| s == 0.0));
    assert_eq!(grid.point_noise, 1.0);
}

/// At preview (no denoiser) the bake's estimate is of what a point shows: in the Cornell box,
/// whose texel grid adds nothing, the estimate with the grid check is that share of the one
/// without it, and within 0.7–1.5× of what `--verify` measures (1.61× per texel).
#[test]
fn at_preview_the_estimate_is_of_the_noise_a_point_shows() {
    let scene =
        lightbake::scene::testscenes::cornell_box(lightbake::scene::testscenes::CornellLight::Area);
    let (per_texel, _) = verified(&scene, BakeSettings::preview(), 0);
    let (at_points, ratio) = verified(&scene, BakeSettings::preview(), 16_384);
    let share = at_points / per_texel;
    println!(
        "estimate {per_texel:.4} per texel, {at_points:.4} at points ({share:.3}), {ratio:.2}× measured"
    );
    assert!((0.6..0.72).contains(&share), "{share}");
    assert!((0.7..=1.5).contains(&ratio), "{ratio}");
}
