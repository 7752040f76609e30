//! The denoiser: an edge-aware filter over each chart's texels, applied to each texel only as
//! strongly as its own estimated noise warrants, with the error estimate carried through.
//!
//! Every valid texel i has a value x_i (E/π) and the standard error σ_i of its luminance
//! from the passes that sampled it (the direct pass's footprint blocks and the gathers'
//! ray blocks, `radiosity::monte_carlo::gather`), averaged (as a variance) over the
//! texels the filter could mix with it: a few samples estimate one texel's variance poorly,
//! and the variance changes slowly across a chart. The filter is a joint bilateral
//! one (Tomasi & Manduchi 1998; guided by the surface, as lightmap denoisers such as
//! Godot's JNLM are):
//!
//! f_i = Σ_j w_ij·x_j / Σ_j w_ij,  w_ij = exp(−d²/2s²) · exp(−(L_j − G_i)² / 2k²(σ_j² + σ_G²))
//!
//! with G_i the luminance around i averaged over its 3 × 3 neighbourhood (a guide that one
//! noisy centre, a firefly, cannot pull far) and σ_G² its variance, over the texel itself
//! and the texels j within `radius` texels of i (s = radius/2, k = 2) that are valid, of
//! the same instance and chart (never across charts), face the same way (normals within
//! 25°) and lie where the texel grid says they do (world distance at most 1.5× the texel
//! distance plus a texel: not across a fold of the chart). The luminance term is measured in
//! units of the texels' noise: a difference the noise explains is averaged away, a
//! shadow edge or a contact darkening several noise units deep is kept.
//!
//! How much of f_i a texel takes is a Wiener shrinkage (Lee 1980): α_i = σ_i² / (σ_i² + v_i),
//! v_i the variance of the signal around i (the weighted variance of its neighbours'
//! luminance about f_i less their mean noise variance, the texel itself left out). A texel
//! whose noise is small against the detail around it keeps its value; in a flat, noisy
//! region it takes the filtered one.
//!
//! The output is linear in the inputs, x̂_i = Σ_j a_ij·x_j, so its noise is
//! σ̂_i² = Σ_j a_ij²·σ_j²; its bias, which no noise estimate sees, is estimated from what the
//! filter changed: b_i² = max(0, (L̂_i − L_i)² − Σ_j (a_ij − δ_ij)²·σ_j²) (the change less
//! what noise alone would change; unbiased in the sum over texels). Each texel's error after
//! the filter is √(σ̂_i² + b_i²), and the bake's estimate is made from those.

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use super::{Assembly, TexelState};
use crate::color::luminance;
use crate::error_estimate::ErrorEstimate;
use crate::raster::{Patch, Patches};
use crate::unwrap::Layout;

/// Cosine of the largest angle between two texels' normals that the filter mixes (25°).
const NORMAL_COS: f32 = 0.906;
/// Range-kernel width in units of a texel's noise and the guide's.
const RANGE_K: f32 = 2.0;

/// What the denoiser did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct DenoiseStats {
    /// Filter radius, texels.
    pub radius: u32,
    /// Texels filtered (valid texels with a noise estimate).
    pub texels: usize,
    /// Mean strength α over them (0: kept, 1: the filtered value).
    pub mean_strength: f64,
    /// RMS standard error of the texels' luminance before, lux.
    pub noise_before: f64,
    /// RMS standard error after, lux.
    pub noise_after: f64,
    /// RMS of the estimated bias the filter added, lux.
    pub bias: f64,
}

/// One texel's result.
struct Filtered {
    value: Vec3,
    strength: f32,
    /// σ̂² and b² (E/π luminance units, squared).
    noise_sq: f32,
    bias_sq: f32,
}

