//! A bake with light groups relit from its cache (`lightbake::incremental::relight`): an
//! edit of only its lights' colour or intensity (or the sky's) is the weighted sum of the
//! cached groups' pages, bit for bit; it agrees with a full bake of the edited scene within
//! that bake's estimate; every other edit is baked in full with the reason.

use std::path::Path;

use glam::Vec3;
use lightbake::analysis::agreement::agreement;
use lightbake::incremental::{BakeCache, Plan, plan};
use lightbake::lightmap::LightmapPage;
use lightbake::scene::Scene;
use lightbake::settings::{BakeSettings, LightGroup};
use lightbake::stage::Stage;
use lightbake::{BakeBuilder, BakeOutput, LightConvention};

/// The shipped sunlit room: a sun (group `day`) and a sky (the implicit `ungrouped`).
fn sunlit_room() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/sunlit_room.gltf");
    lightbake::import_gltf(&path, LightConvention::GltfSpec)
        .expect("the shipped sunlit room")
        .scene
}

fn settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(24.0);
    s.layout.texel_density_from_scene = false;
    s.groups = vec![LightGroup {
        name: "day".into(),
        members: vec!["sun".into()],
    }];
    s
}

fn bake(scene: &Scene, s: &BakeSettings, following: Plan) -> BakeOutput {
    BakeBuilder::new(scene.clone())
        .settings(s.clone())
        .following(following)
        .run()
        .unwrap_or_else(|e| panic!("{e}"))
}

fn bits(pages: &[LightmapPage]) -> Vec<u32> {
    (pages.iter())
        .flat_map(|p| p.texels.iter().flat_map(|t| t.to_array()))
        .map(f32::to_bits)
        .collect()
}

/// `pages` with every texel multiplied by `w`.
fn weighted(pages: &[LightmapPage], w: Vec3) -> Vec<LightmapPage> {
    (pages.iter())
        .map(|p| LightmapPage {
            texels: p.texels.iter().map(|&t| t * w).collect(),
            ..p.clone()
        })
        .collect()
}

fn first_bake(scene: &Scene, s: &BakeSettings) -> (BakeOutput, BakeCache) {
    let out = bake(scene, s, Plan::Full("the first bake".into()));
    let cache = out.cache.clone().expect("a bake with groups keeps a cache");
    assert_eq!(cache.groups.groups.len(), 2, "day and ungrouped");
    let read = BakeCache::from_bytes(&cache.to_bytes()).expect("the cache reads back");
    assert_eq!(read, cache, "the groups' pages survive the file");
    (out, cache)
}

#[test]
fn a_change_of_colour_or_intensity_is_the_weighted_sum_of_the_cached_groups() {
    let scene = sunlit_room();
    let s = settings();
    let (base, cache) = first_bake(&scene, &s);
    let mut edited = scene.clone();
    let sun = edited.lights.iter_mut().find(|l| l.name == "sun").unwrap();
    sun.intensity *= 0.5;
    sun.color *= Vec3::new(1.0, 0.9, 0.7);
    edited.sky *= 1.5;
    let following = plan(Ok(Some(cache.clone())), &edited, &s, false);
    let Plan::Relight(r) = &following else {
        panic!("not relit: {}", following.describe());
    };
    assert_eq!(r.weights.len(), 2);
    for (w, want) in r
        .weights
        .iter()
        .zip([Vec3::new(0.5, 0.45, 0.35), Vec3::splat(1.5)])
    {
        assert!((*w - want).abs().max_element() < 1e-5, "{w} against {want}");
    }
    assert!(
        following.describe().contains("relit"),
        "{}",
        following.describe()
    );
    let weights = r.weights.clone();
    let relit = bake(&edited, &s, following);
    // Bit for bit the weighted groups, and their sum the bake's pages.
    for ((g, before), w) in relit.groups.iter().zip(&base.groups).zip(&weights) {
        assert_eq!(
            bits(&g.pages),
            bits(&weighted(&before.pages, *w)),
            "{}",
            g.name
        );
    }
    let mut sum = weighted(&base.groups[0].pages, weights[0]);
    for (a, b) in sum
        .iter_mut()
        .zip(weighted(&base.groups[1].pages, weights[1]))
    {
        for (x, y) in a.texels.iter_mut().zip(&b.texels) {
            *x += *y;
        }
    }
    assert_eq!(bits(&relit.pages), bits(&sum));
    assert_eq!(relit.layout.instances, base.layout.instances);
    let stages: Vec<Stage> = relit.report.stages.iter().map(|s| s.run.stage).collect();
    assert_eq!(stages, [Stage::Relight], "nothing lit");
    assert_eq!(
        relit.cache.as_ref(),
        Some(&cache),
        "the cache stays the basis"
    );
    // Against a full bake of the edited scene (other rays where its adaptive gather follows
    // the other light) within that bake's estimated error.
    let full = bake(&edited, &s, Plan::Full("the reference".into()));
    let estimate = full
        .report
        .error
        .as_ref()
        .expect("an estimate")
        .relative_rms;
    let a = agreement(&edited, &relit, &full, 2048, 7);
    assert!(
        a.relative_rms <= 1.5 * estimate,
        "relit against full {:.2}%, the full bake's estimate {:.2}%",
        100.0 * a.relative_rms,
        100.0 * estimate
    );
    // The relit bake's own estimate: the groups' estimates scaled with their light.
    let own = relit
        .report
        .error
        .as_ref()
        .expect("an estimate")
        .relative_rms;
    assert!(
        (own / estimate - 1.0).abs() < 0.5,
        "relit estimate {own}, full {estimate}"
    );
}

