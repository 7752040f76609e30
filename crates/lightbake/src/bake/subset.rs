//! A bake over a subset of the texels: the third place a stage's work units run, beside one
//! whole process and one shard of a split bake ([`super::stages::Scope`]).
//!
//! A [`TexelRun`] either computes every texel and keeps each split stage's values
//! ([`TexelRun::all`]), or computes only the texels it marks and takes every other texel's
//! values from an earlier run's [`StageValues`] ([`TexelRun::only`]). The earlier values
//! must come from a bake with the same settings and texel patches (the same geometry and
//! layout; lights and materials may differ), checked by hashes of both and by each split
//! stage's name and size in the order the bake reaches it. Every value is the
//! same function of its texel and the stages before it in either case (as in a split bake),
//! so a run over a subset with values kept from a run of the same input gives the same bits
//! as the whole bake; the texels outside the subset keep what the earlier run computed. This
//! is the seam incremental rebakes run on: they decide which texels a change touches.

use std::sync::Mutex;

use super::shard::patches_hash;
use crate::error::{BakeError, Result};
use crate::raster::Patches;
use crate::runner::Record;
use crate::sampling::Fnv1a;
use crate::settings::BakeSettings;
use crate::stage::Stage;

/// The values of a bake's split stages (direct light, the gather's pilot, final gather,
/// correction), in the order the bake computed them, with hashes of the texel patches they
/// belong to and of the settings that computed them. Held in memory (not written to a file).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageValues {
    patches_hash: u64,
    settings_hash: u64,
    stages: Vec<(Stage, usize, Vec<u8>)>,
}

impl StageValues {
    /// The stages kept, in order, with their item counts.
    pub fn stages(&self) -> impl Iterator<Item = (Stage, usize)> + '_ {
        self.stages.iter().map(|(s, n, _)| (*s, *n))
    }
}

/// Whether texel (page, x, y) is computed here.
type TexelMask = Box<dyn Fn(u32, u32, u32) -> bool + Send + Sync>;

/// Which texels a bake computes, and where the others' values come from
/// ([`super::BakeBuilder::run_texels`]).
///
/// [`TexelRun::all`] computes every texel and keeps each split stage's values (direct light,
/// the gather's pilot, final gather, correction); [`TexelRun::only`] computes the texels it
/// marks and takes every other texel's values from an earlier run's [`StageValues`], which
/// must come from a bake of the same settings and texel patches (checked). The stages between
/// and after them run whole, on the merged values. Since each value is the same function of
/// its texel and the stages before it, values kept from the same input give the whole bake's
/// bits; after a change, the texels outside the subset keep the earlier light. This is the
/// seam incremental rebakes run on: they decide which texels a change touches.
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
    /// Whether texel (page, x, y) is computed here; `None`: every texel.
    texels: Option<TexelMask>,
    earlier: StageValues,
    state: Mutex<RunState>,
}

#[derive(Default)]
struct RunState {
    /// Per patch: computed here (known once the patches are).
    mask: Option<Vec<bool>>,
    /// This run's values, kept for a later run.
    kept: StageValues,
    /// Items computed here and items in all, over the split stages.
    computed: [u64; 2],
}

impl std::fmt::Debug for TexelRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TexelRun")
            .field("subset", &self.texels.is_some())
            .field("earlier_stages", &self.earlier.stages.len())
            .finish()
    }
}

impl TexelRun {
    /// Every texel computed; each split stage's values kept ([`Self::values`]).
    pub fn all() -> Self {
        Self {
            texels: None,
            earlier: StageValues::default(),
            state: Mutex::new(RunState::default()),
        }
    }

    /// Only the texels `texels(page, x, y)` marks computed; every other texel's values taken
    /// from `earlier` (from [`Self::values`] of a run of the same scene and settings).
    pub fn only(
        earlier: StageValues,
        texels: impl Fn(u32, u32, u32) -> bool + Send + Sync + 'static,
    ) -> Self {
        Self {
            texels: Some(Box::new(texels)),
            earlier,
            state: Mutex::new(RunState::default()),
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

    fn lock(&self) -> std::sync::MutexGuard<'_, RunState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn err(message: String) -> BakeError {
        BakeError::Subset { message }
    }

    /// Marks the patches this run computes, once the bake knows them; refuses earlier values
    /// of other patches or other settings.
    ///
    /// # Errors
    /// [`BakeError::Subset`] when the earlier values belong to other texel patches or were
    /// kept by a bake with other settings.
    pub(super) fn patches_known(&self, patches: &Patches, settings: &BakeSettings) -> Result<()> {
        let hash = patches_hash(patches);
        // Every setting but the thread count (which changes no bit) decides the values.
        let settings = BakeSettings {
            threads: 0,
            ..settings.clone()
        };
        let mut h = Fnv1a::default();
        h.bytes(&serde_json::to_vec(&settings).unwrap_or_default());
        let mut state = self.lock();
        state.kept = StageValues {
            patches_hash: hash,
            settings_hash: h.finish(),
            stages: Vec::new(),
        };
        state.computed = [0; 2];
        if let Some(texels) = &self.texels {
            if self.earlier.patches_hash != hash {
                return Err(Self::err(
                    "the earlier values belong to other texel patches: the geometry, its layout or the settings changed since they were kept, so every texel must be baked again".into(),
                ));
            }
            if self.earlier.settings_hash != state.kept.settings_hash {
                return Err(Self::err(
                    "the earlier values were kept by a bake with other settings: every texel must be baked again".into(),
                ));
            }
            state.mask = Some(
                (patches.patches.iter())
                    .map(|p| texels(p.page, p.x, p.y))
                    .collect(),
            );
        }
        Ok(())
    }

    /// The values of the `index`-th split stage `stage` of `items` items (item `i` belongs
    /// to patch `patch(i)`): `compute(only)` computes the items in the subset (`None`: all),
    /// the rest are the earlier run's.
    ///
    /// # Errors
    /// [`BakeError::Subset`] when the earlier run has no values for this stage or they do
    /// not fit.
    pub(super) fn split<T: Record>(
        &self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        compute: impl FnOnce(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])> {
        let (mask, index) = {
            let state = self.lock();
            (state.mask.clone(), state.kept.stages.len())
        };
        let (values, rays, computed) = match mask {
            None => {
                let (v, r) = compute(None);
                (v, r, items as u64)
            }
            Some(mask) => {
                let earlier = match self.earlier.stages.get(index) {
                    Some((s, n, bytes))
                        if *s == stage && *n == items && bytes.len() == items * T::BYTES =>
                    {
                        bytes
                    }
                    _ => {
                        return Err(Self::err(format!(
                            "the earlier values have no '{stage}' stage of {items} items at step {}: they were kept by a bake with other settings",
                            index + 1
                        )));
                    }
                };
                let only: Vec<bool> = (0..items).map(|i| mask[patch(i)]).collect();
                let (mut v, r) = compute(Some(&only));
                for (i, value) in v.iter_mut().enumerate() {
                    if !only[i] {
                        *value = T::get(&earlier[i * T::BYTES..(i + 1) * T::BYTES]);
                    }
                }
                let computed = only.iter().filter(|&&m| m).count() as u64;
                (v, r, computed)
            }
        };
        let mut bytes = Vec::with_capacity(items * T::BYTES);
        for v in &values {
            v.put(&mut bytes);
        }
        let mut state = self.lock();
        state.kept.stages.push((stage, items, bytes));
        state.computed[0] += computed;
        state.computed[1] += items as u64;
        Ok((values, rays))
    }
}
