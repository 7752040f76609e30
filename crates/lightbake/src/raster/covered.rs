//! Texels in a gap thinner than a texel: the floor under a rug, the underside of a block
//! resting on another. A texel whose representative point has a surface over it within a
//! texel along its normal ([`Gap::Covered`]) is lit only from the points of its footprint in
//! the same gap ([`Patches::sees`]), which no view can see. Where part of its footprint is
//! out in the open (a floor texel whose centre lies under a rug's edge, the underside of a
//! brick whose centre rests on a half-block beside a groove), that part is what a viewer
//! sees. The texel's point moves to the most central point of its footprint that has nothing
//! over it within a texel and is open surface by the test of [`super::validity`] (not inside
//! a solid: a point of a roof's underside resting on a thick wall has nothing over it within
//! a texel either), and it is lit from the open part, like a texel whose centre is hidden
//! inside a solid. Only a texel with no such point among [`COVERED_POINTS`] keeps its point
//! and is marked [`Patch::COVERED`].

use rayon::prelude::*;

use super::footprint::{Gap, gap_probe};
use super::validity::{VALIDITY_SEED, open_surface};
use super::{Patch, Patches, Surface, SurfacePoint};
use crate::bvh::RayScene;
use crate::sampling::hash_words;
use crate::unwrap::Layout;

/// Footprint points searched for open surface in a covered texel (from the centre
/// outwards): an open part of about a sixteenth of the texel or more is found. Most covered
/// texels are covered all over (a ground plane a millimetre under a floor slab), and each
/// costs this many rays.
pub const COVERED_POINTS: u32 = 16;

/// Stream of the search's points (mixed into a patch's key with [`VALIDITY_SEED`]).
const STREAM: u32 = 0xc0_7e4d;

impl Patches {
    /// Marks the valid patches near geometry whose point lies in a gap thinner than a texel
    /// [`Patch::COVERED`], or moves them to open surface in their footprint (see the module
    /// docs; counted in `moved` and `rescued`). Returns the rays traced.
    pub(super) fn settle_covered(
        &mut self,
        layout: &Layout,
        surface: &Surface<'_>,
        rays: &RayScene,
    ) -> u64 {
        let found: Vec<(Gap, Option<SurfacePoint>, u64)> = self
            .patches
            .par_iter()
            .map(|p| {
                if !p.is_valid() || p.flags & Patch::NEAR_GEOMETRY == 0 {
                    return (Gap::Open, None, 0);
                }
                let gap = gap_probe(rays, &p.representative(), p.texel_size);
                if gap != Gap::Covered {
                    return (gap, None, 1);
                }
                let key = p.rng(VALIDITY_SEED, STREAM);
                let points = self.footprint_points(p, (layout, surface), key, 0..COVERED_POINTS);
                let mut used = 1;
                for (s, sp) in points {
                    used += 1;
                    let fan = hash_words(&[key, s]);
                    if gap_probe(rays, &sp, p.texel_size) == Gap::Open
                        && open_surface((sp.position, sp.geometric_normal), fan, rays, &mut used)
                    {
                        return (gap, Some(sp), used);
                    }
                }
                (gap, None, used)
            })
            .collect();
        let mut traced = 0;
        for (p, (gap, open, used)) in self.patches.iter_mut().zip(found) {
            traced += used;
            match open {
                Some(sp) => {
                    if p.flags & Patch::MOVED == 0 {
                        self.moved += 1;
                    }
                    if p.flags & Patch::PARTLY_HIDDEN == 0 {
                        self.rescued += 1;
                    }
                    p.flags |= Patch::MOVED | Patch::PARTLY_HIDDEN;
                    p.position = sp.position;
                    p.normal = sp.normal;
                    p.geometric_normal = sp.geometric_normal;
                    p.triangle = sp.triangle;
                }
                None if gap == Gap::Covered => p.flags |= Patch::COVERED,
                None => {}
            }
        }
        traced
    }
}
