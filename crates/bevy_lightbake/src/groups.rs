//! Light groups at run time. A glTF baked with light groups (`bake --group NAME=light,...`)
//! lists, in its scene's `extras.lightbake.light_groups`, each group's image of every page
//! and of every irradiance volume. Light adds up, so the plugin shows `Σ weightᵢ × groupᵢ` in
//! place of each page and each volume: a compute pass on the GPU sums the group images into
//! one `Rgba16Float` image per page (2D), which the page's meshes take as their `Lightmap`,
//! and one per volume (3D), which the volume's `IrradianceVolume` takes as its voxels,
//! whenever [`LightGroupWeights`] or a group image changes — in the frame it changes, before
//! the cameras draw. No rebake; the sum never leaves the GPU (the group images stay loaded as
//! the `AssetServer` loads any image).
//!
//! Until a page's (or volume's) group images are loaded and first summed (or where the app
//! has no renderer) it shows what the bake wrote, which is every group at weight 1.

use std::borrow::Cow;
use std::collections::HashMap;
use std::num::NonZeroU64;
use std::sync::{Arc, Mutex};

use bevy::asset::{AssetPath, RenderAssetUsages};
use bevy::core_pipeline::schedule::camera_driver;
use bevy::diagnostic::FrameCount;
use bevy::gltf::GltfSceneExtras;
use bevy::light::IrradianceVolume;
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    texture_2d, texture_3d, texture_storage_2d, texture_storage_3d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupEntry, BindGroupLayoutDescriptor, BindingResource, BufferInitDescriptor, BufferUsages,
    CachedComputePipelineId, ComputePassDescriptor, ComputePipelineDescriptor, Extent3d,
    PipelineCache, ShaderStages, StorageTextureAccess, TextureDimension, TextureFormat, TextureId,
    TextureSampleType, TextureUsages,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph};
use bevy::render::texture::{FallbackImage, GpuImage};
use bevy::render::{RenderApp, RenderStartup};
use lightbake::scene::extras::{self, GroupExtras, SceneExtras};

use crate::LightbakeSystems;
use crate::components::{LightbakeConfig, Lightmapped};
use crate::images::{page_image, volume_image};

/// Group images one pass sums (the least number of textures every GPU binds to one shader
/// stage; the bake takes at most this many groups).
pub const MAX_SUMMED: usize = 16;

/// Weights of the light groups, by group name: a page shows `Σ weight × group`. A group
/// without a weight has weight 1 (the bake's own page); weight 0 leaves its light out. A
/// weight that is negative or not finite counts as 0.
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct LightGroupWeights {
    weights: HashMap<String, f32>,
}

impl LightGroupWeights {
    /// The weight of `group` (1 unless set).
    pub fn get(&self, group: &str) -> f32 {
        let w = self.weights.get(group).copied().unwrap_or(1.0);
        if w.is_finite() { w.max(0.0) } else { 0.0 }
    }

    /// Sets the weight of `group`.
    pub fn set(&mut self, group: impl Into<String>, weight: f32) -> &mut Self {
        self.weights.insert(group.into(), weight);
        self
    }
}

/// Which page of which baked glTF a mesh entity's lightmap is (set with its [`Lightmapped`]
/// by the glTF lookup).
#[derive(Component, Clone, Debug, PartialEq, Eq, Hash)]
pub struct GltfPage {
    /// The baked glTF, without a label.
    pub gltf: AssetPath<'static>,
    /// The page index.
    pub page: u32,
}

/// A mesh entity whose page is shown as a sum of light groups (when it is ready).
#[derive(Component, Clone, Debug)]
pub struct SummedPage(pub GltfPage);

/// Which irradiance volume of which baked glTF (or of the bake in the app) a volume entity
/// shows.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct GltfVolume {
    /// The baked glTF, without a label.
    pub gltf: AssetPath<'static>,
    /// The volume's index in the scene's `irradiance_volumes`.
    pub volume: u32,
}

/// A `LightProbe` + `IrradianceVolume` entity whose voxels are shown as a sum of light groups
/// (when it is ready).
#[derive(Component, Clone, Debug)]
pub struct SummedVolume(pub GltfVolume);

/// A mesh entity whose scene was looked up for light groups.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct GroupsLookedUp;

