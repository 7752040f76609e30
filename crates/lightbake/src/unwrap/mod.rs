//! Lightmap UVs and the atlas layout.
//!
//! Each mesh gets its own lightmap rectangle of `width × height` texels, with `TEXCOORD_1` in
//! [0, 1]² spanning it: xatlas segments, parameterises and packs its charts (with `padding`
//! texels between them; for BC6H pages they are packed again on 4×4 blocks of their own,
//! [`block_pack`]), or the mesh's own `TEXCOORD_1` is kept after validation (for BC6H pages
//! its charts moved by whole texels onto blocks of their own, [`block_pack::onto_blocks`]).
//! Every baked *instance* of the mesh then gets a copy of that rectangle on an atlas page;
//! Bevy's `Lightmap::uv_rect` maps the mesh's [0, 1]² onto it, so one `TEXCOORD_1` serves
//! every instance. Rectangles are shelf-packed into pages of at most `max_page_size` texels, with
//! `padding` texels between them.
//!
//! Texel conventions (Bevy's and glTF's): texel (x, y) covers [x, x+1] × [y, y+1] in texel
//! units; its centre is at uv ((x + ½)/W, (y + ½)/H); v grows downwards in the image.

mod atlas;
mod block_pack;
mod existing;
mod items;
mod pack;
mod pieces;
mod rescale;
mod squashed;
pub mod stable;
pub mod xatlas;

use atlas::xatlas_unwrap;
use existing::existing_uvs;
#[cfg(any(test, feature = "internals"))]
pub use existing::overlapping_texels;
use pack::pack_instances;

use glam::{Vec2, Vec3};
use serde::Serialize;

use crate::error::Result;
use crate::scene::{Mesh, Scene};
use crate::settings::BakeSettings;

/// Where a mesh's lightmap UVs came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UvOrigin {
    /// Unwrapped by lightbake: xatlas, with a big mesh's planar regions charted directly
    /// and the rest given to xatlas in pieces (`unwrap::pieces`).
    Xatlas,
    /// The mesh's own `TEXCOORD_1`, validated and kept (for BC6H pages its charts moved by
    /// whole texels onto 4×4 blocks: then `xref` is set).
    Existing,
}

/// The lightmap parameterisation of one mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshUnwrap {
    /// Texels across the mesh's rectangle.
    pub width: u32,
    /// Texels down the mesh's rectangle.
    pub height: u32,
    /// `TEXCOORD_1` of every output vertex, in [0, 1]².
    pub uv1: Vec<Vec2>,
    /// Output vertex → source vertex, when xatlas split vertices along chart seams
    /// (`None`: the vertices are the source's).
    pub xref: Option<Vec<u32>>,
    /// Output triangle list; triangle t is source triangle t.
    pub indices: Vec<u32>,
    /// Chart of each triangle (`u32::MAX` for degenerate triangles xatlas ignored).
    pub triangle_charts: Vec<u32>,
    /// Number of charts.
    pub chart_count: u32,
    /// xatlas or the mesh's own UVs.
    pub origin: UvOrigin,
    /// Texels per metre on the mesh's largest baked instance.
    pub texels_per_metre: f32,
    /// The requested density was lowered so the mesh fits on one page.
    pub scaled_to_fit: bool,
}

impl MeshUnwrap {
    /// Texel area of each chart (texels², the triangles' areas in the rectangle).
    pub fn chart_texels(&self) -> Vec<f64> {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let mut out = vec![0.0; self.chart_count as usize];
        for (t, &c) in self.triangle_charts.iter().enumerate() {
            let [a, b, d] = [0, 1, 2].map(|k| self.uv1[self.indices[3 * t + k] as usize] * size);
            if let Some(x) = out.get_mut(c as usize) {
                *x += 0.5 * (b - a).perp_dot(d - a).abs() as f64;
            }
        }
        out
    }

