//! Direct light at every texel patch: punctual lights, the sun, the sky and emissive
//! triangles, each with shadow rays, averaged over `samples_per_texel` points of the texel's
//! footprint so shadow edges are antialiased.
//!
//! Irradiance E is computed in lux (linear RGB); the lightmap stores E/π (see
//! [`crate::lightmap`]).
//!
//! * **Point / spot** (glTF `KHR_lights_punctual`, as Bevy shades them): E = I·cosθ/d² ·
//!   W(d) · S(cd), with Bevy's range window W(d) = saturate(1 − (d/range)⁴)² and
//!   d² clamped below at 10⁻⁴ m², and the glTF spot falloff
//!   S = saturate(cd·scale + offset)², scale = 1/max(cos θᵢ − cos θₒ, 10⁻⁴),
//!   offset = −cos θₒ·scale, cd the cosine to the spot axis.
//! * **Directional** (sun): E = E⊥·cosθ, with directions sampled uniformly in the sun's cone
//!   when it has an angular radius (soft shadows).
//! * **Sky**: uniform luminance L: E = π·L·(fraction of cosine-distributed rays that escape).
//! * **Emissive triangles**: with at most `max_closed_form_emitters` emitting triangles, the
//!   unoccluded irradiance is evaluated in closed form ([`polygon`]) and shadow rays estimate
//!   only the visible fraction with a ratio estimator: the emitter is sampled in proportion to
//!   each triangle's closed-form contribution, uniformly in area within it, and
//!   E ≈ E_unoccluded · Σ wᵢVᵢ / Σ wᵢ with wᵢ = f(yᵢ)/p(yᵢ). This is exact wherever the
//!   emitter is fully visible or fully hidden. With more emitters, triangles are picked by
//!   power and the plain Monte Carlo estimator f·V/p is used.

pub mod polygon;

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bake::BakeContext;
use crate::bvh::{RayScene, coincident_groups};
use crate::estimate::standard_error;
use crate::plan::BakePlan;
use crate::progress::Progress;
use crate::raster::{Patch, Patches, Surface, SurfaceFrame, SurfacePoint};
use crate::sampling::{
    cosine_hemisphere, hash, sobol_02, uniform_cone, uniform_triangle, unit_float,
};
use crate::scene::{LightKind, Scene};
use crate::settings::BakeSettings;
use crate::unwrap::Layout;
use polygon::point_to_polygon_form_factor;

/// Random-number streams of a texel (mixed into its key).
mod stream {
    pub const FOOTPRINT: u32 = 1;
    pub const FOOTPRINT_RETRY: u32 = 2;
    pub const SKY: u32 = 3;
    pub const EMITTER: u32 = 4;
    pub const EMITTER_PICK: u32 = 5;
    pub const LIGHT: u32 = 100;
}

/// An emissive triangle, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// Global triangle index.
    pub triangle: u32,
    /// World vertices.
    pub vertices: [Vec3; 3],
    /// Unit normal (front side).
    pub normal: Vec3,
    /// Area, m².
    pub area: f32,
    /// Emitted luminance, nits, linear RGB.
    pub radiance: Vec3,
    /// Emits from both faces (double-sided material).
    pub two_sided: bool,
}

/// Every emissive triangle of the scene, with a power CDF for sampling.
#[derive(Clone, Debug, Default)]
pub struct Emitters {
    /// The triangles.
    pub list: Vec<Emitter>,
    /// Cumulative power (luminance-weighted radiance × area × sides), normalised to end at 1.
    cdf: Vec<f32>,
    /// (global triangle, emitter index), sorted by triangle.
    by_triangle: Vec<(u32, u32)>,
    /// Emissive triangles left out of sampling because an earlier one has the same three
    /// world vertices (a duplicated mesh or face); rays that hit them still see their radiance.
    pub coincident: usize,
    /// Pairs of sampled emitter triangles that lie in the same plane, face the same way and
    /// overlap with positive area (not exact duplicates): their light adds up where they
    /// overlap. Up to [`MAX_OVERLAPS_LISTED`] pairs of global triangles; see
    /// [`Emitters::overlapping_count`] for how many there are.
    pub overlapping: Vec<(u32, u32)>,
    /// Number of such pairs.
    pub overlapping_count: usize,
}

