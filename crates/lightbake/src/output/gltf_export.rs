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

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use super::drawable;
use crate::error::{BakeError, Result};
use crate::scene::extras::{
    self, LightBakeExtras, LightExtras, NodeExtras, NodeLightmap, SceneExtras,
};
use crate::scene::glb::glb;
use crate::scene::gltf_accessor::read_dense;
use crate::scene::gltf_import::GltfSource;
use crate::scene::resources::{percent_decode, percent_encode_path, used_buffer_views};
use crate::scene::{GltfPrimitiveRef, Scene};
use crate::unwrap::{Layout, MeshUnwrap};

/// The files of the baked glTF, and what it adds or cannot help for Bevy to draw it.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct BakedGltf {
    /// (path relative to the output directory, bytes) of every file.
    pub files: Vec<(PathBuf, Vec<u8>)>,
    /// The primitives given a `TEXCOORD_0` (the accessor of their `TEXCOORD_1`), as
    /// `mesh 'NAME' primitive P` ([`drawable::add_texcoord_0`]).
    pub texcoord_0_added: Vec<String>,
    /// Why parts of the baked scene draw other than as baked in Bevy
    /// ([`drawable::drawing_warnings`]).
    pub warnings: Vec<String>,
}

fn err(path: &Path, message: impl Into<String>) -> BakeError {
    BakeError::BadGltf {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Appends `bytes` to the blob (4-byte aligned) and returns a new bufferView index.
fn push_view(json: &mut Value, blob: &mut Vec<u8>, bytes: &[u8], target: Option<u32>) -> usize {
    while !blob.len().is_multiple_of(4) {
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

/// Builds the baked glTF. `lightmaps` lists (node, lightmap) for every baked primitive;
/// `written` holds the scene extras the bake writes (its volumes and light groups); `stem` is
/// the output file name without extension; `reserved` names the other files of the output
/// folder (relative, `/`-separated), which copied images never replace.
///
/// Only bytes the import read go out: the buffer views in use (not whole buffers), and the
/// image files the import read under its read rule.
///
/// # Errors
/// [`BakeError::BadAccessor`] / [`BakeError::BadGltf`] if the source cannot be re-read or a
/// buffer view in use lies outside its buffer.
pub fn baked_gltf(
    source: &GltfSource,
    original: &Scene,
    layout: &Layout,
    lightmaps: &[(usize, NodeLightmap)],
    written: &SceneExtras,
    stem: &str,
    reserved: &[String],
) -> Result<BakedGltf> {
    let path = &source.path;
    let mut json = source.json.clone();
    let root: gltf::json::Root = serde_json::from_value(source.json.clone())
        .map_err(|e| err(path, format!("cannot re-read the document: {e}")))?;
    let document = gltf::Document::from_json_without_validation(root);
    for key in ["buffers", "bufferViews", "accessors"] {
        ensure_array(&mut json, key);
    }
    // 1. The buffer views in use copied into one blob, the others dropped.
    let mut blob = merge_buffers(&mut json, &source.buffers).map_err(|m| err(path, m))?;
    // 2. Unwrapped primitives rewritten.
    let mut baked = Vec::new();
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
        baked.push((src.mesh, src.primitive));
    }
    // 3. What Bevy needs to draw the primitives: TEXCOORD_0 where only TEXCOORD_1 is.
    let warnings = drawable::drawing_warnings(&json, &baked);
    let texcoord_0_added = drawable::add_texcoord_0(&mut json);
    // 4. Lightmap references in node extras, volumes in the scenes' extras; 5. punctual
    // lights marked as baked (or baked indirect only).
    write_node_lightmaps(&mut json, lightmaps);
    write_scene_extras(&mut json, written);
    mark_lights_baked(&mut json, original);
    // 6. Images copied (gltf) or embedded (glb), then one buffer and the container.
    let mut taken: HashSet<String> = reserved.iter().map(|r| r.to_lowercase()).collect();
    for ext in ["gltf", "glb", "bin"] {
        taken.insert(format!("{stem}.{ext}").to_lowercase());
    }
    let mut files = images(&mut json, &mut blob, source, &mut taken);
    while blob.len() % 4 != 0 {
        blob.push(0);
    }
    if source.is_glb {
        json["buffers"] = json!([{ "byteLength": blob.len() }]);
        let text = serde_json::to_vec(&json).map_err(|e| err(path, e.to_string()))?;
        files.push((PathBuf::from(format!("{stem}.glb")), glb(text, &blob)));
    } else {
        let bin = format!("{stem}.bin");
        json["buffers"] = json!([{ "byteLength": blob.len(), "uri": percent_encode_path(&bin) }]);
        let text = serde_json::to_vec_pretty(&json).map_err(|e| err(path, e.to_string()))?;
        files.push((PathBuf::from(format!("{stem}.gltf")), text));
        files.push((PathBuf::from(bin), blob));
    }
    Ok(BakedGltf {
        files,
        texcoord_0_added,
        warnings,
    })
}

/// The document and the merged buffer being written.
struct Out<'a> {
    json: &'a mut Value,
    blob: &'a mut Vec<u8>,
}

/// Copies every buffer view in use into one blob (each at its old offset modulo 16, so every
/// accessor keeps its alignment), drops the views nothing uses and renumbers the references.
///
/// # Errors
/// A view in use that lies outside its buffer.
fn merge_buffers(json: &mut Value, buffers: &[Vec<u8>]) -> std::result::Result<Vec<u8>, String> {
    let used = used_buffer_views(json);
    let views = json["bufferViews"].as_array().cloned().unwrap_or_default();
    let mut blob = Vec::new();
    let mut kept = Vec::new();
    let mut renumber = vec![None; views.len()];
    for (v, view) in views.iter().enumerate() {
        if !used[v] {
            continue;
        }
        let b = view["buffer"].as_u64().unwrap_or(0) as usize;
        let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let length = view["byteLength"].as_u64().unwrap_or(0) as usize;
        let bytes = buffers
            .get(b)
            .and_then(|data| data.get(offset..offset.checked_add(length)?))
            .ok_or_else(|| {
                format!("bufferView {v} (bytes {offset}..+{length} of buffer {b}) lies outside its buffer")
            })?;
        while blob.len() % 16 != offset % 16 {
            blob.push(0);
        }
        let mut out = view.clone();
        out["buffer"] = json!(0);
        out["byteOffset"] = json!(blob.len());
        blob.extend_from_slice(bytes);
        renumber[v] = Some(kept.len());
        kept.push(out);
    }
    json["bufferViews"] = Value::Array(kept);
    let mut stack: Vec<&mut Value> = vec![json];
    while let Some(v) = stack.pop() {
        match v {
            Value::Object(map) => {
                for (k, child) in map.iter_mut() {
                    if k == "bufferView"
                        && let Some(i) = child.as_u64()
                    {
                        *child = json!(renumber.get(i as usize).copied().flatten().unwrap_or(0));
                    } else {
                        stack.push(child);
                    }
                }
            }
            Value::Array(list) => stack.extend(list.iter_mut()),
            _ => {}
        }
    }
    Ok(blob)
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
    // A TEXCOORD_0 sharing the TEXCOORD_1 accessor is an earlier bake's addition: dropped
    // here, and given again on the new TEXCOORD_1 by `drawable::add_texcoord_0`.
    let earlier_copy = drawable::shares_lightmap_uvs(
        &source.json["meshes"][src.mesh]["primitives"][src.primitive],
    );
    let mut new_attributes = serde_json::Map::new();
    let mut new_targets: Vec<serde_json::Map<String, Value>> = Vec::new();
    if let Some(xref) = &unwrap.xref {
        for (semantic, accessor) in gprim.attributes() {
            let name = semantic.to_string();
            if name == "TEXCOORD_1" || (earlier_copy && name == "TEXCOORD_0") {
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
        if earlier_copy && let Some(attributes) = prim["attributes"].as_object_mut() {
            attributes.remove("TEXCOORD_0");
        }
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

/// Writes every scene's `extras.lightbake.irradiance_volumes` and `light_groups` from
/// `written` (its other extras kept), so an engine that spawns the scene finds its volumes and
/// groups.
fn write_scene_extras(json: &mut Value, written: &SceneExtras) {
    if written.irradiance_volumes.is_empty() && written.light_groups.is_empty() {
        return;
    }
    let Some(scenes) = json.get_mut("scenes").and_then(Value::as_array_mut) else {
        return;
    };
    for scene in scenes.iter_mut().filter(|s| s.is_object()) {
        let mut lb: SceneExtras =
            extras::read_value(scene["extras"].get(extras::KEY), "scene", &mut Vec::new());
        lb.irradiance_volumes = written.irradiance_volumes.clone();
        lb.light_groups = written.light_groups.clone();
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

/// External images the import read: embedded in the blob for a `.glb`, or returned as files
/// to copy next to a `.gltf` — at their own relative path when it stays inside the folder and
/// no other output file has it (`taken`), else under `textures/` with a free name — their
/// URIs percent-encoded. Images the import did not read keep their URIs and are not copied.
fn images(
    json: &mut Value,
    blob: &mut Vec<u8>,
    source: &GltfSource,
    taken: &mut HashSet<String>,
) -> Vec<(PathBuf, Vec<u8>)> {
    let mut files = Vec::new();
    let image_count = json
        .get("images")
        .and_then(Value::as_array)
        .map_or(0, Vec::len);
    for i in 0..image_count {
        let (Some(uri), Some(Some(bytes))) = (
            json["images"][i]
                .get("uri")
                .and_then(Value::as_str)
                .map(str::to_string),
            source.images.get(i),
        ) else {
            continue;
        };
        let rel = percent_decode(&uri).unwrap_or_default();
        if source.is_glb {
            let png = bytes.starts_with(b"\x89PNG");
            let view = push_view(json, blob, bytes, None);
            let image = json["images"][i]
                .as_object_mut()
                .expect("image is an object");
            image.remove("uri");
            image.insert("bufferView".into(), json!(view));
            image.insert(
                "mimeType".into(),
                json!(if png { "image/png" } else { "image/jpeg" }),
            );
        } else {
            let dest = image_destination(&rel, taken);
            json["images"][i]["uri"] = json!(percent_encode_path(&dest));
            files.push((PathBuf::from(dest), bytes.clone()));
        }
    }
    files
}

/// Where a copied image goes: `rel` with `.` and inner `..` steps resolved when it stays
/// inside the folder and is free, else `textures/NAME` (or `textures/STEM-K.EXT`) free.
fn image_destination(rel: &str, taken: &mut HashSet<String>) -> String {
    let mut parts: Vec<&str> = Vec::new();
    let mut inside = true;
    for part in rel.split(['/', '\\']) {
        match part {
            "" | "." => {}
            ".." => inside &= parts.pop().is_some(),
            p => parts.push(p),
        }
    }
    let name = parts.last().copied().unwrap_or("image");
    let mut candidates = Vec::new();
    if inside && !parts.is_empty() {
        candidates.push(parts.join("/"));
    }
    candidates.push(format!("textures/{name}"));
    let (stem, ext) = match name.rsplit_once('.') {
        Some((s, e)) if !s.is_empty() => (s, format!(".{e}")),
        _ => (name, String::new()),
    };
    let dest = candidates
        .into_iter()
        .chain((1..).map(|k| format!("textures/{stem}-{k}{ext}")))
        .find(|c| !taken.contains(&c.to_lowercase()))
        .expect("an endless list has a free name");
    taken.insert(dest.to_lowercase());
    dest
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
