//! Validity: texels inside or behind geometry. Probe rays along the surface find single-sided
//! back faces within a texel — the sign that the point is inside or behind geometry (a floor
//! texel under a wall). The point is moved out past the nearest such face. If most hemisphere
//! probes still see back faces, the texel's footprint is searched for open surface (a point
//! whose hemisphere is mostly not the inside of a solid): a texel whose centre lies under a
//! wall but whose rim shows in the room takes the most central open point as its
//! representative, and is lit from the visible part of its footprint. Only a texel with no
//! open point is marked invalid — *hidden*: no view can see it — and later filled from its
//! chart neighbours. A second, independent search over other points of every hidden texel's
//! footprint counts those of which it finds an eighth or more clearly open after all
//! (*visible but unlit*: zero when the first search is dense enough). Patches with geometry
//! that close are flagged [`Patch::NEAR_GEOMETRY`], and footprint samples of such patches are
//! only used when they see the representative point (so a texel straddling a thin wall does
//! not mix in light from the far side). A texel whose point has a surface over it within a
//! texel (under a rug) is then lit from the open part of its footprint where it has one
//! ([`super::covered`]).
//!
//! Most texels of a level lie in the open middle of a floor or a wall, where the short probes
//! (along the surface and along the normal, within 1.5 texels) cannot hit anything: a query of
//! the BVH's boxes against balls around the probes finds every triangle they could meet, and
//! where none crosses the heights the probes run at, the texel takes their answer (nothing
//! near, no back face) without tracing them. On the corpus this holds at 93–99.9% of the texels
//! whose probes find nothing, and never where they find something (`tests/validity.rs`).
//!
//! Most hidden texels lie wholly under a wall or a crate. Where the centre's fan sees back
//! faces in at least three quarters of its directions, no surface crosses the footprint at
//! the height rays leave it from, and every footprint point is nearer the centre than the
//! nearest face its fan saw, the footprint's points are inside the same solid as the centre:
//! the texel is hidden without the search, which would have traced 4 rays or more at each of
//! 64 points (on the corpus 29–100% of the hidden texels; the house: 29% at preview, 50% at
//! medium). Where the footprint lies so beside a centre whose fan sees back faces in more
//! than half but under three quarters of its directions, the search stops at 64 points. Traced anyway in the tests, the search
//! finds an open point in 3 of the house's 3 613 skipped texels at preview, each at most
//! 3 cm from a centre whose nearest face is 22–27 cm away (its own fan's noise), and in none
//! elsewhere. Once something is near a texel, its fan stops as soon as it cannot see mostly
//! back faces (after 8 open rays of 16 beside a wall).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::footprint::gap_probe;
use super::open_plane::{footprint_beside, short_probes_meet_nothing};
use super::{Patch, Patches, Surface, SurfacePoint};
use crate::bvh::RayScene;
use crate::sampling::{basis, cosine_hemisphere, hash_words, sobol_02};
use crate::scene::Scene;
use crate::unwrap::Layout;

/// Seed of the validity pass's probes (see [`Patches::fix_validity`]).
pub const VALIDITY_SEED: u32 = 0x7a11_d17e;

/// Footprint samples that measure the visible share of a patch near geometry.
const VISIBILITY_SAMPLES: u32 = 16;

/// Rays along the surface that look for the way out of a solid.
const TANGENT_RAYS: u32 = 8;
/// Rays of the cosine fan that measures how much of a patch's view is inside a solid.
const HEMISPHERE_RAYS: u32 = 16;
/// Short probes along the normal for geometry hanging just above a patch.
const NORMAL_PROBES: u32 = 4;
/// Footprint points searched for open surface when a texel's centre is hidden; where one of
/// them is only just closed (open surface may be near), [`RESCUE_MORE_POINTS`] in all.
const RESCUE_POINTS: u32 = 64;
/// Footprint points searched in a texel where open surface may be near.
const RESCUE_MORE_POINTS: u32 = 256;
/// Footprint points of the second search over the hidden texels: it counts a texel as
/// visible when 2 of them are clearly open (an eighth of the texel or so; smaller slivers of
/// open surface are below what it resolves).
const CHECK_POINTS: u32 = 16;
/// Rays of a fan after which a point all of whose rays saw back faces is taken to be inside
/// a solid (most points of a hidden texel are, and need no more).
const PRETEST_RAYS: u32 = 4;
/// Rays of a fan before a point is found closed for it to count as only just closed (at
/// most [`OPEN_BACK`] back faces among the rays before): only such a point sends the search
/// for open surface on to [`RESCUE_MORE_POINTS`]. A point closed sooner sees back faces over
/// far more than a quarter of its view, and the open surface the longer search looks for is
/// rarely near it (on the corpus it found an open point in 0–1.3% of the texels it ran for).
const LATE_CLOSED_RAYS: u32 = 12;

