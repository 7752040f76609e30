//! The passes of a bake that are not lighting: the texel patches (rasterised and validated,
//! or read from a split bake's work folder), the floor calibration, and the finishing passes
//! on the pages (denoise, contact fit, dilate, stitch) and the irradiance volume. Each is one
//! stage, timed and recorded by [`Stages`].

use glam::Vec3;

use super::estimate::denoised_error;
use super::passes::Lighting;
use super::shard::Units;
use super::stages::Stages;
use super::{CALIBRATION_RAYS, Lit, calibration_origins, finite};
use crate::bvh::RayScene;
use crate::bvh::workload::{RayRates, calibrate};
use crate::context::BakeContext;
use crate::error::Result;
use crate::lightmap::contacts::{self, ContactStats};
use crate::lightmap::denoise::{denoise, denoise_parts, noise_scale};
use crate::lightmap::seams::find_seams;
use crate::lightmap::stitch::{StitchStats, stitch};
use crate::lightmap::{Assembly, LightmapPage};
use crate::lights::Emitters;
use crate::plan::BakePlan;
use crate::probes::gather::Solution;
use crate::probes::{IrradianceVolume, VolumeGrid, VolumeStats, bake_volume};
use crate::progress::RayKind;
use crate::raster::Patches;
use crate::runner::StageRunner;
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::settings::Method;
use crate::stage::Stage;
use crate::unwrap::Layout;

/// The texel patches: rasterised and moved out of geometry (stages `raster` and `validity`;
/// a split bake's prepare writes them and its work units, and stops), or, in a shard or the
/// merge of a split bake, read from the work folder (stage `patches`).
pub(super) fn texel_patches(
    scene: &Scene,
    layout: &Layout,
    settings: &BakeSettings,
    plan: &BakePlan,
    rays: &RayScene,
    stages: &mut Stages<'_>,
) -> Result<Patches> {
    let reader = stages
        .scope()
        .split_bake()
        .filter(|run| run.reads_patches());
    Ok(match reader {
        // A shard or the merge of a split bake reads prepare's patches.
        Some(run) => stages.run(Stage::Patches, 1, || {
            let p = run.read_prepared(layout, rays.triangles.len(), scene.instances.len())?;
            let note = format!(
                "{} texel patches, read from the work folder",
                p.patches.len()
            );
            Ok((p, 0, note))
        })?,
        // A bake that follows an earlier one of the same geometry and layout takes its
        // patches.
        None if let Some(p) = (stages.scope().texel_run())
            .and_then(|run| run.kept_patches(scene, layout, rays.triangles.len())) =>
        {
            let patches = stages.run(Stage::Patches, 1, || {
                let note = format!(
                    "{} texel patches, kept from the earlier bake (the geometry and its layout did not change)",
                    p.patches.len()
                );
                Ok((p, 0, note))
            })?;
            if let Some(run) = stages.scope().texel_run() {
                run.patches_known((scene, layout, rays), &patches, settings)?;
            }
            patches
        }
        None => {
            let mut patches = stages.run(Stage::Raster, 1, || {
                let p = Patches::build(scene, layout, rays);
                let note = format!("{} texel patches", p.patches.len());
                Ok((p, 0, note))
            })?;
            stages.run(Stage::Validity, patches.patches.len() as u64, || {
                patches.fix_validity(scene, layout, rays);
                let note = format!(
                    "{} moved ({} seen only in part), {} hidden ({} without a search), {} visible but unlit; {}",
                    patches.moved,
                    patches.rescued,
                    patches.invalid,
                    patches.sealed,
                    patches.visible_unlit,
                    patches.ray_steps
                );
                Ok(((), patches.rays, note))
            })?;
            stages.annotate(RayKind::Shadow, None);
            if let Some(run) = stages.scope().texel_run() {
                run.patches_known((scene, layout, rays), &patches, settings)?;
            }
            if let Some(run) = stages.scope().split_bake() {
                // Prepare writes the patches and the work units here, and stops.
                let units = Units::plan(&patches, layout, settings, scene.lights.len(), plan.sky);
                run.prepared(units, &patches)?;
            }
            patches
        }
    })
}

