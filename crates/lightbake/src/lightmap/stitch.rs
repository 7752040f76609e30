//! The seam stitch: the texels along every seam ([`super::seams`]) adjusted so the two sides
//! show the same light after bilinear filtering (the
//! least-squares stitch of ands/seamoptimizer and z3y/glim):
//!
//! min Σ_s (f_A(s) − f_B(s))² / (L(s)² + L₀²)  +  Σ_j λ_j·(x_j − x⁰_j)² / (L(x⁰_j)² + L₀²)
//!
//! f_A and f_B the bilinear reconstructions of the two sides at seam sample s (about two per
//! texel of edge), L(s) the mean luminance of the two sides there and L₀ 1% of the RMS
//! texel luminance; the errors are relative, as in [`super::contacts`]. The padding texels
//! the seam's samples read, which no surface owns, are nearly free (held at their dilated
//! values with λ = 10⁻⁴), so they take most of the change; the texels that hold light of
//! their own keep it with λ = 0.1 (the seam weighs as much as ten texels' worth of their own
//! value): a shadow that crosses a seam reaches it on both sides and stays, a texel beside
//! the seam moves only as much as the two sides disagree. Solved by
//! [`super::least_squares`]; a value is kept at most twice the brightest texel its samples
//! read and no brighter than the brightest covered texel of its page (a padding texel read
//! with a small weight would otherwise take the jump divided by that weight: on Kenney's FPS
//! level, 2.3× the brightest texel of the scene).

use glam::{DVec3, Vec2};
use serde::Serialize;

use super::least_squares::{LeastSquares, Unknowns, holds_value, relative_weight};
use super::seams::{Seam, SeamJumps, seam_jumps};
use super::{Assembly, bilinear_taps};
use crate::bvh::RayScene;
use crate::raster::footprint::{Gap, gap_probe};
use crate::raster::{Patches, SurfacePoint};

/// Weight of a texel's own value.
const HOLD: f64 = 0.1;
/// Weight of a padding or hidden texel's value.
const FREE: f64 = 1e-4;
/// A stitched value is at most this many times the brightest texel its seam samples read
/// (and at most the brightest covered texel of its page).
const CEILING: f32 = 2.0;

/// What the stitch did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct StitchStats {
    /// The seams' jumps before the stitch.
    pub before: SeamJumps,
    /// And after.
    pub after: SeamJumps,
    /// Texels solved for.
    pub unknowns: usize,
    /// Seam samples left out: geometry stands on them.
    pub closed: usize,
    /// Conjugate-gradient iterations (the largest of the three channels).
    pub iterations: u32,
    /// Values lowered to twice the brightest texel their seam samples read, or to the
    /// brightest covered texel of their page.
    pub capped: usize,
}

/// A bilinear sample's four (page texel index, weight) taps.
type Taps = [(u32, f32); 4];

/// The four (page texel index, weight) taps of a bilinear sample at page texel point `q`.
fn taps(a: &Assembly, page: u32, q: Vec2) -> Taps {
    let p = &a.pages[page as usize];
    bilinear_taps(
        p.width,
        p.height,
        q.x / p.width as f32,
        q.y / p.height as f32,
    )
    .map(|((x, y), w)| (y * p.width + x, w))
}

/// Whether the seam's point at parameter `t` is open surface: nothing lies within a texel of
/// it, along either side's normal, that hides it (a wall standing on the seam line: the
/// two sides are two rooms, and must not be made to agree).
fn open_at(seam: &Seam, t: f32, rays: &RayScene) -> bool {
    let at = seam.world[0].lerp(seam.world[1], t);
    let texels = seam.sides[0].texels[0]
        .distance(seam.sides[0].texels[1])
        .max(1e-6);
    let texel = seam.world[0].distance(seam.world[1]) / texels;
    seam.normals.iter().all(|&n| {
        let sp = SurfacePoint {
            position: at,
            normal: n,
            geometric_normal: n,
            triangle: 0,
            bary: Vec2::ZERO,
        };
        gap_probe(rays, &sp, texel) != Gap::Back
    })
}