    /// Texels across and down each chart's bounding box in the rectangle (zero for a chart
    /// with no triangle).
    pub fn chart_extents(&self) -> Vec<Vec2> {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let empty = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        let mut bounds = vec![empty; self.chart_count as usize];
        for (t, &c) in self.triangle_charts.iter().enumerate() {
            if let Some(b) = bounds.get_mut(c as usize) {
                for k in 0..3 {
                    let p = self.uv1[self.indices[3 * t + k] as usize] * size;
                    *b = (b.0.min(p), b.1.max(p));
                }
            }
        }
        bounds
            .iter()
            .map(|(lo, hi)| (*hi - *lo).max(Vec2::ZERO))
            .collect()
    }

    /// The mesh with its vertices split as the unwrap requires and `uv1` set.
    pub fn apply(&self, mesh: &Mesh) -> Mesh {
        let Some(xref) = &self.xref else {
            return Mesh {
                uv1: Some(self.uv1.clone()),
                indices: self.indices.clone(),
                ..mesh.clone()
            };
        };
        let gather3 = |v: &[Vec3]| xref.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
        let gather2 = |v: &[Vec2]| xref.iter().map(|&i| v[i as usize]).collect::<Vec<_>>();
        Mesh {
            name: mesh.name.clone(),
            positions: gather3(&mesh.positions),
            normals: gather3(&mesh.normals),
            uv0: mesh.uv0.as_deref().map(gather2),
            uv1: Some(self.uv1.clone()),
            indices: self.indices.clone(),
            material: mesh.material,
            source: mesh.source,
        }
    }
}

/// Where one instance's lightmap lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct InstanceRect {
    /// Atlas page.
    pub page: u32,
    /// Left texel of the rectangle.
    pub x: u32,
    /// Top texel of the rectangle.
    pub y: u32,
    /// Width in texels (the mesh's).
    pub width: u32,
    /// Height in texels (the mesh's).
    pub height: u32,
}

/// Size of an atlas page in texels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct PageSize {
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
}

impl InstanceRect {
    /// Bevy's `Lightmap::uv_rect` (min u, min v, max u, max v) on a page of the given size.
    pub fn uv_rect(&self, page: PageSize) -> [f32; 4] {
        [
            self.x as f32 / page.width as f32,
            self.y as f32 / page.height as f32,
            (self.x + self.width) as f32 / page.width as f32,
            (self.y + self.height) as f32 / page.height as f32,
        ]
    }
}

/// The whole scene's lightmap layout.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Layout {
    /// Per scene mesh: its unwrap, or `None` when no instance of it is baked.
    pub meshes: Vec<Option<MeshUnwrap>>,
    /// Per scene instance: its rectangle, or `None` when it is not baked.
    pub instances: Vec<Option<InstanceRect>>,
    /// Atlas pages.
    pub pages: Vec<PageSize>,
    /// Messages about repairs and compromises (invalid UVs replaced, density lowered).
    pub warnings: Vec<String>,
}

