//! Error estimates: what each Monte Carlo stage says about its own noise, and how a bake
//! adds them up.
//!
//! Every stage that samples estimates, per texel, the **standard error** of its result
//! (luminance, lux):
//!
//! - direct light: the spread of four blocks of its footprint samples, each block a stratified
//!   replicate of the whole (the direct pass); below eight samples, the sample variance
//!   over N samples divided by N (for the closed-form emitter's ratio estimator, the
//!   delta-method variance);
//! - radiosity: two independent re-gathers of sample nodes against the solution
//!   (`radiosity::gather_error`);
//! - instant radiosity: the variance over particle paths.
//!
//! Over the lightmap they are summarised as
//!
//! - **relative RMS** = √(Σ_t se_t²) / √(Σ_t E_t²) — the RMS error relative to the RMS value,
//!   the same normalisation the convergence study uses for the *measured* error, so the two
//!   can be compared directly;
//! - **p95** = the 95th percentile of se_t / RMS(E): how bad the worst twentieth of texels is,
//!   again relative to the lightmap's RMS value (not to each texel, which would let dark
//!   texels dominate).
//!
//! Stages sample independently, so their absolute RMS errors add in quadrature. The texel
//! grid's own error (shadow edges and light finer than a texel) is no stage's noise: the bake
//! checks the direct light's part of it at points (the `grid error` stage,
//! `lightmap::grid_error`) and adds it in quadrature too. None of the estimates sees other
//! bias (clamping, a basis' discretisation); the convergence study
//! (`bake convergence`) prints the ratio of estimated to measured error so the user can see
//! how far they can be trusted.

use serde::Serialize;

/// One stage's (or a whole bake's) estimate of its own error.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ErrorEstimate {
    /// Absolute RMS standard error over the texels, lux (luminance).
    pub rms: f64,
    /// Absolute 95th percentile of the per-texel standard error, lux.
    pub p95_abs: f64,
    /// RMS luminance of the lightmap the relative figures are measured against, lux.
    pub value_rms: f64,
    /// `rms / value_rms` (0 when the lightmap is black).
    pub relative_rms: f64,
    /// `p95_abs / value_rms`.
    pub p95: f64,
    /// Texels (or radiosity nodes) the estimate covers.
    pub texels: usize,
    /// How it was estimated, in words.
    pub method: String,
}

impl ErrorEstimate {
    /// Summarises per-texel standard errors `se` (lux) against a lightmap whose RMS luminance
    /// is `value_rms` (lux). Non-finite entries are skipped.
    pub fn from_standard_errors(se: &[f32], value_rms: f64, method: impl Into<String>) -> Self {
        let mut finite: Vec<f32> = se.iter().copied().filter(|s| s.is_finite()).collect();
        let n = finite.len();
        if n == 0 {
            return Self {
                method: method.into(),
                ..Self::default()
            }
            .relative_to(value_rms);
        }
        let sum_sq: f64 = finite.iter().map(|&s| (s as f64) * (s as f64)).sum();
        let k = ((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1;
        let (_, p95, _) = finite.select_nth_unstable_by(k, f32::total_cmp);
        Self {
            rms: (sum_sq / n as f64).sqrt(),
            p95_abs: *p95 as f64,
            texels: n,
            method: method.into(),
            ..Self::default()
        }
        .relative_to(value_rms)
    }

    /// The same absolute error expressed against a lightmap of RMS luminance `value_rms`.
    pub fn relative_to(&self, value_rms: f64) -> Self {
        let rel = |x: f64| if value_rms > 0.0 { x / value_rms } else { 0.0 };
        Self {
            value_rms,
            relative_rms: rel(self.rms),
            p95: rel(self.p95_abs),
            ..self.clone()
        }
    }

    /// Independent estimates combined: absolute RMS errors add in quadrature; so do the
    /// p95s (exact when the worst texels coincide, an approximation otherwise). Relative to
    /// `value_rms`.
    pub fn combine<'a>(parts: impl IntoIterator<Item = &'a ErrorEstimate>, value_rms: f64) -> Self {
        let (mut sq, mut p95_sq, mut texels, mut count) = (0.0f64, 0.0f64, 0usize, 0usize);
        for p in parts {
            sq += p.rms * p.rms;
            p95_sq += p.p95_abs * p.p95_abs;
            texels = texels.max(p.texels);
            count += 1;
        }
        Self {
            rms: sq.sqrt(),
            p95_abs: p95_sq.sqrt(),
            texels,
            method: format!("quadrature sum of {count} stage estimate(s)"),
            ..Self::default()
        }
        .relative_to(value_rms)
    }
}

/// RMS luminance (lux) of `values`.
pub fn rms_luminance<'a>(values: impl IntoIterator<Item = &'a glam::Vec3>) -> f64 {
    let (mut s, mut n) = (0.0f64, 0usize);
    for v in values {
        let l = crate::color::luminance(*v) as f64;
        s += l * l;
        n += 1;
    }
    if n == 0 { 0.0 } else { (s / n as f64).sqrt() }
}

