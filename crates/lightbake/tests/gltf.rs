//! glTF in and out: a round trip keeps the scene and adds TEXCOORD_1 (as .gltf and .glb, with
//! textures); bad input gives errors that name the file, buffer, mesh, vertex, triangle or
//! node; repairs (missing normals, inverted normals) are reported as warnings.

mod common;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use lightbake::BakeError;
use lightbake::output::write_outputs;
use lightbake::progress::Progress;
use lightbake::scene::gltf_import::{ImportedScene, import_gltf};
use lightbake::scene::gltf_write::{scene_to_glb, write_scene_gltf};
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::scene::{Scene, Texture, TextureRef};
use lightbake::settings::{BakeSettings, LightConvention};
use serde_json::Value;

fn import(path: &Path) -> Result<ImportedScene, BakeError> {
    import_gltf(path, LightConvention::GltfSpec)
}

fn write_cornell(dir: &Path, light: CornellLight) -> PathBuf {
    let path = dir.join("cornell_box.gltf");
    write_scene_gltf(&cornell_box(light), &path).unwrap();
    path
}

fn fast_settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(64.0);
    s.layout.texel_density_from_scene = false;
    s
}

/// World positions of every triangle of every instance, in order.
fn world_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for inst in &scene.instances {
        let m = &scene.meshes[inst.mesh];
        for t in 0..m.triangle_count() {
            out.push(
                m.triangle(t)
                    .map(|i| inst.transform.transform_point3(m.positions[i])),
            );
        }
    }
    out
}

fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.instances.len(), b.instances.len());
    assert_eq!(a.materials.len(), b.materials.len());
    assert_eq!(a.lights.len(), b.lights.len());
    for (x, y) in world_triangles(a).iter().zip(world_triangles(b).iter()) {
        for k in 0..3 {
            assert!((x[k] - y[k]).length() < 1e-6, "{x:?} vs {y:?}");
        }
    }
    assert_eq!(world_triangles(a).len(), world_triangles(b).len());
    for (x, y) in a.materials.iter().zip(&b.materials) {
        assert_eq!(x.name, y.name);
        assert!((x.base_color - y.base_color).abs().max_element() < 1e-6);
        assert!(
            (x.emissive - y.emissive).abs().max_element()
                < 1e-3 * x.emissive.max_element().max(1.0)
        );
    }
    for (x, y) in a.lights.iter().zip(&b.lights) {
        assert_eq!(x.kind, y.kind);
        assert!(
            (x.intensity - y.intensity).abs() < 1e-4 && (x.position - y.position).length() < 1e-5
        );
        assert!((x.direction - y.direction).length() < 1e-5);
    }
    assert_eq!(a.texel_density_hint, b.texel_density_hint);
}

