//! Where an irradiance volume's probes go: a box over the baked instances, cut into cubic
//! cells of one spacing, a probe at each cell's centre (where Bevy's `IrradianceVolume`
//! samples its voxels: the texture is stretched over the unit cube, texel centres at
//! (i + ½)/R). Where the level has floors, one layer of probes is set [`FLOOR_LIFT`] of a
//! spacing over the main one ([`VolumeGrid::on_floors`]).

use glam::{Quat, UVec3, Vec3};
use serde::Serialize;

use super::headroom::{Floors, ROOFED_SHARE, headroom};
use crate::error::{BakeError, Result};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::unwrap::Layout;

/// The spacing of the probes in lightmap texels when neither `probe_spacing` nor the level's
/// headroom ([`AutoSpacing::for_level`]) asks for a finer one (16 texels: 6 cm in a Cornell
/// box at 256 texels/m, 0.5 m in a house at 32).
pub const TEXELS_PER_PROBE: f32 = 16.0;

/// Thinnest gap above a floor that holds a moving object, in lightmap texels (the lightmaps
/// resolve nothing thinner).
pub const LEAST_GAP_TEXELS: f32 = 2.0;

/// Most probes a volume gets when its spacing is chosen automatically; the spacing grows
/// until the grid fits (the plan says so).
pub const MAX_AUTO_PROBES: u64 = 1 << 16;

/// Most probes of any volume (an explicit `probe_spacing` beyond it is refused).
pub const MAX_PROBES: u64 = 1 << 20;

/// Largest side of a 3D texture a GPU must support (WebGPU's and wgpu's default
/// `max_texture_dimension_3d`): the texture is (Rx, 2·Ry, 3·Rz) texels.
pub const MAX_TEXTURE_SIDE: u32 = 2048;

/// Height of a volume's layer of probes over the floor it is set on, in spacings: a moving
/// object's feet take the light of that floor, not of probes half a spacing up or, below
/// them, in the slab (`tests/volume_regions.rs`).
pub const FLOOR_LIFT: f32 = 0.25;

/// The probe grid of one volume.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VolumeGrid {
    /// The volume's box, metres, in its own frame (world axes turned by [`Self::rotation`]):
    /// lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
    /// Probes along x, y and z.
    pub resolution: UVec3,
    /// Edge of a cell (the distance between neighbouring probes), m.
    pub spacing: f32,
    /// How the spacing was chosen, in words (for the plan).
    pub reason: String,
    /// World from the box's frame: the box turned with the level's walls
    /// (`super::regions`). Identity: axis-aligned.
    pub rotation: Quat,
    /// Bevy's `LightProbe::falloff`: per axis of the box, the fraction of its size over
    /// which the volume's weight ramps from 0 at the box's faces to 1 inside, so that
    /// overlapping neighbours blend. Zero: no ramp (a volume alone).
    pub falloff: Vec3,
    /// The part of the box the volume is for, in the box's frame (lower and upper corner,
    /// m): its room, before the box grew past the cuts to overlap its neighbours; the bounds
    /// it was planned over for a volume alone. A probe inside a wall is moved out on this
    /// side of it where it can be (`super::bake`): out past a façade it would carry the sky
    /// into the room.
    pub room: [Vec3; 2],
}

/// The spacing a volume's probes want when `volume.probe_spacing` is not set: the finer of
/// [`TEXELS_PER_PROBE`] lightmap texels and the level's median headroom over
/// `volume.probes_per_headroom`, so that a moving object in a room is lit by probes in that
/// room, not by ones in the walls, floors and ceilings around it. [`VolumeGrid::for_bounds`]
/// widens it when a box would hold over [`MAX_AUTO_PROBES`].
#[derive(Clone, Debug, PartialEq)]
pub struct AutoSpacing {
    /// The spacing, m.
    pub spacing: f32,
    /// Why, in words (for the plan).
    pub reason: String,
}

