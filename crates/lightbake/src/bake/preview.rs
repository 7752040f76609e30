//! Progressive previews: the lightmaps as they stand while a bake runs, for an editor or a
//! game to show before the end. A bake that publishes previews ([`PreviewSlot::enabled`])
//! assembles its pages (hidden texels filled, padding dilated, as the final pages are) at
//! three points:
//!
//! 1. [`PreviewKind::Direct`]: the direct light, when the direct stage ends;
//! 2. [`PreviewKind::Indirect`]: the direct light plus the indirect solution's first
//!    answer — the hierarchical solve's coarse level (each texel the reflected light of its
//!    cell), or the full matrix's solve — plus progressive radiosity's ambient term for the
//!    energy that solve left undistributed (Cohen, Chen, Wallace & Greenberg 1988; see
//!    `solve::System::ambient_term`);
//! 3. [`PreviewKind::Final`]: the finished pages (what the bake returns).
//!
//! The slot keeps only the latest preview; a watcher polls [`PreviewSlot::latest`] and
//! compares [`Preview::sequence`] with what it showed last.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use glam::Vec3;
use serde::Serialize;

use crate::lightmap::{Assembly, LightmapPage};
use crate::raster::Patches;
use crate::unwrap::Layout;

/// Which picture a preview is, in the order a bake publishes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreviewKind {
    /// Direct light only.
    Direct,
    /// Direct light plus the first indirect solution and the ambient term.
    Indirect,
    /// The finished lightmaps.
    Final,
}

impl PreviewKind {
    /// A short description, for status lines.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Direct => "direct light",
            Self::Indirect => "direct light + coarse indirect light (ambient term for the rest)",
            Self::Final => "final",
        }
    }
}

/// The lightmaps at one point of a bake.
#[derive(Debug)]
pub struct Preview {
    /// Which point.
    pub kind: PreviewKind,
    /// 1 for the bake's first preview, then 2, 3, …
    pub sequence: u32,
    /// The layout the pages belong to (the meshes' `UV_1` and the instances' rectangles): a
    /// watcher applies it before showing the first preview.
    pub layout: Arc<Layout>,
    /// The pages (E/π, linear RGB), filled and dilated like the final ones.
    pub pages: Vec<LightmapPage>,
    /// The ambient term included, lux (zero but for [`PreviewKind::Indirect`]).
    pub ambient: Vec3,
}

/// A function that sees every preview as it is published.
type Observer = Box<dyn Fn(&Arc<Preview>) + Send + Sync>;

/// Where a running bake leaves its previews.
#[derive(Default)]
pub struct PreviewSlot {
    enabled: AtomicBool,
    latest: Mutex<Option<Arc<Preview>>>,
    layout: Mutex<Option<Arc<Layout>>>,
    observer: Option<Observer>,
}

impl std::fmt::Debug for PreviewSlot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PreviewSlot")
            .field("enabled", &self.is_enabled())
            .field("latest", &self.latest().map(|p| (p.kind, p.sequence)))
            .finish_non_exhaustive()
    }
}

impl PreviewSlot {
    /// A slot that asks for previews and hands each one to `observer` as it is published
    /// (on the bake's thread), besides keeping the latest.
    pub fn observed(observer: impl Fn(&Arc<Preview>) + Send + Sync + 'static) -> Self {
        Self {
            enabled: AtomicBool::new(true),
            observer: Some(Box::new(observer)),
            ..Self::default()
        }
    }

    /// A slot that asks the bake for previews.
    pub fn enabled() -> Self {
        Self {
            enabled: AtomicBool::new(true),
            ..Self::default()
        }
    }

    /// Whether the bake should assemble previews.
    pub fn is_enabled(&self) -> bool {
        self.enabled.load(Ordering::Relaxed)
    }

    /// The latest preview, if any.
    pub fn latest(&self) -> Option<Arc<Preview>> {
        self.latest
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// Publishes pages of `kind` (with `ambient` included) over `layout`.
    pub(super) fn publish(
        &self,
        kind: PreviewKind,
        layout: &Layout,
        pages: Vec<LightmapPage>,
        ambient: Vec3,
    ) {
        let layout = {
            let mut kept = self.layout.lock().unwrap_or_else(|e| e.into_inner());
            Arc::clone(kept.get_or_insert_with(|| Arc::new(layout.clone())))
        };
        let mut latest = self.latest.lock().unwrap_or_else(|e| e.into_inner());
        let sequence = latest.as_ref().map_or(1, |p| p.sequence + 1);
        let preview = Arc::new(Preview {
            kind,
            sequence,
            layout,
            pages,
            ambient,
        });
        *latest = Some(Arc::clone(&preview));
        drop(latest);
        if let Some(observe) = &self.observer {
            observe(&preview);
        }
    }
}

/// Pages of `irradiance` per patch (lux), hidden texels filled and padding dilated as the
/// bake does for its final pages (without the denoiser, contact fit and stitch).
pub(super) fn pages(
    layout: &Layout,
    patches: &Patches,
    irradiance: &[Vec3],
    padding: u32,
) -> Vec<LightmapPage> {
    let mut a = Assembly::new(layout, patches, irradiance);
    a.fill_hidden(patches);
    a.dilate(padding + 2);
    a.pages
}
