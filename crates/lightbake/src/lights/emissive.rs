//! Emissive triangles as lights: every triangle whose material emits, with its world
//! vertices, normal, area and luminance (nits), and what the baker asks of them:
//!
//! * the closed-form unoccluded irradiance at a point ([`Emitter::unoccluded_irradiance`]:
//!   E = π·L·F with Lambert's polygon form factor F, [`crate::form_factor`]);
//! * a direction towards a point of the triangle for a shadow ray
//!   ([`emitter_direction`]): uniform in solid angle for triangles that look large (Arvo 1995),
//!   uniform in area for small ones;
//! * picking a triangle by power ([`Emitters::pick`]), the total power and particle emission
//!   ([`Emitters::power`], [`Emitters::emit`]) for instant radiosity.
//!
//! Duplicated faces are sampled once, and overlapping coplanar emitters are found and
//! reported (their light adds up where they overlap).

use glam::{Vec2, Vec3};

use super::{Emission, Incident, Start};
use crate::bvh::{RayScene, coincident_groups};
use crate::color::luminance;
use crate::form_factor::point_to_polygon_form_factor;
use crate::raster::SurfacePoint;
use crate::sampling::{cosine_hemisphere, spherical_triangle, uniform_triangle};
use crate::scene::Scene;

/// An emissive triangle, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// Global triangle index.
    pub triangle: u32,
    /// World vertices.
    pub vertices: [Vec3; 3],
    /// Unit normal (front side).
    pub normal: Vec3,
    /// Area, m².
    pub area: f32,
    /// Emitted luminance, nits, linear RGB.
    pub radiance: Vec3,
    /// Emits from both faces (double-sided material).
    pub two_sided: bool,
}

/// Every emissive triangle of the scene, with a power CDF for sampling.
#[derive(Clone, Debug, Default)]
pub struct Emitters {
    /// The triangles.
    pub list: Vec<Emitter>,
    /// Cumulative power (luminance-weighted radiance × area × sides), normalised to end at 1.
    cdf: Vec<f32>,
    /// (global triangle, emitter index), sorted by triangle.
    by_triangle: Vec<(u32, u32)>,
    /// Emissive triangles left out of sampling because an earlier one has the same three
    /// world vertices (a duplicated mesh or face); rays that hit them still see their radiance.
    pub coincident: usize,
    /// Pairs of sampled emitter triangles that lie in the same plane, face the same way and
    /// overlap with positive area (not exact duplicates): their light adds up where they
    /// overlap. Up to [`MAX_OVERLAPS_LISTED`] pairs of global triangles; see
    /// [`Emitters::overlapping_count`] for how many there are.
    pub overlapping: Vec<(u32, u32)>,
    /// Number of such pairs.
    pub overlapping_count: usize,
}

/// Overlapping emitter pairs kept by name in [`Emitters::overlapping`].
pub const MAX_OVERLAPS_LISTED: usize = 8;

