//! `bake`: bake lightmaps for a glTF scene. The binary is `src/main.rs`; the command itself
//! lives here so that other crates' tests can run exactly what users run ([`run_from`]).
//!
//! ```text
//! bake assets/cornell_box.gltf -o baked/cornell_box        (the same as `bake bake …`)
//! bake scene.glb -o out --quality high --format exr,ktx2
//! bake convergence SCENE -o DIR                            error against time, every method
//! bake prepare SCENE -o WORK [bake flags]                  a bake split across processes:
//! bake shard WORK --count N [--index I]                      one shard's part
//! bake merge WORK -o OUT                                     the outputs
//! ```
//!
//! Exit status: 0 on success, 1 when the bake fails (the cause on one line on stderr),
//! 2 for a bad command line.

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lightbake::report::BakePlan;
use lightbake::{
    BakeBuilder, BakeHandle, BakeSettings, Basis, ImageFormat, ImportOptions, LightConvention,
    Method, OutputFormats, Progress, Quality, Sequence, SolverChoice, import_gltf_with,
};

mod convergence;
mod follow;
mod lights;
mod plot;
mod split;

/// Parses `R,G,B` (three numbers separated by commas).
fn parse_rgb(text: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let [r, g, b] = parts[..] else {
        return Err(format!("expected R,G,B (three numbers), got {text:?}"));
    };
    let num = |p: &str| {
        p.parse::<f32>()
            .map_err(|e| format!("{p:?} is not a number: {e}"))
    };
    Ok([num(r)?, num(g)?, num(b)?])
}

/// The long description `bake --help` starts with.
const ABOUT: &str = "Bake lightmaps for a glTF scene: lightmap UVs (xatlas, or the scene's TEXCOORD_1), direct light by shadow rays, interreflected light by radiosity (hierarchical, with a final gather) or instant radiosity, an error estimate, and optionally an irradiance volume for dynamic objects. Writes HDR lightmaps, a baked glTF (TEXCOORD_1), manifest.json and report.json.\n\n`bake SCENE -o OUT [flags]` is `bake bake SCENE -o OUT [flags]`.";

/// The command line: a subcommand, or a bake's arguments alone.
#[derive(Debug, Parser)]
#[command(
    name = "bake",
    version,
    about = ABOUT,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
