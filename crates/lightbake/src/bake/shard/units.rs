//! Work units: the texel patches of a split bake cut into contiguous runs of about equal
//! estimated rays, and the hashes that tie them to the patches and the layout they were cut
//! from.

use serde::{Deserialize, Serialize};

use crate::raster::{Patch, Patches};
use crate::sampling::Fnv1a;
use crate::settings::BakeSettings;
use crate::unwrap::Layout;

/// Work units per bake (fewer when there are fewer patches).
pub const UNITS: usize = 1024;

/// Work units: contiguous runs of texel patches with about equal estimated rays each.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// First patch of each unit, then the number of patches.
    pub starts: Vec<u32>,
    /// Estimated rays of each unit.
    pub rays: Vec<f64>,
    /// Hash of the patches they were cut from (positions, normals, flags, keys).
    pub patches_hash: u64,
    /// Hash of the lightmap layout the patches belong to ([`layout_hash`]).
    pub layout_hash: u64,
    /// The `prepare` run that wrote them (drawn from the clock and the process when it wrote
    /// them; 0 before). Parts of another run are never taken: a work folder prepared again
    /// with other settings may have the same patches, but not the same values.
    #[serde(default)]
    pub preparation: u64,
}

/// Estimated rays of one patch: its direct samples and its gathers.
fn patch_rays(p: &Patch, settings: &BakeSettings, lights: usize, sky: bool) -> f64 {
    if !p.is_valid() {
        return 1.0;
    }
    let spp = settings.direct.samples_per_texel as f64;
    let sky = if sky {
        settings.direct.sky_samples as f64
    } else {
        0.0
    };
    spp * (lights as f64 + 1.0) + sky + 1.25 * settings.radiosity.transport_rays as f64
}

/// An identifier of this `prepare` run: the clock, the process and the patches, mixed.
pub(super) fn preparation_id(units: &Units) -> u64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let mut h = Fnv1a::default();
    for w in [
        nanos as u32,
        (nanos >> 32) as u32,
        (nanos >> 64) as u32,
        std::process::id(),
        units.patches_hash as u32,
        (units.patches_hash >> 32) as u32,
    ] {
        h.word(w);
    }
    // 0 means "not prepared".
    h.finish().max(1)
}

/// FNV-1a over the layout: pages, instance rectangles, every unwrap's UVs and triangles.
pub fn layout_hash(layout: &Layout) -> u64 {
    let mut h = Fnv1a::default();
    for p in &layout.pages {
        h.word(p.width);
        h.word(p.height);
    }
    for r in layout.instances.iter().flatten() {
        for w in [r.page, r.x, r.y, r.width, r.height] {
            h.word(w);
        }
    }
    for u in layout.meshes.iter().flatten() {
        h.word(u.width);
        h.word(u.height);
        for v in &u.uv1 {
            h.word(v.x.to_bits());
            h.word(v.y.to_bits());
        }
        u.indices.iter().for_each(|&i| h.word(i));
    }
    h.finish()
}

/// FNV-1a over every patch's identity and geometry.
pub(in crate::bake) fn patches_hash(patches: &Patches) -> u64 {
    let mut h = Fnv1a::default();
    let mut eat = |w: u32| h.word(w);
    for p in &patches.patches {
        for w in [
            p.instance,
            p.page,
            p.x,
            p.y,
            p.triangle,
            p.key,
            p.flags as u32,
        ] {
            eat(w);
        }
        for v in [p.position, p.normal, p.geometric_normal] {
            for c in v.to_array() {
                eat(c.to_bits());
            }
        }
    }
    h.finish()
}

impl Units {
    /// Cuts `patches` (of `layout`) into at most [`UNITS`] units of about equal estimated
    /// rays (direct samples of `lights` lights and the sky, gathers).
    pub(crate) fn plan(
        patches: &Patches,
        layout: &Layout,
        settings: &BakeSettings,
        lights: usize,
        sky: bool,
    ) -> Self {
        let costs: Vec<f64> = patches
            .patches
            .iter()
            .map(|p| patch_rays(p, settings, lights, sky))
            .collect();
        let total: f64 = costs.iter().sum();
        let units = UNITS.min(costs.len()).max(1);
        let mut starts = vec![0u32];
        let mut rays = Vec::new();
        let mut acc = 0.0;
        let mut unit = 0.0;
        for (i, c) in costs.iter().enumerate() {
            acc += c;
            unit += c;
            let k = starts.len() as f64;
            if acc >= total * k / units as f64 && i + 1 < costs.len() && starts.len() < units {
                starts.push(i as u32 + 1);
                rays.push(unit);
                unit = 0.0;
            }
        }
        starts.push(costs.len() as u32);
        rays.push(unit);
        Self {
            starts,
            rays,
            patches_hash: patches_hash(patches),
            layout_hash: layout_hash(layout),
            preparation: 0,
        }
    }

    /// Checks units read from a file against the patches they cut: at least one unit, starts
    /// rising strictly from 0 to `patches`, one ray estimate per unit, finite and non-negative.
    ///
    /// # Errors
    /// The first violation.
    pub fn check(&self, patches: usize) -> Result<(), BadUnits> {
        let units = self.rays.len();
        if units == 0 || units > UNITS || self.starts.len() != units + 1 {
            return Err(BadUnits::Count {
                starts: self.starts.len(),
                units,
            });
        }
        if self.starts[0] != 0 || *self.starts.last().unwrap_or(&0) as usize != patches {
            return Err(BadUnits::Span { patches });
        }
        if self.starts.windows(2).any(|w| w[0] >= w[1]) && patches > 0 {
            return Err(BadUnits::NotRising);
        }
        if self.rays.iter().any(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(BadUnits::BadRays);
        }
        Ok(())
    }

    /// The shard of every patch, for `count` shards: unit `u` goes to shard `u mod count`,
    /// so every shard gets units from all over the atlas, and the stages whose costs vary
    /// differently over it (direct light near many lights, gathers near geometry) are each
    /// spread evenly.
    pub fn patch_shards(&self, count: u32) -> Vec<u32> {
        let n = *self.starts.last().unwrap_or(&0) as usize;
        let mut out = vec![0u32; n];
        for (u, w) in self.starts.windows(2).enumerate() {
            out[w[0] as usize..w[1] as usize].fill(u as u32 % count.max(1));
        }
        out
    }

    /// Estimated rays of each of `count` shards.
    pub fn shard_rays(&self, count: u32) -> Vec<f64> {
        let n = count.max(1) as usize;
        let mut out = vec![0.0; n];
        for (u, r) in self.rays.iter().enumerate() {
            out[u % n] += r;
        }
        out
    }
}

/// What is wrong with work units read from a file ([`Units::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum BadUnits {
    /// No units, more than [`UNITS`], or not one start per unit plus the end.
    #[error("{starts} starts for {units} units (at most {UNITS})")]
    Count {
        /// Starts in the file.
        starts: usize,
        /// Ray estimates (units) in the file.
        units: usize,
    },
    /// The starts do not run from patch 0 to the last patch.
    #[error("the units do not run from patch 0 to patch {patches}")]
    Span {
        /// Patches in the patch file.
        patches: usize,
    },
    /// A start is not above the one before it.
    #[error("the units' starts do not rise")]
    NotRising,
    /// A ray estimate is negative, NaN or infinite.
    #[error("a unit's ray estimate is not a finite number")]
    BadRays,
}
