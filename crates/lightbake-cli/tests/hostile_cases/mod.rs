//! The hostile-input suite's harness: each case is a folder of files (a glTF and what it
//! names) baked by the `bake` binary in a sandbox that also holds a secret file outside the
//! scene's folder; the outcome is classified and the outputs are searched for the secret.
//!
//! Every case must *behave*: bake (exit 0) or be refused in one line (`error: …`, exit 1);
//! never panic (exit 101), abort (a signal, an allocation failure), hang (no answer within
//! the case's time limit) or run past the address-space cap; and no byte of the secret may
//! reach any file the bake writes.
//!
//! `LIGHTBAKE_HOSTILE_BIN` runs the suite against another `bake` binary (to compare builds).

#![allow(dead_code)] // the small and the large suite each use their share

pub mod cases;
pub mod gltf;
pub mod outputs;
pub mod split;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The secret planted outside every scene's folder; no output may contain it.
pub const SECRET: &str = "LIGHTBAKE-HOSTILE-SECRET-5d1c2b7e";

/// Address-space cap of every bake, KiB (6 GiB).
pub const MEMORY_CAP_KIB: u64 = 6 * 1024 * 1024;

/// What a case expects.
#[derive(Clone, Debug)]
pub enum Expect {
    /// A clean bake (exit 0).
    Bake,
    /// A one-line refusal whose message contains this text.
    Refuse(&'static str),
    /// Either a bake or a one-line refusal.
    Either,
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Exit 0.
    Baked,
    /// Exit 1 (or 2, a bad command line) with one `error:` line.
    Refused(String),
    /// A Rust panic (exit 101).
    Panic(String),
    /// Killed by a signal or an allocation failure.
    Abort(String),
    /// No answer within the time limit.
    Hang(f64),
    /// Anything else (several error lines, another exit code).
    Other(String),
}

impl Outcome {
    /// A bake or a one-line refusal.
    pub fn behaved(&self) -> bool {
        matches!(self, Self::Baked | Self::Refused(_))
    }

    /// One word for the tables.
    pub fn word(&self) -> &'static str {
        match self {
            Self::Baked => "baked",
            Self::Refused(_) => "refused",
            Self::Panic(_) => "PANIC",
            Self::Abort(_) => "ABORT",
            Self::Hang(_) => "HANG",
            Self::Other(_) => "OTHER",
        }
    }
}

/// Files and a command for one case.
pub struct Case {
    /// Short name.
    pub name: String,
    /// Files written into the scene folder (relative path, bytes).
    pub files: Vec<(String, Vec<u8>)>,
    /// Symbolic links made in the scene folder (link, target; `{secret}` in the target is
    /// the secret folder, `{root}` the sandbox).
    pub links: Vec<(String, String)>,
    /// FIFOs made in the scene folder.
    pub fifos: Vec<String>,
    /// The command after the program name; `{scene}` is the scene folder, `{out}` the
    /// output folder, `{secret}` the secret folder, `{root}` the sandbox.
    pub args: Vec<String>,
    /// What must happen.
    pub expect: Expect,
    /// Seconds before the run counts as a hang.
    pub timeout: f64,
    /// Commands run before the case's own (a `bake prepare`, say), each expected to exit 0.
    pub before: Vec<Vec<String>>,
    /// Edits applied to files after `before` ran (path under the sandbox, new bytes from
    /// the old).
    pub edits: Vec<(String, Edit)>,
    /// Commands run after a clean bake, each expected to exit 0 (baking the output again).
    pub after: Vec<Vec<String>>,
    /// Checks of the sandbox after a clean bake.
    pub checks: Vec<Check>,
}

/// A check of the sandbox after a clean bake.
pub type Check = fn(&Path) -> Result<(), String>;

/// A change to a file written by an earlier command.
pub type Edit = fn(Vec<u8>) -> Vec<u8>;