/// Overlapping emitter pairs kept by name in [`Emitters::overlapping`].
pub const MAX_OVERLAPS_LISTED: usize = 8;

/// Pairs (i < j) of `list` that lie in one plane, face the same way and overlap with positive
/// area. Emitters are grouped by plane (normal to 10⁻⁴, offset to 10⁻⁵ of the scene extent
/// `extent`), then swept by bounding box along the plane's first tangent, and each candidate
/// pair is checked by separating axes in the plane with a small margin (triangles that share
/// an edge touch but do not overlap).
fn overlapping_pairs(list: &[Emitter], extent: f32) -> Vec<(usize, usize)> {
    let tol = 1e-5 * extent.max(1e-30);
    let mut keyed: Vec<((i64, i64, i64, i64), usize)> = list
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let n = e.normal;
            let q = |x: f32| (x * 1e4).round() as i64;
            let d = ((n.dot(e.vertices[0]) / tol).round()) as i64;
            ((q(n.x), q(n.y), q(n.z), d), k)
        })
        .collect();
    keyed.sort_unstable();
    let mut pairs = Vec::new();
    for group in keyed.chunk_by(|a, b| a.0 == b.0) {
        if group.len() < 2 {
            continue;
        }
        let (t, b) = crate::sampling::basis(list[group[0].1].normal);
        let flat = |k: usize| list[k].vertices.map(|v| Vec2::new(v.dot(t), v.dot(b)));
        let mut items: Vec<(f32, f32, usize, [Vec2; 3])> = group
            .iter()
            .map(|&(_, k)| {
                let f = flat(k);
                let (lo, hi) = f.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                    (lo.min(p.x), hi.max(p.x))
                });
                (lo, hi, k, f)
            })
            .collect();
        items.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for (i, a) in items.iter().enumerate() {
            for b in &items[i + 1..] {
                if b.0 >= a.1 - tol {
                    break;
                }
                if triangles_overlap(&a.3, &b.3, tol) {
                    pairs.push((a.2.min(b.2), a.2.max(b.2)));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Whether two plane triangles overlap by more than `margin` (no edge normal of either
/// separates them with a gap or an overlap thinner than `margin`).
fn triangles_overlap(a: &[Vec2; 3], b: &[Vec2; 3], margin: f32) -> bool {
    for tri in [a, b] {
        for i in 0..3 {
            let e = tri[(i + 1) % 3] - tri[i];
            let axis = Vec2::new(-e.y, e.x);
            let len = axis.length();
            if len <= 0.0 {
                return false;
            }
            let axis = axis / len;
            let project = |t: &[Vec2; 3]| {
                t.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                    let x = p.dot(axis);
                    (lo.min(x), hi.max(x))
                })
            };
            let (a0, a1) = project(a);
            let (b0, b1) = project(b);
            if a1.min(b1) - a0.max(b0) <= margin {
                return false;
            }
        }
    }
    true
}

/// Luminance weights of linear Rec.709 RGB.
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

impl Emitters {
    /// Collects emissive triangles of every instance (baked or not).
    pub fn collect(scene: &Scene, rays: &RayScene) -> Self {
        let mut list = Vec::new();
        for (g, info) in rays.triangles.iter().enumerate() {
            if info.area <= 0.0 {
                continue;
            }
            let inst = &scene.instances[info.instance as usize];
            let material = scene.material_of(inst.mesh);
            if !material.is_emissive() {
                continue;
            }
            let mesh = &scene.meshes[inst.mesh];
            let [a, b, c] = mesh.triangle(info.local as usize);
            let mut radiance = material.emissive;
            if let (Some(t), Some(uv0)) = (material.emissive_texture, mesh.uv0.as_ref()) {
                let tex = &scene.textures[t.texture];
                let centroid = (uv0[a] + uv0[b] + uv0[c]) / 3.0;
                let mean = [uv0[a], uv0[b], uv0[c], centroid]
                    .iter()
                    .map(|&uv| tex.sample_srgb(uv).truncate())
                    .sum::<Vec3>()
                    / 4.0;
                radiance *= mean;
            }
            if radiance.max_element() <= 0.0 {
                continue;
            }
            list.push(Emitter {
                triangle: g as u32,
                vertices: [a, b, c].map(|i| inst.transform.transform_point3(mesh.positions[i])),
                normal: info.normal,
                area: info.area,
                radiance,
                two_sided: material.double_sided,
            });
        }
        // Coincident duplicates: two emitters on the same triangle are one visible surface, but
        // each adds its full closed-form irradiance and neither shadows the other, so the light
        // would count twice. Sample the first; map hits on a twin to it.
        // `sampled_as[k]`: the emitter that stands for emitter k (itself unless an earlier
        // coincident one with the same radiance does).
        let mut sampled_as: Vec<usize> = (0..list.len()).collect();
        for group in coincident_groups(list.iter().enumerate().map(|(k, e)| (k as u32, e.vertices)))
        {
            for (i, &k) in group.iter().enumerate() {
                let k = k as usize;
                if let Some(&f) = group[..i].iter().find(|&&f| {
                    sampled_as[f as usize] == f as usize
                        && list[f as usize].radiance == list[k].radiance
                }) {
                    sampled_as[k] = f as usize;
                }
            }
        }
        let mut new_index = vec![0u32; list.len()];
        let mut kept = Vec::with_capacity(list.len());
        for (k, e) in list.iter().enumerate() {
            if sampled_as[k] == k {
                new_index[k] = kept.len() as u32;
                kept.push(*e);
            }
        }
        let twins: Vec<(u32, u32)> = (0..list.len())
            .filter(|&k| sampled_as[k] != k)
            .map(|k| (list[k].triangle, new_index[sampled_as[k]]))
            .collect();
        list = kept;
        let mut total = 0.0f64;
        let mut cdf: Vec<f32> = list
            .iter()
            .map(|e| {
                total += (luminance(e.radiance).max(1e-20)
                    * e.area
                    * if e.two_sided { 2.0 } else { 1.0 }) as f64;
                total as f32
            })
            .collect();
        if total > 0.0 {
            for c in &mut cdf {
                *c /= total as f32;
            }
        }
        let mut by_triangle: Vec<(u32, u32)> = list
            .iter()
            .enumerate()
            .map(|(k, e)| (e.triangle, k as u32))
            .chain(twins.iter().copied())
            .collect();
        by_triangle.sort_unstable();
        let pairs = overlapping_pairs(&list, rays.extent);
        Self {
            overlapping: pairs
                .iter()
                .take(MAX_OVERLAPS_LISTED)
                .map(|&(a, b)| (list[a].triangle, list[b].triangle))
                .collect(),
            overlapping_count: pairs.len(),
            list,
            cdf,
            by_triangle,
            coincident: twins.len(),
        }
    }

    /// Whether there is nothing to sample.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The emitter on global triangle `triangle`, if it emits.
    pub fn index_of(&self, triangle: u32) -> Option<usize> {
        self.by_triangle
            .binary_search_by_key(&triangle, |e| e.0)
            .ok()
            .map(|k| self.by_triangle[k].1 as usize)
    }

    /// Probability with which [`Emitters::pick`] picks emitter `k`.
    pub fn probability(&self, k: usize) -> f32 {
        self.cdf[k] - if k == 0 { 0.0 } else { self.cdf[k - 1] }
    }

    /// Picks an emitter by power: (index, probability).
    pub fn pick(&self, u: f32) -> (usize, f32) {
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.list.len() - 1);
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (i, self.cdf[i] - prev)
    }
}

/// Irradiance of one point light at `sp`, before visibility, and the shadow-ray target.
pub(crate) fn punctual(
    light: &crate::scene::Light,
    sp: &SurfacePoint,
) -> Option<(Vec3, Vec3, f32)> {
    let to_light = light.position - sp.position;
    let d2 = to_light.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let d = d2.sqrt();
    let l = to_light / d;
    let cos = sp.normal.dot(l);
    if cos <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
        return None;
    }
    let window = match light.range {
        Some(r) => {
            let f = d2 / (r * r);
            let s = (1.0 - f * f).clamp(0.0, 1.0);
            s * s
        }
        None => 1.0,
    };
    let cone = match light.kind {
        LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => {
            let (ci, co) = (inner_cone_angle.cos(), outer_cone_angle.cos());
            let scale = 1.0 / (ci - co).max(1e-4);
            let offset = -co * scale;
            let cd = light.direction.dot(-l);
            let a = (cd * scale + offset).clamp(0.0, 1.0);
            a * a
        }
        _ => 1.0,
    };
    let e = light.color * (light.intensity * cos * window * cone / d2.max(1e-4));
    (e.max_element() > 0.0).then_some((e, l, d))
}

