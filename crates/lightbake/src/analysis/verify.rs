//! A bake checked against the path tracer: `bake --verify N`
//! ([`CheckSettings::verify_points`](crate::settings::CheckSettings::verify_points)).
//!
//! * **Points**: `N` points of the baked surfaces (`points::sample_surface`: spread
//!   by area × the instance's texel-density scale², open surface, not inside solids), kept
//!   only where a viewer can see them (`edges::is_seen`: a quarter of a cosine fan
//!   travels eight texels before hitting anything). Numbers from the bake's seed, so the same
//!   bake gives the same points on any thread count.
//! * **Reference**: `reference::irradiance` at
//!   [`CheckSettings::verify_paths`](crate::settings::CheckSettings::verify_paths) paths
//!   per point in two independent halves (`points::references`); its noise is stated.
//! * **Bake**: the lightmap where the GPU reads it (`points::sample_bake`: bilinear,
//!   on the point's lightmap UV in the baked scene).
//! * **Measures** ([`Verification`](crate::report::Verification), in `checks`): the relative RMS error of the luminance of E/π with the
//!   reference's noise taken out, √((Σ(b − r)² − Σ var r) / Σ r²) as in
//!   `points::score`, with its uncertainty from the choice of points and from the
//!   reference's noise ([`Verification::uncertainty`](crate::report::Verification::uncertainty)); the relative bias Σ(b − r) / Σ r; the
//!   shares of points beyond ±10% and ±25% (points where both are black, below 1% of the RMS
//!   reference, left out); the points the path tracer finds lit where the lightmap is black;
//!   the worst point's share of the squared error; the bake's own estimate against the
//!   measurement; the ten worst points.

use std::time::Instant;

use super::checks::{measure, verification_points};
use crate::bake::BakeOutput;
use crate::sampling::hash_words;
use crate::scene::Scene;

/// Checks `out` (a bake of `scene`) against the path tracer as its settings ask
/// ([`CheckSettings::verify_points`] points at [`CheckSettings::verify_paths`] paths;
/// nothing when the points are 0) and records the result in `out.report.verification`.
///
/// [`CheckSettings::verify_points`]: crate::settings::CheckSettings::verify_points
/// [`CheckSettings::verify_paths`]: crate::settings::CheckSettings::verify_paths
pub fn verify(scene: &Scene, out: &mut BakeOutput) {
    let settings = &out.report.settings;
    if settings.checks.verify_points == 0 {
        return;
    }
    let (count, paths) = (
        settings.checks.verify_points as usize,
        settings.checks.verify_paths,
    );
    let seed = hash_words(&[settings.seed, 0x7e21_f1e5]);
    let start = Instant::now();
    let points = verification_points(scene, out, count, paths, seed, seed);
    let mut v = measure(scene, out, &points);
    v.paths = 2 * paths.div_ceil(2);
    v.seconds = start.elapsed().as_secs_f64();
    out.report.verification = Some(v);
}
