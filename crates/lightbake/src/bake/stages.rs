//! Running stages: each one is timed, counted and recorded (and published to the progress),
//! and a cancel is seen between them; and the rounds a sampling stage takes to reach its share
//! of a target error ([`until_target`]).

use std::time::Instant;

use super::preview::{self, PreviewKind, PreviewSlot};
use super::shard::ShardRun;
use super::subset::TexelRun;
use crate::context::BakeContext;
use crate::error::{BakeError, Result};
use crate::error_estimate::ErrorEstimate;
use crate::lightmap::LightmapPage;
use crate::progress::{Progress, RayKind, StageStats};
use crate::runner::{Record, StageRunner, WorkScope};
use crate::settings::BakeSettings;
use crate::stage::{Stage, StageRun};
use crate::unwrap::Layout;

/// Where a stage's work units run: the one seam between a pass and the process it runs in.
/// A pass says what it computes for the items a mask marks (`compute(only)`, `None`: every
/// item); the scope says which items this process computes and where the rest come from.
#[derive(Clone, Copy, Debug)]
pub(super) enum Scope<'a> {
    /// Every item, in this process.
    All,
    /// One process of a split bake: its shard's items (by their patches' work units), the
    /// rest read from the other shards' parts ([`ShardRun::split`]); prepare and the shards
    /// stop where their part ends ([`Scope::stop_after_split`]).
    Split(&'a ShardRun),
    /// The texels a [`TexelRun`] marks, the rest taken from an earlier run's values
    /// ([`TexelRun::split`]).
    Subset(&'a TexelRun),
}

impl WorkScope for Scope<'_> {
    fn split<T: Record>(
        self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
        compute: impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])> {
        match self {
            Scope::All => Ok(compute(None)),
            Scope::Split(run) => run.split(stage, items, patch, compute),
            Scope::Subset(run) => run.split(stage, items, patch, summary, compute),
        }
    }

    fn kept_across_edits<T: Record>(
        self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
        compute: impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])> {
        match self {
            Scope::All | Scope::Split(_) => Ok(compute(None)),
            Scope::Subset(run) => run.split(stage, items, patch, summary, compute),
        }
    }

    fn earlier_state(self, stage: Stage, key: u64) -> Option<Vec<u8>> {
        match self {
            Scope::All | Scope::Split(_) => None,
            Scope::Subset(run) => run.earlier_state(stage, key),
        }
    }

    fn keep_state(self, stage: Stage, key: u64, bytes: impl FnOnce() -> Vec<u8>) {
        if let Scope::Subset(run) = self {
            run.keep_state(stage, key, bytes);
        }
    }

    /// See [`ShardRun::shard_stops`].
    fn stop_after_split(self) -> Result<()> {
        match self {
            Scope::All | Scope::Subset(_) => Ok(()),
            Scope::Split(run) => run.shard_stops(),
        }
    }
}

impl<'a> Scope<'a> {
    /// The split bake this process is part of, if any.
    pub(super) fn split_bake(self) -> Option<&'a ShardRun> {
        match self {
            Scope::All | Scope::Subset(_) => None,
            Scope::Split(run) => Some(run),
        }
    }

    /// The bake over a subset of the texels this is, if any.
    pub(super) fn texel_run(self) -> Option<&'a TexelRun> {
        match self {
            Scope::Subset(run) => Some(run),
            Scope::All | Scope::Split(_) => None,
        }
    }
}

/// The finished stages of one bake, in order.
pub(super) struct Stages<'p> {
    pub(super) list: Vec<StageStats>,
    progress: &'p Progress,
    previews: &'p PreviewSlot,
    /// Where the stages' work units run.
    scope: Scope<'p>,
    /// The direct light the previews show (lux per patch), kept for the indirect preview
    /// when previews are asked for.
    preview_direct: Option<Vec<glam::Vec3>>,
}

impl<'p> Stages<'p> {
    pub(super) fn new(progress: &'p Progress, previews: &'p PreviewSlot, scope: Scope<'p>) -> Self {
        Self {
            list: Vec::new(),
            progress,
            previews,
            scope,
            preview_direct: None,
        }
    }

