//! A layout that follows an earlier one: every mesh whose geometry and texel request did not
//! change keeps its unwrap (its charts and `TEXCOORD_1` bytes), and every instance of such a
//! mesh that is still in the scene keeps its rectangle on its page (its `uv_rect`), so a
//! game's assets that reference unchanged meshes do not change. Changed and added meshes are
//! unwrapped at the earlier density; their instances are placed in the free space of the
//! earlier pages (first fit, tallest first, keeping the padding, on 4×4 blocks for BC6H
//! pages), and those that fit nowhere are shelf-packed onto new pages. Pages keep their
//! sizes, so no `uv_rect` moves.

use super::pack::shelf_pack;
use super::{
    InstanceRect, Layout, PageSize, UnwrapNotes, requests, unwrap_one, with_xatlas_threads,
};
use crate::error::Result;
use crate::scene::Scene;
use crate::scene::hashes::{InstanceHashes, identities, mesh_geometry};
use crate::settings::BakeSettings;

/// The texels per mesh unit each mesh of `scene` is unwrapped for at `density` texels per
/// metre (its most demanding baked instance's; zero when none is baked).
pub fn mesh_requests(scene: &Scene, density: f32) -> Vec<f32> {
    requests(scene, density)
        .iter()
        .map(|d| d.texels_per_unit)
        .collect()
}

/// The earlier bake's layout and what it was made of.
pub struct Earlier<'a> {
    /// Its layout.
    pub layout: &'a Layout,
    /// Per mesh, the texels per unit its unwrap was made for ([`mesh_requests`]).
    pub requests: &'a [f32],
    /// Per mesh, its geometry's hash.
    pub mesh_geometry: &'a [u64],
    /// Per instance, its hashes (its identity, its mesh's geometry).
    pub instances: &'a [InstanceHashes],
}

/// The layout of `scene` at `density` that keeps `earlier`'s unwraps and rectangles where
/// nothing changed, and notes saying how much was kept and where the rest went.
///
/// # Errors
/// [`crate::BakeError::Unwrap`] when xatlas refuses a changed or added mesh.
pub fn follow(
    scene: &Scene,
    settings: &BakeSettings,
    density: f32,
    earlier: &Earlier<'_>,
) -> Result<(Layout, Vec<String>)> {
    with_xatlas_threads(settings, || follow_on(scene, settings, density, earlier))
}

