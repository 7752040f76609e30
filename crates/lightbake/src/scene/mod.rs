//! The engine-free scene the baker works on: meshes, their placed instances, materials,
//! textures, lights and the sky.
//!
//! # Units
//! Lengths are metres. Light quantities follow glTF (`KHR_lights_punctual`,
//! `KHR_materials_emissive_strength`), which are also Bevy's (see `docs/units.md`):
//!
//! | quantity | unit | Bevy |
//! |---|---|---|
//! | point / spot intensity | candela (cd) | `PointLight::intensity` lumens = 4π·cd |
//! | directional intensity | lux (lx) | `DirectionalLight::illuminance` |
//! | emissive, sky | luminance, nits (cd/m²) | `StandardMaterial::emissive` |
//! | lightmap texel | irradiance / π (lx/π) | `Lightmap` RGB × `base_color` |
//!
//! Colours are linear RGB; intensities multiply them.

use glam::{Affine3A, Mat3, Vec3};

use crate::error::{BakeError, Result};

/// Largest world coordinate a vertex may have, m (default and only value: 10⁹ m). Beyond it
/// f32 positions are more than 100 m apart, so nothing can be baked there; xatlas crashed on
/// a fuzzed scene with a vertex at 1.4·10²² m (`crates/lightbake/tests/fuzz_import.rs`).
pub const MAX_COORDINATE: f32 = 1e9;

mod closest;
pub mod extras;
internal!(glb, gltf_accessor, gltf_data, resources);
pub mod gltf_import;
pub mod gltf_write;
pub mod groups;
pub mod hashes;
mod light;
mod material;
mod mesh;
#[cfg(any(test, feature = "testscenes"))]
pub mod testscenes;
mod texture;

pub use closest::closest_on_triangle;
pub use light::{Light, LightBake, LightKind};
pub use material::{Material, TexCoords, TextureRef};
pub use mesh::{CREASE_DEGREES, GltfPrimitiveRef, Mesh};
pub use texture::{Texture, Wrap};

/// Reads a regular file of at most `limit` bytes the way the import reads a scene's files:
/// without following a final link, without blocking on a FIFO, and refusing anything but a
/// regular file before reading it.
///
/// # Errors
/// [`BakeError::Read`] naming the file and why it cannot be read.
pub fn read_regular_file(path: &std::path::Path, limit: u64) -> Result<Vec<u8>> {
    resources::read_regular_file(path, limit).map_err(|why| BakeError::Read {
        path: path.to_path_buf(),
        source: std::io::Error::other(why),
    })
}

/// A mesh placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Name used in messages and the manifest (glTF node name, or `node N`).
    pub name: String,
    /// Index into [`Scene::meshes`].
    pub mesh: usize,
    /// Mesh space → world space (the whole node hierarchy, composed).
    pub transform: Affine3A,
    /// Receive a lightmap. Instances that are not baked still cast shadows and reflect light.
    pub bake: bool,
    /// Per-instance multiplier of the texel density (glTF node
    /// `extras.lightbake.texel_density_scale`). Default 1.
    pub texel_density_scale: f32,
    /// The glTF node it came from.
    pub gltf_node: Option<usize>,
}

impl Instance {
    /// Places `mesh` with `transform`, baked, at the default density.
    pub fn new(name: impl Into<String>, mesh: usize, transform: Affine3A) -> Self {
        Self {
            name: name.into(),
            mesh,
            transform,
            bake: true,
            texel_density_scale: 1.0,
            gltf_node: None,
        }
    }

    /// The matrix that takes mesh-space normals to world space (inverse transpose).
    pub fn normal_matrix(&self) -> Mat3 {
        Mat3::from(self.transform.matrix3).inverse().transpose()
    }

    /// Whether the transform is finite and invertible.
    ///
    /// # Errors
    /// [`BakeError::BadTransform`] naming the instance.
    pub fn validate(&self) -> Result<()> {
        let m = Mat3::from(self.transform.matrix3);
        if !(m.is_finite() && self.transform.translation.is_finite()) {
            return Err(BakeError::BadTransform {
                node: self.name.clone(),
                problem: "not finite",
            });
        }
        // Relative determinant test: |det| against the product of the column lengths.
        let scale = m.x_axis.length() * m.y_axis.length() * m.z_axis.length();
        if !(scale > 0.0 && (m.determinant().abs() / scale) > 1e-6) {
            return Err(BakeError::BadTransform {
                node: self.name.clone(),
                problem: "singular (zero scale)",
            });
        }
        Ok(())
    }
}

/// A scene ready to bake.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// Name used in messages (the file name for imported scenes).
    pub name: String,
    /// Meshes (one per glTF primitive).
    pub meshes: Vec<Mesh>,
    /// Placed meshes.
    pub instances: Vec<Instance>,
    /// Materials referenced by meshes.
    pub materials: Vec<Material>,
    /// Textures referenced by materials.
    pub textures: Vec<Texture>,
    /// Punctual lights.
    pub lights: Vec<Light>,
    /// Uniform sky luminance in nits, linear RGB, seen by rays that leave the scene. Black by
    /// default.
    pub sky: Vec3,
    /// The scene's suggested texel density (glTF `scene.extras.lightbake.texel_density`).
    pub texel_density_hint: Option<f32>,
    /// Warnings raised while building the scene (repairs made on import).
    pub warnings: Vec<String>,
}