impl Layout {
    /// The scene with every unwrapped mesh replaced by its split, `TEXCOORD_1`-carrying version.
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut out = scene.clone();
        for (m, unwrap) in self.meshes.iter().enumerate() {
            if let Some(u) = unwrap {
                out.meshes[m] = u.apply(&scene.meshes[m]);
            }
        }
        out
    }

    /// The layout with the charts of each mesh that has `scales[m]` drawn at those scales
    /// (one per chart, on its texels per metre per axis; see `unwrap::rescale`) and every instance
    /// packed again. Meshes that keep their own `TEXCOORD_1`, or whose scaled charts fit no
    /// page, keep their unwrap (a warning names the latter).
    pub fn with_chart_scales(
        &self,
        scene: &Scene,
        settings: &BakeSettings,
        scales: &[Option<Vec<f32>>],
    ) -> Layout {
        let mut out = Layout {
            meshes: self.meshes.clone(),
            instances: vec![None; self.instances.len()],
            pages: Vec::new(),
            warnings: self.warnings.clone(),
        };
        for (m, s) in scales.iter().enumerate() {
            let (Some(s), Some(Some(u))) = (s, self.meshes.get(m)) else {
                continue;
            };
            match rescale::rescale_charts(&scene.meshes[m], u, s, settings) {
                Some(r) => out.meshes[m] = Some(r),
                None if u.origin == UvOrigin::Xatlas => out.warnings.push(format!(
                    "mesh '{}': its charts at their own densities fit no {}² page; kept at one density",
                    scene.meshes[m].name, settings.layout.max_page_size
                )),
                None => {}
            }
        }
        pack_instances(scene, settings, &mut out);
        out
    }

    /// Total texels over all pages.
    pub fn page_texels(&self) -> u64 {
        self.pages
            .iter()
            .map(|p| p.width as u64 * p.height as u64)
            .sum()
    }

    /// Checks the layout: UVs in [0, 1], rectangles inside their pages and not overlapping.
    ///
    /// # Errors
    /// [`BadLayout`]: the first violation.
    pub fn validate(&self) -> std::result::Result<(), BadLayout> {
        for (m, u) in self.meshes.iter().enumerate() {
            let Some(u) = u else { continue };
            if let Some(bad) = u
                .uv1
                .iter()
                .position(|p| !(p.min_element() >= 0.0 && p.max_element() <= 1.0))
            {
                return Err(BadLayout::UvOutside {
                    mesh: m,
                    index: bad,
                    uv: u.uv1[bad],
                });
            }
            if u.triangle_charts.len() * 3 != u.indices.len() {
                return Err(BadLayout::Charts { mesh: m });
            }
        }
        let rects: Vec<(usize, InstanceRect)> = self
            .instances
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.map(|r| (i, r)))
            .collect();
        for &(i, r) in &rects {
            let page = self.pages.get(r.page as usize).ok_or(BadLayout::NoPage {
                instance: i,
                page: r.page,
            })?;
            if r.x + r.width > page.width || r.y + r.height > page.height {
                return Err(BadLayout::OffPage {
                    instance: i,
                    rect: r,
                });
            }
        }
        for (a, &(i, ra)) in rects.iter().enumerate() {
            for &(j, rb) in &rects[a + 1..] {
                let disjoint = ra.page != rb.page
                    || ra.x + ra.width <= rb.x
                    || rb.x + rb.width <= ra.x
                    || ra.y + ra.height <= rb.y
                    || rb.y + rb.height <= ra.y;
                if !disjoint {
                    return Err(BadLayout::Overlap {
                        instances: [i, j],
                        rects: [ra, rb],
                    });
                }
            }
        }
        Ok(())
    }
}

/// What [`Layout::validate`] found wrong with a layout.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BadLayout {
    /// A lightmap UV outside [0, 1].
    #[error("mesh {mesh}: lightmap UV {index} = {uv} is outside [0, 1]")]
    UvOutside {
        /// The mesh.
        mesh: usize,
        /// The vertex.
        index: usize,
        /// Its UV.
        uv: Vec2,
    },
    /// The per-triangle chart list does not have one entry per triangle.
    #[error("mesh {mesh}: its chart list does not match its triangles")]
    Charts {
        /// The mesh.
        mesh: usize,
    },
    /// An instance's rectangle names a page the layout does not have.
    #[error("instance {instance}: page {page} does not exist")]
    NoPage {
        /// The instance.
        instance: usize,
        /// The page it names.
        page: u32,
    },
    /// An instance's rectangle reaches past its page's edge.
    #[error("instance {instance}: its rectangle {rect:?} leaves its page")]
    OffPage {
        /// The instance.
        instance: usize,
        /// Its rectangle, texels.
        rect: InstanceRect,
    },
    /// Two instances' rectangles overlap.
    #[error("instances {} and {} overlap: {:?} / {:?}", instances[0], instances[1], rects[0], rects[1])]
    Overlap {
        /// The two instances.
        instances: [usize; 2],
        /// Their rectangles, texels.
        rects: [InstanceRect; 2],
    },
}

/// World-area scale of `mesh` under an instance transform: sqrt(world area / local area).
fn area_scale(mesh: &Mesh, transform: &glam::Affine3A) -> f32 {
    let (mut local, mut world) = (0.0f64, 0.0f64);
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let p = [mesh.positions[a], mesh.positions[b], mesh.positions[c]];
        local += (p[1] - p[0]).cross(p[2] - p[0]).length() as f64;
        let w = p.map(|q| transform.transform_point3(q));
        world += (w[1] - w[0]).cross(w[2] - w[0]).length() as f64;
    }
    if local > 0.0 {
        (world / local).sqrt() as f32
    } else {
        1.0
    }
}