    /// The direct-light preview of `direct` (lux per patch, without the direct light of
    /// lights baked indirect only), kept for [`Self::preview_indirect`].
    pub(super) fn preview_direct(&mut self, ctx: &BakeContext<'_>, direct: Vec<glam::Vec3>) {
        if !self.previews.is_enabled() {
            return;
        }
        let pages = || {
            preview::pages(
                ctx.layout,
                ctx.patches,
                &direct,
                ctx.settings.layout.padding,
            )
        };
        self.preview(PreviewKind::Direct, ctx.layout, glam::Vec3::ZERO, pages);
        self.preview_direct = Some(direct);
    }

    /// Publishes a preview of `kind` when the bake's watcher asked for previews: `pages`
    /// makes them (only then) over `layout`, with the ambient term `ambient` included.
    pub(super) fn preview(
        &self,
        kind: PreviewKind,
        layout: &Layout,
        ambient: glam::Vec3,
        pages: impl FnOnce() -> Vec<LightmapPage>,
    ) {
        if self.previews.is_enabled() && !self.progress.is_cancelled() {
            self.previews.publish(kind, layout, pages(), ambient);
        }
    }
}

impl<'p> StageRunner<'p> for Stages<'p> {
    type Scope = Scope<'p>;

    /// Where the stages' work units run ([`Scope`]).
    fn scope(&self) -> Scope<'p> {
        self.scope
    }

    /// Whether the bake publishes previews (and has a direct-light preview to build on).
    fn previewing(&self) -> bool {
        self.previews.is_enabled() && self.preview_direct.is_some()
    }

    /// The indirect preview: the direct light of [`Self::preview_direct`] plus `indirect`
    /// (lux per patch) and the ambient term `ambient` (lux) on every texel.
    fn preview_indirect(
        &self,
        ctx: &BakeContext<'_>,
        indirect: &[glam::Vec3],
        ambient: glam::Vec3,
    ) {
        let Some(direct) = &self.preview_direct else {
            return;
        };
        let pages = || {
            let sum: Vec<glam::Vec3> = direct
                .iter()
                .zip(indirect)
                .map(|(d, i)| (*d + *i + ambient).max(glam::Vec3::ZERO))
                .collect();
            preview::pages(ctx.layout, ctx.patches, &sum, ctx.settings.layout.padding)
        };
        self.preview(PreviewKind::Indirect, ctx.layout, ambient, pages);
    }

    /// The progress the stages report to.
    fn progress(&self) -> &'p Progress {
        self.progress
    }

    /// Runs stage `run` of `total` work units: `f` returns its value, rays traced and note.
    ///
    /// # Errors
    /// What `f` returns, or [`BakeError::Cancelled`] when the bake was cancelled meanwhile.
    fn run<T>(
        &mut self,
        run: impl Into<StageRun>,
        total: u64,
        f: impl FnOnce() -> Result<(T, u64, String)>,
    ) -> Result<T> {
        let run = run.into();
        self.progress.begin(run, total);
        let start = Instant::now();
        let (value, rays, note) = f()?;
        self.list.push(StageStats {
            run,
            seconds: start.elapsed().as_secs_f64(),
            rays,
            ray_kind: if rays > 0 {
                RayKind::Closest
            } else {
                RayKind::None
            },
            shadow_rays: 0,
            error: None,
            note,
        });
        self.progress
            .record_stage(self.list.len() - 1, &self.list[self.list.len() - 1]);
        if self.progress.is_cancelled() {
            return Err(BakeError::Cancelled);
        }
        Ok(value)
    }

    /// Sets how many of the last stage's rays were any-hit visibility tests (of a stage of
    /// closest-hit rays).
    fn shadow_rays(&mut self, rays: u64) {
        let index = self.list.len().saturating_sub(1);
        if let Some(last) = self.list.last_mut() {
            last.shadow_rays = rays;
            self.progress.record_stage(index, last);
        }
    }

    /// Sets the last stage's ray kind and error estimate (and publishes the estimate).
    fn annotate(&mut self, kind: RayKind, error: Option<ErrorEstimate>) {
        let index = self.list.len().saturating_sub(1);
        if let Some(last) = self.list.last_mut() {
            if last.rays > 0 {
                last.ray_kind = kind;
            }
            if let Some(e) = &error {
                self.progress.set_error_estimate(e.relative_rms);
            }
            last.error = error;
            self.progress.record_stage(index, last);
        }
    }
}

