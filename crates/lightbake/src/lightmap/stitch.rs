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
//! their own keep it with λ = 0.02 (the seam weighs as much as fifty texels' worth of their
//! own value; at 0.1 the house kept a mean jump of 2.5% after the stitch, at 0.02 1.0%, with
//! `--verify 4096` the same on three corpus levels): a shadow that crosses a seam reaches it on both sides and stays, a texel beside
//! the seam moves only as much as the two sides disagree. Solved by
//! [`super::least_squares`]; a value is kept at most twice the brightest texel its samples
//! read and no brighter than the brightest covered texel of its page (a padding texel read
//! with a small weight would otherwise take the jump divided by that weight: on Kenney's FPS
//! level, 2.3× the brightest texel of the scene).
//!
//! The stats say what is left: the jumps before and after over the samples the stitch
//! closes, apart from those where geometry stands on the seam (left apart by design), and
//! the seams still above 10% after it, each with why ([`OpenSeam`]).

use glam::{DVec3, Vec2};
use serde::Serialize;

use super::least_squares::{LeastSquares, Unknowns, holds_value, relative_weight};
use super::seams::{Seam, SeamJumps, jump_floor, sample_jump, seam_jumps_where};
use super::{Assembly, bilinear_taps};
use crate::bvh::RayScene;
use crate::raster::footprint::{Gap, gap_probe};
use crate::raster::{Patches, SurfacePoint};

/// Weight of a texel's own value.
const HOLD: f64 = 0.02;
/// Weight of a padding or hidden texel's value.
const FREE: f64 = 1e-4;
/// A stitched value is at most this many times the brightest texel its seam samples read
/// (and at most the brightest covered texel of its page).
const CEILING: f32 = 2.0;

/// A seam whose jump after the stitch is still above this (relative) is listed with why.
pub const OPEN_JUMP: f64 = 0.10;

/// What the stitch did, for the report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StitchStats {
    /// The seams' jumps before the stitch, over the samples it closes (not those where
    /// geometry stands on the seam).
    pub before: SeamJumps,
    /// And after.
    pub after: SeamJumps,
    /// The jumps after the stitch at the samples where geometry stands on the seam (a wall
    /// on the seam line: two rooms), which it leaves apart.
    pub apart: SeamJumps,
    /// Texels solved for.
    pub unknowns: usize,
    /// Seam samples left out: geometry stands on them.
    pub closed: usize,
    /// Conjugate-gradient iterations (the largest of the three channels).
    pub iterations: u32,
    /// Values lowered to twice the brightest texel their seam samples read, or to the
    /// brightest covered texel of their page.
    pub capped: usize,
    /// Seams with a jump above 10% after the stitch.
    pub open_count: usize,
    /// Each of them, the worst first, with why.
    pub open: Vec<OpenSeam>,
}

impl StitchStats {
    /// One line: the jumps before and after over the samples the stitch closes, the samples
    /// it leaves apart and the seams left open (`seams`: seam edges in all).
    pub fn summary(&self, seams: usize) -> String {
        let mut s = format!(
            "{seams} seam edges, jump {:.2}% mean / {:.2}% max before, {:.2}% / {:.2}% after ({} values capped)",
            100.0 * self.before.mean,
            100.0 * self.before.max,
            100.0 * self.after.mean,
            100.0 * self.after.max,
            self.capped
        );
        if self.closed > 0 {
            s.push_str(&format!(
                "; {} samples where geometry stands on the seam left apart ({:.2}% mean / {:.2}% max)",
                self.closed,
                100.0 * self.apart.mean,
                100.0 * self.apart.max
            ));
        }
        if self.open_count > 0 {
            let mut why: Vec<&str> = self.open.iter().map(|o| o.why.words()).collect();
            why.sort_unstable();
            why.dedup();
            s.push_str(&format!(
                "; {} seam(s) above {:.0}% after: {}",
                self.open_count,
                100.0 * OPEN_JUMP,
                why.join("; ")
            ));
        }
        s
    }
}

/// A seam whose two sides still differ by more than 10% after the stitch.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OpenSeam {
    /// The middle of the seam edge, world m.
    pub at: [f32; 3],
    /// The scene instances of its two sides.
    pub instances: [u32; 2],
    /// Its largest jump after the stitch (relative, as [`SeamJumps`]).
    pub jump: f64,
    /// Why it is left open.
    pub why: OpenWhy,
}

/// Why a seam is left open.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum OpenWhy {
    /// Geometry stands on the seam line (the two sides are two rooms): left apart by design.
    GeometryOnIt,
    /// A value it reads was capped (at twice the brightest texel its samples read, or the
    /// page's brightest covered texel).
    Capped,
    /// Every texel either side reads holds light of its own, and the light changes within a
    /// texel across the seam: the stitch moves them only as far as their hold allows.
    LightWithinATexel,
    /// Its texels are also read by other seams or sides that want other values (a corner
    /// where charts meet).
    SharedTexels,
}

impl OpenWhy {
    /// In words, for the report.
    pub fn words(self) -> &'static str {
        match self {
            OpenWhy::GeometryOnIt => "geometry stands on it (two rooms): left apart",
            OpenWhy::Capped => "a value it reads was capped",
            OpenWhy::LightWithinATexel => {
                "both sides hold light of their own that changes within a texel across it"
            }
            OpenWhy::SharedTexels => "its texels also serve other seams that want other values",
        }
    }
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

