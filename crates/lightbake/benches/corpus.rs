//! The corpus at every preset: the house (`assets/corpus/house.gltf`), Kenney's FPS and
//! platformer levels (`assets/corpus/kenney_*`), four OpenArena levels
//! (`assets/corpus/openarena/`), assimp's teapots in centimetres and mirrored cubes
//! (`assets/corpus/assimp/`) and the generated office floor, each baked at preview, medium
//! and high with the defaults (automatic texel density, `auto` solver), scored against the
//! in-tree path tracer at 256 open surface points (4096 paths each; `analysis::points`) and by
//! the bake's own check at 1 024 points a viewer can see (`--verify 1024`;
//! `analysis::verify`), with the bake's own estimate, its time and its peak memory. Each case
//! runs in a child process of this binary, so its peak resident memory (`VmHWM`, the check
//! included) is its own. Prints a Markdown table for `docs/benchmarks.md`.
//!
//! `cargo bench -p lightbake --bench corpus` (add `-- --quick` to leave the office floor out)

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use lightbake::analysis::points::{score, score_points};
use lightbake::analysis::verify::verify;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::office_level;
use lightbake::settings::{BakeSettings, LightConvention, Quality};

/// Peak resident set of this process, MiB (0 where the system does not say).
fn peak_rss_mib() -> f64 {
    lightbake::memory::peak_resident_bytes().map_or(0.0, |b| b as f64 / 1048576.0)
}

fn scene(name: &str) -> Scene {
    match name {
        "office" => office_level(8, 6),
        _ => {
            let file = match name {
                "kenney_fps" => "kenney_fps/kenney_fps.gltf",
                "kenney_platformer" => "kenney_platformer/kenney_platformer.gltf",
                "aggressor" => "openarena/aggressor.gltf",
                "q3dm6ish" => "openarena/q3dm6ish.gltf",
                "oa_bases3" => "openarena/oa_bases3.gltf",
                "kaos" => "openarena/kaos.gltf",
                "teapots" => "assimp/teapots.gltf",
                "mirrored_cubes" => "assimp/mirrored_cubes.gltf",
                _ => "house.gltf",
            };
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../assets/corpus")
                .join(file);
            lightbake::import_gltf(&path, LightConvention::GltfSpec)
                .expect("a corpus scene")
                .scene
        }
    }
}

/// One case: `name` at `quality`, one Markdown row.
fn run_case(name: &str, quality: Quality) {
    let scene = scene(name);
    let start = Instant::now();
    let points = score_points(&scene, 256, 4096, 7);
    let reference_seconds = start.elapsed().as_secs_f64();
    let settings = BakeSettings::preset(quality);
    let start = Instant::now();
    let out = lightbake::bake(&scene, &settings, &Progress::new()).expect("bake");
    let seconds = start.elapsed().as_secs_f64();
    let measured = score(&points, &out);
    // The bake's own check (`--verify 1024`): points a viewer can see, with its uncertainty.
    let mut out = out;
    out.report.settings.checks.verify_points = 1024;
    verify(&scene, &mut out);
    let v = out.report.verification.as_ref().expect("a verification");
    let radiosity = out.report.radiosity.as_ref();
    println!(
        "| {name} | {quality:?} | {} | {:.1} | {:.2}% | {:.2}% | {:.2}% | {:.2}% ± {:.2}% | {:.1}% | {} | {} | {:.2} | {:.0} | {:.1} |",
        out.report.texels.patches,
        seconds,
        100.0
            * out
                .report
                .error
                .as_ref()
                .map_or(f64::NAN, |e| e.relative_rms),
        100.0 * measured.relative_rms,
        100.0 * measured.reference_noise,
        100.0 * v.relative_rms,
        100.0 * v.uncertainty,
        100.0 * v.beyond_25,
        v.lit_but_black,
        radiosity.map_or("-", |r| r.solver),
        out.report.floor.as_ref().map_or(f64::NAN, |f| f.ratio),
        peak_rss_mib(),
        reference_seconds,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--case") {
        let quality = match args[i + 2].as_str() {
            "preview" => Quality::Preview,
            "high" => Quality::High,
            _ => Quality::Medium,
        };
        run_case(&args[i + 1], quality);
        return;
    }
    // The generated office floor last: `--quick` leaves it out.
    let all = [
        "house",
        "kenney_fps",
        "kenney_platformer",
        "aggressor",
        "q3dm6ish",
        "oa_bases3",
        "kaos",
        "teapots",
        "mirrored_cubes",
        "office",
    ];
    let quick = args.iter().any(|a| a == "--quick");
    let scenes = &all[..all.len() - usize::from(quick)];
    println!(
        "| scene | preset | patches | bake (s) | estimated error | measured error | reference noise | --verify 1024 | beyond ±25% | lit but black | solver | bake / floor | peak RSS (MiB) | reference (s) |"
    );
    println!("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|");
    let exe = std::env::current_exe().expect("own path");
    for name in scenes {
        for quality in ["preview", "medium", "high"] {
            let status = Command::new(&exe)
                .args(["--case", name, quality])
                .status()
                .expect("run a case");
            if !status.success() {
                println!("| {name} | {quality} | failed: {status} |");
            }
        }
    }
}
