//! `bake prepare`, `bake shard` and `bake merge`: one bake split across processes
//! (`lightbake::bake::shard`), run by any batch engine over a shared folder.
//!
//! ```text
//! bake prepare SCENE -o WORK [every bake flag]
//! bake shard WORK [--index I] --count N [--no-wait] [--timeout S] [--scene PATH] [--threads T]
//! bake merge WORK -o OUT [--scene PATH] [--threads T]
//! ```
//!
//! `prepare` writes `WORK/work.json` (the bake's settings as `BakeSettings` serialises them,
//! the light convention, the sky and light modes the flags set, the folders the scene may
//! read from, the scene's path and a hash of the document, its buffers and its images),
//! `WORK/patches.bin` (the texel patches) and
//! `WORK/units.json` (the work units); each shard and the merge read the scene again (from
//! `--scene`, else that absolute path, else the same place relative to the work folder) and
//! check the hash. A shard's index comes from `--index`, else `JOB_COMPLETION_INDEX`
//! (Kubernetes Indexed Jobs), else `SLURM_ARRAY_TASK_ID` (Slurm job arrays).

use std::path::{Path, PathBuf};
use std::time::Duration;

use lightbake::bake::shard::{Role, ShardRun};
use lightbake::scene::LightBake;
use lightbake::{BakeBuilder, BakeSettings, LightConvention, SplitOutcome};
use serde::{Deserialize, Serialize};

use super::{Args, CliError, import_options, load, write_and_print};

/// The work folder's description of the bake.
const WORK_FILE: &str = "work.json";

/// `work.json`'s format tag.
const WORK_FORMAT: &str = "lightbake-work-4";

