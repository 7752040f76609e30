//! Texel patches: every lightmap texel that a triangle touches becomes a patch with a world
//! position, a normal, the world area it covers and the triangle that owns it.
//!
//! 1. **Conservative rasterisation** ([`rasterize_mesh`]): each triangle is clipped against
//!    every texel square of its bounding box in lightmap space (Sutherland–Hodgman); any texel
//!    with a non-empty intersection is covered, and the clipped areas give the patch's exact
//!    world area. Done once per mesh and shared by its instances.
//! 2. **Representative point**: the texel centre when a triangle contains it, otherwise the
//!    centroid of the largest clipped piece (inside the triangle *and* the texel).
//! 3. **Validity** ([`Patches::fix_validity`], after the BVH exists): probe rays along the
//!    surface find single-sided back faces within a texel — the sign that the point is inside
//!    or behind geometry (a floor texel under a wall). The point is moved out past the nearest
//!    such face; if most hemisphere probes still see back faces the patch is marked invalid and
//!    later filled from its chart neighbours. Patches with geometry that close are flagged
//!    [`Patch::NEAR_GEOMETRY`], and footprint samples of such patches are only used when they
//!    see the representative point (so a texel straddling a thin wall does not mix in light
//!    from the far side).

use glam::{Mat3, Vec2, Vec3};
use rayon::prelude::*;

use crate::bvh::{RayScene, TriangleInfo};
use crate::sampling::{basis, cosine_hemisphere, hash_words, sobol_02};
use crate::scene::{Instance, Mesh, Scene};
use crate::unwrap::Layout;

/// A lightmap texel treated as a surface patch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// Instance it belongs to.
    pub instance: u32,
    /// Atlas page.
    pub page: u32,
    /// Texel column on the page.
    pub x: u32,
    /// Texel row on the page.
    pub y: u32,
    /// Representative world position (validated: outside solid geometry).
    pub position: Vec3,
    /// Unit shading normal there (interpolated, turned to the front side).
    pub normal: Vec3,
    /// Unit geometric normal of the owning triangle.
    pub geometric_normal: Vec3,
    /// World area covered by the texel, m².
    pub area: f32,
    /// World edge length of a whole texel here, m.
    pub texel_size: f32,
    /// Owning triangle (global index, see [`crate::bvh::TriangleInfo`]).
    pub triangle: u32,
    /// Chart of the owning triangle within its mesh.
    pub chart: u32,
    /// `VALID`, `NEAR_GEOMETRY`, `MOVED` bits.
    pub flags: u8,
    /// First entry of this patch's triangles in [`Patches::footprint`].
    pub footprint_start: u32,
    /// Number of triangles overlapping the texel.
    pub footprint_len: u32,
    /// Hash of (instance, texel within the instance's rectangle): random numbers depend on it,
    /// not on the page position or the patch's index, so repacking does not change them.
    pub key: u32,
}

impl Patch {
    /// The patch sees the scene from outside geometry and gets its own value.
    pub const VALID: u8 = 1;
    /// Geometry lies within about a texel: footprint samples are checked against occlusion.
    pub const NEAR_GEOMETRY: u8 = 2;
    /// The representative point was moved out of geometry.
    pub const MOVED: u8 = 4;

    /// Whether the patch has its own value.
    pub fn is_valid(&self) -> bool {
        self.flags & Self::VALID != 0
    }

    /// Key for this texel's random numbers, mixed with `seed` and a stream number.
    pub fn rng(&self, seed: u32, stream: u32) -> u32 {
        hash_words(&[seed, self.key, stream])
    }
}

/// A point on a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// World position, m.
    pub position: Vec3,
    /// Unit shading normal.
    pub normal: Vec3,
    /// Unit geometric normal.
    pub geometric_normal: Vec3,
    /// Global triangle the point lies on.
    pub triangle: u32,
    /// Barycentric weights of the triangle's second and third vertices.
    pub bary: Vec2,
}

/// One texel of one mesh's rectangle, in mesh-local terms (before instancing).
#[derive(Clone, Debug)]
struct LocalTexel {
    x: u32,
    y: u32,
    /// Local triangles overlapping the texel, with their clipped areas (texel² units).
    triangles: Vec<(u32, f32)>,
    /// Owner triangle and the texel-space point to represent the texel.
    owner: u32,
    point: Vec2,
}

