//! The plan leaves out what a scene does not need and says so; bakes that cannot fit are
//! refused before allocating; a cancelled or failed bake leaves earlier outputs untouched.

mod common;

use std::sync::Arc;

use glam::Vec3;
use lightbake::output::write_outputs;
use lightbake::plan::DirectSource;
use lightbake::progress::Progress;
use lightbake::scene::gltf_import::import_gltf;
use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, LightConvention};
use lightbake::{BakeError, Stage};

#[test]
fn unlit_scene_bakes_black_and_says_why() {
    let mut scene = cornell_box(CornellLight::Point);
    scene.lights.clear();
    let out = common::bake(&scene, &common::settings(64.0, 4));
    assert!(out.report.plan.nothing_to_bake);
    let ran: Vec<Stage> = out.report.stages.iter().map(|s| s.run.stage).collect();
    assert_eq!(
        ran,
        [Stage::Plan, Stage::Unwrap],
        "no raster, BVH or lighting for an unlit scene"
    );
    assert!(
        out.pages
            .iter()
            .all(|p| p.texels.iter().all(|t| *t == Vec3::ZERO))
    );
    assert!(out.report.plan.describe().contains("NOTHING TO BAKE"));
    // Every instance still gets UVs and a rectangle, so the baked glTF is complete.
    assert!(out.layout.instances.iter().all(Option::is_some));
}

#[test]
fn stages_are_skipped_with_reasons() {
    let out = common::bake(&sunlit_room(), &common::settings(6.0, 2));
    let plan = &out.report.plan;
    let stage = |n: Stage| plan.stages.iter().find(|s| s.stage == n).unwrap().clone();
    let source = |n: DirectSource| plan.sources.iter().find(|s| s.source == n).unwrap();
    let area = source(DirectSource::AreaLights);
    assert!(!area.used && area.reason.contains("no emissive"));
    assert!(plan.samples(DirectSource::Sky) && plan.samples(DirectSource::Lights));
    assert!(stage(Stage::Direct).run && plan.describe().contains("shadow rays to: lights, sky"));
    let indirect = stage(Stage::Indirect);
    assert!(!indirect.run && indirect.reason.contains("direct"));
    // The run's radiosity stages are the plan's indirect stage.
    assert!(!plan.runs(Stage::FinalGather) && plan.runs(Stage::Dilate));
    assert!(plan.meshes_to_unwrap > 0);
}

#[test]
fn over_budget_bakes_are_refused_before_allocating() {
    let scene = cornell_box(CornellLight::Area);
    let mut settings = common::settings(50_000.0, 4);
    settings.memory_budget_mib = 4096;
    match lightbake::bake(&scene, &settings, &Progress::new()) {
        Err(BakeError::OverMemoryBudget {
            needed_mib,
            budget_mib,
            breakdown,
        }) => {
            assert!(needed_mib > budget_mib && budget_mib == 4096.0);
            assert!(breakdown.contains("texel patches"), "{breakdown}");
        }
        other => panic!(
            "expected a refusal, got {:?}",
            other.map(|o| o.report.texels)
        ),
    }
}

#[test]
fn cancelled_bake_returns_cancelled_and_writes_nothing() {
    let scene = sunlit_room();
    let settings = common::settings(24.0, 16);
    let progress = Arc::new(Progress::new());
    let p = Arc::clone(&progress);
    let handle = std::thread::spawn(move || lightbake::bake(&scene, &settings, &p));
    while progress.snapshot().stage.map(|s| s.stage) != Some(Stage::Direct) && !handle.is_finished()
    {
        std::thread::yield_now();
    }
    progress.cancel();
    match handle.join().unwrap() {
        Err(BakeError::Cancelled) => {}
        Ok(_) => panic!("the bake finished before it could be cancelled"),
        Err(e) => panic!("unexpected error {e}"),
    }
}

#[test]
fn a_failed_write_leaves_the_previous_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cornell_box.gltf");
    write_scene_gltf(&cornell_box(CornellLight::Point), &path).unwrap();
    let imported = import_gltf(&path, LightConvention::GltfSpec).unwrap();
    let settings = common::settings(48.0, 4);
    let out_dir = dir.path().join("out");
    let first = common::bake(&imported.scene, &settings);
    write_outputs(
        &out_dir,
        &first,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    let before: Vec<(std::path::PathBuf, Vec<u8>)> = [
        "lightmaps/lightmap_0.exr",
        "cornell_box.gltf",
        "manifest.json",
    ]
    .iter()
    .map(|f| (out_dir.join(f), std::fs::read(out_dir.join(f)).unwrap()))
    .collect();
    // A second bake with different settings whose writing fails half way (the report cannot be
    // written because a directory sits where the file would go).
    let mut settings2 = BakeSettings::preview();
    settings2.layout.texel_density = Some(30.0);
    settings2.layout.texel_density_from_scene = false;
    let second = common::bake(&imported.scene, &settings2);
    std::fs::remove_file(out_dir.join("report.json")).unwrap();
    std::fs::create_dir(out_dir.join("report.json")).unwrap();
    assert!(
        write_outputs(
            &out_dir,
            &second,
            &imported.scene,
            Some(&imported.source),
            &settings2
        )
        .is_err()
    );
    for (path, bytes) in before {
        assert_eq!(
            std::fs::read(&path).unwrap(),
            bytes,
            "{} changed",
            path.display()
        );
    }
}