/// Denoises the valid texels on the assembled pages (right after [`Assembly::new`]) with a
/// filter of `radius` texels; `noise` is the standard error of each patch's irradiance
/// (luminance, lux). Returns the statistics and each patch's error after the filter (lux;
/// for patches the filter left alone, their noise averaged over their neighbourhood).
pub fn denoise(
    assembly: &mut Assembly,
    patches: &Patches,
    noise: &[f32],
    radius: u32,
) -> (DenoiseStats, Vec<f32>) {
    let pi = std::f32::consts::PI;
    // The noise estimates, averaged over each texel's neighbourhood (a handful of samples
    // estimate a texel's own variance poorly; the variance changes slowly across a chart).
    let smoothed = smooth_variance(assembly, patches, noise, radius);
    let sigma = |i: usize| smoothed[i] / pi;
    let results: Vec<Option<Filtered>> = patches
        .patches
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            // A NaN noise counts as none.
            if !p.is_valid() || sigma(i).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            Some(filter_one(assembly, patches, i, radius, &sigma))
        })
        .collect();
    let mut stats = DenoiseStats {
        radius,
        ..DenoiseStats::default()
    };
    let mut error = smoothed.clone();
    let (mut before, mut after, mut bias, mut strength) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (i, r) in results.into_iter().enumerate() {
        let Some(r) = r else { continue };
        let p = &patches.patches[i];
        let page = &mut assembly.pages[p.page as usize];
        let k = (p.y * page.width + p.x) as usize;
        debug_assert_eq!(assembly.state[p.page as usize][k], TexelState::Set);
        page.texels[k] = r.value;
        stats.texels += 1;
        strength += r.strength as f64;
        before += (smoothed[i] as f64).powi(2);
        after += r.noise_sq as f64 * (pi as f64).powi(2);
        bias += r.bias_sq as f64 * (pi as f64).powi(2);
        error[i] = (r.noise_sq + r.bias_sq).sqrt() * pi;
    }
    if stats.texels > 0 {
        let n = stats.texels as f64;
        stats.mean_strength = strength / n;
        stats.noise_before = (before / n).sqrt();
        stats.noise_after = (after / n).sqrt();
        stats.bias = (bias / n).sqrt();
    }
    (stats, error)
}

/// Denoises two parts of the light apart and sums them: each part (irradiance per patch,
/// lux, and its standard error, luminance, lux) is assembled onto pages of `layout` and
/// filtered by [`denoise`], whose luminance guide then sees only that part's edges: the
/// indirect light, smooth and noisy, is filtered across the hard shadow edges of the direct
/// light, which keeps them (a point light's shadow has no noise to filter). Returns the
/// summed pages (as [`Assembly::new`] of the sum, filtered), the statistics of both (noise
/// and bias summed in quadrature, the strength averaged over both parts' texels) and each
/// patch's error (lux).
pub fn denoise_parts(
    layout: &Layout,
    patches: &Patches,
    parts: [(&[Vec3], &[f32]); 2],
    radius: u32,
) -> (Assembly, DenoiseStats, Vec<f32>) {
    let mut sum: Option<Assembly> = None;
    let mut stats = DenoiseStats {
        radius,
        ..DenoiseStats::default()
    };
    let mut error = vec![0.0f32; patches.patches.len()];
    let (mut strength, mut count, mut before, mut after, mut bias) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (values, noise) in parts {
        let mut part = Assembly::new(layout, patches, values);
        let (st, e) = denoise(&mut part, patches, noise, radius);
        let n = st.texels as f64;
        stats.texels = stats.texels.max(st.texels);
        strength += st.mean_strength * n;
        count += n;
        before += st.noise_before.powi(2) * n;
        after += st.noise_after.powi(2) * n;
        bias += st.bias.powi(2) * n;
        for (t, v) in error.iter_mut().zip(&e) {
            *t = t.hypot(*v);
        }
        match &mut sum {
            None => sum = Some(part),
            Some(total) => {
                for (a, b) in total.pages.iter_mut().zip(&part.pages) {
                    for (x, y) in a.texels.iter_mut().zip(&b.texels) {
                        *x += *y;
                    }
                }
            }
        }
    }
    if stats.texels > 0 {
        let n = stats.texels as f64;
        stats.mean_strength = strength / count;
        stats.noise_before = (before / n).sqrt();
        stats.noise_after = (after / n).sqrt();
        stats.bias = (bias / n).sqrt();
    }
    (sum.expect("two parts"), stats, error)
}

