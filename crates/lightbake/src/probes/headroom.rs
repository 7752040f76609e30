//! How much room the level leaves a moving object: the *headroom* above its walkable floors
//! (the height from a floor up to the next surface over it), so that the volumes' probes are
//! close enough to resolve the spaces dynamic objects walk in. A house's rooms, 2.5 m from
//! floor to ceiling, want probes well under 2.5 m apart, whatever the lightmaps' texel density
//! (16 texels at a preview's 5.5 texels/m are 2.9 m: one probe across a room).
//!
//! Measured on a [`RASTER`]² grid of columns over the level's horizontal extent (in the
//! volumes' frame, whose y axis is the world's vertical). In each column, every non-vertical
//! triangle over the column's centre gives a height; a *walkable* one (facing up within
//! [`WALKABLE_DEGREES`] of the vertical, the usual slope limit of a character controller)
//! is a floor sample, whose headroom is the distance up to the next height in its column, or
//! none (open sky) when there is none. Gaps thinner than the caller's least gap (a rug on a
//! floor, a decal, two faces of one slab) hold no object and are no floor sample. Each column
//! is the same area, so the median over the roofed samples is the area-weighted median
//! headroom, and their share of the samples the share of the floor area that is roofed. A
//! level whose floors are almost all open (less than [`ROOFED_SHARE`] of their area under a
//! surface: floating platforms, open ground with a bus shelter) is not spaced by its headroom.
//!
//! The same floor samples over one region give its [`Floors`]: the main floor, on which its
//! volume's layers of probes are set, and the lowest, below which its box need not reach.

use glam::{Vec2, Vec3, Vec3Swizzles};

/// Columns along the longer horizontal side of the level.
pub const RASTER: usize = 256;

/// Steepest slope of a floor something can stand on, degrees from the horizontal.
pub const WALKABLE_DEGREES: f32 = 45.0;

/// Most (column, height) samples the measurement keeps; a level with more stacked
/// horizontal surfaces is measured on fewer, wider columns (12 bytes a sample: at most
/// 12 MiB while the volumes are planned).
pub const MAX_SAMPLES: usize = 1 << 20;

/// Least share of a level's floor area under a surface for its headroom to set its probes'
/// spacing (`super::grid::AutoSpacing`).
pub const ROOFED_SHARE: f32 = 0.02;

/// Triangles steeper than this (|normal · up| below it) give no height: walls.
const VERTICAL: f32 = 0.05;

/// The headroom of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Headroom {
    /// The area-weighted median of the roofed floors' headroom, m.
    pub median: f32,
    /// Share of the floor area (of gaps at least the least gap high) under a surface.
    pub roofed: f32,
}

/// The headroom over the walkable floors among `tris` (positions in a frame whose y axis is
/// up), ignoring gaps under `least_gap` metres. `None` when no floor is under a surface.
pub fn headroom(tris: &[[Vec3; 3]], least_gap: f32) -> Option<Headroom> {
    let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for t in tris {
        for p in t {
            lo = lo.min(p.xz());
            hi = hi.max(p.xz());
        }
    }
    let mut rooms: Vec<f32> = Vec::new();
    let mut open = 0usize;
    for floor in floor_samples(tris, (lo, hi), least_gap)? {
        match floor.headroom {
            None => open += 1,
            Some(h) => rooms.push(h),
        }
    }
    if rooms.is_empty() {
        return None;
    }
    rooms.sort_unstable_by(f32::total_cmp);
    Some(Headroom {
        median: rooms[rooms.len() / 2],
        roofed: rooms.len() as f32 / (rooms.len() + open) as f32,
    })
}

/// The floors of a region: where its volume's layers of probes are set
/// (`super::grid::VolumeGrid::on_floors`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floors {
    /// Height of the floor under most of the region's rooms, m: the most roofed floor samples
    /// within a least gap of each other (their median); over all the floor samples when
    /// under [`ROOFED_SHARE`] of them are roofed. A flat roof, open to the sky, is as large
    /// as the floor under it; the rooms are what moving objects walk in.
    pub main: f32,
    /// Height of the lowest floor, m (the lowest hundredth of the floor samples left out: a
    /// strip of ground at the region's edge is no floor of it), so that nothing stands lower.
    pub lowest: f32,
}

/// The height most common among `ys` (sorted): the median of the `window`-deep band of
/// heights holding the most of them.
fn commonest(ys: &[f32], window: f32) -> Option<f32> {
    let (mut best, mut end) = ((0, 0), 0);
    for start in 0..ys.len() {
        while end < ys.len() && ys[end] <= ys[start] + window {
            end += 1;
        }
        if end - start > best.1 - best.0 {
            best = (start, end);
        }
    }
    ys.get((best.0 + best.1) / 2).copied()
}

