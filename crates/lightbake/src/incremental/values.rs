//! The values a bake's split stages ended with, kept for a later bake: per stage its items'
//! values as [`Record`] bytes, the texel patch each item belongs to, and, for the stages
//! whose passes state it, each item's *input summary* (a number whose change bounds the
//! change of the item's value, such as the coarse light a node gathers). Patches are known
//! across bakes by a key of their instance's identity, their texel within the instance's
//! rectangle and their own geometry (`patch_key`), so a patch that did not change is found
//! again wherever the edit moved the others.

use super::codec::{Bad, Reader, Writer};
use crate::raster::{Patch, Patches};
use crate::runner::Record;
use crate::scene::Scene;
use crate::scene::hashes::{Hasher, mesh_geometry};
use crate::stage::Stage;
use crate::unwrap::Layout;

/// One split stage's kept values.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptStage {
    /// The stage.
    pub stage: Stage,
    /// Items (texels or radiosity nodes).
    pub items: usize,
    /// The patch of each item.
    pub item_patch: Vec<u32>,
    /// Each item's input summary, when the pass stated one (else empty).
    pub summary: Vec<f32>,
    /// The values, [`Record::BYTES`] bytes each.
    pub bytes: Vec<u8>,
    /// Per item, whether its value was computed: empty when every item was. Only the last
    /// stage of a bake that stopped during it ([`super::PARTIAL_FILE`]) has unfinished items.
    pub finished: Vec<bool>,
}

impl KeptStage {
    /// Item `i`'s value.
    pub fn value<T: Record>(&self, i: usize) -> T {
        T::get(&self.bytes[i * T::BYTES..(i + 1) * T::BYTES])
    }

    /// Whether item `i` has its value (not an unfinished item of a stage a bake stopped in).
    pub fn is_finished(&self, i: usize) -> bool {
        self.finished.get(i).copied().unwrap_or(true)
    }

    /// The share of the items that have their values (1 for a finished stage).
    pub fn finished_share(&self) -> f64 {
        if self.finished.is_empty() || self.items == 0 {
            return 1.0;
        }
        self.finished.iter().filter(|&&f| f).count() as f64 / self.items as f64
    }

    /// The item of each patch (of `patches` patches), if it has one.
    pub fn item_of_patch(&self, patches: usize) -> Vec<Option<u32>> {
        let mut out = vec![None; patches];
        for (i, &p) in self.item_patch.iter().enumerate() {
            if let Some(slot) = out.get_mut(p as usize) {
                *slot = Some(i as u32);
            }
        }
        out
    }
}

/// What a whole stage (not split into items) left for a later bake: bytes its pass wrote and
/// reads back itself, under a key of what they were made from (the pass's own hash; a later
/// bake takes them only when its key is the same). The coarse level of the hierarchical
/// solve keeps its cut, matrix and first bounce this way.
#[derive(Clone, Debug, PartialEq)]
pub struct KeptState {
    /// The stage.
    pub stage: Stage,
    /// What the bytes were made from, hashed by the pass.
    pub key: u64,
    /// The pass's bytes.
    pub bytes: Vec<u8>,
    /// Their checksum when they were kept: bytes that no longer match it are not taken.
    pub sum: u64,
}

impl KeptState {
    /// `bytes` kept for `stage` under `key`, with their checksum.
    pub fn new(stage: Stage, key: u64, bytes: Vec<u8>) -> Self {
        let sum = super::codec::checksum(&bytes);
        Self {
            stage,
            key,
            bytes,
            sum,
        }
    }

    /// Whether the bytes still match their checksum.
    pub fn intact(&self) -> bool {
        super::codec::checksum(&self.bytes) == self.sum
    }
}

/// The values of a bake's split stages (direct light, the gather's pilot, final gather,
/// correction, reflection), in the order the bake computed them, with the keys of the texel
/// patches they belong to and hashes of the patches and of the settings that computed them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StageValues {
    /// Every setting but the thread count, hashed.
    pub settings_hash: u64,
    /// The texel patches, hashed (equal for the same geometry, layout and settings).
    pub patches_hash: u64,
    /// Per patch, its key (`patch_key`).
    pub patch_keys: Vec<u64>,
    /// The split stages, in order.
    pub stages: Vec<KeptStage>,
    /// What the texel patches are made from (`patch_geometry` over
    /// the scene and the layout): a later bake whose own is the same takes `patches` as
    /// they are, without the rasteriser and the validity pass.
    pub geometry_key: u64,
    /// The texel patches as bytes (as the split bake writes them; empty when not kept).
    pub patches: Vec<u8>,
    /// What whole stages kept (at most one per stage).
    pub states: Vec<KeptState>,
}

