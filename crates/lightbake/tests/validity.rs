//! Texels whose centre is inside or behind geometry: where part of the footprint is open
//! surface, the texel is lit from that part; only texels no view can see stay unlit. Checked
//! on the real house of the corpus and the sunlit room with a visibility test of the test's
//! own.

mod common;

use std::path::Path;

use glam::Vec2;
use lightbake::analysis::reference::irradiance;
use lightbake::color::luminance;
use lightbake::context::Prepared;
use lightbake::lights::Emitters;
use lightbake::progress::Progress;
use lightbake::raster::{Patch, Surface, SurfacePoint};
use lightbake::sampling::{cosine_hemisphere, hash_words, sobol_02, unit_float};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::sunlit_room;
use lightbake::settings::{BakeSettings, LightConvention};

/// The architectural house of the corpus (`assets/corpus`).
fn house() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus/house.gltf");
    lightbake::import_gltf(&path, LightConvention::GltfSpec)
        .unwrap()
        .scene
}

/// Points of `p`'s footprint seen from a room, by this test's own check (not the baker's):
/// of 16 random points of the texel square that lie on the surface, those from which at most an
/// eighth of 32 cosine-distributed rays meet the back of a single-sided surface (a point
/// inside a solid meets backs in every direction, a point in a room none) and nothing lies
/// within a texel straight above (a point pressed under a rug or a slab is not seen).
fn visible_points(prep: &Prepared, surface: &Surface<'_>, p: &Patch) -> Vec<SurfacePoint> {
    let Some(rect) = prep.layout.instances[p.instance as usize] else {
        return Vec::new();
    };
    let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
    let footprint = prep.patches.footprint_of(p);
    let key = hash_words(&[p.key, 0x7e57]);
    (0..16u32)
        .filter_map(|s| {
            let u = Vec2::new(
                unit_float(hash_words(&[key, s, 1])),
                unit_float(hash_words(&[key, s, 2])),
            );
            footprint
                .iter()
                .find_map(|&t| surface.point(t, texel + u, 0.0))
        })
        .filter(|sp| {
            let origin = prep.rays.offset(sp.position, sp.geometric_normal);
            let above = prep
                .rays
                .closest_hit(origin, sp.geometric_normal, 0.0, p.texel_size);
            if above.is_some() {
                return false;
            }
            let backs = (0..32u32)
                .filter(|&k| {
                    let dir = cosine_hemisphere(sp.geometric_normal, sobol_02(k, key));
                    prep.rays
                        .closest_hit(origin, dir, 0.0, f32::INFINITY)
                        .is_some_and(|h| {
                            !h.front_face && !prep.rays.triangles[h.triangle as usize].double_sided
                        })
                })
                .count();
            backs <= 4
        })
        .collect()
}

#[test]
fn no_texel_that_can_be_seen_is_left_unlit_in_the_house_and_the_sunlit_room() {
    for (scene, least_partly_hidden, least_seen) in [(house(), 500, 100), (sunlit_room(), 0, 0)] {
        let prep = Prepared::new(&scene, &BakeSettings::medium()).unwrap();
        let patches = &prep.patches;
        let surface = Surface::new(&prep.scene, &prep.layout, &prep.rays);
        let hidden: Vec<&Patch> = patches.patches.iter().filter(|p| !p.is_valid()).collect();
        let partly: Vec<&Patch> = patches
            .patches
            .iter()
            .filter(|p| p.flags & Patch::PARTLY_HIDDEN != 0)
            .collect();
        // Hidden texels this test sees into: two or more of 16 points visible.
        let seen: Vec<(u32, u32, usize)> = hidden
            .iter()
            .map(|p| (p.x, p.y, visible_points(&prep, &surface, p).len()))
            .filter(|h| h.2 >= 2)
            .collect();
        // The texels lit from the visible part of their footprint: this test sees into them
        // too, so were they left hidden, the check above would find them.
        let partly_seen = partly
            .iter()
            .filter(|p| !visible_points(&prep, &surface, p).is_empty())
            .count();
        println!(
            "{}: {} patches, {} hidden ({} of them seen into), {} lit from part of their footprint ({} seen into), the bake's own count of visible but unlit: {}",
            scene.name,
            patches.patches.len(),
            hidden.len(),
            seen.len(),
            partly.len(),
            partly_seen,
            patches.visible_unlit
        );
        assert_eq!(patches.visible_unlit, 0, "{}", scene.name);
        assert!(
            seen.is_empty(),
            "{}: hidden texels with visible points (x, y, points): {:?}",
            scene.name,
            &seen[..seen.len().min(20)]
        );
        assert!(
            partly.len() >= least_partly_hidden,
            "{}: {} texels lit from part of their footprint",
            scene.name,
            partly.len()
        );
        assert!(
            partly_seen >= least_seen,
            "{}: {partly_seen} of {} partly hidden texels seen into",
            scene.name,
            partly.len()
        );
    }
}