/// One page (or volume) shown as a weighted sum.
#[derive(Clone, Debug)]
struct SumPage {
    /// Group names and their images of the page.
    sources: Vec<(String, Handle<Image>)>,
    /// The image the sum is written to, once the sources' size is known.
    target: Option<Handle<Image>>,
}

impl SumPage {
    fn new(sources: Vec<(String, Handle<Image>)>) -> Self {
        Self {
            sources,
            target: None,
        }
    }
}

/// The pages and volumes shown as weighted sums, and how far the GPU has got with them.
#[derive(Resource, Default)]
pub struct GroupSums {
    pages: HashMap<GltfPage, SumPage>,
    volumes: HashMap<GltfVolume, SumPage>,
    /// Bumped whenever the weights change.
    generation: u64,
    progress: SumProgress,
}

impl GroupSums {
    /// Pages shown as sums.
    pub fn pages(&self) -> usize {
        self.pages.len()
    }

    /// The sum image of `page`, once created.
    pub fn target(&self, page: &GltfPage) -> Option<&Handle<Image>> {
        self.pages.get(page)?.target.as_ref()
    }

    /// The group images of `page` by group name.
    pub fn sources(&self, page: &GltfPage) -> Vec<(String, Handle<Image>)> {
        self.pages
            .get(page)
            .map(|p| p.sources.clone())
            .unwrap_or_default()
    }

    /// The sum image of `volume`, once created.
    pub fn volume_target(&self, volume: &GltfVolume) -> Option<&Handle<Image>> {
        self.volumes.get(volume)?.target.as_ref()
    }

    /// Whether `volume` is shown as a sum.
    pub fn has_volume(&self, volume: &GltfVolume) -> bool {
        self.volumes.contains_key(volume)
    }

    /// Registers `volume` as shown by the sum of `sources` (its group images by group name),
    /// unless it is already; false when there is nothing to sum or too much (more than
    /// [`MAX_SUMMED`] groups, warned of).
    pub(crate) fn add_volume(
        &mut self,
        volume: &GltfVolume,
        sources: Vec<(String, Handle<Image>)>,
    ) -> bool {
        if self.volumes.contains_key(volume) {
            return true;
        }
        if !summable(&volume.gltf, &sources, "irradiance volumes") {
            return false;
        }
        self.volumes.insert(volume.clone(), SumPage::new(sources));
        true
    }

    /// Every page and volume shown as a sum.
    fn all(&self) -> impl Iterator<Item = &SumPage> {
        self.pages.values().chain(self.volumes.values())
    }

    /// Whether `lightmapped`, of a mesh whose page is `page`, shows the page's sum.
    pub fn shows_sum(&self, page: &SummedPage, lightmapped: &Lightmapped) -> bool {
        self.target(&page.0) == Some(&lightmapped.image)
    }

    /// Whether every page's sum holds the current weights (the GPU pass ran with them).
    pub fn applied(&self) -> bool {
        self.summed_in_frame().is_some()
    }

    /// The frame ([`FrameCount`](bevy::diagnostic::FrameCount) as the render world saw it)
    /// whose render first summed every page at the current weights; `None` before. With
    /// pipelined rendering a frame renders while the next one updates.
    pub fn summed_in_frame(&self) -> Option<u32> {
        let done = self.progress.0.lock().expect("not poisoned");
        let mut last = None;
        for p in self.all() {
            let (generation, frame) = *done.get(&p.target.as_ref()?.id())?;
            if generation != self.generation {
                return None;
            }
            last = last.max(Some(frame));
        }
        last
    }
}

/// Per sum image, the weights' generation the GPU last summed and the frame it did so in
/// (written by the render world).
#[derive(Resource, Clone, Default)]
struct SumProgress(Arc<Mutex<HashMap<AssetId<Image>, (u64, u32)>>>);

/// What the render world sums this frame.
#[derive(Resource, Clone, Default, ExtractResource)]
#[extract_app(RenderApp)]
struct SumJobs(Vec<SumJob>);

#[derive(Clone, Debug, PartialEq)]
struct SumJob {
    target: AssetId<Image>,
    sources: Vec<AssetId<Image>>,
    weights: Vec<f32>,
    generation: u64,
}

/// Light groups at run time: [`LightGroupWeights`], the sums, the GPU pass.
pub struct LightGroupsPlugin;

