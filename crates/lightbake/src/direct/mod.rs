//! Direct light at every texel patch: punctual lights, the sun, the sky and emissive
//! triangles ([`crate::lights`]), each with shadow rays, averaged over `samples_per_texel`
//! points of the texel's footprint ([`Footprint`]) so shadow edges are antialiased.
//!
//! Irradiance E is computed in lux (linear RGB); the lightmap stores E/π (see
//! [`crate::lightmap`]). Point, spot and directional lights give one sample each per
//! footprint point ([`LightSource::incident`]); the sky adds `sky_samples` cosine-distributed
//! rays, E = π·L·(fraction that escapes); emissive triangles are estimated in closed form with
//! a ratio estimator for their visibility, or by power sampling when there are many
//! ([`emitters`]). Each texel also estimates its own error ([`variance`]).

pub mod emitters;
pub mod light_choice;
pub mod variance;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use crate::bvh::RayScene;
use crate::color::luminance;
use crate::context::BakeContext;
use crate::error_estimate::standard_error;
use crate::lights::tree::{LightTree, MANY_LIGHTS, PER_TEXEL_LIGHTS, PICKS_PER_SAMPLE};
use crate::lights::{Emitters, LightSource, SceneDisc, sky};
use crate::plan::BakePlan;
use crate::progress::Progress;
use crate::raster::{Footprint, Patch, Patches, Surface, SurfacePoint};
use crate::sampling::{hash, sobol_02, unit_float};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::unwrap::Layout;
use emitters::RatioEstimate;
use light_choice::TexelLights;
pub use variance::error_method;
use variance::{BLOCKS, Block, block_variance, uses_blocks};

/// Random-number streams of a texel (mixed into its key; 1 and 2 are the footprint's, see
/// [`crate::raster::footprint`]).
mod stream {
    pub const SKY: u32 = 3;
    pub const EMITTER: u32 = 4;
    pub const EMITTER_PICK: u32 = 5;
    pub const LIGHT_PICK: u32 = 6;
    pub const LIGHT: u32 = 100;
}

/// What the direct pass produced.
#[derive(Clone, Debug, Default)]
pub struct DirectResult {
    /// Irradiance per patch, lux, linear RGB.
    pub irradiance: Vec<Vec3>,
    /// Standard error of each patch's irradiance from its own samples, lux (luminance; see
    /// [`crate::error_estimate`]). Zero for invalid patches.
    pub standard_error: Vec<f32>,
    /// Shadow and sky rays traced.
    pub rays: u64,
    /// The part of `irradiance` from lights baked indirect only
    /// ([`crate::scene::LightBake::IndirectOnly`]), lux: it feeds the interreflections and
    /// is taken out of the lightmaps. Empty when the scene has no such light.
    pub realtime: Vec<Vec3>,
}

/// Per-pass context shared by the texel workers.
struct Ctx<'a> {
    scene: &'a Scene,
    layout: &'a Layout,
    rays: &'a RayScene,
    patches: &'a Patches,
    surface: Surface<'a>,
    settings: &'a BakeSettings,
    plan: &'a BakePlan,
    emitters: &'a Emitters,
    closed_form: bool,
    /// The lights sampled one per footprint sample, for instances reached by more than
    /// [`MANY_LIGHTS`] ([`LightTree`]); empty otherwise.
    tree: LightTree,
    /// The lights of those instances the tree leaves out (suns, lights without power),
    /// evaluated one by one; sorted.
    untreed: Vec<u32>,
}

/// The light tree of a pass, over every light that reaches an instance with more than
/// [`MANY_LIGHTS`] lights (empty when none has), and those lights it leaves out.
fn light_tree(bake: &BakeContext<'_>) -> (LightTree, Vec<u32>) {
    let mut ids: Vec<u32> = (0..bake.scene.instances.len())
        .filter(|&i| bake.plan.lights_for(i).len() > MANY_LIGHTS)
        .flat_map(|i| bake.plan.lights_for(i).iter().copied())
        .collect();
    if ids.is_empty() {
        return (LightTree::default(), Vec::new());
    }
    ids.sort_unstable();
    ids.dedup();
    let tree = LightTree::build(bake.scene, &ids, &SceneDisc::covering(bake.rays));
    let untreed = ids.into_iter().filter(|&li| !tree.holds(li)).collect();
    (tree, untreed)
}

