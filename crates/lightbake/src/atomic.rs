//! Writing a set of files so that readers see the old set or the new one.
//!
//! Every file of a set is first written in full into a *staging folder*: a private folder
//! (mode 0700, a random name, created exclusively by `tempfile`) in the system temporary
//! directory when that is on the destination's file system, else beside the destination
//! folder. Files in it are created exclusively (`O_EXCL`), so nothing planted there in
//! advance (a link to a file elsewhere) is ever written through. A game watching its assets
//! folder (Bevy's `file_watcher`) then sees only the final renames (`IN_MOVED_TO` → a
//! reload), never a temporary name.
//!
//! [`StagedFiles::commit`] first writes a journal into the staging folder — the list of
//! renames — and renames it into place there: that rename is the instant the new set is
//! committed. Then every file is renamed over its destination (each rename replaces one file
//! atomically), and the staging folder is removed. A bake that fails or is killed before the
//! journal is in place leaves every old file as it was. One killed while renaming leaves a
//! committed journal behind: [`recover`] (which every commit and every `bake` into the folder
//! runs first) finishes its renames, so the folder holds the whole new set; a rename that
//! fails in a live process puts the old files back instead.

use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{BakeError, Result};

/// Prefix of every staging folder's name.
const STAGE_PREFIX: &str = ".lightbake-stage-";

/// The journal that commits a staging folder's renames.
const JOURNAL: &str = "commit.json";

/// The file naming the process that owns a staging folder.
const OWNER: &str = "owner";

/// Files written into a staging folder, waiting to be renamed into place under `root`.
#[derive(Debug)]
pub struct StagedFiles {
    root: PathBuf,
    stage: Option<tempfile::TempDir>,
    staged: Vec<(PathBuf, PathBuf)>,
}

/// A committed set of renames: staged file name → destination (absolute).
#[derive(Debug, Serialize, Deserialize)]
struct Journal {
    root: PathBuf,
    renames: Vec<(String, PathBuf)>,
}

fn write_err(path: &Path) -> impl FnOnce(std::io::Error) -> BakeError + '_ {
    move |source| BakeError::Write {
        path: path.to_path_buf(),
        source,
    }
}

/// `path` with `.` steps and inner `..` steps resolved lexically, absolute.
pub(crate) fn normalized(path: &Path) -> std::io::Result<PathBuf> {
    let abs = std::path::absolute(path)?;
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    Ok(out)
}

impl StagedFiles {
    /// No files yet; every file staged must lie under the folder `root`.
    pub fn new(root: &Path) -> Self {
        Self {
            root: normalized(root).unwrap_or_else(|_| root.to_path_buf()),
            stage: None,
            staged: Vec::new(),
        }
    }

    /// The staging folder, made on first use (after finishing any interrupted commit into
    /// `root`).
    fn stage_dir(&mut self) -> Result<&Path> {
        if self.stage.is_none() {
            std::fs::create_dir_all(&self.root).map_err(write_err(&self.root))?;
            recover(&self.root)?;
            let system = std::env::temp_dir();
            let parent = self
                .root
                .parent()
                .map_or_else(|| self.root.clone(), Path::to_path_buf);
            let place = if same_file_system(&system, &self.root) {
                system
            } else {
                parent
            };
            let dir = tempfile::Builder::new()
                .prefix(STAGE_PREFIX)
                .tempdir_in(&place)
                .map_err(write_err(&place))?;
            let owner = dir.path().join(OWNER);
            create_new(&owner, std::process::id().to_string().as_bytes())
                .map_err(write_err(&owner))?;
            self.stage = Some(dir);
        }
        Ok(self.stage.as_ref().expect("made above").path())
    }