impl StageValues {
    /// The stages kept, in order, with their item counts.
    pub fn stages(&self) -> impl Iterator<Item = (Stage, usize)> + '_ {
        self.stages.iter().map(|s| (s.stage, s.items))
    }

    pub(super) fn write(&self, w: &mut Writer) {
        w.u64(self.settings_hash);
        w.u64(self.patches_hash);
        w.u64s(&self.patch_keys);
        w.len(self.stages.len());
        for s in &self.stages {
            w.str(s.stage.name());
            w.len(s.items);
            w.u32s(&s.item_patch);
            w.f32s(&s.summary);
            w.bytes(&s.bytes);
            let finished: Vec<u8> = s.finished.iter().map(|&f| u8::from(f)).collect();
            w.bytes(&finished);
        }
        w.u64(self.geometry_key);
        w.bytes(&self.patches);
        w.len(self.states.len());
        for s in &self.states {
            w.str(s.stage.name());
            w.u64(s.key);
            w.bytes(&s.bytes);
            w.u64(s.sum);
        }
    }

    pub(super) fn read(r: &mut Reader<'_>) -> Result<Self, Bad> {
        let settings_hash = r.u64()?;
        let patches_hash = r.u64()?;
        let patch_keys = r.u64s()?;
        let n = r.len(32)?;
        let mut stages = Vec::with_capacity(n);
        for _ in 0..n {
            let name = r.str()?;
            let stage: Stage = name
                .parse()
                .map_err(|_| format!("it names a stage '{name}'"))?;
            let items = r.u64()? as usize;
            let item_patch = r.u32s()?;
            let summary = r.f32s()?;
            let bytes = r.bytes()?.to_vec();
            let finished: Vec<bool> = r.bytes()?.iter().map(|&b| b != 0).collect();
            let fits = item_patch.len() == items
                && (finished.is_empty() || finished.len() == items)
                && (summary.is_empty() || summary.len() == items)
                && items > 0
                && bytes.len() % items == 0
                && item_patch.iter().all(|&p| (p as usize) < patch_keys.len());
            if !fits {
                return Err(format!(
                    "its '{name}' values do not fit their {items} items"
                ));
            }
            stages.push(KeptStage {
                stage,
                items,
                item_patch,
                summary,
                bytes,
                finished,
            });
        }
        let geometry_key = r.u64()?;
        let patches = r.bytes()?.to_vec();
        let n = r.len(32)?;
        let mut states = Vec::with_capacity(n);
        for _ in 0..n {
            let name = r.str()?;
            let stage: Stage = name
                .parse()
                .map_err(|_| format!("it names a stage '{name}'"))?;
            let key = r.u64()?;
            let bytes = r.bytes()?.to_vec();
            let sum = r.u64()?;
            states.push(KeptState {
                stage,
                key,
                bytes,
                sum,
            });
        }
        Ok(Self {
            settings_hash,
            patches_hash,
            patch_keys,
            stages,
            geometry_key,
            patches,
            states,
        })
    }
}

/// A patch's key: its instance's identity, its texel within the instance's rectangle, and
/// its own geometry (position, normals, area, flags, footprint size), so that a patch moved
/// out of geometry differently, or on a moved instance, is a new patch.
pub(crate) fn patch_key(identity: u64, origin: (u32, u32), p: &Patch) -> u64 {
    let mut h = Hasher::default();
    h.u64(identity);
    h.u32(p.x.wrapping_sub(origin.0))
        .u32(p.y.wrapping_sub(origin.1));
    h.vec3(p.position).vec3(p.normal).vec3(p.geometric_normal);
    h.f32(p.area).f32(p.texel_size);
    h.u32(u32::from(p.flags)).u32(p.footprint_len);
    h.finish()
}

/// The key of every patch of `patches` (of `layout`, whose instances have `identities`).
pub(crate) fn patch_keys(patches: &Patches, layout: &Layout, identities: &[u64]) -> Vec<u64> {
    (patches.patches.iter())
        .map(|p| {
            let i = p.instance as usize;
            let origin =
                (layout.instances.get(i).copied().flatten()).map_or((0, 0), |r| (r.x, r.y));
            patch_key(identities.get(i).copied().unwrap_or(0), origin, p)
        })
        .collect()
}

/// The hash of what a bake's texel patches are made from: every instance's mesh geometry
/// ([`mesh_geometry`], with its `TEXCOORD_1`), transform, `bake` flag and two-sidedness, in
/// order, and `layout` (each page's size, each instance's rectangle and each mesh's unwrap).
/// Two bakes with the same key rasterise the same patches and move them out of geometry alike.
pub(crate) fn patch_geometry(scene: &Scene, layout: &Layout) -> u64 {
    let mut h = Hasher::default();
    let meshes: Vec<u64> = scene.meshes.iter().map(mesh_geometry).collect();
    h.u64(scene.instances.len() as u64);
    for inst in &scene.instances {
        h.u64(meshes[inst.mesh]);
        h.f32s(&inst.transform.to_cols_array());
        h.u32(u32::from(inst.bake));
        h.u32(u32::from(scene.material_of(inst.mesh).double_sided));
    }
    h.u64(layout.pages.len() as u64);
    for p in &layout.pages {
        h.u32(p.width).u32(p.height);
    }
    for r in &layout.instances {
        match r {
            Some(r) => h
                .u32(1)
                .u32(r.page)
                .u32(r.x)
                .u32(r.y)
                .u32(r.width)
                .u32(r.height),
            None => h.u32(0),
        };
    }
    for m in &layout.meshes {
        let Some(u) = m else {
            h.u32(0);
            continue;
        };
        h.u32(1).u32(u.width).u32(u.height);
        for v in &u.uv1 {
            h.f32(v.x).f32(v.y);
        }
        h.u64(u.indices.len() as u64);
        for &i in &u.indices {
            h.u32(i);
        }
    }
    h.finish()
}