/// The rasterised lightmap of one mesh, shared by its instances.
#[derive(Clone, Debug, Default)]
pub struct MeshRaster {
    texels: Vec<LocalTexel>,
}

/// All patches of a bake.
#[derive(Clone, Debug, Default)]
pub struct Patches {
    /// The patches, grouped by instance, each instance's texels in row-major order.
    pub patches: Vec<Patch>,
    /// Global triangle indices overlapping each patch (see [`Patch::footprint_start`]).
    pub footprint: Vec<u32>,
    /// Per page, `width × height` patch indices (`u32::MAX` where no texel is covered).
    pub page_index: Vec<Vec<u32>>,
    /// Patches whose point was moved out of geometry.
    pub moved: usize,
    /// Patches marked invalid (inside geometry).
    pub invalid: usize,
    /// Rays traced by the validity pass.
    pub rays: u64,
}

/// Area and centroid of the part of triangle `t` inside the unit square at (x, y).
fn clip_to_texel(t: [Vec2; 3], x: f32, y: f32) -> (f32, Vec2) {
    let mut poly: Vec<Vec2> = t.to_vec();
    let planes = [
        (Vec2::X, x),
        (Vec2::NEG_X, -(x + 1.0)),
        (Vec2::Y, y),
        (Vec2::NEG_Y, -(y + 1.0)),
    ];
    for (n, d) in planes {
        if poly.is_empty() {
            break;
        }
        let mut out = Vec::with_capacity(poly.len() + 1);
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            let (da, db) = (n.dot(a) - d, n.dot(b) - d);
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
        poly = out;
    }
    if poly.len() < 3 {
        return (0.0, Vec2::ZERO);
    }
    let (mut area2, mut c) = (0.0f32, Vec2::ZERO);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let cross = a.perp_dot(b);
        area2 += cross;
        c += (a + b) * cross;
    }
    if area2.abs() < 1e-12 {
        return (0.0, Vec2::ZERO);
    }
    (0.5 * area2.abs(), c / (3.0 * area2))
}

/// Barycentric coordinates (of vertices 1 and 2) of `q` in the 2D triangle `t`, if inside
/// (with a tolerance of `tol` in barycentric units).
pub(crate) fn barycentric_2d(t: [Vec2; 3], q: Vec2, tol: f32) -> Option<Vec2> {
    let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], q - t[0]);
    let det = e1.perp_dot(e2);
    if det.abs() < 1e-20 {
        return None;
    }
    let u = d.perp_dot(e2) / det;
    let v = e1.perp_dot(d) / det;
    (u >= -tol && v >= -tol && u + v <= 1.0 + tol).then_some(Vec2::new(u, v))
}

/// Seed of the validity pass's probes (see [`Patches::fix_validity`]).
pub const VALIDITY_SEED: u32 = 0x7a11_d17e;

/// Footprint samples that measure the visible share of a patch near geometry.
const VISIBILITY_SAMPLES: u32 = 16;

/// How far (texels) a texel's representative point is pulled into its triangle.
const INSET: f32 = 0.05;

