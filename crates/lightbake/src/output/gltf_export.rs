//! The baked glTF: the input document, verbatim where possible, plus `TEXCOORD_1` on every
//! baked primitive and, on every baked node, `extras.lightbake.lightmaps` listing each
//! primitive's page image and `uv_rect` (what Bevy's `Lightmap` needs; Bevy exposes node
//! extras as `GltfExtras`). Every `KHR_lights_punctual` light gets `extras.lightbake.baked`.
//!
//! A primitive that xatlas unwrapped has its vertices split along chart seams, so all of its
//! vertex attributes (and morph targets) are gathered into new accessors, with new triangle
//! list indices. Everything else is left as it was. All buffers are merged into one: a `.bin`
//! next to a `.gltf`, or the `BIN` chunk of a `.glb`. External images are copied next to a
//! `.gltf` output, or embedded in a `.glb`.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use crate::error::{BakeError, Result};
use crate::scene::extras::{
    self, LightBakeExtras, LightExtras, NodeExtras, NodeLightmap, SceneExtras, VolumeExtras,
};
use crate::scene::glb::glb;
use crate::scene::gltf_accessor::read_dense;
use crate::scene::gltf_import::GltfSource;
use crate::scene::{GltfPrimitiveRef, Scene};
use crate::unwrap::{Layout, MeshUnwrap};

/// The files of the baked glTF.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct BakedGltf {
    /// (path relative to the output directory, bytes) of every file.
    pub files: Vec<(PathBuf, Vec<u8>)>,
}

fn err(path: &Path, message: impl Into<String>) -> BakeError {
    BakeError::BadGltf {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Appends `bytes` to the blob (4-byte aligned) and returns a new bufferView index.
fn push_view(json: &mut Value, blob: &mut Vec<u8>, bytes: &[u8], target: Option<u32>) -> usize {
    while blob.len() % 4 != 0 {
        blob.push(0);
    }
    let offset = blob.len();
    blob.extend_from_slice(bytes);
    let views = json["bufferViews"]
        .as_array_mut()
        .expect("bufferViews is an array");
    let mut view = json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() });
    if let Some(t) = target {
        view["target"] = json!(t);
    }
    views.push(view);
    views.len() - 1
}

fn push_accessor(json: &mut Value, accessor: Value) -> usize {
    let list = json["accessors"]
        .as_array_mut()
        .expect("accessors is an array");
    list.push(accessor);
    list.len() - 1
}

fn ensure_array(json: &mut Value, key: &str) {
    if !json[key].is_array() {
        json[key] = json!([]);
    }
}

