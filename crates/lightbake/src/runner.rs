//! How a lighting pass runs its stages, without knowing the process it runs in: the driver
//! implements [`StageRunner`] (each stage timed, counted, recorded and published to the
//! progress, a cancel seen between stages, previews) and [`WorkScope`] (which of a stage's
//! work units this process computes: all of them; one shard's share of a bake split across
//! processes, the rest read from the other shards; or the texels of a subset, the rest kept
//! from an earlier run). A pass composes its own stages
//! through them: it says what it computes, not where or for whom.

use glam::Vec3;

use crate::context::BakeContext;
use crate::error::Result;
use crate::error_estimate::ErrorEstimate;
use crate::progress::{Progress, RayKind};
use crate::stage::{Stage, StageRun};

/// Runs the stages of a bake; `'p` is the life of the bake's progress.
pub trait StageRunner<'p> {
    /// Where this runner's stages compute their work units.
    type Scope: WorkScope;

    /// Where the stages' work units run.
    fn scope(&self) -> Self::Scope;

    /// The progress the stages report to (and whose cancel they watch).
    fn progress(&self) -> &'p Progress;

    /// Runs stage `run` of `units` work units: `f` returns its value, the rays it traced and
    /// a note for the report.
    ///
    /// # Errors
    /// What `f` returns, or a cancel seen when the stage ends.
    fn run<T>(
        &mut self,
        run: impl Into<StageRun>,
        units: u64,
        f: impl FnOnce() -> Result<(T, u64, String)>,
    ) -> Result<T>;

    /// Sets the last stage's ray kind and error estimate (and publishes the estimate).
    fn annotate(&mut self, kind: RayKind, error: Option<ErrorEstimate>);

    /// Sets how many of the last stage's rays were any-hit visibility tests.
    fn shadow_rays(&mut self, rays: u64);

    /// Whether the bake publishes previews (so a pass may build one).
    fn previewing(&self) -> bool;

    /// Publishes the indirect preview: the direct light plus `indirect` (lux per patch) and
    /// the ambient term `ambient` (lux) on every texel.
    fn preview_indirect(&self, ctx: &BakeContext<'_>, indirect: &[Vec3], ambient: Vec3);
}

/// Which of a stage's work units this process computes.
pub trait WorkScope: Copy {
    /// The values of stage `stage`'s `items` items (item `i` belongs to patch `patch(i)`) and
    /// the (closest, any-hit) rays this process traced for them: `compute(only)` computes the
    /// items `only` marks (`None`: every item), the rest come from elsewhere. `summary`, when
    /// the pass knows it, states each item's inputs in one number (lux, luminance) whose
    /// change bounds the change of the item's value — for a gather, the coarse light the node
    /// gathers — so that a bake following an edit keeps the items whose inputs barely moved.
    ///
    /// # Errors
    /// A part of another process that cannot be read, or a cancel.
    fn split<T: Record>(
        self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
        compute: impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])>;

    /// Like [`WorkScope::split`] for a stage that a bake split across processes computes
    /// whole in one of them (after the shards' part, in the merge): every item is computed
    /// here but in a bake that follows an edit, which keeps the items whose `summary` barely
    /// moved.
    ///
    /// # Errors
    /// As [`WorkScope::split`].
    fn kept_across_edits<T: Record>(
        self,
        stage: Stage,
        items: usize,
        patch: impl Fn(usize) -> usize,
        summary: Option<&[f32]>,
        compute: impl Fn(Option<&[bool]>) -> (Vec<T>, [u64; 2]),
    ) -> Result<(Vec<T>, [u64; 2])>;

    /// The bytes that whole stage `stage` of the earlier bake this one follows kept under
    /// `key` ([`WorkScope::keep_state`]), when that bake had the same texel patches and
    /// settings; `None` otherwise (and in a bake that follows none).
    fn earlier_state(self, stage: Stage, key: u64) -> Option<Vec<u8>>;

    /// Keeps `bytes()` as whole stage `stage`'s state under `key` (the pass's hash of what
    /// they were made from) for a later bake, in place of any it kept before; nothing where
    /// no later bake follows this one's values (`bytes` is then not called).
    fn keep_state(self, stage: Stage, key: u64, bytes: impl FnOnce() -> Vec<u8>);

    /// Ends this process here when the rest of the bake is another process's (nothing for a
    /// bake in one process).
    ///
    /// # Errors
    /// The stop of a process that did its part.
    fn stop_after_split(self) -> Result<()>;
}

/// A value a split stage computes per item, as bytes (little-endian f32s), so that split
/// processes can exchange them.
pub trait Record: Copy + Default {
    /// Bytes per value.
    const BYTES: usize;
    /// Appends the value.
    fn put(&self, out: &mut Vec<u8>);
    /// Reads a value from `BYTES` bytes.
    fn get(b: &[u8]) -> Self;
    /// The value's level (luminance of its light, lux): what an incremental bake weighs a
    /// change of the value's inputs against. Default 0 (every change counts).
    fn level(&self) -> f32 {
        0.0
    }
}

fn f32s(b: &[u8], k: usize) -> f32 {
    f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
}

impl Record for (Vec3, f32) {
    const BYTES: usize = 16;
    fn put(&self, out: &mut Vec<u8>) {
        for c in [self.0.x, self.0.y, self.0.z, self.1] {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn get(b: &[u8]) -> Self {
        (Vec3::new(f32s(b, 0), f32s(b, 1), f32s(b, 2)), f32s(b, 3))
    }
    fn level(&self) -> f32 {
        crate::color::luminance(self.0)
    }
}

impl Record for (Vec3, f32, Vec3) {
    const BYTES: usize = 28;
    fn put(&self, out: &mut Vec<u8>) {
        let (a, s, c) = self;
        for v in [a.x, a.y, a.z, *s, c.x, c.y, c.z] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    fn get(b: &[u8]) -> Self {
        (
            Vec3::new(f32s(b, 0), f32s(b, 1), f32s(b, 2)),
            f32s(b, 3),
            Vec3::new(f32s(b, 4), f32s(b, 5), f32s(b, 6)),
        )
    }
    fn level(&self) -> f32 {
        crate::color::luminance(self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_bit_for_bit() {
        let v = (
            Vec3::new(1.5, -2.0, f32::MIN_POSITIVE),
            0.25f32,
            Vec3::splat(3.0),
        );
        let mut b = Vec::new();
        v.put(&mut b);
        assert_eq!(b.len(), 28);
        assert_eq!(<(Vec3, f32, Vec3)>::get(&b), v);
        let w = (Vec3::new(-0.0, f32::MAX, 1e-30), -7.5f32);
        let mut b = Vec::new();
        w.put(&mut b);
        assert_eq!(b.len(), 16);
        let back = <(Vec3, f32)>::get(&b);
        assert_eq!(back.0.x.to_bits(), w.0.x.to_bits());
        assert_eq!(back, w);
    }
}
