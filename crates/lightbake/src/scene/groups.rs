//! Light groups resolved against a scene: which of its lights, emissive materials and sky
//! each group holds ([`crate::settings::groups`] says how members are named), and the scene
//! each group's lighting passes see: its own emitters only, every surface as it is.

use glam::Vec3;

use super::Scene;
use crate::error::{BakeError, Result};
use crate::settings::groups::{LightGroup, SKY, UNGROUPED};

/// One group's emitters in a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct GroupMembers {
    /// The group's name ([`UNGROUPED`] for the emitters no group names).
    pub name: String,
    /// Indices into [`Scene::lights`].
    pub lights: Vec<usize>,
    /// Indices into [`Scene::materials`] of emissive materials.
    pub materials: Vec<usize>,
    /// Whether the group holds the sky.
    pub sky: bool,
}

impl GroupMembers {
    /// `scene` with only this group's emitters: the other lights removed, the other
    /// materials' emission and (unless the group holds it) the sky set to zero. Geometry,
    /// albedo and instances are unchanged, so the unwrap and the BVH of `scene` serve it.
    pub fn scene_of(&self, scene: &Scene) -> Scene {
        let mut s = scene.clone();
        s.lights = (self.lights.iter())
            .map(|&i| scene.lights[i].clone())
            .collect();
        for (i, m) in s.materials.iter_mut().enumerate() {
            if !self.materials.contains(&i) {
                m.emissive = Vec3::ZERO;
            }
        }
        if !self.sky {
            s.sky = Vec3::ZERO;
        }
        s
    }

    /// The members by name, for the report and the manifest: `light NAME`, `material NAME`,
    /// `sky`.
    pub fn describe(&self, scene: &Scene) -> Vec<String> {
        let mut names: Vec<String> = Vec::new();
        let mut push = |n: String| {
            if !names.contains(&n) {
                names.push(n);
            }
        };
        for &i in &self.lights {
            push(format!("light {}", scene.lights[i].name));
        }
        for &i in &self.materials {
            push(format!("material {}", scene.materials[i].name));
        }
        if self.sky {
            push(SKY.to_string());
        }
        names
    }

    /// Whether the group holds no emitter.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty() && self.materials.is_empty() && !self.sky
    }
}

/// Adds `member` to the group named `group` in `groups` (created at the end when new; a
/// member already there is not added twice): how the glTF importer collects the groups its
/// extras name.
pub fn add_member(groups: &mut Vec<LightGroup>, group: &str, member: String) {
    let g = match groups.iter().position(|g| g.name == group) {
        Some(i) => &mut groups[i],
        None => {
            groups.push(LightGroup {
                name: group.to_string(),
                members: Vec::new(),
            });
            groups.last_mut().expect("just pushed")
        }
    };
    if !g.members.contains(&member) {
        g.members.push(member);
    }
}

/// Whether material `m` of `scene` emits light.
fn emits(scene: &Scene, m: usize) -> bool {
    scene.materials[m].emissive.max_element() > 0.0
}

