//! A glTF scene of the attribute combinations and material kinds Bevy's `StandardMaterial`
//! shader has to compile for with a lightmap: no `TEXCOORD_0` anywhere, no normals, vertex
//! colours, tangents, a mesh's own `TEXCOORD_1`, double-sided, emissive, glossy (IOR and
//! specular), transmissive, clear-coated, blended, masked and unlit materials.

use std::path::{Path, PathBuf};

use bevy::prelude::*;
use serde_json::{Value, json};

/// A glTF document and its binary buffer, built up.
struct Doc {
    json: Value,
    bin: Vec<u8>,
}

impl Doc {
    /// An accessor of `values` (floats, `n` per element) in a new buffer view.
    fn floats(&mut self, values: &[f32], kind: &str, n: usize) -> usize {
        let offset = self.bin.len();
        self.bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        let view = push(
            &mut self.json["bufferViews"],
            json!({"buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4}),
        );
        let acc = json!({"bufferView": view, "componentType": 5126, "count": values.len() / n, "type": kind});
        push(&mut self.json["accessors"], acc)
    }

    /// A POSITION accessor of `values` (x, y, z each), with its bounds.
    fn positions(&mut self, values: &[f32]) -> usize {
        let acc = self.floats(values, "VEC3", 3);
        let (lo, hi) = bounds(values);
        self.json["accessors"][acc]["min"] = json!(lo);
        self.json["accessors"][acc]["max"] = json!(hi);
        acc
    }

    fn indices(&mut self, values: &[u32]) -> usize {
        let offset = self.bin.len();
        self.bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        let view = push(
            &mut self.json["bufferViews"],
            json!({"buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4}),
        );
        push(
            &mut self.json["accessors"],
            json!({"bufferView": view, "componentType": 5125, "count": values.len(), "type": "SCALAR"}),
        )
    }
}

fn push(list: &mut Value, item: Value) -> usize {
    let list = list.as_array_mut().unwrap();
    list.push(item);
    list.len() - 1
}

fn bounds(values: &[f32]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for p in values.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// A box's vertex attributes as floats, and its indices.
#[derive(Default)]
struct Cuboid {
    positions: Vec<f32>,
    normals: Vec<f32>,
    tangents: Vec<f32>,
    uv1: Vec<f32>,
    indices: Vec<u32>,
}

/// A box of half-size `h` (four vertices per face), with a TEXCOORD_1 that puts each face in
/// its own cell of a 3 × 2 grid.
fn cuboid(h: Vec3) -> Cuboid {
    let Cuboid {
        positions: mut p,
        normals: mut n,
        tangents: mut t,
        uv1: mut uv,
        indices: mut idx,
    } = Cuboid::default();
    let faces = [
        Vec3::X,
        Vec3::NEG_X,
        Vec3::Y,
        Vec3::NEG_Y,
        Vec3::Z,
        Vec3::NEG_Z,
    ];
    for (f, normal) in faces.into_iter().enumerate() {
        let u = if normal.y.abs() > 0.5 {
            Vec3::X
        } else {
            Vec3::Y
        };
        let v = normal.cross(u);
        let base = (p.len() / 3) as u32;
        let cell = Vec2::new((f % 3) as f32, (f / 3) as f32);
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let q = (normal + u * a + v * b) * h;
            p.extend(q.to_array());
            n.extend(normal.to_array());
            t.extend([u.x, u.y, u.z, 1.0]);
            let c = (cell + Vec2::new(0.1 + 0.4 * (a + 1.0), 0.1 + 0.4 * (b + 1.0)))
                / Vec2::new(3.0, 2.0);
            uv.extend(c.to_array());
        }
        idx.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    Cuboid {
        positions: p,
        normals: n,
        tangents: t,
        uv1: uv,
        indices: idx,
    }
}

/// Writes `combos.gltf` (+ `.bin`) into `dir`: a 10 m floor with no texture coordinates,
/// twelve boxes on it, each a mesh with one attribute combination or material kind, a lamp
/// and a sun. Returns the glTF's path.
pub fn combos_scene(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut doc = Doc {
        json: json!({
            "asset": {"version": "2.0"},
            "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength",
                "KHR_materials_ior", "KHR_materials_specular", "KHR_materials_transmission",
                "KHR_materials_volume", "KHR_materials_clearcoat", "KHR_materials_unlit"],
            "buffers": [], "bufferViews": [], "accessors": [], "meshes": [], "nodes": [],
            "materials": [
                {"name": "white", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1.0], "metallicFactor": 0.0}},
                {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.2, 0.15, 1.0], "metallicFactor": 0.0}},
                {"name": "two_sided", "doubleSided": true, "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.6, 0.3, 1.0], "metallicFactor": 0.0}},
                {"name": "glow", "emissiveFactor": [1.0, 0.8, 0.5], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}},
                    "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0}},
                {"name": "glossy", "extensions": {"KHR_materials_ior": {"ior": 1.7}, "KHR_materials_specular": {"specularFactor": 0.8}},
                    "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.3, 0.7, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.3}},
                {"name": "glass", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.5}, "KHR_materials_volume": {"thicknessFactor": 0.2}},
                    "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.9, 0.9, 1.0], "metallicFactor": 0.0}},
                {"name": "coated", "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.1}},
                    "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.5, 0.2, 1.0], "metallicFactor": 0.0}},
                {"name": "blended", "alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.9, 0.5], "metallicFactor": 0.0}},
                {"name": "masked", "alphaMode": "MASK", "alphaCutoff": 0.5, "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.6, 1.0], "metallicFactor": 0.0}},
                {"name": "unlit", "extensions": {"KHR_materials_unlit": {}}, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}
            ],
            "extensions": {"KHR_lights_punctual": {"lights": [
                {"type": "point", "name": "lamp", "color": [1.0, 0.9, 0.8], "intensity": 400.0},
                {"type": "directional", "name": "sun", "intensity": 3.0}
            ]}},
            "scenes": [{"nodes": []}], "scene": 0
        }),
        bin: Vec::new(),
    };
    // The floor: positions and normals only.
    let s = 5.0;
    let fp = [-s, 0.0, -s, -s, 0.0, s, s, 0.0, s, s, 0.0, -s];
    let pos = doc.positions(&fp);
    let nor = doc.floats(&[0.0, 1.0, 0.0].repeat(4), "VEC3", 3);
    let ind = doc.indices(&[0, 1, 2, 0, 2, 3]);
    let mut meshes = vec![(
        "floor",
        json!({"POSITION": pos, "NORMAL": nor}),
        ind,
        0,
        Vec3::ZERO,
    )];
    // The boxes: (name, attributes beyond POSITION, material).
    let kinds: [(&str, &[&str], usize); 12] = [
        ("plain", &["NORMAL"], 1),
        ("no_normals", &[], 1),
        ("vertex_colours", &["NORMAL", "COLOR_0"], 0),
        ("tangents", &["NORMAL", "TANGENT"], 1),
        ("own_uv1", &["NORMAL", "TEXCOORD_1"], 1),
        ("two_sided", &["NORMAL"], 2),
        ("emissive", &["NORMAL"], 3),
        ("glossy", &["NORMAL"], 4),
        ("glass", &["NORMAL"], 5),
        ("coated", &["NORMAL"], 6),
        ("blended", &["NORMAL"], 7),
        ("masked", &["NORMAL"], 8),
    ];
    let Cuboid {
        positions: bp,
        normals: bn,
        tangents: bt,
        uv1: buv,
        indices: bi,
    } = cuboid(Vec3::splat(0.4));
    let box_pos = doc.positions(&bp);
    let box_nor = doc.floats(&bn, "VEC3", 3);
    let box_tan = doc.floats(&bt, "VEC4", 4);
    let box_uv1 = doc.floats(&buv, "VEC2", 2);
    let box_col = doc.floats(&[0.9, 0.85, 0.8, 1.0].repeat(bp.len() / 3), "VEC4", 4);
    let box_ind = doc.indices(&bi);
    for (k, (name, attributes, material)) in kinds.iter().enumerate() {
        let mut a = json!({"POSITION": box_pos});
        for &attr in *attributes {
            a[attr] = json!(match attr {
                "NORMAL" => box_nor,
                "TANGENT" => box_tan,
                "TEXCOORD_1" => box_uv1,
                _ => box_col,
            });
        }
        let at = Vec3::new(
            -3.0 + 1.5 * (k % 4) as f32,
            0.4,
            -2.0 + 2.0 * (k / 4) as f32,
        );
        meshes.push((name, a, box_ind, *material, at));
    }
    // The unlit one, beside the others.
    meshes.push((
        "unlit",
        json!({"POSITION": box_pos, "NORMAL": box_nor}),
        box_ind,
        9,
        Vec3::new(3.5, 0.4, 3.5),
    ));
    for (name, attributes, indices, material, at) in meshes {
        let mesh = push(
            &mut doc.json["meshes"],
            json!({"name": name, "primitives": [{"attributes": attributes, "indices": indices, "material": material}]}),
        );
        let node = push(
            &mut doc.json["nodes"],
            json!({"name": name, "mesh": mesh, "translation": at.to_array()}),
        );
        push(&mut doc.json["scenes"][0]["nodes"], json!(node));
    }
    for (name, light, at, rotation) in [
        ("lamp", 0, [0.5, 2.5, 0.5], [0.0, 0.0, 0.0, 1.0]),
        // 50° down from the vertical, from +x.
        (
            "sun",
            1,
            [0.0, 10.0, 0.0],
            [0.0, 0.0, 0.42261826, 0.90630779],
        ),
    ] {
        let node = push(
            &mut doc.json["nodes"],
            json!({"name": name, "translation": at, "rotation": rotation, "extensions": {"KHR_lights_punctual": {"light": light}}}),
        );
        push(&mut doc.json["scenes"][0]["nodes"], json!(node));
    }
    doc.json["buffers"] = json!([{"byteLength": doc.bin.len(), "uri": "combos.bin"}]);
    let path = dir.join("combos.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc.json).unwrap()).unwrap();
    std::fs::write(dir.join("combos.bin"), &doc.bin).unwrap();
    path
}
