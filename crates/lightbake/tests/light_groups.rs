//! Light groups: each group's pages are, bit for bit, the bake of its emitters alone on the
//! shared layout; the bake's pages are their sum and agree with a bake without groups within
//! the noise; the glTF extras name groups; bad groups are refused naming the member.

mod common;

use std::path::Path;

use glam::Vec3;
use lightbake::color::luminance;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::settings::{BakeSettings, LightGroup};
use lightbake::{BakeOutput, LightConvention};

/// The shipped sunlit room (a sun and a sky), as the importer reads it.
fn sunlit_room() -> lightbake::ImportedScene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/sunlit_room.gltf");
    lightbake::import_gltf(&path, LightConvention::GltfSpec).expect("the shipped sunlit room")
}

/// Preview settings with the density fixed (the density that follows the light would
/// differ between a scene and the same scene with fewer lights) and no grid check.
fn settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.adaptive_density = false;
    s.checks.grid_error_points = 0;
    s
}

fn group(name: &str, members: &[&str]) -> LightGroup {
    LightGroup {
        name: name.into(),
        members: members.iter().map(|m| m.to_string()).collect(),
    }
}

fn bake(scene: &Scene, settings: &BakeSettings) -> BakeOutput {
    lightbake::bake(scene, settings, &Progress::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// Mean luminance of every texel of `pages`.
fn mean(pages: &[lightbake::LightmapPage]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in pages {
        for t in &p.texels {
            sum += f64::from(luminance(*t));
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// The sunlit room with only the sun, and with only the sky.
fn sun_and_sky_alone(scene: &Scene) -> [Scene; 2] {
    let mut sun_only = scene.clone();
    sun_only.sky = Vec3::ZERO;
    let mut sky_only = scene.clone();
    sky_only.lights.clear();
    [sun_only, sky_only]
}

#[test]
fn each_group_is_its_emitters_alone_and_the_pages_are_their_sum() {
    let scene = sunlit_room().scene;
    // Every node's gather takes the settings' rays, and the coarse level keeps its first cut:
    // with the rays not shared out by the whole light's noise and the cells not split by it,
    // a group's shared coarse level and gathers trace exactly the rays of its own bake.
    let mut plain = settings();
    plain.radiosity.adaptive_gather = false;
    plain.radiosity.cluster_tolerance = 0.99;
    let mut s = plain.clone();
    s.groups = vec![group("day", &["sun"])];
    let grouped = bake(&scene, &s);
    let names: Vec<&str> = grouped.groups.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        names,
        ["day", "ungrouped"],
        "the sky goes to the implicit group"
    );
    assert_eq!(grouped.groups[0].report.members, ["light sun"]);
    assert_eq!(grouped.groups[1].report.members, ["sky"]);
    assert_eq!(grouped.report.groups.len(), 2);
    assert!(grouped.report.groups.iter().all(|g| g.rays > 0));
    // The transport was shared: one set of nodes, one coarse level and one final gather for
    // both groups.
    let shared: Vec<&str> = (grouped.report.stages.iter())
        .filter(|st| st.note.starts_with("[shared]"))
        .map(|st| st.run.stage.name())
        .collect();
    println!("shared stages: {shared:?}");
    for stage in [
        "nodes",
        "coarse solve",
        "final gather",
        "correction",
        "reflection",
    ] {
        assert_eq!(
            shared.iter().filter(|&&n| n == stage).count(),
            1,
            "{stage}: {shared:?}"
        );
    }

    // Each group against a bake of the scene with only its emitters: the same bits.
    for (g, alone) in grouped.groups.iter().zip(sun_and_sky_alone(&scene)) {
        let reference = bake(&alone, &plain);
        assert_eq!(g.pages.len(), reference.pages.len());
        for (a, b) in g.pages.iter().zip(&reference.pages) {
            assert!(
                a.texels == b.texels,
                "group {}: its pages differ from the bake of its emitters alone",
                g.name
            );
        }
    }

    // The bake's pages are the groups' sum, texel by texel.
    for (i, page) in grouped.pages.iter().enumerate() {
        for (k, t) in page.texels.iter().enumerate() {
            let sum: Vec3 = grouped.groups.iter().map(|g| g.pages[i].texels[k]).sum();
            assert_eq!(*t, sum, "page {i} texel {k}");
        }
    }

    // Against one bake of every light: the same light within the noise.
    let whole = bake(&scene, &plain);
    assert_eq!(
        grouped.report.texels, whole.report.texels,
        "the same texels filled and dilated"
    );
    let (m_grouped, m_whole) = (mean(&grouped.pages), mean(&whole.pages));
    let relative = (m_grouped - m_whole).abs() / m_whole;
    let estimate = grouped.report.error.as_ref().expect("an estimate");
    println!(
        "sum of the groups: mean E/π {m_grouped:.3} against {m_whole:.3} in one bake ({:.3}%); the sum's estimated error {:.2}% RMS",
        100.0 * relative,
        100.0 * estimate.relative_rms
    );
    assert!(relative < 0.01, "{relative}");
    assert!(estimate.relative_rms > 0.0 && estimate.relative_rms < 0.2);
}

#[test]
fn with_rays_shared_out_by_the_whole_light_each_group_is_its_bake_within_the_noise() {
    // The default gather: each node's rays follow the noise of the groups' summed light, so a
    // group's rays are not its own bake's, and the two agree within their noise.
    let scene = sunlit_room().scene;
    let mut s = settings();
    s.groups = vec![group("day", &["sun"])];
    let grouped = bake(&scene, &s);
    let mut other = settings();
    other.seed = 1;
    for ((g, alone), r) in (grouped.groups.iter())
        .zip(sun_and_sky_alone(&scene))
        .zip(&grouped.report.groups)
    {
        let reference = bake(&alone, &other);
        let (mut diff_sq, mut ref_sq, mut diff_sum, mut ref_sum) = (0.0, 0.0, 0.0, 0.0);
        for (a, b) in g.pages.iter().zip(&reference.pages) {
            for (x, y) in a.texels.iter().zip(&b.texels) {
                let (x, y) = (f64::from(luminance(*x)), f64::from(luminance(*y)));
                diff_sq += (x - y) * (x - y);
                ref_sq += y * y;
                diff_sum += x - y;
                ref_sum += y;
            }
        }
        let measured = (diff_sq / ref_sq).sqrt();
        let bias = diff_sum / ref_sum;
        let (e_group, e_ref) = (
            r.error.as_ref().unwrap().relative_rms,
            reference.report.error.as_ref().unwrap().relative_rms,
        );
        let expected = e_group.hypot(e_ref);
        println!(
            "group {}: against a bake of its emitters alone (another seed) {:.2}% RMS (the two bakes' noise: {:.2}%), mean {:+.3}%",
            g.name,
            100.0 * measured,
            100.0 * expected,
            100.0 * bias
        );
        assert!(bias.abs() < 0.01, "{}: {bias}", g.name);
        assert!(
            measured < 1.5 * expected,
            "{}: {measured} against {expected}",
            g.name
        );
    }
}

#[test]
fn bad_groups_are_refused_naming_the_member() {
    let scene = sunlit_room().scene;
    let refused = |groups: Vec<LightGroup>| {
        let mut s = settings();
        s.groups = groups;
        lightbake::bake(&scene, &s, &Progress::new())
            .expect_err("refused")
            .to_string()
    };
    let e = refused(vec![group("night", &["lamp"])]);
    assert!(e.contains("lamp") && e.contains("its lights: sun"), "{e}");
    let e = refused(vec![group("a", &["sun"]), group("b", &["light:sun"])]);
    assert!(e.contains("'a' and 'b'"), "{e}");
    let e = refused(vec![group("a", &["sky"]), group("b", &["sky"])]);
    assert!(e.contains("'a' and 'b'"), "{e}");
    let e = refused(vec![group("a", &["material:sun"])]);
    assert!(e.contains("no emissive material named 'sun'"), "{e}");
    let mut dark = scene.clone();
    dark.sky = Vec3::ZERO;
    let mut s = settings();
    s.groups = vec![group("outside", &["sky"])];
    let e = lightbake::bake(&dark, &s, &Progress::new())
        .expect_err("no sky")
        .to_string();
    assert!(e.contains("outside=sky") && e.contains("no sky"), "{e}");
    let e = refused(vec![group("ungrouped", &["sun"])]);
    assert!(e.contains("pick another name"), "{e}");
}

#[test]
fn the_gltf_extras_name_groups() {
    let imported = sunlit_room();
    let dir = tempfile::tempdir().unwrap();
    let mut json = imported.source.json.clone();
    json["extensions"]["KHR_lights_punctual"]["lights"][0]["extras"]["lightbake"]["group"] =
        "day".into();
    json["scenes"][0]["extras"]["lightbake"]["sky_group"] = "outside".into();
    std::fs::write(
        dir.path().join("room.gltf"),
        serde_json::to_vec(&json).unwrap(),
    )
    .unwrap();
    let bin = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/sunlit_room.bin");
    std::fs::copy(bin, dir.path().join("sunlit_room.bin")).unwrap();
    let again =
        lightbake::import_gltf(&dir.path().join("room.gltf"), LightConvention::GltfSpec).unwrap();
    assert_eq!(
        again.light_groups,
        [group("outside", &["sky"]), group("day", &["light:sun"])]
    );
    assert!(imported.light_groups.is_empty());
}

#[test]
fn a_weighted_sum_is_a_bake_at_those_intensities() {
    let scene = sunlit_room().scene;
    let mut s = settings();
    s.groups = vec![group("sun", &["sun"])];
    let grouped = bake(&scene, &s);
    let (w_sun, w_sky) = (0.5f32, 2.0f32);
    let mut scaled = scene.clone();
    scaled.lights[0].intensity *= w_sun;
    scaled.sky *= w_sky;
    // Another seed: noise independent of the groups' (with the same seed the two bakes
    // trace the same samples and would agree far inside their noise).
    let mut other = settings();
    other.seed = 1;
    let reference = bake(&scaled, &other);
    let (mut diff_sq, mut ref_sq, mut diff_sum, mut ref_sum, mut n) = (0.0, 0.0, 0.0, 0.0, 0);
    for (i, page) in reference.pages.iter().enumerate() {
        for (k, t) in page.texels.iter().enumerate() {
            let sum = w_sun * grouped.groups[0].pages[i].texels[k]
                + w_sky * grouped.groups[1].pages[i].texels[k];
            let (a, b) = (f64::from(luminance(sum)), f64::from(luminance(*t)));
            diff_sq += (a - b) * (a - b);
            ref_sq += b * b;
            diff_sum += a - b;
            ref_sum += b;
            n += 1;
        }
    }
    let measured = (diff_sq / ref_sq).sqrt();
    let bias = diff_sum / ref_sum;
    // Both sides' noise: the reference's estimate, and the groups' absolute errors scaled by
    // their weights, relative to the same RMS texel.
    let e_ref = reference.report.error.as_ref().unwrap();
    let groups: Vec<&lightbake::error_estimate::ErrorEstimate> = grouped
        .report
        .groups
        .iter()
        .map(|g| g.error.as_ref().unwrap())
        .collect();
    let e_sum = ((f64::from(w_sun) * groups[0].rms).powi(2)
        + (f64::from(w_sky) * groups[1].rms).powi(2))
    .sqrt()
        / e_ref.value_rms;
    let expected = (e_ref.relative_rms.powi(2) + e_sum.powi(2)).sqrt();
    println!(
        "0.5 × sun + 2 × sky against a bake at those intensities over {n} texels: {:.2}% RMS (the two bakes' noise: {:.2}%), mean {:+.3}%",
        100.0 * measured,
        100.0 * expected,
        100.0 * bias
    );
    assert!(bias.abs() < 0.01, "{bias}");
    assert!(measured < 1.5 * expected, "{measured} against {expected}");
}

#[test]
fn groups_whose_shared_solve_is_over_the_budget_each_run_their_own() {
    // The sunlit room at preview: one hierarchical solve holds 38 MiB, two groups' shared
    // one over 100 MiB; at 64 MiB each group's radiosity runs on its own, said in a warning.
    let scene = sunlit_room().scene;
    let mut plain = settings();
    plain.radiosity.transport_budget_mib = 64;
    let mut s = plain.clone();
    s.groups = vec![group("day", &["sun"])];
    let grouped = bake(&scene, &s);
    let warning = (grouped.report.warnings.iter())
        .find(|w| w.contains("shared radiosity would hold"))
        .unwrap_or_else(|| panic!("no warning: {:?}", grouped.report.warnings));
    println!("{warning}");
    assert!(warning.contains("over the solvers' 64 MiB"), "{warning}");
    let shared: Vec<&str> = (grouped.report.stages.iter())
        .filter(|st| st.note.starts_with("[shared]"))
        .map(|st| st.run.stage.name())
        .collect();
    assert_eq!(shared, ["nodes"], "only the nodes are shared");
    // Each group's own radiosity, the rays shared out by its own noise: its own bake's bits.
    for (g, alone) in grouped.groups.iter().zip(sun_and_sky_alone(&scene)) {
        let reference = bake(&alone, &plain);
        for (a, b) in g.pages.iter().zip(&reference.pages) {
            assert!(a.texels == b.texels, "group {}", g.name);
        }
    }
}
