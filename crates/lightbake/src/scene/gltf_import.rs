//! glTF 2.0 import: meshes (with `TEXCOORD_0/1`), the node hierarchy, metallic-roughness
//! materials with `KHR_materials_emissive_strength`, `KHR_lights_punctual` lights, and
//! lightbake's own `extras` ([`super::extras`]: the scene's texel density and sky, a node's
//! density scale and whether it is baked, a sun's angular radius).
//!
//! Repairs are reported in [`Scene::warnings`]: missing normals are computed; unloadable
//! textures fall back to their material's factors; non-triangle primitives are skipped.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Affine3A, Mat4, Vec2, Vec3, Vec4};
use gltf::Semantic;
use gltf::mesh::Mode;

use super::extras::{self, LightExtras, MaterialExtras, NodeExtras, SceneExtras};
use super::gltf_accessor::{read_indices, read_uv, read_vec3};
use super::gltf_data::{Budget, ImageError, Images, read_buffers};
use super::groups::add_member;
use super::resources::{ReadPolicy, read_regular_file};
use super::{
    GltfPrimitiveRef, Instance, Light, LightKind, Material, Mesh, Scene, Texture, TextureRef, Wrap,
};
use crate::error::{BakeError, Result};
use crate::settings::LightConvention;

/// The parsed source document, kept for writing the baked glTF.
#[derive(Clone, Debug)]
pub struct GltfSource {
    /// The file that was read.
    pub path: PathBuf,
    /// The JSON document, verbatim (unknown extensions and extras included).
    pub json: serde_json::Value,
    /// Every buffer's bytes, in order (the GLB `BIN` chunk for buffer 0 of a `.glb`); empty
    /// for a buffer no buffer view in use lies in (it is not read).
    pub buffers: Vec<Vec<u8>>,
    /// The file bytes of every image read from a URI (`None` for embedded images and images
    /// no texture uses), for the baked glTF to copy.
    pub images: Vec<Option<Vec<u8>>>,
    /// Every file the import read, canonical (the scene file, buffer files, image files):
    /// the outputs may not replace them.
    pub inputs: Vec<PathBuf>,
    /// Whether the source is binary glTF.
    pub is_glb: bool,
}

/// A scene imported from glTF plus the document it came from.
#[derive(Clone, Debug)]
pub struct ImportedScene {
    /// The scene to bake.
    pub scene: Scene,
    /// The source, for the baked-glTF export.
    pub source: GltfSource,
    /// The light groups the extras name (`group` on lights and materials, the scene's
    /// `sky_group`), members written `light:NAME`, `material:NAME` and `sky`.
    pub light_groups: Vec<crate::settings::LightGroup>,
}

impl ImportedScene {
    /// A 64-bit FNV-1a hash of what the import read: the glTF document, its buffers and its
    /// decoded images (sizes and texels). Two imports with the same hash read the same
    /// content (a split bake's shards check it against `prepare`'s).
    pub fn content_hash(&self) -> u64 {
        let mut h = crate::sampling::Fnv1a::default();
        h.bytes(&serde_json::to_vec(&self.source.json).unwrap_or_default());
        for buffer in &self.source.buffers {
            h.bytes(buffer);
        }
        for t in &self.scene.textures {
            h.word(t.width);
            h.word(t.height);
            h.bytes(t.rgba8.as_flattened());
        }
        h.finish()
    }
}

/// How a glTF file is read: the light convention, the folders its URIs may read from besides
/// its own, and the limits that keep a hostile file from exhausting the machine.
#[derive(Clone, Debug)]
pub struct ImportOptions {
    /// How punctual lights' intensities and colours are read. Default glTF's.
    pub light_convention: LightConvention,
    /// Folders besides the scene file's own that buffer and image URIs may name (shared
    /// texture libraries; the CLI's `--allow-read`). Default none.
    pub allow_read: Vec<PathBuf>,
    /// Bytes the import may hold: the buffers it reads, image files and decoded images.
    /// Default 8 GiB (the bake's default memory budget).
    pub memory_budget_bytes: u64,
    /// Most mesh instances and lights the node graph may place (each path from a scene root
    /// to a node counts; counted before the graph is expanded). Default 1 000 000.
    pub max_instances: u64,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            light_convention: LightConvention::default(),
            allow_read: Vec::new(),
            memory_budget_bytes: 8192 << 20,
            max_instances: 1_000_000,
        }
    }
}

