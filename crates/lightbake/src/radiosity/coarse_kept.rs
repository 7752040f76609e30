//! The coarse level kept across edits: a bake keeps its cut, its coarse matrix and its first
//! bounce ([`KeptCoarse`]); a later bake over the same texel patches (a light, the sky or a
//! material's albedo edited; a killed bake run again) updates the first bounce by shooting
//! the change of the reflected direct light from the nodes where it changed, and solves the
//! coarse system again over the kept matrix — the incremental form of progressive radiosity
//! (Chen 1990, "Incremental radiosity: an extension of progressive radiosity to an
//! interactive image synthesis system"; George, Sillion & Greenberg 1990, shooting the
//! difference of an edited emitter).
//!
//! Cell c's first bounce is E₁(c) = Σ_j F_cj·s_j, with s_j = ρ_j·H_d,j node j's reflected
//! direct light and F_cj the form factor from the cell to node j's basis function. The kept
//! bake gathered it with rays from the cell's nodes ([`super::coarse::build`]); by
//! reciprocity (A_c·F_cj = A_j·F_jc) its change is
//!
//! ΔE₁(c) = (1 / A_c) · Σ_{j changed} A_j · Δs_j · F̂_jc,
//!
//! F̂_jc the share of node j's rays (started over its basis support, cosine-distributed) whose
//! hits land on cell c's nodes, weighted by their basis weights: the rays start only at the
//! nodes that changed. Nodes whose s_j kept its bits add nothing, so a bake run again on the
//! same input solves the same system and gets the same bits. The cut is the kept bake's
//! (its refinement followed the earlier light); what a coarser cut misses is the
//! correction's ([`super::hierarchical_solve`]), as in any bake.

use glam::Vec3;
use rayon::prelude::*;

use super::clusters::{Cell, Clusters};
use super::coarse::CoarseRows;
use super::hierarchical::{Coarse, CoarseReport, FieldSolve, HierarchyOptions, field_solve};
use super::hit_mapper::HitMapper;
use super::monte_carlo::for_each_sample;
use super::nodes::Nodes;
use crate::context::BakeContext;
use crate::incremental::codec::{Bad, Reader, Writer};
use crate::incremental::patch_geometry;
use crate::progress::Progress;
use crate::scene::hashes::Hasher;
use crate::settings::Basis;
use crate::solve::transport::Transport;

/// Random-number stream of the rays shot from changed nodes.
const STREAM_SHOOT: u32 = 240;

/// Nodes shot in one block: each block's contributions are summed in node order, so the
/// sums do not depend on the threads.
const SHOOT_BLOCK: usize = 4096;

/// The shooting is taken while its rays are at most this share of the rays the kept coarse
/// level traced; beyond, the coarse level is built again.
const SHOOT_SHARE: f64 = 0.5;

/// The shooting is taken while the change it shoots carries at most this share of the power
/// of the new reflected direct light (Σ A·|Δs| against Σ A·s, over the colour channels):
/// the new first bounce is the kept one plus the shot change, and where most of the light
/// went (a sun switched off) that sum is a small difference of two large, noisy figures.
const CHANGE_SHARE: f64 = 0.25;

/// What a bake keeps of its coarse level for a later one.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptCoarse {
    /// The cut.
    pub clusters: Clusters,
    /// The coarse matrix of the cut.
    pub matrix: Transport,
    /// Per cell, the first bounce E₁ (lux).
    pub first_bounce: Vec<Vec3>,
    /// Per node, the reflected direct light s = ρ·H_d it was gathered from (lux).
    pub source: Vec<Vec3>,
    /// Refinement rounds the cut took.
    pub rounds: u32,
    /// The missed detail the cut was left with under the light it was refined for
    /// ([`CoarseReport::missed_detail`]).
    pub missed_detail: f64,
    /// Rays the kept coarse level traced (its rows and oracle over every round).
    pub rays: u64,
    /// The power of the changes shot into its first bounce since it was built
    /// (Σ A·|Δs| over the colour channels, summed over the bakes that updated it): each
    /// shot adds its own noise, so the level is built again once they add up to
    /// [`CHANGE_SHARE`] of the light's power.
    pub shot: f64,
}

