//! Texel density that follows the light (`lightbake::density`): the texel budget is kept, the
//! charts whose light changes within a texel get the texels, the result does not depend on
//! the thread count, what is left alone is said, and on a real level the same texels give a
//! smaller error.

mod common;

use common::add;
use glam::{Affine3A, Vec3};
use lightbake::Stage;
use lightbake::analysis::checks::{measure, verification_points};
use lightbake::bvh::RayScene;
use lightbake::context::Prepared;
use lightbake::density::adapt;
use lightbake::plan::BakePlan;
use lightbake::scene::testscenes::{plane, quad};
use lightbake::scene::{Light, LightKind, Scene};
use lightbake::unwrap::unwrap_scene;
use lightbake::{BakeSettings, Progress};

fn lamp(position: Vec3, intensity: f32) -> Light {
    Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::ONE,
        intensity,
        range: None,
        position,
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    }
}

/// A 1 m floor with a lamp 0.15 m over it (its light falls from the centre to a tenth within
/// 0.3 m), and a 4 m floor 10 m away with one 6 m over it (smooth across it) giving its centre
/// a tenth of the first floor's: a wall lamp of a game level and the hall around it.
fn near_and_far_lamps() -> Scene {
    let mut s = Scene::default();
    let grey = Vec3::splat(0.5);
    add(&mut s, plane("near", 1.0), grey, Affine3A::IDENTITY, true);
    let far = Affine3A::from_translation(Vec3::new(10.0, 0.0, 0.0));
    add(&mut s, plane("far", 4.0), grey, far, true);
    s.lights.push(lamp(Vec3::new(0.0, 0.15, 0.0), 0.225));
    s.lights.push(lamp(Vec3::new(10.0, 6.0, 0.0), 36.0));
    s
}

/// Covered texels of each mesh's rectangle (its charts' areas) per m² of the mesh.
fn texels_of(p: &Prepared, mesh: usize) -> f64 {
    let texels: f64 = p.layout.meshes[mesh]
        .as_ref()
        .unwrap()
        .chart_texels()
        .iter()
        .sum();
    texels / [1.0, 16.0][mesh]
}

/// At most 1 000 texels over 17 m² (14 cm texels): the near lamp's light bends within one.
fn coarse() -> BakeSettings {
    let mut settings = BakeSettings::preview();
    settings.layout.texel_budget = 1_000;
    settings
}

#[test]
fn the_floor_under_the_near_lamp_gets_the_texels_within_the_same_budget() {
    let scene = near_and_far_lamps();
    let mut settings = coarse();
    let adaptive = Prepared::new(&scene, &settings).unwrap();
    settings.layout.adaptive_density = false;
    let uniform = Prepared::new(&scene, &settings).unwrap();
    assert!(
        adaptive.plan.runs(Stage::Density),
        "{}",
        adaptive.plan.describe()
    );
    assert!(!uniform.plan.runs(Stage::Density));
    let (near, far) = (texels_of(&adaptive, 0), texels_of(&adaptive, 1));
    let (near_u, far_u) = (texels_of(&uniform, 0), texels_of(&uniform, 1));
    assert!((near_u / far_u - 1.0).abs() < 0.1, "{near_u} / {far_u}");
    println!("near {near:.1}, far {far:.1}; uniform {near_u:.1}, {far_u:.1} texels per m²");
    // The near floor at about twice the density of the far one.
    assert!(
        near / far > 3.0,
        "near {near:.1}, far {far:.1} texels per m²"
    );
    // The total is the budget's.
    let (total, total_u) = (near + 16.0 * far, near_u + 16.0 * far_u);
    assert!(
        (total / total_u - 1.0).abs() < 0.03,
        "{total:.0} texels against {total_u:.0}"
    );
}

/// A strip under four texels across keeps its density, where the far floor beside it, in the
/// same flat light, gives texels up.
#[test]
fn thin_charts_are_never_drawn_smaller() {
    let mut scene = near_and_far_lamps();
    let strip = quad(
        "strip",
        [
            Vec3::new(12.5, 0.0, -2.0),
            Vec3::new(12.55, 0.0, -2.0),
            Vec3::new(12.55, 0.0, 2.0),
            Vec3::new(12.5, 0.0, 2.0),
        ],
        Vec3::Y,
    );
    add(
        &mut scene,
        strip,
        Vec3::splat(0.5),
        Affine3A::IDENTITY,
        true,
    );
    let settings = coarse();
    let plan = BakePlan::new(&scene, &settings);
    let layout = unwrap_scene(&scene, &settings, plan.texel_density).unwrap();
    let rays = RayScene::build(&scene);
    let (_, report) = adapt(&scene, &settings, &plan, &layout, &rays).unwrap();
    let scales = |name: &str| {
        report
            .meshes
            .iter()
            .find(|m| m.mesh == name)
            .unwrap()
            .scales
            .clone()
    };
    assert!(
        scales("far").iter().all(|&s| s < 0.95),
        "{:?}",
        scales("far")
    );
    assert!(
        scales("strip").iter().all(|&s| s >= 1.0),
        "{:?}",
        scales("strip")
    );
}

