//! What a game puts in its world to bake, and what the plugin puts back.

use std::path::PathBuf;

use bevy::asset::io::file::FileAssetReader;
use bevy::prelude::*;
use lightbake::BakeSettings;
use lightbake::report::BakeReport;

/// Marks a static mesh entity (`Mesh3d` + `MeshMaterial3d<StandardMaterial>`) as part of the
/// baked scene: it casts shadows, reflects light and, when `receive_lightmap` is set, gets a
/// lightmap. Meshes without it (characters, props that move) are left out of the bake
/// entirely.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component, Default)]
pub struct Lightbaked {
    /// Lightmap texels per metre for this mesh; `None` uses the bake's density
    /// ([`LightbakeConfig::settings`]`.texel_density`, or the one chosen from its texel
    /// budget). Default `None`.
    pub texel_density: Option<f32>,
    /// Give this mesh a lightmap. `false` keeps it as an occluder and reflector only (a
    /// mesh that is never seen up close). Default `true`.
    pub receive_lightmap: bool,
}

impl Default for Lightbaked {
    fn default() -> Self {
        Self {
            texel_density: None,
            receive_lightmap: true,
        }
    }
}

impl Lightbaked {
    /// Baked at the given density, texels per metre.
    pub fn with_density(texels_per_metre: f32) -> Self {
        Self {
            texel_density: Some(texels_per_metre),
            ..Self::default()
        }
    }

    /// An occluder and reflector that gets no lightmap.
    pub fn occluder() -> Self {
        Self {
            receive_lightmap: false,
            ..Self::default()
        }
    }
}

/// On a `PointLight`, `SpotLight` or `DirectionalLight`: leave this light out of the bake. It
/// keeps lighting everything in real time (a torch the player carries, a flickering lamp).
/// Every light without it is baked.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Default)]
pub struct NotBaked;

/// On a `PointLight`, `SpotLight`, `DirectionalLight` or `RectLight`, or on a [`Lightbaked`]
/// mesh with an emissive `StandardMaterial`: the light group its light bakes into
/// (`lightbake::settings::groups`; the sky's is [`LightbakeConfig::sky_group`]). A bake in the
/// app with groups writes one set of lightmaps (and volumes) per group (lights and emitters
/// without a group go to `ungrouped`), and the meshes and volumes show their sum at the
/// [`LightGroupWeights`](crate::LightGroupWeights). A material's light belongs to one group:
/// meshes sharing an emissive material share the first one's group (with a warning). The
/// name names files: letters, digits, `_` and `-`.
#[derive(Component, Clone, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct LightGroup(pub String);

/// On a `PointLight`, `SpotLight`, `DirectionalLight` or `RectLight`: which part of its light
/// the bake puts into the lightmaps. Without it, point, spot and directional lights are baked
/// [`BakeMode::Full`] and rect lights [`BakeMode::IndirectOnly`].
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub enum BakeMode {
    /// Direct and indirect light: after the bake the light stops lighting lightmapped meshes
    /// (`affects_lightmapped_mesh_diffuse = false`) but still lights dynamic objects and
    /// gives specular highlights.
    Full,
    /// Only the light it sends after a reflection (Bevy's mixed lighting): the light stays
    /// real time on lightmapped meshes too, with Bevy's shadows, and the lightmaps add what it
    /// reflects. The default for `RectLight`: Bevy 0.20 has no switch to stop a rect light
    /// lighting lightmapped meshes (its shader always adds their diffuse light), so its
    /// direct light cannot be baked without showing twice.
    IndirectOnly,
}

/// Where the bake's sky (light arriving from outside the scene) comes from.
#[derive(Clone, Copy, Debug, PartialEq, Reflect)]
pub enum SkySource {
    /// Bevy's `GlobalAmbientLight`: `color × brightness`, in nits (cd/m²), as Bevy defines
    /// it. Baked, it is occluded like a real sky, so rooms get darker inside than under
    /// Bevy's uniform ambient. After a bake the ambient light stops lighting lightmapped
    /// meshes (`affects_lightmapped_meshes = false`). The default.
    GlobalAmbient,
    /// The camera clear colour (`ClearColor`, linear) times this luminance in nits: the
    /// background the player sees lights the scene.
    ClearColor {
        /// Luminance of a clear colour of (1, 1, 1), nits.
        nits: f32,
    },
    /// A fixed linear RGB luminance, nits.
    Nits(Vec3),
    /// No sky.
    None,
}