/// Direct irradiance per patch (lux) of the scene's own emitters, without progress or error
/// estimates.
pub fn direct_irradiance(ctx: &BakeContext<'_>) -> Vec<Vec3> {
    let emitters = Emitters::collect(ctx.scene, ctx.rays);
    direct_light(ctx, &emitters, &Progress::new()).irradiance
}

/// Computes direct irradiance at every patch. Invalid patches get zero (they are filled from
/// their neighbours later).
pub fn direct_light(
    bake: &BakeContext<'_>,
    emitters: &Emitters,
    progress: &Progress,
) -> DirectResult {
    direct_light_of(bake, emitters, None, progress)
}

/// [`direct_light`] of the patches `only` marks (all for `None`); the others get zero. Each
/// patch's value does not depend on which others are computed.
pub fn direct_light_of(
    bake: &BakeContext<'_>,
    emitters: &Emitters,
    only: Option<&[bool]>,
    progress: &Progress,
) -> DirectResult {
    let (tree, untreed) = light_tree(bake);
    let ctx = Ctx {
        scene: bake.scene,
        layout: bake.layout,
        rays: bake.rays,
        patches: bake.patches,
        surface: Surface::new(bake.scene, bake.layout, bake.rays),
        settings: bake.settings,
        plan: bake.plan,
        emitters,
        closed_form: emitters.list.len() <= bake.settings.direct.max_closed_form_emitters as usize,
        tree,
        untreed,
    };
    let ray_count = AtomicU64::new(0);
    let any_realtime = bake.scene.lights.iter().any(|l| !l.direct_is_baked());
    let (values, realtime): (Vec<(Vec3, f32)>, Vec<Vec3>) = bake
        .patches
        .patches
        .par_chunks(256)
        .enumerate()
        .flat_map_iter(|(c, chunk)| {
            let cancelled = progress.is_cancelled();
            let mut local_rays = 0u64;
            let out: Vec<((Vec3, f32), Vec3)> = chunk
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    let skipped = only.is_some_and(|o| !o[256 * c + k]);
                    if cancelled || skipped || !p.is_valid() {
                        ((Vec3::ZERO, 0.0), Vec3::ZERO)
                    } else {
                        let mut realtime = Vec3::ZERO;
                        let v = texel(&ctx, p, &mut local_rays, &mut realtime);
                        (v, realtime)
                    }
                })
                .collect();
            ray_count.fetch_add(local_rays, Ordering::Relaxed);
            progress.advance(chunk.len() as u64);
            out
        })
        .unzip();
    let (irradiance, standard_error) = values.into_iter().unzip();
    DirectResult {
        irradiance,
        standard_error,
        rays: ray_count.into_inner(),
        realtime: if any_realtime { realtime } else { Vec::new() },
    }
}

/// Luminance sums of one texel's footprint samples, for its error estimate: the plain terms,
/// the unoccluded closed-form irradiance, and the ratio estimator's Σw² over all and over
/// visible samples (its visibility v is 0 or 1, so Σw²(v − R)² = Σ_vis w² − 2R·Σ_vis w² +
/// R²·Σw²); and the same sums per block of consecutive samples ([`variance::block_variance`]).
#[derive(Default)]
struct Spread {
    plain: f64,
    plain_sq: f64,
    unoccluded: f64,
    unoccluded_sq: f64,
    w2_all: f64,
    w2_visible: f64,
    blocks: [Block; BLOCKS],
}