/// `bake shard WORK`: compute one shard's part of every split stage.
#[derive(Debug, clap::Args)]
pub(super) struct ShardArgs {
    /// The work folder `bake prepare` wrote (shared by every shard).
    work: PathBuf,
    /// This shard, 0-based. Default: `JOB_COMPLETION_INDEX`, else `SLURM_ARRAY_TASK_ID`.
    #[arg(long)]
    index: Option<u32>,
    /// Shards in all; every shard and every re-run must give the same.
    #[arg(long)]
    count: u32,
    /// Stop after computing the first stage this shard has not done, instead of waiting for
    /// the other shards and going on (for engines that run the stages as separate waves).
    #[arg(long)]
    no_wait: bool,
    /// The scene file, where this machine sees it. Default: where `prepare` read it, else
    /// the same place relative to the work folder (for a shared volume mounted elsewhere).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Give up waiting for the other shards' parts after this many seconds (0 to 10⁷, about
    /// 116 days).
    #[arg(long, default_value_t = 86_400.0, value_parser = parse_timeout)]
    timeout: f64,
    /// Worker threads (0 = every core). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// `bake merge WORK -o OUT`: read every shard's parts and write the outputs.
#[derive(Debug, clap::Args)]
pub(super) struct MergeArgs {
    /// The work folder.
    work: PathBuf,
    /// Output directory, as for a bake.
    #[arg(short, long)]
    output: PathBuf,
    /// The scene file, where this machine sees it. Default: where `prepare` read it, else
    /// the same place relative to the work folder (for a shared volume mounted elsewhere).
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Worker threads (0 = every core). The result does not depend on it.
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// Longest wait for the other shards, s.
const MAX_TIMEOUT: f64 = 1e7;

/// `--timeout`: a number of seconds in [0, [`MAX_TIMEOUT`]].
fn parse_timeout(text: &str) -> Result<f64, String> {
    let t: f64 = text
        .parse()
        .map_err(|e| format!("{text:?} is not a number of seconds: {e}"))?;
    if !(0.0..=MAX_TIMEOUT).contains(&t) {
        return Err(format!(
            "{text} is not a number of seconds from 0 to {MAX_TIMEOUT:e}"
        ));
    }
    Ok(t)
}

/// `work.json`: the bake a work folder holds, as settings (not as a command line), so the
/// shards and the merge rebuild exactly the prepared bake.
#[derive(Debug, Serialize, Deserialize)]
struct Work {
    format: String,
    /// The scene, absolute.
    scene: PathBuf,
    /// The scene relative to the work folder (both with links resolved), when they share a
    /// root.
    #[serde(default)]
    scene_from_work: Option<PathBuf>,
    /// The bake's settings (the shards and the merge set only their own thread count).
    settings: BakeSettings,
    /// How the glTF's punctual lights are read (`--light-convention`).
    light_convention: LightConvention,
    /// The sky luminance `--sky` set, nits.
    sky: Option<[f32; 3]>,
    /// The lights (by index in the scene) baked indirect only.
    indirect_only: Vec<usize>,
    /// Folders besides the scene's own that its URIs may read from.
    allow_read: Vec<PathBuf>,
    /// FNV-1a of the glTF document, its buffers and its images.
    scene_hash: u64,
}

/// `bake prepare SCENE -o WORK [flags]`: writes `work.json` and the prepared patches.
pub(super) fn prepare(args: Args) -> Result<(), CliError> {
    let (settings, imported) = load(&args)?;
    let scene =
        std::path::absolute(&args.scene).map_err(|e| format!("{}: {e}", args.scene.display()))?;
    std::fs::create_dir_all(&args.output).map_err(|e| format!("{}: {e}", args.output.display()))?;
    let scene_from_work = match (args.scene.canonicalize(), args.output.canonicalize()) {
        (Ok(scene), Ok(work)) => relative(&work, &scene),
        _ => None,
    };
    let work = Work {
        format: WORK_FORMAT.into(),
        scene,
        scene_from_work,
        settings: settings.clone(),
        light_convention: args.light_convention,
        sky: args.sky,
        indirect_only: (imported.scene.lights.iter().enumerate())
            .filter(|(_, l)| l.bake == LightBake::IndirectOnly)
            .map(|(i, _)| i)
            .collect(),
        allow_read: args.allow_read.clone(),
        scene_hash: imported.content_hash(),
    };
    let text = serde_json::to_vec_pretty(&work).map_err(|e| e.to_string())?;
    let mut staged = lightbake::atomic::StagedFiles::new(&args.output);
    staged.stage(&args.output.join(WORK_FILE), &text)?;
    staged.commit()?;
    run_role(&imported, &settings, &args.output, Role::Prepare).map(|_| ())
}

/// `to` as a path from the folder `from` (both absolute, links resolved); `None` when they
/// have no common root.
fn relative(from: &Path, to: &Path) -> Option<PathBuf> {
    let from: Vec<_> = from.components().collect();
    let to: Vec<_> = to.components().collect();
    let common = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return None;
    }
    let mut out = PathBuf::new();
    for _ in common..from.len() {
        out.push("..");
    }
    out.extend(&to[common..]);
    Some(out)
}

/// The scene file of `work`: `chosen`, else where prepare read it, else the same place
/// relative to the work folder.
fn scene_path(work: &Work, work_dir: &Path, chosen: Option<&Path>) -> Result<PathBuf, CliError> {
    if let Some(path) = chosen {
        return Ok(path.to_path_buf());
    }
    if work.scene.exists() {
        return Ok(work.scene.clone());
    }
    match &work.scene_from_work {
        Some(rel) if work_dir.join(rel).exists() => Ok(work_dir.join(rel)),
        _ => Err(CliError::Input(format!(
            "{}: no such file here{}: give its path on this machine with --scene",
            work.scene.display(),
            work.scene_from_work
                .as_ref()
                .map(|rel| format!(", nor at {}", work_dir.join(rel).display()))
                .unwrap_or_default()
        ))),
    }
}

/// The bake `work.json` describes, with `threads` threads, reading the scene from `scene`
/// when given.
fn reload(
    work_dir: &Path,
    threads: usize,
    scene: Option<&Path>,
) -> Result<(BakeSettings, lightbake::ImportedScene), CliError> {
    let path = work_dir.join(WORK_FILE);
    let text = lightbake::scene::read_regular_file(&path, 1 << 20).map_err(|e| {
        format!(
            "{e} (run `bake prepare SCENE -o {}` first)",
            work_dir.display()
        )
    })?;
    let work: Work =
        serde_json::from_slice(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    if work.format != WORK_FORMAT {
        return Err(format!(
            "{}: format '{}', this bake reads '{WORK_FORMAT}': prepare again with this version",
            path.display(),
            work.format
        )
        .into());
    }
    let scene = scene_path(&work, work_dir, scene)?;
    let mut settings = work.settings;
    settings.threads = threads;
    settings.validate()?;
    let mut imported = lightbake::import_gltf_with(
        &scene,
        &import_options(&settings, work.light_convention, &work.allow_read),
    )?;
    if let Some(sky) = work.sky {
        imported.scene.sky = glam::Vec3::from_array(sky);
    }
    let lights = imported.scene.lights.len();
    for &i in &work.indirect_only {
        let light = imported.scene.lights.get_mut(i).ok_or_else(|| {
            format!(
                "{}: light {i} is baked indirect only, and the scene has {lights} lights: prepare again",
                path.display()
            )
        })?;
        light.bake = LightBake::IndirectOnly;
    }
    if imported.content_hash() != work.scene_hash {
        return Err(format!(
            "{} changed since `bake prepare`: prepare again",
            scene.display()
        )
        .into());
    }
    Ok((settings, imported))
}

/// Runs the bake in `role`; `None` when the process did its part and stopped there.
fn run_role(
    imported: &lightbake::ImportedScene,
    settings: &BakeSettings,
    work: &Path,
    role: Role,
) -> Result<Option<lightbake::BakeOutput>, CliError> {
    let run = ShardRun::new(work, role);
    let outcome = BakeBuilder::new(imported.scene.clone())
        .settings(settings.clone())
        .run_split(&run)?;
    match outcome {
        SplitOutcome::Merged(out) => Ok(Some(*out)),
        SplitOutcome::PartDone(done) => {
            println!("{done}");
            Ok(None)
        }
    }
}

/// `bake shard WORK --count N [--index I]`.
pub(super) fn shard(args: ShardArgs) -> Result<(), CliError> {
    let index = match args.index {
        Some(i) => i,
        None => ["JOB_COMPLETION_INDEX", "SLURM_ARRAY_TASK_ID"]
            .iter()
            .find_map(|v| std::env::var(v).ok())
            .ok_or("no shard index: give --index, or run under a Kubernetes Indexed Job (JOB_COMPLETION_INDEX) or a Slurm job array (SLURM_ARRAY_TASK_ID)")?
            .trim()
            .parse()
            .map_err(|e| format!("the shard index from the environment is not a number: {e}"))?,
    };
    if args.count == 0 || index >= args.count {
        return Err(format!(
            "--index {index} is not a shard of --count {}: indices run from 0 to count − 1",
            args.count
        )
        .into());
    }
    let (settings, imported) = reload(&args.work, args.threads, args.scene.as_deref())?;
    let wait = (!args.no_wait).then(|| Duration::from_secs_f64(args.timeout));
    let role = Role::Shard {
        index,
        count: args.count,
        wait,
    };
    match run_role(&imported, &settings, &args.work, role)? {
        Some(_) => Err("internal error: a shard ran the whole bake".into()),
        None => Ok(()),
    }
}

/// `bake merge WORK -o OUT`.
pub(super) fn merge(args: MergeArgs) -> Result<(), CliError> {
    let (settings, imported) = reload(&args.work, args.threads, args.scene.as_deref())?;
    let Some(mut output) = run_role(&imported, &settings, &args.work, Role::Merge)? else {
        return Err("internal error: the merge stopped early".into());
    };
    for stage in &output.report.split {
        let seconds: Vec<f64> = stage.parts.iter().map(|p| p.seconds).collect();
        let max = seconds.iter().cloned().fold(0.0, f64::max);
        let mean = seconds.iter().sum::<f64>() / seconds.len().max(1) as f64;
        let rays: u64 = stage.parts.iter().map(|p| p.rays[0] + p.rays[1]).sum();
        println!(
            "{}: {} shards, {:.3} s mean, {:.3} s max (max / mean {:.2}), {} rays",
            stage.stage,
            stage.parts.len(),
            mean,
            max,
            if mean > 0.0 { max / mean } else { 1.0 },
            rays
        );
    }
    write_and_print(&args.output, &mut output, &imported, &settings)
}
