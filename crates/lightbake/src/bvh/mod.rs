//! Ray queries against the world-space triangles of every instance: obvhs builds a binary
//! PLOC tree (Meister & Bittner 2018) and optimises it by reinsertion; [`wide`] collapses it
//! into an eight-wide BVH traversed with AVX2 where the CPU has it (SSE otherwise, with the
//! same bits), testing four triangles at a time ([`packet`]), so hits come back with
//! barycentrics and the side that was hit.
//!
//! Closest hit ([`RayScene::closest_hit`]) and any hit ([`RayScene::occluded`]) are
//! single-ray calls; callers parallelise over texels with rayon.
//!
//! # Scale-aware offsets
//! Ray origins leave a surface along its geometric normal by [`RayScene::offset`], which grows
//! with the scene extent and with the magnitude of the coordinates (the float spacing there),
//! so a 1 mm scene and a 10 km scene both trace without self-intersection or visible gaps.

pub mod packet;
pub mod watertight;
pub mod wide;
pub mod workload;

use std::time::Duration;

use glam::Vec3;
use obvhs::{BvhBuildParams, bvh2::reinsertion::ReinsertionOptimizer, ploc::PlocBuilder};

use packet::Ray4;
use wide::Bvh8;

use crate::scene::{Scene, closest_on_triangle};

/// What the baker knows about each world-space triangle (global order: instance by instance,
/// triangles in mesh order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleInfo {
    /// Index into [`Scene::instances`].
    pub instance: u32,
    /// Triangle index within the instance's mesh.
    pub local: u32,
    /// Unit geometric normal in world space: the side the mesh's counter-clockwise winding
    /// faces, under a mirroring transform too.
    pub normal: Vec3,
    /// World-space area, m².
    pub area: f32,
    /// The material is double-sided: the back face is a real surface, not the inside of a solid.
    pub double_sided: bool,
}

/// Groups of triangles lying exactly on each other (the same three vertices, in any order),
/// from `(id, vertices)` pairs: each group lists its ids in increasing order; triangles
/// without a twin are left out.
pub fn coincident_groups(tris: impl IntoIterator<Item = (u32, [Vec3; 3])>) -> Vec<Vec<u32>> {
    let mut keyed: Vec<([[u32; 3]; 3], u32)> = tris
        .into_iter()
        .map(|(id, v)| {
            let mut key = v.map(|p| p.to_array().map(f32::to_bits));
            key.sort_unstable();
            (key, id)
        })
        .collect();
    keyed.sort_unstable();
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .filter(|run| run.len() > 1)
        .map(|run| run.iter().map(|e| e.1).collect())
        .collect()
}

/// A ray–triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Global triangle index (see [`TriangleInfo`]).
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
    /// The ray hit the front (counter-clockwise) side.
    pub front_face: bool,
}

/// The ray-tracing view of a scene.
pub struct RayScene {
    bvh: Bvh8,
    /// World vertices per global triangle (zero for zero-area triangles, which are not in
    /// the BVH).
    accel: Vec<[Vec3; 3]>,
    /// Triangles in the BVH.
    live_count: usize,
    /// Per global triangle.
    pub triangles: Vec<TriangleInfo>,
    /// First global triangle of each instance (length = instances + 1).
    pub instance_first_triangle: Vec<u32>,
    /// World bounds (min, max).
    pub bounds: (Vec3, Vec3),
    /// Length of the bounds' diagonal, m (at least 1e-30).
    pub extent: f32,
    /// Core BVH build time.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    pub build_time: Duration,
}