/// How the plugin bakes. Change it at any time; the next bake uses it.
#[derive(Resource, Clone, Debug)]
pub struct LightbakeConfig {
    /// Everything the core baker takes: quality, method, solver, texel density, ... Default:
    /// [`BakeSettings::medium`] with `threads` = cores − 1 (at least 1), so that the game
    /// keeps a core while it bakes.
    pub settings: BakeSettings,
    /// Where the sky comes from. Default [`SkySource::GlobalAmbient`].
    pub sky: SkySource,
    /// The light group the sky bakes into (see [`LightGroup`]), unless a group of
    /// `settings.groups` already holds it; a name of letters, digits, `_` and `-`. Default
    /// none: the sky goes to `ungrouped` when the bake has groups.
    pub sky_group: Option<String>,
    /// Write the lightmaps (EXR + PNG preview), `manifest.json` and `report.json` into
    /// `assets_folder/output_dir` and load them through the `AssetServer`, so that they are
    /// assets like any other: hot-reloaded when the `bake` command rewrites them, and kept
    /// when the game ships. `false` keeps them in memory only. Default `true`.
    pub write_files: bool,
    /// The folder Bevy's `AssetPlugin` reads (`AssetPlugin::file_path`, resolved). Default:
    /// Bevy's base path (`BEVY_ASSET_ROOT`, else `CARGO_MANIFEST_DIR`, else the executable's
    /// folder) joined with `assets`. Set it when your `AssetPlugin` uses another folder.
    pub assets_folder: PathBuf,
    /// Sub-folder of `assets_folder` for in-app bakes, as an asset path. Default `lightbake`.
    pub output_dir: String,
    /// After attaching lightmaps, stop `GlobalAmbientLight` from also lighting lightmapped
    /// meshes (the bake already contains all diffuse light it knows of). Default `true`.
    pub disable_ambient_on_lightmapped: bool,
    /// Show the lightmaps while the bake runs: the direct light first, then the coarse
    /// indirect light (with progressive radiosity's ambient term for the rest), then the
    /// result ([`BakeStatus::preview`] says which). A bake that is cancelled or fails puts the
    /// previous lightmaps back. Default `true`.
    pub previews: bool,
    /// Load BC6H pages (1 byte per texel against `Rgba16Float`'s 8) in place of the other
    /// pages, where the bake wrote them (`bake --format exr,ktx2-bc6h`; in the app,
    /// `settings.formats.ktx2_bc6h` with [`Self::write_files`]) and the GPU samples BC
    /// textures (`TEXTURE_COMPRESSION_BC`: desktop GPUs; not WebGL 2 or most mobile GPUs,
    /// which load the other pages). Read when a baked glTF's meshes are first looked up, and
    /// when an in-app bake finishes (its pages show as half floats until the BC6H files are
    /// read). Default `true`.
    pub bc6h: bool,
    /// Bake again, incrementally, after an edit: when a [`Lightbaked`] entity moves, a baked
    /// light moves or changes its colour, intensity, range or cone, or a baked mesh's
    /// material changes its base colour or emission, a [`RequestBake`] is sent once the
    /// world has stayed unchanged for [`Self::rebake_after_seconds`]. The bake follows the
    /// last finished one (`lightbake::incremental`): unchanged meshes keep their lightmap
    /// layout and only what the edit can change is computed again. Watched only after a
    /// first bake has finished; the sky is not watched. Default `false`.
    pub auto_rebake: bool,
    /// How long the world must stay unchanged after an edit before an automatic rebake
    /// starts, seconds (an edit during a rebake cancels it and starts another after this
    /// pause). Default 0.3.
    pub rebake_after_seconds: f32,
}

impl Default for LightbakeConfig {
    fn default() -> Self {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Self {
            settings: BakeSettings {
                threads: cores.saturating_sub(1).max(1),
                ..BakeSettings::medium()
            },
            sky: SkySource::GlobalAmbient,
            sky_group: None,
            write_files: true,
            assets_folder: FileAssetReader::get_base_path().join("assets"),
            output_dir: "lightbake".into(),
            disable_ambient_on_lightmapped: true,
            previews: true,
            bc6h: true,
            auto_rebake: false,
            rebake_after_seconds: 0.3,
        }
    }
}

/// What the plugin is doing, for progress bars and tests.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum BakePhase {
    /// No bake has been requested yet.
    #[default]
    Idle,
    /// A bake is running in the background.
    Running,
    /// The last bake finished; its lightmaps are attached (or loading).
    Done,
    /// The last bake was cancelled; the previous lightmaps stay.
    Cancelled,
    /// The last bake failed with this message; the previous lightmaps stay.
    Failed(String),
}

