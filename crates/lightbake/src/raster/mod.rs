//! Texel patches: every lightmap texel that a triangle touches becomes a patch with a world
//! position, a normal, the world area it covers and the triangle that owns it.
//!
//! 1. [`rasterize`]: conservative rasterisation of each mesh into its lightmap rectangle, the
//!    exact world area of every covered texel and its representative point.
//! 2. [`surface`]: lightmap-space points → world surface points.
//! 3. [`validity`] (after the BVH exists): texels inside or behind geometry are moved out or
//!    marked invalid; texels next to geometry are flagged. `open_plane` answers its short
//!    probes without rays where nothing near can meet them.
//! 4. [`footprint`]: the points of a texel's footprint that the lighting passes sample.
//!
//! [`persist`] writes the patches to bytes and reads them back (for bakes split across
//! processes).

mod covered;
pub mod footprint;
mod open_plane;
pub mod persist;
pub mod rasterize;
pub mod surface;
pub mod validity;
pub use validity::ValidityRays;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::bvh::RayScene;
use crate::sampling::hash_words;
use crate::scene::Scene;
use crate::unwrap::Layout;
pub use footprint::Footprint;
pub use rasterize::{MeshRaster, rasterize_mesh};
pub use surface::{Surface, SurfaceFrame, SurfacePoint};
/// The four texel centres around texel-space point `q` (texel (i, j) has its centre at
/// (i + ½, j + ½), the GPU's convention) with their bilinear weights, unclamped:
/// (column, row, weight) in the order top-left, top-right, bottom-left, bottom-right. The
/// weights sum to 1; corners outside the grid are the caller's to drop or clamp.
#[inline]
pub fn bilinear_corners(q: Vec2) -> [(i64, i64, f32); 4] {
    let (x, y) = (q.x - 0.5, q.y - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (x0, y0) = (x0 as i64, y0 as i64);
    [
        (x0, y0, (1.0 - fx) * (1.0 - fy)),
        (x0 + 1, y0, fx * (1.0 - fy)),
        (x0, y0 + 1, (1.0 - fx) * fy),
        (x0 + 1, y0 + 1, fx * fy),
    ]
}

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
    /// Unit shading normal there (interpolated from the triangle's corner normals,
    /// [`crate::scene::Mesh::corner_normals`], turned to the front side).
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
    /// `VALID`, `NEAR_GEOMETRY`, `MOVED`, `PARTLY_HIDDEN`, `COVERED` bits.
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
    /// The texel's centre is hidden (inside or behind geometry) and its point was moved to
    /// the open part of its footprint, which lights it.
    pub const PARTLY_HIDDEN: u8 = 8;
    /// Geometry lies within a texel along the representative point's normal: the point is in
    /// a gap thinner than a texel (the floor under a rug), and only footprint points in such a
    /// gap too belong to its surface (see [`Patches::sees`]).
    pub const COVERED: u8 = 16;

    /// Whether the patch has its own value.
    pub fn is_valid(&self) -> bool {
        self.flags & Self::VALID != 0
    }

    /// Key for this texel's random numbers, mixed with `seed` and a stream number.
    #[inline]
    pub fn rng(&self, seed: u32, stream: u32) -> u32 {
        hash_words(&[seed, self.key, stream])
    }

    /// The representative point as a surface point (its barycentrics are not tracked: the
    /// point may have been moved off its triangle by the validity pass).
    #[inline]
    pub fn representative(&self) -> SurfacePoint {
        SurfacePoint {
            position: self.position,
            normal: self.normal,
            geometric_normal: self.geometric_normal,
            triangle: self.triangle,
            bary: Vec2::splat(1.0 / 3.0),
        }
    }
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
    /// Patches whose centre is hidden (inside or behind geometry, or in a gap thinner than a
    /// texel) but whose footprint is partly open surface: their point moved to the open part
    /// (counted in `moved` too).
    pub rescued: usize,
    /// Patches marked invalid: no point of their footprint is open surface (*hidden*).
    pub invalid: usize,
    /// Hidden patches found so without searching their footprint: every ray of their
    /// centre's fan saw a back face, and their footprint lies on the centre's side of every
    /// surface (zero for patches read from a file; see [`validity`]).
    pub sealed: usize,
    /// Hidden patches in which a second, independent search of the footprint found open
    /// surface (visible, yet not lit by the bake; see [`validity`]).
    pub visible_unlit: usize,
    /// Rays traced by the validity pass.
    pub rays: u64,
    /// The validity pass's rays by step (zero for patches read from a file).
    pub ray_steps: ValidityRays,
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
        // Sized once: patches and footprints grown by doubling would hold up to twice
        // their bytes, and copy them, at the peak of the bake's memory.
        let (texels, pieces) = scene
            .instances
            .iter()
            .enumerate()
            .filter(|(ii, _)| layout.instances[*ii].is_some())
            .filter_map(|(_, inst)| rasters[inst.mesh].as_ref())
            .fold((0, 0), |(t, p), r| (t + r.texels.len(), p + r.pieces.len()));
        out.patches.reserve_exact(texels);
        out.footprint.reserve_exact(pieces);
        for (ii, inst) in scene.instances.iter().enumerate() {
            let (Some(rect), Some(raster)) = (layout.instances[ii], &rasters[inst.mesh]) else {
                continue;
            };
            let unwrap = layout.meshes[inst.mesh]
                .as_ref()
                .expect("rect implies unwrap");
            let first = rays.instance_first_triangle[ii];
            let built: Vec<Option<Patch>> = raster
                .texels
                .par_iter()
                .map(|t| {
                    let owner = first + t.owner;
                    let sp = surface.point(owner, t.point, 1e-3)?;
                    // World area: texel-space pieces scaled by each triangle's world/texel ratio.
                    let mut area = 0.0f32;
                    let mut owner_ratio = 0.0f32;
                    for &(lt, a) in raster.pieces_of(t) {
                        let ratio = world_per_texel_area(scene, layout, rays, first + lt);
                        area += a * ratio;
                        if lt == t.owner {
                            owner_ratio = ratio;
                        }
                    }
                    Some(Patch {
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
                        footprint_len: t.len,
                        key: hash_words(&[ii as u32, t.x, t.y]),
                    })
                })
                .collect();
            for (t, patch) in raster.texels.iter().zip(built) {
                let Some(mut patch) = patch else {
                    continue;
                };
                patch.footprint_start = out.footprint.len() as u32;
                out.footprint
                    .extend(raster.pieces_of(t).iter().map(|&(lt, _)| first + lt));
                let page = &mut out.page_index[patch.page as usize];
                let w = layout.pages[patch.page as usize].width;
                page[(patch.y * w + patch.x) as usize] = out.patches.len() as u32;
                out.patches.push(patch);
            }
        }
        out
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
    #[cfg_attr(not(feature = "internals"), allow(dead_code))] // for the tests and benchmarks
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
