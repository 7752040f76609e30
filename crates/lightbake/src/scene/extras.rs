//! lightbake's glTF `extras`: one schema for every reader and writer. The importer and the
//! Bevy plugin read it; the scene writer and the baked-glTF export write it. Everything lives
//! under the `lightbake` key of an object's `extras`, so other tools' extras are left alone.
//!
//! | object | key | type | meaning |
//! |---|---|---|---|
//! | scene | `texel_density` | number | suggested texels per metre |
//! | scene | `sky` | `[r, g, b]` | uniform sky luminance, nits, linear RGB |
//! | scene | `irradiance_volumes` | list | written by the bake: each volume's image, centre, size, rotation, falloff and resolution |
//! | scene | `light_groups` | list | written by the bake: each light group's name, members, page images and volume images |
//! | node | `texel_density_scale` | number | density multiplier for this node's meshes |
//! | node | `bake` | bool | `false`: cast shadows and reflect, but get no lightmap |
//! | node | `lightmaps` | list | written by the bake: per primitive, its page image and `uv_rect` |
//! | light | `angular_radius` | number | sun disc radius, radians |
//! | light | `baked` | bool | written by the bake: the light's diffuse light is in the lightmaps |
//! | light | `bake` | `"full"` / `"indirect"` | bake all its light (default), or only its indirect light (it stays real-time) |
//! | light | `rect` | `[width, height]` | a spot light that is really a rectangle (Bevy's `RectLight`), m; its `intensity` is then candela on the axis, luminance × area |
//! | light | `group` | string | the light group the light bakes into ([`crate::settings::groups`]) |
//! | material | `group` | string | the light group the material's emission bakes into |
//! | scene | `sky_group` | string | the light group the sky bakes into |
//!
//! Reading is lenient per key ([`read`]): a key of the wrong type or an unknown key is
//! reported and left out, and the other keys still apply.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Deserializer, Serialize};
use serde_json::{Map, Value};

/// The key under an object's `extras` that holds lightbake's own data.
pub const KEY: &str = "lightbake";

/// A glTF scene's `extras.lightbake`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneExtras {
    /// Suggested texel density, texels per metre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texel_density: Option<f32>,
    /// Uniform sky luminance, nits, linear RGB.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky: Option<[f32; 3]>,
    /// The irradiance volumes baked for the scene (written by the bake). Malformed entries
    /// are skipped when read.
    #[serde(
        default,
        skip_serializing_if = "Vec::is_empty",
        deserialize_with = "well_formed_entries"
    )]
    pub irradiance_volumes: Vec<VolumeExtras>,
    /// The light group the sky bakes into.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sky_group: Option<String>,
    /// The light groups baked for the scene (written by the bake). Malformed entries are
    /// skipped when read.
    #[serde(
        default,
        skip_serializing_if = "Vec::is_empty",
        deserialize_with = "well_formed_entries"
    )]
    pub light_groups: Vec<GroupExtras>,
}

/// One light group's lightmaps, in a scene's `extras.lightbake.light_groups` and in
/// `manifest.json`: the group's light alone, on the same pages (and volume boxes) as the
/// scene's own lightmaps, which are the sum of every group's. An engine shows
/// `Σ weightᵢ × groupᵢ` in place of the scene's page.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupExtras {
    /// The group's name.
    pub name: String,
    /// What it holds: `light NAME`, `material NAME`, `sky`.
    pub members: Vec<String>,
    /// Per page of the scene, in page order, the group's image of it, relative to the glTF
    /// file (or the output directory, in the manifest).
    pub pages: Vec<String>,
    /// Per page, the group's BC6H image of it when the bake wrote one besides `pages`' (as
    /// [`NodeLightmap::image_bc6h`]); empty otherwise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pages_bc6h: Vec<String>,
    /// Per irradiance volume of the scene, in order, the group's volume image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub irradiance_volumes: Vec<String>,
}

