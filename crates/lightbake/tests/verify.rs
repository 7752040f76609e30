//! `bake --verify`: the check of a finished bake against the path tracer.

mod common;

use common::corpus_scene;
use lightbake::analysis::checks::{measure, verification_points};
use lightbake::analysis::verify::verify;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::{BakeSettings, Progress};

/// On the Cornell box the check at 1 024 paths per point measures the same error as one at
/// 16 384 paths (independent numbers, same points) within the uncertainty it states for the
/// reference's noise, its
/// stated reference noise is the noise the long reference sees, and the default bake is
/// right: error under 2%, no lit point left black.
#[test]
fn verify_agrees_with_a_long_reference_within_its_stated_noise() {
    let scene = cornell_box(CornellLight::Area);
    let mut settings = BakeSettings::medium();
    settings.checks.verify_points = 256;
    settings.checks.verify_paths = 1024;
    let mut out = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    verify(&scene, &mut out);
    let v = out.report.verification.clone().unwrap();
    assert_eq!(v.points, 256);
    assert_eq!(v.paths, 1024);
    assert!(v.relative_rms.is_finite() && v.relative_rms < 0.02, "{v:?}");
    assert!(
        v.reference_noise > 0.0 && v.reference_uncertainty > 0.0,
        "{v:?}"
    );
    assert!(v.uncertainty > v.reference_uncertainty, "{v:?}");
    assert_eq!(v.lit_but_black, 0);
    assert_eq!(v.worst.len(), 10);
    assert!(v.summary().contains("verify: 256 points"));

    let seed = 0xabcd;
    let short = verification_points(&scene, &out, 256, 1024, seed, 1);
    let long = verification_points(&scene, &out, 256, 16384, seed, 2);
    assert_eq!(short.len(), long.len());
    assert!(
        short
            .iter()
            .zip(&long)
            .all(|(a, b)| a.position == b.position)
    );
    // The short reference's spread about the long one is the noise it states.
    let lum = |c: glam::Vec3| (0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z) as f64;
    let (mut d2, mut stated, mut norm) = (0.0, 0.0, 0.0);
    for (a, b) in short.iter().zip(&long) {
        d2 += (lum(a.reference) - lum(b.reference)).powi(2);
        stated += a.variance + b.variance;
        norm += lum(b.reference).powi(2);
    }
    let ratio = (d2 / stated).sqrt();
    assert!(
        (0.75..1.33).contains(&ratio),
        "the references differ by {:.3}% RMS where their stated noise gives {:.3}%",
        100.0 * (d2 / norm).sqrt(),
        100.0 * (stated / norm).sqrt()
    );
    let (s, l) = (measure(&scene, &out, &short), measure(&scene, &out, &long));
    assert!(s.uncertainty >= s.reference_uncertainty);
    let spread = 3.0 * (s.reference_uncertainty.powi(2) + l.reference_uncertainty.powi(2)).sqrt();
    assert!(
        (s.relative_rms - l.relative_rms).abs() <= spread,
        "{:.3}% at 1 024 paths, {:.3}% at 16 384 (3σ = {:.3}%)",
        100.0 * s.relative_rms,
        100.0 * l.relative_rms,
        100.0 * spread
    );
}

/// The check sees what is wrong: a lightmap blacked out over one wall shows as lit points
/// left black and as error.
#[test]
fn verify_sees_a_black_wall() {
    let scene = cornell_box(CornellLight::Area);
    let mut settings = BakeSettings::preview();
    settings.checks.verify_points = 128;
    settings.checks.verify_paths = 256;
    let mut out = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    verify(&scene, &mut out);
    let good = out.report.verification.take().unwrap();
    let wall = scene
        .instances
        .iter()
        .position(|i| i.name == "back_wall")
        .unwrap();
    let rect = out.layout.instances[wall].unwrap();
    let page = &mut out.pages[rect.page as usize];
    for y in rect.y..rect.y + rect.height {
        for x in rect.x..rect.x + rect.width {
            let i = (y * page.width + x) as usize;
            page.texels[i] = glam::Vec3::ZERO;
        }
    }
    verify(&scene, &mut out);
    let bad = out.report.verification.unwrap();
    assert_eq!(good.lit_but_black, 0);
    assert!(bad.lit_but_black > 5, "{bad:?}");
    assert!(bad.relative_rms > 10.0 * good.relative_rms.max(0.005));
    assert!(bad.relative_bias < -0.05);
    assert!(bad.worst.iter().any(|p| p.instance == "back_wall"));
}