impl ImportOptions {
    /// The defaults with `convention`.
    pub fn with_convention(convention: LightConvention) -> Self {
        Self {
            light_convention: convention,
            ..Self::default()
        }
    }
}

/// Reads a `.gltf` or `.glb` file with the default [`ImportOptions`] and `convention`.
///
/// # Errors
/// As [`import_gltf_with`].
pub fn import_gltf(path: &Path, convention: LightConvention) -> Result<ImportedScene> {
    import_gltf_with(path, &ImportOptions::with_convention(convention))
}

/// Reads a `.gltf` or `.glb` file. Its buffer and image URIs are read only inside its folder
/// and `options.allow_read`: a URI is a relative path (percent-decoded) naming a regular file
/// that, with every link resolved, lies inside those folders, or a base64 `data:` URI. Other
/// schemes, absolute paths, `..` steps or links that lead out, directories, devices and FIFOs
/// are refused with an error naming the URI.
///
/// # Errors
/// [`BakeError::Read`] for a missing file, [`BakeError::BadGltf`] for a malformed document
/// or a node graph over the instance limit, [`BakeError::MissingBuffer`] for a buffer that
/// cannot be read (or may not be: its URI leaves the allowed folders),
/// [`BakeError::BadAccessor`] and the validation errors of [`Scene::validate`], each naming
/// the file, mesh or node at fault.
pub fn import_gltf_with(path: &Path, options: &ImportOptions) -> Result<ImportedScene> {
    let bytes = read_regular_file(path, options.memory_budget_bytes).map_err(|message| {
        BakeError::Read {
            path: path.to_path_buf(),
            source: std::io::Error::other(message),
        }
    })?;
    import_gltf_slice_with(&bytes, path, options)
}

/// Like [`import_gltf`] for bytes already in memory; `path` names the file in messages and
/// is the base for relative URIs.
///
/// # Errors
/// As [`import_gltf`].
pub fn import_gltf_slice(
    bytes: &[u8],
    path: &Path,
    convention: LightConvention,
) -> Result<ImportedScene> {
    import_gltf_slice_with(bytes, path, &ImportOptions::with_convention(convention))
}

