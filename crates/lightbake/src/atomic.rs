//! Writing files so that nothing already written is lost.
//!
//! Every output is first written in full to a temporary file, then all of them are renamed
//! into place together ([`StagedFiles::commit`]). A bake that fails or is cancelled before the
//! commit leaves the previous outputs untouched; a reader never sees a half-written file.
//!
//! Temporary files go to the system temporary directory when it is on the same file system
//! as the destination, so a game watching its assets folder (Bevy's `file_watcher`) only sees
//! the final rename (`IN_MOVED_TO` → a reload), never the temporary name; otherwise they are
//! written next to the destination under a hidden name.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{BakeError, Result};

/// Files written to temporary names, waiting to be renamed into place.
#[derive(Debug, Default)]
pub struct StagedFiles {
    staged: Vec<(PathBuf, PathBuf)>,
}

fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> BakeError + '_ {
    move |source| BakeError::Write {
        path: path.to_path_buf(),
        source,
    }
}

fn unique_suffix() -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    format!(
        "{}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

impl StagedFiles {
    /// No files yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `bytes` to a temporary file destined for `path`. The directory of `path` is
    /// created if needed.
    ///
    /// # Errors
    /// [`BakeError::Write`] naming the destination.
    pub fn stage(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        let dir = path.parent().unwrap_or(Path::new("."));
        std::fs::create_dir_all(dir).map_err(write_err(dir))?;
        let name = path
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
        let suffix = unique_suffix();
        // Prefer the system temp dir (outside any watched folder), if a rename can reach.
        let system_tmp = std::env::temp_dir().join(format!(".lightbake-{suffix}-{name}"));
        let tmp = if same_file_system(&std::env::temp_dir(), dir) {
            system_tmp
        } else {
            dir.join(format!(".{name}.lightbake-{suffix}.tmp"))
        };
        let result = (|| -> std::io::Result<()> {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = result {
            let _ = std::fs::remove_file(&tmp);
            return Err(write_err(path)(e));
        }
        self.staged.push((tmp, path.to_path_buf()));
        Ok(())
    }

    /// Destinations staged so far.
    pub fn destinations(&self) -> impl Iterator<Item = &Path> {
        self.staged.iter().map(|(_, d)| d.as_path())
    }

    /// Renames every staged file into place, all or nothing: each existing destination is
    /// first linked (or copied) to a hidden name beside it, then the new files are renamed
    /// over the destinations; if any step fails, the old files are renamed back. The kept
    /// copies are deleted at the end.
    ///
    /// Every rename replaces its destination atomically, so at every instant, even if the
    /// process is killed, each destination holds either its complete old file or its
    /// complete new one. (A kill inside the rename loop can leave some files new and some
    /// old; hidden `.NAME.lightbake-old-*` copies left by a killed commit are removed by the
    /// next commit to the same directory, and so are the temporaries of killed bakes, there
    /// and in the system temp directory, once their process is gone.)
    ///
    /// # Errors
    /// [`BakeError::Write`] naming the destination that could not be replaced (the directory
    /// is then as it was before).
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let staged = std::mem::take(&mut self.staged);
        // 1. Refuse early what a rename cannot replace.
        for (_, dest) in &staged {
            if dest.is_dir() {
                let e = std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way",
                );
                for (t, _) in &staged {
                    let _ = std::fs::remove_file(t);
                }
                return Err(write_err(dest)(e));
            }
        }
        // 2. Keep a copy of each existing file (a hard link: the destination stays in place).
        let mut aside: Vec<(PathBuf, PathBuf)> = Vec::new();
        for (_, dest) in &staged {
            remove_stale_copies(dest);
            if dest.exists() {
                let name = dest
                    .file_name()
                    .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
                let old = dest.with_file_name(format!(".{name}.lightbake-old-{}", unique_suffix()));
                let kept = std::fs::hard_link(dest, &old)
                    .or_else(|_| std::fs::copy(dest, &old).map(|_| ()));
                if let Err(e) = kept {
                    restore(&aside, &[]);
                    for (t, _) in &staged {
                        let _ = std::fs::remove_file(t);
                    }
                    return Err(write_err(dest)(e));
                }
                aside.push((dest.clone(), old));
            }
        }
        // 3. Rename the new files in.
        let mut placed: Vec<PathBuf> = Vec::new();
        for (i, (tmp, dest)) in staged.iter().enumerate() {
            if let Err(e) = rename_or_copy(tmp, dest) {
                for (t, _) in &staged[i..] {
                    let _ = std::fs::remove_file(t);
                }
                restore(&aside, &placed);
                return Err(write_err(dest)(e));
            }
            placed.push(dest.clone());
        }
        // 4. Drop the old copies, and temporaries that killed bakes left behind.
        for (_, old) in aside {
            let _ = std::fs::remove_file(old);
        }
        let mut dirs: Vec<PathBuf> = vec![std::env::temp_dir()];
        for dest in &placed {
            let dir = dest.parent().unwrap_or(Path::new("."));
            if !dirs.iter().any(|d| d == dir) {
                dirs.push(dir.to_path_buf());
            }
        }
        for dir in dirs {
            sweep_orphans(&dir);
        }
        Ok(placed)
    }
}

/// The process that made temporary `name` (`.lightbake-PID-N-NAME` in the system temp
/// directory, `.NAME.lightbake-PID-N.tmp` or `.lightbake-PID-N.tmp` beside an output), if it
/// is one of ours.
fn temp_owner(name: &str) -> Option<u32> {
    let rest = if let Some(rest) = name.strip_prefix(".lightbake-") {
        rest
    } else if name.starts_with('.') && name.ends_with(".tmp") {
        &name[name.rfind(".lightbake-")? + ".lightbake-".len()..]
    } else {
        return None;
    };
    let (pid, rest) = rest.split_once('-')?;
    // The counter follows: digits, then `-NAME` or `.tmp`.
    let counter_end = rest.find(|c: char| !c.is_ascii_digit())?;
    (counter_end > 0).then_some(())?;
    pid.parse().ok()
}

/// Whether the temporary owned by process `pid` and last modified `age` ago may belong to a
/// bake still running. It is taken as dead only when it is over ten minutes old and its
/// process is gone (where `/proc` tells; a bake on another machine writing to a shared folder
/// is protected by the age), or, without `/proc`, when it is over a day old.
fn maybe_running(pid: u32, age: std::time::Duration) -> bool {
    if pid == std::process::id() || age < std::time::Duration::from_secs(600) {
        return true;
    }
    let proc = Path::new("/proc");
    if proc.join("self").exists() {
        return proc.join(pid.to_string()).exists();
    }
    age < std::time::Duration::from_secs(24 * 3600)
}

/// Removes the temporaries in `dir` whose bake was killed before it could delete them (see
/// [`temp_owner`] and [`maybe_running`]).
fn sweep_orphans(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = temp_owner(&name.to_string_lossy()) else {
            continue;
        };
        let Ok(meta) = entry.metadata() else {
            continue;
        };
        let age = meta
            .modified()
            .ok()
            .and_then(|m| m.elapsed().ok())
            .unwrap_or_default();
        if meta.is_file() && !maybe_running(pid, age) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Undoes a partial commit: puts the old files back over the new ones (atomically) and
/// removes new files that had no old version.
fn restore(aside: &[(PathBuf, PathBuf)], placed: &[PathBuf]) {
    for p in placed {
        if !aside.iter().any(|(dest, _)| dest == p) {
            let _ = std::fs::remove_file(p);
        }
    }
    for (dest, old) in aside {
        let _ = std::fs::rename(old, dest);
        // A rename between two links of one file does nothing (POSIX): the destination was
        // never replaced, and the copy is dropped here.
        let _ = std::fs::remove_file(old);
    }
}

/// Removes hidden copies of `dest` kept by an earlier commit that was killed before it could
/// delete them (`.NAME.lightbake-old-*` beside it).
fn remove_stale_copies(dest: &Path) {
    let (Some(dir), Some(name)) = (dest.parent(), dest.file_name()) else {
        return;
    };
    let prefix = format!(".{}.lightbake-old-", name.to_string_lossy());
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        if entry.file_name().to_string_lossy().starts_with(&prefix) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

impl Drop for StagedFiles {
    /// Uncommitted temporaries are removed (a failed or cancelled bake leaves nothing behind).
    fn drop(&mut self) {
        for (tmp, _) in self.staged.drain(..) {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Rename, falling back to copy-then-rename within the destination directory when the
/// temporary is on another file system after all.
fn rename_or_copy(tmp: &Path, dest: &Path) -> std::io::Result<()> {
    match std::fs::rename(tmp, dest) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::CrossesDevices => {
            let dir = dest.parent().unwrap_or(Path::new("."));
            let local = dir.join(format!(".lightbake-{}.tmp", unique_suffix()));
            std::fs::copy(tmp, &local)?;
            std::fs::remove_file(tmp)?;
            std::fs::rename(&local, dest)
        }
        Err(e) => Err(e),
    }
}

#[cfg(unix)]
fn same_file_system(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file_system(_a: &Path, _b: &Path) -> bool {
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporaries_of_dead_bakes_are_swept_and_live_ones_kept() {
        assert_eq!(temp_owner(".lightbake-123-4-lightmap_0.exr"), Some(123));
        assert_eq!(temp_owner(".scene.gltf.lightbake-77-0.tmp"), Some(77));
        assert_eq!(temp_owner(".lightbake-9-12.tmp"), Some(9));
        assert_eq!(temp_owner(".scene.gltf.lightbake-old-77-0"), None);
        assert_eq!(temp_owner("lightbake-1-2-x"), None);
        assert_eq!(temp_owner("notes.tmp"), None);
        let dir = std::env::temp_dir().join(format!("lightbake-sweep-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // No process has this id (Linux's pid_max is at most 2²²).
        let dead = u32::MAX - 1;
        let me = std::process::id();
        let files = [
            (format!(".out.exr.lightbake-{dead}-0.tmp"), false),
            (format!(".lightbake-{dead}-3-out.exr"), false),
            (format!(".out.exr.lightbake-{me}-0.tmp"), true),
            ("keep.tmp".to_string(), true),
        ];
        let two_hours_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7200);
        for (name, _) in &files {
            std::fs::write(dir.join(name), b"x").unwrap();
            let f = std::fs::File::options()
                .write(true)
                .open(dir.join(name))
                .unwrap();
            f.set_modified(two_hours_ago).unwrap();
        }
        // A fresh temporary of a dead process may be a bake on another machine: kept.
        let fresh = format!(".lightbake-{}-5-out.exr", u32::MAX - 1);
        std::fs::write(dir.join(&fresh), b"x").unwrap();
        let mut staged = StagedFiles::new();
        staged.stage(&dir.join("out.exr"), b"new").unwrap();
        staged.commit().unwrap();
        for (name, kept) in &files {
            // Without /proc only day-old files count as dead.
            let expect = *kept || !Path::new("/proc/self").exists();
            assert_eq!(dir.join(name).exists(), expect, "{name}");
        }
        assert!(dir.join(&fresh).exists());
        assert_eq!(std::fs::read(dir.join("out.exr")).unwrap(), b"new");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn nothing_changes_until_commit_and_drop_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.txt");
        std::fs::write(&a, b"old").unwrap();
        {
            let mut s = StagedFiles::new();
            s.stage(&a, b"new").unwrap();
            s.stage(&dir.path().join("sub/b.txt"), b"b").unwrap();
            assert_eq!(std::fs::read(&a).unwrap(), b"old");
            // dropped without commit
        }
        assert_eq!(std::fs::read(&a).unwrap(), b"old");
        assert!(!dir.path().join("sub/b.txt").exists());
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains("lightbake"))
            .collect();
        assert!(leftovers.is_empty());

        let mut s = StagedFiles::new();
        s.stage(&a, b"new").unwrap();
        let written = s.commit().unwrap();
        assert_eq!(written, vec![a.clone()]);
        assert_eq!(std::fs::read(&a).unwrap(), b"new");
        // No set-aside copies are left behind.
        assert!(std::fs::read_dir(dir.path()).unwrap().all(|e| {
            !e.unwrap()
                .file_name()
                .to_string_lossy()
                .contains("lightbake")
        }));
    }

    #[test]
    fn a_failing_rename_rolls_back_every_file() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a"),
            dir.path().join("b"),
            dir.path().join("c"),
        );
        std::fs::write(&a, b"old a").unwrap();
        std::fs::write(&b, b"old b").unwrap();
        let mut s = StagedFiles::new();
        s.stage(&a, b"new a").unwrap();
        s.stage(&b, b"new b").unwrap();
        s.stage(&c, b"new c").unwrap();
        // Make the last rename fail: a non-empty directory where `c` goes.
        std::fs::create_dir(&c).unwrap();
        std::fs::write(c.join("x"), b"").unwrap();
        assert!(s.commit().is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert!(c.is_dir());
        let names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names.len(), 3, "{names:?}");
    }

    #[test]
    fn unwritable_destination_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, b"x").unwrap();
        let mut s = StagedFiles::new();
        let err = s.stage(&blocker.join("inside.txt"), b"y").unwrap_err();
        assert!(err.to_string().contains("file"), "{err}");
    }
}
