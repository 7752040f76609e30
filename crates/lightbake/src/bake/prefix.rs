//! The geometry stages every bake starts with, each one stage: the plan (refused early when
//! the texel count or the rays alone are over budget), the unwrap, the density that follows
//! the light, the memory admission (with the irradiance volume's grid), and the BVH.

use super::preview::PreviewSlot;
use super::stages::Stages;
use crate::bvh::RayScene;
use crate::density::DensityReport;
use crate::error::Result;
use crate::memory::{self, MemoryEstimate};
use crate::plan::BakePlan;
use crate::probes::VolumeGrid;
use crate::report::Decision;
use crate::runner::StageRunner;
use crate::scene::Scene;
use crate::settings::{BakeSettings, Method};
use crate::stage::Stage;
use crate::unwrap::{Layout, unwrap_scene};

/// The plan (stage `plan`), refused when the texels alone would not fit the memory budget or
/// the rays the ray budget.
pub(super) fn plan(
    scene: &Scene,
    settings: &BakeSettings,
    stages: &mut Stages<'_>,
) -> Result<BakePlan> {
    let earlier = stages.scope().texel_run().and_then(|r| r.earlier_density());
    let plan = stages.run(Stage::Plan, 1, || {
        let mut plan = BakePlan::new(scene, settings);
        if let Some(density) = earlier {
            // An edit keeps the cached bake's layout, so its density: a new one would move
            // every chart.
            plan.follow_layout(density);
        }
        let note = format!("{} texels/m", crate::plan::density_text(plan.texel_density));
        Ok((plan, 0, note))
    })?;
    memory::estimate_from_area(scene, plan.texel_density).check(settings.memory_budget_mib)?;
    plan.check_rays(settings)?;
    Ok(plan)
}

/// Lightmap UVs packed into pages at the plan's density (stage `unwrap`).
pub(super) fn unwrap(
    scene: &Scene,
    settings: &BakeSettings,
    plan: &BakePlan,
    stages: &mut Stages<'_>,
) -> Result<Layout> {
    if let Some(run) = stages.scope().texel_run()
        && let Some(earlier) = run.earlier_layout()
    {
        return stages.run(Stage::Unwrap, scene.meshes.len() as u64, || {
            let (layout, lines) =
                crate::unwrap::stable::follow(scene, settings, plan.texel_density, &earlier)?;
            let note = format!("the cached bake's layout followed: {}", lines.join("; "));
            run.layout_followed(lines);
            Ok((layout, 0, note))
        });
    }
    stages.run(Stage::Unwrap, scene.meshes.len() as u64, || {
        let layout = unwrap_scene(scene, settings, plan.texel_density)?;
        let note = format!(
            "{} mesh(es) xatlas, {} kept, {} page(s)",
            plan.meshes_to_unwrap,
            plan.meshes_keeping_uv1,
            layout.pages.len()
        );
        Ok((layout, 0, note))
    })
}

/// The density that follows the light (stage `density`, when the plan runs it): a pilot on
/// the first layout, which is then repacked. Returns the layout, the ray scene the pilot
/// traced (the lighting passes' own: the same triangles) and the density report; what was
/// decided goes in `decisions`.
pub(super) fn density(
    scene: &Scene,
    settings: &BakeSettings,
    plan: &BakePlan,
    layout: Layout,
    stages: &mut Stages<'_>,
    decisions: &mut Vec<Decision>,
) -> Result<(Layout, Option<RayScene>, Option<DensityReport>)> {
    if !plan.runs(Stage::Density) {
        return Ok((layout, None, None));
    }
    let (layout, rays, density) = stages.run(Stage::Density, 1, || {
        let rays = RayScene::build(scene);
        match crate::density::adapt(scene, settings, plan, &layout, &rays) {
            Ok((adapted, report)) => {
                let note = report.summary();
                let traced = report.rays;
                Ok(((adapted, rays, Ok(report)), traced, note))
            }
            Err(reason) => Ok(((layout, rays, Err(reason.clone())), 0, reason)),
        }
    })?;
    Ok(match density {
        Ok(report) => {
            decisions.push(Decision::ran(Stage::Density, report.summary()));
            (layout, Some(rays), Some(report))
        }
        Err(reason) => {
            decisions.push(Decision::skipped(Stage::Density, reason));
            (layout, Some(rays), None)
        }
    })
}