/// Each patch's noise (lux) as the RMS of the noise of the texels around it that the filter
/// could mix (valid, same instance and chart, facing the same way: the guides of
/// The denoiser's calibration: the factor that scales the per-patch noise so its RMS over the valid patches matches the
/// sampling stages' own estimate (`estimate`, less the hierarchical solve's coarse bias
/// `coarse_bias`, relative): the per-texel figures give the shape, the stage estimates
/// (independent re-gathers for radiosity) the scale.
pub fn noise_scale(
    patches: &Patches,
    noise: &[f32],
    estimate: Option<&ErrorEstimate>,
    coarse_bias: Option<f64>,
) -> f32 {
    let Some(e) = estimate else {
        return 1.0;
    };
    let bias = coarse_bias.unwrap_or(0.0) * e.value_rms;
    let target = (e.rms * e.rms - bias * bias).max(0.0).sqrt();
    let valid: Vec<f32> = (patches.patches.iter().zip(noise))
        .filter(|(p, _)| p.is_valid())
        .map(|(_, n)| *n)
        .collect();
    let own = rms_of(&valid);
    if own > 0.0 {
        (target / own) as f32
    } else {
        1.0
    }
}

/// RMS of `values`.
fn rms_of(values: &[f32]) -> f64 {
    let n = values.len().max(1) as f64;
    (values.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / n).sqrt()
}

/// [`filter_one`] without the luminance term), weighted as the filter weighs distance.
fn smooth_variance(a: &Assembly, patches: &Patches, noise: &[f32], radius: u32) -> Vec<f32> {
    patches
        .patches
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            if !p.is_valid() {
                return noise[i];
            }
            let page = &a.pages[p.page as usize];
            let (sum, weight) = neighbours(patches, p, (page.width, page.height), radius)
                .map(|(j, w)| (w * noise[j] * noise[j], w))
                .fold((noise[i] * noise[i], 1.0), |(s, t), (a, b)| (s + a, t + b));
            (sum / weight).sqrt()
        })
        .collect()
}

/// The texels within `radius` of patch `p` that the filter may mix with it (valid, same
/// instance and chart, normals within 25°, where the texel grid puts them in the world),
/// with their spatial weight; `p` itself left out.
fn neighbours<'a>(
    patches: &'a Patches,
    p: &'a Patch,
    (w, h): (u32, u32),
    radius: u32,
) -> impl Iterator<Item = (usize, f32)> + 'a {
    let index = &patches.page_index[p.page as usize];
    let r = radius as i64;
    let spatial = 2.0 * (radius as f32 * 0.5).max(0.5).powi(2);
    (-r..=r)
        .flat_map(move |dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter_map(move |(dx, dy)| {
            let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
            if (dx == 0 && dy == 0) || x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                return None;
            }
            let j = index[(y * w as i64 + x) as usize];
            if j == u32::MAX {
                return None;
            }
            let q = &patches.patches[j as usize];
            if !q.is_valid() || q.instance != p.instance || q.chart != p.chart {
                return None;
            }
            if p.normal.dot(q.normal) < NORMAL_COS {
                return None;
            }
            let d = ((dx * dx + dy * dy) as f32).sqrt();
            if p.position.distance(q.position) > (1.5 * d + 1.0) * p.texel_size.max(q.texel_size) {
                return None;
            }
            Some((j as usize, (-(d * d) / spatial).exp()))
        })
}

