//! How bake time and memory grow with the atlas size and the triangle count: the Cornell box
//! baked with radiosity at the preview preset's sample counts (direct 4 spp, 32 form-factor
//! rays per node), (a) at texel densities that give atlases of about 64² … 2048² texels and
//! (b) with every quad split so the scene has about 10k … 1M triangles at a fixed density.
//! Each case runs in a child process of this binary so that its peak resident memory
//! (`VmHWM`) is its own. Prints a Markdown table for `docs/benchmarks.md`.
//!
//! `cargo bench -p lightbake --bench scale` (add `-- --quick` for the smaller half)

use std::process::Command;
use std::time::Instant;

use glam::Vec2;
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, subdivide_quads};
use lightbake::settings::BakeSettings;

/// The Cornell box with every quad split `n` × `n` and its own lightmap UVs: quad k of a mesh
/// gets cell k of a grid over [0, 1]², inset so charts do not touch (no xatlas, which would
/// dominate at a million triangles and is measured in its own bench).
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

fn settings(density: f32) -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.texel_density = Some(density);
    s.texel_density_from_scene = false;
    s.formats.png_preview = false;
    s
}

/// Peak resident set of this process, MiB.
fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(0.0, |kib| kib / 1024.0)
}

/// Runs one case and prints one Markdown row.
fn run_case(kind: &str, value: f64) {
    let (scene, density) = match kind {
        "texels" => (cornell_box(CornellLight::Area), value as f32),
        _ => (dense_with_uv1(value as u32), 96.0),
    };
    let s = settings(density);
    let start = Instant::now();
    let out = lightbake::bake(&scene, &s, &Progress::new()).expect("bake");
    let seconds = start.elapsed().as_secs_f64();
    let stage = |name: &str| {
        out.report
            .stages
            .iter()
            .filter(|st| st.name == name)
            .map(|st| st.seconds)
            .sum::<f64>()
    };
    println!(
        "| {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {:.2} | {:.1} | {:.0} | {:.0} |",
        if kind == "texels" {
            format!("{density} texels/m")
        } else {
            format!("split {value}")
        },
        scene.instanced_triangle_count(),
        out.report.texels.page_texels,
        out.report.texels.patches,
        seconds,
        stage("unwrap") + stage("raster") + stage("validity"),
        stage("bvh"),
        stage("transport"),
        stage("solve"),
        out.report.total_rays(),
        out.report.floor.as_ref().map_or(f64::NAN, |f| f.seconds),
        out.report.floor.as_ref().map_or(f64::NAN, |f| f.ratio),
        out.report.memory.mib()
            + out.report.radiosity.as_ref().map_or(0.0, |i| {
                (i.transport_estimate_bytes + i.solver_working_bytes) as f64 / 1048576.0
            }),
        peak_rss_mib(),
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(i) = args.iter().position(|a| a == "--case") {
        run_case(&args[i + 1], args[i + 2].parse().expect("case value"));
        return;
    }
    let quick = args.iter().any(|a| a == "--quick");
    // The Cornell box's atlas at 256 texels/m is about 362²; density ∝ side.
    let texels: &[f64] = if quick {
        &[45.0, 90.0, 180.0]
    } else {
        &[45.0, 90.0, 180.0, 360.0, 720.0, 1440.0]
    };
    let splits: &[f64] = if quick {
        &[18.0, 56.0]
    } else {
        &[18.0, 56.0, 125.0, 177.0]
    };
    println!(
        "| case | triangles | atlas texels | patches | bake (s) | unwrap+raster+validity (s) | BVH (s) | transport (s) | solve (s) | rays | ray floor (s) | bake / floor | planned (MiB) | peak RSS (MiB) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    let exe = std::env::current_exe().expect("own path");
    for (kind, values) in [("texels", texels), ("triangles", splits)] {
        for &v in values {
            let status = Command::new(&exe)
                .args(["--case", kind, &v.to_string()])
                .status()
                .expect("run a case");
            if !status.success() {
                println!("| {kind} {v} | failed: {status} |");
            }
        }
    }
}