    /// Writes `bytes` to a new file in the staging folder, destined for `path` (under the
    /// root; its folder is made at the commit).
    ///
    /// # Errors
    /// [`BakeError::Write`] naming the destination (also when it lies outside the root).
    pub fn stage(&mut self, path: &Path, bytes: &[u8]) -> Result<()> {
        let dest = normalized(path).map_err(write_err(path))?;
        if !dest.starts_with(&self.root) || dest == self.root {
            return Err(write_err(path)(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("it lies outside the output folder {}", self.root.display()),
            )));
        }
        let name = self.staged.len().to_string();
        let file = self.stage_dir()?.join(&name);
        create_new(&file, bytes).map_err(write_err(path))?;
        self.staged.push((file, dest));
        Ok(())
    }

    /// Destinations staged so far (absolute).
    pub fn destinations(&self) -> impl Iterator<Item = &Path> {
        self.staged.iter().map(|(_, d)| d.as_path())
    }

    /// Commits the set: the journal first, then every file renamed into place. A failure
    /// before the journal changes nothing; a rename that fails after it puts the old files
    /// back.
    ///
    /// # Errors
    /// [`BakeError::Write`] naming the destination that could not be replaced (the folder
    /// is then as it was before).
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        let staged = std::mem::take(&mut self.staged);
        let Some(stage) = self.stage.take() else {
            return Ok(Vec::new());
        };
        // 1. Refuse early what a rename cannot replace.
        for (_, dest) in &staged {
            if dest.is_dir() {
                return Err(write_err(dest)(std::io::Error::new(
                    std::io::ErrorKind::IsADirectory,
                    "a directory is in the way",
                )));
            }
            if let Some(dir) = dest.parent() {
                std::fs::create_dir_all(dir).map_err(write_err(dir))?;
            }
        }
        // 2. The journal, renamed into place: the set is committed.
        let journal = Journal {
            root: self.root.clone(),
            renames: staged
                .iter()
                .map(|(file, dest)| {
                    let name = file.file_name().unwrap_or_default().to_string_lossy();
                    (name.into_owned(), dest.clone())
                })
                .collect(),
        };
        let text = serde_json::to_vec(&journal).map_err(|e| BakeError::Internal {
            message: format!("the commit journal cannot be written: {e}"),
        })?;
        let pending = stage.path().join("journal.tmp");
        create_new(&pending, &text).map_err(write_err(&pending))?;
        std::fs::rename(&pending, stage.path().join(JOURNAL)).map_err(write_err(&pending))?;
        // 3. Keep each old file (a hard link in the staging folder) until every rename is done.
        let mut aside: Vec<(PathBuf, PathBuf)> = Vec::new();
        for (k, (_, dest)) in staged.iter().enumerate() {
            if dest.is_file() {
                let old = stage.path().join(format!("old-{k}"));
                if std::fs::hard_link(dest, &old).is_ok() {
                    aside.push((dest.clone(), old));
                }
            }
        }
        // 4. Rename the new files in.
        let mut placed: Vec<PathBuf> = Vec::new();
        for (file, dest) in &staged {
            if let Err(e) = rename_or_copy(file, dest) {
                restore(&aside, &placed);
                let _ = std::fs::remove_file(stage.path().join(JOURNAL));
                return Err(write_err(dest)(e));
            }
            placed.push(dest.clone());
        }
        // 5. Done: the staging folder (the journal, the old copies) goes.
        drop(stage);
        Ok(placed)
    }
}

/// Creates `path` exclusively (never through an existing file or link) with `bytes`, synced.
fn create_new(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut f = std::fs::File::options()
        .write(true)
        .create_new(true)
        .open(path)?;
    f.write_all(bytes)?;
    f.sync_all()
}