/// The filter at patch `i` (see the module docs), reading the pages as they were.
fn filter_one(
    a: &Assembly,
    patches: &Patches,
    i: usize,
    radius: u32,
    sigma: &impl Fn(usize) -> f32,
) -> Filtered {
    let p = &patches.patches[i];
    let page = &a.pages[p.page as usize];
    let size = (page.width, page.height);
    let x_i = page.get(p.x, p.y);
    let (l_i, s_i) = (luminance(x_i), sigma(i));
    let lum = |j: usize| {
        let q = &patches.patches[j];
        luminance(page.get(q.x, q.y))
    };
    // The guide: the luminance around the texel, averaged over its closest neighbours, and
    // the variance of that average. Every texel, the centre too, is weighed by how far it
    // lies from the guide in noise units, so an outlier at the centre (a firefly) does not
    // keep its neighbours out.
    let (mut g_sum, mut g_weight, mut g_var) = (l_i, 1.0f32, s_i * s_i);
    for (j, spatial) in neighbours(patches, p, size, 1) {
        g_sum += spatial * lum(j);
        g_weight += spatial;
        g_var += spatial * spatial * sigma(j).powi(2);
    }
    let (guide, guide_var) = (g_sum / g_weight, g_var / (g_weight * g_weight));
    let range_weight = |l: f32, s: f32| {
        let range = RANGE_K * RANGE_K * (s * s + guide_var);
        if range > 0.0 {
            (-(l - guide).powi(2) / (2.0 * range)).exp()
        } else {
            0.0
        }
    };
    // (patch, weight) of every texel the filter mixes, the texel itself first.
    let mut taps: Vec<(usize, f32)> = vec![(i, range_weight(l_i, s_i).max(1e-4))];
    for (j, spatial) in neighbours(patches, p, size, radius) {
        let weight = spatial * range_weight(lum(j), sigma(j));
        if weight > 1e-4 {
            taps.push((j, weight));
        }
    }
    let total: f32 = taps.iter().map(|t| t.1).sum();
    let value_of = |j: usize| {
        let q = &patches.patches[j];
        page.get(q.x, q.y)
    };
    let filtered = taps
        .iter()
        .fold(Vec3::ZERO, |s, &(j, wj)| s + value_of(j) * (wj / total));
    let l_f = luminance(filtered);
    // The signal's variance around the texel: the neighbours' spread less their noise (the
    // texel itself left out: it is what is being estimated, and an outlier would count its
    // own error as detail and keep itself).
    let (mut spread, mut noise, mut around) = (0.0f32, 0.0f32, 0.0f32);
    for &(j, wj) in &taps[1..] {
        spread += wj * (luminance(value_of(j)) - l_f).powi(2);
        noise += wj * sigma(j).powi(2);
        around += wj;
    }
    // α = σ²/(σ² + signal), 0 where both vanish (σ² underflows to 0 for σ below 10⁻¹⁹;
    // 0/0 there was a NaN).
    let s2 = s_i * s_i;
    let alpha = if around > 0.0 {
        let signal = ((spread - noise) / around).max(0.0);
        let denominator = s2 + signal;
        if denominator > 0.0 && denominator.is_finite() {
            s2 / denominator
        } else {
            0.0
        }
    } else {
        0.0
    };
    let value = x_i + (filtered - x_i) * alpha;
    // The output's noise and the part of the change that noise explains.
    let (mut noise_sq, mut change_noise) = (0.0f32, 0.0f32);
    for (k, &(j, wj)) in taps.iter().enumerate() {
        let a_ij = alpha * wj / total + if k == 0 { 1.0 - alpha } else { 0.0 };
        let sj2 = sigma(j).powi(2);
        noise_sq += a_ij * a_ij * sj2;
        let c = a_ij - if k == 0 { 1.0 } else { 0.0 };
        change_noise += c * c * sj2;
    }
    let bias_sq = ((luminance(value) - l_i).powi(2) - change_noise).max(0.0);
    Filtered {
        value,
        strength: alpha,
        noise_sq,
        bias_sq,
    }
}