impl AutoSpacing {
    /// [`TEXELS_PER_PROBE`] texels at `texel_density` (texels per metre).
    pub fn of_texels(texel_density: f32) -> Self {
        Self {
            spacing: TEXELS_PER_PROBE / texel_density,
            reason: format!(
                "{} texels at {} texels/m",
                TEXELS_PER_PROBE,
                crate::plan::density_text(texel_density)
            ),
        }
    }

    /// The spacing for a level of triangles `tris` (in a frame whose y axis is up), baked at
    /// `texel_density`: [`Self::of_texels`], or the headroom over its floors over
    /// `per_headroom` where that is finer and at least [`ROOFED_SHARE`] of their area is
    /// roofed.
    pub fn for_level(tris: &[[Vec3; 3]], texel_density: f32, per_headroom: u32) -> Self {
        let texels = Self::of_texels(texel_density);
        let per = per_headroom.max(1) as f32;
        match headroom(tris, LEAST_GAP_TEXELS / texel_density) {
            Some(h) if h.roofed >= ROOFED_SHARE && h.median / per < texels.spacing => Self {
                spacing: h.median / per,
                reason: format!(
                    "{per} probes over the floors' median headroom of {:.3e} m ({:.0}% of the floor area roofed)",
                    h.median,
                    100.0 * h.roofed
                ),
            },
            _ => texels,
        }
    }
}

