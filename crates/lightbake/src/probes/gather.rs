//! The light arriving at a point from every direction, read from the bake's own solution:
//! uniformly distributed rays (a scrambled Sobol' (0,2) sequence warped to the sphere), each
//! taking the radiance of what it hits — for a baked surface its albedo times its lightmap
//! value, E/π bilinearly sampled at the hit's `TEXCOORD_1` (plus the direct light of lights
//! baked indirect only, which the lightmap leaves out, by one shadow ray each); for a surface
//! without a lightmap the direct light of the scene's lights at the hit (its interreflected
//! light is not known there and is left out); the sky for a ray that leaves the scene; black
//! for the back of a single-sided surface (the inside of a solid). Emissive surfaces are
//! reached by next-event estimation instead (a triangle picked by power, a point on it
//! sampled as the direct pass does, `emitter_direction`, and a shadow ray), so a small lamp
//! seen from afar is not left to the few rays that happen to hit it; rays that hit an
//! emitter take only what it reflects.
//!
//! The six sides of an ambient cube (Mitchell 2006, "Shading in Valve's Source engine",
//! slide 27) are the irradiance E(d) = ∫ L(ω)·max(0, ω·d) dω for d = ±X, ±Y, ±Z, estimated as
//! (4π/N)·Σ L(ωₖ)·max(0, ωₖ·d) plus the emitters' (1/M)·Σ L·max(0, lₘ·d)·measure/p, and
//! stored as E/π like the lightmap texels.

use glam::{Vec2, Vec3};

use crate::bvh::RayScene;
use crate::color::luminance;
use crate::lightmap::LightmapPage;
use crate::lights::emissive::emitter_direction;
use crate::lights::{Emitters, LightSource};
use crate::raster::SurfacePoint;
use crate::sampling::{hash_words, sobol_02, uniform_cone, unit_float};
use crate::scene::Scene;
use crate::unwrap::Layout;
use crate::vpl::walk::albedo_at;

/// The six axis directions in the order −X, +X, −Y, +Y, −Z, +Z.
pub const SIDES: [Vec3; 6] = [
    Vec3::NEG_X,
    Vec3::X,
    Vec3::NEG_Y,
    Vec3::Y,
    Vec3::NEG_Z,
    Vec3::Z,
];

/// What the rays read: the baked scene (with `TEXCOORD_1`), its layout and pages.
pub struct Solution<'a> {
    /// The baked scene ([`Layout::apply`]).
    pub scene: &'a Scene,
    /// The lightmap layout.
    pub layout: &'a Layout,
    /// The lightmap pages (E/π).
    pub pages: &'a [LightmapPage],
    /// The rays over `scene`.
    pub rays: &'a RayScene,
    /// The scene's emissive triangles.
    pub emitters: &'a Emitters,
}

/// One point's gather.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Gathered {
    /// E/π of each side (−X, +X, −Y, +Y, −Z, +Z), linear RGB.
    pub sides: [Vec3; 6],
    /// The standard error of each side's luminance.
    pub standard_error: [f32; 6],
    /// Rays that met the back of a single-sided surface.
    pub back_hits: u32,
    /// Of those, the nearest few: (distance, direction), nearest first.
    pub nearest_backs: [(f32, Vec3); 8],
    /// How many of `nearest_backs` are set.
    pub backs_kept: usize,
    /// Rays whose first hit (either side of a surface) was within the caller's `near`
    /// distance ([`Solution::gather`]).
    pub near_hits: u32,
    /// Rays traced (gather and shadow rays).
    pub rays: u64,
    /// Whether the gather stopped early, its back hits over the caller's limit
    /// ([`Solution::gather`]): then `sides` and `standard_error` are not set.
    pub stopped: bool,
}