/// Conservatively rasterises one mesh's triangles in its `width × height` texel rectangle.
pub fn rasterize_mesh(uv1: &[Vec2], indices: &[u32], width: u32, height: u32) -> MeshRaster {
    let scale = Vec2::new(width as f32, height as f32);
    let mut entries: Vec<(u32, u32, f32, Vec2, bool)> = Vec::new(); // texel, tri, area, centroid, centre inside
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        let p = [tri[0], tri[1], tri[2]].map(|i| uv1[i as usize] * scale);
        let twice_area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
        if twice_area.abs() < 1e-12 {
            continue;
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        let (x0, y0) = (lo.x.floor().max(0.0) as u32, lo.y.floor().max(0.0) as u32);
        let x1 = (hi.x.ceil() as u32).min(width);
        let y1 = (hi.y.ceil() as u32).min(height);
        for y in y0..y1 {
            for x in x0..x1 {
                let (area, centroid) = clip_to_texel(p, x as f32, y as f32);
                if area <= 1e-7 {
                    continue;
                }
                let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let inside = barycentric_2d(p, centre, 0.0).is_some();
                entries.push((y * width + x, t as u32, area, centroid, inside));
            }
        }
    }
    entries.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut texels = Vec::new();
    let mut i = 0;
    while i < entries.len() {
        let texel = entries[i].0;
        let mut j = i;
        while j < entries.len() && entries[j].0 == texel {
            j += 1;
        }
        let group = &entries[i..j];
        let (x, y) = (texel % width, texel / width);
        let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        // Owner: the triangle containing the centre, else the largest piece.
        let (owner, point) = match group.iter().find(|e| e.4) {
            Some(e) => (e.1, centre),
            None => {
                let e = group
                    .iter()
                    .max_by(|a, b| a.2.total_cmp(&b.2).then(b.1.cmp(&a.1)))
                    .expect("group is not empty");
                (e.1, e.3)
            }
        };
        // xatlas offsets charts by half a texel, so border texel centres lie exactly on chart
        // edges — on the geometric edge where two walls meet. Evaluated there, half of a
        // gather hemisphere leaks out through the edge. Pull the point a little into its
        // triangle (towards the centroid, at most INSET texels).
        let tri = &indices[3 * owner as usize..3 * owner as usize + 3];
        let centroid = tri.iter().map(|&i| uv1[i as usize] * scale).sum::<Vec2>() / 3.0;
        let to_centroid = centroid - point;
        let point = point + to_centroid * (INSET / to_centroid.length().max(INSET));
        texels.push(LocalTexel {
            x,
            y,
            triangles: group.iter().map(|e| (e.1, e.2)).collect(),
            owner,
            point,
        });
        i = j;
    }
    MeshRaster { texels }
}

/// Maps lightmap-space points of instance triangles to world surface points.
pub struct Surface<'a> {
    scene: &'a Scene,
    layout: &'a Layout,
    rays: &'a RayScene,
    /// Per instance: the matrix that carries mesh normals to world space (computed once; the
    /// lookups are among the hottest code of the transport build).
    normal_matrices: Vec<Mat3>,
}

impl<'a> Surface<'a> {
    /// `scene` must be the unwrapped scene ([`Layout::apply`]).
    pub fn new(scene: &'a Scene, layout: &'a Layout, rays: &'a RayScene) -> Self {
        Self {
            scene,
            layout,
            rays,
            normal_matrices: scene.instances.iter().map(|i| i.normal_matrix()).collect(),
        }
    }

    /// Global triangle `triangle` as the lightmap sees it: its ray-scene record, instance,
    /// mesh, mesh vertex indices and texel-space UVs (`TEXCOORD_1` × the mesh's rectangle).
    /// `None` when its mesh is not unwrapped.
    #[allow(clippy::type_complexity)]
    fn lightmap_triangle(
        &self,
        triangle: u32,
    ) -> Option<(TriangleInfo, &Instance, &Mesh, [usize; 3], [Vec2; 3])> {
        let info = self.rays.triangles[triangle as usize];
        let inst = &self.scene.instances[info.instance as usize];
        let mesh = &self.scene.meshes[inst.mesh];
        let unwrap = self.layout.meshes[inst.mesh].as_ref()?;
        let uv1 = mesh.uv1.as_ref()?;
        let scale = Vec2::new(unwrap.width as f32, unwrap.height as f32);
        let abc = mesh.triangle(info.local as usize);
        Some((info, inst, mesh, abc, abc.map(|k| uv1[k] * scale)))
    }