impl Case {
    /// A case baking `scene.gltf` (or the first file) at preview with one thread.
    pub fn bake(name: &str, files: Vec<(String, Vec<u8>)>, expect: Expect) -> Self {
        let scene = files
            .first()
            .map_or_else(|| "scene.gltf".to_string(), |f| f.0.clone());
        Self {
            name: name.to_string(),
            files,
            links: Vec::new(),
            fifos: Vec::new(),
            args: vec![
                format!("{{scene}}/{scene}"),
                "-o".into(),
                "{out}".into(),
                "--quality".into(),
                "preview".into(),
                "--threads".into(),
                "1".into(),
                "--texel-density".into(),
                "8".into(),
                "--quiet".into(),
            ],
            expect,
            timeout: 60.0,
            before: Vec::new(),
            edits: Vec::new(),
            after: Vec::new(),
            checks: Vec::new(),
        }
    }

    /// The same case expecting `expect`.
    pub fn expecting(mut self, expect: Expect) -> Self {
        self.expect = expect;
        self
    }

    /// The same case with more arguments; a flag given again replaces the flag and value
    /// already there.
    pub fn with_args(mut self, extra: &[&str]) -> Self {
        let mut i = 0;
        while i < extra.len() {
            let flag = extra[i];
            let value = extra.get(i + 1).filter(|v| !v.starts_with("--"));
            if let Some(at) = self.args.iter().position(|a| a == flag) {
                self.args.remove(at);
                if value.is_some() && at < self.args.len() && !self.args[at].starts_with("--") {
                    self.args.remove(at);
                }
            }
            self.args.push(flag.to_string());
            if let Some(v) = value {
                self.args.push(v.to_string());
                i += 1;
            }
            i += 1;
        }
        self
    }
}

/// The `bake` binary under test.
pub fn binary() -> PathBuf {
    std::env::var_os("LIGHTBAKE_HOSTILE_BIN")
        .map_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_bake")), PathBuf::from)
}

/// The sandbox of one case: `root/secret/` (the secret), `root/scene/`, `root/out/`.
pub struct Sandbox {
    _dir: tempfile::TempDir,
    /// The sandbox.
    pub root: PathBuf,
}

impl Sandbox {
    fn new() -> Self {
        let mut dir = tempfile::tempdir().expect("temp dir");
        // LIGHTBAKE_HOSTILE_KEEP=1 keeps every sandbox, to run a case again by hand.
        if std::env::var_os("LIGHTBAKE_HOSTILE_KEEP").is_some() {
            dir.disable_cleanup(true);
            println!("sandbox {}", dir.path().display());
        }
        let root = dir.path().to_path_buf();
        let secret = root.join("secret");
        std::fs::create_dir_all(&secret).unwrap();
        std::fs::write(secret.join("passwd"), format!("root:x:0:0:{SECRET}\n")).unwrap();
        // A valid PNG with the secret after its end: a copy carries it.
        let mut png = gltf::png(2, 2, [200, 100, 50, 255]);
        png.extend_from_slice(SECRET.as_bytes());
        std::fs::write(secret.join("secret.png"), png).unwrap();
        std::fs::create_dir_all(root.join("scene")).unwrap();
        Self { _dir: dir, root }
    }

    fn expand(&self, s: &str) -> String {
        s.replace("{scene}", &self.root.join("scene").to_string_lossy())
            .replace("{out}", &self.root.join("out").to_string_lossy())
            .replace("{secret}", &self.root.join("secret").to_string_lossy())
            .replace("{root}", &self.root.to_string_lossy())
    }
}