impl Solution<'_> {
    /// Gathers `n` rays at `origin` (and `n`/4 emitter samples, at least one, when the scene
    /// has emissive surfaces), numbers keyed by `key`; stopped as soon as more than
    /// `most_backs` rays have met the back of a single-sided surface (`u32::MAX`: never).
    /// Such a point is inside a solid whatever the rest would meet, and its light is not
    /// needed (`stopped`; the nearest back faces are those of the rays traced); a gather that
    /// does not stop is the same bits whatever `most_backs`. Rays that hit anything within
    /// `near` (m) are counted (`near_hits`).
    pub fn gather(&self, origin: Vec3, n: u32, key: u32, most_backs: u32, near: f32) -> Gathered {
        let mut g = Gathered::default();
        let mut rays = Sides::default();
        for k in 0..n {
            let dir = uniform_cone(Vec3::Z, -1.0, sobol_02(k, key));
            let (l, hit) = self.radiance(origin, dir, hash_words(&[key, k]), &mut g.rays);
            if hit.is_some_and(|(t, _)| t <= near) {
                g.near_hits += 1;
            }
            if let Some((t, true)) = hit {
                g.back_hits += 1;
                keep_nearest(&mut g, t, dir);
                if g.back_hits > most_backs {
                    g.stopped = true;
                    return g;
                }
            }
            // Uniform over the sphere: pdf 1/(4π), so each ray's term is 4π·L·max(0, ω·d),
            // and π of it leaves with the division to E/π.
            rays.add(l * 4.0, dir);
        }
        let mut sides = rays.mean(n);
        if !self.emitters.is_empty() {
            let m = (n / 4).max(1);
            let mut lamps = Sides::default();
            for k in 0..m {
                let (w, dir) = self.emitter_sample(origin, [key, k], &mut g.rays);
                lamps.add(w / std::f32::consts::PI, dir);
            }
            let emitted = lamps.mean(m);
            for s in 0..6 {
                sides.0[s] += emitted.0[s];
                sides.1[s] = sides.1[s].hypot(emitted.1[s]);
            }
        }
        (g.sides, g.standard_error) = sides;
        g
    }

    /// One next-event sample of the emitters' light at `origin`: L·measure/p towards the
    /// sampled direction when the shadow ray is open (zero otherwise).
    fn emitter_sample(&self, origin: Vec3, key: [u32; 2], rays: &mut u64) -> (Vec3, Vec3) {
        let u = |d: u32| unit_float(hash_words(&[key[0], 0xe111, key[1], d]));
        let (i, prob) = self.emitters.pick(u(0));
        if prob <= 0.0 {
            return (Vec3::ZERO, Vec3::Z);
        }
        let em = &self.emitters.list[i];
        let Some((l, d, measure)) = emitter_direction(em, origin, Vec2::new(u(1), u(2))) else {
            return (Vec3::ZERO, Vec3::Z);
        };
        *rays += 1;
        let tmax = d - 2.0 * self.rays.epsilon(origin + l * d);
        if self.rays.occluded(origin, l, 0.0, tmax) {
            return (Vec3::ZERO, l);
        }
        (em.radiance * (measure / prob), l)
    }

    /// The radiance arriving at `origin` from `dir` (see the module docs), and the distance
    /// to what the ray hit, with whether that was the back of a single-sided surface.
    fn radiance(
        &self,
        origin: Vec3,
        dir: Vec3,
        key: u32,
        rays: &mut u64,
    ) -> (Vec3, Option<(f32, bool)>) {
        *rays += 1;
        let Some(hit) = self.rays.closest_hit(origin, dir, 0.0, f32::INFINITY) else {
            return (self.scene.sky, None);
        };
        let info = self.rays.triangles[hit.triangle as usize];
        if !hit.front_face && !info.double_sided {
            return (Vec3::ZERO, Some((hit.t, true)));
        }
        let seen = Some((hit.t, false));
        let normal = if hit.front_face {
            info.normal
        } else {
            -info.normal
        };
        let position = origin + dir * hit.t;
        let sp = SurfacePoint {
            position,
            normal,
            geometric_normal: normal,
            triangle: hit.triangle,
            bary: Vec2::new(hit.u, hit.v),
        };
        // An emitter's own light arrives by next-event estimation ([`Self::gather`]).
        let albedo = albedo_at(self.scene, self.rays, &hit);
        if albedo.max_element() <= 0.0 {
            return (Vec3::ZERO, seen);
        }
        let lightmap = self.lightmap_at(info.instance as usize, info.local as usize, sp.bary);
        // Lights whose direct light the lightmap lacks: all of them without a lightmap, the
        // indirect-only ones with one.
        let origin = self.rays.offset(position, normal);
        let mut direct = Vec3::ZERO;
        for (li, light) in self.scene.lights.iter().enumerate() {
            if lightmap.is_some() && light.direct_is_baked() {
                continue;
            }
            let u = Vec2::new(
                unit_float(hash_words(&[key, li as u32, 1])),
                unit_float(hash_words(&[key, li as u32, 2])),
            );
            if let Some(i) = light.incident(&sp, u, self.rays) {
                *rays += 1;
                if i.visible(self.rays, origin) {
                    direct += i.irradiance;
                }
            }
        }
        let e_over_pi = lightmap.unwrap_or(Vec3::ZERO) + direct * std::f32::consts::FRAC_1_PI;
        (albedo * e_over_pi, seen)
    }

    /// The lightmap's E/π on `triangle` of `instance` at barycentrics `bary`, bilinear as the
    /// GPU reads it; `None` when the instance has no lightmap.
    pub fn lightmap_at(&self, instance: usize, triangle: usize, bary: Vec2) -> Option<Vec3> {
        let rect = self.layout.instances.get(instance).copied().flatten()?;
        let inst = &self.scene.instances[instance];
        let mesh = &self.scene.meshes[inst.mesh];
        let uv1 = mesh.uv1.as_ref()?;
        let [a, b, c] = mesh.triangle(triangle);
        let uv = uv1[a] * (1.0 - bary.x - bary.y) + uv1[b] * bary.x + uv1[c] * bary.y;
        let page = self.pages.get(rect.page as usize)?;
        let x = rect.x as f32 + uv.x * rect.width as f32;
        let y = rect.y as f32 + uv.y * rect.height as f32;
        Some(page.sample_bilinear(x / page.width as f32, y / page.height as f32))
    }
}

