//! What changed between the bake a cache holds and the scene about to be baked: instances
//! moved, added, removed or given other geometry; surfaces that reflect or emit otherwise;
//! lights moved, added, removed or changed in intensity, colour, range or cone; the sky. Or
//! why the edit cannot be followed and the bake is full.

use glam::Vec3;

use super::BakeCache;
use crate::scene::hashes::{InstanceHashes, SceneHashes};
use crate::scene::{Light, Scene};
use crate::settings::BakeSettings;
use crate::stage::Input;

/// A world box: (min, max).
pub type Aabb = (Vec3, Vec3);

/// An emitting surface's world box and the largest luminance it emits, nits (luminance of
/// the emission's RGB).
pub type Emitter = (Aabb, f32);

/// The changes between a cached bake and the scene being baked, as the passes see them.
#[derive(Clone, Debug, Default)]
pub struct Edits {
    /// Each change, one line each, for the plan and the report.
    pub lines: Vec<String>,
    /// Each light that changed: as it was (none when added) and as it is (none when removed).
    pub lights: Vec<(Option<Light>, Option<Light>)>,
    /// The world boxes of geometry that moved, changed, came or went: each instance's before
    /// and after.
    pub boxes: Vec<Aabb>,
    /// Emitting surfaces whose light changed (before and after), with their luminance.
    pub emitters: Vec<Emitter>,
    /// The sky before and after, when it changed (nits).
    pub sky: Option<(Vec3, Vec3)>,
    /// Instances whose surface reflects otherwise (their albedo changed).
    pub albedo: usize,
}

impl Edits {
    /// Whether nothing changed.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The parts of the input the edit changed: what [`Stage::changed_by`](crate::stage::Stage::changed_by) reads against
    /// each stage's declared inputs ([`Stage::reads`](crate::stage::Stage::reads)). Geometry that moved, changed, came
    /// or went changes the layout too (its meshes' charts are placed again).
    pub fn changed(&self) -> Vec<Input> {
        let mut c = Vec::new();
        if !self.boxes.is_empty() {
            c.extend([Input::Geometry, Input::Layout]);
        }
        if self.albedo > 0 {
            c.push(Input::Albedo);
        }
        if !self.emitters.is_empty() {
            c.push(Input::Emission);
        }
        if !self.lights.is_empty() {
            c.push(Input::Lights);
        }
        if self.sky.is_some() {
            c.push(Input::Sky);
        }
        c
    }
}

/// The settings a bake's values depend on: all but the thread count, the checks (verify
/// points) and the output formats other than BC6H (which lays the pages out on blocks).
pub fn deciding_settings(settings: &BakeSettings) -> BakeSettings {
    let mut s = settings.clone();
    s.threads = 0;
    s.checks = Default::default();
    let bc6h = s.formats.ktx2_bc6h;
    s.formats = Default::default();
    s.formats.ktx2_bc6h = bc6h;
    s
}

/// The settings groups in which `a` and `b` differ, by name.
fn changed_groups(a: &BakeSettings, b: &BakeSettings) -> Vec<String> {
    let (Ok(serde_json::Value::Object(x)), Ok(serde_json::Value::Object(y))) =
        (serde_json::to_value(a), serde_json::to_value(b))
    else {
        return vec!["settings".into()];
    };
    let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| x.get(*k) != y.get(*k))
        .cloned()
        .collect()
}

/// The world box and emitted luminance of each instance of `scene`.
pub fn instance_boxes(scene: &Scene) -> Vec<Emitter> {
    (0..scene.instances.len())
        .map(|i| {
            let emitted = scene
                .material_of(scene.instances[i].mesh)
                .emissive
                .max_element();
            (scene.instance_bounds(i), emitted)
        })
        .collect()
}

/// What changed from `cache` to `scene` baked with `settings`, or why it cannot be baked as
/// an edit of the cached bake (then the bake is full).
///
/// # Errors
/// The reason for a full bake: settings that change every texel (or light groups, a target
/// error), a cache of another scene.
pub fn edits(cache: &BakeCache, scene: &Scene, settings: &BakeSettings) -> Result<Edits, String> {
    same_settings(cache, settings)?;
    if !settings.groups.is_empty() {
        return Err("light groups are baked over every texel".into());
    }
    if settings.target_error.is_some() {
        return Err("a target error's rounds take every texel's estimate".into());
    }
    changed_parts(cache, scene)
}

/// What changed from `cache` to `scene` baked with `settings`, whatever the settings' light
/// groups and target error: what a bake with light groups relights from (`super::relight`).
///
/// # Errors
/// Settings that change every texel, a cache of another scene.
pub(super) fn changes(
    cache: &BakeCache,
    scene: &Scene,
    settings: &BakeSettings,
) -> Result<Edits, String> {
    same_settings(cache, settings)?;
    changed_parts(cache, scene)
}

/// Whether `settings` decide the texels as the cached bake's did.
fn same_settings(cache: &BakeCache, settings: &BakeSettings) -> Result<(), String> {
    let (before, now) = (
        deciding_settings(&cache.settings),
        deciding_settings(settings),
    );
    if before != now {
        return Err(format!(
            "the settings changed ({}), which changes every texel",
            changed_groups(&before, &now).join(", ")
        ));
    }
    Ok(())
}

