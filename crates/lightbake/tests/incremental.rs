//! Incremental bakes (`lightbake::incremental`): a bake that follows an earlier bake's cache
//! keeps the layout of every mesh that did not change, recomputes what the edit can change
//! and agrees with a full bake of the edited scene within that bake's estimated error; a
//! cache that cannot be trusted gives a full bake with the reason.

use lightbake::analysis::agreement::{agreement, moved_instances};
use lightbake::analysis::edit_cases::EditCase;
use std::sync::{Arc, Mutex};

use lightbake::incremental::{self, BakeCache, CACHE_FILE, Plan, plan};
use lightbake::lightmap::LightmapPage;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::BakeSettings;
use lightbake::{BakeBuilder, BakeOutput};

fn settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(48.0);
    s.layout.texel_density_from_scene = false;
    s
}

fn bake(scene: &Scene, s: &BakeSettings, following: Plan) -> BakeOutput {
    BakeBuilder::new(scene.clone())
        .settings(s.clone())
        .following(following)
        .run()
        .unwrap()
}

fn bits(pages: &[LightmapPage]) -> Vec<u32> {
    (pages.iter())
        .flat_map(|p| p.texels.iter().flat_map(|t| t.to_array()))
        .map(f32::to_bits)
        .collect()
}

fn first_bake(scene: &Scene, s: &BakeSettings) -> (BakeOutput, BakeCache) {
    let out = bake(scene, s, Plan::Full("the first bake".into()));
    let cache = out.cache.clone().expect("a full bake keeps a cache");
    (out, cache)
}

#[test]
fn an_unchanged_scene_keeps_every_value_and_gives_the_same_bits() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings();
    let (full, cache) = first_bake(&scene, &s);
    let following = plan(Ok(Some(cache)), &scene, &s, false);
    assert!(
        matches!(&following, Plan::Edit(e) if e.0.is_empty()),
        "{}",
        following.describe()
    );
    let again = bake(&scene, &s, following);
    assert_eq!(bits(&again.pages), bits(&full.pages));
    assert_eq!(again.layout.instances, full.layout.instances);
    let inc = again.report.incremental.expect("an incremental report");
    assert_eq!(inc.recomputed, 0.0, "{inc:?}");
}

#[test]
fn edits_agree_with_a_full_bake_of_the_edited_scene_within_its_estimate() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings();
    let (base, cache) = first_bake(&scene, &s);
    for case in [
        EditCase::LampMoved,
        EditCase::MeshMoved,
        EditCase::Albedo,
        EditCase::MeshAdded,
        EditCase::MeshRemoved,
    ] {
        let (edited, what) = case.apply(&scene).expect("the Cornell box has it");
        let following = plan(Ok(Some(cache.clone())), &edited, &s, false);
        assert!(
            matches!(&following, Plan::Edit(e) if !e.0.is_empty()),
            "{what}: {}",
            following.describe()
        );
        let inc = bake(&edited, &s, following);
        let full = bake(&edited, &s, Plan::Full("the reference".into()));
        let report = inc
            .report
            .incremental
            .clone()
            .expect("an incremental report");
        assert!(report.full.is_none(), "{what}: {report:?}");
        assert!(
            report.recomputed < 0.99,
            "{what}: {:.1}% computed again",
            100.0 * report.recomputed
        );
        let estimate = full
            .report
            .error
            .as_ref()
            .expect("an estimate")
            .relative_rms;
        let a = agreement(&edited, &inc, &full, 2048, 7);
        assert!(
            a.relative_rms <= 1.5 * estimate,
            "{what}: incremental against full {:.2}%, the full bake's estimate {:.2}%",
            100.0 * a.relative_rms,
            100.0 * estimate
        );
        let moved = moved_instances((&base, &scene), (&inc, &edited));
        assert!(moved.is_empty(), "{what}: {moved:?} moved in the atlas");
    }
}

#[test]
fn a_moved_mesh_recomputes_direct_light_only_where_it_can_change() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings();
    let (_, cache) = first_bake(&scene, &s);
    let (edited, what) = EditCase::MeshMoved.apply(&scene).unwrap();
    let inc = bake(&edited, &s, plan(Ok(Some(cache)), &edited, &s, false));
    let report = inc.report.incremental.unwrap();
    let direct = (report.stages.iter())
        .find(|st| st.stage.to_string() == "direct")
        .expect("a direct stage");
    assert!(
        direct.computed * 2 < direct.items,
        "{what}: direct light computed again at {} of {} texels",
        direct.computed,
        direct.items
    );
}