/// Finishes or discards the staging folders left by killed bakes where bakes into `root`
/// stage (the system temporary folder, and beside `root`): a committed one (its journal in
/// place) has its remaining renames done, an uncommitted one is removed, once its process is
/// gone. Staging folders of live bakes are left alone.
///
/// # Errors
/// [`BakeError::Write`] when a committed rename cannot be finished.
pub fn recover(root: &Path) -> Result<()> {
    let root = normalized(root).map_err(write_err(root))?;
    let mut places = vec![std::env::temp_dir()];
    if let Some(parent) = root.parent() {
        places.push(parent.to_path_buf());
    }
    for place in places {
        let Ok(entries) = std::fs::read_dir(&place) else {
            continue;
        };
        for entry in entries.flatten() {
            let name = entry.file_name();
            if !name.to_string_lossy().starts_with(STAGE_PREFIX) {
                continue;
            }
            let dir = entry.path();
            let Ok(meta) = std::fs::symlink_metadata(&dir) else {
                continue;
            };
            if !meta.is_dir() || is_alive(&dir, &meta) {
                continue;
            }
            let journal: Option<Journal> = std::fs::read(dir.join(JOURNAL))
                .ok()
                .and_then(|t| serde_json::from_slice(&t).ok());
            // A committed journal is finished whichever folder it is for (its files are
            // complete, and its renames stay inside its own root).
            if let Some(j) = journal {
                for (name, dest) in &j.renames {
                    let file = dir.join(name);
                    if file.exists() && dest.starts_with(&j.root) {
                        rename_or_copy(&file, dest).map_err(write_err(dest))?;
                    }
                }
            }
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    Ok(())
}

/// Whether the staging folder `dir` may belong to a bake still running: its owner's process
/// exists (where `/proc` tells), or it is younger than ten minutes (a bake on another machine
/// writing to a shared folder), or, without `/proc`, younger than a day.
fn is_alive(dir: &Path, meta: &std::fs::Metadata) -> bool {
    let age = meta
        .modified()
        .ok()
        .and_then(|m| m.elapsed().ok())
        .unwrap_or_default();
    let pid: Option<u32> = std::fs::read_to_string(dir.join(OWNER))
        .ok()
        .and_then(|t| t.trim().parse().ok());
    if pid == Some(std::process::id()) || age < std::time::Duration::from_secs(600) {
        return true;
    }
    let proc = Path::new("/proc");
    if proc.join("self").exists() {
        return pid.is_some_and(|p| proc.join(p.to_string()).exists());
    }
    age < std::time::Duration::from_secs(24 * 3600)
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
    }
}

/// Rename, falling back to copy-then-rename within the destination's folder when the staging
/// folder is on another file system after all.
fn rename_or_copy(from: &Path, dest: &Path) -> std::io::Result<()> {
    match std::fs::rename(from, dest) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::CrossesDevices => {
            let dir = dest.parent().unwrap_or(Path::new("."));
            let local = tempfile::Builder::new()
                .prefix(STAGE_PREFIX)
                .tempfile_in(dir)?;
            let mut src = std::fs::File::open(from)?;
            std::io::copy(&mut src, &mut local.as_file())?;
            local.as_file().sync_all()?;
            local.persist(dest).map_err(|e| e.error)?;
            std::fs::remove_file(from)
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

    /// Names in `dir` that are ours (staging folders).
    fn ours(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(STAGE_PREFIX))
            .collect()
    }

    #[test]
    fn nothing_changes_until_commit_and_drop_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.txt");
        std::fs::write(&a, b"old").unwrap();
        let staging;
        {
            let mut s = StagedFiles::new(dir.path());
            s.stage(&a, b"new").unwrap();
            s.stage(&dir.path().join("sub/b.txt"), b"b").unwrap();
            staging = s.stage.as_ref().unwrap().path().to_path_buf();
            assert!(staging.is_dir());
            assert_eq!(std::fs::read(&a).unwrap(), b"old");
            // dropped without commit
        }
        assert!(!staging.exists());
        assert_eq!(std::fs::read(&a).unwrap(), b"old");
        assert!(!dir.path().join("sub/b.txt").exists());
        let mut s = StagedFiles::new(dir.path());
        s.stage(&a, b"new").unwrap();
        let written = s.commit().unwrap();
        assert_eq!(written, vec![normalized(&a).unwrap()]);
        assert_eq!(std::fs::read(&a).unwrap(), b"new");
        assert!(ours(dir.path()).is_empty());
    }

    #[test]
    fn a_failing_rename_rolls_back_every_file() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a"),
            dir.path().join("b"),
            dir.path().join("c/d"),
        );
        std::fs::write(&a, b"old a").unwrap();
        std::fs::write(&b, b"old b").unwrap();
        let mut s = StagedFiles::new(dir.path());
        s.stage(&a, b"new a").unwrap();
        s.stage(&b, b"new b").unwrap();
        s.stage(&c, b"new c").unwrap();
        // Make the last rename fail: a non-empty directory where `c/d` goes.
        std::fs::create_dir_all(c.join("x")).unwrap();
        assert!(s.commit().is_err());
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert!(c.is_dir());
    }

    #[test]
    fn a_commit_killed_while_renaming_is_finished_by_the_next() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir_all(&out).unwrap();
        for f in ["a", "b", "c"] {
            std::fs::write(out.join(f), b"old").unwrap();
        }
        // A dead bake's staging folder beside the output: journal written, one of three
        // files renamed.
        let stage = dir.path().join(format!("{STAGE_PREFIX}dead"));
        std::fs::create_dir_all(&stage).unwrap();
        std::fs::write(stage.join(OWNER), (u32::MAX - 1).to_string()).unwrap();
        for (k, f) in ["a", "b", "c"].iter().enumerate() {
            std::fs::write(stage.join(k.to_string()), format!("new {f}")).unwrap();
        }
        let root = normalized(&out).unwrap();
        let journal = Journal {
            root: root.clone(),
            renames: ["a", "b", "c"]
                .iter()
                .enumerate()
                .map(|(k, f)| (k.to_string(), root.join(f)))
                .collect(),
        };
        std::fs::write(stage.join(JOURNAL), serde_json::to_vec(&journal).unwrap()).unwrap();
        std::fs::rename(stage.join("0"), out.join("a")).unwrap();
        // An uncommitted staging folder of a dead bake, and one of a live bake.
        let dead = dir.path().join(format!("{STAGE_PREFIX}uncommitted"));
        std::fs::create_dir_all(&dead).unwrap();
        std::fs::write(dead.join(OWNER), (u32::MAX - 1).to_string()).unwrap();
        let live = dir.path().join(format!("{STAGE_PREFIX}live"));
        std::fs::create_dir_all(&live).unwrap();
        std::fs::write(live.join(OWNER), std::process::id().to_string()).unwrap();
        let two_hours_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7200);
        for d in [&stage, &dead, &live] {
            std::fs::File::open(d)
                .unwrap()
                .set_modified(two_hours_ago)
                .unwrap();
        }
        recover(&out).unwrap();
        for f in ["a", "b", "c"] {
            assert_eq!(
                std::fs::read_to_string(out.join(f)).unwrap(),
                format!("new {f}")
            );
        }
        assert!(!stage.exists());
        assert_eq!(!dead.exists(), Path::new("/proc/self").exists());
        assert!(live.exists());
    }

    #[cfg(unix)]
    #[test]
    fn files_outside_the_root_and_planted_names_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let mut s = StagedFiles::new(&out);
        assert!(s.stage(&dir.path().join("x"), b"y").is_err());
        assert!(s.stage(&out.join("../x"), b"y").is_err());
        s.stage(&out.join("ok"), b"y").unwrap();
        // A file planted under the next staged name is not written through.
        let stage = s.stage.as_ref().unwrap().path().to_path_buf();
        std::os::unix::fs::symlink(dir.path().join("victim"), stage.join("1")).unwrap();
        assert!(s.stage(&out.join("next"), b"z").is_err());
        assert!(!dir.path().join("victim").exists());
    }

    #[test]
    fn unwritable_destination_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, b"x").unwrap();
        let mut s = StagedFiles::new(dir.path());
        s.stage(&blocker.join("inside.txt"), b"y").unwrap();
        let err = s.commit().unwrap_err();
        assert!(err.to_string().contains("file"), "{err}");
    }
}