/// What the direct pass produced.
#[derive(Clone, Debug, Default)]
pub struct DirectResult {
    /// Irradiance per patch, lux, linear RGB.
    pub irradiance: Vec<Vec3>,
    /// Standard error of each patch's irradiance from its own samples, lux (luminance; see
    /// [`crate::estimate`]). Zero for invalid patches.
    pub standard_error: Vec<f32>,
    /// Shadow and sky rays traced.
    pub rays: u64,
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
}

/// Computes direct irradiance at every patch. Invalid patches get zero (they are filled from
/// their neighbours later).
pub fn direct_light(
    bake: &BakeContext<'_>,
    emitters: &Emitters,
    progress: &Progress,
) -> DirectResult {
    let ctx = Ctx {
        scene: bake.scene,
        layout: bake.layout,
        rays: bake.rays,
        patches: bake.patches,
        surface: Surface::new(bake.scene, bake.layout, bake.rays),
        settings: bake.settings,
        plan: bake.plan,
        emitters,
        closed_form: emitters.list.len() <= bake.settings.max_closed_form_emitters as usize,
    };
    let ray_count = AtomicU64::new(0);
    let (irradiance, standard_error): (Vec<Vec3>, Vec<f32>) = bake
        .patches
        .patches
        .par_chunks(256)
        .flat_map_iter(|chunk| {
            let cancelled = progress.is_cancelled();
            let mut local_rays = 0u64;
            let out: Vec<(Vec3, f32)> = chunk
                .iter()
                .map(|p| {
                    if cancelled || !p.is_valid() {
                        (Vec3::ZERO, 0.0)
                    } else {
                        texel(&ctx, p, &mut local_rays)
                    }
                })
                .collect();
            ray_count.fetch_add(local_rays, Ordering::Relaxed);
            progress.advance(chunk.len() as u64);
            out
        })
        .unzip();
    DirectResult {
        irradiance,
        standard_error,
        rays: ray_count.into_inner(),
    }
}