/// One irradiance volume, in a scene's `extras.lightbake.irradiance_volumes` and in
/// `manifest.json`: Bevy's light probe is the unit cube centred on the origin under
/// `Transform::from_translation(center).with_rotation(rotation).with_scale(size)` (in the
/// scene's space), with `LightProbe::falloff` `falloff` and an `IrradianceVolume` whose
/// `voxels` is `image` and whose `intensity` is `intensity`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VolumeExtras {
    /// The KTX2 3D texture (`Rgba16Float`, Bevy's ambient-cube layout), relative to the
    /// glTF file (or the output directory, in the manifest).
    pub image: String,
    /// Centre of the volume's box, m.
    pub center: [f32; 3],
    /// Size of the box along its own axes, m (the light probe's scale).
    pub size: [f32; 3],
    /// The box's rotation, a unit quaternion (x, y, z, w); absent: none.
    #[serde(default = "no_rotation")]
    pub rotation: [f32; 4],
    /// `LightProbe::falloff`: per axis of the box, the fraction of its size over which the
    /// volume fades out towards its faces, where it overlaps a neighbour; absent: 0.
    #[serde(default)]
    pub falloff: [f32; 3],
    /// Probes along x, y, z.
    pub resolution: [u32; 3],
    /// `IrradianceVolume::intensity`: 1, since the voxels hold E/π like the lightmaps (the
    /// light from each side without the lights' direct light).
    pub intensity: f32,
}

fn no_rotation() -> [f32; 4] {
    [0.0, 0.0, 0.0, 1.0]
}

/// A glTF node's `extras.lightbake`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeExtras {
    /// Multiplier of the texel density for this node's meshes (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub texel_density_scale: Option<f32>,
    /// `Some(false)`: the node's meshes cast shadows and reflect light but get no lightmap.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bake: Option<bool>,
    /// The lightmap of each baked primitive (written by the bake). Malformed entries are
    /// skipped when read.
    #[serde(
        default,
        skip_serializing_if = "Vec::is_empty",
        deserialize_with = "well_formed_entries"
    )]
    pub lightmaps: Vec<NodeLightmap>,
}

/// One primitive's lightmap in a node's `extras.lightbake.lightmaps`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeLightmap {
    /// Primitive index within the node's mesh.
    pub primitive: usize,
    /// Atlas page.
    pub page: u32,
    /// The page image, relative to the glTF file.
    pub image: String,
    /// The same page as BC6H blocks (`lightmaps/lightmap_N.bc6h.ktx2`), when the bake wrote
    /// one besides `image` (`--format ...,ktx2-bc6h`): an engine whose GPU samples BC
    /// textures may load it instead, at an eighth of the memory. Absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_bc6h: Option<String>,
    /// Bevy's `Lightmap::uv_rect`: [min u, min v, max u, max v] on the page.
    pub uv_rect: [f32; 4],
}

/// A `KHR_lights_punctual` light's `extras.lightbake`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightExtras {
    /// Angular radius of a directional light's disc, radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angular_radius: Option<f32>,
    /// The light's diffuse light is in the lightmaps (written by the bake), so an engine
    /// should stop it lighting lightmapped surfaces a second time.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub baked: bool,
    /// `"indirect"`: bake only the light's indirect light ([`super::LightBake::IndirectOnly`]);
    /// `"full"` (or absent): all of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bake: Option<LightBakeExtras>,
    /// A rectangle of this width × height (m) in the node's XY plane, facing −Z: the light is
    /// a rect light, its spot entry the far-field stand-in for readers without lightbake.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rect: Option<[f32; 2]>,
    /// The light group the light bakes into.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

/// A material's `extras.lightbake`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialExtras {
    /// The light group the material's emission bakes into.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

/// The values of a light's `extras.lightbake.bake`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightBakeExtras {
    /// All of the light.
    Full,
    /// Its indirect light only.
    Indirect,
}

/// Deserialises a list, keeping the entries that parse.
fn well_formed_entries<'de, D, T>(deserializer: D) -> Result<Vec<T>, D::Error>
where
    D: Deserializer<'de>,
    T: DeserializeOwned,
{
    let values = Vec::<Value>::deserialize(deserializer)?;
    Ok(values
        .into_iter()
        .filter_map(|v| serde_json::from_value(v).ok())
        .collect())
}

/// Reads `extras.lightbake` from an object's whole `extras` JSON text (`None` when the object
/// has none). Keys that do not fit the schema are reported in `warnings` as
/// "`place` extras.lightbake.KEY ignored: WHY" and left at their defaults; the rest apply.
pub fn read<T: DeserializeOwned + Default>(
    extras: Option<&str>,
    place: &str,
    warnings: &mut Vec<String>,
) -> T {
    let Some(text) = extras else {
        return T::default();
    };
    let Ok(value) = serde_json::from_str::<Value>(text) else {
        warnings.push(format!("{place}: extras are not valid JSON; ignored"));
        return T::default();
    };
    read_value(value.get(KEY), place, warnings)
}

