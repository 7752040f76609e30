//! `bake prepare`, `bake shard` and `bake merge`: one bake split across processes
//! (`lightbake::bake::shard`), run by any batch engine over a shared folder.
//!
//! ```text
//! bake prepare SCENE -o WORK [every bake flag]
//! bake shard WORK [--index I] --count N [--no-wait] [--timeout S] [--scene PATH] [--threads T]
//! bake merge WORK -o OUT [--scene PATH] [--threads T]
//! ```
//!
//! `prepare` writes `WORK/work.json` (the command line, the scene's path and a hash of the
//! document, its buffers and its images), `WORK/patches.bin` (the texel patches) and
//! `WORK/units.json` (the work units); each shard and the merge read the scene again (from
//! `--scene`, else that absolute path, else the same place relative to the work folder) and
//! check the hash. A shard's index comes from `--index`, else `JOB_COMPLETION_INDEX`
//! (Kubernetes Indexed Jobs), else `SLURM_ARRAY_TASK_ID` (Slurm job arrays).

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Duration;

use clap::Parser;
use lightbake::bake::shard::{Role, ShardRun};
use lightbake::{BakeError, Progress};
use serde::{Deserialize, Serialize};

use super::{Args, load, write_and_print};

/// The work folder's description of the bake.
const WORK_FILE: &str = "work.json";

/// `work.json`'s format tag.
const WORK_FORMAT: &str = "lightbake-work-2";