#[test]
fn gltf_round_trip_keeps_the_scene_and_adds_texcoord1() {
    let dir = tempfile::tempdir().unwrap();
    for light in [CornellLight::Area, CornellLight::Point] {
        let path = write_cornell(dir.path(), light);
        let imported = import(&path).unwrap();
        assert_same_scene(&cornell_box(light), &imported.scene);
        assert!(
            imported.scene.warnings.is_empty(),
            "{:?}",
            imported.scene.warnings
        );

        let settings = fast_settings();
        let out = lightbake::bake(&imported.scene, &settings, &Progress::new()).unwrap();
        let out_dir = dir.path().join(format!("baked_{light:?}"));
        write_outputs(
            &out_dir,
            &out,
            &imported.scene,
            Some(&imported.source),
            &settings,
        )
        .unwrap();
        let baked = import(&out_dir.join("cornell_box.gltf")).unwrap();
        assert_same_scene(&imported.scene, &baked.scene);
        let json: Value =
            serde_json::from_slice(&std::fs::read(out_dir.join("cornell_box.gltf")).unwrap())
                .unwrap();
        let manifest: Value =
            serde_json::from_slice(&std::fs::read(out_dir.join("manifest.json")).unwrap()).unwrap();
        for (i, inst) in baked.scene.instances.iter().enumerate() {
            let mesh = &baked.scene.meshes[inst.mesh];
            let uv1 = mesh
                .uv1
                .as_ref()
                .unwrap_or_else(|| panic!("{} has no TEXCOORD_1", mesh.name));
            assert!(
                uv1.iter()
                    .all(|p| p.min_element() >= 0.0 && p.max_element() <= 1.0)
            );
            // The node's extras and the manifest point at the same page and rectangle.
            let node = inst.gltf_node.unwrap();
            let extras = &json["nodes"][node]["extras"]["lightbake"]["lightmaps"][0];
            let entry = &manifest["instances"][i];
            for k in 0..4 {
                let (a, b) = (
                    extras["uv_rect"][k].as_f64().unwrap(),
                    entry["uv_rect"][k].as_f64().unwrap(),
                );
                assert!((a - b).abs() < 1e-6, "{a} vs {b}");
            }
            assert_eq!(extras["image"], entry["image"]);
            assert!(out_dir.join(entry["image"].as_str().unwrap()).exists());
        }
        // Every punctual light is flagged as baked; the area-light box has none.
        let lights = json
            .pointer("/extensions/KHR_lights_punctual/lights")
            .and_then(Value::as_array);
        assert_eq!(lights.map_or(0, Vec::len), imported.scene.lights.len());
        for l in lights.into_iter().flatten() {
            assert_eq!(l["extras"]["lightbake"]["baked"], Value::Bool(true), "{l}");
        }
        // Baking the baked file keeps the UVs it now has.
        let plan = lightbake::plan::BakePlan::new(&baked.scene, &settings);
        assert_eq!(plan.meshes_to_unwrap, 0);
        assert_eq!(plan.meshes_keeping_uv1, baked.scene.meshes.len());
    }
}

#[test]
fn glb_with_textures_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = cornell_box(CornellLight::Point);
    // A 2×2 checker on the floor.
    scene.textures.push(Texture {
        name: "checker".into(),
        width: 2,
        height: 2,
        rgba8: vec![
            [255, 255, 255, 255],
            [40, 40, 40, 255],
            [40, 40, 40, 255],
            [255, 255, 255, 255],
        ],
        wrap_u: Default::default(),
        wrap_v: Default::default(),
    });
    scene.materials[0].base_color_texture = Some(TextureRef {
        texture: 0,
        tex_coord: 0,
    });
    let path = dir.path().join("textured.glb");
    std::fs::write(&path, scene_to_glb(&scene)).unwrap();
    let imported = import(&path).unwrap();
    assert!(imported.source.is_glb);
    assert_eq!(imported.scene.textures.len(), 1);
    assert_eq!(imported.scene.textures[0].rgba8, scene.textures[0].rgba8);
    assert_same_scene(&scene, &imported.scene);

    let settings = fast_settings();
    let out = lightbake::bake(&imported.scene, &settings, &Progress::new()).unwrap();
    let out_dir = dir.path().join("out");
    write_outputs(
        &out_dir,
        &out,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    let baked = import(&out_dir.join("textured.glb")).unwrap();
    assert_same_scene(&imported.scene, &baked.scene);
    assert_eq!(baked.scene.textures[0].rgba8, scene.textures[0].rgba8);
    assert!(baked.scene.meshes.iter().all(|m| m.uv1.is_some()));
    // UV0 follows the vertices through the seam split.
    for (a, b) in imported.scene.meshes.iter().zip(&baked.scene.meshes) {
        for t in 0..a.triangle_count() {
            let (ta, tb) = (a.triangle(t), b.triangle(t));
            for k in 0..3 {
                let (ua, ub): (Vec2, Vec2) = (
                    a.uv0.as_ref().unwrap()[ta[k]],
                    b.uv0.as_ref().unwrap()[tb[k]],
                );
                assert_eq!(ua, ub);
            }
        }
    }
}

