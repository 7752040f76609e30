//! Where a level's irradiance volumes go (`volume.regions` > 1): the baked geometry cut at
//! its walls into rooms, one volume per room, each box fitted to the geometry in it, the
//! boxes overlapping by a probe spacing with a falloff across the overlap, so that Bevy's
//! light probes (0.19 and later: every volume holding a point weighted by a ramp inside its
//! box, `light_probe.wesl`) blend neighbours without a seam.
//!
//! 1. **Frame.** With `volume.oriented`, the boxes turn about the vertical with the level's
//!    walls: the area-weighted circular mean of the vertical faces' normal angles, taken
//!    modulo 90° (the mean of e^{4iθ}), when those faces agree (resultant at least
//!    [`FRAME_AGREEMENT`]) and the mean is over [`FRAME_MIN_DEGREES`] off the world axes. A
//!    level under a rotated glTF node turns its walls and so its volumes.
//! 2. **Walls.** A plane across a region is a wall when surfaces facing along its axis, within
//!    a probe spacing of it, cover at least [`WALL_COVER`] of the region's occupied
//!    cross-section: the cells (of a [`RASTER`]² grid) whose line along the axis meets
//!    geometry on both sides of the plane, so the open sky over a ground plane does not count
//!    against a building's wall. A door leaves most of a wall covered; a row of pillars or a
//!    desk's side does not.
//! 3. **Cuts.** Until there are `volume.regions` regions or none can be cut: the largest
//!    region with a wall is cut at its best-covered wall, each side at least
//!    [`MIN_SIDE_CELLS`] spacings deep; when no region has a wall left, the largest whose grid
//!    at the wanted spacing would be over [`MAX_AUTO_PROBES`] probes is cut in half across
//!    its longest side (so a large open area keeps more of its density).
//!    A wall is looked for a spacing clear of the region's cut faces, so the joints and
//!    window jambs of a façade cut through its middle are no wall across the strip of ground
//!    beside it.
//! 4. **Boxes.** Each region shrinks to the geometry in it (its *room*), then grows past
//!    every cut face: past a wall, [`WALL_REACH`] of a spacing beyond the wall's far face;
//!    past a halving, a spacing. The falloff spans the overlap from both sides (on each axis
//!    with a cut face), so the two weights cross-fade in the wall's doors and across a
//!    halving; inside a room, its own volume alone lights a moving object. (Boxes reaching
//!    a spacing past every cut put probes beyond a façade a cell from the room and the
//!    ground's volume a spacing into the building: trilinear filtering carries the sky in, and
//!    an office floor along its windowed wall reads up to 2.9 times the path tracer's light,
//!    `tests/volume_regions.rs`.)
//!    The layers of probes are set on the region's floor ([`super::headroom::floors`],
//!    [`VolumeGrid::on_floors`]), a region of open ground reaches as high as the rooms'
//!    headroom, and a probe inside a wall is moved out on its room's side (`super::bake`).

use glam::{Quat, Vec2, Vec3, Vec3Swizzles};

use super::grid::{AutoSpacing, LEAST_GAP_TEXELS, MAX_AUTO_PROBES, VolumeGrid};
use super::headroom::{floors, headroom};
use crate::error::Result;
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::unwrap::Layout;

/// Least share of a region's cross-section the faces at a plane must cover for it to be a
/// wall between two rooms.
pub const WALL_COVER: f32 = 0.6;

/// How far past a wall's far face the boxes on either side of it reach, in probe spacings:
/// they overlap in the wall (and its doors, where Bevy's falloff cross-fades them), and a
/// room's volume holds no probe of the room beyond.
pub const WALL_REACH: f32 = 0.1;

/// Least depth of each side of a cut, in probe spacings.
pub const MIN_SIDE_CELLS: f32 = 4.0;

/// Cells per side of the grid a plane's cover is measured on.
pub const RASTER: usize = 48;

