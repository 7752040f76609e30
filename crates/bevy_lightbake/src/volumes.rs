//! Irradiance volumes for dynamic objects: `LightProbe` + `IrradianceVolume` entities spawned
//! from an in-app bake (when `LightbakeConfig::settings.volume.enabled` is set) and from
//! the scene extras of a glTF baked by `bake --irradiance-volume`
//! (`extras.lightbake.irradiance_volumes`, image paths relative to the glTF file). The voxel
//! images are loaded through the `AssetServer`, so the file watcher reloads them when the
//! `bake` command rewrites them. Lightmapped meshes keep their lightmaps
//! (`affects_lightmapped_meshes = false`); moving meshes take their diffuse light from the
//! volume.

use bevy::gltf::GltfSceneExtras;
use bevy::light::{GlobalAmbientLight, IrradianceVolume, LightProbe};
use bevy::prelude::*;
use bevy::render::renderer::RenderDevice;
use bevy::render::settings::WgpuFeatures;
use bevy::world_serialization::WorldAssetRoot;
use lightbake::BakeOutput;
use lightbake::scene::extras::{self, SceneExtras, VolumeExtras};

use crate::LightbakeSystems;
use crate::components::{BakedVolume, ShowLightmaps};
use crate::groups::{GltfVolume, GroupSums, SummedVolume, in_app_volume};
use crate::images::volume_image;

/// Probe volumes: baked volumes of glTF scenes found, and every volume shown or hidden with
/// the lightmaps (after them, in [`LightbakeSystems::Lightmaps`]).
pub struct VolumesPlugin;

impl Plugin for VolumesPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<SuppressedAmbient>()
            .add_systems(Update, attach_gltf_volumes.in_set(LightbakeSystems::Gltf))
            .add_systems(
                PostUpdate,
                (
                    sync_volumes
                        .after(crate::lightmaps::sync_lightmaps)
                        .in_set(LightbakeSystems::Lightmaps),
                    warn_when_one_volume_is_drawn,
                ),
            );
    }
}

/// A volume entity spawned by an in-app bake (replaced by the next one).
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct InAppVolume;

/// A glTF scene root already searched for volumes.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct VolumesLookedUp;

/// The ambient light's brightness while a volume carrying it is shown (restored after).
#[derive(Resource, Default)]
pub(crate) struct SuppressedAmbient(Option<f32>);

/// The light probe bundle of one volume entry, its voxels `image`.
fn volume_bundle(
    entry: &VolumeExtras,
    image: Handle<Image>,
    carries_ambient: bool,
) -> impl Bundle + use<> {
    (
        Name::new(format!("lightbake irradiance volume ({})", entry.image)),
        LightProbe {
            falloff: Vec3::from_array(entry.falloff),
        },
        IrradianceVolume {
            voxels: image,
            intensity: entry.intensity,
            affects_lightmapped_meshes: false,
        },
        Transform::from_translation(Vec3::from_array(entry.center))
            .with_rotation(rotation(entry.rotation))
            .with_scale(Vec3::from_array(entry.size)),
        BakedVolume { carries_ambient },
    )
}

/// The box's rotation an entry gives: a unit quaternion, or none for a malformed one.
fn rotation(q: [f32; 4]) -> Quat {
    let q = Quat::from_array(q);
    if q.is_finite() && q.length() > 0.5 {
        q.normalize()
    } else {
        Quat::IDENTITY
    }
}

/// Replaces the volumes of the previous in-app bake with `output`'s: their images loaded from
/// `paths` (the files just written, as asset paths) or made in memory.
pub(crate) fn spawn_bake_volumes(
    world: &mut World,
    output: &BakeOutput,
    paths: Option<&[String]>,
    carries_ambient: bool,
) {
    let old: Vec<Entity> = world
        .query_filtered::<Entity, With<InAppVolume>>()
        .iter(world)
        .collect();
    for e in old {
        world.despawn(e);
    }
    let entries = lightbake::output::volumes(output);
    for (i, (entry, volume)) in entries.iter().zip(&output.irradiance_volumes).enumerate() {
        // The file's asset (tied to it for hot reloads) holds the new voxels at once.
        let image = match paths.and_then(|p| p.get(i)) {
            Some(path) => {
                let server = world.resource::<AssetServer>().clone();
                let h = server
                    .get_handle::<Image>(path)
                    .unwrap_or_else(|| server.load(path));
                let _ = world
                    .resource_mut::<Assets<Image>>()
                    .insert(h.id(), volume_image(volume));
                h
            }
            None => world
                .resource_mut::<Assets<Image>>()
                .add(volume_image(volume)),
        };
        // Its light groups' sum, registered by `apply_in_app_groups` just before.
        let key = in_app_volume(i);
        let summed = (world.get_resource::<GroupSums>()).is_some_and(|s| s.has_volume(&key));
        let mut e = world.spawn((volume_bundle(entry, image, carries_ambient), InAppVolume));
        if summed {
            e.insert(SummedVolume(key));
        }
    }
}