#[test]
fn external_images_are_copied_next_to_the_baked_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_cornell(dir.path(), CornellLight::Point);
    let mut json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    image::RgbaImage::from_pixel(4, 4, image::Rgba([200, 100, 50, 255]))
        .save(dir.path().join("wall paint.png"))
        .unwrap();
    json["images"] = serde_json::json!([{ "uri": "wall%20paint.png" }]);
    json["textures"] = serde_json::json!([{ "source": 0 }]);
    json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
        serde_json::json!({ "index": 0 });
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let imported = import(&path).unwrap();
    assert_eq!(imported.scene.textures.len(), 1);
    let settings = fast_settings();
    let out = lightbake::bake(&imported.scene, &settings, &Progress::new()).unwrap();
    let out_dir = dir.path().join("out");
    write_outputs(
        &out_dir,
        &out,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    assert!(out_dir.join("wall paint.png").exists());
    let baked = import(&out_dir.join("cornell_box.gltf")).unwrap();
    assert_eq!(baked.scene.textures.len(), 1);
}

/// Edits a written glTF: a closure on the JSON and one on the binary buffer.
fn corrupt(
    dir: &Path,
    edit_json: impl FnOnce(&mut Value),
    edit_bin: impl FnOnce(&Value, &mut Vec<u8>),
) -> PathBuf {
    let path = write_cornell(dir, CornellLight::Point);
    let bin_path = dir.join("cornell_box.bin");
    let mut json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let mut bin = std::fs::read(&bin_path).unwrap();
    edit_json(&mut json);
    edit_bin(&json, &mut bin);
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    std::fs::write(&bin_path, bin).unwrap();
    path
}

/// Byte offset of element `i` of accessor `a` in the (single) buffer.
fn element_offset(json: &Value, a: u64, i: usize, size: usize) -> usize {
    let acc = &json["accessors"][a as usize];
    let view = &json["bufferViews"][acc["bufferView"].as_u64().unwrap() as usize];
    view["byteOffset"].as_u64().unwrap_or(0) as usize
        + acc["byteOffset"].as_u64().unwrap_or(0) as usize
        + i * size
}

