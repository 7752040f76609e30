//! A bake over a subset of the texels: the third place a stage's work units run, beside one
//! whole process and one shard of a split bake ([`super::stages::Scope`]). It is the seam
//! incremental bakes run on.
//!
//! A [`TexelRun`] computes every texel and keeps each split stage's values
//! ([`TexelRun::all`]); computes only the texels it marks and takes every other texel's
//! values from an earlier run of the same patches ([`TexelRun::only`]); or follows an edit
//! of a cached bake ([`TexelRun::following`]): the layout of the meshes that did not change
//! is kept, each texel patch is found again by its key (its instance, its texel in the
//! instance's rectangle, its own geometry), and an item is computed again where its patch is
//! new or its inputs moved, relative to their earlier level, by more than
//! [`SHARE`](crate::incremental::SHARE) of the earlier bake's estimated error — the direct
//! light by the bound of [`direct_bounds`] (what the edit can change there) over its earlier
//! value, a gather by the change of the input summary its pass states (the coarse light the
//! node gathers). A split stage that states neither is computed whole. Every computed value is the same function of its texel and the
//! stages before it as in a whole bake, so values kept from the same input give the whole
//! bake's bits.

use std::collections::HashMap;
use std::sync::Mutex;

use super::shard::patches_hash;
use crate::bvh::RayScene;
use crate::error::{BakeError, Result};
use crate::incremental::{
    BakeCache, Edits, IncrementalReport, KeptStage, KeptState, Plan, SHARE, StageShare,
    StageValues, deciding_settings, direct_bounds, patch_geometry, patch_keys,
};
use crate::raster::Patches;
use crate::runner::Record;
use crate::sampling::Fnv1a;
use crate::scene::Scene;
use crate::scene::hashes::identities;
use crate::settings::BakeSettings;
use crate::stage::Stage;
use crate::unwrap::Layout;
use crate::unwrap::stable::Earlier;

/// Blocks a split stage's items are computed in when the bake keeps checkpoints.
const BLOCKS: usize = 16;

/// Seconds between two checkpoints within a split stage, at least.
const CHECKPOINT_SECONDS: f64 = 2.0;

/// Within a split stage, a checkpoint also waits this many times the time the last one took
/// to write, so writing them takes at most a twentieth of the stage (a checkpoint of a
/// furnished house holds 50–90 MB).
const CHECKPOINT_SPACING: f64 = 19.0;

/// Values as [`Record`] bytes.
fn to_bytes<T: Record>(values: &[T]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(values.len() * T::BYTES);
    for v in values {
        v.put(&mut bytes);
    }
    bytes
}

/// Per item of a split stage, whether it is computed here, and the earlier item each of the
/// others takes its value from.
type Subset = (Vec<bool>, Vec<Option<u32>>);

/// Whether texel (page, x, y) is computed here.
type TexelMask = Box<dyn Fn(u32, u32, u32) -> bool + Send + Sync>;

/// Which texels a run computes.
enum Mode {
    /// Every texel.
    All,
    /// The texels the mask marks, over the earlier run's patches.
    Only(TexelMask),
    /// Those an edit of the cached bake can change (the cache without its values, and the
    /// edits), or every texel with the reason for a full bake.
    Follow(Box<Following>),
}

/// An incremental bake's view of the cached bake.
struct Following {
    /// Why the bake is full, or the edits it follows over `cache`.
    edit: std::result::Result<(Edits, BakeCache), String>,
}

/// Which texels a bake computes, and where the others' values come from
/// ([`super::BakeBuilder::run_texels`], [`super::BakeBuilder::following`]).
///
/// ```no_run
/// use lightbake::bake::{BakeBuilder, TexelRun};
/// # fn scene() -> lightbake::Scene { unimplemented!() }
/// let first = TexelRun::all();
/// BakeBuilder::new(scene()).run_texels(&first)?;
/// // Rebake the left half of page 0 only.
/// let left = TexelRun::only(first.values(), |page, x, _| page == 0 && x < 256);
/// let output = BakeBuilder::new(scene()).run_texels(&left)?;
/// # Ok::<(), lightbake::BakeError>(())
/// ```
pub struct TexelRun {
    mode: Mode,
    earlier: StageValues,
    state: Mutex<RunState>,
    /// Called with what a later bake can follow after each split stage (a resumable bake).
    checkpoint: Option<Checkpoint>,
    /// Seconds between two checkpoints within a split stage.
    interval: f64,
}

