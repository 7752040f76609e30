//! Texels pressed under a cover thinner than a texel with part of their footprint in the open
//! (`raster/covered.rs`), on the Kenney platformer of the corpus, whose blocks rest on one
//! another with double-sided faces pressed together: the underside of a brick lies on two
//! half-blocks except in a 5 cm groove between them, narrower than a texel. Lit only from the
//! covered part, a texel across the groove held no light and a viewer looking up into the
//! groove saw black; lit from its open part it holds the groove's light.

mod common;

use lightbake::analysis::verify::verify;
use lightbake::context::Prepared;
use lightbake::raster::Patch;
use lightbake::{BakeSettings, Progress};

#[test]
fn covered_texels_with_an_open_rim_are_lit_from_it_on_the_kenney_platformer() {
    let scene = common::corpus_scene("kenney_platformer/kenney_platformer.gltf");
    let mut settings = BakeSettings::preview();
    settings.layout.adaptive_density = false;
    let prep = Prepared::new(&scene, &settings).unwrap();
    let patches = &prep.patches;
    let covered = patches
        .patches
        .iter()
        .filter(|p| p.flags & Patch::COVERED != 0)
        .count();
    println!(
        "{} patches: {} lit from the open part of their footprint, {} covered",
        patches.patches.len(),
        patches.rescued,
        covered
    );
    // Every material is double-sided, so no texel is inside a solid by the back-face test:
    // the moved texels are all covered ones with an open rim.
    assert!(patches.rescued > 100, "{}", patches.rescued);
    assert_eq!(patches.moved, patches.rescued);
    // No point the path tracer finds lit is black in the bake (the groove under a brick
    // was, at 1 of these 4 096 points).
    settings.checks.verify_points = 4096;
    settings.checks.verify_paths = 4096;
    let mut out = lightbake::bake(&scene, &settings, &Progress::new()).unwrap();
    verify(&scene, &mut out);
    let v = out.report.verification.clone().unwrap();
    println!("{}", v.summary());
    assert_eq!(v.lit_but_black, 0, "{v:?}");
    assert!(v.relative_rms < 0.1, "{v:?}");
}