impl Plugin for LightGroupsPlugin {
    fn build(&self, app: &mut App) {
        let shaders =
            (app.world_mut().get_resource_mut::<Assets<Shader>>()).map(|mut s| SumShaders {
                pages: s.add(sum_shader(false)),
                volumes: s.add(sum_shader(true)),
            });
        let sums = GroupSums::default();
        let progress = sums.progress.clone();
        app.init_resource::<LightGroupWeights>()
            .insert_resource(sums)
            .init_resource::<SumJobs>()
            .add_systems(
                PostUpdate,
                (
                    find_summed_pages,
                    create_targets,
                    (show_sums, show_volume_sums),
                    publish_jobs,
                )
                    .chain()
                    .before(LightbakeSystems::Lightmaps),
            );
        let (Some(render_app), Some(shaders)) = (app.get_sub_app_mut(RenderApp), shaders) else {
            return; // no renderer: the pages the bake wrote stay
        };
        render_app
            .insert_resource(progress)
            .insert_resource(shaders)
            .init_resource::<Dispatched>()
            .add_systems(RenderStartup, init_pipeline)
            .add_systems(RenderGraph, sum_groups.before(camera_driver));
        app.add_plugins(ExtractResourcePlugin::<SumJobs>::default());
    }
}

/// The glTF scene root above `entity` (the entity with the scene's extras), if any.
fn scene_root(
    entity: Entity,
    parents: &Query<&ChildOf>,
    extras: &Query<&GltfSceneExtras>,
) -> Option<Entity> {
    let mut e = entity;
    while !extras.contains(e) {
        e = parents.get(e).ok()?.parent();
    }
    Some(e)
}

/// The key path of the pages of a bake in the app.
const IN_APP: &str = "lightbake-in-app";

/// The key of volume `i` of the bake in the app.
pub(crate) fn in_app_volume(i: usize) -> GltfVolume {
    GltfVolume {
        gltf: AssetPath::from(IN_APP),
        volume: i as u32,
    }
}

/// After a bake in the app: its light groups' pages and volumes as images, each page of
/// `entities` (mesh entity, page index) shown as their sum, and each volume registered under
/// [`in_app_volume`] (for the volume entities the bake spawns next); a bake without groups
/// drops the earlier bake's.
pub(crate) fn apply_in_app_groups(
    world: &mut World,
    groups: &[lightbake::bake::GroupPages],
    entities: &[(Entity, u32)],
) {
    let in_app = AssetPath::from(IN_APP);
    let mut old = world.query::<(Entity, &SummedPage)>();
    let stale: Vec<Entity> = (old.iter(world))
        .filter(|(_, p)| p.0.gltf == in_app)
        .map(|(e, _)| e)
        .collect();
    for e in stale {
        world.entity_mut(e).remove::<SummedPage>();
    }
    let mut sums = world.resource_mut::<GroupSums>();
    sums.pages.retain(|k, _| k.gltf != in_app);
    sums.volumes.retain(|k, _| k.gltf != in_app);
    if groups.is_empty() {
        return;
    }
    let mut images = world.resource_mut::<Assets<Image>>();
    let handles: Vec<Vec<Handle<Image>>> = (groups.iter())
        .map(|g| g.pages.iter().map(|p| images.add(page_image(p))).collect())
        .collect();
    let volumes: Vec<Vec<Handle<Image>>> = (groups.iter())
        .map(|g| {
            (g.irradiance_volumes.iter())
                .map(|v| images.add(volume_image(v)))
                .collect()
        })
        .collect();
    let mut sums = world.resource_mut::<GroupSums>();
    let named = |h: &[Vec<Handle<Image>>], i: usize| -> Vec<(String, Handle<Image>)> {
        (groups.iter().zip(h))
            .filter_map(|(g, h)| Some((g.name.clone(), h.get(i)?.clone())))
            .collect()
    };
    for page in 0..handles[0].len() {
        let key = GltfPage {
            gltf: in_app.clone(),
            page: page as u32,
        };
        sums.pages.insert(key, SumPage::new(named(&handles, page)));
    }
    for volume in 0..volumes[0].len() {
        let key = GltfVolume {
            gltf: in_app.clone(),
            volume: volume as u32,
        };
        sums.add_volume(&key, named(&volumes, volume));
    }
    for &(e, page) in entities {
        if let Ok(mut e) = world.get_entity_mut(e) {
            e.insert(SummedPage(GltfPage {
                gltf: in_app.clone(),
                page,
            }));
        }
    }
}

