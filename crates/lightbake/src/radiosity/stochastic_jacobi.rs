//! Stochastic Jacobi radiosity, incremental form (Neumann, Bekaert et al.; Dutré et al.,
//! *Advanced Global Illumination*, §6.3): matrix-free, for scenes whose transport matrix does
//! not fit in memory.
//!
//! Each iteration shoots the unshot radiosity ΔB with N rays:
//!
//! 1. the unshot power of node j is Φ_j = lum(|ΔB_j|)·A_j, Φ = Σ Φ_j;
//! 2. ray k picks its source by the ξ-stratified number ξ_k = (k + u)/N in the cumulative
//!    distribution of Φ_j (so sources get rays in proportion to their power, with the
//!    stratification of a systematic sample), starts at a random point of the source texel
//!    and leaves in a cosine-distributed direction, carrying the RGB power
//!    ΔB_j·A_j / (N·p_j), p_j = Φ_j/Φ;
//! 3. at its hit the power is split over the nodes by the basis weights: ΔHᵢ += wᵢ·power/Aᵢ
//!    (irradiance received);
//! 4. ΔB ← ρ∘ΔH, B += ΔB, H_indirect += ΔH; N shrinks with Φ so every ray carries about the
//!    same power.
//!
//! Double-sided surfaces and coincident faces follow the gathering matrix's conventions, so
//! that both solve the same system: a texel holds the irradiance on its front side, and the
//! back of a double-sided face shows the same radiosity. A double-sided node therefore shoots
//! from both sides (twice the power, half its rays from the back), and a ray that reaches the
//! back of a double-sided face deposits nothing (that face's back irradiance is not stored).
//! Faces lying exactly on each other (the same three vertices) are one visible surface to
//! a gathering ray, which sees whichever of them the BVH returns: so a shooting ray that
//! reaches such a group deposits its full power in every member it reaches from the front,
//! and a ray that leaves one of k coincident faces carries 1/k of the power (together they
//! radiate as one surface).
//!
//! The unshot fraction ‖ΔB‖/‖S‖ is the residual of the deterministic iteration; the result is
//! a Monte Carlo estimate with noise ∝ 1/√(rays). Rays are processed in fixed chunks whose
//! contributions are merged in order, so the result does not depend on the thread count.

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::hit_mapper::HitMapper;
use super::monte_carlo;
use super::nodes::Nodes;
use super::support::support_point;
use crate::bvh::{Hit, RayScene, coincident_groups};
use crate::color::luminance;
use crate::context::BakeContext;
use crate::progress::Progress;
use crate::raster::SurfacePoint;
use crate::sampling::{cosine_hemisphere, hash_words, unit_float};
use crate::solve::{Recorder, Solution, norm, to_f64};

/// Stopping rules and ray budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StochasticOptions {
    /// Rays shot in the first iteration (later iterations shoot fewer, in proportion to the
    /// unshot power).
    pub first_iteration_rays: u64,
    /// Stop when ‖ΔB‖ / ‖S‖ falls below this.
    pub tolerance: f64,
    /// Give up after this many iterations.
    pub max_iterations: u32,
}

const CHUNK: u64 = 4096;
/// Chunks shot before their deposits are merged: at most 256 × 4096 rays × 4 deposits × 16
/// bytes = 64 MiB of deposits at a time.
const BLOCK_CHUNKS: u64 = 256;

