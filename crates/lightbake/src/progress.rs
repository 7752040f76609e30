//! Progress and cancellation shared between a running bake and whoever watches it (the CLI's
//! progress bars, the Bevy plugin's progress resource).
//!
//! The bake updates a few atomics; a watcher reads [`Progress::snapshot`] whenever it likes.
//! [`Progress::cancel`] asks the bake to stop at its next check; it then returns
//! [`crate::BakeError::Cancelled`] without writing anything.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};

use serde::Serialize;

use crate::error_estimate::ErrorEstimate;
use crate::stage::StageRun;

/// Counters of one stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageStats {
    /// The stage and its round.
    #[serde(flatten)]
    pub run: StageRun,
    /// Wall time, seconds.
    pub seconds: f64,
    /// Rays traced.
    pub rays: u64,
    /// What most of its rays are (for the ray-tracing floor).
    pub ray_kind: RayKind,
    /// Of `rays`, the any-hit ones of a stage whose `ray_kind` is [`RayKind::Closest`] (the
    /// visibility tests of its rays' start points); 0 otherwise.
    pub shadow_rays: u64,
    /// The stage's estimate of its own error (Monte Carlo stages; see [`crate::error_estimate`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorEstimate>,
    /// A short note (counts, sizes).
    pub note: String,
}

/// The kind of ray a stage mostly traces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayKind {
    /// No rays.
    #[default]
    None,
    /// Closest-hit rays (gathers, walks, validity probes).
    Closest,
    /// Any-hit shadow rays.
    Shadow,
}

impl StageStats {
    /// (closest-hit, any-hit) rays, for the ray-tracing floor.
    pub fn rays_by_kind(&self) -> (u64, u64) {
        match self.ray_kind {
            RayKind::None => (0, 0),
            RayKind::Closest => (
                self.rays - self.shadow_rays.min(self.rays),
                self.shadow_rays,
            ),
            RayKind::Shadow => (0, self.rays),
        }
    }

    /// Million rays per second (0 when no rays).
    pub fn mrays_per_second(&self) -> f64 {
        if self.rays == 0 || self.seconds <= 0.0 {
            0.0
        } else {
            self.rays as f64 / self.seconds / 1e6
        }
    }
}

/// Thread-safe bake progress.
#[derive(Debug)]
pub struct Progress {
    stage: Mutex<Option<StageRun>>,
    stage_index: AtomicU64,
    done: AtomicU64,
    total: AtomicU64,
    /// f32 bits of the running stage's error estimate; `NO_ESTIMATE` when it has none.
    estimate: AtomicU32,
    finished: Mutex<Vec<StageStats>>,
    cancelled: AtomicBool,
}

/// Bit pattern of "no estimate" (a NaN).
const NO_ESTIMATE: u32 = f32::NAN.to_bits();

impl Default for Progress {
    fn default() -> Self {
        Self {
            stage: Mutex::default(),
            stage_index: AtomicU64::new(0),
            done: AtomicU64::new(0),
            total: AtomicU64::new(0),
            estimate: AtomicU32::new(NO_ESTIMATE),
            finished: Mutex::default(),
            cancelled: AtomicBool::new(false),
        }
    }
}

/// A copy of the progress at one moment.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ProgressSnapshot {
    /// The running stage (`None` before the first).
    pub stage: Option<StageRun>,
    /// How many stages have started (1 for the first).
    pub stage_index: u64,
    /// Work units done in this stage.
    pub done: u64,
    /// Work units in this stage (0 when unknown).
    pub total: u64,
    /// The running stage's own estimate of the relative error of what it has computed so far
    /// (the radiosity solvers publish theirs after every sweep: the error bound
    /// ‖B − Bₖ‖∞/‖Bₖ‖∞ when the method has one, else the relative residual). `None` when the
    /// stage has no estimate.
    pub error_estimate: Option<f32>,
    /// The stages finished so far, in order: wall time, rays and (for sampling stages) their
    /// error estimate.
    pub finished: Vec<StageStats>,
}

impl ProgressSnapshot {
    /// Fraction of the current stage done, in [0, 1].
    pub fn fraction(&self) -> f32 {
        if self.total == 0 {
            0.0
        } else {
            (self.done as f64 / self.total as f64).min(1.0) as f32
        }
    }
}

impl Progress {
    /// Fresh progress, not cancelled.
    pub fn new() -> Self {
        Self::default()
    }

    /// Starts a stage with `total` work units.
    pub fn begin(&self, stage: impl Into<StageRun>, total: u64) {
        *self.stage.lock().unwrap_or_else(|e| e.into_inner()) = Some(stage.into());
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
        self.estimate.store(NO_ESTIMATE, Ordering::Relaxed);
        self.stage_index.fetch_add(1, Ordering::Relaxed);
    }

    /// Publishes the running stage's estimate of its relative error (see
    /// [`ProgressSnapshot::error_estimate`]). Non-finite values clear it.
    pub fn set_error_estimate(&self, relative_error: f64) {
        let bits = if relative_error.is_finite() {
            (relative_error as f32).to_bits()
        } else {
            NO_ESTIMATE
        };
        self.estimate.store(bits, Ordering::Relaxed);
    }

    /// Records the counters of finished stage number `index` (0-based; replaces what was
    /// recorded under that index).
    pub fn record_stage(&self, index: usize, stats: &StageStats) {
        let mut f = self.finished.lock().unwrap_or_else(|e| e.into_inner());
        if index < f.len() {
            f[index] = stats.clone();
        } else {
            f.push(stats.clone());
        }
    }

    /// Records `n` more units done.
    pub fn advance(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }

    /// Asks the bake to stop.
    pub fn cancel(&self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }

    /// Whether [`Progress::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::Relaxed)
    }

    /// The current state.
    pub fn snapshot(&self) -> ProgressSnapshot {
        ProgressSnapshot {
            stage: *self.stage.lock().unwrap_or_else(|e| e.into_inner()),
            stage_index: self.stage_index.load(Ordering::Relaxed),
            done: self.done.load(Ordering::Relaxed),
            total: self.total.load(Ordering::Relaxed),
            error_estimate: Some(f32::from_bits(self.estimate.load(Ordering::Relaxed)))
                .filter(|e| e.is_finite()),
            finished: self
                .finished
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stage::Stage;

    #[test]
    fn stages_reset_counts() {
        let p = Progress::new();
        p.begin(Stage::Unwrap, 10);
        p.advance(4);
        assert_eq!(p.snapshot().fraction(), 0.4);
        p.begin(Stage::Bvh, 0);
        let s = p.snapshot();
        assert_eq!(
            (s.stage, s.stage_index, s.done),
            (Some(StageRun::first(Stage::Bvh)), 2, 0)
        );
        assert_eq!(s.error_estimate, None);
        p.set_error_estimate(0.25);
        assert_eq!(p.snapshot().error_estimate, Some(0.25));
        p.begin(Stage::Raster, 1);
        assert_eq!(
            p.snapshot().error_estimate,
            None,
            "a new stage has no estimate yet"
        );
        p.set_error_estimate(0.0);
        assert_eq!(p.snapshot().error_estimate, Some(0.0));
        assert_eq!(Progress::default().snapshot().error_estimate, None);
        assert!(!p.is_cancelled());
        p.cancel();
        assert!(p.is_cancelled());
    }
}
