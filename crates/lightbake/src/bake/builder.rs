//! One way to set up any bake, in the manner of texture-synthesis's `Session::builder()`: the
//! scene and its settings, then how it is watched (progress, previews), then where it runs
//! (this thread, a thread of its own, one process of a split bake, or a subset of the texels).
//!
//! ```no_run
//! use std::sync::Arc;
//! use lightbake::bake::{BakeBuilder, PreviewSlot};
//! use lightbake::{BakeSettings, Scene};
//!
//! # fn scene() -> Scene { unimplemented!() }
//! let previews = Arc::new(PreviewSlot::enabled());
//! let handle = BakeBuilder::new(scene())
//!     .settings(BakeSettings::preview())
//!     .previews(Arc::clone(&previews))
//!     .spawn()?;
//! while !handle.is_finished() {
//!     if let Some(p) = handle.preview() { /* show p.pages */ }
//! }
//! let output = handle.join()?;
//! # Ok::<(), lightbake::BakeError>(())
//! ```

use std::sync::Arc;
use std::time::Duration;

use super::handle::BakeHandle;
use super::preview::PreviewSlot;
use super::shard::ShardRun;
use super::stages::Scope;
use super::subset::{Checkpoint, TexelRun};
use super::{BakeOutput, bake_split, bake_texels, bake_with};
use crate::error::Result;
use crate::incremental::Plan;
use crate::progress::Progress;
use crate::scene::Scene;
use crate::settings::BakeSettings;

/// A bake being set up: [`BakeBuilder::new`], the optional steps, then [`BakeBuilder::run`],
/// [`BakeBuilder::spawn`], [`BakeBuilder::run_split`] or [`BakeBuilder::run_texels`].
#[derive(Debug)]
pub struct BakeBuilder {
    scene: Scene,
    settings: BakeSettings,
    progress: Arc<Progress>,
    previews: Arc<PreviewSlot>,
    /// How the bake follows the cached bake of its output folder, when it keeps a cache.
    following: Option<Plan>,
    /// Where a bake that keeps a cache hands its state after each split stage.
    checkpoint: Option<Sink>,
    /// Time between two checkpoints within a split stage.
    checkpoint_interval: Duration,
}

/// A [`Checkpoint`] in the builder (shown as its presence).
#[derive(Clone)]
struct Sink(Checkpoint);

impl std::fmt::Debug for Sink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Checkpoint")
    }
}

/// How one process of a split bake ended.
#[derive(Debug)]
pub enum SplitOutcome {
    /// The merge finished the bake: bit for bit the output of the same bake in one process.
    Merged(Box<BakeOutput>),
    /// `prepare` or a shard did its part and stopped where it was meant to; what it did.
    PartDone(String),
}

impl BakeBuilder {
    /// A bake of `scene` with the default settings ([`BakeSettings::default`], the medium
    /// preset), a fresh progress and no previews.
    pub fn new(scene: Scene) -> Self {
        Self {
            scene,
            settings: BakeSettings::default(),
            progress: Arc::new(Progress::new()),
            previews: Arc::new(PreviewSlot::default()),
            following: None,
            checkpoint: None,
            checkpoint_interval: Duration::from_secs(2),
        }
    }

    /// Bakes with `settings`.
    pub fn settings(mut self, settings: BakeSettings) -> Self {
        self.settings = settings;
        self
    }

    /// Reports progress to (and obeys cancellation from) `progress`, which another thread
    /// may watch.
    pub fn progress(mut self, progress: Arc<Progress>) -> Self {
        self.progress = progress;
        self
    }

    /// Publishes progressive previews of the lightmaps to `previews` when it is
    /// [`PreviewSlot::enabled`] (see [`super::preview`]): the direct light, then the first
    /// indirect solution, then the final pages.
    pub fn previews(mut self, previews: Arc<PreviewSlot>) -> Self {
        self.previews = previews;
        self
    }

    /// Follows `plan` ([`crate::incremental::plan`]): a full bake, or an edit of the cached
    /// bake that recomputes only what the edit changed (see [`crate::incremental`]); either
    /// way the output keeps a cache for the next bake ([`BakeOutput::cache`]).
    pub fn following(mut self, plan: Plan) -> Self {
        self.following = Some(plan);
        self
    }

    /// With [`Self::following`]: `sink` gets, after each split stage, the cache of a bake
    /// that stopped there. A bake of the same input that follows it keeps the stages it
    /// finished: the `bake` command writes it to `OUT/lightbake.partial` so that a killed
    /// bake run again resumes.
    ///
    /// A long split stage hands over its state too: its items are computed in 16 blocks, and
    /// the finished ones are kept in a checkpoint once [`Self::checkpoint_interval`] and 19
    /// times the last checkpoint's writing time have passed since the last (so writing them
    /// takes at most a twentieth of the stage).
    pub fn checkpoints(mut self, sink: Checkpoint) -> Self {
        self.checkpoint = Some(Sink(sink));
        self
    }