struct Cli {
    /// What to do.
    #[command(subcommand)]
    command: Option<Command>,
    /// The bare form: `bake SCENE -o OUT [flags]`.
    #[command(flatten)]
    bake: Option<Args>,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
enum Command {
    /// Bake a scene (the default when the first argument is a scene).
    Bake(Args),
    /// Every method over a sweep of budgets: error against a reference bake versus run time
    /// (convergence.csv, .md, .svg and .png).
    Convergence(ConvergenceArgs),
    /// Start a bake split across processes: plan, unwrap and rasterise into a work folder
    /// (takes every flag of a bake).
    Prepare(Args),
    /// Compute one shard's part of every split stage of a prepared bake.
    Shard(split::ShardArgs),
    /// Read every shard's parts of a prepared bake and write its outputs.
    Merge(split::MergeArgs),
}

/// What `bake` can fail with.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The command line could not be parsed (clap's message, with usage).
    #[error("{0}")]
    CommandLine(#[from] clap::Error),
    /// The bake, the import or the writing failed.
    #[error("{0}")]
    Bake(#[from] lightbake::BakeError),
    /// A flag's value or a file the command reads is not usable (the message says which).
    #[error("{0}")]
    Input(String),
}

impl From<String> for CliError {
    fn from(message: String) -> Self {
        CliError::Input(message)
    }
}

impl From<&str> for CliError {
    fn from(message: &str) -> Self {
        CliError::Input(message.to_string())
    }
}

/// A bake's arguments: the scene, the output folder and one flag per setting.
#[derive(Debug, clap::Args)]
struct Args {
    /// The scene: a .gltf or .glb file.
    scene: PathBuf,
    /// Output directory (created if needed; files in it are replaced atomically).
    #[arg(short, long)]
    output: PathBuf,
    /// Preset for density and samples; the options below override it.
    #[arg(long, value_enum, default_value = "medium")]
    quality: Quality,
    /// How light is computed.
    #[arg(long, value_enum, default_value = "radiosity")]
    method: Method,
    /// Radiosity solver.
    #[arg(long, value_enum, default_value = "auto")]
    solver: SolverChoice,
    /// Radiosity basis over the texel grid.
    #[arg(long, value_enum, default_value = "linear")]
    basis: Basis,
    /// Form-factor rays per texel (radiosity).
    #[arg(long)]
    transport_rays: Option<u32>,
    /// Hierarchical solve: edge of its first clusters, texels (a power of two, at most 256).
    #[arg(long)]
    cluster_texels: Option<u32>,
    /// Hierarchical solve: form-factor rays per cluster of its coarse level.
    #[arg(long)]
    cluster_rays: Option<u32>,
    /// Hierarchical solve: refine the coarse level until the light its clusters miss is at
    /// most this fraction of the irradiance.
    #[arg(long)]
    cluster_tolerance: Option<f64>,
    /// Largest transport matrix plus the solver's vectors beside it, MiB (above it `auto` takes
    /// the hierarchical solve); what the memory budget leaves beside the rest of the bake also
    /// bounds it.
    #[arg(long)]
    transport_budget: Option<u64>,
    /// Target relative error of the radiosity solve.
    #[arg(long)]
    tolerance: Option<f64>,
    /// Give the radiosity solver up after this many iterations (sweeps).
    #[arg(long)]
    max_solver_iterations: Option<u32>,
    /// Stochastic Jacobi: rays per node in its first iteration.
    #[arg(long)]
    stochastic_rays: Option<u32>,
    /// Instant radiosity: particles started from the lights.
    #[arg(long)]
    vpl_particles: Option<u32>,
    /// Instant radiosity: VPLs each texel gathers through a lightcut (0: every VPL).
    #[arg(long)]
    vpl_cut: Option<u32>,
    /// Instant radiosity: fit the gather into this many seconds (sets the cut, or the particles
    /// with --vpl-cut 0).
    #[arg(long)]
    vpl_time_budget: Option<f64>,
    /// Instant radiosity: number pattern of the walks.
    #[arg(long, value_enum, default_value = "scrambled-halton")]
    vpl_sequence: Sequence,
    /// Instant radiosity: clamp distance in metres (default 2% of the scene's diagonal).
    #[arg(long)]
    vpl_clamp: Option<f32>,
    /// Instant radiosity: restore the clamped energy (Kollig & Keller bias compensation).
    #[arg(long)]
    bias_compensation: bool,
    /// Instant radiosity: rays per texel of the bias compensation.
    #[arg(long)]
    vpl_compensation_rays: Option<u32>,
    /// Instant radiosity: deepest reflection followed (at most 29).
    #[arg(long)]
    vpl_max_depth: Option<u32>,
    /// Lightmap texels per metre (overrides the scene's own hint and the texel budget).
    #[arg(long)]
    texel_density: Option<f32>,
    /// Ignore the scene's suggested density (`extras.lightbake.texel_density`) and choose one
    /// from the texel budget.
    #[arg(long)]
    ignore_scene_density: bool,
    /// Covered texels to aim for when the density is chosen automatically (the preset's: 65536
    /// preview, 262144 medium, 1048576 high).
    #[arg(long)]
    texel_budget: Option<u64>,
    /// Keep every chart at the one density, instead of sharing the texel budget out by a
    /// pilot of the direct light (up to 2× where the light varies within a texel, down to ½×
    /// where it is flat).
    #[arg(long)]
    uniform_density: bool,
    /// Samples per texel for direct light (footprint points × one sample per light).
    #[arg(long)]
    samples: Option<u32>,
    /// Sky rays per texel.
    #[arg(long)]
    sky_samples: Option<u32>,
    /// Emissive triangles up to which direct light is computed in closed form (above it they
    /// are sampled by power).
    #[arg(long)]
    max_closed_form_emitters: Option<u32>,
    /// Empty texels between charts.
    #[arg(long)]
    padding: Option<u32>,
    /// Largest atlas page, texels per side.
    #[arg(long)]
    max_page_size: Option<u32>,
    /// HDR formats to write, comma separated.
    #[arg(long, value_enum, value_delimiter = ',', default_value = "exr")]
    format: Vec<ImageFormat>,
    /// Do not write the tonemapped PNG previews.
    #[arg(long)]
    no_preview: bool,
    /// Unwrap every mesh with xatlas, even those with their own TEXCOORD_1.
    #[arg(long)]
    reunwrap: bool,
    /// Leave out the contact fit (texels next to geometry fitted so the bilinear
    /// reconstruction is right on the visible surface).
    #[arg(long)]
    no_contact_fit: bool,
    /// Leave out the seam stitch (both sides of a seam made to agree).
    #[arg(long)]
    no_stitch: bool,
    /// The same rays at every node in the hierarchical solve's final gather, instead of
    /// shared out by each node's noise in a pilot.
    #[arg(long)]
    even_gather: bool,
    /// The final gather through an irradiance cache of cells this many texels wide (a power
    /// of two, 2 to 64), interpolated where the light is smooth; 0: every texel gathered.
    #[arg(long, value_name = "TEXELS")]
    gather_cache: Option<u32>,
    /// The irradiance cache's accuracy (Ward's a; smaller: more gathers).
    #[arg(long)]
    cache_accuracy: Option<f32>,
    /// The edge-aware denoiser (default: off for preview, on for medium and high).
    #[arg(long, value_parser = parse_on_off, value_name = "on|off")]
    denoise: Option<bool>,
    /// The denoiser's radius, texels (default 3).
    #[arg(long)]
    denoise_radius: Option<u32>,
    /// Also bake irradiance volumes for dynamic objects: one per room, the level cut at its
    /// walls (`irradiance_volumes/volume_N.ktx2`, Bevy's `IrradianceVolume` layout, listed
    /// in manifest.json with their transforms and falloffs).
    #[arg(long)]
    irradiance_volume: bool,
    /// Most irradiance volumes (default 8, the most Bevy draws in one view; 1: one volume
    /// over the whole level).
    #[arg(long, value_name = "N")]
    volume_regions: Option<u32>,
    /// Keep the volumes on the world axes even when the level's walls are turned.
    #[arg(long)]
    volume_world_axes: bool,
    /// Distance between the volumes' probes, m (default: 16 texels at the bake's density, or
    /// the level's median headroom over its roofed floors divided by --probes-per-headroom
    /// where that is finer; widened to at most 65 536 probes per volume).
    #[arg(long, value_name = "M")]
    probe_spacing: Option<f32>,
    /// Without --probe-spacing: the least probes from a floor up to the ceiling over it
    /// (default 4 preview, 6 medium, 8 high).
    #[arg(long, value_name = "N")]
    probes_per_headroom: Option<u32>,
    /// Rays per probe of the volume (default 256 preview, 512 medium, 1024 high).
    #[arg(long)]
    probe_rays: Option<u32>,
    /// Worker threads (0 = every core). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Seed of the sample sequences.
    #[arg(long, default_value_t = 0)]
    seed: u32,
    /// Which part of the lights' light goes into the lightmaps: `full` (direct and indirect;
    /// the engine must stop those lights lighting lightmapped meshes) or `indirect` (only the
    /// light they send after a reflection: the lights stay real-time, with the engine's
    /// shadows; Bevy's mixed lighting). Applies to every light, or to those named by
    /// `--indirect-only`. Sky and emissive surfaces are always baked in full.
    #[arg(long, value_enum, default_value = "full")]
    lighting: lights::Lighting,
    /// Bake only these lights (glTF light names, comma-separated) indirect only; the rest in
    /// full. Implies `--lighting indirect` for them.
    #[arg(long, value_name = "NAME,...", value_delimiter = ',')]
    indirect_only: Vec<String>,
    /// A light group, baked into lightmaps of its own (`lightmaps/groups/NAME/`, listed in
    /// manifest.json) so a game can switch and blend it at run time: `NAME=MEMBER,...`, each
    /// member a light name, an emissive material name or `sky` (`light:NAME` and
    /// `material:NAME` when a light and a material share a name). Repeat for more groups;
    /// what no group names bakes into the group `ungrouped`; the bake's own pages are the
    /// sum. Replaces the groups the glTF's extras give.
    #[arg(long, value_name = "NAME=MEMBER,...", value_parser = lights::parse_group)]
    group: Vec<lightbake::settings::LightGroup>,
    /// Uniform sky luminance in nits, linear RGB (overrides the scene's).
    #[arg(long, value_name = "R,G,B", value_parser = parse_rgb)]
    sky: Option<[f32; 3]>,
    /// Refuse bakes estimated to need more memory than this (MiB); the transport matrix is
    /// planned within what the rest of the bake leaves of it.
    #[arg(long)]
    memory_budget: Option<u64>,
    /// Refuse a bake the plan estimates to trace more rays than this (default 10¹¹, about
    /// three hours at 10 Mrays/s).
    #[arg(long)]
    max_rays: Option<u64>,
    /// Target relative RMS error (0.02 = 2%): sample counts become a pilot, and each sampling
    /// stage raises them until its own error estimate reaches its share of the target (the
    /// texel grid's error, which samples do not lower, is printed beside it).
    #[arg(long)]
    target_error: Option<f32>,
    /// Points at which the bake checks its own texel grid (default 16384; 0 leaves it out):
    /// the direct light the lightmap shows between texel centres against the direct light
    /// at the point, added to the printed error estimate.
    #[arg(long, value_name = "N")]
    grid_error_points: Option<u32>,
    /// After the bake, check it against the in-tree path tracer at N points spread over the
    /// surfaces a viewer can see: the measured error, its bias, the share of points beyond
    /// ±10% and ±25%, lit points left black, the bake's estimate against the measurement and
    /// the worst points (printed, and in report.json as `verification`).
    #[arg(long, value_name = "N")]
    verify: Option<u32>,
    /// Paths per point of `--verify` (default 4096): the reference's noise falls as
    /// 1/√paths and is printed beside the error.
    #[arg(long)]
    verify_paths: Option<u32>,
    /// How glTF punctual lights are read.
    #[arg(long, value_enum, default_value = "gltf")]
    light_convention: LightConvention,
    /// A folder besides the scene's own that its buffer and image URIs may read from (a
    /// shared texture library); repeat for more. Without it, URIs that lead outside the
    /// scene's folder are refused.
    #[arg(long, value_name = "DIR")]
    allow_read: Vec<PathBuf>,
    /// Print the plan and exit without baking.
    #[arg(long)]
    plan_only: bool,
    /// Bake every texel again, although OUT holds the cache of an earlier bake of the scene
    /// (by default a bake into OUT follows it, baking again only what the edit changed).
    #[arg(long)]
    full: bool,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

/// `bake convergence SCENE -o DIR`: every method over a sweep of budgets, error against a
/// reference bake versus run time; writes `convergence.csv`, `convergence.md`,
/// `convergence.svg` and `convergence.png` to DIR.
#[derive(Debug, clap::Args)]
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
    light_convention: LightConvention,
    /// A folder besides the scene's own that its URIs may read from; repeat for more.
    #[arg(long, value_name = "DIR")]
    allow_read: Vec<PathBuf>,
}

/// How a command line's scene is read: its light convention, the folders it may read from
/// and the memory budget.
fn import_options(
    settings: &BakeSettings,
    light_convention: LightConvention,
    allow_read: &[PathBuf],
) -> ImportOptions {
    ImportOptions {
        light_convention,
        allow_read: allow_read.to_vec(),
        memory_budget_bytes: settings.memory_budget_mib.saturating_mul(1 << 20),
        ..ImportOptions::default()
    }
}

/// The settings the command line asks for: the preset, then every flag given (one flag per
/// field of [`BakeSettings`]).
fn settings_from(args: &Args) -> BakeSettings {
    let mut s = BakeSettings::preset(args.quality);
    let set = |field: &mut u32, v: Option<u32>| {
        if let Some(v) = v {
            *field = v;
        }
    };
    s.method = args.method;
    s.radiosity.solver = args.solver;
    s.radiosity.basis = args.basis;
    set(&mut s.radiosity.transport_rays, args.transport_rays);
    set(&mut s.radiosity.cluster_texels, args.cluster_texels);
    set(&mut s.radiosity.cluster_rays, args.cluster_rays);
    set(&mut s.radiosity.cache_spacing, args.gather_cache);
    if let Some(a) = args.cache_accuracy {
        s.radiosity.cache_accuracy = a;
    }
    if let Some(v) = args.cluster_tolerance {
        s.radiosity.cluster_tolerance = v;
    }
    if let Some(v) = args.transport_budget {
        s.radiosity.transport_budget_mib = v;
    }
    if let Some(v) = args.tolerance {
        s.radiosity.solver_tolerance = v;
    }
    set(
        &mut s.radiosity.max_solver_iterations,
        args.max_solver_iterations,
    );
    set(
        &mut s.radiosity.stochastic_rays_per_node,
        args.stochastic_rays,
    );
    set(&mut s.vpl.particles, args.vpl_particles);
    set(&mut s.vpl.cut_size, args.vpl_cut);
    s.vpl.time_budget_s = args.vpl_time_budget;
    s.vpl.sequence = args.vpl_sequence;
    s.vpl.clamp_distance = args.vpl_clamp;
    s.vpl.bias_compensation = args.bias_compensation;
    set(&mut s.vpl.compensation_rays, args.vpl_compensation_rays);
    set(&mut s.vpl.max_depth, args.vpl_max_depth);
    s.layout.texel_density = args.texel_density;
    // An explicit density wins over the scene's hint anyway; the report says so too.
    s.layout.texel_density_from_scene = args.texel_density.is_none() && !args.ignore_scene_density;
    s.layout.adaptive_density = !args.uniform_density;
    if let Some(v) = args.texel_budget {
        s.layout.texel_budget = v;
    }
    set(&mut s.direct.samples_per_texel, args.samples);
    set(&mut s.direct.sky_samples, args.sky_samples);
    set(
        &mut s.direct.max_closed_form_emitters,
        args.max_closed_form_emitters,
    );
    set(&mut s.layout.padding, args.padding);
    set(&mut s.layout.max_page_size, args.max_page_size);
    s.formats = OutputFormats::of(&args.format, !args.no_preview);
    s.layout.reunwrap = args.reunwrap;
    s.finish.contact_fit = !args.no_contact_fit;
    s.finish.stitch_seams = !args.no_stitch;
    s.radiosity.adaptive_gather = !args.even_gather;
    if let Some(v) = args.denoise {
        s.finish.denoise = v;
    }
    set(&mut s.finish.denoise_radius, args.denoise_radius);
    s.volume.enabled = args.irradiance_volume;
    s.volume.probe_spacing = args.probe_spacing;
    set(&mut s.volume.regions, args.volume_regions);
    s.volume.oriented = !args.volume_world_axes;
    set(&mut s.volume.probe_rays, args.probe_rays);
    set(&mut s.volume.probes_per_headroom, args.probes_per_headroom);
    s.threads = args.threads;
    s.seed = args.seed;
    if let Some(v) = args.memory_budget {
        s.memory_budget_mib = v;
    }
    if let Some(v) = args.max_rays {
        s.max_rays = v;
    }
    s.target_error = args.target_error;
    set(&mut s.checks.grid_error_points, args.grid_error_points);
    if let Some(v) = args.verify {
        s.checks.verify_points = v;
    }
    set(&mut s.checks.verify_paths, args.verify_paths);
    s.groups = args.group.clone();
    s
}

/// `on` or `off`.
fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("expected on or off, not {s:?}")),
    }
}