/// Like [`import_gltf_with`] for bytes already in memory.
///
/// # Errors
/// As [`import_gltf_with`].
pub fn import_gltf_slice_with(
    bytes: &[u8],
    path: &Path,
    options: &ImportOptions,
) -> Result<ImportedScene> {
    let bad_gltf = |message: String| BakeError::BadGltf {
        path: path.to_path_buf(),
        message,
    };
    let is_glb = bytes.starts_with(b"glTF");
    let json: serde_json::Value = if is_glb {
        let glb = gltf::Glb::from_slice(bytes).map_err(|e| bad_gltf(e.to_string()))?;
        serde_json::from_slice(&glb.json).map_err(|e| bad_gltf(e.to_string()))?
    } else {
        serde_json::from_slice(bytes)
            .map_err(|e| bad_gltf(format!("not a valid glTF (JSON: {e})")))?
    };
    // The gltf crate's validator indexes `accessors` with a primitive's POSITION before
    // checking it (gltf-json 1.4.1, mesh.rs:151) and panics on a bad index: check first.
    check_primitive_accessors(&json).map_err(bad_gltf)?;
    let parsed = std::panic::catch_unwind(|| gltf::Gltf::from_slice(bytes)).map_err(|_| {
        bad_gltf("not a valid glTF (the gltf crate's validator failed on it)".into())
    })?;
    let gltf = parsed.map_err(|e| bad_gltf(e.to_string()))?;
    let document = gltf.document;
    let policy = ReadPolicy::new(path, &options.allow_read)?;
    let mut budget = Budget::new(options.memory_budget_bytes);

    // The node graph's size before it is expanded: a small graph can have 2⁴⁰ paths.
    let roots = scene_roots(&document);
    let placed = count_placements(&document, &roots).map_err(bad_gltf)?;
    if placed > options.max_instances {
        return Err(bad_gltf(format!(
            "its node graph places {placed} mesh instances and lights (every path from a scene root counts), more than the limit of {} instances",
            options.max_instances
        )));
    }
    let mut inputs: Vec<PathBuf> = path.canonicalize().into_iter().collect();
    let buffers = read_buffers(
        path,
        &document,
        &json,
        gltf.blob,
        &policy,
        &mut budget,
        &mut inputs,
    )?;
    let mut importer = Importer {
        document: &document,
        buffers: &buffers,
        images: Images::new(&document, &buffers, &policy),
        budget,
        convention: options.light_convention,
        scene: Scene {
            name: path
                .file_name()
                .map_or_else(|| "scene".into(), |n| n.to_string_lossy().into_owned()),
            ..Scene::default()
        },
        groups: Vec::new(),
        mesh_map: HashMap::new(),
        texture_map: HashMap::new(),
    };
    importer.materials()?;
    if let Some(s) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        importer.scene_extras(s.extras());
    }
    for node in &roots {
        importer.node(node, Mat4::IDENTITY, 0)?;
    }
    let images = std::mem::take(&mut importer.images.files);
    inputs.append(&mut importer.images.paths);
    let (scene, light_groups) = (importer.scene, importer.groups);
    scene.validate()?;
    Ok(ImportedScene {
        scene,
        light_groups,
        source: GltfSource {
            path: path.to_path_buf(),
            json,
            buffers,
            images,
            inputs,
            is_glb,
        },
    })
}

/// The nodes a scene shows: the default scene's (or the first's) roots, or every node that is
/// no other's child when the file has no scenes.
fn scene_roots(document: &gltf::Document) -> Vec<gltf::Node<'_>> {
    if let Some(s) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        return s.nodes().collect();
    }
    let mut is_child = vec![false; document.nodes().len()];
    for n in document.nodes() {
        for c in n.children() {
            is_child[c.index()] = true;
        }
    }
    document.nodes().filter(|n| !is_child[n.index()]).collect()
}

/// The deepest node hierarchy read (a deeper one is taken for a cycle).
const MAX_DEPTH: usize = 256;

/// Mesh primitives and lights the graph places, counting every path from `roots` (saturating),
/// without expanding it: each node's count is memoised.
///
/// # Errors
/// A hierarchy deeper than [`MAX_DEPTH`] (a cycle).
fn count_placements(
    document: &gltf::Document,
    roots: &[gltf::Node<'_>],
) -> std::result::Result<u64, String> {
    fn visit(
        node: &gltf::Node<'_>,
        depth: usize,
        memo: &mut [Option<u64>],
    ) -> std::result::Result<u64, String> {
        if let Some(c) = memo[node.index()] {
            return Ok(c);
        }
        if depth > MAX_DEPTH {
            let name = node
                .name()
                .map_or_else(|| format!("node {}", node.index()), str::to_string);
            return Err(format!(
                "node '{name}': the hierarchy is deeper than {MAX_DEPTH} levels (a cycle?)"
            ));
        }
        let mut count =
            node.mesh().map_or(0, |m| m.primitives().len() as u64) + node.light().map_or(0, |_| 1);
        for child in node.children() {
            count = count.saturating_add(visit(&child, depth + 1, memo)?);
        }
        memo[node.index()] = Some(count);
        Ok(count)
    }
    let mut memo = vec![None; document.nodes().len()];
    let mut total = 0u64;
    for root in roots {
        total = total.saturating_add(visit(root, 0, &mut memo)?);
    }
    Ok(total)
}

struct Importer<'a> {
    document: &'a gltf::Document,
    buffers: &'a [Vec<u8>],
    images: Images<'a>,
    budget: Budget,
    convention: LightConvention,
    scene: Scene,
    groups: Vec<crate::settings::LightGroup>,
    /// (glTF mesh, primitive) → scene mesh (None when skipped).
    mesh_map: HashMap<(usize, usize), Option<usize>>,
    /// (image, wrap u, wrap v) → scene texture (None when it could not be loaded).
    texture_map: HashMap<(usize, Wrap, Wrap), Option<usize>>,
}