fn follow_on(
    scene: &Scene,
    settings: &BakeSettings,
    density: f32,
    earlier: &Earlier<'_>,
) -> Result<(Layout, Vec<String>)> {
    let requests = requests(scene, density);
    let geometry: Vec<u64> = scene.meshes.iter().map(mesh_geometry).collect();
    let mut layout = Layout {
        meshes: vec![None; scene.meshes.len()],
        instances: vec![None; scene.instances.len()],
        pages: earlier.layout.pages.clone(),
        warnings: Vec::new(),
    };
    // 1. Meshes: an unchanged mesh at the same request keeps its unwrap.
    let mut reused = vec![false; scene.meshes.len()];
    let mut notes = UnwrapNotes::default();
    for m in 0..scene.meshes.len() {
        let same = |k: usize| {
            earlier.mesh_geometry[k] == geometry[m]
                && earlier.layout.meshes[k].is_some()
                && same_request(earlier.requests[k], requests[m].texels_per_unit)
        };
        // The same mesh when it is still there (meshes of the same geometry may have charts
        // drawn at other scales by the density that follows the light), else any alike.
        let k = (m < earlier.mesh_geometry.len() && same(m))
            .then_some(m)
            .or_else(|| (0..earlier.mesh_geometry.len()).find(|&k| same(k)));
        if let Some(k) = k {
            layout.meshes[m] = earlier.layout.meshes[k].clone();
            reused[m] = true;
        } else {
            layout.meshes[m] = unwrap_one(scene, m, requests[m], settings, &mut notes)?;
        }
    }
    layout.warnings = notes.finish();
    // 2. Instances: one still in the scene, of an unchanged mesh, keeps its rectangle.
    let ids = identities(scene.instances.iter().map(|i| i.name.as_str()));
    let mut free = Pages::new(&layout.pages, settings);
    let mut to_place = Vec::new();
    let mut kept = 0;
    for (i, inst) in scene.instances.iter().enumerate() {
        let Some(unwrap) = layout.meshes[inst.mesh].as_ref().filter(|_| inst.bake) else {
            continue;
        };
        let old = (earlier.instances.iter())
            .position(|h| h.identity == ids[i])
            .filter(|&j| earlier.instances[j].geometry == geometry[inst.mesh] && reused[inst.mesh])
            .and_then(|j| earlier.layout.instances[j])
            .filter(|r| (r.width, r.height) == (unwrap.width, unwrap.height));
        match old {
            Some(rect) if free.take(rect) => {
                layout.instances[i] = Some(rect);
                kept += 1;
            }
            _ => to_place.push((i, unwrap.width, unwrap.height)),
        }
    }
    for rect in layout.instances.iter().flatten() {
        free.pad(*rect);
    }
    // 3. The rest in the free space, tallest first; what fits nowhere onto new pages.
    to_place.sort_by(|a, b| b.2.cmp(&a.2).then(b.1.cmp(&a.1)).then(a.0.cmp(&b.0)));
    let (mut placed, mut left) = (0, Vec::new());
    for (i, w, h) in to_place {
        match free.place(w, h) {
            Some(rect) => {
                layout.instances[i] = Some(rect);
                placed += 1;
            }
            None => left.push((i, w, h)),
        }
    }
    let mut lines = vec![format!(
        "{kept} instance(s) keep their place, {} mesh(es) of {} keep their charts",
        reused.iter().filter(|&&r| r).count(),
        scene.meshes.len()
    )];
    if placed > 0 {
        lines.push(format!(
            "{placed} changed or added instance(s) placed in free space"
        ));
    }
    if !left.is_empty() {
        let first = layout.pages.len() as u32;
        let (rects, pages) = shelf_pack(left.clone(), settings);
        for (i, mut rect) in rects {
            rect.page += first;
            layout.instances[i] = Some(rect);
        }
        lines.push(format!(
            "{} instance(s) found no free space on the {} page(s) and went onto {} new page(s)",
            left.len(),
            first,
            pages.len()
        ));
        layout.pages.extend(pages);
    }
    Ok((layout, lines))
}

/// Whether two texel requests are the same (to rounding).
fn same_request(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-5 * a.abs().max(b.abs())
}

/// The pages' free space: per texel, whether a rectangle (with its padding) holds it.
struct Pages {
    sizes: Vec<PageSize>,
    used: Vec<Vec<bool>>,
    gap: u32,
    block: u32,
}

impl Pages {
    fn new(sizes: &[PageSize], settings: &BakeSettings) -> Self {
        Self {
            sizes: sizes.to_vec(),
            used: (sizes.iter())
                .map(|p| vec![false; p.width as usize * p.height as usize])
                .collect(),
            gap: settings.layout.padding,
            block: if settings.formats.ktx2_bc6h { 4 } else { 1 },
        }
    }

    /// The texels a rectangle at (x, y) of w × h holds with its padding: up to the next
    /// rectangle's start, as the shelf packer spaces them.
    fn extent(&self, w: u32, h: u32) -> (u32, u32) {
        (
            (w + self.gap).next_multiple_of(self.block),
            (h + self.gap).next_multiple_of(self.block),
        )
    }

    /// Whether the area of `page` at (x, y) of `w × h` texels is inside it and free.
    fn is_free(&self, page: usize, (x, y): (u32, u32), (w, h): (u32, u32)) -> bool {
        let size = self.sizes[page];
        if x + w > size.width || y + h > size.height {
            return false;
        }
        let width = size.width as usize;
        (y..y + h).all(|row| {
            let start = row as usize * width;
            !self.used[page][start + x as usize..start + (x + w) as usize]
                .iter()
                .any(|&u| u)
        })
    }