/// Rays of a hidden texel's fan that may see something other than a back face (the front
/// of a surface, or nothing) for its footprint to be found hidden without a search
/// ([`Patches::open_footprint_point`]): a quarter of them, as a footprint point's fan may see
/// back faces and still be open ([`OPEN_BACK`]).
const SEALED_OTHER: u32 = HEMISPHERE_RAYS / 4;

/// The validity pass's rays by step ([`Patches::ray_steps`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ValidityRays {
    /// Short probes along the surface and the normal (within 1.5 texels).
    pub probes: u64,
    /// Cosine fans: how much of a point's view is the inside of a solid.
    pub fans: u64,
    /// The search of the footprints of texels whose centre is hidden for open surface.
    pub search: u64,
    /// The second search over the hidden texels.
    pub second_search: u64,
    /// Texels near geometry: the gap probe and the visible share of the footprint.
    pub near: u64,
}

impl ValidityRays {
    /// Rays of every step.
    pub fn total(&self) -> u64 {
        self.probes + self.fans + self.search + self.second_search + self.near
    }
}

impl std::fmt::Display for ValidityRays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let m = |r: u64| r as f64 / 1e6;
        write!(
            f,
            "rays (M): short probes {:.2}, fans {:.2}, hidden-centre search {:.2}, second search {:.2}, near geometry {:.2}",
            m(self.probes),
            m(self.fans),
            m(self.search),
            m(self.second_search),
            m(self.near)
        )
    }
}

/// One patch after its probes.
struct Probed {
    position: Vec3,
    flags: u8,
    /// The open point of the footprint that stands for a texel whose centre is hidden.
    rescued: Option<SurfacePoint>,
    /// Rays of its short probes, its fans and its footprint's search.
    rays: [u64; 3],
    /// Hidden without the search: its footprint lies beside a centre inside a solid
    /// ([`footprint_beside`]).
    sealed: bool,
    /// Clearly open: nothing within reach, and at most [`OPEN_BACK`] rays of its fan saw
    /// back faces (set for texels of the fan grid only).
    clear: bool,
}

/// Whether texel `p` is on the fan grid: every other texel in each direction of its page.
/// These always trace their cosine fan; a texel off the grid with nothing within reach
/// takes the answer of the grid texels around it when they are all clearly open
/// ([`Patches::fix_validity`]).
fn on_fan_grid(p: &Patch) -> bool {
    p.x.is_multiple_of(2) && p.y.is_multiple_of(2)
}

/// The nearest single-sided back face within `reach` along the surface (rays slightly
/// lifted, so the surface itself is not hit): (distance, direction). Any hit sets `near`.
fn nearest_back_face(
    p: &Patch,
    rays: &RayScene,
    reach: f32,
    near: &mut bool,
    used: &mut u64,
) -> Option<(f32, Vec3)> {
    let (t, b) = basis(p.geometric_normal);
    let origin = rays.offset(p.position, p.geometric_normal);
    let mut exit: Option<(f32, Vec3)> = None;
    for k in 0..TANGENT_RAYS {
        let phi = std::f32::consts::TAU * (k as f32 + 0.5) / TANGENT_RAYS as f32;
        let dir = (t * phi.cos() + b * phi.sin()).normalize();
        *used += 1;
        if let Some(h) = rays.closest_hit(origin, dir, 0.0, reach) {
            *near = true;
            let info = rays.triangles[h.triangle as usize];
            if !h.front_face && !info.double_sided && exit.is_none_or(|e| h.t < e.0) {
                exit = Some((h.t, dir));
            }
        }
    }
    exit
}