/// The settings and the scene a command line asks for: the preset and every flag, the glTF
/// imported, the sky and the lights' bake modes applied.
fn load(args: &Args) -> Result<(BakeSettings, lightbake::ImportedScene), CliError> {
    let settings = settings_from(args);
    settings.validate()?;
    let options = import_options(&settings, args.light_convention, &args.allow_read);
    let mut imported = import_gltf_with(&args.scene, &options)?;
    if let Some(sky) = args.sky {
        imported.scene.sky = glam::Vec3::from_array(sky);
    }
    lights::choose_lighting(args, &mut imported.scene)?;
    let settings = lights::with_groups(settings, args, &imported)?;
    Ok((settings, imported))
}

fn run(args: Args) -> Result<(), CliError> {
    let (settings, imported) = load(&args)?;
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
    plan.check_rays(&settings)?;
    let following = follow::plan(&args.output, scene, &settings, args.full);
    print!("{}", following.describe());
    if args.plan_only {
        return Ok(());
    }

    let existed = args.output.exists();
    let handle = BakeBuilder::new(imported.scene.clone())
        .settings(settings.clone())
        .following(following)
        .checkpoints(follow::checkpoints(&args.output))
        .spawn()?;
    watch(&handle, args.quiet);
    let done = (handle.join().map_err(CliError::from))
        .and_then(|mut output| write_and_print(&args.output, &mut output, &imported, &settings));
    if done.is_err() {
        // A bake that failed (rather than was killed) leaves OUT as it found it.
        follow::discard_partial(&args.output, existed);
    }
    done
}