/// The parts of `scene` that differ from the cached bake's.
fn changed_parts(cache: &BakeCache, scene: &Scene) -> Result<Edits, String> {
    let hashes = SceneHashes::of(scene);
    let old = &cache.scene;
    let mut edits = Edits::default();
    let boxes = instance_boxes(scene);
    // Instances by identity.
    let by_id = |list: &[InstanceHashes], id: u64| list.iter().position(|h| h.identity == id);
    let kept = hashes
        .instances
        .iter()
        .filter(|h| by_id(&old.instances, h.identity).is_some())
        .count();
    if kept == 0 && !old.instances.is_empty() && !hashes.instances.is_empty() {
        return Err("no instance of the cached bake is in the scene: it is another scene".into());
    }
    let mut in_place = Vec::new();
    let (mut moved, mut added, mut removed, mut reshaped, mut painted, mut lit) = (
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
        Vec::new(),
    );
    let name = |s: &Scene, i: usize| s.instances[i].name.clone();
    for (i, h) in hashes.instances.iter().enumerate() {
        let Some(j) = by_id(&old.instances, h.identity) else {
            added.push(name(scene, i));
            edits.boxes.push(boxes[i].0);
            if boxes[i].1 > 0.0 {
                edits.emitters.push(boxes[i]);
            }
            continue;
        };
        let o = &old.instances[j];
        let before = cache.boxes[j];
        if o.placement != h.placement {
            edits.boxes.extend([before.0, boxes[i].0]);
            if o.geometry != h.geometry {
                reshaped.push(name(scene, i));
            } else if before.0 == boxes[i].0 {
                // Where it was, of the same geometry: its two-sidedness, its `bake` flag or
                // its density scale changed.
                in_place.push(name(scene, i));
            } else {
                moved.push(name(scene, i));
            }
            if before.1 > 0.0 || boxes[i].1 > 0.0 {
                edits.emitters.extend([before, boxes[i]]);
            }
        }
        if o.emission != h.emission {
            lit.push(name(scene, i));
            edits.emitters.extend([before, boxes[i]]);
        }
        if o.albedo != h.albedo {
            painted.push(name(scene, i));
        }
    }
    for (j, o) in old.instances.iter().enumerate() {
        if by_id(&hashes.instances, o.identity).is_none() {
            removed.push(cache.instance_names[j].clone());
            edits.boxes.push(cache.boxes[j].0);
            if cache.boxes[j].1 > 0.0 {
                edits.emitters.push(cache.boxes[j]);
            }
        }
    }
    edits.albedo = painted.len();
    let mut line = |what: &str, names: &[String]| {
        if !names.is_empty() {
            let shown: Vec<&str> = names.iter().take(4).map(String::as_str).collect();
            let more = if names.len() > 4 {
                format!(" and {} more", names.len() - 4)
            } else {
                String::new()
            };
            edits
                .lines
                .push(format!("{what}: {}{more}", shown.join(", ")));
        }
    };
    line("moved", &moved);
    line("added", &added);
    line("removed", &removed);
    line("other geometry", &reshaped);
    line("sides, bake flag or density scale changed", &in_place);
    line("albedo changed", &painted);
    line("emission changed", &lit);
    lights(cache, scene, &hashes, &mut edits);
    if old.sky != hashes.sky {
        edits.sky = Some((cache.sky, scene.sky));
        edits.lines.push(format!(
            "sky: {:?} → {:?} nits",
            cache.sky.to_array(),
            scene.sky.to_array()
        ));
    }
    Ok(edits)
}

/// The lights that changed, added or went, by identity.
fn lights(cache: &BakeCache, scene: &Scene, hashes: &SceneHashes, edits: &mut Edits) {
    let old = &cache.scene.lights;
    for (i, (id, h)) in hashes.lights.iter().enumerate() {
        let now = &scene.lights[i];
        match old.iter().position(|(oid, _)| oid == id) {
            None => {
                edits.lines.push(format!("light '{}' added", now.name));
                edits.lights.push((None, Some(now.clone())));
            }
            Some(j) if old[j].1 != *h => {
                let was = &cache.lights[j];
                edits
                    .lines
                    .push(format!("light '{}' {}", now.name, light_change(was, now)));
                edits.lights.push((Some(was.clone()), Some(now.clone())));
            }
            Some(_) => {}
        }
    }
    for (j, (oid, _)) in old.iter().enumerate() {
        if !hashes.lights.iter().any(|(id, _)| id == oid) {
            edits
                .lines
                .push(format!("light '{}' removed", cache.lights[j].name));
            edits.lights.push((Some(cache.lights[j].clone()), None));
        }
    }
}

/// What changed of a light, in words.
fn light_change(was: &Light, now: &Light) -> String {
    let mut what = Vec::new();
    if was.position != now.position {
        what.push(format!(
            "moved {:.3} m",
            was.position.distance(now.position)
        ));
    }
    if was.direction != now.direction {
        what.push(format!(
            "turned {:.1}°",
            was.direction.angle_between(now.direction).to_degrees()
        ));
    }
    if was.intensity != now.intensity {
        what.push(format!("intensity {} → {}", was.intensity, now.intensity));
    }
    if was.color != now.color {
        what.push(format!(
            "colour {:?} → {:?}",
            was.color.to_array(),
            now.color.to_array()
        ));
    }
    if was.range != now.range {
        what.push(format!("range {:?} → {:?}", was.range, now.range));
    }
    if was.kind != now.kind {
        what.push("kind or cone changed".into());
    }
    if was.bake != now.bake {
        what.push(format!("bake {:?} → {:?}", was.bake, now.bake));
    }
    if what.is_empty() {
        "changed".into()
    } else {
        what.join(", ")
    }
}