/// Direct irradiance of one valid patch and its standard error (luminance, lux).
///
/// The error comes from the spread of the footprint samples. With at least two samples per
/// block it is the spread of [`BLOCKS`] blocks' own estimates ([`variance::block_variance`]).
/// With fewer it treats the samples as independent: the punctual, directional and
/// sampled-emitter terms are a plain mean over `spp` samples; the closed-form emitter term is
/// Ū·R, with Ū the mean unoccluded irradiance and R the ratio estimate of its visible
/// fraction, whose variance is taken by the delta method (Σw²(v − R)²/(Σw)²); the sky term is
/// a binomial proportion of escaped rays.
///
/// The part from lights baked indirect only is also added to `realtime` (lux).
fn texel(ctx: &Ctx<'_>, p: &Patch, rays: &mut u64, realtime: &mut Vec3) -> (Vec3, f32) {
    let spp = ctx.settings.direct.samples_per_texel;
    let closed_form = ctx.plan.area_lights && ctx.closed_form && !ctx.emitters.is_empty();
    let mut e = Vec3::ZERO;
    let mut ratio = RatioEstimate::default();
    let mut spread = Spread::default();
    let mut samples: Vec<SurfacePoint> = Vec::with_capacity(spp as usize);
    let footprint = Footprint::new(
        ctx.layout,
        ctx.patches,
        &ctx.surface,
        ctx.rays,
        p,
        ctx.settings.seed,
    );
    let mut choice = None;
    for s in 0..spp {
        let e_before = e;
        let (unoccluded_before, wv_before, wt_before) =
            (ratio.unoccluded, ratio.w_visible, ratio.w_total);
        let sp = footprint.point(s, rays);
        samples.push(sp);
        let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
        if s == 0 {
            choice = texel_choice(ctx, p, &sp, rays);
        }
        add_lights(
            ctx,
            p,
            s,
            &sp,
            origin,
            choice.as_ref(),
            &mut e,
            realtime,
            rays,
        );
        if ctx.plan.area_lights && !ctx.emitters.is_empty() {
            if ctx.closed_form {
                ratio.add(ctx, p, s, &sp, origin, rays);
                let w2 = ((ratio.w_total - wt_before) as f64).powi(2);
                spread.w2_all += w2;
                if ratio.w_visible > wv_before {
                    spread.w2_visible += w2;
                }
            } else {
                e += emitters::sampled(ctx, p, s, &sp, origin, rays);
            }
        }
        let y = luminance(e - e_before) as f64;
        spread.plain += y;
        spread.plain_sq += y * y;
        let u = luminance(ratio.unoccluded - unoccluded_before) as f64;
        spread.unoccluded += u;
        spread.unoccluded_sq += u * u;
        let block = &mut spread.blocks[(s as usize * BLOCKS) / spp as usize];
        block.n += 1;
        block.plain += y;
        block.unoccluded += u;
        block.w_visible += (ratio.w_visible - wv_before) as f64;
        block.w_total += (ratio.w_total - wt_before) as f64;
    }
    *realtime /= spp as f32;
    let mut irradiance = e / spp as f32;
    let mut variance = (standard_error(spread.plain, spread.plain_sq, spp) as f64).powi(2);
    if closed_form && ratio.w_total > 0.0 {
        let r = ratio.visible_fraction();
        irradiance += ratio.unoccluded / spp as f32 * r as f32;
        // Var(Ū·R) ≈ R²·Var(Ū) + Ū²·Var(R).
        let u_mean = spread.unoccluded / spp as f64;
        let var_r = (spread.w2_visible * (1.0 - 2.0 * r) + r * r * spread.w2_all).max(0.0)
            / (ratio.w_total as f64).powi(2);
        variance +=
            r * r * (standard_error(spread.unoccluded, spread.unoccluded_sq, spp) as f64).powi(2)
                + u_mean * u_mean * var_r;
    }
    if ctx.plan.sky {
        irradiance += add_sky(ctx, p, &samples, &mut spread, &mut variance, rays);
    }
    if uses_blocks(ctx.settings, ctx.plan.sky) {
        variance = block_variance(&spread.blocks, ratio.visible_fraction());
    }
    (irradiance, variance.sqrt() as f32)
}

/// The texel's own weights for picking one light per footprint sample (from its
/// representative point and its first footprint point `first`), when more than
/// [`MANY_LIGHTS`] and at most [`PER_TEXEL_LIGHTS`] lights reach its instance; `None`
/// otherwise (every light is evaluated, or the light tree picks).
fn texel_choice(
    ctx: &Ctx<'_>,
    p: &Patch,
    first: &SurfacePoint,
    rays: &mut u64,
) -> Option<TexelLights> {
    let lights = ctx.plan.lights_for(p.instance as usize);
    if lights.len() <= MANY_LIGHTS || lights.len() > PER_TEXEL_LIGHTS || ctx.tree.is_empty() {
        return None;
    }
    let picked: Vec<u32> = lights
        .iter()
        .copied()
        .filter(|&li| ctx.tree.holds(li))
        .collect();
    Some(TexelLights::weigh(
        ctx,
        &[p.representative(), *first],
        picked,
        rays,
    ))
}