/// Most planes along an axis a wall is looked for at.
pub const MAX_BINS: usize = 4096;

/// Least agreement of the vertical faces' directions (the mean resultant length of e^{4iθ},
/// area-weighted) for the boxes to turn with them.
pub const FRAME_AGREEMENT: f32 = 0.5;

/// Least turn, degrees, of the walls off the world axes for the boxes to follow them.
pub const FRAME_MIN_DEGREES: f32 = 1.0;

/// One region of the level, in the frame: its box and which of its faces are cuts (per axis,
/// the low and the high face).
#[derive(Clone, Debug)]
struct Region {
    lo: Vec3,
    hi: Vec3,
    /// Per axis, the low and the high face: `Some(reach)` when the face is a cut, the box
    /// reaching that far past it (m).
    cut: [[Option<f32>; 2]; 3],
}

/// The grids of the volumes over the instances `layout` gives a lightmap: one per region
/// (see the module docs), at most `settings.volume.regions`; one over them all when that is
/// one. Empty when no instance is baked. Without `volume.probe_spacing` the probes are
/// [`AutoSpacing::for_level`] apart (finer than the texels' spacing where the level's rooms
/// are lower than it resolves).
///
/// # Errors
/// As [`VolumeGrid::plan`], for any region.
pub fn plan_volumes(
    scene: &Scene,
    layout: &Layout,
    settings: &BakeSettings,
    texel_density: f32,
) -> Result<Vec<VolumeGrid>> {
    let most = settings.volume.regions.max(1) as usize;
    let baked: Vec<usize> = (0..scene.instances.len())
        .filter(|&i| layout.instances.get(i).is_some_and(Option::is_some))
        .collect();
    if baked.is_empty() {
        return Ok(Vec::new());
    }
    // The automatic spacing, measured only when no spacing is set (an explicit one leaves it
    // unused: the texels' stands in).
    let auto_for = |world: &[[Vec3; 3]]| match settings.volume.probe_spacing {
        Some(_) => AutoSpacing::of_texels(texel_density),
        None => AutoSpacing::for_level(world, texel_density, settings.volume.probes_per_headroom),
    };
    let least_gap = LEAST_GAP_TEXELS / texel_density;
    let world = triangles(scene, &baked, Quat::IDENTITY);
    if most == 1 {
        let (lo, hi) = bounds(world.iter().flatten().copied());
        let footing = floors(&world, (lo.xz(), hi.xz()), least_gap);
        return Ok(
            VolumeGrid::plan(scene, layout, settings, &auto_for(&world), footing)?
                .into_iter()
                .collect(),
        );
    }
    let auto = auto_for(&world);
    let rotation = if settings.volume.oriented {
        wall_frame(&world)
    } else {
        Quat::IDENTITY
    };
    let tris = if rotation == Quat::IDENTITY {
        world
    } else {
        drop(world);
        triangles(scene, &baked, rotation)
    };
    let (lo, hi) = bounds(tris.iter().flatten().copied());
    if !(lo.cmple(hi).all() && lo.is_finite() && hi.is_finite()) {
        return Ok(Vec::new());
    }
    let spacing = settings.volume.probe_spacing.unwrap_or(auto.spacing);
    // How high above its floor a region's box reaches at least: the rooms' headroom, or
    // the level's top where no floor is roofed.
    let level_hi = hi;
    let room_height = headroom(&tris, least_gap).map_or(f32::INFINITY, |h| h.median);
    let mut regions = vec![Region {
        lo,
        hi,
        cut: [[None; 2]; 3],
    }];
    // Each region's triangles (those whose bounds reach into it) and its wall cut, found
    // once.
    let mut walls: Vec<Option<(usize, f32, f32)>> = vec![wall_cut(&tris, &regions[0], spacing)];
    let mut within: Vec<Vec<[Vec3; 3]>> = vec![tris];
    while regions.len() < most {
        let mut order: Vec<usize> = (0..regions.len()).collect();
        order.sort_by(|&a, &b| volume(&regions[b]).total_cmp(&volume(&regions[a])));
        // A wall anywhere first, then a halving of a region too large for its grid.
        // A wall's box reaches a tenth of a spacing past its far face; a halving's a
        // spacing past the cut.
        let wall = (order.iter())
            .find_map(|&k| walls[k].map(|(a, p, half)| (k, a, p, half + WALL_REACH * spacing)));
        let Some((k, axis, plane, reach)) = wall.or_else(|| {
            (order.iter())
                .find_map(|&k| halving_cut(&regions[k], spacing).map(|(a, p)| (k, a, p, spacing)))
        }) else {
            break;
        };
        let mut high = regions[k].clone();
        regions[k].hi[axis] = plane;
        regions[k].cut[axis][1] = Some(reach);
        high.lo[axis] = plane;
        high.cut[axis][0] = Some(reach);
        let parent = std::mem::take(&mut within[k]);
        for (slot, r) in [(Some(k), regions[k].clone()), (None, high)] {
            let own: Vec<[Vec3; 3]> = (parent.iter())
                .filter(|t| {
                    let (a, b) = bounds(t.iter().copied());
                    r.holds(a, b)
                })
                .copied()
                .collect();
            let cut = wall_cut(&own, &r, spacing);
            match slot {
                Some(k) => (within[k], walls[k]) = (own, cut),
                None => {
                    within.push(own);
                    walls.push(cut);
                    regions.push(r);
                }
            }
        }
    }
    let several = regions.len() > 1;
    let mut grids = Vec::with_capacity(regions.len());
    for (r, tris) in regions.iter().zip(&within) {
        let (mut lo, mut hi) = fitted(tris, r);
        let room = [lo, hi];
        let mut footing = floors(tris, (lo.xz(), hi.xz()), least_gap);
        for axis in 0..3 {
            if let Some(reach) = r.cut[axis][0] {
                lo[axis] = r.lo[axis] - reach;
            }
            if let Some(reach) = r.cut[axis][1] {
                hi[axis] = r.hi[axis] + reach;
            }
        }
        if let Some(f) = footing.filter(|_| r.cut[1][1].is_none()) {
            // A region of open ground beside a building holds what stands on it as high
            // as the building's rooms (the fitted box is as thin as the ground itself).
            hi.y = hi.y.max(level_hi.y.min(f.main + room_height));
        }
        if let Some(f) = footing.as_mut().filter(|_| r.cut[1][0].is_some()) {
            // Cut under it (a storey): the box reaches below the cut.
            f.lowest = lo.y;
        }
        let mut grid =
            VolumeGrid::for_bounds(lo, hi, settings.volume.probe_spacing, &auto, footing)?;
        grid.rotation = rotation;
        grid.room = room;
        for axis in 0..3 {
            if r.cut[axis] == [None; 2] {
                continue;
            }
            // The ramp reaches from the box's face as far inside the cut as the box reaches
            // past it, on each side.
            let size = grid.max[axis] - grid.min[axis];
            let mut ramp: f32 = 0.0;
            if let Some(reach) = r.cut[axis][0] {
                ramp = ramp.max(r.lo[axis] + reach - grid.min[axis]);
            }
            if let Some(reach) = r.cut[axis][1] {
                ramp = ramp.max(grid.max[axis] - (r.hi[axis] - reach));
            }
            grid.falloff[axis] = (ramp / size).clamp(0.0, 1.0);
        }
        if several {
            grid.reason = format!(
                "{}; room {} of {} cut at the level's walls",
                grid.reason,
                grids.len() + 1,
                regions.len()
            );
        }
        grids.push(grid);
    }
    Ok(grids)
}

