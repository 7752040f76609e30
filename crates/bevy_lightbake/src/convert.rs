//! The marked Bevy world → the core's [`Scene`], and the unit conversions between the two.
//!
//! | Bevy 0.20 | core scene | conversion |
//! |---|---|---|
//! | `PointLight::intensity`, `SpotLight::intensity` (lumens) | candela | I = Φ / 4π (Bevy's own shading divides by 4π) |
//! | `PointLight::range`, `SpotLight::range` (m) | `range` | same; Bevy's window (1 − (d/r)⁴)² |
//! | `SpotLight::{inner,outer}_angle` (rad) | cone angles | same |
//! | `DirectionalLight::illuminance` (lux) | lux | same; `SunDisk::angular_size / 2` is the angular radius |
//! | `RectLight::{intensity, width, height}` (lumens, m, local XY facing −Z) | luminance, nits | L = Φ / (π·w·h), w and h scaled by the transform (Bevy's own conversion) |
//! | [`BakeMode`] on a light | `LightBake` | `Full` (default; rect lights `IndirectOnly`) |
//! | [`LightGroup`] on a light | a member `light:NAME` of `BakeSettings::groups` | the light's name made unique |
//! | [`LightGroup`] on a `Lightbaked` mesh with an emissive material | a member `material:NAME` | one group per material |
//! | `Color` | linear RGB | `Color::to_linear` |
//! | `StandardMaterial::emissive` (`LinearRgba`, nits) | `emissive`, nits | same |
//! | `StandardMaterial::{base_color, base_color_texture, metallic, double_sided}` | same | linear; sRGB texture |
//! | `GlobalAmbientLight::{color, brightness}` (nits) | sky, nits | `color × brightness` |
//! | `GlobalTransform` | `Instance::transform` | same matrix |
//!
//! See `docs/units.md` for what a texel stores (E/π, shown by Bevy with `lightmap_exposure` 1).

use std::collections::HashMap;
use std::f32::consts::PI;

use bevy::asset::AssetId;
use bevy::image::{ImageAddressMode, ImageSampler};
use bevy::light::RectLight;
use bevy::light::{GlobalAmbientLight, SunDisk};
use bevy::mesh::{Indices, MeshAccessError, PrimitiveTopology, UvChannel, VertexAttributeValues};
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use lightbake::scene::{
    Instance as CoreInstance, Light as CoreLight, LightBake, LightKind, Material as CoreMaterial,
    Mesh as CoreMesh, Scene, Texture as CoreTexture, TextureRef, Wrap,
};

use crate::components::{BakeMode, LightGroup, Lightbaked, NotBaked, SkySource};

/// Which Bevy entity and asset each part of the core scene came from, to carry the bake's
/// results back.
#[derive(Clone, Debug, Default)]
pub struct SceneMapping {
    /// Per core instance: its mesh entity.
    pub instances: Vec<Entity>,
    /// Per core instance: its core mesh.
    pub instance_meshes: Vec<usize>,
    /// Per core mesh: the Bevy mesh it was read from.
    pub meshes: Vec<MeshSource>,
    /// Light entities whose direct light is baked ([`BakeMode::Full`]): after the bake they
    /// stop lighting lightmapped meshes.
    pub lights: Vec<Entity>,
    /// Light entities baked indirect only ([`BakeMode::IndirectOnly`]): they stay real time.
    pub realtime_lights: Vec<Entity>,
    /// The sky was taken from `GlobalAmbientLight`.
    pub sky_from_ambient: bool,
}

/// The Bevy mesh behind one core mesh.
#[derive(Clone, Debug)]
pub struct MeshSource {
    /// The asset the entities use.
    pub handle: Handle<Mesh>,
    /// A copy of the asset as it was read (the bake's vertex remap applies to this).
    pub original: Mesh,
    /// Another core mesh (another material on the same asset) came first: this one gets a
    /// new asset of its own, since its unwrap differs.
    pub needs_own_asset: bool,
}