/// Percent-decodes a relative URI (`%20` → space).
fn decode_uri(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let Ok(v) = u8::from_str_radix(&uri[i + 1..i + 3], 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Builds the baked glTF. `lightmaps` lists (node, lightmap) for every baked primitive;
/// `stem` is the output file name without extension.
///
/// # Errors
/// [`BakeError::BadAccessor`] / [`BakeError::BadGltf`] if the source cannot be re-read,
/// [`BakeError::Read`] for an external image that cannot be copied.
pub fn baked_gltf(
    source: &GltfSource,
    original: &Scene,
    layout: &Layout,
    lightmaps: &[(usize, NodeLightmap)],
    volumes: &[VolumeExtras],
    stem: &str,
) -> Result<BakedGltf> {
    let path = &source.path;
    let mut json = source.json.clone();
    let root: gltf::json::Root = serde_json::from_value(source.json.clone())
        .map_err(|e| err(path, format!("cannot re-read the document: {e}")))?;
    let document = gltf::Document::from_json_without_validation(root);
    for key in ["buffers", "bufferViews", "accessors"] {
        ensure_array(&mut json, key);
    }
    // 1. Every buffer merged into one blob, the views pointed at it.
    let mut blob = merge_buffers(&mut json, &source.buffers);
    // 2. Unwrapped primitives rewritten.
    for (m, unwrap) in layout.meshes.iter().enumerate() {
        let (Some(unwrap), Some(src)) = (unwrap, original.meshes[m].source) else {
            continue;
        };
        let Some(gprim) = document
            .meshes()
            .nth(src.mesh)
            .and_then(|gmesh| gmesh.primitives().nth(src.primitive))
        else {
            continue;
        };
        let mut out = Out {
            json: &mut json,
            blob: &mut blob,
        };
        let context = |sem: &str| {
            format!(
                "mesh '{}' primitive {} {sem}",
                original.meshes[m].name, src.primitive
            )
        };
        rewrite_primitive(&mut out, source, &gprim, src, unwrap, &context)?;
    }
    // 3. Lightmap references in node extras, volumes in the scenes' extras; 4. punctual
    // lights marked as baked (or baked indirect only).
    write_node_lightmaps(&mut json, lightmaps);
    write_scene_volumes(&mut json, volumes);
    mark_lights_baked(&mut json, original);
    // 5. Images copied (gltf) or embedded (glb), then one buffer and the container.
    let mut files = images(&mut json, &mut blob, source)?;
    while blob.len() % 4 != 0 {
        blob.push(0);
    }
    if source.is_glb {
        json["buffers"] = json!([{ "byteLength": blob.len() }]);
        let text = serde_json::to_vec(&json).map_err(|e| err(path, e.to_string()))?;
        files.push((PathBuf::from(format!("{stem}.glb")), glb(text, &blob)));
    } else {
        let bin = format!("{stem}.bin");
        json["buffers"] = json!([{ "byteLength": blob.len(), "uri": bin }]);
        let text = serde_json::to_vec_pretty(&json).map_err(|e| err(path, e.to_string()))?;
        files.push((PathBuf::from(format!("{stem}.gltf")), text));
        files.push((PathBuf::from(bin), blob));
    }
    Ok(BakedGltf { files })
}

/// The document and the merged buffer being written.
struct Out<'a> {
    json: &'a mut Value,
    blob: &'a mut Vec<u8>,
}

/// Concatenates every buffer (16-byte aligned) and points the buffer views at the result.
fn merge_buffers(json: &mut Value, buffers: &[Vec<u8>]) -> Vec<u8> {
    let mut blob = Vec::new();
    let mut base = Vec::with_capacity(buffers.len());
    for b in buffers {
        while blob.len() % 16 != 0 {
            blob.push(0);
        }
        base.push(blob.len());
        blob.extend_from_slice(b);
    }
    for view in json["bufferViews"]
        .as_array_mut()
        .expect("array")
        .iter_mut()
    {
        let b = view["buffer"].as_u64().unwrap_or(0) as usize;
        let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        view["buffer"] = json!(0);
        view["byteOffset"] = json!(base.get(b).copied().unwrap_or(0) + offset);
    }
    blob
}

/// Gives a primitive its `TEXCOORD_1` and, when xatlas split its vertices, gathers every
/// other attribute (and morph target) through the split and writes new triangle indices.
fn rewrite_primitive(
    out: &mut Out<'_>,
    source: &GltfSource,
    gprim: &gltf::Primitive<'_>,
    src: GltfPrimitiveRef,
    unwrap: &MeshUnwrap,
    context: &dyn Fn(&str) -> String,
) -> Result<()> {
    let uv1_bytes: Vec<u8> = unwrap
        .uv1
        .iter()
        .flat_map(|p| [p.x, p.y])
        .flat_map(f32::to_le_bytes)
        .collect();
    let uv1_view = push_view(out.json, out.blob, &uv1_bytes, Some(34962));
    let uv1_accessor = push_accessor(
        out.json,
        json!({ "bufferView": uv1_view, "componentType": 5126, "count": unwrap.uv1.len(), "type": "VEC2" }),
    );
    let mut new_attributes = serde_json::Map::new();
    let mut new_targets: Vec<serde_json::Map<String, Value>> = Vec::new();
    if let Some(xref) = &unwrap.xref {
        for (semantic, accessor) in gprim.attributes() {
            let name = semantic.to_string();
            if name == "TEXCOORD_1" {
                continue;
            }
            let idx = gather(out, source, &accessor, xref, &name, context)?;
            new_attributes.insert(name, json!(idx));
        }
        for target in gprim.morph_targets() {
            let mut t = serde_json::Map::new();
            for (name, acc) in [
                ("POSITION", target.positions()),
                ("NORMAL", target.normals()),
                ("TANGENT", target.tangents()),
            ] {
                if let Some(acc) = acc {
                    t.insert(
                        name.into(),
                        json!(gather(out, source, &acc, xref, name, context)?),
                    );
                }
            }
            new_targets.push(t);
        }
    }
    new_attributes.insert("TEXCOORD_1".into(), json!(uv1_accessor));
    let prim = &mut out.json["meshes"][src.mesh]["primitives"][src.primitive];
    if unwrap.xref.is_some() {
        prim["attributes"] = Value::Object(new_attributes);
        if !new_targets.is_empty() {
            prim["targets"] = json!(new_targets);
        }
    } else {
        prim["attributes"]["TEXCOORD_1"] = json!(uv1_accessor);
    }
    // Indices: always a triangle list after unwrapping (strips and fans are converted).
    if unwrap.xref.is_some() || prim.get("mode").is_some_and(|m| m.as_u64() != Some(4)) {
        let acc = write_indices(out, unwrap);
        let prim = &mut out.json["meshes"][src.mesh]["primitives"][src.primitive];
        prim["indices"] = json!(acc);
        prim["mode"] = json!(4);
    }
    Ok(())
}

/// A new accessor holding `accessor`'s elements in the order of `xref` (new vertex k is old
/// vertex `xref[k]`); `sem` names the attribute in messages.
fn gather(
    out: &mut Out<'_>,
    source: &GltfSource,
    accessor: &gltf::Accessor<'_>,
    xref: &[u32],
    sem: &str,
    context: &dyn Fn(&str) -> String,
) -> Result<usize> {
    let dense = read_dense(accessor, &source.buffers, &context(sem))?;
    let es = dense.element_size;
    let mut bytes = Vec::with_capacity(xref.len() * es);
    for &i in xref {
        let i = i as usize;
        bytes.extend_from_slice(&dense.bytes[i * es..(i + 1) * es]);
    }
    let view = push_view(out.json, out.blob, &bytes, Some(34962));
    let mut acc = json!({
        "bufferView": view,
        "componentType": accessor.data_type().as_gl_enum(),
        "count": xref.len(),
        "type": dimensions_name(accessor.dimensions()),
    });
    if accessor.normalized() {
        acc["normalized"] = json!(true);
    }
    if sem == "POSITION" && dense.data_type == gltf::accessor::DataType::F32 && es == 12 {
        let (lo, hi) = min_max3(&bytes);
        acc["min"] = json!(lo);
        acc["max"] = json!(hi);
    }
    Ok(push_accessor(out.json, acc))
}

/// The unwrap's triangle list as a new index accessor (16-bit when the vertices allow).
fn write_indices(out: &mut Out<'_>, unwrap: &MeshUnwrap) -> usize {
    let count = unwrap.indices.len();
    let (bytes, component): (Vec<u8>, u32) = if unwrap.uv1.len() <= u16::MAX as usize {
        (
            unwrap
                .indices
                .iter()
                .flat_map(|&i| (i as u16).to_le_bytes())
                .collect(),
            5123,
        )
    } else {
        (
            unwrap
                .indices
                .iter()
                .flat_map(|&i| i.to_le_bytes())
                .collect(),
            5125,
        )
    };
    let view = push_view(out.json, out.blob, &bytes, Some(34963));
    push_accessor(
        out.json,
        json!({ "bufferView": view, "componentType": component, "count": count, "type": "SCALAR" }),
    )
}

/// Writes every baked node's `extras.lightbake.lightmaps` (its other extras kept).
fn write_node_lightmaps(json: &mut Value, lightmaps: &[(usize, NodeLightmap)]) {
    let mut by_node: HashMap<usize, Vec<NodeLightmap>> = HashMap::new();
    for (node, l) in lightmaps {
        by_node.entry(*node).or_default().push(l.clone());
    }
    let mut nodes: Vec<_> = by_node.into_iter().collect();
    nodes.sort_by_key(|(n, _)| *n);
    for (node, list) in nodes {
        let node_json = &mut json["nodes"][node];
        if !node_json.is_object() {
            continue;
        }
        let mut lb: NodeExtras = extras::read_value(
            node_json["extras"].get(extras::KEY),
            "node",
            &mut Vec::new(),
        );
        lb.lightmaps = list;
        extras::write(node_json, &lb);
    }
}

/// Writes every scene's `extras.lightbake.irradiance_volumes` (its other extras kept), so an
/// engine that spawns the scene finds its volumes.
fn write_scene_volumes(json: &mut Value, volumes: &[VolumeExtras]) {
    if volumes.is_empty() {
        return;
    }
    let Some(scenes) = json.get_mut("scenes").and_then(Value::as_array_mut) else {
        return;
    };
    for scene in scenes.iter_mut().filter(|s| s.is_object()) {
        let mut lb: SceneExtras =
            extras::read_value(scene["extras"].get(extras::KEY), "scene", &mut Vec::new());
        lb.irradiance_volumes = volumes.to_vec();
        extras::write(scene, &lb);
    }
}

/// Marks every punctual light as baked (`extras.lightbake.baked`), so an engine that loads the
/// baked glTF can keep the light for specular and dynamic objects but stop it lighting
/// lightmapped surfaces a second time (Bevy: `affects_lightmapped_mesh_diffuse`, which the
/// `bevy_lightbake` plugin sets from this flag) — except the lights `original` bakes
/// indirect only (matched by the light's name, or its nodes' names when it has none): those
/// get `bake: "indirect"` and stay real-time.
fn mark_lights_baked(json: &mut Value, original: &Scene) {
    let indirect: Vec<&str> = original
        .lights
        .iter()
        .filter(|l| !l.direct_is_baked())
        .map(|l| l.name.as_str())
        .collect();
    // The names of the nodes that carry each light.
    let mut carriers: Vec<Vec<String>> = Vec::new();
    for node in json
        .get("nodes")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let light = node
            .pointer("/extensions/KHR_lights_punctual/light")
            .and_then(Value::as_u64);
        if let (Some(i), Some(name)) = (light, node.get("name").and_then(Value::as_str)) {
            let i = i as usize;
            if carriers.len() <= i {
                carriers.resize(i + 1, Vec::new());
            }
            carriers[i].push(name.to_string());
        }
    }
    let Some(lights) = json
        .pointer_mut("/extensions/KHR_lights_punctual/lights")
        .and_then(Value::as_array_mut)
    else {
        return;
    };
    for (i, light) in lights.iter_mut().enumerate().filter(|(_, l)| l.is_object()) {
        let mut lb: LightExtras =
            extras::read_value(light["extras"].get(extras::KEY), "light", &mut Vec::new());
        let only_indirect = match light.get("name").and_then(Value::as_str) {
            Some(name) => indirect.contains(&name),
            None => carriers
                .get(i)
                .is_some_and(|names| names.iter().any(|n| indirect.contains(&n.as_str()))),
        };
        lb.baked = !only_indirect;
        lb.bake = only_indirect.then_some(LightBakeExtras::Indirect);
        extras::write(light, &lb);
    }
}

