//! Progressive previews in the game: while a bake runs, the lightmaps it has so far are
//! shown ([`lightbake::bake::preview`]: the direct light, then the coarse indirect light with
//! progressive radiosity's ambient term, then the result), and a bake that is cancelled or
//! fails puts back what the first preview replaced.

use std::collections::HashMap;

use bevy::light::GlobalAmbientLight;
use bevy::pbr::Lightmap;
use bevy::prelude::*;
use lightbake::bake::Preview;

use crate::components::{BakeStatus, BakedLight, Lightmapped};
use crate::convert::SceneMapping;
use crate::images::page_image;
use crate::lightmaps::{
    affects_lightmapped, apply_meshes, attach_lightmaps, mark_lights_baked, memory_pages,
    set_affects_lightmapped,
};

/// The previews of one bake: the last shown and what the first replaced.
#[derive(Default)]
pub(crate) struct Previewing {
    /// The last preview shown (its sequence number; 0 before the first).
    shown: u32,
    /// What the first preview replaced, put back when the bake is cancelled or fails.
    restore: Option<Restore>,
    /// The meshes the first preview split off into assets of their own (by core mesh).
    meshes: Option<HashMap<usize, Handle<Mesh>>>,
    /// The images a preview was written into, as they were before.
    images: Vec<(AssetId<Image>, Image)>,
}

/// What the first preview of a bake replaced.
struct Restore {
    /// Per core mesh, the asset's mesh as it was (it may hold an earlier bake's `UV_1`).
    meshes: Vec<Option<Mesh>>,
    /// Per baked instance (in the mapping's order): its entity's lightmap and mesh before.
    instances: Vec<(Option<Lightmapped>, Option<Mesh3d>)>,
    /// Per baked light (in the mapping's order): its `affects_lightmapped_mesh_diffuse` and
    /// whether it carried [`BakedLight`].
    lights: Vec<(Option<bool>, bool)>,
    /// `GlobalAmbientLight::affects_lightmapped_meshes`.
    ambient: Option<bool>,
}

impl Restore {
    /// Records the state of every entity and mesh `mapping` names.
    fn record(world: &World, mapping: &SceneMapping) -> Self {
        let assets = world.resource::<Assets<Mesh>>();
        let meshes = (mapping.meshes.iter())
            .map(|m| assets.get(&m.handle).cloned())
            .collect();
        let instances = mapping
            .instances
            .iter()
            .map(|&e| {
                world.get_entity(e).map_or((None, None), |e| {
                    (e.get::<Lightmapped>().cloned(), e.get::<Mesh3d>().cloned())
                })
            })
            .collect();
        let lights = all_lights(mapping)
            .map(|e| {
                world.get_entity(e).map_or((None, false), |e| {
                    (affects_lightmapped(&e), e.contains::<BakedLight>())
                })
            })
            .collect();
        let ambient = world
            .get_resource::<GlobalAmbientLight>()
            .map(|a| a.affects_lightmapped_meshes);
        Self {
            meshes,
            instances,
            lights,
            ambient,
        }
    }

    /// Puts everything back: the meshes as they were read for the bake, the entities' meshes
    /// and lightmaps, the lights' flags.
    fn apply(self, world: &mut World, mapping: &SceneMapping) {
        for (source, before) in mapping.meshes.iter().zip(self.meshes) {
            if let (false, Some(before)) = (source.needs_own_asset, before) {
                let _ = world
                    .resource_mut::<Assets<Mesh>>()
                    .insert(source.handle.id(), before);
            }
        }
        for (&entity, (lightmapped, mesh)) in mapping.instances.iter().zip(self.instances) {
            let Ok(mut e) = world.get_entity_mut(entity) else {
                continue;
            };
            if let Some(mesh) = mesh {
                e.insert(mesh);
            }
            match lightmapped {
                Some(l) => {
                    e.insert(l);
                }
                None => {
                    e.remove::<(Lightmapped, Lightmap)>();
                }
            }
            // Bevy chooses the pipeline (lightmapped or not) when the mesh entity changes.
            if let Some(mut mesh) = e.get_mut::<Mesh3d>() {
                mesh.set_changed();
            }
        }
        for (entity, (affects, baked)) in all_lights(mapping).zip(self.lights) {
            let Ok(mut e) = world.get_entity_mut(entity) else {
                continue;
            };
            if let Some(a) = affects {
                set_affects_lightmapped(&mut e, a);
            }
            if baked {
                e.insert(BakedLight);
            } else {
                e.remove::<BakedLight>();
            }
        }
        if let (Some(before), Some(mut a)) =
            (self.ambient, world.get_resource_mut::<GlobalAmbientLight>())
        {
            a.affects_lightmapped_meshes = before;
        }
    }
}