/// Linear RGB of a Bevy colour as the core's vector.
pub fn linear_rgb(c: Color) -> lightbake::glam::Vec3 {
    let l = c.to_linear();
    lightbake::glam::Vec3::new(l.red, l.green, l.blue)
}

/// Bevy's luminous power (lumens) of a point or spot light → luminous intensity (candela).
pub fn lumens_to_candela(lumens: f32) -> f32 {
    lumens / (4.0 * PI)
}

fn affine(t: &GlobalTransform) -> lightbake::glam::Affine3A {
    lightbake::glam::Affine3A::from_cols_array(&t.affine().to_cols_array())
}

fn vec3(v: Vec3) -> lightbake::glam::Vec3 {
    lightbake::glam::Vec3::from_array(v.to_array())
}

/// Why part of the world cannot be baked; each names the entity, mesh or texture (`label`).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConvertError {
    /// A mesh that is not a triangle list.
    #[error("{label}: the mesh is a {topology}; only triangle lists can be baked")]
    NotTriangles {
        /// The entity or mesh.
        label: String,
        /// Its primitive topology.
        topology: String,
    },
    /// Mesh data that lives only on the GPU.
    #[error(
        "{label}: mesh data is not readable on the CPU ({reason}); keep RenderAssetUsages::MAIN_WORLD on baked meshes"
    )]
    NotOnCpu {
        /// The entity or mesh.
        label: String,
        /// Bevy's reason.
        reason: String,
    },
    /// A vertex attribute in a format the baker does not read.
    #[error("{label}: {attribute} are {found}; expected {expected}")]
    AttributeFormat {
        /// The entity or mesh.
        label: String,
        /// The attribute, in words (`positions`, `UV_0 coordinates`, ...).
        attribute: &'static str,
        /// Its format.
        found: &'static str,
        /// The format the baker reads.
        expected: &'static str,
    },
    /// A mesh without positions.
    #[error("{label}: the mesh has no positions")]
    NoPositions {
        /// The entity or mesh.
        label: String,
    },
    /// A baked entity whose mesh asset is not loaded yet.
    #[error("{label}: its mesh is not loaded yet; bake once it is")]
    MeshNotLoaded {
        /// The entity.
        label: String,
    },
    /// A texture in a format the baker does not read.
    #[error(
        "{label}: texture format {format} is not read by the baker (8-bit RGBA only); its mean colour is taken as white"
    )]
    TextureFormat {
        /// The material's texture.
        label: String,
        /// Its format.
        format: String,
    },
    /// A texture whose pixels are not on the CPU.
    #[error("{label}: texture pixels are not on the CPU")]
    TextureNotOnCpu {
        /// The material's texture.
        label: String,
    },
}

/// The name used in messages: the entity's `Name`, else its id.
pub fn entity_label(entity: Entity, name: Option<&Name>) -> String {
    name.map_or_else(|| format!("entity {entity}"), |n| n.as_str().to_string())
}

