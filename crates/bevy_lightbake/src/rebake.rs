//! Incremental rebakes in the running app ([`LightbakeConfig::auto_rebake`]).
//!
//! Every bake in the app follows the last finished one (`lightbake::incremental`): the core
//! keeps a cache of it in memory ([`KeptBake`]), and the next bake with the same settings
//! keeps the layout of the meshes that did not change and recomputes only what the edit can
//! change. With `auto_rebake`, [`watch_edits`] sums up, each frame, what a bake reads of the
//! world and can be edited cheaply (the baked meshes' placement and materials, the baked
//! lights) and sends a [`RequestBake`] once that has stayed unchanged for
//! [`LightbakeConfig::rebake_after_seconds`] after it differed from the last bake's. An edit
//! during a rebake cancels it ([`crate::requests::read_requests`]) and starts another from
//! the same cache. The frame loop only hashes; the bake runs on its own thread.

use std::collections::HashMap;
use std::hash::{Hash, Hasher};

use bevy::prelude::*;
use lightbake::incremental::BakeCache;

use crate::LightbakeSystems;
use crate::components::{BakeStatus, LightbakeConfig, Lightbaked, NotBaked, RequestBake};

/// Watches the world for edits and schedules rebakes ([`LightbakeSystems::Requests`], before
/// the requests are read).
pub struct AutoRebakePlugin;

impl Plugin for AutoRebakePlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<KeptBake>()
            .init_resource::<UnwrappedMeshes>()
            .init_resource::<EditWatch>()
            .add_systems(Update, watch_edits.before(LightbakeSystems::Requests));
    }
}

/// The meshes a bake in the app gave lightmap UVs (`UV_1`, with the vertices split at the
/// charts' seams), by the asset now holding them: the mesh as it was before, and a summary of
/// what was written. The next bake reads the mesh as it was, so an unchanged mesh stays the
/// same input and keeps its layout; an asset the game replaced since is read as it is.
#[derive(Resource, Default)]
pub struct UnwrappedMeshes(HashMap<AssetId<Mesh>, (Mesh, u64)>);

impl UnwrappedMeshes {
    /// Notes that the asset `id` now holds a mesh of summary `written`
    /// ([`written_summary`]), made from `original`.
    pub(crate) fn insert(&mut self, id: AssetId<Mesh>, original: Mesh, written: u64) {
        self.0.insert(id, (original, written));
    }

    /// The mesh a bake reads for the asset `id` holding `current`: the mesh before an earlier
    /// bake gave it `UV_1`, or `current` when the asset holds something else since.
    pub fn source<'a>(&'a self, id: AssetId<Mesh>, current: &'a Mesh) -> &'a Mesh {
        match self.0.get(&id) {
            Some((original, written)) if *written == written_summary(current) => original,
            _ => current,
        }
    }
}

/// A summary of a mesh's positions, indices and `UV_1`.
pub(crate) fn written_summary(mesh: &Mesh) -> u64 {
    use bevy::mesh::VertexAttributeValues as V;
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for attribute in [Mesh::ATTRIBUTE_POSITION, Mesh::ATTRIBUTE_UV_1] {
        match mesh.attribute(attribute) {
            Some(V::Float32x3(v)) => v.iter().flatten().for_each(|x| x.to_bits().hash(&mut h)),
            Some(V::Float32x2(v)) => v.iter().flatten().for_each(|x| x.to_bits().hash(&mut h)),
            Some(other) => other.len().hash(&mut h),
            None => 0u8.hash(&mut h),
        }
    }
    if let Some(indices) = mesh.indices() {
        indices.iter().for_each(|k| k.hash(&mut h));
    }
    h.finish()
}

/// The cache of the last finished bake in the app, which the next bake follows.
#[derive(Resource, Default)]
pub struct KeptBake(pub Option<BakeCache>);

/// What the watcher knows: the world's summary when the last bake started, the one it saw
/// last and since when.
#[derive(Resource, Default, Debug)]
pub struct EditWatch {
    /// The summary of the world the running or last bake read; `None` before any bake.
    pub baked: Option<u64>,
    /// The summary seen last.
    seen: u64,
    /// When it last changed, seconds of `Time<Real>`.
    changed_at: f64,
    /// Rebakes requested by the watcher.
    pub requested: u32,
}

