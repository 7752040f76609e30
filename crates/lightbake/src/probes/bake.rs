//! The volume stage: every probe of the grid gathered from the bake's solution
//! (`super::gather`), probes that sit inside geometry moved to the nearest open point or,
//! failing that (or enclosed in a sliver between surfaces), filled from their neighbours
//! (see [`super::volume`]).

use glam::Vec3;
use rayon::prelude::*;

use super::gather::{Gathered, Solution};
use super::grid::VolumeGrid;
use super::volume::{
    ENCLOSED_FRACTION, ENCLOSED_REACH, INSIDE_FRACTION, IrradianceVolume, ProbeState, VolumeStats,
};
use crate::color::luminance;
use crate::progress::Progress;
use crate::sampling::hash_words;

/// One probe's gather after the inside test.
struct Probe {
    sides: [Vec3; 6],
    /// Standard error of each side's luminance.
    error: [f32; 6],
    /// Where it was gathered, when it was moved.
    moved: Option<Vec3>,
    open: bool,
    rays: u64,
}

/// Bakes the volume over `grid` from `solution` with `rays` rays per probe (numbers keyed by
/// the probe and `seed`; the same bits on any thread count).
pub fn bake_volume(
    solution: &Solution<'_>,
    grid: VolumeGrid,
    rays: u32,
    seed: u32,
    progress: &Progress,
) -> (IrradianceVolume, VolumeStats) {
    let probes: Vec<Probe> = (0..grid.len())
        .into_par_iter()
        .with_min_len(4)
        .map(|i| {
            if progress.is_cancelled() {
                return Probe {
                    sides: [Vec3::ZERO; 6],
                    error: [0.0; 6],
                    moved: None,
                    open: true,
                    rays: 0,
                };
            }
            let p = probe(solution, &grid, i, rays, seed);
            progress.advance(1);
            p
        })
        .collect();
    let mut stats = VolumeStats {
        probes: grid.len(),
        resolution: grid.resolution.to_array(),
        spacing: grid.spacing,
        spacing_reason: grid.reason.clone(),
        rays_per_probe: rays,
        rays: probes.iter().map(|p| p.rays).sum(),
        ..VolumeStats::default()
    };
    let (mut err2, mut val2) = (0.0f64, 0.0f64);
    for p in probes.iter().filter(|p| p.open) {
        for s in 0..6 {
            err2 += (p.error[s] as f64).powi(2);
            val2 += (luminance(p.sides[s]) as f64).powi(2);
        }
    }
    if val2 > 0.0 {
        stats.relative_standard_error = (err2 / val2).sqrt();
    }
    stats.moved = probes.iter().filter(|p| p.moved.is_some()).count();
    let mut voxels: Vec<[Vec3; 6]> = probes.iter().map(|p| p.sides).collect();
    let open: Vec<bool> = probes.iter().map(|p| p.open).collect();
    let mut states: Vec<ProbeState> = probes
        .iter()
        .map(|p| match (p.open, p.moved) {
            (true, Some(at)) => ProbeState::Moved(at),
            (true, None) => ProbeState::Open,
            (false, _) => ProbeState::Black,
        })
        .collect();
    let filled = fill(&grid, &mut voxels, open);
    for i in filled {
        states[i] = ProbeState::Filled;
    }
    stats.filled = states.iter().filter(|s| **s == ProbeState::Filled).count();
    stats.unfilled = states.iter().filter(|s| **s == ProbeState::Black).count();
    (
        IrradianceVolume {
            grid,
            voxels,
            states,
        },
        stats,
    )
}

/// What makes a probe's place closed.
#[derive(Clone, Copy)]
struct Test {
    /// The most back hits of an open place.
    most_backs: u32,
    /// The reach of the enclosure test, m.
    near: f32,
    /// The most hits within `near` of an open place.
    most_near: u32,
}

impl Test {
    /// The test for `rays` rays per probe at `spacing` (m): inside geometry over
    /// [`INSIDE_FRACTION`] of the rays, enclosed over [`ENCLOSED_FRACTION`].
    fn new(rays: u32, spacing: f32) -> Self {
        Test {
            most_backs: (INSIDE_FRACTION * rays as f32).floor() as u32,
            near: ENCLOSED_REACH * spacing,
            most_near: (ENCLOSED_FRACTION * rays as f32).floor() as u32,
        }
    }

    /// Whether gather `g` found its place inside geometry (over `most_backs` back hits) or
    /// enclosed (over `most_near` hits within `near`).
    fn closed(&self, g: &Gathered) -> bool {
        g.stopped || g.back_hits > self.most_backs || g.near_hits > self.most_near
    }
}

