//! Progress and cancellation shared between a running bake and whoever watches it (the CLI's
//! progress bars, the Bevy plugin's progress resource).
//!
//! The bake updates a few atomics; a watcher reads [`Progress::snapshot`] whenever it likes.
//! [`Progress::cancel`] asks the bake to stop at its next check; it then returns
//! [`crate::BakeError::Cancelled`] without writing anything.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Thread-safe bake progress.
#[derive(Debug, Default)]
pub struct Progress {
    stage: Mutex<String>,
    stage_index: AtomicU64,
    done: AtomicU64,
    total: AtomicU64,
    cancelled: AtomicBool,
}

/// A copy of the progress at one moment.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ProgressSnapshot {
    /// Name of the running stage.
    pub stage: String,
    /// How many stages have started (1 for the first).
    pub stage_index: u64,
    /// Work units done in this stage.
    pub done: u64,
    /// Work units in this stage (0 when unknown).
    pub total: u64,
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
    pub fn begin(&self, stage: &str, total: u64) {
        *self.stage.lock().unwrap_or_else(|e| e.into_inner()) = stage.to_string();
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
        self.stage_index.fetch_add(1, Ordering::Relaxed);
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
            stage: self.stage.lock().unwrap_or_else(|e| e.into_inner()).clone(),
            stage_index: self.stage_index.load(Ordering::Relaxed),
            done: self.done.load(Ordering::Relaxed),
            total: self.total.load(Ordering::Relaxed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_reset_counts() {
        let p = Progress::new();
        p.begin("a", 10);
        p.advance(4);
        assert_eq!(p.snapshot().fraction(), 0.4);
        p.begin("b", 0);
        let s = p.snapshot();
        assert_eq!((s.stage.as_str(), s.stage_index, s.done), ("b", 2, 0));
        assert!(!p.is_cancelled());
        p.cancel();
        assert!(p.is_cancelled());
    }
}