#[test]
fn a_light_turned_off_and_on_again_gives_the_first_bake_back() {
    let scene = sunlit_room();
    let s = settings();
    let (base, cache) = first_bake(&scene, &s);
    let mut off = scene.clone();
    off.lights.iter_mut().for_each(|l| l.intensity = 0.0);
    let following = plan(Ok(Some(cache.clone())), &off, &s, false);
    assert!(
        matches!(following, Plan::Relight(_)),
        "{}",
        following.describe()
    );
    let dark = bake(&off, &s, following);
    assert!(
        dark.groups[0]
            .pages
            .iter()
            .all(|p| p.texels.iter().all(|t| *t == Vec3::ZERO))
    );
    let cache = dark.cache.expect("kept");
    let following = plan(Ok(Some(cache)), &scene, &s, false);
    let Plan::Relight(r) = &following else {
        panic!("not relit: {}", following.describe());
    };
    assert_eq!(r.weights, [Vec3::ONE, Vec3::ONE]);
    let again = bake(&scene, &s, following);
    assert_eq!(bits(&again.pages), bits(&base.pages));
}

#[test]
fn every_other_edit_of_a_bake_with_groups_is_full_with_the_reason() {
    let scene = sunlit_room();
    let s = settings();
    let (_, cache) = first_bake(&scene, &s);
    let mut turned = scene.clone();
    let sun = turned.lights.iter_mut().find(|l| l.name == "sun").unwrap();
    sun.direction = (sun.direction + Vec3::new(0.1, 0.0, 0.0)).normalize();
    let Plan::Full(why) = plan(Ok(Some(cache.clone())), &turned, &s, false) else {
        panic!("a turned sun was relit");
    };
    assert!(
        why.contains("colour and intensity") && why.contains("'sun'"),
        "{why}"
    );
    let mut painted = scene.clone();
    painted.materials[0].base_color *= 0.5;
    let Plan::Full(why) = plan(Ok(Some(cache.clone())), &painted, &s, false) else {
        panic!("an albedo edit was relit");
    };
    assert!(why.contains("albedo"), "{why}");
    // A group whose member starts to emit in a channel the group was lit without.
    let mut blue = scene.clone();
    let sun = blue.lights.iter_mut().find(|l| l.name == "sun").unwrap();
    let was = sun.color;
    sun.color = Vec3::new(was.x, was.y, 0.0);
    let dimmed = bake(&blue, &s, Plan::Full("a sun without blue".into()));
    let mut back = blue.clone();
    back.lights
        .iter_mut()
        .find(|l| l.name == "sun")
        .unwrap()
        .color = was;
    let Plan::Full(why) = plan(
        dimmed.cache.clone().map(Some).ok_or(String::new()),
        &back,
        &s,
        false,
    ) else {
        panic!("a channel lit from nothing was relit");
    };
    assert!(why.contains("channel"), "{why}");
    // Other groups than the cached bake's.
    let mut other = s.clone();
    other.groups[0].name = "sunlight".into();
    let Plan::Full(why) = plan(Ok(Some(cache)), &scene, &other, false) else {
        panic!("other groups were relit");
    };
    assert!(why.contains("settings"), "{why}");
}