/// Standard error of a mean of `n` samples whose sum is `sum` and sum of squares `sum_sq`
/// (unbiased sample variance / n; zero for n < 2).
pub fn standard_error(sum: f64, sum_sq: f64, n: u32) -> f32 {
    if n < 2 {
        return 0.0;
    }
    let n = n as f64;
    let var = ((sum_sq - sum * sum / n) / (n - 1.0)).max(0.0);
    (var / n).sqrt() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic uniform numbers in [0, 1).
    fn uniform(i: u32, seed: u32) -> f64 {
        crate::sampling::unit_float(crate::sampling::hash(i ^ seed.wrapping_mul(0x9e37_79b9)))
            as f64
    }

    #[test]
    fn standard_error_of_uniform_samples_matches_theory() {
        // U(0,1): σ² = 1/12, so se = √(1/(12n)).
        let n = 10_000u32;
        let (mut s, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let x = uniform(i, 7);
            s += x;
            s2 += x * x;
        }
        let se = standard_error(s, s2, n) as f64;
        let want = (1.0 / (12.0 * n as f64)).sqrt();
        assert!((se / want - 1.0).abs() < 0.03, "{se} vs {want}");
        assert_eq!(standard_error(1.0, 1.0, 1), 0.0);
    }

    #[test]
    fn estimate_predicts_the_spread_of_independent_means() {
        // 400 "texels", each the mean of 64 uniform samples around 1: the estimated RMS
        // standard error must match the measured RMS deviation from the true mean 1.
        let (texels, n) = (400u32, 64u32);
        let mut se = Vec::new();
        let mut err_sq = 0.0;
        for t in 0..texels {
            let (mut s, mut s2) = (0.0, 0.0);
            for i in 0..n {
                let x = 0.5 + uniform(t * n + i, 3);
                s += x;
                s2 += x * x;
            }
            se.push(standard_error(s, s2, n));
            err_sq += (s / n as f64 - 1.0).powi(2);
        }
        let measured = (err_sq / texels as f64).sqrt();
        let est = ErrorEstimate::from_standard_errors(&se, 1.0, "test");
        assert!(
            (est.relative_rms / measured - 1.0).abs() < 0.15,
            "estimated {} measured {measured}",
            est.relative_rms
        );
        assert!(est.p95 >= est.relative_rms * 0.9);
        assert_eq!(est.texels, texels as usize);
    }

    #[test]
    fn combination_adds_in_quadrature() {
        let a = ErrorEstimate::from_standard_errors(&[3.0; 10], 10.0, "a");
        let b = ErrorEstimate::from_standard_errors(&[4.0; 10], 20.0, "b");
        let c = ErrorEstimate::combine([&a, &b], 50.0);
        assert!((c.rms - 5.0).abs() < 1e-9);
        assert!((c.relative_rms - 0.1).abs() < 1e-9);
        assert!((c.p95 - 0.1).abs() < 1e-9);
        let r = a.relative_to(30.0);
        assert!((r.relative_rms - 0.1).abs() < 1e-9 && (r.p95 - 0.1).abs() < 1e-9);
        let empty = ErrorEstimate::from_standard_errors(&[f32::NAN], 1.0, "none");
        assert_eq!((empty.rms, empty.texels), (0.0, 0));
    }
}