/// Triangle-list indices of a primitive drawn in `mode` (strips and fans converted).
fn triangle_list(mode: Mode, raw: Vec<u32>) -> Vec<u32> {
    match mode {
        Mode::TriangleStrip => (0..raw.len().saturating_sub(2))
            .flat_map(|i| {
                if i % 2 == 0 {
                    [raw[i], raw[i + 1], raw[i + 2]]
                } else {
                    [raw[i + 1], raw[i], raw[i + 2]]
                }
            })
            .collect(),
        Mode::TriangleFan => (1..raw.len().saturating_sub(1))
            .flat_map(|i| [raw[0], raw[i], raw[i + 1]])
            .collect(),
        _ => raw,
    }
}

/// The raw `extras` JSON text of a glTF object.
fn extras_text(extras: &gltf::json::Extras) -> Option<&str> {
    extras.as_ref().map(|raw| raw.get())
}

fn wrap_mode(w: gltf::texture::WrappingMode) -> Wrap {
    match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

impl Importer<'_> {
    fn scene_extras(&mut self, raw: &gltf::json::Extras) {
        let lb: SceneExtras = extras::read(extras_text(raw), "scene", &mut self.scene.warnings);
        if let Some(d) = lb.texel_density {
            self.scene.texel_density_hint = Some(d);
        }
        if let Some([r, g, b]) = lb.sky {
            self.scene.sky = Vec3::new(r, g, b);
        }
        if let Some(g) = lb.sky_group {
            add_member(&mut self.groups, &g, "sky".into());
        }
    }

    fn materials(&mut self) -> Result<()> {
        let document = self.document;
        for m in document.materials() {
            let name = m.name().map_or_else(
                || format!("material {}", m.index().unwrap_or(0)),
                str::to_string,
            );
            let pbr = m.pbr_metallic_roughness();
            let base_color_texture = match pbr.base_color_texture() {
                Some(info) => self.texture(&info.texture(), info.tex_coord(), &name)?,
                None => None,
            };
            let emissive_texture = match m.emissive_texture() {
                Some(info) => self.texture(&info.texture(), info.tex_coord(), &name)?,
                None => None,
            };
            let strength = m.emissive_strength().unwrap_or(1.0);
            let place = format!("material '{name}'");
            let lb: MaterialExtras =
                extras::read(extras_text(m.extras()), &place, &mut self.scene.warnings);
            if let Some(g) = lb.group {
                add_member(&mut self.groups, &g, format!("material:{name}"));
            }
            self.scene.materials.push(Material {
                name,
                base_color: Vec4::from_array(pbr.base_color_factor()),
                base_color_texture,
                metallic: pbr.metallic_factor(),
                emissive: Vec3::from_array(m.emissive_factor()) * strength,
                emissive_texture,
                double_sided: m.double_sided(),
            });
        }
        Ok(())
    }

    /// The scene texture of a glTF texture: its image decoded once (shared by every texture
    /// with the same image and wrap modes). An image that cannot be used leaves the material
    /// with its factors (a warning); one whose URI breaks the read rule stops the import.
    fn texture(
        &mut self,
        texture: &gltf::Texture<'_>,
        tex_coord: u32,
        material: &str,
    ) -> Result<Option<TextureRef>> {
        let image = texture.source();
        let sampler = texture.sampler();
        let (wrap_u, wrap_v) = (wrap_mode(sampler.wrap_s()), wrap_mode(sampler.wrap_t()));
        let key = (image.index(), wrap_u, wrap_v);
        let as_ref = |t: Option<usize>| {
            t.map(|t| TextureRef {
                texture: t,
                tex_coord,
            })
        };
        if let Some(cached) = self.texture_map.get(&key) {
            return Ok(as_ref(*cached));
        }
        let label = match image.source() {
            gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => uri.to_string(),
            _ => format!("image {}", image.index()),
        };
        let result = match self.images.decode(image.index(), &mut self.budget) {
            Ok(decoded) => {
                self.budget
                    .take(
                        decoded.rgba8.len() as u64 * 4,
                        &format!("texture {} ({label})", texture.index()),
                    )
                    .map_err(|message| BakeError::BadGltf {
                        path: PathBuf::from(&self.scene.name),
                        message: format!("material '{material}': {message}"),
                    })?;
                self.scene.textures.push(Texture {
                    name: label,
                    width: decoded.width,
                    height: decoded.height,
                    rgba8: decoded.rgba8.clone(),
                    wrap_u,
                    wrap_v,
                });
                Some(self.scene.textures.len() - 1)
            }
            Err(ImageError::Unusable(e)) => {
                self.scene.warnings.push(format!(
                    "material '{material}': texture {} ({label}) cannot be loaded ({e}); using the material's factors only",
                    texture.index()
                ));
                None
            }
            Err(ImageError::Refused(e)) => {
                return Err(BakeError::BadGltf {
                    path: PathBuf::from(&self.scene.name),
                    message: format!(
                        "material '{material}': image {} ({label}) is refused: {e}",
                        image.index()
                    ),
                });
            }
        };
        self.texture_map.insert(key, result);
        Ok(as_ref(result))
    }

    fn node(&mut self, node: &gltf::Node<'_>, parent: Mat4, depth: usize) -> Result<()> {
        let name = node
            .name()
            .map_or_else(|| format!("node {}", node.index()), str::to_string);
        if depth > MAX_DEPTH {
            return Err(BakeError::BadGltf {
                path: PathBuf::from(&self.scene.name),
                message: format!(
                    "node '{name}': the hierarchy is deeper than {MAX_DEPTH} levels (a cycle?)"
                ),
            });
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        let lb: NodeExtras = extras::read(
            extras_text(node.extras()),
            &format!("node '{name}'"),
            &mut self.scene.warnings,
        );
        if let Some(mesh) = node.mesh() {
            let affine = Affine3A::from_mat4(world);
            let primitive_count = mesh.primitives().len();
            for primitive in mesh.primitives() {
                let Some(m) = self.mesh(&mesh, &primitive)? else {
                    continue;
                };
                let mut inst = Instance::new(
                    if primitive_count > 1 {
                        format!("{name}#{}", primitive.index())
                    } else {
                        name.clone()
                    },
                    m,
                    affine,
                );
                inst.gltf_node = Some(node.index());
                if let Some(s) = lb.texel_density_scale {
                    inst.texel_density_scale = s;
                }
                if let Some(b) = lb.bake {
                    inst.bake = b;
                }
                // A transform that collapses space is bad input for a lightmapped mesh.
                inst.validate()?;
                self.scene.instances.push(inst);
            }
        }
        if let Some(light) = node.light() {
            self.light(&light, world, &name);
        }
        for child in node.children() {
            self.node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    fn light(&mut self, light: &gltf::khr_lights_punctual::Light<'_>, world: Mat4, node: &str) {
        use gltf::khr_lights_punctual::Kind;
        let name = light
            .name()
            .map_or_else(|| node.to_string(), str::to_string);
        let lb: LightExtras = extras::read(
            extras_text(light.extras()),
            &format!("light '{name}'"),
            &mut self.scene.warnings,
        );
        let bevy = self.convention == LightConvention::BevyGltfLoader;
        let mut color = Vec3::from_array(light.color());
        if bevy {
            color = Vec3::new(
                crate::color::srgb_to_linear(color.x),
                crate::color::srgb_to_linear(color.y),
                crate::color::srgb_to_linear(color.z),
            );
        }
        let kind = match light.kind() {
            Kind::Point => LightKind::Point,
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            },
            Kind::Directional => LightKind::Directional {
                angular_radius: lb.angular_radius.unwrap_or(0.0),
            },
        };
        let right = world.transform_vector3(Vec3::X).normalize_or(Vec3::X);
        let (kind, intensity) = match lb.rect {
            Some([w, h]) => (
                LightKind::Rect {
                    right,
                    width: w,
                    height: h,
                },
                // Candela on the axis (the spot stand-in) → luminance.
                light.intensity() / (w * h).max(f32::MIN_POSITIVE),
            ),
            None => (kind, light.intensity()),
        };
        let bake = match lb.bake {
            Some(extras::LightBakeExtras::Indirect) => crate::scene::LightBake::IndirectOnly,
            _ => crate::scene::LightBake::Full,
        };
        let range = match (light.range(), bevy, kind) {
            (Some(r), _, _) => Some(r),
            (None, true, LightKind::Point | LightKind::Spot { .. } | LightKind::Rect { .. }) => {
                Some(20.0)
            }
            (None, _, _) => None,
        };
        if let Some(g) = &lb.group {
            add_member(&mut self.groups, g, format!("light:{name}"));
        }
        self.scene.lights.push(Light {
            name,
            kind,
            color,
            intensity,
            range,
            position: world.transform_point3(Vec3::ZERO),
            direction: world
                .transform_vector3(Vec3::NEG_Z)
                .normalize_or(Vec3::NEG_Y),
            bake,
        });
    }

    /// Checks a mesh's own normals (count, finite), reports triangles whose normals point
    /// against their winding, replaces zero-length normals by the face normals and normalises
    /// the rest.
    fn repair_normals(&mut self, m: &mut Mesh, context: &str) -> Result<()> {
        let name = &m.name;
        if m.normals.len() != m.positions.len() {
            return Err(BakeError::BadAccessor {
                context: context.to_string(),
                message: format!(
                    "{} normals for {} positions",
                    m.normals.len(),
                    m.positions.len()
                ),
            });
        }
        if let Some(vertex) = m.normals.iter().position(|n| !n.is_finite()) {
            return Err(BakeError::NonFiniteVertex {
                mesh: name.clone(),
                vertex,
                attribute: "normal",
                value: format!("{:?}", m.normals[vertex]),
            });
        }
        let zero = m
            .normals
            .iter()
            .filter(|n| n.length_squared() < 1e-12)
            .count();
        let flipped = (0..m.triangle_count())
            .filter(|&t| {
                let [a, b, c] = m.triangle(t);
                let g = (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]);
                [a, b, c].iter().all(|&v| m.normals[v].dot(g) < 0.0)
            })
            .count();
        if flipped > 0 {
            self.scene.warnings.push(format!(
                "mesh '{name}': {flipped} of {} triangles have normals pointing against their winding; the front face (counter-clockwise winding) is baked with the normal flipped to it",
                m.triangle_count()
            ));
        }
        if zero > 0 {
            self.scene.warnings.push(format!(
                "mesh '{name}': {zero} zero-length normals replaced by the face normals"
            ));
            let mut computed = m.clone();
            computed.compute_normals();
            for (n, c) in m.normals.iter_mut().zip(&computed.normals) {
                if n.length_squared() < 1e-12 {
                    *n = *c;
                }
            }
        }
        for n in &mut m.normals {
            *n = n.normalize_or(Vec3::Y);
        }
        Ok(())
    }

    fn mesh(
        &mut self,
        mesh: &gltf::Mesh<'_>,
        primitive: &gltf::Primitive<'_>,
    ) -> Result<Option<usize>> {
        let key = (mesh.index(), primitive.index());
        if let Some(&m) = self.mesh_map.get(&key) {
            return Ok(m);
        }
        let mesh_name = mesh
            .name()
            .map_or_else(|| format!("mesh {}", mesh.index()), str::to_string);
        let name = format!("{mesh_name}/{}", primitive.index());
        let ctx = |attr: &str| format!("mesh '{mesh_name}' primitive {} {attr}", primitive.index());
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.scene.warnings.push(format!(
                "mesh '{name}': primitive mode {mode:?} has no surface to bake; skipped"
            ));
            self.mesh_map.insert(key, None);
            return Ok(None);
        }
        let Some(pos_acc) = primitive.get(&Semantic::Positions) else {
            return Err(BakeError::BadAccessor {
                context: ctx("POSITION"),
                message: "the primitive has no POSITION attribute".into(),
            });
        };
        let positions: Vec<Vec3> = read_vec3(&pos_acc, self.buffers, &ctx("POSITION"))?
            .into_iter()
            .map(Vec3::from_array)
            .collect();
        let raw_indices = match primitive.indices() {
            Some(acc) => read_indices(&acc, self.buffers, &ctx("indices"))?,
            None => (0..positions.len() as u32).collect(),
        };
        let indices = triangle_list(mode, raw_indices);
        let mut m = Mesh {
            name: name.clone(),
            positions,
            normals: Vec::new(),
            uv0: None,
            uv1: None,
            indices,
            material: primitive.material().index(),
            source: Some(GltfPrimitiveRef {
                mesh: mesh.index(),
                primitive: primitive.index(),
            }),
        };
        let read_uv_set = |set: u32| -> Result<Option<Vec<Vec2>>> {
            match primitive.get(&Semantic::TexCoords(set)) {
                Some(acc) => Ok(Some(
                    read_uv(&acc, self.buffers, &ctx(&format!("TEXCOORD_{set}")))?
                        .into_iter()
                        .map(Vec2::from_array)
                        .collect(),
                )),
                None => Ok(None),
            }
        };
        m.uv0 = read_uv_set(0)?;
        m.uv1 = read_uv_set(1)?;
        // Positions and indices are checked before normals are computed from them.
        m.validate_geometry()?;
        match primitive.get(&Semantic::Normals) {
            Some(acc) => {
                m.normals = read_vec3(&acc, self.buffers, &ctx("NORMAL"))?
                    .into_iter()
                    .map(Vec3::from_array)
                    .collect();
                self.repair_normals(&mut m, &ctx("NORMAL"))?;
            }
            None => {
                self.scene.warnings.push(format!(
                    "mesh '{name}': no NORMAL attribute; smooth normals computed from the triangles"
                ));
                m.compute_normals();
            }
        }
        if m.material.is_some_and(|i| i >= self.scene.materials.len()) {
            return Err(BakeError::BadReference {
                what: format!("mesh '{name}' uses a material that does not exist"),
            });
        }
        self.scene.meshes.push(m);
        let index = self.scene.meshes.len() - 1;
        self.mesh_map.insert(key, Some(index));
        Ok(Some(index))
    }
}