/// Runs `bake args` under the memory cap, killed after `timeout` seconds.
fn run(args: &[String], timeout: f64) -> (Outcome, f64) {
    let start = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_CAP_KIB}; exec \"$0\" \"$@\""))
        .arg(binary())
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run bake");
    let stderr = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        use std::io::Read;
        let _ = std::io::BufReader::new(stderr)
            .take(1 << 20)
            .read_to_string(&mut text);
        text
    });
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break Some(status);
        }
        if start.elapsed().as_secs_f64() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let seconds = start.elapsed().as_secs_f64();
    let text = reader.join().unwrap_or_default();
    let Some(status) = status else {
        return (Outcome::Hang(seconds), seconds);
    };
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    let outcome = match status.code() {
        Some(0) => Outcome::Baked,
        Some(101) => Outcome::Panic(first_line(&text)),
        // 1: the bake refused; 2: the command line did (clap's one-line error).
        Some(1 | 2) if errors.len() == 1 && !text.contains("panicked") => {
            Outcome::Refused(errors[0].to_string())
        }
        Some(134) => Outcome::Abort(first_line(&text)),
        None => Outcome::Abort(format!("signal; {}", first_line(&text))),
        Some(c) if text.contains("memory allocation") => {
            Outcome::Abort(format!("exit {c}: {}", first_line(&text)))
        }
        Some(c) => Outcome::Other(format!("exit {c}: {}", last_line(&text))),
    };
    (outcome, seconds)
}

fn first_line(text: &str) -> String {
    text.lines()
        .find(|l| l.contains("panicked") || l.contains("memory") || l.starts_with("error"))
        .or_else(|| text.lines().next())
        .unwrap_or("")
        .chars()
        .take(200)
        .collect()
}

fn last_line(text: &str) -> String {
    text.lines()
        .last()
        .unwrap_or("")
        .chars()
        .take(200)
        .collect()
}

/// Files under `dir` (links not followed) whose bytes contain the secret.
fn leaks(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries.flatten() {
            let Ok(meta) = std::fs::symlink_metadata(entry.path()) else {
                continue;
            };
            if meta.is_dir() {
                stack.push(entry.path());
            } else if meta.is_file()
                && std::fs::read(entry.path())
                    .is_ok_and(|b| b.windows(SECRET.len()).any(|w| w == SECRET.as_bytes()))
            {
                out.push(entry.path());
            }
        }
    }
    out
}

/// The result of one case.
pub struct Report {
    /// The case.
    pub name: String,
    /// How it ended.
    pub outcome: Outcome,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Files that hold the secret.
    pub leaked: Vec<PathBuf>,
    /// What is wrong, if anything.
    pub problem: Option<String>,
    /// The bake's peak resident memory, MiB (from its report).
    pub peak_mib: Option<f64>,
}