    /// The world surface point at texel-space point `q` (texel units of the instance's
    /// rectangle) on global triangle `triangle`, if `q` lies inside it (`tol` in barycentric
    /// units; clamped to the triangle when within it).
    pub fn point(&self, triangle: u32, q: Vec2, tol: f32) -> Option<SurfacePoint> {
        let (info, inst, mesh, [a, b, c], t) = self.lightmap_triangle(triangle)?;
        let b2 = barycentric_2d(t, q, tol)?;
        // Clamp into the triangle.
        let (mut u, mut v) = (b2.x.max(0.0), b2.y.max(0.0));
        if u + v > 1.0 {
            let s = u + v;
            u /= s;
            v /= s;
        }
        let w = 1.0 - u - v;
        let local = mesh.positions[a] * w + mesh.positions[b] * u + mesh.positions[c] * v;
        let n_local = mesh.normals[a] * w + mesh.normals[b] * u + mesh.normals[c] * v;
        let position = inst.transform.transform_point3(local);
        let g = info.normal;
        Some(SurfacePoint {
            position,
            normal: front_normal(self.normal_matrices[info.instance as usize] * n_local, g),
            geometric_normal: g,
            triangle,
            bary: Vec2::new(u, v),
        })
    }

    /// The affine map of the surface of global triangle `triangle` around texel-space point `q`
    /// (as in [`Self::point`]): lightmap UVs, barycentrics and positions are all linear over a
    /// triangle, so points near `q` need no barycentric solve. `None` for a degenerate triangle
    /// or one without lightmap UVs.
    pub fn frame(&self, triangle: u32, q: Vec2) -> Option<SurfaceFrame> {
        let (info, inst, mesh, [a, b, c], t) = self.lightmap_triangle(triangle)?;
        let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], q - t[0]);
        let det = e1.perp_dot(e2);
        if det.abs() < 1e-20 {
            return None;
        }
        // Barycentrics (u, v) of q and their gradients in q (the solve of `barycentric_2d`).
        let bary = Vec2::new(d.perp_dot(e2), e1.perp_dot(d)) / det;
        let du = Vec2::new(e2.y, -e2.x) / det;
        let dv = Vec2::new(-e1.y, e1.x) / det;
        let along = |f: [Vec3; 3]| {
            let (f1, f2) = (f[1] - f[0], f[2] - f[0]);
            [
                f[0] + f1 * bary.x + f2 * bary.y,
                f1 * du.x + f2 * dv.x,
                f1 * du.y + f2 * dv.y,
            ]
        };
        let nm = self.normal_matrices[info.instance as usize];
        Some(SurfaceFrame {
            triangle,
            geometric_normal: info.normal,
            position: along([a, b, c].map(|k| inst.transform.transform_point3(mesh.positions[k]))),
            normal: along([a, b, c].map(|k| nm * mesh.normals[k])),
            bary: [bary, Vec2::new(du.x, dv.x), Vec2::new(du.y, dv.y)],
        })
    }
}

/// A shading normal turned to the front of geometric normal `g`: normalised, and reflected
/// about the tangent plane when it points behind it.
fn front_normal(n: Vec3, g: Vec3) -> Vec3 {
    let n = n.normalize_or(g);
    let d = n.dot(g);
    if d < 0.0 {
        (n - 2.0 * d * g).normalize_or(g)
    } else {
        n
    }
}

/// The surface of one triangle around a texel-space point q₀ as an affine map of the offset
/// (see [`Surface::frame`]): each quantity is stored as its value at q₀ and its derivatives
/// along the texel x and y axes.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceFrame {
    triangle: u32,
    geometric_normal: Vec3,
    /// World position, m (value, ∂/∂x, ∂/∂y per texel).
    position: [Vec3; 3],
    /// Interpolated world shading normal before normalisation.
    normal: [Vec3; 3],
    /// Barycentrics of the triangle's second and third vertices.
    bary: [Vec2; 3],
}

impl SurfaceFrame {
    /// Barycentrics at q₀ + `d` (not clamped: outside the triangle they leave [0, 1]).
    pub fn bary_at(&self, d: Vec2) -> Vec2 {
        self.bary[0] + self.bary[1] * d.x + self.bary[2] * d.y
    }

    /// Whether q₀ + `d` lies inside the triangle by at least `margin` in every barycentric.
    pub fn contains(&self, d: Vec2, margin: f32) -> bool {
        let b = self.bary_at(d);
        b.x >= margin && b.y >= margin && 1.0 - b.x - b.y >= margin
    }

