//! Edges: the shipped scenes, the edge test scenes and the corpus baked with the defaults,
//! scored against the in-tree path tracer at points sampled densely next to contacts and
//! seams and at points away from both (`lightbake::analysis::edges`: 2048 points of each
//! kind, 1024 interior ones, 4096 paths each), with the seams' jump before and after the
//! stitch and the time of the finishing stages. Each scene is scored twice at the same points:
//! with the finishing stages (denoise, contact fit, stitch) off and with the preset's
//! defaults. Prints the Markdown table of `docs/stability.md`.
//!
//! `cargo bench -p lightbake --bench edges` (add `-- --quick` for the small scenes alone,
//! `-- --corpus` for the house and the office floor alone)

use lightbake::Stage;
use std::path::Path;

use lightbake::analysis::edges::{ClassScore, edge_points, edge_score};
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{
    CornellLight, contact_room, cornell_box, office_level, seam_room, sunlit_room,
};
use lightbake::settings::{BakeSettings, LightConvention, Quality};

fn scene(name: &str) -> Scene {
    match name {
        "Cornell box" => cornell_box(CornellLight::Area),
        "sunlit room" => sunlit_room(),
        "contact room" => contact_room(),
        "seam room" => seam_room(),
        "office floor" => office_level(8, 6),
        _ => {
            let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus/house.gltf");
            lightbake::import_gltf(&path, LightConvention::GltfSpec)
                .expect("the house")
                .scene
        }
    }
}

/// `beyond (bright / dark), RMS` of one class, or a dash without points.
fn cell(c: &ClassScore) -> String {
    if c.points == 0 {
        return "-".into();
    }
    format!(
        "{:.1}% ({:.1} / {:.1}), {:.1}%",
        100.0 * c.beyond(),
        100.0 * c.bright,
        100.0 * c.dark,
        100.0 * c.relative_rms
    )
}

fn run_case(name: &str, quality: Quality) {
    let scene = scene(name);
    let settings = BakeSettings::preset(quality);
    let out = lightbake::bake(&scene, &settings, &Progress::new()).expect("bake");
    let points = edge_points(&scene, &out, 2048, 4096, 7);
    let score = edge_score(&points, &out);
    // The same bake without the finishing stages: the unwrap is the same, so the points
    // (and the path tracer's values at them) carry over.
    let bare = {
        let mut s = settings;
        s.finish.contact_fit = false;
        s.finish.stitch_seams = false;
        s.finish.denoise = false;
        s
    };
    let out_bare = lightbake::bake(&scene, &bare, &Progress::new()).expect("bake");
    let score_bare = edge_score(&points, &out_bare);
    let stage = |n: Stage| {
        out.report
            .stages
            .iter()
            .find(|s| s.run.stage == n)
            .map_or("-".to_string(), |s| format!("{:.2}", s.seconds))
    };
    let jumps = out.report.seams.map_or("-".to_string(), |s| {
        if s.before.seams == 0 {
            "no seams".into()
        } else {
            format!(
                "{:.1}% / {:.0}% → {:.1}% / {:.0}%",
                100.0 * s.before.mean,
                100.0 * s.before.max,
                100.0 * s.after.mean,
                100.0 * s.after.max
            )
        }
    });
    println!(
        "| {name} | {quality:?} | {} | {} → {} | {} → {} | {} → {} | {jumps} | {} / {} / {} | {:.1} |",
        out.report.texels.patches,
        cell(&score_bare.contact),
        cell(&score.contact),
        cell(&score_bare.seam),
        cell(&score.seam),
        cell(&score_bare.interior),
        cell(&score.interior),
        stage(Stage::ContactFit),
        stage(Stage::Stitch),
        stage(Stage::Denoise),
        out.report.total_seconds,
    );
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let corpus_only = std::env::args().any(|a| a == "--corpus");
    println!(
        "| scene | preset | patches | contacts: beyond ±25% (bright / dark), RMS; finishing stages off → on | seams, off → on | away from both, off → on | seam jump mean / max, before → after the stitch | contact fit / stitch / denoise (s) | bake (s) |"
    );
    println!("|---|---|---:|---|---|---|---|---|---:|");
    let mut cases = if corpus_only {
        vec![]
    } else {
        vec![
            ("Cornell box", Quality::Preview),
            ("Cornell box", Quality::Medium),
            ("sunlit room", Quality::Preview),
            ("sunlit room", Quality::Medium),
            ("contact room", Quality::Preview),
            ("contact room", Quality::Medium),
            ("seam room", Quality::Preview),
            ("seam room", Quality::Medium),
        ]
    };
    if !quick {
        cases.extend([
            ("house", Quality::Preview),
            ("house", Quality::Medium),
            ("office floor", Quality::Preview),
        ]);
    }
    for (name, quality) in cases {
        run_case(name, quality);
    }
}
