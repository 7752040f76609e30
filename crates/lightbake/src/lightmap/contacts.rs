//! The contact fit: the texels that have no light of their own — padding outside a chart,
//! texels hidden under geometry — chosen next to geometry so that the bilinear reconstruction
//! the GPU shows is right on the visible surface beside them.
//!
//! The GPU mixes the four texels around a point whatever stands between their centres. Next
//! to a wall standing on a floor, the floor texels under the wall are hidden; filled from
//! their neighbours, they carry one side's light into the reconstruction on the other (a
//! bright strip along the far side of the wall's foot), and padding beside a chart border at
//! a contact is mixed into the texels beside it. Each valid texel's value was computed over
//! its own open footprint, so the lightmap knows what the light should be at a visible point
//! q: the bilinear reconstruction of the texels that belong to q's surface — the valid texels
//! whose representative point sees q as part of its own surface (`Patches::sees`:
//! decided per texel and per sample) — with their weights renormalised, g_q. The fit chooses
//! the free texels' values x so that the plain four-texel reconstruction approaches it:
//!
//! min Σ_q a_q·(Σ_free w_j(q)·x_j + Σ_held w_j(q)·x⁰_j − g_q)² / (L(g_q)² + L₀²)
//!
//! over the samples q that read a free texel, with x⁰ the texel values before the fit (the
//! valid texels keep theirs), a_q the share of a texel each sample stands for, L the luminance
//! and L₀ 1% of the RMS texel luminance. The errors are relative: where a hidden texel is read
//! by a lit floor and a dark one, the dark side is not given a lit side's leak. Each free
//! texel is also held at the mean target of its samples, with as much weight as they have:
//! an exact fit would extrapolate, and amplify, the noise of the texels beside it (a free
//! texel read with a small bilinear weight); held, it stays as quiet as they are. A texel's
//! samples are `SAMPLES` stratified points of its footprint; only texels near geometry take
//! part. The normal equations are solved by conjugate gradients, one per channel; values
//! are kept at zero or above, at most twice the brightest target of the samples that read
//! them and at most the brightest covered texel of the page: a texel read with a small
//! weight would otherwise take the light its samples need divided by that weight, far above
//! any light in the scene and beyond the half-float range, and the GPU shows it wherever
//! else it reads that texel.
//!
//! A valid texel shared by two sides of a wall thinner than a texel keeps its value (lit from
//! its representative point's side): no value serves both sides, and giving it the dark
//! side's light would black out a strip of the lit floor a texel wide.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;

use super::least_squares::{LeastSquares, Unknowns, relative_weight};
use super::{Assembly, bilinear_taps};
use crate::bvh::RayScene;
use crate::context::BakeContext;
use crate::error::Result;
use crate::incremental::codec::{Reader, Writer};
use crate::incremental::patch_geometry;
use crate::raster::footprint::gap_probe;
use crate::raster::{Patch, Patches, Surface, SurfacePoint};
use crate::runner::{StageRunner, WorkScope};
use crate::sampling::sobol_02;
use crate::scene::Scene;
use crate::scene::hashes::Hasher;
use crate::stage::Stage;
use crate::unwrap::Layout;

/// Footprint samples per texel.
const SAMPLES: u32 = 16;
/// Patches per chunk of work.
const CHUNK: usize = 4096;
/// Weight of a free texel's hold at its samples' mean target, relative to theirs.
const FREE: f64 = 1.0;
/// A fitted value is at most this many times the brightest target of the samples that
/// read it (and at most the brightest covered texel of its page).
const CEILING: f32 = 2.0;
/// Stream of the fit's sample points (mixed into a patch's key with [`FIT_SEED`]).
const STREAM: u32 = 0xc0a7;
/// The fit's samples are geometry, like validity's probes: a fixed seed.
const FIT_SEED: u32 = 0x0c0a_7f17;

/// What the contact fit did, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ContactStats {
    /// Texels whose samples took part (near geometry, with a sample that reads a free
    /// texel).
    pub texels: usize,
    /// Valid texels moved out of geometry none of whose footprint is open to them: free too.
    pub moved_out: usize,
    /// Values solved for (those texels' four-texel neighbourhoods, padding included).
    pub unknowns: usize,
    /// Samples that read a free texel.
    pub cut_samples: usize,
    /// Rays traced.
    pub rays: u64,
    /// Conjugate-gradient iterations (the largest of the three channels).
    pub iterations: u32,
    /// Fitted values lowered to twice the brightest light their samples ask for, or to the
    /// brightest covered texel of their page.
    pub capped: usize,
}

