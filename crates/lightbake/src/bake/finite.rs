//! No non-finite value leaves a stage: every stage's output (per-patch light, the pages after
//! each pass over them, the volume's probes) is checked in one pass, and the first NaN or
//! infinity found stops the bake with an internal error naming the stage, the texel (page,
//! x, y), its instance and the value — before anything is written. The writers check again
//! ([`crate::output::images`]).
//!
//! With the `internals` feature, [`inject_nan`] makes the check of one named stage find a NaN
//! it plants first, so a test can see each check fire.

use glam::Vec3;

use crate::error::{BakeError, Result};
use crate::lightmap::LightmapPage;
use crate::raster::Patches;
use crate::scene::Scene;

#[cfg(feature = "internals")]
static INJECT: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Makes the finite check of `stage` (or of none, for `None`) plant a NaN in the first value
/// it checks. For tests.
#[cfg(feature = "internals")]
pub fn inject_nan(stage: Option<&str>) {
    *INJECT.lock().unwrap_or_else(|e| e.into_inner()) = stage.map(str::to_string);
}

/// Whether a NaN is to be planted in `stage`'s output.
fn injected(stage: &str) -> bool {
    #[cfg(feature = "internals")]
    {
        INJECT.lock().unwrap_or_else(|e| e.into_inner()).as_deref() == Some(stage)
    }
    #[cfg(not(feature = "internals"))]
    {
        let _ = stage;
        false
    }
}

/// The error for a non-finite `value` at texel (`x`, `y`) of page `page` (`width` texels
/// across), naming the instance the texel belongs to.
#[allow(clippy::too_many_arguments)]
fn error(
    stage: &str,
    scene: &Scene,
    patches: &Patches,
    page: u32,
    width: u32,
    (x, y): (u32, u32),
    value: Vec3,
) -> BakeError {
    let patch = patches
        .page_index
        .get(page as usize)
        .and_then(|index| index.get((y as u64 * width as u64 + x as u64) as usize))
        .filter(|&&i| i != u32::MAX);
    let instance = patch.map_or_else(
        || "a padding texel".to_string(),
        |&i| {
            let ii = patches.patches[i as usize].instance as usize;
            scene.instances.get(ii).map_or_else(
                || format!("instance {ii}"),
                |inst| format!("instance '{}'", inst.name),
            )
        },
    );
    BakeError::NonFinite {
        stage: stage.to_string(),
        place: format!("texel ({x}, {y}) of page {page}, {instance}"),
        value: format!("{value:?}"),
    }
}

/// Checks a per-patch output of `stage` (one value per patch).
///
/// # Errors
/// [`BakeError::NonFinite`] at the first non-finite value.
pub(super) fn patches(
    stage: &str,
    scene: &Scene,
    patches: &Patches,
    values: &mut [Vec3],
) -> Result<()> {
    if injected(stage)
        && let Some(v) = values.first_mut()
    {
        *v = Vec3::NAN;
    }
    let Some(i) = values.iter().position(|v| !v.is_finite()) else {
        return Ok(());
    };
    let (place, instance) = match patches.patches.get(i) {
        Some(p) => (
            format!("texel ({}, {}) of page {}", p.x, p.y, p.page),
            scene
                .instances
                .get(p.instance as usize)
                .map_or_else(String::new, |inst| format!(", instance '{}'", inst.name)),
        ),
        None => (format!("value {i}"), String::new()),
    };
    Err(BakeError::NonFinite {
        stage: stage.to_string(),
        place: format!("{place}{instance}"),
        value: format!("{:?}", values[i]),
    })
}

/// Checks the pages after `stage`.
///
/// # Errors
/// [`BakeError::NonFinite`] at the first non-finite texel.
pub(super) fn pages(
    stage: &str,
    scene: &Scene,
    patches: &Patches,
    pages: &mut [LightmapPage],
) -> Result<()> {
    if injected(stage)
        && let Some(t) = pages.first_mut().and_then(|p| p.texels.first_mut())
    {
        *t = Vec3::NAN;
    }
    for (pi, page) in pages.iter().enumerate() {
        if let Some(k) = page.texels.iter().position(|t| !t.is_finite()) {
            let (x, y) = (k as u32 % page.width, k as u32 / page.width);
            return Err(error(
                stage,
                scene,
                patches,
                pi as u32,
                page.width,
                (x, y),
                page.texels[k],
            ));
        }
    }
    Ok(())
}

/// Checks the irradiance volume's probes.
///
/// # Errors
/// [`BakeError::NonFinite`] at the first non-finite probe.
pub(super) fn probes(voxels: &mut [[Vec3; 6]]) -> Result<()> {
    if injected("volume")
        && let Some(v) = voxels.first_mut()
    {
        v[0] = Vec3::NAN;
    }
    match voxels.iter().position(|v| v.iter().any(|s| !s.is_finite())) {
        None => Ok(()),
        Some(i) => Err(BakeError::NonFinite {
            stage: "volume".into(),
            place: format!("probe {i}"),
            value: format!("{:?}", voxels[i]),
        }),
    }
}
