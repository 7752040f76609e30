//! The irradiance volume: every probe's six sides (gathered by the volume stage,
//! `probes::bake`), and the 3D texture Bevy's `IrradianceVolume` reads.
//!
//! **Inside geometry** (what the volume stage does). A probe whose rays meet the back of single-sided surfaces more than
//! [`INSIDE_FRACTION`] of the time is inside a solid (a pillar, a thick wall) or under a
//! floor: its light is not the light a dynamic object there would get, and with trilinear
//! filtering a black voxel darkens every point within a cell of it. Its gather stops as soon
//! as its back hits pass that fraction of its rays (the verdict is then certain). Such a
//! probe is moved past the nearest back faces it saw (the way out of the solid), at most one
//! cell away, and gathered there: first to places in the volume's room (`VolumeGrid::room`),
//! then past each back face on the way to the room's centre, then elsewhere (a probe in a
//! façade moved past its outer face would carry the sky into the room); a probe with no such
//! way out, or one enclosed in a sliver
//! between surfaces ([`ENCLOSED_FRACTION`]), is *filled*: the mean of its open neighbours,
//! repeated outwards, as the lightmap's dilation fills hidden texels.
//!
//! **Texture layout**, as Bevy 0.20's shader reads it (`irradiance_volume.wesl`): a volume of
//! resolution (Rx, Ry, Rz) is a 3D texture of (Rx, 2Ry, 3Rz) texels; side S of voxel
//! (x, y, z) is at s = x, t = y (+ Ry for −X, −Y, −Z: the shader adds half the height for a
//! negative normal component), p = z (+ Rz for ±Y, + 2Rz for ±Z). The module docs of
//! `bevy_pbr::irradiance_volume` put the offset on the positive sides instead; their diagram
//! and the shader put the positive sides in the first half, and the shader is what renders.

use glam::{UVec3, Vec3};
use serde::Serialize;

use super::grid::VolumeGrid;

/// A probe whose rays meet back faces more often than this is inside geometry.
pub const INSIDE_FRACTION: f32 = 0.25;

/// A probe more than this share of whose rays hit a surface (either side) within
/// [`ENCLOSED_REACH`] is *enclosed*: in a sliver between surfaces (a floor slab laid a
/// millimetre over the ground), open by the back-face test but no place a moving object can
/// be, and as dark as the sliver. It is filled from its neighbours like a probe inside a solid.
/// A probe on a floor has half its rays within reach, one in a floor's corner with a wall
/// three quarters.
pub const ENCLOSED_FRACTION: f32 = 0.75;

/// The reach of [`ENCLOSED_FRACTION`], as a share of the probes' spacing.
pub const ENCLOSED_REACH: f32 = 0.1;

/// Bytes the volume stage holds per probe at its peak: the gathered probe (its sides, their
/// errors, where it moved, 128), the voxels and states kept (72 + 16) and the texture laid
/// out for writing (72).
pub const BYTES_PER_PROBE: u64 = 288;

/// A baked irradiance volume.
#[derive(Clone, Debug, PartialEq)]
pub struct IrradianceVolume {
    /// Where the probes are.
    pub grid: VolumeGrid,
    /// Per probe ([`VolumeGrid::index`]), the irradiance over π from each side in the order
    /// −X, +X, −Y, +Y, −Z, +Z (`gather::SIDES`), linear RGB: what a white Lambertian surface
    /// facing that way would show, in the lightmap's units.
    pub voxels: Vec<[Vec3; 6]>,
    /// Per probe, what became of it.
    pub states: Vec<ProbeState>,
}

/// What became of one probe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProbeState {
    /// Gathered at its cell's centre.
    Open,
    /// Inside geometry at its centre; gathered at this open point instead (world, m).
    Moved(Vec3),
    /// Inside geometry with no open point within a cell: its neighbours' mean.
    Filled,
    /// Inside geometry, and no probe of the volume is open: black.
    Black,
}

/// What the volume stage did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct VolumeStats {
    /// Probes in the grid.
    pub probes: usize,
    /// Probes along x, y, z.
    pub resolution: [u32; 3],
    /// Distance between probes, m.
    pub spacing: f32,
    /// Why that spacing.
    pub spacing_reason: String,
    /// Rays per probe (emitter samples not counted).
    pub rays_per_probe: u32,
    /// Probes found inside geometry and moved to an open point within a cell.
    pub moved: usize,
    /// Probes inside geometry with no open point within a cell, filled from their neighbours.
    pub filled: usize,
    /// Probes left black: inside geometry with no open probe anywhere in the volume.
    pub unfilled: usize,
    /// The gathers' noise: RMS over the open probes' sides of the standard error of the
    /// luminance, over the RMS luminance of the sides.
    pub relative_standard_error: f64,
    /// Rays traced (gather, emitter and shadow rays).
    pub rays: u64,
}