/// Unwraps (or validates) every baked mesh and packs every baked instance onto pages.
///
/// `density` is the texel density in texels per metre (the settings' or the scene's hint).
///
/// # Errors
/// [`BakeError::Unwrap`] when xatlas refuses a mesh.
pub fn unwrap_scene(scene: &Scene, settings: &BakeSettings, density: f32) -> Result<Layout> {
    with_xatlas_threads(settings, || unwrap_meshes(scene, settings, density))
}

/// Runs `f` with xatlas' workers kept to the bake's thread count.
fn with_xatlas_threads<T>(settings: &BakeSettings, f: impl FnOnce() -> T) -> T {
    let threads = match settings.threads {
        0 => 0,
        n => n.min(std::thread::available_parallelism().map_or(1, |c| c.get())),
    };
    xatlas::with_thread_limit(threads, f)
}

fn unwrap_meshes(scene: &Scene, settings: &BakeSettings, density: f32) -> Result<Layout> {
    let mut layout = Layout {
        meshes: vec![None; scene.meshes.len()],
        instances: vec![None; scene.instances.len()],
        ..Layout::default()
    };
    let requests = requests(scene, density);
    let mut notes = UnwrapNotes::default();
    for m in 0..scene.meshes.len() {
        layout.meshes[m] = unwrap_one(scene, m, requests[m], settings, &mut notes)?;
    }
    layout.warnings = notes.finish();
    pack_instances(scene, settings, &mut layout);
    Ok(layout)
}

/// Texels per mesh unit needed by the most demanding baked instance of each mesh, at
/// `density` texels per metre (zero for a mesh no baked instance uses).
fn requests(scene: &Scene, density: f32) -> Vec<Density> {
    let mut requests = vec![Density::default(); scene.meshes.len()];
    for inst in scene.instances.iter().filter(|i| i.bake) {
        let mesh = &scene.meshes[inst.mesh];
        if mesh.triangle_count() == 0 {
            continue;
        }
        let per_metre = density * inst.texel_density_scale;
        let tpu = per_metre * area_scale(mesh, &inst.transform);
        if tpu > requests[inst.mesh].texels_per_unit {
            requests[inst.mesh] = Density {
                texels_per_unit: tpu,
                texels_per_metre: per_metre,
            };
        }
    }
    requests
}

/// What the unwrap of the meshes gathers for its warnings.
#[derive(Default)]
struct UnwrapNotes {
    warnings: Vec<String>,
    /// Meshes raised to the smallest chart.
    raised: Vec<String>,
    /// Meshes whose own TEXCOORD_1 was moved onto blocks, and their rectangles' texels before
    /// and after.
    moved_own: (usize, u64, u64),
}

impl UnwrapNotes {
    fn finish(mut self) -> Vec<String> {
        if !self.raised.is_empty() {
            let shown: Vec<&str> = self.raised.iter().take(3).map(String::as_str).collect();
            self.warnings.push(format!(
                "{} mesh(es) smaller than two texels at the texel density got the smallest chart instead ({}{})",
                self.raised.len(),
                shown.join(", "),
                if self.raised.len() > 3 { ", …" } else { "" }
            ));
        }
        let (n, before, after) = self.moved_own;
        if after as f64 > OWN_UV_GROWTH_WARNING * before as f64 {
            self.warnings.push(format!(
                "the own TEXCOORD_1 charts of {n} mesh(es) take {:.2}× the texels on 4×4 blocks of their own for BC6H (each chart rounds up to whole blocks with its padding); --reunwrap lets xatlas chart them for blocks",
                after as f64 / before as f64
            ));
        }
        self.warnings
    }
}