/// One sample: its four texels (page texel index, weight, whether it belongs to the sample's
/// surface, whether its value is free to choose).
#[derive(Clone, Copy)]
struct Row {
    page: u32,
    taps: [Tap; 4],
}

/// One of a sample's four texels.
#[derive(Clone, Copy, Default)]
struct Tap {
    texel: u32,
    weight: f32,
    /// A valid texel whose representative point sees the sample as its own surface.
    visible: bool,
    /// Padding or a hidden texel: no value of its own.
    free: bool,
}

impl Row {
    /// Whether the sample reads a free texel.
    fn is_cut(&self) -> bool {
        self.taps.iter().any(|t| t.weight > 0.0 && t.free)
    }
}

/// The contact fit's samples: what it reads of the geometry (fixed numbers, so the same for
/// the same geometry, layout and texel patches), made once and kept across edits of the
/// light ([`ContactRows::to_bytes`]).
#[derive(Clone, Default)]
pub struct ContactRows {
    rows: Vec<Row>,
    /// The samples' counters (texels, moved out, cut samples, rays traced).
    stats: ContactStats,
}

/// The contact fit as stage `contact fit` on `assembly`: its samples read only the geometry
/// and layout, so they are taken from the earlier bake this one follows when it kept them
/// under the same [`samples_key`] ([`WorkScope::earlier_state`]), and kept for a later bake.
///
/// # Errors
/// A cancel seen when the stage ends.
pub fn fit_stage<'p>(
    ctx: &BakeContext<'_>,
    assembly: &mut Assembly,
    stages: &mut impl StageRunner<'p>,
) -> Result<ContactStats> {
    let (scene, layout, patches, rays) = (ctx.scene, ctx.layout, ctx.patches, ctx.rays);
    let scope = stages.scope();
    let key = samples_key(scene, layout, patches);
    let earlier = scope.earlier_state(Stage::ContactFit, key);
    let (st, samples) = stages.run(Stage::ContactFit, 1, || {
        let kept = earlier.and_then(|b| ContactRows::read(&b, layout));
        let was_kept = kept.is_some();
        let samples = kept.unwrap_or_else(|| ContactRows::new(scene, layout, patches, rays));
        let mut st = fit(assembly, &samples);
        if was_kept {
            // Nothing traced here.
            st.rays = 0;
        }
        let note = if st.texels == 0 {
            "no texel next to geometry shows light of the wrong side".to_string()
        } else {
            format!(
                "{} texels next to geometry ({} samples cut{}), {} values fitted ({} capped), {} CG iterations",
                st.texels,
                st.cut_samples,
                if was_kept { ", kept from the earlier bake" } else { "" },
                st.unknowns,
                st.capped,
                st.iterations
            )
        };
        Ok(((st, samples), st.rays, note))
    })?;
    scope.keep_state(Stage::ContactFit, key, || samples.to_bytes());
    Ok(st)
}

/// What the contact fit's samples are made from, hashed: the geometry and layout of the
/// texel patches ([`crate::incremental::patch_geometry`]) and their count. Samples are kept
/// across bakes only under the same key (and the same texel patches and settings).
pub fn samples_key(scene: &Scene, layout: &Layout, patches: &Patches) -> u64 {
    let mut h = Hasher::default();
    h.u64(patch_geometry(scene, layout))
        .u64(patches.patches.len() as u64)
        .u32(SAMPLES)
        .u32(FIT_SEED);
    h.finish()
}