/// Whether geometry hangs within `reach` above `points` of a patch's footprint (short probes
/// along the normal, up to the first hit).
fn hangs_over(points: &[SurfacePoint], rays: &RayScene, reach: f32, used: &mut u64) -> bool {
    points.iter().any(|sp| {
        *used += 1;
        let o = rays.offset(sp.position, sp.geometric_normal);
        rays.occluded(o, sp.geometric_normal, 0.0, reach)
    })
}

/// What [`is_open`] found at a point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Openness {
    /// At most the allowed share of the fan sees back faces.
    Open,
    /// More does, but not all of the first rays: open surface may be near when it was found
    /// only after [`LATE_CLOSED_RAYS`] rays (`late`).
    Closed {
        /// Found closed only after [`LATE_CLOSED_RAYS`] rays or more.
        late: bool,
    },
    /// All of the first [`PRETEST_RAYS`] rays see back faces: deep inside a solid.
    Inside,
}

/// Back faces a point of a hidden texel's footprint may see and be open: a quarter of its fan.
/// A point in a room sees none (it sees the front of what stands around it); a point on the
/// line where a wall meets the floor sees about half (its fan is half inside the wall), and
/// a texel whose only open points lie on that line is hidden, not lit from a sliver of no
/// width.
const OPEN_BACK: u32 = HEMISPHERE_RAYS / 4;
/// Back faces a point's fan may see to be *clearly* open, for the second search over the
/// hidden texels: an eighth of it. The margin to [`OPEN_BACK`] keeps points that are open to
/// one fan and closed to the next out of the count.
const CLEARLY_OPEN_BACK: u32 = HEMISPHERE_RAYS / 8;

/// Whether a point at `at` with geometric normal `g` is open surface by the test a texel's
/// centre takes ([`is_open`] with at most [`OPEN_BACK`] back faces).
pub(super) fn open_surface(at: (Vec3, Vec3), key: u32, rays: &RayScene, used: &mut u64) -> bool {
    matches!(is_open(at, key, rays, OPEN_BACK, used), Openness::Open)
}

/// Whether a point at `at` with geometric normal `g` is open surface: at most `max_back` rays
/// of a cosine fan of [`HEMISPHERE_RAYS`] (scrambled by `key`: each point of a footprint its
/// own, so no one set of directions decides for all of them) see the back of a single-sided
/// surface. A point whose first [`PRETEST_RAYS`] rays all do is taken to be inside a solid
/// without the rest.
fn is_open(
    (at, g): (Vec3, Vec3),
    key: u32,
    rays: &RayScene,
    max_back: u32,
    used: &mut u64,
) -> Openness {
    let origin = rays.offset(at, g);
    let mut back = 0;
    for s in 0..HEMISPHERE_RAYS {
        if s == PRETEST_RAYS && back == PRETEST_RAYS {
            return Openness::Inside;
        }
        let dir = cosine_hemisphere(g, sobol_02(s, key));
        *used += 1;
        if let Some(h) = rays.closest_hit(origin, dir, 0.0, f32::INFINITY)
            && !h.front_face
            && !rays.triangles[h.triangle as usize].double_sided
        {
            back += 1;
            if back > max_back {
                return Openness::Closed {
                    late: s + 1 >= LATE_CLOSED_RAYS,
                };
            }
        }
    }
    Openness::Open
}

/// What a cosine fan of [`HEMISPHERE_RAYS`] found ([`back_faces`]).
#[derive(Clone, Copy, Debug)]
struct Fan {
    /// Rays that saw the back of a single-sided surface. When the fan stopped early this
    /// counts the rays traced: at most half the fan, as the whole fan's count would be.
    back: u32,
    /// At most [`SEALED_OTHER`] of the fan's rays saw anything else (it traced them all).
    closed: bool,
    /// The distance to the nearest hit of the rays traced (∞ when none hit).
    nearest: f32,
}

impl Fan {
    /// More than half of the fan sees back faces: the point is inside or behind a solid.
    fn mostly_back(&self) -> bool {
        2 * self.back > HEMISPHERE_RAYS
    }
}