/// The machine's ray rates the floor is measured at: a short calibration on the bake's pool.
pub(super) fn calibrate_floor(
    rays: &RayScene,
    patches: &Patches,
    settings: &BakeSettings,
    stages: &mut Stages<'_>,
) -> Result<RayRates> {
    stages.run(Stage::Calibrate, 1, || {
        let r = calibrate(
            rays,
            &calibration_origins(patches, settings.seed),
            CALIBRATION_RAYS,
            settings.seed,
        );
        let note = format!(
            "BVH rates for the floor: {:.2} Mrays/s closest, {:.2} shadow",
            r.closest_per_second / 1e6,
            r.shadow_per_second / 1e6
        );
        Ok((r, 0, note))
    })
}

/// The denoiser (stage `denoise`, [`crate::lightmap::denoise`]) on `assembly`: direct and
/// indirect light filtered apart when the indirect pass estimates its noise texel by texel,
/// the noise scaled to the bake's estimate first; the estimate carried through. Recorded in
/// `lit` (or, when the indirect pass has no per-texel noise, why it was skipped).
pub(super) fn denoise_pages(
    ctx: &BakeContext<'_>,
    light: &Lighting,
    irradiance: &[Vec3],
    assembly: &mut Assembly,
    lit: &mut Lit,
    stages: &mut Stages<'_>,
) -> Result<()> {
    let (scene, layout, patches, settings, plan) =
        (ctx.scene, ctx.layout, ctx.patches, ctx.settings, ctx.plan);
    let covers = light.indirect.is_some() || !plan.runs(Stage::Indirect);
    if covers {
        let (st, error) = stages.run(Stage::Denoise, 1, || {
            let radius = settings.finish.denoise_radius;
            let (st, error) = match &light.indirect {
                // Direct and indirect light apart, each with its own noise (scaled as the
                // sum is to the bake's estimate).
                Some((indirect, indirect_noise)) => {
                    let total: Vec<f32> = light
                        .texel_error
                        .iter()
                        .zip(indirect_noise)
                        .map(|(d, i)| d.hypot(*i))
                        .collect();
                    let scale = noise_scale(patches, &total, lit.error.as_ref(), light.coarse_bias);
                    let scaled = |n: &[f32]| n.iter().map(|&v| v * scale).collect::<Vec<f32>>();
                    let direct: Vec<Vec3> =
                        irradiance.iter().zip(indirect).map(|(t, i)| *t - *i).collect();
                    let (a, st, error) = denoise_parts(
                        layout,
                        patches,
                        [
                            (&direct, &scaled(&light.texel_error)),
                            (indirect, &scaled(indirect_noise)),
                        ],
                        radius,
                    );
                    *assembly = a;
                    (st, error)
                }
                None => {
                    let noise = &light.texel_error;
                    let scale = noise_scale(patches, noise, lit.error.as_ref(), light.coarse_bias);
                    let noise: Vec<f32> = noise.iter().map(|&v| v * scale).collect();
                    denoise(assembly, patches, &noise, radius)
                }
            };
            let note = format!(
                "radius {} texels, {} texels, mean strength {:.2}; noise {:.3} → {:.3} lux RMS, bias added {:.3} lux RMS{}",
                st.radius,
                st.texels,
                st.mean_strength,
                st.noise_before,
                st.noise_after,
                st.bias,
                if light.indirect.is_some() { "; direct and indirect light filtered apart" } else { "" }
            );
            Ok(((st, error), 0, note))
        })?;
        if let Some(e) = &lit.error {
            lit.error = Some(denoised_error(patches, &error, e, light.coarse_bias));
        }
        finite::pages("denoise", scene, patches, &mut assembly.pages)?;
        lit.denoise = Some(st);
    } else {
        let why = if matches!(settings.method, Method::Vpl | Method::Hybrid) {
            // Its per-texel noise (the cut's picks paired node by node) overstates the noise
            // 1.4–2.4×; filtered that strongly, a floor's light crossed under a thin wall
            // into the dark room and a 5° wedge lost 10% of its light (tests/stability.rs).
            "instant radiosity's per-texel noise estimate overstates its noise, and filtering by it blurs light across walls"
        } else {
            "the indirect pass gives no per-texel noise estimate (only the hierarchical solve's gathers do)"
        };
        lit.skipped.push((Stage::Denoise, why.to_string()));
    }
    Ok(())
}