/// Registers the pages of newly lightmapped glTF meshes whose scene has light groups (their
/// BC6H images where [`crate::images::loads_bc6h`]).
fn find_summed_pages(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut sums: ResMut<GroupSums>,
    config: Res<LightbakeConfig>,
    device: Option<Res<RenderDevice>>,
    new: Query<(Entity, &GltfPage), Without<GroupsLookedUp>>,
    parents: Query<&ChildOf>,
    extras: Query<&GltfSceneExtras>,
) {
    // Each scene's extras are read once, however many of its meshes are new.
    let mut scenes: HashMap<Entity, Vec<GroupExtras>> = HashMap::new();
    let bc6h = crate::images::loads_bc6h(&config, device.as_deref());
    for (entity, page) in &new {
        commands.entity(entity).insert(GroupsLookedUp);
        if sums.pages.contains_key(page) {
            commands.entity(entity).insert(SummedPage(page.clone()));
            continue;
        }
        let Some(root) = scene_root(entity, &parents, &extras) else {
            continue;
        };
        let groups = scenes.entry(root).or_insert_with(|| {
            let x = extras.get(root).map(|x| x.value.as_str()).ok();
            extras::read::<SceneExtras>(x, "scene", &mut Vec::new()).light_groups
        });
        let mut sources = Vec::new();
        for g in groups.iter() {
            let pages = if bc6h && g.pages_bc6h.len() == g.pages.len() {
                &g.pages_bc6h
            } else {
                &g.pages
            };
            let Some(image) = pages.get(page.page as usize) else {
                continue;
            };
            match page.gltf.resolve_embed_str(image) {
                Ok(path) => sources.push((g.name.clone(), server.load(path))),
                Err(e) => warn!(
                    "lightbake: {}: bad light group image {image:?}: {e}",
                    page.gltf
                ),
            }
        }
        if summable(&page.gltf, &sources, "pages") {
            sums.pages.insert(page.clone(), SumPage::new(sources));
            commands.entity(entity).insert(SummedPage(page.clone()));
        }
    }
}

/// Whether the group images `sources` of one of `gltf`'s `what` (pages, volumes) can be
/// summed: some, and no more than [`MAX_SUMMED`] (warned of: then it shows every group at
/// weight 1).
fn summable(gltf: &AssetPath, sources: &[(String, Handle<Image>)], what: &str) -> bool {
    if sources.len() > MAX_SUMMED {
        warn!(
            "lightbake: {gltf} has {} light groups; at most {MAX_SUMMED} are summed, so its {what} show every group at weight 1",
            sources.len()
        );
        return false;
    }
    !sources.is_empty()
}

/// Creates each page's and volume's sum image once its group images are loaded, at their size
/// and dimension (again when a rebake changed them).
fn create_targets(mut sums: ResMut<GroupSums>, mut images: ResMut<Assets<Image>>) {
    let sums = &mut *sums;
    for (key, page) in sums.pages.iter_mut() {
        let what = || format!("{} page {}", key.gltf, key.page);
        create_target(what, page, &mut images);
    }
    for (key, volume) in sums.volumes.iter_mut() {
        let what = || format!("{} irradiance volume {}", key.gltf, key.volume);
        create_target(what, volume, &mut images);
    }
}

/// Creates `page`'s sum image (`what` names it in a warning) when its sources are loaded and
/// it has none of their size.
fn create_target(what: impl Fn() -> String, page: &mut SumPage, images: &mut Assets<Image>) {
    let shapes: Option<Vec<(Extent3d, TextureDimension)>> = (page.sources.iter())
        .map(|(_, h)| {
            let d = &images.get(h)?.texture_descriptor;
            Some((d.size, d.dimension))
        })
        .collect();
    let Some(shapes) = shapes else {
        return; // not all loaded yet
    };
    let shape = shapes[0];
    if shapes.iter().any(|s| *s != shape) {
        warn!(
            "lightbake: {}: its light groups' images differ in size; it shows every group at weight 1",
            what()
        );
        return;
    }
    let current = page.target.as_ref().and_then(|t| images.get(t));
    if current.is_some_and(|t| (t.texture_descriptor.size, t.texture_descriptor.dimension) == shape)
    {
        return;
    }
    let mut image = Image::new_fill(
        shape.0,
        shape.1,
        &[0; 8],
        TextureFormat::Rgba16Float,
        RenderAssetUsages::default(),
    );
    image.texture_descriptor.usage |= TextureUsages::STORAGE_BINDING;
    page.target = Some(images.add(image));
}