/// Probe `i`: gathered at its cell's centre, or moved out of the geometry it sits in. A
/// gather stops once its back hits make the point inside (over [`INSIDE_FRACTION`] of the
/// rays): a probe deep in a wall traces about a quarter of its rays at each place it tries.
/// A probe enclosed in a sliver between surfaces ([`ENCLOSED_FRACTION`]) saw no back face to
/// move past: it is left closed, and filled.
fn probe(solution: &Solution<'_>, grid: &VolumeGrid, i: usize, rays: u32, seed: u32) -> Probe {
    let key = hash_words(&[seed, 0x9b0e, i as u32]);
    let centre = grid.position(i);
    let test = Test::new(rays, grid.spacing);
    let g = solution.gather(centre, rays, key, test.most_backs, test.near);
    let mut spent = g.rays;
    if !test.closed(&g) {
        return Probe {
            sides: g.sides,
            error: g.standard_error,
            moved: None,
            open: true,
            rays: spent,
        };
    }
    // Out past the nearest back faces it saw, within one cell: those into the volume's room
    // first, each kind nearest first.
    let margin = (0.05 * grid.spacing).max(16.0 * solution.rays.epsilon(centre));
    let mut places: Vec<(usize, Vec3)> = (g.nearest_backs[..g.backs_kept].iter())
        .map(|&(t, dir)| dir * (t + margin))
        .take_while(|to| to.length() <= grid.spacing)
        .map(|to| centre + to)
        .enumerate()
        .collect();
    // Then out past each back face towards the room's centre (solids overlapping at a corner
    // have several), within one cell: a probe in a façade cut at its outer face sees the
    // near, outer face first, and the sky is behind it.
    let home = grid.rotation * (0.5 * (grid.room[0] + grid.room[1]));
    let dir = (home - centre).normalize_or_zero();
    if dir != Vec3::ZERO {
        let mut from = 0.0;
        for k in 0..g.nearest_backs.len() {
            spent += 1;
            let Some(hit) = solution.rays.closest_hit(centre, dir, from, grid.spacing) else {
                break;
            };
            from = hit.t + margin;
            let info = solution.rays.triangles[hit.triangle as usize];
            if from > grid.spacing {
                break;
            }
            if !hit.front_face && !info.double_sided {
                places.push((g.nearest_backs.len() + k, centre + dir * from));
            }
        }
    }
    places.sort_by_key(|&(k, at)| (!grid.in_room(at), k));
    for (k, at) in places {
        let key = hash_words(&[key, k as u32 + 1]);
        let moved = solution.gather(at, rays, key, test.most_backs, test.near);
        spent += moved.rays;
        if !test.closed(&moved) {
            return Probe {
                sides: moved.sides,
                error: moved.standard_error,
                moved: Some(at),
                open: true,
                rays: spent,
            };
        }
    }
    Probe {
        sides: [Vec3::ZERO; 6],
        error: [0.0; 6],
        moved: None,
        open: false,
        rays: spent,
    }
}

/// Fills the probes that are not `open` with the mean of their open neighbours (the 26
/// around them), pass after pass outwards. Returns the probes filled.
fn fill(grid: &VolumeGrid, voxels: &mut [[Vec3; 6]], mut open: Vec<bool>) -> Vec<usize> {
    let r = grid.resolution.as_ivec3();
    let mut filled = Vec::new();
    loop {
        let mut updates = Vec::new();
        for i in 0..voxels.len() {
            if open[i] {
                continue;
            }
            let c = grid.coords(i).as_ivec3();
            let mut sum = [Vec3::ZERO; 6];
            let mut count = 0;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let q = c + glam::IVec3::new(dx, dy, dz);
                        if q.cmplt(glam::IVec3::ZERO).any() || q.cmpge(r).any() {
                            continue;
                        }
                        let j = grid.index(q.x as u32, q.y as u32, q.z as u32);
                        if open[j] {
                            for s in 0..6 {
                                sum[s] += voxels[j][s];
                            }
                            count += 1;
                        }
                    }
                }
            }
            if count > 0 {
                updates.push((i, sum.map(|v| v / count as f32)));
            }
        }
        if updates.is_empty() {
            break;
        }
        for (i, v) in updates {
            voxels[i] = v;
            open[i] = true;
            filled.push(i);
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_probes_are_filled_from_open_neighbours() {
        let grid = VolumeGrid::over(Vec3::ZERO, Vec3::new(4.0, 2.0, 2.0), 1.0, String::new());
        let mut voxels = vec![[Vec3::ONE; 6]; grid.len()];
        let mut open = vec![true; grid.len()];
        // A solid column at x = 0..1 of the first row: two probes, one behind the other.
        for x in 0..2 {
            let i = grid.index(x, 0, 0);
            voxels[i] = [Vec3::ZERO; 6];
            open[i] = false;
        }
        let filled = fill(&grid, &mut voxels, open);
        assert_eq!(filled, vec![grid.index(0, 0, 0), grid.index(1, 0, 0)]);
        assert!(voxels.iter().all(|v| v[0] == Vec3::ONE));
        let mut none = vec![[Vec3::ZERO; 6]; grid.len()];
        assert!(fill(&grid, &mut none, vec![false; grid.len()]).is_empty());
    }
}