/// Reads a Bevy mesh as a core mesh (no material yet).
///
/// # Errors
/// A [`ConvertError`] naming `label` when the mesh cannot be baked (not a triangle list, no
/// positions, attribute formats the baker does not read, data only on the GPU).
pub fn core_mesh(mesh: &Mesh, label: &str) -> Result<CoreMesh, ConvertError> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(ConvertError::NotTriangles {
            label: label.to_string(),
            topology: format!("{:?}", mesh.primitive_topology()),
        });
    }
    let unreadable = |e: MeshAccessError| ConvertError::NotOnCpu {
        label: label.to_string(),
        reason: e.to_string(),
    };
    let format =
        |attribute, found: &VertexAttributeValues, expected| ConvertError::AttributeFormat {
            label: label.to_string(),
            attribute,
            found: found.enum_variant_name(),
            expected,
        };
    let float3 = |attr, what| -> Result<Option<Vec<lightbake::glam::Vec3>>, ConvertError> {
        match mesh.try_attribute_option(attr).map_err(unreadable)? {
            None => Ok(None),
            Some(VertexAttributeValues::Float32x3(v)) => Ok(Some(
                v.iter()
                    .map(|p| lightbake::glam::Vec3::from_array(*p))
                    .collect(),
            )),
            Some(other) => Err(format(what, other, "Float32x3")),
        }
    };
    let float2 = |attr, what| -> Result<Option<Vec<lightbake::glam::Vec2>>, ConvertError> {
        match mesh.try_attribute_option(attr).map_err(unreadable)? {
            None => Ok(None),
            Some(VertexAttributeValues::Float32x2(v)) => Ok(Some(
                v.iter()
                    .map(|p| lightbake::glam::Vec2::from_array(*p))
                    .collect(),
            )),
            Some(other) => Err(format(what, other, "Float32x2")),
        }
    };
    let positions = float3(Mesh::ATTRIBUTE_POSITION, "positions")?.ok_or_else(|| {
        ConvertError::NoPositions {
            label: label.to_string(),
        }
    })?;
    let normals = float3(Mesh::ATTRIBUTE_NORMAL, "normals")?;
    let uv0 = float2(Mesh::ATTRIBUTE_UV_0, "UV_0 coordinates")?;
    let uv1 = float2(Mesh::ATTRIBUTE_UV_1, "UV_1 coordinates")?;
    let indices: Vec<u32> = match mesh.try_indices_option().map_err(unreadable)? {
        Some(Indices::U16(i)) => i.iter().map(|&i| i as u32).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => (0..positions.len() as u32).collect(),
    };
    let mut core = CoreMesh {
        name: label.to_string(),
        normals: normals.unwrap_or_default(),
        positions,
        uv0,
        uv1,
        indices,
        material: None,
        source: None,
    };
    if core.normals.len() != core.positions.len() {
        core.compute_normals();
    }
    Ok(core)
}

/// A Bevy image as a core texture (8-bit RGBA only).
///
/// # Errors
/// [`ConvertError::TextureFormat`] when the format is not 8-bit RGBA,
/// [`ConvertError::TextureNotOnCpu`] when the pixels are not on the CPU.
pub fn core_texture(image: &Image, label: &str) -> Result<CoreTexture, ConvertError> {
    let format = image.texture_descriptor.format;
    if !matches!(
        format,
        TextureFormat::Rgba8UnormSrgb | TextureFormat::Rgba8Unorm
    ) {
        return Err(ConvertError::TextureFormat {
            label: label.to_string(),
            format: format!("{format:?}"),
        });
    }
    let data = image
        .data
        .as_ref()
        .ok_or_else(|| ConvertError::TextureNotOnCpu {
            label: label.to_string(),
        })?;
    let wrap = |m: ImageAddressMode| match m {
        ImageAddressMode::Repeat => Wrap::Repeat,
        ImageAddressMode::MirrorRepeat => Wrap::MirroredRepeat,
        _ => Wrap::ClampToEdge,
    };
    let (wrap_u, wrap_v) = match &image.sampler {
        ImageSampler::Descriptor(d) => (wrap(d.address_mode_u), wrap(d.address_mode_v)),
        ImageSampler::Default => (Wrap::Repeat, Wrap::Repeat),
    };
    Ok(CoreTexture {
        name: label.to_string(),
        width: image.width(),
        height: image.height(),
        rgba8: data
            .chunks_exact(4)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
        wrap_u,
        wrap_v,
    })
}

/// A material's name in the bake's reports and light groups: its asset path
/// (`level.gltf#Material2`), else `unnamed K` for the K-th core material.
fn material_label(
    handle: &Handle<StandardMaterial>,
    server: Option<&AssetServer>,
    k: usize,
) -> String {
    server
        .and_then(|s| s.get_path(handle.id()))
        .map_or_else(|| format!("unnamed {k}"), |p| p.to_string())
}