/// What `nodes` and their coarse level in round `round` of the hierarchical solve are made
/// from, hashed: the geometry and layout the texel patches come from, the nodes (their
/// patches and basis areas), the coarse level's options and the round. A kept coarse level
/// is taken only under the same key.
pub fn key(ctx: &BakeContext<'_>, nodes: &Nodes, options: &HierarchyOptions, round: u32) -> u64 {
    let mut h = Hasher::default();
    h.u32(round);
    h.u64(patch_geometry(ctx.scene, ctx.layout));
    h.u64(nodes.len() as u64);
    for (&p, &a) in nodes.patch.iter().zip(&nodes.area) {
        h.u64(u64::from(p) << 32 | u64::from(a.to_bits()));
    }
    h.u64(u64::from(options.top_level));
    h.u64(u64::from(options.cell_rays));
    h.u64(options.tolerance.to_bits());
    h.u64(options.max_matrix_bytes);
    h.u64(options.solver_tolerance.to_bits());
    h.u64(u64::from(options.max_iterations));
    h.u64(u64::from(ctx.settings.radiosity.basis == Basis::Linear));
    h.finish()
}

/// Per node, its reflected direct light s = ρ·H_d (`direct` per patch, lux).
pub fn source(nodes: &Nodes, direct: &[Vec3]) -> Vec<Vec3> {
    (0..nodes.len())
        .map(|j| nodes.albedo[j] * direct[nodes.patch[j] as usize])
        .collect()
}

impl KeptCoarse {
    /// What a bake keeps of its finished coarse level: the cut of `coarse`, the last round's
    /// `rows` (one field) and `source`, the reflected direct light the rows gathered.
    pub fn new(coarse: &Coarse, rows: CoarseRows, source: Vec<Vec3>) -> Option<Self> {
        let CoarseRows {
            matrix,
            mut first_bounce,
        } = rows;
        (first_bounce.len() == 1).then(|| KeptCoarse {
            clusters: coarse.clusters.clone(),
            matrix,
            first_bounce: first_bounce.pop().unwrap_or_default(),
            source,
            rounds: coarse.report.rounds,
            missed_detail: coarse.report.missed_detail,
            rays: coarse.report.rays,
            shot: 0.0,
        })
    }

