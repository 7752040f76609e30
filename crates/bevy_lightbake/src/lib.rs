//! # bevy_lightbake
//!
//! Bake lightmaps inside a Bevy 0.20 game with the [`lightbake`] baker, and show lightmaps
//! baked by the `bake` command.
//!
//! * Mark static meshes with [`Lightbaked`]. Every `PointLight`, `SpotLight` and
//!   `DirectionalLight` (unless marked [`NotBaked`]), every emissive `StandardMaterial` and
//!   the `GlobalAmbientLight` (as a sky; see [`SkySource`]) are baked.
//! * Write a [`RequestBake`] message. The world is converted into the core's scene and baked
//!   on a background thread with its own worker pool (cores − 1 threads by default), so the
//!   game keeps running (not on Bevy's `AsyncComputeTaskPool`, whose one thread on a small
//!   machine also compiles the render pipelines); [`BakeStatus`] shows the stage, fraction and the solver's error estimate;
//!   [`CancelBake`] stops it. When it is done the meshes get `Mesh::ATTRIBUTE_UV_1`, the
//!   entities get Bevy's `bevy::pbr::Lightmap`, the baked lights get
//!   `affects_lightmapped_mesh_diffuse = false`, and [`BakeFinished`] is written.
//! * The lightmaps are written (temporary file, then rename) into
//!   `assets/<output_dir>/lightmaps/` and loaded through the `AssetServer`; with Bevy's
//!   `file_watcher` (this crate's default feature) a rewrite by the `bake` command shows up in
//!   the running game.
//! * A glTF baked by the `bake` command gets its lightmaps as soon as its scene spawns, and
//!   its irradiance volumes (`bake --irradiance-volume`) as `LightProbe` + `IrradianceVolume`
//!   entities under the scene's root.
//! * With `LightbakeConfig::settings.volume.enabled` an in-app bake also spawns an
//!   irradiance volume, so moving meshes (without [`Lightbaked`]) get the baked indirect light
//!   (see [`volumes`]).
//! * While a bake runs the lightmaps show its progress ([`LightbakeConfig::previews`]): the
//!   direct light, then the coarse indirect light, then the result; [`BakeStatus::preview`]
//!   says which.
//! * A light with [`BakeMode::IndirectOnly`] stays real time, with Bevy's shadows; the
//!   lightmaps add only what it reflects (mixed lighting). `RectLight`s are baked that way
//!   by default, since Bevy 0.20 cannot stop them lighting lightmapped meshes.
//! * Light groups (`bake --group`, or a [`LightGroup`] on lights baked in the app) bake into
//!   lightmaps of their own; the meshes show `Σ weight × group`, summed on the GPU in the
//!   frame [`LightGroupWeights`] changes (see [`groups`]).
//!
//! Texels store irradiance / π, shown by Bevy with `lightmap_exposure = 1` (the default);
//! units are Bevy's (lumens, lux, nits). See `docs/units.md`.
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_lightbake::prelude::*;
//!
//! fn main() {
//!     App::new()
//!         .add_plugins((DefaultPlugins, LightbakePlugin))
//!         .add_systems(Startup, setup)
//!         .run();
//! }
//!
//! fn setup(
//!     mut commands: Commands,
//!     mut meshes: ResMut<Assets<Mesh>>,
//!     mut materials: ResMut<Assets<StandardMaterial>>,
//!     mut bake: MessageWriter<RequestBake>,
//! ) {
//!     commands.spawn((
//!         Mesh3d(meshes.add(Plane3d::default().mesh().size(10.0, 10.0))),
//!         MeshMaterial3d(materials.add(Color::WHITE)),
//!         Lightbaked::default(),
//!     ));
//!     commands.spawn((PointLight::default(), Transform::from_xyz(0.0, 3.0, 0.0)));
//!     commands.spawn((Camera3d::default(), Transform::from_xyz(0.0, 6.0, 8.0).looking_at(Vec3::ZERO, Vec3::Y)));
//!     bake.write(RequestBake::default());
//! }
//! ```

