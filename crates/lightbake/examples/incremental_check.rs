//! Incremental bakes measured on a scene: it is baked in full (keeping its cache), then each
//! edit of `lightbake::analysis::edit_cases` is baked twice — following the cache, and in
//! full — and the two are compared at surface points (`lightbake::analysis::agreement`).
//!
//! ```text
//! cargo run --release -p lightbake --features internals,testscenes --example incremental_check -- SCENE.gltf [--quality preview|medium|high] [--points N] [--only EDIT] [--verify N [--verify-paths P]]
//! cargo run --release -p lightbake --features internals,testscenes --example incremental_check -- SCENE.gltf --checkpoint-overhead RUNS
//! ```
//!
//! `--group-each-light` bakes each light into a light group of its own (at most 15), and
//! `--group-light NAME` the lights of that name into one (the other emitters in `ungrouped`),
//! so that an edit of their colour or intensity is relit from the cached groups
//! (`lightbake::incremental::relight`).
//!
//! Prints a Markdown table: per edit, the full bake's and the incremental bake's seconds and
//! their ratio, the split stages' items computed again, the RMS difference of the two bakes
//! at the points (relative to the RMS value) against the full bake's own estimate, and
//! whether every unchanged instance kept its `uv_rect` and its mesh its `TEXCOORD_1`.

use std::time::Instant;

use lightbake::analysis::agreement::{agreement, moved_instances};
use lightbake::analysis::edit_cases::EditCase;
use lightbake::incremental::{BakeCache, Plan, plan};
use lightbake::settings::LightGroup;
use lightbake::settings::groups::MAX_GROUPS;
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
    let mut settings = BakeSettings::preset(quality);
    // `--verify N [--verify-paths P]`: both bakes of each edit checked against the path
    // tracer at N points (as `bake --verify N`).
    let verify: Option<u32> = arg("--verify").map(|v| v.parse().expect("--verify N"));
    let verify_paths: u32 =
        arg("--verify-paths").map_or(1024, |p| p.parse().expect("--verify-paths P"));
    let scene = lightbake::import_gltf(path.as_ref(), LightConvention::GltfSpec)
        .unwrap_or_else(|e| panic!("{e}"))
        .scene;
    if std::env::args().any(|a| a == "--group-each-light") {
        // Each light in a light group of its own (the sky and emissive surfaces in the
        // implicit `ungrouped`): an edit of a light's colour or intensity is relit.
        settings.groups = each_light_grouped(&scene);
    }
    if let Some(light) = arg("--group-light") {
        // That light in a group of its own, every other emitter in `ungrouped`.
        settings.groups = vec![LightGroup {
            name: "tuned".into(),
            members: vec![light],
        }];
    }
    if let Some(runs) = arg("--checkpoint-overhead") {
        checkpoint_overhead(
            &scene,
            &settings,
            runs.parse().expect("--checkpoint-overhead N"),
        );
        return;
    }
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
        if std::env::var("INCREMENTAL_CHECK_STAGES").is_ok_and(|v| v == "1") {
            eprint!("{}", following.describe());
        }
        let (mut inc, inc_seconds) = bake(&edited, &settings, following);
        let (mut full, full_seconds) = bake(&edited, &settings, Plan::Full("the reference".into()));
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
        if let Some(points) = verify {
            // Both bakes checked against the path tracer at the same points.
            let mut line = Vec::new();
            for (name, out) in [("incremental", &mut inc), ("full", &mut full)] {
                out.report.settings.checks.verify_points = points;
                out.report.settings.checks.verify_paths = verify_paths;
                lightbake::analysis::verify::verify(&edited, out);
                if let Some(v) = &out.report.verification {
                    line.push(format!(
                        "{name} {:.2}% ± {:.2}%",
                        100.0 * v.relative_rms,
                        100.0 * v.uncertainty
                    ));
                }
            }
            println!(
                "|   `--verify {points}` ({verify_paths} paths) | {} | | | | | | | |",
                line.join(", ")
            );
        }
        if std::env::var("INCREMENTAL_CHECK_STAGES").is_ok_and(|v| v == "1") {
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

/// One light group per light name (at most `MAX_GROUPS`), named after it.
fn each_light_grouped(scene: &Scene) -> Vec<LightGroup> {
    let mut groups: Vec<LightGroup> = Vec::new();
    for l in &scene.lights {
        let name: String = (l.name.chars())
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .take(64)
            .collect();
        if groups.len() < MAX_GROUPS && !groups.iter().any(|g| g.members[0] == l.name) {
            groups.push(LightGroup {
                name: format!("{name}_{}", groups.len()),
                members: vec![l.name.clone()],
            });
        }
    }
    groups
}

/// What checkpoints cost a full bake: `runs` pairs of bakes, alternating without and with
/// checkpoints written to a file (as `bake` writes `OUT/lightbake.partial`); prints each pair,
/// the checkpoints written and the seconds spent writing them, and the medians.
fn checkpoint_overhead(scene: &Scene, settings: &BakeSettings, runs: usize) {
    use std::sync::{Arc, Mutex};
    let dir = std::env::temp_dir().join("incremental_check_partial");
    let (mut without, mut with) = (Vec::new(), Vec::new());
    let stages = std::env::var("INCREMENTAL_CHECK_STAGES").is_ok_and(|v| v == "1");
    // `--checkpoint-interval S`: seconds between two checkpoints within a split stage.
    let interval = arg("--checkpoint-interval").map_or(std::time::Duration::from_secs(2), |s| {
        std::time::Duration::from_secs_f64(s.parse().expect("--checkpoint-interval S"))
    });
    for _ in 0..runs {
        let (plain, seconds) = bake(scene, settings, Plan::Full("plain".into()));
        without.push(seconds);
        // (checkpoints written, seconds spent writing them)
        let written = Arc::new(Mutex::new((0usize, 0.0f64)));
        let seen = Arc::clone(&written);
        let target = dir.clone();
        let start = Instant::now();
        let out = BakeBuilder::new(scene.clone())
            .settings(settings.clone())
            .following(Plan::Full("with checkpoints".into()))
            .checkpoint_interval(interval)
            .checkpoints(Arc::new(move |c: &BakeCache| {
                let t = Instant::now();
                lightbake::incremental::write_partial(&target, c).expect("the partial file");
                let mut w = seen.lock().expect("the count");
                w.0 += 1;
                w.1 += t.elapsed().as_secs_f64();
            }))
            .run()
            .unwrap_or_else(|e| panic!("{e}"));
        with.push(start.elapsed().as_secs_f64());
        let (count, writing) = *written.lock().expect("the count");
        println!(
            "without {:.2} s, with {:.2} s ({count} checkpoints, {writing:.2} s writing them)",
            without.last().unwrap(),
            with.last().unwrap(),
        );
        if stages {
            eprintln!("{}\n{}", plain.report.table(), out.report.table());
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b) = (median(&mut without), median(&mut with));
    println!(
        "medians: without {a:.2} s, with {b:.2} s, ratio {:.3}",
        b / a
    );
    let _ = std::fs::remove_dir_all(&dir);
}