/// Per side, the running sums of one estimator's terms T·max(0, ω·d) (and of their
/// luminance and its square, for the standard error).
#[derive(Default)]
struct Sides {
    sum: [Vec3; 6],
    lum: [f64; 6],
    sq: [f64; 6],
}

impl Sides {
    /// Adds the term `t` arriving from direction `dir`.
    fn add(&mut self, t: Vec3, dir: Vec3) {
        let y = luminance(t) as f64;
        for (s, d) in SIDES.iter().enumerate() {
            let c = dir.dot(*d).max(0.0);
            self.sum[s] += t * c;
            self.lum[s] += y * c as f64;
            self.sq[s] += (y * c as f64).powi(2);
        }
    }

    /// The means over `n` terms and the standard errors of their luminance.
    fn mean(&self, n: u32) -> ([Vec3; 6], [f32; 6]) {
        let nf = n.max(1) as f64;
        let mut out = ([Vec3::ZERO; 6], [0.0f32; 6]);
        for s in 0..6 {
            out.0[s] = self.sum[s] / nf as f32;
            let mean = self.lum[s] / nf;
            let var = (self.sq[s] / nf - mean * mean).max(0.0) / (nf - 1.0).max(1.0);
            out.1[s] = var.sqrt() as f32;
        }
        out
    }
}

/// Keeps the nearest back-face hits, nearest first.
fn keep_nearest(g: &mut Gathered, t: f32, dir: Vec3) {
    let n = g.backs_kept;
    if n == g.nearest_backs.len() && t >= g.nearest_backs[n - 1].0 {
        return;
    }
    let mut i = n.min(g.nearest_backs.len() - 1);
    g.nearest_backs[i] = (t, dir);
    while i > 0 && g.nearest_backs[i - 1].0 > g.nearest_backs[i].0 {
        g.nearest_backs.swap(i - 1, i);
        i -= 1;
    }
    g.backs_kept = (n + 1).min(g.nearest_backs.len());
}
