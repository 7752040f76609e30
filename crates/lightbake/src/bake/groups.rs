//! Light groups in the driver: the lighting and finishing passes once per group
//! ([`crate::settings::groups`]), over the texel patches, the unwrap and the BVH every group
//! shares, each group seeing only its own emitters. Light adds up, so the bake's own pages
//! and volume are the groups' sum, and a game shows any weighted sum of the groups' pages.

use std::time::Instant;

use glam::Vec3;

use super::stages::Stages;
use super::{Lit, light_patches, valid};
use crate::context::BakeContext;
use crate::error::Result;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lightmap::LightmapPage;
use crate::plan::BakePlan;
use crate::probes::{IrradianceVolume, VolumeGrid};
use crate::report::GroupReport;
use crate::scene::groups::GroupMembers;
use crate::unwrap::Layout;

/// One light group's output: its pages (E/π from its emitters alone, on the bake's layout)
/// and its irradiance volume.
#[derive(Clone, Debug)]
pub struct GroupPages {
    /// The group's name.
    pub name: String,
    /// Its pages, in the order and sizes of the bake's pages.
    pub pages: Vec<LightmapPage>,
    /// Its irradiance volumes, in the order of the bake's; empty when the bake has none.
    pub irradiance_volumes: Vec<IrradianceVolume>,
    /// Its members, time, rays and error.
    pub report: GroupReport,
}

/// Lights the scene of `ctx` once per group in `groups` and returns `lit` with the groups'
/// pages, their sum as the bake's pages (and volume) and the estimate of the sum; the floor
/// calibration, the filled-texel counts and the reports of the radiosity, instant-radiosity
/// and finishing passes are the first lit group's.
pub(super) fn light_groups(
    ctx: &BakeContext<'_>,
    groups: &[GroupMembers],
    volume_grids: Vec<VolumeGrid>,
    mut lit: Lit,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    let mut sum = vec![Vec3::ZERO; ctx.patches.patches.len()];
    let mut errors: Vec<ErrorEstimate> = Vec::new();
    for g in groups {
        let scene = g.scene_of(ctx.scene);
        let mut plan = BakePlan::new(&scene, ctx.settings);
        // The layout is the whole scene's: the density that follows the light was decided on
        // every group's light.
        plan.texel_density = ctx.plan.texel_density;
        plan.texel_density_source = ctx.plan.texel_density_source.clone();
        let gctx = BakeContext {
            scene: &scene,
            plan: &plan,
            ..*ctx
        };
        let first = stages.list.len();
        let start = Instant::now();
        let mut own = Vec::new();
        let mut got = if plan.nothing_to_bake {
            Lit::black(ctx.layout)
        } else {
            let calibrate = lit.rates.closest_per_second == 0.0;
            light_patches(
                &gctx,
                volume_grids.clone(),
                calibrate,
                Lit::default(),
                stages,
                &mut own,
            )?
        };
        let seconds = start.elapsed().as_secs_f64();
        for s in &mut stages.list[first..] {
            s.note = format!("[{}] {}", g.name, s.note);
        }
        warnings.extend(
            own.into_iter()
                .map(|w| format!("light group {}: {w}", g.name)),
        );
        for (s, e) in sum.iter_mut().zip(&got.irradiance) {
            *s += *e;
        }
        let volumes = std::mem::take(&mut got.volumes);
        if let Some(e) = &got.error {
            errors.push(e.clone());
        }
        lit.groups.push(GroupPages {
            name: g.name.clone(),
            pages: std::mem::take(&mut got.pages),
            irradiance_volumes: volumes.iter().map(|v| v.0.clone()).collect(),
            report: GroupReport {
                name: g.name.clone(),
                members: g.describe(ctx.scene),
                seconds,
                rays: stages.list[first..].iter().map(|s| s.rays).sum(),
                error: got.error.clone(),
            },
        });
        if lit.rates.closest_per_second == 0.0 && !plan.nothing_to_bake {
            // The first group lit: its floor calibration and its count of the texels the
            // finishing passes filled (every group fills the same ones).
            lit.rates = got.rates;
            lit.texels.filled = got.texels.filled;
            lit.texels.unfilled = got.texels.unfilled;
            lit.texels.dilated = got.texels.dilated;
        }
        lit.radiosity = lit.radiosity.take().or(got.radiosity.take());
        lit.vpl = lit.vpl.take().or(got.vpl.take());
        lit.indirect_reason = lit.indirect_reason.take().or(got.indirect_reason.take());
        lit.contact = lit.contact.take().or(got.contact.take());
        lit.seams = lit.seams.take().or(got.seams.take());
        lit.denoise = lit.denoise.take().or(got.denoise.take());
        if lit.volumes.is_empty() {
            lit.volumes = volumes;
        } else if !volumes.is_empty() {
            for ((total, _), (v, _)) in lit.volumes.iter_mut().zip(&volumes) {
                for (a, b) in total.voxels.iter_mut().zip(&v.voxels) {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += *y;
                    }
                }
            }
        }
        for s in got.skipped {
            if !lit.skipped.contains(&s) {
                lit.skipped.push(s);
            }
        }
    }
    lit.pages = sum_pages(ctx.layout, &lit.groups);
    if !errors.is_empty() {
        // The groups' noise is independent: their absolute errors add in quadrature.
        let value = rms_luminance(&valid(ctx.patches, &sum));
        lit.error = Some(ErrorEstimate::combine(&errors, value));
    }
    Ok(lit)
}

/// The bake's pages: the sum of the groups' pages.
fn sum_pages(layout: &Layout, groups: &[GroupPages]) -> Vec<LightmapPage> {
    let mut pages: Vec<LightmapPage> = (layout.pages.iter())
        .map(|p| LightmapPage::black(p.width, p.height))
        .collect();
    for g in groups {
        for (sum, page) in pages.iter_mut().zip(&g.pages) {
            for (a, b) in sum.texels.iter_mut().zip(&page.texels) {
                *a += *b;
            }
        }
    }
    pages
}

/// Black pages and no volume for every group (a scene with nothing to bake).
pub(super) fn black_groups(
    layout: &Layout,
    groups: &[GroupMembers],
    scene: &crate::scene::Scene,
) -> Vec<GroupPages> {
    groups
        .iter()
        .map(|g| GroupPages {
            name: g.name.clone(),
            pages: Lit::black(layout).pages,
            irradiance_volumes: Vec::new(),
            report: GroupReport {
                name: g.name.clone(),
                members: g.describe(scene),
                seconds: 0.0,
                rays: 0,
                error: None,
            },
        })
        .collect()
}
