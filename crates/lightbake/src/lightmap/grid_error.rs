//! The texel grid's own error, estimated by the bake: how far the lightmap's bilinear
//! reconstruction of the direct light (what the GPU shows between texel centres) is from the
//! direct light at points of the surface.
//!
//! The sampling stages estimate their noise ([`crate::error_estimate`]); none of them sees
//! what a texel grid cannot hold: a shadow edge or a light's falloff finer than a texel, a
//! texel beside a thin gap, a contact. On real levels that is most of the error: read at the
//! points of `bake --verify` on the teapots, the Kenney FPS level and the house at medium,
//! the direct light's reconstruction error is 0.95–1.01 of the whole error the path tracer
//! measures (`docs/benchmarks.md`).
//!
//! The check:
//!
//! * **Points**: [`CheckSettings::grid_error_points`](crate::settings::CheckSettings::grid_error_points)
//!   valid texel patches drawn at random, uniform over texels, each with a uniform point of
//!   its texel square mapped onto the surface (the footprint triangles; near geometry only
//!   open surface on the patch's side of a wall, [`Patches::sees`]), four attempts, else the
//!   point is dropped. Each point is weighted by its texel's area × its instance's
//!   `texel_density_scale`², so the points stand for the surface as `--verify` spreads its
//!   points: by area, a ground plane the scene bakes at an eighth of the density carrying a
//!   64th of the weight. Unweighted, the charts the density pass draws at twice the density
//!   (those with the sharpest direct light) would weigh four times as much: the house's
//!   estimate at medium would read 6.30% against 3.03% measured (2.08×); weighted it reads
//!   3.55% (1.17×).
//! * **Truth**: the direct light at the point itself, E_d(p): every light the plan lets reach
//!   the instance and baked in full, the sky and emissive triangles, with [`SAMPLES`]
//!   samples (a point of a sun's disc or an area light, one cosine-distributed sky ray, a
//!   point of an emitting triangle picked by power). The samples form two halves, each its
//!   own scrambled (0,2)-sequence, whose difference gives the variance of their mean (two
//!   halves of one sequence are not independent, and their difference would overstate it).
//!   The emitters' light is their closed-form unoccluded irradiance times the visible share
//!   of the samples' weights (the direct pass's ratio estimator), exact where they are
//!   wholly visible or hidden. Point and spot lights and a sun without a disc are traced
//!   once.
//! * **Lightmap**: the direct pass's texels (what the lightmap shows of them: lights baked
//!   indirect only left out), assembled into pages as the final light is (hidden texels
//!   filled from their chart, padding dilated), read bilinearly at the point: B_d(p), with
//!   the variance Σ w_j²·se_j² from the texels' own standard errors. The contact fit is not
//!   run on these pages: on the mirrored cubes and the teapots at medium it changes the
//!   estimate by less than 0.01 percentage points, for twice the rays.
//! * **Estimate**: RMS = √(max(0, Σw(B_d − E_d)² − Σw var E_d − Σw var B_d) / Σw), luminance,
//!   lux; p95 the 95th percentile of |B_d − E_d| by weight, scaled by the same share (the
//!   noise taken out).
//!   It is added in quadrature to the sampling stages' estimate: the two are independent.
//! * **Noise at a point**: the sampling stages estimate each texel's noise, and a point a
//!   viewer sees reads four texels bilinearly, whose independent noise partly cancels: a
//!   uniform point of a chart's middle shows (2/3)² of a texel's variance. The points give the
//!   factor for the bake's own charts ([`GridError::point_noise`], from the direct light's
//!   per-texel errors), and the sampling stages' estimate is scaled by it before the two are
//!   added, so that the sum estimates what `bake --verify` measures at points. Not after the
//!   denoiser, whose filter leaves neighbouring texels' errors correlated.
//!
//! What it does not see: the indirect light's grid error (smooth away from contacts), and
//! what the denoiser and the stitch change. Beside a lamp a few points can carry most of the
//! squared error ([`GridError::worst_share`]); the estimate is then as unsure as they make
//! it.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{assemble, bilinear_taps};
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::error_estimate::ErrorEstimate;
use crate::lights::{Emitters, LightSource, sky};
use crate::plan::BakePlan;
use crate::raster::{Patch, Patches, Surface, SurfacePoint};
use crate::sampling::{hash_words, sobol_02, unit_float};
use crate::scene::{LightKind, Scene};
use crate::settings::BakeSettings;
use crate::unwrap::Layout;

