//! Light groups at run time. A glTF baked with light groups (`bake --group NAME=light,...`)
//! lists, in its scene's `extras.lightbake.light_groups`, each group's image of every page.
//! Light adds up, so the plugin shows `Σ weightᵢ × groupᵢ` in place of each page: a compute
//! pass on the GPU sums the group images into one `Rgba16Float` image per page, which the
//! page's meshes take as their `Lightmap`, whenever [`LightGroupWeights`] or a group image
//! changes — in the frame it changes, before the cameras draw. No rebake; the sum never
//! leaves the GPU (the group images stay loaded as the `AssetServer` loads any image).
//!
//! Until a page's group images are loaded and first summed (or where the app has no
//! renderer) its meshes show the page the bake wrote, which is every group at weight 1.

use std::borrow::Cow;
use std::collections::HashMap;
use std::num::NonZeroU64;
use std::sync::{Arc, Mutex};

use bevy::asset::{AssetPath, RenderAssetUsages, embedded_asset, load_embedded_asset};
use bevy::core_pipeline::schedule::camera_driver;
use bevy::diagnostic::FrameCount;
use bevy::gltf::GltfSceneExtras;
use bevy::prelude::*;
use bevy::render::extract_resource::{ExtractResource, ExtractResourcePlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    texture_2d, texture_storage_2d, uniform_buffer_sized,
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
use crate::components::Lightmapped;
use crate::images::page_image;

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

/// A mesh entity whose scene was looked up for light groups.
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct GroupsLookedUp;

/// One page shown as a weighted sum.
#[derive(Clone, Debug)]
struct SumPage {
    /// Group names and their images of the page.
    sources: Vec<(String, Handle<Image>)>,
    /// The image the sum is written to, once the sources' size is known.
    target: Option<Handle<Image>>,
}

/// The pages shown as weighted sums, and how far the GPU has got with them.
#[derive(Resource, Default)]
pub struct GroupSums {
    pages: HashMap<GltfPage, SumPage>,
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
        for p in self.pages.values() {
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
        embedded_asset!(app, "group_sum.wgsl");
        let sums = GroupSums::default();
        let progress = sums.progress.clone();
        app.init_resource::<LightGroupWeights>()
            .insert_resource(sums)
            .init_resource::<SumJobs>()
            .add_systems(
                PostUpdate,
                (find_summed_pages, create_targets, show_sums, publish_jobs)
                    .chain()
                    .before(LightbakeSystems::Lightmaps),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return; // no renderer: the pages the bake wrote stay
        };
        render_app
            .insert_resource(progress)
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

/// After a bake in the app: its light groups' pages as images, each page of `entities` (mesh
/// entity, page index) shown as their sum; a bake without groups drops the earlier bake's.
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
    world
        .resource_mut::<GroupSums>()
        .pages
        .retain(|k, _| k.gltf != in_app);
    if groups.is_empty() {
        return;
    }
    let mut images = world.resource_mut::<Assets<Image>>();
    let handles: Vec<Vec<Handle<Image>>> = (groups.iter())
        .map(|g| g.pages.iter().map(|p| images.add(page_image(p))).collect())
        .collect();
    let mut sums = world.resource_mut::<GroupSums>();
    for page in 0..handles[0].len() {
        let key = GltfPage {
            gltf: in_app.clone(),
            page: page as u32,
        };
        let sources = (groups.iter().zip(&handles))
            .map(|(g, h)| (g.name.clone(), h[page].clone()))
            .collect();
        sums.pages.insert(
            key,
            SumPage {
                sources,
                target: None,
            },
        );
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

/// Registers the pages of newly lightmapped glTF meshes whose scene has light groups.
fn find_summed_pages(
    mut commands: Commands,
    server: Res<AssetServer>,
    mut sums: ResMut<GroupSums>,
    new: Query<(Entity, &GltfPage), Without<GroupsLookedUp>>,
    parents: Query<&ChildOf>,
    extras: Query<&GltfSceneExtras>,
) {
    // Each scene's extras are read once, however many of its meshes are new.
    let mut scenes: HashMap<Entity, Vec<GroupExtras>> = HashMap::new();
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
            let Some(image) = g.pages.get(page.page as usize) else {
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
        if sources.len() > MAX_SUMMED {
            warn!(
                "lightbake: {} has {} light groups; at most {MAX_SUMMED} are summed, so its pages show every group at weight 1",
                page.gltf,
                sources.len()
            );
            sources.clear();
        }
        if !sources.is_empty() {
            let summed = SumPage {
                sources,
                target: None,
            };
            sums.pages.insert(page.clone(), summed);
            commands.entity(entity).insert(SummedPage(page.clone()));
        }
    }
}

/// Creates each page's sum image once its group images are loaded, at their size (again
/// when a rebake changed it).
fn create_targets(mut sums: ResMut<GroupSums>, mut images: ResMut<Assets<Image>>) {
    for (key, page) in sums.pages.iter_mut() {
        let sizes: Option<Vec<UVec2>> = (page.sources.iter())
            .map(|(_, h)| images.get(h).map(Image::size))
            .collect();
        let Some(sizes) = sizes else {
            continue; // not all loaded yet
        };
        let size = sizes[0];
        if sizes.iter().any(|s| *s != size) {
            warn!(
                "lightbake: {} page {}: its light groups' images differ in size; the page shows every group at weight 1",
                key.gltf, key.page
            );
            continue;
        }
        let current = page.target.as_ref().and_then(|t| images.get(t));
        if current.is_some_and(|t| t.size() == size) {
            continue;
        }
        let mut image = Image::new_fill(
            Extent3d {
                width: size.x,
                height: size.y,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            &[0; 8],
            TextureFormat::Rgba16Float,
            RenderAssetUsages::default(),
        );
        image.texture_descriptor.usage |= TextureUsages::STORAGE_BINDING;
        page.target = Some(images.add(image));
    }
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

/// The jobs of this frame for the render world: every page's sum at the current weights.
fn publish_jobs(
    mut sums: ResMut<GroupSums>,
    weights: Res<LightGroupWeights>,
    mut jobs: ResMut<SumJobs>,
) {
    if weights.is_changed() {
        sums.generation += 1;
    }
    let next: Vec<SumJob> = (sums.pages.values())
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

/// The compute pipeline and its bind group layout.
#[derive(Resource)]
struct SumPipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: CachedComputePipelineId,
}

fn init_pipeline(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    cache: Res<PipelineCache>,
) {
    let mut entries = vec![
        uniform_buffer_sized(false, NonZeroU64::new(64)).build(0, ShaderStages::COMPUTE),
        texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly)
            .build(1, ShaderStages::COMPUTE),
    ];
    for i in 0..MAX_SUMMED as u32 {
        entries.push(
            texture_2d(TextureSampleType::Float { filterable: false })
                .build(2 + i, ShaderStages::COMPUTE),
        );
    }
    let layout = BindGroupLayoutDescriptor::new("lightbake_group_sum", &entries);
    let pipeline = cache.queue_compute_pipeline(ComputePipelineDescriptor {
        label: Some("lightbake_group_sum".into()),
        layout: vec![layout.clone()],
        shader: load_embedded_asset!(asset_server.as_ref(), "group_sum.wgsl"),
        entry_point: Some(Cow::from("sum")),
        ..default()
    });
    commands.insert_resource(SumPipeline { layout, pipeline });
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
    let Some(compute) = cache.get_compute_pipeline(pipeline.pipeline) else {
        return; // still compiling
    };
    for job in &jobs.0 {
        let Some(target) = images.get(job.target) else {
            continue;
        };
        let sources: Option<Vec<&GpuImage>> = job.sources.iter().map(|s| images.get(*s)).collect();
        let Some(sources) = sources else {
            continue;
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
            let view = sources
                .get(i)
                .map_or(&fallback.d2.texture_view, |s| &s.texture_view);
            entries.push(BindGroupEntry {
                binding: 2 + i as u32,
                resource: BindingResource::TextureView(view),
            });
        }
        let layout = cache.get_bind_group_layout(&pipeline.layout);
        let bind_group = device.create_bind_group("lightbake_group_sum", &layout, &entries);
        let size = target.texture.size();
        {
            let mut pass = render_context
                .command_encoder()
                .begin_compute_pass(&ComputePassDescriptor::default());
            pass.set_pipeline(compute);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(size.width.div_ceil(8), size.height.div_ceil(8), 1);
        }
        dispatched.0.insert(job.target, key);
        done.insert(job.target, (job.generation, frame.0));
    }
}
