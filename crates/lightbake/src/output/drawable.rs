//! What the baked glTF needs so that Bevy draws it, and what Bevy cannot draw as baked.
//!
//! Bevy 0.20's `StandardMaterial` fragment shader (`pbr_fragment.wesl`) declares the
//! texture coordinate `uv` only when the mesh has `UV_0` (`VERTEX_UVS_A`), but reads it
//! whenever the mesh has any UV set: with `UV_1` alone it starts `var uv_b = uv;` and the
//! pipeline fails to compile (`cannot find declaration of 'uv'`), so the mesh is not drawn
//! at all. Every baked primitive gets `TEXCOORD_1`; one without `TEXCOORD_0` is given one
//! that names the same accessor as its `TEXCOORD_1` ([`add_texcoord_0`]). That costs no
//! bytes, and changes nothing a textured mesh shows: a valid glTF primitive that samples a
//! texture by `TEXCOORD_0` has one already. A later bake of the baked glTF treats a
//! `TEXCOORD_0` that shares the `TEXCOORD_1` accessor as this addition and keeps it on the
//! new `TEXCOORD_1`.
//!
//! The other attribute combinations the shader was checked with (the render test
//! `tests/render_corpus.rs` draws each one) need nothing: no normals (Bevy's loader computes
//! flat ones), vertex colours, tangents without `TEXCOORD_0`, double-sided materials,
//! `KHR_materials_emissive_strength`, `_ior`, `_specular`, `_transmission`, `_volume`,
//! `_clearcoat`, alpha blending and masking.
//!
//! What still draws other than as baked is reported by [`drawing_warnings`], one line per
//! material and reason, naming the first mesh: a texture read by a `TEXCOORD_n` the
//! primitive lacks or that Bevy does not read (it reads `TEXCOORD_0` and `TEXCOORD_1`, and
//! falls back to `TEXCOORD_0` above), vertex colours (Bevy multiplies the base colour by them;
//! the bake does not), transmission (Bevy multiplies the diffuse colour, and so the
//! lightmap, by 1 − transmission; the bake treats the surface as opaque), an unlit material
//! (Bevy shows no lightmap on it), and a required extension Bevy's glTF loader refuses
//! (nothing of the file loads).

use std::collections::BTreeMap;

use serde_json::Value;
#[cfg(test)]
use serde_json::json;

/// Extensions Bevy 0.20's glTF loader reads (its crate docs' table); a file that requires
/// any other is refused whole.
const BEVY_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_volume",
    "KHR_texture_transform",
];

/// A primitive as messages name it: `mesh 'NAME' primitive P`.
fn primitive_name(json: &Value, mesh: usize, primitive: usize) -> String {
    let name = json["meshes"][mesh]["name"]
        .as_str()
        .map_or_else(|| format!("mesh {mesh}"), |n| format!("mesh '{n}'"));
    format!("{name} primitive {primitive}")
}

/// A material as messages name it: `material 'NAME'` or `material M`.
fn material_name(json: &Value, material: usize) -> String {
    json["materials"][material]["name"].as_str().map_or_else(
        || format!("material {material}"),
        |n| format!("material '{n}'"),
    )
}

/// Whether the primitive has the attribute `name`.
fn has_attribute(prim: &Value, name: &str) -> bool {
    prim["attributes"].get(name).is_some()
}

/// The `(mesh, primitive)` of every primitive in the document, with its JSON.
fn primitives(json: &Value) -> Vec<(usize, usize, &Value)> {
    let mut out = Vec::new();
    for (m, mesh) in json["meshes"].as_array().into_iter().flatten().enumerate() {
        for (p, prim) in (mesh["primitives"].as_array().into_iter().flatten()).enumerate() {
            out.push((m, p, prim));
        }
    }
    out
}

/// Gives every primitive that has `TEXCOORD_1` but no `TEXCOORD_0` a `TEXCOORD_0` naming
/// the same accessor, so Bevy's `StandardMaterial` shader compiles for it (see the module
/// docs). Returns the primitives it was added to, as messages name them.
pub fn add_texcoord_0(json: &mut Value) -> Vec<String> {
    let mut added = Vec::new();
    let wanting: Vec<(usize, usize, Value)> = primitives(json)
        .into_iter()
        .filter_map(|(m, p, prim)| {
            let attributes = prim["attributes"].as_object()?;
            let uv1 = attributes.get("TEXCOORD_1")?;
            (!attributes.contains_key("TEXCOORD_0")).then(|| (m, p, uv1.clone()))
        })
        .collect();
    for (m, p, uv1) in wanting {
        json["meshes"][m]["primitives"][p]["attributes"]["TEXCOORD_0"] = uv1;
        added.push(primitive_name(json, m, p));
    }
    added
}

