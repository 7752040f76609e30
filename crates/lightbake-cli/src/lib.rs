//! `bake`: bake lightmaps for a glTF scene. The binary is `src/main.rs`; the command itself
//! lives here so that other crates' tests can run exactly what users run ([`run_from`]).
//!
//! ```text
//! bake assets/cornell_box.gltf -o baked/cornell_box
//! bake scene.glb -o out --quality high --format exr,ktx2
//! ```
//!
//! Exit status: 0 on success, 1 when the bake fails (the cause on one line on stderr),
//! 2 for a bad command line.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

use clap::{Parser, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use lightbake::plan::BakePlan;
use lightbake::progress::Progress;
use lightbake::sampling::Sequence;
use lightbake::scene::gltf_import::import_gltf;
use lightbake::settings::{BakeSettings, LightConvention, Method, Quality};
use lightbake::solve::SolverChoice;
use lightbake::transport::Basis;

mod plot;

#[derive(Clone, Copy, Debug, ValueEnum)]
enum QualityArg {
    Preview,
    Medium,
    High,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum FormatArg {
    Exr,
    Hdr,
    Ktx2,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum MethodArg {
    /// Direct light only.
    Direct,
    /// Direct light plus interreflection by radiosity over the texels.
    Radiosity,
    /// Instant radiosity: all light from virtual point lights.
    Vpl,
    /// Direct light exact, indirect light from virtual point lights.
    Hybrid,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SequenceArg {
    Halton,
    ScrambledHalton,
    Jittered,
    Random,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SolverArg {
    /// Chosen from the scene (stated in the plan).
    Auto,
    Jacobi,
    GaussSeidel,
    /// Progressive refinement (Southwell shooting).
    Shooting,
    /// Matrix-free, for scenes whose transport matrix does not fit.
    StochasticJacobi,
    /// BiCGStab, for stiff scenes (albedo near 1).
    Krylov,
    /// Conjugate gradients on the reciprocity-symmetrised system.
    KrylovCg,
    /// Dense LU (small scenes).
    Direct,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum BasisArg {
    /// Bilinear between texel centres (what the GPU shows).
    Linear,
    /// Constant per texel.
    Constant,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ConventionArg {
    /// The glTF specification: linear light colours, no range = infinite.
    Gltf,
    /// What Bevy 0.19's glTF loader does: sRGB light colours, no range = 20 m.
    Bevy,
}

/// Bake lightmaps for a glTF scene: xatlas unwrap, texel patches, shadow-ray direct light;
/// HDR lightmaps, a baked glTF (with TEXCOORD_1), manifest.json and report.json out.
#[derive(Debug, Parser)]
#[command(name = "bake", version)]
struct Args {
    /// The scene: a .gltf or .glb file.
    scene: PathBuf,
    /// Output directory (created if needed; files in it are replaced atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// Preset for density and samples; the options below override it.
    #[arg(long, value_enum, default_value = "medium")]
    quality: QualityArg,
    /// How light is computed.
    #[arg(long, value_enum, default_value = "radiosity")]
    method: MethodArg,
    /// Radiosity solver.
    #[arg(long, value_enum, default_value = "auto")]
    solver: SolverArg,
    /// Radiosity basis over the texel grid.
    #[arg(long, value_enum, default_value = "linear")]
    basis: BasisArg,
    /// Form-factor rays per texel (radiosity).
    #[arg(long)]
    transport_rays: Option<u32>,
    /// Largest transport matrix plus the solver's vectors beside it, MiB (above it `auto` goes
    /// matrix-free); what the memory budget leaves beside the rest of the bake also bounds it.
    #[arg(long)]
    transport_budget: Option<u64>,
    /// Target relative error of the radiosity solve.
    #[arg(long)]
    tolerance: Option<f64>,
    /// Instant radiosity: particles started from the lights.
    #[arg(long)]
    vpl_particles: Option<u32>,
    /// Instant radiosity: choose the particle count to fit this many seconds of gathering.
    #[arg(long)]
    vpl_time_budget: Option<f64>,
    /// Instant radiosity: number pattern of the walks.
    #[arg(long, value_enum, default_value = "scrambled-halton")]
    vpl_sequence: SequenceArg,
    /// Instant radiosity: clamp distance in metres (default 2% of the scene's diagonal).
    #[arg(long)]
    vpl_clamp: Option<f32>,
    /// Instant radiosity: restore the clamped energy (Kollig & Keller bias compensation).
    #[arg(long)]
    bias_compensation: bool,
    /// Lightmap texels per metre (overrides the preset and the scene's own hint).
    #[arg(long)]
    texel_density: Option<f32>,
    /// Samples per texel for direct light (footprint points × one sample per light).
    #[arg(long)]
    samples: Option<u32>,
    /// Sky rays per texel.
    #[arg(long)]
    sky_samples: Option<u32>,
    /// Empty texels between charts.
    #[arg(long)]
    padding: Option<u32>,
    /// Largest atlas page, texels per side.
    #[arg(long)]
    max_page_size: Option<u32>,
    /// HDR formats to write, comma separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "exr")]
    format: Vec<FormatArg>,
    /// Do not write the tonemapped PNG previews.
    #[arg(long)]
    no_preview: bool,
    /// Unwrap every mesh with xatlas, even those with their own TEXCOORD_1.
    #[arg(long)]
    reunwrap: bool,
    /// Worker threads (0 = every core). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Seed of the sample sequences.
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Uniform sky luminance R,G,B in nits (overrides the scene's).
    #[arg(long, value_delimiter = ',', num_args = 3)]
    sky: Option<Vec<f32>>,
    /// Refuse bakes estimated to need more memory than this (MiB); the transport matrix is
    /// planned within what the rest of the bake leaves of it.
    #[arg(long)]
    memory_budget: Option<u64>,
    /// Target relative RMS error (0.02 = 2%): sample counts become a pilot, and each sampling
    /// stage raises them until its own error estimate reaches its share of the target.
    #[arg(long)]
    target_error: Option<f32>,
    /// How glTF punctual lights are read.
    #[arg(long, value_enum, default_value = "gltf")]
    light_convention: ConventionArg,
    /// Print the plan and exit without baking.
    #[arg(long)]
    plan_only: bool,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

/// `bake convergence SCENE -o DIR`: every method over a sweep of budgets, error against a
/// reference bake versus run time; writes `convergence.csv`, `convergence.md`,
/// `convergence.svg` and `convergence.png` to DIR.
#[derive(Debug, Parser)]
#[command(name = "bake convergence", version)]
struct ConvergenceArgs {
    /// The scene: a .gltf or .glb file.
    scene: PathBuf,
    /// Output directory.
    #[arg(short, long)]
    output: PathBuf,
    /// Lightmap texels per metre (default: the scene's hint, else the medium preset's).
    #[arg(long)]
    texel_density: Option<f32>,
    /// Two budgets per curve instead of the full sweeps.
    #[arg(long)]
    quick: bool,
    /// Worker threads (0 = every core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// How glTF punctual lights are read.
    #[arg(long, value_enum, default_value = "gltf")]
    light_convention: ConventionArg,
}

mod convergence {
    use super::*;
    use lightbake::output::atomic::StagedFiles;
    use lightbake::study::{StudyRow, StudySize, run_study};

    pub(super) fn run(args: ConvergenceArgs) -> Result<(), String> {
        let mut settings = BakeSettings::medium();
        settings.threads = args.threads;
        settings.light_convention = match args.light_convention {
            ConventionArg::Gltf => LightConvention::GltfSpec,
            ConventionArg::Bevy => LightConvention::BevyGltfLoader,
        };
        if let Some(d) = args.texel_density {
            settings.texel_density = d;
            settings.texel_density_from_scene = false;
        }
        settings.validate().map_err(|e| e.to_string())?;
        let imported =
            import_gltf(&args.scene, settings.light_convention).map_err(|e| e.to_string())?;
        let size = if args.quick {
            StudySize::Quick
        } else {
            StudySize::Full
        };
        println!(
            "convergence study of {} (reference bake first)",
            args.scene.display()
        );
        println!(
            "{:<20} {:>12} {:>9} {:>10} {:>10}",
            "curve", "budget", "time", "measured", "estimated"
        );
        let study = run_study(&imported.scene, &settings, size, |r: &StudyRow| {
            println!(
                "{:<20} {:>12} {:>8.3}s {:>9.3}% {:>10}",
                r.curve,
                format!("{}={}", r.parameter, r.budget),
                r.seconds,
                100.0 * r.measured,
                r.estimated
                    .map_or("-".into(), |e| format!("{:.3}%", 100.0 * e))
            );
        })
        .map_err(|e| e.to_string())?;
        let mut csv = String::from(StudyRow::CSV_HEADER);
        csv.push('\n');
        for r in &study.rows {
            csv.push_str(&r.csv());
            csv.push('\n');
        }
        let (svg, png) = plot::render(&study)?;
        let mut files = StagedFiles::new();
        let out = &args.output;
        let stage = |files: &mut StagedFiles, name: &str, bytes: &[u8]| {
            files
                .stage(&out.join(name), bytes)
                .map_err(|e| e.to_string())
        };
        stage(&mut files, "convergence.csv", csv.as_bytes())?;
        stage(&mut files, "convergence.md", study.markdown().as_bytes())?;
        stage(&mut files, "convergence.svg", &svg)?;
        stage(&mut files, "convergence.png", &png)?;
        let written = files.commit().map_err(|e| e.to_string())?;
        println!();
        print!("{}", study.markdown());
        println!("wrote {} files to {}", written.len(), out.display());
        Ok(())
    }
}

fn settings_from(args: &Args) -> BakeSettings {
    let mut s = BakeSettings::preset(match args.quality {
        QualityArg::Preview => Quality::Preview,
        QualityArg::Medium => Quality::Medium,
        QualityArg::High => Quality::High,
    });
    if let Some(d) = args.texel_density {
        s.texel_density = d;
        s.texel_density_from_scene = false;
    }
    if let Some(v) = args.samples {
        s.samples_per_texel = v;
    }
    if let Some(v) = args.sky_samples {
        s.sky_samples = v;
    }
    if let Some(v) = args.padding {
        s.padding = v;
    }
    if let Some(v) = args.max_page_size {
        s.max_page_size = v;
    }
    if let Some(v) = args.memory_budget {
        s.memory_budget_mib = v;
    }
    s.target_error = args.target_error;
    s.method = match args.method {
        MethodArg::Direct => Method::Direct,
        MethodArg::Radiosity => Method::Radiosity,
        MethodArg::Vpl => Method::Vpl,
        MethodArg::Hybrid => Method::Hybrid,
    };
    if let Some(v) = args.vpl_particles {
        s.vpl_particles = v;
    }
    s.vpl_time_budget_s = args.vpl_time_budget;
    s.vpl_sequence = match args.vpl_sequence {
        SequenceArg::Halton => Sequence::Halton,
        SequenceArg::ScrambledHalton => Sequence::ScrambledHalton,
        SequenceArg::Jittered => Sequence::Jittered,
        SequenceArg::Random => Sequence::Random,
    };
    s.vpl_clamp_distance = args.vpl_clamp;
    s.vpl_bias_compensation = args.bias_compensation;
    s.solver = match args.solver {
        SolverArg::Auto => SolverChoice::Auto,
        SolverArg::Jacobi => SolverChoice::Jacobi,
        SolverArg::GaussSeidel => SolverChoice::GaussSeidel,
        SolverArg::Shooting => SolverChoice::Shooting,
        SolverArg::StochasticJacobi => SolverChoice::StochasticJacobi,
        SolverArg::Krylov => SolverChoice::Krylov,
        SolverArg::KrylovCg => SolverChoice::KrylovCg,
        SolverArg::Direct => SolverChoice::Direct,
    };
    s.basis = match args.basis {
        BasisArg::Linear => Basis::Linear,
        BasisArg::Constant => Basis::Constant,
    };
    if let Some(v) = args.transport_rays {
        s.transport_rays = v;
    }
    if let Some(v) = args.transport_budget {
        s.transport_budget_mib = v;
    }
    if let Some(v) = args.tolerance {
        s.solver_tolerance = v;
    }
    s.formats.exr = args.format.iter().any(|f| matches!(f, FormatArg::Exr));
    s.formats.hdr = args.format.iter().any(|f| matches!(f, FormatArg::Hdr));
    s.formats.ktx2 = args.format.iter().any(|f| matches!(f, FormatArg::Ktx2));
    s.formats.png_preview = !args.no_preview;
    s.reunwrap = args.reunwrap;
    s.threads = args.threads;
    s.seed = args.seed;
    s.light_convention = match args.light_convention {
        ConventionArg::Gltf => LightConvention::GltfSpec,
        ConventionArg::Bevy => LightConvention::BevyGltfLoader,
    };
    s
}

fn run(args: Args) -> Result<(), String> {
    let settings = settings_from(&args);
    settings.validate().map_err(|e| e.to_string())?;
    let mut imported =
        import_gltf(&args.scene, settings.light_convention).map_err(|e| e.to_string())?;
    if let Some(sky) = &args.sky {
        imported.scene.sky = glam::Vec3::new(sky[0], sky[1], sky[2]);
    }
    let scene = &imported.scene;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    let plan = BakePlan::new(scene, &settings);
    println!(
        "{}: {} meshes, {} instances, {} triangles, {} lights",
        args.scene.display(),
        scene.meshes.len(),
        scene.instances.len(),
        scene.instanced_triangle_count(),
        scene.lights.len()
    );
    print!("plan:\n{}", plan.describe());
    if args.plan_only {
        return Ok(());
    }

    let progress = Arc::new(Progress::new());
    let worker = {
        let progress = Arc::clone(&progress);
        let scene = imported.scene.clone();
        let settings = settings.clone();
        std::thread::spawn(move || lightbake::bake(&scene, &settings, &progress))
    };
    watch(&progress, &worker, args.quiet);
    let output = worker
        .join()
        .map_err(|_| "the bake thread panicked".to_string())?
        .map_err(|e| e.to_string())?;
    let written = lightbake::output::write_outputs(
        &args.output,
        &output,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .map_err(|e| e.to_string())?;
    println!();
    print!("{}", output.report.table());
    println!(
        "{} page(s), {} texel patches ({} moved out of geometry, {} invalid filled)",
        output.report.texels.pages,
        output.report.texels.patches,
        output.report.texels.moved,
        output.report.texels.filled
    );
    if let Some(v) = &output.report.vpl {
        println!(
            "instant radiosity: {} particles ({}), {} VPLs, {} shadow rays in {:.2} s ({:.2} Mrays/s), {:.1}% of the VPL light clamped{}",
            v.particles,
            v.particles_reason,
            v.vpls,
            v.shadow_rays,
            v.gather_seconds,
            v.shadow_rays_per_second / 1e6,
            100.0 * v.clamped_fraction,
            if v.compensated { " and restored" } else { "" }
        );
    }
    if let Some(ind) = &output.report.indirect {
        println!(
            "radiosity: {} nodes, solver {} ({}), {} iterations, {}",
            ind.nodes,
            ind.solver,
            ind.solver_reason,
            ind.solution.iterations,
            ind.solution.stop_reason
        );
    }
    for w in &output.report.warnings {
        eprintln!("warning: {w}");
    }
    if written.clamped_channels > 0 {
        eprintln!(
            "warning: {} texel channels clamped to the half-float maximum 65504",
            written.clamped_channels
        );
    }
    println!(
        "wrote {} files to {}:",
        written.files.len(),
        args.output.display()
    );
    for f in &written.files {
        println!("  {}", f.display());
    }
    Ok(())
}

/// Draws one progress bar per stage until the bake thread finishes.
fn watch<T>(progress: &Progress, worker: &std::thread::JoinHandle<T>, quiet: bool) {
    let style =
        ProgressStyle::with_template("{prefix:>10} [{bar:32}] {pos}/{len} {elapsed_precise} {msg}")
            .expect("valid template")
            .progress_chars("=> ");
    let mut bar: Option<ProgressBar> = None;
    let mut index = 0;
    while !worker.is_finished() {
        let snap = progress.snapshot();
        if !quiet {
            if snap.stage_index != index {
                if let Some(b) = bar.take() {
                    b.finish();
                }
                index = snap.stage_index;
                let b = ProgressBar::new(snap.total.max(1)).with_style(style.clone());
                b.set_prefix(snap.stage.clone());
                bar = Some(b);
            }
            if let Some(b) = &bar {
                b.set_position(snap.done.min(snap.total.max(1)));
                if let Some(e) = snap.error_estimate {
                    b.set_message(format!("error ≈ {e:.1e}"));
                }
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    if let Some(b) = bar {
        b.set_position(b.length().unwrap_or(0));
        b.finish();
    }
}

/// Runs the `bake` command with `args` (the first is the program name), printing what the
/// binary prints.
///
/// # Errors
/// A bad command line (clap's message) or a failed bake (the cause on one line).
pub fn run_from<I, T>(args: I) -> Result<(), String>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let args: Vec<OsString> = args.into_iter().map(Into::into).collect();
    if args.get(1).is_some_and(|a| a == "convergence") {
        let c =
            ConvergenceArgs::try_parse_from(convergence_args(&args)).map_err(|e| e.to_string())?;
        return convergence::run(c);
    }
    let args = Args::try_parse_from(args).map_err(|e| e.to_string())?;
    run(args)
}

/// `bake convergence …` parsed as its own command named `bake convergence`.
fn convergence_args(args: &[OsString]) -> Vec<OsString> {
    std::iter::once(OsString::from("bake convergence"))
        .chain(args.iter().skip(2).cloned())
        .collect()
}

/// The binary's `main`: parses the process arguments (exit 2 on a bad command line), runs,
/// and prints the error on one line (exit 1).
pub fn main() -> ExitCode {
    let argv: Vec<OsString> = std::env::args_os().collect();
    let result = if argv.get(1).is_some_and(|a| a == "convergence") {
        convergence::run(ConvergenceArgs::parse_from(convergence_args(&argv)))
    } else {
        run(Args::parse_from(argv))
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}
