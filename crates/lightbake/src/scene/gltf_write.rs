//! Writes a [`Scene`] as glTF 2.0 (`.gltf` + `.bin`): how the shipped assets are produced
//! from `scene::testscenes`, and how tests make input files.
//!
//! One node per instance (TRS), one mesh with one primitive per scene mesh, metallic-roughness
//! materials (metallic 0, roughness 1) with `KHR_materials_emissive_strength` when the
//! emission exceeds 1, `KHR_lights_punctual` lights on their own nodes, textures embedded as
//! PNG, and lightbake's extras (see [`super::gltf_import`]).

use glam::{Quat, Vec3};
use serde_json::{Value, json};

use super::extras::{self, LightExtras, NodeExtras, SceneExtras};
use super::{LightKind, Scene, Wrap};

fn pad4(bin: &mut Vec<u8>) {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
}

struct Writer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Writer {
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        pad4(&mut self.bin);
        let mut v = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    fn floats(&mut self, data: &[f32], kind: &str, count: usize, minmax: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        let mut a =
            json!({ "bufferView": view, "componentType": 5126, "count": count, "type": kind });
        if minmax && count > 0 {
            let n = data.len() / count;
            let lo: Vec<f32> = (0..n)
                .map(|k| {
                    data.iter()
                        .skip(k)
                        .step_by(n)
                        .copied()
                        .fold(f32::INFINITY, f32::min)
                })
                .collect();
            let hi: Vec<f32> = (0..n)
                .map(|k| {
                    data.iter()
                        .skip(k)
                        .step_by(n)
                        .copied()
                        .fold(f32::NEG_INFINITY, f32::max)
                })
                .collect();
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

fn wrap_code(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => 10497,
        Wrap::MirroredRepeat => 33648,
        Wrap::ClampToEdge => 33071,
    }
}

impl Writer {
    /// One scene mesh as a glTF mesh with one primitive.
    fn mesh(&mut self, m: &super::Mesh) -> Value {
        let w = self;
        let mut attributes = serde_json::Map::new();
        let pos: Vec<f32> = m.positions.iter().flat_map(|p| p.to_array()).collect();
        attributes.insert(
            "POSITION".into(),
            json!(w.floats(&pos, "VEC3", m.positions.len(), true)),
        );
        let nrm: Vec<f32> = m.normals.iter().flat_map(|p| p.to_array()).collect();
        attributes.insert(
            "NORMAL".into(),
            json!(w.floats(&nrm, "VEC3", m.normals.len(), false)),
        );
        for (name, uv) in [("TEXCOORD_0", &m.uv0), ("TEXCOORD_1", &m.uv1)] {
            if let Some(uv) = uv {
                let d: Vec<f32> = uv.iter().flat_map(|p| p.to_array()).collect();
                attributes.insert(name.into(), json!(w.floats(&d, "VEC2", uv.len(), false)));
            }
        }
        let (bytes, component): (Vec<u8>, u32) = if m.positions.len() <= u16::MAX as usize {
            (
                m.indices
                    .iter()
                    .flat_map(|&i| (i as u16).to_le_bytes())
                    .collect(),
                5123,
            )
        } else {
            (
                m.indices.iter().flat_map(|&i| i.to_le_bytes()).collect(),
                5125,
            )
        };
        let view = w.view(&bytes, Some(34963));
        w.accessors.push(json!({ "bufferView": view, "componentType": component, "count": m.indices.len(), "type": "SCALAR" }));
        let mut prim =
            json!({ "attributes": attributes, "indices": w.accessors.len() - 1, "mode": 4 });
        if let Some(mat) = m.material {
            prim["material"] = json!(mat);
        }
        json!({ "name": m.name, "primitives": [prim] })
    }

    /// One texture as an embedded PNG: (image, sampler).
    ///
    /// # Panics
    /// If the texture cannot be PNG-encoded (its pixel count does not match its size).
    fn texture(&mut self, t: &super::Texture) -> (Value, Value) {
        let w = self;
        let raw: Vec<u8> = t.rgba8.iter().flatten().copied().collect();
        let img = image::RgbaImage::from_raw(t.width, t.height, raw)
            .expect("texture size matches its pixels");
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("PNG encoding into memory");
        let view = w.view(&png, None);
        (
            json!({ "name": t.name, "bufferView": view, "mimeType": "image/png" }),
            json!({ "wrapS": wrap_code(t.wrap_u), "wrapT": wrap_code(t.wrap_v) }),
        )
    }
}

/// One material as glTF metallic-roughness (metallic 0 unless set, roughness 1), and whether
/// it needs `KHR_materials_emissive_strength`.
fn material(m: &super::Material) -> (Value, bool) {
    let mut uses_strength = false;
    let mut pbr = json!({
        "baseColorFactor": m.base_color.to_array(),
        "metallicFactor": m.metallic,
        "roughnessFactor": 1.0,
    });
    if let Some(t) = m.base_color_texture {
        pbr["baseColorTexture"] = json!({ "index": t.texture, "texCoord": t.tex_coord });
    }
    let mut v =
        json!({ "name": m.name, "pbrMetallicRoughness": pbr, "doubleSided": m.double_sided });
    let peak = m.emissive.max_element();
    if peak > 0.0 {
        let strength = peak.max(1.0);
        v["emissiveFactor"] = json!((m.emissive / strength).to_array());
        if strength > 1.0 {
            uses_strength = true;
            v["extensions"] =
                json!({ "KHR_materials_emissive_strength": { "emissiveStrength": strength } });
        }
    }
    if let Some(t) = m.emissive_texture {
        v["emissiveTexture"] = json!({ "index": t.texture, "texCoord": t.tex_coord });
    }
    (v, uses_strength)
}

/// The node of one instance (TRS, with lightbake's node extras).
fn instance_node(inst: &super::Instance) -> Value {
    let (scale, rotation, translation) = inst.transform.to_scale_rotation_translation();
    let mut n = json!({ "name": inst.name, "mesh": inst.mesh });
    if translation != Vec3::ZERO {
        n["translation"] = json!(translation.to_array());
    }
    if rotation != Quat::IDENTITY {
        n["rotation"] = json!(rotation.to_array());
    }
    if scale != Vec3::ONE {
        n["scale"] = json!(scale.to_array());
    }
    let lb = NodeExtras {
        texel_density_scale: (inst.texel_density_scale != 1.0).then_some(inst.texel_density_scale),
        bake: (!inst.bake).then_some(false),
        ..NodeExtras::default()
    };
    extras::write(&mut n, &lb);
    n
}

/// One light: its `KHR_lights_punctual` entry (index `i`) and its node.
fn light(l: &super::Light, i: usize) -> (Value, Value) {
    let mut light =
        json!({ "name": l.name, "color": l.color.to_array(), "intensity": l.intensity });
    match l.kind {
        LightKind::Point => light["type"] = json!("point"),
        LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => {
            light["type"] = json!("spot");
            light["spot"] =
                json!({ "innerConeAngle": inner_cone_angle, "outerConeAngle": outer_cone_angle });
        }
        LightKind::Directional { angular_radius } => {
            light["type"] = json!("directional");
            let lb = LightExtras {
                angular_radius: (angular_radius > 0.0).then_some(angular_radius),
                ..LightExtras::default()
            };
            extras::write(&mut light, &lb);
        }
        LightKind::Rect { width, height, .. } => {
            // A hemisphere spot with the rectangle's on-axis intensity stands in for it.
            light["type"] = json!("spot");
            light["intensity"] = json!(l.intensity * width * height);
            light["spot"] =
                json!({ "innerConeAngle": 0.0, "outerConeAngle": std::f32::consts::FRAC_PI_2 });
            let lb = LightExtras {
                rect: Some([width, height]),
                ..LightExtras::default()
            };
            extras::write(&mut light, &lb);
        }
    }
    if l.bake == crate::scene::LightBake::IndirectOnly {
        let mut lb: LightExtras = extras::read_value(
            light.get("extras").and_then(|e| e.get(extras::KEY)),
            "",
            &mut Vec::new(),
        );
        lb.bake = Some(extras::LightBakeExtras::Indirect);
        extras::write(&mut light, &lb);
    }
    if let Some(r) = l.range {
        light["range"] = json!(r);
    }
    let mut rotation = Quat::from_rotation_arc(Vec3::NEG_Z, l.direction);
    if let LightKind::Rect { right, .. } = l.kind {
        // The whole frame: −Z to the facing, X to the width axis.
        let up = right.cross(l.direction);
        rotation = Quat::from_mat3(&glam::Mat3::from_cols(right, up, -l.direction));
    }
    let mut n = json!({ "name": l.name, "extensions": { "KHR_lights_punctual": { "light": i } } });
    if l.position != Vec3::ZERO {
        n["translation"] = json!(l.position.to_array());
    }
    if rotation != Quat::IDENTITY {
        n["rotation"] = json!(rotation.to_array());
    }
    (light, n)
}

/// The glTF JSON (pretty) and binary buffer of `scene`; the JSON refers to the buffer as
/// `bin_uri`.
///
/// # Panics
/// If a texture cannot be PNG-encoded (its pixel count does not match its size).
pub fn scene_to_gltf(scene: &Scene, bin_uri: &str) -> (Vec<u8>, Vec<u8>) {
    let mut w = Writer {
        bin: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let meshes: Vec<Value> = scene.meshes.iter().map(|m| w.mesh(m)).collect();
    let mut images = Vec::new();
    let mut textures = Vec::new();
    let mut samplers = Vec::new();
    for t in &scene.textures {
        let (image, sampler) = w.texture(t);
        images.push(image);
        samplers.push(sampler);
        textures.push(json!({ "source": images.len() - 1, "sampler": samplers.len() - 1 }));
    }
    let mut uses_strength = false;
    let materials: Vec<Value> = scene
        .materials
        .iter()
        .map(|m| {
            let (v, strength) = material(m);
            uses_strength |= strength;
            v
        })
        .collect();
    let mut nodes: Vec<Value> = scene.instances.iter().map(instance_node).collect();
    let mut lights = Vec::new();
    for (i, l) in scene.lights.iter().enumerate() {
        let (light, node) = light(l, i);
        lights.push(light);
        nodes.push(node);
    }
    let mut gltf_scene =
        json!({ "name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>() });
    let lb = SceneExtras {
        texel_density: scene.texel_density_hint,
        sky: (scene.sky != Vec3::ZERO).then(|| scene.sky.to_array()),
        ..SceneExtras::default()
    };
    extras::write(&mut gltf_scene, &lb);
    pad4(&mut w.bin);
    let mut doc = json!({
        "asset": { "version": "2.0", "generator": "lightbake scene writer" },
        "scene": 0,
        "scenes": [gltf_scene],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "buffers": [{ "byteLength": w.bin.len(), "uri": bin_uri }],
        "bufferViews": w.views,
        "accessors": w.accessors,
    });
    let mut used = Vec::new();
    if !lights.is_empty() {
        used.push("KHR_lights_punctual");
        doc["extensions"] = json!({ "KHR_lights_punctual": { "lights": lights } });
    }
    if uses_strength {
        used.push("KHR_materials_emissive_strength");
    }
    if !used.is_empty() {
        doc["extensionsUsed"] = json!(used);
    }
    if !images.is_empty() {
        doc["images"] = json!(images);
        doc["textures"] = json!(textures);
        doc["samplers"] = json!(samplers);
    }
    let mut text = serde_json::to_vec_pretty(&doc).expect("JSON values serialise");
    text.push(b'\n');
    (text, w.bin)
}

/// `scene` as a single binary glTF (`.glb`).
pub fn scene_to_glb(scene: &Scene) -> Vec<u8> {
    let (json, bin) = scene_to_gltf(scene, "");
    let mut doc: Value = serde_json::from_slice(&json).expect("own JSON parses");
    doc["buffers"][0]
        .as_object_mut()
        .expect("buffer object")
        .remove("uri");
    let text = serde_json::to_vec(&doc).expect("JSON values serialise");
    super::glb::glb(text, &bin)
}

/// Writes `scene` to `path` (`.gltf`) and its buffer next to it (`.bin`), atomically.
///
/// # Errors
/// [`crate::BakeError::Write`] naming the file.
pub fn write_scene_gltf(scene: &Scene, path: &std::path::Path) -> crate::Result<()> {
    let stem = path
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    let bin_name = format!("{stem}.bin");
    let (json, bin) = scene_to_gltf(scene, &super::resources::percent_encode_path(&bin_name));
    let mut staged =
        crate::atomic::StagedFiles::new(path.parent().unwrap_or(std::path::Path::new(".")));
    staged.stage(path, &json)?;
    staged.stage(&path.with_file_name(bin_name), &bin)?;
    staged.commit()?;
    Ok(())
}