    /// As bytes (read back by [`Self::read`]).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = Writer::default();
        let c = &self.clusters;
        w.len(c.cells.len());
        for cell in &c.cells {
            w.u32(cell.instance);
            w.u32(cell.chart);
            w.u32(u32::from(cell.level));
            w.u32(cell.x);
            w.u32(cell.y);
            w.u32(cell.part);
        }
        w.u32s(&c.of_node);
        w.u32s(&c.start);
        w.u32s(&c.members);
        w.f32s(&c.area);
        let (row_ptr, cols, vals, escaped) = self.matrix.parts();
        w.u64s(row_ptr);
        w.u32s(cols);
        w.f32s(vals);
        w.f32s(escaped);
        w.u64(self.matrix.rays);
        w.f32s(&flatten(&self.first_bounce));
        w.f32s(&flatten(&self.source));
        w.u32(self.rounds);
        w.u64(self.missed_detail.to_bits());
        w.u64(self.rays);
        w.u64(self.shot.to_bits());
        w.into_bytes()
    }

    /// Reads [`Self::to_bytes`] for `nodes` (the cells' albedo taken from the nodes);
    /// refuses bytes whose parts do not fit together or these nodes.
    ///
    /// # Errors
    /// What does not fit, in words.
    pub fn read(bytes: &[u8], nodes: &Nodes) -> Result<Self, Bad> {
        let mut r = Reader::part(bytes);
        let m = r.len(24)?;
        let mut cells = Vec::with_capacity(m);
        for _ in 0..m {
            let (instance, chart, level) = (r.u32()?, r.u32()?, r.u32()?);
            let (x, y, part) = (r.u32()?, r.u32()?, r.u32()?);
            let level = u8::try_from(level).map_err(|_| "a cell level over 255")?;
            cells.push(Cell {
                instance,
                chart,
                level,
                x,
                y,
                part,
            });
        }
        let (of_node, start, members, area) = (r.u32s()?, r.u32s()?, r.u32s()?, r.f32s()?);
        let n = nodes.len();
        let cut_fits = of_node.len() == n
            && of_node.iter().all(|&c| (c as usize) < m)
            && start.len() == m + 1
            && start.first() == Some(&0)
            && start.windows(2).all(|w| w[0] < w[1])
            && start.last() == Some(&(members.len() as u32))
            && members.len() == n
            && members.iter().all(|&i| (i as usize) < n)
            && (0..m).all(|c| {
                let range = start[c] as usize..start[c + 1] as usize;
                members[range]
                    .iter()
                    .all(|&i| of_node[i as usize] == c as u32)
            })
            && area.len() == m;
        if !cut_fits {
            return Err("its coarse cut does not fit the nodes".into());
        }
        let parts = (r.u64s()?, r.u32s()?, r.f32s()?, r.f32s()?);
        let matrix_rays = r.u64()?;
        let matrix = Transport::from_parts(m, parts, matrix_rays, Basis::Constant)
            .ok_or("its coarse matrix does not fit its cut")?;
        let first_bounce = vec3s(&r.f32s()?, m).ok_or("its first bounce does not fit")?;
        let source = vec3s(&r.f32s()?, n).ok_or("its exitance does not fit the nodes")?;
        let rounds = r.u32()?;
        let missed_detail = f64::from_bits(r.u64()?);
        let rays = r.u64()?;
        let shot = f64::from_bits(r.u64()?);
        r.end()?;
        if !(shot.is_finite() && shot >= 0.0) {
            return Err("its shot power is not a power".into());
        }
        let mut clusters = Clusters {
            cells,
            of_node,
            start,
            members,
            area: Vec::new(),
            albedo: Vec::new(),
        };
        clusters.aggregate(nodes);
        Ok(KeptCoarse {
            clusters,
            matrix,
            first_bounce,
            source,
            rounds,
            missed_detail,
            rays,
            shot,
        })
    }
}

fn flatten(v: &[Vec3]) -> Vec<f32> {
    v.iter().flat_map(|x| x.to_array()).collect()
}

fn vec3s(f: &[f32], n: usize) -> Option<Vec<Vec3>> {
    (f.len() == 3 * n).then(|| f.chunks_exact(3).map(Vec3::from_slice).collect())
}

/// Rays shot from a changed node of cell `c`: twice its share of the cell's rays in the
/// build ([`super::coarse::build`]), at least 4.
fn shoot_rays(clusters: &Clusters, c: usize, cell_rays: u32) -> u32 {
    let members = clusters.members_of(c).len().max(1) as u32;
    2 * cell_rays.div_ceil(members).max(2)
}