/// What the memory admission found.
pub(super) struct Admitted {
    /// The estimate the bake was admitted with.
    pub(super) estimate: MemoryEstimate,
    /// The irradiance volumes' grids, one per region of the level; empty when none is baked.
    pub(super) volume_grids: Vec<VolumeGrid>,
}

/// The memory the bake will take with `layout` (the volumes' grids planned here, so that a
/// spacing they cannot take is refused before the lighting passes run; previews kept),
/// checked against the budget.
pub(super) fn admit(
    scene: &Scene,
    settings: &BakeSettings,
    plan: &BakePlan,
    layout: &Layout,
    previews: &PreviewSlot,
    decisions: &mut Vec<Decision>,
) -> Result<Admitted> {
    let mut estimate = memory::estimate_from_layout(scene, layout);
    let volume_grids = if plan.runs(Stage::Volume) {
        crate::probes::plan_volumes(scene, layout, settings, plan.texel_density)?
    } else {
        Vec::new()
    };
    if !volume_grids.is_empty() {
        let probes: usize = volume_grids.iter().map(VolumeGrid::len).sum();
        estimate = estimate.with(
            "irradiance volumes",
            probes as u64 * crate::probes::volume::BYTES_PER_PROBE,
        );
        let boxes: Vec<String> = volume_grids
            .iter()
            .map(|g| {
                format!(
                    "{} × {} × {} probes {:.3e} m apart ({})",
                    g.resolution.x, g.resolution.y, g.resolution.z, g.spacing, g.reason
                )
            })
            .collect();
        let turned = volume_grids[0].rotation.to_axis_angle().1.to_degrees();
        decisions.push(Decision::ran(
            Stage::Volume,
            format!(
                "{} irradiance volume{} for dynamic objects{}, {} rays per probe: {}",
                volume_grids.len(),
                if volume_grids.len() == 1 { "" } else { "s" },
                if turned > 0.01 {
                    format!(", turned {turned:.1}° about the vertical with the walls")
                } else {
                    String::new()
                },
                settings.volume.probe_rays,
                boxes.join("; ")
            ),
        ));
    } else if plan.runs(Stage::Volume) {
        decisions.push(Decision::skipped(
            Stage::Volume,
            "no instance has a lightmap".into(),
        ));
    }
    if plan.runs(Stage::Indirect) && matches!(settings.method, Method::Vpl | Method::Hybrid) {
        estimate = estimate.with(
            "virtual point lights",
            crate::vpl::expected_vpls(scene, settings) * crate::vpl::cut::BYTES_PER_VPL,
        );
    }
    if previews.is_enabled() {
        // The direct light kept per patch (at most one per page texel, 12 bytes) and two
        // sets of pages alive at once (the preview shown and the one being made, 16 each).
        estimate = estimate.with("progressive previews", layout.page_texels() * (12 + 2 * 16));
    }
    estimate.check(settings.memory_budget_mib)?;
    Ok(Admitted {
        estimate,
        volume_grids,
    })
}

/// The BVH of `baked_scene` (stage `bvh`): the density pilot's (`early`, the same triangles)
/// when it built one.
pub(super) fn bvh(
    baked_scene: &Scene,
    early: Option<RayScene>,
    stages: &mut Stages<'_>,
) -> Result<RayScene> {
    stages.run(Stage::Bvh, 1, || {
        let reused = early.is_some();
        let rays = early.unwrap_or_else(|| RayScene::build(baked_scene));
        let (nodes, packets, bytes) = rays.bvh_size();
        let note = format!(
            "{} triangles, {nodes} eight-wide nodes, {packets} leaf packets, {:.1} MiB, traced with {}{}",
            rays.bvh_triangle_count(),
            bytes as f64 / 1048576.0,
            if rays.traces_with_avx2() { "AVX2" } else { "SSE" },
            if reused {
                " (built for the density pilot)"
            } else {
                ""
            }
        );
        Ok((rays, 0, note))
    })
}