/// Rounds a sampling stage may take to reach its share of `target_error`.
pub(super) const TARGET_ROUNDS: u32 = 3;

/// The factor on a sample count that brings `error` down to `target` (error ∝ 1/√count),
/// with a 20% margin; 1 when already there.
fn count_factor(error: f64, target: f64) -> f64 {
    if error <= target || target <= 0.0 {
        1.0
    } else {
        (error / target).powi(2) * 1.2
    }
}

/// `count` × `factor`, rounded up and capped at `max`.
pub(super) fn scaled(count: u32, factor: f64, max: u32) -> u32 {
    ((count as f64 * factor).ceil()).min(max as f64) as u32
}

/// The last round of a sampling stage.
pub(super) struct Rounds<T> {
    /// Its result.
    pub(super) value: T,
    /// Its number (1 for the first).
    pub(super) round: u32,
    /// Its estimate was still above the share (counts capped, or rounds used up).
    pub(super) missed: bool,
}

/// The target-error rounds of one sampling stage (see `BakeSettings::target_error`):
/// `attempt(settings, round)` runs the stage with the current counts and returns its result
/// and relative error estimate; `raise(settings, result, factor)` multiplies the counts that
/// set its noise by `factor` and says whether they changed. The rounds stop when the
/// estimate reaches `share`, when the counts no longer change, or after [`TARGET_ROUNDS`].
/// Without a share (or an estimate) the stage runs once.
///
/// # Errors
/// What `attempt` returns.
pub(super) fn until_target<T>(
    share: Option<f64>,
    mut settings: BakeSettings,
    mut attempt: impl FnMut(&BakeSettings, u32) -> Result<(T, Option<f64>)>,
    raise: impl Fn(&mut BakeSettings, &T, f64) -> bool,
) -> Result<Rounds<T>> {
    let mut round = 1;
    loop {
        let (value, error) = attempt(&settings, round)?;
        let factor = match (share, error) {
            (Some(t), Some(e)) => count_factor(e, t),
            _ => 1.0,
        };
        if factor <= 1.0 || round == TARGET_ROUNDS || !raise(&mut settings, &value, factor) {
            return Ok(Rounds {
                value,
                round,
                missed: factor > 1.0,
            });
        }
        round += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stage whose error is 1/√count: from a pilot of 10 at 8% towards 2%, the count goes
    /// to 10·4²·1.2 = 192 (error 1.8%), where it stops.
    #[test]
    fn rounds_raise_the_count_until_the_share_is_reached() {
        let settings = {
            let mut s = BakeSettings::default();
            s.direct.samples_per_texel = 10;
            s
        };
        let mut seen = Vec::new();
        let rounds = until_target(
            Some(0.02),
            settings,
            |s, round| {
                seen.push((round, s.direct.samples_per_texel));
                let error = 0.08 * (10.0 / s.direct.samples_per_texel as f64).sqrt();
                Ok((s.direct.samples_per_texel, Some(error)))
            },
            |s, _, factor| {
                let next = scaled(s.direct.samples_per_texel, factor, 4096);
                let changed = next != s.direct.samples_per_texel;
                s.direct.samples_per_texel = next;
                changed
            },
        )
        .unwrap();
        assert_eq!(seen, vec![(1, 10), (2, 192)]);
        assert_eq!((rounds.value, rounds.round, rounds.missed), (192, 2, false));
    }

    #[test]
    fn a_capped_count_stops_and_reports_the_miss() {
        let rounds = until_target(
            Some(0.01),
            BakeSettings::default(),
            |_, _| Ok(((), Some(0.5))),
            |_, _, _| false,
        )
        .unwrap();
        assert_eq!((rounds.round, rounds.missed), (1, true));
        let once = until_target(
            None,
            BakeSettings::default(),
            |_, _| Ok(((), Some(0.5))),
            |_, _, _| true,
        )
        .unwrap();
        assert_eq!((once.round, once.missed), (1, false));
    }
}