/// Samples of the direct light at each point (an even number: two halves).
pub const SAMPLES: u32 = 64;

/// What the check found.
#[derive(Clone, Debug)]
pub struct GridError {
    /// The estimate (absolute figures in lux, luminance).
    pub estimate: ErrorEstimate,
    /// Points checked.
    pub points: usize,
    /// The worst point's share of Σw(B_d − E_d)²: near a lamp a few points can carry most of
    /// it, and the estimate is then as unsure as one point makes it.
    pub worst_share: f64,
    /// Shadow and sky rays traced (and the footprint checks near geometry).
    pub rays: u64,
    /// How much of a texel's noise a point shows, as a factor on an RMS: √(Σ w_j²σ_j² /
    /// Σ w_j σ_j²) over the points, σ_j the direct light's standard error at the texels the
    /// bilinear read takes with weights w_j. Texels whose noise is independent give 2/3 in
    /// the middle of a chart (E[Σw²] = (2/3)² for a uniform point), nearer 1 along its edges;
    /// 1 when no texel carries noise.
    pub point_noise: f64,
}

/// One checked point: (B_d − E_d)², var E_d, var B_d (lux²), its rays, its weight (see the
/// module docs), and Σ w_j σ_j² (lux²: the taps' own variances, as texels carry them).
type Checked = (f64, f64, f64, u64, f64, f64);