/// The representative point of a patch as a surface point (its barycentrics are not tracked:
/// the point may have been moved off its triangle by the validity pass).
pub fn representative(p: &Patch) -> SurfacePoint {
    SurfacePoint {
        position: p.position,
        normal: p.normal,
        geometric_normal: p.geometric_normal,
        triangle: p.triangle,
        bary: Vec2::splat(1.0 / 3.0),
    }
}

/// The points of one patch's texel footprint: point `s` is a point of the texel square on one
/// of its triangles, or the representative point when the square point misses them (partly
/// covered texel) or cannot see the representative point (geometry in between). Shared by the
/// passes that sample texel footprints.
pub struct Footprint<'a> {
    layout: &'a Layout,
    patches: &'a Patches,
    surface: &'a Surface<'a>,
    rays: &'a RayScene,
    p: &'a Patch,
    seed: u32,
    /// The surface over the whole texel square as one affine map, when the square lies inside
    /// the patch's triangle and no other geometry is near: every first-attempt point then
    /// comes from it without a search of the footprint triangles, as [`Surface::point`] would
    /// give it.
    frame: Option<SurfaceFrame>,
}

/// Barycentric margin a texel square must keep inside its triangle for [`Footprint`]'s affine
/// map (so rounding cannot put a point where the search would pick another triangle).
const FRAME_MARGIN: f32 = 1e-4;

impl<'a> Footprint<'a> {
    /// The footprint of patch `p`, with random streams keyed by `seed`.
    pub fn new(
        layout: &'a Layout,
        patches: &'a Patches,
        surface: &'a Surface<'a>,
        rays: &'a RayScene,
        p: &'a Patch,
        seed: u32,
    ) -> Self {
        let frame = (p.flags & (Patch::NEAR_GEOMETRY | Patch::MOVED) == 0
            && patches.footprint_of(p).contains(&p.triangle))
        .then(|| layout.instances[p.instance as usize])
        .flatten()
        .and_then(|rect| {
            let centre = Vec2::new((p.x - rect.x) as f32 + 0.5, (p.y - rect.y) as f32 + 0.5);
            surface.frame(p.triangle, centre)
        })
        .filter(|frame| frame.covers(0.5, FRAME_MARGIN));
        Self {
            layout,
            patches,
            surface,
            rays,
            p,
            seed,
            frame,
        }
    }