#[test]
fn settings_that_decide_the_texels_give_a_full_bake_with_the_reason() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings();
    let (_, cache) = first_bake(&scene, &s);
    let mut denser = s.clone();
    denser.layout.texel_density = Some(64.0);
    let Plan::Full(why) = plan(Ok(Some(cache.clone())), &scene, &denser, false) else {
        panic!("another density followed the cache");
    };
    assert!(why.contains("density") || why.contains("settings"), "{why}");
    let Plan::Full(why) = plan(Ok(Some(cache)), &scene, &s, true) else {
        panic!("--full followed the cache");
    };
    assert!(why.contains("asked"), "{why}");
}

#[test]
fn a_damaged_truncated_or_foreign_cache_gives_a_full_bake_with_a_warning() {
    let scene = cornell_box(CornellLight::Point);
    let s = settings();
    let (_, cache) = first_bake(&scene, &s);
    let bytes = cache.to_bytes();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(CACHE_FILE);
    let read = |b: &[u8]| {
        std::fs::write(&path, b).unwrap();
        incremental::read_cache(dir.path(), 1 << 30)
    };
    assert!(matches!(read(&bytes), Ok(Some(_))));

    let mut flipped = bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x40;
    let mut older = bytes.clone();
    older[8] = older[8].wrapping_sub(1);
    let cases: [(&str, Vec<u8>); 5] = [
        ("a flipped byte", flipped),
        ("truncated", bytes[..bytes.len() / 3].to_vec()),
        ("empty", Vec::new()),
        ("another format", older),
        ("foreign", b"glTF\x02\0\0\0 not a cache at all".to_vec()),
    ];
    for (name, b) in cases {
        let why = read(&b).expect_err(name);
        assert!(
            !why.contains('\n') && why.contains(CACHE_FILE),
            "{name}: {why}"
        );
        let Plan::Full(reason) = plan(Err(why.clone()), &scene, &s, false) else {
            panic!("{name}: followed");
        };
        assert_eq!(reason, why);
    }

    // Larger than the limit: refused before it is read.
    std::fs::write(&path, &bytes).unwrap();
    let why = incremental::read_cache(dir.path(), 64).expect_err("over the limit");
    assert!(!why.contains('\n'), "{why}");

    // Another scene's cache: its instances are not this scene's, so every texel is baked.
    let other = lightbake::scene::testscenes::sunlit_room();
    let following = plan(Ok(Some(cache)), &other, &s, false);
    match following {
        Plan::Full(_) => {}
        Plan::Edit(e) => {
            let out = bake(&other, &s, Plan::Edit(e));
            let inc = out.report.incremental.unwrap();
            assert!(
                inc.full.is_some() || inc.recomputed == 1.0,
                "another scene's values were kept: {inc:?}"
            );
        }
        Plan::Relight(_) => panic!("a bake without light groups was relit"),
    }
}

/// The Cornell box with a point light at the medium preset with the hierarchical solve (its
/// split stages are the direct light and the gathers), baked in full with checkpoints at
/// `interval` within a stage: the settings, the bake and every checkpoint it handed over.
fn bake_with_checkpoints(
    scene: &Scene,
    interval: std::time::Duration,
) -> (BakeSettings, BakeOutput, Vec<BakeCache>) {
    let mut s = BakeSettings::medium();
    s.layout.texel_density = Some(32.0);
    s.layout.texel_density_from_scene = false;
    s.radiosity.solver = lightbake::settings::SolverChoice::Hierarchical;
    let seen: Arc<Mutex<Vec<BakeCache>>> = Arc::default();
    let sink = Arc::clone(&seen);
    let full = BakeBuilder::new(scene.clone())
        .settings(s.clone())
        .following(Plan::Full("the first bake".into()))
        .checkpoints(Arc::new(move |c: &BakeCache| {
            sink.lock().unwrap().push(c.clone())
        }))
        .checkpoint_interval(interval)
        .run()
        .unwrap();
    let seen = seen.lock().unwrap().clone();
    (s, full, seen)
}