/// Runs one case in a fresh sandbox.
pub fn run_case(case: &Case) -> Report {
    let sandbox = Sandbox::new();
    let scene = sandbox.root.join("scene");
    for (path, bytes) in &case.files {
        let p = scene.join(path);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        let bytes = if path.ends_with(".gltf") {
            String::from_utf8(bytes.clone())
                .map_or_else(|_| bytes.clone(), |t| sandbox.expand(&t).into_bytes())
        } else {
            bytes.clone()
        };
        std::fs::write(p, bytes).unwrap();
    }
    for (link, target) in &case.links {
        let p = scene.join(link);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::os::unix::fs::symlink(sandbox.expand(target), p).unwrap();
    }
    for fifo in &case.fifos {
        let status = Command::new("mkfifo")
            .arg(scene.join(fifo))
            .status()
            .expect("mkfifo");
        assert!(status.success());
    }
    for command in &case.before {
        let args: Vec<String> = command.iter().map(|a| sandbox.expand(a)).collect();
        let (outcome, _) = run(&args, 300.0);
        if outcome != Outcome::Baked {
            return Report {
                name: case.name.clone(),
                outcome,
                seconds: 0.0,
                leaked: Vec::new(),
                problem: Some(format!("setup command {args:?} failed")),
                peak_mib: None,
            };
        }
    }
    for (path, edit) in &case.edits {
        let p = PathBuf::from(sandbox.expand(path));
        let bytes = std::fs::read(&p).unwrap_or_default();
        std::fs::write(&p, edit(bytes)).unwrap();
    }
    let inputs_before = snapshot(&scene);
    let args: Vec<String> = case.args.iter().map(|a| sandbox.expand(a)).collect();
    // LIGHTBAKE_HOSTILE_TIMEOUT=S caps every case's time limit (to make sandboxes quickly).
    let timeout = std::env::var("LIGHTBAKE_HOSTILE_TIMEOUT")
        .ok()
        .and_then(|t| t.parse::<f64>().ok())
        .map_or(case.timeout, |t| t.min(case.timeout));
    let (outcome, seconds) = run(&args, timeout);
    let mut leaked = leaks(&sandbox.root);
    leaked.retain(|p| !p.starts_with(sandbox.root.join("secret")));
    let mut problem = match (&case.expect, &outcome) {
        (_, o) if !o.behaved() => Some(format!("{} ({o:?})", o.word())),
        (Expect::Bake, Outcome::Refused(m)) => Some(format!("expected a bake, got: {m}")),
        (Expect::Refuse(_), Outcome::Baked) => Some("expected a refusal, it baked".into()),
        (Expect::Refuse(text), Outcome::Refused(m)) if !m.contains(text) => {
            Some(format!("the refusal does not name '{text}': {m}"))
        }
        _ => None,
    };
    if !leaked.is_empty() {
        problem = Some(format!("the secret is in {leaked:?}"));
    }
    let after = snapshot(&scene);
    let changed = inputs_before
        .iter()
        .any(|(p, b)| !after.iter().any(|(q, c)| p == q && b == c));
    if problem.is_none() && changed {
        problem = Some("an input file in the scene's folder was changed".into());
    }
    if problem.is_none() && outcome == Outcome::Baked {
        for command in &case.after {
            let args: Vec<String> = command.iter().map(|a| sandbox.expand(a)).collect();
            let (again, _) = run(&args, case.timeout);
            if again != Outcome::Baked {
                problem = Some(format!("the output does not bake again: {again:?}"));
            }
        }
        for check in &case.checks {
            if let Err(e) = check(&sandbox.root) {
                problem = Some(e);
            }
        }
    }
    let peak_mib = std::fs::read(sandbox.root.join("out/report.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
        .and_then(|r| r["peak_resident_mib"].as_f64());
    Report {
        name: case.name.clone(),
        outcome,
        seconds,
        leaked,
        problem,
        peak_mib,
    }
}

/// Regular files under `dir` (links not followed) and their bytes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries.flatten() {
            let Ok(meta) = std::fs::symlink_metadata(entry.path()) else {
                continue;
            };
            if meta.is_dir() {
                stack.push(entry.path());
            } else if meta.is_file() {
                out.push((
                    entry.path(),
                    std::fs::read(entry.path()).unwrap_or_default(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// Runs every case (two at a time; `LIGHTBAKE_HOSTILE_ONLY=TEXT`: only those whose name
/// holds TEXT) and prints a table; returns the reports.
pub fn run_all(cases: &[Case]) -> Vec<Report> {
    let only = std::env::var("LIGHTBAKE_HOSTILE_ONLY").unwrap_or_default();
    let cases: Vec<&Case> = cases.iter().filter(|c| c.name.contains(&only)).collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let reports = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(case) = cases.get(i).copied() else {
                        break;
                    };
                    let r = run_case(case);
                    reports.lock().unwrap().push((i, r));
                }
            });
        }
    });
    let mut reports = reports.into_inner().unwrap();
    reports.sort_by_key(|(i, _)| *i);
    let reports: Vec<Report> = reports.into_iter().map(|(_, r)| r).collect();
    println!(
        "{:<44} {:>8} {:>8} {:>9}  detail",
        "case", "outcome", "seconds", "peak MiB"
    );
    for r in &reports {
        let detail = match (&r.problem, &r.outcome) {
            (Some(p), _) => format!("FAIL: {p}"),
            (None, Outcome::Refused(m)) => m.chars().take(150).collect(),
            _ => String::new(),
        };
        println!(
            "{:<44} {:>8} {:>8.2} {:>9}  {detail}",
            r.name,
            r.outcome.word(),
            r.seconds,
            r.peak_mib.map_or("-".into(), |m| format!("{m:.0}"))
        );
    }
    reports
}