/// Pairs (i < j) of `list` that lie in one plane, face the same way and overlap with positive
/// area. Emitters are grouped by plane (normal to 10⁻⁴, offset to 10⁻⁵ of the scene extent
/// `extent`), then swept by bounding box along the plane's first tangent, and each candidate
/// pair is checked by separating axes in the plane with a small margin (triangles that share
/// an edge touch but do not overlap).
fn overlapping_pairs(list: &[Emitter], extent: f32) -> Vec<(usize, usize)> {
    let tol = 1e-5 * extent.max(1e-30);
    let mut keyed: Vec<((i64, i64, i64, i64), usize)> = list
        .iter()
        .enumerate()
        .map(|(k, e)| {
            let n = e.normal;
            let q = |x: f32| (x * 1e4).round() as i64;
            let d = ((n.dot(e.vertices[0]) / tol).round()) as i64;
            ((q(n.x), q(n.y), q(n.z), d), k)
        })
        .collect();
    keyed.sort_unstable();
    let mut pairs = Vec::new();
    for group in keyed.chunk_by(|a, b| a.0 == b.0) {
        if group.len() < 2 {
            continue;
        }
        let (t, b) = crate::sampling::basis(list[group[0].1].normal);
        let flat = |k: usize| list[k].vertices.map(|v| Vec2::new(v.dot(t), v.dot(b)));
        let mut items: Vec<(f32, f32, usize, [Vec2; 3])> = group
            .iter()
            .map(|&(_, k)| {
                let f = flat(k);
                let (lo, hi) = f.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                    (lo.min(p.x), hi.max(p.x))
                });
                (lo, hi, k, f)
            })
            .collect();
        items.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for (i, a) in items.iter().enumerate() {
            for b in &items[i + 1..] {
                if b.0 >= a.1 - tol {
                    break;
                }
                if triangles_overlap(&a.3, &b.3, tol) {
                    pairs.push((a.2.min(b.2), a.2.max(b.2)));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs
}

/// Whether two plane triangles overlap by more than `margin` (no edge normal of either
/// separates them with a gap or an overlap thinner than `margin`).
fn triangles_overlap(a: &[Vec2; 3], b: &[Vec2; 3], margin: f32) -> bool {
    for tri in [a, b] {
        for i in 0..3 {
            let e = tri[(i + 1) % 3] - tri[i];
            let axis = Vec2::new(-e.y, e.x);
            let len = axis.length();
            if len <= 0.0 {
                return false;
            }
            let axis = axis / len;
            let project = |t: &[Vec2; 3]| {
                t.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                    let x = p.dot(axis);
                    (lo.min(x), hi.max(x))
                })
            };
            let (a0, a1) = project(a);
            let (b0, b1) = project(b);
            if a1.min(b1) - a0.max(b0) <= margin {
                return false;
            }
        }
    }
    true
}

impl Emitters {
    /// Collects emissive triangles of every instance (baked or not).
    pub fn collect(scene: &Scene, rays: &RayScene) -> Self {
        let mut list = Vec::new();
        for (g, info) in rays.triangles.iter().enumerate() {
            if info.area <= 0.0 {
                continue;
            }
            let inst = &scene.instances[info.instance as usize];
            let material = scene.material_of(inst.mesh);
            if !material.is_emissive() {
                continue;
            }
            let mesh = &scene.meshes[inst.mesh];
            let t = info.local as usize;
            let [a, b, c] = mesh.triangle(t);
            // A textured emitter's luminance: the mean at its corners and centroid.
            let radiance = if material.emissive_texture.is_some() {
                [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::splat(1.0 / 3.0)]
                    .iter()
                    .map(|&bary| material.emission(&scene.textures, mesh.texcoords(t, bary)))
                    .sum::<Vec3>()
                    / 4.0
            } else {
                material.emissive
            };
            if radiance.max_element() <= 0.0 {
                continue;
            }
            list.push(Emitter {
                triangle: g as u32,
                vertices: [a, b, c].map(|i| inst.transform.transform_point3(mesh.positions[i])),
                normal: info.normal,
                area: info.area,
                radiance,
                two_sided: material.double_sided,
            });
        }
        // Coincident duplicates: two emitters on the same triangle are one visible surface, but
        // each adds its full closed-form irradiance and neither shadows the other, so the light
        // would count twice. Sample the first; map hits on a twin to it.
        // `sampled_as[k]`: the emitter that stands for emitter k (itself unless an earlier
        // coincident one with the same radiance does).
        let mut sampled_as: Vec<usize> = (0..list.len()).collect();
        for group in coincident_groups(list.iter().enumerate().map(|(k, e)| (k as u32, e.vertices)))
        {
            for (i, &k) in group.iter().enumerate() {
                let k = k as usize;
                if let Some(&f) = group[..i].iter().find(|&&f| {
                    sampled_as[f as usize] == f as usize
                        && list[f as usize].radiance == list[k].radiance
                }) {
                    sampled_as[k] = f as usize;
                }
            }
        }
        let mut new_index = vec![0u32; list.len()];
        let mut kept = Vec::with_capacity(list.len());
        for (k, e) in list.iter().enumerate() {
            if sampled_as[k] == k {
                new_index[k] = kept.len() as u32;
                kept.push(*e);
            }
        }
        let twins: Vec<(u32, u32)> = (0..list.len())
            .filter(|&k| sampled_as[k] != k)
            .map(|k| (list[k].triangle, new_index[sampled_as[k]]))
            .collect();
        list = kept;
        let mut total = 0.0f64;
        let mut cdf: Vec<f32> = list
            .iter()
            .map(|e| {
                total += (luminance(e.radiance).max(1e-20)
                    * e.area
                    * if e.two_sided { 2.0 } else { 1.0 }) as f64;
                total as f32
            })
            .collect();
        if total > 0.0 {
            for c in &mut cdf {
                *c /= total as f32;
            }
        }
        let mut by_triangle: Vec<(u32, u32)> = list
            .iter()
            .enumerate()
            .map(|(k, e)| (e.triangle, k as u32))
            .chain(twins.iter().copied())
            .collect();
        by_triangle.sort_unstable();
        let pairs = overlapping_pairs(&list, rays.extent);
        Self {
            overlapping: pairs
                .iter()
                .take(MAX_OVERLAPS_LISTED)
                .map(|&(a, b)| (list[a].triangle, list[b].triangle))
                .collect(),
            overlapping_count: pairs.len(),
            list,
            cdf,
            by_triangle,
            coincident: twins.len(),
        }
    }