#[test]
fn texels_lit_from_the_visible_part_of_their_footprint_get_the_light_there() {
    // The house's texels whose centre is hidden against the path tracer at the points of
    // their footprint this test sees into: the light they hold is the light of their visible
    // part (were they filled from their neighbours or left black, the sums would differ).
    let scene = house();
    let settings = BakeSettings::preview();
    let prep = Prepared::new(&scene, &settings).unwrap();
    let out = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    let surface = Surface::new(&prep.scene, &prep.layout, &prep.rays);
    let ctx = prep.ctx();
    let emitters = Emitters::collect(&prep.scene, &prep.rays);
    let (mut baked, mut traced, mut texels) = (0.0f64, 0.0f64, 0);
    for p in prep
        .patches
        .patches
        .iter()
        .filter(|p| p.flags & Patch::PARTLY_HIDDEN != 0)
    {
        let points = visible_points(&prep, &surface, p);
        if points.is_empty() {
            continue;
        }
        let e: f64 = points
            .iter()
            .enumerate()
            .map(|(k, sp)| {
                let r = irradiance(&ctx, &emitters, sp, 64, hash_words(&[p.key, k as u32, 9]));
                luminance(r.direct + r.indirect) as f64
            })
            .sum::<f64>()
            / points.len() as f64;
        let v = out.pages[p.page as usize].get(p.x, p.y);
        assert!(v.is_finite() && v.min_element() >= 0.0, "{v}");
        baked += luminance(v) as f64 * std::f64::consts::PI;
        traced += e;
        texels += 1;
    }
    let ratio = baked / traced;
    println!(
        "{texels} partly hidden texels: baked {baked:.0} lux in all, path traced {traced:.0}, ratio {ratio:.3}"
    );
    assert!(texels > 100, "{texels}");
    assert!(
        (0.75..1.33).contains(&ratio),
        "baked / path traced = {ratio:.3}"
    );
}

/// The validity pass skips a texel's short probes when every triangle within their reach
/// lies in the texel's plane; on real scenes (flat floors, curved teapots, a mirrored
/// instance, centimetre units) the probes it skips would have found nothing.
#[test]
fn texels_in_an_open_plane_skip_only_probes_that_find_nothing() {
    let mut scenes = vec![("house", house()), ("sunlit room", sunlit_room())];
    for file in [
        "assimp/teapots.gltf",
        "assimp/mirrored_cubes.gltf",
        "openarena/kaos.gltf",
    ] {
        scenes.push((file, common::corpus_scene(file)));
    }
    for (name, scene) in scenes {
        let settings = BakeSettings::preview();
        let prep = Prepared::new(&scene, &settings).unwrap();
        let raw = lightbake::raster::Patches::build(&prep.scene, &prep.layout, &prep.rays);
        let [nothing, passed, contradicted] =
            raw.open_plane_check(&prep.scene, &prep.layout, &prep.rays);
        println!(
            "{name}: {passed} of {} texels skip their probes; the probes find nothing at {nothing}",
            raw.patches.len()
        );
        assert_eq!(
            contradicted, 0,
            "{name}: probes skipped that would have hit"
        );
        assert!(
            passed as f64 > 0.9 * nothing as f64,
            "{name}: only {passed} of the {nothing} texels that could skip"
        );
    }
}

/// Most hidden texels skip the search of their footprint: their centre's fan sees back faces
/// in at least three quarters of its directions, their footprint lies on its side of every
/// surface and nearer than any face it saw. Traced anyway, the search finds an open point in
/// almost none of them, and in those only a point that its own fan's noise lets through
/// (the bake's second search and the check above, with more rays, see none of them).
#[test]
fn hidden_texels_that_skip_the_search_are_those_the_search_finds_hidden() {
    let mut scenes = vec![("house", house()), ("sunlit room", sunlit_room())];
    for file in ["openarena/oa_bases3.gltf", "openarena/kaos.gltf"] {
        scenes.push((file, common::corpus_scene(file)));
    }
    for (name, scene) in scenes {
        let prep = Prepared::new(&scene, &BakeSettings::preview()).unwrap();
        let patches = &prep.patches;
        let [sealed, open] = patches.sealed_check(&prep.scene, &prep.layout, &prep.rays);
        println!(
            "{name}: {} hidden, {sealed} without a search (the bake's count: {}), {open} of them with an open point",
            patches.invalid, patches.sealed
        );
        assert_eq!(sealed, patches.sealed, "{name}");
        assert!(
            sealed * 4 > patches.invalid,
            "{name}: {sealed} of {}",
            patches.invalid
        );
        assert!(open * 500 <= sealed, "{name}: {open} of {sealed}");
        assert_eq!(patches.visible_unlit, 0, "{name}");
    }
}