/// Runs stochastic Jacobi on the nodes with source `source` (S = ρ·H_direct).
pub fn solve(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    mapper: &HitMapper<'_>,
    source: &[Vec3],
    options: &StochasticOptions,
    progress: &Progress,
) -> Solution {
    let n = nodes.len();
    let shooter = Shooter::new(ctx, nodes, mapper);
    let mut rec = Recorder::new(Some(progress));
    let s_norm = norm(&to_f64(source), &nodes.area).max(1e-300);
    let mut b = source.to_vec();
    let mut unshot = source.to_vec();
    let mut indirect = vec![Vec3::ZERO; n];
    let mut total_rays = 0u64;
    let mut first_power = None;
    let mut iteration = 0u32;
    rec.record(0.0, 1.0, None);
    let (converged, reason) = loop {
        let residual = norm(&to_f64(&unshot), &nodes.area) / s_norm;
        if residual < options.tolerance {
            break (
                true,
                format!("unshot fraction {residual:.2e} < {:.1e}", options.tolerance),
            );
        }
        if iteration >= options.max_iterations {
            break (
                false,
                format!("stopped after {iteration} iterations at unshot fraction {residual:.2e}"),
            );
        }
        if progress.is_cancelled() {
            break (false, "cancelled".into());
        }
        // 1. Unshot power and its distribution.
        let sources = Sources::new(&shooter, &unshot, iteration);
        if sources.total <= 0.0 {
            break (true, "no unshot power left".into());
        }
        let phi0 = *first_power.get_or_insert(sources.total);
        let rays =
            ((options.first_iteration_rays as f64 * sources.total / phi0).ceil() as u64).max(CHUNK);
        // 2–3. Shoot.
        let received = shooter.shoot(&sources, rays, progress);
        if progress.is_cancelled() {
            break (false, "cancelled".into());
        }
        total_rays += rays;
        // 4. Update.
        for i in 0..n {
            let received = received[i].as_vec3();
            indirect[i] += received;
            unshot[i] = nodes.albedo[i] * received;
            b[i] += unshot[i];
        }
        iteration += 1;
        rec.record(
            iteration as f64,
            norm(&to_f64(&unshot), &nodes.area) / s_norm,
            None,
        );
        progress.advance(1);
    };
    total_rays += gather_slivers(ctx, nodes, mapper, &mut b, &mut indirect);
    Solution {
        solver: "stochastic-jacobi",
        b,
        indirect,
        history: rec.history,
        converged,
        iterations: iteration as f64,
        rays: total_rays,
        stop_reason: reason,
    }
}

/// Sliver nodes (no open footprint point, see [`Nodes::sliver`]) stand for a point, not an
/// area: shot rays almost never land on them. Their reflected light is gathered once at that
/// point from the final exitance `b`, as the gathering solvers' rows do. Returns the rays.
fn gather_slivers(
    ctx: &BakeContext<'_>,
    nodes: &Nodes,
    mapper: &HitMapper<'_>,
    b: &mut [Vec3],
    indirect: &mut [Vec3],
) -> u64 {
    let slivers: Vec<usize> = (0..nodes.len())
        .filter(|&i| nodes.sliver.get(i).copied().unwrap_or(false))
        .collect();
    let gather_rays = ctx.settings.radiosity.transport_rays.max(1);
    let gathered: Vec<Vec3> = slivers
        .par_iter()
        .map(|&i| monte_carlo::gather_row(ctx, mapper, nodes, i, gather_rays, b))
        .collect();
    for (&i, h) in slivers.iter().zip(gathered) {
        b[i] += nodes.albedo[i] * (h - indirect[i]);
        indirect[i] = h;
    }
    slivers.len() as u64 * gather_rays as u64
}

/// What one iteration shoots from: the unshot radiosity, the cumulative distribution of its
/// power over the nodes, and the iteration's random numbers.
struct Sources<'u> {
    unshot: &'u [Vec3],
    /// Cumulative unshot power Σ lum(|ΔB_j|)·A_j·sides_j.
    cdf: Vec<f64>,
    total: f64,
    /// The systematic sample's offset.
    u0: f32,
    /// Seed of the rays' numbers.
    seed: u32,
}

impl<'u> Sources<'u> {
    fn new(shooter: &Shooter<'_>, unshot: &'u [Vec3], iteration: u32) -> Self {
        let nodes = shooter.nodes;
        let mut cdf = Vec::with_capacity(nodes.len());
        let mut total = 0.0f64;
        for j in 0..nodes.len() {
            total += (luminance(unshot[j].abs()) * nodes.area[j] * shooter.sides[j]) as f64;
            cdf.push(total);
        }
        let seed = shooter.ctx.settings.seed;
        Self {
            unshot,
            cdf,
            total,
            u0: unit_float(hash_words(&[seed, iteration, 0x5707])),
            seed: hash_words(&[seed, iteration]),
        }
    }
}