/// The texel grid's error of the direct light `direct` (lux per patch, what the lightmap
/// shows; `direct_se` its per-patch standard error) at `settings.checks.grid_error_points` points,
/// relative to `value_rms` (lux; see the module docs). `None` when no valid texel exists or
/// no point could be placed.
#[allow(clippy::too_many_arguments)]
pub fn grid_error(
    scene: &Scene,
    layout: &Layout,
    patches: &Patches,
    rays: &RayScene,
    plan: &BakePlan,
    emitters: &Emitters,
    settings: &BakeSettings,
    direct: &[Vec3],
    direct_se: &[f32],
    value_rms: f64,
) -> Option<GridError> {
    let valid: Vec<u32> = (0..patches.patches.len() as u32)
        .filter(|&i| patches.patches[i as usize].is_valid())
        .collect();
    if valid.is_empty() || settings.checks.grid_error_points == 0 {
        return None;
    }
    let (pages, _) = assemble(layout, patches, direct, settings.layout.padding + 2);
    let surface = Surface::new(scene, layout, rays);
    let seed = hash_words(&[settings.seed, 0x96d1_e44e]);
    let checked: Vec<Option<Checked>> = (0..settings.checks.grid_error_points)
        .into_par_iter()
        .map(|i| {
            let key = hash_words(&[seed, i]);
            let index = valid[(hash_words(&[key, 0]) as usize) % valid.len()] as usize;
            let p = &patches.patches[index];
            let (sp, q, mut n_rays) = place(layout, patches, &surface, rays, p, key)?;
            let (e, var_e, r) = direct_at(scene, rays, plan, emitters, p, &sp, key);
            n_rays += r;
            let page = &pages[p.page as usize];
            let (u, v) = (q.x / page.width as f32, q.y / page.height as f32);
            let b = std::f64::consts::PI * luminance(page.sample_bilinear(u, v)) as f64;
            let (var_b, var_texels) = bilinear_taps(page.width, page.height, u, v)
                .iter()
                .map(|&((x, y), w)| {
                    let k = patches.page_index[p.page as usize][(y * page.width + x) as usize];
                    let se = if k == u32::MAX {
                        0.0
                    } else {
                        direct_se.get(k as usize).copied().unwrap_or(0.0) as f64
                    };
                    ((w as f64 * se).powi(2), w as f64 * se * se)
                })
                .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
            // Texels drawn uniformly, weighted by their area × the instance's density scale²:
            // by area over charts the density pass drew finer or coarser.
            let scale = scene.instances[p.instance as usize].texel_density_scale as f64;
            let weight = (p.texel_size as f64 * scale).powi(2);
            Some(((b - e).powi(2), var_e, var_b, n_rays, weight, var_texels))
        })
        .collect();
    // A point whose light overflows (a lamp touching the surface) says nothing about the
    // grid: left out, so the estimate stays finite.
    let done: Vec<Checked> = checked
        .into_iter()
        .flatten()
        .filter(|c| c.0.is_finite() && c.1.is_finite() && c.2.is_finite() && c.5.is_finite())
        .filter(|c| c.4 > 0.0)
        .collect();
    if done.is_empty() {
        return None;
    }
    let weight: f64 = done.iter().map(|c| c.4).sum();
    let (sq, var_e, var_b) = done.iter().fold((0.0, 0.0, 0.0), |(s, a, b), c| {
        (s + c.4 * c.0, a + c.4 * c.1, b + c.4 * c.2)
    });
    let var_texels: f64 = done.iter().map(|c| c.4 * c.5).sum();
    let point_noise = if var_texels > 0.0 {
        (var_b / var_texels).sqrt().min(1.0)
    } else {
        1.0
    };
    let worst = done.iter().map(|c| c.4 * c.0).fold(0.0, f64::max);
    let method = format!(
        "the texel grid: the direct light's bilinear reconstruction against its value at {} points",
        done.len()
    );
    // The 95th percentile of the differences (by weight), scaled as their RMS is once the
    // noise is taken out (the noise would otherwise stand in for grid error).
    let (raw, rms) = (
        (sq / weight).sqrt(),
        ((sq - var_e - var_b).max(0.0) / weight).sqrt(),
    );
    let p95_abs = if raw > 0.0 {
        weighted_p95(&done) * rms / raw
    } else {
        0.0
    };
    let estimate = ErrorEstimate {
        rms,
        p95_abs,
        texels: done.len(),
        method,
        ..ErrorEstimate::default()
    }
    .relative_to(value_rms);
    Some(GridError {
        estimate,
        points: done.len(),
        worst_share: if sq > 0.0 { worst / sq } else { 0.0 },
        rays: done.iter().map(|c| c.3).sum(),
        point_noise,
    })
}

/// The 95th percentile of |B_d − E_d| over the checked points, by their weights.
fn weighted_p95(done: &[Checked]) -> f64 {
    let mut by_size: Vec<(f64, f64)> = done.iter().map(|c| (c.0.sqrt(), c.4)).collect();
    by_size.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = by_size.iter().map(|c| c.1).sum();
    let mut below = 0.0;
    for &(size, w) in &by_size {
        below += w;
        if below >= 0.95 * total {
            return size;
        }
    }
    by_size.last().map_or(0.0, |c| c.0)
}

/// A uniform point of `p`'s texel square on its open surface, and where it lies on the page
/// (texel units); `None` after four misses. Also the rays its checks traced.
fn place(
    layout: &Layout,
    patches: &Patches,
    surface: &Surface<'_>,
    rays: &RayScene,
    p: &Patch,
    key: u32,
) -> Option<(SurfacePoint, Vec2, u64)> {
    let rect = layout.instances[p.instance as usize]?;
    let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
    let mut traced = 0;
    for attempt in 0..4u32 {
        let u = Vec2::new(
            unit_float(hash_words(&[key, 1, attempt])),
            unit_float(hash_words(&[key, 2, attempt])),
        );
        let Some(sp) = patches
            .footprint_of(p)
            .iter()
            .find_map(|&t| surface.point(t, texel + u, 0.0))
        else {
            continue;
        };
        if p.flags & Patch::NEAR_GEOMETRY != 0 {
            traced += 2;
            if !patches.sees(p, &sp, rays) {
                continue;
            }
        }
        return Some((sp, Vec2::new(p.x as f32, p.y as f32) + u, traced));
    }
    None
}

