//! A bake on a thread of its own, watched through its progress and cancelled on request: what
//! the `bake` command and the Bevy plugin both run. The thread has its own rayon pool of
//! `settings.threads` workers, so a game's task pools stay free for rendering.

use std::sync::Arc;
use std::thread::JoinHandle;

use super::BakeOutput;
use super::preview::{Preview, PreviewSlot};
use crate::error::{BakeError, Result};
use crate::progress::{Progress, ProgressSnapshot};

/// A running bake (and whatever follows it on the same thread, such as writing its files),
/// started by [`super::BakeBuilder::spawn`] or [`super::BakeBuilder::spawn_then`].
#[derive(Debug)]
pub struct BakeHandle<T = BakeOutput> {
    thread: Option<JoinHandle<Result<T>>>,
    progress: Arc<Progress>,
    previews: Arc<PreviewSlot>,
}

impl<T: Send + 'static> BakeHandle<T> {
    /// Runs `work` on a new thread named `lightbake`, watched through `progress` and
    /// `previews` ([`super::BakeBuilder::spawn_then`] starts bakes this way).
    pub(super) fn start(
        progress: Arc<Progress>,
        previews: Arc<PreviewSlot>,
        work: impl FnOnce() -> Result<T> + Send + 'static,
    ) -> Result<Self> {
        let thread = std::thread::Builder::new()
            .name("lightbake".into())
            .spawn(work)
            .map_err(|source| BakeError::Thread { source })?;
        Ok(Self {
            thread: Some(thread),
            progress,
            previews,
        })
    }

    /// The latest progressive preview of the lightmaps (a bake set up with
    /// [`super::BakeBuilder::previews`]; `None` before the first and for other bakes).
    pub fn preview(&self) -> Option<Arc<Preview>> {
        self.previews.latest()
    }

    /// The bake's progress (stage, fraction, error estimate, finished stages).
    pub fn progress(&self) -> &Progress {
        &self.progress
    }

    /// A copy of the progress now.
    pub fn snapshot(&self) -> ProgressSnapshot {
        self.progress.snapshot()
    }

    /// Asks the bake to stop at its next check; it then ends with [`BakeError::Cancelled`].
    pub fn cancel(&self) {
        self.progress.cancel();
    }

    /// Whether the thread has finished (so [`Self::join`] will not wait).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Waits for the end and returns the result.
    ///
    /// # Errors
    /// The bake's error, or [`BakeError::Internal`] when the thread panicked (a bug).
    pub fn join(mut self) -> Result<T> {
        self.take_result()
    }

    /// The result when the thread has finished, without waiting; `None` while it runs, and
    /// after the result has been taken.
    pub fn try_join(&mut self) -> Option<Result<T>> {
        (self.thread.is_some() && self.is_finished()).then(|| self.take_result())
    }

    fn take_result(&mut self) -> Result<T> {
        let Some(thread) = self.thread.take() else {
            return Err(BakeError::Internal {
                message: "the bake's result was already taken".into(),
            });
        };
        thread.join().unwrap_or_else(|payload| {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(BakeError::Internal {
                message: format!("the bake thread panicked: {message}"),
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::BakeBuilder;
    use crate::scene::testscenes::{CornellLight, cornell_box};
    use crate::settings::BakeSettings;

    #[test]
    fn a_handle_bakes_and_reports_panics() {
        let settings = {
            let mut s = BakeSettings::preview();
            s.layout.texel_density = Some(4.0);
            s.layout.texel_density_from_scene = false;
            s.direct.samples_per_texel = 2;
            s.method = crate::settings::Method::Direct;
            s
        };
        let scene = cornell_box(CornellLight::Point);
        let handle = BakeBuilder::new(scene.clone())
            .settings(settings.clone())
            .spawn()
            .unwrap();
        let output = handle.join().unwrap();
        assert!(!output.pages.is_empty());

        let mut handle: BakeHandle<()> = BakeBuilder::new(scene)
            .settings(settings)
            .spawn_then(|_, _, _| panic!("on purpose"))
            .unwrap();
        let result = loop {
            if let Some(r) = handle.try_join() {
                break r;
            }
            std::thread::yield_now();
        };
        let message = result.unwrap_err().to_string();
        assert!(message.contains("panicked: on purpose"), "{message}");
        assert!(handle.try_join().is_none(), "the result is taken once");
    }
}