/// The contact fit (stage `contact fit`, [`crate::lightmap::contacts`]) on `assembly`.
pub(super) fn contact_fit_pages(
    ctx: &BakeContext<'_>,
    assembly: &mut Assembly,
    stages: &mut Stages<'_>,
) -> Result<ContactStats> {
    let (scene, patches) = (ctx.scene, ctx.patches);
    let st = contacts::fit_stage(ctx, assembly, stages)?;
    stages.annotate(RayKind::Shadow, None);
    finite::pages("contact fit", scene, patches, &mut assembly.pages)?;
    Ok(st)
}

/// Invalid texels filled and the padding dilated (stage `dilate`), counted in `lit`.
pub(super) fn dilate_pages(
    ctx: &BakeContext<'_>,
    assembly: &mut Assembly,
    lit: &mut Lit,
    stages: &mut Stages<'_>,
) -> Result<()> {
    let (scene, patches, settings) = (ctx.scene, ctx.patches, ctx.settings);
    stages.run(Stage::Dilate, 1, || {
        assembly.dilate(settings.layout.padding + 2);
        let st = assembly.stats;
        lit.texels.filled = st.filled;
        lit.texels.dilated = st.dilated;
        lit.texels.unfilled = st.unfilled;
        let note = format!("{} filled, {} padding texels", st.filled, st.dilated);
        Ok(((), 0, note))
    })?;
    finite::pages("dilate", scene, patches, &mut assembly.pages)?;
    Ok(())
}

/// The seams' stitch (stage `stitch`, [`crate::lightmap::stitch`]) on `assembly`.
pub(super) fn stitch_pages(
    ctx: &BakeContext<'_>,
    assembly: &mut Assembly,
    stages: &mut Stages<'_>,
) -> Result<StitchStats> {
    let (scene, layout, patches, rays) = (ctx.scene, ctx.layout, ctx.patches, ctx.rays);
    let st = stages.run(Stage::Stitch, 1, || {
        let seams = find_seams(scene, layout);
        let st = stitch(assembly, patches, &seams, rays);
        let note = if seams.is_empty() {
            "no seams: no smooth surface is split between charts (chart borders lie on hard edges)"
                .to_string()
        } else {
            st.summary(seams.len())
        };
        Ok((st, 0, note))
    })?;
    finite::pages("stitch", scene, patches, &mut assembly.pages)?;
    Ok(st)
}

/// The irradiance volume stage ([`crate::probes`]): every probe of every grid in `grids`
/// gathered from the finished `pages` (the first volume's numbers keyed by the bake's seed,
/// volume k's by the seed and k).
pub(super) fn volume_stage(
    ctx: &BakeContext<'_>,
    grids: Vec<VolumeGrid>,
    emitters: &Emitters,
    pages: &[LightmapPage],
    stages: &mut Stages<'_>,
) -> Result<Vec<(IrradianceVolume, VolumeStats)>> {
    let settings = ctx.settings;
    let solution = Solution {
        scene: ctx.scene,
        layout: ctx.layout,
        pages,
        rays: ctx.rays,
        emitters,
    };
    let progress = stages.progress();
    let probes: usize = grids.iter().map(VolumeGrid::len).sum();
    let mut volumes = stages.run(Stage::Volume, probes as u64, || {
        let mut out = Vec::with_capacity(grids.len());
        let (mut notes, mut rays) = (Vec::new(), 0);
        for (k, grid) in grids.into_iter().enumerate() {
            let seed = match k {
                0 => settings.seed,
                k => crate::sampling::hash_words(&[settings.seed, 0x005e_610a, k as u32]),
            };
            let (volume, st) = bake_volume(&solution, grid, settings.volume.probe_rays, seed, progress);
            notes.push(format!(
                "{} × {} × {} probes, {:.3e} m apart, {} moved out of geometry, {} filled; noise {:.2}%",
                st.resolution[0],
                st.resolution[1],
                st.resolution[2],
                st.spacing,
                st.moved,
                st.filled,
                100.0 * st.relative_standard_error
            ));
            rays += st.rays;
            out.push((volume, st));
        }
        Ok((out, rays, notes.join("; ")))
    })?;
    for (volume, _) in &mut volumes {
        finite::probes(&mut volume.voxels)?;
    }
    Ok(volumes)
}