    /// Whether there is nothing to sample.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The emitter on global triangle `triangle`, if it emits.
    pub fn index_of(&self, triangle: u32) -> Option<usize> {
        self.by_triangle
            .binary_search_by_key(&triangle, |e| e.0)
            .ok()
            .map(|k| self.by_triangle[k].1 as usize)
    }

    /// Probability with which [`Emitters::pick`] picks emitter `k`.
    pub fn probability(&self, k: usize) -> f32 {
        self.cdf[k] - if k == 0 { 0.0 } else { self.cdf[k - 1] }
    }

    /// Picks an emitter by power: (index, probability).
    pub fn pick(&self, u: f32) -> (usize, f32) {
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.list.len() - 1);
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (i, self.cdf[i] - prev)
    }

    /// One sample of the emitters' light at `sp` (shadow rays from `origin`): a triangle
    /// picked by power with `u_pick`, a direction towards it from `u` ([`emitter_direction`]),
    /// and the one-sample estimate L·cosθ·measure / p. `None` when the sample sends nothing.
    pub fn incident(
        &self,
        sp: &SurfacePoint,
        origin: Vec3,
        u_pick: f32,
        u: Vec2,
        rays: &RayScene,
    ) -> Option<Incident> {
        let (i, prob) = self.pick(u_pick);
        if prob <= 0.0 {
            return None;
        }
        let em = &self.list[i];
        let (l, d, measure) = emitter_direction(em, origin, u)?;
        let cos_r = sp.normal.dot(l);
        if cos_r <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
            return None;
        }
        Some(Incident {
            irradiance: em.radiance * (cos_r * measure / prob),
            direction: l,
            tmax: d - 2.0 * rays.epsilon(origin + l * d),
        })
    }

    /// Total emitted power, lumens, linear RGB: π·L·A per side.
    pub fn power(&self) -> Vec3 {
        self.list.iter().fold(Vec3::ZERO, |s, e| {
            s + e.radiance * (std::f32::consts::PI * e.area * if e.two_sided { 2.0 } else { 1.0 })
        })
    }

    /// A particle from the triangle picked by power with `u_pick`, at the uniform point
    /// `u_position` of it, leaving in a cosine-distributed direction from `u_direction`
    /// (a two-sided triangle's side from the first half of `u_direction.x`); it starts just
    /// off the surface.
    pub fn emit(
        &self,
        rays: &RayScene,
        u_pick: f32,
        u_position: Vec2,
        u_direction: Vec2,
    ) -> Emission {
        let (e, _) = self.pick(u_pick);
        let em = &self.list[e];
        let y = em.point(u_position);
        let mut normal = em.normal;
        if em.two_sided && u_direction.x < 0.5 {
            normal = -normal;
        }
        let d = cosine_hemisphere(
            normal,
            Vec2::new(
                if em.two_sided {
                    (u_direction.x * 2.0).fract()
                } else {
                    u_direction.x
                },
                u_direction.y,
            ),
        );
        Emission {
            origin: rays.offset(y, normal),
            direction: d,
            weight: 1.0,
            start: Start::Surface { normal },
        }
    }
}