    fn mark(&mut self, page: usize, (x, y): (u32, u32), (w, h): (u32, u32)) {
        let size = self.sizes[page];
        let width = size.width as usize;
        for row in y..(y + h).min(size.height) {
            let start = row as usize * width;
            let end = start + (x + w).min(size.width) as usize;
            self.used[page][start + x as usize..end].fill(true);
        }
    }

    /// Takes `rect` when its own texels are free (its padding is marked by [`Self::pad`]
    /// once every kept rectangle is taken: the earlier layout's rectangles never overlap, but
    /// a packer may have set one inside another's padding — the first fit of an earlier
    /// incremental bake, the density pass's own packing — and it keeps its place).
    fn take(&mut self, rect: InstanceRect) -> bool {
        let page = rect.page as usize;
        let Some(size) = self.sizes.get(page).copied() else {
            return false;
        };
        let own = (rect.width, rect.height);
        if rect.x + rect.width > size.width
            || rect.y + rect.height > size.height
            || !self.is_free(page, (rect.x, rect.y), own)
        {
            return false;
        }
        self.mark(page, (rect.x, rect.y), own);
        true
    }

    /// Marks `rect`'s padding (clipped to the page) as used.
    fn pad(&mut self, rect: InstanceRect) {
        let page = rect.page as usize;
        let Some(size) = self.sizes.get(page).copied() else {
            return;
        };
        let (w, h) = self.extent(rect.width, rect.height);
        let clipped = (
            w.min(size.width - rect.x.min(size.width)),
            h.min(size.height - rect.y.min(size.height)),
        );
        self.mark(page, (rect.x, rect.y), clipped);
    }

    /// The first free place for a `w × h` rectangle with its padding (on blocks for BC6H),
    /// taken.
    fn place(&mut self, w: u32, h: u32) -> Option<InstanceRect> {
        let need = self.extent(w, h);
        for page in 0..self.sizes.len() {
            let size = self.sizes[page];
            if need.0 > size.width || need.1 > size.height {
                continue;
            }
            for y in (0..=size.height - need.1).step_by(self.block as usize) {
                for x in (0..=size.width - need.0).step_by(self.block as usize) {
                    if self.is_free(page, (x, y), need) {
                        self.mark(page, (x, y), need);
                        return Some(InstanceRect {
                            page: page as u32,
                            x,
                            y,
                            width: w,
                            height: h,
                        });
                    }
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(page: u32, x: u32, y: u32, w: u32, h: u32) -> InstanceRect {
        InstanceRect {
            page,
            x,
            y,
            width: w,
            height: h,
        }
    }

    #[test]
    fn free_space_keeps_the_padding_and_the_blocks() {
        let mut s = BakeSettings::preview();
        s.layout.padding = 2;
        let mut pages = Pages::new(
            &[PageSize {
                width: 32,
                height: 16,
            }],
            &s,
        );
        assert!(pages.take(rect(0, 0, 0, 10, 10)));
        assert!(!pages.take(rect(0, 5, 5, 4, 4)), "overlaps");
        // A kept rectangle inside another's padding keeps its place.
        assert!(pages.take(rect(0, 10, 11, 4, 4)));
        pages.pad(rect(0, 0, 0, 10, 10));
        pages.pad(rect(0, 10, 11, 4, 4));
        // Next to them, past their padding.
        let r = pages.place(8, 8).unwrap();
        assert_eq!((r.x, r.y), (12, 0));
        assert!(pages.place(30, 30).is_none(), "larger than the page");
        s.formats.ktx2_bc6h = true;
        let mut blocks = Pages::new(
            &[PageSize {
                width: 32,
                height: 16,
            }],
            &s,
        );
        assert!(blocks.take(rect(0, 0, 0, 9, 9)));
        blocks.pad(rect(0, 0, 0, 9, 9));
        let r = blocks.place(3, 3).unwrap();
        assert_eq!((r.x % 4, r.y % 4), (0, 0));
        assert_eq!(r.x, 12, "past the first rectangle's padding, on a block");
    }
}