/// The scene as stochastic Jacobi shoots through it.
struct Shooter<'a> {
    ctx: &'a BakeContext<'a>,
    nodes: &'a Nodes,
    mapper: &'a HitMapper<'a>,
    /// Sides each node shoots from (2 for double-sided materials).
    sides: Vec<f32>,
    twins: Twins,
}

impl<'a> Shooter<'a> {
    fn new(ctx: &'a BakeContext<'a>, nodes: &'a Nodes, mapper: &'a HitMapper<'a>) -> Self {
        let sides = (0..nodes.len())
            .map(|j| {
                let patch = &ctx.patches.patches[nodes.patch[j] as usize];
                let mesh = ctx.scene.instances[patch.instance as usize].mesh;
                if ctx.scene.material_of(mesh).double_sided {
                    2.0
                } else {
                    1.0
                }
            })
            .collect();
        Self {
            ctx,
            nodes,
            mapper,
            sides,
            twins: Twins::new(ctx.rays),
        }
    }

    /// Shoots `rays` rays from `sources` in fixed chunks; each chunk returns its sorted
    /// deposits. Chunks run in blocks whose deposits are merged (in chunk order) before the
    /// next block, so the deposits in memory stay bounded however many rays the iteration
    /// shoots. A node can receive millions of deposits in one iteration: they are summed in
    /// f64. Returns the irradiance each node received.
    fn shoot(&self, sources: &Sources<'_>, rays: u64, progress: &Progress) -> Vec<DVec3> {
        let mut received = vec![DVec3::ZERO; self.nodes.len()];
        let chunks = rays.div_ceil(CHUNK);
        for block in (0..chunks).step_by(BLOCK_CHUNKS as usize) {
            // A large iteration shoots many blocks: a cancel is seen between them.
            if progress.is_cancelled() {
                break;
            }
            let deposits: Vec<Vec<(u32, Vec3)>> = (block..(block + BLOCK_CHUNKS).min(chunks))
                .into_par_iter()
                .map(|c| self.chunk(sources, c, rays))
                .collect();
            for chunk in deposits {
                for (i, h) in chunk {
                    received[i as usize] += h.as_dvec3();
                }
            }
        }
        received
    }

    /// The sorted deposits (node, irradiance) of chunk `c` of the iteration's `rays` rays.
    fn chunk(&self, sources: &Sources<'_>, c: u64, rays: u64) -> Vec<(u32, Vec3)> {
        let (ctx, nodes) = (self.ctx, self.nodes);
        let n = nodes.len();
        let mut deposits: Vec<(u32, Vec3)> = Vec::new();
        let mut out = [(0u32, 0f32); 4];
        for k in c * CHUNK..((c + 1) * CHUNK).min(rays) {
            // The source by the ξ-stratified number in the power distribution.
            let xi = ((k as f64 + sources.u0 as f64) / rays as f64) * sources.total;
            let j = sources.cdf.partition_point(|&v| v <= xi).min(n - 1);
            let unshot = sources.unshot[j];
            let pj =
                (luminance(unshot.abs()) * nodes.area[j] * self.sides[j]) as f64 / sources.total;
            if pj <= 0.0 {
                continue;
            }
            let power = unshot * (nodes.area[j] * self.sides[j] / (rays as f64 * pj) as f32);
            let key = hash_words(&[sources.seed, k as u32]);
            let Some((origin, dir, sp)) = self.ray(j, key) else {
                continue;
            };
            let power = power / self.twins.count(sp.triangle) as f32;
            let Some(hit) = ctx.rays.closest_hit(origin, dir, 0.0, f32::INFINITY) else {
                continue;
            };
            self.twins.deposit(ctx.rays, origin, dir, &hit, |hit| {
                // The back of a double-sided face: its texels hold the front only.
                if !hit.front_face {
                    return;
                }
                let m = self.mapper.weights(hit, &mut out);
                for &(i, w) in &out[..m] {
                    deposits.push((i, power * (w / nodes.area[i as usize])));
                }
            });
        }
        deposits.sort_by_key(|d| d.0);
        deposits
    }

