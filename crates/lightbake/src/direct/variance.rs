//! The direct pass's estimate of its own error: the spread of blocks of each texel's
//! footprint samples (replicates), or, with too few samples for blocks, the independent-sample
//! variance (see `texel` in the direct pass).

use crate::settings::BakeSettings;

/// Whether the direct pass estimates its variance from blocks of samples
/// ([`block_variance`]): when every block gets at least two footprint samples (and two sky
/// rays, when the sky is sampled).
pub(super) fn uses_blocks(settings: &BakeSettings, sky: bool) -> bool {
    let enough = |n: u32| n as usize >= 2 * BLOCKS;
    enough(settings.direct.samples_per_texel) && (!sky || enough(settings.direct.sky_samples))
}

/// How the direct pass estimates its error with these settings (for the report).
pub fn error_method(settings: &BakeSettings, sky: bool) -> String {
    if uses_blocks(settings, sky) {
        format!(
            "spread of {BLOCKS} blocks of the {} footprint samples",
            settings.direct.samples_per_texel
        )
    } else {
        format!(
            "variance over {} footprint samples",
            settings.direct.samples_per_texel
        )
    }
}

/// Blocks of consecutive samples for the replicate variance estimate.
pub(super) const BLOCKS: usize = 4;

/// One block's luminance sums (see [`block_variance`]).
#[derive(Clone, Copy, Default)]
pub(super) struct Block {
    pub(super) n: u32,
    pub(super) plain: f64,
    pub(super) unoccluded: f64,
    pub(super) w_visible: f64,
    pub(super) w_total: f64,
    pub(super) sky: f64,
    pub(super) sky_n: u32,
}

/// Variance of a texel's direct estimate from the spread of its blocks' own estimates
/// (replicated estimates, as in randomised quasi-Monte Carlo; Owen 2013, *Monte Carlo theory,
/// methods and examples*, §17): each block of consecutive samples of the scrambled
/// (0, 2)-sequence is itself a stratified point set, so its estimate y_b is a replicate of the
/// whole one with 1/B of the samples, and the variance of their mean is estimated by
/// Σ(y_b − ȳ)²/(B(B − 1)). Unlike the independent-sample formula, this sees what the
/// stratification gains (hard shadow edges across a texel, stratified sky rays), which that
/// formula counts as noise (it overstates the sunlit room's error about 2.5×). The whole sequence
/// is better stratified than B separate blocks, so in expectation this overstates the variance
/// of the estimate a little; it cannot see bias. `r` is the whole texel's visible fraction,
/// used for a block whose ratio estimator drew no weight.
pub(super) fn block_variance(blocks: &[Block; BLOCKS], r: f64) -> f64 {
    let y = blocks.map(|b| {
        let n = b.n.max(1) as f64;
        let rb = if b.w_total > 0.0 {
            b.w_visible / b.w_total
        } else {
            r
        };
        b.plain / n + b.unoccluded / n * rb + b.sky / b.sky_n.max(1) as f64
    });
    let mean = y.iter().sum::<f64>() / BLOCKS as f64;
    y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (BLOCKS * (BLOCKS - 1)) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{hash, unit_float};

    fn block(plain: &[f64]) -> Block {
        Block {
            n: plain.len() as u32,
            plain: plain.iter().sum(),
            ..Block::default()
        }
    }

    #[test]
    fn equal_blocks_have_no_spread() {
        let b = block(&[1.0, 3.0]);
        assert_eq!(block_variance(&[b; BLOCKS], 0.0), 0.0);
    }

    /// A block's estimate: its plain mean, plus its mean unoccluded irradiance times its own
    /// visible fraction (the texel's when the block drew no weight), plus its sky share.
    #[test]
    fn block_estimates_combine_their_terms() {
        let with = |w_visible: f64, w_total: f64| Block {
            n: 2,
            plain: 2.0,
            unoccluded: 8.0,
            w_visible,
            w_total,
            sky: 3.0,
            sky_n: 3,
        };
        // Estimates 1 + 4·R_b + 1: R_b = 1/4, 3/4, 1/2 and (no weight) the texel's 1/2.
        let blocks = [
            with(1.0, 4.0),
            with(3.0, 4.0),
            with(2.0, 4.0),
            with(0.0, 0.0),
        ];
        let y: [f64; BLOCKS] = [3.0, 5.0, 4.0, 4.0];
        let mean = 4.0;
        let expected = y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / 12.0;
        assert!((block_variance(&blocks, 0.5) - expected).abs() < 1e-12);
    }

    /// For independent samples the block estimate is unbiased: averaged over many texels it
    /// gives Var(mean) = σ²/n (uniform samples, σ² = 1/12).
    #[test]
    fn block_variance_is_unbiased_for_independent_samples() {
        let per_block = 8;
        let texels = 40_000;
        let mut sum = 0.0;
        for t in 0..texels {
            let blocks: [Block; BLOCKS] = std::array::from_fn(|b| {
                let xs: Vec<f64> = (0..per_block)
                    .map(|k| {
                        let i = ((t * BLOCKS + b) * per_block + k) as u32;
                        unit_float(hash(i ^ 0x5bd1_e995)) as f64
                    })
                    .collect();
                block(&xs)
            });
            sum += block_variance(&blocks, 0.0);
        }
        let mean = sum / texels as f64;
        let expected = 1.0 / 12.0 / (BLOCKS * per_block) as f64;
        assert!(
            (mean / expected - 1.0).abs() < 0.03,
            "{mean} against {expected}"
        );
    }
}