/// Adds the light of every punctual and directional light the plan evaluates for `p` at
/// footprint sample `s` (point `sp`, shadow rays from `origin`) to `e`, one light at a time,
/// and the light of those baked indirect only to `realtime` as well. With many lights, some
/// are picked: [`PICKS_PER_SAMPLE`] by the texel's `choice` when it has one, else one from the
/// light tree.
#[allow(clippy::too_many_arguments)]
fn add_lights(
    ctx: &Ctx<'_>,
    p: &Patch,
    s: u32,
    sp: &SurfacePoint,
    origin: Vec3,
    choice: Option<&TexelLights>,
    e: &mut Vec3,
    realtime: &mut Vec3,
    rays: &mut u64,
) {
    let lights = ctx.plan.lights_for(p.instance as usize);
    let sampled = lights.len() > MANY_LIGHTS && !ctx.tree.is_empty();
    let mut add = |li: u32, weight: f32| {
        let light = &ctx.scene.lights[li as usize];
        let u = sobol_02(s, p.rng(ctx.settings.seed, stream::LIGHT + li));
        if let Some(incident) = light.incident(sp, u, ctx.rays) {
            *rays += 1;
            if incident.visible(ctx.rays, origin) {
                *e += incident.irradiance * weight;
                if !light.direct_is_baked() {
                    *realtime += incident.irradiance * weight;
                }
            }
        }
    };
    if !sampled {
        for &li in lights {
            add(li, 1.0);
        }
        return;
    }
    // Many lights: those outside the tree (the sun) one by one, then one from the tree,
    // weighted by 1/p (a light the plan culled for this instance adds nothing).
    for &li in ctx
        .untreed
        .iter()
        .filter(|li| lights.binary_search(li).is_ok())
    {
        add(li, 1.0);
    }
    // A texel's own weights pick k = `PICKS_PER_SAMPLE` lights per sample (pick j of sample s
    // is draw s·k + j of the texel's stream), each weighted 1/(k·p); the tree picks one.
    let picks = if choice.is_some() {
        PICKS_PER_SAMPLE
    } else {
        1
    };
    for j in 0..picks {
        let draw = s.wrapping_mul(picks).wrapping_add(j);
        let u = unit_float(hash(
            p.rng(ctx.settings.seed, stream::LIGHT_PICK) ^ draw.wrapping_mul(0x9e37_79b9),
        ));
        let picked = match choice {
            Some(c) => c.pick(u),
            None => ctx.tree.pick(sp.position, sp.normal, u),
        };
        if let Some((li, pdf)) = picked
            && lights.binary_search(&li).is_ok()
            && pdf > 0.0
        {
            add(li, 1.0 / (picks as f32 * pdf));
        }
    }
}

/// The sky term E = π·L·(escaped fraction) of `sky_samples` cosine-distributed rays from the
/// footprint points `samples` (in turn), with its binomial variance added to `variance` and
/// its block sums to `spread`.
fn add_sky(
    ctx: &Ctx<'_>,
    p: &Patch,
    samples: &[SurfacePoint],
    spread: &mut Spread,
    variance: &mut f64,
    rays: &mut u64,
) -> Vec3 {
    let n = ctx.settings.direct.sky_samples;
    let spp = samples.len() as u32;
    let mut escaped = 0u32;
    let scale = std::f64::consts::PI * luminance(ctx.scene.sky) as f64;
    let key = p.rng(ctx.settings.seed, stream::SKY);
    for k in 0..n {
        let block = &mut spread.blocks[(k as usize * BLOCKS) / n as usize];
        block.sky_n += 1;
        let sp = samples[(k % spp) as usize];
        let u = sobol_02(k, key);
        let Some(incident) = sky::incident(ctx.scene.sky, &sp, u, ctx.rays) else {
            continue;
        };
        *rays += 1;
        let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
        if incident.visible(ctx.rays, origin) {
            escaped += 1;
            block.sky += scale;
        }
    }
    if n > 1 {
        let q = escaped as f64 / n as f64;
        *variance += scale * scale * q * (1.0 - q) / n as f64;
    }
    ctx.scene.sky * (std::f32::consts::PI * escaped as f32 / n as f32)
}