/// A sink for a bake's state after each split stage: the cache of a bake that stopped there,
/// which a bake of the same input follows to keep the stages it finished.
pub type Checkpoint = std::sync::Arc<dyn Fn(&BakeCache) + Send + Sync>;

#[derive(Default)]
struct RunState {
    /// Per patch: computed here (`only` runs, known once the patches are).
    mask: Option<Vec<bool>>,
    /// Per patch, the earlier run's patch with its key (runs that follow an edit).
    earlier_patch: Vec<Option<u32>>,
    /// Per patch, the bound of its direct light's change (runs that follow an edit).
    direct_bound: Vec<f32>,
    /// This run's values, kept for a later run.
    kept: StageValues,
    /// Items computed here and items in all, over the split stages.
    computed: [u64; 2],
    /// Per split stage, items computed here and in all.
    shares: Vec<StageShare>,
    /// How the layout followed the earlier one.
    layout: Vec<String>,
    /// The cache a checkpoint writes, without its values (known once the patches are).
    template: Option<BakeCache>,
    /// When the last checkpoint was written, and the seconds its writing took.
    checkpointed: Option<(std::time::Instant, f64)>,
}

impl std::fmt::Debug for TexelRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TexelRun")
            .field("subset", &!matches!(self.mode, Mode::All))
            .field("earlier_stages", &self.earlier.stages.len())
            .finish()
    }
}

impl TexelRun {
    fn with(mode: Mode, earlier: StageValues) -> Self {
        Self {
            mode,
            earlier,
            state: Mutex::new(RunState::default()),
            checkpoint: None,
            interval: CHECKPOINT_SECONDS,
        }
    }

    /// This run with `sink` called after each split stage with the cache of a bake that
    /// stopped there (see [`Checkpoint`]).
    pub fn with_checkpoints(mut self, sink: Checkpoint) -> Self {
        self.checkpoint = Some(sink);
        self
    }

    /// With [`Self::with_checkpoints`]: a split stage under way hands its state over too,
    /// after each of its 16 blocks once `interval` (default 2 s) and 19 times the last
    /// checkpoint's writing time have passed since the last checkpoint; zero: after every
    /// block, whatever the writing takes.
    pub fn with_checkpoint_interval(mut self, interval: std::time::Duration) -> Self {
        self.interval = interval.as_secs_f64();
        self
    }

    /// Every texel computed; each split stage's values kept ([`Self::values`]).
    pub fn all() -> Self {
        Self::with(Mode::All, StageValues::default())
    }

    /// Only the texels `texels(page, x, y)` marks computed; every other texel's values taken
    /// from `earlier` (from [`Self::values`] of a run of the same scene and settings).
    pub fn only(
        earlier: StageValues,
        texels: impl Fn(u32, u32, u32) -> bool + Send + Sync + 'static,
    ) -> Self {
        Self::with(Mode::Only(Box::new(texels)), earlier)
    }

    /// A run that follows `plan`: a full bake (every texel, values kept for the next), or an
    /// edit of the cached bake (see the module docs).
    pub fn following(plan: Plan) -> Self {
        match plan {
            Plan::Full(why) => Self::with(
                Mode::Follow(Box::new(Following { edit: Err(why) })),
                StageValues::default(),
            ),
            // Relit from the groups' pages by the builder, never over texels: here, a full
            // bake.
            Plan::Relight(_) => Self::with(
                Mode::Follow(Box::new(Following {
                    edit: Err("a relit bake takes no subset of the texels".into()),
                })),
                StageValues::default(),
            ),
            Plan::Edit(edit) => {
                let (edits, mut cache) = *edit;
                let values = std::mem::take(&mut cache.values);
                Self::with(
                    Mode::Follow(Box::new(Following {
                        edit: Ok((edits, cache)),
                    })),
                    values,
                )
            }
        }
    }

