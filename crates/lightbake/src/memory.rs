//! Memory planning: estimate what a bake will allocate before allocating it, and refuse with
//! the estimate in the message when it exceeds `memory_budget_mib`.
//!
//! The per-item costs are the sizes of the structures involved (measured with
//! `size_of`), with the transient peaks of rasterisation and image encoding included.

use serde::Serialize;

use crate::error::{BakeError, Result};
use crate::raster::Patch;
use crate::scene::Scene;
use crate::unwrap::Layout;

/// Bytes per covered texel: the patch, its footprint list, the irradiance, and the transient
/// rasterisation entry.
pub const BYTES_PER_PATCH: u64 = size_of::<Patch>() as u64 + 2 * 4 + 12 + 48;
/// Bytes per page texel: index, RGB f32, coverage and fill state, half-float and PNG encode
/// buffers.
pub const BYTES_PER_PAGE_TEXEL: u64 = 4 + 12 + 2 + 8 + 8;
/// Bytes per triangle in the ray-tracing structures: triangle data (48) and info (40), the
/// four-wide BVH's nodes and leaf packets, and the binary builder's temporaries (312, from
/// the peak RSS of a million-triangle bake in `benches/scale.rs`).
pub const BYTES_PER_TRIANGLE: u64 = 48 + 40 + 312;

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
/// packing and padding), pages sized to match.
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

/// After unwrapping, from the actual pages and mesh rectangles (covered texels are bounded
/// by the rectangles' areas).
pub fn estimate_from_layout(scene: &Scene, layout: &Layout) -> MemoryEstimate {
    let rect_texels: u64 = layout
        .instances
        .iter()
        .flatten()
        .map(|r| r.width as u64 * r.height as u64)
        .sum();
    MemoryEstimate::from_items(vec![
        ("texel patches".into(), rect_texels * BYTES_PER_PATCH),
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