/// Points each summed mesh's [`Lightmapped`] at its page's sum once the GPU has written it.
fn show_sums(sums: Res<GroupSums>, mut meshes: Query<(&SummedPage, &mut Lightmapped)>) {
    let done = sums.progress.0.lock().expect("not poisoned");
    for (SummedPage(page), mut lightmapped) in &mut meshes {
        let Some(target) = sums.target(page) else {
            continue;
        };
        if done.contains_key(&target.id()) && lightmapped.image != *target {
            lightmapped.image = target.clone();
        }
    }
}

/// Points each summed volume's voxels at its sum once the GPU has written it.
fn show_volume_sums(
    sums: Res<GroupSums>,
    mut volumes: Query<(&SummedVolume, &mut IrradianceVolume)>,
) {
    let done = sums.progress.0.lock().expect("not poisoned");
    for (SummedVolume(key), mut volume) in &mut volumes {
        let Some(target) = sums.volume_target(key) else {
            continue;
        };
        if done.contains_key(&target.id()) && volume.voxels != *target {
            volume.voxels = target.clone();
        }
    }
}

/// The jobs of this frame for the render world: every page's sum at the current weights.
fn publish_jobs(
    mut sums: ResMut<GroupSums>,
    weights: Res<LightGroupWeights>,
    mut jobs: ResMut<SumJobs>,
) {
    if weights.is_changed() {
        sums.generation += 1;
    }
    let next: Vec<SumJob> = (sums.all())
        .filter_map(|p| {
            Some(SumJob {
                target: p.target.as_ref()?.id(),
                sources: p.sources.iter().map(|(_, h)| h.id()).collect(),
                weights: p.sources.iter().map(|(g, _)| weights.get(g)).collect(),
                generation: sums.generation,
            })
        })
        .collect();
    if jobs.0 != next {
        jobs.0 = next;
    }
}

/// The sum's compute shader for pages (2D) or volumes (3D): `group_sum.wgsl` after the
/// declarations that differ.
fn sum_shader(volume: bool) -> Shader {
    let (d, coords) = if volume {
        ("3d", "id")
    } else {
        ("2d", "id.xy")
    };
    let texel = if volume { "vec3<i32>" } else { "vec2<i32>" };
    let header = format!(
        "alias Group = texture_{d}<f32>;
alias Texel = {texel};
@group(0) @binding(1) var output: texture_storage_{d}<rgba16float, write>;
struct At {{ inside: bool, p: Texel }}
fn texel_of(id: vec3<u32>) -> At {{
    return At(all({coords} < textureDimensions(output)), Texel({coords}));
}}
"
    );
    let name = if volume { "volume" } else { "page" };
    Shader::from_wgsl(
        header + include_str!("group_sum.wgsl"),
        format!("bevy_lightbake/group_sum_{name}.wgsl"),
    )
}

/// The sum's shaders, made once in the main world.
#[derive(Resource, Clone)]
struct SumShaders {
    pages: Handle<Shader>,
    volumes: Handle<Shader>,
}

/// The compute pipelines and their bind group layouts: one for pages (2D), one for volumes
/// (3D).
#[derive(Resource)]
struct SumPipeline {
    pages: (BindGroupLayoutDescriptor, CachedComputePipelineId),
    volumes: (BindGroupLayoutDescriptor, CachedComputePipelineId),
}

fn init_pipeline(mut commands: Commands, shaders: Res<SumShaders>, cache: Res<PipelineCache>) {
    let queue = |volume: bool| {
        let output = if volume {
            texture_storage_3d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly)
        } else {
            texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly)
        };
        let mut entries = vec![
            uniform_buffer_sized(false, NonZeroU64::new(64)).build(0, ShaderStages::COMPUTE),
            output.build(1, ShaderStages::COMPUTE),
        ];
        let float = TextureSampleType::Float { filterable: false };
        for i in 0..MAX_SUMMED as u32 {
            let source = if volume {
                texture_3d(float)
            } else {
                texture_2d(float)
            };
            entries.push(source.build(2 + i, ShaderStages::COMPUTE));
        }
        let label = if volume {
            "lightbake_group_sum_volume"
        } else {
            "lightbake_group_sum"
        };
        let layout = BindGroupLayoutDescriptor::new(label, &entries);
        let pipeline = cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some(label.into()),
            layout: vec![layout.clone()],
            shader: if volume {
                shaders.volumes.clone()
            } else {
                shaders.pages.clone()
            },
            entry_point: Some(Cow::from("sum")),
            ..default()
        });
        (layout, pipeline)
    };
    commands.insert_resource(SumPipeline {
        pages: queue(false),
        volumes: queue(true),
    });
}

