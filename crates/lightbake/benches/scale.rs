//! How bake time and memory grow with the texels and the triangles.
//!
//! * **Texels.** The Cornell box and the generated office floor of the corpus
//!   (`testscenes::office_level(8, 6)`: 336 846 triangles, 939 instances) at the medium preset
//!   with texel budgets of 256 k, 1 M, 4 M and 16 M texels (`--quick`: 256 k and 1 M), so the
//!   density follows the budget; the solver is `auto` (the hierarchical solve at these sizes).
//! * **Triangles.** The Cornell box with every quad split n × n (about 10 k … 1 M triangles)
//!   at a fixed density with its own lightmap UVs (no xatlas, which would dominate at a
//!   million triangles and is measured in its own bench), at the preview preset.
//!
//! Each case runs in a child process of this binary, so its peak resident memory (`VmHWM`) is
//! its own; "planned" is the memory the bake's plan admitted it with (the estimate after the
//! unwrap plus the solver's), and bytes per patch are the peak over the covered texels. Prints
//! Markdown tables for `docs/benchmarks.md`.
//!
//! `cargo bench -p lightbake --bench scale` (add `-- --quick` for the smaller half)

use lightbake::Stage;
use std::process::Command;
use std::time::Instant;

use glam::Vec2;
use lightbake::BakeOutput;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, office_level, subdivide_quads};
use lightbake::settings::BakeSettings;

/// The Cornell box with every quad split `n` × `n` and its own lightmap UVs: quad k of a mesh
/// gets cell k of a grid over [0, 1]², inset so charts do not touch.
fn dense_with_uv1(n: u32) -> Scene {
    let mut s = cornell_box(CornellLight::Area);
    for m in &mut s.meshes {
        let quads = m.indices.len() / 6;
        let cells = (quads as f32).sqrt().ceil() as usize;
        let mut uv = vec![Vec2::ZERO; m.positions.len()];
        for (k, q) in m.indices.chunks_exact(6).enumerate() {
            let (cx, cy) = ((k % cells) as f32, (k / cells) as f32);
            let size = 1.0 / cells as f32;
            let (lo, hi) = (0.05 * size, 0.95 * size);
            let corner = |a: f32, b: f32| Vec2::new(cx * size + a, cy * size + b);
            // quad() emits (0,1,2),(0,2,3).
            uv[q[0] as usize] = corner(lo, lo);
            uv[q[1] as usize] = corner(hi, lo);
            uv[q[2] as usize] = corner(hi, hi);
            uv[q[5] as usize] = corner(lo, hi);
        }
        m.uv0 = Some(uv);
        let mut d = subdivide_quads(m, n);
        d.uv1 = d.uv0.clone();
        *m = d;
    }
    s.name = format!("cornell_dense{n}");
    s
}

/// Peak resident set of this process, MiB (0 where the system does not say).
fn peak_rss_mib() -> f64 {
    lightbake::memory::peak_resident_bytes().map_or(0.0, |b| b as f64 / 1048576.0)
}

/// Seconds of the stages `stages` (every round).
fn stage(out: &BakeOutput, stages: &[Stage]) -> f64 {
    out.report
        .stages
        .iter()
        .filter(|st| stages.contains(&st.run.stage))
        .map(|st| st.seconds)
        .sum()
}

/// The memory the bake was admitted with, MiB: its estimate after the unwrap and the
/// solver's.
fn planned_mib(out: &BakeOutput) -> f64 {
    out.report.memory.mib()
        + out.report.radiosity.as_ref().map_or(0.0, |r| {
            (r.transport_estimate_bytes + r.solver_working_bytes) as f64 / 1048576.0
        })
}

