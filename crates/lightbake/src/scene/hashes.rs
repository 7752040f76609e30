//! Content hashes of a scene's parts, so that a later bake of an edited scene can tell what
//! changed: each mesh's geometry, each instance's placement and surface, each light, the sky.
//! Instances and lights are told apart across bakes by their *identity*: their name and how
//! many earlier ones share it (glTF node names, Bevy entity names), so renumbering the scene
//! does not change them.
//!
//! Hashes are FNV-1a over the values' bits (`Fnv1a`); two bakes of the same input give the
//! same hashes on every machine.

use glam::Vec3;

use super::{Instance, Mesh, Scene};
use crate::sampling::Fnv1a;

/// A running hash fed with the bits of floats and integers.
#[derive(Default)]
pub(crate) struct Hasher(Fnv1a);

impl Hasher {
    pub(crate) fn u32(&mut self, v: u32) -> &mut Self {
        self.0.word(v);
        self
    }

    pub(crate) fn u64(&mut self, v: u64) -> &mut Self {
        self.0.bytes(&v.to_le_bytes());
        self
    }

    pub(crate) fn f32(&mut self, v: f32) -> &mut Self {
        self.0.word(v.to_bits());
        self
    }

    pub(crate) fn f32s(&mut self, v: &[f32]) -> &mut Self {
        self.u64(v.len() as u64);
        for x in v {
            self.f32(*x);
        }
        self
    }

    pub(crate) fn vec3(&mut self, v: Vec3) -> &mut Self {
        self.f32s(&v.to_array())
    }

    pub(crate) fn str(&mut self, s: &str) -> &mut Self {
        self.u64(s.len() as u64);
        self.0.bytes(s.as_bytes());
        self
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) -> &mut Self {
        self.u64(b.len() as u64);
        self.0.bytes(b);
        self
    }

    pub(crate) fn finish(&self) -> u64 {
        self.0.finish()
    }
}

/// The hash of a mesh's geometry: positions, normals, indices and its own `TEXCOORD_1` (what
/// its lightmap UVs and texel patches are made from; its material is the instances' surface).
pub fn mesh_geometry(mesh: &Mesh) -> u64 {
    let mut h = Hasher::default();
    h.u64(mesh.positions.len() as u64);
    for p in &mesh.positions {
        h.vec3(*p);
    }
    for n in &mesh.normals {
        h.vec3(*n);
    }
    h.u64(mesh.indices.len() as u64);
    for i in &mesh.indices {
        h.u32(*i);
    }
    match &mesh.uv1 {
        Some(uv) => {
            h.u32(1);
            for t in uv {
                h.f32(t.x).f32(t.y);
            }
        }
        None => {
            h.u32(0);
        }
    }
    h.finish()
}

/// Identities of `names` in order: each name with how many earlier ones share it.
pub fn identities<'a>(names: impl IntoIterator<Item = &'a str>) -> Vec<u64> {
    let mut seen: std::collections::HashMap<&str, u32> = std::collections::HashMap::new();
    names
        .into_iter()
        .map(|name| {
            let k = seen.entry(name).or_insert(0);
            let id = Hasher::default().str(name).u32(*k).finish();
            *k += 1;
            id
        })
        .collect()
}

/// What an instance is, in hashes: its place in the scene (mesh geometry, transform, whether
/// it is baked, its density scale, whether rays see its back faces), its surface's albedo
/// (base colour, metallic, texture, UV sets the texture is read by) and its emission.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InstanceHashes {
    /// Name and occurrence (see the module docs).
    pub identity: u64,
    /// The mesh's geometry ([`mesh_geometry`]).
    pub geometry: u64,
    /// Geometry, transform, `bake`, `texel_density_scale` and the material's two-sidedness
    /// (which faces block and take light: what the validity pass, the shadow rays and the
    /// gathers' hits read).
    pub placement: u64,
    /// What the surface reflects: base colour factor and texture, metallic.
    pub albedo: u64,
    /// What the surface emits: emissive factor and texture.
    pub emission: u64,
}

/// The hashes of every part of a scene that a bake reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneHashes {
    /// Per mesh, its geometry ([`mesh_geometry`]).
    pub meshes: Vec<u64>,
    /// Per instance.
    pub instances: Vec<InstanceHashes>,
    /// Per light: its identity and all it is (kind, position, direction, colour, intensity,
    /// range, cone, baked part).
    pub lights: Vec<(u64, u64)>,
    /// The sky's luminance.
    pub sky: u64,
}