/// [`read`] from the `extras.lightbake` value itself.
pub fn read_value<T: DeserializeOwned + Default>(
    value: Option<&Value>,
    place: &str,
    warnings: &mut Vec<String>,
) -> T {
    let Some(value) = value else {
        return T::default();
    };
    let Some(object) = value.as_object() else {
        warnings.push(format!("{place}: extras.{KEY} is not an object; ignored"));
        return T::default();
    };
    if let Ok(parsed) = serde_json::from_value(value.clone()) {
        return parsed;
    }
    // Some key does not fit: keep the keys that do, one at a time.
    let mut kept = Map::new();
    for (key, v) in object {
        let mut trial = kept.clone();
        trial.insert(key.clone(), v.clone());
        match serde_json::from_value::<T>(Value::Object(trial)) {
            Ok(_) => {
                kept.insert(key.clone(), v.clone());
            }
            Err(e) => warnings.push(format!("{place}: extras.{KEY}.{key} ignored: {e}")),
        }
    }
    serde_json::from_value(Value::Object(kept)).unwrap_or_default()
}

/// Sets `extras.lightbake` of a glTF object (a JSON object) to `data`, keeping its other
/// extras; an empty `data` removes the key (and an `extras` left empty).
pub fn write<T: Serialize>(object: &mut Value, data: &T) {
    let value = serde_json::to_value(data).expect("the extras schema serialises");
    let empty = value.as_object().is_some_and(Map::is_empty);
    let Some(object) = object.as_object_mut() else {
        return;
    };
    if empty {
        if let Some(extras) = object.get_mut("extras").and_then(Value::as_object_mut) {
            extras.remove(KEY);
            if extras.is_empty() {
                object.remove("extras");
            }
        }
        return;
    }
    let extras = object
        .entry("extras")
        .or_insert_with(|| Value::Object(Map::new()));
    if !extras.is_object() {
        *extras = Value::Object(Map::new());
    }
    extras
        .as_object_mut()
        .expect("an object")
        .insert(KEY.into(), value);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_keys_are_reported_and_the_rest_kept() {
        let mut warnings = Vec::new();
        let s: SceneExtras = read(
            Some(
                r#"{"other": 1, "lightbake": {"texel_density": 64, "sky": [1, 2], "texel_densty": 3}}"#,
            ),
            "scene",
            &mut warnings,
        );
        assert_eq!(s.texel_density, Some(64.0));
        assert_eq!(s.sky, None);
        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(
            warnings[0].contains("extras.lightbake.sky ignored"),
            "{warnings:?}"
        );
        assert!(warnings[1].contains("texel_densty"), "{warnings:?}");
        let mut none = Vec::new();
        assert_eq!(
            read::<NodeExtras>(None, "node", &mut none),
            NodeExtras::default()
        );
        assert!(none.is_empty());
    }

    #[test]
    fn malformed_lightmap_entries_are_skipped() {
        let mut warnings = Vec::new();
        let n: NodeExtras = read(
            Some(
                r#"{"lightbake": {"lightmaps": [
                {"primitive": 1, "page": 0, "image": "lightmaps/lightmap_0.exr", "uv_rect": [0.0, 0.5, 0.25, 1.0]},
                {"primitive": "bad"}]}}"#,
            ),
            "node",
            &mut warnings,
        );
        assert!(warnings.is_empty());
        assert_eq!(n.lightmaps.len(), 1);
        assert_eq!(n.lightmaps[0].uv_rect, [0.0, 0.5, 0.25, 1.0]);
    }

    #[test]
    fn writing_keeps_other_extras_and_round_trips() {
        let mut node = serde_json::json!({ "name": "n", "extras": { "other": true } });
        let data = NodeExtras {
            texel_density_scale: Some(0.5),
            ..NodeExtras::default()
        };
        write(&mut node, &data);
        assert_eq!(node["extras"]["other"], Value::Bool(true));
        let text = node["extras"].to_string();
        let back: NodeExtras = read(Some(&text), "node", &mut Vec::new());
        assert_eq!(back, data);
        write(&mut node, &NodeExtras::default());
        assert_eq!(node["extras"], serde_json::json!({ "other": true }));
        let mut bare = serde_json::json!({});
        write(&mut bare, &LightExtras::default());
        assert_eq!(bare, serde_json::json!({}));
    }
}