fn error_of(path: &Path) -> String {
    match import(path) {
        Ok(_) => panic!("{} imported without error", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_inputs_give_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    let msg = error_of(&d.join("missing.gltf"));
    assert!(
        msg.contains("missing.gltf") && msg.contains("cannot read"),
        "{msg}"
    );

    let bad = d.join("bad.gltf");
    std::fs::write(&bad, b"{ this is not json").unwrap();
    let msg = error_of(&bad);
    assert!(
        msg.contains("bad.gltf") && msg.contains("not a valid glTF"),
        "{msg}"
    );

    let path = write_cornell(d, CornellLight::Point);
    std::fs::remove_file(d.join("cornell_box.bin")).unwrap();
    let msg = error_of(&path);
    assert!(
        msg.contains("buffer 0") && msg.contains("cornell_box.bin"),
        "{msg}"
    );

    let short = corrupt(d, |_| {}, |_, bin| bin.truncate(100));
    let msg = error_of(&short);
    assert!(
        msg.contains("buffer 0") && msg.contains("declares"),
        "{msg}"
    );

    let wrong_type = corrupt(
        d,
        |j| {
            let a = j["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            j["accessors"][a]["componentType"] = serde_json::json!(5123); // UNSIGNED_SHORT
        },
        |_, _| {},
    );
    let msg = error_of(&wrong_type);
    assert!(msg.contains("POSITION") && msg.contains("floor"), "{msg}");

    let nan = corrupt(
        d,
        |_| {},
        |j, bin| {
            let a = j["meshes"][1]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap();
            let o = element_offset(j, a, 2, 12);
            bin[o + 4..o + 8].copy_from_slice(&f32::NAN.to_le_bytes());
        },
    );
    let msg = error_of(&nan);
    assert!(
        msg.contains("ceiling") && msg.contains("vertex 2") && msg.contains("position"),
        "{msg}"
    );

    let inf = corrupt(
        d,
        |_| {},
        |j, bin| {
            let a = j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]
                .as_u64()
                .unwrap();
            let o = element_offset(j, a, 1, 12);
            bin[o..o + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        },
    );
    let msg = error_of(&inf);
    assert!(
        msg.contains("floor") && msg.contains("normal") && msg.contains("vertex 1"),
        "{msg}"
    );

    let out_of_range = corrupt(
        d,
        |_| {},
        |j, bin| {
            let a = j["meshes"][2]["primitives"][0]["indices"].as_u64().unwrap();
            let o = element_offset(j, a, 4, 2);
            bin[o..o + 2].copy_from_slice(&999u16.to_le_bytes());
        },
    );
    let msg = error_of(&out_of_range);
    assert!(
        msg.contains("back_wall") && msg.contains("triangle 1") && msg.contains("999"),
        "{msg}"
    );

    let zero_scale = corrupt(
        d,
        |j| j["nodes"][3]["scale"] = serde_json::json!([0.0, 0.0, 0.0]),
        |_, _| {},
    );
    let msg = error_of(&zero_scale);
    assert!(
        msg.contains("green_wall") && msg.contains("zero scale"),
        "{msg}"
    );

    let far = corrupt(
        d,
        |j| j["nodes"][2]["translation"] = serde_json::json!([0.0, 3e9, 0.0]),
        |_, _| {},
    );
    let msg = error_of(&far);
    assert!(
        msg.contains("back_wall") && msg.contains("beyond 1e9 m"),
        "{msg}"
    );

    let only_light = corrupt(
        d,
        |j| {
            let light_node = j["nodes"].as_array().unwrap().len() - 1;
            j["scenes"][0]["nodes"] = serde_json::json!([light_node]);
        },
        |_, _| {},
    );
    let msg = error_of(&only_light);
    assert!(msg.contains("no triangles"), "{msg}");
}

#[test]
fn repairs_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let no_normals = corrupt(
        d,
        |j| {
            j["meshes"][0]["primitives"][0]["attributes"]
                .as_object_mut()
                .unwrap()
                .remove("NORMAL");
        },
        |_, _| {},
    );
    let s = import(&no_normals).unwrap().scene;
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("floor") && w.contains("no NORMAL")),
        "{:?}",
        s.warnings
    );
    // The computed normals face up (the floor's winding).
    assert!(s.meshes[0].normals.iter().all(|n| (n.y - 1.0).abs() < 1e-5));

    let inverted = corrupt(
        d,
        |_| {},
        |j, bin| {
            let a = j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]
                .as_u64()
                .unwrap();
            for v in 0..4 {
                let o = element_offset(j, a, v, 12);
                for k in 0..3 {
                    let x = f32::from_le_bytes(bin[o + 4 * k..o + 4 * k + 4].try_into().unwrap());
                    bin[o + 4 * k..o + 4 * k + 4].copy_from_slice(&(-x).to_le_bytes());
                }
            }
        },
    );
    let imported = import(&inverted).unwrap();
    assert!(
        imported
            .scene
            .warnings
            .iter()
            .any(|w| w.contains("floor") && w.contains("against their winding")),
        "{:?}",
        imported.scene.warnings
    );
    // The floor is still lit from above: it is baked on its front (winding) side.
    let out = lightbake::bake(&imported.scene, &fast_settings(), &Progress::new()).unwrap();
    let floor = common::texels(&out, 0);
    let lit = floor.iter().filter(|t| t.value.max_element() > 0.0).count();
    assert!(lit > floor.len() / 2, "{lit} of {}", floor.len());
}

#[test]
fn light_conventions_differ_where_bevy_departs_from_the_spec() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_cornell(dir.path(), CornellLight::Point);
    let mut json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    json["extensions"]["KHR_lights_punctual"]["lights"][0]["color"] =
        serde_json::json!([0.5, 0.5, 0.5]);
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();

    let spec = import_gltf(&path, LightConvention::GltfSpec).unwrap().scene;
    assert_eq!(spec.lights[0].color, Vec3::splat(0.5));
    assert_eq!(spec.lights[0].range, None);

    let bevy = import_gltf(&path, LightConvention::BevyGltfLoader)
        .unwrap()
        .scene;
    // sRGB 0.5 decodes to 0.2140 linear; no range means 20 m in Bevy's loader.
    assert!((bevy.lights[0].color.x - 0.214_041).abs() < 1e-5);
    assert_eq!(bevy.lights[0].range, Some(20.0));
    assert_eq!(spec.lights[0].intensity, bevy.lights[0].intensity);
}