/// How many of a cosine-distributed fan of rays from `at` (about `p`'s normal) see the back
/// of a single-sided surface; a hit within `reach` sets `near`.
///
/// Once `near` is set, the caller reads only whether the fan sees mostly back faces
/// ([`Fan::mostly_back`]; the count's other use, "clearly open", needs nothing near), so the
/// fan stops once the rays left cannot make it so: after 8 rays without a back face at an
/// open point beside a wall. A fan that may see mostly back faces runs to the end, for
/// [`Fan::closed`] and [`Fan::nearest`]. The flags the pass sets are those of the whole fan.
fn back_faces(
    p: &Patch,
    at: Vec3,
    rays: &RayScene,
    reach: f32,
    near: &mut bool,
    used: &mut u64,
) -> Fan {
    let g = p.geometric_normal;
    let key = p.rng(VALIDITY_SEED, 0x5a11d);
    let origin = rays.offset(at, g);
    let half = HEMISPHERE_RAYS / 2;
    let mut back = 0;
    let mut nearest = f32::INFINITY;
    for s in 0..HEMISPHERE_RAYS {
        let left = HEMISPHERE_RAYS - s;
        if *near && back + left <= half {
            return Fan {
                back,
                closed: false,
                nearest,
            };
        }
        let dir = cosine_hemisphere(g, sobol_02(s, key));
        *used += 1;
        if let Some(h) = rays.closest_hit(origin, dir, 0.0, f32::INFINITY) {
            if h.t < reach {
                *near = true;
            }
            nearest = nearest.min(h.t);
            let info = rays.triangles[h.triangle as usize];
            if !h.front_face && !info.double_sided {
                back += 1;
            }
        }
    }
    Fan {
        back,
        closed: HEMISPHERE_RAYS - back <= SEALED_OTHER,
        nearest,
    }
}