    /// Whether the square q₀ ± `half` (texels) lies inside the triangle by at least `margin`
    /// in every barycentric (its four corners do; the triangle is convex).
    pub fn covers(&self, half: f32, margin: f32) -> bool {
        [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
            .iter()
            .all(|&(x, y)| self.contains(Vec2::new(x, y) * half, margin))
    }

    /// The surface point at q₀ + `d` (texels), as [`Surface::point`] gives it for a point
    /// inside the triangle.
    pub fn point(&self, d: Vec2) -> SurfacePoint {
        let g = self.geometric_normal;
        let n = self.normal[0] + self.normal[1] * d.x + self.normal[2] * d.y;
        SurfacePoint {
            position: self.position[0] + self.position[1] * d.x + self.position[2] * d.y,
            normal: front_normal(n, g),
            geometric_normal: g,
            triangle: self.triangle,
            bary: self.bary_at(d),
        }
    }
}

impl Patches {
    /// Builds every baked instance's patches. `scene` is the unwrapped scene.
    pub fn build(scene: &Scene, layout: &Layout, rays: &RayScene) -> Self {
        // Rasterise each mesh once.
        let rasters: Vec<Option<MeshRaster>> = layout
            .meshes
            .par_iter()
            .enumerate()
            .map(|(m, u)| {
                u.as_ref().map(|u| {
                    let uv1 = scene.meshes[m]
                        .uv1
                        .as_deref()
                        .expect("unwrapped meshes have uv1");
                    rasterize_mesh(uv1, &scene.meshes[m].indices, u.width, u.height)
                })
            })
            .collect();
        let surface = Surface::new(scene, layout, rays);
        let mut out = Patches {
            page_index: layout
                .pages
                .iter()
                .map(|p| vec![u32::MAX; (p.width * p.height) as usize])
                .collect(),
            ..Patches::default()
        };
        for (ii, inst) in scene.instances.iter().enumerate() {
            let (Some(rect), Some(raster)) = (layout.instances[ii], &rasters[inst.mesh]) else {
                continue;
            };
            let unwrap = layout.meshes[inst.mesh]
                .as_ref()
                .expect("rect implies unwrap");
            let first = rays.instance_first_triangle[ii];
            let built: Vec<(Patch, Vec<u32>)> = raster
                .texels
                .par_iter()
                .filter_map(|t| {
                    let owner = first + t.owner;
                    let sp = surface.point(owner, t.point, 1e-3)?;
                    // World area: texel-space pieces scaled by each triangle's world/texel ratio.
                    let mut area = 0.0f32;
                    let mut owner_ratio = 0.0f32;
                    for &(lt, a) in &t.triangles {
                        let ratio = world_per_texel_area(scene, layout, rays, first + lt);
                        area += a * ratio;
                        if lt == t.owner {
                            owner_ratio = ratio;
                        }
                    }
                    let patch = Patch {
                        instance: ii as u32,
                        page: rect.page,
                        x: rect.x + t.x,
                        y: rect.y + t.y,
                        position: sp.position,
                        normal: sp.normal,
                        geometric_normal: sp.geometric_normal,
                        area,
                        texel_size: owner_ratio.sqrt(),
                        triangle: owner,
                        chart: unwrap.triangle_charts[t.owner as usize],
                        flags: Patch::VALID,
                        footprint_start: 0,
                        footprint_len: t.triangles.len() as u32,
                        key: hash_words(&[ii as u32, t.x, t.y]),
                    };
                    Some((
                        patch,
                        t.triangles.iter().map(|&(lt, _)| first + lt).collect(),
                    ))
                })
                .collect();
            for (mut patch, tris) in built {
                patch.footprint_start = out.footprint.len() as u32;
                out.footprint.extend(tris);
                let page = &mut out.page_index[patch.page as usize];
                let w = layout.pages[patch.page as usize].width;
                page[(patch.y * w + patch.x) as usize] = out.patches.len() as u32;
                out.patches.push(patch);
            }
        }
        out
    }

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

    /// The footprint triangles of a patch.
    pub fn footprint_of(&self, p: &Patch) -> &[u32] {
        &self.footprint[p.footprint_start as usize..(p.footprint_start + p.footprint_len) as usize]
    }