impl Emitter {
    /// The closed-form unoccluded irradiance this triangle gives `sp`, lux (Lambert's
    /// polygon form factor, [`crate::form_factor`]): zero when `sp` sees its back and it is
    /// one-sided.
    pub fn unoccluded_irradiance(&self, sp: &SurfacePoint) -> Vec3 {
        let em = self;
        let facing = em.normal.dot(sp.position - em.vertices[0]);
        if facing <= 0.0 && !em.two_sided {
            return Vec3::ZERO;
        }
        em.radiance
            * (std::f32::consts::PI
                * point_to_polygon_form_factor(sp.position, sp.normal, &em.vertices))
    }

    /// The point of the triangle at uniform sample `u` ∈ [0, 1)².
    pub fn point(&self, u: Vec2) -> Vec3 {
        let b = uniform_triangle(u);
        self.vertices[0] * (1.0 - b.x - b.y) + self.vertices[1] * b.x + self.vertices[2] * b.y
    }
}

/// Below this solid angle (sr) an emitter triangle is sampled by area, not by solid angle:
/// the area density is then nearly uniform in solid angle anyway, and the spherical
/// triangle's angles lose accuracy.
const MIN_SOLID_ANGLE: f32 = 1e-2;

/// A point on emitter `em` as seen from `origin`: (unit direction, distance, measure) where
/// `L·cos_r·measure` is the one-sample estimate of the emitter's irradiance (before the pick
/// probability). Triangles that subtend a large solid angle are sampled uniformly in it
/// (measure Ω, Arvo 1995): near an emitter, area sampling's 1/d² weights make the estimate
/// very noisy (two emitting plates meeting at a sharp angle). Small ones are sampled by area
/// (measure A·cos_e/d²). `None` when the point sees the emitter's back (one-sided) or edge-on.
pub fn emitter_direction(em: &Emitter, origin: Vec3, u: Vec2) -> Option<(Vec3, f32, f32)> {
    let facing = |l: Vec3| {
        let cos_e = -em.normal.dot(l);
        if em.two_sided { cos_e.abs() } else { cos_e }
    };
    if let Some((l, omega)) = spherical_triangle(origin, em.vertices, u, MIN_SOLID_ANGLE) {
        let cos_e = facing(l);
        let d = em.normal.dot(em.vertices[0] - origin) / em.normal.dot(l);
        return (cos_e > 0.0 && d > 0.0 && d.is_finite()).then_some((l, d, omega));
    }
    let b = uniform_triangle(u);
    let y = em.vertices[0] * (1.0 - b.x - b.y) + em.vertices[1] * b.x + em.vertices[2] * b.y;
    let to = y - origin;
    let d2 = to.length_squared();
    if d2 <= 0.0 {
        return None;
    }
    let d = d2.sqrt();
    let l = to / d;
    let cos_e = facing(l);
    (cos_e > 0.0).then_some((l, d, em.area * cos_e / d2))
}