impl IrradianceVolume {
    /// The texture Bevy's `IrradianceVolume` reads (see the module docs): its size
    /// (Rx, 2Ry, 3Rz) and its texels, s fastest, then t, then p.
    pub fn texture(&self) -> (UVec3, Vec<Vec3>) {
        let r = self.grid.resolution;
        let size = UVec3::new(r.x, 2 * r.y, 3 * r.z);
        let mut texels = vec![Vec3::ZERO; (size.x * size.y * size.z) as usize];
        for (i, sides) in self.voxels.iter().enumerate() {
            let c = self.grid.coords(i);
            for (k, v) in sides.iter().enumerate() {
                let (axis, positive) = (k as u32 / 2, k % 2 == 1);
                let t = c.y + if positive { 0 } else { r.y };
                let p = c.z + axis * r.z;
                texels[(c.x + size.x * (t + size.y * p)) as usize] = *v;
            }
        }
        (size, texels)
    }

    /// What Bevy's shader gives a surface at `position` with unit normal `normal` from this
    /// volume (`irradiance_volume.wesl`): each axis' side facing the normal, trilinearly
    /// filtered between probe centres (clamped at the outer ones), weighted by the squared
    /// normal's components. E/π, linear RGB.
    pub fn sample(&self, position: Vec3, normal: Vec3) -> Vec3 {
        let r = self.grid.resolution.as_vec3();
        let unit = self.grid.unit_position(position);
        let stp = ((unit + 0.5) * r).clamp(Vec3::splat(0.5), r - 0.5) - 0.5;
        let base = stp.floor().as_uvec3();
        let f = stp - stp.floor();
        let mut out = Vec3::ZERO;
        for axis in 0..3 {
            let n = normal[axis];
            let side = 2 * axis + usize::from(n >= 0.0);
            let mut v = Vec3::ZERO;
            for corner in 0..8u32 {
                let o = UVec3::new(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
                let q = (base + o).min(self.grid.resolution - 1);
                let w = (0..3).fold(1.0, |w, a| w * if o[a] == 1 { f[a] } else { 1.0 - f[a] });
                v += self.voxels[self.grid.index(q.x, q.y, q.z)][side] * w;
            }
            out += v * n * n;
        }
        out
    }
}

/// What Bevy's shader gives a surface at `position` with unit normal `normal` from several
/// volumes (`irradiance_volume.wesl`): each containing volume's [`IrradianceVolume::sample`]
/// weighted by its [`VolumeGrid::weight`] there, over the sum of the weights; black where no
/// volume holds the point. The sides stay world-axis in a turned volume: Bevy reads them
/// with the world normal.
pub fn blend(volumes: &[IrradianceVolume], position: Vec3, normal: Vec3) -> Vec3 {
    let (mut sum, mut weights) = (Vec3::ZERO, 0.0);
    for v in volumes {
        let w = v.grid.weight(position);
        if w > 0.0 {
            sum += v.sample(position, normal) * w;
            weights += w;
        }
    }
    if weights > 0.0 {
        sum / weights
    } else {
        Vec3::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume() -> IrradianceVolume {
        let grid = VolumeGrid::over(Vec3::ZERO, Vec3::new(2.0, 1.0, 3.0), 1.0, String::new());
        let voxels = (0..grid.len())
            .map(|i| {
                let c = grid.coords(i).as_vec3();
                std::array::from_fn(|s| Vec3::new(c.x + 10.0 * s as f32, c.y, c.z))
            })
            .collect();
        let states = vec![ProbeState::Open; grid.len()];
        IrradianceVolume {
            grid,
            voxels,
            states,
        }
    }

    #[test]
    fn texture_layout_is_bevys() {
        let v = volume();
        let r = v.grid.resolution;
        assert_eq!(r, UVec3::new(2, 2, 3));
        let (size, texels) = v.texture();
        assert_eq!(size, UVec3::new(2, 4, 9));
        let at = |s: u32, t: u32, p: u32| texels[(s + size.x * (t + size.y * p)) as usize];
        // Voxel (1, 0, 2): +X at (1, 0, 2), −X at (1, 2, 2), −Y at (1, 2, 5), +Z at (1, 0, 8).
        let i = v.grid.index(1, 0, 2);
        assert_eq!(at(1, 2, 2), v.voxels[i][0]);
        assert_eq!(at(1, 0, 2), v.voxels[i][1]);
        assert_eq!(at(1, 2, 5), v.voxels[i][2]);
        assert_eq!(at(1, 0, 8), v.voxels[i][5]);
    }

    /// Bevy 0.20's `irradiance_volume_light` on the texture, step by step: the unit cube's
    /// point scaled to voxels and clamped, the half for a negative normal component added to
    /// v, the third of each axis added to w, each read with trilinear filtering (texel
    /// centres at (i + ½)/size), weighted by N².
    fn shader(size: UVec3, texels: &[Vec3], unit_pos: Vec3, n: Vec3) -> Vec3 {
        let atlas = size.as_vec3();
        let resolution = atlas / Vec3::new(1.0, 2.0, 3.0);
        let stp = ((unit_pos + 0.5) * resolution).clamp(Vec3::splat(0.5), resolution - 0.5);
        let uvw = stp / atlas;
        let neg = Vec3::select(n.cmplt(Vec3::ZERO), Vec3::splat(0.5), Vec3::ZERO);
        let fetch = |uvw: Vec3| {
            let c = uvw * atlas - 0.5;
            let base = c.floor();
            let f = c - base;
            let mut v = Vec3::ZERO;
            for k in 0..8u32 {
                let o = UVec3::new(k & 1, (k >> 1) & 1, (k >> 2) & 1);
                let q = (base.as_ivec3() + o.as_ivec3())
                    .clamp(glam::IVec3::ZERO, size.as_ivec3() - 1)
                    .as_uvec3();
                let w = (0..3).fold(1.0, |w, a| w * if o[a] == 1 { f[a] } else { 1.0 - f[a] });
                v += texels[(q.x + size.x * (q.y + size.y * q.z)) as usize] * w;
            }
            v
        };
        let x = fetch(uvw + Vec3::new(0.0, neg.x, 0.0));
        let y = fetch(uvw + Vec3::new(0.0, neg.y, 1.0 / 3.0));
        let z = fetch(uvw + Vec3::new(0.0, neg.z, 2.0 / 3.0));
        let nn = n * n;
        x * nn.x + y * nn.y + z * nn.z
    }

    #[test]
    fn the_texture_gives_bevys_shader_what_sample_gives() {
        let v = volume();
        let (size, texels) = v.texture();
        let (centre, extent) = v.grid.centre_and_size();
        for (p, n) in [
            (Vec3::new(0.7, 0.2, 1.1), Vec3::Y),
            (Vec3::new(1.3, 0.8, 2.6), Vec3::NEG_Y),
            (Vec3::new(0.2, 0.5, 0.4), Vec3::new(0.6, -0.8, 0.0)),
            (Vec3::new(1.9, 0.1, 1.7), Vec3::new(-0.48, 0.6, -0.64)),
        ] {
            let want = v.sample(p, n);
            let got = shader(size, &texels, (p - centre) / extent, n);
            assert!(
                (want - got).length() < 1e-3 * want.length().max(1.0),
                "{p} {n}: {want} against {got}"
            );
        }
    }

    #[test]
    fn sampling_at_a_probe_returns_its_side_and_blends_between() {
        let v = volume();
        let i = v.grid.index(1, 1, 1);
        let p = v.grid.position(i);
        assert_eq!(v.sample(p, Vec3::X), v.voxels[i][1]);
        assert_eq!(v.sample(p, Vec3::NEG_Z), v.voxels[i][4]);
        let n = Vec3::new(0.6, 0.0, 0.8);
        let expected = v.voxels[i][1] * 0.36 + v.voxels[i][5] * 0.64;
        assert!((v.sample(p, n) - expected).length() < 1e-4);
        // Halfway between two probes along x: the mean; beyond the outer ones: clamped.
        let j = v.grid.index(0, 1, 1);
        let mid = 0.5 * (p + v.grid.position(j));
        assert!((v.sample(mid, Vec3::Y) - 0.5 * (v.voxels[i][3] + v.voxels[j][3])).length() < 1e-4);
        assert_eq!(v.sample(p + Vec3::X * 5.0, Vec3::Y), v.voxels[i][3]);
    }
}