fn volume(r: &Region) -> f32 {
    (r.hi - r.lo).max(Vec3::ZERO).element_product()
}

/// The triangles of the `baked` instances, world positions turned into the frame
/// `rotation` gives (its inverse applied); degenerate ones left out.
fn triangles(scene: &Scene, baked: &[usize], rotation: Quat) -> Vec<[Vec3; 3]> {
    let inverse = rotation.inverse();
    let mut out = Vec::new();
    for &i in baked {
        let inst = &scene.instances[i];
        let mesh = &scene.meshes[inst.mesh];
        for t in 0..mesh.triangle_count() {
            let tri = mesh
                .triangle(t)
                .map(|v| inverse * inst.transform.transform_point3(mesh.positions[v]));
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            if n.length_squared() > 0.0 && n.is_finite() {
                out.push(tri);
            }
        }
    }
    out
}

fn bounds(points: impl Iterator<Item = Vec3>) -> (Vec3, Vec3) {
    points.fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(p), hi.max(p)),
    )
}

/// The turn about the vertical that lines the world axes up with the level's walls (see the
/// module docs), or the identity.
fn wall_frame(tris: &[[Vec3; 3]]) -> Quat {
    let (mut acc, mut total) = (glam::DVec2::ZERO, 0.0f64);
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let area = 0.5 * n.length();
        let n = n / (2.0 * area);
        if n.y.abs() > 0.1 {
            continue;
        }
        let theta = n.z.atan2(n.x);
        acc +=
            glam::DVec2::new((4.0 * theta).cos() as f64, (4.0 * theta).sin() as f64) * area as f64;
        total += area as f64;
    }
    if total == 0.0 {
        return Quat::IDENTITY;
    }
    let sum = (acc / total).as_vec2();
    if sum.length() < FRAME_AGREEMENT {
        return Quat::IDENTITY;
    }
    let phi = sum.y.atan2(sum.x) / 4.0;
    if phi.abs().to_degrees() < FRAME_MIN_DEGREES {
        return Quat::IDENTITY;
    }
    // Turning the frame's x axis by −φ about y points it at angle φ in the xz-plane.
    Quat::from_rotation_y(-phi)
}