/// The lightmap UVs of mesh `m` at `request` (none when no baked instance uses it): its own
/// validated TEXCOORD_1 (moved onto blocks for BC6H pages) or a new unwrap.
fn unwrap_one(
    scene: &Scene,
    m: usize,
    request: Density,
    settings: &BakeSettings,
    notes: &mut UnwrapNotes,
) -> Result<Option<MeshUnwrap>> {
    let mesh = &scene.meshes[m];
    if request.texels_per_unit <= 0.0 || mesh.area() <= 0.0 {
        return Ok(None);
    }
    let mut small = false;
    let keep_existing = !settings.layout.reunwrap && mesh.uv1.is_some();
    let warnings = &mut notes.warnings;
    let unwrap = if keep_existing {
        match existing_uvs(mesh, request, settings) {
            Ok(u) if settings.formats.ktx2_bc6h => {
                let kept = |why: &str| {
                    format!(
                        "mesh '{}': its own TEXCOORD_1 is kept as it is ({why}), so a BC6H block may hold two of its charts",
                        mesh.name
                    )
                };
                if textures_use_set_1(scene, mesh) {
                    let why = "its material's textures are mapped by it";
                    warnings.push(kept(why));
                    u
                } else if let Ok(moved) = block_pack::onto_blocks(mesh, &u, settings) {
                    let area = |u: &MeshUnwrap| u64::from(u.width) * u64::from(u.height);
                    notes.moved_own.0 += 1;
                    notes.moved_own.1 += area(&u);
                    notes.moved_own.2 += area(&moved);
                    moved
                } else {
                    let why = format!(
                        "its charts on their own 4×4 blocks fit no {0}² page",
                        settings.layout.max_page_size
                    );
                    warnings.push(kept(&why));
                    u
                }
            }
            Ok(u) => u,
            Err(problem) => {
                warnings.push(format!(
                    "mesh '{}': its TEXCOORD_1 cannot be used ({problem}); unwrapped again with xatlas",
                    mesh.name
                ));
                unwrap_mesh(mesh, request, settings, warnings, &mut small)?
            }
        }
    } else {
        unwrap_mesh(mesh, request, settings, warnings, &mut small)?
    };
    if small {
        notes.raised.push(mesh.name.clone());
    }
    if unwrap.origin == UvOrigin::Xatlas && mesh.uv1.is_some() && textures_use_set_1(scene, mesh) {
        warnings.push(format!(
            "mesh '{}': its material's textures are mapped by TEXCOORD_1, which the new lightmap UVs replace; the bake, the baked glTF and the plugin's meshes map them by the lightmap UVs",
            mesh.name
        ));
    }
    Ok(Some(unwrap))
}

/// How much larger the meshes' own charts may grow, moved onto BC6H blocks, before a warning
/// suggests `--reunwrap` (the texels of their rectangles, after over before).
const OWN_UV_GROWTH_WARNING: f64 = 1.5;

/// A new unwrap of one mesh: by xatlas, or in pieces when it is big ([`pieces`]). When the
/// unwrap squashes or stretches triangles ([`squashed`]), the mesh is charted again with
/// every flat region projected onto its own plane, and the better of the two is kept (a
/// warning says which and why).
fn unwrap_mesh(
    mesh: &Mesh,
    request: Density,
    settings: &BakeSettings,
    warnings: &mut Vec<String>,
    raised: &mut bool,
) -> Result<MeshUnwrap> {
    // Each attempt's own warnings: only the kept one's are passed on.
    let mut first_notes = Vec::new();
    let first = if mesh.triangle_count() > pieces::BIG_MESH_TRIANGLES {
        let min = pieces::MIN_PLANAR;
        pieces::unwrap_in_pieces(mesh, request, settings, min, &mut first_notes, raised)?
    } else {
        xatlas_unwrap(mesh, request, settings, &mut first_notes, raised)?
    };
    // The density the unwrap reached (lowered to fit a page, or raised for a tiny mesh).
    let asked = request.texels_per_metre.max(f32::MIN_POSITIVE);
    let achieved = |u: &MeshUnwrap| request.texels_per_unit * u.texels_per_metre / asked;
    let first_found = squashed::squashed(mesh, &first, achieved(&first));
    if first_found.count() == 0 {
        warnings.extend(first_notes);
        return Ok(first);
    }
    let mut notes = Vec::new();
    let second = pieces::unwrap_in_pieces(mesh, request, settings, 1, &mut notes, raised)?;
    let second_found = squashed::squashed(mesh, &second, achieved(&second));
    let name = &mesh.name;
    if second_found.count() < first_found.count() {
        warnings.push(format!(
            "mesh '{name}': xatlas gave {}; charted again with each flat region projected onto its plane ({} left)",
            first_found.describe(),
            second_found.count()
        ));
        warnings.extend(notes);
        Ok(second)
    } else {
        warnings.push(format!(
            "mesh '{name}': xatlas gave {}, and charting its flat regions directly does no better ({})",
            first_found.describe(),
            second_found.describe()
        ));
        warnings.extend(first_notes);
        Ok(first)
    }
}