impl VolumeGrid {
    /// The grid over the bounds of the instances `layout` gives a lightmap, at
    /// `settings.volume.probe_spacing` or `auto`. `None` when no instance is baked.
    ///
    /// # Errors
    /// [`BakeError::BadSetting`] (`volume.probe_spacing`) when an explicit spacing gives more
    /// than [`MAX_PROBES`] probes or a texture side beyond [`MAX_TEXTURE_SIDE`].
    pub fn plan(
        scene: &Scene,
        layout: &Layout,
        settings: &BakeSettings,
        auto: &AutoSpacing,
        floors: Option<Floors>,
    ) -> Result<Option<Self>> {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for (i, rect) in layout.instances.iter().enumerate() {
            if rect.is_some() {
                let (a, b) = scene.instance_bounds(i);
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        if !(lo.x <= hi.x && lo.is_finite() && hi.is_finite()) {
            return Ok(None);
        }
        Self::for_bounds(lo, hi, settings.volume.probe_spacing, auto, floors).map(Some)
    }

    /// The grid over `[lo, hi]` at `spacing`, or (`None`) at `auto`'s, widened to
    /// [`MAX_AUTO_PROBES`]; with `floors`, a layer of probes [`FLOOR_LIFT`] spacings over the
    /// main floor and the box reaching down to the lowest (see [`Self::on_floors`]).
    ///
    /// # Errors
    /// As [`Self::plan`].
    pub fn for_bounds(
        lo: Vec3,
        hi: Vec3,
        spacing: Option<f32>,
        auto: &AutoSpacing,
        floors: Option<Floors>,
    ) -> Result<Self> {
        let over = |s: f32, reason: String| Self::on_floors(lo, hi, s, floors, reason);
        let mut grid = match spacing {
            Some(s) => {
                let grid = over(s, format!("{s} m (volume.probe_spacing)"));
                if let Some(why) = grid.too_large(MAX_PROBES) {
                    return Err(BakeError::BadSetting {
                        name: "volume.probe_spacing",
                        value: s.to_string(),
                        message: format!(
                            "{why}: choose a larger spacing (the baked region is {:.3} × {:.3} × {:.3} m)",
                            hi.x - lo.x,
                            hi.y - lo.y,
                            hi.z - lo.z
                        ),
                    });
                }
                grid
            }
            None => {
                let wanted = auto.spacing;
                let mut s = wanted;
                let mut grid = over(s, String::new());
                while grid.too_large(MAX_AUTO_PROBES).is_some() {
                    s *= 1.05;
                    grid = over(s, String::new());
                }
                grid.reason = if s == wanted {
                    auto.reason.clone()
                } else {
                    format!(
                        "widened from {} ({wanted:.3e} m) to keep the volume within {MAX_AUTO_PROBES} probes (set volume.probe_spacing, --probe-spacing, to choose)",
                        auto.reason
                    )
                };
                grid
            }
        };
        if let Some(f) = floors.filter(|f| (lo.y..=hi.y).contains(&f.main)) {
            grid.reason = format!(
                "{}; a layer {:.3e} m over the floor at y = {:.3e} m",
                grid.reason,
                FLOOR_LIFT * grid.spacing,
                f.main
            );
        }
        Ok(grid)
    }

    /// The grid of cubic cells of edge `spacing` over `[lo, hi]`: at least two probes per
    /// axis (so a flat region gets probes on both sides of it, not on it), the box grown
    /// about its centre to a whole number of cells.
    pub fn over(lo: Vec3, hi: Vec3, spacing: f32, reason: String) -> Self {
        let extent = hi - lo;
        let cells = |e: f32| ((e / spacing).ceil() as u32).max(2);
        let resolution = UVec3::new(cells(extent.x), cells(extent.y), cells(extent.z));
        let centre = 0.5 * (lo + hi);
        let half = 0.5 * spacing * resolution.as_vec3();
        Self {
            min: centre - half,
            max: centre + half,
            resolution,
            spacing,
            reason,
            rotation: Quat::IDENTITY,
            falloff: Vec3::ZERO,
            room: [lo, hi],
        }
    }

    /// [`Self::over`] with its layers set on `floors` (when the main floor lies in
    /// `[lo, hi]`): one layer [`FLOOR_LIFT`] spacings over the main floor, the box reaching
    /// down to the lowest floor (or `lo`, if that is higher) and up to `hi`. Without it the
    /// layers fall wherever the box's rounding puts them: at 0.75 m in an office, on the
    /// floor itself and at desk height.
    pub fn on_floors(
        lo: Vec3,
        hi: Vec3,
        spacing: f32,
        floors: Option<Floors>,
        reason: String,
    ) -> Self {
        let mut grid = Self::over(lo, hi, spacing, reason);
        let Some(f) = floors.filter(|f| (lo.y..=hi.y).contains(&f.main)) else {
            return grid;
        };
        let face = f.main + (FLOOR_LIFT - 0.5) * spacing;
        let bottom = f.lowest.clamp(lo.y, f.main);
        let min = face - ((face - bottom) / spacing).ceil().max(0.0) * spacing;
        let cells = (((hi.y - min) / spacing).ceil() as u32).max(2);
        grid.min.y = min;
        grid.max.y = min + cells as f32 * spacing;
        grid.resolution.y = cells;
        grid
    }

    /// Why the grid cannot be a texture of at most `max_probes` probes, if it cannot.
    pub(super) fn too_large(&self, max_probes: u64) -> Option<String> {
        let r = self.resolution;
        let n = self.len() as u64;
        if n > max_probes {
            return Some(format!(
                "{} × {} × {} = {n} probes, more than {max_probes}",
                r.x, r.y, r.z
            ));
        }
        let side = (r.x as u64).max(2 * r.y as u64).max(3 * r.z as u64);
        (side > MAX_TEXTURE_SIDE as u64).then(|| {
            format!(
                "a {} × {} × {} texture (Bevy's layout: x, 2·y, 3·z), beyond the {MAX_TEXTURE_SIDE} a GPU must support",
                r.x,
                2 * r.y as u64,
                3 * r.z as u64
            )
        })
    }

    /// Number of probes.
    pub fn len(&self) -> usize {
        let r = self.resolution.as_u64vec3();
        (r.x * r.y * r.z) as usize
    }

    /// Whether the grid has no probe (never, for a planned grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of probe (x, y, z): x fastest.
    pub fn index(&self, x: u32, y: u32, z: u32) -> usize {
        (x + self.resolution.x * (y + self.resolution.y * z)) as usize
    }

    /// (x, y, z) of probe `i`.
    pub fn coords(&self, i: usize) -> UVec3 {
        let i = i as u32;
        let r = self.resolution;
        UVec3::new(i % r.x, (i / r.x) % r.y, i / (r.x * r.y))
    }

    /// World position of probe `i`: its cell's centre.
    pub fn position(&self, i: usize) -> Vec3 {
        self.rotation * (self.min + (self.coords(i).as_vec3() + 0.5) * self.spacing)
    }

    /// The box's centre (world) and size (along its own axes), m: Bevy's light probe is the
    /// unit cube under `Transform::from_translation(centre).with_rotation(rotation)
    /// .with_scale(size)`.
    pub fn centre_and_size(&self) -> (Vec3, Vec3) {
        (
            self.rotation * (0.5 * (self.min + self.max)),
            self.max - self.min,
        )
    }

    /// `world` in the box's unit cube (−½..½ inside), as Bevy's shader finds it.
    pub fn unit_position(&self, world: Vec3) -> Vec3 {
        let (centre, size) = self.centre_and_size();
        self.rotation.inverse() * (world - centre) / size
    }

    /// Whether `world` lies in the volume's [`Self::room`].
    pub fn in_room(&self, world: Vec3) -> bool {
        let p = self.rotation.inverse() * world;
        (p.cmpge(self.room[0]) & p.cmple(self.room[1])).all()
    }

    /// The weight Bevy gives this volume at `world` (`light_probe.wesl`): per axis, a ramp
    /// from 0 at the box's face to 1 at [`Self::falloff`] of its size inside; the least of
    /// the three. 0 outside the box.
    pub fn weight(&self, world: Vec3) -> f32 {
        let p = self.unit_position(world);
        let f = self.falloff.max(Vec3::splat(1e-4));
        let w = ((Vec3::ONE - 2.0 * p.abs()) / (2.0 * f)).clamp(Vec3::ZERO, Vec3::ONE);
        w.min_element()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_layer_is_set_on_the_floor() {
        // A room 3.3 m high over a 0.3 m slab, probes 0.75 m apart: a layer 0.1875 m over its
        // floor (centred on its bounds, the layers fall at 0.0 and 0.75: on the floor and at
        // desk height).
        let (lo, hi) = (Vec3::new(0.0, -0.3, 0.0), Vec3::new(6.0, 3.3, 5.0));
        let floors = Floors {
            main: 0.0,
            lowest: 0.0,
        };
        let centred = VolumeGrid::over(lo, hi, 0.75, String::new());
        assert!((centred.position(0).y - 0.0).abs() < 1e-5);
        let g = VolumeGrid::on_floors(lo, hi, 0.75, Some(floors), String::new());
        assert!((g.position(0).y - 0.1875).abs() < 1e-5, "{g:?}");
        // The box reaches from a quarter spacing under the floor to over the top.
        assert!((g.min.y + 0.1875).abs() < 1e-5 && g.max.y >= hi.y, "{g:?}");
        assert_eq!((g.min.x, g.max.x), (centred.min.x, centred.max.x));
        // A lower floor (a sunken part of the room) pulls the box down with it, on the same
        // layers.
        let sunken = Floors {
            main: 0.0,
            lowest: -0.3,
        };
        let g = VolumeGrid::on_floors(lo, hi, 0.75, Some(sunken), String::new());
        assert!(g.min.y <= -0.3 && g.min.y > -0.3 - 0.75, "{g:?}");
        assert!(
            (g.position(g.index(0, 1, 0)).y - 0.1875).abs() < 1e-5,
            "{g:?}"
        );
        // A floor outside the bounds sets nothing.
        let above = Floors {
            main: 5.0,
            lowest: 5.0,
        };
        assert_eq!(
            VolumeGrid::on_floors(lo, hi, 0.75, Some(above), String::new()),
            centred
        );
    }

    #[test]
    fn probes_sit_at_cell_centres_inside_the_box() {
        let g = VolumeGrid::over(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.45), 0.1, String::new());
        assert_eq!(g.resolution, UVec3::new(10, 2, 5));
        assert!((g.min.y + 0.1).abs() < 1e-6 && (g.max.y - 0.1).abs() < 1e-6);
        assert!((g.min.z + 0.025).abs() < 1e-6);
        for i in 0..g.len() {
            let c = g.coords(i);
            assert_eq!(g.index(c.x, c.y, c.z), i);
            let p = g.position(i);
            assert!(p.cmpgt(g.min).all() && p.cmplt(g.max).all());
        }
        // The flat axis gets a probe on each side of the plane, none on it.
        assert!((g.position(0).y + 0.05).abs() < 1e-6);
        assert!((g.position(g.index(0, 1, 0)).y - 0.05).abs() < 1e-6);
        assert!(g.too_large(MAX_PROBES).is_none());
        assert!(g.too_large(10).unwrap().contains("100 probes"));
        let long = VolumeGrid::over(Vec3::ZERO, Vec3::new(0.1, 0.1, 1000.0), 1.0, String::new());
        assert!(long.too_large(MAX_PROBES).unwrap().contains("texture"));
    }

    #[test]
    fn the_spacing_resolves_the_rooms_headroom() {
        // A 6 × 5 m floor under a ceiling 2.5 m up: at 4 texels/m, 16 texels are 4 m; four
        // probes over the headroom ask for 2.5 / 4 m.
        let quad = |y: f32, up: bool| {
            let c =
                [(0.0, 0.0), (6.0, 0.0), (6.0, 5.0), (0.0, 5.0)].map(|(x, z)| Vec3::new(x, y, z));
            let (a, b) = if up { (2, 1) } else { (1, 2) };
            [[c[0], c[a], c[b]], [c[0], c[a + 1], c[b + 1]]]
        };
        let mut room: Vec<[Vec3; 3]> = quad(0.0, true).to_vec();
        room.extend(quad(2.5, false));
        let a = AutoSpacing::for_level(&room, 4.0, 4);
        assert!((a.spacing - 0.625).abs() < 1e-3, "{a:?}");
        assert!(a.reason.contains("headroom"), "{}", a.reason);
        // At 256 texels/m the texels' 6 cm are finer: kept.
        assert_eq!(
            AutoSpacing::for_level(&room, 256.0, 4),
            AutoSpacing::of_texels(256.0)
        );
        // The floor alone is open: the texels' spacing.
        assert_eq!(
            AutoSpacing::for_level(&quad(0.0, true), 4.0, 4),
            AutoSpacing::of_texels(4.0)
        );
    }

    #[test]
    fn the_spacing_follows_the_density_and_widens_to_the_budget() {
        let (lo, hi) = (Vec3::ZERO, Vec3::new(8.0, 3.0, 6.0));
        // 32 texels/m: 16 texels = 0.5 m, 16 × 6 × 12 probes.
        let g = VolumeGrid::for_bounds(lo, hi, None, &AutoSpacing::of_texels(32.0), None).unwrap();
        assert_eq!(g.spacing, 0.5);
        assert_eq!(g.resolution, UVec3::new(16, 6, 12));
        assert!(g.reason.starts_with("16 texels"), "{}", g.reason);
        // 400 texels/m would be 200 × 75 × 150 probes: widened to the budget.
        let fine = AutoSpacing::of_texels(400.0);
        let g = VolumeGrid::for_bounds(lo, hi, None, &fine, None).unwrap();
        assert!(g.len() as u64 <= MAX_AUTO_PROBES && g.len() as u64 > MAX_AUTO_PROBES / 2);
        assert!(g.reason.contains("widened"), "{}", g.reason);
        // An explicit spacing is kept, or refused by name.
        let g = VolumeGrid::for_bounds(lo, hi, Some(0.25), &fine, None).unwrap();
        assert_eq!(g.resolution, UVec3::new(32, 12, 24));
        let e = VolumeGrid::for_bounds(lo, hi, Some(0.01), &fine, None).unwrap_err();
        assert!(e.to_string().contains("probe_spacing"), "{e}");
    }
}