impl Mesh {
    /// Index ranges and finite positions, before normals exist.
    fn validate_geometry(&self) -> Result<()> {
        let mut probe = self.clone();
        probe.normals = vec![Vec3::Y; self.positions.len()];
        probe.validate()
    }
}

/// Every accessor a mesh primitive names (attributes, indices) exists.
fn check_primitive_accessors(json: &serde_json::Value) -> std::result::Result<(), String> {
    let accessors = json["accessors"].as_array().map_or(0, |a| a.len());
    let Some(meshes) = json["meshes"].as_array() else {
        return Ok(());
    };
    for (m, mesh) in meshes.iter().enumerate() {
        let Some(primitives) = mesh["primitives"].as_array() else {
            continue;
        };
        for (p, prim) in primitives.iter().enumerate() {
            let mut refs: Vec<(String, &serde_json::Value)> = Vec::new();
            if let Some(attributes) = prim["attributes"].as_object() {
                refs.extend(attributes.iter().map(|(k, v)| (k.clone(), v)));
            }
            if !prim["indices"].is_null() {
                refs.push(("indices".into(), &prim["indices"]));
            }
            for (what, v) in refs {
                if v.as_u64().is_none_or(|i| (i as usize) >= accessors) {
                    return Err(format!(
                        "mesh {m} primitive {p}: {what} refers to accessor {v}, but the file has {accessors} accessors"
                    ));
                }
            }
        }
    }
    Ok(())
}