/// The floors among `tris` over the rectangle `(lo, hi)` (x and z; positions in a frame whose
/// y axis is up), ignoring gaps under `least_gap` metres (the ground under a floor slab is no
/// floor). `None` when there is no floor there.
pub fn floors(tris: &[[Vec3; 3]], (lo, hi): (Vec2, Vec2), least_gap: f32) -> Option<Floors> {
    let samples = floor_samples(tris, (lo, hi), least_gap)?;
    let sorted = |roofed_only: bool| {
        let mut ys: Vec<f32> = (samples.iter())
            .filter(|f| !roofed_only || f.headroom.is_some())
            .map(|f| f.y)
            .collect();
        ys.sort_unstable_by(f32::total_cmp);
        ys
    };
    let all = sorted(false);
    let roofed = sorted(true);
    let lowest = *all.get(all.len() / 100)?;
    let main = if roofed.len() as f32 >= ROOFED_SHARE * all.len() as f32 {
        commonest(&roofed, least_gap)?
    } else {
        commonest(&all, least_gap)?
    };
    Some(Floors {
        main,
        lowest: lowest.min(main),
    })
}

/// A floor sample: a walkable surface over a column's centre with at least the least gap
/// over it.
struct FloorSample {
    y: f32,
    /// Up to the next surface over it; `None`: open sky.
    headroom: Option<f32>,
}

/// The floor samples of the columns over `(lo, hi)` (see the module docs); `None` over an
/// empty or non-finite rectangle.
fn floor_samples(
    tris: &[[Vec3; 3]],
    (lo, hi): (Vec2, Vec2),
    least_gap: f32,
) -> Option<Vec<FloorSample>> {
    if !(lo.cmple(hi).all() && lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let side = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let mut columns = RASTER;
    let mut samples = column_samples(tris, (lo, hi), side / columns as f32);
    while samples.is_none() && columns > 8 {
        columns /= 2;
        samples = column_samples(tris, (lo, hi), side / columns as f32);
    }
    let mut samples = samples?;
    samples.sort_unstable_by(|a, b| a.column.cmp(&b.column).then(a.y.total_cmp(&b.y)));
    let mut out = Vec::new();
    for (k, s) in samples.iter().enumerate() {
        if !s.walkable {
            continue;
        }
        // The next height above this one in the column (a coplanar duplicate is not above).
        let above = samples[k + 1..]
            .iter()
            .take_while(|a| a.column == s.column)
            .find(|a| a.y > s.y);
        match above {
            None => out.push(FloorSample {
                y: s.y,
                headroom: None,
            }),
            Some(a) if a.y - s.y >= least_gap => out.push(FloorSample {
                y: s.y,
                headroom: Some(a.y - s.y),
            }),
            Some(_) => {}
        }
    }
    Some(out)
}

/// A surface over a column's centre.
struct Sample {
    column: u32,
    y: f32,
    walkable: bool,
}

/// The non-vertical triangles over the centres of the columns a side of `cell` over the
/// rectangle `(lo, hi)`; `None` when there would be more than [`MAX_SAMPLES`].
fn column_samples(tris: &[[Vec3; 3]], (lo, hi): (Vec2, Vec2), cell: f32) -> Option<Vec<Sample>> {
    let walkable_cos = WALKABLE_DEGREES.to_radians().cos();
    let columns = ((hi - lo) / cell).ceil().max(Vec2::ONE);
    let last = columns - 1.0;
    let mut out = Vec::new();
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let len = n.length();
        if !(len > 0.0 && len.is_finite()) || n.y.abs() < VERTICAL * len {
            continue;
        }
        let walkable = n.y >= walkable_cos * len;
        let p = t.map(|v| (v.xz() - lo) / cell - 0.5);
        let (a, b) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
        let (a, b) = (a.ceil().max(Vec2::ZERO), b.floor().min(last));
        if b.x < a.x || b.y < a.y {
            continue;
        }
        let area = cross(p[1] - p[0], p[2] - p[0]);
        for z in a.y as u32..=b.y as u32 {
            for x in a.x as u32..=b.x as u32 {
                let q = Vec2::new(x as f32, z as f32);
                let (w0, w1) = (
                    cross(p[1] - q, p[2] - q) / area,
                    cross(p[2] - q, p[0] - q) / area,
                );
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                if out.len() >= MAX_SAMPLES {
                    return None;
                }
                out.push(Sample {
                    column: z * columns.x as u32 + x,
                    y: w0 * t[0].y + w1 * t[1].y + w2 * t[2].y,
                    walkable,
                });
            }
        }
    }
    Some(out)
}