/// Every texture a material samples: (where in the material, the `TEXCOORD_n` it reads).
/// Found by walking the material for texture-info objects (an `index` under a key ending in
/// `Texture`), so the `KHR_materials_*` extensions' textures are included; a
/// `KHR_texture_transform` `texCoord` overrides the texture info's own.
fn material_textures(material: &Value) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let mut stack: Vec<(String, &Value)> = vec![(String::new(), material)];
    while let Some((path, v)) = stack.pop() {
        let Some(map) = v.as_object() else {
            continue;
        };
        for (key, child) in map {
            let here = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            if key.ends_with("Texture") && child.get("index").is_some() {
                let set = (child.pointer("/extensions/KHR_texture_transform/texCoord"))
                    .or_else(|| child.get("texCoord"))
                    .and_then(Value::as_u64)
                    .unwrap_or(0);
                out.push((here, set));
            } else if key != "extras" {
                stack.push((here, child));
            }
        }
    }
    out.sort();
    out
}

/// Why a baked scene draws other than as baked in Bevy, one line per material and reason
/// (naming the first primitive and how many more share it), and one per required extension
/// Bevy's loader refuses. `json` is the baked document before [`add_texcoord_0`]; `baked`
/// lists the `(mesh, primitive)` pairs that carry a lightmap.
pub fn drawing_warnings(json: &Value, baked: &[(usize, usize)]) -> Vec<String> {
    let mut warnings = Vec::new();
    for ext in json["extensionsRequired"].as_array().into_iter().flatten() {
        if let Some(ext) = ext.as_str()
            && !BEVY_EXTENSIONS.contains(&ext)
        {
            warnings.push(format!(
                "the scene requires the glTF extension {ext}, which Bevy's glTF loader does not read: Bevy refuses the whole baked glTF"
            ));
        }
    }
    // (material, reason) → (first primitive, how many).
    let mut found: BTreeMap<(usize, String), (String, usize)> = BTreeMap::new();
    let mut note = |material: usize, reason: String, prim: String| {
        (found.entry((material, reason)).or_insert((prim, 0))).1 += 1;
    };
    for (m, p, prim) in primitives(json) {
        let Some(material) = prim["material"].as_u64().map(|i| i as usize) else {
            continue;
        };
        let Some(mat) = json["materials"].get(material) else {
            continue;
        };
        let has = |set: u64| has_attribute(prim, &format!("TEXCOORD_{set}"));
        let is_baked = baked.contains(&(m, p));
        // What Bevy samples by when a texture's set is missing or above 1: TEXCOORD_0, which
        // a primitive with TEXCOORD_1 gets from [`add_texcoord_0`] if it has none.
        let fallback = if has(0) {
            "TEXCOORD_0"
        } else if has(1) {
            "TEXCOORD_0, the lightmap's UVs that the baked glTF copies there"
        } else {
            "nothing: it draws the material without that texture"
        };
        for (texture, set) in material_textures(mat) {
            let reason = if set >= 2 {
                format!(
                    "samples {texture} by TEXCOORD_{set}; Bevy reads textures by TEXCOORD_0 and TEXCOORD_1 only, and samples it by {fallback}"
                )
            } else if !has(set) {
                format!(
                    "samples {texture} by TEXCOORD_{set}, which the primitive does not have; Bevy samples it by {fallback}"
                )
            } else {
                continue;
            };
            note(material, reason, primitive_name(json, m, p));
        }
        if is_baked && has_attribute(prim, "COLOR_0") {
            note(
                material,
                "has vertex colours (COLOR_0): Bevy multiplies the base colour by them, while the bake's bounced light takes the base colour alone".into(),
                primitive_name(json, m, p),
            );
        }
        let transmission = (mat
            .pointer("/extensions/KHR_materials_transmission/transmissionFactor"))
        .and_then(Value::as_f64)
        .unwrap_or(0.0);
        if is_baked && transmission > 0.0 {
            note(
                material,
                format!(
                    "transmits light (KHR_materials_transmission, {transmission}): Bevy shows its lightmap at (1 − {transmission}) of the base colour, while the bake treats it as opaque"
                ),
                primitive_name(json, m, p),
            );
        }
        if is_baked && mat.pointer("/extensions/KHR_materials_unlit").is_some() {
            note(
                material,
                "is unlit (KHR_materials_unlit): Bevy draws its base colour alone and shows no lightmap".into(),
                primitive_name(json, m, p),
            );
        }
    }
    for ((material, reason), (first, count)) in found {
        let more = match count {
            1 => String::new(),
            n => format!(" and {} more primitive(s)", n - 1),
        };
        warnings.push(format!(
            "{} ({first}{more}) {reason}",
            material_name(json, material)
        ));
    }
    warnings
}

