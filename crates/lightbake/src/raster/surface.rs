//! Surface queries: lightmap-space points of instance triangles → world surface points
//! (position, shading and geometric normals), one at a time ([`Surface::point`]) or as an
//! affine map around a texel ([`Surface::frame`]).

use glam::{Mat3, Vec2, Vec3};

use crate::bvh::{RayScene, TriangleInfo};
use crate::scene::{Instance, Mesh, Scene};
use crate::unwrap::Layout;

use super::rasterize::barycentric_2d;

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
        let n_local = mesh.shading_normal(info.local as usize, Vec2::new(u, v));
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
            normal: along(mesh.corner_normals(info.local as usize).map(|n| nm * n)),
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
    #[inline]
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