impl RayScene {
    /// Builds the BVH over every instance's triangles (including instances that are not
    /// baked: they still cast shadows). Zero-area triangles are kept in
    /// [`RayScene::triangles`] but left out of the BVH.
    ///
    /// The BVH uses obvhs' `very_slow_build` preset without pre-splitting (a split triangle
    /// would sit in several leaves): measured on baker rays through 204 800 triangles it
    /// traces 2.8× (closest hit) and 3.8× (any hit) faster than `medium_build` for a 2.9×
    /// longer build (docs/benchmarks.md).
    pub fn build(scene: &Scene) -> Self {
        let mut triangles = Vec::with_capacity(scene.instanced_triangle_count());
        let mut instance_first_triangle = Vec::with_capacity(scene.instances.len() + 1);
        let mut world_tris: Vec<[Vec3; 3]> = Vec::with_capacity(triangles.capacity());
        for (ii, inst) in scene.instances.iter().enumerate() {
            instance_first_triangle.push(triangles.len() as u32);
            let mesh = &scene.meshes[inst.mesh];
            let double_sided = scene.material_of(inst.mesh).double_sided;
            // A mirroring transform (negative determinant) turns the winding in the world; the
            // front stays the side the mesh's own counter-clockwise winding names (glTF 2.0
            // §3.5.3, "Instantiation").
            let front = inst.transform.matrix3.determinant().signum();
            for t in 0..mesh.triangle_count() {
                let [a, b, c] = mesh.triangle(t);
                let p = [a, b, c].map(|i| inst.transform.transform_point3(mesh.positions[i]));
                let cross = (p[1] - p[0]).cross(p[2] - p[0]);
                let len = cross.length();
                triangles.push(TriangleInfo {
                    instance: ii as u32,
                    local: t as u32,
                    normal: if len > 0.0 {
                        front * cross / len
                    } else {
                        Vec3::Y
                    },
                    area: 0.5 * len,
                    double_sided,
                });
                world_tris.push(p);
            }
        }
        instance_first_triangle.push(triangles.len() as u32);

        let (lo, hi) = world_tris.iter().flatten().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let bounds = if lo.x <= hi.x {
            (lo, hi)
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        };
        let extent = (bounds.1 - bounds.0).length().max(1e-30);

        // Only triangles with area go into the BVH.
        let live: Vec<u32> = (0..triangles.len() as u32)
            .filter(|&i| triangles[i as usize].area > 0.0)
            .collect();
        // Primitive k of the tree is live triangle k; its leaf lane holds its global index, so
        // a hit names its triangle without a lookup (`u32::MAX` marks padding lanes).
        assert!(
            triangles.len() < u32::MAX as usize,
            "more than 2³² − 1 triangles for the BVH"
        );
        let live_tris: Vec<[Vec3; 3]> = live.iter().map(|&g| world_tris[g as usize]).collect();
        drop(world_tris);
        let live_count = live.len();
        let obvhs_tris: Vec<obvhs::triangle::Triangle> = live_tris
            .iter()
            .map(|p| obvhs::triangle::Triangle {
                v0: p[0].into(),
                v1: p[1].into(),
                v2: p[2].into(),
            })
            .collect();
        let params = BvhBuildParams::very_slow_build();
        let start = std::time::Instant::now();
        let mut bvh2 = PlocBuilder::with_capacity(obvhs_tris.len()).build(
            params.ploc_search_distance,
            &obvhs_tris,
            (0..obvhs_tris.len() as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
        drop(obvhs_tris);
        let bvh = Bvh8::collapse(&bvh2, &live_tris, &live);
        let build_time = start.elapsed();
        drop(bvh2);
        let mut accel = vec![[Vec3::ZERO; 3]; triangles.len()];
        for (&g, tri) in live.iter().zip(live_tris) {
            accel[g as usize] = tri;
        }
        Self {
            bvh,
            accel,
            live_count,
            triangles,
            instance_first_triangle,
            bounds,
            extent,
            build_time,
        }
    }

    /// World vertices of global triangle `g` (zero for zero-area triangles, which are not in
    /// the BVH).
    pub fn triangle_vertices(&self, g: u32) -> [Vec3; 3] {
        self.accel
            .get(g as usize)
            .copied()
            .unwrap_or([Vec3::ZERO; 3])
    }

    /// Eight-wide nodes, leaf packets and bytes of the BVH.
    pub fn bvh_size(&self) -> (usize, usize, usize) {
        let (nodes, packets) = self.bvh.sizes();
        (nodes, packets, self.bvh.bytes())
    }

    /// Whether rays are traced with AVX2 (this CPU has it) rather than SSE; both give the
    /// same bits.
    pub fn traces_with_avx2(&self) -> bool {
        self.bvh.uses_avx2()
    }

    /// Number of triangles in the BVH (zero-area ones excluded).
    pub fn bvh_triangle_count(&self) -> usize {
        self.live_count
    }

    /// Distance to push a ray origin at `p` off its surface: 1e-6 of the scene extent plus
    /// 16 float spacings of the largest coordinate of `p`.
    #[inline]
    pub fn epsilon(&self, p: Vec3) -> f32 {
        self.extent * 1e-6 + p.abs().max_element() * (16.0 * f32::EPSILON)
    }

    /// A ray length that leaves the scene from anywhere in it (4 extents and a metre): the end
    /// of shadow rays towards the sun and the sky.
    #[inline]
    pub fn escape_distance(&self) -> f32 {
        self.extent * 4.0 + 1.0
    }

    /// `p` moved off its surface along unit geometric normal `n` (use −n to leave from the back).
    #[inline]
    pub fn offset(&self, p: Vec3, n: Vec3) -> Vec3 {
        p + n * self.epsilon(p)
    }

    /// The closest hit along `dir` (unit) from `origin` with t in [tmin, tmax].
    #[inline]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let mut ray = Ray4::new(origin, dir, tmin, tmax);
        let hit = self.bvh.closest_hit(&mut ray)?;
        let normal = self.triangles[hit.tag as usize].normal;
        Some(Hit {
            t: hit.t,
            triangle: hit.tag,
            u: hit.u,
            v: hit.v,
            front_face: normal.dot(dir) < 0.0,
        })
    }

    /// Whether anything blocks the segment from `origin` along unit `dir` for t in [tmin, tmax].
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        if tmax <= tmin {
            return false;
        }
        self.bvh.occluded(&mut Ray4::new(origin, dir, tmin, tmax))
    }