impl ContactRows {
    /// The samples of the texels near geometry that read a free texel (see the module docs).
    pub fn new(scene: &Scene, layout: &Layout, patches: &Patches, rays: &RayScene) -> Self {
        let surface = Surface::new(scene, layout, rays);
        // 1. The texels with no light of their own: hidden ones, and those moved out of geometry
        // none of whose footprint is open to them (their light is from beside their texel).
        let moved_out: Vec<(Vec<bool>, u64)> = patches
            .patches
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut used = 0;
                let free = chunk
                    .iter()
                    .map(|p| {
                        if !p.is_valid() {
                            return true;
                        }
                        p.flags & Patch::MOVED != 0
                            && !own_footprint(p, (layout, patches, &surface, rays), &mut used)
                                .any(|sp| patches.sees(p, &sp, rays))
                    })
                    .collect();
                (free, used)
            })
            .collect();
        let mut stats = ContactStats::default();
        let mut free = Vec::with_capacity(patches.patches.len());
        for (f, used) in moved_out {
            stats.rays += used;
            free.extend(f);
        }
        stats.moved_out = patches
            .patches
            .iter()
            .zip(&free)
            .filter(|(p, f)| **f && p.is_valid())
            .count();
        // 2. Samples of the footprints of texels near geometry that read a free texel (only those
        // kept, chunk by chunk: most samples read none).
        let per_chunk: Vec<(Vec<Row>, usize, u64)> = patches
            .patches
            .par_chunks(CHUNK)
            .map(|chunk| {
                let (mut rows, mut texels, mut used) = (Vec::new(), 0, 0);
                for p in chunk {
                    if p.flags & Patch::NEAR_GEOMETRY == 0 {
                        continue;
                    }
                    let before = rows.len();
                    rows.extend(
                        sample_rows(p, (layout, patches, &surface, rays), &free, &mut used)
                            .into_iter()
                            .filter(Row::is_cut),
                    );
                    texels += usize::from(rows.len() > before);
                }
                (rows, texels, used)
            })
            .collect();
        let mut rows = Vec::new();
        for (r, texels, used) in per_chunk {
            stats.rays += used;
            stats.texels += texels;
            stats.cut_samples += r.len();
            rows.extend(r);
        }
        ContactRows { rows, stats }
    }

    /// As bytes, for a later bake ([`Self::read`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = Writer::default();
        let st = &self.stats;
        for v in [st.texels, st.moved_out, st.cut_samples] {
            w.len(v);
        }
        w.u64(st.rays);
        w.len(self.rows.len());
        for r in &self.rows {
            w.u32(r.page);
            for t in &r.taps {
                w.u32(t.texel);
                w.f32(t.weight);
                w.u32(u32::from(t.visible) | u32::from(t.free) << 1);
            }
        }
        w.into_bytes()
    }

    /// [`Self::to_bytes`] read back over `layout` (with the rays they took when they were
    /// made); `None` when a row names a page or texel the layout does not have, or the bytes
    /// do not fit.
    pub fn read(bytes: &[u8], layout: &Layout) -> Option<Self> {
        let mut r = Reader::part(bytes);
        let stats = ContactStats {
            texels: r.u64().ok()? as usize,
            moved_out: r.u64().ok()? as usize,
            cut_samples: r.u64().ok()? as usize,
            rays: r.u64().ok()?,
            ..ContactStats::default()
        };
        let n = r.len(4 + 4 * 12).ok()?;
        let mut rows = Vec::with_capacity(n);
        for _ in 0..n {
            let page = r.u32().ok()?;
            let size = layout.pages.get(page as usize)?;
            let texels = u64::from(size.width) * u64::from(size.height);
            let mut taps = [Tap::default(); 4];
            for t in &mut taps {
                let (texel, weight, flags) = (r.u32().ok()?, r.f32().ok()?, r.u32().ok()?);
                if u64::from(texel) >= texels || !weight.is_finite() || flags > 3 {
                    return None;
                }
                *t = Tap {
                    texel,
                    weight,
                    visible: flags & 1 != 0,
                    free: flags & 2 != 0,
                };
            }
            rows.push(Row { page, taps });
        }
        r.end().ok()?;
        (stats.cut_samples == rows.len()).then_some(ContactRows { rows, stats })
    }
}