/// Stitches `seams` on the assembled pages (after dilation: the padding texels the seam
/// samples read start from their dilated values). Samples where geometry stands on the seam
/// are left out (`open_at`).
pub fn stitch(
    assembly: &mut Assembly,
    patches: &Patches,
    seams: &[Seam],
    rays: &RayScene,
) -> StitchStats {
    let before = seam_jumps(seams, &assembly.pages);
    let mut stats = StitchStats {
        before,
        after: before,
        ..StitchStats::default()
    };
    if seams.is_empty() {
        return stats;
    }
    // Per seam sample: each side's page and bilinear taps.
    let mut samples: Vec<(u32, Taps, u32, Taps)> = Vec::new();
    for s in seams {
        let (pa, pb) = (s.sides[0].page, s.sides[1].page);
        for t in s.samples() {
            if open_at(s, t, rays) {
                samples.push((
                    pa,
                    taps(assembly, pa, s.at(0, t)),
                    pb,
                    taps(assembly, pb, s.at(1, t)),
                ));
            } else {
                stats.closed += 1;
            }
        }
    }
    let unknowns = Unknowns::new(samples.iter().flat_map(|(pa, ta, pb, tb)| {
        ta.iter()
            .map(move |t| (*pa, t.0))
            .chain(tb.iter().map(move |t| (*pb, t.0)))
    }));
    stats.unknowns = unknowns.len();
    let x0 = unknowns.values(assembly);
    let relative = relative_weight(assembly);
    let mut system = LeastSquares::new(unknowns.len());
    let mut row = Vec::with_capacity(8);
    // Per unknown: Σ w·(the relative weight of its samples) and Σ w, for its hold weight.
    let mut scale = vec![(0.0f64, 0.0f64); unknowns.len()];
    // Per unknown: its own value, or `CEILING` × the brightest texel its samples read if
    // higher (a texel a sample reads with weight 0 is an unknown in no row: it keeps its
    // value).
    let mut ceiling = x0.clone();
    for (pa, ta, pb, tb) in &samples {
        row.clear();
        let mut mean = glam::Vec3::ZERO;
        for &(t, w) in ta {
            if w > 0.0 {
                let i = unknowns.index(*pa, t);
                row.push((i, w as f64));
                mean += x0[i as usize] * (0.5 * w);
            }
        }
        for &(t, w) in tb {
            if w > 0.0 {
                let i = unknowns.index(*pb, t);
                row.push((i, -(w as f64)));
                mean += x0[i as usize] * (0.5 * w);
            }
        }
        let a = relative(mean);
        let brightest = row
            .iter()
            .fold(glam::Vec3::ZERO, |m, &(i, _)| m.max(x0[i as usize]));
        for &(i, w) in &row {
            scale[i as usize].0 += w.abs() * a;
            scale[i as usize].1 += w.abs();
            ceiling[i as usize] = ceiling[i as usize].max(CEILING * brightest);
        }
        system.add_row(&row, a, DVec3::ZERO);
    }
    // Both sides of a seam hold their values with the weight of the seam's own samples (not
    // each texel's: a darker side would hold harder in relative terms and pull the seam
    // towards it).
    for (i, (page, t)) in unknowns.iter().enumerate() {
        let kind = if holds_value(assembly, patches, page, t) {
            HOLD
        } else {
            FREE
        };
        let (sum, weight) = scale[i];
        let a = if weight > 0.0 {
            sum / weight
        } else {
            relative(x0[i])
        };
        system.hold(i, kind * a, x0[i].as_dvec3());
    }
    let (mut x, iterations) = system.solve(&x0);
    stats.iterations = iterations;
    stats.capped = unknowns.cap(assembly, &mut x, &ceiling);
    unknowns.write(assembly, &x);
    stats.after = seam_jumps(seams, &assembly.pages);
    stats
}
