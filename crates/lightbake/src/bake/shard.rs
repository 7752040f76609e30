//! One bake split across processes (machines of a farm, run by any batch engine), with the
//! same bits as one process.
//!
//! Every process runs the same deterministic pipeline. Each derives the lightmap layout from
//! the scene (checked against `prepare`'s by [`layout_hash`]) and reads the texel patches
//! `prepare` wrote after the validity pass ([`PATCHES_FILE`]), and the stages whose work is
//! per texel and heavy — direct light, the hierarchical solve's final gather and its
//! correction — are *split*: each is cut into work units (contiguous runs of texel patches
//! of about equal estimated rays, [`Units`], dealt out to the shards in turn), shard *I* of
//! *N* computes its units and writes their values to `WORK/shards/I/STAGE.bin`, and whoever
//! needs the whole stage (the other shards, for the next split stage; the merge) reads every
//! shard's file. Each value is computed by the same function of its texel and the stages
//! before, so the merged arrays are those of one process, bit for bit; what runs between the
//! split stages (the coarse solve, which needs the direct light of every texel) runs again
//! in each process that needs it.
//!
//! Roles ([`Role`]): *prepare* stops when the patches are known and writes them
//! ([`PATCHES_FILE`]) and the work units ([`UNITS_FILE`]); a *shard* computes its part of
//! each split stage in turn, waiting for the other shards' parts between stages (or, without
//! waiting, computes its part of the first stage it has not done and stops, for engines that
//! run the stages as separate waves); the *merge* reads every part and finishes the bake.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::atomic::StagedFiles;
use crate::error::{BakeError, Result};
use crate::raster::Patches;
pub use crate::report::{ShardPart, SplitStage};
use crate::stage::Stage;
use crate::unwrap::Layout;

mod units;
pub use crate::runner::Record;
pub(in crate::bake) use units::patches_hash;
use units::preparation_id;
pub use units::{BadUnits, UNITS, Units, layout_hash};

/// File of the work units in the work folder.
pub const UNITS_FILE: &str = "units.json";

/// File of the texel patches after the validity pass, in the work folder.
pub const PATCHES_FILE: &str = "patches.bin";

/// What a process of a split bake does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// Derive the layout and patches, write the work units, stop.
    Prepare,
    /// Compute shard `index` of `count` of every split stage.
    Shard {
        /// This shard, 0-based.
        index: u32,
        /// Shards in all.
        count: u32,
        /// Wait (up to this long) for the other shards between split stages; `None`: stop
        /// after computing the first stage whose part is missing.
        wait: Option<Duration>,
    },
    /// Read every shard's parts and finish the bake.
    Merge,
}

/// Magic of a part file.
const MAGIC: &[u8; 8] = b"LBSHARD1";

/// A process of a split bake: its role and its work folder.
#[derive(Debug)]
pub struct ShardRun {
    /// The work folder (`bake prepare`'s output).
    pub dir: PathBuf,
    /// What this process does.
    pub role: Role,
    /// Shards in all (read from the parts for a merge).
    count: Mutex<Option<u32>>,
    units: Mutex<Option<Units>>,
    started: Instant,
    split: Mutex<Vec<SplitStage>>,
    /// What this process did when it stopped after its part (prepare, or a shard).
    stopped: Mutex<Option<String>>,
}

/// The header of a part file, as JSON before its values.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct PartHeader {
    stage: Stage,
    count: u32,
    /// [`Units::preparation`] of the work folder it was written for.
    preparation: u64,
    values: u64,
    part: ShardPart,
}

impl ShardRun {
    /// A process of `role` over the work folder `dir`.
    pub fn new(dir: &Path, role: Role) -> Self {
        let count = match role {
            Role::Shard { count, .. } => Some(count),
            _ => None,
        };
        Self {
            dir: dir.to_path_buf(),
            role,
            count: Mutex::new(count),
            units: Mutex::new(None),
            started: Instant::now(),
            split: Mutex::new(Vec::new()),
            stopped: Mutex::new(None),
        }
    }

    fn err(&self, message: String) -> BakeError {
        BakeError::Shard {
            dir: self.dir.clone(),
            message,
        }
    }