/// One texel-budget case: `scene` ("cornell" or "office") at the medium preset.
fn texel_case(scene: &str, budget: f64) {
    let scene = match scene {
        "office" => office_level(8, 6),
        _ => cornell_box(CornellLight::Area),
    };
    let mut s = BakeSettings::medium();
    s.layout.texel_budget = budget as u64;
    s.layout.texel_density_from_scene = false;
    s.formats.png_preview = false;
    // A 16 M-texel bake plans about 6 GiB; the budget is this machine's, not the default.
    s.memory_budget_mib = 20_000;
    let start = Instant::now();
    let out = lightbake::bake(&scene, &s, &Progress::new()).expect("bake");
    let seconds = start.elapsed().as_secs_f64();
    let floor = out.report.floor.clone().unwrap_or_default();
    let gather_ratio = floor
        .stages
        .iter()
        .find(|(n, _)| n.stage == Stage::FinalGather)
        .map_or(f64::NAN, |s| s.1);
    let patches = out.report.texels.patches;
    let rss = peak_rss_mib();
    println!(
        "| {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.2} | {:.0} | {:.0} | {:.0} |",
        scene.name,
        budget,
        scene.instanced_triangle_count(),
        patches,
        seconds,
        stage(
            &out,
            &[
                Stage::Unwrap,
                Stage::Raster,
                Stage::Validity,
                Stage::Bvh,
                Stage::Nodes
            ]
        ),
        stage(&out, &[Stage::Direct]),
        stage(&out, &[Stage::CoarseSolve, Stage::Transport, Stage::Solve]),
        stage(
            &out,
            &[Stage::GatherPilot, Stage::FinalGather, Stage::Correction]
        ),
        stage(
            &out,
            &[Stage::ErrorEstimate, Stage::Calibrate, Stage::Dilate]
        ),
        floor.ratio,
        gather_ratio,
        planned_mib(&out),
        rss,
        rss * 1048576.0 / patches as f64,
    );
}

/// One triangle-count case: the Cornell box split `n` × `n` at the preview preset.
fn triangle_case(n: f64) {
    let scene = dense_with_uv1(n as u32);
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(96.0);
    s.layout.texel_density_from_scene = false;
    s.formats.png_preview = false;
    let start = Instant::now();
    let out = lightbake::bake(&scene, &s, &Progress::new()).expect("bake");
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "| split {n} × {n} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} | {:.0} | {:.0} |",
        scene.instanced_triangle_count(),
        out.report.texels.patches,
        seconds,
        stage(&out, &[Stage::Bvh]),
        stage(&out, &[Stage::Direct]),
        stage(
            &out,
            &[
                Stage::CoarseSolve,
                Stage::Transport,
                Stage::Solve,
                Stage::GatherPilot,
                Stage::FinalGather,
                Stage::Correction
            ]
        ),
        out.report.floor.as_ref().map_or(f64::NAN, |f| f.ratio),
        planned_mib(&out),
        peak_rss_mib(),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--case") {
        let value: f64 = args[i + 2].parse().expect("case value");
        match args[i + 1].as_str() {
            "triangles" => triangle_case(value),
            scene => texel_case(scene, value),
        }
        return;
    }
    let quick = args.iter().any(|a| a == "--quick");
    let budgets: &[f64] = if quick {
        &[262_144.0, 1_048_576.0]
    } else {
        &[262_144.0, 1_048_576.0, 4_194_304.0, 16_777_216.0]
    };
    let splits: &[f64] = if quick {
        &[18.0, 56.0]
    } else {
        &[18.0, 56.0, 125.0, 177.0]
    };
    let exe = std::env::current_exe().expect("own path");
    let run = |kind: &str, v: f64| {
        let status = Command::new(&exe)
            .args(["--case", kind, &v.to_string()])
            .status()
            .expect("run a case");
        if !status.success() {
            println!("| {kind} {v} | failed: {status} |");
        }
    };
    println!(
        "| scene | texel budget | triangles | patches | bake (s) | unwrap, raster, validity, BVH, nodes (s) | direct (s) | coarse solve (s) | final gather + correction (s) | estimate, calibrate, dilate (s) | bake / floor | final gather / its floor | planned (MiB) | peak RSS (MiB) | bytes per patch |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for scene in ["cornell", "office"] {
        for &b in budgets {
            // The office at 16 M texels takes most of an hour; the Cornell box shows the scale.
            if scene == "office" && b > 5e6 {
                continue;
            }
            run(scene, b);
        }
    }
    println!();
    println!(
        "| case | triangles | patches | bake (s) | BVH (s) | direct (s) | radiosity (s) | bake / floor | planned (MiB) | peak RSS (MiB) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for &n in splits {
        run("triangles", n);
    }
}