/// Builds core materials (with their textures) from Bevy materials, once per asset.
#[derive(Default)]
struct Materials {
    by_id: HashMap<AssetId<StandardMaterial>, usize>,
    textures: HashMap<AssetId<Image>, Option<usize>>,
}

impl Materials {
    fn texture(
        &mut self,
        scene: &mut Scene,
        images: &Assets<Image>,
        handle: Option<&Handle<Image>>,
        channel: UvChannel,
        label: &str,
    ) -> Option<TextureRef> {
        let handle = handle?;
        let index = *self.textures.entry(handle.id()).or_insert_with(|| {
            let Some(image) = images.get(handle) else {
                scene
                    .warnings
                    .push(format!("{label}: texture not loaded yet; baked without it"));
                return None;
            };
            match core_texture(image, label) {
                Ok(t) => {
                    scene.textures.push(t);
                    Some(scene.textures.len() - 1)
                }
                Err(e) => {
                    scene.warnings.push(e.to_string());
                    None
                }
            }
        });
        index.map(|texture| TextureRef {
            texture,
            tex_coord: match channel {
                UvChannel::Uv0 => 0,
                UvChannel::Uv1 => 1,
            },
        })
    }

    fn get(
        &mut self,
        scene: &mut Scene,
        (images, materials, server): (
            &Assets<Image>,
            &Assets<StandardMaterial>,
            Option<&AssetServer>,
        ),
        handle: Option<&Handle<StandardMaterial>>,
    ) -> Option<usize> {
        let handle = handle?;
        if let Some(&m) = self.by_id.get(&handle.id()) {
            return Some(m);
        }
        let label = material_label(handle, server, scene.materials.len());
        let Some(mat) = materials.get(handle) else {
            scene.warnings.push(format!(
                "material {label} is not loaded; the glTF default (white) was used"
            ));
            return None;
        };
        let base = mat.base_color.to_linear();
        let core = CoreMaterial {
            name: label.clone(),
            base_color: lightbake::glam::Vec4::new(base.red, base.green, base.blue, base.alpha),
            base_color_texture: self.texture(
                scene,
                images,
                mat.base_color_texture.as_ref(),
                mat.base_color_channel.clone(),
                &format!("{label} base colour"),
            ),
            metallic: mat.metallic,
            emissive: lightbake::glam::Vec3::new(
                mat.emissive.red,
                mat.emissive.green,
                mat.emissive.blue,
            ),
            emissive_texture: self.texture(
                scene,
                images,
                mat.emissive_texture.as_ref(),
                mat.emissive_channel.clone(),
                &format!("{label} emissive"),
            ),
            double_sided: mat.double_sided,
        };
        if mat.lightmap_exposure != 1.0 {
            scene.warnings.push(format!(
                "{label}: lightmap_exposure is {}; lightmaps are made for 1, so Bevy will show the baked light scaled by it",
                mat.lightmap_exposure
            ));
        }
        let index = scene.add_material(core);
        self.by_id.insert(handle.id(), index);
        Some(index)
    }
}