/// A rebake into the same folder removes the page and volume files the earlier bake wrote
/// and this one does not (a format, the volume and a light group dropped), and nothing else:
/// not the files it writes again, not a file of the developer's beside them, and not a file
/// outside the bake's page and volume folders that a crafted `report.json` names.
#[test]
fn a_rebake_removes_the_earlier_bakes_stale_files_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_cornell(dir.path(), CornellLight::Point);
    let imported = import(&path).unwrap();
    let out_dir = dir.path().join("out");
    let bake_into = |settings: &BakeSettings| {
        let out = lightbake::bake(&imported.scene, settings, &Progress::new()).unwrap();
        write_outputs(
            &out_dir,
            &out,
            &imported.scene,
            Some(&imported.source),
            settings,
        )
        .unwrap()
    };
    let mut first = fast_settings();
    first.formats.hdr = true;
    first.volume.enabled = true;
    first.groups = vec![lightbake::settings::LightGroup {
        name: "lamp".into(),
        members: vec!["ceiling_point".into()],
    }];
    let written = bake_into(&first);
    assert!(written.removed.is_empty());
    let mut stale = vec![
        "lightmaps/lightmap_0.hdr",
        "lightmaps/groups/lamp/lightmap_0.exr",
        "lightmaps/groups/lamp/lightmap_0.hdr",
        "irradiance_volumes/volume_0.ktx2",
        "irradiance_volumes/groups/lamp/volume_0.ktx2",
    ];
    if first.formats.png_preview {
        stale.push("lightmaps/groups/lamp/lightmap_0.preview.png");
    }
    stale.sort();
    for &f in &stale {
        assert!(out_dir.join(f).is_file(), "{f} written");
    }
    // The developer's own files in the bake's folders.
    let own = ["lightmaps/lightmap_7.exr", "lightmaps/notes.txt"];
    for f in own {
        std::fs::write(out_dir.join(f), b"mine").unwrap();
    }

    let second = fast_settings();
    let written = bake_into(&second);
    let mut removed: Vec<String> = (written.removed.iter())
        .map(|p| {
            let rel = p.strip_prefix(&out_dir).unwrap();
            rel.to_string_lossy().replace('\\', "/")
        })
        .collect();
    removed.sort();
    assert_eq!(removed, stale);
    for &f in &stale {
        assert!(!out_dir.join(f).exists(), "{f} removed");
    }
    assert!(!out_dir.join("lightmaps/groups").exists());
    assert!(!out_dir.join("irradiance_volumes").exists());
    assert!(out_dir.join("lightmaps/lightmap_0.exr").is_file());
    for f in own {
        assert_eq!(std::fs::read(out_dir.join(f)).unwrap(), b"mine");
    }

    // A report that names files outside the page and volume folders, or leaves them.
    let outside = dir.path().join("outside");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::write(outside.join("lightmap_0.exr"), b"theirs").unwrap();
    let crafted = serde_json::json!({ "outputs": [
        "../outside/lightmap_0.exr",
        "lightmaps/../../outside/lightmap_0.exr",
        outside.join("lightmap_0.exr").to_string_lossy(),
        "lightmaps/notes.txt",
        "cornell_box.gltf.bak",
    ]});
    std::fs::write(out_dir.join("report.json"), crafted.to_string()).unwrap();
    std::fs::write(out_dir.join("cornell_box.gltf.bak"), b"mine").unwrap();
    let written = bake_into(&second);
    assert!(written.removed.is_empty(), "{:?}", written.removed);
    // Nor one that a linked folder inside leads to.
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&outside, out_dir.join("irradiance_volumes")).unwrap();
        std::fs::write(outside.join("volume_0.ktx2"), b"theirs").unwrap();
        let crafted = serde_json::json!({ "outputs": ["irradiance_volumes/volume_0.ktx2"] });
        std::fs::write(out_dir.join("report.json"), crafted.to_string()).unwrap();
        let written = bake_into(&second);
        assert!(written.removed.is_empty(), "{:?}", written.removed);
        assert_eq!(
            std::fs::read(outside.join("volume_0.ktx2")).unwrap(),
            b"theirs"
        );
    }
    assert_eq!(
        std::fs::read(outside.join("lightmap_0.exr")).unwrap(),
        b"theirs"
    );
    assert!(out_dir.join("lightmaps/notes.txt").is_file());
    assert!(out_dir.join("cornell_box.gltf.bak").is_file());
}