/// The contact fit over `samples` on the assembled pages (after hidden texels are filled,
/// before the padding is dilated: the padding texels it solves for are set, the rest dilated
/// after; see the module docs).
pub fn fit(assembly: &mut Assembly, samples: &ContactRows) -> ContactStats {
    let (rows, mut stats) = (&samples.rows, samples.stats);
    if rows.is_empty() {
        return stats;
    }
    // 3. The unknowns: every free texel a sample reads.
    let unknowns = Unknowns::new(rows.iter().flat_map(|r| {
        r.taps
            .iter()
            .filter(|t| t.weight > 0.0 && t.free)
            .map(move |t| (r.page, t.texel))
    }));
    stats.unknowns = unknowns.len();
    let x0 = unknowns.values(assembly);
    let relative = relative_weight(assembly);
    // 4. The normal equations: Σ_free w·x ≈ g − Σ_held w·x⁰ per sample.
    let mut system = LeastSquares::new(unknowns.len());
    let share = 1.0 / SAMPLES as f64;
    let mut taps = Vec::with_capacity(4);
    // The brightest target each unknown's samples ask for (per channel).
    let mut ceiling = vec![Vec3::ZERO; unknowns.len()];
    for r in rows {
        let value = |t: &Tap| assembly.pages[r.page as usize].texels[t.texel as usize];
        let (mut g, mut wv, mut held) = (Vec3::ZERO, 0.0f32, Vec3::ZERO);
        taps.clear();
        for t in r.taps.iter().filter(|t| t.weight > 0.0) {
            if t.visible {
                g += value(t) * t.weight;
                wv += t.weight;
            }
            if t.free {
                taps.push((unknowns.index(r.page, t.texel), t.weight as f64));
            } else {
                held += value(t) * t.weight;
            }
        }
        let g = g / wv;
        let a = share * relative(g);
        system.add_row(&taps, a, (g - held).as_dvec3());
        for &(i, wi) in &taps {
            system.add_target(i, a * wi * wi, g.as_dvec3());
            ceiling[i as usize] = ceiling[i as usize].max(g);
        }
    }
    for i in 0..unknowns.len() {
        system.free(i, FREE, x0[i].as_dvec3());
    }
    // 5. Solve and write back.
    let (mut x, iterations) = system.solve(&x0);
    stats.iterations = iterations;
    // At most `CEILING` × the brightest target of a value's samples (`Unknowns::cap`).
    for c in &mut ceiling {
        *c *= CEILING;
    }
    stats.capped = unknowns.cap(assembly, &mut x, &ceiling);
    unknowns.write(assembly, &x);
    stats
}

/// The points of patch `p`'s footprint the fit samples, with their page texel points:
/// `SAMPLES` stratified points of the texel square (fixed numbers: the samples are geometry,
/// like validity's probes), those that lie on its triangles.
fn footprint_points<'a>(
    p: &'a Patch,
    (layout, patches, surface): (&'a Layout, &'a Patches, &'a Surface<'a>),
) -> impl Iterator<Item = (SurfacePoint, Vec2)> + 'a {
    let rect = layout.instances[p.instance as usize];
    let footprint = patches.footprint_of(p);
    (0..SAMPLES).filter_map(move |s| {
        let rect = rect?;
        let local = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
        let u = sobol_02(s, p.rng(FIT_SEED, STREAM));
        let sp = footprint
            .iter()
            .find_map(|&t| surface.point(t, local + u, 0.0))?;
        Some((sp, Vec2::new(rect.x as f32, rect.y as f32) + local + u))
    })
}

/// [`footprint_points`] without their page points.
fn own_footprint<'a>(
    p: &'a Patch,
    (layout, patches, surface, _): (&'a Layout, &'a Patches, &'a Surface<'a>, &'a RayScene),
    used: &'a mut u64,
) -> impl Iterator<Item = SurfacePoint> + 'a {
    footprint_points(p, (layout, patches, surface)).map(move |(sp, _)| {
        *used += 2;
        sp
    })
}

/// The rows of patch `p`'s footprint samples (see the module docs): a tap is free when
/// `free` says so of its texel, or the texel is padding. Rays traced are added to `used`.
fn sample_rows(
    p: &Patch,
    (layout, patches, surface, rays): (&Layout, &Patches, &Surface<'_>, &RayScene),
    free: &[bool],
    used: &mut u64,
) -> Vec<Row> {
    let page = layout.pages[p.page as usize];
    let index = &patches.page_index[p.page as usize];
    let mut rows = Vec::with_capacity(SAMPLES as usize);
    for (sp, q) in footprint_points(p, (layout, patches, surface)) {
        let probe = gap_probe(rays, &sp, p.texel_size);
        *used += 1;
        let taps = bilinear_taps(
            page.width,
            page.height,
            q.x / page.width as f32,
            q.y / page.height as f32,
        );
        let mut row = Row {
            page: p.page,
            taps: [Tap::default(); 4],
        };
        let mut any = false;
        for (slot, &((x, y), w)) in row.taps.iter_mut().zip(&taps) {
            let k = y * page.width + x;
            let pi = index[k as usize];
            let own = pi != u32::MAX && !free[pi as usize];
            let visible = w > 0.0 && own && {
                let j = &patches.patches[pi as usize];
                let same = j.instance == p.instance && j.chart == p.chart;
                if same && j.flags & Patch::NEAR_GEOMETRY != 0 {
                    *used += 1;
                }
                same && patches.sees_probed(j, &sp, probe, rays)
            };
            any |= visible;
            *slot = Tap {
                texel: k,
                weight: w,
                visible,
                free: !own,
            };
        }
        if any {
            rows.push(row);
        }
    }
    rows
}
