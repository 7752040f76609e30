//! Incremental bakes measured on a scene: it is baked in full (keeping its cache), then each
//! edit of `lightbake::analysis::edit_cases` is baked twice — following the cache, and in
//! full — and the two are compared at surface points (`lightbake::analysis::agreement`).
//!
//! ```text
//! cargo run --release -p lightbake --features internals,testscenes --example incremental_check -- SCENE.gltf [--quality preview|medium|high] [--points N] [--only EDIT]
//! ```
//!
//! Prints a Markdown table: per edit, the full bake's and the incremental bake's seconds and
//! their ratio, the split stages' items computed again, the RMS difference of the two bakes
//! at the points (relative to the RMS value) against the full bake's own estimate, and
//! whether every unchanged instance kept its `uv_rect` and its mesh its `TEXCOORD_1`.

use std::time::Instant;

use lightbake::analysis::agreement::{agreement, moved_instances};
use lightbake::analysis::edit_cases::EditCase;
use lightbake::incremental::{BakeCache, Plan, plan};
use lightbake::{BakeBuilder, BakeOutput, BakeSettings, LightConvention, Quality, Scene};

fn arg(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    let i = args.iter().position(|a| a == name)?;
    args.get(i + 1).cloned()
}

fn bake(scene: &Scene, settings: &BakeSettings, following: Plan) -> (BakeOutput, f64) {
    let start = Instant::now();
    let out = BakeBuilder::new(scene.clone())
        .settings(settings.clone())
        .following(following)
        .run()
        .unwrap_or_else(|e| panic!("{e}"));
    (out, start.elapsed().as_secs_f64())
}

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!(
            "usage: incremental_check SCENE.gltf [--quality preview|medium|high] [--points N]"
        );
        std::process::exit(2);
    };
    let quality = match arg("--quality").as_deref() {
        Some("preview") => Quality::Preview,
        Some("high") => Quality::High,
        _ => Quality::Medium,
    };
    let points: usize = arg("--points").map_or(4096, |p| p.parse().expect("--points N"));
    let settings = BakeSettings::preset(quality);
    let scene = lightbake::import_gltf(path.as_ref(), LightConvention::GltfSpec)
        .unwrap_or_else(|e| panic!("{e}"))
        .scene;
    let (base, base_seconds) = bake(&scene, &settings, Plan::Full("the first bake".into()));
    let cache: BakeCache = base.cache.clone().expect("a cache");
    println!(
        "{path} at {quality:?}: full bake {base_seconds:.2} s, estimated error {:.2}%",
        100.0 * base.report.error.as_ref().map_or(0.0, |e| e.relative_rms)
    );
    println!();
    println!(
        "| edit | full s | incremental s | ratio | items again | difference | full's estimate | difference / estimate | layout kept |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---|");
    let only = arg("--only");
    for case in EditCase::ALL {
        if only.as_deref().is_some_and(|o| o != case.name()) {
            continue;
        }
        let Some((edited, what)) = case.apply(&scene) else {
            println!(
                "| {} | – | – | – | – | – | – | – | nothing to edit |",
                case.name()
            );
            continue;
        };
        let following = plan(Ok(Some(cache.clone())), &edited, &settings, false);
        let (inc, inc_seconds) = bake(&edited, &settings, following);
        let (full, full_seconds) = bake(&edited, &settings, Plan::Full("the reference".into()));
        let a = agreement(&edited, &inc, &full, points, 7);
        let estimate = full.report.error.as_ref().map_or(0.0, |e| e.relative_rms);
        let again = inc
            .report
            .incremental
            .as_ref()
            .map_or(1.0, |r| r.recomputed);
        let full_reason = inc.report.incremental.as_ref().and_then(|r| r.full.clone());
        let moved = moved_instances((&base, &scene), (&inc, &edited));
        println!(
            "| {} ({what}){} | {full_seconds:.2} | {inc_seconds:.2} | {:.0}% | {:.1}% | {:.2}% | {:.2}% | {:.2} | {} |",
            case.name(),
            full_reason.map_or_else(String::new, |r| format!(" — full: {r}")),
            100.0 * inc_seconds / full_seconds,
            100.0 * again,
            100.0 * a.relative_rms,
            100.0 * estimate,
            a.relative_rms / estimate.max(1e-12),
            if moved.is_empty() { "yes" } else { "no" }
        );
        if std::env::var_os("INCREMENTAL_CHECK_STAGES").is_some() {
            for s in inc.report.incremental.iter().flat_map(|r| &r.stages) {
                eprintln!("    {}: {} of {}", s.stage, s.computed, s.items);
            }
            eprintln!("{}", inc.report.table());
            for m in &moved {
                eprintln!("    moved in the atlas: {m}");
            }
        }
    }
}
