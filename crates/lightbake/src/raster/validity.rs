//! Validity: texels inside or behind geometry. Probe rays along the surface find single-sided
//! back faces within a texel — the sign that the point is inside or behind geometry (a floor
//! texel under a wall). The point is moved out past the nearest such face; if most hemisphere
//! probes still see back faces the patch is marked invalid and later filled from its chart
//! neighbours. Patches with geometry that close are flagged [`Patch::NEAR_GEOMETRY`], and
//! footprint samples of such patches are only used when they see the representative point
//! (so a texel straddling a thin wall does not mix in light from the far side).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{Patch, Patches, Surface, SurfacePoint};
use crate::bvh::RayScene;
use crate::sampling::{basis, cosine_hemisphere, sobol_02};
use crate::scene::Scene;
use crate::unwrap::Layout;

/// Seed of the validity pass's probes (see [`Patches::fix_validity`]).
pub const VALIDITY_SEED: u32 = 0x7a11_d17e;

/// Footprint samples that measure the visible share of a patch near geometry.
const VISIBILITY_SAMPLES: u32 = 16;

impl Patches {
    /// Finds patches inside or behind geometry, moves them out or marks them invalid, and
    /// flags those with geometry within a texel (see the module docs). The area of a flagged
    /// patch is reduced to the part of its footprint that its representative point sees (the
    /// rest is hidden under geometry, such as a floor texel half under a wall), so that areas
    /// and form factors stay reciprocal.
    ///
    /// Its probes use a fixed seed ([`VALIDITY_SEED`]), not the bake's: which texels move,
    /// where to and how much of them is visible are geometry, and a bake with another seed
    /// must differ from this one by Monte Carlo noise alone (a seed-dependent validity put a
    /// floor of about 2.4% under the sunlit room's convergence curves, measured against a
    /// reference baked with another seed).
    pub fn fix_validity(&mut self, scene: &Scene, layout: &Layout, rays: &RayScene) {
        let seed = VALIDITY_SEED;
        const TANGENT_RAYS: u32 = 8;
        const HEMISPHERE_RAYS: u32 = 16;
        const NORMAL_PROBES: u32 = 4;
        let surface = Surface::new(scene, layout, rays);
        let results: Vec<(Vec3, u8, u64)> = self
            .patches
            .par_iter()
            .map(|p| {
                let mut rays_used = 0u64;
                let reach = 1.5 * p.texel_size;
                let g = p.geometric_normal;
                let (t, b) = basis(g);
                let origin = rays.offset(p.position, g);
                let mut near = false;
                // Geometry hanging just above the texel (a lamp under a ceiling): short probes
                // along the normal from points of the footprint.
                if let Some(rect) = layout.instances[p.instance as usize] {
                    let texel = Vec2::new((p.x - rect.x) as f32, (p.y - rect.y) as f32);
                    let footprint = self.footprint_of(p);
                    for k in 0..NORMAL_PROBES {
                        let q = texel + sobol_02(k, p.rng(seed, 0x0e4a));
                        if let Some(sp) =
                            footprint.iter().find_map(|&tri| surface.point(tri, q, 0.0))
                        {
                            rays_used += 1;
                            let o = rays.offset(sp.position, sp.geometric_normal);
                            if rays.occluded(o, sp.geometric_normal, 0.0, reach) {
                                near = true;
                                break;
                            }
                        }
                    }
                }
                let mut exit: Option<(f32, Vec3)> = None;
                // Probe along the surface (slightly lifted so the surface itself is not hit).
                for k in 0..TANGENT_RAYS {
                    let phi = std::f32::consts::TAU * (k as f32 + 0.5) / TANGENT_RAYS as f32;
                    let dir = (t * phi.cos() + b * phi.sin()).normalize();
                    rays_used += 1;
                    if let Some(h) = rays.closest_hit(origin, dir, 0.0, reach) {
                        near = true;
                        let info = rays.triangles[h.triangle as usize];
                        if !h.front_face && !info.double_sided && exit.is_none_or(|e| h.t < e.0) {
                            exit = Some((h.t, dir));
                        }
                    }
                }
                // How many of a cosine-distributed fan of rays from `at` see back faces.
                let key = p.rng(seed, 0x5a11d);
                let mut back_faces = |at: Vec3, near: &mut bool| {
                    let origin = rays.offset(at, g);
                    let mut back = 0;
                    for s in 0..HEMISPHERE_RAYS {
                        let dir = cosine_hemisphere(g, sobol_02(s, key));
                        rays_used += 1;
                        if let Some(h) = rays.closest_hit(origin, dir, 0.0, f32::INFINITY) {
                            if h.t < reach {
                                *near = true;
                            }
                            let info = rays.triangles[h.triangle as usize];
                            if !h.front_face && !info.double_sided {
                                back += 1;
                            }
                        }
                    }
                    back
                };
                let mut position = p.position;
                let mut flags = p.flags;
                let mut back = back_faces(position, &mut near);
                // Push the point out through the back face only when it is inside a solid (it
                // sees mostly back faces): a texel behind a thin single-sided wall sees the
                // wall's back over part of its view only, and pushing it through would carry
                // the other side's light into a room that gets none.
                if let Some((dist, dir)) = exit.filter(|_| 2 * back > HEMISPHERE_RAYS) {
                    position =
                        p.position + dir * (dist + 0.05 * p.texel_size + rays.epsilon(p.position));
                    flags |= Patch::MOVED;
                    // Does the moved point still see mostly back faces?
                    back = back_faces(position, &mut near);
                }
                if 2 * back > HEMISPHERE_RAYS {
                    flags &= !Patch::VALID;
                }
                if near {
                    flags |= Patch::NEAR_GEOMETRY;
                }
                (position, flags, rays_used)
            })
            .collect();
        self.moved = 0;
        self.invalid = 0;
        for (p, (position, flags, n)) in self.patches.iter_mut().zip(results) {
            p.position = position;
            p.flags = flags;
            self.rays += n;
            self.moved += usize::from(flags & Patch::MOVED != 0);
            self.invalid += usize::from(flags & Patch::VALID == 0);
        }
        // Texels next to an invalid texel (geometry hides the surface there) are near
        // geometry too, even where the probes missed it.
        let mut mark = Vec::new();
        for (i, p) in self.patches.iter().enumerate() {
            if p.flags & Patch::NEAR_GEOMETRY != 0 {
                continue;
            }
            let w = layout.pages[p.page as usize].width as i64;
            let h = layout.pages[p.page as usize].height as i64;
            let index = &self.page_index[p.page as usize];
            let touches_invalid = (-1i64..=1).any(|dy| {
                (-1i64..=1).any(|dx| {
                    let (x, y) = (p.x as i64 + dx, p.y as i64 + dy);
                    if x < 0 || y < 0 || x >= w || y >= h {
                        return false;
                    }
                    let j = index[(y * w + x) as usize];
                    j != u32::MAX && !self.patches[j as usize].is_valid()
                })
            });
            if touches_invalid {
                mark.push(i);
            }
        }
        for i in mark {
            self.patches[i].flags |= Patch::NEAR_GEOMETRY;
        }
        // Visible share of the footprint of patches near geometry.
        let shares: Vec<(f32, u64)> = self
            .patches
            .par_iter()
            .map(|p| {
                if p.flags & Patch::NEAR_GEOMETRY == 0 || !p.is_valid() {
                    return (1.0, 0);
                }
                let (visible, total, traced) =
                    self.visible_footprint(p, layout, &surface, rays, seed);
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
            self.rays += traced;
        }
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
            traced += 2;
            if self.sees(p, &sp, rays) {
                visible += 1;
            }
        }
        (visible, total, traced)
    }

    /// Whether a point of patch `p`'s footprint is open surface (always, for patches not near
    /// geometry): it is not hidden from the representative point by geometry (a floor texel
    /// half under a wall), and it does not face the back of a single-sided surface within a
    /// texel (a ceiling texel sandwiched above a lamp hung just below it).
    pub fn sees(&self, p: &Patch, sp: &SurfacePoint, rays: &RayScene) -> bool {
        if p.flags & Patch::NEAR_GEOMETRY == 0 {
            return true;
        }
        let a = rays.offset(p.position, p.geometric_normal);
        let b = rays.offset(sp.position, sp.geometric_normal);
        let d = b - a;
        let len = d.length();
        if len > 0.0 && rays.occluded(a, d / len, 0.0, len) {
            return false;
        }
        match rays.closest_hit(b, sp.geometric_normal, 0.0, p.texel_size) {
            Some(h) => h.front_face || rays.triangles[h.triangle as usize].double_sided,
            None => true,
        }
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