#[test]
fn a_bake_resumed_from_a_checkpoint_keeps_the_stages_it_finished_and_gives_the_same_bits() {
    let scene = cornell_box(CornellLight::Point);
    let (s, full, seen) = bake_with_checkpoints(&scene, std::time::Duration::from_secs(2));
    // The checkpoints after whole stages (those within a long stage are the next test's).
    let checkpoints: Vec<BakeCache> = (seen.iter())
        .filter(|c| c.values.stages.last().is_none_or(|k| k.finished.is_empty()))
        .cloned()
        .collect();
    assert!(checkpoints.len() >= 2, "{} checkpoints", checkpoints.len());
    for (k, c) in checkpoints.iter().enumerate() {
        assert_eq!(c.values.stages().count(), k + 1, "checkpoint {k}");
    }
    // Stopped after its first split stage, as the bytes on disk hold it.
    let first = BakeCache::from_bytes(&checkpoints[0].to_bytes()).unwrap();
    let kept: Vec<_> = first
        .values
        .stages()
        .map(|(st, _)| st.to_string())
        .collect();
    let why = incremental::edits(&first, &scene, &s).map(|e| e.lines);
    let resumed_plan = incremental::resume(first, &scene, &s)
        .unwrap_or_else(|| panic!("the same input does not resume: {why:?}"));
    let resumed = bake(&scene, &s, resumed_plan);
    assert_eq!(bits(&resumed.pages), bits(&full.pages));
    let inc = resumed.report.incremental.unwrap();
    let first_stage = &inc.stages[0];
    assert_eq!(
        (first_stage.stage.to_string(), first_stage.computed),
        (kept[0].clone(), 0),
        "{inc:?}"
    );
    assert!(
        inc.stages[1..].iter().all(|st| st.computed == st.items),
        "{inc:?}"
    );

    // Another input does not resume it.
    let (edited, _) = EditCase::LampMoved.apply(&scene).unwrap();
    assert!(incremental::resume(checkpoints[0].clone(), &edited, &s).is_none());
    let mut other = s.clone();
    other.seed += 1;
    assert!(incremental::resume(checkpoints[0].clone(), &scene, &other).is_none());
}

/// The stages a bake ran, by name.
fn stage_names(out: &BakeOutput) -> Vec<String> {
    (out.report.stages.iter())
        .map(|st| st.run.stage.to_string())
        .collect()
}

#[test]
fn a_bake_killed_within_a_stage_resumes_with_the_items_it_finished_and_the_same_bits() {
    let scene = cornell_box(CornellLight::Point);
    let (s, full, seen) = bake_with_checkpoints(&scene, std::time::Duration::ZERO);
    // A checkpoint within the final gather, about half of its nodes done, as on disk.
    let within: Vec<BakeCache> = (seen.iter())
        .filter(|c| {
            c.values
                .stages
                .last()
                .is_some_and(|k| k.stage.to_string() == "final gather" && !k.finished.is_empty())
        })
        .cloned()
        .collect();
    assert!(
        within.len() >= 8,
        "{} checkpoints within the final gather",
        within.len()
    );
    let middle = &within[within.len() / 2];
    let stopped = BakeCache::from_bytes(&middle.to_bytes()).unwrap();
    let last = stopped.values.stages.last().unwrap();
    let share = last.finished_share();
    assert!((0.2..0.8).contains(&share), "{share}");
    let unfinished = last.finished.iter().filter(|&&f| !f).count() as u64;
    let resumed_plan = incremental::resume(stopped, &scene, &s).expect("the same input resumes");
    let resumed = bake(&scene, &s, resumed_plan);
    assert_eq!(bits(&resumed.pages), bits(&full.pages));
    // It kept the patches, every stage before the final gather, and the gather's finished
    // nodes.
    let names = stage_names(&resumed);
    assert!(names.contains(&"patches".to_string()), "{names:?}");
    assert!(!names.contains(&"validity".to_string()), "{names:?}");
    let inc = resumed.report.incremental.unwrap();
    let gather = (inc.stages.iter())
        .position(|st| st.stage.to_string() == "final gather")
        .expect("a final gather");
    assert!(
        inc.stages[..gather].iter().all(|st| st.computed == 0),
        "{inc:?}"
    );
    assert_eq!(inc.stages[gather].computed, unfinished, "{inc:?}");
}