#[test]
fn the_density_does_not_depend_on_the_thread_count() {
    let scene = near_and_far_lamps();
    let settings = coarse();
    let layout = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| Prepared::new(&scene, &settings).unwrap().layout)
    };
    assert_eq!(layout(1), layout(2));
}

#[test]
fn the_plan_says_why_the_density_stays_put() {
    let scene = near_and_far_lamps();
    let mut settings = BakeSettings::preview();
    settings.layout.texel_density = Some(8.0);
    let p = Prepared::new(&scene, &settings).unwrap();
    assert!(!p.plan.runs(Stage::Density));
    assert!(
        p.plan.describe().contains("the settings set the density"),
        "{}",
        p.plan.describe()
    );
    settings.layout.texel_density = None;
    let mut hinted = scene.clone();
    hinted.texel_density_hint = Some(8.0);
    let p = Prepared::new(&hinted, &settings).unwrap();
    assert!(
        p.plan.describe().contains("the scene sets its density"),
        "{}",
        p.plan.describe()
    );
    // Lit by the sky alone: the pilot has no light to follow.
    let mut sky = scene.clone();
    sky.lights.clear();
    sky.sky = Vec3::splat(1000.0);
    let p = Prepared::new(&sky, &settings).unwrap();
    assert!(!p.plan.runs(Stage::Density));
    assert!(
        p.plan.describe().contains("the pilot sees only those"),
        "{}",
        p.plan.describe()
    );
}

/// Kenney's FPS level at preview (not built for these tests): with the density following the
/// sun's shadow edges and the lamps the bake has no more texels, and its error at the same
/// 8 192 points is under nine tenths of the one-density bake's (`bake --verify 8192
/// --verify-paths 512`: 6.46% ± 0.35% → 5.08% ± 0.34%), with no more lit points left black.
/// Errors on a level are heavy-tailed, so only many points compare two bakes surely.
#[test]
fn on_a_real_level_the_same_texels_give_a_smaller_error() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/corpus/kenney_fps/kenney_fps.gltf");
    let scene = lightbake::import_gltf(&path, lightbake::LightConvention::GltfSpec)
        .unwrap()
        .scene;
    let mut settings = BakeSettings::preview();
    let adaptive = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    settings.layout.adaptive_density = false;
    let uniform = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    let density = adaptive
        .report
        .density
        .as_ref()
        .expect("the density followed the light");
    assert!(
        density.charts > 20 && density.at_greatest > 0,
        "{density:?}"
    );
    assert!(uniform.report.density.is_none());
    let (a, u) = (
        adaptive.report.texels.patches,
        uniform.report.texels.patches,
    );
    assert!(a as f64 <= 1.02 * u as f64, "{a} texels against {u}");
    let points = verification_points(&scene, &uniform, 8192, 512, 0x5eed, 1);
    let (ea, eu) = (
        measure(&scene, &adaptive, &points),
        measure(&scene, &uniform, &points),
    );
    println!(
        "adaptive {:.2}% ± {:.2}% ({a} texels, {} lit but black), uniform {:.2}% ± {:.2}% ({u} texels, {} lit but black)",
        100.0 * ea.relative_rms,
        100.0 * ea.uncertainty,
        ea.lit_but_black,
        100.0 * eu.relative_rms,
        100.0 * eu.uncertainty,
        eu.lit_but_black
    );
    // One point of these 8 192 is a lit ledge narrower than a texel, black at either density.
    assert!(ea.lit_but_black <= eu.lit_but_black, "{ea:?} / {eu:?}");
    assert!(
        ea.relative_rms < 0.9 * eu.relative_rms,
        "adaptive {:.2}%, uniform {:.2}%",
        100.0 * ea.relative_rms,
        100.0 * eu.relative_rms
    );
}