/// Resolves `groups` against `scene`: each group's emitters, then the group [`UNGROUPED`]
/// of the emitters no group names (when there are any). Empty `groups` give no groups.
///
/// # Errors
/// [`BakeError::BadSetting`] naming the group and member: a member that names no light,
/// emissive material or sky of the scene (`sky` in a scene whose sky is 0 among them); a
/// name that is both a light and an emissive material (write `light:NAME` or
/// `material:NAME`); an emitter that two groups name.
pub fn resolve(scene: &Scene, groups: &[LightGroup]) -> Result<Vec<GroupMembers>> {
    crate::settings::groups::check(groups)?;
    if groups.is_empty() {
        return Ok(Vec::new());
    }
    let mut resolved: Vec<GroupMembers> = Vec::new();
    let mut owner_light: Vec<Option<usize>> = vec![None; scene.lights.len()];
    let mut owner_material: Vec<Option<usize>> = vec![None; scene.materials.len()];
    let mut owner_sky: Option<usize> = None;
    for (gi, g) in groups.iter().enumerate() {
        let bad = |member: &str, message: String| BakeError::BadSetting {
            name: "groups",
            value: format!("{}={member}", g.name),
            message,
        };
        let mut members = GroupMembers {
            name: g.name.clone(),
            lights: Vec::new(),
            materials: Vec::new(),
            sky: false,
        };
        for member in &g.members {
            let (kind, name) = match member.split_once(':') {
                Some(("light", n)) => (Some("light"), n),
                Some(("material", n)) => (Some("material"), n),
                _ => (None, member.as_str()),
            };
            let lights: Vec<usize> = (0..scene.lights.len())
                .filter(|&i| scene.lights[i].name == name)
                .collect();
            let materials: Vec<usize> = (0..scene.materials.len())
                .filter(|&i| scene.materials[i].name == name && emits(scene, i))
                .collect();
            let (lights, materials, sky) = match kind {
                Some("light") => (lights, Vec::new(), false),
                Some("material") => (Vec::new(), materials, false),
                _ if member == SKY => (Vec::new(), Vec::new(), true),
                _ => {
                    if !lights.is_empty() && !materials.is_empty() {
                        return Err(bad(
                            member,
                            format!(
                                "'{name}' is both a light and an emissive material: write light:{name} or material:{name}"
                            ),
                        ));
                    }
                    (lights, materials, false)
                }
            };
            if sky && scene.sky.max_element() <= 0.0 {
                return Err(bad(
                    member,
                    "the scene has no sky (its sky luminance is 0: set one with --sky or the scene's extras.lightbake.sky)".into(),
                ));
            }
            if lights.is_empty() && materials.is_empty() && !sky {
                return Err(bad(
                    member,
                    format!(
                        "the scene has no {} named '{name}' (its lights: {})",
                        match kind {
                            Some("material") => "emissive material",
                            Some(_) => "light",
                            None => "light or emissive material",
                        },
                        light_names(scene)
                    ),
                ));
            }
            let taken = |owner: Option<usize>| -> Result<()> {
                match owner {
                    Some(o) if o != gi => Err(bad(
                        member,
                        format!(
                            "'{name}' is in light groups '{}' and '{}': each light, emissive material and the sky belongs to one group",
                            groups[o].name, g.name
                        ),
                    )),
                    _ => Ok(()),
                }
            };
            for &l in &lights {
                taken(owner_light[l])?;
                owner_light[l] = Some(gi);
                if !members.lights.contains(&l) {
                    members.lights.push(l);
                }
            }
            for &m in &materials {
                taken(owner_material[m])?;
                owner_material[m] = Some(gi);
                if !members.materials.contains(&m) {
                    members.materials.push(m);
                }
            }
            if sky {
                taken(owner_sky)?;
                owner_sky = Some(gi);
                members.sky = true;
            }
        }
        resolved.push(members);
    }
    let rest = GroupMembers {
        name: UNGROUPED.to_string(),
        lights: (0..scene.lights.len())
            .filter(|&i| owner_light[i].is_none())
            .collect(),
        materials: (0..scene.materials.len())
            .filter(|&i| owner_material[i].is_none() && emits(scene, i))
            .collect(),
        sky: owner_sky.is_none() && scene.sky.max_element() > 0.0,
    };
    if !rest.is_empty() {
        resolved.push(rest);
    }
    Ok(resolved)
}

/// The scene's light names, for a message (the first 12).
fn light_names(scene: &Scene) -> String {
    let mut names: Vec<&str> = Vec::new();
    for l in &scene.lights {
        if !names.contains(&l.name.as_str()) {
            names.push(&l.name);
        }
    }
    if names.is_empty() {
        return "none".into();
    }
    let more = names.len().saturating_sub(12);
    names.truncate(12);
    let mut text = names.join(", ");
    if more > 0 {
        text.push_str(&format!(" and {more} more"));
    }
    text
}