fn cross(a: Vec2, b: Vec2) -> f32 {
    a.x * b.y - a.y * b.x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a horizontal rectangle at height `y`, facing up or down.
    fn slab(lo: Vec2, hi: Vec2, y: f32, up: bool) -> Vec<[Vec3; 3]> {
        let c = [
            Vec3::new(lo.x, y, lo.y),
            Vec3::new(hi.x, y, lo.y),
            Vec3::new(hi.x, y, hi.y),
            Vec3::new(lo.x, y, hi.y),
        ];
        let mut tris = vec![[c[0], c[2], c[1]], [c[0], c[3], c[2]]];
        if !up {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }
        tris
    }

    #[test]
    fn a_room_under_a_ceiling_has_its_height_of_headroom() {
        let (lo, hi) = (Vec2::ZERO, Vec2::new(6.0, 5.0));
        let mut tris = slab(lo, hi, 0.0, true);
        tris.extend(slab(lo, hi, 2.5, false));
        // A rug 1 cm thick on part of the floor, and a wall (vertical: no height).
        tris.extend(slab(Vec2::new(1.0, 1.0), Vec2::new(3.0, 2.0), 0.01, true));
        tris.extend(slab(Vec2::new(1.0, 1.0), Vec2::new(3.0, 2.0), 0.0, false));
        tris.push([
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(3.0, 2.5, 0.0),
            Vec3::new(3.0, 0.0, 5.0),
        ]);
        let h = headroom(&tris, 0.05).unwrap();
        assert!((h.median - 2.5).abs() < 0.02, "{h:?}");
        assert_eq!(h.roofed, 1.0);
        // The same room at a kilometre's scale: the measure has no unit of its own.
        let big: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|v| v * 1000.0)).collect();
        let h = headroom(&big, 50.0).unwrap();
        assert!((h.median - 2500.0).abs() < 20.0, "{h:?}");
    }

    #[test]
    fn the_main_floor_is_the_rooms_not_the_roof_over_them() {
        let (lo, hi) = (Vec2::ZERO, Vec2::splat(10.0));
        // A room: its floor at 0, its ceiling at 2.5, a flat roof on top at 2.6 (open, as
        // large as the floor); the ground a millimetre under the floor slab (no floor: the
        // gap holds nothing); a strip of open ground 4 cm wide at the edge, half a metre down.
        let mut tris = slab(lo, hi, 0.0, true);
        tris.extend(slab(lo, hi, 2.5, false));
        tris.extend(slab(lo, hi, 2.6, true));
        tris.extend(slab(lo, hi, -0.3, false));
        tris.extend(slab(lo, hi, -0.301, true));
        tris.extend(slab(
            Vec2::new(10.0, 0.0),
            Vec2::new(10.04, 10.0),
            -0.5,
            true,
        ));
        let f = floors(&tris, (lo, Vec2::new(10.04, 10.0)), 0.05).unwrap();
        assert_eq!(
            f,
            Floors {
                main: 0.0,
                lowest: 0.0
            }
        );
        // Over the strip alone, it is the floor.
        let strip = (Vec2::new(10.0, 0.0), Vec2::new(10.04, 10.0));
        assert_eq!(
            floors(&tris, strip, 0.05),
            Some(Floors {
                main: -0.5,
                lowest: -0.5
            })
        );
        // Open ground alone: its own floor; nothing walkable: none.
        let ground = slab(lo, hi, 1.0, true);
        assert_eq!(
            floors(&ground, (lo, hi), 0.05),
            Some(Floors {
                main: 1.0,
                lowest: 1.0
            })
        );
        assert_eq!(floors(&slab(lo, hi, 1.0, false), (lo, hi), 0.05), None);
    }

    #[test]
    fn a_roof_over_part_of_the_ground_roofs_that_share_of_the_floor() {
        // A 10 × 10 m ground, 20% of it under a flat roof 3 m up (whose top is open floor
        // too): 20 of 120 m² roofed.
        let ground = slab(Vec2::ZERO, Vec2::splat(10.0), 0.0, true);
        let mut tris = ground.clone();
        tris.extend(slab(Vec2::ZERO, Vec2::new(2.0, 10.0), 3.0, true));
        let h = headroom(&tris, 0.05).unwrap();
        assert!((h.median - 3.0).abs() < 1e-4, "{h:?}");
        assert!((h.roofed - 2.0 / 12.0).abs() < 0.03, "{h:?}");
        // Open ground alone.
        assert_eq!(headroom(&ground, 0.05), None);
        // Nothing walkable (a ceiling alone), or nothing at all.
        assert_eq!(
            headroom(&slab(Vec2::ZERO, Vec2::ONE, 1.0, false), 0.05),
            None
        );
        assert_eq!(headroom(&[], 0.05), None);
    }
}