impl Scene {
    /// The material of mesh `m` (the glTF default when it has none).
    pub fn material_of(&self, mesh: usize) -> std::borrow::Cow<'_, Material> {
        match self.meshes[mesh].material {
            Some(i) => std::borrow::Cow::Borrowed(&self.materials[i]),
            None => std::borrow::Cow::Owned(Material::default()),
        }
    }

    /// The diffuse albedo of instance `instance` at barycentric weights `bary` of its mesh's
    /// triangle `triangle` ([`Material::diffuse_albedo`]).
    pub fn albedo_at(&self, instance: usize, triangle: usize, bary: glam::Vec2) -> Vec3 {
        let mesh = self.instances[instance].mesh;
        self.material_of(mesh)
            .diffuse_albedo(&self.textures, self.meshes[mesh].texcoords(triangle, bary))
    }

    /// Number of triangles over all instances (the ray-tracing load).
    pub fn instanced_triangle_count(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh].triangle_count())
            .sum()
    }

    /// Checks every mesh, instance (including that its world vertices lie within
    /// [`MAX_COORDINATE`] of the origin), material and light; names the first problem.
    ///
    /// # Errors
    /// The first [`BakeError`] found, or [`BakeError::NoTriangles`].
    pub fn validate(&self) -> Result<()> {
        for m in &self.meshes {
            m.validate()?;
            if let Some(mat) = m.material
                && mat >= self.materials.len()
            {
                return Err(BakeError::BadReference {
                    what: format!(
                        "mesh '{}' uses material {mat}, which does not exist",
                        m.name
                    ),
                });
            }
        }
        for inst in &self.instances {
            if inst.mesh >= self.meshes.len() {
                return Err(BakeError::BadReference {
                    what: format!(
                        "instance '{}' uses mesh {}, which does not exist",
                        inst.name, inst.mesh
                    ),
                });
            }
            inst.validate()?;
            let mesh = &self.meshes[inst.mesh];
            if let Some((vertex, p)) = mesh
                .positions
                .iter()
                .map(|&p| inst.transform.transform_point3(p))
                .enumerate()
                .find(|(_, p)| p.is_nan() || p.abs().max_element() > MAX_COORDINATE)
            {
                return Err(BakeError::FarVertex {
                    instance: inst.name.clone(),
                    mesh: mesh.name.clone(),
                    vertex,
                    position: format!("{p}"),
                    limit: MAX_COORDINATE,
                    spacing: MAX_COORDINATE * f32::EPSILON,
                });
            }
            if !(inst.texel_density_scale.is_finite() && inst.texel_density_scale > 0.0) {
                return Err(BakeError::BadSetting {
                    name: "texel_density_scale",
                    value: inst.texel_density_scale.to_string(),
                    message: format!("instance '{}': must be positive", inst.name),
                });
            }
        }
        for mat in &self.materials {
            mat.validate()?;
            for t in [mat.base_color_texture, mat.emissive_texture]
                .into_iter()
                .flatten()
            {
                if t.texture >= self.textures.len() {
                    return Err(BakeError::BadReference {
                        what: format!(
                            "material '{}' uses texture {}, which does not exist",
                            mat.name, t.texture
                        ),
                    });
                }
            }
        }
        for light in &self.lights {
            light.validate()?;
        }
        if !self.sky.is_finite() || self.sky.min_element() < 0.0 {
            return Err(BakeError::BadSetting {
                name: "sky",
                value: format!("{:?}", self.sky),
                message: "sky luminance must be finite and non-negative".into(),
            });
        }
        if self.instanced_triangle_count() == 0 {
            return Err(BakeError::NoTriangles {
                scene: self.name.clone(),
            });
        }
        Ok(())
    }

    /// World-space bounds of every instance: (min, max). Empty scenes give (0, 0).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for inst in &self.instances {
            for p in &self.meshes[inst.mesh].positions {
                let w = inst.transform.transform_point3(*p);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        if lo.x > hi.x {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }

    /// The world-space surface area of one instance, m² (its mesh's area under its
    /// transform).
    pub fn instance_area(&self, instance: usize) -> f32 {
        let inst = &self.instances[instance];
        let mesh = &self.meshes[inst.mesh];
        (0..mesh.triangle_count())
            .map(|t| {
                let [a, b, c] = mesh
                    .triangle(t)
                    .map(|i| inst.transform.transform_point3(mesh.positions[i]));
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// The world-space bounds of one instance.
    pub fn instance_bounds(&self, instance: usize) -> (Vec3, Vec3) {
        let inst = &self.instances[instance];
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in &self.meshes[inst.mesh].positions {
            let w = inst.transform.transform_point3(*p);
            lo = lo.min(w);
            hi = hi.max(w);
        }
        (lo, hi)
    }

    /// Adds a mesh and returns its index.
    pub fn add_mesh(&mut self, mesh: Mesh) -> usize {
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    /// Adds a material and returns its index.
    pub fn add_material(&mut self, material: Material) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }
}