/// Per sum image, what it was last summed from: weights (bits) and textures.
#[derive(Resource, Default)]
struct Dispatched(HashMap<AssetId<Image>, (Vec<u32>, Vec<TextureId>, TextureId)>);

/// Sums every page whose weights or images changed since it was last summed, before the
/// cameras draw.
#[allow(clippy::too_many_arguments)]
fn sum_groups(
    mut render_context: RenderContext,
    jobs: Option<Res<SumJobs>>,
    pipeline: Option<Res<SumPipeline>>,
    cache: Res<PipelineCache>,
    images: Res<RenderAssets<GpuImage>>,
    fallback: Res<FallbackImage>,
    device: Res<RenderDevice>,
    progress: Res<SumProgress>,
    frame: Res<FrameCount>,
    mut dispatched: ResMut<Dispatched>,
) {
    let (Some(jobs), Some(pipeline)) = (jobs, pipeline) else {
        return;
    };
    for job in &jobs.0 {
        let Some(target) = images.get(job.target) else {
            continue;
        };
        let sources: Option<Vec<&GpuImage>> = job.sources.iter().map(|s| images.get(*s)).collect();
        let Some(sources) = sources else {
            continue;
        };
        let shape = |t: &GpuImage| (t.texture.size(), t.texture.dimension());
        if sources.iter().any(|s| shape(s) != shape(target)) {
            continue; // a source reloaded at another size: its new target comes next frame
        }
        let volume = target.texture.dimension() == TextureDimension::D3;
        let (layout, id) = if volume {
            &pipeline.volumes
        } else {
            &pipeline.pages
        };
        let Some(compute) = cache.get_compute_pipeline(*id) else {
            continue; // still compiling
        };
        let key = (
            job.weights.iter().map(|w| w.to_bits()).collect::<Vec<_>>(),
            sources.iter().map(|s| s.texture.id()).collect::<Vec<_>>(),
            target.texture.id(),
        );
        let mut done = progress.0.lock().expect("not poisoned");
        if dispatched.0.get(&job.target) == Some(&key) {
            if done.get(&job.target).is_none_or(|d| d.0 != job.generation) {
                done.insert(job.target, (job.generation, frame.0));
            }
            continue;
        }
        let mut weights = [0.0f32; MAX_SUMMED];
        weights[..job.weights.len()].copy_from_slice(&job.weights);
        let bytes: Vec<u8> = weights.iter().flat_map(|w| w.to_le_bytes()).collect();
        let buffer = device.create_buffer_with_data(&BufferInitDescriptor {
            label: Some("lightbake_group_weights"),
            contents: &bytes,
            usage: BufferUsages::UNIFORM,
        });
        let mut entries = vec![
            BindGroupEntry {
                binding: 0,
                resource: buffer.as_entire_binding(),
            },
            BindGroupEntry {
                binding: 1,
                resource: BindingResource::TextureView(&target.texture_view),
            },
        ];
        for i in 0..MAX_SUMMED {
            let unused = if volume { &fallback.d3 } else { &fallback.d2 };
            let view = sources
                .get(i)
                .map_or(&unused.texture_view, |s| &s.texture_view);
            entries.push(BindGroupEntry {
                binding: 2 + i as u32,
                resource: BindingResource::TextureView(view),
            });
        }
        let layout = cache.get_bind_group_layout(layout);
        let bind_group = device.create_bind_group("lightbake_group_sum", &layout, &entries);
        let size = target.texture.size();
        let depth = if volume {
            size.depth_or_array_layers
        } else {
            1
        };
        {
            let mut pass = render_context
                .command_encoder()
                .begin_compute_pass(&ComputePassDescriptor::default());
            pass.set_pipeline(compute);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(size.width.div_ceil(8), size.height.div_ceil(8), depth);
        }
        dispatched.0.insert(job.target, key);
        done.insert(job.target, (job.generation, frame.0));
    }
}