/// Converts every `Lightbaked` mesh entity and every light without [`NotBaked`] into a core
/// scene named `name`. Entities are taken in the order of their `Name` (then id), so the same
/// world gives the same scene and the same bake.
///
/// An entity's own density ([`Lightbaked::texel_density`], texels per metre) becomes its
/// instance's `texel_density_scale` against the bake's density. When `settings` choose the
/// density from their texel budget, that density is fixed here first (over the whole scene)
/// and written into `settings.layout.texel_density`, so every entity's own density holds.
///
/// # Errors
/// A [`ConvertError`] naming the entity whose mesh cannot be read.
pub fn extract_scene(
    world: &mut World,
    name: &str,
    sky: SkySource,
    settings: &mut lightbake::BakeSettings,
) -> Result<(Scene, SceneMapping), ConvertError> {
    let mut scene = Scene {
        name: name.to_string(),
        ..Scene::default()
    };
    let mut mapping = SceneMapping::default();

    let (own, material_groups) = extract_instances(world, &mut scene, &mut mapping)?;
    let mut groups = extract_lights(world, &mut scene, &mut mapping);
    for g in material_groups {
        for m in g.members {
            lightbake::scene::groups::add_member(&mut groups, &g.name, m);
        }
    }
    if settings.groups.is_empty() {
        settings.groups = groups;
    }
    scene.sky = match sky {
        SkySource::GlobalAmbient => {
            let a = world.get_resource::<GlobalAmbientLight>();
            mapping.sky_from_ambient = a.is_some();
            a.map_or(lightbake::glam::Vec3::ZERO, |a| {
                linear_rgb(a.color) * a.brightness
            })
        }
        SkySource::ClearColor { nits } => world
            .get_resource::<ClearColor>()
            .map_or(lightbake::glam::Vec3::ZERO, |c| linear_rgb(c.0) * nits),
        SkySource::Nits(v) => vec3(v),
        SkySource::None => lightbake::glam::Vec3::ZERO,
    };
    if !own.is_empty() {
        let base = settings
            .layout
            .texel_density
            .unwrap_or_else(|| lightbake::chosen_texel_density(&scene, settings).0);
        settings.layout.texel_density = Some(base);
        for (i, d) in own {
            scene.instances[i].texel_density_scale = d / base;
        }
    }
    Ok((scene, mapping))
}

/// Every `Lightbaked` mesh entity as a core instance (its mesh and material converted once
/// per (mesh, material) pair), in the order of their names.
/// Returns the instances whose entity asks for its own density, with that density, and the
/// light groups that [`LightGroup`] components on entities with emissive materials make.
fn extract_instances(
    world: &mut World,
    scene: &mut Scene,
    mapping: &mut SceneMapping,
) -> Result<(Vec<(usize, f32)>, Vec<lightbake::settings::LightGroup>), ConvertError> {
    let mut own = Vec::new();
    // Per emissive material, the entities with it and their groups.
    let mut emitters: std::collections::BTreeMap<usize, Vec<(String, Option<String>)>> =
        Default::default();
    let mut query = world.query::<(
        Entity,
        &Mesh3d,
        Option<&MeshMaterial3d<StandardMaterial>>,
        &GlobalTransform,
        &Lightbaked,
        Option<&Name>,
        Option<&LightGroup>,
    )>();
    let mut rows: Vec<_> = query
        .iter(world)
        .map(|(e, m, mat, t, lb, n, g)| {
            (
                entity_label(e, n),
                e,
                m.0.clone(),
                mat.map(|m| m.0.clone()),
                *t,
                (*lb, g.cloned()),
            )
        })
        .collect();
    rows.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    let meshes = world.resource::<Assets<Mesh>>();
    let images = world.resource::<Assets<Image>>();
    let materials = world.resource::<Assets<StandardMaterial>>();
    let server = world.get_resource::<AssetServer>();
    let unwrapped = world.get_resource::<crate::rebake::UnwrappedMeshes>();
    let mut mats = Materials::default();
    let mut core_meshes: HashMap<(AssetId<Mesh>, Option<AssetId<StandardMaterial>>), usize> =
        HashMap::new();
    for (label, entity, mesh_handle, mat_handle, transform, (baked, group)) in rows {
        let key = (mesh_handle.id(), mat_handle.as_ref().map(Handle::id));
        let mesh_index = match core_meshes.get(&key) {
            Some(&m) => m,
            None => {
                let mesh = meshes
                    .get(&mesh_handle)
                    .ok_or_else(|| ConvertError::MeshNotLoaded {
                        label: label.clone(),
                    })?;
                // The mesh as it was before a bake in the app gave it lightmap UVs.
                let mesh = match unwrapped {
                    Some(u) => u.source(mesh_handle.id(), mesh),
                    None => mesh,
                };
                if mesh.has_morph_targets() {
                    scene.warnings.push(format!(
                        "{label}: morph targets are ignored; the mesh is baked in its rest pose"
                    ));
                }
                let mut core = core_mesh(mesh, &label)?;
                let sources = (images, materials, server);
                core.material = mats.get(scene, sources, mat_handle.as_ref());
                let needs_own_asset = mapping.meshes.iter().any(|s| s.handle == mesh_handle);
                mapping.meshes.push(MeshSource {
                    handle: mesh_handle.clone(),
                    original: mesh.clone(),
                    needs_own_asset,
                });
                let m = scene.add_mesh(core);
                core_meshes.insert(key, m);
                m
            }
        };
        let emitting = (scene.meshes[mesh_index].material)
            .filter(|&m| scene.materials[m].emissive.max_element() > 0.0);
        if let Some(m) = emitting {
            let group = group.map(|LightGroup(g)| g);
            emitters.entry(m).or_default().push((label.clone(), group));
        }
        let mut instance = CoreInstance::new(label, mesh_index, affine(&transform));
        instance.bake = baked.receive_lightmap;
        if let Some(d) = baked.texel_density {
            own.push((scene.instances.len(), d));
        }
        scene.instances.push(instance);
        mapping.instances.push(entity);
        mapping.instance_meshes.push(mesh_index);
    }
    Ok((own, emissive_groups(scene, &emitters)))
}