/// Progress of the running bake, updated every frame while it runs.
#[derive(Resource, Clone, Debug, Default)]
pub struct BakeStatus {
    /// What is happening.
    pub phase: BakePhase,
    /// The running stage and its round (`None` before the first stage of a bake).
    pub stage: Option<lightbake::StageRun>,
    /// How many stages have started.
    pub stage_index: u64,
    /// Fraction of the running stage done, [0, 1].
    pub fraction: f32,
    /// The running stage's own estimate of its relative error so far (the radiosity solvers
    /// publish one per sweep), when it has one.
    pub error_estimate: Option<f32>,
    /// The stages finished so far in the running (or last) bake, in order: wall time, rays
    /// and, for the sampling stages, their own error estimate
    /// ([`lightbake::report::ErrorEstimate`], relative RMS and 95th percentile).
    pub finished_stages: Vec<lightbake::report::StageStats>,
    /// Seconds since the bake started (wall clock).
    pub elapsed_seconds: f32,
    /// What the lightmaps on screen show while a bake runs and after it: its direct light,
    /// its first indirect solution, or the final result (`None` before the first preview,
    /// and after a bake that was cancelled or failed, when the previous lightmaps are back).
    pub preview: Option<lightbake::bake::PreviewKind>,
    /// Bakes finished (with lightmaps) since the app started.
    pub completed: u32,
    /// The report of the last finished bake: stages, timings, rays, error estimates.
    pub last_report: Option<Box<BakeReport>>,
}

impl BakeStatus {
    /// Whether a bake is running.
    pub fn is_running(&self) -> bool {
        self.phase == BakePhase::Running
    }
}

/// Message: bake the marked world now. A bake already running is cancelled and the new one
/// starts when it has stopped.
#[derive(Message, Clone, Debug, Default)]
pub struct RequestBake {
    /// Settings for this bake only; `None` uses [`LightbakeConfig::settings`].
    pub settings: Option<BakeSettings>,
    /// Bake every texel even where the last finished bake in the app could be followed
    /// (`lightbake::incremental`). Default `false`: a bake with the same settings as the last
    /// one recomputes only what changed since.
    pub full: bool,
}

/// Message: stop the running bake. Nothing is written and the previous lightmaps stay.
#[derive(Message, Clone, Copy, Debug, Default)]
pub struct CancelBake;

/// How a bake ended.
#[derive(Clone, Debug, PartialEq)]
pub enum BakeOutcome {
    /// Lightmaps were made and are being attached.
    Baked,
    /// [`CancelBake`] (or a newer [`RequestBake`]) stopped it.
    Cancelled,
    /// The scene or settings were rejected; the message names what is wrong.
    Failed(String),
}

/// Message written when a bake ends.
#[derive(Message, Clone, Debug)]
pub struct BakeFinished {
    /// How it ended.
    pub outcome: BakeOutcome,
    /// Wall-clock seconds from the request to the end.
    pub seconds: f64,
    /// Lightmapped entities (mesh entities that got a lightmap).
    pub lightmapped: usize,
}

/// The lightmap the plugin keeps on a mesh entity (from an in-app bake or a baked glTF).
/// The plugin derives Bevy's `bevy::pbr::Lightmap` from it: inserted once the image is
/// loaded and in a GPU-friendly format (`Rgba16Float`), removed while [`ShowLightmaps`] is
/// off, and re-inserted a frame later when the image is replaced by one of another size
/// (Bevy's renderer ignores a `Lightmap` whose image changes in place).
#[derive(Component, Clone, Debug, PartialEq)]
pub struct Lightmapped {
    /// The page image.
    pub image: Handle<Image>,
    /// Bevy's `Lightmap::uv_rect`: where this mesh's `UV_1` square lies on the page.
    pub uv_rect: Rect,
}

impl Lightmapped {
    /// Whether `lightmap` (the entity's Bevy `Lightmap`, if any) shows this lightmap: its
    /// image and rectangle. After a bake, an entity keeps showing its preview (or previous
    /// lightmap) until the new image has loaded; a test or a screenshot that wants the final
    /// picture waits until this holds for every entity.
    pub fn is_shown_by(&self, lightmap: Option<&bevy::pbr::Lightmap>) -> bool {
        lightmap.is_some_and(|l| l.image == self.image && l.uv_rect == self.uv_rect)
    }
}

/// Show the baked lightmaps (`true`, the default) or Bevy's real-time lighting (`false`:
/// every plugin-managed `Lightmap` is removed, so baked lights and the ambient light light
/// those meshes again in real time).
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShowLightmaps(pub bool);

impl Default for ShowLightmaps {
    fn default() -> Self {
        Self(true)
    }
}

/// On a light whose diffuse light is in the lightmaps: the plugin set its
/// `affects_lightmapped_mesh_diffuse` to `false`.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BakedLight;

/// On a `LightProbe` + `IrradianceVolume` entity the plugin spawned from a bake (in the app,
/// or listed in a baked glTF's scene extras). Shown while [`ShowLightmaps`] is on.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BakedVolume {
    /// The volume carries the light of `GlobalAmbientLight` (the bake's sky came from it):
    /// while the volume is shown the plugin turns that ambient light's brightness to zero, so
    /// dynamic objects do not get the sky twice (once occluded from the volume, once
    /// unoccluded from the ambient light), and restores it when the volume is hidden.
    pub carries_ambient: bool,
}