    /// Whether the points come from the affine map of the texel square (see the field docs).
    pub fn is_affine(&self) -> bool {
        self.frame.is_some()
    }

    /// Point `s` (see the type docs); shadow rays traced to check it are added to `rays`.
    pub fn point(&self, s: u32, rays: &mut u64) -> SurfacePoint {
        match &self.frame {
            Some(frame) => frame.point(self.first(s) - Vec2::splat(0.5)),
            None => self.searched_point(s, rays),
        }
    }

    /// The first-attempt offset of point `s` in the texel square, in [0, 1)².
    fn first(&self, s: u32) -> Vec2 {
        sobol_02(s, self.p.rng(self.seed, stream::FOOTPRINT))
    }

    /// Point `s` found by the general search of the footprint triangles, which
    /// [`Self::point`] skips when the texel has an affine map (the same point up to rounding).
    pub fn searched_point(&self, s: u32, rays: &mut u64) -> SurfacePoint {
        let p = self.p;
        let rep = representative(p);
        let footprint = self.patches.footprint_of(p);
        let Some(rect) = self.layout.instances[p.instance as usize] else {
            return rep;
        };
        let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
        for attempt in 0..4u32 {
            let u = if attempt == 0 {
                self.first(s)
            } else {
                let k = p.rng(self.seed, stream::FOOTPRINT_RETRY);
                Vec2::new(
                    unit_float(hash(k ^ (s * 8 + attempt))),
                    unit_float(hash(k.wrapping_add(0x9e37_79b9) ^ (s * 8 + attempt))),
                )
            };
            let q = texel + u;
            let Some(sp) = footprint
                .iter()
                .find_map(|&t| self.surface.point(t, q, 0.0))
            else {
                continue;
            };
            if p.flags & Patch::NEAR_GEOMETRY != 0 {
                // Only open surface on the representative point's side of any wall.
                *rays += 2;
                if !self.patches.sees(p, &sp, self.rays) {
                    return rep;
                }
            }
            return sp;
        }
        rep
    }
}