/// The light groups of emissive materials: each material goes to the group of the first of
/// its entities (in the order of their names) that has a [`LightGroup`]; the others with
/// another group or none are warned of (a material's light belongs to one group).
fn emissive_groups(
    scene: &mut Scene,
    emitters: &std::collections::BTreeMap<usize, Vec<(String, Option<String>)>>,
) -> Vec<lightbake::settings::LightGroup> {
    let mut groups = Vec::new();
    for (&m, users) in emitters {
        let Some((by, first)) = (users.iter()).find_map(|(l, g)| Some((l, g.as_ref()?))) else {
            continue;
        };
        let name = &scene.materials[m].name;
        lightbake::scene::groups::add_member(&mut groups, first, format!("material:{name}"));
        for (label, group) in users {
            if group.as_ref() == Some(first) {
                continue;
            }
            let own = match group {
                Some(g) => format!("to put it in '{g}'"),
                None => "to keep it ungrouped".into(),
            };
            scene.warnings.push(format!(
                "{label}: its emissive material is also on {by}, in light group '{first}', and a material's light belongs to one group: its light is in '{first}' too (give {label} a material of its own {own})"
            ));
        }
    }
    groups
}

/// The core's [`LightBake`] for a light with `mode` (`None`: `default`).
fn light_bake(mode: Option<&BakeMode>, default: BakeMode) -> LightBake {
    match mode.copied().unwrap_or(default) {
        BakeMode::Full => LightBake::Full,
        BakeMode::IndirectOnly => LightBake::IndirectOnly,
    }
}