impl Patches {
    /// Finds patches inside or behind geometry, moves them out or marks them invalid, and
    /// flags those with geometry within a texel (see the module docs). The area of a flagged
    /// patch is reduced to the part of its footprint that its representative point sees (the
    /// rest is hidden under geometry, such as a floor texel half under a wall), so that areas
    /// and form factors stay reciprocal.
    ///
    /// Its probes use a fixed seed ([`VALIDITY_SEED`]), not the bake's: which texels move,
    /// where to and how much of them is visible are geometry, and a bake with another seed
    /// must differ from this one by Monte Carlo noise alone (a seed-dependent validity puts a
    /// floor of a few percent under the convergence curves, which are measured against a
    /// reference baked with another seed).
    pub fn fix_validity(&mut self, scene: &Scene, layout: &Layout, rays: &RayScene) {
        let surface = Surface::new(scene, layout, rays);
        // 1. Probe every patch: move it out of solids, mark it invalid, flag it near geometry.
        // The texels of the fan grid first; then the others, each of which skips its fan when
        // nothing is within its reach and every grid texel of its 3 × 3 neighbourhood is
        // clearly open. Nothing within reach means no surface crosses its own within 1.5
        // texels (its tangent rays would hit it), so its neighbours, at most √2 texels away on
        // the same chart, lie on the same side of every solid, and it would see what they see.
        let (on, off): (Vec<usize>, Vec<usize>) =
            (0..self.patches.len()).partition(|&i| on_fan_grid(&self.patches[i]));
        let probe_all = |indices: &[usize], clear_around: &(dyn Fn(&Patch) -> bool + Sync)| {
            indices
                .par_iter()
                .map(|&i| self.probe(&self.patches[i], layout, &surface, rays, clear_around))
                .collect::<Vec<Probed>>()
        };
        let grid = probe_all(&on, &|_| false);
        let mut clear = vec![false; self.patches.len()];
        for (&i, g) in on.iter().zip(&grid) {
            clear[i] = g.clear;
        }
        let rest = probe_all(&off, &|p| self.grid_around_is_clear(p, layout, &clear));
        let (mut grid, mut rest) = (grid.into_iter(), rest.into_iter());
        self.moved = 0;
        self.invalid = 0;
        self.rescued = 0;
        self.sealed = 0;
        self.ray_steps = ValidityRays::default();
        for p in &mut self.patches {
            let r = if on_fan_grid(p) {
                grid.next()
            } else {
                rest.next()
            };
            let r = r.expect("one probe per patch");
            p.position = r.position;
            p.flags = r.flags;
            if let Some(sp) = r.rescued {
                p.position = sp.position;
                p.normal = sp.normal;
                p.geometric_normal = sp.geometric_normal;
                p.triangle = sp.triangle;
                self.rescued += 1;
            }
            self.ray_steps.probes += r.rays[0];
            self.ray_steps.fans += r.rays[1];
            self.ray_steps.search += r.rays[2];
            self.sealed += usize::from(r.sealed);
            self.moved += usize::from(r.flags & Patch::MOVED != 0);
            self.invalid += usize::from(r.flags & Patch::VALID == 0);
        }
        // The second search over the hidden texels (see the module docs).
        let second: Vec<(bool, u64)> = self
            .patches
            .par_iter()
            .map(|p| {
                if p.is_valid() {
                    return (false, 0);
                }
                let mut used = 0;
                let key = p.rng(VALIDITY_SEED, 0x005e_c02d);
                let found = self.partly_open(p, (layout, &surface, rays), key, &mut used);
                (found, used)
            })
            .collect();
        self.visible_unlit = 0;
        for (found, used) in second {
            self.visible_unlit += usize::from(found);
            self.ray_steps.second_search += used;
        }
        // 2. Texels next to an invalid texel (geometry hides the surface there) are near
        // geometry too, even where the probes missed it.
        let mark: Vec<usize> = (0..self.patches.len())
            .filter(|&i| {
                self.patches[i].flags & Patch::NEAR_GEOMETRY == 0
                    && self.touches_invalid(&self.patches[i], layout)
            })
            .collect();
        for i in mark {
            self.patches[i].flags |= Patch::NEAR_GEOMETRY;
        }
        // Representative points in a gap thinner than a texel (under a rug), moved to open
        // surface in their footprint where it has some (`covered.rs`).
        self.ray_steps.near += self.settle_covered(layout, &surface, rays);
        // 3. The area of a patch near geometry: the visible share of its footprint.
        let shares: Vec<(f32, u64)> = self
            .patches
            .par_iter()
            .map(|p| {
                if p.flags & Patch::NEAR_GEOMETRY == 0 || !p.is_valid() {
                    return (1.0, 0);
                }
                let (visible, total, traced) =
                    self.visible_footprint(p, layout, &surface, rays, VALIDITY_SEED);
                let share = if total == 0 {
                    1.0
                } else {
                    (visible as f32 / total as f32).max(1.0 / VISIBILITY_SAMPLES as f32)
                };
                (share, traced)
            })
            .collect();
        for (p, (share, traced)) in self.patches.iter_mut().zip(shares) {
            p.area *= share;
            self.ray_steps.near += traced;
        }
        self.rays = self.ray_steps.total();
    }