    /// The ray that node `j` shoots with numbers `key`: its origin, direction and start point.
    /// It starts on the node's basis support, ∝ φ_j: tent samples accepted with probability
    /// weight / (1.5 × texel area) (the weight is the texel area inside a chart, so 2/3 are
    /// accepted there), and leaves cosine-distributed, from the back for half the rays of a
    /// double-sided node. `None` when the direction points below the surface.
    fn ray(&self, j: usize, key: u32) -> Option<(Vec3, Vec3, SurfacePoint)> {
        let ctx = self.ctx;
        let patch = &ctx.patches.patches[self.nodes.patch[j] as usize];
        let max_w = 1.5 * patch.texel_size * patch.texel_size;
        let sp = (0..8u32)
            .find_map(|attempt| {
                let (sp, w) = support_point(
                    ctx,
                    self.mapper,
                    j,
                    patch,
                    attempt,
                    hash_words(&[key, 7]),
                    &mut 0,
                )?;
                (unit_float(hash_words(&[key, 8, attempt])) * max_w <= w).then_some(sp)
            })
            .unwrap_or_else(|| patch.representative());
        let u = Vec2::new(
            unit_float(hash_words(&[key, 1])),
            unit_float(hash_words(&[key, 2])),
        );
        let back = self.sides[j] > 1.0 && hash_words(&[key, 9]) & 1 == 1;
        let (normal, geometric) = if back {
            (-sp.normal, -sp.geometric_normal)
        } else {
            (sp.normal, sp.geometric_normal)
        };
        let dir = cosine_hemisphere(normal, u);
        if dir.dot(geometric) <= 0.0 {
            return None;
        }
        Some((ctx.rays.offset(sp.position, geometric), dir, sp))
    }
}

/// Groups of triangles with the same three world vertices (coincident faces).
struct Twins {
    /// (triangle, group), sorted by triangle; only triangles that have a twin.
    of: Vec<(u32, u32)>,
    /// The triangles of each group.
    groups: Vec<Vec<u32>>,
}

impl Twins {
    fn new(rays: &RayScene) -> Self {
        let groups = coincident_groups(
            (0..rays.triangles.len() as u32)
                .filter(|&g| rays.triangles[g as usize].area > 0.0)
                .map(|g| (g, rays.triangle_vertices(g))),
        );
        let mut of: Vec<(u32, u32)> = groups
            .iter()
            .enumerate()
            .flat_map(|(id, group)| group.iter().map(move |&g| (g, id as u32)))
            .collect();
        of.sort_unstable();
        Self { of, groups }
    }

    /// How many faces lie exactly on triangle `g` (itself included).
    fn count(&self, g: u32) -> usize {
        self.of
            .binary_search_by_key(&g, |e| e.0)
            .map_or(1, |k| self.groups[self.of[k].1 as usize].len())
    }

    /// Calls `f(hit)` for the hit triangle or, when it has coincident twins, for each of them
    /// reached from the front, with its own barycentrics at the hit point.
    fn deposit(
        &self,
        rays: &RayScene,
        origin: Vec3,
        dir: Vec3,
        hit: &Hit,
        mut f: impl FnMut(&Hit),
    ) {
        let Ok(k) = self.of.binary_search_by_key(&hit.triangle, |e| e.0) else {
            f(hit);
            return;
        };
        let p = origin + dir * hit.t;
        let members: Vec<Hit> = self.groups[self.of[k].1 as usize]
            .iter()
            .map(|&g| {
                let [a, b, c] = rays.triangle_vertices(g);
                let (e1, e2, d) = (b - a, c - a, p - a);
                let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
                let (d1, d2) = (d.dot(e1), d.dot(e2));
                let det = d11 * d22 - d12 * d12;
                let (u, v) = if det > 0.0 {
                    ((d22 * d1 - d12 * d2) / det, (d11 * d2 - d12 * d1) / det)
                } else {
                    (hit.u, hit.v)
                };
                Hit {
                    t: hit.t,
                    triangle: g,
                    u: u.clamp(0.0, 1.0),
                    v: v.clamp(0.0, 1.0 - u.clamp(0.0, 1.0)),
                    front_face: rays.triangles[g as usize].normal.dot(dir) < 0.0,
                }
            })
            .collect();
        if !members.iter().any(|h| h.front_face) {
            f(hit);
            return;
        }
        for h in members.iter().filter(|h| h.front_face) {
            f(h);
        }
    }
}
