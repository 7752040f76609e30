//! The points of a texel's footprint that the lighting passes sample (direct light, texel
//! albedo): stratified by an Owen-scrambled (0,2)-sequence over the texel square, each mapped
//! onto the surface, and kept only where that surface is open (not hidden under geometry from
//! the texel's representative point); and what makes a point of a footprint open surface
//! ([`Patches::sees`], [`Patches::open_point`], [`gap_probe`]).

use glam::Vec2;

use super::{Patch, Patches, Surface, SurfaceFrame, SurfacePoint};
use crate::bvh::RayScene;
use crate::sampling::{hash, sobol_02, unit_float};
use crate::unwrap::Layout;

/// Random-number streams of a texel's footprint points (mixed into its key).
mod stream {
    pub const FOOTPRINT: u32 = 1;
    pub const FOOTPRINT_RETRY: u32 = 2;
}

/// The points of one patch's texel footprint: point `s` is a point of the texel square on one
/// of its triangles that is open surface of the patch ([`Patches::sees`]); when the square
/// point misses the triangles (a partly covered texel) or is hidden (under geometry, behind
/// a wall, in a gap the representative point is not in), other points are drawn, and after
/// four misses the representative point stands in. So the passes that sample footprints
/// integrate over the visible part of the texel only.
pub struct Footprint<'a> {
    layout: &'a Layout,
    patches: &'a Patches,
    surface: &'a Surface<'a>,
    rays: &'a RayScene,
    p: &'a Patch,
    seed: u32,
    /// The scramble of the first-attempt points (`p`'s footprint stream).
    first_key: u32,
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
            first_key: p.rng(seed, stream::FOOTPRINT),
            frame,
        }
    }

    #[cfg(any(test, feature = "internals"))]
    /// Whether the points come from the affine map of the texel square (see the field docs).
    pub fn is_affine(&self) -> bool {
        self.frame.is_some()
    }

    /// Point `s` (see the type docs); shadow rays traced to check it are added to `rays`.
    #[inline]
    pub fn point(&self, s: u32, rays: &mut u64) -> SurfacePoint {
        match &self.frame {
            Some(frame) => frame.point(self.first(s) - Vec2::splat(0.5)),
            None => self.searched_point(s, rays),
        }
    }

    /// The first-attempt offset of point `s` in the texel square, in [0, 1)².
    #[inline]
    fn first(&self, s: u32) -> Vec2 {
        sobol_02(s, self.first_key)
    }

    /// Point `s` found by the general search of the footprint triangles, which
    /// [`Self::point`] skips when the texel has an affine map (the same point up to rounding).
    pub fn searched_point(&self, s: u32, rays: &mut u64) -> SurfacePoint {
        let p = self.p;
        let rep = p.representative();
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
                    continue;
                }
            }
            return sp;
        }
        rep
    }
}

/// What lies within `reach` along a surface point's normal (see [`gap_probe`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gap {
    /// Nothing.
    Open,
    /// The front of a surface (or a double-sided one): the point is in a thin gap.
    Covered,
    /// The back of a single-sided surface: the point faces the inside of a solid.
    Back,
}

/// What lies within `reach` above surface point `sp`, along its geometric normal.
pub fn gap_probe(rays: &RayScene, sp: &SurfacePoint, reach: f32) -> Gap {
    let from = rays.offset(sp.position, sp.geometric_normal);
    match rays.closest_hit(from, sp.geometric_normal, 0.0, reach) {
        None => Gap::Open,
        Some(h) if h.front_face || rays.triangles[h.triangle as usize].double_sided => Gap::Covered,
        Some(_) => Gap::Back,
    }
}

impl Patches {
    /// Whether a point of patch `p`'s footprint is open surface (always, for patches not near
    /// geometry): it is not hidden from the representative point by geometry (a floor texel
    /// half under a wall), it does not face the back of a single-sided surface within a texel
    /// (a ceiling texel sandwiched above a lamp hung just below it), and it lies in a gap
    /// thinner than a texel exactly when the representative point does ([`Patch::COVERED`]:
    /// the floor under a rug is not the floor beside it).
    pub fn sees(&self, p: &Patch, sp: &SurfacePoint, rays: &RayScene) -> bool {
        if p.flags & Patch::NEAR_GEOMETRY == 0 {
            return true;
        }
        let probe = gap_probe(rays, sp, p.texel_size);
        self.sees_probed(p, sp, probe, rays)
    }

    /// [`Self::sees`] with the point's [`gap_probe`] already traced.
    pub fn sees_probed(&self, p: &Patch, sp: &SurfacePoint, probe: Gap, rays: &RayScene) -> bool {
        if p.flags & Patch::NEAR_GEOMETRY == 0 {
            return true;
        }
        Self::gap_agrees(p, probe) && !Self::hidden_from(p, sp, rays)
    }

    /// Whether a point's [`gap_probe`] finds what `p`'s representative point finds: no back
    /// face, and a gap thinner than a texel exactly when `p` lies in one.
    pub(super) fn gap_agrees(p: &Patch, probe: Gap) -> bool {
        match probe {
            Gap::Back => false,
            Gap::Covered => p.flags & Patch::COVERED != 0,
            Gap::Open => p.flags & Patch::COVERED == 0,
        }
    }

    /// Whether geometry stands between `p`'s representative point and `sp` (one shadow ray).
    pub(super) fn hidden_from(p: &Patch, sp: &SurfacePoint, rays: &RayScene) -> bool {
        let a = rays.offset(p.position, p.geometric_normal);
        let b = rays.offset(sp.position, sp.geometric_normal);
        let d = b - a;
        let len = d.length();
        len > 0.0 && rays.occluded(a, d / len, 0.0, len)
    }

    /// Whether a point `sp` in the footprint of texel `texel` is open surface, for the node
    /// `anchor` whose support it is sampled for: for a valid texel, [`Patches::sees`]; for an
    /// invalid one (its own point is inside geometry) the point must see `anchor`'s point and
    /// face no back of a single-sided surface within a texel (the visible rim of a ceiling
    /// texel whose centre lies above a lamp, but not a floor under a block).
    pub fn open_point(
        &self,
        texel: &Patch,
        sp: &SurfacePoint,
        anchor: &Patch,
        rays: &RayScene,
    ) -> bool {
        if texel.is_valid() {
            return self.sees(texel, sp, rays);
        }
        let a = rays.offset(anchor.position, anchor.geometric_normal);
        let b = rays.offset(sp.position, sp.geometric_normal);
        let d = b - a;
        let len = d.length();
        if len > 0.0 && rays.occluded(a, d / len, 0.0, len) {
            return false;
        }
        rays.closest_hit(b, sp.geometric_normal, 0.0, texel.texel_size)
            .is_none()
    }
}