/// Spawns the volumes a baked glTF lists, as children of its scene's root (so they move with
/// it), once per spawned scene; a volume whose light groups the glTF lists shows their
/// weighted sum ([`crate::groups`]).
pub(crate) fn attach_gltf_volumes(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut sums: Option<ResMut<GroupSums>>,
    scenes: Query<(Entity, &GltfSceneExtras, Option<&ChildOf>), Without<VolumesLookedUp>>,
    roots: Query<&WorldAssetRoot>,
) {
    for (entity, scene_extras, parent) in &scenes {
        commands.entity(entity).insert(VolumesLookedUp);
        let lb: SceneExtras = extras::read(Some(&scene_extras.value), "scene", &mut Vec::new());
        if lb.irradiance_volumes.is_empty() {
            continue;
        }
        let Some(gltf_path) = parent
            .and_then(|p| roots.get(p.parent()).ok())
            .and_then(|root| server.get_path(root.id()))
        else {
            warn!("lightbake: a glTF scene lists irradiance volumes but its file is unknown");
            continue;
        };
        let gltf = gltf_path.without_label().into_owned();
        for (i, entry) in lb.irradiance_volumes.iter().enumerate() {
            let load = |image: &str| match gltf.resolve_embed_str(image) {
                Ok(path) => Some(server.load(path)),
                Err(e) => {
                    warn!("lightbake: {gltf}: bad irradiance volume path {image:?}: {e}");
                    None
                }
            };
            let Some(image) = load(&entry.image) else {
                continue;
            };
            let mut child = commands.spawn((volume_bundle(entry, image, false), ChildOf(entity)));
            // Its light groups' images, summed at the weights the app sets.
            let groups: Option<Vec<(String, Handle<Image>)>> = (lb.light_groups.iter())
                .map(|g| Some((g.name.clone(), load(g.irradiance_volumes.get(i)?)?)))
                .collect();
            let key = GltfVolume {
                gltf: gltf.clone(),
                volume: i as u32,
            };
            if let (Some(groups), Some(sums)) = (groups, sums.as_mut())
                && sums.add_volume(&key, groups)
            {
                child.insert(SummedVolume(key));
            }
        }
    }
}

/// Whether the GPU lets Bevy draw several irradiance volumes in a view, each from its own
/// voxels. Bevy 0.20 binds them as one texture array, which needs texture binding arrays
/// (`bevy_pbr`'s `binding_arrays_are_usable`: the features below and room for its 16
/// material textures and 8 light probes); without them (WebGL 2, many mobile GPUs, Mesa
/// 22's lavapipe; Mesa 25's has them) every volume a fragment lies in is read from one
/// texture, the first volume's, so a level baked with several volumes is lit wrongly there:
/// bake it with `--volume-regions 1` for such targets.
pub fn draws_several_volumes(device: &RenderDevice) -> bool {
    const BINDINGS: u32 = 16 + 8;
    let limits = device.limits();
    limits.max_binding_array_elements_per_shader_stage >= BINDINGS
        && limits.max_binding_array_sampler_elements_per_shader_stage >= BINDINGS
        && device.features().contains(
            WgpuFeatures::TEXTURE_BINDING_ARRAY
                | WgpuFeatures::SAMPLED_TEXTURE_AND_STORAGE_BUFFER_ARRAY_NON_UNIFORM_INDEXING,
        )
}

/// Warns once when several baked volumes are spawned on a GPU that draws only one volume's
/// voxels ([`draws_several_volumes`]).
fn warn_when_one_volume_is_drawn(
    volumes: Query<(), With<BakedVolume>>,
    device: Option<Res<RenderDevice>>,
    mut warned: Local<bool>,
) {
    let n = volumes.iter().count();
    if *warned || n < 2 {
        return;
    }
    let Some(device) = device else {
        return;
    };
    if !draws_several_volumes(&device) {
        warn!(
            "lightbake: {n} irradiance volumes, but this GPU has no texture binding arrays, so Bevy reads every volume from one texture and moving objects are lit wrongly: bake with --volume-regions 1 (volume.regions = 1) for it"
        );
    }
    *warned = true;
}

/// Gives the ambient light back the brightness a shown volume took from it.
pub(crate) fn restore_ambient(world: &mut World) {
    if let Some(b) = world.resource_mut::<SuppressedAmbient>().0.take()
        && let Some(mut a) = world.get_resource_mut::<GlobalAmbientLight>()
    {
        a.brightness = b;
    }
}

/// Shows the baked volumes while [`ShowLightmaps`] is on; while one that carries the ambient
/// light's sky is shown, that light's brightness is zero (see [`BakedVolume`]).
pub(crate) fn sync_volumes(
    show: Res<ShowLightmaps>,
    mut volumes: Query<(&BakedVolume, &mut Visibility)>,
    mut ambient: Option<ResMut<GlobalAmbientLight>>,
    mut suppressed: ResMut<SuppressedAmbient>,
) {
    let mut carries = false;
    for (v, mut visibility) in &mut volumes {
        let wanted = if show.0 {
            Visibility::Inherited
        } else {
            Visibility::Hidden
        };
        visibility.set_if_neq(wanted);
        carries |= show.0 && v.carries_ambient;
    }
    let Some(a) = ambient.as_mut() else {
        return;
    };
    match (carries, suppressed.0) {
        (true, None) => {
            suppressed.0 = Some(a.brightness);
            a.brightness = 0.0;
        }
        (false, Some(b)) => {
            a.brightness = b;
            suppressed.0 = None;
        }
        _ => {}
    }
}