/// E_d at `sp` (luminance, lux), the variance of that mean from its two halves, and the
/// rays traced. Point and spot lights and a sun without a disc give the same light for every
/// sample: they are traced once.
fn direct_at(
    scene: &Scene,
    rays: &RayScene,
    plan: &BakePlan,
    emitters: &Emitters,
    p: &Patch,
    sp: &SurfacePoint,
    key: u32,
) -> (f64, f64, u64) {
    let origin = rays.offset(sp.position, sp.geometric_normal);
    let (light_key, sky_key) = (hash_words(&[key, 3]), hash_words(&[key, 4]));
    let mut traced = 0u64;
    // The light of light `li` for sample `s`, and the rays it traced.
    let light_of = |li: u32, s: u32| -> (Vec3, u64) {
        let light = &scene.lights[li as usize];
        let u = sobol_02(s / 2, hash_words(&[light_key, li, s % 2]));
        light
            .incident(sp, u, rays)
            .map_or((Vec3::ZERO, 0), |incident| {
                let lit = incident.visible(rays, origin);
                (if lit { incident.irradiance } else { Vec3::ZERO }, 1)
            })
    };
    let (fixed, sampled): (Vec<u32>, Vec<u32>) = plan
        .lights_for(p.instance as usize)
        .iter()
        .copied()
        .filter(|&li| scene.lights[li as usize].direct_is_baked())
        .partition(|&li| match scene.lights[li as usize].kind {
            LightKind::Point | LightKind::Spot { .. } => true,
            LightKind::Directional { angular_radius } => angular_radius <= 0.0,
            LightKind::Rect { .. } => false,
        });
    let mut constant = Vec3::ZERO;
    for &li in &fixed {
        let (e, r) = light_of(li, 0);
        constant += e;
        traced += r;
    }
    let with_emitters = plan.area_lights && !emitters.is_empty();
    let unoccluded: Vec3 = if with_emitters {
        emitters
            .list
            .iter()
            .map(|em| em.unoccluded_irradiance(sp))
            .sum()
    } else {
        Vec3::ZERO
    };
    let emitter_key = hash_words(&[key, 5]);
    // Per half: Σ w over the emitter samples, and over those whose shadow ray is clear.
    let mut weights = [[0.0f64; 2]; 2];
    let mut halves = [0.0f64; 2];
    for s in 0..SAMPLES {
        if with_emitters {
            let pick = unit_float(hash_words(&[emitter_key, s]));
            let u = sobol_02(s / 2, hash_words(&[emitter_key, s % 2]));
            if let Some(incident) = emitters.incident(sp, origin, pick, u, rays) {
                traced += 1;
                let w = luminance(incident.irradiance) as f64;
                let half = &mut weights[(s % 2) as usize];
                half[0] += w;
                if incident.visible(rays, origin) {
                    half[1] += w;
                }
            }
        }
        let mut e = constant;
        for &li in &sampled {
            let (light, r) = light_of(li, s);
            e += light;
            traced += r;
        }
        if plan.sky
            && let Some(incident) = sky::incident(
                scene.sky,
                sp,
                sobol_02(s / 2, hash_words(&[sky_key, s % 2])),
                rays,
            )
        {
            traced += 1;
            if incident.visible(rays, origin) {
                e += incident.irradiance;
            }
        }
        halves[(s % 2) as usize] += luminance(e) as f64;
    }
    let half = (SAMPLES / 2) as f64;
    let emitted = |h: usize| {
        let [all, clear] = weights[h];
        if all > 0.0 {
            luminance(unoccluded) as f64 * clear / all
        } else {
            0.0
        }
    };
    let (a, b) = (halves[0] / half + emitted(0), halves[1] / half + emitted(1));
    ((a + b) / 2.0, (a - b).powi(2) / 4.0, traced)
}
