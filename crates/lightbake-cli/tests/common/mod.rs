//! Helpers shared by the CLI's integration tests: run `bake`, find the shipped assets, read
//! an output folder.

#![allow(dead_code)] // each test binary uses its own share of them

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bake"))
        .args(args)
        .output()
        .expect("run bake")
}

pub fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets")
        .join(name)
}

pub fn stderr_line(out: &Output) -> String {
    let text = String::from_utf8_lossy(&out.stderr).into_owned();
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "expected one error line, got: {text}");
    errors[0].to_string()
}

/// Every visible file under `dir` (hidden temporaries and kept copies excluded), by relative
/// path, with its bytes.
pub fn files(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap().flatten() {
            let path = entry.path();
            if entry.file_name().to_string_lossy().starts_with('.') {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(rel, std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

/// Every output file of a bake, by name relative to `dir` (the report aside: its times
/// differ from run to run; and the cache a bake in one process keeps for the next bake into
/// the folder, which a split bake's merge does not write).
pub fn outputs(dir: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = files(dir);
    out.retain(|p, _| {
        p.file_name()
            .is_some_and(|n| n != "report.json" && n != "lightbake.cache")
    });
    out
}

pub fn run_ok(args: &[&str]) -> String {
    let out = bake(args);
    assert!(
        out.status.success(),
        "bake {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}