/// Direct irradiance of one valid patch and its standard error (luminance, lux).
///
/// The error comes from the spread of the footprint samples. With at least two samples per
/// block it is the spread of [`BLOCKS`] blocks' own estimates ([`block_variance`]). With
/// fewer it treats the samples as independent: the punctual, directional and sampled-emitter
/// terms are a plain mean over `spp` samples; the closed-form emitter term is Ū·R, with Ū the
/// mean unoccluded irradiance and R the ratio estimate of its visible fraction, whose variance
/// is taken by the delta method (Σw²(v − R)²/(Σw)²); the sky term is a binomial proportion
/// of escaped rays.
fn texel(ctx: &Ctx<'_>, p: &Patch, rays: &mut u64) -> (Vec3, f32) {
    let seed = ctx.settings.seed;
    let spp = ctx.settings.samples_per_texel;
    let lights = ctx.plan.lights_for(p.instance as usize);
    let far = ctx.rays.extent * 4.0 + 1.0;
    let mut e = Vec3::ZERO;
    // Ratio-estimator sums for the closed-form emitter path.
    let mut unoccluded_sum = Vec3::ZERO;
    let (mut w_visible, mut w_total) = (0.0f32, 0.0f32);
    let mut contributions: Vec<f32> = Vec::new();
    let mut samples: Vec<SurfacePoint> = Vec::with_capacity(spp as usize);
    // Per-sample luminance sums for the error estimate: the plain terms, the unoccluded
    // closed-form irradiance, and the ratio estimator's Σw² over all and over visible samples
    // (its visibility v is 0 or 1, so Σw²(v − R)² = Σ_vis w² − 2R·Σ_vis w² + R²·Σw²).
    let (mut plain, mut plain_sq) = (0.0f64, 0.0f64);
    let (mut unocc, mut unocc_sq) = (0.0f64, 0.0f64);
    let (mut w2_all, mut w2_visible) = (0.0f64, 0.0f64);
    // The same sums per block of consecutive samples (see `block_variance`).
    let mut blocks = [Block::default(); BLOCKS];
    let footprint = Footprint::new(
        ctx.layout,
        ctx.patches,
        &ctx.surface,
        ctx.rays,
        p,
        ctx.settings.seed,
    );
    for s in 0..spp {
        let e_before = e;
        let unoccluded_before = unoccluded_sum;
        let (wv_before, wt_before) = (w_visible, w_total);
        let sp = footprint.point(s, rays);
        samples.push(sp);
        let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
        for &li in lights {
            let light = &ctx.scene.lights[li as usize];
            let u = sobol_02(s, p.rng(seed, stream::LIGHT + li));
            match light.kind {
                LightKind::Point | LightKind::Spot { .. } => {
                    if let Some((irr, l, d)) = punctual(light, &sp) {
                        *rays += 1;
                        let tmax = d - ctx.rays.epsilon(light.position);
                        if !ctx.rays.occluded(origin, l, 0.0, tmax) {
                            e += irr;
                        }
                    }
                }
                LightKind::Directional { angular_radius } => {
                    let to_sun = -light.direction;
                    let dir = if angular_radius > 0.0 {
                        uniform_cone(to_sun, angular_radius.cos(), u)
                    } else {
                        to_sun
                    };
                    let cos = sp.normal.dot(dir);
                    if cos > 0.0 && sp.geometric_normal.dot(dir) > 0.0 {
                        *rays += 1;
                        if !ctx.rays.occluded(origin, dir, 0.0, far) {
                            e += light.color * (light.intensity * cos);
                        }
                    }
                }
            }
        }
        if ctx.plan.area_lights && !ctx.emitters.is_empty() {
            if ctx.closed_form {
                let (wv, wt) = (w_visible, w_total);
                closed_form_emitter_sample(
                    ctx,
                    p,
                    s,
                    &sp,
                    origin,
                    &mut contributions,
                    &mut unoccluded_sum,
                    &mut w_visible,
                    &mut w_total,
                    rays,
                );
                let w2 = ((w_total - wt) as f64).powi(2);
                w2_all += w2;
                if w_visible > wv {
                    w2_visible += w2;
                }
            } else {
                e += sampled_emitter(ctx, p, s, &sp, origin, rays);
            }
        }
        let y = luminance(e - e_before) as f64;
        plain += y;
        plain_sq += y * y;
        let u = luminance(unoccluded_sum - unoccluded_before) as f64;
        unocc += u;
        unocc_sq += u * u;
        let block = &mut blocks[(s as usize * BLOCKS) / spp as usize];
        block.n += 1;
        block.plain += y;
        block.unoccluded += u;
        block.w_visible += (w_visible - wv_before) as f64;
        block.w_total += (w_total - wt_before) as f64;
    }
    let mut irradiance = e / spp as f32;
    let mut variance = (standard_error(plain, plain_sq, spp) as f64).powi(2);
    if ctx.plan.area_lights && ctx.closed_form && w_total > 0.0 {
        let r = (w_visible / w_total) as f64;
        irradiance += unoccluded_sum / spp as f32 * r as f32;
        // Var(Ū·R) ≈ R²·Var(Ū) + Ū²·Var(R).
        let u_mean = unocc / spp as f64;
        let var_r =
            (w2_visible * (1.0 - 2.0 * r) + r * r * w2_all).max(0.0) / (w_total as f64).powi(2);
        variance +=
            r * r * (standard_error(unocc, unocc_sq, spp) as f64).powi(2) + u_mean * u_mean * var_r;
    }
    if ctx.plan.sky {
        let n = ctx.settings.sky_samples;
        let mut escaped = 0u32;
        let scale = std::f64::consts::PI * luminance(ctx.scene.sky) as f64;
        for k in 0..n {
            let block = &mut blocks[(k as usize * BLOCKS) / n as usize];
            block.sky_n += 1;
            let sp = samples[(k % spp) as usize];
            let dir = cosine_hemisphere(sp.normal, sobol_02(k, p.rng(seed, stream::SKY)));
            if sp.geometric_normal.dot(dir) <= 0.0 {
                continue;
            }
            *rays += 1;
            let origin = ctx.rays.offset(sp.position, sp.geometric_normal);
            if !ctx.rays.occluded(origin, dir, 0.0, far) {
                escaped += 1;
                block.sky += scale;
            }
        }
        irradiance += ctx.scene.sky * (std::f32::consts::PI * escaped as f32 / n as f32);
        if n > 1 {
            let q = escaped as f64 / n as f64;
            variance += scale * scale * q * (1.0 - q) / n as f64;
        }
    }
    if uses_blocks(ctx.settings, ctx.plan.sky) {
        let r = if w_total > 0.0 {
            (w_visible / w_total) as f64
        } else {
            0.0
        };
        variance = block_variance(&blocks, r);
    }
    (irradiance, variance.sqrt() as f32)
}