/// Checks a bake against the path tracer when the settings ask for it
/// (`BakeSettings::checks.verify_points`), writes its outputs into `dir` and prints its
/// table, counts, check and files.
fn write_and_print(
    dir: &std::path::Path,
    output: &mut lightbake::BakeOutput,
    imported: &lightbake::ImportedScene,
    settings: &BakeSettings,
) -> Result<(), CliError> {
    if settings.checks.verify_points > 0 {
        println!(
            "verifying at {} points with the path tracer ({} paths each)",
            settings.checks.verify_points, settings.checks.verify_paths
        );
        lightbake::analysis::verify::verify(&imported.scene, output);
    }
    let written = lightbake::output::write_outputs(
        dir,
        output,
        &imported.scene,
        Some(&imported.source),
        settings,
    )?;
    println!();
    print!("{}", output.report.table());
    println!("{}", output.report.texels.summary());
    if let Some(v) = &output.report.vpl {
        println!("{}", v.summary());
    }
    if let Some(ind) = &output.report.radiosity {
        println!(
            "radiosity: {} nodes, solver {} ({}), {} iterations, {}",
            ind.nodes,
            ind.solver,
            ind.solver_reason,
            ind.solution.iterations,
            ind.solution.stop_reason
        );
    }
    if let Some(v) = &output.report.verification {
        print!("{}", v.summary());
    }
    if let Some(line) = follow::summary(&output.report) {
        println!("{line}");
    }
    for w in &output.report.warnings {
        eprintln!("warning: {w}");
    }
    for w in &written.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(first) = written.texcoord_0_added.first() {
        let n = written.texcoord_0_added.len();
        let more = if n > 1 {
            format!(" and {} more", n - 1)
        } else {
            String::new()
        };
        println!(
            "baked glTF: TEXCOORD_0 added to {n} primitive(s) ({first}{more}) as their TEXCOORD_1, since Bevy's StandardMaterial shader needs UV_0 where UV_1 is set (report.json: texcoord_0_added)"
        );
    }
    for (i, e) in written.bc6h.iter().enumerate() {
        println!("{}", e.summary(i));
    }
    println!("wrote {} files to {}:", written.files.len(), dir.display());
    for f in &written.files {
        println!("  {}", f.display());
    }
    if !written.removed.is_empty() {
        println!(
            "removed {} files an earlier bake into the folder wrote and this one did not:",
            written.removed.len()
        );
        for f in &written.removed {
            println!("  {}", f.display());
        }
    }
    Ok(())
}