/// `bake shard WORK`: compute one shard's part of every split stage.
#[derive(Debug, Parser)]
#[command(name = "bake shard", version)]
struct ShardArgs {
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
#[derive(Debug, Parser)]
#[command(name = "bake merge", version)]
struct MergeArgs {
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

/// `work.json`.
#[derive(Debug, Serialize, Deserialize)]
struct Work {
    format: String,
    /// The scene, absolute.
    scene: PathBuf,
    /// The scene relative to the work folder (both with links resolved), when they share a
    /// root.
    #[serde(default)]
    scene_from_work: Option<PathBuf>,
    /// `prepare`'s command line after the scene and without `-o` (the bake's flags).
    flags: Vec<String>,
    /// FNV-1a of the glTF document, its buffers and its images.
    scene_hash: u64,
}

/// Runs `prepare`, `shard` or `merge` when `argv[1]` names one (`exit_on_error`: clap
/// prints help or the error and exits, as the binary does).
pub(super) fn dispatch(argv: &[OsString], exit_on_error: bool) -> Option<Result<(), String>> {
    let command = argv.get(1)?.to_str()?;
    if !matches!(command, "prepare" | "shard" | "merge") {
        return None;
    }
    let named: Vec<OsString> = std::iter::once(OsString::from(format!("bake {command}")))
        .chain(argv[2..].iter().cloned())
        .collect();
    fn parse<P: Parser>(args: Vec<OsString>, exit: bool) -> Result<P, String> {
        if exit {
            Ok(P::parse_from(args))
        } else {
            P::try_parse_from(args).map_err(|e| e.to_string())
        }
    }
    Some(match command {
        "prepare" => parse::<Args>(named, exit_on_error).and_then(|a| prepare(a, &argv[2..])),
        "shard" => parse::<ShardArgs>(named, exit_on_error).and_then(shard),
        _ => parse::<MergeArgs>(named, exit_on_error).and_then(merge),
    })
}

/// FNV-1a of the document, its buffers and its decoded images (sizes and texels): whatever
/// of the scene's files a shard reads.
fn scene_hash(imported: &lightbake::ImportedScene) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut add = |bytes: &[u8]| {
        for b in bytes {
            h ^= *b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    add(&serde_json::to_vec(&imported.source.json).unwrap_or_default());
    for buffer in &imported.source.buffers {
        add(buffer);
    }
    for t in &imported.scene.textures {
        add(&t.width.to_le_bytes());
        add(&t.height.to_le_bytes());
        add(t.rgba8.as_flattened());
    }
    h
}

/// The flags of a bake command line: without the scene and without `-o`/`--output`.
fn bake_flags(tokens: &[OsString], scene: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut skip = false;
    for t in tokens.iter().map(|t| t.to_string_lossy().into_owned()) {
        if skip {
            skip = false;
            continue;
        }
        if t == "-o" || t == "--output" {
            skip = true;
            continue;
        }
        if t.starts_with("--output=") || (t.starts_with("-o") && t.len() > 2) {
            continue;
        }
        if Path::new(&t) == scene {
            continue;
        }
        out.push(t);
    }
    out
}

fn prepare(args: Args, tokens: &[OsString]) -> Result<(), String> {
    let (settings, imported) = load(&args)?;
    let scene = std::path::absolute(&args.scene).map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&args.output).map_err(|e| format!("{}: {e}", args.output.display()))?;
    let scene_from_work = match (args.scene.canonicalize(), args.output.canonicalize()) {
        (Ok(scene), Ok(work)) => relative(&work, &scene),
        _ => None,
    };
    let work = Work {
        format: WORK_FORMAT.into(),
        flags: bake_flags(tokens, &args.scene),
        scene,
        scene_from_work,
        scene_hash: scene_hash(&imported),
    };
    let text = serde_json::to_vec_pretty(&work).map_err(|e| e.to_string())?;
    let mut staged = lightbake::atomic::StagedFiles::new(&args.output);
    staged
        .stage(&args.output.join(WORK_FILE), &text)
        .map_err(|e| e.to_string())?;
    staged.commit().map_err(|e| e.to_string())?;
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
fn scene_path(work: &Work, work_dir: &Path, chosen: Option<&Path>) -> Result<PathBuf, String> {
    if let Some(path) = chosen {
        return Ok(path.to_path_buf());
    }
    if work.scene.exists() {
        return Ok(work.scene.clone());
    }
    match &work.scene_from_work {
        Some(rel) if work_dir.join(rel).exists() => Ok(work_dir.join(rel)),
        _ => Err(format!(
            "{}: no such file here{}: give its path on this machine with --scene",
            work.scene.display(),
            work.scene_from_work
                .as_ref()
                .map(|rel| format!(", nor at {}", work_dir.join(rel).display()))
                .unwrap_or_default()
        )),
    }
}

/// The bake `work.json` describes, with `threads` threads, reading the scene from `scene`
/// when given.
fn reload(
    work_dir: &Path,
    threads: usize,
    scene: Option<&Path>,
) -> Result<(lightbake::BakeSettings, lightbake::ImportedScene), String> {
    let path = work_dir.join(WORK_FILE);
    let text = lightbake::scene::resources::read_regular_file(&path, 1 << 20).map_err(|e| {
        format!(
            "{}: {e} (run `bake prepare SCENE -o {}` first)",
            path.display(),
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
        ));
    }
    let scene = scene_path(&work, work_dir, scene)?;
    let mut tokens = vec![
        "bake".to_string(),
        scene.to_string_lossy().into_owned(),
        "-o".into(),
        work_dir.to_string_lossy().into_owned(),
    ];
    tokens.extend(work.flags);
    let mut args = Args::try_parse_from(tokens).map_err(|e| format!("{}: {e}", path.display()))?;
    args.threads = threads;
    let (settings, imported) = load(&args)?;
    if scene_hash(&imported) != work.scene_hash {
        return Err(format!(
            "{} changed since `bake prepare`: prepare again",
            scene.display()
        ));
    }
    Ok((settings, imported))
}

/// Runs the bake in `role`; `None` when the process did its part and stopped there.
fn run_role(
    imported: &lightbake::ImportedScene,
    settings: &lightbake::BakeSettings,
    work: &Path,
    role: Role,
) -> Result<Option<lightbake::BakeOutput>, String> {
    let run = ShardRun::new(work, role);
    let progress = Progress::new();
    match lightbake::bake::bake_split(&imported.scene, settings, &progress, &run) {
        Ok(out) => Ok(Some(out)),
        Err(BakeError::ShardPartDone { done }) => {
            println!("{done}");
            Ok(None)
        }
        Err(e) => Err(e.to_string()),
    }
}

fn shard(args: ShardArgs) -> Result<(), String> {
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
        ));
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

fn merge(args: MergeArgs) -> Result<(), String> {
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
