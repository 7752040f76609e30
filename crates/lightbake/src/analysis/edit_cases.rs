//! The edits a level designer makes between two bakes, applied to any scene, for checking and
//! measuring incremental bakes: a lamp moved 30 cm, switched off or given another colour, a
//! table-sized mesh moved 20 cm, a wall's albedo changed, a mesh added, a mesh removed.
//! Each picks its target from the scene itself (the first lamp; the largest instance between
//! 30 cm and 2 m across; the largest upright instance), so it applies to levels nobody
//! prepared for it.

// Measurement tools for the benchmarks, examples and tests (the `internals` feature); an
// embedding program's build has no use for them.
#![cfg_attr(not(feature = "internals"), allow(dead_code))]

use glam::{Affine3A, Quat, Vec3};

use crate::scene::{LightKind, Scene};

/// One kind of edit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EditCase {
    /// The first lamp moved 30 cm sideways, or a tenth of the scene's smallest extent where that is shorter (a scene with only a sun: the sun turned 2°).
    LampMoved,
    /// The first lamp removed.
    LampOff,
    /// The first lamp's colour changed to a warm white.
    LampColour,
    /// A table-sized instance moved 20 cm sideways (or a tenth of the smallest extent).
    MeshMoved,
    /// The largest upright instance's albedo tinted.
    Albedo,
    /// A copy of the table-sized instance, beside it.
    MeshAdded,
    /// The table-sized instance removed.
    MeshRemoved,
}

impl EditCase {
    /// Every case, in the order above.
    pub const ALL: [EditCase; 7] = [
        EditCase::LampMoved,
        EditCase::LampOff,
        EditCase::LampColour,
        EditCase::MeshMoved,
        EditCase::Albedo,
        EditCase::MeshAdded,
        EditCase::MeshRemoved,
    ];

    /// The case's name.
    pub const fn name(self) -> &'static str {
        match self {
            EditCase::LampMoved => "lamp moved",
            EditCase::LampOff => "lamp off",
            EditCase::LampColour => "lamp colour",
            EditCase::MeshMoved => "mesh moved",
            EditCase::Albedo => "albedo",
            EditCase::MeshAdded => "mesh added",
            EditCase::MeshRemoved => "mesh removed",
        }
    }

    /// `scene` with the edit applied and what it did, or `None` when the scene has nothing
    /// to apply it to.
    pub fn apply(self, scene: &Scene) -> Option<(Scene, String)> {
        let mut s = scene.clone();
        let lamp = (scene.lights.iter())
            .position(|l| !matches!(l.kind, LightKind::Directional { .. }))
            .or_else(|| (!scene.lights.is_empty()).then_some(0));
        let what = match self {
            EditCase::LampMoved => {
                let l = &mut s.lights[lamp?];
                if let LightKind::Directional { .. } = l.kind {
                    l.direction = Quat::from_rotation_y(2f32.to_radians()) * l.direction;
                    format!("sun '{}' turned 2°", l.name)
                } else {
                    let d = step(scene, 0.3);
                    l.position += Vec3::new(d, 0.0, 0.0);
                    format!("lamp '{}' moved {:.0} cm", l.name, 100.0 * d)
                }
            }
            EditCase::LampOff => {
                let l = s.lights.remove(lamp?);
                format!("light '{}' off", l.name)
            }
            EditCase::LampColour => {
                let l = &mut s.lights[lamp?];
                l.color = Vec3::new(1.0, 0.8, 0.6);
                format!("light '{}' to a warm white", l.name)
            }
            EditCase::MeshMoved => {
                let i = table(scene)?;
                let d = step(scene, 0.2);
                let t = &mut s.instances[i].transform;
                *t = Affine3A::from_translation(Vec3::new(d, 0.0, 0.0)) * *t;
                format!("'{}' moved {:.0} cm", s.instances[i].name, 100.0 * d)
            }
            EditCase::Albedo => {
                let i = wall(scene)?;
                let m = s.instances[i].mesh;
                let mut material = scene.material_of(m).into_owned();
                material.base_color *= glam::Vec4::new(0.5, 0.8, 1.0, 1.0);
                material.name = format!("{} (tinted)", material.name);
                s.materials.push(material);
                s.meshes[m].material = Some(s.materials.len() - 1);
                format!("'{}' tinted blue", s.instances[i].name)
            }
            EditCase::MeshAdded => {
                let i = table(scene)?;
                let mut copy = s.instances[i].clone();
                let (lo, hi) = scene.instance_bounds(i);
                let step = (hi - lo).x + 0.1;
                copy.transform =
                    Affine3A::from_translation(Vec3::new(step, 0.0, 0.0)) * copy.transform;
                copy.name = format!("{} copy", copy.name);
                copy.gltf_node = None;
                let name = copy.name.clone();
                s.instances.push(copy);
                format!("'{name}' added")
            }
            EditCase::MeshRemoved => {
                let i = table(scene)?;
                let gone = s.instances.remove(i);
                format!("'{}' removed", gone.name)
            }
        };
        Some((s, what))
    }
}

/// A move of `metres`, or of a tenth of the scene's extent where that is shorter (a 30 cm
/// move takes a lamp out of a box half a metre across).
fn step(scene: &Scene, metres: f32) -> f32 {
    let extent = (0..scene.instances.len())
        .map(|i| scene.instance_bounds(i))
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
        .map_or(0.0, |(lo, hi)| (hi - lo).min_element());
    metres.min(0.1 * extent).max(0.01)
}

/// The largest baked instance between 30 cm and 2 m across (a table, a crate, a chair).
fn table(scene: &Scene) -> Option<usize> {
    (0..scene.instances.len())
        .filter(|&i| scene.instances[i].bake)
        .filter(|&i| {
            let (lo, hi) = scene.instance_bounds(i);
            let size = (hi - lo).max_element();
            (0.3..=2.0).contains(&size)
        })
        .max_by(|&a, &b| scene.instance_area(a).total_cmp(&scene.instance_area(b)))
}

/// The baked instance with the largest area facing sideways (a wall).
fn wall(scene: &Scene) -> Option<usize> {
    let upright = |i: usize| {
        let inst = &scene.instances[i];
        let mesh = &scene.meshes[inst.mesh];
        let mut side = 0.0f32;
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh
                .triangle(t)
                .map(|k| inst.transform.transform_point3(mesh.positions[k]));
            let n = (b - a).cross(c - a);
            side += 0.5 * (n.x.abs() + n.z.abs());
        }
        side
    };
    (0..scene.instances.len())
        .filter(|&i| scene.instances[i].bake)
        .max_by(|&a, &b| upright(a).total_cmp(&upright(b)))
}