    /// Probes one patch (see the module docs): short rays along its normal from points of its
    /// footprint (geometry hanging just above, a lamp under a ceiling), along the surface (the
    /// nearest single-sided back face, the way out of a solid), and a cosine fan (how much of
    /// its view is the inside of a solid) — before and, when it is moved out, after the move.
    /// A patch with nothing within reach skips its fan when `clear_around(p)` says the fan
    /// grid around it is clearly open.
    fn probe(
        &self,
        p: &Patch,
        layout: &Layout,
        surface: &Surface<'_>,
        rays: &RayScene,
        clear_around: &dyn Fn(&Patch) -> bool,
    ) -> Probed {
        let mut used = 0u64;
        let reach = 1.5 * p.texel_size;
        let points: Vec<SurfacePoint> = self.normal_probe_points(p, layout, surface).collect();
        let (mut near, exit) = if short_probes_meet_nothing(rays, p, reach, &points) {
            (false, None)
        } else {
            let mut near = hangs_over(&points, rays, reach, &mut used);
            let exit = nearest_back_face(p, rays, reach, &mut near, &mut used);
            (near, exit)
        };
        let probes = used;
        let mut position = p.position;
        let mut flags = p.flags;
        if !near && clear_around(p) {
            return Probed {
                position,
                flags,
                rescued: None,
                rays: [probes, 0, 0],
                sealed: false,
                clear: false,
            };
        }
        let mut fan = back_faces(p, position, rays, reach, &mut near, &mut used);
        let clear = !near && fan.back <= OPEN_BACK;
        // Push the point out through the back face only when it is inside a solid (it sees
        // mostly back faces): a texel behind a thin single-sided wall sees the wall's back
        // over part of its view only, and pushing it through would carry the other side's
        // light into a room that gets none.
        if let Some((dist, dir)) = exit.filter(|_| fan.mostly_back()) {
            position = p.position + dir * (dist + 0.05 * p.texel_size + rays.epsilon(p.position));
            flags |= Patch::MOVED;
            // Does the moved point still see mostly back faces?
            fan = back_faces(p, position, rays, reach, &mut near, &mut used);
        }
        let fans = used - probes;
        let mut rescued = None;
        let mut sealed = false;
        if fan.mostly_back() {
            // The centre is hidden: is any of the footprint open surface?
            let key = p.rng(VALIDITY_SEED, 0x0e5c);
            (rescued, sealed) = self.open_footprint_point(
                p,
                (layout, surface, rays),
                key,
                (position, fan),
                &mut used,
            );
            if rescued.is_some() {
                // Lit from the visible part of its footprint, which the rest of it cannot see.
                flags |= Patch::MOVED | Patch::PARTLY_HIDDEN;
                near = true;
            } else {
                flags &= !Patch::VALID;
            }
        }
        if near {
            flags |= Patch::NEAR_GEOMETRY;
        }
        Probed {
            position,
            flags,
            rescued,
            rays: [probes, fans, used - probes - fans],
            sealed,
            clear,
        }
    }

    /// The fast path against the rays it saves, for the tests: over every patch (before the
    /// validity pass), (patches whose short probes find nothing near and no back face,
    /// patches the fast path (`open_plane.rs`) passes, those of them whose probes do find
    /// something: must be none).
    #[cfg(feature = "internals")]
    pub fn open_plane_check(&self, scene: &Scene, layout: &Layout, rays: &RayScene) -> [usize; 3] {
        let surface = Surface::new(scene, layout, rays);
        let checked: Vec<[bool; 3]> = self
            .patches
            .par_iter()
            .map(|p| {
                let reach = 1.5 * p.texel_size;
                let points: Vec<SurfacePoint> =
                    self.normal_probe_points(p, layout, &surface).collect();
                let passed = short_probes_meet_nothing(rays, p, reach, &points);
                let mut used = 0;
                let mut near = hangs_over(&points, rays, reach, &mut used);
                let found =
                    nearest_back_face(p, rays, reach, &mut near, &mut used).is_some() || near;
                [!found, passed, passed && found]
            })
            .collect();
        [0, 1, 2].map(|k| checked.iter().filter(|c| c[k]).count())
    }

    /// The search that hidden texels skip, traced anyway, for the tests: over the hidden
    /// patches of a finished pass, (those whose footprint was found hidden without a search,
    /// those of them in which the search finds an open point).
    #[cfg(feature = "internals")]
    pub fn sealed_check(&self, scene: &Scene, layout: &Layout, rays: &RayScene) -> [usize; 2] {
        let surface = Surface::new(scene, layout, rays);
        let checked: Vec<[bool; 2]> = self
            .patches
            .par_iter()
            .filter(|p| !p.is_valid())
            .map(|p| {
                let (mut near, mut used) = (false, 0);
                let reach = 1.5 * p.texel_size;
                let fan = back_faces(p, p.position, rays, reach, &mut near, &mut used);
                let key = p.rng(VALIDITY_SEED, 0x0e5c);
                let ctx = (layout, &surface, rays);
                let (_, sealed) =
                    self.open_footprint_point(p, ctx, key, (p.position, fan), &mut used);
                let points = self.footprint_points(p, (layout, &surface), key, 0..RESCUE_POINTS);
                let open = sealed
                    && points.iter().any(|&(s, sp)| {
                        let fan = hash_words(&[key, s]);
                        let at = (sp.position, sp.geometric_normal);
                        is_open(at, fan, rays, OPEN_BACK, &mut used) == Openness::Open
                    });
                [sealed, open]
            })
            .collect();
        [0, 1].map(|k| checked.iter().filter(|c| c[k]).count())
    }