/// Every point, spot, directional and rect light without [`NotBaked`] into `scene`, in the
/// order of their names; returns the light groups their [`LightGroup`] components make.
fn extract_lights(
    world: &mut World,
    scene: &mut Scene,
    mapping: &mut SceneMapping,
) -> Vec<lightbake::settings::LightGroup> {
    let mut lights: Vec<(String, Entity, CoreLight)> = Vec::new();
    let light =
        |name: String, kind, color: Color, intensity, range, t: &GlobalTransform, bake| CoreLight {
            name,
            kind,
            color: linear_rgb(color),
            intensity,
            range,
            position: vec3(t.translation()),
            direction: vec3(t.forward().as_vec3()),
            bake,
        };
    let mut q = world.query_filtered::<(
        Entity,
        &PointLight,
        &GlobalTransform,
        Option<&Name>,
        Option<&BakeMode>,
    ), Without<NotBaked>>();
    for (e, l, t, n, mode) in q.iter(world) {
        let name = entity_label(e, n);
        let bake = light_bake(mode, BakeMode::Full);
        let core = light(
            name.clone(),
            LightKind::Point,
            l.color,
            lumens_to_candela(l.intensity),
            Some(l.range),
            t,
            bake,
        );
        lights.push((name, e, core));
    }
    let mut q = world.query_filtered::<(
        Entity,
        &SpotLight,
        &GlobalTransform,
        Option<&Name>,
        Option<&BakeMode>,
    ), Without<NotBaked>>();
    for (e, l, t, n, mode) in q.iter(world) {
        let name = entity_label(e, n);
        let kind = LightKind::Spot {
            inner_cone_angle: l.inner_angle.min(l.outer_angle),
            outer_cone_angle: l.outer_angle,
        };
        let bake = light_bake(mode, BakeMode::Full);
        let core = light(
            name.clone(),
            kind,
            l.color,
            lumens_to_candela(l.intensity),
            Some(l.range),
            t,
            bake,
        );
        lights.push((name, e, core));
    }
    let mut q = world.query_filtered::<(
        Entity,
        &DirectionalLight,
        &GlobalTransform,
        Option<&SunDisk>,
        Option<&Name>,
        Option<&BakeMode>,
    ), Without<NotBaked>>();
    for (e, l, t, disk, n, mode) in q.iter(world) {
        let name = entity_label(e, n);
        let kind = LightKind::Directional {
            angular_radius: disk.map_or(0.0, |d| 0.5 * d.angular_size),
        };
        let bake = light_bake(mode, BakeMode::Full);
        let core = light(name.clone(), kind, l.color, l.illuminance, None, t, bake);
        lights.push((name, e, core));
    }
    let mut q = world.query_filtered::<(
        Entity,
        &RectLight,
        &GlobalTransform,
        Option<&Name>,
        Option<&BakeMode>,
    ), Without<NotBaked>>();
    for (e, l, t, n, mode) in q.iter(world) {
        let name = entity_label(e, n);
        // The rectangle as Bevy extracts it: its sides scaled by the transform.
        let affine = t.affine();
        let (width, height) = (
            l.width * affine.matrix3.x_axis.length(),
            l.height * affine.matrix3.y_axis.length(),
        );
        let kind = LightKind::Rect {
            right: vec3(t.right().as_vec3()),
            width,
            height,
        };
        let luminance = l.intensity / (PI * width * height).max(f32::MIN_POSITIVE);
        let bake = light_bake(mode, BakeMode::IndirectOnly);
        if bake == LightBake::Full {
            scene.warnings.push(format!(
                "{name}: a RectLight baked with BakeMode::Full still lights lightmapped meshes in Bevy 0.20 (it has no affects_lightmapped_mesh_diffuse): hide it after the bake, or bake it IndirectOnly"
            ));
        }
        let core = light(
            name.clone(),
            kind,
            l.color,
            luminance,
            Some(l.range),
            t,
            bake,
        );
        lights.push((name, e, core));
    }
    lights.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut count: HashMap<&str, usize> = HashMap::new();
    for (name, _, _) in &lights {
        *count.entry(name.as_str()).or_default() += 1;
    }
    let shared: Vec<bool> = lights
        .iter()
        .map(|(n, _, _)| count[n.as_str()] > 1)
        .collect();
    let mut groups = Vec::new();
    for ((name, e, mut l), shared) in lights.into_iter().zip(shared) {
        if let Some(LightGroup(group)) = world.get::<LightGroup>(e) {
            // Groups name lights by name: a grouped light's name is made its own.
            if shared {
                l.name = format!("{name} ({e})");
            }
            lightbake::scene::groups::add_member(&mut groups, group, format!("light:{}", l.name));
        }
        if l.direct_is_baked() {
            mapping.lights.push(e);
        } else {
            mapping.realtime_lights.push(e);
        }
        scene.lights.push(l);
    }
    groups
}