/// Bakes a scene of the corpus at preview, checked at 256 points: no lit point left black —
/// the independent test of the bake's own `visible but unlit` count — every texel finite,
/// no padding texel brighter than twice the brightest covered one, and the error below
/// `bound`.
fn corpus_scene_checks(file: &str, bound: f64) {
    let scene = corpus_scene(file);
    let mut settings = BakeSettings::preview();
    settings.checks.verify_points = 256;
    settings.checks.verify_paths = 1024;
    let mut out = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    verify(&scene, &mut out);
    let v = out.report.verification.clone().unwrap();
    println!("{file}: {}", v.summary());
    assert_eq!(out.report.texels.visible_unlit, 0);
    assert_eq!(v.lit_but_black, 0, "{v:?}");
    assert!(v.points >= 250);
    assert!(
        v.relative_rms.is_finite() && v.relative_rms < bound,
        "{v:?}"
    );
    assert!(
        out.pages
            .iter()
            .all(|p| p.texels.iter().all(|t| t.is_finite()))
    );
    // No texel outside the charts (padding the contact fit chose, dilation) is brighter than
    // twice the brightest texel inside them.
    let brightest = |covered: bool| {
        out.pages
            .iter()
            .flat_map(|p| p.texels.iter().zip(&p.covered))
            .filter(|(_, c)| **c == covered)
            .map(|(t, _)| t.max_element())
            .fold(0.0f32, f32::max)
    };
    let (inside, outside) = (brightest(true), brightest(false));
    assert!(
        outside <= 2.0 * inside,
        "a padding texel holds {outside}, the brightest covered texel {inside}"
    );
}

/// The house (a real architectural model, not built for these tests).
#[test]
fn the_house_has_no_lit_point_left_black() {
    corpus_scene_checks("house.gltf", 0.1);
}

/// Kenney's 3D platformer level (a game level, not built for these tests).
#[test]
fn the_kenney_platformer_has_no_lit_point_left_black() {
    corpus_scene_checks("kenney_platformer/kenney_platformer.gltf", 0.12);
}

/// Kenney's FPS starter level (a game level, not built for these tests).
#[test]
fn the_kenney_level_has_no_lit_point_left_black() {
    corpus_scene_checks("kenney_fps/kenney_fps.gltf", 0.12);
}

/// OpenArena's `aggressor` (a game level, Z-up in inches under its root node, 84 point
/// lights, most of them in other rooms than any one texel).
#[test]
fn the_openarena_aggressor_level_has_no_lit_point_left_black() {
    corpus_scene_checks("openarena/aggressor.gltf", 0.2);
}

/// OpenArena's `q3dm6ish` (a game level, Z-up in inches, 30 point lights).
#[test]
fn the_openarena_q3dm6ish_level_has_no_lit_point_left_black() {
    corpus_scene_checks("openarena/q3dm6ish.gltf", 0.25);
}

/// Three teapots exported from 3ds Max, authored Z-up in centimetres (assimp's
/// `teapots.DAE`): meshes in centimetres under transforms that scale them by 0.01, standing
/// on a ground square in metres, the smallest one floating.
#[test]
fn the_teapots_in_centimetres_have_no_lit_point_left_black() {
    let scene = corpus_scene("assimp/teapots.gltf");
    let teapots: Vec<_> = scene
        .instances
        .iter()
        .filter(|i| i.name.starts_with("Teapot"))
        .collect();
    assert_eq!(teapots.len(), 3);
    // Authored in centimetres: the root's 0.01 (times the node's own scale) is in every
    // teapot's transform, and its vertices span tens of units.
    for t in &teapots {
        let scale = t.transform.matrix3.determinant().abs().cbrt();
        assert!((0.009..0.023).contains(&scale), "{}: {scale}", t.name);
        let extent = scene.meshes[t.mesh]
            .positions
            .iter()
            .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
        assert!(extent > 10.0, "{}: {extent}", t.name);
    }
    corpus_scene_checks("assimp/teapots.gltf", 0.08);
}
