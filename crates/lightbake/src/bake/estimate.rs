//! The bake's error estimate after the lighting passes: the sampling stages' noise once the
//! denoiser has run, and the texel grid's own error ([`crate::lightmap::grid_error`]) added
//! in quadrature.

use glam::Vec3;

use super::stages::Stages;
use super::valid;
use crate::bvh::RayScene;
use crate::context::BakeContext;
use crate::error::Result;
use crate::error_estimate::ErrorEstimate;
use crate::lightmap::grid_error::grid_error;
use crate::lights::Emitters;
use crate::progress::RayKind;
use crate::raster::Patches;
use crate::runner::StageRunner;
use crate::stage::Stage;

/// The bake's error estimate after the denoiser: its per-texel errors (noise and the bias it
/// added, lux) with the hierarchical solve's coarse bias added in quadrature, relative to the
/// value `before` was.
pub(super) fn denoised_error(
    patches: &Patches,
    error: &[f32],
    before: &ErrorEstimate,
    coarse_bias: Option<f64>,
) -> ErrorEstimate {
    let filtered = ErrorEstimate::from_standard_errors(
        &valid(patches, error),
        before.value_rms,
        "denoised texels: their noise after the filter and the bias it added",
    );
    let bias = coarse_bias.unwrap_or(0.0) * before.value_rms;
    let coarse = ErrorEstimate {
        rms: bias,
        p95_abs: bias,
        texels: filtered.texels,
        method: "the coarse level's bias".into(),
        ..ErrorEstimate::default()
    };
    ErrorEstimate {
        method:
            "the denoised texels' noise and the bias the filter added, with the coarse level's bias"
                .into(),
        ..ErrorEstimate::combine([&filtered, &coarse], before.value_rms)
    }
}

/// The "grid error" stage: the texel grid's error of the direct light `direct` (lux per
/// patch; `direct_se` its standard error) added in quadrature to the sampling stages'
/// `estimate` (relative to `value_rms`, lux), that estimate first scaled to the noise a point
/// shows between texels (`GridError::point_noise`) unless the texels were `denoised`. The
/// estimate as it was when no point could be checked.
#[allow(clippy::too_many_arguments)]
pub(super) fn with_grid_error(
    ctx: &BakeContext<'_>,
    rays: &RayScene,
    emitters: &Emitters,
    stages: &mut Stages<'_>,
    direct: &[Vec3],
    direct_se: &[f32],
    (estimate, denoised): (Option<ErrorEstimate>, bool),
    value_rms: f64,
) -> Result<Option<ErrorEstimate>> {
    let grid = stages.run(Stage::GridError, 1, || {
        let grid = grid_error(
            ctx.scene,
            ctx.layout,
            ctx.patches,
            rays,
            ctx.plan,
            emitters,
            ctx.settings,
            direct,
            direct_se,
            value_rms,
        );
        let (rays, note) = grid.as_ref().map_or_else(
            || (0, "no point of a valid texel could be placed".to_string()),
            |g| {
                (
                    g.rays,
                    format!(
                        "{:.2}% at {} points (95th percentile {:.2}%; the worst point carries {:.0}% of the squared error), added to the estimate{}",
                        100.0 * g.estimate.relative_rms,
                        g.points,
                        100.0 * g.estimate.p95,
                        100.0 * g.worst_share,
                        if denoised {
                            String::new()
                        } else {
                            format!(
                                "; a point shows {:.2}× a texel's noise",
                                g.point_noise
                            )
                        }
                    ),
                )
            },
        );
        Ok((grid, rays, note))
    })?;
    stages.annotate(RayKind::Shadow, grid.as_ref().map(|g| g.estimate.clone()));
    Ok(match (estimate, grid) {
        (estimate, None) => estimate,
        (None, Some(g)) => Some(g.estimate),
        (Some(e), Some(g)) => {
            let k = if denoised { 1.0 } else { g.point_noise };
            let at_points = ErrorEstimate {
                rms: k * e.rms,
                p95_abs: k * e.p95_abs,
                ..e.clone()
            };
            let scaled = if denoised {
                String::new()
            } else {
                format!(" (×{k:.2}: the noise a point shows between texels)")
            };
            Some(ErrorEstimate {
                method: format!("{}{scaled}, and {}", e.method, g.estimate.method),
                ..ErrorEstimate::combine([&at_points, &g.estimate], value_rms)
            })
        }
    })
}