/// The accessor index of `semantic` on every primitive of `json` that has one.
fn attribute_of(json: &Value, semantic: &str) -> Vec<Option<u64>> {
    let mut out = Vec::new();
    for mesh in json["meshes"].as_array().unwrap() {
        for prim in mesh["primitives"].as_array().unwrap() {
            out.push(prim["attributes"][semantic].as_u64());
        }
    }
    out
}

#[test]
fn primitives_without_texcoord_0_get_their_lightmap_uvs_as_one() {
    // An OpenArena level: positions and normals only. Bevy's StandardMaterial shader does not
    // compile for a mesh with UV_1 and no UV_0.
    let dir = tempfile::tempdir().unwrap();
    let source =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus/openarena/q3dm6ish.gltf");
    let imported = import(&source).unwrap();
    let mut settings = BakeSettings::preview();
    settings.layout.texel_budget = 20_000;
    let out = lightbake::bake(&imported.scene, &settings, &Progress::new()).unwrap();
    let first = dir.path().join("first");
    let written = write_outputs(
        &first,
        &out,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    let json: Value =
        serde_json::from_slice(&std::fs::read(first.join("q3dm6ish.gltf")).unwrap()).unwrap();
    let (uv0, uv1) = (
        attribute_of(&json, "TEXCOORD_0"),
        attribute_of(&json, "TEXCOORD_1"),
    );
    assert!(uv1.iter().all(Option::is_some));
    assert_eq!(
        uv0, uv1,
        "TEXCOORD_0 names the TEXCOORD_1 accessor (no bytes of its own)"
    );
    assert_eq!(written.texcoord_0_added.len(), uv1.len());
    assert!(
        written.texcoord_0_added[0].starts_with("mesh '"),
        "{:?}",
        written.texcoord_0_added
    );
    let report: Value =
        serde_json::from_slice(&std::fs::read(first.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["texcoord_0_added"].as_array().unwrap().len(),
        uv1.len()
    );

    // Baked again with new lightmap UVs: TEXCOORD_0 follows the new TEXCOORD_1.
    let baked = import(&first.join("q3dm6ish.gltf")).unwrap();
    settings.layout.reunwrap = true;
    let again = lightbake::bake(&baked.scene, &settings, &Progress::new()).unwrap();
    let second = dir.path().join("second");
    write_outputs(
        &second,
        &again,
        &baked.scene,
        Some(&baked.source),
        &settings,
    )
    .unwrap();
    let json2: Value =
        serde_json::from_slice(&std::fs::read(second.join("q3dm6ish.gltf")).unwrap()).unwrap();
    let (uv0, uv1) = (
        attribute_of(&json2, "TEXCOORD_0"),
        attribute_of(&json2, "TEXCOORD_1"),
    );
    assert_eq!(uv0, uv1);

    // A primitive with its own TEXCOORD_0 (the shipped Cornell box) keeps it.
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/cornell_box.gltf");
    let imported = import(&cornell).unwrap();
    let settings = fast_settings();
    let out = lightbake::bake(&imported.scene, &settings, &Progress::new()).unwrap();
    let third = dir.path().join("third");
    let written = write_outputs(
        &third,
        &out,
        &imported.scene,
        Some(&imported.source),
        &settings,
    )
    .unwrap();
    assert!(written.texcoord_0_added.is_empty());
    let json3: Value =
        serde_json::from_slice(&std::fs::read(third.join("cornell_box.gltf")).unwrap()).unwrap();
    for (a, b) in attribute_of(&json3, "TEXCOORD_0")
        .iter()
        .zip(attribute_of(&json3, "TEXCOORD_1"))
    {
        assert!(a.is_some() && *a != b);
    }
}