/// Whether the direct pass estimates its variance from blocks of samples
/// ([`block_variance`]): when every block gets at least two footprint samples (and two sky
/// rays, when the sky is sampled).
fn uses_blocks(settings: &BakeSettings, sky: bool) -> bool {
    let enough = |n: u32| n as usize >= 2 * BLOCKS;
    enough(settings.samples_per_texel) && (!sky || enough(settings.sky_samples))
}

/// How the direct pass estimates its error with these settings (for the report).
pub fn error_method(settings: &BakeSettings, sky: bool) -> String {
    if uses_blocks(settings, sky) {
        format!(
            "spread of {BLOCKS} blocks of the {} footprint samples",
            settings.samples_per_texel
        )
    } else {
        format!(
            "variance over {} footprint samples",
            settings.samples_per_texel
        )
    }
}

/// Blocks of consecutive samples for the replicate variance estimate.
const BLOCKS: usize = 4;

/// One block's luminance sums (see [`block_variance`]).
#[derive(Clone, Copy, Default)]
struct Block {
    n: u32,
    plain: f64,
    unoccluded: f64,
    w_visible: f64,
    w_total: f64,
    sky: f64,
    sky_n: u32,
}

/// Variance of a texel's direct estimate from the spread of its blocks' own estimates
/// (replicated estimates, as in randomised quasi-Monte Carlo; Owen 2013, *Monte Carlo theory,
/// methods and examples*, §17): each block of consecutive samples of the scrambled
/// (0, 2)-sequence is itself a stratified point set, so its estimate y_b is a replicate of the
/// whole one with 1/B of the samples, and the variance of their mean is estimated by
/// Σ(y_b − ȳ)²/(B(B − 1)). Unlike the independent-sample formula, this sees what the
/// stratification gains (hard shadow edges across a texel, stratified sky rays), which that
/// formula counted as noise: 2.6× the measured error in the sunlit room. The whole sequence
/// is better stratified than B separate blocks, so in expectation this overstates the variance
/// of the estimate a little; it cannot see bias. `r` is the whole texel's visible fraction,
/// used for a block whose ratio estimator drew no weight.
fn block_variance(blocks: &[Block; BLOCKS], r: f64) -> f64 {
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

/// The emitter triangle as seen from `sp`: closed-form unoccluded irradiance (lux).
fn emitter_irradiance(em: &Emitter, sp: &SurfacePoint) -> Vec3 {
    let facing = em.normal.dot(sp.position - em.vertices[0]);
    if facing <= 0.0 && !em.two_sided {
        return Vec3::ZERO;
    }
    em.radiance
        * (std::f32::consts::PI
            * point_to_polygon_form_factor(sp.position, sp.normal, &em.vertices))
}

/// One footprint sample of the closed-form + ratio estimator (see the module docs).
#[allow(clippy::too_many_arguments)]
fn closed_form_emitter_sample(
    ctx: &Ctx<'_>,
    p: &Patch,
    s: u32,
    sp: &SurfacePoint,
    origin: Vec3,
    contributions: &mut Vec<f32>,
    unoccluded_sum: &mut Vec3,
    w_visible: &mut f32,
    w_total: &mut f32,
    rays: &mut u64,
) {
    contributions.clear();
    let mut total = Vec3::ZERO;
    let mut lum_total = 0.0f32;
    for em in &ctx.emitters.list {
        let e = emitter_irradiance(em, sp);
        total += e;
        let l = luminance(e).max(0.0);
        lum_total += l;
        contributions.push(lum_total);
    }
    *unoccluded_sum += total;
    if lum_total <= 0.0 {
        return;
    }
    // Pick a triangle by its share of the unoccluded irradiance, then a point on it.
    let seed = ctx.settings.seed;
    let pick = unit_float(hash(
        p.rng(seed, stream::EMITTER_PICK) ^ s.wrapping_mul(0x2c1b_3c6d),
    )) * lum_total;
    let i = contributions
        .partition_point(|&c| c <= pick)
        .min(contributions.len() - 1);
    let prev = if i == 0 { 0.0 } else { contributions[i - 1] };
    let prob = (contributions[i] - prev) / lum_total;
    if prob <= 0.0 {
        return;
    }
    let em = &ctx.emitters.list[i];
    let Some((l, d, measure)) =
        emitter_direction(em, origin, sobol_02(s, p.rng(seed, stream::EMITTER)))
    else {
        return;
    };
    let cos_r = sp.normal.dot(l);
    if cos_r <= 0.0 {
        return;
    }
    let w = luminance(em.radiance) * cos_r * measure / prob;
    *w_total += w;
    *rays += 1;
    let tmax = d - 2.0 * ctx.rays.epsilon(origin + l * d);
    if !ctx.rays.occluded(origin, l, 0.0, tmax) {
        *w_visible += w;
    }
}

/// Below this solid angle (sr) an emitter triangle is sampled by area, not by solid angle:
/// the area density is then nearly uniform in solid angle anyway, and the spherical
/// triangle's angles lose accuracy.
const MIN_SOLID_ANGLE: f32 = 1e-2;

/// A point on emitter `em` as seen from `origin`: (unit direction, distance, measure) where
/// `L·cos_r·measure` is the one-sample estimate of the emitter's irradiance (before the pick
/// probability). Triangles that subtend a large solid angle are sampled uniformly in it
/// (measure Ω, Arvo 1995): near an emitter, area sampling's 1/d² weights make the estimate
/// very noisy (two emitting plates meeting at a sharp angle). Small ones are sampled by area
/// (measure A·cos_e/d²). `None` when the point sees the emitter's back (one-sided) or edge-on.
fn emitter_direction(em: &Emitter, origin: Vec3, u: Vec2) -> Option<(Vec3, f32, f32)> {
    let facing = |l: Vec3| {
        let cos_e = -em.normal.dot(l);
        if em.two_sided { cos_e.abs() } else { cos_e }
    };
    if let Some((l, omega)) =
        crate::sampling::spherical_triangle(origin, em.vertices, u, MIN_SOLID_ANGLE)
    {
        let cos_e = facing(l);
        let d = em.normal.dot(em.vertices[0] - origin) / em.normal.dot(l);
        return (cos_e > 0.0 && d > 0.0 && d.is_finite()).then_some((l, d, omega));
    }
    let b = uniform_triangle(u);
    let y = em.vertices[0] * (1.0 - b.x - b.y) + em.vertices[1] * b.x + em.vertices[2] * b.y;
    let to = y - origin;
    let d2 = to.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let d = d2.sqrt();
    let l = to / d;
    let cos_e = facing(l);
    (cos_e > 0.0).then_some((l, d, em.area * cos_e / d2))
}

/// One footprint sample of the plain Monte Carlo emitter estimator (many emitters).
fn sampled_emitter(
    ctx: &Ctx<'_>,
    p: &Patch,
    s: u32,
    sp: &SurfacePoint,
    origin: Vec3,
    rays: &mut u64,
) -> Vec3 {
    let seed = ctx.settings.seed;
    let pick = unit_float(hash(
        p.rng(seed, stream::EMITTER_PICK) ^ s.wrapping_mul(0x2c1b_3c6d),
    ));
    let (i, prob) = ctx.emitters.pick(pick);
    if prob <= 0.0 {
        return Vec3::ZERO;
    }
    let em = &ctx.emitters.list[i];
    let Some((l, d, measure)) =
        emitter_direction(em, origin, sobol_02(s, p.rng(seed, stream::EMITTER)))
    else {
        return Vec3::ZERO;
    };
    let cos_r = sp.normal.dot(l);
    if cos_r <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
        return Vec3::ZERO;
    }
    *rays += 1;
    let tmax = d - 2.0 * ctx.rays.epsilon(origin + l * d);
    if ctx.rays.occluded(origin, l, 0.0, tmax) {
        return Vec3::ZERO;
    }
    em.radiance * (cos_r * measure / prob)
}

#[cfg(test)]
mod tests {
    use super::*;

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