/// Whether the seam's point at parameter `t` is open surface: the first surface along either
/// side's normal is not the back of a single-sided one (the point is not inside a solid: a
/// wall standing on the seam line, whose top the probe meets from inside however tall the
/// wall), and nothing stands between the surface half a texel to either side of it (a wall
/// thinner than that). The two sides are then two rooms, and must not be made to agree.
fn open_at(seam: &Seam, t: f32, rays: &RayScene) -> bool {
    let at = seam.world[0].lerp(seam.world[1], t);
    let texels = seam.sides[0].texels[0]
        .distance(seam.sides[0].texels[1])
        .max(1e-6);
    let texel = seam.world[0].distance(seam.world[1]) / texels;
    let probed = seam.normals.iter().all(|&n| {
        let sp = SurfacePoint {
            position: at,
            normal: n,
            geometric_normal: n,
            triangle: 0,
            bary: Vec2::ZERO,
        };
        gap_probe(rays, &sp, f32::INFINITY) != Gap::Back
    });
    if !probed {
        return false;
    }
    // Across the seam, just above the surface: half a texel to either side of the line.
    let n = (seam.normals[0] + seam.normals[1]).normalize_or_zero();
    let along = (seam.world[1] - seam.world[0]).normalize_or_zero();
    let across = n.cross(along);
    if n == glam::Vec3::ZERO || across == glam::Vec3::ZERO {
        return true;
    }
    let [a, b] = [-0.5f32, 0.5].map(|k| rays.offset(at + across * (k * texel), n));
    let d = b - a;
    let len = d.length();
    !(len > 0.0 && rays.occluded(a, d / len, 0.0, len))
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
    // Per seam, per sample: whether it is open surface (geometry does not stand on it).
    let open: Vec<Vec<bool>> = (seams.iter())
        .map(|s| s.samples().map(|t| open_at(s, t, rays)).collect())
        .collect();
    let stitched = |i: usize, k: usize| open[i][k];
    let before = seam_jumps_where(
        seams,
        &assembly.pages,
        jump_floor(&assembly.pages),
        stitched,
    );
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
    for (i, s) in seams.iter().enumerate() {
        let (pa, pb) = (s.sides[0].page, s.sides[1].page);
        for (k, t) in s.samples().enumerate() {
            if open[i][k] {
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
    let solved = x.clone();
    stats.capped = unknowns.cap(assembly, &mut x, &ceiling);
    unknowns.write(assembly, &x);
    let floor = jump_floor(&assembly.pages);
    stats.after = seam_jumps_where(seams, &assembly.pages, floor, stitched);
    stats.apart = seam_jumps_where(seams, &assembly.pages, floor, |i, k| !open[i][k]);
    let capped: Vec<bool> = solved.iter().zip(&x).map(|(a, b)| a != b).collect();
    stats.open = open_seams(assembly, patches, seams, &open, floor, (&unknowns, &capped));
    stats.open_count = stats.open.len();
    stats
}

/// The seams whose jump after the stitch is above [`OPEN_JUMP`], the worst first, each with
/// why (`open`: per seam and sample, whether the stitch closed it; `floor`: the pages'
/// [`jump_floor`]; `capped`: per unknown, whether its value was capped).
fn open_seams(
    assembly: &Assembly,
    patches: &Patches,
    seams: &[Seam],
    open: &[Vec<bool>],
    floor: f64,
    (unknowns, capped): (&Unknowns, &[bool]),
) -> Vec<OpenSeam> {
    let mut left = Vec::new();
    for (i, s) in seams.iter().enumerate() {
        // The worst sample, and whether it is one the stitch closes.
        let (mut jump, mut worst) = (0.0f64, None);
        for (k, t) in s.samples().enumerate() {
            let j = sample_jump(s, t, &assembly.pages, floor);
            if j > jump {
                (jump, worst) = (j, Some((t, open[i][k])));
            }
        }
        let Some((t, stitched)) = worst.filter(|_| jump > OPEN_JUMP) else {
            continue;
        };
        let sides = [0, 1].map(|k| taps(assembly, s.sides[k].page, s.at(k, t)));
        let read = |k: usize| {
            (sides[k].iter())
                .filter(|(_, w)| *w > 0.0)
                .map(move |&(texel, w)| (s.sides[k].page, texel, w))
        };
        let why = if !stitched {
            OpenWhy::GeometryOnIt
        } else if (read(0).chain(read(1)))
            .any(|(page, texel, _)| capped[unknowns.index(page, texel) as usize])
        {
            OpenWhy::Capped
        } else if [0, 1].iter().all(|&k| {
            let held: f32 = (read(k))
                .filter(|&(page, texel, _)| holds_value(assembly, patches, page, texel))
                .map(|(_, _, w)| w)
                .sum();
            held >= 0.5
        }) {
            OpenWhy::LightWithinATexel
        } else {
            OpenWhy::SharedTexels
        };
        let at = (0.5 * (s.world[0] + s.world[1])).to_array();
        let instances = s.sides.map(|d| d.instance);
        left.push(OpenSeam {
            at,
            instances,
            jump,
            why,
        });
    }
    left.sort_by(|a, b| b.jump.total_cmp(&a.jump));
    left
}