/// Every light entity the bake reads, baked in full or indirect only.
fn all_lights(mapping: &SceneMapping) -> impl Iterator<Item = Entity> + '_ {
    mapping
        .lights
        .iter()
        .chain(&mapping.realtime_lights)
        .copied()
}

impl Previewing {
    /// The sequence number of the last preview shown (0 before the first).
    pub(crate) fn shown(&self) -> u32 {
        self.shown
    }

    /// Shows `preview` of the running bake: the first one applies its layout (the meshes'
    /// `UV_1`) and takes the baked lights off lightmapped meshes, as the finished bake does;
    /// each puts its pages in memory and on the entities.
    pub(crate) fn show(&mut self, world: &mut World, mapping: &SceneMapping, preview: &Preview) {
        if self.restore.is_none() {
            self.restore = Some(Restore::record(world, mapping));
            mark_lights_baked(world, mapping);
        }
        if self.meshes.is_none() {
            self.meshes = Some(apply_meshes(world, &preview.layout, mapping));
        }
        let new_handles = self.meshes.clone().unwrap_or_default();
        let handles = match self.in_place(world, mapping, preview) {
            Some(handles) => handles,
            None => memory_pages(world, &preview.pages),
        };
        attach_lightmaps(world, &preview.layout, mapping, &new_handles, &handles);
        self.shown = preview.sequence;
        world.resource_mut::<BakeStatus>().preview = Some(preview.kind);
    }

    /// The images the entities show now, when the preview's pages can be written into them
    /// (a rebake over the same layout: each page shown by some entity, at the same size),
    /// with the preview written there; their content before is kept for [`Self::restore`].
    /// Writing in place keeps the entities on the images they show: switching a file-loaded
    /// page to another image stalled a frame for the rest of the bake under lavapipe.
    fn in_place(
        &mut self,
        world: &mut World,
        mapping: &SceneMapping,
        preview: &Preview,
    ) -> Option<Vec<Handle<Image>>> {
        let mut shown: Vec<Option<Handle<Image>>> = vec![None; preview.pages.len()];
        for (&entity, rect) in mapping.instances.iter().zip(&preview.layout.instances) {
            let (Some(rect), Some(l)) = (rect, world.get::<Lightmapped>(entity)) else {
                continue;
            };
            let slot = shown.get_mut(rect.page as usize)?;
            match slot {
                Some(h) if *h != l.image => return None,
                _ => *slot = Some(l.image.clone()),
            }
        }
        let shown: Vec<Handle<Image>> = shown.into_iter().collect::<Option<_>>()?;
        // One image per page: an instance that moved to another page shows its old page's.
        let mut ids: Vec<AssetId<Image>> = shown.iter().map(Handle::id).collect();
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != shown.len() {
            return None;
        }
        let mut images = world.resource_mut::<Assets<Image>>();
        let fits = shown.iter().zip(&preview.pages).all(|(h, page)| {
            images
                .get(h)
                .is_some_and(|i| (i.width(), i.height()) == (page.width, page.height))
        });
        if !fits {
            return None;
        }
        for (h, page) in shown.iter().zip(&preview.pages) {
            if !self.images.iter().any(|(id, _)| *id == h.id())
                && let Some(before) = images.get(h)
            {
                self.images.push((h.id(), before.clone()));
            }
            let _ = images.insert(h.id(), page_image(page));
        }
        Some(shown)
    }

    /// Puts back what the first preview replaced (a bake cancelled or failed); whether there
    /// was anything to put back.
    pub(crate) fn restore(&mut self, world: &mut World, mapping: &SceneMapping) -> bool {
        let mut images = world.resource_mut::<Assets<Image>>();
        for (id, before) in std::mem::take(&mut self.images) {
            let _ = images.insert(id, before);
        }
        match self.restore.take() {
            Some(restore) => {
                restore.apply(world, mapping);
                true
            }
            None => false,
        }
    }
}