    /// Checks the invariants: every patch indexed on its page, texels of different charts or
    /// instances at least `padding` texels apart (Chebyshev distance > padding), areas finite
    /// and positive.
    ///
    /// # Errors
    /// A description of the first violation.
    pub fn validate(&self, layout: &Layout, padding: u32) -> Result<(), String> {
        for (i, p) in self.patches.iter().enumerate() {
            let w = layout.pages[p.page as usize].width;
            if self.page_index[p.page as usize][(p.y * w + p.x) as usize] != i as u32 {
                return Err(format!("patch {i} at ({}, {}) is not indexed", p.x, p.y));
            }
            if !(p.area.is_finite() && p.area > 0.0 && p.position.is_finite()) {
                return Err(format!(
                    "patch {i} has area {} position {:?}",
                    p.area, p.position
                ));
            }
        }
        let r = padding as i64;
        for (pi, page) in layout.pages.iter().enumerate() {
            let index = &self.page_index[pi];
            let (w, h) = (page.width as i64, page.height as i64);
            for y in 0..h {
                for x in 0..w {
                    let a = index[(y * w + x) as usize];
                    if a == u32::MAX {
                        continue;
                    }
                    let pa = &self.patches[a as usize];
                    for dy in -r..=r {
                        for dx in -r..=r {
                            let (nx, ny) = (x + dx, y + dy);
                            if nx < 0 || ny < 0 || nx >= w || ny >= h {
                                continue;
                            }
                            let b = index[(ny * w + nx) as usize];
                            if b == u32::MAX {
                                continue;
                            }
                            let pb = &self.patches[b as usize];
                            if pa.instance != pb.instance || pa.chart != pb.chart {
                                return Err(format!(
                                    "page {pi}: texel ({x}, {y}) (instance {} chart {}) is within {padding} texels of ({nx}, {ny}) (instance {} chart {})",
                                    pa.instance, pa.chart, pb.instance, pb.chart
                                ));
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// World m² per texel² on a global triangle.
fn world_per_texel_area(scene: &Scene, layout: &Layout, rays: &RayScene, triangle: u32) -> f32 {
    let info = rays.triangles[triangle as usize];
    let inst = &scene.instances[info.instance as usize];
    let mesh = &scene.meshes[inst.mesh];
    let Some(unwrap) = layout.meshes[inst.mesh].as_ref() else {
        return 0.0;
    };
    let uv1 = mesh.uv1.as_ref().expect("unwrapped");
    let scale = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let [a, b, c] = mesh.triangle(info.local as usize);
    let (pa, pb, pc) = (uv1[a] * scale, uv1[b] * scale, uv1[c] * scale);
    let texel_area = 0.5 * (pb - pa).perp_dot(pc - pa).abs();
    if texel_area <= 0.0 {
        0.0
    } else {
        info.area / texel_area
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_gives_exact_areas() {
        // A right triangle covering half of a 2×2 block.
        let t = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(0.0, 2.0),
        ];
        let total: f32 = (0..2)
            .flat_map(|y| (0..2).map(move |x| (x, y)))
            .map(|(x, y)| clip_to_texel(t, x as f32, y as f32).0)
            .sum();
        assert!((total - 2.0).abs() < 1e-6);
        assert!((clip_to_texel(t, 0.0, 0.0).0 - 1.0).abs() < 1e-6);
        assert!((clip_to_texel(t, 1.0, 0.0).0 - 0.5).abs() < 1e-6);
        assert_eq!(clip_to_texel(t, 1.0, 1.0).0, 0.0);
    }

    #[test]
    fn conservative_raster_covers_touched_texels() {
        // A thin sliver crossing texels without covering any centre.
        let uv = [
            Vec2::new(0.1, 0.1),
            Vec2::new(0.9, 0.12),
            Vec2::new(0.1, 0.11),
        ];
        let r = rasterize_mesh(&uv, &[0, 1, 2], 8, 8);
        assert!(r.texels.len() >= 7, "{}", r.texels.len());
        for t in &r.texels {
            assert!(t.triangles[0].1 > 0.0);
            // The representative point is inside the texel.
            assert!(t.point.x >= t.x as f32 - 1e-4 && t.point.x <= (t.x + 1) as f32 + 1e-4);
        }
    }
}
