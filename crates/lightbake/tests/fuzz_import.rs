//! Property-based fuzzing of the glTF importer and the scene validation (proptest): a valid
//! Cornell box glTF with random edits to its JSON (numbers set to edge values, keys removed,
//! strings replaced) or random bytes of its buffer overwritten must import to a scene or to an
//! error, never panic; an imported scene must then prepare (unwrap, texel patches, BVH) or be
//! refused with an error.
//!
//! Bounded for CI: 500 cases per property from a fixed seed (a few seconds); set
//! `PROPTEST_CASES` and `PROPTEST_RNG_SEED=random` for a longer search.

mod common;

use std::path::Path;

use lightbake::context::Prepared;
use lightbake::scene::gltf_import::import_gltf;
use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::{BakeSettings, LightConvention};
use proptest::prelude::*;
use serde_json::Value;

/// What one fuzz case does to the JSON.
#[derive(Clone, Debug)]
enum Edit {
    /// Sets the `k`-th number (in document order, modulo their count) to a value.
    Number(usize, f64),
    /// Removes the `k`-th object key.
    Remove(usize),
    /// Replaces the `k`-th string with another.
    Text(usize, String),
}

fn edit() -> impl Strategy<Value = Edit> {
    let numbers = prop_oneof![
        Just(0.0),
        Just(-1.0),
        Just(1.0),
        Just(3.0),
        Just(5121.0),
        Just(5123.0),
        Just(5125.0),
        Just(5126.0),
        Just(4_294_967_295.0),
        Just(1e30),
        Just(-1e30),
        Just(1e-30),
        any::<i32>().prop_map(f64::from),
        any::<f32>()
            .prop_filter("JSON numbers are finite", |x| x.is_finite())
            .prop_map(f64::from),
    ];
    prop_oneof![
        (any::<usize>(), numbers).prop_map(|(k, v)| Edit::Number(k, v)),
        any::<usize>().prop_map(Edit::Remove),
        (any::<usize>(), "[A-Za-z0-9_./]{0,12}").prop_map(|(k, s)| Edit::Text(k, s)),
    ]
}

/// Visits every value of the document in order.
fn visit(v: &mut Value, f: &mut dyn FnMut(&mut Value)) {
    f(v);
    match v {
        Value::Array(a) => a.iter_mut().for_each(|x| visit(x, f)),
        Value::Object(o) => o.values_mut().for_each(|x| visit(x, f)),
        _ => {}
    }
}

/// Calls `f` once, on the `k`-th value (in document order, modulo their count) that `pred`
/// accepts.
fn edit_nth(json: &mut Value, k: usize, pred: impl Fn(&Value) -> bool, f: impl FnOnce(&mut Value)) {
    let mut n = 0;
    visit(json, &mut |v| n += pred(v) as usize);
    let (mut i, target, mut f) = (0, k % n.max(1), Some(f));
    visit(json, &mut |v| {
        if pred(v) {
            if i == target
                && let Some(f) = f.take()
            {
                f(v);
            }
            i += 1;
        }
    });
}

fn apply(json: &mut Value, e: &Edit) {
    match e {
        Edit::Number(k, x) => edit_nth(json, *k, Value::is_number, |v| {
            *v = serde_json::Number::from_f64(*x).map_or(Value::Null, Value::Number);
        }),
        Edit::Remove(k) => edit_nth(
            json,
            *k,
            |v| v.as_object().is_some_and(|o| !o.is_empty()),
            |v| {
                if let Value::Object(o) = v {
                    let key = o.keys().nth(k % o.len()).cloned().unwrap();
                    o.remove(&key);
                }
            },
        ),
        Edit::Text(k, s) => edit_nth(json, *k, Value::is_string, |v| {
            *v = Value::String(s.clone());
        }),
    }
}

fn settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(8.0);
    s.layout.texel_density_from_scene = false;
    s.memory_budget_mib = 256;
    s
}

/// Imports `path`; if that works, validates and prepares the scene. Any panic fails the case.
fn import_and_prepare(path: &Path) {
    if let Ok(imported) = import_gltf(path, LightConvention::GltfSpec)
        && imported.scene.validate().is_ok()
    {
        let _ = Prepared::new(&imported.scene, &settings());
    }
}

fn written(dir: &Path) -> (Value, Vec<u8>) {
    let path = dir.join("cornell_box.gltf");
    write_scene_gltf(&cornell_box(CornellLight::Point), &path).unwrap();
    (
        serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap(),
        std::fs::read(dir.join("cornell_box.bin")).unwrap(),
    )
}

proptest! {
    #![proptest_config(common::proptest_config(0x0011_bace))]

    #[test]
    fn edited_json_imports_or_errors(edits in prop::collection::vec(edit(), 1..4)) {
        let dir = tempfile::tempdir().unwrap();
        let (mut json, _) = written(dir.path());
        for e in &edits {
            apply(&mut json, e);
        }
        let path = dir.path().join("cornell_box.gltf");
        std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
        import_and_prepare(&path);
    }

    #[test]
    fn overwritten_buffer_bytes_import_or_error(
        writes in prop::collection::vec((any::<usize>(), any::<[u8; 4]>()), 1..12)
    ) {
        let dir = tempfile::tempdir().unwrap();
        let (_, mut bin) = written(dir.path());
        let len = bin.len() - 3;
        for (at, bytes) in &writes {
            let at = at % len;
            bin[at..at + 4].copy_from_slice(bytes);
        }
        std::fs::write(dir.path().join("cornell_box.bin"), &bin).unwrap();
        import_and_prepare(&dir.path().join("cornell_box.gltf"));
    }
}