/// The coarse level of `direct` (per patch, lux) from `kept`: the first bounce updated by
/// shooting from the nodes whose reflected direct light changed, the system solved again
/// over the kept matrix (the cells' albedo the nodes' own).
///
/// # Errors
/// Why the level is to be built again instead, in words: the shooting would take more than
/// [`SHOOT_SHARE`] of the rays the kept level traced, or the change, with those shot since
/// the level was built, would carry more than [`CHANGE_SHARE`] of the new light's power.
pub fn update(
    ctx: &BakeContext<'_>,
    mapper: &HitMapper<'_>,
    nodes: &Nodes,
    direct: &[Vec3],
    kept: KeptCoarse,
    options: &HierarchyOptions,
    progress: &Progress,
) -> Result<(Coarse, KeptCoarse), String> {
    let KeptCoarse {
        clusters,
        matrix,
        mut first_bounce,
        source: old,
        rounds,
        missed_detail,
        rays: kept_rays,
        shot: shot_before,
    } = kept;
    let new = source(nodes, direct);
    let changed: Vec<u32> = (0..nodes.len() as u32)
        .filter(|&j| {
            let (a, b) = (new[j as usize], old[j as usize]);
            a.to_array().map(f32::to_bits) != b.to_array().map(f32::to_bits)
        })
        .collect();
    let ray_of = |j: u32| {
        let c = clusters.of_node[j as usize] as usize;
        shoot_rays(&clusters, c, options.cell_rays)
    };
    let shot: u64 = changed.iter().map(|&j| u64::from(ray_of(j))).sum();
    if shot as f64 > SHOOT_SHARE * kept_rays as f64 {
        return Err(format!(
            "the light changed at {} of {} nodes, more than shooting from them saves",
            changed.len(),
            nodes.len()
        ));
    }
    let power = |v: Vec3| f64::from(v.abs().element_sum());
    let moved: f64 = (changed.iter())
        .map(|&j| f64::from(nodes.area[j as usize]) * power(new[j as usize] - old[j as usize]))
        .sum();
    let total: f64 = (0..nodes.len())
        .map(|j| f64::from(nodes.area[j]) * power(new[j]))
        .sum();
    if shot_before + moved > CHANGE_SHARE * total {
        return Err(format!(
            "the change carries {:.0}% of the reflected direct light's power ({:.0}% with the changes shot since it was built), more than the {:.0}% a shot change is taken for",
            100.0 * moved / total.max(f64::MIN_POSITIVE),
            100.0 * (shot_before + moved) / total.max(f64::MIN_POSITIVE),
            100.0 * CHANGE_SHARE
        ));
    }
    for block in changed.chunks(SHOOT_BLOCK) {
        if progress.is_cancelled() {
            break;
        }
        let parts: Vec<Vec<(u32, Vec3)>> = block
            .par_iter()
            .map(|&j| {
                let j = j as usize;
                let delta = new[j] - old[j];
                let mut hits: Vec<(u32, f32)> = Vec::new();
                let mut total = 0.0f32;
                let _ = for_each_sample(ctx, mapper, nodes, j, ray_of(j as u32), STREAM_SHOOT, {
                    |weight, hit| {
                        total += weight;
                        for &(k, wk) in hit {
                            hits.push((clusters.of_node[k as usize], wk * weight));
                        }
                    }
                });
                if total <= 0.0 {
                    return Vec::new();
                }
                let scale = nodes.area[j] / total;
                hits.iter()
                    .map(|&(c, w)| (c, delta * (w * scale)))
                    .collect()
            })
            .collect();
        for (c, d) in parts.into_iter().flatten() {
            let area = clusters.area[c as usize];
            if area > 0.0 {
                first_bounce[c as usize] += d / area;
            }
        }
    }
    let FieldSolve {
        solution, ambient, ..
    } = field_solve(nodes, direct, &clusters, &matrix, &first_bounce, options);
    let report = CoarseReport {
        cells: clusters.len(),
        cells_per_level: clusters.levels(),
        rounds: 0,
        matrix_entries: matrix.nnz(),
        matrix_bytes: matrix.bytes(),
        missed_detail,
        stop_reason: format!(
            "the earlier bake's cut kept (refined in {rounds} round(s) for its light), its first bounce updated by shooting from {} changed node(s)",
            changed.len()
        ),
        solver: solution.solver,
        rays: shot,
    };
    let coarse = Coarse {
        clusters: clusters.clone(),
        solution,
        report,
        ambient,
    };
    let kept = KeptCoarse {
        clusters,
        matrix,
        first_bounce,
        source: new,
        rounds,
        missed_detail,
        rays: kept_rays,
        shot: shot_before + moved,
    };
    Ok((coarse, kept))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vec3s_round_trip_and_refuse_other_lengths() {
        let v = vec![Vec3::new(1.0, -2.0, 3.5), Vec3::splat(f32::MIN_POSITIVE)];
        assert_eq!(vec3s(&flatten(&v), 2), Some(v.clone()));
        assert_eq!(vec3s(&flatten(&v), 3), None);
        assert_eq!(vec3s(&flatten(&v)[..5], 2), None);
    }
}