//!
//! # Organised by feature
//!
//! [`LightbakePlugin`] orders the [`LightbakeSystems`] sets and adds one plugin per feature,
//! as `bevy_pbr`'s light probes do: [`requests::BakeRequestsPlugin`] (bake requests, the
//! background bake and its status, with progressive previews), [`lightmaps::LightmapsPlugin`]
//! (lightmaps applied to meshes and kept in step with their images),
//! [`volumes::VolumesPlugin`] (irradiance volumes), [`gltf::GltfScenesPlugin`] (baked glTF
//! scenes) and [`groups::LightGroupsPlugin`] (light groups at run time).
// Bevy systems name their data in their signatures: long query types and many parameters are
// the idiom (Bevy's own crates allow both).
#![allow(clippy::type_complexity, clippy::too_many_arguments)]

pub mod capture;
pub mod components;
pub mod convert;
pub mod gltf;
pub mod groups;
pub mod images;
pub mod lightmaps;
mod preview;
pub mod rebake;
pub mod requests;
pub mod sample;
pub mod spawn;
pub mod volumes;

use bevy::asset::AssetEventSystems;
use bevy::prelude::*;

pub use components::{
    BakeFinished, BakeMode, BakeOutcome, BakePhase, BakeStatus, BakedLight, BakedVolume,
    CancelBake, LightGroup, LightbakeConfig, Lightbaked, Lightmapped, NotBaked, RequestBake,
    ShowLightmaps, SkySource,
};
pub use groups::LightGroupWeights;
pub use lightbake;

/// The usual imports.
pub mod prelude {
    pub use crate::components::{
        BakeFinished, BakeMode, BakeOutcome, BakePhase, BakeStatus, BakedVolume, CancelBake,
        LightGroup, LightbakeConfig, Lightbaked, Lightmapped, NotBaked, RequestBake, ShowLightmaps,
        SkySource,
    };
    pub use crate::groups::LightGroupWeights;
    pub use crate::{LightbakePlugin, LightbakeSystems};
    pub use lightbake::BakeSettings;
    pub use lightbake::bake::PreviewKind;
}

/// Ordering of the plugin's systems.
#[derive(SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightbakeSystems {
    /// `Update`: read [`RequestBake`] / [`CancelBake`].
    Requests,
    /// `Update`, after `Requests`: start a bake, poll the running one, apply its results.
    Bake,
    /// `Update`, after `Bake`: find lightmaps of baked glTF scenes.
    Gltf,
    /// `PostUpdate`, after the asset events and before Bevy's mesh re-specialization check:
    /// prepare lightmap images and insert, remove or re-insert Bevy's `Lightmap` components.
    Lightmaps,
}

/// The plugin. Add it after Bevy's `DefaultPlugins` (it needs assets, meshes, images and the
/// PBR types); configure it with the [`LightbakeConfig`] resource.
#[derive(Default)]
pub struct LightbakePlugin;

impl Plugin for LightbakePlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<Lightbaked>()
            .register_type::<LightGroup>()
            .register_type::<NotBaked>()
            .register_type::<BakeMode>()
            .configure_sets(
                Update,
                (
                    LightbakeSystems::Requests,
                    LightbakeSystems::Bake,
                    LightbakeSystems::Gltf,
                )
                    .chain(),
            )
            .configure_sets(
                PostUpdate,
                LightbakeSystems::Lightmaps
                    .after(AssetEventSystems)
                    // Before Bevy decides which meshes need a new pipeline (see
                    // `lightmaps::sync_lightmaps`).
                    .before(bevy::pbr::check_entities_needing_specialization::<StandardMaterial>),
            )
            .add_plugins((
                requests::BakeRequestsPlugin,
                lightmaps::LightmapsPlugin,
                volumes::VolumesPlugin,
                gltf::GltfScenesPlugin,
                groups::LightGroupsPlugin,
                rebake::AutoRebakePlugin,
            ));
    }
}