/// The primitive's `TEXCOORD_0` named the same accessor as its `TEXCOORD_1` in `prim`: the
/// addition [`add_texcoord_0`] makes, which a re-bake moves onto the new `TEXCOORD_1`.
pub fn shares_lightmap_uvs(prim: &Value) -> bool {
    let a = &prim["attributes"];
    a.get("TEXCOORD_0").is_some() && a.get("TEXCOORD_0") == a.get("TEXCOORD_1")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn doc() -> Value {
        json!({
            "extensionsRequired": ["KHR_materials_unlit", "KHR_draco_mesh_compression"],
            "materials": [
                {"name": "plain"},
                {"name": "tex", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                {"name": "third", "emissiveTexture": {"index": 0, "texCoord": 2}},
                {"name": "unlit", "extensions": {"KHR_materials_unlit": {}}},
                {"name": "coat", "extensions": {"KHR_materials_clearcoat": {"clearcoatTexture": {"index": 0, "texCoord": 1}}}},
                {"name": "glass", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.25}}}
            ],
            "meshes": [
                {"name": "a", "primitives": [
                    {"attributes": {"POSITION": 0, "TEXCOORD_1": 3}, "material": 0},
                    {"attributes": {"POSITION": 0, "TEXCOORD_0": 2, "TEXCOORD_1": 3}, "material": 1}
                ]},
                {"primitives": [
                    {"attributes": {"POSITION": 0, "TEXCOORD_1": 4}, "material": 1},
                    {"attributes": {"POSITION": 0, "TEXCOORD_1": 4}, "material": 1},
                    {"attributes": {"POSITION": 0}, "material": 4},
                    {"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 5, "COLOR_0": 6}, "material": 2},
                    {"attributes": {"POSITION": 0, "TEXCOORD_1": 5}, "material": 3},
                    {"attributes": {"POSITION": 0, "TEXCOORD_1": 5}, "material": 5}
                ]}
            ]
        })
    }

    #[test]
    fn texcoord_0_is_added_where_only_texcoord_1_is() {
        let mut json = doc();
        let added = add_texcoord_0(&mut json);
        assert_eq!(
            added,
            [
                "mesh 'a' primitive 0",
                "mesh 1 primitive 0",
                "mesh 1 primitive 1",
                "mesh 1 primitive 4",
                "mesh 1 primitive 5"
            ]
        );
        assert_eq!(
            json["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"],
            3
        );
        // A primitive with its own TEXCOORD_0 keeps it; one with no UVs gets none.
        assert_eq!(
            json["meshes"][0]["primitives"][1]["attributes"]["TEXCOORD_0"],
            2
        );
        assert!(
            json["meshes"][1]["primitives"][2]["attributes"]
                .get("TEXCOORD_0")
                .is_none()
        );
        assert!(shares_lightmap_uvs(&json["meshes"][1]["primitives"][4]));
        assert!(!shares_lightmap_uvs(&json["meshes"][0]["primitives"][1]));
        // Added again: nothing more.
        assert!(add_texcoord_0(&mut json).is_empty());
    }

    #[test]
    fn what_bevy_draws_otherwise_is_named_once_per_material_and_reason() {
        let json = doc();
        let baked = [(0, 0), (0, 1), (1, 0), (1, 1), (1, 3), (1, 4), (1, 5)];
        let w = drawing_warnings(&json, &baked);
        for x in &w {
            println!("{x}");
        }
        assert_eq!(w.len(), 7, "{w:#?}");
        assert!(w[0].contains("KHR_draco_mesh_compression") && w[0].contains("refuses"));
        assert!(w[1].starts_with("material 'tex' (mesh 1 primitive 0 and 1 more primitive(s))"));
        assert!(w[1].contains("baseColorTexture by TEXCOORD_0"));
        assert!(w[2].starts_with("material 'third' (mesh 1 primitive 3) has vertex colours"));
        assert!(w[3].starts_with("material 'third' (mesh 1 primitive 3)"));
        assert!(w[3].contains("emissiveTexture by TEXCOORD_2"));
        assert!(w[4].starts_with("material 'unlit' (mesh 1 primitive 4)"));
        assert!(w[5].starts_with("material 'coat' (mesh 1 primitive 2)"));
        assert!(w[5].contains("extensions.KHR_materials_clearcoat.clearcoatTexture"));
        assert!(w[5].contains("TEXCOORD_1, which the primitive does not have"));
        assert!(w[5].contains("draws the material without that texture"));
        assert!(w[6].starts_with("material 'glass' (mesh 1 primitive 5) transmits light"));
        assert!(w[6].contains("(1 − 0.25)"));
        assert!(w[1].contains("the lightmap's UVs"));
        // An unlit material or vertex colours on a primitive that is not baked say nothing.
        assert_eq!(drawing_warnings(&json, &[]).len(), 4);
    }

    #[test]
    fn texture_transform_overrides_the_set() {
        let m = json!({"normalTexture": {"index": 0, "texCoord": 0,
            "extensions": {"KHR_texture_transform": {"texCoord": 1}}},
            "extras": {"someTexture": {"index": 3}}});
        assert_eq!(material_textures(&m), [("normalTexture".to_string(), 1)]);
    }
}
