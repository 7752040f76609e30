//! Memory planning: estimate what a bake will allocate before allocating it, and refuse with
//! the estimate in the message when it exceeds `memory_budget_mib`.
//!
//! The per-item costs are the sizes of the structures involved (`size_of`), counted at the
//! bake's peak: while the lighting passes run, with the patches, the pages' index and the
//! ray-tracing structure alive. The radiosity pass adds its own working memory when it plans
//! its solver (`radiosity::plan_solver`: nodes, the hit mapper's grid, the solver's vectors,
//! the matrix or the coarse level), and the plan compares the sum with the peak resident
//! memory in `tests/memory.rs`.

use serde::Serialize;

use crate::error::{BakeError, Result};
use crate::raster::Patch;
use crate::scene::Scene;
use crate::unwrap::{Layout, MeshUnwrap};

/// Bytes per covered texel (patch) through the lighting passes: the patch, its footprint
/// list (two triangles on average), its node index, its direct irradiance and the copy of
/// it the texel grid's check reads after them (`lightmap::grid_error`; the page it
/// assembles from it is built once the passes' working memory is freed).
pub const BYTES_PER_PATCH: u64 = size_of::<Patch>() as u64 + 2 * 4 + 4 + 12 + 12;
/// Bytes per page texel: its patch index, the finished page (RGB f32 and coverage) and its
/// fill state.
pub const BYTES_PER_PAGE_TEXEL: u64 = 4 + 12 + 1 + 1;
/// Bytes per triangle in the ray-tracing structures: triangle data (36) and info (40), the
/// eight-wide BVH's nodes and leaf packets, and the binary builder's temporaries (312, from
/// the peak RSS of a million-triangle bake in `benches/scale.rs`).
pub const BYTES_PER_TRIANGLE: u64 = 36 + 40 + 312;
/// The program itself: code, thread stacks and the allocator's own (the peak resident memory
/// of a bake of a few texels is 14 MiB).
pub const PROGRAM_BYTES: u64 = 16 << 20;

/// An itemised estimate.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct MemoryEstimate {
    /// (item, bytes), largest first.
    pub items: Vec<(String, u64)>,
    /// Sum of the items.
    pub total: u64,
}

impl MemoryEstimate {
    fn from_items(mut items: Vec<(String, u64)>) -> Self {
        items.sort_by_key(|item| std::cmp::Reverse(item.1));
        let total = items.iter().map(|i| i.1).sum();
        Self { items, total }
    }

    /// The estimate with one more item.
    pub fn with(self, item: &str, bytes: u64) -> Self {
        let mut items = self.items;
        items.push((item.to_string(), bytes));
        Self::from_items(items)
    }

    /// Total in MiB.
    pub fn mib(&self) -> f64 {
        self.total as f64 / (1024.0 * 1024.0)
    }

    /// Errors when the estimate exceeds `budget_mib`.
    ///
    /// # Errors
    /// [`BakeError::OverMemoryBudget`] with the estimate and its largest items.
    pub fn check(&self, budget_mib: u64) -> Result<()> {
        let needed = self.mib();
        if needed <= budget_mib as f64 {
            return Ok(());
        }
        let breakdown = self
            .items
            .iter()
            .take(3)
            .map(|(name, b)| format!("{name} {:.0} MiB", *b as f64 / 1048576.0))
            .collect::<Vec<_>>()
            .join(", ");
        Err(BakeError::OverMemoryBudget {
            needed_mib: needed,
            budget_mib: budget_mib as f64,
            breakdown,
        })
    }
}

/// Before unwrapping: texels from the baked world area at `density` (with 1/0.6 for chart
/// packing and padding), pages sized to match: a first guard against a density far too high.
pub fn estimate_from_area(scene: &Scene, density: f32) -> MemoryEstimate {
    let texels: f64 = scene
        .instances
        .iter()
        .enumerate()
        .filter(|(_, inst)| inst.bake)
        .map(|(i, inst)| {
            let d = (density * inst.texel_density_scale) as f64;
            scene.instance_area(i) as f64 * d * d
        })
        .sum();
    let page_texels = texels / 0.6;
    MemoryEstimate::from_items(vec![
        ("program".into(), PROGRAM_BYTES),
        (
            "texel patches".into(),
            (texels * BYTES_PER_PATCH as f64) as u64,
        ),
        (
            "lightmap pages".into(),
            (page_texels * BYTES_PER_PAGE_TEXEL as f64) as u64,
        ),
        (
            "ray tracing".into(),
            scene.instanced_triangle_count() as u64 * BYTES_PER_TRIANGLE,
        ),
    ])
}

/// After unwrapping, from the actual pages and the covered texels each mesh's charts will
/// give ([`covered_texels`]).
pub fn estimate_from_layout(scene: &Scene, layout: &Layout) -> MemoryEstimate {
    let covered: Vec<f64> = layout
        .meshes
        .iter()
        .map(|u| u.as_ref().map_or(0.0, covered_texels))
        .collect();
    let patches: f64 = scene
        .instances
        .iter()
        .enumerate()
        .filter(|(i, _)| layout.instances[*i].is_some())
        .map(|(_, inst)| covered[inst.mesh])
        .sum();
    MemoryEstimate::from_items(vec![
        ("program".into(), PROGRAM_BYTES),
        (
            "texel patches".into(),
            (patches * BYTES_PER_PATCH as f64) as u64,
        ),
        (
            "lightmap pages".into(),
            layout.page_texels() * BYTES_PER_PAGE_TEXEL,
        ),
        (
            "ray tracing".into(),
            scene.instanced_triangle_count() as u64 * BYTES_PER_TRIANGLE,
        ),
    ])
}

/// The texels conservative rasterisation will cover in a mesh's rectangle, estimated from its
/// charts: their area in texels, plus half of each chart border edge's |Δx| + |Δy| in texels
/// (the partly covered texels along it), plus one per chart. Exact for a rectangle at any
/// sub-texel offset ((w + 1)·(h + 1)); charts of a few texels are mostly border.
pub fn covered_texels(unwrap: &MeshUnwrap) -> f64 {
    let scale = glam::Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let mut area = 0.0f64;
    // Edges used by one triangle (xatlas splits vertices along chart seams, so a chart's
    // border is made of them), keyed by their vertex pair.
    let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for tri in unwrap.indices.chunks_exact(3) {
        let p = [tri[0], tri[1], tri[2]].map(|i| unwrap.uv1[i as usize] * scale);
        area += 0.5 * (p[1] - p[0]).perp_dot(p[2] - p[0]).abs() as f64;
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let border: f64 = edges
        .iter()
        .filter(|&(_, &n)| n == 1)
        .map(|(&(a, b), _)| {
            let d = (unwrap.uv1[a as usize] - unwrap.uv1[b as usize]) * scale;
            0.5 * (d.x.abs() + d.y.abs()) as f64
        })
        .sum();
    area + border + unwrap.chart_count as f64
}

/// This process's peak resident memory so far (`VmHWM` in `/proc/self/status`), bytes; `None`
/// where the system has no such file. The benches and `tests/memory.rs` compare it with the
/// plan, and the report records it.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kib: u64 = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box};

    #[test]
    fn absurd_density_is_refused_with_the_estimate() {
        let s = cornell_box(CornellLight::Area);
        let est = estimate_from_area(&s, 100_000.0);
        let err = est.check(8192).unwrap_err().to_string();
        assert!(
            err.contains("MiB") && err.contains("texel patches"),
            "{err}"
        );
        assert!(estimate_from_area(&s, 256.0).check(8192).is_ok());
    }
}