    /// Whether the texels of the fan grid in `p`'s 3 × 3 neighbourhood are all clearly open
    /// (`clear`, by patch), and there is at least one.
    fn grid_around_is_clear(&self, p: &Patch, layout: &Layout, clear: &[bool]) -> bool {
        let w = layout.pages[p.page as usize].width as i64;
        let h = layout.pages[p.page as usize].height as i64;
        let index = &self.page_index[p.page as usize];
        let mut seen = 0;
        for dy in -1i64..=1 {
            for dx in -1i64..=1 {
                let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
                if x < 0 || y < 0 || x >= w || y >= h || x % 2 != 0 || y % 2 != 0 {
                    continue;
                }
                let j = index[(y * w + x) as usize];
                if j == u32::MAX {
                    continue;
                }
                if !clear[j as usize] {
                    return false;
                }
                seen += 1;
            }
        }
        seen > 0
    }

    /// Points of `p`'s footprint on the surface, with their index: stratified points `range`
    /// of the sequence scrambled by `key`, from the texel's centre outwards.
    pub(super) fn footprint_points(
        &self,
        p: &Patch,
        (layout, surface): (&Layout, &Surface<'_>),
        key: u32,
        range: std::ops::Range<u32>,
    ) -> Vec<(u32, SurfacePoint)> {
        let Some(rect) = layout.instances[p.instance as usize] else {
            return Vec::new();
        };
        let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
        let footprint = self.footprint_of(p);
        let centre = Vec2::splat(0.5);
        let mut offsets: Vec<(u32, Vec2)> = range.map(|s| (s, sobol_02(s, key))).collect();
        offsets.sort_by(|a, b| {
            a.1.distance_squared(centre)
                .total_cmp(&b.1.distance_squared(centre))
        });
        offsets
            .into_iter()
            .filter_map(|(s, u)| {
                footprint
                    .iter()
                    .find_map(|&t| surface.point(t, texel + u, 0.0))
                    .map(|sp| (s, sp))
            })
            .collect()
    }

    /// The most central open point of `p`'s footprint ([`is_open`]: the test the texel's
    /// centre failed) among [`RESCUE_POINTS`] (scrambled by `key`); when none is open but one
    /// was only just closed ([`LATE_CLOSED_RAYS`]), among [`RESCUE_MORE_POINTS`]. And whether
    /// the search was skipped, finding nothing.
    ///
    /// `at` is the texel's point and `fan` what its fan saw (mostly back faces). When the
    /// footprint's points lie beside it ([`footprint_beside`]: on its side of every surface,
    /// nearer than the nearest face its fan saw), they see what it sees (module docs):
    /// beside a [`Fan::closed`] centre the search is skipped, beside any other it stops at
    /// [`RESCUE_POINTS`] (more points of the same view only give a fan's noise more tries;
    /// such texels with nothing near took 1 300 rays each on oa_bases3). Without the distance
    /// the rule fails under a thin open mesh just above a surface (a 3 mm card on a table in
    /// the house: the footprint's rim, 5 cm from the centre, sees the room); with half the
    /// fan instead of three quarters, 48 of the house's preview texels lost their open point,
    /// 2 of them clearly visible. The second search over the hidden texels checks the rule.
    fn open_footprint_point(
        &self,
        p: &Patch,
        (layout, surface, rays): (&Layout, &Surface<'_>, &RayScene),
        key: u32,
        (at, fan): (Vec3, Fan),
        used: &mut u64,
    ) -> (Option<SurfacePoint>, bool) {
        let mut near_open = false;
        let mut beside = false;
        for range in [0..RESCUE_POINTS, RESCUE_POINTS..RESCUE_MORE_POINTS] {
            if range.start > 0 && (!near_open || beside) {
                break;
            }
            let first = range.start == 0;
            let points = self.footprint_points(p, (layout, surface), key, range);
            if first {
                let on_surface = points.iter().map(|(_, sp)| sp);
                beside = footprint_beside(rays, (at, p.geometric_normal), on_surface, fan.nearest);
                if beside && fan.closed {
                    return (None, true);
                }
            }
            for (s, sp) in points {
                let fan = hash_words(&[key, s]);
                match is_open(
                    (sp.position, sp.geometric_normal),
                    fan,
                    rays,
                    OPEN_BACK,
                    used,
                ) {
                    Openness::Open => return (Some(sp), false),
                    Openness::Closed { late } => near_open |= late,
                    Openness::Inside => {}
                }
            }
        }
        (None, false)
    }

    /// Whether at least 2 of [`CHECK_POINTS`] points of `p`'s footprint (scrambled by
    /// `key`) are clearly open ([`CLEARLY_OPEN_BACK`]): at least about an eighth of it is
    /// visible.
    fn partly_open(
        &self,
        p: &Patch,
        (layout, surface, rays): (&Layout, &Surface<'_>, &RayScene),
        key: u32,
        used: &mut u64,
    ) -> bool {
        let points = self.footprint_points(p, (layout, surface), key, 0..CHECK_POINTS);
        points
            .iter()
            .filter(|(s, sp)| {
                let fan = hash_words(&[key, *s]);
                is_open(
                    (sp.position, sp.geometric_normal),
                    fan,
                    rays,
                    CLEARLY_OPEN_BACK,
                    used,
                ) == Openness::Open
            })
            .take(2)
            .count()
            == 2
    }

    /// The points of the patch's footprint its normal probes start from ([`NORMAL_PROBES`]
    /// stratified points of the texel that lie on its surface).
    fn normal_probe_points<'s>(
        &'s self,
        p: &'s Patch,
        layout: &Layout,
        surface: &'s Surface<'_>,
    ) -> impl Iterator<Item = SurfacePoint> + 's {
        let rect = layout.instances[p.instance as usize];
        let footprint = self.footprint_of(p);
        (0..NORMAL_PROBES).filter_map(move |k| {
            let rect = rect?;
            let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
            let q = texel + sobol_02(k, p.rng(VALIDITY_SEED, 0x0e4a));
            footprint.iter().find_map(|&tri| surface.point(tri, q, 0.0))
        })
    }

    /// Whether a texel of the 8-neighbourhood of `p` is an invalid patch.
    fn touches_invalid(&self, p: &Patch, layout: &Layout) -> bool {
        let w = layout.pages[p.page as usize].width as i64;
        let h = layout.pages[p.page as usize].height as i64;
        let index = &self.page_index[p.page as usize];
        (-1i64..=1).any(|dy| {
            (-1i64..=1).any(|dx| {
                let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
                if x < 0 || y < 0 || x >= w || y >= h {
                    return false;
                }
                let j = index[(y * w + x) as usize];
                j != u32::MAX && !self.patches[j as usize].is_valid()
            })
        })
    }

    /// Stratified points of a patch's footprint on its surface, with whether each is visible
    /// from the representative point: (visible, on the surface, rays traced).
    fn visible_footprint(
        &self,
        p: &Patch,
        layout: &Layout,
        surface: &Surface<'_>,
        rays: &RayScene,
        seed: u32,
    ) -> (u32, u32, u64) {
        let Some(rect) = layout.instances[p.instance as usize] else {
            return (0, 0, 0);
        };
        let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
        let footprint = self.footprint_of(p);
        let (mut visible, mut total, mut traced) = (0, 0, 0);
        for s in 0..VISIBILITY_SAMPLES {
            let q = texel + sobol_02(s, p.rng(seed, 0x51b1e));
            let Some(sp) = footprint.iter().find_map(|&t| surface.point(t, q, 0.0)) else {
                continue;
            };
            total += 1;
            traced += 1;
            let probe = gap_probe(rays, &sp, p.texel_size);
            if Self::gap_agrees(p, probe) {
                traced += 1;
                visible += u32::from(!Self::hidden_from(p, &sp, rays));
            }
        }
        (visible, total, traced)
    }
}