    /// With [`Self::checkpoints`]: the least time between two checkpoints within a split
    /// stage (default 2 s; zero: after every block of its items, whatever the writing takes).
    pub fn checkpoint_interval(mut self, interval: Duration) -> Self {
        self.checkpoint_interval = interval;
        self
    }

    /// Runs the bake on this thread (its work on a pool of `settings.threads` threads).
    ///
    /// # Errors
    /// As [`super::bake()`].
    pub fn run(self) -> Result<BakeOutput> {
        let Self {
            scene,
            settings,
            progress,
            previews,
            following,
            checkpoint,
            checkpoint_interval,
        } = self;
        run_following(
            &scene,
            &settings,
            &progress,
            &previews,
            (following, checkpoint.map(|c| (c, checkpoint_interval))),
        )
    }

    /// Runs the bake on this thread over the texels `run` marks, the others' values taken
    /// from an earlier run (see [`TexelRun`]); `run` keeps this run's values for the
    /// next.
    ///
    /// # Errors
    /// As [`super::bake()`]; [`crate::BakeError::Subset`] when the earlier values belong to
    /// other texel patches or settings; [`crate::BakeError::BadSetting`] for a target error.
    pub fn run_texels(self, run: &TexelRun) -> Result<BakeOutput> {
        bake_texels(
            &self.scene,
            &self.settings,
            &self.progress,
            &self.previews,
            run,
        )
    }

    /// Runs this process's part of a bake split across processes ([`super::shard`]): `run`
    /// says which part (prepare, shard I of N, merge) and where the work folder is.
    /// Previews are not published.
    ///
    /// # Errors
    /// As [`super::bake()`]; [`crate::BakeError::Shard`] when the work folder is incomplete
    /// or from another preparation; [`crate::BakeError::BadSetting`] for a target error (its
    /// rounds would need each whole stage's estimate).
    pub fn run_split(self, run: &ShardRun) -> Result<SplitOutcome> {
        bake_split(&self.scene, &self.settings, &self.progress, run)
    }

    /// Starts the bake on a thread of its own named `lightbake`.
    ///
    /// # Errors
    /// [`crate::BakeError::Thread`] when the thread cannot be started.
    pub fn spawn(self) -> Result<BakeHandle> {
        self.spawn_then(|output, _, _| Ok(output))
    }

    /// Starts the bake on a thread of its own, then runs `then(output, &scene, &settings)`
    /// there (writing the outputs, say).
    ///
    /// # Errors
    /// [`crate::BakeError::Thread`] when the thread cannot be started.
    pub fn spawn_then<T: Send + 'static>(
        self,
        then: impl FnOnce(BakeOutput, &Scene, &BakeSettings) -> Result<T> + Send + 'static,
    ) -> Result<BakeHandle<T>> {
        let Self {
            scene,
            settings,
            progress,
            previews,
            following,
            checkpoint,
            checkpoint_interval,
        } = self;
        let (watched, published) = (Arc::clone(&progress), Arc::clone(&previews));
        BakeHandle::start(progress, previews, move || {
            let plan = (following, checkpoint.map(|c| (c, checkpoint_interval)));
            let output = run_following(&scene, &settings, &watched, &published, plan)?;
            then(output, &scene, &settings)
        })
    }
}

/// A bake in one process: whole, or following `plan` over a [`TexelRun`]; with light groups,
/// relit from the cache ([`super::relight`]) or whole, keeping the groups' pages for the next.
fn run_following(
    scene: &Scene,
    settings: &BakeSettings,
    progress: &Progress,
    previews: &PreviewSlot,
    (plan, checkpoint): (Option<Plan>, Option<(Sink, Duration)>),
) -> Result<BakeOutput> {
    // A target error's rounds take every texel: no cache is kept for them (the plan says why
    // a later bake is full).
    if settings.target_error.is_some() {
        return bake_with(scene, settings, progress, previews, Scope::All);
    }
    match plan {
        Some(Plan::Relight(r)) => super::relight::relit(scene, settings, progress, *r),
        Some(plan) if !settings.groups.is_empty() => {
            // Light groups are lit over every texel; the groups' pages are kept for a later
            // bake to relight.
            let why = match plan {
                Plan::Full(why) => why,
                _ => "light groups are baked over every texel".into(),
            };
            let mut out = bake_with(scene, settings, progress, previews, Scope::All)?;
            out.cache = Some(super::relight::group_cache(scene, settings, &out));
            out.report.incremental = Some(crate::incremental::IncrementalReport {
                full: Some(why),
                ..Default::default()
            });
            Ok(out)
        }
        Some(plan) => {
            let mut run = TexelRun::following(plan);
            if let Some((Sink(sink), interval)) = checkpoint {
                run = run
                    .with_checkpoints(sink)
                    .with_checkpoint_interval(interval);
            }
            bake_with(scene, settings, progress, previews, Scope::Subset(&run))
        }
        None => bake_with(scene, settings, progress, previews, Scope::All),
    }
}