    /// The values this run's split stages ended with (computed here or taken from the
    /// earlier run), for a later run over a subset.
    pub fn values(&self) -> StageValues {
        self.lock().kept.clone()
    }

    /// Items computed here and items in all, summed over the split stages run so far.
    pub fn computed(&self) -> [u64; 2] {
        self.lock().computed
    }

    /// Whether the bake keeps a cache for the next one (a run that follows a plan).
    pub(super) fn keeps_cache(&self) -> bool {
        matches!(self.mode, Mode::Follow(_))
    }

    /// The edit this run follows, if any.
    fn edit(&self) -> Option<&(Edits, BakeCache)> {
        match &self.mode {
            Mode::Follow(f) => f.edit.as_ref().ok(),
            _ => None,
        }
    }

    /// The cached bake's density, when this run follows an edit of it.
    pub(super) fn earlier_density(&self) -> Option<f32> {
        self.edit().map(|(_, c)| c.density)
    }

    /// The cached bake's layout and what it was made of, when this run follows an edit.
    pub(super) fn earlier_layout(&self) -> Option<Earlier<'_>> {
        let (_, c) = self.edit()?;
        Some(Earlier {
            layout: &c.layout,
            requests: &c.requests,
            mesh_geometry: &c.scene.meshes,
            instances: &c.scene.instances,
        })
    }

    /// Notes how the layout followed the earlier one.
    pub(super) fn layout_followed(&self, lines: Vec<String>) {
        self.lock().layout = lines;
    }

    /// What the run did, for the report (runs that follow a plan).
    pub(super) fn report(&self) -> Option<IncrementalReport> {
        let Mode::Follow(f) = &self.mode else {
            return None;
        };
        let state = self.lock();
        let [computed, items] = state.computed;
        Some(IncrementalReport {
            full: f.edit.as_ref().err().cloned(),
            changes: f
                .edit
                .as_ref()
                .map(|(e, _)| e.lines.clone())
                .unwrap_or_default(),
            layout: state.layout.clone(),
            stages: state.shares.clone(),
            recomputed: if items == 0 {
                1.0
            } else {
                computed as f64 / items as f64
            },
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, RunState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn err(message: String) -> BakeError {
        BakeError::Subset { message }
    }

    /// Marks the patches this run computes, once the bake knows them (`scene` the unwrapped
    /// scene over `layout`, `rays` its ray queries); refuses earlier values of other patches
    /// or other settings.
    ///
    /// # Errors
    /// [`BakeError::Subset`] when the earlier values belong to other texel patches or were
    /// kept by a bake with other settings.
    pub(super) fn patches_known(
        &self,
        (scene, layout, rays): (&Scene, &Layout, &RayScene),
        patches: &Patches,
        settings: &BakeSettings,
    ) -> Result<()> {
        let hash = patches_hash(patches);
        let mut h = Fnv1a::default();
        h.bytes(&serde_json::to_vec(&deciding_settings(settings)).unwrap_or_default());
        let ids = identities(scene.instances.iter().map(|i| i.name.as_str()));
        let mut state = self.lock();
        state.kept = StageValues {
            settings_hash: h.finish(),
            patches_hash: hash,
            patch_keys: patch_keys(patches, layout, &ids),
            stages: Vec::new(),
            geometry_key: patch_geometry(scene, layout),
            patches: patches.to_bytes(),
            states: Vec::new(),
        };
        state.computed = [0; 2];
        state.shares.clear();

        let other_settings = || {
            Self::err(
                "the earlier values were kept by a bake with other settings: every texel must be baked again".into(),
            )
        };
        match &self.mode {
            Mode::All => {}
            Mode::Only(texels) => {
                if self.earlier.patches_hash != hash {
                    return Err(Self::err(
                        "the earlier values belong to other texel patches: the geometry, its layout or the settings changed since they were kept, so every texel must be baked again".into(),
                    ));
                }
                if self.earlier.settings_hash != state.kept.settings_hash {
                    return Err(other_settings());
                }
                state.mask = Some(
                    (patches.patches.iter())
                        .map(|p| texels(p.page, p.x, p.y))
                        .collect(),
                );
            }
            Mode::Follow(_) => {
                let Some((edits, cache)) = self.edit() else {
                    return Ok(());
                };
                if self.earlier.settings_hash != state.kept.settings_hash {
                    return Err(other_settings());
                }
                let earlier: HashMap<u64, u32> = (self.earlier.patch_keys.iter())
                    .enumerate()
                    .map(|(i, &k)| (k, i as u32))
                    .collect();
                state.earlier_patch = (state.kept.patch_keys.iter())
                    .map(|k| earlier.get(k).copied())
                    .collect();
                let emitted = (scene.materials.iter())
                    .map(|m| m.emissive.max_element())
                    .fold(0.0f32, f32::max);
                let hidden = emitted
                    .max(scene.sky.max_element())
                    .max(cache.sky.max_element());
                state.direct_bound = direct_bounds(edits, &scene.lights, hidden, rays, patches);
            }
        }
        Ok(())
    }

    /// The texel patches of the earlier run, where this run follows it (an edit of its
    /// scene or the same texels again) and its patches were made from the same geometry
    /// and layout ([`patch_geometry`]): `scene` the unwrapped scene over `layout`, with
    /// `triangles` ray triangles. `None` when they must be made again.
    pub(super) fn kept_patches(
        &self,
        scene: &Scene,
        layout: &Layout,
        triangles: usize,
    ) -> Option<Patches> {
        // What the patches read ([`Stage::reads`]) did not change in the edit followed.
        let follows = match &self.mode {
            Mode::All => false,
            Mode::Only(_) => true,
            Mode::Follow(_) => self
                .edit()
                .is_some_and(|(edits, _)| !Stage::Validity.changed_by(&edits.changed())),
        };
        let earlier = &self.earlier;
        if !follows
            || earlier.patches.is_empty()
            || earlier.geometry_key != patch_geometry(scene, layout)
        {
            return None;
        }
        let patches = Patches::from_bytes(&earlier.patches)?;
        let fits = patches_hash(&patches) == earlier.patches_hash
            && patches.patches.len() == earlier.patch_keys.len()
            && patches
                .check(layout, triangles, scene.instances.len())
                .is_ok();
        fits.then_some(patches)
    }

    /// What whole stage `stage` of the earlier run kept under `key`, when the earlier run had
    /// this run's texel patches and settings and the bytes still match their checksum.
    pub(super) fn earlier_state(&self, stage: Stage, key: u64) -> Option<Vec<u8>> {
        let state = self.lock();
        let same = !state.kept.patch_keys.is_empty()
            && self.earlier.patches_hash == state.kept.patches_hash
            && self.earlier.settings_hash == state.kept.settings_hash;
        (self.earlier.states.iter())
            .find(|s| same && s.stage == stage && s.key == key && s.intact())
            .map(|s| s.bytes.clone())
    }

    /// Keeps `bytes()` as whole stage `stage`'s state under `key` with this run's values.
    pub(super) fn keep_state(&self, stage: Stage, key: u64, bytes: impl FnOnce() -> Vec<u8>) {
        let bytes = bytes();
        let mut state = self.lock();
        state.kept.states.retain(|s| s.stage != stage);
        state.kept.states.push(KeptState::new(stage, key, bytes));
    }

    /// The bake's input `scene` (before the layout's UVs are given to it), `settings` and
    /// its layout at `density` are known: what a checkpoint writes besides the values.
    pub(super) fn layout_known(
        &self,
        scene: &Scene,
        settings: &BakeSettings,
        density: f32,
        layout: &Layout,
    ) {
        if self.checkpoint.is_some() {
            let cache = BakeCache::new(
                scene,
                settings,
                density,
                layout,
                StageValues::default(),
                0.0,
            );
            self.lock().template = Some(cache);
        }
    }

    /// The values of the `index`-th split stage `stage` of `items` items (item `i` belongs
    /// to patch `patch(i)`, `summary[i]` states its inputs where the pass knows them):
    /// `compute(only)` computes the items in the subset (`None`: all), the rest are the
    /// earlier run's.
    ///
    /// # Errors
    /// [`BakeError::Subset`] when an `only` run's earlier values have no values for this
    /// stage or they do not fit.
    pub(super) fn split<T: Record>(
        &self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
        compute: impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])> {
        let index = self.lock().kept.stages.len();
        let only = self.subset::<T>(stage, index, items, &patch, summary)?;
        let item_patch: Vec<u32> = (0..items).map(|i| patch(i) as u32).collect();
        let kept = |bytes: Vec<u8>, finished: Vec<bool>| KeptStage {
            stage,
            items,
            item_patch: item_patch.clone(),
            summary: summary.map(<[f32]>::to_vec).unwrap_or_default(),
            bytes,
            finished,
        };
        let (values, rays, computed) = match only {
            None if self.checkpoint.is_none() => {
                let (v, r) = compute(None);
                (v, r, items as u64)
            }
            only => {
                let (todo, earlier) =
                    only.unwrap_or_else(|| (vec![true; items], vec![None; items]));
                let mut values = vec![T::default(); items];
                for (i, value) in values.iter_mut().enumerate() {
                    if let (false, Some(j)) = (todo[i], earlier[i]) {
                        *value = self.earlier.stages[index].value(j as usize);
                    }
                }
                let (rays, computed) =
                    self.compute_in_blocks(&todo, &mut values, &compute, |values, finished| {
                        kept(to_bytes(values), finished.to_vec())
                    });
                (values, rays, computed)
            }
        };
        let mut state = self.lock();
        state.kept.stages.push(kept(to_bytes(&values), Vec::new()));
        state.computed[0] += computed;
        state.computed[1] += items as u64;
        state.shares.push(StageShare {
            stage,
            computed,
            items: items as u64,
        });
        let checkpoint = (state.template.clone()).map(|mut c| {
            c.values = state.kept.clone();
            c
        });
        drop(state);
        if let Some(cache) = checkpoint {
            self.write_checkpoint(&cache);
        }
        Ok((values, rays))
    }

    /// Computes the items `todo` marks into `values`: at once, or (a bake that keeps
    /// checkpoints) in [`BLOCKS`] blocks, each followed, once the checkpoint interval and
    /// [`CHECKPOINT_SPACING`] times the last checkpoint's writing time have passed since the
    /// stage began or the last checkpoint, by a checkpoint that holds the stage so far
    /// (`partial(values, finished)`), so a bake killed in a long stage keeps the items it
    /// finished. Gives the rays traced and the items computed.
    fn compute_in_blocks<T: Record>(
        &self,
        todo: &[bool],
        values: &mut [T],
        compute: &impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
        partial: impl Fn(&[T], &[bool]) -> KeptStage,
    ) -> ([u64; 2], u64) {
        let marked: Vec<usize> = (0..todo.len()).filter(|&i| todo[i]).collect();
        let computed = marked.len() as u64;
        let blocks = if self.checkpoint.is_some() {
            BLOCKS.min(marked.len()).max(1)
        } else {
            1
        };
        // Block b takes every `blocks`-th marked item from the b-th on: each block spreads
        // over the whole stage, so its items share out over the threads as the whole would.
        let chunks: Vec<Vec<usize>> = (0..blocks)
            .map(|b| marked.iter().copied().skip(b).step_by(blocks).collect())
            .collect();
        let mut finished: Vec<bool> = todo.iter().map(|&t| !t).collect();
        let mut rays = [0u64; 2];
        let began = std::time::Instant::now();
        let mut mask = vec![false; todo.len()];
        for (n, chunk) in chunks.iter().enumerate() {
            let whole = chunks.len() == 1 && chunk.len() == todo.len();
            for &i in chunk {
                mask[i] = true;
            }
            let (v, r) = compute((!whole).then_some(mask.as_slice()));
            for &i in chunk {
                values[i] = v[i];
                finished[i] = true;
                mask[i] = false;
            }
            rays[0] += r[0];
            rays[1] += r[1];
            let due = || {
                let (since, wait) = match self.lock().checkpointed {
                    _ if self.interval == 0.0 => (began, 0.0),
                    Some((at, took)) => {
                        (at.max(began), self.interval.max(CHECKPOINT_SPACING * took))
                    }
                    None => (began, self.interval),
                };
                since.elapsed().as_secs_f64() >= wait
            };
            if n + 1 < chunks.len() && due() {
                self.checkpoint_within(partial(values, &finished));
            }
        }
        (rays, computed)
    }

    /// Writes a checkpoint of the stages finished so far and `stage`, the one under way.
    fn checkpoint_within(&self, stage: KeptStage) {
        let cache = {
            let state = self.lock();
            (state.template.clone()).map(|mut c| {
                c.values = state.kept.clone();
                c.values.stages.push(stage);
                c
            })
        };
        if let Some(cache) = cache {
            self.write_checkpoint(&cache);
        }
    }

    /// Hands `cache` to the checkpoint sink and notes when, and how long it took.
    fn write_checkpoint(&self, cache: &BakeCache) {
        if let Some(sink) = &self.checkpoint {
            let start = std::time::Instant::now();
            sink(cache);
            let end = std::time::Instant::now();
            self.lock().checkpointed = Some((end, (end - start).as_secs_f64()));
        }
    }

    /// Which items of split stage `index` are computed here, and the earlier item each of
    /// the others takes its value from; `None` when every item is computed.
    fn subset<T: Record>(
        &self,
        stage: Stage,
        index: usize,
        items: usize,
        patch: &impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
    ) -> Result<Option<Subset>> {
        let state = self.lock();
        match &self.mode {
            Mode::All => Ok(None),
            Mode::Only(_) => {
                let Some(mask) = &state.mask else {
                    return Ok(None);
                };
                match self.earlier.stages.get(index) {
                    Some(k)
                        if k.stage == stage
                            && k.items == items
                            && k.bytes.len() == items * T::BYTES => {}
                    _ => {
                        return Err(Self::err(format!(
                            "the earlier values have no '{stage}' stage of {items} items at step {}: they were kept by a bake with other settings",
                            index + 1
                        )));
                    }
                }
                let k = &self.earlier.stages[index];
                let only: Vec<bool> = (0..items)
                    .map(|i| mask[patch(i)] || !k.is_finished(i))
                    .collect();
                let earlier = (0..items).map(|i| Some(i as u32)).collect();
                Ok(Some((only, earlier)))
            }
            Mode::Follow(_) => {
                let kept = match self.earlier.stages.get(index) {
                    Some(k) if k.stage == stage && k.bytes.len() == k.items * T::BYTES => k,
                    _ => return Ok(None),
                };
                // A stage that states nothing of its inputs but the patches is computed whole,
                // but for the direct light, whose inputs the edit's bounds cover.
                let stated =
                    stage == Stage::Direct || (summary.is_some() && !kept.summary.is_empty());
                if self.edit().is_none() || !stated {
                    return Ok(None);
                }
                let item_of = kept.item_of_patch(self.earlier.patch_keys.len());
                let tolerance = self.edit().map_or(0.0, |(_, cache)| SHARE * cache.error);
                let mut only = vec![true; items];
                let mut earlier = vec![None; items];
                for i in 0..items {
                    let p = patch(i);
                    let Some(j) = state
                        .earlier_patch
                        .get(p)
                        .copied()
                        .flatten()
                        .and_then(|q| item_of[q as usize])
                    else {
                        continue;
                    };
                    // The change of the item's inputs, relative to their earlier level.
                    let mut change = if stage == Stage::Direct {
                        let bound = state.direct_bound.get(p).copied().unwrap_or(f32::INFINITY);
                        if bound > 0.0 {
                            bound / kept.value::<T>(j as usize).level()
                        } else {
                            0.0
                        }
                    } else {
                        0.0
                    };
                    if let Some(s) = summary.filter(|_| !kept.summary.is_empty()) {
                        let (new, old) = (s[i], kept.summary[j as usize]);
                        if new != old {
                            change = change.max((new - old).abs() / old.abs());
                        }
                    }
                    earlier[i] = Some(j);
                    only[i] =
                        change.is_nan() || change > tolerance || !kept.is_finished(j as usize);
                }
                Ok(Some((only, earlier)))
            }
        }
    }
}
