//! A bake over a subset of the texels (`TexelRun`): computed texels are the same function of
//! their texel as in a whole bake, the others keep an earlier run's values, and earlier
//! values that do not fit are refused.

use lightbake::bake::{BakeBuilder, TexelRun};
use lightbake::lightmap::LightmapPage;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::{BakeSettings, SolverChoice};
use lightbake::{BakeError, BakeOutput};

fn settings(density: f32) -> BakeSettings {
    density_at(BakeSettings::preview(), density)
}

fn density_at(mut s: BakeSettings, density: f32) -> BakeSettings {
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    s
}

fn bits(pages: &[LightmapPage]) -> Vec<u32> {
    (pages.iter())
        .flat_map(|p| p.texels.iter().flat_map(|t| t.to_array()))
        .map(f32::to_bits)
        .collect()
}

fn bake_over(scene: &Scene, s: &BakeSettings, run: &TexelRun) -> BakeOutput {
    BakeBuilder::new(scene.clone())
        .settings(s.clone())
        .run_texels(run)
        .unwrap()
}

/// Rays of the stages the subset splits (direct light, final gather, correction).
fn split_rays(out: &BakeOutput) -> u64 {
    (out.report.stages.iter())
        .filter(|s| {
            let name = s.run.to_string();
            ["direct", "final gather", "correction"]
                .iter()
                .any(|n| name.starts_with(n))
        })
        .map(|s| s.rays)
        .sum()
}

#[test]
fn a_subset_over_kept_values_of_the_same_input_gives_the_whole_bakes_bits() {
    let scene = cornell_box(CornellLight::Point);
    // The medium preset with the hierarchical solve: its split stages are the direct light,
    // the final gather and the correction.
    let mut s = density_at(BakeSettings::default(), 32.0);
    s.radiosity.solver = SolverChoice::Hierarchical;
    let whole = lightbake::bake(&scene, &s, &Progress::new()).unwrap();
    let all = TexelRun::all();
    let kept = bake_over(&scene, &s, &all);
    assert_eq!(
        bits(&kept.pages),
        bits(&whole.pages),
        "a run over every texel"
    );
    let values = all.values();
    let stages: Vec<_> = values.stages().collect();
    for name in ["direct", "final gather", "correction"] {
        assert!(
            stages.iter().any(|(stage, _)| stage.to_string() == name),
            "{name} not among the kept stages {stages:?}"
        );
    }
    let [computed, items] = all.computed();
    assert_eq!(computed, items);

    let half = TexelRun::only(values.clone(), |_, x, _| x % 2 == 0);
    let out = bake_over(&scene, &s, &half);
    assert_eq!(bits(&out.pages), bits(&whole.pages), "half the texels");
    let [computed, items] = half.computed();
    let share = computed as f64 / items as f64;
    assert!(
        (0.35..0.65).contains(&share),
        "computed {computed} of {items}"
    );
    let (ours, theirs) = (split_rays(&out), split_rays(&whole));
    assert!(
        (ours as f64) < 0.75 * theirs as f64,
        "split stages' rays {ours} against the whole bake's {theirs}"
    );
    assert_eq!(half.values(), values, "the values kept for a next run");
}

/// The final gather through the irradiance cache: each node's value reads only the records
/// of the cells around it, so a subset run (and a split bake's shard) gets the whole bits.
#[test]
fn a_subset_with_the_irradiance_cache_gives_the_whole_bakes_bits() {
    let scene = cornell_box(CornellLight::Point);
    let mut s = density_at(BakeSettings::default(), 32.0);
    s.radiosity.solver = SolverChoice::Hierarchical;
    s.radiosity.cache_spacing = 4;
    let whole = lightbake::bake(&scene, &s, &Progress::new()).unwrap();
    let all = TexelRun::all();
    assert_eq!(bits(&bake_over(&scene, &s, &all).pages), bits(&whole.pages));
    let third = TexelRun::only(all.values(), |_, x, y| (x + 2 * y) % 3 == 0);
    let out = bake_over(&scene, &s, &third);
    assert_eq!(
        bits(&out.pages),
        bits(&whole.pages),
        "a third of the texels"
    );
    let [computed, items] = third.computed();
    assert!(computed < items, "computed {computed} of {items}");
}

#[test]
fn texels_outside_the_subset_keep_the_earlier_runs_light() {
    let s = settings(64.0);
    let dim = cornell_box(CornellLight::Point);
    let mut bright = dim.clone();
    for l in &mut bright.lights {
        l.intensity *= 2.0;
    }
    let earlier = TexelRun::all();
    bake_over(&dim, &s, &earlier);
    let bright_whole = lightbake::bake(&bright, &s, &Progress::new()).unwrap();

    // Every texel computed: the earlier values are not read.
    let every = TexelRun::only(earlier.values(), |_, _, _| true);
    let out = bake_over(&bright, &s, &every);
    assert_eq!(bits(&out.pages), bits(&bright_whole.pages));

    // No texel computed: the split stages' values are the dim light's.
    let none = TexelRun::only(earlier.values(), |_, _, _| false);
    let out = bake_over(&bright, &s, &none);
    assert_eq!(none.computed()[0], 0);
    let sum = |pages: &[LightmapPage]| -> f64 {
        (pages.iter())
            .flat_map(|p| p.texels.iter())
            .map(|t| f64::from(t.x + t.y + t.z))
            .sum()
    };
    let (kept, rebaked) = (sum(&out.pages), sum(&bright_whole.pages));
    assert!(
        kept < 0.8 * rebaked,
        "kept direct light {kept} against the brighter bake's {rebaked}"
    );
}

#[test]
fn values_kept_for_other_patches_or_settings_are_refused() {
    let scene = cornell_box(CornellLight::Point);
    let earlier = TexelRun::all();
    bake_over(&scene, &settings(64.0), &earlier);

    let other_density = TexelRun::only(earlier.values(), |_, x, _| x < 8);
    let err = BakeBuilder::new(scene.clone())
        .settings(settings(48.0))
        .run_texels(&other_density)
        .unwrap_err();
    assert!(
        matches!(&err, BakeError::Subset { message } if message.contains("other texel patches")),
        "{err}"
    );

    let mut more_samples = settings(64.0);
    more_samples.direct.samples_per_texel *= 2;
    let other_settings = TexelRun::only(earlier.values(), |_, x, _| x < 8);
    let err = BakeBuilder::new(scene.clone())
        .settings(more_samples)
        .run_texels(&other_settings)
        .unwrap_err();
    assert!(
        matches!(&err, BakeError::Subset { message } if message.contains("other settings")),
        "{err}"
    );

    let mut target = settings(64.0);
    target.target_error = Some(0.05);
    let with_target = TexelRun::only(earlier.values(), |_, x, _| x < 8);
    let err = BakeBuilder::new(scene)
        .settings(target)
        .run_texels(&with_target)
        .unwrap_err();
    assert!(
        matches!(&err, BakeError::BadSetting { name, .. } if *name == "target_error"),
        "{err}"
    );
}