/// Whether a texture of the mesh's material is mapped by `TEXCOORD_1`.
fn textures_use_set_1(scene: &Scene, mesh: &Mesh) -> bool {
    let material = match mesh.material {
        Some(i) => &scene.materials[i],
        None => return false,
    };
    [material.base_color_texture, material.emissive_texture]
        .iter()
        .flatten()
        .any(|t| t.tex_coord == 1)
}

/// What a mesh's most demanding baked instance asks for.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Density {
    /// Texels per mesh-space unit.
    pub(super) texels_per_unit: f32,
    /// Texels per metre on that instance.
    pub(super) texels_per_metre: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Instance;
    use crate::scene::testscenes::{CornellLight, cornell_box, cuboid, plane};
    use glam::Affine3A;

    #[test]
    fn cornell_layout_is_valid() {
        let s = cornell_box(CornellLight::Area);
        let settings = BakeSettings::default();
        let layout = unwrap_scene(&s, &settings, 128.0).unwrap();
        layout.validate().unwrap();
        assert_eq!(layout.pages.len(), 1);
        for (i, inst) in s.instances.iter().enumerate() {
            assert!(layout.instances[i].is_some(), "{}", inst.name);
        }
        // A floor of 0.55 m at 128 texels/m needs about 70 texels across.
        let floor = s.meshes.iter().position(|m| m.name == "floor").unwrap();
        let u = layout.meshes[floor].as_ref().unwrap();
        assert!(u.width >= 60 && u.width <= 90, "{}", u.width);
    }

    #[test]
    fn a_broken_layout_names_what_is_wrong() {
        let s = cornell_box(CornellLight::Area);
        let layout = unwrap_scene(&s, &BakeSettings::default(), 64.0).unwrap();
        let mut overlapping = layout.clone();
        overlapping.instances[1] = overlapping.instances[0];
        assert_eq!(
            overlapping.validate(),
            Err(BadLayout::Overlap {
                instances: [0, 1],
                rects: [layout.instances[0].unwrap(); 2],
            })
        );
        let mut outside = layout.clone();
        let r = outside.instances[2].as_mut().unwrap();
        r.x = outside.pages[0].width;
        let err = outside.validate().unwrap_err();
        assert!(
            matches!(err, BadLayout::OffPage { instance: 2, .. }),
            "{err}"
        );
        assert!(
            err.to_string().starts_with("instance 2: its rectangle"),
            "{err}"
        );
    }

    #[test]
    fn existing_uv1_is_kept_and_overlaps_are_rejected() {
        let mut s = Scene::default();
        let mut m = plane("p", 1.0);
        m.uv1 = m.uv0.clone();
        let id = s.add_mesh(m);
        s.instances.push(Instance::new("p", id, Affine3A::IDENTITY));
        let layout = unwrap_scene(&s, &BakeSettings::default(), 32.0).unwrap();
        let u = layout.meshes[0].as_ref().unwrap();
        assert_eq!(u.origin, UvOrigin::Existing);
        assert_eq!(Some(&u.uv1), s.meshes[0].uv1.as_ref());
        assert!(u.xref.is_none());
        assert_eq!(u.width, 32);

        // Both triangles mapped onto the same UV triangle: overlap → re-unwrapped.
        let mut bad = plane("bad", 1.0);
        bad.uv1 = Some(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0),
        ]);
        s.meshes[0] = bad;
        let layout = unwrap_scene(&s, &BakeSettings::default(), 32.0).unwrap();
        assert_eq!(layout.meshes[0].as_ref().unwrap().origin, UvOrigin::Xatlas);
        assert!(
            layout.warnings[0].contains("TEXCOORD_1"),
            "{:?}",
            layout.warnings
        );
    }

    #[test]
    fn existing_uv1_is_moved_onto_blocks_for_bc6h_unless_textures_use_it() {
        let mut s = Scene::default();
        let mut m = plane("p", 1.0);
        // Its one chart a third of a texel (of 32) in from its rectangle's corner.
        m.uv1 = Some(
            m.uv0
                .clone()
                .unwrap()
                .iter()
                .map(|p| *p * 0.5 + 0.01)
                .collect(),
        );
        let id = s.add_mesh(m);
        s.instances.push(Instance::new("p", id, Affine3A::IDENTITY));
        let mut bc6h = BakeSettings::default();
        bc6h.formats.ktx2_bc6h = true;
        let kept = unwrap_scene(&s, &BakeSettings::default(), 16.0).unwrap();
        let moved = unwrap_scene(&s, &bc6h, 16.0).unwrap();
        let (k, u) = (
            kept.meshes[0].as_ref().unwrap(),
            moved.meshes[0].as_ref().unwrap(),
        );
        assert_eq!(u.origin, UvOrigin::Existing);
        let xref = u.xref.as_ref().expect("moved");
        let texel = |uv: Vec2, w: u32, h: u32| uv * Vec2::new(w as f32, h as f32);
        let shift =
            texel(u.uv1[0], u.width, u.height) - texel(k.uv1[xref[0] as usize], k.width, k.height);
        assert!(
            (shift - shift.round()).abs().max_element() < 1e-4,
            "{shift}"
        );
        for (v, &src) in xref.iter().enumerate() {
            let d =
                texel(u.uv1[v], u.width, u.height) - texel(k.uv1[src as usize], k.width, k.height);
            assert!((d - shift).abs().max_element() < 1e-4, "{d} {shift}");
        }
        assert!(moved.warnings.is_empty(), "{:?}", moved.warnings);
        // A base colour texture mapped by TEXCOORD_1: kept as it is, with a warning.
        s.textures.push(crate::scene::Texture {
            name: "t".into(),
            width: 1,
            height: 1,
            rgba8: vec![[255; 4]],
            wrap_u: crate::scene::Wrap::Repeat,
            wrap_v: crate::scene::Wrap::Repeat,
        });
        let material = s.add_material(crate::scene::Material {
            base_color_texture: Some(crate::scene::TextureRef {
                texture: 0,
                tex_coord: 1,
            }),
            ..crate::scene::Material::diffuse("m", Vec3::ONE)
        });
        s.meshes[0].material = Some(material);
        let textured = unwrap_scene(&s, &bc6h, 16.0).unwrap();
        assert!(textured.meshes[0].as_ref().unwrap().xref.is_none());
        assert!(
            textured.warnings[0].contains("kept as it is"),
            "{:?}",
            textured.warnings
        );
    }

    #[test]
    fn oversized_meshes_are_scaled_to_fit_a_page() {
        let mut s = Scene::default();
        let id = s.add_mesh(cuboid("big", Vec3::ZERO, Vec3::splat(100.0), false));
        s.instances
            .push(Instance::new("big", id, Affine3A::IDENTITY));
        let settings = {
            let mut s = BakeSettings::default();
            s.layout.max_page_size = 256;
            s
        };
        let layout = unwrap_scene(&s, &settings, 32.0).unwrap();
        let u = layout.meshes[0].as_ref().unwrap();
        assert!(u.scaled_to_fit && u.width <= 256 && u.height <= 256);
        assert!(!layout.warnings.is_empty());
        layout.validate().unwrap();
    }

    #[test]
    fn many_instances_spill_onto_more_pages() {
        let mut s = Scene::default();
        let id = s.add_mesh(plane("p", 1.0));
        for i in 0..40 {
            s.instances.push(Instance::new(
                format!("p{i}"),
                id,
                Affine3A::from_translation(Vec3::new(i as f32 * 2.0, 0.0, 0.0)),
            ));
        }
        let settings = {
            let mut s = BakeSettings::default();
            s.layout.max_page_size = 128;
            s
        };
        let layout = unwrap_scene(&s, &settings, 40.0).unwrap();
        layout.validate().unwrap();
        assert!(layout.pages.len() > 1, "{:?}", layout.pages);
        assert!(
            layout
                .pages
                .iter()
                .all(|p| p.width <= 128 && p.height <= 128)
        );
    }
}