/// External images: embedded in the blob for a `.glb`, or returned as files to copy next to
/// a `.gltf` (paths leaving the folder go to `textures/`).
fn images(
    json: &mut Value,
    blob: &mut Vec<u8>,
    source: &GltfSource,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut files = Vec::new();
    let source_dir = source.path.parent().unwrap_or(Path::new("."));
    let image_count = json
        .get("images")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    for i in 0..image_count {
        let Some(uri) = json["images"][i]
            .get("uri")
            .and_then(Value::as_str)
            .map(str::to_string)
        else {
            continue;
        };
        if uri.starts_with("data:") {
            continue;
        }
        let rel = decode_uri(&uri);
        let file = source_dir.join(&rel);
        let bytes = std::fs::read(&file).map_err(|e| BakeError::Read {
            path: file.clone(),
            source: e,
        })?;
        if source.is_glb {
            let mime = if rel.to_ascii_lowercase().ends_with(".png") {
                "image/png"
            } else {
                "image/jpeg"
            };
            let view = push_view(json, blob, &bytes, None);
            let image = json["images"][i]
                .as_object_mut()
                .expect("image is an object");
            image.remove("uri");
            image.insert("bufferView".into(), json!(view));
            image.insert("mimeType".into(), json!(mime));
        } else {
            let safe = !rel.contains("..") && !Path::new(&rel).is_absolute();
            let dest = if safe {
                PathBuf::from(&rel)
            } else {
                PathBuf::from("textures").join(Path::new(&rel).file_name().unwrap_or_default())
            };
            json["images"][i]["uri"] = json!(dest.to_string_lossy().replace('\\', "/"));
            files.push((dest, bytes));
        }
    }
    Ok(files)
}

fn dimensions_name(d: gltf::accessor::Dimensions) -> &'static str {
    use gltf::accessor::Dimensions::*;
    match d {
        Scalar => "SCALAR",
        Vec2 => "VEC2",
        Vec3 => "VEC3",
        Vec4 => "VEC4",
        Mat2 => "MAT2",
        Mat3 => "MAT3",
        Mat4 => "MAT4",
    }
}

fn min_max3(bytes: &[u8]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for c in bytes.chunks_exact(12) {
        for k in 0..3 {
            let v = f32::from_le_bytes([c[4 * k], c[4 * k + 1], c[4 * k + 2], c[4 * k + 3]]);
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    (lo, hi)
}
