//! The check `bake --verify` runs (see [`super::verify`]): the points a viewer can see with
//! the path tracer's reference at each, and the bake measured against them.

use crate::bake::BakeOutput;
use crate::bvh::RayScene;
use crate::color::luminance;
use crate::report::{Verification, VerifiedPoint};
use crate::sampling::hash_words;
use crate::scene::Scene;

use super::edges::is_seen;
use super::points::{ScorePoint, references, sample_bake, sample_surface};

/// Worst points kept in the report.
const WORST: usize = 10;

/// `count` points of `out`'s baked surfaces a viewer can see (see the module docs), placed by
/// `place_seed`, with the path tracer's reference at `paths` paths each, numbered by
/// `path_seed` (another seed gives the same points with independent references).
pub fn verification_points(
    scene: &Scene,
    out: &BakeOutput,
    count: usize,
    paths: u32,
    place_seed: u32,
    path_seed: u32,
) -> Vec<ScorePoint> {
    let rays = RayScene::build(scene);
    // A viewer sees the point from eight texels away (a quarter of a cosine fan gets there).
    let band = 2.0 / out.report.plan.texel_density;
    let candidates = sample_surface(scene, &rays, count, place_seed, |sp| {
        is_seen(
            &rays,
            sp,
            band,
            hash_words(&[place_seed, sp.triangle, 0x5ee]),
        )
    });
    references(scene, &rays, &candidates, paths, path_seed)
}

/// The [`Verification`] of `out` at `points` (its `paths` and `seconds` left 0).
pub fn measure(scene: &Scene, out: &BakeOutput, points: &[ScorePoint]) -> Verification {
    let pairs: Vec<(&ScorePoint, f64, f64)> = points
        .iter()
        .filter_map(|p| {
            let b = luminance(sample_bake(out, p)?) as f64;
            Some((p, b, luminance(p.reference) as f64))
        })
        .collect();
    let n = pairs.len();
    let mut v = Verification {
        points: n,
        estimated: out.report.error.as_ref().map(|e| e.relative_rms),
        estimate_covers_grid: out.report.grid_checked(),
        ..Verification::default()
    };
    if n == 0 {
        return v;
    }
    let (mut diff2, mut norm2, mut noise, mut diff, mut sum) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    let mut var_diff2 = 0.0f64;
    for &(p, b, r) in &pairs {
        diff2 += (b - r) * (b - r);
        var_diff2 += 4.0 * (b - r) * (b - r) * p.variance + 2.0 * p.variance * p.variance;
        norm2 += r * r;
        noise += p.variance;
        diff += b - r;
        sum += r;
    }
    let rms_reference = (norm2 / n as f64).sqrt();
    let black = 0.01 * rms_reference;
    let lit = 0.05 * rms_reference;
    let (mut counted, mut beyond_10, mut beyond_25) = (0usize, 0usize, 0usize);
    for &(_, b, r) in &pairs {
        if r >= lit && b < 0.1 * r {
            v.lit_but_black += 1;
        }
        if r < black && b < black {
            continue;
        }
        counted += 1;
        let off = (b - r).abs() / r.max(black);
        beyond_10 += usize::from(off > 0.10);
        beyond_25 += usize::from(off > 0.25);
    }
    if counted > 0 {
        v.beyond_10 = beyond_10 as f64 / counted as f64;
        v.beyond_25 = beyond_25 as f64 / counted as f64;
    }
    if norm2 > 0.0 {
        let m2 = (diff2 - noise) / norm2;
        let half_width = |var: f64| {
            let sd = var.sqrt();
            0.5 * ((m2 + sd).max(0.0).sqrt() - (m2 - sd).max(0.0).sqrt())
        };
        let reference_var = var_diff2 / (norm2 * norm2);
        let sampling_var: f64 = pairs
            .iter()
            .map(|&(p, b, r)| ((b - r) * (b - r) - p.variance - m2 * r * r).powi(2))
            .sum::<f64>()
            / (norm2 * norm2);
        v.relative_rms = m2.max(0.0).sqrt();
        v.uncertainty = half_width(sampling_var + reference_var);
        v.reference_uncertainty = half_width(reference_var);
        v.reference_noise = (noise / norm2).sqrt();
    }
    if sum > 0.0 {
        v.relative_bias = diff / sum;
    }
    if diff2 > 0.0 {
        v.worst_share = pairs
            .iter()
            .map(|&(_, b, r)| (b - r) * (b - r))
            .fold(0.0, f64::max)
            / diff2;
    }
    v.estimate_ratio = v
        .estimated
        .filter(|_| v.relative_rms > 0.0)
        .map(|e| e / v.relative_rms);
    let mut worst: Vec<_> = pairs.iter().collect();
    worst.sort_by(|a, b| {
        let e = |&&(_, b, r): &&(&ScorePoint, f64, f64)| (b - r) * (b - r);
        e(b).total_cmp(&e(a))
    });
    v.worst = worst
        .into_iter()
        .take(WORST)
        .map(|&(p, b, r)| VerifiedPoint {
            instance: scene
                .instances
                .get(p.instance as usize)
                .map_or_else(String::new, |i| i.name.clone()),
            position: p.position.to_array(),
            normal: p.normal.to_array(),
            baked: b as f32,
            reference: r as f32,
        })
        .collect();
    v
}