    /// Whether a triangle (its world vertices) that `accept` takes comes within `radius` of
    /// `center` (m): a query of the BVH's boxes against the ball, then the exact distance.
    pub fn any_triangle_within(
        &self,
        center: Vec3,
        radius: f32,
        mut accept: impl FnMut(&[Vec3; 3]) -> bool,
    ) -> bool {
        self.bvh.any_in_ball(center, radius, |tag| {
            let t = &self.accel[tag as usize];
            accept(t)
                && closest_on_triangle(center, *t).0.distance_squared(center) <= radius * radius
        })
    }

    /// Reference implementation of [`RayScene::closest_hit`]: tests every triangle. For tests.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    pub fn closest_hit_brute_force(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let shear = watertight::Shear::new(dir);
        for (g, tri) in self.accel.iter().enumerate() {
            if self.triangles[g].area <= 0.0 {
                continue;
            }
            let limit = best.map_or(tmax, |b| b.t);
            if let Some((t, u, v)) = watertight::intersect(tri, origin, &shear, tmin, limit)
                && best.is_none_or(|b| t < b.t)
            {
                let triangle = g as u32;
                best = Some(Hit {
                    t,
                    triangle,
                    u,
                    v,
                    front_face: self.triangles[g].normal.dot(dir) < 0.0,
                });
            }
        }
        best
    }

    /// Checks the BVH's invariants (every primitive in exactly one leaf, node boxes contain
    /// their subtrees, the traversal stack bound holds) and the index maps.
    ///
    /// # Panics
    /// When an invariant is broken.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
    pub fn validate(&self) {
        let tags: Vec<u32> = self
            .triangles
            .iter()
            .enumerate()
            .filter(|(_, info)| info.area > 0.0)
            .map(|(g, _)| g as u32)
            .collect();
        assert_eq!(tags.len(), self.live_count);
        self.bvh.validate(&tags);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{hash_words, sobol_02, unit_float};
    use crate::scene::testscenes::{CornellLight, cornell_box, grid};
    use crate::scene::{Instance, Mesh};
    use glam::Affine3A;

    fn random_scene() -> Scene {
        let mut s = cornell_box(CornellLight::Area);
        // Add a tilted, finely divided grid so there are many small triangles.
        let g = s.add_mesh(Mesh {
            material: Some(0),
            ..grid("grid", 0.3, 24)
        });
        s.instances.push(Instance::new(
            "grid",
            g,
            Affine3A::from_rotation_translation(
                glam::Quat::from_rotation_x(0.7),
                Vec3::new(0.05, 0.25, 0.0),
            ),
        ));
        // And a mirrored copy: its front is the side its own winding names.
        s.instances.push(Instance::new(
            "mirrored grid",
            g,
            Affine3A::from_scale_rotation_translation(
                Vec3::new(-1.0, 1.0, 1.0),
                glam::Quat::from_rotation_x(-0.9),
                Vec3::new(-0.1, 0.35, 0.1),
            ),
        ));
        s
    }

    #[test]
    fn triangles_within_a_ball_agree_with_brute_force() {
        let s = random_scene();
        let rs = RayScene::build(&s);
        let (lo, hi) = rs.bounds;
        let (mut found, mut empty) = (0, 0);
        for i in 0..3000u32 {
            let r = |k: u32| unit_float(hash_words(&[i, k, 9]));
            let center = lo + (hi - lo) * Vec3::new(r(0), r(1), r(2));
            let radius = 0.002 + 0.05 * r(3);
            // Accept only triangles facing up, to check that the filter is applied.
            let up = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).y > 0.0;
            let fast = rs.any_triangle_within(center, radius, up);
            let slow = rs.accel.iter().any(|t| {
                up(t)
                    && closest_on_triangle(center, *t).0.distance_squared(center) <= radius * radius
            });
            assert_eq!(fast, slow, "ball {i}: {center} radius {radius}");
            if fast {
                found += 1;
            } else {
                empty += 1;
            }
        }
        assert!(found > 200 && empty > 200, "{found} found, {empty} empty");
    }

    #[test]
    fn closest_and_any_hit_agree_with_brute_force() {
        let s = random_scene();
        let rs = RayScene::build(&s);
        rs.validate();
        let (lo, hi) = rs.bounds;
        let (mut hits, mut mirrored_hits) = (0, 0);
        for i in 0..4000u32 {
            let r = |k: u32| unit_float(hash_words(&[i, k]));
            let origin = lo + (hi - lo) * Vec3::new(r(0), r(1), r(2));
            let u = sobol_02(i, 77);
            let dir = crate::sampling::uniform_cone(Vec3::Y, -1.0, u);
            let tmax = if i % 3 == 0 { 0.2 } else { f32::INFINITY };
            let a = rs.closest_hit(origin, dir, 0.0, tmax);
            let b = rs.closest_hit_brute_force(origin, dir, 0.0, tmax);
            match (a, b) {
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert!(
                        (a.t - b.t).abs() <= 1e-6 * a.t.max(1.0),
                        "ray {i}: {a:?} vs {b:?}"
                    );
                    if a.triangle != b.triangle {
                        // Equal distances (shared edges) may pick either triangle.
                        assert!((a.t - b.t).abs() < 1e-6);
                    } else {
                        assert!((a.u - b.u).abs() < 1e-5 && (a.v - b.v).abs() < 1e-5);
                        assert_eq!(a.front_face, b.front_face);
                    }
                    let instance = rs.triangles[a.triangle as usize].instance as usize;
                    mirrored_hits += usize::from(s.instances[instance].name == "mirrored grid");
                }
                (None, None) => {}
                (a, b) => panic!("ray {i}: bvh {a:?} vs brute force {b:?}"),
            }
            assert_eq!(rs.occluded(origin, dir, 0.0, tmax), b.is_some(), "ray {i}");
        }
        assert!(hits > 1000, "{hits} hits");
        assert!(
            mirrored_hits > 20,
            "{mirrored_hits} hits on the mirrored grid"
        );
    }

    /// The AVX2 traversal and the one for any x86-64 run the same operations in the same
    /// order: the same hits to the bit.
    #[test]
    fn the_avx2_traversal_gives_the_portable_bits() {
        let rs = RayScene::build(&random_scene());
        let portable = rs.bvh.clone().without_avx2();
        if !rs.bvh.uses_avx2() {
            eprintln!("this CPU has no AVX2: nothing to compare");
            return;
        }
        let (lo, hi) = rs.bounds;
        let mut hits = 0;
        for i in 0..20_000u32 {
            let r = |k: u32| unit_float(hash_words(&[i, k, 5]));
            let origin = lo + (hi - lo) * Vec3::new(r(0), r(1), r(2));
            let dir = crate::sampling::uniform_cone(Vec3::Y, -1.0, sobol_02(i, 3));
            let tmax = if i % 4 == 0 { 0.3 } else { f32::INFINITY };
            let a = rs.bvh.closest_hit(&mut Ray4::new(origin, dir, 0.0, tmax));
            let b = portable.closest_hit(&mut Ray4::new(origin, dir, 0.0, tmax));
            let bits = |h: Option<packet::Hit4>| {
                h.map(|h| (h.tag, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
            };
            assert_eq!(bits(a), bits(b), "ray {i}");
            hits += usize::from(a.is_some());
            let occluded = |bvh: &Bvh8| bvh.occluded(&mut Ray4::new(origin, dir, 0.0, tmax));
            assert_eq!(occluded(&rs.bvh), occluded(&portable), "ray {i}");
        }
        assert!(hits > 5000, "{hits} hits");
    }

    /// Gather ray 80 818 of the ray benchmark's workload crosses the shared edge of two of
    /// its 204 800 triangles 13 nm inside one of them (docs/benchmarks.md); a
    /// Möller–Trumbore test rejects it against both, and the ray leaves the closed box. With
    /// the watertight test the BVH and the brute force both keep it, and every gather ray of
    /// the workload hits what Embree 4 hits on the same triangles (84 369 of 100 000).
    #[cfg(all(feature = "testscenes", feature = "internals"))]
    #[test]
    fn no_workload_ray_slips_through_a_shared_edge() {
        let (rs, gather, _) = workload::cornell_workload(100_000);
        let r = gather[80_818];
        let bvh = rs.closest_hit(r.origin, r.direction, 0.0, r.tmax);
        let brute = rs.closest_hit_brute_force(r.origin, r.direction, 0.0, r.tmax);
        assert!(bvh.is_some() && brute.is_some(), "{bvh:?} {brute:?}");
        let hits = gather
            .iter()
            .filter(|r| rs.closest_hit(r.origin, r.direction, 0.0, r.tmax).is_some())
            .count();
        assert_eq!(hits, 84_369);
    }

    #[test]
    fn hit_reports_side_and_barycentrics() {
        let mut s = Scene::default();
        let m = s.add_mesh(crate::scene::testscenes::plane("p", 2.0));
        s.instances.push(Instance::new("p", m, Affine3A::IDENTITY));
        let rs = RayScene::build(&s);
        let h = rs
            .closest_hit(Vec3::new(0.2, 1.0, 0.3), Vec3::NEG_Y, 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-6 && h.front_face);
        // Reconstruct the point from the barycentrics.
        let mesh = &s.meshes[0];
        let [a, b, c] = mesh.triangle(rs.triangles[h.triangle as usize].local as usize);
        let p = mesh.positions[a] * (1.0 - h.u - h.v)
            + mesh.positions[b] * h.u
            + mesh.positions[c] * h.v;
        assert!((p - Vec3::new(0.2, 0.0, 0.3)).length() < 1e-5);
        let back = rs
            .closest_hit(Vec3::new(0.2, -1.0, 0.3), Vec3::Y, 0.0, f32::INFINITY)
            .unwrap();
        assert!(!back.front_face);
    }

    #[test]
    fn hits_next_to_the_origin_are_found() {
        // A ray leaving a floor 0.08 mm from a wall, nearly along the floor, hits the wall
        // 0.09 mm away; obvhs' own node test (fixed 1e-4 minimum) culls it.
        let s = crate::scene::testscenes::furnace_box(1.0, 0.5, 1.0);
        let rs = RayScene::build(&s);
        let origin = Vec3::new(0.499_915_7, -0.499_997_3, 0.219_412);
        let dir = Vec3::new(0.960_614_1, 0.230_101_6, 0.155_800_6);
        let bvh = rs.closest_hit(origin, dir, 0.0, f32::INFINITY);
        let brute = rs
            .closest_hit_brute_force(origin, dir, 0.0, f32::INFINITY)
            .unwrap();
        assert_eq!(bvh.map(|h| h.triangle), Some(brute.triangle));
        assert!(brute.t < 1e-4);
        assert!(rs.occluded(origin, dir, 0.0, 1.0));
        // A millimetre-sized box is traced like a metre-sized one.
        let mut tiny = crate::scene::testscenes::furnace_box(0.001, 0.5, 1.0);
        tiny.name = "tiny".into();
        let rs = RayScene::build(&tiny);
        let mut misses = 0;
        for i in 0..2000u32 {
            let u = sobol_02(i, 3);
            let dir = crate::sampling::uniform_cone(Vec3::Y, -1.0, u);
            if rs
                .closest_hit(Vec3::splat(0.0001), dir, 0.0, f32::INFINITY)
                .is_none()
            {
                misses += 1;
            }
        }
        assert_eq!(misses, 0, "rays from inside a closed 1 mm box escaped");
    }

    #[test]
    fn offsets_scale_with_the_scene() {
        let mut small = Scene::default();
        let m = small.add_mesh(crate::scene::testscenes::plane("p", 0.001));
        small
            .instances
            .push(Instance::new("p", m, Affine3A::IDENTITY));
        let mut huge = Scene::default();
        let m = huge.add_mesh(crate::scene::testscenes::plane("p", 10_000.0));
        huge.instances
            .push(Instance::new("p", m, Affine3A::IDENTITY));
        let (a, b) = (RayScene::build(&small), RayScene::build(&huge));
        let (ea, eb) = (a.epsilon(Vec3::ZERO), b.epsilon(Vec3::ZERO));
        assert!(ea < 1e-8 && eb > 1e-3 && eb < 0.1, "{ea} {eb}");
        // A ray leaving the surface at the far corner of the huge plane does not hit it again.
        let p = Vec3::new(4999.0, 0.0, 4999.0);
        let o = b.offset(p, Vec3::Y);
        assert!(!b.occluded(o, Vec3::new(1.0, 0.001, 0.0).normalize(), 0.0, 100.0));
    }
}