/// Called when a bake starts: the world it reads is the one the next edit is measured from.
pub(crate) fn bake_started(world: &mut World) {
    let summary = summarise(world);
    let mut watch = world.resource_mut::<EditWatch>();
    watch.baked = Some(summary);
    watch.seen = summary;
}

/// Sends a [`RequestBake`] when the world has settled after an edit (see the module docs).
pub fn watch_edits(world: &mut World) {
    let config = world.resource::<LightbakeConfig>();
    if !config.auto_rebake {
        return;
    }
    let settle = f64::from(config.rebake_after_seconds.max(0.0));
    let Some(baked) = world.resource::<EditWatch>().baked else {
        return;
    };
    // Nothing to follow before a first bake has finished in the app.
    if world.resource::<KeptBake>().0.is_none() && !world.resource::<BakeStatus>().is_running() {
        return;
    }
    let now = world.resource::<Time<Real>>().elapsed_secs_f64();
    let summary = summarise(world);
    let mut watch = world.resource_mut::<EditWatch>();
    if summary != watch.seen {
        watch.seen = summary;
        watch.changed_at = now;
        return;
    }
    if summary == baked || now - watch.changed_at < settle {
        return;
    }
    watch.baked = Some(summary);
    watch.requested += 1;
    world.write_message(RequestBake::default());
}

/// One number for what a bake reads of the world and an edit can change: the baked meshes'
/// transforms and materials' base colour and emission, the baked lights' placement, colour,
/// intensity, range and cone. Entities are combined in any order.
fn summarise(world: &mut World) -> u64 {
    let mut sum = 0u64;
    let mut add = |e: Entity, f: &dyn Fn(&mut std::collections::hash_map::DefaultHasher)| {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        e.to_bits().hash(&mut h);
        f(&mut h);
        sum = sum.wrapping_add(h.finish());
    };
    let bits = |h: &mut std::collections::hash_map::DefaultHasher, v: &[f32]| {
        for x in v {
            x.to_bits().hash(h);
        }
    };
    let colour = |c: Color| c.to_linear().to_f32_array();
    let placed = |t: &GlobalTransform| t.to_matrix().to_cols_array();

    let mut meshes = world.query_filtered::<(
        Entity,
        &GlobalTransform,
        Option<&MeshMaterial3d<StandardMaterial>>,
        &Lightbaked,
    ), With<Mesh3d>>();
    let mut points =
        world.query_filtered::<(Entity, &GlobalTransform, &PointLight), Without<NotBaked>>();
    let mut spots =
        world.query_filtered::<(Entity, &GlobalTransform, &SpotLight), Without<NotBaked>>();
    let mut suns =
        world.query_filtered::<(Entity, &GlobalTransform, &DirectionalLight), Without<NotBaked>>();
    let world: &World = world;
    let materials = world.resource::<Assets<StandardMaterial>>();
    for (e, t, m, l) in meshes.iter(world) {
        let m = m.and_then(|m| materials.get(&m.0));
        add(e, &|h| {
            bits(h, &placed(t));
            l.receive_lightmap.hash(h);
            if let Some(m) = m {
                bits(h, &colour(m.base_color));
                bits(h, &m.emissive.to_f32_array());
            }
        });
    }
    for (e, t, l) in points.iter(world) {
        add(e, &|h| {
            bits(h, &placed(t));
            bits(h, &colour(l.color));
            bits(h, &[l.intensity, l.range, l.radius]);
        });
    }
    for (e, t, l) in spots.iter(world) {
        add(e, &|h| {
            bits(h, &placed(t));
            bits(h, &colour(l.color));
            bits(
                h,
                &[l.intensity, l.range, l.radius, l.inner_angle, l.outer_angle],
            );
        });
    }
    for (e, t, l) in suns.iter(world) {
        add(e, &|h| {
            bits(h, &placed(t));
            bits(h, &colour(l.color));
            bits(h, &[l.illuminance]);
        });
    }
    sum
}