impl SceneHashes {
    /// The hashes of `scene`'s parts.
    pub fn of(scene: &Scene) -> Self {
        let meshes: Vec<u64> = scene.meshes.iter().map(mesh_geometry).collect();
        let textures: Vec<u64> = (scene.textures.iter())
            .map(|t| {
                let mut h = Hasher::default();
                h.u32(t.width).u32(t.height);
                h.u32(t.wrap_u as u32).u32(t.wrap_v as u32);
                h.bytes(t.rgba8.as_flattened());
                h.finish()
            })
            .collect();
        let ids = identities(scene.instances.iter().map(|i| i.name.as_str()));
        let instances = (scene.instances.iter().zip(ids))
            .map(|(inst, identity)| instance_hashes(scene, inst, identity, &meshes, &textures))
            .collect();
        let light_ids = identities(scene.lights.iter().map(|l| l.name.as_str()));
        let lights = (scene.lights.iter().zip(light_ids))
            .map(|(l, id)| {
                let json = serde_json::to_vec(l).unwrap_or_default();
                (id, Hasher::default().bytes(&json).finish())
            })
            .collect();
        Self {
            meshes,
            instances,
            lights,
            sky: Hasher::default().vec3(scene.sky).finish(),
        }
    }
}

fn instance_hashes(
    scene: &Scene,
    inst: &Instance,
    identity: u64,
    meshes: &[u64],
    textures: &[u64],
) -> InstanceHashes {
    let geometry = meshes[inst.mesh];
    let mut placement = Hasher::default();
    placement.u64(geometry);
    placement.f32s(&inst.transform.to_cols_array());
    let material = scene.meshes[inst.mesh]
        .material
        .map(|m| &scene.materials[m]);
    placement
        .u32(u32::from(inst.bake))
        .f32(inst.texel_density_scale)
        .u32(u32::from(material.is_some_and(|m| m.double_sided)));
    let texture = |t: Option<super::TextureRef>| {
        t.map_or(0, |t| textures[t.texture] ^ u64::from(t.tex_coord))
    };
    let mut albedo = Hasher::default();
    let mut emission = Hasher::default();
    if let Some(m) = material {
        albedo
            .f32s(&m.base_color.to_array())
            .u64(texture(m.base_color_texture));
        albedo.f32(m.metallic);
        emission.vec3(m.emissive).u64(texture(m.emissive_texture));
    }
    InstanceHashes {
        identity,
        geometry,
        placement: placement.finish(),
        albedo: albedo.finish(),
        emission: emission.finish(),
    }
}

#[cfg(test)]
mod tests {
    use glam::Affine3A;

    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box};

    #[test]
    fn identities_count_repeated_names() {
        let ids = identities(["a", "b", "a", "a"]);
        assert_eq!(ids.len(), 4);
        assert_ne!(ids[0], ids[2]);
        assert_ne!(ids[2], ids[3]);
        assert_eq!(ids, identities(["a", "b", "a", "a"]));
        assert_eq!(ids[1], identities(["b"])[0]);
    }

    #[test]
    fn each_edit_changes_its_own_hash_only() {
        let scene = cornell_box(CornellLight::Point);
        let base = SceneHashes::of(&scene);
        assert_eq!(base, SceneHashes::of(&scene.clone()));

        let mut moved = scene.clone();
        moved.instances[1].transform =
            Affine3A::from_translation(Vec3::X) * moved.instances[1].transform;
        let h = SceneHashes::of(&moved);
        assert_ne!(h.instances[1].placement, base.instances[1].placement);
        assert_eq!(h.instances[1].geometry, base.instances[1].geometry);
        assert_eq!(h.instances[1].albedo, base.instances[1].albedo);
        assert_eq!(h.instances[0], base.instances[0]);
        assert_eq!(h.lights, base.lights);

        let mut lamp = scene.clone();
        lamp.lights[0].intensity *= 2.0;
        let h = SceneHashes::of(&lamp);
        assert_eq!(h.lights[0].0, base.lights[0].0);
        assert_ne!(h.lights[0].1, base.lights[0].1);
        assert_eq!(h.instances, base.instances);

        let mut sky = scene.clone();
        sky.sky = Vec3::ONE;
        assert_ne!(SceneHashes::of(&sky).sky, base.sky);

        let mut paint = scene;
        let m = paint.meshes[paint.instances[2].mesh].material.unwrap();
        let scene_albedo = paint.materials[m].base_color;
        paint.materials[m].base_color *= 0.5;
        let h = SceneHashes::of(&paint);
        let changed: Vec<usize> = (0..h.instances.len())
            .filter(|&i| h.instances[i].albedo != base.instances[i].albedo)
            .collect();
        assert!(changed.contains(&2));
        assert!(
            changed
                .iter()
                .all(|&i| h.instances[i].placement == base.instances[i].placement)
        );

        // Two-sidedness decides which faces block light: the instance's placement, not its
        // albedo.
        let mut sides = paint.clone();
        sides.materials[m].base_color = scene_albedo;
        sides.materials[m].double_sided = !sides.materials[m].double_sided;
        let h = SceneHashes::of(&sides);
        assert_ne!(h.instances[2].placement, base.instances[2].placement);
        assert_eq!(h.instances[2].albedo, base.instances[2].albedo);
        assert_eq!(h.instances[2].geometry, base.instances[2].geometry);
    }
}
