//! Lights baked indirect only (`LightBake::IndirectOnly`, Bevy's mixed lighting): the
//! lightmaps hold everything but those lights' direct light, measured against the path
//! tracer's irradiance without it; a light with nothing to reflect it leaves the lightmaps
//! black; and rect lights bake to their closed form.

mod common;

use glam::{Affine3A, Vec3};
use lightbake::analysis::points::{score, score_points};
use lightbake::progress::Progress;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::scene::{Light, LightBake, LightKind, Scene};
use lightbake::settings::BakeSettings;

fn indirect_only(mut scene: Scene) -> Scene {
    for l in &mut scene.lights {
        l.bake = LightBake::IndirectOnly;
    }
    scene
}

fn mean_luminance(out: &lightbake::BakeOutput) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in &out.pages {
        for t in &p.texels {
            sum += (0.2126 * t.x + 0.7152 * t.y + 0.0722 * t.z) as f64;
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// The mixed bake of `scene` against the path tracer without the real-time lights' direct
/// light, and next to the full bake.
fn mixed_matches_the_reference(scene: Scene, limit: f64) {
    let settings = BakeSettings::medium();
    let full = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    let mixed_scene = indirect_only(scene);
    let points = score_points(&mixed_scene, 256, 4096, 11);
    let mixed = lightbake::bake(&mixed_scene, &settings, &Progress::new()).unwrap();
    let s = score(&points, &mixed);
    let (f, m) = (mean_luminance(&full), mean_luminance(&mixed));
    println!(
        "{}: mixed {:.2}% RMS against the reference (noise {:.2}%), mean E/π {m:.4} against {f:.4} full",
        mixed_scene.name,
        100.0 * s.relative_rms,
        100.0 * s.reference_noise
    );
    assert!(
        s.relative_rms < limit,
        "{}: {:.4}",
        mixed_scene.name,
        s.relative_rms
    );
    assert!(
        m < 0.8 * f,
        "the direct light left the lightmaps: {m} of {f}"
    );
    assert!(mixed.report.plan.describe().contains("indirect only"));
}

#[test]
fn cornell_box_point_light_indirect_only_matches_the_path_tracer() {
    mixed_matches_the_reference(cornell_box(CornellLight::Point), 0.08);
}

#[test]
fn sunlit_room_sun_indirect_only_matches_the_path_tracer() {
    // The sky stays fully baked; the sun's direct light leaves.
    mixed_matches_the_reference(sunlit_room(), 0.08);
}

#[test]
fn a_light_with_nothing_to_reflect_it_leaves_the_lightmaps_black() {
    let mut scene = Scene::default();
    common::add(
        &mut scene,
        common::uv_plane("floor", 4.0),
        Vec3::splat(0.8),
        Affine3A::IDENTITY,
        true,
    );
    scene.lights.push(Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity: 100.0,
        range: None,
        position: Vec3::new(0.0, 1.0, 0.0),
        direction: Vec3::NEG_Y,
        bake: LightBake::IndirectOnly,
    });
    let out = lightbake::bake(&scene, &BakeSettings::preview(), &Progress::new()).unwrap();
    let max = out
        .pages
        .iter()
        .flat_map(|p| p.texels.iter())
        .fold(0.0f32, |m, t| m.max(t.max_element()));
    assert_eq!(max, 0.0, "a lone plane reflects nothing onto itself");
    // Fully baked, the same light is there.
    scene.lights[0].bake = LightBake::Full;
    let out = lightbake::bake(&scene, &BakeSettings::preview(), &Progress::new()).unwrap();
    assert!(mean_luminance(&out) > 0.1);
}

#[test]
fn the_vpl_method_refuses_indirect_only_lights() {
    let scene = indirect_only(cornell_box(CornellLight::Point));
    let settings = BakeSettings {
        method: lightbake::settings::Method::Vpl,
        ..BakeSettings::preview()
    };
    let err = lightbake::bake(&scene, &settings, &Progress::new()).unwrap_err();
    assert!(err.to_string().contains("indirect only"), "{err}");
}

#[test]
fn a_rect_light_bakes_to_the_path_tracers_irradiance() {
    // The Cornell box with its ceiling light replaced by a rect light of the same size and
    // luminance, just under the ceiling.
    let mut scene = cornell_box(CornellLight::Point);
    scene.lights.clear();
    scene.lights.push(Light {
        name: "panel".into(),
        kind: LightKind::Rect {
            right: Vec3::X,
            width: 0.13,
            height: 0.105,
        },
        color: Vec3::new(1.0, 0.85, 0.6),
        intensity: 5000.0,
        range: None,
        position: Vec3::new(0.0, 0.5468, 0.0),
        direction: Vec3::NEG_Y,
        bake: LightBake::Full,
    });
    let points = score_points(&scene, 256, 4096, 5);
    let out = lightbake::bake(&scene, &BakeSettings::medium(), &Progress::new()).unwrap();
    let s = score(&points, &out);
    println!(
        "rect light: {:.2}% RMS (reference noise {:.2}%)",
        100.0 * s.relative_rms,
        100.0 * s.reference_noise
    );
    assert!(s.relative_rms < 0.08, "{}", s.relative_rms);
}