/// The region's box shrunk to the geometry in it (the triangles' bounds clipped to it).
fn fitted(tris: &[[Vec3; 3]], r: &Region) -> (Vec3, Vec3) {
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for t in tris {
        let (a, b) = bounds(t.iter().copied());
        let (a, b) = (a.max(r.lo), b.min(r.hi));
        if a.cmple(b).all() {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    }
    if lo.cmple(hi).all() {
        (lo, hi)
    } else {
        (r.lo, r.hi)
    }
}

/// Where to cut `r` at a wall, if anywhere: (axis, coordinate in the frame, half the wall's
/// thickness).
fn wall_cut(tris: &[[Vec3; 3]], r: &Region, spacing: f32) -> Option<(usize, f32, f32)> {
    let ext = r.hi - r.lo;
    let min_side = MIN_SIDE_CELLS * spacing;
    let mut best: Option<(f32, usize, f32, f32)> = None;
    for axis in 0..3 {
        if ext[axis] < 2.0 * min_side {
            continue;
        }
        if let Some((cover, plane, half)) = best_wall(tris, r, axis, spacing, min_side) {
            let better = best.is_none_or(|(c, a, p, _)| {
                let mid = |a: usize, p: f32| (p - 0.5 * (r.lo[a] + r.hi[a])).abs() / ext[a];
                cover > c + 1e-3 || (cover > c - 1e-3 && mid(axis, plane) < mid(a, p))
            });
            if better {
                best = Some((cover, axis, plane, half));
            }
        }
    }
    best.map(|(_, axis, plane, half)| (axis, plane, half))
}

/// The cut in half across its longest side of a region too large for one grid at the
/// wanted spacing, if it is.
fn halving_cut(r: &Region, spacing: f32) -> Option<(usize, f32)> {
    let ext = r.hi - r.lo;
    let grid = VolumeGrid::over(r.lo, r.hi, spacing, String::new());
    let axis = ext.max_position();
    (grid.too_large(MAX_AUTO_PROBES).is_some() && ext[axis] >= 2.0 * MIN_SIDE_CELLS * spacing)
        .then(|| (axis, 0.5 * (r.lo[axis] + r.hi[axis])))
}

/// The plane across `axis` whose facing surfaces cover most of `r`'s occupied cross-section,
/// if one covers [`WALL_COVER`] of it: (cover, the middle of those surfaces along the axis,
/// half their distance: the wall's half thickness).
/// A point of the cross-section is occupied on one side when the line along the axis through
/// it meets geometry on that side beyond the wall's own surfaces (inside a building, not in
/// the open air over a ground plane); the cover is measured for each side on a [`RASTER`]²
/// grid over the bounds of the part occupied there, so a building's outer wall (the
/// building on one side, open ground on the other) is a wall as a wall between two rooms is.
fn best_wall(
    tris: &[[Vec3; 3]],
    r: &Region,
    axis: usize,
    spacing: f32,
    min_side: f32,
) -> Option<(f32, f32, f32)> {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    // Measured a spacing clear of the region's cut faces across the axis: what lies within
    // a spacing of a cut is the neighbour's too (its box reaches that far), and a sliver of
    // the wall cut through there is no wall across this region.
    let r = &r.clear_of_cuts(spacing, [u, v])?;
    // Half a spacing, or coarser on a region so long that there would be more than
    // MAX_BINS of them (the search's work stays bounded; such a grid is refused later).
    let bin = (0.5 * spacing).max((r.hi[axis] - r.lo[axis]) / MAX_BINS as f32);
    let bins = ((r.hi[axis] - r.lo[axis]) / bin)
        .ceil()
        .clamp(1.0, MAX_BINS as f32) as usize;
    let whole = Raster::over(
        Vec2::new(r.lo[u], r.lo[v]),
        Vec2::new(r.hi[u], r.hi[v]),
        (axis, u, v),
    )?;
    // The faces along the axis, flat within a quarter spacing, with their area per bin.
    let mut facing: Vec<(f32, &[Vec3; 3])> = Vec::new();
    let mut area = vec![0.0f32; bins];
    for t in tris {
        let (a, b) = bounds(t.iter().copied());
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        if n[axis].abs() < 0.9 * n.length() || b[axis] - a[axis] > 0.5 * bin || !r.holds(a, b) {
            continue;
        }
        let c = 0.5 * (a[axis] + b[axis]);
        let k = (((c - r.lo[axis]) / bin).max(0.0) as usize).min(bins - 1);
        area[k] += 0.5 * n[axis].abs();
        facing.push((c, t));
    }
    let (near, far) = whole.depths(tris, r);
    // Occupied on the low side, or on the high side, of the surfaces at a..b.
    let occupied = |near: &[f32], far: &[f32], a: f32, b: f32, side: usize| -> Vec<bool> {
        near.iter()
            .zip(far)
            .map(|(n, f)| match side {
                0 => *n < a - bin,
                1 => *f > b + bin,
                _ => *n < a - bin || *f > b + bin,
            })
            .collect()
    };
    // Candidate planes: windows of three bins (a wall's two faces) with area enough for
    // the occupied cells there, each side deep enough, and occupied over at least half the
    // largest occupied cross-section of the region (not a gap between furniture); the best
    // three.
    let occupied_area: Vec<f32> = (0..bins)
        .map(|k| {
            let c = r.lo[axis] + (k as f32 + 0.5) * bin;
            let occ = occupied(&near, &far, c - 0.5 * bin, c + 0.5 * bin, 2);
            occ.iter().filter(|&&o| o).count() as f32 * whole.cell_area()
        })
        .collect();
    let widest = occupied_area.iter().copied().fold(0.0, f32::max);
    let mut candidates: Vec<(f32, usize)> = (0..bins)
        .filter_map(|k| {
            let c = r.lo[axis] + (k as f32 + 0.5) * bin;
            if c - r.lo[axis] < min_side || r.hi[axis] - c < min_side {
                return None;
            }
            let sum: f32 = area[k.saturating_sub(1)..(k + 2).min(bins)].iter().sum();
            let occ = occupied_area[k];
            (occ > 0.0 && sum >= 0.5 * WALL_COVER * occ).then_some((sum / occ, k))
        })
        .collect();
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut best: Option<(f32, f32, f32)> = None;
    for &(_, k) in candidates.iter().take(3) {
        let slab = (k as f32 - 1.0) * bin + r.lo[axis]..(k as f32 + 2.0) * bin + r.lo[axis];
        let wall: Vec<(f32, &[Vec3; 3])> = (facing.iter())
            .filter(|(c, _)| slab.contains(c))
            .copied()
            .collect();
        let (a, b) = wall_faces(&wall, axis, bin);
        let plane = 0.5 * (a + b);
        if plane - r.lo[axis] < min_side || r.hi[axis] - plane < min_side {
            continue;
        }
        // Per side, the part occupied there, and the cover measured finely over its bounds.
        for side in 0..2 {
            let occ = occupied(&near, &far, a, b, side);
            let Some((lo, hi)) = whole.bounds_of(&occ) else {
                continue;
            };
            let Some(fine) = Raster::over(lo, hi, (axis, u, v)) else {
                continue;
            };
            let (near, far) = fine.depths(tris, r);
            let occ = occupied(&near, &far, a, b, side);
            let mut covered = vec![false; RASTER * RASTER];
            for (_, t) in &wall {
                fine.cells(t, |k| covered[k] = true);
            }
            let total = occ.iter().filter(|&&o| o).count();
            let hit = occ.iter().zip(&covered).filter(|(o, c)| **o && **c).count();
            let cover = hit as f32 / total.max(1) as f32;
            let area = total as f32 * fine.cell_area();
            if total >= 16
                && area >= 0.5 * widest
                && cover >= WALL_COVER
                && best.is_none_or(|(c, _, _)| cover > c)
            {
                best = Some((cover, plane, 0.5 * (b - a)));
            }
        }
    }
    best
}

/// The coordinates along `axis` of a wall's two faces among the surfaces `wall` of a slab:
/// the largest area at one coordinate (within a fiftieth of `bin`), and with it every
/// coordinate within `bin` of it holding at least 30% as much (a wall's other face; not the
/// smaller back of a shelf against it).
fn wall_faces(wall: &[(f32, &[Vec3; 3])], axis: usize, bin: f32) -> (f32, f32) {
    let step = bin / 50.0;
    let mut at: Vec<(i64, f32)> = wall
        .iter()
        .map(|(c, t)| {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            ((c / step).round() as i64, 0.5 * n[axis].abs())
        })
        .collect();
    at.sort_by_key(|(k, _)| *k);
    let mut faces: Vec<(f32, f32)> = Vec::new();
    for (k, area) in at {
        match faces.last_mut() {
            Some((c, a)) if (*c / step).round() as i64 == k => *a += area,
            _ => faces.push((k as f32 * step, area)),
        }
    }
    let (top, most) = faces
        .iter()
        .copied()
        .fold((0.0, 0.0), |b, f| if f.1 > b.1 { f } else { b });
    faces
        .iter()
        .filter(|(c, a)| (c - top).abs() <= bin && *a >= 0.3 * most)
        .fold((top, top), |(lo, hi), (c, _)| (lo.min(*c), hi.max(*c)))
}

impl Region {
    /// The region with its cut faces on the axes `across` moved `by` inwards; none when
    /// that leaves it empty.
    fn clear_of_cuts(&self, by: f32, across: [usize; 2]) -> Option<Self> {
        let mut r = self.clone();
        for a in across {
            if r.cut[a][0].is_some() {
                r.lo[a] += by;
            }
            if r.cut[a][1].is_some() {
                r.hi[a] -= by;
            }
            if r.lo[a] >= r.hi[a] {
                return None;
            }
        }
        Some(r)
    }

    /// Whether the bounds `a`..`b` reach into the region.
    fn holds(&self, a: Vec3, b: Vec3) -> bool {
        a.cmple(self.hi).all() && b.cmpge(self.lo).all()
    }
}

/// A [`RASTER`]² grid over a rectangle of a region's cross-section: the plane of axes `u`
/// and `v` across `axis`.
struct Raster {
    origin: Vec2,
    cell: Vec2,
    axis: usize,
    u: usize,
    v: usize,
}

impl Raster {
    /// The grid over `lo`..`hi` (in `u`, `v`); none over an empty rectangle.
    fn over(lo: Vec2, hi: Vec2, (axis, u, v): (usize, usize, usize)) -> Option<Self> {
        let cell = (hi - lo) / RASTER as f32;
        (cell.x > 0.0 && cell.y > 0.0).then_some(Self {
            origin: lo,
            cell,
            axis,
            u,
            v,
        })
    }

    fn cell_area(&self) -> f32 {
        self.cell.x * self.cell.y
    }

    /// Per cell, the nearest and farthest coordinate along the axis of `tris` over it,
    /// within `r`.
    fn depths(&self, tris: &[[Vec3; 3]], r: &Region) -> (Vec<f32>, Vec<f32>) {
        let mut near = vec![f32::INFINITY; RASTER * RASTER];
        let mut far = vec![f32::NEG_INFINITY; RASTER * RASTER];
        for t in tris {
            let (a, b) = bounds(t.iter().copied());
            if !r.holds(a, b) {
                continue;
            }
            let (lo, hi) = (
                a[self.axis].max(r.lo[self.axis]),
                b[self.axis].min(r.hi[self.axis]),
            );
            self.cells(t, |c| {
                near[c] = near[c].min(lo);
                far[c] = far[c].max(hi);
            });
        }
        (near, far)
    }

    /// The bounds (in `u`, `v`) of the cells marked in `cells`, grown by a cell.
    fn bounds_of(&self, cells: &[bool]) -> Option<(Vec2, Vec2)> {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for (k, _) in cells.iter().enumerate().filter(|(_, c)| **c) {
            let q = Vec2::new((k % RASTER) as f32, (k / RASTER) as f32);
            lo = lo.min(self.origin + (q - 1.0) * self.cell);
            hi = hi.max(self.origin + (q + 2.0) * self.cell);
        }
        (lo.x < hi.x).then_some((lo, hi))
    }

    /// Calls `f` with every cell whose centre lies in `t` projected onto the grid.
    fn cells(&self, t: &[Vec3; 3], mut f: impl FnMut(usize)) {
        let p = t.map(|q| (Vec2::new(q[self.u], q[self.v]) - self.origin) / self.cell - 0.5);
        let edge = |a: Vec2, b: Vec2, q: Vec2| (b - a).perp_dot(q - a);
        let twice = edge(p[0], p[1], p[2]);
        if twice == 0.0 {
            return;
        }
        let (a, b) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        let last = RASTER as f32 - 1.0;
        let (x0, y0) = (a.x.ceil().max(0.0), a.y.ceil().max(0.0));
        let (x1, y1) = (b.x.floor().min(last), b.y.floor().min(last));
        if x0 > x1 || y0 > y1 {
            return;
        }
        for y in y0 as usize..=y1 as usize {
            for x in x0 as usize..=x1 as usize {
                let q = Vec2::new(x as f32, y as f32);
                let w = [
                    edge(p[1], p[2], q),
                    edge(p[2], p[0], q),
                    edge(p[0], p[1], q),
                ];
                if w.iter().all(|&e| e * twice >= 0.0) {
                    f(y * RASTER + x);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::office_level;

    #[test]
    fn the_frame_follows_turned_walls_and_ignores_straight_ones() {
        let square = |turn: f32| -> Vec<[Vec3; 3]> {
            // Four walls of a box, turned by `turn` about y.
            let q = Quat::from_rotation_y(turn);
            let mut out = Vec::new();
            for k in 0..4 {
                let side = Quat::from_rotation_y(k as f32 * std::f32::consts::FRAC_PI_2);
                let (a, b, c) = (
                    Vec3::new(1.0, 0.0, -1.0),
                    Vec3::new(1.0, 0.0, 1.0),
                    Vec3::new(1.0, 2.0, 0.0),
                );
                out.push([a, b, c].map(|p| q * (side * p)));
            }
            out
        };
        assert_eq!(wall_frame(&square(0.0)), Quat::IDENTITY);
        assert_eq!(wall_frame(&square(0.3_f32.to_radians())), Quat::IDENTITY);
        let turn = 30f32.to_radians();
        let frame = wall_frame(&square(turn));
        // In the frame, the walls face along its axes.
        for t in square(turn) {
            let local = t.map(|p| frame.inverse() * p);
            let n = (local[1] - local[0]).cross(local[2] - local[0]).normalize();
            assert!(n.abs().max_element() > 0.9999, "{n}");
        }
    }

    #[test]
    fn an_office_floor_is_cut_at_its_walls() {
        // 3 × 1 rooms of 6 m along x: walls at x = 6 and 12.
        let scene = office_level(3, 1);
        let baked: Vec<usize> = (0..scene.instances.len()).collect();
        let tris = triangles(&scene, &baked, Quat::IDENTITY);
        let (lo, hi) = bounds(tris.iter().flatten().copied());
        let all = Region {
            lo,
            hi,
            cut: [[None; 2]; 3],
        };
        // The ground around the building is open: the first cut is a façade, x = −0.125
        // (west, 25 cm thick) or 18.125 (east), or a wall between rooms.
        let (axis, plane, _) = wall_cut(&tris, &all, 0.5).expect("a wall");
        assert_eq!(axis, 0);
        assert!(
            [-0.125, 6.0, 12.0, 18.125]
                .iter()
                .any(|x| (plane - x).abs() < 0.01),
            "{plane}"
        );
        // Inside the building's envelope, the walls between rooms.
        let building = Region {
            lo: Vec3::new(-0.125, lo.y, -0.125),
            hi: Vec3::new(18.125, hi.y, 5.125),
            cut: [[None; 2]; 3],
        };
        let (axis, plane, half) = wall_cut(&tris, &building, 0.5).expect("a wall");
        assert_eq!(axis, 0);
        assert!(
            (plane - 6.0).abs() < 0.01 || (plane - 12.0).abs() < 0.01,
            "{plane}"
        );
        // The walls between rooms are 12 cm thick.
        assert!((half - 0.06).abs() < 0.01, "{half}");
        // A room alone (the building's first up to the cut in its wall, without the ground
        // around it) has no wall across it, and is small enough for one grid.
        let room = Region {
            lo: Vec3::new(-0.25, lo.y, -0.25),
            hi: Vec3::new(6.0, hi.y, 5.25),
            cut: [[None; 2]; 3],
        };
        assert_eq!(wall_cut(&tris, &room, 0.5), None);
        // The strip of ground south of the building, cut from it in the middle of its façade
        // (and at the side façades): nothing across it is a wall.
        // (Without the clearance, the façade's window jambs and the joints of its pieces at
        // x = 6 and 12 m, in its 12.5 cm beyond the cut, covered the strip's cross-section
        // there: a "wall".)
        let strip = Region {
            lo: Vec3::new(-0.125, lo.y, -7.0),
            hi: Vec3::new(18.125, hi.y, -0.125),
            cut: [[Some(0.1); 2], [None; 2], [None, Some(0.1)]],
        };
        assert_eq!(wall_cut(&tris, &strip, 0.75), None);
    }
}