    /// The split stages read so far, with every shard's part (for the merged report).
    pub fn split_stages(&self) -> Vec<SplitStage> {
        self.split.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Called by *prepare* when the patches are known: writes them and the units, and stops.
    pub(super) fn prepared(&self, mut units: Units, patches: &Patches) -> Result<()> {
        units.preparation = preparation_id(&units);
        let text = serde_json::to_vec(&units).map_err(|e| self.err(e.to_string()))?;
        let mut staged = StagedFiles::new(&self.dir);
        staged.stage(&self.dir.join(PATCHES_FILE), &patches.to_bytes())?;
        staged.stage(&self.dir.join(UNITS_FILE), &text)?;
        staged.commit()?;
        Err(self.stop(format!(
            "prepared {} work units over {} texel patches in {}",
            units.rays.len(),
            patches.patches.len(),
            self.dir.display()
        )))
    }

    /// Stops this process after its part: records `done` (what it did) for
    /// [`super::SplitOutcome::PartDone`] and returns the error that unwinds the bake's stages
    /// ([`BakeError::Cancelled`]; the split bake's entry point turns it into the outcome).
    fn stop(&self, done: String) -> BakeError {
        *self.stopped.lock().unwrap_or_else(|e| e.into_inner()) = Some(done);
        BakeError::Cancelled
    }

    /// What this process did, when it stopped after its part.
    pub(super) fn stopped(&self) -> Option<String> {
        self.stopped
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Whether this process reads prepare's patches (a shard or the merge) rather than making
    /// them (prepare).
    pub(super) fn reads_patches(&self) -> bool {
        self.role != Role::Prepare
    }

    /// Prepare's patches, read from the work folder after checking that `layout` (derived
    /// again here, over `triangles` ray triangles and `instances` instances) is prepare's,
    /// and that the files agree with it and with each other.
    pub(super) fn read_prepared(
        &self,
        layout: &Layout,
        triangles: usize,
        instances: usize,
    ) -> Result<Patches> {
        let read = |name: &str, limit: u64| {
            let path = self.dir.join(name);
            crate::scene::resources::read_regular_file(&path, limit).map_err(|message| {
                BakeError::Read {
                    path,
                    source: std::io::Error::other(message),
                }
            })
        };
        let units: Units = serde_json::from_slice(&read(UNITS_FILE, 1 << 20)?)
            .map_err(|e| self.err(format!("{UNITS_FILE}: {e}")))?;
        if units.layout_hash != layout_hash(layout) {
            return Err(self.err(
                "this process's lightmap layout differs from prepare's: the scene, the settings or the baker changed since `bake prepare`; prepare again".into(),
            ));
        }
        // At most 84 bytes a texel of the layout, its footprints and its page index.
        let limit = 256 * layout.page_texels() + (1 << 20);
        let patches = Patches::from_bytes(&read(PATCHES_FILE, limit)?)
            .filter(|p| patches_hash(p) == units.patches_hash)
            .ok_or_else(|| self.err(format!("{PATCHES_FILE} is damaged or not prepare's")))?;
        patches
            .check(layout, triangles, instances)
            .map_err(|e| self.err(format!("{PATCHES_FILE} is damaged: {e}")))?;
        units
            .check(patches.patches.len())
            .map_err(|e| self.err(format!("{UNITS_FILE} is damaged: {e}")))?;
        *self.units.lock().unwrap_or_else(|e| e.into_inner()) = Some(units);
        Ok(patches)
    }

    fn part_path(&self, index: u32, stage: Stage) -> PathBuf {
        self.dir
            .join("shards")
            .join(index.to_string())
            .join(format!("{}.bin", stage.name().replace(' ', "_")))
    }

    /// The shards' count: this shard's, or (merge) the one every part of the first split
    /// stage was written with.
    fn shard_count(&self, stage: Stage) -> Result<u32> {
        if let Some(c) = *self.count.lock().unwrap_or_else(|e| e.into_inner()) {
            return Ok(c);
        }
        let header = self.current_header(0, stage).ok_or_else(|| {
            self.err(format!(
                "no part of stage '{stage}' from shard 0 of this preparation: run `bake shard` for every shard first"
            ))
        })?;
        *self.count.lock().unwrap_or_else(|e| e.into_inner()) = Some(header.count);
        Ok(header.count)
    }

    /// The header of shard `index`'s part of `stage` when it was written for the work units
    /// read here (this preparation).
    fn current_header(&self, index: u32, stage: Stage) -> Option<PartHeader> {
        let preparation = self
            .units
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .as_ref()?
            .preparation;
        self.read_header(&self.part_path(index, stage))
            .ok()
            .filter(|h| h.preparation == preparation)
    }

    /// The header of a part file, read without its values (shards waiting for each other
    /// look at every part several times a second).
    fn read_header(&self, path: &Path) -> Result<PartHeader> {
        use std::io::Read;
        let io = |source| BakeError::Read {
            path: path.to_path_buf(),
            source,
        };
        let not_part = || self.err(format!("{} is not a shard part", path.display()));
        let (mut file, _) = crate::scene::resources::open_regular_file(path)
            .map_err(|m| io(std::io::Error::other(m)))?;
        let mut prefix = [0u8; 16];
        file.read_exact(&mut prefix).map_err(io)?;
        let mut head = vec![0u8; header_len(&prefix).ok_or_else(not_part)?];
        file.read_exact(&mut head).map_err(io)?;
        serde_json::from_slice(&head).map_err(|_| not_part())
    }

    /// Whether a shard process stops here: after its last split stage nothing is left for it
    /// (the rest is the merge's).
    pub(super) fn shard_stops(&self) -> Result<()> {
        match self.role {
            Role::Shard { index, count, .. } => Err(self.stop(format!(
                    "shard {index} of {count}: every split stage done; run `bake merge` when all shards are"
                ))),
            _ => Ok(()),
        }
    }

    /// A split stage `stage` of `items` values: item `i` belongs to patch `patch(i)`.
    /// `compute(only)` computes the items `only` marks (all for `None`) and returns the
    /// values (zero elsewhere) and the (closest, any-hit) rays. Returns every value, computed
    /// here or read from the shards' parts.
    ///
    /// # Errors
    /// [`BakeError::Cancelled`] when this shard stops after its part (see [`Self::stop`]);
    /// [`BakeError::Shard`] when a part is missing, from another count or another
    /// preparation.
    pub(super) fn split<T: Record>(
        &self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        compute: impl FnOnce(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])> {
        let units = self.units.lock().unwrap_or_else(|e| e.into_inner()).clone();
        let Some(units) = units else {
            return Err(self.err("the work units are not known yet".into()));
        };
        let count = self.shard_count(stage)?;
        if count == 0 || count as usize > units.rays.len() {
            return Err(self.err(format!(
                "a split into {count} shards, but the work folder has {} work units: run at most that many shards (--count)",
                units.rays.len()
            )));
        }
        let owner = units.patch_shards(count);
        let shard_of = |i: usize| owner[patch(i)];
        if let Role::Shard { index, wait, .. } = self.role {
            self.check_counts(stage, count)?;
            let own = self.part_path(index, stage);
            // A part of this preparation and count is kept (a re-run resumes); any other is
            // replaced.
            let kept = self
                .read_header(&own)
                .is_ok_and(|h| h.count == count && h.preparation == units.preparation);
            if !kept {
                let start = Instant::now();
                let mask: Vec<bool> = (0..items).map(|i| shard_of(i) == index).collect();
                let (values, rays) = compute(Some(&mask));
                let part = ShardPart {
                    index,
                    items: mask.iter().filter(|&&m| m).count() as u64,
                    seconds: start.elapsed().as_secs_f64(),
                    rays,
                    process_seconds: self.started.elapsed().as_secs_f64(),
                };
                self.write_part(&own, stage, count, &units, &values, &mask, part)?;
            }
            match wait {
                // Without waiting, a call computes one stage at most: the waves of an engine
                // that runs the stages one by one each do the same work.
                None if !kept => {
                    return Err(self.stop(format!(
                            "shard {index} of {count}: stage '{stage}' done; run the shard again for the next stage once every shard's part of this one is written"
                        )));
                }
                None if !self.all_there(stage, count) => {
                    return Err(self.stop(format!(
                            "shard {index} of {count}: stage '{stage}' was done already; the next stage waits for shards {:?}",
                            self.missing(stage, count)
                        )));
                }
                None => {}
                Some(limit) => self.wait_for(stage, count, limit)?,
            }
        }
        self.read_all(stage, items, count, &units, shard_of)
    }

    /// Refuses parts of `stage` that other shards wrote for another count.
    fn check_counts(&self, stage: Stage, count: u32) -> Result<()> {
        let Ok(entries) = std::fs::read_dir(self.dir.join("shards")) else {
            return Ok(());
        };
        for entry in entries.flatten() {
            let Some(index) = entry
                .file_name()
                .to_str()
                .and_then(|n| n.parse::<u32>().ok())
            else {
                continue;
            };
            if let Some(h) = self.current_header(index, stage)
                && h.count != count
            {
                return Err(self.err(format!(
                    "shard {index} wrote its part of stage '{stage}' as one of {} shards, not {count}: run every shard with the same --count (or prepare a new work folder)",
                    h.count
                )));
            }
        }
        Ok(())
    }

    fn all_there(&self, stage: Stage, count: u32) -> bool {
        (0..count).all(|s| self.current_header(s, stage).is_some())
    }

    fn missing(&self, stage: Stage, count: u32) -> Vec<u32> {
        (0..count)
            .filter(|&s| self.current_header(s, stage).is_none())
            .collect()
    }

    fn wait_for(&self, stage: Stage, count: u32, limit: Duration) -> Result<()> {
        let start = Instant::now();
        while !self.all_there(stage, count) {
            if start.elapsed() > limit {
                return Err(self.err(format!(
                    "stage '{stage}': shards {:?} of {count} did not write their parts within {:.0} s",
                    self.missing(stage, count),
                    limit.as_secs_f64()
                )));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    fn write_part<T: Record>(
        &self,
        path: &Path,
        stage: Stage,
        count: u32,
        units: &Units,
        values: &[T],
        mask: &[bool],
        part: ShardPart,
    ) -> Result<()> {
        let owned = mask.iter().filter(|&&m| m).count();
        let header = PartHeader {
            stage,
            count,
            preparation: units.preparation,
            values: owned as u64,
            part,
        };
        let head = serde_json::to_vec(&header).map_err(|e| self.err(e.to_string()))?;
        let mut bytes = Vec::with_capacity(16 + head.len() + owned * T::BYTES);
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(head.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&head);
        for (v, _) in values.iter().zip(mask).filter(|(_, m)| **m) {
            v.put(&mut bytes);
        }
        let mut staged = StagedFiles::new(path.parent().unwrap_or(&self.dir));
        staged.stage(path, &bytes)?;
        staged.commit()?;
        Ok(())
    }

    fn read_all<T: Record>(
        &self,
        stage: Stage,
        items: usize,
        count: u32,
        units: &Units,
        shard_of: impl Fn(usize) -> u32,
    ) -> Result<(Vec<T>, [u64; 2])> {
        let missing = self.missing(stage, count);
        if !missing.is_empty() {
            return Err(self.err(format!(
                "stage '{stage}': no part from shards {missing:?} of {count}; run them (`bake shard --index I --count {count}`)"
            )));
        }
        let mut values = vec![T::default(); items];
        let mut rays = [0u64; 2];
        let mut parts = Vec::new();
        for s in 0..count {
            let path = self.part_path(s, stage);
            let limit = (16 + (1 << 20) + items * T::BYTES) as u64;
            let bytes = crate::scene::resources::read_regular_file(&path, limit).map_err(|m| {
                BakeError::Read {
                    path: path.clone(),
                    source: std::io::Error::other(m),
                }
            })?;
            let (header, data) = parse(&bytes)
                .ok_or_else(|| self.err(format!("{} is not a shard part", path.display())))?;
            if header.count != count || header.preparation != units.preparation {
                return Err(self.err(format!(
                    "{} was written for another preparation, or as one of {} shards, not {count}: run every shard of this preparation with --count {count}",
                    path.display(),
                    header.count
                )));
            }
            let mut k = 0usize;
            for (i, v) in values.iter_mut().enumerate() {
                if shard_of(i) == s {
                    let b = data.get(k * T::BYTES..(k + 1) * T::BYTES).ok_or_else(|| {
                        self.err(format!(
                            "{} holds fewer values than its share",
                            path.display()
                        ))
                    })?;
                    *v = T::get(b);
                    k += 1;
                }
            }
            rays[0] += header.part.rays[0];
            rays[1] += header.part.rays[1];
            parts.push(header.part);
        }
        self.split
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(SplitStage { stage, parts });
        Ok((values, rays))
    }
}

/// The length of a part file's JSON header, from its first 16 bytes (the magic, then the
/// length); `None` for anything else.
fn header_len(prefix: &[u8]) -> Option<usize> {
    if prefix.get(..8)? != MAGIC {
        return None;
    }
    let len = u64::from_le_bytes(prefix.get(8..16)?.try_into().ok()?);
    // A header is a few hundred bytes; a larger length is a damaged file.
    (len <= 1 << 20).then_some(len as usize)
}

/// A part file's header and values.
fn parse(bytes: &[u8]) -> Option<(PartHeader, &[u8])> {
    let len = header_len(bytes)?;
    let header: PartHeader = serde_json::from_slice(bytes.get(16..16 + len)?).ok()?;
    Some((header, &bytes[16 + len..]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_cut_even_shares() {
        let units = Units {
            starts: (0..=10).map(|k| k * 10).collect(),
            rays: vec![1.0, 1.0, 1.0, 5.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0],
            patches_hash: 7,
            layout_hash: 9,
            preparation: 1,
        };
        let owner = units.patch_shards(3);
        assert_eq!(owner.len(), 100);
        assert_eq!(
            (owner[0], owner[10], owner[20], owner[30], owner[99]),
            (0, 1, 2, 0, 0)
        );
        assert_eq!(units.shard_rays(3), vec![9.0, 3.0, 3.0]);
        // One shard takes everything; more shards than units leaves some empty.
        assert!(units.patch_shards(1).iter().all(|&s| s == 0));
        assert_eq!(units.shard_rays(16)[12], 0.0);
    }
}