/// Draws one progress bar per stage until the bake thread finishes.
fn watch<T: Send + 'static>(handle: &BakeHandle<T>, quiet: bool) {
    let progress: &Progress = handle.progress();
    let style =
        ProgressStyle::with_template("{prefix:>10} [{bar:32}] {pos}/{len} {elapsed_precise} {msg}")
            .expect("valid template")
            .progress_chars("=> ");
    let mut bar: Option<ProgressBar> = None;
    let mut index = 0;
    while !handle.is_finished() {
        let snap = progress.snapshot();
        if !quiet {
            if snap.stage_index != index {
                if let Some(b) = bar.take() {
                    b.finish();
                }
                index = snap.stage_index;
                let b = ProgressBar::new(snap.total.max(1)).with_style(style.clone());
                b.set_prefix(snap.stage.map_or_else(String::new, |s| s.to_string()));
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
/// A bad command line ([`CliError::CommandLine`], clap's message) or a failed bake (the
/// cause on one line).
pub fn run_from<I, T>(args: I) -> Result<(), CliError>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    run_cli(Cli::try_parse_from(args)?)
}

/// Runs what the command line asks for.
fn run_cli(cli: Cli) -> Result<(), CliError> {
    match (cli.command, cli.bake) {
        (Some(Command::Bake(args)), _) | (None, Some(args)) => run(args),
        (Some(Command::Convergence(args)), _) => convergence::run(args),
        (Some(Command::Prepare(args)), _) => split::prepare(args),
        (Some(Command::Shard(args)), _) => split::shard(args),
        (Some(Command::Merge(args)), _) => split::merge(args),
        (None, None) => {
            use clap::CommandFactory;
            Err(Cli::command()
                .error(
                    clap::error::ErrorKind::MissingRequiredArgument,
                    "give a scene and an output folder (bake SCENE -o OUT), or a subcommand",
                )
                .into())
        }
    }
}

/// The binary's `main`: parses the process arguments (exit 2 on a bad command line), runs,
/// and prints the error on one line (exit 1).
pub fn main() -> ExitCode {
    match run_cli(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::CommandLine(e)) => e.exit(),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests;
