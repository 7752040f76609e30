//! Light groups in the driver: the lighting and finishing passes once per group
//! ([`crate::settings::groups`]), over the texel patches, the unwrap and the BVH every group
//! shares, each group seeing only its own emitters. Their radiosity shares its nodes, the
//! hierarchical solve's coarse level and its gathers ([`super::group_lighting`]) where the
//! bake runs in one round and one process. Light adds up, so the bake's own pages and volume are the groups' sum,
//! and a game shows any weighted sum of the groups' pages.

use std::time::Instant;

use glam::Vec3;

use super::group_lighting::{self, GroupCost};
use super::passes::Lighting;
use super::stages::Stages;
use super::{Lit, emitters_of, finish_patches, light_patches, valid};
use crate::context::BakeContext;
use crate::error::Result;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lightmap::LightmapPage;
use crate::lights::Emitters;
use crate::plan::BakePlan;
use crate::probes::{IrradianceVolume, VolumeGrid};
use crate::report::GroupReport;
use crate::scene::Scene;
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
/// and finishing passes are the first lit group's. Where they can
/// ([`group_lighting::shares_transport`]) the groups' radiosity shares its nodes, its coarse
/// level and its gathers' rays.
pub(super) fn light_groups(
    ctx: &BakeContext<'_>,
    groups: &[GroupMembers],
    volume_grids: Vec<VolumeGrid>,
    mut lit: Lit,
    stages: &mut Stages<'_>,
    warnings: &mut Vec<String>,
) -> Result<Lit> {
    // Each group's scene (its emitters only) and plan, made once. They are held together only
    // when the groups may share their transport; else each is made when its group is lit.
    let share = groups.len() > 1 && group_lighting::shares_transport(ctx, stages);
    let made = |g: &GroupMembers| {
        let scene = g.scene_of(ctx.scene);
        let mut plan = BakePlan::new(&scene, ctx.settings);
        // The layout is the whole scene's: the density that follows the light was decided on
        // every group's light.
        plan.texel_density = ctx.plan.texel_density;
        plan.texel_density_source = ctx.plan.texel_density_source.clone();
        (scene, plan)
    };
    let mut held: Vec<Option<(Scene, BakePlan)>> =
        (groups.iter()).map(|g| share.then(|| made(g))).collect();
    // The groups with something to light, and (when they share their transport) their
    // lighting passes, run together.
    let lit_groups: Vec<usize> = (0..groups.len())
        .filter(|&g| held[g].as_ref().is_some_and(|(_, p)| !p.nothing_to_bake))
        .collect();
    let mut own: Vec<Vec<String>> = vec![Vec::new(); groups.len()];
    let mut shared: Vec<Option<(Lighting, GroupCost)>> = (0..groups.len()).map(|_| None).collect();
    let mut emitters: Vec<Option<Emitters>> = (0..groups.len()).map(|_| None).collect();
    if share && lit_groups.len() > 1 {
        let sharing: Vec<BakeContext<'_>> = (lit_groups.iter())
            .map(|&g| {
                let (scene, plan) = held[g].as_ref().expect("held when shared");
                BakeContext {
                    scene,
                    plan,
                    ..*ctx
                }
            })
            .collect();
        let found: Vec<Emitters> = (lit_groups.iter().zip(&sharing))
            .map(|(&g, c)| emitters_of(c, &mut own[g]))
            .collect();
        let names: Vec<&str> = lit_groups
            .iter()
            .map(|&g| groups[g].name.as_str())
            .collect();
        let mut group_warnings: Vec<Vec<String>> = vec![Vec::new(); lit_groups.len()];
        let (lights, costs) = group_lighting::lighting_groups(
            &sharing,
            &found,
            &names,
            stages,
            (&mut group_warnings, warnings),
        )?;
        for ((((&g, light), cost), e), w) in (lit_groups.iter().zip(lights))
            .zip(costs)
            .zip(found)
            .zip(group_warnings)
        {
            shared[g] = Some((light, cost));
            emitters[g] = Some(e);
            own[g].extend(w);
        }
    }
    let mut sum = vec![Vec3::ZERO; ctx.patches.patches.len()];
    let mut errors: Vec<ErrorEstimate> = Vec::new();
    for (gi, g) in groups.iter().enumerate() {
        let (scene, plan) = held[gi].take().unwrap_or_else(|| made(g));
        let plan = &plan;
        let gctx = &BakeContext {
            scene: &scene,
            plan,
            ..*ctx
        };
        let first = stages.list.len();
        let start = Instant::now();
        let mut own = std::mem::take(&mut own[gi]);
        let calibrate = lit.rates.closest_per_second == 0.0;
        let (mut got, lighting) = if plan.nothing_to_bake {
            (Lit::black(ctx.layout), None)
        } else if let Some((light, cost)) = shared[gi].take() {
            let e = emitters[gi].take().expect("found with the lighting");
            let grids = (volume_grids.clone(), calibrate);
            let got = finish_patches(gctx, &e, light, grids, Lit::default(), stages, &mut own)?;
            (got, Some(cost))
        } else {
            let grids = volume_grids.clone();
            let got = light_patches(gctx, grids, calibrate, Lit::default(), stages, &mut own)?;
            (got, None)
        };
        let mut seconds = start.elapsed().as_secs_f64();
        let mut rays: u64 = stages.list[first..].iter().map(|s| s.rays).sum();
        if let Some(cost) = lighting {
            seconds += cost.seconds;
            rays += cost.rays;
        }
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
                rays,
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
    scene: &Scene,
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