#[test]
fn an_edit_of_the_light_alone_keeps_the_texel_patches_and_the_reflection_where_it_can() {
    let scene = cornell_box(CornellLight::Point);
    let mut s = settings();
    s.radiosity.solver = lightbake::settings::SolverChoice::Hierarchical;
    let (_, cache) = first_bake(&scene, &s);
    let (lit, what) = EditCase::LampColour.apply(&scene).unwrap();
    let inc = bake(&lit, &s, plan(Ok(Some(cache.clone())), &lit, &s, false));
    let names = stage_names(&inc);
    assert!(names.contains(&"patches".to_string()), "{what}: {names:?}");
    assert!(
        !names.contains(&"validity".to_string()),
        "{what}: {names:?}"
    );
    // The reflection of the correction is kept item by item like the gathers.
    let report = inc.report.incremental.clone().unwrap();
    let reflection = (report.stages.iter())
        .find(|st| st.stage.to_string() == "reflection")
        .expect("a reflection stage");
    assert!(
        reflection.computed < reflection.items,
        "{what}: the reflection computed again at {} of {} nodes",
        reflection.computed,
        reflection.items
    );
    // Geometry that moved makes them again.
    let (moved, what) = EditCase::MeshMoved.apply(&scene).unwrap();
    let inc = bake(&moved, &s, plan(Ok(Some(cache.clone())), &moved, &s, false));
    let names = stage_names(&inc);
    assert!(names.contains(&"validity".to_string()), "{what}: {names:?}");
    assert!(!names.contains(&"patches".to_string()), "{what}: {names:?}");
    // A cache whose kept patches were tampered with (their hash no longer matches) makes
    // them again too, rather than reading them.
    let mut tampered = cache.clone();
    // A byte of the middle patch's position (after the 12-byte header, 84 bytes a patch,
    // its instance, page and texel first).
    let count = tampered.values.patch_keys.len();
    let at = 12 + 84 * (count / 2) + 16 + 2;
    tampered.values.patches[at] ^= 0x40;
    let inc = bake(&lit, &s, plan(Ok(Some(tampered)), &lit, &s, false));
    let names = stage_names(&inc);
    assert!(
        names.contains(&"validity".to_string()),
        "tampered: {names:?}"
    );
}

/// The note of `stage` in `out`'s report.
fn note(out: &BakeOutput, stage: &str) -> String {
    (out.report.stages.iter())
        .find(|st| st.run.stage.to_string() == stage)
        .map(|st| st.note.clone())
        .unwrap_or_else(|| panic!("no '{stage}' stage"))
}

#[test]
fn an_edit_of_the_light_keeps_what_reads_only_the_geometry_and_updates_the_coarse_level() {
    let scene = cornell_box(CornellLight::Point);
    let mut s = settings();
    s.radiosity.solver = lightbake::settings::SolverChoice::Hierarchical;
    let (_, cache) = first_bake(&scene, &s);
    let kept = ["nodes", "coarse solve", "contact fit"];
    for stage in kept {
        assert!(
            (cache.values.states.iter()).any(|st| st.stage.to_string() == stage),
            "the cache keeps no '{stage}' state"
        );
    }
    let (moved_lamp, what) = EditCase::LampMoved.apply(&scene).unwrap();
    let inc = bake(
        &moved_lamp,
        &s,
        plan(Ok(Some(cache.clone())), &moved_lamp, &s, false),
    );
    assert!(
        note(&inc, "nodes").contains("basis areas kept"),
        "{what}: {}",
        note(&inc, "nodes")
    );
    // The small box's lamp moved changes the light at most nodes: the coarse level is built
    // again, and says why.
    assert!(
        note(&inc, "coarse solve").contains("not kept: the light changed at"),
        "{what}: {}",
        note(&inc, "coarse solve")
    );
    assert!(
        note(&inc, "contact fit").contains("kept from the earlier bake"),
        "{what}: {}",
        note(&inc, "contact fit")
    );
    // A wall's albedo changes the reflected light at that wall's nodes alone: the coarse
    // level's cut and matrix are kept, its first bounce updated.
    let (tinted, what) = EditCase::Albedo.apply(&scene).unwrap();
    let inc = bake(
        &tinted,
        &s,
        plan(Ok(Some(cache.clone())), &tinted, &s, false),
    );
    assert!(
        note(&inc, "coarse solve").contains("the earlier bake's cut kept"),
        "{what}: {}",
        note(&inc, "coarse solve")
    );
    // A moved mesh makes all three again.
    let (moved, what) = EditCase::MeshMoved.apply(&scene).unwrap();
    let inc = bake(&moved, &s, plan(Ok(Some(cache.clone())), &moved, &s, false));
    assert!(!note(&inc, "nodes").contains("kept"), "{what}");
    assert!(!note(&inc, "coarse solve").contains("kept"), "{what}");
    assert!(!note(&inc, "contact fit").contains("kept"), "{what}");
    // Kept bytes that no longer match their checksum are not taken: the stage runs again.
    let mut tampered = cache.clone();
    for st in &mut tampered.values.states {
        let middle = st.bytes.len() / 2;
        st.bytes[middle] ^= 0x10;
    }
    let inc = bake(&tinted, &s, plan(Ok(Some(tampered)), &tinted, &s, false));
    for stage in kept {
        assert!(
            !note(&inc, stage).contains("kept"),
            "tampered: {}",
            note(&inc, stage)
        );
    }
}
